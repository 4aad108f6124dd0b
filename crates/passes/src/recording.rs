//! Recording the scene's draws, for every pass that draws scene geometry: the CPU draw lists as
//! instanced draws (or one draw per instance under conditional rendering), and the culling
//! shader's lists as indirect draws with a GPU count. Single- and double-sided draws take two
//! pipelines; blended draws keep their back-to-front order and switch where the sidedness
//! changes, the others are grouped by pipeline (their order only helps early depth rejection).
//! A draw whose material is an engine's (crate::materials) binds that material's pipeline, set 0
//! with its layout and then the engine's own sets; GPU lists then draw in runs of groups of one
//! pipeline, in the list's order.

use tilegraph_vk::ash::vk;
use tilegraph_vk::executor::PassContext;
use tilegraph_vk::VkError;

use crate::cull::{list_index, CullState};
use crate::draws::DrawClass;
use crate::frame::{DrawSource, SceneResources};
use crate::occlusion::OqState;
use crate::pipelines::{Pipelines, Variant};
use tilegraph_scene::DepthConvention;

/// Binds the scene's vertex and index buffers and set 0 (`culled`: the set whose draw list is
/// the culling shader's), and sets the viewport; the set bound.
pub fn bind_geometry(
    pc: &PassContext<'_>,
    res: &SceneResources,
    culled: bool,
) -> Result<vk::DescriptorSet, VkError> {
    let slot = pc.frame_slot;
    let set = if culled {
        res.scene.culled_set(slot)
    } else {
        res.scene.set(slot)
    }
    .ok_or_else(|| VkError::Invalid {
        what: pc.pass_name.into(),
        reason: format!(
            "no {}scene descriptor set for frame slot {slot}",
            if culled { "culled " } else { "" }
        ),
    })?;
    pc.set_full_viewport();
    let d = &pc.ctx.device;
    // SAFETY: recording inside a subpass; buffers and set are live.
    unsafe {
        d.cmd_bind_vertex_buffers(pc.cb, 0, &[res.scene.vertices.raw], &[0]);
        d.cmd_bind_index_buffer(pc.cb, res.scene.indices.raw, 0, vk::IndexType::UINT32);
        d.cmd_bind_descriptor_sets(
            pc.cb,
            vk::PipelineBindPoint::GRAPHICS,
            res.pipelines.scene_layout,
            0,
            &[set],
            &[],
        );
    }
    Ok(set)
}

/// What a recording loop has bound: the sidedness and the engine material of its pipeline.
type Bound = Option<(bool, Option<u32>)>;

/// Binds the pipeline of `variant` for (`sided`, `engine`) unless `bound` already is it; around
/// an engine material's pipeline, set 0 again with the matching layout and the engine's sets.
fn bind_pipeline(
    pc: &PassContext<'_>,
    pipelines: &mut Pipelines,
    (variant, colors, depth): (Variant, u32, DepthConvention),
    (sided, engine): (bool, Option<u32>),
    set: vk::DescriptorSet,
    bound: &mut Bound,
) -> Result<(), VkError> {
    if *bound == Some((sided, engine)) {
        return Ok(());
    }
    let was_engine = bound.is_some_and(|(_, e)| e.is_some());
    let p = pipelines.scene(pc, (variant, engine), sided, colors, depth)?;
    let d = &pc.ctx.device;
    // SAFETY: inside the subpass; the pipeline and set are live, and the layout's set 0 is
    // the scene's (an engine material's layout must be made with it).
    unsafe {
        d.cmd_bind_pipeline(pc.cb, vk::PipelineBindPoint::GRAPHICS, p);
        if engine.is_some() || was_engine {
            d.cmd_bind_descriptor_sets(
                pc.cb,
                vk::PipelineBindPoint::GRAPHICS,
                pipelines.layout_for(engine),
                0,
                &[set],
                &[],
            );
        }
    }
    if let Some(k) = engine {
        pipelines.bind_material(pc.ctx, pc.cb, k, variant);
    }
    *bound = Some((sided, engine));
    Ok(())
}

/// Which occlusion-query results a pass's CPU draws are predicated on (conditional rendering).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Predicate {
    /// Drawn unconditionally.
    None,
    /// This frame's results, copied after the queries (the colour passes).
    ThisFrame,
    /// The previous frame's, still in the buffer before this frame's copy (the depth
    /// pre-pass: last frame's visible set).
    LastFrame,
}

/// Records the draws of material `class` from `source` with `variant` into a subpass with
/// `colors` colour attachments; with a `predicate`, each instance is drawn under conditional
/// rendering on its occlusion query's result.
pub fn record_class(
    pc: &PassContext<'_>,
    res: &mut SceneResources,
    variant: Variant,
    class: DrawClass,
    source: DrawSource,
    colors: u32,
    predicate: Predicate,
) -> Result<(), VkError> {
    match source {
        DrawSource::Cpu if predicate != Predicate::None => {
            record_conditional(pc, res, variant, class, colors, predicate)
        }
        DrawSource::Cpu => record_cpu(pc, res, variant, class, colors),
        DrawSource::Gpu {
            phase, clusters, ..
        } => record_indirect(pc, res, variant, class, (phase, clusters), colors),
    }
}

/// The CPU draw list's instanced draws.
fn record_cpu(
    pc: &PassContext<'_>,
    res: &mut SceneResources,
    variant: Variant,
    class: DrawClass,
    colors: u32,
) -> Result<(), VkError> {
    if res.frame.draws.of(class).is_empty() {
        return Ok(());
    }
    let set = bind_geometry(pc, res, false)?;
    let SceneResources {
        pipelines, frame, ..
    } = res;
    let draws = frame.draws.of(class);
    let d = &pc.ctx.device;
    let groups: &[Option<bool>] = if class == DrawClass::Blended {
        &[None]
    } else {
        &[Some(false), Some(true)]
    };
    let state = (variant, colors, frame.depth);
    for &group in groups {
        let mut bound: Bound = None;
        for draw in draws
            .iter()
            .filter(|d| group.is_none_or(|sided| d.double_sided == sided))
        {
            let engine = pipelines.engine_for(frame.engine_of(draw.mesh), variant);
            bind_pipeline(
                pc,
                pipelines,
                state,
                (draw.double_sided, engine),
                set,
                &mut bound,
            )?;
            // SAFETY: the draw's ranges lie inside the scene's buffers (built from the scene).
            unsafe {
                d.cmd_draw_indexed(
                    pc.cb,
                    draw.index_count,
                    draw.instance_count,
                    draw.first_index,
                    draw.vertex_offset,
                    draw.first_instance,
                )
            };
        }
    }
    Ok(())
}

/// The CPU draw list predicated on the occlusion queries' results: each run of consecutive
/// instances under one query is one instanced draw (instances the frame did not query are drawn
/// unconditionally). Same order as the instanced draws, so the image equals the unculled one.
fn record_conditional(
    pc: &PassContext<'_>,
    res: &mut SceneResources,
    variant: Variant,
    class: DrawClass,
    colors: u32,
    predicate: Predicate,
) -> Result<(), VkError> {
    if res.frame.draws.of(class).is_empty() {
        return Ok(());
    }
    let set = bind_geometry(pc, res, false)?;
    let SceneResources {
        pipelines,
        frame,
        states,
        ..
    } = res;
    let queries = states.require::<OqState>(pc.pass_name)?;
    let Some(cond) = pc.ctx.conditional_rendering() else {
        return Err(VkError::Invalid {
            what: pc.pass_name.into(),
            reason: "conditional draws need VK_EXT_conditional_rendering".into(),
        });
    };
    let Some(conditions) = queries.conditions.as_ref().map(|b| b.raw) else {
        return Err(VkError::Invalid {
            what: pc.pass_name.into(),
            reason: "the occlusion queries keep no results on the GPU".into(),
        });
    };
    let d = &pc.ctx.device;
    let state = (variant, colors, frame.depth);
    for sided in [false, true] {
        let mut bound: Bound = None;
        for draw in frame
            .draws
            .of(class)
            .iter()
            .filter(|d| d.double_sided == sided)
        {
            let engine = pipelines.engine_for(frame.engine_of(draw.mesh), variant);
            bind_pipeline(pc, pipelines, state, (sided, engine), set, &mut bound)?;
            // Runs of consecutive instances under one query draw instanced, predicated once
            // (query groups hold one mesh's instances, so a group's members often follow each
            // other in the draw's distance order).
            let condition = |k: u32| {
                frame
                    .draws
                    .instances
                    .get(k as usize)
                    .and_then(|&id| match predicate {
                        Predicate::LastFrame => queries.previous_condition_offset(id),
                        _ => queries.condition_offset(id),
                    })
            };
            let end = draw.first_instance + draw.instance_count;
            let mut k = draw.first_instance;
            while k < end {
                let offset = condition(k);
                let mut run = 1;
                while k + run < end && condition(k + run) == offset {
                    run += 1;
                }
                if let Some(offset) = offset {
                    let begin = vk::ConditionalRenderingBeginInfoEXT::default()
                        .buffer(conditions)
                        .offset(offset);
                    // SAFETY: the buffer has CONDITIONAL_RENDERING usage, the offset is a
                    // multiple of 4 inside it; the copy pass wrote it and the graph made it
                    // visible to the conditional-rendering stage (the pass's predicate).
                    unsafe { (cond.fp().cmd_begin_conditional_rendering_ext)(pc.cb, &begin) };
                }
                // SAFETY: the draw's ranges lie inside the scene's buffers; `k..k + run` lies
                // inside the draw's instances.
                unsafe {
                    d.cmd_draw_indexed(
                        pc.cb,
                        draw.index_count,
                        run,
                        draw.first_index,
                        draw.vertex_offset,
                        k,
                    )
                };
                if offset.is_some() {
                    // SAFETY: ends the conditional block begun above, in the same subpass.
                    unsafe { (cond.fp().cmd_end_conditional_rendering_ext)(pc.cb) };
                }
                k += run;
            }
        }
    }
    Ok(())
}

/// The culling shader's lists of one material class and phase (single- and double-sided, each
/// with its pipeline) as compacted indirect draws.
fn record_indirect(
    pc: &PassContext<'_>,
    res: &mut SceneResources,
    variant: Variant,
    class: DrawClass,
    (phase, clusters): (u32, bool),
    colors: u32,
) -> Result<(), VkError> {
    let set = bind_geometry(pc, res, true)?;
    let SceneResources {
        pipelines,
        frame,
        states,
        ..
    } = res;
    let culling = states.require::<CullState>(pc.pass_name)?;
    let state = (variant, colors, frame.depth);
    for sided in [false, true] {
        let list = list_index(class.index(), sided, phase);
        let mut bound: Bound = None;
        let meshes = culling.group_meshes(pc.frame_slot, list)?;
        let engine_of = |p: &Pipelines, g: &u32| p.engine_for(frame.engine_of(*g), variant);
        if !meshes.iter().any(|g| engine_of(pipelines, g).is_some()) {
            bind_pipeline(pc, pipelines, state, (sided, None), set, &mut bound)?;
            culling.record_draws(pc.ctx, pc.cb, pc.frame_slot, (list, clusters))?;
            continue;
        }
        // Runs of consecutive groups of one pipeline.
        let mut first = 0;
        while first < meshes.len() {
            let engine = engine_of(pipelines, &meshes[first]);
            let len = meshes[first..]
                .iter()
                .take_while(|g| engine_of(pipelines, g) == engine)
                .count();
            bind_pipeline(pc, pipelines, state, (sided, engine), set, &mut bound)?;
            culling.record_group_run(
                pc.ctx,
                pc.cb,
                pc.frame_slot,
                (list, clusters),
                (first as u32, len as u32),
            )?;
            first += len;
        }
    }
    Ok(())
}
