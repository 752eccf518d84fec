//! The assembled system and its right-hand sides.

use std::time::Instant;

use fibfluid_geometry::{FiberSet, Vec3};
use fibfluid_linalg::{Blocks, BorderedMatrix, Mat};
use rayon::prelude::*;

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

/// The body as the assembly sees it (a triangle mesh or the paper's 2D polygon).
#[derive(Clone, Copy, Debug)]
pub struct Body<'a> {
    /// 2 (polygon) or 3 (surface).
    pub axes: usize,
    /// Positions the stiffness is computed on.
    pub positions: &'a [Vec3],
    /// Vertex area vectors S of that shape.
    pub vertex_areas: &'a [Vec3],
    /// Surface edges (surface fibers), each once.
    pub edges: &'a [[u32; 2]],
    /// Kept bulk fibers.
    pub fibers: &'a FiberSet,
    /// Rest positions, for strain-dependent materials (None = `positions`).
    pub rest_positions: Option<&'a [Vec3]>,
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
pub fn assemble(
    body: &Body,
    material: &Material,
    constraints: &Constraints,
    opts: &AssemblyOptions,
) -> Result<System> {
    let start = Instant::now();
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
    let conn = body.fibers.mean_connections();
    let area: Vec<f64> =
        body.vertex_areas.iter().map(|s| (s[0] * s[0] + s[1] * s[1] + s[2] * s[2]).sqrt()).collect();
    let mut neighbors: Vec<Vec<u32>> = vec![Vec::new(); n];
    if material.surface_tension > 0.0 {
        for e in body.edges {
            neighbors[e[0] as usize].push(e[1]);
            neighbors[e[1] as usize].push(e[0]);
        }
        neighbors.iter_mut().for_each(|v| v.sort_unstable());
    }
    let rest = body.rest_positions.unwrap_or(body.positions);
    // Row-major bulk (without Y) and surface weights; K is symmetric so row-major equals
    // column-major and each row can be filled independently.
    let mut bulk = vec![0.0f64; n * n];
    let mut surf = vec![0.0f64; if material.surface_tension > 0.0 { n * n } else { 0 }];
    let gamma = material.surface_tension;
    let coincident = std::sync::Mutex::new(None);
    let bulk_row = |(i, row): (usize, &mut [f64])| {
        let pi = body.positions[i];
        for j in 0..n {
            if j == i || !body.fibers.contains(i, j) {
                continue;
            }
            let d = dist(pi, body.positions[j]);
            if !(d > 0.0) {
                *coincident.lock().unwrap_or_else(|e| e.into_inner()) = Some((i.min(j), i.max(j), d));
                continue;
            }
            let mut w = (area[i] + area[j]) / (2.0 * conn * d);
            if !material.law.is_linear() {
                let d0 = dist(rest[i], rest[j]);
                w *= material.law.factor((d - d0) / d0);
            }
            row[j] = w;
        }
    };
    // Small systems are filled on one thread: waking the pool costs more than the work.
    if n * n < PARALLEL_WORK {
        bulk.chunks_mut(n).enumerate().for_each(bulk_row);
    } else {
        bulk.par_chunks_mut(n).enumerate().for_each(bulk_row);
    }
    if let Some((i, j, distance)) = coincident.into_inner().unwrap_or(None) {
        return Err(AssemblyError::CoincidentVertices { i, j, distance });
    }
    if gamma > 0.0 {
        surf.par_chunks_mut(n).enumerate().for_each(|(i, row)| {
            for &j in &neighbors[i] {
                let j = j as usize;
                let d = dist(body.positions[i], body.positions[j]);
                if d > 0.0 {
                    row[j] = gamma * (area[i] + area[j]) / (2.0 * d * d);
                }
            }
        });
    }
    let shared = material.is_isotropic() && constraints.is_uniform(axes);
    let nblocks = if shared { 1 } else { axes };
    let mut blocks = Vec::with_capacity(nblocks);
    let mut diag_scale = [0.0; 3];
    let mut lifts = Vec::new();
    for c in 0..nblocks {
        let y = material.young[c];
        let mut k = Mat::<f64>::from_fn(n, n, |i, j| {
            if i == j {
                0.0
            } else {
                let s = if surf.is_empty() { 0.0 } else { surf[i * n + j] };
                -(y * bulk[i * n + j] + s)
            }
        });
        for j in 0..n {
            let s: f64 = k.col(j).iter().sum();
            k[(j, j)] = -s;
        }
        let free_diag: Vec<f64> =
            (0..n).filter(|&i| constraints.get(i, c).is_none()).map(|i| k[(i, i)]).collect();
        let mean_diag = free_diag.iter().sum::<f64>() / free_diag.len().max(1) as f64;
        // Record lifts for every axis this block serves.
        let served: Vec<usize> = if shared { (0..axes).collect() } else { vec![c] };
        for &axis in &served {
            diag_scale[axis] = mean_diag;
            for i in 0..n {
                if let Some(v) = constraints.get(i, axis)
                    && v != 0.0
                    && opts.method == ConstraintMethod::Eliminate
                {
                    lifts.push(Lift {
                        axis,
                        vertex: i,
                        value: v,
                        column: k.col(i).iter().copied().collect(),
                    });
                }
            }
        }
        for i in 0..n {
            if constraints.get(i, c).is_none() {
                continue;
            }
            match opts.method {
                ConstraintMethod::Penalty { big } => k[(i, i)] = big,
                ConstraintMethod::Eliminate => {
                    for j in 0..n {
                        k[(i, j)] = 0.0;
                        k[(j, i)] = 0.0;
                    }
                    k[(i, i)] = mean_diag;
                }
            }
        }
        blocks.push(k);
    }
    let blocks =
        if shared { Blocks::Shared(blocks.pop().expect("one block")) } else { Blocks::PerAxis(blocks) };
    let scale = match opts.pressure_scaling {
        PressureScaling::None => 1.0,
        PressureScaling::Auto => {
            let s = auto_pressure_scale(&blocks, body.vertex_areas, constraints, axes);
            if s.is_finite() && s > 0.0 { s } else { 1.0 }
        }
        PressureScaling::Factor(f) => f,
    };
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

/// Below this many matrix entries assembly runs on one thread.
const PARALLEL_WORK: usize = 1 << 16;

/// The [`PressureScaling::Auto`] factor `lambda_S / |S|`, with `|S|` the 2-norm of the
/// border over the free degrees of freedom and `lambda_S = S' K S / S' S` the Rayleigh
/// quotient of the (constrained) blocks along it.
///
/// Along S the bordered matrix acts like `[[lambda_S, s |S|], [s |S|, 0]]`, whose eigenvalues
/// are `lambda_S (1 +- sqrt(5)) / 2` when `s |S| = lambda_S`: the pressure then adds no
/// eigenvalue outside the blocks' own range. The factor scales like K, so the condition
/// number does not depend on the units of Y and gamma.
fn auto_pressure_scale(blocks: &Blocks, areas: &[Vec3], constraints: &Constraints, axes: usize) -> f64 {
    let (mut sks, mut ss) = (0.0, 0.0);
    for c in 0..axes {
        let k = match blocks {
            Blocks::Shared(k) => k,
            Blocks::PerAxis(ks) => &ks[c],
        };
        let free = |i: usize| constraints.get(i, c).is_none();
        let s: Vec<f64> = (0..areas.len()).map(|i| if free(i) { areas[i][c] } else { 0.0 }).collect();
        for (j, &sj) in s.iter().enumerate() {
            if sj != 0.0 {
                let col = k.col(j);
                sks += sj * s.iter().enumerate().map(|(i, si)| si * col[i]).sum::<f64>();
                ss += sj * sj;
            }
        }
    }
    (sks / ss) / ss.sqrt()
}

#[inline]
fn dist(a: Vec3, b: Vec3) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
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
