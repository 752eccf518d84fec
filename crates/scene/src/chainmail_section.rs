//! The `[chainmail]` section: read into ChainMail's own settings and checked by them
//! ([`ChainmailSettings::check`]). The lattice's memory is checked when a ChainMail body
//! is built, not when a scene is read: a `run` of the same scene never builds one.

use fibfluid_interact::chainmail_settings::{ChainmailSettings, MaterialRegion, SettingProblem, Variant};

use crate::error::SceneProblem;
use crate::invalid::{Invalid, choice, invalid, range};
use crate::spec::{ChainmailToml, PerAxis};

const KEY: &str = "[chainmail]";

/// Reads `[chainmail]` (absent: the defaults).
pub(crate) fn parse(spec: Option<ChainmailToml>) -> Result<ChainmailSettings, Invalid> {
    let mut s = ChainmailSettings::default();
    let Some(t) = spec else { return Ok(s) };
    s.variant = choice(&format!("{KEY}.variant"), t.variant, s.variant)?;
    s.spacing = t.spacing;
    s.alpha_min = t.alpha_min.map(PerAxis::get).unwrap_or(s.alpha_min);
    s.alpha_max = t.alpha_max.map(PerAxis::get).unwrap_or(s.alpha_max);
    s.beta = t.beta.map(PerAxis::get).unwrap_or(s.beta);
    s.tss = t.tss.unwrap_or(s.tss);
    if let Some(r) = t.relaxation {
        s.relaxation =
            usize::try_from(r).map_err(|_| range(format!("{KEY}.relaxation"), "between 0 and 100000", r))?;
    }
    for r in t.material {
        let [min, max] = r.bbox;
        s.regions.push(MaterialRegion {
            min,
            max,
            alpha_min: r.alpha_min.map(PerAxis::get).unwrap_or(s.alpha_min),
            alpha_max: r.alpha_max.map(PerAxis::get).unwrap_or(s.alpha_max),
        });
    }
    s.check().map_err(keyed)?;
    if s.variant == Variant::Generalized && !s.regions.is_empty() {
        return Err(invalid(
            "[[chainmail.material]]",
            SceneProblem::Conflict(
                "material regions need variant = \"tsve\" (Generalized ChainMail has one material)",
            ),
        ));
    }
    Ok(s)
}

/// The scene key of a settings problem.
fn keyed(p: SettingProblem) -> Invalid {
    let key = match p.region {
        None => format!("{KEY}.{}", p.key),
        Some(k) => format!("[[chainmail.material]] #{}.{}", k + 1, p.key),
    };
    range(key, p.rule, p.value)
}
