//! `cargo test --release` runs the default manifests, so CI gates from either side.

use crate::root;
use furnace::harness::{self, manifest, BuiltIn, RunOptions};
use furnace::report::text;

#[test]
fn default_manifests_pass() {
    let files = manifest::manifests_in(&root("tests/manifests")).unwrap();
    assert!(files.len() >= 4);
    let mut specs = Vec::new();
    for f in &files {
        specs.extend(manifest::load(f).unwrap_or_else(|e| panic!("{e}")));
    }
    let kinds: std::collections::BTreeSet<&str> = specs.iter().map(|s| s.kind_name()).collect();
    assert_eq!(
        kinds.len(),
        furnace::harness::registry::KINDS.len(),
        "every kind is covered: {kinds:?}"
    );
    let report = harness::run(
        &specs,
        &RunOptions::default(),
        &BuiltIn,
        vec![],
        &mut |_| {},
    );
    // Regression baseline (not validation): the suite's numbers at seed 1, bit for bit. The
    // runner runs these checks side by side (one per core); the baseline was written when it
    // ran them one at a time, so this also shows that the order does not touch a number.
    crate::digests::compare_with_baseline(
        "tests/digests/default-suite-seed1.txt",
        &crate::digests::report_digest(&report),
    );
    let lines: Vec<String> = report.outcomes.iter().map(text::line).collect();
    assert!(
        report.outcomes.iter().all(|o| !o.is_failure()),
        "{}\n{}",
        lines.join("\n"),
        text::summary(&report)
    );
}
