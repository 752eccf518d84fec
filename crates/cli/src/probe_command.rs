//! `fibfluid probe`'s arguments and printing: replay a tool path on a scene's body (the run
//! and its files are `fibfluid_cli::probe_run`).

use std::path::PathBuf;

use fibfluid::interact::{Method, RefreshMode};
use fibfluid::{Scene, load_tool_path};
use fibfluid_cli::probe_run::{PROBE_FILES, run_probe_with};

/// Arguments of `fibfluid probe`.
#[derive(clap::Args)]
pub struct ProbeArgs {
    /// Scene TOML file (probed in paper mode about its rest shape, its loads as the base).
    scene: PathBuf,
    #[command(flatten)]
    response: crate::response_flags::ResponseFlags,
    /// Tool path CSV: `frame,vertex,ux,uy,uz` (grab), `frame,vertex,fx,fy,fz` (force), `frame,vertex,ux,uy,uz,radius` (grasp a patch) or `frame,x,y,z,radius` (press a spherical tip); lengths in the mesh unit.
    #[arg(long)]
    path: PathBuf,
    /// Output directory (frames.csv, final.obj, report.json, probe.png).
    #[arg(long)]
    out: PathBuf,
    /// Deformation method: ffm, fem, tsve-chainmail or generalized-chainmail; default: the
    /// scene's `[solver] method` (ChainMail is displacement-driven: grab paths only; its
    /// settings come from the scene's [chainmail] section).
    #[arg(long)]
    method: Option<Method>,
}

/// Runs `fibfluid probe`.
pub fn run(args: &ProbeArgs) -> Result<(), crate::CliError> {
    let scene = Scene::load(&args.scene)?;
    let method = args.method.unwrap_or(scene.model.solver.method);
    for w in fibfluid::ineffective_interactive(&scene) {
        tell!("warning: {w}");
    }
    let opts = args.response.options(RefreshMode::Scheduled, &scene, &[method])?;
    let path = load_tool_path(&args.path)?;
    // Long replays report their progress with an estimate of the time left.
    let progress = crate::progress(path.frames(), "probe");
    let report = run_probe_with(&scene, &path, &args.out, &opts, method, progress.as_deref())?;
    for w in &report.warnings {
        tell!("warning: {w}");
    }
    let l = report.probe.latency_us;
    say!(
        "{} ({}): {} vertices, {} frames ({} path, {} probed), precompute {:.3} s, {:.1} MiB ({}), frame latency p50 {:.1} us, p99 {:.1} us, max {:.1} us",
        report.scene,
        report.method,
        report.probe.vertices,
        report.probe.frames,
        report.kind.name(),
        report.probe.probed_vertices,
        report.probe.precompute_seconds,
        report.probe.memory_bytes as f64 / 1048576.0,
        report.precision,
        l.p50,
        l.p99,
        l.max
    );
    for f in PROBE_FILES {
        say!("  wrote {}", args.out.join(f).display());
    }
    Ok(())
}
