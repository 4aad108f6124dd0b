//! How the scene's colour passes test depth: against a pre-pass or not, in either depth
//! convention.

use tilegraph_scene::DepthConvention;
use tilegraph_vk::ash::vk;

/// How a colour pass uses depth.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ColourDepth {
    /// No pre-pass wrote this class: test nearer, write.
    Write,
    /// A pre-pass wrote the depth of every instance drawn here: test EQUAL, no writes.
    Equal,
    /// A pre-pass wrote part of it (last frame's visible set): test nearer-or-equal, write.
    /// The colour of each pixel is that of the last fragment drawn at its nearest depth, as
    /// with `Equal` after a full pre-pass — so the image is the same.
    WriteOrEqual,
}

/// The depth compare that lets a nearer fragment through, or one level with it.
pub fn nearer_or_equal(depth: DepthConvention) -> vk::CompareOp {
    match depth {
        DepthConvention::Reverse => vk::CompareOp::GREATER_OR_EQUAL,
        DepthConvention::Standard => vk::CompareOp::LESS_OR_EQUAL,
    }
}

/// The depth compare that lets a nearer fragment through.
pub fn nearer(depth: DepthConvention) -> vk::CompareOp {
    match depth {
        DepthConvention::Reverse => vk::CompareOp::GREATER,
        DepthConvention::Standard => vk::CompareOp::LESS,
    }
}
