//! The `[chainmail]` section of a scene: how the ChainMail methods (TSVE and Generalized)
//! voxelize and deform the scene's body. See docs/scene-format.md for defaults and why.

use fibfluid_chainmail::{EmbeddingGrid, GeneralizedMaterial, TsveMaterial};
use fibfluid_geometry::Vec3;
use fibfluid_linalg::{Choice, impl_choice};
use serde::Deserialize;

use crate::error::SceneProblem;
use crate::scene::{Invalid, choice, invalid, range};

/// Which ChainMail model the `[chainmail]` section describes for `fibfluid probe
/// --method`; the method flag picks the variant actually run, this is the scene's
/// preference (and what `tss` and the material regions are checked against).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Variant {
    /// TSVE-ChainMail (Zhang et al. 2016): symmetric CBRs, volume and strain-energy
    /// relaxation, returns to rest after release.
    #[default]
    Tsve,
    /// Generalized (traditional) ChainMail: CBRs only, no relaxation.
    Generalized,
}

impl Choice for Variant {
    const WHAT: &'static str = "ChainMail variant";
    const ALL: &'static [Self] = &[Variant::Tsve, Variant::Generalized];
    fn name(self) -> &'static str {
        match self {
            Variant::Tsve => "tsve",
            Variant::Generalized => "generalized",
        }
    }
}
impl_choice!(Variant);

/// A region of a heterogeneous ChainMail body (`[[chainmail.material]]`): elements whose
/// rest position lies in the box take these limits.
#[derive(Clone, Debug, PartialEq)]
pub struct MaterialRegion {
    /// Lowest corner of the box.
    pub min: Vec3,
    /// Highest corner of the box.
    pub max: Vec3,
    /// Compression limit per axis (`0 < alpha_min <= 1`).
    pub alpha_min: Vec3,
    /// Stretch limit per axis (`alpha_max >= 1`).
    pub alpha_max: Vec3,
}

/// The `[chainmail]` section.
#[derive(Clone, Debug, PartialEq)]
pub struct ChainmailSettings {
    /// The scene's preferred variant.
    pub variant: Variant,
    /// Lattice spacing; `None`: [`DEFAULT_SPACING_FRACTION`] of the longest side of the
    /// body's bounding box.
    pub spacing: Option<f64>,
    /// Compression limit per axis: a link may shrink to `alpha_min` times its rest length.
    pub alpha_min: Vec3,
    /// Stretch limit per axis: a link may stretch to `alpha_max` times its rest length.
    pub alpha_max: Vec3,
    /// Shear limit per axis of Generalized ChainMail (`beta` times the rest distance across).
    pub beta: Vec3,
    /// Use the time-saving scheme where the paper proves it exact (homogeneous TSVE material,
    /// one displacement for all sponsors); `false`: always the exhaustive scheme.
    pub tss: bool,
    /// Relaxation sweeps per frame (TSVE only).
    pub relaxation: usize,
    /// Heterogeneous regions, later ones over earlier ones (TSVE only).
    pub regions: Vec<MaterialRegion>,
}

/// The default spacing as a fraction of the longest side of the bounding box.
pub const DEFAULT_SPACING_FRACTION: f64 = 1.0 / 12.0;

/// Default relaxation sweeps per frame.
pub const DEFAULT_RELAXATION: usize = 50;

/// The largest number of relaxation sweeps per frame a scene may ask for.
pub const MAX_RELAXATION: usize = 100_000;

impl Default for ChainmailSettings {
    /// TSVE, spacing 1/12 of the longest side, `alpha_min = 0.8`, `alpha_max = 1.2`,
    /// `beta = 0.2`, time-saving scheme on, 50 relaxation sweeps per frame, homogeneous.
    fn default() -> Self {
        Self {
            variant: Variant::Tsve,
            spacing: None,
            alpha_min: [0.8; 3],
            alpha_max: [1.2; 3],
            beta: [0.2; 3],
            tss: true,
            relaxation: DEFAULT_RELAXATION,
            regions: Vec::new(),
        }
    }
}

impl ChainmailSettings {
    /// The lattice spacing for a body with these rest positions.
    pub fn spacing_for(&self, positions: &[Vec3]) -> f64 {
        self.spacing.unwrap_or_else(|| {
            let (lo, hi) = fibfluid_geometry::bounding_box(positions);
            let longest = (0..3).map(|a| hi[a] - lo[a]).fold(0.0, f64::max);
            if longest > 0.0 { longest * DEFAULT_SPACING_FRACTION } else { 1.0 }
        })
    }

    /// The Generalized material: `alpha_min`, `alpha_max`, `beta` per axis (regions are
    /// refused for this variant when the scene is read).
    pub fn generalized_material(&self) -> GeneralizedMaterial {
        GeneralizedMaterial { alpha_min: self.alpha_min, alpha_max: self.alpha_max, beta: self.beta }
    }

    /// The TSVE material of a lattice whose elements rest at `rest`: per axis
    /// `alpha = (alpha_max - alpha_min) / 2`, the half-width of the allowed stretch range
    /// (TSVE's bounding region is symmetric about the rest offset), region by region.
    pub fn tsve_material(&self, rest: &[Vec3]) -> TsveMaterial {
        let half = |lo: Vec3, hi: Vec3| [0.5 * (hi[0] - lo[0]), 0.5 * (hi[1] - lo[1]), 0.5 * (hi[2] - lo[2])];
        let base = half(self.alpha_min, self.alpha_max);
        let alpha = rest
            .iter()
            .map(|p| {
                let mut a = base;
                for r in &self.regions {
                    if (0..3).all(|c| p[c] >= r.min[c] && p[c] <= r.max[c]) {
                        a = half(r.alpha_min, r.alpha_max);
                    }
                }
                a
            })
            .collect();
        TsveMaterial { alpha }
    }
}

#[derive(Deserialize)]
#[serde(untagged, expecting = "expected a number or an array of three numbers [x, y, z]")]
pub(crate) enum PerAxis {
    One(f64),
    Three([f64; 3]),
}

impl PerAxis {
    fn get(self) -> Vec3 {
        match self {
            PerAxis::One(v) => [v; 3],
            PerAxis::Three(v) => v,
        }
    }
}

/// `[chainmail]` as written.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct ChainmailToml {
    variant: Option<String>,
    spacing: Option<f64>,
    alpha_min: Option<PerAxis>,
    alpha_max: Option<PerAxis>,
    beta: Option<PerAxis>,
    tss: Option<bool>,
    relaxation: Option<i64>,
    #[serde(default)]
    material: Vec<RegionToml>,
}

/// `[[chainmail.material]]` as written.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RegionToml {
    #[serde(rename = "box")]
    bbox: [[f64; 3]; 2],
    alpha_min: Option<PerAxis>,
    alpha_max: Option<PerAxis>,
}

fn check_alphas(key: &str, lo: Vec3, hi: Vec3) -> Result<(), Invalid> {
    for c in 0..3 {
        let axis = ['x', 'y', 'z'][c];
        if !(lo[c].is_finite() && lo[c] > 0.0 && lo[c] <= 1.0) {
            return Err(range(format!("{key}.alpha_min"), "in (0, 1]", format!("{} along {axis}", lo[c])));
        }
        if !(hi[c].is_finite() && hi[c] >= 1.0) {
            return Err(range(
                format!("{key}.alpha_max"),
                ">= 1 and finite",
                format!("{} along {axis}", hi[c]),
            ));
        }
    }
    Ok(())
}

/// Checks `[chainmail]` against the body (`positions`, the rest surface) and the memory:
/// a lattice that would not fit in `budget` bytes is refused before anything is
/// allocated.
pub(crate) fn parse(
    spec: Option<ChainmailToml>,
    positions: &[Vec3],
    budget: u64,
) -> Result<ChainmailSettings, Invalid> {
    let mut s = ChainmailSettings::default();
    let Some(t) = spec else { return Ok(s) };
    const KEY: &str = "[chainmail]";
    s.variant = choice(&format!("{KEY}.variant"), t.variant, s.variant)?;
    if let Some(h) = t.spacing {
        if !(h.is_finite() && h > 0.0) {
            return Err(range(format!("{KEY}.spacing"), "positive", h));
        }
        s.spacing = Some(h);
    }
    s.alpha_min = t.alpha_min.map(PerAxis::get).unwrap_or(s.alpha_min);
    s.alpha_max = t.alpha_max.map(PerAxis::get).unwrap_or(s.alpha_max);
    check_alphas(KEY, s.alpha_min, s.alpha_max)?;
    if let Some(b) = t.beta {
        s.beta = b.get();
        if let Some(b) = s.beta.iter().find(|b| !(b.is_finite() && **b >= 0.0)) {
            return Err(range(format!("{KEY}.beta"), ">= 0", b));
        }
    }
    s.tss = t.tss.unwrap_or(s.tss);
    if let Some(r) = t.relaxation {
        if !(0..=MAX_RELAXATION as i64).contains(&r) {
            return Err(range(format!("{KEY}.relaxation"), "between 0 and 100000", r));
        }
        s.relaxation = r as usize;
    }
    for (k, r) in t.material.into_iter().enumerate() {
        let key = format!("[[chainmail.material]] #{}", k + 1);
        let [lo, hi] = r.bbox;
        if lo.iter().chain(&hi).any(|v| !v.is_finite()) || (0..3).any(|c| lo[c] > hi[c]) {
            return Err(range(
                format!("{key}.box"),
                "finite, [[min x, y, z], [max x, y, z]] with min <= max",
                format!("{:?}", r.bbox),
            ));
        }
        let region = MaterialRegion {
            min: lo,
            max: hi,
            alpha_min: r.alpha_min.map(PerAxis::get).unwrap_or(s.alpha_min),
            alpha_max: r.alpha_max.map(PerAxis::get).unwrap_or(s.alpha_max),
        };
        check_alphas(&key, region.alpha_min, region.alpha_max)?;
        s.regions.push(region);
    }
    if s.variant == Variant::Generalized && !s.regions.is_empty() {
        return Err(invalid(
            "[[chainmail.material]]",
            SceneProblem::Conflict(
                "material regions need variant = \"tsve\" (Generalized ChainMail has one material)",
            ),
        ));
    }
    let h = s.spacing_for(positions);
    let (lo, hi) = fibfluid_geometry::bounding_box(positions);
    let too_large = |bytes: u128| {
        invalid(
            format!("{KEY}.spacing"),
            SceneProblem::ChainmailLatticeTooLarge { spacing: h, bytes, available: budget },
        )
    };
    match EmbeddingGrid::for_box(lo, hi, h) {
        Ok(grid) => {
            let bytes = grid.bytes_upper_bound(positions.len());
            if bytes > budget as u128 {
                return Err(too_large(bytes));
            }
        }
        Err(_) => {
            // More grid nodes than the lattice can index: the bytes by the box alone.
            let nodes: u128 = (0..3).map(|a| ((hi[a] - lo[a]) / h).ceil().max(1.0) as u128 + 2).product();
            return Err(too_large(
                nodes * (fibfluid_chainmail::BYTES_PER_NODE + fibfluid_chainmail::BYTES_PER_ELEMENT) as u128,
            ));
        }
    }
    Ok(s)
}
