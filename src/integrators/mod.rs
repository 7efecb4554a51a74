//! Light-transport estimators. Each returns the radiance (W·sr⁻¹·m⁻²·nm⁻¹) arriving at the
//! camera along a ray, at the path's wavelengths.

pub mod path;

pub use path::{PathTracer, Strategy};
