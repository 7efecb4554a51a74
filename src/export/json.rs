//! furnace scene interchange JSON, version 1 (docs/scene-json.md): a validated scene resolved
//! into plain geometry, linear-sRGB colours and numbers, for the drivers of RGB renderers
//! (Blender Cycles in `reference/cycles/`, LuxCoreRender in `reference/luxcore/`). Quads and
//! flipped meshes become triangles wound so that (p_b − p_a) × (p_c − p_a) is furnace's normal.
//! Spectra become RGB (emission: the film's RGB of the spectrum; reflectance-like quantities:
//! per-channel averages under an equal-energy illuminant, exact for constants); what the
//! format cannot hold (a dispersive index, a non-square pixel) is an error, never approximated.

use super::ExportError;
use crate::geometry::Shape;
use crate::lights::Light;
use crate::math::Vec3;
use crate::media::PhaseFunction;
use crate::scattering::{Bsdf, ConductorFresnel, Ior};
use crate::scene::Scene;
use crate::spectrum::{cie, Observer, Spectrum};
use serde_json::{json, Value};
use std::path::{Path, PathBuf};

/// Name of the format in messages.
const FORMAT: &str = "furnace scene JSON";

/// The film's linear sRGB of a radiance (or intensity) spectrum, in film units: a flat
/// spectrum of 1 has Y = 1 (CIE 1931 by 1 nm sums, the film's observer; sRGB matrix of
/// IEC 61966-2-1).
pub fn emission_rgb(s: &Spectrum) -> [f64; 3] {
    Observer::Cie1931.xyz_to_rgb(cie::tables().spectrum_to_xyz(s))
}

/// The linear sRGB of a reflectance-like spectrum ρ(λ): the RGB of ρ under an equal-energy
/// illuminant divided channel-wise by the RGB of that illuminant, so a constant c gives
/// exactly (c, c, c) (docs/scene-json.md, "Colour").
pub fn reflectance_rgb(s: &Spectrum) -> [f64; 3] {
    if let Spectrum::Constant(c) = s {
        return [*c; 3];
    }
    let white = emission_rgb(&Spectrum::Constant(1.0));
    let rgb = emission_rgb(s);
    std::array::from_fn(|k| rgb[k] / white[k])
}

/// [`emission_rgb`] of an emitted spectrum, refused by name when a channel is negative: a
/// narrow band (360–365 nm, say) lies outside the sRGB gamut, and an RGB renderer clamps the
/// negative channel to 0, which changes Y by a factor of 20 (both Cycles and LuxCore read the
/// same clamped value; reports/renderers/four/FINDINGS.md).
pub fn emission_rgb_in_gamut(
    what: impl Fn() -> String,
    s: &Spectrum,
) -> Result<[f64; 3], ExportError> {
    in_gamut(what, emission_rgb(s), |rgb| {
        format!(
        "an emission spectrum whose linear sRGB is ({:.4e}, {:.4e}, {:.4e}): outside the sRGB gamut, and an RGB renderer clamps a negative channel to 0",
        rgb[0], rgb[1], rgb[2]
    )
    })
}

/// [`reflectance_rgb`] of a quantity that must not be negative (a reflectance, an index, a
/// coefficient): a spectrum outside the sRGB gamut can map to a negative channel, which no
/// renderer can take; it is refused by name rather than clamped.
fn nonnegative_rgb(what: impl Fn() -> String, s: &Spectrum) -> Result<[f64; 3], ExportError> {
    in_gamut(what, reflectance_rgb(s), |rgb| {
        format!(
        "a spectrum whose per-channel RGB is ({:.4}, {:.4}, {:.4}): outside the sRGB gamut, and a negative value is not physical",
        rgb[0], rgb[1], rgb[2]
    )
    })
}

/// `rgb` when every channel is finite and non-negative; else the export of `what` is refused,
/// `why` saying why from the channels.
fn in_gamut(
    what: impl Fn() -> String,
    rgb: [f64; 3],
    why: impl Fn([f64; 3]) -> String,
) -> Result<[f64; 3], ExportError> {
    if rgb.iter().all(|c| *c >= 0.0 && c.is_finite()) {
        return Ok(rgb);
    }
    Err(ExportError::Unsupported {
        format: FORMAT,
        what: what(),
        why: why(rgb),
    })
}

fn v3(p: Vec3) -> Value {
    json!([p.x, p.y, p.z])
}

fn triangles(tris: &[[u32; 3]], flip: bool) -> Value {
    Value::Array(
        tris.iter()
            .map(|t| {
                if flip {
                    json!([t[0], t[2], t[1]])
                } else {
                    json!([t[0], t[1], t[2]])
                }
            })
            .collect(),
    )
}

/// The material of shape `i`.
fn material(i: usize, b: &Bsdf) -> Result<Value, ExportError> {
    let alpha = |g: &Option<crate::scattering::microfacet::Ggx>| {
        g.as_ref().map_or((0.0, 0.0), |g| (g.alpha_x, g.alpha_y))
    };
    let rgb =
        |part: &str, s: &Spectrum| nonnegative_rgb(|| format!("shape[{i}] material {part}"), s);
    Ok(match b {
        Bsdf::Diffuse(l) => json!({"type": "diffuse", "rgb": rgb("reflectance", &l.reflectance)?}),
        Bsdf::Conductor(c) => {
            let (ax, ay) = alpha(&c.microfacet);
            match &c.fresnel {
                ConductorFresnel::Perfect => {
                    json!({"type": "conductor", "eta_rgb": [0.0, 0.0, 0.0],
                    "k_rgb": [0.0, 0.0, 0.0], "perfect": true, "alpha_x": ax, "alpha_y": ay})
                }
                ConductorFresnel::Complex { eta, k } => json!({"type": "conductor",
                    "eta_rgb": rgb("eta", eta)?, "k_rgb": rgb("k", k)?,
                    "perfect": false, "alpha_x": ax, "alpha_y": ay}),
            }
        }
        Bsdf::Dielectric(d) => {
            let Ior::Constant(n) = d.ior else {
                return Err(ExportError::Unsupported {
                    format: FORMAT,
                    what: format!("shape[{i}] material"),
                    why: "a dispersive index: the format's dielectric has one ior for all three channels".into(),
                });
            };
            let (ax, ay) = alpha(&d.microfacet);
            if ax != ay {
                return Err(ExportError::Unsupported {
                    format: FORMAT,
                    what: format!("shape[{i}] material"),
                    why: "an anisotropic rough dielectric: the format's dielectric has one alpha"
                        .into(),
                });
            }
            json!({"type": "dielectric", "ior": n, "alpha": ax})
        }
        Bsdf::Ward(w) => json!({"type": "ward", "diffuse_rgb": rgb("diffuse", &w.diffuse)?,
            "specular_rgb": rgb("specular", &w.specular)?, "alpha_x": w.alpha_x, "alpha_y": w.alpha_y}),
        Bsdf::Null(_) => json!({"type": "null"}),
    })
}

/// Translates `scene` into the interchange JSON (see the module doc).
pub fn export(scene: &Scene) -> Result<Value, ExportError> {
    let r = &scene.render;
    let cam = &scene.camera;
    if let Some(a) = cam.film_aspect {
        let image = r.width as f64 / r.height as f64;
        if (a - image).abs() > 1e-12 * image {
            return Err(ExportError::Unsupported {
                format: FORMAT,
                what: "camera film_aspect".into(),
                why: format!("the format has square pixels; the film aspect {a} differs from the image's {image}"),
            });
        }
    }
    let mut materials = Vec::new();
    let mut shapes = Vec::new();
    for (i, shape) in scene.aggregate.shapes().iter().enumerate() {
        materials.push(material(i, &scene.bsdfs[i])?);
        let emission = match scene.shape_light[i].map(|l| &scene.lights[l as usize]) {
            Some(Light::Area {
                radiance,
                two_sided,
                ..
            }) => {
                json!({"rgb": emission_rgb_in_gamut(|| format!("shape[{i}] emission"), radiance)?,
                "two_sided": two_sided})
            }
            _ => Value::Null,
        };
        let (interior, exterior) = match scene.shape_media[i] {
            Some(b) => (json!(b.interior), json!(b.exterior)),
            None => (Value::Null, Value::Null),
        };
        let mut s = match shape {
            Shape::Sphere(s) => json!({"type": "sphere", "center": v3(s.center),
                "radius": s.radius, "flip_normals": s.flip_normals}),
            Shape::Quad(q) => {
                let c = q.corner;
                let p = [c, c + q.edge_u, c + q.edge_u + q.edge_v, c + q.edge_v];
                json!({"type": "mesh", "positions": p.iter().map(|p| v3(*p)).collect::<Vec<_>>(),
                    "triangles": triangles(&[[0, 1, 2], [0, 2, 3]], q.flip_normals)})
            }
            Shape::Mesh(m) => json!({"type": "mesh",
                "positions": m.positions.iter().map(|p| v3(*p)).collect::<Vec<_>>(),
                "triangles": triangles(&m.triangles, m.flip_normals)}),
        };
        s["material"] = json!(i);
        s["emission"] = emission;
        s["interior"] = interior;
        s["exterior"] = exterior;
        shapes.push(s);
    }
    let mut lights = Vec::new();
    for l in &scene.lights {
        match l {
            Light::Area { .. } => {}
            Light::Point {
                position,
                intensity,
            } => lights.push(json!({"type": "point", "position": v3(*position),
                "intensity_rgb": emission_rgb_in_gamut(|| "point light intensity".into(), intensity)?})),
            Light::Environment { radiance } => {
                lights.push(json!({"type": "environment",
                    "radiance_rgb": emission_rgb_in_gamut(|| "environment radiance".into(), radiance)?}))
            }
        }
    }
    let media: Vec<Value> = scene
        .media
        .iter()
        .zip(&scene.medium_names)
        .map(|(m, name)| {
            let phase = match m.phase {
                PhaseFunction::Isotropic => json!({"type": "isotropic"}),
                PhaseFunction::HenyeyGreenstein(hg) => json!({"type": "hg", "g": hg.g}),
                PhaseFunction::Rayleigh => json!({"type": "rayleigh"}),
            };
            let rgb =
                |part: &str, s: &Spectrum| nonnegative_rgb(|| format!("medium {name} {part}"), s);
            Ok(json!({"sigma_a_rgb": rgb("sigma_a", &m.sigma_a)?,
                "sigma_s_rgb": rgb("sigma_s", &m.sigma_s)?, "phase": phase}))
        })
        .collect::<Result<_, ExportError>>()?;
    Ok(json!({
        "format": "furnace-scene-json",
        "version": 1,
        "exported_by": format!("furnace {}", env!("CARGO_PKG_VERSION")),
        "render": {"width": r.width, "height": r.height, "spp": r.spp, "max_depth": r.max_depth},
        "camera": {"position": v3(cam.position), "look_at": v3(cam.look_at), "up": v3(cam.up),
            "fov_y_deg": cam.fov_y, "medium": cam.medium},
        "materials": materials,
        "shapes": shapes,
        "lights": lights,
        "media": media,
    }))
}

/// Exports `scene` into `dir` as `scene.json`; returns its path.
pub fn write(scene: &Scene, dir: &Path) -> Result<PathBuf, ExportError> {
    super::write_files(dir, &files(scene)?)
}

/// The file of [`write()`]: `scene.json`.
pub fn files(scene: &Scene) -> Result<super::Files, ExportError> {
    let text = serde_json::to_string(&export(scene)?).expect("a JSON value serialises");
    Ok(vec![(PathBuf::from("scene.json"), text.into_bytes())])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scene(text: &str) -> Scene {
        Scene::parse(text, Path::new("inline.toml")).unwrap()
    }

    const CAMERA: &str = "[camera]\nposition = [0.0, 0.0, -3.0]\nlook_at = [0.0, 0.0, 0.0]\nup = [0.0, 1.0, 0.0]\nfov = 40.0\n";

    #[test]
    fn grey_scenes_are_exact_and_windings_keep_the_normal() {
        let s = scene(&format!(
            "{CAMERA}[render]\nwidth = 8\nheight = 4\nspp = 16\nmax_depth = 3\n\
             [materials.w]\ntype = \"diffuse\"\nreflectance = 0.25\n\
             [[shape]]\ntype = \"quad\"\ncorner = [-1.0, -1.0, 1.0]\nedge_u = [2.0, 0.0, 0.0]\nedge_v = [0.0, 2.0, 0.0]\nmaterial = \"w\"\nemission = 2.0\nflip_normals = true\n\
             [[light]]\ntype = \"point\"\nposition = [0.0, 1.0, 0.0]\nintensity = 3.0\n"
        ));
        let j = export(&s).unwrap();
        assert_eq!(j["format"], "furnace-scene-json");
        assert_eq!(j["render"]["max_depth"], 3);
        assert_eq!(j["materials"][0]["rgb"], json!([0.25, 0.25, 0.25]));
        // a flat spectrum of 2 has Y = 2: its RGB is 2 × the RGB of Y-normalised white
        let e = &j["shapes"][0]["emission"];
        assert_eq!(e["two_sided"], false);
        let rgb: [f64; 3] = std::array::from_fn(|k| e["rgb"][k].as_f64().unwrap());
        let y = Observer::Cie1931.rgb_to_xyz(rgb)[1];
        assert!((y - 2.0).abs() < 1e-9, "Y of the emission {y}");
        // flipped: (p_b − p_a) × (p_c − p_a) of the first triangle points along −(u × v) = −z
        let p = |i: u64| -> Vec3 {
            let v = &j["shapes"][0]["positions"][i as usize];
            Vec3::new(
                v[0].as_f64().unwrap(),
                v[1].as_f64().unwrap(),
                v[2].as_f64().unwrap(),
            )
        };
        let t = &j["shapes"][0]["triangles"][0];
        let (a, b, c) = (
            p(t[0].as_u64().unwrap()),
            p(t[1].as_u64().unwrap()),
            p(t[2].as_u64().unwrap()),
        );
        assert!((b - a).cross(c - a).z < 0.0);
        assert_eq!(j["lights"][0]["type"], "point");
    }

    #[test]
    fn what_the_format_cannot_hold_is_refused_by_name() {
        let s = scene(&format!(
            "{CAMERA}[materials.g]\ntype = \"dielectric\"\nior = \"bk7\"\n\
             [[shape]]\ntype = \"sphere\"\ncenter = [0.0, 0.0, 0.0]\nradius = 1.0\nmaterial = \"g\"\n\
             [[light]]\ntype = \"environment\"\nradiance = 1.0\n"
        ));
        let e = export(&s).unwrap_err().to_string();
        assert!(
            e.contains("shape[0] material") && e.contains("dispersive"),
            "{e}"
        );
    }

    #[test]
    fn a_spectrum_outside_the_srgb_gamut_is_refused_not_clamped() {
        // a reflectance that is 0.9 only between 495 and 510 nm: spectral cyan-green, whose
        // red is negative in sRGB
        let s = scene(&format!(
            "{CAMERA}[materials.m]\ntype = \"diffuse\"\n\
             reflectance = {{ wavelengths = [494.0, 495.0, 510.0, 511.0], values = [0.0, 0.9, 0.9, 0.0] }}\n\
             [[shape]]\ntype = \"sphere\"\ncenter = [0.0, 0.0, 0.0]\nradius = 1.0\nmaterial = \"m\"\n\
             [[light]]\ntype = \"environment\"\nradiance = 1.0\n"
        ));
        let e = export(&s).unwrap_err().to_string();
        assert!(
            e.contains("shape[0] material reflectance") && e.contains("sRGB gamut"),
            "{e}"
        );
    }

    #[test]
    fn an_emission_outside_the_srgb_gamut_is_refused_not_clamped() {
        // 360-365 nm, as radiance/band-at-360nm: its linear sRGB has a negative green, which
        // Cycles and LuxCore clamp to 0 (Y 0.00541 instead of 2.48e-4)
        let s = scene(&format!(
            "{CAMERA}[materials.m]\ntype = \"diffuse\"\nreflectance = 0.0\n\
             [spectra]\nband = {{ wavelengths = [359.0, 360.0, 365.0, 366.0], values = [0.0, 1.0, 1.0, 0.0] }}\n\
             [[shape]]\ntype = \"sphere\"\ncenter = [0.0, 0.0, 0.0]\nradius = 1.0\nmaterial = \"m\"\nemission = \"band\"\n"
        ));
        let e = export(&s).unwrap_err().to_string();
        assert!(
            e.contains("shape[0] emission") && e.contains("clamps a negative channel"),
            "{e}"
        );
        // a broad emitter in the gamut still exports
        let s = scene(&format!(
            "{CAMERA}[materials.m]\ntype = \"diffuse\"\nreflectance = 0.0\n\
             [spectra]\nwarm = {{ blackbody = 4000.0, scale = 1.0e-3 }}\n\
             [[shape]]\ntype = \"sphere\"\ncenter = [0.0, 0.0, 0.0]\nradius = 1.0\nmaterial = \"m\"\nemission = \"warm\"\n"
        ));
        assert!(export(&s).is_ok());
    }
}
