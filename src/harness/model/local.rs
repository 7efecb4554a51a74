//! furnace's own models answering the batched interface of `under_test.rs` in process: each
//! query is one call of the model (`Bxdf`, `Phase`, a light's sampler), in order.

use super::catalogue;
use crate::harness::under_test::{
    BsdfFlags, BsdfModel, EmitterModel, EmitterSample, ModelError, ModelSource, Named, PhaseModel,
};
use crate::math::Vec3;
use crate::media::{Phase, PhaseFunction, PhaseSample};
use crate::scattering::{Bsdf, BsdfSample, Bxdf};
use crate::spectrum::{SampledSpectrum, Wavelengths};
use std::sync::Arc;

/// A BSDF in process.
pub struct LocalBsdf<B> {
    /// The model.
    pub bsdf: B,
    /// What it says about itself.
    pub flags: BsdfFlags,
}

impl<B: Bxdf> LocalBsdf<B> {
    /// A model with flags read from the `Bxdf` interface alone: a Dirac lobe where the
    /// roughness is 0, transmission where η differs below the surface; not lossless, not
    /// dispersive (test models say otherwise through [`LocalBsdf::with_flags`]).
    pub fn new(bsdf: B) -> Self {
        let wl = catalogue::check_wavelengths();
        let below = bsdf.eta(Vec3::new(0.0, 0.0, -1.0), &wl).0[0];
        let flags = BsdfFlags {
            delta: bsdf.roughness() == 0.0,
            two_sided: false,
            transmission: below != 1.0,
            eta: below,
            lossless: false,
            dispersive: false,
            min_roughness: bsdf.roughness(),
        };
        LocalBsdf { bsdf, flags }
    }

    /// A model with the given flags.
    pub fn with_flags(bsdf: B, flags: BsdfFlags) -> Self {
        LocalBsdf { bsdf, flags }
    }
}

impl LocalBsdf<Bsdf> {
    /// One of furnace's scene BSDFs, with its exact flags.
    pub fn of(bsdf: Bsdf) -> Self {
        let mut m = LocalBsdf::new(bsdf);
        let b = &m.bsdf;
        m.flags.two_sided = matches!(b, Bsdf::Diffuse(_) | Bsdf::Ward(_));
        m.flags.lossless = b.is_lossless();
        m.flags.dispersive = b.separates_wavelengths();
        if let Bsdf::Dielectric(d) = b {
            m.flags.eta = d.ior.eval(589.3);
            m.flags.transmission = true;
        }
        m
    }
}

impl<B: Bxdf + Send + Sync> BsdfModel for LocalBsdf<B> {
    fn flags(&self) -> &BsdfFlags {
        &self.flags
    }
    fn eval(
        &self,
        q: &[(Vec3, Vec3)],
        wl: &Wavelengths,
    ) -> Result<Vec<SampledSpectrum>, ModelError> {
        Ok(q.iter()
            .map(|&(wo, wi)| self.bsdf.eval(wo, wi, wl))
            .collect())
    }
    fn pdf(&self, q: &[(Vec3, Vec3)], wl: &Wavelengths) -> Result<Vec<f64>, ModelError> {
        Ok(q.iter()
            .map(|&(wo, wi)| self.bsdf.pdf(wo, wi, wl))
            .collect())
    }
    fn sample(
        &self,
        q: &[(Vec3, [f64; 2], f64)],
        wl: &Wavelengths,
    ) -> Result<Vec<Option<BsdfSample>>, ModelError> {
        Ok(q.iter()
            .map(|&(wo, u, uc)| self.bsdf.sample(wo, u, uc, wl))
            .collect())
    }
    fn eta(&self, w: &[Vec3], wl: &Wavelengths) -> Result<Vec<SampledSpectrum>, ModelError> {
        Ok(w.iter().map(|&w| self.bsdf.eta(w, wl)).collect())
    }
}

/// A phase function in process, with its stated mean cosine.
pub struct LocalPhase<P> {
    /// The model.
    pub phase: P,
    /// Its mean scattering cosine, when known.
    pub mean_cosine: Option<f64>,
}

impl<P: Phase + Send + Sync> PhaseModel for LocalPhase<P> {
    fn mean_cosine(&self) -> Option<f64> {
        self.mean_cosine
    }
    fn eval(&self, q: &[(Vec3, Vec3)]) -> Result<Vec<f64>, ModelError> {
        Ok(q.iter().map(|&(wo, wi)| self.phase.eval(wo, wi)).collect())
    }
    fn pdf(&self, q: &[(Vec3, Vec3)]) -> Result<Vec<f64>, ModelError> {
        Ok(q.iter().map(|&(wo, wi)| self.phase.pdf(wo, wi)).collect())
    }
    fn sample(&self, q: &[(Vec3, [f64; 2])]) -> Result<Vec<PhaseSample>, ModelError> {
        Ok(q.iter().map(|&(wo, u)| self.phase.sample(wo, u)).collect())
    }
}

/// One of furnace's lights in a canonical scene, sampled from the origin; its pdf comes from
/// intersecting the light's shape, independently of the light's own sampling code
/// ([`catalogue::LightSampler`]).
pub struct LocalEmitter(pub catalogue::LightSampler);

impl EmitterModel for LocalEmitter {
    fn sample(
        &self,
        q: &[([f64; 2], f64)],
        wl: &Wavelengths,
    ) -> Result<Vec<Option<EmitterSample>>, ModelError> {
        let l = &self.0;
        Ok(q.iter()
            .map(|&(u, uc)| {
                l.light
                    .sample(l.p, uc, u, &l.shapes, wl)
                    .map(|s| EmitterSample {
                        wi: s.wi,
                        radiance: s.radiance,
                        pdf: s.pdf,
                        dist: s.point.map_or(f64::INFINITY, |p| (p.p - l.p).length()),
                        delta: s.delta,
                    })
            })
            .collect())
    }
    fn pdf(&self, w: &[Vec3], _wl: &Wavelengths) -> Result<Vec<f64>, ModelError> {
        Ok(w.iter().map(|&w| self.0.pdf_of(w)).collect())
    }
}

/// furnace's model catalogue, in process.
#[derive(Debug, Clone, Copy, Default)]
pub struct LocalModels;

impl ModelSource for LocalModels {
    fn describe(&self) -> String {
        format!("furnace {} (in process)", env!("CARGO_PKG_VERSION"))
    }
    fn bsdfs(&self) -> Result<Vec<Named<dyn BsdfModel>>, ModelError> {
        Ok(catalogue::bsdfs()
            .into_iter()
            .map(|(name, b)| Named {
                name,
                model: Arc::new(LocalBsdf::of(b)) as Arc<dyn BsdfModel>,
            })
            .collect())
    }
    fn phases(&self) -> Result<Vec<Named<dyn PhaseModel>>, ModelError> {
        Ok(catalogue::phases()
            .into_iter()
            .map(|(name, phase, mean_cosine)| Named {
                name,
                model: Arc::new(LocalPhase::<PhaseFunction> {
                    phase,
                    mean_cosine: Some(mean_cosine),
                }) as Arc<dyn PhaseModel>,
            })
            .collect())
    }
    fn emitters(&self) -> Result<Vec<Named<dyn EmitterModel>>, ModelError> {
        Ok(catalogue::lights()
            .into_iter()
            .map(|(name, l)| Named {
                name,
                model: Arc::new(LocalEmitter(l)) as Arc<dyn EmitterModel>,
            })
            .collect())
    }
}
