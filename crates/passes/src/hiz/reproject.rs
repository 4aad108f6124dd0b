//! Depth reprojection (`Culling::Reproject`, seed 000; seed 002's previous-frame depth): last
//! frame's depth, moved into this frame's view, as the occluder of a single-phase HiZ test.
//!
//! The renderer keeps last frame's depth as the HiZ pyramid's level 0 (built at the end of each
//! frame, as for `Culling::Hiz`). Each frame, before culling: `reproject` moves every texel of it
//! into this frame's view (one pixel each, the farthest depth kept where several land),
//! `reproject-resolve` writes the result as a second pyramid's level 0 (empty pixels far), and
//! `reproject-reduce` reduces that pyramid's further levels. `cull.comp` then tests every
//! instance against it with this frame's matrices — where `hiz` tests with last frame's matrices
//! against last frame's pyramid. Neither is conservative: a texel is a point sample, so a
//! surface is taken to cover the pixels its samples land on, and what last frame's depth did not
//! see (disocclusion) reads as far. docs/ACCURACY.md measures both.

use bytemuck::{Pod, Zeroable};
use glam::{DMat4, Mat4};
use tilegraph_graph::{
    AccessFlags, BufferId, Import, InitialContent, PassClass, PipelineStages, ResourceState,
};
use tilegraph_profile::MemoryUse;
use tilegraph_scene::{CameraFrame, DepthConvention};
use tilegraph_vk::ash::vk;
use tilegraph_vk::executor::BufferHandle;
use tilegraph_vk::pipeline::{
    allocate_set, create_compute_pipeline, create_pipeline_layout, create_set_layout,
    write_buffer_set, Stage,
};
use tilegraph_vk::{Buffer, Context, VkError};

use super::{HizBuilder, HizLayout, HizState};
use crate::frame::{FrameGraph, PassState, Payload};

const REPROJECT_SPV: &[u8] = include_bytes!("../../../../shaders/spv/reproject.comp.spv");
const RESOLVE_SPV: &[u8] = include_bytes!("../../../../shaders/spv/reproject_resolve.comp.spv");

/// `Push` of reproject.comp and reproject_resolve.comp.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct ReprojectPush {
    /// Last frame's NDC (x, y, depth, 1) -> this frame's camera-relative clip space.
    pub now_from_previous: [[f32; 4]; 4],
    /// x, y level 0 size; z 1 reverse-Z; w level 0's first texel.
    pub info: [u32; 4],
}

/// The reprojected pyramid and what makes it.
pub struct ReprojectState {
    /// The pyramid of this frame's reprojected depth (the layout of [`HizState`]'s).
    pub pyramid: Buffer,
    /// Per level-0 pixel: the farthest depth's key, or empty.
    keys: Buffer,
    layout: HizLayout,
    builder: HizBuilder,
    set_layout: vk::DescriptorSetLayout,
    pipeline_layout: vk::PipelineLayout,
    /// reproject.comp, reproject_resolve.comp.
    pipelines: [vk::Pipeline; 2],
    pool: vk::DescriptorPool,
    set: vk::DescriptorSet,
    /// This frame's push constants; `None` when there is nothing to reproject (the first frame,
    /// a cut, a change of depth convention): the culling then tests the frustum only.
    push: Option<ReprojectPush>,
}

impl PassState for ReprojectState {
    fn destroy(self: Box<Self>, ctx: &Context) {
        self.destroy_all(ctx);
    }
}

impl ReprojectState {
    /// The reprojection of `hiz`'s level 0, which must be the full-resolution depth (its base
    /// level 0).
    pub fn new(ctx: &Context, hiz: &HizState, frames_in_flight: usize) -> Result<Self, VkError> {
        let layout = hiz.layout.clone();
        if layout.levels.first().map(|l| l.level) != Some(0) {
            return Err(VkError::Invalid {
                what: "depth reprojection".into(),
                reason: "needs the pyramid's level 0 (hiz_resolution full)".into(),
            });
        }
        let (w, h) = layout.extent_px();
        let storage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let pyramid = ctx.create_buffer(
            "reprojected pyramid",
            layout.size_bytes(),
            storage,
            MemoryUse::GpuOnly,
        )?;
        let keys = match ctx.create_buffer(
            "reprojection keys",
            u64::from(w) * u64::from(h) * 4,
            storage | vk::BufferUsageFlags::TRANSFER_DST,
            MemoryUse::GpuOnly,
        ) {
            Ok(k) => k,
            Err(e) => {
                ctx.destroy_buffer(pyramid);
                return Err(e);
            }
        };
        let builder = match HizBuilder::new(ctx, frames_in_flight) {
            Ok(b) => b,
            Err(e) => {
                ctx.destroy_buffer(pyramid);
                ctx.destroy_buffer(keys);
                return Err(e);
            }
        };
        let mut state = ReprojectState {
            pyramid,
            keys,
            layout,
            builder,
            set_layout: vk::DescriptorSetLayout::null(),
            pipeline_layout: vk::PipelineLayout::null(),
            pipelines: [vk::Pipeline::null(); 2],
            pool: vk::DescriptorPool::null(),
            set: vk::DescriptorSet::null(),
            push: None,
        };
        match state.init(ctx, hiz) {
            Ok(()) => Ok(state),
            Err(e) => {
                state.destroy_all(ctx);
                Err(e)
            }
        }
    }

    fn init(&mut self, ctx: &Context, hiz: &HizState) -> Result<(), VkError> {
        let c = vk::ShaderStageFlags::COMPUTE;
        let ssbo = vk::DescriptorType::STORAGE_BUFFER;
        self.set_layout = create_set_layout(ctx, &[(0, ssbo, c), (1, ssbo, c), (2, ssbo, c)])?;
        let push = vk::PushConstantRange {
            stage_flags: c,
            offset: 0,
            size: std::mem::size_of::<ReprojectPush>() as u32,
        };
        self.pipeline_layout = create_pipeline_layout(ctx, &[self.set_layout], Some(push))?;
        for (pipeline, (name, spirv)) in self.pipelines.iter_mut().zip([
            ("reproject.comp", REPROJECT_SPV),
            ("reproject_resolve.comp", RESOLVE_SPV),
        ]) {
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
        let sizes = [vk::DescriptorPoolSize {
            ty: ssbo,
            descriptor_count: 3,
        }];
        let info = vk::DescriptorPoolCreateInfo::default()
            .max_sets(1)
            .pool_sizes(&sizes);
        // SAFETY: valid create info.
        self.pool = unsafe { ctx.device.create_descriptor_pool(&info, None) }
            .map_err(|r| VkError::call("vkCreateDescriptorPool", r))?;
        self.set = allocate_set(ctx, self.pool, self.set_layout)?;
        write_buffer_set(
            ctx,
            self.set,
            &[
                (0, ssbo, hiz.pyramid.raw),
                (1, ssbo, self.keys.raw),
                (2, ssbo, self.pyramid.raw),
            ],
        );
        Ok(())
    }

    /// This frame's reprojection: from last frame's view (`frame.reproject`, last frame's
    /// view-projection moved to this frame's eye) to this one's, when last frame's depth is
    /// there to move (`built_from` its convention, the same as this frame's, and no cut).
    pub fn write_frame(&mut self, frame: &CameraFrame, built_from: Option<DepthConvention>) {
        let m = &frame.current;
        if frame.cut || built_from != Some(m.depth) {
            self.push = None;
            return;
        }
        let f64_of = |a: Mat4| DMat4::from_cols_array(&a.to_cols_array().map(f64::from));
        // f64: the inverse of a reverse-Z infinite projection loses digits in f32.
        let now_from_previous = f64_of(m.view_projection) * f64_of(frame.reproject).inverse();
        let (w, h) = self.layout.extent_px();
        let first = self
            .layout
            .levels
            .first()
            .map_or(0, |l| l.offset_texels as u32);
        self.push = Some(ReprojectPush {
            now_from_previous: now_from_previous.as_mat4().to_cols_array_2d(),
            info: [w, h, u32::from(m.depth == DepthConvention::Reverse), first],
        });
    }

    /// Whether this frame tests against a reprojected pyramid.
    pub fn active(&self) -> bool {
        self.push.is_some()
    }

    fn record(&self, ctx: &Context, cb: vk::CommandBuffer, pipeline: usize) -> Result<(), VkError> {
        let Some(push) = self.push else {
            return Ok(());
        };
        let (w, h) = self.layout.extent_px();
        // SAFETY: recording outside a render pass; pipeline, layout and set are live; the push
        // block is the layout's range.
        unsafe {
            let d = &ctx.device;
            d.cmd_bind_pipeline(cb, vk::PipelineBindPoint::COMPUTE, self.pipelines[pipeline]);
            d.cmd_bind_descriptor_sets(
                cb,
                vk::PipelineBindPoint::COMPUTE,
                self.pipeline_layout,
                0,
                &[self.set],
                &[],
            );
            d.cmd_push_constants(
                cb,
                self.pipeline_layout,
                vk::ShaderStageFlags::COMPUTE,
                0,
                bytemuck::bytes_of(&push),
            );
            d.cmd_dispatch(cb, w.div_ceil(8), h.div_ceil(8), 1);
        }
        Ok(())
    }

    fn destroy_all(self, ctx: &Context) {
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
        self.builder.destroy(ctx);
        ctx.destroy_buffer(self.pyramid);
        ctx.destroy_buffer(self.keys);
    }
}

/// The reprojection's buffers in one frame's graph.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Reprojected {
    pub keys: BufferId,
    pub pyramid: BufferId,
}

/// Imports the reprojection's buffers into the frame.
pub fn import_reprojection(g: &mut FrameGraph, state: &ReprojectState) -> Reprojected {
    let any = ResourceState::buffer(
        PipelineStages::EVERY_GRAPH_STAGE,
        AccessFlags::MEMORY_READ.union(AccessFlags::MEMORY_WRITE),
    );
    let import = |content| Import {
        initial: any,
        content,
        final_state: any,
    };
    // Emptied by each frame's `reproject-clear`.
    let keys = g.import_buffer(
        "reprojection-keys",
        state.keys.size,
        import(InitialContent::Discard),
    );
    let pyramid = g.import_buffer(
        "reprojected-pyramid",
        state.pyramid.size,
        import(InitialContent::Discard),
    );
    Reprojected { keys, pyramid }
}

/// Declares the reprojection of `previous` (last frame's pyramid) into `r.pyramid`: keys
/// emptied, scatter, resolve, reduce. The culling then reads `r.pyramid`.
pub fn add_reprojection(g: &mut FrameGraph, previous: BufferId, r: Reprojected) {
    let keys = r.keys;
    let clear: Payload = Box::new(move |pc, _| {
        let b = pc.buffer(keys)?;
        // SAFETY: recording outside a render pass; the graph made the buffer a transfer
        // destination for this pass.
        unsafe {
            pc.ctx
                .device
                .cmd_fill_buffer(pc.cb, b.raw, 0, vk::WHOLE_SIZE, !0)
        };
        Ok(())
    });
    g.transfer_pass("reproject-clear", PassClass::Transfer, clear)
        .transfer_dst(r.keys);
    let scatter: Payload = Box::new(|pc, res| {
        let state = res.states.require::<ReprojectState>(pc.pass_name)?;
        state.record(pc.ctx, pc.cb, 0)
    });
    g.compute_pass("reproject", PassClass::Compute, scatter)
        .storage_read(previous)
        .storage_read_write(r.keys);
    let resolve: Payload = Box::new(|pc, res| {
        let state = res.states.require::<ReprojectState>(pc.pass_name)?;
        state.record(pc.ctx, pc.cb, 1)
    });
    g.compute_pass("reproject-resolve", PassClass::Compute, resolve)
        .storage_read(r.keys)
        .storage_write(r.pyramid);
    let pyramid = r.pyramid;
    let reduce: Payload = Box::new(move |pc, res| {
        let buffer = pc.buffer(pyramid)?;
        let state = res.states.require_mut::<ReprojectState>(pc.pass_name)?;
        if !state.active() {
            return Ok(());
        }
        let ReprojectState {
            builder, layout, ..
        } = state;
        builder.record_reductions(pc.ctx, pc.cb, pc.frame_slot, buffer, layout)
    });
    g.compute_pass("reproject-reduce", PassClass::Compute, reduce)
        .storage_read_write(r.pyramid);
}

impl ReprojectState {
    pub fn handle(&self) -> BufferHandle {
        BufferHandle {
            raw: self.pyramid.raw,
            size: self.pyramid.size,
        }
    }

    pub fn keys_handle(&self) -> BufferHandle {
        BufferHandle {
            raw: self.keys.raw,
            size: self.keys.size,
        }
    }
}
