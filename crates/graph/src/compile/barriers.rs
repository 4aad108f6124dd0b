//! `plan_barriers`: synchronization2 barriers and layout transitions between steps, only where
//! a hazard exists. It walks the work steps load/store inference built (or the steps of an
//! existing plan, to re-plan after aliasing with real memory requirements).
//!
//! Each resource carries a small state: its layout, the stages and accesses of its last write,
//! the stages that read it since, and which stages/accesses already see that write. A new
//! access needs a barrier for a layout change, a read or write after an unseen write (RAW,
//! WAW), or a write after reads (WAR, execution dependency only). All barriers needed before a
//! step go into one batch. Inside a merged render pass the same hazards are subpass
//! dependencies (built with the render pass); before it, one batch prepares every attachment
//! (initial layout `Undefined`, and no barrier, for an attachment nothing touched before) and
//! every descriptor or vertex resource of all its subpasses. Load and store ops count as
//! accesses: every attachment is written at the end of its render pass (both `STORE` and
//! `DONT_CARE` write, as synchronization validation models them).
//!
//! Aliasing: the first use of a resource that takes over memory waits for the last accesses of
//! the resources that held it ([`AliasAssignment::handoffs`]). Imported resources start from
//! their declared state and end with a barrier into their final state.

use crate::declare::{
    Import, InitialContent, Origin, PassId, ResourceDesc, ResourceId, ResourceState,
};
use crate::plan::{
    AliasAssignment, BarrierBatch, BufferBarrier, Hazard, ImageBarrier, QueueTransfer, RenderPass,
    Step, StepIndex, StepRange,
};
use crate::types::{AccessFlags, Layout, LoadOp, PipelineStages, StoreOp};

use super::access::{Access, PassAccesses, DEPTH_TESTS};

/// What the barrier planner needs to know about a resource.
#[derive(Debug, Clone, Copy)]
pub(crate) struct ResourceSync {
    pub is_image: bool,
    pub is_depth: bool,
    pub import: Option<Import>,
}

impl ResourceSync {
    pub fn of(desc: &ResourceDesc, origin: &Origin) -> Self {
        ResourceSync {
            is_image: desc.image().is_some(),
            is_depth: desc.image().is_some_and(|d| d.format.is_depth_stencil()),
            import: match origin {
                Origin::Imported(import) => Some(*import),
                Origin::Created => None,
            },
        }
    }
}

#[derive(Debug, Clone, Copy)]
struct SyncState {
    layout: Layout,
    write_stages: PipelineStages,
    write_access: AccessFlags,
    read_stages: PipelineStages,
    visible_stages: PipelineStages,
    visible_access: AccessFlags,
    touched: bool,
    /// The next barrier is the aliasing handoff.
    alias_pending: bool,
    /// Copied from the resource: the hot loops read one array.
    is_image: bool,
    is_depth: bool,
}

impl SyncState {
    fn initial(r: &ResourceSync) -> Self {
        let mut s = SyncState {
            layout: Layout::Undefined,
            write_stages: PipelineStages::NONE,
            write_access: AccessFlags::NONE,
            read_stages: PipelineStages::NONE,
            visible_stages: PipelineStages::NONE,
            visible_access: AccessFlags::NONE,
            touched: false,
            alias_pending: false,
            is_image: r.is_image,
            is_depth: r.is_depth,
        };
        if let Some(import) = r.import {
            if r.is_image && import.content == InitialContent::Preserve {
                s.layout = import.initial.layout;
            }
            if import.initial.access.writes().is_empty() {
                s.read_stages = import.initial.stages;
            } else {
                s.write_stages = import.initial.stages;
                s.write_access = import.initial.access;
            }
        }
        s
    }

    fn is_fresh(&self) -> bool {
        self.write_stages.is_empty() && self.write_access.is_empty() && self.read_stages.is_empty()
    }

    /// Records an access after its barrier.
    fn apply(&mut self, u: &SyncUse, is_image: bool) {
        if u.writes {
            self.write_stages = u.stages;
            self.write_access = u.access;
            self.read_stages = PipelineStages::NONE;
            self.visible_stages = PipelineStages::NONE;
            self.visible_access = AccessFlags::NONE;
        } else if u.reads {
            self.read_stages |= u.stages;
        }
        if is_image {
            self.layout = u.layout;
        }
    }
}

/// One access as the synchronization model sees it.
#[derive(Debug, Clone, Copy, PartialEq)]
struct SyncUse {
    stages: PipelineStages,
    access: AccessFlags,
    layout: Layout,
    reads: bool,
    writes: bool,
    /// The old content is not needed: transition from `Undefined`.
    discard: bool,
}

impl SyncUse {
    fn of(a: &Access) -> Self {
        SyncUse {
            stages: a.stages,
            access: a.access,
            layout: a.layout,
            reads: a.reads_prior() || a.explicit_read(),
            writes: a.writes(),
            discard: a.writes() && !a.reads_prior(),
        }
    }
}

#[derive(Debug, Clone, Copy)]
pub(super) struct BarrierParts {
    pub src_stages: PipelineStages,
    pub src_access: AccessFlags,
    pub dst_stages: PipelineStages,
    pub dst_access: AccessFlags,
    pub old_layout: Layout,
    pub new_layout: Layout,
    pub hazard: Hazard,
    /// The half of an ownership transfer between the queues' families (`queues.rs`).
    pub transfer: Option<QueueTransfer>,
}

/// The barrier `u` needs given state `st` (and updates `st` for it), or `None`.
fn sync(st: &mut SyncState, u: &SyncUse, is_image: bool) -> Option<BarrierParts> {
    let layout_change = is_image && st.layout != u.layout;
    let has_write = !st.write_stages.is_empty() || !st.write_access.is_empty();
    let covered = st.visible_stages.contains(u.stages) && st.visible_access.contains(u.access);
    let mut src_stages = PipelineStages::NONE;
    let mut src_access = AccessFlags::NONE;
    let mut hazard = None;
    let mut synced_write = false;
    let mut synced_reads = false;
    if layout_change {
        // A transition reads and writes the whole image: wait for everything before it.
        src_stages = st.write_stages | st.read_stages;
        src_access = st.write_access.writes();
        hazard = Some(Hazard::LayoutTransition);
        synced_write = true;
        synced_reads = true;
    } else {
        if has_write && !covered && (u.reads || u.writes) {
            src_stages |= st.write_stages;
            src_access |= st.write_access.writes();
            synced_write = true;
            hazard = Some(if u.reads {
                Hazard::ReadAfterWrite
            } else {
                Hazard::WriteAfterWrite
            });
        }
        if u.writes && !st.read_stages.is_empty() {
            src_stages |= st.read_stages;
            synced_reads = true;
            hazard.get_or_insert(Hazard::WriteAfterRead);
        }
    }
    let hazard = hazard?;
    let parts = BarrierParts {
        src_stages,
        src_access,
        dst_stages: u.stages,
        dst_access: u.access,
        old_layout: if u.discard || !is_image {
            Layout::Undefined
        } else {
            st.layout
        },
        new_layout: if is_image {
            u.layout
        } else {
            Layout::Undefined
        },
        hazard,
        transfer: None,
    };
    if layout_change {
        st.layout = u.layout;
        // Later accesses chain through the transition's destination stages.
        st.write_stages = u.stages;
        st.write_access = AccessFlags::NONE;
    }
    if synced_write {
        st.visible_stages = u.stages;
        st.visible_access = u.access;
    }
    if synced_reads {
        st.read_stages = PipelineStages::NONE;
    }
    Some(parts)
}

pub(super) fn push_barrier(
    batch: &mut BarrierBatch,
    resource: usize,
    is_image: bool,
    b: BarrierParts,
) {
    let resource = ResourceId(resource as u32);
    if is_image {
        batch.images.push(ImageBarrier {
            resource,
            src_stages: b.src_stages,
            src_access: b.src_access,
            dst_stages: b.dst_stages,
            dst_access: b.dst_access,
            old_layout: b.old_layout,
            new_layout: b.new_layout,
            hazard: b.hazard,
            queue_transfer: b.transfer,
        });
    } else {
        batch.buffers.push(BufferBarrier {
            resource,
            src_stages: b.src_stages,
            src_access: b.src_access,
            dst_stages: b.dst_stages,
            dst_access: b.dst_access,
            hazard: b.hazard,
            queue_transfer: b.transfer,
        });
    }
}

/// Stages and access of an attachment's load op (a read for LOAD, a write otherwise) and of
/// its store op (always a write).
fn load_store_access(is_depth: bool, load: LoadOp) -> (PipelineStages, AccessFlags, AccessFlags) {
    if is_depth {
        let load_access = if load == LoadOp::Load {
            AccessFlags::DEPTH_STENCIL_ATTACHMENT_READ
        } else {
            AccessFlags::DEPTH_STENCIL_ATTACHMENT_WRITE
        };
        (
            DEPTH_TESTS,
            load_access,
            AccessFlags::DEPTH_STENCIL_ATTACHMENT_WRITE,
        )
    } else {
        let load_access = if load == LoadOp::Load {
            AccessFlags::COLOR_ATTACHMENT_READ
        } else {
            AccessFlags::COLOR_ATTACHMENT_WRITE
        };
        (
            PipelineStages::COLOR_ATTACHMENT_OUTPUT,
            load_access,
            AccessFlags::COLOR_ATTACHMENT_WRITE,
        )
    }
}

/// Where each resource's hand-offs start in `aliasing.handoffs` (sorted by `to`), one entry
/// per resource and one past the end: a range lookup instead of a search per resource.
fn handoff_ranges(aliasing: &AliasAssignment, n_resources: usize) -> Vec<u32> {
    let mut start = vec![0u32; n_resources + 1];
    for h in &aliasing.handoffs {
        if let Some(count) = start.get_mut(h.to.index() + 1) {
            *count += 1;
        }
    }
    for i in 1..start.len() {
        start[i] += start[i - 1];
    }
    start
}

pub(crate) struct BarrierPlan {
    pub steps: Vec<Step>,
    /// The state each resource is left in (imported: their final state).
    pub final_states: Vec<ResourceState>,
}

const NONE: u32 = u32::MAX;

/// An attachment's accesses over all subpasses of its render pass.
#[derive(Debug, Clone, Copy, PartialEq)]
struct AttachmentUse {
    /// Layout of the first subpass that uses it.
    first_layout: Option<Layout>,
    stages: PipelineStages,
    access: AccessFlags,
}

/// What the subpasses of one render pass do to each resource, merged: per attachment, and per
/// resource reached through memory, gathered from its subpasses' accesses.
#[derive(Debug, Default, PartialEq)]
struct RenderPassUses {
    /// Index = attachment index.
    attachments: Vec<AttachmentUse>,
    /// Resources the subpasses reach through memory, each once, in order of first use.
    others: Vec<(usize, SyncUse)>,
}

impl RenderPassUses {
    fn clear(&mut self) {
        self.attachments.clear();
        self.others.clear();
    }

    /// Attachment `index` (the next one, or one already added) is used by access `a`.
    #[inline]
    fn attachment_access(&mut self, index: usize, a: &Access) {
        debug_assert!(
            index <= self.attachments.len(),
            "attachments are added in order"
        );
        if index == self.attachments.len() {
            self.attachments.push(AttachmentUse {
                first_layout: Some(a.layout),
                stages: a.stages,
                access: a.access,
            });
        } else if let Some(au) = self.attachments.get_mut(index) {
            au.first_layout.get_or_insert(a.layout);
            au.stages |= a.stages;
            au.access |= a.access;
        }
    }

    /// A resource reached through memory is used by access `a`: `seen` is the index this
    /// returned for its first use in this render pass (`None`: this is the first).
    #[inline]
    fn other_access(&mut self, seen: Option<usize>, a: &Access) -> usize {
        let u = SyncUse::of(a);
        if let Some(i) = seen {
            if let Some((_, o)) = self.others.get_mut(i) {
                o.stages |= u.stages;
                o.access |= u.access;
                o.reads |= u.reads;
                o.writes |= u.writes;
                return i;
            }
        }
        self.others.push((a.resource.index(), u));
        self.others.len() - 1
    }

    /// Gathers the uses of a planned render pass from its subpasses' accesses (`slot`: per
    /// resource scratch, all `NONE`, left so).
    fn gather(&mut self, rp: &RenderPass, accesses: &PassAccesses, slot: &mut [u32]) {
        self.clear();
        for (i, att) in rp.attachments.iter().enumerate() {
            slot[att.resource.index()] = i as u32;
            self.attachments.push(AttachmentUse {
                first_layout: None,
                stages: PipelineStages::NONE,
                access: AccessFlags::NONE,
            });
        }
        let n_attachments = rp.attachments.len() as u32;
        for s in &rp.subpasses {
            for a in accesses.of(s.pass) {
                let r = a.resource.index();
                match slot[r] {
                    NONE => {
                        let i = self.other_access(None, a);
                        slot[r] = n_attachments + i as u32;
                    }
                    i if i < n_attachments => self.attachment_access(i as usize, a),
                    i => {
                        self.other_access(Some((i - n_attachments) as usize), a);
                    }
                }
            }
        }
        for att in &rp.attachments {
            slot[att.resource.index()] = NONE;
        }
        for &(r, _) in &self.others {
            slot[r] = NONE;
        }
    }
}

/// The barriers of a frame: the work steps in execution order (barrier batches among them
/// are dropped and planned anew), each after the batch of barriers it needs, if any (render
/// passes get their initial layouts), and a last batch that releases imported resources.
pub(crate) fn plan_barriers(
    work: Vec<Step>,
    accesses: &PassAccesses,
    resources: &[ResourceSync],
    aliasing: &AliasAssignment,
) -> BarrierPlan {
    let mut planner = BarrierPlanner::new(accesses, resources, aliasing, work.len());
    for step in work {
        planner.push(step);
    }
    planner.finish()
}

/// Plans barriers step by step.
struct BarrierPlanner<'a> {
    planner: Planner<'a>,
    /// Barriers before the next step.
    batch: BarrierBatch,
    /// Scratch: the current render pass's uses.
    uses: RenderPassUses,
    steps: Vec<Step>,
}

/// The synchronization state of every resource.
struct Planner<'a> {
    accesses: &'a PassAccesses,
    resources: &'a [ResourceSync],
    aliasing: &'a AliasAssignment,
    /// `aliasing.handoffs[handoffs_of[r]..handoffs_of[r + 1]]` hand memory to resource `r`.
    handoffs_of: Vec<u32>,
    states: Vec<SyncState>,
    /// Scratch, per resource, for [`RenderPassUses::gather`]: `NONE` between render passes.
    slot: Vec<u32>,
}

impl Planner<'_> {
    /// First touch: fold in the memory predecessors' last accesses.
    #[inline]
    fn touch(&mut self, r: usize) {
        if !self.states[r].touched {
            self.first_touch(r);
        }
    }

    #[cold]
    fn first_touch(&mut self, r: usize) {
        self.states[r].touched = true;
        let mut any = false;
        let mut stages = PipelineStages::NONE;
        let mut access = AccessFlags::NONE;
        let (start, end) = match self.handoffs_of.get(r..r + 2) {
            Some(&[start, end]) => (start as usize, end as usize),
            _ => (0, 0),
        };
        for h in self.aliasing.handoffs.get(start..end).unwrap_or(&[]) {
            if let Some(p) = self.states.get(h.from.index()) {
                stages |= p.write_stages | p.read_stages;
                access |= p.write_access.writes();
                any = true;
            }
        }
        if any {
            let st = &mut self.states[r];
            st.write_stages |= stages;
            st.write_access |= access;
            st.alias_pending = true;
        }
    }

    fn barrier(&mut self, r: usize, u: &SyncUse, batch: &mut BarrierBatch) {
        let is_image = self.states[r].is_image;
        if let Some(mut parts) = sync(&mut self.states[r], u, is_image) {
            if std::mem::take(&mut self.states[r].alias_pending) {
                parts.hazard = Hazard::Aliasing;
            }
            push_barrier(batch, r, is_image, parts);
        }
    }

    fn render_pass(
        &mut self,
        rp: &mut RenderPass,
        uses: &RenderPassUses,
        batch: &mut BarrierBatch,
    ) {
        // Attachment by attachment (each is one resource): the barrier that prepares it, then
        // the state the render pass leaves it in.
        for (att, au) in rp.attachments.iter_mut().zip(&uses.attachments) {
            let r = att.resource.index();
            self.touch(r);
            let is_depth = self.states[r].is_depth;
            let (stages, load_access, store_access) = load_store_access(is_depth, att.load_op);
            // Even a read-only attachment is written by its store op (STORE and DONT_CARE both
            // write): earlier reads of it (a sampler, say) must finish first, and an earlier
            // write is made visible to the store too (write after write). NONE is no access: a
            // render pass that only reads is a reader like any other.
            let stores = att.store_op != StoreOp::None;
            if let Some(first_layout) = au.first_layout {
                let loads = att.load_op == LoadOp::Load;
                // Later subpasses are ordered by subpass dependencies, but the barrier before
                // the render pass covers every stage that touches the attachment in it (a
                // sampled read of a read-only depth attachment, say).
                let u = SyncUse {
                    stages: au.stages | stages,
                    access: au.access
                        | load_access
                        | if stores {
                            store_access
                        } else {
                            AccessFlags::NONE
                        },
                    layout: first_layout,
                    reads: loads,
                    writes: stores,
                    discard: !loads,
                };
                if self.states[r].is_fresh() && !loads && !self.states[r].alias_pending {
                    // Nothing to wait for: the render pass transitions from Undefined itself.
                    att.initial_layout = Layout::Undefined;
                } else {
                    self.barrier(r, &u, batch);
                    att.initial_layout = self.states[r].layout;
                }
            }
            // After the render pass: written by its store op.
            let st = &mut self.states[r];
            st.layout = att.final_layout;
            if !stores {
                // Only read, by the subpasses and the LOAD op (the last subpass's layout is the
                // final one: no transition).
                st.read_stages |= au.stages | stages;
                continue;
            }
            st.write_stages = au.stages | stages;
            st.write_access = au.access.writes() | store_access;
            st.read_stages = PipelineStages::NONE;
            st.visible_stages = PipelineStages::NONE;
            st.visible_access = AccessFlags::NONE;
        }
        // Resources the subpasses reach through memory: one entry each, so each one's state
        // moves on right after its barrier.
        for &(r, u) in &uses.others {
            self.touch(r);
            self.barrier(r, &u, batch);
            let is_image = self.states[r].is_image;
            self.states[r].apply(&u, is_image);
        }
    }

    fn single_pass(&mut self, pass: PassId, batch: &mut BarrierBatch) {
        // One access per resource in a pass: each resource's state moves on right after its
        // barrier.
        for a in self.accesses.of(pass) {
            let r = a.resource.index();
            let u = SyncUse::of(a);
            self.touch(r);
            self.barrier(r, &u, batch);
            let is_image = self.states[r].is_image;
            self.states[r].apply(&u, is_image);
        }
    }
}

impl<'a> BarrierPlanner<'a> {
    /// A planner for a frame of about `work_steps` steps (work steps and flushes).
    fn new(
        accesses: &'a PassAccesses,
        resources: &'a [ResourceSync],
        aliasing: &'a AliasAssignment,
        work_steps: usize,
    ) -> Self {
        BarrierPlanner {
            planner: Planner {
                accesses,
                resources,
                aliasing,
                handoffs_of: handoff_ranges(aliasing, resources.len()),
                states: resources.iter().map(SyncState::initial).collect(),
                slot: vec![NONE; resources.len()],
            },
            batch: BarrierBatch::default(),
            uses: RenderPassUses {
                attachments: Vec::with_capacity(16),
                others: Vec::with_capacity(16),
            },
            // Most work steps need a batch before them; one more releases the imports.
            steps: Vec::with_capacity(2 * work_steps + 1),
        }
    }

    /// Ends the frame: a last batch releases imported resources into their final state (the
    /// rest stay as their last use left them).
    fn finish(mut self) -> BarrierPlan {
        let planner = &mut self.planner;
        let mut final_states = Vec::with_capacity(planner.resources.len());
        for (r, res) in planner.resources.iter().enumerate() {
            let st = &mut planner.states[r];
            let Some(import) = res.import else {
                final_states.push(ResourceState {
                    layout: st.layout,
                    stages: st.write_stages | st.read_stages,
                    access: st.write_access,
                });
                continue;
            };
            let mut fin = import.final_state;
            if fin.layout == Layout::Undefined || !res.is_image {
                // No layout asked for: keep the current one (a transition to Undefined is
                // invalid).
                fin.layout = if res.is_image {
                    st.layout
                } else {
                    Layout::Undefined
                };
            }
            let u = SyncUse {
                stages: fin.stages,
                access: fin.access,
                layout: fin.layout,
                reads: true,
                writes: !fin.access.writes().is_empty(),
                discard: false,
            };
            if let Some(mut parts) = sync(st, &u, res.is_image) {
                parts.hazard = Hazard::Release;
                push_barrier(&mut self.batch, r, res.is_image, parts);
            }
            final_states.push(fin);
        }
        if !self.batch.is_empty() {
            let b = std::mem::take(&mut self.batch);
            self.steps.push(Step::Barriers(b));
        }
        BarrierPlan {
            steps: self.steps,
            final_states,
        }
    }
}

impl BarrierPlanner<'_> {
    /// Plans the barriers `step` needs and appends them, then the step. Barrier steps in the
    /// input are dropped (they are planned anew).
    fn push(&mut self, mut step: Step) {
        match &mut step {
            Step::Compute { pass } | Step::Transfer { pass } => {
                self.planner.single_pass(*pass, &mut self.batch);
            }
            Step::RenderPass(rp) => {
                let planner = &mut self.planner;
                self.uses.gather(rp, planner.accesses, &mut planner.slot);
                planner.render_pass(rp, &self.uses, &mut self.batch)
            }
            Step::Flush(_) => {}
            Step::Barriers(_) => return,
        }
        if !self.batch.is_empty() {
            self.steps
                .push(Step::Barriers(std::mem::take(&mut self.batch)));
        }
        self.steps.push(step);
    }
}

/// First and last work step using each resource.
pub(crate) fn step_lifetimes(
    steps: &[Step],
    accesses: &PassAccesses,
    n_resources: usize,
) -> Vec<Option<StepRange>> {
    let mut out: Vec<Option<StepRange>> = vec![None; n_resources];
    let mut mark = |resource: usize, step: StepIndex| {
        if let Some(slot) = out.get_mut(resource) {
            match slot {
                None => {
                    *slot = Some(StepRange {
                        first: step,
                        last: step,
                    })
                }
                Some(range) => range.last = step,
            }
        }
    };
    for (i, step) in steps.iter().enumerate() {
        let index = StepIndex(i as u32);
        match step {
            Step::RenderPass(rp) => {
                for s in &rp.subpasses {
                    for a in accesses.of(s.pass) {
                        mark(a.resource.index(), index);
                    }
                }
            }
            Step::Compute { pass } | Step::Transfer { pass } => {
                for a in accesses.of(*pass) {
                    mark(a.resource.index(), index);
                }
            }
            Step::Barriers(_) | Step::Flush(_) => {}
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use crate::testing::*;
    use crate::*;

    fn static_buffer(g: &mut GraphBuilder<()>, name: &str) -> BufferId {
        g.import_buffer(
            name,
            1024,
            Import {
                initial: ResourceState::UNDEFINED,
                content: InitialContent::Preserve,
                final_state: ResourceState::UNDEFINED,
            },
        )
    }

    #[test]
    fn read_after_write_waits_for_the_writer() {
        let mut g = GraphBuilder::new();
        let instances = static_buffer(&mut g, "instances");
        let args = g.create_buffer("args", 256);
        let out = swapchain(&mut g);
        g.compute_pass("cull", PassClass::Compute, ())
            .storage_read(instances)
            .storage_write(args)
            .coverage(Coverage::Full);
        g.raster_pass("draw", PassClass::Opaque, ())
            .indirect(args)
            .color_clear(out, ClearColor::BLACK);
        let plan = compile(g, &tiler());
        let seen = barriers_of(&plan, "args");
        assert_eq!(seen.len(), 1, "{plan}");
        assert_eq!(seen[0].hazard, Hazard::ReadAfterWrite);
        assert_eq!(
            seen[0].src,
            (
                PipelineStages::COMPUTE_SHADER,
                AccessFlags::SHADER_STORAGE_WRITE
            )
        );
        assert_eq!(
            seen[0].dst,
            (
                PipelineStages::DRAW_INDIRECT,
                AccessFlags::INDIRECT_COMMAND_READ
            )
        );
        // The static input was never written in the frame: nothing to wait for.
        assert!(barriers_of(&plan, "instances").is_empty());
    }

    /// The oq-conditional frame: query results copied into a buffer, then draws predicated on
    /// it. The predicate is read by the conditional-rendering stage (not as indirect
    /// arguments), both after the copy and, next time the buffer is overwritten, before it.
    #[test]
    fn a_conditional_rendering_predicate_waits_at_its_own_stage() {
        let mut g = GraphBuilder::new();
        let conditions = g.create_buffer("conditions", 256);
        let out = swapchain(&mut g);
        g.transfer_pass("copy_results", PassClass::Transfer, ())
            .transfer_dst(conditions)
            .coverage(Coverage::Full);
        g.raster_pass("draw", PassClass::Opaque, ())
            .predicate(conditions)
            .color_clear(out, ClearColor::BLACK);
        g.transfer_pass("reset", PassClass::Transfer, ())
            .transfer_dst(conditions)
            .coverage(Coverage::Full)
            .retention(Retention::Always);
        let plan = compile(g, &tiler());
        let seen = barriers_of(&plan, "conditions");
        assert_eq!(seen.len(), 2, "{plan}");
        assert_eq!(seen[0].hazard, Hazard::ReadAfterWrite);
        assert_eq!(
            seen[0].dst,
            (
                PipelineStages::CONDITIONAL_RENDERING,
                AccessFlags::CONDITIONAL_RENDERING_READ
            )
        );
        // The second copy overwrites the first (WAW) and must wait for the predicate reads.
        assert_eq!(seen[1].hazard, Hazard::WriteAfterWrite);
        assert!(seen[1]
            .src
            .0
            .contains(PipelineStages::CONDITIONAL_RENDERING));
        let usage = plan.resource_by_name("conditions").map(|r| r.usage);
        assert_eq!(
            usage,
            Some(Usage::Buffer(
                BufferUsage::TRANSFER_DST | BufferUsage::CONDITIONAL_RENDERING
            ))
        );
    }

    #[test]
    fn reads_after_reads_need_nothing_more() {
        let mut g = GraphBuilder::new();
        let data = g.create_buffer("data", 256);
        let a = g.create_buffer("a", 256);
        let b = g.create_buffer("b", 256);
        g.export(a);
        g.export(b);
        g.compute_pass("produce", PassClass::Compute, ())
            .storage_write(data);
        g.compute_pass("read_a", PassClass::Compute, ())
            .storage_read(data)
            .storage_write(a);
        g.compute_pass("read_b", PassClass::Compute, ())
            .storage_read(data)
            .storage_write(b);
        let plan = compile(g, &tiler());
        let seen = barriers_of(&plan, "data");
        assert_eq!(seen.len(), 1, "{plan}");
        assert_eq!(seen[0].hazard, Hazard::ReadAfterWrite);
    }

    #[test]
    fn write_after_read_is_an_execution_dependency() {
        let mut g = GraphBuilder::new();
        let data = g.create_buffer("data", 256);
        let copy = g.create_buffer("copy", 256);
        g.export(data);
        g.export(copy);
        g.compute_pass("produce", PassClass::Compute, ())
            .storage_write(data);
        g.transfer_pass("snapshot", PassClass::Transfer, ())
            .transfer_src(data)
            .transfer_dst(copy);
        g.compute_pass("update", PassClass::Compute, ())
            .storage_read_write(data);
        let plan = compile(g, &tiler());
        let seen = barriers_of(&plan, "data");
        assert_eq!(seen.len(), 2, "{plan}");
        assert_eq!(seen[1].hazard, Hazard::ReadAfterWrite);
        // update reads what produce wrote (already visible to transfer, not to compute) and
        // overwrites what snapshot read.
        assert_eq!(
            seen[1].src.0,
            PipelineStages::COMPUTE_SHADER | PipelineStages::ALL_TRANSFER
        );
        assert_eq!(seen[1].src.1, AccessFlags::SHADER_STORAGE_WRITE);

        let mut g = GraphBuilder::new();
        let data = g.create_buffer("data", 256);
        let copy = g.create_buffer("copy", 256);
        g.export(data);
        g.export(copy);
        g.compute_pass("produce", PassClass::Compute, ())
            .storage_write(data);
        g.transfer_pass("snapshot", PassClass::Transfer, ())
            .transfer_src(data)
            .transfer_dst(copy);
        g.transfer_pass("reset", PassClass::Transfer, ())
            .transfer_dst(data)
            .coverage(Coverage::Full);
        let plan = compile(g, &tiler());
        let seen = barriers_of(&plan, "data");
        // produce's write was made visible to transfer reads, not writes: the barrier orders
        // reset after it (WAW) and after snapshot's read (WAR) at once.
        assert_eq!(seen[1].hazard, Hazard::WriteAfterWrite);
        assert_eq!(
            seen[1].src,
            (
                PipelineStages::COMPUTE_SHADER | PipelineStages::ALL_TRANSFER,
                AccessFlags::SHADER_STORAGE_WRITE
            )
        );
        assert_eq!(seen[1].layouts, None);

        // A read-only history: overwriting it after it was read needs only the read to finish.
        let mut g = GraphBuilder::new();
        let lut = history(&mut g, "lut");
        let out = swapchain(&mut g);
        g.raster_pass("grade", PassClass::Post, ())
            .sampled(lut)
            .color(out)
            .coverage(Coverage::Full);
        g.compute_pass("rebuild_lut", PassClass::Other, ())
            .storage_write(lut)
            .coverage(Coverage::Full);
        g.export(lut);
        let plan = compile(g, &tiler());
        let seen = barriers_of(&plan, "lut");
        assert_eq!(seen[0].hazard, Hazard::LayoutTransition);
        // Waits for this frame's read and for the reads the import declared (last frame's).
        assert_eq!(
            seen[0].src,
            (
                PipelineStages::VERTEX_SHADER
                    | PipelineStages::FRAGMENT_SHADER
                    | PipelineStages::COMPUTE_SHADER,
                AccessFlags::NONE
            )
        );
        // Its old content is not needed: the transition starts from Undefined.
        assert_eq!(seen[0].layouts, Some((Layout::Undefined, Layout::General)));
    }

    #[test]
    fn layout_changes_between_passes_are_barriers_and_inside_render_passes_are_dependencies() {
        let mut g = GraphBuilder::new();
        let color = rgba8(&mut g, "color");
        let out = swapchain(&mut g);
        g.raster_pass("opaque", PassClass::Opaque, ())
            .color_clear(color, ClearColor::BLACK);
        g.raster_pass("post", PassClass::Post, ())
            .sampled(color)
            .color(out)
            .coverage(Coverage::Full);
        let plan = compile(g, &tiler());
        let seen = barriers_of(&plan, "color");
        assert_eq!(seen.len(), 1);
        assert_eq!(seen[0].hazard, Hazard::LayoutTransition);
        assert_eq!(
            seen[0].layouts,
            Some((Layout::ColorAttachment, Layout::ShaderReadOnly))
        );
        // Nothing touched it before its render pass: the render pass starts from Undefined.
        assert_eq!(attachment(&plan, "color").initial_layout, Layout::Undefined);
        // The swapchain: acquired (wait at colour output), then released for presentation.
        let swap = barriers_of(&plan, "swapchain");
        assert_eq!(swap.len(), 2);
        assert_eq!(
            swap[0].layouts,
            Some((Layout::Undefined, Layout::ColorAttachment))
        );
        assert_eq!(swap[0].src.0, PipelineStages::COLOR_ATTACHMENT_OUTPUT);
        assert_eq!(swap[1].hazard, Hazard::Release);
        assert_eq!(
            swap[1].layouts,
            Some((Layout::ColorAttachment, Layout::Present))
        );
    }

    #[test]
    fn imported_history_starts_from_its_state_and_created_exports_report_theirs() {
        let mut g = GraphBuilder::new();
        let prev = history(&mut g, "history");
        let next = rgba8(&mut g, "next_history");
        g.export(next);
        g.raster_pass("taa", PassClass::Post, ())
            .sampled(prev)
            .color(next)
            .coverage(Coverage::Full);
        g.raster_pass("accumulate", PassClass::Post, ()).color(prev);
        g.export(prev);
        let plan = compile(g, &tiler());
        let seen = barriers_of(&plan, "history");
        // Written after being sampled (WAR + layout), then left in its requested final state.
        assert_eq!(
            seen.iter()
                .map(|b| (b.hazard, b.layouts))
                .collect::<Vec<_>>(),
            [
                (
                    Hazard::LayoutTransition,
                    Some((Layout::ShaderReadOnly, Layout::ColorAttachment))
                ),
                (
                    Hazard::Release,
                    Some((Layout::ColorAttachment, Layout::ShaderReadOnly))
                ),
            ]
        );
        assert_eq!(attachment(&plan, "history").load_op, LoadOp::Load);
        let next = plan.resource_by_name("next_history").map(|r| r.final_state);
        assert_eq!(
            next,
            Some(ResourceState::image(
                Layout::ColorAttachment,
                PipelineStages::COLOR_ATTACHMENT_OUTPUT,
                AccessFlags::COLOR_ATTACHMENT_WRITE
            ))
        );
        assert_eq!(
            plan.resource_by_name("next_history").map(|r| r.residency),
            Some(Residency::Exported)
        );
    }

    #[test]
    fn readback_is_released_to_the_host() {
        let mut g = GraphBuilder::new();
        let counters = g.create_buffer("counters", 64);
        let readback = g.import_buffer(
            "readback",
            64,
            Import {
                initial: ResourceState::UNDEFINED,
                content: InitialContent::Discard,
                final_state: ResourceState::HOST_READ,
            },
        );
        g.export(readback);
        g.compute_pass("count", PassClass::Compute, ())
            .storage_write(counters)
            .coverage(Coverage::Full);
        g.transfer_pass("copy", PassClass::Transfer, ())
            .transfer_src(counters)
            .transfer_dst(readback)
            .coverage(Coverage::Full);
        let plan = compile(g, &tiler());
        let seen = barriers_of(&plan, "readback");
        assert_eq!(seen.len(), 1);
        assert_eq!(seen[0].hazard, Hazard::Release);
        assert_eq!(
            seen[0].src,
            (PipelineStages::ALL_TRANSFER, AccessFlags::TRANSFER_WRITE)
        );
        assert_eq!(seen[0].dst, (PipelineStages::HOST, AccessFlags::HOST_READ));
    }

    #[test]
    fn memory_taken_over_from_another_resource_waits_for_it() {
        let mut g = GraphBuilder::new();
        let first = rgba8(&mut g, "first");
        let second = rgba8(&mut g, "second");
        let out = swapchain(&mut g);
        g.raster_pass("draw_first", PassClass::Opaque, ())
            .color_clear(first, ClearColor::BLACK);
        g.raster_pass("use_first", PassClass::Post, ())
            .sampled(first)
            .color(out)
            .coverage(Coverage::Full);
        g.raster_pass("draw_second", PassClass::Post, ())
            .color_clear(second, ClearColor::BLACK);
        g.raster_pass("use_second", PassClass::Post, ())
            .sampled(second)
            .color(out);
        let plan = compile(g, &desktop());
        let slot = |name| plan.resource_by_name(name).and_then(|r| r.memory);
        assert_eq!(
            slot("first").map(|s| s.block),
            slot("second").map(|s| s.block)
        );
        assert_eq!(plan.aliasing.saved_bytes(), PIXELS * 4);
        let seen = barriers_of(&plan, "second");
        assert_eq!(seen[0].hazard, Hazard::Aliasing);
        // first was last sampled: the new owner's transition waits for those reads.
        assert_eq!(
            seen[0].src,
            (
                PipelineStages::VERTEX_SHADER | PipelineStages::FRAGMENT_SHADER,
                AccessFlags::NONE
            )
        );
        assert_eq!(
            seen[0].layouts,
            Some((Layout::Undefined, Layout::ColorAttachment))
        );
        assert_eq!(
            attachment(&plan, "second").initial_layout,
            Layout::ColorAttachment
        );
    }
}
