//! `fibfluid compare`: one grab path replayed with the three methods.

use std::path::PathBuf;

use fibfluid::Scene;
use fibfluid::compare::{COMPARE_FILES, run_compare};
use fibfluid::probe::interact::Storage;
use fibfluid::probe::{ProbeOptions, ToolPath};

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
    /// Storage of FFM's precomputed response (f64, f32).
    #[arg(long, default_value = "f64")]
    precision: Storage,
    /// Memory budget in bytes per method (default: half the available memory).
    #[arg(long, value_name = "BYTES")]
    max_memory: Option<u64>,
}

/// Runs `fibfluid compare`.
pub fn run(args: &CompareArgs) -> Result<(), crate::CliError> {
    let scene = Scene::load(&args.scene)?;
    let path = ToolPath::load(&args.path)?;
    let opts = ProbeOptions { storage: args.precision, max_memory_bytes: args.max_memory };
    let report = run_compare(&scene, &path, &args.out, &opts)?;
    println!("{}: {} vertices, {} frames", report.scene, report.vertices, report.frames);
    println!(
        "{:<22} {:>9} {:>10} {:>10} {:>10} {:>10} {:>9} {:>9} {:>9}",
        "method", "setup s", "memory B", "p50 us", "p99 us", "max us", "dV max", "rest d", "rms/ffm"
    );
    for (name, m) in &report.methods {
        println!(
            "{:<22} {:>9.3} {:>10} {:>10.1} {:>10.1} {:>10.1} {:>9.2e} {:>9.2e} {:>9.2e}",
            name,
            m.setup_seconds,
            m.memory_bytes,
            m.latency_us.p50,
            m.latency_us.p99,
            m.latency_us.max,
            m.volume_change_max,
            m.rest_distance_after_release,
            m.surface_rms_vs_ffm
        );
    }
    for f in COMPARE_FILES {
        println!("  wrote {}", args.out.join(f).display());
    }
    Ok(())
}
