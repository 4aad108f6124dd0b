//! Where each instance slot's clusters sit in the cluster stage's buffers (the base words), and
//! how much room the buffers were made with: laid out once over every slot, then followed
//! through the scene's changes at the cost of the changes (docs/CULLING.md, "Instances that
//! come and go").
//!
//! A slot's clusters are a range of the cluster instances and of the chunks of [`CHUNK`], at a
//! prefix of the slots before it. A removed instance's slot keeps its range (the scene keeps a
//! freed slot's mesh, and culling skips it); an instance added in a new slot appends one; an
//! instance added in a freed slot takes the range in place when its mesh has no more clusters
//! than the range holds (the shaders stop at the mesh's own count: the rest of the range idles).
//! Only a slot that needs more than it holds lays every slot out anew, no range smaller than
//! it was.

use tilegraph_scene::{Change, MaterialClass, Scene};

use super::{list_index, LISTS_PER_PHASE};

/// Clusters a workgroup of the cull and emit dispatches handles.
pub const CHUNK: u32 = 64;

/// A slot whose clusters count into no list (blended: drawn by the CPU lists, in place).
const NO_LIST: u8 = u8::MAX;

/// Where each instance slot's clusters sit and how many commands each list can hold.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ClusterLayout {
    /// Per slot: its first cluster instance (its range ends where the next slot's begins, the
    /// last one's at `total`).
    pub base: Vec<u32>,
    /// Cluster instances laid out (blended ones included: they keep their place).
    pub total: u32,
    /// Per list of a phase: the cluster instances of its slots (its most commands).
    pub capacity: [u32; 4],
    /// Per slot, its first chunk of [`CHUNK`] clusters, and the chunks' end: slot `i`'s chunks
    /// are `chunk_base[i]..chunk_base[i + 1]`.
    pub chunk_base: Vec<u32>,
    /// Per chunk, its slot.
    pub chunk_instance: Vec<u32>,
    /// Per slot, the list of a phase its clusters count into ([`NO_LIST`]: none).
    lists: Vec<u8>,
    /// Bumped whenever a slot's range moved (laid out anew): base words written before hold
    /// nothing of this layout; within one epoch, only slots and chunks are appended.
    pub epoch: u64,
}

impl ClusterLayout {
    /// The layout of `scene`'s clusters over every slot, or `None` when it has none attached.
    pub fn of(scene: &Scene) -> Option<Self> {
        Self::lay_out(scene, &[], 0)
    }

    /// Every slot of `scene` laid out, slot `i`'s range at least `floor[i]` clusters.
    fn lay_out(scene: &Scene, floor: &[u32], epoch: u64) -> Option<Self> {
        let mut layout = ClusterLayout {
            base: Vec::with_capacity(scene.instances().len()),
            total: 0,
            capacity: [0; 4],
            chunk_base: Vec::with_capacity(scene.instances().len() + 1),
            chunk_instance: Vec::new(),
            lists: Vec::with_capacity(scene.instances().len()),
            epoch,
        };
        layout.chunk_base.push(0);
        layout.append(scene, floor)?;
        Some(layout)
    }

    /// Chunks of [`CHUNK`] clusters over every slot.
    pub fn chunks(&self) -> u32 {
        self.chunk_instance.len() as u32
    }

    /// Slots laid out.
    pub fn slots(&self) -> u32 {
        self.base.len() as u32
    }

    /// Follows `scene` from the state `changes` lead from (`None`: unknown, the scene lost
    /// track): new slots appended, a slot reused in place where its range holds the new mesh's
    /// clusters (a list's capacity moved with it), else every slot laid out anew. False when
    /// the scene has no clusters any more.
    pub fn follow(&mut self, scene: &Scene, changes: Option<&[Change]>) -> bool {
        let Some(clusters) = scene.clusters() else {
            return false;
        };
        let anew = match changes {
            // A mesh cannot change while clusters are attached (the scene refuses), nor a
            // material's class (`Scene::set_engine_material` keeps it): the slots say it all.
            Some(changes) => changes.iter().any(|c| match *c {
                Change::Everything | Change::Mesh(_) => true,
                Change::Instance(i) if i < self.slots() => {
                    let (count, list) = slot_needs(scene, clusters, i);
                    let allocated = self.allocated(i);
                    if count > allocated {
                        return true;
                    }
                    if count < allocated {
                        log::debug!("cluster layout: slot {i} holds {count} of its {allocated}");
                    }
                    self.move_list(i, list);
                    false
                }
                _ => false,
            }),
            None => true,
        };
        if anew {
            let epoch = self.epoch + 1;
            log::debug!(
                "cluster layout: {} slots laid out anew (epoch {epoch})",
                scene.instances().len()
            );
            // No range shrinks: a slot that held a larger mesh may again (instances of a few
            // kinds churning through the freed slots lay out anew once, not every time).
            let floor: Vec<u32> = (0..self.slots()).map(|i| self.allocated(i)).collect();
            match Self::lay_out(scene, &floor, epoch) {
                Some(fresh) => *self = fresh,
                None => return false,
            }
            return true;
        }
        self.append(scene, &[]).is_some()
    }

    /// Slot `i`'s cluster instances.
    fn allocated(&self, i: u32) -> u32 {
        let end = self.base.get(i as usize + 1).copied().unwrap_or(self.total);
        self.base.get(i as usize).map_or(0, |&b| end - b)
    }

    /// Moves slot `i`'s range from the list it counted into to `list`.
    fn move_list(&mut self, i: u32, list: u8) {
        let allocated = self.allocated(i);
        let Some(old) = self.lists.get_mut(i as usize) else {
            return;
        };
        if *old == list {
            return;
        }
        if let Some(c) = self.capacity.get_mut(usize::from(*old)) {
            *c -= allocated;
        }
        if let Some(c) = self.capacity.get_mut(usize::from(list)) {
            *c += allocated;
        }
        *old = list;
    }

    /// Lays out the scene's slots past the last one laid out, slot `i`'s range at least
    /// `floor[i]` clusters; `None` without clusters, or where the cluster instances would
    /// pass 2^32 (the shaders' words).
    fn append(&mut self, scene: &Scene, floor: &[u32]) -> Option<()> {
        let clusters = scene.clusters()?;
        if self.slots() < scene.instances().len() as u32 && self.slots() > 0 {
            log::debug!(
                "cluster layout: slots {}..{} appended",
                self.slots(),
                scene.instances().len()
            );
        }
        for i in self.slots()..scene.instances().len() as u32 {
            let (need, list) = slot_needs(scene, clusters, i);
            let count = need.max(floor.get(i as usize).copied().unwrap_or(0));
            self.base.push(self.total);
            self.total = self.total.checked_add(count)?;
            let chunks = count.div_ceil(CHUNK) as usize;
            self.chunk_instance.extend(std::iter::repeat_n(i, chunks));
            self.chunk_base.push(self.chunk_instance.len() as u32);
            if let Some(c) = self.capacity.get_mut(usize::from(list)) {
                *c += count;
            }
            self.lists.push(list);
        }
        Some(())
    }
}

/// Slot `i`'s clusters (its mesh's) and the list of a phase they count into.
fn slot_needs(scene: &Scene, clusters: &tilegraph_scene::clusters::Clusters, i: u32) -> (u32, u8) {
    let Some(inst) = scene.instances().get(i as usize) else {
        return (0, NO_LIST);
    };
    let count = clusters.of_mesh(inst.mesh.0).len() as u32;
    let material = scene.instance_material(inst);
    let class = match material.map(|m| m.class) {
        Some(MaterialClass::Blended) => return (count, NO_LIST),
        Some(MaterialClass::AlphaTested { .. }) => 1,
        Some(MaterialClass::Opaque) | None => 0,
    };
    let sided = material.is_some_and(|m| m.double_sided);
    (count, list_index(class, sided, 0) as u8)
}

/// What the stage's buffers were made to hold: a layout a quarter larger than the scene's
/// when they were made (and 64 more of each), so that instances coming and going take a new
/// layout in the same buffers (`ClusterStage::follow`) — the culling history, the pyramid and
/// the frames in flight stay — and new buffers are made once per growth of a quarter.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ClusterRoom {
    /// Cluster instances: each region's flags and the cluster visibility.
    pub total: u32,
    /// Chunks: each region's chunk list and chunk runs (`CullParams::commands` w, their stride).
    pub chunks: u32,
    /// Per list of a phase: its most commands.
    pub capacity: [u32; 4],
    /// Per list 0-7: its first command.
    pub cmd_base: [u32; 8],
    /// Instance slots the base words have room for.
    pub instances: u32,
}

impl ClusterRoom {
    /// Room for `layout` and growth, and for `instances` instance slots.
    pub fn for_layout(layout: &ClusterLayout, instances: u32) -> Self {
        // A list with no clusters stays empty: a first instance in it is a new layout.
        let grown = |x: u32| {
            if x == 0 {
                0
            } else {
                x.saturating_add(x / 4).saturating_add(64)
            }
        };
        let capacity = layout.capacity.map(grown);
        let mut cmd_base = [0u32; 8];
        let mut at = 0u32;
        for (list, b) in cmd_base.iter_mut().enumerate() {
            *b = at;
            at = at.saturating_add(capacity[list % LISTS_PER_PHASE as usize]);
        }
        ClusterRoom {
            total: grown(layout.total),
            chunks: grown(layout.chunks()),
            capacity,
            cmd_base,
            instances: instances.max(layout.slots()),
        }
    }

    /// Whether `layout` fits.
    pub fn holds(&self, layout: &ClusterLayout) -> bool {
        layout.total <= self.total
            && layout.chunks() <= self.chunks
            && layout.slots() <= self.instances
            && layout
                .capacity
                .iter()
                .zip(self.capacity)
                .all(|(&need, room)| need <= room)
    }

    /// Commands of both phases' lists.
    pub fn commands(&self) -> u32 {
        2 * self.capacity.iter().sum::<u32>()
    }

    /// Where the base words keep each slot's first chunk and each chunk's slot
    /// (`CullParams::commands` y, z): after room for every slot's first cluster instance, and
    /// for every slot's first chunk and the chunks' end. The places do not move as slots are
    /// appended, so appending writes only what was appended ([`Self::base_writes`]).
    pub fn chunk_words(&self) -> [u32; 2] {
        [self.instances, 2 * self.instances + 1]
    }

    /// Bytes of the base words.
    pub fn base_bytes(&self) -> u64 {
        4 * (2 * u64::from(self.instances) + 1 + u64::from(self.chunks))
    }

    /// The writes (word offset, words) that bring base words holding `written` — the
    /// layout's epoch, slots and chunks when they were last written; `None`: nothing — to
    /// `layout` (which the room holds): the appended slots and chunks within one epoch,
    /// everything else.
    pub fn base_writes<'a>(
        &self,
        layout: &'a ClusterLayout,
        written: Option<(u64, u32, u32)>,
    ) -> [(u32, &'a [u32]); 3] {
        let (slots, chunks) = match written {
            Some((epoch, slots, chunks))
                if epoch == layout.epoch
                    && slots <= layout.slots()
                    && chunks <= layout.chunks() =>
            {
                (slots as usize, chunks as usize)
            }
            _ => (0, 0),
        };
        let [first_chunks, chunk_slots] = self.chunk_words();
        let tail = |words: &'a [u32], from: usize| words.get(from..).unwrap_or(&[]);
        // A slot's first chunk and the end after it: the end written last time is the first
        // appended slot's first chunk, the same word.
        [
            (slots as u32, tail(&layout.base, slots)),
            (first_chunks + slots as u32, tail(&layout.chunk_base, slots)),
            (
                chunk_slots + chunks as u32,
                tail(&layout.chunk_instance, chunks),
            ),
        ]
    }
}

#[cfg(test)]
mod tests;
