//! Confinement of job paths to the data directory: a job names its inputs and outputs by
//! paths relative to `--data-dir`. Absolute paths, `..` components, URLs and symlinks that
//! resolve outside the data directory are refused.

use std::path::{Component, Path, PathBuf};

#[derive(Debug, Clone)]
pub struct DataDir {
    /// Canonical (symlinks resolved) absolute path.
    root: PathBuf,
}

impl DataDir {
    pub fn new(dir: &Path) -> Result<DataDir, String> {
        std::fs::create_dir_all(dir)
            .and_then(|()| dir.canonicalize())
            .map(|root| DataDir { root })
            .map_err(|e| format!("data directory {}: {e}", dir.display()))
    }

    pub fn root(&self) -> &Path {
        &self.root
    }

    /// Syntactic checks: non-empty, relative, no `..`, not a URL.
    fn relative<'a>(&self, what: &str, rel: &'a str) -> Result<&'a Path, String> {
        let refuse = |why: &str| Err(format!("{what} {rel:?}: {why}"));
        if rel.trim().is_empty() {
            return refuse("empty path");
        }
        if rel.contains("://") || rel.starts_with("file:") || rel.contains('\0') {
            return refuse("URLs are not accepted; give a path relative to the data directory");
        }
        let path = Path::new(rel);
        if path.is_absolute() || rel.starts_with('\\') {
            return refuse(
                "absolute paths are not accepted; give a path relative to the data directory",
            );
        }
        for component in path.components() {
            match component {
                Component::Normal(_) | Component::CurDir => {}
                _ => return refuse("'..' and root components are not accepted"),
            }
        }
        Ok(path)
    }

    /// An existing file or directory inside the data directory (after resolving symlinks).
    pub fn existing(&self, what: &str, rel: &str) -> Result<PathBuf, String> {
        let path = self.relative(what, rel)?;
        let full = self.root.join(path);
        let canonical = full
            .canonicalize()
            .map_err(|e| format!("{what} {rel:?}: {e}"))?;
        self.inside(what, rel, canonical)
    }

    /// A directory inside the data directory, created if missing.
    pub fn output_dir(&self, what: &str, rel: &str) -> Result<PathBuf, String> {
        self.check_output(what, rel)?;
        let full = self.root.join(rel);
        std::fs::create_dir_all(&full).map_err(|e| format!("{what} {rel:?}: {e}"))?;
        let canonical = full
            .canonicalize()
            .map_err(|e| format!("{what} {rel:?}: {e}"))?;
        if !canonical.is_dir() {
            return Err(format!("{what} {rel:?}: not a directory"));
        }
        self.inside(what, rel, canonical)
    }

    /// Whether [`DataDir::output_dir`] may create (or reuse) `rel`, without creating it:
    /// the deepest existing ancestor must resolve inside the data directory, so that
    /// creating the rest cannot follow a symlink out of it.
    pub fn check_output(&self, what: &str, rel: &str) -> Result<(), String> {
        let path = self.relative(what, rel)?;
        let mut existing = self.root.join(path);
        while !existing.exists() {
            match existing.parent() {
                Some(parent) => existing = parent.to_path_buf(),
                None => break,
            }
        }
        let canonical = existing
            .canonicalize()
            .map_err(|e| format!("{what} {rel:?}: {e}"))?;
        let canonical = self.inside(what, rel, canonical)?;
        if canonical == self.root.join(path) && !canonical.is_dir() {
            return Err(format!("{what} {rel:?}: not a directory"));
        }
        Ok(())
    }

    /// A path found inside a dataset (a manifest row, a probe list entry) must also stay
    /// inside the data directory.
    pub fn check_resolved(&self, what: &str, path: &Path) -> Result<(), String> {
        let canonical = path
            .canonicalize()
            .map_err(|e| format!("{what} {}: {e}", path.display()))?;
        self.inside(what, &path.display().to_string(), canonical)
            .map(|_| ())
    }

    fn inside(&self, what: &str, rel: &str, canonical: PathBuf) -> Result<PathBuf, String> {
        if canonical.starts_with(&self.root) {
            Ok(canonical)
        } else {
            Err(format!(
                "{what} {rel:?} resolves outside the data directory"
            ))
        }
    }

    /// `path` relative to the data directory, for reports.
    pub fn display(&self, path: &Path) -> String {
        path.strip_prefix(&self.root)
            .unwrap_or(path)
            .display()
            .to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn escapes_are_refused() {
        let base = std::env::temp_dir().join(format!("datadir-test-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&base);
        let data = base.join("data");
        std::fs::create_dir_all(data.join("sets")).unwrap();
        std::fs::write(data.join("sets/m.csv"), "path\n").unwrap();
        std::fs::write(base.join("secret.csv"), "path\n").unwrap();
        #[cfg(unix)]
        std::os::unix::fs::symlink(base.join("secret.csv"), data.join("link.csv")).unwrap();
        let dir = DataDir::new(&data).unwrap();
        assert!(dir.existing("dataset", "sets/m.csv").is_ok());
        assert!(dir.existing("dataset", "./sets/m.csv").is_ok());
        for bad in [
            "",
            "/etc/passwd",
            "../secret.csv",
            "sets/../../secret.csv",
            "http://example.com/m.csv",
            "file:///etc/passwd",
            "missing.csv",
        ] {
            assert!(dir.existing("dataset", bad).is_err(), "{bad}");
        }
        #[cfg(unix)]
        assert!(
            dir.existing("dataset", "link.csv")
                .unwrap_err()
                .contains("outside")
        );
        assert!(dir.check_output("out", "renders/a").is_ok());
        assert!(!data.join("renders").exists(), "checking creates nothing");
        assert!(dir.check_output("out", "sets/m.csv").is_err());
        assert!(dir.output_dir("out", "renders/a").unwrap().is_dir());
        assert!(dir.output_dir("out", "../renders").is_err());
        assert!(dir.check_output("out", "../renders").is_err());
        let _ = std::fs::remove_dir_all(&base);
    }
}
