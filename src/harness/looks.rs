//! Region comparisons in sequential looks: each region × channel test of a comparison is a
//! group-sequential test of its cumulative statistic against one fixed expected value (a
//! stored or once-rendered reference, or a closed form), stopping on its own at the Šidák
//! share of the check's level. Used by `image_compare`; the method is in docs/statistics.md,
//! "Image comparisons in looks".

use crate::harness::compare::{regions_measurement, RegionResult};
use crate::harness::measurement::fmt_sig;
use crate::harness::{CheckError, Measurement};
use crate::stats::sequential::{self, upper_quantile, Design, LOOKS, POWER, SHAPES};
use std::sync::{Mutex, OnceLock};

/// The three looks' sample counts: a quarter, a quarter and a half of `budget` times
/// `written` (the budget is the design's inflation, [`Design::inflation`]: 1.11 at the suite's
/// levels), each a multiple of `step`. The reference's noise needs no more: under the refitted
/// last boundary ([`fit`]) the power at the fixed test's detection limit stays at least the
/// design's for any share of reference noise (docs/statistics.md, "Image comparisons in
/// looks").
pub fn look_sizes(written: u64, step: u64, budget: f64) -> [u64; 3] {
    let step = step.max(1);
    let quarter = ((written as f64 * budget / 4.0).ceil() as u64)
        .max(1)
        .div_ceil(step)
        * step;
    [quarter, quarter, 2 * quarter]
}

/// A region test's statistic on the normal scale: its t through its own two-sided p, with
/// the sign of its difference.
pub fn stage_z(r: &RegionResult) -> f64 {
    upper_quantile((r.p / 2.0).clamp(1e-300, 0.5)).copysign(r.z)
}

/// The two-sided design of [`LOOKS`] and [`SHAPES`] at per-test level `alpha`, computed once
/// per level and run (about 0.1 s each).
pub fn design_at(alpha: f64) -> Result<Design, CheckError> {
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

/// The outcome of a comparison in looks: every test with its stage-wise p, and what the
/// check's line says about the looks.
pub struct Looked {
    /// Each test's result where it stopped (the open ones at the last look), p stage-wise.
    tests: Vec<RegionResult>,
    /// Samples spent over the looks (pixels × samples).
    samples: u64,
    /// The worst test's fixed-test standard error whose detection limit the looks detect with
    /// 95 % probability (`Measurement::power_std_error`).
    power_se: f64,
    /// The sequential clause of the check's line.
    note: String,
}

impl Looked {
    /// The check's measurement: the region tests' Šidák combination with the looks' clause.
    pub fn measurement(&self, what: &str) -> Result<Measurement, CheckError> {
        let mut m = regions_measurement(&self.tests, self.samples, what)?;
        m.power_std_error = Some(self.power_se);
        m.message = format!("{}; {}", m.message, self.note);
        Ok(m)
    }
}

/// Runs a comparison of `n_tests` tests in three looks ([`look_sizes`], multiples of `step`)
/// of `unit` (what a sample count counts, e.g. "spp") against a written count of `written`, at
/// family level `alpha` for all its tests. `look(k, n, open)` adds n samples at look k to the
/// tests still open (`open[j]`) and returns every test's result on the cumulative samples,
/// always in the same order, and the pixel samples it spent. A test stops when the design
/// decides it; the looks end at a rejection or when every test stopped.
pub fn run(
    alpha: f64,
    n_tests: usize,
    written: u64,
    step: u64,
    unit: &str,
    mut look: impl FnMut(usize, u64, &[bool]) -> Result<(Vec<RegionResult>, u64), CheckError>,
) -> Result<Looked, CheckError> {
    if n_tests == 0 {
        return Err(CheckError::Setup(
            "a comparison in looks without tests".into(),
        ));
    }
    // Šidák share of the check's level: the check rejects at alpha when one test does
    let alpha_test = -((-alpha).ln_1p() / n_tests as f64).exp_m1();
    let d = design_at(alpha_test)?;
    let looks = look_sizes(written, step, d.inflation);
    // per test, once stopped: the look, its result there and its z
    let mut stopped: Vec<Option<(usize, RegionResult, f64)>> = vec![None; n_tests];
    // the refitted designs of the tests decided at the last look, kept for their p-values
    let mut fitted: Vec<Option<ReferenceFit>> = (0..n_tests).map(|_| None).collect();
    let mut samples = 0u64;
    let mut last: Vec<RegionResult> = Vec::new();
    let mut looks_done = 0;
    let mut rejected = false;
    let n_max: u64 = looks.iter().sum();
    for (k, &n) in looks.iter().enumerate() {
        let open: Vec<bool> = stopped.iter().map(Option::is_none).collect();
        let (results, spent) = look(k, n, &open)?;
        samples += spent;
        looks_done = k + 1;
        if results.len() != n_tests {
            return Err(CheckError::Setup(format!(
                "a look returned {} tests for {}",
                results.len(),
                n_tests
            )));
        }
        for (j, r) in results.iter().enumerate() {
            if stopped[j].is_some() {
                continue;
            }
            if !r.p.is_finite() {
                break; // reported by the measurement as a non-finite test
            }
            let z = stage_z(r);
            // the last look's boundary holds the level under the test's measured fractions
            let decision = if k + 1 == looks.len() {
                let f = fit(&d, r, n_max as f64, &looks, written);
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
        last = results;
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
    let cumulative = |k: usize| looks[..=k].iter().sum::<u64>() as f64;
    let fits: Vec<ReferenceFit> = tests
        .iter()
        .zip(fitted)
        .map(|((k, r, _), f)| f.unwrap_or_else(|| fit(&d, r, cumulative(*k), &looks, written)))
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
    // the worst test's level and power under its measured information fractions
    let worst = staged
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.p.total_cmp(&b.1.p))
        .map_or(0, |(j, _)| j);
    let weakest = fits.iter().map(|f| f.power).fold(1.0f64, f64::min);
    let highest = fits.iter().map(|f| f.level).fold(0.0f64, f64::max);
    let fractions = &fits[worst].design.t;
    let stops: Vec<usize> = (0..looks.len())
        .map(|k| tests.iter().filter(|t| t.0 == k).count())
        .collect();
    let verdict = if rejected { "rejected" } else { "accepted" };
    let note = format!(
        "sequential: {verdict} at look {looks_done} of 3 (looks of {} {unit}, at most {n_max} of the written {written}; tests stopped per look {stops:?}); stage-wise p at level {} a test; the reference's noise in every look: the worst test's information fractions {}, each test's last boundary fitted to its own, level at most {}, power at the fixed test's detection limit at least {}",
        looks.map(|x| x.to_string()).join(", "),
        fmt_sig(alpha_test),
        fractions.iter().map(|t| fmt_sig(*t)).collect::<Vec<_>>().join(", "),
        fmt_sig(highest),
        fmt_sig(weakest),
    );
    Ok(Looked {
        tests: staged,
        samples,
        power_se: fits[worst].power_se,
        note,
    })
}

/// A test's design under its measured information fractions: with the test's variance v (per
/// sample, times the sample count) and the reference's s², look k's information is
/// 1/(v/n_k + s²), and the cumulative z keeps the canonical joint law with it (Jennison &
/// Turnbull 2000, §3.1), so the fractions exceed n_k/n_max by the reference's share. The
/// design's first boundaries stand; the last efficacy boundary is solved again so that the
/// level is the design's under these fractions.
pub struct ReferenceFit {
    /// The design at the measured fractions, its last boundary refitted.
    pub design: Design,
    /// Its level (the design's, unless the earlier looks alone spend more).
    pub level: f64,
    /// Its power at the fixed test's detection limit.
    pub power: f64,
    /// The standard error of the fixed test whose detection limit the looks detect with 95 %
    /// probability (the fixed test's own when the power there is at least 95 %).
    pub power_se: f64,
}

/// [`ReferenceFit`] of test result `r` measured at `used` cumulative samples, with looks of
/// `looks` and the check's written count.
pub fn fit(
    d: &Design,
    r: &RegionResult,
    used: f64,
    looks: &[u64; 3],
    written: u64,
) -> ReferenceFit {
    let v = r.test.1.powi(2) * used;
    let s2 = r.reference.1.powi(2);
    let info = |n: f64| 1.0 / (v / n + s2);
    let n_max: f64 = looks.iter().sum::<u64>() as f64;
    let mut n = 0.0;
    let t: Vec<f64> = looks
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
        let look_spp = look_sizes(written, 1, d.inflation);
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
    fn the_designs_budget_keeps_the_power_whatever_the_reference_noise() {
        // With looks of the design's inflation and the last boundary refitted, the power at the
        // fixed test's detection limit is the design's 95 % or more for a reference variance
        // from none to 100× the fixed test's image variance, at the levels of a suite's tests
        // (3e-6) up to 0.05: the reference's noise needs no margin in the budget.
        for alpha in [3.4e-6, 1e-4, 1e-3, 1e-2, 5e-2] {
            let d = design_at(alpha).unwrap();
            let written = 1000u64;
            let looks = look_sizes(written, 1, d.inflation);
            let n = looks.iter().sum::<u64>() as f64;
            for rho in [0.0, 0.03, 0.1, 0.3, 1.0, 3.0, 10.0, 100.0] {
                let r = RegionResult {
                    region: "r".into(),
                    channel: "R",
                    test: (0.0, (1.0 / n).sqrt()),
                    reference: (0.0, (rho / written as f64).sqrt()),
                    z: 0.0,
                    dof: f64::INFINITY,
                    p: 1.0,
                };
                let f = fit(&d, &r, n, &looks, written);
                assert!(f.power >= 0.9499, "α {alpha}, ρ {rho}: power {}", f.power);
                assert!(
                    f.level <= alpha * 1.001,
                    "α {alpha}, ρ {rho}: level {}",
                    f.level
                );
            }
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
