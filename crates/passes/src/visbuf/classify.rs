//! Material classification for the visibility buffer (seed 000; Dawn engine's material depth,
//! Nanite's material passes, Horizon Forbidden West's compute classification): after the ids
//! are written, a compute pass finds which materials each screen tile shows and appends the tile
//! to those materials' tile lists, growing each material's indirect draw; each material's
//! resolve then draws quads over its own tiles only, and its fragment shader — the resolve
//! specialized to that material — shades that material's pixels and discards the others' in
//! the tiles it shares. One pipeline per material: what lets a visibility buffer carry many
//! materials, each with a shader of its own.
//!
//! The classification reads the ids from memory, so on a tiler they leave tile memory (stored
//! after the id pass, read back by the classification and the resolve): `uber` keeps the
//! resolve a subpass instead, and is what the tiler profiles choose (docs/PROFILES.md).

use tilegraph_graph::{BufferId, ImageId, PassClass, PassId};
use tilegraph_vk::ash::vk;
use tilegraph_vk::executor::PassContext;
use tilegraph_vk::pipeline::{
    allocate_set, create_compute_pipeline, create_described_pipeline, create_nearest_sampler,
    create_pipeline_layout, create_set_layout, Blend, DepthState, GraphicsDesc, Stage,
};
use tilegraph_vk::{Context, Feature, VkError};

use crate::cull::zero_fill;
use crate::frame::{scene_set, FrameGraph, PassState, Payload, SceneResources};
use crate::materials::MaterialPass;
use crate::pipelines::{with_colors, PipelineKey};
use crate::spv;
use crate::targets::SceneTargets;

/// Materials classification tracks: a scene with more resolves in one pass (its materials'
/// bits would not fit a tile's mask; `MAX_CLASSIFIED_MATERIALS` in `shaders/common/visbuf.glsl`).
pub const MAX_CLASSIFIED_MATERIALS: u32 = 256;

/// The screen's tiles of `tile` pixels: columns and rows.
pub fn tile_grid(width: u32, height: u32, tile: u32) -> (u32, u32) {
    (width.div_ceil(tile), height.div_ceil(tile))
}

/// The classification's set 1 (the ids sampled, the tile lists, the indirect draws), its
/// pipeline layout (the scene's set 0, then set 1: the compute pass and the resolve share
/// it), a set per frame slot and the compute pipeline of each tile size used.
pub struct ClassifyState {
    set_layout: vk::DescriptorSetLayout,
    pub(super) layout: vk::PipelineLayout,
    pool: vk::DescriptorPool,
    sampler: vk::Sampler,
    sets: Vec<vk::DescriptorSet>,
    compute: Vec<(u32, vk::Pipeline)>,
}

impl ClassifyState {
    pub fn new(
        ctx: &Context,
        scene_set_layout: vk::DescriptorSetLayout,
        frames_in_flight: usize,
    ) -> Result<Self, VkError> {
        let n = frames_in_flight.max(1) as u32;
        let mut s = ClassifyState {
            set_layout: vk::DescriptorSetLayout::null(),
            layout: vk::PipelineLayout::null(),
            pool: vk::DescriptorPool::null(),
            sampler: vk::Sampler::null(),
            sets: Vec::new(),
            compute: Vec::new(),
        };
        match s.create(ctx, scene_set_layout, n) {
            Ok(()) => Ok(s),
            Err(e) => {
                Box::new(s).destroy(ctx);
                Err(e)
            }
        }
    }

    fn create(
        &mut self,
        ctx: &Context,
        scene_set_layout: vk::DescriptorSetLayout,
        n: u32,
    ) -> Result<(), VkError> {
        use vk::ShaderStageFlags as S;
        let ssbo = vk::DescriptorType::STORAGE_BUFFER;
        self.set_layout = create_set_layout(
            ctx,
            &[
                (
                    0,
                    vk::DescriptorType::COMBINED_IMAGE_SAMPLER,
                    S::COMPUTE | S::FRAGMENT,
                ),
                (1, ssbo, S::COMPUTE | S::VERTEX),
                (2, ssbo, S::COMPUTE),
            ],
        )?;
        self.layout = create_pipeline_layout(ctx, &[scene_set_layout, self.set_layout], None)?;
        let sizes = [
            vk::DescriptorPoolSize {
                ty: vk::DescriptorType::COMBINED_IMAGE_SAMPLER,
                descriptor_count: n,
            },
            vk::DescriptorPoolSize {
                ty: ssbo,
                descriptor_count: 2 * n,
            },
        ];
        let info = vk::DescriptorPoolCreateInfo::default()
            .max_sets(n)
            .pool_sizes(&sizes);
        // SAFETY: valid create info.
        self.pool = unsafe { ctx.device.create_descriptor_pool(&info, None) }
            .map_err(|r| VkError::call("vkCreateDescriptorPool", r))?;
        self.sampler = create_nearest_sampler(ctx)?;
        for _ in 0..n {
            let set = allocate_set(ctx, self.pool, self.set_layout)?;
            self.sets.push(set);
        }
        Ok(())
    }

    /// Set 1's layout (an engine resolve's pipeline layout has it as set 1).
    pub fn set_layout(&self) -> vk::DescriptorSetLayout {
        self.set_layout
    }

    /// The classification pipeline for tiles of `tile` pixels (made on first use).
    fn compute_pipeline(&mut self, ctx: &Context, tile: u32) -> Result<vk::Pipeline, VkError> {
        if let Some((_, p)) = self.compute.iter().find(|(t, _)| *t == tile) {
            return Ok(*p);
        }
        let spec = [(3, tile)];
        let p = create_compute_pipeline(
            ctx,
            &Stage {
                name: "visbuf_classify.comp",
                spirv: spv::CLASSIFY_CS,
                specialization: &spec,
            },
            self.layout,
        )?;
        self.compute.push((tile, p));
        Ok(p)
    }

    /// The set of the frame slot `pc` records.
    fn set(&self, pc: &PassContext<'_>) -> Result<vk::DescriptorSet, VkError> {
        self.sets
            .get(pc.frame_slot)
            .copied()
            .ok_or_else(|| VkError::Invalid {
                what: pc.pass_name.into(),
                reason: format!("no classification set for frame slot {}", pc.frame_slot),
            })
    }

    /// Points the frame slot's set at this frame's ids, tile lists and draws (once per frame,
    /// by the classification, before anything binds it); the set.
    fn write_set(
        &self,
        pc: &PassContext<'_>,
        (ids, tiles, commands): (ImageId, BufferId, BufferId),
    ) -> Result<vk::DescriptorSet, VkError> {
        let set = self.set(pc)?;
        let image = [vk::DescriptorImageInfo {
            sampler: self.sampler,
            image_view: pc.image(ids)?.view,
            image_layout: vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL,
        }];
        let buffer = |b: BufferId| -> Result<[vk::DescriptorBufferInfo; 1], VkError> {
            Ok([vk::DescriptorBufferInfo {
                buffer: pc.buffer(b)?.raw,
                offset: 0,
                range: vk::WHOLE_SIZE,
            }])
        };
        let (t, c) = (buffer(tiles)?, buffer(commands)?);
        let writes = [
            vk::WriteDescriptorSet::default()
                .dst_set(set)
                .dst_binding(0)
                .descriptor_type(vk::DescriptorType::COMBINED_IMAGE_SAMPLER)
                .image_info(&image),
            vk::WriteDescriptorSet::default()
                .dst_set(set)
                .dst_binding(1)
                .descriptor_type(vk::DescriptorType::STORAGE_BUFFER)
                .buffer_info(&t),
            vk::WriteDescriptorSet::default()
                .dst_set(set)
                .dst_binding(2)
                .descriptor_type(vk::DescriptorType::STORAGE_BUFFER)
                .buffer_info(&c),
        ];
        // SAFETY: the slot's previous frame completed (executor guarantee): the set is idle.
        unsafe { pc.ctx.device.update_descriptor_sets(&writes, &[]) };
        Ok(set)
    }
}

impl PassState for ClassifyState {
    fn destroy(self: Box<Self>, ctx: &Context) {
        // SAFETY: the GPU is idle (caller's guarantee); the sets go with the pool; null
        // handles are ignored.
        unsafe {
            for (_, p) in &self.compute {
                ctx.device.destroy_pipeline(*p, None);
            }
            ctx.device.destroy_sampler(self.sampler, None);
            ctx.device.destroy_descriptor_pool(self.pool, None);
            ctx.device.destroy_pipeline_layout(self.layout, None);
            ctx.device
                .destroy_descriptor_set_layout(self.set_layout, None);
        }
    }
}

/// Declares the classification and the classified resolve of `materials` materials over tiles
/// of `tile` pixels: the draws zeroed, the tiles sorted (compute), each material's tiles
/// resolved (one indirect draw per material).
pub fn add_classified_resolve(
    g: &mut FrameGraph,
    targets: &mut SceneTargets,
    ids: ImageId,
    materials: u32,
    tile: u32,
) -> PassId {
    let (columns, rows) = tile_grid(targets.extent.width_px, targets.extent.height_px, tile);
    let capacity = u64::from(columns * rows);
    let m = u64::from(materials.max(1));
    let commands = g.create_buffer("visbuf-material-draws", m * 16);
    let tiles = g.create_buffer("visbuf-material-tiles", m * capacity * 4);
    let clear: Payload = Box::new(move |pc, _| zero_fill(pc, commands));
    g.transfer_pass("visbuf-classify-clear", PassClass::Transfer, clear)
        .transfer_dst(commands);
    let classify: Payload = Box::new(move |pc, res| {
        let set = scene_set(pc, res)?;
        let state = res.states.require_mut::<ClassifyState>(pc.pass_name)?;
        let pipeline = state.compute_pipeline(pc.ctx, tile)?;
        let own = state.write_set(pc, (ids, tiles, commands))?;
        let d = &pc.ctx.device;
        // SAFETY: recording outside a render pass; the sets and pipeline are live.
        unsafe {
            d.cmd_bind_pipeline(pc.cb, vk::PipelineBindPoint::COMPUTE, pipeline);
            d.cmd_bind_descriptor_sets(
                pc.cb,
                vk::PipelineBindPoint::COMPUTE,
                state.layout,
                0,
                &[set, own],
                &[],
            );
            d.cmd_dispatch(pc.cb, columns, rows, 1);
        }
        Ok(())
    });
    g.compute_pass("visbuf-classify", PassClass::Compute, classify)
        .sampled(ids)
        .storage_write(tiles)
        .storage_read_write(commands);
    let record: Payload =
        Box::new(move |pc, res| record_classified(pc, res, commands, materials, tile));
    let mut p = g.raster_pass("visbuf-resolve", PassClass::Opaque, record);
    p.sampled(ids).storage_read(tiles).indirect(commands);
    targets.attach_color(&mut p);
    p.id()
}

/// Each material's tiles, resolved by its own pipeline.
fn record_classified(
    pc: &mut PassContext<'_>,
    res: &mut SceneResources,
    commands: BufferId,
    materials: u32,
    tile: u32,
) -> Result<(), VkError> {
    let set = scene_set(pc, res)?;
    let state = res.states.require::<ClassifyState>(pc.pass_name)?;
    // Written by this frame's classification.
    let (layout, own) = (state.layout, state.set(pc)?);
    let commands = pc.buffer(commands)?.raw;
    pc.set_full_viewport();
    // SAFETY: recording inside the resolve's subpass; the sets are live.
    unsafe {
        pc.ctx.device.cmd_bind_descriptor_sets(
            pc.cb,
            vk::PipelineBindPoint::GRAPHICS,
            layout,
            0,
            &[set, own],
            &[],
        )
    };
    // With a draw count, a material without tiles costs no draw: its command's instance count
    // (0, or 1 once the classification found a tile) is the count. (It also keeps lavapipe
    // right: Mesa 22.3's vkCmdDrawIndirect after a vkCmdDrawIndexedIndirectCount in the same
    // command buffer reuses the earlier count buffer.)
    let counted = pc.ctx.has_feature(Feature::DrawIndirectCount);
    for m in 0..materials {
        let engine = res.frame.engine_resolve_of(m);
        let coverage = Coverage::Tiles { tile, layout };
        let pipeline = material_resolve(pc, res, m, coverage, engine)?;
        let d = &pc.ctx.device;
        let at = u64::from(m) * 16;
        // SAFETY: as above; the draw's command was written by the classification; the count
        // variant only where the device enabled drawIndirectCount.
        unsafe {
            d.cmd_bind_pipeline(pc.cb, vk::PipelineBindPoint::GRAPHICS, pipeline);
        }
        if let Some(material) = engine.and_then(|k| res.pipelines.engine_material(k)) {
            if let Some(r) = &material.resolve {
                // Sets 0 and 1 again with the engine's layout (its push constants may make it
                // incompatible with the classification's), then the engine's own.
                // SAFETY: as above.
                unsafe {
                    d.cmd_bind_descriptor_sets(
                        pc.cb,
                        vk::PipelineBindPoint::GRAPHICS,
                        r.layout,
                        0,
                        &[set, own],
                        &[],
                    )
                };
                (material.bind)(pc.ctx, pc.cb, MaterialPass::Resolve);
            }
        }
        // SAFETY: as above.
        unsafe {
            if counted {
                d.cmd_draw_indirect_count(pc.cb, commands, at, commands, at + 4, 1, 16);
            } else {
                d.cmd_draw_indirect(pc.cb, commands, at, 1, 16);
            }
        }
    }
    Ok(())
}

/// What a per-material resolve pipeline draws.
#[derive(Debug, Clone, Copy)]
pub(super) enum Coverage {
    /// One triangle over the screen; the ids read as an input attachment or sampled, with
    /// the resolve's own layout.
    Screen {
        input: bool,
        layout: vk::PipelineLayout,
    },
    /// The material's tiles (`visbuf_tile.vert`), with the classification's layout.
    Tiles {
        tile: u32,
        layout: vk::PipelineLayout,
    },
}

/// The resolve of material `material` alone for the subpass `pc` records into: tilegraph's,
/// or engine material `engine`'s (over tiles only: its layout has the classification's set 1).
pub(super) fn material_resolve(
    pc: &PassContext<'_>,
    res: &mut SceneResources,
    material: u32,
    coverage: Coverage,
    engine: Option<u32>,
) -> Result<vk::Pipeline, VkError> {
    let (input, tile, layout) = match coverage {
        Coverage::Screen { input, layout } => (input, 0, layout),
        Coverage::Tiles { tile, layout } => (false, tile, layout),
    };
    let key = PipelineKey::Resolve {
        material,
        input,
        tile,
        engine,
    };
    let (name, fragment_spirv) = res.pipelines.resolve_fragment(input);
    let slots = res.pipelines.texture_slots();
    let own = engine
        .and_then(|k| res.pipelines.engine_material(k))
        .filter(|m| m.resolve.is_some())
        .cloned();
    res.pipelines.get_or_create(pc, key, |target| {
        let engine_resolve = own.as_deref().and_then(|m| m.resolve.as_ref());
        let (name, fragment_spirv, layout) = match engine_resolve {
            Some(r) => (r.fragment.name.as_str(), &r.fragment.spirv[..], r.layout),
            None => (name, fragment_spirv, layout),
        };
        let fragment_spec = [(1, slots), (2, material)];
        let tile_spec = [(2, material), (3, tile)];
        let vertex = if tile == 0 {
            Stage {
                name: "fullscreen.vert",
                spirv: crate::pipelines::FULLSCREEN_VS,
                specialization: &[],
            }
        } else {
            Stage {
                name: "visbuf_tile.vert",
                spirv: spv::TILE_VS,
                specialization: &tile_spec,
            }
        };
        create_described_pipeline(
            pc.ctx,
            &GraphicsDesc {
                name: pc.pass_name,
                vertex,
                fragment: Some(Stage {
                    name,
                    spirv: fragment_spirv,
                    specialization: &fragment_spec,
                }),
                vertex_layout: None,
                layout,
                target: with_colors(target, 1),
                depth: DepthState::OFF,
                blend: Blend::Opaque,
                cull: vk::CullModeFlags::NONE,
                samples: vk::SampleCountFlags::TYPE_1,
            },
        )
    })
}
