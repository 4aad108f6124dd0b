//! The scene as flat, GPU-ready arrays: one vertex buffer, one index buffer, a mesh table, a
//! material table and instances with world bounds.

use std::sync::Arc;

use glam::{DVec3, Vec3};
use serde::Serialize;

use crate::bounds::{transformed_bounds, Aabb, DAabb};
use crate::camera::CameraPath;
use crate::error::SceneError;
use crate::texture::{Texture, TextureId};

mod buckets;
mod clusters;
mod edit;
mod elements;
mod gpu;
mod grid;
mod info;
mod journal;
mod mirror;
mod one_mesh;
mod placement;
mod pool;
mod variants;

pub use buckets::{DrawBuckets, DrawGroup, DRAW_LISTS};
pub use clusters::{
    ClusterData, Clusters, GpuCluster, GpuLod, MAX_LODS, MAX_TRIANGLES, MAX_VERTICES,
};
pub use elements::{
    Instance, InstanceBounds, InstanceFlags, InstanceHandle, InstanceId, Material, MaterialClass,
    MaterialId, Mesh, MeshHandle, MeshId, Transform, Vertex,
};
pub use gpu::{GpuInstance, GpuMaterial, GpuMesh, RelativeInstance, SplitPoint};
pub use grid::{CellRun, GridMember, LooseGrid, Overlap};
pub use info::{BoundsInfo, ClassCounts, Degenerate, SceneInfo};
pub use journal::{Change, SceneCursor};

/// Where a scene came from.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum SceneSource {
    Gltf {
        path: String,
    },
    Procedural {
        name: String,
        size: usize,
        seed: u64,
    },
    Built,
}

/// glTF document-level counts, kept next to the tilegraph-level ones.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct GltfCounts {
    /// Nodes in the document.
    pub nodes: usize,
    /// Meshes in the document.
    pub meshes: usize,
    /// Primitives over all meshes of the document.
    pub primitives: usize,
    /// Nodes reached from the loaded scene's roots.
    pub nodes_in_scene: usize,
}

/// A loaded or generated scene: arrays a renderer uploads, changed by handle
/// ([`Scene::add_instance`], [`Scene::set_transforms`], [`Scene::add_mesh`], ... in `edit.rs`),
/// each change written to a journal a renderer follows ([`Scene::changes_since`]).
///
/// [`Scene::instances`] holds every instance slot, free ones too (flags
/// [`InstanceFlags::is_drawn`] false): an instance's slot is its index on the GPU.
#[derive(Clone, Debug)]
pub struct Scene {
    name: String,
    source: SceneSource,
    vertices: Vec<Vertex>,
    indices: Vec<u32>,
    meshes: Vec<Mesh>,
    materials: Vec<Material>,
    /// Shared between clones: a scene's textures are large and never change after build.
    textures: Arc<[Texture]>,
    instances: Vec<Instance>,
    bounds: DAabb,
    gltf_counts: Option<GltfCounts>,
    camera_path: CameraPath,
    /// Attached clusters (the index buffer is then in cluster order).
    clusters: Option<Clusters>,
    /// Handles, free slots and ranges, buckets, grids, the journal.
    dynamic: edit::Dynamic,
}

impl Scene {
    pub fn name(&self) -> &str {
        &self.name
    }
    pub fn source(&self) -> &SceneSource {
        &self.source
    }
    /// The shared vertex buffer.
    pub fn vertices(&self) -> &[Vertex] {
        &self.vertices
    }
    /// The shared index buffer; each mesh's indices are relative to its `vertex_offset`.
    pub fn indices(&self) -> &[u32] {
        &self.indices
    }
    pub fn meshes(&self) -> &[Mesh] {
        &self.meshes
    }
    pub fn materials(&self) -> &[Material] {
        &self.materials
    }
    pub fn instances(&self) -> &[Instance] {
        &self.instances
    }
    /// The textures materials sample ([`Material::base_color_texture`]).
    pub fn textures(&self) -> &[Texture] {
        &self.textures
    }
    /// Bytes of every texture's mip chain: what the GPU copies hold.
    pub fn texture_bytes(&self) -> u64 {
        self.textures.iter().map(|t| t.byte_size() as u64).sum()
    }
    pub fn mesh(&self, id: MeshId) -> Option<&Mesh> {
        self.meshes.get(id.index())
    }
    pub fn material(&self, id: MaterialId) -> Option<&Material> {
        self.materials.get(id.index())
    }
    /// The material of an instance (through its mesh).
    pub fn instance_material(&self, instance: &Instance) -> Option<&Material> {
        self.mesh(instance.mesh)
            .and_then(|m| self.material(m.material))
    }
    /// World bounds of all instances (f64).
    pub fn bounds(&self) -> DAabb {
        self.bounds
    }
    pub fn gltf_counts(&self) -> Option<&GltfCounts> {
        self.gltf_counts.as_ref()
    }
    /// The scene's default test camera path (procedural: designed per kind; glTF: an orbit).
    pub fn camera_path(&self) -> &CameraPath {
        &self.camera_path
    }
    pub fn set_camera_path(&mut self, path: CameraPath) {
        self.camera_path = path;
    }

    /// A hash of what clusters are built from: positions, indices and the mesh table.
    pub fn geometry_fingerprint(&self) -> u64 {
        let mut h = clusters::FNV_OFFSET;
        for v in self.vertices() {
            h = clusters::fnv1a(h, bytemuck::cast_slice(&v.position));
        }
        h = clusters::fnv1a(h, bytemuck::cast_slice(self.indices()));
        for m in self.meshes() {
            for w in [
                m.first_index,
                m.index_count,
                m.vertex_offset as u32,
                m.vertex_count,
            ] {
                h = clusters::fnv1a(h, &w.to_le_bytes());
            }
        }
        h
    }

    /// The clusters, once attached ([`Scene::attach_clusters`]).
    pub fn clusters(&self) -> Option<&Clusters> {
        self.clusters.as_ref()
    }

    /// Attaches clusters built from this scene's geometry: checks them (same geometry
    /// fingerprint, each mesh's index range tiled in order), then takes their index buffer,
    /// which holds the same triangles in cluster order.
    pub fn attach_clusters(&mut self, data: ClusterData) -> Result<(), SceneError> {
        if data.fingerprint != self.geometry_fingerprint() {
            return Err(SceneError::Clusters {
                what: self.name.clone(),
                reason: "built from other geometry (fingerprint differs)".into(),
            });
        }
        clusters::validate(self, &data)?;
        self.indices = data.indices;
        // Levels of detail follow the scene's indices: a mesh copy made later goes after them.
        (self.dynamic.index_pool).extend_to(self.indices.len() as u32);
        self.dynamic.journal.push(Change::Everything);
        self.clusters = Some(Clusters {
            clusters: data.clusters,
            mesh_clusters: data.mesh_clusters,
            lods: data.lods,
        });
        Ok(())
    }

    /// Triangles drawn when every instance is drawn once.
    pub fn triangles_drawn(&self) -> u64 {
        self.instances
            .iter()
            .filter(|i| i.flags.is_drawn())
            .map(|i| {
                self.mesh(i.mesh)
                    .map_or(0, |m| u64::from(m.triangle_count()))
            })
            .sum()
    }

    /// Every instance slot's record as [`Instance::gpu_record`] makes it.
    pub fn gpu_records(&self) -> Vec<GpuInstance> {
        self.instances.iter().map(Instance::gpu_record).collect()
    }

    /// Every instance slot seen from `eye`, as the shaders see it ([`GpuInstance::relative`]):
    /// what CPU references test.
    pub fn gpu_instances(&self, eye: DVec3) -> Vec<RelativeInstance> {
        let eye = SplitPoint::new(eye);
        self.instances
            .iter()
            .map(|i| i.gpu_record().relative(&eye))
            .collect()
    }

    pub fn gpu_meshes(&self) -> Vec<GpuMesh> {
        self.meshes.iter().map(Mesh::gpu).collect()
    }

    pub fn gpu_materials(&self) -> Vec<GpuMaterial> {
        self.materials.iter().map(Material::gpu).collect()
    }

    /// Triangles of the largest mesh.
    pub fn max_mesh_triangles(&self) -> u32 {
        self.meshes
            .iter()
            .map(Mesh::triangle_count)
            .max()
            .unwrap_or(0)
    }

    /// Moves the whole world (instances, bounds, camera path) by `offset`, in f64.
    ///
    /// Used to test and benchmark far-from-origin worlds: the same scene at 10^6 units.
    pub fn translate(&mut self, offset: DVec3) {
        for inst in &mut self.instances {
            inst.transform.translation += offset;
            inst.bounds.center += offset;
        }
        if !self.bounds.is_empty() {
            self.bounds = DAabb::new(self.bounds.min + offset, self.bounds.max + offset);
        }
        self.camera_path = self.camera_path.translated(offset);
        self.dynamic
            .index_all(&self.instances, &self.meshes, &self.materials, self.bounds);
        self.dynamic.journal.push(Change::Everything);
    }
}

/// Checks a mesh's data: the material exists, indices are a positive multiple of 3 and inside
/// the vertices, every vertex is finite.
fn check_mesh(
    name: &str,
    pointer: &str,
    vertices: &[Vertex],
    indices: &[u32],
    material: MaterialId,
    materials: usize,
) -> Result<(), SceneError> {
    check_indices(name, pointer, indices, vertices.len(), material, materials)?;
    check_vertices(name, pointer, vertices)
}

/// A mesh's indices (whole triangles, each below `vertex_count`) and its material.
fn check_indices(
    name: &str,
    pointer: &str,
    indices: &[u32],
    vertex_count: usize,
    material: MaterialId,
    materials: usize,
) -> Result<(), SceneError> {
    let invalid = |reason: String| SceneError::Invalid {
        file: name.to_string(),
        pointer: pointer.to_string(),
        reason,
    };
    if material.index() >= materials {
        return Err(invalid(format!("material {} does not exist", material.0)));
    }
    if !indices.len().is_multiple_of(3) || indices.is_empty() {
        return Err(invalid(format!(
            "{} indices is not a positive multiple of 3",
            indices.len()
        )));
    }
    if let Some((position, &index)) = indices
        .iter()
        .enumerate()
        .find(|(_, &i)| i as usize >= vertex_count)
    {
        return Err(SceneError::IndexOutOfRange {
            file: name.to_string(),
            pointer: pointer.to_string(),
            index: u64::from(index),
            position,
            vertex_count,
        });
    }
    Ok(())
}

/// Every vertex value finite.
fn check_vertices(name: &str, pointer: &str, vertices: &[Vertex]) -> Result<(), SceneError> {
    if let Some(i) = vertices
        .iter()
        .position(|v| !(v.position.iter().chain(&v.normal).chain(&v.uv)).all(|x| x.is_finite()))
    {
        return Err(SceneError::NonFinite {
            file: name.to_string(),
            pointer: pointer.to_string(),
            what: format!("vertex {i}"),
        });
    }
    Ok(())
}

/// Builds a [`Scene`] from meshes, materials and instances; checks what it is given.
///
/// The glTF loader and the procedural generators use it; tests in other crates can too.
#[derive(Debug)]
pub struct SceneBuilder {
    name: String,
    source: SceneSource,
    vertices: Vec<Vertex>,
    indices: Vec<u32>,
    meshes: Vec<Mesh>,
    materials: Vec<Material>,
    textures: Vec<Texture>,
    instances: Vec<Instance>,
    gltf_counts: Option<GltfCounts>,
    /// Each mesh's winding and its copy with the other ([`mirror`]).
    mirrors: mirror::Mirrors,
}

impl SceneBuilder {
    pub fn new(name: impl Into<String>) -> Self {
        SceneBuilder {
            name: name.into(),
            source: SceneSource::Built,
            vertices: Vec::new(),
            indices: Vec::new(),
            meshes: Vec::new(),
            materials: Vec::new(),
            textures: Vec::new(),
            instances: Vec::new(),
            gltf_counts: None,
            mirrors: mirror::Mirrors::default(),
        }
    }

    pub(crate) fn set_source(&mut self, source: SceneSource) {
        self.source = source;
    }

    pub(crate) fn set_gltf_counts(&mut self, counts: GltfCounts) {
        self.gltf_counts = Some(counts);
    }

    pub(crate) fn reserve_instances(&mut self, n: usize) {
        self.instances.reserve(n);
    }

    pub fn add_material(&mut self, material: Material) -> MaterialId {
        self.materials.push(material);
        MaterialId((self.materials.len() - 1) as u32)
    }

    pub fn add_texture(&mut self, texture: Texture) -> TextureId {
        self.textures.push(texture);
        TextureId((self.textures.len() - 1) as u32)
    }

    fn error(&self, pointer: String, reason: String) -> SceneError {
        SceneError::Invalid {
            file: self.name.clone(),
            pointer,
            reason,
        }
    }

    /// Adds a mesh with its own vertices. Checks indices, finiteness and the material id.
    pub fn add_mesh(
        &mut self,
        vertices: &[Vertex],
        indices: &[u32],
        material: MaterialId,
    ) -> Result<MeshId, SceneError> {
        let pointer = format!("/meshes/{}", self.meshes.len());
        check_mesh(
            &self.name,
            &pointer,
            vertices,
            indices,
            material,
            self.materials.len(),
        )?;
        if self.vertices.len() + vertices.len() > i32::MAX as usize
            || self.indices.len() + indices.len() > u32::MAX as usize
        {
            return Err(self.error(pointer, "shared buffers would exceed 32-bit offsets".into()));
        }
        let offset = self.push_vertices(vertices);
        Ok(self.push_mesh_range(offset, vertices.len() as u32, indices, material))
    }

    /// Adds a mesh over the vertices of mesh `of`, added before: engines whose meshes index
    /// one vertex buffer share its vertices once instead of a copy per mesh. Checks the
    /// indices against `of`'s vertices and the material id.
    pub fn add_mesh_sharing(
        &mut self,
        of: MeshId,
        indices: &[u32],
        material: MaterialId,
    ) -> Result<MeshId, SceneError> {
        let pointer = format!("/meshes/{}", self.meshes.len());
        let Some((offset, count)) = self.mesh_vertex_range(of) else {
            return Err(self.error(pointer, format!("mesh {} does not exist", of.0)));
        };
        check_indices(
            &self.name,
            &pointer,
            indices,
            count as usize,
            material,
            self.materials.len(),
        )?;
        if self.indices.len() + indices.len() > u32::MAX as usize {
            return Err(self.error(pointer, "shared buffers would exceed 32-bit offsets".into()));
        }
        Ok(self.push_mesh_range(offset, count, indices, material))
    }

    /// Appends vertices to the shared buffer; returns their offset. Callers check sizes.
    pub(crate) fn push_vertices(&mut self, vertices: &[Vertex]) -> u32 {
        let offset = self.vertices.len() as u32;
        self.vertices.extend_from_slice(vertices);
        offset
    }

    /// The vertex range (offset, count) of an existing mesh.
    pub(crate) fn mesh_vertex_range(&self, mesh: MeshId) -> Option<(u32, u32)> {
        self.meshes
            .get(mesh.index())
            .map(|m| (m.vertex_offset as u32, m.vertex_count))
    }

    pub(crate) fn vertex_count(&self) -> usize {
        self.vertices.len()
    }

    pub(crate) fn index_count(&self) -> usize {
        self.indices.len()
    }

    /// Adds a mesh over an already pushed vertex range. Callers guarantee every index is below
    /// `vertex_count` and the material exists; the local AABB is taken over the vertices the
    /// indices reach (a range may be shared by several primitives).
    pub(crate) fn push_mesh_range(
        &mut self,
        vertex_offset: u32,
        vertex_count: u32,
        indices: &[u32],
        material: MaterialId,
    ) -> MeshId {
        let first_index = self.indices.len() as u32;
        self.indices.extend_from_slice(indices);
        let base = vertex_offset as usize;
        let verts = &self.vertices[base..base + vertex_count as usize];
        let local_aabb = Aabb::from_points(
            indices
                .iter()
                .filter_map(|&i| verts.get(i as usize))
                .map(|v| Vec3::from_array(v.position)),
        );
        self.meshes.push(Mesh {
            first_index,
            index_count: indices.len() as u32,
            vertex_offset: vertex_offset as i32,
            vertex_count,
            material,
            local_aabb,
        });
        let id = (self.meshes.len() - 1) as u32;
        self.mirrors.set(id, false);
        MeshId(id)
    }

    /// The indices an instance of `mesh` under `linear` adds: a mirroring instance's first
    /// draws a copy of the mesh with the winding reversed ([`mirror`]).
    pub(crate) fn indices_added(&self, mesh: MeshId, linear: &glam::Mat3) -> usize {
        let copy =
            self.mirrors.needs_partner(mesh.0, linear) && self.mirrors.partner(mesh.0).is_none();
        match self.meshes.get(mesh.index()) {
            Some(m) if copy => m.index_count as usize,
            _ => 0,
        }
    }

    /// The mesh an instance of `mesh` under `linear` draws: `mesh`, or for a transform of the
    /// other sign its copy with the winding reversed (same vertices, material and bounds),
    /// made on first use. `None` for an unknown mesh.
    fn drawn_mesh(&mut self, mesh: MeshId, linear: &glam::Mat3) -> Option<MeshId> {
        let m = *self.meshes.get(mesh.index())?;
        if !self.mirrors.needs_partner(mesh.0, linear) {
            return Some(mesh);
        }
        if let Some(p) = self.mirrors.partner(mesh.0) {
            return Some(MeshId(p));
        }
        let first = m.first_index as usize;
        let range = self.indices.get(first..first + m.index_count as usize)?;
        let flipped: Vec<u32> = mirror::reversed_winding(range).collect();
        let first_index = self.indices.len() as u32;
        self.indices.extend_from_slice(&flipped);
        self.meshes.push(Mesh {
            first_index,
            index_count: flipped.len() as u32,
            ..m
        });
        let copy = (self.meshes.len() - 1) as u32;
        self.mirrors.link(mesh.0, copy);
        Some(MeshId(copy))
    }

    /// Adds an instance; checks the mesh id and that the transform and bounds are finite. A
    /// mirroring transform (negative determinant) draws the mesh's copy with the winding
    /// reversed, made on first use, so that its front faces stay front ([`mirror`]).
    pub fn add_instance(
        &mut self,
        transform: Transform,
        mesh: MeshId,
    ) -> Result<InstanceId, SceneError> {
        let pointer = format!("/instances/{}", self.instances.len());
        let Some(m) = self.meshes.get(mesh.index()) else {
            return Err(self.error(pointer, format!("mesh {} does not exist", mesh.0)));
        };
        if !transform.is_finite() {
            return Err(SceneError::NonFinite {
                file: self.name.clone(),
                pointer,
                what: "transform".into(),
            });
        }
        let local = m.local_aabb;
        let (center, half_extents, radius) =
            transformed_bounds(transform.linear, transform.translation, &local);
        if !(center.is_finite() && half_extents.is_finite() && radius.is_finite()) {
            return Err(SceneError::NonFinite {
                file: self.name.clone(),
                pointer,
                what: "world bounds overflow".into(),
            });
        }
        let Some(mesh) = self.drawn_mesh(mesh, &transform.linear) else {
            return Err(self.error(pointer, format!("mesh {} does not exist", mesh.0)));
        };
        self.instances.push(Instance {
            transform,
            mesh,
            bounds: InstanceBounds {
                center,
                half_extents,
                radius,
            },
            flags: InstanceFlags::default(),
        });
        Ok(InstanceId((self.instances.len() - 1) as u32))
    }

    /// Adds an instance whose mesh id the caller knows to be valid and whose transform is finite
    /// by construction (procedural generators, copies of a scene): the mesh is drawn as given,
    /// so under a mirroring transform it must be one whose winding is already reversed. Skips the checks of [`Self::add_instance`] that
    /// would otherwise cost a measurable share of generating a million instances.
    #[inline]
    pub(crate) fn push_instance_trusted(&mut self, transform: Transform, mesh: MeshId) {
        let local = self
            .meshes
            .get(mesh.index())
            .map_or(Aabb::new(Vec3::ZERO, Vec3::ZERO), |m| m.local_aabb);
        let (center, half_extents, radius) =
            transformed_bounds(transform.linear, transform.translation, &local);
        self.instances.push(Instance {
            transform,
            mesh,
            bounds: InstanceBounds {
                center,
                half_extents,
                radius,
            },
            flags: InstanceFlags::default(),
        });
    }

    pub fn instance_count(&self) -> usize {
        self.instances.len()
    }

    /// Finishes the scene. A scene that draws no triangle is an error ([`SceneError::EmptyScene`]).
    pub fn build(self, camera_path: Option<CameraPath>) -> Result<Scene, SceneError> {
        if self.instances.is_empty() {
            return Err(SceneError::EmptyScene {
                file: self.name,
                reason: "no instance".into(),
            });
        }
        let bounds = self
            .instances
            .iter()
            .fold(DAabb::EMPTY, |b, i| b.union(i.bounds.aabb()));
        if !(bounds.min.is_finite() && bounds.max.is_finite()) {
            return Err(SceneError::NonFinite {
                file: self.name,
                pointer: String::new(),
                what: "scene bounds".into(),
            });
        }
        for (i, m) in self.materials.iter().enumerate() {
            if let Some(t) = m
                .base_color_texture
                .filter(|t| t.index() >= self.textures.len())
            {
                return Err(self.error(
                    format!("/materials/{i}/baseColorTexture"),
                    format!("texture {} of {}", t.0, self.textures.len()),
                ));
            }
        }
        let camera_path = match camera_path {
            Some(p) => p,
            None => CameraPath::orbit_bounds(&bounds),
        };
        let dynamic = edit::Dynamic::build(
            &self.instances,
            &self.meshes,
            &self.materials,
            self.vertices.len(),
            self.indices.len(),
            bounds,
            self.mirrors,
        );
        Ok(Scene {
            name: self.name,
            source: self.source,
            vertices: self.vertices,
            indices: self.indices,
            meshes: self.meshes,
            materials: self.materials,
            textures: self.textures.into(),
            instances: self.instances,
            bounds,
            gltf_counts: self.gltf_counts,
            camera_path,
            clusters: None,
            dynamic,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Mat3;
    use std::mem::{align_of, offset_of, size_of};

    /// A mesh whose coordinates sit 10^4 m from its origin, placed at the origin and 10^6 m
    /// out, seen from 5 cm and from far: the camera-relative box the shaders compute encloses
    /// every vertex where the GPU puts it (f32 transform of f32 inputs), and the
    /// camera-relative translation made from the split record is within a few f32 ulps of the
    /// exact f64 difference.
    #[test]
    fn gpu_records_enclose_far_off_origin_vertices() {
        let local = Aabb::new(
            Vec3::new(10_000.0, 0.0, 0.0),
            Vec3::new(10_000.251, 0.1, 0.1),
        );
        for translation in [DVec3::ZERO, DVec3::new(1e6 + 0.3, -2.0, 1e6)] {
            let (center, half_extents, radius) =
                transformed_bounds(Mat3::IDENTITY, translation, &local);
            let instance = Instance {
                transform: Transform::from_translation(translation),
                mesh: MeshId(0),
                bounds: InstanceBounds {
                    center,
                    half_extents,
                    radius,
                },
                flags: InstanceFlags::default(),
            };
            let record = instance.gpu_record();
            for eye_x in [10_000.3, 10_000.0, 9_999.9, 0.0, -5e5] {
                let eye = translation + DVec3::new(eye_x, 0.05, 0.05);
                let r = record.relative(&SplitPoint::new(eye));
                let t = Vec3::new(r.model_rows[0][3], r.model_rows[1][3], r.model_rows[2][3]);
                let exact = translation - eye;
                let err = (t.as_dvec3() - exact).abs().max_element();
                assert!(
                    err <= 4.0 * f64::from(f32::EPSILON) * exact.abs().max_element() + 1e-6,
                    "eye x {eye_x}: translation {t:?}, exact {exact:?}"
                );
                let (c, h) = (Vec3::from_array(r.center), Vec3::from_array(r.half_extents));
                for p in [local.min, local.max] {
                    let on_gpu = p + t;
                    assert!(
                        (on_gpu - c).abs().cmple(h).all(),
                        "eye x {eye_x}: vertex at {on_gpu:?} outside {c:?} +- {h:?}"
                    );
                }
            }
        }
    }

    #[test]
    fn gpu_layouts_match_their_glsl_declarations() {
        assert_eq!(size_of::<Vertex>(), 32);
        assert_eq!(offset_of!(Vertex, normal), 12);
        assert_eq!(offset_of!(Vertex, uv), 24);
        assert_eq!(size_of::<GpuInstance>(), 96);
        assert_eq!(offset_of!(GpuInstance, translation_low), 48);
        assert_eq!(offset_of!(GpuInstance, mesh), 60);
        assert_eq!(offset_of!(GpuInstance, center_offset), 64);
        assert_eq!(offset_of!(GpuInstance, radius), 76);
        assert_eq!(offset_of!(GpuInstance, half_extents), 80);
        assert_eq!(offset_of!(GpuInstance, flags), 92);
        assert_eq!(size_of::<GpuMesh>(), 48);
        assert_eq!(offset_of!(GpuMesh, aabb_min), 16);
        assert_eq!(offset_of!(GpuMesh, aabb_max), 32);
        assert_eq!(size_of::<GpuMaterial>(), 32);
        assert_eq!(offset_of!(GpuMaterial, class), 16);
        // std430 arrays of these structs need a 16-byte multiple stride.
        for s in [
            size_of::<GpuInstance>(),
            size_of::<GpuMesh>(),
            size_of::<GpuMaterial>(),
        ] {
            assert_eq!(s % 16, 0);
        }
        assert_eq!(align_of::<Vertex>(), 4);
    }

    fn tri() -> [Vertex; 3] {
        let v = |x: f32, z: f32| Vertex {
            position: [x, 0.0, z],
            normal: [0.0, 1.0, 0.0],
            uv: [0.0; 2],
        };
        [v(0.0, 0.0), v(1.0, 0.0), v(0.0, 1.0)]
    }

    #[test]
    fn builder_rejects_bad_meshes_and_instances() {
        let mut b = SceneBuilder::new("t");
        let mat = b.add_material(Material::opaque([1.0; 4]));
        assert!(matches!(
            b.add_mesh(&tri(), &[0, 1, 3], mat),
            Err(SceneError::IndexOutOfRange { index: 3, .. })
        ));
        assert!(b.add_mesh(&tri(), &[0, 1], mat).is_err());
        assert!(b.add_mesh(&tri(), &[0, 1, 2], MaterialId(9)).is_err());
        let mut bad = tri();
        bad[1].position[0] = f32::NAN;
        assert!(matches!(
            b.add_mesh(&bad, &[0, 1, 2], mat),
            Err(SceneError::NonFinite { .. })
        ));
        let mesh = b.add_mesh(&tri(), &[0, 1, 2], mat).unwrap();
        assert!(b
            .add_instance(
                Transform::from_translation(DVec3::new(f64::NAN, 0.0, 0.0)),
                mesh
            )
            .is_err());
        assert!(b.add_instance(Transform::IDENTITY, MeshId(7)).is_err());
        b.add_instance(Transform::IDENTITY, mesh).unwrap();
        let scene = b.build(None).unwrap();
        assert_eq!(scene.triangles_drawn(), 1);
        assert!(SceneBuilder::new("e").build(None).is_err());
    }

    #[test]
    fn gpu_record_is_camera_relative() {
        let mut b = SceneBuilder::new("t");
        let mat = b.add_material(Material::opaque([1.0; 4]));
        let mesh = b.add_mesh(&tri(), &[0, 1, 2], mat).unwrap();
        let far = DVec3::new(1e6 + 0.25, 2.0, -1e6);
        b.add_instance(Transform::from_translation(far), mesh)
            .unwrap();
        let scene = b.build(None).unwrap();
        let rec = scene.gpu_instances(far - DVec3::new(0.25, 0.0, 0.0));
        let m = rec[0].model_matrix();
        assert_eq!(m.w_axis.truncate(), Vec3::new(0.25, 0.0, 0.0));
        assert_eq!(rec[0].mesh, 0);
    }
}
