//! `fibfluid sweep`: one `fibfluid run` per combination of the `--set` values (their
//! cartesian product), run as parallel processes of this executable, each into its own
//! directory `run-001`, `run-002`, ...; `sweep.csv` holds a row per combination in order.

use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use fibfluid::Scene;
use fibfluid::fem::hyper::Parameter;
use fibfluid::sim::Model;

use crate::CliError;

/// The file of one row per run.
pub const SWEEP_FILE: &str = "sweep.csv";

/// Arguments of `fibfluid sweep`.
#[derive(clap::Args)]
pub struct SweepArgs {
    /// Scene TOML file.
    scene: PathBuf,
    /// A parameter and its values, `KEY=V1,V2,...` (keys as `[fit]` names them:
    /// tissue.young, region.NAME.poisson, gravity, ...); repeated, the runs are every
    /// combination.
    #[arg(long = "set", value_name = "KEY=V1,V2,..", required = true)]
    set: Vec<String>,
    /// Output directory: run-001, run-002, ... (each what `fibfluid run` writes) and sweep.csv.
    #[arg(long)]
    out: PathBuf,
    /// Runs at once (default: the machine's cores); each run gets the cores divided by this.
    #[arg(long)]
    jobs: Option<usize>,
}

/// A `--set` value: the key, what it names on the model, and its values (checked on a copy
/// of the model, so a value the tissue refuses is an error before anything runs).
pub struct Assignment {
    /// The dotted key as given.
    pub key: String,
    /// What it names.
    pub parameter: Parameter,
    /// Its values, in order.
    pub values: Vec<f64>,
}

/// Reads `KEY=V1,V2,...` against `model`.
///
/// Errors: no `=`, an unknown key, no value, a value that is not a finite number or that the
/// tissue refuses ([`CliError::Set`]).
pub fn assignment(text: &str, model: &Model) -> Result<Assignment, CliError> {
    let bad = |problem: String| CliError::Set { value: text.to_string(), problem };
    let Some((key, values)) = text.split_once('=') else {
        return Err(bad("expected KEY=VALUE (for example tissue.young=3000)".into()));
    };
    let key = key.trim();
    let parameter = fibfluid::scene::parameter_of_key(key, model).map_err(&bad)?;
    let values = values
        .split(',')
        .map(str::trim)
        .filter(|v| !v.is_empty())
        .map(|v| {
            v.parse::<f64>()
                .ok()
                .filter(|x| x.is_finite())
                .ok_or_else(|| bad(format!("`{v}` is not a finite number")))
        })
        .collect::<Result<Vec<f64>, CliError>>()?;
    if values.is_empty() {
        return Err(bad(format!("no value for `{key}`")));
    }
    let mut probe = model.clone();
    for &v in &values {
        fibfluid::sim::inverse::set_parameter(&mut probe, parameter, v)
            .map_err(|e| bad(format!("`{key}` = {v}: {}", crate::one_line(&e.to_string()))))?;
    }
    Ok(Assignment { key: key.to_string(), parameter, values })
}

/// Applies `run --set KEY=VALUE` values (one value each) to `scene`.
pub fn apply_sets(sets: &[String], scene: &mut Scene) -> Result<(), CliError> {
    for text in sets {
        let a = assignment(text, &scene.model)?;
        if a.values.len() != 1 {
            return Err(CliError::Set {
                value: text.clone(),
                problem: "`run` takes one value per key (`sweep` takes several)".into(),
            });
        }
        fibfluid::sim::inverse::set_parameter(&mut scene.model, a.parameter, a.values[0])?;
    }
    Ok(())
}

/// What one run gave: its values, the status (`ok` or the error line), the largest
/// displacement (m), the plates' final forces (N) and its seconds.
struct Row {
    values: Vec<f64>,
    status: String,
    max_displacement: Option<f64>,
    plate_forces: Vec<f64>,
    seconds: f64,
}

/// Every combination of the assignments' values, the last key varying fastest.
fn combinations(sets: &[Assignment]) -> Vec<Vec<f64>> {
    sets.iter().fold(vec![vec![]], |acc, a| {
        acc.iter()
            .flat_map(|head| {
                a.values.iter().map(move |&v| {
                    let mut c = head.clone();
                    c.push(v);
                    c
                })
            })
            .collect()
    })
}

/// Runs `fibfluid sweep`.
pub fn run(args: &SweepArgs) -> Result<(), CliError> {
    let scene = Scene::load(&args.scene)?;
    let sets = args.set.iter().map(|s| assignment(s, &scene.model)).collect::<Result<Vec<_>, _>>()?;
    for (i, a) in sets.iter().enumerate() {
        if sets[..i].iter().any(|b| b.parameter == a.parameter) {
            return Err(CliError::Set {
                value: args.set[i].clone(),
                problem: format!("`{}` is set twice", a.key),
            });
        }
    }
    let cores = fibfluid::linalg::parallel::cores();
    let jobs = args.jobs.unwrap_or(cores);
    if jobs == 0 {
        return Err(CliError::Flag { flag: "jobs", value: "0".into(), problem: "must be at least 1" });
    }
    fibfluid_cli::check_output_dir(&args.out, &[SWEEP_FILE])?;
    let combos = combinations(&sets);
    let width = combos.len().to_string().len().max(3);
    let names: Vec<String> = (1..=combos.len()).map(|k| format!("run-{k:0width$}")).collect();
    if let Some(blocked) = names.iter().map(|n| args.out.join(n)).find(|p| p.exists() && !p.is_dir()) {
        return Err(fibfluid_cli::Error::OutputBlocked {
            path: blocked,
            problem: "is a file, where a run's directory would go (nothing was run)",
        }
        .into());
    }
    let exe = std::env::current_exe()
        .map_err(|source| fibfluid_cli::Error::Io { path: PathBuf::from("fibfluid"), source })?;
    let jobs = jobs.min(combos.len());
    let threads = (cores / jobs).max(1);
    let next = AtomicUsize::new(0);
    let done = AtomicUsize::new(0);
    let rows: Mutex<Vec<Option<Row>>> = Mutex::new((0..combos.len()).map(|_| None).collect());
    std::thread::scope(|s| {
        for _ in 0..jobs {
            s.spawn(|| {
                loop {
                    let k = next.fetch_add(1, Ordering::SeqCst);
                    let Some(values) = combos.get(k) else { break };
                    let dir = args.out.join(&names[k]);
                    let row = one_run(&exe, &args.scene, &dir, &sets, values, threads);
                    let n = done.fetch_add(1, Ordering::SeqCst) + 1;
                    tell!(
                        "sweep: {} {} ({:.1} s), {n} of {}",
                        names[k],
                        row.status,
                        row.seconds,
                        combos.len()
                    );
                    if let Ok(mut rows) = rows.lock() {
                        rows[k] = Some(row);
                    }
                }
            });
        }
    });
    let rows: Vec<Row> = rows.into_inner().unwrap_or_default().into_iter().flatten().collect();
    let keys: Vec<&str> = sets.iter().map(|a| a.key.as_str()).collect();
    let csv = sweep_csv(&keys, &names, &rows, scene.model.plates.len());
    let written = fibfluid_cli::write_files_atomically(&args.out, &[(SWEEP_FILE, csv.into_bytes())])?;
    let failed = rows.iter().filter(|r| r.status != "ok").count();
    for w in written {
        say!("wrote {} ({} runs, {} ok)", w.display(), rows.len(), rows.len() - failed);
    }
    if failed > 0 {
        return Err(CliError::SweepFailed { csv: args.out.join(SWEEP_FILE), failed, total: rows.len() });
    }
    Ok(())
}

/// Runs this executable's `run` on one combination into `dir`; reads its report back.
fn one_run(exe: &Path, scene: &Path, dir: &Path, sets: &[Assignment], values: &[f64], threads: usize) -> Row {
    let start = Instant::now();
    let mut command = std::process::Command::new(exe);
    command.arg("--threads").arg(threads.to_string()).arg("run").arg(scene).arg("--out").arg(dir);
    for (a, v) in sets.iter().zip(values) {
        command.arg("--set").arg(format!("{}={v:?}", a.key));
    }
    let output = command.stdin(std::process::Stdio::null()).output();
    let seconds = start.elapsed().as_secs_f64();
    let mut row = Row {
        values: values.to_vec(),
        status: String::new(),
        max_displacement: None,
        plate_forces: vec![],
        seconds,
    };
    row.status = match output {
        Err(e) => format!("could not start {}: {e}", exe.display()),
        Ok(o) if !o.status.success() => {
            let err = String::from_utf8_lossy(&o.stderr);
            err.lines()
                .rev()
                .find_map(|l| l.strip_prefix("error: "))
                .map(str::to_string)
                .unwrap_or_else(|| format!("run ended with {}", o.status))
        }
        Ok(_) => match read_report(&dir.join("report.json")) {
            Ok((u, forces)) => {
                row.max_displacement = Some(u);
                row.plate_forces = forces;
                "ok".into()
            }
            Err(e) => e,
        },
    };
    row
}

/// The largest displacement (m) and the plates' final forces (N) of a run's `report.json`
/// (`plates[].force`: a finite-element run's number, else the last of FFM's per step).
fn read_report(path: &Path) -> Result<(f64, Vec<f64>), String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let report: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))?;
    let u = report["result"]["max_displacement"]
        .as_f64()
        .or_else(|| report["max_displacement"].as_f64())
        .ok_or_else(|| format!("{}: no max_displacement", path.display()))?;
    let forces = report["plates"]
        .as_array()
        .into_iter()
        .flatten()
        .filter_map(|p| p["force"].as_f64().or_else(|| p["force"].as_array()?.last()?.as_f64()))
        .collect();
    Ok((u, forces))
}

/// `sweep.csv`: a row per run (its directory, the values, the status, max |u| in m, each
/// plate's final force in N, the seconds); a status with a comma or quote is quoted.
fn sweep_csv(keys: &[&str], names: &[String], rows: &[Row], plates: usize) -> String {
    let mut header = vec!["run".to_string()];
    header.extend(keys.iter().map(|k| k.to_string()));
    header.extend(["status".into(), "max_displacement_m".into()]);
    header.extend((1..=plates).map(|k| format!("plate_{k}_force_N")));
    header.push("seconds".into());
    let mut text = header.join(",") + "\n";
    for (name, r) in names.iter().zip(rows) {
        let mut fields = vec![name.clone()];
        fields.extend(r.values.iter().map(|v| format!("{v:?}")));
        let status = if r.status.contains([',', '"', '\n']) {
            format!("\"{}\"", r.status.replace('"', "\"\"").replace('\n', " "))
        } else {
            r.status.clone()
        };
        fields.push(status);
        fields.push(r.max_displacement.map(|u| format!("{u:e}")).unwrap_or_default());
        fields
            .extend((0..plates).map(|k| r.plate_forces.get(k).map(|f| format!("{f:e}")).unwrap_or_default()));
        fields.push(format!("{:.3}", r.seconds));
        text.push_str(&fields.join(","));
        text.push('\n');
    }
    text
}
