//! `[[pressure]]`: a pressure on the outer surface, on a cavity or on the faces in a box
//! (finite-element method only).

use fibfluid_fem::hyper::Pressure;
use fibfluid_sim::{NamedPressure, Shape};
use serde::Deserialize;

use crate::error::SceneProblem;
use crate::invalid::{Invalid, invalid, range};

/// `[[pressure]]` as written.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct PressureToml {
    pub(crate) value: f64,
    pub(crate) surface: Option<String>,
    pub(crate) r#box: Option<[[f64; 3]; 2]>,
}

/// The scene's pressures on the body `shape` (positions in metres; a box is in the mesh's
/// unit, `metres` per unit); `fem`: the method is the finite-element method.
pub(crate) fn pressures(
    specs: &[PressureToml],
    shape: &Shape,
    metres: f64,
    fem: bool,
) -> Result<Vec<NamedPressure>, Invalid> {
    if specs.is_empty() {
        return Ok(Vec::new());
    }
    if !fem {
        let problem = "a pressure is a load of the finite-element method only: set [solver] method = \"fem\" with a [tissue] table";
        return Err(invalid("[[pressure]]", SceneProblem::Conflict(problem)));
    }
    let Shape::Surface(file) = shape else {
        let problem = "a pressure needs a surface mesh (the body is a 2D polygon)";
        return Err(invalid("[[pressure]]", SceneProblem::Conflict(problem)));
    };
    let mesh = &file.mesh;
    let shells = mesh.shells();
    let mut out = Vec::with_capacity(specs.len());
    for (k, p) in specs.iter().enumerate() {
        let key = format!("[[pressure]] #{}", k + 1);
        if !p.value.is_finite() {
            return Err(range(
                format!("{key}.value"),
                "finite (Pa; positive pushes into the material)",
                p.value,
            ));
        }
        let (surface, faces): (String, Vec<usize>) = match (&p.surface, &p.r#box) {
            (Some(_), Some(_)) => {
                let problem = "give a surface or a box, not both";
                return Err(invalid(format!("{key}.box"), SceneProblem::Conflict(problem)));
            }
            (None, None) => {
                let problem =
                    "give surface = \"outer\" or \"cavity K\", or a box = [[x0, y0, z0], [x1, y1, z1]]";
                return Err(invalid(key, SceneProblem::Conflict(problem)));
            }
            (Some(s), None) => {
                let shell = shell_of(s).ok_or_else(|| {
                    range(format!("{key}.surface"), "\"outer\" or \"cavity K\" (K from 1)", format!("{s:?}"))
                })?;
                if shell >= shells.len() {
                    let problem = SceneProblem::NoSuchCavity { cavity: shell, count: shells.len() - 1 };
                    return Err(invalid(format!("{key}.surface"), problem));
                }
                (s.trim().to_string(), shells[shell].faces.clone())
            }
            (None, Some([lo, hi])) => {
                if lo.iter().chain(hi).any(|c| !c.is_finite()) {
                    return Err(range(format!("{key}.box"), "finite", format!("{:?}", [lo, hi])));
                }
                let inside = |q: &[f64; 3]| (0..3).all(|a| q[a] >= lo[a] * metres && q[a] <= hi[a] * metres);
                let faces: Vec<usize> =
                    (0..mesh.n_faces()).filter(|&f| mesh.corners(f).iter().all(inside)).collect();
                if faces.is_empty() {
                    return Err(invalid(format!("{key}.box"), SceneProblem::EmptyPressureBox));
                }
                ("box".to_string(), faces)
            }
        };
        let faces = faces.iter().map(|&f| mesh.triangles()[f]).collect();
        out.push(NamedPressure { surface, pressure: Pressure { value: p.value, faces } });
    }
    Ok(out)
}

/// The shell `"outer"` (0) or `"cavity K"` (K) names.
fn shell_of(s: &str) -> Option<usize> {
    let s = s.trim();
    if s == "outer" {
        return Some(0);
    }
    let k: usize = s.strip_prefix("cavity")?.trim().parse().ok()?;
    (k >= 1).then_some(k)
}
