//! The assembled system and its right-hand sides.

use std::time::Instant;

use fibfluid_geometry::Vec3;
use fibfluid_linalg::{Blocks, BorderedMatrix};

use crate::block::{BlockSpec, PairData, fill_block};
use crate::body::Body;
use crate::{AXES, AssemblyError, ConstraintMethod, Constraints, Material, Result};

/// How the pressure unknown is scaled.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum PressureScaling {
    /// The paper's raw border (`S`), as in Eq. 8.
    None,
    /// Border times `lambda_S / |S|`, with `lambda_S = S' K S / S' S` the stiffness along the
    /// border (free degrees of freedom), so the pressure row has the displacement rows'
    /// scale in any units (REFERENCE §3 suggests `sqrt(diag K) / |S|`, which is not
    /// invariant under a change of the units of Y and gamma).
    #[default]
    Auto,
    /// A given factor.
    Factor(f64),
}

/// Options of [`assemble`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AssemblyOptions {
    /// How fixed degrees of freedom are imposed.
    pub method: ConstraintMethod,
    /// Pressure scaling.
    pub pressure_scaling: PressureScaling,
}

/// What assembly did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct AssemblyStats {
    /// Bulk fibers used.
    pub bulk_fibers: usize,
    /// Surface fibers used (0 when gamma = 0).
    pub surface_fibers: usize,
    /// The effective connection count that replaces N - 1 in Eq. 6.
    pub connections: f64,
    /// Number of K blocks stored (1 when shared).
    pub blocks: usize,
    /// Seconds spent.
    pub seconds: f64,
}

/// A prescribed non-zero displacement moved to the right-hand side (elimination).
#[derive(Clone, Debug, PartialEq)]
struct Lift {
    axis: usize,
    vertex: usize,
    value: f64,
    /// The original column of K_axis at `vertex`.
    column: Vec<f64>,
}

/// The assembled bordered system plus what is needed to build right-hand sides for it.
#[derive(Clone, Debug)]
pub struct System {
    /// The matrix handed to a linear solver.
    pub matrix: BorderedMatrix,
    /// What assembly did.
    pub stats: AssemblyStats,
    constraints: Constraints,
    method: ConstraintMethod,
    axes: usize,
    diag_scale: [f64; 3],
    lifts: Vec<Lift>,
}

/// Assembles the bordered system for a body, material and constraints.
///
/// Each K block is written once, column by column in parallel (K is symmetric, so column
/// j is row j): the fiber weights of a column come from one loop over contiguous
/// coordinate arrays (`d = sqrt(dx^2 + dy^2 + dz^2)`), compiled for the CPU's widest
/// vector unit; the surface fibers, the diagonal, the elimination or penalty of fixed
/// degrees of freedom and the terms of the automatic pressure scale follow while the
/// column is in cache.
pub fn assemble(
    body: &Body,
    material: &Material,
    constraints: &Constraints,
    opts: &AssemblyOptions,
) -> Result<System> {
    let start = Instant::now();
    validate(body, material, constraints)?;
    let (n, axes) = (body.positions.len(), body.axes);
    let conn = body.fibers.mean_connections();
    let pairs = PairData::new(body, material, conn);
    let shared = material.is_isotropic() && constraints.is_uniform(axes);
    let nblocks = if shared { 1 } else { axes };
    let mut blocks = Vec::with_capacity(nblocks);
    let mut diag_scale = [0.0; 3];
    let mut lifts = Vec::new();
    let (mut sks, mut ss) = (vec![0.0; axes], vec![0.0; axes]);
    for c in 0..nblocks {
        let served: Vec<usize> = if shared { (0..axes).collect() } else { vec![c] };
        let spec = BlockSpec {
            fiber_modulus: material.fiber_modulus()[c],
            fixed: (0..n).map(|i| constraints.get(i, c).is_some()).collect(),
            method: opts.method,
            // Free border components of the served axes, for the automatic pressure scale.
            borders: if opts.pressure_scaling == PressureScaling::Auto {
                served.iter().map(|&a| free_border(body.vertex_areas, constraints, a)).collect()
            } else {
                Vec::new()
            },
            keep: (0..n)
                .filter(|&i| {
                    opts.method == ConstraintMethod::Eliminate
                        && served.iter().any(|&a| constraints.get(i, a).is_some_and(|v| v != 0.0))
                })
                .collect(),
        };
        let block = fill_block(&pairs, &spec)?;
        for (s, &axis) in served.iter().enumerate() {
            diag_scale[axis] = block.mean_diag;
            if let Some(&(num, den)) = block.scale_terms.get(s) {
                (sks[axis], ss[axis]) = (num, den);
            }
            for (i, column) in &block.kept_columns {
                if let Some(value) = constraints.get(*i, axis).filter(|v| *v != 0.0) {
                    lifts.push(Lift { axis, vertex: *i, value, column: column.clone() });
                }
            }
        }
        blocks.push(block.k);
    }
    // Lifts in vertex order within each axis, as the right-hand side expects them.
    lifts.sort_by_key(|l| (l.axis, l.vertex));
    let blocks =
        if shared { Blocks::Shared(blocks.pop().expect("one block")) } else { Blocks::PerAxis(blocks) };
    let scale = match opts.pressure_scaling {
        PressureScaling::None => 1.0,
        PressureScaling::Auto => {
            let (num, den) = (sks.iter().sum::<f64>(), ss.iter().sum::<f64>());
            let s = (num / den) / den.sqrt();
            if s.is_finite() && s > 0.0 { s } else { 1.0 }
        }
        PressureScaling::Factor(f) => f,
    };
    let gamma = material.surface_tension();
    let mut system = System {
        matrix: BorderedMatrix::new(blocks, vec![vec![0.0; n]; axes], scale),
        stats: AssemblyStats {
            bulk_fibers: body.fibers.kept(),
            surface_fibers: if gamma > 0.0 { body.edges.len() } else { 0 },
            connections: conn,
            blocks: nblocks,
            seconds: 0.0,
        },
        constraints: constraints.clone(),
        method: opts.method,
        axes,
        diag_scale,
        lifts,
    };
    let border = system.border_for(body.vertex_areas);
    system.matrix.set_border(&border);
    system.stats.seconds = start.elapsed().as_secs_f64();
    Ok(system)
}

/// The checks of [`assemble`] that need no matrix.
pub(crate) fn validate(body: &Body, material: &Material, constraints: &Constraints) -> Result<()> {
    material.check()?;
    let (n, axes) = (body.positions.len(), body.axes);
    if constraints.n_vertices() != n {
        return Err(AssemblyError::VertexOutOfRange { vertex: constraints.n_vertices(), vertices: n });
    }
    for c in 0..axes {
        if constraints.count(c) == 0 {
            return Err(AssemblyError::Unconstrained { axis: AXES[c] });
        }
    }
    if (0..axes).all(|c| constraints.count(c) == n) {
        return Err(AssemblyError::EverythingFixed);
    }
    Ok(())
}

/// Axis `c` of the vertex area vectors, zero at the vertices fixed along it.
fn free_border(areas: &[Vec3], constraints: &Constraints, c: usize) -> Vec<f64> {
    areas.iter().enumerate().map(|(i, s)| if constraints.get(i, c).is_none() { s[c] } else { 0.0 }).collect()
}

impl System {
    /// Number of axes.
    pub fn axes(&self) -> usize {
        self.axes
    }

    /// The constraints it was assembled with.
    pub fn constraints(&self) -> &Constraints {
        &self.constraints
    }

    /// The constraint method.
    pub fn method(&self) -> ConstraintMethod {
        self.method
    }

    /// The physical border for vertex area vectors `S` (eliminated degrees of freedom get
    /// a zero border entry).
    pub fn border_for(&self, vertex_areas: &[Vec3]) -> Vec<Vec<f64>> {
        let n = vertex_areas.len();
        (0..self.axes)
            .map(|c| {
                (0..n)
                    .map(|i| {
                        if self.method == ConstraintMethod::Eliminate && self.constraints.get(i, c).is_some()
                        {
                            0.0
                        } else {
                            vertex_areas[i][c]
                        }
                    })
                    .collect()
            })
            .collect()
    }

    /// The full right-hand side for a load vector `b` (length axes*N, paper layout) and a
    /// volume target `t` (the last row asks `sum S . u = t`).
    ///
    /// `border_areas` are the `S` currently in the border (needed to move prescribed
    /// displacements to the right-hand side under elimination).
    ///
    /// Prescribed displacements enter multiplied by `prescribed_scale` (1 for a full
    /// solve, 1/steps for one load step).
    pub fn rhs(
        &self,
        b: &[f64],
        volume_target: f64,
        border_areas: &[Vec3],
        prescribed_scale: f64,
    ) -> Vec<f64> {
        let n = self.matrix.n_vertices();
        let mut r = Vec::with_capacity(self.axes * n + 1);
        r.extend_from_slice(b);
        let mut target = volume_target;
        for c in 0..self.axes {
            for i in 0..n {
                if let Some(v) = self.constraints.get(i, c) {
                    let v = v * prescribed_scale;
                    match self.method {
                        ConstraintMethod::Penalty { big } => r[c * n + i] += big * v,
                        ConstraintMethod::Eliminate => {
                            r[c * n + i] = self.diag_scale[c] * v;
                            target -= border_areas[i][c] * v;
                        }
                    }
                }
            }
        }
        for lift in &self.lifts {
            for j in 0..n {
                if self.constraints.get(j, lift.axis).is_none() {
                    r[lift.axis * n + j] -= lift.column[j] * lift.value * prescribed_scale;
                }
            }
        }
        r.push(self.matrix.pressure_scale() * target);
        r
    }

    /// `(K u)` at the free degree of freedom (`vertex`, `axis`) for displacements `u`: the
    /// force of the fibers on the vertex along the axis. The columns of eliminated
    /// degrees of freedom that hold a non-zero prescribed value are put back, so the
    /// value is that of the stiffness before elimination. Meaningless at a fixed degree
    /// of freedom (its row is the constraint's).
    pub fn stiffness_force(&self, vertex: usize, axis: usize, u: &[Vec3]) -> f64 {
        // K is symmetric: row `vertex` is column `vertex`.
        let column = self.matrix.block_column(axis, vertex);
        let mut sum: f64 = column.iter().zip(u).map(|(k, d)| k * d[axis]).sum();
        for lift in self.lifts.iter().filter(|l| l.axis == axis) {
            sum += lift.column[vertex] * u[lift.vertex][axis];
        }
        sum
    }

    /// Splits a solution into per-vertex displacements and the (physical) pressure.
    pub fn split_solution(&self, x: &[f64]) -> (Vec<Vec3>, f64) {
        let n = self.matrix.n_vertices();
        let u = (0..n)
            .map(|i| {
                let mut v = [0.0; 3];
                for c in 0..self.axes {
                    v[c] = x[c * n + i];
                }
                v
            })
            .collect();
        (u, x[self.axes * n] * self.matrix.pressure_scale())
    }
}
