//! Reference renders shared by the checks of one run: where several checks compare an
//! estimator against the same path-traced image (the same scene and settings), it is rendered
//! once. Its seed comes from the run's seed and what is rendered, never from a check, so a
//! check's numbers are the same whether the image came from the store or was rendered for it
//! alone (past the memory cap it is). Closed forms computed per pixel (a convergence
//! ladder's reference) are kept the same way: they depend on no seed.

use super::error::CheckError;
use super::renderer::{Renderer, RendererError};
use crate::film::Film;
use crate::math::rng::mix64;
use crate::render::RenderSettings;
use crate::scene::Scene;
use std::collections::HashMap;
use std::fmt::Write;
use std::sync::{Arc, Mutex, PoisonError};

/// Most pixels the store keeps over a run (200 bytes each: 50 MiB); a film that would
/// pass it is rendered for its check alone, with the same seed.
pub const MAX_STORED_PIXELS: usize = 1 << 18;

/// Most closed-form values the store keeps over a run (8 MiB); past it a closed form is
/// computed for its check alone.
pub const MAX_STORED_VALUES: usize = 1 << 20;

/// One request's value once made (None while the first asker makes it, or after it failed:
/// the next asker makes it again).
type Slot<T> = Arc<Mutex<Option<Arc<T>>>>;

/// Values kept by request over a run, each made once: the first asker makes it while later
/// ones wait for it, a failure is not kept, and a value that would take the units kept past
/// `cap` is made for its asker alone.
#[derive(Debug)]
struct Kept<T> {
    slots: Mutex<HashMap<String, Slot<T>>>,
    /// Units (pixels, values) kept.
    stored: Mutex<usize>,
    cap: usize,
}

impl<T> Kept<T> {
    fn new(cap: usize) -> Self {
        Kept {
            slots: Mutex::new(HashMap::new()),
            stored: Mutex::new(0),
            cap,
        }
    }

    /// The value under `key`, from `make` the first time; `units` is what it takes of the cap.
    fn get<E>(
        &self,
        key: String,
        make: impl FnOnce() -> Result<T, E>,
        units: impl FnOnce(&T) -> usize,
    ) -> Result<Arc<T>, E> {
        let slot = {
            let mut slots = self.slots.lock().unwrap_or_else(PoisonError::into_inner);
            slots.entry(key).or_default().clone()
        };
        let mut kept = slot.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some(v) = kept.as_ref() {
            return Ok(v.clone());
        }
        let made = Arc::new(make()?);
        let n = units(&made);
        let mut stored = self.stored.lock().unwrap_or_else(PoisonError::into_inner);
        if stored.saturating_add(n) <= self.cap {
            *stored += n;
            *kept = Some(made.clone());
        }
        Ok(made)
    }
}

/// One run's store of shared reference images and closed-form values.
#[derive(Debug)]
pub struct SharedRenders {
    run_seed: u64,
    /// Films by request, counted in pixels.
    films: Kept<Film>,
    /// Closed-form values by request, counted in values.
    values: Kept<Vec<f64>>,
}

impl SharedRenders {
    /// An empty store for a run with seed `run_seed`.
    pub fn new(run_seed: u64) -> Self {
        SharedRenders {
            run_seed,
            films: Kept::new(MAX_STORED_PIXELS),
            values: Kept::new(MAX_STORED_VALUES),
        }
    }

    /// The values `compute` gives for `request` (which names the closed form and everything
    /// it depends on but the scene) on `scene`: computed once per run and request, so the
    /// checks asking for it get the same values; a failed computation is not kept.
    pub fn closed_form(
        &self,
        scene: &Scene,
        request: &str,
        compute: impl FnOnce() -> Result<Vec<f64>, CheckError>,
    ) -> Result<Arc<Vec<f64>>, CheckError> {
        let key = format!("{request}\n{}", crate::render::scene_fingerprint(scene));
        self.values.get(key, compute, Vec::len)
    }

    /// `renderer`'s image of `scene` with `settings`, whose seed is replaced by one derived
    /// from the run's seed and the rest of the request (renderer, scene, settings but threads
    /// and deadline): every check asking for it gets the same film, rendered once. A failed
    /// render is not kept.
    pub fn render(
        &self,
        renderer: &dyn Renderer,
        scene: &Scene,
        settings: &RenderSettings,
    ) -> Result<Arc<Film>, RendererError> {
        let (key, seed) = self.key(renderer, scene, settings);
        let s = RenderSettings {
            seed,
            ..settings.clone()
        };
        let pixels = s.width.saturating_mul(s.height);
        self.films
            .get(key, || renderer.render(scene, &s), |_| pixels)
    }

    /// The request's key and the seed it is rendered with.
    fn key(
        &self,
        renderer: &dyn Renderer,
        scene: &Scene,
        settings: &RenderSettings,
    ) -> (String, u64) {
        let request = RenderSettings {
            seed: 0,
            threads: 0,
            deadline: None,
            ..settings.clone()
        };
        let mut key = String::new();
        write!(
            key,
            "{}\n{}\n{request:?}",
            renderer.name(),
            crate::render::scene_fingerprint(scene)
        )
        .expect("writing to a String cannot fail");
        let mut h = crate::math::Fnv1a::default();
        h.eat(key.as_bytes());
        (key, mix64(self.run_seed ^ mix64(h.0)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::harness::BuiltIn;
    use std::path::Path;

    fn settings(seed: u64) -> RenderSettings {
        RenderSettings {
            width: 6,
            height: 6,
            spp: 8,
            seed,
            threads: 1,
            ..crate::render::test_settings(1)
        }
    }

    #[test]
    fn one_film_per_request_whatever_the_asking_seed_and_the_same_rendered_alone() {
        let scene = Scene::load(Path::new("scenes/cornell-box.toml")).unwrap();
        let store = SharedRenders::new(7);
        let a = store.render(&BuiltIn, &scene, &settings(1)).unwrap();
        let b = store.render(&BuiltIn, &scene, &settings(2)).unwrap();
        assert!(Arc::ptr_eq(&a, &b), "rendered twice");
        // a fresh store (nothing kept) renders the same bits
        let c = SharedRenders::new(7)
            .render(&BuiltIn, &scene, &settings(3))
            .unwrap();
        assert_eq!(*a, *c);
        // another run seed, or other settings, another film
        let d = SharedRenders::new(8)
            .render(&BuiltIn, &scene, &settings(1))
            .unwrap();
        assert_ne!(*a, *d);
        let more = RenderSettings {
            spp: 9,
            ..settings(1)
        };
        let e = store.render(&BuiltIn, &scene, &more).unwrap();
        assert!(!Arc::ptr_eq(&a, &e));
        assert_eq!(*store.films.stored.lock().unwrap(), 72);
    }

    #[test]
    fn past_the_cap_films_are_rendered_alone_and_failures_are_not_kept() {
        let scene = Scene::load(Path::new("scenes/cornell-box.toml")).unwrap();
        let store = SharedRenders::new(7);
        *store.films.stored.lock().unwrap() = MAX_STORED_PIXELS - 10;
        let a = store.render(&BuiltIn, &scene, &settings(1)).unwrap();
        let b = store.render(&BuiltIn, &scene, &settings(1)).unwrap();
        assert!(!Arc::ptr_eq(&a, &b), "kept past the cap");
        assert_eq!(*a, *b);
        let past = RenderSettings {
            deadline: Some(std::time::Instant::now()),
            ..settings(1)
        };
        let fresh = SharedRenders::new(7);
        assert!(fresh.render(&BuiltIn, &scene, &past).is_err());
        let ok = fresh.render(&BuiltIn, &scene, &settings(1)).unwrap();
        assert_eq!(*ok, *a);
    }

    #[test]
    fn a_closed_form_is_computed_once_per_request_and_scene_and_failures_are_not_kept() {
        let scene = Scene::load(Path::new("scenes/cornell-box.toml")).unwrap();
        let other = Scene::load(Path::new("scenes/cornell-glossy.toml")).unwrap();
        let store = SharedRenders::new(7);
        let calls = std::cell::Cell::new(0);
        let compute = || {
            calls.set(calls.get() + 1);
            Ok(vec![1.0, 2.0])
        };
        let a = store.closed_form(&scene, "r", compute).unwrap();
        let b = store.closed_form(&scene, "r", compute).unwrap();
        assert!(Arc::ptr_eq(&a, &b));
        assert_eq!(calls.get(), 1);
        // another request or another scene is computed anew
        store.closed_form(&scene, "s", compute).unwrap();
        store.closed_form(&other, "r", compute).unwrap();
        assert_eq!(calls.get(), 3);
        // a failure is passed on and not kept
        let failed = store.closed_form(&scene, "t", || Err(CheckError::Setup("no".into())));
        assert!(failed.is_err());
        assert_eq!(
            *store.closed_form(&scene, "t", compute).unwrap(),
            vec![1.0, 2.0]
        );
        // past the cap the values are computed for the asker alone
        *store.values.stored.lock().unwrap() = MAX_STORED_VALUES - 1;
        let c = store.closed_form(&scene, "u", compute).unwrap();
        let d = store.closed_form(&scene, "u", compute).unwrap();
        assert!(!Arc::ptr_eq(&c, &d));
        assert_eq!(c, d);
    }
}
