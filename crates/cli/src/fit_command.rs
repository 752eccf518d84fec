//! `fibfluid fit`: the scene's `[fit]` parameters fitted to the observed surface positions;
//! writes `fit.json` and `fit.png` (the residual of each observed vertex on the fitted
//! surface, and the residual per iteration) and prints a progress line per iteration.

use std::path::PathBuf;

use fibfluid::sim::inverse::{Observation, read_observed};
use fibfluid::sim::inverse_fit::{FitProgress, FitReport, fit};
use fibfluid::{Model, Scene, Shape, render};

use crate::CliError;
use crate::say::num;

/// Arguments of `fibfluid fit`.
#[derive(clap::Args)]
pub struct FitArgs {
    /// Scene TOML file with a [fit] section.
    scene: PathBuf,
    /// Output directory (fit.json, fit.png).
    #[arg(long)]
    out: PathBuf,
    /// Refuse a solve whose factor needs more than this many bytes (default: the
    /// machine's memory).
    #[arg(long, value_name = "BYTES")]
    max_memory: Option<u64>,
}

/// Runs `fibfluid fit`.
pub fn run(args: &FitArgs) -> Result<(), CliError> {
    let scene = Scene::load(&args.scene)?;
    let in_scene = crate::in_scene(&args.scene);
    let Some(spec) = scene.fem.fit.clone() else {
        return Err(in_scene(fibfluid::sim::Error::FitInput {
            path: args.scene.clone(),
            line: None,
            problem: "has no [fit] section (parameters, bounds, observed)".into(),
        }));
    };
    fibfluid_cli::check_output_dir(&args.out, &["fit.json", "fit.png"])?;
    let observed = read_observed(&scene.model, &spec.observed, spec.metres)?;
    let limit = fibfluid::memory_budget(args.max_memory);
    let keys: Vec<&str> = spec.parameters.iter().map(|p| p.key.as_str()).collect();
    let mut progress = |p: &FitProgress| {
        let values: Vec<String> =
            keys.iter().zip(&p.values).map(|(k, v)| format!("{k} {}", num(*v))).collect();
        tell!(
            "fit: iteration {}: rms {} m ({:.3} % of the observed displacement), {}",
            p.iteration,
            num(p.rms),
            100.0 * p.relative,
            values.join(", ")
        );
    };
    let report = fit(&scene.model, &spec, &observed, limit, &mut progress).map_err(&in_scene)?;
    let json = serde_json::to_vec_pretty(&report)?;
    let mut files = vec![("fit.json", json)];
    if !report.history.is_empty() {
        files.push(("fit.png", fit_png(&scene.model, &observed, &report)?));
    }
    fibfluid_cli::write_files_atomically(&args.out, &files)?;
    for p in &report.parameters {
        match (p.value, p.sigma) {
            (Some(v), Some(s)) => say!("{:<28} {} +- {}", p.key, num(v), num(s)),
            (Some(v), None) => say!("{:<28} {}", p.key, num(v)),
            _ => say!("{:<28} not identifiable from these observations", p.key),
        }
    }
    say!(
        "residual {} m rms ({:.3} % of the observed displacement) over {} vertices; {} iterations, {} Newton solves{}",
        num(report.residual_rms),
        100.0 * report.residual_relative,
        report.observations,
        report.iterations,
        report.newton_solves,
        if report.converged { "" } else { " (not converged: the iteration limit)" }
    );
    Ok(())
}

/// `fit.png`'s size (pixels): the fitted surface left, the residual per iteration right.
pub const FIT_PNG_SIZE: [u32; 2] = [1600, 640];

/// Grey: the vertices that were not observed.
const NOT_OBSERVED: [u8; 3] = [175, 175, 175];

/// `fit.png`: the fitted surface colored by each observed vertex's distance from its
/// observed position (mm; the faces around the observed vertices colored, the rest grey),
/// beside the base-10 logarithm of the RMS residual (m) after each iteration.
fn fit_png(model: &Model, observed: &[Observation], report: &FitReport) -> Result<Vec<u8>, CliError> {
    let triangles = match &model.shape {
        Shape::Surface(m) => m.mesh.triangles().to_vec(),
        Shape::Polygon(_) => Vec::new(),
    };
    let mut scalar = vec![f64::NAN; report.surface.positions.len()];
    for (o, r) in observed.iter().zip(&report.surface.residuals) {
        scalar[o.vertex] = 1e3 * r.distance;
    }
    let top = report.surface.residuals.iter().map(|r| 1e3 * r.distance).fold(0.0, f64::max);
    let opts = render::ViewOptions {
        width: FIT_PNG_SIZE[1],
        height: FIT_PNG_SIZE[1],
        scalar_label: "|x_model - x_observed| (mm)".into(),
        no_value: Some(NOT_OBSERVED),
        ..Default::default()
    };
    let title = format!("residual at {} observed vertices (grey: none)", observed.len());
    let panel = render::Surface {
        positions: &report.surface.positions,
        triangles: &triangles,
        scalar: &scalar,
        title,
    };
    let surface =
        render::render_surfaces(&[panel], Some((0.0, top)), &opts).map_err(fibfluid_cli::Error::from)?;
    // The PNG header's width (bytes 16..20, big-endian).
    let surface_width = surface.get(16..20).map_or(0, |b| u32::from_be_bytes([b[0], b[1], b[2], b[3]]));
    let points = report
        .history
        .iter()
        .enumerate()
        .map(|(k, r)| ((k + 1) as f64, r.max(f64::MIN_POSITIVE).log10()))
        .collect();
    let series = [render::Series { label: "rms residual".into(), points }];
    let title = format!("{}: fit residual per iteration", report.scene);
    let chart_width = FIT_PNG_SIZE[0].saturating_sub(surface_width).max(320);
    let chart = render::line_chart(
        &title,
        "iteration",
        "log10 rms residual (m)",
        &series,
        chart_width,
        FIT_PNG_SIZE[1],
    )
    .map_err(fibfluid_cli::Error::from)?;
    Ok(render::side_by_side(&[&surface, &chart]).map_err(fibfluid_cli::Error::from)?)
}
