//! Conductors (metals): a smooth mirror or a rough GGX microfacet reflector whose Fresnel
//! term uses the spectral complex index n + ik. Two-sided: the back side behaves as the
//! mirror image of the front (a metal sheet). Roughness 0 means smooth (a delta lobe).

use super::fresnel;
use super::microfacet::Ggx;
use super::{BsdfSample, Bxdf};
use crate::math::Vec3;
use crate::spectrum::{SampledSpectrum, Spectrum, Wavelengths};

/// How a conductor's Fresnel reflectance is obtained.
#[derive(Debug, Clone, PartialEq)]
pub enum ConductorFresnel {
    /// Complex index n + ik relative to the outside medium, per wavelength.
    Complex {
        /// Real part n.
        eta: Spectrum,
        /// Extinction coefficient k.
        k: Spectrum,
    },
    /// F = 1 at every angle (Mitsuba's material `none`): the lossless limit, for furnace tests.
    Perfect,
}

/// A smooth or GGX-rough conductor.
#[derive(Debug, Clone, PartialEq)]
pub struct Conductor {
    /// Fresnel model.
    pub fresnel: ConductorFresnel,
    /// GGX microfacets, or None for a smooth mirror (a delta lobe).
    pub microfacet: Option<Ggx>,
}

/// Mirrors `w` into the upper hemisphere (z ≥ 0).
#[inline]
pub(crate) fn upper(w: Vec3) -> Vec3 {
    Vec3::new(w.x, w.y, w.z.abs())
}

impl Conductor {
    /// True for the smooth (delta) conductor.
    pub fn is_smooth(&self) -> bool {
        self.microfacet.is_none()
    }

    /// Fresnel reflectance at incidence cosine `cos` per wavelength.
    pub fn fresnel(&self, cos: f64, wl: &Wavelengths) -> SampledSpectrum {
        match &self.fresnel {
            ConductorFresnel::Perfect => SampledSpectrum::ONE,
            ConductorFresnel::Complex { eta, k } => {
                let (n, k) = (eta.sample(wl), k.sample(wl));
                SampledSpectrum(std::array::from_fn(|i| {
                    fresnel::conductor(cos, n.0[i], k.0[i])
                }))
            }
        }
    }
}

impl Bxdf for Conductor {
    // Cook & Torrance 1982 (ACM ToG 1(1)) microfacet reflection f = D G F / (4 cos θo cos θi)
    // with the GGX D and Smith G of Walter et al. 2007 (EGSR), eq. 20.
    fn eval(&self, wo: Vec3, wi: Vec3, wl: &Wavelengths) -> SampledSpectrum {
        let Some(g) = &self.microfacet else {
            return SampledSpectrum::ZERO;
        };
        if wo.z * wi.z <= 0.0 {
            return SampledSpectrum::ZERO;
        }
        let (o, i) = (upper(wo), upper(wi));
        let h = (o + i).normalize();
        let s = g.d(h) * g.g1(o, h) * g.g1(i, h) / (4.0 * o.z * i.z);
        if s.is_nan() || s <= 0.0 {
            return SampledSpectrum::ZERO;
        }
        self.fresnel(o.dot(h), wl) * s
    }

    fn sample(&self, wo: Vec3, u: [f64; 2], _uc: f64, wl: &Wavelengths) -> Option<BsdfSample> {
        if wo.z == 0.0 {
            return None;
        }
        let flip = |w: Vec3| {
            if wo.z < 0.0 {
                Vec3::new(w.x, w.y, -w.z)
            } else {
                w
            }
        };
        let o = upper(wo);
        let Some(g) = &self.microfacet else {
            return Some(BsdfSample {
                wi: flip(Vec3::new(-o.x, -o.y, o.z)),
                weight: self.fresnel(o.z, wl),
                pdf: 1.0,
                delta: true,
            });
        };
        let m = g.sample_visible(o, u);
        let i = fresnel::reflect(o, m);
        if i.z <= 0.0 {
            return None;
        }
        // pdf = D_v(m)/(4 o·m) (Walter et al. 2007, eq. 14 Jacobian), so
        // weight = f cos θi / pdf = F G1(i).
        let pdf = g.d(m) * g.g1(o, m) / (4.0 * o.z);
        if pdf.is_nan() || pdf <= 0.0 {
            return None;
        }
        Some(BsdfSample {
            wi: flip(i),
            weight: self.fresnel(o.dot(m), wl) * g.g1(i, m),
            pdf,
            delta: false,
        })
    }

    fn roughness(&self) -> f64 {
        self.microfacet.map_or(0.0, |g| g.alpha_x.min(g.alpha_y))
    }

    fn pdf(&self, wo: Vec3, wi: Vec3, _wl: &Wavelengths) -> f64 {
        let Some(g) = &self.microfacet else {
            return 0.0;
        };
        if wo.z * wi.z <= 0.0 {
            return 0.0;
        }
        let (o, i) = (upper(wo), upper(wi));
        let h = (o + i).normalize();
        let p = g.d(h) * g.g1(o, h) / (4.0 * o.z);
        if p.is_finite() {
            p
        } else {
            0.0
        }
    }
}
