//! furnace integration tests: one binary, one module per concern.

mod adapter;
mod budgets;
mod cli;
mod colorimetry;
mod digests;
mod docs_consistency;
mod export;
mod false_alarms;
mod hostile;
mod layering;
mod manifest_errors;
mod manifests;
mod measured;
mod models;
mod negative;
mod references;
mod render;
mod report_html;
mod scene_errors;
mod scene_parse;
mod shard;

use std::path::PathBuf;

/// Path of a file relative to the crate root.
pub fn root(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(rel)
}
