//! Self-contained HTML reports (images embedded as data URIs, no scripts, no external files)
//! and a Markdown summary for CI job pages.
//!
//! Check results are read in the JSON schema `furnace.check-results/1` ([`super::json`]), as
//! `serde_json::Value`, so a report can gather results from several runs or renderers.
//! Comparisons carry their images: test, reference, a |z| map and a relative-error map.

use crate::harness::compare::{Comparison, RgbImage, CHANNELS};
use crate::io::image::encode_png_srgb;
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

/// Escapes text for HTML element content and attribute values.
pub fn escape(s: &str) -> String {
    let mut o = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => o.push_str("&amp;"),
            '<' => o.push_str("&lt;"),
            '>' => o.push_str("&gt;"),
            '"' => o.push_str("&quot;"),
            '\'' => o.push_str("&#39;"),
            c => o.push(c),
        }
    }
    o
}

/// Standard base64 (RFC 4648 §4) with padding.
pub fn base64(bytes: &[u8]) -> String {
    const T: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut o = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            *chunk.get(1).unwrap_or(&0),
            *chunk.get(2).unwrap_or(&0),
        ];
        let v = (b[0] as u32) << 16 | (b[1] as u32) << 8 | b[2] as u32;
        for k in 0..4 {
            if k <= chunk.len() {
                o.push(T[(v >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                o.push('=');
            }
        }
    }
    o
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
figure img{width:256px;image-rendering:pixelated;border:1px solid #999}\
figcaption{font-size:0.8em;max-width:256px}.msg{font-size:0.8em;text-align:left;max-width:40em}";

/// The whole report page: a verdict banner, each check run's table, each comparison with its
/// images and region table.
pub fn page(title: &str, runs: &[Value], comparisons: &[ComparisonSection]) -> String {
    page_with_notes(title, runs, comparisons, None)
}

/// [`page`] with a notes section (plain text: paragraphs separated by blank lines, lines
/// starting with "- " as list items) after the banner: findings and their evidence.
pub fn page_with_notes(
    title: &str,
    runs: &[Value],
    comparisons: &[ComparisonSection],
    notes: Option<&str>,
) -> String {
    let mut h = String::new();
    let ok = all_pass(runs, comparisons);
    let _ = write!(
        h,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{}</title><style>{STYLE}</style></head><body>\n<h1>{}</h1>\n",
        escape(title),
        escape(title)
    );
    let _ = writeln!(
        h,
        "<p id=\"verdict\" class=\"{}\"><strong>{}</strong> — furnace {}</p>",
        if ok { "pass" } else { "fail" },
        if ok {
            "ALL PASS"
        } else {
            "FAILURES: see the red rows"
        },
        env!("CARGO_PKG_VERSION")
    );
    if let Some(n) = notes {
        h.push_str("<h2>Notes and findings</h2>\n");
        for para in n.split("\n\n").map(str::trim).filter(|p| !p.is_empty()) {
            if para.lines().all(|l| l.trim_start().starts_with("- ")) {
                h.push_str("<ul>");
                for l in para.lines() {
                    let _ = write!(
                        h,
                        "<li>{}</li>",
                        escape(l.trim_start().trim_start_matches("- "))
                    );
                }
                h.push_str("</ul>\n");
            } else if let Some(head) = para.strip_prefix("## ") {
                let _ = writeln!(h, "<h3>{}</h3>", escape(head));
            } else {
                let _ = writeln!(h, "<p>{}</p>", escape(para));
            }
        }
    }
    if runs.len() > 1 {
        side_by_side(&mut h, runs);
    }
    for run in runs {
        let _ = writeln!(
            h,
            "<h2>Checks: {}</h2>\n<p>manifests {}; seed {}; family-wise false-alarm rate {} ({}, {} stochastic tests); renderer {}</p>",
            escape(run["renderer"].as_str().unwrap_or("furnace")),
            escape(&run["manifests"].as_array().map(|m| m.iter().filter_map(|x| x.as_str()).collect::<Vec<_>>().join(", ")).unwrap_or_default()),
            num(&run["seed"]),
            num(&run["family_alpha"]),
            escape(run["correction"].as_str().unwrap_or("")),
            num(&run["stochastic_tests"]),
            escape(run["renderer"].as_str().unwrap_or("furnace")),
        );
        h.push_str("<table><tr><th class=\"l\">check</th><th class=\"l\">kind</th><th>verdict</th><th>estimate</th><th>± se</th><th>expected</th><th>p</th><th>α</th><th>power</th><th>s</th><th class=\"l\">what was measured</th></tr>\n");
        for o in run["outcomes"].as_array().into_iter().flatten() {
            let v = o["verdict"].as_str().unwrap_or("?");
            let power = o["detection_power"]
                .as_f64()
                .map(|p| format!("{:.3} %", 100.0 * p))
                .unwrap_or("–".into());
            let _ = writeln!(
                h,
                "<tr class=\"{}\"><td class=\"l\">{}</td><td class=\"l\">{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{:.2}</td><td class=\"msg\">{}</td></tr>",
                verdict_class(v),
                escape(o["name"].as_str().unwrap_or("")),
                escape(o["kind"].as_str().unwrap_or("")),
                if o["regression"].as_bool() == Some(true) {
                    format!("{v} (regression baseline)")
                } else {
                    v.to_string()
                },
                num(&o["estimate"]),
                num(&o["std_error"]),
                num(&o["expected"]),
                num(&o["p_value"]),
                num(&o["alpha"]),
                power,
                o["seconds"].as_f64().unwrap_or(0.0),
                escape(o["message"].as_str().unwrap_or("")),
            );
        }
        h.push_str("</table>\n");
    }
    for c in comparisons {
        comparison_html(&mut h, c);
    }
    h.push_str("</body></html>\n");
    h
}

/// Renderers side by side: per check, each renderer's estimate ± standard error, its deviation
/// from the expected value in % and in standard errors, verdict, time and samples per second.
fn side_by_side(h: &mut String, runs: &[Value]) {
    let mut names: Vec<(String, String)> = Vec::new();
    for r in runs {
        for o in r["outcomes"].as_array().into_iter().flatten() {
            let n = o["name"].as_str().unwrap_or("").to_string();
            if !names.iter().any(|x| x.0 == n) {
                names.push((n, o["kind"].as_str().unwrap_or("").to_string()));
            }
        }
    }
    h.push_str("<h2>Renderers side by side</h2>\n<table><tr><th class=\"l\">check</th><th class=\"l\">kind</th><th>expected</th>");
    for r in runs {
        let _ = write!(
            h,
            "<th colspan=\"5\">{}</th>",
            escape(r["renderer"].as_str().unwrap_or("?"))
        );
    }
    h.push_str("</tr>\n<tr><th></th><th></th><th></th>");
    for _ in runs {
        h.push_str(
            "<th>verdict</th><th>estimate ± se</th><th>deviation</th><th>s</th><th>samples/s</th>",
        );
    }
    h.push_str("</tr>\n");
    for (name, kind) in &names {
        let find = |r: &Value| -> Option<Value> {
            r["outcomes"]
                .as_array()?
                .iter()
                .find(|o| o["name"].as_str() == Some(name.as_str()))
                .cloned()
        };
        let expected = runs
            .iter()
            .filter_map(&find)
            .map(|o| o["expected"].clone())
            .find(|e| !e.is_null())
            .unwrap_or(Value::Null);
        let _ = write!(
            h,
            "<tr><td class=\"l\">{}</td><td class=\"l\">{}</td><td>{}</td>",
            escape(name),
            escape(kind),
            num(&expected)
        );
        for r in runs {
            match find(r) {
                None => h.push_str("<td class=\"skip\" colspan=\"5\">not run</td>"),
                Some(o) => {
                    let v = o["verdict"].as_str().unwrap_or("?");
                    let dev = match (
                        o["estimate"].as_f64(),
                        o["expected"].as_f64(),
                        o["std_error"].as_f64(),
                    ) {
                        (Some(e), Some(x), se) if x != 0.0 => format!(
                            "{:+.3} %{}",
                            100.0 * (e / x - 1.0),
                            // σ only for a real standard error (not rounding-level)
                            se.filter(|s| *s > 1e-9 * x.abs())
                                .map(|s| format!(" ({:+.1}σ)", (e - x) / s))
                                .unwrap_or_default()
                        ),
                        _ => "–".into(),
                    };
                    let secs = o["seconds"].as_f64().unwrap_or(0.0);
                    let rate = o["samples"]
                        .as_f64()
                        .filter(|_| secs > 0.0)
                        .map(|n| format!("{:.3e}", n / secs))
                        .unwrap_or("–".into());
                    let _ = write!(
                        h,
                        "<td class=\"{}\">{v}</td><td>{} ± {}</td><td>{dev}</td><td>{secs:.2}</td><td>{rate}</td>",
                        verdict_class(v),
                        num(&o["estimate"]),
                        num(&o["std_error"]),
                    );
                }
            }
        }
        h.push_str("</tr>\n");
    }
    h.push_str("</table>\n");
}

fn comparison_html(h: &mut String, s: &ComparisonSection) {
    let c = &s.comparison;
    let _ = writeln!(
        h,
        "<h2>{}</h2>\n<p class=\"{}\"><strong>{}</strong>: {} region × channel z tests at Šidák per-test α {:.2e} (family-wise {}){}{}</p>",
        escape(&s.title),
        if c.differ { "fail" } else { "pass" },
        if c.differ { "DIFFERENT" } else { "AGREE" },
        c.regions.len(),
        c.alpha,
        s.family_alpha,
        if c.reference_has_variance { "" } else { "; the reference has no variance channels and is treated as exact" },
        c.flagged_pixels.map(|k| format!("; {k} pixels differ beyond noise (Benjamini–Hochberg)")).unwrap_or_default(),
    );
    h.push_str("<div>");
    for p in &s.panels {
        let _ = write!(
            h,
            "<figure><img alt=\"{}\" src=\"data:image/png;base64,{}\"><figcaption>{}</figcaption></figure>",
            escape(&p.caption),
            base64(&p.png),
            escape(&p.caption)
        );
    }
    h.push_str("</div>\n<table><tr><th class=\"l\">channel</th><th>mean test</th><th>mean reference</th><th>RMSE</th><th>relMSE</th><th>SMAPE</th></tr>\n");
    for (ch, m) in CHANNELS.iter().zip(&c.metrics) {
        let _ = writeln!(
            h,
            "<tr><td class=\"l\">{ch}</td><td>{:.6}</td><td>{:.6}</td><td>{:.4e}</td><td>{:.4e}</td><td>{:.4}</td></tr>",
            m.mean_test, m.mean_reference, m.rmse, m.rel_mse, m.smape
        );
    }
    h.push_str("</table>\n<table><tr><th class=\"l\">region</th><th>ch</th><th>test ± se</th><th>reference ± se</th><th>difference</th><th>z</th><th>p</th></tr>\n");
    for r in &c.regions {
        let _ = writeln!(
            h,
            "<tr class=\"{}\"><td class=\"l\">{}</td><td>{}</td><td>{:.6} ± {:.1e}</td><td>{:.6} ± {:.1e}</td><td>{:+.3} %</td><td>{:.2}</td><td>{:.2e}</td></tr>",
            if r.p <= c.alpha { "fail" } else { "pass" },
            escape(&r.region),
            r.channel,
            r.test.0,
            r.test.1,
            r.reference.0,
            r.reference.1,
            r.difference_percent(),
            r.z,
            r.p
        );
    }
    h.push_str("</table>\n");
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
    let baseline = |o: &Value| o["regression"].as_bool() == Some(true);
    for run in runs {
        let text = |c: Vec<(String, usize)>| {
            c.into_iter()
                .map(|(v, n)| format!("{n} {v}"))
                .collect::<Vec<_>>()
                .join(", ")
        };
        let c = text(counts_where(std::slice::from_ref(run), |o| !baseline(o)));
        let b = text(counts_where(std::slice::from_ref(run), baseline));
        if !c.is_empty() || !b.is_empty() {
            let _ = writeln!(
                m,
                "Checks ({}): {}{}\n",
                run["renderer"].as_str().unwrap_or("furnace"),
                c,
                if b.is_empty() {
                    String::new()
                } else {
                    format!("; regression baselines (not validation): {b}")
                }
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
                o["message"].as_str().unwrap_or("").replace('|', "\\|"),
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
        assert_eq!(
            escape("<a href=\"x\">&'"),
            "&lt;a href=&quot;x&quot;&gt;&amp;&#39;"
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
        assert!(html.contains("class=\"fail\"><td class=\"l\">b</td>"));
        assert!(html.contains("FAILURES"));
        let md = markdown(&[run], &[s]);
        assert!(md.starts_with("## furnace: failures"), "{md}");
        assert!(
            md.contains("Checks (furnace): 1 FAIL, 1 PASS") && md.contains("x \\| y"),
            "{md}"
        );
        assert!(md.contains("**t vs r**: DIFFERENT"), "{md}");
    }
}
