//! Invalid manifests: every error names the manifest file, line, column and key, and says what
//! is allowed; `furnace check` exits 2 on them. Messages are snapshotted.

use crate::root;
use furnace::harness::manifest;
use std::path::Path;
use std::process::Command;

fn error_of(text: &str) -> String {
    // anchored in tests/manifests so that relative scene paths resolve like the real ones
    match manifest::parse(text, &root("tests/manifests/bad.toml")) {
        Ok(specs) => panic!("manifest accepted ({} checks):\n{text}", specs.len()),
        Err(e) => e.to_string().replace(&root("").display().to_string(), ""),
    }
}

#[test]
fn manifest_error_messages() {
    let cases: Vec<(&str, String)> = vec![
        ("toml_syntax", error_of("[[check]\nname = \"x\"\n")),
        ("unknown_top_level_key", error_of("checks = 1\n")),
        ("unknown_check_key", error_of("[[check]]\nname = \"x\"\nkind = \"reciprocity\"\nsampels = 3\n")),
        ("unknown_kind", error_of("[[check]]\nname = \"x\"\nkind = \"furnice\"\n")),
        ("key_of_another_kind", error_of("[[check]]\nname = \"x\"\nkind = \"reciprocity\"\ndistances = [1.0]\n")),
        ("missing_name", error_of("[[check]]\nkind = \"reciprocity\"\n")),
        ("missing_scene", error_of("[[check]]\nname = \"x\"\nkind = \"furnace\"\n")),
        ("missing_scene_file", error_of("[[check]]\nname = \"x\"\nkind = \"furnace\"\nscene = \"scenes/nope.toml\"\n")),
        ("invalid_scene", error_of("[[check]]\nname = \"x\"\nkind = \"furnace\"\n[check.scene]\ncamera = 3\n")),
        // an inline scene's errors name the manifest's own lines, in the second check too
        ("inline_scene_unknown_key", error_of("[[check]]\nname = \"y\"\nkind = \"hg\"\n\n[[check]]\nname = \"x\"\nkind = \"furnace\"\n[check.scene]\n[check.scene.camera]\nlook_at = [0, 0, 0]\neye = [0, 0, 5]\n")),
        ("inline_scene_without_camera", error_of("[[check]]\nname = \"x\"\nkind = \"furnace\"\n\n[check.scene]\n[[check.scene.shape]]\ntype = \"sphere\"\n")),
        ("unresolved_placeholder", error_of("[[check]]\nname = \"x\"\nkind = \"furnace\"\nscene = \"scenes/furnace-sphere.toml\"\n")),
        ("unknown_placeholder", error_of("[[check]]\nname = \"x\"\nkind = \"furnace\"\nscene = \"scenes/furnace-sphere.toml\"\nvary = { albedo = [0.5], colour = [1.0] }\n")),
        ("vary_nan", error_of("[[check]]\nname = \"x\"\nkind = \"furnace\"\nscene = \"scenes/furnace-sphere.toml\"\nvary = { albedo = [0.5, nan] }\n")),
        ("spp_past_toml_integers", error_of("[[check]]\nname = \"x\"\nkind = \"furnace\"\nscene = \"scenes/furnace-sphere-0.5.toml\"\nspp = 18446744073709551615\n")),
        ("empty_vary", error_of("[[check]]\nname = \"x\"\nkind = \"furnace\"\nscene = \"scenes/furnace-sphere.toml\"\nvary = { albedo = [] }\n")),
        ("spp_one", error_of("[[check]]\nname = \"x\"\nkind = \"furnace\"\nscene = \"scenes/furnace-sphere-0.5.toml\"\nspp = 1\n")),
        ("g_out_of_range", error_of("[[check]]\nname = \"x\"\nkind = \"hg\"\ng = [0.5, 1.0]\n")),
        ("tolerance_too_large", error_of("[[check]]\nname = \"x\"\nkind = \"lambert\"\nscene = \"scenes/lambert-sky.toml\"\nrel_tolerance = 0.5\n")),
        ("roulette_off_without_depth", error_of("[[check]]\nname = \"x\"\nkind = \"furnace\"\nscene = \"scenes/furnace-sphere-0.5.toml\"\nroulette = false\n")),
        ("bad_region", error_of("[[check]]\nname = \"x\"\nkind = \"furnace\"\nscene = \"scenes/furnace-sphere-0.5.toml\"\nregion = [4, 4, 2, 8]\n")),
        // found when the manifest is loaded, not when the check runs
        ("region_past_the_image", error_of("[[check]]\nname = \"x\"\nkind = \"furnace\"\nscene = \"scenes/furnace-sphere-0.5.toml\"\nwidth = 16\nregion = [0, 0, 17, 8]\n")),
        ("image_compare_reference_not_an_exr", error_of("[[check]]\nname = \"x\"\nkind = \"image_compare\"\nscene = \"scenes/furnace-sphere-0.5.toml\"\nreference = \"scenes/furnace-sphere-0.5.toml\"\n")),
        ("measured_file_not_a_measurement", error_of("[[check]]\nname = \"x\"\nkind = \"measured\"\nscene = \"scenes/furnace-sphere-0.5.toml\"\nmeasurement = \"../../reference/mitsuba/furnace-sphere.exr\"\n")),
        ("scale_without_of", error_of("[[check]]\nname = \"x\"\nkind = \"scale_invariance\"\nscene = \"scenes/furnace-sphere-0.5.toml\"\n")),
        ("lambert_scale_with_depth", error_of("[[check]]\nname = \"x\"\nkind = \"scale_invariance\"\nof = \"lambert\"\nscene = \"scenes/lambert-sky.toml\"\nmax_depth = 3\n")),
        ("image_compare_without_reference", error_of("[[check]]\nname = \"x\"\nkind = \"image_compare\"\nscene = \"scenes/furnace-sphere-0.5.toml\"\n")),
        ("image_compare_missing_reference", error_of("[[check]]\nname = \"x\"\nkind = \"image_compare\"\nscene = \"scenes/furnace-sphere-0.5.toml\"\nreference = \"nope.exr\"\n")),
        ("unknown_observer", error_of("[[check]]\nname = \"x\"\nkind = \"image_compare\"\nscene = \"scenes/furnace-sphere-0.5.toml\"\nreference = \"../../reference/mitsuba/furnace-sphere.exr\"\nobserver = \"cie2006\"\n")),
        ("measured_without_measurement", error_of("[[check]]\nname = \"x\"\nkind = \"measured\"\nscene = \"scenes/furnace-sphere-0.5.toml\"\n")),
        ("light_grid_and_regions", error_of("[[check]]\nname = \"x\"\nkind = \"reciprocity_image\"\nscene = \"scenes/furnace-sphere-0.5.toml\"\ngrid = 3\nregions = \"../../scenes/cornell-box.regions.toml\"\n")),
        ("light_paths_one", error_of("[[check]]\nname = \"x\"\nkind = \"reciprocity_image\"\nscene = \"scenes/furnace-sphere-0.5.toml\"\nlight_paths = 1\n")),
        ("empty_scales", error_of("[[check]]\nname = \"x\"\nkind = \"scale_invariance\"\nof = \"furnace\"\nscene = \"scenes/furnace-sphere-0.5.toml\"\nscales = []\n")),
        ("empty_offsets", error_of("[[check]]\nname = \"x\"\nkind = \"scale_invariance\"\nof = \"furnace\"\nscene = \"scenes/furnace-sphere-0.5.toml\"\noffsets = []\n")),
        ("empty_g", error_of("[[check]]\nname = \"x\"\nkind = \"hg\"\ng = []\n")),
        ("max_bias_above_one", error_of("[[check]]\nname = \"x\"\nkind = \"algorithm_agreement\"\nintegrator = \"radiosity\"\nscene = \"../../scenes/cornell-box.toml\"\nmax_bias = 2.0\n")),
        ("duplicate_names", error_of("[[check]]\nname = \"x\"\nkind = \"reciprocity\"\n[[check]]\nname = \"x\"\nkind = \"energy\"\n")),
    ];
    for (name, message) in cases {
        assert!(message.contains(".toml"), "{name}: {message}");
        insta::assert_snapshot!(name, message);
    }
}

#[test]
fn check_exits_2_on_an_invalid_manifest_and_1_on_a_failing_check() {
    let dir = crate::scratch_dir().join(format!("furnace-manifest-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let bad = dir.join("bad.toml");
    std::fs::write(&bad, "[[check]]\nname = \"x\"\nkind = \"furnice\"\n").unwrap();
    let run = |p: &Path, extra: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_furnace"))
            .current_dir(root(""))
            .arg("check")
            .arg(p)
            .args(extra)
            .output()
            .unwrap()
    };
    let out = run(&bad, &[]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("bad.toml:3:8"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // A white-furnace check whose region includes background pixels: the scene validation
    // turns it into an ERROR, which fails the run (exit 1).
    let failing = dir.join("failing.toml");
    let scene = root("tests/manifests/scenes/white-furnace-sphere.toml")
        .display()
        .to_string();
    std::fs::write(
        &failing,
        format!("[[check]]\nname = \"sees-background\"\nkind = \"furnace\"\nscene = \"{scene}\"\nvary = {{ albedo = [0.5] }}\nspp = 4\n"),
    )
    .unwrap();
    let junit = dir.join("j.xml");
    let json = dir.join("r.json");
    let out = run(
        &failing,
        &[
            "--junit",
            junit.to_str().unwrap(),
            "--json",
            json.to_str().unwrap(),
        ],
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(1), "{stdout}");
    assert!(
        stdout.contains("ERROR") && stdout.contains("escapes"),
        "{stdout}"
    );
    assert!(
        stdout.trim_end().ends_with("0 passed, 1 failed"),
        "{stdout}"
    );
    assert!(std::fs::read_to_string(&junit).unwrap().contains("<error"));
    assert!(std::fs::read_to_string(&json)
        .unwrap()
        .contains("\"schema\": \"furnace.check-results/1\""));
    std::fs::remove_dir_all(&dir).ok();
}
