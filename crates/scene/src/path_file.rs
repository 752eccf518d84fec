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
//! Tools with a size:
//!
//! ```text
//! frame,vertex,ux,uy,uz,radius (grasp: the patch within `radius` of the vertex, moved by u)
//! frame,x,y,z,radius           (press: a spherical tip of that radius centred at x, y, z)
//! ```
//!
//! Lengths (displacements, centres, radii) are in the mesh's unit, forces in newtons.
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
    let kind = PathKind::ALL
        .into_iter()
        .find(|k| names.join(",") == k.header())
        .ok_or_else(|| err(hline, PathProblem::Header { found: excerpt(header) }))?;
    let columns: Vec<&'static str> = kind.header().split(',').collect();
    let mut rows: Vec<PathRow> = Vec::new();
    for (line, text) in lines {
        let fields: Vec<&str> = text.split(',').map(str::trim).collect();
        // `12` alone declares an empty frame as `12,,,,` does.
        let mut fields = fields;
        if fields.len() == 1 {
            fields.resize(columns.len(), "");
        }
        if fields.len() != columns.len() {
            return Err(err(line, PathProblem::FieldCount { expected: columns.len(), found: fields.len() }));
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
        if fields[1..].iter().all(|f| f.is_empty()) {
            rows.push(PathRow { line, frame, vertex: None, value: [0.0; 3], radius: None });
            continue;
        }
        let row = parse_row(kind, &columns, &fields, line, frame).map_err(|p| err(line, p))?;
        rows.push(row);
    }
    if rows.is_empty() {
        return Err(ProbeError::EmptyPath { path: source });
    }
    Ok(ToolPath { source, kind, rows })
}

/// A row with values: the vertex (grab, force, grasp), three numbers and the radius
/// (grasp, press).
fn parse_row(
    kind: PathKind,
    columns: &[&'static str],
    fields: &[&str],
    line: usize,
    frame: usize,
) -> Result<PathRow, PathProblem> {
    let number = |i: usize| -> Result<f64, PathProblem> {
        let f = fields[i];
        let v: f64 =
            f.parse().map_err(|_| PathProblem::NotANumber { column: columns[i], value: f.to_string() })?;
        if !v.is_finite() {
            return Err(PathProblem::NonFinite { column: columns[i], value: v });
        }
        Ok(v)
    };
    let has_vertex = kind != PathKind::Press;
    let vertex = if !has_vertex {
        None
    } else if fields[1].is_empty() {
        return Err(PathProblem::ValuesWithoutVertex);
    } else {
        Some(
            fields[1]
                .parse::<usize>()
                .map_err(|_| PathProblem::BadVertex { value: fields[1].to_string() })?,
        )
    };
    let first = if has_vertex { 2 } else { 1 };
    let value = [number(first)?, number(first + 1)?, number(first + 2)?];
    let radius = match kind {
        PathKind::Grasp | PathKind::Press => {
            let r = number(first + 3)?;
            if r <= 0.0 {
                return Err(PathProblem::BadRadius { value: r });
            }
            Some(r)
        }
        PathKind::Grab | PathKind::Force => None,
    };
    Ok(PathRow { line, frame, vertex, value, radius })
}
