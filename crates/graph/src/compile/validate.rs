//! Phase 0, `validate_declarations`: checks every declaration, merges each pass's uses into one
//! access per resource, and records what each read sees (its producer: the last pass declared
//! before it that writes the resource). Errors name the pass and resource.

use tilegraph_profile::Profile;

use super::access::{push_pass_accesses, Access};
use crate::declare::{
    InitialContent, Origin, PassDecl, PassId, PassKind, ResourceDecl, ResourceDesc, ResourceId,
    UseKind,
};
use crate::error::GraphError;
use crate::types::Extent2d;

/// Larger than any `maxImageDimension2D` a driver reports.
pub(crate) const MAX_EXTENT_PX: u32 = 32_768;
/// 256 TiB: far beyond any GPU, small enough that sums of sizes cannot overflow in practice.
pub(crate) const MAX_BUFFER_BYTES: u64 = 1 << 48;

/// The validated graph: per-pass accesses and producers.
#[derive(Debug)]
pub(crate) struct Analysis {
    /// Every pass's accesses, pass after pass.
    pub accesses: Vec<Access>,
    /// `accesses[start..end]` of each pass.
    pub pass_ranges: Vec<(u32, u32)>,
    /// Render area of each raster pass.
    pub render_areas: Vec<Option<Extent2d>>,
    /// Per pass, the passes whose writes it reads (`producers[start..end]`).
    pub producer_ranges: Vec<(u32, u32)>,
    pub producers: Vec<PassId>,
    /// Per resource, the last declared pass that writes it.
    pub last_writer: Vec<Option<PassId>>,
}

impl Analysis {
    pub fn accesses_of(&self, pass: usize) -> &[Access] {
        let (start, end) = self.pass_ranges[pass];
        &self.accesses[start as usize..end as usize]
    }

    pub fn producers_of(&self, pass: usize) -> &[PassId] {
        let (start, end) = self.producer_ranges[pass];
        &self.producers[start as usize..end as usize]
    }
}

pub(crate) fn has_initial_content(resource: &ResourceDecl) -> bool {
    matches!(
        resource.origin,
        Origin::Imported(import) if import.content == InitialContent::Preserve
    )
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

/// Checks that a use fits the resource (image vs buffer, colour vs depth format).
fn check_use_target(pass: &PassDecl, kind: &UseKind, r: &ResourceDecl) -> Result<(), GraphError> {
    let mismatch = |format: &'static str| GraphError::FormatMismatch {
        pass: pass.name.clone(),
        resource: r.name.clone(),
        format,
        usage: kind.name(),
    };
    match (&r.desc, kind) {
        (ResourceDesc::Buffer(_), k) if k.is_attachment() || matches!(k, UseKind::Sampled) => {
            Err(mismatch("a buffer"))
        }
        (
            ResourceDesc::Image(_),
            UseKind::Uniform | UseKind::Vertex | UseKind::Index | UseKind::Indirect,
        ) => Err(mismatch("an image")),
        (
            ResourceDesc::Image(d),
            UseKind::ColorAttachment { .. } | UseKind::ResolveTarget { .. },
        ) if d.format.is_depth_stencil() => Err(mismatch(d.format.name())),
        (
            ResourceDesc::Image(d),
            UseKind::DepthStencilAttachment { .. } | UseKind::DepthStencilReadOnly,
        ) if !d.format.is_depth_stencil() => Err(mismatch(d.format.name())),
        _ => Ok(()),
    }
}

/// Checks the attachments of a raster pass and returns its render area.
fn check_raster(
    pass: &PassDecl,
    resources: &[ResourceDecl],
    profile: &Profile,
) -> Result<Extent2d, GraphError> {
    let mut area = pass.render_area;
    let mut samples: Option<u32> = None;
    let mut colors = 0u32;
    for u in &pass.uses {
        if !u.kind.is_attachment() {
            continue;
        }
        let r = &resources[u.resource.index()];
        let Some(desc) = r.desc.image() else {
            continue;
        };
        let extent = desc.extent_px;
        match area {
            None => area = Some(extent),
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
            match samples {
                None => samples = Some(found),
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
            colors += 1;
        }
        if let UseKind::ResolveTarget { source } = u.kind {
            check_resolve(pass, resources, source, u.resource)?;
        }
    }
    let max = profile.render_pass.max_color_attachments;
    if colors > max {
        return Err(GraphError::TooManyColorAttachments {
            pass: pass.name.clone(),
            count: colors,
            max,
            profile: profile.name.clone(),
        });
    }
    area.ok_or_else(|| GraphError::MissingRenderArea {
        pass: pass.name.clone(),
    })
}

fn check_resolve(
    pass: &PassDecl,
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
) -> Result<Analysis, GraphError> {
    for r in resources {
        validate_resource(r)?;
    }

    let total_uses: usize = passes.iter().map(|p| p.uses.len()).sum();
    let mut accesses: Vec<Access> = Vec::with_capacity(total_uses);
    let mut pass_ranges = Vec::with_capacity(passes.len());
    let mut render_areas = Vec::with_capacity(passes.len());
    for pass in passes {
        let start = accesses.len();
        for u in &pass.uses {
            let Some(r) = resources.get(u.resource.index()) else {
                return Err(GraphError::UnknownResource {
                    pass: pass.name.clone(),
                    index: u.resource.0,
                });
            };
            check_use_target(pass, &u.kind, r)?;
        }
        push_pass_accesses(
            pass.kind,
            pass.coverage,
            &pass.uses,
            |id| resources.get(id.index()).map(|r| &r.desc),
            &mut accesses,
        )
        .map_err(|c| GraphError::ConflictingUses {
            pass: pass.name.clone(),
            resource: resources[c.resource.index()].name.clone(),
            first: c.first,
            second: c.second,
        })?;
        pass_ranges.push((start as u32, accesses.len() as u32));
        render_areas.push(match pass.kind {
            PassKind::Raster => Some(check_raster(pass, resources, profile)?),
            PassKind::Compute | PassKind::Transfer => None,
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

    // What each read sees: the last writer declared before the reading pass.
    let mut last_writer: Vec<Option<PassId>> = vec![None; resources.len()];
    let mut producer_ranges = Vec::with_capacity(passes.len());
    let mut producers = Vec::with_capacity(accesses.len());
    for (p, pass) in passes.iter().enumerate() {
        let start = producers.len();
        let (a0, a1) = pass_ranges[p];
        for a in &accesses[a0 as usize..a1 as usize] {
            if !a.reads_prior {
                continue;
            }
            match last_writer[a.resource.index()] {
                Some(w) => producers.push(w),
                None => {
                    let r = &resources[a.resource.index()];
                    if a.explicit_read && !has_initial_content(r) {
                        return Err(GraphError::ReadBeforeWrite {
                            pass: pass.name.clone(),
                            resource: r.name.clone(),
                            usage: a.first_kind.name(),
                        });
                    }
                }
            }
        }
        producer_ranges.push((start as u32, producers.len() as u32));
        for a in &accesses[a0 as usize..a1 as usize] {
            if a.writes {
                last_writer[a.resource.index()] = Some(PassId(p as u32));
            }
        }
    }

    for &e in exports {
        let r = &resources[e.index()];
        if last_writer[e.index()].is_none() && !has_initial_content(r) {
            return Err(GraphError::ExportOfCulledResource {
                resource: r.name.clone(),
            });
        }
    }

    Ok(Analysis {
        accesses,
        pass_ranges,
        render_areas,
        producer_ranges,
        producers,
        last_writer,
    })
}
