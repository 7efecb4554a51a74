//! Family-wise error control for many simultaneous tests.
//!
//! Running m tests each at level α rejects at least one true null hypothesis with
//! probability up to 1 − (1 − α)^m. These routines choose per-test levels (Šidák), combine
//! p-values of a family into one (Šidák on the minimum), or decide rejections step-down
//! (Holm) so that the probability of *any* false rejection stays at most the family rate.
//!
//! Conventions, shared by every function here: probabilities are clamped into [0, 1]; a
//! NaN p-value counts as 0 (a test that could not compute its p-value is a failure, never
//! silently a pass); a NaN or non-positive family rate rejects nothing.

/// Šidák per-test level for m independent tests at family-wise rate `family_alpha`
/// (probability): 1 − (1 − α)^(1/m). Accurate for tiny α and huge m.
///
/// Degenerate inputs: `m = 0` returns `family_alpha`; a NaN or non-positive
/// `family_alpha` returns 0; `family_alpha >= 1` returns 1.
pub fn sidak_alpha(family_alpha: f64, m: usize) -> f64 {
    if family_alpha.is_nan() || family_alpha <= 0.0 {
        return 0.0;
    }
    if family_alpha >= 1.0 {
        return 1.0;
    }
    if m == 0 {
        return family_alpha;
    }
    // Šidák 1967, JASA 62: α_1 = 1 − (1 − α)^(1/m), evaluated as −expm1(ln1p(−α)/m).
    (-((-family_alpha).ln_1p() / m as f64).exp_m1()).clamp(0.0, 1.0)
}

/// Šidák-combined p-value (probability) of a family of k independent tests, from the
/// smallest of their p-values: 1 − (1 − p_min)^k. Accurate for tiny p_min and huge k.
///
/// An empty family returns 1 (no evidence against anything). NaN p-values count as 0.
pub fn sidak_combine(p_values: &[f64]) -> f64 {
    if p_values.is_empty() {
        return 1.0;
    }
    let p_min = p_values.iter().map(|&p| clean_p(p)).fold(1.0f64, f64::min);
    let k = p_values.len() as f64;
    // Šidák 1967, JASA 62 (distribution of the minimum of k uniforms): 1 − (1 − p)^k.
    (-(k * (-p_min).ln_1p()).exp_m1()).clamp(0.0, 1.0)
}

/// Holm step-down procedure at family-wise rate `family_alpha` (probability).
///
/// Returns, for each input p-value in input order, `(rejected, threshold)`: the i-th
/// smallest p-value (i = 1..m, ties broken by input order) has threshold α / (m − i + 1);
/// p-values are rejected in ascending order while each is ≤ its threshold, and the first
/// one that is not stops the procedure (every larger p-value is then kept even if it is
/// below its own threshold). NaN p-values count as 0; a NaN or non-positive rate rejects
/// nothing.
pub fn holm(p_values: &[f64], family_alpha: f64) -> Vec<(bool, f64)> {
    let m = p_values.len();
    let alpha = if family_alpha.is_nan() {
        0.0
    } else {
        family_alpha.clamp(0.0, 1.0)
    };
    let mut order: Vec<usize> = (0..m).collect();
    order.sort_by(|&a, &b| clean_p(p_values[a]).total_cmp(&clean_p(p_values[b])));
    let mut out = vec![(false, 0.0); m];
    let mut still_rejecting = alpha > 0.0;
    for (rank, &i) in order.iter().enumerate() {
        // Holm 1979, Scand. J. Stat. 6: threshold α / (m − i + 1) for the i-th smallest.
        let threshold = alpha / (m - rank) as f64;
        still_rejecting = still_rejecting && clean_p(p_values[i]) <= threshold;
        out[i] = (still_rejecting, threshold);
    }
    out
}

/// NaN counts as 0 (failure); everything else is clamped into [0, 1].
fn clean_p(p: f64) -> f64 {
    if p.is_nan() {
        0.0
    } else {
        p.clamp(0.0, 1.0)
    }
}

/// Number of hypotheses rejected by the Benjamini–Hochberg step-up procedure at FDR `q`:
/// the largest k with p₍ₖ₎ ≤ k·q/m (Benjamini & Hochberg 1995, §3). NaN p-values count as 0.
pub fn benjamini_hochberg(p: &[f64], q: f64) -> usize {
    let m = p.len();
    let mut s: Vec<f64> = p
        .iter()
        .map(|x| if x.is_nan() { 0.0 } else { *x })
        .collect();
    s.sort_by(f64::total_cmp);
    (1..=m)
        .rev()
        .find(|&k| s[k - 1] <= k as f64 * q / m as f64)
        .unwrap_or(0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rel(a: f64, b: f64) -> f64 {
        ((a - b) / b).abs()
    }

    #[test]
    fn sidak_alpha_known_values() {
        // 1 − 0.95^(1/10) = 0.005116196891...
        assert!(rel(sidak_alpha(0.05, 10), 0.005_116_196_891_4) < 1e-10);
        // 1 − 0.99^(1/2) = 0.005012562893...
        assert!(rel(sidak_alpha(0.01, 2), 0.005_012_562_893_4) < 1e-10);
        assert_eq!(sidak_alpha(0.05, 1), 0.05);
        // Šidák is always slightly more generous than Bonferroni α/m.
        assert!(sidak_alpha(0.05, 10) > 0.005);
    }

    #[test]
    fn sidak_alpha_tiny_rates_keep_precision() {
        // α = 1e-12, m = 1e6: naive 1 − (1 − α)^(1/m) loses everything; the answer is
        // α/m·(1 + α(1 − 1/m)/2 + ...) = 1e-18·(1 + 5e-13).
        let a = sidak_alpha(1e-12, 1_000_000);
        assert!(rel(a, 1e-18) < 1e-12, "{a:e}");
        let naive = 1.0 - (1.0f64 - 1e-12).powf(1e-6);
        assert!(
            rel(naive, 1e-18) > 1e-3,
            "the naive form should be visibly wrong"
        );
    }

    #[test]
    fn sidak_alpha_degenerate_inputs() {
        assert_eq!(sidak_alpha(0.05, 0), 0.05);
        assert_eq!(sidak_alpha(f64::NAN, 3), 0.0);
        assert_eq!(sidak_alpha(-1.0, 3), 0.0);
        assert_eq!(sidak_alpha(0.0, 3), 0.0);
        assert_eq!(sidak_alpha(1.0, 3), 1.0);
        assert_eq!(sidak_alpha(2.0, 3), 1.0);
    }

    #[test]
    fn sidak_combine_known_values() {
        // 1 − 0.99^3 = 0.029701.
        assert!(rel(sidak_combine(&[0.2, 0.01, 0.5]), 0.029_701) < 1e-12);
        // Combining with the per-test Šidák level recovers the family rate.
        let a = sidak_alpha(0.05, 7);
        assert!(rel(sidak_combine(&[a, 0.9, 0.9, 0.9, 0.9, 0.9, 0.9]), 0.05) < 1e-12);
        // Tiny p, many tests: 1 − (1 − 1e-20)^1000 = 1e-17.
        assert!(rel(sidak_combine(&vec![1e-20; 1000]), 1e-17) < 1e-12);
        assert_eq!(sidak_combine(&[0.3]), 0.3);
    }

    #[test]
    fn sidak_combine_degenerate_inputs() {
        assert_eq!(sidak_combine(&[]), 1.0);
        assert_eq!(
            sidak_combine(&[0.5, f64::NAN]),
            0.0,
            "NaN must count as failure"
        );
        assert_eq!(sidak_combine(&[1.5, 2.0]), 1.0);
        assert_eq!(sidak_combine(&[-0.5, 0.5]), 0.0);
    }

    #[test]
    fn holm_textbook_example() {
        // m = 4, α = 0.05; sorted 0.005 (thr 0.0125, reject), 0.01 (thr 0.05/3, reject),
        // 0.03 (thr 0.025, keep: stop), 0.04 (thr 0.05, kept although 0.04 <= 0.05).
        let r = holm(&[0.01, 0.04, 0.03, 0.005], 0.05);
        let want = [
            (true, 0.05 / 3.0),
            (false, 0.05),
            (false, 0.025),
            (true, 0.0125),
        ];
        for (got, want) in r.iter().zip(want) {
            assert_eq!(got.0, want.0);
            assert!(rel(got.1, want.1) < 1e-15);
        }
    }

    #[test]
    fn holm_rejects_nothing_under_the_null_and_all_when_strong() {
        let r = holm(&[0.2, 0.5, 0.9, 0.04], 0.05);
        assert!(
            r.iter().all(|&(rej, _)| !rej),
            "0.04 > 0.05/4 must not be rejected"
        );
        let r = holm(&[1e-6, 1e-5, 1e-4], 0.05);
        assert!(r.iter().all(|&(rej, _)| rej));
    }

    #[test]
    fn holm_ties_and_degenerate_inputs() {
        // Ties: both 0.02 get distinct thresholds 0.025 then 0.05, both rejected.
        let r = holm(&[0.02, 0.02], 0.05);
        assert_eq!(r, vec![(true, 0.025), (true, 0.05)]);
        assert!(holm(&[], 0.05).is_empty());
        assert!(holm(&[f64::NAN, 0.9], 0.05)[0].0, "NaN counts as failure");
        assert!(holm(&[0.0, 0.0], f64::NAN).iter().all(|&(rej, _)| !rej));
        assert!(holm(&[0.0, 0.0], 0.0).iter().all(|&(rej, _)| !rej));
    }

    #[test]
    fn bh_textbook() {
        // Benjamini & Hochberg 1995, §4 example with 15 p-values: 4 rejected at q = 0.05.
        let p = [
            0.0001, 0.0004, 0.0019, 0.0095, 0.0201, 0.0278, 0.0298, 0.0344, 0.0459, 0.3240, 0.4262,
            0.5719, 0.6528, 0.7590, 1.0,
        ];
        assert_eq!(super::benjamini_hochberg(&p, 0.05), 4);
        assert_eq!(super::benjamini_hochberg(&[], 0.05), 0);
    }
}
