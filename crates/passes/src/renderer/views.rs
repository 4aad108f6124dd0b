//! The views a renderer's frame renders: the main view (the camera a frame is rendered with,
//! into the renderer's or the engine's colour target) and further views added with
//! [`SceneRenderer::add_view`] — a camera of their own into a colour target the renderer keeps
//! (a mirror, a minimap, a second player's screen).
//!
//! Each view has its own options (size, technique, culling, shadows), its own CPU lists and
//! technique states (pyramid, last frame's visibility, query pools, shadow cascades), its own
//! uniforms and sets; the scene's buffers, the pipelines and the executor are shared. Every
//! view's passes are declared on one graph, compiled for the profile and submitted together:
//! the graph orders them, merges what it can and counts their traffic.

use std::sync::Arc;

use tilegraph_scene::{Camera, CameraFrame, DepthConvention, Scene, SceneCursor};
use tilegraph_vk::ash::vk;
use tilegraph_vk::executor::{ImageHandle, Submission};
use tilegraph_vk::readback::RgbaImage;
use tilegraph_vk::{Context, VkError};

use super::fit::{decide_setup, CpuLists};
use super::{SceneRenderer, Target};
use crate::cull::{
    cpu_frustum_visible, cpu_frustum_visible_by_cell, CullState, Culling, FrameLists, GpuCullCounts,
};
use crate::draws::{order_groups, Visible};
use crate::gpu_scene::{visbuf_instance_bits, FrameUniforms};
use crate::hiz::{HizState, ReprojectState};
use crate::occlusion::{OqState, RasterOcclusion};
use crate::options::{check_device, RenderError, RenderOptions};
use crate::setup::{FrameSetup, SceneContent, Technique};
use crate::shadow::{write_shadow_uniforms, ShadowState};
use crate::targets::{create_target, destroy_target};

/// A view of the frame other than the main one ([`SceneRenderer::add_view`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct ViewId(pub(crate) u32);

impl ViewId {
    /// The view of index `index` (what [`Self::index`] gave: from the C ABI).
    pub fn new(index: u32) -> Self {
        ViewId(index)
    }

    /// The view's index among the frame's views (the main view is 0, so a `ViewId` is ≥ 1).
    pub fn index(self) -> usize {
        self.0 as usize
    }
}

/// What the renderer keeps per view.
pub(super) struct View {
    pub(super) options: RenderOptions,
    /// The passes of this view's frames, decided from the scene and the profile.
    pub(super) setup: Arc<FrameSetup>,
    /// The colour target the renderer keeps (`None` for the main view of an engine's
    /// renderer: it renders into the engine's).
    pub(super) target: Option<Target>,
    /// The captured id image (with `capture_ids`).
    pub(super) ids_target: Option<Target>,
    /// The captured depth (with `capture_depth`).
    pub(super) depth_target: Option<Target>,
    pub(super) instance_bits: Option<u32>,
    /// What the CPU decides per frame, kept from frame to frame (no allocation per frame).
    pub(super) cpu: CpuLists,
    /// Where the occlusion queries' groups stand in the scene's changes.
    pub(super) oq_cursor: Option<SceneCursor>,
    /// Occlusion queries: the opaque and alpha-tested instances the last frame drew.
    pub(super) last_drawn: Option<Vec<u32>>,
    /// The newest completed frame's GPU culling counts (read without waiting).
    pub(super) gpu_counts: Option<GpuCullCounts>,
    /// The camera of the last frame rendered.
    pub(super) last_camera: Option<Camera>,
    /// A further view's camera for the next frame (the main view's comes with the frame).
    pub(super) next: Option<CameraFrame>,
    /// The camera frame being prepared and recorded.
    pub(super) current: Option<CameraFrame>,
    /// The depth convention of its camera this frame (the declaration depends on it).
    pub(super) depth: DepthConvention,
    /// Frames this view's targets were rendered in (the first imports them undefined).
    pub(super) frames: u64,
}

impl View {
    /// Keeps the CPU lists' opaque and alpha-tested instances as the frame's drawn set (what
    /// `drawn_instances` reports for techniques the CPU decides).
    fn record_drawn(&mut self) {
        let mut drawn = self.last_drawn.take().unwrap_or_default();
        drawn.clear();
        drawn.extend(self.cpu.visible.iter().map(|m| m.instance));
        drawn.sort_unstable();
        self.last_drawn = Some(drawn);
    }

    /// A view of `options` with its targets: a colour target unless the engine's main view
    /// renders into its own, an id target when the visibility buffer's ids are captured.
    pub(super) fn new(
        ctx: &Context,
        scene: &Scene,
        options: RenderOptions,
        content: SceneContent,
        submission: Submission,
    ) -> Result<Self, RenderError> {
        let instance_bits = check_device(ctx, &options, scene)?;
        let (target, ids_target) = create_targets(ctx, &options, submission)?;
        let depth_target = match options.capture_depth {
            true => match create_depth_target(ctx, &options) {
                Ok(t) => Some(t),
                Err(e) => {
                    for t in [target, ids_target].into_iter().flatten() {
                        destroy_target(ctx, t);
                    }
                    return Err(e);
                }
            },
            false => None,
        };
        let setup = decide_setup(&options, ctx, content);
        Ok(View {
            options,
            setup: Arc::new(setup),
            target,
            ids_target,
            depth_target,
            instance_bits,
            cpu: CpuLists::default(),
            oq_cursor: Some(scene.cursor()),
            last_drawn: None,
            gpu_counts: None,
            last_camera: None,
            next: None,
            current: None,
            depth: DepthConvention::default(),
            frames: 0,
        })
    }

    pub(super) fn destroy(self, ctx: &Context) {
        for t in [self.target, self.ids_target, self.depth_target]
            .into_iter()
            .flatten()
        {
            destroy_target(ctx, t);
        }
    }

    /// The colour target's image as the last frame left it (`None`: the view renders into an
    /// engine's target); the caller waited for the GPU.
    pub(super) fn read_target(&self, ctx: &Context) -> Result<Option<RgbaImage>, RenderError> {
        let Some((_, target)) = &self.target else {
            return Ok(None);
        };
        let pixels = tilegraph_vk::readback::read_image(
            ctx,
            target,
            vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
            0,
        )?;
        Ok(Some(RgbaImage {
            width: self.options.width,
            height: self.options.height,
            pixels,
        }))
    }

    pub(super) fn aspect(&self) -> f32 {
        self.options.width as f32 / self.options.height.max(1) as f32
    }
}

/// The frame's views: the main one, then the further ones in the order they were added (a
/// view's index is its place here).
pub(super) struct Views {
    pub(super) main: View,
    pub(super) further: Vec<View>,
}

impl Views {
    pub(super) fn len(&self) -> usize {
        1 + self.further.len()
    }

    pub(super) fn get(&self, k: usize) -> Option<&View> {
        match k {
            0 => Some(&self.main),
            _ => self.further.get(k - 1),
        }
    }

    pub(super) fn get_mut(&mut self, k: usize) -> Option<&mut View> {
        match k {
            0 => Some(&mut self.main),
            _ => self.further.get_mut(k - 1),
        }
    }

    pub(super) fn iter(&self) -> impl Iterator<Item = &View> {
        std::iter::once(&self.main).chain(&self.further)
    }

    pub(super) fn iter_mut(&mut self) -> impl Iterator<Item = &mut View> {
        std::iter::once(&mut self.main).chain(&mut self.further)
    }

    pub(super) fn destroy(self, ctx: &Context) {
        self.main.destroy(ctx);
        for v in self.further {
            v.destroy(ctx);
        }
    }
}

/// The colour target (for a renderer that submits its own frames, or a further view), and the
/// id target when the ids are captured.
fn create_targets(
    ctx: &Context,
    options: &RenderOptions,
    submission: Submission,
) -> Result<(Option<Target>, Option<Target>), RenderError> {
    let size = (options.width, options.height);
    let target = match submission {
        Submission::Owned => Some(create_target(ctx, size, vk::Format::R8G8B8A8_UNORM)?),
        Submission::Engine => None,
    };
    if !(options.capture_ids && options.technique == Technique::Visbuf) {
        return Ok((target, None));
    }
    match create_target(ctx, size, vk::Format::R32_UINT) {
        Ok(ids) => Ok((target, Some(ids))),
        Err(e) => {
            if let Some(target) = target {
                destroy_target(ctx, target);
            }
            Err(e.into())
        }
    }
}

/// The depth image a view keeps with `capture_depth`: its depth format, every use a frame may
/// make of the depth (attachment, input attachment, sampled), and a copy source.
fn create_depth_target(ctx: &Context, options: &RenderOptions) -> Result<Target, RenderError> {
    let format = match options.depth_format {
        tilegraph_cull::DepthFormat::D16Unorm => vk::Format::D16_UNORM,
        tilegraph_cull::DepthFormat::D32Float => vk::Format::D32_SFLOAT,
    };
    let usage = vk::ImageUsageFlags::DEPTH_STENCIL_ATTACHMENT
        | vk::ImageUsageFlags::INPUT_ATTACHMENT
        | vk::ImageUsageFlags::SAMPLED
        | vk::ImageUsageFlags::TRANSFER_SRC;
    Ok(crate::images::create_image_2d(
        ctx,
        "captured depth",
        (options.width, options.height),
        format,
        usage,
        vk::ImageAspectFlags::DEPTH,
    )?)
}

impl SceneRenderer {
    /// Adds a view to every frame from the next one: `camera` seen with `options` (its size,
    /// technique, culling, shadows, clear colour) into a colour target the renderer keeps
    /// ([`Self::view_target`], left `TRANSFER_SRC_OPTIMAL` after each frame). The scene-wide
    /// options — lighting, GPU timing, instance capacity, texture binding, fragment counting —
    /// are the main view's. The frames in flight are waited for and the renderer's buffers
    /// made again (add views before the first frame where that matters).
    pub fn add_view(
        &mut self,
        ctx: &Context,
        scene: &Scene,
        options: RenderOptions,
        camera: &Camera,
    ) -> Result<ViewId, RenderError> {
        camera
            .validate()
            .map_err(|(field, reason)| RenderError::Camera { field, reason })?;
        let main = self.options();
        let options = RenderOptions {
            lighting: main.lighting,
            gpu_timing: main.gpu_timing,
            instance_capacity: main.instance_capacity,
            texture_binding: main.texture_binding,
            count_fragments: main.count_fragments,
            probe: main.probe,
            ..options
        };
        let index = u32::try_from(self.views.len()).map_err(|_| RenderError::TooManyViews)?;
        let mut view = View::new(ctx, scene, options, self.content, Submission::Owned)?;
        view.next = Some(CameraFrame::new(0, *camera, None, view.aspect()));
        self.views.further.push(view);
        if let Err(e) = self.rebuild(ctx, scene) {
            if let Some(v) = self.views.further.pop() {
                v.destroy(ctx);
            }
            return Err(e);
        }
        log::info!("renderer: view {index} added");
        Ok(ViewId(index))
    }

    /// The further views' count plus the main view.
    pub fn view_count(&self) -> usize {
        self.views.len()
    }

    /// `view`'s camera for the next frame: continuing from its last one, or after a `cut`
    /// (the camera jumped: nothing of the view's last frame applies — single-phase occlusion
    /// culling reuses what the last frame saw).
    pub fn set_view_camera(
        &mut self,
        view: ViewId,
        camera: &Camera,
        cut: bool,
    ) -> Result<(), RenderError> {
        let v = self.further_view(view)?;
        let previous = if cut { None } else { v.last_camera.as_ref() };
        let frame = CameraFrame::new(v.frames as usize, *camera, previous, v.aspect());
        self.set_view_frame(view, &frame)
    }

    /// `view`'s camera frame for the next frame (its previous matrices and cut as for the main
    /// view's [`Self::render_frame`]).
    pub fn set_view_frame(&mut self, view: ViewId, frame: &CameraFrame) -> Result<(), RenderError> {
        frame
            .camera
            .validate()
            .map_err(|(field, reason)| RenderError::Camera { field, reason })?;
        self.further_view_mut(view)?.next = Some(*frame);
        Ok(())
    }

    /// The colour target `view` renders into (`TRANSFER_SRC_OPTIMAL` after a frame).
    pub fn view_target(&self, view: ViewId) -> Result<&ImageHandle, RenderError> {
        let v = self.further_view(view)?;
        v.target
            .as_ref()
            .map(|(_, h)| h)
            .ok_or(RenderError::UnknownView(view.0))
    }

    /// `view`'s image of the last frame (waits for the GPU).
    pub fn read_view_image(
        &mut self,
        ctx: &Context,
        view: ViewId,
    ) -> Result<RgbaImage, RenderError> {
        self.executor.finish(ctx)?;
        self.further_view(view)?
            .read_target(ctx)?
            .ok_or(RenderError::UnknownView(view.0))
    }

    fn further_view(&self, view: ViewId) -> Result<&View, RenderError> {
        match view.index() {
            0 => None,
            i => self.views.get(i),
        }
        .ok_or(RenderError::UnknownView(view.0))
    }

    fn further_view_mut(&mut self, view: ViewId) -> Result<&mut View, RenderError> {
        match view.index() {
            0 => None,
            i => self.views.get_mut(i),
        }
        .ok_or(RenderError::UnknownView(view.0))
    }

    /// View `k`'s CPU culling for `frame` (no GPU wait): the frustum's blended instances, and
    /// its opaque ones for the techniques whose CPU lists draw them.
    pub(super) fn cull_view_on_cpu(
        &mut self,
        scene: &Scene,
        k: usize,
        frame: &CameraFrame,
        subpixel_bits: u32,
    ) -> Result<(), RenderError> {
        let Some(view) = self.views.get_mut(k) else {
            return Ok(());
        };
        view.last_camera = Some(frame.camera);
        let m = frame.current;
        let culling = view.options.culling;
        // Blended geometry is frustum-culled here and sorted back to front by every technique.
        // Techniques whose CPU lists draw opaque geometry (queries, and the pre-pass that raster
        // occlusion tests against) frustum-cull it here too; unculled and GPU-culled frames draw
        // the scene's buckets as they are.
        cpu_frustum_visible(scene.blended_grid(), &m, &mut view.cpu.blended)?;
        if culling.cpu_lists() {
            let opaque = match &mut view.cpu.opaque {
                Some(g) => {
                    g.refit(scene);
                    g
                }
                None => view.cpu.opaque.insert(super::fit::OpaqueGrid::of(scene)),
            };
            if culling == Culling::SoftwareOcclusion {
                let (visible, cells) = (&mut view.cpu.visible, &mut view.cpu.cells);
                cpu_frustum_visible_by_cell(&opaque.grid, &m, visible, cells)?;
            } else {
                cpu_frustum_visible(&opaque.grid, &m, &mut view.cpu.visible)?;
            }
        }
        if let (Culling::Pvs, Some(pvs)) = (culling, &view.options.pvs) {
            // Outside the baked region every instance in the frustum is drawn.
            let cpu = &mut view.cpu;
            if pvs.visible_from(m.eye, view.options.pvs_dilation, &mut cpu.pvs_ids) {
                let ids = &cpu.pvs_ids;
                cpu.visible
                    .retain(|v| ids.binary_search(&v.instance).is_ok());
            }
        }
        if culling == Culling::SoftwareOcclusion {
            view.cpu
                .software
                .get_or_insert_with(Default::default)
                .cull(
                    scene,
                    frame,
                    &crate::occlusion::SoftwareTarget {
                        size: (view.options.width, view.options.height),
                        format: view.options.depth_format,
                        knobs: view.options.software,
                        subpixel_bits,
                    },
                    &view.cpu.cells,
                    &mut view.cpu.visible,
                )
                .map_err(RenderError::Software)?;
        }
        Ok(())
    }

    /// View `k`'s part of the frame written into `slot` (whose previous frame completed): the
    /// occlusion results and GPU counts read, the draw lists built, the uniforms and CPU list
    /// written, the culling inputs written. Leaves `k` the resources' current view.
    pub(super) fn write_view(
        &mut self,
        ctx: &Context,
        scene: &Scene,
        k: usize,
        frame: &CameraFrame,
        slot: usize,
    ) -> Result<(), RenderError> {
        let SceneRenderer {
            views,
            resources: res,
            draw_builder,
            ..
        } = self;
        let lighting = views.main.options.lighting;
        let Some(view) = views.get_mut(k) else {
            return Ok(());
        };
        res.enter_view(k);
        let m = frame.current;
        let (w, h) = (view.options.width, view.options.height);
        let culling = view.options.culling;
        let cpu_lists = culling.cpu_lists();
        if let Some(cull) = res.states.get_mut::<CullState>() {
            // The slot's frame has completed: its counts are there to read.
            if let Some(counts) = cull.collect(ctx, slot)? {
                view.gpu_counts = Some(counts);
            }
        }
        if let Some(oq) = res.states.get_mut::<OqState>() {
            // Occlusion queries: the newest complete frame's results select what this frame
            // draws (read now, never waited for: the acquired slot's frame has completed).
            oq.collect(ctx, slot)?;
            let cpu = &mut view.cpu;
            cpu.mark_visible(scene.instances().len());
            if culling.conditional() {
                // Same-frame results on the GPU; reading the slot only recycles its pool.
                oq.prepare(slot, &m, h as f32, Some(&cpu.mask));
            } else {
                let passed = oq.mask();
                // Every instance in the frustum is queried, drawn or not: a hidden one must be
                // able to come back.
                oq.prepare(slot, &m, h as f32, Some(&cpu.mask));
                cpu.visible
                    .retain(|m| passed.get(m.instance as usize).copied().unwrap_or(true));
                view.record_drawn();
            }
        }
        if matches!(culling, Culling::SoftwareOcclusion | Culling::Pvs) {
            // Decided on the CPU before this function (`cull_view_on_cpu`).
            view.record_drawn();
        }
        let order = view
            .options
            .opaque_order
            .unwrap_or(ctx.profile().passes.opaque_sort);
        order_groups(scene, m.eye, order, &mut view.cpu.groups);
        let capacity = res.scene.capacity();
        draw_builder.build_into(
            scene,
            m.eye,
            &view.cpu.groups,
            Visible {
                opaque: cpu_lists.then_some(view.cpu.visible.as_slice()),
                blended: &view.cpu.blended,
            },
            capacity.cpu_base_of(k),
            &mut res.frame.draws,
        );
        if k == 0 {
            draw_builder.narrow(scene, &mut res.frame.draws);
        }
        res.frame.depth = m.depth;
        view.depth = m.depth;
        let instance_bits =
            visbuf_instance_bits(capacity.instances as usize, scene.max_mesh_triangles());
        if view.options.technique == Technique::Visbuf && instance_bits.is_none() {
            return Err(RenderError::VisbufIdOverflow {
                instances: capacity.instances as usize,
                max_triangles: scene.max_mesh_triangles(),
            });
        }
        crate::options::check_gbuffer_materials(view.options.technique, scene)?;
        let mut uniforms = FrameUniforms::new(
            m.view_projection,
            m.depth,
            (w, h),
            &lighting,
            instance_bits.unwrap_or(32),
            m.eye,
        );
        let atlas = res.scene.atlas(k).map(|a| a.desc).ok_or_else(|| {
            RenderError::Vk(VkError::Invalid {
                what: "shadows".into(),
                reason: format!("no shadow atlas for view {k}"),
            })
        })?;
        write_shadow_uniforms(
            &mut uniforms,
            &frame.camera,
            view.aspect(),
            scene,
            lighting.direction,
            &view.options.shadows,
            atlas,
        );
        if let Some(s) = res.states.get_mut::<ShadowState>() {
            s.set_instances(scene.instances().len() as u32);
        }
        view.instance_bits = instance_bits;
        res.scene
            .write_view(ctx, slot, k, &uniforms, &res.frame.draws.instances)?;
        let pyramid = res.states.get::<HizState>().map(HizState::info);
        if let Some(cull) = res.states.get_mut::<CullState>() {
            let lists = FrameLists {
                groups: &view.cpu.groups,
                stride: scene.buckets().stride(),
                instance_slots: scene.instances().len() as u32,
            };
            // Per-triangle culling packs into the index buffer's tail, where this frame's
            // geometry (grown if need be) left it.
            cull.index_tail = res.scene.index_tail(k);
            cull.write_frame(ctx, slot, frame, lists, (w, h), pyramid)?;
        }
        let recheck = res.states.get::<CullState>().map(CullState::recheck);
        if let (Some(r), Some(recheck)) = (res.states.get_mut::<RasterOcclusion>(), recheck) {
            r.set_recheck(recheck);
        }
        if let Some(r) = res.states.get_mut::<ReprojectState>() {
            r.write_frame(frame, pyramid.and_then(|p| p.built_from));
        }
        Ok(())
    }
}
