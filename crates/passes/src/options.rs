//! How a renderer renders ([`RenderOptions`]), what it reports per frame ([`FrameReport`]), its
//! errors, and what it needs of the device.

use std::sync::Arc;

use tilegraph_cull::NpotMode;
use tilegraph_graph::{GraphError, Plan};
use tilegraph_scene::Scene;
use tilegraph_vk::executor::FrameStats;
use tilegraph_vk::{Context, Feature, FeatureRequest, VkError};

use crate::cull::{CullState, Culling};
use crate::gpu_scene::{visbuf_instance_bits, Lighting};
use crate::occlusion::OqState;
use crate::setup::{FrameSetup, Technique};

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
    #[error("technique {technique} needs device feature {feature}, which {device:?} does not have (or it was not requested)")]
    MissingFeature {
        technique: &'static str,
        feature: Feature,
        device: String,
    },
    #[error("culling {culling} needs {extension}, which {device:?} does not have (or it was not requested)")]
    MissingExtension {
        culling: &'static str,
        extension: &'static str,
        device: String,
    },
    #[error("culling {culling} does not support the {technique} technique (it needs a depth pre-pass before colour)")]
    UnsupportedCulling {
        culling: &'static str,
        technique: &'static str,
    },
    #[error("invalid render size {width}x{height}")]
    Size { width: u32, height: u32 },
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
    /// Overrides the profile's opaque draw order (measurements: `BackToFront` is the worst
    /// case for early depth rejection).
    pub opaque_order: Option<tilegraph_profile::SortOrder>,
    /// GPU culling before drawing (opaque and alpha-tested instances; blended ones are frustum
    /// culled on the CPU and sorted back to front).
    pub culling: Culling,
    /// How the HiZ pyramid handles non-power-of-two sizes (seed 000's two fixes).
    pub hiz_mode: NpotMode,
    /// Keep the visibility buffer's ids after the frame (the oracle reads them back):
    /// the id attachment becomes an imported image, so it is stored.
    pub capture_ids: bool,
    /// Occlusion queries: instances per query (groups of nearby instances share one box).
    pub oq_group: usize,
    /// Raster occlusion: 1 tests boxes at full resolution; 2 or 4 test screen rectangles
    /// against a conservative (farthest-depth) 1/2 or 1/4 resolution depth.
    pub raster_occlusion_scale: u32,
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
            opaque_order: None,
            culling: Culling::None,
            hiz_mode: NpotMode::EdgeAware,
            capture_ids: false,
            oq_group: 1,
            raster_occlusion_scale: 1,
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
    /// Draws and triangles of the CPU draw lists.
    pub draws: usize,
    pub triangles: u64,
}

/// Device features a technique needs (request them when creating the context).
pub fn required_features(technique: Technique) -> FeatureRequest {
    let r = FeatureRequest::default();
    match technique {
        Technique::Visbuf => r.require([Feature::GeometryShader]),
        Technique::Forward | Technique::Prepass => r,
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
    let mut needed = required_features(options.technique);
    if options.culling.uses_gpu_lists() {
        needed.required.extend(CullState::required_features());
    }
    if options.culling == Culling::RasterOcclusion || options.count_fragments {
        needed.required.insert(Feature::FragmentStoresAndAtomics);
    }
    if options.culling.uses_queries() {
        needed.required.extend(OqState::required_features());
    }
    if options.technique == Technique::Visbuf
        && matches!(
            options.culling,
            Culling::OqConditional | Culling::RasterOcclusion
        )
    {
        // Both test boxes against a depth pre-pass before colour; the visibility buffer has no
        // pre-pass to test against.
        return Err(RenderError::UnsupportedCulling {
            culling: options.culling.name(),
            technique: options.technique.name(),
        });
    }
    let device = || ctx.physical.identity.device_name.clone();
    if options.culling.conditional() && !ctx.has_feature(Feature::ConditionalRendering) {
        return Err(RenderError::MissingExtension {
            culling: options.culling.name(),
            extension: "VK_EXT_conditional_rendering",
            device: device(),
        });
    }
    for f in needed.required {
        if !ctx.has_feature(f) {
            return Err(RenderError::MissingFeature {
                technique: options.technique.name(),
                feature: f,
                device: device(),
            });
        }
    }
    Ok(instance_bits)
}
