//! The one error type of this crate. Every variant names the input it rejects (`what`) and
//! where in it the problem sits, so a caller several layers up can report it without context.

/// Invalid input to a culling reference function.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CullError {
    /// An occluder mesh the software rasterizer cannot take (bad indices, non-finite vertices).
    #[error("software occluder: {reason}")]
    InvalidOccluder { reason: String },

    /// A precomputed visible set that does not hold together.
    #[error("precomputed visible set: {reason}")]
    InvalidPvs { reason: String },

    /// A viewport, depth buffer or id buffer of width or height 0.
    #[error("{what}: extent {width_px}x{height_px} px is empty; both sides must be at least 1")]
    ZeroExtent {
        what: &'static str,
        width_px: u32,
        height_px: u32,
    },

    /// An extent above [`crate::MAX_EXTENT_PX`]; the integer texel mapping of the pyramid is
    /// specified for 32-bit GPU arithmetic and would overflow beyond it.
    #[error("{what}: extent {width_px}x{height_px} px exceeds the maximum side of {max_px} px")]
    ExtentTooLarge {
        what: &'static str,
        width_px: u32,
        height_px: u32,
        max_px: u32,
    },

    /// A buffer whose length does not match the extent it is declared with.
    #[error("{what}: buffer holds {actual_len} values, its extent needs {expected_len}")]
    BufferSizeMismatch {
        what: &'static str,
        expected_len: usize,
        actual_len: usize,
    },

    /// A NaN or infinite depth value; min/max reductions of NaN differ between CPUs and GPUs.
    #[error("{what}: depth at pixel ({x_px}, {y_px}) is not finite ({value})")]
    NonFiniteDepth {
        what: &'static str,
        x_px: u32,
        y_px: u32,
        value: f32,
    },

    /// A value in a buffer declared as D16 that no 16-bit UNORM code produces.
    #[error("{what}: depth {value} at pixel ({x_px}, {y_px}) is not a D16 UNORM value (k/65535)")]
    NotD16Quantized {
        what: &'static str,
        x_px: u32,
        y_px: u32,
        value: f32,
    },

    /// A matrix with a NaN or infinite element.
    #[error("{what}: matrix element column {column}, row {row} is not finite ({value})")]
    NonFiniteMatrix {
        what: &'static str,
        column: usize,
        row: usize,
        value: f32,
    },

    /// A scalar or vector component that must be finite and is not.
    #[error("{what}: {field} is not finite ({value})")]
    NonFiniteValue {
        what: &'static str,
        field: &'static str,
        value: f32,
    },

    /// An axis-aligned box whose minimum exceeds its maximum on some axis.
    #[error("{what}: min {min} > max {max} on axis {axis}")]
    InvertedBounds {
        what: &'static str,
        axis: char,
        min: f32,
        max: f32,
    },

    /// A sphere of negative radius.
    #[error("{what}: radius {radius_m} m is negative")]
    NegativeRadius { what: &'static str, radius_m: f32 },

    /// A projection parameter outside its domain.
    #[error("projection: {parameter} = {value} is invalid: {reason}")]
    InvalidProjection {
        parameter: &'static str,
        value: f32,
        reason: &'static str,
    },

    /// A frustum that is not a closed convex polyhedron even after clamping an infinite far
    /// plane, so the separating-axis test has no corners to work with.
    #[error("frustum: {reason}")]
    DegenerateFrustum { reason: &'static str },

    /// A pyramid level index past the last level.
    #[error("hiz: level {level} does not exist; the pyramid has {level_count} levels")]
    LevelOutOfRange { level: u32, level_count: u32 },

    /// An instance id at or past the instance count the caller declared.
    #[error("{what}: instance id {id} is not below the instance count {instance_count}")]
    InstanceIdOutOfRange {
        what: &'static str,
        id: u32,
        instance_count: u32,
    },
}
