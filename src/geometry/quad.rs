//! Analytic parallelogram ("quad"): corner + u·edge_u + v·edge_v for u, v in [0, 1].

use super::{gamma, Ray, SurfacePoint};
use crate::math::Vec3;

/// A parallelogram in scene units; normal = normalize(edge_u × edge_v), reversed if flipped.
#[derive(Debug, Clone, PartialEq)]
pub struct Quad {
    /// One corner.
    pub corner: Vec3,
    /// First edge from the corner.
    pub edge_u: Vec3,
    /// Second edge from the corner.
    pub edge_v: Vec3,
    /// Reverse the normal.
    pub flip_normals: bool,
}

impl Quad {
    fn cross(&self) -> Vec3 {
        self.edge_u.cross(self.edge_v)
    }

    /// Area |edge_u × edge_v|.
    pub fn area(&self) -> f64 {
        self.cross().length()
    }

    /// Unit normal.
    pub fn normal(&self) -> Vec3 {
        let n = self.cross().normalize();
        if self.flip_normals {
            -n
        } else {
            n
        }
    }

    /// Axis-aligned bounds (min, max).
    pub fn bounds(&self) -> (Vec3, Vec3) {
        let pts = [
            self.corner,
            self.corner + self.edge_u,
            self.corner + self.edge_v,
            self.corner + self.edge_u + self.edge_v,
        ];
        let lo = pts.iter().fold(Vec3::INFINITY, |a, p| a.min(*p));
        let hi = pts.iter().fold(Vec3::NEG_INFINITY, |a, p| a.max(*p));
        (lo, hi)
    }

    /// Nearest hit with 0 < t < t_max: ray–plane distance, then (u, v) from the plane point
    /// by the dual basis w = n/(n·n): u = w·(h × e_v), v = w·(e_u × h) with h = p − corner.
    pub fn intersect(&self, ray: &Ray, t_max: f64) -> Option<(f64, SurfacePoint)> {
        let (t, u, v) = self.hit(ray, t_max)?;
        Some((t, self.surface_point(u, v)))
    }

    /// [`Quad::intersect`]'s hit as (t, u, v), without its surface point (what a shadow ray
    /// needs).
    #[inline]
    pub fn hit(&self, ray: &Ray, t_max: f64) -> Option<(f64, f64, f64)> {
        let n = self.cross();
        let denom = n.dot(ray.d);
        if denom == 0.0 {
            return None;
        }
        let t = (self.corner - ray.o).dot(n) / denom;
        // Bound on the rounding error of t (the dot product of a difference, γ(5) relative to
        // its absolute terms, PBR 3rd ed. §3.9.1): a ray starting on the plane must not hit it.
        let delta_t = gamma(5) * (self.corner.abs() + ray.o.abs()).dot(n.abs()) / denom.abs();
        if !(t > delta_t && t < t_max) {
            return None;
        }
        let h = ray.at(t) - self.corner;
        let w = n / n.length_squared();
        let u = w.dot(h.cross(self.edge_v));
        let v = w.dot(self.edge_u.cross(h));
        ((0.0..=1.0).contains(&u) && (0.0..=1.0).contains(&v)).then_some((t, u, v))
    }

    /// The point at (u, v), recomputed on the plane; error bound γ(7) of the summands
    /// (PBR 3rd ed. §3.9.4, as for barycentric interpolation).
    fn surface_point(&self, u: f64, v: f64) -> SurfacePoint {
        let (a, b) = (self.edge_u * u, self.edge_v * v);
        let p = self.corner + a + b;
        let p_error = (self.corner.abs() + a.abs() + b.abs()) * gamma(7);
        SurfacePoint {
            p,
            p_error,
            n: self.normal(),
        }
    }

    /// A point uniformly distributed over the area; pdf 1/area.
    pub fn sample(&self, u: [f64; 2]) -> SurfacePoint {
        self.surface_point(u[0], u[1])
    }
}
