//! What changed in a scene since a reader last looked: the list a renderer follows to upload
//! only what changed (docs/ARCHITECTURE.md, "A scene that changes").
//!
//! Each change is one entry; a reader keeps a [`SceneCursor`] and asks for the changes after
//! it. The journal keeps a bounded tail: a reader that fell further behind (or holds a cursor of
//! another scene) is told so and uploads everything once.

use std::sync::atomic::{AtomicU64, Ordering};

/// One change to what a renderer mirrors.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Change {
    /// An instance's record (transform, bounds, mesh, flags) or its draw-list entry changed;
    /// also an instance added or removed.
    Instance(u32),
    /// An instance moved (or its bounds changed): its record, not its draw-list entry.
    Moved(u32),
    /// Draw-list entry `e` ([`crate::DrawBuckets`]) holds another instance.
    Entry(u32),
    /// The draw lists were laid out anew: every entry, and every instance's entry, moved.
    Layout,
    /// A mesh table entry.
    Mesh(u32),
    /// A material table entry.
    Material(u32),
    /// Vertices `start..start + len` of the shared vertex array.
    Vertices { start: u32, len: u32 },
    /// Indices `start..start + len` of the shared index array.
    Indices { start: u32, len: u32 },
    /// Everything (the world moved as a whole, or clusters reordered the indices).
    Everything,
}

/// Where a reader of a scene's changes is: which scene, and how many changes it has seen.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct SceneCursor {
    scene: u64,
    seq: u64,
}

/// A scene's identity: every scene, a clone included, gets its own, so a cursor of one scene
/// never reads another's changes.
#[derive(Debug)]
pub(crate) struct Identity(u64);

impl Identity {
    pub(crate) fn fresh() -> Self {
        static NEXT: AtomicU64 = AtomicU64::new(1);
        Identity(NEXT.fetch_add(1, Ordering::Relaxed))
    }
}

impl Clone for Identity {
    fn clone(&self) -> Self {
        Identity::fresh()
    }
}

/// The tail of a scene's changes.
#[derive(Clone, Debug)]
pub(crate) struct Journal {
    id: Identity,
    /// Sequence number of `changes[0]`.
    base: u64,
    changes: Vec<Change>,
    /// Changes kept: past it, the older half is dropped.
    keep: usize,
}

impl Journal {
    /// Keeps at least `keep` changes (a reader one frame behind, moving every instance, still
    /// finds its changes; one further behind uploads everything).
    pub(crate) fn new(keep: usize) -> Self {
        let keep = keep.max(1 << 16);
        Journal {
            id: Identity::fresh(),
            base: 0,
            // Room for the most it holds (twice `keep`): pushing never reallocates.
            changes: Vec::with_capacity(2 * keep),
            keep,
        }
    }

    /// Keeps at least `keep` changes from now on.
    pub(crate) fn keep_at_least(&mut self, keep: usize) {
        if keep > self.keep {
            self.keep = keep.next_power_of_two();
            let room = 2 * self.keep;
            self.changes
                .reserve(room.saturating_sub(self.changes.len()));
        }
    }

    pub(crate) fn push(&mut self, change: Change) {
        if self.changes.len() >= 2 * self.keep {
            let drop = self.changes.len() - self.keep;
            self.changes.drain(..drop);
            self.base += drop as u64;
        }
        self.changes.push(change);
    }

    pub(crate) fn cursor(&self) -> SceneCursor {
        SceneCursor {
            scene: self.id.0,
            seq: self.base + self.changes.len() as u64,
        }
    }

    /// The changes after `cursor`, or `None` when they are not all kept (or the cursor is
    /// another scene's): the reader takes everything.
    pub(crate) fn since(&self, cursor: SceneCursor) -> Option<&[Change]> {
        if cursor.scene != self.id.0 || cursor.seq < self.base {
            return None;
        }
        let from = usize::try_from(cursor.seq - self.base).ok()?;
        self.changes.get(from..)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_reader_sees_what_came_after_its_cursor_until_it_falls_behind() {
        let mut j = Journal::new(0);
        let keep = j.keep;
        let start = j.cursor();
        j.push(Change::Instance(3));
        let mid = j.cursor();
        j.push(Change::Mesh(1));
        assert_eq!(
            j.since(start),
            Some(&[Change::Instance(3), Change::Mesh(1)][..])
        );
        assert_eq!(j.since(mid), Some(&[Change::Mesh(1)][..]));
        assert_eq!(j.since(j.cursor()), Some(&[][..]));
        // A clone is another scene: its cursors do not read this one.
        let other = j.clone();
        assert_eq!(j.since(other.cursor()), None);
        for i in 0..2 * keep as u32 {
            j.push(Change::Instance(i));
        }
        assert_eq!(j.since(start), None);
        let recent = j.cursor();
        j.push(Change::Layout);
        assert_eq!(j.since(recent), Some(&[Change::Layout][..]));
        assert!(j.changes.len() <= 2 * keep);
    }
}
