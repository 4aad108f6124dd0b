//! The images the scene passes draw into — colour, depth, the visibility buffer's ids, deferred
//! texturing's G-buffer — and which of them a pass of this frame has written yet: the first use
//! of each clears it, every later one keeps what is there. The render targets a renderer owns
//! across frames are made in `images.rs` (re-exported here).

use tilegraph_graph::{ClearColor, ClearDepthStencil, Extent2d, ImageId, RasterPassBuilder};
use tilegraph_scene::DepthConvention;

use crate::frame::Payload;

/// The scene's attachments in one frame's graph.
#[derive(Debug, Clone)]
pub struct SceneTargets {
    pub color: ImageId,
    pub depth: ImageId,
    /// The visibility buffer's ids: imported when the caller keeps them, else created by the
    /// first id pass.
    pub ids: Option<ImageId>,
    /// Deferred texturing's G-buffer, created by the first G-buffer pass.
    pub gbuffer: Option<ImageId>,
    /// The light's shadow atlas, when the frame has shadows: every colour pass samples it.
    pub shadow: Option<ImageId>,
    pub extent: Extent2d,
    color_clear: ClearColor,
    depth_clear: ClearDepthStencil,
    color_written: bool,
    depth_written: bool,
}

impl SceneTargets {
    /// Targets that no pass has written yet: colour clears to `clear_color`, depth to the far
    /// plane of `depth_convention`.
    pub fn new(
        color: ImageId,
        depth: ImageId,
        extent: Extent2d,
        clear_color: [f32; 4],
        depth_convention: DepthConvention,
    ) -> Self {
        SceneTargets {
            color,
            depth,
            ids: None,
            gbuffer: None,
            shadow: None,
            extent,
            color_clear: ClearColor::Float(clear_color),
            depth_clear: ClearDepthStencil {
                depth: depth_convention.far_depth(),
                stencil: 0,
            },
            color_written: false,
            depth_written: false,
        }
    }

    /// Whether a pass of this frame drew colour.
    pub fn color_written(&self) -> bool {
        self.color_written
    }

    /// Whether a pass of this frame wrote depth (there is something to test against).
    pub fn depth_written(&self) -> bool {
        self.depth_written
    }

    /// The depth clear value (the far plane).
    pub fn depth_clear(&self) -> ClearDepthStencil {
        self.depth_clear
    }

    /// Attaches the colour target to `pass`: cleared by the frame's first colour pass.
    /// Colour passes shade, and shading samples the shadow atlas when there is one.
    pub fn attach_color(&mut self, pass: &mut RasterPassBuilder<'_, Payload>) {
        if let Some(atlas) = self.shadow {
            pass.sampled(atlas);
        }
        if self.color_written {
            pass.color(self.color);
        } else {
            pass.color_clear(self.color, self.color_clear);
            self.color_written = true;
        }
    }

    /// Attaches depth to `pass`, tested and written, or tested only (`read_only`): cleared by
    /// the frame's first depth pass, which always writes.
    pub fn attach_depth(&mut self, pass: &mut RasterPassBuilder<'_, Payload>, read_only: bool) {
        if !self.depth_written {
            pass.depth_stencil_clear(self.depth, self.depth_clear);
            self.depth_written = true;
        } else if read_only {
            pass.depth_stencil_read_only(self.depth);
        } else {
            pass.depth_stencil(self.depth);
        }
    }
}

pub use crate::images::{create_image_2d, create_target, destroy_target};
