//! Renderers: a scene drawn into the engine's colour target, recorded into the engine's
//! command buffer; per-frame statistics and GPU times per pass.

use std::ffi::{c_char, c_void, CString};

use tilegraph_graph::{AccessFlags, Layout, PipelineStages, ResourceState};
use tilegraph_passes::{EngineTarget, FrameReport, GpuTiming, RenderOptions, SceneRenderer};
use tilegraph_scene::{Camera, CameraFrame, Scene};
use tilegraph_vk::ash::vk::{self, Handle};
use tilegraph_vk::executor::{EngineFrame, ImageHandle};

use crate::context::{ContextObject, TgContext};
use crate::options::{view_options, TgViewDesc};
use crate::pvs::TgPvs;
use crate::registry::{self, Kind};
use crate::scene::{TgCamera, TgScene};
use crate::status::{arg, boundary, out, Failure, TgStatus};

/// A renderer: one scene, drawn frame after frame into the engine's target.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TgRenderer {
    pub raw: u64,
}

#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct TgRendererDesc {
    /// A TgTechnique.
    pub technique: u32,
    /// A TgCulling.
    pub culling: u32,
    /// The size of the targets the renderer draws into.
    pub width: u32,
    pub height: u32,
    /// The engine's frames in flight, 1 to 16: `TgEngineFrame::slot` is below it.
    pub frames_in_flight: u32,
    pub clear_color: [f32; 4],
    /// Instance slots the renderer's buffers hold from the start (0: the scene's; rounded up to
    /// a power of two). A scene that outgrows them gets new buffers at its next record, which
    /// waits for the device: give the count the game will reach.
    pub instance_capacity: u32,
    /// TG_TECHNIQUE_VISBUF's resolve: 0 the profile's knob `visbuf_resolve`, 1 one shader for
    /// every material, 2 a full-screen pass per material, 3 material classification (what an
    /// engine material's resolve shader needs).
    pub visbuf_resolve: u32,
    /// The directional light's cascaded shadow maps (`tg_renderer_set_light` points the
    /// light): 0 none, 1 to 4 cascades in one depth atlas, drawn and sampled by the renderer's
    /// passes (docs/CULLING.md, "Shadow casters").
    pub shadow_cascades: u32,
    /// Texels on a side of each cascade, 64 to 4096 (0: 1024).
    pub shadow_resolution: u32,
    /// A TgShadowCulling: which casters each cascade draws (every choice gives the same image).
    pub shadow_culling: u32,
    /// As `TgViewDesc::pvs` and `pvs_dilation`: the visible set TG_CULLING_PVS draws from.
    pub pvs: TgPvs,
    pub pvs_dilation: u32,
    /// As `TgViewDesc::lod_error_px`.
    pub lod_error_px: f32,
    /// As `TgViewDesc::lod_hysteresis`.
    pub lod_hysteresis: f32,
}

/// Which shadow casters each cascade draws (docs/CULLING.md, "Shadow casters"). All exact.
#[repr(u32)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TgShadowCulling {
    /// Those whose shadow can reach the camera's view (the default).
    Receivers = 0,
    /// Every caster into every cascade.
    None = 1,
    /// Those in the cascade's box.
    Cascade = 2,
    /// Of `Receivers`, those whose shadow falls on something the camera sees (this frame's
    /// depth pyramid: TG_CULLING_HIZ_TWO_PHASE with a pre-pass or the visibility buffer; else
    /// it is `Receivers`).
    ReceiversHiz = 3,
}

/// An image's layout and last (or next) use.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct TgImageState {
    /// VkImageLayout.
    pub layout: i32,
    /// VkPipelineStageFlags2.
    pub stages: u64,
    /// VkAccessFlags2.
    pub access: u64,
}

/// The engine's colour target for one frame.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct TgTarget {
    /// VkImage (2D, one mip, one layer, COLOR_ATTACHMENT usage).
    pub image: u64,
    /// VkImageView of it.
    pub view: u64,
    /// VkFormat (a colour format).
    pub format: i32,
    pub width: u32,
    pub height: u32,
    /// The state the engine left it in (layout UNDEFINED discards the content).
    pub initial: TgImageState,
    /// The state the frame leaves it in (PRESENT_SRC_KHR for a swapchain image).
    pub final_state: TgImageState,
}

/// The engine's side of a frame.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct TgEngineFrame {
    /// VkCommandBuffer in the recording state, outside a render pass.
    pub command_buffer: *mut c_void,
    /// The engine's frame slot: the GPU has finished the frame last recorded with it.
    pub slot: u32,
}

/// What the last recorded frame did.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default)]
pub struct TgFrameStats {
    /// The frame's number (0, 1, ...).
    pub frame: u64,
    pub render_passes: u32,
    pub subpasses: u32,
    pub barriers: u32,
    /// Plan flushes the engine may make by splitting its submission (Adreno, before
    /// occlusion queries): recorded as one command buffer here.
    pub flushes_left_to_engine: u32,
    /// Non-zero when the frame built its resources (a new plan).
    pub rebuilt: u32,
    /// Device-memory allocations the frame made (0 in steady state).
    pub device_allocations: u64,
    /// Draws and triangles of the CPU draw lists (GPU culling draws a subset of them).
    pub draws: u32,
    pub triangles: u64,
    /// The newest frame whose GPU times arrived (frames in flight earlier), and its passes.
    pub timed_frame: u64,
    pub timed_pass_count: u32,
    /// The sum of that frame's timings: its passes' GPU time, or with `TG_GPU_TIMING_FRAME`
    /// the whole frame's.
    pub timed_gpu_ms: f64,
    /// Non-zero when the GPU culling counts below exist (GPU culling, and a frame completed).
    pub gpu_counted: u32,
    /// The frame they describe (frames in flight earlier), the indirect commands its colour
    /// pass drew, the instances they drew and the instances culled on the GPU.
    pub gpu_counted_frame: u64,
    pub gpu_commands: u32,
    pub gpu_drawn: u32,
    pub gpu_culled: u32,
}

/// One pass's GPU time in the newest timed frame.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct TgPassTime {
    /// The pass's name; valid until the next call on this renderer.
    pub name: *const c_char,
    pub gpu_ms: f64,
    /// Non-zero when the device counts shader invocations (pipeline statistics).
    pub has_statistics: u32,
    pub vertex_invocations: u64,
    pub fragment_invocations: u64,
}

pub(crate) struct RendererObject {
    pub(crate) renderer: SceneRenderer,
    pub(crate) context: u64,
    pub(crate) scene: u64,
    aspect: f32,
    previous: Option<Camera>,
    frames: usize,
    last: Option<FrameReport>,
    /// Pass names handed out by `tg_renderer_pass_time`, replaced only when a name changes.
    names: Vec<CString>,
}

pub(crate) fn state(s: &TgImageState, name: &str) -> Result<ResourceState, Failure> {
    let layout = Layout::from_vk_raw(s.layout).ok_or_else(|| {
        Failure::invalid(format!(
            "`{name}.layout` {} is not a layout tilegraph uses",
            s.layout
        ))
    })?;
    let stages = PipelineStages::from_named_bits(s.stages).ok_or_else(|| {
        Failure::invalid(format!(
            "`{name}.stages` {:#x} holds bits that are no VkPipelineStageFlagBits2 tilegraph knows",
            s.stages
        ))
    })?;
    let access = AccessFlags::from_named_bits(s.access).ok_or_else(|| {
        Failure::invalid(format!(
            "`{name}.access` {:#x} holds bits that are no VkAccessFlagBits2 tilegraph knows",
            s.access
        ))
    })?;
    Ok(ResourceState::image(layout, stages, access))
}

/// Makes a renderer for `scene` on `context`: uploads the scene, makes the culling
/// technique's state and the pipelines. The engine will record its frames with
/// `tg_renderer_record`.
///
/// # Safety
/// `desc` is valid; `out_renderer` is writable.
#[no_mangle]
pub unsafe extern "C" fn tg_renderer_create(
    context: TgContext,
    scene: TgScene,
    desc: *const TgRendererDesc,
    out_renderer: *mut TgRenderer,
) -> TgStatus {
    boundary("tg_renderer_create", || {
        // SAFETY: the caller's contract.
        let desc = unsafe { arg(desc, "desc") }?;
        // SAFETY: as above.
        let out_renderer = unsafe { out(out_renderer, "out_renderer") }?;
        *out_renderer = TgRenderer { raw: 0 };
        if desc.width == 0 || desc.height == 0 || desc.frames_in_flight == 0 {
            return Err(Failure::invalid(format!(
                "width {}, height {} and frames_in_flight {} must all be non-zero",
                desc.width, desc.height, desc.frames_in_flight
            )));
        }
        let most = tilegraph_vk::frames::MAX_FRAMES_IN_FLIGHT;
        if desc.frames_in_flight as usize > most {
            return Err(Failure::invalid(format!(
                "frames_in_flight {} is more than {most}",
                desc.frames_in_flight
            )));
        }
        // The renderer's own camera is a view like any other, with the scene-wide choices.
        let options = RenderOptions {
            instance_capacity: desc.instance_capacity,
            ..view_options(&TgViewDesc {
                technique: desc.technique,
                culling: desc.culling,
                width: desc.width,
                height: desc.height,
                clear_color: desc.clear_color,
                visbuf_resolve: desc.visbuf_resolve,
                shadow_cascades: desc.shadow_cascades,
                shadow_resolution: desc.shadow_resolution,
                shadow_culling: desc.shadow_culling,
                pvs: desc.pvs,
                pvs_dilation: desc.pvs_dilation,
                lod_error_px: desc.lod_error_px,
                lod_hysteresis: desc.lod_hysteresis,
            })?
        };
        let renderer = registry::with2(
            (context.raw, Kind::Context, "context"),
            (scene.raw, Kind::Scene, "scene"),
            |c: &ContextObject, s: &Scene| {
                Ok(SceneRenderer::for_engine(
                    &c.ctx,
                    s,
                    options,
                    desc.frames_in_flight as usize,
                )?)
            },
        )?;
        let object = RendererObject {
            renderer,
            context: context.raw,
            scene: scene.raw,
            aspect: desc.width as f32 / desc.height as f32,
            previous: None,
            frames: 0,
            last: None,
            names: Vec::new(),
        };
        let uses = [
            (context.raw, Kind::Context, "context"),
            (scene.raw, Kind::Scene, "scene"),
        ];
        *out_renderer = TgRenderer {
            raw: registry::insert_using(Kind::Renderer, object, &uses)?,
        };
        Ok(())
    })
}

/// Records one frame seen by `camera` into the engine's command buffer and target; `cut`
/// non-zero: the camera jumped (nothing of the last frame's view applies). Nothing is
/// submitted: the engine submits `frame->command_buffer` on the context's queue after the
/// frames it recorded before, and waits for it before handing `frame->slot` again. After a
/// failure the command buffer holds part of a frame: reset it, do not submit it.
///
/// # Safety
/// `camera`, `frame` and `target` are valid; the command buffer is recording, the image and
/// view are live and stay so until the frame completes.
#[no_mangle]
pub unsafe extern "C" fn tg_renderer_record(
    renderer: TgRenderer,
    camera: *const TgCamera,
    cut: u32,
    frame: *const TgEngineFrame,
    target: *const TgTarget,
) -> TgStatus {
    boundary("tg_renderer_record", || {
        // SAFETY: the caller's contract.
        let (camera, frame, target) = unsafe {
            (
                arg(camera, "camera")?,
                arg(frame, "frame")?,
                arg(target, "target")?,
            )
        };
        if frame.command_buffer.is_null() {
            return Err(Failure::new(
                TgStatus::NullPointer,
                "`frame->command_buffer` is null",
            ));
        }
        if target.image == 0 || target.view == 0 {
            return Err(Failure::new(
                TgStatus::NullPointer,
                "`target->image` or `target->view` is VK_NULL_HANDLE",
            ));
        }
        let camera = camera.to_camera()?;
        let handle = ImageHandle {
            raw: vk::Image::from_raw(target.image),
            view: vk::ImageView::from_raw(target.view),
            full_view: vk::ImageView::from_raw(target.view),
            mip_views: Vec::new(),
            format: vk::Format::from_raw(target.format),
            extent: vk::Extent2D {
                width: target.width,
                height: target.height,
            },
            mip_levels: 1,
            aspect: vk::ImageAspectFlags::COLOR,
        };
        let engine_target = EngineTarget {
            image: &handle,
            initial: state(&target.initial, "target->initial")?,
            final_state: state(&target.final_state, "target->final_state")?,
        };
        let engine_frame = EngineFrame {
            command_buffer: vk::CommandBuffer::from_raw(frame.command_buffer as u64),
            slot: frame.slot as usize,
        };
        let mut r = registry::take::<RendererObject>(renderer.raw, Kind::Renderer, "renderer")?;
        let result = registry::with2(
            (r.context, Kind::Context, "context"),
            (r.scene, Kind::Scene, "scene"),
            |c: &ContextObject, s: &Scene| {
                let previous = if cut != 0 { None } else { r.previous.as_ref() };
                let camera_frame = CameraFrame::new(r.frames, camera, previous, r.aspect);
                let report =
                    r.renderer
                        .record(&c.ctx, s, &camera_frame, engine_frame, &engine_target)?;
                Ok(report)
            },
        );
        if let Ok(report) = &result {
            r.previous = Some(camera);
            r.frames += 1;
            r.last = Some(report.clone());
        }
        registry::put_back(renderer.raw, Kind::Renderer, r);
        result.map(drop)
    })
}

/// The last recorded frame's statistics, and the newest GPU times (which arrive frames in
/// flight later, read without waiting).
///
/// # Safety
/// `out_stats` is writable.
#[no_mangle]
pub unsafe extern "C" fn tg_renderer_stats(
    renderer: TgRenderer,
    out_stats: *mut TgFrameStats,
) -> TgStatus {
    boundary("tg_renderer_stats", || {
        // SAFETY: the caller's contract.
        let out_stats = unsafe { out(out_stats, "out_stats") }?;
        registry::with(
            renderer.raw,
            Kind::Renderer,
            "renderer",
            |r: &RendererObject| {
                let mut s = TgFrameStats::default();
                if let Some(report) = &r.last {
                    let st = &report.stats;
                    s.frame = st.frame;
                    s.render_passes = st.render_passes;
                    s.subpasses = st.subpasses;
                    s.barriers = st.barriers;
                    s.flushes_left_to_engine = st.flushes_left_to_engine;
                    s.rebuilt = u32::from(st.rebuilt);
                    s.device_allocations = st.allocations;
                    s.draws = report.draws as u32;
                    s.triangles = report.triangles;
                    if let Some(c) = report.gpu_culling {
                        s.gpu_counted = 1;
                        s.gpu_counted_frame = c.frame;
                        s.gpu_commands = c.commands;
                        s.gpu_drawn = c.instances;
                        s.gpu_culled = c.culled;
                    }
                }
                if let Some(t) = r.renderer.executor().latest_timings() {
                    s.timed_frame = t.frame;
                    s.timed_pass_count = t.passes.len() as u32;
                    s.timed_gpu_ms = t.passes.iter().map(|p| p.gpu_ms).sum();
                }
                *out_stats = s;
                Ok(())
            },
        )
    })
}

/// Pass `index` (below `TgFrameStats::timed_pass_count`) of the newest timed frame.
///
/// # Safety
/// `out_time` is writable.
#[no_mangle]
pub unsafe extern "C" fn tg_renderer_pass_time(
    renderer: TgRenderer,
    index: u32,
    out_time: *mut TgPassTime,
) -> TgStatus {
    boundary("tg_renderer_pass_time", || {
        // SAFETY: the caller's contract.
        let out_time = unsafe { out(out_time, "out_time") }?;
        let mut r = registry::take::<RendererObject>(renderer.raw, Kind::Renderer, "renderer")?;
        let result = pass_time(&mut r, index as usize);
        registry::put_back(renderer.raw, Kind::Renderer, r);
        *out_time = result?;
        Ok(())
    })
}

fn pass_time(r: &mut RendererObject, index: usize) -> Result<TgPassTime, Failure> {
    let timings = r.renderer.executor().latest_timings();
    let pass = timings.and_then(|t| t.passes.get(index)).ok_or_else(|| {
        Failure::invalid(format!(
            "pass {index} is past the {} passes of the newest timed frame",
            timings.map_or(0, |t| t.passes.len())
        ))
    })?;
    if r.names.len() <= index {
        r.names.resize(index + 1, CString::default());
    }
    if r.names[index].as_bytes() != pass.name.as_bytes() {
        r.names[index] = CString::new(pass.name.replace('\0', " ")).unwrap_or_default();
    }
    Ok(TgPassTime {
        name: r.names[index].as_ptr(),
        gpu_ms: pass.gpu_ms,
        has_statistics: u32::from(pass.vertex_invocations.is_some()),
        vertex_invocations: pass.vertex_invocations.unwrap_or(0),
        fragment_invocations: pass.fragment_invocations.unwrap_or(0),
    })
}

/// What the GPU queries of a renderer's frames measure (`tg_renderer_set_gpu_timing`).
#[repr(u32)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TgGpuTiming {
    /// No queries: `TgFrameStats::timed_pass_count` stays 0.
    Off = 0,
    /// Two timestamps around the frame: one timing, named "frame" — the GPU frame time
    /// (clears, stores and barriers between passes included), for a shipped game's HUD.
    Frame = 1,
    /// A timestamp pair around each pass.
    Passes = 2,
    /// Timestamps and shader-invocation counts around each pass (the default; profiling).
    PassStatistics = 3,
}

fn gpu_timing(raw: u32) -> Result<GpuTiming, Failure> {
    Ok(match raw {
        0 => GpuTiming::Off,
        1 => GpuTiming::Frame,
        2 => GpuTiming::Passes,
        3 => GpuTiming::PassStatistics,
        _ => {
            return Err(Failure::invalid(format!(
                "gpu timing {raw} is no TgGpuTiming"
            )))
        }
    })
}

/// Points the renderer's directional light along `to_light` (three floats: the direction
/// towards the light, any length but zero), and gives it `color` (three floats, linear RGB;
/// NULL keeps it), from the next frame recorded. Shading and shadows follow.
///
/// # Safety
/// `to_light` points to three floats; `color` is NULL or points to three floats.
#[no_mangle]
pub unsafe extern "C" fn tg_renderer_set_light(
    renderer: TgRenderer,
    to_light: *const f32,
    color: *const f32,
) -> TgStatus {
    boundary("tg_renderer_set_light", || {
        // SAFETY: the caller's contract (three floats).
        let dir = unsafe { arg(to_light.cast::<[f32; 3]>(), "to_light") }?;
        let dir = glam::Vec3::from_array(*dir);
        if !dir.is_finite() || dir.length_squared() == 0.0 {
            return Err(Failure::invalid(format!(
                "`to_light` {dir:?} must be finite and not zero"
            )));
        }
        let color = if color.is_null() {
            None
        } else {
            // SAFETY: as above, where not NULL.
            let c = glam::Vec3::from_array(*unsafe { arg(color.cast::<[f32; 3]>(), "color") }?);
            if !c.is_finite() || c.min_element() < 0.0 {
                return Err(Failure::invalid(format!(
                    "`color` {c:?} must be finite and not negative"
                )));
            }
            Some(c)
        };
        registry::with_mut(
            renderer.raw,
            Kind::Renderer,
            "renderer",
            |r: &mut RendererObject| {
                r.renderer.set_light_direction(dir.normalize());
                if let Some(c) = color {
                    r.renderer.set_light_color(c);
                }
                Ok(())
            },
        )
    })
}

/// Sets what the GPU queries of the renderer's next frames measure (a `TgGpuTiming`). A
/// change waits for the device (as `tg_renderer_destroy`: the engine's queue is idle
/// meanwhile) and forgets the times so far; the same timing again does nothing. Call it after
/// submitting every frame recorded: one recorded and not yet submitted is never timed.
#[no_mangle]
pub extern "C" fn tg_renderer_set_gpu_timing(renderer: TgRenderer, timing: u32) -> TgStatus {
    boundary("tg_renderer_set_gpu_timing", || {
        let timing = gpu_timing(timing)?;
        let mut r = registry::take::<RendererObject>(renderer.raw, Kind::Renderer, "renderer")?;
        let result = registry::with(r.context, Kind::Context, "context", |c: &ContextObject| {
            Ok(r.renderer.set_gpu_timing(&c.ctx, timing)?)
        });
        registry::put_back(renderer.raw, Kind::Renderer, r);
        result
    })
}

/// Destroys a renderer: waits for the device (the engine's queue is idle meanwhile), then
/// frees what it made. A zero handle is a no-op.
#[no_mangle]
pub extern "C" fn tg_renderer_destroy(renderer: TgRenderer) -> TgStatus {
    boundary("tg_renderer_destroy", || {
        if renderer.raw == 0 {
            return Ok(());
        }
        let Some(r) = registry::remove::<RendererObject>(renderer.raw, Kind::Renderer, "renderer")?
        else {
            return Ok(());
        };
        let RendererObject {
            renderer, context, ..
        } = *r;
        // The context outlives its renderers (the registry refuses to destroy it before).
        registry::with(context, Kind::Context, "context", |c: &ContextObject| {
            renderer.destroy(&c.ctx);
            Ok(())
        })
    })
}
