//! A scene a game changes: instances added, removed, moved, hidden; meshes streamed in and
//! out; materials added. Each change goes through a generation-checked handle, is refused
//! whole when any part of it is wrong (a stale handle, a NaN), and is written to the
//! scene's journal, from which a renderer uploads only what changed at its next frame.
//!
//! What the CPU keeps per instance beside the arrays — its draw bucket
//! ([`DrawBuckets`](super::buckets::DrawBuckets)) and its grid cell ([`LooseGrid`]) — changes
//! with it, at a cost that does not grow with the scene.

use std::collections::HashMap;

use glam::Vec3;

use super::buckets::DrawBuckets;
use super::grid::LooseGrid;
use super::journal::{Change, Journal, SceneCursor};
use super::mirror::{mirroring, Mirrors};
use super::pool::{write_range, RangePool};
use super::{
    check_mesh, ClassCounts, Instance, InstanceBounds, InstanceFlags, InstanceHandle, InstanceId,
    Material, MaterialClass, MaterialId, Mesh, MeshHandle, MeshId, Scene, Transform, Vertex,
};
use crate::bounds::{transformed_bounds, Aabb};
use crate::error::SceneError;

/// What a scene keeps to be changed by handle: generations, free slots, geometry ranges,
/// buckets, grids and the journal.
#[derive(Clone, Debug)]
pub(super) struct Dynamic {
    /// Per instance slot: its generation, bumped when its instance is removed.
    pub generations: Vec<u32>,
    pub free_instances: Vec<u32>,
    /// Per mesh: its generation, bumped when it is removed.
    pub mesh_generations: Vec<u32>,
    /// Per mesh: the live instances that draw it.
    pub mesh_users: Vec<u32>,
    pub free_meshes: Vec<u32>,
    pub vertex_pool: RangePool,
    pub index_pool: RangePool,
    /// Local boxes an engine gave for instances it animates (skinned meshes).
    pub local_bounds: HashMap<u32, Aabb>,
    pub buckets: DrawBuckets,
    /// The drawn blended instances (every frame sorts the visible ones back to front). The
    /// opaque ones have no grid here: only the techniques whose CPU decides what is drawn look
    /// for them, and such a renderer keeps its own (a move pays for no grid it does not use).
    pub blended_grid: LooseGrid,
    pub journal: Journal,
    /// Changes of which instances and meshes exist (not of where they are).
    pub structure: u64,
    /// Drawn instances per material class.
    pub drawn: ClassCounts,
    /// A batch's new bounds, checked before any is applied (kept: no allocation per batch).
    pub scratch: Vec<InstanceBounds>,
    /// Each mesh's winding and its copy with the other, for mirroring instances.
    pub mirrors: Mirrors,
}

/// The edit a bounds computation is for (what an error names).
#[derive(Clone, Copy)]
enum Edit {
    New,
    Batch(usize),
    LocalBounds,
}

/// Where a drawn instance goes: a draw list (opaque and alpha-tested) or the blended set.
enum Placement {
    List(u8, u32),
    Blended,
}

impl Dynamic {
    /// The bookkeeping of a scene as built: every instance and mesh at generation 0.
    pub(super) fn build(
        instances: &[Instance],
        meshes: &[Mesh],
        materials: &[Material],
        vertices: usize,
        indices: usize,
        bounds: crate::bounds::DAabb,
        mut mirrors: Mirrors,
    ) -> Self {
        mirrors.infer(
            meshes.len(),
            instances
                .iter()
                .map(|i| (i.mesh.0, mirroring(&i.transform.linear))),
        );
        let mut mesh_users = vec![0u32; meshes.len()];
        for i in instances {
            if let Some(u) = mesh_users.get_mut(i.mesh.index()) {
                *u += 1;
            }
        }
        let mut d = Dynamic {
            generations: vec![0; instances.len()],
            free_instances: Vec::new(),
            mesh_generations: vec![0; meshes.len()],
            mesh_users,
            free_meshes: Vec::new(),
            vertex_pool: RangePool::full(vertices as u32),
            index_pool: RangePool::full(indices as u32),
            local_bounds: HashMap::new(),
            buckets: DrawBuckets::default(),
            blended_grid: LooseGrid::new(bounds, 0),
            journal: Journal::new(instances.len()),
            structure: 0,
            drawn: ClassCounts::default(),
            scratch: Vec::new(),
            mirrors,
        };
        d.index_all(instances, meshes, materials, bounds);
        d
    }

    /// Builds the buckets and grids of every drawn instance anew.
    pub(super) fn index_all(
        &mut self,
        instances: &[Instance],
        meshes: &[Mesh],
        materials: &[Material],
        bounds: crate::bounds::DAabb,
    ) {
        let mut lists = Vec::with_capacity(instances.len());
        let mut blended = 0;
        self.drawn = ClassCounts::default();
        for (i, inst) in instances.iter().enumerate() {
            if !inst.flags.is_drawn() {
                continue;
            }
            let material = material_of(meshes, materials, inst.mesh);
            if let Some(m) = material {
                self.drawn.add(m.class);
            }
            match placement(material, inst.mesh) {
                Placement::List(l, m) => lists.push((i as u32, l, m, inst.bounds.aabb())),
                Placement::Blended => blended += 1,
            }
        }
        self.buckets = DrawBuckets::build(instances.len(), lists.into_iter());
        self.blended_grid = LooseGrid::new(bounds, blended);
        for (i, inst) in instances.iter().enumerate() {
            let material = material_of(meshes, materials, inst.mesh);
            if inst.flags.is_drawn() && matches!(placement(material, inst.mesh), Placement::Blended)
            {
                self.blended_grid
                    .insert(i as u32, inst.mesh.0, &inst.bounds);
            }
        }
    }
}

fn material_of<'a>(
    meshes: &[Mesh],
    materials: &'a [Material],
    mesh: MeshId,
) -> Option<&'a Material> {
    meshes
        .get(mesh.index())
        .and_then(|m| materials.get(m.material.index()))
}

fn placement(material: Option<&Material>, mesh: MeshId) -> Placement {
    let (class, sided) = match material {
        Some(m) => (m.class, m.double_sided),
        None => (MaterialClass::Opaque, false),
    };
    match class {
        MaterialClass::Blended => Placement::Blended,
        MaterialClass::AlphaTested { .. } => Placement::List(2 + u8::from(sided), mesh.0),
        MaterialClass::Opaque => Placement::List(u8::from(sided), mesh.0),
    }
}

impl Scene {
    /// The handle of the instance in slot `id`, when one lives there.
    pub fn instance_handle(&self, id: InstanceId) -> Option<InstanceHandle> {
        let inst = self.instances.get(id.index())?;
        let generation = *self.dynamic.generations.get(id.index())?;
        (!inst.flags.is_free()).then_some(InstanceHandle {
            slot: id.0,
            generation,
        })
    }

    /// The handle of mesh `id`, when it exists.
    pub fn mesh_handle(&self, id: MeshId) -> Option<MeshHandle> {
        let generation = *self.dynamic.mesh_generations.get(id.index())?;
        let live = self.meshes.get(id.index())?.index_count > 0;
        live.then_some(MeshHandle {
            index: id.0,
            generation,
        })
    }

    /// The slot of a live instance, or [`SceneError::StaleHandle`].
    fn live_slot(&self, h: InstanceHandle) -> Result<usize, SceneError> {
        let slot = h.slot as usize;
        match (self.dynamic.generations.get(slot), self.instances.get(slot)) {
            (Some(&g), Some(i)) if g == h.generation && !i.flags.is_free() => Ok(slot),
            (Some(&g), Some(_)) => Err(self.stale("instance", h.slot, h.generation, g)),
            _ => Err(SceneError::StaleHandle {
                scene: self.name.clone(),
                what: "instance",
                index: h.slot,
                generation: h.generation,
                reason: format!(
                    "no such slot (the scene has {} instance slots)",
                    self.instances.len()
                ),
            }),
        }
    }

    pub(super) fn live_mesh(&self, h: MeshHandle) -> Result<usize, SceneError> {
        let i = h.index as usize;
        match self.dynamic.mesh_generations.get(i) {
            Some(&g) if g == h.generation && self.mesh_handle(MeshId(h.index)).is_some() => Ok(i),
            Some(&g) => Err(self.stale("mesh", h.index, h.generation, g)),
            None => Err(SceneError::StaleHandle {
                scene: self.name.clone(),
                what: "mesh",
                index: h.index,
                generation: h.generation,
                reason: format!("no such mesh (the scene has {})", self.meshes.len()),
            }),
        }
    }

    fn stale(&self, what: &'static str, index: u32, generation: u32, now: u32) -> SceneError {
        SceneError::StaleHandle {
            scene: self.name.clone(),
            what,
            index,
            generation,
            reason: if now == generation {
                "removed".into()
            } else {
                format!("removed (the slot is at generation {now} now)")
            },
        }
    }

    /// The live instance behind `h`.
    pub fn instance(&self, h: InstanceHandle) -> Result<&Instance, SceneError> {
        let slot = self.live_slot(h)?;
        Ok(&self.instances[slot])
    }

    /// Instances that exist (drawn or hidden); [`Scene::instances`] also holds free slots.
    pub fn live_instances(&self) -> usize {
        self.instances.len() - self.dynamic.free_instances.len()
    }

    /// Drawn instances per material class.
    pub fn drawn_by_class(&self) -> ClassCounts {
        self.dynamic.drawn
    }

    /// The draw buckets of the drawn opaque and alpha-tested instances.
    pub fn buckets(&self) -> &DrawBuckets {
        &self.dynamic.buckets
    }

    /// The loose grid of the drawn blended instances.
    pub fn blended_grid(&self) -> &LooseGrid {
        &self.dynamic.blended_grid
    }

    /// Where the changes stand now: a renderer keeps this after an upload.
    pub fn cursor(&self) -> SceneCursor {
        self.dynamic.journal.cursor()
    }

    /// The changes after `cursor`, or `None` when the scene no longer keeps them all (or the
    /// cursor is another scene's): then everything is to be read again.
    pub fn changes_since(&self, cursor: SceneCursor) -> Option<&[Change]> {
        self.dynamic.journal.since(cursor)
    }

    /// A number that changes whenever instances or meshes are added or removed (not when they
    /// move or hide): what a renderer's per-instance layouts (query groups, cluster bases)
    /// depend on.
    pub fn structure_version(&self) -> u64 {
        self.dynamic.structure
    }

    /// Materials are read by meshes; a new one is in the journal for renderers.
    pub fn add_material(&mut self, material: Material) -> Result<MaterialId, SceneError> {
        let cutoff = match material.class {
            MaterialClass::AlphaTested { cutoff } => cutoff,
            _ => 0.0,
        };
        if !(material.base_color.iter().all(|c| c.is_finite()) && cutoff.is_finite()) {
            return Err(SceneError::NonFinite {
                file: self.name.clone(),
                pointer: format!("/materials/{}", self.materials.len()),
                what: "material".into(),
            });
        }
        if let Some(t) = material
            .base_color_texture
            .filter(|t| t.index() >= self.textures.len())
        {
            return Err(SceneError::Invalid {
                file: self.name.clone(),
                pointer: format!("/materials/{}/baseColorTexture", self.materials.len()),
                reason: format!("texture {} of {}", t.0, self.textures.len()),
            });
        }
        let id = MaterialId(self.materials.len() as u32);
        self.materials.push(material);
        self.dynamic.journal.push(Change::Material(id.0));
        Ok(id)
    }

    /// Sets which engine material draws material `id` (`None`: tilegraph's shaders). Nothing
    /// else of the material changes: its class, and so every draw list, stay as they are.
    pub fn set_engine_material(
        &mut self,
        id: MaterialId,
        engine: Option<u32>,
    ) -> Result<(), SceneError> {
        let count = self.materials.len();
        let m = self
            .materials
            .get_mut(id.index())
            .ok_or_else(|| SceneError::Invalid {
                file: self.name.clone(),
                pointer: format!("/materials/{}", id.0),
                reason: format!("material {} of {count}", id.0),
            })?;
        m.engine_material = engine;
        self.dynamic.journal.push(Change::Material(id.0));
        Ok(())
    }

    /// Adds a mesh: its vertices and indices go into free ranges of the shared arrays (or at
    /// their end). Refused on a scene with clusters attached (a new mesh would have none).
    pub fn add_mesh(
        &mut self,
        vertices: &[Vertex],
        indices: &[u32],
        material: MaterialId,
    ) -> Result<MeshHandle, SceneError> {
        let slot = self
            .dynamic
            .free_meshes
            .last()
            .copied()
            .unwrap_or(self.meshes.len() as u32);
        let pointer = format!("/meshes/{slot}");
        if self.clusters.is_some() {
            return Err(SceneError::Invalid {
                file: self.name.clone(),
                pointer,
                reason: "clusters are attached: a mesh added now would have none (attach \
                         clusters after the geometry changes)"
                    .into(),
            });
        }
        check_mesh(
            &self.name,
            &pointer,
            vertices,
            indices,
            material,
            self.materials.len(),
        )?;
        let too_big = || SceneError::Invalid {
            file: self.name.clone(),
            pointer: pointer.clone(),
            reason: "shared buffers would exceed 32-bit offsets".into(),
        };
        let d = &mut self.dynamic;
        let vertex_start = d
            .vertex_pool
            .allocate(vertices.len() as u32)
            .filter(|&s| u64::from(s) + vertices.len() as u64 <= i32::MAX as u64)
            .ok_or_else(too_big)?;
        let Some(index_start) = d.index_pool.allocate(indices.len() as u32) else {
            d.vertex_pool.release(vertex_start, vertices.len() as u32);
            return Err(too_big());
        };
        write_range(&mut self.vertices, vertex_start, vertices);
        write_range(&mut self.indices, index_start, indices);
        let local_aabb = Aabb::from_points(
            indices
                .iter()
                .filter_map(|&i| vertices.get(i as usize))
                .map(|v| Vec3::from_array(v.position)),
        );
        let mesh = Mesh {
            first_index: index_start,
            index_count: indices.len() as u32,
            vertex_offset: vertex_start as i32,
            vertex_count: vertices.len() as u32,
            material,
            local_aabb,
        };
        self.dynamic.journal.push(Change::Vertices {
            start: vertex_start,
            len: vertices.len() as u32,
        });
        self.dynamic.journal.push(Change::Indices {
            start: index_start,
            len: indices.len() as u32,
        });
        let index = self.new_mesh(mesh);
        self.dynamic.mirrors.set(index, false);
        Ok(MeshHandle {
            index,
            generation: self.dynamic.mesh_generations[index as usize],
        })
    }

    /// Puts `mesh` (its vertices and indices written and in the journal) into a free mesh
    /// slot or a new one, and into the journal; returns its slot.
    pub(super) fn new_mesh(&mut self, mesh: Mesh) -> u32 {
        let d = &mut self.dynamic;
        let index = match d.free_meshes.pop() {
            Some(i) => {
                self.meshes[i as usize] = mesh;
                d.mesh_users[i as usize] = 0;
                i
            }
            None => {
                self.meshes.push(mesh);
                d.mesh_generations.push(0);
                d.mesh_users.push(0);
                self.meshes.len() as u32 - 1
            }
        };
        d.journal.push(Change::Mesh(index));
        d.structure += 1;
        index
    }

    /// Removes a mesh no instance draws any more, with its copy of reversed winding that
    /// mirroring instances draw; their geometry ranges are free for the next mesh (vertices
    /// stay taken while another mesh shares them).
    pub fn remove_mesh(&mut self, h: MeshHandle) -> Result<(), SceneError> {
        let i = self.live_mesh(h)?;
        if self.clusters.is_some() {
            return Err(SceneError::Invalid {
                file: self.name.clone(),
                pointer: format!("/meshes/{i}"),
                reason: "clusters are attached: the geometry cannot change under them".into(),
            });
        }
        let partner = self.dynamic.mirrors.partner(i as u32).map(|p| p as usize);
        let users = self.dynamic.mesh_users[i]
            + partner.map_or(0, |p| self.dynamic.mesh_users.get(p).copied().unwrap_or(0));
        if users > 0 {
            return Err(SceneError::MeshInUse {
                scene: self.name.clone(),
                mesh: h.index,
                instances: users,
            });
        }
        self.dynamic.mirrors.forget(i as u32);
        if let Some(p) = partner {
            self.free_mesh(p);
        }
        self.free_mesh(i);
        Ok(())
    }

    /// Frees mesh slot `i` and its ranges (its vertices only where no other mesh shares them).
    fn free_mesh(&mut self, i: usize) {
        let m = self.meshes[i];
        let shared = self
            .meshes
            .iter()
            .enumerate()
            .any(|(k, o)| k != i && o.index_count > 0 && o.vertex_offset == m.vertex_offset);
        let d = &mut self.dynamic;
        d.index_pool.release(m.first_index, m.index_count);
        if !shared {
            d.vertex_pool
                .release(m.vertex_offset as u32, m.vertex_count);
        }
        self.meshes[i] = Mesh {
            first_index: 0,
            index_count: 0,
            vertex_offset: 0,
            vertex_count: 0,
            material: m.material,
            local_aabb: Aabb::new(Vec3::ZERO, Vec3::ZERO),
        };
        d.mesh_generations[i] = d.mesh_generations[i].wrapping_add(1);
        d.free_meshes.push(i as u32);
        d.journal.push(Change::Mesh(i as u32));
        d.structure += 1;
    }

    /// World bounds of `transform` over the instance's local box (its mesh's, or the one the
    /// engine gave), or the error naming what is not finite.
    fn placed_bounds(
        &self,
        slot: u32,
        mesh: MeshId,
        transform: &Transform,
        what: Edit,
    ) -> Result<InstanceBounds, SceneError> {
        let non_finite = |part: &str| SceneError::NonFinite {
            file: self.name.clone(),
            pointer: format!("/instances/{slot}"),
            what: match what {
                Edit::New => format!("new instance: {part}"),
                Edit::Batch(k) => format!("set_transforms entry {k}: {part}"),
                Edit::LocalBounds => format!("local bounds: {part}"),
            },
        };
        if !transform.is_finite() {
            return Err(non_finite("transform"));
        }
        let local = match self.dynamic.local_bounds.get(&slot) {
            Some(b) => *b,
            None => self
                .meshes
                .get(mesh.index())
                .map_or(Aabb::new(Vec3::ZERO, Vec3::ZERO), |m| m.local_aabb),
        };
        let (center, half_extents, radius) =
            transformed_bounds(transform.linear, transform.translation, &local);
        if !(center.is_finite() && half_extents.is_finite() && radius.is_finite()) {
            return Err(non_finite("world bounds overflow"));
        }
        Ok(InstanceBounds {
            center,
            half_extents,
            radius,
        })
    }

    /// Adds an instance of mesh `mesh`. Under a mirroring transform (negative determinant) it
    /// draws the mesh's copy with the winding reversed, made on first use (`mirror.rs`).
    pub fn add_instance(
        &mut self,
        mesh: MeshHandle,
        transform: Transform,
        flags: InstanceFlags,
    ) -> Result<InstanceHandle, SceneError> {
        let m = self.live_mesh(mesh)?;
        let flags = flags.public();
        let slot = self
            .dynamic
            .free_instances
            .last()
            .copied()
            .unwrap_or(self.instances.len() as u32);
        self.dynamic.local_bounds.remove(&slot);
        let bounds = self.placed_bounds(slot, MeshId(m as u32), &transform, Edit::New)?;
        let m = self.drawn_mesh(m as u32, &transform.linear)? as usize;
        let instance = Instance {
            transform,
            mesh: MeshId(m as u32),
            bounds,
            flags,
        };
        let d = &mut self.dynamic;
        if d.free_instances.pop().is_some() {
            self.instances[slot as usize] = instance;
        } else {
            self.instances.push(instance);
            d.generations.push(0);
            d.journal.keep_at_least(self.instances.len());
        }
        d.mesh_users[m] += 1;
        d.structure += 1;
        d.journal.push(Change::Instance(slot));
        self.bounds = self.bounds.union(bounds.aabb());
        self.place(slot);
        Ok(InstanceHandle {
            slot,
            generation: self.dynamic.generations[slot as usize],
        })
    }

    /// Removes an instance; its handle (and every copy of it) is stale from now on.
    pub fn remove_instance(&mut self, h: InstanceHandle) -> Result<(), SceneError> {
        let slot = self.live_slot(h)?;
        self.unplace(slot as u32);
        let inst = &mut self.instances[slot];
        inst.flags = InstanceFlags::FREE;
        let mesh = inst.mesh.index();
        let d = &mut self.dynamic;
        if let Some(u) = d.mesh_users.get_mut(mesh) {
            *u = u.saturating_sub(1);
        }
        d.generations[slot] = d.generations[slot].wrapping_add(1);
        d.free_instances.push(slot as u32);
        d.local_bounds.remove(&(slot as u32));
        d.structure += 1;
        d.journal.push(Change::Instance(slot as u32));
        Ok(())
    }

    /// Moves instances, in one batch: every handle is checked and every transform must be
    /// finite before any moves (an error names the first bad entry and changes nothing). An
    /// instance whose transform turns mirroring, or back, draws its mesh's copy of the other
    /// winding from then on (`mirror.rs`; a copy made here stays made if the batch fails).
    pub fn set_transforms(
        &mut self,
        moves: &[(InstanceHandle, Transform)],
    ) -> Result<(), SceneError> {
        let mut placed = std::mem::take(&mut self.dynamic.scratch);
        placed.clear();
        let mut flips = 0usize;
        let mut checked = moves.iter().enumerate().try_for_each(|(k, (h, t))| {
            let slot = self.live_slot(*h)?;
            let mesh = self.instances[slot].mesh;
            placed.push(self.placed_bounds(slot as u32, mesh, t, Edit::Batch(k))?);
            flips += usize::from(self.dynamic.mirrors.needs_partner(mesh.0, &t.linear));
            Ok(())
        });
        if checked.is_ok() && flips > 0 {
            checked = moves.iter().try_for_each(|(h, t)| {
                let mesh = self.instances[h.slot as usize].mesh.0;
                self.drawn_mesh(mesh, &t.linear).map(|_| ())
            });
        }
        if checked.is_ok() {
            for ((h, t), bounds) in moves.iter().zip(&placed) {
                let slot = h.slot as usize;
                let mesh = self.instances[slot].mesh.0;
                match self.dynamic.mirrors.partner(mesh) {
                    Some(p) if self.dynamic.mirrors.needs_partner(mesh, &t.linear) => {
                        self.remesh(slot as u32, MeshId(p), *t, *bounds)
                    }
                    _ => self.move_to(slot, *t, *bounds),
                }
            }
        }
        self.dynamic.scratch = placed;
        checked
    }

    pub(super) fn move_to(&mut self, slot: usize, transform: Transform, bounds: InstanceBounds) {
        let inst = &mut self.instances[slot];
        inst.transform = transform;
        inst.bounds = bounds;
        let d = &mut self.dynamic;
        // A blended instance is in the grid, an opaque or alpha-tested one in a bucket; each
        // call does nothing for an instance not there.
        let s = slot as u32;
        d.blended_grid.update(s, &bounds);
        d.buckets.moved(s, bounds.aabb());
        d.journal.push(Change::Moved(s));
        self.bounds = self.bounds.union(bounds.aabb());
    }

    /// Sets an instance's flags ([`InstanceFlags::HIDDEN`]: kept, not drawn).
    pub fn set_flags(&mut self, h: InstanceHandle, flags: InstanceFlags) -> Result<(), SceneError> {
        let slot = self.live_slot(h)?;
        self.unplace(slot as u32);
        self.instances[slot].flags = flags.public();
        self.place(slot as u32);
        self.dynamic.journal.push(Change::Instance(slot as u32));
        Ok(())
    }

    /// Gives an instance its own local box (an engine's animated, skinned mesh: the box of every
    /// pose it can take), or back its mesh's with `None`. Culling tests the world box of it.
    pub fn set_local_bounds(
        &mut self,
        h: InstanceHandle,
        local: Option<Aabb>,
    ) -> Result<(), SceneError> {
        let slot = self.live_slot(h)?;
        if let Some(b) = local {
            if !(b.min.is_finite() && b.max.is_finite()) || b.min.cmpgt(b.max).any() {
                return Err(SceneError::NonFinite {
                    file: self.name.clone(),
                    pointer: format!("/instances/{slot}"),
                    what: format!("local bounds {:?}..{:?}", b.min, b.max),
                });
            }
        }
        let previous = match local {
            Some(b) => self.dynamic.local_bounds.insert(slot as u32, b),
            None => self.dynamic.local_bounds.remove(&(slot as u32)),
        };
        let inst = self.instances[slot];
        match self.placed_bounds(slot as u32, inst.mesh, &inst.transform, Edit::LocalBounds) {
            Ok(bounds) => {
                self.move_to(slot, inst.transform, bounds);
                Ok(())
            }
            Err(e) => {
                match previous {
                    Some(p) => self.dynamic.local_bounds.insert(slot as u32, p),
                    None => self.dynamic.local_bounds.remove(&(slot as u32)),
                };
                Err(e)
            }
        }
    }

    /// Puts a drawn instance into its bucket or the blended set, and its grid.
    pub(super) fn place(&mut self, slot: u32) {
        let inst = self.instances[slot as usize];
        if !inst.flags.is_drawn() {
            return;
        }
        let material = material_of(&self.meshes, &self.materials, inst.mesh);
        let d = &mut self.dynamic;
        if let Some(m) = material {
            d.drawn.add(m.class);
        }
        match placement(material, inst.mesh) {
            Placement::List(list, mesh) => {
                let instances = &self.instances;
                let boxes = |i: u32| {
                    instances
                        .get(i as usize)
                        .map_or(crate::bounds::DAabb::EMPTY, |x| x.bounds.aabb())
                };
                d.buckets.insert(
                    slot,
                    (list, mesh, inst.bounds.aabb()),
                    &boxes,
                    &mut d.journal,
                );
            }
            Placement::Blended => d.blended_grid.insert(slot, inst.mesh.0, &inst.bounds),
        }
    }

    /// Takes an instance out of its bucket and grid (before it is removed, hidden, or given
    /// another mesh).
    pub(super) fn unplace(&mut self, slot: u32) {
        let inst = self.instances[slot as usize];
        if !inst.flags.is_drawn() {
            return;
        }
        let material = material_of(&self.meshes, &self.materials, inst.mesh);
        let d = &mut self.dynamic;
        if let Some(m) = material {
            d.drawn.remove(m.class);
        }
        d.buckets.remove(slot, &mut d.journal);
        d.blended_grid.remove(slot);
    }
}
