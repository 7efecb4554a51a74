//! The directional albedo of a BSDF, a(wo) = ∫ f(wo, wi) |cos θi| dωi, and its power form
//! with the η² ratio of refraction (Veach 1997, §5.2, §6.2 eq. 6.6): by midpoint quadrature over
//! the sphere and by Monte Carlo over the model's own sampling weights; the outgoing angles
//! every albedo-based kind tests.

use super::catalogue;
use crate::harness::under_test::{BsdfModel, ModelError};
use crate::math::{rng::SampleStream, Vec3, PI};
use crate::stats::MeanVar;

/// Directional albedo per wavelength component by midpoint quadrature: `n_mu` × `n_phi` cells
/// in (cos θi ∈ [−1, 1], φ), where dω = d(cos θ) dφ makes the cell weights exact.
pub fn albedo_quadrature(
    b: &dyn BsdfModel,
    wo: Vec3,
    n_mu: usize,
    n_phi: usize,
) -> Result<[f64; 4], ModelError> {
    quadrature(b, wo, n_mu, n_phi, false)
}

/// The same quadrature of the power albedo: each cell weighted by [`power_factors`].
pub fn power_albedo_quadrature(
    b: &dyn BsdfModel,
    wo: Vec3,
    n_mu: usize,
    n_phi: usize,
) -> Result<[f64; 4], ModelError> {
    quadrature(b, wo, n_mu, n_phi, true)
}

/// ∫ f(wo, wi)·factor(wi)·|cos θi| dωi per wavelength by the midpoint rule described above,
/// the factor being η(wi)²/η(wo)² when `power` (else 1).
fn quadrature(
    b: &dyn BsdfModel,
    wo: Vec3,
    n_mu: usize,
    n_phi: usize,
    power: bool,
) -> Result<[f64; 4], ModelError> {
    let wl = catalogue::check_wavelengths();
    let cell = (2.0 / n_mu as f64) * (2.0 * PI / n_phi as f64);
    let mut rows = Vec::with_capacity(n_mu * n_phi);
    let mut mus = Vec::with_capacity(n_mu * n_phi);
    for i in 0..n_mu {
        let mu = -1.0 + (i as f64 + 0.5) * 2.0 / n_mu as f64;
        let r = (1.0 - mu * mu).max(0.0).sqrt();
        for j in 0..n_phi {
            let phi = (j as f64 + 0.5) * 2.0 * PI / n_phi as f64;
            rows.push((wo, Vec3::new(r * phi.cos(), r * phi.sin(), mu)));
            mus.push(mu);
        }
    }
    let f = b.eval(&rows, &wl)?;
    let k = if power {
        let wi: Vec<Vec3> = rows.iter().map(|r| r.1).collect();
        power_factors(b, wo, &wi)?
    } else {
        vec![[1.0; 4]; rows.len()]
    };
    let mut acc = [0.0; 4];
    for ((f, k), mu) in f.iter().zip(&k).zip(&mus) {
        for c in 0..4 {
            acc[c] += f.0[c] * k[c] * mu.abs() * cell;
        }
    }
    Ok(acc)
}

/// Outgoing directions tested: θo ∈ {0, 30, 60, 80, 89, θmax}°.
pub fn outgoing(theta_max_deg: f64) -> Vec<Vec3> {
    [0.0, 30.0, 60.0, 80.0, 89.0, theta_max_deg]
        .iter()
        .map(|t: &f64| Vec3::new(t.to_radians().sin(), 0.0, t.to_radians().cos()))
        .collect()
}

/// The ratio η(wi)²/η(wo)² per wavelength, for each `wi`, that turns scattered radiance into
/// power (Veach 1997, §5.2).
pub fn power_factors(
    b: &dyn BsdfModel,
    wo: Vec3,
    wi: &[Vec3],
) -> Result<Vec<[f64; 4]>, ModelError> {
    let wl = catalogue::check_wavelengths();
    let eo = b.eta(&[wo], &wl)?[0];
    Ok(b.eta(wi, &wl)?
        .iter()
        .map(|ei| std::array::from_fn(|k| (ei.0[k] / eo.0[k]).powi(2)))
        .collect())
}

/// Monte Carlo estimate of the power albedo per wavelength from `samples` BSDF samples:
/// (mean, standard error, non-finite weights).
pub fn albedo_mc(
    b: &dyn BsdfModel,
    wo: Vec3,
    samples: u64,
    rng: &mut SampleStream,
) -> Result<([f64; 4], [f64; 4], u64), ModelError> {
    let wl = catalogue::check_wavelengths();
    let rows: Vec<_> = (0..samples)
        .map(|_| (wo, rng.next_2d(), rng.next_f64()))
        .collect();
    let drawn = b.sample(&rows, &wl)?;
    let wi: Vec<Vec3> = drawn.iter().flatten().map(|s| s.wi).collect();
    let mut factors = power_factors(b, wo, &wi)?.into_iter();
    let mut mv = [MeanVar::default(); 4];
    let mut bad = 0;
    for s in &drawn {
        let (w, k) = match s {
            Some(s) => (s.weight.0, factors.next().unwrap_or([1.0; 4])),
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
    Ok((mv.map(|m| m.mean()), mv.map(|m| m.std_error()), bad))
}

/// True when the quadrature grid resolves the model at outgoing direction `wo`.
pub fn quadrature_resolves(b: &dyn BsdfModel, wo: Vec3) -> bool {
    let r = b.flags().min_roughness;
    r.is_infinite() || (r >= catalogue::QUADRATURE_MIN_ROUGHNESS && wo.z >= 0.5)
}
