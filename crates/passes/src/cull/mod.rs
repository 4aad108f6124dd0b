//! GPU-driven culling: frustum, HiZ against last frame's pyramid, and two-phase occlusion
//! culling (seeds 000, 002, 004), as compute passes that write compacted indirect draws.
//!
//! Each culling phase is three dispatches (docs/ARCHITECTURE.md, "ordered compaction"):
//! `cull.comp` marks every instance's fixed entry in the unculled draw order,
//! `cull_compact.comp` packs the survivors of each draw group (one mesh's run of entries, the
//! CPU list's instanced draw) in that order, and `cull_commands.comp` writes one instanced
//! command per group that kept an instance, in group order, with the draw count. The culled
//! frame therefore draws its survivors in the unculled order (images stay bit-equal), and the
//! command processor walks survivors only. Where the device or the profile does without
//! `drawIndirectCount`, every group keeps its command (zero instances when culled) and the CPU
//! draws the list's group count.
//!
//! The buffers live as long as the renderer (they carry visibility and the pyramid from frame to
//! frame, and tools read the drawn set back); each frame imports them into its graph, so the
//! graph orders the dispatches, the indirect draws and the pyramid build and puts the barriers
//! between them.

use ash::vk;
use bytemuck::{Pod, Zeroable};
use glam::Mat4;
use tilegraph_cull::Frustum;
use tilegraph_graph::{
    AccessFlags, BufferId, Import, InitialContent, PassClass, PipelineStages, ResourceState,
    Retention,
};
use tilegraph_scene::DepthConvention;
use tilegraph_vk::ash;
use tilegraph_vk::executor::PassContext;
use tilegraph_vk::VkError;

pub use crate::setup::Culling;

use crate::frame::{scene_set, DrawSource, FrameGraph, Payload};
use crate::hiz::HizState;
use triangles::TriangleStep;

mod cluster_layout;
pub mod clusters;
mod compute;
mod layout;
mod readback;
mod state;
pub mod triangles;

pub use layout::GpuLayout;
pub use readback::{GpuLists, IndirectDraw};
pub use state::{CullInputs, CullState, DrawCount, FrameLists, GpuCullCounts, Occluder};

/// Temporal coherence of the occlusion tests (knob `occlusion_recheck`; CHC++, Mattausch et al.
/// 2008, re-queries visible objects at intervals): an item (a query group, or an instance under
/// raster occlusion) found visible is drawn without a test until its turn comes, once every
/// `interval` frames, staggered by item so the re-tests spread over the frames. Hidden items are
/// tested every frame, so nothing visible is ever culled: a stale "visible" costs draws only.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Recheck {
    interval: u32,
    offset: u32,
}

impl Recheck {
    /// Frame `frame`'s turns with `interval` (1 or less: every item is tested every frame).
    pub fn new(interval: u32, frame: u64) -> Self {
        let interval = interval.clamp(1, 0xFFFF);
        Recheck {
            interval,
            offset: (frame % u64::from(interval)) as u32,
        }
    }

    /// Whether an item found visible skips its test this frame (`recheck_carries` in
    /// `shaders/common/recheck.glsl`).
    pub fn carries(self, item: u32) -> bool {
        !item.wrapping_add(self.offset).is_multiple_of(self.interval)
    }

    /// The shaders' form: interval | offset << 16.
    pub fn packed(self) -> u32 {
        self.interval | (self.offset << 16)
    }
}

/// The culling buffers in one frame's graph. They live as long as the renderer (visibility and
/// the pyramid carry over from frame to frame, tools read the drawn set back), so each frame
/// imports them; the graph then orders the culling dispatches, the indirect draws and the
/// pyramid build, and puts the barriers between them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CullLists {
    pub commands: BufferId,
    pub counts: BufferId,
    pub draw_ids: BufferId,
    pub visibility: BufferId,
    /// Per list entry: 0 culled, instance id + 1 drawn (`cull.comp` → `cull_compact.comp`).
    pub entries: BufferId,
    /// Per draw group and phase: how many instances survived (→ `cull_commands.comp`).
    pub survivors: BufferId,
    pub pyramid: Option<BufferId>,
    /// What single-phase culling tests against: the pyramid (`hiz`), or the reprojected one
    /// (`reproject`).
    pub occluder: Option<BufferId>,
    /// Levels of detail are chosen: each instance's level is kept in the visibility words
    /// from frame to frame (the hysteresis), whatever the culling.
    pub lod_history: bool,
    /// The cluster stage's buffers (cluster techniques).
    pub clusters: Option<ClusterLists>,
}

/// The cluster stage's buffers in one frame's graph.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ClusterLists {
    pub commands: BufferId,
    pub counts: BufferId,
    pub flags: BufferId,
    /// Per cluster instance: visible last frame (kept from frame to frame).
    pub visibility: BufferId,
    pub runs: BufferId,
    pub offsets: BufferId,
    /// Each phase's chunks to cull and emit, and their indirect dispatches.
    pub work: BufferId,
    /// Per cluster command: the mesh's triangle its run starts at (the visibility buffer's
    /// ids count from it; visbuf.vert).
    pub run_triangles: BufferId,
    /// `cluster_early = instances`: the early phase is hiz-2phase's (the instance compaction,
    /// whole instances drawn); the cluster stage runs in the late phase only.
    pub whole_early: bool,
    /// A fixed draw count draws every list's whole capacity: the commands past this frame's
    /// count must be empty, so each emit is preceded by a clear.
    pub clear: bool,
    /// Per-triangle culling's buffers (knob `triangle_culling`).
    pub triangles: Option<TriangleLists>,
}

/// Per-triangle culling's buffers in one frame's graph.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TriangleLists {
    /// Per command slot: its kept triangles, then its place in the tail.
    pub triangles: BufferId,
    /// The scene's index buffer: the commands' cluster ranges are read, the tail written.
    pub indices: BufferId,
}

impl CullLists {
    /// The draws of culling phase `phase` (0: early or only, 1: late): the cluster commands
    /// where the technique culls clusters.
    pub fn source(self, phase: u32) -> DrawSource {
        let (commands, counts) = self
            .clusters
            .map_or((self.commands, self.counts), |c| (c.commands, c.counts));
        DrawSource::Gpu {
            commands,
            counts,
            draw_ids: self.draw_ids,
            runs: self.clusters.map(|c| c.run_triangles),
            group_counts: self.clusters.map(|c| c.offsets),
            phase,
            clusters: self.clusters.is_some(),
            indices: self.clusters.and_then(|c| c.triangles).map(|t| t.indices),
        }
    }

    /// The draws of two-phase culling's early depth pass: the instance lists where the cluster
    /// stage does not run early (`cluster_early = instances`: hiz-2phase's own early phase).
    pub fn early_depth_source(self) -> DrawSource {
        match self.clusters {
            Some(c) if c.whole_early => DrawSource::Gpu {
                commands: self.commands,
                counts: self.counts,
                draw_ids: self.draw_ids,
                // The culled set binds the runs: the visibility buffer's pass reads them.
                runs: Some(c.run_triangles),
                group_counts: None,
                phase: 0,
                clusters: false,
                indices: None,
            },
            _ => self.source(0),
        }
    }
}

/// Imports `state`'s buffers (and `hiz`'s pyramid) into the frame's graph; per-triangle
/// culling's with the scene's index buffer of `index_bytes`.
pub fn import_cull_buffers(
    g: &mut FrameGraph,
    state: &CullState,
    hiz: Option<&HizState>,
    reprojected: Option<BufferId>,
    index_bytes: Option<u64>,
) -> CullLists {
    // Conservative boundary states: whatever touched them last frame, this frame waits for.
    let any = ResourceState::buffer(
        PipelineStages::EVERY_GRAPH_STAGE,
        AccessFlags::MEMORY_READ.union(AccessFlags::MEMORY_WRITE),
    );
    let import = |content| Import {
        initial: any,
        content,
        final_state: any,
    };
    let discard = import(InitialContent::Discard);
    let keep = import(InitialContent::Preserve);
    let commands = g.import_buffer("cull-commands", state.commands.size, discard);
    let counts = g.import_buffer("cull-counts", state.counts.size, discard);
    let draw_ids = g.import_buffer("cull-draw-ids", state.draw_ids.size, discard);
    let visibility = g.import_buffer("visibility", state.visibility.size, keep);
    let entries = g.import_buffer("cull-entries", state.entries.size, discard);
    let survivors = g.import_buffer("cull-survivors", state.survivors.size, discard);
    let pyramid = hiz.map(|h| g.import_buffer("hiz-pyramid", h.pyramid.size, keep));
    let clusters = state.clusters.as_ref().map(|c| {
        let lists = ClusterLists {
            commands: g.import_buffer("cluster-commands", c.commands.size, discard),
            counts: g.import_buffer("cluster-counts", c.counts.size, discard),
            flags: g.import_buffer("cluster-flags", c.flags.size, discard),
            visibility: g.import_buffer("cluster-visibility", c.visibility.size, keep),
            runs: g.import_buffer("cluster-runs", c.runs.size, discard),
            offsets: g.import_buffer("cluster-offsets", c.offsets.size, discard),
            // Two-phase culling's late test empties the early phase's work for the next frame.
            work: g.import_buffer("cluster-work", c.work.size, keep),
            // Its first word, where the commands' draw ids start, is written once.
            run_triangles: g.import_buffer("cluster-run-triangles", c.run_triangles.size, keep),
            whole_early: state.cluster_early == ClusterEarly::Instances,
            clear: matches!(state.draw_count, DrawCount::Fixed { .. }),
            triangles: c.triangles.as_ref().zip(index_bytes).map(|(t, bytes)| {
                let lists = TriangleLists {
                    triangles: g.import_buffer("cluster-triangles", t.triangles.size, discard),
                    indices: g.import_buffer("scene-indices", bytes, keep),
                };
                g.export(lists.indices);
                lists
            }),
        };
        g.export(lists.visibility);
        g.export(lists.commands);
        g.export(lists.counts);
        lists
    });
    // What the next frame reads survives this one.
    g.export(visibility);
    if let Some(p) = pyramid {
        g.export(p);
    }
    // Tools read the drawn set back after the frame (a cluster technique's from the cluster
    // lists: the instance lists are not compacted).
    if clusters.is_none() {
        g.export(counts);
        g.export(commands);
    }
    g.export(draw_ids);
    CullLists {
        commands,
        counts,
        draw_ids,
        visibility,
        entries,
        survivors,
        pyramid,
        occluder: reprojected.or(pyramid),
        lod_history: state.lod_levels > 1,
        clusters,
    }
}

/// The three dispatches of a culling phase.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Step {
    /// `cull.comp`: one thread per instance marks its entries.
    Mark,
    /// `cull_compact.comp`: one workgroup per draw group packs its survivors.
    Compact,
    /// `cull_commands.comp`: one workgroup per list writes its commands and count.
    Commands,
    /// The cluster stage's dispatches (cluster techniques).
    Cluster(clusters::ClusterStep),
}

/// Declares the culling of the early (or only) phase of `culling`: the dispatches that write the
/// indirect lists (and empty the late lists, which a late phase fills). Frustum and HiZ test every instance (HiZ against
/// last frame's pyramid); two-phase culling's early phase draws last frame's visible set;
/// raster occlusion turns the flags its boxes wrote into lists.
pub fn add_cull(g: &mut FrameGraph, lists: CullLists, culling: Culling) {
    let two_phase = culling.base() == Culling::HizTwoPhase;
    let name = if two_phase { "cull-early" } else { "cull" };
    if let (Some(cl), false) = (lists.clusters, two_phase) {
        // The chunk list starts empty (the instance test appends). Two-phase culling's
        // instance tests empty each other's phase's instead (cull_body.glsl): no transfer
        // and barrier open its frame.
        let reset: Payload = Box::new(|pc, res| {
            let culling = res.states.require::<CullState>(pc.pass_name)?;
            culling.record_work_reset(pc.ctx, pc.cb)
        });
        g.transfer_pass("cluster-work-reset", PassClass::Transfer, reset)
            .transfer_dst(cl.work)
            .async_compute();
    }
    // Every culling dispatch reads the scene's buffers and writes only what it declares: all
    // may run on the async compute queue.
    let mut c = g.compute_pass(name, PassClass::Compute, dispatch(0, Step::Mark));
    c.async_compute().storage_write(lists.entries);
    if let Some(cl) = lists.clusters {
        c.storage_read_write(cl.work);
    }
    if two_phase || culling == Culling::RasterOcclusion || lists.lod_history {
        // The early phase reads last frame's visibility (raster occlusion: this frame's
        // flags; levels of detail: last frame's levels); cull.comp's visibility binding is
        // writable (the late phase writes it), so synchronization validation counts the
        // dispatch as a writer.
        c.storage_read_write(lists.visibility);
    }
    if let (Culling::Hiz | Culling::Reproject, Some(p)) = (culling, lists.occluder) {
        c.storage_read(p);
    }
    let (compact, commands) = if two_phase {
        ("cull-early-compact", "cull-early-commands")
    } else {
        ("cull-compact", "cull-commands")
    };
    match lists.clusters {
        // The cluster stage's own early phase.
        Some(c) if !(two_phase && c.whole_early) => add_cluster_stage(g, lists, 0),
        _ => add_compaction(g, lists, 0, [compact, commands]),
    }
    if !two_phase {
        add_cull_stats(g, lists);
    }
}

/// The cluster stage of phase `which` (0 early or only, 1 late), after the phase's instance
/// culling: cluster flags and runs, their places, then the commands (docs/CULLING.md).
fn add_cluster_stage(g: &mut FrameGraph, lists: CullLists, which: usize) {
    let Some(c) = lists.clusters else {
        return;
    };
    let names = if which == 0 {
        [
            "cluster-cull",
            "cluster-place",
            "cluster-clear",
            "cluster-emit",
        ]
    } else {
        [
            "cluster-cull-late",
            "cluster-place-late",
            "cluster-clear-late",
            "cluster-emit-late",
        ]
    };
    let mut cull = g.compute_pass(
        names[0],
        PassClass::Compute,
        dispatch(which, Step::Cluster(clusters::ClusterStep::Cull)),
    );
    cull.async_compute()
        .indirect(c.work)
        .storage_read(c.work)
        .storage_read(lists.entries)
        .storage_read(lists.visibility)
        .storage_read_write(c.flags)
        .storage_read_write(c.runs)
        .storage_read_write(c.visibility);
    // The shader reads the pyramid in the late phase only, but binds it in both.
    if let Some(p) = lists.pyramid {
        cull.storage_read(p);
    }
    g.compute_pass(
        names[1],
        PassClass::Compute,
        dispatch(which, Step::Cluster(clusters::ClusterStep::Place)),
    )
    .async_compute()
    .storage_read(c.runs)
    // Its last workgroup of a list reads the groups' places the others wrote.
    .storage_read_write(c.offsets)
    .storage_write(c.counts)
    // The lists' placed-group counters.
    .storage_read_write(c.work);
    if c.clear {
        let commands = c.commands;
        let clear: Payload = Box::new(move |pc, _| zero_fill(pc, commands));
        g.transfer_pass(names[2], PassClass::Transfer, clear)
            .transfer_dst(c.commands)
            .async_compute();
    }
    g.compute_pass(
        names[3],
        PassClass::Compute,
        dispatch(which, Step::Cluster(clusters::ClusterStep::Emit)),
    )
    .async_compute()
    .indirect(c.work)
    .storage_read(c.work)
    // It zeroes the entries' runs once placed, for the next culling to add to.
    .storage_read_write(c.runs)
    .storage_read(c.offsets)
    .storage_read(c.flags)
    .storage_read_write(c.commands)
    .storage_write(lists.draw_ids)
    .storage_write(c.run_triangles);
    if let Some(t) = c.triangles {
        add_triangle_stage(g, lists, c, t, which);
    }
}

/// Per-triangle culling of phase `which` after its cluster commands: count, place, pack
/// (docs/CULLING.md, "Triangles").
fn add_triangle_stage(
    g: &mut FrameGraph,
    lists: CullLists,
    c: ClusterLists,
    t: TriangleLists,
    which: usize,
) {
    let names = if which == 0 {
        ["triangle-count", "triangle-scan", "triangle-write"]
    } else {
        [
            "triangle-count-late",
            "triangle-scan-late",
            "triangle-write-late",
        ]
    };
    let step = |s| dispatch(which, Step::Cluster(clusters::ClusterStep::Triangles(s)));
    let mut count = g.compute_pass(names[0], PassClass::Compute, step(TriangleStep::Count));
    count
        .async_compute()
        .storage_read(c.commands)
        .storage_read(c.counts)
        .storage_read(c.offsets)
        .storage_read(lists.draw_ids)
        .storage_read(t.indices)
        .storage_read_write(t.triangles);
    if let Some(p) = lists.pyramid {
        count.storage_read(p);
    }
    g.compute_pass(names[1], PassClass::Compute, step(TriangleStep::Scan))
        .async_compute()
        .storage_read(c.counts)
        .storage_read(c.offsets)
        .storage_read_write(t.triangles);
    let mut write = g.compute_pass(names[2], PassClass::Compute, step(TriangleStep::Write));
    write
        .async_compute()
        .storage_read_write(c.commands)
        .storage_read(c.counts)
        .storage_read(c.offsets)
        .storage_read(lists.draw_ids)
        .storage_read_write(t.indices)
        .storage_read_write(t.triangles);
    if let Some(p) = lists.pyramid {
        write.storage_read(p);
    }
}

/// Declares the copy of the frame's draw and instance counts to the slot's host-visible
/// buffer, which the renderer reads when the slot comes round again (no stall). Kept: nothing in
/// the graph reads what it writes.
fn add_cull_stats(g: &mut FrameGraph, lists: CullLists) {
    let copy: Payload = Box::new(|pc, res| {
        let culling = res.states.require::<CullState>(pc.pass_name)?;
        culling.record_stats_copy(pc.ctx, pc.cb, pc.frame_slot)
    });
    let counts = lists.clusters.map_or(lists.counts, |c| c.counts);
    g.transfer_pass("cull-stats", PassClass::Transfer, copy)
        .transfer_src(counts)
        .retention(Retention::Always);
}

/// The compaction of phase `which` (0 early or only, 1 late): survivors packed per group, then
/// the commands and counts.
fn add_compaction(g: &mut FrameGraph, lists: CullLists, which: usize, names: [&'static str; 2]) {
    g.compute_pass(names[0], PassClass::Compute, dispatch(which, Step::Compact))
        .async_compute()
        .storage_read(lists.entries)
        .storage_write(lists.draw_ids)
        .storage_write(lists.survivors);
    g.compute_pass(
        names[1],
        PassClass::Compute,
        dispatch(which, Step::Commands),
    )
    .async_compute()
    .storage_read(lists.survivors)
    .storage_write(lists.commands)
    .storage_write(lists.counts);
}

/// Declares two-phase culling's late phase: the instances the early phase left out, tested
/// against the pyramid of the early phase's depth; the newly visible ones get the late lists
/// (the late depth pass) and join the early lists (the colour pass draws the union), and become
/// next frame's early set.
pub fn add_cull_late(g: &mut FrameGraph, lists: CullLists) {
    let mut c = g.compute_pass("cull-late", PassClass::Compute, dispatch(1, Step::Mark));
    c.async_compute()
        .storage_read_write(lists.entries)
        .storage_read_write(lists.visibility);
    if let Some(p) = lists.pyramid {
        c.storage_read(p);
    }
    if let Some(cl) = lists.clusters {
        c.storage_read_write(cl.work);
    }
    if lists.clusters.is_none() {
        add_compaction(g, lists, 1, ["cull-late-compact", "cull-late-commands"]);
    }
    add_cluster_stage(g, lists, 1);
    add_cull_stats(g, lists);
}

/// The culling dispatch `step` of phase `which` (0 early or only, 1 late).
fn dispatch(which: usize, step: Step) -> Payload {
    Box::new(move |pc, res| {
        let set = scene_set(pc, res)?;
        let culling = res.states.require::<CullState>(pc.pass_name)?;
        culling.record_dispatch(pc.ctx, pc.cb, set, pc.frame_slot, which, step)
    })
}

/// Zeroes a whole buffer (the graph put it in TRANSFER_DST use for the pass).
pub fn zero_fill(pc: &PassContext<'_>, buffer: BufferId) -> Result<(), VkError> {
    let b = pc.buffer(buffer)?;
    // SAFETY: recording outside a render pass; the buffer is live and a transfer destination.
    unsafe {
        pc.ctx
            .device
            .cmd_fill_buffer(pc.cb, b.raw, 0, vk::WHOLE_SIZE, 0)
    };
    Ok(())
}

/// Draw lists the culling shader writes: opaque and alpha-tested, single- and double-sided,
/// for the early (or only) phase and the late phase.
pub const LISTS_PER_PHASE: u32 = 4;
pub const LIST_COUNT: u32 = 2 * LISTS_PER_PHASE;

/// List index of a class (0 opaque, 1 alpha-tested) and sidedness in a phase (0 early/only,
/// 1 late).
pub fn list_index(class: u32, double_sided: bool, phase: u32) -> u32 {
    phase * LISTS_PER_PHASE + class * 2 + u32::from(double_sided)
}

/// `CullParams` of `shaders/common/cull.glsl` (std140).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct CullParams {
    pub planes: [[f32; 4]; 6],
    pub hiz_view_proj: [[f32; 4]; 4],
    /// x instances, y phase, z HiZ levels (0 = none), w 1 for reverse-Z.
    pub info: [u32; 4],
    /// x, y pyramid level-0 size; z list stride.
    pub screen: [u32; 4],
    /// x draw groups per phase (at least 1), y 1 = keep empty commands (fixed draw count),
    /// z 1 = a D16 pyramid (the HiZ test compares the code on the near side).
    pub groups: [u32; 4],
    /// Per list of a phase: its first draw group.
    pub group_start: [u32; 4],
    /// Per list of a phase: its number of draw groups.
    pub group_count: [u32; 4],
    /// Sphere bounds: camera-relative position -> view space of the pyramid's frame.
    pub hiz_view: [[f32; 4]; 4],
    /// Sphere bounds: x, y NDC per view unit; z 1 perspective, 0 orthographic, -1 a matrix
    /// the sphere test does not model (the box is tested).
    pub hiz_proj: [f32; 4],
    /// Sphere bounds: clip z = x * view z + y, clip w = z * view z + w.
    pub hiz_depth: [f32; 4],
    /// Cluster culling: x draw id of cluster command 0, y 1 = cone test, z cluster instances.
    pub clusters: [u32; 4],
    /// Cluster culling: per list 0-7, its first command.
    pub cmd_base: [[u32; 4]; 2],
    /// x: command slots per list (the most draw groups a list holds); cluster culling: y where
    /// the instances' first chunks are kept in the cluster base buffer, z where the chunks'
    /// instances are, w the chunks.
    pub commands: [u32; 4],
    /// Per-triangle culling: x the index buffer tail's first index, y its length, z the
    /// snapping step in pixels (f32 bits), w where the tail places start in its buffer.
    pub triangles: [u32; 4],
    /// Level of detail: x the largest error in pixels (0 off), y pixels per unit of length at
    /// distance 1 (perspective) or anywhere (orthographic), z 1 perspective.
    pub lod: [f32; 4],
    /// Level of detail: x levels per draw group (1 off: the commands per group), y meshes in
    /// the level table.
    pub lod_info: [u32; 4],
}

/// The bounding volume culling tests an instance by (knob `cull_bounds`). Both are conservative
/// and come from the same transformed local box (`tilegraph_scene`'s instance bounds).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum CullBounds {
    /// The world-space AABB: six plane tests, eight projected corners.
    #[default]
    Aabb,
    /// The sphere around the transformed local box: one plane test per plane and the tight
    /// rect of its silhouette (Mara & McGuire 2013). Fewer instructions; looser than the box
    /// for boxy, axis-aligned objects, tighter for rotated thin ones.
    Sphere,
}

impl CullBounds {
    pub fn name(self) -> &'static str {
        match self {
            CullBounds::Aabb => "aabb",
            CullBounds::Sphere => "sphere",
        }
    }
}

/// The longest gap of culled clusters a cluster technique's command draws through by default
/// (knob `cluster_gap`): docs/CULLING.md, "Clusters", measures the trade.
pub const CLUSTER_GAP: u32 = 0;

/// What two-phase cluster culling's early phase draws of an instance visible last frame (knob
/// `cluster_early`; docs/CULLING.md, "Clusters"). Both are exact: the late phase tests every
/// cluster of the instances visible now.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ClusterEarly {
    /// The whole instance: the early phase is `hiz-2phase`'s own (its instanced lists; the
    /// cluster stage runs in the late phase only), so the same depth, pyramid, instances
    /// visible now and history — and the colour pass, clusters of those instances, never draws
    /// more triangles than `hiz-2phase`'s.
    #[default]
    Instances,
    /// Its clusters in the frustum and not back-facing that the pyramid did not find occluded
    /// last frame (the cluster stage runs in both phases): less early work where instances are
    /// large and mostly hidden (a level's room as one mesh), but after a turn or a cut the early
    /// depth can be thinner than instance culling's, and the late phase then draws more.
    Clusters,
}

impl ClusterEarly {
    pub fn name(self) -> &'static str {
        match self {
            ClusterEarly::Instances => "instances",
            ClusterEarly::Clusters => "clusters",
        }
    }

    pub fn parse(s: &str) -> Option<Self> {
        [ClusterEarly::Instances, ClusterEarly::Clusters]
            .into_iter()
            .find(|c| c.name() == s)
    }
}

/// What the sphere test needs of a projection matrix: (P00, P11, kind, 0) and the depth row
/// (m22, m32, m23, m33). Kind 1 perspective, 0 orthographic, -1 anything with off-centre or
/// shear terms, for which the shader tests the box instead.
pub fn sphere_projection(projection: Mat4) -> ([f32; 4], [f32; 4]) {
    let (x, y, z, w) = (
        projection.x_axis,
        projection.y_axis,
        projection.z_axis,
        projection.w_axis,
    );
    let plain = x.y == 0.0
        && x.z == 0.0
        && x.w == 0.0
        && y.x == 0.0
        && y.z == 0.0
        && y.w == 0.0
        && z.x == 0.0
        && z.y == 0.0
        && w.x == 0.0
        && w.y == 0.0;
    let kind = match (plain, z.w != 0.0) {
        (false, _) => -1.0,
        (true, true) if w.w == 0.0 => 1.0,
        (true, true) => -1.0,
        (true, false) => 0.0,
    };
    ([x.x, y.y, kind, 0.0], [z.z, w.z, z.w, w.w])
}

/// The phase argument of `cull.comp`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Phase {
    Frustum = 0,
    HizPrevious = 1,
    Early = 2,
    Late = 3,
}

/// Levels of detail as GPU culling chooses them (docs/CULLING.md, "Levels of detail").
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LodSettings {
    /// The largest error a level may project to, in pixels (knob `lod_error_px`; 0: full
    /// detail).
    pub error_px: f32,
    /// The switching band (knob `lod_hysteresis`): an instance moves to a coarser level than
    /// last frame's only when that level's error projects to at most `error_px * (1 -
    /// hysteresis)`; to a finer one as soon as its level's exceeds `error_px`. 0: no band.
    pub hysteresis: f32,
}

/// Frustum planes of a camera-relative view-projection, for the shader (absent far plane of an
/// infinite projection becomes a plane every point passes).
pub fn gpu_planes(view_proj: Mat4, convention: DepthConvention) -> Result<[[f32; 4]; 6], VkError> {
    let f =
        Frustum::from_clip_from_world(&view_proj, convention).map_err(|e| VkError::Invalid {
            what: "frustum".into(),
            reason: e.to_string(),
        })?;
    Ok(f.gpu_planes().map(|p| p.to_array()))
}

/// CPU plane-test frustum culling (the reference's conservative test), in camera-relative f64
/// bounds, of the drawn instances of `grid` (one of the scene's): `out` gets those not
/// rejected. Cells first, then the members of the cells the frustum cuts: the cost follows what
/// is visible. Used for blended geometry (the GPU lists leave it to the CPU to be sorted back
/// to front) and for the lists the CPU decides.
pub fn cpu_frustum_visible(
    grid: &tilegraph_scene::LooseGrid,
    m: &tilegraph_scene::FrameMatrices,
    out: &mut Vec<tilegraph_scene::GridMember>,
) -> Result<(), VkError> {
    frustum_visit(grid, m, out, None)
}

/// [`cpu_frustum_visible`], also saying which runs of `out` share a cell (`cells`, in order):
/// software occlusion tests a cell's box before its members.
pub fn cpu_frustum_visible_by_cell(
    grid: &tilegraph_scene::LooseGrid,
    m: &tilegraph_scene::FrameMatrices,
    out: &mut Vec<tilegraph_scene::GridMember>,
    cells: &mut Vec<tilegraph_scene::CellRun>,
) -> Result<(), VkError> {
    frustum_visit(grid, m, out, Some(cells))
}

fn frustum_visit(
    grid: &tilegraph_scene::LooseGrid,
    m: &tilegraph_scene::FrameMatrices,
    out: &mut Vec<tilegraph_scene::GridMember>,
    mut cells: Option<&mut Vec<tilegraph_scene::CellRun>>,
) -> Result<(), VkError> {
    let frustum = Frustum::from_clip_from_world(&m.view_projection, m.depth).map_err(|e| {
        VkError::Invalid {
            what: "frustum".into(),
            reason: e.to_string(),
        }
    })?;
    let eye = m.eye;
    out.clear();
    if let Some(c) = cells.as_deref_mut() {
        c.clear();
    }
    // Bounds are finite (the scene refuses anything else): the f64 test needs no checks.
    grid.visit_cells(
        |cell| {
            let center = (cell.min + cell.max) * 0.5 - eye;
            match frustum.test_box(center, (cell.max - cell.min) * 0.5) {
                tilegraph_cull::PlaneTest::Inside => tilegraph_scene::Overlap::Inside,
                tilegraph_cull::PlaneTest::Intersecting => tilegraph_scene::Overlap::Partial,
                tilegraph_cull::PlaneTest::Outside(_) => tilegraph_scene::Overlap::Outside,
            }
        },
        |bounds, members, overlap| {
            let before = out.len();
            if overlap == tilegraph_scene::Overlap::Inside {
                out.extend_from_slice(members);
            } else {
                out.extend(members.iter().filter(|member| {
                    !matches!(
                        frustum.test_box(member.center - eye, member.half_extents.as_dvec3()),
                        tilegraph_cull::PlaneTest::Outside(_)
                    )
                }));
            }
            if let (Some(c), true) = (cells.as_deref_mut(), out.len() > before) {
                c.push(tilegraph_scene::CellRun {
                    bounds: *bounds,
                    end: out.len() as u32,
                });
            }
        },
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_item_has_one_turn_in_each_interval_and_the_turns_are_staggered() {
        for interval in [1u32, 2, 8, 32] {
            for item in [0u32, 1, 7, 12_345, u32::MAX] {
                let turns = (0..u64::from(interval))
                    .filter(|&f| !Recheck::new(interval, f).carries(item))
                    .count();
                assert_eq!(turns, 1, "item {item}, interval {interval}");
            }
            // In any frame, 1 item in `interval` has its turn.
            let due = (0..1024u32)
                .filter(|&i| !Recheck::new(interval, 5).carries(i))
                .count();
            assert_eq!(due, 1024 / interval as usize, "interval {interval}");
        }
        assert_eq!(Recheck::new(8, 13).packed(), 8 | (5 << 16));
        // Out of range: every item tested every frame.
        assert!(!Recheck::new(0, 3).carries(9));
    }

    #[test]
    fn cli_spellings_round_trip() {
        for c in Culling::ALL {
            assert_eq!(Culling::parse(c.name()), Some(c));
        }
        assert_eq!(
            Culling::parse("oq-conditional"),
            Some(Culling::OqConditional)
        );
        assert_eq!(
            Culling::parse("raster-occlusion"),
            Some(Culling::RasterOcclusion)
        );
        assert_eq!(Culling::parse("occlusion"), None);
    }

    #[test]
    fn same_frame_occlusion_techniques_need_a_prepass_and_the_right_path() {
        assert!(Culling::OqConditional.needs_prepass() && Culling::OqConditional.uses_queries());
        assert!(!Culling::OqConditional.uses_gpu_lists());
        assert!(
            Culling::RasterOcclusion.needs_prepass() && Culling::RasterOcclusion.uses_gpu_lists()
        );
        assert!(!Culling::Oq.needs_prepass() && !Culling::Oq.uses_gpu_lists());
    }

    #[test]
    fn sphere_projection_reads_the_matrices_tilegraph_makes_and_flags_others() {
        use tilegraph_scene::Projection;
        let perspective = Projection::Perspective {
            fov_y_rad: 1.0,
            near: 0.1,
            far: None,
            depth: DepthConvention::Reverse,
        };
        let (proj, depth) = sphere_projection(perspective.matrix(2.0));
        let (sx, sy) = perspective.ndc_scale(2.0);
        assert_eq!(proj[2], 1.0);
        assert!((f64::from(proj[0]) - sx).abs() < 1e-6 && (f64::from(proj[1]) - sy).abs() < 1e-6);
        // Reverse infinite: clip z = near, clip w = -z.
        assert_eq!(depth, [0.0, 0.1, -1.0, 0.0]);
        let ortho = Projection::Orthographic {
            half_height: 5.0,
            near: 0.5,
            far: 50.0,
            depth: DepthConvention::Standard,
        };
        assert_eq!(sphere_projection(ortho.matrix(1.0)).0[2], 0.0);
        // An off-centre (jittered) projection is not modelled: the shader tests the box.
        let mut jittered = perspective.matrix(2.0);
        jittered.z_axis.x = 0.001;
        assert_eq!(sphere_projection(jittered).0[2], -1.0);
    }
}
