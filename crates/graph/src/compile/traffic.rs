//! `estimate_traffic`: bytes moved between the GPU and system memory per frame, from the
//! finished plan (its passes' accesses and its render passes' load and store ops).
//!
//! **Tiler model** (profiles with `architecture = "tiler"`): attachments live in tile memory
//! during a render pass, so a render pass costs one read of every attachment it LOADs and one
//! write of every attachment it STOREs (`width * height * bytes_per_pixel * samples`; a resolve
//! target's store is counted as resolve). Whatever happens between subpasses stays on chip.
//!
//! **Immediate model** (`architecture = "immediate"`): no tile memory; every raster pass reads
//! each attachment whose old content it uses (LOAD, blending, depth test, input attachment) and
//! writes each attachment it writes (a clear counts as a write; a resolve reads the multisampled
//! source and writes the target). Caches are ignored.
//!
//! **Both models** add, per pass, one full read of every sampled image (all mips, once per pass
//! however often the shader samples it), storage reads and writes of the whole image or buffer,
//! uniform/vertex/index/indirect buffers read once, and transfer sources read and destinations
//! written once.
//!
//! **Naive plan**, for comparison: every raster pass is its own render pass and loads and stores
//! every attachment it declares; the other traffic is the same. Both numbers are in the plan.

use crate::declare::{InitialContent, Origin, PassKind, ResourceDesc, ResourceId, UseKind};
use crate::plan::{
    PlanResource, PlannedPass, RenderPass, Step, TrafficBreakdown, TrafficEstimate, TrafficModel,
};
use crate::types::{LoadOp, StoreOp};

use super::access::{role, Access, PassAccesses, BUFFER_READ_ROLES, RESOLVE_ROLE};

fn add(slot: &mut u64, bytes: u64) {
    *slot = slot.saturating_add(bytes);
}

const SAMPLED: u16 = role(UseKind::Sampled);
const STORAGE_READS: u16 = role(UseKind::StorageRead) | role(UseKind::StorageReadWrite);
const STORAGE_WRITES: u16 = role(UseKind::StorageWrite) | role(UseKind::StorageReadWrite);
const BUFFER_READS: u16 = BUFFER_READ_ROLES;
const TRANSFER_SRC: u16 = role(UseKind::TransferSrc);
const TRANSFER_DST: u16 = role(UseKind::TransferDst);
const MEMORY_ROLES: u16 =
    SAMPLED | STORAGE_READS | STORAGE_WRITES | BUFFER_READS | TRANSFER_SRC | TRANSFER_DST;
const RESOLVE: u16 = RESOLVE_ROLE;

/// Per resource: bytes of one attachment load or store (mip 0, all samples), and of the whole
/// resource (every mip; a buffer's size).
struct Sizes {
    attachment: Vec<u64>,
    whole: Vec<u64>,
}

impl Sizes {
    fn of(resources: &[PlanResource]) -> Self {
        let attachment = resources
            .iter()
            .map(|r| match &r.desc {
                ResourceDesc::Image(d) => d.attachment_bytes(),
                ResourceDesc::Buffer(d) => d.size_bytes,
            })
            .collect();
        let whole = resources.iter().map(|r| r.desc.size_bytes()).collect();
        Sizes { attachment, whole }
    }

    fn attachment(&self, r: ResourceId) -> u64 {
        self.attachment.get(r.index()).copied().unwrap_or(0)
    }

    fn whole(&self, r: ResourceId) -> u64 {
        self.whole.get(r.index()).copied().unwrap_or(0)
    }
}

/// Traffic that does not go through attachments: descriptors, vertex input, transfers.
fn memory_traffic(a: &Access, bytes: u64, out: &mut TrafficBreakdown) {
    let roles = a.roles;
    if roles & MEMORY_ROLES == 0 {
        // Attachment-only: counted by the load/store model.
        return;
    }
    if roles & SAMPLED != 0 {
        add(&mut out.sampled_read_bytes, bytes);
    }
    if roles & STORAGE_READS != 0 {
        add(&mut out.storage_read_bytes, bytes);
    }
    if roles & STORAGE_WRITES != 0 {
        add(&mut out.storage_write_bytes, bytes);
    }
    if roles & BUFFER_READS != 0 {
        add(&mut out.buffer_read_bytes, bytes);
    }
    if roles & TRANSFER_SRC != 0 {
        add(&mut out.transfer_read_bytes, bytes);
    }
    if roles & TRANSFER_DST != 0 {
        add(&mut out.transfer_write_bytes, bytes);
    }
}

pub(crate) fn estimate_traffic(
    model: TrafficModel,
    steps: &[Step],
    passes: &[PlannedPass],
    resources: &[PlanResource],
    accesses: &PassAccesses,
) -> TrafficEstimate {
    let sizes = Sizes::of(resources);
    // What both plans share (descriptors, vertex input, transfers), and the naive plan's
    // attachments: every raster pass loads and stores every attachment it declares.
    let mut common = TrafficBreakdown::default();
    let mut naive_attachments = 0u64;
    for pass in passes {
        for a in accesses.of(pass.id) {
            memory_traffic(a, sizes.whole(a.resource), &mut common);
            if pass.kind == PassKind::Raster && a.attachment() {
                add(&mut naive_attachments, sizes.attachment(a.resource));
            }
        }
    }
    let mut naive = common;
    add(&mut naive.attachment_read_bytes, naive_attachments);
    add(&mut naive.attachment_write_bytes, naive_attachments);
    let mut planned = common;

    match model {
        TrafficModel::Tiler => {
            for rp in steps.iter().filter_map(|s| match s {
                Step::RenderPass(rp) => Some(rp),
                _ => None,
            }) {
                tiler_render_pass(rp, &sizes, &mut planned);
            }
        }
        TrafficModel::Immediate => {
            let mut has_content: Vec<bool> = resources
                .iter()
                .map(|r| {
                    matches!(r.origin, Origin::Imported(i) if i.content == InitialContent::Preserve)
                })
                .collect();
            for pass in passes {
                if pass.kind == PassKind::Raster {
                    for a in accesses.of(pass.id).iter().filter(|a| a.attachment()) {
                        immediate_attachment(pass, a, &has_content, &sizes, &mut planned);
                    }
                }
                for a in accesses.of(pass.id).iter().filter(|a| a.writes()) {
                    if let Some(c) = has_content.get_mut(a.resource.index()) {
                        *c = true;
                    }
                }
            }
        }
    }
    TrafficEstimate {
        model,
        planned,
        naive,
    }
}

/// One render pass on a tiler: a LOAD reads an attachment into tile memory, a STORE writes it
/// back — as a resolve when no subpass binds it (a resolve target only receives the resolve).
fn tiler_render_pass(rp: &RenderPass, sizes: &Sizes, planned: &mut TrafficBreakdown) {
    for (i, att) in rp.attachments.iter().enumerate() {
        let bytes = sizes.attachment(att.resource);
        if att.load_op == LoadOp::Load {
            add(&mut planned.attachment_read_bytes, bytes);
        }
        if att.store_op != StoreOp::Store {
            continue;
        }
        let on_chip = rp.subpasses.iter().any(|s| {
            s.colors
                .iter()
                .chain(s.inputs.iter())
                .chain(s.depth_stencil.iter())
                .any(|r| r.attachment.0 as usize == i)
        });
        if on_chip {
            add(&mut planned.attachment_write_bytes, bytes);
        } else {
            add(&mut planned.resolve_write_bytes, bytes);
        }
    }
}

/// One raster pass's traffic for one attachment on an immediate GPU.
fn immediate_attachment(
    pass: &PlannedPass,
    a: &Access,
    has_content: &[bool],
    sizes: &Sizes,
    planned: &mut TrafficBreakdown,
) {
    let bytes = sizes.attachment(a.resource);
    let old = has_content
        .get(a.resource.index())
        .copied()
        .unwrap_or(false);
    if a.explicit_read() || (a.reads_prior() && old) {
        add(&mut planned.attachment_read_bytes, bytes);
    }
    if a.roles & RESOLVE != 0 {
        add(&mut planned.resolve_write_bytes, bytes);
        let source = pass.uses.iter().find_map(|u| match u.kind {
            UseKind::ResolveTarget { source } if u.resource == a.resource => Some(source),
            _ => None,
        });
        if let Some(source) = source {
            add(&mut planned.attachment_read_bytes, sizes.attachment(source));
        }
    } else if a.writes() {
        add(&mut planned.attachment_write_bytes, bytes);
    }
}

#[cfg(test)]
mod tests {
    use crate::testing::*;
    use crate::*;

    /// prepass, opaque, transparent, post (same pixel): 4-byte formats everywhere.
    fn classic() -> GraphBuilder<()> {
        let mut g = GraphBuilder::new();
        let depth = d24s8(&mut g, "depth");
        let color = rgba8(&mut g, "color");
        let out = swapchain(&mut g);
        g.raster_pass("prepass", PassClass::DepthPrepass, ())
            .depth_stencil_clear(depth, ClearDepthStencil::REVERSE_Z);
        g.raster_pass("opaque", PassClass::Opaque, ())
            .color_clear(color, ClearColor::BLACK)
            .depth_stencil_read_only(depth);
        g.raster_pass("transparent", PassClass::Transparent, ())
            .color(color)
            .depth_stencil_read_only(depth);
        g.raster_pass("post", PassClass::Post, ())
            .input(color)
            .color(out)
            .coverage(Coverage::Full);
        g
    }

    #[test]
    fn a_merged_frame_on_a_tiler_moves_only_the_presented_image() {
        let plan = compile(classic(), &tiler());
        assert_eq!(plan.traffic.model, TrafficModel::Tiler);
        assert_eq!(plan.traffic.planned.attachment_write_bytes, PIXELS * 4);
        assert_eq!(plan.traffic.planned.total_bytes(), PIXELS * 4);
        // Naive: each pass loads and stores each attachment: 1 + 2 + 2 + 2 attachments.
        assert_eq!(plan.traffic.naive.attachment_read_bytes, PIXELS * 4 * 7);
        assert_eq!(plan.traffic.naive.total_bytes(), PIXELS * 4 * 14);
    }

    #[test]
    fn the_immediate_model_counts_every_attachment_access() {
        let plan = compile(classic(), &desktop());
        assert_eq!(plan.traffic.model, TrafficModel::Immediate);
        // Reads: depth tested twice, colour blended once and read as input once.
        assert_eq!(plan.traffic.planned.attachment_read_bytes, PIXELS * 4 * 4);
        // Writes: depth clear, colour clear, colour blend, presented image.
        assert_eq!(plan.traffic.planned.attachment_write_bytes, PIXELS * 4 * 4);
        assert_eq!(
            plan.traffic.naive,
            compile(classic(), &tiler()).traffic.naive
        );
    }

    #[test]
    fn memory_accesses_count_whole_resources_once_per_pass() {
        let mut g = GraphBuilder::new();
        let mesh = g.import_buffer(
            "mesh",
            1000,
            Import {
                initial: ResourceState::UNDEFINED,
                content: InitialContent::Preserve,
                final_state: ResourceState::UNDEFINED,
            },
        );
        let pyramid_desc =
            ImageDesc::new(Extent2d::new(8, 4), Format::R32_SFLOAT).with_mip_levels(4);
        let pyramid = g.create_image("pyramid", pyramid_desc);
        let counts = g.create_buffer("counts", 64);
        g.export(counts);
        g.compute_pass("build", PassClass::Compute, ())
            .storage_read_write(pyramid)
            .coverage(Coverage::Full);
        g.compute_pass("test", PassClass::Compute, ())
            .sampled(pyramid)
            .storage_read(mesh)
            .storage_write(counts);
        let plan = compile(g, &tiler());
        let pyramid_bytes = (32 + 8 + 2 + 1) * 4;
        assert_eq!(pyramid_desc.total_bytes(), pyramid_bytes);
        let t = plan.traffic.planned;
        assert_eq!(t.sampled_read_bytes, pyramid_bytes);
        assert_eq!(t.storage_read_bytes, pyramid_bytes + 1000);
        assert_eq!(t.storage_write_bytes, pyramid_bytes + 64);
        assert_eq!(t.attachment_read_bytes + t.attachment_write_bytes, 0);
        assert_eq!(plan.traffic.naive, t);
    }
}
