//! The Vulkan objects a culling stage is made of — instance culling (`cull.comp`,
//! `cull_compact.comp`, `cull_commands.comp`) and the cluster stage (`cluster_cull.comp`,
//! `cluster_place.comp`, `cluster_emit.comp`) alike: one descriptor set
//! layout (binding 0 the phase's parameter block, then storage buffers), a pipeline layout after
//! the scene's set, `N` compute pipelines and a pool for the per-slot, per-phase sets.

use ash::vk;
use tilegraph_vk::ash;
use tilegraph_vk::pipeline::{
    allocate_set, create_compute_pipeline, create_pipeline_layout, create_set_layout, Stage,
};
use tilegraph_vk::{Context, VkError};

/// The set of frame slot `slot` and phase `which` (0 early or only, 1 late) among a stage's
/// sets, two per slot; an error naming the stage (`what`) for a slot it has no set for.
pub(super) fn phase_set(
    sets: &[vk::DescriptorSet],
    slot: usize,
    which: usize,
    what: &str,
) -> Result<vk::DescriptorSet, VkError> {
    sets.get(2 * slot + which)
        .copied()
        .ok_or_else(|| VkError::Invalid {
            what: what.into(),
            reason: format!("no set for slot {slot}"),
        })
}

/// A compute shader of a stage: its name (for errors and debug names) and SPIR-V.
pub(super) type Shader = (&'static str, &'static [u8]);

/// Set layout, pipeline layout, the stage's `N` pipelines and its descriptor pool. Made empty
/// ([`ComputeStage::EMPTY`]) and filled by [`ComputeStage::init`], so an error half-way leaves
/// what was made for [`ComputeStage::destroy`].
pub(super) struct ComputeStage<const N: usize> {
    pub set_layout: vk::DescriptorSetLayout,
    pub pipeline_layout: vk::PipelineLayout,
    pub pipelines: [vk::Pipeline; N],
    pool: vk::DescriptorPool,
}

impl<const N: usize> ComputeStage<N> {
    pub const EMPTY: ComputeStage<N> = ComputeStage {
        set_layout: vk::DescriptorSetLayout::null(),
        pipeline_layout: vk::PipelineLayout::null(),
        pipelines: [vk::Pipeline::null(); N],
        pool: vk::DescriptorPool::null(),
    };

    /// Binding 0 a uniform buffer, bindings 1..=`storage` storage buffers (all compute); the
    /// pipelines of `shaders` (set 0 the scene's, set 1 this one); a pool for `sets` sets.
    pub fn init(
        &mut self,
        ctx: &Context,
        scene_set_layout: vk::DescriptorSetLayout,
        storage: u32,
        shaders: [Shader; N],
        sets: u32,
    ) -> Result<(), VkError> {
        let c = vk::ShaderStageFlags::COMPUTE;
        let ssbo = vk::DescriptorType::STORAGE_BUFFER;
        let mut bindings = vec![(0, vk::DescriptorType::UNIFORM_BUFFER, c)];
        bindings.extend((1..=storage).map(|b| (b, ssbo, c)));
        self.set_layout = create_set_layout(ctx, &bindings)?;
        self.pipeline_layout =
            create_pipeline_layout(ctx, &[scene_set_layout, self.set_layout], None)?;
        for (pipeline, (name, spirv)) in self.pipelines.iter_mut().zip(shaders) {
            *pipeline = create_compute_pipeline(
                ctx,
                &Stage {
                    name,
                    spirv,
                    specialization: &[],
                },
                self.pipeline_layout,
            )?;
        }
        let sizes = [
            vk::DescriptorPoolSize {
                ty: vk::DescriptorType::UNIFORM_BUFFER,
                descriptor_count: sets,
            },
            vk::DescriptorPoolSize {
                ty: ssbo,
                descriptor_count: storage * sets,
            },
        ];
        let pool_info = vk::DescriptorPoolCreateInfo::default()
            .max_sets(sets)
            .pool_sizes(&sizes);
        // SAFETY: valid create info.
        self.pool = unsafe { ctx.device.create_descriptor_pool(&pool_info, None) }
            .map_err(|r| VkError::call("vkCreateDescriptorPool", r))?;
        Ok(())
    }

    /// One set of the stage's layout from its pool.
    pub fn allocate_set(&self, ctx: &Context) -> Result<vk::DescriptorSet, VkError> {
        allocate_set(ctx, self.pool, self.set_layout)
    }

    /// Records `pipeline` (one of [`Self::pipelines`]) over `groups` workgroups with the scene's
    /// set and the stage's `set`; nothing when a dimension is 0. The graph put the barriers
    /// around the pass.
    pub fn dispatch(
        &self,
        ctx: &Context,
        cb: vk::CommandBuffer,
        pipeline: vk::Pipeline,
        sets: [vk::DescriptorSet; 2],
        groups: (u32, u32),
    ) {
        if groups.0 == 0 || groups.1 == 0 {
            return;
        }
        self.bind(ctx, cb, pipeline, sets);
        // SAFETY: recording outside a render pass, the pipeline and sets bound.
        unsafe { ctx.device.cmd_dispatch(cb, groups.0, groups.1, 1) };
    }

    /// Binds `pipeline` and `sets` (the scene's, the stage's) for a dispatch.
    fn bind(
        &self,
        ctx: &Context,
        cb: vk::CommandBuffer,
        pipeline: vk::Pipeline,
        sets: [vk::DescriptorSet; 2],
    ) {
        // SAFETY: recording outside a render pass; pipeline, layout and sets are live.
        unsafe {
            ctx.device
                .cmd_bind_pipeline(cb, vk::PipelineBindPoint::COMPUTE, pipeline);
            ctx.device.cmd_bind_descriptor_sets(
                cb,
                vk::PipelineBindPoint::COMPUTE,
                self.pipeline_layout,
                0,
                &sets,
                &[],
            );
        }
    }

    /// Records `pipeline` over the workgroups the `VkDispatchIndirectCommand` at `args` (a
    /// buffer and offset) says, with the scene's set and the stage's `set`. The graph put the
    /// barriers around the pass (the arguments read as indirect).
    pub fn dispatch_indirect(
        &self,
        ctx: &Context,
        cb: vk::CommandBuffer,
        pipeline: vk::Pipeline,
        sets: [vk::DescriptorSet; 2],
        args: (vk::Buffer, u64),
    ) {
        self.bind(ctx, cb, pipeline, sets);
        // SAFETY: recording outside a render pass, the pipeline and sets bound; the argument
        // buffer (an indirect buffer holding 12 bytes at the offset) is live.
        unsafe { ctx.device.cmd_dispatch_indirect(cb, args.0, args.1) };
    }

    /// Destroys what was made; the GPU must be idle.
    pub fn destroy(self, ctx: &Context) {
        // SAFETY: the GPU is idle (caller's guarantee); null handles are ignored.
        unsafe {
            for p in self.pipelines {
                ctx.device.destroy_pipeline(p, None);
            }
            ctx.device
                .destroy_pipeline_layout(self.pipeline_layout, None);
            ctx.device.destroy_descriptor_pool(self.pool, None);
            ctx.device
                .destroy_descriptor_set_layout(self.set_layout, None);
        }
    }
}
