//! OFF files (Geomview's Object File Format, ASCII) in and out.
//!
//! The reader takes the `OFF` keyword (also `COFF`, `NOFF`, `STOFF` and their combinations,
//! whose vertex lines carry colours, normals or texture coordinates after x y z: those are
//! ignored), the counts `nv nf [ne]` on the keyword's line or the next one, `nv` vertex lines
//! and `nf` face lines `k i0 .. ik-1` (0-based indices; anything after them, such as a
//! colour, is ignored). `#` starts a comment; blank lines are skipped. Polygons are
//! fan-triangulated as OBJ polygons are. The counts are checked against the file's size
//! before anything is allocated for them.

use std::io::Write;

use crate::raw::{ParseResult, RawMesh, UTF8_BOM, push_fan};
use crate::vec3::Vec3;

/// Fewest bytes of a vertex line (`0 0 0\n`) and of a face line (`3 0 1 2\n`).
const MIN_VERTEX_BYTES: u128 = 6;
const MIN_FACE_BYTES: u128 = 8;

/// Whether `keyword` is an ASCII OFF header keyword this reader takes: `[ST][C][N]OFF`.
fn is_off_keyword(keyword: &str) -> bool {
    let Some(prefix) = keyword.strip_suffix("OFF") else { return false };
    let prefix = prefix.strip_prefix("ST").unwrap_or(prefix);
    let prefix = prefix.strip_prefix('C').unwrap_or(prefix);
    matches!(prefix, "" | "N")
}

/// The file's lines without comments and blank ones: (1-based line number, tokens).
fn content_lines(text: &str) -> impl Iterator<Item = (usize, Vec<&str>)> {
    text.split('\n').enumerate().filter_map(|(i, line)| {
        let line = line.split('#').next().unwrap_or("");
        let tokens: Vec<&str> = line.split_ascii_whitespace().collect();
        (!tokens.is_empty()).then_some((i + 1, tokens))
    })
}

/// Reads the keyword and the counts: (vertices, faces).
fn parse_header<'a>(
    lines: &mut impl Iterator<Item = (usize, Vec<&'a str>)>,
    size: usize,
) -> ParseResult<(u64, u64)> {
    let (ln, tokens) = lines.next().ok_or((0, "not an OFF file (it is empty)".to_string()))?;
    let keyword = tokens[0];
    if !is_off_keyword(keyword) {
        let message = if keyword.ends_with("OFF") {
            format!("`{keyword}` files (4D or n-dimensional OFF) are not read; 3D `OFF` is")
        } else {
            format!("not an OFF file (it starts with `{keyword}`, not `OFF`)")
        };
        return Err((ln, message));
    }
    let (ln, counts) = match &tokens[1..] {
        ["BINARY", ..] => return Err((ln, "binary OFF is not read; save it as ASCII OFF or as PLY".into())),
        [] => lines.next().ok_or((0, "the file ends before the vertex and face counts".to_string()))?,
        rest => (ln, rest.to_vec()),
    };
    if !(2..=3).contains(&counts.len()) {
        return Err((
            ln,
            format!("expected the counts `vertices faces edges`, found {} values", counts.len()),
        ));
    }
    let count =
        |tok: &str, what: &str| tok.parse::<u64>().map_err(|_| (ln, format!("bad {what} count `{tok}`")));
    let (nv, nf) = (count(counts[0], "vertex")?, count(counts[1], "face")?);
    if let Some(ne) = counts.get(2) {
        count(ne, "edge")?;
    }
    let need = nv as u128 * MIN_VERTEX_BYTES + nf as u128 * MIN_FACE_BYTES;
    if need > size as u128 {
        return Err((
            ln,
            format!(
                "the header claims {nv} vertices and {nf} faces (at least {need} bytes) but the file has {size} bytes"
            ),
        ));
    }
    if nv > u32::MAX as u64 {
        return Err((ln, format!("{nv} vertices: more than this reader indexes (2^32 - 1)")));
    }
    Ok((nv, nf))
}

/// Parses an OFF file's bytes.
pub(crate) fn parse_off(bytes: &[u8]) -> ParseResult<RawMesh> {
    let bytes = bytes.strip_prefix(UTF8_BOM).unwrap_or(bytes);
    let text = std::str::from_utf8(bytes).map_err(|e| {
        let line = 1 + bytes[..e.valid_up_to()].iter().filter(|&&b| b == b'\n').count();
        (line, "not a text OFF file (invalid UTF-8)".to_string())
    })?;
    let mut lines = content_lines(text);
    let (nv, nf) = parse_header(&mut lines, bytes.len())?;
    let mut positions: Vec<Vec3> = Vec::new();
    positions
        .try_reserve_exact(nv as usize)
        .map_err(|_| (0, format!("cannot allocate memory for {nv} vertices")))?;
    for k in 0..nv {
        let (ln, tokens) = lines.next().ok_or((0, format!("the file ends after {k} of {nv} vertices")))?;
        if tokens.len() < 3 {
            return Err((ln, format!("vertex {k} has {} coordinates, 3 expected", tokens.len())));
        }
        let mut p = [0.0; 3];
        for (slot, tok) in p.iter_mut().zip(&tokens) {
            *slot = tok.parse::<f64>().map_err(|_| (ln, format!("bad coordinate `{tok}`")))?;
        }
        if p.iter().any(|c| !c.is_finite()) {
            return Err((ln, format!("vertex {k} has a non-finite coordinate")));
        }
        positions.push(p);
    }
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    triangles
        .try_reserve_exact(nf as usize)
        .map_err(|_| (0, format!("cannot allocate memory for {nf} faces")))?;
    let (mut polygons, mut idx) = (0usize, Vec::new());
    for k in 0..nf {
        let (ln, tokens) = lines.next().ok_or((0, format!("the file ends after {k} of {nf} faces")))?;
        let n: usize =
            tokens[0].parse().map_err(|_| (ln, format!("bad vertex count `{}` of face {k}", tokens[0])))?;
        if n < 3 {
            return Err((ln, format!("face {k} has {n} vertices (at least 3 needed)")));
        }
        if tokens.len() - 1 < n {
            return Err((ln, format!("face {k} announces {n} vertices but lists {}", tokens.len() - 1)));
        }
        idx.clear();
        for tok in &tokens[1..=n] {
            let v: i64 = tok.parse().map_err(|_| (ln, format!("bad face index `{tok}`")))?;
            if v < 0 || v as u64 >= nv {
                return Err((
                    ln,
                    format!("face refers to vertex {v} but the file has {nv} vertices (0-based)"),
                ));
            }
            idx.push(v as u32);
        }
        polygons += usize::from(n > 3);
        push_fan(&mut triangles, &idx);
    }
    if positions.is_empty() {
        return Err((0, "no vertices (the header counts 0)".into()));
    }
    if triangles.is_empty() {
        return Err((0, "no faces (the header counts 0)".into()));
    }
    let mut notes = Vec::new();
    if polygons > 0 {
        notes.push(format!("{polygons} polygons with more than 3 vertices triangulated as fans"));
    }
    let trailing = lines.count();
    if trailing > 0 {
        notes.push(format!("{trailing} lines after the last face ignored"));
    }
    Ok(RawMesh { positions, triangles, notes })
}

/// Writes an OFF file to any writer: the shortest decimal that reads back to the same f64
/// for every coordinate, and one `3 a b c` line (0-based) per triangle.
pub fn write_off_to(out: &mut impl Write, positions: &[Vec3], triangles: &[[u32; 3]]) -> std::io::Result<()> {
    writeln!(out, "OFF\n{} {} 0", positions.len(), triangles.len())?;
    for p in positions {
        writeln!(out, "{:?} {:?} {:?}", p[0], p[1], p[2])?;
    }
    for t in triangles {
        writeln!(out, "3 {} {} {}", t[0], t[1], t[2])?;
    }
    Ok(())
}
