//! Per-triangle culling (knob `triangle_culling`; seed 000, after Wihlidal's "Optimizing the
//! Graphics Pipeline with Compute", GDC 2016): after each phase's cluster commands, three
//! dispatches (`cluster_tri_count.comp`, `cluster_tri_scan.comp`, `cluster_tri_write.comp`)
//! test every triangle of every command — clip volume, back-facing, zero-area, no sample
//! covered, and in two-phase culling's late phase the pyramid — and pack the indices of those
//! that may be drawn, in their order, into a tail reserved at the end of the scene's index
//! buffer ([`crate::GpuScene::reserve_index_tail`]); each command then draws its packed range.
//! Exact: a triangle goes only where the rasterizer would make no fragment of it or every
//! fragment would fail the depth test (common/triangles.glsl keeps the snapping margins), and
//! the order is the unculled one. A command that would run past the tail keeps its cluster
//! range.

use ash::vk;
use tilegraph_profile::MemoryUse;
use tilegraph_vk::ash;
use tilegraph_vk::pipeline::write_buffer_set;
use tilegraph_vk::{Buffer, Context, VkError};

use super::compute::{phase_set, ComputeStage};

const COUNT_SPV: &[u8] = include_bytes!("../../../../shaders/spv/cluster_tri_count.comp.spv");
const SCAN_SPV: &[u8] = include_bytes!("../../../../shaders/spv/cluster_tri_scan.comp.spv");
const WRITE_SPV: &[u8] = include_bytes!("../../../../shaders/spv/cluster_tri_write.comp.spv");

/// The stage's storage bindings 1-7 (common/triangles.glsl).
const STORAGE_BINDINGS: u32 = 7;

/// The most workgroups a count or write dispatch starts per slice (each strides over the
/// commands): enough to fill a GPU; on a CPU device (lavapipe) every workgroup is a task, and
/// the slices of the short commands that most are would start thousands for nothing.
const MAX_WORKGROUPS: u32 = 4096;
const MAX_WORKGROUPS_CPU: u32 = 256;

/// Slices of a command, a workgroup each (common/triangles.glsl's `TRI_SLICES`).
const SLICES: u32 = 8;

/// Words of the stage's buffer per command slot: its slices' counts, its place, its range.
const WORDS_PER_SLOT: u64 = SLICES as u64 + 3;

/// The most indices the tail holds: 2^23 (32 MiB); a frame that keeps more draws the rest of
/// its commands whole.
pub const MAX_TAIL_INDICES: u64 = 1 << 23;

/// The tail per-triangle culling reserves for `scene`: what its instances draw unculled (the
/// most one frame's commands can keep), at most [`MAX_TAIL_INDICES`].
pub fn tail_indices(scene: &tilegraph_scene::Scene) -> u64 {
    let meshes = scene.meshes();
    let total: u64 = scene
        .instances()
        .iter()
        .filter_map(|i| meshes.get(i.mesh.0 as usize))
        .map(|m| u64::from(m.index_count))
        .sum();
    total.clamp(3, MAX_TAIL_INDICES)
}

/// One of the three dispatches of a phase.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TriangleStep {
    /// `cluster_tri_count.comp`: a workgroup per slice of 1,024 triangles of a command counts
    /// the triangles it keeps.
    Count,
    /// `cluster_tri_scan.comp`: one workgroup places the commands' triangles in the tail.
    Scan,
    /// `cluster_tri_write.comp`: a workgroup per slice packs its triangles; the first slice's
    /// rewrites the command.
    Write,
}

/// The buffers the stage binds that the cluster stage and the instance culling own, per frame
/// slot the phases' parameter blocks.
pub(super) struct TriangleInputs {
    pub params: Vec<[vk::Buffer; 2]>,
    pub commands: vk::Buffer,
    pub counts: vk::Buffer,
    pub draw_ids: vk::Buffer,
    pub pyramid: vk::Buffer,
    pub levels: vk::Buffer,
    /// The cluster stage's places: where each draw group's commands start with fixed places
    /// (engine materials), and the runs of the list's groups before it.
    pub offsets: vk::Buffer,
    /// Command slots of both phases' lists.
    pub command_slots: u32,
}

/// The stage's buffer (per command slot: its slices' kept triangles, its place in the tail,
/// its range as emitted), its pipelines and sets.
pub struct TriangleStage {
    pub triangles: Buffer,
    command_slots: u32,
    /// The most workgroups per slice of a count or write dispatch.
    workgroups: u32,
    compute: ComputeStage<3>,
    /// Two per slot: the early (or only) and the late phase.
    sets: Vec<vk::DescriptorSet>,
}

impl TriangleStage {
    pub(super) fn new(
        ctx: &Context,
        inputs: &TriangleInputs,
        scene_set_layout: vk::DescriptorSetLayout,
    ) -> Result<Self, VkError> {
        let slots = u64::from(inputs.command_slots.max(1));
        let triangles = ctx.create_buffer(
            "cluster triangles",
            WORDS_PER_SLOT * slots * 4,
            vk::BufferUsageFlags::STORAGE_BUFFER,
            MemoryUse::GpuOnly,
        )?;
        let cpu = ctx.physical.identity.device_type == tilegraph_profile::DeviceType::Cpu;
        let mut stage = TriangleStage {
            triangles,
            command_slots: inputs.command_slots,
            workgroups: if cpu {
                MAX_WORKGROUPS_CPU
            } else {
                MAX_WORKGROUPS
            },
            compute: ComputeStage::EMPTY,
            sets: Vec::new(),
        };
        match stage.init(ctx, inputs, scene_set_layout) {
            Ok(()) => Ok(stage),
            Err(e) => {
                stage.destroy(ctx);
                Err(e)
            }
        }
    }

    fn init(
        &mut self,
        ctx: &Context,
        inputs: &TriangleInputs,
        scene_set_layout: vk::DescriptorSetLayout,
    ) -> Result<(), VkError> {
        let shaders = [
            ("cluster_tri_count.comp", COUNT_SPV),
            ("cluster_tri_scan.comp", SCAN_SPV),
            ("cluster_tri_write.comp", WRITE_SPV),
        ];
        let sets = 2 * inputs.params.len() as u32;
        self.compute
            .init(ctx, scene_set_layout, STORAGE_BINDINGS, shaders, sets)?;
        let ssbo = vk::DescriptorType::STORAGE_BUFFER;
        for params in &inputs.params {
            for p in params {
                let set = self.compute.allocate_set(ctx)?;
                write_buffer_set(
                    ctx,
                    set,
                    &[
                        (0, vk::DescriptorType::UNIFORM_BUFFER, *p),
                        (1, ssbo, inputs.commands),
                        (2, ssbo, inputs.counts),
                        (3, ssbo, inputs.draw_ids),
                        (4, ssbo, self.triangles.raw),
                        (5, ssbo, inputs.pyramid),
                        (6, ssbo, inputs.levels),
                        (7, ssbo, inputs.offsets),
                    ],
                );
                self.sets.push(set);
            }
        }
        Ok(())
    }

    /// `CullParams::triangles`: the tail's first index and length, the snapping step in pixels
    /// (f32 bits) of a rasterizer of `sub_pixel_bits`, where the places start.
    pub fn params(&self, tail: (u32, u32), sub_pixel_bits: u32) -> [u32; 4] {
        let step = 1.0 / (1u64 << sub_pixel_bits.min(16)) as f32;
        [tail.0, tail.1, step.to_bits(), self.command_slots.max(1)]
    }

    /// Records dispatch `step` of phase `which` (0 early or only, 1 late); the graph put the
    /// barriers around it.
    pub(super) fn record_dispatch(
        &self,
        ctx: &Context,
        cb: vk::CommandBuffer,
        scene_set: vk::DescriptorSet,
        slot: usize,
        which: usize,
        step: TriangleStep,
    ) -> Result<(), VkError> {
        let set = phase_set(&self.sets, slot, which, "triangle culling")?;
        // A workgroup per command and slice at most: the phase's lists hold at most half the
        // slots (the early phase's), or all of them (the late phase rewrites the union and
        // writes its own).
        let commands = (self.command_slots / 2 * (which as u32 + 1)).clamp(1, self.workgroups);
        let (pipeline, groups) = match step {
            TriangleStep::Count => (0, (commands, SLICES)),
            TriangleStep::Scan => (1, (1, 1)),
            TriangleStep::Write => (2, (commands, SLICES)),
        };
        self.compute.dispatch(
            ctx,
            cb,
            self.compute.pipelines[pipeline],
            [scene_set, set],
            groups,
        );
        Ok(())
    }

    pub(super) fn destroy(self, ctx: &Context) {
        self.compute.destroy(ctx);
        ctx.destroy_buffer(self.triangles);
    }
}
