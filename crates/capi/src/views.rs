//! Further views of a renderer's frame: a second camera (a mirror, a minimap, a second
//! player) rendered in the same recorded frame, on the same graph, into an image the renderer
//! keeps and the engine reads or samples.

use tilegraph_passes::ViewId;
use tilegraph_scene::Scene;
use tilegraph_vk::ash::vk::Handle;

use crate::context::ContextObject;
use crate::options::{view_options, TgViewDesc};
use crate::registry::{self, Kind};
use crate::renderer::{RendererObject, TgRenderer};
use crate::scene::TgCamera;
use crate::status::{arg, boundary, out, Failure, TgStatus};

/// The image a view renders into, kept by the renderer. After each recorded frame it is in
/// `VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL`, its last writes made visible to transfer reads
/// (`VK_PIPELINE_STAGE_2_COPY_BIT`, `VK_ACCESS_2_TRANSFER_READ_BIT`): copy it, or move it to
/// a shader read with a barrier of the engine's and back before the next frame.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default)]
pub struct TgViewImage {
    /// VkImage.
    pub image: u64,
    /// VkImageView.
    pub view: u64,
    /// VkFormat.
    pub format: i32,
    pub width: u32,
    pub height: u32,
    /// VkImageLayout after a frame.
    pub layout: i32,
}

/// Adds a view to the renderer's frames from the next recorded one: `camera` seen as `desc`
/// says, into an image of the renderer's (`tg_renderer_view_image`). Waits for the device and
/// makes the renderer's buffers again (add views before the first frame where that matters).
/// `out_view` receives the view's index (1, 2, ...; the renderer's own camera is view 0).
///
/// # Safety
/// `desc` and `camera` are valid; `out_view` is writable.
#[no_mangle]
pub unsafe extern "C" fn tg_renderer_add_view(
    renderer: TgRenderer,
    desc: *const TgViewDesc,
    camera: *const TgCamera,
    out_view: *mut u32,
) -> TgStatus {
    boundary("tg_renderer_add_view", || {
        // SAFETY: the caller's contract.
        let (desc, camera) = unsafe { (arg(desc, "desc")?, arg(camera, "camera")?) };
        // SAFETY: as above.
        let out_view = unsafe { out(out_view, "out_view") }?;
        *out_view = 0;
        if desc.width == 0 || desc.height == 0 {
            return Err(Failure::invalid(format!(
                "width {} and height {} must be non-zero",
                desc.width, desc.height
            )));
        }
        let camera = camera.to_camera()?;
        let options = view_options(desc)?;
        let mut r = registry::take::<RendererObject>(renderer.raw, Kind::Renderer, "renderer")?;
        let result = registry::with2(
            (r.context, Kind::Context, "context"),
            (r.scene, Kind::Scene, "scene"),
            |c: &ContextObject, s: &Scene| Ok(r.renderer.add_view(&c.ctx, s, options, &camera)?),
        );
        registry::put_back(renderer.raw, Kind::Renderer, r);
        *out_view = result?.index() as u32;
        Ok(())
    })
}

/// `view`'s camera for the next recorded frame; `cut` non-zero: the camera jumped (nothing of
/// the view's last frame applies). A view keeps its camera until this is called again.
///
/// # Safety
/// `camera` is valid.
#[no_mangle]
pub unsafe extern "C" fn tg_renderer_set_view_camera(
    renderer: TgRenderer,
    view: u32,
    camera: *const TgCamera,
    cut: u32,
) -> TgStatus {
    boundary("tg_renderer_set_view_camera", || {
        // SAFETY: the caller's contract.
        let camera = unsafe { arg(camera, "camera") }?.to_camera()?;
        registry::with_mut(
            renderer.raw,
            Kind::Renderer,
            "renderer",
            |r: &mut RendererObject| {
                Ok(r.renderer
                    .set_view_camera(ViewId::new(view), &camera, cut != 0)?)
            },
        )
    })
}

/// The image `view` renders into.
///
/// # Safety
/// `out_image` is writable.
#[no_mangle]
pub unsafe extern "C" fn tg_renderer_view_image(
    renderer: TgRenderer,
    view: u32,
    out_image: *mut TgViewImage,
) -> TgStatus {
    boundary("tg_renderer_view_image", || {
        // SAFETY: the caller's contract.
        let out_image = unsafe { out(out_image, "out_image") }?;
        registry::with(
            renderer.raw,
            Kind::Renderer,
            "renderer",
            |r: &RendererObject| {
                let h = r.renderer.view_target(ViewId::new(view))?;
                *out_image = TgViewImage {
                    image: h.raw.as_raw(),
                    view: h.view.as_raw(),
                    format: h.format.as_raw(),
                    width: h.extent.width,
                    height: h.extent.height,
                    layout: tilegraph_vk::ash::vk::ImageLayout::TRANSFER_SRC_OPTIMAL.as_raw(),
                };
                Ok(())
            },
        )
    })
}
