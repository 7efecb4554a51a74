//! Statistics in f64: running mean and variance, and the two-sided z test the checks use.
//! `statrs` lives only here.

pub mod chi2;
pub mod multiple;
pub mod power;
pub mod regression;
pub mod sphere;
pub mod stability;

use statrs::distribution::{ContinuousCDF, Normal, StudentsT};

/// Running mean and variance of a stream of f64 values (Welford 1962, "Note on a method
/// for calculating corrected sums of squares and products", Technometrics 4(3)).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct MeanVar {
    n: u64,
    mean: f64,
    m2: f64,
}

impl MeanVar {
    /// Adds one observation.
    pub fn push(&mut self, x: f64) {
        self.n += 1;
        let d = x - self.mean;
        self.mean += d / self.n as f64;
        self.m2 += d * (x - self.mean);
    }

    /// The statistics of `n` observations given their sum and sum of squares (f64 sums of
    /// the raw values); m2 = Σx² − (Σx)²/n, clamped at 0 against rounding. Use it for
    /// sparse streams (mostly zeros), where pushing every zero would cost more than the data.
    pub fn from_sums(n: u64, sum: f64, sum_sq: f64) -> Self {
        if n == 0 {
            return MeanVar::default();
        }
        let mean = sum / n as f64;
        MeanVar {
            n,
            mean,
            m2: (sum_sq - sum * mean).max(0.0),
        }
    }

    /// Adds the observations summarised by `other` (Chan, Golub & LeVeque 1979, "Updating
    /// formulae and a pairwise algorithm for computing sample variances", eq. 2.1b: the
    /// pairwise combination of two (n, mean, m2) summaries).
    pub fn merge(&mut self, other: &MeanVar) {
        if other.n == 0 {
            return;
        }
        if self.n == 0 {
            *self = *other;
            return;
        }
        let n = self.n + other.n;
        let d = other.mean - self.mean;
        let (na, nb) = (self.n as f64, other.n as f64);
        self.mean += d * nb / n as f64;
        self.m2 += other.m2 + d * d * na * nb / n as f64;
        self.n = n;
    }

    /// Number of observations.
    pub fn count(&self) -> u64 {
        self.n
    }

    /// Sample mean (0 when empty).
    pub fn mean(&self) -> f64 {
        self.mean
    }

    /// Unbiased sample variance (0 with fewer than two observations).
    pub fn variance(&self) -> f64 {
        if self.n < 2 {
            0.0
        } else {
            self.m2 / (self.n - 1) as f64
        }
    }

    /// Standard error of the mean, sqrt(s²/n).
    pub fn std_error(&self) -> f64 {
        if self.n == 0 {
            0.0
        } else {
            (self.variance() / self.n as f64).sqrt()
        }
    }
}

/// Upper tail of the standard normal distribution, P(Z > x).
pub fn normal_sf(x: f64) -> f64 {
    Normal::standard().sf(x)
}

/// Outcome of a two-sided z test of `estimate` against `expected`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ZTest {
    /// (estimate - expected) / standard error.
    pub z: f64,
    /// Two-sided p-value, 2·(1 - Φ(|z|)).
    pub p: f64,
}

/// Two-sided z test; a zero standard error gives z = ±inf (p = 0) unless the estimate is exact.
pub fn z_test(estimate: f64, std_error: f64, expected: f64) -> ZTest {
    let diff = estimate - expected;
    let z = if std_error > 0.0 {
        diff / std_error
    } else if diff == 0.0 {
        0.0
    } else {
        f64::INFINITY.copysign(diff)
    };
    let normal = Normal::standard();
    let p = 2.0 * normal.sf(z.abs());
    ZTest { z, p }
}

/// Two-sided Welch test of a difference `diff` whose variance is the sum of independent
/// estimated variances `parts` = [(variance, degrees of freedom)] (`f64::INFINITY` for a known
/// variance): t = diff/√Σv with the Welch–Satterthwaite degrees of freedom
/// ν = (Σv)²/Σ(v²/ν) (Welch 1947, Biometrika 34, eq. 9; Satterthwaite 1946). Returns
/// (t, two-sided p, ν); ν above 1e6 uses the normal distribution.
pub fn welch_test(diff: f64, parts: &[(f64, f64)]) -> (f64, f64, f64) {
    let var: f64 = parts.iter().map(|p| p.0).sum();
    let denom: f64 = parts
        .iter()
        .filter(|p| p.0 > 0.0 && p.1.is_finite())
        .map(|p| p.0 * p.0 / p.1)
        .sum();
    let nu = if denom > 0.0 {
        var * var / denom
    } else {
        f64::INFINITY
    };
    let z = z_test(diff, var.sqrt(), 0.0);
    if !(nu.is_finite() && nu < 1e6 && z.z.is_finite()) {
        return (z.z, z.p, nu);
    }
    let t = StudentsT::new(0.0, 1.0, nu).expect("nu > 0");
    (z.z, (2.0 * t.sf(z.z.abs())).min(1.0), nu)
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

#[cfg(test)]
mod z_tolerance_tests {
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn welch_matches_tables_and_falls_back_to_z() {
        // t = 2.262 is the two-sided 5 % point of Student's t with 9 dof.
        let (t, p, nu) = welch_test(2.262, &[(1.0, 9.0)]);
        assert!((t - 2.262).abs() < 1e-12 && (p - 0.05).abs() < 2e-4 && (nu - 9.0).abs() < 1e-12);
        // Two equal parts with 15 dof each: ν = 30.
        let (_, _, nu) = welch_test(1.0, &[(0.5, 15.0), (0.5, 15.0)]);
        assert!((nu - 30.0).abs() < 1e-12);
        // Known variances: the z test.
        let (_, p, nu) = welch_test(1.96, &[(1.0, f64::INFINITY)]);
        assert!(nu.is_infinite() && (p - 0.05).abs() < 1e-3);
    }

    #[test]
    fn mean_var_matches_two_pass() {
        let xs = [1.0, 2.0, 4.0, 8.0, 16.0];
        let mut mv = MeanVar::default();
        xs.iter().for_each(|&x| mv.push(x));
        let mean = xs.iter().sum::<f64>() / 5.0;
        let var = xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / 4.0;
        assert!((mv.mean() - mean).abs() < 1e-14);
        assert!((mv.variance() - var).abs() < 1e-12);
    }

    #[test]
    fn mean_var_from_sums_and_merge_match_push() {
        let xs = [0.0, 3.0, 0.0, 0.0, 7.5, 1.0, 0.0, 2.0];
        let mut all = MeanVar::default();
        xs.iter().for_each(|&x| all.push(x));
        let part = |s: &[f64]| {
            MeanVar::from_sums(
                s.len() as u64,
                s.iter().sum(),
                s.iter().map(|x| x * x).sum(),
            )
        };
        let mut m = part(&xs[..3]);
        m.merge(&part(&xs[3..]));
        m.merge(&MeanVar::default());
        assert_eq!(m.count(), all.count());
        assert!((m.mean() - all.mean()).abs() < 1e-14);
        assert!((m.variance() - all.variance()).abs() < 1e-12);
    }

    #[test]
    fn z_test_known_values() {
        let t = z_test(1.96, 1.0, 0.0);
        assert!((t.p - 0.0499958).abs() < 1e-5);
        assert_eq!(z_test(1.0, 0.0, 1.0).p, 1.0);
        assert_eq!(z_test(1.1, 0.0, 1.0).p, 0.0);
    }
}
