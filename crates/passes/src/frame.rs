//! What a frame's passes are declared on and record with.
//!
//! Every shipped pass is an `add_*` function that declares the pass on a [`FrameGraph`] (its
//! reads and writes) together with its recording, a [`Payload`]. A payload captures only what
//! the declaration decided (handles, the pipeline variant, the phase): everything it records
//! with arrives as arguments — the executor's [`PassContext`] and the [`SceneResources`] the
//! renderer keeps across frames. So a frame whose declaration did not change keeps its
//! payloads, and an engine's own passes sit on the same graph with the same signature (they
//! capture their own state, or keep it among the resources' [`States`]).

use std::any::Any;

use tilegraph_graph::{BufferId, GraphBuilder, RasterPassBuilder};
use tilegraph_scene::DepthConvention;
use tilegraph_vk::executor::PassContext;
use tilegraph_vk::{Context, VkError};

use crate::draws::DrawList;
use crate::gpu_scene::GpuScene;
use crate::pipelines::Pipelines;

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
    /// Per mesh: the engine material of its material (`Material::engine_material`); empty
    /// while the engine registered none.
    pub engine_of_mesh: Vec<Option<u32>>,
    /// The scene's materials this frame (the per-material resolves draw each).
    pub material_count: u32,
    /// Per scene material: the engine material whose resolve shades its pixels (after
    /// classification); empty while the engine registered no material with a resolve.
    pub engine_resolve: Vec<Option<u32>>,
}

impl FrameData {
    /// The engine material resolving scene material `material`'s pixels, if any.
    pub fn engine_resolve_of(&self, material: u32) -> Option<u32> {
        self.engine_resolve
            .get(material as usize)
            .copied()
            .flatten()
    }

    /// The engine material of `mesh`'s material, if any.
    pub fn engine_of(&self, mesh: u32) -> Option<u32> {
        self.engine_of_mesh.get(mesh as usize).copied().flatten()
    }
}

/// What the passes record with, kept by the renderer across frames and handed to every
/// payload: the scene's buffers, the pipelines, this frame's draw lists, and the state of each
/// technique in use (the culling buffers, the pyramid, the query pools...).
///
/// A frame may render several views (cameras with their own targets and culling). The scene's
/// buffers and the pipelines are shared; the draw lists, the depth convention, the techniques'
/// states and the scene's sets 0 are the **current view's**: the renderer makes a pass's view
/// current ([`Self::enter_view`]) before its payload records, so a pass records the same way
/// whichever view it belongs to.
pub struct SceneResources {
    pub scene: GpuScene,
    pub pipelines: Pipelines,
    pub frame: FrameData,
    pub states: States,
    /// Per view, its draw lists and states while another view is current (the current view's
    /// entry holds empty ones).
    parked: Vec<ViewParts>,
}

/// A view's own part of the resources.
#[derive(Default)]
struct ViewParts {
    draws: DrawList,
    depth: DepthConvention,
    states: States,
}

impl ViewParts {
    /// Swaps these parts with the current ones of `frame` and `states`.
    fn swap(&mut self, frame: &mut FrameData, states: &mut States) {
        std::mem::swap(&mut self.draws, &mut frame.draws);
        std::mem::swap(&mut self.depth, &mut frame.depth);
        std::mem::swap(&mut self.states, states);
    }
}

impl SceneResources {
    /// Resources for the views `scene` has sets for, view 0 current.
    pub fn new(scene: GpuScene, pipelines: Pipelines) -> Self {
        let views = scene.views().max(1);
        SceneResources {
            scene,
            pipelines,
            frame: FrameData::default(),
            states: States::default(),
            parked: (0..views).map(|_| ViewParts::default()).collect(),
        }
    }

    /// The views the resources hold.
    pub fn views(&self) -> usize {
        self.parked.len()
    }

    /// The current view.
    pub fn view(&self) -> usize {
        self.scene.current_view()
    }

    /// View `view`'s states, current or not (`None`: no such view).
    pub fn view_states(&self, view: usize) -> Option<&States> {
        if view == self.scene.current_view() {
            Some(&self.states)
        } else {
            self.parked.get(view).map(|p| &p.states)
        }
    }

    /// Makes `view` current: its draw lists, states and sets are the ones the passes see. An
    /// unknown view leaves the current one.
    pub fn enter_view(&mut self, view: usize) {
        let current = self.scene.current_view();
        if view == current || view >= self.parked.len() {
            return;
        }
        let SceneResources {
            frame,
            states,
            parked,
            scene,
            ..
        } = self;
        if let Some(p) = parked.get_mut(current) {
            p.swap(frame, states);
        }
        if let Some(p) = parked.get_mut(view) {
            p.swap(frame, states);
        }
        scene.enter_view(view);
    }

    /// Destroys everything; the GPU must be idle.
    pub fn destroy(self, ctx: &Context) {
        self.states.destroy(ctx);
        for p in self.parked {
            p.states.destroy(ctx);
        }
        self.pipelines.destroy(ctx);
        self.scene.destroy(ctx);
    }
}

/// GPU state a technique keeps across frames (its buffers, pools, pipelines), owned by the
/// frame's [`SceneResources`] and found by its type.
pub trait PassState: Any {
    /// Destroys its Vulkan objects; the GPU must be idle.
    fn destroy(self: Box<Self>, ctx: &Context);
}

/// The techniques' states, one per type. A handful at most: looked up by a scan.
#[derive(Default)]
pub struct States {
    items: Vec<Box<dyn PassState>>,
}

impl States {
    /// Adds `state`; one of the same type already there is handed back.
    pub fn insert<T: PassState>(&mut self, state: T) -> Option<T> {
        let old = self
            .items
            .iter()
            .position(|s| (&**s as &dyn Any).is::<T>())
            .map(|i| self.items.swap_remove(i));
        self.items.push(Box::new(state));
        old.and_then(|b| (b as Box<dyn Any>).downcast::<T>().ok().map(|b| *b))
    }

    pub fn get<T: PassState>(&self) -> Option<&T> {
        self.items
            .iter()
            .find_map(|s| (&**s as &dyn Any).downcast_ref::<T>())
    }

    pub fn get_mut<T: PassState>(&mut self) -> Option<&mut T> {
        self.items
            .iter_mut()
            .find_map(|s| (&mut **s as &mut dyn Any).downcast_mut::<T>())
    }

    /// The state of type `T`, or an error naming it and the pass that wanted it.
    pub fn require<T: PassState>(&self, pass: &str) -> Result<&T, VkError> {
        self.get().ok_or_else(|| missing::<T>(pass))
    }

    /// [`Self::require`], mutable.
    pub fn require_mut<T: PassState>(&mut self, pass: &str) -> Result<&mut T, VkError> {
        self.get_mut().ok_or_else(|| missing::<T>(pass))
    }

    /// Destroys every state; the GPU must be idle.
    pub fn destroy(self, ctx: &Context) {
        for s in self.items {
            s.destroy(ctx);
        }
    }
}

#[cold]
fn missing<T>(pass: &str) -> VkError {
    VkError::Invalid {
        what: pass.into(),
        reason: format!(
            "records with a {}, which the renderer does not keep",
            std::any::type_name::<T>()
        ),
    }
}

/// Where a geometry pass's draws come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DrawSource {
    /// The frame's CPU draw list ([`FrameData::draws`]).
    Cpu,
    /// The culling shader's indirect lists of one phase (0: early or only, 1: late), read
    /// from `commands`, `counts` and `draw_ids`: the cluster stage's (`clusters`) or the
    /// instance compaction's.
    Gpu {
        commands: BufferId,
        counts: BufferId,
        draw_ids: BufferId,
        /// Cluster culling's runs: per command, the mesh's triangle it starts at (bound in
        /// the culled set; the visibility buffer's pass reads it).
        runs: Option<BufferId>,
        /// Cluster culling's places, which hold each draw group's draw count where engine
        /// materials draw the lists group by group (fixed places, `cluster.glsl`).
        group_counts: Option<BufferId>,
        phase: u32,
        clusters: bool,
        /// Per-triangle culling: the scene's index buffer, whose tail the commands draw.
        indices: Option<BufferId>,
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
            runs,
            group_counts,
            indices,
            ..
        } = self
        {
            p.indirect(commands).indirect(counts).storage_read(draw_ids);
            if let Some(c) = group_counts {
                p.indirect(c);
            }
            if let Some(r) = runs {
                p.storage_read(r);
            }
            if let Some(i) = indices {
                p.index(i);
            }
        }
    }
}

/// The scene's descriptor set 0 of a frame slot, or an error naming the pass.
pub fn scene_set(
    pc: &PassContext<'_>,
    res: &SceneResources,
) -> Result<tilegraph_vk::ash::vk::DescriptorSet, VkError> {
    res.scene
        .set(pc.frame_slot)
        .ok_or_else(|| VkError::Invalid {
            what: pc.pass_name.into(),
            reason: format!("no scene descriptor set for frame slot {}", pc.frame_slot),
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    struct A(u32);
    struct B;
    struct Missing;
    impl PassState for A {
        fn destroy(self: Box<Self>, _: &Context) {}
    }
    impl PassState for B {
        fn destroy(self: Box<Self>, _: &Context) {}
    }
    impl PassState for Missing {
        fn destroy(self: Box<Self>, _: &Context) {}
    }

    #[test]
    fn states_are_found_by_type_and_replaced_by_one_of_the_same_type() {
        let mut s = States::default();
        assert!(s.get::<A>().is_none());
        assert!(s.insert(A(1)).is_none());
        assert!(s.insert(B).is_none());
        assert_eq!(s.get::<A>().map(|a| a.0), Some(1));
        if let Some(a) = s.get_mut::<A>() {
            a.0 = 2;
        }
        assert_eq!(s.insert(A(3)).map(|a| a.0), Some(2));
        assert_eq!(s.get::<A>().map(|a| a.0), Some(3));
        assert!(s.get::<B>().is_some());
        let e = s.require::<Missing>("post").err().map(|e| e.to_string());
        assert!(
            e.as_deref()
                .is_some_and(|e| e.contains("post") && e.contains("Missing")),
            "{e:?}"
        );
    }
}
