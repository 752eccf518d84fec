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
        Self { offsets, values }
    }

    /// Cell `c`'s values (`8 x state_len`, point by point; empty for a stateless law).
    pub fn cell(&self, c: usize) -> &[f64] {
        self.offsets.get(c).zip(self.offsets.get(c + 1)).map_or(&[], |(&a, &b)| &self.values[a..b])
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

/// Point `p`'s slice of a cell's values for a law keeping `len` per point.
pub(crate) fn point_state(cell: &[f64], len: usize, p: usize) -> &[f64] {
    cell.get(p * len..(p + 1) * len).unwrap_or(&[])
}
