//! Flattening the node hierarchy into instances: each node's world transform, its mesh's
//! primitives converted to tilegraph meshes on first use (shared vertices where primitives share
//! accessors, a mirrored copy where a node's transform flips winding), and the limits checked
//! as data is read.

use std::collections::HashMap;

use glam::{DAffine3, Vec3};
use gltf::json::mesh::Mode;

use super::data::Reader;
use super::doc::Doc;
use super::nodes::local_transform;
use super::{Ctx, Limits, Prim};
use crate::error::SceneError;
use crate::scene::{Material, MaterialId, MeshId, SceneBuilder, Transform, Vertex};

/// Flattening state: the builder, and glTF meshes converted on first use.
pub(super) struct Flatten<'x, 'd, 'a> {
    pub(super) doc: &'x Doc,
    pub(super) reader: &'x Reader<'d, 'a>,
    pub(super) prims: &'x [Vec<Prim>],
    pub(super) limits: &'x Limits,
    pub(super) ctx: &'x Ctx,
    pub(super) builder: SceneBuilder,
    pub(super) mesh_cache: Vec<Option<Vec<MeshId>>>,
    /// (POSITION, NORMAL, TEXCOORD_n) accessors -> (vertex offset, count): primitives that share
    /// vertex accessors share vertices.
    pub(super) vertex_cache: HashMap<(usize, usize, Option<usize>), (u32, u32)>,
    /// (POSITION, TEXCOORD_n) accessors -> their vertices, for primitives without normals (each
    /// is de-indexed into flat-shaded corners; the source is read once however many share it).
    pub(super) flat_source_cache: HashMap<(usize, Option<usize>), std::rc::Rc<Vec<Vertex>>>,
    /// Vertices read from accessors so far: bounded like the vertices kept, so a small file
    /// cannot make the loader read (or zero-fill) far more than it keeps.
    pub(super) vertices_read: usize,
    pub(super) default_material: Option<MaterialId>,
    pub(super) material_count: usize,
}

impl Flatten<'_, '_, '_> {
    pub(super) fn flatten(&mut self, roots: &[usize]) -> Result<usize, SceneError> {
        let mut stack: Vec<(usize, DAffine3)> = roots
            .iter()
            .rev()
            .map(|&r| (r, DAffine3::IDENTITY))
            .collect();
        let mut visited = 0usize;
        while let Some((i, parent_world)) = stack.pop() {
            visited += 1;
            let Some(node) = self.doc.nodes.get(i) else {
                return Err(self.ctx.unresolved(
                    format!("/nodes/{i}"),
                    "/nodes",
                    i,
                    self.doc.nodes.len(),
                ));
            };
            let world = parent_world * local_transform(node, i, self.ctx)?;
            if !(world.matrix3.is_finite() && world.translation.is_finite()) {
                return Err(self
                    .ctx
                    .non_finite(format!("/nodes/{i}"), "world transform overflows".into()));
            }
            if let Some(m) = node.mesh {
                let ids = self.mesh(m.value())?;
                // glTF: a mirroring transform (negative determinant) makes front faces
                // clockwise; its instances draw a copy with the winding reversed, which the
                // builder makes on first use (its indices count against the limit).
                let transform = Transform::from_daffine(&world);
                for id in ids {
                    let copy = self.builder.indices_added(id, &transform.linear);
                    if copy > 0 {
                        self.check_limit(
                            &format!("/nodes/{i}"),
                            "indices",
                            self.builder.index_count(),
                            copy,
                            self.index_limit(),
                        )?;
                    }
                    if self.builder.instance_count() >= self.limits.max_instances {
                        return Err(self.ctx.limit(
                            format!("/nodes/{i}"),
                            "instances",
                            self.builder.instance_count() + 1,
                            self.limits.max_instances,
                        ));
                    }
                    self.builder
                        .add_instance(transform, id)
                        .map_err(|e| match e {
                            SceneError::NonFinite { what, .. } => self.ctx.non_finite(
                                format!("/nodes/{i}"),
                                format!("instance of mesh {}: {what}", m.value()),
                            ),
                            other => other,
                        })?;
                }
            }
            if node.skin.is_some() {
                log::debug!(
                    "{}: /nodes/{i}: skin ignored (bind pose drawn)",
                    self.ctx.file
                );
            }
            for c in node.children.iter().flatten().rev() {
                stack.push((c.value(), world));
            }
        }
        Ok(visited)
    }

    /// The tilegraph meshes of glTF mesh `m`, converting it on first use.
    fn mesh(&mut self, m: usize) -> Result<Vec<MeshId>, SceneError> {
        if let Some(Some(ids)) = self.mesh_cache.get(m) {
            return Ok(ids.clone());
        }
        let prims = self.prims.get(m).cloned().unwrap_or_default();
        let mut ids = Vec::with_capacity(prims.len());
        for (pi, prim) in prims.iter().enumerate() {
            if let Some(id) = self.primitive(m, pi, prim)? {
                ids.push(id);
            }
        }
        if let Some(slot) = self.mesh_cache.get_mut(m) {
            *slot = Some(ids.clone());
        }
        Ok(ids)
    }

    fn material(&mut self, index: Option<usize>) -> MaterialId {
        match index {
            Some(i) if i < self.material_count => MaterialId(i as u32),
            _ => *self.default_material.get_or_insert_with(|| {
                // glTF's default material: white, opaque, single-sided.
                self.builder.add_material(Material::opaque([1.0; 4]))
            }),
        }
    }

    fn check_finite(
        &self,
        values: &[f32],
        comps: usize,
        accessor: usize,
        what: &str,
        pp: &str,
    ) -> Result<(), SceneError> {
        match values.iter().position(|v| !v.is_finite()) {
            None => Ok(()),
            Some(k) => Err(self.ctx.non_finite(
                format!("/accessors/{accessor}"),
                format!(
                    "{what} element {} (used by {pp}) is {}",
                    k / comps,
                    values[k]
                ),
            )),
        }
    }

    fn primitive(
        &mut self,
        m: usize,
        pi: usize,
        prim: &Prim,
    ) -> Result<Option<MeshId>, SceneError> {
        let pp = format!("/meshes/{m}/primitives/{pi}");
        if matches!(
            prim.mode,
            Mode::Points | Mode::Lines | Mode::LineLoop | Mode::LineStrip
        ) {
            log::warn!(
                "{}: {pp}: mode {:?} is not triangles; skipped",
                self.ctx.file,
                prim.mode
            );
            return Ok(None);
        }
        let Some(pos) = prim.position else {
            log::warn!("{}: {pp}: no POSITION; skipped", self.ctx.file);
            return Ok(None);
        };
        let n = self.reader.accessor(pos).map_or(0, |a| a.count);
        let raw = match prim.indices {
            Some(ii) => {
                let count = self.reader.accessor(ii).map_or(0, |a| a.count);
                // Strips and fans triple their indices: the limit applies to what they expand
                // to, checked before anything is read.
                self.check_limit(
                    &pp,
                    "indices",
                    self.builder.index_count(),
                    count.max(triangle_index_count(count, prim.mode)),
                    self.index_limit(),
                )?;
                let raw = self.reader.read_indices(ii)?;
                if let Some((position, &index)) =
                    raw.iter().enumerate().find(|(_, &i)| i as usize >= n)
                {
                    return Err(SceneError::IndexOutOfRange {
                        file: self.ctx.file.clone(),
                        pointer: format!("{pp}/indices"),
                        index: u64::from(index),
                        position,
                        vertex_count: n,
                    });
                }
                raw
            }
            None => {
                self.check_limit(
                    &pp,
                    "indices",
                    self.builder.index_count(),
                    n.max(triangle_index_count(n, prim.mode)),
                    self.index_limit(),
                )?;
                (0..n as u32).collect()
            }
        };
        let tris = triangles(&raw, prim.mode);
        if raw.len() > tris.len() && prim.mode == Mode::Triangles {
            log::warn!(
                "{}: {pp}: {} trailing indices do not form a triangle; dropped",
                self.ctx.file,
                raw.len() - tris.len()
            );
        }
        if tris.is_empty() {
            log::warn!("{}: {pp}: no triangle; skipped", self.ctx.file);
            return Ok(None);
        }
        let material = self.material(prim.material);

        match prim.normal {
            Some(normal) => {
                let key = (pos, normal, prim.uv);
                let (offset, count) = match self.vertex_cache.get(&key) {
                    Some(&range) => range,
                    None => {
                        let vertices = self.read_vertices(pos, Some(normal), prim.uv, &pp)?;
                        let range = self.push_vertices(&vertices, &pp)?;
                        self.vertex_cache.insert(key, range);
                        range
                    }
                };
                Ok(Some(
                    self.builder.push_mesh_range(offset, count, &tris, material),
                ))
            }
            None => {
                // glTF: without normals, flat normals. Flat shading needs a vertex per corner:
                // check that many against the vertex limit before building them.
                let limit = self.limits.max_vertices.min(i32::MAX as usize);
                self.check_limit(
                    &pp,
                    "vertices",
                    self.builder.vertex_count(),
                    tris.len(),
                    limit,
                )?;
                let shared = match self.flat_source_cache.get(&(pos, prim.uv)) {
                    Some(v) => v.clone(),
                    None => {
                        let v = std::rc::Rc::new(self.read_vertices(pos, None, prim.uv, &pp)?);
                        self.flat_source_cache.insert((pos, prim.uv), v.clone());
                        v
                    }
                };
                let mut vertices = Vec::with_capacity(tris.len());
                for t in tris.chunks_exact(3) {
                    let p = |k: usize| Vec3::from_array(shared[t[k] as usize].position);
                    let normal = (p(1) - p(0))
                        .cross(p(2) - p(0))
                        .normalize_or(Vec3::Y)
                        .to_array();
                    for &k in t {
                        vertices.push(Vertex {
                            normal,
                            ..shared[k as usize]
                        });
                    }
                }
                let (offset, count) = self.push_vertices(&vertices, &pp)?;
                let seq: Vec<u32> = (0..count).collect();
                Ok(Some(
                    self.builder.push_mesh_range(offset, count, &seq, material),
                ))
            }
        }
    }

    fn check_limit(
        &self,
        pp: &str,
        what: &'static str,
        have: usize,
        add: usize,
        limit: usize,
    ) -> Result<(), SceneError> {
        let total = have.saturating_add(add);
        if total > limit {
            return Err(self.ctx.limit(pp.to_string(), what, total, limit));
        }
        Ok(())
    }

    /// Mesh ranges are u32 (`first_index`, `index_count`), whatever the caller's limit.
    fn index_limit(&self) -> usize {
        self.limits.max_indices.min(u32::MAX as usize)
    }

    fn push_vertices(&mut self, vertices: &[Vertex], pp: &str) -> Result<(u32, u32), SceneError> {
        // Mesh offsets are i32 (VkDrawIndexedIndirectCommand::vertexOffset).
        let limit = self.limits.max_vertices.min(i32::MAX as usize);
        self.check_limit(
            pp,
            "vertices",
            self.builder.vertex_count(),
            vertices.len(),
            limit,
        )?;
        Ok((self.builder.push_vertices(vertices), vertices.len() as u32))
    }

    fn read_vertices(
        &mut self,
        pos: usize,
        normal: Option<usize>,
        uv: Option<usize>,
        pp: &str,
    ) -> Result<Vec<Vertex>, SceneError> {
        let n = self.reader.accessor(pos).map_or(0, |a| a.count);
        let limit = self.limits.max_vertices.min(i32::MAX as usize);
        self.check_limit(pp, "vertices", self.builder.vertex_count(), n, limit)?;
        self.check_limit(pp, "vertices read", self.vertices_read, n, limit)?;
        self.vertices_read += n;
        let positions = self.reader.read_f32(pos, 3)?;
        self.check_finite(&positions, 3, pos, "POSITION", pp)?;
        let normals = match normal {
            Some(a) => {
                let v = self.reader.read_f32(a, 3)?;
                self.check_finite(&v, 3, a, "NORMAL", pp)?;
                Some(v)
            }
            None => None,
        };
        let uvs = match uv {
            Some(a) => {
                let v = self.reader.read_f32(a, 2)?;
                self.check_finite(&v, 2, a, "TEXCOORD", pp)?;
                Some(v)
            }
            None => None,
        };
        Ok((0..n)
            .map(|i| Vertex {
                position: [positions[3 * i], positions[3 * i + 1], positions[3 * i + 2]],
                normal: normals
                    .as_ref()
                    .map_or([0.0; 3], |v| [v[3 * i], v[3 * i + 1], v[3 * i + 2]]),
                uv: uvs.as_ref().map_or([0.0; 2], |v| [v[2 * i], v[2 * i + 1]]),
            })
            .collect())
    }
}

/// Triangle list from indices in `mode` (triangles, strip or fan). Caller skips other modes.
/// How many indices [`triangles`] makes of `len` indices.
fn triangle_index_count(len: usize, mode: Mode) -> usize {
    match mode {
        Mode::TriangleStrip | Mode::TriangleFan => len.saturating_sub(2).saturating_mul(3),
        _ => len / 3 * 3,
    }
}

fn triangles(raw: &[u32], mode: Mode) -> Vec<u32> {
    match mode {
        Mode::TriangleStrip => {
            let mut out = Vec::with_capacity(raw.len().saturating_sub(2) * 3);
            for i in 0..raw.len().saturating_sub(2) {
                // glTF: triangle i is (v[i], v[i + 1 + i % 2], v[i + 2 - i % 2]), which keeps
                // every triangle's winding the same as the first's.
                if i % 2 == 0 {
                    out.extend_from_slice(&[raw[i], raw[i + 1], raw[i + 2]]);
                } else {
                    out.extend_from_slice(&[raw[i], raw[i + 2], raw[i + 1]]);
                }
            }
            out
        }
        Mode::TriangleFan => {
            let mut out = Vec::with_capacity(raw.len().saturating_sub(2) * 3);
            for i in 1..raw.len().saturating_sub(1) {
                out.extend_from_slice(&[raw[i], raw[i + 1], raw[0]]);
            }
            out
        }
        _ => raw[..raw.len() / 3 * 3].to_vec(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn strips_and_fans_become_lists_with_the_spec_winding() {
        assert_eq!(
            triangles(&[0, 1, 2, 3], Mode::TriangleStrip),
            vec![0, 1, 2, 1, 3, 2]
        );
        assert_eq!(
            triangles(&[0, 1, 2, 3], Mode::TriangleFan),
            vec![1, 2, 0, 2, 3, 0]
        );
        assert_eq!(triangles(&[0, 1, 2, 3], Mode::Triangles), vec![0, 1, 2]);
        assert!(triangles(&[0, 1], Mode::TriangleStrip).is_empty());
        assert!(triangles(&[0], Mode::TriangleFan).is_empty());
    }
}
