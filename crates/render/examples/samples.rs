//! Writes one sample picture of each kind into a folder (default
//! `/tmp/render-samples`) and prints how long each took.
//!
//! `cargo run --release -p fibfluid-render --example samples -- [DIR]`

#[path = "../tests/common/mod.rs"]
mod common;

use std::time::Instant;

use fibfluid_render::{Colormap, Series, Surface, ViewOptions, loglog_chart, pareto_front, render_surfaces};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let dir = std::env::args().nth(1).unwrap_or_else(|| "/tmp/render-samples".into());
    std::fs::create_dir_all(&dir)?;

    let (p, t) = common::bumpy_sphere(60, 51);
    let before: Vec<f64> = p.iter().map(|q| 1e-3 * (q[0] * q[1] + 0.2 * q[2])).collect();
    let after: Vec<f64> = p.iter().map(|q| 2e-3 * q[1] * q[1]).collect();
    let panels = [
        Surface { positions: &p, triangles: &t, scalar: &before, title: "before".into() },
        Surface { positions: &p, triangles: &t, scalar: &after, title: "after 10 steps".into() },
    ];
    let opts = ViewOptions {
        width: 800,
        height: 800,
        scalar_label: "displacement [m]".into(),
        ..ViewOptions::default()
    };
    let start = Instant::now();
    let png = render_surfaces(&panels, None, &opts)?;
    println!("surfaces (2 x 6000 triangles, 800x800): {:?}", start.elapsed());
    std::fs::write(format!("{dir}/surfaces.png"), png)?;

    let (cp, ct) = common::split_cube();
    let cs: Vec<f64> = (0..cp.len()).map(|i| (i / 4) as f64 * 20.0).collect();
    let cube = [Surface { positions: &cp, triangles: &ct, scalar: &cs, title: "cube faces (turbo)".into() }];
    let opts = ViewOptions {
        width: 400,
        height: 400,
        colormap: Colormap::Turbo,
        scalar_label: "face index x 20".into(),
        background: [30, 30, 40],
        ..ViewOptions::default()
    };
    std::fs::write(format!("{dir}/cube.png"), render_surfaces(&cube, None, &opts)?)?;

    // An open wavy sheet (back side visible) next to a constant scalar.
    let n = 40;
    let mut sp = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let (x, z) = (i as f64 / n as f64 - 0.5, j as f64 / n as f64 - 0.5);
            sp.push([x, 0.15 * (6.0 * x).sin() * (4.0 * z).cos(), z]);
        }
    }
    let mut st = Vec::new();
    for j in 0..n as u32 {
        for i in 0..n as u32 {
            let a = j * (n as u32 + 1) + i;
            let b = a + n as u32 + 1;
            st.push([a, a + 1, b + 1]);
            st.push([a, b + 1, b]);
        }
    }
    let height: Vec<f64> = sp.iter().map(|q| q[1]).collect();
    let constant = vec![7.0; sp.len()];
    let sheets = [
        Surface { positions: &sp, triangles: &st, scalar: &height, title: "open sheet, height".into() },
        Surface { positions: &sp, triangles: &st, scalar: &constant, title: "constant 7".into() },
    ];
    let opts = ViewOptions {
        width: 360,
        height: 300,
        view_dir: [-0.3, 0.8, -1.0],
        colormap: Colormap::Plasma,
        scalar_label: "y".into(),
        ..ViewOptions::default()
    };
    std::fs::write(format!("{dir}/sheet.png"), render_surfaces(&sheets, None, &opts)?)?;

    let series = vec![
        Series {
            label: "dense LU".into(),
            points: vec![(0.002, 0.3), (0.011, 0.06), (0.09, 0.011), (0.8, 0.0021)],
        },
        Series {
            label: "structured".into(),
            points: vec![(0.004, 0.12), (0.02, 0.03), (0.12, 0.004), (0.9, 0.0009)],
        },
        Series {
            label: "chainmail".into(),
            points: vec![(0.0008, 0.9), (0.003, 0.5), (0.03, 0.2), (0.2, 0.15)],
        },
    ];
    let all: Vec<(f64, f64)> = series.iter().flat_map(|s| s.points.clone()).collect();
    let front: Vec<(f64, f64)> = pareto_front(&all).into_iter().map(|i| all[i]).collect();
    let start = Instant::now();
    let png = loglog_chart("Error vs run time", "run time [s]", "relative error", &series, &front, 800, 560)?;
    println!("chart: {:?}", start.elapsed());
    std::fs::write(format!("{dir}/chart.png"), png)?;
    let rising = [Series {
        label: "memory".into(),
        points: vec![(10.0, 2.0), (100.0, 30.0), (1000.0, 500.0), (1e4, 9000.0)],
    }];
    std::fs::write(
        format!("{dir}/chart_rising.png"),
        loglog_chart("Memory vs size", "vertices", "MiB", &rising, &[], 500, 360)?,
    )?;
    println!("wrote {dir}/surfaces.png, cube.png, sheet.png, chart.png, chart_rising.png");
    Ok(())
}
