//! Dataset archive unpacking on arbitrary bytes (tar, tar.gz, zip or nothing): `unpack`
//! refuses or unpacks, never panics; whatever it unpacks stays inside the destination as
//! regular files within the limits, nothing is written beside it, and a `manifest.csv` it
//! unpacked is read with the rows `ingest::is_inside` accepts resolving inside the folder.
#![no_main]

use libfuzzer_sys::fuzz_target;
use reflectance::{ArchiveLimits, unpack_archive as unpack};
use reflectance_core::dataset::{ingest, read_manifest};
use std::path::{Component, Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

const LIMITS: ArchiveLimits = ArchiveLimits {
    members: 64,
    unpacked_bytes: 1 << 20,
};

/// Every path under `dir`, after checking that each is a regular file or a folder.
fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).expect("readable") {
        let entry = entry.expect("an entry");
        let kind = entry.file_type().expect("a type");
        assert!(
            kind.is_file() || kind.is_dir(),
            "{:?} is neither",
            entry.path()
        );
        if kind.is_dir() {
            walk(&entry.path(), out);
        }
        out.push(entry.path());
    }
}

fuzz_target!(|data: &[u8]| {
    static RUN: AtomicU64 = AtomicU64::new(0);
    let run = std::env::temp_dir().join(format!(
        "reflectance-fuzz-archive-{}-{}",
        std::process::id(),
        RUN.fetch_add(1, Ordering::Relaxed)
    ));
    let dest = run.join("out");
    std::fs::create_dir_all(&dest).expect("a scratch folder");
    let archive = run.join("archive");
    std::fs::write(&archive, data).expect("written");
    if let Ok(unpacked) = unpack(&archive, &dest, LIMITS) {
        assert!(unpacked.bytes <= LIMITS.unpacked_bytes);
        let mut found = Vec::new();
        walk(&dest, &mut found);
        let mut bytes = 0;
        for rel in &unpacked.files {
            let path = dest.join(rel);
            assert!(
                Path::new(rel)
                    .components()
                    .all(|c| matches!(c, Component::Normal(_))),
                "{rel}"
            );
            bytes += std::fs::metadata(&path).expect("unpacked").len();
        }
        assert_eq!(bytes, unpacked.bytes);
        if unpacked.files.contains("manifest.csv") {
            if let Ok(manifest) = read_manifest(&dest.join("manifest.csv")) {
                for entry in &manifest.entries {
                    if ingest::is_inside(&entry.path) {
                        assert!(entry.file.starts_with(&dest), "{:?}", entry.file);
                    }
                }
            }
        }
    }
    // Nothing beside the destination.
    let mut beside: Vec<_> = std::fs::read_dir(&run)
        .expect("readable")
        .map(|e| e.expect("an entry").file_name())
        .collect();
    beside.sort();
    assert_eq!(beside, ["archive", "out"]);
    std::fs::remove_dir_all(&run).expect("removed");
});
