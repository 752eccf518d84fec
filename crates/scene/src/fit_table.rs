//! `[fit]`: the parameters `fibfluid fit` fits (dotted keys of the scene), their bounds and
//! the observed positions' file.

use std::path::Path;

use fibfluid_fem::hyper::Parameter;
use fibfluid_sim::Model;
use fibfluid_sim::inverse::{FitParameter, FitSpec, parameter_value};

use crate::error::SceneProblem;
use crate::invalid::{Invalid, invalid};
use crate::spec::FitToml;

/// The keys a tissue's parameter takes after `tissue.` or `region.NAME.`.
const FIELDS: [&str; 3] = ["young", "poisson", "density"];

/// The parameter a dotted key (`tissue.young`, `region.NAME.poisson`, `gravity`) names on
/// `model`, or why not (one line naming the key). `[fit]`, `run --set` and `sweep --set`
/// read their keys with it.
pub fn parameter_of_key(key: &str, model: &Model) -> Result<Parameter, String> {
    let field = |tissue: usize, field: &str| match field {
        "young" => Ok(Parameter::Young(tissue)),
        "poisson" => Ok(Parameter::Poisson(tissue)),
        "density" => Ok(Parameter::Density(tissue)),
        other => Err(format!("`{key}`: `{other}` is not one of {}", FIELDS.join(", "))),
    };
    if key == "gravity" {
        return Ok(Parameter::Gravity);
    }
    if let Some(rest) = key.strip_prefix("tissue.") {
        if model.tissue.is_none() {
            return Err(format!("`{key}`: the scene has no [tissue]"));
        }
        return field(0, rest);
    }
    if let Some(rest) = key.strip_prefix("region.") {
        let names: Vec<&str> = model.fem.regions.iter().map(|r| r.name.as_str()).collect();
        for (k, name) in names.iter().enumerate() {
            if let Some(f) = rest.strip_prefix(name).and_then(|r| r.strip_prefix('.')) {
                return field(k + 1, f);
            }
        }
        return Err(format!("`{key}`: no [[region]] of that name (the scene's: {})", names.join(", ")));
    }
    Err(format!(
        "`{key}` is not a parameter (tissue.young, tissue.poisson, tissue.density, region.NAME.young, ..., gravity)"
    ))
}

/// `[fit]` against the built `model`; `metres`: metres per unit of the observed positions.
pub(crate) fn fit(
    f: Option<FitToml>,
    dir: &Path,
    model: &Model,
    metres: f64,
) -> Result<Option<FitSpec>, Invalid> {
    let Some(f) = f else { return Ok(None) };
    let parameters = fit_parameters(&f.parameters, &f.bounds, model)
        .map_err(|(key, problem)| invalid(format!("[fit].{key}"), SceneProblem::Fit(problem)))?;
    Ok(Some(FitSpec { parameters, bounds: f.bounds, observed: dir.join(&f.observed), metres }))
}

/// The fitted parameters of `keys` (dotted keys) with their `bounds` (one `[lower, upper]`
/// each, in order) on `model`, checked as `[fit]`'s: or which of `parameters` and `bounds`
/// is wrong and why (one line naming the key). `[fit]` and Python's `fibfluid.fit` read them
/// with it.
pub fn fit_parameters(
    keys: &[String],
    bounds: &[[f64; 2]],
    model: &Model,
) -> Result<Vec<FitParameter>, (&'static str, String)> {
    if keys.is_empty() {
        return Err(("parameters", "names no parameter".into()));
    }
    if bounds.len() != keys.len() {
        let (b, p) = (bounds.len(), keys.len());
        return Err(("bounds", format!("{b} bounds for {p} parameters (one [lower, upper] each, in order)")));
    }
    let mut parameters = Vec::new();
    for (key, b) in keys.iter().zip(bounds) {
        let p = parameter_of_key(key, model).map_err(|e| ("parameters", e))?;
        if parameters.iter().any(|q: &FitParameter| q.parameter == p) {
            return Err(("parameters", format!("`{key}` is named twice")));
        }
        let start = parameter_value(model, p).unwrap_or(f64::NAN);
        if !(b[0].is_finite() && b[1].is_finite() && b[0] > 0.0 && b[0] < b[1]) {
            return Err(("bounds", format!("`{key}`: [{}, {}] must be 0 < lower < upper", b[0], b[1])));
        }
        if !(start >= b[0] && start <= b[1]) {
            return Err(("bounds", format!("`{key}`: the start {start} lies outside [{}, {}]", b[0], b[1])));
        }
        if matches!(p, Parameter::Poisson(_)) && b[1] >= 0.5 {
            return Err((
                "bounds",
                format!("`{key}`: Poisson's ratio's upper bound {} must be below 0.5", b[1]),
            ));
        }
        parameters.push(FitParameter { key: key.clone(), parameter: p });
    }
    Ok(parameters)
}
