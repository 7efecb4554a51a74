//! Surface scattering: the [`Bxdf`] interface and the closed [`Bsdf`] set used by scenes.
//!
//! Conventions (checked by the analytic suite): directions are local to the shading frame
//! (z = normal), both `wo` (towards the viewer) and `wi` (towards the light) point away from
//! the surface; `eval` returns f(wo, wi) in sr⁻¹ **without** the cosine; pdfs are per unit
//! solid angle; a sample's `weight` is f·|cos θi|/pdf. Delta lobes are flagged and never
//! evaluated by `eval` or `pdf` (both return 0 for them).

pub mod lambert;

pub use lambert::Lambertian;

use crate::math::Vec3;
use crate::spectrum::{SampledSpectrum, Wavelengths};

/// One sampled scattering direction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BsdfSample {
    /// Sampled incident direction (local, unit).
    pub wi: Vec3,
    /// f·|cos θi| / pdf at the path's wavelengths.
    pub weight: SampledSpectrum,
    /// Pdf of `wi` per unit solid angle (for a delta lobe: the discrete probability).
    pub pdf: f64,
    /// True for a delta (specular) lobe.
    pub delta: bool,
}

/// A bidirectional scattering distribution function in the local frame.
pub trait Bxdf {
    /// f(wo, wi) in sr⁻¹, without the cosine; zero for delta lobes.
    fn eval(&self, wo: Vec3, wi: Vec3, wl: &Wavelengths) -> SampledSpectrum;
    /// Samples `wi` given `wo` from two uniform numbers `u` and one `uc` for lobe choice.
    fn sample(&self, wo: Vec3, u: [f64; 2], uc: f64, wl: &Wavelengths) -> Option<BsdfSample>;
    /// Pdf of sampling `wi` given `wo`, per unit solid angle; zero for delta lobes.
    fn pdf(&self, wo: Vec3, wi: Vec3, wl: &Wavelengths) -> f64;
    /// Refractive index of the medium on the side of `w` (relative to the side the normal
    /// points to, which is 1), per wavelength. `eval` carries radiance, so across a
    /// refractive interface it is not symmetric: f(wo, wi)/η(wo)² = f(wi, wo)/η(wi)²
    /// (Veach 1997, PhD thesis, §5.2, the generalised reciprocity of non-symmetric BSDFs).
    /// The adjoint (importance-carrying) BSDF used by light tracing is
    /// f*(wo, wi) = f(wi, wo) = f(wo, wi)·η(wi)²/η(wo)².
    fn eta(&self, _w: Vec3, _wl: &Wavelengths) -> SampledSpectrum {
        SampledSpectrum::ONE
    }
}

/// The BSDFs a scene can use.
#[derive(Debug, Clone, PartialEq)]
pub enum Bsdf {
    /// Lambertian reflector.
    Diffuse(Lambertian),
}

impl Bxdf for Bsdf {
    #[inline]
    fn eval(&self, wo: Vec3, wi: Vec3, wl: &Wavelengths) -> SampledSpectrum {
        match self {
            Bsdf::Diffuse(b) => b.eval(wo, wi, wl),
        }
    }
    #[inline]
    fn sample(&self, wo: Vec3, u: [f64; 2], uc: f64, wl: &Wavelengths) -> Option<BsdfSample> {
        match self {
            Bsdf::Diffuse(b) => b.sample(wo, u, uc, wl),
        }
    }
    #[inline]
    fn pdf(&self, wo: Vec3, wi: Vec3, wl: &Wavelengths) -> f64 {
        match self {
            Bsdf::Diffuse(b) => b.pdf(wo, wi, wl),
        }
    }
    #[inline]
    fn eta(&self, w: Vec3, wl: &Wavelengths) -> SampledSpectrum {
        match self {
            Bsdf::Diffuse(b) => b.eta(w, wl),
        }
    }
}
