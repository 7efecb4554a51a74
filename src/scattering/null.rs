//! The null interface: a surface that only marks where a medium begins and ends (an
//! index-matched boundary). Light passes straight through it unchanged.

use super::{BsdfSample, Bxdf};
use crate::math::Vec3;
use crate::spectrum::{SampledSpectrum, Wavelengths};

/// An index-matched boundary of a medium: f = δ(wi + wo)/|cos θi|, transmission 1.
/// Integrators step through it without counting a bounce; as a [`Bxdf`] it is the delta
/// transmission that describes the same thing.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct NullInterface;

impl Bxdf for NullInterface {
    fn eval(&self, _wo: Vec3, _wi: Vec3, _wl: &Wavelengths) -> SampledSpectrum {
        SampledSpectrum::ZERO
    }
    fn sample(&self, wo: Vec3, _u: [f64; 2], _uc: f64, _wl: &Wavelengths) -> Option<BsdfSample> {
        Some(BsdfSample {
            wi: -wo,
            weight: SampledSpectrum::ONE,
            pdf: 1.0,
            delta: true,
        })
    }
    fn pdf(&self, _wo: Vec3, _wi: Vec3, _wl: &Wavelengths) -> f64 {
        0.0
    }
    fn roughness(&self) -> f64 {
        0.0
    }
}
