//! The model protocol end to end: furnace's own models served by `furnace serve-models` give
//! the in-process verdicts bit for bit; deliberately wrong models served through it fail; a
//! server that crashes, hangs, answers NaN, short payloads or another protocol version makes
//! the check an ERROR with the server's words; the C example server answers furnace.

use crate::root;
use furnace::harness::model::client::RemoteModels;
use furnace::harness::model::local::LocalModels;
use furnace::harness::outcome::{RunReport, Verdict};
use furnace::harness::under_test::ServerCommand;
use furnace::harness::{self, manifest, BuiltIn, RunOptions, Subject};
use std::path::Path;
use std::time::Duration;

/// The model-level checks of tests/manifests/bsdf.toml at small sample counts.
const SMALL: &str = r#"
[[check]]
name = "reciprocity"
kind = "reciprocity"
samples = 500
rel_tol = 1e-9
abs_tol = 1e-12
[[check]]
name = "energy"
kind = "energy"
samples = 2000
[[check]]
name = "weights"
kind = "sample_weights"
samples = 500
[[check]]
name = "chi2"
kind = "chi2"
samples = 20000
bins = [12, 24]
[[check]]
name = "hg"
kind = "hg"
samples = 5000
[[check]]
name = "phase"
kind = "phase"
samples = 5000
[[check]]
name = "albedo"
kind = "albedo"
samples = 500
[[check]]
name = "smooth-limit"
kind = "smooth_limit"
samples = 500
"#;

fn server(args: &[&str], timeout: f64) -> ServerCommand {
    let mut argv = vec![
        env!("CARGO_BIN_EXE_furnace").to_string(),
        "serve-models".into(),
    ];
    argv.extend(args.iter().map(|s| s.to_string()));
    ServerCommand {
        argv,
        workdir: root(""),
        env: Vec::new(),
        timeout: Duration::from_secs_f64(timeout),
    }
}

fn run(text: &str, models: &dyn furnace::harness::ModelSource) -> RunReport {
    let checks = manifest::parse(text, &root("tests/manifests/models-test.toml")).unwrap();
    harness::run_with(
        &checks,
        &RunOptions::default(),
        Subject {
            renderer: &BuiltIn,
            models: Some(models),
        },
        vec![],
        &mut |_| {},
    )
}

#[test]
fn the_stand_in_server_gives_the_in_process_verdicts_bit_for_bit() {
    let local = run(SMALL, &LocalModels);
    let remote = RemoteModels::start(&server(&[], 60.0)).unwrap();
    let served = run(SMALL, &remote);
    assert_eq!(local.outcomes.len(), 8);
    for (a, b) in local.outcomes.iter().zip(&served.outcomes) {
        assert_eq!(a.verdict, Verdict::Pass, "{}: {}", a.name, a.message);
        assert_eq!(
            (
                a.verdict,
                a.estimate.map(f64::to_bits),
                a.std_error.map(f64::to_bits)
            ),
            (
                b.verdict,
                b.estimate.map(f64::to_bits),
                b.std_error.map(f64::to_bits)
            ),
            "{}: in process {} vs served {}",
            a.name,
            a.message,
            b.message
        );
        assert_eq!(
            a.p_value.map(f64::to_bits),
            b.p_value.map(f64::to_bits),
            "{}",
            a.name
        );
        assert_eq!(a.statistic, b.statistic, "{}", a.name);
        assert_eq!(a.message, b.message, "{}", a.name);
    }
}

#[test]
fn wrong_models_served_through_the_protocol_fail_for_their_reason() {
    let remote = RemoteModels::start(&server(&["--controls"], 60.0)).unwrap();
    // energy sees the Lambertian without 1/π (albedo π/2); chi-square the uniform draws
    for (kind, control, extra) in [
        ("energy", "control/lambert without 1/pi", "samples = 2000"),
        (
            "chi2",
            "control/cosine pdf, uniform draws",
            "samples = 20000\nbins = [12, 24]",
        ),
    ] {
        let text = format!(
            "[[check]]\nname = \"{kind}\"\nkind = \"{kind}\"\nmodels = [\"{control}\"]\n{extra}\n"
        );
        let r = run(&text, &remote);
        assert_eq!(
            r.outcomes[0].verdict,
            Verdict::Fail,
            "{}",
            r.outcomes[0].message
        );
        assert!(
            r.outcomes[0].message.contains(control),
            "{}",
            r.outcomes[0].message
        );
        // the clean twin: the catalogue's Lambertian through the same server passes
        let text = text.replace(control, "diffuse/0.5");
        let r = run(&text, &remote);
        assert_eq!(
            r.outcomes[0].verdict,
            Verdict::Pass,
            "{}",
            r.outcomes[0].message
        );
    }
}

#[test]
fn a_misbehaving_server_makes_the_check_an_error_with_its_words() {
    let text = "[[check]]\nname = \"energy\"\nkind = \"energy\"\nsamples = 200\nmodels = [\"diffuse/0.5\"]\n";
    for (fault, want) in [
        ("crash", "exited"),
        ("hang", "no reply"),
        ("nan", "answered NaN"),
        // +∞ in a weight read as a FAIL with an estimate of 0
        ("inf", "answered inf"),
        ("short", "payload shorter"),
    ] {
        let remote = RemoteModels::start(&server(&["--fault", fault], 2.0)).unwrap();
        let r = run(text, &remote);
        let o = &r.outcomes[0];
        assert_eq!(o.verdict, Verdict::Error, "{fault}: {}", o.message);
        assert!(o.message.contains(want), "{fault}: {}", o.message);
    }
    let e = RemoteModels::start(&server(&["--fault", "version"], 2.0))
        .err()
        .unwrap();
    assert!(e.0.contains("speaks protocol 2; furnace speaks 1"), "{e}");
    let e = RemoteModels::start(&ServerCommand {
        argv: vec!["/nonexistent/server".into()],
        ..server(&[], 2.0)
    })
    .err()
    .unwrap();
    assert!(e.0.contains("cannot start model server"), "{e}");
}

#[test]
fn the_c_example_server_answers_furnace() {
    let out = crate::scratch_dir().join(format!("furnace-example-server-{}", std::process::id()));
    let cc = std::process::Command::new("cc")
        .args(["-std=c99", "-Wall", "-Wextra", "-Werror", "-O2"])
        .arg(root("protocol/example_server.c"))
        .arg("-o")
        .arg(&out)
        .arg("-lm")
        .output();
    let Ok(cc) = cc else {
        eprintln!("skipped: no C compiler (cc) on this machine");
        return;
    };
    assert!(
        cc.status.success(),
        "{}",
        String::from_utf8_lossy(&cc.stderr)
    );
    let cmd = ServerCommand {
        argv: vec![out.display().to_string()],
        ..server(&[], 30.0)
    };
    let remote = RemoteModels::start(&cmd).unwrap();
    let energy = |model: &str| {
        let text = format!(
            "[[check]]\nname = \"energy\"\nkind = \"energy\"\nsamples = 5000\nmodels = [\"{model}\"]\n"
        );
        run(&text, &remote).outcomes[0].clone()
    };
    let good = energy("diffuse/0.5");
    assert_eq!(good.verdict, Verdict::Pass, "{}", good.message);
    let bad = energy("diffuse/0.5 without 1/pi");
    assert_eq!(bad.verdict, Verdict::Fail, "{}", bad.message);
    let text = "[[check]]\nname = \"hg\"\nkind = \"hg\"\ng = [0.5]\nsamples = 20000\n";
    let hg = &run(text, &remote).outcomes[0];
    assert_eq!(hg.verdict, Verdict::Pass, "{}", hg.message);
    // the README's example: the default suite against the example server gives one FAIL (its
    // deliberately wrong model) and no ERROR; checks naming models it does not serve are SKIPs
    let table = out.with_extension("toml");
    std::fs::write(
        &table,
        format!(
            "[renderer.mine]\nexporter = \"mitsuba3\"\nobserver = \"cie1931\"\nmodels = [{:?}]\n",
            out.display().to_string()
        ),
    )
    .unwrap();
    let suite = std::process::Command::new(env!("CARGO_BIN_EXE_furnace"))
        .current_dir(root(""))
        .args(["check", "--renderer", "mine", "--renderers"])
        .arg(&table)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&suite.stdout);
    assert_eq!(suite.status.code(), Some(1), "{text}");
    let fails: Vec<&str> = text
        .lines()
        .filter(|l| l.starts_with("FAIL") || l.starts_with("ERROR"))
        .collect();
    assert!(
        fails.len() == 1 && fails[0].contains("energy/all-bsdfs"),
        "{text}"
    );
    assert!(
        text.contains("mine serves no model this check can measure among those its `models`"),
        "{text}"
    );
    let _ = std::fs::remove_file(table);
    let _ = std::fs::remove_file(out);
}

#[test]
fn furnace_check_runs_the_model_kinds_on_the_stand_in_from_the_built_in_table() {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_furnace"))
        .current_dir(root(""))
        .args([
            "check",
            "--renderer",
            "furnace-models",
            "--filter",
            "reciprocity/*",
        ])
        .arg(Path::new("tests/manifests/bsdf.toml"))
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(0), "{text}");
    assert!(text.contains("PASS      reciprocity/all-bsdfs"), "{text}");
}
