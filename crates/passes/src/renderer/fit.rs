//! Keeping a renderer fit for a scene that changes: room in its buffers, per-instance layouts
//! that cannot follow changes made again, the frame's passes decided again when a material
//! class appears or disappears; and what the CPU decides per frame, kept between frames.

use std::sync::Arc;

use tilegraph_scene::{
    Change, DrawGroup, GridMember, LooseGrid, MaterialClass, Scene, SceneCursor,
};
use tilegraph_vk::Context;

use super::{create_resources, SceneRenderer};
use crate::cull::CullState;
use crate::gpu_scene::Capacity;
use crate::occlusion::OqState;
use crate::options::{RenderError, RenderOptions};
use crate::setup::{FrameSetup, SceneContent};

/// What the CPU decides per frame: the frustum's blended instances (and opaque ones for the
/// techniques whose CPU lists draw them), a per-slot mask of them for the occlusion queries,
/// and the scene's buckets in the frame's draw order.
#[derive(Debug, Default)]
pub(super) struct CpuLists {
    pub(super) visible: Vec<GridMember>,
    pub(super) blended: Vec<GridMember>,
    pub(super) mask: Vec<bool>,
    /// The slots set in `mask` (cleared next frame: the cost follows what is visible).
    marked: Vec<u32>,
    pub(super) groups: Vec<DrawGroup>,
    /// The opaque and alpha-tested instances in a grid, for techniques whose CPU lists draw
    /// them (made at their first frame).
    pub(super) opaque: Option<OpaqueGrid>,
    /// Software occlusion's buffer and occluder meshes (made at its first frame), and the runs
    /// of `visible` that share a grid cell (its cells are tested before their members).
    pub(super) software: Option<crate::occlusion::SoftwareCull>,
    pub(super) cells: Vec<tilegraph_scene::CellRun>,
    /// `Culling::Pvs`: the instances the camera's cell (and its neighbours) may see, ascending.
    pub(super) pvs_ids: Vec<u32>,
}

/// A renderer's grid of the scene's drawn opaque and alpha-tested instances, refitted from the
/// scene's changes before each frame: only the techniques that need it pay for it (the scene
/// keeps no such grid, so a move costs the GPU-culled techniques nothing here).
#[derive(Debug)]
pub(super) struct OpaqueGrid {
    pub(super) grid: LooseGrid,
    cursor: Option<SceneCursor>,
}

impl OpaqueGrid {
    pub(super) fn of(scene: &Scene) -> Self {
        let mut g = OpaqueGrid {
            grid: LooseGrid::new(scene.bounds(), 0),
            cursor: None,
        };
        g.refit(scene);
        g
    }

    /// Brings the grid up to `scene`: the instances that changed placed again, or (a cursor the
    /// scene no longer follows, the world moved as a whole) every instance.
    pub(super) fn refit(&mut self, scene: &Scene) {
        match self.cursor.and_then(|c| scene.changes_since(c)) {
            Some(changes) if !changes.contains(&Change::Everything) => {
                for c in changes {
                    if let Change::Instance(i) | Change::Moved(i) = c {
                        self.place(scene, *i);
                    }
                }
            }
            _ => {
                let n = scene.drawn_by_class();
                self.grid = LooseGrid::new(scene.bounds(), (n.opaque + n.alpha_tested) as usize);
                for i in 0..scene.instances().len() as u32 {
                    self.place(scene, i);
                }
            }
        }
        self.cursor = Some(scene.cursor());
    }

    fn place(&mut self, scene: &Scene, i: u32) {
        if self.grid.contains(i) {
            self.grid.remove(i);
        }
        let Some(inst) = scene.instances().get(i as usize) else {
            return;
        };
        let opaque = !scene
            .instance_material(inst)
            .is_some_and(|m| m.class == MaterialClass::Blended);
        if inst.flags.is_drawn() && opaque {
            self.grid.insert(i, inst.mesh.0, &inst.bounds);
        }
    }
}

impl CpuLists {
    /// `mask` for a scene of `slots` instance slots: true exactly for `visible`.
    pub(super) fn mark_visible(&mut self, slots: usize) {
        for &i in &self.marked {
            if let Some(m) = self.mask.get_mut(i as usize) {
                *m = false;
            }
        }
        self.mask.resize(slots, false);
        self.marked.clear();
        for v in &self.visible {
            if let Some(m) = self.mask.get_mut(v.instance as usize) {
                *m = true;
                self.marked.push(v.instance);
            }
        }
    }
}

/// The frame setup of `options` for a scene holding `content`, on `ctx`'s profile.
pub(super) fn decide_setup(
    options: &RenderOptions,
    ctx: &Context,
    content: SceneContent,
) -> FrameSetup {
    crate::setup::decide_for(
        content,
        ctx.profile(),
        options.technique,
        options.culling,
        crate::setup::PrepassKnobs {
            depth: options.depth_prepass,
            alpha: options.alpha_prepass,
        },
    )
}

impl SceneRenderer {
    /// Makes the renderer fit `scene` before a frame: buffers with room for its instances and
    /// lists (else new ones: the frames in flight are waited for, once per doubling), per-
    /// instance layouts following the changes (the cluster bases at the changes' cost, in the
    /// same buffers until they outgrow them by a quarter) or made again where they cannot
    /// (query groups when a quarter of the instances changed), and the frame's passes decided
    /// again when a material class appears or disappears.
    pub(super) fn fit(&mut self, ctx: &Context, scene: &Scene) -> Result<(), RenderError> {
        let mut rebuild = !self.resources.scene.capacity().holds(scene);
        for k in 0..self.views.len() {
            let (Some(view), res) = (self.views.get_mut(k), &mut self.resources) else {
                continue;
            };
            res.enter_view(k);
            // The cluster layout follows the instances that came or went, in the same buffers
            // where it fits (the culling history and the pyramid stay), else new buffers.
            if !rebuild {
                if let Some(cull) = res.states.get_mut::<CullState>() {
                    rebuild |= !cull.follow_clusters(scene);
                }
            }
            if let Some(oq) = res.states.get_mut::<OqState>() {
                match view.oq_cursor.and_then(|c| scene.changes_since(c)) {
                    Some(changes) => {
                        for c in changes {
                            if let Change::Instance(i) | Change::Moved(i) = c {
                                oq.forget(*i);
                            }
                        }
                        rebuild |= oq.forgotten() * 4 > scene.live_instances().max(64);
                    }
                    None => rebuild = true,
                }
            }
            view.oq_cursor = Some(scene.cursor());
        }
        self.resources.enter_view(0);
        if rebuild {
            self.rebuild(ctx, scene)?;
        }
        let content = SceneContent::of(scene);
        if content.presence() != self.content.presence() {
            for v in self.views.iter_mut() {
                v.setup = Arc::new(decide_setup(&v.options, ctx, content));
            }
            self.declared = None;
        }
        self.content = content;
        Ok(())
    }

    /// New buffers and technique states for `scene` and every view (the frames in flight are
    /// waited for; the old ones go), and the frame declared again.
    pub(super) fn rebuild(&mut self, ctx: &Context, scene: &Scene) -> Result<(), RenderError> {
        self.executor.finish(ctx)?;
        let hint = self
            .options()
            .instance_capacity
            .max(self.resources.scene.capacity().instances);
        let capacity = Capacity::for_scene(scene, hint).with_views(self.views.len());
        let lod_levels = self
            .views
            .iter()
            .map(|v| crate::options::lod_levels(&v.options, scene))
            .max()
            .unwrap_or(1);
        super::check_capacity(ctx, capacity, lod_levels)?;
        log::info!(
            "renderer: new buffers for {} instance slots, list stride {}, {} views ({:?})",
            scene.instances().len(),
            scene.buckets().stride(),
            self.views.len(),
            capacity
        );
        let options: Vec<&RenderOptions> = self.views.iter().map(|v| &v.options).collect();
        let fresh = create_resources(
            ctx,
            scene,
            &options,
            self.executor.frames_in_flight(),
            capacity,
        )?;
        self.declared = None;
        let mut old = std::mem::replace(&mut self.resources, fresh);
        // The engine's materials stay registered (before, new buffers — a scene outgrowing its
        // room, a mirrored copy with clusters attached — drew them with tilegraph's shaders).
        old.pipelines
            .hand_materials_to(&mut self.resources.pipelines);
        old.destroy(ctx);
        for v in self.views.iter_mut() {
            v.last_drawn = None;
            v.gpu_counts = None;
        }
        Ok(())
    }
}
