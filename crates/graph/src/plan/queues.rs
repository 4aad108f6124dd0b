//! The plan's queues: which queue each step runs on, the submissions the steps are cut into, and
//! the semaphore waits and queue-family ownership transfers between them.

use crate::declare::ResourceId;
use crate::plan::{BarrierBatch, Hazard, StepIndex};
use crate::types::PipelineStages;

/// A queue of the frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Queue {
    /// The queue that draws: every raster and transfer pass, and every compute pass not
    /// declared async-capable (or all of them where the profile keeps async compute off).
    Graphics,
    /// A second queue, of a compute-only family where the device has one: compute passes
    /// declared async-capable run there, beside the raster work.
    AsyncCompute,
}

impl Queue {
    pub const fn name(self) -> &'static str {
        match self {
            Queue::Graphics => "graphics",
            Queue::AsyncCompute => "async-compute",
        }
    }

    /// Every pipeline stage work on this queue can run in: what a wait on it may name.
    pub const fn stages(self) -> PipelineStages {
        match self {
            Queue::Graphics => PipelineStages::EVERY_GRAPH_STAGE,
            Queue::AsyncCompute => PipelineStages::from_bits(
                PipelineStages::COMPUTE_SHADER.bits()
                    | PipelineStages::DRAW_INDIRECT.bits()
                    | PipelineStages::ALL_TRANSFER.bits(),
            ),
        }
    }
}

/// A queue-family ownership transfer a barrier takes part in (exclusive sharing): the release
/// half on the queue that had the resource, the acquire half on the queue that takes it, with
/// the same layouts. Where both queues are of one family there is nothing to transfer: the
/// executor drops the release and records the acquire as a plain barrier.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct QueueTransfer {
    pub from: Queue,
    pub to: Queue,
}

/// Index into [`crate::Plan::submissions`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct SubmissionIndex(pub u32);

impl SubmissionIndex {
    pub const fn index(self) -> usize {
        self.0 as usize
    }
}

/// Steps recorded into one command buffer and submitted to one queue, after the waits it
/// names; it signals its own completion (each queue's timeline semaphore counts its
/// submissions), which later submissions of the other queue wait on. Submissions are in an
/// order every wait respects (a submission waits only on earlier ones), so submitting them in
/// order never deadlocks, even on one queue.
#[derive(Debug, Clone, PartialEq)]
pub struct Submission {
    pub queue: Queue,
    /// `plan.steps[first..end]`; empty for the frame's first submission (it only signals that
    /// the frame began on the graphics queue, and releases what the other queue takes first)
    /// and for a last one that only joins the other queue.
    pub first: StepIndex,
    pub end: StepIndex,
    pub waits: Vec<QueueWait>,
    /// Release barriers recorded at its end, after its steps: the resources the other queue
    /// takes next leave this queue's family (exclusive sharing).
    pub releases: BarrierBatch,
}

impl Submission {
    pub fn steps(&self) -> std::ops::Range<usize> {
        self.first.index()..self.end.index()
    }
}

/// A wait on another queue's submission before this one runs its work in `dst_stages`.
#[derive(Debug, Clone, PartialEq)]
pub struct QueueWait {
    pub submission: SubmissionIndex,
    pub dst_stages: PipelineStages,
    pub reasons: Vec<WaitReason>,
}

/// Why a submission waits on the other queue.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum WaitReason {
    /// A hazard on a resource used on both queues (`transfer`: its ownership moves with it).
    Resource {
        resource: ResourceId,
        hazard: Hazard,
        transfer: bool,
    },
    /// The async queue's first work waits for the frame to begin on the graphics queue: the
    /// previous frame's use of the same memory and the imports' producers are behind it.
    FrameStart,
    /// The frame ends on the graphics queue after all of the async queue's work, so one
    /// fence (and the next frame's graphics work) covers both.
    Join,
}
