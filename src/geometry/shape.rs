//! The closed set of shapes a scene is built from, with uniform area sampling.

use super::triangle::{self, ShearedRay};
use super::{mesh::TriangleMesh, quad::Quad, sphere::Sphere, SurfacePoint};
use crate::math::Vec3;

/// A shape: a sphere, a parallelogram, or a triangle mesh (one BVH primitive per triangle).
#[derive(Debug, Clone, PartialEq)]
pub enum Shape {
    /// Analytic sphere.
    Sphere(Sphere),
    /// Analytic parallelogram.
    Quad(Quad),
    /// Triangle mesh.
    Mesh(TriangleMesh),
}

impl Shape {
    /// Number of BVH primitives (1, or the triangle count).
    pub fn primitive_count(&self) -> usize {
        match self {
            Shape::Mesh(m) => m.triangles.len(),
            _ => 1,
        }
    }

    /// Bounds of primitive `prim`.
    pub fn primitive_bounds(&self, prim: usize) -> (Vec3, Vec3) {
        match self {
            Shape::Sphere(s) => s.bounds(),
            Shape::Quad(q) => q.bounds(),
            Shape::Mesh(m) => m.triangle_bounds(prim),
        }
    }

    /// Nearest hit of primitive `prim` with 0 < t < t_max; the surface point is computed
    /// only for a hit.
    #[inline]
    pub fn intersect_primitive(
        &self,
        prim: usize,
        ray: &ShearedRay,
        t_max: f64,
    ) -> Option<(f64, SurfacePoint)> {
        match self {
            Shape::Sphere(s) => s.intersect(&ray.ray, t_max),
            Shape::Quad(q) => q.intersect(&ray.ray, t_max),
            Shape::Mesh(m) => {
                let (t, bary) = triangle::intersect_sheared(ray, m.vertices(prim), t_max)?;
                Some((t, m.surface_point(prim, bary)))
            }
        }
    }

    /// True for a flat shape (a quad, a mesh on one plane): it cannot shadow a segment that
    /// ends on it from a point off its plane.
    pub fn is_planar(&self) -> bool {
        match self {
            Shape::Sphere(_) => false,
            Shape::Quad(_) => true,
            Shape::Mesh(m) => m.is_planar(),
        }
    }

    /// Total surface area, scene units².
    pub fn area(&self) -> f64 {
        match self {
            Shape::Sphere(s) => s.area(),
            Shape::Quad(q) => q.area(),
            Shape::Mesh(m) => m.area(),
        }
    }

    /// A point uniformly distributed over the area (pdf 1/area); `u_select` picks the
    /// triangle of a mesh.
    pub fn sample(&self, u_select: f64, u: [f64; 2]) -> SurfacePoint {
        match self {
            Shape::Sphere(s) => s.sample(u),
            Shape::Quad(q) => q.sample(u),
            Shape::Mesh(m) => m.sample(u_select, u),
        }
    }
}
