//! `fibfluid validate`: the field's benchmarks for the finite-element method, each case a
//! quantity against a reference with its source (a closed form, a published value or an
//! independent solution), computed at the case's resolution and at twice it, with the
//! relative error and the tolerance the case promises at the finer one.
//!
//! - [`cases`] lists them; [`run_case`] runs one at one resolution; [`Case::check`] runs it at
//!   both and says whether it meets its tolerance.
//! - The references live in [`closed_form`] and never call the finite-element code; the
//!   bodies in [`bodies`] are built through `fibfluid-fem`'s public API.

pub mod bodies;
pub mod closed_form;
mod suite;

pub use suite::{Case, CaseError, Outcome, Row, Speed, cases, cases_at, run_case};
