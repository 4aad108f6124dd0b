//! What the knobs (`tilegraph_profile::knobs`) mean for a renderer: a run's settings over the
//! profile's over the built-in defaults, checked against the scene and the culling they are for,
//! turned into [`RenderOptions`]; and `culling = auto`, which picks the culling from what the
//! scene holds and says why.

use std::fmt;

use serde::Serialize;
use tilegraph_cull::NpotMode;
use tilegraph_profile::knobs::{
    spec, Applies, KnobError, KnobSettings, KnobSpec, KnobValue, KNOBS,
};
use tilegraph_profile::{Profile, SortOrder};
use tilegraph_scene::Scene;

use tilegraph_vk::queries::{GpuTiming, FRAME_TIMING};
use tilegraph_vk::Context;

use crate::cull::{ClusterEarly, CullBounds, Culling};
use crate::options::{RenderError, RenderOptions};
use crate::renderer::SceneRenderer;
use crate::setup::{SceneContent, Technique, VisbufResolve};

/// Below this many instances `auto` draws everything: culling has a fixed cost (six dispatches
/// and a pyramid, 0.1 ms on the H100 at 1080p) that a small level's whole frame does not reach
/// (60 instances, 30 k triangles: 0.026 ms unculled, 0.13 ms with two-phase HiZ on the H100).
pub const AUTO_MIN_INSTANCES: usize = 256;

/// From this many triangles per opaque instance `auto` prefers same-frame occlusion queries
/// (where the device has conditional rendering): a box per instance costs less than the
/// triangles of instances whose box passes a HiZ test (Godot rooms, 3,748 triangles per
/// instance: 6.45 ms against two-phase HiZ's 19.4 ms on the H100, docs/ACCURACY.md).
pub const AUTO_QUERY_TRIANGLES_PER_INSTANCE: u64 = 1000;

/// `auto` also tries the cluster techniques where instances hold at least this many triangles
/// on average — a level baked into a few meshes, where instance culling can only draw all or
/// nothing of each: on the H100 at 1080p `frustum-clusters` draws `interior:3000@one-mesh`'s
/// walk in 0.82 ms against 1.01 unculled (docs/ACCURACY.md, the one-mesh levels). The scene then
/// needs its clusters ([`auto_wants_clusters`]).
pub const AUTO_CLUSTER_TRIANGLES_PER_INSTANCE: u64 = 8192;

/// Frames each candidate of `auto`'s trial runs before it is timed (two-phase culling's first
/// frame starts from an empty visibility and draws everything in the frustum).
pub const AUTO_WARMUP_FRAMES: usize = 2;
/// Frames each candidate is timed over (the median of their GPU frame times counts). Eight:
/// with three, lavapipe's run-to-run noise (10-20 % on millisecond frames) picked a candidate
/// 15 % slower than the best in one of three runs; the whole trial is still under a second at
/// 60 frames per second.
pub const AUTO_TIMED_FRAMES: usize = 8;

/// `auto`'s trial: what the scene holds gives a first pick ([`auto_culling`]), but what pays
/// depends on the device as much as on the scene (the FlightHelmet at 320x180 on lavapipe is
/// fastest frustum-culled, at 1080p on an H200 unculled; a single Godot room on both with
/// same-frame queries). So `auto` times every conservative candidate the device can run on the
/// first frames — the first pick, then none, frustum, two-phase HiZ, same-frame queries, on a
/// scene with its clusters attached the two cluster techniques, and software occlusion (its
/// GPU frame plus its CPU time) — and keeps the fastest. Every candidate is conservative: no frame of the trial loses an
/// instance.
#[derive(Debug, Clone, PartialEq)]
pub struct AutoTrial {
    candidates: Vec<Culling>,
    current: usize,
    frames: usize,
    /// (candidate, median GPU frame ms).
    timed: Vec<(Culling, f64)>,
}

/// What the caller does after a frame of the trial.
#[derive(Debug, Clone, PartialEq)]
pub enum TrialStep {
    /// Render the next frame with the same candidate.
    Continue,
    /// The candidate is warm: forget its timings so far (`finish`, `clear_timings`).
    StartTiming,
    /// The candidate's timed frames are done: give [`AutoTrial::record`] their median frame ms.
    Measure,
}

impl AutoTrial {
    /// The trial of `first` and the other candidates that run with `technique` on a device
    /// with `inputs`.
    pub fn new(first: Culling, inputs: AutoInputs, technique: Technique) -> AutoTrial {
        let mut candidates = vec![first];
        for c in [
            Culling::None,
            Culling::Frustum,
            Culling::HizTwoPhase,
            Culling::OqConditional,
            Culling::FrustumClusters,
            Culling::HizTwoPhaseClusters,
            Culling::SoftwareOcclusion,
            Culling::Pvs,
        ] {
            if candidates.contains(&c)
                || (c == Culling::Pvs && !inputs.pvs)
                || (c == Culling::OqConditional && !inputs.conditional_rendering)
                || (c.clusters() && !inputs.clusters)
                || c.unsupported_with(technique).is_some()
            {
                continue;
            }
            candidates.push(c);
        }
        AutoTrial {
            candidates,
            current: 0,
            frames: 0,
            timed: Vec::new(),
        }
    }

    /// The candidate to render with now.
    pub fn current(&self) -> Culling {
        self.candidates
            .get(self.current)
            .copied()
            .unwrap_or(Culling::None)
    }

    /// Frames the whole trial takes.
    pub fn frames(&self) -> usize {
        self.candidates.len() * (AUTO_WARMUP_FRAMES + AUTO_TIMED_FRAMES)
    }

    /// After a frame rendered with [`Self::current`].
    pub fn after_frame(&mut self) -> TrialStep {
        self.frames += 1;
        if self.frames == AUTO_WARMUP_FRAMES {
            TrialStep::StartTiming
        } else if self.frames == AUTO_WARMUP_FRAMES + AUTO_TIMED_FRAMES {
            TrialStep::Measure
        } else {
            TrialStep::Continue
        }
    }

    /// Call after `renderer` rendered a frame with [`Self::current`] (`options` made it): times
    /// the candidate, and after its last timed frame replaces `renderer` with one of the next
    /// candidate (`options.culling` follows). Returns the renderer to go on with and, when the
    /// trial ends, the decision with what was timed; the renderer then renders with the fastest.
    ///
    /// The old renderer is destroyed before the next one is made: one made while another still
    /// held its memory ran every pass 3–17 % slower on an H100 (docs/ACCURACY.md). On an error
    /// the renderer is destroyed too; there is none to go on with.
    pub fn after_render(
        &mut self,
        ctx: &Context,
        scene: &Scene,
        mut renderer: SceneRenderer,
        options: &mut RenderOptions,
    ) -> Result<(SceneRenderer, Option<String>), RenderError> {
        let step = self.after_frame();
        if step == TrialStep::Continue {
            return Ok((renderer, None));
        }
        if let Err(e) = renderer.finish(ctx) {
            renderer.destroy(ctx);
            return Err(e);
        }
        // The candidates are timed as whole frames (two timestamps, no per-pass queries):
        // clears, stores and barriers between passes count, per-pass queries do not. The
        // renderer goes back to the engine's timing once its time is read.
        if step == TrialStep::StartTiming {
            if let Err(e) = renderer.set_gpu_timing(ctx, GpuTiming::Frame) {
                renderer.destroy(ctx);
                return Err(e);
            }
            renderer.clear_timings();
            return Ok((renderer, None));
        }
        // A CPU technique's frame costs its CPU work too: software occlusion is timed as its
        // GPU frame plus its own CPU milliseconds (as if they ran one after the other: the
        // render thread's time is what it takes from the frame when the CPU bounds it).
        let cpu_ms = renderer.software_cpu_ms().unwrap_or(0.0);
        let ms = match renderer.medians().iter().find(|m| m.name == FRAME_TIMING) {
            Some(m) => m.median_gpu_ms + cpu_ms,
            None => {
                log::warn!(
                    "auto: no GPU frame time arrived for {}; it is not kept",
                    self.current().name()
                );
                f64::INFINITY
            }
        };
        if let Err(e) = renderer.set_gpu_timing(ctx, options.gpu_timing) {
            renderer.destroy(ctx);
            return Err(e);
        }
        let (next, decided) = match self.record(ms) {
            Ok(next) => (next, None),
            Err((best, why)) => (best, Some(why)),
        };
        if next == options.culling {
            return Ok((renderer, decided));
        }
        options.culling = next;
        renderer.destroy(ctx);
        let fresh = SceneRenderer::new(ctx, scene, options.clone())?;
        Ok((fresh, decided))
    }

    /// The current candidate's median GPU frame time. Returns the culling to render with
    /// next: the next candidate, or — when every candidate is timed — the fastest, with the
    /// reason (`Err` carries the decision).
    pub fn record(&mut self, frame_ms: f64) -> Result<Culling, (Culling, String)> {
        self.timed.push((self.current(), frame_ms));
        self.current += 1;
        self.frames = 0;
        if self.current < self.candidates.len() {
            return Ok(self.current());
        }
        let (best, best_ms) = self
            .timed
            .iter()
            .copied()
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .unwrap_or((Culling::None, 0.0));
        if !best_ms.is_finite() {
            // No candidate's GPU frame time arrived: nothing to compare.
            let first = self.candidates.first().copied().unwrap_or(Culling::None);
            return Err((
                first,
                format!(
                    "auto could not time the candidates on this device (no GPU frame time arrived): {} kept",
                    first.name()
                ),
            ));
        }
        let tried: Vec<String> = self
            .timed
            .iter()
            .map(|(c, ms)| format!("{} {ms:.3} ms", c.name()))
            .collect();
        Err((
            best,
            format!(
                "auto timed on this device over {AUTO_TIMED_FRAMES} frames each: {} — {} is fastest ({best_ms:.3} ms)",
                tried.join(", "),
                best.name()
            ),
        ))
    }
}

/// Where a knob's value came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Origin {
    /// The built-in default ([`tilegraph_profile::knobs::KNOBS`]).
    Default,
    /// The profile's `[knobs]` table.
    Profile,
    /// This run (`--set`, `--culling`, `--shading`).
    Run,
}

impl fmt::Display for Origin {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Origin::Default => "default",
            Origin::Profile => "profile",
            Origin::Run => "this run",
        })
    }
}

/// One knob as a run uses it.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct KnobChoice {
    pub name: &'static str,
    pub value: KnobValue,
    pub origin: Origin,
}

/// A run's knob settings that cannot apply.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum KnobUseError {
    #[error(transparent)]
    Knob(#[from] KnobError),
    #[error("knob {name}: {why}")]
    NotForScene { name: &'static str, why: String },
    #[error("knob {name} applies to culling {applies_to}, and this run culls with {culling}")]
    IgnoredByCulling {
        name: &'static str,
        applies_to: String,
        culling: &'static str,
    },
}

/// What the device and the scene offer that `auto` chooses between.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct AutoInputs {
    /// `VK_EXT_conditional_rendering` (same-frame occlusion queries).
    pub conditional_rendering: bool,
    /// The scene has its clusters attached: the cluster techniques can be tried.
    pub clusters: bool,
    /// The profile prefers software occlusion on the CPU (`[passes] cpu_occlusion = "prefer"`:
    /// its family builds depth pyramids slowly): `auto` starts from it.
    pub prefer_cpu_occlusion: bool,
    /// A precomputed visible set baked for the scene is given and the profile lets `auto` pick
    /// one (`[passes] auto_pvs = "allow"`): it is timed with the other candidates.
    pub pvs: bool,
}

/// Whether `auto` would try cluster culling on `scene` if it had its clusters: its opaque and
/// alpha-tested instances hold at least [`AUTO_CLUSTER_TRIANGLES_PER_INSTANCE`] triangles on
/// average (a caller attaches them, then says so in [`AutoInputs::clusters`]).
pub fn auto_wants_clusters(scene: &Scene) -> bool {
    let content = SceneContent::of(scene);
    let drawn = (content.opaque + content.alpha_tested) as u64;
    let triangles: u64 = scene
        .instances()
        .iter()
        .filter(|i| i.flags.is_drawn())
        .filter_map(|i| scene.mesh(i.mesh))
        .map(|m| u64::from(m.triangle_count()))
        .sum();
    drawn > 0 && triangles / drawn >= AUTO_CLUSTER_TRIANGLES_PER_INSTANCE
}

/// The knobs of one run, resolved.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Resolved {
    #[serde(skip)]
    pub culling: Culling,
    #[serde(skip)]
    pub technique: Technique,
    /// Why `auto` chose [`Self::culling`] (`None` when a value was given).
    pub auto_reason: Option<String>,
    /// Every knob offered to this scene, with its value and origin.
    pub knobs: Vec<KnobChoice>,
}

impl Resolved {
    /// `auto`'s trial, when `culling = auto` chose [`Self::culling`] (`None` when the culling
    /// was given).
    pub fn auto_trial(&self, inputs: AutoInputs) -> Option<AutoTrial> {
        // Per-triangle culling packs the triangles anew: the visibility buffer's ids cannot
        // name them, so cluster culling is no candidate there.
        let triangles = self.get("triangle_culling").and_then(KnobValue::as_name) == Some("on");
        let inputs = AutoInputs {
            clusters: inputs.clusters && !(triangles && self.technique == Technique::Visbuf),
            ..inputs
        };
        self.auto_reason
            .as_ref()
            .map(|_| AutoTrial::new(self.culling, inputs, self.technique))
    }
}

/// The knobs a scene can use: `alpha_prepass` only where there is alpha-tested geometry.
pub fn offered(content: SceneContent) -> impl Iterator<Item = &'static KnobSpec> {
    KNOBS
        .iter()
        .filter(move |k| k.applies != Applies::AlphaTestedScene || content.alpha_tested > 0)
}

/// Picks the culling for a scene (`culling = auto`), with the reason.
pub fn auto_culling(scene: &Scene, inputs: AutoInputs, technique: Technique) -> (Culling, String) {
    let content = SceneContent::of(scene);
    let drawn = content.opaque + content.alpha_tested;
    let triangles: u64 = scene
        .instances()
        .iter()
        .filter_map(|i| scene.mesh(i.mesh))
        .map(|m| u64::from(m.triangle_count()))
        .sum();
    let per_instance = triangles / (scene.instances().len().max(1) as u64);
    if drawn < AUTO_MIN_INSTANCES {
        return (
            Culling::None,
            format!(
                "auto: {drawn} opaque and alpha-tested instances, fewer than {AUTO_MIN_INSTANCES}: culling's fixed cost would exceed what it saves"
            ),
        );
    }
    if inputs.prefer_cpu_occlusion {
        return (
            Culling::SoftwareOcclusion,
            format!(
                "auto: {drawn} instances, and the profile prefers occlusion on the CPU (its family builds depth pyramids slowly: seed 000 measured 10-20 ms on Adreno 505): software occlusion"
            ),
        );
    }
    let queries_run = Culling::OqConditional.unsupported_with(technique).is_none();
    if per_instance >= AUTO_QUERY_TRIANGLES_PER_INSTANCE
        && inputs.conditional_rendering
        && queries_run
    {
        return (
            Culling::OqConditional,
            format!(
                "auto: {drawn} instances of {per_instance} triangles on average (at least {AUTO_QUERY_TRIANGLES_PER_INSTANCE}): a query box per instance costs less than the triangles a HiZ test lets through"
            ),
        );
    }
    (
        Culling::HizTwoPhase,
        format!(
            "auto: {drawn} instances of {per_instance} triangles on average: two-phase HiZ, the cheapest conservative culling{}",
            match (per_instance >= AUTO_QUERY_TRIANGLES_PER_INSTANCE, queries_run) {
                (false, _) => String::new(),
                (true, false) => format!(
                    " (same-frame queries would suit heavy instances, but shading {} has no depth pre-pass for them)",
                    technique.name()
                ),
                (true, true) => {
                    " (same-frame queries would suit heavy instances, but the device lacks conditional rendering)".to_string()
                }
            }
        ),
    )
}

/// Resolves a run's knobs: `run` over `profile.knobs` over the defaults. A knob the run sets
/// that the scene cannot use, or that the chosen culling ignores, is an error; the profile's
/// settings of such knobs are simply not used.
pub fn resolve(
    profile: &Profile,
    run: &KnobSettings,
    scene: &Scene,
    inputs: AutoInputs,
) -> Result<Resolved, KnobUseError> {
    let content = SceneContent::of(scene);
    for (name, _) in run.iter() {
        let Some(k) = spec(name) else { continue };
        if !offered(content).any(|o| o.name == k.name) {
            return Err(KnobUseError::NotForScene {
                name: k.name,
                why: format!("scene {:?} has no alpha-tested geometry", scene.name()),
            });
        }
    }
    let merged = profile.knobs.overridden_by(run);
    let value = |k: &KnobSpec| -> (KnobValue, Origin) {
        match (run.get(k.name), profile.knobs.get(k.name)) {
            (Some(v), _) => (v.clone(), Origin::Run),
            (None, Some(v)) => (v.clone(), Origin::Profile),
            (None, None) => (k.default.into(), Origin::Default),
        }
    };
    let name_of = |knob: &str| -> String {
        merged
            .get(knob)
            .cloned()
            .or_else(|| spec(knob).map(|k| k.default.into()))
            .map(|v| v.to_string())
            .unwrap_or_default()
    };
    let technique = Technique::parse(&name_of("shading")).unwrap_or(Technique::Forward);
    let (culling, auto_reason) = match Culling::parse(&name_of("culling")) {
        Some(c) => (c, None),
        None => {
            let (c, why) = auto_culling(scene, inputs, technique);
            (c, Some(why))
        }
    };
    let mut knobs = Vec::new();
    for k in offered(content) {
        let (v, origin) = value(k);
        if let Applies::WithCulling(techniques) = k.applies {
            let requested = name_of("culling");
            if !techniques.contains(&culling.name()) && !techniques.contains(&requested.as_str()) {
                if origin == Origin::Run {
                    return Err(KnobUseError::IgnoredByCulling {
                        name: k.name,
                        applies_to: techniques.join(", "),
                        culling: culling.name(),
                    });
                }
                continue;
            }
        }
        if let Applies::WithShading(shadings) = k.applies {
            if !shadings.contains(&technique.name()) {
                if origin == Origin::Run {
                    return Err(KnobUseError::NotForScene {
                        name: k.name,
                        why: format!(
                            "it applies to shading {} only, and the run shades {}",
                            shadings.join(", "),
                            technique.name()
                        ),
                    });
                }
                continue;
            }
        }
        if k.name == "depth_prepass" {
            let inert = match technique {
                Technique::Visbuf | Technique::DeferredTexturing => Some(format!(
                    "shading {} has no depth pre-pass",
                    technique.name()
                )),
                Technique::Prepass => Some("shading prepass always draws one".to_string()),
                Technique::Forward if culling.needs_prepass() => Some(format!(
                    "culling {} draws its own depth pre-pass",
                    culling.name()
                )),
                Technique::Forward => None,
            };
            match (inert, origin) {
                (Some(why), Origin::Run) => {
                    return Err(KnobUseError::NotForScene { name: k.name, why })
                }
                (Some(_), _) => continue,
                (None, _) => {}
            }
        }
        if k.name == "alpha_prepass" {
            let inert = if technique.screen_space() {
                Some(format!(
                    "shading {} has no depth pre-pass",
                    technique.name()
                ))
            } else if culling.needs_prepass() {
                Some(format!(
                    "culling {} draws alpha-tested depth in its own pre-pass",
                    culling.name()
                ))
            } else {
                None
            };
            match (inert, origin) {
                (Some(why), Origin::Run) => {
                    return Err(KnobUseError::NotForScene { name: k.name, why })
                }
                (Some(_), _) => continue,
                (None, _) => {}
            }
        }
        knobs.push(KnobChoice {
            name: k.name,
            value: v,
            origin,
        });
    }
    Ok(Resolved {
        culling,
        technique,
        auto_reason,
        knobs,
    })
}

impl Resolved {
    fn get(&self, name: &str) -> Option<&KnobValue> {
        self.knobs.iter().find(|k| k.name == name).map(|k| &k.value)
    }

    /// Writes the resolved knobs into `options` (culling, shading, and every other knob offered).
    pub fn apply(&self, options: &mut RenderOptions) {
        options.culling = self.culling;
        options.technique = self.technique;
        let name = |k: &str| self.get(k).and_then(KnobValue::as_name).unwrap_or("");
        options.opaque_order = match name("opaque_sort") {
            "front-to-back" => Some(SortOrder::FrontToBack),
            "back-to-front" => Some(SortOrder::BackToFront),
            "by-state" => Some(SortOrder::ByState),
            "none" => Some(SortOrder::None),
            _ => None,
        };
        options.depth_prepass = match name("depth_prepass") {
            "on" => Some(true),
            "off" => Some(false),
            _ => None,
        };
        options.alpha_prepass = match name("alpha_prepass") {
            "on" => Some(true),
            "off" => Some(false),
            _ => None,
        };
        if name("depth_format") == "d16" {
            options.depth_format = tilegraph_cull::DepthFormat::D16Unorm;
        }
        if name("hiz_npot") == "pad-to-pow2" {
            options.hiz_mode = NpotMode::PadToPow2;
        }
        options.hiz_base_level = match name("hiz_resolution") {
            "half" => 1,
            "quarter" => 2,
            _ => 0,
        };
        options.cull_bounds = match name("cull_bounds") {
            "sphere" => CullBounds::Sphere,
            _ => CullBounds::Aabb,
        };
        options.cluster_early = ClusterEarly::parse(name("cluster_early")).unwrap_or_default();
        options.triangle_culling = name("triangle_culling") == "on";
        options.lod_error_px = name("lod_error_px").parse().unwrap_or(0.0);
        options.lod_hysteresis = name("lod_hysteresis").parse().unwrap_or(0.2);
        options.visbuf_resolve = VisbufResolve::parse(name("visbuf_resolve"));
        if let Some(t) = self.get("classify_tile").and_then(KnobValue::as_integer) {
            options.classify_tile = Some(t);
        }
        if let Some(g) = self.get("oq_group").and_then(KnobValue::as_integer) {
            options.oq_group = g as usize;
        }
        if let Some(n) = self
            .get("occlusion_recheck")
            .and_then(KnobValue::as_integer)
        {
            options.occlusion_recheck = n;
        }
        if let Some(s) = self
            .get("raster_occlusion_scale")
            .and_then(KnobValue::as_integer)
        {
            options.raster_occlusion_scale = s;
        }
        let integer = |k: &str| self.get(k).and_then(KnobValue::as_integer);
        if let Some(g) = integer("cluster_gap") {
            options.cluster_gap = g;
        }
        if let Some(r) = crate::occlusion::software::parse_resolution(name("software_resolution")) {
            options.software.resolution = r;
        }
        if let Some(n) = integer("software_threads") {
            options.software.threads = n as usize;
        }
        if let Some(n) = integer("software_occluder_triangles") {
            options.software.occluder_triangles = n;
        }
        if let Some(n) = integer("pvs_dilation") {
            options.pvs_dilation = n;
        }
        let shadows = &mut options.shadows;
        if let Some(n) = integer("shadow_cascades") {
            shadows.cascades = n;
        }
        if let Some(r) = integer("shadow_resolution") {
            shadows.resolution = r;
        }
        if let Some(d) = integer("shadow_distance") {
            shadows.distance = d as f32;
        }
        if let Some(p) = integer("shadow_pcf") {
            shadows.pcf = p;
        }
        shadows.format = crate::shadow::parse_format(name("shadow_format"));
        if let Some(c) = tilegraph_cull::shadow::CasterCulling::parse(name("shadow_culling")) {
            shadows.culling = c;
        }
    }

    /// One line per knob: `name = value (origin)`, and `auto`'s reason.
    pub fn describe(&self) -> Vec<String> {
        let mut lines: Vec<String> = self
            .knobs
            .iter()
            .map(|k| format!("{} = {} ({})", k.name, k.value, k.origin))
            .collect();
        if let Some(why) = &self.auto_reason {
            lines.push(format!("culling {}: {why}", self.culling.name()));
        }
        lines
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use tilegraph_profile::knobs::Domain;

    fn profile(name: &str) -> Profile {
        tilegraph_profile::ProfileSet::embedded()
            .unwrap()
            .get(name)
            .unwrap()
            .clone()
    }

    #[test]
    fn every_domain_value_means_something_here() {
        for k in KNOBS {
            for v in k.domain.values() {
                let s = v.to_string();
                let understood = match k.name {
                    "culling" => s == "auto" || Culling::parse(&s).is_some(),
                    "shading" => Technique::parse(&s).is_some(),
                    "opaque_sort" => [
                        "profile",
                        "front-to-back",
                        "back-to-front",
                        "by-state",
                        "none",
                    ]
                    .contains(&s.as_str()),
                    "depth_format" => ["d32", "d16"].contains(&s.as_str()),
                    "alpha_prepass" | "depth_prepass" => {
                        ["profile", "on", "off"].contains(&s.as_str())
                    }
                    "hiz_npot" => ["edge-aware", "pad-to-pow2"].contains(&s.as_str()),
                    "hiz_resolution" => ["full", "half", "quarter"].contains(&s.as_str()),
                    "cull_bounds" => ["aabb", "sphere"].contains(&s.as_str()),
                    "triangle_culling" => ["off", "on"].contains(&s.as_str()),
                    "lod_error_px" => s.parse::<f32>().is_ok_and(|p| p >= 0.0),
                    "lod_hysteresis" => s.parse::<f32>().is_ok_and(|h| (0.0..1.0).contains(&h)),
                    "cluster_early" => ClusterEarly::parse(&s).is_some(),
                    "visbuf_resolve" => VisbufResolve::parse(&s).is_some(),
                    "classify_tile" => matches!(k.domain, Domain::Integers(_)),
                    "shadow_cascades" | "shadow_resolution" | "shadow_distance" | "shadow_pcf" => {
                        matches!(k.domain, Domain::Integers(_))
                    }
                    "shadow_format" => s == "profile" || crate::shadow::parse_format(&s).is_some(),
                    "shadow_culling" => tilegraph_cull::shadow::CasterCulling::parse(&s).is_some(),
                    "oq_group" | "raster_occlusion_scale" | "occlusion_recheck" | "cluster_gap" => {
                        matches!(k.domain, Domain::Integers(_))
                    }
                    "software_resolution" => {
                        crate::occlusion::software::parse_resolution(&s).is_some()
                    }
                    "software_threads" | "software_occluder_triangles" | "pvs_dilation" => {
                        matches!(k.domain, Domain::Integers(_))
                    }
                    other => panic!("knob {other} has no meaning in tilegraph-passes"),
                };
                assert!(understood, "{}={s}", k.name);
            }
        }
    }

    #[test]
    fn run_over_profile_over_default_and_knobs_that_cannot_apply_are_errors() {
        let city = tilegraph_scene::load("city:400").unwrap();
        let mut p = profile("lavapipe");
        p.knobs.set("oq_group", KnobValue::Integer(8)).unwrap();
        let inputs = AutoInputs {
            conditional_rendering: true,
            clusters: false,
            prefer_cpu_occlusion: false,
            pvs: false,
        };
        let mut run = KnobSettings::default();
        run.set_assignment("culling=oq-conditional").unwrap();
        let r = resolve(&p, &run, &city, inputs).unwrap();
        let mut o = RenderOptions::default();
        r.apply(&mut o);
        assert_eq!((o.culling, o.oq_group), (Culling::OqConditional, 8));
        assert!(r.describe().contains(&"oq_group = 8 (profile)".to_string()));
        run.set_assignment("oq_group=2").unwrap();
        let r = resolve(&p, &run, &city, inputs).unwrap();
        r.apply(&mut o);
        assert_eq!(o.oq_group, 2);
        // The profile's oq_group is not used by HiZ culling; the run's is an error.
        let mut hiz = KnobSettings::default();
        hiz.set_assignment("culling=hiz-2phase").unwrap();
        assert!(resolve(&p, &hiz, &city, inputs).is_ok());
        hiz.set_assignment("oq_group=2").unwrap();
        let e = resolve(&p, &hiz, &city, inputs).unwrap_err();
        assert_eq!(
            e.to_string(),
            "knob oq_group applies to culling oq, oq-conditional, and this run culls with hiz-2phase"
        );
        // The city has no alpha-tested geometry: no alpha_prepass knob.
        assert!(!offered(SceneContent::of(&city)).any(|k| k.name == "alpha_prepass"));
        let mut alpha = KnobSettings::default();
        alpha.set_assignment("alpha_prepass=off").unwrap();
        assert!(matches!(
            resolve(&p, &alpha, &city, inputs),
            Err(KnobUseError::NotForScene {
                name: "alpha_prepass",
                ..
            })
        ));
        let forest = tilegraph_scene::load("forest:300").unwrap();
        alpha.set_assignment("culling=none").unwrap();
        let r = resolve(&p, &alpha, &forest, inputs).unwrap();
        r.apply(&mut o);
        assert_eq!(o.alpha_prepass, Some(false));
    }

    #[test]
    fn auto_times_every_candidate_and_keeps_the_fastest() {
        let inputs = AutoInputs {
            conditional_rendering: false,
            clusters: false,
            prefer_cpu_occlusion: false,
            pvs: false,
        };
        let mut t = AutoTrial::new(Culling::HizTwoPhase, inputs, Technique::Forward);
        assert_eq!(t.frames(), 4 * (AUTO_WARMUP_FRAMES + AUTO_TIMED_FRAMES));
        let times = [0.5, 1.1, 0.7, 0.9];
        let mut decided = None;
        for (i, ms) in times.iter().enumerate() {
            let expected = [
                Culling::HizTwoPhase,
                Culling::None,
                Culling::Frustum,
                Culling::SoftwareOcclusion,
            ][i];
            assert_eq!(t.current(), expected);
            for _ in 1..AUTO_WARMUP_FRAMES {
                assert_eq!(t.after_frame(), TrialStep::Continue);
            }
            assert_eq!(t.after_frame(), TrialStep::StartTiming);
            for _ in 1..AUTO_TIMED_FRAMES {
                assert_eq!(t.after_frame(), TrialStep::Continue);
            }
            assert_eq!(t.after_frame(), TrialStep::Measure);
            match t.record(*ms) {
                Ok(next) => assert_eq!(next, t.current()),
                Err(d) => decided = Some(d),
            }
        }
        let (c, why) = decided.unwrap();
        assert_eq!(c, Culling::HizTwoPhase);
        assert!(why.starts_with("auto timed on this device"), "{why}");
        assert!(why.contains("none 1.100 ms"), "{why}");
        // A trial that timed nothing keeps its first candidate and says why.
        let mut blind = AutoTrial::new(Culling::Frustum, inputs, Technique::Forward);
        let mut kept = None;
        while kept.is_none() {
            kept = blind.record(f64::INFINITY).err();
        }
        let (c, why) = kept.unwrap();
        assert_eq!(c, Culling::Frustum);
        assert!(why.contains("could not time"), "{why}");
        // Same-frame queries are a candidate only where the device has conditional rendering.
        let conditional = AutoInputs {
            conditional_rendering: true,
            clusters: false,
            prefer_cpu_occlusion: false,
            pvs: false,
        };
        let with = AutoTrial::new(Culling::None, conditional, Technique::Forward);
        assert_eq!(with.candidates.len(), 5);
        // ... and only with a technique that draws a depth pre-pass for them to test against.
        let visbuf = AutoTrial::new(Culling::HizTwoPhase, conditional, Technique::Visbuf);
        assert_eq!(
            visbuf.candidates,
            [
                Culling::HizTwoPhase,
                Culling::None,
                Culling::Frustum,
                Culling::SoftwareOcclusion
            ]
        );
        // The cluster techniques only on a scene with its clusters attached, with every
        // shading.
        let clusters = AutoInputs {
            clusters: true,
            ..conditional
        };
        let forward = AutoTrial::new(Culling::None, clusters, Technique::Forward);
        assert_eq!(
            forward.candidates[4..],
            [
                Culling::FrustumClusters,
                Culling::HizTwoPhaseClusters,
                Culling::SoftwareOcclusion
            ]
        );
        let visbuf = AutoTrial::new(Culling::HizTwoPhase, clusters, Technique::Visbuf);
        assert!(visbuf.candidates.contains(&Culling::HizTwoPhaseClusters));
        // Not with per-triangle culling, whose packed triangles the ids cannot name.
        let resolved = |technique, triangles: &str| Resolved {
            culling: Culling::HizTwoPhase,
            technique,
            auto_reason: Some("test".into()),
            knobs: vec![KnobChoice {
                name: "triangle_culling",
                value: KnobValue::Name(triangles.into()),
                origin: Origin::Run,
            }],
        };
        let trial = |r: Resolved| r.auto_trial(clusters).map(|t| t.candidates);
        let packed = trial(resolved(Technique::Visbuf, "on")).unwrap();
        assert!(!packed.iter().any(|c| c.clusters()), "{packed:?}");
        let forward = trial(resolved(Technique::Forward, "on")).unwrap();
        assert!(forward.contains(&Culling::HizTwoPhaseClusters));
        let plain = trial(resolved(Technique::Visbuf, "off")).unwrap();
        assert!(plain.contains(&Culling::HizTwoPhaseClusters));
    }

    #[test]
    fn auto_times_a_given_visible_set_only_where_the_profile_allows() {
        let inputs = |pvs| AutoInputs {
            conditional_rendering: true,
            clusters: false,
            prefer_cpu_occlusion: false,
            pvs,
        };
        let with = AutoTrial::new(Culling::HizTwoPhase, inputs(true), Technique::Forward);
        assert!(with.candidates.contains(&Culling::Pvs));
        let without = AutoTrial::new(Culling::HizTwoPhase, inputs(false), Technique::Forward);
        assert!(!without.candidates.contains(&Culling::Pvs));
        // Every shipped profile keeps auto conservative.
        for p in tilegraph_profile::ProfileSet::embedded()
            .unwrap()
            .profiles()
        {
            assert_eq!(
                p.passes.auto_pvs,
                tilegraph_profile::AutoPvs::Never,
                "{}",
                p.name
            );
        }
    }

    #[test]
    fn a_profile_that_prefers_the_cpu_starts_auto_from_software_occlusion() {
        let prefer = AutoInputs {
            conditional_rendering: true,
            clusters: false,
            prefer_cpu_occlusion: true,
            pvs: false,
        };
        let big = tilegraph_scene::load("city:2000").unwrap();
        let (c, why) = auto_culling(&big, prefer, Technique::Forward);
        assert_eq!(c, Culling::SoftwareOcclusion, "{why}");
        assert!(why.contains("Adreno 505"), "{why}");
        // Small scenes are still drawn whole; the trial still times the GPU techniques.
        let small = tilegraph_scene::load("city:100").unwrap();
        assert_eq!(
            auto_culling(&small, prefer, Technique::Forward).0,
            Culling::None
        );
        let t = AutoTrial::new(Culling::SoftwareOcclusion, prefer, Technique::Forward);
        assert_eq!(t.current(), Culling::SoftwareOcclusion);
        assert!(t.candidates.contains(&Culling::HizTwoPhase));
        // adreno-5xx is the profile that says so (seed 000's Adreno 505).
        let adreno = profile("adreno-5xx");
        assert_eq!(
            adreno.passes.cpu_occlusion,
            tilegraph_profile::CpuOcclusion::Prefer
        );
        assert_eq!(
            profile("mali-valhall").passes.cpu_occlusion,
            tilegraph_profile::CpuOcclusion::Allow
        );
    }

    #[test]
    fn auto_wants_clusters_of_levels_baked_into_few_meshes() {
        let city = tilegraph_scene::load("city:300").unwrap();
        assert!(!auto_wants_clusters(&city));
        let baked = tilegraph_scene::load("interior:3000@one-mesh").unwrap();
        assert!(auto_wants_clusters(&baked));
    }

    #[test]
    fn auto_draws_small_scenes_whole_and_culls_big_ones() {
        let inputs = AutoInputs {
            conditional_rendering: true,
            clusters: false,
            prefer_cpu_occlusion: false,
            pvs: false,
        };
        let small = tilegraph_scene::load("city:100").unwrap();
        let (c, why) = auto_culling(&small, inputs, Technique::Forward);
        assert_eq!(c, Culling::None, "{why}");
        let big = tilegraph_scene::load("city:2000").unwrap();
        let (c, why) = auto_culling(&big, inputs, Technique::Forward);
        assert_eq!(c, Culling::HizTwoPhase, "{why}");
        assert!(why.contains("instances"), "{why}");
    }

    /// Heavy instances get same-frame queries, except under the visibility buffer, which has no
    /// depth pre-pass to test their boxes against (`tilegraph render --shading visbuf` with the
    /// default culling failed on every device with conditional rendering).
    #[test]
    fn auto_leaves_queries_out_where_the_technique_cannot_run_them() {
        let inputs = AutoInputs {
            conditional_rendering: true,
            clusters: false,
            prefer_cpu_occlusion: false,
            pvs: false,
        };
        // 300 instances of a 1,000-triangle mesh.
        let mut b = tilegraph_scene::SceneBuilder::new("heavy");
        let material = b.add_material(tilegraph_scene::Material::opaque([1.0; 4]));
        let v = |x: f32, z: f32| tilegraph_scene::Vertex {
            position: [x, 0.0, z],
            normal: [0.0, 1.0, 0.0],
            uv: [0.0; 2],
        };
        let indices: Vec<u32> = (0..1000).flat_map(|_| [0, 1, 2]).collect();
        let mesh = b
            .add_mesh(&[v(0.0, 0.0), v(1.0, 0.0), v(0.0, 1.0)], &indices, material)
            .unwrap();
        for i in 0..300 {
            let at = glam::DVec3::new(f64::from(i) * 2.0, 0.0, 0.0);
            b.add_instance(tilegraph_scene::Transform::from_translation(at), mesh)
                .unwrap();
        }
        let heavy = b.build(None).unwrap();
        let (c, why) = auto_culling(&heavy, inputs, Technique::Forward);
        assert_eq!(c, Culling::OqConditional, "{why}");
        let (c, why) = auto_culling(&heavy, inputs, Technique::Visbuf);
        assert_eq!(c, Culling::HizTwoPhase, "{why}");
        assert!(
            why.contains("shading visbuf has no depth pre-pass"),
            "{why}"
        );
        assert_eq!(c.unsupported_with(Technique::Visbuf), None);
    }
}
