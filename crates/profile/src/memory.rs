//! Memory-type selection: a pure function of the profile's policy and the device's memory types.
//!
//! Seed 001 (Adreno) is the motivating case: asking for `DEVICE_LOCAL` returns two types,
//! `1 = DEVICE_LOCAL` and `15 = DEVICE_LOCAL | HOST_VISIBLE | HOST_COHERENT | HOST_CACHED`; buffers the
//! CPU rewrites every frame belong in 15 and are written in place, with no staging copy, while
//! static data belongs in 1. Picking by "first type that has DEVICE_LOCAL" gets it wrong.

use std::fmt;

use serde::{Deserialize, Serialize};

use crate::ProfileError;

/// `VkMemoryPropertyFlags`, without Vulkan (same bit values).
#[derive(Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(transparent)]
pub struct MemoryFlags(pub u32);

impl MemoryFlags {
    pub const DEVICE_LOCAL: Self = Self(0x1);
    pub const HOST_VISIBLE: Self = Self(0x2);
    pub const HOST_COHERENT: Self = Self(0x4);
    pub const HOST_CACHED: Self = Self(0x8);
    pub const LAZILY_ALLOCATED: Self = Self(0x10);
    pub const PROTECTED: Self = Self(0x20);

    pub const fn empty() -> Self {
        Self(0)
    }
    pub const fn bits(self) -> u32 {
        self.0
    }
    pub const fn contains(self, other: Self) -> bool {
        self.0 & other.0 == other.0
    }
    pub const fn intersects(self, other: Self) -> bool {
        self.0 & other.0 != 0
    }
    pub const fn union(self, other: Self) -> Self {
        Self(self.0 | other.0)
    }
    /// Number of flags set, used to prefer the type with the fewest flags beyond those required.
    pub const fn count(self) -> u32 {
        self.0.count_ones()
    }

    /// Flag names, in bit order, as written in profiles and printed by `tilegraph devices`.
    pub fn names(self) -> Vec<&'static str> {
        MemoryFlag::ALL
            .iter()
            .filter(|f| self.contains(f.bits()))
            .map(|f| f.name())
            .collect()
    }
}

impl std::ops::BitOr for MemoryFlags {
    type Output = Self;
    fn bitor(self, rhs: Self) -> Self {
        self.union(rhs)
    }
}

impl fmt::Debug for MemoryFlags {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:#x}", self.0)?;
        let names = self.names();
        if !names.is_empty() {
            write!(f, " ({})", names.join(" | "))?;
        }
        Ok(())
    }
}

impl fmt::Display for MemoryFlags {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Debug::fmt(self, f)
    }
}

/// One flag, by the name profiles use for it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MemoryFlag {
    DeviceLocal,
    HostVisible,
    HostCoherent,
    HostCached,
    LazilyAllocated,
    Protected,
}

impl MemoryFlag {
    pub const ALL: [MemoryFlag; 6] = [
        MemoryFlag::DeviceLocal,
        MemoryFlag::HostVisible,
        MemoryFlag::HostCoherent,
        MemoryFlag::HostCached,
        MemoryFlag::LazilyAllocated,
        MemoryFlag::Protected,
    ];

    pub const fn bits(self) -> MemoryFlags {
        match self {
            MemoryFlag::DeviceLocal => MemoryFlags::DEVICE_LOCAL,
            MemoryFlag::HostVisible => MemoryFlags::HOST_VISIBLE,
            MemoryFlag::HostCoherent => MemoryFlags::HOST_COHERENT,
            MemoryFlag::HostCached => MemoryFlags::HOST_CACHED,
            MemoryFlag::LazilyAllocated => MemoryFlags::LAZILY_ALLOCATED,
            MemoryFlag::Protected => MemoryFlags::PROTECTED,
        }
    }

    pub const fn name(self) -> &'static str {
        match self {
            MemoryFlag::DeviceLocal => "device_local",
            MemoryFlag::HostVisible => "host_visible",
            MemoryFlag::HostCoherent => "host_coherent",
            MemoryFlag::HostCached => "host_cached",
            MemoryFlag::LazilyAllocated => "lazily_allocated",
            MemoryFlag::Protected => "protected",
        }
    }
}

fn flags_of(list: &[MemoryFlag]) -> MemoryFlags {
    list.iter()
        .fold(MemoryFlags::empty(), |acc, f| acc | f.bits())
}

/// `VkMemoryType`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct MemoryType {
    pub flags: MemoryFlags,
    pub heap_index: u32,
}

/// `VkMemoryHeap`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct MemoryHeap {
    pub size_bytes: u64,
    pub device_local: bool,
}

/// What a piece of memory is for. Each use has its own preference list in the profile.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MemoryUse {
    /// Vertex/index/instance data uploaded once.
    StaticGeometry,
    /// Images and buffers only the GPU touches: render targets that are stored, storage buffers,
    /// HiZ pyramids, indirect arguments.
    GpuOnly,
    /// Per-frame data the CPU writes and the GPU reads (uniforms, instance transforms).
    Streaming,
    /// Data the GPU writes and the CPU reads (query results, culling counters, image readback).
    Readback,
    /// Upload staging buffers, written once by the CPU and copied by the GPU.
    Staging,
    /// Attachments that never leave tile memory (lazily allocated where the device has it).
    TransientAttachment,
}

impl MemoryUse {
    pub const ALL: [MemoryUse; 6] = [
        MemoryUse::StaticGeometry,
        MemoryUse::GpuOnly,
        MemoryUse::Streaming,
        MemoryUse::Readback,
        MemoryUse::Staging,
        MemoryUse::TransientAttachment,
    ];

    pub const fn name(self) -> &'static str {
        match self {
            MemoryUse::StaticGeometry => "static_geometry",
            MemoryUse::GpuOnly => "gpu_only",
            MemoryUse::Streaming => "streaming",
            MemoryUse::Readback => "readback",
            MemoryUse::Staging => "staging",
            MemoryUse::TransientAttachment => "transient_attachment",
        }
    }

    /// Whether the CPU maps this memory; such uses never take a type without HOST_VISIBLE.
    pub const fn host_access(self) -> bool {
        matches!(
            self,
            MemoryUse::Streaming | MemoryUse::Readback | MemoryUse::Staging
        )
    }
}

/// The preference list for one use, as written in a profile:
///
/// ```toml
/// [memory.streaming]
/// prefer = [["device_local", "host_visible", "host_coherent"], ["host_visible", "host_coherent"]]
/// avoid = []
/// ```
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MemoryRule {
    /// Tiers tried in order; a type qualifies for a tier when it has every flag of the tier.
    pub prefer: Vec<Vec<MemoryFlag>>,
    /// Among qualifying types, prefer those with fewer of these flags.
    #[serde(default)]
    pub avoid: Vec<MemoryFlag>,
}

/// One rule per use.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MemoryPolicy {
    pub static_geometry: MemoryRule,
    pub gpu_only: MemoryRule,
    pub streaming: MemoryRule,
    pub readback: MemoryRule,
    pub staging: MemoryRule,
    pub transient_attachment: MemoryRule,
}

impl MemoryPolicy {
    pub fn rule(&self, use_: MemoryUse) -> &MemoryRule {
        match use_ {
            MemoryUse::StaticGeometry => &self.static_geometry,
            MemoryUse::GpuOnly => &self.gpu_only,
            MemoryUse::Streaming => &self.streaming,
            MemoryUse::Readback => &self.readback,
            MemoryUse::Staging => &self.staging,
            MemoryUse::TransientAttachment => &self.transient_attachment,
        }
    }
}

/// The memory type chosen for a use, and why.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct MemoryChoice {
    pub use_: MemoryUse,
    pub type_index: u32,
    pub flags: MemoryFlags,
    /// Index of the preference tier that matched; `None` when no tier matched and the fallback
    /// (any allowed type with the flags the use cannot do without) was taken.
    pub tier: Option<usize>,
}

/// Picks the memory type for `use_` among `types` restricted to `type_bits`
/// (`VkMemoryRequirements::memoryTypeBits`; pass `u32::MAX` to consider every type).
///
/// Order of decision: the first preference tier that some allowed type satisfies; within it the
/// type with fewest `avoid` flags, then fewest flags overall (so plain `DEVICE_LOCAL` beats
/// `DEVICE_LOCAL | HOST_VISIBLE | ...` for data the CPU never touches), then lowest index.
/// Protected memory is never chosen; lazily allocated memory only for transient attachments;
/// host-accessed uses only get host-visible types. When no tier matches, any allowed type that
/// respects those hard constraints is taken (tier `None`) and a warning is logged.
pub fn select_memory_type(
    policy: &MemoryPolicy,
    types: &[MemoryType],
    type_bits: u32,
    use_: MemoryUse,
) -> Result<MemoryChoice, ProfileError> {
    let rule = policy.rule(use_);
    let avoid = flags_of(&rule.avoid);
    let hard_ok = |t: &MemoryType| {
        if t.flags.contains(MemoryFlags::PROTECTED) {
            return false;
        }
        if t.flags.contains(MemoryFlags::LAZILY_ALLOCATED) && use_ != MemoryUse::TransientAttachment
        {
            return false;
        }
        !use_.host_access() || t.flags.contains(MemoryFlags::HOST_VISIBLE)
    };
    let allowed: Vec<(u32, MemoryType)> = types
        .iter()
        .enumerate()
        .take(32)
        .filter(|(i, t)| type_bits & (1u32 << i) != 0 && hard_ok(t))
        .map(|(i, t)| (i as u32, *t))
        .collect();
    let best = |cands: &mut dyn Iterator<Item = (u32, MemoryType)>| {
        cands.min_by_key(|(i, t)| {
            (
                MemoryFlags(t.flags.0 & avoid.0).count(),
                t.flags.count(),
                *i,
            )
        })
    };
    for (tier, wanted) in rule.prefer.iter().enumerate() {
        let wanted = flags_of(wanted);
        if let Some((index, t)) = best(
            &mut allowed
                .iter()
                .copied()
                .filter(|(_, t)| t.flags.contains(wanted)),
        ) {
            return Ok(MemoryChoice {
                use_,
                type_index: index,
                flags: t.flags,
                tier: Some(tier),
            });
        }
    }
    match best(&mut allowed.iter().copied()) {
        Some((index, t)) => {
            log::warn!(
                "memory use {}: no type matches the profile's preferences; falling back to type {index} ({})",
                use_.name(),
                t.flags
            );
            Ok(MemoryChoice {
                use_,
                type_index: index,
                flags: t.flags,
                tier: None,
            })
        }
        None => Err(ProfileError::NoMemoryType {
            use_: use_.name(),
            type_bits,
        }),
    }
}
