//! A problem found while building a scene's values, before the file and line are attached.

use fibfluid_linalg::Choice;

use crate::error::SceneProblem;

/// A problem found while building a scene, before the file is known.
pub(crate) struct Invalid {
    pub(crate) key: Option<String>,
    pub(crate) problem: SceneProblem,
}

pub(crate) fn invalid(key: impl Into<String>, problem: SceneProblem) -> Invalid {
    Invalid { key: Some(key.into()), problem }
}

pub(crate) fn range(key: impl Into<String>, rule: &'static str, value: impl std::fmt::Display) -> Invalid {
    invalid(key, SceneProblem::Range { rule, value: value.to_string() })
}

pub(crate) fn choice<T: Choice>(
    key: &str,
    value: Option<String>,
    default: T,
) -> std::result::Result<T, Invalid> {
    match value {
        None => Ok(default),
        Some(v) => T::parse_name(&v).map_err(|e| invalid(key, SceneProblem::Choice(e))),
    }
}

/// A problem that names no key.
pub(crate) fn unkeyed(problem: SceneProblem) -> Invalid {
    Invalid { key: None, problem }
}
