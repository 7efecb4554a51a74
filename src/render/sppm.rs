//! The SPPM iteration loop (integrators::sppm has the camera and photon paths): visible points
//! in a uniform grid of cells as wide as the largest radius, photons in a fixed number of
//! chunks whose per-pixel sums are merged in chunk order (so the image is bit-identical for
//! any thread count), the radius update of Hachisuka & Jensen 2009 (eq. 6–9), and `runs`
//! independent runs whose spread gives each pixel's standard error (one run's pixels are
//! correlated across iterations, so a run is one sample).

use super::{FilmResponse, RenderError, RenderSettings};
use crate::film::Film;
use crate::integrators::sppm::{
    camera_path, trace_photon, unsupported, IterationBsdfs, Sppm, VisiblePoint,
};
use crate::math::rng::{run_seed, SampleStream};
use crate::math::Vec3;
use crate::scene::Scene;
use crate::spectrum::Wavelengths;
use rayon::prelude::*;

/// Photon chunks per iteration: the unit of parallel work and of the fixed merge order.
const CHUNKS: u64 = 16;

/// The radiance estimate from flux: (accumulated flux τ, photons emitted over the run, squared
/// radius) → τ/(N π r²) (Hachisuka & Jensen 2009, eq. 10). A parameter of
/// [`render_sppm_runs`] and [`render_sppm_radii`] so that a negative control can pass a wrong one.
pub type DensityEstimate = fn(tau: f64, photons: f64, r2: f64) -> f64;

/// τ/(N π r²): the flux over the emitted photons and the gather disc's area.
pub fn density(tau: f64, photons: f64, r2: f64) -> f64 {
    if tau == 0.0 {
        return 0.0; // no photon found: nothing gathered, whatever the radius
    }
    tau / (photons * std::f64::consts::PI * r2)
}

/// Renders `scene` by SPPM: `runs` independent runs (≥ 2 for a standard error), each
/// `sppm.iterations` iterations; each pixel's samples are the runs' estimates. The pixels of
/// one run share its photons and wavelengths, so a region's standard error must come from the
/// runs' region means ([`render_sppm_runs`]), not from the pixel variances.
pub fn render_sppm(
    scene: &Scene,
    settings: &RenderSettings,
    sppm: &Sppm,
    runs: u64,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<Film, RenderError> {
    render_sppm_each(scene, settings, sppm, runs, progress, &mut |_| {})
}

/// [`render_sppm`], handing each run's film to `each` (in run order) before it is merged, so
/// that a caller can keep what it needs of the runs without holding their films.
pub fn render_sppm_each(
    scene: &Scene,
    settings: &RenderSettings,
    sppm: &Sppm,
    runs: u64,
    progress: &(dyn Fn(u64) + Sync),
    each: &mut (dyn FnMut(&Film) + Send),
) -> Result<Film, RenderError> {
    let mut merged: Option<Film> = None;
    sppm_core(
        scene,
        settings,
        sppm,
        None,
        runs,
        density,
        progress,
        1,
        &mut |_, film| {
            each(&film);
            match &mut merged {
                None => merged = Some(film),
                Some(m) => m.merge(&film),
            }
        },
    )?;
    Ok(merged.expect("at least one run"))
}

/// The `runs` independent SPPM images (one sample per pixel each), with the density estimate
/// `estimate`.
pub fn render_sppm_runs(
    scene: &Scene,
    settings: &RenderSettings,
    sppm: &Sppm,
    runs: u64,
    estimate: DensityEstimate,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<Vec<Film>, RenderError> {
    let mut films = Vec::new();
    sppm_core(
        scene,
        settings,
        sppm,
        None,
        runs,
        estimate,
        progress,
        runs,
        &mut |_, f| films.push(f),
    )?;
    Ok(films)
}

/// Most initial radii [`render_sppm_radii`] renders in one pass.
pub const MAX_RADII: usize = 4;

/// [`render_sppm_runs`] at each initial radius of `radii` (`sppm.initial_radius` is ignored),
/// from the same camera and photon paths: per radius, its `runs` films, each bit-identical to
/// a render at that radius alone, for the cost of one camera and photon pass (the gathers are
/// per radius). A refinement study's images at r and r/2 then differ by the radius alone.
pub fn render_sppm_radii(
    scene: &Scene,
    settings: &RenderSettings,
    sppm: &Sppm,
    radii: &[f64],
    runs: u64,
    estimate: DensityEstimate,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<Vec<Vec<Film>>, RenderError> {
    let mut films: Vec<Vec<Film>> = radii.iter().map(|_| Vec::new()).collect();
    sppm_core(
        scene,
        settings,
        sppm,
        Some(radii),
        runs,
        estimate,
        progress,
        runs,
        &mut |k, f| films[k].push(f),
    )?;
    Ok(films)
}

/// Bytes of SPPM state per pixel besides the kept films: the photon chunks' sums and touched
/// lists, the visible point, its grid entry (40 bytes), the per-pixel statistics, the merged
/// sums and one run's film.
const BYTES_PER_PIXEL: u64 = CHUNKS * (32 + 4) + 600;

/// Memory SPPM may hold (its per-pixel state times the pixels), bytes.
pub const MAX_BYTES: u64 = 8 << 30;

/// The iteration loop at the initial radii `radii` (`None`: `sppm`'s own); `on_run` receives
/// each run's film at each radius (its index in `radii`), runs in order; `kept` films per radius
/// are held at once. The radii share each iteration's camera and photon paths (which do not
/// depend on the radius), so each radius's films are bit-identical to a render at that radius
/// alone.
#[allow(clippy::too_many_arguments)]
fn sppm_core(
    scene: &Scene,
    settings: &RenderSettings,
    sppm: &Sppm,
    radii: Option<&[f64]>,
    runs: u64,
    estimate: DensityEstimate,
    progress: &(dyn Fn(u64) + Sync),
    kept: u64,
    on_run: &mut (dyn FnMut(usize, Film) + Send),
) -> Result<(), RenderError> {
    if let Some(why) = unsupported(scene) {
        return Err(RenderError::Settings(format!(
            "SPPM cannot render this scene: {why}"
        )));
    }
    if sppm.iterations == 0 || sppm.photons_per_iteration == 0 || runs == 0 {
        return Err(RenderError::Settings(
            "SPPM needs at least one run, one iteration and one photon per iteration".into(),
        ));
    }
    if !(sppm.alpha > 0.0 && sppm.alpha <= 1.0) {
        return Err(RenderError::Settings(format!(
            "SPPM's alpha must be in (0, 1], got {}",
            sppm.alpha
        )));
    }
    let (w, h) = (settings.width, settings.height);
    crate::limits::image(w as u64, h as u64).map_err(|e| RenderError::Settings(e.to_string()))?;
    let own = [sppm.radius_in(scene)];
    let radii = radii.unwrap_or(&own);
    if radii.is_empty() || radii.len() > MAX_RADII {
        return Err(RenderError::Settings(format!(
            "SPPM renders 1 to {MAX_RADII} initial radii in one pass, got {}",
            radii.len()
        )));
    }
    let bytes = (w as u64 * h as u64)
        .saturating_mul(
            BYTES_PER_PIXEL + kept.saturating_mul(std::mem::size_of::<crate::film::Pixel>() as u64),
        )
        .saturating_mul(radii.len() as u64);
    if bytes > MAX_BYTES {
        return Err(RenderError::Settings(format!(
            "SPPM would hold {:.1} GiB of per-pixel state for a {w}x{h} image (about {} bytes a pixel); the limit is {} GiB: render a smaller image",
            bytes as f64 / (1u64 << 30) as f64,
            BYTES_PER_PIXEL,
            MAX_BYTES >> 30
        )));
    }
    // the state grows during the render: reserved for the whole of it
    let _reservation = super::reserve(
        &format!("SPPM's per-pixel state for a {w}x{h} image"),
        bytes,
    )?;
    let crop = settings.crop_rect()?;
    let camera = scene.camera.build(w, h).map_err(RenderError::Settings)?;
    if let Some(radius) = radii
        .iter()
        .find(|r| !(r.is_finite() && **r > 0.0 && (**r * **r).is_normal()))
    {
        return Err(RenderError::Settings(format!(
            "SPPM's initial radius must be a positive length whose square is a normal f64 (about 1.5e-154 to 1.3e154), got {radius:e}"
        )));
    }
    let grey = settings.is_grey(scene);
    let lanes = settings.spectral.wavelengths;
    let response = FilmResponse::new(&settings.observer, grey, lanes);
    let n = w * h;
    let start = std::time::Instant::now();
    let mut run_all = || -> Result<(), RenderError> {
        for run in 0..runs {
            let seed = run_seed(settings.seed, run, 0x5350_504d); // "SPPM"
            let mut states: Vec<State> = radii.iter().map(|&r| State::new(n, r)).collect();
            // emission seen by the camera paths, summed over iterations (XYZ): the same at
            // every radius
            let mut le = vec![[0.0; 3]; n];
            let mut truncated = 0u64;
            // per chunk, one set of sums per radius
            let mut sums: Vec<Vec<ChunkSums>> = (0..CHUNKS)
                .map(|_| radii.iter().map(|_| ChunkSums::new(n)).collect())
                .collect();
            let mut found = vec![[0.0; 4]; n];
            for it in 0..sppm.iterations {
                if settings
                    .deadline
                    .is_some_and(|d| std::time::Instant::now() >= d)
                {
                    return Err(RenderError::OutOfTime {
                        seconds: start.elapsed().as_secs_f64(),
                        done: run * sppm.iterations + it,
                        total: runs * sppm.iterations,
                    });
                }
                // one set of wavelengths per iteration, shared by its camera and photon paths,
                // stratified over the iterations (one stratum each, jittered): the run's
                // spectral integral is then a stratified quadrature, not `iterations` random
                // draws that would tint the whole image alike
                let jitter = SampleStream::new(seed, u64::MAX, it).next_f64();
                let u = (it as f64 + jitter) / sppm.iterations as f64;
                let wl = Wavelengths::for_film(u, lanes, grey);
                let bsdfs = IterationBsdfs::new(scene, &wl);
                let at_wl = response.at(&wl);
                let visible: Vec<([f64; 3], Option<VisiblePoint>)> = (0..n)
                    .into_par_iter()
                    .map(|px| {
                        if !super::in_rect(crop, px % w, px / w) {
                            // outside the crop: no visible point, so no photon is gathered
                            return ([0.0; 3], None);
                        }
                        let mut rng = SampleStream::new(seed, px as u64, it);
                        let [jx, jy] = rng.next_2d();
                        let (x, y) = ((px % w) as f64 + jx, (px / w) as f64 + jy);
                        let ray = camera.ray(x, y, w, h);
                        let (le, vp) = camera_path(scene, &bsdfs, ray, &wl, &mut rng);
                        (at_wl.xyz(&le), vp)
                    })
                    .collect();
                for (acc, (seen, _)) in le.iter_mut().zip(&visible) {
                    (0..3).for_each(|c| acc[c] += seen[c]);
                }
                let grids: Vec<Grid> = states.iter().map(|s| Grid::new(&visible, &s.r2)).collect();
                let photons = sppm.photons_per_iteration;
                let cuts: Vec<u64> = sums
                    .par_iter_mut()
                    .enumerate()
                    .map(|(c, acc)| {
                        let c = c as u64;
                        let part = |c: u64| (photons as u128 * c as u128 / CHUNKS as u128) as u64;
                        let mut cut = 0u64;
                        for k in part(c)..part(c + 1) {
                            let mut rng = SampleStream::new(seed ^ 0x5048_4f54, k, it);
                            cut += u64::from(trace_photon(
                                scene,
                                &bsdfs,
                                sppm,
                                &wl,
                                &mut rng,
                                &mut |hit| {
                                    // inside the radius; which sides count is the BSDF's to
                                    // say (a reflector's f is 0 across its surface, a
                                    // dielectric's BTDF gathers the photons arriving from inside)
                                    for (grid, acc) in grids.iter().zip(acc.iter_mut()) {
                                        grid.near(hit.p, |point| {
                                            let px = point.px as usize;
                                            let Some(vp) = &visible[px].1 else { return };
                                            let bsdf = bsdfs.at(scene, vp.shape, &wl);
                                            let f = bsdf.eval(vp.wo, vp.frame.to_local(hit.wi));
                                            let xyz = at_wl.xyz(&(vp.beta * f * hit.power));
                                            acc.add(px, xyz);
                                        });
                                    }
                                },
                            ));
                        }
                        cut
                    })
                    .collect();
                truncated += cuts.iter().sum::<u64>();
                for (k, state) in states.iter_mut().enumerate() {
                    found.fill([0.0; 4]);
                    for chunk in &mut sums {
                        chunk[k].drain_into(&mut found);
                    }
                    state.update(&found, sppm.alpha);
                }
                progress(run * sppm.iterations + it + 1);
            }
            let scale = 1.0 / sppm.iterations as f64;
            let emitted = sppm.iterations as f64 * sppm.photons_per_iteration as f64;
            for (k, state) in states.iter().enumerate() {
                let xyz = (0..n).map(|px| {
                    std::array::from_fn(|c| {
                        le[px][c] * scale + estimate(state.tau[px][c], emitted, state.r2[px])
                    })
                });
                let mut film = super::run_film(settings, xyz, truncated);
                for (px, pixel) in film.pixels.iter_mut().enumerate() {
                    if !super::in_rect(crop, px % w, px / w) {
                        *pixel = Default::default();
                    }
                }
                on_run(k, film);
            }
        }
        Ok(())
    };
    if settings.threads == 0 {
        run_all()?;
    } else {
        rayon::ThreadPoolBuilder::new()
            .num_threads(settings.threads)
            .build()
            .map_err(|e| RenderError::Threads {
                threads: settings.threads,
                message: e.to_string(),
            })?
            .install(run_all)?;
    }
    Ok(())
}

/// One photon chunk's sums per pixel (XYZ flux, photon count) and the pixels it touched, kept
/// across iterations so that an iteration of few photons neither allocates nor zeroes an image's
/// worth of sums per chunk, nor merges untouched pixels (adding a +0 sum changes no bit).
struct ChunkSums {
    acc: Vec<[f64; 4]>,
    touched: Vec<u32>,
}

impl ChunkSums {
    fn new(n: usize) -> Self {
        ChunkSums {
            acc: vec![[0.0; 4]; n],
            touched: Vec::new(),
        }
    }

    /// Adds one photon's XYZ flux to pixel `px`.
    #[inline]
    fn add(&mut self, px: usize, xyz: [f64; 3]) {
        let a = &mut self.acc[px];
        if a[3] == 0.0 {
            self.touched.push(px as u32);
        }
        (0..3).for_each(|i| a[i] += xyz[i]);
        a[3] += 1.0;
    }

    /// Adds the sums to `found` (chunks in chunk order, so each pixel's total has the same
    /// bits for any thread count) and clears them for the next iteration.
    fn drain_into(&mut self, found: &mut [[f64; 4]]) {
        for &px in &self.touched {
            let (f, a) = (&mut found[px as usize], &mut self.acc[px as usize]);
            (0..4).for_each(|i| f[i] += a[i]);
            *a = [0.0; 4];
        }
        self.touched.clear();
    }
}

/// Per-pixel SPPM statistics (Hachisuka & Jensen 2009, §3–4).
struct State {
    /// Squared radius, scene units².
    r2: Vec<f64>,
    /// Accumulated photon count N.
    count: Vec<f64>,
    /// Accumulated flux τ (XYZ).
    tau: Vec<[f64; 3]>,
}

impl State {
    fn new(n: usize, radius: f64) -> Self {
        State {
            r2: vec![radius * radius; n],
            count: vec![0.0; n],
            tau: vec![[0.0; 3]; n],
        }
    }

    /// N' = N + αM, R'² = R² (N + αM)/(N + M), τ' = (τ + Φ) R'²/R² (the paper's eq. 6–9).
    fn update(&mut self, found: &[[f64; 4]], alpha: f64) {
        for (px, f) in found.iter().enumerate() {
            let m = f[3];
            if m == 0.0 {
                continue;
            }
            let n_new = self.count[px] + alpha * m;
            let ratio = n_new / (self.count[px] + m);
            for (tau, flux) in self.tau[px].iter_mut().zip(f) {
                *tau = (*tau + flux) * ratio;
            }
            self.r2[px] *= ratio;
            self.count[px] = n_new;
        }
    }
}

/// Visible points in a uniform grid of cubic cells at least as wide as the largest radius
/// (and at least 1/∛(8n) of the n points' extent, at most 1/128 of it, so that the grid has no
/// more than about 8 cells per point and stays cheap to build each iteration), stored as one
/// list per cell (compressed rows) of each point's position, squared radius and pixel, so a
/// photon's search reads one contiguous run per cell: at most 2×2×2 cells, those that the box
/// of the largest radius around the photon overlaps.
struct Grid {
    lo: Vec3,
    cell: f64,
    dims: [i64; 3],
    /// The largest radius among the points, scene units.
    radius: f64,
    start: Vec<u32>,
    items: Vec<GridPoint>,
}

/// A visible point as the photon search reads it.
#[derive(Debug, Clone, Copy, Default)]
struct GridPoint {
    /// Its position (the visible point's, same bits), scene units.
    p: Vec3,
    /// Its pixel's squared radius, scene units².
    r2: f64,
    /// Its pixel.
    px: u32,
}

impl Grid {
    fn new(visible: &[([f64; 3], Option<VisiblePoint>)], r2: &[f64]) -> Self {
        let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
        for vp in visible.iter().filter_map(|v| v.1.as_ref()) {
            lo = lo.min(vp.point.p);
            hi = hi.max(vp.point.p);
        }
        if lo.x > hi.x {
            return Grid {
                lo: Vec3::ZERO,
                cell: 1.0,
                dims: [1; 3],
                radius: 0.0,
                start: vec![0, 0],
                items: vec![],
            };
        }
        // the largest radius among pixels with a visible point (the others never gather)
        let radius = visible
            .iter()
            .zip(r2)
            .filter(|(v, _)| v.1.is_some())
            .fold(0.0f64, |m, (_, &r2)| m.max(r2))
            .sqrt();
        let extent = (hi - lo).max_element();
        let points = visible.iter().filter(|v| v.1.is_some()).count();
        let divisions = (8.0 * points as f64).cbrt().clamp(1.0, 128.0);
        let cell = radius.max(extent / divisions).max(f64::MIN_POSITIVE);
        let dims = ((hi - lo) / cell).to_array().map(|d| d.floor() as i64 + 1);
        let mut this = Grid {
            lo,
            cell,
            dims,
            radius,
            start: vec![],
            items: vec![],
        };
        let members: Vec<(usize, GridPoint)> = visible
            .iter()
            .enumerate()
            .filter_map(|(px, v)| {
                let p = v.1.as_ref()?.point.p;
                let c = this
                    .index(this.coords(p))
                    .expect("a visible point lies in the grid");
                let (r2, px) = (r2[px], px as u32);
                Some((c, GridPoint { p, r2, px }))
            })
            .collect();
        let total = (dims[0] * dims[1] * dims[2]) as usize;
        let mut start = vec![0u32; total + 1];
        for &(c, _) in &members {
            start[c + 1] += 1;
        }
        for i in 0..total {
            start[i + 1] += start[i];
        }
        let mut fill = start.clone();
        let mut items = vec![GridPoint::default(); members.len()];
        for &(c, point) in &members {
            items[fill[c] as usize] = point;
            fill[c] += 1;
        }
        (this.start, this.items) = (start, items);
        this
    }

    fn coords(&self, p: Vec3) -> [i64; 3] {
        ((p - self.lo) / self.cell)
            .to_array()
            .map(|v| v.floor() as i64)
    }

    fn index(&self, c: [i64; 3]) -> Option<usize> {
        let inside = (0..3).all(|i| c[i] >= 0 && c[i] < self.dims[i]);
        inside.then(|| ((c[2] * self.dims[1] + c[1]) * self.dims[0] + c[0]) as usize)
    }

    /// Calls `each` with every point whose own radius reaches `p` (squared distance at most its
    /// r², computed as the gather always has), once each, cell by cell.
    fn near(&self, p: Vec3, mut each: impl FnMut(&GridPoint)) {
        // the cells the box p ± radius overlaps, padded for the rounding of the cell
        // coordinates (a few ulps of the coordinates involved): visiting a cell too many costs
        // a few distance tests, missing one would lose photons
        let slack = 8.0 * f64::EPSILON * (p.abs() + self.lo.abs() + self.radius);
        let reach = Vec3::splat(self.radius * (1.0 + 1e-9)) + slack;
        let (a, b) = (self.coords(p - reach), self.coords(p + reach));
        let range = |i: usize| a[i].max(0)..=b[i].min(self.dims[i] - 1);
        for z in range(2) {
            for y in range(1) {
                let row = (z * self.dims[1] + y) * self.dims[0];
                let xs = range(0);
                let (x0, x1) = (*xs.start(), *xs.end());
                if x0 > x1 {
                    continue;
                }
                // the cells of one row are adjacent in `start`: one contiguous run of points
                let first = self.start[(row + x0) as usize] as usize;
                let last = self.start[(row + x1 + 1) as usize] as usize;
                for point in &self.items[first..last] {
                    if (point.p - p).length_squared() <= point.r2 {
                        each(point);
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    fn settings(threads: usize) -> RenderSettings {
        crate::render::test_settings(threads)
    }

    #[test]
    fn the_image_does_not_depend_on_the_thread_count() {
        let scene = Scene::load(Path::new("scenes/cornell-box.toml")).unwrap();
        let sppm = Sppm {
            iterations: 2,
            photons_per_iteration: 3000,
            ..Default::default()
        };
        let a = render_sppm(&scene, &settings(1), &sppm, 2, &|_| {}).unwrap();
        let b = render_sppm(&scene, &settings(2), &sppm, 2, &|_| {}).unwrap();
        assert_eq!(a.pixels, b.pixels);
        assert!(a.pixels.iter().any(|p| p.channel(1).mean() > 0.0));
    }

    #[test]
    fn a_cropped_render_is_the_whole_render_inside_and_empty_outside() {
        let scene = Scene::load(Path::new("scenes/cornell-box.toml")).unwrap();
        let sppm = Sppm {
            iterations: 3,
            photons_per_iteration: 3000,
            ..Default::default()
        };
        let whole = render_sppm_runs(&scene, &settings(2), &sppm, 2, density, &|_| {}).unwrap();
        let crop = [2, 3, 7, 6];
        let s = RenderSettings {
            crop: Some(crop),
            ..settings(2)
        };
        let cropped = render_sppm_runs(&scene, &s, &sppm, 2, density, &|_| {}).unwrap();
        for (w, c) in whole.iter().zip(&cropped) {
            assert_eq!(c.rendered_pixels(), 15);
            assert_eq!(w.truncated_paths, c.truncated_paths);
            for (i, (a, b)) in w.pixels.iter().zip(&c.pixels).enumerate() {
                if crate::render::in_rect(crop, i % s.width, i / s.width) {
                    assert_eq!(a, b, "pixel {i}");
                } else {
                    assert_eq!(*b, Default::default(), "pixel {i} outside the crop");
                }
            }
        }
        assert!(cropped[0].pixels.iter().any(|p| p.channel(1).mean() > 0.0));
    }

    #[test]
    fn radii_in_one_pass_are_the_renders_at_each_radius_alone() {
        let scene = Scene::load(Path::new("scenes/cornell-box.toml")).unwrap();
        let sppm = Sppm {
            iterations: 3,
            photons_per_iteration: 3000,
            ..Default::default()
        };
        let r = sppm.radius_in(&scene);
        let radii = [r / 2.0, r, 3.0 * r];
        let together =
            render_sppm_radii(&scene, &settings(2), &sppm, &radii, 2, density, &|_| {}).unwrap();
        assert_eq!(together.len(), radii.len());
        for (films, &radius) in together.iter().zip(&radii) {
            let alone = Sppm {
                initial_radius: Some(radius),
                ..sppm
            };
            let alone = render_sppm_runs(&scene, &settings(1), &alone, 2, density, &|_| {});
            assert_eq!(films, &alone.unwrap(), "radius {radius}");
        }
        // the radii differ in the image, or the test above would prove nothing
        assert_ne!(together[0], together[2]);
        for bad in [
            &[][..],
            &[r; MAX_RADII + 1][..],
            &[r, -1.0][..],
            &[f64::NAN][..],
        ] {
            let e = render_sppm_radii(&scene, &settings(1), &sppm, bad, 2, density, &|_| {});
            assert!(e.is_err(), "{bad:?}");
        }
    }

    #[test]
    fn an_image_too_large_for_its_state_is_refused_before_allocating() {
        let scene = Scene::load(Path::new("scenes/cornell-box.toml")).unwrap();
        let mut s = settings(1);
        (s.width, s.height) = (4096, 4096);
        let e = render_sppm(&scene, &s, &Sppm::default(), 4, &|_| {}).unwrap_err();
        assert!(e.to_string().contains("GiB of per-pixel state"), "{e}");
    }

    #[test]
    fn media_and_environments_are_refused_by_name() {
        for (scene, says) in [
            ("scenes/hg-fog.toml", "participating media"),
            ("scenes/rayleigh-sky.toml", "participating media"),
            ("scenes/mesh-test.toml", "environment light"),
        ] {
            let scene = Scene::load(Path::new(scene)).unwrap();
            let sppm = Sppm::default();
            let e = render_sppm(&scene, &settings(1), &sppm, 2, &|_| {}).unwrap_err();
            assert!(e.to_string().contains(says), "{e}");
        }
    }
}
