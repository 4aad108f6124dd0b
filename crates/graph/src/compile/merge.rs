//! Phase 3, `merge_render_passes`: group consecutive raster passes into render passes.
//!
//! A raster pass joins the render pass before it when the profile allows merging, the render
//! areas are equal, it shares at least one attachment with the render pass (merging unrelated
//! passes saves no traffic and only grows the tile footprint), and every resource the two share
//! is touched only as an attachment by both (so any read of the earlier pass's output is an
//! input-attachment or attachment read at the same pixel), or only read by both in one layout. A clear in a later subpass cannot be a load
//! op, so it starts a new render pass. On tilers this keeps intermediate attachments in tile
//! memory; on immediate GPUs (`MergePolicy::Allowed`) the same merge is harmless and keeps plans
//! alike across profiles.
//!
//! Occlusion-query passes, when the profile wants them in a render pass of their own, never
//! share one with other passes, and with `flush_before` a flush precedes them (seed 001).

use tilegraph_profile::{MergePolicy, PassClass, Profile};

use crate::declare::{PassDecl, PassId, PassKind};
use crate::types::{Extent2d, Layout};

use super::validate::Analysis;

const NONE: u32 = u32::MAX;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum GroupKind {
    Render,
    Compute,
    Transfer,
}

/// One future step: a render pass of `order[start..end]`, or one compute or transfer pass.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Group {
    pub kind: GroupKind,
    pub start: usize,
    pub end: usize,
    pub render_area: Option<Extent2d>,
    /// Submit before this group.
    pub flush_before: bool,
    /// Every pass in it is of class `OcclusionQuery`.
    pub queries_only: bool,
}

/// How the current render pass touches a resource.
#[derive(Debug, Clone, Copy)]
struct Touch {
    group: u32,
    non_attachment: bool,
    written: bool,
    layout: Layout,
}

fn is_query(pass: &PassDecl) -> bool {
    pass.class == PassClass::OcclusionQuery
}

pub(crate) fn merge_render_passes(
    order: &[PassId],
    analysis: &Analysis,
    passes: &[PassDecl],
    n_resources: usize,
    profile: &Profile,
) -> Vec<Group> {
    let policy = &profile.render_pass;
    let queries_alone = profile.passes.occlusion_queries.own_render_pass;
    let mut touch = vec![
        Touch {
            group: NONE,
            non_attachment: false,
            written: false,
            layout: Layout::Undefined,
        };
        n_resources
    ];
    let mut groups: Vec<Group> = Vec::new();
    for (i, &id) in order.iter().enumerate() {
        let p = id.index();
        let pass = &passes[p];
        let area = analysis.render_areas[p];
        let joins = match groups.last() {
            Some(g)
                if g.kind == GroupKind::Render
                    && pass.kind == PassKind::Raster
                    && policy.merge_subpasses != MergePolicy::Never
                    && g.render_area == area
                    && !(queries_alone && g.queries_only != is_query(pass)) =>
            {
                let g_index = (groups.len() - 1) as u32;
                let mut connected = false;
                let compatible = analysis.accesses_of(p).iter().all(|a| {
                    let t = &touch[a.resource.index()];
                    if t.group != g_index {
                        return true;
                    }
                    if a.clear.is_some() {
                        return false;
                    }
                    let same_pixel = !a.non_attachment && !t.non_attachment;
                    connected |= same_pixel;
                    same_pixel || (!a.writes && !t.written && a.layout == t.layout)
                });
                // A pass that shares no attachment with the render pass gains nothing from
                // joining it and would only add to its tile-memory footprint.
                compatible && connected
            }
            _ => false,
        };
        if joins {
            if let Some(g) = groups.last_mut() {
                g.end = i + 1;
                g.queries_only &= is_query(pass);
            }
        } else {
            groups.push(Group {
                kind: match pass.kind {
                    PassKind::Raster => GroupKind::Render,
                    PassKind::Compute => GroupKind::Compute,
                    PassKind::Transfer => GroupKind::Transfer,
                },
                start: i,
                end: i + 1,
                render_area: area,
                flush_before: false,
                queries_only: is_query(pass),
            });
        }
        let g_index = (groups.len() - 1) as u32;
        for a in analysis.accesses_of(p) {
            let t = &mut touch[a.resource.index()];
            if t.group != g_index {
                *t = Touch {
                    group: g_index,
                    non_attachment: a.non_attachment,
                    written: a.writes,
                    layout: a.layout,
                };
            } else {
                t.non_attachment |= a.non_attachment;
                t.written |= a.writes;
                t.layout = a.layout;
            }
        }
    }

    // seed 001: "遮挡查询, 前面加一个flush" — submit before the query render pass.
    if profile.passes.occlusion_queries.flush_before {
        for i in 1..groups.len() {
            if groups[i].queries_only && !groups[i - 1].queries_only {
                groups[i].flush_before = true;
            }
        }
    }
    groups
}
