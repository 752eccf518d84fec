//! The `fibfluid` command line.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;
use std::time::Instant;

use clap::{Parser, Subcommand};
use fibfluid::stages::{StageRecord, names};
use fibfluid::{
    Backend, ConstraintKind, Method, Mode, Plan, Precision, Report, RunOptions, Scene, SetupOptions,
    Simulation, Stepping,
};
use fibfluid_cli::MeshInfo;
use indicatif::{ProgressBar, ProgressStyle};
use say::num;

#[macro_use]
mod say;
mod accuracy;
mod compare_command;
mod fit_command;
mod probe_command;
mod response_flags;
mod sweep_command;
mod validate_command;
mod view;

/// Soft tissue as fluid held by elastic fibers: the fiber–fluid method.
#[derive(Parser)]
#[command(name = "fibfluid", version, about)]
struct Cli {
    /// Threads for the linear backends and rayon (default: all cores; at least 1, more than
    /// 4 per core is lowered with a note).
    #[arg(long, global = true)]
    threads: Option<usize>,
    /// Largest mesh or scene file read, in bytes (suffixes K, M, G, T; default 2G, or the
    /// FIBFLUID_MAX_FILE_BYTES variable).
    #[arg(long, global = true, value_name = "BYTES", value_parser = byte_count)]
    max_file_bytes: Option<u64>,
    #[command(subcommand)]
    command: Command,
}

/// What the command line can get wrong before the library is called.
#[derive(Debug, thiserror::Error)]
enum CliError {
    /// An error of the library or of writing outputs.
    #[error(transparent)]
    Lib(#[from] fibfluid_cli::Error),
    /// An icosphere radius whose coordinates do not make a valid mesh in f64.
    #[error("--radius {radius}: {source}")]
    Radius {
        /// The radius given.
        radius: f64,
        /// What is wrong with the scaled mesh.
        source: fibfluid::geometry::MeshError,
    },
    /// A flag value out of its range.
    #[error("--{flag} {value}: {problem}")]
    Flag {
        /// The flag.
        flag: &'static str,
        /// The value given.
        value: String,
        /// What is wrong.
        problem: &'static str,
    },
    /// An error of the engine on a scene: the scene file named once.
    #[error("{}", engine_message(path, source))]
    Engine {
        /// The scene file.
        path: PathBuf,
        /// What failed.
        source: fibfluid::sim::Error,
    },
    /// A `--set KEY=VALUE` that names no parameter or gives no usable value.
    #[error("--set {value}: {problem}")]
    Set {
        /// The value given.
        value: String,
        /// What is wrong.
        problem: String,
    },
    /// Runs of a sweep that failed (their errors are in `sweep.csv`).
    #[error("{failed} of {total} runs failed (their errors are in {})", csv.display())]
    SweepFailed {
        /// The sweep's table.
        csv: PathBuf,
        /// The runs that failed.
        failed: usize,
        /// All runs.
        total: usize,
    },
    /// A `fibfluid validate --case` that names no case.
    #[error("--case {name}: names no case (cases: {cases})")]
    UnknownCase {
        /// The name given.
        name: String,
        /// The cases there are.
        cases: String,
    },
    /// Cases of `fibfluid validate` outside their tolerance (the table says by how much).
    #[error("outside their tolerance: {cases}")]
    ValidationFailed {
        /// The cases' names.
        cases: String,
    },
    /// An error of the viewer (binding, building a body).
    #[error(transparent)]
    Viewer(#[from] fibfluid_viewer::ViewerError),
}

/// The engine's message with the scene file in front, unless it names the scene already.
fn engine_message(path: &Path, e: &fibfluid::sim::Error) -> String {
    let text = e.to_string();
    let name = path.display().to_string();
    if text.starts_with(&name) { text } else { format!("{name}: {text}") }
}

/// Wraps an engine error with the scene file it ran on.
fn in_scene(path: &Path) -> impl Fn(fibfluid::sim::Error) -> CliError + '_ {
    move |source| CliError::Engine { path: path.to_path_buf(), source }
}

/// Errors that reach the command line through the library's error type.
macro_rules! through_lib {
    ($($t:ty),*) => {$(
        impl From<$t> for CliError {
            fn from(e: $t) -> Self {
                CliError::Lib(e.into())
            }
        }
    )*};
}
through_lib!(
    fibfluid::Error,
    fibfluid::sim::Error,
    fibfluid::interact::ProbeError,
    fibfluid::geometry::GeometryError,
    fibfluid::linalg::LinalgError,
    serde_json::Error
);

#[derive(Subcommand)]
enum Command {
    /// Summarize a mesh: size, area, volume, convexity and kept fibers.
    MeshInfo {
        /// OBJ, STL, PLY or OFF file.
        mesh: PathBuf,
        /// Print one JSON object.
        #[arg(long)]
        json: bool,
        /// Also write the kept fibers as VTK lines.
        #[arg(long, value_name = "FILE.vtk")]
        fibers: Option<PathBuf>,
    },
    /// Write an icosphere OBJ (subdivided icosahedron).
    Icosphere {
        /// Subdivision level (0 = icosahedron).
        #[arg(long, default_value_t = 2)]
        level: u32,
        /// Radius.
        #[arg(long, default_value_t = 1.0)]
        radius: f64,
        /// Output OBJ file.
        #[arg(long)]
        out: PathBuf,
    },
    /// Print the plan of a scene: which stages run, which are skipped and why, their
    /// memory and flops; exit 2 when it does not fit in memory.
    Plan {
        /// Scene TOML file.
        scene: PathBuf,
        #[command(flatten)]
        over: Overrides,
        /// Print one JSON object.
        #[arg(long)]
        json: bool,
    },
    /// Run a scene; write deformed.obj, deformed.vtk, deformed.vtp, report.json and render.png.
    Run {
        /// Scene TOML file.
        scene: PathBuf,
        /// Output directory.
        #[arg(long)]
        out: PathBuf,
        #[command(flatten)]
        over: Overrides,
    },
    /// Compress then decompress and print the round-trip error (paper Eq. 9).
    Roundtrip {
        /// Scene TOML file.
        scene: PathBuf,
        #[command(flatten)]
        over: Overrides,
        /// Print one JSON object.
        #[arg(long)]
        json: bool,
    },
    /// Compare the compiled-in linear backends on this machine.
    Bench {
        /// Vertex counts N (systems of size 3N+1).
        #[arg(long, value_delimiter = ',', default_value = "250,1000")]
        sizes: Vec<usize>,
        /// Timed repeats per backend and size (the median is reported).
        #[arg(long, default_value_t = 5)]
        repeats: usize,
        /// Print a JSON array.
        #[arg(long)]
        json: bool,
        /// Instead of the backends: this scene's assembly, factorization and checked solve
        /// beside their limits on this machine (bandwidth and matrix-product rate measured
        /// in the same run).
        #[arg(long, value_name = "SCENE")]
        stages: Option<PathBuf>,
        /// With --stages: measure the stages once per thread count (for example 1,2,4,8),
        /// in one process, so each stage's scaling on this machine reads as ratios.
        #[arg(long, value_delimiter = ',', value_name = "T,..", requires = "stages")]
        threads_sweep: Option<Vec<usize>>,
        /// Instead of the backends: this neo-Hookean scene's two-rate FEM body against its
        /// linear FEM body on --path, frames paced at 1 kHz (frame p99 ratio; refresh over
        /// one batch Newton iteration).
        #[arg(long, value_name = "SCENE", conflicts_with = "stages")]
        two_rate: Option<PathBuf>,
        /// With --two-rate: the tool path CSV to replay.
        #[arg(long, value_name = "PATH")]
        path: Option<PathBuf>,
        /// Instead of the backends: this scene's finite-element run with each of
        /// --solvers at each of --resolutions (time per Newton iteration, whole run, peak
        /// memory, the multigrid's distance from the direct answer).
        #[arg(long, value_name = "SCENE", conflicts_with_all = ["stages", "two_rate"])]
        fem_solvers: Option<PathBuf>,
        /// With --fem-solvers: the resolutions (cells along the longest side).
        #[arg(
            long,
            value_delimiter = ',',
            value_name = "R,..",
            default_value = "16,24,32",
            requires = "fem_solvers"
        )]
        resolutions: Vec<usize>,
        /// With --fem-solvers: the solvers (direct, multigrid, auto).
        #[arg(
            long,
            value_delimiter = ',',
            value_name = "S,..",
            default_value = "direct,multigrid",
            requires = "fem_solvers"
        )]
        solvers: Vec<fibfluid::fem::FemSolver>,
    },
    /// Accuracy versus time over modes, stepping, steps, precision and backends.
    Accuracy {
        /// Scene TOML file.
        scene: PathBuf,
        /// Output directory (accuracy.csv, accuracy.md, accuracy.png).
        #[arg(long)]
        out: PathBuf,
        #[command(flatten)]
        grid: accuracy::GridFlags,
    },
    /// Replay a tool path (grabs, forces, grasps or a pressing tip per frame) on the scene's precomputed response;
    /// write frames.csv, final.obj, report.json and probe.png.
    Probe(probe_command::ProbeArgs),
    /// Serve a live viewer: drag the scene's surface in a browser (or over a WebSocket).
    View(view::ViewArgs),
    /// Replay one grab path with FFM, TSVE-ChainMail and Generalized ChainMail; write
    /// compare.json and compare.png.
    Compare(compare_command::CompareArgs),
    /// Fit the scene's [fit] parameters (tissue and region moduli, densities, gravity) to
    /// observed surface positions; write fit.json.
    Fit(fit_command::FitArgs),
    /// Run the scene once per combination of the --set values, in parallel processes; write
    /// run-001, run-002, ... (each what `run` writes) and sweep.csv.
    Sweep(sweep_command::SweepArgs),
    /// Run the field's benchmarks (homogeneous tests, the thick sphere, the cantilever,
    /// Hertz) against their references; print the table (exit 1 when a case misses its
    /// tolerance).
    Validate(validate_command::ValidateArgs),
}

/// Command-line overrides of the scene's `[solver]` and `[load]` settings; each flag
/// overrides only its own scene key.
#[derive(clap::Args, Clone, Default)]
struct Overrides {
    /// Linear backend (structured, faer-lu, nalgebra-lu, openblas-lu).
    #[arg(long)]
    backend: Option<Backend>,
    /// Stepping mode (paper, refresh, nonlinear).
    #[arg(long)]
    mode: Option<Mode>,
    /// Stepping scheme (euler, heun).
    #[arg(long)]
    stepping: Option<Stepping>,
    /// Load steps.
    #[arg(long)]
    steps: Option<usize>,
    /// Precision (f64, mixed).
    #[arg(long)]
    precision: Option<Precision>,
    /// Constraint method (penalty, eliminate); the scene's `penalty` value is kept.
    #[arg(long)]
    constraints: Option<ConstraintKind>,
    /// Method of a batch run: ffm or fem (the finite-element reference; needs [tissue]).
    #[arg(long)]
    method: Option<Method>,
    /// Cells along the longest side of the finite-element grid (`[fem] resolution`).
    #[arg(long)]
    resolution: Option<usize>,
    /// The finite-element method's linear solver (`[fem] solver`: auto, direct, multigrid).
    #[arg(long)]
    fem_solver: Option<fibfluid::fem::FemSolver>,
    /// Refuse the scene when its plan needs more than this many bytes (default: the
    /// machine's memory).
    #[arg(long, value_name = "BYTES")]
    max_memory: Option<u64>,
    /// A tissue, region or gravity parameter, `KEY=VALUE` (keys as `[fit]` names them:
    /// tissue.young, region.NAME.poisson, gravity, ...); repeated for several.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<String>,
}

impl Overrides {
    fn apply(&self, scene: &mut Scene) -> Result<(), CliError> {
        let s = &mut scene.solver;
        if let Some(b) = self.backend {
            b.solver().map_err(fibfluid::sim::Error::from)?;
            s.backend = b;
        }
        s.mode = self.mode.unwrap_or(s.mode);
        s.stepping = self.stepping.unwrap_or(s.stepping);
        s.precision = self.precision.unwrap_or(s.precision);
        s.constraints = self.constraints.unwrap_or(s.constraints);
        if let Some(m) = self.method {
            if m.is_chainmail() {
                return Err(CliError::Flag {
                    flag: "method",
                    value: m.to_string(),
                    problem: "a batch run is ffm or fem (ChainMail is interactive: probe, compare, view)",
                });
            }
            if m == Method::Ffm && !scene.ffm_material {
                return Err(CliError::Flag {
                    flag: "method",
                    value: m.to_string(),
                    problem: "the scene has no [material] table for FFM",
                });
            }
            scene.model.solver.method = m;
        }
        if let Some(r) = self.resolution {
            if !(1..=fibfluid::fem::MAX_RESOLUTION).contains(&r) {
                return Err(CliError::Flag {
                    flag: "resolution",
                    value: r.to_string(),
                    problem: "must be between 1 and 256",
                });
            }
            scene.model.fem.resolution = r;
        }
        scene.model.fem.solver = self.fem_solver.unwrap_or(scene.model.fem.solver);
        if let Some(n) = self.steps {
            if !(1..=fibfluid::MAX_STEPS).contains(&n) {
                return Err(CliError::Flag {
                    flag: "steps",
                    value: n.to_string(),
                    problem: "must be between 1 and 1000000",
                });
            }
            scene.load.steps = n;
        }
        sweep_command::apply_sets(&self.set, scene)
    }

    fn setup(&self) -> SetupOptions {
        SetupOptions { max_memory: self.max_memory, ..Default::default() }
    }
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            if e.use_stderr() {
                // clap's message is several lines; keep the one that says what is wrong.
                let text = e.to_string();
                let first = text.lines().find(|l| !l.trim().is_empty()).unwrap_or("invalid arguments");
                tell!("{}", first.trim());
                return ExitCode::from(2);
            }
            say!("{}", e.to_string().trim_end());
            return ExitCode::SUCCESS;
        }
    };
    if let Some(n) = cli.threads {
        match fibfluid::linalg::threads::try_set_threads(n) {
            Ok(setting) => setting.note().into_iter().for_each(|note| tell!("note: {note}")),
            Err(e) => {
                tell!("error: --threads {n}: {}", one_line(&e.to_string()));
                return ExitCode::from(2);
            }
        }
    }
    if let Some(limit) = cli.max_file_bytes {
        fibfluid::geometry::set_max_file_bytes(limit);
    }
    match run(cli.command) {
        Ok(()) => ExitCode::SUCCESS,
        // A measurement outside its tolerance is not a user error: exit 1.
        Err(e @ CliError::ValidationFailed { .. }) => {
            tell!("error: {e}");
            ExitCode::from(1)
        }
        Err(e) => {
            tell!("error: {}", one_line(&e.to_string()));
            ExitCode::from(2)
        }
    }
}

/// Parses `--max-file-bytes` (a byte count with an optional K, M, G or T suffix).
fn byte_count(s: &str) -> Result<u64, String> {
    fibfluid::geometry::parse_byte_count(s)
        .ok_or_else(|| format!("`{s}` is not a positive byte count (e.g. 1073741824, 512M, 4G)"))
}

/// Prints each setting of the scene that cannot act as a `warning:` line on stderr.
fn warn_ineffective(scene: &Scene) {
    for w in fibfluid::ineffective(scene) {
        tell!("warning: {w}");
    }
}

fn one_line(s: &str) -> String {
    s.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// Seconds between the plain progress lines printed when stderr is not a terminal.
const PROGRESS_LINE_SECONDS: f64 = 10.0;

/// Progress of a long run on stderr, with an estimate of the time left: a bar on a
/// terminal, else a plain line every [`PROGRESS_LINE_SECONDS`] (logs and pipes).
fn progress(total: usize, what: &str) -> Option<Arc<dyn Fn(usize, usize) + Send + Sync>> {
    if total < 2 {
        return None;
    }
    if !std::io::IsTerminal::is_terminal(&std::io::stderr()) {
        let what = what.to_string();
        let start = Instant::now();
        let last = std::sync::Mutex::new(0.0f64);
        return Some(Arc::new(move |k, n| {
            let elapsed = start.elapsed().as_secs_f64();
            let Ok(mut last) = last.lock() else { return };
            if k < n && elapsed - *last >= PROGRESS_LINE_SECONDS && k > 0 {
                *last = elapsed;
                let left = elapsed / k as f64 * (n - k) as f64;
                tell!("{what}: step {k} of {n}, {elapsed:.0} s so far, about {left:.0} s left");
            }
        }));
    }
    let bar = ProgressBar::new(total as u64);
    bar.set_style(
        ProgressStyle::with_template("{msg} [{bar:30}] {pos}/{len} steps ({elapsed}, about {eta} left)")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    bar.set_message(what.to_string());
    Some(Arc::new(move |k, n| {
        bar.set_position(k as u64);
        if k == n {
            bar.finish_and_clear();
        }
    }))
}

fn run(command: Command) -> Result<(), CliError> {
    match command {
        Command::MeshInfo { mesh, json, fibers } => mesh_info(&mesh, json, fibers.as_deref()),
        Command::Icosphere { level, radius, out } => {
            if level > 7 {
                return Err(CliError::Flag {
                    flag: "level",
                    value: level.to_string(),
                    problem: "at most 7 (163842 vertices; each level has 10 * 4^level + 2)",
                });
            }
            if !(radius.is_finite() && radius > 0.0) {
                return Err(CliError::Flag {
                    flag: "radius",
                    value: radius.to_string(),
                    problem: "must be positive",
                });
            }
            // Built at radius 1 and scaled here, so a radius whose products overflow or
            // underflow f64 is the mesh check's error, not a panic of the generator.
            let unit = fibfluid::geometry::icosphere(level, 1.0);
            let scaled = unit.positions().iter().map(|p| p.map(|c| c * radius)).collect();
            let m = fibfluid::geometry::TriMesh::new(scaled, unit.triangles().to_vec())
                .and_then(|mut m| m.validate().map(|_| m))
                .map_err(|source| CliError::Radius { radius, source })?;
            fibfluid::geometry::write_obj(&out, m.positions(), m.triangles())?;
            tell!("wrote {} ({} vertices, {} faces)", out.display(), m.n_vertices(), m.n_faces());
            Ok(())
        }
        Command::Plan { scene, over, json } => plan(&scene, &over, json),
        Command::Run { scene, out, over } => run_scene(&scene, &out, &over),
        Command::Roundtrip { scene, over, json } => roundtrip(&scene, &over, json),
        Command::Bench { fem_solvers: Some(scene), resolutions, solvers, json, .. } => {
            bench_fem_solvers(&scene, &resolutions, &solvers, json)
        }
        Command::Bench { two_rate: Some(scene), path: Some(path), json, .. } => {
            bench_two_rate(&scene, &path, json)
        }
        // Each flag of the pair named when the other is missing (one line, not clap's list).
        Command::Bench { two_rate: Some(scene), path: None, .. } => Err(CliError::Flag {
            flag: "two-rate",
            value: scene.display().to_string(),
            problem: "needs --path FILE too (the tool path CSV to replay on the scene)",
        }),
        Command::Bench { two_rate: None, path: Some(path), .. } => Err(CliError::Flag {
            flag: "path",
            value: path.display().to_string(),
            problem: "needs --two-rate SCENE too (the neo-Hookean scene to replay the path on)",
        }),
        Command::Bench { stages: Some(scene), repeats, json, threads_sweep: Some(sweep), .. } => {
            bench_sweep(&scene, repeats, json, &sweep)
        }
        Command::Bench { stages: Some(scene), repeats, json, .. } => bench_stages(&scene, repeats, json),
        Command::Bench { sizes, repeats, json, stages: None, .. } => bench(&sizes, repeats, json),
        Command::Accuracy { scene, out, grid } => accuracy::run(&scene, &out, grid),
        Command::Probe(args) => probe_command::run(&args),
        Command::View(args) => view::run(&args),
        Command::Compare(args) => compare_command::run(&args),
        Command::Fit(args) => fit_command::run(&args),
        Command::Sweep(args) => sweep_command::run(&args),
        Command::Validate(args) => validate_command::run(&args),
    }
}

fn mesh_info(path: &Path, json: bool, fibers_out: Option<&Path>) -> Result<(), CliError> {
    let (info, fibers) = MeshInfo::of_file(path)?;
    if let Some(out) = fibers_out {
        let io = |source| fibfluid_cli::Error::Io { path: out.into(), source };
        let file = fibfluid::geometry::load_mesh(path)?;
        let mut f = std::io::BufWriter::new(std::fs::File::create(out).map_err(io)?);
        fibfluid_cli::write_fibers_vtk(&mut f, file.mesh.positions(), &fibers).map_err(io)?;
        std::io::Write::flush(&mut f).map_err(io)?;
    }
    if json {
        say!("{}", serde_json::to_string(&info)?);
        return Ok(());
    }
    let (lo, hi) = (info.bbox_min, info.bbox_max);
    say!("{}", info.path);
    say!("  vertices        {} ({} in the file)", info.vertices, info.file_vertices);
    say!("  faces           {}", info.faces);
    say!("  closed          yes, genus {}", info.topology.genus);
    for (k, v) in info.topology.cavities.iter().enumerate() {
        say!("  cavity {:<8} volume {}", k + 1, num(*v));
    }
    say!(
        "  bounding box    [{}, {}, {}] .. [{}, {}, {}]",
        num(lo[0]),
        num(lo[1]),
        num(lo[2]),
        num(hi[0]),
        num(hi[1]),
        num(hi[2])
    );
    say!(
        "  area            {}  (sum |S_i| = {})",
        num(info.measures.area),
        num(info.measures.vertex_area_sum)
    );
    say!("  volume          {}", num(info.measures.volume));
    say!(
        "  convex          {}",
        if info.fibers.convex { "yes (every fiber kept, no test ran)" } else { "no" }
    );
    say!(
        "  fibers          {} of {} kept ({:.1} %; exit test removed {}, crossing test {})",
        info.fibers.fibers_kept,
        info.fibers.fibers_total,
        100.0 * info.fibers.fibers_kept as f64 / info.fibers.fibers_total.max(1) as f64,
        info.fibers.fibers_removed_exit,
        info.fibers.fibers_removed_crossing
    );
    say!("  seconds         {:.3} (load, check, cull)", info.seconds);
    for n in &info.notes {
        say!("  note: {n}");
    }
    Ok(())
}

fn load_scene(path: &Path, over: &Overrides) -> Result<(Scene, StageRecord), CliError> {
    let start = Instant::now();
    let mut scene = Scene::load(path)?;
    over.apply(&mut scene)?;
    let rec = StageRecord {
        name: names::LOAD_SCENE,
        parent: None,
        seconds: start.elapsed().as_secs_f64(),
        count: 1,
    };
    Ok((scene, rec))
}

fn plan(path: &Path, over: &Overrides, json: bool) -> Result<(), CliError> {
    let (scene, _) = load_scene(path, over)?;
    let limit = fibfluid::memory_budget(over.max_memory);
    // Refused from counts before the convexity check of a body that cannot fit.
    Plan::from_counts(&scene).check_memory(&scene.name, limit, scene.solver.backend)?;
    let plan = Plan::from_scene(&scene);
    let rate = fibfluid_cli::scaling::measure_gemm_rate(fibfluid_cli::scaling::RATE_PROBE_ORDER);
    let scaling = fibfluid_cli::scaling::scaling(&scene.model, limit, rate);
    if json {
        let mut value = serde_json::to_value(&plan)?;
        if let Some(map) = value.as_object_mut() {
            map.insert("machine".into(), serde_json::to_value(&scaling)?);
        }
        say!("{}", serde_json::to_string_pretty(&value)?);
    } else {
        say!(
            "{}: {} vertices, {} steps ({} / {} / {} / {})",
            scene.name,
            scene.n_vertices(),
            scene.load.steps,
            scene.solver.backend,
            scene.solver.mode,
            scene.solver.stepping,
            scene.solver.precision
        );
        say!("  {:<24} {:>4} {:>12} {:>12}  why", "stage", "run", "MiB", "GFLOP");
        for s in &plan.stages {
            say!(
                "  {:<24} {:>4} {:>12.1} {:>12.3}  {}",
                s.name,
                if s.run { "yes" } else { "no" },
                s.bytes as f64 / 1048576.0,
                s.flops / 1e9,
                s.reason
            );
        }
        say!(
            "  total: {:.1} MiB peak (limit {:.1} MiB), {:.3} GFLOP",
            plan.memory_bytes as f64 / 1048576.0,
            limit as f64 / 1048576.0,
            plan.flops / 1e9
        );
        for line in fibfluid_cli::scaling::scaling_lines(&scaling, limit) {
            say!("{line}");
        }
    }
    plan.check_memory(&scene.name, limit, scene.solver.backend)?;
    Ok(())
}

fn run_scene(path: &Path, out: &Path, over: &Overrides) -> Result<(), CliError> {
    let (scene, load) = load_scene(path, over)?;
    // The outputs' place is checked before anything is computed, not after.
    let mut names = fibfluid_cli::OUTPUT_FILES.to_vec();
    let timed = scene.fem.time.as_ref().map(|t| fibfluid_cli::frames::timed_files(t.settings.outputs()));
    if scene.solver.method == Method::Fem {
        names.push(fibfluid_cli::vtu::VOLUME_FILE);
        names.extend(timed.iter().flatten().map(String::as_str));
        if fibfluid_cli::fem_draws_plates(&scene.model) {
            names.push(fibfluid_cli::COMPRESSION_FILE);
        }
    } else if !scene.model.plates.is_empty() {
        names.push(fibfluid_cli::COMPRESSION_FILE);
    }
    fibfluid_cli::check_output_dir(out, &names)?;
    warn_ineffective(&scene);
    let notes = match &scene.shape {
        fibfluid::Shape::Surface(m) => m.notes.clone(),
        _ => vec![],
    };
    if scene.solver.method == Method::Fem {
        return run_fem(scene, load, notes, out, over);
    }
    let steps = scene.load.steps;
    let mut sim = Simulation::with_options(scene, &over.setup()).map_err(in_scene(path))?;
    let opts = RunOptions { progress: progress(steps, "run"), ..Default::default() };
    sim.run(&opts).map_err(in_scene(path))?;
    print_step_notes(&sim);
    // A non-finite answer stops here, before anything is written.
    print_result_warnings(&sim.answer_guards().map_err(in_scene(path))?);
    let start = Instant::now();
    let mut report = Report::of(&sim, std::slice::from_ref(&load), notes);
    let written = fibfluid_cli::write_outputs(out, &sim, &report)?;
    report.seconds_total += start.elapsed().as_secs_f64();
    say!(
        "{}: {} vertices, {} steps ({} / {} / {}), max |u| = {} m, volume {} -> {} m^3 (drift {:.2e}), P = {} Pa, residual {:.1e}, {:.3} s",
        report.scene,
        report.body.vertices,
        report.load.steps,
        report.solver.backend,
        report.solver.mode,
        report.solver.stepping,
        num(report.result.max_displacement),
        num(report.result.volume_initial),
        num(report.result.volume_final),
        report.result.volume_drift,
        num(report.result.pressure),
        report.cost.residual_max,
        report.seconds_total
    );
    for (k, r) in report.plates.iter().enumerate() {
        let (force, area) =
            (r.force.last().copied().unwrap_or(0.0), r.contact_area.last().copied().unwrap_or(0.0));
        say!(
            "  plate {}: force {} N, {} vertices in contact, contact area {} m^2, mean pressure {} Pa, gap {} m",
            k + 1,
            num(force),
            r.contact_vertices.last().copied().unwrap_or(0),
            num(area),
            num(if area > 0.0 { force / area } else { 0.0 }),
            num(r.gap.last().copied().unwrap_or(0.0))
        );
    }
    for w in written {
        say!("  wrote {}", w.display());
    }
    Ok(())
}

/// Guard warnings (one line each, at most [`MAX_WARNING_LINES`]) and skipped steps, on
/// stderr.
/// `run` with the finite-element method.
fn run_fem(
    scene: Scene,
    load: StageRecord,
    notes: Vec<String>,
    out: &Path,
    over: &Overrides,
) -> Result<(), CliError> {
    let path = scene.source.clone().unwrap_or_default();
    // A timed run writes each output time's volume as it comes (staged, moved in at the end).
    let mut frames = fibfluid_cli::frames::FrameWriter::new(out, &scene.name, scene.unit);
    let mut shown = time_progress("run");
    let run = fibfluid::sim::fem_run::FemRun::observed(scene, over.max_memory, &mut |frame| {
        frames.write(frame);
        shown(frame);
    })
    .map_err(in_scene(&path))?;
    print_result_warnings(&run.warnings);
    let start = Instant::now();
    let mut report = fibfluid::sim::fem_run::FemReport::of(&run, std::slice::from_ref(&load), notes);
    let written = fibfluid_cli::write_fem_outputs(out, &run, &report)?;
    let volumes = frames.finish()?;
    report.seconds_total += start.elapsed().as_secs_f64();
    let unit = run.model.unit;
    let to_unit = 1.0 / unit.metres();
    say!(
        "{}: {} vertices, fem (resolution {}, {} cells, {} unknowns), E = {} Pa, nu = {}, max |u| = {} {unit}, volume {} -> {} m^3, residual {:.1e}, {:.3} s",
        report.scene,
        report.vertices,
        report.fem.resolution,
        report.fem.cells,
        report.fem.dofs,
        num(report.tissue.young()),
        report.tissue.poisson(),
        num(report.result.max_displacement * to_unit),
        num(report.result.volume_initial),
        num(report.result.volume_final),
        report.residual,
        report.seconds_total
    );
    for (k, p) in report.supports.plates.iter().enumerate() {
        say!(
            "  plate {}: force {} N, {} surface samples in contact, deepest {} {unit}, {} augmentations",
            k + 1,
            num(p.force),
            p.contact_samples,
            num(p.penetration * to_unit),
            p.augmentations
        );
    }
    for (k, g) in report.supports.grasps.iter().enumerate() {
        let (f, m) = (g.force, g.moment);
        say!(
            "  grasp {}: {} vertices, force on the grasper [{}, {}, {}] N, moment [{}, {}, {}] N m, largest error {} {unit}",
            k + 1,
            g.vertices,
            num(f[0]),
            num(f[1]),
            num(f[2]),
            num(m[0]),
            num(m[1]),
            num(m[2]),
            num(g.error * to_unit)
        );
    }
    for w in written {
        say!("  wrote {}", w.display());
    }
    if let Some(pvd) = volumes.last() {
        say!(
            "  wrote {} and {} volumes {} to {}",
            pvd.display(),
            volumes.len() - 1,
            fibfluid_cli::frames::frame_file(0),
            fibfluid_cli::frames::frame_file(volumes.len().saturating_sub(2))
        );
    }
    Ok(())
}

/// Progress of a timed run on stderr, at each output time: the simulated time, the steps
/// and cuts (`t = 1.20 s of 10 s, 120 steps, 3 cut`): a bar on a terminal, else a plain
/// line every [`PROGRESS_LINE_SECONDS`] (logs and pipes), as [`progress`].
fn time_progress(what: &str) -> Box<dyn FnMut(&fibfluid::sim::hyper_run::TimeFrame<'_>)> {
    let line = |f: &fibfluid::sim::hyper_run::TimeFrame<'_>| {
        fibfluid_cli::series::progress_line(f.row.time, f.end, f.steps, f.cut_steps)
    };
    let start = Instant::now();
    if !std::io::IsTerminal::is_terminal(&std::io::stderr()) {
        let what = what.to_string();
        let mut last = 0.0f64;
        return Box::new(move |f| {
            let elapsed = start.elapsed().as_secs_f64();
            if f.index + 1 < f.outputs && f.index > 0 && elapsed - last >= PROGRESS_LINE_SECONDS {
                last = elapsed;
                let left = elapsed / f.row.time * (f.end - f.row.time);
                tell!("{what}: {}, {elapsed:.0} s so far, about {left:.0} s left", line(f));
            }
        });
    }
    let what = what.to_string();
    // Made at the first output: a run without time shows nothing.
    let mut shown: Option<ProgressBar> = None;
    Box::new(move |f| {
        let bar = shown.get_or_insert_with(|| {
            let bar = ProgressBar::new(f.outputs.saturating_sub(1).max(1) as u64);
            bar.set_style(
                ProgressStyle::with_template("{msg} [{bar:30}] ({elapsed}, about {eta} left)")
                    .unwrap_or_else(|_| ProgressStyle::default_bar())
                    .progress_chars("=> "),
            );
            bar
        });
        bar.set_length(f.outputs.saturating_sub(1).max(1) as u64);
        bar.set_message(format!("{what}: {}", line(f)));
        bar.set_position(f.index as u64);
        if f.index + 1 == f.outputs {
            bar.finish_and_clear();
        }
    })
}

fn print_step_notes(sim: &Simulation) {
    let warnings = sim.warnings();
    for w in warnings.iter().take(MAX_WARNING_LINES) {
        tell!("warning: {w}");
    }
    if warnings.len() > MAX_WARNING_LINES {
        tell!("warning: {} more guard warnings in report.json", warnings.len() - MAX_WARNING_LINES);
    }
    let skipped = sim.step_stats().skipped;
    if skipped > 0 {
        tell!(
            "note: {skipped} load steps changed no load (a force applied at the last step only) and were skipped without a solve"
        );
    }
}

/// The result guards that fired, one line each on stderr (they are in report.json too).
fn print_result_warnings(warnings: &[fibfluid::sim::result_guards::ResultWarning]) {
    for w in warnings {
        tell!("warning: {w}");
    }
}

/// Most guard warnings printed on stderr; the rest are in report.json.
const MAX_WARNING_LINES: usize = 10;

fn roundtrip(path: &Path, over: &Overrides, json: bool) -> Result<(), CliError> {
    let (scene, _) = load_scene(path, over)?;
    warn_ineffective(&scene);
    let steps = scene.load.steps;
    let progress = progress(2 * steps, "round trip").map(|p| {
        let done = std::sync::atomic::AtomicUsize::new(0);
        let both_ways: Arc<dyn Fn(usize, usize) + Send + Sync> = Arc::new(move |_k, _n| {
            let d = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            p(d, 2 * steps);
        });
        both_ways
    });
    let rt =
        fibfluid::roundtrip(scene, &RunOptions { progress, ..Default::default() }).map_err(in_scene(path))?;
    if json {
        say!("{}", serde_json::to_string(&rt)?);
    } else {
        say!(
            "round trip, {} steps each way ({} / {} / {}): error {:.3e} ({:.4} %), volume drift {:.3e}, {:.3} s",
            rt.steps,
            rt.backend,
            rt.mode,
            rt.stepping,
            rt.roundtrip_error,
            100.0 * rt.roundtrip_error,
            rt.volume_drift,
            rt.seconds
        );
    }
    Ok(())
}

/// `fibfluid bench --stages SCENE`.
fn bench_stages(path: &Path, repeats: usize, json: bool) -> Result<(), CliError> {
    check_repeats(repeats)?;
    let (scene, _) = load_scene(path, &Overrides::default())?;
    let name = scene.name.clone();
    let n = scene.n_vertices();
    let (rates, stages) = fibfluid_cli::bench::bench_stages(scene.model, repeats)?;
    if json {
        say!("{}", serde_json::json!({ "scene": name, "vertices": n, "machine": rates, "stages": stages }));
        return Ok(());
    }
    say!(
        "{name}: {n} vertices; this machine: read {:.1} GB/s (one thread), matrix product {:.1} GFLOP/s",
        rates.read_bytes_per_second / 1e9,
        rates.gemm_flops_per_second / 1e9
    );
    say!("{:<14} {:>10} {:>10} {:>7}  limit", "stage", "seconds", "limit s", "ratio");
    for s in &stages {
        say!("{:<14} {:>10.4} {:>10.4} {:>7.2}  {}", s.stage, s.seconds, s.limit_seconds, s.ratio, s.limit);
    }
    Ok(())
}

/// `fibfluid bench --fem-solvers SCENE --resolutions R,.. --solvers S,..`.
fn bench_fem_solvers(
    path: &Path,
    resolutions: &[usize],
    solvers: &[fibfluid::fem::FemSolver],
    json: bool,
) -> Result<(), CliError> {
    if let Some(&r) = resolutions.iter().find(|&&r| !(1..=fibfluid::fem::MAX_RESOLUTION).contains(&r)) {
        return Err(CliError::Flag {
            flag: "resolutions",
            value: r.to_string(),
            problem: "must be between 1 and 256",
        });
    }
    let (scene, _) = load_scene(path, &Overrides::default())?;
    let rows = fibfluid_cli::bench_fem::bench_fem_solvers(&scene.model, resolutions, solvers)?;
    if json {
        say!("{}", serde_json::json!({ "scene": scene.name, "runs": rows }));
        return Ok(());
    }
    say!(
        "{:>10} {:>9} {:>8} {:>8} {:>7} {:>9} {:>11} {:>9} {:>10} {:>11}",
        "resolution",
        "solver",
        "cells",
        "unknowns",
        "newton",
        "cg/solve",
        "s/newton",
        "run s",
        "peak MB",
        "vs direct"
    );
    for r in &rows {
        say!(
            "{:>10} {:>9} {:>8} {:>8} {:>7} {:>9.1} {:>11.3} {:>9.2} {:>10} {:>11}",
            r.resolution,
            r.solver.to_string(),
            r.cells,
            r.dofs,
            r.newton_iterations,
            r.iterations_per_solve,
            r.seconds_per_newton_iteration,
            r.seconds,
            r.peak_bytes.map_or("-".to_string(), |b| format!("{:.0}", b as f64 / 1e6)),
            r.from_direct.map_or("-".to_string(), |d| format!("{d:.1e}")),
        );
    }
    Ok(())
}

/// `fibfluid bench --two-rate SCENE --path PATH`: the two-rate body against the linear one.
fn bench_two_rate(scene: &Path, path: &Path, json: bool) -> Result<(), CliError> {
    let (scene, _) = load_scene(scene, &Overrides::default())?;
    let path = fibfluid::load_tool_path(path)?;
    let b = fibfluid_cli::bench_two_rate::bench_two_rate(&scene, &path, None)?;
    if json {
        say!("{}", serde_json::to_string(&b).unwrap_or_default());
        return Ok(());
    }
    say!(
        "{}: {} frames per body, one every 1 ms; tracking error at {} frames (every {}) against Newton converged",
        scene.name,
        b.frames,
        b.samples,
        fibfluid_cli::bench_two_rate::SAMPLE_EVERY
    );
    let (l, e) = (b.linear_latency_us, &b.linear_tracking);
    say!("linear FEM           frame p50 {:>8.1} us  p99 {:>8.1} us  max {:>9.1} us", l.p50, l.p99, l.max);
    say!(
        "                     tracking error mean {:.4}  largest {:.4}  last {:.4}",
        e.mean,
        e.largest,
        e.last
    );
    say!("one batch Newton iteration {:.3} s", b.newton_iteration_seconds);
    for run in [&b.newton_only, &b.fixed_chords, &b.two_rate] {
        print_two_rate_run(run);
    }
    Ok(())
}

/// One two-rate body's lines of `bench --two-rate`.
fn print_two_rate_run(r: &fibfluid_cli::bench_two_rate::TwoRateRun) {
    let t = r.latency_us;
    say!("two-rate, chord refreshes per refactorization: {}", r.chords);
    say!("                     frame p50 {:>8.1} us  p99 {:>8.1} us  max {:>9.1} us", t.p50, t.p99, t.max);
    say!("                     frame p99 ratio {:.2} (over the linear body's)", r.frame_p99_ratio);
    say!(
        "                     refreshes {} ({} refactorizations), {:.1} Hz over the replay, {:.1} Hz running",
        r.refreshes,
        r.refactorizations,
        r.refresh_hz,
        r.running_hz
    );
    say!(
        "                     refresh {:.3} s mean (chord {:.3} s, refactorization {:.3} s), ratio {:.2} to a batch Newton iteration",
        r.refresh_seconds,
        r.chord_seconds,
        r.refactor_seconds,
        r.refresh_ratio
    );
    let e = &r.tracking;
    say!(
        "                     tracking error mean {:.4}  largest {:.4}  last {:.4}",
        e.mean,
        e.largest,
        e.last
    );
    if r.failures > 0 {
        let why = r.first_failure.as_deref().unwrap_or("");
        tell!(
            "warning: {} refreshes failed (the frames kept the last good linearization): {why}",
            r.failures
        );
    }
}

/// `fibfluid bench --stages SCENE --threads-sweep T,..`: one table, a column per count.
fn bench_sweep(path: &Path, repeats: usize, json: bool, sweep: &[usize]) -> Result<(), CliError> {
    let cap = fibfluid::linalg::threads::thread_cap();
    if let Some(&t) = sweep.iter().find(|&&t| !(1..=cap).contains(&t)) {
        return Err(CliError::Flag {
            flag: "threads-sweep",
            value: t.to_string(),
            problem: "each count must be between 1 and 4 per available core",
        });
    }
    check_repeats(repeats)?;
    let (scene, _) = load_scene(path, &Overrides::default())?;
    let (name, n) = (scene.name.clone(), scene.n_vertices());
    let rows = fibfluid_cli::bench::bench_stages_sweep(&scene.model, repeats, sweep)?;
    if json {
        say!("{}", serde_json::json!({ "scene": name, "vertices": n, "sweep": rows }));
        return Ok(());
    }
    let cores = fibfluid::linalg::parallel::cores();
    say!("{name}: {n} vertices; {cores} cores; seconds per stage (ratio to its limit in the same run)");
    let header: String = rows
        .iter()
        .map(|r| format!(" {:>17}", format!("T={} (uses {})", r.threads, r.compute_threads)))
        .collect();
    say!("{:<14}{header}", "stage");
    for (i, stage) in rows.first().map(|r| r.stages.as_slice()).unwrap_or_default().iter().enumerate() {
        let cells: String = rows
            .iter()
            .map(|r| format!(" {:>9.4} ({:>5.2})", r.stages[i].seconds, r.stages[i].ratio))
            .collect();
        say!("{:<14}{cells}", stage.stage);
    }
    let gemm: String = rows
        .iter()
        .map(|r| format!(" {:>17}", format!("{:.1} GFLOP/s", r.machine.gemm_flops_per_second / 1e9)))
        .collect();
    say!("{:<14}{gemm}", "GEMM rate");
    Ok(())
}

/// `--repeats` must be between 1 and 1000.
fn check_repeats(repeats: usize) -> Result<(), CliError> {
    if !(1..=1000).contains(&repeats) {
        return Err(CliError::Flag {
            flag: "repeats",
            value: repeats.to_string(),
            problem: "must be between 1 and 1000",
        });
    }
    Ok(())
}

fn bench(sizes: &[usize], repeats: usize, json: bool) -> Result<(), CliError> {
    if let Some(&n) = sizes.iter().find(|n| !fibfluid_cli::bench::BENCH_SIZES.contains(n)) {
        return Err(CliError::Flag {
            flag: "sizes",
            value: n.to_string(),
            problem: "out of range (4..20000)",
        });
    }
    check_repeats(repeats)?;
    let mut rows = Vec::new();
    for &n in sizes {
        for row in fibfluid_cli::bench::bench_backends(n, repeats)? {
            match row {
                Ok(r) => rows.push(r),
                Err((backend, e)) => tell!("{backend} at N = {n}: {}", one_line(&e.to_string())),
            }
        }
    }
    if json {
        say!("{}", serde_json::to_string(&rows)?);
        return Ok(());
    }
    say!(
        "{:<12} {:>6} {:>7} {:>12} {:>12} {:>9} {:>10}",
        "backend",
        "N",
        "dim",
        "factor s",
        "solve s",
        "GFLOP/s",
        "MiB"
    );
    for r in &rows {
        say!(
            "{:<12} {:>6} {:>7} {:>12.5} {:>12.6} {:>9.2} {:>10.1}",
            r.backend.to_string(),
            r.n_vertices,
            r.dim,
            r.factor_seconds,
            r.solve_seconds,
            r.factor_gflops,
            r.memory_bytes as f64 / 1048576.0
        );
    }
    say!(
        "(medians of {repeats} warm runs after one warm-up; the structured backend factors N x N blocks, the dense ones the (3N+1)^2 matrix)"
    );
    Ok(())
}
