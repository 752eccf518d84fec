//! Fixed and prescribed degrees of freedom.

use std::fmt;

use crate::{AXES, AssemblyError, Result};

/// How fixed degrees of freedom enter the system.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ConstraintMethod {
    /// The paper's method: the diagonal entry becomes `big`, the rest of the row stays.
    /// Simple, but the condition number grows with `big` (~1e12 on the sphere case).
    Penalty {
        /// The diagonal value (the paper uses 1e9).
        big: f64,
    },
    /// The row and column are replaced by an identity row scaled to the block's mean
    /// diagonal; prescribed values are moved to the right-hand side. Exact and well
    /// conditioned.
    Eliminate,
}

impl Default for ConstraintMethod {
    fn default() -> Self {
        ConstraintMethod::Penalty { big: 1e9 }
    }
}

impl ConstraintMethod {
    /// The paper's penalty with big = 1e9.
    pub const PAPER: ConstraintMethod = ConstraintMethod::Penalty { big: DEFAULT_PENALTY };

    /// The method of this kind; `big` is used by the penalty only.
    pub fn of_kind(kind: ConstraintKind, big: f64) -> Self {
        match kind {
            ConstraintKind::Penalty => ConstraintMethod::Penalty { big },
            ConstraintKind::Eliminate => ConstraintMethod::Eliminate,
        }
    }

    /// Which kind of method this is.
    pub fn kind(self) -> ConstraintKind {
        match self {
            ConstraintMethod::Penalty { .. } => ConstraintKind::Penalty,
            ConstraintMethod::Eliminate => ConstraintKind::Eliminate,
        }
    }
}

/// The paper's penalty value ("big").
pub const DEFAULT_PENALTY: f64 = 1e9;

/// How fixed degrees of freedom are imposed, by name (`penalty`, `eliminate`); the
/// penalty value is a separate setting, so choosing the kind never drops it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum ConstraintKind {
    /// The paper's penalty ([`ConstraintMethod::Penalty`]).
    Penalty,
    /// Elimination ([`ConstraintMethod::Eliminate`]).
    #[default]
    Eliminate,
}

impl fibfluid_linalg::Choice for ConstraintKind {
    const WHAT: &'static str = "constraint method";
    const ALL: &'static [Self] = &[ConstraintKind::Penalty, ConstraintKind::Eliminate];
    fn name(self) -> &'static str {
        match self {
            ConstraintKind::Penalty => "penalty",
            ConstraintKind::Eliminate => "eliminate",
        }
    }
}
fibfluid_linalg::impl_choice!(ConstraintKind);

/// Which vertices a constraint applies to.
#[derive(Clone, Debug, PartialEq)]
pub enum Selector {
    /// Explicit vertex indices.
    Vertices(Vec<usize>),
    /// Vertices whose coordinate along `axis` is greater than `value`.
    Above {
        /// Axis 0..3.
        axis: usize,
        /// Threshold.
        value: f64,
    },
    /// Vertices whose coordinate along `axis` is less than `value`.
    Below {
        /// Axis 0..3.
        axis: usize,
        /// Threshold.
        value: f64,
    },
    /// Vertices within `within` of the largest coordinate along `axis`.
    Top {
        /// Axis 0..3.
        axis: usize,
        /// Distance from the top.
        within: f64,
    },
    /// Vertices within `within` of the smallest coordinate along `axis`.
    Bottom {
        /// Axis 0..3.
        axis: usize,
        /// Distance from the bottom.
        within: f64,
    },
    /// Vertices inside an axis-aligned box.
    Box {
        /// Lower corner.
        min: [f64; 3],
        /// Upper corner.
        max: [f64; 3],
    },
}

impl fmt::Display for Selector {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Selector::Vertices(v) => write!(f, "vertices {v:?}"),
            Selector::Above { axis, value } => write!(f, "{} > {value}", AXES[*axis]),
            Selector::Below { axis, value } => write!(f, "{} < {value}", AXES[*axis]),
            Selector::Top { axis, within } => write!(f, "within {within} of the top along {}", AXES[*axis]),
            Selector::Bottom { axis, within } => {
                write!(f, "within {within} of the bottom along {}", AXES[*axis])
            }
            Selector::Box { min, max } => write!(f, "box {min:?}..{max:?}"),
        }
    }
}

impl Selector {
    /// The selected vertex indices for these positions.
    pub fn select(&self, positions: &[[f64; 3]]) -> Result<Vec<usize>> {
        let n = positions.len();
        let pick = |pred: &dyn Fn(&[f64; 3]) -> bool| -> Vec<usize> {
            positions.iter().enumerate().filter(|(_, p)| pred(p)).map(|(i, _)| i).collect()
        };
        let sel = match self {
            Selector::Vertices(v) => {
                if let Some(&bad) = v.iter().find(|&&i| i >= n) {
                    return Err(AssemblyError::VertexOutOfRange { vertex: bad, vertices: n });
                }
                v.clone()
            }
            Selector::Above { axis, value } => pick(&|p| p[*axis] > *value),
            Selector::Below { axis, value } => pick(&|p| p[*axis] < *value),
            Selector::Top { axis, within } => {
                let top = positions.iter().map(|p| p[*axis]).fold(f64::NEG_INFINITY, f64::max);
                pick(&|p| p[*axis] >= top - within)
            }
            Selector::Bottom { axis, within } => {
                let bottom = positions.iter().map(|p| p[*axis]).fold(f64::INFINITY, f64::min);
                pick(&|p| p[*axis] <= bottom + within)
            }
            Selector::Box { min, max } => pick(&|p| (0..3).all(|c| p[c] >= min[c] && p[c] <= max[c])),
        };
        if sel.is_empty() {
            return Err(AssemblyError::EmptySelection { selector: self.to_string() });
        }
        Ok(sel)
    }
}

/// Per-vertex, per-axis constraints: `Some(v)` prescribes the displacement v (0 = fixed).
#[derive(Clone, Debug, PartialEq)]
pub struct Constraints {
    dofs: Vec<[Option<f64>; 3]>,
}

impl Constraints {
    /// No constraint on any of `n` vertices.
    pub fn new(n: usize) -> Self {
        Self { dofs: vec![[None; 3]; n] }
    }

    /// Number of vertices.
    pub fn n_vertices(&self) -> usize {
        self.dofs.len()
    }

    /// Fixes the chosen axes of one vertex.
    pub fn fix(&mut self, vertex: usize, axes: [bool; 3]) -> Result<()> {
        let n = self.dofs.len();
        let d = self.dofs.get_mut(vertex).ok_or(AssemblyError::VertexOutOfRange { vertex, vertices: n })?;
        for c in 0..3 {
            if axes[c] {
                d[c] = Some(0.0);
            }
        }
        Ok(())
    }

    /// Prescribes a displacement along one axis of one vertex.
    pub fn prescribe(&mut self, vertex: usize, axis: usize, value: f64) -> Result<()> {
        let n = self.dofs.len();
        let d = self.dofs.get_mut(vertex).ok_or(AssemblyError::VertexOutOfRange { vertex, vertices: n })?;
        d[axis] = Some(value);
        Ok(())
    }

    /// Fixes the chosen axes of every selected vertex; returns how many were selected.
    pub fn fix_selected(
        &mut self,
        selector: &Selector,
        positions: &[[f64; 3]],
        axes: [bool; 3],
    ) -> Result<usize> {
        let sel = selector.select(positions)?;
        for &v in &sel {
            self.fix(v, axes)?;
        }
        Ok(sel.len())
    }

    /// The constraint of one degree of freedom.
    pub fn get(&self, vertex: usize, axis: usize) -> Option<f64> {
        self.dofs[vertex][axis]
    }

    /// Number of constrained degrees of freedom along an axis.
    pub fn count(&self, axis: usize) -> usize {
        self.dofs.iter().filter(|d| d[axis].is_some()).count()
    }

    /// Whether the same vertices are constrained along the first `axes` axes.
    pub fn is_uniform(&self, axes: usize) -> bool {
        self.dofs.iter().all(|d| (1..axes).all(|c| d[c].is_some() == d[0].is_some()))
    }

    /// Whether any prescribed value is non-zero.
    pub fn has_nonzero(&self) -> bool {
        self.dofs.iter().flatten().any(|v| matches!(v, Some(x) if *x != 0.0))
    }

    /// Vertices with every axis in `axes` constrained.
    pub fn fully_fixed_vertices(&self, axes: usize) -> Vec<usize> {
        (0..self.dofs.len()).filter(|&i| (0..axes).all(|c| self.dofs[i][c].is_some())).collect()
    }
}
