//! Propagation: hand-derived chains, the time-saving scheme, and the property that every
//! link satisfies its CBR afterwards.

use fibfluid_chainmail::{
    ChainmailError, GeneralizedMaterial, Lattice, Material, PropagationOptions, Scheme, TsveMaterial,
};
use proptest::prelude::*;

/// Links may exceed their CBR by rounding only.
const EPS: f64 = 1e-9;

fn opts(scheme: Scheme) -> PropagationOptions {
    PropagationOptions { scheme, ..PropagationOptions::default() }
}

fn displacement(l: &Lattice, e: usize) -> [f64; 3] {
    let (p, r) = (l.positions()[e], l.rest_positions()[e]);
    [p[0] - r[0], p[1] - r[1], p[2] - r[2]]
}

/// A 5-element chain along x, TSVE alpha 0.1 (half-width 0.1 per link). Pushing element 0
/// by (1, 0.5, 0) leaves element k displaced by (1 - 0.1k, 0.5 - 0.1k, 0).
#[test]
fn tsve_chain_by_hand() {
    let mut l = Lattice::new_box([5, 1, 1], 1.0, [0.0; 3]).unwrap();
    let m = TsveMaterial::isotropic(5, 0.1);
    let r = l.propagate(&m, &[(0, [1.0, 0.5, 0.0])], &PropagationOptions::default()).unwrap();
    assert!(r.time_saving);
    assert_eq!((r.moved, r.processed, r.max_processed_per_element), (5, 5, 1));
    for k in 0..5 {
        let d = displacement(&l, k);
        let want = [1.0 - 0.1 * k as f64, 0.5 - 0.1 * k as f64, 0.0];
        for a in 0..3 {
            assert!((d[a] - want[a]).abs() < 1e-12, "element {k}: {d:?} vs {want:?}");
        }
    }
}

/// Generalized ChainMail (alpha_min 0.7, alpha_max 1.5, beta 0.25) on a 5-chain along x:
/// compression allowance 0.3, stretch allowance 0.5, shear allowance 0.25 per link.
/// Push +x by 1: displacements 1, 0.7, 0.4, 0.1, 0. Pull -x by 1: -1, -0.5, 0, 0, 0.
/// Shear +y by 1: 1, 0.75, 0.5, 0.25, 0.
#[test]
fn generalized_chain_by_hand() {
    let m = GeneralizedMaterial::isotropic(0.7, 1.5, 0.25);
    let cases: [([f64; 3], usize, [f64; 5]); 3] = [
        ([1.0, 0.0, 0.0], 0, [1.0, 0.7, 0.4, 0.1, 0.0]),
        ([-1.0, 0.0, 0.0], 0, [-1.0, -0.5, 0.0, 0.0, 0.0]),
        ([0.0, 1.0, 0.0], 1, [1.0, 0.75, 0.5, 0.25, 0.0]),
    ];
    for (push, axis, want) in cases {
        let mut l = Lattice::new_box([5, 1, 1], 1.0, [0.0; 3]).unwrap();
        let r = l.propagate(&m, &[(0, push)], &PropagationOptions::default()).unwrap();
        assert!(!r.time_saving && r.converged);
        for k in 0..5 {
            let d = displacement(&l, k);
            assert!((d[axis] - want[k]).abs() < 1e-12, "{push:?} element {k}: {d:?}");
        }
        assert!(l.max_cbr_violation(&m).unwrap() <= EPS);
    }
}

/// Why the time-saving scheme is for isotropic materials only. 3x3x1 lattice, element 1
/// (grid (1,0)) soft, alpha 0.5; all others alpha 0.05. Push element 0 by +1 in x.
/// Link half-widths: 0-1 and 1-4 0.275, every other link 0.05.
///
/// TSS: element 4 is moved once, from element 1: 1 - 0.275 - 0.275 = 0.45, while element 3
/// sits at 1 - 0.05 = 0.95, so link 3-4 is left 0.5 - 0.05 = 0.45 outside its CBR.
/// Exhaustive: displacement = 1 - (shortest weighted path): elements 0..9 get
/// 1, 0.725, 0.8, 0.95, 0.9, 0.85, 0.9, 0.85, 0.8, and no link is violated.
#[test]
fn heterogeneous_needs_exhaustive_scheme() {
    let mut alpha = vec![0.05; 9];
    alpha[1] = 0.5;
    let m = TsveMaterial::heterogeneous(&alpha);
    let mut l = Lattice::new_box([3, 3, 1], 1.0, [0.0; 3]).unwrap();
    let r = l.propagate(&m, &[(0, [1.0, 0.0, 0.0])], &opts(Scheme::TimeSaving)).unwrap();
    assert!(r.time_saving && r.max_processed_per_element == 1);
    assert!((displacement(&l, 4)[0] - 0.45).abs() < 1e-12);
    assert!((l.max_cbr_violation(&m).unwrap() - 0.45).abs() < 1e-12);

    let mut l = Lattice::new_box([3, 3, 1], 1.0, [0.0; 3]).unwrap();
    let r = l.propagate(&m, &[(0, [1.0, 0.0, 0.0])], &PropagationOptions::default()).unwrap();
    assert!(!r.time_saving && r.converged);
    let want = [1.0, 0.725, 0.8, 0.95, 0.9, 0.85, 0.9, 0.85, 0.8];
    for (k, w) in want.iter().enumerate() {
        let d = displacement(&l, k);
        assert!((d[0] - w).abs() < 1e-12, "element {k}: {d:?} vs {w}");
        assert!(d[1].abs() < 1e-12 && d[2].abs() < 1e-12);
    }
    assert!(l.max_cbr_violation(&m).unwrap() <= EPS);
}

/// Fixed elements (zero inverse mass) never move; a violation against one is reported.
#[test]
fn fixed_elements_block() {
    let mut l = Lattice::new_box([3, 1, 1], 1.0, [0.0; 3]).unwrap();
    l.set_inverse_mass(2, 0.0).unwrap();
    let m = TsveMaterial::isotropic(3, 0.1);
    let r = l.propagate(&m, &[(0, [1.0, 0.0, 0.0])], &PropagationOptions::default()).unwrap();
    assert_eq!(l.positions()[2], [2.0, 0.0, 0.0]);
    assert_eq!(r.blocked, 1);
    assert_eq!(r.moved, 2);
    // The exhaustive scheme lets element 1 follow the fixed element back, which the sponsor
    // undoes: the two cannot both be met (2 links allow 0.2, not 1), so it stops unconverged.
    let mut l2 = Lattice::new_box([3, 1, 1], 1.0, [0.0; 3]).unwrap();
    l2.set_inverse_mass(2, 0.0).unwrap();
    let o =
        PropagationOptions { scheme: Scheme::Exhaustive, max_processed: 50, ..PropagationOptions::default() };
    let r = l2.propagate(&m, &[(0, [1.0, 0.0, 0.0])], &o).unwrap();
    assert!(!r.converged);
    assert_eq!(l2.positions()[2], [2.0, 0.0, 0.0]);
    assert_eq!(l2.positions()[0], [1.0, 0.0, 0.0]);
}

#[test]
fn propagation_errors_leave_lattice_untouched() {
    let mut l = Lattice::new_box([3, 3, 3], 1.0, [0.0; 3]).unwrap();
    let m = TsveMaterial::isotropic(27, 0.1);
    let o = PropagationOptions::default();
    assert_eq!(
        l.propagate(&m, &[(27, [0.0; 3])], &o).unwrap_err(),
        ChainmailError::IndexOutOfRange { index: 27, len: 27 }
    );
    assert_eq!(
        l.propagate(&m, &[(0, [1.0, 0.0, 0.0]), (1, [f64::NAN, 0.0, 0.0])], &o).unwrap_err(),
        ChainmailError::NonFinite { index: 1 }
    );
    assert_eq!(
        l.propagate(&m, &[(0, [1.0, 0.0, 0.0]), (0, [2.0, 0.0, 0.0])], &o).unwrap_err(),
        ChainmailError::DuplicateElement { index: 0 }
    );
    assert!(matches!(
        l.propagate(&TsveMaterial::isotropic(26, 0.1), &[(0, [1.0; 3])], &o),
        Err(ChainmailError::LengthMismatch { .. })
    ));
    assert!(matches!(
        l.propagate(&GeneralizedMaterial::isotropic(0.9, 0.8, 0.1), &[(0, [1.0; 3])], &o),
        Err(ChainmailError::InvalidParameter { .. })
    ));
    let bad = PropagationOptions { tolerance: -1.0, ..o };
    assert!(l.propagate(&m, &[(0, [1.0; 3])], &bad).is_err());
    assert_eq!(l.positions(), l.rest_positions());
    // No move at all is fine and does nothing.
    let r = l.propagate(&m, &[], &o).unwrap();
    assert_eq!((r.moved, r.processed), (0, 0));
}

/// The Exhaustive scheme reports when it hits its bound.
#[test]
fn exhaustive_bound_is_reported() {
    let mut l = Lattice::new_box([6, 6, 6], 1.0, [0.0; 3]).unwrap();
    let m = TsveMaterial::isotropic(l.len(), 0.1);
    let o =
        PropagationOptions { scheme: Scheme::Exhaustive, max_processed: 10, ..PropagationOptions::default() };
    let r = l.propagate(&m, &[(0, [3.0, 3.0, 3.0])], &o).unwrap();
    assert!(!r.converged);
    assert_eq!(r.processed, 10);
}

fn l_shape() -> Lattice {
    // Union of two overlapping box surfaces: a non-convex L-shaped lattice.
    let mut pos = Vec::new();
    let mut tris = Vec::new();
    for hi in [[4.0, 1.5, 1.5], [1.5, 4.0, 1.5]] {
        let b = pos.len() as u32;
        for k in 0..8 {
            pos.push([
                if k & 1 == 0 { 0.0 } else { hi[0] },
                if k & 2 == 0 { 0.0 } else { hi[1] },
                if k & 4 == 0 { 0.0 } else { hi[2] },
            ]);
        }
        for q in [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]] {
            tris.push([b + q[0], b + q[1], b + q[2]]);
            tris.push([b + q[0], b + q[2], b + q[3]]);
        }
    }
    Lattice::from_surface(&pos, &tris, 0.5).unwrap()
}

/// A random push: a sponsor, a displacement of up to 2.5 spacings per axis, and whether
/// to push the sponsor's whole 2x2x2 grid block rigidly instead.
fn push_strategy() -> impl Strategy<Value = (f64, [f64; 3], bool)> {
    (0.0..1.0f64, prop::array::uniform3(-2.5..2.5f64), any::<bool>())
}

fn moves_for(l: &Lattice, pick: f64, disp: [f64; 3], region: bool) -> Vec<(usize, [f64; 3])> {
    let s = ((pick * l.len() as f64) as usize).min(l.len() - 1);
    let c = l.grid_coords(s).unwrap();
    let h = l.spacing();
    let mut out = Vec::new();
    let blocks: Vec<[usize; 3]> = if region {
        (0..8).map(|b| [c[0] + (b & 1), c[1] + ((b >> 1) & 1), c[2] + ((b >> 2) & 1)]).collect()
    } else {
        vec![c]
    };
    for g in blocks {
        if let Some(e) = l.element_at(g) {
            let p = l.positions()[e];
            out.push((e, [p[0] + h * disp[0], p[1] + h * disp[1], p[2] + h * disp[2]]));
        }
    }
    out
}

/// Applies the pushes in sequence; after each one every link satisfies its CBR, and, when
/// the time-saving scheme was used, no element was processed more than once.
fn check_sequence<M: Material>(
    mut l: Lattice,
    m: &M,
    pushes: &[(f64, [f64; 3], bool)],
    expect_tss: bool,
) -> Result<(), TestCaseError> {
    for (k, &(pick, disp, region)) in pushes.iter().enumerate() {
        // Region pushes only from rest: from a deformed state the block's elements would
        // end with different displacements, where TSS is not exact (Auto then falls back).
        let moves = moves_for(&l, pick, disp, region && k == 0);
        let r = l.propagate(m, &moves, &PropagationOptions::default()).unwrap();
        prop_assert!(r.converged);
        prop_assert_eq!(r.blocked, 0);
        if expect_tss {
            prop_assert!(r.time_saving);
            prop_assert!(r.max_processed_per_element <= 1);
            prop_assert!(r.processed <= l.len());
            prop_assert!(r.moved <= r.processed);
        }
        let v = l.max_cbr_violation(m).unwrap();
        prop_assert!(v <= EPS * l.spacing(), "violation {} after push {}", v, k);
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 128, ..ProptestConfig::default() })]

    /// Homogeneous TSVE (isotropic or anisotropic): Auto uses the time-saving scheme, each
    /// element is processed at most once, and all CBRs hold after each push.
    #[test]
    fn tsve_homogeneous_box(
        dims in prop::array::uniform3(2usize..6),
        alpha in prop::array::uniform3(0.02..0.6f64),
        isotropic in any::<bool>(),
        pushes in prop::collection::vec(push_strategy(), 1..4),
    ) {
        let l = Lattice::new_box(dims, 0.7, [0.0; 3]).unwrap();
        let a = if isotropic { [alpha[0]; 3] } else { alpha };
        let m = TsveMaterial::anisotropic(l.len(), a);
        check_sequence(l, &m, &pushes, true)?;
    }

    /// Same on a non-convex (L-shaped) voxelized lattice.
    #[test]
    fn tsve_homogeneous_l_shape(
        alpha in 0.02..0.6f64,
        pushes in prop::collection::vec(push_strategy(), 1..4),
    ) {
        let l = l_shape();
        let m = TsveMaterial::isotropic(l.len(), alpha);
        check_sequence(l, &m, &pushes, true)?;
    }

    /// Heterogeneous, anisotropic TSVE: the exhaustive scheme leaves all CBRs satisfied.
    #[test]
    fn tsve_heterogeneous(
        dims in prop::array::uniform3(2usize..5),
        seed in prop::collection::vec(prop::array::uniform3(0.0..0.6f64), 64),
        pushes in prop::collection::vec(push_strategy(), 1..4),
        l_shaped in any::<bool>(),
    ) {
        let l = if l_shaped { l_shape() } else { Lattice::new_box(dims, 1.3, [0.0; 3]).unwrap() };
        let alpha: Vec<[f64; 3]> = (0..l.len()).map(|i| seed[i % seed.len()]).collect();
        let m = TsveMaterial { alpha };
        check_sequence(l, &m, &pushes, false)?;
    }

    /// Generalized ChainMail with random (per-axis) parameters: all CBRs satisfied.
    #[test]
    fn generalized_random(
        dims in prop::array::uniform3(2usize..5),
        amin in prop::array::uniform3(0.3..1.0f64),
        amax in prop::array::uniform3(1.0..2.0f64),
        beta in prop::array::uniform3(0.0..0.5f64),
        pushes in prop::collection::vec(push_strategy(), 1..4),
        l_shaped in any::<bool>(),
    ) {
        let l = if l_shaped { l_shape() } else { Lattice::new_box(dims, 1.0, [0.0; 3]).unwrap() };
        let m = GeneralizedMaterial { alpha_min: amin, alpha_max: amax, beta };
        check_sequence(l, &m, &pushes, false)?;
    }
}
