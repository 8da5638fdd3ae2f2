//! The command line's failures: the layers' own errors, as they are, and what the command
//! line itself refuses. Each prints as one line on stderr (`main`).

use crate::report::ReportError;
use reflectance_core::dataset::DatasetError;
use reflectance_core::decode::DecodeError;
use reflectance_core::features::ConfigError;
use reflectance_core::learn::LearnError;
use reflectance_core::locate::GeometryError;
use reflectance_core::material::ClassFileError;
use reflectance_core::model::ModelError;
use reflectance_core::model::registry::RegistryError;
use reflectance_core::model::train::TrainError;
use reflectance_core::util::shard::ShardError;
use reflectance_core::white::WhiteError;
use reflectance_render::batch::RenderError;

#[derive(Debug, thiserror::Error)]
pub enum CliError {
    #[error(transparent)]
    Decode(#[from] DecodeError),
    #[error(transparent)]
    Dataset(#[from] DatasetError),
    #[error(transparent)]
    Config(#[from] ConfigError),
    #[error(transparent)]
    Geometry(#[from] GeometryError),
    #[error(transparent)]
    White(#[from] WhiteError),
    #[error(transparent)]
    Input(#[from] reflectance_core::analysis::InputError),
    #[error(transparent)]
    Learn(#[from] LearnError),
    #[error(transparent)]
    Train(#[from] TrainError),
    #[error(transparent)]
    Registry(#[from] RegistryError),
    #[error(transparent)]
    Report(#[from] ReportError),
    #[error(transparent)]
    Shard(#[from] ShardError),
    #[error(transparent)]
    Model(#[from] ModelError),
    #[error(transparent)]
    Classes(#[from] ClassFileError),
    #[error(transparent)]
    Render(#[from] RenderError),
    #[error(transparent)]
    Json(#[from] serde_json::Error),
    #[error(transparent)]
    Serve(#[from] crate::server::StartError),
    #[error(transparent)]
    ServeConfig(#[from] crate::server::config::InvalidConfig),
    /// A failure about one thing (a file, an address): what it is, then what went wrong.
    #[error("{what}: {source}")]
    At {
        what: String,
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// What the command line itself refuses: a combination of flags, a value out of range,
    /// or a layer's failure put in the command line's words.
    #[error("{0}")]
    Invalid(String),
}

impl CliError {
    /// A failure about `what` (a path, an address).
    pub fn at(
        what: impl std::fmt::Display,
        source: impl Into<Box<dyn std::error::Error + Send + Sync>>,
    ) -> CliError {
        CliError::At {
            what: what.to_string(),
            source: source.into(),
        }
    }
}

impl From<&str> for CliError {
    fn from(message: &str) -> CliError {
        CliError::Invalid(message.to_string())
    }
}

/// A command's result.
pub type CliResult<T = ()> = Result<T, CliError>;
