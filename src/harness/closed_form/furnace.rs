//! What a furnace scene must read. Enclosure form: inside a closed diffuse enclosure whose
//! every surface emits E and reflects R, radiance is E/(1 − R) everywhere, and with at most D
//! bounces E(1 − R^(D+1))/(1 − R) (the Neumann series of the rendering equation, Kajiya 1986,
//! eq. 5, with a constant kernel). White-furnace form: a convex object of albedo R under a
//! uniform environment L reflects R·L. Lossless media leave a uniform isotropic field unchanged
//! (radiative transfer with σa = 0; Chandrasekhar 1960, *Radiative Transfer*, §1.5).

use super::footprint::per_pixel;
use super::footprint::Deadline;
use crate::harness::error::CheckError;
use crate::lights::Light;
use crate::scattering::Bsdf;
use crate::scene::Scene;
use crate::spectrum::Spectrum;

fn constant(s: &Spectrum, what: &str) -> Result<f64, CheckError> {
    match s {
        Spectrum::Constant(v) => Ok(*v),
        _ => Err(format!("a furnace scene needs constant spectra; {what} is not constant").into()),
    }
}

/// The closed-form radiance (Y) a furnace scene must show, with a description.
pub fn expectation(scene: &Scene, max_depth: Option<u32>) -> Result<(f64, String), CheckError> {
    if let Some(i) = scene.media.iter().position(|m| !m.is_lossless()) {
        return Err(format!(
            "medium {:?} absorbs (sigma_a is not 0): a furnace scene's media must only scatter, which leaves the uniform radiance unchanged",
            scene.medium_names[i]
        ).into());
    }
    if scene.has_media() && max_depth.is_some() {
        return Err(
            "media need unlimited depth: light may scatter any number of times before it leaves"
                .into(),
        );
    }
    let albedos: Vec<f64> = scene
        .bsdfs
        .iter()
        .map(|b| match b {
            Bsdf::Diffuse(l) => constant(&l.reflectance, "a reflectance"),
            // lossless at every wavelength: smooth glass (dispersive or not), a perfect mirror
            b if b.is_lossless() => Ok(1.0),
            _ => Err("a furnace scene needs Lambertian surfaces or lossless ones (a smooth dielectric with a constant index, a perfect smooth mirror); other models reflect a direction-dependent fraction".to_string().into()),
        })
        .collect::<Result<_, _>>()?;
    if max_depth.is_some() && scene.bsdfs.iter().any(|b| !matches!(b, Bsdf::Diffuse(_))) {
        return Err("lossless specular objects need unlimited depth: light may bounce inside them any number of times before it leaves".into());
    }
    let r = albedos
        .first()
        .copied()
        .ok_or("a furnace scene needs at least one shape")?;
    if albedos.iter().any(|a| *a != r) {
        return Err(format!(
            "every surface of a furnace scene must have the same albedo; found {albedos:?}"
        )
        .into());
    }
    let env: Vec<f64> = scene
        .lights
        .iter()
        .filter_map(|l| match l {
            Light::Environment { radiance } => Some(constant(radiance, "the environment radiance")),
            _ => None,
        })
        .collect::<Result<_, _>>()?;
    if scene
        .lights
        .iter()
        .any(|l| matches!(l, Light::Point { .. }))
    {
        return Err("a furnace scene may not have point lights".into());
    }
    if let Some(&l_env) = env.first() {
        if scene.lights.iter().any(|l| matches!(l, Light::Area { .. })) {
            return Err(
                "the white-furnace form takes an environment light and non-emitting objects only"
                    .into(),
            );
        }
        let expected = if max_depth == Some(0) { 0.0 } else { r * l_env };
        return Ok((expected, format!("white furnace: convex object of albedo {r} under environment {l_env}: expected R·L")));
    }
    let emissions: Vec<f64> = scene
        .shape_light
        .iter()
        .map(|l| match l.map(|i| &scene.lights[i as usize]) {
            Some(Light::Area { radiance, .. }) => constant(radiance, "an emission"),
            _ => Err("every surface of a furnace enclosure must emit".into()),
        })
        .collect::<Result<_, _>>()?;
    let e = emissions[0];
    if emissions.iter().any(|x| *x != e) {
        return Err(format!(
            "every surface of a furnace enclosure must emit the same radiance; found {emissions:?}"
        )
        .into());
    }
    match max_depth {
        Some(d) => {
            // E Σ_{k=0}^{D} R^k, summed directly so R = 1 is exact too
            let sum: f64 = (0..=d).map(|k| r.powi(k as i32)).sum();
            Ok((
                e * sum,
                format!(
                    "furnace enclosure E = {e}, R = {r}, D = {d}: expected E(1 − R^(D+1))/(1 − R)"
                ),
            ))
        }
        None if r < 1.0 => Ok((
            e / (1.0 - r),
            format!("furnace enclosure E = {e}, R = {r}: expected E/(1 − R)"),
        )),
        None => Err("R = 1 without a depth cap has no finite radiance".into()),
    }
}

/// Checks that the region sees what the closed form assumes: in the white-furnace form every
/// camera ray of the region hits the (single) object, unless every surface is lossless; in the enclosure form every ray hits a
/// surface whose emission faces the camera (no escaping rays, no back of a one-sided emitter),
/// and the enclosure is closed where light bounces (`max_depth`: the check's cap).
pub fn validate_view(
    scene: &Scene,
    width: usize,
    height: usize,
    region: [usize; 4],
    max_depth: Option<u32>,
    deadline: Deadline,
) -> Result<(), CheckError> {
    let white = scene
        .lights
        .iter()
        .any(|l| matches!(l, Light::Environment { .. }));
    // With every surface lossless (albedo 1) any arrangement reads L everywhere, escaping
    // rays included: each path ends in the environment with its full weight.
    let all_white = scene.bsdfs.iter().all(|b| match b {
        Bsdf::Diffuse(l) => l.reflectance == Spectrum::Constant(1.0),
        b => b.is_lossless(),
    });
    if white && all_white {
        return Ok(());
    }
    if white && scene.has_media() {
        return Err("the white-furnace form with media needs every surface lossless (null boundaries, smooth glass, perfect mirrors, white Lambertian): otherwise the radiance is not uniform".into());
    }
    if white && scene.aggregate.shapes().len() != 1 {
        return Err("the white-furnace form needs exactly one (convex) object unless every surface is lossless: others would be lit by its reflection".into());
    }
    let view = |hit: Option<&crate::geometry::Hit>, d: crate::math::Vec3| {
        let hit = hit.ok_or("a camera ray of the region escapes: the region must see only the object (white furnace) or the enclosure")?;
        if !white && !emits_towards(scene, hit, d) {
            return Err("a camera ray of the region meets a surface that does not emit towards the camera: is the enclosure closed, emitting inward, with the camera inside?".into());
        }
        Ok(0.0)
    };
    per_pixel(scene, width, height, region, &view, deadline)?;
    if white {
        return Ok(());
    }
    enclosed(scene, (width, height, region), max_depth, deadline)
}

/// Whether the surface `hit` by a ray along `d` emits back along it: an area light, two-sided
/// or facing the ray.
fn emits_towards(scene: &Scene, hit: &crate::geometry::Hit, d: crate::math::Vec3) -> bool {
    matches!(
        scene.shape_light[hit.shape as usize].map(|i| &scene.lights[i as usize]),
        Some(Light::Area { two_sided, .. }) if *two_sided || hit.point.n.dot(-d) > 0.0
    )
}

/// Camera rays per side of the region whose middles [`enclosed`] probes from.
const MIDDLES: usize = 4;

/// Directions probed from each middle by [`enclosed`].
const PROBES: usize = 512;

/// Checks that the enclosure is closed: from the middle of each of [`MIDDLES`]² camera rays
/// spread over the region (free space inside, whether or not the camera sits on a wall), rays
/// in [`PROBES`] directions all meet a surface that emits towards them. A gap the camera's own
/// rays miss (an open wall behind it) lets light leave: the scene reads less than the closed
/// form, and the check would fail for a reason that is not the renderer's. Where no light
/// bounces (`max_depth` 0, albedo 0) the closed form is E either way and nothing is probed.
/// The probes use the closed forms' own camera and caster, not the renderer's code, and stop
/// at `deadline`.
fn enclosed(
    scene: &Scene,
    (width, height, region): (usize, usize, [usize; 4]),
    max_depth: Option<u32>,
    deadline: Deadline,
) -> Result<(), CheckError> {
    use crate::math::{warp::fibonacci_sphere, Vec3};
    let black = scene
        .bsdfs
        .iter()
        .all(|b| matches!(b, Bsdf::Diffuse(l) if l.reflectance == Spectrum::Constant(0.0)));
    if max_depth == Some(0) || black {
        return Ok(());
    }
    let eye = super::witness::Eye::new(&scene.camera, width, height).map_err(CheckError::Setup)?;
    let caster = super::witness::Caster::new(scene.aggregate.shapes());
    let v = |a: Vec3| format!("[{:.3}, {:.3}, {:.3}]", a.x, a.y, a.z);
    let probe = |o: Vec3, d: Vec3| -> Result<f64, CheckError> {
        let ray = crate::geometry::Ray { o, d };
        let Some(hit) = caster.nearest_hit(&ray) else {
            return Err(format!("the enclosure is open: the ray from {} towards {} meets no surface, so light leaves and the scene reads less than the closed form; close the enclosure", v(o), v(d)).into());
        };
        if !emits_towards(scene, &hit, d) {
            return Err(format!("the ray from {} towards {} meets shape[{}] on a side that does not emit: every surface the enclosure's inside sees must emit towards it (emitting inward, with the camera inside)", v(o), v(d), hit.shape).into());
        }
        Ok(hit.t)
    };
    let [x0, y0, x1, y1] = region.map(|c| c as f64);
    for j in 0..MIDDLES {
        for i in 0..MIDDLES {
            if deadline.is_some_and(|d| std::time::Instant::now() >= d) {
                return Err(CheckError::Setup("the check's time limit passed while its scene was probed for a closed enclosure: give it a larger time_limit".into()));
            }
            let f = |k: usize| (k as f64 + 0.5) / MIDDLES as f64;
            let ray = eye.ray(x0 + (x1 - x0) * f(i), y0 + (y1 - y0) * f(j));
            let middle = ray.o + ray.d * (0.5 * probe(ray.o, ray.d)?);
            for k in 0..PROBES {
                probe(middle, fibonacci_sphere(k, PROBES))?;
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    fn box_scene(edit: impl Fn(&str) -> String) -> Scene {
        let p = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/manifests/scenes/furnace-box-0.5.toml");
        Scene::parse(&edit(&std::fs::read_to_string(&p).unwrap()), &p).unwrap()
    }

    // the wall z = 0, behind the camera (which looks towards +z): outside its view
    const BACK_WALL: &str =
        "corner = [0.0, 0.0, 0.0]\nedge_u = [1.0, 0.0, 0.0]\nedge_v = [0.0, 1.0, 0.0]";

    #[test]
    fn an_enclosure_open_or_emitting_outward_behind_the_camera_is_refused() {
        let closed = box_scene(str::to_string);
        validate_view(&closed, 8, 8, [3, 3, 5, 5], None, None).unwrap();
        // negative controls: the wall behind the camera gone, or turned to emit outward; the
        // camera's own rays see neither
        let open = box_scene(|t| {
            t.replace(
                BACK_WALL,
                "corner = [0.0, 0.0, -5.0]\nedge_u = [0.1, 0.0, 0.0]\nedge_v = [0.0, 0.1, 0.0]",
            )
        });
        let escapes = per_pixel(
            &open,
            8,
            8,
            [3, 3, 5, 5],
            &|h, _| Ok(h.map_or(1.0, |_| 0.0)),
            None,
        );
        assert_eq!(escapes.unwrap(), vec![0.0; 4], "the region sees the gap");
        let e = validate_view(&open, 8, 8, [3, 3, 5, 5], None, None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("the enclosure is open"), "{e}");
        let outward = box_scene(|t| {
            t.replace(
                BACK_WALL,
                "corner = [0.0, 0.0, 0.0]\nedge_u = [0.0, 1.0, 0.0]\nedge_v = [1.0, 0.0, 0.0]",
            )
        });
        let e = validate_view(&outward, 8, 8, [3, 3, 5, 5], None, None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("does not emit"), "{e}");
        // an open box where no light bounces reads E all the same; a closed one with the
        // camera on its back wall is closed
        validate_view(&open, 8, 8, [3, 3, 5, 5], Some(0), None).unwrap();
        let on_wall =
            box_scene(|t| t.replace("position = [0.3, 0.4, 0.2]", "position = [0.3, 0.4, 0.0]"));
        assert_eq!(on_wall.camera.position.z, 0.0);
        validate_view(&on_wall, 8, 8, [3, 3, 5, 5], None, None).unwrap();
        // the probes stop at the deadline
        let past = Some(std::time::Instant::now());
        let e = enclosed(&closed, (8, 8, [3, 3, 5, 5]), None, past).unwrap_err();
        assert!(
            e.to_string().contains("probed for a closed enclosure"),
            "{e}"
        );
    }
}
