//! `furnace merge-films`: the partial films of a sharded render (`render --shard K/N`) joined
//! into the EXR and PNG the whole render writes, bit for bit.

use super::Failure;
use anyhow::Context;
use clap::Args;
use std::path::PathBuf;

#[derive(Debug, Args)]
// a negative number is a value (refused by its parser), not an unknown option
#[command(allow_negative_numbers = true)]
pub struct MergeFilmsArgs {
    /// The parts' partial films (`furnace render --shard K/N`), every part, in any order.
    #[arg(required = true)]
    parts: Vec<PathBuf>,
    /// Output EXR path.
    #[arg(short, long)]
    out: PathBuf,
    /// PNG preview path [default: the EXR path with extension .png].
    #[arg(long)]
    png: Option<PathBuf>,
    /// Multiplier applied to linear sRGB before the PNG's sRGB encoding.
    #[arg(long, default_value_t = 1.0)]
    exposure: f64,
}

/// Runs `furnace merge-films`; returns the exit code (as `render`'s: 1 when pixels are not
/// finite or paths were cut).
pub fn run(a: MergeFilmsArgs) -> Result<i32, Failure> {
    if !(a.exposure.is_finite() && a.exposure >= 0.0) {
        return Err(
            anyhow::anyhow!("--exposure {:?} must be a finite number >= 0", a.exposure).into(),
        );
    }
    let png = super::preview_path(&a.out, a.png.as_deref(), true)?;
    let inputs: Vec<(&str, &std::path::Path)> = a
        .parts
        .iter()
        .map(|p| ("a partial film", p.as_path()))
        .collect();
    super::distinct_paths(&inputs, &[("--out", &a.out), ("the PNG preview", &png)])?;
    let (header, film) = furnace::film::partial::merge_files(&a.parts).context(
        "cannot merge the partial films (each `render --shard K/N` writes one; give all N)",
    )?;
    let written = super::render::write_film(
        film,
        header.attributes,
        Vec::new(),
        &a.out,
        &png,
        a.exposure,
    )?;
    super::say!(
        "{}x{} px from {} parts; noise: mean variance of the Y pixel means over the squared mean of Y {:.4e}",
        written.width,
        written.height,
        a.parts.len(),
        written.relative_variance
    );
    Ok(written.code)
}
