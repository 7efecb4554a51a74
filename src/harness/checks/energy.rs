//! Energy conservation: the directional albedo a(wo) = ∫ f(wo, wi) |cos θi| dωi ≤ 1 for every
//! BSDF and outgoing direction (Veach 1997, §6.2, eq. 6.6). Deterministic part: tensor-product
//! midpoint quadrature in (cos θi, φi) over the whole sphere, max over wo ≤ 1 + abs_tol.
//! Stochastic part: the Monte Carlo estimate of a(wo) from BSDF sampling weights at the worst
//! wo, one-sided z test of H0: a ≤ 1.

use super::fmt_sig;
use crate::harness::manifest::CheckSpec;
use crate::harness::outcome::Statistic;
use crate::harness::{registry, Context, Measurement};
use crate::math::{rng::SampleStream, Vec3, PI};
use crate::scattering::Bxdf;
use crate::stats::{normal_sf, z_test, MeanVar};

/// Directional albedo per wavelength component by midpoint quadrature: `n_mu` × `n_phi` cells
/// in (cos θi ∈ [−1, 1], φ), where dω = d(cos θ) dφ makes the cell weights exact.
pub fn albedo_quadrature(b: &dyn Bxdf, wo: Vec3, n_mu: usize, n_phi: usize) -> [f64; 4] {
    let wl = registry::check_wavelengths();
    let mut acc = [0.0; 4];
    let cell = (2.0 / n_mu as f64) * (2.0 * PI / n_phi as f64);
    for i in 0..n_mu {
        let mu = -1.0 + (i as f64 + 0.5) * 2.0 / n_mu as f64;
        let r = (1.0 - mu * mu).max(0.0).sqrt();
        for j in 0..n_phi {
            let phi = (j as f64 + 0.5) * 2.0 * PI / n_phi as f64;
            let wi = Vec3::new(r * phi.cos(), r * phi.sin(), mu);
            let f = b.eval(wo, wi, &wl);
            for (a, fk) in acc.iter_mut().zip(f.0) {
                *a += fk * mu.abs() * cell;
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

/// Measures energy conservation of each named model.
pub fn measure(
    models: &[(String, &dyn Bxdf)],
    theta_max_deg: f64,
    abs_tol: f64,
    samples: u64,
    seed: u64,
) -> Measurement {
    let wl = registry::check_wavelengths();
    let mut worst: Option<(f64, String, &dyn Bxdf, Vec3, usize)> = None;
    for (name, b) in models {
        for wo in outgoing(theta_max_deg) {
            let a = albedo_quadrature(*b, wo, 512, 64);
            for (k, &v) in a.iter().enumerate() {
                if worst.as_ref().is_none_or(|w| v > w.0) {
                    worst = Some((
                        v,
                        format!(
                            "{name} at θo = {:.2}°, λ = {} nm",
                            wo.z.acos().to_degrees(),
                            wl.lambda[k]
                        ),
                        *b,
                        wo,
                        k,
                    ));
                }
            }
        }
    }
    let Some((a_max, where_, b, wo, k)) = worst else {
        return Measurement {
            message: "no models".into(),
            deterministic_pass: Some(true),
            ..Default::default()
        };
    };
    let mut rng = SampleStream::new(seed, 1, 0);
    let mut mv = MeanVar::default();
    for _ in 0..samples {
        let w = b
            .sample(wo, rng.next_2d(), rng.next_f64(), &wl)
            .map_or(0.0, |s| s.weight.0[k]);
        mv.push(w);
    }
    let t = z_test(mv.mean(), mv.std_error(), 1.0);
    // One-sided: only an albedo above 1 (beyond f64 rounding) is a violation.
    let excess = mv.mean() - 1.0 - super::ROUNDING;
    let p = if mv.std_error() > 0.0 {
        normal_sf(excess / mv.std_error())
    } else if excess > 0.0 {
        0.0
    } else {
        1.0
    };
    Measurement {
        estimate: Some(mv.mean()),
        std_error: Some(mv.std_error()),
        expected: Some(a_max),
        statistic: Some(Statistic::Tolerance { max_error: (a_max - 1.0).max(0.0), abs_tol, rel_tol: 0.0 }),
        p_value: Some(p),
        deterministic_pass: Some(a_max <= 1.0 + abs_tol),
        unstable: None,
        variants: 1,
        one_sided: true,
        samples: samples + (models.len() * 6 * 512 * 64) as u64,
        message: format!(
            "largest albedo by quadrature {} ({where_}); Monte Carlo there {} ± {} (one-sided z {:.2} against 1)",
            fmt_sig(a_max),
            fmt_sig(mv.mean()),
            fmt_sig(mv.std_error()),
            t.z
        ),
    }
}

/// Runs the energy check over every registered BSDF.
pub fn run(spec: &CheckSpec, ctx: &Context) -> Result<Measurement, String> {
    let models = registry::bsdfs();
    let refs = registry::as_bxdfs(&models);
    let p = &spec.params;
    Ok(measure(
        &refs,
        p.theta_max_deg.unwrap_or(89.9),
        p.abs_tol.unwrap_or(1e-6),
        p.samples.unwrap_or(100_000),
        ctx.seed,
    ))
}
