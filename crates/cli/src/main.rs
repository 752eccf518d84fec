//! The `fibfluid` command line.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;
use std::time::Instant;

use clap::{Parser, Subcommand};
use fibfluid::geometry::{VisibilityOptions, cull_fibers, load_mesh, self_intersections};
use fibfluid::linalg::{FactorizationExt, Precision};
use fibfluid::stages::StageRecord;
use fibfluid::{Error, Mode, Report, RunOptions, Scene, Simulation, Stepping};
use indicatif::{ProgressBar, ProgressStyle};
use serde_json::json;

mod accuracy;

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

#[derive(Subcommand)]
enum Command {
    /// Summarize a mesh: size, area, volume, convexity and kept fibers.
    MeshInfo {
        /// OBJ or STL file.
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
    /// Run a scene; write deformed.obj, deformed.vtk, report.json and render.png.
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
        /// Print a JSON array.
        #[arg(long)]
        json: bool,
    },
    /// Accuracy versus time over modes, stepping, steps, precision and backends.
    Accuracy {
        /// Scene TOML file.
        scene: PathBuf,
        /// Output directory (accuracy.csv, accuracy.md, accuracy.png).
        #[arg(long)]
        out: PathBuf,
        /// Step counts of the grid.
        #[arg(long, value_delimiter = ',', default_value = "1,3,10,30,100")]
        steps: Vec<usize>,
        /// Backends (default: every compiled-in one).
        #[arg(long, value_delimiter = ',')]
        backends: Option<Vec<String>>,
        /// Modes (default: paper, refresh, nonlinear).
        #[arg(long, value_delimiter = ',')]
        modes: Option<Vec<String>>,
        /// Stepping schemes (default: euler, heun).
        #[arg(long, value_delimiter = ',')]
        steppings: Option<Vec<String>>,
        /// Precisions (default: f64, mixed).
        #[arg(long, value_delimiter = ',')]
        precisions: Option<Vec<String>>,
        /// Override the scene's constraint method (penalty, eliminate).
        #[arg(long)]
        constraints: Option<String>,
    },
}

/// Command-line overrides of the scene's [solver] and [load] settings.
#[derive(clap::Args, Clone, Default)]
struct Overrides {
    /// Linear backend (structured, faer-lu, nalgebra-lu, openblas-lu).
    #[arg(long)]
    backend: Option<String>,
    /// Stepping mode (paper, refresh, nonlinear).
    #[arg(long)]
    mode: Option<String>,
    /// Stepping scheme (euler, heun).
    #[arg(long)]
    stepping: Option<String>,
    /// Load steps.
    #[arg(long)]
    steps: Option<usize>,
    /// Precision (f64, mixed).
    #[arg(long)]
    precision: Option<String>,
    /// Constraint method (penalty, eliminate).
    #[arg(long)]
    constraints: Option<String>,
}

impl Overrides {
    fn apply(&self, scene: &mut Scene) -> Result<(), Error> {
        let bad =
            |what: &str, v: &str, ok: &str| Error::Invalid(format!("--{what}: `{v}` is not one of {ok}"));
        if let Some(b) = &self.backend {
            fibfluid::linalg::backend_by_name(b).map_err(|e| Error::Invalid(format!("--backend: {e}")))?;
            scene.solver.backend = b.clone();
        }
        if let Some(m) = &self.mode {
            scene.solver.mode = Mode::parse(m).ok_or_else(|| bad("mode", m, "paper, refresh, nonlinear"))?;
        }
        if let Some(s) = &self.stepping {
            scene.solver.stepping = Stepping::parse(s).ok_or_else(|| bad("stepping", s, "euler, heun"))?;
        }
        if let Some(n) = self.steps {
            if n == 0 {
                return Err(Error::Invalid("--steps: must be at least 1".into()));
            }
            scene.steps = n;
        }
        if let Some(p) = &self.precision {
            scene.solver.precision = match p.as_str() {
                "f64" => Precision::F64,
                "mixed" => Precision::Mixed,
                _ => return Err(bad("precision", p, "f64, mixed")),
            };
        }
        if let Some(c) = &self.constraints {
            scene.solver.constraints = match c.as_str() {
                "penalty" => fibfluid::assembly::ConstraintMethod::PAPER,
                "eliminate" => fibfluid::assembly::ConstraintMethod::Eliminate,
                _ => return Err(bad("constraints", c, "penalty, eliminate")),
            };
        }
        Ok(())
    }
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            let _ = e.print();
            return if e.use_stderr() { ExitCode::from(2) } else { ExitCode::SUCCESS };
        }
    };
    if let Some(n) = cli.threads {
        match fibfluid::linalg::threads::try_set_threads(n) {
            Ok(setting) => setting.note().into_iter().for_each(|note| eprintln!("note: {note}")),
            Err(e) => {
                eprintln!("error: --threads {n}: {}", one_line(&e.to_string()));
                return ExitCode::from(2);
            }
        }
    }
    if let Some(limit) = cli.max_file_bytes {
        fibfluid::geometry::set_max_file_bytes(limit);
    }
    match run(cli.command) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", one_line(&e.to_string()));
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
        eprintln!("warning: {w}");
    }
}

fn one_line(s: &str) -> String {
    s.split_whitespace().collect::<Vec<_>>().join(" ")
}

fn progress(total: usize, what: &str) -> Option<Arc<dyn Fn(usize, usize) + Send + Sync>> {
    if total < 2 {
        return None;
    }
    let bar = ProgressBar::new(total as u64);
    bar.set_style(
        ProgressStyle::with_template("{msg} [{bar:30}] {pos}/{len} steps ({elapsed})")
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

fn run(command: Command) -> Result<(), Error> {
    match command {
        Command::MeshInfo { mesh, json, fibers } => mesh_info(&mesh, json, fibers.as_deref()),
        Command::Icosphere { level, radius, out } => {
            if level > 7 {
                return Err(Error::Invalid(format!("--level {level}: at most 7 (655362 vertices)")));
            }
            if !(radius.is_finite() && radius > 0.0) {
                return Err(Error::Invalid(format!("--radius {radius}: must be positive")));
            }
            // Built at radius 1 and scaled here, so a radius whose products overflow or
            // underflow f64 is the mesh check's error, not a panic of the generator.
            let unit = fibfluid::geometry::icosphere(level, 1.0);
            let scaled = unit.positions().iter().map(|p| p.map(|c| c * radius)).collect();
            let m = fibfluid::geometry::TriMesh::new(scaled, unit.triangles().to_vec())
                .and_then(|mut m| m.validate().map(|_| m))
                .map_err(|e| Error::Invalid(format!("--radius {radius}: {e}")))?;
            fibfluid::geometry::write_obj(&out, m.positions(), m.triangles())?;
            eprintln!("wrote {} ({} vertices, {} faces)", out.display(), m.n_vertices(), m.n_faces());
            Ok(())
        }
        Command::Run { scene, out, over } => run_scene(&scene, &out, &over),
        Command::Roundtrip { scene, over, json } => roundtrip(&scene, &over, json),
        Command::Bench { sizes, json } => bench(&sizes, json),
        Command::Accuracy { scene, out, steps, backends, modes, steppings, precisions, constraints } => {
            accuracy::run(&scene, &out, &steps, backends, modes, steppings, precisions, constraints)
        }
    }
}

fn mesh_info(path: &Path, json: bool, fibers_out: Option<&Path>) -> Result<(), Error> {
    let start = Instant::now();
    let file = load_mesh(path)?;
    let mesh = &file.mesh;
    let (fibers, vis) = cull_fibers(mesh, &VisibilityOptions::default());
    let seconds = start.elapsed().as_secs_f64();
    let crossings = self_intersections(mesh);
    let mut notes = file.notes.clone();
    if !crossings.is_empty() {
        notes.push(format!(
            "the surface intersects itself: {} face pairs cross (e.g. faces {} and {}); fibers near them may be culled inconsistently",
            crossings.len(),
            crossings[0].0,
            crossings[0].1
        ));
    }
    let area = mesh.area();
    let s_sum: f64 = mesh.vertex_area_vectors().iter().map(|s| fibfluid::geometry::vec3::norm(*s)).sum();
    if let Some(out) = fibers_out {
        let mut f = std::io::BufWriter::new(
            std::fs::File::create(out).map_err(|source| Error::Io { path: out.into(), source })?,
        );
        fibfluid::write_fibers_vtk(&mut f, mesh.positions(), &fibers)
            .map_err(|source| Error::Io { path: out.into(), source })?;
        std::io::Write::flush(&mut f).map_err(|source| Error::Io { path: out.into(), source })?;
    }
    if json {
        let v = json!({
            "path": path.display().to_string(),
            "vertices": mesh.n_vertices(),
            "faces": mesh.n_faces(),
            "file_vertices": file.file_vertex_count(),
            "area": area,
            "vertex_area_sum": s_sum,
            "volume": mesh.volume(),
            "closed": true,
            "genus": file.validation.genus,
            "flipped": file.validation.flipped,
            "convex": vis.convex,
            "fibers_total": fibers.total(),
            "fibers_kept": fibers.kept(),
            "fibers_removed_exit": vis.removed_by_exit,
            "fibers_removed_crossing": vis.removed_by_crossing,
            "self_intersections": crossings.len(),
            "notes": notes,
            "seconds": seconds,
        });
        println!("{v}");
    } else {
        let (lo, hi) = mesh.bounding_box();
        println!("{}", path.display());
        println!("  vertices        {} ({} in the file)", mesh.n_vertices(), file.file_vertex_count());
        println!("  faces           {}", mesh.n_faces());
        println!("  closed          yes, genus {}", file.validation.genus);
        println!(
            "  bounding box    [{:.4}, {:.4}, {:.4}] .. [{:.4}, {:.4}, {:.4}]",
            lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]
        );
        println!("  area            {area:.6}  (sum |S_i| = {s_sum:.6})");
        println!("  volume          {:.6}", mesh.volume());
        println!(
            "  convex          {}",
            if vis.convex { "yes (every fiber kept, no test ran)" } else { "no" }
        );
        println!(
            "  fibers          {} of {} kept ({:.1} %; exit test removed {}, crossing test {})",
            fibers.kept(),
            fibers.total(),
            100.0 * fibers.kept() as f64 / fibers.total().max(1) as f64,
            vis.removed_by_exit,
            vis.removed_by_crossing
        );
        println!("  seconds         {seconds:.3} (load, check, cull)");
        for n in &notes {
            println!("  note: {n}");
        }
    }
    Ok(())
}

fn load_scene(path: &Path, over: &Overrides) -> Result<(Scene, StageRecord), Error> {
    let start = Instant::now();
    let mut scene = Scene::load(path)?;
    over.apply(&mut scene)?;
    let rec =
        StageRecord { name: "load scene and mesh".into(), seconds: start.elapsed().as_secs_f64(), count: 1 };
    Ok((scene, rec))
}

fn run_scene(path: &Path, out: &Path, over: &Overrides) -> Result<(), Error> {
    let (scene, load) = load_scene(path, over)?;
    warn_ineffective(&scene);
    let notes = match &scene.shape {
        fibfluid::Shape::Surface(m) => m.notes.clone(),
        _ => vec![],
    };
    let steps = scene.steps;
    let mut sim = Simulation::new(scene)?;
    let opts = RunOptions { progress: progress(steps, "run") };
    sim.run(&opts)?;
    let start = Instant::now();
    let mut report = Report::of(&sim, std::slice::from_ref(&load), notes);
    let written = fibfluid::write_outputs(out, &sim, &report)?;
    report.seconds_total += start.elapsed().as_secs_f64();
    println!(
        "{}: {} vertices, {} steps ({} / {} / {}), max |u| = {:.6}, volume {:.6} -> {:.6} (drift {:.2e}), P = {:.6}, residual {:.1e}, {:.3} s",
        report.scene,
        report.vertices,
        report.steps,
        report.backend,
        report.mode,
        report.stepping,
        report.max_displacement,
        report.volume_initial,
        report.volume_final,
        report.volume_drift,
        report.pressure,
        report.residual_max,
        report.seconds_total
    );
    for w in written {
        println!("  wrote {}", w.display());
    }
    Ok(())
}

fn roundtrip(path: &Path, over: &Overrides, json: bool) -> Result<(), Error> {
    let (scene, _) = load_scene(path, over)?;
    warn_ineffective(&scene);
    let steps = scene.steps;
    let rt = fibfluid::roundtrip(
        scene,
        &RunOptions {
            progress: progress(2 * steps, "round trip").map(|p| {
                let p2: Arc<dyn Fn(usize, usize) + Send + Sync> = Arc::new({
                    let done = std::sync::atomic::AtomicUsize::new(0);
                    move |_k, _n| {
                        let d = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
                        p(d, 2 * steps);
                    }
                });
                p2
            }),
        },
    )?;
    if json {
        println!("{}", serde_json::to_string(&rt).map_err(|e| Error::Invalid(e.to_string()))?);
    } else {
        println!(
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

fn bench(sizes: &[usize], json: bool) -> Result<(), Error> {
    let mut rows = Vec::new();
    for &n in sizes {
        if !(4..=20000).contains(&n) {
            return Err(Error::Invalid(format!("--sizes: {n} is out of range (4..20000)")));
        }
        let system = fibfluid::bench::synthetic_system(n, fibfluid::assembly::ConstraintMethod::Eliminate)?;
        let rhs: Vec<f64> =
            (0..system.matrix.dim()).map(|i| ((i * 7919) % 1000) as f64 / 1000.0 - 0.5).collect();
        for backend in fibfluid::linalg::all_backends() {
            let name = backend.name();
            let f = match backend.factorize(&system.matrix, &Default::default()) {
                Ok(f) => f,
                Err(e) => {
                    eprintln!("{name} at N = {n}: {e}");
                    continue;
                }
            };
            let cost = f.cost();
            let reps = 5;
            let start = Instant::now();
            let mut residual: f64 = 0.0;
            for _ in 0..reps {
                residual = residual.max(f.solve(&rhs)?.relative_residual);
            }
            let solve_seconds = start.elapsed().as_secs_f64() / reps as f64;
            rows.push(json!({
                "backend": name,
                "n_vertices": n,
                "dim": system.matrix.dim(),
                "factor_seconds": cost.seconds,
                "solve_seconds": solve_seconds,
                "factor_gflops": cost.flops / cost.seconds.max(1e-12) / 1e9,
                "memory_bytes": cost.bytes,
                "residual": residual,
            }));
        }
    }
    if json {
        println!("{}", serde_json::Value::Array(rows));
    } else {
        println!(
            "{:<12} {:>6} {:>7} {:>12} {:>12} {:>9} {:>10}",
            "backend", "N", "dim", "factor s", "solve s", "GFLOP/s", "MiB"
        );
        for r in rows {
            println!(
                "{:<12} {:>6} {:>7} {:>12.5} {:>12.6} {:>9.2} {:>10.1}",
                r["backend"].as_str().unwrap_or(""),
                r["n_vertices"],
                r["dim"],
                r["factor_seconds"].as_f64().unwrap_or(0.0),
                r["solve_seconds"].as_f64().unwrap_or(0.0),
                r["factor_gflops"].as_f64().unwrap_or(0.0),
                r["memory_bytes"].as_f64().unwrap_or(0.0) / 1048576.0
            );
        }
        println!("(the structured backend factors N x N blocks; the dense ones the (3N+1)^2 matrix)");
    }
    Ok(())
}
