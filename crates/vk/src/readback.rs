//! Reading GPU results on the host: a copy into a buffer of the profile's readback memory type,
//! then a fence wait. For tests and tools, never on a per-frame path (it waits).

use ash::vk;
use tilegraph_profile::MemoryUse;

use crate::executor::sync::{accesses_in, earlier_work, writes_in};
use crate::executor::{BufferHandle, ImageHandle};
use crate::{Context, VkError};

/// An RGBA8 image read back from the GPU, rows top to bottom.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RgbaImage {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<u8>,
}

impl RgbaImage {
    pub fn pixel(&self, x: u32, y: u32) -> Option<[u8; 4]> {
        if x >= self.width || y >= self.height {
            return None;
        }
        let i = ((y * self.width + x) * 4) as usize;
        self.pixels.get(i..i + 4).map(|p| [p[0], p[1], p[2], p[3]])
    }
}

/// Bytes per texel of the formats tilegraph reads back.
pub fn texel_bytes(format: vk::Format) -> Option<u32> {
    Some(match format {
        vk::Format::R8G8B8A8_UNORM
        | vk::Format::R8G8B8A8_SRGB
        | vk::Format::B8G8R8A8_UNORM
        | vk::Format::B8G8R8A8_SRGB => 4,
        vk::Format::R32_UINT | vk::Format::R32_SFLOAT | vk::Format::D32_SFLOAT => 4,
        vk::Format::R16_SFLOAT | vk::Format::D16_UNORM => 2,
        vk::Format::R32G32_UINT | vk::Format::R16G16B16A16_SFLOAT => 8,
        _ => return None,
    })
}

/// Copies mip `level` of `image` (currently in `layout`, left in `layout`) to host memory, rows
/// tightly packed, top row first. Waits for the earlier GPU work of every stage a graph can
/// declare ([`crate::executor::sync::earlier_work`]; an engine image last touched by other
/// stages — ray tracing, say — needs the engine's own barrier first), so call it after the
/// frame that wrote the image was submitted.
pub fn read_image(
    ctx: &Context,
    image: &ImageHandle,
    layout: vk::ImageLayout,
    level: u32,
) -> Result<Vec<u8>, VkError> {
    let bpp = texel_bytes(image.format).ok_or_else(|| VkError::Invalid {
        what: "readback".into(),
        reason: format!("format {:?} is not readable", image.format),
    })?;
    if level >= image.mip_levels {
        return Err(VkError::Invalid {
            what: "readback".into(),
            reason: format!(
                "mip level {level} of an image with {} levels",
                image.mip_levels
            ),
        });
    }
    let w = (image.extent.width >> level).max(1);
    let h = (image.extent.height >> level).max(1);
    let bytes = u64::from(w) * u64::from(h) * u64::from(bpp);
    let buffer = ctx.create_buffer(
        "readback",
        bytes,
        vk::BufferUsageFlags::TRANSFER_DST,
        MemoryUse::Readback,
    )?;
    let aspect = if image.aspect.contains(vk::ImageAspectFlags::DEPTH) {
        vk::ImageAspectFlags::DEPTH
    } else {
        vk::ImageAspectFlags::COLOR
    };
    // Only the level copied changes layout: the others may be in other layouts.
    let range = vk::ImageSubresourceRange {
        aspect_mask: image.aspect,
        base_mip_level: level,
        level_count: 1,
        base_array_layer: 0,
        layer_count: 1,
    };
    let earlier = earlier_work(ctx.has_feature(crate::Feature::ConditionalRendering));
    // An image found undefined is left in GENERAL, which every later use may transition from.
    let back_layout = if layout == vk::ImageLayout::UNDEFINED {
        vk::ImageLayout::GENERAL
    } else {
        layout
    };
    let copied = ctx.submit_and_wait(|cb| {
        let to_src = [vk::ImageMemoryBarrier2::default()
            .src_stage_mask(earlier)
            .src_access_mask(writes_in(layout))
            .dst_stage_mask(vk::PipelineStageFlags2::COPY)
            .dst_access_mask(vk::AccessFlags2::TRANSFER_READ)
            .old_layout(layout)
            .new_layout(vk::ImageLayout::TRANSFER_SRC_OPTIMAL)
            .image(image.raw)
            .subresource_range(range)];
        ctx.cmd_pipeline_barrier2(
            cb,
            &vk::DependencyInfo::default().image_memory_barriers(&to_src),
        )?;
        let region = vk::BufferImageCopy::default()
            .image_subresource(vk::ImageSubresourceLayers {
                aspect_mask: aspect,
                mip_level: level,
                base_array_layer: 0,
                layer_count: 1,
            })
            .image_extent(vk::Extent3D {
                width: w,
                height: h,
                depth: 1,
            });
        // SAFETY: image in TRANSFER_SRC_OPTIMAL; buffer holds w*h*bpp bytes.
        unsafe {
            ctx.device.cmd_copy_image_to_buffer(
                cb,
                image.raw,
                vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
                buffer.raw,
                &[region],
            )
        };
        let back = [vk::ImageMemoryBarrier2::default()
            .src_stage_mask(vk::PipelineStageFlags2::COPY)
            .src_access_mask(vk::AccessFlags2::TRANSFER_READ)
            .dst_stage_mask(earlier)
            .dst_access_mask(accesses_in(back_layout))
            .old_layout(vk::ImageLayout::TRANSFER_SRC_OPTIMAL)
            .new_layout(back_layout)
            .image(image.raw)
            .subresource_range(range)];
        let to_host = [vk::BufferMemoryBarrier2::default()
            .src_stage_mask(vk::PipelineStageFlags2::COPY)
            .src_access_mask(vk::AccessFlags2::TRANSFER_WRITE)
            .dst_stage_mask(vk::PipelineStageFlags2::HOST)
            .dst_access_mask(vk::AccessFlags2::HOST_READ)
            .buffer(buffer.raw)
            .size(vk::WHOLE_SIZE)];
        ctx.cmd_pipeline_barrier2(
            cb,
            &vk::DependencyInfo::default()
                .image_memory_barriers(&back)
                .buffer_memory_barriers(&to_host),
        )
    });
    let result = copied
        .and_then(|_| ctx.invalidate_mapped(&buffer))
        .and_then(|_| {
            buffer
                .mapped()
                .map(|m| m[..bytes as usize].to_vec())
                .ok_or_else(|| VkError::Invalid {
                    what: "readback".into(),
                    reason: "readback memory is not host-visible".into(),
                })
        });
    ctx.destroy_buffer(buffer);
    result
}

/// Copies a GPU buffer to host memory (waits for all earlier GPU work).
pub fn read_buffer(ctx: &Context, src: BufferHandle) -> Result<Vec<u8>, VkError> {
    let size = src.size.max(4);
    let buffer = ctx.create_buffer(
        "readback",
        size,
        vk::BufferUsageFlags::TRANSFER_DST,
        MemoryUse::Readback,
    )?;
    let earlier = earlier_work(ctx.has_feature(crate::Feature::ConditionalRendering));
    let copied = ctx.submit_and_wait(|cb| {
        let before = [vk::MemoryBarrier2::default()
            .src_stage_mask(earlier)
            .src_access_mask(vk::AccessFlags2::MEMORY_WRITE)
            .dst_stage_mask(vk::PipelineStageFlags2::COPY)
            .dst_access_mask(vk::AccessFlags2::TRANSFER_READ)];
        ctx.cmd_pipeline_barrier2(cb, &vk::DependencyInfo::default().memory_barriers(&before))?;
        // SAFETY: both buffers hold at least `size` bytes.
        unsafe {
            ctx.device.cmd_copy_buffer(
                cb,
                src.raw,
                buffer.raw,
                &[vk::BufferCopy {
                    src_offset: 0,
                    dst_offset: 0,
                    size: src.size,
                }],
            )
        };
        let after = [vk::MemoryBarrier2::default()
            .src_stage_mask(vk::PipelineStageFlags2::COPY)
            .src_access_mask(vk::AccessFlags2::TRANSFER_WRITE)
            .dst_stage_mask(vk::PipelineStageFlags2::HOST)
            .dst_access_mask(vk::AccessFlags2::HOST_READ)];
        ctx.cmd_pipeline_barrier2(cb, &vk::DependencyInfo::default().memory_barriers(&after))
    });
    let result = copied
        .and_then(|_| ctx.invalidate_mapped(&buffer))
        .and_then(|_| {
            buffer
                .mapped()
                .map(|m| m[..src.size as usize].to_vec())
                .ok_or_else(|| VkError::Invalid {
                    what: "readback".into(),
                    reason: "readback memory is not host-visible".into(),
                })
        });
    ctx.destroy_buffer(buffer);
    result
}
