//! The activity's loop: a window brings up the device, the swapchain and the renderer; every
//! frame records the scene's next camera into the sample's command buffer and presents it; a
//! touch switches the culling; once a second a line of statistics goes to the log.

use std::time::{Duration, Instant};

use android_activity::input::{InputEvent, MotionAction};
use android_activity::{AndroidApp, InputStatus, MainEvent, PollEvent};
use tilegraph_passes::cull::Culling;
use tilegraph_passes::{GpuTiming, RenderError, RenderOptions, SceneRenderer};
use tilegraph_scene::Scene;
use tilegraph_vk::executor::EngineFrame;
use tilegraph_vk::Context;

use crate::report::{next_culling, stats_line};
use crate::vulkan::{system_property, Device, Swapchain, FRAMES_IN_FLIGHT};

/// What runs while the activity has a window.
struct Running {
    device: Device,
    ctx: Context,
    swapchain: Swapchain,
    renderer: SceneRenderer,
    frame: usize,
    since_log: Instant,
    frames_since_log: u32,
}

impl Running {
    fn start(app: &AndroidApp, scene: &Scene, culling: Culling) -> Result<Running, RenderError> {
        let window = app
            .native_window()
            .ok_or_else(|| RenderError::Target("the activity has no window yet".into()))?;
        let profile = system_property(c"debug.tilegraph.profile");
        // SAFETY: the window is the activity's, alive until TerminateWindow (which stops this).
        let (device, ctx) = unsafe { Device::new(window.ptr().as_ptr().cast(), profile) }?;
        log::info!(
            "profile {} ({}) on {:?}",
            ctx.profile().name,
            ctx.selection.matched_by,
            ctx.physical.identity.device_name
        );
        let swapchain = match Swapchain::new(&device) {
            Ok(s) => s,
            Err(e) => {
                drop(ctx);
                device.destroy();
                return Err(e.into());
            }
        };
        let renderer = match renderer(&ctx, scene, &swapchain, culling) {
            Ok(r) => r,
            Err(e) => {
                swapchain.destroy(&device);
                drop(ctx);
                device.destroy();
                return Err(e);
            }
        };
        Ok(Running {
            device,
            ctx,
            swapchain,
            renderer,
            frame: 0,
            since_log: Instant::now(),
            frames_since_log: 0,
        })
    }

    fn stop(self) {
        let Running {
            device,
            ctx,
            swapchain,
            renderer,
            ..
        } = self;
        renderer.destroy(&ctx);
        swapchain.destroy(&device);
        drop(ctx);
        device.destroy();
    }

    /// A new renderer (another culling, or a new swapchain size).
    fn replace_renderer(&mut self, scene: &Scene, culling: Culling) -> Result<(), RenderError> {
        let fresh = renderer(&self.ctx, scene, &self.swapchain, culling)?;
        let old = std::mem::replace(&mut self.renderer, fresh);
        old.destroy(&self.ctx);
        Ok(())
    }

    fn draw(&mut self, scene: &Scene, culling: Culling) -> Result<(), RenderError> {
        let Some(frame) = self.swapchain.begin(&self.device)? else {
            // Out of date (rotation, resize): a new swapchain and a renderer of its size.
            self.ctx.wait_idle()?;
            let old = std::mem::replace(&mut self.swapchain, Swapchain::new(&self.device)?);
            old.destroy(&self.device);
            return self.replace_renderer(scene, culling);
        };
        let path = scene.camera_path();
        let extent = self.swapchain.extent;
        let aspect = extent.width as f32 / extent.height.max(1) as f32;
        let camera = path.frame(self.frame % path.len().max(1), aspect);
        let recorded = match (camera, self.swapchain.target(&frame)) {
            (Some(camera), Some(target)) => {
                let engine = EngineFrame {
                    command_buffer: frame.cb,
                    slot: frame.slot,
                };
                self.renderer
                    .record(&self.ctx, scene, &camera, engine, &target)
                    .map(Some)
            }
            _ => Ok(None),
        };
        match recorded {
            Ok(Some(report)) => {
                self.swapchain.submit(&self.device, frame)?;
                self.frame += 1;
                self.frames_since_log += 1;
                let culled = report.gpu_culling.map(|c| c.culled);
                self.log_once_a_second(culling, report.draws, culled);
                Ok(())
            }
            Ok(None) => Ok(self.swapchain.submit_blank(&self.device, frame)?),
            Err(e) if e.is_out_of_memory() => {
                // The frame failed cleanly: show nothing new, try the next one.
                log::warn!("frame {}: {e}", self.frame);
                Ok(self.swapchain.submit_blank(&self.device, frame)?)
            }
            Err(e) => {
                self.swapchain.submit_blank(&self.device, frame)?;
                Err(e)
            }
        }
    }

    fn log_once_a_second(&mut self, culling: Culling, draws: usize, gpu_culled: Option<u32>) {
        let elapsed = self.since_log.elapsed();
        if elapsed < Duration::from_secs(1) {
            return;
        }
        let fps = f64::from(self.frames_since_log) / elapsed.as_secs_f64();
        let timings = self.renderer.executor().latest_timings();
        log::info!("{}", stats_line(culling, fps, draws, gpu_culled, timings));
        self.since_log = Instant::now();
        self.frames_since_log = 0;
    }
}

fn renderer(
    ctx: &Context,
    scene: &Scene,
    swapchain: &Swapchain,
    culling: Culling,
) -> Result<SceneRenderer, RenderError> {
    let options = RenderOptions {
        culling,
        width: swapchain.extent.width,
        height: swapchain.extent.height,
        // The log line shows each pass's time, not its shader invocations: no statistics
        // queries.
        gpu_timing: GpuTiming::Passes,
        ..RenderOptions::default()
    };
    SceneRenderer::for_engine(ctx, scene, options, FRAMES_IN_FLIGHT)
}

/// Whether the device was created with everything `culling` needs.
fn available(ctx: &Context, culling: Culling) -> bool {
    let options = RenderOptions {
        culling,
        ..RenderOptions::default()
    };
    options.needs().iter().all(|(f, _)| ctx.has_feature(*f))
}

/// The activity's main loop (NativeActivity calls `android_main` on its own thread).
pub fn run(app: AndroidApp) {
    android_logger::init_once(
        android_logger::Config::default()
            .with_max_level(log::LevelFilter::Info)
            .with_tag("tilegraph"),
    );
    let spec = system_property(c"debug.tilegraph.scene").unwrap_or_else(|| "city:20000".into());
    let scene = match tilegraph_scene::load(&spec) {
        Ok(s) => s,
        Err(e) => {
            log::error!("scene {spec}: {e}");
            return;
        }
    };
    log::info!("scene {spec}: {} instances", scene.instances().len());
    let mut culling = Culling::HizTwoPhase;
    let mut running: Option<Running> = None;
    let mut quit = false;
    while !quit {
        let mut window_up = false;
        let mut window_down = false;
        let timeout = running.as_ref().map(|_| Duration::ZERO);
        app.poll_events(timeout, |event| match event {
            PollEvent::Main(MainEvent::InitWindow { .. }) => window_up = true,
            PollEvent::Main(MainEvent::TerminateWindow { .. }) => window_down = true,
            PollEvent::Main(MainEvent::Destroy) => quit = true,
            _ => {}
        });
        if window_down || quit {
            if let Some(r) = running.take() {
                r.stop();
            }
        }
        if window_up && running.is_none() {
            match Running::start(&app, &scene, culling) {
                Ok(r) => running = Some(r),
                Err(e) => log::error!("starting the renderer: {e}"),
            }
        }
        let mut touched = false;
        if let Ok(mut events) = app.input_events_iter() {
            while events.next(|event| {
                if let InputEvent::MotionEvent(m) = event {
                    touched |= m.action() == MotionAction::Up;
                }
                InputStatus::Unhandled
            }) {}
        }
        let Some(r) = running.as_mut() else {
            continue;
        };
        if touched {
            let next = next_culling(culling, |c| available(&r.ctx, c));
            match r.replace_renderer(&scene, next) {
                Ok(()) => {
                    culling = next;
                    log::info!("culling: {}", culling.name());
                }
                Err(e) => log::error!("switching to {}: {e}", next.name()),
            }
        }
        if let Err(e) = r.draw(&scene, culling) {
            log::error!("frame: {e}");
            if e.is_device_lost() {
                if let Some(r) = running.take() {
                    r.stop();
                }
                quit = true;
            }
        }
    }
}
