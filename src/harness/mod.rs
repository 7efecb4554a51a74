//! The validation harness: manifests of checks, the check kinds, the models and renderers they
//! judge, and the runner that applies the family-wise error correction.
//!
//! Rooms, each using only those listed before it (`tests/suite/layering.rs` enforces it):
//! `names`, `outcome`, `error`, `machine` → `measurement`, `shard` → `renderer` → `under_test`, `shared` → `context`, `keys` → `kind` →
//! `model/`,
//! `closed_form/`, `region`, `compare`, `adapter`, `ladder` → `looks` → `checks/` (one file per kind) →
//! `registry` → `manifest` → `isolation`, `budget` → `runner`.

pub mod adapter;
pub mod budget;
pub mod checks;
pub mod closed_form;
pub mod compare;
pub mod context;
pub mod error;
pub mod isolation;
pub mod keys;
pub mod kind;
pub mod ladder;
pub mod looks;
pub mod machine;
pub mod manifest;
pub mod measurement;
pub mod model;
pub mod names;
pub mod outcome;
pub mod region;
pub mod registry;
pub mod renderer;
pub mod runner;
pub mod shard;
pub mod shared;
pub mod under_test;

pub use context::{check_seed, Context, Correction, RunOptions, ShardPlan};
pub use error::CheckError;
pub use kind::{Check, Kind, Scope};
pub use measurement::Measurement;
pub use names::glob_match;
pub use renderer::{BuiltIn, Renderer, RendererError};
pub use runner::{judge, run, run_with};
pub use under_test::{ModelSource, Subject};
