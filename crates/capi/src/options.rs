//! What a renderer's or a view's description asks for, as `RenderOptions` — or what is wrong
//! with it.

use tilegraph_passes::shadow::{CasterCulling, ShadowOptions};
use tilegraph_passes::{RenderOptions, VisbufResolve};

use crate::context::{culling, technique};
use crate::pvs::TgPvs;
use crate::status::Failure;

/// A further view: what it draws and how (the scene-wide choices — light, GPU timing,
/// instance capacity — are the renderer's).
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct TgViewDesc {
    /// A TgTechnique.
    pub technique: u32,
    /// A TgCulling.
    pub culling: u32,
    /// The size of the view's image.
    pub width: u32,
    pub height: u32,
    pub clear_color: [f32; 4],
    /// As `TgRendererDesc::visbuf_resolve`.
    pub visbuf_resolve: u32,
    /// The view's own shadow cascades of the renderer's light, as in `TgRendererDesc` (0: the
    /// view draws no shadows).
    pub shadow_cascades: u32,
    pub shadow_resolution: u32,
    /// A TgShadowCulling.
    pub shadow_culling: u32,
    /// The visible set TG_CULLING_PVS draws from (a zero handle: none; other cullings ignore
    /// it), and how many cells around the camera's join their sets to its own (0: its cell
    /// only; 1 is what `tilegraph` uses by default; more trades drawn instances for fewer
    /// misses, docs/ACCURACY.md).
    pub pvs: TgPvs,
    pub pvs_dilation: u32,
    /// Level of detail: each instance drawn with the coarsest simplified level of its mesh
    /// whose error projects to at most this many pixels (0: full detail). The levels come with
    /// the scene's clusters (`tg_scene_attach_clusters`); TG_CULLING_FRUSTUM, _HIZ,
    /// _HIZ_TWO_PHASE and _REPROJECT choose them (docs/CULLING.md, "Levels of detail").
    pub lod_error_px: f32,
    /// Level of detail's switching band, a fraction of `lod_error_px`: an instance moves to a
    /// coarser level than last frame's only once that level's error projects within
    /// `lod_error_px * (1 - band)`, so that one near a threshold does not flip levels from frame
    /// to frame (docs/CULLING.md, "Levels of detail"). 0: the default, 0.2; negative: no band.
    pub lod_hysteresis: f32,
}

/// The options of a view (the renderer's own camera's too): technique, culling, size, clear
/// colour, the visibility buffer's resolve, shadows, a visible set — or what is wrong with them.
pub(crate) fn view_options(desc: &TgViewDesc) -> Result<RenderOptions, Failure> {
    Ok(RenderOptions {
        technique: technique(desc.technique)?,
        culling: culling(desc.culling)?,
        width: desc.width,
        height: desc.height,
        clear_color: desc.clear_color,
        visbuf_resolve: visbuf_resolve(desc.visbuf_resolve)?,
        shadows: shadows(
            desc.shadow_cascades,
            desc.shadow_resolution,
            desc.shadow_culling,
        )?,
        pvs: crate::pvs::of(desc.pvs, "desc->pvs")?,
        pvs_dilation: desc.pvs_dilation,
        lod_error_px: desc.lod_error_px,
        lod_hysteresis: lod_hysteresis(desc.lod_hysteresis),
        ..RenderOptions::default()
    })
}

/// The band of a desc's `lod_hysteresis`: 0 the default, negative none (what is out of range
/// the renderer refuses, saying why).
fn lod_hysteresis(raw: f32) -> f32 {
    if raw == 0.0 {
        RenderOptions::default().lod_hysteresis
    } else if raw < 0.0 {
        0.0
    } else {
        raw
    }
}

/// The visibility buffer's resolve of a desc's `visbuf_resolve`, or what is wrong with it.
fn visbuf_resolve(raw: u32) -> Result<Option<VisbufResolve>, Failure> {
    Ok(match raw {
        0 => None,
        1 => Some(VisbufResolve::Uber),
        2 => Some(VisbufResolve::PerMaterial),
        3 => Some(VisbufResolve::Classified),
        v => {
            return Err(Failure::invalid(format!(
                "`desc->visbuf_resolve` {v} is not 0 to 3"
            )))
        }
    })
}

/// The shadow options of a desc's `shadow_*` fields, or what is wrong with them.
fn shadows(cascades: u32, resolution: u32, culling: u32) -> Result<ShadowOptions, Failure> {
    if cascades > 4 {
        return Err(Failure::invalid(format!(
            "`desc->shadow_cascades` {cascades} is not 0 to 4"
        )));
    }
    let resolution = match resolution {
        0 => 1024,
        r @ 64..=4096 => r,
        r => {
            return Err(Failure::invalid(format!(
                "`desc->shadow_resolution` {r} is not 0 or 64 to 4096"
            )))
        }
    };
    let culling = match culling {
        0 => CasterCulling::Receivers,
        1 => CasterCulling::None,
        2 => CasterCulling::Cascade,
        3 => CasterCulling::ReceiversHiz,
        c => {
            return Err(Failure::invalid(format!(
                "`desc->shadow_culling` {c} is no TgShadowCulling"
            )))
        }
    };
    Ok(ShadowOptions {
        cascades,
        resolution,
        culling,
        ..ShadowOptions::default()
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_view_asks_for_levels_of_detail_by_error_in_pixels() {
        let desc = TgViewDesc {
            technique: 0,
            culling: 3,
            width: 64,
            height: 32,
            clear_color: [0.0; 4],
            visbuf_resolve: 0,
            shadow_cascades: 0,
            shadow_resolution: 0,
            shadow_culling: 0,
            pvs: TgPvs { raw: 0 },
            pvs_dilation: 0,
            lod_error_px: 2.0,
            lod_hysteresis: 0.0,
        };
        let Ok(options) = view_options(&desc) else {
            panic!("refused");
        };
        assert_eq!(options.lod_error_px, 2.0);
        assert_eq!(options.lod_hysteresis, 0.2, "0 is the default band");
        let none = TgViewDesc {
            lod_hysteresis: -1.0,
            ..desc
        };
        assert!(view_options(&none).is_ok_and(|o| o.lod_hysteresis == 0.0));
        let full = TgViewDesc {
            lod_error_px: 0.0,
            ..desc
        };
        assert!(view_options(&full).is_ok_and(|o| o.lod_error_px == 0.0));
    }
}
