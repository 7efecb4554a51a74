//! Mitsuba 3 scene XML (format version 3.0.0) plus binary PLY meshes. Each translation keeps
//! Mitsuba's image equal in expectation to furnace's: spectra stay spectra (same unit,
//! W·sr⁻¹·m⁻²·nm⁻¹), `max_depth` follows Mitsuba's convention (bounces + 1), media become
//! `homogeneous` under `volpath`/`volpathmis`; two-sided emission has no one-shape Mitsuba
//! equivalent and is an error. The full mapping: docs/renderers.md, "`export::mitsuba`".

use super::ExportError;
use crate::geometry::Shape;
use crate::lights::Light;
use crate::math::Vec3;
use crate::media::{Medium, PhaseFunction};
use crate::scattering::microfacet::Ggx;
use crate::scattering::{Bsdf, ConductorFresnel, Ior};
use crate::scene::Scene;
use crate::spectrum::curve::planck;
use crate::spectrum::{Spectrum, LAMBDA_MAX, LAMBDA_MIN};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Name of the format in messages.
const FORMAT: &str = "Mitsuba 3";

/// An exported scene: the XML text and the mesh files it references (by relative path).
#[derive(Debug, Clone, PartialEq)]
pub struct MitsubaScene {
    /// The scene XML.
    pub xml: String,
    /// (path relative to the XML's folder, file contents) of each PLY mesh.
    pub meshes: Vec<(String, Vec<u8>)>,
}

/// Translates `scene`; see the module doc for the mapping.
pub fn export(scene: &Scene) -> Result<MitsubaScene, ExportError> {
    let mut x = String::new();
    let mut meshes = Vec::new();
    let r = &scene.render;
    let max_depth = r.max_depth.map_or(-1, |d| d as i64 + 1);
    x.push_str("<?xml version=\"1.0\" encoding=\"utf-8\"?>\n");
    x.push_str("<!-- Exported by furnace ");
    x.push_str(env!("CARGO_PKG_VERSION"));
    x.push_str(" (src/export/mitsuba.rs). max_depth is Mitsuba's: furnace bounces + 1, -1 = unlimited. -->\n");
    x.push_str("<scene version=\"3.0.0\">\n");
    for (name, value) in [
        ("spp", r.spp.to_string()),
        ("width", r.width.to_string()),
        ("height", r.height.to_string()),
        ("seed", "0".to_string()),
        ("max_depth", max_depth.to_string()),
    ] {
        let _ = writeln!(x, "  <default name=\"{name}\" value=\"{value}\"/>");
    }
    // Mitsuba's `volpath` samples distances with the hero wavelength alone (its documentation
    // says it lacks good strategies for spectrally varying extinction); `volpathmis` adds the
    // spectral MIS that furnace uses, so chromatic media get it.
    let integrator = if scene.media.iter().any(|m| !m.is_constant()) {
        "volpathmis"
    } else if scene.has_media() {
        "volpath"
    } else {
        "path"
    };
    let _ = writeln!(x, "  <integrator type=\"{integrator}\">\n    <integer name=\"max_depth\" value=\"$max_depth\"/>\n  </integrator>");
    for (m, name) in scene.media.iter().zip(&scene.medium_names) {
        medium(&mut x, name, m);
    }
    sensor(&mut x, scene);
    let shapes = scene.aggregate.shapes();
    for (i, shape) in shapes.iter().enumerate() {
        match shape {
            Shape::Sphere(s) => {
                let _ = writeln!(x, "  <shape type=\"sphere\" id=\"shape-{i:03}\">");
                let _ = writeln!(x, "    {}", point("center", s.center));
                let _ = writeln!(x, "    <float name=\"radius\" value=\"{}\"/>", s.radius);
                boolean(&mut x, "flip_normals", s.flip_normals);
            }
            Shape::Quad(q) => {
                let c = q.corner;
                let verts = [c, c + q.edge_u, c + q.edge_u + q.edge_v, c + q.edge_v];
                // (p1 − p0) × (p2 − p0) = edge_u × edge_v for both triangles: furnace's normal.
                ply_shape(&mut x, &mut meshes, i, &verts, &[[0, 1, 2], [0, 2, 3]]);
                boolean(&mut x, "flip_normals", q.flip_normals);
            }
            Shape::Mesh(m) => {
                ply_shape(&mut x, &mut meshes, i, &m.positions, &m.triangles);
                boolean(&mut x, "flip_normals", m.flip_normals);
            }
        }
        bsdf(&mut x, i, &scene.bsdfs[i])?;
        if let Some(b) = scene.shape_media[i] {
            for (side, m) in [("interior", b.interior), ("exterior", b.exterior)] {
                if let Some(m) = m {
                    let id = &scene.medium_names[m as usize];
                    let _ = writeln!(x, "    <ref name=\"{side}\" id=\"medium-{id}\"/>");
                }
            }
        }
        if let Some(li) = scene.shape_light[i] {
            if let Light::Area {
                radiance,
                two_sided,
                ..
            } = &scene.lights[li as usize]
            {
                if *two_sided {
                    return Err(ExportError::Unsupported {
                        format: FORMAT,
                        what: format!("shape[{i}] emission with two_sided = true"),
                        why: "Mitsuba's area emitter emits on one side only; use two shapes with opposite normals".into(),
                    });
                }
                x.push_str("    <emitter type=\"area\">\n");
                spectrum(&mut x, 6, "radiance", radiance);
                x.push_str("    </emitter>\n");
            }
        }
        x.push_str("  </shape>\n");
    }
    for light in &scene.lights {
        match light {
            Light::Area { .. } => {}
            Light::Point {
                position,
                intensity,
            } => {
                x.push_str("  <emitter type=\"point\">\n");
                let _ = writeln!(x, "    {}", point("position", *position));
                spectrum(&mut x, 4, "intensity", intensity);
                x.push_str("  </emitter>\n");
            }
            Light::Environment { radiance } => {
                x.push_str("  <emitter type=\"constant\">\n");
                spectrum(&mut x, 4, "radiance", radiance);
                x.push_str("  </emitter>\n");
            }
        }
    }
    x.push_str("</scene>\n");
    Ok(MitsubaScene { xml: x, meshes })
}

/// Exports `scene` into `dir` as `scene.xml` plus `meshes/*.ply`; returns the XML's path.
pub fn write(scene: &Scene, dir: &Path) -> Result<PathBuf, ExportError> {
    super::write_files(dir, &files(scene)?)
}

/// The files of [`write()`]: `scene.xml`, then `meshes/*.ply`.
pub fn files(scene: &Scene) -> Result<super::Files, ExportError> {
    let out = export(scene)?;
    let mut files = vec![(PathBuf::from("scene.xml"), out.xml.into_bytes())];
    files.extend(
        out.meshes
            .into_iter()
            .map(|(rel, bytes)| (PathBuf::from(rel), bytes)),
    );
    Ok(files)
}

fn sensor(x: &mut String, scene: &Scene) {
    let cam = &scene.camera;
    // Clip planes from the scene's extent (shapes, point lights, camera), as wide as possible
    // without losing depth precision: [1e-4, 1e3] × extent.
    let (mut lo, mut hi) = (cam.position, cam.position);
    let mut grow = |p: Vec3| {
        lo = lo.min(p);
        hi = hi.max(p);
    };
    for s in scene.aggregate.shapes() {
        for prim in 0..s.primitive_count() {
            let (a, b) = s.primitive_bounds(prim);
            grow(a);
            grow(b);
        }
    }
    for l in &scene.lights {
        if let Light::Point { position, .. } = l {
            grow(*position);
        }
    }
    let extent = (hi - lo).max_element();
    let extent = if extent > 0.0 { extent } else { 1.0 };
    x.push_str("  <sensor type=\"perspective\">\n");
    x.push_str("    <string name=\"fov_axis\" value=\"y\"/>\n");
    let _ = writeln!(x, "    <float name=\"fov\" value=\"{}\"/>", cam.fov_y);
    let _ = writeln!(
        x,
        "    <float name=\"near_clip\" value=\"{}\"/>",
        1e-4 * extent
    );
    let _ = writeln!(
        x,
        "    <float name=\"far_clip\" value=\"{}\"/>",
        1e3 * extent
    );
    x.push_str("    <transform name=\"to_world\">\n");
    let v = |p: Vec3| format!("{}, {}, {}", p.x, p.y, p.z);
    let _ = writeln!(
        x,
        "      <lookat origin=\"{}\" target=\"{}\" up=\"{}\"/>",
        v(cam.position),
        v(cam.look_at),
        v(cam.up)
    );
    x.push_str("    </transform>\n");
    if let Some(m) = cam.medium {
        let id = &scene.medium_names[m as usize];
        let _ = writeln!(x, "    <ref name=\"medium\" id=\"medium-{id}\"/>");
    }
    x.push_str("    <sampler type=\"independent\">\n      <integer name=\"sample_count\" value=\"$spp\"/>\n      <integer name=\"seed\" value=\"$seed\"/>\n    </sampler>\n");
    x.push_str("    <film type=\"hdrfilm\">\n      <integer name=\"width\" value=\"$width\"/>\n      <integer name=\"height\" value=\"$height\"/>\n      <string name=\"pixel_format\" value=\"rgb\"/>\n      <string name=\"component_format\" value=\"float32\"/>\n      <rfilter type=\"box\"/>\n    </film>\n");
    x.push_str("  </sensor>\n");
}

fn point(name: &str, p: Vec3) -> String {
    format!(
        "<point name=\"{name}\" x=\"{}\" y=\"{}\" z=\"{}\"/>",
        p.x, p.y, p.z
    )
}

/// The `<bsdf>` of shape `i`: furnace's diffuse and conductor models are two-sided, Mitsuba's
/// one-sided, so they are wrapped in `twosided`; GGX roughness is exported as Mitsuba's
/// `alpha` with `distribution = ggx` (Mitsuba's microfacet models use the same separable
/// Smith masking and visible-normal sampling).
fn bsdf(x: &mut String, i: usize, b: &Bsdf) -> Result<(), ExportError> {
    let unsupported = |why: &str| ExportError::Unsupported {
        format: FORMAT,
        what: format!("shape[{i}] material"),
        why: why.into(),
    };
    let rough = |x: &mut String, g: &Ggx, pad: &str| -> Result<(), ExportError> {
        let (ax, ay) = (g.alpha_x, g.alpha_y);
        if ax != ay {
            return Err(unsupported("anisotropic roughness: Mitsuba's tangent frame differs from furnace's, so alpha_u/alpha_v would not line up; use equal alpha_x and alpha_y"));
        }
        let _ = writeln!(x, "{pad}<string name=\"distribution\" value=\"ggx\"/>");
        let _ = writeln!(x, "{pad}<float name=\"alpha\" value=\"{ax}\"/>");
        Ok(())
    };
    match b {
        Bsdf::Diffuse(l) => {
            x.push_str("    <bsdf type=\"twosided\">\n      <bsdf type=\"diffuse\">\n");
            spectrum(x, 8, "reflectance", &l.reflectance);
            x.push_str("      </bsdf>\n    </bsdf>\n");
        }
        Bsdf::Conductor(c) => {
            let kind = if c.is_smooth() {
                "conductor"
            } else {
                "roughconductor"
            };
            let _ = writeln!(
                x,
                "    <bsdf type=\"twosided\">\n      <bsdf type=\"{kind}\">"
            );
            match &c.fresnel {
                ConductorFresnel::Perfect => {
                    x.push_str("        <string name=\"material\" value=\"none\"/>\n");
                }
                ConductorFresnel::Complex { eta, k } => {
                    spectrum(x, 8, "eta", eta);
                    spectrum(x, 8, "k", k);
                }
            }
            if let Some(g) = &c.microfacet {
                rough(x, g, "        ")?;
            }
            x.push_str("      </bsdf>\n    </bsdf>\n");
        }
        Bsdf::Dielectric(d) => {
            let Ior::Constant(n) = d.ior else {
                return Err(unsupported("a dispersive index: Mitsuba 3's dielectrics take a constant int_ior; use a constant ior"));
            };
            let kind = if d.is_smooth() {
                "dielectric"
            } else {
                "roughdielectric"
            };
            let _ = writeln!(x, "    <bsdf type=\"{kind}\">");
            let _ = writeln!(x, "      <float name=\"int_ior\" value=\"{n}\"/>");
            x.push_str("      <float name=\"ext_ior\" value=\"1\"/>\n");
            if let Some(g) = &d.microfacet {
                rough(x, g, "      ")?;
            }
            x.push_str("    </bsdf>\n");
        }
        Bsdf::Null(_) => x.push_str("    <bsdf type=\"null\"/>\n"),
        Bsdf::Ward(_) => {
            return Err(unsupported(
                "the bounded-albedo Ward model has no Mitsuba 3 plugin",
            ))
        }
    }
    Ok(())
}

/// `<medium type="homogeneous">`: Mitsuba parameterises by σt and the single-scattering
/// albedo σs/σt (0 where σt = 0).
fn medium(x: &mut String, name: &str, m: &Medium) {
    let _ = writeln!(x, "  <medium type=\"homogeneous\" id=\"medium-{name}\">");
    if m.is_constant() {
        let (a, sc) = (m.sigma_a.eval(550.0), m.sigma_s.eval(550.0));
        let t = a + sc;
        spectrum(x, 4, "sigma_t", &Spectrum::Constant(t));
        spectrum(
            x,
            4,
            "albedo",
            &Spectrum::Constant(if t > 0.0 { sc / t } else { 0.0 }),
        );
    } else {
        let wavelengths: Vec<f64> = (LAMBDA_MIN as u32..=LAMBDA_MAX as u32)
            .map(f64::from)
            .collect();
        let (mut t, mut al) = (Vec::new(), Vec::new());
        for &l in &wavelengths {
            let (a, sc) = (m.sigma_a.eval(l), m.sigma_s.eval(l));
            t.push(a + sc);
            al.push(if a + sc > 0.0 { sc / (a + sc) } else { 0.0 });
        }
        // A table whose values are all equal is written as one value: Mitsuba builds a
        // sampling distribution over a tabulated albedo and refuses one without mass (all
        // zeros: a purely absorbing medium), but takes a uniform 0.
        let table = |values: Vec<f64>| {
            if values.iter().all(|v| *v == values[0]) {
                Spectrum::Constant(values[0])
            } else {
                Spectrum::table(wavelengths.clone(), values, crate::spectrum::Outside::Clamp)
            }
        };
        spectrum(x, 4, "sigma_t", &table(t));
        spectrum(x, 4, "albedo", &table(al));
    }
    match m.phase {
        PhaseFunction::Isotropic => x.push_str("    <phase type=\"isotropic\"/>\n"),
        PhaseFunction::HenyeyGreenstein(hg) => {
            let _ = writeln!(
                x,
                "    <phase type=\"hg\">\n      <float name=\"g\" value=\"{}\"/>\n    </phase>",
                hg.g
            );
        }
        PhaseFunction::Rayleigh => x.push_str("    <phase type=\"rayleigh\"/>\n"),
    }
    x.push_str("  </medium>\n");
}

fn boolean(x: &mut String, name: &str, v: bool) {
    let _ = writeln!(x, "    <boolean name=\"{name}\" value=\"{v}\"/>");
}

fn ply_shape(
    x: &mut String,
    meshes: &mut Vec<(String, Vec<u8>)>,
    i: usize,
    positions: &[Vec3],
    triangles: &[[u32; 3]],
) {
    let rel = format!("meshes/shape-{i:03}.ply");
    meshes.push((
        rel.clone(),
        crate::io::mesh::ply_binary_f32(positions, triangles),
    ));
    let _ = writeln!(x, "  <shape type=\"ply\" id=\"shape-{i:03}\">");
    let _ = writeln!(x, "    <string name=\"filename\" value=\"{rel}\"/>");
    boolean(x, "face_normals", true);
}

/// One `<spectrum>` element named `name`, indented by `indent` spaces.
fn spectrum(x: &mut String, indent: usize, name: &str, s: &Spectrum) {
    let pad = " ".repeat(indent);
    match s {
        Spectrum::Constant(c) => {
            let _ = writeln!(x, "{pad}<spectrum name=\"{name}\" value=\"{c}\"/>");
        }
        Spectrum::Tabulated {
            wavelengths,
            values,
            outside,
            ..
        } => {
            let pairs = super::table_pairs(wavelengths, values, *outside);
            let _ = writeln!(
                x,
                "{pad}<spectrum name=\"{name}\" value=\"{}\"/>",
                pairs_text(&pairs)
            );
        }
        Spectrum::Blackbody { kelvin, scale } if *scale == 1.0 => {
            let _ = writeln!(x, "{pad}<spectrum type=\"blackbody\" name=\"{name}\">");
            let _ = writeln!(x, "{pad}  <float name=\"temperature\" value=\"{kelvin}\"/>");
            let _ = writeln!(x, "{pad}</spectrum>");
        }
        Spectrum::Blackbody { kelvin, scale } => {
            // Mitsuba's blackbody has no scale: a 1 nm table of scale · Planck (Planck 1901).
            let pairs: Vec<(f64, f64)> = (LAMBDA_MIN as u32..=LAMBDA_MAX as u32)
                .map(|l| (l as f64, scale * planck(l as f64, *kelvin)))
                .collect();
            let _ = writeln!(
                x,
                "{pad}<spectrum name=\"{name}\" value=\"{}\"/>",
                pairs_text(&pairs)
            );
        }
    }
}

fn pairs_text(pairs: &[(f64, f64)]) -> String {
    pairs
        .iter()
        .map(|(l, v)| format!("{l}:{v}"))
        .collect::<Vec<_>>()
        .join(", ")
}
