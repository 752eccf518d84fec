//! Small software renderer and plots for fibfluid.
//!
//! Two kinds of pictures, both returned as PNG bytes:
//!
//! - [`render_surfaces`]: one or more triangle surfaces side by side, seen
//!   through the same orthographic camera, flat Lambert shaded and colored by
//!   a per-vertex scalar through a [`Colormap`], with a title above each panel
//!   and one shared color bar on the right.
//! - [`loglog_chart`]: a log-log line chart of several [`Series`] with a
//!   legend, optionally highlighting a Pareto front (see [`pareto_front`]);
//!   [`line_chart`]: the same on linear axes (time series such as a probe's
//!   reaction force per frame).
//!
//! [`side_by_side`] joins such pictures into one.
//!
//! Text is drawn with a bundled copy of DejaVu Sans (see
//! `assets/LICENSE-DejaVu.txt`), so no system fonts are needed. The font is
//! registered with `plotters` under the family names `"fibfluid-sans"` and
//! `"sans-serif"` the first time a picture is drawn.
//!
//! Bad input (empty meshes, out-of-range indices, NaN coordinates,
//! non-positive values on a log axis, zero-size images, ...) is reported as a
//! [`RenderError`]; nothing here panics on bad data.

mod chart;
mod compose;
mod error;
mod surface;
mod text;

pub use chart::{Series, line_chart, log_drawable, loglog_chart, pareto_front, pareto_front_with_margin};
pub use compose::side_by_side;
pub use error::{RenderError, Result};
pub use surface::{
    Colormap, OUTLIER_FACTOR, OUTLIER_QUANTILE, Surface, ViewOptions, render_surfaces, robust_range,
};

/// Largest image, in pixels (width × height), that this crate will allocate.
///
/// Larger requests fail with [`RenderError::ImageTooLarge`] instead of
/// exhausting memory.
pub const MAX_PIXELS: u64 = 1 << 26;
