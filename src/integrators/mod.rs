//! Light-transport estimators. The path tracer returns the radiance (W·sr⁻¹·m⁻²·nm⁻¹)
//! arriving at the camera along a ray, at the path's wavelengths; the light tracer returns a
//! light path's contributions to pixel measurements (the same units, per pixel).

pub mod light;
pub mod path;

pub use light::LightTracer;
pub use path::{PathTracer, Strategy};
