//! `validate_declarations`: checks every declaration — resources, each use against its
//! resource, the attachments of each raster pass, dependencies and exports — and merges each
//! pass's uses into one access per resource (`compile/access.rs`), which every later phase
//! reads. Errors name the pass and resource.

use tilegraph_profile::Profile;

use super::access::{
    add_access, role, summarize_use, Access, PassAccesses, BUFFER_READ_ROLES, COLOR_ROLE,
    DEPTH_STENCIL_ROLES, INPUT_ROLE, RESOLVE_ROLE,
};
use crate::declare::{
    Origin, PassDecl, PassId, PassKind, PassUse, ResourceDecl, ResourceDesc, ResourceId, UseKind,
};
use crate::error::GraphError;
use crate::types::{Extent2d, Layout};

/// Larger than any `maxImageDimension2D` a driver reports.
pub(crate) const MAX_EXTENT_PX: u32 = 32_768;
/// 256 TiB: far beyond any GPU, small enough that sums of sizes cannot overflow in practice.
pub(crate) const MAX_BUFFER_BYTES: u64 = 1 << 48;

const NONE: u32 = u32::MAX;

/// The validated declarations: one access per pass and resource, and each raster pass's
/// render area.
#[derive(Debug)]
pub(crate) struct Validated {
    pub accesses: PassAccesses,
    /// Render area of each raster pass (index = `PassId`).
    pub render_areas: Vec<Option<Extent2d>>,
}

fn imported_layout(r: &ResourceDecl) -> Option<Layout> {
    match r.origin {
        Origin::Imported(import) => Some(import.initial.layout),
        Origin::Created => None,
    }
}

fn validate_resource(r: &ResourceDecl) -> Result<(), GraphError> {
    let reason = match &r.desc {
        ResourceDesc::Image(d) => {
            let e = d.extent_px;
            if e.width_px == 0 || e.height_px == 0 {
                Some("zero extent")
            } else if e.width_px > MAX_EXTENT_PX || e.height_px > MAX_EXTENT_PX {
                Some("extent over 32768 px")
            } else if d.mip_levels == 0 {
                Some("zero mip levels")
            } else if d.mip_levels > e.full_mip_count() {
                Some("more mip levels than the extent has")
            } else if d.mip_levels > 1 && d.samples.count() > 1 {
                Some("a multisampled image has one mip level")
            } else if r.has_initial_content() && imported_layout(r) == Some(Layout::Undefined) {
                Some("content to preserve, but imported in the Undefined layout (the first transition would discard it)")
            } else {
                None
            }
        }
        ResourceDesc::Buffer(d) => {
            if d.size_bytes == 0 {
                Some("zero size")
            } else if d.size_bytes > MAX_BUFFER_BYTES {
                Some("size over 2^48 bytes")
            } else {
                None
            }
        }
    };
    match reason {
        Some(reason) => Err(GraphError::InvalidResource {
            resource: r.name.clone(),
            reason,
        }),
        None => Ok(()),
    }
}

/// Uses that need an image.
const IMAGE_ROLES: u16 =
    COLOR_ROLE | DEPTH_STENCIL_ROLES | INPUT_ROLE | RESOLVE_ROLE | role(UseKind::Sampled);
/// Uses that need a buffer.
const BUFFER_ROLES: u16 = BUFFER_READ_ROLES;
/// Uses that need a colour format.
const COLOR_FORMAT_ROLES: u16 = COLOR_ROLE | RESOLVE_ROLE;
/// Uses that need a depth-stencil format.
const DEPTH_FORMAT_ROLES: u16 = DEPTH_STENCIL_ROLES;

/// The uses a resource can take: one mask test per use.
fn allowed_roles(desc: &ResourceDesc) -> u16 {
    match desc {
        ResourceDesc::Buffer(_) => !IMAGE_ROLES,
        ResourceDesc::Image(d) if d.format.is_depth_stencil() => {
            !(BUFFER_ROLES | COLOR_FORMAT_ROLES)
        }
        ResourceDesc::Image(_) => !(BUFFER_ROLES | DEPTH_FORMAT_ROLES),
    }
}

#[cold]
fn use_target_mismatch(pass: &PassDecl, kind: &UseKind, r: &ResourceDecl) -> GraphError {
    let format = match &r.desc {
        ResourceDesc::Buffer(_) => "a buffer",
        ResourceDesc::Image(_) if kind.bit() & BUFFER_ROLES != 0 => "an image",
        ResourceDesc::Image(d) => d.format.name(),
    };
    GraphError::FormatMismatch {
        pass: pass.name.clone(),
        resource: r.name.clone(),
        format,
        usage: kind.name(),
    }
}

/// What the attachment checks of one raster pass have seen so far.
struct RasterCheck {
    area: Option<Extent2d>,
    samples: Option<u32>,
    colors: u32,
    depth: Option<ResourceId>,
}

impl RasterCheck {
    fn new(pass: &PassDecl) -> Self {
        RasterCheck {
            area: pass.render_area,
            samples: None,
            colors: 0,
            depth: None,
        }
    }

    /// Checks the attachment use `pass.uses[i]` of `r` against the pass's other attachments.
    fn attachment(
        &mut self,
        pass: &PassDecl,
        i: usize,
        u: &PassUse,
        r: &ResourceDecl,
        resources: &[ResourceDecl],
    ) -> Result<(), GraphError> {
        if matches!(
            u.kind,
            UseKind::DepthStencilAttachment { .. } | UseKind::DepthStencilReadOnly
        ) {
            match self.depth {
                Some(first) if first != u.resource => {
                    return Err(GraphError::SecondDepthStencil {
                        pass: pass.name.clone(),
                        first: resources[first.index()].name.clone(),
                        second: r.name.clone(),
                    })
                }
                _ => self.depth = Some(u.resource),
            }
        }
        let Some(desc) = r.desc.image() else {
            return Ok(());
        };
        if desc.mip_levels > 1 {
            return Err(GraphError::MipmappedAttachment {
                pass: pass.name.clone(),
                resource: r.name.clone(),
                mip_levels: desc.mip_levels,
            });
        }
        let extent = desc.extent_px;
        match self.area {
            None => self.area = Some(extent),
            Some(expected) if expected != extent => {
                return Err(GraphError::ExtentMismatch {
                    pass: pass.name.clone(),
                    resource: r.name.clone(),
                    expected_px: expected,
                    found_px: extent,
                })
            }
            Some(_) => {}
        }
        let counts_samples = matches!(
            u.kind,
            UseKind::ColorAttachment { .. }
                | UseKind::DepthStencilAttachment { .. }
                | UseKind::DepthStencilReadOnly
        );
        if counts_samples {
            let found = desc.samples.count();
            match self.samples {
                None => self.samples = Some(found),
                Some(expected) if expected != found => {
                    return Err(GraphError::SampleCountMismatch {
                        pass: pass.name.clone(),
                        resource: r.name.clone(),
                        expected,
                        found,
                    })
                }
                Some(_) => {}
            }
        }
        if matches!(u.kind, UseKind::ColorAttachment { .. }) {
            self.colors += 1;
        }
        if let UseKind::ResolveTarget { source } = u.kind {
            check_resolve(pass, i, resources, source, u.resource)?;
        }
        Ok(())
    }

    /// Checks the pass as a whole and returns its render area.
    fn finish(self, pass: &PassDecl, profile: &Profile) -> Result<Extent2d, GraphError> {
        let max = profile.render_pass.max_color_attachments;
        if self.colors > max {
            return Err(GraphError::TooManyColorAttachments {
                pass: pass.name.clone(),
                count: self.colors,
                max,
                profile: profile.name.clone(),
            });
        }
        let area = self.area.ok_or_else(|| GraphError::MissingRenderArea {
            pass: pass.name.clone(),
        })?;
        // Attachments are checked as resources; a declared area without any must be checked
        // here.
        let sides = [area.width_px, area.height_px];
        if sides.iter().any(|&side| side == 0 || side > MAX_EXTENT_PX) {
            return Err(GraphError::InvalidRenderArea {
                pass: pass.name.clone(),
                extent_px: area,
            });
        }
        Ok(area)
    }
}

/// Checks the resolve declared by `pass.uses[use_index]`.
fn check_resolve(
    pass: &PassDecl,
    use_index: usize,
    resources: &[ResourceDecl],
    source: ResourceId,
    target: ResourceId,
) -> Result<(), GraphError> {
    let target_decl = &resources[target.index()];
    let Some(source_decl) = resources.get(source.index()) else {
        return Err(GraphError::UnknownResource {
            pass: pass.name.clone(),
            index: source.0,
        });
    };
    let fail = |reason| GraphError::InvalidResolve {
        pass: pass.name.clone(),
        source_image: source_decl.name.clone(),
        target: target_decl.name.clone(),
        reason,
    };
    let is_color_of_pass = pass
        .uses
        .iter()
        .any(|u| u.resource == source && matches!(u.kind, UseKind::ColorAttachment { .. }));
    if !is_color_of_pass {
        return Err(fail("the source is not a colour attachment of the pass"));
    }
    // A colour attachment has one resolve attachment: a second would be left out of the
    // subpass and its target never written.
    let resolved_before = pass.uses[..use_index]
        .iter()
        .any(|u| matches!(u.kind, UseKind::ResolveTarget { source: s } if s == source));
    if resolved_before {
        return Err(fail("the source is already resolved into another image"));
    }
    let (Some(s), Some(t)) = (source_decl.desc.image(), target_decl.desc.image()) else {
        return Err(fail("both must be images"));
    };
    if s.samples.count() == 1 {
        return Err(fail("the source is not multisampled"));
    }
    if t.samples.count() != 1 {
        return Err(fail("the target is multisampled"));
    }
    if s.format != t.format {
        return Err(fail("the formats differ"));
    }
    Ok(())
}

pub(crate) fn validate_declarations(
    resources: &[ResourceDecl],
    passes: &[PassDecl],
    exports: &[ResourceId],
    dependencies: &[(PassId, PassId)],
    profile: &Profile,
) -> Result<Validated, GraphError> {
    for r in resources {
        validate_resource(r)?;
    }

    let total_uses: usize = passes.iter().map(|p| p.uses.len()).sum();
    let mut accesses: Vec<Access> = Vec::with_capacity(total_uses);
    let mut pass_ranges = Vec::with_capacity(passes.len());
    let mut render_areas = Vec::with_capacity(passes.len());
    // Per resource: (pass, index in `accesses`) of the last pass's access to it.
    let mut access_of = vec![(NONE, NONE); resources.len()];
    for (p, pass) in passes.iter().enumerate() {
        let start = accesses.len();
        let raster = pass.kind == PassKind::Raster;
        let mut attachments = RasterCheck::new(pass);
        for (i, u) in pass.uses.iter().enumerate() {
            let Some(r) = resources.get(u.resource.index()) else {
                return Err(GraphError::UnknownResource {
                    pass: pass.name.clone(),
                    index: u.resource.0,
                });
            };
            let a = summarize_use(pass.kind, pass.coverage, u, i as u32, &r.desc);
            // The use fits the resource (image vs buffer, colour vs depth format).
            if allowed_roles(&r.desc) & a.roles == 0 {
                return Err(use_target_mismatch(pass, &u.kind, r));
            }
            if raster && a.attachment() {
                attachments.attachment(pass, i, u, r, resources)?;
            }
            // The pass's access to the resource so far, if any.
            let seen = &mut access_of[u.resource.index()];
            let existing = if seen.0 == p as u32 {
                Some(seen.1 as usize)
            } else {
                *seen = (p as u32, accesses.len() as u32);
                None
            };
            add_access(&mut accesses, existing, a, &pass.uses).map_err(|c| {
                GraphError::ConflictingUses {
                    pass: pass.name.clone(),
                    resource: r.name.clone(),
                    first: c.first,
                    second: c.second,
                }
            })?;
        }
        pass_ranges.push((start as u32, accesses.len() as u32));
        render_areas.push(if raster {
            Some(attachments.finish(pass, profile)?)
        } else {
            None
        });
    }

    for &(before, after) in dependencies {
        for id in [before, after] {
            if id.index() >= passes.len() {
                return Err(GraphError::UnknownPass { index: id.0 });
            }
        }
    }
    for &e in exports {
        if e.index() >= resources.len() {
            return Err(GraphError::ExportOfUnknownResource { index: e.0 });
        }
    }

    Ok(Validated {
        accesses: PassAccesses {
            accesses,
            ranges: pass_ranges,
        },
        render_areas,
    })
}

#[cfg(test)]
mod tests {
    use crate::testing::*;
    use crate::*;

    #[test]
    fn a_write_and_another_use_of_one_resource_conflict() {
        let mut g = GraphBuilder::new();
        let img = rgba8(&mut g, "feedback");
        g.export(img);
        g.raster_pass("loop", PassClass::Post, ())
            .color_clear(img, ClearColor::BLACK)
            .sampled(img);
        assert_eq!(
            compile_err(g, &tiler()),
            GraphError::ConflictingUses {
                pass: "loop".into(),
                resource: "feedback".into(),
                first: "color",
                second: "sampled",
            }
        );

        let mut g = GraphBuilder::new();
        let buf = g.create_buffer("counts", 256);
        g.export(buf);
        g.compute_pass("count", PassClass::Compute, ())
            .storage_write(buf)
            .storage_read(buf);
        assert!(matches!(
            compile_err(g, &tiler()),
            GraphError::ConflictingUses {
                first: "storage-w",
                second: "storage-r",
                ..
            }
        ));
    }

    #[test]
    fn reads_that_agree_on_the_layout_combine() {
        // One buffer as vertex and index data, depth tested and sampled (soft particles),
        // storage read-write as one use: none of these conflict.
        let mut g = GraphBuilder::new();
        let mesh = g.import_buffer(
            "mesh",
            4096,
            Import {
                initial: ResourceState::UNDEFINED,
                content: InitialContent::Preserve,
                final_state: ResourceState::UNDEFINED,
            },
        );
        let depth = d24s8(&mut g, "depth");
        let hiz = g.create_image(
            "hiz",
            ImageDesc::new(EXTENT, Format::R32_SFLOAT).with_mip_levels(EXTENT.full_mip_count()),
        );
        let out = swapchain(&mut g);
        g.raster_pass("prepass", PassClass::DepthPrepass, ())
            .vertex(mesh)
            .index(mesh)
            .depth_stencil_clear(depth, ClearDepthStencil::REVERSE_Z);
        g.compute_pass("hiz", PassClass::Compute, ())
            .sampled(depth)
            .storage_read_write(hiz)
            .coverage(Coverage::Full);
        g.raster_pass("particles", PassClass::Transparent, ())
            .vertex(mesh)
            .index(mesh)
            .depth_stencil_read_only(depth)
            .sampled(depth)
            .sampled(hiz)
            .color_clear(out, ClearColor::BLACK);
        let plan = compile(g, &tiler());
        assert_eq!(order(&plan), ["prepass", "hiz", "particles"]);
        assert_eq!(
            plan.resource_by_name("mesh").map(|r| r.usage),
            Some(Usage::Buffer(
                BufferUsage::VERTEX_BUFFER | BufferUsage::INDEX_BUFFER
            ))
        );
    }

    #[test]
    fn attachments_of_one_pass_share_one_extent_and_sample_count() {
        let mut g = GraphBuilder::new();
        let color = rgba8(&mut g, "color");
        let depth = g.create_image(
            "small_depth",
            ImageDesc::new(Extent2d::new(32, 32), Format::D32_SFLOAT),
        );
        g.export(color);
        g.raster_pass("draw", PassClass::Opaque, ())
            .color_clear(color, ClearColor::BLACK)
            .depth_stencil_clear(depth, ClearDepthStencil::REVERSE_Z);
        assert_eq!(
            compile_err(g, &tiler()),
            GraphError::ExtentMismatch {
                pass: "draw".into(),
                resource: "small_depth".into(),
                expected_px: EXTENT,
                found_px: Extent2d::new(32, 32),
            }
        );

        let mut g = GraphBuilder::new();
        let color = rgba8(&mut g, "color");
        let depth = g.create_image(
            "msaa_depth",
            ImageDesc::new(EXTENT, Format::D32_SFLOAT).with_samples(SampleCount::S4),
        );
        g.export(color);
        g.raster_pass("draw", PassClass::Opaque, ())
            .color_clear(color, ClearColor::BLACK)
            .depth_stencil_clear(depth, ClearDepthStencil::REVERSE_Z);
        assert!(matches!(
            compile_err(g, &tiler()),
            GraphError::SampleCountMismatch {
                expected: 1,
                found: 4,
                ..
            }
        ));
    }

    #[test]
    fn color_attachments_are_limited_by_the_profile() {
        let mobile = profile("generic-mobile");
        assert_eq!(mobile.render_pass.max_color_attachments, 4);
        let mut g = GraphBuilder::new();
        let targets: Vec<ImageId> = (0..5)
            .map(|i| rgba8(&mut g, &format!("gbuffer{i}")))
            .collect();
        for &t in &targets {
            g.export(t);
        }
        let mut pass = g.raster_pass("gbuffer", PassClass::Opaque, ());
        for &t in &targets {
            pass.color_clear(t, ClearColor::BLACK);
        }
        assert_eq!(
            compile_err(g.clone(), &mobile),
            GraphError::TooManyColorAttachments {
                pass: "gbuffer".into(),
                count: 5,
                max: 4,
                profile: "generic-mobile".into(),
            }
        );
        assert_eq!(compile(g, &tiler()).passes.len(), 1);
    }

    #[test]
    fn a_pass_has_one_depth_stencil_attachment() {
        let mut g = GraphBuilder::new();
        let depth = d24s8(&mut g, "depth");
        let shadow = d24s8(&mut g, "shadow");
        g.export(depth);
        g.raster_pass("prepass", PassClass::DepthPrepass, ())
            .depth_stencil_clear(shadow, ClearDepthStencil::REVERSE_Z);
        g.raster_pass("draw", PassClass::Opaque, ())
            .depth_stencil_clear(depth, ClearDepthStencil::REVERSE_Z)
            .depth_stencil_read_only(shadow);
        assert_eq!(
            compile_err(g, &tiler()),
            GraphError::SecondDepthStencil {
                pass: "draw".into(),
                first: "depth".into(),
                second: "shadow".into(),
            }
        );
    }

    #[test]
    fn formats_must_fit_the_attachment() {
        let mut g = GraphBuilder::new();
        let depth = d24s8(&mut g, "depth");
        g.export(depth);
        g.raster_pass("wrong", PassClass::Opaque, ())
            .color_clear(depth, ClearColor::BLACK);
        assert_eq!(
            compile_err(g, &tiler()),
            GraphError::FormatMismatch {
                pass: "wrong".into(),
                resource: "depth".into(),
                format: "D24S8",
                usage: "color",
            }
        );

        let mut g = GraphBuilder::new();
        let color = rgba8(&mut g, "color");
        g.export(color);
        g.raster_pass("wrong", PassClass::Opaque, ())
            .depth_stencil_clear(color, ClearDepthStencil::REVERSE_Z);
        assert!(matches!(
            compile_err(g, &tiler()),
            GraphError::FormatMismatch { usage: "depth", .. }
        ));
    }

    /// Handles are typed, but their indices are public: a buffer's index in an image handle
    /// (or the reverse) is caught.
    #[test]
    fn images_and_buffers_keep_to_their_uses() {
        let mut g = GraphBuilder::new();
        let params = g.create_buffer("params", 256);
        let out = swapchain(&mut g);
        g.raster_pass("post", PassClass::Post, ())
            .sampled(ImageId(params.0))
            .color(out)
            .coverage(Coverage::Full);
        assert_eq!(
            compile_err(g, &tiler()),
            GraphError::FormatMismatch {
                pass: "post".into(),
                resource: "params".into(),
                format: "a buffer",
                usage: "sampled",
            }
        );

        let mut g = GraphBuilder::new();
        let out = swapchain(&mut g);
        g.raster_pass("draw", PassClass::Opaque, ())
            .vertex(BufferId(out.0))
            .color_clear(out, ClearColor::BLACK);
        assert!(matches!(
            compile_err(g, &tiler()),
            GraphError::FormatMismatch {
                format: "an image",
                usage: "vertex",
                ..
            }
        ));
    }

    #[test]
    fn resolves_need_a_multisampled_colour_of_the_pass() {
        let msaa_desc =
            ImageDesc::new(EXTENT, Format::R8G8B8A8_UNORM).with_samples(SampleCount::S4);
        let cases: [(&str, bool, SampleCount, SampleCount); 3] = [
            (
                "the source is not a colour attachment of the pass",
                false,
                SampleCount::S4,
                SampleCount::S1,
            ),
            (
                "the source is not multisampled",
                true,
                SampleCount::S1,
                SampleCount::S1,
            ),
            (
                "the target is multisampled",
                true,
                SampleCount::S4,
                SampleCount::S4,
            ),
        ];
        for (reason, attach, source_samples, target_samples) in cases {
            let mut g = GraphBuilder::new();
            let msaa = g.create_image("msaa", msaa_desc.with_samples(source_samples));
            let resolved = g.create_image(
                "resolved",
                ImageDesc::new(EXTENT, Format::R8G8B8A8_UNORM).with_samples(target_samples),
            );
            g.export(resolved);
            let mut pass = g.raster_pass("draw", PassClass::Opaque, ());
            if attach {
                pass.color_clear(msaa, ClearColor::BLACK);
            }
            pass.resolve(msaa, resolved);
            assert_eq!(
                compile_err(g, &tiler()),
                GraphError::InvalidResolve {
                    pass: "draw".into(),
                    source_image: "msaa".into(),
                    target: "resolved".into(),
                    reason,
                }
            );
        }
        // One resolve per colour attachment: a second target would be left out of the subpass
        // and never written.
        let mut g = GraphBuilder::new();
        let msaa = g.create_image("msaa", msaa_desc);
        let first = rgba8(&mut g, "first");
        let second = rgba8(&mut g, "second");
        g.export(first);
        g.export(second);
        g.raster_pass("draw", PassClass::Opaque, ())
            .color_clear(msaa, ClearColor::BLACK)
            .resolve(msaa, first)
            .resolve(msaa, second);
        assert_eq!(
            compile_err(g, &tiler()),
            GraphError::InvalidResolve {
                pass: "draw".into(),
                source_image: "msaa".into(),
                target: "second".into(),
                reason: "the source is already resolved into another image",
            }
        );
    }

    /// A render pass writes the one mip level its framebuffer view shows, but layouts are
    /// tracked per image: the other levels would be left in a layout the plan does not know.
    #[test]
    fn attachments_have_one_mip_level() {
        let mut g = GraphBuilder::new();
        let pyramid = g.create_image(
            "pyramid",
            ImageDesc::new(EXTENT, Format::R8G8B8A8_UNORM).with_mip_levels(3),
        );
        g.export(pyramid);
        g.raster_pass("draw", PassClass::Opaque, ())
            .color_clear(pyramid, ClearColor::BLACK);
        assert_eq!(
            compile_err(g, &tiler()),
            GraphError::MipmappedAttachment {
                pass: "draw".into(),
                resource: "pyramid".into(),
                mip_levels: 3
            }
        );
    }

    #[test]
    fn a_raster_pass_needs_a_render_area() {
        let mut g = GraphBuilder::new();
        let queries = g.create_buffer("visible", 64);
        g.export(queries);
        g.raster_pass("raster_cull", PassClass::OcclusionQuery, ())
            .storage_write(queries);
        assert_eq!(
            compile_err(g.clone(), &tiler()),
            GraphError::MissingRenderArea {
                pass: "raster_cull".into()
            }
        );
        let mut g = GraphBuilder::new();
        let queries = g.create_buffer("visible", 64);
        g.export(queries);
        g.raster_pass("raster_cull", PassClass::OcclusionQuery, ())
            .storage_write(queries)
            .render_area(EXTENT);
        assert_eq!(compile(g, &tiler()).passes.len(), 1);
        // A declared area (nothing else checks it without attachments) must be a real extent.
        for extent_px in [Extent2d::new(0, 16), Extent2d::new(64, 40_000)] {
            let mut g = GraphBuilder::new();
            let queries = g.create_buffer("visible", 64);
            g.export(queries);
            g.raster_pass("raster_cull", PassClass::OcclusionQuery, ())
                .storage_write(queries)
                .render_area(extent_px);
            assert_eq!(
                compile_err(g, &tiler()),
                GraphError::InvalidRenderArea {
                    pass: "raster_cull".into(),
                    extent_px
                }
            );
        }
    }

    #[test]
    fn malformed_resources_are_rejected() {
        let cases: [(ImageDesc, &str); 4] = [
            (
                ImageDesc::new(Extent2d::new(0, 16), Format::R8_UNORM),
                "zero extent",
            ),
            (
                ImageDesc::new(Extent2d::new(40_000, 16), Format::R8_UNORM),
                "extent over 32768 px",
            ),
            (
                ImageDesc::new(Extent2d::new(27, 13), Format::R8_UNORM).with_mip_levels(6),
                "more mip levels than the extent has",
            ),
            (
                ImageDesc::new(EXTENT, Format::R8_UNORM)
                    .with_samples(SampleCount::S4)
                    .with_mip_levels(2),
                "a multisampled image has one mip level",
            ),
        ];
        for (desc, reason) in cases {
            let mut g: GraphBuilder<()> = GraphBuilder::new();
            g.create_image("bad", desc);
            assert_eq!(
                compile_err(g, &tiler()),
                GraphError::InvalidResource {
                    resource: "bad".into(),
                    reason
                }
            );
        }
        let mut g: GraphBuilder<()> = GraphBuilder::new();
        g.create_buffer("empty", 0);
        assert!(matches!(
            compile_err(g, &tiler()),
            GraphError::InvalidResource {
                reason: "zero size",
                ..
            }
        ));
        // Content to keep cannot come in Undefined: the first transition would discard it
        // (buffers have no layout: fine).
        let lost = Import {
            initial: ResourceState::UNDEFINED,
            content: InitialContent::Preserve,
            final_state: ResourceState::SHADER_READ,
        };
        let mut g: GraphBuilder<()> = GraphBuilder::new();
        g.import_image(
            "history",
            ImageDesc::new(EXTENT, Format::R8G8B8A8_UNORM),
            lost,
        );
        assert!(matches!(
            compile_err(g, &tiler()),
            GraphError::InvalidResource { reason, .. } if reason.contains("Undefined layout")
        ));
        let mut g: GraphBuilder<()> = GraphBuilder::new();
        let buffer = g.import_buffer("static", 256, lost);
        g.export(buffer);
        assert_eq!(compile(g, &tiler()).resources.len(), 1);
    }

    #[test]
    fn handles_from_elsewhere_are_rejected() {
        let mut g: GraphBuilder<()> = GraphBuilder::new();
        let out = swapchain(&mut g);
        g.raster_pass("post", PassClass::Post, ())
            .sampled(ImageId(ResourceId(42)))
            .color(out);
        assert_eq!(
            compile_err(g, &tiler()),
            GraphError::UnknownResource {
                pass: "post".into(),
                index: 42
            }
        );

        let mut g: GraphBuilder<()> = GraphBuilder::new();
        let out = swapchain(&mut g);
        let post = g.raster_pass("post", PassClass::Post, ()).color(out).id();
        g.add_dependency(PassId(9), post);
        assert_eq!(
            compile_err(g, &tiler()),
            GraphError::UnknownPass { index: 9 }
        );
    }
}
