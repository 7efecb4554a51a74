//! furnace: a predictive-rendering validation harness with a compact spectral reference
//! renderer.
//!
//! Module chain (a module uses only those to its left; `tests/suite/layering.rs` enforces it):
//! `math, limits ← stats ← io ← spectrum ← geometry ← {scattering, media, lights, camera, film} ← scene ←
//! {integrators, export} ← render ← harness ← report`, with the `furnace` binary (`cli.rs`) on top.

pub mod camera;
pub mod export;
pub mod film;
pub mod geometry;
pub mod harness;
pub mod integrators;
pub mod io;
pub mod lights;
pub mod limits;
pub mod math;
pub mod media;
pub mod render;
pub mod report;
pub mod scattering;
pub mod scene;
pub mod spectrum;
pub mod stats;
