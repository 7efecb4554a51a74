//! Convergence rates (the `convergence` kind): the scene is rendered at a ladder of sample
//! counts N with K independent seeds each; the error of every pixel of the region against
//! its closed-form footprint average (k×k quadrature, fine enough to sit far below the
//! errors measured) gives RMSE(N) over pixels and seeds. A least-squares line through
//! (ln N, ln RMSE), weighted by each rung's uncertainty (the spread of its per-seed MSEs),
//! gives the rate: RMSE ∝ N^slope. The check asserts that the slope lies in the stated range
//! (with β̂ ± se, Student t with rungs − 2 dof, the p-value of |β̂ − mid| exceeding the
//! half-width, the tolerance form of `z_with_tolerance`) and that a power law describes the
//! ladder at all (the weighted lack-of-fit χ², referred to an F law because the weights come
//! from K seeds); the two p-values are Šidák-combined.
//!
//! Expected rates: independent sampling −0.5; jittered (stratified) sampling of a smooth 2D
//! pixel integrand −1, across an edge −0.75 (Mitchell 1996, "Consequences of stratified
//! sampling in graphics", SIGGRAPH, §3); Owen-scrambled Sobol at least as fast as jittered for
//! these integrands (Owen 1997, "Scrambled net variance for integrals of smooth functions",
//! Ann. Stat. 25: N^-1.5 for smooth integrands in the limit).
//!
//! `of = "lambert"` renders direct light only (max_depth 1) and compares with R·H/π;
//! `of = "emission"` renders emission only (max_depth 0) and compares with the emitted
//! radiance, whose footprint integrand is a step across every emitter edge; `of = "furnace"`
//! renders a uniform enclosure (with `max_depth` and `roulette` as given) and compares with
//! E/(1 − R) or its depth-capped form, for estimator ladders of multi-bounce transport.

use crate::harness::closed_form::emission::emitted_along_k;
use crate::harness::closed_form::footprint::per_pixel_k;
use crate::harness::closed_form::furnace::{expectation as furnace_expectation, validate_view};
use crate::harness::closed_form::lambert::reflected;
use crate::harness::keys::{common, Key, Keys};
use crate::harness::kind::scope_rule;
use crate::harness::ladder::{counts, fit, measurement, slope, Ladder, Rung};
use crate::harness::region::{region_of, settings_for};
use crate::harness::{Check, CheckError, Context, Kind, Measurement, Scope, Subject};
use crate::integrators::Strategy;
use crate::io::LocatedError;
use crate::math::rng::Sampler;
use std::time::Instant;

/// Quadrature points per pixel side for the reference (k² rays per pixel).
pub const REFERENCE_K: usize = 128;

/// Renders the ladder of a convergence check.
pub fn ladder(check: &Check, p: &Params, ctx: &Context) -> Result<Ladder, CheckError> {
    let scene = check.scene()?;
    let depth = match p.of {
        Of::Emission => Some(0),
        Of::Furnace => check.render.max_depth,
        Of::Lambert => Some(1),
    };
    let mut rungs = Vec::new();
    let mut reference: Option<(Vec<f64>, f64)> = None;
    for (r, &spp) in p.ladder.iter().enumerate() {
        let mut secs = 0.0;
        let mut per_seed = Vec::new();
        let mut samples = 0;
        for k in 0..p.seeds {
            let seed = crate::math::rng::mix64(ctx.seed ^ ((r as u64) << 32) ^ k);
            let mut s = settings_for(check, scene, ctx, seed, depth, p.strategy);
            s.spp = spp;
            s.sampler = p.sampler;
            let region = region_of(check, &s)?;
            if reference.is_none() {
                let px = if p.of == Of::Furnace {
                    // A uniform enclosure: every pixel reads the closed form (where the
                    // region sees only the enclosure's inside and the enclosure is closed)
                    let (v, _) = furnace_expectation(scene, depth)?;
                    validate_view(scene, s.width, s.height, region, depth, ctx.deadline)?;
                    vec![v; (region[2] - region[0]) * (region[3] - region[1])]
                } else {
                    // the ladders of one scene (one per sampler or estimator) share it
                    let request = format!(
                        "convergence reference {:?}, {}x{}, region {region:?}, k {REFERENCE_K}",
                        p.of, s.width, s.height
                    );
                    let px = ctx.closed_form(scene, &request, || match p.of {
                        Of::Emission => emitted_along_k(
                            scene,
                            s.width,
                            s.height,
                            region,
                            REFERENCE_K,
                            ctx.deadline,
                        ),
                        _ => per_pixel_k(
                            scene,
                            s.width,
                            s.height,
                            region,
                            &|h, d| reflected(scene, h, d),
                            REFERENCE_K,
                            ctx.deadline,
                        ),
                    })?;
                    px.to_vec()
                };
                let mean = px.iter().sum::<f64>() / px.len() as f64;
                reference = Some((px, mean));
            }
            let (ref_px, _) = reference.as_ref().expect("set above");
            let t0 = Instant::now();
            let film = ctx.renderer.render(scene, &s)?;
            secs += t0.elapsed().as_secs_f64();
            samples = (s.width * s.height) as u64 * spp;
            let y = film.means(1);
            let mut i = 0;
            let (mut se_k, mut n_k) = (0.0, 0.0);
            for py in region[1]..region[3] {
                for px in region[0]..region[2] {
                    let e = y[py * s.width + px] - ref_px[i];
                    se_k += e * e;
                    n_k += 1.0;
                    i += 1;
                }
            }
            per_seed.push(se_k / n_k);
        }
        rungs.push(Rung::from_mses(
            spp,
            &per_seed,
            reference.as_ref().map_or(0.0, |r| r.1),
            secs / p.seeds as f64,
            samples,
        ));
    }
    fit(p.sampler.name(), rungs, p.seeds)
}

/// The closed form a convergence ladder measures its error against.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Of {
    /// Lambert's law, direct light only.
    Lambert,
    /// Emitted radiance, emission only.
    Emission,
    /// A uniform furnace enclosure.
    Furnace,
}

/// Parameters of a convergence check.
#[derive(Debug, Clone, PartialEq)]
pub struct Params {
    /// The closed form.
    pub of: Of,
    /// Sample pattern.
    pub sampler: Sampler,
    /// How emitters are found.
    pub strategy: Strategy,
    /// Sample counts, increasing.
    pub ladder: Vec<u64>,
    /// Independent seeds per rung.
    pub seeds: u64,
    /// Allowed slope range [min, max].
    pub slope: [f64; 2],
}

/// The `convergence` kind.
pub struct Convergence;

impl Kind for Convergence {
    type Params = Params;
    const NAME: &'static str = "convergence";
    const KEYS: &'static [Key] = &[
        common::SCENE,
        Key {
            name: "of",
            ty: "\"lambert\", \"emission\" or \"furnace\"",
            default: "required",
            doc: "the closed form each pixel's error is measured against",
        },
        Key {
            name: "sampler",
            ty: "\"independent\", \"stratified\" or \"sobol\"",
            default: "\"independent\"",
            doc: "sample pattern per pixel",
        },
        Key {
            name: "strategy",
            ty: "\"mis\", \"bsdf\" or \"light\"",
            default: "\"mis\"",
            doc: "how emitters are found",
        },
        Key {
            name: "ladder",
            ty: "at least 3 increasing integers in 1..=2^20",
            default: "required",
            doc: "samples per pixel of each rung",
        },
        Key {
            name: "seeds",
            ty: "integer 2..=1024",
            default: "8",
            doc: "independent seeds per rung",
        },
        Key {
            name: "slope",
            ty: "[min, max], min < max < 0",
            default: "required",
            doc: "allowed range of the fitted RMSE slope (RMSE ∝ N^slope)",
        },
        common::WIDTH,
        common::HEIGHT,
        common::REGION,
        common::SEED,
        common::MAX_DEPTH,
        common::ROULETTE,
    ];
    const SCOPE: Scope = Scope::Image;

    fn parse(k: &mut Keys) -> Result<Params, LocatedError> {
        let of_list = "\"lambert\", \"emission\", \"furnace\"";
        let of = match k.get::<String>("of")? {
            None => return Err(k.error_at("of", format!("missing; allowed: {of_list}"))),
            Some(o) => match o.get_ref().as_str() {
                "lambert" => Of::Lambert,
                "emission" => Of::Emission,
                "furnace" => Of::Furnace,
                other => {
                    return Err(k.error(o.span(), "of", format!("{other:?}: allowed {of_list}")))
                }
            },
        };
        let sampler = match k.get::<String>("sampler")? {
            None => Sampler::default(),
            Some(v) => Sampler::from_name(v.get_ref()).ok_or_else(|| {
                k.error(
                    v.span(),
                    "sampler",
                    format!(
                        "unknown sampler {:?}; allowed: independent, stratified, sobol",
                        v.get_ref()
                    ),
                )
            })?,
        };
        let strategy = match k.get::<String>("strategy")? {
            None => Strategy::Mis,
            Some(v) => match v.get_ref().as_str() {
                "mis" => Strategy::Mis,
                "bsdf" => Strategy::BsdfOnly,
                "light" => Strategy::LightOnly,
                other => {
                    return Err(k.error(
                        v.span(),
                        "strategy",
                        format!("unknown strategy {other:?}; allowed: mis, bsdf, light"),
                    ))
                }
            },
        };
        let ladder = counts(k, "ladder", 1 << 20)?;
        let slope = slope(k)?;
        Ok(Params {
            of,
            sampler,
            strategy,
            ladder,
            seeds: k.int("seeds", 2, 1024)?.unwrap_or(8),
            slope,
        })
    }

    /// An external renderer's sampler and estimator are its own: only a check stating the
    /// independent-sampling, MIS rate applies to it.
    fn not_applicable(_: &Check, p: &Params, subject: &Subject) -> Option<String> {
        let renderer = subject.renderer;
        if let Some(why) = scope_rule(Self::NAME, Self::SCOPE, subject) {
            return Some(why);
        }
        if renderer.is_reference() {
            return None;
        }
        if !renderer.exact_spp() {
            return Some(format!(
                "{} renders at least the samples per pixel it is asked for, not exactly (renderers.toml spp = \"at-least\"), so a ladder's N would not be N",
                renderer.name()
            ));
        }
        // another renderer runs its own estimator (MIS in every one judged so far) with the
        // pattern its table states
        let pattern = renderer.sampler();
        (p.strategy != Strategy::Mis || pattern != p.sampler.name()).then(|| {
            format!(
                "this convergence check states the rate of {} sampling with {:?}; {} uses its own estimator and samples with its {pattern} pattern",
                p.sampler.name(),
                p.strategy,
                renderer.name()
            )
        })
    }

    /// Runs a convergence check.
    fn run(check: &Check, params: &Params, ctx: &Context) -> Result<Measurement, CheckError> {
        let l = ladder(check, params, ctx)?;
        let samples = l.rungs.iter().map(|r| r.samples).sum::<u64>() * params.seeds;
        let what = format!("{} sampler, {:?}", l.sampler, params.strategy);
        Ok(measurement(&l, params.slope, params.seeds, samples, &what))
    }
}
