//! Executing a compiled [`Plan`]: physical resources (aliased where the plan allows, lazily
//! allocated where it makes attachments transient), render passes with their subpasses, the
//! plan's barriers through synchronization2, per-pass debug labels and GPU timestamps, frames in
//! flight. A steady-state frame allocates nothing: resources, render passes and framebuffers are
//! cached while the plan stays the same.

use std::collections::HashMap;
use std::sync::atomic::{AtomicU64, Ordering};

use ash::vk;
use tilegraph_graph::{
    AccessFlags, Attachment, BarrierBatch, ClearColor, ClearValue, MemoryRequirements, PassId,
    PipelineStages, Plan, PlanResource, RenderPass, Residency, ResourceDesc, ResourceId, Step,
    StoreOp, Usage,
};
use tilegraph_profile::MemoryUse;

use crate::error::{VkError, VkResultExt};
use crate::frames::{FrameRing, FrameToken, DEFAULT_FRAMES_IN_FLIGHT};
use crate::queries::{FrameTimings, PassMedian, QueryRing, TimingHistory};
use crate::{Context, Feature};

/// A physical image as passes see it.
#[derive(Debug, Clone)]
pub struct ImageHandle {
    pub raw: vk::Image,
    /// View of mip 0 with every aspect (attachments; sampling of single-mip images of one
    /// aspect).
    pub view: vk::ImageView,
    /// What a shader samples: every mip, and only the depth aspect of a depth-stencil format.
    /// Equals `view` for single-mip images of one aspect.
    pub full_view: vk::ImageView,
    /// One view per mip level (storage writes into a pyramid); empty for single-mip images.
    pub mip_views: Vec<vk::ImageView>,
    pub format: vk::Format,
    pub extent: vk::Extent2D,
    pub mip_levels: u32,
    pub aspect: vk::ImageAspectFlags,
}

/// A physical buffer as passes see it.
#[derive(Debug, Clone, Copy)]
pub struct BufferHandle {
    pub raw: vk::Buffer,
    pub size: u64,
}

/// A resource the caller owns and passes in each frame (a swapchain-like target, readback
/// buffers, history from earlier frames).
#[derive(Debug, Clone)]
pub enum External {
    Image(ImageHandle),
    Buffer(BufferHandle),
}

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

/// What a pass's payload gets to record with.
pub struct PassContext<'a> {
    pub ctx: &'a Context,
    pub cb: vk::CommandBuffer,
    pub pass: PassId,
    pub pass_name: &'a str,
    /// Frame-in-flight slot: index per-frame buffers with it.
    pub frame_slot: usize,
    pub frame: u64,
    /// The render pass and subpass this pass records into (raster passes), for pipeline creation.
    pub render_pass: Option<RenderPassRef>,
    pub render_area: vk::Extent2D,
    resources: &'a Resources,
    externals: &'a HashMap<ResourceId, External>,
}

impl PassContext<'_> {
    pub fn image(&self, id: impl Into<ResourceId>) -> Result<&ImageHandle, VkError> {
        let id = id.into();
        match self.externals.get(&id) {
            Some(External::Image(i)) => Ok(i),
            Some(External::Buffer(_)) => Err(wrong_kind(self.pass_name, id, "an image")),
            None => self
                .resources
                .image(id)
                .ok_or_else(|| missing(self.pass_name, id)),
        }
    }

    pub fn buffer(&self, id: impl Into<ResourceId>) -> Result<BufferHandle, VkError> {
        let id = id.into();
        match self.externals.get(&id) {
            Some(External::Buffer(b)) => Ok(*b),
            Some(External::Image(_)) => Err(wrong_kind(self.pass_name, id, "a buffer")),
            None => self
                .resources
                .buffer(id)
                .ok_or_else(|| missing(self.pass_name, id)),
        }
    }

    /// Sets a viewport and scissor covering the render area (depth 0..1).
    pub fn set_full_viewport(&self) {
        let e = self.render_area;
        let viewport = vk::Viewport {
            x: 0.0,
            y: 0.0,
            width: e.width as f32,
            height: e.height as f32,
            min_depth: 0.0,
            max_depth: 1.0,
        };
        let scissor = vk::Rect2D {
            offset: vk::Offset2D::default(),
            extent: e,
        };
        // SAFETY: recording command buffer; dynamic viewport/scissor pipelines.
        unsafe {
            self.ctx.device.cmd_set_viewport(self.cb, 0, &[viewport]);
            self.ctx.device.cmd_set_scissor(self.cb, 0, &[scissor]);
        }
    }
}

/// An image handed in by the caller must be what the render pass was built for: same format,
/// at least the render area (a framebuffer larger than its images is invalid usage).
fn check_attachment_image(
    plan: &Plan,
    pass: &str,
    a: &Attachment,
    h: &ImageHandle,
    area: vk::Extent2D,
) -> Result<(), VkError> {
    let format = vk::Format::from_raw(a.format.vk_raw());
    if h.format == format && h.extent.width >= area.width && h.extent.height >= area.height {
        return Ok(());
    }
    let name = plan.resource(a.resource).map_or("?", |r| r.name.as_str());
    Err(VkError::Invalid {
        what: format!("render pass {pass:?}, attachment {name:?}"),
        reason: format!(
            "the image is {:?} {}x{}; the plan needs {:?} of at least {}x{}",
            h.format, h.extent.width, h.extent.height, format, area.width, area.height
        ),
    })
}

fn missing(pass: &str, id: ResourceId) -> VkError {
    VkError::Invalid {
        what: format!("pass {pass:?}"),
        reason: format!(
            "resource #{} has no physical resource (not imported?)",
            id.0
        ),
    }
}

fn wrong_kind(pass: &str, id: ResourceId, want: &str) -> VkError {
    VkError::Invalid {
        what: format!("pass {pass:?}"),
        reason: format!("resource #{} is not {want}", id.0),
    }
}

/// Records one pass. Implemented for closures; a frame's payloads are looked up by [`PassId`].
pub trait RecordPass {
    fn record(&mut self, pass: &mut PassContext<'_>) -> Result<(), VkError>;
}

impl<F: FnMut(&mut PassContext<'_>) -> Result<(), VkError>> RecordPass for F {
    fn record(&mut self, pass: &mut PassContext<'_>) -> Result<(), VkError> {
        self(pass)
    }
}

/// Statistics of one executed frame.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct FrameStats {
    pub frame: u64,
    /// Device-memory allocations made while executing this frame (0 in steady state).
    pub allocations: u64,
    pub render_passes: u32,
    pub subpasses: u32,
    pub barriers: u32,
    pub flushes: u32,
    /// Whether the resource cache was (re)built this frame.
    pub rebuilt: bool,
    /// Whether aliased resources share memory (false when real requirements forced dedicated
    /// allocations, see [`Resources`]).
    pub aliasing_used: bool,
}

enum Memory {
    Dedicated(gpu_allocator::vulkan::Allocation),
    /// Part of a shared block owned by `Resources::blocks`.
    Block,
}

struct PhysImage {
    handle: ImageHandle,
    memory: Option<Memory>,
}

struct PhysBuffer {
    handle: BufferHandle,
    memory: Option<Memory>,
}

/// The plan's physical resources, built once per distinct plan.
#[derive(Default)]
pub struct Resources {
    images: HashMap<ResourceId, PhysImage>,
    buffers: HashMap<ResourceId, PhysBuffer>,
    blocks: Vec<gpu_allocator::vulkan::Allocation>,
    aliasing_used: bool,
    /// The plan as recorded: the compiled one with memory slots and barriers redone for the
    /// real memory requirements (`Plan::reassign_aliases`).
    placed: Option<Plan>,
}

impl Resources {
    pub fn image(&self, id: ResourceId) -> Option<&ImageHandle> {
        self.images.get(&id).map(|i| &i.handle)
    }
    pub fn buffer(&self, id: ResourceId) -> Option<BufferHandle> {
        self.buffers.get(&id).map(|b| b.handle)
    }

    fn destroy(self, ctx: &Context) {
        for (_, img) in self.images {
            destroy_views(ctx, &img.handle);
            // SAFETY: the caller waited for every frame that used it.
            unsafe { ctx.device.destroy_image(img.handle.raw, None) };
            if let Some(Memory::Dedicated(a)) = img.memory {
                ctx.free(a);
            }
        }
        for (_, buf) in self.buffers {
            // SAFETY: as above.
            unsafe { ctx.device.destroy_buffer(buf.handle.raw, None) };
            if let Some(Memory::Dedicated(a)) = buf.memory {
                ctx.free(a);
            }
        }
        for b in self.blocks {
            ctx.free(b);
        }
    }
}

fn destroy_views(ctx: &Context, h: &ImageHandle) {
    if h.view == vk::ImageView::null() {
        return;
    }
    // SAFETY: views of an image no longer in use.
    unsafe {
        for v in &h.mip_views {
            ctx.device.destroy_image_view(*v, None);
        }
        if h.full_view != h.view {
            ctx.device.destroy_image_view(h.full_view, None);
        }
        ctx.device.destroy_image_view(h.view, None);
    }
}

/// Aspect mask of a format.
pub fn aspect_of(format: tilegraph_graph::Format) -> vk::ImageAspectFlags {
    match (format.has_depth(), format.has_stencil()) {
        (true, true) => vk::ImageAspectFlags::DEPTH | vk::ImageAspectFlags::STENCIL,
        (true, false) => vk::ImageAspectFlags::DEPTH,
        (false, true) => vk::ImageAspectFlags::STENCIL,
        (false, false) => vk::ImageAspectFlags::COLOR,
    }
}

fn create_views(
    ctx: &Context,
    raw: vk::Image,
    format: vk::Format,
    aspect: vk::ImageAspectFlags,
    mips: u32,
    storage: bool,
    name: &str,
) -> Result<(vk::ImageView, vk::ImageView, Vec<vk::ImageView>), VkError> {
    let view_of = |base: u32, count: u32, aspect: vk::ImageAspectFlags| {
        let info = vk::ImageViewCreateInfo::default()
            .image(raw)
            .view_type(vk::ImageViewType::TYPE_2D)
            .format(format)
            .subresource_range(vk::ImageSubresourceRange {
                aspect_mask: aspect,
                base_mip_level: base,
                level_count: count,
                base_array_layer: 0,
                layer_count: 1,
            });
        // SAFETY: live image, range within its mips.
        unsafe { ctx.device.create_image_view(&info, None) }.vk("vkCreateImageView")
    };
    // A sampled view shows one aspect (VUID-VkDescriptorImageInfo-imageView-01976): depth for
    // depth-stencil formats.
    let depth_stencil = vk::ImageAspectFlags::DEPTH | vk::ImageAspectFlags::STENCIL;
    let sampled_aspect = if aspect == depth_stencil {
        vk::ImageAspectFlags::DEPTH
    } else {
        aspect
    };
    let view = view_of(0, 1, aspect)?;
    ctx.set_name(view, name);
    if mips <= 1 && sampled_aspect == aspect {
        return Ok((view, view, Vec::new()));
    }
    // Every view made so far, destroyed if a later one fails (nothing else holds them yet).
    let mut made = vec![view];
    let mut more = || -> Result<(vk::ImageView, Vec<vk::ImageView>), VkError> {
        let full = view_of(0, mips, sampled_aspect)?;
        made.push(full);
        let mut per_mip = Vec::new();
        if storage && mips > 1 {
            for m in 0..mips {
                let v = view_of(m, 1, aspect)?;
                made.push(v);
                per_mip.push(v);
            }
        }
        Ok((full, per_mip))
    };
    match more() {
        Ok((full, per_mip)) => Ok((view, full, per_mip)),
        Err(e) => {
            for v in made {
                // SAFETY: created above, never handed out or used.
                unsafe { ctx.device.destroy_image_view(v, None) };
            }
            Err(e)
        }
    }
}

/// Turns a plan into physical resources: real memory requirements (with
/// `bufferImageGranularity` folded in), aliasing redone with them by `Plan::reassign_aliases`
/// (which also redoes the barriers: the placed plan is what gets recorded), dedicated memory if
/// that fails.
fn build_resources(ctx: &Context, plan: &Plan) -> Result<Resources, VkError> {
    let mut res = Resources::default();
    let result = build_into(ctx, plan, &mut res);
    match result {
        Ok(()) => Ok(res),
        Err(e) => {
            res.destroy(ctx);
            Err(e)
        }
    }
}

fn build_into(ctx: &Context, plan: &Plan, res: &mut Resources) -> Result<(), VkError> {
    check_device_support(ctx, plan)?;
    let d = &ctx.device;
    let mut requirements: Vec<MemoryRequirements> = Vec::with_capacity(plan.resources.len());
    let mut vk_reqs: Vec<Option<vk::MemoryRequirements>> = vec![None; plan.resources.len()];
    for r in &plan.resources {
        let owned = matches!(
            r.residency,
            Residency::Exported | Residency::FrameLocal | Residency::Transient
        );
        if !owned {
            requirements.push(MemoryRequirements {
                size_bytes: 0,
                alignment_bytes: 1,
            });
            continue;
        }
        let req = match (&r.desc, r.usage) {
            (ResourceDesc::Image(desc), Usage::Image(usage)) => {
                let format = vk::Format::from_raw(desc.format.vk_raw());
                let info = vk::ImageCreateInfo::default()
                    .image_type(vk::ImageType::TYPE_2D)
                    .format(format)
                    .extent(vk::Extent3D {
                        width: desc.extent_px.width_px,
                        height: desc.extent_px.height_px,
                        depth: 1,
                    })
                    .mip_levels(desc.mip_levels.max(1))
                    .array_layers(1)
                    .samples(vk::SampleCountFlags::from_raw(desc.samples.vk_bits()))
                    .tiling(vk::ImageTiling::OPTIMAL)
                    .usage(vk::ImageUsageFlags::from_raw(usage.bits()))
                    .initial_layout(vk::ImageLayout::UNDEFINED);
                // SAFETY: valid create info derived from the plan (extent checked by the graph).
                let raw = unsafe { d.create_image(&info, None) }.vk("vkCreateImage")?;
                ctx.set_name(raw, &r.name);
                // SAFETY: live image.
                let req = unsafe { d.get_image_memory_requirements(raw) };
                // Views are created once memory is bound (VUID-VkImageViewCreateInfo-image-01020).
                res.images.insert(
                    r.id,
                    PhysImage {
                        handle: ImageHandle {
                            raw,
                            view: vk::ImageView::null(),
                            full_view: vk::ImageView::null(),
                            mip_views: Vec::new(),
                            format,
                            extent: vk::Extent2D {
                                width: desc.extent_px.width_px,
                                height: desc.extent_px.height_px,
                            },
                            mip_levels: desc.mip_levels.max(1),
                            aspect: aspect_of(desc.format),
                        },
                        memory: None,
                    },
                );
                req
            }
            (ResourceDesc::Buffer(desc), Usage::Buffer(usage)) => {
                let info = vk::BufferCreateInfo::default()
                    .size(desc.size_bytes.max(4))
                    .usage(vk::BufferUsageFlags::from_raw(usage.bits()))
                    .sharing_mode(vk::SharingMode::EXCLUSIVE);
                // SAFETY: valid create info.
                let raw = unsafe { d.create_buffer(&info, None) }.vk("vkCreateBuffer")?;
                ctx.set_name(raw, &r.name);
                // SAFETY: live buffer.
                let req = unsafe { d.get_buffer_memory_requirements(raw) };
                res.buffers.insert(
                    r.id,
                    PhysBuffer {
                        handle: BufferHandle {
                            raw,
                            size: desc.size_bytes,
                        },
                        memory: None,
                    },
                );
                req
            }
            _ => {
                return Err(VkError::Invalid {
                    what: format!("resource {:?}", r.name),
                    reason: "usage does not match its kind".into(),
                });
            }
        };
        requirements.push(placement_requirements(
            req,
            r.residency,
            ctx.physical.limits.buffer_image_granularity,
        ));
        vk_reqs[r.id.index()] = Some(req);
    }

    // Aliasing with the real sizes and alignments; the plan's barriers are redone for the new
    // placement (new hand-offs get their barriers). If that fails, frame-local resources get
    // dedicated memory (correct, just larger) and the compiled plan is recorded as it is.
    let mut placed = plan.clone();
    let layout = match placed.reassign_aliases(&requirements) {
        Ok(()) => Some(placed.aliasing.clone()),
        Err(e) => {
            log::warn!("aliasing with the real memory requirements failed ({e}): frame-local resources get dedicated memory");
            placed = plan.clone();
            None
        }
    };
    res.placed = Some(placed);

    // Shared blocks: one allocation per block, in the memory type every member accepts.
    let mut block_of: HashMap<ResourceId, (usize, u64)> = HashMap::new();
    if let Some(layout) = &layout {
        for (bi, block) in layout.blocks.iter().enumerate() {
            let members: Vec<&PlanResource> = plan
                .resources
                .iter()
                .filter(|r| {
                    r.residency == Residency::FrameLocal
                        && layout
                            .slots
                            .get(r.id.index())
                            .copied()
                            .flatten()
                            .is_some_and(|s| s.block.0 as usize == bi)
                })
                .collect();
            if members.len() < 2 {
                continue; // a block of one is a dedicated allocation
            }
            let bits = members
                .iter()
                .filter_map(|r| vk_reqs[r.id.index()])
                .fold(u32::MAX, |b, q| b & q.memory_type_bits);
            let align = members
                .iter()
                .filter_map(|r| vk_reqs[r.id.index()])
                .map(|q| q.alignment)
                .max()
                .unwrap_or(1);
            if bits == 0 {
                continue;
            }
            let req = vk::MemoryRequirements {
                // Ends on a granularity page too: whatever the allocator puts after the block
                // (it is told the block is non-linear) never shares its last page.
                size: block
                    .size_bytes
                    .next_multiple_of(ctx.physical.limits.buffer_image_granularity.max(1)),
                alignment: align.max(block.alignment_bytes),
                memory_type_bits: bits,
            };
            let (alloc, _) =
                ctx.allocate(&format!("alias block {bi}"), req, MemoryUse::GpuOnly, false)?;
            let index = res.blocks.len();
            res.blocks.push(alloc);
            for r in members {
                if let Some(slot) = layout.slots.get(r.id.index()).copied().flatten() {
                    block_of.insert(r.id, (index, slot.offset_bytes));
                }
            }
        }
    }
    res.aliasing_used = !block_of.is_empty();

    for r in &plan.resources {
        let Some(req) = vk_reqs[r.id.index()] else {
            continue;
        };
        let use_ = if r.residency == Residency::Transient {
            MemoryUse::TransientAttachment
        } else {
            MemoryUse::GpuOnly
        };
        let memory = match block_of.get(&r.id) {
            Some(&(block, offset)) => {
                let a = &res.blocks[block];
                // SAFETY: the block's memory handle stays valid while the block lives.
                (unsafe { a.memory() }, a.offset() + offset, Memory::Block)
            }
            None => {
                // Buffers are linear: the allocator keeps them off optimal images' pages.
                let linear = res.buffers.contains_key(&r.id);
                let (a, _) = ctx.allocate(&r.name, req, use_, linear)?;
                // SAFETY: as above.
                (unsafe { a.memory() }, a.offset(), Memory::Dedicated(a))
            }
        };
        let (mem, offset, owner) = memory;
        // The owner is stored before binding, so a failed bind still frees the memory (with
        // the rest of `res`).
        if let Some(img) = res.images.get_mut(&r.id) {
            img.memory = Some(owner);
            // SAFETY: memory satisfies the image's requirements (type, size, alignment checked
            // by the alias layout or by the dedicated allocation).
            unsafe { d.bind_image_memory(img.handle.raw, mem, offset) }.vk("vkBindImageMemory")?;
            let storage = matches!(r.usage, Usage::Image(u) if u.contains(tilegraph_graph::ImageUsage::STORAGE));
            let h = &mut img.handle;
            let (view, full_view, mip_views) = create_views(
                ctx,
                h.raw,
                h.format,
                h.aspect,
                h.mip_levels,
                storage,
                &r.name,
            )?;
            (h.view, h.full_view, h.mip_views) = (view, full_view, mip_views);
        } else if let Some(buf) = res.buffers.get_mut(&r.id) {
            buf.memory = Some(owner);
            // SAFETY: as above.
            unsafe { d.bind_buffer_memory(buf.handle.raw, mem, offset) }
                .vk("vkBindBufferMemory")?;
        } else if let Memory::Dedicated(a) = owner {
            ctx.free(a);
        }
    }
    Ok(())
}

/// Render pass objects and framebuffers of one plan.
#[derive(Default)]
struct RenderPasses {
    /// By step index: the render pass and its serial.
    passes: HashMap<usize, (vk::RenderPass, u64)>,
    /// By (step index, attachment views).
    framebuffers: HashMap<(usize, Vec<vk::ImageView>), vk::Framebuffer>,
}

impl RenderPasses {
    fn destroy(self, ctx: &Context) {
        // SAFETY: no frame using them is in flight (caller waited).
        unsafe {
            for (_, fb) in self.framebuffers {
                ctx.device.destroy_framebuffer(fb, None);
            }
            for (_, (rp, _)) in self.passes {
                ctx.device.destroy_render_pass(rp, None);
            }
        }
    }
}

fn create_render_pass(
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
    // Attachments whose content starts undefined were last written by an earlier frame (the
    // same memory, frames in flight) or by the caller: the subpass that first touches them waits
    // for all earlier work on the queue, so the load op's write never races with those.
    let mut external_into: Vec<u32> = Vec::new();
    for (i, a) in plan_rp.attachments.iter().enumerate() {
        if a.initial_layout != tilegraph_graph::Layout::Undefined {
            continue;
        }
        let first = plan_rp.subpasses.iter().position(|s| {
            let i = i as u32;
            s.colors
                .iter()
                .chain(s.inputs.iter())
                .chain(s.depth_stencil.iter())
                .any(|r| r.attachment.0 == i)
                || s.resolves.iter().flatten().any(|r| r.attachment.0 == i)
        });
        if let Some(f) = first.map(|f| f as u32) {
            if !external_into.contains(&f) {
                external_into.push(f);
            }
        }
    }
    let mut external_barriers: Vec<vk::MemoryBarrier2> = external_into
        .iter()
        .map(|_| {
            vk::MemoryBarrier2::default()
                .src_stage_mask(vk::PipelineStageFlags2::ALL_COMMANDS)
                .src_access_mask(vk::AccessFlags2::MEMORY_WRITE)
                .dst_stage_mask(
                    vk::PipelineStageFlags2::EARLY_FRAGMENT_TESTS
                        | vk::PipelineStageFlags2::LATE_FRAGMENT_TESTS
                        | vk::PipelineStageFlags2::COLOR_ATTACHMENT_OUTPUT
                        | vk::PipelineStageFlags2::FRAGMENT_SHADER,
                )
                .dst_access_mask(
                    vk::AccessFlags2::DEPTH_STENCIL_ATTACHMENT_READ
                        | vk::AccessFlags2::DEPTH_STENCIL_ATTACHMENT_WRITE
                        | vk::AccessFlags2::COLOR_ATTACHMENT_READ
                        | vk::AccessFlags2::COLOR_ATTACHMENT_WRITE
                        | vk::AccessFlags2::INPUT_ATTACHMENT_READ,
                )
        })
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

/// Executes plans frame after frame.
pub struct Executor {
    frames: FrameRing,
    queries: QueryRing,
    history: TimingHistory,
    latest: Option<FrameTimings>,
    plan: Option<Plan>,
    resources: Option<Resources>,
    render_passes: RenderPasses,
    /// Every render pass created since the last rebuild has a serial at least this.
    render_pass_serial_floor: u64,
    /// Frame number of the first frame recorded with the current resources.
    resources_since: u64,
    /// Render passes recorded by the last frame (for tests and reports).
    pub last_stats: FrameStats,
}

impl Executor {
    pub fn new(ctx: &Context) -> Result<Self, VkError> {
        Self::with_frames(ctx, DEFAULT_FRAMES_IN_FLIGHT, 256)
    }

    /// `frames_in_flight` frames, each timing up to `max_passes` passes.
    pub fn with_frames(
        ctx: &Context,
        frames_in_flight: usize,
        max_passes: u32,
    ) -> Result<Self, VkError> {
        // Barriers, timestamps and the subpass dependencies of every render pass are
        // synchronization2 structures: without the feature they would be invalid usage.
        if !ctx.has_feature(Feature::Synchronization2) {
            return Err(VkError::MissingRequired {
                device: ctx.physical.identity.device_name.clone(),
                what: "feature (not enabled; see FeatureRequest::executor)",
                missing: Feature::Synchronization2.to_string(),
            });
        }
        let mut frames = FrameRing::new(ctx, frames_in_flight)?;
        let queries = match QueryRing::new(ctx, frames.frames_in_flight(), max_passes) {
            Ok(q) => q,
            Err(e) => {
                frames.destroy(ctx);
                return Err(e);
            }
        };
        Ok(Executor {
            frames,
            queries,
            history: TimingHistory::default(),
            latest: None,
            plan: None,
            resources: None,
            render_passes: RenderPasses::default(),
            render_pass_serial_floor: NEXT_RENDER_PASS_SERIAL.load(Ordering::Relaxed),
            resources_since: 0,
            last_stats: FrameStats::default(),
        })
    }

    pub fn frames_in_flight(&self) -> usize {
        self.frames.frames_in_flight()
    }

    /// Command buffers allocated over all frame slots: one per slot, plus one per flush step of
    /// the plan (reused every frame).
    pub fn command_buffer_count(&self) -> usize {
        self.frames.command_buffer_count()
    }

    /// The slot the next [`Executor::execute`] will record into (per-frame buffers of passes
    /// are indexed by it; the executor guarantees the slot's previous frame has completed by
    /// the time recording starts).
    pub fn next_slot(&self) -> usize {
        self.frames.next_slot()
    }

    /// Waits until the next frame's slot is free and returns it: per-frame buffers of that slot
    /// may be written now, before [`Executor::execute`] records the frame.
    pub fn acquire_slot(&mut self, ctx: &Context) -> Result<usize, VkError> {
        self.frames.wait_next(ctx)
    }

    /// Per-pass median GPU times over every frame collected so far.
    pub fn medians(&self) -> Vec<PassMedian> {
        self.history.medians()
    }

    /// The most recent frame whose timings were collected.
    pub fn latest_timings(&self) -> Option<&FrameTimings> {
        self.latest.as_ref()
    }

    pub fn history(&self) -> &TimingHistory {
        &self.history
    }

    /// Physical resources of the current plan (e.g. to read back an exported image).
    pub fn resources(&self) -> Option<&Resources> {
        self.resources.as_ref()
    }

    /// Records and submits one frame of `plan`. `record(pass_id, ctx)` records each pass;
    /// `externals` gives the physical resources of the plan's imported resources.
    pub fn execute(
        &mut self,
        ctx: &Context,
        plan: &Plan,
        externals: &HashMap<ResourceId, External>,
        record: &mut dyn FnMut(PassId, &mut PassContext<'_>) -> Result<(), VkError>,
    ) -> Result<FrameStats, VkError> {
        let allocations_before = ctx.allocation_count();
        let mut stats = FrameStats::default();
        if self.plan.as_ref() != Some(plan) {
            // A different plan: wait for every frame in flight, then rebuild.
            self.collect_all(ctx)?;
            if let Some(old) = self.resources.take() {
                old.destroy(ctx);
            }
            std::mem::take(&mut self.render_passes).destroy(ctx);
            self.render_pass_serial_floor = NEXT_RENDER_PASS_SERIAL.load(Ordering::Relaxed);
            // No plan until the new one is built: if building fails, the next call rebuilds
            // (whichever plan it brings) instead of finding no resources for the old one.
            self.plan = None;
            self.resources = Some(build_resources(ctx, plan)?);
            self.plan = Some(plan.clone());
            self.resources_since = self.frames_next_frame();
            stats.rebuilt = true;
        }
        let mut token = self.frames.begin(ctx)?;
        if token.completed_frame.is_some() {
            if let Some(t) = self.queries.collect(ctx, token.slot)? {
                self.history.record(&t);
                self.latest = Some(t);
            }
        }
        self.queries
            .begin_frame(ctx, token.cb, token.slot, token.frame)?;
        // Taken out for the recording so passes can borrow it while the executor mutates its
        // render-pass cache and query ring; always put back.
        let resources = self.resources.take();
        let result = match &resources {
            // The placed plan: same passes and render passes, barriers for the real layout.
            Some(r) => {
                let placed = r.placed.as_ref().unwrap_or(plan);
                self.record_frame(ctx, placed, r, externals, record, &mut token, &mut stats)
            }
            None => Err(VkError::Invalid {
                what: "executor".into(),
                reason: "no resources".into(),
            }),
        };
        self.resources = resources;
        // After a recording error nothing more is submitted. The command buffer may be inside a
        // render pass, so it is not ended: the pool reset at the slot's next use takes it back
        // from the recording state. Work already flushed this frame is tracked by the fence.
        if let Err(e) = result {
            if let Err(gave_up) = self.frames.abandon(ctx, &token) {
                log::error!("giving up the frame after \"{e}\": {gave_up}");
            }
            return Err(e);
        }
        self.frames.submit(ctx, token)?;
        stats.frame = token.frame;
        stats.allocations = ctx.allocation_count() - allocations_before;
        stats.aliasing_used = self.resources.as_ref().is_some_and(|r| r.aliasing_used);
        self.last_stats = stats.clone();
        Ok(stats)
    }

    fn frames_next_frame(&self) -> u64 {
        // The frame number the next begin() will hand out.
        self.frames.next_frame()
    }

    #[allow(clippy::too_many_arguments)]
    fn record_frame(
        &mut self,
        ctx: &Context,
        plan: &Plan,
        resources: &Resources,
        externals: &HashMap<ResourceId, External>,
        record: &mut dyn FnMut(PassId, &mut PassContext<'_>) -> Result<(), VkError>,
        token: &mut FrameToken,
        stats: &mut FrameStats,
    ) -> Result<(), VkError> {
        let lookup = |id: ResourceId| -> Option<External> {
            externals.get(&id).cloned().or_else(|| {
                resources
                    .image(id)
                    .cloned()
                    .map(External::Image)
                    .or_else(|| resources.buffer(id).map(External::Buffer))
            })
        };
        // Resources created by the graph were last touched by an earlier frame (same memory):
        // their first barrier this frame waits for all earlier work, so frames never race on
        // them. The first frame after a rebuild has no earlier user.
        let reused = token.frame > self.resources_since;
        let mut seen_first: Vec<bool> = vec![false; plan.resources.len()];
        for (step_index, step) in plan.steps.iter().enumerate() {
            match step {
                Step::Barriers(batch) => {
                    stats.barriers += batch.len() as u32;
                    self.record_barriers(
                        ctx,
                        token.cb,
                        plan,
                        batch,
                        &lookup,
                        reused,
                        &mut seen_first,
                    )?;
                }
                Step::Flush(_) => {
                    stats.flushes += 1;
                    self.frames.flush(ctx, token)?;
                }
                Step::Compute { pass } | Step::Transfer { pass } => {
                    if reused {
                        wait_for_earlier_frames(
                            ctx,
                            token.cb,
                            plan,
                            std::slice::from_ref(pass),
                            &lookup,
                            &seen_first,
                        )?;
                    }
                    mark_first_uses(plan, *pass, &mut seen_first);
                    let name = plan.pass(*pass).map_or("?", |p| p.name.as_str());
                    self.run_pass(
                        ctx,
                        token,
                        *pass,
                        name,
                        None,
                        vk::Extent2D::default(),
                        resources,
                        externals,
                        record,
                    )?;
                }
                Step::RenderPass(rp) => {
                    stats.render_passes += 1;
                    stats.subpasses += rp.subpasses.len() as u32;
                    if reused {
                        let passes: Vec<PassId> = rp.subpasses.iter().map(|s| s.pass).collect();
                        wait_for_earlier_frames(
                            ctx,
                            token.cb,
                            plan,
                            &passes,
                            &lookup,
                            &seen_first,
                        )?;
                    }
                    for s in &rp.subpasses {
                        mark_first_uses(plan, s.pass, &mut seen_first);
                    }
                    self.record_render_pass(
                        ctx, token, plan, step_index, rp, &lookup, resources, externals, record,
                    )?;
                }
            }
        }
        Ok(())
    }

    #[allow(clippy::too_many_arguments)]
    fn run_pass(
        &mut self,
        ctx: &Context,
        token: &FrameToken,
        pass: PassId,
        name: &str,
        render_pass: Option<RenderPassRef>,
        render_area: vk::Extent2D,
        resources: &Resources,
        externals: &HashMap<ResourceId, External>,
        record: &mut dyn FnMut(PassId, &mut PassContext<'_>) -> Result<(), VkError>,
    ) -> Result<(), VkError> {
        ctx.begin_label(token.cb, name);
        let q = self
            .queries
            .begin_pass(ctx, token.cb, token.slot, name, true)?;
        let mut pc = PassContext {
            ctx,
            cb: token.cb,
            pass,
            pass_name: name,
            frame_slot: token.slot,
            frame: token.frame,
            render_pass,
            render_area,
            resources,
            externals,
        };
        let r = record(pass, &mut pc);
        self.queries.end_pass(ctx, token.cb, token.slot, q)?;
        ctx.end_label(token.cb);
        r
    }

    #[allow(clippy::too_many_arguments)]
    fn record_barriers(
        &self,
        ctx: &Context,
        cb: vk::CommandBuffer,
        plan: &Plan,
        batch: &BarrierBatch,
        lookup: &dyn Fn(ResourceId) -> Option<External>,
        reused: bool,
        seen_first: &mut [bool],
    ) -> Result<(), VkError> {
        let mut images = Vec::with_capacity(batch.images.len());
        for b in &batch.images {
            let Some(External::Image(h)) = lookup(b.resource) else {
                return Err(missing("barrier", b.resource));
            };
            let (mut src_s, mut src_a) = (b.src_stages, b.src_access);
            if reused && first_use_of_owned(plan, b.resource, seen_first) {
                src_s = src_s.union(PipelineStages::ALL_COMMANDS);
                src_a = src_a.union(AccessFlags::MEMORY_WRITE);
            }
            images.push(
                vk::ImageMemoryBarrier2::default()
                    .src_stage_mask(vk::PipelineStageFlags2::from_raw(src_s.bits()))
                    .src_access_mask(vk::AccessFlags2::from_raw(src_a.bits()))
                    .dst_stage_mask(vk::PipelineStageFlags2::from_raw(b.dst_stages.bits()))
                    .dst_access_mask(vk::AccessFlags2::from_raw(b.dst_access.bits()))
                    .old_layout(vk::ImageLayout::from_raw(b.old_layout.vk_raw()))
                    .new_layout(vk::ImageLayout::from_raw(b.new_layout.vk_raw()))
                    .image(h.raw)
                    .subresource_range(vk::ImageSubresourceRange {
                        aspect_mask: h.aspect,
                        base_mip_level: 0,
                        level_count: h.mip_levels,
                        base_array_layer: 0,
                        layer_count: 1,
                    }),
            );
        }
        let mut buffers = Vec::with_capacity(batch.buffers.len());
        for b in &batch.buffers {
            let Some(External::Buffer(h)) = lookup(b.resource) else {
                return Err(missing("barrier", b.resource));
            };
            let (mut src_s, mut src_a) = (b.src_stages, b.src_access);
            if reused && first_use_of_owned(plan, b.resource, seen_first) {
                src_s = src_s.union(PipelineStages::ALL_COMMANDS);
                src_a = src_a.union(AccessFlags::MEMORY_WRITE);
            }
            buffers.push(
                vk::BufferMemoryBarrier2::default()
                    .src_stage_mask(vk::PipelineStageFlags2::from_raw(src_s.bits()))
                    .src_access_mask(vk::AccessFlags2::from_raw(src_a.bits()))
                    .dst_stage_mask(vk::PipelineStageFlags2::from_raw(b.dst_stages.bits()))
                    .dst_access_mask(vk::AccessFlags2::from_raw(b.dst_access.bits()))
                    .buffer(h.raw)
                    .size(vk::WHOLE_SIZE),
            );
        }
        if images.is_empty() && buffers.is_empty() {
            return Ok(());
        }
        let info = vk::DependencyInfo::default()
            .image_memory_barriers(&images)
            .buffer_memory_barriers(&buffers);
        ctx.cmd_pipeline_barrier2(cb, &info)
    }

    #[allow(clippy::too_many_arguments)]
    fn record_render_pass(
        &mut self,
        ctx: &Context,
        token: &FrameToken,
        plan: &Plan,
        step_index: usize,
        rp: &RenderPass,
        lookup: &dyn Fn(ResourceId) -> Option<External>,
        resources: &Resources,
        externals: &HashMap<ResourceId, External>,
        record: &mut dyn FnMut(PassId, &mut PassContext<'_>) -> Result<(), VkError>,
    ) -> Result<(), VkError> {
        let first_name = rp
            .subpasses
            .first()
            .and_then(|s| plan.pass(s.pass))
            .map_or("render pass", |p| p.name.as_str());
        let (raw_rp, serial) = match self.render_passes.passes.get(&step_index) {
            Some(r) => *r,
            None => {
                let r = create_render_pass(ctx, rp, first_name)?;
                let serial = NEXT_RENDER_PASS_SERIAL.fetch_add(1, Ordering::Relaxed);
                self.render_passes.passes.insert(step_index, (r, serial));
                (r, serial)
            }
        };
        let extent = vk::Extent2D {
            width: rp.render_area_px.width_px,
            height: rp.render_area_px.height_px,
        };
        let views: Vec<vk::ImageView> = rp
            .attachments
            .iter()
            .map(|a| match lookup(a.resource) {
                Some(External::Image(h)) => {
                    check_attachment_image(plan, first_name, a, &h, extent)?;
                    Ok(h.view)
                }
                _ => Err(missing(first_name, a.resource)),
            })
            .collect::<Result<_, _>>()?;
        let key = (step_index, views.clone());
        let fb = match self.render_passes.framebuffers.get(&key) {
            Some(f) => *f,
            None => {
                let info = vk::FramebufferCreateInfo::default()
                    .render_pass(raw_rp)
                    .attachments(&views)
                    .width(extent.width)
                    .height(extent.height)
                    .layers(1);
                // SAFETY: views match the render pass's attachments (format, samples, extent).
                let fb = unsafe { ctx.device.create_framebuffer(&info, None) }
                    .vk("vkCreateFramebuffer")?;
                self.render_passes.framebuffers.insert(key, fb);
                fb
            }
        };
        let clears: Vec<vk::ClearValue> = rp.attachments.iter().map(clear_value).collect();
        let begin = vk::RenderPassBeginInfo::default()
            .render_pass(raw_rp)
            .framebuffer(fb)
            .render_area(vk::Rect2D {
                offset: vk::Offset2D::default(),
                extent,
            })
            .clear_values(&clears);
        let sp_begin = vk::SubpassBeginInfo::default().contents(vk::SubpassContents::INLINE);
        // SAFETY: recording, outside any render pass; framebuffer matches.
        unsafe {
            ctx.device
                .cmd_begin_render_pass2(token.cb, &begin, &sp_begin)
        };
        for (i, s) in rp.subpasses.iter().enumerate() {
            if i > 0 {
                // SAFETY: inside the render pass, more subpasses remain.
                unsafe {
                    ctx.device.cmd_next_subpass2(
                        token.cb,
                        &sp_begin,
                        &vk::SubpassEndInfo::default(),
                    )
                };
            }
            let name = plan.pass(s.pass).map_or("?", |p| p.name.as_str());
            self.run_pass(
                ctx,
                token,
                s.pass,
                name,
                Some(RenderPassRef {
                    handle: raw_rp,
                    subpass: i as u32,
                    serial,
                }),
                extent,
                resources,
                externals,
                record,
            )?;
        }
        // SAFETY: matches cmd_begin_render_pass2.
        unsafe {
            ctx.device
                .cmd_end_render_pass2(token.cb, &vk::SubpassEndInfo::default())
        };
        Ok(())
    }

    fn collect_all(&mut self, ctx: &Context) -> Result<(), VkError> {
        let done = self.frames.wait_all(ctx)?;
        let mut frames: Vec<u64> = done;
        frames.sort_unstable();
        for f in frames {
            if let Some(slot) = self.frames.slot_of(f) {
                if let Some(t) = self.queries.collect(ctx, slot)? {
                    self.history.record(&t);
                    self.latest = Some(t);
                }
            }
        }
        Ok(())
    }

    /// Waits for every frame in flight and collects its timings (call before reading results
    /// that the last frame wrote, or before reporting medians).
    pub fn finish(&mut self, ctx: &Context) -> Result<(), VkError> {
        self.collect_all(ctx)
    }

    /// Forgets every framebuffer made with an image view the caller handed in. For a recreated
    /// swapchain: call [`Executor::finish`] first (frames in flight may still use the old
    /// views), destroy the old images and views, then call this before the next `execute`: the
    /// driver may give a new view the handle of a destroyed one, and a framebuffer cached under
    /// that handle would still reference the destroyed view.
    pub fn forget_external_views(&mut self, ctx: &Context) -> Result<(), VkError> {
        self.collect_all(ctx)?;
        let owned: Vec<vk::ImageView> = self
            .resources
            .as_ref()
            .map(|r| r.images.values().map(|i| i.handle.view).collect())
            .unwrap_or_default();
        self.render_passes.framebuffers.retain(|(_, views), fb| {
            let keep = views.iter().all(|v| owned.contains(v));
            if !keep {
                // SAFETY: no frame in flight (collected above).
                unsafe { ctx.device.destroy_framebuffer(*fb, None) };
            }
            keep
        });
        Ok(())
    }

    /// Render passes of the current plan have serials of at least this
    /// ([`RenderPassRef::serial`]); pipelines cached for lower serials belong to render passes
    /// already destroyed, and no frame in flight uses them (the executor waited for every frame
    /// before it rebuilt): they may be destroyed.
    pub fn render_pass_serial_floor(&self) -> u64 {
        self.render_pass_serial_floor
    }

    /// Framebuffers cached for the current plan.
    pub fn framebuffer_count(&self) -> usize {
        self.render_passes.framebuffers.len()
    }

    /// Waits for the GPU and frees everything.
    pub fn destroy(mut self, ctx: &Context) {
        if let Err(e) = self.frames.wait_all(ctx) {
            log::error!("waiting for frames at teardown: {e}");
        }
        if let Some(r) = self.resources.take() {
            r.destroy(ctx);
        }
        std::mem::take(&mut self.render_passes).destroy(ctx);
        self.queries.destroy(ctx);
        self.frames.destroy(ctx);
    }
}

fn clear_value(a: &Attachment) -> vk::ClearValue {
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

/// Whether this barrier is the first touch this frame of a resource the executor owns.
fn first_use_of_owned(plan: &Plan, id: ResourceId, seen_first: &mut [bool]) -> bool {
    let owned = is_owned(plan, id);
    let Some(seen) = seen_first.get_mut(id.index()) else {
        return false;
    };
    let first = owned && !*seen;
    *seen = true;
    first
}

/// A buffer the graph owns may be written first, with no barrier in the plan (nothing earlier
/// in the frame touched it). An earlier frame still running may be reading or writing it, and
/// queue submissions are not ordered by themselves: before the step, its not-yet-seen owned
/// buffers wait for all earlier work (images always get a first barrier: their layout).
fn wait_for_earlier_frames(
    ctx: &Context,
    cb: vk::CommandBuffer,
    plan: &Plan,
    passes: &[PassId],
    lookup: &dyn Fn(ResourceId) -> Option<External>,
    seen_first: &[bool],
) -> Result<(), VkError> {
    let mut buffers: Vec<vk::BufferMemoryBarrier2<'_>> = Vec::new();
    let mut added: Vec<ResourceId> = Vec::new();
    for u in passes
        .iter()
        .filter_map(|&p| plan.pass(p))
        .flat_map(|p| &p.uses)
    {
        let id = u.resource;
        let fresh = !seen_first.get(id.index()).copied().unwrap_or(true);
        if !fresh || added.contains(&id) || !is_owned(plan, id) {
            continue;
        }
        let Some(External::Buffer(h)) = lookup(id) else {
            continue;
        };
        added.push(id);
        buffers.push(
            vk::BufferMemoryBarrier2::default()
                .src_stage_mask(vk::PipelineStageFlags2::ALL_COMMANDS)
                .src_access_mask(vk::AccessFlags2::MEMORY_WRITE)
                .dst_stage_mask(vk::PipelineStageFlags2::ALL_COMMANDS)
                .dst_access_mask(vk::AccessFlags2::MEMORY_READ | vk::AccessFlags2::MEMORY_WRITE)
                .buffer(h.raw)
                .size(vk::WHOLE_SIZE),
        );
    }
    if buffers.is_empty() {
        return Ok(());
    }
    let info = vk::DependencyInfo::default().buffer_memory_barriers(&buffers);
    ctx.cmd_pipeline_barrier2(cb, &info)
}

fn is_owned(plan: &Plan, id: ResourceId) -> bool {
    plan.resource(id).is_some_and(|r| {
        matches!(
            r.residency,
            Residency::FrameLocal | Residency::Exported | Residency::Transient
        )
    })
}

fn mark_first_uses(plan: &Plan, pass: PassId, seen_first: &mut [bool]) {
    if let Some(p) = plan.pass(pass) {
        for u in &p.uses {
            if let Some(s) = seen_first.get_mut(u.resource.index()) {
                *s = true;
            }
        }
    }
}

/// What aliasing places a resource with: its `VkMemoryRequirements`, and for frame-local
/// resources (the ones that share blocks) an alignment of at least `bufferImageGranularity`, so
/// a buffer and an image in one block never share a granularity page (the contract
/// `tilegraph_graph::alias` states for real requirements).
fn placement_requirements(
    req: vk::MemoryRequirements,
    residency: Residency,
    buffer_image_granularity: u64,
) -> MemoryRequirements {
    let alignment = req.alignment.max(1);
    MemoryRequirements {
        size_bytes: req.size,
        alignment_bytes: if residency == Residency::FrameLocal {
            // Both are powers of two: the larger is a multiple of the smaller.
            alignment.max(buffer_image_granularity.max(1).next_power_of_two())
        } else {
            alignment
        },
    }
}

/// Whether a store op keeps the attachment (for reports).
pub fn stores(a: &Attachment) -> bool {
    matches!(a.store_op, StoreOp::Store | StoreOp::None)
}

/// Checks what the plan asks of the device before anything is created: `STORE_OP_NONE` needs
/// Vulkan 1.3 (`Context::new` turns the profile's `store_op_none` off on older devices, so this
/// only fails for plans compiled with another profile), and a conditional-rendering predicate
/// needs VK_EXT_conditional_rendering. Recording `STORE` instead of `NONE` would be a write the
/// plan's barriers do not synchronize.
fn check_device_support(ctx: &Context, plan: &Plan) -> Result<(), VkError> {
    let store_none = plan.render_passes().any(|(_, rp)| {
        rp.attachments
            .iter()
            .any(|a| a.store_op == StoreOp::None || a.stencil_store_op == StoreOp::None)
    });
    if store_none && !ctx.physical.api13() {
        return Err(VkError::Invalid {
            what: format!("plan for profile {}", plan.profile),
            reason: format!(
                "it stores attachments with STORE_OP_NONE, which needs Vulkan 1.3 (the device has {}); compile it with the context's profile",
                ctx.physical.identity.api_version_string()
            ),
        });
    }
    for r in &plan.resources {
        let owned = matches!(
            r.residency,
            Residency::Exported | Residency::FrameLocal | Residency::Transient
        );
        let (true, ResourceDesc::Image(desc), Usage::Image(usage)) = (owned, &r.desc, r.usage)
        else {
            continue;
        };
        let problem = ctx.image_support_problem(
            vk::Format::from_raw(desc.format.vk_raw()),
            vk::ImageUsageFlags::from_raw(usage.bits()),
            vk::SampleCountFlags::from_raw(desc.samples.vk_bits()),
            desc.mip_levels.max(1),
            vk::Extent2D {
                width: desc.extent_px.width_px,
                height: desc.extent_px.height_px,
            },
        );
        if let Some(reason) = problem {
            return Err(VkError::Invalid {
                what: format!(
                    "image {:?} on {}",
                    r.name, ctx.physical.identity.device_name
                ),
                reason,
            });
        }
    }
    let predicate = plan.resources.iter().any(|r| {
        matches!(r.usage, Usage::Buffer(u) if u.contains(tilegraph_graph::BufferUsage::CONDITIONAL_RENDERING))
    });
    if predicate && ctx.conditional_rendering().is_none() {
        return Err(VkError::Invalid {
            what: format!("plan for profile {}", plan.profile),
            reason: "a pass declares a conditional-rendering predicate, which needs VK_EXT_conditional_rendering (Feature::ConditionalRendering)".into(),
        });
    }
    Ok(())
}

#[cfg(test)]
mod placement_tests {
    use super::*;
    use tilegraph_graph::assign_aliases;

    #[test]
    fn shared_resources_are_aligned_to_the_buffer_image_granularity() {
        let req = vk::MemoryRequirements {
            size: 3000,
            alignment: 256,
            memory_type_bits: 1,
        };
        let shared = placement_requirements(req, Residency::FrameLocal, 1024);
        assert_eq!((shared.size_bytes, shared.alignment_bytes), (3000, 1024));
        // A larger own alignment stays; resources with memory of their own keep theirs.
        let image = vk::MemoryRequirements {
            alignment: 65536,
            ..req
        };
        assert_eq!(
            placement_requirements(image, Residency::FrameLocal, 1024).alignment_bytes,
            65536
        );
        assert_eq!(
            placement_requirements(req, Residency::Exported, 1024).alignment_bytes,
            256
        );
        // With the alignments folded in, no two shared placements share a 1 KiB page.
        let lifetimes = [tilegraph_graph::AliasLifetime {
            lifetime: Some(tilegraph_graph::StepRange {
                first: tilegraph_graph::StepIndex(0),
                last: tilegraph_graph::StepIndex(3),
            }),
            memory: tilegraph_graph::MemoryNeed::Shared(tilegraph_graph::MemoryClass::DeviceLocal),
        }; 2];
        let a = assign_aliases(&lifetimes, &[shared, shared]).expect("valid input");
        let (Some(x), Some(y)) = (a.slots[0], a.slots[1]) else {
            panic!("both placed: {a:?}");
        };
        let pages =
            |s: tilegraph_graph::MemorySlot| (s.offset_bytes / 1024, (s.end_bytes() - 1) / 1024);
        assert!(x.block != y.block || pages(x).1 < pages(y).0 || pages(y).1 < pages(x).0);
    }
}

#[cfg(test)]
mod flag_tests {
    //! The executor hands the graph's flag bits to Vulkan unchanged (`from_raw(bits())`): every
    //! graph flag must have Vulkan's value.
    use ash::vk;
    use tilegraph_graph::{AccessFlags, BufferUsage, ImageUsage, PipelineStages};

    #[test]
    fn graph_flags_have_vulkan_values() {
        type S = vk::PipelineStageFlags2;
        let stages = [
            (PipelineStages::TOP_OF_PIPE, S::TOP_OF_PIPE),
            (PipelineStages::DRAW_INDIRECT, S::DRAW_INDIRECT),
            (PipelineStages::VERTEX_INPUT, S::VERTEX_INPUT),
            (PipelineStages::VERTEX_SHADER, S::VERTEX_SHADER),
            (PipelineStages::FRAGMENT_SHADER, S::FRAGMENT_SHADER),
            (
                PipelineStages::EARLY_FRAGMENT_TESTS,
                S::EARLY_FRAGMENT_TESTS,
            ),
            (PipelineStages::LATE_FRAGMENT_TESTS, S::LATE_FRAGMENT_TESTS),
            (
                PipelineStages::COLOR_ATTACHMENT_OUTPUT,
                S::COLOR_ATTACHMENT_OUTPUT,
            ),
            (PipelineStages::COMPUTE_SHADER, S::COMPUTE_SHADER),
            (PipelineStages::ALL_TRANSFER, S::ALL_TRANSFER),
            (PipelineStages::BOTTOM_OF_PIPE, S::BOTTOM_OF_PIPE),
            (PipelineStages::HOST, S::HOST),
            (PipelineStages::ALL_GRAPHICS, S::ALL_GRAPHICS),
            (PipelineStages::ALL_COMMANDS, S::ALL_COMMANDS),
            (
                PipelineStages::CONDITIONAL_RENDERING,
                S::CONDITIONAL_RENDERING_EXT,
            ),
            (PipelineStages::COPY, S::COPY),
            (PipelineStages::RESOLVE, S::RESOLVE),
            (PipelineStages::BLIT, S::BLIT),
            (PipelineStages::CLEAR, S::CLEAR),
            (PipelineStages::INDEX_INPUT, S::INDEX_INPUT),
            (
                PipelineStages::VERTEX_ATTRIBUTE_INPUT,
                S::VERTEX_ATTRIBUTE_INPUT,
            ),
            (
                PipelineStages::PRE_RASTERIZATION_SHADERS,
                S::PRE_RASTERIZATION_SHADERS,
            ),
        ];
        for (graph, vulkan) in stages {
            assert_eq!(graph.bits(), vulkan.as_raw(), "{vulkan:?}");
        }
        type A = vk::AccessFlags2;
        let access = [
            (AccessFlags::INDIRECT_COMMAND_READ, A::INDIRECT_COMMAND_READ),
            (AccessFlags::INDEX_READ, A::INDEX_READ),
            (AccessFlags::VERTEX_ATTRIBUTE_READ, A::VERTEX_ATTRIBUTE_READ),
            (AccessFlags::UNIFORM_READ, A::UNIFORM_READ),
            (AccessFlags::INPUT_ATTACHMENT_READ, A::INPUT_ATTACHMENT_READ),
            (AccessFlags::SHADER_READ, A::SHADER_READ),
            (AccessFlags::SHADER_WRITE, A::SHADER_WRITE),
            (AccessFlags::COLOR_ATTACHMENT_READ, A::COLOR_ATTACHMENT_READ),
            (
                AccessFlags::COLOR_ATTACHMENT_WRITE,
                A::COLOR_ATTACHMENT_WRITE,
            ),
            (
                AccessFlags::DEPTH_STENCIL_ATTACHMENT_READ,
                A::DEPTH_STENCIL_ATTACHMENT_READ,
            ),
            (
                AccessFlags::DEPTH_STENCIL_ATTACHMENT_WRITE,
                A::DEPTH_STENCIL_ATTACHMENT_WRITE,
            ),
            (AccessFlags::TRANSFER_READ, A::TRANSFER_READ),
            (AccessFlags::TRANSFER_WRITE, A::TRANSFER_WRITE),
            (AccessFlags::HOST_READ, A::HOST_READ),
            (AccessFlags::HOST_WRITE, A::HOST_WRITE),
            (AccessFlags::MEMORY_READ, A::MEMORY_READ),
            (AccessFlags::MEMORY_WRITE, A::MEMORY_WRITE),
            (
                AccessFlags::CONDITIONAL_RENDERING_READ,
                A::CONDITIONAL_RENDERING_READ_EXT,
            ),
            (AccessFlags::SHADER_SAMPLED_READ, A::SHADER_SAMPLED_READ),
            (AccessFlags::SHADER_STORAGE_READ, A::SHADER_STORAGE_READ),
            (AccessFlags::SHADER_STORAGE_WRITE, A::SHADER_STORAGE_WRITE),
        ];
        for (graph, vulkan) in access {
            assert_eq!(graph.bits(), vulkan.as_raw(), "{vulkan:?}");
        }
        type B = vk::BufferUsageFlags;
        let buffers = [
            (BufferUsage::TRANSFER_SRC, B::TRANSFER_SRC),
            (BufferUsage::TRANSFER_DST, B::TRANSFER_DST),
            (BufferUsage::UNIFORM_BUFFER, B::UNIFORM_BUFFER),
            (BufferUsage::STORAGE_BUFFER, B::STORAGE_BUFFER),
            (BufferUsage::INDEX_BUFFER, B::INDEX_BUFFER),
            (BufferUsage::VERTEX_BUFFER, B::VERTEX_BUFFER),
            (BufferUsage::INDIRECT_BUFFER, B::INDIRECT_BUFFER),
            (
                BufferUsage::CONDITIONAL_RENDERING,
                B::CONDITIONAL_RENDERING_EXT,
            ),
        ];
        for (graph, vulkan) in buffers {
            assert_eq!(graph.bits(), vulkan.as_raw(), "{vulkan:?}");
        }
        type I = vk::ImageUsageFlags;
        let images = [
            (ImageUsage::TRANSFER_SRC, I::TRANSFER_SRC),
            (ImageUsage::TRANSFER_DST, I::TRANSFER_DST),
            (ImageUsage::SAMPLED, I::SAMPLED),
            (ImageUsage::STORAGE, I::STORAGE),
            (ImageUsage::COLOR_ATTACHMENT, I::COLOR_ATTACHMENT),
            (
                ImageUsage::DEPTH_STENCIL_ATTACHMENT,
                I::DEPTH_STENCIL_ATTACHMENT,
            ),
            (ImageUsage::TRANSIENT_ATTACHMENT, I::TRANSIENT_ATTACHMENT),
            (ImageUsage::INPUT_ATTACHMENT, I::INPUT_ATTACHMENT),
        ];
        for (graph, vulkan) in images {
            assert_eq!(graph.bits(), vulkan.as_raw(), "{vulkan:?}");
        }
    }
}
