//! The packed pyramid's layout and the build's dispatches, as plain data (no Vulkan handles).

use bytemuck::{Pod, Zeroable};
use tilegraph_cull::{level_extents, Extent2d, ExtentExt};
use tilegraph_vk::VkError;

use super::{AxisScale, DepthConvention, DepthFormat, NpotMode};

/// Levels one `hiz_reduce_levels.comp` dispatch writes at most.
pub const FUSED_LEVELS: usize = 4;
/// Texels of a fused dispatch's coarsest level per workgroup and axis (`B` in the shader).
pub const LEVELS_COARSE_TILE: u32 = 2;

/// Largest pyramid accepted, in bytes: the minimum `maxStorageBufferRange` every Vulkan device
/// guarantees (2^27). The whole pyramid is one storage-buffer descriptor, so a larger one could
/// exceed the device's limit (tilegraph-vk does not report the real limit yet). 4096x4096
/// (89 MB) fits; 8192x8192 does not.
pub const MAX_PYRAMID_BYTES: u64 = 1 << 27;
/// How a level's texel picks its source range, per axis (`shaders/common/hiz.glsl`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ReduceRule {
    /// The base level, from the depth image: at level 0 a copy (D16: snapped to the exact
    /// `k / 65535`); at level `b > 0` each texel is the farthest of its level-0 footprint
    /// ([`HizLayout::with_base_level`]), the value the chain of reductions would give.
    FromDepth,
    /// `2t ..= (t == dst - 1 ? src - 1 : 2t + 1)`: EdgeAware, every level >= 1.
    EdgeAware,
    /// `2t ..= min(2t + 1, src - 1)`: PadToPow2, levels >= 2.
    Halve,
    /// `(t * src) / dst ..= ((t + 1) * src + dst - 1) / dst - 1`: PadToPow2, level 1.
    PadFirst,
}

impl ReduceRule {
    /// The value of `HizPush::rule`: `HIZ_RULE_*` in GLSL, or `HIZ_COPY_*` (the depth format)
    /// for the copy.
    fn gpu_code(self, format: DepthFormat) -> u32 {
        match self {
            ReduceRule::FromDepth => match format {
                DepthFormat::D32Float => 0,
                DepthFormat::D16Unorm => 1,
            },
            ReduceRule::EdgeAware => 0,
            ReduceRule::Halve => 1,
            ReduceRule::PadFirst => 2,
        }
    }
}

/// Push constants of both shaders; mirrors `HizPush` in `shaders/common/hiz.glsl` (48 bytes;
/// tests/e2e/hiz.rs checks the offsets against the SPIR-V).
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct HizPush {
    /// First texel of the source level in the pyramid buffer (reduction only).
    pub src_offset: u32,
    /// First texel of the level this dispatch writes.
    pub dst_offset: u32,
    /// Source level (reduction) or depth image (copy) size.
    pub src_extent: [u32; 2],
    /// Size of the level this dispatch writes.
    pub dst_extent: [u32; 2],
    /// `HIZ_RULE_*` (reduction) or `HIZ_COPY_*` (copy: 0 D32, 1 D16).
    pub rule: u32,
    /// 0: Standard (max), 1: Reverse (min).
    pub convention: u32,
    /// The base level's index in the whole chain (copy only): 0 copies, `b` reduces each
    /// texel's level-0 footprint.
    pub base_level: u32,
    /// The footprint rule (copy only): 0 EdgeAware, 1 PadToPow2.
    pub npot: u32,
    /// PadToPow2's level-1 extent `P` per axis (copy only, base level >= 1).
    pub pow2_extent: [u32; 2],
}

/// Push constants of `hiz_reduce_levels.comp` (80 bytes; tests/e2e/hiz.rs checks the offsets
/// against the SPIR-V).
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct HizLevelsPush {
    /// First texel of the source level k.
    pub src_offset: u32,
    /// Levels written, k+1 ..= k+levels (1..=4).
    pub levels: u32,
    pub src_extent: [u32; 2],
    /// `HIZ_RULE_EDGE_AWARE` or `HIZ_RULE_HALVE`.
    pub rule: u32,
    /// 0: Standard (max), 1: Reverse (min).
    pub convention: u32,
    /// Workgroups per axis.
    pub groups: [u32; 2],
    /// First texel of each level written.
    pub dst_offset: [u32; 4],
    /// Size of each level written.
    pub dst_extent: [[u32; 2]; 4],
}

/// One dispatch of the build.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HizStep {
    /// `hiz_copy.comp` (level 0) or `hiz_reduce.comp` (one level).
    Single { level: usize, push: HizPush },
    /// `hiz_reduce_levels.comp`: `push.levels` levels from `first`.
    Fused { first: usize, push: HizLevelsPush },
}

/// Where one level lives in the pyramid buffer, and how level-0 pixels map to its texels.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct HizLevelInfo {
    /// The level's index in the whole chain (level 0 = the depth buffer's extent), which the
    /// CPU reference's `HizPyramid::level` takes; it differs from its index in
    /// [`HizLayout::levels`] when the layout starts at a base level.
    pub level: u32,
    /// First texel (f32 element) of the level in the buffer.
    pub offset_texels: u64,
    pub width: u32,
    pub height: u32,
    /// Level-0 pixel `p` maps to texel `min(p * texels / pixels, extent - 1)` per axis, as
    /// `tilegraph_cull::HizLevel::scale` (integer arithmetic; fits `uint` for any accepted extent).
    pub scale_x: AxisScale,
    pub scale_y: AxisScale,
    /// Which source texels each texel of this level reads.
    pub rule: ReduceRule,
}

impl HizLevelInfo {
    pub fn texel_count(&self) -> u64 {
        u64::from(self.width) * u64::from(self.height)
    }
}

/// The packed layout of a pyramid for one depth extent, mode, convention and depth format: plain
/// data, no Vulkan handles. Computed from `tilegraph_cull::level_extents`, so it always has the
/// CPU reference's levels (from its base level on).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct HizLayout {
    pub mode: NpotMode,
    pub convention: DepthConvention,
    /// The format of the depth image the base level is read from. It must be right: a D32 depth
    /// read as D16 would be snapped to the nearest code, which is not conservative.
    pub format: DepthFormat,
    /// The depth buffer's extent (level 0's, stored or not).
    pub depth_extent: (u32, u32),
    /// The first level stored ([`HizLayout::with_base_level`]; 0 unless it says otherwise).
    pub base_level: u32,
    /// Level 1's extent in the whole chain (PadToPow2's `P`), which a base level >= 1 needs to
    /// find its footprints.
    pub pad_extent: [u32; 2],
    /// The stored levels, the base level first; the last level is 1x1.
    pub levels: Vec<HizLevelInfo>,
    pub total_texels: u64,
    /// Levels one reduction dispatch writes (1..=[`FUSED_LEVELS`]; [`FUSED_LEVELS`] unless
    /// [`HizLayout::with_levels_per_dispatch`] says otherwise).
    pub levels_per_dispatch: usize,
}

impl HizLayout {
    /// The layout for a depth buffer of `extent_px` (width, height) in `format`. Rejects a zero or
    /// oversized extent (`tilegraph_cull::MAX_EXTENT_PX`), `NpotMode::NaiveBuggy` (a reference
    /// for the bug only: the GPU never builds it), and pyramids above [`MAX_PYRAMID_BYTES`].
    pub fn new(
        extent_px: (u32, u32),
        mode: NpotMode,
        convention: DepthConvention,
        format: DepthFormat,
    ) -> Result<Self, VkError> {
        let invalid = |reason: String| VkError::Invalid {
            what: format!("hiz layout {}x{} {mode:?}", extent_px.0, extent_px.1),
            reason,
        };
        if mode == NpotMode::NaiveBuggy {
            return Err(invalid(
                "NaiveBuggy drops the last row/column at odd sizes; the GPU build implements \
                 EdgeAware and PadToPow2 only"
                    .into(),
            ));
        }
        let extent = Extent2d::named("depth extent", extent_px.0, extent_px.1)
            .map_err(|e| invalid(e.to_string()))?;
        let extents = level_extents(extent, mode);
        let (w, h) = (extent.width_px, extent.height_px);
        let (pw, ph) = extents.get(1).map_or((w, h), |e| (e.width_px, e.height_px));
        let mut levels = Vec::with_capacity(extents.len());
        let mut offset = 0u64;
        for (k, e) in extents.iter().enumerate() {
            let k = k as u32;
            let info = HizLevelInfo {
                level: k,
                offset_texels: offset,
                width: e.width_px,
                height: e.height_px,
                scale_x: axis_scale(mode, k, w, pw),
                scale_y: axis_scale(mode, k, h, ph),
                rule: rule_of(mode, k, 0),
            };
            offset += info.texel_count();
            levels.push(info);
        }
        let layout = HizLayout {
            mode,
            convention,
            format,
            depth_extent: extent_px,
            base_level: 0,
            pad_extent: [pw, ph],
            levels,
            total_texels: offset,
            levels_per_dispatch: FUSED_LEVELS,
        };
        if layout.size_bytes() > MAX_PYRAMID_BYTES {
            return Err(invalid(format!(
                "the pyramid needs {} bytes, more than the {MAX_PYRAMID_BYTES} bytes every \
                 device can bind as one storage buffer",
                layout.size_bytes()
            )));
        }
        Ok(layout)
    }

    /// The depth buffer's extent: the pixels the level table's scales map from.
    pub fn extent_px(&self) -> (u32, u32) {
        self.depth_extent
    }

    /// The same pyramid without the levels finer than `base` (clamped to the 1x1 level): the
    /// knob `hiz_resolution` (full 0, half 1, quarter 2). The base level is built straight from
    /// the depth image, each texel the farthest of its level-0 footprint, so every stored level
    /// keeps the CPU reference's values and the test stays conservative; a small object is then
    /// tested against coarser texels (more drawn), for 1/4 or 1/16 of level 0's memory and
    /// writes. Offsets are packed again from 0.
    pub fn with_base_level(mut self, base: u32) -> Self {
        let keep_from = (base as usize).min(self.levels.len().saturating_sub(1));
        let mut offset = 0u64;
        let levels: Vec<HizLevelInfo> = self.levels[keep_from..]
            .iter()
            .map(|l| {
                let info = HizLevelInfo {
                    offset_texels: offset,
                    rule: rule_of(self.mode, l.level, keep_from as u32),
                    ..*l
                };
                offset += info.texel_count();
                info
            })
            .collect();
        self.base_level = keep_from as u32;
        self.levels = levels;
        self.total_texels = offset;
        self
    }

    /// Bytes the pyramid buffer needs (at least).
    pub fn size_bytes(&self) -> u64 {
        self.total_texels * 4
    }

    /// The texels of `level` within a pyramid read back whole (`None` past the last level or
    /// when `pyramid` is too short).
    pub fn level_texels<'a>(&self, pyramid: &'a [f32], level: usize) -> Option<&'a [f32]> {
        let l = self.levels.get(level)?;
        let start = usize::try_from(l.offset_texels).ok()?;
        let len = usize::try_from(l.texel_count()).ok()?;
        pyramid.get(start..start.checked_add(len)?)
    }

    /// The push constants of every dispatch, level 0 (the copy) first.
    pub fn push_constants(&self) -> Result<Vec<HizPush>, VkError> {
        (0..self.levels.len())
            .map(|k| self.push_for_level(k))
            .collect()
    }

    /// The same layout built `n` levels per reduction dispatch (clamped to 1..=4): one where
    /// shared memory and barriers are slow (lavapipe: the profile's
    /// `hiz_levels_per_dispatch`, docs/PROFILES.md).
    pub fn with_levels_per_dispatch(mut self, n: usize) -> Self {
        self.levels_per_dispatch = n.clamp(1, FUSED_LEVELS);
        self
    }

    /// Bytes the build moves if each dispatch reads its source once and writes its levels once
    /// (the copy reads the depth image): the traffic a bandwidth-bound build costs.
    pub fn traffic_bytes(&self) -> u64 {
        (0..).map_while(|i| self.step_bytes(i)).sum()
    }

    /// Bytes dispatch `i` ([`HizLayout::step`]) reads and writes; `None` past the last.
    pub fn step_bytes(&self, i: usize) -> Option<u64> {
        let texels = |k: usize| self.levels.get(k).map_or(0, HizLevelInfo::texel_count);
        let depth_bytes = match self.format {
            DepthFormat::D16Unorm => 2,
            DepthFormat::D32Float => 4,
        };
        Some(match self.step(i)? {
            Ok(HizStep::Single { level: 0, .. }) => {
                let (w, h) = self.depth_extent;
                u64::from(w) * u64::from(h) * depth_bytes + 4 * texels(0)
            }
            Ok(HizStep::Single { level, .. }) => 4 * (texels(level - 1) + texels(level)),
            Ok(HizStep::Fused { first, push }) => {
                let written: u64 = (first..first + push.levels as usize).map(texels).sum();
                4 * (texels(first - 1) + written)
            }
            Err(_) => 0,
        })
    }

    /// The build's dispatches in order: the base level from the depth image, PadToPow2's level 1
    /// alone (when it is not the base), then the rest [`FUSED_LEVELS`] at a time. `i` past the last is `None` (no list is built: recording
    /// allocates nothing).
    pub fn step(&self, i: usize) -> Option<Result<HizStep, VkError>> {
        let single = |level: usize| {
            Some(
                self.push_for_level(level)
                    .map(|push| HizStep::Single { level, push }),
            )
        };
        if i == 0 {
            return single(0);
        }
        if self.levels_per_dispatch <= 1 {
            return (i < self.levels.len()).then(|| single(i)).flatten();
        }
        // PadToPow2's level 1 (a box rule of its own) is a single dispatch.
        let pad_first = self
            .levels
            .get(1)
            .is_some_and(|l| l.rule == ReduceRule::PadFirst);
        if pad_first && i == 1 {
            return single(1);
        }
        let singles = if pad_first { 2 } else { 1 };
        let per = self.levels_per_dispatch.min(FUSED_LEVELS);
        let first = singles + (i - singles) * per;
        if first >= self.levels.len() {
            return None;
        }
        let n = (self.levels.len() - first).min(per);
        Some(
            self.fused_push(first, n)
                .map(|push| HizStep::Fused { first, push }),
        )
    }

    /// The push constants of the fused dispatch writing levels `first .. first + n`.
    fn fused_push(&self, first: usize, n: usize) -> Result<HizLevelsPush, VkError> {
        let invalid = |reason: String| VkError::Invalid {
            what: "hiz layout".into(),
            reason,
        };
        let level = |k: usize| {
            self.levels
                .get(k)
                .ok_or_else(|| invalid(format!("no level {k}")))
        };
        let offset = |texels: u64| {
            u32::try_from(texels)
                .map_err(|_| invalid(format!("texel offset {texels} does not fit a shader uint")))
        };
        let src = level(
            first
                .checked_sub(1)
                .ok_or_else(|| invalid("the base level is read from the depth image".into()))?,
        )?;
        let rule = level(first)?.rule;
        if !(1..=FUSED_LEVELS).contains(&n)
            || !matches!(rule, ReduceRule::EdgeAware | ReduceRule::Halve)
        {
            return Err(invalid(format!(
                "levels {first}+{n} ({rule:?}) cannot be fused"
            )));
        }
        let coarse = level(first + n - 1)?;
        let mut push = HizLevelsPush {
            src_offset: offset(src.offset_texels)?,
            levels: n as u32,
            src_extent: [src.width, src.height],
            rule: rule.gpu_code(self.format),
            convention: match self.convention {
                DepthConvention::Standard => 0,
                DepthConvention::Reverse => 1,
            },
            groups: [
                (coarse.width / LEVELS_COARSE_TILE).max(1),
                (coarse.height / LEVELS_COARSE_TILE).max(1),
            ],
            ..HizLevelsPush::default()
        };
        for j in 0..n {
            let l = level(first + j)?;
            push.dst_offset[j] = offset(l.offset_texels)?;
            push.dst_extent[j] = [l.width, l.height];
        }
        Ok(push)
    }

    fn push_for_level(&self, k: usize) -> Result<HizPush, VkError> {
        let dst = self.levels.get(k).ok_or_else(|| VkError::Invalid {
            what: "hiz layout".into(),
            reason: format!("no level {k}"),
        })?;
        // The base level reads the depth image, which has its own extent.
        let (src_offset, src_extent) = match k.checked_sub(1).and_then(|s| self.levels.get(s)) {
            Some(src) => (src.offset_texels, [src.width, src.height]),
            None => (0, [self.depth_extent.0, self.depth_extent.1]),
        };
        let offset = |texels: u64| {
            u32::try_from(texels).map_err(|_| VkError::Invalid {
                what: "hiz layout".into(),
                reason: format!("texel offset {texels} does not fit a shader uint"),
            })
        };
        Ok(HizPush {
            src_offset: offset(src_offset)?,
            dst_offset: offset(dst.offset_texels)?,
            src_extent,
            dst_extent: [dst.width, dst.height],
            rule: dst.rule.gpu_code(self.format),
            convention: match self.convention {
                DepthConvention::Standard => 0,
                DepthConvention::Reverse => 1,
            },
            base_level: dst.level,
            npot: u32::from(self.mode == NpotMode::PadToPow2),
            pow2_extent: self.pad_extent,
        })
    }
}

/// How level `k` of the whole chain is built when the layout stores levels from `base` on.
fn rule_of(mode: NpotMode, k: u32, base: u32) -> ReduceRule {
    match (mode, k) {
        _ if k == base => ReduceRule::FromDepth,
        (NpotMode::PadToPow2, 1) => ReduceRule::PadFirst,
        (NpotMode::PadToPow2, _) => ReduceRule::Halve,
        _ => ReduceRule::EdgeAware,
    }
}

/// The per-axis pixel -> texel scale of level `k` (docs/CULLING.md, "Level-0 pixel -> texel
/// mapping"); `pow2_px` is level 1's size (PadToPow2's `P`). Checked against the CPU
/// reference's `HizLevel::scale` by tests/e2e/hiz.rs.
fn axis_scale(mode: NpotMode, k: u32, level0_px: u32, pow2_px: u32) -> AxisScale {
    match (mode, k) {
        (_, 0) => AxisScale {
            texels: 1,
            pixels: 1,
        },
        (NpotMode::PadToPow2, k) => AxisScale {
            texels: pow2_px,
            pixels: level0_px << (k - 1),
        },
        (NpotMode::EdgeAware | NpotMode::NaiveBuggy, k) => AxisScale {
            texels: 1,
            pixels: 1 << k,
        },
    }
}
