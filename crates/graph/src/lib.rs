//! tilegraph-graph: declare a frame's resources and passes, compile it to a [`Plan`] that a
//! tile-based GPU is happy with, and measure it. Pure Rust: no Vulkan, no `unsafe`.
//!
//! ```text
//! GraphBuilder<P> --compile(&Profile)--> CompiledGraph<P> { plan: Plan, payloads }
//! ```
//!
//! The [`Plan`] is plain data: passes in execution order, pruned passes with reasons, the
//! resource table (usage, lifetime, memory slot), the [`Step`]s the executor records (barrier
//! batches, render passes with subpasses, compute and transfer passes, flushes), the alias
//! assignment and the traffic estimate. It prints as a table (`Display`) and as Graphviz DOT
//! ([`Plan::to_dot`]). Payloads (the backend's recording callbacks) stay outside the plan and are
//! fetched by [`PassId`] from the [`CompiledGraph`].
//!
//! `docs/ARCHITECTURE.md` walks through compile phase by phase.

#![forbid(unsafe_code)]

mod cache;
mod compile;
mod declare;
mod display;
mod dot;
mod error;
mod explain;
mod plan;
#[cfg(test)]
mod testing;
mod types;

pub use cache::{CachedFrame, PlanCache};
pub use compile::{assign_aliases, estimated_requirements, CompiledGraph};
pub use declare::{
    BufferDesc, BufferId, ComputePassBuilder, Coverage, GraphBuilder, ImageDesc, ImageId, Import,
    InitialContent, Origin, PassId, PassKind, PassUse, RasterPassBuilder, ResourceDesc, ResourceId,
    ResourceState, Retention, TransferPassBuilder, UseKind,
};
pub use error::GraphError;
pub use explain::{Reason, Topic};
pub use plan::{
    AliasAssignment, AliasHandoff, AliasLifetime, Attachment, AttachmentIndex, AttachmentRef,
    BarrierBatch, BlockIndex, BufferBarrier, FlushReason, Hazard, ImageBarrier, InlineVec,
    MemoryBlock, MemoryClass, MemoryNeed, MemoryRequirements, MemorySlot, MergeNote, MergeReason,
    Plan, PlanResource, PlannedPass, PruneReason, PrunedPass, Queue, QueueTransfer, QueueWait,
    RenderPass, Residency, Step, StepIndex, StepRange, Submission, SubmissionIndex, Subpass,
    SubpassDependency, SubpassIndex, TrafficBreakdown, TrafficEstimate, TrafficModel, Usage,
    WaitReason, ESTIMATED_ALIGNMENT_BYTES,
};
pub use tilegraph_profile::PassClass;
pub use types::{
    AccessFlags, BufferUsage, ClearColor, ClearDepthStencil, ClearValue, DependencyFlags, Extent2d,
    Format, ImageUsage, Layout, LoadOp, PipelineStages, SampleCount, StoreOp,
};
