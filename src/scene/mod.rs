//! Scenes: the TOML description (`desc`), its validation into the renderable [`Scene`], and
//! the errors that name file, line, column, key and the allowed values.
//!
//! Lengths are in scene units (any unit; radiance does not depend on it; point-light
//! irradiance I/d² is per scene unit²). Radiance in W·sr⁻¹·m⁻²·nm⁻¹, wavelengths in nm.

pub mod desc;
mod spectra;

pub use crate::io::located::{SceneError, Source};

use crate::camera::{fov_from_film, Camera};
use crate::geometry::{mesh::TriangleMesh, quad::Quad, sphere::Sphere, Aggregate, Shape};
use crate::lights::Light;
use crate::math::Vec3;
use crate::media::{HenyeyGreenstein, Medium, PhaseFunction};
use crate::scattering::microfacet::Ggx;
use crate::scattering::{
    Bsdf, Conductor, ConductorFresnel, Dielectric, Ior, Lambertian, NullInterface, Ward,
};
use crate::spectrum::{Spectrum, LAMBDA_MAX, LAMBDA_MIN};
use desc::{CameraDesc, LightDesc, MaterialDesc, MediumDesc, RenderDesc, SceneDesc, ShapeDesc};
use spectra::{Role, SpectrumParser};
use std::collections::BTreeMap;
use std::ops::Range;
use std::path::{Path, PathBuf};
use toml::Spanned;
use toml::Value;

/// Default image width and height when `[render]` does not set them, pixels.
pub const DEFAULT_SIZE: usize = 256;
/// Default samples per pixel when `[render]` does not set it.
pub const DEFAULT_SPP: u64 = 16;

/// Render settings stored in the scene file (the CLI may override each).
#[derive(Debug, Clone, PartialEq)]
pub struct RenderDefaults {
    /// Image width, pixels.
    pub width: usize,
    /// Image height, pixels.
    pub height: usize,
    /// Samples per pixel.
    pub spp: u64,
    /// Maximum number of bounces; None = unlimited (Russian roulette ends paths).
    pub max_depth: Option<u32>,
}

/// The camera as described; the image aspect is only known at render time.
#[derive(Debug, Clone, PartialEq)]
pub struct CameraSpec {
    /// Eye position.
    pub position: Vec3,
    /// Point looked at.
    pub look_at: Vec3,
    /// Up hint.
    pub up: Vec3,
    /// Vertical field of view, degrees.
    pub fov_y: f64,
    /// Film width/height when given by `film_size`; the image must have this aspect.
    pub film_aspect: Option<f64>,
    /// Index into [`Scene::media`] of the medium the camera sits in (None: vacuum).
    pub medium: Option<u32>,
}

impl CameraSpec {
    /// Why a `width`×`height` image does not fit the film's aspect, or None when it does.
    pub fn aspect_mismatch(&self, width: usize, height: usize) -> Option<String> {
        let aspect = width as f64 / height as f64;
        let film = self.film_aspect?;
        if (film / aspect - 1.0).abs() <= 1e-6 {
            return None;
        }
        // an absurd film size's aspect in exponent form, not in 300 digits
        let film = if (1e-6..1e6).contains(&film) {
            format!("{film:.6}")
        } else {
            format!("{film:e}")
        };
        Some(format!(
            "the image is {width}x{height} (aspect {aspect:.6}) but camera.film_size has aspect {film}; \
             choose a resolution with the film's aspect"
        ))
    }

    /// The camera for a `width`×`height` image, or a message when the image aspect does not
    /// match the film's.
    pub fn build(&self, width: usize, height: usize) -> Result<Camera, String> {
        if let Some(m) = self.aspect_mismatch(width, height) {
            return Err(m);
        }
        let aspect = width as f64 / height as f64;
        Ok(Camera::new(
            self.position,
            self.look_at,
            self.up,
            self.fov_y,
            aspect,
        ))
    }
}

/// A validated, renderable scene.
#[derive(Debug, Clone)]
pub struct Scene {
    /// Shapes and their BVH.
    pub aggregate: Aggregate,
    /// BSDF of each shape.
    pub bsdfs: Vec<Bsdf>,
    /// Per shape: its material's index among the scene's materials, shared by every shape of
    /// that material (a path evaluates each material's spectra once).
    pub material_of: Vec<u32>,
    /// Index into `lights` of each shape's area light, if it emits.
    pub shape_light: Vec<Option<u32>>,
    /// All lights (area lights first, in shape order, then `[[light]]` entries).
    pub lights: Vec<Light>,
    /// Camera.
    pub camera: CameraSpec,
    /// Render defaults.
    pub render: RenderDefaults,
    /// Participating media (empty for a surface-only scene, which never runs media code).
    pub media: Vec<Medium>,
    /// Names of `media`, as in the scene file.
    pub medium_names: Vec<String>,
    /// Per shape: the media it separates, if it bounds any.
    pub shape_media: Vec<Option<MediumBoundary>>,
    /// The files the scene read besides its own text (meshes, CSV tables), as joined to its
    /// folder: inputs an output must not overwrite.
    pub files: Vec<PathBuf>,
}

/// The media on the two sides of a shape that bounds media (None: vacuum on that side).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MediumBoundary {
    /// Medium on the side opposite the normal (inside a sphere whose normals are not flipped).
    pub interior: Option<u32>,
    /// Medium on the side the normal points to.
    pub exterior: Option<u32>,
}

impl Scene {
    /// True when the scene has participating media (the path tracer then runs its
    /// volumetric variant; surface-only scenes never pay for it).
    pub fn has_media(&self) -> bool {
        !self.media.is_empty()
    }

    /// The medium a ray is in after leaving a surface point of `shape` (normal `n`) in
    /// direction `d`, when it was in `current` before: a shape that bounds media sets the
    /// medium of the side `d` points into; any other shape leaves it unchanged.
    #[inline]
    pub fn medium_after(&self, shape: u32, n: Vec3, d: Vec3, current: Option<u32>) -> Option<u32> {
        match self.shape_media.get(shape as usize).copied().flatten() {
            None => current,
            Some(b) if d.dot(n) > 0.0 => b.exterior,
            Some(b) => b.interior,
        }
    }

    /// True when every spectrum in the scene is constant, so radiance does not depend on
    /// wavelength and the renderer may skip wavelength sampling (grey mode).
    pub fn is_grey(&self) -> bool {
        let lights = self.lights.iter().all(|l| match l {
            Light::Area { radiance, .. } | Light::Environment { radiance } => {
                radiance.is_constant()
            }
            Light::Point { intensity, .. } => intensity.is_constant(),
        });
        self.scatters_grey() && lights
    }

    /// Whether every BSDF and medium is the same at every wavelength (emission may be
    /// coloured): the only scenes an RGB renderer computes exactly as a spectral one does,
    /// since a product of spectra is not the product of their RGB projections.
    pub fn scatters_grey(&self) -> bool {
        self.bsdfs.iter().all(Bsdf::is_constant) && self.media.iter().all(Medium::is_constant)
    }

    /// The same scene with every position mapped to `scale`·p + `offset` (camera included);
    /// radiance and intensity spectra are unchanged, so point-light irradiance scales by
    /// 1/scale². Used by the scale-invariance checks.
    pub fn transformed(&self, scale: f64, offset: Vec3) -> Scene {
        let map = |p: Vec3| p * scale + offset;
        let shapes = self
            .aggregate
            .shapes()
            .iter()
            .map(|s| match s {
                Shape::Sphere(sp) => Shape::Sphere(Sphere {
                    center: map(sp.center),
                    radius: sp.radius * scale,
                    flip_normals: sp.flip_normals,
                }),
                Shape::Quad(q) => Shape::Quad(Quad {
                    corner: map(q.corner),
                    edge_u: q.edge_u * scale,
                    edge_v: q.edge_v * scale,
                    flip_normals: q.flip_normals,
                }),
                Shape::Mesh(m) => Shape::Mesh(TriangleMesh::new(
                    m.positions.iter().map(|&p| map(p)).collect(),
                    m.triangles.clone(),
                    m.flip_normals,
                )),
            })
            .collect();
        let lights = self
            .lights
            .iter()
            .map(|l| match l {
                Light::Point {
                    position,
                    intensity,
                } => Light::Point {
                    position: map(*position),
                    intensity: intensity.clone(),
                },
                other => other.clone(),
            })
            .collect();
        let mut camera = self.camera.clone();
        camera.position = map(camera.position);
        camera.look_at = map(camera.look_at);
        // coefficients are per unit length: σ/scale keeps every optical thickness
        let media = self
            .media
            .iter()
            .map(|m| Medium {
                sigma_a: m.sigma_a.scaled(1.0 / scale),
                sigma_s: m.sigma_s.scaled(1.0 / scale),
                phase: m.phase,
            })
            .collect();
        Scene {
            aggregate: Aggregate::new(shapes),
            bsdfs: self.bsdfs.clone(),
            material_of: self.material_of.clone(),
            shape_light: self.shape_light.clone(),
            lights,
            camera,
            render: self.render.clone(),
            media,
            medium_names: self.medium_names.clone(),
            shape_media: self.shape_media.clone(),
            files: self.files.clone(),
        }
    }

    /// Reads and validates a scene file.
    pub fn load(path: &Path) -> Result<Scene, SceneError> {
        let text = crate::io::read_text(path, "the scene file")?;
        Scene::parse(&text, path)
    }

    /// Validates scene text; `path` names it in errors and its folder resolves relative files.
    pub fn parse(text: &str, path: &Path) -> Result<Scene, SceneError> {
        let src = Source { path, text };
        let desc: SceneDesc = crate::io::parse_toml(&src).map_err(|mut e| {
            if text.contains("${") {
                e.message.push_str(
                    " (this scene holds ${…} placeholders: it is a check's template, filled in by its manifest's `vary`; run the check, or render a copy with the values written in)",
                );
            }
            e
        })?;
        Scene::from_desc(desc, src, 0..0)
    }

    /// Validates a scene description deserialized from `src` (whose spans its fields carry,
    /// e.g. a table inside a manifest); errors about the whole scene point at `whole` (bytes of
    /// `src.text`), and `src.path`'s folder resolves relative files.
    pub fn from_desc(
        desc: SceneDesc,
        src: Source<'_>,
        whole: Range<usize>,
    ) -> Result<Scene, SceneError> {
        Builder {
            base: src.path.parent().map(Path::to_path_buf).unwrap_or_default(),
            src,
            whole,
            read: Default::default(),
        }
        .build(desc)
    }
}

/// A validated shape, its BSDF and its emission (radiance, two-sided) if it emits.
type BuiltShape = (Shape, Bsdf, Option<(Spectrum, bool)>);

struct Builder<'a> {
    src: Source<'a>,
    base: PathBuf,
    /// Where errors about the whole scene point (0..0: the file's start).
    whole: Range<usize>,
    /// The files read so far (meshes, CSV tables), for [`Scene::files`].
    read: std::cell::RefCell<Vec<PathBuf>>,
}

const SHAPE_COMMON: [&str; 7] = [
    "type",
    "material",
    "emission",
    "two_sided",
    "flip_normals",
    "interior",
    "exterior",
];
const SHAPE_TYPES: [(&str, &[&str]); 4] = [
    ("sphere", &["center", "radius"]),
    ("quad", &["corner", "edge_u", "edge_v"]),
    ("triangles", &["vertices", "indices"]),
    ("mesh", &["file"]),
];
const LIGHT_TYPES: [(&str, &[&str]); 2] = [
    ("point", &["position", "intensity"]),
    ("environment", &["radiance"]),
];

impl Builder<'_> {
    fn err(
        &self,
        span: Range<usize>,
        key: impl Into<String>,
        msg: impl Into<String>,
    ) -> SceneError {
        self.src.error(span, key, msg)
    }

    fn build(&self, desc: SceneDesc) -> Result<Scene, SceneError> {
        let render = self.render(desc.render.as_ref())?;
        let camera = match &desc.camera {
            Some(c) => self.camera(c)?,
            None => {
                return Err(self.err(
                    self.whole.clone(),
                    "camera",
                    "missing [camera] table; a scene needs a camera",
                ))
            }
        };
        let parser = SpectrumParser::new(self.src, &self.read, &self.base, &desc.spectra)?;
        let mut media = Vec::new();
        let mut medium_names = Vec::new();
        for (name, m) in &desc.media {
            media.push(self.medium(name, m, &parser)?);
            medium_names.push(name.clone());
        }
        let camera = CameraSpec {
            medium: match desc
                .camera
                .as_ref()
                .and_then(|c| c.get_ref().medium.as_ref())
            {
                Some(m) => Some(self.medium_ref(m, "camera.medium", &medium_names)?),
                None => None,
            },
            ..camera
        };
        let mut materials = BTreeMap::new();
        for (name, m) in &desc.materials {
            materials.insert(name.clone(), self.material(name, m, &parser)?);
        }
        let mut shapes = Vec::new();
        let mut bsdfs = Vec::new();
        let mut material_of = Vec::new();
        let mut shape_light = Vec::new();
        let mut lights = Vec::new();
        let mut shape_media = Vec::new();
        for (i, s) in desc.shape.iter().enumerate() {
            let key = format!("shape[{i}]");
            let (shape, material, emission) = self.shape(&key, s, &materials, &parser)?;
            let d = s.get_ref();
            let side = |v: &Option<Spanned<String>>, k: &str| match v {
                Some(m) => self
                    .medium_ref(m, &format!("{key}.{k}"), &medium_names)
                    .map(Some),
                None => Ok(None),
            };
            let boundary = match (
                side(&d.interior, "interior")?,
                side(&d.exterior, "exterior")?,
            ) {
                _ if d.interior.is_none() && d.exterior.is_none() => None,
                (interior, exterior) => Some(MediumBoundary { interior, exterior }),
            };
            if material.is_null() && boundary.is_none() {
                return Err(self.err(
                    d.material.as_ref().map_or(s.span(), |m| m.span()),
                    format!("{key}.material"),
                    "a null material only marks the boundary of a medium; give the shape `interior` and/or `exterior` (medium names)",
                ));
            }
            shape_media.push(boundary);
            if let Some((radiance, two_sided)) = emission {
                shape_light.push(Some(lights.len() as u32));
                lights.push(Light::Area {
                    shape: shapes.len() as u32,
                    radiance,
                    two_sided,
                });
            } else {
                shape_light.push(None);
            }
            shapes.push(shape);
            bsdfs.push(material);
            // (`self.shape` has checked that the material exists)
            let index = d
                .material
                .as_ref()
                .and_then(|m| materials.keys().position(|k| k == m.get_ref()));
            material_of.push(index.map_or(u32::MAX, |i| i as u32));
        }
        let mut env_seen = false;
        for (i, l) in desc.light.iter().enumerate() {
            let light = self.light(&format!("light[{i}]"), l, &parser)?;
            if matches!(light, Light::Environment { .. }) {
                if env_seen {
                    return Err(self.err(
                        l.span(),
                        format!("light[{i}]"),
                        "a scene may have at most one environment light",
                    ));
                }
                env_seen = true;
            }
            lights.push(light);
        }
        if lights.is_empty() {
            return Err(self.err(
                self.whole.clone(),
                "",
                "the scene has no light: give a shape an `emission` or add a [[light]] (point or environment)",
            ));
        }
        // (shapes[i] is the scene file's [[shape]] i)
        let shape_span = |i: usize| desc.shape.get(i).map_or(self.whole.clone(), |s| s.span());
        if let Some((i, lo, hi)) = shapes.iter().enumerate().find_map(|(i, s)| {
            (0..s.primitive_count())
                .map(|p| s.primitive_bounds(p))
                .find(|(lo, hi)| {
                    !lo.is_finite()
                        || !hi.is_finite()
                        || lo.abs().max(hi.abs()).max_element() > crate::limits::MAX_COORDINATE
                })
                .map(|(lo, hi)| (i, lo, hi))
        }) {
            return Err(self.err(
                shape_span(i),
                format!("shape[{i}]"),
                format!(
                    "its bounds {:?} .. {:?} reach beyond {:e} scene units; coordinates and radii must stay within that",
                    lo.to_array(),
                    hi.to_array(),
                    crate::limits::MAX_COORDINATE
                ),
            ));
        }
        if let Some((i, extent)) = shapes.iter().enumerate().find_map(|(i, s)| {
            let (lo, hi) = (0..s.primitive_count())
                .map(|p| s.primitive_bounds(p))
                .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(l, h), (a, b)| {
                    (l.min(a), h.max(b))
                });
            let extent = (hi - lo).max_element();
            (extent < crate::limits::MIN_EXTENT).then_some((i, extent))
        }) {
            return Err(self.err(
                shape_span(i),
                format!("shape[{i}]"),
                format!(
                    "it is {extent:e} scene units across; shapes must be at least {:e} across (choose a larger unit)",
                    crate::limits::MIN_EXTENT
                ),
            ));
        }
        let scene = Scene {
            aggregate: Aggregate::new(shapes),
            bsdfs,
            material_of,
            shape_light,
            lights,
            camera,
            render,
            media,
            medium_names,
            shape_media,
            files: self.read.take(),
        };
        if let (Some(m), Some(span)) = (
            scene.camera.medium,
            desc.camera
                .as_ref()
                .and_then(|c| c.get_ref().medium.as_ref())
                .map(|m| m.span()),
        ) {
            // A ray with no surface ahead leaves every medium (the path tracer's rule), so a
            // camera medium must be enclosed: probe 256 directions (a Fibonacci sphere).
            let n = 256;
            for i in 0..n {
                let d = crate::math::warp::fibonacci_sphere(i, n);
                let ray = crate::geometry::Ray {
                    o: scene.camera.position,
                    d,
                };
                if scene.aggregate.intersect(&ray, f64::INFINITY).is_none() {
                    return Err(self.err(
                        span,
                        "camera.medium",
                        format!(
                            "the camera sits in medium {:?}, but the ray from the camera towards [{:.3}, {:.3}, {:.3}] meets no shape; a medium must be enclosed by shapes (a ray with no surface ahead leaves every medium)",
                            scene.medium_names[m as usize], d.x, d.y, d.z
                        ),
                    ));
                }
            }
        }
        Ok(scene)
    }

    /// A medium name used by a shape or the camera.
    fn medium_ref(
        &self,
        m: &Spanned<String>,
        key: &str,
        names: &[String],
    ) -> Result<u32, SceneError> {
        names
            .iter()
            .position(|n| n == m.get_ref())
            .map(|i| i as u32)
            .ok_or_else(|| {
                self.err(
                    m.span(),
                    key,
                    format!(
                        "unknown medium {:?}; defined in [media]: [{}]",
                        m.get_ref(),
                        names.join(", ")
                    ),
                )
            })
    }

    /// `[media.NAME]`: σa and σs spectra (per scene unit, both required) and a phase function.
    fn medium(
        &self,
        name: &str,
        m: &Spanned<MediumDesc>,
        parser: &SpectrumParser,
    ) -> Result<Medium, SceneError> {
        let key = format!("media.{name}");
        let d = m.get_ref();
        let coefficient = |v: &Option<Spanned<Value>>, k: &str| {
            let s = self.required(v, m.span(), &format!("{key}.{k}"), "a medium needs `sigma_a` and `sigma_s`, spectra >= 0 per scene unit of length (0 for none)")?;
            parser.parse(s, &format!("{key}.{k}"), Role::Coefficient)
        };
        let sigma_a = coefficient(&d.sigma_a, "sigma_a")?;
        let sigma_s = coefficient(&d.sigma_s, "sigma_s")?;
        // A coefficient that is zero at every wavelength is the constant 0, so that the
        // integrator's shortcuts (pure absorber, lossless medium) recognise it however written.
        let sigma_a = if sigma_a.extremes().1 .1 == 0.0 {
            Spectrum::Constant(0.0)
        } else {
            sigma_a
        };
        let sigma_s = if sigma_s.extremes().1 .1 == 0.0 {
            Spectrum::Constant(0.0)
        } else {
            sigma_s
        };
        let phase_name = self.required(&d.phase, m.span(), &format!("{key}.phase"), "allowed phase functions: \"isotropic\", \"hg\" (Henyey-Greenstein, with `g`), \"rayleigh\"")?;
        let phase = match (phase_name.get_ref().as_str(), &d.g) {
            ("isotropic", None) => PhaseFunction::Isotropic,
            ("isotropic", Some(g)) => return Err(self.err(g.span(), format!("{key}.g"), "`g` belongs to phase = \"hg\"; the isotropic phase function has no parameter")),
            ("hg", Some(g)) => {
                let v = *g.get_ref();
                if !(v.is_finite() && v.abs() < 1.0) {
                    return Err(self.err(g.span(), format!("{key}.g"), format!("{v:?}: the Henyey-Greenstein asymmetry must satisfy |g| < 1")));
                }
                PhaseFunction::HenyeyGreenstein(HenyeyGreenstein { g: v })
            }
            ("rayleigh", None) => PhaseFunction::Rayleigh,
            ("rayleigh", Some(g)) => return Err(self.err(g.span(), format!("{key}.g"), "`g` belongs to phase = \"hg\"; the Rayleigh phase function has no parameter")),
            ("hg", None) => return Err(self.err(phase_name.span(), format!("{key}.g"), "missing; phase = \"hg\" needs the asymmetry `g` with |g| < 1")),
            (other, _) => return Err(self.err(phase_name.span(), format!("{key}.phase"), format!("unknown phase function {other:?}; allowed: \"isotropic\", \"hg\", \"rayleigh\""))),
        };
        Ok(Medium {
            sigma_a,
            sigma_s,
            phase,
        })
    }

    fn render(&self, r: Option<&Spanned<RenderDesc>>) -> Result<RenderDefaults, SceneError> {
        let mut out = RenderDefaults {
            width: DEFAULT_SIZE,
            height: DEFAULT_SIZE,
            spp: DEFAULT_SPP,
            max_depth: None,
        };
        let Some(r) = r else { return Ok(out) };
        let r = r.get_ref();
        let int = |v: &Spanned<i64>, key: &str, lo: i64, hi: i64| -> Result<i64, SceneError> {
            let x = *v.get_ref();
            if x < lo || x > hi {
                return Err(self.err(
                    v.span(),
                    format!("render.{key}"),
                    format!("{x} is out of range; allowed {lo}..={hi}"),
                ));
            }
            Ok(x)
        };
        if let Some(v) = &r.width {
            out.width = int(v, "width", 1, 1 << 16)? as usize;
        }
        if let Some(v) = &r.height {
            out.height = int(v, "height", 1, 1 << 16)? as usize;
        }
        if let Some(v) = &r.spp {
            out.spp = int(v, "spp", 1, 1 << 40)? as u64;
        }
        if let Some(v) = &r.max_depth {
            out.max_depth = Some(int(v, "max_depth", 0, 1 << 20)? as u32);
        }
        if let Err(e) = crate::limits::image(out.width as u64, out.height as u64) {
            let span = r
                .width
                .as_ref()
                .or(r.height.as_ref())
                .map_or(self.whole.clone(), |s| s.span());
            return Err(self.err(span, "render", e.to_string()));
        }
        if let Some(f) = &r.filter {
            if f.get_ref() != "box" {
                return Err(self.err(
                    f.span(),
                    "render.filter",
                    format!("unknown filter {:?}; allowed: \"box\"", f.get_ref()),
                ));
            }
        }
        Ok(out)
    }

    fn vec3(&self, v: &Spanned<[f64; 3]>, key: &str) -> Result<Vec3, SceneError> {
        let a = *v.get_ref();
        if a.iter().any(|x| !x.is_finite()) {
            return Err(self.err(
                v.span(),
                key,
                format!("{a:?} has a non-finite component; coordinates must be finite numbers"),
            ));
        }
        Ok(Vec3::from_array(a))
    }

    fn required<'b, T>(
        &self,
        v: &'b Option<Spanned<T>>,
        span: Range<usize>,
        key: &str,
        what: &str,
    ) -> Result<&'b Spanned<T>, SceneError> {
        v.as_ref()
            .ok_or_else(|| self.err(span, key, format!("missing; {what}")))
    }

    fn camera(&self, c: &Spanned<CameraDesc>) -> Result<CameraSpec, SceneError> {
        let span = c.span();
        let d = c.get_ref();
        let position = self.vec3(
            self.required(
                &d.position,
                span.clone(),
                "camera.position",
                "the camera needs a position [x, y, z]",
            )?,
            "camera.position",
        )?;
        let look_at = self.vec3(
            self.required(
                &d.look_at,
                span.clone(),
                "camera.look_at",
                "the camera needs a look_at point [x, y, z]",
            )?,
            "camera.look_at",
        )?;
        let up_s = self.required(
            &d.up,
            span.clone(),
            "camera.up",
            "the camera needs an up vector [x, y, z]",
        )?;
        let up = self.vec3(up_s, "camera.up")?;
        // as for shapes: beyond it the view direction's squared length overflows
        let limit = crate::limits::MAX_COORDINATE;
        for (p, key) in [(position, "camera.position"), (look_at, "camera.look_at")] {
            if p.abs().max_element() > limit {
                return Err(self.err(
                    span.clone(),
                    key,
                    format!(
                        "{:?} lies beyond {limit:e} scene units; coordinates must be within it (choose a larger unit)",
                        p.to_array()
                    ),
                ));
            }
        }
        let forward = look_at - position;
        if forward.length_squared() == 0.0 {
            return Err(self.err(
                span,
                "camera.look_at",
                "look_at equals position; the view direction is undefined",
            ));
        }
        if forward.normalize().cross(up).length() < 1e-9 {
            return Err(self.err(
                up_s.span(),
                "camera.up",
                format!(
                    "{:?} is zero or parallel to the view direction; it must not be",
                    up.to_array()
                ),
            ));
        }
        let (fov_y, film_aspect) = match (&d.fov, &d.focal_length, &d.film_size) {
            (Some(f), None, None) => {
                let v = *f.get_ref();
                if !(v > 0.0 && v < 180.0) {
                    return Err(self.err(f.span(), "camera.fov", format!("{v:?} degrees is out of range; allowed (0, 180)")));
                }
                (v, None)
            }
            (None, Some(fl), Some(fs)) => {
                let f = *fl.get_ref();
                let [w, h] = *fs.get_ref();
                if !(f.is_finite() && f > 0.0) {
                    return Err(self.err(fl.span(), "camera.focal_length", format!("{f:?} must be a finite length > 0 (metres)")));
                }
                if !(w.is_finite() && h.is_finite() && w > 0.0 && h > 0.0) {
                    return Err(self.err(fs.span(), "camera.film_size", format!("[{w:?}, {h:?}] must be two finite lengths > 0 (metres)")));
                }
                (fov_from_film(f, h), Some(w / h))
            }
            _ => {
                return Err(self.err(
                    span,
                    "camera",
                    "give either `fov` (vertical, degrees) or both `focal_length` and `film_size` (metres), not both forms",
                ))
            }
        };
        Ok(CameraSpec {
            position,
            look_at,
            up,
            fov_y,
            film_aspect,
            medium: None,
        })
    }

    fn material(
        &self,
        name: &str,
        m: &Spanned<MaterialDesc>,
        parser: &SpectrumParser,
    ) -> Result<Bsdf, SceneError> {
        const TYPES: &str = "\"diffuse\", \"conductor\", \"dielectric\", \"ward\", \"null\"";
        let key = format!("materials.{name}");
        let d = m.get_ref();
        let kind = self.required(
            &d.kind,
            m.span(),
            &format!("{key}.type"),
            &format!("allowed types: {TYPES}"),
        )?;
        let span = |v: &Option<Spanned<Value>>| v.as_ref().map(|v| v.span());
        let fspan = |v: &Option<Spanned<f64>>| v.as_ref().map(|v| v.span());
        let present = [
            ("reflectance", span(&d.reflectance)),
            ("eta", span(&d.eta)),
            ("k", span(&d.k)),
            ("perfect", d.perfect.as_ref().map(|v| v.span())),
            ("ior", span(&d.ior)),
            ("alpha", fspan(&d.alpha)),
            ("alpha_x", fspan(&d.alpha_x)),
            ("alpha_y", fspan(&d.alpha_y)),
            ("diffuse", span(&d.diffuse)),
            ("specular", span(&d.specular)),
        ];
        let kind_str = kind.get_ref().as_str();
        let allowed: &[&str] = match kind_str {
            "diffuse" => &["reflectance"],
            "conductor" => &["eta", "k", "perfect", "alpha", "alpha_x", "alpha_y"],
            "dielectric" => &["ior", "alpha", "alpha_x", "alpha_y"],
            "ward" => &["diffuse", "specular", "alpha", "alpha_x", "alpha_y"],
            "null" => &[],
            other => {
                return Err(self.err(
                    kind.span(),
                    format!("{key}.type"),
                    format!("unknown material type {other:?}; allowed: {TYPES}"),
                ))
            }
        };
        self.check_keys(&key, kind_str, allowed, &["type"], &present)?;
        let spectrum = |v: &Option<Spanned<Value>>, k: &str, role: Role, what: &str| {
            let s = self.required(v, m.span(), &format!("{key}.{k}"), what)?;
            parser.parse(s, &format!("{key}.{k}"), role)
        };
        match kind_str {
            "null" => Ok(Bsdf::Null(NullInterface)),
            "diffuse" => Ok(Bsdf::Diffuse(Lambertian {
                reflectance: spectrum(
                    &d.reflectance,
                    "reflectance",
                    Role::Reflectance,
                    "a diffuse material needs a reflectance spectrum in [0, 1]",
                )?,
            })),
            "conductor" => {
                let (alpha_x, alpha_y) = self.roughness(&key, d, m.span(), true)?;
                let fresnel = if d.perfect.as_ref().is_some_and(|p| *p.get_ref()) {
                    if let Some(v) = d.eta.as_ref().or(d.k.as_ref()) {
                        return Err(self.err(
                            v.span(),
                            format!("{key}.perfect"),
                            "a perfect mirror has F = 1; remove eta and k, or remove perfect",
                        ));
                    }
                    ConductorFresnel::Perfect
                } else {
                    let what = "a conductor needs its complex index as spectra `eta` (n > 0) and `k` (>= 0), or `perfect = true`";
                    let eta = spectrum(&d.eta, "eta", Role::Index, what)?;
                    let k = spectrum(&d.k, "k", Role::Index, what)?;
                    let ((l, lo), _) = eta.extremes();
                    if lo <= 0.0 {
                        return Err(self.err(d.eta.as_ref().map_or(m.span(), |v| v.span()), format!("{key}.eta"), format!("n = {lo:?} at {l} nm; the real part of a conductor's index must be > 0")));
                    }
                    ConductorFresnel::Complex { eta, k }
                };
                Ok(Bsdf::Conductor(Conductor {
                    fresnel,
                    microfacet: Ggx::rough(alpha_x, alpha_y),
                }))
            }
            "dielectric" => {
                let (alpha_x, alpha_y) = self.roughness(&key, d, m.span(), true)?;
                let v = self.required(&d.ior, m.span(), &format!("{key}.ior"), "a dielectric needs `ior`: a number > 0, a glass name (\"bk7\", \"fused-silica\") or { sellmeier_b = [3 numbers], sellmeier_c = [3 numbers, um^2] }")?;
                let ior = self.ior(&format!("{key}.ior"), v)?;
                Ok(Bsdf::Dielectric(Dielectric {
                    ior,
                    microfacet: Ggx::rough(alpha_x, alpha_y),
                }))
            }
            _ => {
                let (alpha_x, alpha_y) = self.roughness(&key, d, m.span(), false)?;
                let what = "a ward material needs `diffuse` and `specular` reflectance spectra with diffuse + specular <= 1";
                let diffuse = spectrum(&d.diffuse, "diffuse", Role::Reflectance, what)?;
                let specular = spectrum(&d.specular, "specular", Role::Reflectance, what)?;
                let worst = (LAMBDA_MIN as u32..=LAMBDA_MAX as u32)
                    .map(|l| (l, diffuse.eval(l as f64) + specular.eval(l as f64)))
                    .fold((0, 0.0f64), |a, b| if b.1 > a.1 { b } else { a });
                if worst.1 > 1.0 + 1e-12 {
                    return Err(self.err(d.specular.as_ref().map_or(m.span(), |v| v.span()), format!("{key}.specular"), format!("diffuse + specular = {:?} at {} nm; their sum must be <= 1 at every wavelength (energy conservation)", worst.1, worst.0)));
                }
                Ok(Bsdf::Ward(Ward {
                    diffuse,
                    specular,
                    alpha_x,
                    alpha_y,
                }))
            }
        }
    }

    /// `alpha` or `alpha_x` + `alpha_y`; absent = smooth (0) where `smooth_ok`. Allowed
    /// roughness: [1e-4, 1] (Mitsuba clamps below 1e-4; above 1 the lobes are near-uniform).
    fn roughness(
        &self,
        key: &str,
        d: &MaterialDesc,
        span: Range<usize>,
        smooth_ok: bool,
    ) -> Result<(f64, f64), SceneError> {
        let check = |v: &Spanned<f64>, k: &str| -> Result<f64, SceneError> {
            let a = *v.get_ref();
            if (1e-4..=1.0).contains(&a) || (smooth_ok && a == 0.0) {
                Ok(a)
            } else {
                Err(self.err(
                    v.span(),
                    format!("{key}.{k}"),
                    format!(
                        "{a:?} is outside the allowed roughness range [1e-4, 1]{}",
                        if smooth_ok {
                            " (or 0 for a smooth surface)"
                        } else {
                            ""
                        }
                    ),
                ))
            }
        };
        match (&d.alpha, &d.alpha_x, &d.alpha_y) {
            (Some(a), None, None) => {
                let a = check(a, "alpha")?;
                Ok((a, a))
            }
            (None, Some(x), Some(y)) => {
                let (ax, ay) = (check(x, "alpha_x")?, check(y, "alpha_y")?);
                if (ax == 0.0) != (ay == 0.0) {
                    return Err(self.err(x.span(), format!("{key}.alpha_x"), "alpha_x and alpha_y must both be 0 (smooth) or both >= 1e-4"));
                }
                Ok((ax, ay))
            }
            (None, None, None) if smooth_ok => Ok((0.0, 0.0)),
            (Some(a), _, _) => Err(self.err(a.span(), format!("{key}.alpha"), "give either `alpha` or both `alpha_x` and `alpha_y`, not both forms")),
            (None, Some(v), None) | (None, None, Some(v)) => Err(self.err(v.span(), key.to_string(), "anisotropic roughness needs both `alpha_x` and `alpha_y`")),
            (None, None, None) => Err(self.err(span, format!("{key}.alpha"), "missing; a ward material needs a roughness `alpha` (or `alpha_x` and `alpha_y`) in [1e-4, 1]")),
        }
    }

    /// A dielectric's index from a number, a glass name or Sellmeier coefficients.
    fn ior(&self, key: &str, v: &Spanned<Value>) -> Result<Ior, SceneError> {
        let err = |msg: String| self.err(v.span(), key.to_string(), msg);
        let three = |t: &toml::Table, k: &str| -> Result<[f64; 3], SceneError> {
            let arr = t
                .get(k)
                .and_then(|x| x.as_array())
                .ok_or_else(|| err(format!("missing `{k}`: a list of 3 numbers")))?;
            let nums: Vec<f64> = arr
                .iter()
                .filter_map(|x| x.as_float().or(x.as_integer().map(|i| i as f64)))
                .collect();
            if nums.len() != 3 || nums.iter().any(|x| !x.is_finite()) {
                return Err(err(format!("`{k}` must be 3 finite numbers")));
            }
            Ok([nums[0], nums[1], nums[2]])
        };
        let ior = match v.get_ref() {
            Value::Float(_) | Value::Integer(_) => {
                let n = v.get_ref().as_float().or(v.get_ref().as_integer().map(|i| i as f64)).unwrap_or(f64::NAN);
                if !(n.is_finite() && n > 0.0) {
                    return Err(err(format!("{n:?}: an index must be a finite number > 0")));
                }
                Ior::Constant(n)
            }
            Value::String(s) => match s.as_str() {
                "bk7" => Ior::BK7,
                "fused-silica" => Ior::FUSED_SILICA,
                other => return Err(err(format!("unknown glass {other:?}; known: \"bk7\", \"fused-silica\"; or give a number or {{ sellmeier_b, sellmeier_c }}"))),
            },
            Value::Table(t) => {
                if let Some(bad) = t.keys().find(|k| *k != "sellmeier_b" && *k != "sellmeier_c") {
                    return Err(err(format!("unknown key `{bad}`; allowed: sellmeier_b, sellmeier_c")));
                }
                Ior::Sellmeier { b: three(t, "sellmeier_b")?, c: three(t, "sellmeier_c")? }
            }
            other => return Err(err(format!("{other}: expected a number, a glass name or {{ sellmeier_b, sellmeier_c }}"))),
        };
        // Positive and finite over the whole range (a Sellmeier pole inside 360–830 nm is an error).
        for l in LAMBDA_MIN as u32..=LAMBDA_MAX as u32 {
            let n = ior.eval(l as f64);
            if !(n.is_finite() && n > 0.0) {
                return Err(err(format!(
                    "the index is {n} at {l} nm; it must be finite and > 0 over 360-830 nm"
                )));
            }
        }
        Ok(ior)
    }

    /// Rejects keys present in a flat table that its type does not use.
    fn check_keys(
        &self,
        key: &str,
        kind: &str,
        allowed: &[&str],
        common: &[&str],
        present: &[(&str, Option<Range<usize>>)],
    ) -> Result<(), SceneError> {
        for (name, span) in present {
            if let Some(span) = span {
                if !allowed.contains(name) && !common.contains(name) {
                    let mut all: Vec<&str> = common.to_vec();
                    all.extend_from_slice(allowed);
                    return Err(self.err(
                        span.clone(),
                        format!("{key}.{name}"),
                        format!(
                            "`{name}` is not a key of type {kind:?}; its keys are: {}",
                            all.join(", ")
                        ),
                    ));
                }
            }
        }
        Ok(())
    }

    fn shape(
        &self,
        key: &str,
        s: &Spanned<ShapeDesc>,
        materials: &BTreeMap<String, Bsdf>,
        parser: &SpectrumParser,
    ) -> Result<BuiltShape, SceneError> {
        let d = s.get_ref();
        let types: Vec<&str> = SHAPE_TYPES.iter().map(|t| t.0).collect();
        let kind = self.required(
            &d.kind,
            s.span(),
            &format!("{key}.type"),
            &format!("allowed types: {}", types.join(", ")),
        )?;
        let Some((kind_name, allowed)) = SHAPE_TYPES.iter().find(|t| t.0 == kind.get_ref()) else {
            return Err(self.err(
                kind.span(),
                format!("{key}.type"),
                format!(
                    "unknown shape type {:?}; allowed: {}",
                    kind.get_ref(),
                    types.join(", ")
                ),
            ));
        };
        let sp = |o: &Option<Spanned<[f64; 3]>>| o.as_ref().map(|v| v.span());
        self.check_keys(
            key,
            kind_name,
            allowed,
            &SHAPE_COMMON,
            &[
                ("center", sp(&d.center)),
                ("radius", d.radius.as_ref().map(|v| v.span())),
                ("corner", sp(&d.corner)),
                ("edge_u", sp(&d.edge_u)),
                ("edge_v", sp(&d.edge_v)),
                ("vertices", d.vertices.as_ref().map(|v| v.span())),
                ("indices", d.indices.as_ref().map(|v| v.span())),
                ("file", d.file.as_ref().map(|v| v.span())),
            ],
        )?;
        let names: Vec<&str> = materials.keys().map(String::as_str).collect();
        let mat = self.required(
            &d.material,
            s.span(),
            &format!("{key}.material"),
            &format!(
                "every shape needs a material; defined: {}",
                names.join(", ")
            ),
        )?;
        let bsdf = materials.get(mat.get_ref()).cloned().ok_or_else(|| {
            self.err(
                mat.span(),
                format!("{key}.material"),
                format!(
                    "unknown material {:?}; defined materials: [{}]",
                    mat.get_ref(),
                    names.join(", ")
                ),
            )
        })?;
        let flip = d.flip_normals.as_ref().is_some_and(|f| *f.get_ref());
        let need = |field: &str| format!("shape type {kind_name:?} needs `{field}`");
        let shape = match *kind_name {
            "sphere" => {
                let center = self.vec3(
                    self.required(
                        &d.center,
                        s.span(),
                        &format!("{key}.center"),
                        &need("center"),
                    )?,
                    &format!("{key}.center"),
                )?;
                let r = self.required(
                    &d.radius,
                    s.span(),
                    &format!("{key}.radius"),
                    &need("radius"),
                )?;
                let radius = *r.get_ref();
                if !(radius.is_finite() && radius > 0.0) {
                    return Err(self.err(
                        r.span(),
                        format!("{key}.radius"),
                        format!("{radius:?} must be a finite length > 0"),
                    ));
                }
                Shape::Sphere(Sphere {
                    center,
                    radius,
                    flip_normals: flip,
                })
            }
            "quad" => {
                let corner = self.vec3(
                    self.required(
                        &d.corner,
                        s.span(),
                        &format!("{key}.corner"),
                        &need("corner"),
                    )?,
                    &format!("{key}.corner"),
                )?;
                let eu = self.required(
                    &d.edge_u,
                    s.span(),
                    &format!("{key}.edge_u"),
                    &need("edge_u"),
                )?;
                let edge_u = self.vec3(eu, &format!("{key}.edge_u"))?;
                let edge_v = self.vec3(
                    self.required(
                        &d.edge_v,
                        s.span(),
                        &format!("{key}.edge_v"),
                        &need("edge_v"),
                    )?,
                    &format!("{key}.edge_v"),
                )?;
                let q = Quad {
                    corner,
                    edge_u,
                    edge_v,
                    flip_normals: flip,
                };
                if !(q.area() > 0.0 && q.area().is_finite()) {
                    return Err(self.err(eu.span(), format!("{key}.edge_u"), "degenerate quad: edge_u x edge_v is zero (edges zero or parallel); the area must be > 0"));
                }
                Shape::Quad(q)
            }
            "triangles" => {
                let v = self.required(
                    &d.vertices,
                    s.span(),
                    &format!("{key}.vertices"),
                    &need("vertices"),
                )?;
                let ix = self.required(
                    &d.indices,
                    s.span(),
                    &format!("{key}.indices"),
                    &need("indices"),
                )?;
                let positions = v
                    .get_ref()
                    .iter()
                    .map(|p| Vec3::from_array(*p))
                    .collect::<Vec<_>>();
                if let Some(p) = positions.iter().find(|p| !p.is_finite()) {
                    return Err(self.err(
                        v.span(),
                        format!("{key}.vertices"),
                        format!(
                            "vertex {:?} has a non-finite component; coordinates must be finite",
                            p.to_array()
                        ),
                    ));
                }
                let n = positions.len() as i64;
                let mut tris = Vec::with_capacity(ix.get_ref().len());
                for (t, tri) in ix.get_ref().iter().enumerate() {
                    if let Some(bad) = tri.iter().find(|&&k| k < 0 || k >= n) {
                        return Err(self.err(
                            ix.span(),
                            format!("{key}.indices[{t}]"),
                            format!(
                                "index {bad} is out of range; allowed 0..={} ({n} vertices)",
                                n - 1
                            ),
                        ));
                    }
                    tris.push(tri.map(|k| k as u32));
                }
                if tris.is_empty() {
                    return Err(self.err(
                        ix.span(),
                        format!("{key}.indices"),
                        "no triangles; give at least one [i, j, k]",
                    ));
                }
                let tris = with_area(&positions, tris)
                    .map_err(|m| self.err(ix.span(), format!("{key}.indices"), m))?;
                Shape::Mesh(TriangleMesh::new(positions, tris, flip))
            }
            _ => {
                let f = self.required(&d.file, s.span(), &format!("{key}.file"), &need("file"))?;
                let path = self.base.join(f.get_ref());
                self.read.borrow_mut().push(path.clone());
                let data = crate::io::mesh::load_mesh(&path)
                    .map_err(|e| self.err(f.span(), format!("{key}.file"), e.to_string()))?;
                let positions: Vec<Vec3> = data
                    .positions
                    .iter()
                    .map(|p| Vec3::from_array(*p))
                    .collect();
                let tris = with_area(&positions, data.triangles)
                    .map_err(|m| self.err(f.span(), format!("{key}.file"), m))?;
                Shape::Mesh(TriangleMesh::new(positions, tris, flip))
            }
        };
        let emission = match &d.emission {
            Some(e) => {
                let radiance = parser.parse(e, &format!("{key}.emission"), Role::Emission)?;
                let area = shape.area();
                if !(area > 0.0 && area.is_finite()) {
                    return Err(self.err(
                        e.span(),
                        format!("{key}.emission"),
                        format!(
                            "the emitter's area is {area}; an emitter must have a finite area > 0"
                        ),
                    ));
                }
                Some((radiance, d.two_sided.as_ref().is_some_and(|t| *t.get_ref())))
            }
            None => {
                if let Some(t) = &d.two_sided {
                    return Err(self.err(
                        t.span(),
                        format!("{key}.two_sided"),
                        "two_sided only applies to emitters; this shape has no `emission`",
                    ));
                }
                None
            }
        };
        Ok((shape, bsdf, emission))
    }

    fn light(
        &self,
        key: &str,
        l: &Spanned<LightDesc>,
        parser: &SpectrumParser,
    ) -> Result<Light, SceneError> {
        let d = l.get_ref();
        let types: Vec<&str> = LIGHT_TYPES.iter().map(|t| t.0).collect();
        let kind = self.required(
            &d.kind,
            l.span(),
            &format!("{key}.type"),
            &format!("allowed types: {}", types.join(", ")),
        )?;
        let Some((kind_name, allowed)) = LIGHT_TYPES.iter().find(|t| t.0 == kind.get_ref()) else {
            return Err(self.err(
                kind.span(),
                format!("{key}.type"),
                format!(
                    "unknown light type {:?}; allowed: {}",
                    kind.get_ref(),
                    types.join(", ")
                ),
            ));
        };
        self.check_keys(
            key,
            kind_name,
            allowed,
            &["type"],
            &[
                ("position", d.position.as_ref().map(|v| v.span())),
                ("intensity", d.intensity.as_ref().map(|v| v.span())),
                ("radiance", d.radiance.as_ref().map(|v| v.span())),
            ],
        )?;
        let need = |field: &str| format!("light type {kind_name:?} needs `{field}`");
        if *kind_name == "point" {
            let position = self.vec3(
                self.required(
                    &d.position,
                    l.span(),
                    &format!("{key}.position"),
                    &need("position"),
                )?,
                &format!("{key}.position"),
            )?;
            let i = self.required(
                &d.intensity,
                l.span(),
                &format!("{key}.intensity"),
                &need("intensity"),
            )?;
            let intensity = parser.parse(i, &format!("{key}.intensity"), Role::Emission)?;
            Ok(Light::Point {
                position,
                intensity,
            })
        } else {
            let r = self.required(
                &d.radiance,
                l.span(),
                &format!("{key}.radiance"),
                &need("radiance"),
            )?;
            Ok(Light::Environment {
                radiance: parser.parse(r, &format!("{key}.radiance"), Role::Emission)?,
            })
        }
    }
}

/// The triangles of a mesh that have an area (a zero-area triangle can never be hit and would
/// only burden the BVH), or an error when none has; more than
/// [`crate::limits::MAX_TRIANGLES`] is an error too.
fn with_area(positions: &[Vec3], tris: Vec<[u32; 3]>) -> Result<Vec<[u32; 3]>, String> {
    let limit = crate::limits::MAX_TRIANGLES;
    if tris.len() as u64 > limit {
        return Err(format!(
            "{} triangles; the limit is {limit} per mesh",
            tris.len()
        ));
    }
    // (a corner past the bound would overflow the area and pass for a degenerate triangle)
    if let Some((k, p)) = positions
        .iter()
        .enumerate()
        .find(|(_, p)| !p.is_finite() || p.abs().max_element() > crate::limits::MAX_COORDINATE)
    {
        return Err(format!(
            "vertex {k} at {:?} lies beyond {:e} scene units; coordinates must stay within that",
            p.to_array(),
            crate::limits::MAX_COORDINATE
        ));
    }
    let total = tris.len();
    let kept: Vec<[u32; 3]> = tris
        .into_iter()
        .filter(|t| {
            let [a, b, c] = t.map(|k| positions[k as usize]);
            let area = (b - a).cross(c - a).length();
            area > 0.0 && area.is_finite()
        })
        .collect();
    if kept.is_empty() {
        return Err(format!(
            "none of its {total} triangles has an area (all are degenerate: repeated or collinear corners)"
        ));
    }
    Ok(kept)
}
