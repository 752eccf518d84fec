//! What every mesh reader produces before validation, shared by the OBJ, STL, PLY and
//! OFF parsers (`io`, `ply`, `off`).

use crate::vec3::Vec3;

/// Appends polygon `idx` (at least 3 vertices) as the fan `(0, k, k + 1)`, the one
/// triangulation of every reader.
pub(crate) fn push_fan(triangles: &mut Vec<[u32; 3]>, idx: &[u32]) {
    for k in 1..idx.len().saturating_sub(1) {
        triangles.push([idx[0], idx[k], idx[k + 1]]);
    }
}

/// What a parser found: every position of the file, its triangles (file indices) and notes.
pub(crate) struct RawMesh {
    pub(crate) positions: Vec<Vec3>,
    pub(crate) triangles: Vec<[u32; 3]>,
    pub(crate) notes: Vec<String>,
}

/// A parser's result: its error is (1-based line, 0 when not tied to one; message).
pub(crate) type ParseResult<T> = std::result::Result<T, (usize, String)>;

/// The UTF-8 byte-order mark some editors write at the start of a text file.
pub(crate) const UTF8_BOM: &[u8] = b"\xEF\xBB\xBF";
