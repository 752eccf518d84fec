//! The `fibfluid` command line's library half: output files (deformed OBJ, legacy and XML
//! VTK, `report.json`, renders), the probe and comparison runs with their files, the accuracy
//! study and the bench harness. The binary (`src/main.rs`) parses arguments and prints;
//! everything it writes goes through here, all or nothing ([`write_files_atomically`]).

pub mod bench;
pub mod bench_fem;
pub mod bench_two_rate;
pub mod compare_run;
mod error;
pub mod frames;
pub mod grab;
pub mod info;
pub mod output;
mod plates_png;
pub mod probe_run;
pub mod scaling;
pub mod series;
pub mod study;
mod study_grid;
pub mod vtp;
pub mod vtu;

pub use error::{Error, Result};
pub use info::{FiberCounts, MeshInfo, SurfaceMeasures, SurfaceTopology};
pub use output::{
    COMPRESSION_FILE, OUTPUT_FILES, SurfaceResult, check_output_dir, compression_png, fem_draws_plates,
    render_png, write_fem_outputs, write_fibers_vtk, write_files_atomically, write_outputs, write_vtk,
};
