//! Watertight ray–triangle intersection in f64 (Woop, Benthin & Wald 2013, "Watertight
//! Ray/Triangle Intersection", JCGT 2(1)): rays through a shared edge or vertex of a closed
//! mesh hit at least one of the triangles.

use super::{gamma, Ray, SurfacePoint};
use crate::math::Vec3;

/// Intersection of `ray` with triangle (p0, p1, p2) for 0 < t < t_max: (t, barycentrics).
pub fn intersect(ray: &Ray, p0: Vec3, p1: Vec3, p2: Vec3, t_max: f64) -> Option<(f64, [f64; 3])> {
    // Permute so that z is the dominant direction axis (JCGT 2(1), Fig. 1).
    let d = ray.d;
    let kz = d.abs().max_position();
    let mut kx = (kz + 1) % 3;
    let mut ky = (kx + 1) % 3;
    if d[kz] < 0.0 {
        std::mem::swap(&mut kx, &mut ky);
    }
    let sx = d[kx] / d[kz];
    let sy = d[ky] / d[kz];
    let sz = 1.0 / d[kz];
    let a = p0 - ray.o;
    let b = p1 - ray.o;
    let c = p2 - ray.o;
    // Shear and scale so the ray runs along +z.
    let ax = a[kx] - sx * a[kz];
    let ay = a[ky] - sy * a[kz];
    let bx = b[kx] - sx * b[kz];
    let by = b[ky] - sy * b[kz];
    let cx = c[kx] - sx * c[kz];
    let cy = c[ky] - sy * c[kz];
    // Scaled barycentric coordinates (edge functions).
    let u = cx * by - cy * bx;
    let v = ax * cy - ay * cx;
    let w = bx * ay - by * ax;
    if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
        return None;
    }
    let det = u + v + w;
    if det == 0.0 {
        return None;
    }
    let az = sz * a[kz];
    let bz = sz * b[kz];
    let cz = sz * c[kz];
    let t_scaled = u * az + v * bz + w * cz;
    // Compare with the sign of det to avoid dividing before the range test.
    if det > 0.0 {
        if t_scaled <= 0.0 || t_scaled >= t_max * det {
            return None;
        }
    } else if t_scaled >= 0.0 || t_scaled <= t_max * det {
        return None;
    }
    let inv = 1.0 / det;
    let t = t_scaled * inv;
    Some((t, [u * inv, v * inv, w * inv]))
}

/// The point with barycentrics `b` and its error bound γ(7)·Σ|bᵢ pᵢ| (PBR 3rd ed. §3.9.4).
pub fn surface_point(b: [f64; 3], p: [Vec3; 3], n: Vec3) -> SurfacePoint {
    let (q0, q1, q2) = (p[0] * b[0], p[1] * b[1], p[2] * b[2]);
    SurfacePoint {
        p: q0 + q1 + q2,
        p_error: (q0.abs() + q1.abs() + q2.abs()) * gamma(7),
        n,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hits_centre_and_misses_outside() {
        let (p0, p1, p2) = (Vec3::ZERO, Vec3::X, Vec3::Y);
        let r = Ray {
            o: Vec3::new(0.25, 0.25, 1.0),
            d: -Vec3::Z,
        };
        let (t, b) = intersect(&r, p0, p1, p2, f64::INFINITY).unwrap();
        assert!((t - 1.0).abs() < 1e-15);
        assert!((b[0] - 0.5).abs() < 1e-15 && (b[1] - 0.25).abs() < 1e-15);
        let miss = Ray {
            o: Vec3::new(0.75, 0.75, 1.0),
            d: -Vec3::Z,
        };
        assert!(intersect(&miss, p0, p1, p2, f64::INFINITY).is_none());
        assert!(intersect(&r, p0, p1, p2, 0.5).is_none());
    }

    #[test]
    fn shared_edge_of_two_triangles_never_leaks() {
        // A quad split along its diagonal; rays aimed exactly at the diagonal.
        let (a, b, c, d) = (
            Vec3::ZERO,
            Vec3::new(3.0, 0.0, 0.0),
            Vec3::new(3.0, 7.0, 0.0),
            Vec3::new(0.0, 7.0, 0.0),
        );
        for i in 0..=1000 {
            let s = i as f64 / 1000.0;
            let target = a + (c - a) * s;
            let o = Vec3::new(0.123, -0.456, 2.0);
            let r = Ray {
                o,
                d: (target - o).normalize(),
            };
            let hit1 = intersect(&r, a, b, c, f64::INFINITY).is_some();
            let hit2 = intersect(&r, a, c, d, f64::INFINITY).is_some();
            assert!(hit1 || hit2, "leak at s = {s}");
        }
    }
}
