//! The module graph is one-directional (DESIGN.md): a module may use `crate::X` only for X
//! in a lower layer; modules of the same layer do not use each other.

use crate::root;
use std::path::Path;

const LAYERS: [&[&str]; 10] = [
    &["math"],
    &["stats"],
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
        ("exr", &["film/io.rs"]),
        ("png", &["film/io.rs"]),
        ("statrs", &["stats/"]),
        ("indicatif", &["cli.rs"]),
        ("clap", &["cli.rs", "main.rs"]),
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
