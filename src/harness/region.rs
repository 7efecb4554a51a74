//! The skeleton every scene-level check shares: render settings from the check and the scene,
//! the measured pixel region, and the region's mean with a standard error that survives image
//! structure and a variance diagnosis (stable, or UNSTABLE with the numbers).

use super::context::Context;
use super::error::CheckError;
use super::kind::Check;
use super::measurement::Measurement;
use crate::film::Film;
use crate::integrators::{PathTracer, Strategy};
use crate::render::RenderSettings;
use crate::scene::Scene;
use crate::stats::chi2::chi2_sf;
use crate::stats::multiple::sidak_combine;
use crate::stats::{normal_sf, stability, t_with_tolerance, z_with_tolerance};

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
    /// Pixels whose variance holds Monte Carlo noise beyond rounding ([`has_noise`]).
    pub noisy_pixels: usize,
    /// Camera paths traced: spp times the pixels rendered (those outside a crop may be left
    /// empty).
    pub samples: u64,
    /// Whether the variance settled (stats::stability on the pixel residuals).
    pub stable: bool,
    /// The diagnosis with its numbers.
    pub stability: String,
    /// When the diagnosis failed on batch means only (structure across pixels, not an
    /// infinite-variance tail): the re-test that decides between FAIL and UNSTABLE.
    pub retest: Option<Retest>,
    /// Hill's tail index of the noisy pixels' standard deviations, bounded at confidence
    /// 1 − [`HEAVY_TAIL_P`] ([`stability::sd_tail`]); None below 40 noisy pixels.
    pub sd_tail: Option<stability::SdTail>,
    /// Sign of the third central moment of the noisy pixels' means (+1: a right tail, the
    /// side of a radiance estimator's rare large samples; 0 when not evaluated).
    pub tail_side: f64,
}

/// One minus the confidence of the per-pixel sd tail bound that turns a rejected mean test
/// into UNSTABLE ([`heavy_tail`]). It only relabels a rejection, so it cannot add a
/// non-PASS verdict and needs no share of the family-wise rate; 5 % is the rate at which a
/// finite-variance tail of index 2 would be relabelled (docs/statistics.md, "Infinite
/// variance").
pub const HEAVY_TAIL_P: f64 = 0.05;

/// Evidence that a region's variance is infinite, stated for a mean test that rejects: the
/// per-pixel sds' tail index is below 2 at confidence 1 − [`HEAVY_TAIL_P`], and the estimate
/// errs to the side opposite its tail, as an unbiased mean with a heavy tail usually does
/// (it misses the rare large samples). A z or t test assumes a finite variance, so such a
/// rejection is no evidence of a bias: the verdict is UNSTABLE.
pub fn heavy_tail(r: &RegionStats, expected: f64) -> Option<String> {
    let t = r.sd_tail.filter(|t| t.infinite())?;
    ((r.mean - expected) * r.tail_side < 0.0).then(|| {
        format!(
            "UNSTABLE: variance likely infinite, so the mean test's rejection is no evidence of a bias: \
             the per-pixel standard deviations have Hill {} < 2 at {:.0} % confidence, and the \
             estimate reads {} its expected value, as an unbiased mean with a {} tail usually does",
            tail_numbers(&t),
            100.0 * (1.0 - t.p),
            if r.mean < expected { "below" } else { "above" },
            if r.tail_side > 0.0 { "right" } else { "left" },
        )
    })
}

/// The re-test of a region whose residuals have structure. Pixels are independent estimates
/// (furnace seeds every pixel apart; a black-box renderer with an independent sampler does
/// too), so under the null hypothesis (every pixel unbiased) residuals have none: structure is
/// a bias that varies across the region, and two tests ask whether it is real.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Retest {
    /// The mean's standard error inflated to the batch-means estimate at the batch size that
    /// gives the largest one (Schmeiser 1982, Operations Research 30(3), "Batch size effects
    /// in the analysis of simulation output"), and its degrees of freedom, batches − 1.
    pub se: f64,
    /// Degrees of freedom of `se`.
    pub dof: f64,
    /// X = Σ rᵢ²/vᵢ over the pixels with Monte Carlo noise ([`residual_chi2`]).
    pub chi2: f64,
    /// Pixels in `chi2`, less one when the residuals are taken about their own mean.
    pub pixels: usize,
    /// Degrees of freedom of each pixel's variance estimate (spp − 1; ∞: known variances).
    pub pixel_dof: f64,
}

impl Retest {
    /// Šidák combination of the inflated mean test and, where it is calibrated, the structure
    /// test ([`structure_p`]): (mean test's t, p, sub-tests combined). NaN when either p is.
    pub fn p(&self, mean: f64, expected: f64, rel_tolerance: f64) -> (f64, f64, usize) {
        let (t, p_mean) = t_with_tolerance(mean, self.se, expected, rel_tolerance, self.dof);
        match structure_p(self.chi2, self.pixels, self.pixel_dof) {
            None => (t, p_mean, 1),
            Some(p_x) if p_x.is_nan() || p_mean.is_nan() => (t, f64::NAN, 2),
            Some(p_x) => (t, sidak_combine(&[p_mean, p_x]), 2),
        }
    }
}

/// Whether a pixel's variance of the mean `var` holds Monte Carlo noise beyond the absolute
/// rounding `allowance` of its image (the renderer's relative rounding,
/// [`super::Renderer::image_rounding`], times the image's largest |value|): a standard error
/// at or below it is rounding, and a residual divided by it says nothing (an absorber's
/// e^(−330) transmittance read as 0 beside a 1e-317 variance gave z ≈ 7e14).
pub fn has_noise(var: f64, allowance: f64) -> bool {
    var > allowance * allowance
}

/// X = Σ rᵢ²/vᵢ of residuals against their estimated variances, over the pixels with Monte
/// Carlo noise beyond the absolute rounding `allowance` ([`has_noise`]): (X, pixels).
pub fn residual_chi2(resid: &[f64], vars: &[f64], allowance: f64) -> (f64, usize) {
    resid
        .iter()
        .zip(vars)
        .filter(|(_, v)| has_noise(**v, allowance))
        .fold((0.0, 0), |(x, n), (r, v)| (x + r * r / v, n + 1))
}

/// Upper-tail p of X = Σ rᵢ²/v̂ᵢ over `n` independent unbiased near-normal pixels whose
/// variance estimates have `dof` degrees of freedom each: χ²(n) for known variances; else each
/// term is F(1, ν), mean ν/(ν − 2) and variance 2ν²(ν − 1)/((ν − 2)²(ν − 4)) (Johnson, Kotz &
/// Balakrishnan 1995, Continuous Univariate Distributions 2, ch. 27), and X is taken as normal
/// with n times those moments (central limit over pixels). None where that is not calibrated:
/// ν ≤ 30 (a heavy-tailed F) or n < 30.
pub fn structure_p(x: f64, n: usize, dof: f64) -> Option<f64> {
    if n < 30 || dof <= 30.0 || dof.is_nan() {
        return None;
    }
    if dof.is_infinite() {
        return Some(chi2_sf(x, n as f64));
    }
    let nf = n as f64;
    let mean = dof / (dof - 2.0);
    let var = 2.0 * dof * dof * (dof - 1.0) / ((dof - 2.0).powi(2) * (dof - 4.0));
    Some(normal_sf((x - nf * mean) / (nf * var).sqrt()))
}

/// Image size, spp and region of a scene-level check (independent sampling).
pub fn settings_for(
    check: &Check,
    scene: &Scene,
    ctx: &Context,
    seed: u64,
    max_depth: Option<u32>,
    strategy: Strategy,
) -> RenderSettings {
    let ov = &check.render;
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
        sampler: Default::default(),
        spectral: Default::default(),
        deadline: ctx.deadline,
        crop: None,
    }
}

/// The region [x0, y0, x1, y1) of a check, checked against the image size.
pub fn region_of(check: &Check, s: &RenderSettings) -> Result<[usize; 4], CheckError> {
    let r = check.render.region.unwrap_or([0, 0, s.width, s.height]);
    if r[2] > s.width || r[3] > s.height {
        return Err(CheckError::Setup(format!(
            "region {r:?} does not fit the {}x{} image",
            s.width, s.height
        )));
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
) -> Result<RegionStats, CheckError> {
    // only the region is read: the renderer may leave the other pixels empty
    let cropped = RenderSettings {
        crop: Some(region),
        ..settings.clone()
    };
    let film = ctx.renderer.render(scene, &cropped)?;
    Ok(region_stats(
        &film,
        region,
        settings.spp,
        diag_alpha,
        expected_px,
        ctx.renderer.image_rounding(),
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
    rounding: f64,
) -> RegionStats {
    region_stats_of(film, region, spp, alpha, expected_px, 1, rounding)
}

/// [`region_stats`] of XYZ `channel` (0 = X, 1 = Y, 2 = Z); `rounding` is the renderer's
/// relative rounding allowance ([`super::Renderer::image_rounding`]).
pub fn region_stats_of(
    film: &Film,
    region: [usize; 4],
    spp: u64,
    alpha: f64,
    expected_px: Option<&[f64]>,
    channel: usize,
    rounding: f64,
) -> RegionStats {
    let (px, vars) = region_pixels_of(film, region, channel);
    let n = px.len() as f64;
    let mean = px.iter().sum::<f64>() / n;
    let se_within = vars.iter().sum::<f64>().sqrt() / n;
    // the pixels rendered (a renderer may leave those outside a crop empty) times spp
    let samples = film.rendered_pixels() as u64 * spp;
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
            noisy_pixels: px.len(),
            samples,
            stable: false,
            stability: why,
            retest: None,
            sd_tail: None,
            tail_side: 0.0,
        };
    }
    let allowance = rounding * scale;
    let (stable, stability, se_between, infinite) =
        residual_stability(&resid, &vars, allowance, rounding * mean.abs(), alpha);
    let se = se_within.max(se_between);
    // each pixel's variance rests on (its sample count − 1) degrees of freedom
    let pixel_dof = film
        .pixels
        .get(region[1] * film.width + region[0])
        .map_or(f64::NAN, |p| p.count() as f64 - 1.0);
    let retest = (!stable && !infinite)
        .then(|| {
            let raw = stability::diagnose(&resid, alpha);
            let (chi2, pixels) = residual_chi2(&resid, &vars, allowance);
            // residuals about their own mean (no per-pixel closed form) lose one dof
            let pixels = pixels.saturating_sub(usize::from(expected_px.is_none()));
            raw.se_by_batch_size
                .iter()
                .max_by(|a, b| a.1.total_cmp(&b.1))
                .map(|&(b, se_b)| Retest {
                    se: se.max(se_b),
                    dof: (resid.len() / b) as f64 - 1.0,
                    chi2,
                    pixels,
                    pixel_dof,
                })
        })
        .flatten();
    let (sd_tail, tail_side) = tail_of(&px, &vars, allowance);
    RegionStats {
        mean,
        se,
        se_within,
        se_between,
        pixels: px.len(),
        noisy_pixels: vars.iter().filter(|v| has_noise(**v, allowance)).count(),
        samples,
        stable,
        stability,
        retest,
        sd_tail,
        tail_side,
    }
}

/// "tail index … (k = … of … px), upper bound …", the numbers both messages give.
fn tail_numbers(t: &stability::SdTail) -> String {
    format!(
        "tail index {:.3} (k = {} of {} px), upper bound {:.3}",
        t.alpha, t.k, t.n, t.upper
    )
}

/// "; per-pixel sd …" for a message, or nothing where it was not evaluated.
fn sd_tail_text(r: &RegionStats) -> String {
    r.sd_tail.map_or(String::new(), |t| {
        let side = match r.tail_side {
            s if s > 0.0 => "right",
            s if s < 0.0 => "left",
            _ => "none",
        };
        format!(
            "; per-pixel sd {} at {:.0} %, pixel means' tail {side}",
            tail_numbers(&t),
            100.0 * (1.0 - t.p)
        )
    })
}

/// The per-pixel sd tail ([`stability::sd_tail`]) and the side of the pixel means' tail
/// (sign of their third central moment), over the pixels with Monte Carlo noise.
fn tail_of(px: &[f64], vars: &[f64], allowance: f64) -> (Option<stability::SdTail>, f64) {
    let noisy: Vec<(f64, f64)> = px
        .iter()
        .zip(vars)
        .filter(|(_, v)| has_noise(**v, allowance))
        .map(|(m, v)| (*m, *v))
        .collect();
    let sds: Vec<f64> = noisy.iter().map(|(_, v)| v.sqrt()).collect();
    let tail = stability::sd_tail(&sds, HEAVY_TAIL_P);
    if tail.is_none() {
        return (None, 0.0);
    }
    let n = noisy.len() as f64;
    let m = noisy.iter().map(|(x, _)| x).sum::<f64>() / n;
    let m3: f64 = noisy.iter().map(|(x, _)| (x - m).powi(3)).sum();
    // the sign of m3, 0 for none (f64::signum gives ±1 for ±0)
    (tail, if m3 == 0.0 { 0.0 } else { m3.signum() })
}

/// Variance diagnosis of per-pixel residuals rᵢ (zero mean under the null hypothesis) whose
/// variances are `vars`: returns (stable, the diagnosis, batch-means standard error of their
/// mean, whether the failure rests on an infinite-variance tail or on no test at all).
/// Residuals are standardised by their own standard errors first when the variances differ
/// by more than 100× (emitters in view), so that bright pixels do not pass for a heavy tail;
/// the batch-means standard error is then not used (0), and pixels without Monte Carlo noise
/// beyond the absolute rounding `allowance` ([`has_noise`]) are left out. Residuals without
/// any, or whose mean has a standard error within `mean_allowance` (the region test's own
/// rounding allowance: the renderer's relative rounding times the mean), are reported as
/// deterministic.
pub fn residual_stability(
    resid: &[f64],
    vars: &[f64],
    allowance: f64,
    mean_allowance: f64,
    alpha: f64,
) -> (bool, String, f64, bool) {
    if !vars.iter().any(|v| has_noise(*v, allowance)) {
        return (
            true,
            "no Monte Carlo noise: every pixel is exact up to rounding".into(),
            0.0,
            false,
        );
    }
    let n = resid.len() as f64;
    // A mean whose standard error is within the rounding allowance cannot be moved by its
    // noise beyond what the test already allows for rounding, whatever that noise's tail:
    // e.g. the exact next-event estimator inside a sphere, whose few pixels with rounding
    // errors of 1e-11 hold all the variance (a Hill index of 0.6 on pure rounding).
    let se_mean = vars.iter().sum::<f64>().sqrt() / n;
    if se_mean <= mean_allowance {
        return (
            true,
            format!(
                "no Monte Carlo noise above rounding: the mean's standard error {se_mean:.2e} is within the rounding allowance {mean_allowance:.2e}"
            ),
            0.0,
            false,
        );
    }
    let mut sorted: Vec<f64> = vars
        .iter()
        .copied()
        .filter(|v| has_noise(*v, allowance))
        .collect();
    sorted.sort_by(f64::total_cmp);
    let median = sorted.get(sorted.len() / 2).copied().unwrap_or(0.0);
    let hetero = median > 0.0 && sorted.last().copied().unwrap_or(0.0) > 100.0 * median;
    // Only pixels with Monte Carlo noise enter the diagnosis: the residuals of exact pixels
    // differ by rounding alone, and a tail estimated from rounding is no evidence (an exact
    // estimator with one rare event in one pixel read a Hill index of 0.56 from the other
    // pixels' rounding: furnace/white-glass-and-mirror[ior=1.0001], sweep seeds 1052, 1070).
    let values: Vec<f64> = resid
        .iter()
        .zip(vars)
        .filter(|(_, v)| has_noise(**v, allowance))
        .map(|(r, v)| if hetero { r / v.sqrt() } else { *r })
        .collect();
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
    let infinite = diag
        .hill_upper
        .is_some_and(|u| u < stability::INFINITE_VARIANCE_INDEX);
    (
        diag.stable,
        reason,
        se_between,
        infinite || diag.se_by_batch_size.len() < 2,
    )
}

/// Whether a region's variance rests on few pixels: some pixels read their value exactly and
/// fewer than 160 (the smallest sample the tail diagnosis judges) hold Monte Carlo noise.
fn few_noisy(r: &RegionStats) -> bool {
    (2..r
        .pixels
        .min(stability::MIN_HILL_K * stability::HILL_MAX_FRACTION))
        .contains(&r.noisy_pixels)
}

/// A measurement from one region test against a closed form.
pub fn region_measurement(
    r: &RegionStats,
    expected: f64,
    rel_tolerance: f64,
    message: String,
) -> Measurement {
    let unstable = (!r.stable).then(|| format!("UNSTABLE: {}", r.stability));
    let (se, statistic, p, retest_text, tests) = match (r.stable, r.retest) {
        (false, Some(rt)) => {
            let (t, p, tests) = rt.p(r.mean, expected, rel_tolerance);
            let s = super::outcome::Statistic::T { t, dof: rt.dof };
            let structure = if tests == 2 {
                format!(
                    " and Σr²/v {:.4} over {} px (v on {} dof each)",
                    rt.chi2, rt.pixels, rt.pixel_dof
                )
            } else {
                format!(
                    " (Σr²/v not calibrated at {} px, {} dof per pixel)",
                    rt.pixels, rt.pixel_dof
                )
            };
            let text = format!(
                "; re-tested (pixels are independent, so structure is a bias): mean with the batch-means se {:.3e} ({} dof){structure}, combined p {}: a rejection is a FAIL",
                rt.se,
                rt.dof,
                super::measurement::fmt_sig(p)
            );
            (rt.se, s, p, text, tests)
        }
        _ if few_noisy(r) => {
            // The variance rests on the few pixels with noise (the others read their value
            // exactly): Student's t on their count less one, as a sample variance of m values
            // (a furnace of glass and mirror, where a pixel's samples are 0, 1 or η² and 31 of
            // 192 pixels hold any noise, read z = -3.99 at seed 1237: t on 30 dof, p 4.0e-4)
            let dof = (r.noisy_pixels - 1) as f64;
            let (t, p) = t_with_tolerance(r.mean, r.se, expected, rel_tolerance, dof);
            let text = format!(
                "; t on {dof} dof: the variance rests on the {} of {} pixels with Monte Carlo noise",
                r.noisy_pixels, r.pixels
            );
            (r.se, super::outcome::Statistic::T { t, dof }, p, text, 1)
        }
        _ => {
            let (z, p) = z_with_tolerance(r.mean, r.se, expected, rel_tolerance);
            (
                r.se,
                super::outcome::Statistic::Z { z },
                p,
                String::new(),
                1,
            )
        }
    };
    Measurement {
        power_std_error: None,
        power_scale: None,
        power_chi_square: None,
        estimate: Some(r.mean),
        std_error: Some(se),
        expected: Some(expected),
        statistic: Some(statistic),
        p_value: Some(p),
        deterministic_pass: None,
        retested: unstable.is_some() && r.retest.is_some(),
        heavy_tail: unstable.is_none().then(|| heavy_tail(r, expected)).flatten(),
        unstable,
        variants: tests,
        one_sided: false,
        regression: false,
        rel_tolerance: Some(rel_tolerance),
        samples: r.samples,
        message: format!(
            "{message}; Y over {} px; se = max(within-pixel {:.3e}, between-pixel batch means {:.3e}); stability: {}{}{retest_text}",
            r.pixels,
            r.se_within,
            r.se_between,
            r.stability,
            sd_tail_text(r)
        ),
    }
}

/// What one XYZ channel of a region must read: the region mean and, where the image is not
/// uniform, the closed form of every pixel (row-major within the region).
pub struct ChannelExpectation<'a> {
    /// Expected region mean.
    pub mean: f64,
    /// Expected pixel values, or None for a uniform region.
    pub pixels: Option<&'a [f64]>,
}

/// Tests X, Y and Z of one film over `region`, each against its expectation, and combines the
/// three (Šidák; the worst channel's numbers shown); the film's camera paths count once.
pub fn xyz_measurement(
    ctx: &Context,
    film: &Film,
    settings: &RenderSettings,
    region: [usize; 4],
    expected: [ChannelExpectation<'_>; 3],
    rel_tolerance: f64,
    what: &str,
) -> Measurement {
    let parts = expected
        .iter()
        .zip(["X", "Y", "Z"])
        .enumerate()
        .map(|(c, (e, name))| {
            let r = region_stats_of(
                film,
                region,
                settings.spp,
                diagnosis_alpha(ctx, 3),
                e.pixels,
                c,
                ctx.renderer.image_rounding(),
            );
            let message = format!("{what}; channel {name}");
            (
                name.to_string(),
                region_measurement(&r, e.mean, rel_tolerance, message),
            )
        })
        .collect();
    let mut m = super::measurement::combine(parts);
    m.samples = (settings.width * settings.height) as u64 * settings.spp;
    m
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::rng::SampleStream;

    /// Residuals shaped like `media/transmittance[sigma=10000]`: background pixels with
    /// spectral noise (variance 1e-4), a few silhouette pixels 1000× noisier, and an opaque
    /// disk that reads 0 for an expected e^(−330) with a variance at the bottom of f64.
    fn absorber_like(seed: u64, rounding_pixels: &[(f64, f64)]) -> (Vec<f64>, Vec<f64>) {
        let mut s = SampleStream::new(seed, 0, 0);
        let mut normal = || {
            // Box & Muller 1958, Ann. Math. Stat. 29: sqrt(−2 ln u1)·cos(2π u2).
            let (u1, u2) = (1.0 - s.next_f64(), s.next_f64());
            (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
        };
        let mut resid = Vec::new();
        let mut vars = Vec::new();
        for i in 0..256 {
            let v: f64 = if i % 40 == 0 { 1e-1 } else { 1e-4 };
            resid.push(v.sqrt() * normal());
            vars.push(v);
        }
        for &(r, v) in rounding_pixels {
            resid.push(r);
            vars.push(v);
        }
        (resid, vars)
    }

    #[test]
    fn pixels_whose_error_is_rounding_do_not_enter_the_diagnosis() {
        let rounding = [(-6.18e-144, 7.9e-317), (-6.18e-144, 0.0), (1e-20, 1e-60)];
        let (resid, vars) = absorber_like(1018, &rounding);
        let (stable, why, _, _) = residual_stability(&resid, &vars, 2e-12, 2e-12, 1e-4);
        assert!(stable, "{why}");
        let (x, n) = residual_chi2(&resid, &vars, 2e-12);
        assert_eq!(n, 256);
        assert!(x < 400.0, "Σr²/v {x} over {n} px");
        // Negative control: the same residuals with the old rule (any variance above 0 is
        // noise) hold a standardised residual of 7e14 and read as an infinite-variance tail.
        let (_, _, _, infinite) = residual_stability(&resid, &vars, 0.0, 0.0, 1e-4);
        assert!(infinite);
    }

    #[test]
    fn rounding_noise_in_a_few_pixels_is_not_a_heavy_tail() {
        // sphere-depth1 at seed 1023: an exact estimator (1.5 everywhere) whose variance sits
        // in a few pixels with rounding errors near 1e-12 of the value
        let mut vars = vec![1e-32f64; 256];
        vars[17] = 2.7e-24;
        vars[200] = 1e-27;
        let resid: Vec<f64> = vars.iter().map(|v| 0.7 * v.sqrt()).collect();
        let (stable, why, _, infinite) = residual_stability(&resid, &vars, 1.5e-12, 1.5e-12, 1e-4);
        assert!(stable && !infinite, "{why}");
        assert!(why.contains("above rounding"), "{why}");
        // Negative control: the same pattern 1000 times larger in standard error is above the
        // allowance, so the diagnosis runs on it.
        let big: Vec<f64> = vars.iter().map(|v| v * 1e6).collect();
        let resid: Vec<f64> = big.iter().map(|v| 0.7 * v.sqrt()).collect();
        let (_, why, _, _) = residual_stability(&resid, &big, 1.5e-12, 1.5e-12, 1e-4);
        assert!(!why.contains("above rounding"), "{why}");
    }

    #[test]
    fn a_pixel_with_real_noise_still_counts() {
        // a pixel far off its expected value with a variance well above rounding is kept
        let (resid, vars) = absorber_like(7, &[(0.5, 1e-8)]);
        let (x, n) = residual_chi2(&resid, &vars, 2e-12);
        assert_eq!(n, 257);
        assert!(x > 1e7, "{x}");
    }

    #[test]
    fn one_rare_event_among_exact_pixels_is_not_a_heavy_tail() {
        // white-glass-and-mirror at ior 1.0001, sweep seed 1052: 191 pixels read 1 up to
        // rounding, one pixel holds a rare event 1.9e-7 off; the mean's standard error (1e-9)
        // is above the rounding allowance, so the region is diagnosed
        let mut resid: Vec<f64> = (0..192)
            .map(|i| ((i * 7919) % 13) as f64 * 1.1e-16 - 6.6e-16)
            .collect();
        let mut vars = vec![1e-33f64; 192];
        resid[40] = 1.9e-7;
        vars[40] = 3.6e-14;
        let (stable, why, _, _) = residual_stability(&resid, &vars, 1e-12, 1e-12, 1e-4);
        assert!(stable, "{why}");
        // Negative control: the same residuals diagnosed with the exact pixels' rounding in
        // them (the rule before) read an infinite-variance tail.
        let old = stability::diagnose(&resid, 1e-4);
        assert!(!old.stable, "{}", old.reason);
        // and real noise in every pixel with one outlier is still diagnosed
        let noisy: Vec<f64> = (0..192)
            .map(|i| ((i * 7919) % 101) as f64 * 1e-3 - 0.05)
            .collect();
        let (_, why, _, _) = residual_stability(&noisy, &vec![1e-6; 192], 1e-12, 1e-12, 1e-4);
        assert!(!why.contains("too few"), "{why}");
    }

    /// The heavy-tail relabelling needs both an sd tail below 2 and an estimate on the side
    /// opposite the tail.
    #[test]
    fn heavy_tail_needs_the_tail_and_its_side() {
        let tail = |upper: f64| stability::SdTail {
            alpha: upper / 1.2,
            upper,
            k: 64,
            n: 256,
            p: HEAVY_TAIL_P,
        };
        let r = |mean: f64, upper: f64, side: f64| RegionStats {
            mean,
            se: 1.9,
            se_within: 1.9,
            se_between: 0.0,
            pixels: 256,
            noisy_pixels: 256,
            samples: 262_144,
            stable: true,
            stability: "stable".into(),
            retest: None,
            sd_tail: Some(tail(upper)),
            tail_side: side,
        };
        let text = heavy_tail(&r(85.9, 1.6, 1.0), 100.0).unwrap();
        assert!(
            text.contains("upper bound 1.600 < 2") && text.contains("below"),
            "{text}"
        );
        // reads high with a right tail: a rare large sample cannot explain that
        assert!(heavy_tail(&r(114.0, 1.6, 1.0), 100.0).is_none());
        // a tail that may be finite, or no tail evaluated
        assert!(heavy_tail(&r(85.9, 2.05, 1.0), 100.0).is_none());
        assert!(heavy_tail(
            &RegionStats {
                sd_tail: None,
                ..r(85.9, 1.6, 1.0)
            },
            100.0
        )
        .is_none());
        // a left tail with the estimate high is the mirror case
        assert!(heavy_tail(&r(114.0, 1.6, -1.0), 100.0).is_some());
    }

    /// A region whose variance rests on few pixels (the others exact) is judged with
    /// Student's t on their count less one; a region where every pixel is noisy keeps z.
    #[test]
    fn a_variance_on_few_noisy_pixels_is_judged_with_t() {
        let stats = |noisy_pixels| RegionStats {
            mean: 0.99976,
            se: 6.0e-5,
            se_within: 5.4e-5,
            se_between: 6.0e-5,
            pixels: 192,
            noisy_pixels,
            samples: 524_288,
            stable: true,
            stability: "stable".into(),
            retest: None,
            sd_tail: None,
            tail_side: 0.0,
        };
        let few = region_measurement(&stats(31), 1.0, 0.0, String::new());
        assert!(
            matches!(few.statistic, Some(super::super::outcome::Statistic::T { dof, .. }) if dof == 30.0),
            "{:?}",
            few.statistic
        );
        let p = few.p_value.unwrap();
        assert!((3e-4..5e-4).contains(&p), "{p}");
        assert!(few.message.contains("31 of 192 pixels"), "{}", few.message);
        let all = region_measurement(&stats(192), 1.0, 0.0, String::new());
        assert!(matches!(
            all.statistic,
            Some(super::super::outcome::Statistic::Z { .. })
        ));
        assert!(all.p_value.unwrap() < 1e-4);
    }
}
