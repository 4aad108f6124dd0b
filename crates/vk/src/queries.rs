//! GPU timing without stalls: a ring of query pools, one slot per frame in flight.
//!
//! seed 002: measure GPU time with timer queries from a *pool* that is read frames later, never
//! waiting for the GPU — a frame's results are read only after that frame's fence has signalled,
//! with `vkGetQueryPoolResults` and no WAIT flag. What a frame measures is its [`GpuTiming`]: a
//! timestamp before and after each pass (around the whole render pass, its load and store
//! operations included, when the pass is its only subpass), with (where the device supports them) a
//! pipeline-statistics query counting vertex and fragment shader invocations; or two timestamps
//! around the whole frame; or nothing. Medians over frames come from [`TimingHistory`].

use std::collections::BTreeMap;

use ash::vk;
use serde::Serialize;

use crate::error::{VkError, VkResultExt};
use crate::{Context, Feature};

/// One pass's measurements for one frame.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PassTiming {
    pub name: String,
    /// Raw begin/end timestamps (ticks), for monotonicity checks.
    pub begin_ticks: u64,
    pub end_ticks: u64,
    pub gpu_ms: f64,
    /// Vertex shader invocations (pipeline statistics), when supported.
    pub vertex_invocations: Option<u64>,
    /// Fragment shader invocations (pipeline statistics), when supported.
    pub fragment_invocations: Option<u64>,
}

/// Every pass of one frame, in execution order.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct FrameTimings {
    pub frame: u64,
    pub passes: Vec<PassTiming>,
}

impl FrameTimings {
    /// Room for `names` (a plan's passes): entries with those names, overwritten by the next
    /// collection without allocating.
    pub fn reserve<'a>(&mut self, names: impl Iterator<Item = &'a str>) {
        for (i, name) in names.enumerate() {
            match self.passes.get_mut(i) {
                Some(p) if p.name.capacity() >= name.len() => {}
                Some(p) => p.name.reserve(name.len()),
                None => self.passes.push(PassTiming {
                    name: name.to_string(),
                    begin_ticks: 0,
                    end_ticks: 0,
                    gpu_ms: 0.0,
                    vertex_invocations: None,
                    fragment_invocations: None,
                }),
            }
        }
    }
}

struct Slot {
    timestamps: vk::QueryPool,
    stats: vk::QueryPool,
    /// Names of the passes recorded into this slot, in order: the first `passes` of them
    /// (the strings are kept and overwritten, so a steady frame allocates nothing).
    names: Vec<String>,
    passes: usize,
    frame: u64,
    /// Whether statistics queries were begun (and so must be read) for each pass.
    has_stats: Vec<bool>,
    /// What the slot's frame measures (the ring's mode when the frame began).
    timing: GpuTiming,
}

/// What a frame's queries measure. Every query costs the GPU something (on an H100 a
/// statistics query about 4 µs a pass), and only a frame timed whole counts what lies between
/// its passes (attachment clears, stores, barriers). A shipped frame wants `Frame` or `Off`; a
/// profile being tuned wants the passes.
///
/// The opening timestamp of a frame timed whole is written at the top of the pipe: with frames
/// back to back it could be written while the previous frame still runs. Measured, it is not:
/// on an H100 a frame whose first pass is compute times 0.922 ms whole against 0.931 from its
/// first pass's start to its last pass's end, and on lavapipe the whole frame matches the CPU's
/// frame-to-frame time.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum GpuTiming {
    /// No queries.
    Off,
    /// Two timestamps around the whole frame: one timing, named [`FRAME_TIMING`].
    Frame,
    /// A timestamp pair around each pass.
    Passes,
    /// A timestamp pair and a pipeline-statistics query (vertex and fragment shader
    /// invocations, where the device counts them) around each pass.
    #[default]
    PassStatistics,
}

impl GpuTiming {
    /// The mode's name in messages and the docs.
    pub const fn name(self) -> &'static str {
        match self {
            GpuTiming::Off => "off",
            GpuTiming::Frame => "frame",
            GpuTiming::Passes => "passes",
            GpuTiming::PassStatistics => "pass-statistics",
        }
    }

    fn per_pass(self) -> bool {
        matches!(self, GpuTiming::Passes | GpuTiming::PassStatistics)
    }
}

impl std::fmt::Display for GpuTiming {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// The name of the one timing a [`GpuTiming::Frame`] frame has.
pub const FRAME_TIMING: &str = "frame";

/// The ring. `capacity_passes` bounds how many passes one frame may time.
pub struct QueryRing {
    slots: Vec<Slot>,
    /// Result buffers of `collect`, kept.
    timestamp_results: Vec<[u64; 2]>,
    statistics_results: Vec<[u64; 3]>,
    capacity_passes: u32,
    period_ns: f64,
    valid_mask: u64,
    stats_supported: bool,
    timing: GpuTiming,
}

const STATS: vk::QueryPipelineStatisticFlags = vk::QueryPipelineStatisticFlags::from_raw(
    vk::QueryPipelineStatisticFlags::VERTEX_SHADER_INVOCATIONS.as_raw()
        | vk::QueryPipelineStatisticFlags::FRAGMENT_SHADER_INVOCATIONS.as_raw(),
);

impl QueryRing {
    /// A ring of `slots` frames (frames in flight + 1 is plenty), each timing up to
    /// `capacity_passes` passes.
    pub fn new(ctx: &Context, slots: usize, capacity_passes: u32) -> Result<Self, VkError> {
        if ctx.physical.limits.timestamp_valid_bits == 0 {
            return Err(VkError::MissingRequired {
                device: ctx.physical.identity.device_name.clone(),
                what: "queue capability",
                missing: "timestamps on the graphics queue".into(),
            });
        }
        let stats_supported = ctx.has_feature(Feature::PipelineStatisticsQuery);
        let bits = ctx.physical.limits.timestamp_valid_bits;
        let mut ring = QueryRing {
            slots: Vec::with_capacity(slots),
            timestamp_results: Vec::new(),
            statistics_results: Vec::new(),
            // Two timestamps per pass in one pool: at most u32::MAX / 2 passes.
            capacity_passes: capacity_passes.clamp(1, u32::MAX / 2),
            period_ns: f64::from(ctx.physical.limits.timestamp_period_ns),
            valid_mask: if bits >= 64 {
                u64::MAX
            } else {
                (1u64 << bits) - 1
            },
            stats_supported,
            timing: GpuTiming::default(),
        };
        for i in 0..slots.max(1) {
            let ts_info = vk::QueryPoolCreateInfo::default()
                .query_type(vk::QueryType::TIMESTAMP)
                .query_count(2 * ring.capacity_passes);
            // SAFETY: valid create info.
            let timestamps =
                unsafe { ctx.device.create_query_pool(&ts_info, None) }.vk("vkCreateQueryPool");
            let timestamps = match timestamps {
                Ok(p) => p,
                Err(e) => {
                    ring.destroy(ctx);
                    return Err(e);
                }
            };
            let mut stats = vk::QueryPool::null();
            if stats_supported {
                let info = vk::QueryPoolCreateInfo::default()
                    .query_type(vk::QueryType::PIPELINE_STATISTICS)
                    .query_count(ring.capacity_passes)
                    .pipeline_statistics(STATS);
                // SAFETY: pipeline statistics were enabled on this device.
                match unsafe { ctx.device.create_query_pool(&info, None) }.vk("vkCreateQueryPool") {
                    Ok(p) => stats = p,
                    Err(e) => {
                        // SAFETY: unused pool.
                        unsafe { ctx.device.destroy_query_pool(timestamps, None) };
                        ring.destroy(ctx);
                        return Err(e);
                    }
                }
            }
            ctx.set_name(timestamps, &format!("timestamps[{i}]"));
            ring.slots.push(Slot {
                timestamps,
                stats,
                names: Vec::new(),
                passes: 0,
                frame: 0,
                has_stats: Vec::new(),
                timing: GpuTiming::Off,
            });
        }
        Ok(ring)
    }

    pub fn slots(&self) -> usize {
        self.slots.len()
    }

    pub fn capacity_passes(&self) -> u32 {
        self.capacity_passes
    }

    pub fn statistics_supported(&self) -> bool {
        self.stats_supported
    }

    pub fn timing(&self) -> GpuTiming {
        self.timing
    }

    /// Measures the frames recorded from now on with `timing`. A slot recorded before keeps
    /// what it recorded and is collected as it was.
    pub fn set_timing(&mut self, timing: GpuTiming) {
        self.timing = timing;
    }

    /// Starts recording frame `frame` into `slot`: resets its queries on the GPU timeline. The
    /// caller guarantees the slot's previous frame has completed (its fence signalled) and has
    /// been collected (or is abandoned).
    pub fn begin_frame(
        &mut self,
        ctx: &Context,
        cb: vk::CommandBuffer,
        slot: usize,
        frame: u64,
    ) -> Result<(), VkError> {
        let cap = self.capacity_passes;
        let timing = self.timing;
        let s = self.slot_mut(slot)?;
        s.passes = 0;
        s.has_stats.clear();
        s.frame = frame;
        s.timing = timing;
        if timing == GpuTiming::Off {
            return Ok(());
        }
        // Only what this frame writes is reset: two timestamps for a frame-only timing.
        let (timestamps, stats) = match timing {
            GpuTiming::Frame => (2, 0),
            GpuTiming::Passes => (2 * cap, 0),
            _ => (2 * cap, cap),
        };
        // SAFETY: cb is recording outside a render pass; the pools are not in use by the GPU
        // (the caller waited on this slot's fence).
        unsafe {
            ctx.device
                .cmd_reset_query_pool(cb, s.timestamps, 0, timestamps);
            if stats != 0 && s.stats != vk::QueryPool::null() {
                ctx.device.cmd_reset_query_pool(cb, s.stats, 0, stats);
            }
        }
        if timing == GpuTiming::Frame {
            match s.names.first_mut() {
                Some(kept) => {
                    kept.clear();
                    kept.push_str(FRAME_TIMING);
                }
                None => s.names.push(FRAME_TIMING.to_string()),
            }
            s.passes = 1;
            s.has_stats.push(false);
            ctx.cmd_write_timestamp2(cb, vk::PipelineStageFlags2::TOP_OF_PIPE, s.timestamps, 0)?;
        }
        Ok(())
    }

    /// Ends frame-only timing ([`GpuTiming::Frame`]) of the frame recorded into `slot`: its
    /// closing timestamp, after everything the frame recorded. Nothing for the other modes.
    pub fn end_frame(
        &mut self,
        ctx: &Context,
        cb: vk::CommandBuffer,
        slot: usize,
    ) -> Result<(), VkError> {
        let s = self.slot_mut(slot)?;
        if s.timing == GpuTiming::Frame {
            ctx.cmd_write_timestamp2(cb, vk::PipelineStageFlags2::BOTTOM_OF_PIPE, s.timestamps, 1)?;
        }
        Ok(())
    }

    /// Writes the "before" timestamp of a pass and returns its index in the frame, for
    /// [`QueryRing::end_pass`]; `None` when the frame does not time its passes. With
    /// [`GpuTiming::PassStatistics`], begins a pipeline-statistics query (call outside or at the
    /// start of a render pass the query is wholly inside, per the spec's rules on query scope).
    pub fn begin_pass(
        &mut self,
        ctx: &Context,
        cb: vk::CommandBuffer,
        slot: usize,
        (name, graphics): (&str, bool),
    ) -> Result<Option<u32>, VkError> {
        let cap = self.capacity_passes;
        // Pipeline statistics count graphics stages: not on a compute-only queue.
        let stats_ok = self.stats_supported && graphics;
        let s = self.slot_mut(slot)?;
        if !s.timing.per_pass() {
            return Ok(None);
        }
        let index = s.passes as u32;
        if index >= cap {
            return Err(VkError::Invalid {
                what: format!("timing pass {name:?}"),
                reason: format!(
                    "more than {cap} passes in one frame; raise the query ring capacity"
                ),
            });
        }
        match s.names.get_mut(s.passes) {
            Some(kept) => {
                kept.clear();
                kept.push_str(name);
            }
            None => s.names.push(name.to_string()),
        }
        s.passes += 1;
        let stats = s.timing == GpuTiming::PassStatistics && stats_ok;
        s.has_stats.push(stats);
        ctx.cmd_write_timestamp2(
            cb,
            vk::PipelineStageFlags2::TOP_OF_PIPE,
            s.timestamps,
            2 * index,
        )?;
        // SAFETY: queries were reset in begin_frame; each index is begun once per frame.
        unsafe {
            if stats {
                ctx.device
                    .cmd_begin_query(cb, s.stats, index, vk::QueryControlFlags::empty());
            }
        }
        Ok(Some(index))
    }

    /// Writes the "after" timestamp of pass `index` (and ends its statistics query); nothing
    /// for a pass [`QueryRing::begin_pass`] did not time.
    pub fn end_pass(
        &mut self,
        ctx: &Context,
        cb: vk::CommandBuffer,
        slot: usize,
        index: Option<u32>,
    ) -> Result<(), VkError> {
        let Some(index) = index else {
            return Ok(());
        };
        let s = self.slot_mut(slot)?;
        let stats = s.has_stats.get(index as usize).copied().unwrap_or(false);
        if stats {
            // SAFETY: matches the cmd_begin_query of begin_pass on the same command buffer.
            unsafe { ctx.device.cmd_end_query(cb, s.stats, index) };
        }
        ctx.cmd_write_timestamp2(
            cb,
            vk::PipelineStageFlags2::BOTTOM_OF_PIPE,
            s.timestamps,
            2 * index + 1,
        )
    }

    /// Room for a frame of `names` (a plan's passes) in every slot and in the result
    /// buffers: recording and collecting such frames allocate nothing.
    pub fn reserve<'a>(&mut self, names: impl Iterator<Item = &'a str> + Clone) {
        let n = names.clone().count();
        self.timestamp_results.reserve(2 * n);
        self.statistics_results.reserve(n);
        for s in &mut self.slots {
            s.has_stats.reserve(n);
            for (i, name) in names.clone().enumerate() {
                match s.names.get_mut(i) {
                    Some(kept) => kept.reserve(name.len()),
                    None => s.names.push(name.to_string()),
                }
            }
        }
    }

    /// Reads a completed slot without waiting into `out` (its passes overwritten in place:
    /// no allocation once it has held as many passes). `Ok(false)` when the slot holds nothing
    /// or its results are not available yet (the caller asks only after the frame completed).
    pub fn collect_into(
        &mut self,
        ctx: &Context,
        slot: usize,
        out: &mut FrameTimings,
    ) -> Result<bool, VkError> {
        let period_ns = self.period_ns;
        let mask = self.valid_mask;
        let n_slots = self.slots.len();
        let QueryRing {
            slots,
            timestamp_results: ts,
            statistics_results: stats,
            ..
        } = self;
        let s = slots.get_mut(slot).ok_or_else(|| VkError::Invalid {
            what: "query ring".into(),
            reason: format!("slot {slot} out of {n_slots}"),
        })?;
        let n = s.passes;
        if n == 0 {
            return Ok(false);
        }
        // [value, availability] pairs.
        ts.clear();
        ts.resize(2 * n, [0; 2]);
        // SAFETY: queries 0..2n were written in this slot's frame; no WAIT flag: never stalls.
        let r = unsafe {
            ctx.device.get_query_pool_results(
                s.timestamps,
                0,
                ts.as_mut_slice(),
                vk::QueryResultFlags::TYPE_64 | vk::QueryResultFlags::WITH_AVAILABILITY,
            )
        };
        match r {
            Ok(()) | Err(vk::Result::NOT_READY) => {}
            Err(e) => return Err(VkError::call("vkGetQueryPoolResults", e)),
        }
        if ts.iter().any(|[_, avail]| *avail == 0) {
            return Ok(false);
        }
        stats.clear();
        stats.resize(n, [0; 3]);
        if s.has_stats.iter().any(|b| *b) {
            // SAFETY: as above; statistics layout: [vertex, fragment, availability].
            let r = unsafe {
                ctx.device.get_query_pool_results(
                    s.stats,
                    0,
                    stats.as_mut_slice(),
                    vk::QueryResultFlags::TYPE_64 | vk::QueryResultFlags::WITH_AVAILABILITY,
                )
            };
            match r {
                Ok(()) | Err(vk::Result::NOT_READY) => {}
                Err(e) => return Err(VkError::call("vkGetQueryPoolResults", e)),
            }
        }
        out.frame = s.frame;
        out.passes.truncate(n);
        for i in 0..n {
            let begin = ts[2 * i][0] & mask;
            let end = ts[2 * i + 1][0] & mask;
            let st = s.has_stats.get(i).copied().unwrap_or(false) && stats[i][2] != 0;
            let name = s.names.get(i).map_or("?", String::as_str);
            let timing = PassTiming {
                name: String::new(),
                begin_ticks: begin,
                end_ticks: end,
                // The counter wraps at 2^timestampValidBits, not 2^64.
                gpu_ms: (end.wrapping_sub(begin) & mask) as f64 * period_ns / 1e6,
                vertex_invocations: st.then_some(stats[i][0]),
                fragment_invocations: st.then_some(stats[i][1]),
            };
            match out.passes.get_mut(i) {
                Some(kept) => {
                    let mut kept_name = std::mem::take(&mut kept.name);
                    kept_name.clear();
                    kept_name.push_str(name);
                    *kept = PassTiming {
                        name: kept_name,
                        ..timing
                    };
                }
                None => out.passes.push(PassTiming {
                    name: name.to_string(),
                    ..timing
                }),
            }
        }
        s.passes = 0;
        s.has_stats.clear();
        Ok(true)
    }

    /// [`QueryRing::collect_into`] a new [`FrameTimings`].
    pub fn collect(&mut self, ctx: &Context, slot: usize) -> Result<Option<FrameTimings>, VkError> {
        let mut out = FrameTimings {
            frame: 0,
            passes: Vec::new(),
        };
        Ok(self.collect_into(ctx, slot, &mut out)?.then_some(out))
    }

    fn slot_mut(&mut self, slot: usize) -> Result<&mut Slot, VkError> {
        let n = self.slots.len();
        self.slots.get_mut(slot).ok_or_else(|| VkError::Invalid {
            what: "query ring".into(),
            reason: format!("slot {slot} out of {n}"),
        })
    }

    /// Destroys the pools; the caller guarantees the GPU is done with them.
    pub fn destroy(&mut self, ctx: &Context) {
        for s in self.slots.drain(..) {
            // SAFETY: no GPU work references the pools any more (caller's guarantee).
            unsafe {
                ctx.device.destroy_query_pool(s.timestamps, None);
                if s.stats != vk::QueryPool::null() {
                    ctx.device.destroy_query_pool(s.stats, None);
                }
            }
        }
    }
}

/// Per-pass history over the last [`TimingHistory::WINDOW`] frames, for medians. Its memory
/// is bounded (a game runs for hours) and taken once per pass name: recording a frame
/// allocates nothing once its passes are known.
#[derive(Debug, Default, Clone)]
pub struct TimingHistory {
    by_pass: BTreeMap<String, PassSamples>,
    order: Vec<String>,
    frames: u64,
}

/// One pass's newest samples, a ring.
#[derive(Debug, Default, Clone)]
struct PassSamples {
    samples: Vec<f64>,
    /// Where the next sample goes once the ring is full.
    next: usize,
}

/// Median GPU time of one pass over the recorded frames.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PassMedian {
    pub name: String,
    pub median_gpu_ms: f64,
    /// 95th percentile (nearest rank) of the same samples.
    pub p95_gpu_ms: f64,
    pub samples: usize,
}

impl TimingHistory {
    /// Samples kept per pass.
    pub const WINDOW: usize = 2048;

    /// A ring for each of `names` (a plan's passes) not yet seen.
    pub fn reserve<'a>(&mut self, names: impl Iterator<Item = &'a str>) {
        for name in names {
            if !self.by_pass.contains_key(name) {
                self.order.push(name.to_string());
                self.by_pass.insert(
                    name.to_string(),
                    PassSamples {
                        samples: Vec::with_capacity(Self::WINDOW),
                        next: 0,
                    },
                );
            }
        }
    }

    pub fn record(&mut self, frame: &FrameTimings) {
        self.frames += 1;
        for p in &frame.passes {
            let ring = match self.by_pass.get_mut(&p.name) {
                Some(ring) => ring,
                None => {
                    self.order.push(p.name.clone());
                    self.by_pass.entry(p.name.clone()).or_insert(PassSamples {
                        samples: Vec::with_capacity(Self::WINDOW),
                        next: 0,
                    })
                }
            };
            if ring.samples.len() < Self::WINDOW {
                ring.samples.push(p.gpu_ms);
            } else {
                ring.samples[ring.next] = p.gpu_ms;
                ring.next = (ring.next + 1) % Self::WINDOW;
            }
        }
    }

    pub fn frames(&self) -> u64 {
        self.frames
    }

    /// Median per pass, in first-seen order.
    pub fn medians(&self) -> Vec<PassMedian> {
        self.order
            .iter()
            .filter_map(|name| {
                let v = &self.by_pass.get(name)?.samples;
                Some(PassMedian {
                    name: name.clone(),
                    median_gpu_ms: median(v)?,
                    p95_gpu_ms: percentile(v, 95.0)?,
                    samples: v.len(),
                })
            })
            .collect()
    }
}

/// The `p`th percentile (0-100) of a sample by nearest rank; `None` when empty (NaNs ignored).
pub fn percentile(values: &[f64], p: f64) -> Option<f64> {
    let mut v: Vec<f64> = values.iter().copied().filter(|x| !x.is_nan()).collect();
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let rank = ((p.clamp(0.0, 100.0) / 100.0) * v.len() as f64).ceil() as usize;
    v.get(rank.clamp(1, v.len()) - 1).copied()
}

/// Median of a sample (mean of the middle two for even sizes); `None` when empty.
pub fn median(values: &[f64]) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    let mut v: Vec<f64> = values.iter().copied().filter(|x| !x.is_nan()).collect();
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let m = v.len() / 2;
    Some(if v.len() % 2 == 1 {
        v[m]
    } else {
        (v[m - 1] + v[m]) / 2.0
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentile_by_nearest_rank() {
        let v: Vec<f64> = (1..=20).map(f64::from).collect();
        assert_eq!(percentile(&v, 95.0), Some(19.0));
        assert_eq!(percentile(&v, 100.0), Some(20.0));
        assert_eq!(percentile(&v, 0.0), Some(1.0));
        assert_eq!(percentile(&[3.0], 95.0), Some(3.0));
        assert_eq!(percentile(&[], 95.0), None);
    }

    #[test]
    fn median_of_odd_even_and_empty() {
        assert_eq!(median(&[]), None);
        assert_eq!(median(&[3.0, 1.0, 2.0]), Some(2.0));
        assert_eq!(median(&[4.0, 1.0, 3.0, 2.0]), Some(2.5));
        assert_eq!(median(&[f64::NAN, 1.0]), Some(1.0));
    }

    #[test]
    fn history_keeps_first_seen_order() {
        let mut h = TimingHistory::default();
        let t = |n: &str, ms| PassTiming {
            name: n.into(),
            begin_ticks: 0,
            end_ticks: 1,
            gpu_ms: ms,
            vertex_invocations: None,
            fragment_invocations: None,
        };
        h.record(&FrameTimings {
            frame: 0,
            passes: vec![t("b", 1.0), t("a", 5.0)],
        });
        h.record(&FrameTimings {
            frame: 1,
            passes: vec![t("b", 3.0), t("a", 7.0)],
        });
        let m = h.medians();
        assert_eq!(
            m.iter().map(|p| p.name.as_str()).collect::<Vec<_>>(),
            ["b", "a"]
        );
        assert_eq!(m[0].median_gpu_ms, 2.0);
        assert_eq!(h.frames(), 2);
    }
}
