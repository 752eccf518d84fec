//! Tracking a tool on the hyperelastic body: frames answered on the latest linearization
//! converge, as the linearization follows them, to the batch Newton answer for the same
//! holds (an independent solve: load stepping with an augmented-Lagrangian grasp, where
//! tracking meets the holds exactly by a capacitance update), and releasing the holds
//! returns the body to its own equilibrium.

use crate::common::*;
use fibfluid_fem::hyper::{Grasp, HyperBody, HyperSolution, Linearization, Tangent};
use fibfluid_fem::{FemHold, FemOptions, Loads, Tissue, TissueModel};

/// Relative tolerance of the converged tracking against the batch answer (the batch
/// grasp's own constraint error is below `GRASP_TOLERANCE h`, far smaller).
const AGREEMENT: f64 = 1e-6;

fn tissue() -> Tissue {
    Tissue::new(3000.0, 0.45, 1000.0).unwrap().with_model(TissueModel::NeoHookean)
}

/// A surface, its fixed axes and a patch of it.
type HeldSurface = (Vec<[f64; 3]>, Vec<[u32; 3]>, Vec<[bool; 3]>, Vec<usize>);

/// The unit cube (8 x 8 surface squares per face, 4 cells per edge) clamped at z = 0 and
/// the top vertices within 0.3 of the top face's centre.
fn cube() -> HeldSurface {
    let (pos, tris) = box_surface([0.0; 3], [8; 3], 1.0 / 8.0);
    let fixed: Vec<[bool; 3]> = pos.iter().map(|p| [p[2] == 0.0; 3]).collect();
    let patch: Vec<usize> = (0..pos.len())
        .filter(|&v| pos[v][2] == 1.0 && (pos[v][0] - 0.5).hypot(pos[v][1] - 0.5) <= 0.3)
        .collect();
    (pos, tris, fixed, patch)
}

/// Tracks `holds` from `lin` until the step is below 1e-13 of the body's size; returns
/// the converged linearization and the step of every iteration.
fn converge(
    body: &mut HyperBody,
    mut lin: Linearization,
    loads: &Loads,
    holds: &[(usize, FemHold)],
) -> (Linearization, Vec<f64>) {
    let mut steps = Vec::new();
    for _ in 0..40 {
        let next = body.track(&mut lin, loads, &[], holds).unwrap();
        steps.push(next.step);
        lin = next.linearization;
        if next.step < 1e-13 {
            break;
        }
    }
    (lin, steps)
}

/// The cube of [`cube`] at resolution 4 under a gravity of 0.3 m/s^2, its patch pulled
/// 25 cm up and 5 cm across: the batch answer (an augmented-Lagrangian grasp), the free
/// body to track it on, its loads and the patch's holds.
fn pulled_cube() -> (HyperSolution, HyperBody, Loads, Vec<(usize, FemHold)>) {
    let (pos, tris, fixed, patch) = cube();
    let options = FemOptions { resolution: 4, ..FemOptions::default() };
    let loads = Loads { gravity: [0.0, 0.0, -0.3], ..Default::default() };
    let translation = [0.05, 0.0, 0.25];
    let grasp = Grasp { vertices: patch.clone(), translation, rotation: [0.0; 3] };
    let mut batch =
        HyperBody::from_surface_grasped(&pos, &tris, &tissue(), &fixed, &[grasp], &options).unwrap();
    let pulled = batch.solve(&loads, &[]).unwrap();
    let free = HyperBody::from_surface(&pos, &tris, &tissue(), &fixed, &options).unwrap();
    let holds: Vec<(usize, FemHold)> = patch.iter().map(|&v| (v, FemHold::At(translation))).collect();
    (pulled, free, loads, holds)
}

#[test]
fn held_grasp_converges_to_the_batch_answer_and_release_returns_to_rest() {
    let (pulled, mut free, loads, holds) = pulled_cube();
    let hanging = free.solve(&loads, &[]).unwrap();
    let rest = free.linearize_at_rest(&loads).unwrap();
    let (mut lin, steps) = converge(&mut free, rest, &loads, &holds);
    eprintln!("tracking steps (m): {:?}", steps.iter().map(|s| format!("{s:.3e}")).collect::<Vec<_>>());
    assert!(*steps.last().unwrap() < 1e-13, "not converged: {steps:?}");
    // Quadratic near the solution: a step of 1e-4 m is followed by one near (1e-4)^2 m (above
    // the rounding floor).
    for w in steps.windows(2).filter(|w| w[0] < 1e-3 && w[0] > 1e-7) {
        assert!(w[1] < 10.0 * w[0] * w[0], "not quadratic: {w:?}");
    }
    let frame = lin.respond(&[], &holds).unwrap();
    let error = rel_l2(&frame.surface_displacements, &pulled.surface_displacements, |_| true);
    let tracked: [f64; 3] = std::array::from_fn(|a| frame.reactions.iter().map(|r| r[a]).sum());
    let force = pulled.grasps[0].force;
    let force_error = norm(std::array::from_fn(|a| tracked[a] + force[a])) / norm(force);
    eprintln!(
        "tracked against batch: surface {error:.2e}, force {tracked:?} against {force:?} ({force_error:.2e})"
    );
    assert!(error < AGREEMENT, "{error}");
    assert!(force_error < AGREEMENT, "{force_error}");

    let (released, steps) = converge(&mut free, lin, &loads, &[]);
    let back = released.surface_displacements();
    let error = rel_l2(&back, &hanging.surface_displacements, |_| true);
    eprintln!("released after {} iterations: {error:.2e} from the hanging equilibrium", steps.len());
    assert!(error < AGREEMENT, "{error}");
}

/// Chord iterations (`Tangent::Keep`: the factor of an earlier tangent kept, only the
/// state and its force moved) reach the same equilibrium as Newton's iterations: the grasp
/// of the test above, tracked with the factor kept while its steps shrink by half (else
/// refactored, as the two-rate body's refreshes do), ends at the batch answer within the
/// same tolerance. The steps that kept it count their age in `chord_steps`.
#[test]
fn chord_iterations_on_a_kept_factor_reach_the_batch_answer() {
    let (pulled, mut free, loads, holds) = pulled_cube();
    let mut lin = free.linearize_at_rest(&loads).unwrap();
    let (mut chords, mut steps, mut slow) = (0, Vec::<f64>::new(), false);
    for _ in 0..100 {
        let tangent = if slow { Tangent::Refactor } else { Tangent::Keep };
        let next = free.track_with(&mut lin, &loads, &[], &holds, tangent).unwrap();
        let before = steps.last().copied().unwrap_or(f64::INFINITY);
        slow = !next.refactored && next.step > 0.5 * before;
        if next.refactored {
            assert_eq!(next.linearization.chord_steps(), 0);
        } else {
            chords += 1;
            assert_eq!(next.linearization.chord_steps(), lin.chord_steps() + 1);
        }
        steps.push(next.step);
        lin = next.linearization;
        if next.step < 1e-13 {
            break;
        }
    }
    let shown: Vec<String> = steps.iter().map(|s| format!("{s:.2e}")).collect();
    eprintln!("{chords} chord steps of {}: {shown:?}", steps.len());
    assert!(chords > 0, "the kept factor never stepped");
    assert!(*steps.last().unwrap() < 1e-13, "not converged: {steps:?}");
    let frame = lin.respond(&[], &holds).unwrap();
    let error = rel_l2(&frame.surface_displacements, &pulled.surface_displacements, |_| true);
    eprintln!("chord-tracked against batch: surface {error:.2e}");
    assert!(error < AGREEMENT, "{error}");
}

/// Largest difference between two vector lists over the largest norm of the first.
fn relative_difference(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
    let scale = a.iter().map(|v| norm(*v)).fold(0.0, f64::max).max(f64::MIN_POSITIVE);
    let largest =
        a.iter().zip(b).map(|(x, y)| norm(std::array::from_fn(|k| x[k] - y[k]))).fold(0.0, f64::max);
    largest / scale
}

/// The frames' surface-only answer (`respond_at_surface`: the rows' columns projected once
/// onto the surface, the multipliers from the capacitance matrix alone) against the full
/// solve of `respond` (the whole state, the rows imposed on it), at every linearization of
/// a far pull: grasped vertices held at points, others pressed along a normal, a push,
/// and the same rows moved again (the kept projection). Surface, total reaction and step
/// agree to 1e-10 (measured: 1e-14).
#[test]
fn surface_frames_equal_the_full_response() {
    let (pos, tris, fixed, patch) = cube();
    let options = FemOptions { resolution: 4, ..FemOptions::default() };
    let loads = Loads { gravity: [0.0, 0.0, -0.3], ..Default::default() };
    let mut body = HyperBody::from_surface(&pos, &tris, &tissue(), &fixed, &options).unwrap();
    let side: Vec<usize> = (0..pos.len()).filter(|&v| pos[v][0] == 1.0 && pos[v][2] > 0.4).take(3).collect();
    let holds_at = |lift: f64, press: f64| -> Vec<(usize, FemHold)> {
        let grasp = patch.iter().map(|&v| (v, FemHold::At([0.05, 0.0, lift])));
        let pressed = side.iter().map(|&v| (v, FemHold::Along { normal: [-1.0, 0.0, 0.0], along: press }));
        grasp.chain(pressed).collect()
    };
    let pushes = vec![(side[0] + 1, [0.0, 0.3, 0.0])];
    let mut lin = body.linearize_at_rest(&loads).unwrap();
    let mut penalized = 0;
    for k in 0..8 {
        for (lift, press) in [(0.3, 0.02), (0.32, 0.03)] {
            let holds = holds_at(lift, press);
            let full = lin.respond(&pushes, &holds).unwrap();
            let surface = lin.respond_at_surface(&pushes, &holds).unwrap();
            let shape = relative_difference(&full.surface_displacements, &surface.surface_displacements);
            // Per vertex, the reactions of a patch with several vertices in one cell are
            // split by the capacitance's ridge (not unique); their sum is.
            let total = |r: &[[f64; 3]]| [std::array::from_fn::<f64, 3, _>(|a| r.iter().map(|x| x[a]).sum())];
            let force = relative_difference(&total(&full.reactions), &total(&surface.reactions));
            let size = full.surface_displacements.iter().map(|d| norm(*d)).fold(0.0, f64::max);
            let step = (full.step - surface.step).abs() / size;
            assert!(shape < 1e-10 && force < 1e-10 && step < 1e-10, "iteration {k}: {shape} {force} {step}");
            assert_eq!(full.approximate, surface.approximate);
        }
        penalized += usize::from(lin.hold_penalty() > 0.0);
        lin = body.track(&mut lin, &loads, &pushes, &holds_at(0.3, 0.02)).unwrap().linearization;
    }
    eprintln!("linearizations with a hold penalty: {penalized} of 8");
}

/// Frames of a patch held at the targets of one rigid motion (a grasp turned 20 degrees
/// about the vertical and lifted) read at most 12 columns (`frame_columns`: the affine
/// path), and answer what the full solve of `respond` answers (an independent route: the
/// rows imposed on the whole state) to 1e-10, at every linearization of the pull,
/// penalized ones included. With a bilinear twist added to the targets (still met by the
/// cells' nodes, but no affine map), the frame takes the general path and still agrees.
#[test]
fn rigid_patch_frames_read_a_dozen_columns_and_equal_the_full_response() {
    let (pos, tris, fixed, patch) = cube();
    let options = FemOptions { resolution: 4, ..FemOptions::default() };
    let loads = Loads { gravity: [0.0, 0.0, -0.3], ..Default::default() };
    let mut body = HyperBody::from_surface(&pos, &tris, &tissue(), &fixed, &options).unwrap();
    let (c, s) = (20f64.to_radians().cos(), 20f64.to_radians().sin());
    let rigid = |v: usize, lift: f64| -> [f64; 3] {
        let [x, y] = [pos[v][0] - 0.5, pos[v][1] - 0.5];
        [c * x - s * y - x + 0.03, s * x + c * y - y, lift]
    };
    let mut lin = body.linearize_at_rest(&loads).unwrap();
    for k in 0..6 {
        for (lift, off) in [(0.2, 0.0), (0.22, 0.0), (0.22, 0.1)] {
            // A bilinear field is met by the cells' nodes (the patch's rows are dependent:
            // more vertices than nodes per cell), but is no affine map.
            let twisted = |v: usize| {
                let mut d = rigid(v, lift);
                d[2] += off * (pos[v][0] - 0.5) * (pos[v][1] - 0.5);
                d
            };
            let holds: Vec<(usize, FemHold)> = patch.iter().map(|&v| (v, FemHold::At(twisted(v)))).collect();
            let full = lin.respond(&[], &holds).unwrap();
            let surface = lin.respond_at_surface(&[], &holds).unwrap();
            let affine = lin.frame_columns() <= 12;
            assert_eq!(affine, off == 0.0, "iteration {k}: {} columns with {off} off", lin.frame_columns());
            let shape = relative_difference(&full.surface_displacements, &surface.surface_displacements);
            let total = |r: &[[f64; 3]]| [std::array::from_fn::<f64, 3, _>(|a| r.iter().map(|x| x[a]).sum())];
            let force = relative_difference(&total(&full.reactions), &total(&surface.reactions));
            assert!(shape < 1e-10 && force < 1e-10, "iteration {k}, off {off}: {shape:e} {force:e}");
        }
        let holds: Vec<(usize, FemHold)> = patch.iter().map(|&v| (v, FemHold::At(rigid(v, 0.2)))).collect();
        lin = body.track(&mut lin, &loads, &[], &holds).unwrap().linearization;
    }
}

/// A patch picked up where the body had deformed it (its targets' offset `o_i` no affine
/// map of the rest positions: a bilinear sag, as a grasp taken from a hanging body has)
/// and moved rigidly from there, `o_i + (R - I)(X_i + o_i - c) + t`, still reads at most
/// 12 columns (affine in the positions it was picked up at), and answers what the full
/// solve answers to 1e-10.
#[test]
fn a_patch_picked_up_deformed_and_moved_rigidly_reads_a_dozen_columns() {
    let (pos, tris, fixed, patch) = cube();
    let options = FemOptions { resolution: 4, ..FemOptions::default() };
    let loads = Loads { gravity: [0.0, 0.0, -0.3], ..Default::default() };
    let mut body = HyperBody::from_surface(&pos, &tris, &tissue(), &fixed, &options).unwrap();
    let mut lin = body.linearize_at_rest(&loads).unwrap();
    let sag = |v: usize| [0.0, 0.0, -0.2 * (pos[v][0] - 0.5) * (pos[v][1] - 0.5) - 0.05];
    let moved = |v: usize, angle: f64, lift: f64| -> [f64; 3] {
        let o = sag(v);
        let (c, s) = (angle.cos(), angle.sin());
        let [x, y] = [pos[v][0] + o[0] - 0.5, pos[v][1] + o[1] - 0.5];
        [o[0] + c * x - s * y - x, o[1] + s * x + c * y - y, o[2] + lift]
    };
    let picked: Vec<(usize, FemHold)> = patch.iter().map(|&v| (v, FemHold::At(sag(v)))).collect();
    lin.respond_at_surface(&[], &picked).unwrap();
    for (angle, lift) in [(0.0, 0.0), (0.1, 0.02), (0.35, 0.1)] {
        let holds: Vec<(usize, FemHold)> =
            patch.iter().map(|&v| (v, FemHold::At(moved(v, angle, lift)))).collect();
        let full = lin.respond(&[], &holds).unwrap();
        let surface = lin.respond_at_surface(&[], &holds).unwrap();
        assert!(lin.frame_columns() <= 12, "{} columns at {angle} rad", lin.frame_columns());
        let shape = relative_difference(&full.surface_displacements, &surface.surface_displacements);
        assert!(shape < 1e-10, "{angle} rad: {shape:e}");
    }
}
