//! The keys of one `[[check]]` table, read with types and located errors: each kind reads the
//! keys it declares, and a key the kind does not declare is an error naming the kind's keys.

use crate::io::{LocatedError, Source};
use serde::de::DeserializeOwned;
use std::collections::BTreeMap;
use std::ops::Range;
use toml::{Spanned, Value};

/// A manifest key a kind accepts: its name, value type, default and meaning (for docs and
/// error messages).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Key {
    /// Name in the manifest.
    pub name: &'static str,
    /// Value type as a reader sees it, e.g. "integer 2..=2^32".
    pub ty: &'static str,
    /// Default, or "required".
    pub default: &'static str,
    /// What it means, with its unit.
    pub doc: &'static str,
}

/// Keys every check takes, whatever its kind (read by the manifest, not by the kind).
const CHECK_KEYS: [&str; 6] = ["name", "kind", "time_limit", "regression", "power", "fixed"];

/// Keys several kinds share (the scene-level ones, image comparison's regions and observer).
pub mod common {
    use super::Key;

    /// The scene: a path relative to the manifest, or an inline table.
    pub const SCENE: Key = Key {
        name: "scene",
        ty: "path or table",
        default: "required",
        doc: "the scene: a TOML file relative to the manifest (a template when `vary` is given), or an inline [check.scene] table",
    };
    /// Template parameters.
    pub const VARY: Key = Key {
        name: "vary",
        ty: "table of number lists",
        default: "none",
        doc: "placeholder name -> values; one check per combination, named name[k=v,...]",
    };
    /// Samples per pixel.
    pub const SPP: Key = Key {
        name: "spp",
        ty: "integer 2..=2^32",
        default: "the scene's",
        doc: "samples per pixel",
    };
    /// Image width.
    pub const WIDTH: Key = Key {
        name: "width",
        ty: "integer 1..=4096",
        default: "the scene's",
        doc: "image width, pixels",
    };
    /// Image height.
    pub const HEIGHT: Key = Key {
        name: "height",
        ty: "integer 1..=4096",
        default: "the scene's",
        doc: "image height, pixels",
    };
    /// Maximum bounces.
    pub const MAX_DEPTH: Key = Key {
        name: "max_depth",
        ty: "integer 0..=2^20",
        default: "the scene's",
        doc: "maximum bounces (0 = emitters only, 1 = direct light)",
    };
    /// Russian roulette.
    pub const ROULETTE: Key = Key {
        name: "roulette",
        ty: "boolean",
        default: "true",
        doc: "unbiased Russian roulette after 5 bounces; false needs max_depth",
    };
    /// The measured pixel region.
    pub const REGION: Key = Key {
        name: "region",
        ty: "[x0, y0, x1, y1] pixels",
        default: "the whole image",
        doc: "pixel rectangle measured, end exclusive",
    };
    /// The check's seed.
    pub const SEED: Key = Key {
        name: "seed",
        ty: "integer >= 0",
        default: "derived from the run seed and the name",
        doc: "the check's own seed",
    };
    /// A stated model tolerance.
    pub const REL_TOLERANCE: Key = Key {
        name: "rel_tolerance",
        ty: "number in [0, 0.1)",
        default: "0",
        doc: "stated relative model tolerance added to the acceptance rule",
    };

    /// The models under test a model-level check takes, by name.
    pub const MODELS: Key = Key {
        name: "models",
        ty: "list of name patterns (* and ?)",
        default: "every model the renderer serves",
        doc: "names of the models under test this check takes (furnace's catalogue names, or those a model server lists)",
    };

    /// The `regions` key: a regions file (TOML `[[region]]`), relative to the manifest.
    pub const REGIONS: Key = Key {
        name: "regions",
        ty: "path",
        default: "the whole image",
        doc: "regions file (TOML [[region]] tables with name and rect in image fractions), relative to the manifest",
    };

    /// SPPM's photons per iteration.
    pub const PHOTONS_PER_ITERATION: Key = Key {
        name: "photons_per_iteration",
        ty: "integer 1..=10^9",
        default: "100000",
        doc: "SPPM photons per iteration",
    };
    /// SPPM's initial gather radius.
    pub const SPPM_RADIUS: Key = Key {
        name: "radius",
        ty: "length > 0 (scene units)",
        default: "1/50 of the scene's bounding radius",
        doc: "SPPM's initial gather radius",
    };
    /// The `patch_size` key: the longest patch edge of a radiosity solve.
    pub const PATCH_SIZE: Key = Key {
        name: "patch_size",
        ty: "length > 0 (scene units)",
        default: "the smallest giving at most 1024 patches",
        doc: "longest patch edge of the radiosity solve",
    };

    /// The `grid` key: blocks per side of a region grid.
    pub const GRID: Key = Key {
        name: "grid",
        ty: "integer 1..=64",
        default: "4",
        doc: "blocks per side of the region grid (instead of `regions`)",
    };

    /// The `observer` key: the colour pipeline the image is rendered with.
    pub const OBSERVER: Key = Key {
        name: "observer",
        ty: "\"cie1931\" or \"mitsuba3\"",
        default: "\"cie1931\"",
        doc: "colour pipeline of the rendered RGB (match the reference's)",
    };
}

/// One `[[check]]` table as written, keyed by name, with every value's span.
pub type Table = BTreeMap<String, Spanned<Value>>;

/// Typed, located access to one check's keys.
pub struct Keys<'a> {
    /// The manifest text, for locating errors.
    pub src: &'a Source<'a>,
    /// `check[i]`, the prefix of every error key.
    pub at: String,
    /// Span of the whole table (for errors about missing keys).
    pub span: Range<usize>,
    /// The kind's name.
    pub kind: &'static str,
    /// Folder of the manifest, which relative paths are resolved against.
    pub base: std::path::PathBuf,
    table: &'a Table,
}

impl<'a> Keys<'a> {
    /// Access to `table` (the check at `at`, spanning `span`) as kind `kind` with its `allowed`
    /// keys: a key outside them is an error that lists them.
    pub fn new(
        src: &'a Source<'a>,
        table: &'a Table,
        at: String,
        span: Range<usize>,
        kind: &'static str,
        allowed: &[Key],
        base: std::path::PathBuf,
    ) -> Result<Self, LocatedError> {
        let keys = Keys {
            src,
            at,
            span,
            kind,
            base,
            table,
        };
        for (key, v) in table {
            if CHECK_KEYS.contains(&key.as_str()) {
                continue;
            }
            if !allowed.iter().any(|k| k.name == key) {
                let names: Vec<&str> = allowed.iter().map(|k| k.name).collect();
                return Err(keys.error(
                    v.span(),
                    key,
                    format!(
                        "`{key}` is not a key of kind {:?}{}; its keys are: {}, {}",
                        kind,
                        super::names::did_you_mean(key, CHECK_KEYS.iter().chain(&names).copied()),
                        CHECK_KEYS.join(", "),
                        names.join(", ")
                    ),
                ));
            }
        }
        Ok(keys)
    }

    /// An error about `key` at `span`.
    pub fn error(&self, span: Range<usize>, key: &str, message: String) -> LocatedError {
        self.src.error(span, format!("{}.{key}", self.at), message)
    }

    /// An error about `key` located at the key's value, or at the table when it is absent.
    pub fn error_at(&self, key: &str, message: String) -> LocatedError {
        self.error(self.span_of(key), key, message)
    }

    /// The span of `key`'s value, or of the table when it is absent.
    pub fn span_of(&self, key: &str) -> Range<usize> {
        self.table
            .get(key)
            .map(|v| v.span())
            .unwrap_or(self.span.clone())
    }

    /// True when the table has `key`.
    pub fn has(&self, key: &str) -> bool {
        self.table.contains_key(key)
    }

    /// The raw value of `key`.
    pub fn raw(&self, key: &str) -> Option<&'a Spanned<Value>> {
        self.table.get(key)
    }

    /// `key` as a `T`, or None when absent; a value of the wrong type is a located error.
    pub fn get<T: DeserializeOwned>(&self, key: &str) -> Result<Option<Spanned<T>>, LocatedError> {
        let Some(v) = self.table.get(key) else {
            return Ok(None);
        };
        let span = v.span();
        let x: T = v
            .get_ref()
            .clone()
            .try_into()
            .map_err(|e: toml::de::Error| {
                self.error(
                    span.clone(),
                    key,
                    crate::io::suggest::plain_message(e.message().trim_end()),
                )
            })?;
        Ok(Some(Spanned::new(span, x)))
    }

    /// `key` as an integer in `lo..=hi`, converted to `T`.
    pub fn int<T: TryFrom<i64>>(
        &self,
        key: &str,
        lo: i64,
        hi: i64,
    ) -> Result<Option<T>, LocatedError> {
        match self.get::<i64>(key)? {
            None => Ok(None),
            Some(s) => {
                let x = *s.get_ref();
                if x < lo || x > hi {
                    return Err(self.error(
                        s.span(),
                        key,
                        format!("{x} is out of range; allowed {lo}..={hi}"),
                    ));
                }
                Ok(T::try_from(x).ok())
            }
        }
    }

    /// `key` as a finite number ≥ 0.
    pub fn non_negative(&self, key: &str) -> Result<Option<f64>, LocatedError> {
        match self.get::<f64>(key)? {
            None => Ok(None),
            Some(s) => {
                let x = *s.get_ref();
                if !(x.is_finite() && x >= 0.0) {
                    return Err(self.error(
                        s.span(),
                        key,
                        format!("{x:?} must be a finite number >= 0"),
                    ));
                }
                Ok(Some(x))
            }
        }
    }

    /// `key` as a finite number > 0.
    pub fn positive(&self, key: &str) -> Result<Option<f64>, LocatedError> {
        let x = self.non_negative(key)?;
        if x == Some(0.0) {
            return Err(self.error_at(key, format!("{key} must be > 0")));
        }
        Ok(x)
    }

    /// `key` as a list of finite numbers (all > 0 when `positive_only`); empty when absent, an
    /// error when written empty.
    pub fn finite_list(&self, key: &str, positive_only: bool) -> Result<Vec<f64>, LocatedError> {
        match self.get::<Vec<f64>>(key)? {
            None => Ok(Vec::new()),
            Some(s) => {
                // an empty list written out is not the key left out (which takes the default)
                if s.get_ref().is_empty() {
                    return Err(self.error(
                        s.span(),
                        key,
                        "is empty; give at least one value, or leave the key out for its default"
                            .into(),
                    ));
                }
                if let Some(x) = s
                    .get_ref()
                    .iter()
                    .find(|x| !x.is_finite() || (positive_only && **x <= 0.0))
                {
                    let what = if positive_only {
                        "finite and > 0"
                    } else {
                        "finite"
                    };
                    return Err(self.error(
                        s.span(),
                        key,
                        format!("{x:?} is not allowed; every entry must be {what}"),
                    ));
                }
                Ok(s.into_inner())
            }
        }
    }

    /// A file named by `key`, resolved against the manifest's folder; it must exist. When the
    /// kind requires it, `missing` is the message for its absence.
    pub fn existing_file(
        &self,
        key: &str,
        missing: Option<&str>,
    ) -> Result<Option<std::path::PathBuf>, LocatedError> {
        match self.get::<String>(key)? {
            None => match missing {
                Some(m) => Err(self.error(self.span.clone(), key, m.to_string())),
                None => Ok(None),
            },
            Some(r) => {
                let p = self.base.join(r.get_ref());
                if !p.is_file() {
                    return Err(self.error(
                        r.span(),
                        key,
                        format!("{} does not exist or is not a file", p.display()),
                    ));
                }
                Ok(Some(p))
            }
        }
    }

    /// `samples`: samples or direction pairs per model, 1..=2^26.
    pub fn samples(&self) -> Result<Option<u64>, LocatedError> {
        self.int("samples", 1, 1 << 26)
    }

    /// `theta_max_deg`: the largest polar angle tested, in [0, 90) degrees.
    pub fn theta_max_deg(&self) -> Result<Option<f64>, LocatedError> {
        let t = self.non_negative("theta_max_deg")?;
        if let Some(t) = t.filter(|t| *t >= 90.0) {
            return Err(self.error_at("theta_max_deg", format!("{t:?} must be < 90 degrees")));
        }
        Ok(t)
    }

    /// `bins`: sphere histogram bins [theta 2..=1000, phi 2..=2000].
    pub fn bins(&self) -> Result<Option<[usize; 2]>, LocatedError> {
        match self.get::<[i64; 2]>("bins")? {
            None => Ok(None),
            Some(b) => {
                let [t, p] = *b.get_ref();
                if !(2..=1000).contains(&t) || !(2..=2000).contains(&p) {
                    return Err(self.error(
                        b.span(),
                        "bins",
                        format!("[{t}, {p}] must be [theta bins 2..=1000, phi bins 2..=2000]"),
                    ));
                }
                Ok(Some([t as usize, p as usize]))
            }
        }
    }

    /// The colour pipeline named by `observer` (default cie1931).
    pub fn observer(&self) -> Result<crate::spectrum::Observer, LocatedError> {
        use crate::spectrum::Observer;
        let Some(o) = self.get::<String>("observer")? else {
            return Ok(Observer::default());
        };
        Observer::from_name(o.get_ref()).ok_or_else(|| {
            let names: Vec<&str> = Observer::ALL.iter().map(|x| x.0).collect();
            self.error(
                o.span(),
                "observer",
                format!(
                    "unknown observer {:?}; allowed: {}",
                    o.get_ref(),
                    names.join(", ")
                ),
            )
        })
    }
}

/// Keys of the model-level kinds, with the meaning they share (each kind states its default).
pub mod model {
    use super::Key;

    /// Random samples or direction pairs per model.
    pub const fn samples(default: &'static str) -> Key {
        Key {
            name: "samples",
            ty: "integer 1..=2^26",
            default,
            doc: "samples (or direction pairs) per model and angle",
        }
    }
    /// Largest polar angle of the outgoing directions tested.
    pub const fn theta_max_deg(default: &'static str) -> Key {
        Key {
            name: "theta_max_deg",
            ty: "degrees in [0, 90)",
            default,
            doc: "largest polar angle tested (grazing limit)",
        }
    }
    /// Absolute tolerance of a deterministic comparison.
    pub const fn abs_tol(default: &'static str) -> Key {
        Key {
            name: "abs_tol",
            ty: "number >= 0",
            default,
            doc: "absolute tolerance of the deterministic part",
        }
    }
    /// Relative tolerance of a deterministic comparison.
    pub const fn rel_tol(default: &'static str) -> Key {
        Key {
            name: "rel_tol",
            ty: "number >= 0",
            default,
            doc: "relative tolerance of the deterministic part",
        }
    }
    /// Histogram bins of a chi-square test.
    pub const fn bins(default: &'static str) -> Key {
        Key {
            name: "bins",
            ty: "[theta 2..=1000, phi 2..=2000]",
            default,
            doc: "histogram bins of the chi-square tests",
        }
    }
}
