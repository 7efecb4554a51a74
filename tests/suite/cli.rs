//! The `furnace` binary: help text, exit codes, error reporting, outputs.

use crate::root;
use std::process::Command;

fn furnace() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_furnace"));
    c.current_dir(root(""));
    c
}

#[test]
fn version_names_the_vector_code_the_binary_was_built_for() {
    let out = furnace().arg("--version").output().unwrap();
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.starts_with("furnace "), "{text}");
    assert!(text.contains(std::env::consts::ARCH), "{text}");
    // the tests are built with the binary's flags, so they agree on its features
    let avx2 = text.contains(" avx2");
    assert_eq!(avx2, cfg!(target_feature = "avx2"), "{text}");
    assert_eq!(
        text.contains("avx512f"),
        cfg!(target_feature = "avx512f"),
        "{text}"
    );
    // `-V` stays the short form
    let short = furnace().arg("-V").output().unwrap();
    assert_eq!(
        String::from_utf8(short.stdout).unwrap().trim(),
        format!("furnace {}", env!("CARGO_PKG_VERSION"))
    );
}

#[test]
fn render_help_documents_every_option() {
    let out = furnace().args(["render", "--help"]).output().unwrap();
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    for opt in [
        "--spp",
        "--seed",
        "--threads",
        "--width",
        "--height",
        "--max-depth",
        "--out",
        "--png",
        "--exposure",
    ] {
        assert!(text.contains(opt), "render --help lacks {opt}:\n{text}");
    }
}

#[test]
fn render_writes_exr_and_png_and_reports_speed() {
    let dir = crate::scratch_dir().join(format!("furnace-cli-{}", std::process::id()));
    let exr = dir.join("sphere.exr");
    let out = furnace()
        .args([
            "render",
            "scenes/furnace-sphere.toml",
            "--spp",
            "2",
            "--width",
            "16",
            "--height",
            "16",
            "--out",
        ])
        .arg(&exr)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("16x16 px, 2 spp"), "{stdout}");
    assert!(stdout.contains("samples/s"), "{stdout}");
    let layers = furnace::io::image::read_exr(&exr).unwrap();
    for ch in ["R", "G", "B", "X", "Y", "Z", "variance.Y", "variance.R"] {
        let v = layers
            .channel(ch)
            .unwrap_or_else(|| panic!("missing channel {ch}"));
        assert!(v.iter().all(|x| x.is_finite()));
    }
    // the furnace sphere reads Y = E/(1-R) = 2 on average
    let y = layers.channel("Y").unwrap();
    let mean = y.iter().map(|&v| v as f64).sum::<f64>() / y.len() as f64;
    assert!((mean - 2.0).abs() < 0.2, "{mean}");
    assert!(dir.join("sphere.png").exists());
    std::fs::remove_dir_all(&dir).ok();
}

/// Two renderers whose results files would have one name, or one renderer given twice, are
/// refused before anything runs (one's results replaced the other's without a word).
#[test]
fn renderers_whose_results_files_collide_are_refused() {
    let entries =
        crate::scratch_dir().join(format!("furnace-cli-labels-{}.toml", std::process::id()));
    let entry = |name: &str| {
        format!("[renderer.{name}]\nexporter = \"mitsuba3\"\nobserver = \"cie1931\"\ncommand = [\"true\", \"{{out}}\", \"{{variant}}\"]\n")
    };
    std::fs::write(&entries, entry("good") + &entry("good_v")).unwrap();
    for (a, b, says) in [
        ("good:v", "good_v", "files of one name"),
        ("furnace", "furnace", "given twice"),
    ] {
        let out = furnace()
            .args([
                "check",
                "tests/manifests/lambert.toml",
                "--renderer",
                a,
                "--renderer",
                b,
                "--renderers",
            ])
            .arg(&entries)
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(2), "{out:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(says), "{err}");
    }
    // a table's default variant counts: `x` is `x:v`
    let table =
        crate::scratch_dir().join(format!("furnace-cli-variant-{}.toml", std::process::id()));
    std::fs::write(
        &table,
        "[renderer.x]\nexporter = \"mitsuba3\"\nobserver = \"cie1931\"\nvariant = \"v\"\ncommand = [\"true\", \"{out}\", \"{variant}\"]\n",
    )
    .unwrap();
    let out = furnace()
        .args([
            "check",
            "tests/manifests/lambert.toml",
            "--renderer",
            "x",
            "--renderer",
            "x:v",
            "--renderers",
        ])
        .arg(&table)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2), "{out:?}");
    assert!(String::from_utf8_lossy(&out.stderr).contains("\"x:v\" is given twice"));
    let _ = std::fs::remove_file(table);
}

/// `--bundles` where no folder can be made is refused before the run (each external
/// renderer's check ended as ERROR: its renders are kept there while it runs).
#[test]
fn bundles_that_cannot_be_written_are_refused_before_the_run() {
    let dir = crate::scratch_dir().join(format!("furnace-cli-bundles-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("keep.txt");
    std::fs::write(&file, "keep").unwrap();
    let out = furnace()
        .args([
            "check",
            "tests/manifests/lambert.toml",
            "--renderer",
            "mitsuba3",
            "--bundles",
        ])
        .arg(&file)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2), "{out:?}");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("--bundles") && err.contains("not a folder"),
        "{err}"
    );
    assert_eq!(std::fs::read_to_string(&file).unwrap(), "keep");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn invalid_scene_exits_2_with_location() {
    let dir = crate::scratch_dir().join(format!("furnace-cli-bad-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let bad = dir.join("bad.toml");
    std::fs::write(&bad, "[camera]\nposition = [0,0,0]\nlook_at = [0,0,1]\nup = [0,1,0]\nfov = 60\n[materials.m]\ntype = \"diffuse\"\nreflectance = 1.5\n").unwrap();
    let out = furnace().arg("render").arg(&bad).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("bad.toml:8:15"), "{err}");
    assert!(err.contains("materials.m.reflectance"), "{err}");
    assert!(err.contains("[0, 1]"), "{err}");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn missing_scene_file_exits_2() {
    let out = furnace()
        .args(["render", "no/such/scene.toml"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("cannot read the scene file"));
}

#[test]
fn compare_takes_a_bdpt_images_region_errors_from_its_kept_runs() {
    // A BDPT image's pixels are correlated within a run: `compare` refuses its region tests
    // unless the EXR keeps the runs (--keep-runs), and then judges it against a path-traced
    // render of the same scene. The kept runs do not change the image.
    let dir = crate::scratch_dir().join(format!("furnace-keep-runs-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let scene = root("scenes/cornell-box.toml");
    let render = |extra: &[&str], out: &std::path::Path| {
        let o = furnace()
            .args(["render", "-q", "--width", "16", "--height", "16"])
            .arg(&scene)
            .args(extra)
            .arg("-o")
            .arg(out)
            .output()
            .unwrap();
        assert_eq!(
            o.status.code(),
            Some(0),
            "{}",
            String::from_utf8_lossy(&o.stderr)
        );
    };
    let (pt, bd, kept) = (dir.join("pt.exr"), dir.join("bd.exr"), dir.join("kept.exr"));
    render(&["--spp", "256", "--seed", "5"], &pt);
    let bdpt = ["--integrator", "bdpt", "--spp", "64", "--runs", "8"];
    render(&bdpt, &bd);
    render(&[&bdpt[..], &["--keep-runs"]].concat(), &kept);
    let a = furnace::io::image::read_exr(&bd).unwrap();
    let b = furnace::io::image::read_exr(&kept).unwrap();
    assert_eq!(a.channel("R"), b.channel("R"));
    assert_eq!(b.channel("run.7.B").map(<[f32]>::len), Some(256));
    let compare = |test: &std::path::Path| {
        furnace()
            .args(["compare", "-q"])
            .arg(test)
            .arg(&pt)
            .arg("--regions")
            .arg(root("scenes/cornell-box.regions.toml"))
            .output()
            .unwrap()
    };
    let refused = compare(&bd);
    assert_eq!(refused.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&refused.stderr).contains("--keep-runs"));
    let judged = compare(&kept);
    assert_eq!(
        judged.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&judged.stderr)
    );
    // SPPM's runs and light tracing's independent renders are kept and judged too
    for (extra, name) in [
        (
            "--integrator sppm --iterations 2 --photons-per-iteration 2000 --runs 3",
            "sppm.exr",
        ),
        (
            "--integrator light --light-paths 40000 --runs 4",
            "light.exr",
        ),
    ] {
        let out = dir.join(name);
        let extra: Vec<&str> = extra.split(' ').collect();
        render(&[&extra[..], &["--keep-runs"]].concat(), &out);
        let o = compare(&out);
        assert_ne!(
            o.status.code(),
            Some(2),
            "{name}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
    // more runs than an EXR furnace reads can hold is refused before rendering
    let o = furnace()
        .args(["render", "-q", "--keep-runs", "--runs", "18"])
        .args(&bdpt[..4])
        .arg(&scene)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("give 2 to 17"));
    // the path tracer's pixels are independent: nothing to keep
    let o = furnace()
        .args(["render", "-q", "--keep-runs"])
        .arg(&scene)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("independent"));
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn compare_agrees_with_itself_and_rejects_a_two_percent_tint_on_one_wall() {
    use furnace::io::image::{read_exr, write_exr};
    let dir = crate::scratch_dir().join(format!("furnace-compare-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let reference = root("reference/mitsuba/cornell-box.exr");
    let regions = root("scenes/cornell-box.regions.toml");
    let same = furnace()
        .args(["compare"])
        .arg(&reference)
        .arg(&reference)
        .arg("--regions")
        .arg(&regions)
        .output()
        .unwrap();
    assert_eq!(
        same.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&same.stdout)
    );
    assert!(String::from_utf8_lossy(&same.stdout).contains("AGREE"));
    // `--color always` colours compare's verdict too
    let coloured = furnace()
        .args(["--color", "always", "compare"])
        .arg(&reference)
        .arg(&reference)
        .output()
        .unwrap();
    let coloured = String::from_utf8_lossy(&coloured.stdout);
    assert!(
        coloured.contains("\u{1b}[32mAGREE\u{1b}[0m: "),
        "{coloured:?}"
    );
    // tint the red wall's R by 2 % (x < 0.12 of the image)
    let mut img = read_exr(&reference).unwrap();
    let (w, h) = (img.width, img.height);
    for (name, data) in img.channels.iter_mut() {
        if name == "R" {
            for y in 0..h {
                for x in 0..(w * 12 / 100) {
                    data[y * w + x] *= 1.02;
                }
            }
        }
    }
    let tinted = dir.join("tinted.exr");
    write_exr(&tinted, &img).unwrap();
    let zmap = dir.join("z.png");
    let out = furnace()
        .args(["compare"])
        .arg(&tinted)
        .arg(&reference)
        .arg("--regions")
        .arg(&regions)
        .arg("--diff")
        .arg(&zmap)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(1), "{stdout}");
    assert!(
        stdout
            .lines()
            .any(|l| l.starts_with("red wall") && l.contains(" R ") && l.contains("DIFFERENT")),
        "{stdout}"
    );
    assert!(
        stdout
            .lines()
            .any(|l| l.starts_with("back wall") && l.contains(" R ") && !l.contains("DIFFERENT")),
        "{stdout}"
    );
    assert!(zmap.exists());
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn export_writes_a_mitsuba_scene_and_refuses_bad_scenes() {
    let dir = crate::scratch_dir().join(format!("furnace-cli-export-{}", std::process::id()));
    let out = furnace()
        .args(["export", "scenes/cornell-box.toml", "--out"])
        .arg(&dir)
        .output()
        .unwrap();
    assert!(out.status.success(), "{out:?}");
    let xml = std::fs::read_to_string(dir.join("scene.xml")).unwrap();
    assert!(
        xml.contains("<scene version=\"3.0.0\">") && dir.join("meshes/shape-007.ply").is_file()
    );
    let out = furnace()
        .args(["export", "tests/manifests/scenes/furnace-box.toml", "--out"])
        .arg(&dir)
        .output()
        .unwrap();
    assert_eq!(
        out.status.code(),
        Some(2),
        "a template with ${{albedo}} is not a scene"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn report_builds_one_page_from_results_and_comparisons() {
    let dir = crate::scratch_dir().join(format!("furnace-cli-report-{}", std::process::id()));
    let (page, md) = (dir.join("r.html"), dir.join("r.md"));
    let out = furnace()
        .args([
            "report",
            "--results",
            "reports/check-default.json",
            "--compare",
            "reference/mitsuba/furnace-box.exr",
            "reference/mitsuba/furnace-box.exr",
            "--out",
        ])
        .arg(&page)
        .arg("--markdown")
        .arg(&md)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(0), "{out:?}");
    let html = std::fs::read_to_string(&page).unwrap();
    assert!(html.contains("ALL PASS") && html.matches("data:image/png;base64,").count() == 4);
    assert!(html.contains("furnace/sphere[albedo=0.5]"));
    assert!(std::fs::read_to_string(&md)
        .unwrap()
        .starts_with("## furnace: all pass"));
    // Something that is not check results is refused by name.
    let out = furnace()
        .args([
            "report",
            "--results",
            "reference/mitsuba/cornell-box.json",
            "--out",
        ])
        .arg(&page)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("furnace.check-results/1"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn render_with_the_light_tracer() {
    let dir = crate::scratch_dir().join(format!("furnace-cli-light-{}", std::process::id()));
    let exr = dir.join("sphere.exr");
    let out = furnace()
        .args([
            "render",
            "scenes/furnace-sphere.toml",
            "--integrator",
            "light",
            "--light-paths",
            "20000",
            "--width",
            "8",
            "--height",
            "8",
            "--out",
        ])
        .arg(&exr)
        .output()
        .unwrap();
    assert!(out.status.success(), "{out:?}");
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.contains("20000 light paths"), "{text}");
    let img = furnace::harness::compare::RgbImage::load(&exr).unwrap();
    assert_eq!(img.variance_dof, Some(19999.0));
    // --light-paths belongs to the light tracer
    let out = furnace()
        .args([
            "render",
            "scenes/furnace-sphere.toml",
            "--light-paths",
            "10",
            "--quiet",
            "--out",
        ])
        .arg(&exr)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2), "{out:?}");
    // participating media are refused, by name (environment lights and dispersive glass work)
    let scene = dir.join("fog.toml");
    std::fs::write(
        &scene,
        "[camera]\nposition = [0.0, 0.0, 0.0]\nlook_at = [0.0, 0.0, 1.0]\nup = [0.0, 1.0, 0.0]\nfov = 40.0\n[media.fog]\nsigma_a = 0.5\nsigma_s = 0.0\nphase = \"isotropic\"\n[materials.n]\ntype = \"null\"\n[[shape]]\ntype = \"sphere\"\ncenter = [0.0, 0.0, 3.0]\nradius = 1.0\nmaterial = \"n\"\ninterior = \"fog\"\n[[light]]\ntype = \"point\"\nposition = [0.0, 2.0, 3.0]\nintensity = 1.0\n",
    )
    .unwrap();
    let out = furnace()
        .args([
            "render",
            "--integrator",
            "light",
            "--width",
            "4",
            "--height",
            "4",
            "--quiet",
        ])
        .arg(&scene)
        .arg("--out")
        .arg(&exr)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{out:?}");
    assert!(err.contains("participating media"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// `furnace … | head` closes the pipe early: the binary exits with status 141 (SIGPIPE's
/// convention) and no panic message, whatever it was still printing.
#[test]
fn a_closed_stdout_pipe_ends_quietly() {
    let mut child = furnace()
        .args([
            "render",
            "scenes/furnace-sphere.toml",
            "--spp",
            "4",
            "--width",
            "8",
            "--height",
            "8",
        ])
        .arg("--out")
        .arg(crate::scratch_dir().join("furnace-pipe-test.exr"))
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take()); // the reader goes away before anything is printed
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert_eq!(out.status.code(), Some(141), "{stderr}");
}

/// `--quiet` is accepted by every command, before or after it, and silences stdout.
#[test]
fn quiet_silences_stdout_on_every_command() {
    let exr = crate::scratch_dir().join(format!("furnace-quiet-{}.exr", std::process::id()));
    let exr = exr.to_str().unwrap();
    let render = [
        "render",
        "scenes/furnace-sphere.toml",
        "--spp",
        "2",
        "--width",
        "4",
        "--height",
        "4",
        "--out",
        exr,
    ];
    for args in [
        [&["-q"][..], &render[..]].concat(),
        [&render[..], &["--quiet"][..]].concat(),
        vec!["compare", exr, exr, "-q"],
        vec![
            "check",
            "tests/manifests/furnace.toml",
            "--filter",
            "furnace/sphere-depth0*",
            "-q",
        ],
    ] {
        let out = furnace().args(&args).output().unwrap();
        assert!(out.status.success(), "{args:?}: {out:?}");
        assert!(
            out.stdout.is_empty(),
            "{args:?}: {}",
            String::from_utf8_lossy(&out.stdout)
        );
    }
    let _ = std::fs::remove_file(exr);
    let _ = std::fs::remove_file(exr.replace(".exr", ".png"));
}

#[test]
fn color_colours_verdicts_only_when_asked_or_on_a_terminal() {
    let run = |extra: &[&str], no_color: bool| {
        let mut c = furnace();
        c.args([
            "check",
            "tests/manifests/lambert.toml",
            "--filter",
            "lambert/sky",
        ])
        .args(extra);
        if no_color {
            c.env("NO_COLOR", "1");
        } else {
            c.env_remove("NO_COLOR");
        }
        let out = c.output().unwrap();
        (
            out.status.code(),
            String::from_utf8_lossy(&out.stdout).into_owned(),
        )
    };
    let (code, always) = run(&["--color", "always"], true);
    assert_eq!(code, Some(0), "{always}");
    assert!(
        always.contains("\u{1b}[32mPASS\u{1b}[0m      lambert/sky"),
        "{always:?}"
    );
    // stdout is a pipe here, so auto means no colour; never means none anywhere
    for extra in [&[][..], &["--color", "auto"], &["--color", "never"]] {
        let (_, plain) = run(extra, false);
        assert!(
            plain.contains("PASS      lambert/sky") && !plain.contains('\u{1b}'),
            "{plain:?}"
        );
    }
    let (code, _) = run(&["--color", "sometimes"], false);
    assert_eq!(code, Some(2));
}

#[test]
fn render_by_radiosity_reports_the_solve_and_its_discretisation_estimate() {
    let dir = crate::scratch_dir().join(format!("furnace-cli-rad-{}", std::process::id()));
    let exr = dir.join("cbox.exr");
    let out = furnace()
        .args([
            "render",
            "scenes/cornell-box.toml",
            "--integrator",
            "radiosity",
            "--patch-size",
            "200",
            "--width",
            "16",
            "--height",
            "16",
            "--spp",
            "4",
            "-o",
        ])
        .arg(&exr)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(text.contains("Gauss-Seidel sweeps"), "{text}");
    assert!(text.contains("discretisation error estimate"), "{text}");
    assert!(exr.exists());

    // what radiosity does not model, and a patch size too small, are refused by name
    for (args, says) in [
        (
            vec!["scenes/cornell-glossy.toml"],
            "radiosity models diffuse surfaces",
        ),
        (
            vec!["scenes/cornell-box.toml", "--patch-size", "1"],
            "use a patch size of at least",
        ),
        (
            vec!["scenes/cornell-box.toml", "--patch-size", "0"],
            "positive length",
        ),
    ] {
        let out = furnace()
            .args([
                "render",
                "--integrator",
                "radiosity",
                "-o",
                dir.join("refused.exr").to_str().unwrap(),
            ])
            .args(&args)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success() && err.contains(says),
            "{args:?}: {err}"
        );
    }
    // SPPM: a few photons, the photon rate reported
    let exr = dir.join("cbox-sppm.exr");
    let out = furnace()
        .args([
            "render",
            "scenes/cornell-box.toml",
            "--integrator",
            "sppm",
            "--iterations",
            "2",
            "--photons-per-iteration",
            "2000",
            "--runs",
            "2",
            "--width",
            "8",
            "--height",
            "8",
            "-o",
        ])
        .arg(&exr)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(text.contains("M photons/s") && exr.exists(), "{text}");
    std::fs::remove_dir_all(&dir).ok();
    let out = furnace()
        .args(["render", "scenes/cornell-box.toml", "--patch-size", "10"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("only used by --integrator radiosity"));
    // every estimator's own options likewise, never silently ignored
    for (option, by) in [
        ("--iterations", "sppm"),
        ("--photons-per-iteration", "sppm"),
        ("--radius", "sppm"),
        ("--runs", "sppm or bdpt"),
        ("--mutations-per-pixel", "mlt"),
        ("--chains", "mlt"),
    ] {
        let out = furnace()
            .args([
                "render",
                "scenes/cornell-box.toml",
                option,
                "3",
                "-o",
                "out/never-written.exr",
            ])
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{option}: {err}");
        assert!(
            err.contains(&format!("{option} is only used by --integrator {by}")),
            "{err}"
        );
    }
    for (args, says) in [
        (
            ["--integrator", "sppm", "--spp", "8"],
            "--spp is only used by",
        ),
        (
            ["--integrator", "mlt", "--spp", "8"],
            "--spp is only used by",
        ),
        (
            ["--integrator", "bdpt", "--strategy", "bsdf"],
            "--strategy is only used by --integrator path",
        ),
    ] {
        let out = furnace()
            .args([
                "render",
                "scenes/cornell-box.toml",
                "-o",
                "out/never-written.exr",
            ])
            .args(args)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(says), "{args:?}: {err}");
    }
}

#[test]
fn render_bdpt_and_mlt_write_images_and_refuse_what_they_cannot_do() {
    let dir = crate::scratch_dir().join(format!("furnace-bdpt-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let small = ["--width", "8", "--height", "8", "-o"];
    for (integrator, extra, says) in [
        (
            "bdpt",
            vec!["--spp", "8", "--runs", "2"],
            "bdpt: 8x8 px, 8 spp in 2 runs",
        ),
        (
            "mlt",
            vec!["--mutations-per-pixel", "8", "--chains", "2"],
            "mlt: 8x8 px, 8 mutations per pixel in 2 chains",
        ),
    ] {
        let exr = dir.join(format!("cbox-{integrator}.exr"));
        let out = furnace()
            .args([
                "render",
                "scenes/cornell-box.toml",
                "--integrator",
                integrator,
            ])
            .args(&extra)
            .args(small)
            .arg(&exr)
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&out.stdout);
        assert!(
            out.status.success() && text.contains(says) && exr.exists(),
            "{text}{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    let cornell = "scenes/cornell-box.toml";
    for (scene, args, says) in [
        (
            cornell,
            vec!["--integrator", "bdpt", "--spp", "9", "--runs", "2"],
            "a multiple of them",
        ),
        (
            cornell,
            vec!["--integrator", "mlt", "--chains", "1"],
            "at least 2 --chains",
        ),
        (
            cornell,
            vec![
                "--integrator",
                "bdpt",
                "--spp",
                "8",
                "--bdpt-only",
                "2,3",
                "--max-depth",
                "1",
            ],
            "samples paths of 3 bounces",
        ),
        (
            cornell,
            vec!["--bdpt-only", "1,1"],
            "only used by --integrator bdpt",
        ),
        (
            cornell,
            vec!["--integrator", "bdpt", "--bdpt-only", "1,0"],
            "expected S,T",
        ),
        (
            "scenes/hg-fog.toml",
            vec!["--integrator", "bdpt", "--spp", "8"],
            "participating media",
        ),
    ] {
        let out = furnace()
            .args(["render", scene])
            .args(&args)
            .args(small)
            .arg(dir.join("x.exr"))
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success() && err.contains(says),
            "{args:?}: {err}"
        );
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn converge_measures_reference_ladders_of_every_estimator() {
    let dir = crate::scratch_dir().join(format!("furnace-cli-conv-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let scene = root("scenes/cornell-box.toml");
    let mut manifest = String::new();
    for (name, extra) in [
        ("path", "ladder = [4, 8, 16]"),
        ("light", "ladder = [4, 8, 16]"),
        ("sppm", "ladder = [2, 4, 8]\nphotons_per_iteration = 500"),
    ] {
        manifest += &format!(
            "[[check]]\nname = \"tiny/{name}\"\nkind = \"reference_convergence\"\nintegrator = \"{name}\"\nscene = {scene:?}\nwidth = 8\nheight = 8\nruns = 2\nreference_spp = 256\nslope = [-2.0, -0.01]\n{extra}\n\n"
        );
    }
    let m = dir.join("tiny.toml");
    std::fs::write(&m, manifest).unwrap();
    let html = dir.join("tiny.html");
    let out = furnace()
        .arg("converge")
        .arg(&m)
        .arg("--report")
        .arg(&html)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for label in [
        "verdict ladder",
        "tiny/path",
        "tiny/light",
        "tiny/sppm",
        "sppm a=0.6667, 500 photons/it",
        "ladders at their predicted rate",
    ] {
        assert!(text.contains(label), "{label} missing:\n{text}");
    }
    let page = std::fs::read_to_string(&html).unwrap();
    assert!(page.contains("reference_convergence"), "{page}");
    // a manifest without ladders is an error, not an empty table
    let none = furnace()
        .args(["converge", "tests/manifests/lambert.toml"])
        .output()
        .unwrap();
    assert_eq!(none.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&none.stderr).contains("no `convergence`"));
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_negative_number_is_refused_as_that_option_s_value_not_as_an_unknown_option() {
    for (args, said) in [
        (
            &["render", "scenes/cornell-box.toml", "--spp", "-4"][..],
            "invalid value '-4' for '--spp <SPP>'",
        ),
        (
            &["render", "scenes/cornell-box.toml", "--max-depth", "-1"][..],
            "invalid value '-1' for '--max-depth <MAX_DEPTH>'",
        ),
        (
            &["check", "--power", "-0.1", "tests/manifests/furnace.toml"][..],
            "--power -0.1 must be a relative bias in (0, 1)",
        ),
    ] {
        let out = furnace().args(args).output().unwrap();
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(said), "{args:?}: {err}");
        assert!(!err.contains("unexpected argument"), "{args:?}: {err}");
    }
}

#[test]
fn serve_models_refuses_a_hello_of_another_protocol_and_flags_transmitted_samples() {
    use std::io::{BufRead, Read, Write};
    let mut child = furnace()
        .arg("serve-models")
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdin = child.stdin.take().unwrap();
    let mut out = std::io::BufReader::new(child.stdout.take().unwrap());
    let mut line = String::new();
    stdin
        .write_all(b"{\"op\":\"hello\",\"protocol\":2}\n")
        .unwrap();
    out.read_line(&mut line).unwrap();
    assert!(
        line.contains("speaks protocol 1; the hello asked for 2"),
        "{line}"
    );
    stdin
        .write_all(b"{\"op\":\"hello\",\"protocol\":1}\n")
        .unwrap();
    line.clear();
    out.read_line(&mut line).unwrap();
    assert!(line.contains("\"ok\":true"), "{line}");
    // a smooth glass's sample straight down (wo = +z, uc = 0.99 picks refraction): flags
    // 1 | 4 (sampled, transmitted) beside 2 (delta)
    let name = "dielectric/smooth η=1.5";
    assert!(line.contains(name), "{line}");
    let header = format!("{{\"op\":\"bsdf.sample\",\"model\":\"{name}\",\"n\":1,\"width\":10}}\n");
    stdin.write_all(header.as_bytes()).unwrap();
    for v in [0.0f64, 0.0, 1.0, 0.5, 0.5, 0.99, 550.0, 550.0, 550.0, 550.0] {
        stdin.write_all(&v.to_le_bytes()).unwrap();
    }
    stdin.flush().unwrap();
    line.clear();
    out.read_line(&mut line).unwrap();
    assert!(line.contains("\"ok\":true"), "{line}");
    let mut payload = [0u8; 9 * 8];
    out.read_exact(&mut payload).unwrap();
    let v: Vec<f64> = payload
        .chunks_exact(8)
        .map(|b| f64::from_le_bytes(b.try_into().unwrap()))
        .collect();
    assert!(v[2] < 0.0, "refracted down: {v:?}");
    assert_eq!(v[8], 7.0, "flags {v:?}");
    // invalid queries get errors, not plausible answers (a NaN direction's eval read 1/(2π))
    let mut ask = |op: &str, model: &str, row: &[f64]| {
        let header = format!(
            "{{\"op\":\"{op}\",\"model\":\"{model}\",\"n\":1,\"width\":{}}}\n",
            row.len()
        );
        stdin.write_all(header.as_bytes()).unwrap();
        for v in row {
            stdin.write_all(&v.to_le_bytes()).unwrap();
        }
        stdin.flush().unwrap();
        let mut line = String::new();
        out.read_line(&mut line).unwrap();
        line
    };
    let l = [550.0; 4];
    for (op, model, row, says) in [
        (
            "bsdf.eval",
            "diffuse/0.5",
            [&[0.0, f64::NAN, 1.0, 0.0, 0.0, 1.0][..], &l].concat(),
            "NaN is not a finite number",
        ),
        (
            "bsdf.eval",
            "diffuse/0.5",
            [&[0.0, 0.0, 2.0, 0.0, 0.0, 1.0][..], &l].concat(),
            "wo (0.0, 0.0, 2.0) is not a unit vector",
        ),
        (
            "bsdf.sample",
            name,
            [&[0.0, 0.0, 1.0, 5.0, -3.0, 0.5][..], &l].concat(),
            "outside [0, 1)",
        ),
        (
            "bsdf.eval",
            "diffuse/0.5",
            [
                &[0.0, 0.0, 1.0, 0.0, 0.0, 1.0][..],
                &[-5.0, 550.0, 550.0, 550.0],
            ]
            .concat(),
            "wavelength -5.0 nm",
        ),
        (
            "bsdf.eval",
            "hg g=0.9",
            [&[0.0, 0.0, 1.0, 0.0, 0.0, 1.0][..], &l].concat(),
            "it is a phase function",
        ),
    ] {
        let line = ask(op, model, &row);
        assert!(
            line.contains("\"ok\":false") && line.contains(says),
            "{op} {row:?}: {line}"
        );
    }
    drop(stdin);
    child.wait().unwrap();
}

#[test]
fn out_of_range_numbers_are_quoted_short() {
    for args in [
        &["check", "--time-limit", "1e300"][..],
        &["check", "--alpha", "1e300"],
        &["converge", "--target", "1e300"],
        &["render", "scenes/cornell-box.toml", "--exposure", "-1e300"],
    ] {
        let out = furnace().args(args).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains("1e300") && err.len() < 200, "{args:?}: {err}");
    }
}
