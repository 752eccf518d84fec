//! The per-point state buffer the body keeps for its laws.

use crate::hyper::CellMaterial;

/// Gauss points per cell.
pub const POINTS_PER_CELL: usize = 8;

/// Each cell's Gauss points' law state, cell by cell (`8 x state_len` values per cell,
/// none for a stateless law). Made at rest by [`LawStates::new`].
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LawStates {
    /// Where each cell's values start (`n_cells + 1` offsets).
    offsets: Vec<usize>,
    values: Vec<f64>,
    /// The length of the step being solved (s; 0 outside a timed run: the instantaneous
    /// response).
    dt: f64,
}

/// What a law reads at a point while a step is solved: the point's state at the step's
/// start and the step's length.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointState<'a> {
    /// The point's values (`state_len` of them; empty: the law's elastic response).
    pub values: &'a [f64],
    /// The step's length, s (0: the instantaneous response).
    pub dt: f64,
}

impl PointState<'static> {
    /// No state and no time: a law's elastic (instantaneous) response.
    pub const ELASTIC: Self = Self { values: &[], dt: 0.0 };
}

/// One cell's law state while a step is solved: its points' values and the step's length.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CellLawState<'a> {
    /// The cell's values (`8 x state_len`, point by point).
    pub values: &'a [f64],
    /// The step's length, s.
    pub dt: f64,
}

impl<'a> CellLawState<'a> {
    /// No state and no time (see [`PointState::ELASTIC`]).
    pub const ELASTIC: CellLawState<'static> = CellLawState { values: &[], dt: 0.0 };

    /// Point `p`'s state for a law keeping `len` values per point.
    pub fn point(&self, len: usize, p: usize) -> PointState<'a> {
        PointState { values: self.values.get(p * len..(p + 1) * len).unwrap_or(&[]), dt: self.dt }
    }
}

impl LawStates {
    /// Every point of every cell at its law's initial state.
    pub fn new(materials: &[CellMaterial]) -> Self {
        let mut offsets = Vec::with_capacity(materials.len() + 1);
        offsets.push(0);
        for m in materials {
            offsets.push(offsets.last().copied().unwrap_or(0) + POINTS_PER_CELL * m.law.state_len());
        }
        let mut values = vec![0.0; offsets.last().copied().unwrap_or(0)];
        for (c, m) in materials.iter().enumerate() {
            let len = m.law.state_len();
            if len > 0 {
                values[offsets[c]..offsets[c + 1]].chunks_mut(len).for_each(|s| m.law.initial_state(s));
            }
        }
        Self { offsets, values, dt: 0.0 }
    }

    /// Cell `c`'s state as the step being solved reads it (empty values for a stateless
    /// law).
    pub fn cell(&self, c: usize) -> CellLawState<'_> {
        let values =
            self.offsets.get(c).zip(self.offsets.get(c + 1)).map_or(&[][..], |(&a, &b)| &self.values[a..b]);
        CellLawState { values, dt: self.dt }
    }

    /// The length of the step being solved (s).
    pub fn dt(&self) -> f64 {
        self.dt
    }

    /// Sets the length of the step being solved (s; 0: the instantaneous response).
    pub fn set_dt(&mut self, dt: f64) {
        self.dt = dt;
    }

    /// Cell `c`'s values, to update.
    pub fn cell_mut(&mut self, c: usize) -> &mut [f64] {
        match (self.offsets.get(c), self.offsets.get(c + 1)) {
            (Some(&a), Some(&b)) => &mut self.values[a..b],
            _ => &mut [],
        }
    }

    /// Values kept in all.
    pub fn len(&self) -> usize {
        self.values.len()
    }

    /// Whether no law keeps state.
    pub fn is_empty(&self) -> bool {
        self.values.is_empty()
    }
}
