//! Geometry in double precision: rays, the shapes a scene is made of (spheres, quads,
//! triangle meshes), their intersection and area sampling, and the BVH over all of them.
//!
//! Robustness policy (scales 1e-4 … 1e5, translations to 1e6): every intersection point is
//! re-projected onto its surface and carries a conservative bound on its rounding error;
//! spawned rays start outside that error box (Pharr, Jakob & Humphreys, *Physically Based
//! Rendering* 3rd ed., §3.9 "Managing Rounding Error"). The bound is relative to the point's
//! coordinates, so the policy has no scene-scale epsilon.

pub mod accel;
pub mod mesh;
pub mod quad;
pub mod ray;
pub mod shape;
pub mod sphere;
pub mod triangle;

pub use accel::{Aggregate, Skip};
pub use ray::Ray;
pub use shape::Shape;

use crate::math::Vec3;

/// A point on a surface: position, its rounding-error bound and the geometric normal.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfacePoint {
    /// Position, scene units.
    pub p: Vec3,
    /// Per-component bound on |computed p − exact p|, scene units.
    pub p_error: Vec3,
    /// Unit geometric normal, after `flip_normals`.
    pub n: Vec3,
}

/// A ray–scene intersection.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// Distance along the (unit-direction) ray, scene units.
    pub t: f64,
    /// The surface point hit.
    pub point: SurfacePoint,
    /// Index of the shape in the aggregate.
    pub shape: u32,
}

/// γ(n) = n·u/(1 − n·u) with u the f64 unit roundoff: the bound on the relative error of n
/// chained floating-point operations (Higham 2002, *Accuracy and Stability of Numerical
/// Algorithms*, §3.1; PBR 3rd ed. eq. 3.9).
#[inline]
pub fn gamma(n: u32) -> f64 {
    let u = f64::EPSILON * 0.5;
    let nu = n as f64 * u;
    nu / (1.0 - nu)
}
