//! Rendering by light tracing: N i.i.d. light paths splat their camera connections onto the
//! film (integrators::light). Path i gives pixel j one sample c_ij (the sum of its
//! contributions there, 0 for most paths), so each pixel holds the mean and variance of N
//! i.i.d. values (film units, N − 1 degrees of freedom) exactly as a camera-path render does.
//! Pixels are correlated, so region statistics come from per-path region sums
//! ([`LightImage::regions`]). The same seed gives the same bits for any thread count
//! ([`CHUNKS`] fixed chunks). Details: docs/rendering.md, "`render::light`".

use super::{check_common, in_pool, FilmResponse, RenderError, RenderSettings};
use crate::film::blocks::{BlockFold, Piece, Span};
use crate::film::partial::PartialFilm;
use crate::film::{Film, Pixel};
use crate::integrators::light::{PinholeSensor, Sensor, Splat};
use crate::integrators::LightTracer;
use crate::math::rng::{mix64, run_seed, SampleStream, Sampler};
use crate::scene::Scene;
use crate::spectrum::Wavelengths;
use crate::stats::MeanVar;
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

/// Number of chunks the light paths are split into (fixed, so results do not depend on the
/// thread count; the blocks of the merge tree of film::blocks, a power of two).
pub const CHUNKS: u64 = 64;

/// The "pixel" key of light-path random streams (light paths are not tied to a pixel; this
/// keeps them apart from every camera-path stream of the same seed).
const LIGHT_STREAM: u64 = 0x4c49_4748_545f_5452; // "LIGHT_TR"

/// A light-traced image: the film, plus exact statistics of per-path region sums.
#[derive(Debug, Clone, PartialEq)]
pub struct LightImage {
    /// Per-pixel means and variances (X, Y, Z, R, G, B; count = number of light paths).
    pub film: Film,
    /// For each requested region [x0, y0, x1, y1) (pixels, end exclusive) and channel (X, Y, Z,
    /// R, G, B): the statistics of the per-path SUM over the region's pixels. The region's
    /// mean pixel value is `mean()/pixels` and its standard error `std_error()/pixels`.
    pub regions: Vec<[MeanVar; 6]>,
    /// Light paths traced.
    pub paths: u64,
}

/// Renders `scene` by tracing `n_paths` light paths with `settings` (size, seed, threads,
/// max_depth and rr_depth of `settings.integrator`, observer, spectral handling; `spp` is not
/// used). `progress` is called with the number of paths finished so far (from worker
/// threads, once per chunk).
pub fn render_light_paths(
    scene: &Scene,
    settings: &RenderSettings,
    n_paths: u64,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<Film, RenderError> {
    let sensor = pinhole(scene, settings)?;
    trace_light_image(scene, settings, n_paths, &[], &sensor, progress).map(|i| i.film)
}

/// `runs` independent light-traced images of `scene` with `n_paths` paths in all (run r
/// traces paths ⌊r·n/runs⌋..⌊(r+1)·n/runs⌋ of its own stream, `math::rng::run_seed`): the
/// images `furnace render --keep-runs` stores, whose region means give a region's standard
/// error where the pixel variances cannot (a run's pixels are correlated). `progress` is
/// called with the paths finished so far over all runs.
pub fn render_light_runs(
    scene: &Scene,
    settings: &RenderSettings,
    n_paths: u64,
    runs: u64,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<Vec<Film>, RenderError> {
    if runs < 2 || n_paths < 2 * runs {
        return Err(RenderError::Settings(format!(
            "{n_paths} light paths in {runs} runs: a run's spread needs at least 2 runs of at least 2 paths each"
        )));
    }
    let bound = |r: u64| (r as u128 * n_paths as u128 / runs as u128) as u64;
    let mut films = Vec::with_capacity(runs as usize);
    for r in 0..runs {
        let s = RenderSettings {
            seed: run_seed(settings.seed, r, 0x4c49_4748), // "LIGH"
            ..settings.clone()
        };
        let base = bound(r);
        films.push(render_light_paths(scene, &s, bound(r + 1) - base, &|n| {
            progress(base + n)
        })?);
    }
    Ok(films)
}

/// The scene's pinhole camera as the light tracer's sensor.
fn pinhole(scene: &Scene, settings: &RenderSettings) -> Result<PinholeSensor, RenderError> {
    let camera = scene
        .camera
        .build(settings.width, settings.height)
        .map_err(RenderError::Settings)?;
    Ok(PinholeSensor {
        camera,
        width: settings.width,
        height: settings.height,
    })
}

/// Per-chunk accumulators: Σc, Σc², Σc³ and Σc⁴ per pixel and channel (the last two give
/// the variance estimate's own uncertainty, stats::MeanVar), the same per region.
struct ChunkSums {
    paths: u64,
    /// Paths cut by the path-length guard.
    cut: u64,
    /// [Σc, Σc², Σc³, Σc⁴ (6 channels each)] per pixel.
    pixels: Vec<[f64; 24]>,
    /// The same for the per-path region sums.
    regions: Vec<[f64; 24]>,
}

fn add_sample(acc: &mut [f64; 24], v: &[f64; 6]) {
    for c in 0..6 {
        let v2 = v[c] * v[c];
        acc[c] += v[c];
        acc[6 + c] += v2;
        acc[12 + c] += v2 * v[c];
        acc[18 + c] += v2 * v2;
    }
}

fn stats_of(paths: u64, acc: &[f64; 24]) -> [MeanVar; 6] {
    std::array::from_fn(|c| {
        MeanVar::from_power_sums(paths, [acc[c], acc[6 + c], acc[12 + c], acc[18 + c]])
    })
}

/// Light tracing with an explicit sensor (the pinhole of the scene for
/// [`render_light_paths`]; tests pass deliberately wrong ones) and exact statistics of the
/// region sums over `regions` ([x0, y0, x1, y1) pixel rectangles).
pub fn trace_light_image<S: Sensor>(
    scene: &Scene,
    settings: &RenderSettings,
    n_paths: u64,
    regions: &[[usize; 4]],
    sensor: &S,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<LightImage, RenderError> {
    let (mut pieces, cut) = light_blocks(
        scene,
        settings,
        n_paths,
        regions,
        sensor,
        0..CHUNKS,
        true,
        progress,
    )?;
    let (_, state) = pieces.pop().expect("a whole run is one piece");
    Ok(LightImage {
        film: Film {
            width: settings.width,
            height: settings.height,
            pixels: state.pixels,
            truncated_paths: cut,
        },
        regions: state.regions,
        paths: n_paths,
    })
}

/// Light-traces the chunks `chunks` (of [`CHUNKS`]) of a run of `n_paths` paths through the
/// scene's pinhole: one part of a sharded render with the exact state of its pieces. Merging
/// the parts of all chunks (film::partial::merge_files) gives [`render_light_paths`]'s film
/// bit for bit. The header's attributes are left empty for the caller.
pub fn render_light_part(
    scene: &Scene,
    settings: &RenderSettings,
    n_paths: u64,
    chunks: std::ops::Range<u64>,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<PartialFilm, RenderError> {
    if !(chunks.start < chunks.end && chunks.end <= CHUNKS) {
        return Err(RenderError::Settings(format!(
            "chunks {}..{} are not a non-empty part of a light-traced render's {CHUNKS} chunks",
            chunks.start, chunks.end
        )));
    }
    if n_paths < CHUNKS {
        return Err(RenderError::Settings(format!(
            "{n_paths} light paths cannot be split into parts; a sharded light-traced render needs at least {CHUNKS}"
        )));
    }
    let sensor = pinhole(scene, settings)?;
    let (pieces, cut) = light_blocks(
        scene,
        settings,
        n_paths,
        &[],
        &sensor,
        chunks,
        false,
        progress,
    )?;
    let bound = |c: u64| (c as u128 * n_paths as u128 / CHUNKS as u128) as u64;
    let pieces = pieces
        .into_iter()
        .map(|(span, st)| Piece {
            span,
            state: st.pixels,
        })
        .collect();
    Ok(PartialFilm::new(
        (settings.width, settings.height),
        CHUNKS,
        pieces,
        |s| bound(s.end()) - bound(s.start),
        cut,
        super::scene_fingerprint(scene),
    ))
}

/// A chunk range's state: pixel and region statistics.
struct LightState {
    pixels: Vec<Pixel>,
    regions: Vec<[MeanVar; 6]>,
}

/// The light tracer over chunks `chunks`: the part's pieces (one, the finished run, if
/// `whole`) and the count of cut paths.
#[allow(clippy::too_many_arguments)]
fn light_blocks<S: Sensor>(
    scene: &Scene,
    settings: &RenderSettings,
    n_paths: u64,
    regions: &[[usize; 4]],
    sensor: &S,
    chunks: std::ops::Range<u64>,
    whole: bool,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<(Vec<(Span, LightState)>, u64), RenderError> {
    check_common(settings)?;
    let (w, h) = (settings.width, settings.height);
    if sensor.resolution() != (w, h) {
        return Err(RenderError::Settings(format!(
            "the sensor is {:?} pixels but the settings ask for {w}x{h}",
            sensor.resolution()
        )));
    }
    if n_paths < 2 {
        return Err(RenderError::Settings(format!(
            "{n_paths} light paths; at least 2 are needed for a variance estimate"
        )));
    }
    if settings.sampler != Sampler::Independent {
        return Err(RenderError::Settings(format!(
            "sampler {:?} with the light tracer: its variance estimate treats light paths as independent samples, so only the independent sampler is allowed",
            settings.sampler.name()
        )));
    }
    if scene.has_media() {
        return Err(RenderError::Settings(
            "the scene has participating media: the light tracer handles surface scenes only; use the path tracer".into(),
        ));
    }
    if let Some(r) = regions
        .iter()
        .find(|r| !(r[0] < r[2] && r[1] < r[3] && r[2] <= w && r[3] <= h))
    {
        return Err(RenderError::Settings(format!(
            "region {r:?} is empty or does not fit the {w}x{h} image"
        )));
    }
    let pixels = (w * h + regions.len()) as u64;
    // (what other estimators running beside have reserved is not room)
    let room = crate::limits::memory_room().hard.map(|h| {
        h.saturating_sub(crate::limits::BASE_BYTES)
            .saturating_sub(super::reserved())
    });
    let Batch {
        max_batch,
        pending,
        in_flight,
        cap,
    } = batch(pixels, room);
    if max_batch == 0 {
        let gib = |b: u64| b as f64 / (1u64 << 30) as f64;
        let over = if cap < crate::limits::MAX_LIGHT_TRACER_BYTES {
            format!("the {:.1} GiB of memory this process may take (its address-space limit, its cgroup's memory.max, or the machine's memory and swap)", gib(cap))
        } else {
            format!(
                "the light tracer's {} GiB (limits::MAX_LIGHT_TRACER_BYTES)",
                crate::limits::MAX_LIGHT_TRACER_BYTES >> 30
            )
        };
        return Err(RenderError::Settings(format!(
            "a {w}x{h} light-traced image needs {:.1} GiB of film state, over {over}: render fewer pixels or use the path tracer",
            gib(pending + in_flight)
        )));
    }
    // the chunks in flight are as many as the threads, within the batch: reserved for the
    // whole render, so that estimators beside count them
    let threads = match settings.threads {
        0 => std::thread::available_parallelism().map_or(1, |n| n.get()),
        t => t,
    } as u64;
    let _reservation = super::reserve(
        &format!("the light tracer's film state for a {w}x{h} image"),
        pending.saturating_add(in_flight.saturating_mul(threads.clamp(1, max_batch))),
    )?;
    let grey = settings.is_grey(scene);
    let response = FilmResponse::new(&settings.observer, grey, settings.spectral.wavelengths);
    let tracer = LightTracer::from(&settings.integrator);
    let seed = mix64(settings.seed ^ LIGHT_STREAM);
    let done = AtomicU64::new(0);
    let out_of_time = AtomicBool::new(false);
    let start_time = std::time::Instant::now();
    let chunk = |c: u64| -> ChunkSums {
        // Paths [c·N/K, (c+1)·N/K): the split depends only on N and K.
        let bound = |c: u64| (c as u128 * n_paths as u128 / CHUNKS as u128) as u64;
        let (start, end) = (bound(c), bound(c + 1));
        let mut sums = ChunkSums {
            paths: end - start,
            cut: 0,
            pixels: vec![[0.0; 24]; w * h],
            regions: vec![[0.0; 24]; regions.len()],
        };
        let mut splats: Vec<Splat> = Vec::new();
        let mut merged: Vec<(usize, [f64; 6])> = Vec::new();
        let mut region_sum = vec![[0.0f64; 6]; regions.len()];
        let mut touched = vec![false; regions.len()];
        for i in start..end {
            if (i - start) % 1024 == 0
                && (out_of_time.load(Ordering::Relaxed)
                    || settings
                        .deadline
                        .is_some_and(|d| std::time::Instant::now() >= d))
            {
                out_of_time.store(true, Ordering::Relaxed);
                break;
            }
            let mut rng = SampleStream::new(seed, LIGHT_STREAM, i);
            let u_lambda = rng.next_f64();
            let mut wl = Wavelengths::for_film(u_lambda, settings.spectral.wavelengths, grey);
            splats.clear();
            sums.cut += u64::from(tracer.trace(scene, sensor, &mut wl, &mut rng, &mut splats));
            if splats.is_empty() {
                continue;
            }
            // The path's sample for each pixel is the sum of its splats there (square after summing).
            splats.sort_by_key(|s| s.pixel);
            merged.clear();
            // the matching functions looked up once for the path's splats
            let at_wl = response.at(&wl);
            for s in &splats {
                let xyz = at_wl.xyz(&s.value);
                let rgb = settings.observer.xyz_to_rgb(xyz);
                let v = [xyz[0], xyz[1], xyz[2], rgb[0], rgb[1], rgb[2]];
                match merged.last_mut() {
                    Some((p, acc)) if *p == s.pixel => {
                        for c in 0..6 {
                            acc[c] += v[c];
                        }
                    }
                    _ => merged.push((s.pixel, v)),
                }
            }
            for (p, v) in &merged {
                add_sample(&mut sums.pixels[*p], v);
                let (x, y) = (p % w, p / w);
                for (r, rect) in regions.iter().enumerate() {
                    if x >= rect[0] && x < rect[2] && y >= rect[1] && y < rect[3] {
                        touched[r] = true;
                        for c in 0..6 {
                            region_sum[r][c] += v[c];
                        }
                    }
                }
            }
            for r in 0..regions.len() {
                if touched[r] {
                    add_sample(&mut sums.regions[r], &region_sum[r]);
                    region_sum[r] = [0.0; 6];
                    touched[r] = false;
                }
            }
        }
        let n = done.fetch_add(sums.paths, Ordering::Relaxed) + sums.paths;
        progress(n);
        sums
    };
    let merge = |a: &mut LightState, b: &LightState| {
        crate::film::merge_pixels(&mut a.pixels, &b.pixels);
        for (r, q) in a.regions.iter_mut().zip(&b.regions) {
            for (m, o) in r.iter_mut().zip(q) {
                m.merge(o);
            }
        }
    };
    let work = || {
        // Chunks run a pool's width at a time (bounding memory to that many accumulators) and
        // are merged along the fixed tree of film::blocks in chunk order, so neither the batch
        // width nor a split into parts changes the result.
        let mut fold = BlockFold::new(chunks.start);
        let mut cut = 0;
        let batch = rayon::current_num_threads().clamp(1, max_batch as usize) as u64;
        let mut c0 = chunks.start;
        while c0 < chunks.end {
            let c1 = (c0 + batch).min(chunks.end);
            let results: Vec<(LightState, u64)> = (c0..c1)
                .into_par_iter()
                .map(|c| {
                    let r = chunk(c);
                    let state = LightState {
                        pixels: r
                            .pixels
                            .iter()
                            .map(|acc| {
                                Pixel::from_moments(
                                    r.paths,
                                    stats_of(r.paths, acc).map(|m| m.moments()),
                                )
                            })
                            .collect(),
                        regions: r.regions.iter().map(|acc| stats_of(r.paths, acc)).collect(),
                    };
                    (state, r.cut)
                })
                .collect();
            for (state, c) in results {
                cut += c;
                fold.push(state, &merge);
            }
            c0 = c1;
            if out_of_time.load(Ordering::Relaxed) {
                break;
            }
        }
        (fold, cut)
    };
    let (fold, cut) = in_pool(settings.threads, work)?;
    if out_of_time.load(Ordering::Relaxed) {
        return Err(RenderError::OutOfTime {
            seconds: start_time.elapsed().as_secs_f64(),
            done: done.load(Ordering::Relaxed),
            total: n_paths,
        });
    }
    let pieces = if whole {
        let all = fold.finish(&merge).expect("at least one chunk");
        vec![(span_all(), all)]
    } else {
        fold.into_pieces()
            .into_iter()
            .map(|p| (p.span, p.state))
            .collect()
    };
    Ok((pieces, cut))
}

/// Stand-in span of a whole run's single state.
fn span_all() -> Span {
    Span {
        start: 0,
        level: CHUNKS.trailing_zeros(),
    }
}

/// How many chunks may be in flight at once, and the memory behind that number (bytes).
struct Batch {
    /// Chunks in flight at most (0: not even one fits).
    max_batch: u64,
    /// The merge tree's pending nodes: at most log2(CHUNKS) + 1 images.
    pending: u64,
    /// One chunk in flight: its power sums and their conversion to a state.
    in_flight: u64,
    /// What the light tracer may take: its own cap, or the process's `room` where less.
    cap: u64,
}

/// The batch for an image of `pixels` (regions included) in `room` bytes (None: no limit
/// known). The batch width never changes the result, only the memory in use.
fn batch(pixels: u64, room: Option<u64>) -> Batch {
    let node = std::mem::size_of::<Pixel>() as u64 * pixels;
    let in_flight = (std::mem::size_of::<[f64; 24]>() as u64 * pixels).saturating_add(node);
    let pending = node.saturating_mul(CHUNKS.trailing_zeros() as u64 + 1);
    let cap = room.map_or(crate::limits::MAX_LIGHT_TRACER_BYTES, |r| {
        r.min(crate::limits::MAX_LIGHT_TRACER_BYTES)
    });
    Batch {
        max_batch: cap.saturating_sub(pending) / in_flight.max(1),
        pending,
        in_flight,
        cap,
    }
}

#[cfg(test)]
mod tests {
    /// Chunks in flight fill what the process may take, never more, and none fits below one.
    #[test]
    fn chunks_in_flight_fit_in_the_memory_the_process_may_take() {
        let b = batch(256 * 256, None);
        let cap = crate::limits::MAX_LIGHT_TRACER_BYTES;
        assert_eq!(b.cap, cap);
        assert!(b.pending + b.max_batch * b.in_flight <= cap);
        assert!(b.pending + (b.max_batch + 1) * b.in_flight > cap);
        // room for the pending nodes and two and a half chunks: two in flight
        let room = b.pending + 5 * b.in_flight / 2;
        let two = batch(256 * 256, Some(room));
        assert_eq!((two.cap, two.max_batch), (room, 2));
        // below the pending nodes and one chunk: none, which the render refuses by name
        assert_eq!(
            batch(256 * 256, Some(b.pending + b.in_flight - 1)).max_batch,
            0
        );
        // a process limit above the light tracer's own cap does not raise it
        assert_eq!(batch(256 * 256, Some(u64::MAX)).cap, cap);
    }

    use super::*;
    use crate::integrators::PathTracer;
    use crate::spectrum::N_WAVELENGTHS;
    use std::path::Path;

    #[test]
    fn light_runs_are_independent_images_of_their_share_of_the_paths() {
        let scene = scene_file("scenes/cornell-box.toml");
        let mut s = crate::render::test_settings(1);
        (s.width, s.height) = (8, 8);
        let films = render_light_runs(&scene, &s, 3001, 3, &|_| {}).unwrap();
        assert_eq!(films.len(), 3);
        // 1000, 1000 and 1001 paths: each pixel counts its run's paths
        let counts: Vec<u64> = films.iter().map(|f| f.pixels[0].count()).collect();
        assert_eq!(counts, [1000, 1000, 1001]);
        assert!(films[0].pixels != films[1].pixels);
        assert!(render_light_runs(&scene, &s, 5, 3, &|_| {}).is_err());
        assert!(render_light_runs(&scene, &s, 100, 1, &|_| {}).is_err());
    }

    fn scene_file(rel: &str) -> Scene {
        Scene::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)).unwrap()
    }

    fn settings(w: usize, h: usize, threads: usize, max_depth: Option<u32>) -> RenderSettings {
        RenderSettings {
            width: w,
            height: h,
            spp: 16,
            seed: 5,
            threads,
            integrator: PathTracer {
                max_depth,
                ..PathTracer::default()
            },
            observer: Default::default(),
            sampler: Sampler::Independent,
            spectral: Default::default(),
            deadline: None,
            crop: None,
        }
    }

    fn light_image(scene: &Scene, s: &RenderSettings, n: u64) -> LightImage {
        let sensor = PinholeSensor {
            camera: scene.camera.build(s.width, s.height).unwrap(),
            width: s.width,
            height: s.height,
        };
        trace_light_image(scene, s, n, &[[0, 0, s.width, s.height]], &sensor, &|_| {}).unwrap()
    }

    #[test]
    fn white_furnace_reads_e_over_one_minus_r_in_every_pixel() {
        // E = 1, R = 0.5, unlimited bounces: L = E/(1 − R) = 2 everywhere (scenes/furnace-sphere.toml).
        let scene = scene_file("scenes/furnace-sphere.toml");
        let s = settings(8, 8, 0, None);
        let img = light_image(&scene, &s, 400_000);
        let whole = img.regions[0][1];
        let n_px = 64.0;
        let (mean, se) = (whole.mean() / n_px, whole.std_error() / n_px);
        assert!((mean - 2.0).abs() < 4.5 * se && se < 0.01, "{mean} ± {se}");
        // every pixel within noise (a 4.5σ bound is a ~1e-5 false alarm per pixel)
        for (i, p) in img.film.pixels.iter().enumerate() {
            let m = p.channel(1);
            assert_eq!(m.count(), 400_000);
            assert!(
                (m.mean() - 2.0).abs() < 4.5 * m.std_error(),
                "pixel {i}: {m:?}"
            );
        }
        // with max_depth = 2: E(1 + R + R²) = 1.75
        let s = settings(8, 8, 0, Some(2));
        let whole = light_image(&scene, &s, 200_000).regions[0][1];
        let (mean, se) = (whole.mean() / n_px, whole.std_error() / n_px);
        assert!((mean - 1.75).abs() < 4.5 * se, "{mean} ± {se}");
    }

    #[test]
    fn a_light_traced_render_cut_into_parts_merges_to_the_same_bits() {
        use crate::render::tests::{film_bits, merge_in_memory};
        let scene = scene_file("scenes/cornell-box.toml");
        let s = settings(10, 10, 2, Some(3));
        let n = 3000;
        let whole = render_light_paths(&scene, &s, n, &|_| {}).unwrap();
        for n_parts in [1, 2, 3, 7] {
            let parts: Vec<PartialFilm> = (0..n_parts)
                .map(|k| {
                    let range = k * CHUNKS / n_parts..(k + 1) * CHUNKS / n_parts;
                    render_light_part(&scene, &s, n, range, &|_| {}).unwrap()
                })
                .collect();
            let paths: u64 = parts
                .iter()
                .flat_map(|p| p.header.pieces.iter().map(|x| x.2))
                .sum();
            assert_eq!(paths, n);
            let merged = Film {
                width: s.width,
                height: s.height,
                pixels: merge_in_memory(parts),
                truncated_paths: whole.truncated_paths,
            };
            assert_eq!(film_bits(&merged), film_bits(&whole), "{n_parts} parts");
        }
        let e = render_light_part(&scene, &s, 63, 0..1, &|_| {}).unwrap_err();
        assert!(e.to_string().contains("at least 64"), "{e}");
    }

    #[test]
    fn one_and_two_threads_give_the_same_bits() {
        let scene = scene_file("scenes/cornell-box.toml");
        let a = light_image(&scene, &settings(16, 16, 1, None), 20_000);
        let b = light_image(&scene, &settings(16, 16, 2, None), 20_000);
        assert!(a == b, "the image depends on the thread count");
        assert!(a.film.means(1).iter().any(|v| *v > 0.0));
        let c = light_image(&scene, &settings(16, 16, 2, None), 20_001);
        assert!(a != c);
    }

    #[test]
    fn region_variance_matches_replication_and_the_pixel_sum_does_not() {
        // One light path reaches several pixels (and a path that lands in one pixel does not land
        // in the others), so pixels are correlated and Var(region mean) ≠ Σ Var(pixel)/n². The
        // per-path region sums give it exactly; checked against the spread of independent
        // replicate renders. In the Cornell box the pixel sum overstates the whole-image
        // variance about 2× (the negative, multinomial-like covariance dominates).
        let scene = scene_file("scenes/cornell-box.toml");
        let reps = 200;
        let (mut exact, mut naive, mut sum, mut sum2) = (0.0, 0.0, 0.0, 0.0);
        for seed in 0..reps {
            let mut s = settings(16, 16, 0, None);
            s.seed = 1000 + seed;
            let img = light_image(&scene, &s, 2000);
            let r = img.regions[0][1];
            exact += r.variance() / r.count() as f64 / reps as f64;
            naive += img.film.mean_variances(1).iter().sum::<f64>() / reps as f64;
            let total: f64 = img.film.means(1).iter().sum();
            assert!((r.mean() - total).abs() <= 1e-9 * total);
            sum += total;
            sum2 += total * total;
        }
        let n = reps as f64;
        let empirical = (sum2 - sum * sum / n) / (n - 1.0);
        // 200 replicates: the empirical variance has a relative standard error of ~10 %.
        assert!(
            (empirical / exact - 1.0).abs() < 0.3,
            "replicates {empirical:.4e}, per-path region sums {exact:.4e}"
        );
        assert!(
            (empirical / naive - 1.0).abs() > 0.3,
            "replicates {empirical:.4e}, summed pixel variances {naive:.4e}"
        );
    }

    const TWO_LIGHTS: &str = r#"
[render]
width = 12
height = 12
[camera]
position = [0.0, 1.0, -3.0]
look_at = [0.0, 0.3, 0.0]
up = [0.0, 1.0, 0.0]
fov = 60.0
[materials.grey]
type = "diffuse"
reflectance = 0.6
[materials.red]
type = "diffuse"
reflectance = { wavelengths = [400.0, 550.0, 700.0], values = [0.1, 0.2, 0.8] }
[[shape]]
type = "quad"
corner = [-2.0, 0.0, -2.0]
edge_u = [0.0, 0.0, 4.0]
edge_v = [4.0, 0.0, 0.0]
material = "grey"
[[shape]]
type = "quad"
corner = [-2.0, 0.0, 1.5]
edge_u = [4.0, 0.0, 0.0]
edge_v = [0.0, 2.0, 0.0]
material = "red"
[[shape]]
type = "quad"
corner = [-0.4, 1.2, -0.4]
edge_u = [0.8, 0.0, 0.0]
edge_v = [0.0, 0.3, 0.8]
material = "grey"
emission = 3.0
two_sided = true
[[light]]
type = "point"
position = [0.8, 0.8, -0.5]
intensity = 2.0
"#;

    /// An environment light over a floor and a hovering plate, seen from above (every pixel
    /// sees a surface: the camera seeing the environment directly has no light-tracing
    /// estimate).
    const ENVIRONMENT: &str = r#"
[camera]
position = [0.0, 3.0, 0.0]
look_at = [0.0, 0.0, 0.01]
up = [0.0, 0.0, 1.0]
fov = 40.0
[materials.grey]
type = "diffuse"
reflectance = 0.6
[[shape]]
type = "quad"
corner = [-2.0, 0.0, -2.0]
edge_u = [0.0, 0.0, 4.0]
edge_v = [4.0, 0.0, 0.0]
material = "grey"
[[shape]]
type = "quad"
corner = [-0.3, 0.4, -0.3]
edge_u = [0.6, 0.0, 0.0]
edge_v = [0.0, 0.0, 0.6]
material = "grey"
[[light]]
type = "environment"
radiance = { blackbody = 4000.0, scale = 1e-3 }
"#;

    fn assert_path_and_light_agree(scene: &Scene, depths: &[Option<u32>], paths: u64) {
        assert_path_and_light_agree_in(scene, depths, paths, N_WAVELENGTHS)
    }

    fn assert_path_and_light_agree_in(
        scene: &Scene,
        depths: &[Option<u32>],
        paths: u64,
        lanes: usize,
    ) {
        for &depth in depths {
            let mut s = settings(12, 12, 0, depth);
            s.spp = 256;
            s.spectral.wavelengths = lanes;
            let pt = crate::render::render(scene, &s, &|_| {}).unwrap();
            let lt = light_image(scene, &s, paths);
            for c in [0usize, 1, 2] {
                let (m, v) = (pt.means(c), pt.mean_variances(c));
                let n = m.len() as f64;
                let (pm, pse) = (m.iter().sum::<f64>() / n, v.iter().sum::<f64>().sqrt() / n);
                let r = lt.regions[0][c];
                let (lm, lse) = (r.mean() / n, r.std_error() / n);
                let z = (pm - lm) / (pse * pse + lse * lse).sqrt();
                assert!(
                    z.abs() < 4.5,
                    "depth {depth:?} channel {c}: path {pm} ± {pse}, light {lm} ± {lse}"
                );
            }
        }
    }

    /// A rough N-BK7 ball (dispersive, GGX α 0.3) over a floor under a lamp: paths through the
    /// glass keep only their hero wavelength in both tracers.
    const DISPERSIVE: &str = r#"
[camera]
position = [0.0, 1.0, -3.0]
look_at = [0.0, 0.3, 0.0]
up = [0.0, 1.0, 0.0]
fov = 40.0
[materials.grey]
type = "diffuse"
reflectance = 0.6
[materials.glass]
type = "dielectric"
ior = "bk7"
alpha = 0.3
[[shape]]
type = "quad"
corner = [-2.0, 0.0, -2.0]
edge_u = [0.0, 0.0, 4.0]
edge_v = [4.0, 0.0, 0.0]
material = "grey"
[[shape]]
type = "sphere"
center = [0.0, 0.5, 0.0]
radius = 0.5
material = "glass"
[[shape]]
type = "quad"
corner = [-0.5, 2.0, -0.5]
edge_u = [1.0, 0.0, 0.0]
edge_v = [0.0, 0.0, 1.0]
material = "grey"
emission = { blackbody = 5000.0, scale = 1e-3 }
"#;

    #[test]
    fn light_and_path_tracer_agree_through_dispersive_glass() {
        let scene = Scene::parse(DISPERSIVE, Path::new("dispersive.toml")).unwrap();
        assert!(scene.bsdfs.iter().any(|b| b.separates_wavelengths()));
        assert_path_and_light_agree(&scene, &[Some(3)], 300_000);
        // and with the single-wavelength estimator (film weighting the hero alone)
        assert_path_and_light_agree_in(&scene, &[Some(3)], 300_000, 1);
    }

    #[test]
    fn light_and_path_tracer_agree_under_an_environment_light() {
        let scene = Scene::parse(ENVIRONMENT, Path::new("environment.toml")).unwrap();
        assert_path_and_light_agree(&scene, &[Some(1), Some(3)], 300_000);
    }

    #[test]
    fn light_and_path_tracer_agree_with_a_point_light_and_a_two_sided_emitter() {
        let scene = Scene::parse(TWO_LIGHTS, Path::new("two-lights.toml")).unwrap();
        assert_path_and_light_agree(&scene, &[Some(1), Some(3)], 300_000);
    }

    #[test]
    fn bad_settings_are_refused_with_reasons() {
        let s = settings(12, 12, 0, Some(2));
        let scene = Scene::parse(TWO_LIGHTS, Path::new("two-lights.toml")).unwrap();
        let e = render_light_paths(&scene, &s, 1, &|_| {})
            .unwrap_err()
            .to_string();
        assert!(e.contains("at least 2"), "{e}");
        let mut st = s.clone();
        st.sampler = Sampler::Sobol;
        let e = render_light_paths(&scene, &st, 100, &|_| {})
            .unwrap_err()
            .to_string();
        assert!(e.contains("independent"), "{e}");
        let foggy = format!(
            "{TWO_LIGHTS}\n[media.fog]\nsigma_a = 0.1\nsigma_s = 0.0\nphase = \"isotropic\"\n"
        );
        let mut scene = Scene::parse(&foggy, Path::new("fog.toml")).unwrap();
        scene.camera.medium = Some(0);
        let e = render_light_paths(&scene, &s, 100, &|_| {})
            .unwrap_err()
            .to_string();
        assert!(e.contains("participating media"), "{e}");
        // a film state past limits::MAX_LIGHT_TRACER_BYTES, refused before it is allocated
        let scene = Scene::parse(TWO_LIGHTS, Path::new("two-lights.toml")).unwrap();
        let e = render_light_paths(&scene, &settings(4096, 4096, 1, Some(2)), 100, &|_| {})
            .unwrap_err()
            .to_string();
        assert!(e.contains("GiB of film state"), "{e}");
    }
}
