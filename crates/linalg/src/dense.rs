//! Shared helpers of the dense backends.

use crate::{FactorCost, LinalgError, Result, lu_flops};

/// Fraction of the available memory a dense backend may use.
pub const DENSE_MEMORY_FRACTION: f64 = 0.5;

/// Bytes of memory currently available (Linux `MemAvailable`), if known.
pub fn available_memory_bytes() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// Errors before allocating if `copies` dense dim x dim f64 matrices would not fit in
/// [`DENSE_MEMORY_FRACTION`] of the available memory (8 GiB when that is unknown). The dense
/// backends call it with `copies = 2` (the matrix and its factors) before forming the matrix;
/// the error says how much memory is needed and points to the `structured` backend.
pub fn check_dense_memory(dim: usize, copies: usize) -> Result<()> {
    let need = (dim as f64) * (dim as f64) * 8.0 * copies as f64;
    let limit = available_memory_bytes().map(|b| b as f64 * DENSE_MEMORY_FRACTION).unwrap_or(8.0 * GIB);
    if need > limit {
        return Err(LinalgError::TooLarge { dim, gib: need / GIB, limit_gib: limit / GIB });
    }
    Ok(())
}

const GIB: f64 = 1024.0 * 1024.0 * 1024.0;

pub(crate) fn dense_lu_cost(dim: usize, seconds: f64, word_bytes: usize) -> FactorCost {
    FactorCost { flops: lu_flops(dim), seconds, bytes: dim * dim * word_bytes }
}
