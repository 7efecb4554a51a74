//! `furnace serve-models`: furnace's own models as a model server on stdin/stdout
//! (docs/model-protocol.md), the stand-in through which CI checks the protocol.

use super::Failure;
use anyhow::Context;
use clap::Args;
use furnace::harness::model::controls::WithControls;
use furnace::harness::model::local::LocalModels;
use furnace::harness::model::server::{serve, Fault};

#[derive(Debug, Args)]
// a negative number is a value (refused by its parser), not an unknown option
#[command(allow_negative_numbers = true)]
pub struct ServeModelsArgs {
    /// Also serve two deliberately wrong BSDFs ("control/…"), which the model kinds must reject.
    #[arg(long)]
    controls: bool,
    /// Misbehave on purpose, to test clients: none, crash, hang, nan, inf, short, version.
    #[arg(long, default_value = "none", hide = true)]
    fault: String,
}

/// Runs `furnace serve-models`; returns the exit code.
pub fn run(a: ServeModelsArgs) -> Result<i32, Failure> {
    let fault = Fault::from_name(&a.fault).ok_or_else(|| {
        anyhow::anyhow!(
            "--fault {:?}: allowed none, crash, hang, nan, inf, short, version",
            a.fault
        )
    })?;
    let (stdin, stdout) = (std::io::stdin(), std::io::stdout());
    let (mut input, mut output) = (stdin.lock(), stdout.lock());
    let name = format!("furnace {}", env!("CARGO_PKG_VERSION"));
    let served = if a.controls {
        serve(
            &WithControls(LocalModels),
            &name,
            &mut input,
            &mut output,
            fault,
        )
    } else {
        serve(&LocalModels, &name, &mut input, &mut output, fault)
    };
    served.context("model server")?;
    Ok(0)
}
