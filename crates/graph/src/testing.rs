//! Helpers for the unit tests next to each phase.

use tilegraph_profile::{MergePolicy, Profile, ProfileSet};

use crate::*;

/// Small extent: byte counts in assertions stay readable (64 * 32 = 2048 pixels).
pub(crate) const EXTENT: Extent2d = Extent2d::new(64, 32);
pub(crate) const PIXELS: u64 = 64 * 32;

pub(crate) fn profile(name: &str) -> Profile {
    ProfileSet::embedded()
        .expect("embedded profiles load")
        .get(name)
        .expect("profile exists")
        .clone()
}

pub(crate) fn tiler() -> Profile {
    profile("adreno-7xx")
}

pub(crate) fn desktop() -> Profile {
    profile("desktop-nvidia")
}

/// adreno-7xx with merging switched off.
pub(crate) fn never_merge() -> Profile {
    let mut p = tiler();
    p.render_pass.merge_subpasses = MergePolicy::Never;
    p
}

pub(crate) fn rgba8<P>(g: &mut GraphBuilder<P>, name: &str) -> ImageId {
    g.create_image(name, ImageDesc::new(EXTENT, Format::R8G8B8A8_UNORM))
}

pub(crate) fn d24s8<P>(g: &mut GraphBuilder<P>, name: &str) -> ImageId {
    g.create_image(name, ImageDesc::new(EXTENT, Format::D24_UNORM_S8_UINT))
}

/// An imported swapchain-like image, exported.
pub(crate) fn swapchain<P>(g: &mut GraphBuilder<P>) -> ImageId {
    let id = g.import_image(
        "swapchain",
        ImageDesc::new(EXTENT, Format::B8G8R8A8_SRGB),
        Import::SWAPCHAIN,
    );
    g.export(id);
    id
}

/// An imported image whose content is kept (history), in `ShaderReadOnly`.
pub(crate) fn history<P>(g: &mut GraphBuilder<P>, name: &str) -> ImageId {
    g.import_image(
        name,
        ImageDesc::new(EXTENT, Format::R8G8B8A8_UNORM),
        Import {
            initial: ResourceState::SHADER_READ,
            content: InitialContent::Preserve,
            final_state: ResourceState::SHADER_READ,
        },
    )
}

pub(crate) fn compile(g: GraphBuilder<()>, profile: &Profile) -> Plan {
    match g.compile(profile) {
        Ok(c) => c.plan,
        Err(e) => panic!("compile failed: {e}"),
    }
}

pub(crate) fn compile_err(g: GraphBuilder<()>, profile: &Profile) -> GraphError {
    match g.compile(profile) {
        Ok(c) => panic!("compile succeeded:\n{}", c.plan),
        Err(e) => e,
    }
}

pub(crate) fn order(plan: &Plan) -> Vec<&str> {
    plan.passes.iter().map(|p| p.name.as_str()).collect()
}

/// Every render pass attachment of the named resource, in step order.
pub(crate) fn attachments<'p>(plan: &'p Plan, name: &str) -> Vec<&'p Attachment> {
    let Some(r) = plan.resource_by_name(name) else {
        panic!("no resource {name}")
    };
    plan.render_passes()
        .flat_map(|(_, rp)| rp.attachments.iter())
        .filter(|a| a.resource == r.id)
        .collect()
}

/// The only attachment of the named resource.
pub(crate) fn attachment<'p>(plan: &'p Plan, name: &str) -> &'p Attachment {
    let all = attachments(plan, name);
    assert_eq!(
        all.len(),
        1,
        "{name} is attached {} times:\n{plan}",
        all.len()
    );
    all[0]
}

/// One barrier of a resource, image or buffer, with the step it is in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct SeenBarrier {
    pub step: usize,
    pub hazard: Hazard,
    pub src: (PipelineStages, AccessFlags),
    pub dst: (PipelineStages, AccessFlags),
    /// `(old, new)` for images.
    pub layouts: Option<(Layout, Layout)>,
}

/// Every barrier of the named resource, in step order.
pub(crate) fn barriers_of(plan: &Plan, name: &str) -> Vec<SeenBarrier> {
    let Some(r) = plan.resource_by_name(name) else {
        panic!("no resource {name}")
    };
    let mut out = Vec::new();
    for (step, s) in plan.steps.iter().enumerate() {
        let Step::Barriers(batch) = s else { continue };
        for b in batch.images.iter().filter(|b| b.resource == r.id) {
            out.push(SeenBarrier {
                step,
                hazard: b.hazard,
                src: (b.src_stages, b.src_access),
                dst: (b.dst_stages, b.dst_access),
                layouts: Some((b.old_layout, b.new_layout)),
            });
        }
        for b in batch.buffers.iter().filter(|b| b.resource == r.id) {
            out.push(SeenBarrier {
                step,
                hazard: b.hazard,
                src: (b.src_stages, b.src_access),
                dst: (b.dst_stages, b.dst_access),
                layouts: None,
            });
        }
    }
    out
}

/// prepass -> opaque -> post reading the colour at the same pixel (one render pass of three
/// subpasses on a tiler), and its depth image.
pub(crate) fn same_pixel_chain() -> (GraphBuilder<()>, ImageId) {
    let mut g = GraphBuilder::new();
    let depth = d24s8(&mut g, "depth");
    let color = rgba8(&mut g, "color");
    let out = swapchain(&mut g);
    g.raster_pass("prepass", PassClass::DepthPrepass, ())
        .depth_stencil_clear(depth, ClearDepthStencil::REVERSE_Z);
    g.raster_pass("opaque", PassClass::Opaque, ())
        .color_clear(color, ClearColor::BLACK)
        .depth_stencil_read_only(depth);
    g.raster_pass("post", PassClass::Post, ())
        .input(color)
        .color(out)
        .coverage(Coverage::Full);
    (g, depth)
}
