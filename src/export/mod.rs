//! Scene exporters: a validated furnace [`Scene`](crate::scene::Scene) written in another
//! renderer's scene format, so that the same scene can be rendered by that renderer and its
//! image judged by the same checks.
//!
//! Exporters work on the validated scene (spectra resolved, meshes loaded, materials
//! attached), not on the TOML text, so what is exported is exactly what furnace renders.

pub mod mitsuba;
pub mod pbrt;

/// Why a scene could not be exported.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// The scene uses something the target format cannot express exactly.
    #[error("{what} cannot be exported to {format}: {why}")]
    Unsupported {
        /// Target format.
        format: &'static str,
        /// The scene element, e.g. `shape[3] emission`.
        what: String,
        /// Why, and what to do instead.
        why: String,
    },
    /// Writing the files failed.
    #[error("cannot write {path}: {source}")]
    Io {
        /// The file.
        path: std::path::PathBuf,
        /// The operating system's error.
        source: std::io::Error,
    },
}
