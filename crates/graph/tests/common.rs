//! Frames shared by the integration tests.
#![allow(dead_code)]

use tilegraph_graph::*;
use tilegraph_profile::{Profile, ProfileSet};

pub const EXTENT: Extent2d = Extent2d::new(1920, 1080);

pub fn profile(name: &str) -> Profile {
    ProfileSet::embedded()
        .expect("embedded profiles load")
        .get(name)
        .expect("profile exists")
        .clone()
}

/// How the post-process pass reads the scene colour.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PostRead {
    /// Same pixel: an input attachment (can stay on chip).
    SamePixel,
    /// Neighbouring pixels: sampled (cannot merge).
    Neighbours,
}

pub struct ClassicFrame {
    pub graph: GraphBuilder<&'static str>,
    pub depth: ImageId,
    pub scene: ImageId,
    pub swapchain: ImageId,
    pub passes: [PassId; 4],
}

/// Depth pre-pass + opaque + transparent + post into an imported swapchain image.
pub fn classic_frame(post: PostRead) -> ClassicFrame {
    let mut g = GraphBuilder::new();
    let depth = g.create_image("depth", ImageDesc::new(EXTENT, Format::D24_UNORM_S8_UINT));
    let scene = g.create_image(
        "scene_color",
        ImageDesc::new(EXTENT, Format::R16G16B16A16_SFLOAT),
    );
    let swapchain = g.import_image(
        "swapchain",
        ImageDesc::new(EXTENT, Format::B8G8R8A8_SRGB),
        Import::SWAPCHAIN,
    );
    g.export(swapchain);
    let prepass = g
        .raster_pass("depth_prepass", PassClass::DepthPrepass, "depth_prepass")
        .depth_stencil_clear(depth, ClearDepthStencil::REVERSE_Z)
        .id();
    let opaque = g
        .raster_pass("opaque", PassClass::Opaque, "opaque")
        .color_clear(scene, ClearColor::BLACK)
        .depth_stencil_read_only(depth)
        .id();
    let transparent = g
        .raster_pass("transparent", PassClass::Transparent, "transparent")
        .color(scene)
        .depth_stencil_read_only(depth)
        .id();
    let mut post_pass = g.raster_pass("post", PassClass::Post, "post");
    match post {
        PostRead::SamePixel => post_pass.input(scene),
        PostRead::Neighbours => post_pass.sampled(scene),
    };
    let post_id = post_pass.color(swapchain).coverage(Coverage::Full).id();
    ClassicFrame {
        graph: g,
        depth,
        scene,
        swapchain,
        passes: [prepass, opaque, transparent, post_id],
    }
}
