//! The page in a real headless browser (feature `browser`; needs `chromium` on the PATH,
//! or its path in `CHROMIUM`):
//!
//! ```text
//! cargo test -p fibfluid-viewer --features browser --test main browser
//! ```
//!
//! Three screenshots of the paper's sphere: `/` (the base state, no hold), `/?demo=drag`
//! (the page's scripted drag through its own mouse handlers) and `/?demo=drag&reach=8` (the
//! same drag eight times as far, past the body's size). The surface must have moved (pixels
//! differ in the mesh region), the force readout must have appeared (yellow text in the
//! readout region of the drags, next to none in the other), and the result guards' orange
//! line must be absent from the base state and longest after the far drag.

use std::path::{Path, PathBuf};
use std::process::Command;

use fibfluid_interact::Storage;
use tiny_skia::Pixmap;

use crate::common::{scene_body, serve, sphere_path};

const WIDTH: u32 = 1000;
const HEIGHT: u32 = 700;
/// A pixel differs when a channel differs by more than this (anti-aliasing and shading
/// noise stay below).
const CHANNEL_TOLERANCE: u8 = 24;

fn chromium() -> PathBuf {
    if let Ok(p) = std::env::var("CHROMIUM") {
        return PathBuf::from(p);
    }
    for name in ["chromium", "chromium-browser", "google-chrome"] {
        if Command::new(name).arg("--version").output().is_ok_and(|o| o.status.success()) {
            return PathBuf::from(name);
        }
    }
    panic!("no chromium on the PATH (install it: apt-get install -y chromium; or set CHROMIUM)");
}

fn screenshot(url: &str, out: &Path) -> Pixmap {
    let status = Command::new(chromium())
        .args([
            "--headless",
            "--disable-gpu",
            "--no-sandbox",
            "--hide-scrollbars",
            "--force-device-scale-factor=1",
            &format!("--screenshot={}", out.display()),
            &format!("--window-size={WIDTH},{HEIGHT}"),
            "--virtual-time-budget=5000",
            url,
        ])
        .output()
        .expect("chromium runs");
    assert!(status.status.success(), "chromium failed: {}", String::from_utf8_lossy(&status.stderr));
    let bytes = std::fs::read(out).expect("the screenshot was written");
    let p = Pixmap::decode_png(&bytes).expect("a PNG");
    assert_eq!((p.width(), p.height()), (WIDTH, HEIGHT));
    p
}

fn pixel(p: &Pixmap, x: u32, y: u32) -> [u8; 3] {
    let c = p.pixel(x, y).expect("in the image").demultiply();
    [c.red(), c.green(), c.blue()]
}

/// Pixels of the rectangle that differ between the two screenshots.
fn differing(a: &Pixmap, b: &Pixmap, x: std::ops::Range<u32>, y: std::ops::Range<u32>) -> usize {
    let mut count = 0;
    for j in y {
        for i in x.clone() {
            let (p, q) = (pixel(a, i, j), pixel(b, i, j));
            if p.iter().zip(&q).any(|(u, v)| u.abs_diff(*v) > CHANNEL_TOLERANCE) {
                count += 1;
            }
        }
    }
    count
}

/// Pixels of the rectangle in the guard line's orange (#e8590c: red high, green middling,
/// blue low; no color of the surface, the readouts or the fixed vertices is near it).
fn orange(p: &Pixmap, x: std::ops::Range<u32>, y: std::ops::Range<u32>) -> usize {
    let mut count = 0;
    for j in y {
        for i in x.clone() {
            let [r, g, b] = pixel(p, i, j);
            if r > 200 && (60..130).contains(&g) && b < 50 {
                count += 1;
            }
        }
    }
    count
}

/// Pixels of the rectangle in the readout's yellow (#ffd479: red and green high, blue lower).
fn yellow(p: &Pixmap, x: std::ops::Range<u32>, y: std::ops::Range<u32>) -> usize {
    let mut count = 0;
    for j in y {
        for i in x.clone() {
            let [r, g, b] = pixel(p, i, j);
            if r > 180 && g > 140 && (b as i32) < (g as i32) - 40 {
                count += 1;
            }
        }
    }
    count
}

#[test]
fn browser_scripted_drag_moves_the_surface_and_shows_the_force() {
    let (scene, body) = scene_body(sphere_path(), Storage::F64);
    let server = serve(&scene, &body, 4);
    let dir = std::env::temp_dir().join(format!("fibfluid-viewer-browser-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let drag = screenshot(&format!("{}?demo=drag", server.url()), &dir.join("drag.png"));
    let still = screenshot(&server.url(), &dir.join("still.png"));
    let far = screenshot(&format!("{}?demo=drag&reach=8", server.url()), &dir.join("far.png"));

    // The mesh region: right of the panel, above the bottom.
    let (mesh_x, mesh_y) = (340..WIDTH - 80, 0..HEIGHT);
    let moved = differing(&drag, &still, mesh_x.clone(), mesh_y.clone());
    let total = (mesh_x.len() * mesh_y.len()) as f64;
    // The force readout: the two lines under "reaction force" in the panel.
    let (ro_x, ro_y) = (20..330, 92..135);
    let text_drag = yellow(&drag, ro_x.clone(), ro_y.clone());
    let text_still = yellow(&still, ro_x.clone(), ro_y.clone());
    let readout_changed = differing(&drag, &still, ro_x, ro_y);
    eprintln!(
        "browser: {moved} mesh pixels differ ({:.2} %), readout yellow pixels {text_drag} (drag) vs {text_still} (still), {readout_changed} readout pixels differ; screenshots in {}",
        100.0 * moved as f64 / total,
        dir.display()
    );
    assert!(moved as f64 > 0.002 * total, "the surface did not move ({moved} pixels differ)");
    assert!(
        text_drag > 150 && text_drag > 5 * text_still.max(1),
        "no force readout ({text_drag} vs {text_still})"
    );
    assert!(readout_changed > 100);
    // The panel: the guard line sits under the readouts when a guard fired.
    let (panel_x, panel_y) = (10..322, 0..HEIGHT);
    let guard_line = [&still, &drag, &far].map(|p| orange(p, panel_x.clone(), panel_y.clone()));
    eprintln!("browser: guard line pixels {guard_line:?} (still, drag, far)");
    assert!(guard_line[0] < 20, "a guard line on the base state ({guard_line:?})");
    assert!(guard_line[2] > 1000, "no guard line after the far drag ({guard_line:?})");
    // The scripted drag pulls a vertex next to the fixed cap and folds a few faces there
    // (`inverted`); the far one adds `displacement`: a longer line.
    assert!(guard_line[2] > guard_line[1], "the far drag's line is not longer ({guard_line:?})");
    let _ = std::fs::remove_dir_all(&dir);
}
