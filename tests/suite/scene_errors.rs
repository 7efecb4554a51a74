//! Every class of invalid scene gets a clear error naming file, line, column, key and what is
//! allowed, never a panic; each message is snapshotted.

use furnace::scene::Scene;
use std::path::Path;

const BASE: &str = r#"
[camera]
position = [0, 0, 0]
look_at = [0, 0, 1]
up = [0, 1, 0]
fov = 60
[materials.m]
type = "diffuse"
reflectance = 0.5
"#;

fn error_of(extra: &str) -> String {
    let text = format!("{BASE}{extra}");
    match Scene::parse(&text, Path::new("tests/suite/bad.toml")) {
        Ok(_) => panic!("scene was accepted:\n{extra}"),
        Err(e) => e.to_string(),
    }
}

const LIGHT: &str = "\n[[light]]\ntype = \"environment\"\nradiance = 1\n";

#[test]
fn error_messages() {
    let cases: Vec<(&str, String)> = vec![
        ("toml_syntax", error_of("[[shape]\n")),
        ("unknown_top_level_key", Scene::parse(&format!("colour = 3\n{BASE}{LIGHT}"), Path::new("tests/suite/bad.toml")).unwrap_err().to_string()),
        ("unknown_material_key", error_of("colour = 3\n")),
        ("unknown_shape_key", error_of(&format!("[[shape]]\ntype = \"sphere\"\ncenter = [0,0,0]\nradius = 1\nmaterial = \"m\"\nradus = 2\n{LIGHT}"))),
        ("key_of_another_shape_type", error_of(&format!("[[shape]]\ntype = \"sphere\"\ncenter = [0,0,0]\nradius = 1\ncorner = [0,0,0]\nmaterial = \"m\"\n{LIGHT}"))),
        ("unknown_shape_type", error_of("[[shape]]\ntype = \"cube\"\nmaterial = \"m\"\n")),
        ("reflectance_above_one", error_of(&format!("[materials.hot]\ntype = \"diffuse\"\nreflectance = {{ wavelengths = [400, 500, 600], values = [0.5, 1.2, 0.5] }}\n{LIGHT}"))),
        ("negative_reflectance", error_of(&format!("[materials.neg]\ntype = \"diffuse\"\nreflectance = -0.1\n{LIGHT}"))),
        ("negative_radiance", error_of("[[light]]\ntype = \"environment\"\nradiance = { wavelengths = [400, 700], values = [1, -1] }\n")),
        ("nan_value", error_of("[[light]]\ntype = \"environment\"\nradiance = nan\n")),
        ("nan_coordinate", error_of(&format!("[[shape]]\ntype = \"sphere\"\ncenter = [0,nan,0]\nradius = 1\nmaterial = \"m\"\n{LIGHT}"))),
        ("zero_radius", error_of(&format!("[[shape]]\ntype = \"sphere\"\ncenter = [0,0,0]\nradius = 0\nmaterial = \"m\"\n{LIGHT}"))),
        ("degenerate_quad_emitter", error_of("[[shape]]\ntype = \"quad\"\ncorner = [0,0,0]\nedge_u = [1,0,0]\nedge_v = [2,0,0]\nmaterial = \"m\"\nemission = 1\n")),
        ("zero_area_triangle_emitter", error_of("[[shape]]\ntype = \"triangles\"\nvertices = [[0,0,0],[1,0,0],[2,0,0]]\nindices = [[0,1,2]]\nmaterial = \"m\"\nemission = 1\n")),
        ("index_out_of_range", error_of(&format!("[[shape]]\ntype = \"triangles\"\nvertices = [[0,0,0],[1,0,0],[0,1,0]]\nindices = [[0,1,3]]\nmaterial = \"m\"\n{LIGHT}"))),
        ("missing_mesh_file", error_of(&format!("[[shape]]\ntype = \"mesh\"\nfile = \"no-such-mesh.obj\"\nmaterial = \"m\"\n{LIGHT}"))),
        ("unknown_material", error_of(&format!("[[shape]]\ntype = \"sphere\"\ncenter = [0,0,0]\nradius = 1\nmaterial = \"gold\"\n{LIGHT}"))),
        ("unknown_material_type", error_of(&format!("[materials.x]\ntype = \"plastic\"\nreflectance = 0.5\n{LIGHT}"))),
        ("unknown_spectrum_name", error_of(&format!("[materials.x]\ntype = \"diffuse\"\nreflectance = \"beige\"\n{LIGHT}"))),
        ("wavelengths_not_increasing", error_of("[[light]]\ntype = \"environment\"\nradiance = { wavelengths = [500, 400], values = [1, 1] }\n")),
        ("unknown_spectrum_table_key", error_of("[[light]]\ntype = \"environment\"\nradiance = { wavelength = [500], values = [1] }\n")),
        ("missing_csv_file", error_of("[[light]]\ntype = \"environment\"\nradiance = { csv = \"nope.csv\", column = \"x\" }\n")),
        ("unknown_csv_column", error_of("[[light]]\ntype = \"environment\"\nradiance = { csv = \"../../reference/cornell-box/cornell_box_reflectance.csv\", column = \"blue\" }\n")),
        ("negative_blackbody", error_of("[[light]]\ntype = \"environment\"\nradiance = { blackbody = -5 }\n")),
        ("no_light", error_of("[[shape]]\ntype = \"sphere\"\ncenter = [0,0,0]\nradius = 1\nmaterial = \"m\"\n")),
        ("two_sided_without_emission", error_of(&format!("[[shape]]\ntype = \"sphere\"\ncenter = [0,0,0]\nradius = 1\nmaterial = \"m\"\ntwo_sided = true\n{LIGHT}"))),
        ("negative_spp", error_of(&format!("[render]\nspp = -4\n{LIGHT}"))),
        ("template_placeholder", error_of("[[light]]\ntype = \"environment\"\nradiance = ${r}\n")),
        ("spp_as_string", error_of(&format!("[render]\nspp = \"1024\"\n{LIGHT}"))),
        ("unknown_filter", error_of(&format!("[render]\nfilter = \"mitchell\"\n{LIGHT}"))),
        ("two_environment_lights", error_of(&format!("{LIGHT}{LIGHT}"))),
        ("ward_albedo_above_one", error_of(&format!("[materials.x]\ntype = \"ward\"\ndiffuse = 0.5\nspecular = 0.6\nalpha = 0.2\n{LIGHT}"))),
        ("roughness_out_of_range", error_of(&format!("[materials.x]\ntype = \"conductor\"\nperfect = true\nalpha = 2.0\n{LIGHT}"))),
        ("negative_conductor_k", error_of(&format!("[materials.x]\ntype = \"conductor\"\neta = 0.2\nk = -1.0\n{LIGHT}"))),
        ("conductor_without_index", error_of(&format!("[materials.x]\ntype = \"conductor\"\nalpha = 0.1\n{LIGHT}"))),
        ("dielectric_key_on_conductor", error_of(&format!("[materials.x]\ntype = \"conductor\"\nperfect = true\nior = 1.5\n{LIGHT}"))),
        ("nan_ior", error_of(&format!("[materials.x]\ntype = \"dielectric\"\nior = nan\n{LIGHT}"))),
        ("unknown_glass", error_of(&format!("[materials.x]\ntype = \"dielectric\"\nior = \"flint\"\n{LIGHT}"))),
        ("sellmeier_pole_in_range", error_of(&format!("[materials.x]\ntype = \"dielectric\"\nior = {{ sellmeier_b = [1.0, 0.0, 0.0], sellmeier_c = [0.25, 0.0, 0.0] }}\n{LIGHT}"))),
        ("medium_hg_g_out_of_range", error_of(&format!("[media.fog]\nsigma_a = 0\nsigma_s = 1\nphase = \"hg\"\ng = 1.0\n{LIGHT}"))),
        ("medium_negative_sigma", error_of(&format!("[media.fog]\nsigma_a = {{ wavelengths = [400, 700], values = [0.1, -0.1] }}\nsigma_s = 1\nphase = \"isotropic\"\n{LIGHT}"))),
        ("medium_missing_sigma_a", error_of(&format!("[media.fog]\nsigma_s = 1\nphase = \"isotropic\"\n{LIGHT}"))),
        ("medium_g_with_isotropic", error_of(&format!("[media.fog]\nsigma_a = 0\nsigma_s = 1\nphase = \"isotropic\"\ng = 0.3\n{LIGHT}"))),
        ("medium_unknown_phase", error_of(&format!("[media.fog]\nsigma_a = 0\nsigma_s = 1\nphase = \"mie\"\n{LIGHT}"))),
        ("medium_unknown_key", error_of(&format!("[media.fog]\nsigma_a = 0\nsigma_s = 1\nphase = \"isotropic\"\nalbedo = 0.5\n{LIGHT}"))),
        ("unknown_interior_medium", error_of(&format!("[[shape]]\ntype = \"sphere\"\ncenter = [0,0,0]\nradius = 1\nmaterial = \"m\"\ninterior = \"smoke\"\n{LIGHT}"))),
        ("null_material_without_medium", error_of(&format!("[materials.n]\ntype = \"null\"\n[[shape]]\ntype = \"sphere\"\ncenter = [0,0,0]\nradius = 1\nmaterial = \"n\"\n{LIGHT}"))),
        ("medium_coefficient_too_large", error_of(&format!("[media.fog]\nsigma_a = 0\nsigma_s = 1e16\nphase = \"isotropic\"\n{LIGHT}"))),
        ("power_law_overflows", error_of(&format!("[media.fog]\nsigma_a = 0\nsigma_s = {{ power_law = 16, reference = 1e-30 }}\nphase = \"isotropic\"\n{LIGHT}"))),
        ("power_law_without_reference", error_of(&format!("[media.fog]\nsigma_a = 0\nsigma_s = {{ power_law = -4 }}\nphase = \"rayleigh\"\n{LIGHT}"))),
    ];
    for (name, message) in cases {
        assert!(
            message.starts_with("tests/suite/bad.toml:") || message.contains(".csv:"),
            "{name}: {message}"
        );
        insta::assert_snapshot!(name, message);
    }
}

#[test]
fn camera_errors() {
    let camera_cases = [
        ("camera_both_forms", "[camera]\nposition = [0,0,0]\nlook_at = [0,0,1]\nup = [0,1,0]\nfov = 40\nfocal_length = 0.035\nfilm_size = [0.025, 0.025]\n"),
        ("camera_beyond_the_coordinate_limit", "[camera]\nposition = [0,1,-1e300]\nlook_at = [0,0,0]\nup = [0,1,0]\nfov = 40\n"),
        ("camera_up_parallel", "[camera]\nposition = [0,0,0]\nlook_at = [0,0,1]\nup = [0,0,2]\nfov = 40\n"),
        ("camera_fov_out_of_range", "[camera]\nposition = [0,0,0]\nlook_at = [0,0,1]\nup = [0,1,0]\nfov = 180\n"),
        ("camera_missing", "[[light]]\ntype = \"environment\"\nradiance = 1\n"),
        ("camera_medium_unbounded", "[camera]\nposition = [0,0,0]\nlook_at = [0,0,1]\nup = [0,1,0]\nfov = 40\nmedium = \"fog\"\n[media.fog]\nsigma_a = 0\nsigma_s = 1\nphase = \"isotropic\"\n"),
    ];
    for (name, text) in camera_cases {
        let e = Scene::parse(&format!("{text}{LIGHT}"), Path::new("cam.toml"))
            .unwrap_err()
            .to_string();
        insta::assert_snapshot!(name, e);
    }
}

/// A huge or tiny number in a message is written in exponent form, not in the 300 digits
/// Rust's `{}` gives 1e300 (found by replacing every number of the bundled scenes in turn).
#[test]
fn huge_and_tiny_numbers_are_quoted_short() {
    let cam = "[camera]\nposition = [0,0,0]\nlook_at = [0,0,1]\nup = [0,1,0]\n";
    let cases = [
        format!("{cam}fov = 1e300\n{LIGHT}"),
        format!("{cam}focal_length = -1e300\nfilm_size = [0.025, 0.025]\n{LIGHT}"),
        format!("{cam}focal_length = 0.035\nfilm_size = [-1e-310, 0.025]\n{LIGHT}"),
        error_input("[[shape]]\ntype = \"sphere\"\ncenter = [0,0,0]\nradius = -1e300\nmaterial = \"m\"\n"),
        error_input("[materials.r]\ntype = \"ward\"\nreflectance = 0.5\nalpha = 1e-310\n"),
        error_input("[materials.r]\ntype = \"diffuse\"\nreflectance = { wavelengths = [400, -1e300], values = [0.5, 0.5] }\n"),
        error_input("[materials.r]\ntype = \"dielectric\"\nior = -1e300\n"),
        error_input("[media.fog]\nsigma_a = 0\nsigma_s = { power_law = 1e300, reference = 550, scale = 1 }\nphase = \"rayleigh\"\n"),
        error_input("[media.fog]\nsigma_a = 0\nsigma_s = 1\nphase = \"hg\"\ng = -1e300\n"),
        error_input("[[light]]\ntype = \"environment\"\nradiance = { blackbody = -1e300, scale = 1 }\n"),
        error_input("[[light]]\ntype = \"environment\"\nradiance = -1e300\n"),
    ];
    for text in cases {
        let e = match Scene::parse(&text, Path::new("bad.toml")) {
            Ok(_) => panic!("accepted:\n{text}"),
            Err(e) => e.to_string(),
        };
        let digits = e
            .split(|c: char| !c.is_ascii_digit())
            .map(str::len)
            .max()
            .unwrap_or(0);
        assert!(digits <= 20, "{e}");
    }
    // a value of another type is quoted as TOML writes it, not as Rust's debug form
    let e = Scene::parse(
        &error_input(
            "[[light]]\ntype = \"environment\"\nradiance = { blackbody = 3000, scale = \"big\" }\n",
        ),
        Path::new("bad.toml"),
    )
    .err()
    .unwrap()
    .to_string();
    assert!(
        e.contains("scale = \"big\" must be") && !e.contains("String("),
        "{e}"
    );
}

fn error_input(extra: &str) -> String {
    format!("{BASE}{extra}{LIGHT}")
}

#[test]
fn arbitrary_garbage_never_panics() {
    // Every prefix of a valid scene either parses or errors; none panics.
    let full = format!("{BASE}[[shape]]\ntype = \"quad\"\ncorner = [0,0,0]\nedge_u = [1,0,0]\nedge_v = [0,1,0]\nmaterial = \"m\"\nemission = {{ blackbody = 3000 }}\n");
    for cut in 0..full.len() {
        if full.is_char_boundary(cut) {
            let _ = Scene::parse(&full[..cut], Path::new("prefix.toml"));
        }
    }
}
