//! Phase 7, `plan_barriers`: synchronization2 barriers and layout transitions between steps,
//! only where a hazard exists.
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

use crate::alias::AliasAssignment;
use crate::declare::{Import, InitialContent, PassId, ResourceId, ResourceState};
use crate::plan::{
    BarrierBatch, BufferBarrier, Hazard, ImageBarrier, RenderPass, Step, StepIndex, StepRange,
};
use crate::types::{AccessFlags, Layout, LoadOp, PipelineStages};

use super::access::{Access, DEPTH_TESTS};

/// Per-pass accesses, indexed by `PassId`.
pub(crate) struct PassAccesses<'a> {
    pub accesses: &'a [Access],
    pub ranges: &'a [(u32, u32)],
}

impl PassAccesses<'_> {
    pub fn of(&self, pass: PassId) -> &[Access] {
        match self.ranges.get(pass.index()) {
            Some(&(start, end)) => &self.accesses[start as usize..end as usize],
            None => &[],
        }
    }
}

/// What the barrier planner needs to know about a resource.
#[derive(Debug, Clone, Copy)]
pub(crate) struct ResourceSync {
    pub is_image: bool,
    pub is_depth: bool,
    pub import: Option<Import>,
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
#[derive(Debug, Clone, Copy)]
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
            reads: a.reads_prior || a.explicit_read,
            writes: a.writes,
            discard: a.writes && !a.reads_prior,
        }
    }
}

#[derive(Debug, Clone, Copy)]
struct BarrierParts {
    src_stages: PipelineStages,
    src_access: AccessFlags,
    dst_stages: PipelineStages,
    dst_access: AccessFlags,
    old_layout: Layout,
    new_layout: Layout,
    hazard: Hazard,
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

fn push_barrier(batch: &mut BarrierBatch, resource: usize, is_image: bool, b: BarrierParts) {
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
        });
    } else {
        batch.buffers.push(BufferBarrier {
            resource,
            src_stages: b.src_stages,
            src_access: b.src_access,
            dst_stages: b.dst_stages,
            dst_access: b.dst_access,
            hazard: b.hazard,
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

pub(crate) struct BarrierPlan {
    pub steps: Vec<Step>,
    /// The state each resource is left in (imported: their final state).
    pub final_states: Vec<ResourceState>,
}

const NONE: u32 = u32::MAX;

/// An attachment's accesses over all subpasses of its render pass.
#[derive(Debug, Clone, Copy)]
struct AttachmentUse {
    first: Option<Access>,
    stages: PipelineStages,
    access: AccessFlags,
}

struct Planner<'a> {
    resources: &'a [ResourceSync],
    aliasing: &'a AliasAssignment,
    states: Vec<SyncState>,
    /// The next barrier of this resource is its aliasing handoff.
    alias_pending: Vec<bool>,
    /// Scratch, per resource: its attachment in the current render pass, or its entry in
    /// `others`, or `NONE`.
    slot: Vec<u32>,
    attachment_uses: Vec<AttachmentUse>,
    others: Vec<(usize, SyncUse)>,
}

impl Planner<'_> {
    /// First touch: fold in the memory predecessors' last accesses.
    fn touch(&mut self, r: usize) {
        if self.states[r].touched {
            return;
        }
        self.states[r].touched = true;
        let mut any = false;
        let mut stages = PipelineStages::NONE;
        let mut access = AccessFlags::NONE;
        for pred in self.aliasing.predecessors(ResourceId(r as u32)) {
            if let Some(p) = self.states.get(pred.index()) {
                stages |= p.write_stages | p.read_stages;
                access |= p.write_access.writes();
                any = true;
            }
        }
        if any {
            let st = &mut self.states[r];
            st.write_stages |= stages;
            st.write_access |= access;
            self.alias_pending[r] = true;
        }
    }

    fn barrier(&mut self, r: usize, u: &SyncUse, batch: &mut BarrierBatch) {
        let is_image = self.resources[r].is_image;
        if let Some(mut parts) = sync(&mut self.states[r], u, is_image) {
            if std::mem::take(&mut self.alias_pending[r]) {
                parts.hazard = Hazard::Aliasing;
            }
            push_barrier(batch, r, is_image, parts);
        }
    }

    fn render_pass(
        &mut self,
        rp: &mut RenderPass,
        accesses: &PassAccesses<'_>,
        batch: &mut BarrierBatch,
    ) {
        // Gather every subpass's accesses in one sweep: per attachment, and per other resource.
        self.attachment_uses.clear();
        self.others.clear();
        for (i, att) in rp.attachments.iter().enumerate() {
            self.slot[att.resource.index()] = i as u32;
            self.attachment_uses.push(AttachmentUse {
                first: None,
                stages: PipelineStages::NONE,
                access: AccessFlags::NONE,
            });
        }
        let n_attachments = rp.attachments.len() as u32;
        for s in &rp.subpasses {
            for a in accesses.of(s.pass) {
                let r = a.resource.index();
                let slot = self.slot[r];
                let u = SyncUse::of(a);
                if slot == NONE {
                    self.slot[r] = n_attachments + self.others.len() as u32;
                    self.others.push((r, u));
                } else if slot < n_attachments {
                    let au = &mut self.attachment_uses[slot as usize];
                    au.first.get_or_insert(*a);
                    au.stages |= a.stages;
                    au.access |= a.access;
                } else {
                    let (_, o) = &mut self.others[(slot - n_attachments) as usize];
                    o.stages |= u.stages;
                    o.access |= u.access;
                    o.reads |= u.reads;
                    o.writes |= u.writes;
                }
            }
        }

        for (i, att) in rp.attachments.iter_mut().enumerate() {
            let r = att.resource.index();
            self.touch(r);
            let au = self.attachment_uses[i];
            let Some(first) = au.first else { continue };
            let is_depth = self.resources[r].is_depth;
            let (load_stages, load_access, _) = load_store_access(is_depth, att.load_op);
            let loads = att.load_op == LoadOp::Load;
            // Later subpasses are ordered by subpass dependencies, but the barrier before the
            // render pass covers every stage that touches the attachment in it (a sampled
            // read of a read-only depth attachment, say).
            let u = SyncUse {
                stages: au.stages | load_stages,
                access: au.access | load_access,
                layout: first.layout,
                reads: loads,
                writes: !loads || first.writes,
                discard: !loads,
            };
            if self.states[r].is_fresh() && !loads && !self.alias_pending[r] {
                // Nothing to wait for: the render pass transitions from Undefined itself.
                att.initial_layout = Layout::Undefined;
            } else {
                self.barrier(r, &u, batch);
                att.initial_layout = self.states[r].layout;
            }
        }
        for k in 0..self.others.len() {
            let (r, u) = self.others[k];
            self.touch(r);
            self.barrier(r, &u, batch);
        }

        // After the render pass: every attachment was written by its store op.
        for (i, att) in rp.attachments.iter().enumerate() {
            let r = att.resource.index();
            self.slot[r] = NONE;
            let is_depth = self.resources[r].is_depth;
            let (store_stages, _, store_access) = load_store_access(is_depth, att.load_op);
            let au = self.attachment_uses[i];
            let st = &mut self.states[r];
            st.layout = att.final_layout;
            st.write_stages = au.stages | store_stages;
            st.write_access = au.access.writes() | store_access;
            st.read_stages = PipelineStages::NONE;
            st.visible_stages = PipelineStages::NONE;
            st.visible_access = AccessFlags::NONE;
        }
        for k in 0..self.others.len() {
            let (r, u) = self.others[k];
            self.slot[r] = NONE;
            let is_image = self.resources[r].is_image;
            self.states[r].apply(&u, is_image);
        }
    }

    fn single_pass(&mut self, pass: PassId, accesses: &PassAccesses<'_>, batch: &mut BarrierBatch) {
        let list = accesses.of(pass);
        for a in list {
            let r = a.resource.index();
            self.touch(r);
            self.barrier(r, &SyncUse::of(a), batch);
        }
        for a in list {
            let r = a.resource.index();
            let is_image = self.resources[r].is_image;
            self.states[r].apply(&SyncUse::of(a), is_image);
        }
    }
}

/// Inserts barrier batches between the work steps (and after the last one, releasing imported
/// resources), and fills in each render pass's initial layouts.
pub(crate) fn plan_barriers(
    work: Vec<Step>,
    accesses: &PassAccesses<'_>,
    resources: &[ResourceSync],
    aliasing: &AliasAssignment,
) -> BarrierPlan {
    let mut planner = Planner {
        resources,
        aliasing,
        states: resources.iter().map(SyncState::initial).collect(),
        alias_pending: vec![false; resources.len()],
        slot: vec![NONE; resources.len()],
        attachment_uses: Vec::new(),
        others: Vec::new(),
    };
    let mut steps = Vec::with_capacity(work.len() * 2 + 1);
    for mut step in work {
        let mut batch = BarrierBatch::default();
        match &mut step {
            Step::RenderPass(rp) => planner.render_pass(rp, accesses, &mut batch),
            Step::Compute { pass } | Step::Transfer { pass } => {
                planner.single_pass(*pass, accesses, &mut batch)
            }
            Step::Flush(_) | Step::Barriers(_) => {}
        }
        if !batch.is_empty() {
            steps.push(Step::Barriers(batch));
        }
        steps.push(step);
    }

    // Leave imported resources as their import asks; the rest as their last use left them.
    let mut batch = BarrierBatch::default();
    let mut final_states = Vec::with_capacity(resources.len());
    for (r, res) in resources.iter().enumerate() {
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
            // No layout asked for: keep the current one (a transition to Undefined is invalid).
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
            push_barrier(&mut batch, r, res.is_image, parts);
        }
        final_states.push(fin);
    }
    if !batch.is_empty() {
        steps.push(Step::Barriers(batch));
    }
    BarrierPlan {
        steps,
        final_states,
    }
}

/// First and last work step using each resource.
pub(crate) fn step_lifetimes(
    steps: &[Step],
    accesses: &PassAccesses<'_>,
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
