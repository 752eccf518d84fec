//! Fitting the tissues to what was measured (`[fit]`, `fibfluid fit`): the parameters a scene
//! names (a tissue's or a region's Young's modulus, Poisson's ratio or density, gravity's
//! size), the observed surface positions (`vertex,x,y,z`), and the parameters' values on a
//! model. The fit itself is [`crate::inverse_fit`].

use std::path::Path;

pub use fibfluid_fem::hyper::Parameter;
use fibfluid_geometry::{MeshFile, Vec3};

pub use crate::model::{FitParameter, FitSpec};
use crate::model::{Model, Shape};
use crate::{Error, Result};

/// One observed surface vertex.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Observation {
    /// The vertex (mesh index).
    pub vertex: usize,
    /// The vertex as the file numbers it (0-based, file order).
    pub file_vertex: usize,
    /// Its observed deformed position (m).
    pub position: Vec3,
}

/// A problem of the observed file at one line.
fn bad_row(path: &Path, line: usize, problem: String) -> Error {
    Error::FitInput { path: path.to_path_buf(), line: Some(line), problem }
}

/// Reads the observed positions `vertex,x,y,z` (a header line, blank lines and `#`
/// comments allowed; positions in the file's unit, `metres` metres each) for `model`'s
/// mesh (vertex indices in file order, 0-based).
///
/// Errors: an unreadable file, a row that is not four numbers, a vertex out of range or
/// unused, a vertex twice, no row ([`Error::FitInput`], with the line).
pub fn read_observed(model: &Model, path: &Path, metres: f64) -> Result<Vec<Observation>> {
    let Shape::Surface(file) = &model.shape else {
        return Err(Error::FitInput {
            path: path.into(),
            line: None,
            problem: "the body is not a mesh".into(),
        });
    };
    let bytes = fibfluid_geometry::read_file_limited(path, None).map_err(|e| Error::FitInput {
        path: path.into(),
        line: None,
        problem: e.to_string(),
    })?;
    let text = String::from_utf8_lossy(&bytes);
    let mut out: Vec<Observation> = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let line = raw.trim();
        if line.is_empty() || line.starts_with('#') || (out.is_empty() && line.starts_with("vertex")) {
            continue;
        }
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        if fields.len() != 4 {
            return Err(bad_row(path, i + 1, format!("{} fields, expected 4 (vertex,x,y,z)", fields.len())));
        }
        let v: usize = fields[0]
            .parse()
            .map_err(|_| bad_row(path, i + 1, format!("vertex `{}` is not an index", fields[0])))?;
        let mut p = [0.0; 3];
        for a in 0..3 {
            p[a] =
                fields[a + 1].parse::<f64>().ok().filter(|x| x.is_finite()).ok_or_else(|| {
                    bad_row(path, i + 1, format!("`{}` is not a finite number", fields[a + 1]))
                })? * metres;
        }
        let o = observation(file, v, p, &out).map_err(|problem| bad_row(path, i + 1, problem))?;
        out.push(o);
    }
    if out.is_empty() {
        return Err(Error::FitInput { path: path.into(), line: None, problem: "no observed vertex".into() });
    }
    Ok(out)
}

/// The observation of the file's vertex `v` (0-based, file order) at `position` (m) on the
/// mesh `file`, after the observations `earlier`, or why not (a vertex out of range or
/// unused, a vertex observed twice). [`read_observed`] and Python's `fibfluid.fit` read
/// their rows with it.
pub fn observation(
    file: &MeshFile,
    v: usize,
    position: Vec3,
    earlier: &[Observation],
) -> std::result::Result<Observation, String> {
    let count = file.file_vertex_count();
    let vertex = if v < count { file.from_file_index(v) } else { None }
        .ok_or_else(|| format!("vertex {v} is not a vertex of the mesh ({count} in its file, 0-based)"))?;
    if earlier.iter().any(|o| o.vertex == vertex) {
        return Err(format!("vertex {v} is observed twice"));
    }
    Ok(Observation { vertex, file_vertex: v, position })
}

/// The value of `p` on `model` (`None`: a tissue it does not have).
pub fn parameter_value(model: &Model, p: Parameter) -> Option<f64> {
    let tissue = |k: usize| match k {
        0 => model.tissue,
        k => model.fem.regions.get(k - 1).map(|r| r.region.tissue),
    };
    Some(match p {
        Parameter::Young(k) => tissue(k)?.young(),
        Parameter::Poisson(k) => tissue(k)?.poisson(),
        Parameter::Density(k) => tissue(k)?.density(),
        Parameter::Gravity => model.load.gravity.iter().map(|g| g * g).sum::<f64>().sqrt(),
    })
}

/// Sets `p` to `value` on `model`.
///
/// Errors: a value the tissue refuses, a tissue the model does not have.
pub fn set_parameter(model: &mut Model, p: Parameter, value: f64) -> Result<()> {
    let scene = model.display_name();
    let failed = |source| Error::Fem { scene: scene.clone(), source };
    let k = match p {
        Parameter::Gravity => {
            let size = parameter_value(model, p).unwrap_or(0.0);
            model.load.gravity = model.load.gravity.map(|g| g * value / size);
            return Ok(());
        }
        Parameter::Young(k) | Parameter::Poisson(k) | Parameter::Density(k) => k,
    };
    let slot = match k {
        0 => model.tissue.as_mut(),
        k => model.fem.regions.get_mut(k - 1).map(|r| &mut r.region.tissue),
    };
    let Some(t) = slot else {
        return Err(failed(fibfluid_fem::FemError::Sensitivity { reason: format!("{p:?}: no such tissue") }));
    };
    let changed = match p {
        Parameter::Young(_) => t.with_elastic(value, t.poisson()),
        Parameter::Poisson(_) => t.with_elastic(t.young(), value),
        _ => t.with_density(value),
    };
    match changed {
        Ok(new) => {
            *t = new;
            Ok(())
        }
        Err(source) => Err(failed(source)),
    }
}
