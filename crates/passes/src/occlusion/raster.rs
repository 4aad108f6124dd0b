//! Raster occlusion (`Culling::RasterOcclusion`): every instance's bounding box rasterized
//! against the depth pre-pass with early fragment tests; each surviving fragment flags its
//! instance in the culling `visibility` buffer, and the culling shader turns the flags into the
//! indirect lists the colour passes draw. At scale 2 or 4 the boxes are tested against a
//! conservative (farthest-depth) 1/2 or 1/4 resolution copy of the depth.

use ash::vk;
use tilegraph_graph::{Extent2d, Format, ImageDesc, PassClass};
use tilegraph_scene::DepthConvention;
use tilegraph_vk::ash;
use tilegraph_vk::executor::PassContext;
use tilegraph_vk::pipeline::{
    create_described_pipeline, create_nearest_sampler, create_pipeline_layout, Blend, DepthState,
    GraphicsDesc, Stage,
};
use tilegraph_vk::{Buffer, Context, VkError};

use crate::cull::{add_cull, CullLists, Culling, Recheck};
use crate::frame::{scene_set, FrameGraph, PassState, Payload, SceneResources};
use crate::pipelines::{PipelineKey, Pipelines, Proxy, FULLSCREEN_VS};
use crate::targets::SceneTargets;

/// Declares raster occlusion before the first colour pass: the boxes drawn
/// against the targets' depth (or a 1/`scale` copy of it), then the culling dispatch that turns
/// the flags into the lists.
pub fn add_raster_occlusion(
    g: &mut FrameGraph,
    targets: &SceneTargets,
    lists: CullLists,
    scale: u32,
) {
    let visibility = lists.visibility;
    let boxes: Payload = Box::new(|pc, res| {
        let set = scene_set(pc, res)?;
        let SceneResources {
            pipelines,
            states,
            frame,
            ..
        } = res;
        let r = states.require::<RasterOcclusion>(pc.pass_name)?;
        let proxy = Proxy::RasterBox { scale: r.scale };
        let pipeline = pipelines.proxy(pc, proxy, r.pipeline_layout, frame.depth)?;
        r.record(pc, set, pipeline)
    });
    let full = (targets.extent.width_px, targets.extent.height_px);
    let tested_depth = if scale > 1 {
        let low = (full.0.div_ceil(scale).max(1), full.1.div_ceil(scale).max(1));
        let low_depth = g.create_image(
            "occlusion-depth",
            ImageDesc::new(Extent2d::new(low.0, low.1), Format::D32_SFLOAT),
        );
        let depth = targets.depth;
        let downsample: Payload = Box::new(move |pc, res| {
            let view = pc.image(depth)?.view;
            let SceneResources {
                pipelines,
                states,
                frame,
                ..
            } = res;
            let r = states.require::<RasterOcclusion>(pc.pass_name)?;
            r.record_downsample(pc, pipelines, view, full, frame.depth)
        });
        g.raster_pass(
            "raster-occlusion-depth",
            PassClass::OcclusionQuery,
            downsample,
        )
        .sampled(targets.depth)
        .depth_stencil_clear(low_depth, targets.depth_clear());
        low_depth
    } else {
        targets.depth
    };
    // The vertex shader skips the boxes of instances drawn last frame whose turn has not come
    // (`occlusion_recheck`); the fragment shader reads a flag before setting it (one store per
    // visible box). `cull.comp` reads the flags and leaves next frame's (no clear).
    g.raster_pass("raster-occlusion", PassClass::OcclusionQuery, boxes)
        .depth_stencil_read_only(tested_depth)
        .storage_read_write(visibility);
    add_cull(g, lists, Culling::RasterOcclusion);
}

/// A box's 12 triangles over its corners (bit 0: +x, bit 1: +y, bit 2: +z), front faces
/// counter-clockwise seen from outside; the first face's two triangles are also the screen
/// rectangle of reduced-resolution raster occlusion (`raster_occlusion.vert`).
const BOX_INDICES: [u16; 36] = [
    0, 2, 1, 1, 2, 3, // -z
    4, 5, 6, 5, 7, 6, // +z
    0, 1, 4, 1, 5, 4, // -y
    2, 6, 3, 3, 6, 7, // +y
    0, 4, 2, 2, 4, 6, // -x
    1, 3, 5, 3, 7, 5, // +x
];

/// Raster occlusion (`Culling::RasterOcclusion`): every instance's box drawn against the
/// pre-pass depth with early fragment tests, surviving fragments flag the instance in the
/// culling `visibility` buffer, which `cull.comp` (its early phase) turns into indirect draws.
pub struct RasterOcclusion {
    set_layout: vk::DescriptorSetLayout,
    pool: vk::DescriptorPool,
    set: vk::DescriptorSet,
    pub pipeline_layout: vk::PipelineLayout,
    instance_count: u32,
    /// 1: full resolution; k > 1: against a conservative ~1/k-resolution depth.
    pub scale: u32,
    /// This frame's box re-test turns (the culling state's, [`crate::cull::CullState::recheck`]).
    recheck: Recheck,
    /// The box's 12 triangles over its 8 corners ([`BOX_INDICES`]): an indexed draw shades 8
    /// vertices per box, not 36 (the vertex shader's work is the pass's cost where the boxes are
    /// small or skipped).
    indices: Buffer,
    downsample: Option<Downsample>,
}

/// The farthest-depth downsampling pass of raster occlusion at reduced resolution.
struct Downsample {
    set_layout: vk::DescriptorSetLayout,
    pool: vk::DescriptorPool,
    sets: Vec<vk::DescriptorSet>,
    layout: vk::PipelineLayout,
    sampler: vk::Sampler,
}

/// Push constants of `raster_occlusion_downsample.frag`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
struct DownsamplePush {
    scale: [f32; 4],
    info: [u32; 4],
}

const DOWNSAMPLE_FS: &[u8] =
    include_bytes!("../../../../shaders/spv/raster_occlusion_downsample.frag.spv");

impl Downsample {
    fn new(ctx: &Context, frames_in_flight: usize) -> Result<Self, VkError> {
        let set_layout = tilegraph_vk::pipeline::create_set_layout(
            ctx,
            &[(
                0,
                vk::DescriptorType::COMBINED_IMAGE_SAMPLER,
                vk::ShaderStageFlags::FRAGMENT,
            )],
        )?;
        let mut d = Downsample {
            set_layout,
            pool: vk::DescriptorPool::null(),
            sets: Vec::new(),
            layout: vk::PipelineLayout::null(),
            sampler: vk::Sampler::null(),
        };
        if let Err(e) = d.init(ctx, frames_in_flight.max(1)) {
            d.destroy(ctx);
            return Err(e);
        }
        Ok(d)
    }

    fn init(&mut self, ctx: &Context, slots: usize) -> Result<(), VkError> {
        let push = vk::PushConstantRange {
            stage_flags: vk::ShaderStageFlags::FRAGMENT,
            offset: 0,
            size: std::mem::size_of::<DownsamplePush>() as u32,
        };
        self.layout = create_pipeline_layout(ctx, &[self.set_layout], Some(push))?;
        let sizes = [vk::DescriptorPoolSize {
            ty: vk::DescriptorType::COMBINED_IMAGE_SAMPLER,
            descriptor_count: slots as u32,
        }];
        let pool_info = vk::DescriptorPoolCreateInfo::default()
            .max_sets(slots as u32)
            .pool_sizes(&sizes);
        // SAFETY: valid create info.
        self.pool = unsafe { ctx.device.create_descriptor_pool(&pool_info, None) }
            .map_err(|r| VkError::call("vkCreateDescriptorPool", r))?;
        for _ in 0..slots {
            self.sets.push(tilegraph_vk::pipeline::allocate_set(
                ctx,
                self.pool,
                self.set_layout,
            )?);
        }
        self.sampler = create_nearest_sampler(ctx)?;
        Ok(())
    }

    fn destroy(self, ctx: &Context) {
        // SAFETY: the GPU is idle (caller's guarantee); null handles are ignored.
        unsafe {
            ctx.device.destroy_sampler(self.sampler, None);
            ctx.device.destroy_pipeline_layout(self.layout, None);
            ctx.device.destroy_descriptor_pool(self.pool, None);
            ctx.device
                .destroy_descriptor_set_layout(self.set_layout, None);
        }
    }
}

impl PassState for RasterOcclusion {
    fn destroy(self: Box<Self>, ctx: &Context) {
        self.destroy_all(ctx);
    }
}

impl RasterOcclusion {
    pub fn new(
        ctx: &Context,
        scene_set_layout: vk::DescriptorSetLayout,
        visibility: &Buffer,
        instance_count: u32,
        scale: u32,
        frames_in_flight: usize,
    ) -> Result<Self, VkError> {
        let indices = crate::gpu_scene::upload(
            ctx,
            "raster occlusion box",
            bytemuck::cast_slice(&BOX_INDICES),
            vk::BufferUsageFlags::INDEX_BUFFER,
        )?;
        let set_layout = match tilegraph_vk::pipeline::create_set_layout(
            ctx,
            &[(
                0,
                vk::DescriptorType::STORAGE_BUFFER,
                vk::ShaderStageFlags::VERTEX | vk::ShaderStageFlags::FRAGMENT,
            )],
        ) {
            Ok(l) => l,
            Err(e) => {
                ctx.destroy_buffer(indices);
                return Err(e);
            }
        };
        let sizes = [vk::DescriptorPoolSize {
            ty: vk::DescriptorType::STORAGE_BUFFER,
            descriptor_count: 1,
        }];
        let pool_info = vk::DescriptorPoolCreateInfo::default()
            .max_sets(1)
            .pool_sizes(&sizes);
        // SAFETY: valid create info.
        let pool = match unsafe { ctx.device.create_descriptor_pool(&pool_info, None) } {
            Ok(p) => p,
            Err(r) => {
                ctx.destroy_buffer(indices);
                // SAFETY: the layout is unused.
                unsafe { ctx.device.destroy_descriptor_set_layout(set_layout, None) };
                return Err(VkError::call("vkCreateDescriptorPool", r));
            }
        };
        let mut state = RasterOcclusion {
            set_layout,
            pool,
            set: vk::DescriptorSet::null(),
            pipeline_layout: vk::PipelineLayout::null(),
            instance_count,
            scale: scale.max(1),
            recheck: Recheck::new(1, 0),
            indices,
            downsample: None,
        };
        if state.scale > 1 {
            match Downsample::new(ctx, frames_in_flight) {
                Ok(d) => state.downsample = Some(d),
                Err(e) => {
                    state.destroy_all(ctx);
                    return Err(e);
                }
            }
        }
        let push = vk::PushConstantRange {
            stage_flags: vk::ShaderStageFlags::VERTEX,
            offset: 0,
            size: 16,
        };
        match create_pipeline_layout(ctx, &[scene_set_layout, set_layout], Some(push)) {
            Ok(l) => state.pipeline_layout = l,
            Err(e) => {
                state.destroy_all(ctx);
                return Err(e);
            }
        }
        match tilegraph_vk::pipeline::allocate_set(ctx, pool, set_layout) {
            Ok(s) => state.set = s,
            Err(e) => {
                state.destroy_all(ctx);
                return Err(e);
            }
        }
        let info = [vk::DescriptorBufferInfo {
            buffer: visibility.raw,
            offset: 0,
            range: vk::WHOLE_SIZE,
        }];
        let write = vk::WriteDescriptorSet::default()
            .dst_set(state.set)
            .dst_binding(0)
            .descriptor_type(vk::DescriptorType::STORAGE_BUFFER)
            .buffer_info(&info);
        // SAFETY: a new set, not in use; the buffer is live as long as the culling state.
        unsafe { ctx.device.update_descriptor_sets(&[write], &[]) };
        Ok(state)
    }

    /// This frame's re-test turns: the boxes of instances drawn last frame are skipped unless
    /// their turn came (`cull.comp` reads the same turns).
    pub fn set_recheck(&mut self, recheck: Recheck) {
        self.recheck = recheck;
    }

    /// Records one instanced, indexed draw of every instance's box.
    pub fn record(
        &self,
        pc: &PassContext<'_>,
        scene_set: vk::DescriptorSet,
        pipeline: vk::Pipeline,
    ) -> Result<(), VkError> {
        let indices = self.indices.raw;
        pc.set_full_viewport();
        let d = &pc.ctx.device;
        // SAFETY: inside the raster-occlusion subpass; pipeline, layout and sets are live; the
        // graph put the visibility buffer in vertex/fragment-shader storage use for this pass;
        // the index buffer holds BOX_INDICES.
        unsafe {
            d.cmd_bind_pipeline(pc.cb, vk::PipelineBindPoint::GRAPHICS, pipeline);
            d.cmd_bind_descriptor_sets(
                pc.cb,
                vk::PipelineBindPoint::GRAPHICS,
                self.pipeline_layout,
                0,
                &[scene_set, self.set],
                &[],
            );
            d.cmd_push_constants(
                pc.cb,
                self.pipeline_layout,
                vk::ShaderStageFlags::VERTEX,
                0,
                bytemuck::bytes_of(&[self.recheck.packed(), 0, 0, 0]),
            );
            d.cmd_bind_index_buffer(pc.cb, indices, 0, vk::IndexType::UINT16);
            d.cmd_draw_indexed(
                pc.cb,
                BOX_INDICES.len() as u32,
                self.instance_count,
                0,
                0,
                0,
            );
        }
        Ok(())
    }

    /// The low-resolution size for a full-resolution `extent` (`ceil(extent / scale)`).
    pub fn low_extent(&self, extent: (u32, u32)) -> (u32, u32) {
        (
            extent.0.div_ceil(self.scale).max(1),
            extent.1.div_ceil(self.scale).max(1),
        )
    }

    /// Records the farthest-depth downsampling of `depth` (sampled, full resolution) into the
    /// current render pass's low-resolution depth attachment.
    pub fn record_downsample(
        &self,
        pc: &PassContext<'_>,
        pipelines: &mut Pipelines,
        depth_view: vk::ImageView,
        full: (u32, u32),
        convention: DepthConvention,
    ) -> Result<(), VkError> {
        let low = self.low_extent(full);
        let Some(ds) = self.downsample.as_ref() else {
            return Ok(());
        };
        let layout = ds.layout;
        let pipeline = pipelines.get_or_create(
            pc,
            PipelineKey::Named("raster-occlusion-depth"),
            |target| {
                create_described_pipeline(
                    pc.ctx,
                    &GraphicsDesc {
                        name: pc.pass_name,
                        vertex: Stage {
                            name: "fullscreen.vert",
                            spirv: FULLSCREEN_VS,
                            specialization: &[],
                        },
                        fragment: Some(Stage {
                            name: "raster_occlusion_downsample.frag",
                            spirv: DOWNSAMPLE_FS,
                            specialization: &[],
                        }),
                        vertex_layout: None,
                        layout,
                        target,
                        depth: DepthState {
                            test: true,
                            write: true,
                            compare: vk::CompareOp::ALWAYS,
                            bias: 0,
                            slope_bias: 0.0,
                            clamp: false,
                        },
                        blend: Blend::NoColorWrites,
                        cull: vk::CullModeFlags::NONE,
                        samples: vk::SampleCountFlags::TYPE_1,
                    },
                )
            },
        )?;
        let set = *ds.sets.get(pc.frame_slot).ok_or_else(|| VkError::Invalid {
            what: pc.pass_name.into(),
            reason: format!("no descriptor set for slot {}", pc.frame_slot),
        })?;
        let info = [vk::DescriptorImageInfo {
            sampler: ds.sampler,
            image_view: depth_view,
            image_layout: vk::ImageLayout::DEPTH_STENCIL_READ_ONLY_OPTIMAL,
        }];
        let write = vk::WriteDescriptorSet::default()
            .dst_set(set)
            .dst_binding(0)
            .descriptor_type(vk::DescriptorType::COMBINED_IMAGE_SAMPLER)
            .image_info(&info);
        let push = DownsamplePush {
            scale: [
                full.0 as f32 / low.0 as f32,
                full.1 as f32 / low.1 as f32,
                0.0,
                0.0,
            ],
            info: [
                u32::from(convention == DepthConvention::Reverse),
                full.0,
                full.1,
                0,
            ],
        };
        pc.set_full_viewport();
        let d = &pc.ctx.device;
        // SAFETY: the slot's previous frame completed (executor guarantee), so its set is idle;
        // the graph samples depth formats in DEPTH_STENCIL_READ_ONLY_OPTIMAL; recording inside
        // the downsample subpass.
        unsafe {
            d.update_descriptor_sets(&[write], &[]);
            d.cmd_bind_pipeline(pc.cb, vk::PipelineBindPoint::GRAPHICS, pipeline);
            d.cmd_bind_descriptor_sets(
                pc.cb,
                vk::PipelineBindPoint::GRAPHICS,
                ds.layout,
                0,
                &[set],
                &[],
            );
            d.cmd_push_constants(
                pc.cb,
                ds.layout,
                vk::ShaderStageFlags::FRAGMENT,
                0,
                bytemuck::bytes_of(&push),
            );
            d.cmd_draw(pc.cb, 3, 1, 0, 0);
        }
        Ok(())
    }

    fn destroy_all(self, ctx: &Context) {
        if let Some(d) = self.downsample {
            d.destroy(ctx);
        }
        ctx.destroy_buffer(self.indices);
        // SAFETY: the GPU is idle (caller's guarantee); null handles are ignored.
        unsafe {
            ctx.device
                .destroy_pipeline_layout(self.pipeline_layout, None);
            ctx.device.destroy_descriptor_pool(self.pool, None);
            ctx.device
                .destroy_descriptor_set_layout(self.set_layout, None);
        }
    }
}
