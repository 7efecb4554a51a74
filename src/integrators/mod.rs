//! Light-transport estimators. The path tracer returns the radiance (W·sr⁻¹·m⁻²·nm⁻¹)
//! arriving at the camera along a ray, at the path's wavelengths; the light tracer returns a
//! light path's contributions to pixel measurements (the same units, per pixel).

pub mod bdpt;
pub mod light;
pub mod mlt;
pub mod path;
pub mod radiosity;
pub mod sppm;

pub use light::LightTracer;
pub use path::{power_heuristic, shadow_transmittance, PathTracer, Strategy};

use crate::lights::Light;
use crate::scattering::Bsdf;
use crate::scene::Scene;
use crate::spectrum::SampledSpectrum;

/// Spectra at one path's wavelengths, each evaluated on first use: the wavelengths are fixed
/// for the path, so next-event estimation at every vertex, emitters hit along the way and
/// every vertex on the same material reuse them. Keys below `N` are kept (a light's index,
/// a material's); larger ones are evaluated each time.
#[derive(Debug)]
pub(crate) struct PathSpectra<const N: usize> {
    values: [Option<SampledSpectrum>; N],
}

impl<const N: usize> Default for PathSpectra<N> {
    fn default() -> Self {
        PathSpectra { values: [None; N] }
    }
}

impl<const N: usize> PathSpectra<N> {
    /// The spectrum under `key`, from `eval` the first time.
    #[inline]
    pub(crate) fn get(
        &mut self,
        key: usize,
        eval: impl FnOnce() -> SampledSpectrum,
    ) -> SampledSpectrum {
        match self.values.get_mut(key) {
            Some(slot) => *slot.get_or_insert_with(eval),
            None => eval(),
        }
    }
}

/// Light spectra along a path, by light index.
pub(crate) type EmissionCache = PathSpectra<4>;

/// Lambertian reflectances along a path, by material index ([`Scene::material_of`]).
pub(crate) type ReflectanceCache = PathSpectra<8>;

/// `shape` when it is planar: a ray spawned from a point on it (its origin moved to the side
/// the ray runs to), or a shadow ray from a point off its plane ending on it (that end moved
/// to the ray's side), cannot meet it, so a query may skip it ([`crate::geometry::Skip`]; the
/// path tracer's argument, for BDPT, the light tracer and SPPM). A segment between two points
/// of one plane is the exception: `spawn_to` moves its ends to opposite sides of the plane
/// unless the segment lies exactly in it.
#[inline]
pub(crate) fn planar(scene: &Scene, shape: u32) -> Option<u32> {
    scene.aggregate.shapes()[shape as usize]
        .is_planar()
        .then_some(shape)
}

/// The planar shape of area light `light`, if it has one ([`planar`]).
#[inline]
pub(crate) fn emitter_plane(scene: &Scene, light: &Light) -> Option<u32> {
    match light {
        Light::Area { shape, .. } => planar(scene, *shape),
        _ => None,
    }
}

/// The path-length guard: events (surface hits, boundary crossings, medium scatterings) after
/// which a path is cut and counted as cut. A correct scene never comes near it (a furnace of
/// albedo 0.999 reaches it with probability 0.999^100000 ≈ e^-100); a path that would not end
/// (a lossless enclosure or medium, a roulette that never stops) does, and the render says so.
pub const MAX_PATH_EVENTS: u32 = 100_000;

/// Unbiased Russian roulette (Arvo & Kirk 1990, "Particle transport and image synthesis",
/// SIGGRAPH) with survival probability q = min(1, max β·η²), never capped below 1, so the
/// estimator keeps finite variance at albedo near 1; `eta_scale` (η² per lane, 1 outside
/// refractions) takes out the radiance scaling of the interfaces crossed, so a path in glass
/// is not killed for it. With uniform `u`, returns false when the path ends; a surviving
/// path's `beta` is divided by q.
#[inline]
pub fn roulette(beta: &mut SampledSpectrum, eta_scale: SampledSpectrum, u: f64) -> bool {
    let q = (*beta * eta_scale).max_component().min(1.0);
    if u >= q {
        return false;
    }
    *beta *= 1.0 / q;
    true
}

/// Why an estimator that scatters at surfaces only, with emission from the scene's own lights,
/// cannot render `scene` (SPPM and BDPT): media, a dispersive dielectric (refused when
/// `dispersion` gives the reason), a null boundary or an environment light; None otherwise.
pub fn surfaces_only(scene: &Scene, dispersion: Option<&str>) -> Option<String> {
    if scene.has_media() {
        return Some(
            "the scene has participating media (paths here scatter only at surfaces)".into(),
        );
    }
    if let (Some(why), Some(i)) = (
        dispersion,
        scene.bsdfs.iter().position(Bsdf::separates_wavelengths),
    ) {
        return Some(format!("shape {i} is dispersive ({why})"));
    }
    if scene.bsdfs.iter().any(Bsdf::is_null) {
        return Some("the scene has an index-matched (null) boundary".into());
    }
    if scene
        .lights
        .iter()
        .any(|l| matches!(l, Light::Environment { .. }))
    {
        return Some("the scene has an environment light (light paths would have to start on a disk beyond the scene; not modelled here)".into());
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_segment_between_two_points_of_one_tilted_plane_can_cross_it() {
        // why BDPT skips no shape when both ends of a connection lie on one plane: unless the
        // segment lies exactly in the plane, `spawn_to` moves its ends to opposite sides
        use crate::geometry::quad::Quad;
        use crate::geometry::{ray, Aggregate, Shape, Skip};
        use crate::math::Vec3;
        let quad = Quad {
            corner: Vec3::new(-0.7, 0.3, 1.9),
            edge_u: Vec3::new(1.3, 0.4, -0.2),
            edge_v: Vec3::new(-0.1, 0.9, 1.1),
            flip_normals: false,
        };
        let shapes = Aggregate::new(vec![Shape::Quad(quad.clone())]);
        let (mut crossed, mut pairs) = (0, 0);
        for i in 0..40 {
            for j in 0..40 {
                let u = |k: usize| (k as f64 * 0.618_034 + 0.1) % 1.0;
                let z = quad.sample([u(i), u(i + 7)]);
                let y = quad.sample([u(j + 13), u(j + 29)]);
                if z.p == y.p {
                    continue;
                }
                let (shadow, t_max) = ray::spawn_to(&z, &y);
                pairs += 1;
                crossed += usize::from(shapes.occluded_except(&shadow, t_max, Skip::NONE));
            }
        }
        assert!(crossed > 0, "no crossing among {pairs} pairs");
    }

    #[test]
    fn roulette_undoes_the_radiance_scaling_of_refraction() {
        // inside glass of index 1.5 a camera path carries 1/η² of its weight outside
        let inside = SampledSpectrum([1.0 / 2.25; 4]);
        let eta2 = SampledSpectrum([2.25; 4]);
        // with the scaling undone it survives for sure, its beta untouched ...
        let mut beta = inside;
        assert!(roulette(&mut beta, eta2, 0.99));
        assert_eq!(beta, inside);
        // ... without, it would die at u ≥ 1/2.25
        let mut beta = inside;
        assert!(!roulette(&mut beta, SampledSpectrum::ONE, 0.5));
        // and the estimate stays unbiased: E[beta after] = beta before, for q < 1
        let (mut sum, n) = (0.0, 100_000);
        for i in 0..n {
            let mut b = SampledSpectrum([0.1; 4]);
            if roulette(&mut b, eta2, (i as f64 + 0.5) / n as f64) {
                sum += b.0[0];
            }
        }
        assert!((sum / n as f64 - 0.1).abs() < 1e-9, "{}", sum / n as f64);
    }
}
