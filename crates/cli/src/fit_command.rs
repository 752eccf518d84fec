//! `fibfluid fit`: the scene's `[fit]` parameters fitted to the observed surface positions;
//! writes `fit.json` and `fit.png` (the residual per iteration) and prints a progress line
//! per iteration.

use std::path::PathBuf;

use fibfluid::Scene;
use fibfluid::sim::inverse::read_observed;
use fibfluid::sim::inverse_fit::{FitProgress, fit};

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
        files.push(("fit.png", history_png(&report.scene, &report.history)?));
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

/// `fit.png`: the base-10 logarithm of the RMS residual (m) after each iteration.
fn history_png(scene: &str, history: &[f64]) -> Result<Vec<u8>, CliError> {
    let points =
        history.iter().enumerate().map(|(k, r)| ((k + 1) as f64, r.max(f64::MIN_POSITIVE).log10())).collect();
    let series = [fibfluid::render::Series { label: "rms residual".into(), points }];
    let title = format!("{scene}: fit residual per iteration");
    Ok(fibfluid::render::line_chart(&title, "iteration", "log10 rms residual (m)", &series, 900, 520)
        .map_err(fibfluid_cli::Error::from)?)
}
