//! `resource_lifetimes`: what each resource's uses add up to, walked in execution order once
//! the passes are grouped into steps — its first and last group (what aliasing places), its use
//! roles (its usage flags), whether every use is an attachment, the first group that writes it,
//! and for each group that uses it whether a later group needs what it leaves (what the store
//! op will ask). Then `residencies` says where each resource's memory comes from and
//! `infer_usage` which usage flags it is created with.

use tilegraph_profile::Profile;

use crate::declare::{Origin, PassId, ResourceDecl, ResourceDesc, ResourceId, UseKind};
use crate::plan::{Residency, Usage};
use crate::types::{BufferUsage, ImageUsage};

use super::access::{role, PassAccesses};
use super::dataflow::Dataflow;
use super::merge::{Group, GroupKind};

const NONE: u32 = u32::MAX;

/// One resource's uses in execution order, summarized.
#[derive(Debug, Clone, Copy)]
pub(crate) struct ResourceUse {
    /// First and last group (`NONE`: unused).
    first: u32,
    last: u32,
    /// Every use binds it to a render pass.
    pub attachment_only: bool,
    /// [`UseKind::bit`](crate::declare::UseKind) of every use by a kept pass.
    pub roles: u16,
    /// First group that writes it (`NONE`: none does).
    pub first_write: u32,
    /// The access (index into `PassAccesses::accesses`) that began its use in group `last`.
    last_group_start: u32,
}

impl ResourceUse {
    /// First and last group that use it (`None`: unused).
    pub fn lifetime(&self) -> Option<(u32, u32)> {
        (self.last != NONE).then_some((self.first, self.last))
    }
}

/// What later phases need from each resource's uses in execution order.
#[derive(Debug)]
pub(crate) struct ResourceUses {
    /// Per resource.
    pub resources: Vec<ResourceUse>,
    /// Per access (index into `PassAccesses::accesses`) that begins a group's use of a resource:
    /// the content is needed after the group (the next group that uses it reads it first, or
    /// its content outlives the frame: exported, or imported and only read). A group's later
    /// accesses to the resource are not set.
    pub needed_after: Vec<bool>,
}

/// Each resource's uses in execution order: group after group, pass after pass, every
/// surviving access. `kept_at_end` (per resource): its content must outlive the frame, so the
/// group that uses it last leaves content that is needed.
pub(crate) fn resource_lifetimes(
    groups: &[Group],
    order: &[PassId],
    accesses: &PassAccesses,
    n_resources: usize,
    kept_at_end: &[bool],
) -> ResourceUses {
    let mut uses = ResourceUses {
        resources: vec![
            ResourceUse {
                first: NONE,
                last: NONE,
                attachment_only: true,
                roles: 0,
                first_write: NONE,
                last_group_start: NONE,
            };
            n_resources
        ],
        needed_after: vec![false; accesses.accesses.len()],
    };
    for (g, group) in groups.iter().enumerate() {
        let g = g as u32;
        for &p in &order[group.start..group.end] {
            let first_access = accesses.start_of(p);
            for (k, a) in accesses.of(p).iter().enumerate() {
                let s = &mut uses.resources[a.resource.index()];
                if s.last != g {
                    // The group's first use of the resource decides whether the group before
                    // needed what it left.
                    match uses.needed_after.get_mut(s.last_group_start as usize) {
                        Some(needed) => *needed = a.reads_prior(),
                        None => s.first = g,
                    }
                    s.last = g;
                    s.last_group_start = (first_access + k) as u32;
                }
                s.attachment_only &= !a.non_attachment();
                s.roles |= a.roles;
                if a.writes() && s.first_write == NONE {
                    s.first_write = g;
                }
            }
        }
    }
    // After its last group, a resource's content is needed when it must outlive the frame.
    for (s, &kept) in uses.resources.iter().zip(kept_at_end) {
        if let Some(needed) = uses.needed_after.get_mut(s.last_group_start as usize) {
            *needed = kept;
        }
    }
    uses
}

/// Where each resource's memory comes from.
pub(crate) fn residencies(
    uses: &ResourceUses,
    groups: &[Group],
    resources: &[ResourceDecl],
    exported: &[bool],
    profile: &Profile,
) -> Vec<Residency> {
    resources
        .iter()
        .enumerate()
        .map(|(r, decl)| {
            let life = uses.resources[r].lifetime();
            if matches!(decl.origin, Origin::Imported(_)) {
                Residency::Imported
            } else if life.is_none() {
                Residency::Unused
            } else if exported[r] {
                Residency::Exported
            } else {
                let one_render_pass = life.is_some_and(|(first, last)| {
                    first == last && groups[first as usize].kind == GroupKind::Render
                });
                if one_render_pass
                    && uses.resources[r].attachment_only
                    && profile.render_pass.transient_attachments
                {
                    Residency::Transient
                } else {
                    Residency::FrameLocal
                }
            }
        })
        .collect()
}

/// Per resource: its content must outlive the frame. Exports, and imported content that no
/// surviving pass writes: the frame only read it, and a read must not cost the caller what it
/// imported (a static depth buffer tested by decals would otherwise end with a DONT_CARE store).
pub(crate) fn content_kept_at_end(
    resources: &[ResourceDecl],
    exported: &[bool],
    dataflow: &Dataflow,
    alive: &[bool],
    accesses: &PassAccesses,
) -> Vec<bool> {
    let mut kept = exported.to_vec();
    let mut ambiguous = false;
    for (r, decl) in resources.iter().enumerate() {
        // Store ops exist for attachments only, hence images only.
        if kept[r] || decl.desc.image().is_none() || !decl.has_initial_content() {
            continue;
        }
        // The last declared writer tells, unless it was pruned (an earlier one may survive).
        match dataflow.last_writer[r] {
            None => kept[r] = true,
            Some(w) if alive.get(w.index()).copied().unwrap_or(false) => {}
            Some(_) => {
                kept[r] = true;
                ambiguous = true;
            }
        }
    }
    if ambiguous {
        for (p, _) in alive.iter().enumerate().filter(|(_, &a)| a) {
            for a in accesses.of(PassId(p as u32)) {
                if a.writes() && !exported[a.resource.index()] {
                    kept[a.resource.index()] = false;
                }
            }
        }
    }
    kept
}

/// Usage flags from the roles of every surviving access.
pub(crate) fn infer_usage(desc: &ResourceDesc, roles: u16, residency: Residency) -> Usage {
    let has = |kind: UseKind| roles & role(kind) != 0;
    match desc {
        ResourceDesc::Image(_) => {
            let mut u = ImageUsage::NONE;
            if has(UseKind::ColorAttachment { clear: None })
                || has(UseKind::ResolveTarget {
                    source: ResourceId(0),
                })
            {
                u |= ImageUsage::COLOR_ATTACHMENT;
            }
            if has(UseKind::DepthStencilAttachment { clear: None })
                || has(UseKind::DepthStencilReadOnly)
            {
                u |= ImageUsage::DEPTH_STENCIL_ATTACHMENT;
            }
            if has(UseKind::InputAttachment) {
                u |= ImageUsage::INPUT_ATTACHMENT;
            }
            if has(UseKind::Sampled) {
                u |= ImageUsage::SAMPLED;
            }
            if has(UseKind::StorageRead)
                || has(UseKind::StorageWrite)
                || has(UseKind::StorageReadWrite)
            {
                u |= ImageUsage::STORAGE;
            }
            if has(UseKind::TransferSrc) {
                u |= ImageUsage::TRANSFER_SRC;
            }
            if has(UseKind::TransferDst) {
                u |= ImageUsage::TRANSFER_DST;
            }
            if residency == Residency::Transient {
                u |= ImageUsage::TRANSIENT_ATTACHMENT;
            }
            Usage::Image(u)
        }
        ResourceDesc::Buffer(_) => {
            let mut u = BufferUsage::NONE;
            if has(UseKind::Uniform) {
                u |= BufferUsage::UNIFORM_BUFFER;
            }
            if has(UseKind::StorageRead)
                || has(UseKind::StorageWrite)
                || has(UseKind::StorageReadWrite)
            {
                u |= BufferUsage::STORAGE_BUFFER;
            }
            if has(UseKind::Vertex) {
                u |= BufferUsage::VERTEX_BUFFER;
            }
            if has(UseKind::Index) {
                u |= BufferUsage::INDEX_BUFFER;
            }
            if has(UseKind::Indirect) {
                u |= BufferUsage::INDIRECT_BUFFER;
            }
            if has(UseKind::ConditionalPredicate) {
                u |= BufferUsage::CONDITIONAL_RENDERING;
            }
            if has(UseKind::TransferSrc) {
                u |= BufferUsage::TRANSFER_SRC;
            }
            if has(UseKind::TransferDst) {
                u |= BufferUsage::TRANSFER_DST;
            }
            Usage::Buffer(u)
        }
    }
}
