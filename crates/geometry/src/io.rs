//! Mesh files: OBJ, STL (binary and ASCII), PLY (ASCII and binary) and OFF in; OBJ, PLY and
//! OFF out. The PLY and OFF readers live in `ply.rs` and `off.rs` and share this module's
//! bounded reading, its result ([`MeshFile`]) and its errors.
//!
//! The OBJ reader is a small strict parser rather than `tobj` because two things a solver
//! needs are not available through `tobj`: the line number of every problem, and the map
//! from the file's vertex order to the compacted mesh (unreferenced vertices are dropped, but
//! outputs are written back in the input's order, and scenes name vertices by their index in
//! the file). `tobj` is used in the tests as an independent reader of the same files.

use std::collections::HashMap;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use crate::error::{FileKind, GeometryError, MeshError, ReadError, Result};
use crate::mesh::{TriMesh, Validation, suggested_scale};
use crate::raw::{ParseResult, RawMesh, UTF8_BOM, push_fan};
use crate::vec3::Vec3;

pub use crate::limits::{DEFAULT_MAX_FILE_BYTES, MAX_FILE_BYTES_ENV};

/// The process-wide limit set by [`set_max_file_bytes`] (0: not set).
static MAX_FILE_BYTES_SET: AtomicU64 = AtomicU64::new(0);

/// Sets the process-wide file size limit (what `fibfluid --max-file-bytes` does); it takes
/// precedence over [`MAX_FILE_BYTES_ENV`]. A limit of 0 is taken as 1 byte.
pub fn set_max_file_bytes(limit: u64) {
    MAX_FILE_BYTES_SET.store(limit.max(1), Ordering::Relaxed);
}

/// The file size limit in force: [`set_max_file_bytes`], else [`MAX_FILE_BYTES_ENV`], else
/// [`DEFAULT_MAX_FILE_BYTES`]. An environment value that is not a byte count is an error
/// (not silently the default).
pub fn max_file_bytes() -> std::result::Result<u64, ReadError> {
    match MAX_FILE_BYTES_SET.load(Ordering::Relaxed) {
        0 => match std::env::var_os(MAX_FILE_BYTES_ENV) {
            None => Ok(DEFAULT_MAX_FILE_BYTES),
            Some(v) => {
                let v = v.to_string_lossy().into_owned();
                parse_byte_count(&v).ok_or(ReadError::BadLimit { value: v })
            }
        },
        n => Ok(n),
    }
}

/// Parses a byte count: digits with an optional binary suffix `K`, `M`, `G` or `T` (also
/// `KiB`, `MB`, ...: every suffix means a power of 1024). None when malformed, zero or
/// larger than `u64`.
pub fn parse_byte_count(s: &str) -> Option<u64> {
    let s = s.trim();
    let digits = s.find(|c: char| !c.is_ascii_digit()).unwrap_or(s.len());
    let (num, suffix) = s.split_at(digits);
    let n: u64 = num.parse().ok()?;
    let shift = match suffix.trim().to_ascii_lowercase().as_str() {
        "" | "b" => 0,
        "k" | "kb" | "kib" => 10,
        "m" | "mb" | "mib" => 20,
        "g" | "gb" | "gib" => 30,
        "t" | "tb" | "tib" => 40,
        _ => return None,
    };
    let bytes = n.checked_mul(1u64 << shift)?;
    (bytes > 0).then_some(bytes)
}

/// How a mesh file is read.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ReadOptions {
    /// Largest file accepted, in bytes; `None` = [`max_file_bytes`].
    pub max_bytes: Option<u64>,
    /// Factor applied to every coordinate before validation (a scene's `[mesh].scale`), so a
    /// mesh in tiny or huge units is checked in the units it will be used in. `None` = 1.
    pub scale: Option<f64>,
}

/// What a path is, when it is not a regular file (following symbolic links).
fn non_regular_kind(meta: &std::fs::Metadata) -> Option<FileKind> {
    let t = meta.file_type();
    if t.is_file() {
        return None;
    }
    if t.is_dir() {
        return Some(FileKind::Directory);
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_fifo() {
            return Some(FileKind::Fifo);
        }
        if t.is_char_device() {
            return Some(FileKind::CharDevice);
        }
        if t.is_block_device() {
            return Some(FileKind::BlockDevice);
        }
        if t.is_socket() {
            return Some(FileKind::Socket);
        }
    }
    Some(FileKind::Other)
}

/// Reads a whole input file, refusing what could hang or exhaust memory:
///
/// - anything but a regular file (a FIFO, `/dev/zero`, a directory, a socket; symbolic links
///   are followed) is refused from its metadata, before it is opened;
/// - a file larger than `max_bytes` (`None`: [`max_file_bytes`]) is refused before any
///   memory is reserved for it, and the read itself stops one byte past the limit, so a file
///   that grows while it is read (or reports a size of 0, as `/proc` files do) cannot exceed
///   it either;
/// - the buffer is reserved fallibly ([`ReadError::OutOfMemory`], not an abort).
pub fn read_file_limited(
    path: impl AsRef<Path>,
    max_bytes: Option<u64>,
) -> std::result::Result<Vec<u8>, ReadError> {
    use std::io::Read;
    let path = path.as_ref();
    let limit = match max_bytes {
        Some(n) => n,
        None => max_file_bytes()?,
    };
    let meta = std::fs::metadata(path)?;
    if let Some(kind) = non_regular_kind(&meta) {
        return Err(ReadError::NotARegularFile { kind });
    }
    if meta.len() > limit {
        return Err(ReadError::TooLarge { size: meta.len(), limit });
    }
    let file = std::fs::File::open(path)?;
    // The path may have been replaced between the check and the open.
    let meta = file.metadata()?;
    if let Some(kind) = non_regular_kind(&meta) {
        return Err(ReadError::NotARegularFile { kind });
    }
    let mut bytes = Vec::new();
    let expect = meta.len().min(limit);
    bytes.try_reserve_exact(expect as usize).map_err(|_| ReadError::OutOfMemory { bytes: expect })?;
    file.take(limit.saturating_add(1)).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > limit {
        return Err(ReadError::GrewPastLimit { limit });
    }
    Ok(bytes)
}

/// A mesh read from a file, with the map back to the file's vertex order.
#[derive(Clone, Debug)]
pub struct MeshFile {
    /// The file.
    pub path: PathBuf,
    /// The validated, compacted, outward mesh.
    pub mesh: TriMesh,
    /// Every vertex position of the file, in file order (referenced or not).
    pub file_positions: Vec<Vec3>,
    /// For each mesh vertex, its 0-based index in the file.
    pub to_file: Vec<u32>,
    /// What validation found (flip, genus, warnings).
    pub validation: Validation,
    /// Notes about the file (unreferenced vertices dropped, polygons triangulated, ...).
    pub notes: Vec<String>,
}

impl MeshFile {
    /// Wraps a mesh built in code (file order = mesh order, no notes). Validates it.
    pub fn from_mesh(path: impl Into<PathBuf>, mut mesh: TriMesh) -> std::result::Result<Self, MeshError> {
        let validation = mesh.validate()?;
        let n = mesh.n_vertices() as u32;
        Ok(Self {
            path: path.into(),
            file_positions: mesh.positions().to_vec(),
            to_file: (0..n).collect(),
            notes: validation.warnings.clone(),
            validation,
            mesh,
        })
    }

    /// The mesh index of the file's vertex `i`, or None if the vertex is unreferenced or
    /// out of range.
    pub fn from_file_index(&self, i: usize) -> Option<usize> {
        self.to_file.iter().position(|&f| f as usize == i)
    }

    /// The inverse of `to_file`: for each file vertex, its mesh index (`None` when no face
    /// uses it). The one file-to-mesh map; build it once where many lookups follow.
    pub fn file_to_mesh(&self) -> Vec<Option<usize>> {
        let mut map = vec![None; self.file_vertex_count()];
        for (m, &f) in self.to_file.iter().enumerate() {
            map[f as usize] = Some(m);
        }
        map
    }

    /// Number of vertices in the file.
    pub fn file_vertex_count(&self) -> usize {
        self.file_positions.len()
    }

    /// Positions in file order with the mesh vertices replaced by `positions`.
    pub fn positions_in_file_order(&self, positions: &[Vec3]) -> Vec<Vec3> {
        let mut out = self.file_positions.clone();
        for (m, &f) in self.to_file.iter().enumerate() {
            out[f as usize] = positions[m];
        }
        out
    }

    /// Triangles in file vertex indices.
    pub fn triangles_in_file_order(&self) -> Vec<[u32; 3]> {
        self.mesh.triangles().iter().map(|t| t.map(|v| self.to_file[v as usize])).collect()
    }
}

/// Reads a mesh by extension (`.obj`, `.stl`, `.ply`, `.off`; any case), validates it, and flips it outward if needed.
/// The file size limit is [`max_file_bytes`]; see [`load_mesh_with`] for the options.
pub fn load_mesh(path: impl AsRef<Path>) -> Result<MeshFile> {
    load_mesh_with(path, &ReadOptions::default())
}

/// [`load_mesh`] with explicit options: a size limit for this file and a scale applied
/// before validation. The file is read with [`read_file_limited`] (regular files only,
/// bounded).
pub fn load_mesh_with(path: impl AsRef<Path>, opts: &ReadOptions) -> Result<MeshFile> {
    let path = path.as_ref();
    let io = |source| GeometryError::Io { path: path.to_path_buf(), source };
    let meta = std::fs::metadata(path).map_err(io)?;
    if meta.is_dir() {
        return Err(GeometryError::Parse {
            path: path.into(),
            line: 0,
            message: "is a directory, not a mesh file".into(),
        });
    }
    // What it is comes before what it is called: `/dev/zero` is a device, not a bad name.
    if let Some(kind) = non_regular_kind(&meta) {
        return Err(GeometryError::Read { path: path.into(), source: ReadError::NotARegularFile { kind } });
    }
    let ext = path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase());
    let parse: fn(&[u8]) -> ParseResult<RawMesh> = match ext.as_deref() {
        Some("obj") => parse_obj,
        Some("stl") => parse_stl,
        Some("ply") => crate::ply::parse_ply,
        Some("off") => crate::off::parse_off,
        _ => return Err(GeometryError::UnsupportedFormat { path: path.into() }),
    };
    let bytes = read_file_limited(path, opts.max_bytes).map_err(|e| match e {
        ReadError::Io(source) => GeometryError::Io { path: path.into(), source },
        source => GeometryError::Read { path: path.into(), source },
    })?;
    let mut raw =
        parse(&bytes).map_err(|(line, message)| GeometryError::Parse { path: path.into(), line, message })?;
    drop(bytes);
    if let Some(s) = opts.scale {
        raw.positions.iter_mut().for_each(|p| *p = p.map(|c| c * s));
        if let Some(v) = raw.positions.iter().position(|p| p.iter().any(|c| !c.is_finite())) {
            return Err(GeometryError::Parse {
                path: path.into(),
                line: 0,
                message: format!("the scale {s:e} makes vertex {v} overflow f64; use a smaller scale"),
            });
        }
    }
    finish(path, raw).map_err(|e| match (e, opts.scale) {
        // Name the file's coordinates and the `[mesh].scale` to use instead of this one.
        (GeometryError::Mesh { path, source }, Some(s)) => {
            GeometryError::Mesh { path, source: in_file_units(source, s) }
        }
        (e, _) => e,
    })
}

/// Rewrites a coordinate-scale error of a mesh scaled by `s` in the file's units: the
/// magnitude found in the file, and the total scale to ask for.
fn in_file_units(e: MeshError, s: f64) -> MeshError {
    match e {
        MeshError::CoordinateOverflow { site, vertex, magnitude, .. } => MeshError::CoordinateOverflow {
            site,
            vertex,
            magnitude: magnitude / s,
            suggested_scale: suggested_scale(magnitude / s),
        },
        MeshError::CoordinateUnderflow { site, vertex, magnitude, value, .. } => {
            MeshError::CoordinateUnderflow {
                site,
                vertex,
                magnitude: magnitude / s,
                value,
                suggested_scale: suggested_scale(magnitude / s),
            }
        }
        other => other,
    }
}

/// Parses OBJ text already in memory (`path` only names it in errors).
pub fn read_obj_bytes(path: impl AsRef<Path>, bytes: &[u8]) -> Result<MeshFile> {
    read_bytes_with(path.as_ref(), bytes, parse_obj)
}

/// Parses STL bytes already in memory (`path` only names it in errors).
pub fn read_stl_bytes(path: impl AsRef<Path>, bytes: &[u8]) -> Result<MeshFile> {
    read_bytes_with(path.as_ref(), bytes, parse_stl)
}

/// Parses PLY bytes (ASCII, binary little- or big-endian) already in memory (`path` only
/// names it in errors).
pub fn read_ply_bytes(path: impl AsRef<Path>, bytes: &[u8]) -> Result<MeshFile> {
    read_bytes_with(path.as_ref(), bytes, crate::ply::parse_ply)
}

/// Parses OFF text already in memory (`path` only names it in errors).
pub fn read_off_bytes(path: impl AsRef<Path>, bytes: &[u8]) -> Result<MeshFile> {
    read_bytes_with(path.as_ref(), bytes, crate::off::parse_off)
}

fn read_bytes_with(path: &Path, bytes: &[u8], parse: fn(&[u8]) -> ParseResult<RawMesh>) -> Result<MeshFile> {
    let raw =
        parse(bytes).map_err(|(line, message)| GeometryError::Parse { path: path.into(), line, message })?;
    finish(path, raw)
}

fn finish(path: &Path, raw: RawMesh) -> Result<MeshFile> {
    let mesh_err = |source| GeometryError::Mesh { path: path.to_path_buf(), source };
    let RawMesh { positions, triangles, mut notes } = raw;
    if triangles.is_empty() || positions.is_empty() {
        return Err(mesh_err(MeshError::Empty { vertices: positions.len(), faces: triangles.len() }));
    }
    // Compact: keep referenced vertices in file order.
    let mut used = vec![false; positions.len()];
    for t in &triangles {
        for &v in t {
            used[v as usize] = true;
        }
    }
    let mut new_index = vec![u32::MAX; positions.len()];
    let mut to_file = Vec::new();
    let mut compact = Vec::new();
    for (i, p) in positions.iter().enumerate() {
        if used[i] {
            new_index[i] = to_file.len() as u32;
            to_file.push(i as u32);
            compact.push(*p);
        }
    }
    let dropped = positions.len() - compact.len();
    if dropped > 0 {
        notes.push(format!("{dropped} unreferenced vertices dropped (outputs keep the file's vertex order)"));
    }
    let tris = triangles.iter().map(|t| t.map(|v| new_index[v as usize])).collect();
    let mut mesh = TriMesh::new(compact, tris)
        .map_err(|e| match e {
            MeshError::NonFiniteVertex { vertex } => {
                MeshError::NonFiniteVertex { vertex: to_file[vertex] as usize }
            }
            other => other,
        })
        .map_err(mesh_err)?;
    let validation = mesh.validate().map_err(|e| mesh_err(to_file_indices(e, &to_file)))?;
    notes.extend(validation.warnings.iter().cloned());
    Ok(MeshFile { path: path.to_path_buf(), mesh, file_positions: positions, to_file, validation, notes })
}

/// Rewrites vertex indices in an error from mesh order to file order.
fn to_file_indices(e: MeshError, to_file: &[u32]) -> MeshError {
    let f = |v: u32| to_file.get(v as usize).copied().unwrap_or(v);
    match e {
        MeshError::NonManifoldEdge { a, b, faces } => MeshError::NonManifoldEdge { a: f(a), b: f(b), faces },
        MeshError::NonManifoldVertex { vertex, fans } => {
            MeshError::NonManifoldVertex { vertex: f(vertex), fans }
        }
        MeshError::OpenBoundary { count, a, b } => MeshError::OpenBoundary { count, a: f(a), b: f(b) },
        MeshError::InconsistentOrientation { a, b } => {
            MeshError::InconsistentOrientation { a: f(a), b: f(b) }
        }
        MeshError::CoordinateOverflow { site, vertex, magnitude, suggested_scale } => {
            MeshError::CoordinateOverflow { site, vertex: f(vertex), magnitude, suggested_scale }
        }
        MeshError::CoordinateUnderflow { site, vertex, magnitude, value, suggested_scale } => {
            MeshError::CoordinateUnderflow { site, vertex: f(vertex), magnitude, value, suggested_scale }
        }
        other => other,
    }
}

fn parse_obj(bytes: &[u8]) -> ParseResult<RawMesh> {
    // A byte-order mark is not part of the first line (which is still line 1).
    let bytes = bytes.strip_prefix(UTF8_BOM).unwrap_or(bytes);
    let mut positions: Vec<Vec3> = Vec::new();
    let mut faces: Vec<(usize, Vec<i64>)> = Vec::new();
    let mut polygons = 0usize;
    let mut skipped_elements = 0usize;
    for (ln, line) in bytes.split(|&b| b == b'\n').enumerate() {
        let lineno = ln + 1;
        let line = std::str::from_utf8(line)
            .map_err(|_| (lineno, "not a text OBJ file (invalid UTF-8)".to_string()))?;
        let line = line.split('#').next().unwrap_or("").trim();
        let mut it = line.split_whitespace();
        match it.next() {
            Some("v") => {
                let mut p = [0.0; 3];
                for (c, slot) in p.iter_mut().enumerate() {
                    let tok = it.next().ok_or((lineno, format!("vertex has {c} coordinates, 3 expected")))?;
                    *slot = tok.parse::<f64>().map_err(|_| (lineno, format!("bad coordinate `{tok}`")))?;
                }
                if p.iter().any(|c| !c.is_finite()) {
                    return Err((lineno, format!("vertex {} has a non-finite coordinate", positions.len())));
                }
                positions.push(p);
            }
            Some("f") => {
                let mut idx = Vec::new();
                for tok in it {
                    let first = tok.split('/').next().unwrap_or("");
                    let v: i64 = first.parse().map_err(|_| (lineno, format!("bad face index `{tok}`")))?;
                    let resolved = if v > 0 {
                        v - 1
                    } else if v < 0 {
                        positions.len() as i64 + v
                    } else {
                        return Err((lineno, "face index 0 (OBJ indices start at 1)".into()));
                    };
                    if resolved < 0 {
                        return Err((
                            lineno,
                            format!("relative face index {v} points before the first vertex"),
                        ));
                    }
                    idx.push(resolved);
                }
                if idx.len() < 3 {
                    return Err((lineno, format!("face with {} vertices (at least 3 needed)", idx.len())));
                }
                if idx.len() > 3 {
                    polygons += 1;
                }
                faces.push((lineno, idx));
            }
            Some("l") | Some("p") => skipped_elements += 1,
            _ => {}
        }
    }
    let mut triangles = Vec::with_capacity(faces.len());
    let mut polygon = Vec::new();
    for (lineno, idx) in faces {
        if let Some(&bad) = idx.iter().find(|&&v| v as usize >= positions.len()) {
            return Err((
                lineno,
                format!("face refers to vertex {} but the file has {} vertices", bad + 1, positions.len()),
            ));
        }
        polygon.clear();
        polygon.extend(idx.iter().map(|&v| v as u32));
        push_fan(&mut triangles, &polygon);
    }
    if positions.is_empty() {
        return Err((0, "no vertices (`v` lines) found".into()));
    }
    if triangles.is_empty() {
        return Err((0, "no faces (`f` lines) found".into()));
    }
    let mut notes = Vec::new();
    if polygons > 0 {
        notes.push(format!("{polygons} polygons with more than 3 vertices triangulated as fans"));
    }
    if skipped_elements > 0 {
        notes.push(format!("{skipped_elements} line/point elements ignored"));
    }
    Ok(RawMesh { positions, triangles, notes })
}

fn parse_stl(bytes: &[u8]) -> ParseResult<RawMesh> {
    let binary_size_ok = bytes.len() >= 84 && {
        let n = u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]) as u64;
        84 + 50 * n == bytes.len() as u64
    };
    // A byte-order mark may precede an ASCII STL's `solid` (a binary one keeps its header).
    let text_bytes = bytes.strip_prefix(UTF8_BOM).unwrap_or(bytes);
    let looks_ascii = text_bytes.starts_with(b"solid")
        && std::str::from_utf8(&text_bytes[..text_bytes.len().min(1024)])
            .map(|s| s.contains("facet") || s.contains("endsolid"))
            .unwrap_or(false);
    let mut welder = Welder::default();
    let mut triangles = Vec::new();
    if binary_size_ok {
        let n = u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]) as usize;
        for t in 0..n {
            let base = 84 + 50 * t + 12;
            let mut tri = [0u32; 3];
            for (v, slot) in tri.iter_mut().enumerate() {
                let mut p = [0.0; 3];
                for (c, pc) in p.iter_mut().enumerate() {
                    let o = base + 12 * v + 4 * c;
                    *pc = f32::from_le_bytes([bytes[o], bytes[o + 1], bytes[o + 2], bytes[o + 3]]) as f64;
                }
                if p.iter().any(|c| !c.is_finite()) {
                    return Err((0, format!("triangle {t} has a non-finite coordinate")));
                }
                *slot = welder.index(p);
            }
            triangles.push(tri);
        }
    } else if looks_ascii {
        let text =
            std::str::from_utf8(text_bytes).map_err(|_| (0, "ASCII STL is not valid UTF-8".to_string()))?;
        let mut corner = Vec::with_capacity(3);
        let mut last_vertex_line = 0;
        for (ln, line) in text.lines().enumerate() {
            let mut it = line.split_whitespace();
            if it.next() == Some("vertex") {
                last_vertex_line = ln + 1;
                let mut p = [0.0; 3];
                for slot in p.iter_mut() {
                    let tok =
                        it.next().ok_or((ln + 1, "vertex with fewer than 3 coordinates".to_string()))?;
                    *slot = tok.parse().map_err(|_| (ln + 1, format!("bad coordinate `{tok}`")))?;
                }
                if p.iter().any(|c: &f64| !c.is_finite()) {
                    return Err((ln + 1, "non-finite coordinate".into()));
                }
                corner.push(welder.index(p));
                if corner.len() == 3 {
                    triangles.push([corner[0], corner[1], corner[2]]);
                    corner.clear();
                }
            }
        }
        if !corner.is_empty() {
            return Err((last_vertex_line, "the last facet has fewer than 3 vertices".into()));
        }
    } else if bytes.len() >= 84 {
        let n = u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]) as u64;
        return Err((
            0,
            format!(
                "binary STL header claims {n} triangles ({} bytes) but the file has {} bytes",
                84 + 50 * n,
                bytes.len()
            ),
        ));
    } else {
        return Err((0, format!("not an STL file ({} bytes, too short for a binary header)", bytes.len())));
    }
    let notes = vec![format!("STL vertices welded by exact coordinates: {} unique", welder.positions.len())];
    Ok(RawMesh { positions: welder.positions, triangles, notes })
}

#[derive(Default)]
struct Welder {
    map: HashMap<[u64; 3], u32>,
    positions: Vec<Vec3>,
}

impl Welder {
    fn index(&mut self, p: Vec3) -> u32 {
        // +0.0 and -0.0 weld together.
        let key = p.map(|c| if c == 0.0 { 0 } else { c.to_bits() });
        *self.map.entry(key).or_insert_with(|| {
            self.positions.push(p);
            (self.positions.len() - 1) as u32
        })
    }
}

/// Writes an OBJ file (positions with full f64 precision, 1-based triangles).
pub fn write_obj(path: impl AsRef<Path>, positions: &[Vec3], triangles: &[[u32; 3]]) -> Result<()> {
    write_file(path.as_ref(), |out| write_obj_to(out, positions, triangles))
}

/// Writes OBJ text to any writer (every f64 coordinate as the shortest decimal that reads
/// back to it).
pub fn write_obj_to(out: &mut impl Write, positions: &[Vec3], triangles: &[[u32; 3]]) -> std::io::Result<()> {
    for p in positions {
        writeln!(out, "v {:?} {:?} {:?}", p[0], p[1], p[2])?;
    }
    for t in triangles {
        writeln!(out, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1)?;
    }
    Ok(())
}

/// Writes a PLY file of the given encoding (see [`write_ply_to`]).
pub fn write_ply(
    path: impl AsRef<Path>,
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    format: crate::ply::PlyFormat,
) -> Result<()> {
    write_file(path.as_ref(), |out| crate::ply::write_ply_to(out, positions, triangles, format))
}

/// Writes an OFF file (see [`write_off_to`]).
pub fn write_off(path: impl AsRef<Path>, positions: &[Vec3], triangles: &[[u32; 3]]) -> Result<()> {
    write_file(path.as_ref(), |out| crate::off::write_off_to(out, positions, triangles))
}

/// Creates `path` and writes it through a buffer; errors name the file.
fn write_file(
    path: &Path,
    write: impl FnOnce(&mut std::io::BufWriter<std::fs::File>) -> std::io::Result<()>,
) -> Result<()> {
    let io = |source| GeometryError::Io { path: path.to_path_buf(), source };
    let mut out = std::io::BufWriter::new(std::fs::File::create(path).map_err(io)?);
    write(&mut out).map_err(io)?;
    out.flush().map_err(io)
}
