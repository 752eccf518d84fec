//! `fibfluid probe`: replay a tool path on a scene's precomputed response.

use std::path::PathBuf;

use fibfluid::fem::TissueModel;
use fibfluid::interact::{Method, Precompute, ProbeOptions, RefreshMode, Storage};
use fibfluid::{Scene, load_tool_path};
use fibfluid_cli::probe_run::{PROBE_FILES, run_probe_with};

/// The flags of the precomputed response, shared by `probe`, `compare` and `view`.
#[derive(clap::Args)]
pub struct ResponseFlags {
    /// Storage of FFM's full precomputed response (f64, f32; the lazy response is f64).
    #[arg(long, default_value = "f64")]
    pub precision: Storage,
    /// FFM's response: `lazy` computes a vertex's compliance columns when it is first
    /// touched, with the base solve's factorization (the first frame comes right after the
    /// base solve); `full` inverts the stiffness first (N^3 flops, N^2 words: every vertex
    /// ready at once, for haptic devices).
    #[arg(long, default_value = "lazy")]
    pub precompute: Precompute,
    /// Memory budget in bytes (default: half the available memory).
    #[arg(long, value_name = "BYTES")]
    pub max_memory: Option<u64>,
    /// The neo-Hookean FEM body's linearization is refreshed (one iteration: Newton's, or
    /// a chord step on the kept factor, `--chord-refreshes`) before every K-th frame, in
    /// the frame loop. Default: `probe` and `compare` pick K from the
    /// body's counts (reproducible); `view` refreshes on a second thread.
    #[arg(long, value_name = "K")]
    pub refresh_every: Option<u64>,
    /// Neo-Hookean FEM body: refreshes that keep the tangent's factor and move only the
    /// state (chord iterations) between two that factor it; 0: every refresh is a Newton
    /// iteration. Default: 4.
    #[arg(long, value_name = "N")]
    pub chord_refreshes: Option<usize>,
}

impl ResponseFlags {
    /// The probe options these flags set; `refresh` unless `--refresh-every` is given.
    ///
    /// Errors: `--refresh-every 0`, and `--refresh-every` or `--chord-refreshes` when none
    /// of `methods` builds a neo-Hookean FEM body of `scene` (the only body they act on).
    pub fn options(
        &self,
        refresh: RefreshMode,
        scene: &Scene,
        methods: &[Method],
    ) -> Result<ProbeOptions, crate::CliError> {
        if self.refresh_every == Some(0) {
            return Err(crate::CliError::Flag {
                flag: "refresh-every",
                value: "0".into(),
                problem: "must be at least 1",
            });
        }
        let neo_hookean = scene.tissue.is_some_and(|t| t.model() == TissueModel::NeoHookean);
        let two_rate = neo_hookean && methods.contains(&Method::Fem);
        let given = [
            ("refresh-every", self.refresh_every.map(|k| k.to_string())),
            ("chord-refreshes", self.chord_refreshes.map(|n| n.to_string())),
        ];
        if let Some((flag, Some(value))) = given.into_iter().find(|(_, v)| v.is_some())
            && !two_rate
        {
            return Err(crate::CliError::Flag {
                flag,
                value,
                problem: "acts only on a neo-Hookean FEM body (--method fem on a scene whose [tissue] model is \"neo-hookean\")",
            });
        }
        Ok(ProbeOptions {
            storage: self.precision,
            precompute: self.precompute,
            max_memory_bytes: self.max_memory,
            refresh: self.refresh_every.map_or(refresh, RefreshMode::EveryFrames),
            chord_refreshes: self.chord_refreshes,
        })
    }
}

/// Arguments of `fibfluid probe`.
#[derive(clap::Args)]
pub struct ProbeArgs {
    /// Scene TOML file (probed in paper mode about its rest shape, its loads as the base).
    scene: PathBuf,
    #[command(flatten)]
    response: ResponseFlags,
    /// Tool path CSV: `frame,vertex,ux,uy,uz` (grab), `frame,vertex,fx,fy,fz` (force), `frame,vertex,ux,uy,uz,radius` (grasp a patch) or `frame,x,y,z,radius` (press a spherical tip); lengths in the mesh unit.
    #[arg(long)]
    path: PathBuf,
    /// Output directory (frames.csv, final.obj, report.json, probe.png).
    #[arg(long)]
    out: PathBuf,
    /// Deformation method: ffm, tsve-chainmail or generalized-chainmail (ChainMail is
    /// displacement-driven: grab paths only; its settings come from the scene's
    /// [chainmail] section).
    #[arg(long, default_value = "ffm")]
    method: Method,
}

/// Runs `fibfluid probe`.
pub fn run(args: &ProbeArgs) -> Result<(), crate::CliError> {
    let scene = Scene::load(&args.scene)?;
    for w in fibfluid::ineffective_interactive(&scene) {
        tell!("warning: {w}");
    }
    let path = load_tool_path(&args.path)?;
    let opts = args.response.options(RefreshMode::Scheduled, &scene, &[args.method])?;
    // Long replays report their progress with an estimate of the time left.
    let progress = crate::progress(path.frames(), "probe");
    let report = run_probe_with(&scene, &path, &args.out, &opts, args.method, progress.as_deref())?;
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
