//! Patch test: every surface vertex of a box held to a linear field `u = A x + c`; the
//! element must reproduce the field exactly at every node (Q1 with B-bar passes the patch
//! test: constant strain is represented exactly and the mean dilatation of a constant
//! strain is that strain's trace).

use crate::common::*;
use fibfluid_fem::{FemBody, Loads, SparseGrid, Tissue};

#[test]
fn box_held_to_a_linear_field_reproduces_it_at_every_node() {
    // Box [1, 3] x [-1, 1] x [2, 4], grid and surface both of spacing 0.5.
    let lo = [1.0, -1.0, 2.0];
    let (pos, tris) = box_surface(lo, [4, 4, 4], 0.5);
    let grid = SparseGrid::from_surface(&pos, &tris, 4).unwrap();
    assert_eq!(grid.n_cells(), 64);
    assert!(grid.fill().iter().all(|&f| f == 1.0));
    // 3-2-1 support at three corners; the field vanishes there in the fixed axes, which
    // asks A[1][0] = A[2][0] = A[2][1] = 0 (all six strains stay free).
    let corner = |p: V3| pos.iter().position(|q| *q == p).unwrap();
    let (o, ex, ey) = (corner(lo), corner([3.0, -1.0, 2.0]), corner([1.0, 1.0, 2.0]));
    let mut fixed = vec![[false; 3]; pos.len()];
    fixed[o] = [true; 3];
    fixed[ex] = [false, true, true];
    fixed[ey] = [false, false, true];
    let a = [[1e-3, 2e-3, -1.5e-3], [0.0, -2e-3, 0.7e-3], [0.0, 0.0, 3e-3]];
    let field = |x: V3| -> V3 { std::array::from_fn(|i| (0..3).map(|j| a[i][j] * (x[j] - lo[j])).sum()) };
    let tissue = Tissue::new(5e4, 0.49, 1000.0).unwrap();
    let mut body = FemBody::new(grid, &tissue, &fixed).unwrap();
    // Every vertex is held, the supports too: their fixed axes (target 0) are skipped.
    let held: Vec<(usize, V3)> = (0..pos.len()).map(|v| (v, field(pos[v]))).collect();
    let r = body.respond_held(&Loads::default(), &held).unwrap();
    let scale = pos.iter().map(|&p| norm(field(p))).fold(0.0, f64::max);
    let nodes = body.grid().node_positions();
    let mut worst = 0.0_f64;
    for (n, x) in nodes.iter().enumerate() {
        let e = field(*x);
        for c in 0..3 {
            worst = worst.max((r.node_displacements[n][c] - e[c]).abs());
        }
    }
    // Rounding of a solve with cond(K) ~ 1e3 at this size (nu = 0.49): 1e-10 relative.
    assert!(worst <= 1e-10 * scale, "worst node error {worst:e} for field scale {scale:e}");
    // 125 nodes, 27 of them inside the box and not held.
    assert_eq!(nodes.len(), 125);
}
