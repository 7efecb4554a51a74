//! The HTML report renders in a real browser: headless Chromium takes a screenshot of a
//! report whose test image is pure green and whose reference is pure magenta, and both
//! colours must cover most of their 256×256 image boxes (a broken data URI shows nothing).
//!
//! Ignored by default (CI has no browser). Run it with
//! `apt-get install chromium` and
//! `cargo test --release --test suite -- --ignored report_renders_in_chromium`
//! (`FURNACE_CHROMIUM` names another binary).

use furnace::harness::compare::{compare, RgbImage};
use furnace::report::html;
use std::process::Command;

fn flat(rgb: [f64; 3]) -> RgbImage {
    RgbImage {
        width: 32,
        height: 32,
        rgb: std::array::from_fn(|c| vec![rgb[c]; 32 * 32]),
        variance: Some(std::array::from_fn(|_| vec![1e-4; 32 * 32])),
        variance_dof: None,
        variance_variance: None,
    }
}

#[test]
#[ignore = "needs Chromium: apt-get install chromium; see the module doc"]
fn report_renders_in_chromium() {
    let (t, r) = (flat([0.0, 1.0, 0.0]), flat([1.0, 0.0, 1.0]));
    let c = compare(&t, &r, &[], 0.01, 0.01, 0.0).unwrap();
    let section = html::ComparisonSection {
        title: "green vs magenta".into(),
        panels: html::comparison_panels(&t, &r, &c).unwrap(),
        comparison: c,
        family_alpha: 0.01,
    };
    let page = html::page("screenshot test", &[], &[section]);
    let dir = std::env::temp_dir().join(format!("furnace-html-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (file, shot) = (dir.join("report.html"), dir.join("shot.png"));
    std::fs::write(&file, page).unwrap();
    let chromium = std::env::var("FURNACE_CHROMIUM").unwrap_or("chromium".into());
    let status = Command::new(&chromium)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--hide-scrollbars",
            "--window-size=1280,900",
            &format!("--screenshot={}", shot.display()),
            &format!("file://{}", file.display()),
        ])
        .output()
        .unwrap_or_else(|e| panic!("cannot run {chromium}: {e}"));
    assert!(status.status.success(), "{status:?}");
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&shot).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    let channels = info.color_type.samples();
    let (mut green, mut magenta) = (0usize, 0usize);
    for px in buf[..info.buffer_size()].chunks(channels) {
        let (r, g, b) = (px[0], px[1], px[2]);
        if g > 200 && r < 60 && b < 60 {
            green += 1;
        }
        if r > 200 && b > 200 && g < 60 {
            magenta += 1;
        }
    }
    // Each image box is 256×256 = 65536 CSS pixels (device scale 1 in headless mode).
    assert!(
        green > 50_000 && magenta > 50_000,
        "green {green}, magenta {magenta}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
