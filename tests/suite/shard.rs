//! Sharded suites: the default suite run as 4 shards through the command line and merged has
//! the single run's numbers bit for bit (the committed seed-1 digest); merges of shards that do
//! not make one run are refused by name.

use crate::root;
use furnace::harness::outcome::RunReport;
use std::path::Path;
use std::process::Output;

fn furnace(args: &[&str]) -> Output {
    crate::run_furnace(args)
}

/// A fresh scratch folder for one test (removed first if an earlier run left it).
fn scratch(name: &str) -> std::path::PathBuf {
    let d = crate::scratch_dir().join(format!("furnace-shard-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn shard_run(dir: &Path, extra: &[&str], k: usize, n: usize) -> String {
    let out = dir.join(format!("shard-{k}-of-{n}.json"));
    let spec = format!("{k}/{n}");
    let mut args = vec![
        "check",
        "-q",
        "--shard",
        &spec,
        "--json",
        out.to_str().unwrap(),
    ];
    args.extend(extra);
    let o = furnace(&args);
    assert!(
        o.status.code() == Some(0) || o.status.code() == Some(1),
        "{}",
        stderr(&o)
    );
    out.to_str().unwrap().to_string()
}

#[test]
fn four_shards_merge_into_the_single_runs_numbers() {
    // the README's workflow, run as its documented local script: 4 shard jobs, then the merge
    let dir = scratch("four");
    let o = std::process::Command::new("sh")
        .arg(root("docs/ci/shards-locally.sh"))
        .arg("4")
        // the fixed-sample test, which the committed digest holds
        .arg("--fixed")
        .env("FURNACE", env!("CARGO_BIN_EXE_furnace"))
        .env("OUT", &dir)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    // each shard runs only its checks, but the correction spans all of them
    let first: RunReport =
        serde_json::from_str(&std::fs::read_to_string(dir.join("shard-1.json")).unwrap()).unwrap();
    let all = first.shard.as_ref().unwrap().suite.len();
    assert!(
        first.outcomes.len() < all,
        "{} of {all}",
        first.outcomes.len()
    );
    for f in ["junit.xml", "summary.md", "report.html"] {
        assert!(dir.join(f).is_file(), "the script wrote no {f}");
    }
    let merged = dir.join("merged.json");
    let report: RunReport =
        serde_json::from_str(&std::fs::read_to_string(&merged).unwrap()).unwrap();
    assert_eq!(report.outcomes.len(), all);
    assert!(report.shard.is_none());
    // the committed digest of one run at seed 1 (tests/suite/manifests.rs checks it)
    let baseline = std::fs::read_to_string(root("tests/digests/default-suite-seed1.txt")).unwrap();
    let merged = crate::digests::report_digest(&report);
    let differ: Vec<String> = merged
        .lines()
        .zip(baseline.lines())
        .filter(|(a, b)| a != b)
        .take(4)
        .map(|(a, b)| format!("- {b}\n+ {a}"))
        .collect();
    assert!(
        differ.is_empty() && merged.lines().count() == baseline.lines().count(),
        "merged shards differ from the single run:\n{}",
        differ.join("\n")
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn merges_that_are_not_one_run_are_refused_by_name() {
    let dir = scratch("refused");
    let m = ["tests/manifests/bsdf.toml", "--filter", "energy*"];
    let p: Vec<String> = (1..=3).map(|k| shard_run(&dir, &m, k, 3)).collect();
    let merge = |files: &[&str]| {
        let mut args = vec!["merge", "-q"];
        args.extend(files);
        furnace(&args)
    };
    let ok = merge(&[&p[0], &p[1], &p[2]]);
    assert_eq!(ok.status.code(), Some(0), "{}", stderr(&ok));
    let missing = merge(&[&p[0], &p[2]]);
    assert_eq!(missing.status.code(), Some(2));
    assert!(
        stderr(&missing).contains("shard 2/3 missing"),
        "{}",
        stderr(&missing)
    );
    let twice = merge(&[&p[0], &p[1], &p[1], &p[2]]);
    assert!(
        stderr(&twice).contains("shard 2/3 given twice"),
        "{}",
        stderr(&twice)
    );
    // another seed is another run
    let other = dir.join("seed2");
    std::fs::create_dir(&other).unwrap();
    let mut m2 = m.to_vec();
    m2.extend(["--seed", "2"]);
    let q = shard_run(&other, &m2, 2, 3);
    let mixed = merge(&[&p[0], &q, &p[2]]);
    assert!(stderr(&mixed).contains("seed 2 vs 1"), "{}", stderr(&mixed));
    // so is a run that spends its samples another way
    let fixed = dir.join("fixed");
    std::fs::create_dir(&fixed).unwrap();
    let mut m3 = m.to_vec();
    m3.push("--fixed");
    let f = shard_run(&fixed, &m3, 2, 3);
    let mixed = merge(&[&p[0], &f, &p[2]]);
    assert!(
        stderr(&mixed).contains("sample plan fixed looks vs sequential looks"),
        "{}",
        stderr(&mixed)
    );
    // shards of another --filter split another suite, and the refusal says so
    let narrow = dir.join("narrow");
    std::fs::create_dir(&narrow).unwrap();
    let m4 = ["tests/manifests/bsdf.toml", "--filter", "*y/all-bsdfs"];
    let n = shard_run(&narrow, &m4, 2, 3);
    let mixed = merge(&[&p[0], &n, &p[2]]);
    assert!(
        stderr(&mixed).contains("they split different suites")
            && stderr(&mixed).contains("same manifests and --filter"),
        "{}",
        stderr(&mixed)
    );
    // a plain run is not a shard
    let plain = dir.join("plain.json");
    let o = furnace(&[
        "check",
        "-q",
        m[0],
        m[1],
        m[2],
        "--json",
        plain.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let not = merge(&[plain.to_str().unwrap()]);
    assert!(
        stderr(&not).contains("is not a shard's result"),
        "{}",
        stderr(&not)
    );
    // and a bad spec is an error, not a silent full run
    let bad = furnace(&["check", "--shard", "5/4"]);
    assert_eq!(bad.status.code(), Some(2));
    assert!(
        stderr(&bad).contains("--shard \"5/4\" must be K/N"),
        "{}",
        stderr(&bad)
    );
    let _ = std::fs::remove_dir_all(&dir);
}
