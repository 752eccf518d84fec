//! ChainMail's settings (the `[chainmail]` section of a scene, or built in code): how the
//! ChainMail methods voxelize and deform a body. The scene crate reads them; the checks
//! live here, once.

use fibfluid_chainmail::{EmbeddingGrid, GeneralizedMaterial, TsveMaterial, alpha_limits_problem};
use fibfluid_geometry::Vec3;
use fibfluid_linalg::{Choice, impl_choice};
use fibfluid_sim::Method;

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

impl Variant {
    /// The variant a ChainMail [`Method`] runs (`None` for the other methods).
    pub fn of_method(method: Method) -> Option<Self> {
        match method {
            Method::TsveChainmail => Some(Variant::Tsve),
            Method::GeneralizedChainmail => Some(Variant::Generalized),
            Method::Ffm | Method::Fem => None,
        }
    }
}

/// A ChainMail setting out of its range: the key (`alpha_min`, `spacing`, ...), the region
/// (0-based, `None` for the section itself), the rule and the value as written.
#[derive(Clone, Debug, PartialEq)]
pub struct SettingProblem {
    /// The key.
    pub key: &'static str,
    /// The material region, when the key belongs to one.
    pub region: Option<usize>,
    /// The rule the value breaks.
    pub rule: &'static str,
    /// The value, as it will be printed.
    pub value: String,
}

impl ChainmailSettings {
    /// Checks every value (limits, spacing, shear, relaxation, regions), the one check of
    /// these settings whether they come from a file or from code.
    pub fn check(&self) -> Result<(), SettingProblem> {
        let problem = |key, region, rule, value: String| Err(SettingProblem { key, region, rule, value });
        if let Some(h) = self.spacing
            && !(h.is_finite() && h > 0.0)
        {
            return problem("spacing", None, "positive", h.to_string());
        }
        let limits = |lo, hi, region| match alpha_limits_problem(lo, hi) {
            Some(p) => problem(
                p.name,
                region,
                p.rule,
                format!("{} along {}", p.value, fibfluid_geometry::AXES[p.axis]),
            ),
            None => Ok(()),
        };
        limits(self.alpha_min, self.alpha_max, None)?;
        if let Some(b) = self.beta.iter().find(|b| !(b.is_finite() && **b >= 0.0)) {
            return problem("beta", None, ">= 0", b.to_string());
        }
        if self.relaxation > MAX_RELAXATION {
            return problem("relaxation", None, "between 0 and 100000", self.relaxation.to_string());
        }
        for (k, r) in self.regions.iter().enumerate() {
            if r.min.iter().chain(&r.max).any(|v| !v.is_finite()) || (0..3).any(|c| r.min[c] > r.max[c]) {
                let value = format!("{:?}", [r.min, r.max]);
                return problem(
                    "box",
                    Some(k),
                    "finite, [[min x, y, z], [max x, y, z]] with min <= max",
                    value,
                );
            }
            limits(r.alpha_min, r.alpha_max, Some(k))?;
        }
        Ok(())
    }

    /// An upper bound of the bytes a ChainMail body of these rest positions needs (every
    /// grid node an element), computed from counts before anything is allocated.
    pub fn lattice_bytes(&self, positions: &[Vec3]) -> u128 {
        let h = self.spacing_for(positions);
        let (lo, hi) = fibfluid_geometry::bounding_box(positions);
        match EmbeddingGrid::for_box(lo, hi, h) {
            Ok(grid) => grid.bytes_upper_bound(positions.len()),
            // More grid nodes than the lattice can index: the bytes by the box alone.
            Err(_) => {
                let nodes: u128 = (0..3).map(|a| ((hi[a] - lo[a]) / h).ceil().max(1.0) as u128 + 2).product();
                nodes * (fibfluid_chainmail::BYTES_PER_NODE + fibfluid_chainmail::BYTES_PER_ELEMENT) as u128
            }
        }
    }
}
