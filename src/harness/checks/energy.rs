//! Energy conservation: the directional albedo a(wo) = ∫ f(wo, wi) η(wi)²/η(wo)² |cos θi| dωi
//! ≤ 1 for every BSDF and outgoing direction (Veach 1997, §6.2, eq. 6.6; the η² ratio turns the
//! radiance-carrying BTDF into the power it scatters, §5.2). Deterministic part: tensor-product
//! midpoint quadrature in (cos θi, φi) over the whole sphere, max over wo ≤ 1 + abs_tol, for
//! the models and angles the grid resolves (roughness ≥ registry::QUADRATURE_MIN_ROUGHNESS,
//! θo ≤ 60° for microfacet lobes, which the grid cannot follow towards the horizon).
//! Stochastic part: Monte Carlo estimates of a(wo) from BSDF sampling weights for every model
//! and angle (delta lobes included), and a fresh estimate at the largest, one-sided z test of
//! H0: a ≤ 1.

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
    let wl = registry::check_wavelengths();
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
    let wl = registry::check_wavelengths();
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
    r.is_infinite() || (r >= registry::QUADRATURE_MIN_ROUGHNESS && wo.z >= 0.5)
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
    let mut quad_max = (0.0f64, String::from("no model resolved by the grid"));
    let mut worst: Option<(f64, &dyn Bxdf, Vec3, usize, String)> = None;
    let mut rng = SampleStream::new(seed, 2, 0);
    let mut scanned = 0u64;
    let mut non_finite = 0u64;
    for (name, b) in models {
        for wo in outgoing(theta_max_deg) {
            let at = |k: usize| {
                format!(
                    "{name} at θo = {:.2}°, λ = {} nm",
                    wo.z.acos().to_degrees(),
                    wl.lambda[k]
                )
            };
            if quadrature_resolves(*b, wo) {
                let acc = power_albedo_quadrature(*b, wo, 512, 64);
                for (k, &v) in acc.iter().enumerate() {
                    if v > quad_max.0 || v.is_nan() {
                        quad_max = (v, at(k));
                    }
                }
            }
            let (mean, _, bad) = albedo_mc(*b, wo, samples / 5, &mut rng);
            scanned += samples / 5;
            non_finite += bad;
            for (k, &v) in mean.iter().enumerate() {
                if worst.as_ref().is_none_or(|w| v > w.0) {
                    worst = Some((v, *b, wo, k, at(k)));
                }
            }
        }
    }
    let Some((_, b, wo, k, where_)) = worst else {
        return Measurement {
            message: "no models".into(),
            deterministic_pass: Some(true),
            ..Default::default()
        };
    };
    let (mean, se, bad) = albedo_mc(b, wo, samples, &mut SampleStream::new(seed, 1, 0));
    non_finite += bad;
    let (mean, se) = (mean[k], se[k]);
    let t = z_test(mean, se, 1.0);
    // One-sided: only an albedo above 1 (beyond f64 rounding) is a violation.
    let excess = mean - 1.0 - super::ROUNDING;
    let p = if non_finite > 0 {
        0.0
    } else if se > 0.0 {
        normal_sf(excess / se)
    } else if excess > 0.0 {
        0.0
    } else {
        1.0
    };
    let a_max = quad_max.0;
    Measurement {
        estimate: Some(mean),
        std_error: Some(se),
        expected: Some(1.0),
        statistic: Some(Statistic::Tolerance { max_error: (a_max - 1.0).max(0.0), abs_tol, rel_tol: 0.0 }),
        p_value: Some(p),
        deterministic_pass: Some(a_max <= 1.0 + abs_tol),
        unstable: None,
        variants: 1,
        one_sided: true,
        samples: samples + scanned,
        message: format!(
            "largest albedo by quadrature {} ({}); largest Monte Carlo albedo at {where_}: {} ± {} (fresh {samples} samples, one-sided z {:.2} against 1); {non_finite} non-finite weights",
            fmt_sig(a_max),
            quad_max.1,
            fmt_sig(mean),
            fmt_sig(se),
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
