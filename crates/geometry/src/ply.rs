//! PLY files: ASCII, binary little-endian and binary big-endian in, the same three out.
//!
//! The reader takes the `vertex` element's `x`, `y`, `z` and the `face` element's
//! `vertex_indices` (or `vertex_index`) list; every other property and element (normals,
//! colours, edges, ...) is skipped by its declared type. Polygons are fan-triangulated as
//! OBJ polygons are. The header's counts are checked against the bytes that follow it
//! before anything is allocated for them, so a header claiming 10^12 vertices is refused at
//! once. Problems in the header and in an ASCII body name the line; problems in a binary body
//! name the element and its byte offset in the file.

use std::io::Write;

use crate::raw::{ParseResult, RawMesh, UTF8_BOM, push_fan};
use crate::vec3::Vec3;

/// The encoding of a PLY file's body.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PlyFormat {
    /// `format ascii 1.0`: one element per line.
    Ascii,
    /// `format binary_little_endian 1.0`.
    BinaryLittleEndian,
    /// `format binary_big_endian 1.0`.
    BinaryBigEndian,
}

impl PlyFormat {
    /// The name the `format` line of the header gives it.
    pub fn header_name(self) -> &'static str {
        match self {
            PlyFormat::Ascii => "ascii",
            PlyFormat::BinaryLittleEndian => "binary_little_endian",
            PlyFormat::BinaryBigEndian => "binary_big_endian",
        }
    }
}

/// A PLY scalar type.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

/// The type names PLY accepts, in both spellings.
const TYPE_NAMES: &str =
    "char uchar short ushort int uint float double, or int8 uint8 int16 uint16 int32 uint32 float32 float64";

impl Scalar {
    fn parse(name: &str) -> Option<Self> {
        Some(match name {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    /// The values an integer type holds (floats: all of i64).
    fn range(self) -> (i64, i64) {
        match self {
            Scalar::I8 => (i8::MIN.into(), i8::MAX.into()),
            Scalar::U8 => (0, u8::MAX.into()),
            Scalar::I16 => (i16::MIN.into(), i16::MAX.into()),
            Scalar::U16 => (0, u16::MAX.into()),
            Scalar::I32 => (i32::MIN.into(), i32::MAX.into()),
            Scalar::U32 => (0, u32::MAX.into()),
            Scalar::F32 | Scalar::F64 => (i64::MIN, i64::MAX),
        }
    }

    fn is_integer(self) -> bool {
        !matches!(self, Scalar::F32 | Scalar::F64)
    }

    /// The value of `b` (exactly `size()` bytes) as f64.
    fn decode_f64(self, b: &[u8], big: bool) -> f64 {
        match self {
            Scalar::F32 => {
                let a = [b[0], b[1], b[2], b[3]];
                (if big { f32::from_be_bytes(a) } else { f32::from_le_bytes(a) }) as f64
            }
            Scalar::F64 => {
                let a = [b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]];
                if big { f64::from_be_bytes(a) } else { f64::from_le_bytes(a) }
            }
            int => int.decode_i64(b, big) as f64,
        }
    }

    /// The value of `b` (exactly `size()` bytes) of an integer type.
    fn decode_i64(self, b: &[u8], big: bool) -> i64 {
        let two = [b[0], *b.get(1).unwrap_or(&0)];
        let four = || [b[0], b[1], b[2], b[3]];
        match self {
            Scalar::I8 => b[0] as i8 as i64,
            Scalar::U8 => b[0] as i64,
            Scalar::I16 => (if big { i16::from_be_bytes(two) } else { i16::from_le_bytes(two) }) as i64,
            Scalar::U16 => (if big { u16::from_be_bytes(two) } else { u16::from_le_bytes(two) }) as i64,
            Scalar::I32 => (if big { i32::from_be_bytes(four()) } else { i32::from_le_bytes(four()) }) as i64,
            Scalar::U32 => (if big { u32::from_be_bytes(four()) } else { u32::from_le_bytes(four()) }) as i64,
            Scalar::F32 | Scalar::F64 => self.decode_f64(b, big) as i64,
        }
    }
}

/// A property's type: one scalar, or a list with its count type and item type.
#[derive(Clone, Copy, Debug)]
enum PropertyType {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

/// What the reader does with a property.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Role {
    Skip,
    /// Coordinate 0, 1 or 2 of a vertex.
    Coord(usize),
    /// A face's vertex list.
    Indices,
}

#[derive(Debug)]
struct Element {
    name: String,
    count: u64,
    /// Its `element` line in the header.
    line: usize,
    properties: Vec<(String, PropertyType)>,
}

impl Element {
    /// Fewest bytes one element can take: binary, its scalars and list counts; ASCII, a
    /// character and a separator for each.
    fn min_bytes(&self, format: PlyFormat) -> u64 {
        self.properties
            .iter()
            .map(|(_, t)| match (format, t) {
                (PlyFormat::Ascii, _) => 2,
                (_, PropertyType::Scalar(s)) | (_, PropertyType::List { count: s, .. }) => s.size() as u64,
            })
            .sum()
    }
}

#[derive(Debug)]
struct Header {
    format: PlyFormat,
    elements: Vec<Element>,
    /// Byte offset of the body in the file.
    body_start: usize,
    /// Number of lines the header takes (the body's first line is `lines + 1`).
    lines: usize,
}

/// Parses the header's `property` line (tokens after `property`).
fn parse_property(tokens: &[&str], ln: usize) -> ParseResult<(String, PropertyType)> {
    let scalar = |name: &str| {
        Scalar::parse(name).ok_or((ln, format!("unknown property type `{name}` (PLY types: {TYPE_NAMES})")))
    };
    match tokens {
        ["list", count, item, name] => {
            let (count, item) = (scalar(count)?, scalar(item)?);
            if !count.is_integer() {
                return Err((
                    ln,
                    format!("list `{name}` has a count of type `{}`; it must be an integer type", tokens[1]),
                ));
            }
            Ok((name.to_string(), PropertyType::List { count, item }))
        }
        [ty, name] if *ty != "list" => Ok((name.to_string(), PropertyType::Scalar(scalar(ty)?))),
        _ => Err((
            ln,
            "a property line is `property TYPE NAME` or `property list COUNT_TYPE ITEM_TYPE NAME`".into(),
        )),
    }
}

/// Reads the header up to `end_header`.
fn parse_header(bytes: &[u8]) -> ParseResult<Header> {
    let mut pos = if bytes.starts_with(UTF8_BOM) { UTF8_BOM.len() } else { 0 };
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    let mut ln = 0;
    loop {
        ln += 1;
        let Some(len) = bytes[pos..].iter().position(|&b| b == b'\n') else {
            let message = if ln == 1 {
                "not a PLY file (no `ply` line)"
            } else {
                "the header has no `end_header` line"
            };
            return Err((ln, message.into()));
        };
        let raw = &bytes[pos..pos + len];
        pos += len + 1;
        let line = std::str::from_utf8(raw).map_err(|_| {
            let what = if ln == 1 {
                "not a PLY file (the first line is not text)"
            } else {
                "the header is not text"
            };
            (ln, what.to_string())
        })?;
        let tokens: Vec<&str> = line.split_ascii_whitespace().collect();
        if ln == 1 {
            if tokens != ["ply"] {
                return Err((1, "not a PLY file (the first line is not `ply`)".into()));
            }
            continue;
        }
        match tokens.as_slice() {
            [] | ["comment", ..] | ["obj_info", ..] => {}
            ["format", name, _version] => {
                format = Some(match *name {
                    "ascii" => PlyFormat::Ascii,
                    "binary_little_endian" => PlyFormat::BinaryLittleEndian,
                    "binary_big_endian" => PlyFormat::BinaryBigEndian,
                    other => {
                        return Err((
                            ln,
                            format!(
                                "unknown PLY format `{other}` (ascii, binary_little_endian or binary_big_endian)"
                            ),
                        ));
                    }
                })
            }
            ["element", name, count] => {
                let count = count
                    .parse::<u64>()
                    .map_err(|_| (ln, format!("element `{name}` has a bad count `{count}`")))?;
                elements.push(Element { name: name.to_string(), count, line: ln, properties: Vec::new() });
            }
            ["property", rest @ ..] => {
                let property = parse_property(rest, ln)?;
                let element = elements.last_mut().ok_or((ln, "a property before any element".to_string()))?;
                element.properties.push(property);
            }
            ["end_header"] => break,
            ["format" | "element", ..] => {
                let form = if tokens[0] == "format" { "format ascii 1.0" } else { "element NAME COUNT" };
                let article = if tokens[0] == "format" { "a" } else { "an" };
                return Err((ln, format!("{article} {} line is `{form}`", tokens[0])));
            }
            [keyword, ..] => {
                return Err((
                    ln,
                    format!(
                        "unknown header line `{keyword}` (a PLY header has format, element, property, comment and end_header lines)"
                    ),
                ));
            }
        }
    }
    let format = format.ok_or((0, "the header has no `format` line".to_string()))?;
    Ok(Header { format, elements, body_start: pos, lines: ln })
}

/// The roles of every element's properties, after checking that the header describes a
/// surface (one vertex element with x, y, z; one face element with a vertex list of
/// integers) whose counts fit in the bytes that follow the header.
fn plan(header: &Header, body_len: usize) -> ParseResult<Vec<Vec<Role>>> {
    let mut roles = Vec::new();
    let (mut vertex, mut face) = (None, None);
    let mut need: u128 = 0;
    for element in &header.elements {
        let ln = element.line;
        if element.count > 0 && element.properties.is_empty() {
            return Err((ln, format!("element `{}` has no properties", element.name)));
        }
        need += element.count as u128 * element.min_bytes(header.format) as u128;
        if need > body_len as u128 {
            return Err((
                ln,
                format!(
                    "the header claims {} {} elements (at least {need} bytes with those before them) but only {body_len} bytes follow the header",
                    element.count, element.name
                ),
            ));
        }
        let mut r = vec![Role::Skip; element.properties.len()];
        let slot = match element.name.as_str() {
            "vertex" => &mut vertex,
            "face" => &mut face,
            _ => {
                roles.push(r);
                continue;
            }
        };
        if slot.replace(element).is_some() {
            return Err((ln, format!("a second `{}` element", element.name)));
        }
        let find = |names: &[&str]| element.properties.iter().position(|(n, _)| names.contains(&n.as_str()));
        if element.name == "vertex" {
            for (c, axis) in ["x", "y", "z"].into_iter().enumerate() {
                let i = find(&[axis]).ok_or((ln, format!("the vertex element has no `{axis}` property")))?;
                if let PropertyType::List { .. } = element.properties[i].1 {
                    return Err((ln, format!("the vertex property `{axis}` is a list, not a number")));
                }
                r[i] = Role::Coord(c);
            }
        } else {
            let i = find(&["vertex_indices", "vertex_index"]).ok_or((
                ln,
                "the face element has no `vertex_indices` (or `vertex_index`) list".to_string(),
            ))?;
            match element.properties[i].1 {
                PropertyType::List { item, .. } if item.is_integer() => r[i] = Role::Indices,
                _ => {
                    return Err((
                        ln,
                        format!("the face property `{}` must be a list of integers", element.properties[i].0),
                    ));
                }
            }
        }
        roles.push(r);
    }
    let vertex = vertex.ok_or((0, "the header has no `element vertex`".to_string()))?;
    if face.is_none() {
        return Err((0, "the header has no `element face` (a point cloud, not a surface)".into()));
    }
    if vertex.count > u32::MAX as u64 {
        return Err((
            vertex.line,
            format!("{} vertices: more than this reader indexes (2^32 - 1)", vertex.count),
        ));
    }
    Ok(roles)
}

/// Where the body's values come from: ASCII tokens or binary bytes. Errors name the current
/// element (set by `begin`).
trait Body {
    /// Starts element `k` of `name`.
    fn begin(&mut self, name: &str, k: u64) -> ParseResult<()>;
    /// One value as f64.
    fn number(&mut self, ty: Scalar) -> ParseResult<f64>;
    /// One value of an integer type.
    fn integer(&mut self, ty: Scalar) -> ParseResult<i64>;
    /// Skips `n` values of type `ty`.
    fn skip(&mut self, ty: Scalar, n: u64) -> ParseResult<()>;
    /// Ends the element (an ASCII line must hold nothing more).
    fn end(&mut self) -> ParseResult<()>;
    /// An error about the current element.
    fn fail(&self, message: String) -> (usize, String);
    /// A note about what follows the last element, if anything does.
    fn trailing(&mut self) -> Option<String>;
}

/// An ASCII body: one element per line (blank lines are skipped).
struct AsciiBody<'a> {
    lines: std::iter::Enumerate<std::str::Split<'a, char>>,
    first_line: usize,
    tokens: std::str::SplitAsciiWhitespace<'a>,
    line: usize,
    element: (String, u64),
}

impl<'a> AsciiBody<'a> {
    fn token(&mut self) -> ParseResult<&'a str> {
        self.tokens.next().ok_or_else(|| self.fail("fewer values than the header's properties".into()))
    }
}

impl Body for AsciiBody<'_> {
    fn begin(&mut self, name: &str, k: u64) -> ParseResult<()> {
        self.element.0.clear();
        self.element.0.push_str(name);
        self.element.1 = k;
        for (i, line) in self.lines.by_ref() {
            if !line.trim().is_empty() {
                self.line = self.first_line + i;
                self.tokens = line.split_ascii_whitespace();
                return Ok(());
            }
        }
        Err((0, format!("the file ends before {name} {k} (the header announces more)")))
    }

    fn number(&mut self, ty: Scalar) -> ParseResult<f64> {
        if ty.is_integer() {
            return self.integer(ty).map(|v| v as f64);
        }
        let tok = self.token()?;
        tok.parse::<f64>().map_err(|_| self.fail(format!("bad number `{tok}`")))
    }

    fn integer(&mut self, ty: Scalar) -> ParseResult<i64> {
        let tok = self.token()?;
        let v = tok.parse::<i64>().map_err(|_| self.fail(format!("bad integer `{tok}`")))?;
        let (lo, hi) = ty.range();
        if !(lo..=hi).contains(&v) {
            return Err(self.fail(format!("{v} does not fit the property's type ({lo} to {hi})")));
        }
        Ok(v)
    }

    fn skip(&mut self, _ty: Scalar, n: u64) -> ParseResult<()> {
        for _ in 0..n {
            self.token()?;
        }
        Ok(())
    }

    fn end(&mut self) -> ParseResult<()> {
        let extra = self.tokens.by_ref().count();
        if extra > 0 {
            return Err(self.fail(format!("{extra} values more than the header's properties")));
        }
        Ok(())
    }

    fn fail(&self, message: String) -> (usize, String) {
        (self.line, format!("{} {}: {message}", self.element.0, self.element.1))
    }

    fn trailing(&mut self) -> Option<String> {
        let n = self.lines.by_ref().filter(|(_, l)| !l.trim().is_empty()).count();
        (n > 0).then(|| format!("{n} lines after the last element ignored"))
    }
}

/// A binary body, little- or big-endian.
struct BinaryBody<'a> {
    bytes: &'a [u8],
    /// Offset of `bytes` in the file.
    base: usize,
    pos: usize,
    big: bool,
    element: (String, u64),
    /// File offset where the current element starts.
    start: usize,
}

impl<'a> BinaryBody<'a> {
    fn take(&mut self, n: u64) -> ParseResult<&'a [u8]> {
        let left = (self.bytes.len() - self.pos) as u64;
        if n > left {
            return Err(self.fail(format!(
                "the file ends inside it ({n} bytes needed at byte {}, {left} left)",
                self.base + self.pos
            )));
        }
        let s = &self.bytes[self.pos..self.pos + n as usize];
        self.pos += n as usize;
        Ok(s)
    }
}

impl Body for BinaryBody<'_> {
    fn begin(&mut self, name: &str, k: u64) -> ParseResult<()> {
        self.element.0.clear();
        self.element.0.push_str(name);
        self.element.1 = k;
        self.start = self.base + self.pos;
        Ok(())
    }

    fn number(&mut self, ty: Scalar) -> ParseResult<f64> {
        let big = self.big;
        self.take(ty.size() as u64).map(|b| ty.decode_f64(b, big))
    }

    fn integer(&mut self, ty: Scalar) -> ParseResult<i64> {
        let big = self.big;
        self.take(ty.size() as u64).map(|b| ty.decode_i64(b, big))
    }

    fn skip(&mut self, ty: Scalar, n: u64) -> ParseResult<()> {
        self.take(n.saturating_mul(ty.size() as u64)).map(|_| ())
    }

    fn end(&mut self) -> ParseResult<()> {
        Ok(())
    }

    fn fail(&self, message: String) -> (usize, String) {
        (0, format!("binary {} {} at byte {}: {message}", self.element.0, self.element.1, self.start))
    }

    fn trailing(&mut self) -> Option<String> {
        let n = self.bytes.len() - self.pos;
        (n > 0).then(|| format!("{n} bytes after the last element ignored"))
    }
}

/// A vector with room for `n` items, reserved fallibly.
fn reserved<T>(n: u64, what: &str) -> ParseResult<Vec<T>> {
    let mut v = Vec::new();
    v.try_reserve_exact(n as usize).map_err(|_| (0, format!("cannot allocate memory for {n} {what}")))?;
    Ok(v)
}

/// Reads every element of the body.
fn read_body(header: &Header, roles: &[Vec<Role>], body: &mut impl Body) -> ParseResult<RawMesh> {
    let count = |name: &str| header.elements.iter().find(|e| e.name == name).map_or(0, |e| e.count);
    let (nv, nf) = (count("vertex"), count("face"));
    let mut positions: Vec<Vec3> = reserved(nv, "vertices")?;
    let mut triangles: Vec<[u32; 3]> = reserved(nf, "faces")?;
    let (mut polygons, mut skipped) = (0usize, Vec::new());
    let mut idx: Vec<u32> = Vec::new();
    for (element, roles) in header.elements.iter().zip(roles) {
        if element.name != "vertex" && element.name != "face" && element.count > 0 {
            skipped.push(format!("{} ({})", element.name, element.count));
        }
        for k in 0..element.count {
            body.begin(&element.name, k)?;
            let mut p = [0.0; 3];
            for ((_, ty), role) in element.properties.iter().zip(roles) {
                match (*ty, *role) {
                    (PropertyType::Scalar(s), Role::Coord(c)) => p[c] = body.number(s)?,
                    (PropertyType::Scalar(s), _) => body.skip(s, 1)?,
                    (PropertyType::List { count, item }, Role::Indices) => {
                        read_polygon(body, count, item, nv, &mut idx)?;
                        polygons += usize::from(idx.len() > 3);
                        push_fan(&mut triangles, &idx);
                    }
                    (PropertyType::List { count, item }, _) => {
                        let n = body.integer(count)?;
                        let n = u64::try_from(n).map_err(|_| body.fail(format!("a list of {n} items")))?;
                        body.skip(item, n)?;
                    }
                }
            }
            body.end()?;
            if element.name == "vertex" {
                if p.iter().any(|c| !c.is_finite()) {
                    return Err(body.fail("a non-finite coordinate".into()));
                }
                positions.push(p);
            }
        }
    }
    if positions.is_empty() {
        return Err((0, "no vertices (the vertex element is empty)".into()));
    }
    if triangles.is_empty() {
        return Err((0, "no faces (the face element is empty)".into()));
    }
    let mut notes = Vec::new();
    if polygons > 0 {
        notes.push(format!("{polygons} polygons with more than 3 vertices triangulated as fans"));
    }
    if !skipped.is_empty() {
        notes.push(format!("PLY elements ignored: {}", skipped.join(", ")));
    }
    notes.extend(body.trailing());
    Ok(RawMesh { positions, triangles, notes })
}

/// Reads one face's vertex list into `idx`, checking its length and every index.
fn read_polygon(
    body: &mut impl Body,
    count: Scalar,
    item: Scalar,
    nv: u64,
    idx: &mut Vec<u32>,
) -> ParseResult<()> {
    let n = body.integer(count)?;
    if n < 3 {
        return Err(body.fail(format!("a face with {n} vertices (at least 3 needed)")));
    }
    idx.clear();
    for _ in 0..n {
        let v = body.integer(item)?;
        if v < 0 || v as u64 >= nv {
            return Err(
                body.fail(format!("face refers to vertex {v} but the file has {nv} vertices (0-based)"))
            );
        }
        idx.push(v as u32);
    }
    Ok(())
}

/// Parses a PLY file's bytes.
pub(crate) fn parse_ply(bytes: &[u8]) -> ParseResult<RawMesh> {
    let header = parse_header(bytes)?;
    let body = &bytes[header.body_start..];
    let roles = plan(&header, body.len())?;
    match header.format {
        PlyFormat::Ascii => {
            let text = std::str::from_utf8(body).map_err(|e| {
                let line = header.lines + 1 + body[..e.valid_up_to()].iter().filter(|&&b| b == b'\n').count();
                (line, "an ASCII PLY body that is not text (a binary file labelled ascii?)".to_string())
            })?;
            let mut ascii = AsciiBody {
                lines: text.split('\n').enumerate(),
                first_line: header.lines + 1,
                tokens: "".split_ascii_whitespace(),
                line: 0,
                element: (String::new(), 0),
            };
            read_body(&header, &roles, &mut ascii)
        }
        format => {
            let mut binary = BinaryBody {
                bytes: body,
                base: header.body_start,
                pos: 0,
                big: format == PlyFormat::BinaryBigEndian,
                element: (String::new(), 0),
                start: header.body_start,
            };
            read_body(&header, &roles, &mut binary)
        }
    }
}

/// Writes a PLY file of `format` to any writer: `double` x, y, z (every bit of the f64
/// positions; ASCII writes the shortest decimal that reads back to the same f64) and a
/// `uchar`-counted `int` list `vertex_indices` per triangle.
pub fn write_ply_to(
    out: &mut impl Write,
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    format: PlyFormat,
) -> std::io::Result<()> {
    let too_many = || std::io::Error::new(std::io::ErrorKind::InvalidInput, "vertex index past i32::MAX");
    writeln!(out, "ply\nformat {} 1.0\ncomment written by fibfluid", format.header_name())?;
    writeln!(out, "element vertex {}", positions.len())?;
    writeln!(out, "property double x\nproperty double y\nproperty double z")?;
    writeln!(out, "element face {}", triangles.len())?;
    writeln!(out, "property list uchar int vertex_indices\nend_header")?;
    let big = format == PlyFormat::BinaryBigEndian;
    let f64_bytes = |c: f64| if big { c.to_be_bytes() } else { c.to_le_bytes() };
    let i32_bytes = |i: i32| if big { i.to_be_bytes() } else { i.to_le_bytes() };
    for p in positions {
        match format {
            PlyFormat::Ascii => writeln!(out, "{:?} {:?} {:?}", p[0], p[1], p[2])?,
            _ => p.iter().try_for_each(|&c| out.write_all(&f64_bytes(c)))?,
        }
    }
    for t in triangles {
        let mut idx = [0i32; 3];
        for (slot, &i) in idx.iter_mut().zip(t) {
            *slot = i32::try_from(i).map_err(|_| too_many())?;
        }
        match format {
            PlyFormat::Ascii => writeln!(out, "3 {} {} {}", idx[0], idx[1], idx[2])?,
            _ => {
                out.write_all(&[3])?;
                idx.iter().try_for_each(|&i| out.write_all(&i32_bytes(i)))?;
            }
        }
    }
    Ok(())
}
