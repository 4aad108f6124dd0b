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
mod views;

use std::sync::Arc;

use tilegraph_graph::{Format, ImageId, Import, Plan, PlanCache, ResourceState};
use tilegraph_scene::{Camera, CameraFrame, Scene};
use tilegraph_vk::ash::vk;
use tilegraph_vk::executor::{
    EngineFrame, Executor, External, Externals, FrameStats, ImageHandle, PassContext, Submission,
};
use tilegraph_vk::frames::DEFAULT_FRAMES_IN_FLIGHT;
use tilegraph_vk::queries::{GpuTiming, PassMedian};
use tilegraph_vk::{Context, Image, VkError};

use crate::compose::{declare_scene, kept_import, ColorTarget, DeclarationKey, SceneFrame};
use crate::draws::DrawBuilder;
use crate::frame::{FrameGraph, Payload, SceneResources};
use crate::gpu_scene::Capacity;
use crate::lint::lint_frame;
use crate::options::{FrameReport, RenderError, RenderOptions};
use crate::setup::{FrameSetup, SceneContent};
use crate::targets::destroy_target;
pub use memory::{scene_memory, SceneMemory};
pub use readback::PixelOwners;
use resources::create_resources;
pub use views::ViewId;
use views::{View, Views};

/// An image the renderer keeps across frames, with its view.
type Target = (Image, ImageHandle);

/// The scene's frame as declared and compiled.
struct DeclaredFrame {
    /// Per view, what its declaration depended on.
    keys: Vec<DeclarationKey>,
    plan: Arc<Plan>,
    /// Indexed by `PassId`; `None` for pruned passes.
    payloads: Vec<Option<Payload>>,
    /// Indexed by `PassId`: the view the pass belongs to.
    view_of_pass: Vec<usize>,
    externals: Externals,
    /// The main view's colour target's id (its image may change from frame to frame: an
    /// engine's).
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

/// Renders one scene frame after frame: a main view, and the further views an engine adds
/// ([`SceneRenderer::add_view`]), on one graph.
pub struct SceneRenderer {
    views: Views,
    executor: Executor,
    resources: SceneResources,
    last_slot: usize,
    /// Instance slots of the scene the last frame drew.
    last_instances: usize,
    draw_builder: DrawBuilder,
    /// The drawn instances per class the frame setup was decided for.
    content: SceneContent,
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
        let content = SceneContent::of(scene);
        let main = View::new(ctx, scene, options, content, submission)?;
        let options = &main.options;
        let executor = match submission {
            Submission::Owned => Executor::with_frames(ctx, frames_in_flight, 256),
            Submission::Engine => Executor::for_engine(ctx, frames_in_flight),
        };
        let mut executor = match executor {
            Ok(e) => e,
            Err(e) => {
                main.destroy(ctx);
                return Err(e.into());
            }
        };
        let capacity = Capacity::for_scene(scene, options.instance_capacity);
        let made = executor
            .set_timing(ctx, options.gpu_timing)
            .map_err(RenderError::from)
            .and_then(|()| {
                check_capacity(ctx, capacity, crate::options::lod_levels(options, scene))
            })
            .and_then(|()| {
                create_resources(
                    ctx,
                    scene,
                    &[options],
                    executor.frames_in_flight(),
                    capacity,
                )
            });
        let resources = match made {
            Ok(r) => r,
            Err(e) => {
                executor.destroy(ctx);
                main.destroy(ctx);
                return Err(e);
            }
        };
        Ok(SceneRenderer {
            views: Views {
                main,
                further: Vec::new(),
            },
            executor,
            resources,
            last_slot: 0,
            last_instances: scene.instances().len(),
            draw_builder: DrawBuilder::default(),
            content,
            declared: None,
            plan_cache: PlanCache::new(),
            lint_armed: false,
        })
    }

    /// The main view's options (their scene-wide fields are every view's).
    pub fn options(&self) -> &RenderOptions {
        &self.views.main.options
    }

    /// Sets the heavy-material ALU iterations for the next frames.
    pub fn set_heavy_iterations(&mut self, iterations: u32) {
        self.views.main.options.lighting.heavy_iterations = iterations;
    }

    /// Points the directional light (and its shadows) along `to_light` from the next frame.
    pub fn set_light_direction(&mut self, to_light: glam::Vec3) {
        self.views.main.options.lighting.direction = to_light;
    }

    /// Gives the directional light `color` (linear RGB) from the next frame.
    pub fn set_light_color(&mut self, color: glam::Vec3) {
        self.views.main.options.lighting.color = color;
    }

    /// Which passes the main view's frames have.
    pub fn setup(&self) -> &FrameSetup {
        &self.views.main.setup
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
        self.views.main.target.as_ref().map(|(_, h)| h)
    }

    /// Renders one frame from a lone `camera`: a still camera when it is the last frame's
    /// camera, else a cut (no previous frame to reproject).
    pub fn render(
        &mut self,
        ctx: &Context,
        scene: &Scene,
        camera: &Camera,
    ) -> Result<FrameReport, RenderError> {
        let main = &self.views.main;
        let m = camera.matrices(main.aspect());
        let frame = CameraFrame {
            index: 0,
            camera: *camera,
            cut: main.last_camera != Some(*camera),
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
        let Some((_, handle)) = &self.views.main.target else {
            return Err(RenderError::EngineSubmits);
        };
        let handle = handle.clone();
        self.prepare_frame(ctx, scene, frame)?;
        let color = ColorTarget {
            format: Format::R8G8B8A8_UNORM,
            import: kept_import(self.views.main.frames == 0),
        };
        self.run_scene(ctx, color, &handle, None)
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
        self.run_scene(ctx, color, target.image, Some(engine))
    }

    /// The engine's target as the frame declares it, or what is wrong with it.
    fn check_target(&self, target: &EngineTarget<'_>) -> Result<ColorTarget, RenderError> {
        let (w, h) = (self.options().width, self.options().height);
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

    /// View `k`'s declaration key this frame (`color`: the main view's target).
    fn view_key(&self, ctx: &Context, k: usize, color: ColorTarget) -> Option<DeclarationKey> {
        let view = self.views.get(k)?;
        let first = view.frames == 0;
        Some(DeclarationKey {
            depth: view.depth,
            // Only the id and depth targets the renderer keeps are imported differently on the
            // first frame (the colour target's import is in `color`).
            first_frame: first && (view.ids_target.is_some() || view.depth_target.is_some()),
            color: match k {
                0 => color,
                _ => ColorTarget {
                    format: Format::R8G8B8A8_UNORM,
                    import: kept_import(first),
                },
            },
            materials: self.resolve_materials(ctx, &view.options),
            indices: (view.options.triangle_culling && view.options.culling.clusters()).then(
                || {
                    let b = &self.resources.scene.indices;
                    (b.raw, b.size)
                },
            ),
        })
    }

    /// Declares every view's passes on one graph (the further views' names prefixed
    /// `view<k>/`) and compiles it for the profile.
    fn declare(
        &self,
        ctx: &Context,
        color: ColorTarget,
        image: &ImageHandle,
    ) -> Result<DeclaredFrame, RenderError> {
        let unmerged;
        let profile = if self.views.main.options.probe.separate_render_passes {
            let mut p = ctx.profile().clone();
            p.render_pass.merge_subpasses = tilegraph_profile::MergePolicy::Never;
            unmerged = p;
            &unmerged
        } else {
            ctx.profile()
        };
        let mut graph = FrameGraph::new();
        let mut externals = Externals::new();
        let mut keys = Vec::with_capacity(self.views.len());
        let mut view_of_pass = Vec::new();
        let mut main_color = None;
        for (k, view) in self.views.iter().enumerate() {
            let Some(key) = self.view_key(ctx, k, color) else {
                continue;
            };
            let target = match (k, &view.target) {
                (0, _) => image,
                (_, Some((_, h))) => h,
                (_, None) => return Err(RenderError::UnknownView(k as u32)),
            };
            let unknown = || RenderError::UnknownView(k as u32);
            let atlas = self.resources.scene.atlas(k).ok_or_else(unknown)?;
            let states = self.resources.view_states(k).ok_or_else(unknown)?;
            let (passes, resources) = (graph.pass_count(), graph.resource_count());
            let color_id = declare_scene(
                &mut graph,
                &mut externals,
                &SceneFrame {
                    options: &view.options,
                    setup: &view.setup,
                    profile,
                    key,
                    states,
                    target,
                    ids_target: view.ids_target.as_ref().map(|(_, h)| h),
                    depth_target: view.depth_target.as_ref().map(|(_, h)| h),
                    atlas,
                },
            );
            if k > 0 {
                graph.prefix_names(passes, resources, &format!("view{k}/"));
            }
            view_of_pass.resize(graph.pass_count(), k);
            main_color.get_or_insert(color_id);
            keys.push(key);
        }
        let color = main_color.ok_or(RenderError::UnknownView(0))?;
        let (plan, payloads) = graph.compile(profile)?.into_plan_and_payloads();
        Ok(DeclaredFrame {
            keys,
            plan: Arc::new(plan),
            payloads,
            view_of_pass,
            externals,
            color,
        })
    }

    /// Declares the scene's frame (every view's passes on one graph) when what it depends on
    /// changed, and records it: submitted by the executor, or into the engine's command buffer.
    fn run_scene(
        &mut self,
        ctx: &Context,
        color: ColorTarget,
        image: &ImageHandle,
        engine: Option<EngineFrame>,
    ) -> Result<FrameReport, RenderError> {
        self.arm_trace();
        let n = self.views.len();
        let same = self.declared.as_ref().is_some_and(|d| {
            d.keys.len() == n
                && (0..n).all(|k| self.view_key(ctx, k, color).as_ref() == d.keys.get(k))
        });
        let declare = !same;
        if declare {
            self.declared = None;
            self.declared = Some(self.declare(ctx, color, image)?);
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
            view_of_pass,
            ..
        } = declared;
        let upload = resources.scene.take_upload();
        let mut prologue = |ctx: &Context, cb: vk::CommandBuffer| upload.record(ctx, cb);
        let mut record = |id: tilegraph_graph::PassId, pc: &mut PassContext<'_>| {
            // A pass records with its view's lists, states and sets.
            resources.enter_view(view_of_pass.get(id.index()).copied().unwrap_or(0));
            match payloads.get_mut(id.index()).and_then(Option::as_mut) {
                Some(p) => p(pc, resources),
                None => Ok(()),
            }
        };
        let stats = match engine {
            None => executor.execute_with(ctx, plan, externals, &mut prologue, &mut record),
            Some(f) => executor.record_with(ctx, plan, externals, f, &mut prologue, &mut record),
        };
        resources.enter_view(0);
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
        for v in self.views.iter_mut() {
            v.frames += 1;
        }
        let lint = self
            .resources
            .pipelines
            .take_trace()
            .map(|trace| Arc::new(lint_frame(ctx.profile(), &plan, &trace)));
        let draws = &self.resources.frame.draws;
        Ok(FrameReport {
            lint,
            setup: Arc::clone(&self.views.main.setup),
            plan,
            stats,
            declared,
            draws: draws.opaque.len() + draws.alpha_tested.len() + draws.blended.len(),
            triangles: draws.triangles(),
            gpu_culling: self.views.main.gpu_counts,
            software: (self.views.main.options.culling == crate::setup::Culling::SoftwareOcclusion)
                .then(|| self.views.main.cpu.software.as_ref().map(|s| s.last))
                .flatten(),
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
        // Every view's camera: the main view's is the frame's, a further view's the last one
        // set (still when none was set since).
        for k in 1..self.views.len() {
            if let Some(v) = self.views.get_mut(k) {
                let still = v
                    .last_camera
                    .map(|c| CameraFrame::new(0, c, Some(&c), v.aspect()));
                v.current = v.next.take().or(still);
            }
        }
        self.views.main.current = Some(*frame);
        // The CPU's culling first; then the slot, waiting for its previous frame if need be.
        for k in 0..self.views.len() {
            if let Some(f) = self.views.get(k).and_then(|v| v.current) {
                let bits = ctx.physical.limits.sub_pixel_precision_bits;
                self.cull_view_on_cpu(scene, k, &f, bits)?;
            }
        }
        let slot = match slot {
            Some(s) => s,
            None => self.executor.acquire_slot(ctx)?,
        };
        self.resources.scene.write_frame(ctx, slot, scene)?;
        let written = (0..self.views.len()).try_for_each(|k| {
            match self.views.get(k).and_then(|v| v.current) {
                Some(f) => self.write_view(ctx, scene, k, &f, slot),
                None => Ok(()),
            }
        });
        self.resources.enter_view(0);
        written?;
        self.last_slot = slot;
        self.last_instances = scene.instances().len();
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

    /// From the next frame on, the main view draws of its opaque and alpha-tested instances
    /// only these clusters (sorted `(instance << 32) | cluster` keys; `None`: whole
    /// instances): `cull-check`'s ideal frame of a cluster technique.
    pub(crate) fn keep_only_clusters(&mut self, clusters: Option<&[u64]>) {
        self.draw_builder.keep_only(clusters);
    }

    /// Forgets the GPU timings of the frames so far: [`Self::medians`] then covers the frames
    /// rendered after this (call [`Self::finish`] first, so no earlier frame is still to be
    /// collected).
    pub fn clear_timings(&mut self) {
        self.executor.clear_timings();
        if let Some(s) = self.views.main.cpu.software.as_mut() {
            s.history.clear();
        }
    }

    /// With software occlusion: the median CPU milliseconds of its work in the main view's
    /// frames since [`Self::clear_timings`] (the last 64 at most).
    pub fn software_cpu_ms(&self) -> Option<f64> {
        let s = self.views.main.cpu.software.as_ref()?;
        tilegraph_vk::queries::median(&s.history)
    }

    pub fn executor(&self) -> &Executor {
        &self.executor
    }

    /// Stops keeping the main view's depth ([`RenderOptions::capture_depth`]) from the next
    /// frame on: its image is destroyed (after the frames in flight) and the frame declared
    /// again without it, so the depth stays in tile memory where it would have been stored.
    /// `cull-check` compares depth on its checked frames, and times frames without it.
    pub fn stop_keeping_depth(&mut self, ctx: &Context) -> Result<(), RenderError> {
        let Some(target) = self.views.main.depth_target.take() else {
            return Ok(());
        };
        self.executor.finish(ctx)?;
        destroy_target(ctx, target);
        self.views.main.options.capture_depth = false;
        self.declared = None;
        Ok(())
    }

    /// What the GPU queries of the next frames measure ([`RenderOptions::gpu_timing`]). A
    /// change waits for the frames in flight and forgets the timings so far.
    pub fn set_gpu_timing(&mut self, ctx: &Context, timing: GpuTiming) -> Result<(), RenderError> {
        self.executor.set_timing(ctx, timing)?;
        self.views.main.options.gpu_timing = timing;
        Ok(())
    }

    pub fn destroy(self, ctx: &Context) {
        let SceneRenderer {
            executor,
            resources,
            views,
            declared,
            ..
        } = self;
        executor.destroy(ctx);
        // The payloads only hold handles; dropped before what they name.
        drop(declared);
        resources.destroy(ctx);
        views.destroy(ctx);
    }
}

/// Whether the buffers of `capacity` fit the device's storage buffer range (`lod_levels`:
/// commands per draw group).
fn check_capacity(ctx: &Context, capacity: Capacity, lod_levels: u32) -> Result<(), RenderError> {
    let needed_bytes = capacity.largest_storage_buffer(lod_levels);
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
