//! `fibfluid accuracy`: the accuracy-versus-time study of a scene.

use std::path::Path;

use fibfluid::accuracy::{Grid, chart, run_study, to_csv, to_markdown};
use fibfluid::linalg::Precision;
use fibfluid::{Error, Mode, Scene, Stepping};
use indicatif::{ProgressBar, ProgressStyle};

/// Runs the grid and writes accuracy.csv, accuracy.md, accuracy.png and
/// accuracy-reference.png into `out` (all or nothing).
pub fn run(
    scene_path: &Path,
    out: &Path,
    steps: &[usize],
    backends: Option<Vec<String>>,
    modes: Option<Vec<String>>,
    steppings: Option<Vec<String>>,
    precisions: Option<Vec<String>>,
    constraints: Option<String>,
) -> Result<(), Error> {
    let mut scene = Scene::load(scene_path)?;
    // The grid sets the modes, so the scene's own mode says nothing about stiffening here.
    for w in fibfluid::ineffective(&scene) {
        if !matches!(w, fibfluid::Ineffective::StiffeningOutsideNonlinear { .. }) {
            eprintln!("warning: {w}");
        }
    }
    if let Some(c) = constraints {
        scene.solver.constraints = match c.as_str() {
            "penalty" => fibfluid::assembly::ConstraintMethod::PAPER,
            "eliminate" => fibfluid::assembly::ConstraintMethod::Eliminate,
            o => return Err(Error::Invalid(format!("--constraints: `{o}` is not penalty or eliminate"))),
        };
    }
    let mut grid = Grid { steps: steps.to_vec(), ..Grid::default() };
    if steps.is_empty() || steps.contains(&0) {
        return Err(Error::Invalid("--steps: give positive step counts".into()));
    }
    if let Some(b) = backends {
        for name in &b {
            fibfluid::linalg::backend_by_name(name)
                .map_err(|e| Error::Invalid(format!("--backends: {e}")))?;
        }
        grid.backends = b;
    }
    if let Some(m) = modes {
        grid.modes = m
            .iter()
            .map(|s| {
                Mode::parse(s).ok_or_else(|| {
                    Error::Invalid(format!("--modes: `{s}` is not paper, refresh or nonlinear"))
                })
            })
            .collect::<Result<_, _>>()?;
    }
    if let Some(m) = steppings {
        grid.steppings = m
            .iter()
            .map(|s| {
                Stepping::parse(s)
                    .ok_or_else(|| Error::Invalid(format!("--steppings: `{s}` is not euler or heun")))
            })
            .collect::<Result<_, _>>()?;
    }
    if let Some(p) = precisions {
        grid.precisions = p
            .iter()
            .map(|s| match s.as_str() {
                "f64" => Ok(Precision::F64),
                "mixed" => Ok(Precision::Mixed),
                o => Err(Error::Invalid(format!("--precisions: `{o}` is not f64 or mixed"))),
            })
            .collect::<Result<_, _>>()?;
    }
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
        "f64",
        "structured",
    )?;
    let png_ref = chart(
        &study,
        &format!("{title}: distance to the converged reference vs time"),
        "distance to reference",
        |p| p.reference_distance,
        "f64",
        "structured",
    )?;
    let files = [
        ("accuracy.csv", csv.into_bytes()),
        ("accuracy.md", md.into_bytes()),
        ("accuracy.png", png),
        ("accuracy-reference.png", png_ref),
    ];
    fibfluid::write_files_atomically(out, &files)?;
    for (name, _) in &files {
        println!("wrote {}", out.join(name).display());
    }
    let ok = study.points.iter().filter(|p| p.error.is_none()).count();
    println!("{ok} of {} configurations ran; {} skipped", study.points.len(), study.skipped.len());
    Ok(())
}
