//! Label images (segmentations) in NIfTI-1 and NIfTI-2 single files, `.nii` or `.nii.gz`.
//!
//! The header is read by this module (no `nifti` crate: see docs/dependencies.md); gzip goes
//! through `flate2`. A label image holds one non-negative integer per voxel: 0 is background,
//! 1..k are tissues. Accepted data types: uint8, int8, int16, uint16, int32, uint32, and
//! float32/float64 holding whole numbers (others are refused). `scl_slope`/`scl_inter` are
//! ignored: labels are names, not measurements.
//!
//! Geometry: the voxel-to-world affine is the sform when `sform_code > 0`, else the qform
//! when `qform_code > 0`, else the spacing alone (`diag(pixdim[1..3])`, origin 0). Lengths are
//! converted to metres from `xyzt_units` (metre, millimetre, micrometre; millimetre when the
//! code is unknown or 0, the NIfTI convention in practice).
//!
//! Everything that would make the reader allocate or decompress much is decided from the
//! header first: the voxel count must fit the file size limit ([`max_file_bytes`]) both as
//! stored and as decoded labels (4 bytes a voxel), and a `.gz` is never inflated past what
//! the header announces plus [`GZIP_MARGIN`].

use std::io::Read;
use std::path::{Path, PathBuf};

use crate::unit::LengthUnit;

use crate::error::ReadError;
use crate::io::{max_file_bytes, read_file_limited};
use crate::vec3::Vec3;

/// Bytes a `.nii.gz` may inflate to past `vox_offset + voxels x bytes per voxel` (trailing
/// padding some writers add); more is refused as a decompression bomb.
pub const GZIP_MARGIN: u64 = 64 * 1024;

/// Where the voxel-to-world affine of a [`LabelImage`] came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AffineSource {
    /// The sform (`srow_x/y/z`), used when `sform_code > 0`.
    Sform,
    /// The qform (quaternion, offsets, `pixdim`, `qfac`), used when only `qform_code > 0`.
    Qform,
    /// Neither: the spacing alone, origin at voxel (0, 0, 0).
    Spacing,
}

/// A 3-D label volume with its geometry in metres.
#[derive(Clone, Debug, PartialEq)]
pub struct LabelImage {
    /// Voxel counts along i, j, k.
    pub dims: [usize; 3],
    /// Voxel size along i, j, k, in metres (`pixdim[1..3]` converted).
    pub spacing: [f64; 3],
    /// Voxel index `(i, j, k)` to world position in metres: row r is `[a, b, c, t]`, world_r
    /// `= a i + b j + c k + t`.
    pub affine: [[f64; 4]; 3],
    /// Where [`affine`](Self::affine) came from.
    pub affine_source: AffineSource,
    /// One label a voxel, i fastest, then j, then k (the NIfTI order).
    pub labels: Vec<u32>,
}

/// The NIfTI `xyzt_units` code of a unit, and the unit lengths are stored in under it:
/// NIfTI has no centimetre, so centimetres are stored as millimetres.
fn nifti_unit(unit: LengthUnit) -> (u8, LengthUnit) {
    match unit {
        LengthUnit::Metre => (1, LengthUnit::Metre),
        LengthUnit::Centimetre | LengthUnit::Millimetre => (2, LengthUnit::Millimetre),
        LengthUnit::Micrometre => (3, LengthUnit::Micrometre),
    }
}

/// The unit of an `xyzt_units` code (millimetre when unknown or 0).
fn unit_of_code(code: i64) -> LengthUnit {
    match code & 7 {
        1 => LengthUnit::Metre,
        3 => LengthUnit::Micrometre,
        _ => LengthUnit::Millimetre,
    }
}

/// Voxel data types of a label image.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LabelType {
    /// uint8 (code 2).
    U8,
    /// int8 (code 256).
    I8,
    /// int16 (code 4).
    I16,
    /// uint16 (code 512).
    U16,
    /// int32 (code 8).
    I32,
    /// uint32 (code 768).
    U32,
    /// float32 holding whole numbers (code 16).
    F32,
    /// float64 holding whole numbers (code 64).
    F64,
}

impl LabelType {
    fn from_code(code: i64) -> Option<Self> {
        Some(match code {
            2 => LabelType::U8,
            256 => LabelType::I8,
            4 => LabelType::I16,
            512 => LabelType::U16,
            8 => LabelType::I32,
            768 => LabelType::U32,
            16 => LabelType::F32,
            64 => LabelType::F64,
            _ => return None,
        })
    }

    fn code(self) -> i16 {
        match self {
            LabelType::U8 => 2,
            LabelType::I8 => 256,
            LabelType::I16 => 4,
            LabelType::U16 => 512,
            LabelType::I32 => 8,
            LabelType::U32 => 768,
            LabelType::F32 => 16,
            LabelType::F64 => 64,
        }
    }

    /// Bytes a voxel.
    pub fn bytes(self) -> usize {
        match self {
            LabelType::U8 | LabelType::I8 => 1,
            LabelType::I16 | LabelType::U16 => 2,
            LabelType::I32 | LabelType::U32 | LabelType::F32 => 4,
            LabelType::F64 => 8,
        }
    }

    /// The voxel at the start of `b` as a label (`Err` holds the value when it is not one).
    fn decode(self, b: &[u8], big: bool) -> Result<u32, f64> {
        macro_rules! num {
            ($t:ty, $n:literal) => {{
                let a: [u8; $n] = b[..$n].try_into().expect("chunk length");
                if big { <$t>::from_be_bytes(a) } else { <$t>::from_le_bytes(a) }
            }};
        }
        let v: f64 = match self {
            LabelType::U8 => return Ok(b[0] as u32),
            LabelType::U16 => return Ok(num!(u16, 2) as u32),
            LabelType::U32 => return Ok(num!(u32, 4)),
            LabelType::I8 => b[0] as i8 as f64,
            LabelType::I16 => num!(i16, 2) as f64,
            LabelType::I32 => num!(i32, 4) as f64,
            LabelType::F32 => num!(f32, 4) as f64,
            LabelType::F64 => num!(f64, 8),
        };
        if v >= 0.0 && v <= u32::MAX as f64 && v.fract() == 0.0 { Ok(v as u32) } else { Err(v) }
    }
}

/// What is wrong with a label image file (the file is named by [`ImageError`]).
#[derive(Debug, thiserror::Error)]
pub enum ImageProblem {
    /// The file could not be read (not a regular file, larger than the limit, ...).
    #[error(transparent)]
    Read(#[from] ReadError),
    /// Shorter than any NIfTI header.
    #[error("is {size} bytes, shorter than a NIfTI header (348 bytes)")]
    TooShort {
        /// Bytes found (after decompression for a `.gz`).
        size: u64,
    },
    /// `sizeof_hdr` is neither 348 (NIfTI-1) nor 540 (NIfTI-2) in either byte order.
    #[error("is not a NIfTI file (sizeof_hdr = {sizeof_hdr}, expected 348 or 540)")]
    NotNifti {
        /// The first four bytes as a little-endian integer.
        sizeof_hdr: i32,
    },
    /// The magic string is not `n+1` / `n+2` (a `.hdr`/`.img` pair is not read).
    #[error("bad NIfTI magic {found:?} (expected \"n+1\" or \"n+2\": single-file NIfTI only)")]
    BadMagic {
        /// The bytes found.
        found: String,
    },
    /// `dim[0]` is below 3.
    #[error("has {ndim} dimensions; a 3-D label volume is expected")]
    TooFewDimensions {
        /// `dim[0]`.
        ndim: i64,
    },
    /// A dimension is out of range: `dim[0] > 7`, a size below 1, or a 4th (or later)
    /// dimension above 1.
    #[error("dim[{axis}] = {size} is not allowed (sizes must be >= 1, dimensions 4 to 7 must be 1)")]
    BadDimension {
        /// Index in `dim` (1-based axes; 0 = the count).
        axis: usize,
        /// The value.
        size: i64,
    },
    /// The voxels would not fit the file size limit, as stored or as decoded labels.
    #[error(
        "claims {voxels} voxels ({bytes} bytes), more than the limit of {limit} bytes; raise it with --max-file-bytes or {}",
        crate::limits::MAX_FILE_BYTES_ENV
    )]
    TooManyVoxels {
        /// Voxel count the header claims (saturated at `u64::MAX`).
        voxels: u64,
        /// The larger of stored and decoded bytes.
        bytes: u64,
        /// The limit in force.
        limit: u64,
    },
    /// A voxel size is zero, negative or not finite.
    #[error("voxel spacing pixdim[{axis}] = {value} is not a positive finite length")]
    BadSpacing {
        /// 1, 2 or 3.
        axis: usize,
        /// The value.
        value: f64,
    },
    /// `vox_offset` is inside the header, negative or not finite.
    #[error("vox_offset = {value} is not a byte offset past the header")]
    BadVoxOffset {
        /// The value.
        value: f64,
    },
    /// The data type is not an integer label type (nor a float holding integers).
    #[error(
        "data type {code} is not a label type (uint8, int8, int16, uint16, int32, uint32, float32, float64)"
    )]
    UnsupportedDatatype {
        /// NIfTI datatype code.
        code: i64,
    },
    /// The data ends before `vox_offset + voxels x bytes per voxel`.
    #[error("is truncated: the voxels need {needed} bytes, only {found} present")]
    Truncated {
        /// Bytes the header needs.
        needed: u64,
        /// Bytes present (after decompression for a `.gz`).
        found: u64,
    },
    /// A `.gz` inflates past what the header announces (a decompression bomb).
    #[error(
        "inflates to more than the {expected} bytes its header announces (+{GZIP_MARGIN} bytes of margin)"
    )]
    GzipTooLarge {
        /// `vox_offset + voxels x bytes per voxel`.
        expected: u64,
    },
    /// The gzip stream is corrupt.
    #[error("is not a valid gzip stream: {0}")]
    Gzip(std::io::Error),
    /// A voxel holds a negative or non-integer value.
    #[error("voxel {voxel} holds {value}, not a label (a non-negative whole number)")]
    NotALabel {
        /// Linear voxel index.
        voxel: usize,
        /// The value.
        value: f64,
    },
    /// The affine is not finite or is singular.
    #[error("the {source_name} affine is {what}")]
    BadAffine {
        /// "sform" or "qform".
        source_name: &'static str,
        /// "not finite" or "singular".
        what: &'static str,
    },
    /// A label image built in code is inconsistent (labels vs dims, spacing).
    #[error("{0}")]
    Invalid(String),
    /// Writing failed.
    #[error("{0}")]
    Io(#[from] std::io::Error),
}

/// A label image problem, with the file it is about.
#[derive(Debug, thiserror::Error)]
#[error("{path}: {problem}")]
pub struct ImageError {
    /// The file.
    pub path: PathBuf,
    /// What is wrong.
    pub problem: ImageProblem,
}

impl LabelImage {
    /// An image with the spacing (metres) as its only geometry. Checks that `labels` has
    /// `nx ny nz` entries and the spacing is positive and finite.
    pub fn new(dims: [usize; 3], spacing: [f64; 3], labels: Vec<u32>) -> Result<Self, ImageProblem> {
        let n = dims.iter().try_fold(1usize, |a, &d| a.checked_mul(d));
        if n != Some(labels.len()) || labels.is_empty() {
            return Err(ImageProblem::Invalid(format!("{} labels for dims {dims:?}", labels.len())));
        }
        if let Some(axis) = spacing.iter().position(|s| !(s.is_finite() && *s > 0.0)) {
            return Err(ImageProblem::BadSpacing { axis: axis + 1, value: spacing[axis] });
        }
        let affine = [[spacing[0], 0.0, 0.0, 0.0], [0.0, spacing[1], 0.0, 0.0], [0.0, 0.0, spacing[2], 0.0]];
        Ok(Self { dims, spacing, affine, affine_source: AffineSource::Spacing, labels })
    }

    /// Linear index of voxel `(i, j, k)`.
    pub fn index(&self, i: usize, j: usize, k: usize) -> usize {
        i + self.dims[0] * (j + self.dims[1] * k)
    }

    /// World position (metres) of a (possibly fractional) voxel index.
    pub fn to_world(&self, ijk: Vec3) -> Vec3 {
        self.affine.map(|r| r[0] * ijk[0] + r[1] * ijk[1] + r[2] * ijk[2] + r[3])
    }

    /// Volume of one voxel in cubic metres: `|det|` of the affine's linear part.
    pub fn voxel_volume(&self) -> f64 {
        let a = &self.affine;
        let det = a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1])
            - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
            + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
        det.abs()
    }

    /// The distinct non-zero labels, ascending.
    pub fn labels_present(&self) -> Vec<u32> {
        let mut v: Vec<u32> = self.labels.iter().copied().filter(|&l| l != 0).collect();
        v.sort_unstable();
        v.dedup();
        v
    }
}

/// The fields of a NIfTI header this crate uses.
#[derive(Clone, Debug)]
struct Header {
    big: bool,
    dims: [usize; 3],
    ltype: LabelType,
    /// `pixdim[0..4]` (qfac, then the spacing in file units).
    pixdim: [f64; 4],
    vox_offset: u64,
    unit: LengthUnit,
    qform_code: i64,
    sform_code: i64,
    /// quatern_b, c, d, qoffset_x, y, z.
    quatern: [f64; 6],
    srow: [[f64; 4]; 3],
}

impl Header {
    /// `vox_offset + voxels x bytes per voxel`.
    fn data_end(&self) -> u64 {
        self.vox_offset + self.voxels() * self.ltype.bytes() as u64
    }

    fn voxels(&self) -> u64 {
        self.dims.iter().map(|&d| d as u64).product()
    }
}

/// Reads fixed-offset fields in either byte order.
struct Fields<'a> {
    b: &'a [u8],
    big: bool,
}

impl Fields<'_> {
    fn raw<const N: usize>(&self, off: usize) -> [u8; N] {
        let mut a: [u8; N] = self.b[off..off + N].try_into().expect("header length checked");
        if self.big {
            a.reverse();
        }
        a
    }
    fn i16(&self, off: usize) -> i64 {
        i16::from_le_bytes(self.raw(off)) as i64
    }
    fn i32(&self, off: usize) -> i64 {
        i32::from_le_bytes(self.raw(off)) as i64
    }
    fn i64(&self, off: usize) -> i64 {
        i64::from_le_bytes(self.raw(off))
    }
    fn f32(&self, off: usize) -> f64 {
        f32::from_le_bytes(self.raw(off)) as f64
    }
    fn f64(&self, off: usize) -> f64 {
        f64::from_le_bytes(self.raw(off))
    }
}

/// Parses and checks a header from the first bytes of the (decompressed) file; `limit` is
/// the file size limit the voxel count must fit.
fn parse_header(b: &[u8], limit: u64) -> Result<Header, ImageProblem> {
    if b.len() < 348 {
        return Err(ImageProblem::TooShort { size: b.len() as u64 });
    }
    let le = i32::from_le_bytes(b[..4].try_into().expect("4 bytes"));
    let be = i32::from_be_bytes(b[..4].try_into().expect("4 bytes"));
    let (size, big) = match (le, be) {
        (348 | 540, _) => (le, false),
        (_, 348 | 540) => (be, true),
        _ => return Err(ImageProblem::NotNifti { sizeof_hdr: le }),
    };
    if size == 540 && b.len() < 540 {
        return Err(ImageProblem::TooShort { size: b.len() as u64 });
    }
    let f = Fields { b, big };
    let v2 = size == 540;
    let (magic, want): (&[u8], &[u8]) =
        if v2 { (&b[4..12], b"n+2\0\r\n\x1a\n") } else { (&b[344..348], b"n+1\0") };
    if magic != want {
        return Err(ImageProblem::BadMagic { found: String::from_utf8_lossy(magic).into_owned() });
    }
    let dim: Vec<i64> = (0..8).map(|i| if v2 { f.i64(16 + 8 * i) } else { f.i16(40 + 2 * i) }).collect();
    let pixdim: Vec<f64> = (0..4).map(|i| if v2 { f.f64(104 + 8 * i) } else { f.f32(76 + 4 * i) }).collect();
    let datatype = if v2 { f.i16(12) } else { f.i16(70) };
    let vox_offset = if v2 { f.i64(168) as f64 } else { f.f32(108) };
    let units = if v2 { f.i32(500) } else { b[123] as i64 };
    let (qform_code, sform_code) = if v2 { (f.i32(344), f.i32(348)) } else { (f.i16(252), f.i16(254)) };
    let quatern: Vec<f64> =
        (0..6).map(|i| if v2 { f.f64(352 + 8 * i) } else { f.f32(256 + 4 * i) }).collect();
    let srow = std::array::from_fn(|r| {
        std::array::from_fn(|c| if v2 { f.f64(400 + 32 * r + 8 * c) } else { f.f32(280 + 16 * r + 4 * c) })
    });
    let dims = check_dims(&dim)?;
    let ltype = LabelType::from_code(datatype).ok_or(ImageProblem::UnsupportedDatatype { code: datatype })?;
    let header_end = if v2 { 540.0 } else { 348.0 };
    if !(vox_offset.is_finite() && vox_offset >= header_end && vox_offset < u64::MAX as f64 / 2.0) {
        return Err(ImageProblem::BadVoxOffset { value: vox_offset });
    }
    check_voxel_count(&dim[1..4], ltype, vox_offset as u64, limit)?;
    for axis in 1..4 {
        if !(pixdim[axis].is_finite() && pixdim[axis] > 0.0) {
            return Err(ImageProblem::BadSpacing { axis, value: pixdim[axis] });
        }
    }
    Ok(Header {
        big,
        dims,
        ltype,
        pixdim: [pixdim[0], pixdim[1], pixdim[2], pixdim[3]],
        vox_offset: vox_offset as u64,
        unit: unit_of_code(units),
        qform_code,
        sform_code,
        quatern: std::array::from_fn(|i| quatern[i]),
        srow,
    })
}

/// `dim[0..8]`: three to seven dimensions, sizes at least 1, dimensions past the third of
/// size 1. Returns the three sizes.
fn check_dims(dim: &[i64]) -> Result<[usize; 3], ImageProblem> {
    let ndim = dim[0];
    if ndim < 3 {
        return Err(ImageProblem::TooFewDimensions { ndim });
    }
    if ndim > 7 {
        return Err(ImageProblem::BadDimension { axis: 0, size: ndim });
    }
    for axis in 1..=ndim as usize {
        let size = dim[axis];
        if size < 1 || (axis > 3 && size != 1) {
            return Err(ImageProblem::BadDimension { axis, size });
        }
    }
    Ok([dim[1] as usize, dim[2] as usize, dim[3] as usize])
}

/// Refuses a voxel count whose stored bytes or decoded labels exceed `limit`.
fn check_voxel_count(dim: &[i64], ltype: LabelType, offset: u64, limit: u64) -> Result<(), ImageProblem> {
    let voxels = dim.iter().try_fold(1u64, |a, &d| a.checked_mul(d as u64));
    let bytes = voxels.and_then(|n| {
        let stored = n.checked_mul(ltype.bytes() as u64)?.checked_add(offset)?;
        Some(stored.max(n.checked_mul(4)?))
    });
    match bytes {
        Some(b) if b <= limit => Ok(()),
        _ => Err(ImageProblem::TooManyVoxels {
            voxels: voxels.unwrap_or(u64::MAX),
            bytes: bytes.unwrap_or(u64::MAX),
            limit,
        }),
    }
}

/// The voxel-to-world affine in metres, from the sform, the qform or the spacing.
fn affine_of(h: &Header) -> Result<([[f64; 4]; 3], AffineSource), ImageProblem> {
    let unit = h.unit;
    let (a, source, name) = if h.sform_code > 0 {
        (h.srow, AffineSource::Sform, "sform")
    } else if h.qform_code > 0 {
        (qform_affine(h), AffineSource::Qform, "qform")
    } else {
        let p = h.pixdim;
        (
            [[p[1], 0.0, 0.0, 0.0], [0.0, p[2], 0.0, 0.0], [0.0, 0.0, p[3], 0.0]],
            AffineSource::Spacing,
            "spacing",
        )
    };
    let a = a.map(|r| r.map(|x| unit.to_metres(x)));
    if a.iter().flatten().any(|x| !x.is_finite()) {
        return Err(ImageProblem::BadAffine { source_name: name, what: "not finite" });
    }
    let det = a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1])
        - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
        + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
    if !(det.abs() > 0.0) {
        return Err(ImageProblem::BadAffine { source_name: name, what: "singular" });
    }
    Ok((a, source))
}

/// The qform's affine in file units (NIfTI-1 standard: rotation from the quaternion, columns
/// scaled by the spacing, the third by `qfac`).
fn qform_affine(h: &Header) -> [[f64; 4]; 3] {
    let [b, c, d, x, y, z] = h.quatern;
    let a = (1.0 - (b * b + c * c + d * d)).max(0.0).sqrt();
    let r = [
        [a * a + b * b - c * c - d * d, 2.0 * (b * c - a * d), 2.0 * (b * d + a * c)],
        [2.0 * (b * c + a * d), a * a + c * c - b * b - d * d, 2.0 * (c * d - a * b)],
        [2.0 * (b * d - a * c), 2.0 * (c * d + a * b), a * a + d * d - c * c - b * b],
    ];
    let qfac = if h.pixdim[0] < 0.0 { -1.0 } else { 1.0 };
    let s = [h.pixdim[1], h.pixdim[2], h.pixdim[3] * qfac];
    let t = [x, y, z];
    std::array::from_fn(|i| [r[i][0] * s[0], r[i][1] * s[1], r[i][2] * s[2], t[i]])
}

/// Decodes the voxels of a checked header from the whole (decompressed) file.
fn decode(h: &Header, bytes: &[u8]) -> Result<LabelImage, ImageProblem> {
    let needed = h.data_end();
    if (bytes.len() as u64) < needed {
        return Err(ImageProblem::Truncated { needed, found: bytes.len() as u64 });
    }
    let (affine, affine_source) = affine_of(h)?;
    let n = h.voxels() as usize;
    let mut labels = Vec::new();
    labels.try_reserve_exact(n).map_err(|_| ReadError::OutOfMemory { bytes: 4 * n as u64 })?;
    let bpv = h.ltype.bytes();
    let data = &bytes[h.vox_offset as usize..needed as usize];
    for (voxel, chunk) in data.chunks_exact(bpv).enumerate() {
        labels.push(h.ltype.decode(chunk, h.big).map_err(|value| ImageProblem::NotALabel { voxel, value })?);
    }
    let spacing = [1, 2, 3].map(|i| h.unit.to_metres(h.pixdim[i]));
    Ok(LabelImage { dims: h.dims, spacing, affine, affine_source, labels })
}

/// Inflates a `.nii.gz`: the header first, then at most what it announces plus
/// [`GZIP_MARGIN`].
fn inflate(compressed: &[u8], limit: u64) -> Result<(Header, Vec<u8>), ImageProblem> {
    let mut gz = flate2::read::MultiGzDecoder::new(compressed);
    let mut head = Vec::with_capacity(540);
    (&mut gz).take(540).read_to_end(&mut head).map_err(ImageProblem::Gzip)?;
    let header = parse_header(&head, limit)?;
    let expected = header.data_end();
    let cap = expected + GZIP_MARGIN;
    let mut bytes = Vec::new();
    bytes.try_reserve_exact(expected as usize).map_err(|_| ReadError::OutOfMemory { bytes: expected })?;
    bytes.extend_from_slice(&head);
    gz.take(cap + 1 - head.len() as u64).read_to_end(&mut bytes).map_err(ImageProblem::Gzip)?;
    if bytes.len() as u64 > cap {
        return Err(ImageProblem::GzipTooLarge { expected });
    }
    Ok((header, bytes))
}

/// Parses a NIfTI-1 or NIfTI-2 file held in memory, gzip-compressed or not (told by its
/// first bytes). `limit` bounds the voxel data as stored and as decoded labels.
pub fn read_nifti_bytes(bytes: &[u8], limit: u64) -> Result<LabelImage, ImageProblem> {
    if bytes.starts_with(&[0x1f, 0x8b]) {
        let (header, raw) = inflate(bytes, limit)?;
        decode(&header, &raw)
    } else {
        let header = parse_header(bytes, limit)?;
        decode(&header, bytes)
    }
}

/// Reads a label image (`.nii` or `.nii.gz`, NIfTI-1 or NIfTI-2) under the file size limit
/// in force ([`max_file_bytes`]).
pub fn read_nifti(path: impl AsRef<Path>) -> Result<LabelImage, ImageError> {
    read_nifti_with(path, None)
}

/// [`read_nifti`] with an explicit limit in bytes (`None`: [`max_file_bytes`]) for the file
/// and for its voxels.
pub fn read_nifti_with(path: impl AsRef<Path>, max_bytes: Option<u64>) -> Result<LabelImage, ImageError> {
    let path = path.as_ref();
    let err = |problem| ImageError { path: path.to_path_buf(), problem };
    let limit = match max_bytes {
        Some(n) => n,
        None => max_file_bytes().map_err(|e| err(e.into()))?,
    };
    let bytes = read_file_limited(path, Some(limit)).map_err(|e| err(e.into()))?;
    read_nifti_bytes(&bytes, limit).map_err(err)
}

/// How [`write_nifti`] stores an image.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NiftiWriteOptions {
    /// Unit of the stored lengths (`xyzt_units`; centimetres are stored as millimetres,
    /// NIfTI has no code for them).
    pub unit: LengthUnit,
    /// Voxel type; `None`: the smallest of uint8, uint16, uint32 that holds every label.
    pub label_type: Option<LabelType>,
    /// Gzip the file (`.nii.gz`).
    pub gzip: bool,
    /// Write NIfTI-2 (f64 lengths) instead of NIfTI-1 (f32 lengths).
    pub nifti2: bool,
}

impl Default for NiftiWriteOptions {
    fn default() -> Self {
        Self { unit: LengthUnit::Millimetre, label_type: None, gzip: false, nifti2: false }
    }
}

/// Encodes an image as a NIfTI single file, little-endian: NIfTI-1 (`vox_offset` 352,
/// lengths as f32) or, with `opts.nifti2`, NIfTI-2 (`vox_offset` 544, lengths as f64). The
/// affine is written as the sform (code 1, "scanner") unless it came from the spacing alone,
/// in which case both form codes are 0.
pub fn nifti_bytes(image: &LabelImage, opts: &NiftiWriteOptions) -> Vec<u8> {
    let max = image.labels.iter().copied().max().unwrap_or(0);
    let ltype = opts.label_type.unwrap_or(match max {
        0..=255 => LabelType::U8,
        256..=65535 => LabelType::U16,
        _ => LabelType::U32,
    });
    let (unit_code, stored) = nifti_unit(opts.unit);
    let v2 = opts.nifti2;
    let offset = if v2 { 544 } else { 352 };
    let mut h = vec![0u8; offset];
    let put = |h: &mut Vec<u8>, off: usize, b: &[u8]| h[off..off + b.len()].copy_from_slice(b);
    let real = |h: &mut Vec<u8>, off1: usize, off2: usize, x: f64| {
        if v2 { put(h, off2, &x.to_le_bytes()) } else { put(h, off1, &(x as f32).to_le_bytes()) }
    };
    let dims = [3, image.dims[0], image.dims[1], image.dims[2], 1, 1, 1, 1];
    if v2 {
        put(&mut h, 0, &540i32.to_le_bytes());
        put(&mut h, 4, b"n+2\0\r\n\x1a\n");
        put(&mut h, 12, &ltype.code().to_le_bytes());
        put(&mut h, 14, &(8 * ltype.bytes() as i16).to_le_bytes());
        for (i, d) in dims.iter().enumerate() {
            put(&mut h, 16 + 8 * i, &(*d as i64).to_le_bytes());
        }
        put(&mut h, 168, &(offset as i64).to_le_bytes());
        put(&mut h, 500, &i32::from(unit_code).to_le_bytes());
    } else {
        put(&mut h, 0, &348i32.to_le_bytes());
        for (i, d) in dims.iter().enumerate() {
            put(&mut h, 40 + 2 * i, &(*d as i16).to_le_bytes());
        }
        put(&mut h, 70, &ltype.code().to_le_bytes());
        put(&mut h, 72, &(8 * ltype.bytes() as i16).to_le_bytes());
        put(&mut h, 108, &(offset as f32).to_le_bytes());
        h[123] = unit_code;
        put(&mut h, 344, b"n+1\0");
    }
    let pixdim = [
        1.0,
        stored.from_metres(image.spacing[0]),
        stored.from_metres(image.spacing[1]),
        stored.from_metres(image.spacing[2]),
    ];
    for (i, p) in pixdim.iter().enumerate() {
        real(&mut h, 76 + 4 * i, 104 + 8 * i, *p);
    }
    real(&mut h, 112, 176, 1.0);
    if image.affine_source != AffineSource::Spacing {
        if v2 {
            put(&mut h, 348, &1i32.to_le_bytes())
        } else {
            put(&mut h, 254, &1i16.to_le_bytes())
        }
        for (r, row) in image.affine.iter().enumerate() {
            for (c, x) in row.iter().enumerate() {
                real(&mut h, 280 + 16 * r + 4 * c, 400 + 32 * r + 8 * c, stored.from_metres(*x));
            }
        }
    }
    h.reserve(image.labels.len() * ltype.bytes());
    for &l in &image.labels {
        match ltype {
            LabelType::U8 | LabelType::I8 => h.push(l as u8),
            LabelType::U16 | LabelType::I16 => h.extend_from_slice(&(l as u16).to_le_bytes()),
            LabelType::U32 | LabelType::I32 => h.extend_from_slice(&l.to_le_bytes()),
            LabelType::F32 => h.extend_from_slice(&(l as f32).to_le_bytes()),
            LabelType::F64 => h.extend_from_slice(&(l as f64).to_le_bytes()),
        }
    }
    h
}

/// Writes an image as a NIfTI file ([`nifti_bytes`]), gzip-compressed when
/// `opts.gzip`. Labels that do not fit the chosen type are truncated: choose it with care.
pub fn write_nifti(
    path: impl AsRef<Path>,
    image: &LabelImage,
    opts: &NiftiWriteOptions,
) -> Result<(), ImageError> {
    use std::io::Write;
    let path = path.as_ref();
    let err = |e: std::io::Error| ImageError { path: path.to_path_buf(), problem: ImageProblem::Io(e) };
    let bytes = nifti_bytes(image, opts);
    if opts.gzip {
        let file = std::fs::File::create(path).map_err(err)?;
        let mut gz =
            flate2::write::GzEncoder::new(std::io::BufWriter::new(file), flate2::Compression::default());
        gz.write_all(&bytes).map_err(err)?;
        gz.finish().map_err(err)?.flush().map_err(err)
    } else {
        std::fs::write(path, bytes).map_err(err)
    }
}
