//! Machine-readable results: the whole [`RunReport`] as pretty JSON under the schema
//! name [`SCHEMA`], documented field by field in [`SCHEMA_DOC`].
//!
//! Non-finite numbers (NaN, ±inf) are written as `null`: JSON has no spelling for them.

use serde::Serialize;

use crate::harness::outcome::RunReport;

/// The schema name written as the top-level `"schema"` key. The number after the slash
/// changes only when a field is removed, renamed or changes meaning.
pub const SCHEMA: &str = "furnace.check-results/1";

/// Markdown section documenting every field of the JSON document written by [`to_json`]
/// (name, type, unit, meaning), for inclusion in the README.
pub const SCHEMA_DOC: &str = r#"## JSON results (`furnace.check-results/1`)

`furnace` writes one JSON object per run. Numbers are JSON numbers; a number that is
`null` was either not measured or not finite (NaN or infinite: JSON cannot spell those).
Fields may be added within schema version 1; none is removed or changes meaning.

### Run

| field | type | unit | meaning |
|---|---|---|---|
| `schema` | string | — | Always `"furnace.check-results/1"`. |
| `furnace_version` | string | — | Version of furnace that ran the checks. |
| `renderer` | string | — | The renderer judged: `"furnace X.Y.Z"` (the built-in path tracer) or an external renderer as `NAME` or `NAME:VARIANT` (`--renderer`). |
| `manifests` | array of string | — | Manifest files that were run, in order. |
| `seed` | integer (u64) | — | Run seed; each check's seed derives from it unless the check sets its own. May exceed 2^53: parse as a 64-bit integer. |
| `family_alpha` | number or null | probability | Family-wise false-alarm rate that the multiple-testing correction holds over all stochastic tests of the run. |
| `correction` | string | — | Multiple-testing correction: `"sidak"` or `"holm"`. |
| `stochastic_tests` | integer | count | Number of stochastic tests the correction spans. |
| `looks` | string (absent in files written before 2026-12-05) | — | How the checks whose spp is a sample budget spent it: `"sequential"` (looks at ¼, ½ and all of the budget, stopping once the verdict is settled; `furnace check`'s default) or `"fixed"` (`--fixed`, all at once). |
| `power` | number (absent without `--power`) | relative | The power target δ that set every budgeted check's spp: the relative bias each detects with 95 % probability. |
| `outcomes` | array of outcome | — | One object per check, in run order (below). |
| `seconds` | number or null | s | Total wall time of the run. |
| `machine` | string (absent in files written before 2026-12-07) | — | Where the times were measured: the CPU as the kernel names it (model, x86 family/model/stepping), the logical CPUs the run could use, and the vector extensions this furnace binary was compiled for (the default build leaves out AVX-512 even where the CPU has it). A merged run lists each distinct machine of its shards. |
| `shard` | object (absent unless sharded) | — | Set by `furnace check --shard K/N`: `index` (K), `count` (N) and `suite` (every check name of the whole suite, in run order), which `furnace merge` uses to check that its inputs make one run. A merged run has no `shard` and its `seconds` is the longest shard's. |

### Outcome

| field | type | unit | meaning |
|---|---|---|---|
| `name` | string | — | Unique check name, e.g. `furnace/sphere[albedo=0.9]`. |
| `kind` | string | — | Check kind, e.g. `furnace`. |
| `verdict` | string | — | `"PASS"`, `"FAIL"`, `"UNSTABLE"` (variance did not settle; no pass/fail verdict, counts as a failure), `"ERROR"` (the check could not run) or `"SKIPPED"` (not run). |
| `estimate` | number or null | kind's unit (see `message`) | The measured value. |
| `std_error` | number or null | same as `estimate` | Standard error of `estimate`. |
| `expected` | number or null | same as `estimate` | The expected (reference) value. |
| `statistic` | object | — | The statistic the verdict rests on, tagged by `type` (below). |
| `p_value` | number or null | probability | Two-sided p-value of the test (stochastic checks). |
| `alpha` | number or null | probability | Per-check significance level after the family-wise correction; the check fails when `p_value` < `alpha`. |
| `rel_tolerance` | number or null | fraction of `expected` | Relative tolerance added to the acceptance rule: the stated model tolerance plus, for an image check on a renderer with float32 images, its rounding allowance above f64's; 0 when none. |
| `detection_power` | number or null | fraction of `expected` | Smallest relative bias this check detects with 95 % probability at its sample budget and `alpha` (`estimator_agreement`: relative to the region's radiance, its expected difference being 0; `chi2`: the RMS relative error of the binned density, Cohen's w). |
| `samples` | integer | count | Samples used (paths, BSDF samples or quadrature points). |
| `seconds` | number or null | s | Wall time of the check. |
| `message` | string | — | Human-readable explanation: estimator, what was compared, and the evidence for UNSTABLE or ERROR. |
| `regression` | boolean | — | True when the expected value is furnace's own earlier output (a regression baseline, from the manifest's `regression = true` or a check's own regression band): reported apart, never counted as validation. |
| `bundle` | string (absent unless written) | — | The reproducer bundle of a check that did not pass against an external renderer (`furnace check --report` or `--bundles`): the path of its `README.md`, relative to the HTML report's folder, or under `--bundles` as given. |
| `isolation` | string (absent when none) | — | What the failed check's isolation ladder found ([checks.md](checks.md#isolation)): the first simpler variant that fails with its numbers and relative deviation, and the variants that passed. |

### Statistic

| `type` | further fields | meaning |
|---|---|---|
| `"z"` | `z` (number or null): the z score | Two-sided z test: (`estimate` − `expected`) / `std_error`. |
| `"sequential"` | `z` (number or null): the sequential statistic; `look` (integer): the look that settled the check, from 1; `looks` (integer): looks the design allows | Group-sequential test of a budgeted check (the default of `furnace check`): Z combines the looks' stage-wise p-values and is compared with the design's boundaries; `estimate` and `std_error` are the last look's (or pooled over the looks), so Z is not (`estimate` − `expected`) / `std_error`. |
| `"t"` | `t` (number or null): the t score; `dof` (number or null): its degrees of freedom | Two-sided Student t test, used where a standard error rests on few effective samples: Welch–Satterthwaite degrees of freedom from the samples' fourth moments (region tests between images), or batches − 1 (the re-test of a region whose residuals have structure). |
| `"chi_square"` | `chi2` (number or null): the χ² value; `dof` (integer): degrees of freedom after pooling | Pearson χ² goodness of fit. |
| `"tolerance"` | `max_error` (number or null): largest error found; `abs_tol` (number or null): absolute tolerance; `rel_tol` (number or null): relative tolerance | Deterministic comparison; passes when `max_error` ≤ `abs_tol` + `rel_tol`·\|`expected`\|. |
| `"per_value_tolerance"` | `max_ratio` (number or null): largest error / allowance over the values not excused; `abs_tol`, `rel_tol` (number or null): each value's allowance abs_tol + rel_tol·\|value\|; `excused` (integer): values excused as the model's rounding | Deterministic comparison with an allowance per value (reciprocity); passes when `max_ratio` ≤ 1. |
| `"none"` | — | No statistic (errors, skipped checks). |
"#;

/// The document: the schema name first, then every field of the report.
#[derive(Serialize)]
struct Document<'a> {
    schema: &'static str,
    #[serde(flatten)]
    report: &'a RunReport,
}

/// The run as pretty-printed JSON (two-space indent, no trailing newline), with a
/// top-level `"schema": "furnace.check-results/1"` key followed by every field of
/// [`RunReport`], as documented in [`SCHEMA_DOC`]. NaN and infinities become `null`.
pub fn to_json(r: &RunReport) -> String {
    // serde_json writes non-finite floats as `null` (tested below). Serializing these
    // plain data types cannot otherwise fail, but stay total rather than panic.
    serde_json::to_string_pretty(&Document {
        schema: SCHEMA,
        report: r,
    })
    .unwrap_or_else(|e| {
        let error = serde_json::Value::String(e.to_string());
        format!("{{\n  \"schema\": \"{SCHEMA}\",\n  \"error\": {error}\n}}")
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::harness::outcome::{Outcome, Statistic, Verdict};
    use crate::report::fixture;
    use serde_json::Value;

    #[test]
    fn to_json_fixture() {
        insta::assert_snapshot!("to_json", to_json(&fixture::report()));
    }

    #[test]
    fn schema_key_comes_first() {
        let j = to_json(&fixture::report());
        assert!(
            j.starts_with("{\n  \"schema\": \"furnace.check-results/1\",\n"),
            "{j}"
        );
    }

    #[test]
    fn non_finite_numbers_become_null() {
        let mut r = fixture::report();
        r.family_alpha = f64::NAN;
        r.seconds = f64::INFINITY;
        r.outcomes = vec![Outcome {
            verdict: Verdict::Fail,
            estimate: Some(f64::NAN),
            std_error: Some(f64::INFINITY),
            expected: Some(f64::NEG_INFINITY),
            statistic: Statistic::Tolerance {
                max_error: f64::NAN,
                abs_tol: f64::INFINITY,
                rel_tol: 1e-9,
            },
            rel_tolerance: f64::NAN,
            seconds: f64::NAN,
            ..Outcome::new("nan", "k")
        }];
        let j = to_json(&r);
        let v: Value = serde_json::from_str(&j).expect("valid JSON");
        assert_eq!(v["schema"], SCHEMA);
        assert_eq!(v["family_alpha"], Value::Null);
        assert_eq!(v["seconds"], Value::Null);
        let o = &v["outcomes"][0];
        for key in [
            "estimate",
            "std_error",
            "expected",
            "rel_tolerance",
            "seconds",
        ] {
            assert_eq!(o[key], Value::Null, "{key}");
        }
        assert_eq!(o["statistic"]["max_error"], Value::Null);
        assert_eq!(o["statistic"]["abs_tol"], Value::Null);
        assert_eq!(o["statistic"]["rel_tol"], 1e-9);
        assert!(!j.contains("NaN") && !j.contains("inf"), "{j}");
    }

    #[test]
    fn every_field_is_present_and_documented() {
        let v: Value = serde_json::from_str(&to_json(&fixture::report())).expect("valid JSON");
        let run = v.as_object().expect("object");
        let expected_run_keys = [
            "schema",
            "furnace_version",
            "renderer",
            "manifests",
            "seed",
            "family_alpha",
            "correction",
            "stochastic_tests",
            "outcomes",
            "seconds",
            "machine",
        ];
        assert_eq!(run.len(), expected_run_keys.len());
        let mut keys: Vec<&str> = run.keys().map(String::as_str).collect();
        for o in v["outcomes"].as_array().expect("array") {
            keys.extend(o.as_object().expect("object").keys().map(String::as_str));
            keys.extend(
                o["statistic"]
                    .as_object()
                    .expect("object")
                    .keys()
                    .map(String::as_str),
            );
            let tag = o["statistic"]["type"].as_str().expect("tag");
            assert!(
                SCHEMA_DOC.contains(&format!("`\"{tag}\"`")),
                "type {tag} undocumented"
            );
            let verdict = o["verdict"].as_str().expect("verdict");
            assert!(
                SCHEMA_DOC.contains(&format!("`\"{verdict}\"`")),
                "{verdict} undocumented"
            );
        }
        for key in expected_run_keys.iter().copied().chain(keys) {
            assert!(
                SCHEMA_DOC.contains(&format!("`{key}`")),
                "field {key} undocumented"
            );
        }
    }

    #[test]
    fn strings_round_trip() {
        let mut r = fixture::report();
        r.outcomes = vec![Outcome::new("ü🦀 \"q\" \\ <&> \u{0}\u{1f}\n", "k")];
        let v: Value = serde_json::from_str(&to_json(&r)).expect("valid JSON");
        assert_eq!(v["outcomes"][0]["name"], "ü🦀 \"q\" \\ <&> \u{0}\u{1f}\n");
    }
}
