//! Analytic sphere.

use super::{gamma, Ray, SurfacePoint};
use crate::math::frame::Frame;
use crate::math::{warp, Vec3, PI};

/// Relative margin beyond the radius from which a sphere is sampled by its visible cone: a
/// point within (1 + CONE_MARGIN)·r of the centre, or within [`CONE_MARGIN_ULPS`] roundings
/// of its coordinates (inside, on the surface, or just above it), samples the area instead.
pub const CONE_MARGIN: f64 = 1e-7;

/// The margin in units of the rounding of the centre's and the point's coordinates: a point
/// computed on the surface far from the origin may round outside by about γ(5)·|p|.
pub const CONE_MARGIN_ULPS: f64 = 1e3;

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
        let t = self.hit_t(ray, t_max)?;
        Some((t, self.surface_point(ray.at(t))))
    }

    /// The t of [`Sphere::intersect`]'s hit, without its surface point (what a shadow ray
    /// needs).
    #[inline]
    pub fn hit_t(&self, ray: &Ray, t_max: f64) -> Option<f64> {
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
        (t > 0.0 && t < t_max).then_some(t)
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

    /// Whether `p` lies clearly outside: farther from the centre than the radius by more than
    /// [`CONE_MARGIN`]·r and [`CONE_MARGIN_ULPS`] roundings of the coordinates involved.
    pub fn clearly_outside(&self, p: Vec3) -> bool {
        let scale = self.center.abs().max_element().max(p.abs().max_element());
        let margin = (CONE_MARGIN * self.radius).max(CONE_MARGIN_ULPS * f64::EPSILON * scale);
        (self.center - p).length() > self.radius + margin
    }

    /// 1 − cos θmax of the cone under which the sphere is seen from `p` (θmax its half-angle,
    /// sin θmax = r/d), computed as sin²θmax/(1 + cos θmax) to keep small cones exact; None
    /// unless `p` is [`Sphere::clearly_outside`], or when the cone underflows.
    pub fn visible_cone(&self, p: Vec3) -> Option<f64> {
        if !self.clearly_outside(p) {
            return None;
        }
        let d2 = (self.center - p).length_squared();
        let r2 = self.radius * self.radius;
        let sin2_max = r2 / d2;
        let cos_max = (1.0 - sin2_max).max(0.0).sqrt();
        let one_minus_cos = sin2_max / (1.0 + cos_max);
        (one_minus_cos > 0.0 && one_minus_cos.is_finite()).then_some(one_minus_cos)
    }

    /// A direction uniform in the cone the sphere subtends from `p` (Shirley & Wang 1996,
    /// "Monte Carlo Techniques for Direct Lighting Calculations", uniform cone sampling) and
    /// the nearest point of the sphere along it, at the distance t = (d² − r²)/(d cos θ +
    /// √(r² − d² sin²θ)) (the smaller root of the ray–sphere quadratic in the cancellation-free
    /// form, Press et al., *Numerical Recipes* §5.6). Returns the point and the solid-angle pdf
    /// 1/(2π(1 − cos θmax)); None where [`Sphere::visible_cone`] is None.
    pub fn sample_cone(&self, p: Vec3, u: [f64; 2]) -> Option<(SurfacePoint, f64)> {
        let omc_max = self.visible_cone(p)?;
        let to_center = self.center - p;
        let d = to_center.length();
        let r = self.radius;
        let sin2_max = (r / d) * (r / d);
        // cos θ = 1 − u₀(1 − cos θmax), kept as 1 − cos θ; sin²θ = (1 − cos θ)(1 + cos θ)
        let omc = u[0] * omc_max;
        let cos_t = 1.0 - omc;
        let sin2_t = omc * (2.0 - omc);
        let (sin_phi, cos_phi) = warp::sin_cos_turn(u[1]);
        let sin_t = sin2_t.sqrt();
        let w = to_center / d;
        let dir =
            Frame::from_normal(w).to_world(Vec3::new(sin_t * cos_phi, sin_t * sin_phi, cos_t));
        // r² − d² sin²θ = r² (1 − sin²θ / sin²θmax) ≥ 0 inside the cone
        let root = r * (1.0 - (sin2_t / sin2_max).min(1.0)).sqrt();
        let t = (d - r) * (d + r) / (d * cos_t + root);
        Some((self.surface_point(p + dir * t), 1.0 / (2.0 * PI * omc_max)))
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
    fn cone_samples_lie_on_the_near_side_along_their_direction() {
        for (r, d) in [(0.5, 2.0), (1e-6, 1e3), (1.0, 1.0 + 1e-6), (3.0, 1e4)] {
            let s = Sphere {
                center: Vec3::new(0.3, d, -0.2),
                radius: r,
                flip_normals: false,
            };
            let p = Vec3::new(0.3, 0.0, -0.2);
            for i in 0..64 {
                let u = [(i as f64 + 0.5) / 64.0, (i as f64 * 0.618) % 1.0];
                let (sp, pdf) = s.sample_cone(p, u).unwrap();
                // on the sphere, to the rounding of its centre's coordinates
                let tol = 1e-9 + 1e-14 * s.center.length() / r;
                assert!(((sp.p - s.center).length() / r - 1.0).abs() < tol);
                // the point is the sphere's first hit along its own direction
                let dir = (sp.p - p).normalize();
                let (t, _) = s.intersect(&Ray { o: p, d: dir }, f64::INFINITY).unwrap();
                assert!(
                    (t / (sp.p - p).length() - 1.0).abs() < 1e-6,
                    "r {r} d {d} u {u:?}"
                );
                let omc = 1.0 - (1.0 - (r / d) * (r / d)).sqrt();
                assert!((pdf * 2.0 * PI * omc - 1.0).abs() < 1e-6 || omc < 1e-12);
                // its direction makes the sampled angle with the axis: 1 − cos θ = u₀(1 − cos θmax)
                let w = (s.center - p).normalize();
                let omc_max = s.visible_cone(p).unwrap();
                let got = 1.0 - dir.dot(w);
                assert!(
                    (got - u[0] * omc_max).abs() <= 1e-6 * omc_max + 1e-15,
                    "r {r} d {d} u {u:?}: 1 − cos θ {got} vs {}",
                    u[0] * omc_max
                );
            }
        }
        // from inside or on the surface: no cone
        let s = Sphere {
            center: Vec3::ZERO,
            radius: 1.0,
            flip_normals: true,
        };
        assert!(s
            .sample_cone(Vec3::new(0.0, 0.0, 1.0), [0.5, 0.5])
            .is_none());
        assert!(s.sample_cone(Vec3::ZERO, [0.5, 0.5]).is_none());
        // a small sphere far from the origin: its surface points, rounded, are not outside
        let s = Sphere {
            center: Vec3::splat(1e6),
            radius: 1e-4,
            flip_normals: true,
        };
        for i in 0..1000 {
            let d = warp::uniform_sphere([(i as f64 + 0.5) / 1000.0, (i as f64 * 0.618) % 1.0]);
            let (_, sp) = s.intersect(&Ray { o: s.center, d }, f64::INFINITY).unwrap();
            assert!(!s.clearly_outside(sp.p), "{:?}", sp.p - s.center);
        }
    }

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
