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
