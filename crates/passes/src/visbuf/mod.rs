//! The visibility buffer: an id pass writes, per pixel, the instance and triangle that own it
//! (one raster pass, depth tested and written), and a full-screen resolve shades each pixel once
//! from its id. On a tiler the resolve reads the id as an input attachment, so it can be a
//! subpass of the id pass's render pass and the ids never leave tile memory; on immediate GPUs
//! it samples them. The resolve is one shader for every material, or one per material over
//! the screen or over the tiles material classification found it in ([`classify`]).

pub mod classify;

use std::collections::HashMap;

use tilegraph_graph::{ClearColor, Format, ImageDesc, ImageId, PassClass, PassId};
use tilegraph_vk::ash::vk;
use tilegraph_vk::executor::PassContext;
use tilegraph_vk::pipeline::{allocate_set, create_nearest_sampler};
use tilegraph_vk::{Context, VkError};

use crate::draws::DrawClass;
use crate::frame::{scene_set, DrawSource, FrameGraph, PassState, Payload, SceneResources};
use crate::pipelines::Variant;
use crate::recording::{record_class, Predicate};
use crate::setup::VisbufResolve;
use crate::targets::SceneTargets;

/// Declares an id pass named `name` of phase `phase` (0 clears the ids; two-phase culling's
/// second phase adds to them), drawing opaque then alpha-tested geometry from `source`.
/// Returns the ids: the targets' (imported when the caller keeps them), or an image created by
/// the first id pass.
pub fn add_visbuf_write(
    g: &mut FrameGraph,
    targets: &mut SceneTargets,
    phase: u32,
    source: DrawSource,
    name: &str,
) -> ImageId {
    let extent = targets.extent;
    let ids = *targets.ids.get_or_insert_with(|| {
        g.create_image("visbuf-id", ImageDesc::new(extent, Format::R32_UINT))
    });
    let clear = ClearColor::Uint([u32::MAX; 4]);
    let variant = |alpha| Variant::Visbuf { alpha };
    add_screen_write(g, targets, (ids, clear), (phase, source, name), variant);
    ids
}

/// The geometry pass of a screen-space shading (the visibility buffer's ids, deferred
/// texturing's G-buffer): opaque then alpha-tested geometry from `source` drawn with
/// `variant(alpha)` into `image` and the depth, `image` cleared to `clear` by phase 0 (two-phase
/// culling's second phase adds to it).
pub(crate) fn add_screen_write(
    g: &mut FrameGraph,
    targets: &mut SceneTargets,
    (image, clear): (ImageId, ClearColor),
    (phase, source, name): (u32, DrawSource, &str),
    variant: fn(bool) -> Variant,
) {
    let record: Payload = Box::new(move |pc, res| {
        for (class, alpha) in [(DrawClass::Opaque, false), (DrawClass::AlphaTested, true)] {
            record_class(pc, res, variant(alpha), class, source, 1, Predicate::None)?;
        }
        Ok(())
    });
    let mut p = g.raster_pass(name, PassClass::Opaque, record);
    if phase == 0 {
        p.color_clear(image, clear);
    } else {
        p.color(image);
    }
    targets.attach_depth(&mut p, false);
    source.declare_reads(&mut p);
}

/// How a frame resolves the visibility buffer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ResolvePlan {
    pub mode: VisbufResolve,
    /// Read the ids as an input attachment (tilers; not with classification, which stores
    /// them).
    pub input: bool,
    /// The scene's materials (the per-material resolves' count).
    pub materials: u32,
    /// Classification's tile side in pixels.
    pub tile: u32,
}

impl ResolvePlan {
    /// `mode` for a scene of `materials` materials, as the device can run it: classification
    /// needs the materials to fit its tile masks, else the über-resolve runs (logged).
    pub fn new(mode: VisbufResolve, input: bool, materials: u32, tile: u32) -> Self {
        let mode = if mode == VisbufResolve::Classified
            && materials > classify::MAX_CLASSIFIED_MATERIALS
        {
            log::warn!(
                "visbuf_resolve classified: the scene has {materials} materials, more than the {} classification tracks; resolving in one pass",
                classify::MAX_CLASSIFIED_MATERIALS
            );
            VisbufResolve::Uber
        } else {
            mode
        };
        ResolvePlan {
            mode,
            input: input && mode != VisbufResolve::Classified,
            materials,
            tile,
        }
    }
}

/// Declares the resolve: shades every pixel of the colour target from `ids`, read as an input
/// attachment (`plan.input`, tilers) or sampled, in one pass for every material or per
/// material (over the screen, or over the material's tiles after classification).
pub fn add_visbuf_resolve(
    g: &mut FrameGraph,
    targets: &mut SceneTargets,
    ids: ImageId,
    plan: ResolvePlan,
) -> PassId {
    let per_material = match plan.mode {
        VisbufResolve::Classified => {
            return classify::add_classified_resolve(g, targets, ids, plan.materials, plan.tile)
        }
        VisbufResolve::PerMaterial => Some(plan.materials),
        VisbufResolve::Uber => None,
    };
    let input = plan.input;
    let record: Payload =
        Box::new(move |pc, res| record_resolve(pc, res, (ids, input), per_material));
    add_screen_resolve(g, targets, "visbuf-resolve", (&[ids], input), record)
}

/// A screen-space shading's full-screen resolve named `name`: reads `images` as input
/// attachments (`input`, in the shader's `input_attachment_index` order) or sampled, and
/// shades the colour target.
pub(crate) fn add_screen_resolve(
    g: &mut FrameGraph,
    targets: &mut SceneTargets,
    name: &str,
    (images, input): (&[ImageId], bool),
    record: Payload,
) -> PassId {
    let mut p = g.raster_pass(name, PassClass::Opaque, record);
    for &image in images {
        if input {
            p.input(image);
        } else {
            p.sampled(image);
        }
    }
    targets.attach_color(&mut p);
    p.id()
}

/// The resolves' descriptor sets (set 1: the visibility buffer's ids, or deferred texturing's
/// G-buffer and depth), one per frame slot, way of reading and image count.
pub struct ResolveSets {
    pool: vk::DescriptorPool,
    sampler: vk::Sampler,
    sets: HashMap<(usize, bool, usize), vk::DescriptorSet>,
}

/// The most images a resolve reads (deferred texturing: G-buffer and depth).
const MAX_RESOLVE_IMAGES: usize = 2;

impl ResolveSets {
    pub fn new(ctx: &Context, frames_in_flight: usize) -> Result<Self, VkError> {
        let n = frames_in_flight.max(1) as u32;
        // A set of each image count (1..=MAX) per slot and way of reading.
        let per_way = n * (1..=MAX_RESOLVE_IMAGES as u32).sum::<u32>();
        let sizes = [
            vk::DescriptorPoolSize {
                ty: vk::DescriptorType::INPUT_ATTACHMENT,
                descriptor_count: per_way,
            },
            vk::DescriptorPoolSize {
                ty: vk::DescriptorType::COMBINED_IMAGE_SAMPLER,
                descriptor_count: per_way,
            },
        ];
        let pool_info = vk::DescriptorPoolCreateInfo::default()
            .max_sets(2 * n * MAX_RESOLVE_IMAGES as u32)
            .pool_sizes(&sizes);
        // SAFETY: valid create info.
        let pool = unsafe { ctx.device.create_descriptor_pool(&pool_info, None) }
            .map_err(|r| VkError::call("vkCreateDescriptorPool", r))?;
        let sampler = match create_nearest_sampler(ctx) {
            Ok(s) => s,
            Err(e) => {
                // SAFETY: the pool is unused.
                unsafe { ctx.device.destroy_descriptor_pool(pool, None) };
                return Err(e);
            }
        };
        Ok(ResolveSets {
            pool,
            sampler,
            sets: HashMap::new(),
        })
    }

    /// Binds the scene's set and set 1 holding `images` (view and layout, at bindings 0..),
    /// read as input attachments (`input`) or sampled, for the resolve `pc` records; the
    /// frame slot's set, allocated on first use. Returns the pipeline layout bound.
    pub(crate) fn bind(
        pc: &PassContext<'_>,
        res: &mut SceneResources,
        input: bool,
        images: &[(ImageId, vk::ImageLayout)],
    ) -> Result<vk::PipelineLayout, VkError> {
        debug_assert!(!images.is_empty() && images.len() <= MAX_RESOLVE_IMAGES);
        let scene_set = scene_set(pc, res)?;
        let (set_layout, layout) = if input {
            (res.pipelines.input_set_layout, res.pipelines.input_layout)
        } else {
            (
                res.pipelines.sampled_set_layout,
                res.pipelines.sampled_layout,
            )
        };
        let mut infos = [vk::DescriptorImageInfo::default(); MAX_RESOLVE_IMAGES];
        for (info, &(image, image_layout)) in infos.iter_mut().zip(images) {
            *info = vk::DescriptorImageInfo {
                sampler: vk::Sampler::null(),
                image_view: pc.image(image)?.view,
                image_layout,
            };
        }
        let sets = res.states.require_mut::<ResolveSets>(pc.pass_name)?;
        let key = (pc.frame_slot, input, images.len());
        let set = match sets.sets.get(&key) {
            Some(s) => *s,
            None => {
                // The pool holds a set per slot, way of reading and image count.
                let s = allocate_set(pc.ctx, sets.pool, set_layout)?;
                sets.sets.insert(key, s);
                s
            }
        };
        let ty = if input {
            vk::DescriptorType::INPUT_ATTACHMENT
        } else {
            vk::DescriptorType::COMBINED_IMAGE_SAMPLER
        };
        let infos = &mut infos[..images.len()];
        for info in infos.iter_mut() {
            info.sampler = sets.sampler;
        }
        // Every binding written, the ones past `images` with its first (unread by the
        // shader): lavapipe of Mesa 22.3 reads every descriptor of a bound set and crashes on
        // one never written.
        let writes: [vk::WriteDescriptorSet<'_>; MAX_RESOLVE_IMAGES] = std::array::from_fn(|b| {
            vk::WriteDescriptorSet::default()
                .dst_set(set)
                .dst_binding(b as u32)
                .descriptor_type(ty)
                .image_info(std::slice::from_ref(
                    &infos[if b < infos.len() { b } else { 0 }],
                ))
        });
        let d = &pc.ctx.device;
        // SAFETY: the slot's previous frame completed (executor guarantee), so the set is
        // idle; recording inside the resolve's subpass.
        unsafe {
            d.update_descriptor_sets(&writes, &[]);
            d.cmd_bind_descriptor_sets(
                pc.cb,
                vk::PipelineBindPoint::GRAPHICS,
                layout,
                0,
                &[scene_set, set],
                &[],
            );
        }
        Ok(layout)
    }
}

impl PassState for ResolveSets {
    fn destroy(self: Box<Self>, ctx: &Context) {
        // SAFETY: the GPU is idle (caller's guarantee); the sets go with the pool.
        unsafe {
            ctx.device.destroy_sampler(self.sampler, None);
            ctx.device.destroy_descriptor_pool(self.pool, None);
        }
    }
}

/// The resolve over the screen: one draw of the über-resolve, or one per material of its
/// own resolve (`per_material`: the scene's materials).
fn record_resolve(
    pc: &mut PassContext<'_>,
    res: &mut SceneResources,
    (ids, input): (ImageId, bool),
    per_material: Option<u32>,
) -> Result<(), VkError> {
    let variant = if input {
        Variant::ResolveInput
    } else {
        Variant::ResolveSampled
    };
    let uber = match per_material {
        None => Some(
            res.pipelines
                .scene(pc, (variant, None), false, 1, res.frame.depth)?,
        ),
        Some(_) => None,
    };
    pc.set_full_viewport();
    let ids = [(ids, vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL)];
    let layout = ResolveSets::bind(pc, res, input, &ids)?;
    if let Some(pipeline) = uber {
        let d = &pc.ctx.device;
        // SAFETY: recording inside the resolve subpass, its sets bound.
        unsafe {
            d.cmd_bind_pipeline(pc.cb, vk::PipelineBindPoint::GRAPHICS, pipeline);
            d.cmd_draw(pc.cb, 3, 1, 0, 0);
        }
    }
    for m in 0..per_material.unwrap_or(0) {
        let coverage = classify::Coverage::Screen { input, layout };
        let pipeline = classify::material_resolve(pc, res, m, coverage, None)?;
        let d = &pc.ctx.device;
        // SAFETY: as above; set 1 stays bound (the same layout).
        unsafe {
            d.cmd_bind_pipeline(pc.cb, vk::PipelineBindPoint::GRAPHICS, pipeline);
            d.cmd_draw(pc.cb, 3, 1, 0, 0);
        }
    }
    Ok(())
}
