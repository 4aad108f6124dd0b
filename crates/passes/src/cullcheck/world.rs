//! The scene a check renders (still or moving), the warm-up before its timed passes, and
//! `auto`'s trial.

use tilegraph_scene::{CameraPath, Motion, MotionParams, Scene};
use tilegraph_vk::Context;

use crate::knobs::AutoTrial;
use crate::options::{RenderError, RenderOptions};
use crate::renderer::SceneRenderer;

/// The scene a check renders: as given, or moving — a copy its [`Motion`] brings to each frame.
pub(super) enum World<'a> {
    Still(&'a Scene),
    Moving { scene: Box<Scene>, motion: Motion },
}

impl<'a> World<'a> {
    pub(super) fn new(scene: &'a Scene, path: &CameraPath, motion: Option<MotionParams>) -> Self {
        match motion {
            None => World::Still(scene),
            Some(params) => World::Moving {
                scene: Box::new(scene.clone()),
                motion: Motion::new(scene, path, params),
            },
        }
    }

    /// The scene as it stands.
    pub(super) fn scene(&self) -> &Scene {
        match self {
            World::Still(s) => s,
            World::Moving { scene, .. } => scene,
        }
    }

    /// The scene at frame `index` of the path.
    pub(super) fn at(&mut self, index: usize) -> Result<&Scene, RenderError> {
        match self {
            World::Still(s) => Ok(s),
            World::Moving { scene, motion } => {
                motion.apply(scene, index)?;
                Ok(scene)
            }
        }
    }
}

/// What the warm-up and the trial render: the path's first `count` frames, again and again.
pub(super) struct Timing<'a> {
    pub(super) path: &'a CameraPath,
    pub(super) count: usize,
    pub(super) aspect: f32,
    pub(super) warmup: std::time::Duration,
}

impl Timing<'_> {
    /// Renders with `renderer` for [`CheckExtras::timing_warmup`].
    pub(super) fn warm_up(
        &self,
        ctx: &Context,
        world: &mut World<'_>,
        renderer: &mut SceneRenderer,
    ) -> Result<(), RenderError> {
        let warm_until = std::time::Instant::now() + self.warmup;
        let mut index = 0;
        while self.count > 0 && std::time::Instant::now() < warm_until {
            let Some(frame) = self.path.frame(index % self.count, self.aspect) else {
                break;
            };
            renderer.render_frame(ctx, world.at(index % self.count)?, &frame)?;
            index += 1;
        }
        Ok(())
    }
}

/// `auto`'s trial, as an engine runs it: a renderer of its own rendering frames back to back
/// along the path (from its start again where the path is shorter than the trial), after the
/// warm-up. Returns `options` with the culling it kept and what it timed. Its renderer is gone
/// before the check makes the one it checks and times, which is then made like any other
/// check's: a renderer made while another still held its memory timed every pass 3–17 %
/// slower on an H100 than one of the same options made fresh.
pub(super) fn run_trial(
    ctx: &Context,
    timing: &Timing<'_>,
    world: &mut World<'_>,
    mut options: RenderOptions,
    mut trial: AutoTrial,
) -> Result<(RenderOptions, String), RenderError> {
    options.culling = trial.current();
    let mut renderer = SceneRenderer::new(ctx, world.scene(), options.clone())?;
    if let Err(e) = timing.warm_up(ctx, world, &mut renderer) {
        renderer.destroy(ctx);
        return Err(e);
    }
    for index in 0..=trial.frames() {
        let Some(frame) = timing
            .path
            .frame(index % timing.count.max(1), timing.aspect)
        else {
            break;
        };
        let scene = match world.at(index % timing.count.max(1)) {
            Ok(s) => s,
            Err(e) => {
                renderer.destroy(ctx);
                return Err(e);
            }
        };
        if let Err(e) = renderer.render_frame(ctx, scene, &frame) {
            renderer.destroy(ctx);
            return Err(e);
        }
        // On an error the trial has destroyed the renderer.
        let (next, decided) = trial.after_render(ctx, scene, renderer, &mut options)?;
        renderer = next;
        if let Some(why) = decided {
            renderer.destroy(ctx);
            return Ok((options, why));
        }
    }
    renderer.destroy(ctx);
    Ok((
        options,
        format!(
            "auto: the trial did not finish in {} frames; ran {}",
            trial.frames() + 1,
            trial.current().name()
        ),
    ))
}
