//! Confinement of job paths to the data directory: a job names its inputs and outputs by
//! paths relative to `--data-dir`. Absolute paths, `..` components, URLs and symlinks that
//! resolve outside the data directory are refused.

use std::path::{Component, Path, PathBuf};

/// A job's path refused, or the data directory unusable: the message names the job's field
/// and its path as given.
#[derive(Debug, thiserror::Error)]
pub enum PathError {
    #[error("data directory {dir}: {source}")]
    DataDir { dir: String, source: std::io::Error },
    #[error("{what} {rel:?}: {why}")]
    Refused {
        what: String,
        rel: String,
        why: &'static str,
    },
    #[error("{what} {rel:?}: {source}")]
    Unreadable {
        what: String,
        rel: String,
        source: std::io::Error,
    },
    /// A path found inside a dataset, shown as it resolved.
    #[error("{what} {path}: {source}")]
    Unresolved {
        what: String,
        path: String,
        source: std::io::Error,
    },
    #[error("{what} {rel:?}: not a directory")]
    NotADirectory { what: String, rel: String },
    #[error("{what} {rel:?} resolves outside the data directory")]
    Outside { what: String, rel: String },
}

fn unreadable(what: &str, rel: &str) -> impl FnOnce(std::io::Error) -> PathError {
    let (what, rel) = (what.to_string(), rel.to_string());
    move |source| PathError::Unreadable { what, rel, source }
}

#[derive(Debug, Clone)]
pub struct DataDir {
    /// Canonical (symlinks resolved) absolute path.
    root: PathBuf,
}

impl DataDir {
    pub fn new(dir: &Path) -> Result<DataDir, PathError> {
        std::fs::create_dir_all(dir)
            .and_then(|()| dir.canonicalize())
            .map(|root| DataDir { root })
            .map_err(|source| PathError::DataDir {
                dir: dir.display().to_string(),
                source,
            })
    }

    pub fn root(&self) -> &Path {
        &self.root
    }

    /// Syntactic checks: non-empty, relative, no `..`, not a URL.
    fn relative<'a>(&self, what: &str, rel: &'a str) -> Result<&'a Path, PathError> {
        let refuse = |why: &'static str| {
            Err(PathError::Refused {
                what: what.to_string(),
                rel: rel.to_string(),
                why,
            })
        };
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
    pub fn existing(&self, what: &str, rel: &str) -> Result<PathBuf, PathError> {
        let path = self.relative(what, rel)?;
        let full = self.root.join(path);
        let canonical = full.canonicalize().map_err(unreadable(what, rel))?;
        self.inside(what, rel, canonical)
    }

    /// A directory inside the data directory, created if missing.
    pub fn output_dir(&self, what: &str, rel: &str) -> Result<PathBuf, PathError> {
        self.check_output(what, rel)?;
        let full = self.root.join(rel);
        std::fs::create_dir_all(&full).map_err(unreadable(what, rel))?;
        let canonical = full.canonicalize().map_err(unreadable(what, rel))?;
        if !canonical.is_dir() {
            return Err(PathError::NotADirectory {
                what: what.to_string(),
                rel: rel.to_string(),
            });
        }
        self.inside(what, rel, canonical)
    }

    /// Whether [`DataDir::output_dir`] may create (or reuse) `rel`, without creating it:
    /// the deepest existing ancestor must resolve inside the data directory, so that
    /// creating the rest cannot follow a symlink out of it.
    pub fn check_output(&self, what: &str, rel: &str) -> Result<(), PathError> {
        let path = self.relative(what, rel)?;
        let mut existing = self.root.join(path);
        while !existing.exists() {
            match existing.parent() {
                Some(parent) => existing = parent.to_path_buf(),
                None => break,
            }
        }
        let canonical = existing.canonicalize().map_err(unreadable(what, rel))?;
        let canonical = self.inside(what, rel, canonical)?;
        if canonical == self.root.join(path) && !canonical.is_dir() {
            return Err(PathError::NotADirectory {
                what: what.to_string(),
                rel: rel.to_string(),
            });
        }
        Ok(())
    }

    /// A path found inside a dataset (a manifest row, a probe list entry) must also stay
    /// inside the data directory.
    pub fn check_resolved(&self, what: &str, path: &Path) -> Result<(), PathError> {
        let canonical = path
            .canonicalize()
            .map_err(|source| PathError::Unresolved {
                what: what.to_string(),
                path: path.display().to_string(),
                source,
            })?;
        self.inside(what, &path.display().to_string(), canonical)
            .map(|_| ())
    }

    fn inside(&self, what: &str, rel: &str, canonical: PathBuf) -> Result<PathBuf, PathError> {
        if canonical.starts_with(&self.root) {
            Ok(canonical)
        } else {
            Err(PathError::Outside {
                what: what.to_string(),
                rel: rel.to_string(),
            })
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
        assert!(matches!(
            dir.existing("dataset", "link.csv"),
            Err(PathError::Outside { .. })
        ));
        assert!(dir.check_output("out", "renders/a").is_ok());
        assert!(!data.join("renders").exists(), "checking creates nothing");
        assert!(dir.check_output("out", "sets/m.csv").is_err());
        assert!(dir.output_dir("out", "renders/a").unwrap().is_dir());
        assert!(dir.output_dir("out", "../renders").is_err());
        assert!(dir.check_output("out", "../renders").is_err());
        let _ = std::fs::remove_dir_all(&base);
    }
}
