//! Fresnel reflectance of a smooth interface for unpolarised light, and refractive-index
//! models. Indices are relative: η = η_transmitted / η_incident (unitless).

use crate::math::Vec3;

/// Refractive index of a dielectric as a function of wavelength.
#[derive(Debug, Clone, PartialEq)]
pub enum Ior {
    /// The same index at every wavelength.
    Constant(f64),
    /// Sellmeier's dispersion formula n²(λ) = 1 + Σ Bᵢλ²/(λ² − Cᵢ), λ in µm, Cᵢ in µm²
    /// (Sellmeier 1871, Ann. Phys. 219, 272; form as in the SCHOTT optical glass catalogue).
    Sellmeier {
        /// B coefficients (unitless).
        b: [f64; 3],
        /// C coefficients, µm².
        c: [f64; 3],
    },
}

impl Ior {
    /// SCHOTT N-BK7 (SCHOTT Zemax catalogue 2017-01-20b, via the refractiveindex.info
    /// database; reference/glasses/README.md).
    pub const BK7: Ior = Ior::Sellmeier {
        b: [1.039_612_12, 0.231_792_344, 1.010_469_45],
        c: [0.006_000_698_67, 0.020_017_914_4, 103.560_653],
    };
    /// Fused silica (Malitson 1965, JOSA 55, 1205).
    pub const FUSED_SILICA: Ior = Ior::Sellmeier {
        b: [0.696_166_3, 0.407_942_6, 0.897_479_4],
        c: [0.004_679_148, 0.013_512_06, 97.934],
    };

    /// The index at `lambda` nm.
    pub fn eval(&self, lambda: f64) -> f64 {
        match self {
            Ior::Constant(n) => *n,
            Ior::Sellmeier { b, c } => {
                let l2 = (lambda * 1e-3) * (lambda * 1e-3);
                let n2 = 1.0 + (0..3).map(|i| b[i] * l2 / (l2 - c[i])).sum::<f64>();
                n2.max(0.0).sqrt()
            }
        }
    }

    /// True when the index varies with wavelength (so refraction separates wavelengths).
    pub fn is_dispersive(&self) -> bool {
        !matches!(self, Ior::Constant(_))
    }
}

/// Reflectance of a dielectric interface at incidence cosine `cos_i` ∈ [0, 1] with relative
/// index `eta` = η_t/η_i. Returns (F, cos θt); total internal reflection gives (1, 0).
/// Born & Wolf, *Principles of Optics*, 7th ed., §1.5.2, eqs. (21): r_s and r_p squared and
/// averaged; Snell's law for cos θt.
pub fn dielectric(cos_i: f64, eta: f64) -> (f64, f64) {
    let cos_i = cos_i.clamp(0.0, 1.0);
    let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
    if sin2_t >= 1.0 {
        return (1.0, 0.0);
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    let rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    (0.5 * (rs * rs + rp * rp), cos_t)
}

/// A complex number, only what the conductor Fresnel equations need.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Complex {
    re: f64,
    im: f64,
}

impl Complex {
    fn new(re: f64, im: f64) -> Self {
        Complex { re, im }
    }
    fn add(self, o: Self) -> Self {
        Complex::new(self.re + o.re, self.im + o.im)
    }
    fn sub(self, o: Self) -> Self {
        Complex::new(self.re - o.re, self.im - o.im)
    }
    fn mul(self, o: Self) -> Self {
        Complex::new(
            self.re * o.re - self.im * o.im,
            self.re * o.im + self.im * o.re,
        )
    }
    fn norm2(self) -> f64 {
        self.re * self.re + self.im * self.im
    }
    /// |a/b|² without forming the quotient.
    fn ratio_norm2(a: Self, b: Self) -> f64 {
        let d = b.norm2();
        if d == 0.0 {
            1.0
        } else {
            a.norm2() / d
        }
    }
    /// Principal square root (real part ≥ 0).
    fn sqrt(self) -> Self {
        let r = self.norm2().sqrt();
        let re = (0.5 * (r + self.re)).max(0.0).sqrt();
        let im = (0.5 * (r - self.re)).max(0.0).sqrt();
        Complex::new(re, if self.im < 0.0 { -im } else { im })
    }
}

/// Reflectance of a conductor with complex index η = n + i k (relative to the outside medium)
/// at incidence cosine `cos_i` ∈ [0, 1]. Born & Wolf, 7th ed., §14.2 (the Fresnel formulae
/// with a complex index): r_s = (cos θ − w)/(cos θ + w), r_p = (η² cos θ − w)/(η² cos θ + w),
/// w = √(η² − sin² θ).
pub fn conductor(cos_i: f64, n: f64, k: f64) -> f64 {
    let c = cos_i.clamp(0.0, 1.0);
    let eta = Complex::new(n, k);
    let eta2 = eta.mul(eta);
    let w = eta2.sub(Complex::new(1.0 - c * c, 0.0)).sqrt();
    let cc = Complex::new(c, 0.0);
    let rs = Complex::ratio_norm2(cc.sub(w), cc.add(w));
    let e2c = eta2.mul(cc);
    let rp = Complex::ratio_norm2(e2c.sub(w), e2c.add(w));
    (0.5 * (rs + rp)).clamp(0.0, 1.0)
}

/// Mirror reflection of `w` about the unit normal `m`: 2(w·m)m − w.
#[inline]
pub fn reflect(w: Vec3, m: Vec3) -> Vec3 {
    m * (2.0 * w.dot(m)) - w
}

/// Refraction of `w` (pointing away from the surface on the side `m` points to) through a
/// facet with normal `m`, relative index `eta` = η_t/η_i and transmitted cosine `cos_t` from
/// [`dielectric`]; the result points away from the surface on the other side (Snell's law in
/// vector form: t = −w/η + (cos θi/η − cos θt) m).
#[inline]
pub fn refract(w: Vec3, m: Vec3, eta: f64, cos_t: f64) -> Vec3 {
    let cos_i = w.dot(m);
    -w / eta + m * (cos_i / eta - cos_t)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dielectric_known_values() {
        // normal incidence ((η−1)/(η+1))²
        let (f, c) = dielectric(1.0, 1.5);
        assert!((f - 0.04).abs() < 1e-15 && (c - 1.0).abs() < 1e-15);
        // Brewster angle: r_p = 0, F = r_s²/2
        let tb = 1.5f64.atan();
        let (f, _) = dielectric(tb.cos(), 1.5);
        let ct = (1.0 - tb.sin().powi(2) / 2.25).sqrt();
        let rs = (tb.cos() - 1.5 * ct) / (tb.cos() + 1.5 * ct);
        assert!((f - 0.5 * rs * rs).abs() < 1e-15);
        // total internal reflection from inside glass beyond the critical angle
        assert_eq!(dielectric(0.5, 1.0 / 1.5), (1.0, 0.0));
        // grazing and index 1
        assert_eq!(dielectric(0.0, 1.5).0, 1.0);
        assert!(dielectric(0.3, 1.0).0 < 1e-30);
        // Fresnel reciprocity: F seen from either side for Snell-related angles
        let (f1, ct) = dielectric(0.7, 1.5);
        let (f2, _) = dielectric(ct, 1.0 / 1.5);
        assert!((f1 - f2).abs() < 1e-14);
    }

    #[test]
    fn conductor_limits() {
        // k = 0 reduces to the dielectric formula
        for c in [1.0, 0.8, 0.3, 0.01] {
            assert!((conductor(c, 1.5, 0.0) - dielectric(c, 1.5).0).abs() < 1e-14);
        }
        // normal incidence ((n−1)² + k²)/((n+1)² + k²)
        let f = conductor(1.0, 0.2, 3.0);
        let e = (0.64 + 9.0) / (1.44 + 9.0);
        assert!((f - e).abs() < 1e-14);
        assert_eq!(conductor(0.0, 0.2, 3.0), 1.0);
        // huge k: a perfect mirror
        assert!(conductor(0.5, 1.0, 1e6) > 1.0 - 1e-5);
    }

    #[test]
    fn sellmeier_bk7_catalogue_values() {
        // SCHOTT N-BK7: n(587.56 nm) = 1.516800, n(486.13) = 1.522376, n(656.27) = 1.514322
        let bk7 = Ior::Sellmeier {
            b: [1.039_612_12, 0.231_792_344, 1.010_469_45],
            c: [0.006_000_698_67, 0.020_017_914_4, 103.560_653],
        };
        for (l, n) in [(587.56, 1.516800), (486.13, 1.522376), (656.27, 1.514322)] {
            assert!((bk7.eval(l) - n).abs() < 1e-6, "{l}: {}", bk7.eval(l));
        }
        assert!(bk7.is_dispersive() && !Ior::Constant(1.5).is_dispersive());
    }

    #[test]
    fn refraction_obeys_snell() {
        let w = Vec3::new(0.6, 0.0, 0.8);
        let (_, ct) = dielectric(0.8, 1.5);
        let t = refract(w, Vec3::Z, 1.5, ct);
        assert!((t.length() - 1.0).abs() < 1e-14);
        assert!(t.z < 0.0 && (t.x.abs() * 1.5 - 0.6).abs() < 1e-14);
    }
}
