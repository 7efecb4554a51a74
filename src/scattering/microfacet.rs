//! The GGX (Trowbridge–Reitz) microfacet distribution with anisotropic roughness, Smith
//! masking and sampling of the visible normals. Directions are in the local frame with the
//! macro-normal +z; roughness α is the GGX parameter (Mitsuba's `alpha`, not α²).
//!
//! Masking–shadowing is Smith's *separable* form G = G1(wo)·G1(wi), the form Mitsuba 3's
//! `roughconductor`/`roughdielectric` use, so exported scenes compare like for like.

use crate::math::{Vec3, PI};

/// GGX distribution of microfacet normals.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ggx {
    /// Roughness along the local x axis.
    pub alpha_x: f64,
    /// Roughness along the local y axis.
    pub alpha_y: f64,
}

impl Ggx {
    /// The distribution for roughness (αx, αy), or None for 0 (a smooth surface, a delta lobe).
    pub fn rough(alpha_x: f64, alpha_y: f64) -> Option<Ggx> {
        (alpha_x > 0.0 || alpha_y > 0.0).then_some(Ggx { alpha_x, alpha_y })
    }

    /// D(m) per steradian of normals, normalised so that ∫ D(m) cos θm dωm = 1
    /// (Trowbridge & Reitz 1975, JOSA 65; anisotropic form: Heitz 2014, JCGT 3(2), eq. 85).
    pub fn d(&self, m: Vec3) -> f64 {
        if m.z <= 0.0 {
            return 0.0;
        }
        let (ax, ay) = (self.alpha_x, self.alpha_y);
        let t = (m.x / ax).powi(2) + (m.y / ay).powi(2) + m.z * m.z;
        1.0 / (PI * ax * ay * t * t)
    }

    /// Smith's Λ(v) for GGX (Heitz 2014, eq. 86), written as G1 = 2/(1 + √(1 + α²tan²θ)).
    /// Returns G1 for direction `v` and microfacet normal `m`, zero when `v` sees the back of
    /// the facet or lies in the macro-surface.
    pub fn g1(&self, v: Vec3, m: Vec3) -> f64 {
        if v.z == 0.0 || v.dot(m) * v.z <= 0.0 {
            return 0.0;
        }
        let a2 = ((self.alpha_x * v.x).powi(2) + (self.alpha_y * v.y).powi(2)) / (v.z * v.z);
        2.0 / (1.0 + (1.0 + a2).sqrt())
    }

    /// Samples a normal m from the distribution of normals visible from `v` (v.z > 0):
    /// D_v(m) = G1(v, m) max(0, v·m) D(m) / v.z (Heitz 2018, "Sampling the GGX distribution of
    /// visible normals", JCGT 7(4): stretch v to the α = 1 configuration, sample the
    /// projected hemisphere, unstretch).
    pub fn sample_visible(&self, v: Vec3, u: [f64; 2]) -> Vec3 {
        let vh = Vec3::new(self.alpha_x * v.x, self.alpha_y * v.y, v.z).normalize();
        let len2 = vh.x * vh.x + vh.y * vh.y;
        let t1 = if len2 > 0.0 {
            Vec3::new(-vh.y, vh.x, 0.0) / len2.sqrt()
        } else {
            Vec3::X
        };
        let t2 = vh.cross(t1);
        // A uniform point on the unit disk, its second coordinate squeezed onto the part of
        // the disk that the projection of the visible hemisphere covers.
        let r = u[0].sqrt();
        let phi = 2.0 * PI * u[1];
        let p1 = r * phi.cos();
        let s = 0.5 * (1.0 + vh.z);
        let p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * r * phi.sin();
        let nh = t1 * p1 + t2 * p2 + vh * (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt();
        Vec3::new(self.alpha_x * nh.x, self.alpha_y * nh.y, nh.z.max(0.0)).normalize()
    }

    /// Pdf per steradian of [`Ggx::sample_visible`] producing `m`.
    pub fn pdf_visible(&self, v: Vec3, m: Vec3) -> f64 {
        if v.z <= 0.0 {
            return 0.0;
        }
        self.g1(v, m) * v.dot(m).max(0.0) * self.d(m) / v.z
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::rng::SampleStream;

    fn sphere_quadrature(f: impl Fn(Vec3) -> f64, n: usize) -> f64 {
        // midpoint rule in (cos θ ∈ [0,1], φ)
        let mut s = 0.0;
        for i in 0..n {
            let mu = (i as f64 + 0.5) / n as f64;
            let r = (1.0 - mu * mu).sqrt();
            for j in 0..2 * n {
                let phi = (j as f64 + 0.5) * PI / n as f64;
                s += f(Vec3::new(r * phi.cos(), r * phi.sin(), mu));
            }
        }
        s * (1.0 / n as f64) * (PI / n as f64)
    }

    #[test]
    fn projected_area_normalisation() {
        for (ax, ay) in [(0.3, 0.3), (0.1, 0.5), (1.0, 1.0)] {
            let g = Ggx {
                alpha_x: ax,
                alpha_y: ay,
            };
            let i = sphere_quadrature(|m| g.d(m) * m.z, 1000);
            assert!((i - 1.0).abs() < 2e-3, "{ax} {ay}: {i}");
            // visible normals: ∫ D_v dω = 1 for any v
            let v = Vec3::new(0.5, 0.3, 0.7).normalize();
            let iv = sphere_quadrature(|m| g.pdf_visible(v, m), 1000);
            assert!((iv - 1.0).abs() < 2e-3, "{ax} {ay}: {iv}");
        }
    }

    #[test]
    fn visible_samples_are_unit_and_facing() {
        let g = Ggx {
            alpha_x: 0.2,
            alpha_y: 0.6,
        };
        let mut rng = SampleStream::new(3, 0, 0);
        for _ in 0..10_000 {
            let v = Vec3::new(
                rng.next_f64() - 0.5,
                rng.next_f64() - 0.5,
                rng.next_f64() + 1e-3,
            )
            .normalize();
            let m = g.sample_visible(v, rng.next_2d());
            assert!((m.length() - 1.0).abs() < 1e-12 && m.z >= 0.0 && v.dot(m) >= -1e-12);
        }
    }
}
