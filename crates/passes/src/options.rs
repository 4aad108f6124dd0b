//! How a renderer renders ([`RenderOptions`]), what it reports per frame ([`FrameReport`]), its
//! errors, and what it needs of the device.

use std::sync::Arc;

use tilegraph_cull::NpotMode;
use tilegraph_graph::{GraphError, Plan};
use tilegraph_scene::Scene;
use tilegraph_vk::executor::FrameStats;
use tilegraph_vk::queries::GpuTiming;
use tilegraph_vk::{Context, Feature, FeatureRequest, VkError};

use crate::cull::{ClusterEarly, CullBounds, CullState, Culling, GpuCullCounts, CLUSTER_GAP};
use crate::gpu_scene::{visbuf_instance_bits, Lighting};
use crate::lint::FrameLint;
use crate::occlusion::OqState;
use crate::setup::{FrameSetup, Technique, VisbufResolve};

/// Errors of rendering a scene: each names what failed.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    #[error(transparent)]
    Vk(#[from] VkError),
    #[error("compiling the frame graph: {0}")]
    Graph(#[from] GraphError),
    #[error("visibility buffer: {instances} instances and meshes of up to {max_triangles} triangles do not fit a 32-bit id")]
    VisbufIdOverflow {
        instances: usize,
        max_triangles: u32,
    },
    #[error("deferred texturing: the scene has {materials} materials; the G-buffer holds ids of {max} (12 bits, one kept for the background)")]
    GbufferMaterials { materials: usize, max: u32 },
    #[error("{wanted_by} needs device feature {feature}, which {device:?} does not have or was not created with (ask RenderOptions::device_features before creating the device)")]
    MissingFeature {
        feature: Feature,
        wanted_by: WantedBy,
        device: String,
    },
    #[error("culling {culling} does not support the {technique} technique ({reason})")]
    UnsupportedCulling {
        culling: &'static str,
        technique: &'static str,
        reason: &'static str,
    },
    /// `Culling::Pvs` without a visible set, or with one baked for other geometry.
    #[error("culling pvs: {reason}")]
    Pvs { reason: String },
    #[error("culling {culling} culls clusters, and scene {scene:?} has none attached (build them with tilegraph_scene::clusters::cached or read prebuilt ones, then Scene::attach_clusters)")]
    NoClusters {
        culling: &'static str,
        scene: String,
    },
    /// Levels of detail asked for where they cannot be drawn.
    #[error("level of detail (lod_error_px = {error_px}): {reason}")]
    Lod { error_px: f32, reason: &'static str },
    #[error("the engine's colour target: {0}")]
    Target(String),
    /// Software occlusion could not take the frame's camera or an occluder mesh.
    #[error("software occlusion: {0}")]
    Software(tilegraph_cull::CullError),
    #[error("this renderer draws into the engine's target and the engine submits its frames: use SceneRenderer::record")]
    EngineSubmits,
    #[error("invalid render size {width}x{height}")]
    Size { width: u32, height: u32 },
    /// A check's `on_failure` callback failed (writing a failed frame's images).
    #[error("cull-check: {what} read nothing back")]
    MissingReadback { what: &'static str },
    #[error("saving a failed frame: {0}")]
    Save(String),
    /// The scene's buffers would bind more than the device's `maxStorageBufferRange`.
    #[error("a scene of {instances} instance slots needs a storage buffer of {needed_bytes} bytes; this device binds at most {limit_bytes} (maxStorageBufferRange)")]
    SceneTooLarge {
        instances: u32,
        needed_bytes: u64,
        limit_bytes: u64,
    },
    /// A change to the scene was refused (a motion's step, say).
    #[error("scene: {0}")]
    Scene(#[from] tilegraph_scene::SceneError),
    #[error("material {material} names engine material {engine}, and the renderer has {registered} registered (SceneRenderer::add_material)")]
    UnknownEngineMaterial {
        material: u32,
        engine: u32,
        registered: usize,
    },
    #[error("material {material} is resolved by engine material {engine}'s shader, which runs after material classification: set the knob visbuf_resolve = classified (RenderOptions::visbuf_resolve)")]
    EngineResolveNeedsClassification { material: u32, engine: u32 },
    #[error("camera: {field}: {reason}")]
    Camera { field: &'static str, reason: String },
    #[error("view {0} is not a further view of this renderer (SceneRenderer::add_view)")]
    UnknownView(u32),
    #[error("more views than a frame can declare")]
    TooManyViews,
}

impl RenderError {
    /// Out of memory (the device's, the host's, or the context's budget): the frame failed
    /// cleanly; free memory (or raise the budget) and render the next one.
    pub fn is_out_of_memory(&self) -> bool {
        matches!(self, RenderError::Vk(e) if e.is_out_of_memory())
    }

    /// The device was lost: destroy the renderer, the context and the device.
    pub fn is_device_lost(&self) -> bool {
        matches!(self, RenderError::Vk(e) if e.is_device_lost())
    }
}

/// How to render.
#[derive(Debug, Clone, PartialEq)]
pub struct RenderOptions {
    pub technique: Technique,
    pub width: u32,
    pub height: u32,
    pub lighting: Lighting,
    pub clear_color: [f32; 4],
    /// Count the fragments each colour pass shades (an atomic per fragment; needs
    /// `fragmentStoresAndAtomics`). For measurement runs, not for shipping frames.
    pub count_fragments: bool,
    /// `tilegraph bottleneck`'s probes: shaders made trivial to see what a stage costs. Off
    /// (the default) for every frame that is not such a measurement.
    pub probe: crate::probe::StageProbe,
    /// Overrides the profile's opaque draw order (measurements: `BackToFront` is the worst
    /// case for early depth rejection).
    pub opaque_order: Option<tilegraph_profile::SortOrder>,
    /// Overrides the profile's `alpha_tested_prepass` (knob `alpha_prepass`).
    pub alpha_prepass: Option<bool>,
    /// Overrides the profile's `depth_prepass` for forward shading (knob `depth_prepass`).
    pub depth_prepass: Option<bool>,
    /// The depth buffer's format (knob `depth_format`); the HiZ pyramid follows it.
    pub depth_format: tilegraph_cull::DepthFormat,
    /// GPU culling before drawing (opaque and alpha-tested instances; blended ones are frustum
    /// culled on the CPU and sorted back to front).
    pub culling: Culling,
    /// How the HiZ pyramid handles non-power-of-two sizes (seed 000's two fixes).
    pub hiz_mode: NpotMode,
    /// The HiZ pyramid's finest stored level (knob `hiz_resolution`): 0 the depth's resolution,
    /// 1 half, 2 quarter — less memory and build traffic, coarser tests of small objects.
    pub hiz_base_level: u32,
    /// The bounds GPU culling tests (knob `cull_bounds`).
    pub cull_bounds: CullBounds,
    /// What `hiz-2phase-clusters`' early phase draws (knob `cluster_early`).
    pub cluster_early: ClusterEarly,
    /// Cluster techniques: the longest gap of culled clusters a command draws through (knob
    /// `cluster_gap`; 0 draws exactly the surviving clusters).
    pub cluster_gap: u32,
    /// Cluster techniques: per-triangle culling after the clusters (knob `triangle_culling`).
    pub triangle_culling: bool,
    /// Level of detail (knob `lod_error_px`): each instance drawn with the coarsest of its
    /// mesh's simplified levels whose error projects to at most this many pixels; 0 (the
    /// default) draws every mesh at full detail. GPU instance culling chooses the levels.
    pub lod_error_px: f32,
    /// Level of detail's switching band (knob `lod_hysteresis`, in [0, 1)): an instance goes
    /// to a coarser level than last frame's only once that level's error projects to at most
    /// `lod_error_px * (1 - lod_hysteresis)`, and back to a finer one as soon as its level's
    /// exceeds `lod_error_px`: an instance near a threshold does not flip levels from frame to
    /// frame, and no level drawn exceeds the bound. 0: no band.
    pub lod_hysteresis: f32,
    /// Keep the visibility buffer's ids after the frame (the oracle reads them back):
    /// the id attachment becomes an imported image, so it is stored.
    pub capture_ids: bool,
    /// Keep the main view's depth after the frame (`cull-check` compares a level-of-detail
    /// frame's depth with the full-detail one's): the depth becomes an imported image, so it
    /// is stored (on a tiler, traffic the frame otherwise saves).
    pub capture_depth: bool,
    /// Occlusion queries: instances per query (groups of nearby instances share one box).
    pub oq_group: usize,
    /// Occlusion queries and raster occlusion (knob `occlusion_recheck`): what was visible is
    /// drawn untested and its box tested again once every this many frames (staggered per
    /// query group or instance); hidden boxes are tested every frame. 1 tests every box every
    /// frame.
    pub occlusion_recheck: u32,
    /// Raster occlusion: 1 tests boxes at full resolution; 2 or 4 test screen rectangles
    /// against a conservative (farthest-depth) 1/2 or 1/4 resolution depth.
    pub raster_occlusion_scale: u32,
    /// What each frame's GPU queries measure: per pass with shader statistics (the default, for
    /// profiling), per pass, the whole frame only (what a shipped frame needs for its frame
    /// time), or nothing. Timing every pass costs the GPU time of its own, and only the whole frame
    /// counts the clears between passes (docs/ACCURACY.md, "What a frame time is").
    pub gpu_timing: GpuTiming,
    /// Instance slots the renderer's buffers hold from the start (rounded up to a power of
    /// two; at least the scene's). A scene that outgrows them gets new buffers at its next
    /// frame, after the frames in flight are waited for: an engine that knows how many
    /// instances it will spawn says so here.
    pub instance_capacity: u32,
    /// Overrides the profile's texture binding (`[textures] binding`): `layers` forces the
    /// one-image fallback on any device; `indexed` still falls back where the device lacks
    /// the indexing features.
    pub texture_binding: Option<tilegraph_profile::TextureBinding>,
    /// The visibility buffer's resolve (knob `visbuf_resolve`); `None`: the profile's knob,
    /// else the über-resolve.
    pub visbuf_resolve: Option<VisbufResolve>,
    /// Material classification's tile side in pixels, 8, 16 or 32 (knob `classify_tile`);
    /// `None`: the profile's knob, else 16.
    pub classify_tile: Option<u32>,
    /// The directional light's cascaded shadow maps (off by default).
    pub shadows: crate::shadow::ShadowOptions,
    /// Software occlusion's knobs (`Culling::SoftwareOcclusion`).
    pub software: crate::occlusion::SoftwareOptions,
    /// The precomputed visible set `Culling::Pvs` draws from, and how many cells around the
    /// camera's its sets join (knob `pvs_dilation`).
    pub pvs: Option<std::sync::Arc<tilegraph_cull::Pvs>>,
    pub pvs_dilation: u32,
}

impl RenderOptions {
    /// The resolve and classification tile this run uses: its own choice, else `profile`'s
    /// knobs, else the über-resolve and 16-pixel tiles.
    pub fn visbuf_resolve(&self, profile: &tilegraph_profile::Profile) -> (VisbufResolve, u32) {
        let knob = |name: &str| profile.knobs.get(name);
        let resolve = self
            .visbuf_resolve
            .or_else(|| {
                knob("visbuf_resolve")
                    .and_then(|v| v.as_name())
                    .and_then(VisbufResolve::parse)
            })
            .unwrap_or(VisbufResolve::Uber);
        let tile = self
            .classify_tile
            .or_else(|| knob("classify_tile").and_then(|v| v.as_integer()))
            .filter(|t| [8, 16, 32].contains(t))
            .unwrap_or(16);
        (resolve, tile)
    }
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            technique: Technique::Forward,
            width: 320,
            height: 180,
            lighting: Lighting::default(),
            clear_color: [0.55, 0.65, 0.78, 1.0],
            count_fragments: false,
            probe: crate::probe::StageProbe::default(),
            opaque_order: None,
            alpha_prepass: None,
            depth_prepass: None,
            depth_format: tilegraph_cull::DepthFormat::D32Float,
            culling: Culling::None,
            hiz_mode: NpotMode::EdgeAware,
            hiz_base_level: 0,
            cull_bounds: CullBounds::Aabb,
            cluster_early: ClusterEarly::Instances,
            cluster_gap: CLUSTER_GAP,
            triangle_culling: false,
            lod_error_px: 0.0,
            lod_hysteresis: 0.2,
            capture_ids: false,
            capture_depth: false,
            oq_group: 16,
            occlusion_recheck: 8,
            raster_occlusion_scale: 1,
            gpu_timing: GpuTiming::PassStatistics,
            instance_capacity: 0,
            texture_binding: None,
            visbuf_resolve: None,
            classify_tile: None,
            shadows: crate::shadow::ShadowOptions::default(),
            software: crate::occlusion::SoftwareOptions::default(),
            pvs: None,
            pvs_dilation: 1,
        }
    }
}

/// What one frame did.
#[derive(Debug, Clone)]
pub struct FrameReport {
    /// The passes the frame has, each with its reason (decided once per renderer).
    pub setup: Arc<FrameSetup>,
    /// The compiled plan (shared with the frames that reuse it).
    pub plan: Arc<Plan>,
    pub stats: FrameStats,
    /// The frame declared its graph and compiled it (the first frame, or what the declaration
    /// depends on changed); otherwise it reused the last frame's declaration and plan.
    pub declared: bool,
    /// Draws and triangles of the CPU draw lists.
    pub draws: usize,
    pub triangles: u64,
    /// With GPU culling: what the newest completed frame drew and culled on the GPU (frames in
    /// flight earlier than this one; read without waiting). `None` until a frame completed.
    pub gpu_culling: Option<GpuCullCounts>,
    /// The state lint of this frame's draws, after [`SceneRenderer::lint_next_frame`](crate::SceneRenderer::lint_next_frame).
    pub lint: Option<Arc<FrameLint>>,
    /// With software occlusion: what the main view's CPU rasterizer did this frame.
    pub software: Option<crate::occlusion::SoftwareFrame>,
}

/// What in [`RenderOptions`] wants a device feature (named in [`RenderError::MissingFeature`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WantedBy {
    /// The executor itself (barriers, dynamic rendering).
    Executor,
    Technique(Technique),
    Culling(Culling),
    /// [`RenderOptions::count_fragments`].
    FragmentCounting,
}

impl std::fmt::Display for WantedBy {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            WantedBy::Executor => f.write_str("the executor"),
            WantedBy::Technique(t) => write!(f, "technique {}", t.name()),
            WantedBy::Culling(c) => write!(f, "culling {}", c.name()),
            WantedBy::FragmentCounting => f.write_str("fragment counting"),
        }
    }
}

impl RenderOptions {
    /// Every device feature these options need, each with what wants it.
    pub fn needs(&self) -> Vec<(Feature, WantedBy)> {
        let mut needs: Vec<(Feature, WantedBy)> = FeatureRequest::executor()
            .required
            .into_iter()
            .map(|f| (f, WantedBy::Executor))
            .collect();
        if self.technique == Technique::Visbuf {
            needs.push((Feature::GeometryShader, WantedBy::Technique(self.technique)));
        }
        let culling = WantedBy::Culling(self.culling);
        if self.culling.uses_queries() {
            needs.extend(OqState::required_features().map(|f| (f, culling)));
        }
        if self.culling.conditional() {
            needs.push((Feature::ConditionalRendering, culling));
        }
        if self.culling == Culling::RasterOcclusion {
            needs.push((Feature::FragmentStoresAndAtomics, culling));
        }
        if self.count_fragments {
            needs.push((
                Feature::FragmentStoresAndAtomics,
                WantedBy::FragmentCounting,
            ));
        }
        needs
    }

    /// What a device must be created with to render with these options: the executor's
    /// features and everything in [`RenderOptions::needs`] required. An engine that creates
    /// its own device asks for this first (`tilegraph_vk::DeviceConfig::new` turns it into
    /// extensions and feature structs for the physical device).
    pub fn device_features(&self) -> FeatureRequest {
        let mut request =
            FeatureRequest::executor().require(self.needs().into_iter().map(|(f, _)| f));
        // Shadow casters are culled into indirect lists too; their pipelines clamp depth
        // (casters nearer the light than the cascade's top) where the device can.
        if self.culling.uses_gpu_lists() || self.shadows.enabled() {
            request = request.want(CullState::wanted_features());
        }
        if self.shadows.enabled() {
            request = request.want([tilegraph_vk::Feature::DepthClamp]);
        }
        request
    }
}

/// Checks that `options` can render `scene` on `ctx`'s device — the size, the visibility
/// buffer's ids, the features of the technique and the culling, and the combination of both —
/// and returns the visibility buffer's instance bits (`None`: the ids do not fit, and the
/// technique does not use them).
pub(crate) fn check_device(
    ctx: &Context,
    options: &RenderOptions,
    scene: &Scene,
) -> Result<Option<u32>, RenderError> {
    let (w, h) = (options.width, options.height);
    let max = ctx.physical.limits.max_image_dimension_2d;
    if w == 0 || h == 0 || w > max || h > max {
        return Err(RenderError::Size {
            width: w,
            height: h,
        });
    }
    let max_tris = scene
        .meshes()
        .iter()
        .map(|m| m.triangle_count())
        .max()
        .unwrap_or(0);
    let instance_bits = visbuf_instance_bits(scene.instances().len(), max_tris);
    if options.technique == Technique::Visbuf && instance_bits.is_none() {
        return Err(RenderError::VisbufIdOverflow {
            instances: scene.instances().len(),
            max_triangles: max_tris,
        });
    }
    check_gbuffer_materials(options.technique, scene)?;
    if let Some(reason) = options.culling.unsupported_with(options.technique) {
        return Err(RenderError::UnsupportedCulling {
            culling: options.culling.name(),
            technique: options.technique.name(),
            reason,
        });
    }
    if options.triangle_culling
        && options.culling.clusters()
        && options.technique == Technique::Visbuf
    {
        return Err(RenderError::UnsupportedCulling {
            culling: options.culling.name(),
            technique: options.technique.name(),
            reason: "with knob triangle_culling its commands draw the kept triangles packed anew, which the ids' primitive ids cannot name",
        });
    }
    if options.culling == Culling::Pvs {
        let reason = match &options.pvs {
            None => Some("no visible set given (bake one with `tilegraph pvs`, pass it with --pvs or RenderOptions::pvs)".to_string()),
            Some(p) if p.scene_fingerprint != scene.placement_fingerprint() => Some(format!(
                "the visible set was baked for other geometry or placements (fingerprint {:016x}, scene {:016x})",
                p.scene_fingerprint,
                scene.placement_fingerprint()
            )),
            Some(p) => p.validate().err().map(|e| e.to_string()),
        };
        if let Some(reason) = reason {
            return Err(RenderError::Pvs { reason });
        }
    }
    check_lod(options, scene)?;
    if options.culling.clusters() && scene.clusters().is_none() {
        return Err(RenderError::NoClusters {
            culling: options.culling.name(),
            scene: scene.name().to_string(),
        });
    }
    if let Some((feature, wanted_by)) = options
        .needs()
        .into_iter()
        .find(|(f, _)| !ctx.has_feature(*f))
    {
        return Err(RenderError::MissingFeature {
            feature,
            wanted_by,
            device: ctx.physical.identity.device_name.clone(),
        });
    }
    Ok(instance_bits)
}

/// Commands per draw group `options` make GPU culling write for `scene`: one, or with levels of
/// detail (asked for, and the scene has some) one per level — the mesh's own and
/// [`tilegraph_scene::MAX_LODS`] coarser.
pub(crate) fn lod_levels(options: &RenderOptions, scene: &Scene) -> u32 {
    let lods = scene.clusters().is_some_and(|c| c.has_lods());
    if options.lod_error_px > 0.0 && lods {
        1 + tilegraph_scene::MAX_LODS as u32
    } else {
        1
    }
}

/// Checks that levels of detail, if asked for, can be drawn: GPU instance culling chooses them
/// (its list entries carry the level in their top 3 bits), the scene carries them (with its
/// clusters), and the shading draws what the commands say (the visibility buffer's resolve
/// refetches each pixel's triangle from the mesh's full-detail indices).
fn check_lod(options: &RenderOptions, scene: &Scene) -> Result<(), RenderError> {
    let error_px = options.lod_error_px;
    if error_px == 0.0 {
        return Ok(());
    }
    let refuse = |reason| Err(RenderError::Lod { error_px, reason });
    if !(error_px.is_finite() && error_px > 0.0) {
        return refuse("a positive number of pixels, or 0 for full detail");
    }
    if !(0.0..1.0).contains(&options.lod_hysteresis) {
        return refuse("lod_hysteresis is a fraction of the error in [0, 1)");
    }
    if !matches!(
        options.culling,
        Culling::Frustum | Culling::Hiz | Culling::HizTwoPhase | Culling::Reproject
    ) {
        return refuse(
            "levels are chosen by GPU instance culling: frustum, hiz, hiz-2phase or reproject",
        );
    }
    if options.technique == Technique::Visbuf {
        return refuse("the visibility buffer's resolve refetches triangles from the full-detail mesh; shade with forward, prepass or deferred-texturing");
    }
    if scene.clusters().is_none() {
        return refuse("the scene's levels of detail come with its clusters: attach them (tilegraph_scene::clusters::cached, or a prebuilt file)");
    }
    if scene.instances().len() as u64 + u64::from(options.instance_capacity) >= 1 << 29 {
        return refuse(
            "more than 2^29 instance slots: the list entries keep the level in their top bits",
        );
    }
    Ok(())
}

/// Deferred texturing's G-buffer holds 12-bit material ids: a scene of more materials cannot
/// be drawn with it (checked at creation and each frame: materials may be added).
pub(crate) fn check_gbuffer_materials(
    technique: Technique,
    scene: &Scene,
) -> Result<(), RenderError> {
    let max = crate::gbuffer::GBUFFER_MATERIALS;
    let materials = scene.materials().len();
    if technique == Technique::DeferredTexturing && materials > max as usize {
        return Err(RenderError::GbufferMaterials { materials, max });
    }
    Ok(())
}
