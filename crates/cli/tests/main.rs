//! The integration tests of this package, in one binary (one link instead of one per file).

mod bad_inputs;
mod cli_run;
mod fit;
mod scene_method;
mod sweep;
mod validate;
mod view;
