//! The scene's textures on the GPU: uploaded once with their mip chains, bound at set 0,
//! binding [`TEXTURE_BINDING`] as `TEXTURE_SLOTS` array images (`shaders/common/textures.glsl`).
//!
//! Two bindings, chosen per device and profile ([`TexturePolicy`]):
//! - [`TextureBinding::Indexed`]: one descriptor per texture, each its own image and sampler;
//!   the shaders index the array by the material's texture (per pixel in the visibility-buffer
//!   resolve: `shaderSampledImageArrayNonUniformIndexing`).
//! - [`TextureBinding::Layers`]: every texture resampled to the largest size among them, one
//!   layer each of a single array image with one trilinear, repeating sampler: one descriptor,
//!   no indexing feature. glTF samplers other than the default are not honoured there (logged).
//!
//! A scene without textures binds one white texel, so the binding is always valid.

use tilegraph_profile::MemoryUse;
use tilegraph_profile::{TextureBinding, TexturePolicy};
use tilegraph_scene::texture::{Sampler, Wrap};
use tilegraph_scene::{Scene, Texture};
use tilegraph_vk::ash::vk;
use tilegraph_vk::{Buffer, Context, Feature, Image, VkError};

/// The binding of the textures in the scene's set 0.
pub const TEXTURE_BINDING: u32 = 8;

/// Combined image samplers other than the scene's that a fragment stage of the scene's
/// pipelines may bind (the sampled visibility buffer): kept free of the device's limit.
const OTHER_SAMPLERS: u32 = 4;

/// The format of every texture: glTF base colour is sRGB, decoded by the sampler.
const FORMAT: vk::Format = vk::Format::R8G8B8A8_SRGB;

/// The binding `policy` gets on `ctx`'s device for `textures` textures, and why when it is not
/// the policy's.
pub fn choose_binding(
    ctx: &Context,
    policy: TexturePolicy,
    textures: usize,
) -> (TextureBinding, Option<String>) {
    if policy.binding == TextureBinding::Layers {
        return (TextureBinding::Layers, None);
    }
    let features = [
        Feature::SampledImageArrayDynamicIndexing,
        Feature::SampledImageArrayNonUniformIndexing,
    ];
    if let Some(f) = features.iter().find(|f| !ctx.has_feature(**f)) {
        return (
            TextureBinding::Layers,
            Some(format!("the device has no {f}")),
        );
    }
    let device_cap = ctx
        .physical
        .limits
        .max_sampled_images
        .saturating_sub(OTHER_SAMPLERS);
    let cap = device_cap.min(policy.max_indexed) as usize;
    if textures > cap {
        return (
            TextureBinding::Layers,
            Some(format!(
                "{textures} textures, more than the {cap} bound as an array \
                 (profile max_indexed {}, device {device_cap})",
                policy.max_indexed
            )),
        );
    }
    (TextureBinding::Indexed, None)
}

/// The scene's textures as the shaders bind them.
pub struct GpuTextures {
    pub binding: TextureBinding,
    /// Images with their array views.
    images: Vec<(Image, vk::ImageView)>,
    samplers: Vec<vk::Sampler>,
    /// Per descriptor of the binding: (view, sampler).
    slots: Vec<(vk::ImageView, vk::Sampler)>,
    /// Texel bytes uploaded (every level of every layer).
    bytes: u64,
}

impl GpuTextures {
    /// Uploads `scene`'s textures bound as `policy` asks where the device can (waits for the
    /// copy: a load-time step).
    pub fn new(ctx: &Context, scene: &Scene, policy: TexturePolicy) -> Result<Self, VkError> {
        let (binding, why) = choose_binding(ctx, policy, scene.textures().len());
        if let Some(why) = why {
            log::info!(
                "{}: textures bound as layers of one image: {why}",
                scene.name()
            );
        }
        let mut made = GpuTextures {
            binding,
            images: Vec::new(),
            samplers: Vec::new(),
            slots: Vec::new(),
            bytes: 0,
        };
        match made.upload(ctx, scene) {
            Ok(()) => {
                if scene.textures().is_empty() {
                    // The white texel is the binding's, not the scene's.
                    made.bytes = 0;
                }
                Ok(made)
            }
            Err(e) => {
                made.destroy(ctx);
                Err(e)
            }
        }
    }

    /// Texel bytes on the GPU (every level of every image).
    pub fn bytes(&self) -> u64 {
        self.bytes
    }

    /// Descriptors in the binding: what `TEXTURE_SLOTS` is specialized to.
    pub fn slot_count(&self) -> u32 {
        self.slots.len() as u32
    }

    /// The binding's descriptors, slot by slot.
    pub fn image_infos(&self) -> Vec<vk::DescriptorImageInfo> {
        self.slots
            .iter()
            .map(|&(view, sampler)| vk::DescriptorImageInfo {
                sampler,
                image_view: view,
                image_layout: vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL,
            })
            .collect()
    }

    fn upload(&mut self, ctx: &Context, scene: &Scene) -> Result<(), VkError> {
        let white;
        let textures: Vec<&Texture> = if scene.textures().is_empty() {
            white = Texture::from_rgba8("white", 1, 1, vec![255; 4], Sampler::default())
                .map_err(|e| invalid("white texture", e.to_string()))?;
            vec![&white]
        } else {
            scene.textures().iter().collect()
        };
        match self.binding {
            TextureBinding::Indexed => {
                for t in &textures {
                    let sampler = self.sampler(ctx, t.sampler)?;
                    let view = self.image(ctx, &t.name, &[t])?;
                    self.slots.push((view, sampler));
                }
            }
            TextureBinding::Layers => {
                let width = textures.iter().map(|t| t.width()).max().unwrap_or(1);
                let height = textures.iter().map(|t| t.height()).max().unwrap_or(1);
                let max = ctx.physical.limits.max_image_dimension_2d;
                let (width, height) = (width.min(max), height.min(max));
                if textures.len() as u64 > u64::from(ctx.physical.limits.max_image_array_layers) {
                    return Err(invalid(
                        "scene textures",
                        format!(
                            "{} layers, the device allows {}",
                            textures.len(),
                            ctx.physical.limits.max_image_array_layers
                        ),
                    ));
                }
                if textures.iter().any(|t| t.sampler != Sampler::default()) {
                    log::info!(
                        "{}: textures bound as layers share one repeating trilinear sampler",
                        scene.name()
                    );
                }
                let resized = textures
                    .iter()
                    .map(|t| t.resized(width, height))
                    .collect::<Result<Vec<_>, _>>()
                    .map_err(|e| invalid("texture layers", e.to_string()))?;
                let layers: Vec<&Texture> = resized.iter().collect();
                let sampler = self.sampler(ctx, Sampler::default())?;
                let view = self.image(ctx, "scene texture layers", &layers)?;
                self.slots.push((view, sampler));
            }
        }
        Ok(())
    }

    /// A sampler for `s` (shared between textures that ask for the same).
    fn sampler(&mut self, ctx: &Context, s: Sampler) -> Result<vk::Sampler, VkError> {
        let mode = |w: Wrap| match w {
            Wrap::Repeat => vk::SamplerAddressMode::REPEAT,
            Wrap::MirroredRepeat => vk::SamplerAddressMode::MIRRORED_REPEAT,
            Wrap::ClampToEdge => vk::SamplerAddressMode::CLAMP_TO_EDGE,
        };
        let filter = |linear: bool| {
            if linear {
                vk::Filter::LINEAR
            } else {
                vk::Filter::NEAREST
            }
        };
        // W follows U: arrays are sampled at integral layers, and one mode on every axis is
        // what Arm's best practices ask for.
        let info = vk::SamplerCreateInfo::default()
            .mag_filter(filter(s.mag_linear))
            .min_filter(filter(s.min_linear))
            .mipmap_mode(if s.mip_linear {
                vk::SamplerMipmapMode::LINEAR
            } else {
                vk::SamplerMipmapMode::NEAREST
            })
            .address_mode_u(mode(s.wrap_u))
            .address_mode_v(mode(s.wrap_v))
            .address_mode_w(mode(s.wrap_u))
            .max_lod(vk::LOD_CLAMP_NONE);
        // SAFETY: valid create info.
        let sampler = unsafe { ctx.device.create_sampler(&info, None) }
            .map_err(|r| VkError::call("vkCreateSampler", r))?;
        self.samplers.push(sampler);
        Ok(sampler)
    }

    /// One image of `layers` (all the size and level count of the first), uploaded; its view.
    fn image(
        &mut self,
        ctx: &Context,
        name: &str,
        layers: &[&Texture],
    ) -> Result<vk::ImageView, VkError> {
        let first = layers
            .first()
            .ok_or_else(|| invalid(name, "no layers".into()))?;
        let levels = first.levels().len() as u32;
        let info = vk::ImageCreateInfo::default()
            .image_type(vk::ImageType::TYPE_2D)
            .format(FORMAT)
            .extent(vk::Extent3D {
                width: first.width(),
                height: first.height(),
                depth: 1,
            })
            .mip_levels(levels)
            .array_layers(layers.len() as u32)
            .samples(vk::SampleCountFlags::TYPE_1)
            .tiling(vk::ImageTiling::OPTIMAL)
            .usage(vk::ImageUsageFlags::SAMPLED | vk::ImageUsageFlags::TRANSFER_DST)
            .sharing_mode(vk::SharingMode::EXCLUSIVE)
            .initial_layout(vk::ImageLayout::UNDEFINED);
        let image = ctx.create_image(name, &info, MemoryUse::GpuOnly)?;
        let raw = image.raw;
        let range = vk::ImageSubresourceRange {
            aspect_mask: vk::ImageAspectFlags::COLOR,
            base_mip_level: 0,
            level_count: levels,
            base_array_layer: 0,
            layer_count: layers.len() as u32,
        };
        // Indexed textures are sampler2D, layers one sampler2DArray (textures.glsl).
        let view_type = match self.binding {
            TextureBinding::Indexed => vk::ImageViewType::TYPE_2D,
            TextureBinding::Layers => vk::ImageViewType::TYPE_2D_ARRAY,
        };
        let view_info = vk::ImageViewCreateInfo::default()
            .image(raw)
            .view_type(view_type)
            .format(FORMAT)
            .subresource_range(range);
        // SAFETY: live image, a range inside it.
        let view = match unsafe { ctx.device.create_image_view(&view_info, None) } {
            Ok(v) => v,
            Err(r) => {
                ctx.destroy_image(image);
                return Err(VkError::call("vkCreateImageView", r));
            }
        };
        self.images.push((image, view));
        upload_layers(ctx, name, raw, range, layers)?;
        self.bytes += layers.iter().map(|t| t.byte_size() as u64).sum::<u64>();
        Ok(view)
    }

    pub fn destroy(&mut self, ctx: &Context) {
        for (image, view) in self.images.drain(..) {
            // SAFETY: the caller guarantees the GPU is done with the scene.
            unsafe { ctx.device.destroy_image_view(view, None) };
            ctx.destroy_image(image);
        }
        for s in self.samplers.drain(..) {
            // SAFETY: as above.
            unsafe { ctx.device.destroy_sampler(s, None) };
        }
        self.slots.clear();
    }
}

fn invalid(what: &str, reason: String) -> VkError {
    VkError::Invalid {
        what: what.to_string(),
        reason,
    }
}

/// Copies every level of every layer into `image` through one staging buffer and leaves it in
/// SHADER_READ_ONLY_OPTIMAL; waits.
fn upload_layers(
    ctx: &Context,
    name: &str,
    image: vk::Image,
    range: vk::ImageSubresourceRange,
    layers: &[&Texture],
) -> Result<(), VkError> {
    let bytes: usize = layers.iter().map(|t| t.byte_size()).sum();
    let mut staging: Buffer = ctx.create_buffer(
        &format!("{name} staging"),
        bytes as u64,
        vk::BufferUsageFlags::TRANSFER_SRC,
        MemoryUse::Staging,
    )?;
    let mut regions = Vec::new();
    let mut at = 0usize;
    let mut written = Ok(());
    for (layer, t) in layers.iter().enumerate() {
        if written.is_ok() {
            written = ctx.write_mapped(&mut staging, at, t.pixels());
        }
        for (level, l) in t.levels().iter().enumerate() {
            regions.push(vk::BufferImageCopy {
                buffer_offset: (at + l.offset) as u64,
                buffer_row_length: 0,
                buffer_image_height: 0,
                image_subresource: vk::ImageSubresourceLayers {
                    aspect_mask: vk::ImageAspectFlags::COLOR,
                    mip_level: level as u32,
                    base_array_layer: layer as u32,
                    layer_count: 1,
                },
                image_offset: vk::Offset3D::default(),
                image_extent: vk::Extent3D {
                    width: l.width,
                    height: l.height,
                    depth: 1,
                },
            });
        }
        at += t.byte_size();
    }
    let copied = written.and_then(|()| {
        ctx.submit_and_wait(|cb| {
            let to_dst = [vk::ImageMemoryBarrier2::default()
                .src_stage_mask(vk::PipelineStageFlags2::NONE)
                .dst_stage_mask(vk::PipelineStageFlags2::COPY)
                .dst_access_mask(vk::AccessFlags2::TRANSFER_WRITE)
                .old_layout(vk::ImageLayout::UNDEFINED)
                .new_layout(vk::ImageLayout::TRANSFER_DST_OPTIMAL)
                .image(image)
                .subresource_range(range)];
            ctx.cmd_pipeline_barrier2(
                cb,
                &vk::DependencyInfo::default().image_memory_barriers(&to_dst),
            )?;
            // SAFETY: live buffer and image; every region lies inside both.
            unsafe {
                ctx.device.cmd_copy_buffer_to_image(
                    cb,
                    staging.raw,
                    image,
                    vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                    &regions,
                )
            };
            let to_read = [vk::ImageMemoryBarrier2::default()
                .src_stage_mask(vk::PipelineStageFlags2::COPY)
                .src_access_mask(vk::AccessFlags2::TRANSFER_WRITE)
                .dst_stage_mask(vk::PipelineStageFlags2::FRAGMENT_SHADER)
                .dst_access_mask(vk::AccessFlags2::SHADER_SAMPLED_READ)
                .old_layout(vk::ImageLayout::TRANSFER_DST_OPTIMAL)
                .new_layout(vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL)
                .image(image)
                .subresource_range(range)];
            ctx.cmd_pipeline_barrier2(
                cb,
                &vk::DependencyInfo::default().image_memory_barriers(&to_read),
            )
        })
    });
    ctx.destroy_buffer(staging);
    copied
}
