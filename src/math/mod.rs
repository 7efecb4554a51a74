//! Bottom layer: vectors, the local shading frame, warps with their pdfs, and the
//! counter-based random numbers that make renders independent of the thread count.
//!
//! All geometry is double precision (`glam::DVec3`); directions are unit vectors.

pub mod frame;
pub mod rng;
pub mod warp;

pub use glam::DVec3 as Vec3;

/// π as f64.
pub const PI: f64 = std::f64::consts::PI;
/// 1/π.
pub const INV_PI: f64 = std::f64::consts::FRAC_1_PI;
