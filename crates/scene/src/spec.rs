//! The scene file as written: serde structs of every table and key, before validation.

use fibfluid_geometry::Vec3;
use serde::Deserialize;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct SceneToml {
    pub(crate) mesh: Option<MeshToml>,
    pub(crate) polygon: Option<PolygonToml>,
    pub(crate) material: Option<MaterialToml>,
    pub(crate) ffm: Option<FfmToml>,
    pub(crate) tissue: Option<TissueToml>,
    pub(crate) fem: Option<FemToml>,
    pub(crate) fluid: Option<FluidToml>,
    pub(crate) load: Option<LoadToml>,
    pub(crate) gravity: Option<GravityToml>,
    #[serde(default)]
    pub(crate) fix: Vec<FixToml>,
    #[serde(default)]
    pub(crate) force: Vec<ForceToml>,
    pub(crate) solver: Option<SolverToml>,
    pub(crate) guards: Option<GuardsToml>,
    #[serde(default)]
    pub(crate) plate: Vec<PlateToml>,
    #[serde(default)]
    pub(crate) grasp: Vec<GraspToml>,
    #[serde(default)]
    pub(crate) pressure: Vec<crate::pressure_table::PressureToml>,
    pub(crate) chainmail: Option<ChainmailToml>,
    #[serde(default)]
    pub(crate) region: Vec<TissueRegionToml>,
    pub(crate) time: Option<TimeToml>,
    pub(crate) fit: Option<FitToml>,
}

/// `[fit]` as written: the parameters to fit, their bounds and the observed file.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct FitToml {
    pub(crate) parameters: Vec<String>,
    pub(crate) bounds: Vec<[f64; 2]>,
    pub(crate) observed: String,
}

/// `[time]` as written: a run through time (finite-element method only).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct TimeToml {
    pub(crate) end: f64,
    pub(crate) step: f64,
    pub(crate) inertia: Option<bool>,
    pub(crate) damping: Option<[f64; 2]>,
    pub(crate) output_every: Option<f64>,
}

/// `[[tissue.relaxation]]` as written: one Prony term.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct PronyToml {
    pub(crate) g: f64,
    pub(crate) tau: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct TissueRegionToml {
    pub(crate) name: Option<String>,
    pub(crate) mesh: Option<String>,
    pub(crate) r#box: Option<BoxToml>,
    /// A label of `[mesh].image`: the region is that label's surface.
    pub(crate) label: Option<i64>,
    pub(crate) tissue: TissueToml,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct BoxToml {
    pub(crate) min: [f64; 3],
    pub(crate) max: [f64; 3],
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct PlateToml {
    pub(crate) point: [f64; 3],
    pub(crate) normal: [f64; 3],
    #[serde(default)]
    pub(crate) travel: f64,
    /// The contact force that drives the plate instead of `travel` (N).
    pub(crate) force: Option<f64>,
}

/// `[[grasp]]` as written: the patch's centre vertex and radius, and its rigid motion.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct GraspToml {
    pub(crate) vertex: i64,
    pub(crate) radius: f64,
    pub(crate) translation: [f64; 3],
    pub(crate) rotation: Option<[f64; 3]>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct MeshToml {
    pub(crate) path: Option<String>,
    pub(crate) scale: Option<f64>,
    pub(crate) unit: Option<String>,
    /// A NIfTI label image (`.nii`, `.nii.gz`) whose label surface is the body.
    pub(crate) image: Option<String>,
    /// With `image`: the label (default: every non-zero label, the whole body).
    pub(crate) label: Option<i64>,
    /// With `image`: at most this many vertices (decimation, see `extract_surface`).
    pub(crate) vertices: Option<i64>,
    /// With `image`: blur the label mask 3x3x3 before extraction.
    pub(crate) smooth: Option<bool>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct TissueToml {
    pub(crate) young: f64,
    pub(crate) poisson: f64,
    pub(crate) density: Option<f64>,
    pub(crate) model: Option<String>,
    #[serde(default)]
    pub(crate) relaxation: Vec<PronyToml>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct FemToml {
    pub(crate) resolution: Option<i64>,
    pub(crate) solver: Option<String>,
    pub(crate) tolerance: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct PolygonToml {
    pub(crate) points: Vec<[f64; 2]>,
}

/// A fiber modulus as written: one for every axis, or one per axis.
#[derive(Clone, Copy, Deserialize)]
#[serde(untagged, expecting = "expected a number or an array of three numbers [x, y, z]")]
pub(crate) enum FiberModulusToml {
    One(f64),
    Three([f64; 3]),
}

/// `[material]`, the older name of `[ffm]`'s fiber keys: the fiber modulus is `young` there.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct MaterialToml {
    #[serde(rename = "young")]
    pub(crate) fiber_modulus: FiberModulusToml,
    #[serde(default)]
    pub(crate) surface_tension: f64,
    /// Quadratic stiffening coefficient c: Y (1 + c strain^2).
    pub(crate) stiffening: Option<f64>,
}

/// `[ffm]`: the fiber–fluid method's fibers (the newer name of `[material]`'s keys, plus
/// the fiber model).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct FfmToml {
    pub(crate) fiber_modulus: Option<FiberModulusToml>,
    /// The older name of `fiber_modulus`.
    pub(crate) young: Option<FiberModulusToml>,
    pub(crate) surface_tension: Option<f64>,
    pub(crate) stiffening: Option<f64>,
    pub(crate) fibers: Option<String>,
    /// Bulk weights fall as `1 / d^p` (the paper's p = 1).
    pub(crate) kernel_exponent: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct FluidToml {
    pub(crate) density: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct LoadToml {
    pub(crate) steps: Option<i64>,
    pub(crate) tolerance: Option<f64>,
    /// `[[time, factor], ...]`: the load factor through a timed run.
    pub(crate) curve: Option<Vec<[f64; 2]>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct GuardsToml {
    pub(crate) on_failure: Option<String>,
    pub(crate) volume: Option<f64>,
    pub(crate) increment: Option<f64>,
    pub(crate) inverted: Option<i64>,
    pub(crate) residual: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct GravityToml {
    pub(crate) acceleration: [f64; 3],
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct FixToml {
    pub(crate) axis: Option<String>,
    pub(crate) above: Option<f64>,
    pub(crate) below: Option<f64>,
    pub(crate) top: Option<f64>,
    pub(crate) bottom: Option<f64>,
    pub(crate) vertices: Option<Vec<i64>>,
    #[serde(rename = "box")]
    pub(crate) bbox: Option<[[f64; 3]; 2]>,
    pub(crate) dofs: Option<Vec<String>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct ForceToml {
    pub(crate) vertex: i64,
    pub(crate) value: [f64; 3],
    pub(crate) at: Option<String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct SolverToml {
    pub(crate) backend: Option<String>,
    pub(crate) mode: Option<String>,
    pub(crate) stepping: Option<String>,
    pub(crate) precision: Option<String>,
    pub(crate) constraints: Option<String>,
    pub(crate) penalty: Option<f64>,
    pub(crate) method: Option<String>,
}

#[derive(Deserialize)]
#[serde(untagged, expecting = "expected a number or an array of three numbers [x, y, z]")]
pub(crate) enum PerAxis {
    One(f64),
    Three([f64; 3]),
}

impl PerAxis {
    pub(crate) fn get(self) -> Vec3 {
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
    pub(crate) variant: Option<String>,
    pub(crate) spacing: Option<f64>,
    pub(crate) alpha_min: Option<PerAxis>,
    pub(crate) alpha_max: Option<PerAxis>,
    pub(crate) beta: Option<PerAxis>,
    pub(crate) tss: Option<bool>,
    pub(crate) relaxation: Option<i64>,
    #[serde(default)]
    pub(crate) material: Vec<RegionToml>,
}

/// `[[chainmail.material]]` as written.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RegionToml {
    #[serde(rename = "box")]
    pub(crate) bbox: [[f64; 3]; 2],
    pub(crate) alpha_min: Option<PerAxis>,
    pub(crate) alpha_max: Option<PerAxis>,
}
