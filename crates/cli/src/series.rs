//! `series.csv`: a timed run's state at each output time (SI units: s, m, m^3, J, N); its
//! progress line.

use fibfluid::sim::fem_run::FemRun;
use fibfluid::sim::hyper_run::SeriesRow;

/// The series file's name.
pub const SERIES_FILE: &str = "series.csv";

/// The series of a timed run as CSV (`None` for one equilibrium): `time, load,
/// max_displacement, volume, kinetic_energy, strain_energy`, then each plate's force
/// (`plate_K_force`) and each grasp's (`grasp_K_force_x`, `_y`, `_z`).
pub fn series_csv(run: &FemRun) -> Option<Vec<u8>> {
    let rows: &[SeriesRow] = run.newton.as_ref().map(|n| n.series.as_slice()).filter(|s| !s.is_empty())?;
    let (plates, grasps) = (rows[0].plate_forces.len(), rows[0].grasp_forces.len());
    let mut header = String::from("time,load,max_displacement,volume,kinetic_energy,strain_energy");
    for k in 1..=plates {
        header += &format!(",plate_{k}_force");
    }
    for k in 1..=grasps {
        header += &format!(",grasp_{k}_force_x,grasp_{k}_force_y,grasp_{k}_force_z");
    }
    let mut out = header + "\n";
    for r in rows {
        let mut line = format!(
            "{},{},{:e},{:e},{:e},{:e}",
            r.time, r.load, r.max_displacement, r.volume, r.kinetic_energy, r.strain_energy
        );
        for f in &r.plate_forces {
            line += &format!(",{f:e}");
        }
        for f in &r.grasp_forces {
            line += &format!(",{:e},{:e},{:e}", f[0], f[1], f[2]);
        }
        out += &line;
        out.push('\n');
    }
    Some(out.into_bytes())
}

/// The progress of a timed run: `t = 1.20 s of 10 s, 120 steps, 3 cut` (the time to about
/// three significant digits of the end).
pub fn progress_line(time: f64, end: f64, steps: usize, cut: usize) -> String {
    let decimals = (2 - end.log10().floor() as i32).max(2) as usize;
    let plural = if steps == 1 { "" } else { "s" };
    format!("t = {time:.decimals$} s of {end} s, {steps} step{plural}, {cut} cut")
}
