//! `fibfluid._native`: the compiled half of the `fibfluid` Python package (PyO3).
//!
//! The Python package (`python/fibfluid/__init__.py`) wraps these classes and functions;
//! users import `fibfluid`, not this module. Everything here goes through the scene, engine
//! and interactive crates exactly as the command line does, so a run gives the numbers of
//! `fibfluid run`.
//!
//! Every error is `fibfluid.Error` (a `ValueError`) with the one-line message the command
//! line prints after `error: `. No Rust panic reaches Python: each entry point runs under
//! [`guard`], which turns a panic into `fibfluid.Error` naming it an internal error.

use std::panic::{AssertUnwindSafe, catch_unwind};

use pyo3::prelude::*;

mod arrays;
mod body;
mod inverse;
mod run;
mod scene;
mod settings;
mod volume;

pyo3::create_exception!(
    fibfluid,
    Error,
    pyo3::exceptions::PyValueError,
    "Everything fibfluid refuses or fails at: a scene file, a mesh, a setting, a solve, a grab. The message is the one line `fibfluid` prints on the command line."
);

/// Collapses a message onto one line, as the command line prints it.
pub(crate) fn one_line(s: &str) -> String {
    s.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// `fibfluid.Error` with this message (put on one line).
pub(crate) fn error(message: impl AsRef<str>) -> PyErr {
    Error::new_err(one_line(message.as_ref()))
}

/// `fibfluid.Error` from any of the library's errors (its `Display`, on one line).
pub(crate) fn lib_error(e: impl Into<fibfluid_scene::Error>) -> PyErr {
    error(e.into().to_string())
}

/// Runs `f`, turning a panic into `fibfluid.Error` (a bug, reported as one).
pub(crate) fn guard<T>(f: impl FnOnce() -> PyResult<T>) -> PyResult<T> {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(r) => r,
        Err(payload) => {
            let what = payload
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".to_string());
            Err(error(format!("internal error (a bug in fibfluid, please report it): {what}")))
        }
    }
}

/// The compiled module.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("Error", m.py().get_type::<Error>())?;
    m.add("MAX_STEPS", fibfluid_sim::MAX_STEPS)?;
    m.add_class::<scene::NativeScene>()?;
    m.add_class::<body::NativeBody>()?;
    m.add_class::<run::RunOutput>()?;
    m.add_class::<volume::VolumeOutput>()?;
    m.add_function(wrap_pyfunction!(run::run, m)?)?;
    m.add_function(wrap_pyfunction!(set_threads, m)?)?;
    m.add_function(wrap_pyfunction!(inverse::sensitivity, m)?)?;
    m.add_function(wrap_pyfunction!(inverse::fit, m)?)?;
    Ok(())
}

/// Sets the number of threads the linear backends and rayon use (as the command line's
/// `--threads`); returns a note when the number was lowered, else None. Call it before the
/// first run: rayon's pool is built once.
#[pyfunction]
fn set_threads(n: i64) -> PyResult<Option<String>> {
    guard(|| match fibfluid_linalg::threads::try_set_threads(usize::try_from(n).unwrap_or(0)) {
        Ok(setting) => Ok(setting.note()),
        Err(e) => Err(error(format!("threads {n}: {e}"))),
    })
}
