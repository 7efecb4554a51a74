//! The directional albedo of a BSDF, a(wo) = ∫ f(wo, wi) |cos θi| dωi, and its power form
//! with the η² ratio of refraction (Veach 1997, §5.2, §6.2 eq. 6.6): by midpoint quadrature over
//! the sphere and by Monte Carlo over the model's own sampling weights; the outgoing angles
//! every albedo-based kind tests.

use super::catalogue;
use crate::math::{rng::SampleStream, Vec3, PI};
use crate::scattering::Bxdf;
use crate::stats::MeanVar;

/// Directional albedo per wavelength component by midpoint quadrature: `n_mu` × `n_phi` cells
/// in (cos θi ∈ [−1, 1], φ), where dω = d(cos θ) dφ makes the cell weights exact.
pub fn albedo_quadrature(b: &dyn Bxdf, wo: Vec3, n_mu: usize, n_phi: usize) -> [f64; 4] {
    quadrature(b, wo, n_mu, n_phi, |_| [1.0; 4])
}

/// The same quadrature of the power albedo: each cell weighted by [`power_factor`].
pub fn power_albedo_quadrature(b: &dyn Bxdf, wo: Vec3, n_mu: usize, n_phi: usize) -> [f64; 4] {
    quadrature(b, wo, n_mu, n_phi, |wi| power_factor(b, wo, wi))
}

/// ∫ f(wo, wi)·factor(wi)·|cos θi| dωi per wavelength by the midpoint rule described above.
fn quadrature(
    b: &dyn Bxdf,
    wo: Vec3,
    n_mu: usize,
    n_phi: usize,
    factor: impl Fn(Vec3) -> [f64; 4],
) -> [f64; 4] {
    let wl = catalogue::check_wavelengths();
    let mut acc = [0.0; 4];
    let cell = (2.0 / n_mu as f64) * (2.0 * PI / n_phi as f64);
    for i in 0..n_mu {
        let mu = -1.0 + (i as f64 + 0.5) * 2.0 / n_mu as f64;
        let r = (1.0 - mu * mu).max(0.0).sqrt();
        for j in 0..n_phi {
            let phi = (j as f64 + 0.5) * 2.0 * PI / n_phi as f64;
            let wi = Vec3::new(r * phi.cos(), r * phi.sin(), mu);
            let f = b.eval(wo, wi, &wl);
            let k = factor(wi);
            for c in 0..4 {
                acc[c] += f.0[c] * k[c] * mu.abs() * cell;
            }
        }
    }
    acc
}

/// Outgoing directions tested: θo ∈ {0, 30, 60, 80, 89, θmax}°.
pub fn outgoing(theta_max_deg: f64) -> Vec<Vec3> {
    [0.0, 30.0, 60.0, 80.0, 89.0, theta_max_deg]
        .iter()
        .map(|t: &f64| Vec3::new(t.to_radians().sin(), 0.0, t.to_radians().cos()))
        .collect()
}

/// The ratio η(wi)²/η(wo)² per wavelength that turns scattered radiance into power.
pub fn power_factor(b: &dyn Bxdf, wo: Vec3, wi: Vec3) -> [f64; 4] {
    let wl = catalogue::check_wavelengths();
    let (eo, ei) = (b.eta(wo, &wl), b.eta(wi, &wl));
    std::array::from_fn(|k| (ei.0[k] / eo.0[k]).powi(2))
}

/// Monte Carlo estimate of the power albedo per wavelength from `samples` BSDF samples:
/// (mean, standard error, non-finite weights).
pub fn albedo_mc(
    b: &dyn Bxdf,
    wo: Vec3,
    samples: u64,
    rng: &mut SampleStream,
) -> ([f64; 4], [f64; 4], u64) {
    let wl = catalogue::check_wavelengths();
    let mut mv = [MeanVar::default(); 4];
    let mut bad = 0;
    for _ in 0..samples {
        let s = b.sample(wo, rng.next_2d(), rng.next_f64(), &wl);
        let (w, k) = match s {
            Some(s) => (s.weight.0, power_factor(b, wo, s.wi)),
            None => ([0.0; 4], [1.0; 4]),
        };
        for i in 0..4 {
            let v = w[i] * k[i];
            if v.is_finite() {
                mv[i].push(v);
            } else {
                bad += 1;
                mv[i].push(0.0);
            }
        }
    }
    (mv.map(|m| m.mean()), mv.map(|m| m.std_error()), bad)
}

/// True when the quadrature grid resolves the model at outgoing direction `wo`.
pub fn quadrature_resolves(b: &dyn Bxdf, wo: Vec3) -> bool {
    let r = b.roughness();
    r.is_infinite() || (r >= catalogue::QUADRATURE_MIN_ROUGHNESS && wo.z >= 0.5)
}
