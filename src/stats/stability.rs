//! Is a standard error trustworthy? Diagnostics for heavy tails and correlation: [`diagnose`]
//! takes independent batch values in a fixed order (e.g. per-pixel means, in any one unit) and
//! flags (a) batch-means standard errors at b = 1, 2, 4, … that disagree beyond chi-square
//! sampling error (dependence on the order), (b) a Hill tail index of |x − median| whose upper
//! confidence bound is below 2 (infinite variance); (c) the largest share of the sum of
//! squares is evidence only. Calibration and the choices behind (b): docs/statistics.md,
//! "`stats::stability`".

use statrs::distribution::{ChiSquared, ContinuousCDF, Gamma};

/// Fewest batches allowed at any batch size in criterion (a); two batch sizes, and so a
/// diagnosis, need at least 2·MIN_BATCHES = 16 values.
pub const MIN_BATCHES: usize = 8;

/// Fewest upper order statistics for the Hill estimate of criterion (b).
pub const MIN_HILL_K: usize = 10;

/// Largest fraction 1/HILL_MAX_FRACTION of the values used as upper order statistics.
/// Together with [`MIN_HILL_K`] this makes criterion (b) need at least 160 values.
pub const HILL_MAX_FRACTION: usize = 16;

/// Tail index at or below which the variance is infinite.
pub const INFINITE_VARIANCE_INDEX: f64 = 2.0;

/// Verdict of [`diagnose`], with the numbers behind it.
#[derive(Debug, Clone, PartialEq)]
pub struct Stability {
    /// True when no criterion fired (the standard error may be trusted).
    pub stable: bool,
    /// (batch size b in values, standard error of the grand mean of all n values estimated
    /// from the means of batches of b, in the units of the values), for b = 1, 2, 4, …
    /// while at least [`MIN_BATCHES`] batches remain. The SE from batches of b is
    /// sqrt(b·s_b²/n) with s_b² the sample variance of the batch means (equal to
    /// sd(batch means)/sqrt(k) when b divides n; trailing values that do not fill a batch
    /// are left out of s_b²).
    pub se_by_batch_size: Vec<(usize, f64)>,
    /// Largest over smallest entry of `se_by_batch_size` (dimensionless, >= 1); 1 when
    /// not evaluated or all SEs are 0; +∞ when only the smallest is 0.
    pub se_ratio: f64,
    /// Largest `se_ratio` compatible with chi-square sampling error of the two batch sizes
    /// involved, at the false-alarm level (dimensionless); +∞ when not evaluated.
    pub se_ratio_limit: f64,
    /// Hill estimate of the tail index of |x − median| (dimensionless; +∞ when the top
    /// order statistics are all equal). None with fewer than 160 values, or when the
    /// (k+1)-th largest deviation is 0.
    pub hill_alpha: Option<f64>,
    /// Upper confidence bound on the tail index at confidence 1 − false_alarm.
    pub hill_upper: Option<f64>,
    /// Largest single (x − mean)² over Σ (x − mean)², in [0, 1]; evidence only.
    pub max_share: f64,
    /// Which criterion fired, with its numbers; or "stable: …" with the numbers.
    pub reason: String,
}

/// Diagnoses whether the standard error of the mean of `values` (independent batch values
/// in a fixed order) can be trusted. `false_alarm` is the probability (per criterion,
/// so at most 2·false_alarm in all) of declaring well-behaved iid data unstable.
///
/// Degenerate inputs never panic: a `false_alarm` outside (0, 1), or any non-finite
/// value, gives `stable = false` with the reason; fewer than 16 values (fewer than two
/// batch sizes) gives `stable = true` with reason "too few batches to diagnose"; constant
/// input is stable with every standard error 0.
pub fn diagnose(values: &[f64], false_alarm: f64) -> Stability {
    let mut out = Stability {
        stable: true,
        se_by_batch_size: Vec::new(),
        se_ratio: 1.0,
        se_ratio_limit: f64::INFINITY,
        hill_alpha: None,
        hill_upper: None,
        max_share: 0.0,
        reason: String::new(),
    };
    if !(false_alarm > 0.0 && false_alarm < 1.0) {
        out.stable = false;
        out.reason = format!("false_alarm must lie in (0, 1), got {false_alarm}");
        return out;
    }
    let bad = values.iter().filter(|v| !v.is_finite()).count();
    if bad > 0 {
        out.stable = false;
        out.reason = format!("{bad} of {} values are not finite", values.len());
        return out;
    }

    // Work on (x − median)/max|x|: no overflow in squares or differences, and constant
    // data gives exact zeros instead of rounding noise. SEs are scaled back at the end.
    let scale = values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let scaled: Vec<f64> = if scale > 0.0 {
        values.iter().map(|v| v / scale).collect()
    } else {
        values.to_vec()
    };
    let med = median(&scaled);
    let centred: Vec<f64> = scaled.iter().map(|v| v - med).collect();
    let n = centred.len();

    out.se_by_batch_size = batch_standard_errors(&centred)
        .into_iter()
        .map(|(b, se)| (b, se * scale))
        .collect();
    out.max_share = max_share(&centred);
    if out.se_by_batch_size.len() < 2 {
        out.reason = "too few batches to diagnose".to_string();
        return out;
    }

    // (a) Batch-means agreement.
    let sizes = out.se_by_batch_size.len();
    let level = false_alarm / sizes as f64;
    let (i_max, se_max) = extreme(&out.se_by_batch_size, |a, b| a > b);
    let (i_min, se_min) = extreme(&out.se_by_batch_size, |a, b| a < b);
    out.se_ratio = if se_max == 0.0 {
        1.0
    } else if se_min == 0.0 {
        f64::INFINITY
    } else {
        se_max / se_min
    };
    let dof = |i: usize| (n / out.se_by_batch_size[i].0 - 1) as f64;
    // s²·ν/σ² ~ χ²(ν) for normal batch means (Cochran's theorem, e.g. Casella & Berger 2002,
    // Thm 5.3.1), each inside [χ²_{a/2}, χ²_{1−a/2}]/ν: ratio ≤ sqrt(hi(max)/lo(min)).
    let hi = chi2_quantile(1.0 - level / 2.0, dof(i_max)) / dof(i_max);
    let lo = chi2_quantile(level / 2.0, dof(i_min)) / dof(i_min);
    out.se_ratio_limit = if lo > 0.0 {
        (hi / lo).sqrt()
    } else {
        f64::INFINITY
    };
    let batch_fired = out.se_ratio > out.se_ratio_limit;

    // (b) Hill tail index of |x − median|.
    if let Some((alpha, k)) = hill(&centred) {
        out.hill_alpha = Some(alpha);
        out.hill_upper = Some(hill_upper_bound(alpha, k, false_alarm));
    }
    let hill_fired = out.hill_upper.is_some_and(|u| u < INFINITE_VARIANCE_INDEX);

    let batch_text = format!(
        "SE ratio {:.4} (batch size {} vs {}) vs limit {:.4}",
        out.se_ratio,
        out.se_by_batch_size[i_max].0,
        out.se_by_batch_size[i_min].0,
        out.se_ratio_limit
    );
    let hill_text = match (out.hill_alpha, out.hill_upper) {
        (Some(a), Some(u)) => format!("Hill tail index {a:.3}, upper bound {u:.3} vs 2"),
        _ if n < MIN_HILL_K * HILL_MAX_FRACTION => format!(
            "Hill tail index not evaluated (n = {n} < {})",
            MIN_HILL_K * HILL_MAX_FRACTION
        ),
        _ => "Hill tail index not evaluated (threshold deviation is 0)".to_string(),
    };
    let share_text = format!("max share {:.4}", out.max_share);
    out.stable = !(batch_fired || hill_fired);
    out.reason = match (batch_fired, hill_fired) {
        (false, false) => format!("stable: {batch_text}; {hill_text}; {share_text}"),
        (true, false) => format!("batch means disagree: {batch_text}; {hill_text}; {share_text}"),
        (false, true) => {
            format!("variance likely infinite: {hill_text}; {batch_text}; {share_text}")
        }
        (true, true) => format!(
            "batch means disagree and variance likely infinite: {batch_text}; {hill_text}; \
             {share_text}"
        ),
    };
    out
}

/// (b, SE) for b = 1, 2, 4, … while n/b >= MIN_BATCHES, from the first (n/b)·b values.
fn batch_standard_errors(centred: &[f64]) -> Vec<(usize, f64)> {
    let n = centred.len();
    let mut out = Vec::new();
    let mut b = 1usize;
    while b <= n / MIN_BATCHES {
        let k = n / b;
        let means: Vec<f64> = centred[..k * b]
            .chunks_exact(b)
            .map(|c| c.iter().sum::<f64>() / b as f64)
            .collect();
        let m = means.iter().sum::<f64>() / k as f64;
        let s2 = means.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (k - 1) as f64;
        // Batch means (e.g. Law & Kelton 2000, Simulation Modeling and Analysis, §9.5.3):
        // Var(x̄_b) = σ²/b, so b·s_b² estimates σ² and SE(grand mean) = sqrt(b·s_b²/n).
        out.push((b, (b as f64 * s2 / n as f64).sqrt()));
        match b.checked_mul(2) {
            Some(next) => b = next,
            None => break,
        }
    }
    out
}

/// Largest fraction 1/SD_TAIL_FRACTION of the per-pixel standard deviations used as upper
/// order statistics by [`sd_tail`]; with [`MIN_HILL_K`] it needs at least 40 pixels.
pub const SD_TAIL_FRACTION: usize = 4;

/// Hill's tail index of per-pixel standard deviations, from [`sd_tail`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SdTail {
    /// Hill estimate of the tail index (dimensionless; +∞ when the top values are all equal).
    pub alpha: f64,
    /// Upper confidence bound on the tail index at confidence 1 − `p`.
    pub upper: f64,
    /// Upper order statistics used.
    pub k: usize,
    /// Standard deviations given (pixels with Monte Carlo noise).
    pub n: usize,
    /// One minus the bound's confidence.
    pub p: f64,
}

impl SdTail {
    /// True when the bound says the variance is infinite (tail index below 2).
    pub fn infinite(&self) -> bool {
        self.upper < INFINITE_VARIANCE_INDEX
    }
}

/// Hill's tail index of per-pixel sample standard deviations (each pixel's sd of its own
/// samples or batch values, all pixels with the same count), with an upper bound at confidence
/// 1 − `p`. A pixel's sample variance of m draws from a tail of index a has a tail of index a/2
/// (its largest draw dominates it), so its sd has the draws' own index a: unlike the pixel
/// means, which averaging pulls toward a normal body, the sds show an infinite-variance tail
/// (a < 2) at modest budgets. k = n/[`SD_TAIL_FRACTION`]; None below [`MIN_HILL_K`], when
/// the (k+1)-th largest sd is 0, or for a `p` outside (0, 1). Non-finite and non-positive
/// entries are left out. Calibration: docs/statistics.md, "Infinite variance".
pub fn sd_tail(sds: &[f64], p: f64) -> Option<SdTail> {
    if !(p > 0.0 && p < 1.0) {
        return None;
    }
    let mut v: Vec<f64> = sds
        .iter()
        .copied()
        .filter(|s| s.is_finite() && *s > 0.0)
        .collect();
    let n = v.len();
    let k = n / SD_TAIL_FRACTION;
    if k < MIN_HILL_K {
        return None;
    }
    v.sort_by(|a, b| b.total_cmp(a));
    let alpha = hill_of_descending(&v, k)?;
    Some(SdTail {
        alpha,
        upper: hill_upper_bound(alpha, k, p),
        k,
        n,
        p,
    })
}

/// Number of upper order statistics for Hill's estimator from n values:
/// min(2√n, n/16), or None below [`MIN_HILL_K`].
fn hill_k(n: usize) -> Option<usize> {
    let k = ((2.0 * (n as f64).sqrt()) as usize).min(n / HILL_MAX_FRACTION);
    (k >= MIN_HILL_K).then_some(k)
}

/// Hill estimate of the tail index of |centred| and the k it used.
fn hill(centred: &[f64]) -> Option<(f64, usize)> {
    let k = hill_k(centred.len())?;
    let mut dev: Vec<f64> = centred.iter().map(|v| v.abs()).collect();
    dev.sort_by(|a, b| b.total_cmp(a));
    Some((hill_of_descending(&dev, k)?, k))
}

/// Hill's estimate from the k largest of nonnegative values sorted in descending order (more
/// than k of them); None when the (k+1)-th is 0.
fn hill_of_descending(desc: &[f64], k: usize) -> Option<f64> {
    let threshold = *desc.get(k)?;
    if threshold <= 0.0 {
        return None;
    }
    let sum: f64 = desc[..k].iter().map(|x| (x / threshold).ln()).sum();
    // Hill 1975, Ann. Stat. 3:1163: 1/α̂ = (1/k) Σ_{i=1..k} ln(X_(i) / X_(k+1)).
    Some(if sum > 0.0 {
        k as f64 / sum
    } else {
        f64::INFINITY
    })
}

/// Upper confidence bound, at confidence 1 − p, on the tail index given Hill's α̂ from k
/// order statistics. Under a Pareto tail the k log-spacings sum to S with α·S ~ Gamma(k, 1)
/// exactly, so α ≤ α̂·G⁻¹_k(1 − p)/k.
fn hill_upper_bound(alpha_hat: f64, k: usize, p: f64) -> f64 {
    if !alpha_hat.is_finite() {
        return f64::INFINITY;
    }
    // Rényi 1953, Acta Math. Hung. 4 (exponential spacings), as used by Hill 1975:
    // α·Σ ln(X_(i)/X_(k+1)) ~ Γ(k, 1), so P(α ≤ α̂·G⁻¹_k(1 − p)/k) = 1 − p.
    let q = match Gamma::new(k as f64, 1.0) {
        Ok(g) if p > 0.0 && p < 1.0 => g.inverse_cdf(1.0 - p),
        _ => f64::INFINITY,
    };
    alpha_hat * q / k as f64
}

/// Largest single squared deviation from the mean over their sum; 0 when all equal.
fn max_share(centred: &[f64]) -> f64 {
    if centred.is_empty() {
        return 0.0;
    }
    let mean = centred.iter().sum::<f64>() / centred.len() as f64;
    // Definition: max_i (x_i − x̄)² / Σ_i (x_i − x̄)².
    let (sum, max) = centred.iter().fold((0.0f64, 0.0f64), |(s, m), x| {
        let d = (x - mean) * (x - mean);
        (s + d, m.max(d))
    });
    if sum > 0.0 {
        (max / sum).min(1.0)
    } else {
        0.0
    }
}

/// Median of finite values (0 for none).
fn median(values: &[f64]) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    let h = v.len() / 2;
    if v.len() % 2 == 1 {
        v[h]
    } else {
        v[h - 1] + (v[h] - v[h - 1]) / 2.0
    }
}

/// Index and value of the entry of non-empty `v` preferred by `better` (first on ties).
fn extreme(v: &[(usize, f64)], better: impl Fn(f64, f64) -> bool) -> (usize, f64) {
    let mut best = (0, v.first().map_or(0.0, |e| e.1));
    for (i, &(_, se)) in v.iter().enumerate().skip(1) {
        if better(se, best.1) {
            best = (i, se);
        }
    }
    best
}

/// Quantile of ChiSquared(dof) at probability p; 0 for p <= 0, +∞ for p >= 1 or bad dof.
fn chi2_quantile(p: f64, dof: f64) -> f64 {
    if p.is_nan() || p <= 0.0 {
        return 0.0;
    }
    if p >= 1.0 {
        return f64::INFINITY;
    }
    match ChiSquared::new(dof) {
        Ok(d) => d.inverse_cdf(p),
        Err(_) => f64::INFINITY,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::rng::SampleStream;

    /// The crate's deterministic counter-based stream, keyed by the test's seed, with the two
    /// draws these tests need.
    struct TestRng(SampleStream);

    impl TestRng {
        fn new(seed: u64) -> Self {
            TestRng(SampleStream::new(seed, 0, 0))
        }
        /// Uniform in (0, 1].
        fn next_open(&mut self) -> f64 {
            1.0 - self.0.next_f64()
        }
        fn normal(&mut self) -> f64 {
            // Box & Muller 1958, Ann. Math. Stat. 29: sqrt(−2 ln u1)·cos(2π u2).
            let (u1, u2) = (self.next_open(), self.next_open());
            (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
        }
    }

    fn normal_data(seed: u64, n: usize) -> Vec<f64> {
        let mut r = TestRng::new(seed);
        (0..n).map(|_| 3.0 + 0.5 * r.normal()).collect()
    }

    fn exponential_data(seed: u64, n: usize) -> Vec<f64> {
        let mut r = TestRng::new(seed);
        (0..n).map(|_| -r.next_open().ln()).collect()
    }

    fn chi2_1_data(seed: u64, n: usize) -> Vec<f64> {
        let mut r = TestRng::new(seed);
        (0..n).map(|_| r.normal().powi(2)).collect()
    }

    fn t3_data(seed: u64, n: usize) -> Vec<f64> {
        let mut r = TestRng::new(seed);
        (0..n)
            .map(|_| {
                let z = r.normal();
                let c: f64 = (0..3).map(|_| r.normal().powi(2)).sum();
                z / (c / 3.0).sqrt()
            })
            .collect()
    }

    /// Pareto with tail index `index`: x = u^(−1/index), u uniform in (0, 1].
    fn pareto_data(seed: u64, n: usize, index: f64) -> Vec<f64> {
        let mut r = TestRng::new(seed);
        (0..n).map(|_| r.next_open().powf(-1.0 / index)).collect()
    }

    /// Stationary AR(1) with coefficient phi and unit innovations.
    fn ar1_data(seed: u64, n: usize, phi: f64) -> Vec<f64> {
        let mut r = TestRng::new(seed);
        let mut x = r.normal() / (1.0 - phi * phi).sqrt();
        (0..n)
            .map(|_| {
                x = phi * x + r.normal();
                x
            })
            .collect()
    }

    fn no_nan(s: &Stability) -> bool {
        s.se_ratio.is_finite()
            && !s.se_ratio_limit.is_nan()
            && !s.max_share.is_nan()
            && s.se_by_batch_size.iter().all(|(_, se)| se.is_finite())
            && !s.hill_alpha.is_some_and(f64::is_nan)
            && !s.hill_upper.is_some_and(f64::is_nan)
    }

    #[test]
    fn does_not_flag_normal_or_exponential() {
        for seed in 1..=8 {
            for (name, v) in [
                ("normal", normal_data(seed, 4096)),
                ("exponential", exponential_data(seed, 4096)),
            ] {
                let s = diagnose(&v, 1e-3);
                assert!(s.stable, "{name} seed {seed}: {}", s.reason);
                assert!(s.reason.starts_with("stable"));
                assert!(no_nan(&s));
                assert!(s.hill_upper.unwrap() > 3.0, "{name}: {}", s.reason);
                assert_eq!(s.se_by_batch_size.len(), 10, "b = 1 … 512");
            }
        }
    }

    #[test]
    fn flags_pareto_with_infinite_variance() {
        for seed in 1..=8 {
            let s = diagnose(&pareto_data(seed, 4096, 1.2), 1e-3);
            assert!(!s.stable, "seed {seed}: {}", s.reason);
            assert!(
                s.reason.contains("variance likely infinite"),
                "{}",
                s.reason
            );
            assert!(s.hill_upper.unwrap() < 2.0);
            // Evidence: a handful of values carry much of the sum of squares.
            assert!(s.max_share > 0.05, "{}", s.max_share);
        }
    }

    #[test]
    fn hill_recovers_known_tail_index() {
        // Pure Pareto above its median: Hill's estimator is unbiased up to k/(k − 1); with
        // n = 16384 (k = 256) it lands within a few percent of the true index.
        for &index in &[1.0, 1.5, 3.0] {
            let v = pareto_data(11, 16384, index);
            let (a, k) = hill(&v).unwrap();
            assert_eq!(k, 256);
            // |x − 0| here (no centring), so the tail is exactly Pareto.
            assert!((a / index - 1.0).abs() < 0.2, "index {index}: {a}");
        }
    }

    #[test]
    fn hill_upper_bound_matches_gamma_quantile() {
        // Gamma(10, 1) quantile at 0.95 is 15.7052 (χ²_{20, 0.95}/2 = 31.4104/2).
        assert!((hill_upper_bound(1.0, 10, 0.05) - 1.570_52).abs() < 1e-4);
        assert_eq!(hill_upper_bound(f64::INFINITY, 10, 0.05), f64::INFINITY);
    }

    #[test]
    fn flags_strong_serial_correlation() {
        // Negative control for criterion (a): AR(1) with φ = 0.9 has a true SE
        // sqrt((1 + φ)/(1 − φ)) = 4.4 times the naive one; batch means must see it.
        for seed in 1..=5 {
            let s = diagnose(&ar1_data(seed, 4096, 0.9), 1e-3);
            assert!(!s.stable, "seed {seed}: {}", s.reason);
            assert!(s.reason.starts_with("batch means disagree"), "{}", s.reason);
            assert!(s.se_ratio > 2.0);
        }
    }

    #[test]
    fn batch_standard_errors_known_values() {
        // 1..=16: b = 1 gives sd/sqrt(16) with sd² = 16·17/12 = 22.667.
        let v: Vec<f64> = (1..=16).map(f64::from).collect();
        let se = batch_standard_errors(&v);
        assert_eq!(se.len(), 2);
        assert!((se[0].1 - (272.0f64 / 12.0 / 16.0).sqrt()).abs() < 1e-12);
        // b = 2: means 1.5, 3.5, …, 15.5 (8 values, spacing 2): s² = 4·8·9/12 = 24;
        // SE = sqrt(2·24/16) = sqrt(3).
        assert_eq!(se[1].0, 2);
        assert!((se[1].1 - 3f64.sqrt()).abs() < 1e-12);
    }

    #[test]
    fn constant_input_is_stable_with_zero_se() {
        for v in [vec![0.1; 4096], vec![0.0; 100], vec![-7.25; 17]] {
            let s = diagnose(&v, 1e-3);
            assert!(s.stable, "{}", s.reason);
            assert!(s.se_by_batch_size.iter().all(|&(_, se)| se == 0.0));
            assert_eq!(s.se_ratio, 1.0);
            assert_eq!(s.max_share, 0.0);
            assert!(no_nan(&s));
        }
    }

    #[test]
    fn too_few_values() {
        for n in [0, 1, 2, 8, 15] {
            let s = diagnose(&exponential_data(3, n), 1e-3);
            assert!(s.stable);
            assert_eq!(s.reason, "too few batches to diagnose");
            assert!(no_nan(&s));
        }
        // 16 values: two batch sizes, diagnosed (without Hill).
        let s = diagnose(&exponential_data(3, 16), 1e-3);
        assert_eq!(s.se_by_batch_size.len(), 2);
        assert!(s.hill_alpha.is_none());
        assert!(s.reason.contains("not evaluated"), "{}", s.reason);
    }

    #[test]
    fn degenerate_inputs_fail_closed() {
        let mut v = normal_data(1, 100);
        v[5] = f64::NAN;
        let s = diagnose(&v, 1e-3);
        assert!(!s.stable);
        assert!(s.reason.contains("not finite"));
        v[5] = f64::INFINITY;
        assert!(!diagnose(&v, 1e-3).stable);
        for fa in [0.0, 1.0, -1.0, f64::NAN] {
            let s = diagnose(&normal_data(1, 100), fa);
            assert!(!s.stable);
            assert!(s.reason.contains("false_alarm"));
        }
    }

    #[test]
    fn extreme_magnitudes_do_not_overflow() {
        let v: Vec<f64> = normal_data(2, 1024)
            .iter()
            .map(|x| (x - 3.0) * 1e307)
            .collect();
        let s = diagnose(&v, 1e-3);
        assert!(s.stable, "{}", s.reason);
        assert!(no_nan(&s));
        assert!(s.se_by_batch_size[0].1 > 1e304 && s.se_by_batch_size[0].1 < 1e306);
        let tiny: Vec<f64> = normal_data(2, 1024).iter().map(|x| x * 1e-300).collect();
        assert!(diagnose(&tiny, 1e-3).stable);
    }

    #[test]
    fn lumpy_data_has_no_hill_estimate() {
        // Mostly equal values: the (k+1)-th largest deviation from the median is 0.
        let mut v = vec![1.0; 1000];
        v[10] = 5.0;
        let s = diagnose(&v, 1e-3);
        assert!(s.hill_alpha.is_none());
        assert!(no_nan(&s));
        assert!(s.max_share > 0.99);
    }

    /// Calibration run behind the thresholds, part of `cargo test --release` (13 s; slow in
    /// debug builds): `cargo test --release --lib calibration_false_alarm_and_power --
    /// --nocapture` prints the table quoted in docs/statistics.md. Ignored in debug builds.
    #[test]
    #[cfg_attr(debug_assertions, ignore)]
    fn calibration_false_alarm_and_power() {
        type Gen = Box<dyn Fn(u64, usize) -> Vec<f64>>;
        let light: Vec<(&str, Gen)> = vec![
            ("normal", Box::new(normal_data)),
            ("exponential", Box::new(exponential_data)),
            ("chi2(1)", Box::new(chi2_1_data)),
            ("t(3)", Box::new(t3_data)),
        ];
        for &n in &[16usize, 64, 160, 256, 1024, 4096, 16384] {
            let seeds = (2_000_000 / n).clamp(300, 20_000) as u64;
            for (name, gen) in &light {
                let flagged = (0..seeds)
                    .filter(|&s| !diagnose(&gen(s * 7919 + 1, n), 1e-3).stable)
                    .count();
                println!("n = {n:5} {name:12} flagged {flagged} of {seeds}");
                assert!(flagged as f64 <= 2e-3 * seeds as f64 + 1.0);
            }
        }
        let seeds = 2000;
        let flagged = (0..seeds)
            .filter(|&s| !diagnose(&pareto_data(s * 7919 + 1, 4096, 1.2), 1e-3).stable)
            .count();
        println!("n =  4096 Pareto(1.2)  flagged {flagged} of {seeds}");
        // power against infinite variance: at least 99 % (1997 of 2000 on 2026-12-02)
        assert!(
            flagged as f64 >= 0.99 * seeds as f64,
            "{flagged} of {seeds}"
        );
    }

    /// Sample sds of `pixels` groups of `m` consecutive values.
    fn pixel_sds(values: &[f64], m: usize) -> Vec<f64> {
        values
            .chunks_exact(m)
            .map(|c| {
                let mean = c.iter().sum::<f64>() / m as f64;
                (c.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (m - 1) as f64).sqrt()
            })
            .collect()
    }

    #[test]
    fn sd_tail_recovers_the_draws_own_index() {
        // 256 pixels of 64 Pareto(1.2) draws: the sds' index is the draws' 1.2, not the 2-ish
        // that Hill reads on the pixel means
        let sds = pixel_sds(&pareto_data(5, 256 * 64, 1.2), 64);
        let t = sd_tail(&sds, 0.05).unwrap();
        assert!((t.alpha - 1.2).abs() < 0.3, "{t:?}");
        assert!(t.infinite() && t.k == 64 && t.n == 256, "{t:?}");
        // degenerate inputs: too few pixels, zeros, a bad p
        assert!(sd_tail(&sds[..39], 0.05).is_none());
        assert!(sd_tail(&[0.0; 400], 0.05).is_none());
        assert!(sd_tail(&sds, 0.0).is_none() && sd_tail(&sds, f64::NAN).is_none());
        let mut with_bad = sds.clone();
        with_bad.extend([f64::NAN, f64::INFINITY, -1.0]);
        assert_eq!(sd_tail(&with_bad, 0.05).map(|t| t.n), Some(256));
    }

    /// Calibration of [`sd_tail`] at the level the harness uses (5 %, relabelling a rejected
    /// mean test): finite-variance draws (normal, exponential, χ²(1), Student t(3)) in 256 pixels
    /// of 4 (a black box's batches) or 64 values are flagged in at most 1 % of 300 runs (0 on
    /// 2026-12-04); Pareto(1.24) (Mitsuba's capped roulette at albedo 0.99) in at least 95 %.
    /// `cargo test --release --lib sd_tail_calibration -- --nocapture` prints the table quoted
    /// in docs/statistics.md. Ignored in debug builds.
    #[test]
    #[cfg_attr(debug_assertions, ignore)]
    fn sd_tail_calibration() {
        type Gen = Box<dyn Fn(u64, usize) -> Vec<f64>>;
        let cases: Vec<(&str, Gen, bool)> = vec![
            ("normal", Box::new(normal_data), false),
            ("exponential", Box::new(exponential_data), false),
            ("chi2(1)", Box::new(chi2_1_data), false),
            ("t(3)", Box::new(t3_data), false),
            (
                "Pareto(1.24)",
                Box::new(|s, n| pareto_data(s, n, 1.24)),
                true,
            ),
        ];
        let runs = 300u64;
        for m in [4usize, 64] {
            for (name, gen, infinite) in &cases {
                let flagged = (0..runs)
                    .filter(|&s| {
                        sd_tail(&pixel_sds(&gen(s * 7919 + 3, 256 * m), m), 0.05)
                            .is_some_and(|t| t.infinite())
                    })
                    .count();
                println!("m = {m:2} {name:13} flagged {flagged} of {runs}");
                if *infinite {
                    assert!(flagged as f64 >= 0.95 * runs as f64, "{name}: {flagged}");
                } else {
                    assert!(flagged as f64 <= 0.01 * runs as f64, "{name}: {flagged}");
                }
            }
        }
        // Barely finite variance, printed and not asserted (docs/statistics.md): Pareto(2.2),
        // whose third moment is infinite, is flagged often at 4 values per pixel.
        for m in [4usize, 64] {
            let flagged = (0..runs)
                .filter(|&s| {
                    sd_tail(
                        &pixel_sds(&pareto_data(s * 7919 + 3, 256 * m, 2.2), m),
                        0.05,
                    )
                    .is_some_and(|t| t.infinite())
                })
                .count();
            println!("m = {m:2} Pareto(2.2)   flagged {flagged} of {runs} (finite variance)");
        }
    }
}
