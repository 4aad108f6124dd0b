//! `assign_queues` and `plan_submissions`: which queue runs each pass, and the steps cut into
//! submissions with the semaphore waits and ownership transfers between the queues.
//!
//! Barriers are planned first as if one queue ran everything (`plan_barriers`); this phase then
//! walks the steps with each resource's use per queue. Where a step on one queue touches a
//! resource the other queue used in a way that conflicts (a write on either side; a layout
//! change; with exclusive sharing, any use that needs the content, since the content belongs
//! to one family at a time), the step's submission waits on the other queue's submission of
//! that use, and its barrier for the resource starts from the wait (its source stages the
//! wait's, its source access none: the semaphore makes the writes visible). With exclusive
//! sharing an image's content moves by an ownership transfer: a release barrier at the end of
//! the other queue's submission, the acquire in this step's batch. Buffers are always shared
//! concurrently between the two families (the executor creates them so): exclusive ownership
//! buys a buffer nothing (no compression to keep), and the scene's buffers outside the graph
//! (instances, bounds, uniforms), which both queues read, could not be transferred by the graph.
//! A read after a read needs no wait where sharing is concurrent.
//!
//! Every frame starts with an empty graphics submission, which the async queue's first work
//! waits on (the previous frame's graphics work, and the producers of the imports, are behind
//! it), and ends on the graphics queue after the async queue's last submission, so one fence
//! covers the frame. Resources the async queue owns at the end whose content outlives the
//! frame are handed back to the graphics queue then.

use tilegraph_profile::QueueSharing;

use crate::declare::{InitialContent, PassId, ResourceId};
use crate::plan::{
    BarrierBatch, Hazard, Queue, QueueTransfer, QueueWait, Step, StepIndex, Submission,
    SubmissionIndex, WaitReason,
};
use crate::types::{AccessFlags, Layout, PipelineStages, StoreOp};

use super::access::PassAccesses;
use super::barriers::{push_barrier, BarrierParts, ResourceSync};

/// The queue of each pass (index: `PassId`) when the profile asks for async compute:
/// async-capable passes with raster work beside them (`beside`) on the async queue, everything
/// else on the graphics queue.
pub(crate) fn assign_queues(async_capable: &[bool], beside: &[bool]) -> Vec<Queue> {
    async_capable
        .iter()
        .zip(beside)
        .map(|(&capable, &beside)| {
            if capable && beside {
                Queue::AsyncCompute
            } else {
                Queue::Graphics
            }
        })
        .collect()
}

/// What `plan_submissions` reads besides the steps.
pub(crate) struct SubmissionInput<'a> {
    /// Index: `PassId`.
    pub queue_of: &'a [Queue],
    pub accesses: &'a PassAccesses,
    pub resources: &'a [ResourceSync],
    /// Whose content outlives the frame (exported, or imported and kept).
    pub kept_at_end: &'a [bool],
    pub sharing: QueueSharing,
}

/// The queue a step runs on (`None`: a barrier batch, which goes with the step after it).
fn step_queue(step: &Step, queue_of: &[Queue]) -> Option<Queue> {
    match step {
        Step::Compute { pass } | Step::Transfer { pass } => Some(
            queue_of
                .get(pass.index())
                .copied()
                .unwrap_or(Queue::Graphics),
        ),
        Step::RenderPass(_) | Step::Flush(_) => Some(Queue::Graphics),
        Step::Barriers(_) => None,
    }
}

/// Cuts `steps` into submissions (one graphics submission of everything when no step runs on
/// the async queue), turning the barriers of resources that cross queues into the acquire side
/// of the crossing.
pub(crate) fn plan_submissions(
    steps: Vec<Step>,
    input: &SubmissionInput<'_>,
) -> (Vec<Step>, Vec<Submission>) {
    let on_async = steps
        .iter()
        .any(|s| step_queue(s, input.queue_of) == Some(Queue::AsyncCompute));
    if !on_async {
        let end = StepIndex(steps.len() as u32);
        let all = Submission {
            queue: Queue::Graphics,
            first: StepIndex(0),
            end,
            waits: Vec::new(),
            releases: BarrierBatch::default(),
        };
        return (steps, vec![all]);
    }
    let mut s = Splitter::new(input, steps.len());
    let mut pending: Option<BarrierBatch> = None;
    for step in steps {
        match step {
            Step::Barriers(batch) => match &mut pending {
                Some(p) => {
                    p.images.extend(batch.images);
                    p.buffers.extend(batch.buffers);
                }
                None => pending = Some(batch),
            },
            work => {
                let queue = step_queue(&work, input.queue_of).unwrap_or(Queue::Graphics);
                s.work(work, queue, pending.take().unwrap_or_default());
            }
        }
    }
    s.finish(pending.unwrap_or_default())
}

/// One use of a resource by a step, merged over the step's passes.
#[derive(Debug, Clone, Copy)]
struct StepUse {
    resource: usize,
    stages: PipelineStages,
    access: AccessFlags,
    writes: bool,
    /// The step does not need the content before it (it overwrites all of it).
    discard: bool,
    /// The layout the step leaves it in (images).
    layout: Layout,
}

/// A queue's uses of a resource since the other queue last synchronized with them.
#[derive(Debug, Clone, Copy)]
struct Unsynced {
    submission: u32,
    stages: PipelineStages,
    writes: AccessFlags,
    wrote: bool,
}

#[derive(Debug, Clone, Copy)]
struct Crossing {
    /// The queue whose family holds the content (exclusive sharing).
    owner: Queue,
    /// Used (or holding content) already: the first queue to use it takes it without a
    /// transfer.
    touched: bool,
    layout: Layout,
    /// Index: `Queue as usize`.
    unsynced: [Option<Unsynced>; 2],
}

const fn slot(q: Queue) -> usize {
    match q {
        Queue::Graphics => 0,
        Queue::AsyncCompute => 1,
    }
}

const fn other(q: Queue) -> Queue {
    match q {
        Queue::Graphics => Queue::AsyncCompute,
        Queue::AsyncCompute => Queue::Graphics,
    }
}

/// What a step needs from the other queue for one resource.
struct Need {
    resource: usize,
    submission: u32,
    stages: PipelineStages,
    hazard: Hazard,
    /// The release half, when the content changes family.
    release: Option<Unsynced>,
    old_layout: Layout,
}

struct Splitter<'a> {
    input: &'a SubmissionInput<'a>,
    steps: Vec<Step>,
    submissions: Vec<Submission>,
    state: Vec<Crossing>,
    /// The last submission may take more steps (a flush closes it).
    open: bool,
    /// Scratch: the current step's uses, and per resource its index there.
    uses: Vec<StepUse>,
    use_of: Vec<u32>,
}

const NONE: u32 = u32::MAX;

impl<'a> Splitter<'a> {
    fn new(input: &'a SubmissionInput<'a>, steps: usize) -> Self {
        let state = input
            .resources
            .iter()
            .map(|r| {
                // Whatever came before the frame happened on the graphics queue, and is behind
                // the frame's first (graphics) submission.
                let content = r.import.filter(|i| i.content == InitialContent::Preserve);
                let layout = match content {
                    Some(i) if r.is_image => i.initial.layout,
                    _ => Layout::Undefined,
                };
                // An import was last used on the graphics queue (by an earlier frame or the
                // engine); its content, if kept, belongs to the graphics family. The rest of
                // what came before the frame is behind its first submission, which the async
                // queue's first work waits on.
                let before = r.import.map(|i| Unsynced {
                    submission: 0,
                    stages: i.initial.stages.intersection(Queue::Graphics.stages()),
                    writes: AccessFlags::MEMORY_WRITE,
                    wrote: true,
                });
                Crossing {
                    owner: Queue::Graphics,
                    touched: content.is_some(),
                    layout,
                    unsynced: [before, None],
                }
            })
            .collect();
        Splitter {
            input,
            steps: Vec::with_capacity(steps + 4),
            submissions: vec![Submission {
                queue: Queue::Graphics,
                first: StepIndex(0),
                end: StepIndex(0),
                waits: Vec::new(),
                releases: BarrierBatch::default(),
            }],
            state,
            open: false,
            uses: Vec::new(),
            use_of: vec![NONE; input.resources.len()],
        }
    }

    fn sharing_exclusive(&self) -> bool {
        self.input.sharing == QueueSharing::Exclusive
    }

    /// The uses of `step`'s passes, one per resource.
    fn gather(&mut self, step: &Step) {
        for u in self.uses.drain(..) {
            self.use_of[u.resource] = NONE;
        }
        let accesses = self.input.accesses;
        let add = |pass: PassId, uses: &mut Vec<StepUse>, use_of: &mut [u32]| {
            for a in accesses.of(pass) {
                let r = a.resource.index();
                match use_of.get(r).copied() {
                    Some(NONE) => {
                        use_of[r] = uses.len() as u32;
                        uses.push(StepUse {
                            resource: r,
                            stages: a.stages,
                            access: a.access,
                            writes: a.writes(),
                            discard: a.writes() && !a.reads_prior(),
                            layout: a.layout,
                        });
                    }
                    Some(i) => {
                        if let Some(u) = uses.get_mut(i as usize) {
                            u.stages |= a.stages;
                            u.access |= a.access;
                            u.writes |= a.writes();
                            u.layout = a.layout;
                        }
                    }
                    None => {}
                }
            }
        };
        match step {
            Step::RenderPass(rp) => {
                for sp in &rp.subpasses {
                    add(sp.pass, &mut self.uses, &mut self.use_of);
                }
                // Load and store ops access attachments too (a store writes, whatever it keeps).
                for att in &rp.attachments {
                    let r = att.resource.index();
                    let is_depth = self.input.resources.get(r).is_some_and(|s| s.is_depth);
                    if let Some(&i) = self.use_of.get(r) {
                        if let Some(u) = self.uses.get_mut(i as usize) {
                            u.layout = att.final_layout;
                            u.stages |= if is_depth {
                                PipelineStages::EARLY_FRAGMENT_TESTS
                                    | PipelineStages::LATE_FRAGMENT_TESTS
                            } else {
                                PipelineStages::COLOR_ATTACHMENT_OUTPUT
                            };
                            u.writes |= att.store_op != StoreOp::None;
                        }
                    }
                }
            }
            Step::Compute { pass } | Step::Transfer { pass } => {
                add(*pass, &mut self.uses, &mut self.use_of);
            }
            Step::Barriers(_) | Step::Flush(_) => {}
        }
    }

    /// What `u` on `queue` needs from the other queue (and forgets what it synchronizes).
    fn need(&mut self, u: &StepUse, queue: Queue, barrier_old: Option<Layout>) -> Option<Need> {
        let exclusive = self.sharing_exclusive() && self.input.resources[u.resource].is_image;
        let st = &mut self.state[u.resource];
        let p = other(queue);
        let theirs = st.unsynced[slot(p)]?;
        let old_layout = barrier_old.unwrap_or(st.layout);
        let layout_change = old_layout != u.layout && old_layout != Layout::Undefined;
        let transfer = exclusive && st.touched && st.owner == p && !u.discard;
        let conflict = theirs.wrote || u.writes || layout_change || transfer;
        if !conflict {
            return None;
        }
        st.unsynced[slot(p)] = None;
        let hazard = match (theirs.wrote, u.writes) {
            _ if layout_change => Hazard::LayoutTransition,
            (true, false) => Hazard::ReadAfterWrite,
            (true, true) => Hazard::WriteAfterWrite,
            (false, true) => Hazard::WriteAfterRead,
            // Reads on both sides: only the content's family changes.
            (false, false) => Hazard::Release,
        };
        Some(Need {
            resource: u.resource,
            submission: theirs.submission,
            stages: u.stages,
            hazard,
            release: transfer.then_some(theirs),
            old_layout,
        })
    }

    /// Opens a submission on `queue` for the next step unless the open one is on `queue` and
    /// needs no new wait.
    fn submission_for(&mut self, queue: Queue, new_waits: bool) -> usize {
        let at = StepIndex(self.steps.len() as u32);
        let reuse = self.open
            && self
                .submissions
                .last()
                .is_some_and(|s| s.queue == queue && (!new_waits || s.first == s.end));
        if !reuse {
            let first_async =
                queue == Queue::AsyncCompute && !self.submissions.iter().any(|s| s.queue == queue);
            let mut waits = Vec::new();
            if first_async {
                waits.push(QueueWait {
                    submission: SubmissionIndex(0),
                    dst_stages: queue.stages(),
                    reasons: vec![WaitReason::FrameStart],
                });
            }
            self.submissions.push(Submission {
                queue,
                first: at,
                end: at,
                waits,
                releases: BarrierBatch::default(),
            });
            self.open = true;
        }
        self.submissions.len() - 1
    }

    /// A wait already on `queue`, in submission `upto` or an earlier one, that orders `need`:
    /// on its submission or a later one of the other queue (whose signal comes after it), at
    /// `stages` or more. A semaphore wait's second scope takes in every later command of its
    /// queue at its stages, and a barrier after it chains from those stages.
    fn covering_wait(&self, queue: Queue, need: &Need, upto: usize) -> Option<(usize, usize)> {
        let stages = wait_stages(queue, need);
        let subs = self.submissions.get(..=upto)?;
        subs.iter().enumerate().rev().find_map(|(k, s)| {
            let j = s.waits.iter().position(|w| {
                s.queue == queue
                    && w.submission.0 >= need.submission
                    && w.dst_stages.contains(stages)
            })?;
            Some((k, j))
        })
    }

    /// Whether the step can take `need` without opening a submission: a wait covers it already,
    /// or the open submission on `queue` waits on its submission (or a later one) and can wait
    /// at more stages (a little less overlap for the steps it holds, one submission fewer).
    fn takes_without_split(&self, queue: Queue, need: &Need) -> bool {
        let Some(last) = self.submissions.len().checked_sub(1) else {
            return false;
        };
        self.covering_wait(queue, need, last).is_some()
            || (self.open
                && self.submissions[last].queue == queue
                && self.submissions[last]
                    .waits
                    .iter()
                    .any(|w| w.submission.0 >= need.submission))
    }

    /// Adds the wait for `need` to submission `sub` (a covering wait takes its reason; else one
    /// on the same or a later submission waits at more stages; else a new one), the release to
    /// the other queue's submission, and returns the wait's stages.
    fn wait(
        &mut self,
        sub: usize,
        queue: Queue,
        need: &Need,
        new_layout: Layout,
    ) -> PipelineStages {
        let stages = wait_stages(queue, need);
        let reason = WaitReason::Resource {
            resource: ResourceId(need.resource as u32),
            hazard: need.hazard,
            transfer: need.release.is_some(),
        };
        if let Some((k, j)) = self.covering_wait(queue, need, sub) {
            self.submissions[k].waits[j].reasons.push(reason);
        } else {
            let waits = &mut self.submissions[sub].waits;
            match waits.iter_mut().find(|w| w.submission.0 >= need.submission) {
                Some(w) => {
                    w.dst_stages |= stages;
                    w.reasons.push(reason);
                }
                None => waits.push(QueueWait {
                    submission: SubmissionIndex(need.submission),
                    dst_stages: stages,
                    reasons: vec![reason],
                }),
            }
        }
        if let Some(theirs) = need.release {
            let from = other(queue);
            let transfer = Some(QueueTransfer { from, to: queue });
            if let Some(producer) = self.submissions.get_mut(need.submission as usize) {
                push_barrier(
                    &mut producer.releases,
                    need.resource,
                    self.input.resources[need.resource].is_image,
                    BarrierParts {
                        src_stages: theirs.stages.intersection(from.stages()),
                        src_access: theirs.writes,
                        dst_stages: PipelineStages::NONE,
                        dst_access: AccessFlags::NONE,
                        old_layout: need.old_layout,
                        new_layout,
                        hazard: need.hazard,
                        transfer,
                    },
                );
            }
        }
        stages
    }

    /// The crossing `n` of a step on `queue` in submission `sub`: the wait, the release on the
    /// other queue, and the acquire in `batch` (the resource's barrier turned, or a barrier of
    /// its own for a transfer that changes no layout).
    fn cross(&mut self, sub: usize, queue: Queue, n: &Need, u: &StepUse, batch: &mut BarrierBatch) {
        let new_layout = acquired_layout(batch, n);
        let stages = self.wait(sub, queue, n, new_layout);
        let transfer = n.release.map(|_| QueueTransfer {
            from: other(queue),
            to: queue,
        });
        if !acquire(batch, n.resource, stages, transfer) && transfer.is_some() {
            push_barrier(
                batch,
                n.resource,
                self.input.resources[n.resource].is_image,
                BarrierParts {
                    src_stages: stages,
                    src_access: AccessFlags::NONE,
                    dst_stages: u.stages,
                    dst_access: u.access,
                    old_layout: n.old_layout,
                    new_layout: n.old_layout,
                    hazard: n.hazard,
                    transfer,
                },
            );
        }
    }

    fn work(&mut self, step: Step, queue: Queue, mut batch: BarrierBatch) {
        self.gather(&step);
        let uses = std::mem::take(&mut self.uses);
        let mut needs = Vec::new();
        for u in &uses {
            let barrier_old = barrier_layout(&batch, u.resource);
            if let Some(n) = self.need(u, queue, barrier_old) {
                needs.push(n);
            }
        }
        let split = needs.iter().any(|n| !self.takes_without_split(queue, n));
        let sub = self.submission_for(queue, split);
        for n in &needs {
            if let Some(u) = uses.iter().find(|u| u.resource == n.resource) {
                self.cross(sub, queue, n, u, &mut batch);
            }
        }
        if queue == Queue::AsyncCompute {
            restrict_to_compute(&mut batch);
        }
        for u in &uses {
            let exclusive = self.sharing_exclusive() && self.input.resources[u.resource].is_image;
            let st = &mut self.state[u.resource];
            let mine = &mut st.unsynced[slot(queue)];
            *mine = Some(match *mine {
                Some(m) => Unsynced {
                    submission: sub as u32,
                    stages: m.stages | u.stages,
                    writes: m.writes | u.access.writes(),
                    wrote: m.wrote || u.writes,
                },
                None => Unsynced {
                    submission: sub as u32,
                    stages: u.stages,
                    writes: u.access.writes(),
                    wrote: u.writes,
                },
            });
            let took = !st.touched || u.discard || needs.iter().any(|n| n.resource == u.resource);
            if exclusive && took {
                st.owner = queue;
            }
            st.touched = true;
            if self.input.resources[u.resource].is_image {
                st.layout = u.layout;
            }
        }
        self.uses = uses;
        if !batch.is_empty() {
            self.steps.push(Step::Barriers(batch));
        }
        let flush = matches!(step, Step::Flush(_));
        self.steps.push(step);
        if let Some(s) = self.submissions.get_mut(sub) {
            s.end = StepIndex(self.steps.len() as u32);
        }
        if flush {
            self.open = false;
        }
    }

    /// The frame's last batch (the imports' releases into their final states) on the graphics
    /// queue, what the async queue still owns handed back, and the join.
    fn finish(mut self, mut batch: BarrierBatch) -> (Vec<Step>, Vec<Submission>) {
        let queue = Queue::Graphics;
        let exclusive = self.sharing_exclusive();
        let mut needs = Vec::new();
        for r in 0..self.state.len() {
            let st = self.state[r];
            let released = batch
                .images
                .iter()
                .map(|b| (b.resource, b.dst_stages, b.new_layout))
                .chain(
                    batch
                        .buffers
                        .iter()
                        .map(|b| (b.resource, b.dst_stages, Layout::Undefined)),
                )
                .find(|(id, _, _)| id.index() == r);
            let kept = self.input.kept_at_end.get(r).copied().unwrap_or(false);
            let owned_away = exclusive && st.owner == Queue::AsyncCompute && kept;
            if released.is_none() && !owned_away {
                continue;
            }
            let (stages, layout) = released.map_or((queue.stages(), st.layout), |(_, s, l)| (s, l));
            let u = StepUse {
                resource: r,
                stages,
                access: AccessFlags::NONE,
                writes: false,
                discard: false,
                layout,
            };
            let old = barrier_layout(&batch, r);
            if let Some(n) = self.need(&u, queue, old) {
                needs.push((n, u));
            }
        }
        if !needs.is_empty() || !batch.is_empty() {
            let split = needs
                .iter()
                .any(|(n, _)| !self.takes_without_split(queue, n));
            let sub = self.submission_for(queue, split);
            for (n, u) in &needs {
                self.cross(sub, queue, n, u, &mut batch);
                self.state[n.resource].owner = queue;
            }
            if !batch.is_empty() {
                self.steps.push(Step::Barriers(batch));
                if let Some(s) = self.submissions.get_mut(sub) {
                    s.end = StepIndex(self.steps.len() as u32);
                }
            }
        }
        // The join: the last submission runs on the graphics queue after the async queue's
        // last one.
        let last_async = self
            .submissions
            .iter()
            .rposition(|s| s.queue == Queue::AsyncCompute);
        if let Some(a) = last_async {
            let joined = self.submissions[a + 1..].iter().any(|s| {
                s.queue == Queue::Graphics && s.waits.iter().any(|w| w.submission.index() == a)
            }) && self
                .submissions
                .last()
                .is_some_and(|s| s.queue == Queue::Graphics);
            if !joined {
                let at = StepIndex(self.steps.len() as u32);
                self.submissions.push(Submission {
                    queue: Queue::Graphics,
                    first: at,
                    end: at,
                    waits: vec![QueueWait {
                        submission: SubmissionIndex(a as u32),
                        dst_stages: Queue::Graphics.stages(),
                        reasons: vec![WaitReason::Join],
                    }],
                    releases: BarrierBatch::default(),
                });
            }
        }
        (self.steps, self.submissions)
    }
}

/// The stages at which `queue` waits for `need`: those of the access the queue has (all of
/// them where it has none of the access's).
fn wait_stages(queue: Queue, need: &Need) -> PipelineStages {
    let s = need.stages.intersection(queue.stages());
    if s.is_empty() {
        queue.stages()
    } else {
        s
    }
}

/// The old layout of `resource`'s barrier in `batch`, if it has one.
fn barrier_layout(batch: &BarrierBatch, resource: usize) -> Option<Layout> {
    batch
        .images
        .iter()
        .find(|b| b.resource.index() == resource)
        .map(|b| b.old_layout)
}

/// The layout a crossing leaves the resource in on the acquiring queue: its barrier's new
/// layout, else the one it had (both halves of a transfer name the same layouts).
fn acquired_layout(batch: &BarrierBatch, n: &Need) -> Layout {
    batch
        .images
        .iter()
        .find(|b| b.resource.index() == n.resource)
        .map_or(n.old_layout, |b| b.new_layout)
}

/// Turns `resource`'s barrier in `batch` into the acquire side of a crossing: its source scope
/// also takes the semaphore wait's stages (the execution dependency chains through the wait,
/// whose signal made the other queue's writes available); what it waited for on its own queue
/// stays. `false` when the batch has no barrier for it.
fn acquire(
    batch: &mut BarrierBatch,
    resource: usize,
    wait_stages: PipelineStages,
    transfer: Option<QueueTransfer>,
) -> bool {
    if let Some(b) = batch
        .images
        .iter_mut()
        .find(|b| b.resource.index() == resource)
    {
        b.src_stages |= wait_stages;
        b.queue_transfer = transfer;
        return true;
    }
    if let Some(b) = batch
        .buffers
        .iter_mut()
        .find(|b| b.resource.index() == resource)
    {
        b.src_stages |= wait_stages;
        b.queue_transfer = transfer;
        return true;
    }
    false
}

/// The accesses work in `stages` of a compute queue can make.
fn compute_queue_accesses(stages: PipelineStages) -> AccessFlags {
    let mut a = AccessFlags::MEMORY_READ | AccessFlags::MEMORY_WRITE;
    if stages.intersects(PipelineStages::COMPUTE_SHADER) {
        a |= AccessFlags::UNIFORM_READ
            | AccessFlags::SHADER_READ
            | AccessFlags::SHADER_WRITE
            | AccessFlags::SHADER_SAMPLED_READ
            | AccessFlags::SHADER_STORAGE_READ
            | AccessFlags::SHADER_STORAGE_WRITE;
    }
    if stages.intersects(PipelineStages::DRAW_INDIRECT) {
        a |= AccessFlags::INDIRECT_COMMAND_READ;
    }
    if stages.intersects(PipelineStages::ALL_TRANSFER) {
        a |= AccessFlags::TRANSFER_READ | AccessFlags::TRANSFER_WRITE;
    }
    if stages.intersects(PipelineStages::CONDITIONAL_RENDERING) {
        a |= AccessFlags::CONDITIONAL_RENDERING_READ;
    }
    a
}

/// Keeps a batch on the async compute queue to the stages (and their accesses) that queue has
/// (a compute pass's predicate included): what came from the graphics queue is covered by the
/// waits.
fn restrict_to_compute(batch: &mut BarrierBatch) {
    let all = Queue::AsyncCompute.stages() | PipelineStages::CONDITIONAL_RENDERING;
    let fit = |src: &mut PipelineStages,
               src_access: &mut AccessFlags,
               dst: &mut PipelineStages,
               dst_access: &mut AccessFlags| {
        *src = src.intersection(all);
        *dst = dst.intersection(all);
        *src_access = src_access.intersection(compute_queue_accesses(*src));
        *dst_access = dst_access.intersection(compute_queue_accesses(*dst));
    };
    for b in batch.images.iter_mut() {
        fit(
            &mut b.src_stages,
            &mut b.src_access,
            &mut b.dst_stages,
            &mut b.dst_access,
        );
    }
    for b in batch.buffers.iter_mut() {
        fit(
            &mut b.src_stages,
            &mut b.src_access,
            &mut b.dst_stages,
            &mut b.dst_access,
        );
    }
}
