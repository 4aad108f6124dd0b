//! Phases 4 and 5: `resource_lifetimes` (each resource's uses in execution order, its first and
//! last group, and where its memory comes from) and `infer_load_store` (render passes with
//! their attachments, load/store ops, subpasses and subpass dependencies).
//!
//! Load: CLEAR when the first use in the render pass clears; DONT_CARE when that use does not
//! need the old content (it covers everything) or there is none; LOAD only when old content
//! exists and is needed. Store: STORE only when a later pass needs the content (it reads it
//! before overwriting it) or the resource is exported; DONT_CARE otherwise. Depth and stencil of
//! a combined format get the same ops (seed 001: invalidating only one of D24S8 has no effect).

use tilegraph_profile::Profile;

use crate::declare::{PassDecl, PassId, ResourceDecl, UseKind};
use crate::plan::{
    Attachment, AttachmentIndex, AttachmentRef, RenderPass, Residency, Subpass, SubpassDependency,
    SubpassIndex,
};
use crate::types::{
    AccessFlags, DependencyFlags, Extent2d, Layout, LoadOp, PipelineStages, StoreOp,
};

use super::access::Access;
use super::merge::{Group, GroupKind};
use super::validate::{has_initial_content, Analysis};

const NONE: u32 = u32::MAX;

/// One use of a resource in execution order.
#[derive(Debug, Clone, Copy)]
pub(crate) struct TimelineEntry {
    pub group: u32,
    /// Index into `Analysis::accesses`.
    pub access: u32,
}

/// Every resource's uses in execution order (CSR by resource).
#[derive(Debug)]
pub(crate) struct Timeline {
    start: Vec<u32>,
    entries: Vec<TimelineEntry>,
}

impl Timeline {
    pub fn of(&self, resource: usize) -> &[TimelineEntry] {
        &self.entries[self.start[resource] as usize..self.start[resource + 1] as usize]
    }
}

pub(crate) fn build_timeline(
    groups: &[Group],
    order: &[PassId],
    analysis: &Analysis,
    n_resources: usize,
) -> Timeline {
    let mut start = vec![0u32; n_resources + 1];
    for &p in order {
        for a in analysis.accesses_of(p.index()) {
            start[a.resource.index() + 1] += 1;
        }
    }
    for i in 0..n_resources {
        start[i + 1] += start[i];
    }
    let mut fill = start.clone();
    let mut entries = vec![
        TimelineEntry {
            group: 0,
            access: 0
        };
        start[n_resources] as usize
    ];
    for (g, group) in groups.iter().enumerate() {
        for &p in &order[group.start..group.end] {
            let (a0, a1) = analysis.pass_ranges[p.index()];
            for ai in a0..a1 {
                let r = analysis.accesses[ai as usize].resource.index();
                entries[fill[r] as usize] = TimelineEntry {
                    group: g as u32,
                    access: ai,
                };
                fill[r] += 1;
            }
        }
    }
    Timeline { start, entries }
}

/// First and last group of each resource, and its residency.
pub(crate) fn resource_lifetimes(
    timeline: &Timeline,
    groups: &[Group],
    analysis: &Analysis,
    resources: &[ResourceDecl],
    exported: &[bool],
    profile: &Profile,
) -> (Vec<Option<(u32, u32)>>, Vec<Residency>) {
    let mut lifetimes = Vec::with_capacity(resources.len());
    let mut residency = Vec::with_capacity(resources.len());
    for (r, decl) in resources.iter().enumerate() {
        let uses = timeline.of(r);
        let life = match (uses.first(), uses.last()) {
            (Some(first), Some(last)) => Some((first.group, last.group)),
            _ => None,
        };
        lifetimes.push(life);
        let res = if matches!(decl.origin, crate::declare::Origin::Imported(_)) {
            Residency::Imported
        } else if life.is_none() {
            Residency::Unused
        } else if exported[r] {
            Residency::Exported
        } else {
            let one_render_pass = life.is_some_and(|(first, last)| {
                first == last && groups[first as usize].kind == GroupKind::Render
            });
            let attachment_only = uses
                .iter()
                .all(|e| !analysis.accesses[e.access as usize].non_attachment);
            if one_render_pass && attachment_only && profile.render_pass.transient_attachments {
                Residency::Transient
            } else {
                Residency::FrameLocal
            }
        };
        residency.push(res);
    }
    (lifetimes, residency)
}

/// Per-attachment bookkeeping while the subpasses of one render pass are laid out.
#[derive(Debug, Clone, Copy)]
struct AttachmentTrack {
    last_subpass: u32,
    last_stages: PipelineStages,
    layout: Layout,
    write: Option<(u32, PipelineStages, AccessFlags)>,
    /// Occupies tile memory (anything but a resolve target).
    on_chip: bool,
}

fn add_dependency(
    deps: &mut Vec<SubpassDependency>,
    src: u32,
    dst: u32,
    src_stages: PipelineStages,
    src_access: AccessFlags,
    dst_stages: PipelineStages,
    dst_access: AccessFlags,
) {
    if let Some(d) = deps
        .iter_mut()
        .find(|d| d.src_subpass.0 == src && d.dst_subpass.0 == dst)
    {
        d.src_stages |= src_stages;
        d.src_access |= src_access;
        d.dst_stages |= dst_stages;
        d.dst_access |= dst_access;
        return;
    }
    deps.push(SubpassDependency {
        src_subpass: SubpassIndex(src),
        dst_subpass: SubpassIndex(dst),
        src_stages,
        src_access,
        dst_stages,
        dst_access,
        flags: DependencyFlags::BY_REGION,
    });
}

/// Everything `infer_load_store` needs to read.
pub(crate) struct LoadStoreInput<'a> {
    pub groups: &'a [Group],
    pub order: &'a [PassId],
    pub analysis: &'a Analysis,
    pub passes: &'a [PassDecl],
    pub resources: &'a [ResourceDecl],
    pub exported: &'a [bool],
    pub residency: &'a [Residency],
    pub timeline: &'a Timeline,
}

/// Builds the render pass of every render group (`None` for compute and transfer groups).
pub(crate) fn infer_load_store(input: &LoadStoreInput<'_>) -> Vec<Option<RenderPass>> {
    let n_resources = input.resources.len();
    let mut written_before: Vec<bool> = input.resources.iter().map(has_initial_content).collect();
    // Per resource: cursor into its timeline, and its attachment in the current render pass.
    let mut cursor = vec![0u32; n_resources];
    let mut attachment_of = vec![(NONE, NONE); n_resources];
    let mut out = Vec::with_capacity(input.groups.len());
    let mut scratch = Scratch::default();
    for (g, group) in input.groups.iter().enumerate() {
        let rp = match group.kind {
            GroupKind::Render => Some(build_render_pass(
                input,
                &mut scratch,
                g as u32,
                group,
                &written_before,
                &mut cursor,
                &mut attachment_of,
            )),
            GroupKind::Compute | GroupKind::Transfer => None,
        };
        for &p in &input.order[group.start..group.end] {
            for a in input.analysis.accesses_of(p.index()) {
                if a.writes {
                    written_before[a.resource.index()] = true;
                }
            }
        }
        out.push(rp);
    }
    out
}

/// Buffers reused from one render pass to the next.
#[derive(Default)]
struct Scratch {
    tracks: Vec<AttachmentTrack>,
    readers: Vec<(u32, u32, PipelineStages)>,
}

fn build_render_pass(
    input: &LoadStoreInput<'_>,
    scratch: &mut Scratch,
    g: u32,
    group: &Group,
    written_before: &[bool],
    cursor: &mut [u32],
    attachment_of: &mut [(u32, u32)],
) -> RenderPass {
    let attachment_uses: usize = input.order[group.start..group.end]
        .iter()
        .map(|p| input.passes[p.index()].uses.len())
        .sum();
    let mut attachments: Vec<Attachment> = Vec::with_capacity(attachment_uses);
    let mut subpasses: Vec<Subpass> = Vec::with_capacity(group.end - group.start);
    let mut deps: Vec<SubpassDependency> = Vec::new();
    let tracks = &mut scratch.tracks;
    tracks.clear();
    // (attachment, subpass, stages) of reads since the attachment's last write.
    let readers = &mut scratch.readers;
    readers.clear();

    for (s, &p) in input.order[group.start..group.end].iter().enumerate() {
        let s = s as u32;
        let decl = &input.passes[p.index()];
        let accesses = input.analysis.accesses_of(p.index());
        let mut subpass = Subpass {
            pass: p,
            colors: Vec::new(),
            resolves: Vec::new(),
            depth_stencil: None,
            inputs: Vec::new(),
            preserve: Vec::new(),
        };
        let mut resolve_refs: Vec<(crate::declare::ResourceId, AttachmentRef)> = Vec::new();
        for u in decl.uses.iter().filter(|u| u.kind.is_attachment()) {
            let r = u.resource.index();
            let Some(a) = accesses.iter().find(|a| a.resource == u.resource) else {
                continue;
            };
            let index = if attachment_of[r].0 == g {
                attachment_of[r].1
            } else {
                let index = attachments.len() as u32;
                attachment_of[r] = (g, index);
                attachments.push(new_attachment(input, r, a, written_before[r]));
                tracks.push(AttachmentTrack {
                    last_subpass: NONE,
                    last_stages: PipelineStages::NONE,
                    layout: a.layout,
                    write: None,
                    on_chip: false,
                });
                index
            };
            let reference = AttachmentRef {
                attachment: AttachmentIndex(index),
                layout: a.layout,
            };
            match u.kind {
                UseKind::ColorAttachment { .. } => subpass.colors.push(reference),
                UseKind::DepthStencilAttachment { .. } | UseKind::DepthStencilReadOnly => {
                    subpass.depth_stencil = Some(reference)
                }
                UseKind::InputAttachment if !subpass.inputs.contains(&reference) => {
                    subpass.inputs.push(reference)
                }
                UseKind::ResolveTarget { source } => resolve_refs.push((source, reference)),
                _ => {}
            }
            let track = &mut tracks[index as usize];
            track.on_chip |= !matches!(u.kind, UseKind::ResolveTarget { .. });
            if track.last_subpass == s {
                continue;
            }
            // Used before and now, not in between: the subpasses between keep it.
            if track.last_subpass != NONE {
                for gap in (track.last_subpass + 1)..s {
                    subpasses[gap as usize]
                        .preserve
                        .push(AttachmentIndex(index));
                }
            }
            track_subpass_use(&mut deps, readers, track, index, s, a);
            if let Some(att) = attachments.get_mut(index as usize) {
                att.final_layout = a.layout;
            }
        }
        if !resolve_refs.is_empty() {
            subpass.resolves = subpass
                .colors
                .iter()
                .map(|c| {
                    let color_resource = attachments[c.attachment.0 as usize].resource;
                    resolve_refs
                        .iter()
                        .find(|(source, _)| *source == color_resource)
                        .map(|(_, r)| *r)
                })
                .collect();
        }
        subpasses.push(subpass);
    }
    for subpass in &mut subpasses {
        subpass.preserve.sort_unstable();
    }

    // Store: does anything after this render pass need the content?
    for att in &mut attachments {
        let r = att.resource.index();
        let uses = input.timeline.of(r);
        let mut c = cursor[r] as usize;
        while c < uses.len() && uses[c].group <= g {
            c += 1;
        }
        cursor[r] = c as u32;
        let needed = match uses.get(c) {
            Some(next) => input.analysis.accesses[next.access as usize].reads_prior,
            None => input.exported[r],
        };
        att.store_op = if needed {
            StoreOp::Store
        } else {
            StoreOp::DontCare
        };
        if att.format.has_stencil() {
            // seed 001: depth and stencil of D24S8 are invalidated together or not at all.
            att.stencil_store_op = att.store_op;
        }
    }

    deps.sort_by_key(|d| (d.src_subpass, d.dst_subpass));
    let on_chip_bytes_per_px = attachments
        .iter()
        .zip(scratch.tracks.iter())
        .filter(|(_, t)| t.on_chip)
        .map(|(a, _)| a.format.bytes_per_pixel() * a.samples.count())
        .sum();
    RenderPass {
        render_area_px: group.render_area.unwrap_or(Extent2d::new(0, 0)),
        attachments,
        subpasses,
        dependencies: deps,
        on_chip_bytes_per_px,
    }
}

fn new_attachment(
    input: &LoadStoreInput<'_>,
    r: usize,
    a: &Access,
    has_content: bool,
) -> Attachment {
    let desc = input.resources[r].desc.image().copied();
    let (format, samples) = match desc {
        Some(d) => (d.format, d.samples),
        // Validation only lets images be attachments.
        None => (
            crate::types::Format::R8G8B8A8_UNORM,
            crate::types::SampleCount::S1,
        ),
    };
    let load_op = if a.clear.is_some() {
        LoadOp::Clear
    } else if a.reads_prior && has_content {
        LoadOp::Load
    } else {
        LoadOp::DontCare
    };
    let stencil_load_op = if format.has_stencil() {
        // seed 001: depth and stencil of a combined format share the load op.
        load_op
    } else {
        LoadOp::DontCare
    };
    Attachment {
        resource: a.resource,
        format,
        samples,
        load_op,
        store_op: StoreOp::DontCare,
        stencil_load_op,
        stencil_store_op: StoreOp::DontCare,
        initial_layout: a.layout,
        final_layout: a.layout,
        clear: if load_op == LoadOp::Clear {
            a.clear
        } else {
            None
        },
        residency: input.residency[r],
    }
}

/// Adds the subpass dependencies that a use of an attachment in subpass `s` needs against its
/// earlier uses in the same render pass.
fn track_subpass_use(
    deps: &mut Vec<SubpassDependency>,
    readers: &mut Vec<(u32, u32, PipelineStages)>,
    track: &mut AttachmentTrack,
    index: u32,
    s: u32,
    a: &Access,
) {
    let reads = a.reads_prior || a.explicit_read;
    let mut synced_last_user = false;
    if let Some((ws, stages, access)) = track.write {
        if ws != s {
            add_dependency(deps, ws, s, stages, access.writes(), a.stages, a.access);
            synced_last_user |= ws == track.last_subpass;
        }
    }
    if a.writes {
        for &(att, rs, stages) in readers.iter() {
            if att == index && rs != s {
                add_dependency(deps, rs, s, stages, AccessFlags::NONE, a.stages, a.access);
                synced_last_user |= rs == track.last_subpass;
            }
        }
        readers.retain(|&(att, _, _)| att != index);
    }
    // A layout change between subpasses happens inside a dependency.
    if track.last_subpass != NONE && track.layout != a.layout && !synced_last_user {
        add_dependency(
            deps,
            track.last_subpass,
            s,
            track.last_stages,
            AccessFlags::NONE,
            a.stages,
            a.access,
        );
    }
    if a.writes {
        track.write = Some((s, a.stages, a.access));
    } else if reads {
        readers.push((index, s, a.stages));
    }
    track.last_subpass = s;
    track.last_stages = a.stages;
    track.layout = a.layout;
}
