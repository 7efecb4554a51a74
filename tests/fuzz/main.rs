//! Fuzzing of every parser on stable Rust: a mutational generator (seeded, deterministic) over
//! the corpus in `tests/fuzz/corpus/` and the bundled inputs, fed to the scene, manifest, OBJ,
//! PLY, CSV, EXR and renderer-table parsers. Each input must give a value or a named error:
//! no panic, and no allocation beyond `PEAK_LIMIT` (a counting allocator watches the peak).
//!
//! `cargo test --release --test fuzz` runs a short round (a few seconds per parser); the long
//! run is `FURNACE_FUZZ_SECONDS=1800 cargo test --release --test fuzz -- --nocapture`, which
//! divides the time among the parsers and saves any failing input to `tests/fuzz/crashes/`.

use std::alloc::{GlobalAlloc, Layout, System};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

/// Counts live bytes and their peak.
struct Counting;

static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        let p = unsafe { System.alloc(l) };
        if !p.is_null() {
            let now = LIVE.fetch_add(l.size(), Ordering::Relaxed) + l.size();
            PEAK.fetch_max(now, Ordering::Relaxed);
        }
        p
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        unsafe { System.dealloc(p, l) };
        LIVE.fetch_sub(l.size(), Ordering::Relaxed);
    }
    unsafe fn realloc(&self, p: *mut u8, l: Layout, new: usize) -> *mut u8 {
        let q = unsafe { System.realloc(p, l, new) };
        if !q.is_null() {
            if new > l.size() {
                let now = LIVE.fetch_add(new - l.size(), Ordering::Relaxed) + new - l.size();
                PEAK.fetch_max(now, Ordering::Relaxed);
            } else {
                LIVE.fetch_sub(l.size() - new, Ordering::Relaxed);
            }
        }
        q
    }
}

#[global_allocator]
static ALLOC: Counting = Counting;

/// Most bytes one parse may hold at once: far above any seed's needs, far below the machine's.
const PEAK_LIMIT: usize = 1 << 30;

fn root(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(rel)
}

/// splitmix64: the generator's only randomness, so a run is reproducible from its seed.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

/// Tokens that parsers treat specially, spliced into inputs.
const TOKENS: [&[u8]; 32] = [
    b"[",
    b"]",
    b"=",
    b"\"",
    b"{",
    b"}",
    b",",
    b"\n",
    b"#",
    b"[[shape]]",
    b"[[check]]",
    b"1e308",
    b"-1e308",
    b"nan",
    b"inf",
    b"-0",
    b"0",
    b"1",
    b"-1",
    b"4294967296",
    b"9223372036854775807",
    b"1e-320",
    b"${x}",
    b"vary = { x = [1, 2] }",
    b"\xff\xfe",
    b"v 0 0 0\n",
    b"f 1 2 3\n",
    b"f -1 -2 -3\n",
    b"element vertex 4294967295\n",
    b"property list uchar int vertex_indices\n",
    b"format binary_little_endian 1.0\n",
    b"\0",
];

/// One random edit of `input`.
fn mutate(rng: &mut Rng, input: &[u8]) -> Vec<u8> {
    let mut v = input.to_vec();
    for _ in 0..1 + rng.below(4) {
        let at = rng.below(v.len() + 1);
        match rng.below(6) {
            0 if !v.is_empty() => {
                let i = rng.below(v.len());
                v[i] ^= 1 << rng.below(8);
            }
            1 => {
                let t = TOKENS[rng.below(TOKENS.len())];
                v.splice(at..at, t.iter().copied());
            }
            2 if !v.is_empty() => {
                let end = (at + 1 + rng.below(64)).min(v.len());
                v.drain(at.min(end)..end);
            }
            3 if !v.is_empty() => {
                let start = rng.below(v.len());
                let end = (start + 1 + rng.below(256)).min(v.len());
                let piece = v[start..end].to_vec();
                for _ in 0..1 + rng.below(3) {
                    v.splice(at..at, piece.iter().copied());
                }
            }
            4 => v.truncate(at),
            _ => {
                let n = rng.below(16);
                let bytes: Vec<u8> = (0..n).map(|_| rng.next() as u8).collect();
                v.splice(at..at, bytes);
            }
        }
    }
    v
}

/// Files under `dir` ending in one of `exts` (recursively), sorted.
fn files(dir: &Path, exts: &[&str]) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let Ok(rd) = std::fs::read_dir(dir) else {
        return out;
    };
    for e in rd.flatten() {
        let p = e.path();
        if p.is_dir() {
            out.extend(files(&p, exts));
        } else if exts
            .iter()
            .any(|x| p.to_string_lossy().to_ascii_lowercase().ends_with(x))
        {
            out.push(p);
        }
    }
    out.sort();
    out
}

/// The seeds of a target: its corpus folder plus the bundled inputs of its format.
fn seeds(corpus: &str, bundled: &[(&str, &[&str])]) -> Vec<Vec<u8>> {
    let mut v: Vec<Vec<u8>> = files(&root(&format!("tests/fuzz/corpus/{corpus}")), &[""])
        .iter()
        .filter_map(|p| std::fs::read(p).ok())
        .collect();
    for (dir, exts) in bundled {
        for p in files(&root(dir), exts) {
            if let Ok(b) = std::fs::read(&p) {
                if b.len() <= 1 << 20 {
                    v.push(b);
                }
            }
        }
    }
    assert!(!v.is_empty(), "no seeds for {corpus}");
    v
}

/// Runs `parse` on mutations of `seeds` for `budget`; panics (with the input saved) on a panic
/// or an allocation peak over the limit. Returns (cases, largest peak).
fn fuzz(name: &str, seeds: &[Vec<u8>], budget: Duration, parse: &dyn Fn(&[u8])) -> (u64, usize) {
    let mut rng = Rng(0x5eed ^ name.len() as u64);
    let start = Instant::now();
    let (mut cases, mut worst) = (0u64, 0usize);
    // every seed as it is first (the corpus holds past failures as regression inputs), then
    // mutations until the budget is spent
    let mut unmutated = seeds.iter();
    loop {
        let input = match unmutated.next() {
            Some(seed) => seed.clone(),
            None if start.elapsed() < budget => {
                let seed = &seeds[rng.below(seeds.len())];
                mutate(&mut rng, seed)
            }
            None => break,
        };
        let base = LIVE.load(Ordering::Relaxed);
        PEAK.store(base, Ordering::Relaxed);
        let ok = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| parse(&input)));
        let peak = PEAK.load(Ordering::Relaxed).saturating_sub(base);
        worst = worst.max(peak);
        cases += 1;
        if ok.is_err() || peak > PEAK_LIMIT {
            let dir = root("tests/fuzz/crashes");
            let _ = std::fs::create_dir_all(&dir);
            let path = dir.join(format!("{name}-{cases}"));
            let _ = std::fs::write(&path, &input);
            panic!(
                "{name}: {} on the input saved to {}",
                if ok.is_err() {
                    "a panic".to_string()
                } else {
                    format!("{peak} bytes allocated")
                },
                path.display()
            );
        }
    }
    (cases, worst)
}

fn budget() -> Duration {
    let total: f64 = std::env::var("FURNACE_FUZZ_SECONDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(14.0);
    Duration::from_secs_f64(total / 7.0)
}

fn report(name: &str, (cases, peak): (u64, usize)) {
    println!("{name}: {cases} inputs, no panic, largest allocation peak {peak} bytes");
}

#[test]
fn scene_parser() {
    let seeds = seeds(
        "scene",
        &[
            ("scenes", &[".toml"]),
            ("tests/manifests/scenes", &[".toml"]),
        ],
    );
    let at = root("scenes/fuzz.toml");
    report(
        "scene",
        fuzz("scene", &seeds, budget(), &|b| {
            let _ = furnace::scene::Scene::parse(&String::from_utf8_lossy(b), &at);
        }),
    );
}

#[test]
fn manifest_parser() {
    let seeds = seeds("manifest", &[("tests/manifests", &[".toml"])]);
    let at = root("tests/manifests/fuzz.toml");
    report(
        "manifest",
        fuzz("manifest", &seeds, budget(), &|b| {
            let _ = furnace::harness::manifest::parse(&String::from_utf8_lossy(b), &at);
        }),
    );
}

#[test]
fn obj_parser() {
    let seeds = seeds("obj", &[("scenes/meshes", &[".obj"])]);
    report(
        "obj",
        fuzz("obj", &seeds, budget(), &|b| {
            let _ = furnace::io::mesh::parse_obj(&String::from_utf8_lossy(b), Path::new("f.obj"));
        }),
    );
}

#[test]
fn ply_parser() {
    let seeds = seeds("ply", &[("reference/mitsuba", &[".ply"])]);
    report(
        "ply",
        fuzz("ply", &seeds, budget(), &|b| {
            let _ = furnace::io::mesh::parse_ply(b, Path::new("f.ply"));
        }),
    );
}

#[test]
fn csv_parser() {
    let seeds = seeds("csv", &[("reference/conductors", &[".csv"])]);
    report(
        "csv",
        fuzz("csv", &seeds, budget(), &|b| {
            let _ = furnace::io::csv::column(&String::from_utf8_lossy(b), "eta");
        }),
    );
}

#[test]
fn exr_reader() {
    let seeds = seeds("exr", &[]);
    let dir = std::env::temp_dir().join(format!("furnace-fuzz-exr-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("f.exr");
    report(
        "exr",
        fuzz("exr", &seeds, budget(), &|b| {
            std::fs::write(&path, b).unwrap();
            let _ = furnace::io::image::read_exr(&path);
        }),
    );
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn renderer_table_parser() {
    let seeds = seeds("renderers", &[]);
    report(
        "renderers",
        fuzz("renderers", &seeds, budget(), &|b| {
            let _ = furnace::harness::adapter::parse_renderers(
                &String::from_utf8_lossy(b),
                Path::new("r.toml"),
            );
        }),
    );
}
