//! The cases, their resolutions and tolerances, and the rows of the table.

use fibfluid_fem::hyper::NewtonSettings;
use fibfluid_fem::{FemError, FemSolver, Tissue, TissueModel};
use serde::Serialize;

use crate::bodies;
use crate::closed_form as exact;

/// Which resolutions a case runs at: `Quick` (coarse, for `--quick` and the README's tests)
/// or `Full` (the defaults the tolerances are stated for).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Speed {
    /// Coarse grids: the whole suite in about a minute.
    Quick,
    /// The case's default resolution and twice it.
    Full,
}

/// One measurement against its reference.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Outcome {
    /// What fibfluid computed.
    pub value: f64,
    /// The reference value.
    pub reference: f64,
}

impl Outcome {
    /// `|value / reference - 1|`.
    pub fn error(&self) -> f64 {
        (self.value / self.reference - 1.0).abs()
    }
}

/// A case of the suite.
#[derive(Debug, Clone, Copy)]
pub struct Case {
    /// Short name (`fibfluid validate --case NAME`).
    pub name: &'static str,
    /// What is compared, with its unit.
    pub quantity: &'static str,
    /// Where the reference comes from.
    pub source: &'static str,
    /// Resolution of `Speed::Quick` (the finer run is twice it); 0: not in the quick suite.
    pub quick: usize,
    /// Resolution of `Speed::Full`.
    pub full: usize,
    /// The largest relative error allowed at twice the resolution, quick and full.
    pub tolerance: [f64; 2],
    evaluate: fn(usize) -> Result<Outcome, CaseError>,
}

/// Why a case has no outcome.
#[derive(Debug)]
pub enum CaseError {
    /// The finite-element method failed.
    Fem(FemError),
    /// The solver returned an equilibrium past the reference's limit point, where none exists.
    PassedLimitPoint {
        /// The pressure applied over the limit pressure.
        applied: f64,
    },
}

impl std::fmt::Display for CaseError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            CaseError::Fem(e) => write!(f, "{e}"),
            CaseError::PassedLimitPoint { applied } => write!(
                f,
                "converged at {applied} times the limit pressure, where the closed form has no equilibrium"
            ),
        }
    }
}

impl std::error::Error for CaseError {}

impl From<FemError> for CaseError {
    fn from(e: FemError) -> Self {
        CaseError::Fem(e)
    }
}

/// A case's row in the table: the reference and fibfluid at two resolutions.
#[derive(Debug, Clone, Serialize)]
pub struct Row {
    /// The case's name.
    pub case: &'static str,
    /// What is compared.
    pub quantity: &'static str,
    /// The reference's source.
    pub source: &'static str,
    /// The two resolutions.
    pub resolutions: [usize; 2],
    /// The two outcomes (`None`: the run failed; see `failure`).
    pub outcomes: [Option<Outcome>; 2],
    /// The tolerance at the finer resolution.
    pub tolerance: f64,
    /// Why a run failed, if one did.
    pub failure: Option<String>,
    /// Whether the finer run is within the tolerance.
    pub passed: bool,
    /// Seconds spent on the two runs.
    pub seconds: f64,
}

impl Case {
    /// The case's two resolutions at `speed`.
    pub fn resolutions(&self, speed: Speed) -> [usize; 2] {
        let r = if speed == Speed::Quick { self.quick } else { self.full };
        [r, 2 * r]
    }

    /// Runs the case at both resolutions of `speed`.
    pub fn check(&self, speed: Speed) -> Row {
        let start = std::time::Instant::now();
        let resolutions = self.resolutions(speed);
        let mut failure = None;
        let outcomes = resolutions.map(|r| match run_case(self, r) {
            Ok(o) => Some(o),
            Err(e) => {
                failure.get_or_insert_with(|| format!("resolution {r}: {e}"));
                None
            }
        });
        let tolerance = self.tolerance[(speed == Speed::Full) as usize];
        let passed = outcomes[1].is_some_and(|o| o.error() <= tolerance);
        Row {
            case: self.name,
            quantity: self.quantity,
            source: self.source,
            resolutions,
            outcomes,
            tolerance,
            failure,
            passed,
            seconds: start.elapsed().as_secs_f64(),
        }
    }
}

/// Runs `case` at `resolution`.
///
/// Errors: the finite-element method's (a Newton failure is the usual one).
pub fn run_case(case: &Case, resolution: usize) -> Result<Outcome, CaseError> {
    (case.evaluate)(resolution)
}

/// The neo-Hookean tissue of the homogeneous cases and the cantilever (E = 5 kPa).
fn tissue(poisson: f64) -> Tissue {
    Tissue::new(5000.0, poisson, 0.0).expect("a valid tissue").with_model(TissueModel::NeoHookean)
}

/// The nominal stress of the pulled cubes, in units of `mu`.
const PULL: f64 = 0.5;
/// The thick sphere's radii and surface subdivision (level 4: vertices about half a cell
/// apart at resolution 24; level 3's, a cell apart, load the grid in points: 2.0 % off at
/// a stretch of 1.5, against 1.1 %).
const SPHERE: (f64, f64, u32) = (1.0, 2.0, 4);
/// The thick sphere's Poisson's ratio (the closed form is incompressible).
const SPHERE_POISSON: f64 = 0.499;
/// The pressure applied to find the thick sphere's limit point, over the closed form's.
const LIMIT_OVERSHOOT: f64 = 1.3;
/// The smallest load increment of the limit-point run: the limit pressure is found to
/// within this fraction of the pressure applied.
const LIMIT_INCREMENT: f64 = 1.0 / 256.0;
/// The cantilever's length over its thickness.
const SLENDERNESS: usize = 16;
/// Hertz's sphere: radius, subdivision, and each plate's approach over the radius.
const HERTZ: (f64, u32, f64) = (1.0, 5, 0.04);

fn pulled(loaded: usize, resolution: usize) -> Result<Outcome, CaseError> {
    let t = tissue(0.45);
    let p = PULL * t.shear_modulus();
    let value = bodies::pulled_cube(&t, resolution, loaded, p)?;
    let reference = exact::stretch_under_nominal_stress(t.shear_modulus(), t.bulk_modulus(), loaded, p);
    Ok(Outcome { value, reference })
}

fn sheared(_resolution: usize) -> Result<Outcome, CaseError> {
    let (t, gamma) = (tissue(0.45), 0.5);
    let value = bodies::sheared_cell(&t, gamma);
    Ok(Outcome { value, reference: exact::simple_shear_stress(t.shear_modulus(), gamma) })
}

/// The thick sphere's Newton settings: the direct solver, whose steps include the follower
/// pressure's coupling of face corners in different cells (the multigrid's operator is the
/// grid's and leaves it out: its steps are inexact, and Newton then converges slowly).
fn sphere_newton() -> NewtonSettings {
    NewtonSettings { solver: FemSolver::Direct, ..NewtonSettings::default() }
}

fn inflated(stretch: f64, resolution: usize) -> Result<Outcome, CaseError> {
    let t = tissue(SPHERE_POISSON);
    let (a, b, _) = SPHERE;
    let p = exact::thick_sphere_pressure(t.shear_modulus(), stretch, a, b);
    let value = bodies::inflated_sphere(&t, SPHERE, resolution, p, sphere_newton())?;
    Ok(Outcome { value, reference: stretch })
}

/// The thick cylinder's radii.
const CYLINDER: (f64, f64) = (1.0, 2.0);

fn inflated_tube(stretch: f64, resolution: usize) -> Result<Outcome, CaseError> {
    let t = tissue(SPHERE_POISSON);
    let (a, b) = CYLINDER;
    // The dead load on the rest surface that is the closed form's pressure at `stretch` on
    // the deformed one.
    let nominal = stretch * exact::thick_cylinder_pressure(t.shear_modulus(), stretch, a, b);
    let value = bodies::inflated_cylinder(&t, CYLINDER, resolution, nominal)?;
    Ok(Outcome { value, reference: stretch })
}

/// The thick sphere loaded past its limit point (`LIMIT_OVERSHOOT` times the closed form's
/// largest pressure): Newton's method must fail (load stepping cannot pass a limit point),
/// and the load factor it reached, times the pressure applied, estimates the discrete
/// body's limit pressure.
fn limit_point(resolution: usize) -> Result<Outcome, CaseError> {
    let t = tissue(SPHERE_POISSON);
    let (a, b, _) = SPHERE;
    let top = exact::thick_sphere_pressure(t.shear_modulus(), exact::thick_sphere_limit_stretch(a, b), a, b);
    let applied = LIMIT_OVERSHOOT * top;
    // Fewer halvings and iterations than a run's defaults: past the limit point every
    // attempt fails, and the aimed load is known to within the smallest increment.
    let newton = NewtonSettings { min_increment: LIMIT_INCREMENT, max_iterations: 12, ..sphere_newton() };
    match bodies::inflated_sphere(&t, SPHERE, resolution, applied, newton) {
        Ok(_) => Err(CaseError::PassedLimitPoint { applied: LIMIT_OVERSHOOT }),
        Err(FemError::NotConverged { load, .. }) => Ok(Outcome { value: load * applied, reference: top }),
        Err(e) => Err(e.into()),
    }
}

fn cantilever(alpha: f64, resolution: usize) -> Result<Outcome, CaseError> {
    let [deflection, _] = bodies::bent_cantilever(&tissue(0.3), SLENDERNESS, resolution, alpha)?;
    Ok(Outcome { value: deflection, reference: exact::elastica_tip(alpha)[0] })
}

fn hertz(resolution: usize) -> Result<Outcome, CaseError> {
    let t = Tissue::new(5000.0, 0.3, 0.0).expect("a valid tissue");
    let (r, level, depth) = HERTZ;
    let value = bodies::pressed_sphere(&t, (r, level), resolution, depth * r)?;
    Ok(Outcome { value, reference: exact::hertz_force(t.young(), t.poisson(), r, depth * r) })
}

/// Cook's membrane (de Souza Neto et al. 1996; Elguedj et al. 2008): G = 80.1938 MPa and
/// nu = 0.499 (E = 240.565 MPa), a shear traction of 6.25 MPa (100 N per mm of depth over
/// the 16 mm edge); the panel 3 mm deep (a whole number of cells at resolutions 20, 40, 80);
/// its surface lattice.
const COOK: (f64, f64, (f64, f64), (usize, usize)) = (240.565e6, 0.499, (3e-3, 6.25e6), (96, 4));
/// The corner's vertical displacement (m): OpenGeoSys's large-deformation benchmark with
/// F-bar quadrilaterals at 30 elements per side (6.891 mm, rising by 0.02 mm per
/// refinement: 6.859, 6.873, 6.891 at 20, 25, 30), the convergence Elguedj et al. (2008)
/// show.
const COOK_REFERENCE: f64 = 6.891e-3;

fn cook(resolution: usize) -> Result<Outcome, CaseError> {
    let (young, poisson, load, lattice) = COOK;
    let t = Tissue::new(young, poisson, 0.0).expect("a valid tissue").with_model(TissueModel::NeoHookean);
    let value = bodies::cooks_membrane(&t, resolution, load, lattice)?;
    Ok(Outcome { value, reference: COOK_REFERENCE })
}

/// The cases `speed` runs, in the table's order.
pub fn cases_at(speed: Speed) -> Vec<Case> {
    cases().into_iter().filter(|c| speed == Speed::Full || c.quick > 0).collect()
}

/// Every case, in the table's order.
pub fn cases() -> Vec<Case> {
    const CLOSED: &str = "closed form of the neo-Hookean energy";
    const OGDEN: &str = "Ogden 1984, §5.3 (incompressible)";
    const OGDEN_PLANE: &str = "Ogden 1984, §5.3 (incompressible, plane strain)";
    const ELASTICA: &str = "elastica (Bisshopp & Drucker 1945), shot numerically";
    let case = |name, quantity, source, quick, full, tolerance, evaluate| Case {
        name,
        quantity,
        source,
        quick,
        full,
        tolerance,
        evaluate,
    };
    vec![
        case("uniaxial", "stretch at P = mu/2", CLOSED, 2, 4, [1e-3, 1e-3], |r| pulled(1, r)),
        case("equibiaxial", "stretch at P = mu/2", CLOSED, 2, 4, [1e-3, 1e-3], |r| pulled(2, r)),
        case("shear", "P_xy at gamma = 0.5 (Pa, one cell)", CLOSED, 1, 1, [1e-9, 1e-9], sheared),
        case("sphere-1.1", "inner stretch at p(1.1)", OGDEN, 8, 12, [0.04, 0.005], |r| inflated(1.1, r)),
        case("sphere-1.2", "inner stretch at p(1.2)", OGDEN, 8, 12, [0.04, 0.005], |r| inflated(1.2, r)),
        case("sphere-1.3", "inner stretch at p(1.3)", OGDEN, 8, 12, [0.04, 0.008], |r| inflated(1.3, r)),
        case("sphere-1.4", "inner stretch at p(1.4)", OGDEN, 8, 12, [0.04, 0.01], |r| inflated(1.4, r)),
        case("sphere-1.5", "inner stretch at p(1.5)", OGDEN, 8, 12, [0.04, 0.015], |r| inflated(1.5, r)),
        case("cylinder-1.1", "inner stretch at p(1.1)", OGDEN_PLANE, 8, 12, [0.01, 0.005], |r| {
            inflated_tube(1.1, r)
        }),
        case("cylinder-1.2", "inner stretch at p(1.2)", OGDEN_PLANE, 8, 12, [0.01, 0.005], |r| {
            inflated_tube(1.2, r)
        }),
        case("cylinder-1.3", "inner stretch at p(1.3)", OGDEN_PLANE, 8, 12, [0.01, 0.005], |r| {
            inflated_tube(1.3, r)
        }),
        case("cylinder-1.4", "inner stretch at p(1.4)", OGDEN_PLANE, 8, 12, [0.01, 0.005], |r| {
            inflated_tube(1.4, r)
        }),
        case("cylinder-1.5", "inner stretch at p(1.5)", OGDEN_PLANE, 8, 12, [0.01, 0.005], |r| {
            inflated_tube(1.5, r)
        }),
        case("sphere-limit", "limit pressure (Pa): Newton must stop", OGDEN, 0, 8, [0.06, 0.06], limit_point),
        case("cantilever-1", "tip deflection / L at PL^2/EI = 1", ELASTICA, 32, 64, [0.1, 0.02], |r| {
            cantilever(1.0, r)
        }),
        case("cantilever-10", "tip deflection / L at PL^2/EI = 10", ELASTICA, 32, 64, [0.1, 0.02], |r| {
            cantilever(10.0, r)
        }),
        case(
            "cook",
            "corner displacement (m), plane strain",
            "OpenGeoSys benchmark (F-bar, 30 x 30), after Elguedj et al. 2008",
            20,
            40,
            [0.1, 0.02],
            cook,
        ),
        case(
            "hertz",
            "plate force at depth 0.04 R (N)",
            "Hertz (Johnson 1985, §4.2)",
            12,
            24,
            [0.2, 0.15],
            hertz,
        ),
    ]
}
