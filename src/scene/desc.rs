//! The scene file as written: serde structs that mirror the TOML (unknown keys rejected),
//! every value wrapped in `Spanned` so validation errors can point at line and column.
//! Shapes and lights are flat tables with a `type` key; which keys each type allows is
//! checked in `scene::build`, so that errors name the key and the allowed set.

use serde::Deserialize;
use std::collections::BTreeMap;
use toml::{Spanned, Value};

/// The whole scene file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneDesc {
    /// Render defaults.
    pub render: Option<Spanned<RenderDesc>>,
    /// The camera (required).
    pub camera: Option<Spanned<CameraDesc>>,
    /// Named spectra.
    #[serde(default)]
    pub spectra: BTreeMap<String, Spanned<Value>>,
    /// Named materials.
    #[serde(default)]
    pub materials: BTreeMap<String, Spanned<MaterialDesc>>,
    /// Named participating media.
    #[serde(default)]
    pub media: BTreeMap<String, Spanned<MediumDesc>>,
    /// Shapes, in file order.
    #[serde(default)]
    pub shape: Vec<Spanned<ShapeDesc>>,
    /// Non-surface lights, in file order.
    #[serde(default)]
    pub light: Vec<Spanned<LightDesc>>,
}

/// `[render]`: defaults for `furnace render`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RenderDesc {
    /// Image width, pixels.
    pub width: Option<Spanned<i64>>,
    /// Image height, pixels.
    pub height: Option<Spanned<i64>>,
    /// Samples per pixel.
    pub spp: Option<Spanned<i64>>,
    /// Maximum number of bounces.
    pub max_depth: Option<Spanned<i64>>,
    /// Pixel filter name.
    pub filter: Option<Spanned<String>>,
}

/// `[camera]`: a pinhole.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraDesc {
    /// Eye position.
    pub position: Option<Spanned<[f64; 3]>>,
    /// Point looked at.
    pub look_at: Option<Spanned<[f64; 3]>>,
    /// Up hint.
    pub up: Option<Spanned<[f64; 3]>>,
    /// Vertical field of view, degrees.
    pub fov: Option<Spanned<f64>>,
    /// Focal length, metres.
    pub focal_length: Option<Spanned<f64>>,
    /// Film size [width, height], metres.
    pub film_size: Option<Spanned<[f64; 2]>>,
    /// Name of the medium the camera sits in.
    pub medium: Option<Spanned<String>>,
}

/// `[media.NAME]`: a homogeneous medium.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MediumDesc {
    /// Absorption coefficient spectrum, per scene unit.
    pub sigma_a: Option<Spanned<Value>>,
    /// Scattering coefficient spectrum, per scene unit.
    pub sigma_s: Option<Spanned<Value>>,
    /// Phase function name.
    pub phase: Option<Spanned<String>>,
    /// Henyey–Greenstein asymmetry.
    pub g: Option<Spanned<f64>>,
}

/// `[materials.NAME]`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialDesc {
    /// Material type.
    #[serde(rename = "type")]
    pub kind: Option<Spanned<String>>,
    /// Reflectance spectrum (diffuse).
    pub reflectance: Option<Spanned<Value>>,
    /// Real part of a conductor's complex index (spectrum).
    pub eta: Option<Spanned<Value>>,
    /// Extinction coefficient of a conductor (spectrum).
    pub k: Option<Spanned<Value>>,
    /// A perfect mirror conductor (F = 1), instead of `eta` and `k`.
    pub perfect: Option<Spanned<bool>>,
    /// Dielectric index: a number, a glass name, or `{ sellmeier_b, sellmeier_c }`.
    pub ior: Option<Spanned<Value>>,
    /// Isotropic roughness (GGX α for conductors and dielectrics, slope α for Ward).
    pub alpha: Option<Spanned<f64>>,
    /// Roughness along the local x axis (anisotropic).
    pub alpha_x: Option<Spanned<f64>>,
    /// Roughness along the local y axis (anisotropic).
    pub alpha_y: Option<Spanned<f64>>,
    /// Ward diffuse reflectance.
    pub diffuse: Option<Spanned<Value>>,
    /// Ward specular reflectance.
    pub specular: Option<Spanned<Value>>,
}

/// `[[shape]]`: the union of every shape type's keys.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ShapeDesc {
    /// Shape type.
    #[serde(rename = "type")]
    pub kind: Option<Spanned<String>>,
    /// Material name.
    pub material: Option<Spanned<String>>,
    /// Emitted radiance spectrum.
    pub emission: Option<Spanned<Value>>,
    /// Emit on both sides.
    pub two_sided: Option<Spanned<bool>>,
    /// Reverse the normals.
    pub flip_normals: Option<Spanned<bool>>,
    /// Sphere centre.
    pub center: Option<Spanned<[f64; 3]>>,
    /// Sphere radius.
    pub radius: Option<Spanned<f64>>,
    /// Quad corner.
    pub corner: Option<Spanned<[f64; 3]>>,
    /// Quad first edge.
    pub edge_u: Option<Spanned<[f64; 3]>>,
    /// Quad second edge.
    pub edge_v: Option<Spanned<[f64; 3]>>,
    /// Inline mesh vertices.
    pub vertices: Option<Spanned<Vec<[f64; 3]>>>,
    /// Inline mesh triangles.
    pub indices: Option<Spanned<Vec<[i64; 3]>>>,
    /// Mesh file (OBJ or PLY).
    pub file: Option<Spanned<String>>,
    /// Medium on the side opposite the normal.
    pub interior: Option<Spanned<String>>,
    /// Medium on the side the normal points to.
    pub exterior: Option<Spanned<String>>,
}

/// `[[light]]`: the union of every light type's keys.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LightDesc {
    /// Light type.
    #[serde(rename = "type")]
    pub kind: Option<Spanned<String>>,
    /// Point light position.
    pub position: Option<Spanned<[f64; 3]>>,
    /// Point light intensity spectrum.
    pub intensity: Option<Spanned<Value>>,
    /// Environment radiance spectrum.
    pub radiance: Option<Spanned<Value>>,
}
