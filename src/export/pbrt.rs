//! pbrt-v4 scene text (one self-contained `.pbrt` file, meshes inline). Not run here (pbrt-v4
//! is not packaged on these machines): the text is snapshot-tested and the mapping is written
//! from the pbrt-v4 file-format documentation, a starting point to verify with a pbrt build.
//! Every light gets `scale` = furnace's Y of its spectrum, since pbrt-v4 normalises light
//! spectra to unit luminance. The full mapping: docs/renderers.md, "`export::pbrt`".

use super::ExportError;
use crate::geometry::Shape;
use crate::lights::Light;
use crate::math::Vec3;
use crate::scattering::microfacet::Ggx;
use crate::scattering::{Bsdf, ConductorFresnel, Ior};
use crate::scene::Scene;
use crate::spectrum::{cie, Spectrum, LAMBDA_MAX, LAMBDA_MIN};
use std::fmt::Write as _;

const FORMAT: &str = "pbrt-v4";

/// The scene as pbrt-v4 text; `out` names the image pbrt writes; models pbrt-v4 lacks are
/// refused by name.
pub fn export(scene: &Scene, out: &str) -> Result<String, ExportError> {
    if scene.has_media() {
        return Err(ExportError::Unsupported {
            format: FORMAT,
            what: "[media]".into(),
            why: "participating media are not exported to pbrt-v4 yet; export to Mitsuba 3".into(),
        });
    }
    let mut x = String::new();
    let r = &scene.render;
    let cam = &scene.camera;
    let _ = writeln!(
        x,
        "# Exported by furnace {} (src/export/pbrt.rs); not verified with a pbrt build.",
        env!("CARGO_PKG_VERSION")
    );
    // pbrt's fov is that of the shorter image axis; furnace's is vertical.
    let aspect = r.width as f64 / r.height as f64;
    let fov = if aspect >= 1.0 {
        cam.fov_y
    } else {
        (2.0 * ((cam.fov_y.to_radians() / 2.0).tan() * aspect).atan()).to_degrees()
    };
    x.push_str("Scale -1 1 1\n");
    let _ = writeln!(
        x,
        "LookAt {}  {}  {}",
        v3(cam.position),
        v3(cam.look_at),
        v3(cam.up)
    );
    let _ = writeln!(x, "Camera \"perspective\" \"float fov\" [ {fov} ]");
    let _ = writeln!(
        x,
        "Film \"rgb\" \"string filename\" [ \"{out}\" ] \"integer xresolution\" [ {} ] \"integer yresolution\" [ {} ]",
        r.width, r.height
    );
    x.push_str("PixelFilter \"box\"\n");
    let _ = writeln!(
        x,
        "Sampler \"independent\" \"integer pixelsamples\" [ {} ]",
        r.spp
    );
    let _ = writeln!(
        x,
        "Integrator \"path\" \"integer maxdepth\" [ {} ]",
        r.max_depth.unwrap_or(65536)
    );
    x.push_str("WorldBegin\n");
    for light in &scene.lights {
        match light {
            Light::Area { .. } => {}
            Light::Point {
                position,
                intensity,
            } => {
                let _ = writeln!(
                    x,
                    "LightSource \"point\" \"point3 from\" [ {} ] {} \"float scale\" [ {} ]",
                    v3(*position),
                    spectrum("I", intensity),
                    luminance(intensity)
                );
            }
            Light::Environment { radiance } => {
                let _ = writeln!(
                    x,
                    "LightSource \"infinite\" {} \"float scale\" [ {} ]",
                    spectrum("L", radiance),
                    luminance(radiance)
                );
            }
        }
    }
    for (i, shape) in scene.aggregate.shapes().iter().enumerate() {
        let _ = writeln!(x, "AttributeBegin  # shape[{i}]");
        let _ = writeln!(x, "  {}", material(i, &scene.bsdfs[i])?);
        if let Some(li) = scene.shape_light[i] {
            if let Light::Area {
                radiance,
                two_sided,
                ..
            } = &scene.lights[li as usize]
            {
                let _ = writeln!(
                    x,
                    "  AreaLightSource \"diffuse\" {} \"float scale\" [ {} ] \"bool twosided\" [ {two_sided} ]",
                    spectrum("L", radiance),
                    luminance(radiance)
                );
            }
        }
        match shape {
            Shape::Sphere(s) => {
                let _ = writeln!(x, "  Translate {}", v3(s.center));
                if s.flip_normals {
                    x.push_str("  ReverseOrientation\n");
                }
                let _ = writeln!(x, "  Shape \"sphere\" \"float radius\" [ {} ]", s.radius);
            }
            Shape::Quad(q) => {
                if q.flip_normals {
                    x.push_str("  ReverseOrientation\n");
                }
                let c = q.corner;
                let p = [c, c + q.edge_u, c + q.edge_u + q.edge_v, c + q.edge_v];
                mesh(&mut x, &p, &[[0, 1, 2], [0, 2, 3]]);
            }
            Shape::Mesh(m) => {
                if m.flip_normals {
                    x.push_str("  ReverseOrientation\n");
                }
                mesh(&mut x, &m.positions, &m.triangles);
            }
        }
        x.push_str("AttributeEnd\n");
    }
    Ok(x)
}

fn v3(p: Vec3) -> String {
    format!("{} {} {}", p.x, p.y, p.z)
}

fn mesh(x: &mut String, p: &[Vec3], t: &[[u32; 3]]) {
    let pts: Vec<String> = p.iter().map(|&q| v3(q)).collect();
    let idx: Vec<String> = t
        .iter()
        .map(|t| format!("{} {} {}", t[0], t[1], t[2]))
        .collect();
    let _ = writeln!(
        x,
        "  Shape \"trianglemesh\" \"point3 P\" [ {} ] \"integer indices\" [ {} ]",
        pts.join("  "),
        idx.join("  ")
    );
}

/// furnace's Y of a spectrum (∫ S ȳ dλ / ∫ ȳ dλ, 1 nm): the `scale` that makes pbrt-v4's
/// unit-luminance light times its unnormalised film read furnace's Y.
fn luminance(s: &Spectrum) -> f64 {
    cie::tables().spectrum_to_xyz(s)[1]
}

/// The `Material` line of shape `i`. Roughness is passed as GGX α with `remaproughness`
/// false (pbrt-v4's default remaps a perceptual roughness).
fn material(i: usize, b: &Bsdf) -> Result<String, ExportError> {
    // smooth = roughness 0 in pbrt-v4
    let rough = |m: Option<Ggx>| {
        let (ax, ay) = m.map_or((0.0, 0.0), |g| (g.alpha_x, g.alpha_y));
        if ax != ay {
            // pbrt's u and v follow its own (u, v) parameterisation of each shape (default
            // triangle uvs, sphere φ/θ), not furnace's tangent frame
            return Err(ExportError::Unsupported {
                format: FORMAT,
                what: format!("shape[{i}] material"),
                why: "anisotropic roughness: pbrt-v4's u and v directions follow its own shape parameterisation, not furnace's tangent frame, so uroughness/vroughness would not line up; use equal alpha_x and alpha_y".into(),
            });
        }
        Ok(format!("\"float uroughness\" [ {ax} ] \"float vroughness\" [ {ay} ] \"bool remaproughness\" [ false ]"))
    };
    Ok(match b {
        Bsdf::Diffuse(l) => format!(
            "Material \"diffuse\" {}",
            spectrum("reflectance", &l.reflectance)
        ),
        Bsdf::Conductor(c) => {
            let f = match &c.fresnel {
                ConductorFresnel::Perfect => "\"rgb reflectance\" [ 1 1 1 ]".to_string(),
                ConductorFresnel::Complex { eta, k } => {
                    format!("{} {}", spectrum("eta", eta), spectrum("k", k))
                }
            };
            format!("Material \"conductor\" {f} {}", rough(c.microfacet)?)
        }
        Bsdf::Dielectric(d) => {
            let eta = match &d.ior {
                Ior::Constant(n) => format!("\"float eta\" [ {n} ]"),
                Ior::Sellmeier { .. } => {
                    let pairs: Vec<String> = (LAMBDA_MIN as u32..=LAMBDA_MAX as u32)
                        .step_by(5)
                        .map(|l| format!("{l} {}", d.ior.eval(l as f64)))
                        .collect();
                    format!("\"spectrum eta\" [ {} ]", pairs.join(" "))
                }
            };
            format!("Material \"dielectric\" {eta} {}", rough(d.microfacet)?)
        }
        Bsdf::Null(_) => {
            return Err(ExportError::Unsupported {
                format: FORMAT,
                what: format!("shape[{i}] material"),
                why: "null interfaces bound media, which are not exported to pbrt-v4".into(),
            })
        }
        Bsdf::Ward(_) => {
            return Err(ExportError::Unsupported {
                format: FORMAT,
                what: format!("shape[{i}] material"),
                why: "pbrt-v4 has no bounded-albedo Ward model".into(),
            })
        }
    })
}

fn spectrum(name: &str, s: &Spectrum) -> String {
    let pairs: Vec<(f64, f64)> = match s {
        Spectrum::Constant(c) => vec![(LAMBDA_MIN, *c), (LAMBDA_MAX, *c)],
        Spectrum::Tabulated {
            wavelengths,
            values,
            outside,
            ..
        } => {
            let mut p = super::table_pairs(wavelengths, values, *outside);
            if p.len() == 1 {
                // A one-sample table is a spike; pbrt needs two samples.
                p.push((p[0].0 + 1e-3, 0.0));
            }
            p
        }
        Spectrum::Blackbody { kelvin, .. } => {
            return format!("\"blackbody {name}\" [ {kelvin} ]");
        }
    };
    let body: Vec<String> = pairs.iter().map(|(l, v)| format!("{l} {v}")).collect();
    format!("\"spectrum {name}\" [ {} ]", body.join(" "))
}
