//! Spectrum values in scene files: a number, a name from `[spectra]`, or a table
//! (`wavelengths`+`values`, `csv`+`column`, `blackbody`, or `power_law`+`reference`) with
//! optional `scale` and `outside`. Validated for the role they play (reflectance in [0, 1], emission ≥ 0).

use crate::io::located::{SceneError, Source};
use crate::spectrum::{curve::SpectrumError, Outside, Spectrum, LAMBDA_MAX, LAMBDA_MIN};
use std::cell::RefCell;
use std::collections::BTreeMap;
use std::ops::Range;
use std::path::{Path, PathBuf};
use toml::{Spanned, Value};

/// What a spectrum is used for, which fixes its allowed range.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Role {
    /// Unitless reflectance in [0, 1].
    Reflectance,
    /// Radiance or intensity, ≥ 0.
    Emission,
    /// A refractive index component (n or k), ≥ 0.
    Index,
    /// A medium coefficient (σa, σs) per scene unit of length, ≥ 0.
    Coefficient,
}

const TABLE_KEYS: [&str; 9] = [
    "power_law",
    "reference",
    "wavelengths",
    "values",
    "csv",
    "column",
    "blackbody",
    "scale",
    "outside",
];

/// Parses spectrum values against the scene's named spectra.
pub struct SpectrumParser<'a> {
    src: Source<'a>,
    base: PathBuf,
    named: BTreeMap<String, Spectrum>,
    /// Where the CSV tables read are noted.
    read: &'a RefCell<Vec<PathBuf>>,
}

impl<'a> SpectrumParser<'a> {
    /// Parses the `[spectra]` table (names may not refer to other names).
    pub fn new(
        src: Source<'a>,
        read: &'a RefCell<Vec<PathBuf>>,
        base: &Path,
        table: &BTreeMap<String, Spanned<Value>>,
    ) -> Result<Self, SceneError> {
        let mut p = SpectrumParser {
            src,
            base: base.to_path_buf(),
            named: BTreeMap::new(),
            read,
        };
        for (name, v) in table {
            let key = format!("spectra.{name}");
            if let Value::String(s) = v.get_ref() {
                return Err(src.error(v.span(), key, format!("{s:?}: a named spectrum cannot refer to another name; give a number or a table")));
            }
            let s = p.value(v.get_ref(), v.span(), &key)?;
            p.named.insert(name.clone(), s);
        }
        Ok(p)
    }

    /// Parses and validates one spectrum value for `role`.
    pub fn parse(&self, v: &Spanned<Value>, key: &str, role: Role) -> Result<Spectrum, SceneError> {
        let span = v.span();
        let s = match v.get_ref() {
            Value::String(name) => self.named.get(name).cloned().ok_or_else(|| {
                let names: Vec<&str> = self.named.keys().map(String::as_str).collect();
                self.src.error(
                    span.clone(),
                    key,
                    format!(
                        "unknown spectrum {name:?}; defined in [spectra]: [{}]",
                        names.join(", ")
                    ),
                )
            })?,
            other => self.value(other, span.clone(), key)?,
        };
        // finite everywhere (tables are checked entry by entry; this catches a power law or a
        // scale that overflows)
        for l in LAMBDA_MIN as u32..=LAMBDA_MAX as u32 {
            let v = s.eval(l as f64);
            if !v.is_finite() {
                return Err(self.src.error(
                    span,
                    key,
                    format!(
                        "{v} at {l} nm; spectra must be finite at every wavelength in 360-830 nm"
                    ),
                ));
            }
        }
        let ((l_lo, lo), (l_hi, hi)) = s.extremes();
        match role {
            Role::Coefficient if hi > 1e15 => Err(self.src.error(span, key, format!("{hi:?} at {l_hi} nm is too large; a medium coefficient must be <= 1e15 per scene unit (free paths shorter than 1e-15 units fall below the resolution of positions)"))),
            Role::Reflectance if lo < 0.0 || hi > 1.0 => {
                let (l, x) = if lo < 0.0 { (l_lo, lo) } else { (l_hi, hi) };
                Err(self.src.error(span, key, format!("reflectance is {x:?} at {l} nm; a reflectance must lie in [0, 1] at every wavelength in 360-830 nm")))
            }
            Role::Index if lo < 0.0 => Err(self.src.error(span, key, format!("{lo:?} at {l_lo} nm is negative; a refractive index (n or k) must be >= 0 at every wavelength"))),
            Role::Coefficient if lo < 0.0 => Err(self.src.error(span, key, format!("{lo:?} at {l_lo} nm is negative; a medium coefficient must be >= 0 at every wavelength"))),
            Role::Emission if lo < 0.0 => Err(self.src.error(span, key, format!("{lo:?} at {l_lo} nm is negative; emitted radiance and intensity must be >= 0 at every wavelength"))),
            _ => Ok(s),
        }
    }

    fn value(&self, v: &Value, span: Range<usize>, key: &str) -> Result<Spectrum, SceneError> {
        let err = |msg: String| self.src.error(span.clone(), key, msg);
        match v {
            Value::Integer(i) => Ok(Spectrum::Constant(*i as f64)),
            Value::Float(f) if f.is_finite() => Ok(Spectrum::Constant(*f)),
            Value::Float(f) => Err(err(format!(
                "{f} is not a finite number; spectra must be finite"
            ))),
            Value::Table(t) => {
                if let Some(bad) = t.keys().find(|k| !TABLE_KEYS.contains(&k.as_str())) {
                    return Err(err(format!(
                        "unknown key `{bad}` in a spectrum table; allowed: {}",
                        TABLE_KEYS.join(", ")
                    )));
                }
                let scale = match t.get("scale") {
                    None => 1.0,
                    Some(s) => match number(s) {
                        Some(x) if x.is_finite() && x >= 0.0 => x,
                        _ => {
                            return Err(err(format!(
                                "scale = {} must be a finite number >= 0",
                                value_text(s)
                            )))
                        }
                    },
                };
                let outside = match t.get("outside").map(|o| o.as_str()) {
                    None => Outside::Zero,
                    Some(Some("zero")) => Outside::Zero,
                    Some(Some("clamp")) => Outside::Clamp,
                    Some(_) => {
                        return Err(err(format!(
                            "outside = {}: allowed \"zero\" (default) or \"clamp\"",
                            t["outside"]
                        )))
                    }
                };
                let forms = ["wavelengths", "csv", "blackbody", "power_law"]
                    .iter()
                    .filter(|k| t.contains_key(**k))
                    .count();
                if forms != 1 {
                    return Err(err("a spectrum table needs exactly one of `wavelengths` (with `values`), `csv` (with `column`), `blackbody` or `power_law` (with `reference`)".into()));
                }
                let spec_err = |e: SpectrumError| err(e.to_string());
                if let Some(p) = t.get("power_law") {
                    if let Some(bad) = ["outside", "values", "column"]
                        .iter()
                        .find(|k| t.contains_key(**k))
                    {
                        return Err(err(format!("`{bad}` does not go with `power_law`; a power law takes `power_law` (exponent), `reference` (nm) and `scale` (value at the reference)")));
                    }
                    let exponent = number(p)
                        .filter(|x| x.is_finite() && x.abs() <= 16.0)
                        .ok_or_else(|| {
                            err(format!(
                                "power_law = {} must be a finite exponent in [-16, 16]",
                                value_text(p)
                            ))
                        })?;
                    let reference = t.get("reference").and_then(number).filter(|x| x.is_finite() && *x > 0.0).ok_or_else(|| err("`power_law` needs `reference`, the wavelength in nm (> 0) at which the value is `scale`".into()))?;
                    return Ok(power_law(exponent, reference, scale));
                }
                if t.contains_key("reference") {
                    return Err(err("`reference` goes with `power_law`".into()));
                }
                if let Some(k) = t.get("blackbody") {
                    if t.contains_key("outside")
                        || t.contains_key("values")
                        || t.contains_key("column")
                    {
                        return Err(err(
                            "a blackbody takes only `blackbody` (kelvin) and `scale`".into(),
                        ));
                    }
                    let kelvin = number(k).ok_or_else(|| {
                        err(format!("blackbody = {k:?} must be a temperature in kelvin"))
                    })?;
                    return Spectrum::blackbody(kelvin, scale).map_err(spec_err);
                }
                if let Some(w) = t.get("wavelengths") {
                    if t.contains_key("column") {
                        return Err(err(
                            "`column` goes with `csv`, not with `wavelengths`".into()
                        ));
                    }
                    let ws = numbers(w).ok_or_else(|| {
                        err("wavelengths must be an array of numbers (nm)".into())
                    })?;
                    let vs = t.get("values").and_then(numbers).ok_or_else(|| {
                        err(
                            "`wavelengths` needs `values`, an array of numbers of the same length"
                                .into(),
                        )
                    })?;
                    return Spectrum::tabulated(ws, vs, outside, scale).map_err(spec_err);
                }
                if t.contains_key("values") {
                    return Err(err(
                        "`values` goes with `wavelengths`, not with `csv`".into()
                    ));
                }
                let file = t["csv"].as_str().ok_or_else(|| {
                    err("csv must be a file path (string), relative to the scene file".into())
                })?;
                let column = t.get("column").and_then(|c| c.as_str()).ok_or_else(|| {
                    err("`csv` needs `column`, the header name of the values column".into())
                })?;
                let (ws, vs) = self.csv(file, column, span.clone(), key)?;
                Spectrum::tabulated(ws, vs, outside, scale).map_err(|e| err(format!("{file}: {e}")))
            }
            other => Err(err(format!(
                "{other} is not a spectrum; give a number, a name from [spectra], or a table"
            ))),
        }
    }

    /// Reads column `column` of a CSV whose first column is wavelength in nm.
    fn csv(
        &self,
        file: &str,
        column: &str,
        span: Range<usize>,
        key: &str,
    ) -> Result<(Vec<f64>, Vec<f64>), SceneError> {
        let path = self.base.join(file);
        self.read.borrow_mut().push(path.clone());
        let (line, col) = self.src.line_column(span.start);
        let from = format!(
            "(referenced by {key} at {}:{line}:{col})",
            self.src.path.display()
        );
        let text = crate::io::read_small_text(&path).map_err(|e| {
            self.src.error(
                span.clone(),
                key,
                format!("cannot read {}: {e}", path.display()),
            )
        })?;
        crate::io::csv::column(&text, column).map_err(|e| SceneError {
            file: path.clone(),
            line: e.line,
            column: 1,
            key: key.to_string(),
            message: format!("{} {from}", e.message),
        })
    }
}

/// scale·(λ/reference)^exponent tabulated at 1 nm over 360–830 nm (linear interpolation
/// error below 3e-5 relative for |exponent| ≤ 4), so every consumer, exporters included, sees
/// one table. Rayleigh scattering is exponent −4 (Strutt 1871, Phil. Mag. 41, p. 107).
fn power_law(exponent: f64, reference: f64, scale: f64) -> Spectrum {
    let wavelengths: Vec<f64> = (LAMBDA_MIN as u32..=LAMBDA_MAX as u32)
        .map(f64::from)
        .collect();
    let values = wavelengths
        .iter()
        .map(|l| scale * (l / reference).powf(exponent))
        .collect();
    Spectrum::table(wavelengths, values, Outside::Clamp)
}

fn number(v: &Value) -> Option<f64> {
    match v {
        Value::Integer(i) => Some(*i as f64),
        Value::Float(f) => Some(*f),
        _ => None,
    }
}

fn numbers(v: &Value) -> Option<Vec<f64>> {
    v.as_array()?.iter().map(number).collect()
}

/// A TOML value as a message quotes it: a number as Rust's `{:?}` writes it (`1e300`, not its
/// 301 digits), anything else as TOML writes it (`"big"`).
fn value_text(v: &toml::Value) -> String {
    match number(v) {
        Some(x) => format!("{x:?}"),
        None => crate::limits::quote(&v.to_string()),
    }
}
