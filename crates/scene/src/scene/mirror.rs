//! Instances whose transform mirrors (a negative determinant) turn their triangles' winding
//! on screen: drawn as given, their front faces would be culled and their inside drawn. As
//! glTF asks of a mirroring node — and as engines flip the cull mode of such a draw — a
//! mirroring instance draws a copy of its mesh with every triangle's winding reversed (same
//! vertices, material and bounds; only the indices are copied). Every way an instance gets its
//! mesh and transform (the builder, the glTF loader, [`super::Scene::add_instance`],
//! [`super::Scene::set_transforms`]) picks the copy that fits the transform's sign, so the
//! pipelines keep one front face and a draw group keeps drawing many instances at once.

use glam::Mat3;

use super::journal::Change;
use super::pool::write_range;
use super::{InstanceBounds, MeshHandle, MeshId, Scene, Transform};
use crate::error::SceneError;

/// Whether a linear part mirrors: the winding it turns on screen is reversed.
#[inline]
pub(crate) fn mirroring(linear: &Mat3) -> bool {
    linear.determinant() < 0.0
}

const NONE: u32 = u32::MAX;

/// Per mesh: whether its winding is the reversed one (drawn by mirroring instances), and the
/// mesh with the other winding over the same vertices, once made.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub(crate) struct Mirrors {
    reversed: Vec<bool>,
    partner: Vec<u32>,
}

impl Mirrors {
    /// Whether mesh `m` has the reversed winding.
    #[inline]
    pub(crate) fn reversed(&self, m: u32) -> bool {
        self.reversed.get(m as usize).copied().unwrap_or(false)
    }

    /// The mesh with `m`'s other winding, when made.
    #[inline]
    pub(crate) fn partner(&self, m: u32) -> Option<u32> {
        self.partner.get(m as usize).copied().filter(|&p| p != NONE)
    }

    /// Whether an instance of `m` under `linear` draws another mesh than `m`: its partner.
    #[inline]
    pub(crate) fn needs_partner(&self, m: u32, linear: &Mat3) -> bool {
        mirroring(linear) != self.reversed(m)
    }

    /// Mesh slot `m` holds a new mesh of the given winding, without a partner (made or reused).
    pub(crate) fn set(&mut self, m: u32, reversed: bool) {
        let i = m as usize;
        if self.reversed.len() <= i {
            self.reversed.resize(i + 1, false);
            self.partner.resize(i + 1, NONE);
        }
        self.reversed[i] = reversed;
        self.partner[i] = NONE;
    }

    /// `copy` (made now) has `original`'s other winding.
    pub(crate) fn link(&mut self, original: u32, copy: u32) {
        let reversed = !self.reversed(original);
        self.set(copy, reversed);
        self.partner[copy as usize] = original;
        if let Some(p) = self.partner.get_mut(original as usize) {
            *p = copy;
        }
    }

    /// Covers `meshes` meshes; a mesh without a partner that an instance draws under a
    /// mirroring transform is a reversed one (an instance added as drawn, `SceneBuilder::
    /// push_instance_trusted`, says so by its transform).
    pub(crate) fn infer(&mut self, meshes: usize, drawn: impl Iterator<Item = (u32, bool)>) {
        if self.reversed.len() < meshes {
            self.reversed.resize(meshes, false);
            self.partner.resize(meshes, NONE);
        }
        for (m, mirroring) in drawn {
            if mirroring && self.partner(m).is_none() {
                if let Some(r) = self.reversed.get_mut(m as usize) {
                    *r = true;
                }
            }
        }
    }

    /// Mesh `m` is gone: its partner (if any) has none any more.
    pub(crate) fn forget(&mut self, m: u32) {
        if let Some(p) = self.partner(m) {
            if let Some(q) = self.partner.get_mut(p as usize) {
                *q = NONE;
            }
        }
        if let Some(q) = self.partner.get_mut(m as usize) {
            *q = NONE;
        }
    }
}

impl Scene {
    /// Makes the copy of mesh `mesh` with the winding reversed that its mirroring instances
    /// draw, if it is not made yet (the first mirroring instance makes it otherwise). A
    /// renderer takes a new mesh in at its next frame; with clusters attached that means new
    /// cluster buffers, a stall at a frame the engine did not choose: call this at load time
    /// for the meshes it will mirror.
    pub fn prepare_mirroring(&mut self, mesh: MeshHandle) -> Result<(), SceneError> {
        let m = self.live_mesh(mesh)? as u32;
        let other = Mat3::from_diagonal(if self.dynamic.mirrors.reversed(m) {
            glam::Vec3::ONE
        } else {
            glam::Vec3::new(-1.0, 1.0, 1.0)
        });
        self.drawn_mesh(m, &other).map(|_| ())
    }

    /// The mesh an instance of live mesh `m` under `linear` draws: `m`, or its copy of the
    /// other winding, made now if need be (refused when the shared index array is full). With
    /// clusters attached the copy gets the mesh's clusters (same triangles and order, each
    /// cone made again for the turned triangles) and levels of detail, turned likewise.
    pub(super) fn drawn_mesh(&mut self, m: u32, linear: &Mat3) -> Result<u32, SceneError> {
        let mirrors = &self.dynamic.mirrors;
        if !mirrors.needs_partner(m, linear) {
            return Ok(m);
        }
        if let Some(p) = mirrors.partner(m) {
            return Ok(p);
        }
        let Some(&mesh) = self.meshes.get(m as usize) else {
            return Err(self.mirror_refused(m, format!("mesh {m} of {}", self.meshes.len())));
        };
        let start = self.turned_copy(m, mesh.first_index, mesh.index_count)?;
        let levels: Vec<super::GpuLod> = match &self.clusters {
            Some(c) => c.lods_of(m).to_vec(),
            None => Vec::new(),
        };
        let mut turned_levels = Vec::with_capacity(levels.len());
        for l in levels {
            let first_index = self.turned_copy(m, l.first_index, l.index_count)?;
            turned_levels.push(super::GpuLod { first_index, ..l });
        }
        let copy = self.new_mesh(super::Mesh {
            first_index: start,
            ..mesh
        });
        self.dynamic.mirrors.link(m, copy);
        if self.clusters.is_some() {
            self.turn_clusters(m, copy, &turned_levels);
        }
        Ok(copy)
    }

    /// Writes indices `first..first + count` with every triangle turned to a free range of the
    /// index array (in the journal); returns where.
    fn turned_copy(&mut self, m: u32, first: u32, count: u32) -> Result<u32, SceneError> {
        let range = first as usize..(first + count) as usize;
        let turned: Vec<u32> = (self.indices.get(range))
            .map(|r| reversed_winding(r).collect())
            .unwrap_or_default();
        let Some(start) = self.dynamic.index_pool.allocate(turned.len() as u32) else {
            return Err(self.mirror_refused(
                m,
                "its copy of reversed winding would exceed the index array's 32-bit offsets".into(),
            ));
        };
        write_range(&mut self.indices, start, &turned);
        self.dynamic.journal.push(Change::Indices {
            start,
            len: turned.len() as u32,
        });
        Ok(start)
    }

    /// Gives mesh `copy` (mesh `m` turned) `m`'s clusters over its own indices, each cone made
    /// again (a turned triangle faces the other way), and `levels` as its levels of detail.
    fn turn_clusters(&mut self, m: u32, copy: u32, levels: &[super::GpuLod]) {
        let (Some(clusters), Some(from), Some(to)) = (
            self.clusters.as_mut(),
            self.meshes.get(m as usize),
            self.meshes.get(copy as usize),
        ) else {
            return;
        };
        let base = from.vertex_offset.max(0) as usize;
        let own: Vec<_> = clusters.of_mesh(m).to_vec();
        let first = clusters.clusters.len() as u32;
        for c in own {
            let first_index = c.first_index - from.first_index + to.first_index;
            let range = first_index as usize..(first_index + c.index_count) as usize;
            // Each turned triangle's corners; a cluster whose corners cannot all be read
            // (checked when the clusters were attached: not expected) gets no cone.
            let corner = |i: &u32| self.vertices.get(base + *i as usize).map(|v| v.position);
            let corners: Option<Vec<[[f32; 3]; 3]>> = (self.indices.get(range))
                .unwrap_or(&[])
                .chunks_exact(3)
                .map(|t| Some([corner(&t[0])?, corner(&t[1])?, corner(&t[2])?]))
                .collect();
            let cone = corners.map_or(crate::cone::Cone::NONE, |c| {
                crate::cone::Cone::of_triangles(&c)
            });
            clusters.clusters.push(super::GpuCluster {
                first_index,
                cone_apex: cone.apex,
                cone_cutoff: cone.cutoff,
                cone_axis: cone.axis,
                cone_reach: cone.reach,
                cone_thinness: cone.thinness,
                ..c
            });
        }
        let count = clusters.clusters.len() as u32 - first;
        let k = copy as usize;
        if clusters.mesh_clusters.len() <= k {
            clusters.mesh_clusters.resize(k + 1, [0, 0]);
        }
        clusters.mesh_clusters[k] = [first, count];
        if !clusters.lods.is_empty() {
            let at = k * super::MAX_LODS;
            if clusters.lods.len() < at + super::MAX_LODS {
                clusters
                    .lods
                    .resize(at + super::MAX_LODS, super::GpuLod::default());
            }
            for (i, l) in clusters.lods[at..at + super::MAX_LODS]
                .iter_mut()
                .enumerate()
            {
                *l = levels.get(i).copied().unwrap_or_default();
            }
        }
    }

    fn mirror_refused(&self, m: u32, reason: String) -> SceneError {
        SceneError::Invalid {
            file: self.name.clone(),
            pointer: format!("/meshes/{m}"),
            reason,
        }
    }

    /// Moves instance `slot` to `transform` drawing mesh `mesh` (its mesh's copy of the other
    /// winding): out of its draw bucket and into the other's, a change of its record.
    pub(super) fn remesh(
        &mut self,
        slot: u32,
        mesh: MeshId,
        transform: Transform,
        bounds: InstanceBounds,
    ) {
        self.unplace(slot);
        let inst = &mut self.instances[slot as usize];
        let old = std::mem::replace(&mut inst.mesh, mesh);
        inst.transform = transform;
        inst.bounds = bounds;
        let d = &mut self.dynamic;
        if let Some(u) = d.mesh_users.get_mut(old.index()) {
            *u = u.saturating_sub(1);
        }
        if let Some(u) = d.mesh_users.get_mut(mesh.index()) {
            *u += 1;
        }
        d.structure += 1;
        d.journal.push(Change::Instance(slot));
        self.bounds = self.bounds.union(bounds.aabb());
        self.place(slot);
    }
}

/// `indices` with every triangle's winding reversed (`[a, b, c]` -> `[a, c, b]`).
pub(crate) fn reversed_winding(indices: &[u32]) -> impl Iterator<Item = u32> + '_ {
    indices.chunks_exact(3).flat_map(|t| [t[0], t[2], t[1]])
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn a_mirroring_transform_wants_the_reversed_mesh_and_back() {
        let mut m = Mirrors::default();
        // Mesh 1 is drawn under a mirroring transform only: built that way, it is reversed.
        m.infer(2, [(0, false), (1, true)].into_iter());
        assert!(!m.reversed(0) && m.reversed(1));
        let flip = Mat3::from_diagonal(Vec3::new(-1.0, 1.0, 1.0));
        assert!(mirroring(&flip) && !mirroring(&Mat3::IDENTITY));
        // Two flips keep the winding: a rotation by 180 degrees about z.
        assert!(!mirroring(&Mat3::from_diagonal(Vec3::new(-1.0, -1.0, 1.0))));
        assert!(m.needs_partner(0, &flip) && !m.needs_partner(0, &Mat3::IDENTITY));
        m.link(0, 2);
        assert!(m.reversed(2) && !m.reversed(0));
        assert_eq!((m.partner(0), m.partner(2)), (Some(2), Some(0)));
        assert!(!m.needs_partner(2, &flip) && m.needs_partner(2, &Mat3::IDENTITY));
        m.forget(2);
        assert_eq!((m.partner(0), m.partner(2)), (None, None));
        assert_eq!(m.partner(1), None);
        m.set(1, false);
        m.set(5, true);
        assert!(m.reversed(5) && !m.reversed(4) && !m.reversed(1) && m.partner(5).is_none());
        let r: Vec<u32> = reversed_winding(&[0, 1, 2, 3, 4, 5, 9]).collect();
        assert_eq!(r, [0, 2, 1, 3, 5, 4]);
    }
}
