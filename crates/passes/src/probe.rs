//! The bottleneck finder's probes (`tilegraph bottleneck`).

/// Shaders made trivial to measure what a stage of the pipeline costs (seed 002's recipe for
/// finding the bottleneck; `tilegraph bottleneck`). They change the image: measurement only.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct StageProbe {
    /// The forward colour shaders write a fixed colour, their material, texture and lighting
    /// work skipped (`TRIVIAL_FRAGMENT`, specialization 2 of `forward_body.glsl`).
    pub trivial_fragment: bool,
    /// The scene's vertex shaders (`forward.vert`, `depth.vert`) put every vertex at one point
    /// outside the clip volume: the draws and their vertices still run, nothing is rasterized
    /// (`TRIVIAL_VERTEX`, their specialization 0).
    pub trivial_vertex: bool,
}
