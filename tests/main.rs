//! The integration tests of this package, in one binary (one link instead of one per file).

mod chainmail;
mod fibers;
mod frame_guards;
mod fuzz_readers;
mod golden_sphere42;
mod hard_cases;
mod memory_guard;
mod plates;
mod scenes;
mod stepping;
mod structure;
mod tools;
mod units;
mod volume_properties;
