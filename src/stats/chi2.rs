//! Pearson's chi-square goodness-of-fit test of binned counts against expected counts, with
//! pooling of sparsely populated bins: χ² = Σ (O_i − E_i)²/E_i, approximately chi-square with
//! (bins − 1) degrees of freedom once bins with expected count below a threshold
//! (conventionally 5, Cochran 1954, Biometrics 10) are pooled. Expected counts are used exactly
//! as given, not rescaled: docs/statistics.md, "`stats::chi2`".

use statrs::distribution::{ChiSquared, ContinuousCDF};
use thiserror::Error;

/// Outcome of [`chi2_gof`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Chi2Result {
    /// Pearson statistic Σ (O − E)² / E over the bins kept after pooling (dimensionless).
    /// `+∞` when `zero_pdf_hits > 0`.
    pub chi2: f64,
    /// Degrees of freedom: kept bins − 1 (0 only in the zero-pdf-hit case with < 2 bins).
    pub dof: u64,
    /// Upper-tail probability P(ChiSquared(dof) ≥ chi2), in [0, 1]; exactly 0 when
    /// `zero_pdf_hits > 0`.
    pub p_value: f64,
    /// Number of input bins (with positive expected count) that were merged into another
    /// bin because their own expected count was below `min_expected`.
    pub pooled_bins: usize,
    /// Total observed count over all bins (samples), saturating at `u64::MAX`.
    pub total: u64,
    /// Observed count (samples) that fell in bins whose expected count is exactly 0.
    pub zero_pdf_hits: u64,
}

/// Why [`chi2_gof`] could not run.
#[derive(Debug, Clone, Copy, PartialEq, Error)]
pub enum Chi2Error {
    /// `observed` and `expected` have different lengths.
    #[error("observed has {observed} bins but expected has {expected}")]
    LengthMismatch {
        /// Length of `observed`.
        observed: usize,
        /// Length of `expected`.
        expected: usize,
    },
    /// An expected count is negative, NaN or infinite.
    #[error("expected count {value} in bin {index} is not a finite non-negative number")]
    InvalidExpected {
        /// Bin index.
        index: usize,
        /// Offending value.
        value: f64,
    },
    /// `min_expected` is negative, NaN or infinite.
    #[error("min_expected {0} is not a finite non-negative number")]
    InvalidMinExpected(f64),
    /// Fewer than two bins remain after dropping zero-expected bins and pooling.
    #[error("only {kept} bin(s) left after pooling; a chi-square test needs at least 2")]
    TooFewBins {
        /// Bins left after pooling.
        kept: usize,
    },
}

/// Pearson chi-square goodness of fit of `observed` counts (samples per bin) against
/// `expected` counts (samples per bin, already scaled by the caller; not renormalised).
///
/// Bins with expected count exactly 0 take no part in the statistic; any sample observed in
/// one of them is counted in `zero_pdf_hits` and makes the result a certain failure
/// (`p_value = 0`, `chi2 = +∞`), whatever the other bins say. Remaining bins with expected
/// count below `min_expected` (typically 5) are sorted by expected count, ascending, and
/// merged consecutively until each merged group reaches `min_expected`; a final remainder
/// still below it joins the kept bin with the smallest expected count.
///
/// Errors: length mismatch, an expected count that is negative or not finite, an invalid
/// `min_expected`, or fewer than two bins after pooling (unless there were zero-pdf hits,
/// which are reported as a failed test instead).
pub fn chi2_gof(
    observed: &[u64],
    expected: &[f64],
    min_expected: f64,
) -> Result<Chi2Result, Chi2Error> {
    if observed.len() != expected.len() {
        return Err(Chi2Error::LengthMismatch {
            observed: observed.len(),
            expected: expected.len(),
        });
    }
    if !(min_expected.is_finite() && min_expected >= 0.0) {
        return Err(Chi2Error::InvalidMinExpected(min_expected));
    }
    if let Some((index, &value)) = expected
        .iter()
        .enumerate()
        .find(|(_, e)| !(e.is_finite() && **e >= 0.0))
    {
        return Err(Chi2Error::InvalidExpected { index, value });
    }

    let total = observed.iter().fold(0u64, |acc, &o| acc.saturating_add(o));
    let zero_pdf_hits = observed
        .iter()
        .zip(expected)
        .filter(|(_, &e)| e == 0.0)
        .fold(0u64, |acc, (&o, _)| acc.saturating_add(o));

    // Bins with positive expected count, as (observed, expected), split at the threshold.
    let mut small: Vec<(f64, f64)> = Vec::new();
    let mut kept: Vec<(f64, f64)> = Vec::new();
    for (&o, &e) in observed.iter().zip(expected) {
        if e == 0.0 {
            continue;
        }
        if e < min_expected {
            small.push((o as f64, e));
        } else {
            kept.push((o as f64, e));
        }
    }
    let pooled_bins = small.len();

    // Pooling of sparse bins (Cochran 1954, Biometrics 10; Press et al., Numerical Recipes
    // 3rd ed. §14.3): ascending expected count, merge until each group reaches the threshold.
    small.sort_by(|a, b| a.1.total_cmp(&b.1));
    let mut group = (0.0, 0.0);
    for (o, e) in small {
        group.0 += o;
        group.1 += e;
        if group.1 >= min_expected {
            kept.push(group);
            group = (0.0, 0.0);
        }
    }
    if group.1 > 0.0 {
        // The remainder is too small on its own: it joins the smallest kept bin.
        match kept.iter_mut().min_by(|a, b| a.1.total_cmp(&b.1)) {
            Some(smallest) => {
                smallest.0 += group.0;
                smallest.1 += group.1;
            }
            None => kept.push(group),
        }
    }

    if zero_pdf_hits > 0 {
        return Ok(Chi2Result {
            chi2: f64::INFINITY,
            dof: (kept.len() as u64).saturating_sub(1),
            p_value: 0.0,
            pooled_bins,
            total,
            zero_pdf_hits,
        });
    }
    if kept.len() < 2 {
        return Err(Chi2Error::TooFewBins { kept: kept.len() });
    }

    // Pearson 1900, Phil. Mag. (5) 50; Numerical Recipes 3rd ed. eq. 14.3.1: Σ (O − E)² / E.
    let chi2: f64 = kept.iter().map(|&(o, e)| (o - e) * (o - e) / e).sum();
    let dof = kept.len() as u64 - 1;
    let p_value = chi2_sf(chi2, dof as f64);
    Ok(Chi2Result {
        chi2,
        dof,
        p_value,
        pooled_bins,
        total,
        zero_pdf_hits,
    })
}

/// Upper tail of ChiSquared(dof) at `x`, with the infinite/NaN cases pinned to 0.
pub fn chi2_sf(x: f64, dof: f64) -> f64 {
    if !x.is_finite() {
        return 0.0;
    }
    match ChiSquared::new(dof) {
        Ok(d) => d.sf(x).clamp(0.0, 1.0),
        Err(_) => 0.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mendel_peas_textbook_value() {
        // Mendel's dihybrid cross, 9:3:3:1 of 556 peas: χ² = 0.470, dof 3, p = 0.925
        // (e.g. Sokal & Rohlf, Biometry; every genetics text).
        let obs = [315, 108, 101, 32];
        let exp: Vec<f64> = [9.0, 3.0, 3.0, 1.0]
            .iter()
            .map(|r| r / 16.0 * 556.0)
            .collect();
        let r = chi2_gof(&obs, &exp, 5.0).unwrap();
        assert!((r.chi2 - 0.470_024).abs() < 1e-5, "{}", r.chi2);
        assert_eq!(r.dof, 3);
        assert!((r.p_value - 0.925_4).abs() < 1e-3, "{}", r.p_value);
        assert_eq!(r.total, 556);
        assert_eq!(r.pooled_bins, 0);
        assert_eq!(r.zero_pdf_hits, 0);
    }

    #[test]
    fn critical_values_give_five_percent() {
        // Table values: χ²_{0.95}(1) = 3.8415, χ²_{0.95}(3) = 7.8147, χ²_{0.95}(10) = 18.307.
        assert!((chi2_sf(3.8415, 1.0) - 0.05).abs() < 1e-4);
        assert!((chi2_sf(7.8147, 3.0) - 0.05).abs() < 1e-4);
        assert!((chi2_sf(18.307, 10.0) - 0.05).abs() < 1e-4);
        assert_eq!(chi2_sf(f64::INFINITY, 3.0), 0.0);
    }

    #[test]
    fn pooling_merges_small_bins() {
        // Small bins 1, 2, 3 pool into one bin of 6 (>= 5); kept: 6, 10, 20, 14.
        let exp = [1.0, 10.0, 2.0, 20.0, 3.0, 14.0];
        let obs = [2, 9, 1, 22, 4, 12];
        let r = chi2_gof(&obs, &exp, 5.0).unwrap();
        assert_eq!(r.pooled_bins, 3);
        assert_eq!(r.dof, 3);
        let want = (7.0f64 - 6.0).powi(2) / 6.0
            + (9.0f64 - 10.0).powi(2) / 10.0
            + (22.0f64 - 20.0).powi(2) / 20.0
            + (12.0f64 - 14.0).powi(2) / 14.0;
        assert!((r.chi2 - want).abs() < 1e-12);
    }

    #[test]
    fn pooling_remainder_joins_smallest_kept_bin() {
        // Small 1 + 2 = 3 < 5: joins the smallest kept bin (10) -> bins 13 and 20.
        let exp = [1.0, 2.0, 20.0, 10.0];
        let obs = [0, 5, 18, 10];
        let r = chi2_gof(&obs, &exp, 5.0).unwrap();
        assert_eq!(r.dof, 1);
        assert_eq!(r.pooled_bins, 2);
        let want = (15.0f64 - 13.0).powi(2) / 13.0 + (18.0f64 - 20.0).powi(2) / 20.0;
        assert!((r.chi2 - want).abs() < 1e-12);
    }

    #[test]
    fn zero_expected_bins_without_hits_are_ignored() {
        let r1 = chi2_gof(&[315, 108, 101, 32], &[312.75, 104.25, 104.25, 34.75], 5.0).unwrap();
        let r2 = chi2_gof(
            &[0, 315, 108, 0, 101, 32],
            &[0.0, 312.75, 104.25, 0.0, 104.25, 34.75],
            5.0,
        )
        .unwrap();
        assert_eq!(r1, r2);
    }

    #[test]
    fn rejects_sample_where_pdf_is_zero() {
        // A single sample in a zero-pdf bin fails the test, even if the rest fit perfectly.
        let r = chi2_gof(&[100, 100, 1], &[100.0, 100.0, 0.0], 5.0).unwrap();
        assert_eq!(r.zero_pdf_hits, 1);
        assert_eq!(r.p_value, 0.0);
        assert_eq!(r.total, 201);
        // Even with too few bins to run the test otherwise.
        let r = chi2_gof(&[3, 100], &[0.0, 100.0], 5.0).unwrap();
        assert_eq!(r.zero_pdf_hits, 3);
        assert_eq!(r.p_value, 0.0);
    }

    #[test]
    fn rejects_unnormalised_pdf() {
        // 10 000 samples spread perfectly uniformly over 10 bins, but the pdf integrates to
        // 0.9: expected 900 per bin. Must not be renormalised away.
        let obs = [1000u64; 10];
        let good = chi2_gof(&obs, &[1000.0; 10], 5.0).unwrap();
        assert_eq!(good.chi2, 0.0);
        assert!((good.p_value - 1.0).abs() < 1e-12);
        let bad = chi2_gof(&obs, &[900.0; 10], 5.0).unwrap();
        assert!(bad.p_value < 1e-10, "{}", bad.p_value);
    }

    #[test]
    fn rejects_wrong_shape() {
        // Observed linear ramp against a flat expectation with the same total.
        let obs: Vec<u64> = (0..10).map(|i| 50 + 10 * i).collect();
        let n: u64 = obs.iter().sum();
        let exp = vec![n as f64 / 10.0; 10];
        let r = chi2_gof(&obs, &exp, 5.0).unwrap();
        assert!(r.p_value < 1e-6, "{}", r.p_value);
    }

    #[test]
    fn input_errors() {
        assert_eq!(
            chi2_gof(&[1, 2], &[1.0], 5.0),
            Err(Chi2Error::LengthMismatch {
                observed: 2,
                expected: 1
            })
        );
        assert!(matches!(
            chi2_gof(&[1, 2], &[1.0, -1.0], 5.0),
            Err(Chi2Error::InvalidExpected { index: 1, .. })
        ));
        assert!(matches!(
            chi2_gof(&[1, 2], &[f64::NAN, 1.0], 5.0),
            Err(Chi2Error::InvalidExpected { index: 0, .. })
        ));
        assert!(matches!(
            chi2_gof(&[1, 2], &[f64::INFINITY, 1.0], 5.0),
            Err(Chi2Error::InvalidExpected { index: 0, .. })
        ));
        assert!(matches!(
            chi2_gof(&[1, 2], &[1.0, 1.0], f64::NAN),
            Err(Chi2Error::InvalidMinExpected(_))
        ));
        // Everything pools into a single bin.
        assert_eq!(
            chi2_gof(&[1, 2, 1], &[1.0, 1.0, 1.0], 5.0),
            Err(Chi2Error::TooFewBins { kept: 1 })
        );
        assert_eq!(
            chi2_gof(&[], &[], 5.0),
            Err(Chi2Error::TooFewBins { kept: 0 })
        );
        assert_eq!(
            chi2_gof(&[0, 0], &[0.0, 0.0], 5.0),
            Err(Chi2Error::TooFewBins { kept: 0 })
        );
    }

    #[test]
    fn huge_counts_do_not_overflow() {
        let r = chi2_gof(&[u64::MAX, u64::MAX], &[1.0, 1.0], 0.0).unwrap();
        assert_eq!(r.total, u64::MAX);
        assert_eq!(r.p_value, 0.0);
    }
}
