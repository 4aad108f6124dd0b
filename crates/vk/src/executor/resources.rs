//! Physical resources of a plan: images and buffers created with the plan's usage flags, their
//! memory placed again with the driver's real requirements (`Plan::reassign_aliases`, which
//! also redoes the barriers the new placement needs), aliased in shared blocks where the plan
//! allows and lazily allocated where it makes attachments transient; and the caller's
//! resources for the plan's imports.

use std::collections::HashMap;

use ash::vk;
use tilegraph_graph::{
    MemoryRequirements, Plan, PlanResource, Residency, ResourceDesc, ResourceId, StoreOp, Usage,
};
use tilegraph_profile::MemoryUse;

use crate::error::{VkError, VkResultExt};
use crate::Context;

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

/// The physical resources of a plan's imported resources, by [`ResourceId`]: what the caller
/// hands in with each frame. Built once per declaration (a frame that reuses its plan reuses
/// its externals too).
#[derive(Debug, Clone, Default)]
pub struct Externals {
    slots: Vec<Option<External>>,
}

impl Externals {
    pub fn new() -> Self {
        Externals::default()
    }

    /// Gives resource `id` its physical resource (replacing an earlier one).
    pub fn insert(&mut self, id: impl Into<ResourceId>, external: External) {
        let i = id.into().index();
        if self.slots.len() <= i {
            self.slots.resize(i + 1, None);
        }
        self.slots[i] = Some(external);
    }

    pub fn get(&self, id: ResourceId) -> Option<&External> {
        self.slots.get(id.index()).and_then(Option::as_ref)
    }

    pub fn is_empty(&self) -> bool {
        self.slots.iter().all(Option::is_none)
    }
}

impl<I: Into<ResourceId>> FromIterator<(I, External)> for Externals {
    fn from_iter<T: IntoIterator<Item = (I, External)>>(iter: T) -> Self {
        let mut e = Externals::new();
        for (id, external) in iter {
            e.insert(id, external);
        }
        e
    }
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

    /// The plan as recorded: the compiled one with memory slots and barriers redone for the
    /// real memory requirements (the compiled one when that failed).
    pub(super) fn placed(&self) -> Option<&Plan> {
        self.placed.as_ref()
    }

    /// Whether aliased resources share memory.
    pub(super) fn aliasing_used(&self) -> bool {
        self.aliasing_used
    }

    /// Views of the images the graph owns.
    pub(super) fn owned_views(&self) -> impl Iterator<Item = vk::ImageView> + '_ {
        self.images.values().map(|i| i.handle.view)
    }

    pub(super) fn destroy(self, ctx: &Context) {
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
pub(super) fn build_resources(ctx: &Context, plan: &Plan) -> Result<Resources, VkError> {
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
    // Concurrent sharing between the two queues' families (where they differ) for what the
    // async compute queue uses: images where the plan says so, buffers always (the plan moves
    // no buffer between families; `Context::buffer_families`).
    let families = [
        ctx.queue_family,
        ctx.async_queue.map_or(ctx.queue_family, |q| q.family),
    ];
    let concurrent_sharing = plan.queue_sharing == tilegraph_profile::QueueSharing::Concurrent
        && families[0] != families[1];
    for r in &plan.resources {
        let is_buffer = matches!(r.desc, ResourceDesc::Buffer(_));
        let shared =
            (concurrent_sharing || (is_buffer && families[0] != families[1])) && r.async_queue;
        let (sharing, sharing_families): (vk::SharingMode, &[u32]) = if shared {
            (vk::SharingMode::CONCURRENT, &families)
        } else {
            (vk::SharingMode::EXCLUSIVE, &[])
        };
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
                    .sharing_mode(sharing)
                    .queue_family_indices(sharing_families)
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
                    .sharing_mode(sharing)
                    .queue_family_indices(sharing_families);
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

/// What aliasing places a resource with: its `VkMemoryRequirements`, and for frame-local
/// resources (the ones that share blocks) an alignment of at least `bufferImageGranularity`, so
/// a buffer and an image in one block never share a granularity page (the contract
/// `tilegraph_graph::assign_aliases` states for real requirements).
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
