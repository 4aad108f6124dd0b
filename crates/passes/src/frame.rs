//! What a frame's passes are declared on and record with.
//!
//! Every shipped pass is an `add_*` function that declares the pass on a [`FrameGraph`] (its
//! reads and writes) together with its recording, a [`Payload`]. A payload captures only what
//! the declaration decided (handles, the pipeline variant, the phase): everything it records
//! with arrives as arguments — the executor's [`PassContext`] and the [`SceneResources`] the
//! renderer keeps across frames. So a frame whose declaration did not change keeps its
//! payloads, and an engine's own passes sit on the same graph with the same signature (they
//! capture their own state, and may ignore the scene's).

use tilegraph_graph::{BufferId, GraphBuilder, RasterPassBuilder};
use tilegraph_scene::DepthConvention;
use tilegraph_vk::executor::PassContext;
use tilegraph_vk::{Context, VkError};

use crate::cull::CullState;
use crate::draws::DrawList;
use crate::gpu_scene::GpuScene;
use crate::occlusion::{OqState, RasterOcclusion};
use crate::pipelines::Pipelines;
use crate::visbuf::ResolveSets;

/// A pass's recording: called once per frame inside the pass's subpass (raster passes) or on
/// its own (compute and transfer passes), after the graph's barriers.
pub type Payload = Box<dyn FnMut(&mut PassContext<'_>, &mut SceneResources) -> Result<(), VkError>>;

/// The graph a frame is declared on.
pub type FrameGraph = GraphBuilder<Payload>;

/// What this frame draws: written by the renderer before the frame is recorded.
#[derive(Debug, Clone, Default)]
pub struct FrameData {
    /// The CPU draw lists (blended geometry always; all of it without GPU culling).
    pub draws: DrawList,
    /// The camera's depth convention: the depth compare of every pipeline and the reduction of
    /// the HiZ pyramid follow it.
    pub depth: DepthConvention,
}

/// What the shipped passes record with, kept by the renderer across frames and handed to every
/// payload: the scene's buffers, the pipelines, this frame's draw lists, and the state of the
/// culling technique in use.
pub struct SceneResources {
    pub scene: GpuScene,
    pub pipelines: Pipelines,
    pub frame: FrameData,
    /// GPU culling: the indirect lists, visibility and the HiZ pyramid.
    pub culling: Option<CullState>,
    /// Occlusion queries.
    pub queries: Option<OqState>,
    /// Raster occlusion.
    pub raster: Option<RasterOcclusion>,
    /// The visibility buffer's resolve.
    pub resolve: Option<ResolveSets>,
}

impl SceneResources {
    /// Destroys everything; the GPU must be idle.
    pub fn destroy(self, ctx: &Context) {
        if let Some(c) = self.culling {
            c.destroy(ctx);
        }
        if let Some(q) = self.queries {
            q.destroy(ctx);
        }
        if let Some(r) = self.raster {
            r.destroy(ctx);
        }
        if let Some(r) = self.resolve {
            r.destroy(ctx);
        }
        self.pipelines.destroy(ctx);
        self.scene.destroy(ctx);
    }
}

/// Where a geometry pass's draws come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DrawSource {
    /// The frame's CPU draw list ([`FrameData::draws`]).
    Cpu,
    /// The culling shader's indirect lists of one phase (0: early or only, 1: late), read
    /// from `commands`, `counts` and `draw_ids`.
    Gpu {
        commands: BufferId,
        counts: BufferId,
        draw_ids: BufferId,
        phase: u32,
    },
}

impl DrawSource {
    /// Declares what a pass drawing from this source reads: the culling shader's commands and
    /// counts as indirect arguments, its draw ids through the vertex shader.
    pub fn declare_reads(self, p: &mut RasterPassBuilder<'_, Payload>) {
        if let DrawSource::Gpu {
            commands,
            counts,
            draw_ids,
            ..
        } = self
        {
            p.indirect(commands).indirect(counts).storage_read(draw_ids);
        }
    }
}
