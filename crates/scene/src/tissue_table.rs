//! `[tissue]` (and a region's `[region.tissue]`): what the tissue is, in SI units.

use fibfluid_fem::law::PronyTerm;
use fibfluid_fem::{Tissue, TissueParameter};

use crate::error::SceneProblem;
use crate::invalid::{Invalid, choice, invalid, range};
use crate::spec::TissueToml;

/// `[tissue]`: what the tissue is, in SI units, checked by the FEM's own rule.
/// `model = "auto"` is not a law: it asks the run to choose ([`FemSettings::auto_model`]),
/// starting linear.
pub(crate) fn tissue(t: TissueToml) -> Result<(Tissue, bool), Invalid> {
    let density = t.density.unwrap_or(0.0);
    let auto = t.model.as_deref() == Some(AUTO_MODEL);
    let given = if auto { None } else { t.model };
    let model = choice("[tissue].model", given, fibfluid_fem::TissueModel::Linear).map_err(|mut e| {
        if let SceneProblem::Choice(c) = &mut e.problem {
            c.expected.push_str(", auto");
        }
        e
    })?;
    let tissue = Tissue::new(t.young, t.poisson, density).map_err(|e| match e {
        fibfluid_fem::FemError::InvalidTissue { name, value, .. } => {
            let rule = match name {
                TissueParameter::Young => "finite and > 0 (Pa)",
                TissueParameter::Poisson => {
                    "in (-1, 0.5): 0.5 is the incompressible limit the linear FEM cannot take"
                }
                TissueParameter::Density => "finite and >= 0 (kg/m^3)",
            };
            range(format!("[tissue].{name}"), rule, value)
        }
        other => invalid("[tissue]", SceneProblem::Tissue(other)),
    })?;
    let terms: Vec<PronyTerm> = t.relaxation.iter().map(|p| PronyTerm { g: p.g, tau: p.tau }).collect();
    let tissue = tissue
        .with_model(model)
        .with_relaxation(&terms)
        .map_err(|e| invalid("[[tissue.relaxation]]", SceneProblem::Tissue(e)))?;
    Ok((tissue, auto))
}

/// The `[tissue] model` that lets the run choose the law.
const AUTO_MODEL: &str = "auto";
