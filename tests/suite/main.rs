//! furnace integration tests: one binary, one module per concern.

mod adapter;
mod budgets;
mod cli;
mod colorimetry;
mod digests;
mod docs_consistency;
mod export;
mod export_geometry;
mod false_alarms;
mod film_shards;
mod hostile;
mod isolation;
mod layering;
mod manifest_errors;
mod manifests;
mod measured;
mod models;
mod negative;
mod references;
mod render;
mod report_html;
mod sample_plans;
mod scene_errors;
mod scene_parse;
mod shard;

use std::path::PathBuf;

/// Path of a file relative to the crate root.
pub fn root(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(rel)
}

/// The folder for the tests' scratch files: Cargo's temporary folder for integration tests
/// (target/tmp), so that test runs leave nothing in the system's temporary folder.
pub fn scratch_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
}

/// Runs the `furnace` binary from the crate root with `args`.
pub fn run_furnace(args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_furnace"))
        .current_dir(root(""))
        .args(args)
        .output()
        .unwrap()
}
