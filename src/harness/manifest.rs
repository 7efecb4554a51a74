//! Test manifests: TOML files with one `[[check]]` table per check. Unknown keys are errors,
//! and so are keys that the check's kind does not use; every error names the manifest file,
//! line, column and key. Paths (scenes, templates) are relative to the manifest's folder.

use super::compare::{parse_regions, Region};
use crate::integrators::Strategy;
use crate::math::rng::Sampler;
use crate::scene::{Scene, SceneError, Source};
use crate::spectrum::Observer;
use serde::Deserialize;
use std::collections::BTreeMap;
use std::ops::Range;
use std::path::{Path, PathBuf};
use toml::{Spanned, Value};

/// An invalid manifest (or a scene it names): exit code 2.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ManifestError {
    /// A problem located in a manifest or scene file.
    #[error(transparent)]
    At(#[from] SceneError),
}

/// One `[[check]]` table as written: the union of every kind's keys.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CheckDesc {
    /// Unique name.
    pub name: Option<Spanned<String>>,
    /// Check kind.
    pub kind: Option<Spanned<String>>,
    /// Scene: a path (relative to the manifest) or an inline scene table.
    pub scene: Option<Spanned<Value>>,
    /// Template parameters: name → list of numbers; one check per combination.
    pub vary: Option<Spanned<BTreeMap<String, Vec<f64>>>>,
    /// Samples per pixel.
    pub spp: Option<Spanned<i64>>,
    /// Image width override.
    pub width: Option<Spanned<i64>>,
    /// Image height override.
    pub height: Option<Spanned<i64>>,
    /// Maximum bounces override.
    pub max_depth: Option<Spanned<i64>>,
    /// Russian roulette on (default) or off.
    pub roulette: Option<Spanned<bool>>,
    /// Pixel region [x0, y0, x1, y1) measured.
    pub region: Option<Spanned<[i64; 4]>>,
    /// Seed (default: derived from the run seed and the name).
    pub seed: Option<Spanned<i64>>,
    /// Stated relative model tolerance added to a stochastic acceptance rule.
    pub rel_tolerance: Option<Spanned<f64>>,
    /// Camera distances (radiance invariance).
    pub distances: Option<Spanned<Vec<f64>>>,
    /// Scale factors (scale invariance).
    pub scales: Option<Spanned<Vec<f64>>>,
    /// Translations (scale invariance).
    pub offsets: Option<Spanned<Vec<[f64; 3]>>>,
    /// The analytic kind a scale-invariance check re-checks ("furnace" or "lambert").
    pub of: Option<Spanned<String>>,
    /// Number of random direction pairs / samples per model.
    pub samples: Option<Spanned<i64>>,
    /// Largest polar angle tested, degrees.
    pub theta_max_deg: Option<Spanned<f64>>,
    /// Henyey–Greenstein asymmetries tested.
    pub g: Option<Spanned<Vec<f64>>>,
    /// Absolute tolerance of a deterministic comparison.
    pub abs_tol: Option<Spanned<f64>>,
    /// Relative tolerance of a deterministic comparison.
    pub rel_tol: Option<Spanned<f64>>,
    /// Sphere histogram bins [theta, phi] for chi-square tests.
    pub bins: Option<Spanned<[i64; 2]>>,
    /// Reference image (EXR) of an image comparison, relative to the manifest.
    pub reference: Option<Spanned<String>>,
    /// Regions file (TOML `[[region]]`) of an image comparison, relative to the manifest.
    pub regions: Option<Spanned<String>>,
    /// Colour pipeline the image is rendered with (`cie1931` or `mitsuba3`).
    pub observer: Option<Spanned<String>>,
    /// Measurement file (TOML: band images, responses, uncertainties), relative to the manifest.
    pub measurement: Option<Spanned<String>>,
    /// Sample pattern: independent, stratified or sobol.
    pub sampler: Option<Spanned<String>>,
    /// Sample counts of a convergence ladder.
    pub ladder: Option<Spanned<Vec<i64>>>,
    /// Independent seeds per ladder rung.
    pub seeds: Option<Spanned<i64>>,
    /// Allowed range [min, max] of a convergence slope.
    pub slope: Option<Spanned<[f64; 2]>>,
    /// How emitters are found: mis, bsdf or light.
    pub strategy: Option<Spanned<String>>,
    /// Blocks per side of the region grid (reciprocity_image).
    pub grid: Option<Spanned<i64>>,
    /// Light paths traced (reciprocity_image).
    pub light_paths: Option<Spanned<i64>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ManifestDesc {
    #[serde(default)]
    check: Vec<Spanned<CheckDesc>>,
}

/// The check kinds and the keys each uses (besides `name` and `kind`).
pub const KINDS: [(&str, &[&str]); 19] = [
    (
        "half_space",
        &[
            "scene",
            "vary",
            "spp",
            "width",
            "height",
            "region",
            "seed",
            "rel_tolerance",
        ],
    ),
    (
        "transmittance",
        &[
            "scene",
            "vary",
            "spp",
            "width",
            "height",
            "region",
            "seed",
            "rel_tolerance",
        ],
    ),
    (
        "furnace",
        &[
            "scene",
            "vary",
            "spp",
            "width",
            "height",
            "max_depth",
            "roulette",
            "region",
            "seed",
            "rel_tolerance",
        ],
    ),
    (
        "lambert",
        &[
            "scene",
            "vary",
            "spp",
            "width",
            "height",
            "region",
            "seed",
            "rel_tolerance",
        ],
    ),
    (
        "reciprocity",
        &["samples", "theta_max_deg", "abs_tol", "rel_tol", "seed"],
    ),
    ("energy", &["samples", "theta_max_deg", "abs_tol", "seed"]),
    ("albedo", &["samples", "theta_max_deg", "rel_tol", "seed"]),
    ("smooth_limit", &["samples", "rel_tol", "seed"]),
    ("hg", &["g", "samples", "abs_tol", "bins", "seed"]),
    ("phase", &["samples", "abs_tol", "rel_tol", "bins", "seed"]),
    ("chi2", &["samples", "bins", "seed"]),
    (
        "radiance_invariance",
        &[
            "scene",
            "vary",
            "distances",
            "spp",
            "width",
            "height",
            "region",
            "seed",
            "rel_tolerance",
        ],
    ),
    (
        "estimator_agreement",
        &["scene", "vary", "spp", "width", "height", "region", "seed"],
    ),
    (
        "sample_weights",
        &["samples", "theta_max_deg", "rel_tol", "seed"],
    ),
    (
        "scale_invariance",
        &[
            "scene",
            "of",
            "scales",
            "offsets",
            "spp",
            "width",
            "height",
            "max_depth",
            "region",
            "seed",
            "rel_tolerance",
        ],
    ),
    (
        "image_compare",
        &[
            "scene",
            "reference",
            "regions",
            "observer",
            "spp",
            "max_depth",
            "seed",
            "rel_tolerance",
        ],
    ),
    (
        "measured",
        &["scene", "measurement", "spp", "max_depth", "seed"],
    ),
    (
        "reciprocity_image",
        &[
            "scene",
            "spp",
            "light_paths",
            "width",
            "height",
            "max_depth",
            "roulette",
            "grid",
            "regions",
            "observer",
            "seed",
            "rel_tolerance",
        ],
    ),
    (
        "convergence",
        &[
            "scene",
            "of",
            "sampler",
            "strategy",
            "ladder",
            "seeds",
            "slope",
            "width",
            "height",
            "region",
            "seed",
            "max_depth",
            "roulette",
        ],
    ),
];

/// A scene-level check's render settings (None = the scene's own value).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RenderOverrides {
    /// Samples per pixel.
    pub spp: Option<u64>,
    /// Image width.
    pub width: Option<usize>,
    /// Image height.
    pub height: Option<usize>,
    /// Maximum bounces.
    pub max_depth: Option<u32>,
    /// Russian roulette on/off.
    pub roulette: bool,
    /// Pixel region [x0, y0, x1, y1).
    pub region: Option<[usize; 4]>,
}

/// One runnable check (after `vary` expansion), with its validated scene if it has one.
#[derive(Debug, Clone)]
pub struct CheckSpec {
    /// Unique name.
    pub name: String,
    /// Kind (one of [`KINDS`]).
    pub kind: String,
    /// The scene, for scene-level kinds.
    pub scene: Option<Scene>,
    /// Render settings.
    pub render: RenderOverrides,
    /// Explicit seed.
    pub seed: Option<u64>,
    /// Stated relative model tolerance.
    pub rel_tolerance: f64,
    /// Kind-specific numbers: distances, scales, g, tolerances, samples, bins, offsets, of.
    pub params: Params,
    /// Where the check is defined, for messages: `file:line`.
    pub origin: String,
}

/// Kind-specific parameters with their defaults filled in by the kind.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Params {
    /// Camera distances.
    pub distances: Vec<f64>,
    /// Scale factors.
    pub scales: Vec<f64>,
    /// Offsets.
    pub offsets: Vec<[f64; 3]>,
    /// Analytic kind re-checked by scale invariance.
    pub of: Option<String>,
    /// Samples / pairs.
    pub samples: Option<u64>,
    /// Max polar angle, degrees.
    pub theta_max_deg: Option<f64>,
    /// HG asymmetries.
    pub g: Vec<f64>,
    /// Absolute tolerance.
    pub abs_tol: Option<f64>,
    /// Relative tolerance.
    pub rel_tol: Option<f64>,
    /// Chi-square bins [theta, phi].
    pub bins: Option<[usize; 2]>,
    /// Reference image path (image_compare), resolved against the manifest's folder.
    pub reference: Option<PathBuf>,
    /// Named regions compared (image_compare).
    pub regions: Vec<Region>,
    /// Colour pipeline of the render.
    pub observer: Observer,
    /// Measurement file (measured), resolved against the manifest's folder.
    pub measurement: Option<PathBuf>,
    /// Sample pattern.
    pub sampler: Sampler,
    /// Ladder of sample counts (convergence), increasing.
    pub ladder: Vec<u64>,
    /// Seeds per rung (convergence).
    pub seeds: u64,
    /// Allowed slope range (convergence).
    pub slope: Option<[f64; 2]>,
    /// Emitter-finding strategy (convergence).
    pub strategy: Strategy,
    /// Blocks per side of the region grid (reciprocity_image; None: the kind's default, or
    /// the regions file when one is given).
    pub grid: Option<usize>,
    /// Light paths traced (reciprocity_image; None: spp × width × height).
    pub light_paths: Option<u64>,
}

/// Reads a manifest and expands it into runnable checks, validating every scene.
pub fn load(path: &Path) -> Result<Vec<CheckSpec>, ManifestError> {
    let text = std::fs::read_to_string(path).map_err(|e| SceneError {
        file: path.to_path_buf(),
        line: 0,
        column: 0,
        key: String::new(),
        message: format!("cannot read the manifest: {e}"),
    })?;
    parse(&text, path)
}

/// Parses manifest text (`path` names it in errors and anchors relative paths).
pub fn parse(text: &str, path: &Path) -> Result<Vec<CheckSpec>, ManifestError> {
    let src = Source { path, text };
    let desc: ManifestDesc = toml::from_str(text).map_err(|e| {
        let span = e.span().unwrap_or(0..0);
        src.error(span, "", e.message().trim_end().to_string())
    })?;
    let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let mut out: Vec<CheckSpec> = Vec::new();
    let mut seen = std::collections::BTreeSet::new();
    for (i, c) in desc.check.iter().enumerate() {
        for spec in check(&src, &base, i, c)? {
            if !seen.insert(spec.name.clone()) {
                let span = c
                    .get_ref()
                    .name
                    .as_ref()
                    .map(|n| n.span())
                    .unwrap_or(c.span());
                return Err(err(
                    &src,
                    span,
                    format!("check[{i}].name"),
                    format!("duplicate check name {:?}; names must be unique", spec.name),
                ));
            }
            out.push(spec);
        }
    }
    Ok(out)
}

fn err(src: &Source, span: Range<usize>, key: String, msg: String) -> ManifestError {
    src.error(span, key, msg).into()
}

fn uint<T: TryFrom<i64>>(
    src: &Source,
    v: &Option<Spanned<i64>>,
    key: &str,
    lo: i64,
    hi: i64,
) -> Result<Option<T>, ManifestError> {
    match v {
        None => Ok(None),
        Some(s) => {
            let x = *s.get_ref();
            if x < lo || x > hi {
                return Err(err(
                    src,
                    s.span(),
                    key.into(),
                    format!("{x} is out of range; allowed {lo}..={hi}"),
                ));
            }
            Ok(T::try_from(x).ok())
        }
    }
}

fn positive(
    src: &Source,
    v: &Option<Spanned<f64>>,
    key: &str,
) -> Result<Option<f64>, ManifestError> {
    match v {
        None => Ok(None),
        Some(s) => {
            let x = *s.get_ref();
            if !(x.is_finite() && x >= 0.0) {
                return Err(err(
                    src,
                    s.span(),
                    key.into(),
                    format!("{x} must be a finite number >= 0"),
                ));
            }
            Ok(Some(x))
        }
    }
}

fn check(
    src: &Source,
    base: &Path,
    index: usize,
    c: &Spanned<CheckDesc>,
) -> Result<Vec<CheckSpec>, ManifestError> {
    let d = c.get_ref();
    let at = format!("check[{index}]");
    let kinds: Vec<&str> = KINDS.iter().map(|k| k.0).collect();
    let name = d.name.as_ref().ok_or_else(|| {
        err(
            src,
            c.span(),
            format!("{at}.name"),
            "missing; every check needs a unique name".into(),
        )
    })?;
    let kind = d.kind.as_ref().ok_or_else(|| {
        err(
            src,
            c.span(),
            format!("{at}.kind"),
            format!("missing; allowed kinds: {}", kinds.join(", ")),
        )
    })?;
    let Some((kind_name, allowed)) = KINDS.iter().find(|k| k.0 == kind.get_ref()) else {
        return Err(err(
            src,
            kind.span(),
            format!("{at}.kind"),
            format!(
                "unknown check kind {:?}; allowed: {}",
                kind.get_ref(),
                kinds.join(", ")
            ),
        ));
    };
    let present: [(&str, Option<Range<usize>>); 32] = [
        ("scene", d.scene.as_ref().map(|v| v.span())),
        ("vary", d.vary.as_ref().map(|v| v.span())),
        ("spp", d.spp.as_ref().map(|v| v.span())),
        ("width", d.width.as_ref().map(|v| v.span())),
        ("height", d.height.as_ref().map(|v| v.span())),
        ("max_depth", d.max_depth.as_ref().map(|v| v.span())),
        ("roulette", d.roulette.as_ref().map(|v| v.span())),
        ("region", d.region.as_ref().map(|v| v.span())),
        ("seed", d.seed.as_ref().map(|v| v.span())),
        ("rel_tolerance", d.rel_tolerance.as_ref().map(|v| v.span())),
        ("distances", d.distances.as_ref().map(|v| v.span())),
        ("scales", d.scales.as_ref().map(|v| v.span())),
        ("offsets", d.offsets.as_ref().map(|v| v.span())),
        ("of", d.of.as_ref().map(|v| v.span())),
        ("samples", d.samples.as_ref().map(|v| v.span())),
        ("theta_max_deg", d.theta_max_deg.as_ref().map(|v| v.span())),
        ("g", d.g.as_ref().map(|v| v.span())),
        ("abs_tol", d.abs_tol.as_ref().map(|v| v.span())),
        ("rel_tol", d.rel_tol.as_ref().map(|v| v.span())),
        ("bins", d.bins.as_ref().map(|v| v.span())),
        ("reference", d.reference.as_ref().map(|v| v.span())),
        ("regions", d.regions.as_ref().map(|v| v.span())),
        ("observer", d.observer.as_ref().map(|v| v.span())),
        ("measurement", d.measurement.as_ref().map(|v| v.span())),
        ("sampler", d.sampler.as_ref().map(|v| v.span())),
        ("ladder", d.ladder.as_ref().map(|v| v.span())),
        ("seeds", d.seeds.as_ref().map(|v| v.span())),
        ("slope", d.slope.as_ref().map(|v| v.span())),
        ("strategy", d.strategy.as_ref().map(|v| v.span())),
        ("grid", d.grid.as_ref().map(|v| v.span())),
        ("light_paths", d.light_paths.as_ref().map(|v| v.span())),
        ("name", None),
    ];
    for (key, span) in &present {
        if let Some(span) = span {
            if !allowed.contains(key) {
                return Err(err(
                    src,
                    span.clone(),
                    format!("{at}.{key}"),
                    format!(
                        "`{key}` is not a key of kind {kind_name:?}; its keys are: name, kind, {}",
                        allowed.join(", ")
                    ),
                ));
            }
        }
    }
    let scene_level = allowed.contains(&"scene");
    if scene_level && d.scene.is_none() {
        return Err(err(src, c.span(), format!("{at}.scene"), format!("kind {kind_name:?} needs a scene: a path relative to the manifest, or an inline [check.scene] table")));
    }
    let region = match &d.region {
        None => None,
        Some(r) => {
            let [x0, y0, x1, y1] = *r.get_ref();
            if x0 < 0 || y0 < 0 || x1 <= x0 || y1 <= y0 {
                return Err(err(src, r.span(), format!("{at}.region"), format!("[{x0}, {y0}, {x1}, {y1}] must be [x0, y0, x1, y1] with 0 <= x0 < x1 and 0 <= y0 < y1 (pixels, end exclusive)")));
            }
            Some([x0 as usize, y0 as usize, x1 as usize, y1 as usize])
        }
    };
    let render = RenderOverrides {
        // spp ≥ 2: one sample per pixel gives no variance estimate, so no test is possible.
        spp: uint(src, &d.spp, &format!("{at}.spp"), 2, 1 << 32)?,
        width: uint(src, &d.width, &format!("{at}.width"), 1, 4096)?,
        height: uint(src, &d.height, &format!("{at}.height"), 1, 4096)?,
        max_depth: uint(src, &d.max_depth, &format!("{at}.max_depth"), 0, 1 << 20)?,
        roulette: d.roulette.as_ref().is_none_or(|r| *r.get_ref()),
        region,
    };
    if !render.roulette && render.max_depth.is_none() {
        let r = d.roulette.as_ref().map(|r| r.span()).unwrap_or(c.span());
        return Err(err(
            src,
            r,
            format!("{at}.roulette"),
            "roulette = false needs max_depth: paths in a closed scene would never end".into(),
        ));
    }
    let finite_list = |v: &Option<Spanned<Vec<f64>>>,
                       key: &str,
                       positive_only: bool|
     -> Result<Vec<f64>, ManifestError> {
        match v {
            None => Ok(Vec::new()),
            Some(s) => {
                if let Some(x) = s
                    .get_ref()
                    .iter()
                    .find(|x| !x.is_finite() || (positive_only && **x <= 0.0))
                {
                    let what = if positive_only {
                        "finite and > 0"
                    } else {
                        "finite"
                    };
                    return Err(err(
                        src,
                        s.span(),
                        format!("{at}.{key}"),
                        format!("{x} is not allowed; every entry must be {what}"),
                    ));
                }
                Ok(s.get_ref().clone())
            }
        }
    };
    let g = finite_list(&d.g, "g", false)?;
    if let (Some(s), Some(bad)) = (&d.g, g.iter().find(|g| g.abs() >= 1.0)) {
        return Err(err(
            src,
            s.span(),
            format!("{at}.g"),
            format!("g = {bad} is not allowed; Henyey-Greenstein needs |g| < 1"),
        ));
    }
    let of_allowed: &[&str] = if *kind_name == "convergence" {
        &["lambert", "emission", "furnace"]
    } else {
        &["furnace", "lambert"]
    };
    let of_list = of_allowed
        .iter()
        .map(|o| format!("{o:?}"))
        .collect::<Vec<_>>()
        .join(", ");
    let of = match &d.of {
        None if *kind_name == "scale_invariance" || *kind_name == "convergence" => {
            return Err(err(
                src,
                c.span(),
                format!("{at}.of"),
                format!("missing; allowed: {of_list}"),
            ))
        }
        None => None,
        Some(o) if of_allowed.contains(&o.get_ref().as_str()) => Some(o.get_ref().clone()),
        Some(o) => {
            return Err(err(
                src,
                o.span(),
                format!("{at}.of"),
                format!("{:?}: allowed {of_list}", o.get_ref()),
            ))
        }
    };
    let bins = match &d.bins {
        None => None,
        Some(b) => {
            let [t, p] = *b.get_ref();
            if !(2..=1000).contains(&t) || !(2..=2000).contains(&p) {
                return Err(err(
                    src,
                    b.span(),
                    format!("{at}.bins"),
                    format!("[{t}, {p}] must be [theta bins 2..=1000, phi bins 2..=2000]"),
                ));
            }
            Some([t as usize, p as usize])
        }
    };
    let theta = positive(src, &d.theta_max_deg, &format!("{at}.theta_max_deg"))?;
    if let (Some(t), Some(s)) = (theta, &d.theta_max_deg) {
        if t >= 90.0 {
            return Err(err(
                src,
                s.span(),
                format!("{at}.theta_max_deg"),
                format!("{t} must be < 90 degrees"),
            ));
        }
    }
    let params = Params {
        distances: finite_list(&d.distances, "distances", true)?,
        scales: finite_list(&d.scales, "scales", true)?,
        offsets: d
            .offsets
            .as_ref()
            .map(|o| o.get_ref().clone())
            .unwrap_or_default(),
        of,
        samples: uint(src, &d.samples, &format!("{at}.samples"), 1, 1 << 26)?,
        theta_max_deg: theta,
        g,
        abs_tol: positive(src, &d.abs_tol, &format!("{at}.abs_tol"))?,
        rel_tol: positive(src, &d.rel_tol, &format!("{at}.rel_tol"))?,
        bins,
        reference: existing_file(
            src,
            base,
            &at,
            "reference",
            &d.reference,
            c.span(),
            (*kind_name == "image_compare").then_some(
                "missing; an image comparison needs a reference EXR (path relative to the manifest)",
            ),
        )?,
        regions: regions(src, base, &at, d)?,
        observer: observer(src, &at, d)?,
        measurement: existing_file(
            src,
            base,
            &at,
            "measurement",
            &d.measurement,
            c.span(),
            (*kind_name == "measured")
                .then_some("missing; give the measurement file (path relative to the manifest)"),
        )?,
        sampler: sampler(src, &at, d)?,
        ladder: ladder(src, &at, d, c.span(), *kind_name == "convergence")?,
        seeds: uint(src, &d.seeds, &format!("{at}.seeds"), 2, 1024)?.unwrap_or(8),
        slope: slope(src, &at, d, c.span(), *kind_name == "convergence")?,
        grid: uint(src, &d.grid, &format!("{at}.grid"), 1, 64)?,
        light_paths: uint(src, &d.light_paths, &format!("{at}.light_paths"), 2, 1 << 40)?,
        strategy: match d.strategy.as_ref().map(|v| (v, v.get_ref().as_str())) {
            None | Some((_, "mis")) => Strategy::Mis,
            Some((_, "bsdf")) => Strategy::BsdfOnly,
            Some((_, "light")) => Strategy::LightOnly,
            Some((v, other)) => {
                return Err(err(
                    src,
                    v.span(),
                    format!("{at}.strategy"),
                    format!("unknown strategy {other:?}; allowed: mis, bsdf, light"),
                ))
            }
        },
    };
    if let (Some(g), Some(_)) = (&d.grid, &d.regions) {
        return Err(err(
            src,
            g.span(),
            format!("{at}.grid"),
            "give either `grid` (k x k blocks) or `regions` (a regions file), not both".into(),
        ));
    }
    if let Some(o) = &d.offsets {
        if o.get_ref().iter().flatten().any(|x| !x.is_finite()) {
            return Err(err(
                src,
                o.span(),
                format!("{at}.offsets"),
                "every offset component must be finite".into(),
            ));
        }
    }
    let base_spec = CheckSpec {
        name: name.get_ref().clone(),
        kind: kind_name.to_string(),
        scene: None,
        render,
        seed: uint(src, &d.seed, &format!("{at}.seed"), 0, i64::MAX)?,
        rel_tolerance: positive(src, &d.rel_tolerance, &format!("{at}.rel_tolerance"))?
            .unwrap_or(0.0),
        params,
        origin: {
            let (l, _) = src.line_column(c.span().start);
            format!("{}:{l}", src.path.display())
        },
    };
    if base_spec.rel_tolerance >= 0.1 {
        let s = d
            .rel_tolerance
            .as_ref()
            .map(|r| r.span())
            .unwrap_or(c.span());
        return Err(err(src, s, format!("{at}.rel_tolerance"), format!("{} is too large: a model tolerance of 10 % or more lets real bugs pass; allowed [0, 0.1)", base_spec.rel_tolerance)));
    }
    if base_spec.params.of.as_deref() == Some("lambert") {
        if let Some(m) = &d.max_depth {
            return Err(err(src, m.span(), format!("{at}.max_depth"), "scale_invariance of \"lambert\" renders direct light only (max_depth 1); remove max_depth".into()));
        }
    }
    if let Some(v) = &d.vary {
        if let Some((k, _)) = v.get_ref().iter().find(|(_, xs)| xs.is_empty()) {
            return Err(err(
                src,
                v.span(),
                format!("{at}.vary.{k}"),
                "an empty list would expand into no checks; give at least one value".into(),
            ));
        }
    }
    let Some(scene) = &d.scene else {
        return Ok(vec![base_spec]);
    };
    let combos = expand(d.vary.as_ref().map(|v| v.get_ref()));
    if d.vary.is_some() && !matches!(scene.get_ref(), Value::String(_)) {
        return Err(err(
            src,
            scene.span(),
            format!("{at}.scene"),
            "`vary` needs a scene template file (a path) with ${name} placeholders".into(),
        ));
    }
    let mut out = Vec::new();
    for combo in combos {
        let mut spec = base_spec.clone();
        spec.scene = Some(match scene.get_ref() {
            Value::String(rel) => {
                let p = base.join(rel);
                let text = std::fs::read_to_string(&p).map_err(|e| {
                    err(
                        src,
                        scene.span(),
                        format!("{at}.scene"),
                        format!("cannot read {}: {e}", p.display()),
                    )
                })?;
                let text = substitute(&text, &combo).map_err(|m| {
                    err(
                        src,
                        scene.span(),
                        format!("{at}.scene"),
                        format!("{}: {m}", p.display()),
                    )
                })?;
                Scene::parse(&text, &p)?
            }
            Value::Table(t) => {
                let text = toml::to_string(t)
                    .map_err(|e| err(src, scene.span(), format!("{at}.scene"), e.to_string()))?;
                Scene::parse(
                    &text,
                    Path::new(&format!("{}#{}.scene", src.path.display(), at)),
                )
                .map_err(|mut e| {
                    let (l, col) = src.line_column(scene.span().start);
                    e.message = format!(
                        "{} (inline scene at {}:{l}:{col})",
                        e.message,
                        src.path.display()
                    );
                    e
                })?
            }
            other => {
                return Err(err(
                    src,
                    scene.span(),
                    format!("{at}.scene"),
                    format!("{other} is not a scene; give a path or an inline table"),
                ))
            }
        });
        if !combo.is_empty() {
            let label: Vec<String> = combo.iter().map(|(k, v)| format!("{k}={v}")).collect();
            spec.name = format!("{}[{}]", spec.name, label.join(","));
        }
        out.push(spec);
    }
    Ok(out)
}

/// The sample pattern named by `sampler` (default independent).
fn sampler(src: &Source, at: &str, d: &CheckDesc) -> Result<Sampler, ManifestError> {
    let Some(v) = &d.sampler else {
        return Ok(Sampler::default());
    };
    Sampler::from_name(v.get_ref()).ok_or_else(|| {
        err(
            src,
            v.span(),
            format!("{at}.sampler"),
            format!(
                "unknown sampler {:?}; allowed: independent, stratified, sobol",
                v.get_ref()
            ),
        )
    })
}

/// A convergence ladder: at least three strictly increasing sample counts in 1..=2^20.
fn ladder(
    src: &Source,
    at: &str,
    d: &CheckDesc,
    span: Range<usize>,
    required: bool,
) -> Result<Vec<u64>, ManifestError> {
    let Some(v) = &d.ladder else {
        if required {
            return Err(err(
                src,
                span,
                format!("{at}.ladder"),
                "missing; give at least three increasing sample counts, e.g. [4, 16, 64, 256]"
                    .into(),
            ));
        }
        return Ok(Vec::new());
    };
    let l = v.get_ref();
    let ok = l.len() >= 3
        && l.iter().all(|n| (1..=1 << 20).contains(n))
        && l.windows(2).all(|w| w[0] < w[1]);
    if !ok {
        return Err(err(
            src,
            v.span(),
            format!("{at}.ladder"),
            format!("{l:?}: need at least three strictly increasing sample counts in 1..=1048576"),
        ));
    }
    Ok(l.iter().map(|n| *n as u64).collect())
}

/// The allowed slope range [min, max] with min < max < 0.
fn slope(
    src: &Source,
    at: &str,
    d: &CheckDesc,
    span: Range<usize>,
    required: bool,
) -> Result<Option<[f64; 2]>, ManifestError> {
    match &d.slope {
        None if required => Err(err(
            src,
            span,
            format!("{at}.slope"),
            "missing; give the allowed range of the RMSE slope, e.g. [-0.55, -0.45]".into(),
        )),
        None => Ok(None),
        Some(v) => {
            let [a, b] = *v.get_ref();
            if !(a.is_finite() && b.is_finite() && a < b && b < 0.0) {
                return Err(err(
                    src,
                    v.span(),
                    format!("{at}.slope"),
                    format!(
                        "[{a}, {b}] must be [min, max] with min < max < 0 (errors fall as N^slope)"
                    ),
                ));
            }
            Ok(Some([a, b]))
        }
    }
}

/// A file named by `key`, resolved against the manifest's folder; it must exist. When the kind
/// requires it, `missing` is the message for its absence.
fn existing_file(
    src: &Source,
    base: &Path,
    at: &str,
    key: &str,
    v: &Option<Spanned<String>>,
    span: Range<usize>,
    missing: Option<&str>,
) -> Result<Option<PathBuf>, ManifestError> {
    match v {
        None => match missing {
            Some(m) => Err(err(src, span, format!("{at}.{key}"), m.to_string())),
            None => Ok(None),
        },
        Some(r) => {
            let p = base.join(r.get_ref());
            if !p.is_file() {
                return Err(err(
                    src,
                    r.span(),
                    format!("{at}.{key}"),
                    format!("{} does not exist or is not a file", p.display()),
                ));
            }
            Ok(Some(p))
        }
    }
}

/// The named regions of an image comparison, read and validated now so that a bad regions
/// file is an invalid manifest (exit 2), located in the regions file.
fn regions(
    src: &Source,
    base: &Path,
    at: &str,
    d: &CheckDesc,
) -> Result<Vec<Region>, ManifestError> {
    let Some(r) = &d.regions else {
        return Ok(Vec::new());
    };
    let p = base.join(r.get_ref());
    let text = std::fs::read_to_string(&p).map_err(|e| {
        err(
            src,
            r.span(),
            format!("{at}.regions"),
            format!("cannot read {}: {e}", p.display()),
        )
    })?;
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

/// The observer named by `observer` (default cie1931).
fn observer(src: &Source, at: &str, d: &CheckDesc) -> Result<Observer, ManifestError> {
    let Some(o) = &d.observer else {
        return Ok(Observer::default());
    };
    Observer::from_name(o.get_ref()).ok_or_else(|| {
        let names: Vec<&str> = Observer::ALL.iter().map(|x| x.0).collect();
        err(
            src,
            o.span(),
            format!("{at}.observer"),
            format!(
                "unknown observer {:?}; allowed: {}",
                o.get_ref(),
                names.join(", ")
            ),
        )
    })
}

/// Cartesian product of the `vary` lists, in key order.
fn expand(vary: Option<&BTreeMap<String, Vec<f64>>>) -> Vec<Vec<(String, f64)>> {
    let mut combos: Vec<Vec<(String, f64)>> = vec![Vec::new()];
    if let Some(v) = vary {
        for (k, values) in v {
            combos = combos
                .into_iter()
                .flat_map(|c| {
                    values.iter().map(move |x| {
                        let mut c = c.clone();
                        c.push((k.clone(), *x));
                        c
                    })
                })
                .collect();
        }
    }
    combos
}

/// Replaces `${name}` placeholders; an unknown or unresolved placeholder is an error.
fn substitute(text: &str, combo: &[(String, f64)]) -> Result<String, String> {
    let mut out = text.to_string();
    for (k, v) in combo {
        let key = format!("${{{k}}}");
        if !out.contains(&key) {
            return Err(format!("the template has no placeholder {key}"));
        }
        out = out.replace(&key, &format!("{v:?}"));
    }
    if let Some(i) = out.find("${") {
        let rest: String = out[i..].chars().take(24).collect();
        return Err(format!(
            "unresolved placeholder {rest:?}; give it a value in `vary`"
        ));
    }
    Ok(out)
}

/// The manifests of a folder (`*.toml`, sorted by name).
pub fn manifests_in(dir: &Path) -> std::io::Result<Vec<PathBuf>> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    v.sort();
    Ok(v)
}
