//! What a renderer reads back after a frame for tests and tools: the visibility buffer's ids,
//! the drawn set, the GPU lists, fragment counts and the image. Each waits for the GPU.

use tilegraph_vk::ash::vk;
use tilegraph_vk::readback::RgbaImage;
use tilegraph_vk::Context;

use super::SceneRenderer;
use crate::cull::{CullState, GpuLists};
use crate::occlusion::OqState;
use crate::options::RenderError;
use crate::shadow::ShadowState;
use tilegraph_cull::shadow::MAX_CASCADES;

impl SceneRenderer {
    /// Shadow casters the last frame drew into each cascade (opaque and alpha-tested; waits
    /// for the GPU). `None` without shadows, or where the lists keep a fixed draw count.
    pub fn read_shadow_casters(
        &mut self,
        ctx: &Context,
    ) -> Result<Option<[u32; MAX_CASCADES]>, RenderError> {
        self.executor.finish(ctx)?;
        Ok(self
            .resources
            .states
            .get::<ShadowState>()
            .and_then(ShadowState::casters_drawn))
    }

    /// The casters (instance ids, sorted) the last frame drew into each of the main view's
    /// cascades (waits for the GPU; copies the lists out). `None` without shadows, or where
    /// the lists keep a fixed draw count.
    pub fn read_shadow_caster_ids(
        &mut self,
        ctx: &Context,
    ) -> Result<Option<Vec<Vec<u32>>>, RenderError> {
        self.executor.finish(ctx)?;
        match self.resources.states.get::<ShadowState>() {
            Some(s) => Ok(s.read_caster_ids(ctx)?),
            None => Ok(None),
        }
    }

    /// The last frame's depth, one value in [0, 1] a pixel, row by row (waits; `None` without
    /// `capture_depth`).
    pub fn read_depth(&mut self, ctx: &Context) -> Result<Option<Vec<f32>>, RenderError> {
        self.executor.finish(ctx)?;
        let Some((_, h)) = &self.views.main.depth_target else {
            return Ok(None);
        };
        let bytes =
            tilegraph_vk::readback::read_image(ctx, h, vk::ImageLayout::TRANSFER_SRC_OPTIMAL, 0)?;
        let depth = match self.views.main.options.depth_format {
            tilegraph_cull::DepthFormat::D16Unorm => bytes
                .chunks_exact(2)
                .map(|b| f32::from(u16::from_le_bytes([b[0], b[1]])) / 65535.0)
                .collect(),
            tilegraph_cull::DepthFormat::D32Float => bytes
                .chunks_exact(4)
                .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
                .collect(),
        };
        Ok(Some(depth))
    }

    /// The instance owning each pixel of the last frame (`u32::MAX` for background), from the
    /// captured visibility buffer (`capture_ids`); waits for the GPU.
    pub fn read_instance_ids(&mut self, ctx: &Context) -> Result<Option<Vec<u32>>, RenderError> {
        Ok(self.read_pixel_owners(ctx)?.map(|o| o.instances))
    }

    /// Each pixel's instance and, where the id has room for it (the scene's instance count and
    /// largest mesh fit 32 bits, [`crate::gpu_scene::visbuf_instance_bits`]), its triangle in
    /// the mesh's draw (waits; `None` without a visibility buffer).
    pub fn read_pixel_owners(&mut self, ctx: &Context) -> Result<Option<PixelOwners>, RenderError> {
        self.executor.finish(ctx)?;
        let Some((_, h)) = &self.views.main.ids_target else {
            return Ok(None);
        };
        let bytes =
            tilegraph_vk::readback::read_image(ctx, h, vk::ImageLayout::TRANSFER_SRC_OPTIMAL, 0)?;
        let ids: Vec<u32> = bytes
            .chunks_exact(4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect();
        let tri_bits = 32 - self.views.main.instance_bits.unwrap_or(32);
        let instances = ids
            .iter()
            .map(|&id| match id {
                u32::MAX => u32::MAX,
                _ if tri_bits >= 32 => 0,
                _ => id >> tri_bits,
            })
            .collect();
        let triangles = self.views.main.instance_bits.map(|_| {
            let mask = if tri_bits >= 32 {
                u32::MAX
            } else {
                (1u32 << tri_bits) - 1
            };
            ids.iter().map(|&id| id & mask).collect()
        });
        Ok(Some(PixelOwners {
            instances,
            triangles,
        }))
    }

    /// The instances the last frame drew through GPU culling (waits), or `None` without culling.
    pub fn drawn_instances(&mut self, ctx: &Context) -> Result<Option<Vec<u32>>, RenderError> {
        self.executor.finish(ctx)?;
        if let Some(d) = &self.views.main.last_drawn {
            return Ok(Some(d.clone()));
        }
        if let Some(oq) = self.resources.states.get::<OqState>() {
            if oq.conditions.is_some() {
                return Ok(Some(oq.conditional_drawn(ctx)?));
            }
        }
        match self.resources.states.get::<CullState>() {
            Some(c) => Ok(Some(c.drawn_instances(ctx, self.last_slot)?)),
            None => Ok(None),
        }
    }

    /// The last frame's GPU culling lists (waits), or `None` without GPU lists.
    pub fn gpu_lists(&mut self, ctx: &Context) -> Result<Option<GpuLists>, RenderError> {
        self.executor.finish(ctx)?;
        let order = self
            .resources
            .scene
            .read_order(ctx, self.last_slot, self.last_instances)?;
        let cull = self.resources.states.get::<CullState>();
        let slot = self.last_slot;
        Ok(cull.map(|c| c.read_lists(ctx, order, slot)).transpose()?)
    }

    /// Fragments shaded by the opaque, alpha-tested and blended colour passes of the last frame
    /// (with `count_fragments`; waits for the GPU).
    pub fn fragment_counts(&mut self, ctx: &Context) -> Result<[u32; 3], RenderError> {
        self.executor.finish(ctx)?;
        Ok(self
            .resources
            .scene
            .fragment_counts(ctx, self.last_slot, 0)?)
    }

    /// Reads the last frame's image (waits for the GPU); not for a renderer that draws into
    /// an engine's target.
    pub fn read_image(&mut self, ctx: &Context) -> Result<RgbaImage, RenderError> {
        if self.views.main.target.is_none() {
            return Err(RenderError::EngineSubmits);
        }
        self.executor.finish(ctx)?;
        self.views
            .main
            .read_target(ctx)?
            .ok_or(RenderError::EngineSubmits)
    }
}

/// What the visibility buffer says of each pixel ([`SceneRenderer::read_pixel_owners`]).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PixelOwners {
    /// The instance per pixel; `u32::MAX`: background.
    pub instances: Vec<u32>,
    /// The triangle of its mesh per pixel, where the ids hold it.
    pub triangles: Option<Vec<u32>>,
}
