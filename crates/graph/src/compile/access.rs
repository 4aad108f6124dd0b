//! What one pass does to one resource, merged over its declared uses: stages, access mask,
//! layout, and whether it reads the old content and writes new content. Every later phase
//! works on these summaries.

use crate::declare::{Coverage, PassId, PassKind, PassUse, ResourceDesc, ResourceId, UseKind};
use crate::types::{AccessFlags, Format, Layout, PipelineStages};

/// One pass's combined access to one resource.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Access {
    pub resource: ResourceId,
    /// Index of the first declared use in the pass's `uses` (its kind names the access in
    /// messages, and holds the clear value).
    pub first_use: u32,
    pub stages: PipelineStages,
    pub access: AccessFlags,
    /// [`UseKind::bit`] of every declared use.
    pub roles: u16,
    /// Layout the pass needs (images); `Undefined` for buffers.
    pub layout: Layout,
    /// `READS_PRIOR | EXPLICIT_READ | ...`: one byte, so a summary is built and merged with
    /// one store and one OR.
    flags: u8,
}

/// The pass needs the content left by earlier writes: an explicit read, or a write that
/// neither clears nor covers everything.
const READS_PRIOR: u8 = 1;
/// A declared read (sampled, input, storage read, depth test without write...).
const EXPLICIT_READ: u8 = 2;
const WRITES: u8 = 4;
/// Some use binds it to the render pass.
const ATTACHMENT: u8 = 8;
/// Some use reaches it through memory (descriptor, vertex input, transfer).
const NON_ATTACHMENT: u8 = 16;
/// The first use clears it.
const CLEARS: u8 = 32;

impl Access {
    /// The pass needs the content left by earlier writes: an explicit read, or a write that
    /// neither clears nor covers everything.
    pub const fn reads_prior(&self) -> bool {
        self.flags & READS_PRIOR != 0
    }

    /// A declared read (sampled, input, storage read, depth test without write...).
    pub const fn explicit_read(&self) -> bool {
        self.flags & EXPLICIT_READ != 0
    }

    pub const fn writes(&self) -> bool {
        self.flags & WRITES != 0
    }

    /// Some use binds it to the render pass.
    pub const fn attachment(&self) -> bool {
        self.flags & ATTACHMENT != 0
    }

    /// Some use reaches it through memory (descriptor, vertex input, transfer).
    pub const fn non_attachment(&self) -> bool {
        self.flags & NON_ATTACHMENT != 0
    }

    /// The first use clears it.
    pub const fn clears(&self) -> bool {
        self.flags & CLEARS != 0
    }
}

/// Shader stages that a descriptor use in a pass of this kind may touch.
fn shader_stages(kind: PassKind) -> PipelineStages {
    match kind {
        PassKind::Raster => PipelineStages::VERTEX_SHADER | PipelineStages::FRAGMENT_SHADER,
        PassKind::Compute => PipelineStages::COMPUTE_SHADER,
        PassKind::Transfer => PipelineStages::ALL_TRANSFER,
    }
}

pub(crate) const DEPTH_TESTS: PipelineStages = PipelineStages::from_bits(
    PipelineStages::EARLY_FRAGMENT_TESTS.bits() | PipelineStages::LATE_FRAGMENT_TESTS.bits(),
);

/// Read-only layout of an image read through a shader: depth formats stay in the depth
/// read-only layout so a depth test and a sampler can share it.
fn shader_read_layout(format: Option<Format>) -> Layout {
    match format {
        Some(f) if f.is_depth_stencil() => Layout::DepthStencilReadOnly,
        _ => Layout::ShaderReadOnly,
    }
}

/// `flag` if `on`.
const fn bit(on: bool, flag: u8) -> u8 {
    if on {
        flag
    } else {
        0
    }
}

/// Summarizes one declared use (one `match` gives every property).
pub(crate) fn summarize_use(
    pass_kind: PassKind,
    coverage: Coverage,
    u: &PassUse,
    use_index: u32,
    desc: &ResourceDesc,
) -> Access {
    let format = desc.image().map(|d| d.format);
    let is_image = format.is_some();
    let keeps_old = coverage == Coverage::Partial;
    let shader = shader_stages(pass_kind);
    // Reads: the old content, declared as such.
    const READ: u8 = READS_PRIOR | EXPLICIT_READ;
    let (stages, access, layout, flags) = match u.kind {
        UseKind::ColorAttachment { clear } => {
            let reads = clear.is_none() && keeps_old;
            let access = if reads {
                AccessFlags::COLOR_ATTACHMENT_WRITE | AccessFlags::COLOR_ATTACHMENT_READ
            } else {
                AccessFlags::COLOR_ATTACHMENT_WRITE
            };
            (
                PipelineStages::COLOR_ATTACHMENT_OUTPUT,
                access,
                Layout::ColorAttachment,
                WRITES | ATTACHMENT | bit(reads, READS_PRIOR) | bit(clear.is_some(), CLEARS),
            )
        }
        UseKind::DepthStencilAttachment { clear } => (
            DEPTH_TESTS,
            AccessFlags::DEPTH_STENCIL_ATTACHMENT_READ
                | AccessFlags::DEPTH_STENCIL_ATTACHMENT_WRITE,
            Layout::DepthStencilAttachment,
            WRITES
                | ATTACHMENT
                | bit(clear.is_none() && keeps_old, READS_PRIOR)
                | bit(clear.is_some(), CLEARS),
        ),
        UseKind::DepthStencilReadOnly => (
            DEPTH_TESTS,
            AccessFlags::DEPTH_STENCIL_ATTACHMENT_READ,
            Layout::DepthStencilReadOnly,
            READ | ATTACHMENT,
        ),
        UseKind::InputAttachment => (
            PipelineStages::FRAGMENT_SHADER,
            AccessFlags::INPUT_ATTACHMENT_READ,
            shader_read_layout(format),
            READ | ATTACHMENT,
        ),
        // A resolve overwrites every pixel of its target.
        UseKind::ResolveTarget { .. } => (
            PipelineStages::COLOR_ATTACHMENT_OUTPUT,
            AccessFlags::COLOR_ATTACHMENT_WRITE,
            Layout::ColorAttachment,
            WRITES | ATTACHMENT,
        ),
        UseKind::Sampled => (
            shader,
            AccessFlags::SHADER_SAMPLED_READ,
            shader_read_layout(format),
            READ | NON_ATTACHMENT,
        ),
        UseKind::StorageRead => (
            shader,
            AccessFlags::SHADER_STORAGE_READ,
            Layout::General,
            READ | NON_ATTACHMENT,
        ),
        UseKind::StorageWrite => (
            shader,
            AccessFlags::SHADER_STORAGE_WRITE,
            Layout::General,
            WRITES | NON_ATTACHMENT | bit(keeps_old, READS_PRIOR),
        ),
        // Reads what the pass itself writes (HiZ mips), and the old content unless the pass
        // covers everything: not a read of earlier content by itself.
        UseKind::StorageReadWrite => (
            shader,
            AccessFlags::SHADER_STORAGE_READ | AccessFlags::SHADER_STORAGE_WRITE,
            Layout::General,
            WRITES | NON_ATTACHMENT | bit(keeps_old, READS_PRIOR),
        ),
        UseKind::Uniform => (
            shader,
            AccessFlags::UNIFORM_READ,
            Layout::Undefined,
            READ | NON_ATTACHMENT,
        ),
        UseKind::Vertex => (
            PipelineStages::VERTEX_ATTRIBUTE_INPUT,
            AccessFlags::VERTEX_ATTRIBUTE_READ,
            Layout::Undefined,
            READ | NON_ATTACHMENT,
        ),
        UseKind::Index => (
            PipelineStages::INDEX_INPUT,
            AccessFlags::INDEX_READ,
            Layout::Undefined,
            READ | NON_ATTACHMENT,
        ),
        UseKind::Indirect => (
            PipelineStages::DRAW_INDIRECT,
            AccessFlags::INDIRECT_COMMAND_READ,
            Layout::Undefined,
            READ | NON_ATTACHMENT,
        ),
        UseKind::ConditionalPredicate => (
            PipelineStages::CONDITIONAL_RENDERING,
            AccessFlags::CONDITIONAL_RENDERING_READ,
            Layout::Undefined,
            READ | NON_ATTACHMENT,
        ),
        UseKind::TransferSrc => (
            PipelineStages::ALL_TRANSFER,
            AccessFlags::TRANSFER_READ,
            Layout::TransferSrc,
            READ | NON_ATTACHMENT,
        ),
        UseKind::TransferDst => (
            PipelineStages::ALL_TRANSFER,
            AccessFlags::TRANSFER_WRITE,
            Layout::TransferDst,
            WRITES | NON_ATTACHMENT | bit(keeps_old, READS_PRIOR),
        ),
    };
    Access {
        resource: u.resource,
        first_use: use_index,
        stages,
        access,
        roles: u.kind.bit(),
        layout: if is_image { layout } else { Layout::Undefined },
        flags,
    }
}

/// Folds another read into an existing access. Only reads that agree on the layout combine
/// (the caller has checked).
pub(crate) fn merge_reads(into: &mut Access, other: &Access) {
    into.roles |= other.roles;
    into.stages |= other.stages;
    into.access |= other.access;
    // Reads neither write nor clear: their flags add reads and binding kinds only.
    into.flags |= other.flags;
}

/// Bit of a use kind, for tests on `roles`.
pub(crate) const fn role(kind: UseKind) -> u16 {
    kind.bit()
}

/// Role masks shared by the phases.
pub(crate) const COLOR_ROLE: u16 = role(UseKind::ColorAttachment { clear: None });
pub(crate) const DEPTH_STENCIL_ROLES: u16 =
    role(UseKind::DepthStencilAttachment { clear: None }) | role(UseKind::DepthStencilReadOnly);
pub(crate) const INPUT_ROLE: u16 = role(UseKind::InputAttachment);
pub(crate) const RESOLVE_ROLE: u16 = role(UseKind::ResolveTarget {
    source: ResourceId(0),
});
/// Buffers read whole by fixed-function stages or as uniforms.
pub(crate) const BUFFER_READ_ROLES: u16 = role(UseKind::Uniform)
    | role(UseKind::Vertex)
    | role(UseKind::Index)
    | role(UseKind::Indirect)
    | role(UseKind::ConditionalPredicate);

/// Two uses of one resource in one pass that cannot be combined.
#[derive(Debug, Clone, Copy)]
pub(crate) struct UseConflict {
    pub first: &'static str,
    pub second: &'static str,
}

/// Appends one pass's accesses to `out`, one per resource: reads that agree on the layout
/// combine, anything else is a conflict.
pub(crate) fn push_pass_accesses<'d>(
    kind: PassKind,
    coverage: Coverage,
    uses: &[PassUse],
    desc_of: impl Fn(ResourceId) -> Option<&'d ResourceDesc>,
    out: &mut Vec<Access>,
) -> Result<(), UseConflict> {
    let start = out.len();
    for (i, u) in uses.iter().enumerate() {
        let Some(desc) = desc_of(u.resource) else {
            continue;
        };
        let existing = out[start..]
            .iter()
            .position(|x| x.resource == u.resource)
            .map(|k| start + k);
        add_access(
            out,
            existing,
            summarize_use(kind, coverage, u, i as u32, desc),
            uses,
        )?;
    }
    Ok(())
}

/// Adds one use's access to the accesses of its pass: a new resource is appended, a read that
/// agrees on the layout with the resource's access (`out[existing]`, the pass's access to it so
/// far, if any) combines with it.
#[inline]
pub(crate) fn add_access(
    out: &mut Vec<Access>,
    existing: Option<usize>,
    a: Access,
    uses: &[PassUse],
) -> Result<(), UseConflict> {
    match existing.and_then(|i| out.get_mut(i)) {
        None => out.push(a),
        Some(existing) => {
            if existing.writes() || a.writes() || existing.layout != a.layout {
                let name = |i: u32| uses.get(i as usize).map_or("?", |u| u.kind.name());
                return Err(UseConflict {
                    first: name(existing.first_use),
                    second: name(a.first_use),
                });
            }
            merge_reads(existing, &a);
        }
    }
    Ok(())
}

/// Every pass's accesses, pass after pass, and where each pass's run starts and ends (indexed
/// by `PassId`). Validation builds them from the declarations; re-placing a finished plan
/// rebuilds them from its passes' uses.
#[derive(Debug, Default)]
pub(crate) struct PassAccesses {
    pub accesses: Vec<Access>,
    /// `accesses[start..end]` of each pass.
    pub ranges: Vec<(u32, u32)>,
}

impl PassAccesses {
    pub fn of(&self, pass: PassId) -> &[Access] {
        match self.ranges.get(pass.index()) {
            Some(&(start, end)) => &self.accesses[start as usize..end as usize],
            None => &[],
        }
    }

    /// Index in `accesses` of the first access of `pass`.
    pub fn start_of(&self, pass: PassId) -> usize {
        self.ranges
            .get(pass.index())
            .map_or(0, |&(s, _)| s as usize)
    }
}
