//! The light's shadow atlas: one depth image holding every cascade (side by side for one or
//! two, a 2x2 grid for three or four), so the cascades are one render pass and one depth
//! attachment stored — what a tiler wants (one load/store per frame, not one per cascade) — and
//! the shading samples one texture. It lives as long as the renderer and sits, between frames,
//! in the layout the shading samples it in; a renderer without shadows keeps a 1x1 atlas there,
//! so set 0's binding is always valid.

use tilegraph_cull::DepthFormat;
use tilegraph_graph::{AccessFlags, Layout, PipelineStages, ResourceState};
use tilegraph_vk::ash::vk;
use tilegraph_vk::executor::ImageHandle;
use tilegraph_vk::{Context, Image, VkError};

use crate::images::{create_image_2d, destroy_target};

/// The binding of the atlas in the scene's set 0 (`shaders/common/shadow.glsl`).
pub const SHADOW_BINDING: u32 = 9;

/// The layout, stages and access the atlas is in between frames: sampled by the shading.
pub const SAMPLED: ResourceState = ResourceState::image(
    Layout::DepthStencilReadOnly,
    PipelineStages::FRAGMENT_SHADER,
    AccessFlags::SHADER_SAMPLED_READ,
);

/// What an atlas is made for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct AtlasDesc {
    /// 0 (no shadows: a 1x1 atlas) to 4.
    pub cascades: u32,
    /// Texels on a side of one cascade.
    pub resolution: u32,
    pub format: DepthFormat,
}

impl AtlasDesc {
    /// Cascades across and down.
    pub fn grid(&self) -> (u32, u32) {
        match self.cascades {
            0 => (1, 1),
            n @ 1..=2 => (n, 1),
            _ => (2, 2),
        }
    }

    /// The atlas's extent in texels.
    pub fn extent(&self) -> (u32, u32) {
        if self.cascades == 0 {
            return (1, 1);
        }
        let (c, r) = self.grid();
        (c * self.resolution, r * self.resolution)
    }

    pub fn vk_format(&self) -> vk::Format {
        match self.format {
            DepthFormat::D16Unorm => vk::Format::D16_UNORM,
            DepthFormat::D32Float => vk::Format::D32_SFLOAT,
        }
    }

    /// The cascade's rectangle in the atlas: x, y offset.
    pub fn offset(&self, cascade: u32) -> (u32, u32) {
        let (cols, _) = self.grid();
        (
            (cascade % cols) * self.resolution,
            (cascade / cols) * self.resolution,
        )
    }
}

/// The atlas: its image and view, and the comparison sampler the shading reads it with.
pub struct ShadowAtlas {
    pub desc: AtlasDesc,
    image: (Image, ImageHandle),
    sampler: vk::Sampler,
}

impl ShadowAtlas {
    /// Makes the atlas of `desc` and moves it to the layout it is sampled in.
    pub fn new(ctx: &Context, desc: AtlasDesc) -> Result<Self, VkError> {
        let (w, h) = desc.extent();
        let max = ctx.physical.limits.max_image_dimension_2d;
        if w > max || h > max {
            return Err(VkError::Invalid {
                what: "shadow atlas".into(),
                reason: format!(
                    "{} cascades of {} texels need {w}x{h}, above the device's {max}",
                    desc.cascades, desc.resolution
                ),
            });
        }
        let format = desc.vk_format();
        let usage = vk::ImageUsageFlags::DEPTH_STENCIL_ATTACHMENT
            | vk::ImageUsageFlags::SAMPLED
            | vk::ImageUsageFlags::TRANSFER_DST;
        let aspect = vk::ImageAspectFlags::DEPTH;
        let mut atlas = ShadowAtlas {
            desc,
            image: create_image_2d(ctx, "shadow atlas", (w, h), format, usage, aspect)?,
            sampler: vk::Sampler::null(),
        };
        match atlas.init(ctx, format) {
            Ok(()) => Ok(atlas),
            Err(e) => {
                atlas.destroy(ctx);
                Err(e)
            }
        }
    }

    fn init(&mut self, ctx: &Context, format: vk::Format) -> Result<(), VkError> {
        // Bilinear compares (2x2 PCF per tap) where the format filters linearly.
        let linear = ctx
            .format_features(format)
            .contains(vk::FormatFeatureFlags::SAMPLED_IMAGE_FILTER_LINEAR);
        let filter = if linear {
            vk::Filter::LINEAR
        } else {
            vk::Filter::NEAREST
        };
        let info = vk::SamplerCreateInfo::default()
            .mag_filter(filter)
            .min_filter(filter)
            .mipmap_mode(vk::SamplerMipmapMode::NEAREST)
            .address_mode_u(vk::SamplerAddressMode::CLAMP_TO_EDGE)
            .address_mode_v(vk::SamplerAddressMode::CLAMP_TO_EDGE)
            .address_mode_w(vk::SamplerAddressMode::CLAMP_TO_EDGE)
            .compare_enable(true)
            .compare_op(vk::CompareOp::LESS_OR_EQUAL)
            .max_lod(vk::LOD_CLAMP_NONE);
        // SAFETY: valid create info.
        self.sampler = unsafe { ctx.device.create_sampler(&info, None) }
            .map_err(|r| VkError::call("vkCreateSampler", r))?;
        let image = self.handle().raw;
        let range = vk::ImageSubresourceRange {
            aspect_mask: vk::ImageAspectFlags::DEPTH,
            base_mip_level: 0,
            level_count: 1,
            base_array_layer: 0,
            layer_count: 1,
        };
        // Cleared to the far end (everything lit) and left where the shading samples it.
        ctx.submit_and_wait(|cb| {
            let to_clear = [vk::ImageMemoryBarrier2::default()
                .src_stage_mask(vk::PipelineStageFlags2::NONE)
                .dst_stage_mask(vk::PipelineStageFlags2::CLEAR)
                .dst_access_mask(vk::AccessFlags2::TRANSFER_WRITE)
                .old_layout(vk::ImageLayout::UNDEFINED)
                .new_layout(vk::ImageLayout::TRANSFER_DST_OPTIMAL)
                .image(image)
                .subresource_range(range)];
            ctx.cmd_pipeline_barrier2(
                cb,
                &vk::DependencyInfo::default().image_memory_barriers(&to_clear),
            )?;
            let far = vk::ClearDepthStencilValue {
                depth: 1.0,
                stencil: 0,
            };
            // SAFETY: live image in TRANSFER_DST_OPTIMAL; the range is its only subresource.
            unsafe {
                ctx.device.cmd_clear_depth_stencil_image(
                    cb,
                    image,
                    vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                    &far,
                    &[range],
                )
            };
            let to_read = [vk::ImageMemoryBarrier2::default()
                .src_stage_mask(vk::PipelineStageFlags2::CLEAR)
                .src_access_mask(vk::AccessFlags2::TRANSFER_WRITE)
                .dst_stage_mask(vk::PipelineStageFlags2::FRAGMENT_SHADER)
                .dst_access_mask(vk::AccessFlags2::SHADER_SAMPLED_READ)
                .old_layout(vk::ImageLayout::TRANSFER_DST_OPTIMAL)
                .new_layout(vk::ImageLayout::DEPTH_STENCIL_READ_ONLY_OPTIMAL)
                .image(image)
                .subresource_range(range)];
            ctx.cmd_pipeline_barrier2(
                cb,
                &vk::DependencyInfo::default().image_memory_barriers(&to_read),
            )
        })
    }

    /// The image as the graph's executor binds it.
    pub fn handle(&self) -> &ImageHandle {
        &self.image.1
    }

    /// Set 0's descriptor of the atlas.
    pub fn descriptor(&self) -> vk::DescriptorImageInfo {
        vk::DescriptorImageInfo {
            sampler: self.sampler,
            image_view: self.handle().view,
            image_layout: vk::ImageLayout::DEPTH_STENCIL_READ_ONLY_OPTIMAL,
        }
    }

    /// Destroys the image and sampler; the GPU must be done with them.
    pub fn destroy(self, ctx: &Context) {
        // SAFETY: the GPU is done with it (caller's guarantee); null is ignored.
        unsafe { ctx.device.destroy_sampler(self.sampler, None) };
        destroy_target(ctx, self.image);
    }
}
