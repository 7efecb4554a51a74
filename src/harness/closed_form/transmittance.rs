//! Beer–Lambert transmittance along camera rays: emission seen through purely absorbing media
//! is attenuated by exp(−Σ σa,i(λ) dᵢ) over the medium segments dᵢ (Bouguer 1729; Lambert
//! 1760; Beer 1852 — the radiative transfer equation without scattering or emission,
//! Chandrasekhar 1960, *Radiative Transfer*, §1.4), integrated against ȳ at 1 nm. The
//! segments come from the closed forms' own caster and boundary rule (`witness`), not the
//! tracer's.

use super::footprint::Deadline;
use super::footprint::{per_pixel_rays, FOOTPRINT_K};
use super::witness;
use crate::geometry::Ray;
use crate::harness::CheckError;
use crate::lights::Light;
use crate::scene::Scene;
use crate::spectrum::{cie, Spectrum};

/// A scene's spectra on the colour-matching table's rows ([`cie::CieTables::grid_lambda`]),
/// evaluated once for a check rather than at every wavelength of every ray: each light's
/// [`Light::spectrum`] and each medium's σa.
pub struct OnGrid {
    lights: Vec<Vec<f64>>,
    sigma_a: Vec<Vec<f64>>,
}

impl OnGrid {
    /// The spectra of `scene`.
    pub fn new(scene: &Scene) -> OnGrid {
        let rows = |s: &Spectrum| -> Vec<f64> {
            (0..cie::tables().grid_len())
                .map(|i| s.eval(cie::CieTables::grid_lambda(i)))
                .collect()
        };
        OnGrid {
            lights: scene.lights.iter().map(|l| rows(l.spectrum())).collect(),
            sigma_a: scene.media.iter().map(|m| rows(&m.sigma_a)).collect(),
        }
    }
}

/// Y of the radiance arriving along `camera_ray` (starting in the camera's medium): every
/// emitter met through null boundaries and finally the first other surface or the environment,
/// each attenuated by the absorbing segments before it. A ray with no surface ahead has left
/// every medium (as in the path tracer). `grid`: the scene's spectra ([`OnGrid::new`]).
pub fn along(
    scene: &Scene,
    caster: &witness::Caster,
    grid: &OnGrid,
    camera_ray: Ray,
) -> Result<f64, CheckError> {
    let mut path: Vec<(u32, f64)> = Vec::new();
    // (emitting light, number of path segments in front of it)
    let mut sources: Vec<(usize, usize)> = Vec::new();
    let mut medium = scene.camera.medium;
    let r = camera_ray;
    // Every crossing along the camera ray's line, from the closed forms' own caster
    // (closed_form::witness), with media tracked by the boundary rule, not the tracer's code.
    let hits = caster.hits_along(&r);
    let mut next = hits.iter();
    let mut t_last = 0.0;
    loop {
        let hit = next.next().copied();
        if let (Some(m), Some(h)) = (medium, hit.as_ref()) {
            if !scene.media[m as usize].absorbs_only() {
                return Err(format!(
                    "medium {:?} scatters; the transmittance kind needs purely absorbing media (sigma_s = 0)",
                    scene.medium_names[m as usize]
                ).into());
            }
            path.push((m, h.t - t_last));
        }
        let Some(h) = hit else {
            if let Some(env) = scene
                .lights
                .iter()
                .position(|l| matches!(l, Light::Environment { .. }))
            {
                sources.push((env, path.len()));
            }
            break;
        };
        if let Some(li) = scene.shape_light[h.shape as usize] {
            if let Light::Area { two_sided, .. } = &scene.lights[li as usize] {
                if *two_sided || h.point.n.dot(-r.d) > 0.0 {
                    sources.push((li as usize, path.len()));
                }
            }
        }
        if !scene.bsdfs[h.shape as usize].is_null() {
            break;
        }
        medium = witness::medium_beyond(
            scene.shape_media.get(h.shape as usize).copied().flatten(),
            h.point.n,
            r.d,
            medium,
        );
        t_last = h.t;
    }
    Ok(cie::tables().grid_to_xyz(|i| {
        sources
            .iter()
            .map(|&(li, n)| {
                let tau: f64 = path[..n]
                    .iter()
                    .map(|&(m, d)| grid.sigma_a[m as usize][i] * d)
                    .sum();
                grid.lights[li][i] * (-tau).exp()
            })
            .sum()
    })[1])
}

/// The expected Y of each pixel of `region` (x0, y0, x1, y1) of a `width`×`height` render of
/// `scene` with emission only, averaged over each pixel's footprint, and their mean.
pub fn expectation(
    scene: &Scene,
    width: usize,
    height: usize,
    region: [usize; 4],
    deadline: Deadline,
) -> Result<(f64, Vec<f64>), CheckError> {
    let caster = witness::Caster::new(scene.aggregate.shapes());
    let grid = OnGrid::new(scene);
    let px = per_pixel_rays(
        scene,
        width,
        height,
        region,
        &|r| along(scene, &caster, &grid, r),
        FOOTPRINT_K,
        deadline,
    )?;
    let expected = px.iter().sum::<f64>() / px.len() as f64;
    Ok((expected, px))
}
