//! Datasets uploaded over HTTP (`/admin/v1/datasets`), kept under
//! `<data-dir>/datasets/<name>/`: the images, `manifest.csv` (every usable row with its
//! circle) and `dataset.json` (what the upload answered).
//!
//! **Atomic.** An upload is received, unpacked and checked in
//! `<data-dir>/datasets/.incoming/<id>/`, then its folder is renamed into place: a dataset
//! is either whole or absent, and a failure (a refused archive, a full disk, a request
//! that timed out) leaves nothing behind. Leftovers of a crash are removed at start-up.

use super::config::DatasetLimits;
use super::error::{ApiError, Kind};
use super::jobs::JobManager;
use crate::archive;
use reflectance_core::dataset::ingest::{self, Coverage, Refusal};
use reflectance_core::dataset::{self, read_manifest};
use reflectance_core::decode::DecodeOptions;
use reflectance_core::util::durable::write_atomic;
use reflectance_core::util::progress::Observer;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};
use utoipa::ToSchema;

const INCOMING: &str = ".incoming";
const MANIFEST: &str = "manifest.csv";
const INFO: &str = "dataset.json";

/// A stored dataset, as its upload answered.
#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct DatasetInfo {
    pub name: String,
    /// The value to give as `dataset` in a `train` or `cross_validate` job (relative to
    /// the data directory).
    #[schema(example = "datasets/my-spheres/manifest.csv")]
    pub dataset: String,
    pub created: String,
    /// Usable images, each with its circle.
    pub images: usize,
    /// How many of them had no circle in the manifest and were located on upload.
    pub located: usize,
    /// Archive members and manifest rows that were not kept, with the reason.
    pub refused: Vec<RefusalDoc>,
    pub classes: Vec<String>,
    pub illuminations: Vec<String>,
}

/// Something of the archive that was not kept.
#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct RefusalDoc {
    /// The member's path in the archive, or the manifest row's path.
    pub path: String,
    pub reason: String,
}

impl From<Refusal> for RefusalDoc {
    fn from(r: Refusal) -> RefusalDoc {
        RefusalDoc {
            path: r.path,
            reason: r.reason,
        }
    }
}

/// One row of a stored manifest.
#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct ManifestRow {
    pub path: String,
    pub class: String,
    pub illumination: String,
    pub cx: f64,
    pub cy: f64,
    pub r: f64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub white: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub encoding: Option<String>,
}

/// A dataset with its manifest.
#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct DatasetDetail {
    #[serde(flatten)]
    pub info: DatasetInfo,
    pub manifest: Vec<ManifestRow>,
}

#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct DatasetList {
    /// By name.
    pub datasets: Vec<DatasetInfo>,
}

/// The datasets folder of the data directory.
pub struct DatasetStore {
    /// `<data-dir>/datasets`.
    dir: PathBuf,
    limits: DatasetLimits,
    /// Held while a name is checked and taken, or a dataset removed.
    names: Mutex<()>,
}

/// An upload in progress: its folder under `.incoming`, removed when dropped (whatever
/// the outcome), and a flag the request sets when it is abandoned (a timeout, a client
/// gone) so that the checking stops and nothing is published.
pub struct Incoming {
    dir: PathBuf,
    abandoned: Arc<AtomicBool>,
}

impl Incoming {
    /// The file the archive is received into.
    pub fn archive(&self) -> PathBuf {
        self.dir.join("archive")
    }

    fn files(&self) -> PathBuf {
        self.dir.join("files")
    }

    /// Sets the flag when dropped: held by the request while the checking runs elsewhere.
    pub fn abandon_on_drop(&self) -> AbandonOnDrop {
        AbandonOnDrop(self.abandoned.clone())
    }
}

impl Drop for Incoming {
    fn drop(&mut self) {
        if let Err(e) = std::fs::remove_dir_all(&self.dir)
            && e.kind() != std::io::ErrorKind::NotFound
        {
            tracing::warn!(error = %e, dir = %self.dir.display(), "could not remove an upload's leftovers");
        }
    }
}

pub struct AbandonOnDrop(Arc<AtomicBool>);

impl Drop for AbandonOnDrop {
    fn drop(&mut self) {
        self.0.store(true, Ordering::Relaxed);
    }
}

impl Observer for Incoming {
    fn cancelled(&self) -> bool {
        self.abandoned.load(Ordering::Relaxed)
    }
}

fn storage(e: &std::io::Error, what: &str) -> ApiError {
    ApiError::storage(e, format!("cannot store the dataset ({what}): {e}"))
}

fn not_found(name: &str) -> ApiError {
    ApiError::new(Kind::DatasetNotFound, format!("no dataset named {name:?}"))
}

/// A dataset name: what model names may be.
pub fn check_name(name: &str) -> Result<(), ApiError> {
    if reflectance_core::model::registry::valid_name(name) {
        Ok(())
    } else {
        Err(ApiError::new(
            Kind::InvalidField,
            format!("invalid dataset name {name:?} (use 1–64 of a-z, 0-9, '_' and '-')"),
        ))
    }
}

impl DatasetStore {
    /// The store under `data_dir`, with an interrupted upload's leftovers removed. The
    /// folder is made when first needed: a read-only data directory still serves the
    /// rest, and an upload to it is refused with 503.
    pub fn open(data_dir: &Path, limits: DatasetLimits) -> DatasetStore {
        let dir = data_dir.join(super::config::defaults::DATASETS_SUBDIR);
        match std::fs::remove_dir_all(dir.join(INCOMING)) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                tracing::warn!(error = %e, "could not remove the leftovers of interrupted uploads");
            }
            _ => {}
        }
        DatasetStore {
            dir,
            limits,
            names: Mutex::new(()),
        }
    }

    pub fn limits(&self) -> DatasetLimits {
        self.limits
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, ()> {
        self.names.lock().unwrap_or_else(|e| e.into_inner())
    }

    fn folder(&self, name: &str) -> PathBuf {
        self.dir.join(name)
    }

    /// The folder relative to the data directory, as jobs name it.
    fn relative(name: &str) -> PathBuf {
        Path::new(super::config::defaults::DATASETS_SUBDIR).join(name)
    }

    /// 409 when `name` is taken.
    pub fn check_free(&self, name: &str) -> Result<(), ApiError> {
        check_name(name)?;
        if self.folder(name).exists() {
            return Err(ApiError::new(
                Kind::DatasetExists,
                format!("a dataset named {name:?} exists; delete it first or choose another name"),
            ));
        }
        Ok(())
    }

    /// A new upload's folder.
    pub fn incoming(&self) -> Result<Incoming, ApiError> {
        let dir = self.dir.join(INCOMING).join(super::jobs::new_id());
        std::fs::create_dir_all(dir.join("files")).map_err(|e| storage(&e, "incoming folder"))?;
        Ok(Incoming {
            dir,
            abandoned: Arc::new(AtomicBool::new(false)),
        })
    }

    /// Unpack and check a received archive, then publish it as `name`. Blocking.
    pub fn create(
        &self,
        name: &str,
        incoming: &Incoming,
        decode: &DecodeOptions,
    ) -> Result<DatasetInfo, ApiError> {
        let files = incoming.files();
        let unpacked = archive::unpack(&incoming.archive(), &files, self.limits.archive)?;
        std::fs::remove_file(incoming.archive()).map_err(|e| storage(&e, "archive"))?;
        if !unpacked.files.contains(MANIFEST) {
            return Err(ApiError::new(
                Kind::UnusableDataset,
                "the archive has no manifest.csv at its root (columns path,class,illumination[,cx,cy,r,white,encoding])",
            ));
        }
        let manifest = read_manifest(&files.join(MANIFEST)).map_err(|e| {
            ApiError::new(Kind::UnusableDataset, strip_folder(&e.to_string(), &files))
        })?;
        let checked = ingest::ingest(&manifest, decode, incoming).map_err(|e| match e {
            dataset::DatasetError::Cancelled => {
                ApiError::new(Kind::Timeout, "the upload was abandoned")
            }
            other => ApiError::internal(other),
        })?;
        let mut refused: Vec<RefusalDoc> = unpacked.refused.into_iter().map(Into::into).collect();
        refused.extend(checked.refused.into_iter().map(RefusalDoc::from));
        let coverage = Coverage::of(&checked.entries);
        if checked.entries.is_empty() {
            return Err(unusable("no image of the archive is usable", &refused));
        }
        if let Some(problem) = coverage.loio_problem() {
            return Err(unusable(&problem, &refused));
        }
        write_atomic(
            &files.join(MANIFEST),
            &ingest::manifest_csv(&checked.entries),
        )
        .map_err(|e| storage(&e, "manifest"))?;
        remove_unlisted(&files, &unpacked.files, &checked.entries);
        let info = DatasetInfo {
            name: name.to_string(),
            dataset: Self::relative(name).join(MANIFEST).display().to_string(),
            created: reflectance_core::model::now_rfc3339(),
            images: checked.entries.len(),
            located: checked.located,
            refused,
            classes: coverage.classes(),
            illuminations: coverage.illuminations(),
        };
        let json = serde_json::to_vec_pretty(&info).map_err(ApiError::internal)?;
        write_atomic(&files.join(INFO), &json).map_err(|e| storage(&e, "dataset.json"))?;
        if incoming.cancelled() {
            return Err(ApiError::new(Kind::Timeout, "the upload was abandoned"));
        }
        let _names = self.lock();
        self.check_free(name)?;
        std::fs::rename(&files, self.folder(name)).map_err(|e| storage(&e, "rename"))?;
        tracing::info!(dataset = %name, images = info.images, refused = info.refused.len(), "dataset stored");
        Ok(info)
    }

    fn info(&self, name: &str) -> Result<DatasetInfo, ApiError> {
        check_name(name).map_err(|_| not_found(name))?;
        let text = match std::fs::read(self.folder(name).join(INFO)) {
            Ok(text) => text,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Err(not_found(name)),
            Err(e) => return Err(ApiError::internal(e)),
        };
        serde_json::from_slice(&text).map_err(ApiError::internal)
    }

    /// Every dataset, by name.
    pub fn list(&self) -> Result<DatasetList, ApiError> {
        let entries = match std::fs::read_dir(&self.dir) {
            Ok(entries) => entries,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                return Ok(DatasetList { datasets: vec![] });
            }
            Err(e) => return Err(ApiError::internal(e)),
        };
        let mut names: Vec<String> = entries
            .filter_map(|e| e.ok()?.file_name().into_string().ok())
            .filter(|n| reflectance_core::model::registry::valid_name(n))
            .collect();
        names.sort();
        let datasets = names.iter().filter_map(|n| self.info(n).ok()).collect();
        Ok(DatasetList { datasets })
    }

    /// One dataset with its manifest.
    pub fn get(&self, name: &str) -> Result<DatasetDetail, ApiError> {
        let info = self.info(name)?;
        let manifest =
            read_manifest(&self.folder(name).join(MANIFEST)).map_err(ApiError::internal)?;
        let manifest = manifest
            .entries
            .into_iter()
            .filter_map(|e| {
                let c = e.circle?;
                Some(ManifestRow {
                    path: e.path,
                    class: e.class?,
                    illumination: e.illumination?,
                    cx: c.cx,
                    cy: c.cy,
                    r: c.r,
                    white: e.white,
                    encoding: e.encoding.map(|x| x.to_string()),
                })
            })
            .collect();
        Ok(DatasetDetail { info, manifest })
    }

    /// Remove a dataset; 409 while a queued or running job uses it.
    pub fn delete(&self, name: &str, jobs: &JobManager) -> Result<(), ApiError> {
        let _names = self.lock();
        self.info(name)?;
        if let Some(job) = jobs.user_of(&Self::relative(name)) {
            return Err(ApiError::new(
                Kind::DatasetInUse,
                format!("job {job} uses dataset {name:?}; cancel it or wait until it ends"),
            ));
        }
        // Out of sight at once (a job submitted from now on is refused: the path is gone),
        // then removed.
        let doomed = self
            .dir
            .join(INCOMING)
            .join(format!("deleted-{}", super::jobs::new_id()));
        std::fs::create_dir_all(self.dir.join(INCOMING))
            .and_then(|()| std::fs::rename(self.folder(name), &doomed))
            .map_err(|e| storage(&e, "delete"))?;
        if let Err(e) = std::fs::remove_dir_all(&doomed) {
            tracing::warn!(error = %e, "a deleted dataset's files remain until the next start");
        }
        tracing::info!(dataset = %name, "dataset deleted");
        Ok(())
    }
}

/// A dataset nothing can be learned from (422), naming the first refusals.
fn unusable(why: &str, refused: &[RefusalDoc]) -> ApiError {
    const SHOWN: usize = 5;
    let mut detail = why.to_string();
    if !refused.is_empty() {
        let first: Vec<String> = refused
            .iter()
            .take(SHOWN)
            .map(|r| format!("{}: {}", r.path, r.reason))
            .collect();
        detail.push_str(&format!(
            "; refused ({}): {}",
            refused.len(),
            first.join("; ")
        ));
        if refused.len() > SHOWN {
            detail.push_str("; …");
        }
    }
    ApiError::new(Kind::UnusableDataset, detail)
}

/// Error texts name files by their path in the archive, not in the server's folders.
fn strip_folder(text: &str, folder: &Path) -> String {
    text.replace(&format!("{}/", folder.display()), "")
}

/// Remove what the archive held besides the manifest and the images kept.
fn remove_unlisted(
    files: &Path,
    unpacked: &std::collections::BTreeSet<String>,
    kept: &[dataset::Entry],
) {
    let listed: std::collections::BTreeSet<PathBuf> = kept.iter().map(|e| e.file.clone()).collect();
    for rel in unpacked {
        let path = files.join(rel);
        if rel != MANIFEST && !listed.contains(&path) {
            let _ = std::fs::remove_file(&path);
        }
    }
}
