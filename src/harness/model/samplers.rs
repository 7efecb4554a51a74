//! Direction-sampling routines with the pdf they claim, for the chi-square kind: a BSDF's
//! sampling at a fixed outgoing direction, a phase function's, and an emitter's from its
//! receiving point, each queried in batches.

use super::catalogue::{check_wavelengths, CHI2_MIN_ROUGHNESS};
use crate::harness::under_test::{
    BsdfModel, EmitterModel, ModelError, ModelSource, Named, PhaseModel,
};
use crate::math::Vec3;
use std::sync::Arc;

/// A routine that samples directions, with the pdf it claims (per steradian).
pub trait DirectionSampler: Send + Sync {
    /// A direction per (u, uc), or None where the routine produces no sample (a BSDF's Dirac
    /// lobes count as none: they have no density to test).
    fn sample(&self, q: &[([f64; 2], f64)]) -> Result<Vec<Option<Vec3>>, ModelError>;
    /// The claimed pdf of each direction, per steradian.
    fn pdf(&self, w: &[Vec3]) -> Result<Vec<f64>, ModelError>;
}

/// A BSDF's sampling routine at a fixed `wo` (local frame).
pub struct BsdfSampler {
    /// The BSDF.
    pub bsdf: Arc<dyn BsdfModel>,
    /// Outgoing direction.
    pub wo: Vec3,
}

impl DirectionSampler for BsdfSampler {
    fn sample(&self, q: &[([f64; 2], f64)]) -> Result<Vec<Option<Vec3>>, ModelError> {
        let rows: Vec<_> = q.iter().map(|&(u, uc)| (self.wo, u, uc)).collect();
        Ok(self
            .bsdf
            .sample(&rows, &check_wavelengths())?
            .into_iter()
            .map(|s| s.filter(|s| !s.delta).map(|s| s.wi))
            .collect())
    }
    fn pdf(&self, w: &[Vec3]) -> Result<Vec<f64>, ModelError> {
        let rows: Vec<_> = w.iter().map(|&w| (self.wo, w)).collect();
        self.bsdf.pdf(&rows, &check_wavelengths())
    }
}

/// A phase function's sampling routine at a fixed `wo`.
pub struct PhaseSampler {
    /// The phase function.
    pub phase: Arc<dyn PhaseModel>,
    /// Outgoing direction.
    pub wo: Vec3,
}

impl DirectionSampler for PhaseSampler {
    fn sample(&self, q: &[([f64; 2], f64)]) -> Result<Vec<Option<Vec3>>, ModelError> {
        let rows: Vec<_> = q.iter().map(|&(u, _)| (self.wo, u)).collect();
        Ok(self
            .phase
            .sample(&rows)?
            .into_iter()
            .map(|s| Some(s.wi))
            .collect())
    }
    fn pdf(&self, w: &[Vec3]) -> Result<Vec<f64>, ModelError> {
        let rows: Vec<_> = w.iter().map(|&w| (self.wo, w)).collect();
        self.phase.pdf(&rows)
    }
}

/// An emitter's sampling routine from its receiving point.
pub struct EmitterSampler(pub Arc<dyn EmitterModel>);

impl DirectionSampler for EmitterSampler {
    fn sample(&self, q: &[([f64; 2], f64)]) -> Result<Vec<Option<Vec3>>, ModelError> {
        Ok(self
            .0
            .sample(q, &check_wavelengths())?
            .into_iter()
            .map(|s| s.filter(|s| !s.delta).map(|s| s.wi))
            .collect())
    }
    fn pdf(&self, w: &[Vec3]) -> Result<Vec<f64>, ModelError> {
        self.0.pdf(w, &check_wavelengths())
    }
}

/// A sampling routine with its name.
pub type NamedSampler = (String, Box<dyn DirectionSampler>);

/// The outgoing angles (degrees) at which each BSDF's sampling is tested.
pub const BSDF_ANGLES: [f64; 4] = [0.0, 45.0, 80.0, 89.0];

/// Every sampling routine of `models`, by name: BSDFs whose lobes the sphere bins resolve
/// (roughness ≥ [`CHI2_MIN_ROUGHNESS`]) at each of [`BSDF_ANGLES`], phase functions with
/// |⟨cos θ⟩| ≤ 0.95 (narrower lobes fall inside one bin; the phase kind tests them in the
/// scattering cosine with graded bins), and every emitter with a density.
pub fn samplers(models: &dyn ModelSource) -> Result<Vec<NamedSampler>, ModelError> {
    let mut v: Vec<NamedSampler> = Vec::new();
    for Named { name, model } in models.bsdfs()? {
        if model.flags().min_roughness < CHI2_MIN_ROUGHNESS {
            continue;
        }
        for theta in BSDF_ANGLES {
            let wo = Vec3::new(theta.to_radians().sin(), 0.0, theta.to_radians().cos());
            v.push((
                format!("bsdf {name} θo={theta}°"),
                Box::new(BsdfSampler {
                    bsdf: Arc::clone(&model),
                    wo,
                }),
            ));
        }
    }
    for Named { name, model } in models.phases()? {
        if model.mean_cosine().is_some_and(|g| g.abs() > 0.95) {
            continue;
        }
        let wo = Vec3::new(0.3, -0.2, 0.9).normalize();
        v.push((
            format!("phase {name}"),
            Box::new(PhaseSampler { phase: model, wo }),
        ));
    }
    for Named { name, model } in models.emitters()? {
        // a point light has no density: nothing to bin
        let probe = model.sample(&[([0.5, 0.5], 0.5)], &check_wavelengths())?;
        if probe.first().is_some_and(|s| s.is_some_and(|s| s.delta)) {
            continue;
        }
        v.push((name, Box::new(EmitterSampler(model))));
    }
    Ok(v)
}
