//! The committed SPIR-V of the scene passes (`cargo xtask shaders` makes it from `shaders/`).

pub const DEPTH_VS: &[u8] = include_bytes!("../../../shaders/spv/depth.vert.spv");
pub const DEPTH_ALPHA_VS: &[u8] = include_bytes!("../../../shaders/spv/depth_alpha.vert.spv");
pub const DEPTH_ALPHA_FS: &[u8] = include_bytes!("../../../shaders/spv/depth_alpha.frag.spv");
pub const FORWARD_VS: &[u8] = include_bytes!("../../../shaders/spv/forward.vert.spv");
pub const FORWARD_FS: &[u8] = include_bytes!("../../../shaders/spv/forward.frag.spv");
pub const FORWARD_EARLY_FS: &[u8] = include_bytes!("../../../shaders/spv/forward_early.frag.spv");
pub const FORWARD_COUNT_FS: &[u8] = include_bytes!("../../../shaders/spv/forward_count.frag.spv");
pub const FORWARD_LATE_DEPTH_FS: &[u8] =
    include_bytes!("../../../shaders/spv/forward_late_depth.frag.spv");
pub const FORWARD_COUNT_LATE_FS: &[u8] =
    include_bytes!("../../../shaders/spv/forward_count_late.frag.spv");
pub const VISBUF_VS: &[u8] = include_bytes!("../../../shaders/spv/visbuf.vert.spv");
pub const VISBUF_FS: &[u8] = include_bytes!("../../../shaders/spv/visbuf.frag.spv");
pub const FULLSCREEN_VS: &[u8] = include_bytes!("../../../shaders/spv/fullscreen.vert.spv");
pub const RESOLVE_INPUT_FS: &[u8] =
    include_bytes!("../../../shaders/spv/visbuf_resolve_input.frag.spv");
pub const RESOLVE_SAMPLED_FS: &[u8] =
    include_bytes!("../../../shaders/spv/visbuf_resolve_sampled.frag.spv");
pub const GBUFFER_VS: &[u8] = include_bytes!("../../../shaders/spv/gbuffer.vert.spv");
pub const GBUFFER_FS: &[u8] = include_bytes!("../../../shaders/spv/gbuffer.frag.spv");
pub const GBUFFER_INPUT_FS: &[u8] =
    include_bytes!("../../../shaders/spv/gbuffer_resolve_input.frag.spv");
pub const GBUFFER_SAMPLED_FS: &[u8] =
    include_bytes!("../../../shaders/spv/gbuffer_resolve_sampled.frag.spv");
// The same with the textures as layers of one image (TEXTURE_LAYERS).
pub const DEPTH_ALPHA_LAYERS_FS: &[u8] =
    include_bytes!("../../../shaders/spv/depth_alpha_layers.frag.spv");
pub const FORWARD_LAYERS_FS: &[u8] = include_bytes!("../../../shaders/spv/forward_layers.frag.spv");
pub const FORWARD_EARLY_LAYERS_FS: &[u8] =
    include_bytes!("../../../shaders/spv/forward_early_layers.frag.spv");
pub const FORWARD_COUNT_LAYERS_FS: &[u8] =
    include_bytes!("../../../shaders/spv/forward_count_layers.frag.spv");
pub const FORWARD_LATE_DEPTH_LAYERS_FS: &[u8] =
    include_bytes!("../../../shaders/spv/forward_late_depth_layers.frag.spv");
pub const FORWARD_COUNT_LATE_LAYERS_FS: &[u8] =
    include_bytes!("../../../shaders/spv/forward_count_late_layers.frag.spv");
pub const VISBUF_LAYERS_FS: &[u8] = include_bytes!("../../../shaders/spv/visbuf_layers.frag.spv");
pub const RESOLVE_INPUT_LAYERS_FS: &[u8] =
    include_bytes!("../../../shaders/spv/visbuf_resolve_input_layers.frag.spv");
pub const RESOLVE_SAMPLED_LAYERS_FS: &[u8] =
    include_bytes!("../../../shaders/spv/visbuf_resolve_sampled_layers.frag.spv");
pub const GBUFFER_LAYERS_FS: &[u8] = include_bytes!("../../../shaders/spv/gbuffer_layers.frag.spv");
pub const GBUFFER_INPUT_LAYERS_FS: &[u8] =
    include_bytes!("../../../shaders/spv/gbuffer_resolve_input_layers.frag.spv");
pub const GBUFFER_SAMPLED_LAYERS_FS: &[u8] =
    include_bytes!("../../../shaders/spv/gbuffer_resolve_sampled_layers.frag.spv");
pub const OQ_BOX_VS: &[u8] = include_bytes!("../../../shaders/spv/oq_box.vert.spv");
pub const RASTER_VS: &[u8] = include_bytes!("../../../shaders/spv/raster_occlusion.vert.spv");
pub const RASTER_FS: &[u8] = include_bytes!("../../../shaders/spv/raster_occlusion.frag.spv");
pub const CLASSIFY_CS: &[u8] = include_bytes!("../../../shaders/spv/visbuf_classify.comp.spv");
pub const TILE_VS: &[u8] = include_bytes!("../../../shaders/spv/visbuf_tile.vert.spv");
pub const SHADOW_VS: &[u8] = include_bytes!("../../../shaders/spv/shadow.vert.spv");
pub const SHADOW_ALPHA_VS: &[u8] = include_bytes!("../../../shaders/spv/shadow_alpha.vert.spv");
pub const SHADOW_CULL_CS: &[u8] = include_bytes!("../../../shaders/spv/shadow_cull.comp.spv");
pub const SHADOW_CULL_HIZ_CS: &[u8] =
    include_bytes!("../../../shaders/spv/shadow_cull_hiz.comp.spv");
