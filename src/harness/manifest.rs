//! Test manifests: TOML files with one `[[check]]` table per check. Each check names its kind;
//! the kind reads its own keys (`kind.rs`, `checks/`), and any other key is an error. Every
//! error names the manifest file, line, column and key. Paths (scenes, templates, reference
//! files) are relative to the manifest's folder.

use super::keys::{common, Keys, Table};
use super::kind::{Check, RenderOverrides};
use super::registry;
use crate::io::{LocatedError, Source};
use crate::scene::{desc::SceneDesc, Scene};
use serde::Deserialize;
use std::collections::BTreeMap;
use std::ops::Range;
use std::path::{Path, PathBuf};
use toml::{Spanned, Value};

/// An invalid manifest (or a scene or file it names): exit code 2.
pub type ManifestError = LocatedError;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ManifestDesc {
    #[serde(default)]
    check: Vec<Spanned<Table>>,
}

/// A manifest read again, once, for its checks' inline `[check.scene]` tables, deserialized
/// from the manifest's own text so that the scenes' errors name the manifest's lines.
#[derive(Deserialize)]
struct InlineScenes {
    #[serde(default)]
    check: Vec<InlineScene>,
}

/// A check table seen only for its `scene` (its other keys are read elsewhere).
#[derive(Deserialize)]
struct InlineScene {
    #[serde(default)]
    scene: Option<SceneOrPath>,
}

/// A check's `scene` value: an inline table's description, or None for a path.
struct SceneOrPath(Option<SceneDesc>);

impl<'de> Deserialize<'de> for SceneOrPath {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Either;
        impl<'de> serde::de::Visitor<'de> for Either {
            type Value = SceneOrPath;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a scene path or an inline scene table")
            }
            fn visit_str<E: serde::de::Error>(self, _: &str) -> Result<SceneOrPath, E> {
                Ok(SceneOrPath(None))
            }
            fn visit_map<A: serde::de::MapAccess<'de>>(
                self,
                m: A,
            ) -> Result<SceneOrPath, A::Error> {
                SceneDesc::deserialize(serde::de::value::MapAccessDeserializer::new(m))
                    .map(|d| SceneOrPath(Some(d)))
            }
        }
        d.deserialize_any(Either)
    }
}

/// The inline scene tables of every check (None: a path or no scene), deserialized once from
/// the manifest's own text so that their errors name its lines, the key prefixed with the
/// check's (`check[1].scene.camera`). Empty when no check has one.
fn inline_scenes(
    src: &Source,
    checks: &[Spanned<Table>],
) -> Result<Vec<Option<SceneDesc>>, ManifestError> {
    let inline = |c: &Spanned<Table>| {
        matches!(
            c.get_ref().get("scene").map(|v| v.get_ref()),
            Some(Value::Table(_))
        )
    };
    if !checks.iter().any(inline) {
        return Ok(Vec::new());
    }
    let all: InlineScenes = crate::io::parse_toml(src).map_err(|mut e| {
        // the check whose table holds the error: the last one starting on or before its line
        if let Some(i) = checks
            .iter()
            .rposition(|c| src.line_column(c.span().start).0 <= e.line)
        {
            e.key = scene_key(i, &e.key);
        }
        e
    })?;
    Ok(all
        .check
        .into_iter()
        .map(|c| c.scene.and_then(|s| s.0))
        .collect())
}

/// The key of `key` inside check `index`'s inline scene.
fn scene_key(index: usize, key: &str) -> String {
    if key.is_empty() {
        format!("check[{index}].scene")
    } else {
        format!("check[{index}].scene.{key}")
    }
}

/// Reads a manifest and expands it into runnable checks, validating every scene.
pub fn load(path: &Path) -> Result<Vec<Check>, ManifestError> {
    let text = crate::io::read_text(path, "the manifest")?;
    parse(&text, path)
}

/// Parses manifest text (`path` names it in errors and anchors relative paths).
pub fn parse(text: &str, path: &Path) -> Result<Vec<Check>, ManifestError> {
    let src = Source { path, text };
    let desc: ManifestDesc = crate::io::parse_toml(&src)?;
    let mut inline = inline_scenes(&src, &desc.check)?;
    let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let mut out: Vec<Check> = Vec::new();
    let mut seen = std::collections::BTreeSet::new();
    // every expanded check holds its own scene: bound their primitives together
    let mut primitives: u64 = 0;
    for (i, c) in desc.check.iter().enumerate() {
        let scene = inline.get_mut(i).and_then(Option::take);
        let expanded = expand_check(&src, &base, i, c, scene)?;
        if out.len() + expanded.len() > crate::limits::MAX_CHECKS {
            return Err(src.error(
                c.span(),
                format!("check[{i}]"),
                format!(
                    "the manifest expands into more than {} checks",
                    crate::limits::MAX_CHECKS
                ),
            ));
        }
        for check in &expanded {
            primitives += check.scene.as_ref().map_or(0, |s| {
                s.aggregate
                    .shapes()
                    .iter()
                    .map(|sh| sh.primitive_count() as u64)
                    .sum()
            });
        }
        if primitives > crate::limits::MAX_TRIANGLES {
            return Err(src.error(
                c.span(),
                format!("check[{i}]"),
                format!(
                    "the manifest's scenes hold more than {} primitives in all (each expanded check keeps its own scene)",
                    crate::limits::MAX_TRIANGLES
                ),
            ));
        }
        for check in expanded {
            if !seen.insert(check.name.clone()) {
                let span = c
                    .get_ref()
                    .get("name")
                    .map(|n| n.span())
                    .unwrap_or(c.span());
                return Err(src.error(
                    span,
                    format!("check[{i}].name"),
                    format!(
                        "duplicate check name {:?}; names must be unique",
                        check.name
                    ),
                ));
            }
            out.push(check);
        }
    }
    Ok(out)
}

/// The keys every scene-level kind shares: image size, spp, depth, roulette and region.
fn render_overrides(k: &Keys) -> Result<RenderOverrides, ManifestError> {
    let region = match k.get::<[i64; 4]>("region")? {
        None => None,
        Some(r) => {
            let [x0, y0, x1, y1] = *r.get_ref();
            if x0 < 0 || y0 < 0 || x1 <= x0 || y1 <= y0 {
                return Err(k.error(r.span(), "region", format!("[{x0}, {y0}, {x1}, {y1}] must be [x0, y0, x1, y1] with 0 <= x0 < x1 and 0 <= y0 < y1 (pixels, end exclusive)")));
            }
            Some([x0 as usize, y0 as usize, x1 as usize, y1 as usize])
        }
    };
    let render = RenderOverrides {
        // spp ≥ 2: one sample per pixel gives no variance estimate, so no test is possible.
        spp: k.int("spp", 2, 1 << 32)?,
        width: k.int("width", 1, 4096)?,
        height: k.int("height", 1, 4096)?,
        max_depth: k.int("max_depth", 0, 1 << 20)?,
        roulette: k.get::<bool>("roulette")?.is_none_or(|r| *r.get_ref()),
        region,
    };
    if !render.roulette && render.max_depth.is_none() {
        return Err(k.error_at(
            "roulette",
            "roulette = false needs max_depth: paths in a closed scene would never end".into(),
        ));
    }
    Ok(render)
}

/// One `[[check]]` table, expanded over its `vary` combinations.
fn expand_check(
    src: &Source,
    base: &Path,
    index: usize,
    c: &Spanned<Table>,
    mut inline: Option<SceneDesc>,
) -> Result<Vec<Check>, ManifestError> {
    let table = c.get_ref();
    let at = format!("check[{index}]");
    let err =
        |span: Range<usize>, key: &str, msg: String| src.error(span, format!("{at}.{key}"), msg);
    let string = |key: &str| -> Result<Option<Spanned<String>>, ManifestError> {
        match table.get(key) {
            None => Ok(None),
            Some(v) => match v.get_ref() {
                Value::String(s) => Ok(Some(Spanned::new(v.span(), s.clone()))),
                other => Err(err(
                    v.span(),
                    key,
                    format!("invalid type: {}, expected a string", other.type_str()),
                )),
            },
        }
    };
    let name = string("name")?.ok_or_else(|| {
        err(
            c.span(),
            "name",
            "missing; every check needs a unique name".into(),
        )
    })?;
    let names = registry::names().join(", ");
    let kind_name = string("kind")?
        .ok_or_else(|| err(c.span(), "kind", format!("missing; allowed kinds: {names}")))?;
    let kind = registry::find(kind_name.get_ref()).ok_or_else(|| {
        err(
            kind_name.span(),
            "kind",
            format!(
                "unknown check kind {:?}{}; allowed: {names}",
                kind_name.get_ref(),
                super::names::did_you_mean(kind_name.get_ref(), registry::names())
            ),
        )
    })?;
    let mut keys = Keys::new(
        src,
        table,
        at.clone(),
        c.span(),
        kind.name(),
        kind.keys(),
        base.to_path_buf(),
    )?;
    let scene_level = kind.keys().contains(&common::SCENE);
    if scene_level && !keys.has("scene") {
        return Err(err(c.span(), "scene", format!("kind {:?} needs a scene: a path relative to the manifest, or an inline [check.scene] table", kind.name())));
    }
    let render = render_overrides(&keys)?;
    let rel_tolerance = keys.non_negative("rel_tolerance")?.unwrap_or(0.0);
    if rel_tolerance >= 0.1 {
        return Err(keys.error_at("rel_tolerance", format!("{rel_tolerance:?} is too large: a model tolerance of 10 % or more lets real bugs pass; allowed [0, 0.1)")));
    }
    let seed = keys.int("seed", 0, i64::MAX)?;
    let time_limit = match keys.get::<f64>("time_limit")? {
        None => None,
        Some(t) if t.get_ref().is_finite() && *t.get_ref() > 0.0 && *t.get_ref() <= 1e6 => {
            Some(*t.get_ref())
        }
        Some(t) => {
            return Err(keys.error(
                t.span(),
                "time_limit",
                format!("{} must be seconds in (0, 1e6]", t.get_ref()),
            ))
        }
    };
    let regression = keys
        .get::<bool>("regression")?
        .is_some_and(|r| *r.get_ref());
    let power = match keys.get::<f64>("power")? {
        None => None,
        Some(d) if !(d.get_ref().is_finite() && *d.get_ref() > 0.0 && *d.get_ref() < 1.0) => {
            return Err(keys.error(
                d.span(),
                "power",
                format!(
                    "{} must be a relative bias in (0, 1): the smallest bias the check must catch with 95 % probability",
                    d.get_ref()
                ),
            ))
        }
        Some(d) if !kind.budgeted() => {
            return Err(keys.error(
                d.span(),
                "power",
                format!(
                    "kind {} has no sample budget the harness can scale; `power` applies to checks whose spp sets their standard error (docs/statistics.md#power-targets-and-sequential-looks)",
                    kind.name()
                ),
            ))
        }
        Some(d) => Some(*d.get_ref()),
    };
    let fixed_spp = match keys.get::<bool>("fixed")? {
        Some(f) if *f.get_ref() && power.is_some() => {
            return Err(keys.error(
                f.span(),
                "fixed",
                "`fixed = true` keeps the check's spp as written, `power` sets it from a pilot run: give one or the other".into(),
            ))
        }
        Some(f) if *f.get_ref() && !kind.budgeted() && !kind.own_looks() => {
            return Err(keys.error(
                f.span(),
                "fixed",
                format!(
                    "kind {} always runs its spp as written; `fixed` applies to kinds whose spp is a sample budget or that run in sequential looks",
                    kind.name()
                ),
            ))
        }
        f => f.is_some_and(|f| *f.get_ref()),
    };
    let models = keys
        .get::<Vec<String>>("models")?
        .map(|m| m.into_inner())
        .unwrap_or_default();
    let params = kind.parse(&mut keys)?;
    let vary = keys.get::<BTreeMap<String, Vec<f64>>>("vary")?;
    if let Some(v) = &vary {
        let combos = v
            .get_ref()
            .values()
            .fold(1usize, |n, xs| n.saturating_mul(xs.len()));
        if combos > crate::limits::MAX_CHECKS {
            return Err(err(
                v.span(),
                "vary",
                format!(
                    "would expand into {combos} checks; the limit is {} per manifest",
                    crate::limits::MAX_CHECKS
                ),
            ));
        }
        if let Some((k, _)) = v.get_ref().iter().find(|(_, xs)| xs.is_empty()) {
            return Err(err(
                v.span(),
                &format!("vary.{k}"),
                "an empty list would expand into no checks; give at least one value".into(),
            ));
        }
        if let Some((k, x)) = v
            .get_ref()
            .iter()
            .find_map(|(k, xs)| xs.iter().find(|x| !x.is_finite()).map(|x| (k, x)))
        {
            return Err(err(
                v.span(),
                &format!("vary.{k}"),
                format!("{x} is not a finite number; a scene value must be one"),
            ));
        }
    }
    let (line, _) = src.line_column(c.span().start);
    let base_check = Check {
        name: name.get_ref().clone(),
        kind,
        scene: None,
        render,
        seed,
        rel_tolerance,
        models,
        params,
        origin: format!("{}:{line}", src.path.display()),
        time_limit,
        regression,
        power,
        fixed_spp,
    };
    let Some(scene) = keys.raw("scene") else {
        return Ok(vec![base_check]);
    };
    let combos = expand(vary.as_ref().map(|v| v.get_ref()));
    if vary.is_some() && !matches!(scene.get_ref(), Value::String(_)) {
        return Err(err(
            scene.span(),
            "scene",
            "`vary` needs a scene template file (a path) with ${name} placeholders".into(),
        ));
    }
    let mut out = Vec::new();
    for combo in combos {
        let mut check = base_check.clone();
        check.scene = Some(match scene.get_ref() {
            Value::String(rel) => {
                let p = base.join(rel);
                let text = crate::io::read_small_text(&p).map_err(|e| {
                    err(
                        scene.span(),
                        "scene",
                        format!("cannot read {}: {e}", p.display()),
                    )
                })?;
                let text = substitute(&text, &combo)
                    .map_err(|m| err(scene.span(), "scene", format!("{}: {m}", p.display())))?;
                Scene::parse(&text, &p)?
            }
            Value::Table(_) => {
                let desc = inline.take().ok_or_else(|| {
                    err(
                        scene.span(),
                        "scene",
                        "an inline scene table cannot be expanded by `vary`".into(),
                    )
                })?;
                Scene::from_desc(desc, *src, scene.span()).map_err(|mut e| {
                    e.key = scene_key(index, &e.key);
                    e
                })?
            }
            other => {
                return Err(err(
                    scene.span(),
                    "scene",
                    format!("{other} is not a scene; give a path or an inline table"),
                ))
            }
        });
        if let (Some(r), Some(scene)) = (check.render.region, &check.scene) {
            // the size every region-measuring kind renders at (harness::region::settings_for)
            let w = check.render.width.unwrap_or(scene.render.width);
            let h = check.render.height.unwrap_or(scene.render.height);
            if r[2] > w || r[3] > h {
                return Err(keys.error_at(
                    "region",
                    format!("{r:?} does not fit the {w}x{h} image the check renders (pixels, end exclusive)"),
                ));
            }
        }
        if !combo.is_empty() {
            let label: Vec<String> = combo
                .iter()
                .map(|(k, v)| format!("{k}={}", short(*v)))
                .collect();
            check.name = format!("{}[{}]", check.name, label.join(","));
        }
        out.push(check);
    }
    Ok(out)
}

/// A `vary` value as a check name shows it (the name also seeds the check): as Rust writes it
/// for ordinary magnitudes (`0.5`, `1`, `1.7320508075688772`), in exponent form at or past
/// 1e16 and below 1e-6 (`1e308`, not its 309 digits).
fn short(v: f64) -> String {
    if v != 0.0 && !(1e-6..1e16).contains(&v.abs()) {
        format!("{v:e}")
    } else {
        v.to_string()
    }
}

/// Cartesian product of the `vary` lists, in key order.
fn expand(vary: Option<&BTreeMap<String, Vec<f64>>>) -> Vec<Vec<(String, f64)>> {
    let mut combos: Vec<Vec<(String, f64)>> = vec![Vec::new()];
    if let Some(v) = vary {
        for (k, values) in v {
            combos = combos
                .into_iter()
                .flat_map(|c| {
                    values.iter().map(move |x| {
                        let mut c = c.clone();
                        c.push((k.clone(), *x));
                        c
                    })
                })
                .collect();
        }
    }
    combos
}

/// Replaces `${name}` placeholders; an unknown or unresolved placeholder is an error.
fn substitute(text: &str, combo: &[(String, f64)]) -> Result<String, String> {
    let mut out = text.to_string();
    for (k, v) in combo {
        let key = format!("${{{k}}}");
        if !out.contains(&key) {
            return Err(format!("the template has no placeholder {key}"));
        }
        out = out.replace(&key, &format!("{v:?}"));
    }
    if let Some(i) = out.find("${") {
        // the placeholder as written (up to its `}`, at most 40 characters), and its line in
        // the template (found in the text before substitution)
        let rest: String = out[i..].chars().take(40).collect();
        let name = match rest.find('}') {
            Some(end) => rest[..=end].to_string(),
            None => format!("{rest}…"),
        };
        let line = text.find(&name).map_or(String::new(), |j| {
            format!(" (line {})", text[..j].matches('\n').count() + 1)
        });
        let key = name.trim_start_matches("${").trim_end_matches('}');
        let example = if !key.is_empty()
            && name.ends_with('}')
            && key.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
        {
            format!(", e.g. `vary = {{ {key} = [0.5] }}`")
        } else {
            String::new()
        };
        return Err(format!(
            "unresolved placeholder {name}{line}; give it values in the check's `vary`{example}"
        ));
    }
    Ok(out)
}

/// The manifests of a folder (`*.toml`, sorted by name).
pub fn manifests_in(dir: &Path) -> std::io::Result<Vec<PathBuf>> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    v.sort();
    Ok(v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vary_values_keep_their_written_form_in_names_unless_it_runs_long() {
        assert_eq!(short(0.5), "0.5");
        assert_eq!(short(1.0), "1");
        assert_eq!(short(1e-4), "0.0001");
        assert_eq!(short(1.7320508075688772), "1.7320508075688772");
        assert_eq!(short(0.34729635533386066), "0.34729635533386066");
        assert_eq!(short(1e300), "1e300");
        assert_eq!(short(-1.5e-200), "-1.5e-200");
    }
}
