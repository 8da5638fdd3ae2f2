//! The model registry: `<root>/<name>/<version>/model.json` (+ `report.json`, plots).
//!
//! Versions are positive integers and immutable: a new version is written into a hidden
//! temporary directory, fsynced, then renamed into place, so a reader never sees a partial
//! version. `<root>/<name>/ACTIVE` holds the active version (written atomically); without
//! it the latest version is active.

use crate::model::{ModelError, ModelFile};
use crate::util::durable::{sync_dir, write_atomic};
use std::fs;
use std::path::{Path, PathBuf};

/// The model file's name in a version's folder: `ROOT/NAME/VERSION/model.json`.
pub const MODEL_FILE: &str = "model.json";
const ACTIVE_FILE: &str = "ACTIVE";

/// Why the registry cannot answer or change.
#[derive(Debug, thiserror::Error)]
pub enum RegistryError {
    /// A model name outside the safe alphabet ([`valid_name`]).
    #[error("invalid model name {0:?} (use 1–64 of a-z, 0-9, '_' and '-')")]
    BadName(String),
    /// No model of that name.
    #[error("unknown model {0:?}")]
    UnknownModel(String),
    /// The registry's folder does not exist.
    #[error(
        "there is no model folder {0} (a registry of models: FOLDER/NAME/VERSION/model.json, \
         such as models/ward6/1/model.json)"
    )]
    NoFolder(String),
    /// No model of that name in the registry, with the names it holds.
    #[error("unknown model {name:?} in {root} (it holds: {known})")]
    UnknownModelIn {
        /// The name asked for.
        name: String,
        /// The registry's folder.
        root: String,
        /// The names it holds, comma-separated.
        known: String,
    },
    /// The model has no such version.
    #[error("model {name:?} has no version {version}")]
    UnknownVersion {
        /// The model's name.
        name: String,
        /// The version asked for.
        version: u32,
    },
    /// The version is active and cannot be removed.
    #[error("version {version} of {name:?} is active; activate another version first")]
    ActiveVersion {
        /// The model's name.
        name: String,
        /// The active version.
        version: u32,
    },
    /// A file or folder cannot be read or written.
    #[error("{path}: {source}")]
    Io {
        /// Its path.
        path: String,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// A model file cannot be used.
    #[error("{path}: {source}")]
    Model {
        /// The model file's path.
        path: String,
        /// Why it cannot be used.
        source: ModelError,
    },
}

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> RegistryError + '_ {
    move |source| RegistryError::Io {
        path: path.display().to_string(),
        source,
    }
}

/// A model file's identity on disk ([`Registry::stamp`]): it changes when the file is
/// replaced or written to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Stamp {
    len: u64,
    modified: Option<std::time::SystemTime>,
    inode: u64,
}

impl Stamp {
    fn of(meta: &fs::Metadata) -> Stamp {
        #[cfg(unix)]
        let inode = std::os::unix::fs::MetadataExt::ino(meta);
        #[cfg(not(unix))]
        let inode = 0;
        Stamp {
            len: meta.len(),
            modified: meta.modified().ok(),
            inode,
        }
    }
}

/// Model names are path components: keep them to a safe alphabet.
pub fn valid_name(name: &str) -> bool {
    (1..=64).contains(&name.len())
        && name
            .bytes()
            .all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'_' || b == b'-')
}

/// [`valid_name`], as the registry refuses a name outside it.
pub fn check_name(name: &str) -> Result<(), RegistryError> {
    match valid_name(name) {
        true => Ok(()),
        false => Err(RegistryError::BadName(name.to_string())),
    }
}

/// A folder of model versions, `ROOT/NAME/VERSION/model.json`, with each name's active
/// version in `ROOT/NAME/ACTIVE` (docs/design.md §4).
#[derive(Clone, Debug)]
pub struct Registry {
    root: PathBuf,
}

impl Registry {
    /// The registry at `root` (nothing is read until asked).
    pub fn new(root: impl Into<PathBuf>) -> Registry {
        Registry { root: root.into() }
    }

    /// The registry's folder.
    pub fn root(&self) -> &Path {
        &self.root
    }

    fn model_dir(&self, name: &str) -> Result<PathBuf, RegistryError> {
        check_name(name)?;
        Ok(self.root.join(name))
    }

    /// The folder of a version (whether it exists or not), for a valid name.
    pub fn version_dir(&self, name: &str, version: u32) -> Result<PathBuf, RegistryError> {
        Ok(self.model_dir(name)?.join(version.to_string()))
    }

    /// Names with at least one version, sorted.
    pub fn names(&self) -> Result<Vec<String>, RegistryError> {
        let entries = match fs::read_dir(&self.root) {
            Ok(entries) => entries,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Vec::new()),
            Err(e) => return Err(io(&self.root)(e)),
        };
        let mut names: Vec<String> = entries
            .filter_map(|e| e.ok())
            .filter_map(|e| e.file_name().into_string().ok())
            .filter(|n| valid_name(n))
            .filter(|n| self.versions(n).is_ok_and(|v| !v.is_empty()))
            .collect();
        names.sort();
        Ok(names)
    }

    /// Complete versions of a model, ascending (hidden temporary directories are ignored).
    pub fn versions(&self, name: &str) -> Result<Vec<u32>, RegistryError> {
        let dir = self.model_dir(name)?;
        let entries = match fs::read_dir(&dir) {
            Ok(entries) => entries,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                return Err(match self.root.is_dir() {
                    true => RegistryError::UnknownModel(name.to_string()),
                    false => RegistryError::NoFolder(self.root.display().to_string()),
                });
            }
            Err(e) => return Err(io(&dir)(e)),
        };
        let mut versions: Vec<u32> = entries
            .filter_map(|e| e.ok())
            .filter_map(|e| e.file_name().to_str().and_then(|n| n.parse::<u32>().ok()))
            .filter(|&v| v > 0 && dir.join(v.to_string()).join(MODEL_FILE).is_file())
            .collect();
        versions.sort_unstable();
        Ok(versions)
    }

    /// The active version: `ACTIVE` if it names an existing version, else the latest.
    pub fn active(&self, name: &str) -> Result<u32, RegistryError> {
        let versions = self.versions(name)?;
        let pinned = fs::read_to_string(self.model_dir(name)?.join(ACTIVE_FILE))
            .ok()
            .and_then(|t| t.trim().parse::<u32>().ok())
            .filter(|v| versions.contains(v));
        pinned
            .or(versions.last().copied())
            .ok_or_else(|| RegistryError::UnknownModel(name.to_string()))
    }

    /// What `ACTIVE` says: `Ok(None)` without the file, `Err` when it cannot be read or does
    /// not hold a version number (being replaced, or written by hand), whether or not the
    /// version it names exists.
    pub fn pinned(&self, name: &str) -> Result<Option<u32>, RegistryError> {
        let path = self.model_dir(name)?.join(ACTIVE_FILE);
        match fs::read_to_string(&path) {
            Ok(text) => text.trim().parse::<u32>().map(Some).map_err(|_| {
                let source = std::io::Error::new(
                    std::io::ErrorKind::InvalidData,
                    format!("not a version number: {:?}", text.trim()),
                );
                io(&path)(source)
            }),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
            Err(e) => Err(io(&path)(e)),
        }
    }

    /// The identity of a version's model file as the file system gives it (size, change
    /// time, inode): two looks at the registry compare it instead of reading the file again.
    pub fn stamp(&self, name: &str, version: u32) -> Result<Stamp, RegistryError> {
        let path = self.version_dir(name, version)?.join(MODEL_FILE);
        let meta = fs::metadata(&path).map_err(io(&path))?;
        Ok(Stamp::of(&meta))
    }

    /// Record `version` as active (atomically).
    pub fn set_active(&self, name: &str, version: u32) -> Result<(), RegistryError> {
        self.require(name, version)?;
        let path = self.model_dir(name)?.join(ACTIVE_FILE);
        write_atomic(&path, format!("{version}\n").as_bytes()).map_err(io(&path))
    }

    fn require(&self, name: &str, version: u32) -> Result<(), RegistryError> {
        if self.versions(name)?.contains(&version) {
            Ok(())
        } else {
            Err(RegistryError::UnknownVersion {
                name: name.to_string(),
                version,
            })
        }
    }

    /// Read and verify a version's model file.
    pub fn load(&self, name: &str, version: u32) -> Result<ModelFile, RegistryError> {
        self.require(name, version)?;
        let path = self.version_dir(name, version)?.join(MODEL_FILE);
        let bytes = fs::read(&path).map_err(io(&path))?;
        let model = ModelFile::from_json(&bytes).map_err(|source| RegistryError::Model {
            path: path.display().to_string(),
            source,
        });
        drop(bytes);
        let model = model?;
        if model.name != name || model.version != version {
            return Err(RegistryError::Model {
                path: path.display().to_string(),
                source: ModelError::Inconsistent(format!(
                    "the file is {} version {}, stored as {name} version {version}",
                    model.name, model.version
                )),
            });
        }
        Ok(model)
    }

    /// Write `model` (plus extra files, e.g. `report.json`) as the next version of its
    /// name; returns the version and its directory. The version number is assigned here.
    pub fn publish(
        &self,
        model: &mut ModelFile,
        extra: &[(&str, &[u8])],
    ) -> Result<(u32, PathBuf), RegistryError> {
        let dir = self.model_dir(&model.name)?;
        fs::create_dir_all(&dir).map_err(io(&dir))?;
        // Past a folder that holds this number without being a complete version (a
        // version being written in place, or left half-written): the listing alone would
        // give the same number again and again.
        let mut floor = 1;
        loop {
            let version = match self.versions(&model.name) {
                Ok(v) => v.last().copied().unwrap_or(0) + 1,
                Err(RegistryError::UnknownModel(_)) => 1,
                Err(e) => return Err(e),
            }
            .max(floor);
            model.version = version;
            let staging = crate::util::durable::temp_path(&dir.join(version.to_string()));
            let written = self.stage(&staging, model, extra);
            if let Err(e) = written {
                let _ = fs::remove_dir_all(&staging);
                return Err(e);
            }
            crate::util::durable::test_pause("publish");
            let target = dir.join(version.to_string());
            match fs::rename(&staging, &target) {
                Ok(()) => {
                    sync_dir(&dir).map_err(io(&dir))?;
                    return Ok((version, target));
                }
                // Another writer took this number first: try the next one.
                Err(_) if target.exists() => {
                    let _ = fs::remove_dir_all(&staging);
                    floor = version + 1;
                }
                Err(e) => {
                    let _ = fs::remove_dir_all(&staging);
                    return Err(io(&target)(e));
                }
            }
        }
    }

    fn stage(
        &self,
        staging: &Path,
        model: &mut ModelFile,
        extra: &[(&str, &[u8])],
    ) -> Result<(), RegistryError> {
        fs::create_dir_all(staging).map_err(io(staging))?;
        let bytes = model.to_json().map_err(|source| RegistryError::Model {
            path: staging.display().to_string(),
            source,
        })?;
        let files = std::iter::once((MODEL_FILE, bytes.as_slice())).chain(extra.iter().copied());
        for (file, content) in files {
            let path = staging.join(file);
            write_atomic(&path, content).map_err(io(&path))?;
        }
        sync_dir(staging).map_err(io(staging))
    }

    /// Remove an inactive version.
    pub fn delete(&self, name: &str, version: u32) -> Result<(), RegistryError> {
        self.require(name, version)?;
        if self.active(name)? == version {
            return Err(RegistryError::ActiveVersion {
                name: name.to_string(),
                version,
            });
        }
        let dir = self.version_dir(name, version)?;
        // Rename first so the version disappears atomically, then remove the files.
        let doomed = crate::util::durable::temp_path(&dir);
        fs::rename(&dir, &doomed).map_err(io(&dir))?;
        fs::remove_dir_all(&doomed).map_err(io(&doomed))
    }

    /// Leftovers of interrupted writes, removed at start-up: hidden temporary directories
    /// (a version being staged or deleted) and files (an `ACTIVE` being replaced).
    pub fn clean_staging(&self) -> Result<usize, RegistryError> {
        let mut removed = 0;
        for name in self.names_including_empty()? {
            let dir = self.root.join(&name);
            for entry in fs::read_dir(&dir).map_err(io(&dir))?.filter_map(|e| e.ok()) {
                let hidden = entry
                    .file_name()
                    .to_str()
                    .is_some_and(|n| n.starts_with('.') && n.contains(".tmp-"));
                if !hidden {
                    continue;
                }
                let path = entry.path();
                if path.is_dir() {
                    fs::remove_dir_all(&path).map_err(io(&path))?;
                } else {
                    fs::remove_file(&path).map_err(io(&path))?;
                }
                removed += 1;
            }
        }
        Ok(removed)
    }

    fn names_including_empty(&self) -> Result<Vec<String>, RegistryError> {
        match fs::read_dir(&self.root) {
            Ok(entries) => Ok(entries
                .filter_map(|e| e.ok())
                .filter(|e| e.path().is_dir())
                .filter_map(|e| e.file_name().into_string().ok())
                .filter(|n| valid_name(n))
                .collect()),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(Vec::new()),
            Err(e) => Err(io(&self.root)(e)),
        }
    }
}

/// `DIR/NAME` or `DIR/NAME/VERSION` (as `predict --model` takes it): registry, name and
/// the explicit version, if any.
pub fn parse_model_path(path: &Path) -> Result<(Registry, String, Option<u32>), RegistryError> {
    let last = path
        .file_name()
        .and_then(|n| n.to_str())
        .unwrap_or_default();
    // `ward6` alone: a folder here (its parent is the empty path).
    let here = |p: &Path| p.as_os_str().is_empty();
    let parent = path.parent().filter(|p| !here(p)).unwrap_or(Path::new("."));
    if let Ok(version) = last.parse::<u32>() {
        let name = parent
            .file_name()
            .and_then(|n| n.to_str())
            .unwrap_or_default();
        let root = parent
            .parent()
            .filter(|p| !here(p))
            .unwrap_or(Path::new("."));
        if valid_name(name) {
            return Ok((Registry::new(root), name.to_string(), Some(version)));
        }
    }
    if !valid_name(last) {
        return Err(RegistryError::BadName(last.to_string()));
    }
    Ok((Registry::new(parent), last.to_string(), None))
}

/// The model a command line names: `DIR/NAME` (its active version) or `DIR/NAME/VERSION`,
/// loaded and verified.
pub fn load_path(path: &Path) -> Result<ModelFile, RegistryError> {
    let (registry, name, version) = parse_model_path(path)?;
    let version = match version {
        Some(v) => v,
        None => registry.active(&name).map_err(|e| match e {
            RegistryError::UnknownModel(name) => RegistryError::UnknownModelIn {
                name,
                root: registry.root().display().to_string(),
                known: registry.names().unwrap_or_default().join(", "),
            },
            other => other,
        })?,
    };
    registry.load(&name, version)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_safe_path_components() {
        for ok in ["ward6", "ward-11", "a_b"] {
            assert!(valid_name(ok), "{ok}");
        }
        for bad in ["", "..", "a/b", "Ward6", "a b", ".hidden", &"x".repeat(65)] {
            assert!(!valid_name(bad), "{bad}");
        }
    }

    /// A registry holding a copy of the shipped `ward6` version 1.
    fn scratch(name: &str) -> (PathBuf, Registry) {
        let root = std::env::temp_dir().join(format!("registry-{name}-{}", std::process::id()));
        let _ = fs::remove_dir_all(&root);
        let shipped = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models/ward6/1");
        fs::create_dir_all(root.join("ward6/1")).unwrap();
        fs::copy(
            shipped.join(MODEL_FILE),
            root.join("ward6/1").join(MODEL_FILE),
        )
        .unwrap();
        (root.clone(), Registry::new(root))
    }

    #[test]
    fn pinned_is_what_active_says() {
        let (root, registry) = scratch("pinned");
        assert_eq!(registry.pinned("ward6").unwrap(), None);
        fs::write(root.join("ward6/ACTIVE"), "7\n").unwrap();
        // Named even though there is no version 7 (yet): `active` falls back, `pinned` tells.
        assert_eq!(registry.pinned("ward6").unwrap(), Some(7));
        assert_eq!(registry.active("ward6").unwrap(), 1);
        fs::write(root.join("ward6/ACTIVE"), "seven").unwrap();
        assert!(matches!(
            registry.pinned("ward6"),
            Err(RegistryError::Io { .. })
        ));
        fs::remove_dir_all(&root).unwrap();
    }

    #[test]
    fn a_stamp_changes_with_the_file_only() {
        let (root, registry) = scratch("stamp");
        let before = registry.stamp("ward6", 1).unwrap();
        let _ = registry.load("ward6", 1).unwrap();
        assert_eq!(
            registry.stamp("ward6", 1).unwrap(),
            before,
            "reading leaves it"
        );
        let path = root.join("ward6/1").join(MODEL_FILE);
        let bytes = fs::read(&path).unwrap();
        crate::util::durable::write_atomic(&path, &bytes).unwrap();
        assert_ne!(
            registry.stamp("ward6", 1).unwrap(),
            before,
            "the same bytes, replaced"
        );
        assert!(registry.stamp("ward6", 2).is_err());
        fs::remove_dir_all(&root).unwrap();
    }

    #[test]
    fn publish_goes_past_a_folder_being_written() {
        let (root, registry) = scratch("past");
        // Version 2's folder, its model file not there yet: not a version, and not taken over.
        fs::create_dir_all(root.join("ward6/2")).unwrap();
        fs::write(root.join("ward6/2/report.json"), b"{}").unwrap();
        assert_eq!(registry.versions("ward6").unwrap(), [1]);
        let mut model = registry.load("ward6", 1).unwrap();
        let (version, dir) = registry.publish(&mut model, &[]).unwrap();
        assert_eq!((version, dir), (3, root.join("ward6/3")));
        assert_eq!(registry.versions("ward6").unwrap(), [1, 3]);
        assert_eq!(registry.load("ward6", 3).unwrap().version, 3);
        assert!(root.join("ward6/2/report.json").is_file());
        fs::remove_dir_all(&root).unwrap();
    }

    #[test]
    fn model_paths() {
        let (r, n, v) = parse_model_path(Path::new("models/ward6/3")).unwrap();
        assert_eq!(
            (r.root(), n.as_str(), v),
            (Path::new("models"), "ward6", Some(3))
        );
        let (r, n, v) = parse_model_path(Path::new("/srv/models/ward11")).unwrap();
        assert_eq!(
            (r.root(), n.as_str(), v),
            (Path::new("/srv/models"), "ward11", None)
        );
        assert!(parse_model_path(Path::new("models/../..")).is_err());
    }
}
