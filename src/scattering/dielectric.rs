//! Dielectric interfaces (glass, water): a smooth Fresnel interface or a rough GGX one
//! (Walter, Marschner, Li & Torrance 2007, "Microfacet models for refraction through rough
//! surfaces", EGSR). The normal points to the outside (index 1); the inside has index
//! `ior`(λ). `eval` carries radiance: transmitted radiance is scaled by (η_o/η_i)² (see
//! [`Bxdf::eta`]). Reciprocity and dispersion: docs/rendering.md, "`scattering::dielectric`".

use super::fresnel::{self, Ior};
use super::microfacet::Ggx;
use super::{BsdfSample, Bxdf};
use crate::math::Vec3;
use crate::spectrum::{SampledSpectrum, Wavelengths};

/// A smooth or GGX-rough dielectric interface.
#[derive(Debug, Clone, PartialEq)]
pub struct Dielectric {
    /// Refractive index of the inside (the side opposite the normal), relative to outside.
    pub ior: Ior,
    /// GGX microfacets, or None for a smooth interface (delta lobes).
    pub microfacet: Option<Ggx>,
}

/// The geometry of one (wo, wi) pair at one index, in the frame where wo.z > 0.
struct Pair {
    o: Vec3,
    i: Vec3,
    /// Microfacet normal, h.z > 0.
    h: Vec3,
    /// Index on wo's side and on the other side.
    eta_o: f64,
    eta_t: f64,
    reflect: bool,
}

impl Dielectric {
    /// True for the smooth (delta) interface.
    pub fn is_smooth(&self) -> bool {
        self.microfacet.is_none()
    }

    /// (wo, wi) mapped to the frame where wo is above the surface, with the microfacet
    /// normal that connects them (Walter et al. 2007, eq. 13 for reflection, eq. 16 for
    /// transmission: h ∝ −(η_o o + η_i i)); None when no facet does.
    fn pair(wo: Vec3, wi: Vec3, n: f64) -> Option<Pair> {
        if wo.z == 0.0 || wi.z == 0.0 {
            return None;
        }
        let s = wo.z.signum();
        let flip = |w: Vec3| Vec3::new(w.x, w.y, w.z * s);
        let (o, i) = (flip(wo), flip(wi));
        let (eta_o, eta_t) = if wo.z > 0.0 { (1.0, n) } else { (n, 1.0) };
        let reflect = i.z > 0.0;
        let raw = if reflect {
            o + i
        } else {
            -(o * eta_o + i * eta_t)
        };
        let len = raw.length();
        if len.is_nan() || len <= 0.0 {
            return None;
        }
        let h = raw / len * raw.z.signum();
        // the facet must face o, and i must lie on the facet side its hemisphere says
        if h.z <= 0.0 || o.dot(h) <= 0.0 || (i.dot(h) > 0.0) != reflect {
            return None;
        }
        Some(Pair {
            o,
            i,
            h,
            eta_o,
            eta_t,
            reflect,
        })
    }

    /// The pair of (wo, wi) at index `n` with its o·h, i·h and Fresnel reflectance at o·h.
    fn facet(wo: Vec3, wi: Vec3, n: f64) -> Option<(Pair, f64, f64, f64)> {
        let p = Self::pair(wo, wi, n)?;
        let (oh, ih) = (p.o.dot(p.h), p.i.dot(p.h));
        let (f, _) = fresnel::dielectric(oh, p.eta_t / p.eta_o);
        Some((p, oh, ih, f))
    }

    /// f of the rough interface `g` at one index `n` (radiance-carrying).
    fn eval_at(g: &Ggx, wo: Vec3, wi: Vec3, n: f64) -> f64 {
        Self::facet(wo, wi, n).map_or(0.0, |(p, oh, ih, f)| Self::f_of(g, &p, oh, ih, f))
    }

    /// f from a [`Self::facet`].
    fn f_of(g: &Ggx, p: &Pair, oh: f64, ih: f64, f: f64) -> f64 {
        let dg = g.d(p.h) * g.g1(p.o, p.h) * g.g1(p.i, p.h);
        let v = if p.reflect {
            // Walter et al. 2007, eq. 20
            f * dg / (4.0 * p.o.z * p.i.z)
        } else {
            // Walter et al. 2007, eq. 21 (η_o on the viewer's side carries radiance)
            let denom = p.eta_t * ih + p.eta_o * oh;
            (ih * oh / (p.o.z * p.i.z)).abs() * p.eta_o * p.eta_o * (1.0 - f) * dg / (denom * denom)
        };
        if v.is_finite() {
            v
        } else {
            0.0
        }
    }

    /// Pdf of sampling wi at index `n`: the visible-normal pdf times the Jacobian of the
    /// reflection (1/(4 o·h)) or refraction (η_t² |i·h|/(η_t i·h + η_o o·h)², Walter et al.
    /// 2007, eq. 17) mapping, times the probability of choosing that lobe (F or 1 − F).
    fn pdf_at(g: &Ggx, wo: Vec3, wi: Vec3, n: f64) -> f64 {
        Self::facet(wo, wi, n).map_or(0.0, |(p, oh, ih, f)| Self::pdf_of(g, &p, oh, ih, f))
    }

    /// The pdf from a [`Self::facet`].
    fn pdf_of(g: &Ggx, p: &Pair, oh: f64, ih: f64, f: f64) -> f64 {
        let dv = g.pdf_visible(p.o, p.h);
        let v = if p.reflect {
            f * dv / (4.0 * oh)
        } else {
            let denom = p.eta_t * ih + p.eta_o * oh;
            (1.0 - f) * dv * p.eta_t * p.eta_t * ih.abs() / (denom * denom)
        };
        if v.is_finite() {
            v
        } else {
            0.0
        }
    }
}

impl Bxdf for Dielectric {
    fn eval(&self, wo: Vec3, wi: Vec3, wl: &Wavelengths) -> SampledSpectrum {
        let Some(g) = &self.microfacet else {
            return SampledSpectrum::ZERO;
        };
        // one index for every wavelength: one evaluation (the same bits four times over)
        if !self.ior.is_dispersive() {
            return SampledSpectrum::splat(Self::eval_at(g, wo, wi, self.ior.eval(wl.lambda[0])));
        }
        SampledSpectrum(std::array::from_fn(|k| {
            Self::eval_at(g, wo, wi, self.ior.eval(wl.lambda[k]))
        }))
    }

    fn sample(&self, wo: Vec3, u: [f64; 2], uc: f64, wl: &Wavelengths) -> Option<BsdfSample> {
        if wo.z == 0.0 {
            return None;
        }
        let n0 = self.ior.eval(wl.lambda[0]);
        let s = wo.z.signum();
        let flip = |w: Vec3| Vec3::new(w.x, w.y, w.z * s);
        let o = flip(wo);
        let (eta_o, eta_t) = if wo.z > 0.0 { (1.0, n0) } else { (n0, 1.0) };
        let Some(g) = &self.microfacet else {
            let (f0, cos_t) = fresnel::dielectric(o.z, eta_t / eta_o);
            if uc < f0 {
                // Reflection: each wavelength's Fresnel over the hero's choice probability.
                let weight = SampledSpectrum(std::array::from_fn(|k| {
                    let n = self.ior.eval(wl.lambda[k]);
                    let (eo, et) = if wo.z > 0.0 { (1.0, n) } else { (n, 1.0) };
                    fresnel::dielectric(o.z, et / eo).0 / f0
                }));
                return Some(BsdfSample {
                    wi: Vec3::new(-wo.x, -wo.y, wo.z),
                    weight,
                    pdf: f0,
                    delta: true,
                });
            }
            let t = fresnel::refract(o, Vec3::Z, eta_t / eta_o, cos_t);
            // Radiance crossing into the viewer's side is scaled by (η_o/η_t)²; the other
            // wavelengths refract elsewhere and carry nothing along the hero's direction.
            let w0 = (eta_o / eta_t).powi(2);
            let weight = if self.ior.is_dispersive() {
                SampledSpectrum([w0, 0.0, 0.0, 0.0])
            } else {
                SampledSpectrum::splat(w0)
            };
            return Some(BsdfSample {
                wi: flip(t),
                weight,
                pdf: 1.0 - f0,
                delta: true,
            });
        };
        let m = g.sample_visible(o, u);
        let (f, cos_t) = fresnel::dielectric(o.dot(m), eta_t / eta_o);
        let i = if uc < f {
            fresnel::reflect(o, m)
        } else {
            fresnel::refract(o, m, eta_t / eta_o, cos_t)
        };
        if (uc < f) != (i.z > 0.0) || i.z == 0.0 {
            return None;
        }
        let wi = flip(i);
        // the hero's facet once, for its pdf and its f
        let (p, oh, ih, f0) = Self::facet(wo, wi, n0)?;
        let pdf = Self::pdf_of(g, &p, oh, ih, f0);
        if pdf.is_nan() || pdf <= 0.0 {
            return None;
        }
        let f = Self::f_of(g, &p, oh, ih, f0);
        let f = if self.ior.is_dispersive() {
            SampledSpectrum(std::array::from_fn(|k| match k {
                0 => f,
                _ => Self::eval_at(g, wo, wi, self.ior.eval(wl.lambda[k])),
            }))
        } else {
            SampledSpectrum::splat(f)
        };
        let weight = f * (wi.z.abs() / pdf);
        Some(BsdfSample {
            wi,
            weight,
            pdf,
            delta: false,
        })
    }

    /// The transmitted lobe narrows as the index approaches 1 (refraction through a facet
    /// tilted by θm deviates the ray by about (η − 1)θm), so the width is α·min(1, |η − 1|) at
    /// 550 nm.
    fn roughness(&self) -> f64 {
        self.microfacet.map_or(0.0, |g| g.alpha_x.min(g.alpha_y))
            * (self.ior.eval(550.0) - 1.0).abs().min(1.0)
    }

    fn pdf(&self, wo: Vec3, wi: Vec3, wl: &Wavelengths) -> f64 {
        let Some(g) = &self.microfacet else {
            return 0.0;
        };
        Self::pdf_at(g, wo, wi, self.ior.eval(wl.lambda[0]))
    }

    fn eta(&self, w: Vec3, wl: &Wavelengths) -> SampledSpectrum {
        if w.z >= 0.0 {
            SampledSpectrum::ONE
        } else {
            SampledSpectrum(std::array::from_fn(|k| self.ior.eval(wl.lambda[k])))
        }
    }
}
