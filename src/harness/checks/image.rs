//! Image comparison against a reference render: the scene is rendered at the reference's
//! resolution and every named region × channel mean is compared with the reference's
//! (harness::compare: z test with both images' variance channels, Šidák over the region ×
//! channel tests, an optional stated model tolerance). The check's p-value is the Šidák
//! combination of the smallest region p-value: 1 − (1 − p_min)^m (Šidák 1967).

use crate::film::Film;
use crate::harness::compare::{
    compare, regions_key, regions_measurement, whole_image, Region, RegionResult, RgbImage,
    CHANNELS,
};
use crate::harness::keys::{common, Key, Keys};
use crate::harness::measurement::fmt_sig;
use crate::harness::region::settings_for;
use crate::harness::{Check, CheckError, Context, Kind, Measurement, Scope};
use crate::integrators::Strategy;
use crate::io::LocatedError;
use crate::math::rng::mix64;
use crate::render::RenderSettings;
use crate::scene::Scene;
use crate::spectrum::Observer;
use crate::stats::sequential::{self, upper_quantile, Design, LOOKS, POWER, SHAPES};
use std::path::PathBuf;
use std::sync::{Mutex, OnceLock};

/// Runs an image comparison against `reference` (tests pass a deliberately wrong one).
pub fn run_against(
    check: &Check,
    p: &Params,
    ctx: &Context,
    reference: &RgbImage,
) -> Result<Measurement, CheckError> {
    let scene = check.scene()?;
    let mut s = settings_for(
        check,
        scene,
        ctx,
        ctx.seed,
        check.render.max_depth.or(scene.render.max_depth),
        Strategy::Mis,
    );
    s.width = reference.width;
    s.height = reference.height;
    s.observer = p.observer.clone();
    // furnace's own renderer only: its films' per-pixel moments add up across looks (an
    // external renderer's images are batch means, and it may ignore crops)
    if ctx.looks && !check.fixed_spp && ctx.renderer.is_reference() {
        return in_looks(check, p, ctx, reference, scene, &s);
    }
    let film = ctx.renderer.render(scene, &s)?;
    let test = RgbImage::from_film(&film);
    // Only the per-test p-values are used (the family rate passed is irrelevant); the run's correction applies
    // to the combined p-value below.
    let c = compare(
        &test,
        reference,
        &p.regions,
        0.5,
        0.01,
        ctx.rel_tolerance(check.rel_tolerance),
    )?;
    let what = what_was_compared(&s.observer, c.reference_has_variance);
    let mut m = regions_measurement(&c.regions, (s.width * s.height) as u64 * s.spp, &what)?;
    m.rel_tolerance = Some(ctx.rel_tolerance(check.rel_tolerance));
    Ok(m)
}

/// What the line says was compared: the observer, and whether the reference carried an error
/// estimate ([`crate::harness::compare::Comparison::reference_has_variance`]).
fn what_was_compared(observer: &Observer, reference_has_variance: bool) -> String {
    format!(
        "observer {}, reference {}",
        observer.name(),
        if reference_has_variance {
            "with variance channels"
        } else {
            "without variance channels, treated as exact"
        }
    )
}

/// A region test's statistic on the normal scale: its t through its own two-sided p, with
/// the sign of its difference.
fn stage_z(r: &RegionResult) -> f64 {
    upper_quantile((r.p / 2.0).clamp(1e-300, 0.5)).copysign(r.z)
}

/// The largest budget of a comparison in looks, as a multiple of the written spp: the
/// two-sided design's inflation (1.12 at the suite's levels) with room for the reference's own
/// noise, which every look shares (docs/statistics.md, "Image comparisons in looks").
pub const LOOK_BUDGET: f64 = 1.25;

/// The two-sided design of [`LOOKS`] and [`SHAPES`] at per-test level `alpha`, computed once
/// per level and run (about 0.1 s each).
fn design_at(alpha: f64) -> Result<Design, CheckError> {
    static CACHE: OnceLock<Mutex<Vec<(u64, Design)>>> = OnceLock::new();
    let cache = CACHE.get_or_init(Default::default);
    let known = |c: &Vec<(u64, Design)>| {
        c.iter()
            .find(|(a, _)| *a == alpha.to_bits())
            .map(|(_, d)| d.clone())
    };
    if let Some(d) = known(&cache.lock().unwrap_or_else(|e| e.into_inner())) {
        return Ok(d);
    }
    let d = sequential::design(alpha, POWER, &LOOKS, true, SHAPES, true)
        .map_err(|e| CheckError::Setup(format!("sequential design at level {alpha}: {e}")))?;
    let mut c = cache.lock().unwrap_or_else(|e| e.into_inner());
    if c.len() < 64 {
        c.push((alpha.to_bits(), d.clone()));
    }
    Ok(d)
}

/// The comparison in sequential looks: each region × channel test is a group-sequential test
/// of its cumulative z (the test image's samples so far against the one reference) at the
/// Šidák share of the check's level, stopping on its own; each look renders only the regions
/// with a test still open (the whole image while its own tests are), under its own seed, and
/// adds to the pixels' earlier samples. The reference's noise is in every look's z, so the
/// looks' information fractions exceed the design's: each test's last boundary is refitted to
/// its own ([`fit`]), and the check's line gives the largest level and the smallest power at
/// the fixed test's detection limit over the tests (docs/statistics.md, "Image comparisons in
/// looks").
fn in_looks(
    check: &Check,
    p: &Params,
    ctx: &Context,
    reference: &RgbImage,
    scene: &Scene,
    s: &RenderSettings,
) -> Result<Measurement, CheckError> {
    let (w, h) = (s.width, s.height);
    let regions: Vec<Region> = std::iter::once(whole_image())
        .chain(p.regions.iter().cloned())
        .collect();
    let rects = regions
        .iter()
        .map(|r| r.pixels(w, h))
        .collect::<Result<Vec<_>, _>>()
        .map_err(CheckError::Setup)?;
    let channels = CHANNELS.len();
    let m = regions.len() * channels;
    // Šidák share of the check's level: the check rejects at ctx.alpha when one test does
    let alpha = -((-ctx.alpha).ln_1p() / m as f64).exp_m1();
    let d = design_at(alpha)?;
    let step = ctx.renderer.spp_step().max(1);
    let quarter = ((s.spp as f64 * LOOK_BUDGET / 4.0).ceil() as u64)
        .max(1)
        .div_ceil(step)
        * step;
    let look_spp = [quarter, quarter, 2 * quarter];
    let n_max: u64 = look_spp.iter().sum();
    let tolerance = ctx.rel_tolerance(check.rel_tolerance);
    // per test, once stopped: the look, its result there and its z
    let mut stopped: Vec<Option<(usize, RegionResult, f64)>> = vec![None; m];
    let mut cumulative: Option<Film> = None;
    let mut samples = 0u64;
    let mut last: Vec<RegionResult> = Vec::new();
    // the refitted designs of the tests decided at the last look, kept for their p-values
    let mut fitted: Vec<Option<ReferenceFit>> = (0..m).map(|_| None).collect();
    let mut reference_has_variance = reference.variance.is_some();
    let mut looks_done = 0;
    let mut rejected = false;
    for (k, &spp) in look_spp.iter().enumerate() {
        let open: Vec<usize> = (0..regions.len())
            .filter(|r| (0..channels).any(|c| stopped[r * channels + c].is_none()))
            .collect();
        let settings = RenderSettings {
            seed: mix64(ctx.seed ^ (k as u64 + 1)),
            spp,
            ..s.clone()
        };
        let look = render_regions(ctx, scene, &settings, &rects, &open)?;
        samples += look.rendered_pixels() as u64 * spp;
        let film = match cumulative.take() {
            None => look,
            Some(mut c) => {
                add_samples(&mut c, &look);
                c
            }
        };
        let c = compare(
            &RgbImage::from_film(&film),
            reference,
            &p.regions,
            0.5,
            0.01,
            tolerance,
        )?;
        cumulative = Some(film);
        reference_has_variance = c.reference_has_variance;
        looks_done = k + 1;
        for (j, r) in c.regions.iter().enumerate() {
            if stopped[j].is_some() {
                continue;
            }
            if !r.p.is_finite() {
                break; // reported below as regions_measurement's error
            }
            let z = stage_z(r);
            // the last look's boundary holds the level under the test's measured fractions
            let decision = if k + 1 == look_spp.len() {
                let f = fit(&d, r, n_max as f64, &look_spp, s.spp);
                let decision = f.design.decide(k, z);
                fitted[j] = Some(f);
                decision
            } else {
                d.decide(k, z)
            };
            if let Some(reject) = decision {
                stopped[j] = Some((k, r.clone(), z));
                rejected |= reject;
            }
        }
        last = c.regions;
        if rejected || stopped.iter().all(Option::is_some) || last.iter().any(|r| !r.p.is_finite())
        {
            break;
        }
    }
    // each test with its stage-wise p (the open ones at the last look, after a rejection)
    let k_last = looks_done - 1;
    let tests: Vec<(usize, RegionResult, f64)> = last
        .iter()
        .enumerate()
        .map(|(j, r)| {
            stopped[j]
                .clone()
                .unwrap_or_else(|| (k_last, r.clone(), stage_z(r)))
        })
        .collect();
    let cum_spp = |k: usize| look_spp[..=k].iter().sum::<u64>() as f64;
    let fits: Vec<ReferenceFit> = tests
        .iter()
        .zip(fitted)
        .map(|((k, r, _), f)| f.unwrap_or_else(|| fit(&d, r, cum_spp(*k), &look_spp, s.spp)))
        .collect();
    let staged: Vec<RegionResult> = tests
        .iter()
        .zip(&fits)
        .map(|((k, r, z), f)| RegionResult {
            p: if r.p.is_finite() {
                f.design.p_value(*k, *z)
            } else {
                r.p
            },
            ..r.clone()
        })
        .collect();
    let what = what_was_compared(&s.observer, reference_has_variance);
    let mut ms = regions_measurement(&staged, samples, &what)?;
    ms.rel_tolerance = Some(tolerance);
    // the worst test's level and power under its measured information fractions
    let worst = staged
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.p.total_cmp(&b.1.p))
        .map_or(0, |(j, _)| j);
    ms.power_std_error = Some(fits[worst].power_se);
    let weakest = fits.iter().map(|f| f.power).fold(1.0f64, f64::min);
    let highest = fits.iter().map(|f| f.level).fold(0.0f64, f64::max);
    let fractions = &fits[worst].design.t;
    let stops: Vec<usize> = (0..3)
        .map(|k| tests.iter().filter(|t| t.0 == k).count())
        .collect();
    let verdict = if rejected { "rejected" } else { "accepted" };
    ms.message = format!(
        "{}; sequential: {verdict} at look {looks_done} of 3 (looks of {} spp, at most {n_max} of the written {}; tests stopped per look {:?}); stage-wise p at level {} a test; the reference's noise in every look: the worst test's information fractions {}, each test's last boundary fitted to its own, level at most {}, power at the fixed test's detection limit at least {})",
        ms.message,
        look_spp.map(|x| x.to_string()).join(", "),
        s.spp,
        stops,
        fmt_sig(alpha),
        fractions.iter().map(|t| fmt_sig(*t)).collect::<Vec<_>>().join(", "),
        fmt_sig(highest),
        fmt_sig(weakest),
    );
    Ok(ms)
}

/// A test's design under its measured information fractions: with the test image's variance
/// v (per sample, times spp) and the reference's s², look k's information is 1/(v/n_k + s²),
/// and the cumulative z keeps the canonical joint law with it (Jennison & Turnbull 2000,
/// §3.1), so the fractions exceed n_k/n_max by the reference's share. The design's first
/// boundaries stand; the last efficacy boundary is solved again so that the level is the
/// design's under these fractions.
struct ReferenceFit {
    /// The design at the measured fractions, its last boundary refitted.
    design: Design,
    /// Its level (the design's, unless the earlier looks alone spend more).
    level: f64,
    /// Its power at the fixed test's detection limit.
    power: f64,
    /// The standard error of the fixed test whose detection limit the looks detect with 95 %
    /// probability (the fixed test's own when the power there is at least 95 %).
    power_se: f64,
}

/// [`ReferenceFit`] of test result `r` measured at `spp_used` cumulative spp, with looks of
/// `look_spp` and the check's written spp.
fn fit(
    d: &Design,
    r: &RegionResult,
    spp_used: f64,
    look_spp: &[u64; 3],
    written: u64,
) -> ReferenceFit {
    let v = r.test.1.powi(2) * spp_used;
    let s2 = r.reference.1.powi(2);
    let info = |n: f64| 1.0 / (v / n + s2);
    let n_max: f64 = look_spp.iter().sum::<u64>() as f64;
    let mut n = 0.0;
    let t: Vec<f64> = look_spp
        .iter()
        .map(|&k| {
            n += k as f64;
            (info(n) / info(n_max)).min(1.0)
        })
        .collect();
    let ok = v > 0.0 && t.windows(2).all(|w| w[0] < w[1]) && t[0] > 0.0;
    let mut design = d.clone();
    if ok {
        design.t = t;
        // level falls as the last boundary rises
        let last = design.reject.len() - 1;
        let level_at = |c: f64| {
            let mut x = design.clone();
            x.reject[last] = c;
            x.accept[last] = c;
            x.crossing(0.0).rejection()
        };
        // the refitted boundary lies near the design's (a bracket 0.8-1.6 times it, halved
        // 24 times: to about 1e-7 of it)
        let (mut lo, mut hi) = (0.8 * d.reject[last], 1.6 * d.reject[last]);
        if level_at(hi) <= d.alpha {
            for _ in 0..24 {
                let mid = 0.5 * (lo + hi);
                if level_at(mid) > d.alpha {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
        }
        design.reject[last] = hi;
        design.accept[last] = hi;
    }
    let level = design.crossing(0.0).rejection();
    let z_sum = upper_quantile(d.alpha / 2.0) + upper_quantile(1.0 - POWER);
    let fixed_se = (v / written as f64 + s2).sqrt();
    // the fixed test's detection limit as the design's full-information drift
    let scale = info(n_max).sqrt();
    let drift = z_sum * fixed_se * scale;
    let power = design.crossing(drift).rejection();
    let power_se = if power >= POWER || fixed_se.is_nan() || fixed_se <= 0.0 {
        fixed_se
    } else {
        // the drift at which the looks reach 95 %, by bisection, as a fixed test's se
        let (mut lo, mut hi) = (drift, 4.0 * drift);
        for _ in 0..40 {
            let mid = 0.5 * (lo + hi);
            if design.crossing(mid).rejection() < POWER {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        hi / scale / z_sum
    };
    ReferenceFit {
        design,
        level,
        power,
        power_se,
    }
}

/// Renders the regions `open` (indices into `rects`; 0 is the whole image) with `s`: the whole
/// image when it is open, else each region cropped (a renderer that ignores crops renders the
/// whole image, which is then used for all).
fn render_regions(
    ctx: &Context,
    scene: &Scene,
    s: &RenderSettings,
    rects: &[[usize; 4]],
    open: &[usize],
) -> Result<Film, CheckError> {
    if open.contains(&0) {
        return Ok(ctx.renderer.render(scene, s)?);
    }
    let w = s.width;
    let mut film = Film::new(s.width, s.height);
    for &r in open {
        let rect = rects[r];
        let part = ctx.renderer.render(
            scene,
            &RenderSettings {
                crop: Some(rect),
                ..s.clone()
            },
        )?;
        if part.rendered_pixels() == s.width * s.height {
            return Ok(part);
        }
        film.truncated_paths += part.truncated_paths;
        for y in rect[1]..rect[3] {
            for x in rect[0]..rect[2] {
                film.pixels[y * w + x] = part.pixels[y * w + x];
            }
        }
    }
    Ok(film)
}

/// Adds `look`'s samples to `film`'s, pixel by pixel where `look` rendered.
fn add_samples(film: &mut Film, look: &Film) {
    for (a, b) in film.pixels.iter_mut().zip(&look.pixels) {
        if b.channels[1].count() > 0 {
            a.merge(b);
        }
    }
    film.truncated_paths += look.truncated_paths;
}

/// Parameters of an image comparison.
#[derive(Debug, Clone, PartialEq)]
pub struct Params {
    /// Reference image (EXR).
    pub reference: PathBuf,
    /// Named regions compared (empty: the whole image).
    pub regions: Vec<Region>,
    /// Colour pipeline the image is rendered with.
    pub observer: Observer,
}

/// The `image_compare` kind.
pub struct ImageCompare;

impl Kind for ImageCompare {
    type Params = Params;
    const NAME: &'static str = "image_compare";
    const KEYS: &'static [Key] = &[
        common::SCENE,
        Key {
            name: "reference",
            ty: "path",
            default: "required",
            doc:
                "reference EXR (linear R, G, B, optional variance.R/G/B), relative to the manifest",
        },
        common::REGIONS,
        common::OBSERVER,
        common::SPP,
        common::MAX_DEPTH,
        common::SEED,
        common::REL_TOLERANCE,
    ];
    const SCOPE: Scope = Scope::Image;
    const OWN_LOOKS: bool = true;

    fn parse(k: &mut Keys) -> Result<Params, LocatedError> {
        Ok(Params {
            reference: k
                .existing_file(
                    "reference",
                    Some("missing; an image comparison needs a reference EXR (path relative to the manifest)"),
                )?
                .unwrap_or_default(),
            regions: regions_key(k, "regions")?,
            observer: k.observer()?,
        })
    }

    /// Runs an image comparison with the reference read from the manifest's path.
    fn run(check: &Check, p: &Params, ctx: &Context) -> Result<Measurement, CheckError> {
        let reference = RgbImage::load(&p.reference).map_err(CheckError::Setup)?;
        run_against(check, p, ctx, &reference)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::rng::SampleStream;

    /// One region test in looks on synthetic normal data: the reference's error `r` (drawn
    /// once), look increments of variance v/n, the design at level `alpha`; true when rejected.
    fn one_test(
        d: &Design,
        gauss: &mut impl FnMut() -> f64,
        v: f64,
        s_ref: f64,
        bias: f64,
        written: u64,
    ) -> bool {
        let quarter = (written as f64 * LOOK_BUDGET / 4.0).ceil() as u64;
        let look_spp = [quarter, quarter, 2 * quarter];
        let r = s_ref * gauss();
        let (mut sum, mut n) = (0.0, 0.0);
        for (k, &spp) in look_spp.iter().enumerate() {
            // the look's mean of spp samples, added to the running sum
            sum += spp as f64 * (bias + (v / spp as f64).sqrt() * gauss());
            n += spp as f64;
            let (t, se_t) = (sum / n, (v / n).sqrt());
            let z = (t - r) / (se_t * se_t + s_ref * s_ref).sqrt();
            let p = 2.0 * crate::stats::normal_sf(z.abs());
            let result = RegionResult {
                region: "r".into(),
                channel: "R",
                test: (t, se_t),
                reference: (r, s_ref),
                z,
                dof: f64::INFINITY,
                p,
            };
            let decision = if k + 1 == look_spp.len() {
                fit(d, &result, n, &look_spp, written).design.decide(k, z)
            } else {
                d.decide(k, z)
            };
            if let Some(reject) = decision {
                return reject;
            }
        }
        unreachable!("the last look decides")
    }

    fn gaussians(seed: u64) -> impl FnMut() -> f64 {
        let mut rng = SampleStream::new(seed, 0, 0);
        move || {
            let (u1, u2) = (rng.next_f64().max(1e-300), rng.next_f64());
            // Box & Muller 1958
            (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
        }
    }

    #[test]
    fn looks_hold_level_and_power_with_a_noisy_reference() {
        // At α = 0.05 a test, the reference's variance an eighth and twice the fixed test's
        // image variance (v/N): the false-alarm rate within 4.5 standard errors of 5 %, and at
        // the fixed test's detection limit a power of at least 95 % less 4.5 standard errors.
        let alpha = 0.05;
        let d = design_at(alpha).unwrap();
        let (v, written) = (1.0, 256u64);
        let z_sum = upper_quantile(alpha / 2.0) + upper_quantile(1.0 - POWER);
        for (seed, rho) in [(1u64, 0.125), (2, 2.0)] {
            let s_ref = (rho * v / written as f64).sqrt();
            let limit = z_sum * (v / written as f64 + s_ref * s_ref).sqrt();
            let mut gauss = gaussians(seed);
            let n = 4000;
            let alarms = (0..n)
                .filter(|_| one_test(&d, &mut gauss, v, s_ref, 0.0, written))
                .count() as f64;
            let detected = (0..n)
                .filter(|_| one_test(&d, &mut gauss, v, s_ref, limit, written))
                .count() as f64;
            let rate = alarms / n as f64;
            let se = (alpha * (1.0 - alpha) / n as f64).sqrt();
            assert!((rate - alpha).abs() < 4.5 * se, "ρ {rho}: {rate}");
            let power = detected / n as f64;
            eprintln!("ρ {rho}: {alarms} false alarms and {detected} detections in {n} runs each");
            let se_p = (POWER * (1.0 - POWER) / n as f64).sqrt();
            assert!(power > POWER - 4.5 * se_p, "ρ {rho}: power {power}");
        }
    }
}
