//! Volume and strain-energy conservation (Eq. 15–17) and release.
//!
//! Scenario of the comparison tests (also `examples/volume_change.rs`): a 12^3 box of
//! spacing 1 with its bottom layer fixed; the 4x4 patch at the centre of the top face is
//! pushed down by 2 spacings. Measured (see README): traditional Generalized ChainMail
//! (0.8, 1.2, 0.2) loses 12.89 % of its volume; TSVE (alpha 0.2) with the volume constraint
//! loses 0.49 %, with volume + energy at energy_stiffness 0.1 1.49 %, with the default
//! options (energy_stiffness 1) 4.99 %. After release the TSVE model is 0.017 (RMS) from
//! rest, the traditional one 0.715 (unchanged).

use fibfluid_chainmail::{
    ChainmailError, GeneralizedMaterial, Lattice, Material, PropagationOptions, RelaxOptions, TsveMaterial,
};

const N: usize = 12;

fn block() -> (Lattice, Vec<(usize, [f64; 3])>) {
    let mut l = Lattice::new_box([N; 3], 1.0, [0.0; 3]).unwrap();
    for i in 0..N {
        for j in 0..N {
            let e = l.element_at([i, j, 0]).unwrap();
            l.set_inverse_mass(e, 0.0).unwrap();
        }
    }
    let mut moves = Vec::new();
    for i in 4..8 {
        for j in 4..8 {
            let e = l.element_at([i, j, N - 1]).unwrap();
            let p = l.positions()[e];
            moves.push((e, [p[0], p[1], p[2] - 2.0]));
        }
    }
    (l, moves)
}

/// Pushes, optionally relaxes with the pushed patch held; returns the lattice.
fn pushed<M: Material>(m: &M, relax: Option<RelaxOptions>) -> Lattice {
    let (mut l, moves) = block();
    let r = l.propagate(m, &moves, &PropagationOptions::default()).unwrap();
    assert!(r.converged && r.blocked == 0);
    // The patch went down by 2, so the block is thinner by construction: propagation alone
    // must lose volume.
    assert!(l.volume() < l.rest_volume());
    if let Some(o) = relax {
        let held: Vec<usize> = moves.iter().map(|m| m.0).collect();
        l.relax(m, &held, &o).unwrap();
        for &(e, t) in &moves {
            assert_eq!(l.positions()[e], t, "held element moved");
        }
    }
    l
}

#[test]
fn volume_constraint_conserves_volume() {
    let traditional = pushed(&GeneralizedMaterial::isotropic(0.8, 1.2, 0.2), None);
    let tsve_m = TsveMaterial::isotropic(N * N * N, 0.2);
    let volume_only = pushed(&tsve_m, Some(RelaxOptions { energy: false, ..RelaxOptions::default() }));
    let soft_energy =
        pushed(&tsve_m, Some(RelaxOptions { energy_stiffness: 0.1, ..RelaxOptions::default() }));
    let defaults = pushed(&tsve_m, Some(RelaxOptions::default()));
    let dv_trad = traditional.relative_volume_change();
    let dv_vol = volume_only.relative_volume_change();
    let dv_soft = soft_energy.relative_volume_change();
    let dv_def = defaults.relative_volume_change();
    println!("traditional {dv_trad} volume {dv_vol} soft energy {dv_soft} defaults {dv_def}");
    // Paper: 14.31 % (traditional) vs 0.71 % (TSVE).
    assert!(dv_trad > 0.10);
    assert!(dv_vol < 0.02);
    assert!(dv_soft < 0.05);
    assert!(dv_trad > 4.0 * dv_soft);
    assert!(dv_def < 0.5 * dv_trad);
    // Fixed elements stayed put.
    let e = defaults.element_at([3, 3, 0]).unwrap();
    assert_eq!(defaults.positions()[e], defaults.rest_positions()[e]);
}

#[test]
fn release_returns_tsve_not_traditional() {
    let gm = GeneralizedMaterial::isotropic(0.8, 1.2, 0.2);
    let mut traditional = pushed(&gm, None);
    let trad_pushed = traditional.rms_displacement();
    // Traditional ChainMail has no restoring mechanism: release only re-checks its CBRs.
    let no_constraints = RelaxOptions { volume: false, energy: false, ..RelaxOptions::default() };
    traditional.release(&gm, &no_constraints).unwrap();
    let trad_released = traditional.rms_displacement();

    let tm = TsveMaterial::isotropic(N * N * N, 0.2);
    let mut tsve = pushed(&tm, Some(RelaxOptions::default()));
    let tsve_pushed = tsve.rms_displacement();
    tsve.release(&tm, &RelaxOptions::default()).unwrap();
    let tsve_released = tsve.rms_displacement();
    println!("traditional {trad_pushed} -> {trad_released}, TSVE {tsve_pushed} -> {tsve_released}");

    assert!(trad_pushed > 0.3 && tsve_pushed > 0.3, "the push deformed both");
    assert!(trad_released > 0.9 * trad_pushed, "traditional stays deformed");
    assert!(tsve_released < 0.1 * tsve_pushed, "TSVE returns toward rest");
    assert!(tsve_released < 0.1 * trad_released);
    assert!(tsve.relative_volume_change() < 0.005);
}

/// Four fixed corners (bottom face of a single cell), top corners displaced: energy +
/// volume relaxation brings the top back to its rest positions (the rest shape is the only
/// zero of both constraints with the bottom face pinned).
#[test]
fn relaxation_restores_single_cell() {
    let mut l = Lattice::new_box([2, 2, 2], 1.0, [0.0; 3]).unwrap();
    let bottom: Vec<usize> = (0..8).filter(|&e| l.grid_coords(e).unwrap()[2] == 0).collect();
    for &e in &bottom {
        l.set_inverse_mass(e, 0.0).unwrap();
    }
    let m = TsveMaterial::isotropic(8, 0.3);
    // Shear + squash the top face (within its CBRs, half-width 0.3).
    let moves: Vec<(usize, [f64; 3])> = (0..8)
        .filter(|e| !bottom.contains(e))
        .map(|e| {
            let p = l.positions()[e];
            (e, [p[0] + 0.2, p[1] - 0.1, p[2] - 0.25])
        })
        .collect();
    l.propagate(&m, &moves, &PropagationOptions::default()).unwrap();
    assert!((l.volume() - 0.75).abs() < 1e-12, "squashed by a quarter");
    let r = l
        .release(&m, &RelaxOptions { max_iterations: 5000, tolerance: 1e-10, ..RelaxOptions::default() })
        .unwrap();
    assert!(r.converged, "{r:?}");
    for e in 0..8 {
        let (p, q) = (l.positions()[e], l.rest_positions()[e]);
        for a in 0..3 {
            assert!((p[a] - q[a]).abs() < 1e-6, "element {e}: {p:?} vs {q:?}");
        }
    }
}

/// Volume constraint alone, nothing fixed: a cell shrunk to 0.9 of its size (volume 0.729)
/// is brought back to volume 1.
#[test]
fn volume_constraint_restores_cell_volume() {
    let mut l = Lattice::new_box([2, 2, 2], 1.0, [0.0; 3]).unwrap();
    let m = TsveMaterial::isotropic(8, 0.2);
    let moves: Vec<(usize, [f64; 3])> = (0..8)
        .map(|e| {
            let p = l.positions()[e];
            (e, [0.5 + 0.9 * (p[0] - 0.5), 0.5 + 0.9 * (p[1] - 0.5), 0.5 + 0.9 * (p[2] - 0.5)])
        })
        .collect();
    l.propagate(&m, &moves, &PropagationOptions::default()).unwrap();
    assert!((l.volume() - 0.729).abs() < 1e-12);
    let r = l
        .relax(
            &m,
            &[],
            &RelaxOptions {
                energy: false,
                enforce_cbr: false,
                tolerance: 1e-12,
                max_iterations: 1000,
                ..RelaxOptions::default()
            },
        )
        .unwrap();
    assert!(r.converged);
    assert!((l.volume() - 1.0).abs() < 1e-9, "volume {}", l.volume());
    assert!(r.relative_volume_change < 1e-9);
}

/// Eq. 15 with inverse masses: one tet's worth of check on the weights — an element with
/// zero inverse mass never moves, and held elements never move.
#[test]
fn zero_weight_and_held_elements_do_not_move() {
    let mut l = Lattice::new_box([3, 3, 3], 1.0, [0.0; 3]).unwrap();
    let m = TsveMaterial::isotropic(27, 0.3);
    let centre = l.element_at([1, 1, 1]).unwrap();
    let corner = l.element_at([0, 0, 0]).unwrap();
    l.set_inverse_mass(corner, 0.0).unwrap();
    l.propagate(&m, &[(centre, [1.3, 1.2, 0.8])], &PropagationOptions::default()).unwrap();
    let before = l.positions()[centre];
    l.relax(&m, &[centre], &RelaxOptions::default()).unwrap();
    assert_eq!(l.positions()[centre], before);
    assert_eq!(l.positions()[corner], [0.0, 0.0, 0.0]);
}

#[test]
fn relax_errors() {
    let mut l = Lattice::new_box([2, 2, 2], 1.0, [0.0; 3]).unwrap();
    let m = TsveMaterial::isotropic(8, 0.2);
    let o = RelaxOptions::default();
    for bad in [
        RelaxOptions { volume_stiffness: 1.5, ..o },
        RelaxOptions { energy_stiffness: -0.1, ..o },
        RelaxOptions { tolerance: f64::NAN, ..o },
    ] {
        assert!(matches!(l.relax(&m, &[], &bad), Err(ChainmailError::InvalidParameter { .. })));
    }
    assert_eq!(l.relax(&m, &[8], &o).unwrap_err(), ChainmailError::IndexOutOfRange { index: 8, len: 8 });
    assert!(matches!(
        l.release(&TsveMaterial::isotropic(7, 0.2), &o),
        Err(ChainmailError::LengthMismatch { .. })
    ));
    let r = l.release(&m, &o).unwrap();
    assert!(r.converged && r.iterations == 1, "rest state needs no correction");
}

/// TSVE's return to rest frame by frame, as an interactive body releases (50 relaxation
/// sweeps a frame, the energy correction scaled by 0.1: the interactive defaults): the
/// block of the comparison tests pushed and relaxed with the push held, then released. Its
/// RMS displacement falls at every frame, and within 30 frames (1 s at the paper's 30 Hz)
/// below a tenth of the pushed one. The printed fractions are the TSVE column of
/// docs/time.md's relaxation table.
#[test]
fn tsve_returns_toward_rest_frame_by_frame() {
    let tm = TsveMaterial::isotropic(N * N * N, 0.2);
    let frame = RelaxOptions { max_iterations: 50, energy_stiffness: 0.1, ..RelaxOptions::default() };
    let mut l = pushed(&tm, Some(frame));
    let pushed_rms = l.rms_displacement();
    let mut previous = pushed_rms;
    for k in 1..=30 {
        l.release(&tm, &frame).unwrap();
        let rms = l.rms_displacement();
        println!(
            "frame {k} ({:.3} s at 30 Hz): {:.4} of the pushed RMS displacement",
            k as f64 / 30.0,
            rms / pushed_rms
        );
        assert!(rms < previous, "frame {k}: {rms} after {previous}");
        previous = rms;
    }
    assert!(previous < 0.1 * pushed_rms, "{previous} of {pushed_rms}");
}
