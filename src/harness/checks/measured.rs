//! Comparison with measured camera images (the `measured` kind): a measurement is one image
//! per spectral band plus that band's response curve and the stated standard uncertainty of
//! its regional means. furnace renders the scene with the band responses as the film's
//! observer (so each channel is ∫ L(λ) r(λ) dλ), takes the mean of each region shrunk by
//! `edge` pixels on every side (edges mix surfaces and are where registration errors live),
//! and compares rendered and measured means with z = (g·rendered − measured)/σ,
//! σ² = g²·se_render² + (u·measured)². With `scale = "fit"` (relative measurements, such as
//! CCD counts of unknown gain) g is the weighted least-squares gain over all band × region
//! means; with `scale = "absolute"` g = 1. Besides each band × region mean, each band's
//! inverse-variance weighted mean relative residual over its regions is tested (a band error
//! is common to all regions). The check's p-value is the Šidák combination of the smallest
//! p-value over all these tests.
//!
//! The measurement file (TOML, paths relative to it):
//! ```toml
//! regions = "cornell-box.regions.toml"   # optional; default: the whole image
//! edge = 1                               # pixels excluded inside each region's border
//! scale = "fit"                          # or "absolute"
//! [[band]]
//! name = "500 nm"
//! image = "band-500.exr"                 # one channel, `channel` (default "Y")
//! wavelengths = [480.0, 500.0, 520.0]    # response curve, nm
//! values = [0.0, 1.0, 0.0]               # unitless, >= 0
//! uncertainty = 0.01                     # relative standard uncertainty of a regional mean
//! ```

use crate::harness::compare::{parse_regions, Region};
use crate::harness::keys::{common, Key, Keys};
use crate::harness::measurement::fmt_sig;
use crate::harness::outcome::Statistic;
use crate::harness::region::settings_for;
use crate::harness::{Check, CheckError, Context, Kind, Measurement, Scope};
use crate::integrators::Strategy;
use crate::io::image as io;
use crate::io::LocatedError;
use crate::scene::Source;
use crate::spectrum::observer::Responses;
use crate::spectrum::{Observer, Outside, Spectrum};
use crate::stats::z_test;
use serde::Deserialize;
use std::path::{Path, PathBuf};
use std::sync::Arc;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct BandDesc {
    name: String,
    image: String,
    #[serde(default)]
    channel: Option<String>,
    wavelengths: Vec<f64>,
    values: Vec<f64>,
    uncertainty: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct MeasurementDesc {
    #[serde(default)]
    regions: Option<String>,
    #[serde(default)]
    edge: Option<usize>,
    #[serde(default)]
    scale: Option<String>,
    band: Vec<BandDesc>,
}

/// One measured band.
#[derive(Debug, Clone)]
pub struct Band {
    /// Name shown in messages.
    pub name: String,
    /// The measured image (one value per pixel), row-major.
    pub image: Vec<f64>,
    /// Its response curve.
    pub response: Spectrum,
    /// Relative standard uncertainty of a regional mean.
    pub uncertainty: f64,
}

/// A validated measurement.
#[derive(Debug, Clone)]
pub struct MeasuredImages {
    /// Image width, pixels.
    pub width: usize,
    /// Image height, pixels.
    pub height: usize,
    /// Regions compared (the whole image when the file names none).
    pub regions: Vec<Region>,
    /// Pixels excluded inside each region's border.
    pub edge: usize,
    /// Fit one gain (true) or compare absolutely.
    pub fit_scale: bool,
    /// The bands.
    pub bands: Vec<Band>,
}

/// Reads and validates a measurement file; errors name the file, line and column or the band
/// and key.
pub fn load(path: &Path) -> Result<MeasuredImages, String> {
    let text = crate::io::read_text(path, "the measurement file").map_err(|e| e.to_string())?;
    let d: MeasurementDesc =
        crate::io::parse_toml(&Source { path, text: &text }).map_err(|e| e.to_string())?;
    let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let at = |key: &str, msg: String| format!("{}: {key}: {msg}", path.display());
    let regions = match &d.regions {
        None => vec![Region {
            name: "whole image".into(),
            rect: [0.0, 0.0, 1.0, 1.0],
        }],
        Some(r) => {
            let p = base.join(r);
            let t = crate::io::read_small_text(&p)
                .map_err(|e| at("regions", format!("cannot read {}: {e}", p.display())))?;
            parse_regions(&t, &p).map_err(|e| at("regions", e.to_string()))?
        }
    };
    let fit_scale = match d.scale.as_deref() {
        None | Some("fit") => true,
        Some("absolute") => false,
        Some(o) => return Err(at("scale", format!("{o:?}; allowed \"fit\", \"absolute\""))),
    };
    if d.band.is_empty() {
        return Err(at(
            "band",
            "no [[band]]; a measurement needs at least one".into(),
        ));
    }
    let mut bands = Vec::new();
    let mut size = None;
    for (i, b) in d.band.iter().enumerate() {
        let key = |k: &str| format!("band[{i}].{k}");
        if !(b.uncertainty.is_finite() && b.uncertainty > 0.0 && b.uncertainty < 1.0) {
            return Err(at(
                &key("uncertainty"),
                format!(
                    "{} must lie in (0, 1): a relative standard uncertainty",
                    b.uncertainty
                ),
            ));
        }
        if let Some(v) = b.values.iter().find(|v| !(v.is_finite() && **v >= 0.0)) {
            return Err(at(
                &key("values"),
                format!("{v} is not allowed; a response is >= 0"),
            ));
        }
        let response =
            Spectrum::tabulated(b.wavelengths.clone(), b.values.clone(), Outside::Zero, 1.0)
                .map_err(|e| at(&key("wavelengths"), e.to_string()))?;
        let p = base.join(&b.image);
        let layers = io::read_exr(&p).map_err(|e| at(&key("image"), e.to_string()))?;
        let ch = b.channel.clone().unwrap_or("Y".into());
        let img: Vec<f64> = layers
            .channel(&ch)
            .ok_or_else(|| {
                at(
                    &key("channel"),
                    format!("{} has no channel {ch:?}", p.display()),
                )
            })?
            .iter()
            .map(|&v| v as f64)
            .collect();
        if let Some(v) = img.iter().find(|v| !v.is_finite()) {
            return Err(at(
                &key("image"),
                format!("{} holds {v}; measurements must be finite", p.display()),
            ));
        }
        match size {
            None => size = Some((layers.width, layers.height)),
            Some(s) if s != (layers.width, layers.height) => {
                return Err(at(
                    &key("image"),
                    format!(
                        "{}x{} differs from the first band's {}x{}",
                        layers.width, layers.height, s.0, s.1
                    ),
                ))
            }
            _ => {}
        }
        bands.push(Band {
            name: b.name.clone(),
            image: img,
            response,
            uncertainty: b.uncertainty,
        });
    }
    let (width, height) = size.unwrap_or((1, 1));
    let edge = d.edge.unwrap_or(1);
    for r in &regions {
        let px = r.pixels(width, height).map_err(|m| at("regions", m))?;
        if px[2] < px[0] + 2 * edge + 1 || px[3] < px[1] + 2 * edge + 1 {
            return Err(at(
                "edge",
                format!(
                    "{edge} leaves no pixel of region {:?} ({}x{} pixels)",
                    r.name,
                    px[2] - px[0],
                    px[3] - px[1]
                ),
            ));
        }
    }
    Ok(MeasuredImages {
        width,
        height,
        regions,
        edge,
        fit_scale,
        bands,
    })
}

/// Mean and standard error of `values` (with per-pixel variances `vars`) over a rectangle.
fn rect_mean(values: &[f64], vars: Option<&[f64]>, w: usize, r: [usize; 4]) -> (f64, f64) {
    let (mut s, mut v, mut n) = (0.0, 0.0, 0.0);
    for y in r[1]..r[3] {
        for x in r[0]..r[2] {
            s += values[y * w + x];
            v += vars.map_or(0.0, |vs| vs[y * w + x]);
            n += 1.0;
        }
    }
    (s / n, v.sqrt() / n)
}

/// Runs a `measured` check against `m` (tests pass deliberately wrong measurements).
pub fn run_against(
    check: &Check,
    ctx: &Context,
    m: &MeasuredImages,
) -> Result<Measurement, CheckError> {
    let scene = check.scene()?;
    // (band, region) → (rendered mean, its se, measured mean)
    let mut cells: Vec<(usize, String, f64, f64, f64)> = Vec::new();
    let mut samples = 0;
    for (chunk_i, chunk) in m.bands.chunks(3).enumerate() {
        let curves: [Spectrum; 3] = std::array::from_fn(|k| {
            chunk
                .get(k)
                .map_or(Spectrum::Constant(0.0), |b| b.response.clone())
        });
        let mut s = settings_for(
            check,
            scene,
            ctx,
            crate::math::rng::mix64(ctx.seed ^ chunk_i as u64),
            check.render.max_depth.or(scene.render.max_depth),
            Strategy::Mis,
        );
        s.width = m.width;
        s.height = m.height;
        s.observer = Observer::Responses(Arc::new(Responses::new(curves)));
        let film = ctx.renderer.render(scene, &s)?;
        samples += (s.width * s.height) as u64 * s.spp;
        for (k, band) in chunk.iter().enumerate() {
            let (vals, vars) = (film.means(k), film.mean_variances(k));
            for r in &m.regions {
                let px = r.pixels(m.width, m.height)?;
                let e = m.edge;
                let inner = [px[0] + e, px[1] + e, px[2] - e, px[3] - e];
                let (rm, rse) = rect_mean(&vals, Some(&vars), m.width, inner);
                let (mm, _) = rect_mean(&band.image, None, m.width, inner);
                cells.push((chunk_i * 3 + k, r.name.clone(), rm, rse, mm));
            }
        }
    }
    let sigma2 = |g: f64, c: &(usize, String, f64, f64, f64)| {
        let u = m.bands[c.0].uncertainty * c.4;
        g * g * c.3 * c.3 + u * u
    };
    // Weighted least squares gain: g = Σ w r m / Σ w r², w = 1/σ² (σ at g = 1, one pass).
    let gain = if m.fit_scale {
        let (mut a, mut b) = (0.0, 0.0);
        for c in &cells {
            let w = 1.0 / sigma2(1.0, c).max(f64::MIN_POSITIVE);
            a += w * c.2 * c.4;
            b += w * c.2 * c.2;
        }
        if b > 0.0 {
            a / b
        } else {
            1.0
        }
    } else {
        1.0
    };
    // Tests: each band × region mean, and each band's inverse-variance weighted mean of the
    // relative residuals over its regions (a band error is common to all regions, so this
    // is the more powerful test for it).
    // (z, p, description, (estimate, standard error, expected) of the test)
    type Test = (f64, f64, String, (f64, f64, f64));
    let mut tests: Vec<Test> = Vec::new();
    for c in &cells {
        let t = z_test(gain * c.2, sigma2(gain, c).sqrt(), c.4);
        tests.push((
            t.z,
            t.p,
            format!(
                "band {} region {}: rendered x gain {} vs measured {} ({:+.2}%)",
                m.bands[c.0].name,
                c.1,
                fmt_sig(gain * c.2),
                fmt_sig(c.4),
                100.0 * (gain * c.2 / c.4 - 1.0)
            ),
            (gain * c.2, sigma2(gain, c).sqrt(), c.4),
        ));
    }
    for (b, band) in m.bands.iter().enumerate() {
        let (mut sw, mut swd) = (0.0, 0.0);
        for c in cells.iter().filter(|c| c.0 == b && c.4 != 0.0) {
            let d = (gain * c.2 - c.4) / c.4;
            let w = c.4 * c.4 / sigma2(gain, c);
            sw += w;
            swd += w * d;
        }
        if sw > 0.0 {
            let t = z_test(swd / sw, (1.0 / sw).sqrt(), 0.0);
            tests.push((
                t.z,
                t.p,
                format!(
                    "band {} over all regions: {:+.2}% ± {:.2}%",
                    band.name,
                    100.0 * swd / sw,
                    100.0 / sw.sqrt()
                ),
                // relative: rendered/measured over the band's regions, expected 1
                (1.0 + swd / sw, (1.0 / sw).sqrt(), 1.0),
            ));
        }
    }
    if let Some(t) = tests.iter().find(|t| t.1.is_nan()) {
        return Err(format!("non-finite value in {}", t.2).into());
    }
    if m.fit_scale && cells.len() < 2 {
        return Err(
            "a fitted gain needs at least two band x region means (one is always matched exactly); give more regions or bands, or scale = \"absolute\""
                .into(),
        );
    }
    let wi = (0..tests.len())
        .min_by(|&a, &b| tests[a].1.total_cmp(&tests[b].1))
        .ok_or("no band x region to compare")?;
    let (z, p_min) = (tests[wi].0, tests[wi].1);
    let n = tests.len();
    let p = -((-p_min).ln_1p() * n as f64).exp_m1();
    let (estimate, se, expected) = tests[wi].3;
    Ok(Measurement {
        estimate: Some(estimate),
        std_error: Some(se),
        expected: Some(expected),
        statistic: Some(Statistic::Z { z }),
        p_value: Some(p.min(1.0)),
        samples,
        message: format!(
            "{n} z tests: {} band x region means and {} band means ({} regions, {} px edge excluded), gain {} ({}); worst: {} (z {z:.2})",
            cells.len(),
            m.bands.len(),
            m.regions.len(),
            m.edge,
            fmt_sig(gain),
            if m.fit_scale { "fitted, weighted least squares" } else { "absolute" },
            tests[wi].2,
        ),
        variants: n,
        ..Default::default()
    })
}

/// Parameters of a `measured` check.
#[derive(Debug, Clone, PartialEq)]
pub struct Params {
    /// The measurement file.
    pub measurement: PathBuf,
}

/// The `measured` kind.
pub struct Measured;

impl Kind for Measured {
    type Params = Params;
    const NAME: &'static str = "measured";
    const KEYS: &'static [Key] = &[
        common::SCENE,
        Key {
            name: "measurement",
            ty: "path",
            default: "required",
            doc: "measurement file (TOML: band images, responses, uncertainties), relative to the manifest",
        },
        common::SPP,
        common::MAX_DEPTH,
        common::SEED,
    ];
    // A spectral film with the bands' responses: only furnace's renderer has one.
    const SCOPE: Scope = Scope::Furnace;

    fn parse(k: &mut Keys) -> Result<Params, LocatedError> {
        let measurement = k
            .existing_file(
                "measurement",
                Some("missing; give the measurement file (path relative to the manifest)"),
            )?
            .unwrap_or_default();
        // read once to refuse a bad measurement with the manifest (exit 2, at the key), not
        // when the check runs; not kept, so that a run holds only what its running checks read
        load(&measurement).map_err(|e| k.error_at("measurement", e))?;
        Ok(Params { measurement })
    }

    /// Runs a `measured` check with the measurement file named in the manifest.
    fn run(check: &Check, p: &Params, ctx: &Context) -> Result<Measurement, CheckError> {
        run_against(
            check,
            ctx,
            &load(&p.measurement).map_err(CheckError::Setup)?,
        )
    }
}
