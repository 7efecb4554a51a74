//! `furnace compare`: a test image against a reference, region by region and pixel by pixel.

use super::{load_regions, load_rgb, section, write_file, Failure};
use anyhow::Context;
use clap::Args;
use furnace::harness::compare::{self, RgbImage};
use furnace::io::image as io;
use furnace::report::html;
use std::path::PathBuf;

#[derive(Debug, Args)]
// a negative number is a value (refused by its parser), not an unknown option
#[command(allow_negative_numbers = true)]
pub struct CompareArgs {
    /// The image under test (EXR).
    test: PathBuf,
    /// The reference image (EXR); without variance channels it is treated as exact.
    reference: PathBuf,
    /// Named regions (TOML `[[region]]` tables with `name` and `rect = [x0, y0, x1, y1]` in fractions of the image).
    #[arg(long)]
    regions: Option<PathBuf>,
    /// Family-wise false-alarm rate over all region x channel tests (Sidak).
    #[arg(long, default_value_t = 0.01)]
    alpha: f64,
    /// Stated relative model tolerance: a region differs only when |test - reference| exceeds this fraction of the reference by more than noise.
    #[arg(long, default_value_t = 0.0)]
    rel_tolerance: f64,
    /// False-discovery rate of the per-pixel test (Benjamini-Hochberg).
    #[arg(long, default_value_t = 0.01)]
    fdr: f64,
    /// Write a false-colour map of per-pixel |z| (blue 0 .. red >= 5) here (PNG).
    #[arg(long)]
    diff: Option<PathBuf>,
    /// Write the per-pixel relative error |t - r|/(|r| + 0.01), luminance of R, G, B, here (PNG; 1 = white).
    #[arg(long)]
    relerr: Option<PathBuf>,
    /// Write a self-contained HTML report here (images side by side, difference maps, region table).
    #[arg(long)]
    report: Option<PathBuf>,
    /// Write a Markdown summary here (for CI job summaries).
    #[arg(long)]
    markdown: Option<PathBuf>,
}

/// Runs `furnace compare`; returns the exit code.
pub fn run(a: CompareArgs) -> Result<i32, Failure> {
    if !(a.alpha > 0.0 && a.alpha < 1.0 && a.fdr > 0.0 && a.fdr < 1.0) {
        return Err(anyhow::anyhow!("--alpha and --fdr must lie in (0, 1)").into());
    }
    if !(0.0..0.1).contains(&a.rel_tolerance) {
        return Err(anyhow::anyhow!(
            "--rel-tolerance {} must lie in [0, 0.1): a larger model tolerance lets real bugs pass",
            a.rel_tolerance
        )
        .into());
    }
    let mut inputs = vec![
        ("the test image", a.test.as_path()),
        ("the reference", a.reference.as_path()),
    ];
    inputs.extend(super::given(&[("--regions", &a.regions)]));
    let outputs = super::given(&[
        ("--diff", &a.diff),
        ("--relerr", &a.relerr),
        ("--report", &a.report),
        ("--markdown", &a.markdown),
    ]);
    super::distinct_paths(&inputs, &outputs)?;
    let test = load_rgb(&a.test)?;
    let reference = load_rgb(&a.reference)?;
    let regions = match &a.regions {
        None => Vec::new(),
        Some(p) => load_regions(p)?,
    };
    let c = compare::compare(&test, &reference, &regions, a.alpha, a.fdr, a.rel_tolerance)
        .map_err(|e| anyhow::anyhow!(e))?;
    super::say!(
        "test {} vs reference {} ({}x{}){}",
        a.test.display(),
        a.reference.display(),
        test.width,
        test.height,
        if c.reference_has_variance {
            ""
        } else {
            "; the reference has no variance channels and is treated as exact"
        }
    );
    super::say!(
        "{:<8} {:>12} {:>12} {:>12} {:>12} {:>10}",
        "channel",
        "mean test",
        "mean ref",
        "RMSE",
        "relMSE",
        "SMAPE"
    );
    for (ch, m) in compare::CHANNELS.iter().zip(&c.metrics) {
        super::say!(
            "{:<8} {:>12.6} {:>12.6} {:>12.4e} {:>12.4e} {:>10.4}",
            ch,
            m.mean_test,
            m.mean_reference,
            m.rmse,
            m.rel_mse,
            m.smape
        );
    }
    super::say!(
        "{:<22} {:>3} {:>22} {:>22} {:>11} {:>8} {:>9}",
        "region",
        "ch",
        "test ± se",
        "reference ± se",
        "difference",
        "z",
        "p"
    );
    for r in &c.regions {
        super::say!(
            "{:<22} {:>3} {:>13.6} ± {:<7.1e} {:>13.6} ± {:<7.1e} {:>+10.3}% {:>8.2} {:>9.2e}{}",
            r.region,
            r.channel,
            r.test.0,
            r.test.1,
            r.reference.0,
            r.reference.1,
            r.difference_percent(),
            r.z,
            r.p,
            if r.p <= c.alpha {
                format!("  {}", super::comparison_label(true))
            } else {
                String::new()
            }
        );
    }
    if let Some(k) = c.flagged_pixels {
        super::say!(
            "{k} of {} pixels differ beyond noise (Benjamini-Hochberg, FDR {})",
            test.width * test.height,
            a.fdr
        );
        // a pixel mean of few samples is skewed where rare paths carry much of the light, and
        // its t test is then too quick to flag (furnace's own 16-spp Cornell renders against a
        // 1024-spp one flagged 8 % of the pixels, 128-spp ones almost none)
        let fewest = [&test, &reference]
            .iter()
            .filter_map(|im| im.variance_dof)
            .fold(f64::INFINITY, f64::min);
        if k > 0 && fewest < 127.0 {
            super::say!(
                "  (an image's pixel variances rest on {} samples or batches: pixel tests on so few can overstate this count; the region tests above decide the verdict)",
                fewest + 1.0
            );
        }
    }
    if let (Some(p), Some(z)) = (&a.diff, &c.pixel_z) {
        // blue (|z| = 0) to red (|z| >= 5), linear in |z|
        let img: Vec<[f64; 3]> = z
            .iter()
            .map(|z| {
                let t = (z / 5.0).min(1.0);
                [t, 0.0, 1.0 - t]
            })
            .collect();
        io::write_png_srgb(p, test.width, test.height, &img, 1.0)
            .with_context(|| format!("cannot write {}", p.display()))?;
    }
    if let Some(p) = &a.relerr {
        let lum = |im: &RgbImage, i: usize| {
            0.2126 * im.rgb[0][i] + 0.7152 * im.rgb[1][i] + 0.0722 * im.rgb[2][i]
        };
        let img: Vec<[f64; 3]> = (0..test.width * test.height)
            .map(|i| {
                let (t, r) = (lum(&test, i), lum(&reference, i));
                let e = (t - r).abs() / (r.abs() + 0.01);
                [e, e, e]
            })
            .collect();
        io::write_png_srgb(p, test.width, test.height, &img, 1.0)
            .with_context(|| format!("cannot write {}", p.display()))?;
    }
    if a.report.is_some() || a.markdown.is_some() {
        let differ = c.differ;
        let sec = section(
            &a.test,
            &a.reference,
            &test,
            &reference,
            c.clone(),
            &regions,
            a.alpha,
        )?;
        if let Some(p) = &a.report {
            write_file(
                p,
                &html::page("furnace compare", &[], std::slice::from_ref(&sec)),
            )?;
        }
        if let Some(p) = &a.markdown {
            write_file(p, &html::markdown(&[], std::slice::from_ref(&sec)))?;
        }
        debug_assert_eq!(differ, sec.comparison.differ);
    }
    let verdict = super::comparison_label(c.differ);
    super::say!(
        "{verdict}: {} region x channel tests at Sidak per-test alpha {:.2e} (family-wise {})",
        c.regions.len(),
        c.alpha,
        a.alpha
    );
    Ok(if c.differ { 1 } else { 0 })
}
