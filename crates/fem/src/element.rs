//! The 24 x 24 stiffness of a cubic trilinear (Q1) cell.
//!
//! The energy `integral of 2 mu |dev eps|^2 + kappa (tr eps)^2` (with `/2`) is split: the
//! deviatoric part is integrated with 2x2x2 Gauss points; the volumetric part uses the
//! cell's mean dilatation (B-bar; on a cube the mean of each shape-function gradient equals
//! its value at the centre, so this is selective reduced integration at the centre) or, for
//! [`Element::FullQ1`], the same Gauss points. Local dof `3 b + a` is corner `b`, axis `a`.
//! The matrices are for a unit cube and unit moduli; a cell of edge `h` scales them by `h`.

use crate::grid::Element;

/// Local dofs of a cell.
pub(crate) const CELL_DOFS: usize = 24;

/// A dense cell matrix.
pub(crate) type CellMatrix = [[f64; CELL_DOFS]; CELL_DOFS];

/// Gradients of the eight trilinear shape functions at a point `x` of the unit cube.
pub(crate) fn gradients(x: [f64; 3]) -> [[f64; 3]; 8] {
    std::array::from_fn(|b| {
        let f = |a: usize| if (b >> a) & 1 == 1 { x[a] } else { 1.0 - x[a] };
        let df = |a: usize| if (b >> a) & 1 == 1 { 1.0 } else { -1.0 };
        [df(0) * f(1) * f(2), f(0) * df(1) * f(2), f(0) * f(1) * df(2)]
    })
}

/// The 2x2x2 Gauss points of the unit cube (each of weight 1/8).
pub(crate) fn gauss_points() -> [[f64; 3]; 8] {
    let g = 0.5 / 3f64.sqrt();
    std::array::from_fn(|p| std::array::from_fn(|a| 0.5 + if (p >> a) & 1 == 1 { g } else { -g }))
}

/// Unit-cube, unit-moduli cell matrices: `(deviatoric, volumetric)`, so that a cell of
/// edge `h` with shear modulus `mu` and bulk modulus `kappa` has `h (mu D + kappa V)`.
pub(crate) fn unit_cell_matrices(element: Element) -> (CellMatrix, CellMatrix) {
    let mut dev = [[0.0; CELL_DOFS]; CELL_DOFS];
    let mut vol = [[0.0; CELL_DOFS]; CELL_DOFS];
    let w = 1.0 / 8.0;
    for x in gauss_points() {
        let g = gradients(x);
        for b in 0..8 {
            for c in 0..8 {
                let gbgc: f64 = (0..3).map(|a| g[b][a] * g[c][a]).sum();
                for i in 0..3 {
                    for j in 0..3 {
                        // eps(e_i N_b) : eps(e_j N_c) - tr tr' / 3, times 2.
                        let dd = if i == j { gbgc } else { 0.0 } + g[b][j] * g[c][i];
                        dev[3 * b + i][3 * c + j] += w * (dd - 2.0 / 3.0 * g[b][i] * g[c][j]);
                        if element == Element::FullQ1 {
                            vol[3 * b + i][3 * c + j] += w * g[b][i] * g[c][j];
                        }
                    }
                }
            }
        }
    }
    if element == Element::BBar {
        let g = gradients([0.5; 3]);
        for b in 0..8 {
            for c in 0..8 {
                for i in 0..3 {
                    for j in 0..3 {
                        vol[3 * b + i][3 * c + j] = g[b][i] * g[c][j];
                    }
                }
            }
        }
    }
    (dev, vol)
}
