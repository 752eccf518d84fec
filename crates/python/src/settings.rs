//! A scene's settings by name: read as Python values, written with the checks a scene
//! file's keys get (the same ranges and the same choice parsers).

use fibfluid_assembly::{MaterialParameter, StiffnessLaw};
use fibfluid_scene::Scene;
use fibfluid_sim::{Backend, Choice, ConstraintKind, FiberModel, MAX_STEPS, Mode, Precision, Stepping};
use pyo3::IntoPyObjectExt;
use pyo3::prelude::*;
use pyo3::types::PyBool;

use crate::arrays::vec3;
use crate::error;

/// Every setting, in the order `Scene.settings` lists them.
pub(crate) const NAMES: &[&str] = &[
    "steps",
    "tolerance",
    "gravity",
    "fiber_modulus",
    "surface_tension",
    "density",
    "stiffening",
    "fibers",
    "kernel_exponent",
    "backend",
    "mode",
    "stepping",
    "precision",
    "constraints",
    "penalty",
];

/// The solver's settings (`Scene.solver`), a subset of [`NAMES`].
pub(crate) const SOLVER: &[&str] = &["backend", "mode", "stepping", "precision", "constraints", "penalty"];

/// Older names of settings, and the setting each names (a scene file's older keys).
pub(crate) const OLDER_NAMES: &[(&str, &str)] = &[("young", "fiber_modulus")];

/// The setting `name` names: itself, or the one an older name stands for.
fn current(name: &str) -> &str {
    OLDER_NAMES.iter().find(|(old, _)| *old == name).map_or(name, |&(_, new)| new)
}

fn unknown(name: &str) -> PyErr {
    error(format!("unknown setting `{name}` (known: {})", NAMES.join(", ")))
}

/// The value of setting `name`.
pub(crate) fn get(py: Python<'_>, scene: &Scene, name: &str) -> PyResult<Py<PyAny>> {
    let m = &scene.material;
    let s = &scene.solver;
    match current(name) {
        "steps" => scene.load.steps.into_py_any(py),
        "tolerance" => scene.load.tolerance.into_py_any(py),
        "gravity" => (scene.load.gravity[0], scene.load.gravity[1], scene.load.gravity[2]).into_py_any(py),
        "fiber_modulus" if m.fiber_modulus().iter().all(|&y| y == m.fiber_modulus()[0]) => {
            m.fiber_modulus()[0].into_py_any(py)
        }
        "fiber_modulus" => (m.fiber_modulus()[0], m.fiber_modulus()[1], m.fiber_modulus()[2]).into_py_any(py),
        "surface_tension" => m.surface_tension().into_py_any(py),
        "density" => m.density().into_py_any(py),
        "stiffening" => match m.law() {
            StiffnessLaw::Linear => None::<f64>.into_py_any(py),
            StiffnessLaw::Quadratic { c } => c.into_py_any(py),
            // Not from a scene file: a law given in code has no number to show.
            StiffnessLaw::Custom(_) => "custom".into_py_any(py),
        },
        "fibers" => scene.ffm.fibers.name().into_py_any(py),
        "kernel_exponent" => m.kernel_exponent().into_py_any(py),
        "backend" => s.backend.name().into_py_any(py),
        "mode" => s.mode.name().into_py_any(py),
        "stepping" => s.stepping.name().into_py_any(py),
        "precision" => s.precision.name().into_py_any(py),
        "constraints" => s.constraints.name().into_py_any(py),
        "penalty" => s.penalty.into_py_any(py),
        _ => Err(unknown(name)),
    }
}

/// A number (an int or a float, not a bool or a string).
fn number(v: &Bound<'_, PyAny>, name: &str) -> PyResult<f64> {
    if v.is_instance_of::<PyBool>() {
        return Err(error(format!("{name}: expected a number, got a bool")));
    }
    v.extract::<f64>().map_err(|_| error(format!("{name}: expected a number, got {}", type_name(v))))
}

fn type_name(v: &Bound<'_, PyAny>) -> String {
    v.get_type().name().map(|n| n.to_string()).unwrap_or_else(|_| "?".into())
}

/// Checks a number against a rule, as the scene file's ranges do.
fn checked(name: &str, value: f64, rule: &'static str, ok: bool) -> PyResult<f64> {
    if ok { Ok(value) } else { Err(error(format!("{name}: must be {rule}, got {value}"))) }
}

/// Checks a material parameter by the material's own rule ([`MaterialParameter::check`]).
fn material_value(name: &str, value: f64, parameter: MaterialParameter) -> PyResult<f64> {
    checked(name, value, parameter.rule(), parameter.accepts(value))
}

fn choice<T: Choice>(v: &Bound<'_, PyAny>, name: &str) -> PyResult<T> {
    let s: String =
        v.extract().map_err(|_| error(format!("{name}: expected a string, got {}", type_name(v))))?;
    T::parse_name(&s).map_err(|e| error(format!("{name}: {e}")))
}

/// Sets `name` to `v` on `scene`, with the checks of the scene file's key; on error the
/// scene is unchanged.
pub(crate) fn set(scene: &mut Scene, name: &str, v: &Bound<'_, PyAny>) -> PyResult<()> {
    let axes = if scene.is_surface() { 3 } else { 2 };
    let name = current(name);
    match name {
        "steps" => {
            let bad = || error(format!("steps: must be an integer between 1 and {MAX_STEPS}"));
            if v.is_instance_of::<PyBool>() {
                return Err(bad());
            }
            let n: i64 = v.extract().map_err(|_| bad())?;
            if !(1..=MAX_STEPS as i64).contains(&n) {
                return Err(error(format!("steps: must be between 1 and {MAX_STEPS}, got {n}")));
            }
            scene.load.steps = n as usize;
        }
        "tolerance" => {
            scene.load.tolerance = if v.is_none() {
                None
            } else {
                let t = number(v, name)?;
                Some(checked(name, t, "between 0 and 1", t.is_finite() && t > 0.0 && t < 1.0)?)
            };
        }
        "gravity" => scene.load.gravity = vec3(v, "gravity")?,
        "fiber_modulus" => {
            let fiber_modulus = match number(v, name) {
                Ok(y) => [y; 3],
                Err(_) => vec3(v, "fiber_modulus (a number or three numbers)")?,
            };
            for (axis, y) in fiber_modulus.iter().enumerate().take(axes) {
                let parameter = MaterialParameter::FiberModulus { axis };
                if !parameter.accepts(*y) {
                    let axis = fibfluid_geometry::AXES[axis];
                    let rule = parameter.rule();
                    return Err(error(format!("fiber_modulus: must be {rule}, got {y} along {axis}")));
                }
            }
            scene.material.set_fiber_modulus(fiber_modulus).map_err(|e| error(format!("{name}: {e}")))?;
        }
        "surface_tension" => {
            let g = number(v, name)?;
            scene
                .material
                .set_surface_tension(material_value(name, g, MaterialParameter::SurfaceTension)?)
                .map_err(|e| error(format!("{name}: {e}")))?;
        }
        "density" => {
            let d = number(v, name)?;
            scene
                .material
                .set_density(material_value(name, d, MaterialParameter::Density)?)
                .map_err(|e| error(format!("{name}: {e}")))?;
        }
        "stiffening" => {
            let law = if v.is_none() {
                StiffnessLaw::Linear
            } else {
                let c = number(v, name)?;
                StiffnessLaw::Quadratic { c: material_value(name, c, MaterialParameter::Stiffening)? }
            };
            scene.material.set_law(law).map_err(|e| error(format!("{name}: {e}")))?;
        }
        "fibers" => scene.ffm.fibers = choice::<FiberModel>(v, name)?,
        "kernel_exponent" => {
            let p = number(v, name)?;
            scene
                .material
                .set_kernel_exponent(material_value(name, p, MaterialParameter::KernelExponent)?)
                .map_err(|e| error(format!("{name}: {e}")))?;
        }
        "backend" => {
            let b: Backend = choice(v, name)?;
            b.solver().map_err(|e| error(format!("backend: {e}")))?;
            scene.solver.backend = b;
        }
        "mode" => scene.solver.mode = choice::<Mode>(v, name)?,
        "stepping" => scene.solver.stepping = choice::<Stepping>(v, name)?,
        "precision" => scene.solver.precision = choice::<Precision>(v, name)?,
        "constraints" => scene.solver.constraints = choice::<ConstraintKind>(v, name)?,
        "penalty" => {
            let p = number(v, name)?;
            scene.solver.penalty = checked(name, p, "positive", p.is_finite() && p > 0.0)?;
        }
        _ => return Err(unknown(name)),
    }
    Ok(())
}
