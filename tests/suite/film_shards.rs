//! Sharded renders: `render --shard K/N` parts joined by `merge-films` give the whole render's
//! EXR (pixels and attributes bit for bit), and parts that do not make one render are refused
//! by name.

use crate::root;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn furnace(args: &[&str]) -> Output {
    crate::run_furnace(args)
}

fn ok(out: &Output) -> String {
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.status.success(), "{text}");
    text
}

fn scratch(name: &str) -> PathBuf {
    let dir = crate::scratch_dir().join(format!("furnace-films-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Channels as bits and attributes as a sorted list (the exr crate writes header attributes in
/// hash-map order, so file bytes may differ even between two whole renders).
type ExrBits = (Vec<(String, Vec<u32>)>, Vec<(String, String)>);

fn exr_bits(path: &Path) -> ExrBits {
    let layers = furnace::io::image::read_exr(path).unwrap();
    let mut channels: Vec<_> = layers
        .channels
        .iter()
        .map(|(n, v)| (n.clone(), v.iter().map(|x| x.to_bits()).collect()))
        .collect();
    channels.sort();
    let mut attributes = layers.attributes.clone();
    attributes.sort();
    (channels, attributes)
}

/// Renders `scene` whole and in `parts` parts with `extra` options; the merged EXR must equal
/// the whole one.
fn assert_parts_merge_exactly(dir: &Path, scene: &str, extra: &[&str], parts: usize) {
    let common = [&[scene, "-q"][..], extra].concat();
    let whole = dir.join(format!("whole-{parts}.exr"));
    ok(&furnace(
        &[&["render"][..], &common, &["-o", s(&whole)]].concat(),
    ));
    let mut files = Vec::new();
    for k in 1..=parts {
        let f = dir.join(format!("part-{k}-of-{parts}.film"));
        let shard = format!("{k}/{parts}");
        ok(&furnace(
            &[&["render"][..], &common, &["--shard", &shard, "-o", s(&f)]].concat(),
        ));
        files.push(f);
    }
    files.reverse();
    let merged = dir.join(format!("merged-{parts}.exr"));
    let mut args = vec!["merge-films", "-o", s(&merged)];
    args.extend(files.iter().map(|f| s(f)));
    let text = ok(&furnace(&args));
    assert!(text.contains(&format!("from {parts} parts")), "{text}");
    assert_eq!(
        exr_bits(&merged),
        exr_bits(&whole),
        "{scene} {extra:?} in {parts} parts"
    );
    assert_eq!(
        std::fs::read(merged.with_extension("png")).unwrap(),
        std::fs::read(whole.with_extension("png")).unwrap()
    );
}

#[test]
fn a_render_in_1_2_3_and_7_parts_merges_to_the_whole_render() {
    let dir = scratch("path");
    // 100 spp: 7 blocks of 16 samples, the last one short
    let opts = [
        "--spp", "100", "--width", "24", "--height", "24", "--seed", "4",
    ];
    for parts in [1, 2, 3, 7] {
        assert_parts_merge_exactly(&dir, "scenes/cornell-box.toml", &opts, parts);
    }
    // a participating medium and the spectral path
    let opts = [
        "--spp",
        "48",
        "--width",
        "16",
        "--height",
        "16",
        "--no-grey-mode",
    ];
    assert_parts_merge_exactly(&dir, "scenes/hg-fog.toml", &opts, 3);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_light_traced_render_in_parts_merges_to_the_whole_render() {
    let dir = scratch("light");
    let opts = [
        "--integrator",
        "light",
        "--light-paths",
        "20000",
        "--width",
        "24",
        "--height",
        "24",
    ];
    for parts in [2, 7] {
        assert_parts_merge_exactly(&dir, "scenes/cornell-box.toml", &opts, parts);
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// A small render of the Cornell box: 4 blocks of 16 samples.
const SMALL: [&str; 9] = [
    "render",
    "scenes/cornell-box.toml",
    "-q",
    "--spp",
    "64",
    "--width",
    "8",
    "--height",
    "8",
];

#[test]
fn parts_of_different_renders_missing_or_doubled_parts_and_bad_files_are_refused() {
    let dir = scratch("bad");
    let part = |k: usize, n: usize, seed: &str| {
        let f = dir.join(format!("p{k}-{n}-s{seed}.film"));
        let shard = format!("{k}/{n}");
        ok(&furnace(
            &[
                &SMALL[..],
                &["--seed", seed, "--shard", &shard, "-o", s(&f)],
            ]
            .concat(),
        ));
        f
    };
    let (p1, p2, p3) = (part(1, 3, "0"), part(2, 3, "0"), part(3, 3, "0"));
    let out = dir.join("m.exr");
    let merge = |files: &[&PathBuf]| {
        let mut args = vec!["merge-films", "-o", s(&out)];
        args.extend(files.iter().map(|f| s(f)));
        let o = furnace(&args);
        assert_eq!(o.status.code(), Some(2), "{o:?}");
        assert!(!out.exists(), "a refused merge wrote {}", out.display());
        String::from_utf8_lossy(&o.stderr).into_owned()
    };
    let e = merge(&[&p1, &p3]);
    assert!(e.contains("blocks 1..2 are in no part"), "{e}");
    let e = merge(&[&p1, &p2, &p2, &p3]);
    assert!(
        e.contains("in more than one part") && e.contains("p2-3-s0.film"),
        "{e}"
    );
    let other_seed = part(2, 3, "9");
    let e = merge(&[&p1, &other_seed, &p3]);
    assert!(
        e.contains("different runs") && e.contains("furnace.seed"),
        "{e}"
    );
    // parts of different splits of one render merge when they tile it, and overlap otherwise
    let other_split = part(2, 2, "0");
    let e = merge(&[&p1, &p2, &p3, &other_split]);
    assert!(e.contains("blocks 2..4 are in more than one part"), "{e}");
    // a cut file, a file that is not a partial film, an altered header
    let bytes = std::fs::read(&p2).unwrap();
    let cut = dir.join("cut.film");
    std::fs::write(&cut, &bytes[..bytes.len() - 8]).unwrap();
    let e = merge(&[&p1, &cut, &p3]);
    assert!(e.contains("cut short"), "{e}");
    let junk = dir.join("junk.film");
    std::fs::write(&junk, "P6\n8 8\n255\n").unwrap();
    let e = merge(&[&junk]);
    assert!(e.contains("not a furnace partial film"), "{e}");
    let text = String::from_utf8_lossy(&bytes).into_owned();
    let header_end = text.find('\n').unwrap() + 1;
    let header_line_end = header_end + text[header_end..].find('\n').unwrap();
    let header = &text[header_end..header_line_end];
    // p2 with its header line replaced
    let with_header = |name: &str, altered: &str| {
        let f = dir.join(name);
        let body = [
            &bytes[..header_end],
            altered.as_bytes(),
            &bytes[header_line_end..],
        ];
        std::fs::write(&f, body.concat()).unwrap();
        f
    };
    let huge = with_header(
        "huge.film",
        &header.replace("\"width\":8", "\"width\":65536"),
    );
    let e = merge(&[&huge]);
    assert!(e.contains("huge.film"), "{e}");
    // a piece's sample count altered (the sum no longer the run's spp), and a pixel's sum of
    // squared deviations made negative (its first channel's m2, after the mean)
    let pieces = header.find("\"pieces\":[[").unwrap() + "\"pieces\":[[".len();
    let count_at = pieces + header[pieces..].find(']').unwrap();
    let count_start = header[..count_at].rfind(',').unwrap() + 1;
    let more = format!("{}{}{}", &header[..count_start], "99", &header[count_at..]);
    let counted = with_header("counted.film", &more);
    let e = merge(&[&p1, &counted, &p3]);
    assert!(
        e.contains("samples per pixel, but the run's furnace.spp is"),
        "{e}"
    );
    let mut negative = bytes.clone();
    let m2 = header_line_end + 1 + 8;
    negative[m2..m2 + 8].copy_from_slice(&(-1.0f64).to_le_bytes());
    let neg = dir.join("negative.film");
    std::fs::write(&neg, &negative).unwrap();
    let e = merge(&[&p1, &neg, &p3]);
    assert!(e.contains("negative sum of squared deviations"), "{e}");
    // shard specifications the render cannot honour
    // (SMALL's spp gives fewer than 5 blocks of 16; 65 spp, 16·4 + 1, is the least that does)
    for (shard, msg) in [
        ("5/4", "must be K/N"),
        ("1/5", "fewer than 5 parts (give --spp 65 or more"),
    ] {
        let x = dir.join("x.film");
        let o = furnace(&[&SMALL[..], &["--shard", shard, "-o", s(&x)]].concat());
        assert_eq!(o.status.code(), Some(2));
        let e = String::from_utf8_lossy(&o.stderr);
        assert!(e.contains(msg), "{shard}: {e}");
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn the_documented_local_workflow_script_merges_to_the_whole_render() {
    let dir = scratch("script");
    let opts = [
        "--spp", "40", "--width", "16", "--height", "16", "--seed", "2",
    ];
    let whole = dir.join("whole.exr");
    ok(&furnace(
        &[
            &["render", "scenes/cornell-box.toml", "-q", "-o", s(&whole)][..],
            &opts,
        ]
        .concat(),
    ));
    let out = dir.join("films");
    let o = Command::new("sh")
        .arg(root("docs/ci/films-locally.sh"))
        .args(["3", "scenes/cornell-box.toml"])
        .args(opts)
        .env("FURNACE", env!("CARGO_BIN_EXE_furnace"))
        .env("OUT", &out)
        .output()
        .unwrap();
    ok(&o);
    assert_eq!(exr_bits(&out.join("image.exr")), exr_bits(&whole));
    std::fs::remove_dir_all(&dir).ok();
}

/// A renderer table whose one entry, `stand-in`, is `furnace render` of a fixed scene (the
/// exported scene is ignored), in 4 independent runs per image.
fn stand_in_table(dir: &Path) -> PathBuf {
    let p = dir.join("renderers.toml");
    let text = format!(
        "[renderer.stand-in]\nexporter = \"mitsuba3\"\nobserver = \"cie1931\"\nbatches = 4\ncommand = [{:?}, \"render\", \"scenes/cornell-box.toml\", \"--out\", \"{{out}}\", \"--spp\", \"{{spp}}\", \"--seed\", \"{{seed}}\", \"--width\", \"{{width}}\", \"--height\", \"{{height}}\", \"--threads\", \"{{threads}}\", \"--quiet\"]\n",
        env!("CARGO_BIN_EXE_furnace")
    );
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn a_reference_render_through_another_renderer_merges_from_its_runs() {
    let dir = scratch("external");
    let table = stand_in_table(&dir);
    let opts = [
        "--renderer",
        "stand-in",
        "--renderers",
        s(&table),
        "--spp",
        "32",
        "--width",
        "8",
        "--height",
        "8",
    ];
    for parts in [2, 4] {
        assert_parts_merge_exactly(&dir, "scenes/cornell-box.toml", &opts, parts);
    }
    // each pixel's variance comes from the 4 runs
    let layers = furnace::io::image::read_exr(&dir.join("whole-4.exr")).unwrap();
    let attr = |k: &str| {
        layers
            .attributes
            .iter()
            .find(|(n, _)| n == k)
            .map(|(_, v)| v.clone())
    };
    assert_eq!(attr("furnace.variance_dof").as_deref(), Some("3"));
    assert_eq!(attr("furnace.renderer").as_deref(), Some("stand-in"));
    assert_eq!(attr("furnace.integrator"), None);
    // more parts than runs, and light tracing through another renderer, are refused
    let x = dir.join("x.film");
    for (extra, msg) in [
        (&["--shard", "1/5"][..], "fewer than 5 parts"),
        (&["--integrator", "light"][..], "own estimator"),
    ] {
        let o = furnace(
            &[
                &["render", "scenes/cornell-box.toml", "-q", "-o", s(&x)][..],
                &opts,
                extra,
            ]
            .concat(),
        );
        assert_eq!(o.status.code(), Some(2));
        let e = String::from_utf8_lossy(&o.stderr);
        assert!(e.contains(msg), "{extra:?}: {e}");
    }
    std::fs::remove_dir_all(&dir).ok();
}
