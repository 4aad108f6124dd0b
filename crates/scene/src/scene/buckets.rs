//! The scene's draw lists, kept from change to change instead of sorted every frame.
//!
//! Every drawn opaque or alpha-tested instance sits in one **bucket**: its draw list (material
//! class and sidedness, `class * 2 + double_sided`, the GPU culling's list numbers) and its
//! mesh. A bucket's members are consecutive **entries** of its list, from the bucket's base; a
//! list's entries are `list * stride .. (list + 1) * stride`. A bucket is one instanced draw
//! unculled and one draw group for GPU culling, which draws a bucket's survivors in entry
//! order: every technique draws in one order, so culled images equal unculled ones.
//!
//! Adding an instance appends it to its bucket; removing one moves the bucket's last member
//! into the hole (one entry changes). Buckets are laid out with room to grow (a quarter of their
//! size and 8 more); one that outgrows its room, or a new bucket that does not fit its list, lays
//! every bucket out again ([`Change::Layout`]: rare, and a renderer then uploads every entry).
//! The order is the order of changes, so every renderer of one scene draws alike, whenever it
//! was made.

use std::collections::HashMap;

use super::journal::{Change, Journal};
use crate::bounds::DAabb;

/// Draw lists: opaque and alpha-tested, single- and double-sided (`class * 2 + sided`).
pub const DRAW_LISTS: usize = 4;

const NONE: u32 = u32::MAX;

#[derive(Clone, Debug)]
struct Bucket {
    list: u8,
    mesh: u32,
    /// First entry, relative to the list's start.
    base: u32,
    /// Entries laid out for it.
    capacity: u32,
    members: Vec<u32>,
    /// The union of its members' boxes: grown as they arrive or move, made tight again at a
    /// layout (what a frame orders buckets by).
    bounds: DAabb,
}

/// One bucket as drawn: `len` consecutive entries of list `list` from `position`, all of mesh
/// `mesh`, inside `bounds` (world space, perhaps loose).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DrawGroup {
    pub list: u32,
    pub mesh: u32,
    pub position: u32,
    pub len: u32,
    pub bounds: DAabb,
}

/// The buckets of a scene's drawn opaque and alpha-tested instances.
#[derive(Clone, Debug, Default)]
pub struct DrawBuckets {
    buckets: Vec<Bucket>,
    keys: HashMap<(u8, u32), u32>,
    /// Per list: its buckets in draw order (increasing base).
    lists: [Vec<u32>; DRAW_LISTS],
    /// Per list: entries laid out (the next bucket's base).
    used: [u32; DRAW_LISTS],
    stride: u32,
    /// Per instance slot: its bucket and position, `NONE` when not in one.
    place: Vec<(u32, u32)>,
}

/// Room a bucket of `len` members is laid out with.
fn room(len: usize) -> u32 {
    let len = len as u32;
    len.saturating_add(len / 4).saturating_add(8)
}

impl DrawBuckets {
    /// Buckets of `items` (instance, list, mesh, box) for a scene of `slots` instance slots.
    pub(crate) fn build(slots: usize, items: impl Iterator<Item = (u32, u8, u32, DAabb)>) -> Self {
        let mut b = DrawBuckets {
            place: vec![(NONE, 0); slots],
            ..Default::default()
        };
        for (instance, list, mesh, aabb) in items {
            let bucket = b.bucket_of(list, mesh);
            let bk = &mut b.buckets[bucket as usize];
            if let Some(p) = b.place.get_mut(instance as usize) {
                *p = (bucket, bk.members.len() as u32);
                bk.members.push(instance);
                bk.bounds = bk.bounds.union(aabb);
            }
        }
        b.lay_out(None);
        b
    }

    /// The bucket of (list, mesh), made (with no room) when new.
    fn bucket_of(&mut self, list: u8, mesh: u32) -> u32 {
        if let Some(&b) = self.keys.get(&(list, mesh)) {
            return b;
        }
        let b = self.buckets.len() as u32;
        self.buckets.push(Bucket {
            list,
            mesh,
            base: 0,
            capacity: 0,
            members: Vec::new(),
            bounds: DAabb::EMPTY,
        });
        self.keys.insert((list, mesh), b);
        if let Some(l) = self.lists.get_mut(list as usize) {
            l.push(b);
        }
        b
    }

    /// Lays every bucket out anew, each list's buckets by mesh, empty ones dropped; with
    /// `boxes` (per instance slot), each bucket's bounds made tight again.
    fn lay_out(&mut self, boxes: Option<&dyn Fn(u32) -> DAabb>) {
        let mut old = std::mem::take(&mut self.buckets);
        self.keys.clear();
        self.lists = Default::default();
        for list in 0..DRAW_LISTS as u8 {
            let mut ids: Vec<usize> = (0..old.len())
                .filter(|&i| old[i].list == list && !old[i].members.is_empty())
                .collect();
            ids.sort_unstable_by_key(|&i| old[i].mesh);
            let mut at = 0u32;
            for i in ids {
                let mut bucket = std::mem::replace(
                    &mut old[i],
                    Bucket {
                        list,
                        mesh: 0,
                        base: 0,
                        capacity: 0,
                        members: Vec::new(),
                        bounds: DAabb::EMPTY,
                    },
                );
                if let Some(boxes) = boxes {
                    bucket.bounds = bucket
                        .members
                        .iter()
                        .fold(DAabb::EMPTY, |b, &m| b.union(boxes(m)));
                }
                bucket.base = at;
                bucket.capacity = room(bucket.members.len());
                at = at.saturating_add(bucket.capacity);
                let id = self.buckets.len() as u32;
                for (pos, &m) in bucket.members.iter().enumerate() {
                    if let Some(p) = self.place.get_mut(m as usize) {
                        *p = (id, pos as u32);
                    }
                }
                self.keys.insert((list, bucket.mesh), id);
                self.lists[list as usize].push(id);
                self.buckets.push(bucket);
            }
            self.used[list as usize] = at;
        }
        let most = self.used.iter().copied().max().unwrap_or(0);
        self.stride = most.saturating_add(most / 4).saturating_add(64);
    }

    /// Puts `instance` (not in a bucket, with box `aabb`) into the bucket of (`list`, `mesh`);
    /// `boxes` gives every instance's box should the buckets be laid out again.
    pub(crate) fn insert(
        &mut self,
        instance: u32,
        (list, mesh, aabb): (u8, u32, DAabb),
        boxes: &dyn Fn(u32) -> DAabb,
        journal: &mut Journal,
    ) {
        debug_assert!(usize::from(list) < DRAW_LISTS);
        if self.place.len() <= instance as usize {
            self.place.resize(instance as usize + 1, (NONE, 0));
        }
        debug_assert_eq!(self.place[instance as usize].0, NONE);
        let bucket = self.bucket_of(list, mesh);
        let b = &mut self.buckets[bucket as usize];
        let mut fits = (b.members.len() as u32) < b.capacity;
        if b.capacity == 0 {
            // A new bucket: at the end of its list, when the stride has room.
            let used = &mut self.used[list as usize];
            let capacity = room(0);
            if used.saturating_add(capacity) <= self.stride {
                b.base = *used;
                b.capacity = capacity;
                *used += capacity;
                fits = true;
            }
        }
        let pos = b.members.len() as u32;
        b.members.push(instance);
        b.bounds = b.bounds.union(aabb);
        self.place[instance as usize] = (bucket, pos);
        if fits {
            let entry = u32::from(list) * self.stride + b.base + pos;
            journal.push(Change::Entry(entry));
        } else {
            self.lay_out(Some(boxes));
            journal.push(Change::Layout);
        }
    }

    /// `instance` (in a bucket or not) now has box `aabb`: its bucket's bounds grow.
    pub(crate) fn moved(&mut self, instance: u32, aabb: DAabb) {
        if let Some(&(bucket, _)) = self.place.get(instance as usize) {
            if let Some(b) = self.buckets.get_mut(bucket as usize) {
                b.bounds = b.bounds.union(aabb);
            }
        }
    }

    /// Takes `instance` out of its bucket (if in one); the bucket's last member takes its entry.
    pub(crate) fn remove(&mut self, instance: u32, journal: &mut Journal) {
        let Some(&(bucket, pos)) = self.place.get(instance as usize) else {
            return;
        };
        if bucket == NONE {
            return;
        }
        self.place[instance as usize] = (NONE, 0);
        let b = &mut self.buckets[bucket as usize];
        b.members.swap_remove(pos as usize);
        if let Some(&moved) = b.members.get(pos as usize) {
            let entry = u32::from(b.list) * self.stride + b.base + pos;
            self.place[moved as usize] = (bucket, pos);
            journal.push(Change::Entry(entry));
            journal.push(Change::Instance(moved));
        }
    }

    /// Entries per list (`list * stride + position` is an entry).
    pub fn stride(&self) -> u32 {
        self.stride
    }

    /// The entry of `instance`, when it is in a bucket.
    pub fn entry(&self, instance: u32) -> Option<u32> {
        let &(bucket, pos) = self.place.get(instance as usize)?;
        let b = self.buckets.get(bucket as usize)?;
        Some(u32::from(b.list) * self.stride + b.base + pos)
    }

    /// The instance at `entry`, when one is there.
    pub fn instance_at(&self, entry: u32) -> Option<u32> {
        let stride = self.stride.max(1);
        let (list, at) = ((entry / stride) as usize, entry % stride);
        let ids = self.lists.get(list)?;
        let k = ids.partition_point(|&b| self.buckets[b as usize].base <= at);
        let b = &self.buckets[ids.get(k.checked_sub(1)?).copied()? as usize];
        b.members.get((at - b.base) as usize).copied()
    }

    /// The non-empty buckets, list by list, in draw order.
    pub fn groups(&self) -> impl Iterator<Item = DrawGroup> + '_ {
        self.lists.iter().enumerate().flat_map(move |(list, ids)| {
            ids.iter()
                .map(move |&b| &self.buckets[b as usize])
                .filter(|b| !b.members.is_empty())
                .map(move |b| DrawGroup {
                    list: list as u32,
                    mesh: b.mesh,
                    position: b.base,
                    len: b.members.len() as u32,
                    bounds: b.bounds,
                })
        })
    }

    /// The members of the bucket `group` came from, in entry order.
    pub fn members(&self, group: &DrawGroup) -> &[u32] {
        self.keys
            .get(&(group.list as u8, group.mesh))
            .and_then(|&b| self.buckets.get(b as usize))
            .map_or(&[], |b| &b.members)
    }

    /// Instances in buckets, per list.
    pub fn counts(&self) -> [usize; DRAW_LISTS] {
        let mut c = [0; DRAW_LISTS];
        for b in &self.buckets {
            c[b.list as usize % DRAW_LISTS] += b.members.len();
        }
        c
    }

    /// Buckets laid out (empty ones included until the next layout).
    pub fn bucket_count(&self) -> usize {
        self.buckets.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Every member's entry maps back to it, entries of a bucket are consecutive from its base
    /// and inside its room, rooms never overlap and fit the stride.
    fn check(b: &DrawBuckets, expected: &HashMap<u32, (u8, u32)>) {
        let mut seen = 0;
        for g in b.groups() {
            let members = b.members(&g);
            assert_eq!(members.len() as u32, g.len);
            for (k, &m) in members.iter().enumerate() {
                let entry = g.list * b.stride() + g.position + k as u32;
                assert_eq!(b.entry(m), Some(entry));
                assert_eq!(b.instance_at(entry), Some(m));
                assert_eq!(expected.get(&m), Some(&(g.list as u8, g.mesh)));
                seen += 1;
            }
        }
        assert_eq!(seen, expected.len());
        for (list, ids) in b.lists.iter().enumerate() {
            let mut end = 0;
            for &id in ids {
                let bucket = &b.buckets[id as usize];
                assert_eq!(bucket.list as usize, list);
                assert!(bucket.base >= end);
                assert!(bucket.members.len() as u32 <= bucket.capacity);
                end = bucket.base + bucket.capacity;
            }
            assert!(end <= b.stride());
        }
    }

    #[derive(Debug, Clone)]
    enum Op {
        Add { list: u8, mesh: u32 },
        Remove(usize),
    }

    fn op() -> impl Strategy<Value = Op> {
        prop_oneof![
            3 => (0u8..4, 0u32..5).prop_map(|(list, mesh)| Op::Add { list, mesh }),
            2 => any::<usize>().prop_map(Op::Remove),
        ]
    }

    proptest! {
        #[test]
        fn buckets_stay_consistent_under_any_adds_and_removes(
            initial in proptest::collection::vec((0u8..4, 0u32..5), 0..40),
            ops in proptest::collection::vec(op(), 0..300),
        ) {
            let mut expected: HashMap<u32, (u8, u32)> = HashMap::new();
            for (i, &(l, m)) in initial.iter().enumerate() {
                expected.insert(i as u32, (l, m));
            }
            let unit = |_| DAabb::new(glam::DVec3::ZERO, glam::DVec3::ONE);
            let mut b = DrawBuckets::build(
                initial.len(),
                initial.iter().enumerate().map(|(i, &(l, m))| (i as u32, l, m, unit(0))),
            );
            let mut j = Journal::new(0);
            check(&b, &expected);
            let mut next = initial.len() as u32;
            for op in ops {
                match op {
                    Op::Add { list, mesh } => {
                        b.insert(next, (list, mesh, unit(0)), &unit, &mut j);
                        expected.insert(next, (list, mesh));
                        next += 1;
                    }
                    Op::Remove(k) => {
                        let mut live: Vec<u32> = expected.keys().copied().collect();
                        live.sort_unstable();
                        if let Some(&victim) = live.get(k % live.len().max(1)) {
                            b.remove(victim, &mut j);
                            expected.remove(&victim);
                            prop_assert_eq!(b.entry(victim), None);
                        }
                    }
                }
                check(&b, &expected);
            }
        }
    }

    #[test]
    fn a_removal_moves_one_member_and_says_so() {
        let unit = |_| DAabb::new(glam::DVec3::ZERO, glam::DVec3::ONE);
        let mut b = DrawBuckets::build(
            3,
            [(0, 0, 7, unit(0)), (1, 0, 7, unit(0)), (2, 0, 7, unit(0))].into_iter(),
        );
        let mut j = Journal::new(0);
        let start = j.cursor();
        let last = b.entry(2);
        b.remove(0, &mut j);
        // The last member took the hole.
        assert_eq!(b.entry(2), Some(0));
        assert_eq!(last, Some(2));
        assert_eq!(
            j.since(start),
            Some(&[Change::Entry(0), Change::Instance(2)][..])
        );
        // Growing past the room lays out again, once.
        let before = j.cursor();
        for i in 3..3 + room(3) {
            b.insert(i, (0, 7, unit(0)), &unit, &mut j);
        }
        let layouts = j
            .since(before)
            .map_or(0, |c| c.iter().filter(|c| **c == Change::Layout).count());
        assert_eq!(layouts, 1);
    }
}
