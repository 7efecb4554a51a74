//! Self-contained HTML reports (images embedded as data URIs, no scripts, no external files)
//! and a Markdown summary for CI job pages. The markup is built with `maud`, whose templates
//! escape every interpolated string, so no text reaches the page unescaped.
//!
//! Check results are read in the JSON schema `furnace.check-results/1` ([`super::json`]), as
//! `serde_json::Value`, so a report can gather results from several runs or renderers.
//! Comparisons carry their images: test, reference, a |z| map and a relative-error map, with
//! the tested regions drawn over them.

use super::plot::{deviation_dots, Deviations, DEVIATION_CLIP};
use super::text::power_text;
use crate::harness::compare::{Comparison, Region, RgbImage, CHANNELS};
use crate::io::image::encode_png_srgb;
use maud::{html, Markup, PreEscaped, DOCTYPE};
use serde_json::Value;
use std::fmt::Write as _;

/// An image shown in a report.
#[derive(Debug, Clone, PartialEq)]
pub struct Panel {
    /// Caption under the image.
    pub caption: String,
    /// PNG file contents.
    pub png: Vec<u8>,
}

/// One image comparison as shown in a report.
#[derive(Debug, Clone, PartialEq)]
pub struct ComparisonSection {
    /// Heading, e.g. `out/cbox.exr vs reference/mitsuba/cornell-box.exr`.
    pub title: String,
    /// The statistics.
    pub comparison: Comparison,
    /// Family-wise rate the region tests were corrected to.
    pub family_alpha: f64,
    /// Test, reference, |z| and relative-error images.
    pub panels: Vec<Panel>,
    /// The regions tested, drawn over the images.
    pub regions: Vec<Region>,
}

fn luminance(img: &RgbImage, i: usize) -> f64 {
    0.2126 * img.rgb[0][i] + 0.7152 * img.rgb[1][i] + 0.0722 * img.rgb[2][i]
}

/// The four panels of a comparison: both images at one exposure (the reference's 95th
/// luminance percentile maps to 1), per-pixel |z| (blue 0 → red ≥ 5) when both images carry
/// variances, and |t − r|/(|r| + 0.01) of luminance (white = 1).
pub fn comparison_panels(
    test: &RgbImage,
    reference: &RgbImage,
    c: &Comparison,
) -> Result<Vec<Panel>, String> {
    let (w, h) = (test.width, test.height);
    let n = w * h;
    let mut lum: Vec<f64> = (0..n).map(|i| luminance(reference, i)).collect();
    lum.sort_by(f64::total_cmp);
    let p95 = lum[(n * 95 / 100).min(n - 1)];
    let exposure = if p95 > 0.0 && p95.is_finite() {
        1.0 / p95
    } else {
        1.0
    };
    let rgb = |img: &RgbImage| -> Vec<[f64; 3]> {
        (0..n)
            .map(|i| [img.rgb[0][i], img.rgb[1][i], img.rgb[2][i]])
            .collect()
    };
    let png = |px: &[[f64; 3]], e: f64| encode_png_srgb(w, h, px, e).map_err(|e| e.to_string());
    let mut panels = vec![
        Panel {
            caption: format!("test (exposure {exposure:.3})"),
            png: png(&rgb(test), exposure)?,
        },
        Panel {
            caption: format!("reference (exposure {exposure:.3})"),
            png: png(&rgb(reference), exposure)?,
        },
    ];
    if let Some(z) = &c.pixel_z {
        let px: Vec<[f64; 3]> = z
            .iter()
            .map(|z| {
                let t = (z / 5.0).min(1.0);
                [t, 0.0, 1.0 - t]
            })
            .collect();
        panels.push(Panel {
            caption: "|z| per pixel, max over R, G, B: blue 0, red ≥ 5".into(),
            png: png(&px, 1.0)?,
        });
    }
    let rel: Vec<[f64; 3]> = (0..n)
        .map(|i| {
            let (t, r) = (luminance(test, i), luminance(reference, i));
            let e = (t - r).abs() / (r.abs() + 0.01);
            [e, e, e]
        })
        .collect();
    panels.push(Panel {
        caption: "relative error of luminance |t − r|/(|r| + 0.01): black 0, white ≥ 1".into(),
        png: png(&rel, 1.0)?,
    });
    Ok(panels)
}

/// Escapes text for HTML element content and attribute values (maud's escaping, for the
/// few callers that build markup outside a template).
pub fn escape(s: &str) -> String {
    html! { (s) }.into_string()
}

/// Standard base64 (RFC 4648 §4) with padding, for data URIs.
pub fn base64(bytes: &[u8]) -> String {
    use base64::Engine as _;
    base64::engine::general_purpose::STANDARD.encode(bytes)
}

fn num(v: &Value) -> String {
    match v.as_f64() {
        Some(x) if x != 0.0 && (x.abs() < 1e-3 || x.abs() >= 1e5) => format!("{x:.3e}"),
        Some(x) => format!("{}", (x * 1e6).round() / 1e6),
        None => "–".into(),
    }
}

fn verdict_class(v: &str) -> &'static str {
    match v {
        "PASS" => "pass",
        "FAIL" | "UNSTABLE" | "ERROR" => "fail",
        _ => "skip",
    }
}

/// Counts of each verdict over the outcomes of the check runs that `keep` selects.
fn counts_where(runs: &[Value], keep: impl Fn(&Value) -> bool) -> Vec<(String, usize)> {
    let mut c: std::collections::BTreeMap<String, usize> = Default::default();
    for r in runs {
        for o in r["outcomes"]
            .as_array()
            .into_iter()
            .flatten()
            .filter(|o| keep(o))
        {
            *c.entry(o["verdict"].as_str().unwrap_or("?").to_string())
                .or_default() += 1;
        }
    }
    c.into_iter().collect()
}

/// The counts of each verdict of a check run, its validation checks apart from its regression
/// baselines (`2 PASS, 1 FAIL; regression baselines (not validation): 2 PASS`).
fn verdict_counts(run: &Value) -> String {
    let baseline = |o: &Value| o["regression"].as_bool() == Some(true);
    let text = |c: Vec<(String, usize)>| {
        c.into_iter()
            .map(|(v, n)| format!("{n} {v}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let c = text(counts_where(std::slice::from_ref(run), |o| !baseline(o)));
    let b = text(counts_where(std::slice::from_ref(run), baseline));
    match (c.is_empty(), b.is_empty()) {
        (_, true) => c,
        (true, false) => format!("regression baselines (not validation): {b}"),
        (false, false) => format!("{c}; regression baselines (not validation): {b}"),
    }
}

/// True when every check passed (or was skipped) and no comparison found a difference.
pub fn all_pass(runs: &[Value], comparisons: &[ComparisonSection]) -> bool {
    let checks = runs.iter().all(|r| {
        r["outcomes"]
            .as_array()
            .into_iter()
            .flatten()
            .all(|o| matches!(o["verdict"].as_str(), Some("PASS") | Some("SKIPPED")))
    });
    checks && comparisons.iter().all(|c| !c.comparison.differ)
}

const STYLE: &str = "body{font-family:system-ui,sans-serif;margin:2em;max-width:80em;color:#222}\
table{border-collapse:collapse;margin:1em 0;font-size:0.9em}\
td,th{border:1px solid #ccc;padding:0.25em 0.5em;text-align:right}\
td.l,th.l{text-align:left}.pass{background:#dff5df}.fail{background:#f8d7d7}.skip{background:#eee}\
figure{display:inline-block;margin:0.5em;vertical-align:top}\
.img{position:relative;width:256px}.img svg{position:absolute;left:0;top:0;width:256px;height:100%}\
figure img{width:256px;display:block;image-rendering:pixelated;border:1px solid #999}\
figcaption{font-size:0.8em;max-width:256px}.msg{font-size:0.8em;text-align:left;max-width:40em}\
details summary{cursor:pointer}\
tr:target{outline:3px solid #06c}";

/// The whole report page: a verdict banner, each check run's table, each comparison with its
/// images and region table.
pub fn page(title: &str, runs: &[Value], comparisons: &[ComparisonSection]) -> String {
    page_with_notes(title, runs, comparisons, None)
}

/// A fragment identifier for a check's row in a renderer's table, and its bundle folder's
/// name: `RENDERER--CHECK` with everything but ASCII letters, digits and `-` written `_`, and
/// `-HASH` (16 hex digits of the exact pair) unless both names are letters and digits only.
pub fn row_id(renderer: &str, check: &str) -> String {
    let clean = |s: &str| -> String {
        s.chars()
            .map(|c| {
                if c.is_ascii_alphanumeric() || c == '-' {
                    c
                } else {
                    '_'
                }
            })
            .collect()
    };
    let id = format!("{}--{}", clean(renderer), clean(check));
    let plain = |s: &str| s.chars().all(|c| c.is_ascii_alphanumeric());
    if plain(renderer) && plain(check) {
        return id;
    }
    // Cleaning maps `x/y` and `x_y` to one id, and "--" may also occur inside a name: a hash of
    // the exact pair keeps two checks' bundle folders and rows apart (FNV-1a, 64 bits).
    let hash = renderer
        .bytes()
        .chain([0])
        .chain(check.bytes())
        .fold(0xcbf2_9ce4_8422_2325_u64, |h, b| {
            (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
        });
    format!("{id}-{hash:016x}")
}

fn renderer_of(run: &Value) -> &str {
    run["renderer"].as_str().unwrap_or("furnace")
}

/// The checks that did not pass, over every run: (renderer, check, verdict).
fn not_passed(runs: &[Value]) -> Vec<(&str, &str, &str)> {
    runs.iter()
        .flat_map(|r| {
            r["outcomes"]
                .as_array()
                .into_iter()
                .flatten()
                .map(move |o| (renderer_of(r), o))
        })
        .filter_map(|(r, o)| {
            let v = o["verdict"].as_str().unwrap_or("?");
            (!matches!(v, "PASS" | "SKIPPED")).then(|| (r, o["name"].as_str().unwrap_or(""), v))
        })
        .collect()
}

/// [`page`] with a notes section (plain text: paragraphs separated by blank lines, lines
/// starting with "- " as list items) after the banner: findings and their evidence.
pub fn page_with_notes(
    title: &str,
    runs: &[Value],
    comparisons: &[ComparisonSection],
    notes: Option<&str>,
) -> String {
    html! {
        (DOCTYPE)
        html lang="en" {
            head {
                meta charset="utf-8";
                title { (title) }
                style { (PreEscaped(STYLE)) }
            }
            body {
                h1 { (title) }
                (banner(runs, comparisons))
                @if let Some(n) = notes { (notes_html(n)) }
                @if runs.len() > 1 {
                    (side_by_side(runs))
                } @else if runs.len() == 1 {
                    h2 { "Deviations" }
                    (deviation_figure(runs))
                }
                @for run in runs { (run_table(run)) }
                @for (i, c) in comparisons.iter().enumerate() { (comparison_html(i, c)) }
            }
        }
    }
    .into_string()
}

/// The verdict, the counts of each verdict per renderer, and a link to every check that did
/// not pass and every comparison that found a difference.
fn banner(runs: &[Value], comparisons: &[ComparisonSection]) -> Markup {
    let ok = all_pass(runs, comparisons);
    let bad = not_passed(runs);
    html! {
        div #verdict class=(if ok { "pass" } else { "fail" }) {
            p {
                strong { (if ok { "ALL PASS" } else { "FAILURES" }) }
                " — furnace " (env!("CARGO_PKG_VERSION"))
            }
            @if !runs.is_empty() {
                ul {
                    @for run in runs { li { (renderer_of(run)) ": " (verdict_counts(run)) } }
                }
            }
            @if !bad.is_empty() {
                p { "Not passed:" }
                ul #not-passed {
                    @for (r, name, v) in &bad {
                        li { a href={ "#" (row_id(r, name)) } { (name) } " (" (r) "): " (v) }
                    }
                }
            }
            @for (i, c) in comparisons.iter().enumerate() {
                @if c.comparison.differ {
                    p { a href={ "#comparison-" (i) } { (c.title) } ": DIFFERENT" }
                }
            }
        }
    }
}

/// Notes: "## " lines as headings, paragraphs of "- " lines as lists, other paragraphs as text.
fn notes_html(n: &str) -> Markup {
    let paras: Vec<&str> = n
        .split("\n\n")
        .map(str::trim)
        .filter(|p| !p.is_empty())
        .collect();
    html! {
        h2 { "Notes and findings" }
        @for para in paras {
            @if para.lines().all(|l| l.trim_start().starts_with("- ")) {
                ul { @for l in para.lines() { li { (l.trim_start().trim_start_matches("- ")) } } }
            } @else if let Some(head) = para.strip_prefix("## ") {
                h3 { (head) }
            } @else {
                p { (para) }
            }
        }
    }
}

/// One run's table: a row per check with its numbers and message.
fn run_table(run: &Value) -> Markup {
    let manifests = run["manifests"]
        .as_array()
        .map(|m| {
            m.iter()
                .filter_map(|x| x.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        })
        .unwrap_or_default();
    let renderer = renderer_of(run);
    html! {
        h2 { "Checks: " (renderer) }
        p {
            "manifests " (manifests) "; seed " (num(&run["seed"]))
            "; family-wise false-alarm rate " (num(&run["family_alpha"]))
            " (" (run["correction"].as_str().unwrap_or("")) ", " (num(&run["stochastic_tests"]))
            " stochastic tests); renderer " (renderer)
            @if let Some(machine) = run["machine"].as_str().filter(|m| !m.is_empty()) {
                "; times measured on " (machine)
            }
        }
        table {
            tr {
                th.l { "check" } th.l { "kind" } th { "verdict" } th { "estimate" } th { "± se" }
                th { "expected" } th { "p" } th { "α" } th { "power" } th { "s" }
                th.l { "what was measured" }
            }
            @for o in run["outcomes"].as_array().into_iter().flatten() {
                @let v = o["verdict"].as_str().unwrap_or("?");
                @let name = o["name"].as_str().unwrap_or("");
                tr class=(verdict_class(v)) id=(row_id(renderer, name)) {
                    td.l { (name) }
                    td.l { (o["kind"].as_str().unwrap_or("")) }
                    td {
                        (v)
                        @if o["regression"].as_bool() == Some(true) { " (regression baseline)" }
                    }
                    td { (num(&o["estimate"])) }
                    td { (num(&o["std_error"])) }
                    td { (num(&o["expected"])) }
                    td { (num(&o["p_value"])) }
                    td { (num(&o["alpha"])) }
                    td { (o["detection_power"].as_f64().map(power_text).unwrap_or("–".into())) }
                    td { (format!("{:.2}", o["seconds"].as_f64().unwrap_or(0.0))) }
                    td.msg {
                        @let message = o["message"].as_str().unwrap_or("");
                        // the first clause in the row, the whole account on demand (no script)
                        details {
                            summary { (message.split(';').next().unwrap_or("")) }
                            (message)
                        }
                        @if let Some(i) = o["isolation"].as_str() {
                            p { b { "Isolated: " } (i) }
                        }
                        @if let Some(b) = o["bundle"].as_str() {
                            a href=(b) { "reproducer bundle" }
                        }
                    }
                }
            }
        }
    }
}

/// (estimate − expected)/se of an outcome, where it has a real standard error (not one at the
/// rounding level).
fn sigmas(o: &Value) -> Option<f64> {
    // a regression baseline's band is not a closed form to deviate from
    if o["regression"].as_bool() == Some(true) {
        return None;
    }
    let (e, x, se) = (
        o["estimate"].as_f64()?,
        o["expected"].as_f64()?,
        o["std_error"].as_f64()?,
    );
    (se > 1e-9 * x.abs().max(e.abs()) && se > 0.0).then(|| (e - x) / se)
}

/// Every check name over the runs, first seen first, with its kind.
fn check_names(runs: &[Value]) -> Vec<(String, String)> {
    let mut names: Vec<(String, String)> = Vec::new();
    for r in runs {
        for o in r["outcomes"].as_array().into_iter().flatten() {
            let n = o["name"].as_str().unwrap_or("").to_string();
            if !names.iter().any(|x| x.0 == n) {
                names.push((n, o["kind"].as_str().unwrap_or("").to_string()));
            }
        }
    }
    names
}

/// A run's outcome of check `name`.
fn find(r: &Value, name: &str) -> Option<Value> {
    r["outcomes"]
        .as_array()?
        .iter()
        .find(|o| o["name"].as_str() == Some(name))
        .cloned()
}

/// The deviations of every check with a standard error from its expected value, in standard
/// errors, as a dot plot (one colour per run), with the two-sided bound at the smallest
/// per-test α any run used.
fn deviation_figure(runs: &[Value]) -> Markup {
    let names = check_names(runs);
    let plotted: Vec<&(String, String)> = names
        .iter()
        .filter(|(n, _)| {
            runs.iter()
                .any(|r| find(r, n).as_ref().and_then(sigmas).is_some())
        })
        .collect();
    let deviations: Vec<Deviations> = runs
        .iter()
        .map(|r| Deviations {
            name: renderer_of(r).to_string(),
            sigmas: plotted
                .iter()
                .map(|(n, _)| find(r, n).as_ref().and_then(sigmas))
                .collect(),
        })
        .collect();
    let alpha = runs
        .iter()
        .flat_map(|r| r["outcomes"].as_array().into_iter().flatten())
        .filter_map(|o| o["alpha"].as_f64())
        .fold(f64::INFINITY, f64::min);
    let bound = if alpha.is_finite() && alpha > 0.0 {
        crate::stats::power::z_critical(alpha)
    } else {
        3.0
    };
    let check_names: Vec<String> = plotted.iter().map(|(n, _)| n.clone()).collect();
    let plot = deviation_dots(
        "deviation from the expected value, in standard errors",
        &check_names,
        &deviations,
        bound,
    );
    html! {
        @match &plot {
            Ok(svg) => {
                figure.plot {
                    (PreEscaped(svg))
                    figcaption style="max-width:none" {
                        "Each dot is one renderer's (estimate − expected)/se for a check with a standard error; "
                        "dashed: ±" (format!("{bound:.2}")) ", the two-sided bound at the smallest per-test α ("
                        (format!("{alpha:.2e}")) "); beyond ±" (DEVIATION_CLIP) " drawn at the edge as ×."
                    }
                }
            }
            Err(e) => { p.fail { (e.to_string()) } }
        }
    }
}

/// Renderers side by side: per check, each renderer's estimate ± standard error, its deviation
/// from the expected value in % and in standard errors, verdict, time and samples per second;
/// above the table, the deviations in standard errors as a dot plot.
fn side_by_side(runs: &[Value]) -> Markup {
    let names = check_names(runs);
    html! {
        h2 { "Renderers side by side" }
        (deviation_figure(runs))
        table {
            tr {
                th.l { "check" } th.l { "kind" } th { "expected" }
                @for r in runs { th colspan="5" { (renderer_of(r)) } }
            }
            tr {
                th {} th {} th {}
                @for _ in runs {
                    th { "verdict" } th { "estimate ± se" } th { "deviation" } th { "s" } th { "samples/s" }
                }
            }
            @for (name, kind) in &names {
                @let expected = runs
                    .iter()
                    .filter_map(|r| find(r, name))
                    .map(|o| o["expected"].clone())
                    .find(|e| !e.is_null())
                    .unwrap_or(Value::Null);
                tr {
                    td.l { (name) } td.l { (kind) } td { (num(&expected)) }
                    @for r in runs {
                        @match find(r, name) {
                            None => { td.skip colspan="5" { "not run" } }
                            Some(o) => {
                                @let v = o["verdict"].as_str().unwrap_or("?");
                                @let secs = o["seconds"].as_f64().unwrap_or(0.0);
                                td class=(verdict_class(v)) {
                                    a href={ "#" (row_id(renderer_of(r), name)) } { (v) }
                                }
                                td { (num(&o["estimate"])) " ± " (num(&o["std_error"])) }
                                td { (deviation_text(&o)) }
                                td { (format!("{secs:.2}")) }
                                td {
                                    (o["samples"].as_f64().filter(|_| secs > 0.0)
                                        .map(|n| format!("{:.3e}", n / secs)).unwrap_or("–".into()))
                                }
                            }
                        }
                    }
                }
            }
        }
    }
}

/// "+0.123 % (+1.2σ)": relative deviation, and in standard errors where there is a real one.
fn deviation_text(o: &Value) -> String {
    match (o["estimate"].as_f64(), o["expected"].as_f64()) {
        (Some(e), Some(x)) if x != 0.0 => format!(
            "{:+.3} %{}",
            100.0 * (e / x - 1.0),
            sigmas(o)
                .map(|s| format!(" ({s:+.1}σ)"))
                .unwrap_or_default()
        ),
        _ => "–".into(),
    }
}

/// The regions over an image, in the image's fractional coordinates: red where some channel
/// differs at the comparison's level, yellow elsewhere.
fn region_overlay(s: &ComparisonSection) -> Markup {
    let differs = |name: &str| {
        s.comparison
            .regions
            .iter()
            .any(|r| r.region == name && r.p <= s.comparison.alpha)
    };
    html! {
        @if !s.regions.is_empty() {
            svg viewBox="0 0 1 1" preserveAspectRatio="none" {
                @for r in &s.regions {
                    rect x=(r.rect[0]) y=(r.rect[1]) width=(r.rect[2] - r.rect[0])
                        height=(r.rect[3] - r.rect[1]) fill="none"
                        stroke=(if differs(&r.name) { "#e00" } else { "#fd0" })
                        stroke-width="2" vector-effect="non-scaling-stroke" {
                        title { (r.name) }
                    }
                }
            }
        }
    }
}

fn comparison_html(i: usize, s: &ComparisonSection) -> Markup {
    let c = &s.comparison;
    html! {
        h2 id={ "comparison-" (i) } { (s.title) }
        p class=(if c.differ { "fail" } else { "pass" }) {
            strong { (if c.differ { "DIFFERENT" } else { "AGREE" }) }
            ": " (c.regions.len()) " region × channel z tests at Šidák per-test α "
            (format!("{:.2e}", c.alpha)) " (family-wise " (s.family_alpha) ")"
            @if !c.reference_has_variance {
                "; the reference has no variance channels and is treated as exact"
            }
            @if let Some(k) = c.flagged_pixels {
                "; " (k) " pixels differ beyond noise (Benjamini–Hochberg)"
            }
            @if !s.regions.is_empty() { "; regions drawn over the images (red: differs)" }
        }
        div {
            @for p in &s.panels {
                figure {
                    div.img {
                        img alt=(p.caption) src={ "data:image/png;base64," (base64(&p.png)) };
                        (region_overlay(s))
                    }
                    figcaption { (p.caption) }
                }
            }
        }
        table {
            tr {
                th.l { "channel" } th { "mean test" } th { "mean reference" } th { "RMSE" }
                th { "relMSE" } th { "SMAPE" }
            }
            @for (ch, m) in CHANNELS.iter().zip(&c.metrics) {
                tr {
                    td.l { (ch) }
                    td { (format!("{:.6}", m.mean_test)) }
                    td { (format!("{:.6}", m.mean_reference)) }
                    td { (format!("{:.4e}", m.rmse)) }
                    td { (format!("{:.4e}", m.rel_mse)) }
                    td { (format!("{:.4}", m.smape)) }
                }
            }
        }
        table {
            tr {
                th.l { "region" } th { "ch" } th { "test ± se" } th { "reference ± se" }
                th { "difference" } th { "z" } th { "p" }
            }
            @for r in &c.regions {
                tr class=(if r.p <= c.alpha { "fail" } else { "pass" }) {
                    td.l { (r.region) }
                    td { (r.channel) }
                    td { (format!("{:.6} ± {:.1e}", r.test.0, r.test.1)) }
                    td { (format!("{:.6} ± {:.1e}", r.reference.0, r.reference.1)) }
                    td { (format!("{:+.3} %", r.difference_percent())) }
                    td { (format!("{:.2}", r.z)) }
                    td { (format!("{:.2e}", r.p)) }
                }
            }
        }
    }
}

/// A Markdown summary for a CI job page: overall verdict, counts, failing checks, comparisons.
pub fn markdown(runs: &[Value], comparisons: &[ComparisonSection]) -> String {
    let mut m = String::new();
    let ok = all_pass(runs, comparisons);
    let _ = writeln!(
        m,
        "## furnace: {}\n",
        if ok { "all pass" } else { "failures" }
    );
    for run in runs {
        let counts = verdict_counts(run);
        if !counts.is_empty() {
            let _ = writeln!(
                m,
                "Checks ({}): {counts}\n",
                run["renderer"].as_str().unwrap_or("furnace"),
            );
        }
    }
    let bad: Vec<(&str, &Value)> = runs
        .iter()
        .flat_map(|r| {
            let name = r["renderer"].as_str().unwrap_or("furnace");
            r["outcomes"]
                .as_array()
                .into_iter()
                .flatten()
                .map(move |o| (name, o))
        })
        .filter(|(_, o)| !matches!(o["verdict"].as_str(), Some("PASS") | Some("SKIPPED")))
        .collect();
    if !bad.is_empty() {
        m.push_str(
            "| check | renderer | verdict | estimate | expected | p | what |\n|---|---|---|---|---|---|---|\n",
        );
        for (renderer, o) in bad {
            let _ = writeln!(
                m,
                "| {} | {renderer} | {} | {} ± {} | {} | {} | {} |",
                o["name"].as_str().unwrap_or(""),
                o["verdict"].as_str().unwrap_or(""),
                num(&o["estimate"]),
                num(&o["std_error"]),
                num(&o["expected"]),
                num(&o["p_value"]),
                match o["isolation"].as_str() {
                    Some(i) => format!("{}; isolated: {i}", o["message"].as_str().unwrap_or("")),
                    None => o["message"].as_str().unwrap_or("").to_string(),
                }
                .replace('|', "\\|"),
            );
        }
        m.push('\n');
    }
    for s in comparisons {
        let c = &s.comparison;
        let worst = c.regions.iter().min_by(|a, b| a.p.total_cmp(&b.p));
        let _ = writeln!(
            m,
            "- **{}**: {}, {} region × channel tests{}",
            s.title,
            if c.differ { "DIFFERENT" } else { "agree" },
            c.regions.len(),
            worst
                .map(|w| format!(
                    "; smallest p {:.2e} ({} {}, {:+.3} %)",
                    w.p,
                    w.region,
                    w.channel,
                    100.0 * (w.test.0 / w.reference.0 - 1.0)
                ))
                .unwrap_or_default()
        );
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::harness::compare::{compare, Region};

    /// Names that clean to one id (`x/y`, `x_y`; "--" inside a name) keep distinct row ids
    /// and bundle folders; plain names keep theirs as written.
    #[test]
    fn row_ids_keep_every_pair_apart() {
        assert_eq!(row_id("mitsuba3", "lambert"), "mitsuba3--lambert");
        let ids = [
            row_id("good", "x/y"),
            row_id("good", "x_y"),
            row_id("good", "x--y"),
            row_id("good--x", "y"),
            row_id("good-", "-x--y"),
        ];
        for (i, a) in ids.iter().enumerate() {
            assert!(a.starts_with("good"), "{a}");
            for b in &ids[..i] {
                assert_ne!(a, b);
            }
        }
    }

    #[test]
    fn base64_matches_rfc4648_vectors() {
        for (i, o) in [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ] {
            assert_eq!(base64(i.as_bytes()), o);
        }
    }

    #[test]
    fn escape_covers_markup() {
        // attributes are always double-quoted, so ' needs no escape
        assert_eq!(
            escape("<a href=\"x\">&'"),
            "&lt;a href=&quot;x&quot;&gt;&amp;'"
        );
    }

    fn image(v: f64) -> RgbImage {
        RgbImage {
            width: 4,
            height: 4,
            rgb: std::array::from_fn(|_| vec![v; 16]),
            variance: Some(std::array::from_fn(|_| vec![1e-6; 16])),
            variance_dof: None,
            variance_variance: None,
            pixels_correlated: false,
            runs: Vec::new(),
        }
    }

    #[test]
    fn page_embeds_images_and_marks_failures() {
        let (t, r) = (image(1.1), image(1.0));
        let regions = [Region {
            name: "left <half>".into(),
            rect: [0.0, 0.0, 0.5, 1.0],
        }];
        let c = compare(&t, &r, &regions, 0.01, 0.01, 0.0).unwrap();
        let s = ComparisonSection {
            title: "t vs r".into(),
            panels: comparison_panels(&t, &r, &c).unwrap(),
            comparison: c,
            family_alpha: 0.01,
            regions: regions.to_vec(),
        };
        assert_eq!(s.panels.len(), 4);
        let run: Value = serde_json::from_str(
            r#"{"schema":"furnace.check-results/1","manifests":["m.toml"],"seed":1,"family_alpha":0.01,"correction":"sidak","stochastic_tests":1,
               "outcomes":[{"name":"a","kind":"furnace","verdict":"PASS","estimate":2.0,"std_error":0.001,"expected":2.0,"p_value":0.5,"alpha":0.01,"detection_power":0.002,"seconds":0.1,"message":"ok"},
                           {"name":"b","kind":"lambert","verdict":"FAIL","estimate":1.0,"std_error":0.001,"expected":2.0,"p_value":1e-9,"alpha":0.01,"seconds":0.1,"message":"x | y"}]}"#,
        )
        .unwrap();
        let html = page(
            "report",
            std::slice::from_ref(&run),
            std::slice::from_ref(&s),
        );
        assert_eq!(html.matches("<img ").count(), 4);
        assert_eq!(html.matches("data:image/png;base64,iVBORw0KGgo").count(), 4);
        assert!(html.contains("left &lt;half&gt;") && html.contains("DIFFERENT"));
        assert!(html.contains("<tr class=\"fail\" id=\"furnace--b\"><td class=\"l\">b</td>"));
        // the banner counts the verdicts and links the failing check's row
        assert!(
            html.contains("FAILURES") && html.contains("furnace: 1 FAIL, 1 PASS"),
            "{html}"
        );
        assert!(
            html.contains("<a href=\"#furnace--b\">b</a> (furnace): FAIL"),
            "{html}"
        );
        assert!(html.contains("<a href=\"#comparison-0\">t vs r</a>: DIFFERENT"));
        // the region is drawn over each of the four images, red as it differs
        assert_eq!(html.matches("<title>left &lt;half&gt;</title>").count(), 4);
        assert!(html.contains("stroke=\"#e00\""));
        // power with significant digits
        assert!(html.contains("<td>0.2 %</td>"), "{html}");
        // a single run gets its deviations plotted too (check a is exact: 0σ; b: −1000σ)
        assert!(html.contains("<h2>Deviations</h2>") && html.contains("<svg"));
        let md = markdown(&[run], &[s]);
        assert!(md.starts_with("## furnace: failures"), "{md}");
        assert!(
            md.contains("Checks (furnace): 1 FAIL, 1 PASS") && md.contains("x \\| y"),
            "{md}"
        );
        assert!(md.contains("**t vs r**: DIFFERENT"), "{md}");
    }
}
