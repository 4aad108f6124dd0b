//! Hardware occlusion queries (`Culling::Oq`, seeds 001 and 002).
//!
//! Each opaque or alpha-tested instance (or group of nearby instances, `--oq-group N`) gets one
//! `VK_QUERY_TYPE_OCCLUSION` query per frame: its camera-relative bounding box (`oq_box.vert`,
//! 36 vertices, no vertex buffer) is drawn against the frame's depth after all opaque work,
//! depth tested, nothing written, in a pass of class `PassClass::OcclusionQuery` (the graph puts
//! it in a render pass of its own after a flush where the profile asks, seed 001).
//!
//! Results are never waited for (seed 002: query pools never stall). There is a pool per frame
//! slot; when a slot is acquired its fence has signalled, so its results (and those of any
//! later frame that is already complete) are read without `WAIT`; the newest complete frame
//! decides the next frame's drawn set. A query with no result yet counts as passed: the
//! instance is drawn. Objects that become visible are drawn one frame late (false negatives,
//! measured by `cull-check`).

use ash::vk;
use glam::{DVec3, Mat4, Vec3, Vec4};
use tilegraph_graph::{
    AccessFlags, BufferId, ImageId, Import, InitialContent, PassClass, PipelineStages,
    ResourceState, Retention,
};
use tilegraph_scene::{DepthConvention, FrameMatrices, Scene};
use tilegraph_vk::ash;
use tilegraph_vk::executor::PassContext;
use tilegraph_vk::pipeline::create_pipeline_layout;
use tilegraph_vk::{Buffer, Context, VkError};

use crate::cull::Recheck;
use crate::frame::{scene_set, FrameGraph, PassState, Payload, SceneResources};
use crate::pipelines::Proxy;

/// Push constants of `oq_box.vert`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct BoxPush {
    pub center: [f32; 4],
    pub half_extents: [f32; 4],
}

/// One query: the instances it decides for and their union box (world space, f64).
#[derive(Debug, Clone, PartialEq)]
pub struct QueryGroup {
    pub members: Vec<u32>,
    pub min: DVec3,
    pub max: DVec3,
}

/// Groups of `group_size` consecutive instances in a spatial order (Morton code of the bounds
/// centre on a 1024^3 grid over the scene), skipping the excluded (blended) ones. With
/// `group_size` 1, one query per instance. `by_mesh`: a group holds instances of one mesh
/// (conditional rendering then predicates one instanced draw per run of a group's instances).
pub fn build_groups(
    scene: &Scene,
    group_size: usize,
    excluded: &[bool],
    by_mesh: bool,
) -> Vec<QueryGroup> {
    let instances = scene.instances();
    let ids: Vec<u32> = (0..instances.len() as u32)
        .filter(|&i| !excluded.get(i as usize).copied().unwrap_or(false))
        .collect();
    let mut lo = DVec3::splat(f64::INFINITY);
    let mut hi = DVec3::splat(f64::NEG_INFINITY);
    for &i in &ids {
        if let Some(inst) = instances.get(i as usize) {
            lo = lo.min(inst.bounds.center);
            hi = hi.max(inst.bounds.center);
        }
    }
    let extent = (hi - lo).max(DVec3::splat(1e-9));
    let key = |i: u32| -> u64 {
        let Some(inst) = instances.get(i as usize) else {
            return 0;
        };
        let q =
            ((inst.bounds.center - lo) / extent * 1023.0).clamp(DVec3::ZERO, DVec3::splat(1023.0));
        morton3(q.x as u32, q.y as u32, q.z as u32)
    };
    let mesh = |i: &u32| {
        instances
            .get(*i as usize)
            .filter(|_| by_mesh)
            .map_or(0, |inst| inst.mesh.0)
    };
    let mut sorted = ids;
    if group_size > 1 {
        sorted.sort_by_key(|&i| (mesh(&i), key(i), i));
    }
    sorted
        .chunk_by(|a, b| mesh(a) == mesh(b))
        .flat_map(|run| run.chunks(group_size.max(1)))
        .map(|members| {
            let mut min = DVec3::splat(f64::INFINITY);
            let mut max = DVec3::splat(f64::NEG_INFINITY);
            for &i in members {
                if let Some(inst) = instances.get(i as usize) {
                    let b = inst.bounds.aabb();
                    min = min.min(b.min);
                    max = max.max(b.max);
                }
            }
            QueryGroup {
                members: members.to_vec(),
                min,
                max,
            }
        })
        .collect()
}

fn morton3(x: u32, y: u32, z: u32) -> u64 {
    fn spread(v: u32) -> u64 {
        let mut v = u64::from(v & 0x3ff);
        v = (v | (v << 16)) & 0x0300_00ff;
        v = (v | (v << 8)) & 0x0300_f00f;
        v = (v | (v << 4)) & 0x030c_30c3;
        (v | (v << 2)) & 0x0924_9249
    }
    spread(x) | (spread(y) << 1) | (spread(z) << 2)
}

/// A corner of the box the proxy shaders rasterize for a camera-relative box: grown by a little
/// more than a pixel and pulled toward the eye (`proxy_corner` in `shaders/common/scene.glsl`,
/// which this mirrors).
pub fn proxy_corner(center: Vec3, half: Vec3, corner_sign: Vec3, viewport_height_px: f32) -> Vec3 {
    let pixel = center.length() * 0.5 / viewport_height_px.max(1.0);
    let grown = half * (1.0 + 1.0 / 1024.0) + Vec3::splat(1e-4 + pixel);
    (center + grown * corner_sign) * (1.0 - 1.0 / 4096.0)
}

/// How near the near plane a proxy may come and still be drawn, in NDC depth (`NEAR_GUARD` in
/// `shaders/common/scene.glsl`): the proxy pipelines' depth bias (`PROXY_DEPTH_BIAS`, at most
/// 2^-14 for D16) then keeps its depth inside [0, 1].
pub const NEAR_GUARD: f32 = 1.0 / 4096.0;

/// Whether the proxy box of a camera-relative box reaches in front of the near plane, into its
/// guard band ([`NEAR_GUARD`]) or behind the eye: its rasterization is clipped there, so a query
/// could miss a visible object. Such boxes are not queried; their instances are drawn. The test
/// is on the corners the proxy shader draws (grown, see [`proxy_corner`]), not on the box itself.
pub fn crosses_near_plane(
    view_proj: Mat4,
    depth: DepthConvention,
    center: Vec3,
    half: Vec3,
    viewport_height_px: f32,
) -> bool {
    (0..8).any(|c| {
        let s = Vec3::new(
            if c & 1 == 0 { -1.0 } else { 1.0 },
            if c & 2 == 0 { -1.0 } else { 1.0 },
            if c & 4 == 0 { -1.0 } else { 1.0 },
        );
        let corner = proxy_corner(center, half, s, viewport_height_px);
        let p = view_proj * corner.extend(1.0);
        p.w <= 0.0
            || match depth {
                DepthConvention::Reverse => p.z >= p.w * (1.0 - NEAR_GUARD),
                DepthConvention::Standard => p.z <= p.w * NEAR_GUARD,
            }
    })
}

/// Per frame slot: the frame whose queries the pool holds, the group of each query it issued
/// (query `k` tested `groups[k]`), and the groups it drew untested because they were visible
/// (`occlusion_recheck`).
#[derive(Debug, Default, Clone)]
struct Pending {
    frame: u64,
    groups: Vec<u32>,
    carried: Vec<u32>,
}

/// Folds one complete frame into what is known visible per group (`occlusion_recheck`): a query's
/// answer replaces what was known; a group the frame drew untested because it was known visible
/// keeps what is known (a later frame's answer may already have said it is hidden: frames in
/// flight overlap, and results are read in frame order); any other group — out of the frustum,
/// at the near plane — is not known visible, so it is queried when it can be.
fn learn_visibility(known: &mut [bool], carried: &[u32], answers: &[(u32, bool)]) {
    let mut keep = vec![false; known.len()];
    for &g in carried {
        if let Some(k) = keep.get_mut(g as usize) {
            *k = true;
        }
    }
    for (k, keep) in known.iter_mut().zip(keep) {
        *k = *k && keep;
    }
    for &(g, passed) in answers {
        if let Some(k) = known.get_mut(g as usize) {
            *k = passed;
        }
    }
}

/// Marks a group that a frame did not query in [`OqState`]'s per-group query indices.
const NOT_QUERIED: u32 = u32::MAX;

/// The group of an instance that changed since the groups were made ([`OqState::forget`]): in
/// no group, drawn unconditionally (blended instances are in none either, `u32::MAX`, but drawn
/// by their own passes).
const FORGOTTEN: u32 = u32::MAX - 1;

/// The persistent occlusion-query state of one renderer.
pub struct OqState {
    pub groups: Vec<QueryGroup>,
    /// Per instance: its group, `u32::MAX` when not queried (blended).
    group_of: Vec<u32>,
    /// Per group: the newest known result (passed, or no result yet).
    passed: Vec<bool>,
    /// Per group: the newest complete frame found it visible (its query passed, or it was
    /// carried as visible); such a group is queried again only on its turn.
    known_visible: Vec<bool>,
    /// Frames between re-tests of a visible group (knob `occlusion_recheck`).
    recheck_interval: u32,
    pools: Vec<vk::QueryPool>,
    pending: Vec<Option<Pending>>,
    /// This frame's boxes, one query each: query `k` draws `frame_boxes[k]`. Queries are
    /// numbered densely in issue order, so one copy moves every result of a frame.
    frame_boxes: Vec<BoxPush>,
    frame_slot: usize,
    frames: u64,
    pub pipeline_layout: vk::PipelineLayout,
    /// Conditional rendering: this frame's results on the GPU, one u32 per query.
    pub conditions: Option<Buffer>,
    /// Per group: this frame's query index, [`NOT_QUERIED`] when it issued none (its members
    /// draw unconditionally).
    current_query: Vec<u32>,
    /// Per group: the previous frame's query index, whose result [`Self::conditions`] holds
    /// when this frame's depth pre-pass reads it (oq-conditional).
    previous_query: Vec<u32>,
    /// Per instance: whether this frame's CPU lists hold it (frustum).
    current_drawable: Vec<bool>,
    /// Instances forgotten since the groups were made.
    forgotten: usize,
}

impl PassState for OqState {
    fn destroy(self: Box<Self>, ctx: &Context) {
        self.destroy_all(ctx);
    }
}

impl OqState {
    /// Device features the queries need: host query reset (pools are reset on the CPU when
    /// their results are read, so no reset command has to sit outside the query render pass).
    pub fn required_features() -> [tilegraph_vk::Feature; 1] {
        [tilegraph_vk::Feature::HostQueryReset]
    }

    /// Queries for `scene`'s drawn opaque and alpha-tested instances, in groups of
    /// `group_size`.
    pub fn new(
        ctx: &Context,
        scene: &Scene,
        group_size: usize,
        conditional: bool,
        scene_set_layout: vk::DescriptorSetLayout,
        frames_in_flight: usize,
    ) -> Result<Self, VkError> {
        let excluded: Vec<bool> = scene
            .instances()
            .iter()
            .map(|i| {
                !i.flags.is_drawn()
                    || scene
                        .instance_material(i)
                        .is_some_and(|m| m.class == tilegraph_scene::MaterialClass::Blended)
            })
            .collect();
        let groups = build_groups(scene, group_size, &excluded, conditional);
        let mut group_of = vec![u32::MAX; scene.instances().len()];
        for (g, group) in groups.iter().enumerate() {
            for &i in &group.members {
                if let Some(slot) = group_of.get_mut(i as usize) {
                    *slot = g as u32;
                }
            }
        }
        let push = vk::PushConstantRange {
            stage_flags: vk::ShaderStageFlags::VERTEX,
            offset: 0,
            size: std::mem::size_of::<BoxPush>() as u32,
        };
        let pipeline_layout = create_pipeline_layout(ctx, &[scene_set_layout], Some(push))?;
        let mut state = OqState {
            passed: vec![true; groups.len()],
            known_visible: vec![false; groups.len()],
            recheck_interval: 1,
            groups,
            group_of,
            pools: Vec::new(),
            pending: vec![None; frames_in_flight.max(1)],
            frame_boxes: Vec::new(),
            frame_slot: 0,
            frames: 0,
            pipeline_layout,
            conditions: None,
            current_query: Vec::new(),
            previous_query: Vec::new(),
            current_drawable: Vec::new(),
            forgotten: 0,
        };
        let count = state.query_count();
        if conditional {
            match ctx.create_buffer(
                "oq conditions",
                4 * u64::from(count),
                vk::BufferUsageFlags::TRANSFER_DST
                    | vk::BufferUsageFlags::TRANSFER_SRC
                    | vk::BufferUsageFlags::INDIRECT_BUFFER
                    | vk::BufferUsageFlags::CONDITIONAL_RENDERING_EXT,
                tilegraph_profile::MemoryUse::GpuOnly,
            ) {
                Ok(b) => state.conditions = Some(b),
                Err(e) => {
                    state.destroy_all(ctx);
                    return Err(e);
                }
            }
        }
        for _ in 0..frames_in_flight.max(1) {
            let info = vk::QueryPoolCreateInfo::default()
                .query_type(vk::QueryType::OCCLUSION)
                .query_count(count);
            // SAFETY: valid create info.
            let pool = match unsafe { ctx.device.create_query_pool(&info, None) } {
                Ok(p) => p,
                Err(r) => {
                    state.destroy_all(ctx);
                    return Err(VkError::call("vkCreateQueryPool", r));
                }
            };
            // SAFETY: a new pool, unused by the GPU; hostQueryReset is enabled (required).
            unsafe { ctx.device.reset_query_pool(pool, 0, count) };
            state.pools.push(pool);
        }
        Ok(state)
    }

    /// Query a group found visible again once every `interval` frames (staggered by group);
    /// in between it is drawn untested. Hidden groups are queried every frame.
    pub fn set_recheck_interval(&mut self, interval: u32) {
        self.recheck_interval = interval.max(1);
    }

    fn query_count(&self) -> u32 {
        self.groups.len().max(1) as u32
    }

    /// Reads every complete frame's results without waiting, oldest first (call after the
    /// executor acquired `slot`: that slot's frame has completed). Only that slot's pool is
    /// reset on the host: another slot's queries may all be available while its frame is still
    /// running (a copy of its results, say), and resetting under it is invalid.
    pub fn collect(&mut self, ctx: &Context, slot: usize) -> Result<(), VkError> {
        let count = self.query_count();
        let mut order: Vec<(u64, usize)> = self
            .pending
            .iter()
            .enumerate()
            .filter_map(|(s, p)| p.as_ref().map(|p| (p.frame, s)))
            .collect();
        order.sort_unstable();
        for (_, s) in order {
            let (Some(pool), Some(Some(p))) = (self.pools.get(s).copied(), self.pending.get(s))
            else {
                continue;
            };
            // [result, availability] per query issued.
            let mut results = vec![[0u32; 2]; p.groups.len()];
            if !results.is_empty() {
                // SAFETY: the frame issued queries 0..groups.len() of the pool's `count`; no WAIT
                // flag, so this never stalls.
                let r = unsafe {
                    ctx.device.get_query_pool_results(
                        pool,
                        0,
                        &mut results,
                        vk::QueryResultFlags::WITH_AVAILABILITY,
                    )
                };
                match r {
                    Ok(()) | Err(vk::Result::NOT_READY) => {}
                    Err(e) => return Err(VkError::call("vkGetQueryPoolResults", e)),
                }
            }
            let complete = results.iter().all(|[_, avail]| *avail != 0);
            if !complete && s != slot {
                // Still in flight; frames complete in order, so later ones are too.
                break;
            }
            // Groups the frame did not query pass; a query without its result passes too.
            self.passed.fill(true);
            let answers: Vec<(u32, bool)> = p
                .groups
                .iter()
                .zip(&results)
                .map(|(&g, [value, avail])| (g, *avail == 0 || *value != 0))
                .collect();
            for &(g, passed) in &answers {
                if let Some(slot) = self.passed.get_mut(g as usize) {
                    *slot = passed;
                }
            }
            learn_visibility(&mut self.known_visible, &p.carried, &answers);
            if s != slot {
                // Newer results, read early; the pool is recycled when its slot comes round.
                continue;
            }
            // SAFETY: the slot's fence signalled: nothing on the GPU uses the pool; hostQueryReset
            // is enabled.
            unsafe { ctx.device.reset_query_pool(pool, 0, count) };
            if let Some(p) = self.pending.get_mut(s) {
                *p = None;
            }
        }
        Ok(())
    }

    /// Instance slot `instance` changed since the groups were made (it moved, came or went,
    /// was hidden or shown): its group's box no longer stands for it, so it is drawn without a
    /// query from now on, until the groups are made again.
    pub fn forget(&mut self, instance: u32) {
        let i = instance as usize;
        if self.group_of.len() <= i {
            self.group_of.resize(i + 1, FORGOTTEN);
        }
        if self.group_of[i] != FORGOTTEN {
            self.group_of[i] = FORGOTTEN;
            self.forgotten += 1;
        }
    }

    /// Instances drawn without a query since the groups were made ([`Self::forget`]).
    pub fn forgotten(&self) -> usize {
        self.forgotten
    }

    /// Per instance: whether the newest query result lets it be drawn (instances without a
    /// query, the blended ones, are always drawn here).
    pub fn mask(&self) -> Vec<bool> {
        self.group_of
            .iter()
            .map(|&g| g == u32::MAX || self.passed.get(g as usize).copied().unwrap_or(true))
            .collect()
    }

    /// This frame's boxes in slot `slot`, camera-relative to `m.eye`; `drawable` (per
    /// instance, the CPU frustum test) leaves out groups with no member in the frustum: not
    /// queried, and not drawn (they are not in the CPU lists either). A group the newest
    /// complete frame found visible is not queried unless its re-test turn came: it is drawn.
    pub fn prepare(
        &mut self,
        slot: usize,
        m: &FrameMatrices,
        viewport_height_px: f32,
        drawable: Option<&[bool]>,
    ) {
        self.frame_boxes.clear();
        let mut queried = Vec::new();
        let mut carried = Vec::new();
        let recheck = Recheck::new(self.recheck_interval, self.frames);
        let mut query_of = vec![NOT_QUERIED; self.groups.len()];
        let in_view = |i: u32| drawable.is_none_or(|d| d.get(i as usize).copied().unwrap_or(true));
        self.current_drawable = self
            .group_of
            .iter()
            .enumerate()
            .map(|(i, _)| in_view(i as u32))
            .collect();
        for (q, g) in self.groups.iter().enumerate() {
            if !g.members.iter().any(|&i| in_view(i)) {
                continue;
            }
            let center = ((g.min + g.max) * 0.5 - m.eye).as_vec3();
            // Rounding to f32 may shrink the box by an ulp: pad it slightly.
            let half = ((g.max - g.min) * 0.5).as_vec3() * (1.0 + 1e-5) + Vec3::splat(1e-5);
            if crosses_near_plane(m.view_projection, m.depth, center, half, viewport_height_px) {
                continue;
            }
            let q32 = q as u32;
            if self.known_visible.get(q).copied().unwrap_or(false) && recheck.carries(q32) {
                carried.push(q32);
                continue;
            }
            if let Some(k) = query_of.get_mut(q) {
                *k = queried.len() as u32;
            }
            queried.push(q as u32);
            self.frame_boxes.push(BoxPush {
                center: Vec4::from((center, 0.0)).to_array(),
                half_extents: Vec4::from((half, 0.0)).to_array(),
            });
        }
        self.frames += 1;
        self.previous_query = std::mem::replace(&mut self.current_query, query_of);
        if let Some(p) = self.pending.get_mut(slot) {
            *p = Some(Pending {
                frame: self.frames,
                groups: queried,
                carried,
            });
        }
        self.frame_slot = slot;
    }

    /// Records this frame's queries (inside the query pass's subpass).
    pub fn record(
        &self,
        pc: &PassContext<'_>,
        scene_set: vk::DescriptorSet,
        pipeline: vk::Pipeline,
    ) -> Result<(), VkError> {
        let pool = *self
            .pools
            .get(pc.frame_slot)
            .ok_or_else(|| VkError::Invalid {
                what: "occlusion queries".into(),
                reason: format!("no pool for slot {}", pc.frame_slot),
            })?;
        if pc.frame_slot != self.frame_slot {
            return Err(VkError::Invalid {
                what: "occlusion queries".into(),
                reason: format!(
                    "prepared for slot {}, recorded in slot {}",
                    self.frame_slot, pc.frame_slot
                ),
            });
        }
        pc.set_full_viewport();
        let d = &pc.ctx.device;
        // SAFETY: inside the query subpass; pipeline, layout and set are live; every query of
        // the pool was reset on the host after its last use (`collect`, `new`).
        unsafe {
            d.cmd_bind_pipeline(pc.cb, vk::PipelineBindPoint::GRAPHICS, pipeline);
            d.cmd_bind_descriptor_sets(
                pc.cb,
                vk::PipelineBindPoint::GRAPHICS,
                self.pipeline_layout,
                0,
                &[scene_set],
                &[],
            );
            for (q, push) in (0u32..).zip(&self.frame_boxes) {
                d.cmd_begin_query(pc.cb, pool, q, vk::QueryControlFlags::empty());
                d.cmd_push_constants(
                    pc.cb,
                    self.pipeline_layout,
                    vk::ShaderStageFlags::VERTEX,
                    0,
                    bytemuck::bytes_of(push),
                );
                d.cmd_draw(pc.cb, 36, 1, 0, 0);
                d.cmd_end_query(pc.cb, pool, q);
            }
        }
        Ok(())
    }

    /// Conditional rendering: the byte offset of `instance`'s result in [`Self::conditions`],
    /// or `None` when this frame did not query it (it is drawn unconditionally).
    pub fn condition_offset(&self, instance: u32) -> Option<u64> {
        self.offset_in(&self.current_query, instance)
    }

    /// [`Self::condition_offset`] in the results the previous frame left in
    /// [`Self::conditions`]: what this frame's depth pre-pass is predicated on.
    pub fn previous_condition_offset(&self, instance: u32) -> Option<u64> {
        self.offset_in(&self.previous_query, instance)
    }

    /// The result offset of `instance`'s group's query in `query_of` (per group), if it ran.
    fn offset_in(&self, query_of: &[u32], instance: u32) -> Option<u64> {
        let g = *self.group_of.get(instance as usize)?;
        let q = *query_of.get(g as usize)?;
        (q != NOT_QUERIED).then_some(4 * u64::from(q))
    }

    /// Conditional rendering: copies this frame's results into [`Self::conditions`] (waiting on
    /// the GPU, not the CPU). The graph makes them visible to the conditional-rendering stage
    /// (the colour passes declare the buffer as their predicate).
    pub fn record_copy(&self, pc: &PassContext<'_>) -> Result<(), VkError> {
        let (Some(conditions), Some(&pool)) = (&self.conditions, self.pools.get(pc.frame_slot))
        else {
            return Ok(());
        };
        let issued = self.frame_boxes.len() as u32;
        if issued == 0 {
            return Ok(());
        }
        // SAFETY: outside a render pass; queries 0..issued were issued in this frame's command
        // buffers before this pass (the graph orders it after the query pass); the buffer holds
        // a u32 per group, at least as many as queries, and is in TRANSFER_DST use for this pass.
        unsafe {
            pc.ctx.device.cmd_copy_query_pool_results(
                pc.cb,
                pool,
                0,
                issued,
                conditions.raw,
                0,
                4,
                vk::QueryResultFlags::WAIT,
            );
        }
        Ok(())
    }

    /// Conditional rendering: the instances the last frame drew (not queried, or query passed);
    /// reads the results back (the caller waited for the frame).
    pub fn conditional_drawn(&self, ctx: &Context) -> Result<Vec<u32>, VkError> {
        let Some(conditions) = &self.conditions else {
            return Ok(Vec::new());
        };
        let bytes = tilegraph_vk::readback::read_buffer(
            ctx,
            tilegraph_vk::executor::BufferHandle {
                raw: conditions.raw,
                size: conditions.size,
            },
        )?;
        let result = |g: u32| {
            let at = 4 * g as usize;
            bytes
                .get(at..at + 4)
                .map_or(0, |w| u32::from_le_bytes([w[0], w[1], w[2], w[3]]))
        };
        Ok(self
            .group_of
            .iter()
            .enumerate()
            .filter(|(_, &g)| g != u32::MAX)
            .filter(|(i, _)| self.current_drawable.get(*i).copied().unwrap_or(true))
            .filter(|(_, &g)| match self.current_query.get(g as usize) {
                Some(&q) if q != NOT_QUERIED => result(q) != 0,
                _ => true,
            })
            .map(|(i, _)| i as u32)
            .collect())
    }

    fn destroy_all(self, ctx: &Context) {
        if let Some(b) = self.conditions {
            ctx.destroy_buffer(b);
        }
        // SAFETY: the GPU is idle (caller's guarantee).
        unsafe {
            for p in self.pools {
                ctx.device.destroy_query_pool(p, None);
            }
            ctx.device
                .destroy_pipeline_layout(self.pipeline_layout, None);
        }
    }
}

/// Imports the buffer the occlusion queries' results are copied to (`size` bytes, one `u32`
/// per query group), for conditional rendering: it keeps the last frame's results, which the
/// next frame's depth pre-pass is predicated on, until this frame's copy replaces them.
pub fn import_query_results(g: &mut FrameGraph, size: u64) -> BufferId {
    // Last frame's conditional draws read it (the stage needs the feature these frames have).
    let any = ResourceState::buffer(
        PipelineStages::EVERY_GRAPH_STAGE.union(PipelineStages::CONDITIONAL_RENDERING),
        AccessFlags::MEMORY_READ.union(AccessFlags::MEMORY_WRITE),
    );
    let conditions = g.import_buffer(
        "oq-conditions",
        size,
        Import {
            initial: any,
            content: InitialContent::Preserve,
            final_state: any,
        },
    );
    // Tools read the drawn set back after the frame.
    g.export(conditions);
    conditions
}

/// Declares the occlusion queries: every queried box drawn against `depth` (tested, not
/// written), in a pass kept without an export (its results leave the graph through the query
/// pool). With `conditions` ([`import_query_results`], for conditional rendering in the same
/// frame), a copy of the results into it follows, and it is returned for the colour passes to
/// declare as their predicate.
pub fn add_occlusion_queries(
    g: &mut FrameGraph,
    depth: ImageId,
    conditions: Option<BufferId>,
) -> Option<BufferId> {
    let queries: Payload = Box::new(|pc, res| {
        let set = scene_set(pc, res)?;
        let SceneResources {
            pipelines,
            states,
            frame,
            ..
        } = res;
        let q = states.require::<OqState>(pc.pass_name)?;
        let pipeline = pipelines.proxy(pc, Proxy::QueryBox, q.pipeline_layout, frame.depth)?;
        q.record(pc, set, pipeline)
    });
    let query_pass = g
        .raster_pass("occlusion-queries", PassClass::OcclusionQuery, queries)
        .depth_stencil_read_only(depth)
        .retention(Retention::Always)
        .id();
    let conditions = conditions?;
    let copy: Payload =
        Box::new(|pc, res| res.states.require::<OqState>(pc.pass_name)?.record_copy(pc));
    g.transfer_pass("oq-copy-results", PassClass::Transfer, copy)
        .transfer_dst(conditions)
        .after(query_pass);
    Some(conditions)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn groups_cover_every_queried_instance_once_and_their_boxes_hold_the_members() {
        let scene = tilegraph_scene::load("city:300").unwrap();
        let n = scene.instances().len();
        let excluded: Vec<bool> = (0..n).map(|i| i % 7 == 0).collect();
        for (size, by_mesh) in [(1, false), (4, false), (16, false), (16, true)] {
            let groups = build_groups(&scene, size, &excluded, by_mesh);
            if by_mesh {
                for g in &groups {
                    let mesh = |i: &u32| scene.instances()[*i as usize].mesh;
                    assert!(g.members.iter().all(|i| mesh(i) == mesh(&g.members[0])));
                }
            }
            let mut seen = vec![0; n];
            for g in &groups {
                assert!(g.members.len() <= size);
                for &i in &g.members {
                    seen[i as usize] += 1;
                    let b = scene.instances()[i as usize].bounds.aabb();
                    assert!(b.min.cmpge(g.min).all() && b.max.cmple(g.max).all());
                }
            }
            for (i, s) in seen.iter().enumerate() {
                assert_eq!(
                    *s,
                    usize::from(!excluded[i]),
                    "instance {i}, groups of {size}"
                );
            }
        }
    }

    #[test]
    fn boxes_reaching_in_front_of_the_near_plane_are_not_queried() {
        let proj = Mat4::perspective_infinite_reverse_rh(1.0, 16.0 / 9.0, 0.1);
        let reverse = DepthConvention::Reverse;
        let h = 90.0;
        // In front of the camera (-z), well past the near plane.
        assert!(!crosses_near_plane(
            proj,
            reverse,
            Vec3::new(0.0, 0.0, -10.0),
            Vec3::ONE,
            h
        ));
        // The camera inside the box.
        assert!(crosses_near_plane(proj, reverse, Vec3::ZERO, Vec3::ONE, h));
        // Straddling the near plane.
        assert!(crosses_near_plane(
            proj,
            reverse,
            Vec3::new(0.0, 0.0, -0.5),
            Vec3::splat(0.45),
            h
        ));
        // Entirely behind the camera.
        assert!(crosses_near_plane(
            proj,
            reverse,
            Vec3::new(0.0, 0.0, 10.0),
            Vec3::ONE,
            h
        ));
        // A 20 m wall whose nearest face is 2 cm past the near plane, 6 m off-axis: the box
        // itself is clear of the plane, the proxy the shader draws (grown by about a pixel,
        // 3 cm here) is not. Querying it would clip its front face and hide a visible wall.
        let (center, half) = (Vec3::new(6.0, 0.0, -0.17), Vec3::new(10.0, 10.0, 0.05));
        let p = proj * (center + Vec3::new(0.0, 0.0, half.z)).extend(1.0);
        assert!(
            p.z < p.w,
            "the box's own nearest face is past the near plane"
        );
        assert!(crosses_near_plane(proj, reverse, center, half, h));
    }

    /// Two frames in flight: frame F is prepared from F-2's results, so the even and the odd
    /// frames form two chains. A visible group whose turn falls in one chain was found hidden
    /// there; the other chain, which only carried it, must not make it visible again.
    #[test]
    fn a_carried_group_keeps_the_newest_answer_of_any_frame() {
        let mut known = vec![true, true, false];
        // Odd frame: group 0's turn, found hidden; group 1 carried; group 2 out of the frustum.
        learn_visibility(&mut known, &[1], &[(0, false)]);
        assert_eq!(known, [false, true, false]);
        // A frame that carried groups 0 and 1 (it saw them visible) read again after it, as
        // `collect` re-reads a frame whose slot has not come round.
        learn_visibility(&mut known, &[0, 1], &[]);
        assert_eq!(
            known,
            [false, true, false],
            "carrying never makes a group visible"
        );
        // Group 2 comes into view, queried, passes; group 1 leaves the frustum.
        learn_visibility(&mut known, &[], &[(2, true)]);
        assert_eq!(known, [false, false, true]);
    }

    #[test]
    fn morton_keys_interleave_axes() {
        assert_eq!(morton3(1, 0, 0), 1);
        assert_eq!(morton3(0, 1, 0), 2);
        assert_eq!(morton3(0, 0, 1), 4);
        assert_eq!(morton3(1023, 1023, 1023), (1 << 30) - 1);
    }
}
