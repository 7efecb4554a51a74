//! Spectral curves: constant, piecewise-linear tables and Planck blackbodies, evaluated at
//! wavelengths in nm.

use super::{SampledSpectrum, Wavelengths, LAMBDA_MAX, LAMBDA_MIN, N_WAVELENGTHS};
use std::sync::Arc;

/// What a table returns outside its first and last wavelength.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outside {
    /// Zero outside the table (Mitsuba 3's convention for `wl:value` spectra).
    Zero,
    /// Hold the first/last value.
    Clamp,
}

/// A spectrum as a function of wavelength in nm; values in the unit of what it describes
/// (W·sr⁻¹·m⁻²·nm⁻¹ for radiance, W·sr⁻¹·nm⁻¹ for intensity, unitless for reflectance).
#[derive(Debug, Clone, PartialEq)]
pub enum Spectrum {
    /// The same value at every wavelength.
    Constant(f64),
    /// Linear interpolation between samples; wavelengths strictly increasing.
    Tabulated {
        /// Sample wavelengths, nm, strictly increasing.
        wavelengths: Vec<f64>,
        /// Values at the sample wavelengths (already multiplied by any scale).
        values: Vec<f64>,
        /// Behaviour outside the table.
        outside: Outside,
        /// The curve at every whole nm, for fast sampling, when that is exact (see [`Grid`]);
        /// derived from the fields above.
        grid: Grid,
    },
    /// Planck's spectral radiance at `kelvin`, times `scale`, in W·sr⁻¹·m⁻²·nm⁻¹.
    Blackbody {
        /// Temperature, K.
        kelvin: f64,
        /// Multiplier.
        scale: f64,
    },
}

/// A table's curve at every whole nm from [`LAMBDA_MIN`] to [`LAMBDA_MAX`], kept when every
/// table wavelength is a whole nm in that range: then linear interpolation between the
/// whole-nm values is the table's own piecewise-linear curve between its first and last
/// wavelength (up to rounding, ~1e-16 relative), and a lookup needs neither a search nor a
/// division. Derived from the table, so it never makes two spectra unequal.
#[derive(Clone, Default)]
pub struct Grid(Option<Arc<[f64]>>);

impl std::fmt::Debug for Grid {
    /// Whether there is one, not its 471 values.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self.0 {
            Some(_) => "Grid(every whole nm)",
            None => "Grid(none)",
        })
    }
}

impl PartialEq for Grid {
    fn eq(&self, _: &Grid) -> bool {
        true
    }
}

impl Grid {
    /// The grid of a valid table (strictly increasing finite wavelengths, as many values), or
    /// none when a wavelength is not a whole nm in range or the table has fewer than 2 rows.
    pub fn of(wavelengths: &[f64], values: &[f64], outside: Outside) -> Grid {
        let n = wavelengths.len();
        let whole = |w: &f64| w.fract() == 0.0 && (LAMBDA_MIN..=LAMBDA_MAX).contains(w);
        if n < 2 || values.len() != n || !wavelengths.iter().all(whole) {
            return Grid(None);
        }
        let (first, last) = (wavelengths[0], wavelengths[n - 1]);
        let scale = (n - 1) as f64 / (last - first);
        let count = (LAMBDA_MAX - LAMBDA_MIN) as usize + 1;
        let grid = (0..count)
            .map(|k| {
                let l = LAMBDA_MIN + k as f64;
                if l >= first && l < last {
                    interpolate(wavelengths, values, l, scale)
                } else {
                    // read only at `last` (the right end of the last interval); elsewhere
                    // outside the table sampling takes `eval`
                    match (outside, l < first) {
                        (Outside::Clamp, true) => values[0],
                        (Outside::Zero, _) if l != last => 0.0,
                        _ => values[n - 1],
                    }
                }
            })
            .collect();
        Grid(Some(grid))
    }

    /// The curve at `lambda` nm (LAMBDA_MIN <= lambda < LAMBDA_MAX) from grid `g`.
    #[inline(always)]
    fn lerp(g: &[f64], lambda: f64) -> f64 {
        let x = lambda - LAMBDA_MIN;
        // (through i64, as in `interpolate`; x >= 0)
        let i = x as i64 as usize;
        let t = x - i as f64;
        let ab = &g[i..i + 2];
        ab[0] + t * (ab[1] - ab[0])
    }
}

/// Linear interpolation of a table (n >= 2, strictly increasing wavelengths, as many values)
/// at `first <= lambda < last`. Measured tables are usually evenly spaced, so the index
/// `scale`·(λ − first), scale = (n − 1)/(last − first), is tried first and checked, else a
/// binary search finds w[lo] <= λ < w[lo + 1]: the same result either way.
#[inline(always)]
fn interpolate(wavelengths: &[f64], values: &[f64], lambda: f64, scale: f64) -> f64 {
    let n = wavelengths.len();
    let values = &values[..n];
    // (through i64: f64 → u64 has no single x86-64 instruction; the value is >= 0)
    let mut lo = (((lambda - wavelengths[0]) * scale) as i64 as usize).min(n - 2);
    if wavelengths[lo] > lambda || wavelengths[lo + 1] <= lambda {
        lo = wavelengths.partition_point(|&w| w <= lambda) - 1;
    }
    let hi = lo + 1;
    let t = (lambda - wavelengths[lo]) / (wavelengths[hi] - wavelengths[lo]);
    values[lo] + t * (values[hi] - values[lo])
}

/// Why a spectrum could not be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SpectrumError {
    /// Table arrays of different length or too short.
    #[error("wavelengths has {wavelengths} entries but values has {values}; both need the same length, at least 1")]
    Length {
        /// Number of wavelengths.
        wavelengths: usize,
        /// Number of values.
        values: usize,
    },
    /// Wavelengths not strictly increasing or not finite.
    #[error("wavelengths must be finite and strictly increasing; entry {index} is {value:?} nm after {previous:?} nm")]
    NotIncreasing {
        /// Index of the offending entry.
        index: usize,
        /// Its value.
        value: f64,
        /// The entry before it.
        previous: f64,
    },
    /// A value or wavelength that is NaN or infinite.
    #[error("entry {index} is {value}; spectra must be finite numbers")]
    NotFinite {
        /// Index of the offending entry.
        index: usize,
        /// Its value.
        value: f64,
    },
    /// A non-positive blackbody temperature.
    #[error("blackbody temperature {0:?} K must be finite and > 0")]
    Temperature(f64),
}

impl Spectrum {
    /// A validated piecewise-linear table; `scale` multiplies every value.
    pub fn tabulated(
        wavelengths: Vec<f64>,
        values: Vec<f64>,
        outside: Outside,
        scale: f64,
    ) -> Result<Self, SpectrumError> {
        if wavelengths.len() != values.len() || wavelengths.is_empty() {
            return Err(SpectrumError::Length {
                wavelengths: wavelengths.len(),
                values: values.len(),
            });
        }
        for (i, &w) in wavelengths.iter().enumerate() {
            if !w.is_finite() {
                return Err(SpectrumError::NotFinite { index: i, value: w });
            }
            if i > 0 && w <= wavelengths[i - 1] {
                return Err(SpectrumError::NotIncreasing {
                    index: i,
                    value: w,
                    previous: wavelengths[i - 1],
                });
            }
        }
        if let Some((i, &v)) = values.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            return Err(SpectrumError::NotFinite { index: i, value: v });
        }
        let values = values.into_iter().map(|v| v * scale).collect();
        Ok(Spectrum::table(wavelengths, values, outside))
    }

    /// A table from already-validated parts (strictly increasing finite wavelengths, as many
    /// finite values), with its [`Grid`].
    pub fn table(wavelengths: Vec<f64>, values: Vec<f64>, outside: Outside) -> Self {
        let grid = Grid::of(&wavelengths, &values, outside);
        Spectrum::Tabulated {
            wavelengths,
            values,
            outside,
            grid,
        }
    }

    /// A validated blackbody.
    pub fn blackbody(kelvin: f64, scale: f64) -> Result<Self, SpectrumError> {
        if !(kelvin.is_finite() && kelvin > 0.0) {
            return Err(SpectrumError::Temperature(kelvin));
        }
        Ok(Spectrum::Blackbody { kelvin, scale })
    }

    /// The same spectrum multiplied by `f`.
    pub fn scaled(&self, f: f64) -> Spectrum {
        match self {
            Spectrum::Constant(v) => Spectrum::Constant(v * f),
            Spectrum::Tabulated {
                wavelengths,
                values,
                outside,
                ..
            } => Spectrum::table(
                wavelengths.clone(),
                values.iter().map(|v| v * f).collect(),
                *outside,
            ),
            Spectrum::Blackbody { kelvin, scale } => Spectrum::Blackbody {
                kelvin: *kelvin,
                scale: scale * f,
            },
        }
    }

    /// Value at `lambda` nm.
    pub fn eval(&self, lambda: f64) -> f64 {
        match self {
            Spectrum::Constant(v) => *v,
            Spectrum::Tabulated {
                wavelengths,
                values,
                outside,
                ..
            } => {
                let n = wavelengths.len();
                let (first, last) = (wavelengths[0], wavelengths[n - 1]);
                if lambda < first || lambda > last {
                    return match outside {
                        Outside::Zero => 0.0,
                        Outside::Clamp if lambda < first => values[0],
                        Outside::Clamp => values[n - 1],
                    };
                }
                if lambda >= last {
                    return values[n - 1];
                }
                // Now n >= 2 and first <= lambda < last.
                interpolate(wavelengths, values, lambda, (n - 1) as f64 / (last - first))
            }
            Spectrum::Blackbody { kelvin, scale } => scale * planck(lambda, *kelvin),
        }
    }

    /// Values at the path's wavelengths.
    pub fn sample(&self, wl: &Wavelengths) -> SampledSpectrum {
        match self {
            Spectrum::Constant(v) => SampledSpectrum::splat(*v),
            // the table's bounds and index scale once for the four wavelengths; the same
            // values as `eval`
            Spectrum::Tabulated {
                wavelengths,
                values,
                grid,
                ..
            } if wavelengths.len() >= 2 => {
                let n = wavelengths.len();
                let (first, last) = (wavelengths[0], wavelengths[n - 1]);
                // (index loops: `[T; N]::map` compiled to a call per lane through its
                // try-fold machinery here)
                let mut out = [0.0; N_WAVELENGTHS];
                if let Some(g) = &grid.0 {
                    for (o, &l) in out.iter_mut().zip(&wl.lambda) {
                        *o = if l >= first && l < last {
                            Grid::lerp(g, l)
                        } else {
                            self.eval(l)
                        };
                    }
                } else {
                    let scale = (n - 1) as f64 / (last - first);
                    for (o, &l) in out.iter_mut().zip(&wl.lambda) {
                        *o = if l >= first && l < last {
                            interpolate(wavelengths, values, l, scale)
                        } else {
                            self.eval(l)
                        };
                    }
                }
                SampledSpectrum(out)
            }
            _ => {
                let mut out = [0.0; N_WAVELENGTHS];
                for (o, &l) in out.iter_mut().zip(&wl.lambda) {
                    *o = self.eval(l);
                }
                SampledSpectrum(out)
            }
        }
    }

    /// True when the spectrum is the same at every wavelength in [360, 830] nm.
    pub fn is_constant(&self) -> bool {
        matches!(self, Spectrum::Constant(_))
    }

    /// The smallest and the largest value over [360, 830] nm, each with a wavelength (nm)
    /// where it occurs: `((λ_min, v_min), (λ_max, v_max))`. Exact for tables (the extremes of a
    /// piecewise-linear curve lie on its nodes or at the range ends); blackbodies are scanned
    /// at 0.5 nm (Planck's curve is unimodal).
    pub fn extremes(&self) -> ((f64, f64), (f64, f64)) {
        let probes: Vec<f64> = match self {
            Spectrum::Constant(_) => vec![LAMBDA_MIN],
            Spectrum::Tabulated { wavelengths, .. } => {
                let mut p: Vec<f64> = wavelengths
                    .iter()
                    .copied()
                    .filter(|w| (LAMBDA_MIN..=LAMBDA_MAX).contains(w))
                    .collect();
                p.push(LAMBDA_MIN);
                p.push(LAMBDA_MAX);
                p
            }
            Spectrum::Blackbody { .. } => {
                let n = ((LAMBDA_MAX - LAMBDA_MIN) * 2.0) as usize;
                (0..=n).map(|i| LAMBDA_MIN + i as f64 * 0.5).collect()
            }
        };
        let mut lo = (probes[0], self.eval(probes[0]));
        let mut hi = lo;
        for &l in &probes[1..] {
            let v = self.eval(l);
            if v < lo.1 {
                lo = (l, v);
            }
            if v > hi.1 {
                hi = (l, v);
            }
        }
        (lo, hi)
    }
}

/// Planck's law for spectral radiance per unit wavelength, W·sr⁻¹·m⁻²·nm⁻¹
/// (B_λ = 2hc²/λ⁵ / (exp(hc/(λkT)) − 1), Planck 1901; constants: SI 2019 exact values).
pub fn planck(lambda_nm: f64, kelvin: f64) -> f64 {
    const H: f64 = 6.626_070_15e-34; // J s
    const C: f64 = 299_792_458.0; // m/s
    const K: f64 = 1.380_649e-23; // J/K
    let l = lambda_nm * 1e-9;
    let x = H * C / (l * K * kelvin);
    let per_metre = 2.0 * H * C * C / (l.powi(5) * x.exp_m1());
    per_metre * 1e-9
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_lookup_equals_binary_search_on_even_and_uneven_tables() {
        let tables = [
            (0..76)
                .map(|i| 400.0 + 4.0 * i as f64)
                .collect::<Vec<f64>>(),
            vec![360.0, 361.0, 400.0, 555.5, 556.0, 700.0, 829.0, 830.0],
            vec![500.0],
        ];
        for w in tables {
            let v: Vec<f64> = w.iter().map(|x| (x * 0.37).sin()).collect();
            let s = Spectrum::tabulated(w.clone(), v.clone(), Outside::Clamp, 1.0).unwrap();
            let mut lambda = 355.0;
            while lambda < 835.0 {
                let n = w.len();
                let want = if lambda < w[0] {
                    v[0]
                } else if lambda >= w[n - 1] {
                    v[n - 1]
                } else {
                    let hi = w.partition_point(|&x| x <= lambda);
                    let t = (lambda - w[hi - 1]) / (w[hi] - w[hi - 1]);
                    v[hi - 1] + t * (v[hi] - v[hi - 1])
                };
                assert_eq!(s.eval(lambda), want, "{lambda}");
                lambda += 0.173;
            }
            for &x in &w {
                assert_eq!(s.eval(x), v[w.iter().position(|y| *y == x).unwrap()]);
            }
        }
    }

    #[test]
    fn grid_sampling_is_the_table_curve_and_only_for_whole_nm_tables() {
        let whole = (0..76)
            .map(|i| 400.0 + 4.0 * i as f64)
            .collect::<Vec<f64>>();
        let uneven = vec![360.0, 361.0, 400.0, 556.0, 700.0, 829.0, 830.0];
        let fractional = vec![400.0, 555.5, 700.0];
        for (w, gridded) in [(whole, true), (uneven, true), (fractional, false)] {
            for outside in [Outside::Zero, Outside::Clamp] {
                let v: Vec<f64> = w.iter().map(|x| 1.5 + (x * 0.37).sin()).collect();
                let s = Spectrum::tabulated(w.clone(), v, outside, 1.0).unwrap();
                let Spectrum::Tabulated { grid, .. } = &s else {
                    unreachable!()
                };
                assert_eq!(grid.0.is_some(), gridded, "{w:?}");
                // every wavelength from 360 to 830 nm, the table's ends and their
                // neighbourhoods included: sample (which takes the grid) against eval
                let mut lambda = LAMBDA_MIN;
                while lambda < LAMBDA_MAX {
                    let wl = Wavelengths {
                        lambda: [lambda; N_WAVELENGTHS],
                        pdf: [1.0; N_WAVELENGTHS],
                        secondary_terminated: false,
                    };
                    let (got, want) = (s.sample(&wl).0[0], s.eval(lambda));
                    assert!(
                        (got - want).abs() <= 1e-15 * want.abs(),
                        "{lambda}: {got} vs {want}"
                    );
                    lambda += 0.0731;
                }
            }
        }
    }

    #[test]
    fn table_interpolates_and_handles_outside() {
        let s = Spectrum::tabulated(
            vec![400.0, 500.0, 600.0, 700.0],
            vec![0.0, 8.0, 15.6, 18.4],
            Outside::Zero,
            1.0,
        )
        .unwrap();
        assert_eq!(s.eval(400.0), 0.0);
        assert!((s.eval(550.0) - 11.8).abs() < 1e-12);
        assert_eq!(s.eval(700.0), 18.4);
        assert_eq!(s.eval(399.9), 0.0);
        assert_eq!(s.eval(700.1), 0.0);
        assert_eq!(s.extremes(), ((400.0, 0.0), (700.0, 18.4)));
        let c =
            Spectrum::tabulated(vec![400.0, 700.0], vec![0.2, 0.4], Outside::Clamp, 2.0).unwrap();
        assert_eq!(c.eval(360.0), 0.4);
        assert_eq!(c.eval(830.0), 0.8);
    }

    #[test]
    fn table_rejects_bad_input_by_name() {
        let e = Spectrum::tabulated(vec![400.0, 400.0], vec![1.0, 1.0], Outside::Zero, 1.0);
        assert!(matches!(
            e,
            Err(SpectrumError::NotIncreasing { index: 1, .. })
        ));
        let e = Spectrum::tabulated(vec![400.0], vec![f64::NAN], Outside::Zero, 1.0);
        assert!(matches!(e, Err(SpectrumError::NotFinite { index: 0, .. })));
        let e = Spectrum::tabulated(vec![400.0, 500.0], vec![1.0], Outside::Zero, 1.0);
        assert!(matches!(e, Err(SpectrumError::Length { .. })));
        assert!(Spectrum::blackbody(-1.0, 1.0).is_err());
    }

    #[test]
    fn planck_matches_wien_peak_and_a_known_value() {
        // Wien's displacement constant b = 2.897771955e-3 m K.
        let t = 5000.0;
        let peak = 2.897_771_955e-3 / t * 1e9;
        assert!(planck(peak, t) > planck(peak - 1.0, t));
        assert!(planck(peak, t) > planck(peak + 1.0, t));
        // B_λ(500 nm, 5000 K) = 1.2107e13 W sr⁻¹ m⁻³ = 1.2107e4 per nm (direct evaluation).
        assert!((planck(500.0, 5000.0) / 1.2107e4 - 1.0).abs() < 1e-3);
    }
}
