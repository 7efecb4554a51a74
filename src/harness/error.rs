//! Why a check could not give a verdict: its setup does not fit the kind, the renderer under
//! test failed, or an input file is invalid (each an ERROR outcome with this message), or the
//! renderer cannot express the scene (a SKIPPED outcome).

use crate::io::LocatedError;

/// A check that ends without a measurement.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CheckError {
    /// The scene or settings do not fit what the kind's closed form assumes.
    #[error("{0}")]
    Setup(String),
    /// The renderer (or model server) under test failed or cannot do what the check needs.
    #[error("{0}")]
    Renderer(String),
    /// The renderer under test, or the exporter to its format, cannot express the check's
    /// scene (it said so by name): the check does not apply and is SKIPPED with the reason.
    #[error("{0}")]
    Unsupported(String),
    /// A file the check reads (measurement, reference image) is invalid.
    #[error(transparent)]
    Input(#[from] LocatedError),
}

impl From<String> for CheckError {
    fn from(s: String) -> Self {
        CheckError::Setup(s)
    }
}

impl From<&str> for CheckError {
    fn from(s: &str) -> Self {
        CheckError::Setup(s.to_string())
    }
}
