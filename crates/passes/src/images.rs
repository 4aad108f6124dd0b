//! The images a renderer keeps across frames (its colour target, the captured ids, the shadow
//! atlas): device-local 2D images of one mip and layer, each with a view.

use tilegraph_profile::MemoryUse;
use tilegraph_vk::ash::vk;
use tilegraph_vk::executor::ImageHandle;
use tilegraph_vk::{Context, Image, VkError};

/// A 2D image the renderer keeps across frames (its colour target, the captured ids), with a
/// view: a colour attachment the caller can copy from.
pub fn create_target(
    ctx: &Context,
    size: (u32, u32),
    format: vk::Format,
) -> Result<(Image, ImageHandle), VkError> {
    let extra = if format == vk::Format::R32_UINT {
        vk::ImageUsageFlags::INPUT_ATTACHMENT | vk::ImageUsageFlags::SAMPLED
    } else {
        vk::ImageUsageFlags::empty()
    };
    let usage = vk::ImageUsageFlags::COLOR_ATTACHMENT | vk::ImageUsageFlags::TRANSFER_SRC | extra;
    create_image_2d(
        ctx,
        "render target",
        size,
        format,
        usage,
        vk::ImageAspectFlags::COLOR,
    )
}

/// A device-local 2D image of one mip and layer, with a view of `aspect` (a colour target, a
/// depth image a tool fills); destroyed with [`destroy_target`].
pub fn create_image_2d(
    ctx: &Context,
    name: &str,
    (w, h): (u32, u32),
    format: vk::Format,
    usage: vk::ImageUsageFlags,
    aspect: vk::ImageAspectFlags,
) -> Result<(Image, ImageHandle), VkError> {
    let info = vk::ImageCreateInfo::default()
        .image_type(vk::ImageType::TYPE_2D)
        .format(format)
        .extent(vk::Extent3D {
            width: w,
            height: h,
            depth: 1,
        })
        .mip_levels(1)
        .array_layers(1)
        .samples(vk::SampleCountFlags::TYPE_1)
        .tiling(vk::ImageTiling::OPTIMAL)
        .usage(usage)
        .initial_layout(vk::ImageLayout::UNDEFINED);
    let image = ctx.create_image(name, &info, MemoryUse::GpuOnly)?;
    let view_info = vk::ImageViewCreateInfo::default()
        .image(image.raw)
        .view_type(vk::ImageViewType::TYPE_2D)
        .format(format)
        .subresource_range(vk::ImageSubresourceRange {
            aspect_mask: aspect,
            base_mip_level: 0,
            level_count: 1,
            base_array_layer: 0,
            layer_count: 1,
        });
    // SAFETY: live image with bound memory.
    let view = match unsafe { ctx.device.create_image_view(&view_info, None) } {
        Ok(v) => v,
        Err(r) => {
            ctx.destroy_image(image);
            return Err(VkError::call("vkCreateImageView", r));
        }
    };
    let handle = ImageHandle {
        raw: image.raw,
        view,
        full_view: view,
        mip_views: Vec::new(),
        format,
        extent: vk::Extent2D {
            width: w,
            height: h,
        },
        mip_levels: 1,
        aspect,
    };
    Ok((image, handle))
}

/// Destroys an image made by [`create_target`] or [`create_image_2d`]; the GPU must be done
/// with it.
pub fn destroy_target(ctx: &Context, (image, handle): (Image, ImageHandle)) {
    // SAFETY: the GPU is done with the view (caller's guarantee).
    unsafe { ctx.device.destroy_image_view(handle.view, None) };
    ctx.destroy_image(image);
}
