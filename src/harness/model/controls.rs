//! Deliberately wrong models, served by `furnace serve-models --controls` so that tests can
//! show the model-level kinds rejecting a wrong model through the protocol: a Lambertian
//! missing its 1/π (energy rejects it) and one whose sampler draws uniformly while claiming
//! the cosine-weighted pdf (chi-square rejects it).

use super::local::LocalBsdf;
use crate::harness::under_test::{
    BsdfModel, EmitterModel, ModelError, ModelSource, Named, PhaseModel,
};
use crate::math::{warp, Vec3, INV_PI};
use crate::scattering::{BsdfSample, Bxdf};
use crate::spectrum::{SampledSpectrum, Wavelengths};
use std::sync::Arc;

/// Reflectance of both controls.
const RHO: f64 = 0.5;

/// f = ρ instead of ρ/π, sampled by the cosine with the matching weight ρπ: consistent with
/// itself, but its albedo is πρ > 1.
pub struct LambertWithoutInvPi;

impl Bxdf for LambertWithoutInvPi {
    fn eval(&self, wo: Vec3, wi: Vec3, _wl: &Wavelengths) -> SampledSpectrum {
        SampledSpectrum::splat(if wo.z * wi.z > 0.0 { RHO } else { 0.0 })
    }
    fn sample(&self, wo: Vec3, u: [f64; 2], _uc: f64, wl: &Wavelengths) -> Option<BsdfSample> {
        let mut wi = warp::cosine_hemisphere(u);
        wi.z = wi.z.copysign(wo.z);
        let pdf = warp::cosine_hemisphere_pdf(Vec3::new(wi.x, wi.y, wi.z.abs()));
        (pdf > 0.0 && wo.z != 0.0).then(|| BsdfSample {
            wi,
            weight: self.eval(wo, wi, wl) * (wi.z.abs() / pdf),
            pdf,
            delta: false,
        })
    }
    fn pdf(&self, wo: Vec3, wi: Vec3, _wl: &Wavelengths) -> f64 {
        if wo.z * wi.z > 0.0 {
            wi.z.abs() * INV_PI
        } else {
            0.0
        }
    }
}

/// f = ρ/π, claiming the cosine-weighted pdf but drawing uniformly over the hemisphere (its
/// weights follow the claimed pdf, so only the distribution of the draws is wrong).
pub struct CosinePdfUniformDraws;

impl Bxdf for CosinePdfUniformDraws {
    fn eval(&self, wo: Vec3, wi: Vec3, _wl: &Wavelengths) -> SampledSpectrum {
        SampledSpectrum::splat(if wo.z * wi.z > 0.0 { RHO * INV_PI } else { 0.0 })
    }
    fn sample(&self, wo: Vec3, u: [f64; 2], _uc: f64, wl: &Wavelengths) -> Option<BsdfSample> {
        let w = warp::uniform_sphere(u);
        let wi = Vec3::new(w.x, w.y, w.z.abs().copysign(wo.z));
        let pdf = self.pdf(wo, wi, wl);
        (pdf > 0.0).then(|| BsdfSample {
            wi,
            weight: self.eval(wo, wi, wl) * (wi.z.abs() / pdf),
            pdf,
            delta: false,
        })
    }
    fn pdf(&self, wo: Vec3, wi: Vec3, _wl: &Wavelengths) -> f64 {
        if wo.z * wi.z > 0.0 {
            wi.z.abs() * INV_PI
        } else {
            0.0
        }
    }
}

/// Names of the controls.
pub const NAMES: [&str; 2] = [
    "control/lambert without 1/pi",
    "control/cosine pdf, uniform draws",
];

/// `source` with the controls added to its BSDFs.
pub struct WithControls<S>(pub S);

impl<S: ModelSource> ModelSource for WithControls<S> {
    fn describe(&self) -> String {
        format!("{} with deliberately wrong controls", self.0.describe())
    }
    fn bsdfs(&self) -> Result<Vec<Named<dyn BsdfModel>>, ModelError> {
        let mut v = self.0.bsdfs()?;
        v.push(Named {
            name: NAMES[0].into(),
            model: Arc::new(LocalBsdf::new(LambertWithoutInvPi)),
        });
        v.push(Named {
            name: NAMES[1].into(),
            model: Arc::new(LocalBsdf::new(CosinePdfUniformDraws)),
        });
        Ok(v)
    }
    fn phases(&self) -> Result<Vec<Named<dyn PhaseModel>>, ModelError> {
        self.0.phases()
    }
    fn emitters(&self) -> Result<Vec<Named<dyn EmitterModel>>, ModelError> {
        self.0.emitters()
    }
}
