//! Statistics in f64: running mean and variance, and the two-sided z test the checks use.
//! `statrs` lives only here.

pub mod chi2;
pub mod multiple;
pub mod power;
pub mod regression;
pub mod sequential;
pub mod sphere;
pub mod stability;

use statrs::distribution::{ContinuousCDF, Normal, StudentsT};

/// Running mean and variance of a stream of f64 values (Welford 1962, "Note on a method
/// for calculating corrected sums of squares and products", Technometrics 4(3)), with the
/// third and fourth central sums (Pébay 2008, Sandia report SAND2008-6212, eq. 2.7 for one
/// value, eq. 2.1/2.4 for two summaries) so that the variance estimate carries its own
/// uncertainty ([`MeanVar::mean_variance_dof`]).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct MeanVar {
    n: u64,
    mean: f64,
    m2: f64,
    m3: f64,
    m4: f64,
}

impl MeanVar {
    /// Adds one observation.
    pub fn push(&mut self, x: f64) {
        self.n += 1;
        push_moments(
            self.n as f64,
            x,
            &mut self.mean,
            &mut self.m2,
            &mut self.m3,
            &mut self.m4,
        );
    }

    /// The statistics of `n` observations given their power sums [Σx, Σx², Σx³, Σx⁴] (f64 sums
    /// of the raw values), for sparse streams (mostly zeros) where pushing every zero would
    /// cost more than the data. Central sums from raw ones by binomial expansion, clamped at
    /// their bounds against rounding (m2 ≥ 0, m4 ≥ m2²/n); NaN in the last two sums marks the
    /// fourth moment unknown.
    pub fn from_power_sums(n: u64, sums: [f64; 4]) -> Self {
        if n == 0 {
            return MeanVar::default();
        }
        let [s1, s2, s3, s4] = sums;
        let nf = n as f64;
        let mean = s1 / nf;
        let m2 = (s2 - s1 * mean).max(0.0);
        let m3 = s3 - 3.0 * mean * s2 + 2.0 * mean * mean * s1;
        let m4 = s4 - 4.0 * mean * s3 + 6.0 * mean * mean * s2 - 3.0 * mean * mean * mean * s1;
        MeanVar {
            n,
            mean,
            m2,
            m3,
            // NaN stays NaN (f64::max would drop it): the fourth moment is unknown.
            m4: if m4.is_nan() {
                m4
            } else {
                m4.max(m2 * m2 / nf)
            },
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
        let nf = n as f64;
        // Pébay 2008 eq. 2.4 (m4) and 2.1 (m3), with the old m2 and m3 of both parts.
        self.m4 += other.m4
            + d.powi(4) * na * nb * (na * na - na * nb + nb * nb) / nf.powi(3)
            + 6.0 * d * d * (na * na * other.m2 + nb * nb * self.m2) / (nf * nf)
            + 4.0 * d * (na * other.m3 - nb * self.m3) / nf;
        self.m3 += other.m3
            + d.powi(3) * na * nb * (na - nb) / (nf * nf)
            + 3.0 * d * (na * other.m2 - nb * self.m2) / nf;
        self.mean += d * nb / n as f64;
        self.m2 += other.m2 + d * d * na * nb / n as f64;
        self.n = n;
    }

    /// The mean and the second to fourth central sums [mean, m2, m3, m4] (for storing a
    /// summary exactly; [`MeanVar::from_moments`] restores it).
    pub fn moments(&self) -> [f64; 4] {
        [self.mean, self.m2, self.m3, self.m4]
    }

    /// The summary of `n` observations with [mean, m2, m3, m4] as [`MeanVar::moments`] gives
    /// them (stored values, not checked).
    pub fn from_moments(n: u64, moments: [f64; 4]) -> Self {
        let [mean, m2, m3, m4] = moments;
        MeanVar {
            n,
            mean,
            m2,
            m3,
            m4,
        }
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

    /// Variance of the mean, s²/n (0 when empty).
    pub fn mean_variance(&self) -> f64 {
        if self.n == 0 {
            0.0
        } else {
            self.variance() / self.n as f64
        }
    }

    /// Estimated variance of [`MeanVar::mean_variance`] itself, Var(s²)/n² with
    /// Var(s²) = μ₄/n − σ⁴(n − 3)/(n(n − 1)) (Cramér 1946, Mathematical Methods of
    /// Statistics, eq. 27.4.2), μ₄ = m4/n and σ² = s², never below the normal-theory value
    /// 2σ⁴/(n − 1) (so the degrees of freedom never exceed n − 1), which is also the value
    /// for n = 2 and 3; NaN when the fourth moment is unknown (NaN) or n < 2; +∞ when it
    /// overflowed (the degrees of freedom then go to their floor, [`satterthwaite_dof`]).
    pub fn mean_variance_variance(&self) -> f64 {
        if self.n < 2 || self.m4.is_nan() {
            return f64::NAN;
        }
        let n = self.n as f64;
        let s2 = self.variance();
        if self.n < 4 {
            return 2.0 * s2 * s2 / (n - 1.0) / (n * n);
        }
        let var_s2 = self.m4 / (n * n) - s2 * s2 * (n - 3.0) / (n * (n - 1.0));
        var_s2.max(2.0 * s2 * s2 / (n - 1.0)) / (n * n)
    }

    /// Effective degrees of freedom of the variance estimate s²/n (Satterthwaite 1946,
    /// Biometrics Bulletin 2(6), eq. 3: ν = 2·E\[V\]²/Var(V)): n − 1 for normal data, far fewer
    /// when a few large values make up the variance (heavy tails, rare bright paths), which
    /// is when a z test on s²/n would be anti-conservative. INFINITY when unknown.
    pub fn mean_variance_dof(&self) -> f64 {
        satterthwaite_dof(self.mean_variance(), self.mean_variance_variance())
    }
}

/// [`MeanVar::push`]'s update of the mean and the second to fourth central sums by the `n`-th
/// observation `x` (`n` counting it), for summaries that keep their count elsewhere (a film
/// pixel's channels share one).
#[inline(always)]
pub fn push_moments(n: f64, x: f64, mean: &mut f64, m2: &mut f64, m3: &mut f64, m4: &mut f64) {
    let d = x - *mean;
    let dn = d / n;
    // Pébay 2008 eq. 2.7, with the old m2 and m3 (the mean and m2 updates are Welford's).
    let t = d * dn * (n - 1.0);
    *m4 += t * dn * dn * (n * n - 3.0 * n + 3.0) + 6.0 * dn * dn * *m2 - 4.0 * dn * *m3;
    *m3 += t * dn * (n - 2.0) - 3.0 * dn * *m2;
    *mean += dn;
    *m2 += d * (x - *mean);
}

/// ν = 2·V²/W for an estimated variance V whose own estimated variance is W (Satterthwaite
/// 1946, eq. 3), for sums of independent parts V = ΣVᵢ, W = ΣWᵢ; INFINITY when W is 0 or
/// unknown (NaN), so that the z test applies; 1, the most cautious value, when W overflowed.
pub fn satterthwaite_dof(v: f64, w: f64) -> f64 {
    if v.is_nan() || v <= 0.0 || w.is_nan() || w <= 0.0 {
        f64::INFINITY
    } else if w.is_infinite() {
        1.0
    } else {
        (2.0 * v * v / w).max(1.0)
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
    let nu = welch_dof(parts);
    let z = z_test(diff, var.sqrt(), 0.0);
    if !(nu.is_finite() && nu < 1e6 && z.z.is_finite()) {
        return (z.z, z.p, nu);
    }
    let t = StudentsT::new(0.0, 1.0, nu).expect("nu > 0");
    (z.z, (2.0 * t.sf(z.z.abs())).min(1.0), nu)
}

/// The Welch–Satterthwaite degrees of freedom ν = (Σv)²/Σ(v²/ν) of a sum of independent
/// estimated variances `parts` = [(variance, degrees of freedom)] (Welch 1947, Biometrika 34,
/// eq. 9); parts with a known variance (ν = ∞) or none add nothing; ∞ when no part is estimated.
pub fn welch_dof(parts: &[(f64, f64)]) -> f64 {
    let var: f64 = parts.iter().map(|p| p.0).sum();
    let denom: f64 = parts
        .iter()
        .filter(|p| p.0 > 0.0 && p.1.is_finite())
        .map(|p| p.0 * p.0 / p.1)
        .sum();
    if denom > 0.0 {
        var * var / denom
    } else {
        f64::INFINITY
    }
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

/// [`z_with_tolerance`] with a standard error estimated on `dof` effective degrees of freedom:
/// the same allowance, Student's t in place of the normal (ν ≥ 1e6 or ∞: the normal).
/// Returns (t, p).
pub fn t_with_tolerance(
    estimate: f64,
    se: f64,
    expected: f64,
    rel_tolerance: f64,
    dof: f64,
) -> (f64, f64) {
    let (z, p) = z_with_tolerance(estimate, se, expected, rel_tolerance);
    if !(dof.is_finite() && dof < 1e6) || p.is_nan() || se <= 0.0 {
        return (z, p);
    }
    let Ok(t) = StudentsT::new(0.0, 1.0, dof.max(1e-3)) else {
        return (f64::NAN, f64::NAN);
    };
    let allowance = rel_tolerance * expected.abs() + ROUNDING * expected.abs().max(estimate.abs());
    let d = (estimate - expected).abs();
    // as in z_with_tolerance: P(|D| ≥ d) at the boundary bias = allowance, Student's t for D/se
    let p = t.sf((d - allowance) / se) + t.sf((d + allowance) / se);
    (z, p.min(1.0))
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

    #[test]
    fn t_with_tolerance_widens_for_few_dof_and_is_z_for_many() {
        use super::t_with_tolerance;
        // 2.262 is the two-sided 5 % point of t with 9 dof, 1.96 of the normal.
        let (_, p9) = t_with_tolerance(2.262, 1.0, 0.0, 0.0, 9.0);
        assert!((p9 - 0.05).abs() < 2e-4, "{p9}");
        let (_, pz) = t_with_tolerance(1.96, 1.0, 0.0, 0.0, f64::INFINITY);
        assert!((pz - 0.05).abs() < 1e-3, "{pz}");
        assert_eq!(
            t_with_tolerance(3.0, 1.0, 1.0, 0.1, 2e6),
            z_with_tolerance(3.0, 1.0, 1.0, 0.1)
        );
        // the tolerance is subtracted as in the z test: inside it p = 1 up to the tail
        let (_, p) = t_with_tolerance(1.05, 0.01, 1.0, 0.1, 5.0);
        assert!(p > 0.99);
        let (t, p) = t_with_tolerance(f64::NAN, 1.0, 1.0, 0.0, 5.0);
        assert!(t.is_nan() && p.is_nan());
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

    fn two_pass_central(xs: &[f64]) -> (f64, f64, f64) {
        let n = xs.len() as f64;
        let mean = xs.iter().sum::<f64>() / n;
        let m = |k: i32| xs.iter().map(|x| (x - mean).powi(k)).sum::<f64>();
        (m(2), m(3), m(4))
    }

    #[test]
    fn mean_var_power_sums_push_and_merge_agree_on_all_moments() {
        let xs = [0.0, 3.0, 0.0, 0.0, 7.5, 1.0, 0.0, 2.0];
        let mut all = MeanVar::default();
        xs.iter().for_each(|&x| all.push(x));
        let part = |s: &[f64]| {
            let p = |k: i32| s.iter().map(|x| x.powi(k)).sum::<f64>();
            MeanVar::from_power_sums(s.len() as u64, [p(1), p(2), p(3), p(4)])
        };
        let mut m = part(&xs[..3]);
        m.merge(&part(&xs[3..]));
        m.merge(&MeanVar::default());
        let mut pushed = MeanVar::default();
        xs[..5].iter().for_each(|&x| pushed.push(x));
        let mut rest = MeanVar::default();
        xs[5..].iter().for_each(|&x| rest.push(x));
        pushed.merge(&rest);
        let (m2, m3, m4) = two_pass_central(&xs);
        for v in [all, m, pushed] {
            assert_eq!(v.count(), 8);
            assert!((v.mean() - 13.5 / 8.0).abs() < 1e-14);
            assert!((v.m2 - m2).abs() < 1e-12 * m2);
            assert!((v.m3 - m3).abs() < 1e-12 * m3.abs());
            assert!((v.m4 - m4).abs() < 1e-12 * m4);
        }
    }

    #[test]
    fn variance_dof_is_n_minus_1_for_normal_data_and_small_for_rare_spikes() {
        // Normal data (Box–Muller on a fixed LCG): ν ≈ n − 1 within sampling error.
        let mut state = 12345u64;
        let mut u = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        };
        let mut normal = MeanVar::default();
        for _ in 0..20000 {
            let (a, b) = (u(), u());
            normal.push((-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos());
        }
        let nu = normal.mean_variance_dof();
        assert!((nu / 19999.0 - 1.0).abs() < 0.1, "ν = {nu}");
        // Three large values among 6000 small ones: the variance rests on about 3 values,
        // so ν is about 2·3 = 6, not 5999.
        let mut spiky = MeanVar::default();
        for i in 0..6000 {
            spiky.push(if i % 2000 == 7 { 500.0 } else { 0.02 * u() });
        }
        let nu = spiky.mean_variance_dof();
        assert!(nu > 3.0 && nu < 10.0, "ν = {nu}");
        // Unknown fourth moment: the z test (ν = ∞).
        let z = MeanVar::from_power_sums(10, [1.0, 1.0, f64::NAN, f64::NAN]);
        assert!(z.mean_variance_dof().is_infinite());
    }

    #[test]
    fn z_test_known_values() {
        let t = z_test(1.96, 1.0, 0.0);
        assert!((t.p - 0.0499958).abs() < 1e-5);
        assert_eq!(z_test(1.0, 0.0, 1.0).p, 1.0);
        assert_eq!(z_test(1.1, 0.0, 1.0).p, 0.0);
    }
}
