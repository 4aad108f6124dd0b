//! A frame slot's buffers, and bringing them up to the scene: what changed since the slot's
//! last frame, from the scene's journal (every instance slot and list entry once per frame).

use ash::vk;
use tilegraph_profile::MemoryUse;
use tilegraph_scene::{Change, GpuMaterial, GpuMesh, Scene, SceneCursor};
use tilegraph_vk::ash;
use tilegraph_vk::{Buffer, Context, VkError};

use super::{buffer, grown, no_slot, Capacity, GpuScene, ViewBuffers, NO_ENTRY};

/// A frame slot's buffers: the scene's (shared by the views), then each view's.
pub(super) struct SlotBuffers {
    pub(super) records: Buffer,
    pub(super) order: Buffer,
    pub(super) entries: Buffer,
    pub(super) meshes: Buffer,
    pub(super) materials: Buffer,
    /// Per view: its uniforms, counters and sets.
    pub(super) views: Vec<ViewBuffers>,
    /// Geometry copies of this slot's frame read from here (made when first needed).
    pub(super) staging: Option<Buffer>,
    /// The scene as the slot's buffers hold it (`None`: nothing yet).
    pub(super) cursor: Option<SceneCursor>,
    /// The geometry buffers its sets name ([`GpuScene::geometry_serial`]).
    pub(super) geometry_serial: u64,
}

impl GpuScene {
    /// Brings a slot's records, entries and tables up to the scene.
    pub(super) fn sync_slot(
        &mut self,
        ctx: &Context,
        slot: usize,
        scene: &Scene,
    ) -> Result<(), VkError> {
        let serial = self.frames_written;
        let capacity = self.capacity;
        // The tables grow per slot: a slot's frame is complete when it is written.
        let grow_meshes = self.frames.get(slot).is_some_and(|f| {
            f.meshes.size < (scene.meshes().len() * std::mem::size_of::<GpuMesh>()) as u64
        });
        let grow_materials = self.frames.get(slot).is_some_and(|f| {
            f.materials.size < (scene.materials().len() * std::mem::size_of::<GpuMaterial>()) as u64
        });
        let stale_sets = self
            .frames
            .get(slot)
            .is_some_and(|f| f.geometry_serial != self.geometry_serial);
        if grow_meshes || grow_materials || stale_sets {
            self.regrow_tables(ctx, slot, scene, grow_meshes, grow_materials)?;
        }
        let GpuScene {
            frames,
            record_stamps,
            order_stamps,
            entry_stamps,
            ..
        } = self;
        let f = frames.get_mut(slot).ok_or_else(|| no_slot(slot))?;
        let changes = f.cursor.and_then(|c| scene.changes_since(c));
        let everything = changes.is_none_or(|list| {
            list.iter()
                .any(|c| matches!(c, Change::Layout | Change::Everything))
        });
        let mut w = SlotWriter::new(f)?;
        if everything {
            w.all(scene, capacity);
        } else if let Some(list) = changes {
            for &change in list {
                match change {
                    // Each piece is written once per frame, from the scene as it is: a record
                    // whatever changed it, an instance's entry when it may have moved.
                    Change::Instance(i) => {
                        if once(record_stamps, i, serial) {
                            w.record(scene, i);
                        }
                        if once(order_stamps, i, serial) {
                            w.order(scene, i);
                        }
                    }
                    Change::Moved(i) => {
                        if once(record_stamps, i, serial) {
                            w.record(scene, i);
                        }
                    }
                    Change::Entry(e) => {
                        if once(entry_stamps, e, serial) {
                            w.entry(scene, e);
                        }
                    }
                    Change::Mesh(m) => w.mesh(scene, m),
                    Change::Material(m) => w.material(scene, m),
                    Change::Vertices { .. } | Change::Indices { .. } => {}
                    Change::Layout | Change::Everything => {}
                }
            }
        }
        f.cursor = Some(scene.cursor());
        for b in [&f.records, &f.order, &f.entries, &f.meshes, &f.materials] {
            ctx.flush_mapped(b)?;
        }
        Ok(())
    }

    /// New mesh or material tables for a slot (copied from the scene whole), and its sets
    /// written again (also after the geometry buffers were replaced).
    fn regrow_tables(
        &mut self,
        ctx: &Context,
        slot: usize,
        scene: &Scene,
        meshes: bool,
        materials: bool,
    ) -> Result<(), VkError> {
        let storage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let replace = |old: &mut Buffer, name: &str, bytes: u64| -> Result<(), VkError> {
            let new = buffer(ctx, name, bytes, storage, MemoryUse::Streaming)?;
            ctx.destroy_buffer(std::mem::replace(old, new));
            Ok(())
        };
        let f = self.frames.get_mut(slot).ok_or_else(|| no_slot(slot))?;
        if meshes {
            let bytes = grown(scene.meshes().len() as u64) * std::mem::size_of::<GpuMesh>() as u64;
            replace(&mut f.meshes, &format!("meshes[{slot}]"), bytes)?;
            let all = scene.gpu_meshes();
            ctx.write_mapped(&mut f.meshes, 0, bytemuck::cast_slice(&all))?;
        }
        if materials {
            let bytes =
                grown(scene.materials().len() as u64) * std::mem::size_of::<GpuMaterial>() as u64;
            replace(&mut f.materials, &format!("materials[{slot}]"), bytes)?;
            let all = scene.gpu_materials();
            ctx.write_mapped(&mut f.materials, 0, bytemuck::cast_slice(&all))?;
        }
        f.geometry_serial = self.geometry_serial;
        let f = &self.frames[slot];
        self.write_sets(ctx, f);
        Ok(())
    }
}

pub(super) fn destroy_slot(ctx: &Context, f: SlotBuffers) {
    for b in [f.records, f.order, f.entries, f.meshes, f.materials] {
        ctx.destroy_buffer(b);
    }
    for v in f.views {
        v.destroy(ctx);
    }
    if let Some(s) = f.staging {
        ctx.destroy_buffer(s);
    }
}

/// Whether item `i` is still to be written this frame (`serial`); marks it written.
fn once(stamps: &mut [u64], i: u32, serial: u64) -> bool {
    match stamps.get_mut(i as usize) {
        Some(s) if *s != serial => {
            *s = serial;
            true
        }
        _ => false,
    }
}

/// Writes into a slot's mapped buffers.
struct SlotWriter<'a> {
    records: &'a mut [u8],
    order: &'a mut [u8],
    entries: &'a mut [u8],
    meshes: &'a mut [u8],
    materials: &'a mut [u8],
}

fn put(dst: &mut [u8], index: usize, bytes: &[u8]) {
    let at = index * bytes.len();
    if let Some(d) = dst.get_mut(at..at + bytes.len()) {
        d.copy_from_slice(bytes);
    }
}

impl<'a> SlotWriter<'a> {
    fn new(f: &'a mut SlotBuffers) -> Result<Self, VkError> {
        let not_mapped = || VkError::Invalid {
            what: "scene buffers".into(),
            reason: "the streaming memory is not host-visible".into(),
        };
        Ok(SlotWriter {
            records: f.records.mapped_mut().ok_or_else(not_mapped)?,
            order: f.order.mapped_mut().ok_or_else(not_mapped)?,
            entries: f.entries.mapped_mut().ok_or_else(not_mapped)?,
            meshes: f.meshes.mapped_mut().ok_or_else(not_mapped)?,
            materials: f.materials.mapped_mut().ok_or_else(not_mapped)?,
        })
    }

    /// An instance's record and its entry.
    fn instance(&mut self, scene: &Scene, i: u32) {
        self.record(scene, i);
        self.order(scene, i);
    }

    /// An instance's record.
    fn record(&mut self, scene: &Scene, i: u32) {
        if let Some(inst) = scene.instances().get(i as usize) {
            put(
                self.records,
                i as usize,
                bytemuck::bytes_of(&inst.gpu_record()),
            );
        }
    }

    /// An instance's entry.
    fn order(&mut self, scene: &Scene, i: u32) {
        let entry = scene.buckets().entry(i).unwrap_or(NO_ENTRY);
        put(self.order, i as usize, &entry.to_le_bytes());
    }

    fn entry(&mut self, scene: &Scene, e: u32) {
        let id = scene.buckets().instance_at(e).unwrap_or(NO_ENTRY);
        put(self.entries, e as usize, &id.to_le_bytes());
    }

    fn mesh(&mut self, scene: &Scene, m: u32) {
        if let Some(mesh) = scene.meshes().get(m as usize) {
            put(self.meshes, m as usize, bytemuck::bytes_of(&mesh.gpu()));
        }
    }

    fn material(&mut self, scene: &Scene, m: u32) {
        if let Some(mat) = scene.materials().get(m as usize) {
            put(self.materials, m as usize, bytemuck::bytes_of(&mat.gpu()));
        }
    }

    /// Everything: every record and entry, every list's buckets, both tables.
    fn all(&mut self, scene: &Scene, capacity: Capacity) {
        for i in 0..scene.instances().len() as u32 {
            self.instance(scene, i);
        }
        let buckets = scene.buckets();
        let stride = buckets.stride();
        debug_assert!(stride <= capacity.stride);
        for g in buckets.groups() {
            for (k, &m) in buckets.members(&g).iter().enumerate() {
                let e = (g.list * stride + g.position) as usize + k;
                put(self.entries, e, &m.to_le_bytes());
            }
        }
        for m in 0..scene.meshes().len() as u32 {
            self.mesh(scene, m);
        }
        for m in 0..scene.materials().len() as u32 {
            self.material(scene, m);
        }
    }
}
