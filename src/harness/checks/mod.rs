//! The check kinds, one file each, and the helpers scene-level kinds share: rendering a
//! region of an image and turning it into a mean, a standard error and a stability verdict.

pub mod albedo;
pub mod chi2;
pub mod convergence;
pub mod energy;
pub mod estimators;
pub mod furnace;
pub mod half_space;
pub mod hg;
pub mod image;
pub mod lambert;
pub mod measured;
pub mod phase;
pub mod radiance;
pub mod reciprocity;
pub mod reciprocity_image;
pub mod scale;
pub mod smooth_limit;
pub mod transmittance;
pub mod weights;

use super::manifest::{CheckSpec, RenderOverrides};
use super::{Context, Measurement};
use crate::film::Film;
use crate::integrators::{PathTracer, Strategy};
use crate::render::RenderSettings;
use crate::scene::Scene;
use crate::stats::{normal_sf, stability, z_test};

/// Runs one check.
pub fn run(spec: &CheckSpec, ctx: &Context) -> Result<Measurement, String> {
    match spec.kind.as_str() {
        "furnace" => furnace::run(spec, ctx),
        "lambert" => lambert::run(spec, ctx),
        "reciprocity" => reciprocity::run(spec, ctx),
        "energy" => energy::run(spec, ctx),
        "albedo" => albedo::run(spec, ctx),
        "smooth_limit" => smooth_limit::run(spec, ctx),
        "hg" => hg::run(spec, ctx),
        "phase" => phase::run(spec, ctx),
        "chi2" => chi2::run(spec, ctx),
        "radiance_invariance" => radiance::run(spec, ctx),
        "estimator_agreement" => estimators::run(spec, ctx),
        "sample_weights" => weights::run(spec, ctx),
        "scale_invariance" => scale::run(spec, ctx),
        "image_compare" => image::run(spec, ctx),
        "measured" => measured::run(spec, ctx),
        "convergence" => convergence::run(spec, ctx),
        "reciprocity_image" => reciprocity_image::run(spec, ctx),
        "transmittance" => transmittance::run(spec, ctx),
        "half_space" => half_space::run(spec, ctx),
        other => Err(format!("unknown check kind {other:?}")),
    }
}

/// Statistics of the Y channel over a pixel region of a rendered image.
#[derive(Debug, Clone, PartialEq)]
pub struct RegionStats {
    /// Mean of the pixel means (the box-filtered radiance averaged over the region; Y).
    pub mean: f64,
    /// Standard error used by the test: the larger of the within-pixel estimate and (for
    /// homoscedastic regions of at least 16 pixels) the batch-means estimate over pixels,
    /// each pixel mean being a batch of spp samples.
    pub se: f64,
    /// Standard error from the per-pixel sample variances, √(Σ s²ᵢ/nᵢ)/N.
    pub se_within: f64,
    /// Standard error from the spread of the pixel residuals, sd(r)/√N (0 when not used).
    pub se_between: f64,
    /// Pixels in the region.
    pub pixels: usize,
    /// Camera paths traced for the whole image.
    pub samples: u64,
    /// Whether the variance settled (stats::stability on the pixel residuals).
    pub stable: bool,
    /// The diagnosis with its numbers.
    pub stability: String,
}

/// Image size, spp and region of a scene-level check.
pub fn settings_for(
    spec: &CheckSpec,
    scene: &Scene,
    ctx: &Context,
    seed: u64,
    max_depth: Option<u32>,
    strategy: Strategy,
) -> RenderSettings {
    let ov: &RenderOverrides = &spec.render;
    RenderSettings {
        width: ov.width.unwrap_or(scene.render.width),
        height: ov.height.unwrap_or(scene.render.height),
        spp: ov.spp.unwrap_or(scene.render.spp),
        seed,
        threads: ctx.threads,
        integrator: PathTracer {
            max_depth,
            rr_depth: if ov.roulette { Some(5) } else { None },
            strategy,
            force_media_code: false,
        },
        observer: Default::default(),
        sampler: spec.params.sampler,
        spectral: Default::default(),
    }
}

/// The region [x0, y0, x1, y1) of a check, checked against the image size.
pub fn region_of(spec: &CheckSpec, s: &RenderSettings) -> Result<[usize; 4], String> {
    let r = spec.render.region.unwrap_or([0, 0, s.width, s.height]);
    if r[2] > s.width || r[3] > s.height {
        return Err(format!(
            "region {r:?} does not fit the {}x{} image",
            s.width, s.height
        ));
    }
    Ok(r)
}

/// Renders with `settings` and measures the Y channel over `region`; `expected_px` are the
/// closed-form pixel values (row-major within the region) when the image is not uniform.
pub fn render_region(
    ctx: &Context,
    scene: &Scene,
    settings: &RenderSettings,
    region: [usize; 4],
    expected_px: Option<&[f64]>,
    diag_alpha: f64,
) -> Result<RegionStats, String> {
    let film = ctx.renderer.render(scene, settings)?;
    Ok(region_stats(
        &film,
        region,
        settings.spp,
        diag_alpha,
        expected_px,
    ))
}

/// The false-alarm level of each variance diagnosis in a check with `diagnoses` diagnosed
/// images: the diagnosis has two criteria, so α/(2·diagnoses) keeps a check's UNSTABLE
/// false alarms at or below its per-test α.
pub fn diagnosis_alpha(ctx: &Context, diagnoses: usize) -> f64 {
    ctx.alpha / (2.0 * diagnoses.max(1) as f64)
}

/// Pixel means and variances of the mean (Y) over a region, row-major.
pub fn region_pixels(film: &Film, region: [usize; 4]) -> (Vec<f64>, Vec<f64>) {
    region_pixels_of(film, region, 1)
}

/// Pixel means and variances of the mean of XYZ `channel` (0, 1, 2) over a region.
pub fn region_pixels_of(film: &Film, region: [usize; 4], channel: usize) -> (Vec<f64>, Vec<f64>) {
    let means = film.means(channel);
    let vars = film.mean_variances(channel);
    let mut m = Vec::new();
    let mut v = Vec::new();
    for y in region[1]..region[3] {
        for x in region[0]..region[2] {
            m.push(means[y * film.width + x]);
            v.push(vars[y * film.width + x]);
        }
    }
    (m, v)
}

/// Region statistics of a film's Y channel; `expected_px` are the closed-form pixel values
/// (None: the image is expected to be uniform).
pub fn region_stats(
    film: &Film,
    region: [usize; 4],
    spp: u64,
    alpha: f64,
    expected_px: Option<&[f64]>,
) -> RegionStats {
    region_stats_of(film, region, spp, alpha, expected_px, 1)
}

/// [`region_stats`] of XYZ `channel` (0 = X, 1 = Y, 2 = Z).
pub fn region_stats_of(
    film: &Film,
    region: [usize; 4],
    spp: u64,
    alpha: f64,
    expected_px: Option<&[f64]>,
    channel: usize,
) -> RegionStats {
    let (px, vars) = region_pixels_of(film, region, channel);
    let n = px.len() as f64;
    let mean = px.iter().sum::<f64>() / n;
    let se_within = vars.iter().sum::<f64>().sqrt() / n;
    let samples = (film.width * film.height) as u64 * spp;
    let resid: Vec<f64> = match expected_px {
        Some(e) => px.iter().zip(e).map(|(m, e)| m - e).collect(),
        None => px.iter().map(|m| m - mean).collect(),
    };
    let scale = px.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    if spp < 2 {
        let why =
            "spp < 2: one sample per pixel gives no variance estimate, so no test is possible"
                .to_string();
        return RegionStats {
            mean,
            se: se_within,
            se_within,
            se_between: 0.0,
            pixels: px.len(),
            samples,
            stable: false,
            stability: why,
        };
    }
    let (stable, stability, se_between) = residual_stability(&resid, &vars, scale, alpha);
    RegionStats {
        mean,
        se: se_within.max(se_between),
        se_within,
        se_between,
        pixels: px.len(),
        samples,
        stable,
        stability,
    }
}

/// Variance diagnosis of per-pixel residuals rᵢ (zero mean under the null hypothesis) whose
/// variances are `vars`: returns (stable, the diagnosis, batch-means standard error of their
/// mean). Residuals are standardised by their own standard errors first when the variances
/// differ by more than 100× (emitters in view), so that bright pixels do not pass for a heavy
/// tail; the batch-means standard error is then not used (0). Residuals without Monte Carlo
/// noise (all variances below (1e-12·scale)²) are reported as deterministic.
pub fn residual_stability(
    resid: &[f64],
    vars: &[f64],
    scale: f64,
    alpha: f64,
) -> (bool, String, f64) {
    if vars.iter().all(|v| *v <= (1e-12 * scale).powi(2)) {
        return (
            true,
            "no Monte Carlo noise: every pixel is exact up to rounding".into(),
            0.0,
        );
    }
    let n = resid.len() as f64;
    let mut sorted: Vec<f64> = vars.iter().copied().filter(|v| *v > 0.0).collect();
    sorted.sort_by(f64::total_cmp);
    let median = sorted.get(sorted.len() / 2).copied().unwrap_or(0.0);
    let hetero = median > 0.0 && sorted.last().copied().unwrap_or(0.0) > 100.0 * median;
    let values: Vec<f64> = if hetero {
        resid
            .iter()
            .zip(vars)
            .filter(|(_, v)| **v > 0.0)
            .map(|(r, v)| r / v.sqrt())
            .collect()
    } else {
        resid.to_vec()
    };
    let diag = stability::diagnose(&values, alpha);
    let se_between = if !hetero && resid.len() >= 16 {
        let rm = resid.iter().sum::<f64>() / n;
        (resid.iter().map(|r| (r - rm) * (r - rm)).sum::<f64>() / (n - 1.0) / n).sqrt()
    } else {
        0.0
    };
    let reason = format!(
        "{}{}",
        if hetero {
            "standardised residuals: "
        } else {
            ""
        },
        diag.reason
    );
    (diag.stable, reason, se_between)
}

/// Relative allowance for f64 rounding in the comparison of an estimate with its closed form
/// (accumulation and quadrature of a zero-variance estimator differ from the closed form by
/// ~1e-15 relative; 1e-12 is far above that and far below any physical effect).
pub const ROUNDING: f64 = 1e-12;

/// Two-sided z test of `estimate` ± `se` against `expected`, after allowing a stated relative
/// model tolerance and the f64 rounding allowance [`ROUNDING`]:
/// z = sign(est − exp)·max(0, |est − exp| − tol·|exp| − 1e-12·max(|exp|, |est|))/se.
/// Returns (z, p).
pub fn z_with_tolerance(estimate: f64, se: f64, expected: f64, rel_tolerance: f64) -> (f64, f64) {
    // A NaN or infinite input must never turn into p = 1: it propagates as NaN, which the
    // runner reports as ERROR and comparisons as a difference.
    if !(estimate.is_finite() && se.is_finite() && expected.is_finite()) {
        return (f64::NAN, f64::NAN);
    }
    let allowance = rel_tolerance * expected.abs() + ROUNDING * expected.abs().max(estimate.abs());
    let d = (estimate - expected).abs();
    let excess = (d - allowance).max(0.0);
    let z = z_test(excess, se, 0.0).z;
    // p of H0: |bias| ≤ allowance, taken at the boundary bias = allowance:
    // P(|D| ≥ d) = Φ̄((d − a)/se) + Φ̄((d + a)/se); for a = 0 it is the two-sided 2Φ̄(d/se).
    let p = if se > 0.0 {
        normal_sf((d - allowance) / se) + normal_sf((d + allowance) / se)
    } else if excess > 0.0 {
        0.0
    } else {
        1.0
    };
    (z.copysign(estimate - expected), p.min(1.0))
}

/// A measurement from one region test against a closed form.
pub fn region_measurement(
    r: &RegionStats,
    expected: f64,
    rel_tolerance: f64,
    message: String,
) -> Measurement {
    let (z, p) = z_with_tolerance(r.mean, r.se, expected, rel_tolerance);
    Measurement {
        estimate: Some(r.mean),
        std_error: Some(r.se),
        expected: Some(expected),
        statistic: Some(super::outcome::Statistic::Z { z }),
        p_value: Some(p),
        deterministic_pass: None,
        unstable: (!r.stable).then(|| format!("UNSTABLE: {}", r.stability)),
        variants: 1,
        one_sided: false,
        samples: r.samples,
        message: format!(
            "{message}; Y over {} px; se = max(within-pixel {:.3e}, between-pixel batch means {:.3e}); stability: {}",
            r.pixels, r.se_within, r.se_between, r.stability
        ),
    }
}

/// Combines several region tests (one per variant) into one measurement: p is the Šidák
/// combination of the variants' p-values; the reported numbers are the worst variant's.
pub fn combine(parts: Vec<(String, Measurement)>) -> Measurement {
    let ps: Vec<f64> = parts.iter().filter_map(|(_, m)| m.p_value).collect();
    let worst = parts
        .iter()
        .enumerate()
        .min_by(|a, b| {
            a.1 .1
                .p_value
                .unwrap_or(1.0)
                .total_cmp(&b.1 .1.p_value.unwrap_or(1.0))
        })
        .map(|(i, _)| i)
        .unwrap_or(0);
    let samples = parts.iter().map(|(_, m)| m.samples).sum();
    let unstable: Vec<String> = parts
        .iter()
        .filter_map(|(n, m)| m.unstable.as_ref().map(|u| format!("{n}: {u}")))
        .collect();
    let summary: Vec<String> = parts
        .iter()
        .map(|(n, m)| {
            format!(
                "{n}: {} ± {} vs {} (p {})",
                fmt_sig(m.estimate.unwrap_or(f64::NAN)),
                fmt_sig(m.std_error.unwrap_or(f64::NAN)),
                fmt_sig(m.expected.unwrap_or(f64::NAN)),
                fmt_sig(m.p_value.unwrap_or(f64::NAN))
            )
        })
        .collect();
    let det = parts
        .iter()
        .filter_map(|(_, m)| m.deterministic_pass)
        .reduce(|a, b| a && b);
    let mut m = parts.get(worst).map(|p| p.1.clone()).unwrap_or_default();
    // A sub-test that could not be formed (NaN p) makes the whole check an ERROR.
    m.p_value = (!ps.is_empty()).then(|| {
        if ps.iter().any(|p| p.is_nan()) {
            f64::NAN
        } else {
            crate::stats::multiple::sidak_combine(&ps)
        }
    });
    m.variants = parts.iter().map(|(_, p)| p.variants.max(1)).sum();
    m.samples = samples;
    m.deterministic_pass = det;
    m.unstable = (!unstable.is_empty()).then(|| unstable.join("; "));
    m.message = format!(
        "{} variants, p Šidák-combined, worst shown; {}",
        parts.len(),
        summary.join("; ")
    );
    m
}

/// A number with 4 significant digits.
pub fn fmt_sig(x: f64) -> String {
    if x == 0.0 || !x.is_finite() {
        return format!("{x}");
    }
    let a = x.abs();
    if (1e-3..1e5).contains(&a) {
        let decimals = (3 - a.log10().floor() as i32).max(0) as usize;
        format!("{x:.decimals$}")
    } else {
        format!("{x:.3e}")
    }
}

#[cfg(test)]
mod nan_tests {
    use super::z_with_tolerance;

    #[test]
    fn non_finite_inputs_never_pass() {
        for (e, se, x) in [
            (f64::NAN, 1.0, 1.0),
            (1.0, f64::NAN, 1.0),
            (f64::INFINITY, 1.0, 1.0),
        ] {
            let (z, p) = z_with_tolerance(e, se, x, 0.0);
            assert!(z.is_nan() && p.is_nan());
        }
    }
}
