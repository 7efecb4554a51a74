//! Test directions for model checks: random directions over both hemispheres down to a grazing
//! limit, with every eighth exactly at the limit.

use crate::math::{rng::SampleStream, Vec3, PI};

/// A random direction with |cos θ| ≥ cos(θmax), either hemisphere; every 8th one exactly at θmax.
pub fn direction(rng: &mut SampleStream, theta_max_deg: f64, i: u64) -> Vec3 {
    let cmin = theta_max_deg.to_radians().cos();
    let z = if i % 8 == 7 {
        cmin
    } else {
        cmin + (1.0 - cmin) * rng.next_f64()
    };
    let z = if rng.next_f64() < 0.5 { z } else { -z };
    let phi = 2.0 * PI * rng.next_f64();
    let r = (1.0 - z * z).max(0.0).sqrt();
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}
