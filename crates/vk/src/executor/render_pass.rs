//! Render-pass objects: a `VkRenderPass2` per render pass of the plan (attachments with their
//! load/store ops, subpasses, the plan's subpass dependencies as `VkMemoryBarrier2`s), and the
//! framebuffers over the views each frame brings, both cached per step of the plan.

use std::sync::atomic::{AtomicU64, Ordering};

use ash::vk;
use tilegraph_graph::{Attachment, ClearColor, ClearValue, RenderPass};

use super::resources::aspect_of;
use super::sync::{earlier_work, external_dependency, first_subpasses_of_undefined_attachments};
use crate::error::{VkError, VkResultExt};
use crate::Context;

/// The render pass and subpass a raster pass records into.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct RenderPassRef {
    pub handle: vk::RenderPass,
    pub subpass: u32,
    /// Unique to this `VkRenderPass` among all that this process creates. The executor destroys
    /// its render passes when the plan changes, and a driver may hand the same handle value to
    /// the next one, which need not be compatible: key pipeline caches on the serial, never on
    /// the handle. Render passes of the current plan have serials of at least
    /// [`Executor::render_pass_serial_floor`].
    pub serial: u64,
}

/// The next render pass's serial (never 0, never reused).
static NEXT_RENDER_PASS_SERIAL: AtomicU64 = AtomicU64::new(1);

/// Render pass objects and framebuffers of one plan, by step index.
#[derive(Default)]
pub(super) struct RenderPasses {
    /// Per step: the render pass and its serial.
    passes: Vec<Option<(vk::RenderPass, u64)>>,
    /// Per step: a framebuffer per set of attachment views (one, or one per swapchain image).
    framebuffers: Vec<Vec<(Vec<vk::ImageView>, vk::Framebuffer)>>,
}

impl RenderPasses {
    /// The render pass of step `step` (created on first use) and its serial.
    pub fn render_pass(
        &mut self,
        ctx: &Context,
        step: usize,
        plan_rp: &RenderPass,
        name: &str,
    ) -> Result<(vk::RenderPass, u64), VkError> {
        if let Some(Some(r)) = self.passes.get(step) {
            return Ok(*r);
        }
        let raw = create_render_pass(ctx, plan_rp, name)?;
        let serial = NEXT_RENDER_PASS_SERIAL.fetch_add(1, Ordering::Relaxed);
        if self.passes.len() <= step {
            self.passes.resize(step + 1, None);
        }
        self.passes[step] = Some((raw, serial));
        Ok((raw, serial))
    }

    /// The framebuffer of step `step` over `views` (created on first use).
    pub fn framebuffer(
        &mut self,
        ctx: &Context,
        step: usize,
        render_pass: vk::RenderPass,
        views: &[vk::ImageView],
        extent: vk::Extent2D,
    ) -> Result<vk::Framebuffer, VkError> {
        if self.framebuffers.len() <= step {
            self.framebuffers.resize_with(step + 1, Vec::new);
        }
        let cached = &mut self.framebuffers[step];
        if let Some((_, fb)) = cached.iter().find(|(v, _)| v == views) {
            return Ok(*fb);
        }
        let info = vk::FramebufferCreateInfo::default()
            .render_pass(render_pass)
            .attachments(views)
            .width(extent.width)
            .height(extent.height)
            .layers(1);
        // SAFETY: views match the render pass's attachments (format, samples, extent: checked by
        // the recorder).
        let fb = unsafe { ctx.device.create_framebuffer(&info, None) }.vk("vkCreateFramebuffer")?;
        cached.push((views.to_vec(), fb));
        Ok(fb)
    }

    pub fn framebuffer_count(&self) -> usize {
        self.framebuffers.iter().map(Vec::len).sum()
    }

    /// Destroys every framebuffer that uses a view `keep` rejects (the caller waited for the
    /// frames that used them).
    pub fn retain_framebuffers(&mut self, ctx: &Context, keep: impl Fn(vk::ImageView) -> bool) {
        for cached in &mut self.framebuffers {
            cached.retain(|(views, fb)| {
                let kept = views.iter().all(|&v| keep(v));
                if !kept {
                    // SAFETY: no frame in flight uses it (caller's guarantee).
                    unsafe { ctx.device.destroy_framebuffer(*fb, None) };
                }
                kept
            });
        }
    }

    pub fn destroy(self, ctx: &Context) {
        // SAFETY: no frame using them is in flight (caller waited).
        unsafe {
            for (_, fb) in self.framebuffers.into_iter().flatten() {
                ctx.device.destroy_framebuffer(fb, None);
            }
            for (rp, _) in self.passes.into_iter().flatten() {
                ctx.device.destroy_render_pass(rp, None);
            }
        }
    }
}

/// Render passes of the current plan have serials of at least this.
pub(super) fn next_serial() -> u64 {
    NEXT_RENDER_PASS_SERIAL.load(Ordering::Relaxed)
}

pub(super) fn create_render_pass(
    ctx: &Context,
    plan_rp: &RenderPass,
    name: &str,
) -> Result<vk::RenderPass, VkError> {
    let attachments: Vec<vk::AttachmentDescription2> = plan_rp
        .attachments
        .iter()
        .map(|a| {
            vk::AttachmentDescription2::default()
                .format(vk::Format::from_raw(a.format.vk_raw()))
                .samples(vk::SampleCountFlags::from_raw(a.samples.vk_bits()))
                .load_op(vk::AttachmentLoadOp::from_raw(a.load_op.vk_raw()))
                .store_op(vk::AttachmentStoreOp::from_raw(a.store_op.vk_raw()))
                .stencil_load_op(vk::AttachmentLoadOp::from_raw(a.stencil_load_op.vk_raw()))
                .stencil_store_op(vk::AttachmentStoreOp::from_raw(a.stencil_store_op.vk_raw()))
                .initial_layout(vk::ImageLayout::from_raw(a.initial_layout.vk_raw()))
                .final_layout(vk::ImageLayout::from_raw(a.final_layout.vk_raw()))
        })
        .collect();
    let aspect = |i: u32| {
        plan_rp
            .attachments
            .get(i as usize)
            .map_or(vk::ImageAspectFlags::COLOR, |a| aspect_of(a.format))
    };
    let to_ref = |r: &tilegraph_graph::AttachmentRef| {
        vk::AttachmentReference2::default()
            .attachment(r.attachment.0)
            .layout(vk::ImageLayout::from_raw(r.layout.vk_raw()))
            .aspect_mask(aspect(r.attachment.0))
    };
    let unused = vk::AttachmentReference2::default().attachment(vk::ATTACHMENT_UNUSED);
    struct Refs<'a> {
        colors: Vec<vk::AttachmentReference2<'a>>,
        resolves: Vec<vk::AttachmentReference2<'a>>,
        depth: Option<vk::AttachmentReference2<'a>>,
        inputs: Vec<vk::AttachmentReference2<'a>>,
        preserve: Vec<u32>,
    }
    let refs: Vec<Refs> = plan_rp
        .subpasses
        .iter()
        .map(|s| Refs {
            colors: s.colors.iter().map(to_ref).collect(),
            resolves: s
                .resolves
                .iter()
                .map(|r| r.as_ref().map_or(unused, to_ref))
                .collect(),
            depth: s.depth_stencil.as_ref().map(to_ref),
            inputs: s.inputs.iter().map(to_ref).collect(),
            preserve: s.preserve.iter().map(|p| p.0).collect(),
        })
        .collect();
    let subpasses: Vec<vk::SubpassDescription2> = refs
        .iter()
        .map(|r| {
            let mut s = vk::SubpassDescription2::default()
                .pipeline_bind_point(vk::PipelineBindPoint::GRAPHICS)
                .color_attachments(&r.colors)
                .input_attachments(&r.inputs)
                .preserve_attachments(&r.preserve);
            if !r.resolves.is_empty() {
                s = s.resolve_attachments(&r.resolves);
            }
            if let Some(dref) = r.depth.as_ref() {
                s = s.depth_stencil_attachment(dref);
            }
            s
        })
        .collect();
    // Barriers between subpasses come from the plan. In synchronization2 style they carry 64-bit
    // masks, chained as VkMemoryBarrier2 on each dependency.
    let mut barriers: Vec<vk::MemoryBarrier2> = plan_rp
        .dependencies
        .iter()
        .map(|dep| {
            vk::MemoryBarrier2::default()
                .src_stage_mask(vk::PipelineStageFlags2::from_raw(dep.src_stages.bits()))
                .src_access_mask(vk::AccessFlags2::from_raw(dep.src_access.bits()))
                .dst_stage_mask(vk::PipelineStageFlags2::from_raw(dep.dst_stages.bits()))
                .dst_access_mask(vk::AccessFlags2::from_raw(dep.dst_access.bits()))
        })
        .collect();
    // Attachments that start undefined were last written by an earlier frame (frames in flight
    // share the memory) or by the caller: see `sync.rs`.
    let external_into = first_subpasses_of_undefined_attachments(plan_rp);
    let earlier = earlier_work(ctx.has_feature(crate::Feature::ConditionalRendering));
    let mut external_barriers: Vec<vk::MemoryBarrier2> = external_into
        .iter()
        .map(|_| external_dependency(earlier))
        .collect();
    let mut dependencies: Vec<vk::SubpassDependency2> = plan_rp
        .dependencies
        .iter()
        .zip(barriers.iter_mut())
        .map(|(dep, barrier)| {
            vk::SubpassDependency2::default()
                .src_subpass(dep.src_subpass.0)
                .dst_subpass(dep.dst_subpass.0)
                .dependency_flags(vk::DependencyFlags::from_raw(dep.flags.bits()))
                .push_next(barrier)
        })
        .collect();
    for (dst, barrier) in external_into.iter().zip(external_barriers.iter_mut()) {
        dependencies.push(
            vk::SubpassDependency2::default()
                .src_subpass(vk::SUBPASS_EXTERNAL)
                .dst_subpass(*dst)
                .push_next(barrier),
        );
    }
    let info = vk::RenderPassCreateInfo2::default()
        .attachments(&attachments)
        .subpasses(&subpasses)
        .dependencies(&dependencies);
    // SAFETY: every referenced array lives until the call returns.
    let rp = unsafe { ctx.device.create_render_pass2(&info, None) }.vk("vkCreateRenderPass2")?;
    ctx.set_name(rp, name);
    Ok(rp)
}

pub(super) fn clear_value(a: &Attachment) -> vk::ClearValue {
    match a.clear {
        Some(ClearValue::Color(ClearColor::Float(v))) => vk::ClearValue {
            color: vk::ClearColorValue { float32: v },
        },
        Some(ClearValue::Color(ClearColor::Uint(v))) => vk::ClearValue {
            color: vk::ClearColorValue { uint32: v },
        },
        Some(ClearValue::Color(ClearColor::Int(v))) => vk::ClearValue {
            color: vk::ClearColorValue { int32: v },
        },
        Some(ClearValue::DepthStencil(ds)) => vk::ClearValue {
            depth_stencil: vk::ClearDepthStencilValue {
                depth: ds.depth,
                stencil: ds.stencil,
            },
        },
        None => vk::ClearValue::default(),
    }
}
