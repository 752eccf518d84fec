//! The integration tests of this package, in one binary (one link instead of one per file).

mod adjacency;
mod area_volume;
mod cavity;
mod common;
mod decimate;
mod fibers;
mod formats;
mod image;
mod properties;
mod reader;
mod turned;
mod voxel;
