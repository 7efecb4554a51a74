//! The README and docs against the committed reports: every figure the docs quote from a
//! committed run of the default suite (reports/check-default.*) must be what that run says,
//! so that a regenerated report with different numbers fails here until the docs follow.

use crate::root;
use regex::Regex;

fn read(rel: &str) -> String {
    std::fs::read_to_string(root(rel)).unwrap_or_else(|e| panic!("{rel}: {e}"))
}

/// README.md and every page under docs/, with their names.
fn pages() -> Vec<(String, String)> {
    let mut out = vec![("README.md".to_string(), read("README.md"))];
    let mut docs: Vec<_> = std::fs::read_dir(root("docs"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .collect();
    docs.sort();
    for p in docs {
        let name = format!("docs/{}", p.file_name().unwrap().to_string_lossy());
        out.push((name, std::fs::read_to_string(&p).unwrap()));
    }
    out
}

struct Committed {
    checks: usize,
    stochastic: u64,
    per_test_alpha: String,
    lines: Vec<String>,
}

fn committed() -> Committed {
    let json: serde_json::Value =
        serde_json::from_str(&read("reports/check-default.json")).unwrap();
    let stochastic = json["stochastic_tests"].as_u64().unwrap();
    let family = json["family_alpha"].as_f64().unwrap();
    // Šidák per-test level, printed as the text report prints it (two significant digits).
    let per = -((-family).ln_1p() / stochastic as f64).exp_m1();
    let txt = read("reports/check-default.txt");
    let header =
        Regex::new(r"over (\d+) stochastic tests? \(Šidák: per-test α = ([0-9.e-]+)\)").unwrap();
    let caps = header
        .captures(&txt)
        .expect("reports/check-default.txt states its correction");
    assert_eq!(caps[1].parse::<u64>().unwrap(), stochastic);
    let printed: f64 = caps[2].parse().unwrap();
    assert!((printed / per - 1.0).abs() < 0.05, "{printed} vs {per}");
    Committed {
        checks: json["outcomes"].as_array().unwrap().len(),
        stochastic,
        per_test_alpha: caps[2].to_string(),
        lines: txt.lines().map(str::to_string).collect(),
    }
}

/// The fenced code blocks of a Markdown text, each as its lines.
fn code_blocks(text: &str) -> Vec<Vec<&str>> {
    let mut blocks = Vec::new();
    let mut open: Option<Vec<&str>> = None;
    for line in text.lines() {
        if line.starts_with("```") {
            match open.take() {
                Some(block) => blocks.push(block),
                None => open = Some(Vec::new()),
            }
        } else if let Some(block) = open.as_mut() {
            block.push(line);
        }
    }
    blocks
}

#[test]
fn quoted_verdict_lines_are_in_the_committed_report() {
    // A verdict line quoted in a code block must be a line of reports/check-default.txt (the
    // wall time at its end may differ).
    let c = committed();
    let verdict = Regex::new(r"^(PASS|FAIL|UNSTABLE|ERROR|SKIP)\s{2,}\S").unwrap();
    let time = Regex::new(r"\s+[0-9.]+ s$").unwrap();
    let strip = |l: &str| time.replace(l.trim_end(), "").to_string();
    let report: Vec<String> = c.lines.iter().map(|l| strip(l)).collect();
    let mut quoted = 0;
    for (name, text) in pages() {
        for line in code_blocks(&text).into_iter().flatten() {
            if verdict.is_match(line) {
                quoted += 1;
                assert!(
                    report.contains(&strip(line)),
                    "{name} quotes a verdict line that reports/check-default.txt does not hold:\n{line}"
                );
            }
        }
    }
    assert!(quoted >= 1, "the README quotes at least one verdict line");
}

#[test]
fn quoted_summaries_are_the_committed_reports_summary() {
    // A code block that quotes a run's summary (it names the family-wise rate) must be the
    // committed run's closing lines, word for word.
    let c = committed();
    let mut quoted = 0;
    for (name, text) in pages() {
        for block in code_blocks(&text) {
            if !block
                .iter()
                .any(|l| l.starts_with("family-wise false-alarm rate"))
            {
                continue;
            }
            quoted += 1;
            for l in &block {
                assert!(
                    c.lines.iter().any(|r| r == l),
                    "{name} quotes a summary line that reports/check-default.txt does not hold:\n{l}"
                );
            }
        }
    }
    assert!(
        quoted >= 1,
        "the docs quote the committed summary at least once"
    );
}

#[test]
fn quoted_test_counts_and_levels_match_the_committed_report() {
    let c = committed();
    let over = Regex::new(r"over (?:the whole run's )?(\d+) stochastic tests").unwrap();
    let level = Regex::new(r"per-test α = ([0-9.e-]+)").unwrap();
    let checks = Regex::new(r"default suite has (\d+) checks \((\d+) stochastic tests\)").unwrap();
    let alpha_of =
        Regex::new(r"([0-9.e-]+) for the (\d+) stochastic tests of the\s+default suite").unwrap();
    let mut seen = 0;
    for (name, text) in pages() {
        // statistics.md's tables of the first suite are labelled historical and not checked.
        for caps in over.captures_iter(&text) {
            seen += 1;
            assert_eq!(
                caps[1].parse::<u64>().unwrap(),
                c.stochastic,
                "{name}: {}",
                &caps[0]
            );
        }
        for caps in level.captures_iter(&text) {
            seen += 1;
            assert_eq!(caps[1], c.per_test_alpha, "{name}: {}", &caps[0]);
        }
        for caps in checks.captures_iter(&text) {
            seen += 1;
            assert_eq!(
                caps[1].parse::<usize>().unwrap(),
                c.checks,
                "{name}: {}",
                &caps[0]
            );
            assert_eq!(
                caps[2].parse::<u64>().unwrap(),
                c.stochastic,
                "{name}: {}",
                &caps[0]
            );
        }
        for caps in alpha_of.captures_iter(&text) {
            seen += 1;
            assert_eq!(caps[1], c.per_test_alpha, "{name}: {}", &caps[0]);
            assert_eq!(
                caps[2].parse::<u64>().unwrap(),
                c.stochastic,
                "{name}: {}",
                &caps[0]
            );
        }
    }
    assert!(
        seen >= 5,
        "only {seen} quoted figures found: did the wording change?"
    );
    // The README's field table quotes the example line's α.
    let readme = read("README.md");
    assert!(
        readme.contains(&format!("| `α = {}` |", c.per_test_alpha)),
        "README.md's verdict-field table quotes another α than the committed report's {}",
        c.per_test_alpha
    );
}

/// The cells of every table row of an HTML page, tags stripped and trimmed.
fn html_rows(html: &str) -> Vec<Vec<String>> {
    let row = Regex::new(r"(?s)<tr[^>]*>(.*?)</tr>").unwrap();
    let cell = Regex::new(r"(?s)<t[dh][^>]*>(.*?)</t[dh]>").unwrap();
    let tag = Regex::new(r"<[^>]+>").unwrap();
    row.captures_iter(html)
        .map(|r| {
            cell.captures_iter(&r[1])
                .map(|c| tag.replace_all(&c[1], "").trim().to_string())
                .collect()
        })
        .collect()
}

#[test]
fn the_convergence_table_is_the_committed_reports() {
    // docs/convergence.md's table of measured rates quotes reports/convergence.html: slopes
    // word for word, times to target to their two significant digits.
    let mut report: Vec<(String, f64)> = Vec::new(); // (slope, time to target in s)
    for cells in html_rows(&read("reports/convergence.html")) {
        // configuration, sampler, verdict, p, slope ± CI, expected, C, s/sample, efficiency,
        // N*, time to target
        if cells.len() == 11 && cells[0].starts_with("convergence/") {
            report.push((cells[4].clone(), cells[10].parse().unwrap()));
        }
    }
    let doc = read("docs/convergence.md");
    let line = Regex::new(
        r"(?m)^\|[^|\n]*\|[^|\n]*\| ([−-][0-9.]+ ± [0-9.]+) \|[^|\n]*\| ([0-9.]+) (ms|s)\b",
    )
    .unwrap();
    let quoted: Vec<(String, f64)> = line
        .captures_iter(&doc)
        .map(|c| {
            let v: f64 = c[2].parse().unwrap();
            (
                c[1].replace('−', "-"),
                if &c[3] == "ms" { v / 1e3 } else { v },
            )
        })
        .collect();
    assert!(report.len() >= 10, "the report's table: {report:?}");
    assert_eq!(quoted.len(), report.len(), "rows: {quoted:?} vs {report:?}");
    for ((slope, t), (rs, rt)) in quoted.iter().zip(&report) {
        assert_eq!(
            slope, rs,
            "docs/convergence.md quotes slope {slope}, the report has {rs}"
        );
        assert!(
            (t / rt - 1.0).abs() < 0.05,
            "docs/convergence.md quotes {t} s to target where the report has {rt} s"
        );
    }
}

#[test]
fn the_glossy_efficiency_table_is_the_committed_reports() {
    // docs/rendering.md's efficiency table quotes reports/glossy-efficiency.html: per estimator
    // the slope with its CI word for word, C, seconds per sample and efficiency to their
    // printed digits, the time to target to two significant digits.
    let report: Vec<Vec<String>> = html_rows(&read("reports/glossy-efficiency.html"))
        .into_iter()
        .filter(|cells| cells.len() == 11 && cells[0].starts_with("glossy/"))
        .collect();
    assert_eq!(report.len(), 3, "the report's table: {report:?}");
    let doc = read("docs/rendering.md");
    let table = &doc[doc
        .find("| estimator | ladder | fitted rate |")
        .expect("the efficiency table")..];
    let rows: Vec<Vec<String>> = table
        .lines()
        .skip(2)
        .take_while(|l| l.starts_with('|'))
        .map(|l| {
            l.trim_matches('|')
                .split('|')
                .map(|c| c.trim().replace('−', "-"))
                .collect()
        })
        .collect();
    assert_eq!(rows.len(), report.len(), "rows: {rows:?}");
    let close = |quoted: &str, reported: &str, what: &str| {
        let q: f64 = quoted.trim_end_matches(" s").parse().unwrap();
        let r: f64 = reported.parse().unwrap();
        assert!(
            (q / r - 1.0).abs() < 0.06,
            "docs/rendering.md quotes {what} {quoted} where the report has {reported}"
        );
    };
    for (q, r) in rows.iter().zip(&report) {
        assert_eq!(q[2], r[4], "the slope of {}", r[0]);
        close(&q[3], &r[6], "C");
        close(&q[4], &r[7], "seconds per sample");
        close(&q[5], &r[8], "efficiency");
        close(&q[6], &r[10], "time to target");
    }
}

#[test]
fn the_walk_through_quotes_the_lambert_kind_as_it_is() {
    // docs/checks.md, "Adding a check kind", shows the whole lambert kind: a newcomer copies
    // it, so it must be the file, not an older version of it.
    let real = read("src/harness/checks/lambert.rs");
    let checks = read("docs/checks.md");
    let quoted = code_blocks(&checks)
        .into_iter()
        .find(|b| b.first().is_some_and(|l| l.starts_with("//! `lambert`")))
        .expect("docs/checks.md quotes src/harness/checks/lambert.rs");
    assert_eq!(
        quoted.join("\n"),
        real.trim_end(),
        "docs/checks.md's copy of src/harness/checks/lambert.rs differs from the file"
    );
}
