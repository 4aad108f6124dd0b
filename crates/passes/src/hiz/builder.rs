//! The build's pipelines and its recording.

use tilegraph_vk::ash::vk;
use tilegraph_vk::executor::BufferHandle;
use tilegraph_vk::pipeline::{
    create_compute_pipeline, create_pipeline_layout, create_set_layout, Stage,
};
use tilegraph_vk::{Context, VkError};

use super::layout::{HizLayout, HizLevelsPush, HizStep};

/// SPIR-V of the level-0 copy (`shaders/hiz_copy.comp`).
pub const HIZ_COPY_SPV: &[u8] = include_bytes!("../../../../shaders/spv/hiz_copy.comp.spv");
/// SPIR-V of the single-level reduction (`shaders/hiz_reduce.comp`).
pub const HIZ_REDUCE_SPV: &[u8] = include_bytes!("../../../../shaders/spv/hiz_reduce.comp.spv");
/// SPIR-V of the fused reduction (`shaders/hiz_reduce_levels.comp`).
pub const HIZ_REDUCE_LEVELS_SPV: &[u8] =
    include_bytes!("../../../../shaders/spv/hiz_reduce_levels.comp.spv");

/// `local_size_x` and `local_size_y` of the copy and the single-level reduction: one thread per
/// destination texel.
pub const WORKGROUP_SIZE: u32 = 8;
/// `local_size_x` and `local_size_y` of `hiz_reduce_levels.comp`.
pub const LEVELS_WORKGROUP_SIZE: u32 = 16;

/// Descriptor bindings of set 0 (every shader; the reductions only use the pyramid).
const BINDING_DEPTH: u32 = 0;
const BINDING_PYRAMID: u32 = 1;

/// Layouts a sampled depth image may be in while the build reads it.
const READABLE_DEPTH_LAYOUTS: [vk::ImageLayout; 5] = [
    vk::ImageLayout::DEPTH_STENCIL_READ_ONLY_OPTIMAL,
    vk::ImageLayout::DEPTH_READ_ONLY_OPTIMAL,
    vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL,
    vk::ImageLayout::READ_ONLY_OPTIMAL,
    vk::ImageLayout::GENERAL,
];

/// The depth a build reads: a DEPTH-aspect, single-mip view, sampled in `layout`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SampledDepth {
    pub view: vk::ImageView,
    pub layout: vk::ImageLayout,
}

/// The pipelines and per-frame-slot descriptor sets of the build.
pub struct HizBuilder {
    set_layout: vk::DescriptorSetLayout,
    pipeline_layout: vk::PipelineLayout,
    copy: vk::Pipeline,
    reduce: vk::Pipeline,
    reduce_levels: vk::Pipeline,
    /// Where [`HizBuilder::time_dispatches`] asked for timestamps.
    timestamps: Option<(vk::QueryPool, u32)>,
    pool: vk::DescriptorPool,
    /// One set per frame-in-flight slot, rewritten by every `record` for that slot.
    sets: Vec<vk::DescriptorSet>,
}

impl HizBuilder {
    /// Creates both pipelines and `frames_in_flight` descriptor sets.
    pub fn new(ctx: &Context, frames_in_flight: usize) -> Result<Self, VkError> {
        if frames_in_flight == 0 {
            return Err(VkError::Invalid {
                what: "hiz builder".into(),
                reason: "frames_in_flight is zero".into(),
            });
        }
        let n = u32::try_from(frames_in_flight).map_err(|_| VkError::Invalid {
            what: "hiz builder".into(),
            reason: format!("frames_in_flight {frames_in_flight} is too large"),
        })?;
        // Start from null handles and fill in; on error, `destroy` skips what is still null
        // (destroying VK_NULL_HANDLE is a no-op in Vulkan).
        let mut b = HizBuilder {
            set_layout: vk::DescriptorSetLayout::null(),
            pipeline_layout: vk::PipelineLayout::null(),
            copy: vk::Pipeline::null(),
            reduce: vk::Pipeline::null(),
            reduce_levels: vk::Pipeline::null(),
            timestamps: None,
            pool: vk::DescriptorPool::null(),
            sets: Vec::new(),
        };
        match b.create(ctx, n) {
            Ok(()) => Ok(b),
            Err(e) => {
                b.destroy(ctx);
                Err(e)
            }
        }
    }

    fn create(&mut self, ctx: &Context, n: u32) -> Result<(), VkError> {
        let compute = vk::ShaderStageFlags::COMPUTE;
        self.set_layout = create_set_layout(
            ctx,
            &[
                (BINDING_DEPTH, vk::DescriptorType::SAMPLED_IMAGE, compute),
                (BINDING_PYRAMID, vk::DescriptorType::STORAGE_BUFFER, compute),
            ],
        )?;
        self.pipeline_layout = create_pipeline_layout(
            ctx,
            &[self.set_layout],
            Some(vk::PushConstantRange {
                stage_flags: compute,
                offset: 0,
                // Both push blocks start at 0; the larger one sets the range.
                size: std::mem::size_of::<HizLevelsPush>() as u32,
            }),
        )?;
        self.copy = create_compute_pipeline(
            ctx,
            &Stage {
                name: "hiz_copy",
                spirv: HIZ_COPY_SPV,
                specialization: &[],
            },
            self.pipeline_layout,
        )?;
        self.reduce = create_compute_pipeline(
            ctx,
            &Stage {
                name: "hiz_reduce",
                spirv: HIZ_REDUCE_SPV,
                specialization: &[],
            },
            self.pipeline_layout,
        )?;
        self.reduce_levels = create_compute_pipeline(
            ctx,
            &Stage {
                name: "hiz_reduce_levels",
                spirv: HIZ_REDUCE_LEVELS_SPV,
                specialization: &[],
            },
            self.pipeline_layout,
        )?;
        let sizes = [
            vk::DescriptorPoolSize {
                ty: vk::DescriptorType::SAMPLED_IMAGE,
                descriptor_count: n,
            },
            vk::DescriptorPoolSize {
                ty: vk::DescriptorType::STORAGE_BUFFER,
                descriptor_count: n,
            },
        ];
        let pool_info = vk::DescriptorPoolCreateInfo::default()
            .max_sets(n)
            .pool_sizes(&sizes);
        // SAFETY: valid create info on a live device.
        self.pool = unsafe { ctx.device.create_descriptor_pool(&pool_info, None) }
            .map_err(|r| VkError::call("vkCreateDescriptorPool", r))?;
        ctx.set_name(self.pool, "hiz descriptors");
        let layouts = vec![self.set_layout; n as usize];
        let alloc = vk::DescriptorSetAllocateInfo::default()
            .descriptor_pool(self.pool)
            .set_layouts(&layouts);
        // SAFETY: the pool was sized for exactly `n` sets of this layout.
        self.sets = unsafe { ctx.device.allocate_descriptor_sets(&alloc) }
            .map_err(|r| VkError::call("vkAllocateDescriptorSets", r))?;
        Ok(())
    }

    /// Number of frame slots (descriptor sets).
    pub fn frame_slots(&self) -> usize {
        self.sets.len()
    }

    /// From now on, [`HizBuilder::record`] writes a timestamp before the first dispatch and
    /// after each one into queries `first_query..` of `pool` (a timestamp pool with room for one
    /// more query than the layout has steps, reset by the caller): what each dispatch costs.
    /// `None` stops it.
    pub fn time_dispatches(&mut self, timestamps: Option<(vk::QueryPool, u32)>) {
        self.timestamps = timestamps;
    }

    /// Records the whole build: level 0 from `depth` (a view of an image whose extent is
    /// `layout`'s level 0 and whose format is `layout.format`), then every level. `pyramid`
    /// must hold at least `layout.size_bytes()`.
    ///
    /// The caller has already made the depth image readable by compute shaders in
    /// `depth.layout` and made earlier accesses to `pyramid` safe (a graph pass declaring it
    /// StorageReadWrite gets both barriers); this function inserts the barriers *between*
    /// its dispatches only. After it, the pyramid was written by COMPUTE_SHADER / SHADER_STORAGE_WRITE.
    /// The previous use of `frame_slot`'s descriptor set must have completed (the executor's
    /// frames-in-flight guarantee); two builds in one command buffer need two slots.
    pub fn record(
        &mut self,
        ctx: &Context,
        cb: vk::CommandBuffer,
        frame_slot: usize,
        depth: SampledDepth,
        pyramid: BufferHandle,
        layout: &HizLayout,
    ) -> Result<(), VkError> {
        let SampledDepth {
            view: depth_view,
            layout: depth_layout,
        } = depth;
        let invalid = |reason: String| VkError::Invalid {
            what: "hiz build".into(),
            reason,
        };
        let set = *self.sets.get(frame_slot).ok_or_else(|| {
            invalid(format!(
                "frame slot {frame_slot} out of range ({} slots)",
                self.sets.len()
            ))
        })?;
        if !READABLE_DEPTH_LAYOUTS.contains(&depth_layout) {
            return Err(invalid(format!(
                "depth layout {depth_layout:?} is not one a sampled image can be read in"
            )));
        }
        if depth_view == vk::ImageView::null() || pyramid.raw == vk::Buffer::null() {
            return Err(invalid("null depth view or pyramid buffer".into()));
        }
        if pyramid.size < layout.size_bytes() {
            return Err(invalid(format!(
                "pyramid buffer holds {} bytes, the layout needs {}",
                pyramid.size,
                layout.size_bytes()
            )));
        }
        // Checked up front so a bad layout fails before anything is recorded (computed again
        // per dispatch below: no list is kept, nothing allocated per frame).
        let mut steps = 0;
        while let Some(step) = layout.step(steps) {
            step?;
            steps += 1;
        }

        let image_info = [vk::DescriptorImageInfo {
            sampler: vk::Sampler::null(),
            image_view: depth_view,
            image_layout: depth_layout,
        }];
        let buffer_info = [vk::DescriptorBufferInfo {
            buffer: pyramid.raw,
            offset: 0,
            range: layout.size_bytes(),
        }];
        let writes = [
            vk::WriteDescriptorSet::default()
                .dst_set(set)
                .dst_binding(BINDING_DEPTH)
                .descriptor_type(vk::DescriptorType::SAMPLED_IMAGE)
                .image_info(&image_info),
            vk::WriteDescriptorSet::default()
                .dst_set(set)
                .dst_binding(BINDING_PYRAMID)
                .descriptor_type(vk::DescriptorType::STORAGE_BUFFER)
                .buffer_info(&buffer_info),
        ];
        let d = &ctx.device;
        // SAFETY: the set is not in use by pending work (the caller's frame-slot guarantee); the
        // view and buffer are live; the range fits the buffer (checked above) and is below the
        // guaranteed maxStorageBufferRange (HizLayout::new).
        unsafe { d.update_descriptor_sets(&writes, &[]) };
        self.record_steps(ctx, cb, set, pyramid, layout, 0..steps)
    }

    /// The pyramid's levels after its base, reduced from the base level already in `pyramid`
    /// (written by another pass, such as depth reprojection's resolve; the graph made it
    /// visible). Same contract as [`Self::record`] otherwise; the slot's set gets `pyramid`
    /// only (the reductions do not read the depth image).
    pub fn record_reductions(
        &mut self,
        ctx: &Context,
        cb: vk::CommandBuffer,
        frame_slot: usize,
        pyramid: BufferHandle,
        layout: &HizLayout,
    ) -> Result<(), VkError> {
        let invalid = |reason: String| VkError::Invalid {
            what: "hiz reductions".into(),
            reason,
        };
        let set = *self.sets.get(frame_slot).ok_or_else(|| {
            invalid(format!(
                "frame slot {frame_slot} out of range ({} slots)",
                self.sets.len()
            ))
        })?;
        if pyramid.raw == vk::Buffer::null() || pyramid.size < layout.size_bytes() {
            return Err(invalid(format!(
                "pyramid buffer of {} bytes, the layout needs {}",
                pyramid.size,
                layout.size_bytes()
            )));
        }
        let mut steps = 0;
        while let Some(step) = layout.step(steps) {
            step?;
            steps += 1;
        }
        let buffer_info = [vk::DescriptorBufferInfo {
            buffer: pyramid.raw,
            offset: 0,
            range: layout.size_bytes(),
        }];
        let writes = [vk::WriteDescriptorSet::default()
            .dst_set(set)
            .dst_binding(BINDING_PYRAMID)
            .descriptor_type(vk::DescriptorType::STORAGE_BUFFER)
            .buffer_info(&buffer_info)];
        // SAFETY: as in `record`: the set is not in use by pending work, the buffer is live and
        // the range fits it.
        unsafe { ctx.device.update_descriptor_sets(&writes, &[]) };
        self.record_steps(ctx, cb, set, pyramid, layout, 1..steps)
    }

    /// Binds `set` and records steps `first..steps` of `layout` with barriers between them.
    fn record_steps(
        &self,
        ctx: &Context,
        cb: vk::CommandBuffer,
        set: vk::DescriptorSet,
        pyramid: BufferHandle,
        layout: &HizLayout,
        steps: std::ops::Range<usize>,
    ) -> Result<(), VkError> {
        let (first, steps) = (steps.start, steps.end);
        let timestamps = self.timestamps;
        let stamp = |query: usize| match timestamps {
            Some((pool, base)) => ctx.cmd_write_timestamp2(
                cb,
                vk::PipelineStageFlags2::BOTTOM_OF_PIPE,
                pool,
                base + query as u32,
            ),
            None => Ok(()),
        };
        let d = &ctx.device;
        // SAFETY: `cb` is recording outside a render pass (the caller's contract for a compute
        // pass); the set matches the pipeline layout.
        unsafe {
            d.cmd_bind_descriptor_sets(
                cb,
                vk::PipelineBindPoint::COMPUTE,
                self.pipeline_layout,
                0,
                &[set],
                &[],
            );
        }
        // Between levels: level k's writes become visible to level k+1's reads. The destination
        // also names SHADER_STORAGE_WRITE because the whole buffer is one descriptor: the
        // synchronization validator sees every dispatch as reading and writing all of it.
        let between = [vk::BufferMemoryBarrier2::default()
            .src_stage_mask(vk::PipelineStageFlags2::COMPUTE_SHADER)
            .src_access_mask(vk::AccessFlags2::SHADER_STORAGE_WRITE)
            .dst_stage_mask(vk::PipelineStageFlags2::COMPUTE_SHADER)
            .dst_access_mask(
                vk::AccessFlags2::SHADER_STORAGE_READ | vk::AccessFlags2::SHADER_STORAGE_WRITE,
            )
            .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
            .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
            .buffer(pyramid.raw)
            .offset(0)
            .size(layout.size_bytes())];
        stamp(0)?;
        for i in first..steps {
            let Some(step) = layout.step(i) else {
                break;
            };
            if i > first {
                ctx.cmd_pipeline_barrier2(
                    cb,
                    &vk::DependencyInfo::default().buffer_memory_barriers(&between),
                )?;
            }
            // SAFETY (both arms): recording; each pipeline uses `pipeline_layout`, whose push
            // range covers both push blocks (from offset 0); the single-level dispatch covers
            // dst_extent (the shaders bound-check the rest), the fused one covers its tiles.
            match step? {
                HizStep::Single { level, push } => unsafe {
                    let pipeline = if level == 0 { self.copy } else { self.reduce };
                    d.cmd_bind_pipeline(cb, vk::PipelineBindPoint::COMPUTE, pipeline);
                    d.cmd_push_constants(
                        cb,
                        self.pipeline_layout,
                        vk::ShaderStageFlags::COMPUTE,
                        0,
                        bytemuck::bytes_of(&push),
                    );
                    d.cmd_dispatch(
                        cb,
                        push.dst_extent[0].div_ceil(WORKGROUP_SIZE),
                        push.dst_extent[1].div_ceil(WORKGROUP_SIZE),
                        1,
                    );
                },
                HizStep::Fused { push, .. } => unsafe {
                    d.cmd_bind_pipeline(cb, vk::PipelineBindPoint::COMPUTE, self.reduce_levels);
                    d.cmd_push_constants(
                        cb,
                        self.pipeline_layout,
                        vk::ShaderStageFlags::COMPUTE,
                        0,
                        bytemuck::bytes_of(&push),
                    );
                    d.cmd_dispatch(cb, push.groups[0], push.groups[1], 1);
                },
            }
            stamp(i + 1)?;
        }
        Ok(())
    }

    /// Destroys the pipelines, layouts and descriptor pool. The GPU must be done with them.
    pub fn destroy(self, ctx: &Context) {
        // SAFETY: the caller guarantees no pending work uses these objects; null handles (a
        // partially created builder) are ignored by vkDestroy*. Freeing the pool frees the sets.
        unsafe {
            ctx.device.destroy_pipeline(self.copy, None);
            ctx.device.destroy_pipeline(self.reduce, None);
            ctx.device.destroy_pipeline(self.reduce_levels, None);
            ctx.device.destroy_descriptor_pool(self.pool, None);
            ctx.device
                .destroy_pipeline_layout(self.pipeline_layout, None);
            ctx.device
                .destroy_descriptor_set_layout(self.set_layout, None);
        }
    }
}
