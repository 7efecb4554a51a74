//! External renderers through the adapter, without Python: a stand-in renderer that is the
//! `furnace render` command itself (ignoring the exported scene and rendering a fixed scene
//! file) goes through the whole black-box path: export, K independent runs, EXR reading, RGB →
//! XYZ, statistics. It must pass the furnace check of the scene it renders and fail the check
//! of a scene with another albedo (negative control); an unavailable renderer is skipped.

use crate::root;
use furnace::harness::adapter::{load_renderers, External};
use furnace::harness::manifest;
use furnace::harness::outcome::Verdict;
use furnace::harness::{self, RunOptions};
use std::process::Command;

fn renderers(scene: &str, probe: &str) -> std::path::PathBuf {
    let text = format!(
        "[renderer.stand-in]\nexporter = \"mitsuba3\"\nobserver = \"cie1931\"\nbatches = 4\nprobe = [{probe}]\ncommand = [{:?}, \"render\", {scene:?}, \"--out\", \"{{out}}\", \"--spp\", \"{{spp}}\", \"--seed\", \"{{seed}}\", \"--width\", \"{{width}}\", \"--height\", \"{{height}}\", \"--threads\", \"{{threads}}\", \"--quiet\"]\n",
        env!("CARGO_BIN_EXE_furnace")
    );
    // one file per call: tests run in parallel and must not share a table
    static CALLS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let p = crate::scratch_dir().join(format!(
        "furnace-adapter-{}-{}.toml",
        std::process::id(),
        CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed)
    ));
    std::fs::write(&p, text).unwrap();
    p
}

/// [`renderers`] with `keys` (TOML lines) added to the stand-in's table.
fn renderers_with(scene: &str, keys: &str) -> std::path::PathBuf {
    let path = renderers(scene, "\"true\"");
    let text = std::fs::read_to_string(&path)
        .unwrap()
        .replace("batches = 4\n", &format!("batches = 4\n{keys}"));
    std::fs::write(&path, text).unwrap();
    path
}

/// The stand-in renderer of [`renderers_with`]`(scene, keys)`, loaded.
fn stand_in_with(scene: &str, keys: &str) -> External {
    let r = load_renderers(&renderers_with(scene, keys)).unwrap();
    External::from_spec("stand-in", &r, &root("")).unwrap()
}

fn verdict(scene: &str) -> (Verdict, String) {
    let r = load_renderers(&renderers(scene, "\"true\"")).unwrap();
    let ext = External::from_spec("stand-in", &r, &root("")).unwrap();
    let specs: Vec<_> = manifest::load(&root("tests/manifests/furnace.toml"))
        .unwrap()
        .into_iter()
        .filter(|s| s.name == "furnace/sphere[albedo=0.5]")
        .collect();
    let opts = RunOptions {
        family_alpha: 1e-4,
        ..RunOptions::default()
    };
    let report = harness::run(&specs, &opts, &ext, vec![], &mut |_| {});
    assert_eq!(report.renderer, "stand-in");
    let o = &report.outcomes[0];
    (o.verdict, o.message.clone())
}

#[test]
fn a_black_box_renderer_is_judged_by_the_same_statistics() {
    let (v, m) = verdict("tests/manifests/scenes/furnace-sphere-0.5.toml");
    assert_eq!(v, Verdict::Pass, "{m}");
    // Negative control: the stand-in renders albedo 0.45 where the check's scene says 0.5.
    let wrong =
        crate::scratch_dir().join(format!("furnace-adapter-wrong-{}.toml", std::process::id()));
    let text = std::fs::read_to_string(root("tests/manifests/scenes/furnace-sphere-0.5.toml"))
        .unwrap()
        .replace("reflectance = 0.5", "reflectance = 0.45");
    assert!(text.contains("0.45"));
    std::fs::write(&wrong, text).unwrap();
    let (v, m) = verdict(wrong.to_str().unwrap());
    assert_eq!(v, Verdict::Fail, "{m}");
}

#[test]
fn an_unavailable_renderer_is_skipped_with_a_clear_message() {
    let file = renderers("scenes/furnace-sphere.toml", "\"false\"");
    let check = |extra: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_furnace"))
            .current_dir(root(""))
            .args([
                "check",
                "tests/manifests/lambert.toml",
                "--renderer",
                "stand-in",
            ])
            .args(extra)
            .arg("--renderers")
            .arg(&file)
            .output()
            .unwrap()
    };
    let out = check(&[]);
    let (stdout, stderr) = (
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr),
    );
    assert_eq!(out.status.code(), Some(0), "{stdout}{stderr}");
    assert!(
        stderr.contains("renderer stand-in is not available"),
        "{stderr}"
    );
    assert!(stdout.contains("0 passed, 0 failed, 7 skipped"), "{stdout}");
    // A CI job that exists to judge it asks for it: then unavailable is an error (exit 2).
    let out = check(&["--require-renderers"]);
    assert_eq!(out.status.code(), Some(2), "{out:?}");
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("(--require-renderers)"),
        "{out:?}"
    );
    // An unknown renderer is a usage error (exit 2) that lists the known ones.
    let out = Command::new(env!("CARGO_BIN_EXE_furnace"))
        .current_dir(root(""))
        .args(["check", "--renderer", "blender", "--renderers"])
        .arg(&file)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("unknown renderer \"blender\"; known: furnace, stand-in"),
        "{stderr}"
    );
}

#[test]
fn the_recorded_mitsuba_run_rebuilds_the_comparison_report_without_python() {
    let dir = crate::scratch_dir().join(format!("furnace-adapter-report-{}", std::process::id()));
    let page = dir.join("comparison.html");
    let out = Command::new(env!("CARGO_BIN_EXE_furnace"))
        .current_dir(root(""))
        .args([
            "report",
            "--results",
            "reports/renderers/check.json",
            "--results",
            "reports/renderers/check.mitsuba3_scalar_spectral.json",
            "--out",
        ])
        .arg(&page)
        .output()
        .unwrap();
    // Mitsuba fails some checks (README: findings), so the report exits 1.
    assert_eq!(out.status.code(), Some(1), "{out:?}");
    let html = std::fs::read_to_string(&page).unwrap();
    assert!(html.contains("Renderers side by side"));
    assert!(html.contains("mitsuba3:scalar_spectral") && html.contains("furnace 0.1.0"));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn external_renderers_skip_checks_that_state_furnace_internals() {
    let r = load_renderers(&renderers("scenes/furnace-sphere.toml", "\"true\"")).unwrap();
    let ext = External::from_spec("stand-in", &r, &root("")).unwrap();
    let ext = harness::Subject {
        renderer: &ext,
        models: None,
    };
    let local = harness::model::local::LocalModels;
    let builtin = harness::Subject {
        renderer: &harness::BuiltIn,
        models: Some(&local),
    };
    let specs = manifest::load(&root("tests/manifests/convergence.toml")).unwrap();
    for s in &specs {
        let why = s.kind.not_applicable(s, &ext);
        let p = s
            .params_as::<furnace::harness::checks::convergence::Params>()
            .unwrap();
        let own = p.sampler == furnace::math::rng::Sampler::Independent
            && p.strategy == furnace::integrators::Strategy::Mis;
        assert_eq!(why.is_none(), own, "{}: {why:?}", s.name);
        assert!(s.kind.not_applicable(s, &builtin).is_none());
    }
    // model kinds need a model server
    let bsdf = manifest::load(&root("tests/manifests/bsdf.toml")).unwrap();
    assert!(bsdf
        .iter()
        .all(|s| s.kind.not_applicable(s, &ext).is_some()));
    assert!(bsdf
        .iter()
        .all(|s| s.kind.not_applicable(s, &builtin).is_none()));
    // furnace's light tracer cannot be run on an external renderer
    for s in manifest::load(&root("tests/manifests/light.toml")).unwrap() {
        let why = s.kind.not_applicable(&s, &ext).unwrap();
        assert!(why.contains("light tracer"), "{why}");
        assert!(s.kind.not_applicable(&s, &builtin).is_none());
    }
}

/// A renderer's table states its sample pattern; a convergence check that states another
/// pattern's rate does not judge it (Cycles samples with a tabulated Sobol pattern, and its
/// independent-rate ladders read -0.70 to -1.03 where -0.5 is stated).
#[test]
fn convergence_checks_judge_only_renderers_with_their_sample_pattern() {
    let specs = manifest::load(&root("tests/manifests/convergence.toml")).unwrap();
    for (pattern, applies) in [
        ("tabulated-sobol", &[][..]),
        (
            "sobol",
            &["convergence/sobol-smooth", "convergence/sobol-edge"][..],
        ),
    ] {
        let ext = stand_in_with(
            "scenes/furnace-sphere.toml",
            &format!("sampler = {pattern:?}\n"),
        );
        let subject = harness::Subject {
            renderer: &ext,
            models: None,
        };
        for s in &specs {
            let why = s.kind.not_applicable(s, &subject);
            let want = applies.contains(&s.name.as_str());
            assert_eq!(why.is_none(), want, "{pattern}: {}: {why:?}", s.name);
            if let Some(why) = why {
                assert!(why.contains(pattern), "{why}");
            }
        }
    }
    // a pattern is one word
    let path = renderers_with("scenes/furnace-sphere.toml", "sampler = \"\"\n");
    let e = load_renderers(&path).unwrap_err();
    assert!(e.contains("renderer.stand-in.sampler"), "{e}");
}

/// A renderer that renders at least the samples asked for (LuxCore's periodic batch.haltspp)
/// is not judged by convergence ladders, whose N would not be N; a bad value is refused.
#[test]
fn convergence_checks_skip_a_renderer_whose_spp_is_a_lower_bound() {
    let specs = manifest::load(&root("tests/manifests/convergence.toml")).unwrap();
    let ext = stand_in_with("scenes/furnace-sphere.toml", "spp = \"at-least\"\n");
    let subject = harness::Subject {
        renderer: &ext,
        models: None,
    };
    for s in &specs {
        let why = s.kind.not_applicable(s, &subject);
        assert!(
            why.as_deref().is_some_and(|w| w.contains("at-least")),
            "{}: {why:?}",
            s.name
        );
    }
    // the default, exact, leaves the independent ladders to judge it
    let ext = stand_in_with("scenes/furnace-sphere.toml", "spp = \"exact\"\n");
    let subject = harness::Subject {
        renderer: &ext,
        models: None,
    };
    let smooth = specs
        .iter()
        .find(|s| s.name == "convergence/independent-smooth")
        .unwrap();
    assert_eq!(smooth.kind.not_applicable(smooth, &subject), None);
    let path = renderers_with("scenes/furnace-sphere.toml", "spp = \"roughly\"\n");
    let e = load_renderers(&path).unwrap_err();
    assert!(e.contains("renderer.stand-in.spp"), "{e}");
}

/// A check that fails against an external renderer leaves a reproducer bundle beside the
/// report: README.md with the numbers and the re-run command, outcome.json, and the exported
/// scene with a command.sh that re-runs the renderer alone; the report links it. A passing
/// check leaves none.
#[test]
fn a_failing_check_leaves_a_reproducer_bundle_the_report_links() {
    let dir = crate::scratch_dir().join(format!("furnace-bundle-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    // the stand-in renders albedo 0.45 where the check's scene says 0.5: FAIL
    let wrong = dir.join("wrong.toml");
    let text = std::fs::read_to_string(root("tests/manifests/scenes/furnace-sphere-0.5.toml"))
        .unwrap()
        .replace("reflectance = 0.5", "reflectance = 0.45");
    std::fs::write(&wrong, text).unwrap();
    // with a default variant, as the built-in tables have: bundles are named by the label
    // with its variant
    let table = renderers(wrong.to_str().unwrap(), "\"true\"");
    let text = std::fs::read_to_string(&table).unwrap().replace(
        "[renderer.stand-in]\n",
        "[renderer.stand-in]\nvariant = \"v1\"\n",
    );
    std::fs::write(&table, text).unwrap();
    let report = dir.join("r.html");
    let run = |filter: &str| {
        Command::new(env!("CARGO_BIN_EXE_furnace"))
            .current_dir(root(""))
            .args([
                "check",
                "tests/manifests/furnace.toml",
                "--filter",
                filter,
                "--renderer",
                "stand-in",
                "--alpha",
                "1e-4",
                "-q",
                "--renderers",
            ])
            .arg(&table)
            .arg("--report")
            .arg(&report)
            .output()
            .unwrap()
    };
    let out = run("furnace/sphere[albedo=0.5]");
    assert_eq!(out.status.code(), Some(1), "{out:?}");
    // the folder's name is the report row's id: the cleaned names and a hash of the exact pair
    let id = furnace::report::html::row_id("stand-in:v1", "furnace/sphere[albedo=0.5]");
    assert!(
        id.starts_with("stand-in_v1--furnace_sphere_albedo_0_5_-"),
        "{id}"
    );
    let bundle = dir.join("r-bundles").join(&id);
    let readme = std::fs::read_to_string(bundle.join("README.md")).unwrap();
    for part in [
        "# furnace/sphere[albedo=0.5]: FAIL against stand-in:v1",
        "| expected | 2.000",
        "furnace check tests/manifests/furnace.toml --filter 'furnace/sphere[albedo=0.5]' --renderer stand-in:v1 --seed 1 --renderers",
        "sh render-0/command.sh",
    ] {
        assert!(readme.contains(part), "{part:?} missing from\n{readme}");
    }
    let outcome: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(bundle.join("outcome.json")).unwrap())
            .unwrap();
    assert_eq!(outcome["verdict"], "FAIL");
    // the re-run holds the per-test level the check was judged at
    let alpha: f64 = readme
        .split("--alpha ")
        .nth(1)
        .and_then(|rest| rest.split_whitespace().next())
        .and_then(|a| a.parse().ok())
        .unwrap_or_else(|| panic!("no --alpha in the re-run line of\n{readme}"));
    assert_eq!(Some(alpha), outcome["alpha"].as_f64());
    let render = bundle.join("render-0");
    assert!(render.join("scene.xml").is_file());
    // nothing is kept beside the bundle: every kept render belongs to the failing check
    let folders: Vec<_> = std::fs::read_dir(dir.join("r-bundles")).unwrap().collect();
    assert_eq!(folders.len(), 1, "{folders:?}");
    let html = std::fs::read_to_string(&report).unwrap();
    assert!(
        html.contains(&format!(
            "href=\"r-bundles/{id}/README.md\">reproducer bundle"
        )),
        "the report links the bundle"
    );
    // command.sh re-runs the renderer alone: its independent runs write their images again
    for b in 0..4 {
        std::fs::remove_file(render.join(format!("batch-{b}.exr"))).unwrap();
    }
    let sh = Command::new("sh")
        .arg(render.join("command.sh"))
        .output()
        .unwrap();
    assert!(sh.status.success(), "{sh:?}");
    for b in 0..4 {
        assert!(render.join(format!("batch-{b}.exr")).is_file(), "batch {b}");
    }
    // the same check against a stand-in that renders the right scene passes: no bundle
    let right = renderers("tests/manifests/scenes/furnace-sphere-0.5.toml", "\"true\"");
    let out = Command::new(env!("CARGO_BIN_EXE_furnace"))
        .current_dir(root(""))
        .args([
            "check",
            "tests/manifests/furnace.toml",
            "--filter",
            "furnace/sphere[albedo=0.5]",
            "--renderer",
            "stand-in",
            "-q",
            "--renderers",
        ])
        .arg(&right)
        .arg("--bundles")
        .arg(dir.join("pass-bundles"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(0), "{out:?}");
    let left = std::fs::read_dir(dir.join("pass-bundles"))
        .map(|d| d.count())
        .unwrap_or(0);
    assert_eq!(left, 0, "a passing check keeps no renders");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A renderer table with `exporter = "json"` gets the scene as furnace's interchange JSON, and
/// a driver that refuses what its renderer cannot express (exit 3, a line `unsupported: …` on
/// stderr, as reference/cycles and reference/luxcore do) makes the check SKIPPED with that
/// reason, not an ERROR; any other failure stays an ERROR.
#[test]
fn a_renderer_that_cannot_express_a_scene_skips_the_check_by_name() {
    let table = |script: &str| {
        let text = format!(
            "[renderer.refuser]\nexporter = \"json\"\nobserver = \"cie1931\"\nbatches = 2\ncommand = [\"sh\", \"-c\", {script:?}, \"{{scene}}\", \"{{out}}\"]\n"
        );
        let p = crate::scratch_dir().join(format!(
            "furnace-refuser-{}-{}.toml",
            std::process::id(),
            script.len()
        ));
        std::fs::write(&p, text).unwrap();
        load_renderers(&p).unwrap()
    };
    let run = |script: &str| {
        let ext = External::from_spec("refuser", &table(script), &root("")).unwrap();
        let specs: Vec<_> = manifest::load(&root("tests/manifests/furnace.toml"))
            .unwrap()
            .into_iter()
            .filter(|s| s.name == "furnace/sphere[albedo=0.5]")
            .collect();
        let report = harness::run(&specs, &RunOptions::default(), &ext, vec![], &mut |_| {});
        (
            report.outcomes[0].verdict,
            report.outcomes[0].message.clone(),
        )
    };
    // the driver reads the exported scene: JSON of the interchange format, with the sphere
    let refuse = "grep -q '\"format\":\"furnace-scene-json\"' \"$0\" && grep -q '\"type\":\"sphere\"' \"$0\" && echo 'unsupported: analytic spheres' >&2; exit 3";
    let (v, m) = run(refuse);
    assert_eq!(v, Verdict::Skipped, "{m}");
    assert!(
        m.contains("refuser cannot express") && m.contains("analytic spheres"),
        "{m}"
    );
    // exit 3 without the line, or any other failure: an ERROR
    let (v, m) = run("echo 'segfault' >&2; exit 3");
    assert_eq!(v, Verdict::Error, "{m}");
}

/// An external renderer's images are 32-bit floats, and its region tests allow float32
/// rounding (1e-5 relative, as for float32 models; Cycles and LuxCore read 1e-7 to 1e-6 off
/// exact closed forms). The allowance does not hide a real error: through the stand-in, the
/// point-light Lambert check passes the right light and fails one 1 % too bright.
#[test]
fn a_black_box_gets_the_float32_rounding_allowance_and_no_more() {
    let r = load_renderers(&renderers("scenes/furnace-sphere.toml", "\"true\"")).unwrap();
    let ext = External::from_spec("stand-in", &r, &root("")).unwrap();
    assert_eq!(furnace::harness::Renderer::image_rounding(&ext), 1e-5);
    assert_eq!(
        furnace::harness::Renderer::image_rounding(&furnace::harness::BuiltIn),
        1e-12
    );
    let dir = crate::scratch_dir().join(format!("furnace-f32-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let text = std::fs::read_to_string(root("tests/manifests/scenes/lambert-point.toml"))
        .unwrap()
        .replace("${sx}", "1.0")
        .replace("${cy}", "1.7320508075688772");
    let run = |intensity: &str| {
        let scene = dir.join(format!("point-{intensity}.toml"));
        std::fs::write(
            &scene,
            text.replace("intensity = 3.0", &format!("intensity = {intensity}")),
        )
        .unwrap();
        let r = load_renderers(&renderers(scene.to_str().unwrap(), "\"true\"")).unwrap();
        let ext = External::from_spec("stand-in", &r, &root("")).unwrap();
        let specs: Vec<_> = manifest::load(&root("tests/manifests/lambert.toml"))
            .unwrap()
            .into_iter()
            .filter(|s| s.name.starts_with("lambert/point-30deg"))
            .collect();
        let report = harness::run(&specs, &RunOptions::default(), &ext, vec![], &mut |_| {});
        // the outcome states the tolerance the test allowed: the allowance above f64's
        let tol = report.outcomes[0].rel_tolerance;
        assert!((tol - (1e-5 - 1e-12)).abs() < 1e-15, "{tol}");
        (
            report.outcomes[0].verdict,
            report.outcomes[0].message.clone(),
        )
    };
    let (v, m) = run("3.0");
    assert_eq!(v, Verdict::Pass, "{m}");
    // negative control: a light 1 % too bright
    let (v, m) = run("3.03");
    assert_eq!(v, Verdict::Fail, "{m}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// An RGB renderer (`colour = "rgb"`, or a Mitsuba variant named `*_rgb`) is not judged on a
/// scene whose BSDFs or media vary with wavelength: the check is SKIPPED with the reason, since
/// a product of RGB projections is not the projection of the spectral product (Cycles, LuxCore
/// and Mitsuba's scalar_rgb all read the Cornell box's red wall in blue about +600 %). A grey
/// scene is still judged, and an unknown pipeline name is an error.
#[test]
fn rgb_renderers_are_not_judged_against_spectral_products() {
    let specs: Vec<_> = [
        "tests/manifests/reference.toml",
        "tests/manifests/furnace.toml",
    ]
    .iter()
    .flat_map(|m| manifest::load(&root(m)).unwrap())
    .filter(|s| s.name == "mitsuba/cornell-box" || s.name == "furnace/sphere[albedo=0.5]")
    .collect();
    assert_eq!(specs.len(), 2);
    let opts = RunOptions {
        family_alpha: 1e-4,
        ..RunOptions::default()
    };
    let ext = stand_in_with(
        "tests/manifests/scenes/furnace-sphere-0.5.toml",
        "colour = \"rgb\"\n",
    );
    assert!(ext.renders_rgb());
    let report = harness::run(&specs, &opts, &ext, vec![], &mut |_| {});
    let by_name = |n: &str| report.outcomes.iter().find(|o| o.name == n).unwrap();
    let cornell = by_name("mitsuba/cornell-box");
    assert_eq!(cornell.verdict, Verdict::Skipped, "{}", cornell.message);
    assert!(
        cornell.message.contains("renders in RGB"),
        "{}",
        cornell.message
    );
    let grey = by_name("furnace/sphere[albedo=0.5]");
    assert_eq!(grey.verdict, Verdict::Pass, "{}", grey.message);
    // without the key, a variant named *_rgb is an RGB renderer and *_spectral is not
    let r = load_renderers(&renderers("scenes/furnace-sphere.toml", "\"true\"")).unwrap();
    assert!(External::from_spec("stand-in:scalar_rgb", &r, &root(""))
        .unwrap()
        .renders_rgb());
    assert!(
        !External::from_spec("stand-in:scalar_spectral", &r, &root(""))
            .unwrap()
            .renders_rgb()
    );
    // an unknown pipeline is refused when the table is read
    let path = renderers_with("scenes/furnace-sphere.toml", "colour = \"cmyk\"\n");
    let e = load_renderers(&path).unwrap_err();
    assert!(e.contains("renderer.stand-in.colour"), "{e}");
}

/// A renderer whose image holds NaN or infinite pixels gets an ERROR that says so, not a
/// message about a non-finite estimate and an exact image.
#[test]
fn a_renderer_that_writes_nan_pixels_is_named_for_them() {
    use furnace::io::image::{write_exr, Layers};
    let dir = crate::scratch_dir().join(format!("furnace-adapter-nan-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let exr = dir.join("nan.exr");
    let mut r = vec![0.5f32; 64];
    r[9] = f32::NAN;
    r[10] = f32::INFINITY;
    let channels = ["R", "G", "B"]
        .iter()
        .map(|c| {
            (
                c.to_string(),
                if *c == "R" { r.clone() } else { vec![0.5; 64] },
            )
        })
        .collect();
    write_exr(
        &exr,
        &Layers {
            width: 8,
            height: 8,
            channels,
            attributes: vec![],
        },
    )
    .unwrap();
    let o = small_check_through(
        "nan",
        &format!("[\"cp\", {:?}, \"{{out}}\"]", exr.display().to_string()),
    );
    assert_eq!(o.verdict, Verdict::Error, "{}", o.message);
    assert!(
        o.message
            .contains("nan wrote 2 pixels whose R/G/B is NaN or infinite")
            && o.message.contains("x = 1, y = 1"),
        "{}",
        o.message
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// An error that names a render's temporary file says the file is gone by the time it is read.
#[test]
fn an_error_naming_a_temporary_file_says_it_is_removed() {
    let o = small_check_through("corrupt", r#"["sh", "-c", "echo x > \"$0\"", "{out}"]"#);
    assert_eq!(o.verdict, Verdict::Error, "{}", o.message);
    assert!(
        o.message.contains("batch-0.exr") && o.message.contains("were temporary"),
        "{}",
        o.message
    );
}

/// The outcome of an 8×8 furnace check (2 batches of 2 spp) judged through a renderer table
/// entry `name` whose command is the TOML array `command`.
fn small_check_through(name: &str, command: &str) -> furnace::harness::outcome::Outcome {
    let table = crate::scratch_dir().join(format!(
        "furnace-adapter-{name}-{}.toml",
        std::process::id()
    ));
    std::fs::write(
        &table,
        format!("[renderer.{name}]\nexporter = \"mitsuba3\"\nobserver = \"cie1931\"\nbatches = 2\ncommand = {command}\n"),
    )
    .unwrap();
    let ext = External::from_spec(name, &load_renderers(&table).unwrap(), &root("")).unwrap();
    let _ = std::fs::remove_file(table);
    let text = "[[check]]\nname = \"s\"\nkind = \"furnace\"\nscene = \"scenes/furnace-sphere-0.5.toml\"\nwidth = 8\nheight = 8\nspp = 4\n";
    let specs = manifest::parse(text, &root("tests/manifests/x.toml")).unwrap();
    let mut report = harness::run(&specs, &RunOptions::default(), &ext, vec![], &mut |_| {});
    report.outcomes.remove(0)
}
