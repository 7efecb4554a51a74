//! Statistical power of the two-sided z test: how large a bias a check can see.
//!
//! A test that passes says only that no bias larger than its detection limit is present.
//! For an estimate with standard error `se` tested at level α, a true bias δ gives
//! z ~ N(δ/se, 1); the test detects it with probability P(|z| > z_{1−α/2}). The smallest
//! bias detected with a chosen probability (the power) is the detection limit reported
//! next to each passed check.

use statrs::distribution::{ContinuousCDF, Normal};

/// Two-sided critical value z_{1−α/2} (dimensionless) for level `alpha` (probability).
///
/// Accurate for tiny α (computed from the lower tail). Degenerate inputs: NaN or
/// non-positive α gives +∞ (nothing is ever significant); α ≥ 1 gives 0.
pub fn z_critical(alpha: f64) -> f64 {
    if alpha.is_nan() || alpha <= 0.0 {
        return f64::INFINITY;
    }
    if alpha >= 1.0 {
        return 0.0;
    }
    // Definition of the two-sided critical value: z = −Φ⁻¹(α/2) = Φ⁻¹(1 − α/2).
    -Normal::standard().inverse_cdf(alpha / 2.0)
}

/// One-sided normal quantile Φ⁻¹(p), taken from the nearer tail for accuracy. `p` in (0, 1).
fn normal_quantile(p: f64) -> f64 {
    let n = Normal::standard();
    if p > 0.5 {
        -n.inverse_cdf(1.0 - p)
    } else {
        n.inverse_cdf(p)
    }
}

/// Smallest |bias| (same units as `se`, the standard error of the estimate) detected
/// with probability `power` by a two-sided z test at level `alpha`:
/// (z_{1−α/2} + z_{power})·se. Normal approximation that ignores the far rejection
/// tail, so the true power at this bias is slightly above `power`.
///
/// Degenerate inputs: NaN or negative `se`, or NaN `power`, give NaN; `se = 0` gives 0
/// (any bias is then detected); `power <= 0` gives 0; `power >= 1` gives +∞ (for se > 0);
/// an invalid `alpha` behaves as in [`z_critical`]. Never negative.
pub fn min_detectable_bias(se: f64, alpha: f64, power: f64) -> f64 {
    if se.is_nan() || se < 0.0 || power.is_nan() {
        return f64::NAN;
    }
    if se == 0.0 || power <= 0.0 {
        return 0.0;
    }
    if power >= 1.0 {
        return f64::INFINITY;
    }
    // Cohen 1988, Statistical Power Analysis, ch. 12 (normal approximation):
    // δ = (z_{1−α/2} + z_{power})·se.
    let k = z_critical(alpha) + normal_quantile(power);
    (k * se).max(0.0)
}

/// Probability (in [0, 1]) that a two-sided z test at level `alpha` rejects when the true
/// bias is `bias` and the standard error is `se` (same units). Exact under normality.
///
/// Degenerate inputs: any NaN gives NaN; `se = 0` gives 1 for a nonzero bias and α for
/// a zero one (clamped into [0, 1]); negative `se` gives NaN.
pub fn detection_power(bias: f64, se: f64, alpha: f64) -> f64 {
    if bias.is_nan() || se.is_nan() || alpha.is_nan() || se < 0.0 {
        return f64::NAN;
    }
    if se == 0.0 {
        return if bias == 0.0 {
            alpha.clamp(0.0, 1.0)
        } else {
            1.0
        };
    }
    let z = z_critical(alpha);
    let d = (bias / se).abs();
    let n = Normal::standard();
    // z ~ N(δ, 1): P(|z| > c) = Φ(δ − c) + Φ(−δ − c) (e.g. Cohen 1988, ch. 12).
    (n.sf(z - d) + n.cdf(-z - d)).clamp(0.0, 1.0)
}

/// Smallest effect size w (Cohen 1988, Statistical Power Analysis, ch. 7: w² = Σ (p₁ − p₀)²/p₀
/// over the bins, the squared RMS relative error of the binned density under p₀;
/// dimensionless) that a chi-square goodness-of-fit test with `dof` degrees of freedom over
/// `samples` draws, at level `alpha`, detects with probability `power`. Approximations: the
/// critical value by Wilson & Hilferty 1931 (χ²/k ≈ normal in its cube root), the
/// noncentral χ²(k, λ = N w²) by a normal of mean k + λ and variance 2(k + 2λ) (Cohen 1988,
/// ch. 7); both are close for the hundreds of dof of the sphere histograms.
///
/// Degenerate inputs: `dof` or `samples` 0, or NaN anywhere, give NaN; `power` outside (0, 1)
/// behaves as in [`min_detectable_bias`] (0 or +∞).
pub fn chi_square_min_detectable_w(dof: f64, samples: u64, alpha: f64, power: f64) -> f64 {
    if dof.is_nan() || dof <= 0.0 || samples == 0 || alpha.is_nan() || power.is_nan() {
        return f64::NAN;
    }
    if power <= 0.0 {
        return 0.0;
    }
    if power >= 1.0 {
        return f64::INFINITY;
    }
    let k = dof;
    // upper-α critical value of χ²(k) (Wilson & Hilferty 1931):
    // c = k (1 − 2/(9k) + z_{1−α} √(2/(9k)))³, z one-sided
    let z_alpha = z_critical(2.0 * alpha.min(0.5));
    let c = k * (1.0 - 2.0 / (9.0 * k) + z_alpha * (2.0 / (9.0 * k)).sqrt()).powi(3);
    // P(X > c) = power for X ≈ N(k + λ, 2(k + 2λ)): with s = √(2k + 4λ),
    // s²/4 − z_p s + k/2 − c = 0, so s = 2 (z_p + √(z_p² + c − k/2)) and λ = (s² − 2k)/4
    let z_p = normal_quantile(power);
    let disc = (z_p * z_p + c - k / 2.0).max(0.0);
    let s = 2.0 * (z_p + disc.sqrt());
    let lambda = ((s * s - 2.0 * k) / 4.0).max(0.0);
    (lambda / samples as f64).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn z_critical_table_values() {
        assert!((z_critical(0.05) - 1.959_964).abs() < 1e-6);
        assert!((z_critical(0.01) - 2.575_829).abs() < 1e-6);
        assert!((z_critical(1e-3) - 3.290_527).abs() < 1e-6);
        // Deep tail: z_{1 − 5e-13} = 7.130507 for α = 1e-12 (bisection on erfc).
        assert!(
            (z_critical(1e-12) - 7.130_507).abs() < 1e-5,
            "{}",
            z_critical(1e-12)
        );
        assert_eq!(z_critical(1.0), 0.0);
    }

    /// The chi-square detection limit against a simulation of the noncentral χ²(k, λ) as
    /// Σ (Zᵢ + μᵢ)² (independent of both approximations) with the exact central critical value:
    /// at λ = N w² the test rejects with about the stated 95 %.
    #[test]
    fn chi_square_min_detectable_w_has_its_power() {
        use statrs::distribution::ChiSquared;
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut uniform = || {
            // xorshift64*, for this test alone
            state ^= state >> 12;
            state ^= state << 25;
            state ^= state >> 27;
            ((state.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        };
        for (k, alpha) in [(200usize, 1e-3), (1000, 1e-6)] {
            let n = 200_000u64;
            let w = chi_square_min_detectable_w(k as f64, n, alpha, 0.95);
            let lambda = n as f64 * w * w;
            let c = ChiSquared::new(k as f64).unwrap().inverse_cdf(1.0 - alpha);
            let mu = (lambda / k as f64).sqrt();
            let trials = 4000;
            let mut rejected = 0;
            for _ in 0..trials {
                let mut x = 0.0;
                for _ in 0..k / 2 {
                    // Box–Muller: two normals
                    let (u1, u2) = (uniform(), uniform());
                    let r = (-2.0 * u1.ln()).sqrt();
                    let (z1, z2) = (r * (2.0 * PI_F * u2).cos(), r * (2.0 * PI_F * u2).sin());
                    x += (z1 + mu).powi(2) + (z2 + mu).powi(2);
                }
                rejected += usize::from(x > c);
            }
            let rate = rejected as f64 / trials as f64;
            // 4000 trials: standard error 0.0034 at 0.95; the normal approximation errs on
            // the safe side (the stated w is detected a little more often: 0.961 at k = 200, 0.958
            // at k = 1000)
            assert!(
                (0.94..0.975).contains(&rate),
                "k {k}, α {alpha}: power {rate}"
            );
        }
        assert!(chi_square_min_detectable_w(0.0, 10, 1e-3, 0.95).is_nan());
        assert_eq!(chi_square_min_detectable_w(10.0, 10, 1e-3, 0.0), 0.0);
    }

    const PI_F: f64 = std::f64::consts::PI;

    #[test]
    fn z_critical_degenerate_inputs() {
        assert_eq!(z_critical(0.0), f64::INFINITY);
        assert_eq!(z_critical(-1.0), f64::INFINITY);
        assert_eq!(z_critical(f64::NAN), f64::INFINITY);
        assert_eq!(z_critical(3.0), 0.0);
    }

    #[test]
    fn min_detectable_bias_textbook() {
        // α = 0.05, power 0.95: (1.959964 + 1.644854)·se = 3.604818·se.
        let d = min_detectable_bias(2.0, 0.05, 0.95);
        assert!((d - 2.0 * 3.604_818).abs() < 1e-5, "{d}");
        // α = 0.05, power 0.80: 1.959964 + 0.841621 = 2.801585 (Cohen's classic 2.8).
        assert!((min_detectable_bias(1.0, 0.05, 0.8) - 2.801_585).abs() < 1e-5);
        // power 0.5: the detection limit is exactly the critical value.
        assert!((min_detectable_bias(1.0, 0.05, 0.5) - 1.959_964).abs() < 1e-5);
    }

    #[test]
    fn detection_limit_has_at_least_the_requested_power() {
        for &(alpha, power) in &[(0.05, 0.95), (1e-3, 0.9), (1e-6, 0.99), (0.2, 0.6)] {
            let d = min_detectable_bias(0.7, alpha, power);
            let p = detection_power(d, 0.7, alpha);
            assert!(p >= power - 1e-9 && p < power + 1e-2, "{alpha} {power} {p}");
            // Negative control: half the bias is clearly below the requested power.
            assert!(detection_power(d / 2.0, 0.7, alpha) < power - 0.1);
        }
        // With no bias the test rejects at its level.
        assert!((detection_power(0.0, 1.0, 0.05) - 0.05).abs() < 1e-9);
    }

    #[test]
    fn power_degenerate_inputs() {
        assert!(min_detectable_bias(f64::NAN, 0.05, 0.9).is_nan());
        assert!(min_detectable_bias(-1.0, 0.05, 0.9).is_nan());
        assert!(min_detectable_bias(1.0, 0.05, f64::NAN).is_nan());
        assert_eq!(min_detectable_bias(0.0, 0.05, 0.9), 0.0);
        assert_eq!(min_detectable_bias(1.0, 0.05, 0.0), 0.0);
        assert_eq!(min_detectable_bias(1.0, 0.05, 1.0), f64::INFINITY);
        assert_eq!(min_detectable_bias(1.0, 0.0, 0.9), f64::INFINITY);
        assert_eq!(min_detectable_bias(1.0, 0.9, 0.01), 0.0, "clamped at 0");
        assert_eq!(detection_power(1.0, 0.0, 0.05), 1.0);
        assert_eq!(detection_power(0.0, 0.0, 0.05), 0.05);
        assert!(detection_power(1.0, -1.0, 0.05).is_nan());
        assert_eq!(detection_power(1.0, 1.0, 0.0), 0.0);
    }
}
