//! The module graph is one-directional (DESIGN.md): a module may use `crate::X` only for X
//! in a lower layer; modules of the same layer do not use each other.

use crate::root;
use std::path::Path;

const LAYERS: [&[&str]; 11] = [
    &["math", "limits"],
    &["stats"],
    &["io"],
    &["spectrum"],
    &["geometry"],
    &["scattering", "media", "lights", "camera", "film"],
    &["scene"],
    &["integrators", "export"],
    &["render"],
    &["harness"],
    &["report"],
];

fn layer(module: &str) -> Option<usize> {
    LAYERS.iter().position(|l| l.contains(&module))
}

fn visit(dir: &Path, out: &mut Vec<std::path::PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            visit(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

#[test]
fn no_module_uses_a_module_above_or_beside_it() {
    let src = root("src");
    let mut files = Vec::new();
    visit(&src, &mut files);
    let mut violations = Vec::new();
    for f in files {
        let rel = f.strip_prefix(&src).unwrap();
        let own = rel
            .iter()
            .next()
            .unwrap()
            .to_string_lossy()
            .trim_end_matches(".rs")
            .to_string();
        let Some(own_layer) = layer(&own) else {
            continue;
        }; // lib.rs, main.rs, cli.rs: top
        let text = std::fs::read_to_string(&f).unwrap();
        for (i, line) in text.lines().enumerate() {
            let mut rest = line;
            while let Some(k) = rest.find("crate::") {
                rest = &rest[k + 7..];
                let used: String = rest
                    .chars()
                    .take_while(|c| c.is_alphanumeric() || *c == '_')
                    .collect();
                if used == own {
                    continue;
                }
                match layer(&used) {
                    Some(l) if l < own_layer => {}
                    _ => violations.push(format!(
                        "{}:{}: {own} uses crate::{used}",
                        rel.display(),
                        i + 1
                    )),
                }
            }
        }
    }
    assert!(
        violations.is_empty(),
        "forbidden module edges:\n{}",
        violations.join("\n")
    );
}

/// Each third-party crate has one home (DESIGN.md).
#[test]
fn third_party_crates_stay_in_their_homes() {
    let homes: [(&str, &[&str]); 8] = [
        ("obvhs", &["geometry/accel.rs"]),
        ("plotters", &["report/plot.rs"]),
        ("sobol_burley", &["math/rng.rs"]),
        ("exr", &["io/image.rs"]),
        ("png", &["io/image.rs"]),
        ("statrs", &["stats/"]),
        ("indicatif", &["cli/"]),
        ("clap", &["cli/", "main.rs"]),
    ];
    let src = root("src");
    let mut files = Vec::new();
    visit(&src, &mut files);
    let mut violations = Vec::new();
    for f in files {
        let rel = f
            .strip_prefix(&src)
            .unwrap()
            .to_string_lossy()
            .replace('\\', "/");
        let text = std::fs::read_to_string(&f).unwrap();
        for (krate, allowed) in homes {
            let used = text.lines().any(|l| {
                let l = l.trim_start();
                !l.starts_with("//")
                    && (l.contains(&format!("use {krate}::"))
                        || l.contains(&format!(" {krate}::"))
                        || l.contains(&format!("({krate}::")))
            });
            if used && !allowed.iter().any(|a| rel.starts_with(a)) {
                violations.push(format!("{rel} uses {krate}"));
            }
        }
    }
    assert!(
        violations.is_empty(),
        "crates outside their home:\n{}",
        violations.join("\n")
    );
}

/// Rooms of `src/harness/`, lowest first (its module head lists them): a room may use only
/// rooms of a lower layer, so the harness has no import circle; check kinds (`checks/`) do not
/// use each other.
const HARNESS_LAYERS: [&[&str]; 13] = [
    &["names", "outcome", "error", "machine"],
    &["measurement", "shard"],
    &["renderer"],
    &["under_test", "shared"],
    &["context", "keys"],
    &["kind"],
    &[
        "model",
        "closed_form",
        "region",
        "compare",
        "adapter",
        "ladder",
    ],
    &["looks"],
    &["checks"],
    &["registry"],
    &["manifest"],
    &["isolation", "budget"],
    &["runner"],
];

#[test]
fn harness_rooms_use_only_rooms_below_them() {
    let dir = root("src/harness");
    let mut files = Vec::new();
    visit(&dir, &mut files);
    let layer = |room: &str| HARNESS_LAYERS.iter().position(|l| l.contains(&room));
    // harness/mod.rs re-exports: `pub use room::{A, B};` makes crate::harness::A mean room::A
    let mut reexport = std::collections::BTreeMap::new();
    for line in std::fs::read_to_string(dir.join("mod.rs")).unwrap().lines() {
        if let Some(rest) = line.strip_prefix("pub use ") {
            let (room, names) = rest.split_once("::").unwrap();
            for n in names
                .trim_end_matches(';')
                .trim_matches(|c| c == '{' || c == '}')
                .split(',')
            {
                reexport.insert(n.trim().to_string(), room.to_string());
            }
        }
    }
    let mut violations = Vec::new();
    for f in files {
        let rel = f.strip_prefix(&dir).unwrap();
        let parts: Vec<String> = rel
            .iter()
            .map(|p| p.to_string_lossy().trim_end_matches(".rs").to_string())
            .collect();
        let own = parts[0].clone();
        if own == "mod" {
            continue; // harness/mod.rs: the module list and re-exports
        }
        let Some(own_layer) = layer(&own) else {
            violations.push(format!(
                "{}: room {own} is not in HARNESS_LAYERS",
                rel.display()
            ));
            continue;
        };
        // the file's own kind, for checks/: kinds may not use each other
        let own_kind = (own == "checks").then(|| parts.get(1).cloned()).flatten();
        let text = std::fs::read_to_string(&f).unwrap();
        for (i, line) in text.lines().enumerate() {
            if line.trim_start().starts_with("//") {
                continue;
            }
            let mut used: Vec<(String, Option<String>)> = Vec::new();
            for prefix in ["crate::harness::", "super::"] {
                let mut rest = line;
                while let Some(k) = rest.find(prefix) {
                    rest = &rest[k + prefix.len()..];
                    let path: Vec<String> = rest
                        .split("::")
                        .take(2)
                        .map(|s| {
                            s.chars()
                                .take_while(|c| c.is_alphanumeric() || *c == '_')
                                .collect()
                        })
                        .collect();
                    // `super::` from a nested file refers to its own folder
                    if prefix == "super::" && parts.len() > 1 {
                        used.push((own.clone(), path.first().cloned()));
                    } else if prefix == "super::" && layer(&path[0]).is_none() {
                        // an inline module's `super::item`: the room's own item
                        continue;
                    } else if rest.starts_with('{') || path[0].starts_with(char::is_uppercase) {
                        // re-exported names: `crate::harness::{Check, Context}` or `::Check`
                        let list = rest.trim_start_matches('{');
                        let list = &list[..list.find(['}', ';']).unwrap_or(list.len())];
                        for n in list.split(',') {
                            let n = n.split_whitespace().next().unwrap_or("");
                            if n.starts_with(char::is_uppercase) || reexport.contains_key(n) {
                                match reexport.get(n) {
                                    Some(room) => used.push((room.clone(), None)),
                                    None => violations.push(format!(
                                        "{}:{}: {n} is not re-exported by harness/mod.rs",
                                        rel.display(),
                                        i + 1
                                    )),
                                }
                            } else if !n.is_empty() {
                                used.push((n.split("::").next().unwrap_or("").to_string(), None));
                            }
                        }
                    } else {
                        used.push((path[0].clone(), path.get(1).cloned()));
                    }
                }
            }
            for (room, sub) in used {
                if room.is_empty() || room == "{" {
                    continue;
                }
                if room == own {
                    if own == "checks" {
                        if let (Some(k), Some(s)) = (&own_kind, &sub) {
                            if k != s && !s.is_empty() && s != "mod" {
                                violations.push(format!(
                                    "{}:{}: kind {k} uses kind {s}",
                                    rel.display(),
                                    i + 1
                                ));
                            }
                        }
                    }
                    continue;
                }
                match layer(&room) {
                    Some(l) if l < own_layer => {}
                    Some(_) => violations.push(format!(
                        "{}:{}: {own} uses {room} (same or higher layer)",
                        rel.display(),
                        i + 1
                    )),
                    None => violations.push(format!(
                        "{}:{}: {own} uses {room}, which is not a harness room",
                        rel.display(),
                        i + 1
                    )),
                }
            }
        }
    }
    assert!(
        violations.is_empty(),
        "forbidden harness edges:\n{}",
        violations.join("\n")
    );
}

#[test]
fn the_design_page_draws_the_harness_layers_as_enforced() {
    // docs/design.md's diagram of the harness's rooms ("a < b < {c, d}") must list the rooms
    // of HARNESS_LAYERS, layer by layer, so that a newcomer reads the order this file checks.
    let design = std::fs::read_to_string(root("docs/design.md")).unwrap();
    let start = design
        .find("{names, outcome, error, machine}")
        .expect("docs/design.md draws the harness's layers");
    let end = start + design[start..].find("```").unwrap();
    let drawn: Vec<Vec<String>> = design[start..end]
        .split('<')
        .map(|layer| {
            let mut rooms: Vec<String> = layer
                .trim()
                .trim_matches(|c| c == '{' || c == '}')
                .split(',')
                .map(|r| r.trim().trim_end_matches('/').to_string())
                .collect();
            rooms.sort();
            rooms
        })
        .collect();
    let enforced: Vec<Vec<String>> = HARNESS_LAYERS
        .iter()
        .map(|layer| {
            let mut rooms: Vec<String> = layer.iter().map(|r| r.to_string()).collect();
            rooms.sort();
            rooms
        })
        .collect();
    assert_eq!(drawn, enforced, "docs/design.md's harness diagram");
}
