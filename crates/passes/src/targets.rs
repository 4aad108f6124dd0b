//! The images the scene passes draw into — colour, depth, and the visibility buffer's ids — and
//! which of them a pass of this frame has written yet: the first use of each clears it, every
//! later one keeps what is there. The render targets a renderer owns across frames are created
//! here too.

use tilegraph_graph::{ClearColor, ClearDepthStencil, Extent2d, ImageId, RasterPassBuilder};
use tilegraph_profile::MemoryUse;
use tilegraph_scene::DepthConvention;
use tilegraph_vk::ash::vk;
use tilegraph_vk::executor::ImageHandle;
use tilegraph_vk::{Context, Image, VkError};

use crate::frame::Payload;

/// The scene's attachments in one frame's graph.
#[derive(Debug, Clone)]
pub struct SceneTargets {
    pub color: ImageId,
    pub depth: ImageId,
    /// The visibility buffer's ids: imported when the caller keeps them, else created by the
    /// first id pass.
    pub ids: Option<ImageId>,
    pub extent: Extent2d,
    color_clear: ClearColor,
    depth_clear: ClearDepthStencil,
    color_written: bool,
    depth_written: bool,
}

impl SceneTargets {
    /// Targets that no pass has written yet: colour clears to `clear_color`, depth to the far
    /// plane of `depth_convention`.
    pub fn new(
        color: ImageId,
        depth: ImageId,
        extent: Extent2d,
        clear_color: [f32; 4],
        depth_convention: DepthConvention,
    ) -> Self {
        SceneTargets {
            color,
            depth,
            ids: None,
            extent,
            color_clear: ClearColor::Float(clear_color),
            depth_clear: ClearDepthStencil {
                depth: depth_convention.far_depth(),
                stencil: 0,
            },
            color_written: false,
            depth_written: false,
        }
    }

    /// Whether a pass of this frame drew colour.
    pub fn color_written(&self) -> bool {
        self.color_written
    }

    /// Whether a pass of this frame wrote depth (there is something to test against).
    pub fn depth_written(&self) -> bool {
        self.depth_written
    }

    /// The depth clear value (the far plane).
    pub fn depth_clear(&self) -> ClearDepthStencil {
        self.depth_clear
    }

    /// Attaches the colour target to `pass`: cleared by the frame's first colour pass.
    pub fn attach_color(&mut self, pass: &mut RasterPassBuilder<'_, Payload>) {
        if self.color_written {
            pass.color(self.color);
        } else {
            pass.color_clear(self.color, self.color_clear);
            self.color_written = true;
        }
    }

    /// Attaches depth to `pass`, tested and written, or tested only (`read_only`): cleared by
    /// the frame's first depth pass, which always writes.
    pub fn attach_depth(&mut self, pass: &mut RasterPassBuilder<'_, Payload>, read_only: bool) {
        if !self.depth_written {
            pass.depth_stencil_clear(self.depth, self.depth_clear);
            self.depth_written = true;
        } else if read_only {
            pass.depth_stencil_read_only(self.depth);
        } else {
            pass.depth_stencil(self.depth);
        }
    }
}

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
