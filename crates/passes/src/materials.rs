//! Engine materials: an engine's own shaders drawing tilegraph's culled lists.
//!
//! tilegraph compiles each frame's render passes itself (subpasses merged per profile, render
//! passes made again when the plan changes), so a pipeline cannot be made before the graph is:
//! the engine gives its shaders (SPIR-V, compiled against `shaders/include/tilegraph_instance.glsl`),
//! its pipeline layout (set 0 is tilegraph's scene set) and a closure that binds its own sets,
//! and tilegraph makes the pipeline for each render pass and subpass it draws in — the
//! fixed-function state its own pipeline of that pass has (vertex layout, depth test and writes,
//! blending, culling) — caches it with its own, prunes it with them, and lints it from the
//! fragment shader's SPIR-V like its own. Culling, the graph, merging, load/store and barriers
//! do not change: a material's draws are the same draws, bound to another pipeline.

use tilegraph_vk::ash::vk;
use tilegraph_vk::Context;

/// The passes an engine material takes part in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum MaterialPass {
    /// The depth pre-pass: positions only for opaque materials; alpha-tested ones need a
    /// fragment shader that discards exactly where their colour shader does.
    Depth,
    /// The forward colour passes (opaque, alpha-tested, blended). After a depth pre-pass the
    /// colour pass tests EQUAL: the vertex shader must compute positions as the pre-pass does
    /// (`tilegraph_clip_position`, `invariant gl_Position`).
    Color,
    /// The visibility buffer's resolve of the material's pixels, after material classification
    /// (`visbuf_resolve = classified`): the engine's fragment shader
    /// (`shaders/include/tilegraph_visbuf.glsl`) over tilegraph's tile quads.
    Resolve,
}

/// One shader stage: a name (for the lint's findings and debug labels) and its SPIR-V.
#[derive(Debug, Clone)]
pub struct ShaderCode {
    pub name: String,
    pub spirv: Vec<u8>,
}

/// The shaders of one pass kind.
#[derive(Debug, Clone)]
pub struct MaterialShaders {
    pub vertex: ShaderCode,
    /// Required for colour and for alpha-tested depth; an opaque depth pass may go without.
    pub fragment: Option<ShaderCode>,
}

/// Binds the engine's own descriptor sets (set 1 and up) and push constants, after tilegraph
/// bound the material's pipeline and set 0, before its draws.
pub type BindMaterial = Box<dyn Fn(&Context, vk::CommandBuffer, MaterialPass)>;

/// The engine's visibility-buffer resolve of a material: a fragment shader and its pipeline
/// layout — set 0 the renderer's scene set layout, set 1 its resolve set layout
/// ([`crate::SceneRenderer::resolve_set_layout`]), the engine's own sets from 2.
#[derive(Debug, Clone)]
pub struct EngineResolve {
    pub fragment: ShaderCode,
    pub layout: vk::PipelineLayout,
}

/// What an engine registers for a material ([`crate::SceneRenderer::add_material`]).
pub struct EngineMaterial {
    pub name: String,
    /// Its pipeline layout, owned by the engine: set 0 must be the renderer's scene set layout
    /// ([`crate::SceneRenderer::scene_set_layout`]); its own sets and push constants follow.
    pub layout: vk::PipelineLayout,
    /// Its depth pre-pass shaders; `None`: tilegraph's pre-pass draws its instances.
    pub depth: Option<MaterialShaders>,
    /// Its colour shaders; `None`: tilegraph's colour passes draw its instances.
    pub color: Option<MaterialShaders>,
    /// Its visibility-buffer resolve; `None`: tilegraph's resolve shades its pixels.
    pub resolve: Option<EngineResolve>,
    pub bind: BindMaterial,
}

impl EngineMaterial {
    /// Its raster shaders for `pass` (`None` for the resolve: [`Self::resolve`]).
    pub fn shaders(&self, pass: MaterialPass) -> Option<&MaterialShaders> {
        match pass {
            MaterialPass::Depth => self.depth.as_ref(),
            MaterialPass::Color => self.color.as_ref(),
            MaterialPass::Resolve => None,
        }
    }
}

impl std::fmt::Debug for EngineMaterial {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("EngineMaterial")
            .field("name", &self.name)
            .field("layout", &self.layout)
            .field("depth", &self.depth.as_ref().map(|s| &s.vertex.name))
            .field("color", &self.color.as_ref().map(|s| &s.vertex.name))
            .field("resolve", &self.resolve.as_ref().map(|r| &r.fragment.name))
            .finish()
    }
}
