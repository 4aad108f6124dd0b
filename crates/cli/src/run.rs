//! The options every rendering command shares (`render`, `cull-check`, `lint`, `bench`): one
//! vocabulary — `--culling`, `--shading`, `--set knob=value`, `--profile`, `--size`,
//! `--camera-path`, `--frames`, `--json` — and what they become: a context whose profile says
//! who forced it, and [`RenderOptions`] from the knobs (run over profile over defaults).

use std::path::PathBuf;

use tilegraph_passes::cull::Culling;
use tilegraph_passes::knobs::{self, AutoInputs, Resolved};
use tilegraph_passes::{RenderOptions, Technique};
use tilegraph_profile::knobs::{KnobSettings, KnobValue};
use tilegraph_scene::{CameraPath, MotionParams, Scene};
use tilegraph_vk::{Context, ContextOptions, Feature, FeatureRequest};

use crate::{parse_size, CliError};

/// What the deprecated `--technique` meant in a command.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TechniqueMeant {
    Shading,
    Culling,
}

#[derive(clap::Args, Debug, Clone)]
pub struct RunArgs {
    /// A .gltf/.glb path, or city|forest|field|interior|maze[:size[:seed]], or `default`.
    pub scene: String,
    /// Force a profile by name; takes precedence over TILEGRAPH_PROFILE.
    #[arg(long)]
    pub profile: Option<String>,
    /// auto | none | frustum | hiz | hiz-2phase | oq | oq-conditional | raster-occlusion
    /// (default: the profile's `culling` knob; `auto` picks from what the scene holds).
    #[arg(long)]
    pub culling: Option<String>,
    /// forward | prepass | visbuf | deferred-texturing (default: the profile's `shading` knob).
    #[arg(long)]
    pub shading: Option<String>,
    /// Set a knob for this run, e.g. `--set oq_group=16` (`tilegraph knobs` lists them).
    #[arg(long = "set", value_name = "KNOB=VALUE")]
    pub set: Vec<String>,
    /// Frame size, WxH.
    #[arg(long, value_parser = parse_size)]
    pub size: Option<(u32, u32)>,
    /// Camera path: a JSON file (docs/SCENES.md), or `walk[:SEED]` (240 frames at eye height
    /// through the scene, sweeping the view, with cuts); the scene's own path when absent.
    #[arg(long)]
    pub camera_path: Option<PathBuf>,
    /// Frames to render (at least 1).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    pub frames: Option<u32>,
    /// Machine-readable output on standard output.
    #[arg(long)]
    pub json: bool,
    /// How textures are bound: `indexed` (one descriptor each, where the device can index
    /// them) or `layers` (resampled into one array image); default: the profile's `[textures]`.
    #[arg(long, value_parser = parse_texture_binding)]
    pub texture_binding: Option<tilegraph_profile::TextureBinding>,
    /// A precomputed visible set (`tilegraph pvs --out FILE`) for `--culling pvs`.
    #[arg(long, value_name = "FILE")]
    pub pvs: Option<PathBuf>,
    /// Async compute, instead of the profile's `[queues]`: `off`, or on with `exclusive`
    /// (ownership transfers) or `concurrent` sharing. On a device without a second compute
    /// queue (lavapipe) the two-queue plan is submitted to its one queue in order: its waits
    /// and transfers run, the overlap does not.
    #[arg(long, value_parser = parse_async_compute)]
    pub async_compute: Option<tilegraph_profile::QueuePolicy>,
    /// Deprecated: `--shading` in `render`, `--culling` in `cull-check`.
    #[arg(long, hide = true)]
    pub technique: Option<String>,
    /// Deprecated: `--set oq_group=N`.
    #[arg(long, hide = true)]
    pub oq_group: Option<String>,
    /// Deprecated: `--set raster_occlusion_scale=N`.
    #[arg(long, hide = true)]
    pub raster_occlusion_scale: Option<String>,
    /// Deprecated: `--set hiz_npot=MODE`.
    #[arg(long, hide = true)]
    pub hiz_npot: Option<String>,
}

impl RunArgs {
    /// The knobs this run sets: `--set`, then `--culling` / `--shading` and the deprecated
    /// spellings (each with a message saying what replaces it).
    pub fn knob_settings(&self, technique_means: TechniqueMeant) -> Result<KnobSettings, CliError> {
        let mut s = KnobSettings::default();
        for a in &self.set {
            s.set_assignment(a)?;
        }
        let mut flag = |knob: &str, value: &Option<String>, deprecated: Option<&str>| {
            let Some(v) = value else { return Ok(()) };
            if let Some(old) = deprecated {
                eprintln!("tilegraph: {old} is deprecated: use --set {knob}={v}");
            }
            s.set(knob, KnobValue::Name(v.clone()))
        };
        flag("oq_group", &self.oq_group, Some("--oq-group"))?;
        flag(
            "raster_occlusion_scale",
            &self.raster_occlusion_scale,
            Some("--raster-occlusion-scale"),
        )?;
        flag("hiz_npot", &self.hiz_npot, Some("--hiz-npot"))?;
        if let Some(t) = &self.technique {
            let (knob, replacement) = match technique_means {
                TechniqueMeant::Shading => ("shading", "--shading"),
                TechniqueMeant::Culling => ("culling", "--culling"),
            };
            eprintln!("tilegraph: --technique is deprecated: use {replacement} {t}");
            s.set(knob, KnobValue::Name(t.clone()))?;
        }
        let mut flag = |knob: &str, value: &Option<String>| match value {
            Some(v) => s.set(knob, KnobValue::Name(v.clone())),
            None => Ok(()),
        };
        flag("culling", &self.culling)?;
        flag("shading", &self.shading)?;
        Ok(s)
    }

    /// Context options: the environment's, the profile flag credited to `--profile`, and
    /// `features` plus every feature any culling could use, optional (whether the chosen one
    /// has them is checked when the renderer is created, with a typed error naming them).
    pub fn context_options(&self, features: FeatureRequest) -> ContextOptions {
        let mut o = ContextOptions::from_env();
        if let Some(p) = &self.profile {
            o.force_profile(p, "--profile");
        }
        o.features = features;
        if let Some(q) = self.async_compute {
            o.queues = Some(q);
            o.async_on_one_queue = true;
        }
        with_every_culling_feature(o)
    }

    /// The knobs `run` sets (from [`Self::knob_settings`], read before the device is created)
    /// resolved for `scene` on `ctx` (with `options.pvs`, the visible set given), and written
    /// into `options`.
    pub fn resolve(
        ctx: &Context,
        scene: &Scene,
        run: &KnobSettings,
        options: &mut RenderOptions,
    ) -> Result<Resolved, CliError> {
        let inputs = auto_inputs(ctx, scene, options.pvs.as_deref());
        let resolved = knobs::resolve(ctx.profile(), run, scene, inputs)?;
        resolved.apply(options);
        Ok(resolved)
    }

    /// The visible set of `--pvs`, read and checked (`None` without the flag).
    pub fn load_pvs(&self) -> Result<Option<std::sync::Arc<tilegraph_cull::Pvs>>, CliError> {
        let Some(path) = &self.pvs else {
            return Ok(None);
        };
        let usage =
            |e: &dyn std::fmt::Display| CliError::Usage(format!("--pvs {}: {e}", path.display()));
        let bytes = std::fs::read(path).map_err(|e| usage(&e))?;
        let pvs = tilegraph_cull::Pvs::from_json(&bytes).map_err(|e| usage(&e))?;
        Ok(Some(std::sync::Arc::new(pvs)))
    }

    /// The camera path: `--camera-path`, else the scene's own.
    pub fn camera_path(&self, scene: &Scene) -> Result<CameraPath, CliError> {
        match &self.camera_path {
            Some(p) => named_camera_path(&p.to_string_lossy(), scene),
            None => Ok(scene.camera_path().clone()),
        }
    }
}

fn parse_async_compute(s: &str) -> Result<tilegraph_profile::QueuePolicy, String> {
    use tilegraph_profile::{QueuePolicy, QueueSharing};
    let on = |sharing| QueuePolicy {
        async_compute: true,
        sharing,
    };
    match s {
        "off" => Ok(QueuePolicy::default()),
        "exclusive" => Ok(on(QueueSharing::Exclusive)),
        "concurrent" => Ok(on(QueueSharing::Concurrent)),
        _ => Err(format!("`{s}`: off, exclusive or concurrent")),
    }
}

fn parse_texture_binding(s: &str) -> Result<tilegraph_profile::TextureBinding, String> {
    use tilegraph_profile::TextureBinding;
    [TextureBinding::Indexed, TextureBinding::Layers]
        .into_iter()
        .find(|b| b.name() == s)
        .ok_or_else(|| format!("`{s}`: indexed or layers"))
}

/// The seed of a `walk[:SEED]` camera path, `None` for a file; a malformed seed is an error.
pub fn walk_seed(spec: &str) -> Result<Option<u64>, CliError> {
    match spec.strip_prefix("walk") {
        Some("") => Ok(Some(1)),
        Some(rest) => match rest.strip_prefix(':').map(str::parse::<u64>) {
            Some(Ok(seed)) => Ok(Some(seed)),
            _ => Err(CliError::Usage(format!(
                "camera path `{spec}`: `walk` or `walk:SEED` (SEED a whole number)"
            ))),
        },
        None => Ok(None),
    }
}

/// Frames of a `walk` camera path.
pub const WALK_FRAMES: usize = 240;

/// A camera path by name: `walk[:SEED]` ([`CameraPath::eye_height_walk`] through the scene's
/// bounds, [`WALK_FRAMES`] frames), else a JSON file.
pub fn named_camera_path(spec: &str, scene: &Scene) -> Result<CameraPath, CliError> {
    Ok(match walk_seed(spec)? {
        Some(seed) => CameraPath::eye_height_walk(&scene.bounds(), WALK_FRAMES, seed),
        None => CameraPath::load_json(std::path::Path::new(spec))?,
    })
}

/// Whether a scene is loaded with its clusters.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Clusters {
    No,
    Yes,
    /// With the levels of detail they carry (knob `lod_error_px`): without, the scene's index
    /// buffer holds the full meshes only.
    WithLevels,
    /// Where `auto` would try cluster culling on it (`knobs::auto_wants_clusters`).
    ForAuto,
}

/// The clusters the culling `knobs` name needs: a cluster technique or levels of detail, them;
/// `auto` (named, or left to the profile), them where it would try cluster culling.
pub fn wants_clusters(knobs: &KnobSettings) -> Clusters {
    // Levels of detail come with the clusters.
    if knobs
        .get("lod_error_px")
        .is_some_and(|v| v.to_string() != "0")
    {
        return Clusters::WithLevels;
    }
    match knobs.get("culling").map(|v| v.to_string()) {
        None => Clusters::ForAuto,
        Some(name) => match Culling::parse(&name) {
            Some(c) if c.clusters() => Clusters::Yes,
            Some(_) => Clusters::No,
            None => Clusters::ForAuto,
        },
    }
}

/// A scene spec's motion: `SPEC@moving[:MOVERS[:SPAWNS[:SEED[:MIRRORS]]]]` moves the scene
/// along the camera path ([`MotionParams`]: the share of small instances that move, the
/// instances spawned in front of the camera, the seed, the share of movers mirrored for half
/// their period); returns the spec without it.
pub fn split_motion(spec: &str) -> Result<(&str, Option<MotionParams>), CliError> {
    let Some((scene, motion)) = spec.rsplit_once("@moving") else {
        return Ok((spec, None));
    };
    let bad = |why: &str| {
        CliError::Usage(format!(
            "scene `{spec}`: {why} (SPEC@moving[:MOVERS[:SPAWNS[:SEED[:MIRRORS]]]], e.g. city:10k@moving:0.2:12:1:0.5)"
        ))
    };
    let mut params = MotionParams::default();
    if !motion.is_empty() {
        let parts: Vec<&str> = motion
            .strip_prefix(':')
            .ok_or_else(|| bad("`@moving` is followed by `:`"))?
            .split(':')
            .collect();
        if parts.len() > 4 {
            return Err(bad("too many fields"));
        }
        if let Some(m) = parts.first() {
            params.movers = m
                .parse::<f64>()
                .ok()
                .filter(|m| (0.0..=1.0).contains(m))
                .ok_or_else(|| bad("MOVERS is a share from 0 to 1"))?;
        }
        if let Some(n) = parts.get(1) {
            let most = tilegraph_scene::motion::MAX_SPAWNS;
            params.spawns = n
                .parse()
                .ok()
                .filter(|&n| n <= most)
                .ok_or_else(|| bad(&format!("SPAWNS is a count up to {most}")))?;
        }
        if let Some(seed) = parts.get(2) {
            params.seed = seed.parse().map_err(|_| bad("SEED is an integer"))?;
        }
        if let Some(m) = parts.get(3) {
            params.mirrors = m
                .parse::<f64>()
                .ok()
                .filter(|m| (0.0..=1.0).contains(m))
                .ok_or_else(|| bad("MIRRORS is a share from 0 to 1"))?;
        }
    }
    Ok((scene, Some(params)))
}

/// Loads the scene `spec` (without its motion, [`split_motion`]); with `clusters`, attaches
/// its clusters: from the cache (`tilegraph_scene::clusters::cache_dir`), else built with
/// meshoptimizer and cached.
pub fn load_scene(spec: &str, clusters: impl Into<Clusters>) -> Result<Scene, CliError> {
    let (spec, _) = split_motion(spec)?;
    let mut scene = tilegraph_scene::load(spec)?;
    let clusters = clusters.into();
    let attach = match clusters {
        Clusters::No => false,
        Clusters::Yes | Clusters::WithLevels => true,
        Clusters::ForAuto => knobs::auto_wants_clusters(&scene),
    };
    if attach {
        attach_clusters(&mut scene, spec, clusters == Clusters::WithLevels)?;
    }
    Ok(scene)
}

/// Attaches `scene`'s clusters (`what` names it in the log): from the cache, else built; with
/// their levels of detail where `levels` says so.
pub fn attach_clusters(scene: &mut Scene, what: &str, levels: bool) -> Result<(), CliError> {
    let (data, how) = tilegraph_scene::clusters::cached(scene)?;
    let data = if levels { data } else { data.without_lods() };
    match how {
        tilegraph_scene::clusters::Provenance::Cache(path) => {
            log::info!("{what}: clusters from {}", path.display())
        }
        tilegraph_scene::clusters::Provenance::Built(stats) => log::info!(
            "{what}: {} clusters built in {:.1} ms",
            stats.clusters,
            stats.milliseconds
        ),
    }
    scene.attach_clusters(data)?;
    Ok(())
}

/// Runs `work` on a context made from `options`, then destroys it with validation checked
/// (objects left alive are reported at teardown); the work's error comes first.
pub fn on_context<R>(
    options: ContextOptions,
    work: impl FnOnce(&Context) -> Result<R, CliError>,
) -> Result<R, CliError> {
    let ctx = Context::new(options)?;
    let result = work(&ctx);
    let destroyed = ctx.destroy_checked();
    let r = result?;
    destroyed?;
    Ok(r)
}

/// What `auto` may choose between on `ctx`'s device, for `scene` and the visible set given
/// (`--pvs`; `auto` times it only where the profile says `auto_pvs = "allow"` and the set was
/// baked for this scene).
pub fn auto_inputs(ctx: &Context, scene: &Scene, pvs: Option<&tilegraph_cull::Pvs>) -> AutoInputs {
    let passes = &ctx.profile().passes;
    AutoInputs {
        clusters: scene.clusters().is_some(),
        conditional_rendering: ctx.has_feature(Feature::ConditionalRendering),
        prefer_cpu_occlusion: passes.cpu_occlusion == tilegraph_profile::CpuOcclusion::Prefer,
        pvs: passes.auto_pvs == tilegraph_profile::AutoPvs::Allow
            && pvs.is_some_and(|p| p.scene_fingerprint == scene.placement_fingerprint()),
    }
}

/// `o` with every feature a culling or shading technique could use added as optional (whether
/// the chosen one has them is checked when the renderer is created, with a typed error).
pub fn with_every_culling_feature(mut o: ContextOptions) -> ContextOptions {
    for c in ALL_CULLINGS {
        let r = RenderOptions {
            culling: c,
            ..Default::default()
        }
        .device_features();
        o.features.optional.extend(r.required);
        o.features.optional.extend(r.optional);
    }
    for t in [Technique::Forward, Technique::Visbuf] {
        let r = RenderOptions {
            technique: t,
            ..Default::default()
        }
        .device_features();
        o.features.optional.extend(r.required);
    }
    o.features.optional.insert(Feature::ConditionalRendering);
    let required = o.features.required.clone();
    o.features.optional.retain(|f| !required.contains(f));
    o
}

/// The techniques `cull-check`, `bench` and `tune` run when none are named: the
/// instance-level ones (the cluster techniques, which build the scene's clusters, by name).
pub const ALL_CULLINGS: [Culling; 8] = Culling::STANDARD;

/// How long `cull-check`, `bench` and `tune` render the path before they time it
/// (`CheckExtras::timing_warmup`): long enough for a desktop GPU's clocks to settle after the
/// checked pass's readbacks (an H100 timed one setting 0.51 and 1.00 ms in two runs without it).
pub const TIMING_WARMUP: std::time::Duration = std::time::Duration::from_millis(500);

impl From<bool> for Clusters {
    fn from(yes: bool) -> Self {
        if yes {
            Clusters::Yes
        } else {
            Clusters::No
        }
    }
}
