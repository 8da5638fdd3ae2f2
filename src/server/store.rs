//! The model store: the active version of every model, loaded from the registry, swapped
//! atomically on activation, with a small cache of other versions.

use super::metrics;
use reflectance_core::inference::LoadedModel;
use reflectance_core::model::ModelError;
use reflectance_core::model::registry::{Registry, RegistryError};
use std::collections::BTreeMap;
use std::sync::{Arc, Mutex, RwLock};

/// Why the store cannot give, activate or delete a version: the registry refuses (an
/// unknown model or version, the active version, its files), or the version's file is
/// refused (`server::error` maps it to HTTP).
#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    #[error(transparent)]
    Registry(#[from] RegistryError),
    #[error(transparent)]
    Model(#[from] ModelError),
}

/// Outcome of an activation.
#[derive(Debug)]
pub struct Activated {
    pub previous: Option<u32>,
    /// Set when the choice could not be written to the registry (read-only models folder):
    /// it holds in memory until the process restarts.
    pub warning: Option<String>,
}

/// The active version of every model, swapped atomically: a request clones the `Arc` of
/// the version it started with and finishes on it, whatever is activated meanwhile.
#[derive(Debug)]
pub struct ModelStore {
    registry: Registry,
    active: RwLock<BTreeMap<String, Arc<LoadedModel>>>,
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
            cache: Mutex::new(Vec::new()),
            cache_size,
            activation: Mutex::new(()),
        }
    }

    pub fn registry(&self) -> &Registry {
        &self.registry
    }

    /// Load (and verify) a version from the registry. Blocking.
    pub fn load_version(&self, name: &str, version: u32) -> Result<LoadedModel, StoreError> {
        let file = self.registry.load(name, version).inspect_err(|e| {
            if matches!(e, RegistryError::Model { .. } | RegistryError::Io { .. }) {
                metrics::model_load_failure(name);
                tracing::warn!(model = name, version, error = %e, "model version refused");
            }
        });
        // Reading a model file takes several times its size, briefly: give that back.
        crate::heap::release_free();
        LoadedModel::new(file?)
            .inspect_err(|_| metrics::model_load_failure(name))
            .map_err(StoreError::from)
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
            let reason = match self.load_version(&name, wanted) {
                Ok(model) => {
                    self.install(Arc::new(model));
                    continue;
                }
                Err(e) => e.to_string(),
            };
            let mut others = self.registry.versions(&name).unwrap_or_default();
            others.retain(|&v| v != wanted);
            let fallback = others
                .iter()
                .rev()
                .find_map(|&v| self.load_version(&name, v).ok());
            match fallback {
                Some(model) => {
                    tracing::error!(
                        model = %name,
                        wanted,
                        served = model.version(),
                        %reason,
                        "active version does not load: serving the newest version that does"
                    );
                    metrics::model_fallback(&name);
                    self.install(Arc::new(model));
                }
                None => failed.push((
                    name,
                    format!("version {wanted}: {reason}; no other version loads"),
                )),
            }
        }
        Ok(failed)
    }

    fn install(&self, model: Arc<LoadedModel>) {
        metrics::model_active(model.name(), model.version());
        let mut active = self.active.write().unwrap_or_else(|e| e.into_inner());
        active.insert(model.name().to_string(), model);
    }

    /// The active version of `name`, if loaded.
    pub fn active(&self, name: &str) -> Option<Arc<LoadedModel>> {
        let active = self.active.read().unwrap_or_else(|e| e.into_inner());
        active.get(name).cloned()
    }

    /// Every loaded active model, by name.
    pub fn all_active(&self) -> Vec<Arc<LoadedModel>> {
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
        RegistryError::UnknownModel(name.to_string()).into()
    }

    /// The active version of a served model; 404 (`model-not-found`) for any other name.
    pub fn served(&self, name: &str) -> Result<Arc<LoadedModel>, StoreError> {
        self.active(name).ok_or_else(|| self.missing(name))
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
        let model = Arc::new(self.load_version(name, version)?);
        model.file().self_test().map_err(|e| {
            metrics::model_load_failure(name);
            StoreError::Model(e)
        })?;
        let previous = self.active(name).map(|m| m.version());
        self.install(model);
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
