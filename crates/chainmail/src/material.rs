//! ChainMail bounding regions (CBRs) and the two material models.

use crate::error::{ChainmailError, Result};

/// A ChainMail bounding region: the axis-aligned box of allowed offsets `x_j - x_i*` of a
/// chain element `P_j` relative to the (new) position `x_i*` of its neighbour `P_i`.
///
/// In the paper's notation (Eq. 1) the CBR is `x_{j,i}^min <= x_{j,i}* <= x_{j,i}^max`
/// (and the same for y, z); here `x_{j,i}^min = x_i* + min[0]`, `x_{j,i}^max = x_i* + max[0]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cbr {
    /// Lower limits of `x_j - x_i*` along x, y, z.
    pub min: [f64; 3],
    /// Upper limits of `x_j - x_i*` along x, y, z.
    pub max: [f64; 3],
}

impl Cbr {
    /// How far the offset `rel = x_j - x_i*` lies outside the box (largest per-axis excess;
    /// zero when inside).
    pub fn violation(&self, rel: [f64; 3]) -> f64 {
        let mut v = 0.0_f64;
        for a in 0..3 {
            v = v.max(self.min[a] - rel[a]).max(rel[a] - self.max[a]);
        }
        v
    }

    /// The nearest point of the box to `rel` (per-axis clamp; the box is axis-aligned so
    /// the clamp is the Euclidean projection).
    pub fn clamp(&self, rel: [f64; 3]) -> [f64; 3] {
        let mut out = rel;
        for a in 0..3 {
            out[a] = rel[a].max(self.min[a]).min(self.max[a]);
        }
        out
    }
}

/// A ChainMail material: it gives the CBR of every link of the lattice.
///
/// Both models in this crate produce CBRs that are symmetric in the sense that
/// `P_j` inside `CBR_{j,i}` is equivalent to `P_i` inside `CBR_{i,j}` (the rest offset
/// changes sign), so a link is either satisfied or violated, whichever end moved.
pub trait Material {
    /// The CBR of element `j` w.r.t. element `i`, whose rest offset is
    /// `rest_offset = r_j - r_i` (signed; the paper's `Δx = |x_j - x_i|` is its absolute
    /// value, the sign tells on which side of `P_i` the neighbour lies).
    ///
    /// Errors if `i` or `j` is not a valid element for this material.
    fn cbr(&self, i: usize, j: usize, rest_offset: [f64; 3]) -> Result<Cbr>;

    /// Checks the parameters, and that the material covers `element_count` elements.
    fn validate(&self, element_count: usize) -> Result<()>;

    /// True when every link along a given lattice direction has the same symmetric CBR
    /// half-widths (homogeneous TSVE material, isotropic or anisotropic per axis): the case
    /// for which the paper proves the time-saving scheme (each element processed once).
    fn supports_time_saving(&self) -> bool;
}

fn check_finite(name: &'static str, v: f64) -> Result<()> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(ChainmailError::InvalidParameter { name, reason: format!("{v} is not finite") })
    }
}

fn check_nonneg(name: &'static str, v: f64) -> Result<()> {
    check_finite(name, v)?;
    if v < 0.0 {
        return Err(ChainmailError::InvalidParameter { name, reason: format!("{v} is negative") });
    }
    Ok(())
}

/// An out-of-range compression or stretch limit, as [`alpha_limits_problem`] finds it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AlphaProblem {
    /// `alpha_min` or `alpha_max`.
    pub name: &'static str,
    /// The rule it breaks (`in (0, 1]`, `>= 1 and finite`).
    pub rule: &'static str,
    /// The value given.
    pub value: f64,
    /// The axis (0, 1, 2).
    pub axis: usize,
}

/// The one check of ChainMail's compression and stretch limits (scene files, settings
/// built in code and the materials all use it): per axis `0 < alpha_min <= 1` and
/// `1 <= alpha_max < inf`, so the rest state satisfies its CBRs.
pub fn alpha_limits_problem(alpha_min: [f64; 3], alpha_max: [f64; 3]) -> Option<AlphaProblem> {
    (0..3).find_map(|axis| {
        let (lo, hi) = (alpha_min[axis], alpha_max[axis]);
        if !(lo.is_finite() && lo > 0.0 && lo <= 1.0) {
            Some(AlphaProblem { name: "alpha_min", rule: "in (0, 1]", value: lo, axis })
        } else if !(hi.is_finite() && hi >= 1.0) {
            Some(AlphaProblem { name: "alpha_max", rule: ">= 1 and finite", value: hi, axis })
        } else {
            None
        }
    })
}

/// The Generalized ChainMail material of Li & Brodlie (the paper's "traditional" ChainMail,
/// Eq. 1–2), with optional per-axis parameters.
///
/// For a rest offset `d = r_j - r_i` with `Δ = |d|` per axis, the limits along x are
///
/// ```text
/// x_min = x_i* + (alpha_min Δx − beta (Δy + Δz))
/// x_max = x_i* + (alpha_max Δx + beta (Δy + Δz))
/// ```
///
/// for a neighbour on the +x side; on the −x side the box is mirrored
/// (`x_i* − alpha_max Δx − beta(...)` to `x_i* − alpha_min Δx + beta(...)`). The y and z
/// limits use `alpha_min[1]`, ... `beta[2]` in the same way. So a link can shrink to
/// `alpha_min` and stretch to `alpha_max` times its rest length, and shear by `beta` times
/// the rest distance across.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GeneralizedMaterial {
    /// Minimum compression ratio per axis (`0 <= alpha_min <= 1`).
    pub alpha_min: [f64; 3],
    /// Maximum stretch ratio per axis (`alpha_max >= 1`, `alpha_max >= alpha_min`).
    pub alpha_max: [f64; 3],
    /// Shear limit per axis (`beta >= 0`).
    pub beta: [f64; 3],
}

impl GeneralizedMaterial {
    /// The same `alpha_min`, `alpha_max`, `beta` along every axis.
    pub fn isotropic(alpha_min: f64, alpha_max: f64, beta: f64) -> Self {
        Self { alpha_min: [alpha_min; 3], alpha_max: [alpha_max; 3], beta: [beta; 3] }
    }
}

impl Default for GeneralizedMaterial {
    /// `alpha_min = 0.8`, `alpha_max = 1.2`, `beta = 0.1` on every axis.
    fn default() -> Self {
        Self::isotropic(0.8, 1.2, 0.1)
    }
}

impl Material for GeneralizedMaterial {
    fn cbr(&self, _i: usize, _j: usize, d: [f64; 3]) -> Result<Cbr> {
        let abs = [d[0].abs(), d[1].abs(), d[2].abs()];
        let mut min = [0.0; 3];
        let mut max = [0.0; 3];
        for a in 0..3 {
            let across = abs[(a + 1) % 3] + abs[(a + 2) % 3];
            let lo = self.alpha_min[a] * d[a];
            let hi = self.alpha_max[a] * d[a];
            min[a] = lo.min(hi) - self.beta[a] * across;
            max[a] = lo.max(hi) + self.beta[a] * across;
        }
        Ok(Cbr { min, max })
    }

    fn validate(&self, _element_count: usize) -> Result<()> {
        for a in 0..3 {
            check_nonneg("beta", self.beta[a])?;
        }
        match alpha_limits_problem(self.alpha_min, self.alpha_max) {
            None => Ok(()),
            Some(p) => Err(ChainmailError::InvalidParameter {
                name: p.name,
                reason: format!("must be {}, got {} on axis {}", p.rule, p.value, p.axis),
            }),
        }
    }

    fn supports_time_saving(&self) -> bool {
        false
    }
}

/// The TSVE-ChainMail material (Eq. 3–4): per-element, per-axis parameters `alpha_i`.
///
/// For a rest offset `d = r_j - r_i`, the limits along axis `a` are
///
/// ```text
/// x_min = x_i* + (d_a − ((alpha_i[a] + alpha_j[a]) / 2) (Δx + Δy + Δz))
/// x_max = x_i* + (d_a + ((alpha_i[a] + alpha_j[a]) / 2) (Δx + Δy + Δz))
/// ```
///
/// i.e. a box centred on the rest position of `P_j` relative to `P_i*`. With
/// `alpha_i = alpha_j = alpha` this is Eq. 4: `x_min = x_i* + (1 − alpha) Δx − alpha (Δy + Δz)`
/// for a neighbour on the +x side. A heterogeneous material has different `alpha` per
/// element; an anisotropic one has different `alpha` per axis (reading choice: the
/// parameter used in the axis-`a` limit is the axis-`a` component).
#[derive(Debug, Clone, PartialEq)]
pub struct TsveMaterial {
    /// `alpha[i] = [alpha_x, alpha_y, alpha_z]` of element `i`; finite and `>= 0`.
    pub alpha: Vec<[f64; 3]>,
}

impl TsveMaterial {
    /// Isotropic, homogeneous material: `alpha` for every element and axis.
    pub fn isotropic(element_count: usize, alpha: f64) -> Self {
        Self { alpha: vec![[alpha; 3]; element_count] }
    }

    /// Anisotropic, homogeneous material: the same per-axis `alpha` for every element.
    pub fn anisotropic(element_count: usize, alpha: [f64; 3]) -> Self {
        Self { alpha: vec![alpha; element_count] }
    }

    /// Heterogeneous, isotropic material: one scalar `alpha` per element.
    pub fn heterogeneous(alpha: &[f64]) -> Self {
        Self { alpha: alpha.iter().map(|&a| [a; 3]).collect() }
    }
}

impl Material for TsveMaterial {
    fn cbr(&self, i: usize, j: usize, d: [f64; 3]) -> Result<Cbr> {
        let n = self.alpha.len();
        let ai = self.alpha.get(i).ok_or(ChainmailError::IndexOutOfRange { index: i, len: n })?;
        let aj = self.alpha.get(j).ok_or(ChainmailError::IndexOutOfRange { index: j, len: n })?;
        let l1 = d[0].abs() + d[1].abs() + d[2].abs();
        let mut min = [0.0; 3];
        let mut max = [0.0; 3];
        for a in 0..3 {
            let half = 0.5 * (ai[a] + aj[a]) * l1;
            min[a] = d[a] - half;
            max[a] = d[a] + half;
        }
        Ok(Cbr { min, max })
    }

    fn validate(&self, element_count: usize) -> Result<()> {
        if self.alpha.len() != element_count {
            return Err(ChainmailError::LengthMismatch { expected: element_count, found: self.alpha.len() });
        }
        for a in &self.alpha {
            for &v in a {
                check_nonneg("alpha", v)?;
            }
        }
        Ok(())
    }

    fn supports_time_saving(&self) -> bool {
        match self.alpha.first() {
            None => true,
            Some(first) => self.alpha.iter().all(|a| a == first),
        }
    }
}
