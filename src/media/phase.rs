//! Phase functions p(wo, wi) per steradian, normalised so ∫ p dω = 1. Directions both point
//! away from the scattering point: `wo` towards the viewer, `wi` towards the light; forward
//! scattering means wi ≈ −wo, so the scattering angle θ has cos θ = −wo·wi.

use crate::math::{frame::Frame, warp, Vec3, PI};

/// The direction at scattering-angle cosine `mu` from the forward direction −wo, at azimuth
/// `u` of a turn about it.
#[inline(always)]
fn scattered(wo: Vec3, mu: f64, u: f64) -> Vec3 {
    let sin = (1.0 - mu * mu).max(0.0).sqrt();
    let (sin_phi, cos_phi) = warp::sin_cos_turn(u);
    Frame::from_normal(-wo).to_world(Vec3::new(sin * cos_phi, sin * sin_phi, mu))
}

/// A sampled phase-function direction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PhaseSample {
    /// Sampled incident direction (unit).
    pub wi: Vec3,
    /// Its pdf per steradian (equal to p for an exactly sampled phase function).
    pub pdf: f64,
    /// p/pdf (1 for exact sampling).
    pub weight: f64,
}

/// A phase function.
pub trait Phase {
    /// p(wo, wi) per steradian.
    fn eval(&self, wo: Vec3, wi: Vec3) -> f64;
    /// Samples wi from two uniform numbers.
    fn sample(&self, wo: Vec3, u: [f64; 2]) -> PhaseSample;
    /// Pdf of sampling wi, per steradian.
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f64;
}

/// Henyey–Greenstein with asymmetry g in (−1, 1): mean cosine of the scattering angle = g
/// (Henyey & Greenstein 1941, ApJ 93, eq. 1).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HenyeyGreenstein {
    /// Asymmetry parameter, |g| < 1.
    pub g: f64,
}

impl HenyeyGreenstein {
    /// p as a function of the scattering-angle cosine μ: (1 − g²) / (4π (1 + g² − 2gμ)^{3/2}).
    /// The denominator is written (1 − g)² + 2g(1 − μ), which is exact near g → 1, μ → 1 where
    /// 1 + g² − 2gμ cancels catastrophically (DESIGN.md pitfall).
    pub fn eval_cos(&self, mu: f64) -> f64 {
        let g = self.g;
        let denom = (1.0 - g) * (1.0 - g) + 2.0 * g * (1.0 - mu);
        (1.0 - g) * (1.0 + g) / (4.0 * PI * denom * denom.sqrt())
    }

    /// Inverse-CDF sample of μ (Pharr, Jakob & Humphreys, PBR 3rd ed. §15.2.3, eq. 15.7 form):
    /// μ = (1 + g² − ((1 − g²)/(1 + g − 2g ξ))²)/(2g), μ = 1 − 2ξ for |g| < 1e-7.
    pub fn sample_cos(&self, xi: f64) -> f64 {
        let g = self.g;
        // Below 1e-7 HG equals the uniform phase function to ~3e-7 relative, while the general
        // formula would lose digits to cancellation (its error grows like ε/|g|).
        if g.abs() < 1e-7 {
            return 1.0 - 2.0 * xi;
        }
        let s = (1.0 - g * g) / (1.0 + g - 2.0 * g * xi);
        ((1.0 + g * g - s * s) / (2.0 * g)).clamp(-1.0, 1.0)
    }
}

impl Phase for HenyeyGreenstein {
    fn eval(&self, wo: Vec3, wi: Vec3) -> f64 {
        self.eval_cos(-wo.dot(wi))
    }

    fn sample(&self, wo: Vec3, u: [f64; 2]) -> PhaseSample {
        let mu = self.sample_cos(u[0]);
        PhaseSample {
            wi: scattered(wo, mu, u[1]),
            pdf: self.eval_cos(mu),
            weight: 1.0,
        }
    }

    fn pdf(&self, wo: Vec3, wi: Vec3) -> f64 {
        self.eval(wo, wi)
    }
}

/// The Rayleigh phase function p(μ) = 3(1 + μ²)/(16π) (Chandrasekhar 1960, *Radiative
/// Transfer*, §17, eq. 2 for unpolarised light), sampled exactly by inverting its CDF.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Rayleigh;

impl Rayleigh {
    /// p as a function of the scattering-angle cosine μ.
    pub fn eval_cos(mu: f64) -> f64 {
        3.0 * (1.0 + mu * mu) / (16.0 * PI)
    }

    /// μ with CDF(μ) = ξ: the root of μ³ + 3μ = 8ξ − 4, μ = A − 1/A with
    /// A = ∛(z + √(z² + 1)), z = 4ξ − 2 (Frisvad 2011, "Importance sampling the Rayleigh phase
    /// function", JOSA A 28(12), eq. 14 form). A ≥ ∛(√5 − 2) > 0, so there is no cancellation.
    pub fn sample_cos(xi: f64) -> f64 {
        let z = 4.0 * xi - 2.0;
        let a = (z + (z * z + 1.0).sqrt()).cbrt();
        (a - 1.0 / a).clamp(-1.0, 1.0)
    }
}

impl Phase for Rayleigh {
    fn eval(&self, wo: Vec3, wi: Vec3) -> f64 {
        Self::eval_cos(-wo.dot(wi))
    }
    fn sample(&self, wo: Vec3, u: [f64; 2]) -> PhaseSample {
        let mu = Self::sample_cos(u[0]);
        PhaseSample {
            wi: scattered(wo, mu, u[1]),
            pdf: Self::eval_cos(mu),
            weight: 1.0,
        }
    }
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f64 {
        self.eval(wo, wi)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stable_denominator_at_extreme_g() {
        let hg = HenyeyGreenstein { g: 0.9999 };
        let p = hg.eval_cos(1.0);
        // (1 − g²)/(4π(1 − g)³) = (1 + g)/(4π(1 − g)²)
        let exact = (1.0 + 0.9999) / (4.0 * PI * 1e-8);
        assert!((p / exact - 1.0).abs() < 1e-9, "{p} vs {exact}");
        assert!(hg.eval_cos(-1.0) > 0.0);
    }

    #[test]
    fn rayleigh_inverse_cdf_is_exact() {
        for k in 0..=20 {
            let xi = k as f64 / 20.0;
            let mu = Rayleigh::sample_cos(xi);
            // CDF(μ) = 1/2 + (3/8)(μ + μ³/3)
            let cdf = 0.5 + 0.375 * (mu + mu * mu * mu / 3.0);
            assert!((cdf - xi).abs() < 1e-12, "ξ {xi}: μ {mu}, CDF {cdf}");
        }
    }

    #[test]
    fn sampled_cosine_inverts_the_cdf() {
        for g in [-0.9, -0.3, 0.0, 0.5, 0.99] {
            let hg = HenyeyGreenstein { g };
            assert!((hg.sample_cos(0.0) - 1.0).abs() < 1e-9, "g {g}");
            assert!((hg.sample_cos(1.0) + 1.0).abs() < 1e-9, "g {g}");
        }
    }
}
