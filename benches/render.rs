//! Criterion benchmarks of the renderer's hot paths and of one small Cornell Box frame.
//! Run: `cargo bench --bench render`. Throughput is reported in samples (or rays) per second.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use furnace::geometry::Ray;
use furnace::integrators::sppm::Sppm;
use furnace::integrators::PathTracer;
use furnace::math::{rng::SampleStream, warp, Vec3};
use furnace::render::{render, sppm::render_sppm, RenderSettings};
use furnace::scene::Scene;
use furnace::spectrum::Wavelengths;
use std::hint::black_box;
use std::path::Path;

fn cornell() -> Scene {
    Scene::load(Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/scenes/cornell-box.toml"
    )))
    .expect("bundled scene")
}

/// One Cornell Box frame at 64×64, 4 spp, at most 5 bounces (Mitsuba max_depth 6), 2 threads.
fn cornell_frame(c: &mut Criterion) {
    let scene = cornell();
    let settings = RenderSettings {
        width: 64,
        height: 64,
        spp: 4,
        seed: 1,
        threads: 2,
        integrator: PathTracer {
            max_depth: Some(5),
            ..PathTracer::default()
        },
        observer: Default::default(),
        sampler: Default::default(),
        spectral: Default::default(),
        deadline: None,
        crop: None,
    };
    let mut g = c.benchmark_group("cornell_frame");
    g.sample_size(20);
    g.throughput(Throughput::Elements(64 * 64 * 4));
    g.bench_function("64x64_4spp_depth5_2threads", |b| {
        b.iter(|| render(&scene, &settings, &|_| {}).unwrap())
    });
    // The same frame through the volumetric variant (no media in the scene: same image), to
    // measure what compiling the media code out of surface-only scenes saves.
    let mut with_media_code = settings.clone();
    with_media_code.integrator.force_media_code = true;
    g.bench_function("64x64_4spp_depth5_2threads_media_code", |b| {
        b.iter(|| render(&scene, &with_media_code, &|_| {}).unwrap())
    });
    g.finish();
}

/// Settings of a small frame: `w`², `spp`, unlimited depth (roulette from 5), 2 threads.
fn frame_settings(w: usize, spp: u64) -> RenderSettings {
    RenderSettings {
        width: w,
        height: w,
        spp,
        seed: 1,
        threads: 2,
        integrator: PathTracer::default(),
        observer: Default::default(),
        sampler: Default::default(),
        spectral: Default::default(),
        deadline: None,
        crop: None,
    }
}

/// SPPM on the Cornell Box as `sppm/cornell-box` renders it (32×32, 25 000 photons per
/// iteration), 4 iterations and 2 runs; and as `sppm/cornell-convergence` (500 photons per
/// iteration), 64 iterations and 2 runs (a run is the unit of SPPM's standard error).
fn sppm_frame(c: &mut Criterion) {
    let scene = cornell();
    let settings = frame_settings(32, 1);
    let mut g = c.benchmark_group("sppm_frame");
    g.sample_size(10);
    for (name, iterations, photons) in [
        ("32x32_25000_photons_4_iterations_2_runs", 4, 25_000),
        ("32x32_500_photons_64_iterations_2_runs", 64, 500),
    ] {
        let sppm = Sppm {
            iterations,
            photons_per_iteration: photons,
            ..Sppm::default()
        };
        g.throughput(Throughput::Elements(2 * iterations * photons));
        g.bench_function(name, |b| {
            b.iter(|| render_sppm(&scene, &settings, &sppm, 2, &|_| {}).unwrap())
        });
    }
    g.finish();
}

/// The furnace sphere at albedo 0.99 (about 100 bounces a path, one BVH primitive): 8×8,
/// 16 spp, 2 threads.
fn furnace_sphere_frame(c: &mut Criterion) {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/manifests/scenes/furnace-sphere.toml"
    );
    let text = std::fs::read_to_string(path)
        .expect("bundled template")
        .replace("${albedo}", "0.99");
    let scene = Scene::parse(&text, Path::new(path)).expect("bundled scene");
    let settings = frame_settings(8, 16);
    let mut g = c.benchmark_group("furnace_sphere_frame");
    g.sample_size(10);
    g.throughput(Throughput::Elements(8 * 8 * 16));
    g.bench_function("8x8_16spp_albedo_0.99_2threads", |b| {
        b.iter(|| render(&scene, &settings, &|_| {}).unwrap())
    });
    g.finish();
}

/// Closest-hit queries of rays from inside the box in uniformly random directions.
fn bvh_intersect(c: &mut Criterion) {
    let scene = cornell();
    let mut s = SampleStream::new(9, 0, 0);
    let rays: Vec<Ray> = (0..4096)
        .map(|_| Ray {
            o: Vec3::new(278.0, 273.0, 280.0),
            d: warp::uniform_sphere(s.next_2d()),
        })
        .collect();
    let mut g = c.benchmark_group("bvh");
    g.throughput(Throughput::Elements(rays.len() as u64));
    g.bench_function("cornell_closest_hit_4096_rays", |b| {
        b.iter(|| {
            rays.iter()
                .filter(|r| scene.aggregate.intersect(r, f64::INFINITY).is_some())
                .count()
        })
    });
    g.finish();
}

/// Sampling four hero wavelengths and evaluating a 76-entry measured reflectance at them.
fn spectrum_eval(c: &mut Criterion) {
    let scene = cornell();
    let furnace::scattering::Bsdf::Diffuse(white) = &scene.bsdfs[0] else {
        panic!("the Cornell floor is diffuse")
    };
    let mut g = c.benchmark_group("spectrum");
    g.throughput(Throughput::Elements(1024));
    g.bench_function("sample_wavelengths_and_eval_table_x1024", |b| {
        b.iter(|| {
            let mut acc = 0.0;
            for i in 0..1024 {
                let wl = Wavelengths::sample_visible((i as f64 + 0.5) / 1024.0);
                acc += white.reflectance.sample(black_box(&wl)).average();
            }
            acc
        })
    });
    g.finish();
}

/// BSDF sampling, evaluation and pdf of the Cornell white paint (local frame, four lanes).
fn bsdf_sample_eval(c: &mut Criterion) {
    use furnace::scattering::Bxdf;
    let scene = cornell();
    let furnace::scattering::Bsdf::Diffuse(white) = &scene.bsdfs[0] else {
        panic!("the Cornell floor is diffuse")
    };
    let wl = Wavelengths::sample_visible(0.37);
    let mut s = SampleStream::new(11, 0, 0);
    let cases: Vec<(Vec3, [f64; 2], f64)> = (0..1024)
        .map(|_| {
            let mut wo = warp::uniform_sphere(s.next_2d());
            wo.z = wo.z.abs().max(1e-3);
            (wo.normalize(), s.next_2d(), s.next_f64())
        })
        .collect();
    let mut g = c.benchmark_group("bsdf");
    g.throughput(Throughput::Elements(cases.len() as u64));
    g.bench_function("lambert_sample_eval_pdf_x1024", |b| {
        b.iter(|| {
            let mut acc = 0.0;
            for (wo, u, uc) in &cases {
                if let Some(smp) = white.sample(*wo, *u, *uc, &wl) {
                    acc += white.eval(*wo, smp.wi, &wl).average() + white.pdf(*wo, smp.wi, &wl);
                }
            }
            black_box(acc)
        })
    });
    g.finish();
}

/// BVH construction over hostile meshes (issue: coincident primitives made it quadratic):
/// 10^5 and 10^6 triangles all at one place, jittered by 1e-9 of the extent, and spread out.
fn bvh_build(c: &mut Criterion) {
    use furnace::geometry::{mesh::TriangleMesh, Aggregate, Shape};
    let mesh = |n: usize, kind: &str| {
        let mut s = SampleStream::new(5, 0, 0);
        let mut p = Vec::with_capacity(3 * n);
        for _ in 0..n {
            let (o, e) = match kind {
                "spread" => (
                    Vec3::new(s.next_f64(), s.next_f64(), s.next_f64()) * 100.0,
                    0.0,
                ),
                "near" => (Vec3::ZERO, 1e-9),
                _ => (Vec3::ZERO, 0.0),
            };
            let j = |s: &mut SampleStream| Vec3::new(s.next_f64(), s.next_f64(), s.next_f64()) * e;
            p.push(o + j(&mut s));
            p.push(o + Vec3::new(1.0, 0.0, 0.0) + j(&mut s));
            p.push(o + Vec3::new(0.0, 1.0, 0.0) + j(&mut s));
        }
        let tris = (0..n as u32)
            .map(|i| [3 * i, 3 * i + 1, 3 * i + 2])
            .collect();
        TriangleMesh::new(p, tris, false)
    };
    let mut g = c.benchmark_group("bvh_build");
    g.sample_size(10);
    for n in [100_000usize, 1_000_000] {
        for kind in ["coincident", "near", "spread"] {
            let m = mesh(n, kind);
            g.throughput(Throughput::Elements(n as u64));
            g.bench_function(format!("{kind}_{n}"), |b| {
                b.iter(|| black_box(Aggregate::new(vec![Shape::Mesh(m.clone())])))
            });
        }
    }
    g.finish();
}

/// A 512² Cornell film's twelve f32 channels (16 spp, 5 bounces) encoded as OpenEXR with each
/// lossless compression, in memory: what `io::image::write_exr`'s choice (RLE) trades against
/// ZIP and PIZ (docs/performance.md, "EXR files run-length encoded"). Prints each file's size,
/// and the sizes for a 1-spp film, whose variance channels are zero.
fn exr_compression(c: &mut Criterion) {
    use criterion::BatchSize;
    use exr::image::{AnyChannel, AnyChannels, Blocks, Encoding, FlatSamples, Image, Layer};
    use exr::meta::attribute::LineOrder;
    use exr::prelude::{Compression, WritableImage as _};
    let scene = cornell();
    let film = |spp| {
        let mut settings = frame_settings(512, spp);
        settings.integrator.max_depth = Some(5);
        render(&scene, &settings, &|_| {})
            .expect("render")
            .to_layers(Vec::new())
    };
    let (layers, one_spp) = (film(16), film(1));
    let size = (layers.width, layers.height);
    let encode = |channels: Vec<(String, Vec<f32>)>, compression: Compression| {
        let channels = channels
            .into_iter()
            .map(|(name, v)| AnyChannel::new(name.as_str(), FlatSamples::F32(v)))
            .collect();
        let encoding = Encoding {
            compression,
            blocks: Blocks::ScanLines,
            line_order: LineOrder::Increasing,
        };
        let layer = Layer::new(
            size,
            Default::default(),
            encoding,
            AnyChannels::sort(channels),
        );
        let mut bytes = std::io::Cursor::new(Vec::new());
        Image::from_layer(layer)
            .write()
            .to_buffered(&mut bytes)
            .expect("encode");
        bytes.into_inner().len()
    };
    let mut g = c.benchmark_group("exr_compression");
    g.sample_size(10);
    g.throughput(Throughput::Bytes((size.0 * size.1 * 12 * 4) as u64));
    for (name, compression) in [
        ("rle", Compression::RLE),
        ("zip16", Compression::ZIP16),
        ("piz", Compression::PIZ),
        ("uncompressed", Compression::Uncompressed),
    ] {
        println!(
            "exr_compression/{name}: {} bytes at 16 spp, {} bytes at 1 spp",
            encode(layers.channels.clone(), compression),
            encode(one_spp.channels.clone(), compression)
        );
        // the channels' copy is set-up, outside the timing
        g.bench_function(name, |b| {
            b.iter_batched(
                || layers.channels.clone(),
                |channels| encode(channels, compression),
                BatchSize::LargeInput,
            )
        });
    }
    g.finish();
}

criterion_group!(
    benches,
    exr_compression,
    bvh_build,
    cornell_frame,
    sppm_frame,
    furnace_sphere_frame,
    bvh_intersect,
    spectrum_eval,
    bsdf_sample_eval
);
criterion_main!(benches);
