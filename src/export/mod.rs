//! Scene exporters: a validated furnace [`Scene`](crate::scene::Scene) written in another
//! renderer's scene format, so that the same scene can be rendered by that renderer and its
//! image judged by the same checks.
//!
//! Exporters work on the validated scene (spectra resolved, meshes loaded, materials
//! attached), not on the TOML text, so what is exported is exactly what furnace renders.

pub mod json;
pub mod mitsuba;
pub mod pbrt;

use crate::spectrum::{Outside, LAMBDA_MAX, LAMBDA_MIN};

/// A table as (wavelength, value) pairs that other renderers read as zero outside its range:
/// `outside = "clamp"` is made explicit by repeating the end values at 360 and 830 nm, the range
/// both renderers sample.
fn table_pairs(wavelengths: &[f64], values: &[f64], outside: Outside) -> Vec<(f64, f64)> {
    let mut pairs: Vec<(f64, f64)> = wavelengths
        .iter()
        .copied()
        .zip(values.iter().copied())
        .collect();
    if outside == Outside::Clamp {
        let (first, last) = (pairs[0], pairs[pairs.len() - 1]);
        if first.0 > LAMBDA_MIN {
            pairs.insert(0, (LAMBDA_MIN, first.1));
        }
        if last.0 < LAMBDA_MAX {
            pairs.push((LAMBDA_MAX, last.1));
        }
    }
    pairs
}

/// An export's files: (path relative to the output folder, contents), the scene file first.
pub type Files = Vec<(std::path::PathBuf, Vec<u8>)>;

/// Writes `files` under `dir` (created), each through a temporary file renamed over it
/// ([`crate::io::write_atomic`]: a failed write leaves the old file whole, and a link or a
/// pipe under an output's name is refused, not written through); returns the scene file's
/// path. A failure part way leaves the files before it written and the rest as they were.
pub fn write_files(
    dir: &std::path::Path,
    files: &Files,
) -> Result<std::path::PathBuf, ExportError> {
    for (rel, bytes) in files {
        let path = dir.join(rel);
        let io = |source| ExportError::Io {
            path: path.clone(),
            source,
        };
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent).map_err(io)?;
        }
        crate::io::write_atomic(&path, |tmp| std::fs::write(tmp, bytes)).map_err(io)?;
    }
    Ok(dir.join(files.first().map_or(std::path::Path::new(""), |f| &f.0)))
}

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
