//! Property tests on random graphs of up to 200 passes.
//!
//! Random numbers are interpreted into a graph: mostly valid ones (reads only of resources that
//! have content, attachments of matching extent and samples), and in "chaos" mode arbitrary
//! declarations (unknown handles, wrong formats, cycles) that must fail with an error, never a
//! panic. Every plan that compiles is checked by an independent model of the rules:
//!
//! - every read is ordered after the write it reads;
//! - no two resources whose memory overlaps are alive at the same time, and every earlier
//!   holder of a resource's bytes is reached through the aliasing hand-offs;
//! - every hazard between two steps has a barrier (after a write, a memory dependency: the
//!   write in its source access scope, the next step's accesses — load and store ops, depth
//!   tests and blending included — in its destination scope), and layouts chain from barrier to
//!   use;
//! - every barrier and subpass dependency names only accesses its stages perform;
//! - no pruned pass contributes to an export;
//! - with compute passes on an async compute queue: the submissions cover the steps in order,
//!   each waits only on earlier ones (no cycle of waits), a conflicting access on one queue
//!   after one on the other waits on its submission, the frame starts and ends on the graphics
//!   queue, every acquire of an ownership transfer has its release on the other queue (none at
//!   all with concurrent sharing), and barriers on the compute queue name only its stages;
//! - compiling twice gives the same plan;
//! - re-placing memory with other requirements (as the executor does) keeps all of the above.

mod common;

use common::profile;
use proptest::prelude::*;
use tilegraph_graph::*;
use tilegraph_profile::{MergePolicy, Profile, QueueSharing};

const EXTENTS: [Extent2d; 2] = [Extent2d::new(16, 16), Extent2d::new(8, 4)];
const FORMATS: [Format; 6] = [
    Format::R8G8B8A8_UNORM,
    Format::R16G16B16A16_SFLOAT,
    Format::R32_UINT,
    Format::D24_UNORM_S8_UINT,
    Format::D32_SFLOAT,
    Format::B10G11R11_UFLOAT_PACK32,
];
const CLASSES: [PassClass; 9] = [
    PassClass::Compute,
    PassClass::DepthPrepass,
    PassClass::Opaque,
    PassClass::AlphaTested,
    PassClass::Transparent,
    PassClass::OcclusionQuery,
    PassClass::Post,
    PassClass::Transfer,
    PassClass::Other,
];

#[derive(Debug, Clone)]
struct ResSpec {
    image: bool,
    extent: u8,
    format: u8,
    msaa: bool,
    mips: bool,
    size: u16,
    /// 0, 1: created; 2: imported, content kept; 3: imported, content dropped.
    import: u8,
    final_layout: u8,
}

#[derive(Debug, Clone)]
struct PassSpec {
    kind: u8,
    class: u8,
    extent: u8,
    full: bool,
    always: bool,
    uses: Vec<(u8, u16, bool)>,
}

#[derive(Debug, Clone)]
struct Spec {
    resources: Vec<ResSpec>,
    passes: Vec<PassSpec>,
    exports: Vec<u16>,
    dependencies: Vec<(u16, u16)>,
    profile: u8,
    chaos: bool,
    /// Bit `p % 64`: compute or transfer pass `p` may run on an async compute queue.
    async_passes: u64,
}

fn res_spec() -> impl Strategy<Value = ResSpec> {
    (
        prop::bool::weighted(0.7),
        0u8..2,
        0u8..6,
        prop::bool::weighted(0.15),
        prop::bool::weighted(0.2),
        1u16..4096,
        0u8..4,
        0u8..4,
    )
        .prop_map(
            |(image, extent, format, msaa, mips, size, import, final_layout)| ResSpec {
                image,
                extent,
                format,
                msaa,
                mips,
                size,
                import,
                final_layout,
            },
        )
}

fn pass_spec() -> impl Strategy<Value = PassSpec> {
    (
        0u8..3,
        0u8..9,
        0u8..2,
        prop::bool::weighted(0.3),
        prop::bool::weighted(0.05),
        prop::collection::vec((0u8..16, any::<u16>(), any::<bool>()), 0..6),
    )
        .prop_map(|(kind, class, extent, full, always, uses)| PassSpec {
            kind,
            class,
            extent,
            full,
            always,
            uses,
        })
}

fn spec(max_passes: usize) -> impl Strategy<Value = Spec> {
    (
        prop::collection::vec(res_spec(), 1..40),
        prop::collection::vec(pass_spec(), 0..=max_passes),
        prop::collection::vec(any::<u16>(), 0..4),
        prop::collection::vec((any::<u16>(), any::<u16>()), 0..3),
        0u8..10,
        prop::bool::weighted(0.2),
        any::<u64>(),
    )
        .prop_map(
            |(resources, passes, exports, dependencies, profile, chaos, async_passes)| Spec {
                resources,
                passes,
                exports,
                dependencies,
                profile,
                chaos,
                async_passes,
            },
        )
}

fn pick_profile(index: u8) -> Profile {
    let names = [
        "adreno-7xx",
        "mali-valhall",
        "powervr-b",
        "generic-mobile",
        "lavapipe",
        "desktop-nvidia",
    ];
    // Async compute on: exclusive and concurrent sharing, immediate and tiler.
    let async_on = |name: &str, sharing| {
        let mut p = profile(name);
        p.queues.async_compute = true;
        p.queues.sharing = sharing;
        p
    };
    match (names.get(index as usize), index) {
        (Some(name), _) => profile(name),
        (None, 7) => async_on("desktop-nvidia", QueueSharing::Exclusive),
        (None, 8) => async_on("desktop-nvidia", QueueSharing::Concurrent),
        (None, 9) => async_on("mali-valhall", QueueSharing::Exclusive),
        (None, _) => {
            let mut p = profile("adreno-7xx");
            p.render_pass.merge_subpasses = MergePolicy::Never;
            p
        }
    }
}

/// What the test itself believes each pass does to each resource.
#[derive(Debug, Clone, Copy)]
struct MirrorUse {
    resource: u32,
    /// Needs the content earlier writes left (explicit read, or a write that keeps old content).
    reads_prior: bool,
    writes: bool,
}

struct Built {
    graph: GraphBuilder<u32>,
    mirror: Vec<Vec<MirrorUse>>,
    exports: Vec<u32>,
}

fn image_desc(r: &ResSpec) -> ImageDesc {
    let extent = EXTENTS[r.extent as usize % 2];
    let format = FORMATS[r.format as usize % FORMATS.len()];
    let mut desc = ImageDesc::new(extent, format);
    if r.msaa {
        desc = desc.with_samples(SampleCount::S4);
    } else if r.mips {
        desc = desc.with_mip_levels(extent.full_mip_count());
    }
    desc
}

fn final_state(code: u8, image: bool) -> ResourceState {
    match (code, image) {
        (0, true) => ResourceState::PRESENT,
        (1, true) => ResourceState::SHADER_READ,
        (2, _) => ResourceState::HOST_READ,
        _ => ResourceState::UNDEFINED,
    }
}

fn build(spec: &Spec) -> Built {
    let mut g: GraphBuilder<u32> = GraphBuilder::new();
    let mut descs: Vec<Option<ImageDesc>> = Vec::new();
    let mut has_content: Vec<bool> = Vec::new();
    for (i, r) in spec.resources.iter().enumerate() {
        let name = format!("r{i}");
        let import = Import {
            initial: if r.image {
                ResourceState::SHADER_READ
            } else {
                ResourceState::UNDEFINED
            },
            content: if r.import == 2 {
                InitialContent::Preserve
            } else {
                InitialContent::Discard
            },
            final_state: final_state(r.final_layout, r.image),
        };
        if r.image {
            let desc = image_desc(r);
            if r.import >= 2 {
                g.import_image(name, desc, import);
            } else {
                g.create_image(name, desc);
            }
            descs.push(Some(desc));
        } else {
            if r.import >= 2 {
                g.import_buffer(name, u64::from(r.size), import);
            } else {
                g.create_buffer(name, u64::from(r.size));
            }
            descs.push(None);
        }
        has_content.push(r.import == 2);
    }
    let n = descs.len();
    let mut mirror: Vec<Vec<MirrorUse>> = Vec::new();
    for (p, pass) in spec.passes.iter().enumerate() {
        let kind =
            [PassKind::Raster, PassKind::Compute, PassKind::Transfer][pass.kind as usize % 3];
        let class = CLASSES[pass.class as usize % CLASSES.len()];
        let coverage = if pass.full {
            Coverage::Full
        } else {
            Coverage::Partial
        };
        let extent = EXTENTS[pass.extent as usize % 2];
        let mut uses: Vec<(ResourceId, UseKind)> = Vec::new();
        let mut used = vec![false; n];
        let mut samples: Option<SampleCount> = None;
        let mut colors = 0;
        let mut has_depth = false;
        for &(k, pick, clear) in &pass.uses {
            if spec.chaos {
                let resource = ResourceId(u32::from(pick) % (n as u32 + 2));
                let use_kind = chaos_kind(kind, k, clear, resource);
                uses.push((resource, use_kind));
                continue;
            }
            let Some(use_kind) = valid_kind(kind, k, clear) else {
                continue;
            };
            let fits = |i: usize| -> bool {
                if used[i] {
                    return false;
                }
                let d = descs[i];
                let content = has_content[i];
                match use_kind {
                    UseKind::ColorAttachment { .. } => d.is_some_and(|d| {
                        !d.format.is_depth_stencil()
                            && d.extent_px == extent
                            && samples.is_none_or(|s| s == d.samples)
                            && d.mip_levels == 1
                    }),
                    UseKind::DepthStencilAttachment { .. } => d.is_some_and(|d| {
                        d.format.is_depth_stencil()
                            && d.extent_px == extent
                            && samples.is_none_or(|s| s == d.samples)
                            && d.mip_levels == 1
                    }),
                    UseKind::DepthStencilReadOnly => {
                        content
                            && d.is_some_and(|d| {
                                d.format.is_depth_stencil()
                                    && d.extent_px == extent
                                    && samples.is_none_or(|s| s == d.samples)
                                    && d.mip_levels == 1
                            })
                    }
                    UseKind::InputAttachment => {
                        content && d.is_some_and(|d| d.extent_px == extent && d.mip_levels == 1)
                    }
                    UseKind::Sampled => content && d.is_some(),
                    UseKind::StorageRead | UseKind::TransferSrc => content,
                    UseKind::Uniform
                    | UseKind::Vertex
                    | UseKind::Index
                    | UseKind::Indirect
                    | UseKind::ConditionalPredicate => content && d.is_none(),
                    UseKind::StorageWrite | UseKind::StorageReadWrite | UseKind::TransferDst => {
                        d.is_none_or(|d| d.samples == SampleCount::S1)
                    }
                    UseKind::ResolveTarget { .. } => false,
                }
            };
            let candidates: Vec<usize> = (0..n).filter(|&i| fits(i)).collect();
            if candidates.is_empty() {
                continue;
            }
            let i = candidates[pick as usize % candidates.len()];
            let is_attachment = matches!(
                use_kind,
                UseKind::ColorAttachment { .. }
                    | UseKind::DepthStencilAttachment { .. }
                    | UseKind::DepthStencilReadOnly
            );
            if is_attachment {
                samples = samples.or(descs[i].map(|d| d.samples));
            }
            if matches!(use_kind, UseKind::ColorAttachment { .. }) {
                if colors == 4 {
                    continue;
                }
                colors += 1;
            }
            // One depth-stencil attachment per pass.
            if matches!(
                use_kind,
                UseKind::DepthStencilAttachment { .. } | UseKind::DepthStencilReadOnly
            ) {
                if has_depth {
                    continue;
                }
                has_depth = true;
            }
            used[i] = true;
            uses.push((ResourceId(i as u32), use_kind));
            // A multisampled colour may be resolved into a matching single-sample image.
            if let (UseKind::ColorAttachment { .. }, Some(d)) = (use_kind, descs[i]) {
                if d.samples != SampleCount::S1 && clear {
                    let target = (0..n).find(|&t| {
                        !used[t]
                            && descs[t].is_some_and(|td| {
                                td.samples == SampleCount::S1
                                    && td.format == d.format
                                    && td.extent_px == d.extent_px
                                    && td.mip_levels == 1
                            })
                    });
                    if let Some(t) = target {
                        used[t] = true;
                        uses.push((
                            ResourceId(t as u32),
                            UseKind::ResolveTarget {
                                source: ResourceId(i as u32),
                            },
                        ));
                    }
                }
            }
        }

        let payload = p as u32;
        let id = match kind {
            PassKind::Raster => {
                let mut b = g.raster_pass(format!("p{p}"), class, payload);
                for &(r, u) in &uses {
                    raster_use(&mut b, r, u);
                }
                let attached = uses.iter().any(|(_, u)| u.is_attachment());
                if !attached && (!spec.chaos || pass.full) {
                    b.render_area(extent);
                }
                b.coverage(coverage);
                if pass.always {
                    b.retention(Retention::Always);
                }
                b.id()
            }
            PassKind::Compute => {
                let mut b = g.compute_pass(format!("p{p}"), class, payload);
                for &(r, u) in &uses {
                    match u {
                        UseKind::Sampled => b.sampled(ImageId(r)),
                        UseKind::StorageRead => b.storage_read(r),
                        UseKind::StorageWrite => b.storage_write(r),
                        UseKind::StorageReadWrite => b.storage_read_write(r),
                        UseKind::Uniform => b.uniform(BufferId(r)),
                        UseKind::ConditionalPredicate => b.predicate(BufferId(r)),
                        _ => b.indirect(BufferId(r)),
                    };
                }
                b.coverage(coverage);
                if pass.always {
                    b.retention(Retention::Always);
                }
                if spec.async_passes & (1 << (p % 64)) != 0 {
                    b.async_compute();
                }
                b.id()
            }
            PassKind::Transfer => {
                let mut b = g.transfer_pass(format!("p{p}"), class, payload);
                for &(r, u) in &uses {
                    match u {
                        UseKind::TransferSrc => b.transfer_src(r),
                        _ => b.transfer_dst(r),
                    };
                }
                b.coverage(coverage);
                if pass.always {
                    b.retention(Retention::Always);
                }
                if spec.async_passes & (1 << (p % 64)) != 0 {
                    b.async_compute();
                }
                b.id()
            }
        };
        assert_eq!(id, PassId(p as u32));

        let mut m: Vec<MirrorUse> = Vec::new();
        for &(r, u) in &uses {
            let keeps_old = coverage == Coverage::Partial;
            let (reads_prior, writes) = match u {
                UseKind::ColorAttachment { clear } => (clear.is_none() && keeps_old, true),
                UseKind::DepthStencilAttachment { clear } => (clear.is_none() && keeps_old, true),
                UseKind::ResolveTarget { .. } => (false, true),
                UseKind::StorageWrite | UseKind::TransferDst => (keeps_old, true),
                UseKind::StorageReadWrite => (keeps_old, true),
                _ => (true, false),
            };
            match m.iter_mut().find(|x| x.resource == r.0) {
                Some(x) => {
                    x.reads_prior |= reads_prior;
                    x.writes |= writes;
                }
                None => m.push(MirrorUse {
                    resource: r.0,
                    reads_prior,
                    writes,
                }),
            }
            if writes {
                if let Some(c) = has_content.get_mut(r.index()) {
                    *c = true;
                }
            }
        }
        mirror.push(m);
    }

    let mut exports = Vec::new();
    for &e in &spec.exports {
        let index = if spec.chaos {
            u32::from(e) % (n as u32 + 1)
        } else {
            let with_content: Vec<usize> = (0..n).filter(|&i| has_content[i]).collect();
            if with_content.is_empty() {
                continue;
            }
            with_content[e as usize % with_content.len()] as u32
        };
        g.export(ResourceId(index));
        exports.push(index);
    }
    let passes = spec.passes.len().max(1) as u32;
    for &(a, b) in &spec.dependencies {
        let (a, b) = (u32::from(a) % (passes + 1), u32::from(b) % (passes + 1));
        // Valid graphs only get forward dependencies (no cycles); chaos gets anything.
        if spec.chaos || (a < b && b < spec.passes.len() as u32) {
            g.add_dependency(PassId(a), PassId(b));
        }
    }
    Built {
        graph: g,
        mirror,
        exports,
    }
}

fn valid_kind(kind: PassKind, k: u8, clear: bool) -> Option<UseKind> {
    Some(match kind {
        PassKind::Raster => match k {
            0..=3 => UseKind::ColorAttachment {
                clear: clear.then_some(ClearColor::BLACK),
            },
            4 | 5 => UseKind::DepthStencilAttachment {
                clear: clear.then_some(ClearDepthStencil::REVERSE_Z),
            },
            6 => UseKind::DepthStencilReadOnly,
            7 => UseKind::InputAttachment,
            8 => UseKind::Sampled,
            9 => UseKind::StorageRead,
            10 => UseKind::StorageWrite,
            11 => UseKind::Vertex,
            12 => UseKind::Index,
            13 => UseKind::Indirect,
            14 => UseKind::Uniform,
            15 => UseKind::ConditionalPredicate,
            _ => return None,
        },
        PassKind::Compute => match k % 7 {
            0 => UseKind::Sampled,
            1 => UseKind::StorageRead,
            2 => UseKind::StorageWrite,
            3 => UseKind::StorageReadWrite,
            4 => UseKind::Uniform,
            5 => UseKind::Indirect,
            _ => UseKind::ConditionalPredicate,
        },
        PassKind::Transfer => {
            if k.is_multiple_of(2) {
                UseKind::TransferSrc
            } else {
                UseKind::TransferDst
            }
        }
    })
}

fn chaos_kind(kind: PassKind, k: u8, clear: bool, resource: ResourceId) -> UseKind {
    match (kind, k) {
        (PassKind::Raster, 15) => UseKind::ResolveTarget {
            source: ResourceId(resource.0.wrapping_add(1)),
        },
        (PassKind::Raster, 7) => UseKind::InputAttachment,
        _ => valid_kind(kind, k, clear).unwrap_or(UseKind::Sampled),
    }
}

fn raster_use(b: &mut RasterPassBuilder<'_, u32>, r: ResourceId, u: UseKind) {
    let image = ImageId(r);
    match u {
        UseKind::ColorAttachment { clear: Some(c) } => b.color_clear(image, c),
        UseKind::ColorAttachment { clear: None } => b.color(image),
        UseKind::DepthStencilAttachment { clear: Some(c) } => b.depth_stencil_clear(image, c),
        UseKind::DepthStencilAttachment { clear: None } => b.depth_stencil(image),
        UseKind::DepthStencilReadOnly => b.depth_stencil_read_only(image),
        UseKind::InputAttachment => b.input(image),
        UseKind::ResolveTarget { source } => b.resolve(ImageId(source), image),
        UseKind::Sampled => b.sampled(image),
        UseKind::StorageRead => b.storage_read(r),
        UseKind::StorageWrite => b.storage_write(r),
        UseKind::StorageReadWrite => b.storage_read_write(r),
        UseKind::Vertex => b.vertex(BufferId(r)),
        UseKind::Index => b.index(BufferId(r)),
        UseKind::Indirect => b.indirect(BufferId(r)),
        UseKind::ConditionalPredicate => b.predicate(BufferId(r)),
        UseKind::Uniform => b.uniform(BufferId(r)),
        UseKind::TransferSrc | UseKind::TransferDst => b,
    };
}

/// The last pass declared before `pass` that writes `resource`.
fn producer(mirror: &[Vec<MirrorUse>], pass: usize, resource: u32) -> Option<usize> {
    (0..pass)
        .rev()
        .find(|&q| mirror[q].iter().any(|u| u.resource == resource && u.writes))
}

/// Position in execution order of every surviving pass (by `PassId`).
fn positions(plan: &Plan, n: usize) -> Vec<Option<usize>> {
    let mut pos = vec![None; n];
    for (i, p) in plan.passes.iter().enumerate() {
        pos[p.id.index()] = Some(i);
    }
    pos
}

fn check_reads_after_writes(plan: &Plan, mirror: &[Vec<MirrorUse>]) -> Result<(), String> {
    let pos = positions(plan, mirror.len());
    for p in &plan.passes {
        for u in mirror[p.id.index()].iter().filter(|u| u.reads_prior) {
            if let Some(w) = producer(mirror, p.id.index(), u.resource) {
                match (pos[w], pos[p.id.index()]) {
                    (Some(wp), Some(rp)) if wp < rp => {}
                    _ => {
                        return Err(format!(
                            "{} reads r{} written by p{w}, which is pruned or later",
                            p.name, u.resource
                        ))
                    }
                }
            }
        }
    }
    Ok(())
}

fn check_pruned_contribute_nothing(
    plan: &Plan,
    mirror: &[Vec<MirrorUse>],
    exports: &[u32],
) -> Result<(), String> {
    let pos = positions(plan, mirror.len());
    for c in &plan.pruned {
        let c_index = c.id.index();
        if pos[c_index].is_some() {
            return Err(format!("{} is both pruned and planned", c.name));
        }
        for p in &plan.passes {
            for u in mirror[p.id.index()].iter().filter(|u| u.reads_prior) {
                if producer(mirror, p.id.index(), u.resource) == Some(c_index) {
                    return Err(format!("{} reads what pruned {} wrote", p.name, c.name));
                }
            }
        }
        for &e in exports {
            if producer(mirror, mirror.len(), e) == Some(c_index) {
                return Err(format!(
                    "pruned {} is the last writer of export r{e}",
                    c.name
                ));
            }
        }
    }
    Ok(())
}

/// Every resource that held bytes a later resource takes over is reached through the hand-offs
/// (directly, or through the owners in between): each byte's owners form a chain, and each
/// hand-off makes the new owner wait for the previous one.
fn check_handoffs_complete(plan: &Plan) -> Result<(), String> {
    let handed = |to: ResourceId| plan.aliasing.handoffs.iter().filter(move |h| h.to == to);
    for b in &plan.resources {
        let (Some(sb), Some(lb)) = (b.memory, b.lifetime) else {
            continue;
        };
        // Everything reachable from `b` through hand-offs.
        let mut reached = vec![false; plan.resources.len()];
        let mut stack = vec![b.id];
        while let Some(r) = stack.pop() {
            for h in handed(r) {
                if !std::mem::replace(&mut reached[h.from.index()], true) {
                    stack.push(h.from);
                }
            }
        }
        for a in &plan.resources {
            let (Some(sa), Some(la)) = (a.memory, a.lifetime) else {
                continue;
            };
            if a.id != b.id && sa.overlaps(&sb) && la.last < lb.first && !reached[a.id.index()] {
                return Err(format!(
                    "{} takes over memory of {} with no hand-off chain to it",
                    b.name, a.name
                ));
            }
        }
    }
    Ok(())
}

fn check_aliasing(plan: &Plan) -> Result<(), String> {
    for a in &plan.resources {
        for b in &plan.resources {
            if a.id >= b.id {
                continue;
            }
            if let (Some(sa), Some(sb), Some(la), Some(lb)) =
                (a.memory, b.memory, a.lifetime, b.lifetime)
            {
                if sa.overlaps(&sb) && la.overlaps(lb) {
                    return Err(format!(
                        "{} and {} share memory while alive",
                        a.name, b.name
                    ));
                }
            }
        }
    }
    Ok(())
}

/// The stages a use touches, as the test models them (independently of the compiler).
fn stages_of(kind: PassKind, u: &UseKind, format: Option<Format>) -> PipelineStages {
    let shader = match kind {
        PassKind::Raster => PipelineStages::VERTEX_SHADER | PipelineStages::FRAGMENT_SHADER,
        PassKind::Compute => PipelineStages::COMPUTE_SHADER,
        PassKind::Transfer => PipelineStages::ALL_TRANSFER,
    };
    let tests = PipelineStages::EARLY_FRAGMENT_TESTS | PipelineStages::LATE_FRAGMENT_TESTS;
    match u {
        UseKind::ColorAttachment { .. } | UseKind::ResolveTarget { .. } => {
            PipelineStages::COLOR_ATTACHMENT_OUTPUT
        }
        UseKind::DepthStencilAttachment { .. } | UseKind::DepthStencilReadOnly => tests,
        UseKind::InputAttachment => {
            // An input attachment is also loaded and stored by its render pass.
            let store = if format.is_some_and(|f| f.is_depth_stencil()) {
                tests
            } else {
                PipelineStages::COLOR_ATTACHMENT_OUTPUT
            };
            PipelineStages::FRAGMENT_SHADER | store
        }
        UseKind::Sampled
        | UseKind::StorageRead
        | UseKind::StorageWrite
        | UseKind::StorageReadWrite
        | UseKind::Uniform => shader,
        UseKind::Vertex => PipelineStages::VERTEX_ATTRIBUTE_INPUT,
        UseKind::Index => PipelineStages::INDEX_INPUT,
        UseKind::Indirect => PipelineStages::DRAW_INDIRECT,
        UseKind::ConditionalPredicate => PipelineStages::CONDITIONAL_RENDERING,
        UseKind::TransferSrc | UseKind::TransferDst => PipelineStages::ALL_TRANSFER,
    }
}

/// The accesses a use must be made visible to (its reads and writes), and the writes it makes,
/// as the test models them: the least a barrier must name.
fn accesses_of(u: &UseKind) -> (AccessFlags, AccessFlags) {
    match u {
        UseKind::ColorAttachment { .. } | UseKind::ResolveTarget { .. } => (
            AccessFlags::COLOR_ATTACHMENT_WRITE,
            AccessFlags::COLOR_ATTACHMENT_WRITE,
        ),
        // The depth test reads what it then writes.
        UseKind::DepthStencilAttachment { .. } => (
            AccessFlags::DEPTH_STENCIL_ATTACHMENT_READ
                | AccessFlags::DEPTH_STENCIL_ATTACHMENT_WRITE,
            AccessFlags::DEPTH_STENCIL_ATTACHMENT_WRITE,
        ),
        UseKind::DepthStencilReadOnly => (
            AccessFlags::DEPTH_STENCIL_ATTACHMENT_READ,
            AccessFlags::NONE,
        ),
        UseKind::InputAttachment => (AccessFlags::INPUT_ATTACHMENT_READ, AccessFlags::NONE),
        UseKind::Sampled => (AccessFlags::SHADER_SAMPLED_READ, AccessFlags::NONE),
        UseKind::StorageRead => (AccessFlags::SHADER_STORAGE_READ, AccessFlags::NONE),
        UseKind::StorageWrite => (
            AccessFlags::SHADER_STORAGE_WRITE,
            AccessFlags::SHADER_STORAGE_WRITE,
        ),
        UseKind::StorageReadWrite => (
            AccessFlags::SHADER_STORAGE_READ | AccessFlags::SHADER_STORAGE_WRITE,
            AccessFlags::SHADER_STORAGE_WRITE,
        ),
        UseKind::Uniform => (AccessFlags::UNIFORM_READ, AccessFlags::NONE),
        UseKind::Vertex => (AccessFlags::VERTEX_ATTRIBUTE_READ, AccessFlags::NONE),
        UseKind::Index => (AccessFlags::INDEX_READ, AccessFlags::NONE),
        UseKind::Indirect => (AccessFlags::INDIRECT_COMMAND_READ, AccessFlags::NONE),
        UseKind::ConditionalPredicate => {
            (AccessFlags::CONDITIONAL_RENDERING_READ, AccessFlags::NONE)
        }
        UseKind::TransferSrc => (AccessFlags::TRANSFER_READ, AccessFlags::NONE),
        UseKind::TransferDst => (AccessFlags::TRANSFER_WRITE, AccessFlags::TRANSFER_WRITE),
    }
}

/// The read of an attachment's LOAD op.
fn attachment_read(format: Option<Format>) -> AccessFlags {
    if format.is_some_and(|f| f.is_depth_stencil()) {
        AccessFlags::DEPTH_STENCIL_ATTACHMENT_READ
    } else {
        AccessFlags::COLOR_ATTACHMENT_READ
    }
}

/// The write an attachment's store op makes.
fn store_access(format: Option<Format>) -> AccessFlags {
    if format.is_some_and(|f| f.is_depth_stencil()) {
        AccessFlags::DEPTH_STENCIL_ATTACHMENT_WRITE
    } else {
        AccessFlags::COLOR_ATTACHMENT_WRITE
    }
}

/// Accesses that some stage of `stages` performs (the synchronization2 table of supported
/// access types, for the stages and accesses tilegraph uses).
fn supported_accesses(stages: PipelineStages) -> AccessFlags {
    let shader = PipelineStages::VERTEX_SHADER
        | PipelineStages::FRAGMENT_SHADER
        | PipelineStages::COMPUTE_SHADER
        | PipelineStages::PRE_RASTERIZATION_SHADERS;
    let tests = PipelineStages::EARLY_FRAGMENT_TESTS | PipelineStages::LATE_FRAGMENT_TESTS;
    let transfer = PipelineStages::ALL_TRANSFER
        | PipelineStages::COPY
        | PipelineStages::RESOLVE
        | PipelineStages::BLIT
        | PipelineStages::CLEAR;
    let table = [
        (
            PipelineStages::DRAW_INDIRECT,
            AccessFlags::INDIRECT_COMMAND_READ,
        ),
        (
            PipelineStages::VERTEX_INPUT | PipelineStages::INDEX_INPUT,
            AccessFlags::INDEX_READ,
        ),
        (
            PipelineStages::VERTEX_INPUT | PipelineStages::VERTEX_ATTRIBUTE_INPUT,
            AccessFlags::VERTEX_ATTRIBUTE_READ,
        ),
        (
            shader,
            AccessFlags::UNIFORM_READ
                | AccessFlags::SHADER_READ
                | AccessFlags::SHADER_WRITE
                | AccessFlags::SHADER_SAMPLED_READ
                | AccessFlags::SHADER_STORAGE_READ
                | AccessFlags::SHADER_STORAGE_WRITE,
        ),
        (
            PipelineStages::FRAGMENT_SHADER,
            AccessFlags::INPUT_ATTACHMENT_READ,
        ),
        (
            PipelineStages::COLOR_ATTACHMENT_OUTPUT,
            AccessFlags::COLOR_ATTACHMENT_READ | AccessFlags::COLOR_ATTACHMENT_WRITE,
        ),
        (
            tests,
            AccessFlags::DEPTH_STENCIL_ATTACHMENT_READ
                | AccessFlags::DEPTH_STENCIL_ATTACHMENT_WRITE,
        ),
        (
            transfer,
            AccessFlags::TRANSFER_READ | AccessFlags::TRANSFER_WRITE,
        ),
        (
            PipelineStages::HOST,
            AccessFlags::HOST_READ | AccessFlags::HOST_WRITE,
        ),
        (
            PipelineStages::CONDITIONAL_RENDERING,
            AccessFlags::CONDITIONAL_RENDERING_READ,
        ),
    ];
    if stages.intersects(PipelineStages::ALL_COMMANDS) {
        return AccessFlags::from_bits(u64::MAX);
    }
    let stages = if stages.intersects(PipelineStages::ALL_GRAPHICS) {
        stages
            | PipelineStages::DRAW_INDIRECT
            | PipelineStages::VERTEX_INPUT
            | PipelineStages::INDEX_INPUT
            | PipelineStages::VERTEX_ATTRIBUTE_INPUT
            | PipelineStages::VERTEX_SHADER
            | PipelineStages::PRE_RASTERIZATION_SHADERS
            | PipelineStages::FRAGMENT_SHADER
            | tests
            | PipelineStages::COLOR_ATTACHMENT_OUTPUT
            | PipelineStages::CONDITIONAL_RENDERING
    } else {
        stages
    };
    let mut out = AccessFlags::MEMORY_READ | AccessFlags::MEMORY_WRITE;
    for (from, access) in table {
        if stages.intersects(from) {
            out |= access;
        }
    }
    out
}

/// One work step's access to one resource.
#[derive(Debug, Clone, Copy)]
struct StepAccess {
    step: usize,
    stages: PipelineStages,
    writes: bool,
    /// What the step's accesses must be made visible to.
    access: AccessFlags,
    /// The writes it makes.
    write_access: AccessFlags,
}

/// Per resource, its accesses by work step, in step order.
fn step_accesses(plan: &Plan) -> Vec<Vec<StepAccess>> {
    let kind_of = |id: PassId| plan.pass(id).map(|p| p.kind);
    let mut out: Vec<Vec<StepAccess>> = vec![Vec::new(); plan.resources.len()];
    let mut add = |r: ResourceId,
                   step: usize,
                   stages: PipelineStages,
                   (access, write_access): (AccessFlags, AccessFlags)| {
        let list = &mut out[r.index()];
        let writes = !write_access.is_empty();
        match list.last_mut() {
            Some(last) if last.step == step => {
                last.stages |= stages;
                last.writes |= writes;
                last.access |= access;
                last.write_access |= write_access;
            }
            _ => list.push(StepAccess {
                step,
                stages,
                writes,
                access,
                write_access,
            }),
        }
    };
    for (i, s) in plan.steps.iter().enumerate() {
        let passes: Vec<PassId> = match s {
            Step::RenderPass(rp) => {
                for a in &rp.attachments {
                    let format = plan.resources[a.resource.index()].format();
                    let write = store_access(format);
                    // The load op reads (LOAD) or writes (CLEAR, DONT_CARE) the attachment.
                    let load = if a.load_op == LoadOp::Load {
                        (attachment_read(format), AccessFlags::NONE)
                    } else {
                        (write, write)
                    };
                    add(a.resource, i, PipelineStages::NONE, load);
                    // The store op writes it, unless it is NONE (no access).
                    if a.store_op != StoreOp::None {
                        add(a.resource, i, PipelineStages::NONE, (write, write));
                    }
                }
                rp.subpasses.iter().map(|s| s.pass).collect()
            }
            Step::Compute { pass } | Step::Transfer { pass } => vec![*pass],
            Step::Barriers(_) | Step::Flush(_) => continue,
        };
        for id in passes {
            let (Some(p), Some(kind)) = (plan.pass(id), kind_of(id)) else {
                continue;
            };
            for u in &p.uses {
                let format = plan.resources[u.resource.index()].format();
                let (mut needs, writes) = accesses_of(&u.kind);
                // Drawing over old content without covering it all blends with it.
                if matches!(u.kind, UseKind::ColorAttachment { clear: None })
                    && p.coverage == Coverage::Partial
                {
                    needs |= AccessFlags::COLOR_ATTACHMENT_READ;
                }
                add(
                    u.resource,
                    i,
                    stages_of(kind, &u.kind, format),
                    (needs, writes),
                );
            }
        }
    }
    out
}

/// A barrier's two scopes.
#[derive(Debug, Clone, Copy)]
struct Scopes {
    src: PipelineStages,
    src_access: AccessFlags,
    dst: PipelineStages,
    dst_access: AccessFlags,
}

fn barriers_between(plan: &Plan, r: ResourceId, from: usize, to: usize) -> Vec<Scopes> {
    plan.steps[from + 1..to]
        .iter()
        .filter_map(|s| match s {
            Step::Barriers(b) => Some(
                b.images
                    .iter()
                    .filter(|x| x.resource == r)
                    .map(|x| Scopes {
                        src: x.src_stages,
                        src_access: x.src_access,
                        dst: x.dst_stages,
                        dst_access: x.dst_access,
                    })
                    .chain(
                        b.buffers
                            .iter()
                            .filter(|x| x.resource == r)
                            .map(|x| Scopes {
                                src: x.src_stages,
                                src_access: x.src_access,
                                dst: x.dst_stages,
                                dst_access: x.dst_access,
                            }),
                    )
                    .collect::<Vec<_>>(),
            ),
            _ => None,
        })
        .flatten()
        .collect()
}

/// The submission each step is in.
fn submission_of_steps(plan: &Plan) -> Vec<usize> {
    let mut of = vec![usize::MAX; plan.steps.len()];
    for (k, s) in plan.submissions.iter().enumerate() {
        for i in s.steps() {
            if let Some(x) = of.get_mut(i) {
                *x = k;
            }
        }
    }
    of
}

/// Whether a conflicting access in step `a` is ordered before one in step `b` on the other
/// queue: `b`'s submission, or an earlier one of its queue (a semaphore wait's second scope
/// takes in every later command of the queue), waits on `a`'s (or a later one of its queue,
/// whose signal comes after it), at every stage of `b`'s access the queue has.
fn waits_for(plan: &Plan, of: &[usize], a: usize, b: usize, b_stages: PipelineStages) -> bool {
    let (sa, sb) = (of[a], of[b]);
    let queue_a = plan.submissions[sa].queue;
    let queue_b = plan.submissions[sb].queue;
    let need = b_stages.intersection(queue_b.stages());
    plan.submissions[..=sb]
        .iter()
        .filter(|s| s.queue == queue_b)
        .flat_map(|s| &s.waits)
        .any(|w| {
            w.submission.index() >= sa
                && plan.submissions[w.submission.index()].queue == queue_a
                && w.dst_stages.contains(need)
        })
}

fn check_hazards(plan: &Plan) -> Result<(), String> {
    let accesses = step_accesses(plan);
    let of = submission_of_steps(plan);
    // Consecutive accesses of one resource where either writes need a barrier on it between
    // them that waits for the first and blocks the second. After a write (read-after-write,
    // write-after-write) it is also a memory dependency: the write is in its source access
    // scope and every access of the second step in its destination access scope. A write after
    // reads needs only the execution dependency.
    for (r, list) in accesses.iter().enumerate() {
        let id = ResourceId(r as u32);
        for pair in list.windows(2) {
            let (a, b) = (pair[0], pair[1]);
            if !(a.writes || b.writes) {
                continue;
            }
            if plan.submissions[of[a.step]].queue != plan.submissions[of[b.step]].queue {
                if !waits_for(plan, &of, a.step, b.step, b.stages) {
                    return Err(format!(
                        "{}: step {} then step {} on the other queue, without a wait",
                        plan.resources[r].name, a.step, b.step
                    ));
                }
                continue;
            }
            let found = barriers_between(plan, id, a.step, b.step);
            let covers = |x: &Scopes| {
                x.src.contains(a.stages)
                    && x.dst.contains(b.stages)
                    && (!a.writes
                        || (x.src_access.contains(a.write_access)
                            && x.dst_access.contains(b.access)))
            };
            if !found.iter().any(covers) {
                return Err(format!(
                    "{}: step {} then step {}: no barrier covers {} / {} -> {} / {} (found \
                     {found:?})",
                    plan.resources[r].name,
                    a.step,
                    b.step,
                    a.stages,
                    a.write_access,
                    b.stages,
                    b.access
                ));
            }
        }
    }
    // Memory handed from one resource to another: the new owner's first barrier waits for the
    // old owner's last accesses.
    for h in &plan.aliasing.handoffs {
        let (Some(from_last), Some(to_first)) = (
            accesses[h.from.index()].last().copied(),
            accesses[h.to.index()].first().copied(),
        ) else {
            continue;
        };
        let found = barriers_between(plan, h.to, from_last.step, to_first.step);
        let covers = |x: &Scopes| {
            x.src.contains(from_last.stages) && x.src_access.contains(from_last.write_access)
        };
        if !found.iter().any(covers) {
            return Err(format!(
                "{} takes memory of {} without waiting for it",
                plan.resources[h.to.index()].name,
                plan.resources[h.from.index()].name
            ));
        }
    }
    Ok(())
}

/// The layout an image needs for a use.
fn layout_for(u: &UseKind, format: Format) -> Layout {
    let depth = format.is_depth_stencil();
    match u {
        UseKind::StorageRead | UseKind::StorageWrite | UseKind::StorageReadWrite => Layout::General,
        UseKind::Sampled | UseKind::InputAttachment if depth => Layout::DepthStencilReadOnly,
        UseKind::Sampled | UseKind::InputAttachment => Layout::ShaderReadOnly,
        UseKind::TransferSrc => Layout::TransferSrc,
        UseKind::TransferDst => Layout::TransferDst,
        UseKind::ColorAttachment { .. } | UseKind::ResolveTarget { .. } => Layout::ColorAttachment,
        UseKind::DepthStencilAttachment { .. } => Layout::DepthStencilAttachment,
        UseKind::DepthStencilReadOnly => Layout::DepthStencilReadOnly,
        UseKind::Uniform
        | UseKind::Vertex
        | UseKind::Index
        | UseKind::Indirect
        | UseKind::ConditionalPredicate => Layout::Undefined,
    }
}

fn check_layouts(plan: &Plan) -> Result<(), String> {
    let mut layout: Vec<Layout> = plan
        .resources
        .iter()
        .map(|r| match r.origin {
            Origin::Imported(i) if i.content == InitialContent::Preserve => i.initial.layout,
            _ => Layout::Undefined,
        })
        .collect();
    let name = |r: ResourceId| plan.resources[r.index()].name.clone();
    for (i, s) in plan.steps.iter().enumerate() {
        match s {
            Step::Barriers(b) => {
                for x in &b.images {
                    let current = layout[x.resource.index()];
                    if x.old_layout != current && x.old_layout != Layout::Undefined {
                        return Err(format!(
                            "step {i}: {} barrier from {} but it is {current}",
                            name(x.resource),
                            x.old_layout
                        ));
                    }
                    if x.new_layout == Layout::Undefined {
                        return Err(format!(
                            "step {i}: {} transitions to Undefined",
                            name(x.resource)
                        ));
                    }
                    layout[x.resource.index()] = x.new_layout;
                }
            }
            Step::RenderPass(rp) => {
                for a in &rp.attachments {
                    let current = layout[a.resource.index()];
                    if a.initial_layout != current && a.initial_layout != Layout::Undefined {
                        return Err(format!(
                            "step {i}: {} starts the render pass in {} but it is {current}",
                            name(a.resource),
                            a.initial_layout
                        ));
                    }
                }
                for sub in &rp.subpasses {
                    let Some(p) = plan.pass(sub.pass) else {
                        continue;
                    };
                    for u in p.uses.iter().filter(|u| !u.kind.is_attachment()) {
                        if let Some(f) = plan.resources[u.resource.index()].format() {
                            let needed = layout_for(&u.kind, f);
                            if rp.attachments.iter().all(|a| a.resource != u.resource)
                                && layout[u.resource.index()] != needed
                            {
                                return Err(format!(
                                    "step {i}: {} used as {} in {} but is {}",
                                    name(u.resource),
                                    u.kind,
                                    p.name,
                                    layout[u.resource.index()]
                                ));
                            }
                        }
                    }
                }
                for a in &rp.attachments {
                    layout[a.resource.index()] = a.final_layout;
                }
            }
            Step::Compute { pass } | Step::Transfer { pass } => {
                let Some(p) = plan.pass(*pass) else { continue };
                for u in &p.uses {
                    if let Some(f) = plan.resources[u.resource.index()].format() {
                        if layout[u.resource.index()] != layout_for(&u.kind, f) {
                            return Err(format!(
                                "step {i}: {} used as {} but is {}",
                                name(u.resource),
                                u.kind,
                                layout[u.resource.index()]
                            ));
                        }
                    }
                }
            }
            Step::Flush(_) => {}
        }
    }
    for r in &plan.resources {
        if let (Origin::Imported(i), true) = (r.origin, r.is_image()) {
            let wanted = i.final_state.layout;
            if wanted != Layout::Undefined && layout[r.id.index()] != wanted {
                return Err(format!(
                    "{} ends in {} not {wanted}",
                    r.name,
                    layout[r.id.index()]
                ));
            }
        }
    }
    Ok(())
}

fn check_structure(plan: &Plan) -> Result<(), String> {
    let mut seen = vec![
        0u32;
        plan.passes
            .iter()
            .map(|p| p.id.index() + 1)
            .max()
            .unwrap_or(0)
    ];
    for s in &plan.steps {
        let ids: Vec<PassId> = match s {
            Step::RenderPass(rp) => rp.subpasses.iter().map(|s| s.pass).collect(),
            Step::Compute { pass } | Step::Transfer { pass } => vec![*pass],
            _ => continue,
        };
        for id in ids {
            match seen.get_mut(id.index()) {
                Some(c) => *c += 1,
                None => return Err(format!("step records unknown pass {id}")),
            }
        }
    }
    for p in &plan.passes {
        if seen[p.id.index()] != 1 {
            return Err(format!(
                "{} is recorded {} times",
                p.name,
                seen[p.id.index()]
            ));
        }
        // Its step and subpass are where it is recorded.
        let recorded = match (plan.steps.get(p.step.index()), p.subpass) {
            (Some(Step::RenderPass(rp)), Some(s)) => {
                rp.subpasses.get(s.0 as usize).map(|sub| sub.pass) == Some(p.id)
            }
            (Some(Step::Compute { pass } | Step::Transfer { pass }), None) => *pass == p.id,
            _ => false,
        };
        if !recorded {
            return Err(format!(
                "{} says step {:?} subpass {:?}, which does not record it",
                p.name, p.step, p.subpass
            ));
        }
    }
    Ok(())
}

/// Inside a render pass, consecutive subpass uses of an attachment where either writes need a
/// subpass dependency from the first to the second.
fn check_subpass_dependencies(plan: &Plan) -> Result<(), String> {
    for (step, rp) in plan.render_passes() {
        for (index, a) in rp.attachments.iter().enumerate() {
            let format = plan.resources[a.resource.index()].format();
            let mut previous: Option<(u32, PipelineStages, bool)> = None;
            for (s, sub) in rp.subpasses.iter().enumerate() {
                let Some(p) = plan.pass(sub.pass) else {
                    continue;
                };
                let uses: Vec<&PassUse> =
                    p.uses.iter().filter(|u| u.resource == a.resource).collect();
                if uses.is_empty() {
                    continue;
                }
                let mut stages = PipelineStages::NONE;
                let mut writes = false;
                for u in &uses {
                    stages |= stages_of(p.kind, &u.kind, format);
                    writes |= u.kind.writes();
                }
                if let Some((ps, pstages, pwrites)) = previous {
                    if pwrites || writes {
                        let covered = rp.dependencies.iter().any(|d| {
                            d.src_subpass.0 == ps
                                && d.dst_subpass.0 == s as u32
                                && d.src_stages.intersects(pstages)
                                && d.dst_stages.intersects(stages)
                        });
                        if !covered {
                            return Err(format!(
                                "step {}: attachment #{index} {}: subpass {ps} -> {s} has no dependency",
                                step.0, plan.resources[a.resource.index()].name
                            ));
                        }
                    }
                }
                previous = Some((s as u32, stages, writes));
            }
        }
    }
    Ok(())
}

/// An attachment whose content survives the render pass (stored, or kept with NONE) is used or
/// preserved by every subpass from its first use on: a subpass that does neither, after one that
/// used it, may leave it undefined (VkSubpassDescription), and the store would write that back.
fn check_preserved(plan: &Plan) -> Result<(), String> {
    for (step, rp) in plan.render_passes() {
        for (index, a) in rp.attachments.iter().enumerate() {
            if a.store_op == StoreOp::DontCare && a.stencil_store_op == StoreOp::DontCare {
                continue;
            }
            let att = AttachmentIndex(index as u32);
            let used_by = |sub: &tilegraph_graph::Subpass| {
                sub.colors.iter().any(|r| r.attachment == att)
                    || sub.inputs.iter().any(|r| r.attachment == att)
                    || sub.depth_stencil.is_some_and(|r| r.attachment == att)
                    || sub.resolves.iter().flatten().any(|r| r.attachment == att)
            };
            let Some(first) = rp.subpasses.iter().position(used_by) else {
                continue;
            };
            for (s, sub) in rp.subpasses.iter().enumerate().skip(first) {
                if !used_by(sub) && !sub.preserve.contains(&att) {
                    return Err(format!(
                        "step {}: attachment #{index} {} ({:?}) is neither used nor preserved by \
                         subpass {s}",
                        step.0,
                        plan.resources[a.resource.index()].name,
                        a.store_op
                    ));
                }
            }
        }
    }
    Ok(())
}

/// `StoreOp::None` keeps content without writing it: only on profiles that take it, for an
/// attachment the render pass loads and never writes (so its layout never changes inside the
/// render pass), with the same op for the stencil of a combined format.
fn check_store_none(plan: &Plan, store_op_none: bool) -> Result<(), String> {
    for step in &plan.steps {
        let Step::RenderPass(rp) = step else { continue };
        for a in &rp.attachments {
            let name = &plan.resources[a.resource.index()].name;
            if a.format.has_stencil() && a.stencil_store_op != a.store_op {
                return Err(format!(
                    "{name}: stencil store op differs from the depth store op"
                ));
            }
            if a.store_op != StoreOp::None {
                continue;
            }
            if !store_op_none {
                return Err(format!(
                    "{name}: store NONE on a profile without store_op_none"
                ));
            }
            if a.initial_layout != a.final_layout {
                return Err(format!(
                    "{name}: store NONE with a layout change {:?} -> {:?}",
                    a.initial_layout, a.final_layout
                ));
            }
            if a.load_op != LoadOp::Load {
                return Err(format!(
                    "{name}: store NONE after load {}",
                    a.load_op.name()
                ));
            }
            let written = rp.subpasses.iter().any(|s| {
                plan.pass(s.pass).is_some_and(|p| {
                    p.uses
                        .iter()
                        .any(|u| u.resource == a.resource && u.kind.writes())
                })
            });
            if written {
                return Err(format!(
                    "{name}: store NONE on an attachment the render pass writes"
                ));
            }
        }
    }
    Ok(())
}

/// Every barrier and subpass dependency names only accesses its stages perform (what the
/// validation layers check for VkMemoryBarrier2 and VkSubpassDependency2).
fn check_access_support(plan: &Plan) -> Result<(), String> {
    let check = |what: &str, stages: PipelineStages, access: AccessFlags| {
        let unsupported = access.difference(supported_accesses(stages));
        if unsupported.is_empty() {
            Ok(())
        } else {
            Err(format!(
                "{what}: {access} is not performed by {stages} ({unsupported})"
            ))
        }
    };
    for (i, step) in plan.steps.iter().enumerate() {
        match step {
            Step::Barriers(b) => {
                let scopes = b
                    .images
                    .iter()
                    .map(|x| {
                        (
                            x.resource,
                            x.src_stages,
                            x.src_access,
                            x.dst_stages,
                            x.dst_access,
                        )
                    })
                    .chain(b.buffers.iter().map(|x| {
                        (
                            x.resource,
                            x.src_stages,
                            x.src_access,
                            x.dst_stages,
                            x.dst_access,
                        )
                    }));
                for (r, src, src_access, dst, dst_access) in scopes {
                    let what = format!("step {i}: barrier on {}", plan.resources[r.index()].name);
                    check(&what, src, src_access)?;
                    check(&what, dst, dst_access)?;
                }
            }
            Step::RenderPass(rp) => {
                for d in &rp.dependencies {
                    let what = format!(
                        "step {i}: subpass dependency {} -> {}",
                        d.src_subpass.0, d.dst_subpass.0
                    );
                    check(&what, d.src_stages, d.src_access)?;
                    check(&what, d.dst_stages, d.dst_access)?;
                }
            }
            _ => {}
        }
    }
    Ok(())
}

/// Memory requirements unlike compile's estimates, as a driver's may be: each resource's size
/// scaled by `scale / 4` and aligned to `2^align_log2` (`scales` cycled over the resources).
fn other_requirements(plan: &Plan, scales: &[(u64, u32)]) -> Vec<MemoryRequirements> {
    plan.estimated_requirements()
        .iter()
        .enumerate()
        .map(|(i, r)| {
            let (scale, align_log2) = scales[i % scales.len()];
            MemoryRequirements {
                size_bytes: (r.size_bytes * scale / 4).max(1),
                alignment_bytes: 1 << align_log2,
            }
        })
        .collect()
}

/// Happens-before between submissions: the same queue in order, or a chain of waits.
fn ordered(plan: &Plan, from: usize, to: usize) -> bool {
    let mut reach = vec![false; plan.submissions.len()];
    reach[from] = true;
    for k in from + 1..plan.submissions.len() {
        let s = &plan.submissions[k];
        let same_queue_before = (from..k).any(|j| reach[j] && plan.submissions[j].queue == s.queue);
        reach[k] = same_queue_before || s.waits.iter().any(|w| reach[w.submission.index()]);
    }
    reach.get(to).copied().unwrap_or(false)
}

fn check_submissions(plan: &Plan, profile: &Profile) -> Result<(), String> {
    let subs = &plan.submissions;
    if subs.is_empty() {
        return Err("no submission".into());
    }
    let mut at = 0;
    for (k, s) in subs.iter().enumerate() {
        if s.first.index() != at || s.end.index() < s.first.index() {
            return Err(format!(
                "submission {k} does not start where {} ends",
                k.max(1) - 1
            ));
        }
        at = s.end.index();
        for w in &s.waits {
            if w.submission.index() >= k {
                return Err(format!("submission {k} waits on a later one"));
            }
            if subs[w.submission.index()].queue == s.queue {
                return Err(format!("submission {k} waits on its own queue"));
            }
        }
        for i in s.steps() {
            let pass_queue = match &plan.steps[i] {
                Step::Compute { pass } | Step::Transfer { pass } => {
                    plan.pass(*pass).map(|p| p.queue)
                }
                Step::RenderPass(_) | Step::Flush(_) => Some(Queue::Graphics),
                Step::Barriers(b) => {
                    if s.queue == Queue::AsyncCompute {
                        let all =
                            Queue::AsyncCompute.stages() | PipelineStages::CONDITIONAL_RENDERING;
                        let stages = b
                            .images
                            .iter()
                            .flat_map(|x| [x.src_stages, x.dst_stages])
                            .chain(b.buffers.iter().flat_map(|x| [x.src_stages, x.dst_stages]));
                        for st in stages {
                            if !all.contains(st) {
                                return Err(format!("step {i}: {st} on the compute queue"));
                            }
                        }
                    }
                    None
                }
            };
            if pass_queue.is_some_and(|q| q != s.queue) {
                return Err(format!("step {i} is in a submission of another queue"));
            }
        }
    }
    if at != plan.steps.len() {
        return Err("the submissions leave steps out".into());
    }
    let Some(last_async) = subs.iter().rposition(|s| s.queue == Queue::AsyncCompute) else {
        if subs.len() != 1 || plan.passes.iter().any(|p| p.queue != Queue::Graphics) {
            return Err("one queue, but not one submission".into());
        }
        return Ok(());
    };
    if !profile.queues.async_compute {
        return Err("async compute off, but a submission on the async queue".into());
    }
    let first_async = subs
        .iter()
        .position(|s| s.queue == Queue::AsyncCompute)
        .unwrap_or(0);
    let last = subs.len() - 1;
    if subs[0].queue != Queue::Graphics
        || subs[0].first != subs[0].end
        || subs[last].queue != Queue::Graphics
        || !ordered(plan, 0, first_async)
        || !ordered(plan, last_async, last)
    {
        return Err("the frame does not start and end on the graphics queue".into());
    }
    // Ownership transfers: each acquire has its release, earlier, on the other queue, with the
    // same layouts; none at all with concurrent sharing.
    let exclusive = profile.queues.sharing == QueueSharing::Exclusive;
    let of = submission_of_steps(plan);
    for (i, step) in plan.steps.iter().enumerate() {
        let Step::Barriers(b) = step else { continue };
        let acquires = b
            .images
            .iter()
            .map(|x| (x.resource, x.queue_transfer, x.old_layout, x.new_layout))
            .chain(b.buffers.iter().map(|x| {
                (
                    x.resource,
                    x.queue_transfer,
                    Layout::Undefined,
                    Layout::Undefined,
                )
            }));
        for (r, transfer, old, new) in acquires {
            let Some(t) = transfer else { continue };
            if !exclusive {
                return Err(format!(
                    "step {i}: an ownership transfer with concurrent sharing"
                ));
            }
            let released = subs[..of[i]].iter().any(|s| {
                s.queue == t.from
                    && s.releases.images.iter().any(|x| {
                        x.resource == r
                            && x.old_layout == old
                            && x.new_layout == new
                            && x.queue_transfer == Some(t)
                    })
                    || s.queues_release_buffer(r, t)
            });
            if !released {
                return Err(format!(
                    "step {i}: {} acquired without its release",
                    plan.resources[r.index()].name
                ));
            }
        }
    }
    if !exclusive && subs.iter().any(|s| !s.releases.is_empty()) {
        return Err("releases with concurrent sharing".into());
    }
    Ok(())
}

trait ReleasesBuffer {
    fn queues_release_buffer(&self, r: ResourceId, t: QueueTransfer) -> bool;
}

impl ReleasesBuffer for Submission {
    fn queues_release_buffer(&self, r: ResourceId, t: QueueTransfer) -> bool {
        self.queue == t.from
            && self
                .releases
                .buffers
                .iter()
                .any(|x| x.resource == r && x.queue_transfer == Some(t))
    }
}

fn check_plan(plan: &Plan, built: &Built, profile: &Profile) -> Result<(), String> {
    check_submissions(plan, profile)?;
    check_access_support(plan)?;
    check_store_none(plan, profile.render_pass.store_op_none)?;
    check_subpass_dependencies(plan)?;
    check_preserved(plan)?;
    check_structure(plan)?;
    check_reads_after_writes(plan, &built.mirror)?;
    check_pruned_contribute_nothing(plan, &built.mirror, &built.exports)?;
    check_aliasing(plan)?;
    check_handoffs_complete(plan)?;
    check_layouts(plan)?;
    check_hazards(plan)
}

proptest! {
    // 256 cases by default; PROPTEST_CASES asks for more (an explicit `cases` would ignore it).
    #![proptest_config(ProptestConfig {
        cases: std::env::var("PROPTEST_CASES").ok().and_then(|v| v.parse().ok()).unwrap_or(256),
        ..ProptestConfig::default()
    })]

    #[test]
    fn compiled_plans_keep_every_rule(spec in spec(200)) {
        let built = build(&spec);
        let profile = pick_profile(spec.profile);
        let first = built.graph.clone().compile(&profile);
        let second = built.graph.clone().compile(&profile);
        match (first, second) {
            (Ok(a), Ok(b)) => {
                prop_assert_eq!(&a.plan, &b.plan, "compile is not deterministic");
                if let Err(e) = check_plan(&a.plan, &built, &profile) {
                    return Err(TestCaseError::fail(format!("{e}\n{}", a.plan)));
                }
            }
            (Err(a), Err(b)) => {
                prop_assert_eq!(a.clone(), b, "errors differ between runs");
                prop_assert!(spec.chaos, "a valid graph failed to compile: {}", a);
            }
            (a, b) => prop_assert!(false, "runs disagree: {:?} vs {:?}", a.is_ok(), b.is_ok()),
        }
    }

    /// The executor re-places memory with the driver's requirements, which change sizes
    /// relative to each other (and so the placement) and add alignments: the rebuilt barriers
    /// keep every rule, and every slot has the size and alignment asked for.
    #[test]
    fn plans_re_placed_with_other_requirements_keep_every_rule(
        spec in spec(120),
        scales in prop::collection::vec((1u64..=8, 0u32..=16), 40),
    ) {
        let built = build(&spec);
        let profile = pick_profile(spec.profile);
        let Ok(compiled) = built.graph.clone().compile(&profile) else {
            return Ok(());
        };
        let mut plan = compiled.plan;
        let requirements = other_requirements(&plan, &scales);
        if let Err(e) = plan.reassign_aliases(&requirements) {
            return Err(TestCaseError::fail(format!("re-placing failed: {e}\n{plan}")));
        }
        for (r, req) in plan.resources.iter().zip(&requirements) {
            if let Some(slot) = r.memory {
                prop_assert_eq!(slot.size_bytes, req.size_bytes, "{}", r.name);
                prop_assert_eq!(slot.offset_bytes % req.alignment_bytes, 0, "{}", r.name);
            }
        }
        if let Err(e) = check_plan(&plan, &built, &profile) {
            return Err(TestCaseError::fail(format!("{e}\n{plan}")));
        }
    }
}

#[test]
fn the_generator_mostly_makes_graphs_that_compile() {
    // The properties above would be vacuous if most random graphs failed to compile.
    use proptest::strategy::ValueTree;
    use proptest::test_runner::TestRunner;
    let mut runner = TestRunner::deterministic();
    let strategy = spec(200);
    let (mut ok, mut total, mut pruned, mut merged) = (0, 0, 0, 0);
    let (mut two_queues, mut crossings, mut transfers) = (0, 0, 0);
    for _ in 0..64 {
        let Ok(tree) = strategy.new_tree(&mut runner) else {
            continue;
        };
        let mut s = tree.current();
        s.chaos = false;
        let built = build(&s);
        total += 1;
        if let Ok(c) = built.graph.compile(&pick_profile(s.profile)) {
            ok += 1;
            pruned += usize::from(!c.plan.pruned.is_empty());
            merged += usize::from(c.plan.render_passes().any(|(_, rp)| rp.subpasses.len() > 1));
            two_queues += usize::from(c.plan.submissions.len() > 1);
            let waits = c.plan.submissions.iter().flat_map(|s| &s.waits);
            let reasons: Vec<&WaitReason> = waits.flat_map(|w| &w.reasons).collect();
            crossings += usize::from(
                reasons
                    .iter()
                    .any(|r| matches!(r, WaitReason::Resource { .. })),
            );
            transfers += usize::from(
                reasons
                    .iter()
                    .any(|r| matches!(r, WaitReason::Resource { transfer: true, .. })),
            );
        }
    }
    // Three profiles of ten turn async compute on.
    assert!(
        two_queues > total / 8 && crossings > total / 10 && transfers > total / 20,
        "two queues in {two_queues} of {total}, crossings in {crossings}, transfers in {transfers}"
    );
    assert_eq!(ok, total, "every non-chaos graph compiles");
    assert!(
        pruned > total / 4,
        "pruning exercised in {pruned} of {total}"
    );
    assert!(
        merged > total / 8,
        "merging exercised in {merged} of {total}"
    );
}

#[test]
fn the_access_support_model_matches_the_synchronization2_table() {
    let compute = supported_accesses(PipelineStages::COMPUTE_SHADER);
    assert!(compute.contains(AccessFlags::SHADER_SAMPLED_READ | AccessFlags::SHADER_STORAGE_WRITE));
    assert!(!compute
        .intersects(AccessFlags::COLOR_ATTACHMENT_WRITE | AccessFlags::INPUT_ATTACHMENT_READ));
    let tests = PipelineStages::EARLY_FRAGMENT_TESTS | PipelineStages::LATE_FRAGMENT_TESTS;
    assert!(supported_accesses(tests).contains(AccessFlags::DEPTH_STENCIL_ATTACHMENT_WRITE));
    assert!(!supported_accesses(tests).intersects(AccessFlags::COLOR_ATTACHMENT_READ));
    // ALL_GRAPHICS performs every graphics access, but no transfer.
    let graphics = supported_accesses(PipelineStages::ALL_GRAPHICS);
    assert!(
        graphics.contains(AccessFlags::INDIRECT_COMMAND_READ | AccessFlags::INPUT_ATTACHMENT_READ)
    );
    assert!(!graphics.intersects(AccessFlags::TRANSFER_WRITE));
    assert!(supported_accesses(PipelineStages::ALL_COMMANDS).contains(AccessFlags::TRANSFER_WRITE));
}

/// FNV-1a, 64 bits: a digest that does not depend on the Rust release (std's hasher may).
fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

/// The differential test of compile's output: 600 random graphs (valid and chaos) compiled, and
/// the valid ones re-placed with other memory requirements, each printed whole (`Display` and
/// `Debug` of the plan or the error) and digested. The digests are committed in
/// `tests/plan_digests.txt`: a refactor of compile keeps every one of them; a change that is
/// meant to change plans regenerates the file (`TILEGRAPH_BLESS=1`) and shows why in review.
/// `TILEGRAPH_DUMP_PLANS=FILE` writes the printed plans themselves, for a diff between builds.
#[test]
fn plans_match_their_recorded_digests() {
    use proptest::strategy::ValueTree;
    use proptest::test_runner::{Config, RngAlgorithm, TestRng, TestRunner};
    use std::fmt::Write as _;
    let rng = TestRng::from_seed(RngAlgorithm::ChaCha, &[7; 32]);
    let mut runner = TestRunner::new_with_rng(Config::default(), rng);
    let strategy = (spec(200), prop::collection::vec((1u64..=8, 0u32..=16), 40));
    let mut digests = String::new();
    let mut dump = String::new();
    for case in 0..600 {
        let Ok(tree) = strategy.new_tree(&mut runner) else {
            continue;
        };
        let (spec, scales) = tree.current();
        let built = build(&spec);
        let profile = pick_profile(spec.profile);
        let mut text = match built.graph.compile(&profile) {
            Ok(c) => {
                let mut plan = c.plan;
                let mut text = format!("{plan}\n{plan:?}\n");
                let requirements = other_requirements(&plan, &scales);
                match plan.reassign_aliases(&requirements) {
                    Ok(()) => text.push_str(&format!("re-placed\n{plan}\n{plan:?}\n")),
                    Err(e) => text.push_str(&format!("re-placing failed: {e} {e:?}\n")),
                }
                text
            }
            Err(e) => format!("error: {e}\n{e:?}\n"),
        };
        text.insert_str(0, &format!("== case {case}\n"));
        let _ = writeln!(digests, "{case} {:016x}", fnv1a(text.as_bytes()));
        dump.push_str(&text);
    }
    if let Some(path) = std::env::var_os("TILEGRAPH_DUMP_PLANS") {
        std::fs::write(&path, &dump).expect("the dump file can be written");
    }
    let recorded = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/plan_digests.txt");
    if std::env::var_os("TILEGRAPH_BLESS").is_some() {
        std::fs::write(&recorded, &digests).expect("the digest file can be written");
        return;
    }
    let want = std::fs::read_to_string(&recorded).expect("tests/plan_digests.txt is committed");
    let changed: Vec<&str> = digests
        .lines()
        .zip(want.lines())
        .filter(|(a, b)| a != b)
        .map(|(a, _)| a)
        .collect();
    assert!(
        changed.is_empty() && digests.lines().count() == want.lines().count(),
        "{} of {} plans differ from tests/plan_digests.txt (first: {:?}); diff the plans with \
         TILEGRAPH_DUMP_PLANS=FILE against the previous build, and bless with TILEGRAPH_BLESS=1 \
         only when the change is meant",
        changed.len(),
        want.lines().count(),
        changed.first()
    );
}
