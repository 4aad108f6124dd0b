//! The realistic frame of the compile benchmark (`benches/graph_compile.rs`) and the
//! instruction count (`examples/compile_count.rs`): 10-pass "views" (think main view, shadow
//! cascades, reflection probes) of GPU culling against the previous view's HiZ, depth pre-pass,
//! HiZ build, opaque, alpha-tested, transparent, occlusion queries, bloom at half resolution,
//! tonemap, and a debug overlay nobody reads (pruned). Each view samples the previous view's
//! output, and the last one writes the swapchain.

use tilegraph_graph::{
    ClearColor, ClearDepthStencil, Coverage, Extent2d, Format, GraphBuilder, ImageDesc, Import,
    InitialContent, Layout, PassClass, ResourceState, Retention,
};

pub fn realistic_frame(views: usize) -> GraphBuilder<u32> {
    let full = Extent2d::new(1920, 1080);
    let half = Extent2d::new(960, 540);
    let mut g = GraphBuilder::new();
    let static_input = Import {
        initial: ResourceState::UNDEFINED,
        content: InitialContent::Preserve,
        final_state: ResourceState::UNDEFINED,
    };
    let instances = g.import_buffer("instances", 4 << 20, static_input);
    let geometry = g.import_buffer("geometry", 16 << 20, static_input);
    let camera = g.import_buffer("camera", 4096, static_input);
    let environment = g.import_image(
        "environment",
        ImageDesc::new(Extent2d::new(512, 512), Format::R8G8B8A8_SRGB),
        Import {
            initial: ResourceState::image(
                Layout::ShaderReadOnly,
                tilegraph_graph::PipelineStages::NONE,
                tilegraph_graph::AccessFlags::NONE,
            ),
            ..static_input
        },
    );
    let swapchain = g.import_image(
        "swapchain",
        ImageDesc::new(full, Format::B8G8R8A8_SRGB),
        Import::SWAPCHAIN,
    );
    g.export(swapchain);
    let mut previous = environment;
    let mut previous_hiz = None;
    let mut payload = 0u32;
    let mut next = || {
        payload += 1;
        payload
    };
    for v in 0..views {
        let args = g.create_buffer(format!("draw_args{v}"), 256 << 10);
        let depth = g.create_image(
            format!("depth{v}"),
            ImageDesc::new(full, Format::D24_UNORM_S8_UINT),
        );
        let hiz = g.create_image(
            format!("hiz{v}"),
            ImageDesc::new(half, Format::R32_SFLOAT).with_mip_levels(half.full_mip_count()),
        );
        let hdr = g.create_image(
            format!("hdr{v}"),
            ImageDesc::new(full, Format::B10G11R11_UFLOAT_PACK32),
        );
        let bloom = g.create_image(
            format!("bloom{v}"),
            ImageDesc::new(half, Format::B10G11R11_UFLOAT_PACK32),
        );
        let ldr = if v + 1 == views {
            swapchain
        } else {
            g.create_image(
                format!("ldr{v}"),
                ImageDesc::new(full, Format::R8G8B8A8_UNORM),
            )
        };
        let debug = g.create_image(
            format!("debug{v}"),
            ImageDesc::new(full, Format::R8G8B8A8_UNORM),
        );

        // Culling tests against the previous view's HiZ pyramid.
        let mut cull = g.compute_pass(format!("cull{v}"), PassClass::Compute, next());
        cull.storage_read(instances)
            .uniform(camera)
            .storage_write(args)
            .coverage(Coverage::Full);
        if let Some(hiz) = previous_hiz {
            cull.sampled(hiz);
        }
        g.raster_pass(format!("depth_prepass{v}"), PassClass::DepthPrepass, next())
            .indirect(args)
            .vertex(geometry)
            .index(geometry)
            .depth_stencil_clear(depth, ClearDepthStencil::REVERSE_Z);
        g.compute_pass(format!("hiz{v}"), PassClass::Compute, next())
            .sampled(depth)
            .storage_read_write(hiz)
            .coverage(Coverage::Full);
        g.raster_pass(format!("opaque{v}"), PassClass::Opaque, next())
            .indirect(args)
            .vertex(geometry)
            .index(geometry)
            .uniform(camera)
            .sampled(previous)
            .color_clear(hdr, ClearColor::BLACK)
            .depth_stencil_read_only(depth);
        g.raster_pass(format!("alpha_tested{v}"), PassClass::AlphaTested, next())
            .vertex(geometry)
            .index(geometry)
            .color(hdr)
            .depth_stencil(depth);
        g.raster_pass(format!("transparent{v}"), PassClass::Transparent, next())
            .vertex(geometry)
            .index(geometry)
            .uniform(camera)
            .color(hdr)
            .depth_stencil_read_only(depth);
        g.raster_pass(format!("occlusion{v}"), PassClass::OcclusionQuery, next())
            .vertex(geometry)
            .depth_stencil_read_only(depth)
            .retention(Retention::Always);
        g.raster_pass(format!("bloom{v}"), PassClass::Post, next())
            .sampled(hdr)
            .color(bloom)
            .coverage(Coverage::Full);
        g.raster_pass(format!("tonemap{v}"), PassClass::Post, next())
            .sampled(hdr)
            .sampled(bloom)
            .color(ldr)
            .coverage(Coverage::Full);
        g.raster_pass(format!("debug{v}"), PassClass::Other, next())
            .sampled(ldr)
            .color(debug)
            .coverage(Coverage::Full);
        previous = ldr;
        previous_hiz = Some(hiz);
    }
    g
}
