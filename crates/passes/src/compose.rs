//! The scene's frame as a composition of the shipped passes: the frame setup's decisions, in
//! the order the culling technique needs them, each an `add_*` call. This is the file to read
//! to see what a frame of a given technique declares; each pass's own file says what the pass
//! does.

use tilegraph_graph::{
    AccessFlags, BufferId, Extent2d, Format, ImageDesc, ImageId, Import, InitialContent, Layout,
    PipelineStages, ResourceState,
};
use tilegraph_profile::Profile;
use tilegraph_scene::DepthConvention;
use tilegraph_vk::executor::{External, Externals, ImageHandle};

use crate::cull::{add_cull, add_cull_late, import_cull_buffers, CullLists, CullState, Culling};
use crate::draws::DrawClass;
use crate::forward::{add_clear, add_forward, add_transparent};
use crate::frame::{DrawSource, FrameGraph, States};
use crate::gbuffer::{add_gbuffer_resolve, add_gbuffer_write};
use crate::hiz::{
    add_hiz_build, add_reprojection, import_reprojection, HizState, ReprojectState, Reprojected,
};
use crate::occlusion::{
    add_occlusion_queries, add_raster_occlusion, import_query_results, OqState,
};
use crate::options::RenderOptions;
use crate::pipelines::ColourDepth;
use crate::prepass::{add_depth_prepass, add_depth_prepass_of_last_visible};
use crate::setup::{FrameSetup, PassKind};
use crate::shadow::{add_shadow_culling, add_shadow_maps, import_shadows, ShadowState};
use crate::targets::SceneTargets;
use crate::visbuf::{add_visbuf_resolve, add_visbuf_write, ResolvePlan};
use tilegraph_cull::shadow::CasterCulling;

/// What the scene's declaration depends on besides the renderer's options: when it is the same
/// as the last frame's, the declared payloads and the compiled plan are reused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct DeclarationKey {
    /// The clear value of depth, and the compare of every pipeline.
    pub depth: DepthConvention,
    /// The first frame imports the targets the renderer keeps `UNDEFINED`; later ones in the
    /// layout the last frame left them in.
    pub first_frame: bool,
    /// The colour target: its format, the state it starts the frame in and the state the
    /// frame leaves it in (an engine's target says; the renderer's own follows `first_frame`).
    pub color: ColorTarget,
    /// The scene's materials where the visibility buffer resolves per material (their
    /// resolves and tile lists), else 0.
    pub materials: u32,
    /// Per-triangle culling: the scene's index buffer (its handle and size), whose tail the
    /// culling writes; replaced when the geometry grows.
    pub indices: Option<(tilegraph_vk::ash::vk::Buffer, u64)>,
}

/// The colour target as the frame declares it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct ColorTarget {
    pub format: Format,
    pub import: Import,
}

/// The state the targets the renderer keeps are left in after a frame, and found in by the
/// next: `TRANSFER_SRC`, for the readback copy.
pub(crate) const KEPT: ResourceState = ResourceState::image(
    Layout::TransferSrc,
    PipelineStages::COPY,
    AccessFlags::TRANSFER_READ,
);

/// How a target the renderer keeps is imported: discarded and left `KEPT`, found `KEPT`
/// after the first frame.
pub(crate) fn kept_import(first_frame: bool) -> Import {
    Import {
        initial: if first_frame {
            ResourceState::UNDEFINED
        } else {
            KEPT
        },
        content: InitialContent::Discard,
        final_state: KEPT,
    }
}

/// What the scene's frame is declared from.
#[derive(Clone, Copy)]
pub(crate) struct SceneFrame<'a> {
    pub options: &'a RenderOptions,
    pub setup: &'a FrameSetup,
    pub profile: &'a Profile,
    pub key: DeclarationKey,
    /// The techniques' states, whose buffers the frame imports.
    pub states: &'a States,
    /// The renderer's colour target, and its id target when it keeps the ids.
    pub target: &'a ImageHandle,
    pub ids_target: Option<&'a ImageHandle>,
    /// The depth image it keeps (`capture_depth`); else the depth is the frame's own.
    pub depth_target: Option<&'a ImageHandle>,
    /// The light's shadow atlas (imported when the renderer has shadows).
    pub atlas: &'a crate::gpu_scene::shadow_atlas::ShadowAtlas,
}

/// One geometry pass to declare: which, in which culling phase (0: early or only), drawing
/// from where, predicated on which query results (a depth pre-pass: last frame's; colour:
/// this frame's), whether a pre-pass wrote only part of the depth, under which name.
struct Geometry<'n> {
    pass: PassKind,
    phase: u32,
    source: DrawSource,
    predicate: Option<BufferId>,
    partial_prepass: bool,
    name: &'n str,
}

/// Declares one view of the scene's frame on `g`: the frame setup's passes, composed from the
/// `add_*` functions in the order the technique needs, and the physical resources of its
/// imports into `externals`. Returns its colour target (an engine's target changes from frame
/// to frame).
pub(crate) fn declare_scene(
    g: &mut FrameGraph,
    externals: &mut Externals,
    spec: &SceneFrame<'_>,
) -> ImageId {
    let mut c = Composition::import(g, externals, spec);
    let culling = c.culling();
    let two_phase = culling.base() == Culling::HizTwoPhase;
    // The light's cascades, before every colour pass (which samples them): first — or, for
    // `receivers-hiz` where the colour follows a depth phase, after this frame's pyramid.
    let shadows = spec.states.get::<ShadowState>().map(|state| {
        let ids = import_shadows(c.g, c.externals, spec.atlas, state);
        c.t.shadow = Some(ids.atlas);
        (ids, state.has_hiz())
    });
    let after_pyramid = shadows.is_some_and(|(_, hiz)| hiz)
        && spec.options.shadows.culling == CasterCulling::ReceiversHiz
        && two_phase
        && (c.split_depth() || spec.setup.technique.screen_space());
    if let (Some((ids, _)), false) = (shadows, after_pyramid) {
        add_shadow_culling(c.g, ids, None);
        add_shadow_maps(c.g, ids);
    }
    // Reprojection: last frame's depth moved into this frame's view, before the culling that
    // tests against it.
    if let (Some(r), Some(previous)) = (c.reprojected, c.lists.and_then(|l| l.pyramid)) {
        add_reprojection(c.g, previous, r);
    }
    // GPU culling of the early (or only) phase; raster occlusion culls after its boxes.
    if let (Some(lists), false) = (c.lists, culling == Culling::RasterOcclusion) {
        add_cull(c.g, lists, culling);
    }
    for phase in if two_phase { 0..2 } else { 0..1 } {
        if phase == 1 {
            c.pyramid_and_late_culling();
            if let (Some((ids, _)), true) = (shadows, after_pyramid) {
                // The pyramid is this frame's only where the early phase wrote depth.
                let pyramid = c.lists.and_then(|l| l.pyramid);
                let pyramid = pyramid.filter(|_| c.t.depth_written());
                add_shadow_culling(c.g, ids, pyramid);
                add_shadow_maps(c.g, ids);
            }
        }
        c.geometry_phase(phase, two_phase);
    }
    c.colour_after_split_depth();
    c.after_geometry();
    c.finish()
}

/// A scene frame being composed: the graph, the physical resources of its imports, the
/// targets, and what the culling technique has declared so far.
struct Composition<'a> {
    spec: &'a SceneFrame<'a>,
    g: &'a mut FrameGraph,
    externals: &'a mut Externals,
    t: SceneTargets,
    /// The culling buffers, with GPU culling.
    lists: Option<CullLists>,
    /// Depth reprojection's buffers (`reproject`).
    reprojected: Option<Reprojected>,
    /// Same-frame occlusion queries: the buffer of their results on the GPU, which holds the
    /// previous frame's until this frame's copy (imported up front: the pre-pass reads them).
    results: Option<BufferId>,
    /// This frame's results, once the queries and their copy are declared.
    conditions: Option<BufferId>,
    /// Raster occlusion: its flags and culling are declared.
    flags_declared: bool,
}

impl<'a> Composition<'a> {
    /// Imports the targets (the renderer's colour, the ids it keeps) and the technique's
    /// buffers, and creates the depth.
    fn import(
        g: &'a mut FrameGraph,
        externals: &'a mut Externals,
        spec: &'a SceneFrame<'a>,
    ) -> Self {
        let SceneFrame {
            options,
            key,
            states,
            target,
            ids_target,
            depth_target,
            ..
        } = *spec;
        let extent = Extent2d::new(options.width, options.height);
        let color = g.import_image(
            "color",
            ImageDesc::new(extent, key.color.format),
            key.color.import,
        );
        externals.insert(color, External::Image(target.clone()));
        let depth_format = match options.depth_format {
            tilegraph_cull::DepthFormat::D16Unorm => Format::D16_UNORM,
            tilegraph_cull::DepthFormat::D32Float => Format::D32_SFLOAT,
        };
        let depth = match depth_target {
            Some(handle) => {
                let depth = g.import_image(
                    "depth",
                    ImageDesc::new(extent, depth_format),
                    kept_import(key.first_frame),
                );
                g.export(depth);
                externals.insert(depth, External::Image(handle.clone()));
                depth
            }
            None => g.create_image("depth", ImageDesc::new(extent, depth_format)),
        };
        let mut t = SceneTargets::new(color, depth, extent, options.clear_color, key.depth);
        if let Some(handle) = ids_target {
            let ids = g.import_image(
                "visbuf-id",
                ImageDesc::new(extent, Format::R32_UINT),
                kept_import(key.first_frame),
            );
            g.export(ids);
            externals.insert(ids, External::Image(handle.clone()));
            t.ids = Some(ids);
        }
        let hiz = states.get::<HizState>();
        let reprojected = states.get::<ReprojectState>().map(|r| {
            let ids = import_reprojection(g, r);
            externals.insert(ids.keys, External::Buffer(r.keys_handle()));
            externals.insert(ids.pyramid, External::Buffer(r.handle()));
            ids
        });
        let lists = states.get::<CullState>().map(|c| {
            let index_bytes = key.indices.map(|(_, size)| size);
            let lists = import_cull_buffers(g, c, hiz, reprojected.map(|r| r.pyramid), index_bytes);
            for (id, buffer) in [
                (lists.commands, &c.commands),
                (lists.counts, &c.counts),
                (lists.draw_ids, &c.draw_ids),
                (lists.visibility, &c.visibility),
                (lists.entries, &c.entries),
                (lists.survivors, &c.survivors),
            ] {
                externals.insert(id, External::Buffer(CullState::handle(buffer)));
            }
            if let (Some(l), Some(s)) = (lists.clusters, c.clusters.as_ref()) {
                for (id, buffer) in [
                    (l.commands, &s.commands),
                    (l.counts, &s.counts),
                    (l.flags, &s.flags),
                    (l.visibility, &s.visibility),
                    (l.runs, &s.runs),
                    (l.offsets, &s.offsets),
                    (l.work, &s.work),
                    (l.run_triangles, &s.run_triangles),
                ] {
                    externals.insert(id, External::Buffer(CullState::handle(buffer)));
                }
                let triangles = s.triangles.as_ref();
                if let (Some(t), Some(ts), Some((raw, size))) =
                    (l.triangles, triangles, key.indices)
                {
                    let handle = CullState::handle(&ts.triangles);
                    externals.insert(t.triangles, External::Buffer(handle));
                    let indices = tilegraph_vk::executor::BufferHandle { raw, size };
                    externals.insert(t.indices, External::Buffer(indices));
                }
            }
            if let (Some(id), Some(h)) = (lists.pyramid, hiz) {
                externals.insert(id, External::Buffer(CullState::handle(&h.pyramid)));
            }
            lists
        });
        let results = match (options.culling, states.get::<OqState>()) {
            (Culling::OqConditional, Some(q)) => q.conditions.as_ref().map(|buffer| {
                let id = import_query_results(g, buffer.size);
                externals.insert(id, External::Buffer(CullState::handle(buffer)));
                id
            }),
            _ => None,
        };
        Composition {
            spec,
            g,
            externals,
            t,
            lists,
            reprojected,
            results,
            conditions: None,
            flags_declared: false,
        }
    }

    fn culling(&self) -> Culling {
        self.spec.options.culling
    }

    /// Two-phase culling with a pre-pass: depth of the early lists, pyramid, late culling,
    /// depth of the late lists, then colour once over the union (the early lists, which the
    /// late dispatch completes) in the unculled order. The visibility buffer draws ids in both
    /// phases instead.
    fn split_depth(&self) -> bool {
        self.culling().base() == Culling::HizTwoPhase && self.spec.setup.has_prepass()
    }

    /// Between two-phase culling's phases: the pyramid of the early phase's depth, and the
    /// culling of what the early phase left out. No depth written by the early phase (nothing
    /// opaque or alpha-tested): no occluders, no pyramid, and no late lists to fill.
    fn pyramid_and_late_culling(&mut self) {
        if let (Some(lists), true) = (self.lists, self.t.depth_written()) {
            if let Some(pyramid) = lists.pyramid {
                add_hiz_build(self.g, self.t.depth, pyramid);
            }
            add_cull_late(self.g, lists);
        }
    }

    /// The frame setup's geometry passes of one culling phase, with what must precede the
    /// first colour pass: same-frame queries, raster occlusion.
    fn geometry_phase(&mut self, phase: u32, two_phase: bool) {
        let culling = self.culling();
        let setup = self.spec.setup;
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
            if self.split_depth() && !depth_only {
                continue; // colour after both depth phases
            }
            if !depth_only {
                self.before_colour();
            }
            // Raster occlusion tests boxes against the depth of everything: its pre-pass
            // draws the CPU lists; everything else draws the culling shader's lists.
            // What writes depth in the early phase: the pre-pass, or the screen-space
            // techniques' id or G-buffer pass.
            let early_depth =
                depth_only || matches!(pass, PassKind::VisbufWrite | PassKind::GbufferWrite);
            let source = match (self.lists, culling, depth_only) {
                (Some(_), Culling::RasterOcclusion, true) | (None, _, _) => DrawSource::Cpu,
                // Two-phase culling's early depth: where the cluster stage runs late only, the
                // instance compaction's lists.
                (Some(lists), _, _) if early_depth && two_phase && phase == 0 => {
                    lists.early_depth_source()
                }
                (Some(lists), _, _) => lists.source(phase),
            };
            let name = format!("{}{suffix}", pass.name());
            // Same-frame queries test boxes against last frame's visible set, drawn in depth
            // under last frame's results; colour, predicated on this frame's, writes the rest.
            let predicate = if depth_only {
                self.results
            } else {
                self.conditions
            };
            self.geometry(Geometry {
                pass,
                phase,
                source,
                predicate,
                partial_prepass: self.results.is_some(),
                name: &name,
            });
        }
    }

    /// What the first colour pass needs declared before it, once there is depth to test
    /// against: same-frame queries (colour is predicated on them), raster occlusion's boxes and
    /// culling (colour draws the lists they write).
    fn before_colour(&mut self) {
        let culling = self.culling();
        if culling.conditional() && self.conditions.is_none() && self.t.depth_written() {
            self.conditions = add_occlusion_queries(self.g, self.t.depth, self.results);
        }
        if culling == Culling::RasterOcclusion && !self.flags_declared {
            match (self.lists, self.t.depth_written()) {
                (Some(lists), true) => {
                    let scale = self.spec.options.raster_occlusion_scale.max(1);
                    add_raster_occlusion(self.g, &self.t, lists, scale);
                }
                // No pre-pass depth (nothing opaque): no boxes to test; the lists still get
                // written.
                (Some(lists), false) => add_cull(self.g, lists, Culling::RasterOcclusion),
                (None, _) => {}
            }
            self.flags_declared = true;
        }
    }

    /// Two-phase culling's colour, once over the union of both phases.
    fn colour_after_split_depth(&mut self) {
        if !self.split_depth() {
            return;
        }
        let setup = self.spec.setup;
        for pass in setup
            .included()
            .filter(|p| matches!(p, PassKind::Opaque | PassKind::AlphaTested))
        {
            self.geometry(Geometry {
                pass,
                phase: 0,
                source: self.lists.map_or(DrawSource::Cpu, |l| l.source(0)),
                predicate: self.conditions,
                partial_prepass: false,
                name: pass.name(),
            });
        }
    }

    /// After the geometry: the visibility buffer's or the G-buffer's resolve, blended
    /// geometry, next frame's occluders (single-phase HiZ: this frame's depth; occlusion
    /// queries read next frame, after all opaque work by the graph's class order), and a clear
    /// when nothing drew (an empty view of an empty scene still produces a cleared image, and
    /// a kept depth image a cleared depth).
    fn after_geometry(&mut self) {
        let setup = self.spec.setup;
        let culling = self.culling();
        let (g, t) = (&mut *self.g, &mut self.t);
        if let (true, Some(ids)) = (setup.includes(PassKind::VisbufResolve), t.ids) {
            let (mode, tile) = self.spec.options.visbuf_resolve(self.spec.profile);
            let input = self.spec.profile.is_tiler();
            let plan = ResolvePlan::new(mode, input, self.spec.key.materials, tile);
            add_visbuf_resolve(g, t, ids, plan);
        }
        if let (true, Some(gbuffer)) = (setup.includes(PassKind::GbufferResolve), t.gbuffer) {
            add_gbuffer_resolve(g, t, gbuffer, self.spec.profile.is_tiler());
        }
        if setup.includes(PassKind::Transparent) {
            add_transparent(g, t);
        }
        if let (Culling::Hiz | Culling::Reproject, Some(pyramid)) =
            (culling, self.lists.and_then(|l| l.pyramid))
        {
            add_hiz_build(g, t.depth, pyramid);
        }
        if culling.uses_queries() && !culling.conditional() && t.depth_written() {
            add_occlusion_queries(g, t.depth, None);
        }
        // A kept depth image is exported, so something must write it, as the colour.
        let clear_depth = self.spec.depth_target.is_some() && !t.depth_written();
        if !t.color_written() || clear_depth {
            add_clear(g, t, clear_depth);
        }
    }

    fn finish(self) -> ImageId {
        self.g.export(self.t.color);
        self.t.color
    }

    /// One geometry pass of the frame setup.
    fn geometry(&mut self, geometry: Geometry<'_>) {
        declare_geometry(self.g, &mut self.t, self.spec.setup, geometry);
    }
}

/// One geometry pass of the frame setup.
fn declare_geometry(
    g: &mut FrameGraph,
    t: &mut SceneTargets,
    setup: &FrameSetup,
    geometry: Geometry<'_>,
) {
    let Geometry {
        pass,
        phase,
        source,
        predicate,
        partial_prepass,
        name,
    } = geometry;
    let depth = |class: u32| match (setup.prepassed(class), partial_prepass) {
        (false, _) => ColourDepth::Write,
        (true, false) => ColourDepth::Equal,
        (true, true) => ColourDepth::WriteOrEqual,
    };
    match pass {
        PassKind::DepthPrepassOpaque | PassKind::DepthPrepassAlpha => {
            let class = if pass == PassKind::DepthPrepassAlpha {
                DrawClass::AlphaTested
            } else {
                DrawClass::Opaque
            };
            match predicate {
                Some(last) => add_depth_prepass_of_last_visible(g, t, class, last, name),
                None => add_depth_prepass(g, t, class, source, name),
            };
        }
        PassKind::Opaque => {
            add_forward(g, t, DrawClass::Opaque, depth(0), source, predicate, name);
        }
        PassKind::AlphaTested => {
            let d = depth(1);
            add_forward(g, t, DrawClass::AlphaTested, d, source, predicate, name);
        }
        PassKind::VisbufWrite => {
            add_visbuf_write(g, t, phase, source, name);
        }
        PassKind::GbufferWrite => {
            add_gbuffer_write(g, t, phase, source, name);
        }
        // After the geometry phases.
        PassKind::VisbufResolve | PassKind::GbufferResolve | PassKind::Transparent => {}
    }
}
