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

    /// Whether primitive `prim` has a hit with 0 < t < t_max: [`Shape::intersect_primitive`]
    /// without the surface point (the same hits, for shadow rays).
    #[inline]
    pub fn hits_primitive(&self, prim: usize, ray: &ShearedRay, t_max: f64) -> bool {
        match self {
            Shape::Sphere(s) => s.hit_t(&ray.ray, t_max).is_some(),
            Shape::Quad(q) => q.hit(&ray.ray, t_max).is_some(),
            Shape::Mesh(m) => triangle::intersect_sheared(ray, m.vertices(prim), t_max).is_some(),
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Ray;
    use crate::math::rng::SampleStream;

    #[test]
    fn a_shadow_rays_hit_test_agrees_with_the_closest_hit_test() {
        let shapes = [
            Shape::Sphere(Sphere {
                center: Vec3::new(0.1, -0.2, 0.3),
                radius: 0.7,
                flip_normals: false,
            }),
            Shape::Quad(Quad {
                corner: Vec3::new(-0.5, -0.5, 0.2),
                edge_u: Vec3::new(1.0, 0.1, 0.0),
                edge_v: Vec3::new(0.0, 1.0, 0.3),
                flip_normals: false,
            }),
            Shape::Mesh(TriangleMesh::new(
                vec![
                    Vec3::new(-0.6, -0.4, 0.0),
                    Vec3::new(0.6, -0.4, 0.1),
                    Vec3::new(0.0, 0.7, -0.1),
                ],
                vec![[0, 1, 2]],
                false,
            )),
        ];
        let mut rng = SampleStream::new(7, 0, 0);
        let (mut hits, mut misses) = (0, 0);
        for _ in 0..20_000 {
            let o = Vec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * 3.0 - 1.5;
            let to = Vec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) - 0.5;
            let Some(d) = (to - o).try_normalize() else {
                continue;
            };
            let ray = ShearedRay::new(Ray { o, d });
            let t_max = 0.5 + 4.0 * rng.next_f64();
            for s in &shapes {
                let closest = s.intersect_primitive(0, &ray, t_max).is_some();
                assert_eq!(s.hits_primitive(0, &ray, t_max), closest, "{s:?} {ray:?}");
                if closest {
                    hits += 1;
                } else {
                    misses += 1;
                }
            }
        }
        // both answers occur often enough for the agreement to mean something
        assert!(hits > 2000 && misses > 2000, "{hits} hits, {misses} misses");
    }
}
