//! Vendor profiles for tilegraph.
//!
//! A [`Profile`] is data (`config/profiles/*.toml`, embedded at compile time) that says how a GPU
//! family wants to be driven: tiler or immediate, whether a depth pre-pass pays, how passes are
//! ordered, where occlusion queries go, which pipeline states break its hidden-surface removal,
//! and which memory type each use of memory gets. It is chosen from a [`DeviceIdentity`] when the
//! Vulkan device is created ([`ProfileSet::select`]), or forced by name
//! (`TILEGRAPH_PROFILE=adreno-7xx`) so that every profile can run on lavapipe.
//!
//! This crate never touches Vulkan; `tilegraph-vk` builds the [`DeviceIdentity`].
//! Every rule in the TOML files cites its source in `docs/PROFILES.md`.

pub mod accepted;
mod error;
mod identity;
pub mod knobs;
pub mod lint;
mod memory;
mod select;

use serde::{Deserialize, Serialize};

pub use error::ProfileError;
pub use identity::{driver, vendor, DeviceIdentity, DeviceType};
pub use memory::{
    select_memory_type, MemoryChoice, MemoryFlag, MemoryFlags, MemoryHeap, MemoryPolicy,
    MemoryRule, MemoryType, MemoryUse,
};
pub use select::{
    glob_match, MatchRule, MatchedBy, ProfileSet, Selection, PROFILE_DIR_ENV, PROFILE_ENV,
};

/// A vendor profile. Field documentation says what each decides; `docs/PROFILES.md` says why
/// each vendor's value is what it is.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Profile {
    /// Unique name, e.g. `adreno-7xx`; what `TILEGRAPH_PROFILE` names.
    pub name: String,
    pub description: String,
    /// Which devices this profile is for.
    #[serde(rename = "match")]
    pub matching: MatchRule,
    pub gpu: GpuModel,
    pub passes: PassPolicy,
    pub render_pass: RenderPassPolicy,
    pub memory: MemoryPolicy,
    /// Pipeline states that defeat the GPU's hidden-surface removal (LRZ, FPK, HSR, early-Z).
    #[serde(default)]
    pub state_rules: Vec<StateRule>,
    /// What this family ships with for the choices that trade speed for accuracy or memory
    /// ([`knobs::KNOBS`]); a knob not set here takes its built-in default.
    #[serde(default)]
    pub knobs: knobs::KnobSettings,
    /// How material textures are bound; built-in defaults where the profile says nothing.
    #[serde(default)]
    pub textures: TexturePolicy,
    /// Whether compute passes that may run beside the raster work go to an async compute
    /// queue; off where the profile says nothing.
    #[serde(default)]
    pub queues: QueuePolicy,
}

/// How the frame uses the device's queues.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct QueuePolicy {
    /// Compute passes declared async-capable run on a second queue (one of a compute-only
    /// family where the device has one), synchronized with the graphics queue by semaphores.
    /// `tilegraph_vk::Context` turns it off on a device without such a queue.
    #[serde(default)]
    pub async_compute: bool,
    /// How resources used on both queues are shared.
    #[serde(default)]
    pub sharing: QueueSharing,
}

/// How a resource used by both queues is shared between their families.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum QueueSharing {
    /// `VK_SHARING_MODE_EXCLUSIVE` images: the content moves with an ownership transfer (a
    /// release barrier on the queue that had it, an acquire on the queue that takes it) wherever
    /// the families differ. Buffers are concurrent in both modes (nothing to compress).
    #[default]
    Exclusive,
    /// `VK_SHARING_MODE_CONCURRENT`: no transfers; reads on both queues need no wait at all.
    /// Some drivers compress less in this mode.
    Concurrent,
}

/// How the scene's material textures are bound to the shading passes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TexturePolicy {
    pub binding: TextureBinding,
    /// The most textures bound as an array of descriptors (also capped by the device's
    /// per-stage sampler limits); a scene with more falls back to [`TextureBinding::Layers`].
    pub max_indexed: u32,
}

impl Default for TexturePolicy {
    fn default() -> Self {
        TexturePolicy {
            binding: TextureBinding::Indexed,
            max_indexed: 256,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TextureBinding {
    /// One descriptor per texture, indexed by the material's texture id (per draw in the
    /// forward passes, per pixel in the visibility-buffer resolve): needs the device's sampled
    /// image array indexing features, else falls back to `layers`.
    Indexed,
    /// Every texture resampled to one size as a layer of one array image: one descriptor,
    /// works on every device, costs the resampling (and memory where sizes differ).
    Layers,
}

impl TextureBinding {
    pub const fn name(self) -> &'static str {
        match self {
            TextureBinding::Indexed => "indexed",
            TextureBinding::Layers => "layers",
        }
    }
}

impl Profile {
    pub fn is_tiler(&self) -> bool {
        self.gpu.architecture == Architecture::Tiler
    }
}

/// How the GPU turns triangles into pixels, as far as the graph compiler cares.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GpuModel {
    pub architecture: Architecture,
    pub hidden_surface_removal: HiddenSurfaceRemoval,
    /// Tile (bin) size used by the traffic model; for immediate GPUs, the cache-line footprint
    /// granularity (informational).
    pub tile_width_px: u32,
    pub tile_height_px: u32,
    /// On-chip memory per tile in bytes (Adreno GMEM, Mali tile buffer): bounds how many bytes per
    /// pixel a render pass may keep on chip before the driver shrinks tiles.
    pub tile_memory_bytes: u64,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Architecture {
    /// Tile-based (TBR/TBDR): attachments live in on-chip tile memory during a render pass;
    /// loads and stores to system memory are the cost to minimise.
    Tiler,
    /// Immediate-mode: every attachment access goes through caches to memory.
    Immediate,
}

/// The hardware mechanism that removes hidden fragments before shading.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum HiddenSurfaceRemoval {
    /// Per-fragment early depth test only; draw order matters.
    EarlyZ,
    /// Adreno Low Resolution Z, built during the binning pass.
    Lrz,
    /// Arm Mali Forward Pixel Kill (and Fragment Prepass on newer parts).
    Fpk,
    /// PowerVR / Apple deferred hidden-surface removal: opaque fragments are shaded once per pixel
    /// whatever the draw order.
    Hsr,
}

/// Which passes a frame should have and in what order.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PassPolicy {
    pub depth_prepass: DepthPrepass,
    /// Alpha-tested geometry gets its own depth pre-pass subpass with discard, so the costly
    /// discard runs once and the colour pass can test EQUAL (seed 001, seed 003).
    pub alpha_tested_prepass: bool,
    pub opaque_sort: SortOrder,
    /// Ordering among passes that do not depend on each other, by class: a pass of a class that
    /// comes later in this list is not scheduled while a pass of an earlier class can still run.
    pub order: Vec<PassClass>,
    pub occlusion_queries: OcclusionQueryPolicy,
    /// How GPU culling's indirect draws are counted.
    #[serde(default)]
    pub indirect_count: IndirectCount,
    /// HiZ pyramid levels one reduction dispatch writes through shared memory (1-4): fewer
    /// dispatches and barriers where shared memory is fast, 1 where it is not.
    #[serde(default = "four_levels")]
    pub hiz_levels_per_dispatch: u32,
    /// Whether `culling = auto` starts from software occlusion on the CPU (`prefer`: the
    /// family builds depth pyramids slowly or reads culling buffers badly) or only tries it
    /// beside the GPU techniques (`allow`, the default).
    #[serde(default)]
    pub cpu_occlusion: CpuOcclusion,
    /// Whether `culling = auto` may pick a precomputed visible set when one baked for the scene
    /// is given (`allow`), though it is exact only at its baked viewpoints; `never` (the
    /// default, and every shipped profile's) keeps `auto` to conservative cullings.
    #[serde(default)]
    pub auto_pvs: AutoPvs,
}

/// Whether `culling = auto` may pick a precomputed visible set.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AutoPvs {
    /// Only conservative cullings: a PVS can miss between its baked viewpoints.
    #[default]
    Never,
    /// A given set is timed beside the other candidates: the game accepts its misses (measured
    /// by `cull-check --culling pvs` on paths it was not baked on).
    Allow,
}

/// What `culling = auto` makes of software occlusion on a family.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CpuOcclusion {
    /// Timed beside the GPU techniques like any candidate.
    #[default]
    Allow,
    /// The first pick: the family's GPU culling is known to be slow.
    Prefer,
}

fn four_levels() -> u32 {
    4
}

/// How GPU culling's compacted indirect draws are counted.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum IndirectCount {
    /// `vkCmdDrawIndexedIndirectCount` where the device has `drawIndirectCount`: the GPU writes
    /// how many commands survive, and the command processor walks only those.
    #[default]
    WhenSupported,
    /// A fixed command count (one per draw group), culled groups as zero-instance commands:
    /// for drivers without `drawIndirectCount`, or where it is slow.
    Fixed,
}

impl PassPolicy {
    /// Rank of a class in the ordering policy; classes not listed sort after every listed one,
    /// in declaration order.
    pub fn class_rank(&self, class: PassClass) -> usize {
        self.order
            .iter()
            .position(|c| *c == class)
            .unwrap_or(self.order.len())
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DepthPrepass {
    /// A depth pre-pass pays on this hardware when fragments are costly (early-Z, LRZ, FPK).
    Recommended,
    /// The hardware already shades each opaque pixel once (HSR): a pre-pass only adds vertex and
    /// binning work. The frame setup leaves it out unless forced.
    NotNeeded,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SortOrder {
    FrontToBack,
    /// Farthest first: no profile asks for it; measurements use it as the worst case for
    /// early depth rejection (what a pre-pass must make irrelevant).
    BackToFront,
    /// Minimise state changes; depth order does not matter to the hardware.
    ByState,
    None,
}

/// What a pass is for, as far as ordering policy is concerned.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PassClass {
    /// Culling, pyramid builds and other compute that feeds drawing.
    Compute,
    /// Shadow maps: depth from a light, sampled by the colour passes after it.
    Shadow,
    DepthPrepass,
    Opaque,
    AlphaTested,
    Transparent,
    OcclusionQuery,
    Post,
    Transfer,
    Other,
}

impl PassClass {
    pub const fn name(self) -> &'static str {
        match self {
            PassClass::Compute => "compute",
            PassClass::Shadow => "shadow",
            PassClass::DepthPrepass => "depth_prepass",
            PassClass::Opaque => "opaque",
            PassClass::AlphaTested => "alpha_tested",
            PassClass::Transparent => "transparent",
            PassClass::OcclusionQuery => "occlusion_query",
            PassClass::Post => "post",
            PassClass::Transfer => "transfer",
            PassClass::Other => "other",
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OcclusionQueryPolicy {
    /// Occlusion-query passes form a render pass of their own (never merged with drawing), so
    /// the driver can run it in direct mode (seed 001).
    pub own_render_pass: bool,
    /// Submit (flush) the work before the query render pass (seed 001: "遮挡查询, 前面加一个flush").
    pub flush_before: bool,
}

/// Render-pass shaping rules for the compiler.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RenderPassPolicy {
    pub merge_subpasses: MergePolicy,
    /// Attachments whose whole life is one render pass get TRANSIENT usage and lazily allocated
    /// memory (when the device has such a type).
    pub transient_attachments: bool,
    /// Depth and stencil of a combined format are invalidated together or not at all (seed 001:
    /// invalidating only one of D24S8 has no effect).
    pub invalidate_depth_stencil_together: bool,
    /// Most colour attachments a raster pass may declare on this family.
    pub max_color_attachments: u32,
    /// The family's drivers take `VK_ATTACHMENT_STORE_OP_NONE` (Vulkan 1.3, or
    /// VK_KHR/EXT_load_store_op_none, VK_QCOM_render_pass_store_ops): an attachment a render pass
    /// only reads keeps its content without being written back. Off when absent from the file;
    /// `tilegraph_vk::Context::new` turns it off on devices older than Vulkan 1.3.
    #[serde(default)]
    pub store_op_none: bool,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MergePolicy {
    /// Merge every compatible run of raster passes into subpasses (tilers: keeps data on chip).
    Always,
    /// Merging is allowed but gains little (immediate-mode GPUs); the compiler still merges where
    /// it is free, so plans look alike across profiles.
    Allowed,
    /// Never merge (debugging aid, and drivers known to mishandle subpasses).
    Never,
}

/// One pipeline state that defeats hidden-surface removal on this family.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StateRule {
    pub state: PipelineState,
    pub effect: StateEffect,
    /// How far the damage reaches.
    pub scope: StateScope,
    /// Short explanation shown by the lint.
    pub note: String,
    /// Where the rule comes from: a key of docs/PROFILES.md's sources with the section
    /// (`S001 1.1.4`), or `unsourced`. Printed with every finding; loading rejects a rule
    /// without one.
    #[serde(default)]
    pub source: String,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PipelineState {
    /// The fragment shader may `discard` (alpha test) while depth writes are on.
    DiscardWithDepthWrite,
    /// The fragment shader writes `gl_FragDepth`.
    ShaderDepthWrite,
    /// Blending enabled while depth writes are on.
    BlendWithDepthWrite,
    /// A colour write mask that is neither all nor nothing, while depth writes are on.
    PartialColorMask,
    /// A depth-writing draw whose compare direction differs from earlier draws of the same
    /// render pass (e.g. GREATER then LESS).
    DepthCompareDirectionChange,
    /// Stencil test whose outcome depends on the depth test (depth-fail ops).
    StencilDependsOnDepth,
    /// The fragment shader writes storage buffers or images (side effects forbid early kill
    /// unless early_fragment_tests is declared).
    FragmentSideEffects,
    /// Colour attachments of one pass with differing write or blend state, while depth writes
    /// are on.
    MrtStateMismatch,
    /// An occluding draw (depth written, no blend, no discard) after a blended draw in the
    /// same render pass: opaque work should come first.
    OccluderAfterBlend,
    /// An occluding draw after a draw that may discard (alpha test) in the same render pass.
    OccluderAfterDiscard,
    /// Alpha-to-coverage: coverage decided by the shader, like a discard.
    AlphaToCoverage,
    /// The draw is recorded in a secondary command buffer.
    SecondaryCommandBuffer,
}

impl PipelineState {
    pub const fn name(self) -> &'static str {
        match self {
            PipelineState::DiscardWithDepthWrite => "discard_with_depth_write",
            PipelineState::ShaderDepthWrite => "shader_depth_write",
            PipelineState::BlendWithDepthWrite => "blend_with_depth_write",
            PipelineState::PartialColorMask => "partial_color_mask",
            PipelineState::DepthCompareDirectionChange => "depth_compare_direction_change",
            PipelineState::StencilDependsOnDepth => "stencil_depends_on_depth",
            PipelineState::FragmentSideEffects => "fragment_side_effects",
            PipelineState::MrtStateMismatch => "mrt_state_mismatch",
            PipelineState::OccluderAfterBlend => "occluder_after_blend",
            PipelineState::OccluderAfterDiscard => "occluder_after_discard",
            PipelineState::AlphaToCoverage => "alpha_to_coverage",
            PipelineState::SecondaryCommandBuffer => "secondary_command_buffer",
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StateEffect {
    DisablesLrz,
    DisablesFpk,
    DisablesHsr,
    DisablesEarlyZ,
    /// The draw does not update the low-resolution / hidden-surface structure (later draws are
    /// culled less), though it is itself still tested.
    SkipsHsrUpdate,
    /// An occluder drawn after what it hides: the hidden fragments were already shaded.
    LateOccluder,
}

impl StateEffect {
    pub const fn name(self) -> &'static str {
        match self {
            StateEffect::DisablesLrz => "disables_lrz",
            StateEffect::DisablesFpk => "disables_fpk",
            StateEffect::DisablesHsr => "disables_hsr",
            StateEffect::DisablesEarlyZ => "disables_early_z",
            StateEffect::SkipsHsrUpdate => "skips_hsr_update",
            StateEffect::LateOccluder => "late_occluder",
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StateScope {
    /// Only the offending draw loses the optimisation.
    Draw,
    /// Every later draw of the render pass loses it too (Adreno LRZ stays off until the pass ends).
    RestOfRenderPass,
}
