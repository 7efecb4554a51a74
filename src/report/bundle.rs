//! Reproducer bundles: for a check that did not pass against an external renderer, a folder a
//! renderer team can attach to its own bug tracker. It holds `README.md` (what was expected and
//! where that value comes from, what was measured, how to re-run it, a summary paragraph),
//! `outcome.json` (the outcome in the JSON schema) and, written by the adapter while the check
//! ran, one `render-N/` folder per render with the scene exactly as exported, the images the
//! renderer wrote and `command.sh`, which re-runs the renderer alone.

use crate::harness::measurement::fmt_sig;
use crate::harness::outcome::Outcome;

/// What a bundle says about the run beyond the outcome itself.
#[derive(Debug, Clone, PartialEq)]
pub struct BundleInfo {
    /// The renderer as `--renderer` named it (`NAME[:VARIANT]`).
    pub renderer: String,
    /// Its version, as its table's `version` command printed it (or why there is none).
    pub renderer_version: String,
    /// The `furnace check` command line that re-runs the check alone.
    pub rerun: String,
    /// Where the check is defined (`file:line`).
    pub origin: String,
    /// `render-N` folders the adapter kept for the check, in order.
    pub renders: Vec<String>,
}

fn opt(x: Option<f64>) -> String {
    x.map_or("—".into(), fmt_sig)
}

/// The bundle's README.md.
pub fn readme(o: &Outcome, info: &BundleInfo) -> String {
    let verdict = crate::report::text::verdict_label(o.verdict).trim();
    let renders = if info.renders.is_empty() {
        "No image was rendered for this check (a model-level check, or one that ended before \
         rendering): the outcome and the re-run command are the reproducer."
            .to_string()
    } else {
        format!(
            "Each of {} holds the scene exactly as furnace exported it (`scene.xml` or \
             `scene.json` and the files it names), the images the renderer wrote (`batch-B.exr`, one per independent \
             run) and `command.sh`, which re-runs the renderer alone as furnace ran it: \
             `sh {}/command.sh` (it changes to the folder furnace ran from, for the renderer \
             table's relative paths). Folders after the check's own renders hold those of its \
             isolation ladder's variants, in the ladder's order.",
            info.renders
                .iter()
                .map(|r| format!("`{r}/`"))
                .collect::<Vec<_>>()
                .join(", "),
            info.renders[0]
        )
    };
    format!(
        "# {name}: {verdict} against {renderer}\n\n\
         | | |\n|---|---|\n\
         | check | `{name}`, kind `{kind}`, defined at `{origin}` |\n\
         | renderer | `{renderer}`, version {version} |\n\
         | expected | {expected} (the kind's closed form or reference, computed by furnace independently of the renderer: docs/checks.md, section `{kind}`) |\n\
         | measured | {estimate} ± {se} (standard error) |\n\
         | test | {stat}, p = {p} against the per-test level α = {alpha} (family-wise corrected) |\n\
         | samples, time | {samples}, {seconds:.2} s |\n\n\
         ## What was measured\n\n{message}\n\n{isolation}\
         ## Re-run the check\n\n```\n{rerun}\n```\n\n\
         (A stochastic check's `--alpha` is the per-test level α above: alone, the check is the \
         whole family, so the re-run judges it at the same level.)\n\n\
         ## The renderer alone\n\n{renders}\n\n\
         ## Summary\n\n\
         furnace {furnace} judged {renderer} ({version}) with the check `{name}` (kind `{kind}`): \
         expected {expected}, measured {estimate} ± {se}, {stat}, p = {p} against α = {alpha}; \
         verdict {verdict}. The scene as rendered and the command are in this folder. This is a \
         measurement, not yet a diagnosis: before it is called a bias of the renderer, the \
         exporter and the conventions (units, spectra, camera, emitter sidedness, depth) have \
         to be ruled out, for example by the simplest variant of the scene that still \
         disagrees.\n",
        name = o.name,
        kind = o.kind,
        origin = info.origin,
        renderer = info.renderer,
        version = info.renderer_version,
        expected = opt(o.expected),
        estimate = opt(o.estimate),
        se = opt(o.std_error),
        stat = match crate::report::text::statistic_text(o) {
            t if t.is_empty() => "no statistic".into(),
            t => t,
        },
        p = opt(o.p_value),
        alpha = opt(o.alpha),
        samples = o.samples,
        seconds = o.seconds,
        message = o.message,
        isolation = match &o.isolation {
            Some(i) => format!(
                "## Isolation\n\nfurnace re-ran simpler variants of the check (its isolation ladder, docs/checks.md): {i}.\n\n"
            ),
            None => String::new(),
        },
        rerun = info.rerun,
        furnace = env!("CARGO_PKG_VERSION"),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::harness::outcome::{Statistic, Verdict};

    #[test]
    fn readme_states_expected_measured_test_and_how_to_rerun() {
        let mut o = Outcome::new("furnace/sphere[albedo=0.5]", "furnace");
        o.verdict = Verdict::Fail;
        o.estimate = Some(1.8);
        o.std_error = Some(0.01);
        o.expected = Some(2.0);
        o.statistic = Statistic::Z { z: -20.0 };
        o.p_value = Some(1e-88);
        o.alpha = Some(1e-4);
        o.message = "radiance of a white furnace".into();
        let info = BundleInfo {
            renderer: "stand-in".into(),
            renderer_version: "1.2.3".into(),
            rerun: "furnace check m.toml --filter 'x'".into(),
            origin: "m.toml:3".into(),
            renders: vec!["render-0".into()],
        };
        let r = readme(&o, &info);
        for part in [
            "# furnace/sphere[albedo=0.5]: FAIL against stand-in",
            "| expected | 2.000 ",
            "| measured | 1.800 ± 0.01000",
            "z = -20, p = 1.000e-88",
            "furnace check m.toml --filter 'x'",
            "sh render-0/command.sh",
            "version 1.2.3",
            "not yet a diagnosis",
        ] {
            assert!(r.contains(part), "{part:?} missing from\n{r}");
        }
    }
}
