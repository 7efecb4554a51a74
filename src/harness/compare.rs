//! Image comparison: does a test image agree with a reference beyond noise?
//!
//! Both images are read as linear `R`, `G`, `B` with optional `variance.R/G/B` channels (the
//! variance of each pixel mean, as furnace writes them). Region means are compared with a
//! two-sided z test whose standard error combines both images' variance channels; a reference
//! without variance channels is treated as exact (and the report says so). Where the images
//! differ is located pixel by pixel — Welch t tests when a variance is estimated from few
//! batches (its degrees of freedom known from the header or the sidecar), z otherwise — with
//! the Benjamini–Hochberg procedure at a false-discovery
//! rate q (Benjamini & Hochberg 1995, JRSS B 57, §3). Whole-image metrics as used in the
//! rendering literature: RMSE, relMSE with ε (Rousselle et al. 2011, "Adaptive sampling and
//! reconstruction using greedy error minimization", eq. 9 form (x − y)²/(y² + ε)), SMAPE.

use super::error::CheckError;
use super::measurement::{fmt_sig, Measurement};
use super::outcome::Statistic;
use crate::film::Film;
use crate::io::image::{read_exr, Layers};
use crate::scene::{SceneError, Source};
use crate::stats::{multiple, satterthwaite_dof, t_with_tolerance, welch_dof, welch_test};
use serde::Deserialize;

/// Colour channels compared.
pub const CHANNELS: [&str; 3] = ["R", "G", "B"];

/// The channels (index into [`CHANNELS`], name) to test in furnace's own images of a scene:
/// in a grey render (`RenderSettings::is_grey`) R, G and B are one radiance times three
/// constants (every pixel's XYZ is L times the observer's white), so their tests are one
/// test, G alone, lest a Šidák combination count it three times.
pub fn tested_channels(grey: bool) -> impl Iterator<Item = (usize, &'static str)> {
    let all: &[usize] = if grey { &[1] } else { &[0, 1, 2] };
    all.iter().map(|&c| (c, CHANNELS[c]))
}

/// A linear RGB image with optional per-pixel variance of the mean.
#[derive(Debug, Clone, PartialEq)]
pub struct RgbImage {
    /// Width, pixels.
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
    /// R, G, B planes, row-major.
    pub rgb: [Vec<f64>; 3],
    /// variance.R/G/B planes, when present.
    pub variance: Option<[Vec<f64>; 3]>,
    /// Degrees of freedom of each pixel's variance estimate: spp − 1 for a furnace render
    /// (header `furnace.spp`), K − 1 for K independent batches (`furnace.variance_dof`, or
    /// `batches` in the JSON sidecar next to the file); None = treat as known (z test).
    pub variance_dof: Option<f64>,
    /// Estimated variance of each pixel's variance.R/G/B (from the samples' fourth moments,
    /// stats::MeanVar), when known: region tests then use the Satterthwaite degrees of
    /// freedom of the region's variance instead of treating it as known.
    pub variance_variance: Option<[Vec<f64>; 3]>,
    /// Whether the pixels are correlated within a run (header `furnace.pixels_correlated`:
    /// light-traced, BDPT, MLT and SPPM images), so that a region's standard error cannot come
    /// from its pixels' variances.
    pub pixels_correlated: bool,
    /// Linear R, G, B planes of each of the independent runs the image was made from (layers
    /// `run.K.R/G/B`, written by `furnace render --keep-runs`); empty when not stored. A
    /// region's standard error then comes from the spread of the runs' region means.
    pub runs: Vec<[Vec<f64>; 3]>,
}

impl RgbImage {
    /// Takes R, G, B (required) and variance.R/G/B (all three or none) from EXR layers.
    pub fn from_layers(l: &Layers) -> Result<Self, String> {
        let plane = |name: &str| {
            l.channel(name)
                .map(|c| c.iter().map(|&v| v as f64).collect::<Vec<f64>>())
        };
        let mut rgb: [Vec<f64>; 3] = Default::default();
        for (i, c) in CHANNELS.iter().enumerate() {
            rgb[i] = plane(c)
                .ok_or_else(|| format!("no channel {c:?}; an image needs linear R, G and B"))?;
        }
        let vars: Vec<Option<Vec<f64>>> = CHANNELS
            .iter()
            .map(|c| plane(&format!("variance.{c}")))
            .collect();
        let variance =
            match (&vars[0], &vars[1], &vars[2]) {
                (Some(r), Some(g), Some(b)) => Some([r.clone(), g.clone(), b.clone()]),
                (None, None, None) => None,
                _ => return Err(
                    "variance channels must be all of variance.R, variance.G, variance.B or none"
                        .into(),
                ),
            };
        let attr = |k: &str| {
            l.attributes
                .iter()
                .find(|a| a.0 == k)
                .and_then(|a| a.1.parse::<f64>().ok())
        };
        let variance_dof = attr("furnace.variance_dof")
            .or_else(|| attr("furnace.spp").map(|n| n - 1.0))
            .filter(|d| *d >= 1.0);
        let pixels_correlated = l
            .attributes
            .iter()
            .any(|a| a.0 == "furnace.pixels_correlated" && a.1 == "true");
        // runs 0..K-1, each with R, G and B, and no other run.* channel
        let run_channels = l
            .channels
            .iter()
            .filter(|c| c.0.starts_with("run."))
            .count();
        let mut runs = Vec::new();
        while runs.len() * 3 < run_channels {
            let k = runs.len();
            let layer = |c: &str| {
                plane(&format!("run.{k}.{c}")).ok_or_else(|| {
                    format!("{run_channels} run.* channels, but no run.{k}.{c}: runs must be run.0 to run.K-1, each with R, G and B")
                })
            };
            runs.push([layer("R")?, layer("G")?, layer("B")?]);
        }
        if runs.len() * 3 != run_channels {
            return Err(format!(
                "{run_channels} run.* channels: runs must be run.0 to run.K-1, each with R, G and B and nothing else"
            ));
        }
        if runs.len() == 1 {
            return Err(
                "one run layer (run.0.*): a region's spread needs at least two runs".into(),
            );
        }
        Ok(RgbImage {
            width: l.width,
            height: l.height,
            rgb,
            variance,
            variance_dof,
            variance_variance: None,
            pixels_correlated,
            runs,
        })
    }

    /// Reads an EXR; when its header gives no degrees of freedom and a JSON sidecar
    /// (`X.json` next to `X.exr`, as `reference/mitsuba/render.py` writes) says
    /// `"batches": K` with K ≥ 2, the variances are taken as K-batch estimates (K − 1 dof).
    pub fn load(path: &std::path::Path) -> Result<Self, String> {
        let layers = read_exr(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
        let mut img =
            RgbImage::from_layers(&layers).map_err(|e| format!("{}: {e}", path.display()))?;
        if img.variance.is_some() && img.variance_dof.is_none() {
            let sidecar = path.with_extension("json");
            if let Ok(text) = crate::io::read_small_text(&sidecar) {
                let v: serde_json::Value = serde_json::from_str(&text)
                    .map_err(|e| format!("{}: not JSON: {e}", sidecar.display()))?;
                if let Some(k) = v["batches"].as_f64().filter(|k| *k >= 2.0) {
                    img.variance_dof = Some(k - 1.0);
                }
            }
        }
        Ok(img)
    }
}

impl RgbImage {
    /// The linear sRGB means and mean variances of a rendered film.
    pub fn from_film(film: &Film) -> Self {
        RgbImage {
            width: film.width,
            height: film.height,
            rgb: std::array::from_fn(|c| film.means(3 + c)),
            variance: Some(std::array::from_fn(|c| film.mean_variances(3 + c))),
            // the fewest samples of a rendered pixel (pixels of a crop or of sequential looks
            // may hold different counts; a whole render's are all alike)
            variance_dof: film
                .pixels
                .iter()
                .map(crate::film::Pixel::count)
                .filter(|n| *n > 0)
                .min()
                .map(|n| n as f64 - 1.0)
                .filter(|d| *d >= 1.0),
            variance_variance: Some(std::array::from_fn(|c| {
                film.pixels
                    .iter()
                    .map(|p| p.channel(3 + c).mean_variance_variance())
                    .collect()
            })),
            pixels_correlated: false,
            runs: Vec::new(),
        }
    }

    /// The same image with channels multiplied by `gain` inside the pixel rectangle `rect`
    /// [x0, y0, x1, y1) (variances by gain²): how tests build a wrong reference.
    pub fn tinted(&self, rect: [usize; 4], gain: [f64; 3]) -> Self {
        let mut out = self.clone();
        for y in rect[1]..rect[3].min(self.height) {
            for x in rect[0]..rect[2].min(self.width) {
                let i = y * self.width + x;
                for c in 0..3 {
                    out.rgb[c][i] *= gain[c];
                    if let Some(v) = &mut out.variance {
                        v[c][i] *= gain[c] * gain[c];
                    }
                }
            }
        }
        out
    }
}

/// A named rectangle in fractions of the image, [x0, y0, x1, y1) with 0 ≤ x0 < x1 ≤ 1.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Region {
    /// Name shown in reports.
    pub name: String,
    /// [x0, y0, x1, y1) as fractions of width and height (resolution independent).
    pub rect: [f64; 4],
}

/// A regions file: `[[region]]` tables.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Regions {
    /// The regions.
    #[serde(default)]
    pub region: Vec<Region>,
}

/// Parses a regions file (`[[region]]` tables); a TOML error names the file, line and column.
pub fn parse_regions(text: &str, path: &std::path::Path) -> Result<Vec<Region>, SceneError> {
    let r: Regions = crate::io::parse_toml(&Source { path, text })?;
    Ok(r.region)
}

/// The named regions of a regions file given by manifest key `key` (relative to the manifest),
/// read and validated when the manifest is loaded, so that a bad regions file is an invalid
/// manifest (exit 2), located in the regions file. Empty when the key is absent.
pub fn regions_key(k: &super::keys::Keys, key: &str) -> Result<Vec<Region>, SceneError> {
    let Some(r) = k.get::<String>(key)? else {
        return Ok(Vec::new());
    };
    let p = k.base.join(r.get_ref());
    let text = crate::io::read_small_text(&p)
        .map_err(|e| k.error(r.span(), key, format!("cannot read {}: {e}", p.display())))?;
    let regions = parse_regions(&text, &p)?;
    let rsrc = Source {
        path: &p,
        text: &text,
    };
    for reg in &regions {
        reg.pixels(1, 1)
            .map_err(|m| rsrc.error(0..0, "region", m))?;
    }
    Ok(regions)
}

impl Region {
    /// The pixel rectangle [x0, y0, x1, y1) of this region in a `w`×`h` image (at least one pixel).
    pub fn pixels(&self, w: usize, h: usize) -> Result<[usize; 4], String> {
        let [x0, y0, x1, y1] = self.rect;
        if !(0.0 <= x0 && x0 < x1 && x1 <= 1.0 && 0.0 <= y0 && y0 < y1 && y1 <= 1.0) {
            return Err(format!(
                "region {:?}: rect {:?} must satisfy 0 <= x0 < x1 <= 1 and 0 <= y0 < y1 <= 1",
                self.name, self.rect
            ));
        }
        let px = |f: f64, n: usize| ((f * n as f64).round() as usize).min(n);
        // Starts at most at the last pixel, so a region is never empty.
        let (sx, sy) = (px(x0, w).min(w - 1), px(y0, h).min(h - 1));
        let r = [
            sx,
            sy,
            px(x1, w).max(sx + 1).min(w),
            px(y1, h).max(sy + 1).min(h),
        ];
        Ok(r)
    }
}

/// One region × channel comparison.
#[derive(Debug, Clone, PartialEq)]
pub struct RegionResult {
    /// Region name.
    pub region: String,
    /// Channel.
    pub channel: &'static str,
    /// Mean of the test image and its standard error.
    pub test: (f64, f64),
    /// Mean of the reference and its standard error (0 when it has no variance channels).
    pub reference: (f64, f64),
    /// z = (test − reference)/√(se_t² + se_r²) (a t score when `dof` is finite).
    pub z: f64,
    /// Welch–Satterthwaite degrees of freedom of the comparison (∞: a z test).
    pub dof: f64,
    /// Two-sided p.
    pub p: f64,
}

impl RegionResult {
    /// (test − reference)/|reference| in percent (a zero reference gives a huge, finite value).
    pub fn difference_percent(&self) -> f64 {
        100.0 * (self.test.0 - self.reference.0) / self.reference.0.abs().max(f64::MIN_POSITIVE)
    }
}

/// The test of one region × channel: test and reference (mean, standard error) pairs,
/// z = (test − reference)/√(se_t² + se_r²) after the stated relative model tolerance
/// (stats::t_with_tolerance), judged by Student's t with the Welch–Satterthwaite degrees of
/// freedom of the two variance estimates (`dof` = [test, reference]; ∞ for a variance taken
/// as known, which gives the z test). Few effective degrees of freedom (a variance made of a
/// handful of bright samples) widen the acceptance region instead of trusting an
/// underestimated standard error.
pub fn region_test(
    region: &str,
    channel: &'static str,
    test: (f64, f64),
    reference: (f64, f64),
    dof: [f64; 2],
    rel_tolerance: f64,
) -> RegionResult {
    let se = (test.1 * test.1 + reference.1 * reference.1).sqrt();
    let nu = welch_dof(&[
        (test.1 * test.1, dof[0]),
        (reference.1 * reference.1, dof[1]),
    ]);
    let (z, p) = t_with_tolerance(test.0, se, reference.0, rel_tolerance, nu);
    RegionResult {
        region: region.to_string(),
        channel,
        test,
        reference,
        z,
        dof: nu,
        p,
    }
}

/// Blocks per side of the default region grid.
pub const DEFAULT_GRID: usize = 4;

/// The k×k grid of blocks over the image, named `block (column, row)`.
pub fn grid_regions(k: usize) -> Vec<Region> {
    let f = |i: usize| i as f64 / k as f64;
    (0..k)
        .flat_map(|j| {
            (0..k).map(move |i| Region {
                name: format!("block ({i}, {j})"),
                rect: [f(i), f(j), f(i + 1), f(j + 1)],
            })
        })
        .collect()
}

/// Where an image comparison looks: a regions file, or (without one) a k×k grid of blocks;
/// the manifest keys `regions` and `grid`, one or the other.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RegionChoice {
    /// Named regions from a regions file (empty: the grid).
    pub regions: Vec<Region>,
    /// Blocks per side of the grid (None: [`DEFAULT_GRID`]).
    pub grid: Option<usize>,
}

impl RegionChoice {
    /// Reads the `regions` and `grid` keys.
    pub fn parse(k: &super::keys::Keys) -> Result<Self, crate::io::LocatedError> {
        if k.has("grid") && k.has("regions") {
            return Err(k.error_at(
                "grid",
                "give either `grid` (k x k blocks) or `regions` (a regions file), not both".into(),
            ));
        }
        Ok(RegionChoice {
            regions: regions_key(k, "regions")?,
            grid: k.int("grid", 1, 64)?,
        })
    }

    /// `first` followed by the file's regions, or by the grid's blocks.
    pub fn after(&self, first: Vec<Region>) -> Vec<Region> {
        let mut out = first;
        if self.regions.is_empty() {
            out.extend(grid_regions(self.grid.unwrap_or(DEFAULT_GRID)));
        } else {
            out.extend(self.regions.iter().cloned());
        }
        out
    }
}

/// The regions every comparison starts with: the whole image.
pub fn whole_image() -> Region {
    Region {
        name: "whole image".into(),
        rect: [0.0, 0.0, 1.0, 1.0],
    }
}

/// Whole-image metrics per channel.
#[derive(Debug, Clone, PartialEq)]
pub struct Metrics {
    /// Mean of the test image.
    pub mean_test: f64,
    /// Mean of the reference.
    pub mean_reference: f64,
    /// Root-mean-square error.
    pub rmse: f64,
    /// Mean of (t − r)²/(r² + ε), ε = 1e-2.
    pub rel_mse: f64,
    /// Mean of 2|t − r|/(|t| + |r|) over pixels where |t| + |r| > 0.
    pub smape: f64,
}

/// The result of comparing two images.
#[derive(Debug, Clone, PartialEq)]
pub struct Comparison {
    /// Per-channel metrics, R, G, B.
    pub metrics: [Metrics; 3],
    /// Region tests, region-major.
    pub regions: Vec<RegionResult>,
    /// Šidák per-test level used for the region tests.
    pub alpha: f64,
    /// True when some region test rejects at `alpha`.
    pub differ: bool,
    /// Pixels flagged as different by Benjamini–Hochberg at rate q (any channel), when both
    /// images give a standard error per pixel.
    pub flagged_pixels: Option<usize>,
    /// Per-pixel |z| (max over channels) when available, for the difference map.
    pub pixel_z: Option<Vec<f64>>,
    /// Whether the reference carried an error estimate (variance channels or kept runs).
    pub reference_has_variance: bool,
}

/// ε of relMSE.
pub const REL_MSE_EPS: f64 = 1e-2;

/// Region `r`'s mean of channel `c` over independent runs whose pixels are correlated within a
/// run (SPPM, BDPT, MLT): the mean of the runs' region means with its standard error, and that
/// error's degrees of freedom (runs − 1).
pub fn runs_region_mean(runs: &[RgbImage], c: usize, r: [usize; 4]) -> ((f64, f64), f64) {
    spread(runs.iter().map(|img| region_mean(img, c, r).0).collect())
}

/// The mean of K independent estimates, its standard error from their spread, and K − 1.
fn spread(means: Vec<f64>) -> ((f64, f64), f64) {
    let k = means.len() as f64;
    let mean = means.iter().sum::<f64>() / k;
    let var = means.iter().map(|m| (m - mean).powi(2)).sum::<f64>() / (k - 1.0);
    ((mean, (var / k).sqrt()), k - 1.0)
}

/// Region `r`'s mean of channel `c` with its standard error and that error's degrees of
/// freedom, for an image read from a file: from the spread of its stored runs' region means
/// when it has runs, else from its pixels' variances ([`region_mean`], [`region_dof`]). An
/// image whose pixels are correlated within a run and which stores no runs has no valid
/// region error: that is an error, not a guess. The region mean itself is the image's.
pub fn region_estimate(
    img: &RgbImage,
    c: usize,
    r: [usize; 4],
) -> Result<((f64, f64), f64), String> {
    if img.runs.len() >= 2 {
        let n = ((r[2] - r[0]) * (r[3] - r[1])) as f64;
        let means = img
            .runs
            .iter()
            .map(|run| plane_sum(&run[c], img.width, r) / n)
            .collect();
        let ((_, se), dof) = spread(means);
        return Ok(((region_mean(img, c, r).0, se), dof));
    }
    if img.pixels_correlated {
        return Err("its pixels are correlated within a run (header furnace.pixels_correlated: light-traced, BDPT, MLT or SPPM), so a region's standard error is not the sum of its pixels' variances; render it with `furnace render --keep-runs` (not sharded), which stores the independent runs' images, or compare it with `furnace check` (the reciprocity_image and algorithm_agreement kinds keep the runs)".into());
    }
    Ok((region_mean(img, c, r), region_dof(img, c, r)))
}

/// Sum of a plane of width `w` over the pixel rectangle `r` [x0, y0, x1, y1), in row-major
/// order.
fn plane_sum(plane: &[f64], w: usize, r: [usize; 4]) -> f64 {
    let mut sum = 0.0;
    for y in r[1]..r[3] {
        for x in r[0]..r[2] {
            sum += plane[y * w + x];
        }
    }
    sum
}

/// Mean of channel `c` over the pixel rectangle `r` [x0, y0, x1, y1) and its standard error
/// √(Σ var)/n, which treats the pixels as independent estimates (true for camera-path renders;
/// not for light-traced images, whose region statistics come from the light tracer itself).
pub fn region_mean(img: &RgbImage, c: usize, r: [usize; 4]) -> (f64, f64) {
    let n = ((r[2] - r[0]) * (r[3] - r[1])) as f64;
    let var = img
        .variance
        .as_ref()
        .map_or(0.0, |v| plane_sum(&v[c], img.width, r));
    (plane_sum(&img.rgb[c], img.width, r) / n, var.sqrt() / n)
}

/// Degrees of freedom of the variance of a region mean of channel `c` (Satterthwaite: from
/// the pixels' variances and the estimated variances of those, [`RgbImage::variance_variance`]);
/// ∞ (the variance taken as known) when the image carries no such estimate.
pub fn region_dof(img: &RgbImage, c: usize, r: [usize; 4]) -> f64 {
    let (Some(v), Some(vv)) = (&img.variance, &img.variance_variance) else {
        return f64::INFINITY;
    };
    satterthwaite_dof(
        plane_sum(&v[c], img.width, r),
        plane_sum(&vv[c], img.width, r),
    )
}

/// Refuses an image holding a value or variance that is not a finite number: how many pixels,
/// and where the first is.
fn non_finite(img: &RgbImage) -> Result<(), String> {
    let planes = img.rgb.iter().chain(img.variance.iter().flatten());
    let bad: Vec<usize> = (0..img.width * img.height)
        .filter(|&i| planes.clone().any(|p| !p[i].is_finite()))
        .collect();
    match bad.first() {
        None => Ok(()),
        Some(&i) => Err(format!(
            "has {} pixels whose value or variance is not a finite number (the first at x = {}, y = {}): no statistic can be formed from them; an infinite or NaN radiance is itself a finding about the renderer that made it",
            bad.len(),
            i % img.width,
            i / img.width
        )),
    }
}

/// Compares `test` with `reference` over `regions` (the whole image is always one region) at
/// family-wise rate `family_alpha` (Šidák over regions × channels) and pixel FDR `q`. A region
/// differs when |test − reference| exceeds `rel_tolerance`·|reference| by more than noise (a
/// stated model tolerance, 0 for "equal in expectation"). An image with a pixel value or
/// variance that is not a finite number is refused by name: no statistic can be formed.
pub fn compare(
    test: &RgbImage,
    reference: &RgbImage,
    regions: &[Region],
    family_alpha: f64,
    q: f64,
    rel_tolerance: f64,
) -> Result<Comparison, String> {
    if (test.width, test.height) != (reference.width, reference.height) {
        return Err(format!(
            "the images differ in size: {}x{} vs {}x{}",
            test.width, test.height, reference.width, reference.height
        ));
    }
    for (name, img) in [("test", test), ("reference", reference)] {
        non_finite(img).map_err(|m| format!("the {name} image {m}"))?;
    }
    let (w, h) = (test.width, test.height);
    let n = (w * h) as f64;
    let metrics = std::array::from_fn(|c| {
        let (t, r) = (&test.rgb[c], &reference.rgb[c]);
        let mut se = 0.0;
        let mut rel = 0.0;
        let mut sm = (0.0, 0.0);
        for (a, b) in t.iter().zip(r) {
            let d = a - b;
            se += d * d;
            rel += d * d / (b * b + REL_MSE_EPS);
            if a.abs() + b.abs() > 0.0 {
                sm.0 += 2.0 * d.abs() / (a.abs() + b.abs());
                sm.1 += 1.0;
            }
        }
        Metrics {
            mean_test: t.iter().sum::<f64>() / n,
            mean_reference: r.iter().sum::<f64>() / n,
            rmse: (se / n).sqrt(),
            rel_mse: rel / n,
            smape: if sm.1 > 0.0 { sm.0 / sm.1 } else { 0.0 },
        }
    });
    let mut all = vec![whole_image()];
    all.extend(regions.iter().cloned());
    let m = all.len() * 3;
    let alpha = multiple::sidak_alpha(family_alpha, m);
    let mut results = Vec::new();
    for reg in &all {
        let rect = reg.pixels(w, h)?;
        for (c, channel) in CHANNELS.iter().enumerate() {
            let (t, t_dof) =
                region_estimate(test, c, rect).map_err(|e| format!("the test image: {e}"))?;
            let (r, r_dof) = region_estimate(reference, c, rect)
                .map_err(|e| format!("the reference image: {e}"))?;
            results.push(region_test(
                &reg.name,
                channel,
                t,
                r,
                [t_dof, r_dof],
                rel_tolerance,
            ));
        }
    }
    // A NaN p (a non-finite mean or standard error) counts as a difference, never as agreement.
    let differ = results.iter().any(|r| r.p <= alpha || r.p.is_nan());
    // Pixel-level: BH over all pixel×channel tests, when the test image has variances.
    let (flagged, pixel_z) = match &test.variance {
        None => (None, None),
        Some(vt) => {
            let mut ps = Vec::with_capacity(w * h * 3);
            let mut zmax = vec![0.0f64; w * h];
            for c in 0..3 {
                for i in 0..w * h {
                    let dof = |d: Option<f64>| d.unwrap_or(f64::INFINITY);
                    let mut parts = vec![(vt[c][i], dof(test.variance_dof))];
                    if let Some(v) = &reference.variance {
                        parts.push((v[c][i], dof(reference.variance_dof)));
                    }
                    let (t, p, _) = welch_test(test.rgb[c][i] - reference.rgb[c][i], &parts);
                    // NaN (a non-finite pixel) is flagged: p = 0, consistently for the count and
                    // for the sorted set below.
                    ps.push((i, if p.is_nan() { 0.0 } else { p }));
                    zmax[i] = zmax[i].max(t.abs().min(1e6));
                }
            }
            let k = multiple::benjamini_hochberg(&ps.iter().map(|x| x.1).collect::<Vec<_>>(), q);
            let mut sorted: Vec<(usize, f64)> = ps.clone();
            sorted.sort_by(|a, b| a.1.total_cmp(&b.1));
            let mut px = std::collections::BTreeSet::new();
            for (i, _) in sorted.iter().take(k) {
                px.insert(*i);
            }
            (Some(px.len()), Some(zmax))
        }
    };
    Ok(Comparison {
        metrics,
        regions: results,
        alpha,
        differ,
        flagged_pixels: flagged,
        pixel_z,
        reference_has_variance: reference.variance.is_some() || reference.runs.len() >= 2,
    })
}

/// The measurement of a set of region × channel z tests: p is the Šidák combination of the
/// smallest p over the m tests, 1 − (1 − p_min)^m (Šidák 1967); the worst region's numbers are
/// shown, with the three smallest p. `what` describes the comparison for the message.
pub fn regions_measurement(
    regions: &[RegionResult],
    samples: u64,
    what: &str,
) -> Result<Measurement, CheckError> {
    if let Some(r) = regions.iter().find(|r| r.p.is_nan()) {
        return Err(CheckError::Setup(format!(
            "region {:?} channel {} has a non-finite mean or standard error (test {} ± {}, reference {} ± {})",
            r.region, r.channel, r.test.0, r.test.1, r.reference.0, r.reference.1
        )));
    }
    let m = regions.len();
    let worst = regions
        .iter()
        .min_by(|a, b| a.p.total_cmp(&b.p))
        .ok_or("no region to compare")?;
    let p_min = worst.p;
    // Šidák: P(min of m independent uniform p ≤ p_min) = 1 − (1 − p_min)^m.
    let p = -((-p_min).ln_1p() * m as f64).exp_m1();
    let se = (worst.test.1.powi(2) + worst.reference.1.powi(2)).sqrt();
    let rel = |r: &RegionResult| {
        if r.reference.0 != 0.0 {
            format!("{:+.3}%", 100.0 * (r.test.0 / r.reference.0 - 1.0))
        } else {
            "n/a".into()
        }
    };
    let mut listed: Vec<&RegionResult> = regions.iter().collect();
    listed.sort_by(|a, b| a.p.total_cmp(&b.p));
    let top: Vec<String> = listed
        .iter()
        .take(3)
        .map(|r| {
            if r.dof.is_finite() {
                format!(
                    "{} {} {} (t {:.2}, ν {})",
                    r.region,
                    r.channel,
                    rel(r),
                    r.z,
                    fmt_sig(r.dof)
                )
            } else {
                format!("{} {} {} (z {:.2})", r.region, r.channel, rel(r), r.z)
            }
        })
        .collect();
    Ok(Measurement {
        estimate: Some(worst.test.0),
        std_error: Some(se),
        expected: Some(worst.reference.0),
        statistic: Some(if worst.dof.is_finite() {
            Statistic::T {
                t: worst.z,
                dof: worst.dof,
            }
        } else {
            Statistic::Z { z: worst.z }
        }),
        p_value: Some(p.min(1.0)),
        samples,
        message: format!(
            "{m} region x channel tests (z, or Welch t with ν where a variance rests on few effective samples; {what}); worst: {} {} test {} ± {} vs reference {} ± {}; smallest p first: {}",
            worst.region,
            worst.channel,
            fmt_sig(worst.test.0),
            fmt_sig(worst.test.1),
            fmt_sig(worst.reference.0),
            fmt_sig(worst.reference.1),
            top.join("; ")
        ),
        variants: m,
        ..Default::default()
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_image_with_a_non_finite_pixel_is_refused_by_name() {
        let good = RgbImage {
            width: 2,
            height: 2,
            rgb: std::array::from_fn(|_| vec![1.0; 4]),
            variance: Some(std::array::from_fn(|_| vec![0.01; 4])),
            variance_dof: None,
            variance_variance: None,
            pixels_correlated: false,
            runs: Vec::new(),
        };
        assert!(compare(&good, &good, &[], 0.01, 0.05, 0.0).is_ok());
        for (plane, at) in [(0, 3), (1, 1)] {
            let mut bad = good.clone();
            bad.rgb[plane][at] = f64::NAN;
            let e = compare(&bad, &good, &[], 0.01, 0.05, 0.0).unwrap_err();
            assert!(
                e.contains("the test image has 1 pixels")
                    && e.contains(&format!("x = {}, y = {}", at % 2, at / 2)),
                "{e}"
            );
            let mut bad = good.clone();
            bad.variance.as_mut().unwrap()[plane][at] = f64::INFINITY;
            let e = compare(&good, &bad, &[], 0.01, 0.05, 0.0).unwrap_err();
            assert!(e.contains("the reference image has 1 pixels"), "{e}");
        }
    }

    #[test]
    fn a_grey_render_tests_one_channel_a_coloured_one_three() {
        assert_eq!(tested_channels(true).collect::<Vec<_>>(), [(1, "G")]);
        assert_eq!(
            tested_channels(false).collect::<Vec<_>>(),
            [(0, "R"), (1, "G"), (2, "B")]
        );
    }

    #[test]
    fn the_grid_tiles_the_image() {
        let g = grid_regions(4);
        assert_eq!(g.len(), 16);
        let mut covered = vec![0u32; 32 * 32];
        for r in &g {
            let [x0, y0, x1, y1] = r.pixels(32, 32).unwrap();
            for y in y0..y1 {
                for x in x0..x1 {
                    covered[y * 32 + x] += 1;
                }
            }
        }
        assert!(covered.iter().all(|c| *c == 1));
    }
    use crate::math::rng::SampleStream;

    /// Standard normal numbers from stream `stream` of `seed` (Box–Muller, Box & Muller 1958).
    fn gaussians(seed: u64, stream: u64) -> impl FnMut() -> f64 {
        let mut rng = SampleStream::new(seed, stream, 0);
        move || {
            let (u1, u2) = (rng.next_f64().max(1e-300), rng.next_f64());
            (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
        }
    }

    /// A synthetic render of a known image: pixel means with Gaussian noise of known variance.
    fn noisy(
        w: usize,
        h: usize,
        truth: impl Fn(usize, usize, usize) -> f64,
        sd: f64,
        seed: u64,
    ) -> RgbImage {
        let mut gauss = gaussians(seed, 0);
        let rgb = std::array::from_fn(|c| {
            (0..w * h)
                .map(|i| truth(i % w, i / w, c) + sd * gauss())
                .collect()
        });
        let variance = Some(std::array::from_fn(|_| vec![sd * sd; w * h]));
        RgbImage {
            width: w,
            height: h,
            rgb,
            variance,
            variance_dof: None,
            variance_variance: None,
            pixels_correlated: false,
            runs: Vec::new(),
        }
    }

    /// An image of `truth` whose pixels are means of `k` noisy batches, with the variance of
    /// each mean *estimated* from those batches (as render.py --batches does).
    fn batched(w: usize, h: usize, k: usize, sd: f64, seed: u64) -> RgbImage {
        let mut gauss = gaussians(seed, 1);
        let batches = (0..k)
            .map(|_| std::array::from_fn(|_| (0..w * h).map(|_| 1.0 + sd * gauss()).collect()))
            .collect();
        from_runs(w, h, batches, false)
    }

    /// An image of 1.0 everywhere made of `k` runs whose pixels share a run-wide offset
    /// (sd `shared`) besides their own noise (sd 0.01): pixels correlated within a run, as in
    /// an SPPM run's shared photons. Pixel variances come from the runs' spread.
    fn correlated_runs(w: usize, h: usize, k: usize, shared: f64, seed: u64) -> RgbImage {
        let mut gauss = gaussians(seed, 2);
        let runs = (0..k)
            .map(|_| {
                std::array::from_fn(|_| {
                    let offset = shared * gauss();
                    (0..w * h).map(|_| 1.0 + offset + 0.01 * gauss()).collect()
                })
            })
            .collect();
        from_runs(w, h, runs, true)
    }

    /// The image of independent runs' planes: each pixel's mean over the runs and the
    /// variance of that mean from their spread (runs − 1 dof); `correlated` keeps the runs
    /// and marks the pixels correlated.
    fn from_runs(w: usize, h: usize, runs: Vec<[Vec<f64>; 3]>, correlated: bool) -> RgbImage {
        let k = runs.len() as f64;
        let mut rgb: [Vec<f64>; 3] = Default::default();
        let mut var: [Vec<f64>; 3] = Default::default();
        for c in 0..3 {
            for i in 0..w * h {
                let m = runs.iter().map(|r| r[c][i]).sum::<f64>() / k;
                let s2 = runs.iter().map(|r| (r[c][i] - m).powi(2)).sum::<f64>() / (k - 1.0);
                rgb[c].push(m);
                var[c].push(s2 / k);
            }
        }
        RgbImage {
            width: w,
            height: h,
            rgb,
            variance: Some(var),
            variance_dof: Some(k - 1.0),
            variance_variance: None,
            pixels_correlated: correlated,
            runs: if correlated { runs } else { Vec::new() },
        }
    }

    #[test]
    fn correlated_pixels_take_region_errors_from_their_runs() {
        // Ten pairs of images of the same truth, each the mean of 8 runs whose pixels share a
        // run-wide offset: with the runs' region means the regions agree (at the family rate,
        // so at most one pair may differ), while summing the pixel variances treats 1024
        // correlated pixels as independent, understates a region's error 14- to 29-fold and
        // calls nearly every pair different (the negative control).
        let (mut agree, mut naive_differ) = (0, 0);
        for pair in 0..10 {
            let a = correlated_runs(32, 32, 8, 0.02, 2 * pair);
            let b = correlated_runs(32, 32, 8, 0.02, 2 * pair + 1);
            let c = compare(&a, &b, &grid_regions(2), 0.01, 0.01, 0.0).unwrap();
            assert!(
                c.regions
                    .iter()
                    .all(|r| (7.0..=14.0 + 1e-9).contains(&r.dof)),
                "{:?}",
                c.regions[0]
            );
            agree += usize::from(!c.differ);
            let naive = |img: &RgbImage| RgbImage {
                pixels_correlated: false,
                runs: Vec::new(),
                ..img.clone()
            };
            naive_differ += usize::from(
                compare(&naive(&a), &naive(&b), &grid_regions(2), 0.01, 0.01, 0.0)
                    .unwrap()
                    .differ,
            );
        }
        assert!(agree >= 9, "{agree} of 10 pairs agree");
        assert!(naive_differ >= 9, "{naive_differ} of 10 naive pairs differ");
        // the region error is the runs' spread: for the whole image, sd(offset)/√8
        let a = correlated_runs(32, 32, 8, 0.02, 99);
        let ((_, se), dof) = region_estimate(&a, 0, [0, 0, 32, 32]).unwrap();
        assert_eq!(dof, 7.0);
        assert!(
            se > 0.02 / 8f64.sqrt() / 3.0 && se < 0.02 / 8f64.sqrt() * 3.0,
            "{se}"
        );
    }

    #[test]
    fn correlated_pixels_without_runs_are_refused_not_guessed() {
        let mut a = correlated_runs(8, 8, 4, 0.02, 1);
        a.runs.clear();
        let b = correlated_runs(8, 8, 4, 0.02, 2);
        let e = compare(&a, &b, &[], 0.01, 0.01, 0.0).unwrap_err();
        assert!(
            e.starts_with("the test image:") && e.contains("--keep-runs"),
            "{e}"
        );
        let e = compare(&b, &a, &[], 0.01, 0.01, 0.0).unwrap_err();
        assert!(e.starts_with("the reference image:"), "{e}");
    }

    #[test]
    fn run_layers_are_read_back_and_checked() {
        let img = correlated_runs(4, 2, 3, 0.02, 5);
        let mut channels = Vec::new();
        for (c, name) in CHANNELS.iter().enumerate() {
            channels.push((
                name.to_string(),
                img.rgb[c].iter().map(|&v| v as f32).collect(),
            ));
        }
        for (k, run) in img.runs.iter().enumerate() {
            for (c, name) in CHANNELS.iter().enumerate() {
                let plane: Vec<f32> = run[c].iter().map(|&v| v as f32).collect();
                channels.push((format!("run.{k}.{name}"), plane));
            }
        }
        let layers = Layers {
            width: 4,
            height: 2,
            channels,
            attributes: vec![("furnace.pixels_correlated".into(), "true".into())],
        };
        let back = RgbImage::from_layers(&layers).unwrap();
        assert!(back.pixels_correlated);
        assert_eq!(back.runs.len(), 3);
        assert_eq!(back.runs[2][1][7], img.runs[2][1][7] as f32 as f64);
        // a run without all three channels, or a single run, is an error
        let mut broken = layers.clone();
        broken.channels.retain(|(n, _)| n != "run.1.B");
        let e = RgbImage::from_layers(&broken).unwrap_err();
        assert!(e.contains("run.1.B"), "{e}");
        let mut gap = layers.clone();
        gap.channels.retain(|(n, _)| !n.starts_with("run.1."));
        let e = RgbImage::from_layers(&gap).unwrap_err();
        assert!(e.contains("no run.1.R"), "{e}");
        let mut stray = layers.clone();
        stray.channels.push(("run.x".into(), vec![0.0; 8]));
        assert!(RgbImage::from_layers(&stray).is_err());
        let mut single = layers;
        single
            .channels
            .retain(|(n, _)| !n.starts_with("run.1.") && !n.starts_with("run.2."));
        assert!(RgbImage::from_layers(&single)
            .unwrap_err()
            .contains("two runs"));
    }

    #[test]
    fn batch_estimated_variances_need_welch_t_at_the_pixel_level() {
        // Two images of the same truth, variances from 4 batches each: with Welch t the
        // pixel FDR procedure flags (almost) nothing; treating the estimates as exact (z)
        // flags many pixels, as a Mitsuba-vs-Mitsuba comparison once did (95 of 16384).
        let (a, b) = (batched(64, 64, 4, 0.1, 1), batched(64, 64, 4, 0.1, 2));
        let c = compare(&a, &b, &[], 0.01, 0.01, 0.0).unwrap();
        assert!(c.flagged_pixels.unwrap() <= 2, "{:?}", c.flagged_pixels);
        let (mut az, mut bz) = (a.clone(), b.clone());
        az.variance_dof = None;
        bz.variance_dof = None;
        let c = compare(&az, &bz, &[], 0.01, 0.01, 0.0).unwrap();
        assert!(c.flagged_pixels.unwrap() >= 10, "{:?}", c.flagged_pixels);
    }

    fn cornellish(x: usize, _y: usize, c: usize) -> f64 {
        // a "red wall" on the left fifth, grey elsewhere
        if x < 12 {
            [0.6, 0.05, 0.05][c]
        } else {
            0.5
        }
    }

    fn regions() -> Vec<Region> {
        vec![
            Region {
                name: "red wall".into(),
                rect: [0.0, 0.0, 0.2, 1.0],
            },
            Region {
                name: "back".into(),
                rect: [0.4, 0.3, 0.6, 0.6],
            },
        ]
    }

    #[test]
    fn two_noisy_renders_of_the_same_image_agree() {
        let mut false_alarms = 0;
        for seed in 0..20 {
            let a = noisy(64, 48, cornellish, 0.05, seed);
            let b = noisy(64, 48, cornellish, 0.05, 100 + seed);
            let c = compare(&a, &b, &regions(), 0.01, 0.01, 0.0).unwrap();
            false_alarms += c.differ as usize;
            // with no true difference BH should flag (almost) nothing
            assert!(c.flagged_pixels.unwrap() <= 3, "{:?}", c.flagged_pixels);
        }
        assert!(
            false_alarms <= 2,
            "{false_alarms} false alarms in 20 at 1 %"
        );
    }

    #[test]
    fn a_two_percent_tint_on_one_wall_is_rejected() {
        let a = noisy(64, 48, cornellish, 0.05, 1);
        let tinted = |x: usize, y: usize, c: usize| {
            cornellish(x, y, c) * if x < 12 && c == 0 { 1.02 } else { 1.0 }
        };
        let b = noisy(64, 48, tinted, 0.05, 2);
        let c = compare(&a, &b, &regions(), 0.01, 0.01, 0.0).unwrap();
        assert!(c.differ, "{:?}", c.regions);
        let red = c
            .regions
            .iter()
            .find(|r| r.region == "red wall" && r.channel == "R")
            .unwrap();
        assert!(red.p <= c.alpha, "{red:?}");
        // the untouched back wall agrees
        let back = c
            .regions
            .iter()
            .find(|r| r.region == "back" && r.channel == "R")
            .unwrap();
        assert!(back.p > c.alpha);
    }

    #[test]
    fn metrics_have_known_values() {
        let img = |v: f64| RgbImage {
            width: 2,
            height: 1,
            rgb: [vec![v, v], vec![v, v], vec![v, v]],
            variance: None,
            variance_dof: None,
            variance_variance: None,
            pixels_correlated: false,
            runs: Vec::new(),
        };
        let c = compare(&img(1.1), &img(1.0), &[], 0.01, 0.01, 0.0).unwrap();
        let m = &c.metrics[0];
        assert!((m.rmse - 0.1).abs() < 1e-12);
        assert!((m.rel_mse - 0.01 / 1.01).abs() < 1e-12);
        assert!((m.smape - 0.2 / 2.1).abs() < 1e-12);
        // exact images: zero se on both sides, any difference rejects
        assert!(c.differ && !c.reference_has_variance && c.flagged_pixels.is_none());
    }

    #[test]
    fn regions_map_to_pixels_and_reject_bad_rects() {
        let r = Region {
            name: "x".into(),
            rect: [0.0, 0.0, 0.5, 0.25],
        };
        assert_eq!(r.pixels(64, 48).unwrap(), [0, 0, 32, 12]);
        assert!(Region {
            name: "bad".into(),
            rect: [0.5, 0.0, 0.4, 1.0]
        }
        .pixels(64, 48)
        .is_err());
    }
}
