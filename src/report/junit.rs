//! JUnit XML for CI test reporters (Jenkins, GitLab, GitHub actions that read
//! `junit.xml`): one `<testsuite name="furnace">` with one `<testcase>` per check, written by
//! `quick-junit` (the crate cargo-nextest writes its JUnit with), which escapes markup and
//! drops what XML 1.0 cannot carry (control characters, ANSI escapes).
//!
//! Mapping: FAIL → `<failure type="fail">`, UNSTABLE → `<failure type="unstable">`
//! (so both count in `failures`), ERROR → `<error type="error">`, SKIP → `<skipped/>`.
//! Every test case carries its text line in `<system-out>`. Attribute values are one line:
//! tabs and line breaks in names and messages become spaces (XML would turn raw ones into
//! spaces when read anyway).

use std::time::Duration;

use quick_junit::{NonSuccessKind, Property, Report, TestCase, TestCaseStatus, TestSuite};

use crate::harness::outcome::{Outcome, RunReport, Verdict};
use crate::report::text;

/// The run as a JUnit XML document (UTF-8, ending with a newline).
///
/// `<testsuites>` and its one `<testsuite>` carry `tests`, `failures` (FAIL and
/// UNSTABLE), `errors`, `skipped` and `time` (seconds, 3 decimals); the suite also lists
/// the run settings as `<properties>`. Each `<testcase>` has the check name, the class
/// name `furnace.<kind>` (`furnace.regression.<kind>` for a regression baseline) and its time.
pub fn to_junit(r: &RunReport) -> Result<String, quick_junit::SerializeError> {
    let mut suite = TestSuite::new("furnace");
    suite.set_time(duration(r.seconds));
    let mut property = |name: &str, value: &str| {
        suite.add_property(Property::new(name, one_line(value)));
    };
    property("furnace_version", &r.furnace_version);
    for manifest in &r.manifests {
        property("manifest", manifest);
    }
    property("seed", &r.seed.to_string());
    property("family_alpha", &text::sig(r.family_alpha, 6, true));
    property("correction", &r.correction);
    property("stochastic_tests", &r.stochastic_tests.to_string());
    if !r.machine.is_empty() {
        property("machine", &r.machine);
    }
    suite.add_test_cases(r.outcomes.iter().map(testcase));
    let mut report = Report::new("furnace");
    report.set_time(duration(r.seconds));
    report.add_test_suite(suite);
    report.to_string()
}

/// One `<testcase>` element.
fn testcase(o: &Outcome) -> TestCase {
    let kind = o.kind.trim();
    // Regression baselines get a class of their own, so CI views list them apart.
    let root = if o.regression {
        "furnace.regression"
    } else {
        "furnace"
    };
    let classname = if kind.is_empty() {
        root.to_string()
    } else {
        format!("{root}.{kind}")
    };
    let line = xml_chars(&text::line(o));
    let numbers = text::numbers(o);
    let numbers = if numbers.is_empty() {
        text::verdict_label(o.verdict).to_string()
    } else {
        numbers
    };
    let message = text::one_line(o.message.trim());
    let status = match o.verdict {
        Verdict::Pass => TestCaseStatus::success(),
        Verdict::Fail | Verdict::Unstable => {
            let mut s = TestCaseStatus::non_success(NonSuccessKind::Failure);
            s.set_message(one_line(&numbers))
                .set_type(if o.verdict == Verdict::Fail {
                    "fail"
                } else {
                    "unstable"
                })
                .set_description(line.as_str());
            s
        }
        Verdict::Error => {
            let summary = if message.is_empty() { numbers } else { message };
            let mut s = TestCaseStatus::non_success(NonSuccessKind::Error);
            s.set_message(one_line(&summary))
                .set_type("error")
                .set_description(line.as_str());
            s
        }
        Verdict::Skipped => {
            let mut s = TestCaseStatus::skipped();
            if !message.is_empty() {
                s.set_message(one_line(&message));
            }
            s
        }
    };
    let name = if o.name.trim().is_empty() {
        "(unnamed)"
    } else {
        &o.name
    };
    let mut case = TestCase::new(one_line(name), status);
    case.set_classname(one_line(&classname))
        .set_time(duration(o.seconds))
        .set_system_out(line.as_str());
    case
}

/// An attribute value on one line (tabs and line breaks become spaces, other control
/// characters visible escapes), without what XML 1.0 cannot carry.
fn one_line(s: &str) -> String {
    xml_chars(&text::one_line(s))
}

/// `s` without the characters XML 1.0 does not allow (quick-junit drops control characters
/// but passes the non-characters U+FFFE and U+FFFF, which XML parsers reject).
fn xml_chars(s: &str) -> String {
    s.chars().filter(|&c| is_xml10_char(c)).collect()
}

/// XML 1.0 `Char` production (surrogates cannot occur in a Rust `char`).
fn is_xml10_char(c: char) -> bool {
    matches!(c,
        '\u{9}' | '\u{A}' | '\u{D}'
        | '\u{20}'..='\u{D7FF}'
        | '\u{E000}'..='\u{FFFD}'
        | '\u{10000}'..='\u{10FFFF}')
}

/// A check's time; zero for negative or non-finite times, which CI reporters would reject.
fn duration(s: f64) -> Duration {
    Duration::try_from_secs_f64(s).unwrap_or(Duration::ZERO)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::harness::outcome::Statistic;
    use crate::report::fixture;
    use quick_xml::escape::resolve_predefined_entity;
    use quick_xml::events::{BytesStart, Event};
    use quick_xml::{Reader, XmlVersion};
    use std::collections::BTreeMap;

    #[test]
    fn to_junit_fixture() {
        insta::assert_snapshot!("to_junit", to_junit(&fixture::report()).unwrap());
    }

    /// One `<testcase>` as parsed back.
    #[derive(Debug, Default)]
    struct Case {
        attrs: BTreeMap<String, String>,
        /// Child element names (`failure`, `error`, `skipped`, `system-out`).
        children: Vec<String>,
        /// Attributes of the `failure`/`error`/`skipped` child.
        result_attrs: BTreeMap<String, String>,
        /// Text of the `failure`/`error` child.
        result_text: String,
        system_out: String,
    }

    /// What the parser found.
    #[derive(Debug, Default)]
    struct Parsed {
        root: String,
        root_attrs: BTreeMap<String, String>,
        suites: Vec<BTreeMap<String, String>>,
        cases: Vec<Case>,
    }

    fn attributes(e: &BytesStart<'_>) -> BTreeMap<String, String> {
        e.attributes()
            .map(|a| {
                let a = a.expect("well-formed attribute");
                let key = a.key.as_ref().to_string();
                let value = a
                    .normalized_value(XmlVersion::Explicit1_0)
                    .expect("valid escapes");
                (key, value.into_owned())
            })
            .collect()
    }

    /// Parses every event with quick-xml (which checks tag nesting and end names) and
    /// collects the JUnit structure.
    fn parse(xml: &str) -> Parsed {
        assert!(xml.starts_with("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"));
        // quick-xml does not check the XML 1.0 Char production; check it here.
        assert!(
            xml.chars().all(is_xml10_char),
            "illegal XML character in {xml:?}"
        );
        let mut reader = Reader::from_str(xml);
        let mut parsed = Parsed::default();
        let mut path: Vec<String> = Vec::new();
        let mut saw_decl = false;
        loop {
            let event = reader.read_event().unwrap_or_else(|e| {
                panic!(
                    "not well-formed at {}: {e}\n{xml}",
                    reader.buffer_position()
                )
            });
            let (name, attrs, empty) = match &event {
                Event::Eof => break,
                Event::Decl(_) => {
                    assert!(path.is_empty() && !saw_decl);
                    saw_decl = true;
                    continue;
                }
                Event::Start(e) | Event::Empty(e) => (
                    e.name().as_ref().to_string(),
                    attributes(e),
                    matches!(event, Event::Empty(_)),
                ),
                Event::End(_) => {
                    path.pop();
                    continue;
                }
                Event::Text(t) => {
                    let t = t.xml10_content();
                    text_into(&mut parsed, &path, &t);
                    continue;
                }
                Event::GeneralRef(r) => {
                    let resolved = match r.resolve_char_ref().expect("valid char ref") {
                        Some(c) => c.to_string(),
                        None => resolve_predefined_entity(&r.xml10_content())
                            .expect("predefined entity")
                            .to_string(),
                    };
                    text_into(&mut parsed, &path, &resolved);
                    continue;
                }
                other => panic!("unexpected event {other:?}"),
            };
            match (path.len(), name.as_str()) {
                (0, _) => {
                    assert!(parsed.root.is_empty(), "second root element {name}");
                    parsed.root = name.clone();
                    parsed.root_attrs = attrs;
                }
                (1, "testsuite") => parsed.suites.push(attrs),
                (2, "properties") | (3, "property") => {}
                (2, "testcase") => parsed.cases.push(Case {
                    attrs,
                    ..Case::default()
                }),
                (3, child) => {
                    let case = parsed.cases.last_mut().expect("inside a testcase");
                    assert_eq!(path.last().map(String::as_str), Some("testcase"));
                    if child != "system-out" {
                        case.result_attrs = attrs;
                    }
                    case.children.push(child.to_string());
                }
                (depth, _) => panic!("unexpected <{name}> at depth {depth} under {path:?}"),
            }
            if !empty {
                path.push(name);
            }
        }
        assert!(saw_decl && path.is_empty());
        parsed
    }

    fn text_into(parsed: &mut Parsed, path: &[String], text: &str) {
        match path.last().map(String::as_str) {
            Some("failure") | Some("error") => parsed
                .cases
                .last_mut()
                .expect("case")
                .result_text
                .push_str(text),
            Some("system-out") => parsed
                .cases
                .last_mut()
                .expect("case")
                .system_out
                .push_str(text),
            _ => assert!(text.trim().is_empty(), "stray text {text:?} under {path:?}"),
        }
    }

    fn count(cases: &[Case], child: &str) -> usize {
        cases
            .iter()
            .filter(|c| c.children.iter().any(|n| n == child))
            .count()
    }

    #[test]
    fn structure_and_counts() {
        let r = fixture::report();
        let p = parse(&to_junit(&r).unwrap());
        assert_eq!(p.root, "testsuites");
        assert_eq!(p.suites.len(), 1);
        assert_eq!(p.suites[0]["name"], "furnace");
        assert_eq!(p.cases.len(), r.outcomes.len());

        let failures = count(&p.cases, "failure");
        let errors = count(&p.cases, "error");
        let skipped = count(&p.cases, "skipped");
        assert_eq!((failures, errors, skipped), (2, 1, 1));
        for attrs in [&p.root_attrs, &p.suites[0]] {
            assert_eq!(attrs["tests"], p.cases.len().to_string());
            assert_eq!(attrs["failures"], failures.to_string());
            assert_eq!(attrs["errors"], errors.to_string());
            assert_eq!(attrs["skipped"], skipped.to_string());
            assert_eq!(attrs["time"], "5.201");
        }

        for (case, o) in p.cases.iter().zip(&r.outcomes) {
            assert_eq!(case.attrs["classname"], format!("furnace.{}", o.kind));
            assert_eq!(case.system_out, text::line(o));
            let time = &case.attrs["time"];
            assert!(
                time.split_once('.').is_some_and(|(_, d)| d.len() == 3),
                "{time}"
            );
            match o.verdict {
                Verdict::Pass => assert_eq!(case.children, ["system-out"]),
                Verdict::Fail | Verdict::Unstable => {
                    assert_eq!(case.children, ["failure", "system-out"]);
                    assert_eq!(case.result_text, text::line(o));
                    assert_eq!(case.result_attrs["message"], text::numbers(o));
                    let kind = if o.verdict == Verdict::Fail {
                        "fail"
                    } else {
                        "unstable"
                    };
                    assert_eq!(case.result_attrs["type"], kind);
                }
                Verdict::Error => {
                    assert_eq!(case.children, ["error", "system-out"]);
                    assert_eq!(case.result_attrs["message"], o.message);
                }
                Verdict::Skipped => assert_eq!(case.children, ["skipped", "system-out"]),
            }
        }
    }

    #[test]
    fn special_characters_round_trip_escaped() {
        let mut r = fixture::report();
        let name = "odd <&>\"' name\u{1}\u{1b}\ttab\nnewline\u{FFFE}ü🦀";
        r.outcomes.push(Outcome {
            verdict: Verdict::Fail,
            statistic: Statistic::Z { z: 9.0 },
            message: "<b>&amp;</b> \u{0}".into(),
            ..Outcome::new(name, "k<&>\"'\u{2}")
        });
        let xml = to_junit(&r).unwrap();
        assert!(xml.contains("odd &lt;&amp;&gt;&quot;&apos; name"), "{xml}");
        let p = parse(&xml);
        let case = p.cases.last().expect("case");
        // The name comes back as written on one line: control characters as visible
        // escapes, tab and newline as spaces, and what XML 1.0 cannot carry dropped.
        assert_eq!(
            case.attrs["name"],
            "odd <&>\"' name\\u{1}\\u{1b} tab newlineü🦀"
        );
        assert_eq!(case.attrs["classname"], "furnace.k<&>\"'\\u{2}");
        // The text line shows the control characters as visible escapes instead.
        assert!(
            case.system_out.contains("name\\u{1}\\u{1b} tab newline"),
            "{}",
            case.system_out
        );
        assert_eq!(p.root_attrs["failures"], "3");
    }

    #[test]
    fn hostile_inputs_never_panic_and_stay_valid() {
        let numbers = [
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            0.0,
            -0.0,
            5e-324,
            f64::MIN_POSITIVE,
            1e-300,
            -1e300,
            f64::MAX,
            f64::MIN,
            999_999.5,
            0.000_999_95,
        ];
        let names = [
            "",
            " ",
            "\u{0}",
            "`|`*_<x>",
            "ü🦀",
            "\u{fffe}\u{ffff}\u{10ffff}",
            "\r\n\t",
            "]]>",
        ];
        let verdicts = [
            Verdict::Pass,
            Verdict::Fail,
            Verdict::Unstable,
            Verdict::Error,
            Verdict::Skipped,
        ];
        let mut outcomes = Vec::new();
        for (i, &x) in numbers.iter().enumerate() {
            let y = numbers[(i + 5) % numbers.len()];
            let statistics = [
                Statistic::Z { z: x },
                Statistic::Sequential {
                    z: x,
                    look: 1,
                    looks: 3,
                },
                Statistic::T { t: x, dof: y },
                Statistic::PerValueTolerance {
                    max_ratio: x,
                    abs_tol: y,
                    rel_tol: x,
                    excused: 3,
                },
                Statistic::ChiSquare {
                    chi2: x,
                    dof: u64::MAX,
                },
                Statistic::Tolerance {
                    max_error: x,
                    abs_tol: y,
                    rel_tol: x,
                },
                Statistic::Tolerance {
                    max_error: y,
                    abs_tol: 0.0,
                    rel_tol: x,
                },
                Statistic::None,
            ];
            for (j, statistic) in statistics.into_iter().enumerate() {
                outcomes.push(Outcome {
                    verdict: verdicts[(i + j) % verdicts.len()],
                    estimate: Some(x),
                    std_error: if j % 2 == 0 { Some(y) } else { None },
                    expected: if j % 3 == 0 { None } else { Some(y) },
                    statistic,
                    p_value: Some(y),
                    alpha: Some(x),
                    rel_tolerance: x,
                    detection_power: Some(y),
                    samples: u64::MAX,
                    seconds: x,
                    message: names[(i + j) % names.len()].to_string(),
                    ..Outcome::new(names[i % names.len()], names[j % names.len()])
                });
            }
        }
        let r = RunReport {
            renderer: "furnace 0.1.0".into(),
            furnace_version: "\u{0}".into(),
            manifests: names.iter().map(|n| n.to_string()).collect(),
            seed: u64::MAX,
            family_alpha: f64::NAN,
            correction: "\u{1b}[2J".into(),
            stochastic_tests: usize::MAX,
            looks: String::new(),
            power: None,
            outcomes,
            seconds: f64::NEG_INFINITY,
            machine: "\u{7}<cpu>".into(),
            shard: None,
        };
        let p = parse(&to_junit(&r).unwrap());
        assert_eq!(p.cases.len(), r.outcomes.len());
        for o in &r.outcomes {
            let l = text::line(o);
            assert!(!l.contains('\n'), "{l:?}");
        }
        let s = text::summary(&r);
        assert!(
            s.lines().last().is_some_and(|l| l.ends_with("skipped")),
            "{s}"
        );
        let t = text::table_markdown(&r);
        assert_eq!(t.lines().count(), r.outcomes.len() + 2);
        let j: serde_json::Value =
            serde_json::from_str(&crate::report::json::to_json(&r)).expect("valid JSON");
        assert_eq!(
            j["outcomes"].as_array().map(Vec::len),
            Some(r.outcomes.len())
        );
    }

    #[test]
    fn times_are_durations_and_bad_ones_zero() {
        assert_eq!(duration(0.4137), Duration::from_secs_f64(0.4137));
        for bad in [f64::NAN, -1.0, f64::INFINITY, f64::NEG_INFINITY] {
            assert_eq!(duration(bad), Duration::ZERO, "{bad}");
        }
        let mut r = fixture::report();
        r.outcomes[0].seconds = 0.4137;
        r.outcomes[1].seconds = f64::NAN;
        let p = parse(&to_junit(&r).unwrap());
        assert_eq!(p.cases[0].attrs["time"], "0.414");
        assert_eq!(p.cases[1].attrs["time"], "0.000");
    }
}
