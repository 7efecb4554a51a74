//! The three HTML report pages render in a real browser: headless Chromium takes a screenshot
//! of each, the screenshot must have the window's size, and a few colour probes must find what
//! the page draws (a broken data URI, SVG or stylesheet shows nothing):
//!
//! * the check report of two renderers, one check failing: the red verdict banner, and the
//!   deviation dot plot's first renderer colour;
//! * an image comparison whose test image is pure green and whose reference is pure magenta:
//!   both colours cover most of their 256×256 image boxes;
//! * the convergence page: the plotted ladder's colour and the green rows of passing ladders.
//!
//! Runs in `cargo test --release` wherever Chromium is installed (`apt-get install chromium`;
//! `FURNACE_CHROMIUM` names another binary) and prints why it is skipped where it is not.

use furnace::harness::compare::{compare, RgbImage};
use furnace::harness::ladder::LadderSummary;
use furnace::report::convergence::{self, ManifestLadders};
use furnace::report::html;
use furnace::report::plot::Series;
use std::process::Command;

/// Window size of the screenshots, CSS px (device scale 1 in headless mode).
const WINDOW: (u32, u32) = (1280, 900);

fn chromium() -> Option<String> {
    let bin = std::env::var("FURNACE_CHROMIUM").unwrap_or("chromium".into());
    match Command::new(&bin).arg("--version").output() {
        Ok(o) if o.status.success() => Some(bin),
        _ => {
            eprintln!(
                "SKIPPED: {bin} not found (apt-get install chromium, or set FURNACE_CHROMIUM)"
            );
            None
        }
    }
}

/// An RGB(A) screenshot: width, height, channels, pixels.
struct Shot {
    width: u32,
    height: u32,
    channels: usize,
    pixels: Vec<u8>,
}

impl Shot {
    /// Pixels within ±12 of `rgb` in every channel.
    fn count(&self, rgb: [u8; 3]) -> usize {
        self.pixels
            .chunks(self.channels)
            .filter(|p| (0..3).all(|c| (p[c] as i32 - rgb[c] as i32).abs() <= 12))
            .count()
    }
}

fn screenshot(bin: &str, name: &str, page: &str) -> Shot {
    let dir = crate::scratch_dir().join(format!("furnace-html-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (file, shot) = (dir.join("report.html"), dir.join("shot.png"));
    std::fs::write(&file, page).unwrap();
    let mut cmd = Command::new(bin);
    cmd.args([
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-dev-shm-usage",
        "--hide-scrollbars",
        "--force-device-scale-factor=1",
        &format!("--user-data-dir={}", dir.join("profile").display()),
        &format!("--window-size={},{}", WINDOW.0, WINDOW.1),
        &format!("--screenshot={}", shot.display()),
        &format!("file://{}", file.display()),
    ]);
    // bounded: a browser that hangs fails the test instead of the whole suite
    let out = furnace::harness::adapter::run_bounded(cmd, std::time::Duration::from_secs(120))
        .unwrap_or_else(|e| panic!("{name}: {bin}: {e}"));
    assert!(
        out.success,
        "{name}: {bin} exited with {}: {}",
        out.status, out.stderr
    );
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&shot).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    buf.truncate(info.buffer_size());
    let _ = std::fs::remove_dir_all(&dir);
    let s = Shot {
        width: info.width,
        height: info.height,
        channels: info.color_type.samples(),
        pixels: buf,
    };
    assert_eq!((s.width, s.height), WINDOW, "{name}: screenshot size");
    s
}

fn flat(rgb: [f64; 3]) -> RgbImage {
    RgbImage {
        width: 32,
        height: 32,
        rgb: std::array::from_fn(|c| vec![rgb[c]; 32 * 32]),
        variance: Some(std::array::from_fn(|_| vec![1e-4; 32 * 32])),
        variance_dof: None,
        variance_variance: None,
        pixels_correlated: false,
        runs: Vec::new(),
    }
}

/// One run's results in the JSON schema, with one check passing and, if `fail`, one failing.
fn run(renderer: &str, fail: bool) -> serde_json::Value {
    let b = if fail {
        r#"{"name":"b","kind":"lambert","verdict":"FAIL","estimate":1.9,"std_error":0.01,"expected":2.0,"p_value":1e-20,"alpha":0.001,"seconds":0.1,"message":"10 se low"}"#
    } else {
        r#"{"name":"b","kind":"lambert","verdict":"PASS","estimate":2.001,"std_error":0.01,"expected":2.0,"p_value":0.9,"alpha":0.001,"seconds":0.1,"message":"ok"}"#
    };
    serde_json::from_str(&format!(
        r#"{{"schema":"furnace.check-results/1","renderer":"{renderer}","manifests":["m.toml"],"seed":1,"family_alpha":0.01,"correction":"sidak","stochastic_tests":2,
           "outcomes":[{{"name":"a","kind":"furnace","verdict":"PASS","estimate":2.0,"std_error":0.001,"expected":2.0,"p_value":0.5,"alpha":0.001,"detection_power":0.002,"seconds":0.1,"message":"ok"}},{b}]}}"#
    ))
    .unwrap()
}

#[test]
fn report_pages_render_in_chromium() {
    let Some(bin) = chromium() else { return };

    // 1. the check report of two renderers, one check failing
    let page = html::page(
        "check report",
        &[run("furnace", false), run("other", true)],
        &[],
    );
    let s = screenshot(&bin, "check", &page);
    let banner = s.count([0xf8, 0xd7, 0xd7]);
    let dots = s.count([0x1f, 0x77, 0xb4]);
    assert!(banner > 5_000, "red banner: {banner} px");
    assert!(dots > 20, "the deviation plot's first renderer: {dots} px");

    // 2. an image comparison: green test, magenta reference
    let (t, r) = (flat([0.0, 1.0, 0.0]), flat([1.0, 0.0, 1.0]));
    let c = compare(&t, &r, &[], 0.01, 0.01, 0.0).unwrap();
    let section = html::ComparisonSection {
        title: "green vs magenta".into(),
        panels: html::comparison_panels(&t, &r, &c).unwrap(),
        comparison: c,
        family_alpha: 0.01,
        regions: Vec::new(),
    };
    let s = screenshot(
        &bin,
        "comparison",
        &html::page("comparison", &[], &[section]),
    );
    let (green, magenta) = (s.count([0, 255, 0]), s.count([255, 0, 255]));
    // each image box is 256×256 = 65536 px
    assert!(
        green > 50_000 && magenta > 50_000,
        "green {green}, magenta {magenta}"
    );

    // 3. the convergence page: one ladder at its predicted rate
    let summary = LadderSummary {
        name: "convergence/smooth".into(),
        sampler: "independent".into(),
        slope: -0.5,
        slope_ci95: 0.02,
        constant: 0.1,
        seconds_per_sample: 1e-7,
        efficiency: 1e3,
        n_star: 1e4,
        seconds_to_target: 0.5,
        expected_slope: [-0.55, -0.45],
        p: 0.8,
    };
    let series = Series {
        name: "smooth".into(),
        points: (0..6)
            .map(|k| {
                let n = 4f64.powi(k + 1);
                (n, 0.1 / n.sqrt())
            })
            .collect(),
        guide_slope: Some(-0.5),
    };
    let manifests = [ManifestLadders {
        manifest: "m.toml".into(),
        series: vec![series.clone()],
    }];
    let page = convergence::page(1, 1e-3, 0.01, &[summary], &manifests, &[series]).unwrap();
    let s = screenshot(&bin, "convergence", &page);
    let (line, pass) = (s.count([0x1f, 0x77, 0xb4]), s.count([0xdf, 0xf5, 0xdf]));
    assert!(line > 200, "the ladder's line: {line} px");
    assert!(pass > 1_000, "green verdict banner and row: {pass} px");
}
