//! The CIE 1931 2° standard observer (1 nm, 360–830 nm) and the CIE D65 illuminant (5 nm),
//! compiled in from `reference/cie/` (provenance in `reference/cie/PROVENANCE.md`).
//!
//! XYZ here are normalised so that a constant spectral radiance of 1 W·sr⁻¹·m⁻²·nm⁻¹ has
//! Y = 1: X = ∫ L x̄ dλ / ∫ ȳ dλ. Multiply Y by [`CieTables::y_integral`] for the
//! ȳ-weighted radiance in W·sr⁻¹·m⁻², and by a further 683 lm/W for luminance in cd/m².

use super::{Outside, Spectrum, LAMBDA_MIN};
use std::sync::OnceLock;

const CMF_CSV: &str = include_str!("../../reference/cie/cie1931_2deg_cmf_1nm.csv");
const D65_CSV: &str = include_str!("../../reference/cie/cie_illuminant_d65_5nm.csv");

/// The colour-matching functions at 1 nm steps from 360 nm.
#[derive(Debug)]
pub struct CieTables {
    xyz: Vec<[f64; 3]>,
    y_integral: f64,
}

/// The compiled-in CIE 1931 tables, parsed once.
pub fn tables() -> &'static CieTables {
    static TABLES: OnceLock<CieTables> = OnceLock::new();
    TABLES.get_or_init(|| {
        let rows = parse_csv(CMF_CSV, 4);
        let xyz: Vec<[f64; 3]> = rows.iter().map(|r| [r[1], r[2], r[3]]).collect();
        assert_eq!(rows[0][0], LAMBDA_MIN, "CMF table must start at 360 nm");
        assert_eq!(xyz.len(), 471, "CMF table must have 471 rows at 1 nm");
        // Riemann sum at 1 nm: the table's own normalisation (Σ ȳ Δλ ≈ 106.857 nm).
        let y_integral = xyz.iter().map(|v| v[1]).sum::<f64>();
        CieTables { xyz, y_integral }
    })
}

impl CieTables {
    /// (x̄, ȳ, z̄) at `lambda` nm by linear interpolation; zero outside 360–830 nm.
    #[inline]
    pub fn cmf(&self, lambda: f64) -> [f64; 3] {
        let x = lambda - LAMBDA_MIN;
        if !(0.0..=(self.xyz.len() - 1) as f64).contains(&x) {
            return [0.0; 3];
        }
        // (through i64: f64 → u64 has no single x86-64 instruction; x >= 0 here)
        let i = (x as i64 as usize).min(self.xyz.len() - 2);
        let t = x - i as f64;
        let (a, b) = (self.xyz[i], self.xyz[i + 1]);
        [
            a[0] + t * (b[0] - a[0]),
            a[1] + t * (b[1] - a[1]),
            a[2] + t * (b[2] - a[2]),
        ]
    }

    /// Number of 1 nm rows (471: 360–830 nm).
    pub fn len(&self) -> usize {
        self.xyz.len()
    }

    /// Always false: the compiled-in table has 471 rows.
    pub fn is_empty(&self) -> bool {
        self.xyz.is_empty()
    }

    /// (x̄, ȳ, z̄) of row `i` (wavelength 360 + i nm).
    pub fn row(&self, i: usize) -> [f64; 3] {
        self.xyz[i]
    }

    /// ∫ ȳ dλ over 360–830 nm in nm (the XYZ normalisation constant).
    pub fn y_integral(&self) -> f64 {
        self.y_integral
    }

    /// XYZ of a spectrum by 1 nm quadrature over 360–830 nm, normalised as in the module doc.
    pub fn spectrum_to_xyz(&self, s: &Spectrum) -> [f64; 3] {
        self.function_to_xyz(|l| s.eval(l))
    }

    /// XYZ of `s` as the exact integral ∫ L(λ) (x̄, ȳ, z̄)(λ) dλ over 360–830 nm of the
    /// spectrum times the linearly interpolated table, normalised by [`Self::y_integral`]: what
    /// a renderer sampling λ continuously estimates. Tables and constants are integrated
    /// exactly (both factors are linear between the merged breakpoints, so Simpson's rule is
    /// exact on each piece); a blackbody by Simpson's rule on 0.5 nm pieces. It differs from
    /// the CIE 1 nm summation ([`Self::spectrum_to_xyz`], CIE 15:2004 §7) by half a row at each
    /// end of the range and at each discontinuity of `s` (a band's edges): negligible for
    /// smooth spectra, 20 % for a 5 nm band.
    pub fn integral_xyz(&self, s: &Spectrum) -> [f64; 3] {
        let (lo, hi) = (LAMBDA_MIN, LAMBDA_MIN + (self.xyz.len() - 1) as f64);
        let mut cuts: Vec<f64> = (0..self.xyz.len()).map(|i| lo + i as f64).collect();
        match s {
            Spectrum::Tabulated { wavelengths, .. } => {
                cuts.extend(wavelengths.iter().copied().filter(|w| *w > lo && *w < hi))
            }
            Spectrum::Blackbody { .. } => {
                cuts.extend((0..self.xyz.len() - 1).map(|i| lo + i as f64 + 0.5))
            }
            Spectrum::Constant(_) => {}
        }
        cuts.sort_by(f64::total_cmp);
        cuts.dedup();
        let mut acc = [0.0; 3];
        for w in cuts.windows(2) {
            let (a, b) = (w[0], w[1]);
            let h = b - a;
            // one-sided values at the piece's ends, so a step at a breakpoint counts exactly
            let (ea, eb) = (a + h * 1e-9, b - h * 1e-9);
            let m = 0.5 * (a + b);
            let (la, lm, lb) = (s.eval(ea), s.eval(m), s.eval(eb));
            let (ca, cm, cb) = (self.cmf(ea), self.cmf(m), self.cmf(eb));
            for k in 0..3 {
                acc[k] += h / 6.0 * (la * ca[k] + 4.0 * lm * cm[k] + lb * cb[k]);
            }
        }
        acc.map(|a| a / self.y_integral)
    }

    /// XYZ of a spectral function of wavelength (nm), normalised as [`Self::spectrum_to_xyz`].
    pub fn function_to_xyz(&self, f: impl Fn(f64) -> f64) -> [f64; 3] {
        self.grid_to_xyz(|i| f(Self::grid_lambda(i)))
    }

    /// [`Self::function_to_xyz`] of a function given on the table's rows: `f(i)` is its value at
    /// [`Self::grid_lambda`]`(i)`, for i below [`Self::grid_len`].
    pub fn grid_to_xyz(&self, f: impl Fn(usize) -> f64) -> [f64; 3] {
        let mut acc = [0.0; 3];
        for (i, c) in self.xyz.iter().enumerate() {
            let v = f(i);
            for k in 0..3 {
                acc[k] += v * c[k];
            }
        }
        acc.map(|a| a / self.y_integral)
    }

    /// Rows of the table (one per whole nm from [`LAMBDA_MIN`]).
    pub fn grid_len(&self) -> usize {
        self.xyz.len()
    }

    /// Wavelength of row `i`, nm.
    pub fn grid_lambda(i: usize) -> f64 {
        LAMBDA_MIN + i as f64
    }
}

/// The CIE standard illuminant D65, relative spectral power (100 at 560 nm), 300–830 nm.
pub fn d65() -> Spectrum {
    let rows = parse_csv(D65_CSV, 2);
    Spectrum::tabulated(
        rows.iter().map(|r| r[0]).collect(),
        rows.iter().map(|r| r[1]).collect(),
        Outside::Zero,
        1.0,
    )
    .expect("compiled-in D65 table is valid")
}

/// Parses a compiled-in numeric CSV with a header row; panics only on a corrupt build input.
fn parse_csv(text: &str, columns: usize) -> Vec<Vec<f64>> {
    text.lines()
        .skip(1)
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            let row: Vec<f64> = l
                .split(',')
                .take(columns)
                .map(|v| {
                    v.trim()
                        .parse::<f64>()
                        .expect("compiled-in CIE table is numeric")
                })
                .collect();
            assert_eq!(row.len(), columns, "compiled-in CIE table row is short");
            row
        })
        .collect()
}

#[cfg(test)]
mod tests {

    #[test]
    fn integral_counts_narrow_bands_exactly_and_agrees_with_the_sum_for_smooth_spectra() {
        let t = tables();
        // a 1 nm band [500, 501]: ∫ ȳ over it = (ȳ(500) + ȳ(501))/2 for the interpolated table
        let band =
            Spectrum::tabulated(vec![500.0, 501.0], vec![1.0, 1.0], Outside::Zero, 1.0).unwrap();
        let want = 0.5 * (t.row(140)[1] + t.row(141)[1]) / t.y_integral();
        assert!((t.integral_xyz(&band)[1] / want - 1.0).abs() < 1e-9);
        // the 1 nm CIE sum counts both end rows in full: (ȳ(500) + ȳ(501))/y_integral, twice
        assert!((t.spectrum_to_xyz(&band)[1] / want - 2.0).abs() < 1e-2);
        // smooth spectra: the two agree to 1e-5 (the half end rows at 360 and 830 nm; z̄(360) is largest)
        for s in [
            Spectrum::Constant(1.0),
            Spectrum::blackbody(3000.0, 1e-3).unwrap(),
        ] {
            let (a, b) = (t.integral_xyz(&s), t.spectrum_to_xyz(&s));
            for k in 0..3 {
                assert!((a[k] / b[k] - 1.0).abs() < 1e-5, "{s:?}: {a:?} vs {b:?}");
            }
        }
    }

    use super::*;

    #[test]
    fn tables_have_known_values() {
        let t = tables();
        // CIE 1931 ȳ(555 nm) = 1.0 and x̄(600 nm) = 1.0622 (CIE 15:2004 table).
        assert!((t.cmf(555.0)[1] - 1.0).abs() < 1e-4);
        assert!((t.cmf(600.0)[0] - 1.0622).abs() < 1e-3);
        assert!(
            (t.y_integral() - 106.857).abs() < 1e-2,
            "{}",
            t.y_integral()
        );
        assert_eq!(t.cmf(359.0), [0.0; 3]);
        assert_eq!(t.cmf(831.0), [0.0; 3]);
    }

    #[test]
    fn equal_energy_white_is_neutral() {
        let xyz = tables().spectrum_to_xyz(&Spectrum::Constant(1.0));
        assert!((xyz[1] - 1.0).abs() < 1e-12);
        // illuminant E has chromaticity (1/3, 1/3)
        let s = xyz[0] + xyz[1] + xyz[2];
        assert!((xyz[0] / s - 1.0 / 3.0).abs() < 1e-3);
        assert!((xyz[1] / s - 1.0 / 3.0).abs() < 1e-3);
    }

    #[test]
    fn d65_chromaticity() {
        let xyz = tables().spectrum_to_xyz(&d65());
        let s = xyz[0] + xyz[1] + xyz[2];
        // CIE 15:2004 D65 white point, 2° observer: x = 0.31272, y = 0.32903
        assert!((xyz[0] / s - 0.31272).abs() < 2e-4);
        assert!((xyz[1] / s - 0.32903).abs() < 2e-4);
    }
}
