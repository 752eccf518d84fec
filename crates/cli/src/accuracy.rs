//! `fibfluid accuracy`: the accuracy-versus-time study of a scene.

use std::path::Path;

use fibfluid::{Backend, ConstraintKind, Mode, Precision, Scene, Stepping};
use fibfluid_cli::study::{Grid, chart, run_study, to_csv, to_markdown};
use indicatif::{ProgressBar, ProgressStyle};

use crate::CliError;

/// The grid flags of `fibfluid accuracy`; each replaces its axis of the default grid.
#[derive(clap::Args)]
pub struct GridFlags {
    /// Step counts of the grid.
    #[arg(long, value_delimiter = ',', default_value = "1,3,10,30,100")]
    pub steps: Vec<usize>,
    /// Adaptive stepping tolerances of the grid.
    #[arg(long, value_delimiter = ',', default_value = "1e-2,1e-3,1e-4")]
    pub tolerances: Vec<f64>,
    /// Backends (default: every compiled-in one).
    #[arg(long, value_delimiter = ',')]
    pub backends: Option<Vec<Backend>>,
    /// Modes (default: paper, refresh, nonlinear).
    #[arg(long, value_delimiter = ',')]
    pub modes: Option<Vec<Mode>>,
    /// Stepping schemes (default: euler, heun).
    #[arg(long, value_delimiter = ',')]
    pub steppings: Option<Vec<Stepping>>,
    /// Precisions (default: f64, mixed).
    #[arg(long, value_delimiter = ',')]
    pub precisions: Option<Vec<Precision>>,
    /// Override the scene's constraint method (penalty, eliminate).
    #[arg(long)]
    pub constraints: Option<ConstraintKind>,
}

/// Runs the grid and writes accuracy.csv, accuracy.md, accuracy.png and
/// accuracy-reference.png into `out` (all or nothing); with `[tissue]` also
/// accuracy-fem.png, accuracy-grab.csv and accuracy-grab.png.
pub fn run(scene_path: &Path, out: &Path, flags: GridFlags) -> Result<(), CliError> {
    let mut scene = Scene::load(scene_path)?;
    // The grid sets the modes, so the scene's own mode says nothing about stiffening here.
    for w in fibfluid::ineffective(&scene) {
        if !matches!(w, fibfluid::Ineffective::StiffeningOutsideNonlinear { .. }) {
            tell!("warning: {w}");
        }
    }
    scene.solver.constraints = flags.constraints.unwrap_or(scene.solver.constraints);
    if let Some(&n) = flags.steps.iter().find(|&&n| !(1..=fibfluid::MAX_STEPS).contains(&n)) {
        return Err(CliError::Flag {
            flag: "steps",
            value: n.to_string(),
            problem: "give step counts from 1 to 1000000",
        });
    }
    if let Some(&t) = flags.tolerances.iter().find(|&&t| !(t > 0.0 && t < 1.0)) {
        return Err(CliError::Flag {
            flag: "tolerances",
            value: t.to_string(),
            problem: "give tolerances between 0 and 1",
        });
    }
    let mut grid = Grid { steps: flags.steps, tolerances: flags.tolerances, ..Grid::default() };
    if let Some(b) = flags.backends {
        for backend in &b {
            backend.solver().map_err(fibfluid::sim::Error::from)?;
        }
        grid.backends = b;
    }
    if scene.tissue.is_some() {
        // The physical axis compares both fiber models with the FEM.
        grid.fibers = vec![fibfluid::sim::FiberModel::Paper, fibfluid::sim::FiberModel::Projected];
    }
    grid.modes = flags.modes.unwrap_or(grid.modes);
    grid.steppings = flags.steppings.unwrap_or(grid.steppings);
    grid.precisions = flags.precisions.unwrap_or(grid.precisions);
    let bar = ProgressBar::new(0);
    bar.set_style(
        ProgressStyle::with_template("accuracy [{bar:30}] {pos}/{len} runs ({elapsed})")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    let study = run_study(&scene, &grid, &|k, n| {
        bar.set_length(n as u64);
        bar.set_position(k as u64);
    })?;
    bar.finish_and_clear();
    let title = format!("{} ({} vertices)", scene.name, scene.n_vertices());
    let csv = to_csv(&study);
    let md = to_markdown(&study, &title);
    // The charts draw the structured f64 lines (the table has every backend and precision);
    // the Pareto front is over the whole grid.
    let png = chart(
        &study,
        &format!("{title}: round-trip error vs time"),
        "round-trip error (Eq. 9)",
        |p| p.roundtrip_error,
        Precision::F64,
        Backend::Structured,
    )?;
    let png_ref = chart(
        &study,
        &format!("{title}: distance to the converged reference vs time"),
        "distance to reference",
        |p| p.reference_distance,
        Precision::F64,
        Backend::Structured,
    )?;
    let mut files = vec![
        ("accuracy.csv", csv.into_bytes()),
        ("accuracy.md", md.into_bytes()),
        ("accuracy.png", png),
        ("accuracy-reference.png", png_ref),
    ];
    if let Some(png_fem) =
        fibfluid_cli::study::physical_chart(&study, &format!("{title}: difference from the FEM vs time"))?
    {
        files.push(("accuracy-fem.png", png_fem));
    }
    if let Some(grab) = study.physical.as_ref().and_then(|a| a.grab.as_ref()) {
        let png =
            fibfluid_cli::grab::chart(grab, &format!("{title}: one grasp, difference from the FEM vs time"))?;
        files.push(("accuracy-grab.csv", fibfluid_cli::grab::to_csv(grab).into_bytes()));
        files.push(("accuracy-grab.png", png));
    }
    fibfluid_cli::write_files_atomically(out, &files)?;
    for (name, _) in &files {
        say!("wrote {}", out.join(name).display());
    }
    let ok = study.points.iter().filter(|p| p.error.is_none()).count();
    say!("{ok} of {} configurations ran; {} skipped", study.points.len(), study.skipped.len());
    Ok(())
}
