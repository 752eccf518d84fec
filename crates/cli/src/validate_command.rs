//! `fibfluid validate`: runs the field's benchmarks ([`fibfluid_validate::cases`]) and prints
//! a table (case, quantity, reference and its source, fibfluid at two resolutions, errors,
//! tolerance); `--out DIR` also writes `validation.json` and `validation.csv`.

use std::path::PathBuf;

use fibfluid_validate::{Row, Speed, cases_at};

use crate::CliError;
use crate::say::num;

/// Arguments of `fibfluid validate`.
#[derive(clap::Args)]
pub struct ValidateArgs {
    /// Coarse grids (the whole suite in about a minute) instead of the cases' defaults.
    #[arg(long)]
    quick: bool,
    /// Only the cases whose name starts with this (e.g. sphere, cantilever).
    #[arg(long, value_name = "NAME")]
    case: Option<String>,
    /// Output directory (validation.json, validation.csv).
    #[arg(long)]
    out: Option<PathBuf>,
}

/// Runs `fibfluid validate`.
pub fn run(args: &ValidateArgs) -> Result<(), CliError> {
    let speed = if args.quick { Speed::Quick } else { Speed::Full };
    let chosen: Vec<_> = cases_at(speed)
        .into_iter()
        .filter(|c| args.case.as_deref().is_none_or(|n| c.name.starts_with(n)))
        .collect();
    if chosen.is_empty() {
        let names: Vec<&str> = cases_at(speed).iter().map(|c| c.name).collect();
        return Err(CliError::UnknownCase {
            name: args.case.clone().unwrap_or_default(),
            cases: names.join(", "),
        });
    }
    if let Some(out) = &args.out {
        fibfluid_cli::check_output_dir(out, &["validation.json", "validation.csv"])?;
    }
    say!("{}", header());
    let mut rows = Vec::new();
    for case in &chosen {
        let row = case.check(speed);
        say!("{}", line(&row));
        rows.push(row);
    }
    let failed: Vec<&str> = rows.iter().filter(|r| !r.passed).map(|r| r.case).collect();
    say!("{} of {} cases within their tolerance", rows.len() - failed.len(), rows.len());
    if let Some(out) = &args.out {
        let files = [("validation.json", serde_json::to_vec_pretty(&rows)?), ("validation.csv", csv(&rows))];
        fibfluid_cli::write_files_atomically(out, &files)?;
    }
    if failed.is_empty() { Ok(()) } else { Err(CliError::ValidationFailed { cases: failed.join(", ") }) }
}

fn header() -> String {
    format!(
        "{:<14} {:<36} {:>11} {:>4} {:>11} {:>8} {:>4} {:>11} {:>8} {:>6}  source",
        "case", "quantity", "reference", "res", "fibfluid", "error", "res", "fibfluid", "error", "tol"
    )
}

fn line(row: &Row) -> String {
    let reference = row.outcomes.iter().flatten().next().map_or("-".to_string(), |o| num(o.reference));
    let cell = |k: usize| match row.outcomes[k] {
        Some(o) => format!("{:>4} {:>11} {:>7.3}%", row.resolutions[k], num(o.value), 100.0 * o.error()),
        None => format!("{:>4} {:>11} {:>8}", row.resolutions[k], "failed", "-"),
    };
    let mark = if row.passed { "" } else { "  OUTSIDE TOLERANCE" };
    let mut s = format!(
        "{:<14} {:<36} {:>11} {} {} {:>5.2}%  {}{mark}",
        row.case,
        row.quantity,
        reference,
        cell(0),
        cell(1),
        100.0 * row.tolerance,
        row.source
    );
    if let Some(f) = &row.failure {
        s.push_str(&format!("\n{:<14} {f}", ""));
    }
    s
}

fn csv(rows: &[Row]) -> Vec<u8> {
    let mut s = String::from(
        "case,quantity,reference,source,resolution,value,error,resolution_2x,value_2x,error_2x,tolerance,passed,seconds\n",
    );
    let quote = |t: &str| format!("\"{}\"", t.replace('"', "\"\""));
    for r in rows {
        let reference = r.outcomes.iter().flatten().next().map_or(String::new(), |o| o.reference.to_string());
        let cell = |k: usize| match r.outcomes[k] {
            Some(o) => format!("{},{},{}", r.resolutions[k], o.value, o.error()),
            None => format!("{},,", r.resolutions[k]),
        };
        s.push_str(&format!(
            "{},{},{},{},{},{},{},{},{:.3}\n",
            r.case,
            quote(r.quantity),
            reference,
            quote(r.source),
            cell(0),
            cell(1),
            r.tolerance,
            r.passed,
            r.seconds
        ));
    }
    s.into_bytes()
}
