//! Lambertian (ideal diffuse) reflection, two-sided: f = R/π on the side `wo` lies on
//! (Lambert 1760, *Photometria*; R is the reflectance spectrum, unitless in [0, 1]).

use super::{BsdfSample, Bxdf};
use crate::math::{warp, Vec3, INV_PI};
use crate::spectrum::{SampledSpectrum, Spectrum, Wavelengths};

/// Lambertian reflector with a reflectance spectrum in [0, 1].
#[derive(Debug, Clone, PartialEq)]
pub struct Lambertian {
    /// Reflectance (albedo) spectrum.
    pub reflectance: Spectrum,
}

impl Lambertian {
    /// [`Bxdf::eval`] with the reflectance `r` already evaluated at the path's wavelengths.
    #[inline]
    pub fn eval_with(wo: Vec3, wi: Vec3, r: &SampledSpectrum) -> SampledSpectrum {
        if wo.z * wi.z <= 0.0 {
            return SampledSpectrum::ZERO;
        }
        *r * INV_PI
    }

    /// [`Bxdf::sample`] with the reflectance `r` already evaluated at the path's wavelengths.
    #[inline]
    pub fn sample_with(wo: Vec3, u: [f64; 2], r: &SampledSpectrum) -> Option<BsdfSample> {
        if wo.z == 0.0 {
            return None;
        }
        let mut wi = warp::cosine_hemisphere(u);
        if wo.z < 0.0 {
            wi.z = -wi.z;
        }
        let pdf = warp::cosine_hemisphere_pdf(Vec3::new(wi.x, wi.y, wi.z.abs()));
        if pdf == 0.0 {
            return None;
        }
        // f·cos/pdf = (R/π)·cos/(cos/π) = R exactly.
        Some(BsdfSample {
            wi,
            weight: *r,
            pdf,
            delta: false,
        })
    }
}

impl Bxdf for Lambertian {
    fn eval(&self, wo: Vec3, wi: Vec3, wl: &Wavelengths) -> SampledSpectrum {
        Self::eval_with(wo, wi, &self.reflectance.sample(wl))
    }

    fn sample(&self, wo: Vec3, u: [f64; 2], _uc: f64, wl: &Wavelengths) -> Option<BsdfSample> {
        Self::sample_with(wo, u, &self.reflectance.sample(wl))
    }

    fn pdf(&self, wo: Vec3, wi: Vec3, _wl: &Wavelengths) -> f64 {
        if wo.z * wi.z <= 0.0 {
            return 0.0;
        }
        wi.z.abs() * INV_PI
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reciprocal_and_weight_consistent() {
        let b = Lambertian {
            reflectance: Spectrum::Constant(0.7),
        };
        let wl = Wavelengths::sample_visible(0.3);
        let wo = Vec3::new(0.3, 0.1, 0.9).normalize();
        let s = b.sample(wo, [0.2, 0.7], 0.0, &wl).unwrap();
        let f = b.eval(wo, s.wi, &wl);
        let w = f * (s.wi.z.abs() / s.pdf);
        for i in 0..4 {
            assert!((w.0[i] - s.weight.0[i]).abs() < 1e-12);
        }
        assert_eq!(b.eval(wo, s.wi, &wl), b.eval(s.wi, wo, &wl));
        assert!((b.pdf(wo, s.wi, &wl) - s.pdf).abs() < 1e-15);
        // back side: mirrored
        let wo_back = Vec3::new(wo.x, wo.y, -wo.z);
        let s = b.sample(wo_back, [0.2, 0.7], 0.0, &wl).unwrap();
        assert!(s.wi.z < 0.0);
    }
}
