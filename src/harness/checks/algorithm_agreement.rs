//! `algorithm_agreement`: two rendering algorithms that share nothing but the scene and the
//! camera must give the same image: furnace's path tracer (Monte Carlo, NEE + MIS, all bounces
//! by unbiased roulette) against its radiosity solver (deterministic finite elements, Goral et
//! al. 1984), its photon mapper (SPPM, Hachisuka & Jensen 2009) or its bidirectional path
//! tracer (BDPT, Veach 1997 ch. 10; unbiased, so no allowance) or Metropolis light transport
//! over it (Kelemen et al. 2002; consistent, its chains independent). Each region × channel mean
//! (G alone in a grey render, `compare::tested_channels`) is compared by the z test of harness::compare; with `refine` (the default) the algorithm's
//! own bias is estimated by refinement and allowed per region as a tolerance (at most
//! `max_bias`, since the estimate is the algorithm's own): radiosity at the
//! patch size h against 2h (the same camera samples; the difference estimates the first-order
//! error of the finer one, Cohen & Wallace 1993, §6.2), SPPM at the initial radius r/2 against r
//! (its bias shrinks at least linearly with the radius; the runs paired by seed, the mean paired
//! difference less one standard error). The check's p is the Šidák combination
//! over regions. Radiosity takes diffuse scenes lit by area emitters, SPPM and BDPT surface
//! scenes without environment lights; each refuses the rest by name.

use crate::harness::closed_form::furnace::{expectation, validate_view};
use crate::harness::compare::{
    region_dof, region_mean, region_test, regions_measurement, runs_region_mean, tested_channels,
    whole_image, RegionChoice, RgbImage,
};
use crate::harness::keys::{common, Key, Keys};
use crate::harness::measurement::fmt_sig;
use crate::harness::region::settings_for;
use crate::harness::{Check, CheckError, Context, Kind, Measurement, Scope};
use crate::integrators::radiosity::{default_patch_size, RadiositySettings};
use crate::integrators::sppm::Sppm;
use crate::integrators::Strategy;
use crate::io::LocatedError;
use crate::math::rng::mix64;

/// The algorithm compared with the path tracer.
#[derive(Debug, Clone, PartialEq)]
pub enum Algorithm {
    /// Radiosity at a patch size (None: the solver's default).
    Radiosity {
        /// Longest patch edge, scene units.
        patch_size: Option<f64>,
    },
    /// Bidirectional path tracing (unbiased: no refinement), in independent runs.
    Bdpt {
        /// Independent runs (the standard error's sample), each of the check's spp.
        runs: u64,
    },
    /// Metropolis light transport over the BDPT, in independent chains.
    Mlt {
        /// Independent chains.
        chains: u64,
        /// Mutations per pixel over all chains.
        mutations_per_pixel: u64,
    },
    /// SPPM with its settings and independent runs.
    Sppm {
        /// Iterations, photons, radius.
        settings: Sppm,
        /// Independent runs (the standard error's sample).
        runs: u64,
    },
}

/// Parameters of an algorithm_agreement check.
#[derive(Debug, Clone, PartialEq)]
pub struct Params {
    /// The algorithm under comparison.
    pub algorithm: Algorithm,
    /// Estimate its bias by refinement and allow it (false: it must agree within noise alone).
    pub refine: bool,
    /// The largest bias allowance of a region, relative to its reference: the refinement is
    /// the algorithm's own estimate of its error, so without a cap an algorithm whose image
    /// moves much under refinement would be allowed that much.
    pub max_bias: f64,
    /// Where the images are compared (after the whole image).
    pub regions: RegionChoice,
    /// Compare with the furnace closed form E/(1 − R) instead of the path tracer.
    pub closed_form: bool,
    /// Samples per pixel of the path tracer's image (None: the check's spp).
    pub reference_spp: Option<u64>,
}

/// Default [`Params::max_bias`] (`radiosity/cornell-box`, whose estimate sits at 4.9–5.0 %,
/// states 8 %).
pub const MAX_BIAS: f64 = 0.05;

/// The `algorithm_agreement` kind.
pub struct AlgorithmAgreement;

impl Kind for AlgorithmAgreement {
    type Params = Params;
    const NAME: &'static str = "algorithm_agreement";
    const KEYS: &'static [Key] = &[
        common::SCENE,
        common::VARY,
        common::SPP,
        common::WIDTH,
        common::HEIGHT,
        Key {
            name: "integrator",
            ty: "\"radiosity\", \"sppm\", \"bdpt\" or \"mlt\"",
            default: "(required)",
            doc: "the algorithm compared with the path tracer",
        },
        Key {
            name: "refine",
            ty: "boolean",
            default: "true",
            doc: "estimate the algorithm's bias by refinement (patch size or radius halved) and allow it per region; false where it is unbiased",
        },
        Key {
            name: "max_bias",
            ty: "number in (0, 1]",
            default: "0.05",
            doc: "the largest bias allowance of a region, relative to its reference, whatever the refinement estimates (the refinement is the algorithm's own estimate of its error); the verdict states how many regions reached it",
        },
        common::PATCH_SIZE,
        Key {
            name: "iterations",
            ty: "integer 1..=100000",
            default: "64",
            doc: "SPPM iterations",
        },
        common::PHOTONS_PER_ITERATION,
        Key {
            name: "runs",
            ty: "integer 2..=1000",
            default: "4",
            doc: "independent SPPM or BDPT runs (their spread is the standard error; BDPT divides spp among them)",
        },
        common::SPPM_RADIUS,
        Key {
            name: "reference",
            ty: "\"path\" or \"closed_form\"",
            default: "\"path\"",
            doc: "what the algorithm's image is compared with: the path tracer's image, or (a furnace scene) the closed form E/(1 - R) in every pixel",
        },
        Key {
            name: "reference_spp",
            ty: "integer 1..=2^20",
            default: "the check's spp",
            doc: "samples per pixel of the path tracer's image, where rare paths need more than the algorithm (docs/statistics.md, \"Rare paths\")",
        },
        Key {
            name: "chains",
            ty: "integer 2..=1000",
            default: "8",
            doc: "independent MLT chains, each with its own bootstrap (their spread is the standard error)",
        },
        Key {
            name: "mutations_per_pixel",
            ty: "integer 1..=1000000",
            default: "64",
            doc: "MLT mutations per pixel over all chains",
        },
        common::GRID,
        common::REGIONS,
        common::SEED,
        common::REL_TOLERANCE,
    ];
    const SCOPE: Scope = Scope::Furnace;

    fn parse(k: &mut Keys) -> Result<Params, LocatedError> {
        let algorithm = match k.get::<String>("integrator")? {
            Some(i) if i.get_ref() == "radiosity" => Algorithm::Radiosity {
                patch_size: k.positive("patch_size")?,
            },
            Some(i) if i.get_ref() == "sppm" => {
                let d = Sppm::default();
                Algorithm::Sppm {
                    settings: Sppm {
                        iterations: k.int("iterations", 1, 100_000)?.unwrap_or(d.iterations),
                        photons_per_iteration: k
                            .int("photons_per_iteration", 1, 1_000_000_000)?
                            .unwrap_or(d.photons_per_iteration),
                        initial_radius: k.positive("radius")?,
                        ..d
                    },
                    runs: k.int("runs", 2, 1000)?.unwrap_or(4),
                }
            }
            Some(i) if i.get_ref() == "mlt" => Algorithm::Mlt {
                chains: k.int("chains", 2, 1000)?.unwrap_or(8),
                mutations_per_pixel: k.int("mutations_per_pixel", 1, 1_000_000)?.unwrap_or(64),
            },
            Some(i) if i.get_ref() == "bdpt" => Algorithm::Bdpt {
                runs: k.int("runs", 2, 1000)?.unwrap_or(4),
            },
            Some(i) => {
                return Err(k.error(
                    i.span(),
                    "integrator",
                    format!(
                        "unknown integrator {:?}; known: \"radiosity\", \"sppm\", \"bdpt\", \"mlt\"",
                        i.get_ref()
                    ),
                ))
            }
            None => {
                return Err(k.error_at(
                    "integrator",
                    "give `integrator = \"radiosity\"`, `\"sppm\"`, `\"bdpt\"` or `\"mlt\"`: the algorithm compared with the path tracer".into(),
                ))
            }
        };
        Ok(Params {
            algorithm,
            refine: k.get::<bool>("refine")?.is_none_or(|b| *b.get_ref()),
            max_bias: match k.positive("max_bias")? {
                Some(m) if m > 1.0 => {
                    return Err(k.error_at("max_bias", format!("{m:?} must be at most 1")))
                }
                m => m.unwrap_or(MAX_BIAS),
            },
            regions: RegionChoice::parse(k)?,
            closed_form: match k.get::<String>("reference")? {
                None => false,
                Some(r) if r.get_ref() == "path" => false,
                Some(r) if r.get_ref() == "closed_form" => true,
                Some(r) => {
                    return Err(k.error(
                        r.span(),
                        "reference",
                        format!(
                            "unknown reference {:?}; known: \"path\", \"closed_form\"",
                            r.get_ref()
                        ),
                    ))
                }
            },
            reference_spp: k.int("reference_spp", 1, 1 << 20)?,
        })
    }

    /// Renders the scene by path tracing and by the algorithm (twice with `refine`) and compares.
    fn run(check: &Check, p: &Params, ctx: &Context) -> Result<Measurement, CheckError> {
        let scene = check.scene()?;
        if scene.render.max_depth.is_some()
            && matches!(
                p.algorithm,
                Algorithm::Radiosity { .. } | Algorithm::Sppm { .. }
            )
        {
            return Err("radiosity and SPPM render every bounce: the scene's render.max_depth must be absent (unlimited) for the path tracer to estimate the same image".into());
        }
        let s = settings_for(check, scene, ctx, ctx.seed, None, Strategy::Mis);
        let (w, h) = (s.width, s.height);
        let regions = p.regions.after(vec![whole_image()]);
        let rects = regions
            .iter()
            .map(|r| r.pixels(w, h))
            .collect::<Result<Vec<_>, _>>()?;
        // the reference: the path tracer's image, or the closed form in every pixel (its RGB
        // that of a flat spectrum of that radiance: grey-scene furnaces only)
        let (path, closed) = if p.closed_form {
            let (e, what) = expectation(scene, s.integrator.max_depth)?;
            validate_view(
                scene,
                w,
                h,
                [0, 0, w, h],
                s.integrator.max_depth,
                ctx.deadline,
            )?;
            let white = s.observer.white();
            let rgb = s
                .observer
                .xyz_to_rgb([e * white[0] / white[1], e, e * white[2] / white[1]]);
            (None, Some((rgb, what)))
        } else {
            let mut ps = s.clone();
            ps.spp = p.reference_spp.unwrap_or(s.spp);
            (
                Some(RgbImage::from_film(&*ctx.reference_render(scene, &ps)?)),
                None,
            )
        };
        // independent samples for the algorithm's images (the same for both of its images, so
        // that their difference is the refinement's alone)
        let mut rs = s.clone();
        rs.seed = mix64(ctx.seed ^ 0x5241_4449_4f53_4954);
        let (test, coarse, what) = render_pair(scene, &rs, &p.algorithm, p.refine, ctx)?;
        let grey = rs.is_grey(scene);
        let mut results = Vec::with_capacity(rects.len() * 3);
        let (mut widest, mut capped) = (0.0f64, 0);
        for (reg, rect) in regions.iter().zip(&rects) {
            for (c, channel) in tested_channels(grey) {
                let (t, dof) = test.region(c, *rect);
                let (reference, ref_dof) = match (&path, &closed) {
                    (Some(path), _) => (region_mean(path, c, *rect), region_dof(path, c, *rect)),
                    (None, Some((rgb, _))) => ((rgb[c], 0.0), f64::INFINITY),
                    (None, None) => unreachable!("one reference"),
                };
                let estimated = coarse.as_ref().map_or(0.0, |coarse| {
                    test.refinement(coarse, c, *rect) / reference.0.abs().max(f64::MIN_POSITIVE)
                });
                // (a NaN estimate stays NaN, and the test an ERROR, rather than the cap)
                let bias = if estimated.is_nan() {
                    estimated
                } else {
                    estimated.min(p.max_bias)
                };
                capped += usize::from(estimated > p.max_bias);
                widest = widest.max(bias);
                results.push(region_test(
                    &reg.name,
                    channel,
                    t,
                    reference,
                    [dof, ref_dof],
                    bias + ctx.rel_tolerance(check.rel_tolerance),
                ));
            }
        }
        let allowance = if coarse.is_some() {
            format!(
                "; bias allowance per region from refinement, up to {} relative (at most {}; {capped} region x channel tests at that cap)",
                fmt_sig(widest),
                fmt_sig(p.max_bias)
            )
        } else {
            "; no bias allowance".into()
        };
        let reference = match &closed {
            Some((_, cf)) => format!("the closed form ({cf})"),
            None => format!(
                "path tracer ({} spp, {})",
                p.reference_spp.unwrap_or(s.spp),
                s.integrator
                    .max_depth
                    .map_or("unlimited depth".into(), |d| format!("at most {d} bounces"))
            ),
        };
        let reference_spp = if p.closed_form {
            0
        } else {
            p.reference_spp.unwrap_or(s.spp)
        };
        regions_measurement(
            &results,
            (w * h) as u64 * (s.spp + reference_spp),
            &format!("{what}{allowance} = test, {reference} = reference, {w}x{h}"),
        )
    }
}

/// An algorithm's images: one with independent pixels (radiosity: each pixel's camera
/// samples are its own), or independent runs whose pixels are correlated within a run (SPPM:
/// shared photons and wavelengths), where a region's error comes from the runs' region means.
enum Images {
    Pixels(Box<RgbImage>),
    Runs(Vec<RgbImage>),
}

impl Images {
    /// Region mean of channel `c` with its standard error, and the error's degrees of freedom.
    fn region(&self, c: usize, rect: [usize; 4]) -> ((f64, f64), f64) {
        match self {
            Images::Pixels(img) => (region_mean(img, c, rect), region_dof(img, c, rect)),
            Images::Runs(runs) => runs_region_mean(runs, c, rect),
        }
    }

    /// The bias allowance of this image given its coarser twin, absolute: for radiosity the
    /// region difference (both images share their camera samples, so it is the
    /// discretisation's alone); for SPPM runs paired by seed, the mean paired difference less
    /// one standard error of it, so that the runs' noise is not allowed twice.
    fn refinement(&self, coarse: &Images, c: usize, rect: [usize; 4]) -> f64 {
        match (self, coarse) {
            (Images::Runs(fine), Images::Runs(coarse)) if fine.len() == coarse.len() => {
                let d: Vec<f64> = fine
                    .iter()
                    .zip(coarse)
                    .map(|(f, c2)| region_mean(c2, c, rect).0 - region_mean(f, c, rect).0)
                    .collect();
                let k = d.len() as f64;
                let mean = d.iter().sum::<f64>() / k;
                let var = d.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (k - 1.0);
                (mean.abs() - (var / k).sqrt()).max(0.0)
            }
            _ => (coarse.region(c, rect).0 .0 - self.region(c, rect).0 .0).abs(),
        }
    }
}

/// The algorithm's image, and with `refine` its coarser twin (radiosity at twice the patch
/// size, SPPM at twice the radius), with a description.
fn render_pair(
    scene: &crate::scene::Scene,
    s: &crate::render::RenderSettings,
    algorithm: &Algorithm,
    refine: bool,
    ctx: &Context,
) -> Result<(Images, Option<Images>, String), CheckError> {
    match algorithm {
        Algorithm::Radiosity { patch_size } => {
            let size = patch_size.unwrap_or_else(|| default_patch_size(scene.aggregate.shapes()));
            let solve_at = |size: f64| {
                let settings = RadiositySettings {
                    patch_size: Some(size),
                    ..Default::default()
                };
                ctx.renderer.render_radiosity(scene, s, &settings)
            };
            let (fine, st) = solve_at(size)?;
            let coarse = if refine {
                let coarse = solve_at(2.0 * size)?.0;
                Some(Images::Pixels(Box::new(RgbImage::from_film(&coarse))))
            } else {
                None
            };
            Ok((
                Images::Pixels(Box::new(RgbImage::from_film(&fine))),
                coarse,
                format!(
                    "radiosity ({} patches of at most {}, solver bound {})",
                    st.patches,
                    fmt_sig(st.patch_size),
                    fmt_sig(st.error_bound)
                ),
            ))
        }
        Algorithm::Bdpt { runs } => {
            // the check's spp divided among the runs: BDPT gets the path tracer's budget
            let per_run = crate::render::RenderSettings {
                spp: (s.spp / runs).max(1),
                ..s.clone()
            };
            let bdpt = crate::integrators::bdpt::Bdpt::from(&s.integrator);
            let films = ctx.renderer.render_bdpt(scene, &per_run, &bdpt, *runs)?;
            if films.len() as u64 != *runs {
                return Err(CheckError::Renderer(format!(
                    "the bidirectional path tracer returned {} runs for {runs}",
                    films.len()
                )));
            }
            Ok((
                Images::Runs(films.iter().map(RgbImage::from_film).collect()),
                None,
                format!(
                    "BDPT ({runs} runs x {} spp, all strategies by the power heuristic)",
                    per_run.spp
                ),
            ))
        }
        Algorithm::Mlt {
            chains,
            mutations_per_pixel,
        } => {
            let settings = crate::integrators::mlt::Mlt {
                chains: *chains,
                mutations_per_pixel: *mutations_per_pixel,
                ..Default::default()
            };
            let bdpt = crate::integrators::bdpt::Bdpt::from(&s.integrator);
            let films = ctx.renderer.render_mlt(scene, s, &bdpt, &settings)?;
            if films.len() as u64 != settings.chains {
                return Err(CheckError::Renderer(format!(
                    "Metropolis light transport returned {} chains for {}",
                    films.len(),
                    settings.chains
                )));
            }
            Ok((
                Images::Runs(films.iter().map(RgbImage::from_film).collect()),
                None,
                format!(
                    "MLT over the BDPT ({} chains x {} mutations per pixel in all, each chain with its own bootstrap)",
                    settings.chains, settings.mutations_per_pixel
                ),
            ))
        }
        Algorithm::Sppm { settings, runs } => {
            let r = settings.radius_in(scene);
            // with refinement, the images at r/2 and r in one pass (the same paths gathered
            // at both radii)
            let radii: &[f64] = if refine { &[r / 2.0, r] } else { &[r] };
            let mut images = ctx
                .renderer
                .render_sppm_radii(scene, s, settings, radii, *runs)?
                .into_iter();
            let mut next = || {
                let films = images.next().unwrap_or_default();
                if films.len() as u64 != *runs {
                    return Err(CheckError::Renderer(format!(
                        "the photon mapper returned {} runs for {runs}",
                        films.len()
                    )));
                }
                Ok::<_, CheckError>(Images::Runs(
                    films.iter().map(RgbImage::from_film).collect(),
                ))
            };
            let test = next()?;
            let coarse = if refine { Some(next()?) } else { None };
            Ok((
                test,
                coarse,
                format!(
                    "SPPM ({runs} runs x {} iterations x {} photons, initial radius {})",
                    settings.iterations,
                    settings.photons_per_iteration,
                    fmt_sig(if refine { r / 2.0 } else { r })
                ),
            ))
        }
    }
}
