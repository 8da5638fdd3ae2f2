//! The model store: the active version of every model, loaded from the registry, swapped
//! atomically on activation or when a look at the registry ([`ModelStore::poll`]) finds
//! another version to serve, with a small cache of other versions.

use super::metrics;
use reflectance_core::inference::LoadedModel;
use reflectance_core::model::ModelError;
use reflectance_core::model::registry::{Registry, RegistryError, Stamp};
use std::collections::BTreeMap;
use std::sync::{Arc, Mutex, RwLock};
use std::time::SystemTime;

/// Why the store cannot give, activate or delete a version: the registry refuses (an
/// unknown model or version, the active version, its files), or the version's file is
/// refused (`server::error` maps it to HTTP).
#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    #[error(transparent)]
    Registry(#[from] RegistryError),
    #[error(transparent)]
    Model(#[from] ModelError),
    /// A name the server does not serve, with the names it does.
    #[error("unknown model {name:?} (this server serves: {served})")]
    Unserved { name: String, served: String },
}

/// Count and log a version refused for its files (schema, checksum, self-test, I/O); an
/// unknown model or version is the caller's mistake, not counted.
fn count_refusal(name: &str, version: u32, e: &StoreError) {
    let files = matches!(
        e,
        StoreError::Model(_)
            | StoreError::Registry(RegistryError::Model { .. } | RegistryError::Io { .. })
    );
    if files {
        metrics::model_load_failure(name);
        tracing::warn!(model = name, version, error = %e, "model version refused");
    }
}

/// Outcome of an activation.
#[derive(Debug)]
pub struct Activated {
    pub previous: Option<u32>,
    /// Set when the choice could not be written to the registry (read-only models folder):
    /// it holds in memory until the process restarts.
    pub warning: Option<String>,
}

/// A served version: the model, when this process loaded it, and its file's identity when
/// it was read (`None`: unknown, read again at the next look at the registry).
#[derive(Clone, Debug)]
pub struct Served {
    pub model: Arc<LoadedModel>,
    pub loaded: SystemTime,
    stamp: Option<Stamp>,
}

/// What one look at the registry ([`ModelStore::poll`]) changed.
#[derive(Debug, Default, PartialEq, Eq)]
pub struct Polled {
    /// Versions swapped in (model, version).
    pub swapped: Vec<(String, u32)>,
    /// Versions that failed to load (model, version): the previous ones serve.
    pub refused: Vec<(String, u32)>,
    /// Models with no version left, no longer served.
    pub removed: Vec<String>,
}

/// The active version of every model, swapped atomically: a request clones the `Arc` of
/// the version it started with and finishes on it, whatever is activated meanwhile.
#[derive(Debug)]
pub struct ModelStore {
    registry: Registry,
    active: RwLock<BTreeMap<String, Served>>,
    /// Versions that failed to load, with their file's identity then: a look at the registry
    /// tries one again only once its file has changed.
    refused: Mutex<BTreeMap<(String, u32), Option<Stamp>>>,
    /// Recently used non-active versions (`?version=`), most recent last.
    cache: Mutex<Vec<Arc<LoadedModel>>>,
    cache_size: usize,
    /// Serializes activations so that load-verify-swap-persist happen as one step.
    activation: Mutex<()>,
}

impl ModelStore {
    pub fn new(registry: Registry, cache_size: usize) -> ModelStore {
        ModelStore {
            registry,
            active: RwLock::new(BTreeMap::new()),
            refused: Mutex::new(BTreeMap::new()),
            cache: Mutex::new(Vec::new()),
            cache_size,
            activation: Mutex::new(()),
        }
    }

    pub fn registry(&self) -> &Registry {
        &self.registry
    }

    /// Load (and verify) a version from the registry. Blocking. A version whose files are
    /// refused is counted in `reflectance_model_load_failures_total`.
    pub fn load_version(&self, name: &str, version: u32) -> Result<LoadedModel, StoreError> {
        self.read_version(name, version)
            .inspect_err(|e| count_refusal(name, version, e))
    }

    /// [`Self::load_version`] without counting a failure.
    fn read_version(&self, name: &str, version: u32) -> Result<LoadedModel, StoreError> {
        let file = self.registry.load(name, version);
        // Reading a model file takes several times its size, briefly: give that back.
        crate::heap::release_free();
        Ok(LoadedModel::new(file?)?)
    }

    /// The checks of an activation, uncounted: the file's schema and checksum (read and
    /// verified by the registry), then the self-test.
    fn read_checked(&self, name: &str, version: u32) -> Result<LoadedModel, StoreError> {
        let model = self.read_version(name, version)?;
        model.file().self_test()?;
        Ok(model)
    }

    /// Load the active version of every model in the registry. Blocking. When the active
    /// version (the `ACTIVE` one, else the newest) does not load, the newest version that
    /// does is served instead — in memory only: the registry's record is left as it is —
    /// with an error in the log and `reflectance_model_fallbacks_total` counting it.
    /// Returns the models of which no version loads (name, reason); they are not served.
    pub fn load_all(&self) -> Result<Vec<(String, String)>, RegistryError> {
        let mut failed = Vec::new();
        for name in self.registry.names()? {
            let wanted = match self.registry.active(&name) {
                Ok(v) => v,
                Err(e) => {
                    failed.push((name, e.to_string()));
                    continue;
                }
            };
            let stamp = self.registry.stamp(&name, wanted).ok();
            let reason = match self.load_version(&name, wanted) {
                Ok(model) => {
                    self.install(Arc::new(model), stamp);
                    continue;
                }
                Err(e) => {
                    self.refuse(&name, wanted, stamp);
                    e.to_string()
                }
            };
            let mut others = self.registry.versions(&name).unwrap_or_default();
            others.retain(|&v| v != wanted);
            let fallback = others.iter().rev().find_map(|&v| {
                let stamp = self.registry.stamp(&name, v).ok();
                self.load_version(&name, v).ok().map(|m| (m, stamp))
            });
            match fallback {
                Some((model, stamp)) => {
                    tracing::error!(
                        model = %name,
                        wanted,
                        served = model.version(),
                        %reason,
                        "active version does not load: serving the newest version that does"
                    );
                    metrics::model_fallback(&name);
                    self.install(Arc::new(model), stamp);
                }
                None => failed.push((
                    name,
                    format!("version {wanted}: {reason}; no other version loads"),
                )),
            }
        }
        Ok(failed)
    }

    /// Serve `model` from now on (the swap): requests on the previous version finish on it.
    fn install(&self, model: Arc<LoadedModel>, stamp: Option<Stamp>) {
        let loaded = SystemTime::now();
        metrics::model_active(model.name(), model.version(), loaded);
        let served = Served {
            model,
            loaded,
            stamp,
        };
        let mut active = self.active.write().unwrap_or_else(|e| e.into_inner());
        active.insert(served.model.name().to_string(), served);
    }

    fn refuse(&self, name: &str, version: u32, stamp: Option<Stamp>) {
        let mut refused = self.refused.lock().unwrap_or_else(|e| e.into_inner());
        refused.insert((name.to_string(), version), stamp);
    }

    /// The active version of `name`, if loaded.
    pub fn active(&self, name: &str) -> Option<Arc<LoadedModel>> {
        self.served_entry(name).map(|s| s.model)
    }

    /// The active version of `name` with when it was loaded, if loaded.
    pub fn served_entry(&self, name: &str) -> Option<Served> {
        let active = self.active.read().unwrap_or_else(|e| e.into_inner());
        active.get(name).cloned()
    }

    /// Every loaded active model, by name.
    pub fn all_active(&self) -> Vec<Arc<LoadedModel>> {
        self.all_served().into_iter().map(|s| s.model).collect()
    }

    /// Every loaded active model with when it was loaded, by name.
    pub fn all_served(&self) -> Vec<Served> {
        let active = self.active.read().unwrap_or_else(|e| e.into_inner());
        active.values().cloned().collect()
    }

    /// The model to serve: the active version, or a specific one (loaded on first use and
    /// cached). Blocking when a version must be read from disk.
    pub fn get(&self, name: &str, version: Option<u32>) -> Result<Arc<LoadedModel>, StoreError> {
        let active = self.active(name);
        let Some(version) = version else {
            return match active {
                Some(model) => Ok(model),
                None => Err(self.missing(name)),
            };
        };
        if let Some(model) = active.filter(|m| m.version() == version) {
            return Ok(model);
        }
        {
            let mut cache = self.cache.lock().unwrap_or_else(|e| e.into_inner());
            if let Some(i) = cache
                .iter()
                .position(|m| m.name() == name && m.version() == version)
            {
                let model = cache.remove(i);
                cache.push(model.clone());
                return Ok(model);
            }
        }
        if self.active(name).is_none() {
            return Err(self.missing(name));
        }
        let model = Arc::new(self.load_version(name, version)?);
        if self.cache_size > 0 {
            let mut cache = self.cache.lock().unwrap_or_else(|e| e.into_inner());
            cache.push(model.clone());
            let excess = cache.len().saturating_sub(self.cache_size);
            cache.drain(..excess);
        }
        Ok(model)
    }

    fn missing(&self, name: &str) -> StoreError {
        let mut served: Vec<String> = self
            .all_active()
            .iter()
            .map(|m| m.name().to_string())
            .collect();
        served.sort();
        let served = match served.is_empty() {
            true => "none".to_string(),
            false => served.join(", "),
        };
        StoreError::Unserved {
            name: name.to_string(),
            served,
        }
    }

    /// The active version of a served model; 404 (`model-not-found`) for any other name.
    pub fn served(&self, name: &str) -> Result<Arc<LoadedModel>, StoreError> {
        self.active(name).ok_or_else(|| self.missing(name))
    }

    /// The active version of a served model with when it was loaded; 404 for any other name.
    pub fn served_with_time(&self, name: &str) -> Result<Served, StoreError> {
        self.served_entry(name).ok_or_else(|| self.missing(name))
    }

    /// Whether a model name is served.
    pub fn is_served(&self, name: &str) -> bool {
        self.active(name).is_some()
    }

    /// Make `version` the active version of `name`: load it, verify schema and checksum,
    /// self-test, then swap atomically and record it in the registry. A failure leaves the
    /// previous version serving (and is counted in `reflectance_model_load_failures_total`).
    /// Blocking.
    pub fn activate(&self, name: &str, version: u32) -> Result<Activated, StoreError> {
        let _serial = self.activation.lock().unwrap_or_else(|e| e.into_inner());
        let stamp = self.registry.stamp(name, version).ok();
        let model = self
            .read_checked(name, version)
            .inspect_err(|e| count_refusal(name, version, e))?;
        let model = Arc::new(model);
        let previous = self.active(name).map(|m| m.version());
        self.install(model, stamp);
        reflectance_core::util::durable::test_pause("activate");
        let warning = self.registry.set_active(name, version).err().map(|e| {
            let warning = format!(
                "activation of {name} version {version} holds in memory only: the registry \
                 could not record it ({e})"
            );
            tracing::warn!(model = name, version, error = %e, "activation not persisted");
            warning
        });
        let mut cache = self.cache.lock().unwrap_or_else(|e| e.into_inner());
        cache.retain(|m| !(m.name() == name && m.version() == version));
        match previous {
            Some(previous) => tracing::info!(model = name, version, previous, "model activated"),
            None => tracing::info!(model = name, version, "model activated"),
        }
        Ok(Activated { previous, warning })
    }

    /// Look at the registry once and serve what it says, comparing before reading: for each
    /// model, the version `ACTIVE` names (once it is complete), else the newest; a version
    /// whose file is the one already served is left alone, one that failed to load is tried
    /// again only once its file has changed. A new version is loaded with the checks of an
    /// activation and swapped in atomically; one that fails leaves the previous version
    /// serving (`reflectance_model_load_failures_total` counts it), except a file that
    /// changed while it was read (being written in place): it is looked at again next time,
    /// uncounted. A model with no version left stops being served (its requests finish on
    /// it), except `keep` (the default model). Blocking.
    pub fn poll(&self, keep: &str) -> Result<Polled, RegistryError> {
        if !self.registry.root().is_dir() {
            // An unmounted or vanished volume is no reason to stop serving.
            return Err(RegistryError::NoFolder(
                self.registry.root().display().to_string(),
            ));
        }
        let names = self.registry.names()?;
        let mut polled = Polled::default();
        for name in &names {
            if self.current(name).is_none() {
                continue;
            }
            // Decided again under the activations' lock: an activation may have just
            // swapped a version in and not yet recorded it in `ACTIVE`.
            let _serial = self.activation.lock().unwrap_or_else(|e| e.into_inner());
            let Some((version, stamp)) = self.current(name) else {
                continue;
            };
            match self.read_checked(name, version) {
                Ok(model) => {
                    let previous = self.active(name).map(|m| m.version());
                    self.install(Arc::new(model), Some(stamp));
                    let mut refused = self.refused.lock().unwrap_or_else(|e| e.into_inner());
                    refused.remove(&(name.clone(), version));
                    tracing::info!(model = %name, version, ?previous, "model loaded from the registry");
                    polled.swapped.push((name.clone(), version));
                }
                Err(e) if self.registry.stamp(name, version).ok() != Some(stamp) => {
                    tracing::info!(model = %name, version, error = %e,
                        "version changed while it was read: looked at again next time");
                }
                Err(e) => {
                    count_refusal(name, version, &e);
                    self.refuse(name, version, Some(stamp));
                    tracing::error!(model = %name, version, error = %e,
                        "version refused: the previous one keeps serving; tried again when its file changes");
                    polled.refused.push((name.clone(), version));
                }
            }
        }
        for served in self.all_served() {
            let name = served.model.name().to_string();
            if names.contains(&name) || name == keep {
                continue;
            }
            // Gone for good, not merely unreadable this time.
            let gone = match self.registry.versions(&name) {
                Ok(versions) => versions.is_empty(),
                Err(RegistryError::UnknownModel(_)) => true,
                Err(e) => {
                    tracing::warn!(model = %name, error = %e, "cannot list the versions: the served one stays");
                    false
                }
            };
            if !gone {
                continue;
            }
            let mut active = self.active.write().unwrap_or_else(|e| e.into_inner());
            active.remove(&name);
            metrics::model_removed(&name);
            tracing::info!(model = %name, "model no longer in the registry: not served");
            polled.removed.push(name);
        }
        let mut cache = self.cache.lock().unwrap_or_else(|e| e.into_inner());
        cache.retain(|m| self.registry.stamp(m.name(), m.version()).is_ok());
        metrics::registry_polled();
        Ok(polled)
    }

    /// What `name` should load to serve what the registry says: the version and its file's
    /// identity, or `None` when it serves that already, when that version failed and its file
    /// is unchanged, or when the file is gone meanwhile.
    fn current(&self, name: &str) -> Option<(u32, Stamp)> {
        let served = self.served_entry(name);
        let version = self.wanted(name, served.as_ref().map(|s| s.model.version()))?;
        let stamp = self.registry.stamp(name, version).ok()?;
        if served.is_some_and(|s| s.model.version() == version && s.stamp == Some(stamp)) {
            return None;
        }
        let refused = self.refused.lock().unwrap_or_else(|e| e.into_inner());
        match refused.get(&(name.to_string(), version)) {
            Some(before) if *before == Some(stamp) => None,
            _ => Some((version, stamp)),
        }
    }

    /// The version the registry says to serve: the one `ACTIVE` names once it is complete,
    /// else the newest; while `ACTIVE` names a version not complete yet (or cannot be read),
    /// the one serving, as long as it is there.
    fn wanted(&self, name: &str, served: Option<u32>) -> Option<u32> {
        let versions = self.registry.versions(name).ok()?;
        let latest = *versions.last()?;
        match self.registry.pinned(name) {
            Ok(Some(v)) if versions.contains(&v) => Some(v),
            Ok(None) => Some(latest),
            _ => Some(served.filter(|v| versions.contains(v)).unwrap_or(latest)),
        }
    }

    /// Delete an inactive version (the served active version is refused even if the
    /// registry's record differs). Blocking.
    pub fn delete(&self, name: &str, version: u32) -> Result<(), StoreError> {
        let _serial = self.activation.lock().unwrap_or_else(|e| e.into_inner());
        if self.active(name).is_some_and(|m| m.version() == version) {
            let name = name.to_string();
            return Err(RegistryError::ActiveVersion { name, version }.into());
        }
        self.registry.delete(name, version)?;
        let mut cache = self.cache.lock().unwrap_or_else(|e| e.into_inner());
        cache.retain(|m| !(m.name() == name && m.version() == version));
        Ok(())
    }

    /// Serialize with activations (used by jobs that publish and may activate).
    pub fn lock_registry(&self) -> std::sync::MutexGuard<'_, ()> {
        self.activation.lock().unwrap_or_else(|e| e.into_inner())
    }
}
