//! A scene as many levels are exported: every drawn instance's triangles baked into one mesh per
//! material. The shape instance culling cannot help with (one instance covers the level) and
//! cluster culling exists for: its clusters lie far from their mesh's origin, thin pieces of
//! surface and distant ones share a mesh with everything else.

use glam::{DVec3, Mat3, Vec3};

use super::{MaterialId, Scene, SceneBuilder, Transform, Vertex};
use crate::error::SceneError;

impl Scene {
    /// The scene with every drawn instance baked into one mesh per material (world positions
    /// relative to the scene's bounds centre, where each mesh's one instance stands; normals by
    /// the inverse transpose; each triangle's corners in the order its instance draws them).
    /// Same materials, same camera path, same image.
    pub fn one_mesh_per_material(&self) -> Result<Scene, SceneError> {
        let origin = if self.bounds.is_empty() {
            DVec3::ZERO
        } else {
            self.bounds.center()
        };
        let mut b = SceneBuilder::new(format!("{}@one-mesh", self.name));
        for m in &self.materials {
            b.add_material(*m);
        }
        let mut per_material: Vec<(Vec<Vertex>, Vec<u32>)> =
            vec![(Vec::new(), Vec::new()); self.materials.len()];
        for inst in self.instances.iter().filter(|i| i.flags.is_drawn()) {
            let Some(mesh) = self.meshes.get(inst.mesh.index()) else {
                continue;
            };
            let Some((vertices, indices)) = per_material.get_mut(mesh.material.0 as usize) else {
                continue;
            };
            let l = inst.transform.linear;
            let normal = normal_matrix(l);
            let offset = inst.transform.translation - origin;
            let base = vertices.len() as u32;
            let first = mesh.vertex_offset.max(0) as usize;
            let Some(src) = self.vertices.get(first..first + mesh.vertex_count as usize) else {
                continue;
            };
            vertices.extend(src.iter().map(|v| {
                Vertex {
                    position: ((l * Vec3::from(v.position)).as_dvec3() + offset)
                        .as_vec3()
                        .to_array(),
                    normal: (normal * Vec3::from(v.normal))
                        .normalize_or_zero()
                        .to_array(),
                    uv: v.uv,
                }
            }));
            let range = mesh.first_index as usize..(mesh.first_index + mesh.index_count) as usize;
            let Some(tri) = self.indices.get(range) else {
                continue;
            };
            // As drawn: a mirroring instance's mesh already has the winding that keeps its
            // front faces front once transformed (`mirror.rs`), and baking keeps the order.
            indices.extend(tri.iter().map(|&i| base + i));
        }
        for (m, (vertices, indices)) in per_material.iter().enumerate() {
            if indices.is_empty() {
                continue;
            }
            let mesh = b.add_mesh(vertices, indices, MaterialId(m as u32))?;
            b.add_instance(Transform::new(Mat3::IDENTITY, origin), mesh)?;
        }
        b.build(Some(self.camera_path.clone()))
    }
}

/// The inverse transpose of `l` (normals of a sheared or non-uniformly scaled instance), scaled
/// freely: normals are normalized after.
fn normal_matrix(l: Mat3) -> Mat3 {
    let det = l.determinant();
    if det == 0.0 || !det.is_finite() {
        return l;
    }
    l.inverse().transpose()
}

#[cfg(test)]
mod tests {
    use crate::{generate, ProceduralKind, ProceduralParams};

    #[test]
    fn one_mesh_per_material_keeps_every_triangle_and_the_bounds() {
        let scene = generate(
            ProceduralKind::Interior,
            ProceduralParams { size: 300, seed: 5 },
        )
        .unwrap();
        let one = scene.one_mesh_per_material().unwrap();
        assert!(one.instances().len() <= scene.materials().len());
        assert_eq!(one.triangles_drawn(), scene.triangles_drawn());
        let (a, b) = (scene.bounds(), one.bounds());
        // Tighter or equal: each instance's box bounds its transformed mesh box, the baked
        // mesh's box its vertices.
        let slack = 1e-4 * (a.max - a.min).length();
        assert!(a.contains_box(&b, slack), "{a:?} {b:?}");
        assert!((b.max - b.min).length() > 0.5 * (a.max - a.min).length());
        assert_eq!(one.camera_path(), scene.camera_path());
    }
}
