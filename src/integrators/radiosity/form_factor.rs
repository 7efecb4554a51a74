//! Form factors. From a differential area at `x` (unit normal `n`) to a planar polygon, the
//! exact unoccluded factor is Lambert's contour integral
//! F = (1/2π) Σₖ γₖ n·(Rₖ × Rₖ₊₁)/|Rₖ × Rₖ₊₁|, Rₖ = vₖ − x, γₖ the angle between Rₖ and Rₖ₊₁
//! (Baum, Rushmeier & Winget 1989, "Improving radiosity solutions through the use of
//! analytically determined form-factors", SIGGRAPH, eq. 7), valid for a polygon wholly above
//! the tangent plane, so the polygon is first clipped to it.

use crate::math::Vec3;

/// A point-to-polygon form factor: (point, its unit normal, polygon vertices in order) → the
/// fraction of the point's cosine-weighted hemisphere the polygon covers (no occlusion).
/// The solver takes it as a parameter so that a negative control can hand it a wrong one.
pub type PointFactor = fn(x: Vec3, n: Vec3, polygon: &[Vec3]) -> f64;

/// Vertices of a clipped polygon at most: a quad cut by one plane has at most 5.
const MAX_CLIPPED: usize = 8;

/// Lambert's exact point-to-polygon factor, the polygon clipped to the half-space in front
/// of `n` (Sutherland & Hodgman 1974, "Reentrant polygon clipping", CACM 17(1), one plane).
pub fn point_to_polygon(x: Vec3, n: Vec3, polygon: &[Vec3]) -> f64 {
    let mut clipped = [Vec3::ZERO; MAX_CLIPPED];
    let m = clip_to_front(x, n, polygon, &mut clipped);
    // fewer than 3 vertices, or all on the tangent plane (x's own plane): no solid angle
    if m < 3 || clipped[..m].iter().all(|&v| n.dot(v - x) <= 0.0) {
        return 0.0;
    }
    let mut sum = 0.0;
    for k in 0..m {
        let a = clipped[k] - x;
        let b = clipped[(k + 1) % m] - x;
        let c = a.cross(b);
        let len = c.length();
        if len == 0.0 {
            continue; // x on the edge's line: the edge subtends no angle
        }
        // γ by atan2 (accurate for tiny and near-π angles, where acos of a dot loses digits)
        let gamma = len.atan2(a.dot(b));
        sum += gamma * n.dot(c) / len;
    }
    // the winding as seen from x sets the sign; the factor is its magnitude
    (sum.abs() / (2.0 * std::f64::consts::PI)).min(1.0)
}

/// Clips `polygon` to {y : n·(y − x) ≥ 0} into `out`; returns the vertex count.
fn clip_to_front(x: Vec3, n: Vec3, polygon: &[Vec3], out: &mut [Vec3; MAX_CLIPPED]) -> usize {
    let mut m = 0;
    let k = polygon.len();
    for i in 0..k {
        let (a, b) = (polygon[i], polygon[(i + 1) % k]);
        let (da, db) = (n.dot(a - x), n.dot(b - x));
        if da >= 0.0 && m < MAX_CLIPPED {
            out[m] = a;
            m += 1;
        }
        if (da > 0.0 && db < 0.0) || (da < 0.0 && db > 0.0) {
            let t = da / (da - db);
            if m < MAX_CLIPPED {
                out[m] = a + (b - a) * t;
                m += 1;
            }
        }
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    fn square(h: f64, half: f64) -> Vec<Vec3> {
        vec![
            Vec3::new(-half, -half, h),
            Vec3::new(half, -half, h),
            Vec3::new(half, half, h),
            Vec3::new(-half, half, h),
        ]
    }

    /// Parallel square centred above the point: F = (2/π)[a/√(1+a²) atan(a/√(1+a²))]·2 with
    /// a = half/h (Howell, "A catalog of radiation heat transfer configuration factors", B-3
    /// specialised to a point on the axis; here as the sum of four corner rectangles, C-11).
    #[test]
    fn parallel_square_on_axis_matches_the_catalogue() {
        for (h, half) in [(1.0, 1.0), (2.0, 0.5), (0.1, 3.0)] {
            let a: f64 = half / h;
            // corner rectangle a x a at distance 1 (Howell C-11 with X = Y = a):
            let x = a / (1.0 + a * a).sqrt();
            let corner = (1.0 / (2.0 * PI)) * 2.0 * x * x.atan();
            let expected = 4.0 * corner;
            let f = point_to_polygon(Vec3::ZERO, Vec3::Z, &square(h, half));
            assert!((f - expected).abs() < 1e-14, "{f} vs {expected}");
        }
    }

    /// An infinite plane in front of the point covers the whole hemisphere: a huge square
    /// approaches 1 and never exceeds it.
    #[test]
    fn a_huge_square_covers_the_hemisphere() {
        let f = point_to_polygon(Vec3::ZERO, Vec3::Z, &square(1.0, 1e6));
        assert!((1.0 - f) < 1e-5 && f <= 1.0, "{f}");
    }

    /// Winding does not matter; a polygon behind the tangent plane gives 0; one straddling it
    /// counts only its front part (a square cut in half by the plane: half its factor seen
    /// from a normal rotated so that the plane bisects it).
    #[test]
    fn winding_back_faces_and_clipping() {
        let sq = square(1.0, 1.0);
        let rev: Vec<Vec3> = sq.iter().rev().copied().collect();
        let f = point_to_polygon(Vec3::ZERO, Vec3::Z, &sq);
        assert_eq!(f, point_to_polygon(Vec3::ZERO, Vec3::Z, &rev));
        assert_eq!(point_to_polygon(Vec3::ZERO, -Vec3::Z, &sq), 0.0);
        // a unit square in the plane x = 1 seen from the origin with normal +x, and the same
        // square extended to y in [-1, 1] seen with normal +y: the plane y = 0 cuts it in half
        let wall = vec![
            Vec3::new(1.0, -1.0, -0.5),
            Vec3::new(1.0, 1.0, -0.5),
            Vec3::new(1.0, 1.0, 0.5),
            Vec3::new(1.0, -1.0, 0.5),
        ];
        let half = vec![
            Vec3::new(1.0, 0.0, -0.5),
            Vec3::new(1.0, 1.0, -0.5),
            Vec3::new(1.0, 1.0, 0.5),
            Vec3::new(1.0, 0.0, 0.5),
        ];
        let clipped = point_to_polygon(Vec3::ZERO, Vec3::Y, &wall);
        let direct = point_to_polygon(Vec3::ZERO, Vec3::Y, &half);
        assert!((clipped - direct).abs() < 1e-15 && direct > 0.0);
    }

    /// Closure: the six faces of a cube seen from a point on the inside of one face sum to 1
    /// (the face the point lies on contributes 0).
    #[test]
    fn cube_faces_sum_to_one() {
        let c = |x: f64, y: f64, z: f64| Vec3::new(x, y, z);
        let faces = [
            [c(0., 0., 0.), c(1., 0., 0.), c(1., 1., 0.), c(0., 1., 0.)],
            [c(0., 0., 1.), c(1., 0., 1.), c(1., 1., 1.), c(0., 1., 1.)],
            [c(0., 0., 0.), c(0., 1., 0.), c(0., 1., 1.), c(0., 0., 1.)],
            [c(1., 0., 0.), c(1., 1., 0.), c(1., 1., 1.), c(1., 0., 1.)],
            [c(0., 0., 0.), c(1., 0., 0.), c(1., 0., 1.), c(0., 0., 1.)],
            [c(0., 1., 0.), c(1., 1., 0.), c(1., 1., 1.), c(0., 1., 1.)],
        ];
        for x in [c(0.3, 0.7, 0.0), c(0.01, 0.99, 0.0), c(0.5, 0.5, 0.0)] {
            let sum: f64 = faces.iter().map(|f| point_to_polygon(x, Vec3::Z, f)).sum();
            assert!((sum - 1.0).abs() < 1e-13, "{sum}");
        }
    }
}
