//! The first frame: one triangle into an offscreen image, read back to host memory.
//!
//! It exercises the whole path a real frame takes — profile-chosen memory, dynamic rendering,
//! synchronization2 barriers, a copy into the profile's readback memory type — with nothing else
//! in the way, so a broken driver or install shows up here first.

use ash::vk;
use tilegraph_profile::MemoryUse;

use crate::error::{VkError, VkResultExt};
use crate::readback::RgbaImage;
use crate::shader::{create_shader_module, embedded};
use crate::Context;

const CLEAR: [f32; 4] = [0.05, 0.05, 0.08, 1.0];

/// Renders the smoke-test triangle at `width` x `height` and returns the pixels.
pub fn render_triangle(ctx: &Context, width: u32, height: u32) -> Result<RgbaImage, VkError> {
    if width == 0 || height == 0 {
        return Err(VkError::Invalid {
            what: "first frame".into(),
            reason: format!("extent {width}x{height}"),
        });
    }
    let format = vk::Format::R8G8B8A8_UNORM;
    let image_info = vk::ImageCreateInfo::default()
        .image_type(vk::ImageType::TYPE_2D)
        .format(format)
        .extent(vk::Extent3D {
            width,
            height,
            depth: 1,
        })
        .mip_levels(1)
        .array_layers(1)
        .samples(vk::SampleCountFlags::TYPE_1)
        .tiling(vk::ImageTiling::OPTIMAL)
        .usage(vk::ImageUsageFlags::COLOR_ATTACHMENT | vk::ImageUsageFlags::TRANSFER_SRC)
        .initial_layout(vk::ImageLayout::UNDEFINED);
    let image = ctx.create_image("first-frame color", &image_info, MemoryUse::GpuOnly)?;
    let bytes = u64::from(width) * u64::from(height) * 4;
    let readback = match ctx.create_buffer(
        "first-frame readback",
        bytes,
        vk::BufferUsageFlags::TRANSFER_DST,
        MemoryUse::Readback,
    ) {
        Ok(b) => b,
        Err(e) => {
            ctx.destroy_image(image);
            return Err(e);
        }
    };
    let mut objects = Objects::default();
    let result = draw(ctx, &image, &readback, format, width, height, &mut objects).and_then(|_| {
        ctx.invalidate_mapped(&readback)?;
        let mapped = readback.mapped().ok_or_else(|| VkError::Invalid {
            what: "readback buffer".into(),
            reason: "memory type is not host-visible".into(),
        })?;
        Ok(RgbaImage {
            width,
            height,
            pixels: mapped[..bytes as usize].to_vec(),
        })
    });
    objects.destroy(ctx);
    ctx.destroy_buffer(readback);
    ctx.destroy_image(image);
    result
}

#[derive(Default)]
struct Objects {
    view: vk::ImageView,
    layout: vk::PipelineLayout,
    pipeline: vk::Pipeline,
    modules: Vec<vk::ShaderModule>,
}

impl Objects {
    fn destroy(self, ctx: &Context) {
        // SAFETY: the GPU work using these finished (submit_and_wait) or never started.
        unsafe {
            ctx.device.destroy_pipeline(self.pipeline, None);
            ctx.device.destroy_pipeline_layout(self.layout, None);
            ctx.device.destroy_image_view(self.view, None);
            for m in self.modules {
                ctx.device.destroy_shader_module(m, None);
            }
        }
    }
}

fn draw(
    ctx: &Context,
    image: &crate::Image,
    readback: &crate::Buffer,
    format: vk::Format,
    width: u32,
    height: u32,
    o: &mut Objects,
) -> Result<(), VkError> {
    let d = &ctx.device;
    let color_range = vk::ImageSubresourceRange::default()
        .aspect_mask(vk::ImageAspectFlags::COLOR)
        .level_count(1)
        .layer_count(1);
    let view_info = vk::ImageViewCreateInfo::default()
        .image(image.raw)
        .view_type(vk::ImageViewType::TYPE_2D)
        .format(format)
        .subresource_range(color_range);
    // SAFETY: image is live and created with a compatible format.
    o.view = unsafe { d.create_image_view(&view_info, None) }.vk("vkCreateImageView")?;
    // SAFETY: empty layout.
    o.layout = unsafe { d.create_pipeline_layout(&vk::PipelineLayoutCreateInfo::default(), None) }
        .vk("vkCreatePipelineLayout")?;
    let vs = create_shader_module(ctx, "triangle.vert", embedded::TRIANGLE_VERT)?;
    o.modules.push(vs);
    let fs = create_shader_module(ctx, "triangle.frag", embedded::TRIANGLE_FRAG)?;
    o.modules.push(fs);
    let stages = [
        vk::PipelineShaderStageCreateInfo::default()
            .stage(vk::ShaderStageFlags::VERTEX)
            .module(vs)
            .name(c"main"),
        vk::PipelineShaderStageCreateInfo::default()
            .stage(vk::ShaderStageFlags::FRAGMENT)
            .module(fs)
            .name(c"main"),
    ];
    let vertex_input = vk::PipelineVertexInputStateCreateInfo::default();
    let assembly = vk::PipelineInputAssemblyStateCreateInfo::default()
        .topology(vk::PrimitiveTopology::TRIANGLE_LIST);
    let viewport_state = vk::PipelineViewportStateCreateInfo::default()
        .viewport_count(1)
        .scissor_count(1);
    let raster = vk::PipelineRasterizationStateCreateInfo::default()
        .polygon_mode(vk::PolygonMode::FILL)
        .cull_mode(vk::CullModeFlags::NONE)
        .line_width(1.0);
    let multisample = vk::PipelineMultisampleStateCreateInfo::default()
        .rasterization_samples(vk::SampleCountFlags::TYPE_1);
    let blend_attachments = [vk::PipelineColorBlendAttachmentState::default()
        .color_write_mask(vk::ColorComponentFlags::RGBA)];
    let blend = vk::PipelineColorBlendStateCreateInfo::default().attachments(&blend_attachments);
    let dynamic = [vk::DynamicState::VIEWPORT, vk::DynamicState::SCISSOR];
    let dynamic_state = vk::PipelineDynamicStateCreateInfo::default().dynamic_states(&dynamic);
    let formats = [format];
    let mut rendering =
        vk::PipelineRenderingCreateInfo::default().color_attachment_formats(&formats);
    let info = vk::GraphicsPipelineCreateInfo::default()
        .stages(&stages)
        .vertex_input_state(&vertex_input)
        .input_assembly_state(&assembly)
        .viewport_state(&viewport_state)
        .rasterization_state(&raster)
        .multisample_state(&multisample)
        .color_blend_state(&blend)
        .dynamic_state(&dynamic_state)
        .layout(o.layout)
        .push_next(&mut rendering);
    // SAFETY: every referenced state struct lives until the call returns.
    o.pipeline = unsafe { d.create_graphics_pipelines(vk::PipelineCache::null(), &[info], None) }
        .map_err(|(_, r)| VkError::call("vkCreateGraphicsPipelines", r))?
        .first()
        .copied()
        .ok_or_else(|| VkError::Invalid {
            what: "pipeline".into(),
            reason: "none returned".into(),
        })?;

    ctx.submit_and_wait(|cb| {
        let to_color = [vk::ImageMemoryBarrier2::default()
            .src_stage_mask(vk::PipelineStageFlags2::NONE)
            .src_access_mask(vk::AccessFlags2::NONE)
            .dst_stage_mask(vk::PipelineStageFlags2::COLOR_ATTACHMENT_OUTPUT)
            .dst_access_mask(vk::AccessFlags2::COLOR_ATTACHMENT_WRITE)
            .old_layout(vk::ImageLayout::UNDEFINED)
            .new_layout(vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL)
            .image(image.raw)
            .subresource_range(color_range)];
        ctx.cmd_pipeline_barrier2(
            cb,
            &vk::DependencyInfo::default().image_memory_barriers(&to_color),
        )?;
        ctx.begin_label(cb, "first-frame triangle");
        let attachments = [vk::RenderingAttachmentInfo::default()
            .image_view(o.view)
            .image_layout(vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL)
            .load_op(vk::AttachmentLoadOp::CLEAR)
            .store_op(vk::AttachmentStoreOp::STORE)
            .clear_value(vk::ClearValue {
                color: vk::ClearColorValue { float32: CLEAR },
            })];
        let area = vk::Rect2D {
            offset: vk::Offset2D::default(),
            extent: vk::Extent2D { width, height },
        };
        let rendering = vk::RenderingInfo::default()
            .render_area(area)
            .layer_count(1)
            .color_attachments(&attachments);
        ctx.cmd_begin_rendering(cb, &rendering)?;
        let viewport = vk::Viewport {
            x: 0.0,
            y: 0.0,
            width: width as f32,
            height: height as f32,
            min_depth: 0.0,
            max_depth: 1.0,
        };
        // SAFETY: recording inside a rendering scope with a compatible pipeline.
        unsafe {
            d.cmd_bind_pipeline(cb, vk::PipelineBindPoint::GRAPHICS, o.pipeline);
            d.cmd_set_viewport(cb, 0, &[viewport]);
            d.cmd_set_scissor(cb, 0, &[area]);
            d.cmd_draw(cb, 3, 1, 0, 0);
        }
        ctx.cmd_end_rendering(cb)?;
        ctx.end_label(cb);
        let to_transfer = [vk::ImageMemoryBarrier2::default()
            .src_stage_mask(vk::PipelineStageFlags2::COLOR_ATTACHMENT_OUTPUT)
            .src_access_mask(vk::AccessFlags2::COLOR_ATTACHMENT_WRITE)
            .dst_stage_mask(vk::PipelineStageFlags2::COPY)
            .dst_access_mask(vk::AccessFlags2::TRANSFER_READ)
            .old_layout(vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL)
            .new_layout(vk::ImageLayout::TRANSFER_SRC_OPTIMAL)
            .image(image.raw)
            .subresource_range(color_range)];
        ctx.cmd_pipeline_barrier2(
            cb,
            &vk::DependencyInfo::default().image_memory_barriers(&to_transfer),
        )?;
        let region = vk::BufferImageCopy::default()
            .image_subresource(
                vk::ImageSubresourceLayers::default()
                    .aspect_mask(vk::ImageAspectFlags::COLOR)
                    .layer_count(1),
            )
            .image_extent(vk::Extent3D {
                width,
                height,
                depth: 1,
            });
        // SAFETY: image is in TRANSFER_SRC_OPTIMAL; buffer is large enough (w*h*4).
        unsafe {
            d.cmd_copy_image_to_buffer(
                cb,
                image.raw,
                vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
                readback.raw,
                &[region],
            )
        };
        let to_host = [vk::BufferMemoryBarrier2::default()
            .src_stage_mask(vk::PipelineStageFlags2::COPY)
            .src_access_mask(vk::AccessFlags2::TRANSFER_WRITE)
            .dst_stage_mask(vk::PipelineStageFlags2::HOST)
            .dst_access_mask(vk::AccessFlags2::HOST_READ)
            .buffer(readback.raw)
            .size(vk::WHOLE_SIZE)];
        ctx.cmd_pipeline_barrier2(
            cb,
            &vk::DependencyInfo::default().buffer_memory_barriers(&to_host),
        )?;
        Ok(())
    })
}
