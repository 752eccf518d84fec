//! Tool-path files (`PATH.csv`), read through the same size- and type-checked reader as
//! meshes and scenes.
//!
//! # The path file
//!
//! ```text
//! frame,vertex,ux,uy,uz        (grab: displacement from rest)   or
//! frame,vertex,fx,fy,fz        (push: applied force)
//! 0,12,0.0,-0.01,0.0
//! 1,12,0.0,-0.02,0.0
//! 2,,,,                        (a frame with nothing applied)
//! ```
//!
//! Vertices are 0-based indices in the mesh file's order (as in a scene's `[[force]]`).
//! Frames run from 0 to the largest frame number; rows of the same frame apply together; a
//! vertex absent from a frame is released; frame numbers must not decrease. Blank lines and
//! lines starting with `#` are skipped.

use std::path::{Path, PathBuf};

use fibfluid_interact::{MAX_FRAME, PathKind, PathProblem, PathRow, ProbeError, ToolPath};

use crate::Error;

/// Reads and parses a path file: regular files only, at most the file size limit
/// ([`fibfluid_geometry::read_file_limited`]), UTF-8 text.
pub fn load_tool_path(path: impl AsRef<Path>) -> Result<ToolPath, Error> {
    let path = path.as_ref();
    if path.is_dir() {
        return Err(ProbeError::IsDirectory { path: path.to_path_buf() }.into());
    }
    let bytes = fibfluid_geometry::read_file_limited(path, None).map_err(|e| match e {
        fibfluid_geometry::ReadError::Io(source) => Error::Io { path: path.to_path_buf(), source },
        other => ProbeError::Unreadable { path: path.to_path_buf(), problem: other }.into(),
    })?;
    let text = String::from_utf8(bytes).map_err(|_| ProbeError::NotUtf8 { path: path.to_path_buf() })?;
    Ok(parse_tool_path(path, &text)?)
}

/// At most this many characters of a line are quoted back in a message.
const QUOTE_CHARS: usize = 80;

/// The start of `line`, for a one-line message (a 100 MB line is not echoed).
fn excerpt(line: &str) -> String {
    let mut s: String = line.chars().take(QUOTE_CHARS).collect();
    if line.chars().nth(QUOTE_CHARS).is_some() {
        s.push_str("...");
    }
    s
}

/// Parses the text of a path file; `source` names it in errors.
pub fn parse_tool_path(source: impl Into<PathBuf>, text: &str) -> Result<ToolPath, ProbeError> {
    let source = source.into();
    let err = |line: usize, problem: PathProblem| ProbeError::Path { path: source.clone(), line, problem };
    let mut lines = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim_start_matches('\u{feff}').trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'));
    let Some((hline, header)) = lines.next() else {
        return Err(ProbeError::EmptyPath { path: source });
    };
    let names: Vec<String> = header.split(',').map(|f| f.trim().to_ascii_lowercase()).collect();
    let kind = match names.iter().map(String::as_str).collect::<Vec<_>>().as_slice() {
        ["frame", "vertex", "ux", "uy", "uz"] => PathKind::Grab,
        ["frame", "vertex", "fx", "fy", "fz"] => PathKind::Force,
        _ => return Err(err(hline, PathProblem::Header { found: excerpt(header) })),
    };
    let columns: [&'static str; 3] = match kind {
        PathKind::Grab => ["ux", "uy", "uz"],
        PathKind::Force => ["fx", "fy", "fz"],
    };
    let mut rows: Vec<PathRow> = Vec::new();
    for (line, text) in lines {
        let fields: Vec<&str> = text.split(',').map(str::trim).collect();
        // `12` alone declares an empty frame as `12,,,,` does.
        let fields: Vec<&str> = if fields.len() == 1 { vec![fields[0], "", "", "", ""] } else { fields };
        if fields.len() != 5 {
            return Err(err(line, PathProblem::FieldCount { found: fields.len() }));
        }
        let frame: usize = fields[0]
            .parse()
            .map_err(|_| err(line, PathProblem::BadFrame { value: fields[0].to_string() }))?;
        if frame > MAX_FRAME {
            return Err(err(line, PathProblem::FrameTooLarge { frame }));
        }
        if let Some(prev) = rows.last()
            && frame < prev.frame
        {
            return Err(err(line, PathProblem::DecreasingFrame { frame, previous: prev.frame }));
        }
        let vertex = if fields[1].is_empty() {
            if fields[2..].iter().any(|f| !f.is_empty()) {
                return Err(err(line, PathProblem::ValuesWithoutVertex));
            }
            None
        } else {
            Some(
                fields[1]
                    .parse::<usize>()
                    .map_err(|_| err(line, PathProblem::BadVertex { value: fields[1].to_string() }))?,
            )
        };
        let mut value = [0.0; 3];
        if vertex.is_some() {
            for c in 0..3 {
                let f = fields[2 + c];
                let v: f64 = f.parse().map_err(|_| {
                    err(line, PathProblem::NotANumber { column: columns[c], value: f.to_string() })
                })?;
                if !v.is_finite() {
                    return Err(err(line, PathProblem::NonFinite { column: columns[c], value: v }));
                }
                value[c] = v;
            }
        }
        rows.push(PathRow { line, frame, vertex, value });
    }
    if rows.is_empty() {
        return Err(ProbeError::EmptyPath { path: source });
    }
    Ok(ToolPath { source, kind, rows })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn path_rows_group_and_empty_frames() {
        let p = parse_tool_path("p.csv", "frame,vertex,ux,uy,uz\n0,1,0,0,0.1\n0,2,0,0,0\n3,,,,\n").unwrap();
        assert_eq!(p.kind, PathKind::Grab);
        assert_eq!(p.frames(), 4);
        assert_eq!(p.rows[2].vertex, None);
        let e = parse_tool_path("p.csv", "frame,vertex,ux,uy,uz\n2,1,0,0,0\n1,1,0,0,0\n").unwrap_err();
        assert_eq!(e.to_string(), "p.csv:3: frame 1 comes after frame 2: frame numbers must not decrease");
        let e = parse_tool_path("p.csv", "frame,vertex,ux,uy,uz\n0,1,0,NaN,0\n").unwrap_err();
        assert_eq!(e.to_string(), "p.csv:2: uy: NaN is not finite");
        let e = parse_tool_path("p.csv", "frame,vertex,ux,uy,uz\n").unwrap_err();
        assert!(matches!(e, ProbeError::EmptyPath { .. }));
    }
}
