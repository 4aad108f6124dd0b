//! The compiled plan: plain data (indices, enums, names) that the Vulkan executor walks, that
//! `Display` prints as a table and [`Plan::to_dot`] draws.

mod memory;
mod queues;
mod traffic;

pub use memory::{
    AliasAssignment, AliasHandoff, AliasLifetime, BlockIndex, MemoryBlock, MemoryClass, MemoryNeed,
    MemoryRequirements, MemorySlot, ESTIMATED_ALIGNMENT_BYTES,
};
pub use queues::{Queue, QueueTransfer, QueueWait, Submission, SubmissionIndex, WaitReason};
pub use traffic::{TrafficBreakdown, TrafficEstimate, TrafficModel};

use tilegraph_profile::{PassClass, QueueSharing};

use smallvec::SmallVec;

use crate::declare::{
    Coverage, Origin, PassId, PassKind, PassUse, ResourceDesc, ResourceId, ResourceState, Retention,
};
use crate::types::{
    AccessFlags, BufferUsage, ClearValue, DependencyFlags, Extent2d, Format, ImageUsage, Layout,
    LoadOp, PipelineStages, SampleCount, StoreOp,
};

/// A short list stored inline up to `N` entries (a [`SmallVec`]: derefs to a slice, grows onto
/// the heap past `N`). A plan is rebuilt every frame, and its per-subpass and per-barrier-batch
/// lists hold one to three entries, so inline storage keeps compile from making a heap
/// allocation for each of them.
pub type InlineVec<T, const N: usize> = SmallVec<[T; N]>;

/// Index into [`Plan::steps`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct StepIndex(pub u32);

impl StepIndex {
    pub const fn index(self) -> usize {
        self.0 as usize
    }
}

/// Index into [`RenderPass::attachments`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct AttachmentIndex(pub u32);

/// Index into [`RenderPass::subpasses`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct SubpassIndex(pub u32);

/// First and last step (inclusive) that use a resource.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct StepRange {
    pub first: StepIndex,
    pub last: StepIndex,
}

impl StepRange {
    pub const fn overlaps(self, other: StepRange) -> bool {
        self.first.0 <= other.last.0 && other.first.0 <= self.last.0
    }
}

/// The compiled frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Plan {
    /// Name of the profile it was compiled for.
    pub profile: String,
    /// Tile memory per pixel on tilers (`tile_memory_bytes / (tile_width_px *
    /// tile_height_px)`): a render pass whose attachments need more makes the driver shrink
    /// its tiles. `None` on immediate-mode GPUs.
    pub tile_budget_bytes_per_px: Option<u32>,
    /// Surviving passes in execution order.
    pub passes: Vec<PlannedPass>,
    /// Pruned passes (nothing exported needs them) in declaration order, with the reason.
    pub pruned: Vec<PrunedPass>,
    /// Every declared resource, indexed by [`ResourceId`].
    pub resources: Vec<PlanResource>,
    /// What the executor records, in order.
    pub steps: Vec<Step>,
    pub aliasing: AliasAssignment,
    pub traffic: TrafficEstimate,
    /// Per raster pass after the first of a run: whether it joined the render pass before it,
    /// and why (or why not).
    pub merges: Vec<MergeNote>,
    /// The steps cut into submissions, each to one queue, in an order every wait respects: one
    /// graphics submission of every step unless some pass runs on the async compute queue.
    pub submissions: Vec<Submission>,
    /// How resources used on both queues are shared (the profile's `[queues] sharing`).
    pub queue_sharing: QueueSharing,
    /// Whether the profile asked for async compute (`[queues] async_compute`): async-capable
    /// passes then run on the async queue where raster work can run beside them.
    pub async_compute: bool,
}

/// Whether a raster pass joined the render pass of the raster pass before it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MergeNote {
    pub pass: PassId,
    /// The raster pass before it in execution order (its render pass is the candidate).
    pub after: PassId,
    pub joined: bool,
    pub reason: MergeReason,
}

/// Why a raster pass did or did not join the render pass before it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MergeReason {
    /// Joined: both use this resource as an attachment at the same pixel.
    SharesAttachment(ResourceId),
    /// A compute or transfer step lies between them.
    NotAdjacent,
    /// The profile's `merge_subpasses = "never"`.
    MergingOff,
    /// The render areas differ.
    RenderArea,
    /// The profile keeps occlusion-query passes in a render pass of their own.
    QueriesApart,
    /// It clears this resource, which the render pass already uses: a clear can only be a
    /// render pass's load op.
    Clears(ResourceId),
    /// One of them reads this resource through a descriptor while the other uses it as an
    /// attachment (or writes it): outside the attachment's subpass dependencies.
    DescriptorAccess(ResourceId),
    /// They share no attachment: merging would only grow the tile footprint.
    NothingShared,
}

/// A pass that survived pruning.
#[derive(Debug, Clone, PartialEq)]
pub struct PlannedPass {
    pub id: PassId,
    pub name: String,
    pub kind: PassKind,
    pub class: PassClass,
    pub coverage: Coverage,
    pub retention: Retention,
    pub uses: Vec<PassUse>,
    /// The step that records it (a render pass, compute or transfer step).
    pub step: StepIndex,
    /// Its subpass when `step` is a render pass.
    pub subpass: Option<SubpassIndex>,
    /// The queue that runs it.
    pub queue: Queue,
    /// Declared able to run on an async compute queue (whether or not it does).
    pub async_capable: bool,
}

/// A pass removed because nothing needed what it writes.
#[derive(Debug, Clone, PartialEq)]
pub struct PrunedPass {
    pub id: PassId,
    pub name: String,
    pub kind: PassKind,
    pub class: PassClass,
    pub coverage: Coverage,
    pub uses: Vec<PassUse>,
    pub reason: PruneReason,
}

#[derive(Debug, Clone, PartialEq, Eq)]
pub enum PruneReason {
    /// It writes no resource, so nothing can depend on it (and it is not `Retention::Always`).
    NoOutputs,
    /// Nothing reads what it writes before it is overwritten, and none of it is exported.
    OutputsUnused,
    /// Only passes that were themselves pruned read what it writes.
    ConsumersPruned { consumers: Vec<PassId> },
}

/// How a resource's memory is provided.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Residency {
    /// Owned by the caller.
    Imported,
    /// Created by the graph and exported (survives the frame): dedicated memory, never aliased.
    Exported,
    /// Created for this frame; may share memory with resources not alive at the same time.
    FrameLocal,
    /// Whole life inside one render pass, never loaded nor stored: TRANSIENT_ATTACHMENT usage
    /// and lazily allocated memory (profiles with `transient_attachments`).
    Transient,
    /// No surviving pass uses it: nothing to allocate.
    Unused,
}

impl Residency {
    pub const fn name(self) -> &'static str {
        match self {
            Residency::Imported => "imported",
            Residency::Exported => "exported",
            Residency::FrameLocal => "frame",
            Residency::Transient => "transient",
            Residency::Unused => "unused",
        }
    }
}

/// Usage flags inferred from the surviving passes' declared uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Usage {
    Image(ImageUsage),
    Buffer(BufferUsage),
}

#[derive(Debug, Clone, PartialEq)]
pub struct PlanResource {
    pub id: ResourceId,
    pub name: String,
    pub desc: ResourceDesc,
    pub origin: Origin,
    pub residency: Residency,
    pub usage: Usage,
    /// First and last step that use it; `None` when unused.
    pub lifetime: Option<StepRange>,
    /// Where it lives in [`AliasAssignment::blocks`]; `None` for imported and unused resources.
    pub memory: Option<MemorySlot>,
    /// The graph's size estimate (every mip and sample; a buffer's size).
    pub estimated_size_bytes: u64,
    /// The conservative alignment the estimate assumes ([`crate::ESTIMATED_ALIGNMENT_BYTES`]).
    pub estimated_alignment_bytes: u64,
    /// The state the frame leaves it in: the imported `final_state`, or for created resources
    /// the state after their last use (what next frame's import of a history image declares).
    pub final_state: ResourceState,
    /// A pass on the async compute queue uses it: it gets memory of its own (a hand-off of
    /// memory between queues would need a semaphore of its own) and, with concurrent sharing,
    /// is created shared by both queues' families.
    pub async_queue: bool,
}

impl PlanResource {
    pub fn is_image(&self) -> bool {
        matches!(self.desc, ResourceDesc::Image(_))
    }

    pub fn format(&self) -> Option<Format> {
        self.desc.image().map(|d| d.format)
    }

    /// What [`crate::assign_aliases`] needs about this resource.
    pub fn alias_lifetime(&self) -> AliasLifetime {
        let memory = match self.residency {
            Residency::Imported | Residency::Unused => MemoryNeed::External,
            Residency::Exported => MemoryNeed::Dedicated(MemoryClass::DeviceLocal),
            Residency::Transient => MemoryNeed::Dedicated(MemoryClass::LazilyAllocated),
            Residency::FrameLocal if self.async_queue => {
                MemoryNeed::Dedicated(MemoryClass::DeviceLocal)
            }
            Residency::FrameLocal => MemoryNeed::Shared(MemoryClass::DeviceLocal),
        };
        AliasLifetime {
            lifetime: self.lifetime,
            memory,
        }
    }
}

/// One thing the executor records, in order.
#[derive(Debug, Clone, PartialEq)]
pub enum Step {
    /// One `vkCmdPipelineBarrier2`.
    Barriers(BarrierBatch),
    RenderPass(RenderPass),
    /// Record the compute pass's payload.
    Compute {
        pass: PassId,
    },
    /// Record the transfer pass's payload.
    Transfer {
        pass: PassId,
    },
    /// Submit what was recorded so far before going on.
    Flush(FlushReason),
}

impl Step {
    pub const fn name(&self) -> &'static str {
        match self {
            Step::Barriers(_) => "barriers",
            Step::RenderPass(_) => "render pass",
            Step::Compute { .. } => "compute",
            Step::Transfer { .. } => "transfer",
            Step::Flush(_) => "flush",
        }
    }

    /// Steps that record passes (everything but barriers and flushes).
    pub const fn is_work(&self) -> bool {
        matches!(
            self,
            Step::RenderPass(_) | Step::Compute { .. } | Step::Transfer { .. }
        )
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum FlushReason {
    /// seed 001: on Adreno, occlusion queries go in a render pass of their own after a flush, so
    /// the driver can run that pass in direct mode.
    BeforeOcclusionQueries,
}

#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct BarrierBatch {
    pub images: InlineVec<ImageBarrier, 3>,
    pub buffers: InlineVec<BufferBarrier, 2>,
}

impl BarrierBatch {
    pub fn is_empty(&self) -> bool {
        self.images.is_empty() && self.buffers.is_empty()
    }

    pub fn len(&self) -> usize {
        self.images.len() + self.buffers.len()
    }
}

/// Why a barrier exists.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Hazard {
    ReadAfterWrite,
    WriteAfterRead,
    WriteAfterWrite,
    /// A layout change (which is a read and a write of the whole image).
    LayoutTransition,
    /// First use of memory that an earlier resource used.
    Aliasing,
    /// Leaving an imported resource in the state its import asks for.
    Release,
}

impl Hazard {
    pub const fn name(self) -> &'static str {
        match self {
            Hazard::ReadAfterWrite => "RAW",
            Hazard::WriteAfterRead => "WAR",
            Hazard::WriteAfterWrite => "WAW",
            Hazard::LayoutTransition => "layout",
            Hazard::Aliasing => "alias",
            Hazard::Release => "release",
        }
    }
}

/// A synchronization2 image barrier over the whole image (every mip, one layer, every aspect of
/// its format).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ImageBarrier {
    pub resource: ResourceId,
    pub src_stages: PipelineStages,
    pub src_access: AccessFlags,
    pub dst_stages: PipelineStages,
    pub dst_access: AccessFlags,
    pub old_layout: Layout,
    pub new_layout: Layout,
    pub hazard: Hazard,
    /// Half of a queue-family ownership transfer (`None`: a barrier of one queue).
    pub queue_transfer: Option<QueueTransfer>,
}

/// A synchronization2 buffer barrier over the whole buffer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BufferBarrier {
    pub resource: ResourceId,
    pub src_stages: PipelineStages,
    pub src_access: AccessFlags,
    pub dst_stages: PipelineStages,
    pub dst_access: AccessFlags,
    pub hazard: Hazard,
    /// Half of a queue-family ownership transfer (`None`: a barrier of one queue).
    pub queue_transfer: Option<QueueTransfer>,
}

/// One `VkRenderPass` (with its framebuffer), one subpass per merged raster pass.
#[derive(Debug, Clone, PartialEq)]
pub struct RenderPass {
    pub render_area_px: Extent2d,
    pub attachments: InlineVec<Attachment, 2>,
    pub subpasses: InlineVec<Subpass, 1>,
    pub dependencies: Vec<SubpassDependency>,
    /// Bytes per pixel the attachments occupy in tile memory (resolve targets excluded).
    pub on_chip_bytes_per_px: u32,
}

impl RenderPass {
    /// No attachments, no subpasses: filled in by compile.
    pub(crate) fn empty() -> Self {
        RenderPass {
            render_area_px: Extent2d::new(0, 0),
            attachments: InlineVec::new(),
            subpasses: InlineVec::new(),
            dependencies: Vec::new(),
            on_chip_bytes_per_px: 0,
        }
    }
}

#[derive(Debug, Clone, PartialEq)]
pub struct Attachment {
    pub resource: ResourceId,
    pub format: Format,
    pub samples: SampleCount,
    pub load_op: LoadOp,
    pub store_op: StoreOp,
    /// Equal to `load_op`/`store_op` for formats with stencil (seed 001: depth and stencil are
    /// invalidated together), `DontCare` otherwise.
    pub stencil_load_op: LoadOp,
    pub stencil_store_op: StoreOp,
    pub initial_layout: Layout,
    pub final_layout: Layout,
    /// Set when `load_op` is `Clear`.
    pub clear: Option<ClearValue>,
    /// `Transient` attachments are lazily allocated and carry TRANSIENT_ATTACHMENT usage.
    pub residency: Residency,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct AttachmentRef {
    pub attachment: AttachmentIndex,
    pub layout: Layout,
}

#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Subpass {
    /// The logical pass whose payload records this subpass.
    pub pass: PassId,
    pub colors: InlineVec<AttachmentRef, 4>,
    /// Empty, or one entry per colour attachment (`None` where that colour is not resolved).
    pub resolves: InlineVec<Option<AttachmentRef>, 2>,
    pub depth_stencil: Option<AttachmentRef>,
    pub inputs: InlineVec<AttachmentRef, 2>,
    /// Attachments used before and after this subpass but not by it, whose content must stay.
    pub preserve: InlineVec<AttachmentIndex, 4>,
}

/// A dependency between two subpasses of one render pass (always by region: merging requires
/// same-pixel access).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SubpassDependency {
    pub src_subpass: SubpassIndex,
    pub dst_subpass: SubpassIndex,
    pub src_stages: PipelineStages,
    pub src_access: AccessFlags,
    pub dst_stages: PipelineStages,
    pub dst_access: AccessFlags,
    pub flags: DependencyFlags,
}

impl Plan {
    /// The planned pass with this id (linear search; the executor walks `steps` instead).
    pub fn pass(&self, id: PassId) -> Option<&PlannedPass> {
        self.passes.iter().find(|p| p.id == id)
    }

    pub fn pass_by_name(&self, name: &str) -> Option<&PlannedPass> {
        self.passes.iter().find(|p| p.name == name)
    }

    pub fn resource(&self, id: ResourceId) -> Option<&PlanResource> {
        self.resources.get(id.index())
    }

    pub fn resource_by_name(&self, name: &str) -> Option<&PlanResource> {
        self.resources.iter().find(|r| r.name == name)
    }

    /// Render passes in execution order with their step index.
    pub fn render_passes(&self) -> impl Iterator<Item = (StepIndex, &RenderPass)> {
        self.steps.iter().enumerate().filter_map(|(i, s)| match s {
            Step::RenderPass(rp) => Some((StepIndex(i as u32), rp)),
            _ => None,
        })
    }

    /// Every barrier of the plan with the step it belongs to.
    pub fn barrier_count(&self) -> usize {
        self.steps
            .iter()
            .map(|s| match s {
                Step::Barriers(b) => b.len(),
                _ => 0,
            })
            .sum()
    }

    /// Per resource, what [`crate::assign_aliases`] needs (index = [`ResourceId`]).
    pub fn alias_lifetimes(&self) -> Vec<AliasLifetime> {
        self.resources
            .iter()
            .map(PlanResource::alias_lifetime)
            .collect()
    }

    /// The attachment's render pass's view of where a resource is bound, for display and tests.
    pub fn attachment_of(&self, step: StepIndex, resource: ResourceId) -> Option<&Attachment> {
        match self.steps.get(step.index()) {
            Some(Step::RenderPass(rp)) => rp.attachments.iter().find(|a| a.resource == resource),
            _ => None,
        }
    }
}
