//! Crash-safe file writes: a temporary file in the same directory, fsync, rename, fsync the
//! directory. Readers see the old file or the new one, never a partial one.

use std::fs;
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// A unique hidden temporary path next to `path`.
pub fn temp_path(path: &Path) -> PathBuf {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let name = path
        .file_name()
        .map_or_else(|| "tmp".into(), |n| n.to_string_lossy());
    let unique = COUNTER.fetch_add(1, Ordering::Relaxed);
    path.with_file_name(format!(".{name}.tmp-{}-{unique}", std::process::id()))
}

/// Test-only crash windows: with `REFLECTANCE_TEST_PAUSE=point=ms[,point=ms…]` in the
/// environment the calling thread sleeps at the named point, so that the crash-safety
/// tests (`tests/server/faults.rs`) can SIGKILL the process there deterministically. Points:
/// `publish` (a new version's files are staged in a hidden directory, not yet renamed into
/// place), `activate` (a version is swapped in memory, not yet recorded in `ACTIVE`) and
/// `render-image` (before each image a render batch draws).
/// Unset in production; it is read only at these rare points.
pub fn test_pause(point: &str) {
    let Ok(spec) = std::env::var("REFLECTANCE_TEST_PAUSE") else {
        return;
    };
    for item in spec.split(',') {
        if let Some((name, ms)) = item.split_once('=')
            && name.trim() == point
            && let Ok(ms) = ms.trim().parse::<u64>()
        {
            tracing::warn!(point, ms, "REFLECTANCE_TEST_PAUSE: pausing");
            std::thread::sleep(std::time::Duration::from_millis(ms));
        }
    }
}

/// fsync a directory so that a rename inside it is durable.
pub fn sync_dir(dir: &Path) -> io::Result<()> {
    fs::File::open(dir)?.sync_all()
}

fn parent_dir(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

/// Replace `path` with `bytes` atomically.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> io::Result<()> {
    let tmp = temp_path(path);
    let result = (|| {
        let mut file = fs::File::create(&tmp)?;
        file.write_all(bytes)?;
        file.sync_all()?;
        fs::rename(&tmp, path)?;
        sync_dir(parent_dir(path))
    })();
    if result.is_err() {
        let _ = fs::remove_file(&tmp);
    }
    result
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn replaces_content_and_leaves_no_temporary() {
        let dir = std::env::temp_dir().join(format!("durable-test-{}", std::process::id()));
        fs::create_dir_all(&dir).unwrap();
        let target = dir.join("a.txt");
        write_atomic(&target, b"one").unwrap();
        write_atomic(&target, b"two").unwrap();
        assert_eq!(fs::read(&target).unwrap(), b"two");
        let names: Vec<_> = fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names.len(), 1, "{names:?}");
        fs::remove_dir_all(&dir).unwrap();
    }
}
