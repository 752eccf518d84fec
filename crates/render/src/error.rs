//! The crate's error type.

/// Everything that can go wrong while rendering a picture.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum RenderError {
    /// Nothing to draw: no panels, a panel without vertices or triangles, or
    /// a chart without any point.
    #[error("empty input: {what}")]
    EmptyInput {
        /// What was empty.
        what: String,
    },

    /// A triangle refers to a vertex that does not exist.
    #[error(
        "panel {panel}: triangle {triangle} refers to vertex {index}, but the surface has only {vertex_count} vertices"
    )]
    IndexOutOfRange {
        /// Index of the panel (surface) in the input slice.
        panel: usize,
        /// Index of the offending triangle.
        triangle: usize,
        /// The out-of-range vertex index.
        index: u32,
        /// Number of vertices of the surface.
        vertex_count: usize,
    },

    /// A vertex position has a NaN or infinite coordinate.
    #[error("panel {panel}: vertex {vertex} has a non-finite position {position:?}")]
    NonFinitePosition {
        /// Index of the panel (surface) in the input slice.
        panel: usize,
        /// Index of the offending vertex.
        vertex: usize,
        /// The offending position.
        position: [f64; 3],
    },

    /// A point of a linear chart has a NaN or infinite coordinate.
    #[error("series `{series}`: point {point} is not finite ({x}, {y})")]
    NonFinitePoint {
        /// The series' label.
        series: String,
        /// Index of the point in the series.
        point: usize,
        /// Its x coordinate.
        x: f64,
        /// Its y coordinate.
        y: f64,
    },

    /// A per-vertex scalar is NaN or infinite.
    #[error("panel {panel}: the scalar at vertex {vertex} is not finite ({value})")]
    NonFiniteScalar {
        /// Index of the panel (surface) in the input slice.
        panel: usize,
        /// Index of the offending vertex.
        vertex: usize,
        /// The offending value.
        value: f64,
    },

    /// The scalar slice does not have one value per vertex.
    #[error("panel {panel}: {scalars} scalar values for {vertices} vertices")]
    ScalarLength {
        /// Index of the panel (surface) in the input slice.
        panel: usize,
        /// Length of the scalar slice.
        scalars: usize,
        /// Number of vertices.
        vertices: usize,
    },

    /// A requested image (or panel) has zero width or height.
    #[error("image size {width}x{height} has a zero side")]
    ZeroSize {
        /// Requested width in pixels.
        width: u32,
        /// Requested height in pixels.
        height: u32,
    },

    /// The whole image would exceed [`crate::MAX_PIXELS`].
    #[error("image of {width}x{height} pixels is too large (limit {limit} pixels)", limit = crate::MAX_PIXELS)]
    ImageTooLarge {
        /// Width in pixels of the whole image.
        width: u64,
        /// Height in pixels of the whole image.
        height: u64,
    },

    /// The explicit color range is not finite or has `min > max`.
    #[error("invalid scalar range ({min}, {max}): need finite values with min <= max")]
    InvalidRange {
        /// Lower end given.
        min: f64,
        /// Upper end given.
        max: f64,
    },

    /// The camera's view direction or up vector is zero or not finite.
    #[error("invalid camera: {what} must be finite and non-zero, got {value:?}")]
    InvalidView {
        /// `"view_dir"` or `"up"`.
        what: &'static str,
        /// The offending vector.
        value: [f64; 3],
    },

    /// A chart point cannot be placed on a logarithmic axis (a coordinate is
    /// zero, negative, NaN, infinite, or outside `1e-100..=1e100`).
    #[error(
        "series \"{series}\": point {point} ({x}, {y}) cannot be drawn on a log axis (coordinates must be positive, between 1e-100 and 1e100)"
    )]
    NonPositiveLog {
        /// Label of the series (`"Pareto front"` for the Pareto points).
        series: String,
        /// Index of the point in its series.
        point: usize,
        /// Its x coordinate.
        x: f64,
        /// Its y coordinate.
        y: f64,
    },

    /// The drawing library failed (should not happen with valid input).
    #[error("drawing failed: {0}")]
    Draw(String),

    /// PNG encoding failed.
    #[error("PNG encoding failed: {0}")]
    Encode(String),
}

/// Result type of this crate.
pub type Result<T> = std::result::Result<T, RenderError>;
