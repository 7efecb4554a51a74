//! Warps from the unit square to directions and points, each with its pdf twin beside it.
//! Directions are local (z up) unless stated; pdfs are per unit solid angle or per unit area.

use super::{Vec3, INV_PI, PI};

/// Cosine-weighted hemisphere direction by Malley's method: a concentric disk sample
/// (Shirley & Chiu 1997, "A Low Distortion Map Between Disk and Square", JGT 2(3)) lifted to z.
pub fn cosine_hemisphere(u: [f64; 2]) -> Vec3 {
    let [dx, dy] = concentric_disk(u);
    let z = (1.0 - dx * dx - dy * dy).max(0.0).sqrt();
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
    let a = 2.0 * u[0] - 1.0;
    let b = 2.0 * u[1] - 1.0;
    if a == 0.0 && b == 0.0 {
        return [0.0, 0.0];
    }
    let (r, phi) = if a.abs() > b.abs() {
        (a, (PI / 4.0) * (b / a))
    } else {
        (b, PI / 2.0 - (PI / 4.0) * (a / b))
    };
    [r * phi.cos(), r * phi.sin()]
}

/// Uniform direction on the unit sphere (Archimedes' hat-box theorem: z uniform in [-1,1]).
pub fn uniform_sphere(u: [f64; 2]) -> Vec3 {
    let z = 1.0 - 2.0 * u[0];
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * PI * u[1];
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
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
}
