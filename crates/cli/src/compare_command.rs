//! `fibfluid compare`'s arguments and printing: one grab path replayed with every method
//! (the run and its files are `fibfluid_cli::compare_run`).

use std::path::PathBuf;

use fibfluid::{Scene, load_tool_path};
use fibfluid_cli::compare_run::{COMPARE_FILES, run_compare};

/// Arguments of `fibfluid compare`.
#[derive(clap::Args)]
pub struct CompareArgs {
    /// Scene TOML file (its [chainmail] section sets the ChainMail lattice and material).
    scene: PathBuf,
    /// Grab path CSV: `frame,vertex,ux,uy,uz`.
    #[arg(long)]
    path: PathBuf,
    /// Output directory (compare.json, compare.png).
    #[arg(long)]
    out: PathBuf,
    #[command(flatten)]
    response: crate::response_flags::ResponseFlags,
}

/// Runs `fibfluid compare`.
pub fn run(args: &CompareArgs) -> Result<(), crate::CliError> {
    let scene = Scene::load(&args.scene)?;
    for w in fibfluid::ineffective_interactive(&scene) {
        tell!("warning: {w}");
    }
    // The comparison replays the FEM body among the others when the scene gives [tissue].
    let methods = [fibfluid::interact::Method::Fem];
    let opts = args.response.options(fibfluid::interact::RefreshMode::Scheduled, &scene, &methods)?;
    let path = load_tool_path(&args.path)?;
    let report = run_compare(&scene, &path, &args.out, &opts)?;
    for (method, m) in &report.methods {
        for w in &m.warnings {
            tell!("warning: {method}: {w}");
        }
    }
    say!(
        "{}: {} vertices, {} frames; {} against {}",
        report.scene,
        report.vertices,
        report.frames,
        report.compared,
        report.reference
    );
    say!(
        "{:<22} {:>9} {:>10} {:>10} {:>10} {:>9} {:>9} {:>9}",
        "method",
        "setup s",
        "memory B",
        "p50 us",
        "p99 us",
        "error",
        "worst",
        "dV max"
    );
    for (name, m) in &report.methods {
        say!(
            "{:<22} {:>9.3} {:>10} {:>10.1} {:>10.1} {:>9.3} {:>9.3} {:>9.2e}",
            name,
            m.setup_seconds,
            m.memory_bytes,
            m.latency_us.p50,
            m.latency_us.p99,
            m.error_vs_reference,
            m.worst_vertex_error,
            m.volume_change_max
        );
    }
    for (name, why) in &report.skipped {
        say!("{name:<22} skipped: {why}");
    }
    for f in COMPARE_FILES {
        say!("  wrote {}", args.out.join(f).display());
    }
    Ok(())
}
