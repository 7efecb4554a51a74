//! Analytic sphere.

use super::{gamma, Ray, SurfacePoint};
use crate::math::{warp, Vec3, PI};

/// A sphere: centre and radius in scene units; the normal points outward unless flipped.
#[derive(Debug, Clone, PartialEq)]
pub struct Sphere {
    /// Centre.
    pub center: Vec3,
    /// Radius, > 0.
    pub radius: f64,
    /// Normal points inward when true.
    pub flip_normals: bool,
}

impl Sphere {
    /// Surface area, 4πr².
    pub fn area(&self) -> f64 {
        4.0 * PI * self.radius * self.radius
    }

    /// Axis-aligned bounds (min, max).
    pub fn bounds(&self) -> (Vec3, Vec3) {
        let r = Vec3::splat(self.radius);
        (self.center - r, self.center + r)
    }

    /// Nearest hit with 0 < t < t_max. The discriminant uses the form that avoids
    /// cancellation (Haines et al. 2019, "Precision Improvements for Ray/Sphere
    /// Intersection", Ray Tracing Gems ch. 7, eq. 10) and the roots the stable pair
    /// q = b + sign(b)√Δ, t = c/q, q (Press et al., *Numerical Recipes* §5.6).
    pub fn intersect(&self, ray: &Ray, t_max: f64) -> Option<(f64, SurfacePoint)> {
        let f = ray.o - self.center;
        let b = -f.dot(ray.d);
        let l = f + ray.d * b; // f minus its projection on d
        let r2 = self.radius * self.radius;
        let disc = r2 - l.length_squared();
        if disc < 0.0 {
            return None;
        }
        let c = f.length_squared() - r2;
        let q = b + disc.sqrt().copysign(b);
        let (mut t0, mut t1) = if q == 0.0 { (0.0, 0.0) } else { (c / q, q) };
        if t0 > t1 {
            std::mem::swap(&mut t0, &mut t1);
        }
        let t = if t0 > 0.0 { t0 } else { t1 };
        if !(t > 0.0 && t < t_max) {
            return None;
        }
        Some((t, self.surface_point(ray.at(t))))
    }

    /// Re-projects `p` onto the sphere and attaches its error bound (PBR 3rd ed. §3.9.4:
    /// γ(5)·|p| for the re-projected point).
    fn surface_point(&self, p: Vec3) -> SurfacePoint {
        let dir = p - self.center;
        let len = dir.length();
        let unit = if len > 0.0 { dir / len } else { Vec3::Z };
        let p = self.center + unit * self.radius;
        let p_error = (p.abs() + self.center.abs()) * gamma(5);
        let n = if self.flip_normals { -unit } else { unit };
        SurfacePoint { p, p_error, n }
    }

    /// A point uniformly distributed over the area; pdf 1/area.
    pub fn sample(&self, u: [f64; 2]) -> SurfacePoint {
        self.surface_point(self.center + warp::uniform_sphere(u) * self.radius)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hits_from_inside_and_outside_at_any_scale() {
        for scale in [1e-4, 1.0, 1e5] {
            for shift in [0.0, 1e6] {
                let c = Vec3::splat(shift);
                let s = Sphere {
                    center: c,
                    radius: scale,
                    flip_normals: false,
                };
                let out = Ray {
                    o: c + Vec3::new(0.0, 0.0, -3.0 * scale),
                    d: Vec3::Z,
                };
                let (t, sp) = s.intersect(&out, f64::INFINITY).unwrap();
                assert!(
                    (t / scale - 2.0).abs() < 1e-6,
                    "scale {scale} shift {shift}: {t}"
                );
                assert!((sp.n - (-Vec3::Z)).length() < 1e-9);
                let inside = Ray { o: c, d: Vec3::X };
                let (t, _) = s.intersect(&inside, f64::INFINITY).unwrap();
                assert!((t / scale - 1.0).abs() < 1e-6);
                assert!(s.intersect(&inside, 0.5 * scale).is_none());
            }
        }
    }
}
