//! Warps from the unit square to directions and points, each with its pdf twin beside it.
//! Directions are local (z up) unless stated; pdfs are per unit solid angle or per unit area.

use super::{Vec3, INV_PI, PI};

/// Cosine-weighted hemisphere direction by Malley's method: a concentric disk sample
/// (Shirley & Chiu 1997, "A Low Distortion Map Between Disk and Square", JGT 2(3)) lifted to z.
/// The lift takes the disk radius r as the map gives it (z = √(1 − r²)), so the square root
/// runs beside the angle's division and series instead of after them.
pub fn cosine_hemisphere(u: [f64; 2]) -> Vec3 {
    let ([dx, dy], r) = concentric_disk_and_radius(u);
    let z = (1.0 - r * r).max(0.0).sqrt();
    Vec3::new(dx, dy, z)
}

/// Pdf of [`cosine_hemisphere`] per unit solid angle: cos θ / π for z > 0, else 0.
pub fn cosine_hemisphere_pdf(w: Vec3) -> f64 {
    if w.z > 0.0 {
        w.z * INV_PI
    } else {
        0.0
    }
}

/// Concentric map of the unit square onto the unit disk (Shirley & Chiu 1997).
pub fn concentric_disk(u: [f64; 2]) -> [f64; 2] {
    concentric_disk_and_radius(u).0
}

/// [`concentric_disk`] with the point's radius r as the map sets it (|a| or |b|, exact), not
/// recomputed from the point.
#[inline]
fn concentric_disk_and_radius(u: [f64; 2]) -> ([f64; 2], f64) {
    let a = 2.0 * u[0] - 1.0;
    let b = 2.0 * u[1] - 1.0;
    if a == 0.0 && b == 0.0 {
        return ([0.0, 0.0], 0.0);
    }
    // φ = (π/4)(b/a) in the a-dominant wedges, π/2 − (π/4)(a/b) in the others; with
    // x = (π/4)(a/b), cos φ = sin x and sin φ = cos x, so only |x| <= π/4 is ever needed.
    if a.abs() > b.abs() {
        let (s, c) = sin_cos_quarter((PI / 4.0) * (b / a));
        ([a * c, a * s], a.abs())
    } else {
        let (s, c) = sin_cos_quarter((PI / 4.0) * (a / b));
        ([b * s, b * c], b.abs())
    }
}

/// (sin x, cos x) for |x| <= π/4 from their Taylor series to x^17 and x^18 (remainders below
/// (π/4)^19/19! ≈ 1e-19 and (π/4)^20/20! ≈ 3e-21, far under an ulp), summed by Estrin's
/// scheme (a short dependency chain); the general-range library call with its argument
/// reduction costs several times more.
#[inline]
pub fn sin_cos_quarter(x: f64) -> (f64, f64) {
    // 1/n! for n = 2..=18
    const INV_FACT: [f64; 17] = {
        let mut f = [0.0; 17];
        let mut n = 2;
        let mut fact = 1.0;
        while n <= 18 {
            fact *= n as f64;
            f[n - 2] = 1.0 / fact;
            n += 1;
        }
        f
    };
    // every other one, from `first`
    const fn every_other<const N: usize>(first: usize) -> [f64; N] {
        let mut c = [0.0; N];
        let mut k = 0;
        while k < N {
            c[k] = INV_FACT[first + 2 * k];
            k += 1;
        }
        c
    }
    const ODD: [f64; 8] = every_other(1); // 1/3!, 1/5!, …, 1/17!
    const EVEN: [f64; 9] = every_other(0); // 1/2!, 1/4!, …, 1/18!
    let z = x * x;
    // Estrin's scheme (Estrin 1960, Proc. Western Joint Computer Conf., pp. 33-40) in w = −z:
    // pairs, then pairs of pairs, three multiply-adds deep instead of Horner's eight
    let w = -z;
    let w2 = w * w;
    let w4 = w2 * w2;
    let pair = |c: &[f64], k: usize| c[k] + w * c[k + 1];
    let odd = (pair(&ODD, 0) + w2 * pair(&ODD, 2)) + w4 * (pair(&ODD, 4) + w2 * pair(&ODD, 6));
    let even = (pair(&EVEN, 0) + w2 * pair(&EVEN, 2))
        + w4 * ((pair(&EVEN, 4) + w2 * pair(&EVEN, 6)) + w4 * EVEN[8]);
    let sin = x - x * z * odd;
    let cos = 1.0 - z * even;
    (sin, cos)
}

/// (sin 2πu, cos 2πu) for u in [0, 1] (an azimuth drawn as a fraction of a turn): the
/// quarter turn q and the rest f = 4u − q are exact, f folds to |x| ≤ π/4 about the nearer
/// quadrant, and [`sin_cos_quarter`] does the rest; the quadrant rotates the pair by a table
/// lookup, not a branch (the azimuth is random). It agrees with the library's sin and cos of
/// the rounded 2πu to 2 ulps plus that rounding (a unit test); cheaper than the general-range
/// call and its argument reduction.
#[inline]
pub fn sin_cos_turn(u: f64) -> (f64, f64) {
    let t = 4.0 * u;
    let q = t.floor();
    let f = t - q;
    // the nearer quadrant: x = (π/2)·f for f ≤ 1/2, (π/2)·(f − 1) of the next one above
    let up = f > 0.5;
    let x = (PI / 2.0) * if up { f - 1.0 } else { f };
    let (s, c) = sin_cos_quarter(x);
    // sin and cos of x + k·π/2 for k = 0..3 are s, c, −s, −c read from k and k + 1
    let k = ((q as i64 + i64::from(up)) & 3) as usize;
    let ring = [s, c, -s, -c];
    (ring[k], ring[(k + 1) & 3])
}

/// Direction `i` of `n` spread evenly over the unit sphere (a Fibonacci sphere: equal-area
/// bands in z, the golden angle between neighbours; González 2010, "Measurement of Areas on a
/// Sphere Using Fibonacci and Latitude–Longitude Lattices", Math. Geosci. 42(1)): a
/// deterministic probe of every direction.
pub fn fibonacci_sphere(i: usize, n: usize) -> Vec3 {
    let z = 1.0 - (2.0 * i as f64 + 1.0) / n as f64;
    let rho = (1.0 - z * z).max(0.0).sqrt();
    let phi = i as f64 * 2.399_963_229_728_653; // the golden angle π(3 − √5)
    Vec3::new(rho * phi.cos(), rho * phi.sin(), z)
}

/// Uniform direction on the unit sphere (Archimedes' hat-box theorem: z uniform in [-1,1]).
pub fn uniform_sphere(u: [f64; 2]) -> Vec3 {
    let z = 1.0 - 2.0 * u[0];
    let r = (1.0 - z * z).max(0.0).sqrt();
    let (sin, cos) = sin_cos_turn(u[1]);
    Vec3::new(r * cos, r * sin, z)
}

/// Pdf of [`uniform_sphere`]: 1/(4π) per steradian.
pub const UNIFORM_SPHERE_PDF: f64 = 0.25 * INV_PI;

/// Uniform barycentrics (b1, b2) on a triangle: b0 = 1 - b1 - b2
/// (Osada et al. 2002, "Shape distributions", ACM TOG 21(4), §4.2, the sqrt warp).
pub fn uniform_triangle(u: [f64; 2]) -> [f64; 2] {
    let s = u[0].sqrt();
    [1.0 - s, u[1] * s]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::rng::SampleStream;

    #[test]
    fn cosine_hemisphere_is_unit_and_upper() {
        let mut s = SampleStream::new(3, 0, 0);
        let mut mean_z = 0.0;
        let n = 100_000;
        for _ in 0..n {
            let w = cosine_hemisphere(s.next_2d());
            assert!((w.length() - 1.0).abs() < 1e-12);
            assert!(w.z >= 0.0);
            mean_z += w.z;
        }
        // E[cos θ] under cos/π is 2/3; std dev of cos is sqrt(1/2 - 4/9) ~ 0.236
        let se = 0.236 / (n as f64).sqrt();
        assert!((mean_z / n as f64 - 2.0 / 3.0).abs() < 5.0 * se);
    }

    #[test]
    fn uniform_sphere_mean_is_zero() {
        let mut s = SampleStream::new(4, 0, 0);
        let n = 100_000;
        let mut m = Vec3::ZERO;
        for _ in 0..n {
            m += uniform_sphere(s.next_2d());
        }
        m /= n as f64;
        // each component has variance 1/3
        let se = (1.0 / 3.0 / n as f64).sqrt();
        assert!(m.abs().max_element() < 5.0 * se);
    }

    #[test]
    fn uniform_triangle_barycentrics_are_valid_and_centred() {
        let mut s = SampleStream::new(5, 0, 0);
        let n = 100_000;
        let (mut m1, mut m2) = (0.0, 0.0);
        for _ in 0..n {
            let [b1, b2] = uniform_triangle(s.next_2d());
            assert!(b1 >= 0.0 && b2 >= 0.0 && b1 + b2 <= 1.0 + 1e-15);
            m1 += b1;
            m2 += b2;
        }
        // uniform barycentrics have mean 1/3 and variance 1/18
        let se = (1.0 / 18.0 / n as f64).sqrt();
        assert!((m1 / n as f64 - 1.0 / 3.0).abs() < 5.0 * se);
        assert!((m2 / n as f64 - 1.0 / 3.0).abs() < 5.0 * se);
    }

    #[test]
    fn sin_cos_turn_matches_the_library_to_two_ulps() {
        // every quadrant boundary and fold, and a fine sweep
        let mut us: Vec<f64> = (0..=8).map(|k| k as f64 / 8.0).collect();
        for &b in &[0.125, 0.25, 0.375, 0.5, 0.625, 0.75, 0.875] {
            us.extend([b - 1e-12, f64::next_down(b), f64::next_up(b), b + 1e-12]);
        }
        us.extend((0..200_000).map(|k| k as f64 / 200_000.0));
        us.push(f64::next_down(1.0));
        for u in us {
            let (s, c) = sin_cos_turn(u);
            let phi = 2.0 * PI * u;
            // 2 ulps of 1 (the larger of the two is at least 1/√2), plus the library's own
            // error from rounding 2πu (up to an ulp of it)
            let tol = (2.0 + phi) * f64::EPSILON;
            assert!(
                (s - phi.sin()).abs() <= tol,
                "sin(2π·{u}): {s} vs {}",
                phi.sin()
            );
            assert!(
                (c - phi.cos()).abs() <= tol,
                "cos(2π·{u}): {c} vs {}",
                phi.cos()
            );
        }
        assert_eq!(sin_cos_turn(0.0), (0.0, 1.0));
        assert_eq!(sin_cos_turn(0.25), (1.0, 0.0));
    }

    #[test]
    fn sin_cos_quarter_matches_the_library_to_an_ulp_or_two() {
        let q = PI / 4.0;
        for k in 0..=20_000 {
            let x = -q + 2.0 * q * k as f64 / 20_000.0;
            let (s, c) = sin_cos_quarter(x);
            assert!(
                (s - x.sin()).abs() <= 2.5e-16,
                "sin({x}): {s} vs {}",
                x.sin()
            );
            assert!(
                (c - x.cos()).abs() <= 2.5e-16,
                "cos({x}): {c} vs {}",
                x.cos()
            );
        }
    }
}
