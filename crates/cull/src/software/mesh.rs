//! An occluder's triangles as the rasterizer needs them: vertices welded by exact position (a
//! glTF mesh splits vertices by normal and UV, so a box's faces share no index), and for each
//! triangle edge the triangle on its other side where the edge is manifold (exactly one
//! triangle each way along it). Across such an edge two front-facing triangles cover every
//! pixel centre between them, which is what lets a tile be full where two faces meet.

use std::collections::HashMap;

use glam::Vec3;

use crate::CullError;

/// No neighbour across an edge.
pub(crate) const NONE: u32 = u32::MAX;

/// A mesh prepared for software occlusion. Build once per mesh; instances share it.
#[derive(Clone, Debug, Default)]
pub struct OccluderMesh {
    pub(crate) positions: Vec<Vec3>,
    /// Welded vertex ids, in the mesh's winding.
    pub(crate) triangles: Vec<[u32; 3]>,
    /// Per triangle and edge `i` (from vertex `i` to `i + 1`): the triangle across it, or [`NONE`].
    pub(crate) neighbours: Vec<[u32; 3]>,
    pub(crate) double_sided: bool,
}

impl OccluderMesh {
    /// Welds `positions` (object space) and finds the manifold edges of the triangle list
    /// `indices`. `double_sided`: the material draws back faces too. Errors on an index out of
    /// range, a non-finite position or a list whose length is not a multiple of 3.
    pub fn new(positions: &[Vec3], indices: &[u32], double_sided: bool) -> Result<Self, CullError> {
        if !indices.len().is_multiple_of(3) {
            return Err(CullError::InvalidOccluder {
                reason: format!(
                    "{} indices is not a whole number of triangles",
                    indices.len()
                ),
            });
        }
        if let Some((i, p)) = positions.iter().enumerate().find(|(_, p)| !p.is_finite()) {
            return Err(CullError::InvalidOccluder {
                reason: format!("vertex {i} is not finite: {p:?}"),
            });
        }
        let mut weld: HashMap<[u32; 3], u32> = HashMap::new();
        let mut welded = Vec::new();
        let mut remap = Vec::with_capacity(positions.len());
        for p in positions {
            // -0.0 and 0.0 are one position.
            let key = (*p + Vec3::ZERO).to_array().map(f32::to_bits);
            let id = *weld.entry(key).or_insert_with(|| {
                welded.push(*p);
                (welded.len() - 1) as u32
            });
            remap.push(id);
        }
        let mut triangles = Vec::with_capacity(indices.len() / 3);
        for (t, tri) in indices.chunks_exact(3).enumerate() {
            let mut ids = [0u32; 3];
            for (k, &i) in tri.iter().enumerate() {
                ids[k] = *remap
                    .get(i as usize)
                    .ok_or_else(|| CullError::InvalidOccluder {
                        reason: format!("triangle {t} refers to vertex {i} of {}", positions.len()),
                    })?;
            }
            triangles.push(ids);
        }
        let neighbours = manifold_neighbours(&triangles);
        Ok(OccluderMesh {
            positions: welded,
            triangles,
            neighbours,
            double_sided,
        })
    }

    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// Edges with a triangle across them (each counted once per side).
    pub fn manifold_edges(&self) -> usize {
        self.neighbours
            .iter()
            .flatten()
            .filter(|&&n| n != NONE)
            .count()
    }
}

/// For each directed edge (a, b) of a triangle: the triangle holding (b, a), when (a, b) and
/// (b, a) each occur exactly once; otherwise [`NONE`]. Degenerate edges (a == b) have none.
fn manifold_neighbours(triangles: &[[u32; 3]]) -> Vec<[u32; 3]> {
    let mut directed: HashMap<(u32, u32), (u32, u32)> = HashMap::with_capacity(triangles.len() * 3);
    for (t, tri) in triangles.iter().enumerate() {
        for i in 0..3 {
            let e = (tri[i], tri[(i + 1) % 3]);
            let slot = directed.entry(e).or_insert((t as u32, 0));
            slot.1 += 1;
        }
    }
    triangles
        .iter()
        .map(|tri| {
            let mut n = [NONE; 3];
            for (i, slot) in n.iter_mut().enumerate() {
                let (a, b) = (tri[i], tri[(i + 1) % 3]);
                if a == b {
                    continue;
                }
                let once = |e| directed.get(&e).filter(|s| s.1 == 1).map(|s| s.0);
                if let (Some(_), Some(other)) = (once((a, b)), once((b, a))) {
                    *slot = other;
                }
            }
            n
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_split_vertex_cube_is_closed_after_welding() {
        // 24 vertices (4 per face, as glTF exports them), 12 triangles.
        let mut positions = Vec::new();
        let mut indices = Vec::new();
        let faces = [
            (Vec3::X, Vec3::Y, Vec3::Z),
            (-Vec3::X, Vec3::Z, Vec3::Y),
            (Vec3::Y, Vec3::Z, Vec3::X),
            (-Vec3::Y, Vec3::X, Vec3::Z),
            (Vec3::Z, Vec3::X, Vec3::Y),
            (-Vec3::Z, Vec3::Y, Vec3::X),
        ];
        for (n, u, v) in faces {
            let base = positions.len() as u32;
            for (su, sv) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                positions.push(n + u * su + v * sv);
            }
            indices.extend([base, base + 1, base + 2, base, base + 2, base + 3]);
        }
        let mesh = OccluderMesh::new(&positions, &indices, false).unwrap();
        assert_eq!(mesh.positions.len(), 8);
        assert_eq!(mesh.triangle_count(), 12);
        // Every face is wound counter-clockwise from outside (u x v = n): all 36 edge sides
        // have their neighbour.
        assert_eq!(mesh.manifold_edges(), 36);
    }

    #[test]
    fn a_fold_of_three_triangles_on_one_edge_is_not_manifold() {
        let positions = [Vec3::ZERO, Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z];
        let indices = [0, 1, 2, 1, 0, 3, 1, 0, 4];
        let mesh = OccluderMesh::new(&positions, &indices, false).unwrap();
        assert_eq!(mesh.neighbours[0][0], NONE);
        assert!(OccluderMesh::new(&positions, &[0, 1, 9], false).is_err());
        assert!(OccluderMesh::new(&positions, &[0, 1], false).is_err());
    }
}
