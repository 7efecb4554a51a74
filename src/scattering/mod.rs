//! Surface scattering: the [`Bxdf`] interface and the closed [`Bsdf`] set used by scenes.
//!
//! Conventions (checked by the analytic suite): directions are local to the shading frame
//! (z = normal), both `wo` (towards the viewer) and `wi` (towards the light) point away from
//! the surface; `eval` returns f(wo, wi) in sr⁻¹ **without** the cosine; pdfs are per unit
//! solid angle; a sample's `weight` is f·|cos θi|/pdf. Delta lobes are flagged and never
//! evaluated by `eval` or `pdf` (both return 0 for them).

pub mod conductor;
pub mod dielectric;
pub mod fresnel;
pub mod lambert;
pub mod microfacet;
pub mod null;
pub mod ward;

pub use conductor::{Conductor, ConductorFresnel};
pub use dielectric::Dielectric;
pub use fresnel::Ior;
pub use lambert::Lambertian;
pub use null::NullInterface;
pub use ward::Ward;

use crate::math::Vec3;
use crate::spectrum::{SampledSpectrum, Spectrum, Wavelengths};

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
    /// The smallest roughness of any lobe (GGX/Ward α): 0 for a delta lobe, +∞ for lobes
    /// without a width (Lambert). Checks that integrate `eval` on a fixed grid skip lobes
    /// narrower than the grid resolves, and say so.
    fn roughness(&self) -> f64 {
        f64::INFINITY
    }
}

/// The BSDFs a scene can use.
#[derive(Debug, Clone, PartialEq)]
pub enum Bsdf {
    /// Lambertian reflector.
    Diffuse(Lambertian),
    /// Smooth or GGX-rough metal.
    Conductor(Conductor),
    /// Smooth or GGX-rough dielectric interface.
    Dielectric(Dielectric),
    /// Ward with bounded albedo.
    Ward(Ward),
    /// Index-matched medium boundary (no scattering).
    Null(NullInterface),
}

/// Dispatches a method call to the variant.
macro_rules! each {
    ($self:expr, $b:ident => $e:expr) => {
        match $self {
            Bsdf::Diffuse($b) => $e,
            Bsdf::Conductor($b) => $e,
            Bsdf::Dielectric($b) => $e,
            Bsdf::Ward($b) => $e,
            Bsdf::Null($b) => $e,
        }
    };
}

impl Bsdf {
    /// η(wi)²/η(wo)² per wavelength (1 for a reflection): the factor of the adjoint BSDF
    /// ([`Bxdf::eta`]), and the radiance scaling of a refraction that roulette undoes.
    pub fn eta_ratio_squared(&self, wo: Vec3, wi: Vec3, wl: &Wavelengths) -> SampledSpectrum {
        let (to, from) = (self.eta(wi, wl), self.eta(wo, wl));
        SampledSpectrum(std::array::from_fn(|i| {
            let r = to.0[i] / from.0[i];
            r * r
        }))
    }
    /// True for a null interface, which integrators step through without a bounce.
    #[inline]
    pub fn is_null(&self) -> bool {
        matches!(self, Bsdf::Null(_))
    }

    /// True when the BSDF sends different wavelengths in different directions (a dispersive
    /// dielectric): a path through it keeps only its hero wavelength.
    pub fn separates_wavelengths(&self) -> bool {
        matches!(self, Bsdf::Dielectric(d) if d.ior.is_dispersive())
    }

    /// True when the BSDF scatters all power at every angle at the hero wavelength: a smooth
    /// dielectric (R + T = 1 in power; Born & Wolf §1.5.3) or a perfect smooth mirror.
    pub fn is_lossless(&self) -> bool {
        match self {
            Bsdf::Dielectric(d) => d.is_smooth(),
            Bsdf::Conductor(c) => c.is_smooth() && c.fresnel == ConductorFresnel::Perfect,
            Bsdf::Null(_) => true,
            _ => false,
        }
    }

    /// True when nothing about the BSDF depends on wavelength (grey mode may be used).
    pub fn is_constant(&self) -> bool {
        match self {
            Bsdf::Diffuse(l) => l.reflectance.is_constant(),
            Bsdf::Conductor(c) => match &c.fresnel {
                ConductorFresnel::Perfect => true,
                ConductorFresnel::Complex { eta, k } => eta.is_constant() && k.is_constant(),
            },
            Bsdf::Dielectric(d) => !d.ior.is_dispersive(),
            Bsdf::Ward(w) => w.diffuse.is_constant() && w.specular.is_constant(),
            Bsdf::Null(_) => true,
        }
    }
}

/// A BSDF at one path vertex with the spectra its evaluation and its sampling share already
/// evaluated at the path's wavelengths (a Lambertian's reflectance), so next-event estimation
/// and sampling at the vertex evaluate them once; the same values as the [`Bsdf`] itself.
#[derive(Debug, Clone, Copy)]
pub struct SampledBsdf<'a> {
    bsdf: &'a Bsdf,
    wl: &'a Wavelengths,
    /// A Lambertian's reflectance at `wl` (Some exactly when `bsdf` is a Lambertian).
    reflectance: Option<SampledSpectrum>,
}

impl<'a> SampledBsdf<'a> {
    /// `bsdf` at the wavelengths `wl`.
    #[inline]
    pub fn new(bsdf: &'a Bsdf, wl: &'a Wavelengths) -> Self {
        Self::with_reflectance(bsdf, wl, |r| r.sample(wl))
    }

    /// [`SampledBsdf::new`] with a Lambertian's reflectance at `wl` given by `sampled`
    /// (which may return it from a cache).
    #[inline]
    pub fn with_reflectance(
        bsdf: &'a Bsdf,
        wl: &'a Wavelengths,
        sampled: impl FnOnce(&Spectrum) -> SampledSpectrum,
    ) -> Self {
        let reflectance = match bsdf {
            Bsdf::Diffuse(l) => Some(sampled(&l.reflectance)),
            _ => None,
        };
        SampledBsdf {
            bsdf,
            wl,
            reflectance,
        }
    }

    /// [`Bxdf::eval`] at the vertex's wavelengths.
    #[inline]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> SampledSpectrum {
        match &self.reflectance {
            Some(r) => Lambertian::eval_with(wo, wi, r),
            None => self.bsdf.eval(wo, wi, self.wl),
        }
    }

    /// [`Bxdf::sample`] at the vertex's wavelengths.
    #[inline]
    pub fn sample(&self, wo: Vec3, u: [f64; 2], uc: f64) -> Option<BsdfSample> {
        match &self.reflectance {
            Some(r) => Lambertian::sample_with(wo, u, r),
            None => self.bsdf.sample(wo, u, uc, self.wl),
        }
    }

    /// [`SampledBsdf::new`] with a Lambertian's reflectance at `wl` already known (`known`,
    /// as [`SampledBsdf::reflectance`] gave it), else evaluated here.
    #[inline]
    pub fn with_known(bsdf: &'a Bsdf, wl: &'a Wavelengths, known: Option<SampledSpectrum>) -> Self {
        Self::with_reflectance(bsdf, wl, |r| known.unwrap_or_else(|| r.sample(wl)))
    }

    /// A Lambertian's reflectance at the vertex's wavelengths (None for other BSDFs), for a
    /// caller that keeps it with the vertex.
    #[inline]
    pub fn reflectance(&self) -> Option<SampledSpectrum> {
        self.reflectance
    }

    /// [`Bxdf::pdf`] at the vertex's wavelengths.
    #[inline]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f64 {
        self.bsdf.pdf(wo, wi, self.wl)
    }
}

impl Bxdf for Bsdf {
    #[inline]
    fn eval(&self, wo: Vec3, wi: Vec3, wl: &Wavelengths) -> SampledSpectrum {
        each!(self, b => b.eval(wo, wi, wl))
    }
    #[inline]
    fn sample(&self, wo: Vec3, u: [f64; 2], uc: f64, wl: &Wavelengths) -> Option<BsdfSample> {
        each!(self, b => b.sample(wo, u, uc, wl))
    }
    #[inline]
    fn pdf(&self, wo: Vec3, wi: Vec3, wl: &Wavelengths) -> f64 {
        each!(self, b => b.pdf(wo, wi, wl))
    }
    #[inline]
    fn eta(&self, w: Vec3, wl: &Wavelengths) -> SampledSpectrum {
        each!(self, b => b.eta(w, wl))
    }
    fn roughness(&self) -> f64 {
        each!(self, b => b.roughness())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spectrum::Spectrum;

    #[test]
    fn sampled_bsdf_gives_the_bsdfs_own_values() {
        // a tabulated reflectance, so that a wrong or stale cached spectrum would show
        let r = Spectrum::tabulated(
            vec![400.0, 500.0, 600.0, 700.0],
            vec![0.2, 0.5, 0.7, 0.4],
            crate::spectrum::Outside::Zero,
            1.0,
        )
        .unwrap();
        let bsdfs = [
            Bsdf::Diffuse(Lambertian { reflectance: r }),
            Bsdf::Dielectric(Dielectric {
                ior: Ior::Constant(1.5),
                microfacet: None,
            }),
        ];
        let wo = Vec3::new(0.3, 0.1, 0.9).normalize();
        let wi = Vec3::new(-0.2, 0.4, 0.7).normalize();
        for u in [0.1, 0.45, 0.8] {
            let wl = Wavelengths::sample_visible(u);
            for b in &bsdfs {
                let at = SampledBsdf::new(b, &wl);
                assert_eq!(at.eval(wo, wi), b.eval(wo, wi, &wl));
                assert_eq!(at.pdf(wo, wi), b.pdf(wo, wi, &wl));
                assert_eq!(
                    at.sample(wo, [0.3, 0.6], 0.4),
                    b.sample(wo, [0.3, 0.6], 0.4, &wl)
                );
            }
        }
    }
}
