//! The test of one phase function against a claimed asymmetry g: ∫ p dω = 1 and the mean
//! cosine ∫ μ p dω = g by graded Gauss–Legendre quadrature in μ (deterministic, abs_tol), and
//! the sampling routine against p: chi-square of μ in bins of (nearly) equal mass whose
//! expected counts are integrated from `eval`, chi-square of φ against uniform, and a z test of
//! the sampled mean cosine against g, Šidák-combined. Used by the `hg` and `phase` kinds.

use crate::harness::measurement::{fmt_sig, Measurement};
use crate::harness::outcome::Statistic;
use crate::harness::under_test::{ModelError, PhaseModel, Precision};
use crate::math::warp;
use crate::math::{rng::SampleStream, Vec3, PI};
use crate::stats::{chi2::chi2_gof, z_test, MeanVar};
use std::cell::{Cell, RefCell};

// 8-point Gauss–Legendre nodes and weights on [−1, 1] (Abramowitz & Stegun, Table 25.4).
const GL_X: [f64; 4] = [
    0.183_434_642_495_649_8,
    0.525_532_409_916_329,
    0.796_666_477_413_626_7,
    0.960_289_856_497_536_3,
];
const GL_W: [f64; 4] = [
    0.362_683_783_378_362,
    0.313_706_645_877_887_3,
    0.222_381_034_453_374_5,
    0.101_228_536_290_376_3,
];

/// Panel edges on [−1, 1] refined geometrically towards both ends (where |g| → 1 peaks).
fn graded_edges() -> Vec<f64> {
    let k = 80;
    let mut upper: Vec<f64> = (0..=k)
        .map(|i| 1.0 - 10f64.powf(-14.0 + 14.0 * i as f64 / k as f64))
        .collect();
    upper.push(1.0);
    upper.sort_by(f64::total_cmp);
    let mut e: Vec<f64> = upper.iter().map(|x| -x).collect();
    e.extend(upper.iter().copied());
    e.sort_by(f64::total_cmp);
    e.dedup();
    e
}

/// ∫_a^b f(μ) dμ, splitting [a, b] at the graded edges and applying GL8 on each piece.
pub fn integrate_mu(f: &dyn Fn(f64) -> f64, a: f64, b: f64, edges: &[f64]) -> f64 {
    let mut pts = vec![a];
    pts.extend(edges.iter().copied().filter(|&x| x > a && x < b));
    pts.push(b);
    let mut sum = 0.0;
    for w in pts.windows(2) {
        let (c, h) = (0.5 * (w[0] + w[1]), 0.5 * (w[1] - w[0]));
        for i in 0..4 {
            sum += GL_W[i] * h * (f(c + h * GL_X[i]) + f(c - h * GL_X[i]));
        }
    }
    sum
}

/// Runs `compute`, which integrates p(μ) (the phase function at scattering cosine μ, wo = −z)
/// through the function it is given, twice: once to record the cosines it asks for, then with
/// the model's values for them from one batch. `compute`'s control flow must not depend on the
/// values; it then sees the same values in the same order as direct calls would give.
fn with_p_of_mu<T>(
    phase: &dyn PhaseModel,
    compute: impl Fn(&dyn Fn(f64) -> f64) -> T,
) -> Result<T, ModelError> {
    let wanted = RefCell::new(Vec::new());
    compute(&|mu| {
        wanted.borrow_mut().push(mu);
        0.0
    });
    let wo = Vec3::new(0.0, 0.0, -1.0);
    let rows: Vec<(Vec3, Vec3)> = wanted
        .into_inner()
        .iter()
        .map(|&mu| (wo, Vec3::new((1.0 - mu * mu).max(0.0).sqrt(), 0.0, mu)))
        .collect();
    let values = phase.eval(&rows)?;
    let next = Cell::new(0);
    Ok(compute(&|_| {
        let i = next.get();
        next.set(i + 1);
        values.get(i).copied().unwrap_or(f64::NAN)
    }))
}

/// Measures one phase function claimed to have mean cosine `g`, in f64, against its own eval.
pub fn measure_phase(
    phase: &dyn PhaseModel,
    g: f64,
    abs_tol: f64,
    samples: u64,
    mu_bins: usize,
    phi_bins: usize,
    seed: u64,
) -> Result<Measurement, ModelError> {
    let precision = Precision::F64;
    measure_phase_at(
        phase,
        g,
        abs_tol,
        samples,
        [mu_bins, phi_bins],
        seed,
        precision,
        None,
    )
}

/// Relative error a model computing in `precision` makes in an HG-like p(μ) near its peak:
/// 1 + g² − 2gμ is a difference of numbers near 2 rounded to ε each, relative to its minimum
/// (1 − |g|)², and p goes as its −3/2 power: 3ε/(1 − |g|)².
pub fn eval_conditioning(g: f64, precision: Precision) -> f64 {
    3.0 * precision.unit_roundoff() / ((1.0 - g.abs()) * (1.0 - g.abs())).max(f64::MIN_POSITIVE)
}

/// Above this relative eval error, the χ²(μ) expected counts do not come from the model's eval:
/// from `reference` when given (the closed form the model claims), else the μ test is left out.
pub const EVAL_TRUST: f64 = 1e-4;

/// [`measure_phase`] of a model computing in `precision`: no μ bin is made narrower than the
/// directions resolve near ±1 ([`Precision::mu_resolution`]), so rounding that piles samples
/// onto μ = ±1 is not taken for a wrong distribution; the quadrature identities are held to
/// max(abs_tol, [`eval_conditioning`]); and where the eval is too ill-conditioned to give
/// expected counts ([`EVAL_TRUST`]), `reference` (p(μ) in sr⁻¹, the closed form the model
/// claims) gives them, or the μ test is left out and the message says so.
#[allow(clippy::too_many_arguments)]
pub fn measure_phase_at(
    phase: &dyn PhaseModel,
    g: f64,
    abs_tol: f64,
    samples: u64,
    [mu_bins, phi_bins]: [usize; 2],
    seed: u64,
    precision: Precision,
    reference: Option<&dyn Fn(f64) -> f64>,
) -> Result<Measurement, ModelError> {
    let resolution = precision.mu_resolution();
    let conditioning = eval_conditioning(g, precision);
    let abs_tol = abs_tol.max(conditioning);
    let trusted = conditioning <= EVAL_TRUST;
    let edges = graded_edges();
    // ∫p dω, ∫μ p dω and the cumulative table on the graded grid, from one batch of p(μ)
    let (norm, mean_cos, second, cum) = with_p_of_mu(phase, |p| {
        let norm = 2.0 * PI * integrate_mu(&|m| p(m), -1.0, 1.0, &edges);
        let mean_cos = 2.0 * PI * integrate_mu(&|m| m * p(m), -1.0, 1.0, &edges);
        let second = 2.0 * PI * integrate_mu(&|m| m * m * p(m), -1.0, 1.0, &edges);
        let mut cum = vec![0.0];
        for w in edges.windows(2) {
            let last = *cum.last().unwrap_or(&0.0);
            cum.push(last + 2.0 * PI * integrate_mu(&|m| p(m), w[0], w[1], &[]));
        }
        (norm, mean_cos, second, cum)
    })?;
    // with the closed form the model claims, its shape too: p(μ) against it at every grid
    // cosine, relative (∫p = 1 and ⟨μ⟩ = g alone pass any normalised lobe of that mean)
    let shape_err = match reference {
        Some(r) if trusted => with_p_of_mu(phase, |p| {
            edges
                .iter()
                .map(|&m| ((p(m) - r(m)) / r(m)).abs())
                .fold(0.0, f64::max)
        })?,
        _ => 0.0,
    };
    let det_err = (norm - 1.0).abs().max((mean_cos - g).abs()).max(shape_err);
    // μ bins: edges at near-equal mass from the cumulative table.
    let total = *cum.last().unwrap_or(&1.0);
    let mut bin_edges = vec![-1.0];
    for q in 1..mu_bins {
        let target = total * q as f64 / mu_bins as f64;
        let i = cum
            .partition_point(|&c| c < target)
            .clamp(1, edges.len() - 1);
        let t = (target - cum[i - 1]) / (cum[i] - cum[i - 1]).max(f64::MIN_POSITIVE);
        let e = edges[i - 1] + t.clamp(0.0, 1.0) * (edges[i] - edges[i - 1]);
        if e > *bin_edges.last().unwrap_or(&-1.0) + resolution && e < 1.0 - resolution {
            bin_edges.push(e);
        }
    }
    bin_edges.push(1.0);
    let counts_from = |p: &dyn Fn(f64) -> f64| -> Vec<f64> {
        bin_edges
            .windows(2)
            .map(|w| samples as f64 * 2.0 * PI * integrate_mu(&|m| p(m), w[0], w[1], &edges))
            .collect()
    };
    let expected: Vec<f64> = match reference {
        Some(r) if !trusted => counts_from(r),
        _ => with_p_of_mu(phase, counts_from)?,
    };
    let mu_source = match (trusted, reference.is_some()) {
        (true, _) => "",
        (false, true) => " (χ²(μ) expected counts from the closed form: the eval's float rounding alone reaches this)",
        (false, false) => " (χ²(μ) left out: the eval's float rounding alone reaches this)",
    };
    let mut counts = vec![0u64; expected.len()];
    let mut phi_counts = vec![0u64; phi_bins];
    let mut mv = MeanVar::default();
    let mut rng = SampleStream::new(seed, 2, 0);
    let wo = Vec3::new(0.0, 0.0, -1.0);
    let rows: Vec<_> = (0..samples).map(|_| (wo, rng.next_2d())).collect();
    for s in phase.sample(&rows)? {
        let mu = s.wi.z.clamp(-1.0, 1.0);
        mv.push(mu);
        let b = bin_edges
            .partition_point(|&e| e <= mu)
            .clamp(1, counts.len())
            - 1;
        counts[b] += 1;
        // A draw on the axis (x = y = 0, as rounding makes of μ within ε of ±1) has no φ.
        if s.wi.x != 0.0 || s.wi.y != 0.0 {
            let phi = s.wi.y.atan2(s.wi.x).rem_euclid(2.0 * PI);
            phi_counts[((phi / (2.0 * PI) * phi_bins as f64) as usize).min(phi_bins - 1)] += 1;
        }
    }
    let on_axis = samples - phi_counts.iter().sum::<u64>();
    let chi_mu = chi2_gof(&counts, &expected, 5.0);
    let chi_phi = chi2_gof(
        &phi_counts,
        &vec![(samples - on_axis) as f64 / phi_bins as f64; phi_bins],
        5.0,
    );
    // Under H0 (draws from the claimed p) the sampled mean cosine has variance Var_p(μ)/N,
    // known by quadrature; near |g| = 1 the sample variance of 10^5 draws underestimates it
    // (its mass is in rare back-scattered draws), so the larger of the two is used.
    let se_null = ((second - mean_cos * mean_cos).max(0.0) / samples as f64).sqrt();
    let se = mv.std_error().max(se_null);
    let t = z_test(mv.mean(), se, g);
    // A chi-square that cannot be formed gives a NaN p-value: the check is an ERROR, not a FAIL.
    let (chi, dof, p_mu) = match &chi_mu {
        Ok(c) => (c.chi2, c.dof, c.p_value),
        Err(_) => (f64::NAN, 0, f64::NAN),
    };
    let p_phi = chi_phi.as_ref().map_or(f64::NAN, |c| c.p_value);
    // The tests share samples, so they are combined by Bonferroni, min(1, k·p_min), which
    // holds under any dependence.
    let ps: Vec<f64> = if trusted || reference.is_some() {
        vec![p_mu, p_phi, t.p]
    } else {
        vec![p_phi, t.p]
    };
    let p_combined = if ps.iter().any(|p| p.is_nan()) {
        f64::NAN
    } else {
        (ps.len() as f64 * ps.iter().copied().fold(1.0, f64::min)).min(1.0)
    };
    Ok(Measurement {
        power_std_error: None,
        power_scale: None,
        power_chi_square: None,
        estimate: Some(mv.mean()),
        std_error: Some(se),
        expected: Some(g),
        statistic: Some(Statistic::ChiSquare { chi2: chi, dof }),
        p_value: Some(p_combined),
        deterministic_pass: Some(det_err <= abs_tol),
        unstable: None,
        retested: false,
        heavy_tail: None,
        variants: 3,
        one_sided: false,
        regression: false,
        rel_tolerance: None,
        samples,
        message: format!(
            "g = {g}: ∫p dω = {} and mean cosine {} by quadrature{} (|error| {:.1e} vs abs_tol {abs_tol:.0e}{}); sampled mean cosine {} ± {} (larger of sample {} and null √(Var_p μ/N) {}); χ²(μ) p {}{mu_source}, χ²(φ) p {} ({on_axis} draws on the axis left out)",
            fmt_sig(norm),
            fmt_sig(mean_cos),
            if reference.is_some() && trusted {
                format!(", p(μ) against the closed form at {} cosines (largest relative difference {shape_err:.1e})", edges.len())
            } else {
                String::new()
            },
            det_err,
            if conditioning > 1e-12 {
                format!(", at least the {} eval's rounding 3ε/(1−|g|)² = {conditioning:.1e}", precision.name())
            } else {
                String::new()
            },
            fmt_sig(mv.mean()),
            fmt_sig(se),
            fmt_sig(mv.std_error()),
            fmt_sig(se_null),
            fmt_sig(p_mu),
            fmt_sig(p_phi)
        ),
    })
}

/// Largest relative asymmetry |p(wo, wi) − p(wi, wo)|/p, and largest relative mismatch
/// |pdf(wo, wi) − sample.pdf|/pdf, over `pairs` random directions (infinite for a non-finite
/// value or a sampled direction whose length is further than `unit_tol` from 1).
pub fn reciprocity_error(
    phase: &dyn PhaseModel,
    pairs: u64,
    seed: u64,
    unit_tol: f64,
) -> Result<(f64, f64), ModelError> {
    let mut rng = SampleStream::new(seed, 3, 0);
    let (mut worst, mut worst_pdf) = (0.0f64, 0.0f64);
    let mut fwd = Vec::new();
    let mut rows = Vec::new();
    for _ in 0..pairs {
        let wo = warp::uniform_sphere(rng.next_2d());
        let wi = warp::uniform_sphere(rng.next_2d());
        fwd.push((wo, wi));
        rows.push((wo, rng.next_2d()));
    }
    let back: Vec<(Vec3, Vec3)> = fwd.iter().map(|&(wo, wi)| (wi, wo)).collect();
    let (pa, pb) = (phase.eval(&fwd)?, phase.eval(&back)?);
    let drawn = phase.sample(&rows)?;
    let at: Vec<(Vec3, Vec3)> = rows.iter().zip(&drawn).map(|(r, s)| (r.0, s.wi)).collect();
    let pdfs = phase.pdf(&at)?;
    for (((a, b), s), p) in pa.iter().zip(&pb).zip(&drawn).zip(&pdfs) {
        worst = worst.max((a - b).abs() / a.abs().max(b.abs()).max(f64::MIN_POSITIVE));
        worst_pdf = worst_pdf.max((p - s.pdf).abs() / p.max(f64::MIN_POSITIVE));
        if !(a.is_finite()
            && b.is_finite()
            && p.is_finite()
            && s.pdf.is_finite()
            && s.weight.is_finite()
            && s.wi.is_finite()
            && (s.wi.length() - 1.0).abs() < unit_tol)
        {
            return Ok((f64::INFINITY, f64::INFINITY));
        }
    }
    Ok((worst, worst_pdf))
}

/// Allowed relative mismatch between a sample's pdf (computed from the sampled cosine) and
/// `pdf` of the returned direction (from the direction vector): at g = 0.9999 the rounding of
/// μ (~1e-16) is amplified by d ln p/dμ ≈ 3/(1 − g)² = 3e8.
pub const PDF_REL_TOL: f64 = 1e-6;
