//! Watertight ray–triangle intersection in f64 (Woop, Benthin & Wald 2013, "Watertight
//! Ray/Triangle Intersection", JCGT 2(1)): rays through a shared edge or vertex of a closed
//! mesh hit at least one of the triangles.

use super::{gamma, Ray, SurfacePoint};
use crate::math::Vec3;

/// The per-ray part of the watertight test (axis permutation and shear), computed once per
/// ray and reused for every triangle it meets (Woop et al. 2013, §3, "precomputation").
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ShearedRay {
    /// The ray.
    pub ray: Ray,
    /// The dominant axis of the direction (0, 1, 2): it becomes z'; x' and y' are the next
    /// two axes in cyclic order.
    kz: usize,
    /// Shear and scale: x' = a[kx] − sx·a[kz], y' = a[ky] − sy·a[kz], z' = sz·a[kz].
    s: [f64; 3],
}

impl ShearedRay {
    /// Precomputes the permutation that makes z the dominant direction axis and the shear.
    /// Woop et al. swap x' and y' when d\[kz\] < 0 to keep the winding; the test here is
    /// two-sided, and without the swap u, v, w, det and t·det change sign exactly (IEEE
    /// negation), so t and the barycentrics are the same bits.
    pub fn new(ray: Ray) -> Self {
        let d = ray.d.to_array();
        let kz = ray.d.abs().max_position();
        let (kx, ky) = ((kz + 1) % 3, (kz + 2) % 3);
        let s = [d[kx] / d[kz], d[ky] / d[kz], 1.0 / d[kz]];
        ShearedRay { ray, kz, s }
    }
}

/// Intersection of `ray` with triangle (p0, p1, p2) for 0 < t < t_max: (t, barycentrics).
pub fn intersect(ray: &Ray, p0: Vec3, p1: Vec3, p2: Vec3, t_max: f64) -> Option<(f64, [f64; 3])> {
    intersect_sheared(&ShearedRay::new(*ray), [p0, p1, p2], t_max)
}

/// [`intersect`] with the per-ray setup done once.
#[inline]
pub fn intersect_sheared(r: &ShearedRay, p: [Vec3; 3], t_max: f64) -> Option<(f64, [f64; 3])> {
    // one well-predicted branch per test (kz is fixed for the ray); each arm has constant
    // indices, so the permutation costs nothing
    match r.kz {
        0 => intersect_axis::<0>(r, p, t_max),
        1 => intersect_axis::<1>(r, p, t_max),
        _ => intersect_axis::<2>(r, p, t_max),
    }
}

/// Two triangles sharing an edge, (a, b, c) and (a, c, d) for corners `q` = [a, b, c, d] (a
/// quad's halves: the walls of a room, the faces of a box), tested together for one ray: four
/// corners sheared instead of six. Each half gives exactly what [`intersect_sheared`] gives
/// it; the second is tested up to the first one's hit. Returns the nearer hit with
/// 0 < t < t_max: (t, which half, barycentrics of its corners).
#[inline]
pub fn intersect_pair_sheared(
    r: &ShearedRay,
    q: &[Vec3; 4],
    t_max: f64,
) -> Option<(f64, usize, [f64; 3])> {
    match r.kz {
        0 => intersect_pair_axis::<0>(r, q, t_max),
        1 => intersect_pair_axis::<1>(r, q, t_max),
        _ => intersect_pair_axis::<2>(r, q, t_max),
    }
}

/// [`intersect_pair_sheared`] with the dominant axis known at compile time.
#[inline(always)]
fn intersect_pair_axis<const KZ: usize>(
    r: &ShearedRay,
    q: &[Vec3; 4],
    t_max: f64,
) -> Option<(f64, usize, [f64; 3])> {
    // (by hand: `[T; 4]::map` compiled to an out-of-line call through its try-fold here)
    let [a, b, c, d] = [
        shear::<KZ>(r, q[0]),
        shear::<KZ>(r, q[1]),
        shear::<KZ>(r, q[2]),
        shear::<KZ>(r, q[3]),
    ];
    let hit = test_sheared(r, a, b, c, t_max);
    let t_max = hit.map_or(t_max, |h| h.0);
    match test_sheared(r, a, c, d, t_max) {
        Some((t, b)) => Some((t, 1, b)),
        None => hit.map(|(t, b)| (t, 0, b)),
    }
}

/// A corner relative to the ray origin, sheared and scaled so the ray runs along +z:
/// (x', y', a[KZ]) with x' = a[kx] − sx·a[KZ], y' = a[ky] − sy·a[KZ]; z' = sz·a[KZ] is formed
/// only for triangles that pass the edge test.
#[inline(always)]
fn shear<const KZ: usize>(r: &ShearedRay, p: Vec3) -> [f64; 3] {
    let (kx, ky) = ((KZ + 1) % 3, (KZ + 2) % 3);
    let [sx, sy, _] = r.s;
    let a = (p - r.ray.o).to_array();
    [a[kx] - sx * a[KZ], a[ky] - sy * a[KZ], a[KZ]]
}

/// The test with the dominant axis `KZ` known at compile time.
#[inline(always)]
fn intersect_axis<const KZ: usize>(
    r: &ShearedRay,
    p: [Vec3; 3],
    t_max: f64,
) -> Option<(f64, [f64; 3])> {
    test_sheared(
        r,
        shear::<KZ>(r, p[0]),
        shear::<KZ>(r, p[1]),
        shear::<KZ>(r, p[2]),
        t_max,
    )
}

/// The rest of the test, on three corners from [`shear`].
#[inline(always)]
fn test_sheared(
    r: &ShearedRay,
    [ax, ay, a_kz]: [f64; 3],
    [bx, by, b_kz]: [f64; 3],
    [cx, cy, c_kz]: [f64; 3],
    t_max: f64,
) -> Option<(f64, [f64; 3])> {
    let sz = r.s[2];
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
    let (az, bz, cz) = (sz * a_kz, sz * b_kz, sz * c_kz);
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
    // Conservative bound on the rounding error of t; a ray starting on the triangle's own
    // plane (e.g. spawned from a coordinate-aligned wall, where the point's error bound is
    // exactly 0) must not hit it at a tiny positive t (PBR 3rd ed. §3.9.6, eqs. 3.19-3.22).
    let max_zt = az.abs().max(bz.abs()).max(cz.abs());
    let max_xt = ax.abs().max(bx.abs()).max(cx.abs());
    let max_yt = ay.abs().max(by.abs()).max(cy.abs());
    let delta_z = gamma(3) * max_zt;
    let delta_x = gamma(5) * (max_xt + max_zt);
    let delta_y = gamma(5) * (max_yt + max_zt);
    let delta_e = 2.0 * (gamma(2) * max_xt * max_yt + delta_y * max_xt + delta_x * max_yt);
    let max_e = u.abs().max(v.abs()).max(w.abs());
    let delta_t =
        3.0 * (gamma(3) * max_e * max_zt + delta_e * max_zt + delta_z * max_e) * inv.abs();
    if t <= delta_t {
        return None;
    }
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
    fn a_pair_gives_exactly_what_its_two_triangles_give() {
        // a non-planar quad (a, b, c, d) seen from everywhere, and a ray along the diagonal
        let q = [
            Vec3::new(0.1, -0.2, 0.05),
            Vec3::new(2.0, 0.1, -0.3),
            Vec3::new(2.2, 1.9, 0.4),
            Vec3::new(-0.1, 2.1, 0.0),
        ];
        let mut hits = [0; 2];
        for i in 0..4000 {
            let f = |k: u32| ((i * 7919 + k * 104_729) % 1000) as f64 / 1000.0;
            let o = Vec3::new(f(1) * 6.0 - 2.0, f(2) * 6.0 - 2.0, f(3) * 6.0 - 3.0);
            let target = q[0] + (q[2] - q[0]) * f(4) + Vec3::new(0.0, 0.0, f(5) * 0.01);
            let r = Ray {
                o,
                d: (target - o).normalize(),
            };
            let sr = ShearedRay::new(r);
            let first = intersect_sheared(&sr, [q[0], q[1], q[2]], f64::INFINITY);
            let t_max = first.map_or(f64::INFINITY, |h| h.0);
            let second = intersect_sheared(&sr, [q[0], q[2], q[3]], t_max);
            let expected = second
                .map(|(t, b)| (t, 1, b))
                .or(first.map(|(t, b)| (t, 0, b)));
            let got = intersect_pair_sheared(&sr, &q, f64::INFINITY);
            assert_eq!(got, expected, "{r:?}");
            if let Some((_, k, _)) = got {
                hits[k] += 1;
            }
        }
        assert!(hits[0] > 100 && hits[1] > 100, "{hits:?}");
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
