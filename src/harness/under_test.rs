//! What the model-level kinds judge: a renderer's own BSDFs, phase functions and emitters,
//! answering many queries at once (in process for furnace, through the model protocol of
//! `docs/model-protocol.md` for other renderers). Conventions: local shading frame, z = normal,
//! `wo` and `wi` point away from the surface; `eval` without the cosine; pdfs per steradian.

use super::names::glob_match;
use super::renderer::Renderer;
use crate::math::Vec3;
use crate::media::PhaseSample;
use crate::scattering::BsdfSample;
use crate::spectrum::{SampledSpectrum, Wavelengths};
use std::sync::Arc;
use std::time::Duration;

/// A model could not answer: the server failed, timed out or broke the protocol.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct ModelError(pub String);

impl From<ModelError> for super::error::CheckError {
    fn from(e: ModelError) -> Self {
        super::error::CheckError::Renderer(e.0)
    }
}

/// What a BSDF says about itself; the physics expectations that apply follow from it.
#[derive(Debug, Clone, PartialEq)]
pub struct BsdfFlags {
    /// Has a Dirac lobe.
    pub delta: bool,
    /// Answers for `wo` below the surface as for its mirror image above.
    pub two_sided: bool,
    /// Has transmitted lobes.
    pub transmission: bool,
    /// η(inside)/η(outside) at 589.3 nm for transmissive models, else 1.
    pub eta: f64,
    /// Scatters all power at every angle (smooth glass, a perfect mirror).
    pub lossless: bool,
    /// η depends on wavelength: a sampled direction is right only for the hero.
    pub dispersive: bool,
    /// Smallest microfacet α of any lobe: 0 for a Dirac lobe, +∞ for lobes without a width.
    pub min_roughness: f64,
}

/// A BSDF answering batches of queries at the wavelengths `wl` (the same for every row).
pub trait BsdfModel: Send + Sync {
    /// Its flags.
    fn flags(&self) -> &BsdfFlags;
    /// f(wo, wi) per wavelength, sr⁻¹, without the cosine (0 for Dirac lobes).
    fn eval(
        &self,
        q: &[(Vec3, Vec3)],
        wl: &Wavelengths,
    ) -> Result<Vec<SampledSpectrum>, ModelError>;
    /// pdf(wo, wi) per steradian (0 for Dirac lobes).
    fn pdf(&self, q: &[(Vec3, Vec3)], wl: &Wavelengths) -> Result<Vec<f64>, ModelError>;
    /// A sample per (wo, u, uc), or None where the model produces none.
    fn sample(
        &self,
        q: &[(Vec3, [f64; 2], f64)],
        wl: &Wavelengths,
    ) -> Result<Vec<Option<BsdfSample>>, ModelError>;
    /// The refractive index on the side of each direction (1 on the normal's side).
    fn eta(&self, w: &[Vec3], wl: &Wavelengths) -> Result<Vec<SampledSpectrum>, ModelError>;
}

/// A phase function answering batches; directions point away from the scattering point.
pub trait PhaseModel: Send + Sync {
    /// ⟨cos θ⟩ of the scattering angle, when the model states it.
    fn mean_cosine(&self) -> Option<f64>;
    /// p(wo, wi) per steradian.
    fn eval(&self, q: &[(Vec3, Vec3)]) -> Result<Vec<f64>, ModelError>;
    /// The sampling pdf per steradian.
    fn pdf(&self, q: &[(Vec3, Vec3)]) -> Result<Vec<f64>, ModelError>;
    /// A sample per (wo, u).
    fn sample(&self, q: &[(Vec3, [f64; 2])]) -> Result<Vec<PhaseSample>, ModelError>;
}

/// A direction sampled towards an emitter from its receiving point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EmitterSample {
    /// Unit direction towards the sampled point.
    pub wi: Vec3,
    /// Radiance arriving along `wi` (a point light: intensity/distance²).
    pub radiance: SampledSpectrum,
    /// Pdf per steradian at the receiving point (1 for a point light).
    pub pdf: f64,
    /// Distance to the sampled point (∞ at infinity).
    pub dist: f64,
    /// A point light: no density.
    pub delta: bool,
}

/// An emitter in a small canonical scene, sampled from that scene's receiving point.
pub trait EmitterModel: Send + Sync {
    /// A sample per (u, uc), or None where the emitter produces none.
    fn sample(
        &self,
        q: &[([f64; 2], f64)],
        wl: &Wavelengths,
    ) -> Result<Vec<Option<EmitterSample>>, ModelError>;
    /// The solid-angle density of producing each direction, summed over the emitter's points
    /// along it.
    fn pdf(&self, w: &[Vec3], wl: &Wavelengths) -> Result<Vec<f64>, ModelError>;
}

/// A model with its name.
pub struct Named<M: ?Sized> {
    /// Name, unique within its kind.
    pub name: String,
    /// The model.
    pub model: Arc<M>,
}

impl<M: ?Sized> Clone for Named<M> {
    fn clone(&self) -> Self {
        Named {
            name: self.name.clone(),
            model: Arc::clone(&self.model),
        }
    }
}

/// The arithmetic a model computes in, which bounds how exactly it can meet an identity.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Precision {
    /// IEEE double precision (furnace's own models).
    #[default]
    F64,
    /// IEEE single precision (most GPU and SIMD renderers, Mitsuba 3's default variants).
    F32,
}

impl Precision {
    /// Relative allowance for rounding when a statistic is compared with its expected value:
    /// 1e-12 for f64 (about 4500 ulp, `stats::ROUNDING`), 1e-5 for f32 (about 80 ulp: the
    /// weights and albedos of an f32 model differ from their f64 quadrature by a few ulp).
    pub fn rounding(self) -> f64 {
        match self {
            Precision::F64 => crate::stats::ROUNDING,
            Precision::F32 => 1e-5,
        }
    }

    /// The smallest relative tolerance of a deterministic identity (reciprocity, weight =
    /// f·cos/pdf): the manifest's for f64; 1e-3 for f32, where identities whose two sides are
    /// computed along different paths (a Fresnel term from either side, a half vector near
    /// grazing) lose three to four digits of the seven an f32 carries, while the bugs these
    /// identities catch (a missing η², a wrong weight) are O(1).
    pub fn min_rel_tol(self) -> f64 {
        match self {
            Precision::F64 => 0.0,
            Precision::F32 => 1e-3,
        }
    }

    /// The narrowest histogram bin in the scattering cosine μ the model's directions resolve
    /// near μ = ±1: 0 for f64; 1e-5 for f32 (about 170 ulp of 1).
    pub fn mu_resolution(self) -> f64 {
        match self {
            Precision::F64 => 0.0,
            Precision::F32 => 1e-5,
        }
    }

    /// Unit roundoff ε of the arithmetic: 2⁻⁵³ for f64, 2⁻²⁴ for f32. An expression whose
    /// condition number is κ cannot be computed closer than about κε.
    pub fn unit_roundoff(self) -> f64 {
        match self {
            Precision::F64 => f64::EPSILON / 2.0,
            Precision::F32 => f32::EPSILON as f64 / 2.0,
        }
    }

    /// How far from 1 the length of a unit direction the model returns may be: 1e-9 for f64,
    /// 1e-6 for f32 (a normalised f32 vector is 1 ± a few ε, about 1e-7).
    pub fn unit_length_tol(self) -> f64 {
        match self {
            Precision::F64 => 1e-9,
            Precision::F32 => 1e-6,
        }
    }

    /// Its name on the wire and in messages.
    pub fn name(self) -> &'static str {
        match self {
            Precision::F64 => "float64",
            Precision::F32 => "float32",
        }
    }
}

/// The models a renderer exposes to the model-level kinds.
pub trait ModelSource: Send + Sync {
    /// Who serves them, for reports ("furnace 0.1.0 in process", "mitsuba3 3.9.1 ...").
    fn describe(&self) -> String;
    /// The arithmetic its models compute in.
    fn precision(&self) -> Precision {
        Precision::F64
    }
    /// Every BSDF.
    fn bsdfs(&self) -> Result<Vec<Named<dyn BsdfModel>>, ModelError>;
    /// Every phase function.
    fn phases(&self) -> Result<Vec<Named<dyn PhaseModel>>, ModelError>;
    /// Every emitter.
    fn emitters(&self) -> Result<Vec<Named<dyn EmitterModel>>, ModelError>;
}

/// What a run judges: a renderer's images and, when it serves them, its models.
#[derive(Clone, Copy)]
pub struct Subject<'a> {
    /// The renderer.
    pub renderer: &'a dyn Renderer,
    /// Its models, or None when it serves none.
    pub models: Option<&'a dyn ModelSource>,
}

/// The models of `inner` whose names match one of `globs`.
pub struct Filtered<'a> {
    /// The source.
    pub inner: &'a dyn ModelSource,
    /// Name patterns (`*`, `?`).
    pub globs: &'a [String],
}

impl Filtered<'_> {
    fn keep<M: ?Sized>(&self, v: Vec<Named<M>>) -> Vec<Named<M>> {
        v.into_iter()
            .filter(|m| self.globs.iter().any(|g| glob_match(g, &m.name)))
            .collect()
    }
}

impl ModelSource for Filtered<'_> {
    fn describe(&self) -> String {
        format!("{} (models {:?})", self.inner.describe(), self.globs)
    }
    fn precision(&self) -> Precision {
        self.inner.precision()
    }
    fn bsdfs(&self) -> Result<Vec<Named<dyn BsdfModel>>, ModelError> {
        Ok(self.keep(self.inner.bsdfs()?))
    }
    fn phases(&self) -> Result<Vec<Named<dyn PhaseModel>>, ModelError> {
        Ok(self.keep(self.inner.phases()?))
    }
    fn emitters(&self) -> Result<Vec<Named<dyn EmitterModel>>, ModelError> {
        Ok(self.keep(self.inner.emitters()?))
    }
}

/// How to start a server and how long to wait for each reply.
#[derive(Debug, Clone)]
pub struct ServerCommand {
    /// argv.
    pub argv: Vec<String>,
    /// Working directory.
    pub workdir: std::path::PathBuf,
    /// Environment variables set for it (the environment is otherwise cleared but for PATH,
    /// HOME, LANG and TMPDIR).
    pub env: Vec<(String, String)>,
    /// Longest wait for one reply.
    pub timeout: Duration,
}
