//! Observers: how a spectral radiance sample becomes CIE XYZ and linear sRGB on the film.
//!
//! Two renderers that agree on spectral radiance can still disagree on RGB by more than
//! their noise in channels near zero (the green channel of the red wall, for instance),
//! because they tabulate the colour-matching functions, normalise Y and round the XYZ → sRGB
//! matrix differently. An [`Observer`] names one such pipeline, so that an image can be
//! rendered with the pipeline of the renderer it is compared with and the comparison tests
//! radiance, not colour conversion.

use super::cie;
use super::color::XYZ_TO_SRGB;
use super::{Spectrum, LAMBDA_MAX, LAMBDA_MIN};
use std::sync::Arc;

/// Three spectral response curves that replace x̄, ȳ, z̄: the film's X, Y, Z channels then
/// hold ∫ L(λ) rₖ(λ) dλ (no normalisation), and R, G, B repeat them.
#[derive(Debug, Clone, PartialEq)]
pub struct Responses {
    /// The curves (unitless sensitivities; a zero curve fills an unused channel).
    pub curves: [Spectrum; 3],
    /// ∫ rₖ dλ over 360–830 nm, nm (trapezoid at 0.05 nm).
    pub integrals: [f64; 3],
}

impl Responses {
    /// Responses from three curves.
    pub fn new(curves: [Spectrum; 3]) -> Self {
        let integrals = std::array::from_fn(|k| {
            let n = ((LAMBDA_MAX - LAMBDA_MIN) / 0.05).round() as usize;
            let h = (LAMBDA_MAX - LAMBDA_MIN) / n as f64;
            (0..=n)
                .map(|i| {
                    let w = if i == 0 || i == n { 0.5 } else { 1.0 };
                    w * curves[k].eval(LAMBDA_MIN + i as f64 * h)
                })
                .sum::<f64>()
                * h
        });
        Responses { curves, integrals }
    }
}

/// A spectrum-to-colour pipeline.
#[derive(Debug, Clone, PartialEq, Default)]
pub enum Observer {
    /// furnace's own: the CIE 1931 2° table at 1 nm with linear interpolation, Y normalised
    /// by its 1 nm sum (106.857 nm), Lindbloom's 7-digit IEC 61966-2-1 sRGB matrix.
    #[default]
    Cie1931,
    /// Mitsuba 3's spectral film (checked against 3.9.1): the same CIE 1931 table sampled at
    /// 5 nm (Mitsuba's 95-entry table equals our 1 nm rows at multiples of 5 nm to 6e-8)
    /// with linear interpolation in between, Y normalised by 1/106.7502593994140625
    /// (`mi.MI_CIE_Y_NORMALIZATION`), and Mitsuba's 6-digit sRGB matrix (`mi.xyz_to_srgb`).
    Mitsuba3,
    /// Camera or filter responses (the `measured` check kind): channels are band signals.
    Responses(Arc<Responses>),
}

/// Mitsuba 3's XYZ → linear sRGB matrix, as `mi.xyz_to_srgb` returns it for unit XYZ vectors.
const MITSUBA_XYZ_TO_SRGB: [[f64; 3]; 3] = [
    [3.24048, -1.53715, -0.498535],
    [-0.969256, 1.87599, 0.041556],
    [0.055648, -0.204043, 1.05731],
];

/// Mitsuba 3's ∫ȳ dλ normalisation constant, nm (`1 / mi.MI_CIE_Y_NORMALIZATION`).
const MITSUBA_Y_INTEGRAL: f64 = 106.750_259_399_414_06;

/// Table step of the Mitsuba 3 pipeline, nm.
const MITSUBA_STEP: usize = 5;

impl Observer {
    /// All observers with their names as written in manifests and on the command line.
    pub const ALL: [(&'static str, Observer); 2] = [
        ("cie1931", Observer::Cie1931),
        ("mitsuba3", Observer::Mitsuba3),
    ];

    /// The observer called `name`, if any.
    pub fn from_name(name: &str) -> Option<Observer> {
        Self::ALL
            .iter()
            .find(|(n, _)| *n == name)
            .map(|(_, o)| o.clone())
    }

    /// The name as written in manifests (`responses` for custom curves).
    pub fn name(&self) -> &'static str {
        match self {
            Observer::Cie1931 => "cie1931",
            Observer::Mitsuba3 => "mitsuba3",
            Observer::Responses(_) => "responses",
        }
    }

    /// (x̄, ȳ, z̄) at `lambda` nm; zero outside 360–830 nm.
    #[inline]
    pub fn cmf(&self, lambda: f64) -> [f64; 3] {
        let t = cie::tables();
        match self {
            Observer::Cie1931 => t.cmf(lambda),
            Observer::Mitsuba3 => {
                let x = (lambda - LAMBDA_MIN) / MITSUBA_STEP as f64;
                let last = (t.len() - 1) / MITSUBA_STEP;
                if !(0.0..=last as f64).contains(&x) {
                    return [0.0; 3];
                }
                // (through i64, as in CieTables::cmf; x >= 0 here)
                let i = (x as i64 as usize).min(last - 1);
                let f = x - i as f64;
                let (a, b) = (t.row(i * MITSUBA_STEP), t.row((i + 1) * MITSUBA_STEP));
                std::array::from_fn(|k| a[k] + f * (b[k] - a[k]))
            }
            Observer::Responses(r) => std::array::from_fn(|k| r.curves[k].eval(lambda)),
        }
    }

    /// ∫ȳ dλ, nm: XYZ = ∫ L (x̄, ȳ, z̄) dλ divided by this, so that a flat radiance of 1 has
    /// Y ≈ 1.
    pub fn y_integral(&self) -> f64 {
        match self {
            Observer::Cie1931 => cie::tables().y_integral(),
            Observer::Mitsuba3 => MITSUBA_Y_INTEGRAL,
            Observer::Responses(_) => 1.0,
        }
    }

    /// XYZ of a constant spectrum of 1 (what grey mode multiplies radiance by): the exact
    /// integral of this observer's interpolated table over 360–830 nm, normalised.
    pub fn white(&self) -> [f64; 3] {
        let t = cie::tables();
        match self {
            // The 1 nm sum furnace has always used (equal to the trapezoid up to the end rows,
            // which are ~1e-4 of the peak).
            Observer::Cie1931 => t.spectrum_to_xyz(&Spectrum::Constant(1.0)),
            Observer::Responses(r) => r.integrals,
            Observer::Mitsuba3 => {
                // Trapezoid over 5 nm rows: exact for the piecewise-linear table.
                let mut acc = [0.0; 3];
                let last = (t.len() - 1) / MITSUBA_STEP;
                for i in 0..last {
                    let (a, b) = (t.row(i * MITSUBA_STEP), t.row((i + 1) * MITSUBA_STEP));
                    for k in 0..3 {
                        acc[k] += 0.5 * (a[k] + b[k]) * MITSUBA_STEP as f64;
                    }
                }
                acc.map(|v| v / MITSUBA_Y_INTEGRAL)
            }
        }
    }

    /// Linear sRGB → XYZ: the inverse of [`Observer::xyz_to_rgb`] (identity for responses).
    pub fn rgb_to_xyz(&self, rgb: [f64; 3]) -> [f64; 3] {
        let inv = match self {
            Observer::Cie1931 => &SRGB_TO_XYZ,
            Observer::Mitsuba3 => &MITSUBA_SRGB_TO_XYZ,
            Observer::Responses(_) => return rgb,
        };
        std::array::from_fn(|r| inv[r][0] * rgb[0] + inv[r][1] * rgb[1] + inv[r][2] * rgb[2])
    }

    /// XYZ → linear sRGB with this pipeline's matrix.
    #[inline]
    pub fn xyz_to_rgb(&self, xyz: [f64; 3]) -> [f64; 3] {
        let m = match self {
            Observer::Cie1931 => &XYZ_TO_SRGB,
            Observer::Mitsuba3 => &MITSUBA_XYZ_TO_SRGB,
            Observer::Responses(_) => return xyz,
        };
        std::array::from_fn(|r| m[r][0] * xyz[0] + m[r][1] * xyz[1] + m[r][2] * xyz[2])
    }
}

/// Inverse of a 3×3 matrix by cofactors (the sRGB matrices are well conditioned).
/// Evaluated at compile time for the two matrices ([`SRGB_TO_XYZ`], [`MITSUBA_SRGB_TO_XYZ`]).
const fn invert3(m: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    const fn cof(m: &[[f64; 3]; 3], r: usize, k: usize) -> f64 {
        let (r1, r2) = ((r + 1) % 3, (r + 2) % 3);
        let (k1, k2) = ((k + 1) % 3, (k + 2) % 3);
        m[r1][k1] * m[r2][k2] - m[r1][k2] * m[r2][k1]
    }
    let det = m[0][0] * cof(m, 0, 0) + m[0][1] * cof(m, 0, 1) + m[0][2] * cof(m, 0, 2);
    let mut inv = [[0.0; 3]; 3];
    let mut r = 0;
    while r < 3 {
        let mut k = 0;
        while k < 3 {
            inv[r][k] = cof(m, k, r) / det;
            k += 1;
        }
        r += 1;
    }
    inv
}

/// Linear sRGB → XYZ for furnace's pipeline.
const SRGB_TO_XYZ: [[f64; 3]; 3] = invert3(&XYZ_TO_SRGB);
/// Linear sRGB → XYZ for Mitsuba 3's pipeline.
const MITSUBA_SRGB_TO_XYZ: [[f64; 3]; 3] = invert3(&MITSUBA_XYZ_TO_SRGB);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rgb_to_xyz_inverts_xyz_to_rgb() {
        for o in [Observer::Cie1931, Observer::Mitsuba3] {
            let xyz = [0.3, 0.5, 0.7];
            let back = o.rgb_to_xyz(o.xyz_to_rgb(xyz));
            for k in 0..3 {
                assert!((back[k] - xyz[k]).abs() < 1e-12, "{back:?}");
            }
        }
    }

    #[test]
    fn names_round_trip() {
        for (n, o) in Observer::ALL {
            assert_eq!(Observer::from_name(n), Some(o.clone()));
            assert_eq!(o.name(), n);
        }
        assert_eq!(Observer::from_name("cie2006"), None);
    }

    #[test]
    fn mitsuba_table_agrees_with_1nm_table_at_5nm_rows_and_is_linear_between() {
        let (m, c) = (Observer::Mitsuba3, Observer::Cie1931);
        for l in (360..=830).step_by(5) {
            assert_eq!(m.cmf(l as f64), c.cmf(l as f64));
        }
        // Mitsuba 3.9.1: mi.cie1931_xyz(552.5) = (0.47275, 0.997475, 0.00725).
        let v = m.cmf(552.5);
        for (a, b) in v.iter().zip([0.47275, 0.997475, 0.00725]) {
            assert!((a - b).abs() < 1e-6, "{v:?}");
        }
        assert_eq!(m.cmf(359.9), [0.0; 3]);
        assert_eq!(m.cmf(830.1), [0.0; 3]);
        assert!(m.cmf(830.0)[1] > 0.0);
    }

    #[test]
    fn white_points_differ_by_the_normalisation_ratio() {
        // Both tables integrate to 106.857 nm; Mitsuba divides by 106.750, so its flat
        // spectrum reads 0.1 % brighter: the ratio the README quotes.
        let (m, c) = (Observer::Mitsuba3.white(), Observer::Cie1931.white());
        assert!((c[1] - 1.0).abs() < 1e-12);
        assert!((m[1] / c[1] - 106.857 / 106.7503).abs() < 2e-5, "{m:?}");
        // Mitsuba 3.9.1 renders a flat spectrum of 1 as sRGB (1.2066, 0.9492, 0.9076) ± 0.3 %.
        let rgb = Observer::Mitsuba3.xyz_to_rgb(m);
        for (a, b) in rgb.iter().zip([1.2066, 0.9492, 0.9076]) {
            assert!((a / b - 1.0).abs() < 4e-3, "{rgb:?}");
        }
    }

    #[test]
    fn responses_integrate_radiance_against_their_curves() {
        let tri = Spectrum::tabulated(
            vec![500.0, 520.0, 540.0],
            vec![0.0, 1.0, 0.0],
            crate::spectrum::Outside::Zero,
            1.0,
        )
        .unwrap();
        let o = Observer::Responses(Arc::new(Responses::new([
            tri,
            Spectrum::Constant(1.0),
            Spectrum::Constant(0.0),
        ])));
        let w = o.white();
        assert!(
            (w[0] - 20.0).abs() < 1e-9 && (w[1] - 470.0).abs() < 1e-9 && w[2] == 0.0,
            "{w:?}"
        );
        assert_eq!(o.y_integral(), 1.0);
        assert_eq!(o.xyz_to_rgb([1.0, 2.0, 3.0]), [1.0, 2.0, 3.0]);
        assert_eq!(o.cmf(520.0), [1.0, 1.0, 0.0]);
        assert_eq!(o.name(), "responses");
    }
}
