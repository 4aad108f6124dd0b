//! [`SceneRenderer`]: one scene rendered frame after frame — the frame setup's passes, composed
//! from the `add_*` functions, compiled for the context's profile, executed.
//!
//! A frame is two halves. [`SceneRenderer::prepare_frame`] does the scene's CPU work and writes
//! this frame's data into the slot's buffers: CPU frustum culling where the technique needs it,
//! the draw lists in the profile's order, camera-relative instances, the culling inputs, the
//! occlusion queries' results. Then the frame's graph is recorded: [`SceneRenderer::render_frame`]
//! declares the scene's passes (`compose.rs`) only when what they depend on
//! changed (the depth convention, and the first frame's imports) and otherwise reuses the
//! declared payloads and the compiled plan; [`SceneRenderer::execute_graph`] records a graph the
//! caller declared — an engine's frame, the shipped passes and its own on one graph.

mod fit;
mod materials;
mod memory;
mod readback;
mod resources;

use std::sync::Arc;

use tilegraph_graph::{Format, ImageId, Import, Plan, PlanCache, ResourceState};
use tilegraph_scene::{Camera, CameraFrame, DepthConvention, Scene, SceneCursor};
use tilegraph_vk::ash::vk;
use tilegraph_vk::executor::{
    EngineFrame, Executor, External, Externals, FrameStats, ImageHandle, PassContext, Submission,
};
use tilegraph_vk::frames::DEFAULT_FRAMES_IN_FLIGHT;
use tilegraph_vk::queries::{GpuTiming, PassMedian};
use tilegraph_vk::{Context, Image, VkError};

use crate::compose::{declare_scene, kept_import, ColorTarget, DeclarationKey, SceneFrame};
use crate::cull::{cpu_frustum_visible, CullState, Culling, FrameLists, GpuCullCounts};
use crate::draws::{order_groups, DrawBuilder, Visible};
use crate::frame::{FrameGraph, Payload, SceneResources};
use crate::gpu_scene::{visbuf_instance_bits, Capacity, FrameUniforms};
use crate::hiz::{HizState, ReprojectState};
use crate::lint::lint_frame;
use crate::occlusion::{OqState, RasterOcclusion};
use crate::options::{check_device, FrameReport, RenderError, RenderOptions};
use crate::setup::{FrameSetup, SceneContent, Technique};
use crate::shadow::{write_shadow_uniforms, ShadowState};
use crate::targets::{create_target, destroy_target};
use fit::{decide_setup, CpuLists};
pub use memory::{scene_memory, SceneMemory};
pub use readback::PixelOwners;
use resources::create_resources;

/// An image the renderer keeps across frames, with its view.
type Target = (Image, ImageHandle);

/// The scene's frame as declared and compiled.
struct DeclaredFrame {
    key: DeclarationKey,
    plan: Arc<Plan>,
    /// Indexed by `PassId`; `None` for pruned passes.
    payloads: Vec<Option<Payload>>,
    externals: Externals,
    /// The colour target's id (its image may change from frame to frame: an engine's).
    color: ImageId,
}

/// An engine's colour target for one frame ([`SceneRenderer::record`]): the image the frame
/// renders into (a swapchain image, an offscreen target of the engine's), the state the engine
/// left it in, and the state the frame must leave it in.
#[derive(Debug, Clone, Copy)]
pub struct EngineTarget<'a> {
    /// Its extent must be the renderer's size, its format a colour format of the graph's.
    pub image: &'a ImageHandle,
    /// Layout, stages and access of the engine's last use (`ResourceState::UNDEFINED` discards
    /// the content, as for an acquired swapchain image).
    pub initial: ResourceState,
    /// Where the frame leaves it: `ResourceState::PRESENT` for a swapchain image, a shader
    /// read for the engine's post-processing, `TRANSFER_SRC` for a copy.
    pub final_state: ResourceState,
}

/// Renders one scene frame after frame.
pub struct SceneRenderer {
    options: RenderOptions,
    /// The passes of this renderer's frames, decided once from the scene and the profile.
    setup: Arc<FrameSetup>,
    executor: Executor,
    resources: SceneResources,
    /// The colour target the renderer keeps (`None` when it renders into an engine's).
    target: Option<Target>,
    /// The captured id image (with `capture_ids`).
    ids_target: Option<Target>,
    instance_bits: Option<u32>,
    frames: u64,
    last_slot: usize,
    /// Instance slots of the scene the last frame drew.
    last_instances: usize,
    /// What the CPU decides per frame, kept from frame to frame (no allocation per frame).
    cpu: CpuLists,
    draw_builder: DrawBuilder,
    /// The scene's structure version the per-instance layouts were made for.
    structure: u64,
    /// Where the occlusion queries' groups stand in the scene's changes.
    oq_cursor: Option<SceneCursor>,
    /// The drawn instances per class the frame setup was decided for.
    content: SceneContent,
    /// Occlusion queries: the opaque and alpha-tested instances the last frame drew.
    last_drawn: Option<Vec<u32>>,
    /// The newest completed frame's GPU culling counts (read without waiting).
    gpu_counts: Option<GpuCullCounts>,
    /// The camera of the last frame rendered.
    last_camera: Option<Camera>,
    declared: Option<DeclaredFrame>,
    /// Plans of graphs declared by the caller ([`Self::execute_graph`]).
    plan_cache: PlanCache,
    /// The next frame recorded is traced for the state lint.
    lint_armed: bool,
}

impl SceneRenderer {
    /// A renderer that submits its own frames into a colour target it keeps.
    pub fn new(ctx: &Context, scene: &Scene, options: RenderOptions) -> Result<Self, RenderError> {
        Self::build(
            ctx,
            scene,
            options,
            Submission::Owned,
            DEFAULT_FRAMES_IN_FLIGHT,
        )
    }

    /// A renderer whose frames the engine submits ([`SceneRenderer::record`]): with
    /// `frames_in_flight` slots, rendering into the engine's colour target (it keeps none).
    pub fn for_engine(
        ctx: &Context,
        scene: &Scene,
        options: RenderOptions,
        frames_in_flight: usize,
    ) -> Result<Self, RenderError> {
        Self::build(ctx, scene, options, Submission::Engine, frames_in_flight)
    }

    fn build(
        ctx: &Context,
        scene: &Scene,
        options: RenderOptions,
        submission: Submission,
        frames_in_flight: usize,
    ) -> Result<Self, RenderError> {
        let instance_bits = check_device(ctx, &options, scene)?;
        let mut executor = match submission {
            Submission::Owned => Executor::with_frames(ctx, frames_in_flight, 256)?,
            Submission::Engine => Executor::for_engine(ctx, frames_in_flight)?,
        };
        if let Err(e) = executor.set_timing(ctx, options.gpu_timing) {
            executor.destroy(ctx);
            return Err(e.into());
        }
        let capacity = Capacity::for_scene(scene, options.instance_capacity);
        if let Err(e) = check_capacity(ctx, capacity) {
            executor.destroy(ctx);
            return Err(e);
        }
        let parts = create_resources(ctx, scene, &options, executor.frames_in_flight(), capacity)
            .and_then(
                |resources| match create_targets(ctx, &options, submission) {
                    Ok(targets) => Ok((resources, targets)),
                    Err(e) => {
                        resources.destroy(ctx);
                        Err(e)
                    }
                },
            );
        let (resources, (target, ids_target)) = match parts {
            Ok(p) => p,
            Err(e) => {
                executor.destroy(ctx);
                return Err(e);
            }
        };
        let content = SceneContent::of(scene);
        let setup = decide_setup(&options, ctx, content);
        Ok(SceneRenderer {
            options,
            setup: Arc::new(setup),
            executor,
            resources,
            target,
            ids_target,
            instance_bits,
            frames: 0,
            last_slot: 0,
            last_instances: scene.instances().len(),
            cpu: CpuLists::default(),
            draw_builder: DrawBuilder::default(),
            structure: scene.structure_version(),
            oq_cursor: Some(scene.cursor()),
            content,
            last_drawn: None,
            gpu_counts: None,
            last_camera: None,
            declared: None,
            plan_cache: PlanCache::new(),
            lint_armed: false,
        })
    }

    pub fn options(&self) -> &RenderOptions {
        &self.options
    }

    /// Sets the heavy-material ALU iterations for the next frames.
    pub fn set_heavy_iterations(&mut self, iterations: u32) {
        self.options.lighting.heavy_iterations = iterations;
    }

    /// Points the directional light (and its shadows) along `to_light` from the next frame.
    pub fn set_light_direction(&mut self, to_light: glam::Vec3) {
        self.options.lighting.direction = to_light;
    }

    /// Gives the directional light `color` (linear RGB) from the next frame.
    pub fn set_light_color(&mut self, color: glam::Vec3) {
        self.options.lighting.color = color;
    }

    /// Which passes this renderer's frames have.
    pub fn setup(&self) -> &FrameSetup {
        &self.setup
    }

    /// Lints the next frame: every pipeline it binds is traced and checked against the
    /// profile's state rules ([`FrameReport::lint`]). The frames after it are not traced.
    pub fn lint_next_frame(&mut self) {
        self.lint_armed = true;
    }

    /// Starts the lint's trace for the frame about to record when one was asked for; drops
    /// what a failed frame left (a frame that fails is not linted).
    fn arm_trace(&mut self) {
        let pipelines = &mut self.resources.pipelines;
        pipelines.take_trace();
        if std::mem::take(&mut self.lint_armed) {
            pipelines.start_trace();
        }
    }

    /// The colour target every frame ends in (`TRANSFER_SRC_OPTIMAL` after a frame); `None`
    /// for a renderer that draws into an engine's target.
    pub fn target(&self) -> Option<&ImageHandle> {
        self.target.as_ref().map(|(_, h)| h)
    }

    /// Renders one frame from a lone `camera`: a still camera when it is the last frame's
    /// camera, else a cut (no previous frame to reproject).
    pub fn render(
        &mut self,
        ctx: &Context,
        scene: &Scene,
        camera: &Camera,
    ) -> Result<FrameReport, RenderError> {
        let m = camera.matrices(self.options.width as f32 / self.options.height as f32);
        let frame = CameraFrame {
            index: 0,
            camera: *camera,
            cut: self.last_camera != Some(*camera),
            current: m,
            previous: m,
            reproject: m.view_projection,
        };
        self.render_frame(ctx, scene, &frame)
    }

    /// Renders one frame of a camera path (its previous matrices feed single-phase HiZ).
    pub fn render_frame(
        &mut self,
        ctx: &Context,
        scene: &Scene,
        frame: &CameraFrame,
    ) -> Result<FrameReport, RenderError> {
        let Some((_, handle)) = &self.target else {
            return Err(RenderError::EngineSubmits);
        };
        let handle = handle.clone();
        self.prepare_frame(ctx, scene, frame)?;
        let color = ColorTarget {
            format: Format::R8G8B8A8_UNORM,
            import: kept_import(self.frames == 0),
        };
        self.run_scene(ctx, frame.current.depth, color, &handle, None)
    }

    /// Records one frame of a camera path into the engine's command buffer and colour target
    /// (a renderer made with [`SceneRenderer::for_engine`]). Nothing is submitted: the engine
    /// submits `engine.command_buffer` on the context's queue after the frames it recorded
    /// before, waits for it before handing `engine.slot` again, and owns its swapchain's
    /// synchronisation (EMBEDDING.md). An unchanged frame reuses its declaration and plan.
    pub fn record(
        &mut self,
        ctx: &Context,
        scene: &Scene,
        frame: &CameraFrame,
        engine: EngineFrame,
        target: &EngineTarget<'_>,
    ) -> Result<FrameReport, RenderError> {
        let color = self.check_target(target)?;
        self.prepare_frame_in_slot(ctx, scene, frame, engine.slot)?;
        self.run_scene(ctx, frame.current.depth, color, target.image, Some(engine))
    }

    /// The engine's target as the frame declares it, or what is wrong with it.
    fn check_target(&self, target: &EngineTarget<'_>) -> Result<ColorTarget, RenderError> {
        let (w, h) = (self.options.width, self.options.height);
        let extent = target.image.extent;
        if (extent.width, extent.height) != (w, h) {
            return Err(RenderError::Target(format!(
                "its extent {}x{} is not the renderer's {w}x{h}",
                extent.width, extent.height
            )));
        }
        let raw = target.image.format.as_raw();
        let format = Format::from_vk_raw(raw)
            .filter(|f| !f.is_depth_stencil())
            .ok_or_else(|| {
                RenderError::Target(format!(
                    "VkFormat {raw} is not a colour format of the graph's"
                ))
            })?;
        Ok(ColorTarget {
            format,
            import: Import {
                initial: target.initial,
                content: tilegraph_graph::InitialContent::Discard,
                final_state: target.final_state,
            },
        })
    }

    /// Declares the scene's frame when what it depends on changed, and records it: submitted
    /// by the executor, or into the engine's command buffer.
    fn run_scene(
        &mut self,
        ctx: &Context,
        depth: DepthConvention,
        color: ColorTarget,
        image: &ImageHandle,
        engine: Option<EngineFrame>,
    ) -> Result<FrameReport, RenderError> {
        self.arm_trace();
        let key = DeclarationKey {
            depth,
            // Only the id target the renderer keeps is imported differently on the first
            // frame (the colour target's import is in `color`).
            first_frame: self.frames == 0 && self.ids_target.is_some(),
            color,
            materials: self.resolve_materials(ctx),
        };
        let declare = self.declared.as_ref().is_none_or(|d| d.key != key);
        if declare {
            self.declared = None;
            let profile = ctx.profile();
            let declared = declare_scene(&SceneFrame {
                options: &self.options,
                setup: &self.setup,
                profile,
                key,
                states: &self.resources.states,
                target: image,
                ids_target: self.ids_target.as_ref().map(|(_, h)| h),
                atlas: &self.resources.scene.shadow_atlas,
            });
            let (plan, payloads) = declared.graph.compile(profile)?.into_plan_and_payloads();
            self.declared = Some(DeclaredFrame {
                key,
                plan: Arc::new(plan),
                payloads,
                externals: declared.externals,
                color: declared.color,
            });
        }
        let SceneRenderer {
            executor,
            resources,
            declared,
            ..
        } = self;
        let Some(declared) = declared.as_mut() else {
            // Declared just above.
            return Err(RenderError::Vk(VkError::Invalid {
                what: "scene renderer".into(),
                reason: "no declared frame".into(),
            }));
        };
        // An engine's target may be another image every frame (its swapchain's).
        declared
            .externals
            .insert(declared.color, External::Image(image.clone()));
        let DeclaredFrame {
            plan,
            payloads,
            externals,
            ..
        } = declared;
        let upload = resources.scene.take_upload();
        let mut prologue = |ctx: &Context, cb: vk::CommandBuffer| upload.record(ctx, cb);
        let mut record = |id: tilegraph_graph::PassId, pc: &mut PassContext<'_>| match payloads
            .get_mut(id.index())
            .and_then(Option::as_mut)
        {
            Some(p) => p(pc, resources),
            None => Ok(()),
        };
        let stats = match engine {
            None => executor.execute_with(ctx, plan, externals, &mut prologue, &mut record),
            Some(f) => executor.record_with(ctx, plan, externals, f, &mut prologue, &mut record),
        };
        resources.scene.end_upload(upload, stats.is_ok());
        let stats = stats?;
        let plan = Arc::clone(plan);
        self.finish_frame(ctx, plan, stats, declare)
    }

    /// Records and submits a frame the caller declared on `graph` — the shipped `add_*`
    /// functions and its own passes — after [`Self::prepare_frame`]; `externals` gives the
    /// physical resources of its imports. A graph whose declarations equal the last one's
    /// reuses its plan.
    pub fn execute_graph(
        &mut self,
        ctx: &Context,
        graph: FrameGraph,
        externals: &Externals,
    ) -> Result<FrameReport, RenderError> {
        self.run_graph(ctx, graph, externals, None)
    }

    /// [`Self::execute_graph`] for a renderer whose frames the engine submits: records into
    /// `engine.command_buffer`, after [`Self::prepare_frame_in_slot`] with `engine.slot`.
    pub fn record_graph(
        &mut self,
        ctx: &Context,
        graph: FrameGraph,
        externals: &Externals,
        engine: EngineFrame,
    ) -> Result<FrameReport, RenderError> {
        self.run_graph(ctx, graph, externals, Some(engine))
    }

    fn run_graph(
        &mut self,
        ctx: &Context,
        graph: FrameGraph,
        externals: &Externals,
        engine: Option<EngineFrame>,
    ) -> Result<FrameReport, RenderError> {
        self.arm_trace();
        let mut frame = self.plan_cache.compile(graph, ctx.profile())?;
        let resources = &mut self.resources;
        let upload = resources.scene.take_upload();
        let mut prologue = |ctx: &Context, cb: vk::CommandBuffer| upload.record(ctx, cb);
        let mut record = |id: tilegraph_graph::PassId, pc: &mut PassContext<'_>| match frame
            .payloads
            .get_mut(id.index())
            .and_then(Option::as_mut)
        {
            Some(p) => p(pc, resources),
            None => Ok(()),
        };
        let plan = &frame.plan;
        let stats = match engine {
            None => self
                .executor
                .execute_with(ctx, plan, externals, &mut prologue, &mut record),
            Some(f) => {
                self.executor
                    .record_with(ctx, plan, externals, f, &mut prologue, &mut record)
            }
        };
        self.resources.scene.end_upload(upload, stats.is_ok());
        let stats = stats?;
        self.finish_frame(ctx, frame.plan, stats, !frame.reused)
    }

    fn finish_frame(
        &mut self,
        ctx: &Context,
        plan: Arc<Plan>,
        stats: FrameStats,
        declared: bool,
    ) -> Result<FrameReport, RenderError> {
        // After a rebuild, the pipelines of the destroyed render passes go (at the first frame
        // that succeeds after it: the floor only rises).
        self.resources
            .pipelines
            .prune(ctx, self.executor.render_pass_serial_floor());
        self.frames += 1;
        let lint = self
            .resources
            .pipelines
            .take_trace()
            .map(|trace| Arc::new(lint_frame(ctx.profile(), &plan, &trace)));
        let draws = &self.resources.frame.draws;
        Ok(FrameReport {
            lint,
            setup: Arc::clone(&self.setup),
            plan,
            stats,
            declared,
            draws: draws.opaque.len() + draws.alpha_tested.len() + draws.blended.len(),
            triangles: draws.triangles(),
            gpu_culling: self.gpu_counts,
        })
    }

    /// The scene's CPU work for `frame`, written into the next frame slot's buffers (waiting for
    /// that slot's previous frame): CPU frustum culling where the technique needs it, the
    /// occlusion queries' newest results, the draw lists, instances and uniforms, and the GPU
    /// culling's inputs.
    pub fn prepare_frame(
        &mut self,
        ctx: &Context,
        scene: &Scene,
        frame: &CameraFrame,
    ) -> Result<(), RenderError> {
        self.prepare(ctx, scene, frame, None)
    }

    /// [`Self::prepare_frame`] into the engine's frame slot `slot` (a renderer whose frames
    /// the engine submits; the GPU has finished the slot's previous frame).
    pub fn prepare_frame_in_slot(
        &mut self,
        ctx: &Context,
        scene: &Scene,
        frame: &CameraFrame,
        slot: usize,
    ) -> Result<(), RenderError> {
        let slots = self.executor.frames_in_flight();
        if slot >= slots {
            return Err(RenderError::Vk(VkError::Invalid {
                what: "engine frame".into(),
                reason: format!(
                    "slot {slot} out of the {slots} frames in flight the renderer was made for"
                ),
            }));
        }
        self.prepare(ctx, scene, frame, Some(slot))
    }

    fn prepare(
        &mut self,
        ctx: &Context,
        scene: &Scene,
        frame: &CameraFrame,
        slot: Option<usize>,
    ) -> Result<(), RenderError> {
        self.fit(ctx, scene)?;
        self.prepare_materials(ctx, scene)?;
        let (w, h) = (self.options.width, self.options.height);
        self.last_camera = Some(frame.camera);
        let m = frame.current;
        let culling = self.options.culling;
        // Blended geometry is frustum-culled here and sorted back to front by every technique.
        // Techniques whose CPU lists draw opaque geometry (queries, and the pre-pass that raster
        // occlusion tests against) frustum-cull it here too; unculled and GPU-culled frames draw
        // the scene's buckets as they are.
        let cpu_lists = culling.uses_queries() || culling == Culling::RasterOcclusion;
        cpu_frustum_visible(scene.blended_grid(), &m, &mut self.cpu.blended)?;
        if cpu_lists {
            let opaque = match &mut self.cpu.opaque {
                Some(g) => {
                    g.refit(scene);
                    g
                }
                None => self.cpu.opaque.insert(fit::OpaqueGrid::of(scene)),
            };
            cpu_frustum_visible(&opaque.grid, &m, &mut self.cpu.visible)?;
        }
        let slot = match slot {
            Some(s) => s,
            None => self.executor.acquire_slot(ctx)?,
        };
        if let Some(cull) = self.resources.states.get_mut::<CullState>() {
            // The slot's frame has completed: its counts are there to read.
            if let Some(counts) = cull.collect(ctx, slot)? {
                self.gpu_counts = Some(counts);
            }
        }
        if let Some(oq) = self.resources.states.get_mut::<OqState>() {
            // Occlusion queries: the newest complete frame's results select what this frame
            // draws (read now, never waited for: the acquired slot's frame has completed).
            oq.collect(ctx, slot)?;
            self.cpu.mark_visible(scene.instances().len());
            if culling.conditional() {
                // Same-frame results on the GPU; reading the slot only recycles its pool.
                oq.prepare(slot, &m, h as f32, Some(&self.cpu.mask));
            } else {
                let passed = oq.mask();
                // Every instance in the frustum is queried, drawn or not: a hidden one must be
                // able to come back.
                oq.prepare(slot, &m, h as f32, Some(&self.cpu.mask));
                self.cpu
                    .visible
                    .retain(|m| passed.get(m.instance as usize).copied().unwrap_or(true));
                let mut drawn = self.last_drawn.take().unwrap_or_default();
                drawn.clear();
                drawn.extend(self.cpu.visible.iter().map(|m| m.instance));
                drawn.sort_unstable();
                self.last_drawn = Some(drawn);
            }
        }
        let profile = ctx.profile();
        let order = self
            .options
            .opaque_order
            .unwrap_or(profile.passes.opaque_sort);
        order_groups(scene, m.eye, order, &mut self.cpu.groups);
        let res = &mut self.resources;
        let capacity = res.scene.capacity();
        self.draw_builder.build_into(
            scene,
            m.eye,
            &self.cpu.groups,
            Visible {
                opaque: cpu_lists.then_some(self.cpu.visible.as_slice()),
                blended: &self.cpu.blended,
            },
            capacity.cpu_base(),
            &mut res.frame.draws,
        );
        res.frame.depth = m.depth;
        let instance_bits =
            visbuf_instance_bits(capacity.instances as usize, scene.max_mesh_triangles());
        if self.options.technique == Technique::Visbuf && instance_bits.is_none() {
            return Err(RenderError::VisbufIdOverflow {
                instances: capacity.instances as usize,
                max_triangles: scene.max_mesh_triangles(),
            });
        }
        let mut uniforms = FrameUniforms::new(
            m.view_projection,
            m.depth,
            (w, h),
            &self.options.lighting,
            instance_bits.unwrap_or(32),
            m.eye,
        );
        write_shadow_uniforms(
            &mut uniforms,
            &frame.camera,
            w as f32 / h.max(1) as f32,
            scene,
            self.options.lighting.direction,
            &self.options.shadows,
            res.scene.shadow_atlas.desc,
        );
        if let Some(s) = res.states.get_mut::<ShadowState>() {
            s.set_instances(scene.instances().len() as u32);
        }
        self.instance_bits = instance_bits;
        res.scene
            .write_frame(ctx, slot, scene, &uniforms, &res.frame.draws.instances)?;
        self.last_slot = slot;
        self.last_instances = scene.instances().len();
        let pyramid = res.states.get::<HizState>().map(HizState::info);
        if let Some(cull) = res.states.get_mut::<CullState>() {
            let lists = FrameLists {
                groups: &self.cpu.groups,
                stride: scene.buckets().stride(),
                instance_slots: scene.instances().len() as u32,
            };
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

    /// Waits for the frames in flight, collecting their GPU timings.
    pub fn finish(&mut self, ctx: &Context) -> Result<(), RenderError> {
        Ok(self.executor.finish(ctx)?)
    }

    /// Median GPU time per pass over the frames rendered so far (call [`Self::finish`] first).
    pub fn medians(&self) -> Vec<PassMedian> {
        self.executor.medians()
    }

    /// Graphics pipelines cached now (those of render passes the executor destroyed are
    /// dropped after the frame that rebuilt them).
    pub fn cached_pipelines(&self) -> usize {
        self.resources.pipelines.len()
    }

    /// Forgets the GPU timings of the frames so far: [`Self::medians`] then covers the frames
    /// rendered after this (call [`Self::finish`] first, so no earlier frame is still to be
    /// collected).
    pub fn clear_timings(&mut self) {
        self.executor.clear_timings();
    }

    pub fn executor(&self) -> &Executor {
        &self.executor
    }

    /// What the GPU queries of the next frames measure ([`RenderOptions::gpu_timing`]). A
    /// change waits for the frames in flight and forgets the timings so far.
    pub fn set_gpu_timing(&mut self, ctx: &Context, timing: GpuTiming) -> Result<(), RenderError> {
        self.executor.set_timing(ctx, timing)?;
        self.options.gpu_timing = timing;
        Ok(())
    }

    pub fn destroy(self, ctx: &Context) {
        let SceneRenderer {
            executor,
            resources,
            target,
            ids_target,
            declared,
            ..
        } = self;
        executor.destroy(ctx);
        // The payloads only hold handles; dropped before what they name.
        drop(declared);
        resources.destroy(ctx);
        if let Some(target) = target {
            destroy_target(ctx, target);
        }
        if let Some(ids) = ids_target {
            destroy_target(ctx, ids);
        }
    }
}

/// Whether the buffers of `capacity` fit the device's storage buffer range.
fn check_capacity(ctx: &Context, capacity: Capacity) -> Result<(), RenderError> {
    let needed_bytes = capacity.largest_storage_buffer();
    let limit_bytes = u64::from(ctx.physical.limits.max_storage_buffer_range);
    if needed_bytes > limit_bytes {
        return Err(RenderError::SceneTooLarge {
            instances: capacity.instances,
            needed_bytes,
            limit_bytes,
        });
    }
    Ok(())
}

/// The colour target, and the id target when the ids are captured.
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
