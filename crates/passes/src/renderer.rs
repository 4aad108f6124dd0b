//! [`SceneRenderer`]: one scene rendered frame after frame — the frame setup's passes, composed
//! from the `add_*` functions, compiled for the context's profile, executed.
//!
//! A frame is two halves. [`SceneRenderer::prepare_frame`] does the scene's CPU work and writes
//! this frame's data into the slot's buffers: CPU frustum culling where the technique needs it,
//! the draw lists in the profile's order, camera-relative instances, the culling inputs, the
//! occlusion queries' results. Then the frame's graph is recorded: [`SceneRenderer::render_frame`]
//! declares the scene's passes ([`SceneRenderer::declare_scene`]) only when what they depend on
//! changed (the depth convention, and the first frame's imports) and otherwise reuses the
//! declared payloads and the compiled plan; [`SceneRenderer::execute_graph`] records a graph the
//! caller declared — an engine's frame, the shipped passes and its own on one graph.

use std::sync::Arc;

use tilegraph_graph::{
    AccessFlags, Extent2d, Format, ImageDesc, Import, InitialContent, Layout, PipelineStages, Plan,
    PlanCache, ResourceState,
};
use tilegraph_profile::Profile;
use tilegraph_scene::{Camera, CameraFrame, DepthConvention, MaterialClass, Scene};
use tilegraph_vk::ash::vk;
use tilegraph_vk::executor::{Executor, External, Externals, ImageHandle};
use tilegraph_vk::queries::PassMedian;
use tilegraph_vk::readback::RgbaImage;
use tilegraph_vk::{Context, Image};

use crate::cull::{
    add_cull, add_cull_late, cpu_frustum_mask, import_cull_buffers, CullState, Culling,
};
use crate::draws::{self, DrawClass};
use crate::forward::{add_clear, add_forward, add_transparent};
use crate::frame::{DrawSource, FrameData, FrameGraph, Payload, SceneResources};
use crate::gpu_scene::{FrameUniforms, GpuScene};
use crate::hiz::add_hiz_build;
use crate::occlusion::{add_occlusion_queries, add_raster_occlusion, OqState, RasterOcclusion};
use crate::options::{check_device, FrameReport, RenderError, RenderOptions};
use crate::pipelines::Pipelines;
use crate::prepass::add_depth_prepass;
use crate::setup::{decide, FrameSetup, PassKind, SceneContent};
use crate::targets::{create_target, destroy_target, SceneTargets};
use crate::visbuf::{add_visbuf_resolve, add_visbuf_write, ResolveSets};

/// What the scene's declaration depends on besides the renderer's options: when it is the same
/// as the last frame's, the declared payloads and the compiled plan are reused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct DeclarationKey {
    /// The clear value of depth, and the compare of every pipeline.
    depth: DepthConvention,
    /// The first frame imports its targets `UNDEFINED`; later ones in the layout the last
    /// frame left them in.
    first_frame: bool,
}

/// An image the renderer keeps across frames, with its view.
type Target = (Image, ImageHandle);

/// One geometry pass to declare: which, in which culling phase (0: early or only), drawing
/// from where, predicated on which query results, under which name.
struct Geometry<'n> {
    pass: PassKind,
    phase: u32,
    source: DrawSource,
    predicate: Option<tilegraph_graph::BufferId>,
    name: &'n str,
}

/// The scene's frame as declared and compiled.
struct Declared {
    key: DeclarationKey,
    plan: Arc<Plan>,
    /// Indexed by `PassId`; `None` for pruned passes.
    payloads: Vec<Option<Payload>>,
    externals: Externals,
}

/// Renders one scene frame after frame.
pub struct SceneRenderer {
    options: RenderOptions,
    /// The passes of this renderer's frames, decided once from the scene and the profile.
    setup: Arc<FrameSetup>,
    executor: Executor,
    resources: SceneResources,
    target: Target,
    /// The captured id image (with `capture_ids`).
    ids_target: Option<Target>,
    instance_bits: Option<u32>,
    frames: u64,
    last_slot: usize,
    /// Per instance: whether its material is blended.
    blended: Vec<bool>,
    /// Occlusion queries: the opaque and alpha-tested instances the last frame drew.
    last_drawn: Option<Vec<u32>>,
    /// The camera of the last frame rendered.
    last_camera: Option<Camera>,
    declared: Option<Declared>,
    /// Plans of graphs declared by the caller ([`Self::execute_graph`]).
    plan_cache: PlanCache,
}

impl SceneRenderer {
    pub fn new(ctx: &Context, scene: &Scene, options: RenderOptions) -> Result<Self, RenderError> {
        let instance_bits = check_device(ctx, &options, scene)?;
        let executor = Executor::new(ctx)?;
        let blended: Vec<bool> = scene
            .instances()
            .iter()
            .map(|i| {
                scene
                    .instance_material(i)
                    .is_some_and(|m| m.class == MaterialClass::Blended)
            })
            .collect();
        let parts = create_resources(ctx, scene, &options, &blended, executor.frames_in_flight())
            .and_then(|resources| match create_targets(ctx, &options) {
                Ok(targets) => Ok((resources, targets)),
                Err(e) => {
                    resources.destroy(ctx);
                    Err(e)
                }
            });
        let (resources, (target, ids_target)) = match parts {
            Ok(p) => p,
            Err(e) => {
                executor.destroy(ctx);
                return Err(e);
            }
        };
        let setup = decide(SceneContent::of(scene), ctx.profile(), options.technique)
            .with_culling(options.culling);
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
            blended,
            last_drawn: None,
            last_camera: None,
            declared: None,
            plan_cache: PlanCache::new(),
        })
    }

    pub fn options(&self) -> &RenderOptions {
        &self.options
    }

    /// Sets the heavy-material ALU iterations for the next frames.
    pub fn set_heavy_iterations(&mut self, iterations: u32) {
        self.options.lighting.heavy_iterations = iterations;
    }

    /// Which passes this renderer's frames have.
    pub fn setup(&self) -> &FrameSetup {
        &self.setup
    }

    /// The colour target every frame ends in (`TRANSFER_SRC_OPTIMAL` after a frame).
    pub fn target(&self) -> &ImageHandle {
        &self.target.1
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
        self.prepare_frame(ctx, scene, frame)?;
        let key = DeclarationKey {
            depth: frame.current.depth,
            first_frame: self.frames == 0,
        };
        if self.declared.as_ref().is_none_or(|d| d.key != key) {
            self.declared = None;
            let profile = ctx.profile();
            let (graph, externals) = self.declare_scene(profile, key);
            let (plan, payloads) = graph.compile(profile)?.into_plan_and_payloads();
            self.declared = Some(Declared {
                key,
                plan: Arc::new(plan),
                payloads,
                externals,
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
            return Err(RenderError::Vk(tilegraph_vk::VkError::Invalid {
                what: "scene renderer".into(),
                reason: "no declared frame".into(),
            }));
        };
        let stats =
            executor.execute(
                ctx,
                &declared.plan,
                &declared.externals,
                &mut |id, pc| match declared
                    .payloads
                    .get_mut(id.index())
                    .and_then(Option::as_mut)
                {
                    Some(p) => p(pc, resources),
                    None => Ok(()),
                },
            )?;
        let plan = Arc::clone(&declared.plan);
        self.finish_frame(ctx, plan, stats)
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
        let mut frame = self.plan_cache.compile(graph, ctx.profile())?;
        let resources = &mut self.resources;
        let stats =
            self.executor
                .execute(ctx, &frame.plan, externals, &mut |id, pc| match frame
                    .payloads
                    .get_mut(id.index())
                    .and_then(Option::as_mut)
                {
                    Some(p) => p(pc, resources),
                    None => Ok(()),
                })?;
        self.finish_frame(ctx, frame.plan, stats)
    }

    fn finish_frame(
        &mut self,
        ctx: &Context,
        plan: Arc<Plan>,
        stats: tilegraph_vk::executor::FrameStats,
    ) -> Result<FrameReport, RenderError> {
        // After a rebuild, the pipelines of the destroyed render passes go (at the first frame
        // that succeeds after it: the floor only rises).
        self.resources
            .pipelines
            .prune(ctx, self.executor.render_pass_serial_floor());
        self.frames += 1;
        let draws = &self.resources.frame.draws;
        Ok(FrameReport {
            setup: Arc::clone(&self.setup),
            plan,
            stats,
            draws: draws.opaque.len() + draws.alpha_tested.len() + draws.blended.len(),
            triangles: draws.triangles(),
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
        let (w, h) = (self.options.width, self.options.height);
        self.last_camera = Some(frame.camera);
        let m = frame.current;
        let culling = self.options.culling;
        // With GPU culling on, the CPU lists serve only blended geometry: frustum-cull it here.
        // Techniques whose CPU lists draw opaque geometry (queries, and the pre-pass that raster
        // occlusion tests against) frustum-cull all of it here; the others only blended.
        let cpu_frustum_all = culling.uses_queries() || culling == Culling::RasterOcclusion;
        let mut visible = match culling {
            Culling::None => None,
            _ => Some(
                cpu_frustum_mask(scene, &m)?
                    .into_iter()
                    .zip(&self.blended)
                    .map(|(v, b)| v || (!b && !cpu_frustum_all))
                    .collect::<Vec<bool>>(),
            ),
        };
        let slot = self.executor.acquire_slot(ctx)?;
        // Occlusion queries: the newest complete frame's results select what this frame draws
        // (read now, never waited for: the acquired slot's frame has completed).
        if let Some(oq) = self.resources.queries.as_mut() {
            oq.collect(ctx, slot)?;
            if culling.conditional() {
                // Same-frame results on the GPU; reading the slot only recycles its pool.
                oq.prepare(slot, &m, h as f32, visible.as_deref());
            } else {
                let passed = oq.mask();
                // Every instance in the frustum is queried, drawn or not: a hidden one must be
                // able to come back.
                oq.prepare(slot, &m, h as f32, visible.as_deref());
                let combined: Vec<bool> = visible
                    .unwrap_or_else(|| vec![true; passed.len()])
                    .into_iter()
                    .zip(passed)
                    .map(|(a, b)| a && b)
                    .collect();
                self.last_drawn = Some(
                    (0..combined.len())
                        .filter(|&i| combined[i] && !self.blended.get(i).copied().unwrap_or(false))
                        .map(|i| i as u32)
                        .collect(),
                );
                visible = Some(combined);
            }
        }
        let profile = ctx.profile();
        let order = self
            .options
            .opaque_order
            .unwrap_or(profile.passes.opaque_sort);
        let draws = draws::build(scene, m.eye, order, visible.as_deref());
        let uniforms = FrameUniforms::new(
            m.view_projection,
            m.depth,
            (w, h),
            &self.options.lighting,
            self.instance_bits.unwrap_or(32),
        );
        self.resources
            .scene
            .write_frame(ctx, slot, scene, m.eye, &uniforms, &draws)?;
        self.last_slot = slot;
        if let Some(cull) = self.resources.culling.as_mut() {
            cull.write_frame(ctx, slot, frame, &draws, (w, h))?;
        }
        self.resources.frame = FrameData {
            draws,
            depth: m.depth,
        };
        Ok(())
    }

    /// Declares the scene's frame: the frame setup's passes, composed from the `add_*`
    /// functions in the order the technique needs, and the physical resources of its imports.
    fn declare_scene(&self, profile: &Profile, key: DeclarationKey) -> (FrameGraph, Externals) {
        let extent = Extent2d::new(self.options.width, self.options.height);
        let culling = self.options.culling;
        let setup = &self.setup;
        let mut g = FrameGraph::new();
        let mut externals = Externals::new();
        // The targets survive frames: after the first they are in TRANSFER_SRC from the last
        // frame's release, read by the readback copy.
        let kept = ResourceState::image(
            Layout::TransferSrc,
            PipelineStages::COPY,
            AccessFlags::TRANSFER_READ,
        );
        let import = Import {
            initial: if key.first_frame {
                ResourceState::UNDEFINED
            } else {
                kept
            },
            content: InitialContent::Discard,
            final_state: kept,
        };
        let color = g.import_image(
            "color",
            ImageDesc::new(extent, Format::R8G8B8A8_UNORM),
            import,
        );
        externals.insert(color, External::Image(self.target.1.clone()));
        let depth = g.create_image("depth", ImageDesc::new(extent, Format::D32_SFLOAT));
        let mut t = SceneTargets::new(color, depth, extent, self.options.clear_color, key.depth);
        if let Some((_, handle)) = &self.ids_target {
            let ids = g.import_image(
                "visbuf-id",
                ImageDesc::new(extent, Format::R32_UINT),
                import,
            );
            g.export(ids);
            externals.insert(ids, External::Image(handle.clone()));
            t.ids = Some(ids);
        }
        let lists = self.resources.culling.as_ref().map(|c| {
            let lists = import_cull_buffers(&mut g, c);
            for (id, buffer) in [
                (lists.commands, &c.commands),
                (lists.counts, &c.counts),
                (lists.draw_ids, &c.draw_ids),
                (lists.visibility, &c.visibility),
            ] {
                externals.insert(id, External::Buffer(CullState::handle(buffer)));
            }
            if let (Some(id), Some(buffer)) = (lists.pyramid, c.pyramid.as_ref()) {
                externals.insert(id, External::Buffer(CullState::handle(buffer)));
            }
            lists
        });
        let conditions_size = self
            .resources
            .queries
            .as_ref()
            .and_then(|q| q.conditions.as_ref())
            .map(|b| b.size);
        let mut conditions = None;

        if let (Some(lists), false) = (lists, culling == Culling::RasterOcclusion) {
            add_cull(&mut g, lists, culling);
        }
        // Two-phase with a pre-pass: depth of the early lists, pyramid, late culling, depth of
        // the late lists, then colour once over the union (the early lists, which the late
        // dispatch completes) in the unculled order. The visibility buffer draws ids in both
        // phases instead.
        let two_phase = culling == Culling::HizTwoPhase;
        let split_depth = two_phase && setup.has_prepass();
        let phases: &[u32] = if two_phase { &[0, 1] } else { &[0] };
        let mut flags_declared = false;
        for &phase in phases {
            if phase == 1 {
                // No depth written by the early phase (nothing opaque or alpha-tested): no
                // occluders, no pyramid, and no late lists to fill.
                if let (Some(lists), true) = (lists, t.depth_written()) {
                    if let Some(pyramid) = lists.pyramid {
                        add_hiz_build(&mut g, t.depth, pyramid);
                    }
                    add_cull_late(&mut g, lists);
                }
            }
            let suffix = match (two_phase, phase) {
                (false, _) => "",
                (true, 0) => "-early",
                (true, _) => "-late",
            };
            for pass in setup.included() {
                let depth_only = matches!(
                    pass,
                    PassKind::DepthPrepassOpaque | PassKind::DepthPrepassAlpha
                );
                if split_depth && !depth_only {
                    continue; // colour after both depth phases
                }
                if culling.conditional() && !depth_only && conditions.is_none() && t.depth_written()
                {
                    // Boxes against the pre-pass depth, then colour predicated on them.
                    conditions =
                        self.declare_queries(&mut g, &mut externals, t.depth, conditions_size);
                }
                if culling == Culling::RasterOcclusion && !depth_only && !flags_declared {
                    match (lists, t.depth_written()) {
                        (Some(lists), true) => add_raster_occlusion(
                            &mut g,
                            &t,
                            lists,
                            self.options.raster_occlusion_scale.max(1),
                        ),
                        // No pre-pass depth (nothing opaque): no boxes to test; the lists
                        // still get written.
                        (Some(lists), false) => add_cull(&mut g, lists, Culling::RasterOcclusion),
                        (None, _) => {}
                    }
                    flags_declared = true;
                }
                // Raster occlusion tests boxes against the depth of everything: its pre-pass
                // draws the CPU lists; everything else draws the culling shader's lists.
                let source = match (lists, culling, depth_only) {
                    (Some(_), Culling::RasterOcclusion, true) | (None, _, _) => DrawSource::Cpu,
                    (Some(lists), _, _) => lists.source(phase),
                };
                let name = format!("{}{suffix}", pass.name());
                let geometry = Geometry {
                    pass,
                    phase,
                    source,
                    predicate: conditions,
                    name: &name,
                };
                self.declare_geometry(&mut g, &mut t, geometry);
            }
        }
        if split_depth {
            for pass in setup
                .included()
                .filter(|p| matches!(p, PassKind::Opaque | PassKind::AlphaTested))
            {
                let geometry = Geometry {
                    pass,
                    phase: 0,
                    source: lists.map_or(DrawSource::Cpu, |l| l.source(0)),
                    predicate: conditions,
                    name: pass.name(),
                };
                self.declare_geometry(&mut g, &mut t, geometry);
            }
        }
        if let (true, Some(ids)) = (setup.includes(PassKind::VisbufResolve), t.ids) {
            add_visbuf_resolve(&mut g, &mut t, ids, profile.is_tiler());
        }
        if setup.includes(PassKind::Transparent) {
            add_transparent(&mut g, &mut t);
        }
        if let (Culling::Hiz, Some(pyramid)) = (culling, lists.and_then(|l| l.pyramid)) {
            // Next frame's occluders: this frame's depth.
            add_hiz_build(&mut g, t.depth, pyramid);
        }
        if culling.uses_queries() && !culling.conditional() && t.depth_written() {
            // After all opaque work (the graph's class order); results are read next frame.
            self.declare_queries(&mut g, &mut externals, t.depth, None);
        }
        if !t.color_written() {
            add_clear(&mut g, &mut t);
        }
        g.export(color);
        (g, externals)
    }

    /// The occlusion queries, with their results buffer among the externals.
    fn declare_queries(
        &self,
        g: &mut FrameGraph,
        externals: &mut Externals,
        depth: tilegraph_graph::ImageId,
        conditions_size: Option<u64>,
    ) -> Option<tilegraph_graph::BufferId> {
        let conditions = add_occlusion_queries(g, depth, conditions_size)?;
        let buffer = self.resources.queries.as_ref()?.conditions.as_ref()?;
        externals.insert(conditions, External::Buffer(CullState::handle(buffer)));
        Some(conditions)
    }

    /// One geometry pass of the frame setup.
    fn declare_geometry(&self, g: &mut FrameGraph, t: &mut SceneTargets, geometry: Geometry<'_>) {
        let Geometry {
            pass,
            phase,
            source,
            predicate,
            name,
        } = geometry;
        match pass {
            PassKind::DepthPrepassOpaque => {
                add_depth_prepass(g, t, DrawClass::Opaque, source, name);
            }
            PassKind::DepthPrepassAlpha => {
                add_depth_prepass(g, t, DrawClass::AlphaTested, source, name);
            }
            PassKind::Opaque => {
                let prepassed = self.setup.prepassed(0);
                add_forward(g, t, DrawClass::Opaque, prepassed, source, predicate, name);
            }
            PassKind::AlphaTested => {
                let prepassed = self.setup.prepassed(1);
                add_forward(
                    g,
                    t,
                    DrawClass::AlphaTested,
                    prepassed,
                    source,
                    predicate,
                    name,
                );
            }
            PassKind::VisbufWrite => {
                add_visbuf_write(g, t, phase, source, name);
            }
            PassKind::VisbufResolve | PassKind::Transparent => {} // after the geometry phases
        }
    }

    /// The instance owning each pixel of the last frame (`u32::MAX` for background), from the
    /// captured visibility buffer (`capture_ids`); waits for the GPU.
    pub fn read_instance_ids(&mut self, ctx: &Context) -> Result<Option<Vec<u32>>, RenderError> {
        self.executor.finish(ctx)?;
        let Some((_, h)) = &self.ids_target else {
            return Ok(None);
        };
        let bytes =
            tilegraph_vk::readback::read_image(ctx, h, vk::ImageLayout::TRANSFER_SRC_OPTIMAL, 0)?;
        let tri_bits = 32 - self.instance_bits.unwrap_or(32);
        Ok(Some(
            bytes
                .chunks_exact(4)
                .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
                .map(|id| {
                    if id == u32::MAX {
                        u32::MAX
                    } else if tri_bits >= 32 {
                        0
                    } else {
                        id >> tri_bits
                    }
                })
                .collect(),
        ))
    }

    /// The instances the last frame drew through GPU culling (waits), or `None` without culling.
    pub fn drawn_instances(&mut self, ctx: &Context) -> Result<Option<Vec<u32>>, RenderError> {
        self.executor.finish(ctx)?;
        if let Some(d) = &self.last_drawn {
            return Ok(Some(d.clone()));
        }
        if let Some(oq) = self.resources.queries.as_ref() {
            if oq.conditions.is_some() {
                return Ok(Some(oq.conditional_drawn(ctx)?));
            }
        }
        match self.resources.culling.as_ref() {
            Some(c) => Ok(Some(c.drawn_instances(ctx)?)),
            None => Ok(None),
        }
    }

    /// Waits for the frames in flight, collecting their GPU timings.
    pub fn finish(&mut self, ctx: &Context) -> Result<(), RenderError> {
        Ok(self.executor.finish(ctx)?)
    }

    /// Median GPU time per pass over the frames rendered so far (call [`Self::finish`] first).
    pub fn medians(&self) -> Vec<PassMedian> {
        self.executor.medians()
    }

    /// Fragments shaded by the opaque, alpha-tested and blended colour passes of the last frame
    /// (with `count_fragments`; waits for the GPU).
    pub fn fragment_counts(&mut self, ctx: &Context) -> Result<[u32; 3], RenderError> {
        self.executor.finish(ctx)?;
        Ok(self.resources.scene.fragment_counts(ctx, self.last_slot)?)
    }

    /// Graphics pipelines cached now (those of render passes the executor destroyed are
    /// dropped after the frame that rebuilt them).
    pub fn cached_pipelines(&self) -> usize {
        self.resources.pipelines.len()
    }

    pub fn executor(&self) -> &Executor {
        &self.executor
    }

    /// Reads the last frame's image (waits for the GPU).
    pub fn read_image(&mut self, ctx: &Context) -> Result<RgbaImage, RenderError> {
        self.executor.finish(ctx)?;
        let pixels = tilegraph_vk::readback::read_image(
            ctx,
            &self.target.1,
            vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
            0,
        )?;
        Ok(RgbaImage {
            width: self.options.width,
            height: self.options.height,
            pixels,
        })
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
        destroy_target(ctx, target);
        if let Some(ids) = ids_target {
            destroy_target(ctx, ids);
        }
    }
}

/// The GPU side of a renderer: the scene uploaded, the pipelines' layouts, and the state of the
/// culling technique. Whatever was created is destroyed again when a later step fails.
fn create_resources(
    ctx: &Context,
    scene: &Scene,
    options: &RenderOptions,
    blended: &[bool],
    frames_in_flight: usize,
) -> Result<SceneResources, RenderError> {
    let mut gpu = GpuScene::new(ctx, scene, frames_in_flight)?;
    let pipelines = match Pipelines::new(ctx, gpu.set_layout, options.count_fragments) {
        Ok(p) => p,
        Err(e) => {
            gpu.destroy(ctx);
            return Err(e.into());
        }
    };
    let culling = options.culling;
    let mut culling_state = None;
    if culling.uses_gpu_lists() {
        let depth = scene
            .camera_path()
            .camera(0)
            .map_or(DepthConvention::Reverse, |c| {
                c.projection.depth_convention()
            });
        let made = CullState::new(
            ctx,
            culling,
            scene.instances().len() as u32,
            (options.width, options.height),
            depth,
            options.hiz_mode,
            gpu.set_layout,
            frames_in_flight,
        )
        .and_then(|c| match gpu.add_culled_sets(ctx, c.draw_ids.raw) {
            Ok(()) => Ok(c),
            Err(e) => {
                c.destroy(ctx);
                Err(e)
            }
        });
        match made {
            Ok(c) => culling_state = Some(c),
            Err(e) => {
                pipelines.destroy(ctx);
                gpu.destroy(ctx);
                return Err(e.into());
            }
        }
    }
    let mut res = SceneResources {
        scene: gpu,
        pipelines,
        frame: FrameData::default(),
        culling: culling_state,
        queries: None,
        raster: None,
        resolve: None,
    };
    let made = (|| -> Result<(), tilegraph_vk::VkError> {
        if culling.uses_queries() {
            res.queries = Some(OqState::new(
                ctx,
                scene,
                options.oq_group,
                culling.conditional(),
                blended,
                res.scene.set_layout,
                frames_in_flight,
            )?);
        }
        if let (Culling::RasterOcclusion, Some(c)) = (culling, res.culling.as_ref()) {
            res.raster = Some(RasterOcclusion::new(
                ctx,
                res.scene.set_layout,
                &c.visibility,
                scene.instances().len() as u32,
                options.raster_occlusion_scale,
                frames_in_flight,
            )?);
        }
        if options.technique == crate::setup::Technique::Visbuf {
            res.resolve = Some(ResolveSets::new(ctx, frames_in_flight)?);
        }
        Ok(())
    })();
    match made {
        Ok(()) => Ok(res),
        Err(e) => {
            res.destroy(ctx);
            Err(e.into())
        }
    }
}

/// The colour target, and the id target when the ids are captured.
fn create_targets(
    ctx: &Context,
    options: &RenderOptions,
) -> Result<(Target, Option<Target>), RenderError> {
    let size = (options.width, options.height);
    let target = create_target(ctx, size, vk::Format::R8G8B8A8_UNORM)?;
    if !(options.capture_ids && options.technique == crate::setup::Technique::Visbuf) {
        return Ok((target, None));
    }
    match create_target(ctx, size, vk::Format::R32_UINT) {
        Ok(ids) => Ok((target, Some(ids))),
        Err(e) => {
            destroy_target(ctx, target);
            Err(e.into())
        }
    }
}
