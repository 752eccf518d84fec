//! Measures the volume change after a push and the residual deformation after release for
//! traditional (Generalized) ChainMail and TSVE-ChainMail, and the cost of propagation
//! with and without the time-saving scheme.
//!
//! Run: `cargo run --release -p fibfluid-chainmail --example volume_change`

use std::time::Instant;

use fibfluid_chainmail::{
    GeneralizedMaterial, Lattice, Material, PropagationOptions, RelaxOptions, Result, Scheme, TsveMaterial,
};

/// Sponsors and their targets.
type Moves = Vec<(usize, [f64; 3])>;

const N: usize = 12;
const DEPTH: f64 = 2.0;

/// 12^3 box, spacing 1, bottom layer fixed; the 4x4 patch at the centre of the top face is
/// pushed down by 2 spacings.
fn block() -> Result<(Lattice, Moves)> {
    let mut lattice = Lattice::new_box([N; 3], 1.0, [0.0; 3])?;
    for i in 0..N {
        for j in 0..N {
            if let Some(e) = lattice.element_at([i, j, 0]) {
                lattice.set_inverse_mass(e, 0.0)?;
            }
        }
    }
    let mut moves = Vec::new();
    for i in 4..8 {
        for j in 4..8 {
            if let Some(e) = lattice.element_at([i, j, N - 1]) {
                let p = lattice.positions()[e];
                moves.push((e, [p[0], p[1], p[2] - DEPTH]));
            }
        }
    }
    Ok((lattice, moves))
}

fn run<M: Material>(name: &str, m: &M, push: Option<RelaxOptions>) -> Result<()> {
    let (mut lattice, moves) = block()?;
    let p = lattice.propagate(m, &moves, &PropagationOptions::default())?;
    let dv_propagation = lattice.volume() / lattice.rest_volume() - 1.0;
    let held: Vec<usize> = moves.iter().map(|m| m.0).collect();
    let sweeps = match &push {
        Some(r) => lattice.relax(m, &held, r)?.iterations,
        None => 0,
    };
    let dv = lattice.volume() / lattice.rest_volume() - 1.0;
    let rms_push = lattice.rms_displacement();
    // Release: TSVE relaxes under volume + energy; traditional ChainMail has no restoring
    // mechanism, so its release only re-checks the CBRs.
    let release = match &push {
        Some(_) => RelaxOptions::default(),
        None => RelaxOptions { volume: false, energy: false, ..RelaxOptions::default() },
    };
    lattice.release(m, &release)?;
    println!(
        "| {name} | {} | {} | {} | {:+.2} % | {:+.2} % ({sweeps}) | {:.3} | {:.4} |",
        if p.time_saving { "TSS" } else { "exhaustive" },
        p.moved,
        p.processed,
        100.0 * dv_propagation,
        100.0 * dv,
        rms_push,
        lattice.rms_displacement(),
    );
    Ok(())
}

fn timing() -> Result<()> {
    let n = 40;
    let mut base = Lattice::new_box([n; 3], 1.0, [0.0; 3])?;
    let m = TsveMaterial::isotropic(base.len(), 0.05);
    let centre = base.element_at([n / 2, n / 2, n - 1]).expect("box");
    let p = base.positions()[centre];
    let moves = [(centre, [p[0] + 1.0, p[1] - 0.5, p[2] - 3.0])];
    println!("\n{n}^3 box, TSVE alpha 0.05, top-centre element pushed by (1, -0.5, -3):\n");
    println!("| scheme | moved | processed | CBR checks | time |");
    println!("|---|---|---|---|---|");
    for scheme in [Scheme::TimeSaving, Scheme::Exhaustive] {
        let mut best = f64::INFINITY;
        let mut report = None;
        for _ in 0..5 {
            base.reset();
            let t = Instant::now();
            let r =
                base.propagate(&m, &moves, &PropagationOptions { scheme, ..PropagationOptions::default() })?;
            best = best.min(t.elapsed().as_secs_f64());
            report = Some(r);
        }
        let r = report.expect("ran");
        println!("| {scheme:?} | {} | {} | {} | {:.2} ms |", r.moved, r.processed, r.checks, 1e3 * best);
    }
    Ok(())
}

fn main() -> Result<()> {
    println!(
        "{N}^3 box, spacing 1, bottom layer fixed, 4x4 top patch pushed down by {DEPTH}; \
         dV = volume / rest volume - 1; rms = RMS distance from rest.\n"
    );
    println!(
        "| model | scheme | moved | processed | dV after propagation | dV after push (sweeps) | rms pushed | rms after release |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    let n = N * N * N;
    let traditional = GeneralizedMaterial::isotropic(0.8, 1.2, 0.2);
    let tsve = TsveMaterial::isotropic(n, 0.2);
    run("Generalized (0.8, 1.2, 0.2), no constraints", &traditional, None)?;
    run("TSVE alpha 0.2, no constraints", &tsve, None)?;
    run("TSVE alpha 0.2 + volume", &tsve, Some(RelaxOptions { energy: false, ..RelaxOptions::default() }))?;
    run("TSVE alpha 0.2 + volume + energy (defaults)", &tsve, Some(RelaxOptions::default()))?;
    run(
        "TSVE alpha 0.2 + volume + energy, energy_stiffness 0.1",
        &tsve,
        Some(RelaxOptions { energy_stiffness: 0.1, ..RelaxOptions::default() }),
    )?;
    timing()
}
