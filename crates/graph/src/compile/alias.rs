//! Memory aliasing: resources that are never alive at the same time share memory.
//!
//! The graph cannot know the driver's `VkMemoryRequirements`, so `compile` runs
//! `assign_aliases` on estimates: an image takes `w * h * bytes_per_pixel * samples` summed
//! over its mips, a buffer its size, and both are aligned to [`ESTIMATED_ALIGNMENT_BYTES`](crate::ESTIMATED_ALIGNMENT_BYTES)
//! (64 KiB). 64 KiB is at least every alignment and every `bufferImageGranularity` that shipping
//! drivers report, and because every resource starts on a 64 KiB boundary, a buffer and an image
//! in one block never share a granularity page. The executor places memory again with the real
//! requirements through [`crate::Plan::reassign_aliases`], which also rebuilds the barriers the
//! new placement needs; it folds `bufferImageGranularity` into the alignments first.
//!
//! The algorithm is a sweep over first use (ties: larger first): retire the resources whose
//! last use is earlier, then place the resource in the tightest gap of a partly used block,
//! else the smallest empty block that holds it, else the largest empty block grown to fit, else
//! a new block. Blocks are kept in ordered sets, so a placement costs O(log blocks). Blocks are
//! only sizes; the executor allocates them.

use smallvec::SmallVec;

use crate::declare::ResourceId;
use crate::error::GraphError;
use crate::plan::{
    AliasAssignment, AliasHandoff, AliasLifetime, BlockIndex, MemoryBlock, MemoryClass, MemoryNeed,
    MemoryRequirements, MemorySlot,
};

#[derive(Clone, Copy)]
struct Placed {
    offset: u64,
    end: u64,
    resource: u32,
    /// Still in use (else: retired, kept as the last holder of its bytes).
    alive: bool,
}

struct BlockState {
    class: MemoryClass,
    size: u64,
    alignment: u64,
    /// The most recent occupant of each byte range, sorted and disjoint. Allocations alive now
    /// are among them (nothing can be placed over a live one).
    occupants: SmallVec<[Placed; 4]>,
    live: u32,
    live_bytes: u64,
}

/// `value` rounded up to a multiple of `alignment` (a power of two); `None` past `u64::MAX`.
const fn align_up(value: u64, alignment: u64) -> Option<u64> {
    match value.checked_add(alignment - 1) {
        Some(v) => Some(v & !(alignment - 1)),
        None => None,
    }
}

impl BlockState {
    fn free_bytes(&self) -> u64 {
        self.size.saturating_sub(self.live_bytes)
    }

    /// Lowest aligned offset where `size` bytes fit between the live allocations and inside
    /// the block.
    fn gap_within(&self, size: u64, alignment: u64) -> Option<u64> {
        let fits_below =
            |start: u64, limit: u64| start.checked_add(size).is_some_and(|end| end <= limit);
        let mut cursor = 0u64;
        for placed in self.occupants.iter().filter(|p| p.alive) {
            // Past u64::MAX nothing fits, here or further on.
            let candidate = align_up(cursor, alignment)?;
            if fits_below(candidate, placed.offset) {
                return Some(candidate);
            }
            cursor = cursor.max(placed.end);
        }
        let candidate = align_up(cursor, alignment)?;
        fits_below(candidate, self.size).then_some(candidate)
    }

    fn place(&mut self, offset: u64, size: u64, resource: u32, handoffs: &mut Vec<u32>) {
        let end = offset.saturating_add(size);
        self.live += 1;
        self.live_bytes = self.live_bytes.saturating_add(size);
        // Everyone who last held some of [offset, end) hands it over; pieces outside stay.
        let first = self.occupants.partition_point(|p| p.end <= offset);
        let last = first + self.occupants[first..].partition_point(|p| p.offset < end);
        let placed = Placed {
            offset,
            end,
            resource,
            alive: true,
        };
        if first == last {
            self.occupants.insert(first, placed);
            return;
        }
        handoffs.extend(self.occupants[first..last].iter().map(|p| p.resource));
        let (head, tail) = (self.occupants[first], self.occupants[last - 1]);
        // occupants[first..last] becomes [head's part below `offset`] placed [tail's part
        // above `end`]: at most three entries where there was at least one.
        let keep_head = head.offset < offset;
        let keep_tail = tail.end > end;
        let needed = 1 + usize::from(keep_head) + usize::from(keep_tail);
        let mut have = last - first;
        while have < needed {
            self.occupants.insert(last, placed);
            have += 1;
        }
        if have > needed {
            self.occupants.drain(first + needed..first + have);
        }
        let mut at = first;
        if keep_head {
            self.occupants[at] = Placed {
                end: offset,
                ..head
            };
            at += 1;
        }
        self.occupants[at] = placed;
        if keep_tail {
            self.occupants[at + 1] = Placed {
                offset: end,
                ..tail
            };
        }
    }

    fn retire(&mut self, resource: u32) {
        if let Some(p) = self
            .occupants
            .iter_mut()
            .find(|p| p.alive && p.resource == resource)
        {
            p.alive = false;
            self.live -= 1;
            self.live_bytes = self.live_bytes.saturating_sub(p.end - p.offset);
        }
    }
}

/// Blocks of one sweep, indexed for best fit: empty blocks by size, partly used ones by free
/// bytes (sorted vectors of packed keys: there are few blocks, and one integer comparison per
/// search step beats tree nodes).
#[derive(Default)]
struct Blocks {
    blocks: Vec<BlockState>,
    empty: Vec<u128>,
    partial: Vec<u128>,
}

/// `(class, bytes, block)` packed so that integer order is tuple order.
const fn block_key(class: MemoryClass, bytes: u64, b: u32) -> u128 {
    ((class as u128) << 96) | ((bytes as u128) << 32) | b as u128
}

const fn key_block(key: u128) -> u32 {
    key as u32
}

const fn key_class(key: u128) -> u128 {
    key >> 96
}

/// The two indexes of [`Blocks`].
#[derive(Clone, Copy, PartialEq, Eq)]
enum BlockSet {
    /// Nothing alive in the block, keyed by its size.
    Empty,
    /// Some of it alive, keyed by its free bytes.
    Partial,
}

/// Which index holds a block, under which key (`None`: full, in neither).
fn block_entry(block: &BlockState, b: u32) -> Option<(BlockSet, u128)> {
    if block.live == 0 {
        Some((BlockSet::Empty, block_key(block.class, block.size, b)))
    } else if block.free_bytes() > 0 {
        Some((
            BlockSet::Partial,
            block_key(block.class, block.free_bytes(), b),
        ))
    } else {
        None
    }
}

impl Blocks {
    fn set(&mut self, set: BlockSet) -> &mut Vec<u128> {
        match set {
            BlockSet::Empty => &mut self.empty,
            BlockSet::Partial => &mut self.partial,
        }
    }

    /// Re-files block `b` after a change that turned its entry `before` into its current one:
    /// within one set, the entries in between shift by one place (a single move).
    fn refile(&mut self, b: u32, before: Option<(BlockSet, u128)>) {
        let after = block_entry(&self.blocks[b as usize], b);
        match (before, after) {
            (Some((set_a, old)), Some((set_b, new))) if set_a == set_b => {
                if old == new {
                    return;
                }
                let set = self.set(set_a);
                let Ok(from) = set.binary_search(&old) else {
                    return;
                };
                // Shift the entries between the old and the new place by one (few: a
                // block's free bytes change by one resource's size).
                let mut at = from;
                if new > old {
                    while at + 1 < set.len() && set[at + 1] < new {
                        set[at] = set[at + 1];
                        at += 1;
                    }
                } else {
                    while at > 0 && set[at - 1] > new {
                        set[at] = set[at - 1];
                        at -= 1;
                    }
                }
                set[at] = new;
            }
            _ => {
                if let Some((set, old)) = before {
                    let set = self.set(set);
                    if let Ok(i) = set.binary_search(&old) {
                        set.remove(i);
                    }
                }
                if let Some((set, new)) = after {
                    let set = self.set(set);
                    if let Err(i) = set.binary_search(&new) {
                        set.insert(i, new);
                    }
                }
            }
        }
    }

    /// Where a resource goes: a gap in a partly used block (tightest first), else the smallest
    /// empty block that holds it, else the largest empty block grown to fit, else a new block.
    fn choose(&self, class: MemoryClass, size: u64, alignment: u64) -> (u32, u64) {
        let class_bits = class as u128;
        let from = self
            .partial
            .partition_point(|&k| k < block_key(class, size, 0));
        for &k in &self.partial[from..] {
            if key_class(k) != class_bits {
                break;
            }
            let b = key_block(k);
            if let Some(offset) = self.blocks[b as usize].gap_within(size, alignment) {
                return (b, offset);
            }
        }
        let fit = self
            .empty
            .partition_point(|&k| k < block_key(class, size, 0));
        if let Some(&k) = self.empty.get(fit) {
            if key_class(k) == class_bits {
                return (key_block(k), 0);
            }
        }
        if fit > 0 {
            let k = self.empty[fit - 1];
            if key_class(k) == class_bits {
                return (key_block(k), 0);
            }
        }
        (self.blocks.len() as u32, 0)
    }
}

/// Sorts `items` by a small integer key (a step number or a resource index), keeping the
/// order of equal keys: a counting sort when the keys are dense, as those of one frame are.
fn sort_by_small_key<T: Copy>(items: &mut Vec<T>, key: impl Fn(&T) -> u32) {
    let Some(first) = items.first().copied() else {
        return;
    };
    let max = items.iter().map(|x| key(x) as usize).max().unwrap_or(0);
    if max > 4 * items.len() + 64 {
        items.sort_by_key(|x| key(x));
        return;
    }
    let mut start = vec![0u32; max + 2];
    for x in items.iter() {
        start[key(x) as usize + 1] += 1;
    }
    for i in 1..start.len() {
        start[i] += start[i - 1];
    }
    let mut sorted = vec![first; items.len()];
    for &x in items.iter() {
        let at = &mut start[key(&x) as usize];
        sorted[*at as usize] = x;
        *at += 1;
    }
    *items = sorted;
}

/// Places every resource that needs memory into blocks; resources of one class whose
/// lifetimes do not overlap may share bytes. `lifetimes[i]` and `requirements[i]` describe
/// resource `i`. Deterministic, and depends only on the order of lifetimes, so any strictly
/// increasing renumbering of steps gives the same assignment.
pub fn assign_aliases(
    lifetimes: &[AliasLifetime],
    requirements: &[MemoryRequirements],
) -> Result<AliasAssignment, GraphError> {
    if lifetimes.len() != requirements.len() {
        return Err(GraphError::AliasInputMismatch {
            lifetimes: lifetimes.len(),
            requirements: requirements.len(),
        });
    }
    let mut alignments = Vec::with_capacity(requirements.len());
    for (index, req) in requirements.iter().enumerate() {
        let alignment = req.alignment_bytes.max(1);
        if !alignment.is_power_of_two() {
            return Err(GraphError::InvalidAlignment {
                index,
                alignment_bytes: req.alignment_bytes,
            });
        }
        alignments.push(alignment);
    }

    let mut out = AliasAssignment {
        slots: vec![None; lifetimes.len()],
        ..AliasAssignment::default()
    };

    // Shared resources, swept by first use; bigger first on ties so they open the blocks; then
    // declaration order. Steps are dense (group or step numbers of one frame): a counting sort.
    let shared_ids = || {
        lifetimes
            .iter()
            .enumerate()
            .filter_map(|(i, l)| match (l.memory, l.lifetime) {
                (MemoryNeed::Shared(_), Some(range)) => Some((range, i as u32)),
                _ => None,
            })
    };
    let mut shared: Vec<(u32, u32)> = Vec::with_capacity(lifetimes.len());
    shared.extend(shared_ids().map(|(r, i)| (r.first.0, i)));
    sort_by_small_key(&mut shared, |&(first, _)| first);
    for run in shared.chunk_by_mut(|a, b| a.0 == b.0) {
        if run.len() > 1 {
            run.sort_by_key(|&(_, i)| std::cmp::Reverse(requirements[i as usize].size_bytes));
        }
    }
    // The same resources by last use (then declaration order): retiring is a cursor over this
    // order.
    let mut expiry: Vec<(u32, u32)> = Vec::with_capacity(shared.len());
    expiry.extend(shared_ids().map(|(r, i)| (r.last.0, i)));
    sort_by_small_key(&mut expiry, |&(last, _)| last);
    let mut expired = 0usize;
    let mut block_of: Vec<u32> = vec![u32::MAX; lifetimes.len()];

    let mut blocks = Blocks {
        blocks: Vec::with_capacity(shared.len()),
        empty: Vec::with_capacity(shared.len()),
        partial: Vec::with_capacity(shared.len()),
    };
    out.handoffs.reserve(shared.len());
    let mut handoff_from: Vec<u32> = Vec::new();
    for &(first, i) in &shared {
        let MemoryNeed::Shared(class) = lifetimes[i as usize].memory else {
            continue;
        };
        while let Some(&(last, resource)) = expiry.get(expired) {
            if last >= first {
                break;
            }
            expired += 1;
            let b = block_of[resource as usize];
            if b == u32::MAX {
                continue;
            }
            let before = block_entry(&blocks.blocks[b as usize], b);
            blocks.blocks[b as usize].retire(resource);
            blocks.refile(b, before);
        }
        let size = requirements[i as usize].size_bytes;
        let alignment = alignments[i as usize];
        let (b, offset) = blocks.choose(class, size, alignment);
        let before = if b as usize == blocks.blocks.len() {
            blocks.blocks.push(BlockState {
                class,
                size: 0,
                alignment: 1,
                occupants: SmallVec::new(),
                live: 0,
                live_bytes: 0,
            });
            None
        } else {
            block_entry(&blocks.blocks[b as usize], b)
        };
        let block = &mut blocks.blocks[b as usize];
        handoff_from.clear();
        block.place(offset, size, i, &mut handoff_from);
        block.size = block.size.max(offset.saturating_add(size));
        block.alignment = block.alignment.max(alignment);
        blocks.refile(b, before);
        if handoff_from.len() > 1 {
            handoff_from.sort_unstable();
            handoff_from.dedup();
        }
        for &from in &handoff_from {
            out.handoffs.push(AliasHandoff {
                to: ResourceId(i),
                from: ResourceId(from),
            });
        }
        out.slots[i as usize] = Some(MemorySlot {
            block: BlockIndex(b),
            offset_bytes: offset,
            size_bytes: size,
        });
        out.requested_bytes = out.requested_bytes.saturating_add(size);
        block_of[i as usize] = b;
    }
    let dedicated = lifetimes
        .iter()
        .filter(|l| matches!(l.memory, MemoryNeed::Dedicated(_)) && l.lifetime.is_some())
        .count();
    out.blocks = Vec::with_capacity(blocks.blocks.len() + dedicated);
    out.blocks
        .extend(blocks.blocks.into_iter().map(|b| MemoryBlock {
            class: b.class,
            size_bytes: b.size,
            alignment_bytes: b.alignment,
        }));

    // Dedicated resources: one block each, in resource order.
    for (i, l) in lifetimes.iter().enumerate() {
        let MemoryNeed::Dedicated(class) = l.memory else {
            continue;
        };
        if l.lifetime.is_none() {
            continue;
        }
        let size = requirements[i].size_bytes;
        out.slots[i] = Some(MemorySlot {
            block: BlockIndex(out.blocks.len() as u32),
            offset_bytes: 0,
            size_bytes: size,
        });
        out.blocks.push(MemoryBlock {
            class,
            size_bytes: size,
            alignment_bytes: alignments[i],
        });
        out.requested_bytes = out.requested_bytes.saturating_add(size);
    }
    out.allocated_bytes = out
        .blocks
        .iter()
        .fold(0u64, |acc, b| acc.saturating_add(b.size_bytes));
    // Each resource's hand-offs were pushed together, sorted by `from`.
    sort_by_small_key(&mut out.handoffs, |h| h.to.0);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plan::{StepIndex, StepRange};

    fn shared(first: u32, last: u32) -> AliasLifetime {
        AliasLifetime {
            lifetime: Some(StepRange {
                first: StepIndex(first),
                last: StepIndex(last),
            }),
            memory: MemoryNeed::Shared(MemoryClass::DeviceLocal),
        }
    }

    fn req(size_bytes: u64) -> MemoryRequirements {
        MemoryRequirements {
            size_bytes,
            alignment_bytes: 256,
        }
    }

    /// Requirements near `u64::MAX` (only the executor's path can pass them): a gap whose
    /// aligned start would pass `u64::MAX` holds nothing, so live resources never share bytes.
    #[test]
    fn alignment_overflow_never_places_over_a_live_resource() {
        let lifetimes = [shared(0, 0), shared(1, 1), shared(1, 1)];
        let reqs = [
            MemoryRequirements {
                size_bytes: u64::MAX,
                alignment_bytes: 1,
            },
            MemoryRequirements {
                size_bytes: (1 << 63) + 1,
                alignment_bytes: 1,
            },
            MemoryRequirements {
                size_bytes: 1 << 62,
                alignment_bytes: 1 << 63,
            },
        ];
        let a = assign_aliases(&lifetimes, &reqs).unwrap();
        let (b, c) = (a.slots[1].unwrap(), a.slots[2].unwrap());
        assert!(!b.overlaps(&c), "{b:?} and {c:?} are alive at once");
    }

    #[test]
    fn disjoint_lifetimes_share_one_block() {
        let lifetimes = [shared(0, 1), shared(2, 3), shared(4, 5)];
        let reqs = [req(1000), req(800), req(1000)];
        let a = assign_aliases(&lifetimes, &reqs).unwrap();
        assert_eq!(a.blocks.len(), 1);
        assert_eq!(a.blocks[0].size_bytes, 1000);
        assert_eq!(a.requested_bytes, 2800);
        assert_eq!(a.saved_bytes(), 1800);
        // Each follows whoever last held its bytes: 2 covers what 1 and the tail of 0 held.
        let h = |to, from| AliasHandoff {
            to: ResourceId(to),
            from: ResourceId(from),
        };
        assert_eq!(a.handoffs, vec![h(1, 0), h(2, 0), h(2, 1)]);
    }

    #[test]
    fn overlapping_lifetimes_never_share_bytes() {
        let lifetimes = [shared(0, 2), shared(1, 3), shared(2, 4)];
        let reqs = [req(100), req(100), req(100)];
        let a = assign_aliases(&lifetimes, &reqs).unwrap();
        let slots: Vec<_> = a.slots.iter().map(|s| s.unwrap()).collect();
        for i in 0..3 {
            for j in (i + 1)..3 {
                assert!(!slots[i].overlaps(&slots[j]), "{i} and {j} overlap");
            }
        }
        assert_eq!(a.saved_bytes(), 0);
    }

    #[test]
    fn small_resources_pack_into_a_big_retired_block() {
        // A big image dies, then two small buffers live at once: both fit in its bytes.
        let lifetimes = [shared(0, 0), shared(1, 2), shared(1, 2)];
        let reqs = [req(4096), req(1024), req(1024)];
        let a = assign_aliases(&lifetimes, &reqs).unwrap();
        assert_eq!(a.blocks.len(), 1);
        assert_eq!(a.blocks[0].size_bytes, 4096);
        let (s1, s2) = (a.slots[1].unwrap(), a.slots[2].unwrap());
        assert!(!s1.overlaps(&s2));
        assert_eq!(
            a.predecessors(ResourceId(2)).collect::<Vec<_>>(),
            vec![ResourceId(0)]
        );
    }

    #[test]
    fn dedicated_and_external_resources() {
        let lifetimes = [
            AliasLifetime {
                lifetime: Some(StepRange {
                    first: StepIndex(0),
                    last: StepIndex(0),
                }),
                memory: MemoryNeed::Dedicated(MemoryClass::LazilyAllocated),
            },
            AliasLifetime {
                lifetime: Some(StepRange {
                    first: StepIndex(1),
                    last: StepIndex(1),
                }),
                memory: MemoryNeed::External,
            },
        ];
        let a = assign_aliases(&lifetimes, &[req(64), req(64)]).unwrap();
        assert_eq!(a.blocks.len(), 1);
        assert_eq!(a.blocks[0].class, MemoryClass::LazilyAllocated);
        assert!(a.slots[1].is_none());
    }

    #[test]
    fn alignment_is_respected_and_checked() {
        let lifetimes = [shared(0, 5), shared(1, 5)];
        let reqs = [
            req(100),
            MemoryRequirements {
                size_bytes: 100,
                alignment_bytes: 4096,
            },
        ];
        let a = assign_aliases(&lifetimes, &reqs).unwrap();
        assert_eq!(a.slots[1].unwrap().offset_bytes % 4096, 0);
        let bad = [MemoryRequirements {
            size_bytes: 1,
            alignment_bytes: 3,
        }];
        assert!(matches!(
            assign_aliases(&lifetimes[..1], &bad),
            Err(GraphError::InvalidAlignment { .. })
        ));
        assert!(matches!(
            assign_aliases(&lifetimes, &bad),
            Err(GraphError::AliasInputMismatch { .. })
        ));
    }

    #[test]
    fn renumbering_steps_keeps_the_assignment() {
        let a_lifetimes = [shared(0, 1), shared(2, 3), shared(1, 2), shared(4, 4)];
        let b_lifetimes = [shared(1, 3), shared(5, 7), shared(3, 5), shared(9, 9)];
        let reqs = [req(300), req(500), req(200), req(800)];
        assert_eq!(
            assign_aliases(&a_lifetimes, &reqs).unwrap(),
            assign_aliases(&b_lifetimes, &reqs).unwrap()
        );
    }
}
