//! Shaders and state made to measure: the bottleneck finder's probes (`tilegraph bottleneck`)
//! and seed 000's depth-test variants (`tilegraph experiments`).

/// Shaders and depth state changed to measure: made trivial to see what a stage of the
/// pipeline costs (seed 002's recipe for finding the bottleneck; `tilegraph bottleneck`), or
/// testing depth late or not at all (seed 000's variants; `tilegraph experiments`). Measurement
/// only, never a shipping frame.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct StageProbe {
    /// The forward colour shaders write a fixed colour, their material, texture and lighting
    /// work skipped (`TRIVIAL_FRAGMENT`, specialization 2 of `forward_body.glsl`).
    pub trivial_fragment: bool,
    /// The scene's vertex shaders (`forward.vert`, `depth.vert`) put every vertex at one point
    /// outside the clip volume: the draws and their vertices still run, nothing is rasterized
    /// (`TRIVIAL_VERTEX`, their specialization 0).
    pub trivial_vertex: bool,
    /// The forward colour passes test no depth and write none (seed 000's "without ZS":
    /// `tilegraph experiments`). The image is wrong wherever surfaces overlap.
    pub no_depth_test: bool,
    /// The forward colour shaders write the depth they would have (`forward_late_depth.frag`):
    /// the depth test runs after the shader (seed 000's "late ZS"). The image is unchanged.
    pub late_depth: bool,
    /// Every raster pass a render pass of its own, as if the profile's `merge_subpasses` were
    /// `never` (seed 000's depth pre-pass "separate" beside "as a subpass"): what a pass's
    /// attachments cost when they go to memory between passes. The image is unchanged.
    pub separate_render_passes: bool,
}
