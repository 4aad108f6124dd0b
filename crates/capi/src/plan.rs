//! A compiled plan, walked from C: its steps in recording order, each render pass's
//! attachments (load/store ops, layouts, residency) and subpasses, each barrier, and the
//! submissions that cut the steps between the graphics and the async compute queue (what to
//! submit where, what each waits on, which ownership releases end it).

use std::ffi::{c_char, CString};

use tilegraph_graph::{BarrierBatch, Plan, Queue, QueueTransfer, Residency, Step};

use crate::registry::{self, Kind};
use crate::status::{boundary, out, Failure, TgStatus};

/// A compiled plan.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TgPlan {
    pub raw: u64,
}

/// What a plan step records.
#[repr(u32)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TgStepKind {
    /// One vkCmdPipelineBarrier2 with `barrier_count` barriers.
    Barriers = 0,
    /// One render pass with `subpass_count` subpasses and `attachment_count` attachments.
    RenderPass = 1,
    /// The compute pass `pass` records its dispatches.
    Compute = 2,
    /// The transfer pass `pass` records its copies.
    Transfer = 3,
    /// Submit what was recorded so far (Adreno: before the occlusion-query render pass).
    Flush = 4,
}

/// Where an attachment's memory lives.
#[repr(u32)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TgResidency {
    /// The caller's image.
    Imported = 0,
    /// Created by the graph and kept after the frame.
    Exported = 1,
    /// Created for the frame; may share memory with resources not alive at the same time.
    FrameLocal = 2,
    /// Never leaves tile memory: TRANSIENT_ATTACHMENT, lazily allocated memory.
    Transient = 3,
    /// No pass the plan kept uses it: nothing is allocated.
    Unused = 4,
}

/// A plan's overview.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default)]
pub struct TgPlanSummary {
    pub step_count: u32,
    pub render_pass_count: u32,
    pub barrier_count: u32,
    /// Passes kept, and passes pruned (they contribute to no exported or imported resource).
    pub pass_count: u32,
    pub pruned_count: u32,
    /// Attachments that never leave tile memory.
    pub transient_count: u32,
    /// Estimated attachment memory traffic per frame, bytes (loads + stores + resolves).
    pub attachment_traffic_bytes: u64,
    /// The same estimate with every raster pass alone, loading and storing everything.
    pub naive_attachment_traffic_bytes: u64,
    /// Submissions (`tg_plan_submission`): 1 unless passes run on the async compute queue.
    pub submission_count: u32,
}

/// The queue a submission goes to.
#[repr(u32)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TgQueue {
    /// The queue the frame's raster work runs on (graphics and compute).
    Graphics = 0,
    /// A second queue for passes declared async-capable (`tg_pass_async_compute`): of a
    /// compute-only family where the device has one.
    AsyncCompute = 1,
}

/// An ownership transfer a barrier makes between the two queues' families (exclusive
/// sharing; with one family, record the barrier without it).
#[repr(u32)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TgQueueTransfer {
    None = 0,
    GraphicsToAsyncCompute = 1,
    AsyncComputeToGraphics = 2,
}

/// Steps `first_step..end_step` submitted to one queue: record them into a command buffer of
/// that queue, then the `release_count` ownership releases (`tg_plan_submission_release`);
/// submit after waiting on the `wait_count` waits (`tg_plan_submission_wait`), and signal
/// (a timeline value per queue) what later submissions wait on. The first submission is empty
/// and on the graphics queue (the async queue's first wait), the last is on the graphics queue.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default)]
pub struct TgSubmission {
    /// A TgQueue.
    pub queue: u32,
    pub first_step: u32,
    pub end_step: u32,
    pub wait_count: u32,
    pub release_count: u32,
}

/// One wait of a submission: on submission `submission` of the other queue (its signal), at
/// `dst_stages` (VkPipelineStageFlags2) of this one.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default)]
pub struct TgQueueWait {
    pub submission: u32,
    pub dst_stages: u64,
}

/// One step of the plan.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default)]
pub struct TgStep {
    /// A TgStepKind.
    pub kind: u32,
    /// The pass (compute, transfer) or the first subpass's pass (render pass).
    pub pass: u32,
    pub barrier_count: u32,
    pub subpass_count: u32,
    pub attachment_count: u32,
    pub render_area_width: u32,
    pub render_area_height: u32,
}

/// One attachment of a render-pass step.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default)]
pub struct TgAttachment {
    /// The resource id the declaration returned.
    pub resource: u32,
    /// VkFormat.
    pub format: i32,
    /// VkAttachmentLoadOp, VkAttachmentStoreOp (STORE_OP_NONE where the profile has it).
    pub load_op: i32,
    pub store_op: i32,
    pub stencil_load_op: i32,
    pub stencil_store_op: i32,
    /// VkImageLayout at the render pass's start and end.
    pub initial_layout: i32,
    pub final_layout: i32,
    /// A TgResidency.
    pub residency: u32,
}

/// One subpass of a render-pass step.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default)]
pub struct TgSubpass {
    /// The pass whose commands the subpass records.
    pub pass: u32,
    pub color_count: u32,
    pub input_count: u32,
    /// The depth attachment's index in the render pass, or -1.
    pub depth_attachment: i32,
}

/// One barrier of a barrier step (synchronization2 values).
#[repr(C)]
#[derive(Debug, Clone, Copy, Default)]
pub struct TgBarrier {
    pub resource: u32,
    /// Non-zero: an image barrier (the layouts apply); zero: a buffer barrier.
    pub is_image: u32,
    pub src_stages: u64,
    pub src_access: u64,
    pub dst_stages: u64,
    pub dst_access: u64,
    pub old_layout: i32,
    pub new_layout: i32,
    /// A TgQueueTransfer: the acquire half (in a barrier step) or the release half (a
    /// submission's releases) of an ownership transfer.
    pub queue_transfer: u32,
}

pub(crate) struct PlanObject {
    plan: Plan,
    names: Vec<CString>,
}

impl PlanObject {
    pub(crate) fn new(plan: Plan) -> Self {
        let names = plan
            .passes
            .iter()
            .map(|p| CString::new(p.name.replace('\0', " ")).unwrap_or_default())
            .collect();
        PlanObject { plan, names }
    }
}

/// Destroys a plan. A zero handle is a no-op.
#[no_mangle]
pub extern "C" fn tg_plan_destroy(plan: TgPlan) -> TgStatus {
    boundary("tg_plan_destroy", || {
        if plan.raw == 0 {
            return Ok(());
        }
        registry::remove::<PlanObject>(plan.raw, Kind::Plan, "plan").map(drop)
    })
}

fn on_plan<R>(
    plan: TgPlan,
    f: impl FnOnce(&PlanObject) -> Result<R, Failure>,
) -> Result<R, Failure> {
    registry::with(plan.raw, Kind::Plan, "plan", f)
}

/// The plan's counts and traffic estimate.
///
/// # Safety
/// `out_summary` is writable.
#[no_mangle]
pub unsafe extern "C" fn tg_plan_summary(
    plan: TgPlan,
    out_summary: *mut TgPlanSummary,
) -> TgStatus {
    boundary("tg_plan_summary", || {
        // SAFETY: the caller's contract.
        let out_summary = unsafe { out(out_summary, "out_summary") }?;
        on_plan(plan, |p| {
            let p = &p.plan;
            let attachments = |b: &tilegraph_graph::TrafficBreakdown| {
                b.attachment_read_bytes + b.attachment_write_bytes + b.resolve_write_bytes
            };
            *out_summary = TgPlanSummary {
                step_count: p.steps.len() as u32,
                render_pass_count: p.render_passes().count() as u32,
                barrier_count: p.barrier_count() as u32,
                pass_count: p.passes.len() as u32,
                pruned_count: p.pruned.len() as u32,
                transient_count: p
                    .resources
                    .iter()
                    .filter(|r| r.residency == Residency::Transient)
                    .count() as u32,
                attachment_traffic_bytes: attachments(&p.traffic.planned),
                naive_attachment_traffic_bytes: attachments(&p.traffic.naive),
                submission_count: p.submissions.len() as u32,
            };
            Ok(())
        })
    })
}

fn step(p: &Plan, index: u32) -> Result<&Step, Failure> {
    p.steps.get(index as usize).ok_or_else(|| {
        Failure::invalid(format!(
            "step {index} is past the plan's {} steps",
            p.steps.len()
        ))
    })
}

/// Step `index` of the plan, in recording order.
///
/// # Safety
/// `out_step` is writable.
#[no_mangle]
pub unsafe extern "C" fn tg_plan_step(plan: TgPlan, index: u32, out_step: *mut TgStep) -> TgStatus {
    boundary("tg_plan_step", || {
        // SAFETY: the caller's contract.
        let out_step = unsafe { out(out_step, "out_step") }?;
        on_plan(plan, |p| {
            let mut s = TgStep::default();
            match step(&p.plan, index)? {
                Step::Barriers(b) => {
                    s.kind = TgStepKind::Barriers as u32;
                    s.barrier_count = b.len() as u32;
                }
                Step::RenderPass(rp) => {
                    s.kind = TgStepKind::RenderPass as u32;
                    s.pass = rp.subpasses.first().map_or(0, |sp| sp.pass.0);
                    s.subpass_count = rp.subpasses.len() as u32;
                    s.attachment_count = rp.attachments.len() as u32;
                    s.render_area_width = rp.render_area_px.width_px;
                    s.render_area_height = rp.render_area_px.height_px;
                }
                Step::Compute { pass } => {
                    s.kind = TgStepKind::Compute as u32;
                    s.pass = pass.0;
                }
                Step::Transfer { pass } => {
                    s.kind = TgStepKind::Transfer as u32;
                    s.pass = pass.0;
                }
                Step::Flush(_) => s.kind = TgStepKind::Flush as u32,
            }
            *out_step = s;
            Ok(())
        })
    })
}

fn render_pass(p: &Plan, index: u32) -> Result<&tilegraph_graph::RenderPass, Failure> {
    match step(p, index)? {
        Step::RenderPass(rp) => Ok(rp),
        other => Err(Failure::invalid(format!(
            "step {index} is a {} step, not a render pass",
            other.name()
        ))),
    }
}

/// Attachment `attachment` of render-pass step `step_index`.
///
/// # Safety
/// `out_attachment` is writable.
#[no_mangle]
pub unsafe extern "C" fn tg_plan_attachment(
    plan: TgPlan,
    step_index: u32,
    attachment: u32,
    out_attachment: *mut TgAttachment,
) -> TgStatus {
    boundary("tg_plan_attachment", || {
        // SAFETY: the caller's contract.
        let out_attachment = unsafe { out(out_attachment, "out_attachment") }?;
        on_plan(plan, |p| {
            let rp = render_pass(&p.plan, step_index)?;
            let a = rp.attachments.get(attachment as usize).ok_or_else(|| {
                Failure::invalid(format!(
                    "attachment {attachment} is past the render pass's {}",
                    rp.attachments.len()
                ))
            })?;
            *out_attachment = TgAttachment {
                resource: a.resource.0,
                format: a.format.vk_raw(),
                load_op: a.load_op.vk_raw(),
                store_op: a.store_op.vk_raw(),
                stencil_load_op: a.stencil_load_op.vk_raw(),
                stencil_store_op: a.stencil_store_op.vk_raw(),
                initial_layout: a.initial_layout.vk_raw(),
                final_layout: a.final_layout.vk_raw(),
                residency: match a.residency {
                    Residency::Imported => TgResidency::Imported,
                    Residency::Exported => TgResidency::Exported,
                    Residency::FrameLocal => TgResidency::FrameLocal,
                    Residency::Transient => TgResidency::Transient,
                    Residency::Unused => TgResidency::Unused,
                } as u32,
            };
            Ok(())
        })
    })
}

/// Subpass `subpass` of render-pass step `step_index`.
///
/// # Safety
/// `out_subpass` is writable.
#[no_mangle]
pub unsafe extern "C" fn tg_plan_subpass(
    plan: TgPlan,
    step_index: u32,
    subpass: u32,
    out_subpass: *mut TgSubpass,
) -> TgStatus {
    boundary("tg_plan_subpass", || {
        // SAFETY: the caller's contract.
        let out_subpass = unsafe { out(out_subpass, "out_subpass") }?;
        on_plan(plan, |p| {
            let rp = render_pass(&p.plan, step_index)?;
            let s = rp.subpasses.get(subpass as usize).ok_or_else(|| {
                Failure::invalid(format!(
                    "subpass {subpass} is past the render pass's {}",
                    rp.subpasses.len()
                ))
            })?;
            *out_subpass = TgSubpass {
                pass: s.pass.0,
                color_count: s.colors.len() as u32,
                input_count: s.inputs.len() as u32,
                depth_attachment: s.depth_stencil.map_or(-1, |d| d.attachment.0 as i32),
            };
            Ok(())
        })
    })
}

/// Barrier `barrier` of barrier step `step_index` (images first, then buffers).
///
/// # Safety
/// `out_barrier` is writable.
#[no_mangle]
pub unsafe extern "C" fn tg_plan_barrier(
    plan: TgPlan,
    step_index: u32,
    barrier: u32,
    out_barrier: *mut TgBarrier,
) -> TgStatus {
    boundary("tg_plan_barrier", || {
        // SAFETY: the caller's contract.
        let out_barrier = unsafe { out(out_barrier, "out_barrier") }?;
        on_plan(plan, |p| {
            let Step::Barriers(batch) = step(&p.plan, step_index)? else {
                return Err(Failure::invalid(format!(
                    "step {step_index} is no barrier step"
                )));
            };
            let b = barrier_of(batch, barrier).ok_or_else(|| {
                Failure::invalid(format!(
                    "barrier {barrier} is past the step's {}",
                    batch.len()
                ))
            })?;
            *out_barrier = b;
            Ok(())
        })
    })
}

/// The name of pass `pass` (an id `tg_graph_add_pass` returned) if the plan kept it; the
/// string lives as long as the plan.
///
/// # Safety
/// `out_name` is writable.
#[no_mangle]
pub unsafe extern "C" fn tg_plan_pass_name(
    plan: TgPlan,
    pass: u32,
    out_name: *mut *const c_char,
) -> TgStatus {
    boundary("tg_plan_pass_name", || {
        // SAFETY: the caller's contract.
        let out_name = unsafe { out(out_name, "out_name") }?;
        on_plan(plan, |p| {
            let i = p
                .plan
                .passes
                .iter()
                .position(|planned| planned.id.0 == pass)
                .ok_or_else(|| {
                    Failure::invalid(format!(
                        "pass {pass} is not in the plan (pruned, or no such pass)"
                    ))
                })?;
            *out_name = p.names[i].as_ptr();
            Ok(())
        })
    })
}

fn transfer_of(t: Option<QueueTransfer>) -> u32 {
    match t {
        None => TgQueueTransfer::None as u32,
        Some(QueueTransfer {
            to: Queue::AsyncCompute,
            ..
        }) => TgQueueTransfer::GraphicsToAsyncCompute as u32,
        Some(QueueTransfer {
            to: Queue::Graphics,
            ..
        }) => TgQueueTransfer::AsyncComputeToGraphics as u32,
    }
}

/// Barrier `index` of `batch` (images first, then buffers).
fn barrier_of(batch: &BarrierBatch, index: u32) -> Option<TgBarrier> {
    let i = index as usize;
    if let Some(b) = batch.images.get(i) {
        return Some(TgBarrier {
            resource: b.resource.0,
            is_image: 1,
            src_stages: b.src_stages.bits(),
            src_access: b.src_access.bits(),
            dst_stages: b.dst_stages.bits(),
            dst_access: b.dst_access.bits(),
            old_layout: b.old_layout.vk_raw(),
            new_layout: b.new_layout.vk_raw(),
            queue_transfer: transfer_of(b.queue_transfer),
        });
    }
    let b = batch.buffers.get(i.checked_sub(batch.images.len())?)?;
    Some(TgBarrier {
        resource: b.resource.0,
        is_image: 0,
        src_stages: b.src_stages.bits(),
        src_access: b.src_access.bits(),
        dst_stages: b.dst_stages.bits(),
        dst_access: b.dst_access.bits(),
        old_layout: 0,
        new_layout: 0,
        queue_transfer: transfer_of(b.queue_transfer),
    })
}

fn submission(p: &Plan, index: u32) -> Result<&tilegraph_graph::Submission, Failure> {
    p.submissions.get(index as usize).ok_or_else(|| {
        Failure::invalid(format!(
            "submission {index} is past the plan's {} submissions",
            p.submissions.len()
        ))
    })
}

/// Submission `index` of the plan, in submission order.
///
/// # Safety
/// `out_submission` is writable.
#[no_mangle]
pub unsafe extern "C" fn tg_plan_submission(
    plan: TgPlan,
    index: u32,
    out_submission: *mut TgSubmission,
) -> TgStatus {
    boundary("tg_plan_submission", || {
        // SAFETY: the caller's contract.
        let out_submission = unsafe { out(out_submission, "out_submission") }?;
        on_plan(plan, |p| {
            let s = submission(&p.plan, index)?;
            *out_submission = TgSubmission {
                queue: match s.queue {
                    Queue::Graphics => TgQueue::Graphics as u32,
                    Queue::AsyncCompute => TgQueue::AsyncCompute as u32,
                },
                first_step: s.first.0,
                end_step: s.end.0,
                wait_count: s.waits.len() as u32,
                release_count: s.releases.len() as u32,
            };
            Ok(())
        })
    })
}

/// Wait `wait` of submission `index`.
///
/// # Safety
/// `out_wait` is writable.
#[no_mangle]
pub unsafe extern "C" fn tg_plan_submission_wait(
    plan: TgPlan,
    index: u32,
    wait: u32,
    out_wait: *mut TgQueueWait,
) -> TgStatus {
    boundary("tg_plan_submission_wait", || {
        // SAFETY: the caller's contract.
        let out_wait = unsafe { out(out_wait, "out_wait") }?;
        on_plan(plan, |p| {
            let s = submission(&p.plan, index)?;
            let w = s.waits.get(wait as usize).ok_or_else(|| {
                Failure::invalid(format!(
                    "wait {wait} is past submission {index}'s {}",
                    s.waits.len()
                ))
            })?;
            *out_wait = TgQueueWait {
                submission: w.submission.0,
                dst_stages: w.dst_stages.bits(),
            };
            Ok(())
        })
    })
}

/// Ownership release `release` recorded at the end of submission `index` (images first, then
/// buffers): the release half of a transfer whose acquire half is a barrier of a later
/// submission on the other queue.
///
/// # Safety
/// `out_barrier` is writable.
#[no_mangle]
pub unsafe extern "C" fn tg_plan_submission_release(
    plan: TgPlan,
    index: u32,
    release: u32,
    out_barrier: *mut TgBarrier,
) -> TgStatus {
    boundary("tg_plan_submission_release", || {
        // SAFETY: the caller's contract.
        let out_barrier = unsafe { out(out_barrier, "out_barrier") }?;
        on_plan(plan, |p| {
            let s = submission(&p.plan, index)?;
            *out_barrier = barrier_of(&s.releases, release).ok_or_else(|| {
                Failure::invalid(format!(
                    "release {release} is past submission {index}'s {}",
                    s.releases.len()
                ))
            })?;
            Ok(())
        })
    })
}
