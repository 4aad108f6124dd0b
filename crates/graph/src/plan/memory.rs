//! Memory in the plan: which block each resource lives in, at which offset, and which resource
//! hands its bytes to which. Compile's aliasing phase (`compile/alias.rs`) fills it; the
//! executor allocates the blocks.

use crate::declare::ResourceId;
use crate::plan::StepRange;

/// Alignment the compile-time estimate assumes for every resource placed in a block.
pub const ESTIMATED_ALIGNMENT_BYTES: u64 = 64 * 1024;

/// Which kind of memory a block is allocated from (the executor maps it to a profile
/// `MemoryUse`: `DeviceLocal` to `gpu_only`, `LazilyAllocated` to `transient_attachment`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum MemoryClass {
    DeviceLocal,
    /// Transient attachments: on a tiler nothing is committed, so these are never aliased
    /// (sharing would save nothing and add barriers).
    LazilyAllocated,
}

impl MemoryClass {
    pub const fn name(self) -> &'static str {
        match self {
            MemoryClass::DeviceLocal => "device-local",
            MemoryClass::LazilyAllocated => "lazily-allocated",
        }
    }
}

/// What memory a resource needs from the graph.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum MemoryNeed {
    /// None: imported (the caller owns it) or unused.
    External,
    /// A block of its own.
    Dedicated(MemoryClass),
    /// A place in a block shared with resources whose lifetimes do not overlap.
    Shared(MemoryClass),
}

/// Input of [`assign_aliases`](crate::assign_aliases) for one resource.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct AliasLifetime {
    pub lifetime: Option<StepRange>,
    pub memory: MemoryNeed,
}

/// Size and alignment of one resource: estimated by the graph, or `VkMemoryRequirements`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct MemoryRequirements {
    pub size_bytes: u64,
    /// A power of two (0 is read as 1).
    pub alignment_bytes: u64,
}

/// Index into [`AliasAssignment::blocks`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct BlockIndex(pub u32);

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct MemoryBlock {
    pub class: MemoryClass,
    pub size_bytes: u64,
    /// Largest alignment of anything placed in it: allocate the block at least this aligned.
    pub alignment_bytes: u64,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct MemorySlot {
    pub block: BlockIndex,
    pub offset_bytes: u64,
    pub size_bytes: u64,
}

impl MemorySlot {
    pub const fn end_bytes(&self) -> u64 {
        self.offset_bytes.saturating_add(self.size_bytes)
    }

    /// Same block and overlapping bytes.
    pub const fn overlaps(&self, other: &MemorySlot) -> bool {
        self.block.0 == other.block.0
            && self.offset_bytes < other.end_bytes()
            && other.offset_bytes < self.end_bytes()
    }
}

/// `to` takes over bytes that `from` used earlier in the frame: `to`'s first barrier waits for
/// `from`'s last accesses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct AliasHandoff {
    pub to: ResourceId,
    pub from: ResourceId,
}

#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct AliasAssignment {
    pub blocks: Vec<MemoryBlock>,
    /// Per resource (index = [`ResourceId`]).
    pub slots: Vec<Option<MemorySlot>>,
    /// Sorted by `to`, then `from`.
    pub handoffs: Vec<AliasHandoff>,
    /// Bytes the resources would take, each in its own allocation.
    pub requested_bytes: u64,
    /// Bytes of all blocks.
    pub allocated_bytes: u64,
}

impl AliasAssignment {
    pub fn saved_bytes(&self) -> u64 {
        self.requested_bytes.saturating_sub(self.allocated_bytes)
    }

    /// Resources whose first barrier must wait for `to`'s predecessors in memory.
    pub fn predecessors(&self, to: ResourceId) -> impl Iterator<Item = ResourceId> + '_ {
        let start = self.handoffs.partition_point(|h| h.to < to);
        self.handoffs[start..]
            .iter()
            .take_while(move |h| h.to == to)
            .map(|h| h.from)
    }
}
