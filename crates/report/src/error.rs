//! Errors of the report.

use needlesim::RunError;

/// Errors of the report.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    /// A run failed (scene, backend, divergence).
    #[error(transparent)]
    Run(#[from] RunError),
    /// The engine stopped a run.
    #[error(transparent)]
    Sim(#[from] needlesim_core::SimError),
    /// The needle simulation stopped.
    #[error(transparent)]
    Needle(#[from] needlesim_needle::SimulationError),
    /// Writing an output failed.
    #[error("cannot write {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// The reference data shipped with needlesim is malformed.
    #[error("reference data: {0}")]
    Reference(String),
    /// A shipped scene the report varies cannot be read or changed.
    #[error("scene: {0}")]
    Scene(String),
}
