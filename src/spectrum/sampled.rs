//! Per-path spectral values at [`N_WAVELENGTHS`] wavelengths, and hero-wavelength sampling.

use super::{LAMBDA_MAX, LAMBDA_MIN};
use std::ops::{Add, AddAssign, Div, Mul, MulAssign};

/// Number of wavelengths carried by one path (Wilkie et al. 2014, "Hero Wavelength Spectral
/// Sampling", EGSR, §4: one hero plus three rotated wavelengths).
pub const N_WAVELENGTHS: usize = 4;

/// A spectral quantity sampled at the path's wavelengths (units of whatever it samples).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SampledSpectrum(pub [f64; N_WAVELENGTHS]);

impl SampledSpectrum {
    /// All components equal to `v`.
    pub const fn splat(v: f64) -> Self {
        SampledSpectrum([v; N_WAVELENGTHS])
    }
    /// All zero.
    pub const ZERO: Self = Self::splat(0.0);
    /// All one.
    pub const ONE: Self = Self::splat(1.0);

    /// Largest component.
    pub fn max_component(&self) -> f64 {
        self.0.iter().copied().fold(f64::NEG_INFINITY, f64::max)
    }

    /// True when every component is zero.
    pub fn is_black(&self) -> bool {
        self.0.iter().all(|&v| v == 0.0)
    }

    /// True when no component is NaN or infinite.
    pub fn is_finite(&self) -> bool {
        self.0.iter().all(|v| v.is_finite())
    }

    /// Mean of the components.
    pub fn average(&self) -> f64 {
        self.0.iter().sum::<f64>() / N_WAVELENGTHS as f64
    }
}

impl Add for SampledSpectrum {
    type Output = Self;
    fn add(self, o: Self) -> Self {
        SampledSpectrum(std::array::from_fn(|i| self.0[i] + o.0[i]))
    }
}
impl AddAssign for SampledSpectrum {
    fn add_assign(&mut self, o: Self) {
        *self = *self + o;
    }
}
impl Mul for SampledSpectrum {
    type Output = Self;
    fn mul(self, o: Self) -> Self {
        SampledSpectrum(std::array::from_fn(|i| self.0[i] * o.0[i]))
    }
}
impl MulAssign for SampledSpectrum {
    fn mul_assign(&mut self, o: Self) {
        *self = *self * o;
    }
}
impl Mul<f64> for SampledSpectrum {
    type Output = Self;
    fn mul(self, s: f64) -> Self {
        SampledSpectrum(self.0.map(|v| v * s))
    }
}
impl MulAssign<f64> for SampledSpectrum {
    fn mul_assign(&mut self, s: f64) {
        *self = *self * s;
    }
}
impl Div<f64> for SampledSpectrum {
    type Output = Self;
    fn div(self, s: f64) -> Self {
        SampledSpectrum(self.0.map(|v| v / s))
    }
}

/// The wavelengths a path carries (nm) and the marginal pdf of each (per nm).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Wavelengths {
    /// Wavelengths in nm, within [360, 830].
    pub lambda: [f64; N_WAVELENGTHS],
    /// Marginal pdf of each wavelength, per nm.
    pub pdf: [f64; N_WAVELENGTHS],
    /// Set when the path met a surface that sends wavelengths apart (dispersion), or from the
    /// start for the single-wavelength estimator: only the hero (index 0) still carries an
    /// estimate from then on.
    pub secondary_terminated: bool,
}

// Visible-range importance pdf p(λ) ∝ sech²(A (λ - B)) on [360, 830] nm (Radziszewski, Boryczko
// & Alda 2009, "An improved technique for full spectral rendering", JWSCG 17; constants as in
// Pharr, Jakob & Humphreys, PBR 4th ed., §4.6.5). Its CDF is proportional to tanh(A (λ - B)).
const VIS_A: f64 = 0.0072;
const VIS_B: f64 = 538.0;

fn vis_tanh(lambda: f64) -> f64 {
    (VIS_A * (lambda - VIS_B)).tanh()
}

/// tanh(A (360 − B)) and tanh(A (830 − B)), the CDF's ends (checked in the tests).
const VIS_T0: f64 = -0.856_910_625_469_828;
const VIS_T1: f64 = 0.970_591_346_940_269_8;
/// The pdf's normalisation A / (T1 − T0), per nm.
const VIS_NORM: f64 = VIS_A / (VIS_T1 - VIS_T0);

impl Wavelengths {
    /// Samples four wavelengths from one uniform number `u`: the hero at the inverse CDF of
    /// `u`, the others at `u + i/4 (mod 1)`, so each is marginally distributed with the
    /// visible pdf and the four are stratified (the rotation of Wilkie et al. 2014, done in
    /// primary-sample space so that a non-uniform pdf stays exact).
    pub fn sample_visible(u: f64) -> Self {
        let (t0, t1) = (VIS_T0, VIS_T1);
        let mut lambda = [0.0; N_WAVELENGTHS];
        let mut pdf = [0.0; N_WAVELENGTHS];
        for i in 0..N_WAVELENGTHS {
            let ui = (u + i as f64 / N_WAVELENGTHS as f64).fract();
            let x = t0 + ui * (t1 - t0);
            // atanh x = ½ ln((1 + x)/(1 − x)); x <= T1 < 1. `ln` rather than f64::atanh (which
            // goes through log1p and its errno wrapper): absolute error ~1e-16, i.e. 1e-14 nm
            let l = VIS_B + 0.5 * ((1.0 + x) / (1.0 - x)).ln() / VIS_A;
            lambda[i] = l.clamp(LAMBDA_MIN, LAMBDA_MAX);
            // tanh(A (λ − B)) = x at the sampled λ, so sech² = 1 − x² without a second
            // transcendental (equal to visible_pdf(λ) up to λ's rounding); a λ clamped to the
            // range ends takes the pdf there.
            pdf[i] = if l == lambda[i] {
                VIS_NORM * (1.0 - x * x)
            } else {
                Self::visible_pdf(lambda[i])
            };
        }
        Wavelengths {
            lambda,
            pdf,
            secondary_terminated: false,
        }
    }

    /// The wavelengths of one film sample: [`Self::sample_visible`] from `u` (u = 0.5 in grey
    /// mode, where nothing depends on wavelength), and for a film that weighs only the hero
    /// (`lanes == 1`, the single-wavelength estimator) the secondaries dropped from the start,
    /// so that integrators never scale the hero by the lane count for it. Both renderers use
    /// this, which keeps the film weights and the integrators' hero scaling in step.
    pub fn for_film(u: f64, lanes: usize, grey: bool) -> Self {
        let mut wl = Self::sample_visible(if grey { 0.5 } else { u });
        if lanes == 1 && !grey {
            wl.terminate_secondary();
        }
        wl
    }

    /// The visible-range pdf per nm at `lambda` (0 outside [360, 830] nm).
    pub fn visible_pdf(lambda: f64) -> f64 {
        if !(LAMBDA_MIN..=LAMBDA_MAX).contains(&lambda) {
            return 0.0;
        }
        // sech² = 1 − tanh²: one transcendental instead of cosh.
        let t = vis_tanh(lambda);
        VIS_NORM * (1.0 - t * t)
    }

    /// Drops every wavelength but the hero from the start (the single-wavelength film); paths
    /// that meet dispersion use [`Wavelengths::disperse`], which also rescales the throughput.
    pub fn terminate_secondary(&mut self) {
        self.secondary_terminated = true;
    }

    /// The dispersion rule, at a surface that sends wavelengths apart (Wilkie et al. 2014,
    /// §4.3: past it the secondary wavelengths' paths no longer exist): only the hero goes on,
    /// with throughput `beta` over its lane density ratio `hero_ratio` (the hero's pdf over the
    /// lanes' mean pdf; 1 without media) times the lane count, since the film keeps weighting
    /// every lane 1/N and what the path gathered before stays a four-lane estimate. A path
    /// already reduced to its hero is left alone. True when the secondaries were dropped here.
    pub fn disperse(&mut self, beta: &mut SampledSpectrum, hero_ratio: f64) -> bool {
        if self.secondary_terminated {
            return false;
        }
        self.secondary_terminated = true;
        let b0 = if hero_ratio > 0.0 {
            beta.0[0] / hero_ratio
        } else {
            0.0
        };
        *beta = SampledSpectrum([b0 * N_WAVELENGTHS as f64, 0.0, 0.0, 0.0]);
        true
    }

    /// Wavelengths still carried by the path: 1 after dispersion, else all.
    pub fn active_lanes(&self) -> usize {
        if self.secondary_terminated {
            1
        } else {
            N_WAVELENGTHS
        }
    }

    /// Four fixed wavelengths with a given pdf; for tests and single-wavelength studies.
    pub fn fixed(lambda: [f64; N_WAVELENGTHS], pdf: [f64; N_WAVELENGTHS]) -> Self {
        Wavelengths {
            lambda,
            pdf,
            secondary_terminated: false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cdf_end_constants_match_their_definition() {
        assert_eq!(VIS_T0, vis_tanh(LAMBDA_MIN));
        assert_eq!(VIS_T1, vis_tanh(LAMBDA_MAX));
    }

    #[test]
    fn visible_pdf_integrates_to_one() {
        // midpoint rule over 360..830 nm at 0.01 nm
        let n = 47_000;
        let h = (LAMBDA_MAX - LAMBDA_MIN) / n as f64;
        let total: f64 = (0..n)
            .map(|i| Wavelengths::visible_pdf(LAMBDA_MIN + (i as f64 + 0.5) * h) * h)
            .sum();
        assert!((total - 1.0).abs() < 1e-9, "{total}");
    }

    #[test]
    fn sampled_wavelengths_follow_the_cdf() {
        // The inverse CDF must map u to the wavelength whose CDF is u.
        for k in 0..100 {
            let u = (k as f64 + 0.5) / 100.0;
            let w = Wavelengths::sample_visible(u);
            let n = 20_000;
            let h = (w.lambda[0] - LAMBDA_MIN) / n as f64;
            let cdf: f64 = (0..n)
                .map(|i| Wavelengths::visible_pdf(LAMBDA_MIN + (i as f64 + 0.5) * h) * h)
                .sum();
            assert!((cdf - u).abs() < 1e-7, "u={u} cdf={cdf}");
            for i in 0..N_WAVELENGTHS {
                assert!((LAMBDA_MIN..=LAMBDA_MAX).contains(&w.lambda[i]));
                assert!(w.pdf[i] > 0.0);
            }
        }
    }

    #[test]
    fn extremes_of_u_stay_in_range() {
        for u in [0.0, 1e-17, 0.999_999_999_999, 0.25, 0.75] {
            let w = Wavelengths::sample_visible(u);
            assert!(w
                .lambda
                .iter()
                .all(|l| (LAMBDA_MIN..=LAMBDA_MAX).contains(l)));
            assert!(w.pdf.iter().all(|p| p.is_finite() && *p > 0.0));
        }
    }

    #[test]
    fn sampled_pdf_is_the_visible_pdf_at_the_sampled_wavelength() {
        // the pdf comes from the inverse-CDF argument, not from λ: they must agree to rounding
        for k in 0..10_000 {
            let w = Wavelengths::sample_visible((k as f64 + 0.5) / 10_000.0);
            for (l, p) in w.lambda.iter().zip(&w.pdf) {
                let want = Wavelengths::visible_pdf(*l);
                assert!((p - want).abs() <= 1e-12 * want, "{l} nm: {p} vs {want}");
            }
        }
        for u in [0.0, 1e-17, 0.999_999_999_999_999_9] {
            let w = Wavelengths::sample_visible(u);
            for (l, p) in w.lambda.iter().zip(&w.pdf) {
                let want = Wavelengths::visible_pdf(*l);
                assert!((p - want).abs() <= 1e-12 * want, "{l} nm: {p} vs {want}");
            }
        }
    }
}
