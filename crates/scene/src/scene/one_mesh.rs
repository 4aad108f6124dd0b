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

    /// Baked, every triangle still faces where its vertex normals point, mirroring instances
    /// included (they draw their mesh's turned copy: baked as drawn, not turned again).
    #[test]
    fn baked_triangles_face_their_normals_under_mirroring_transforms() {
        use crate::scene::{Material, SceneBuilder, Transform, Vertex};
        use glam::{DVec3, Mat3, Vec3};
        let mut b = SceneBuilder::new("mirrors");
        let material = b.add_material(Material::opaque([1.0; 4]));
        // A quad facing +y (counter-clockwise seen from above), normals +y.
        let v = |x: f32, z: f32| Vertex {
            position: [x, 0.0, z],
            normal: [0.0, 1.0, 0.0],
            uv: [x, z],
        };
        let quad = [v(0.0, 0.0), v(0.0, 1.0), v(1.0, 1.0), v(1.0, 0.0)];
        let mesh = b.add_mesh(&quad, &[0, 1, 2, 0, 2, 3], material).unwrap();
        for (k, scale) in [
            Vec3::ONE,
            Vec3::new(-1.0, 1.0, 1.0),
            Vec3::new(2.0, 1.0, -3.0),
        ]
        .into_iter()
        .enumerate()
        {
            let linear = Mat3::from_rotation_y(0.3 * k as f32) * Mat3::from_diagonal(scale);
            let at = DVec3::new(3.0 * k as f64, 0.0, 0.0);
            b.add_instance(Transform::new(linear, at), mesh).unwrap();
        }
        let one = b.build(None).unwrap().one_mesh_per_material().unwrap();
        let m = one.meshes()[0];
        let vertices = &one.vertices()[m.vertex_offset as usize..];
        let range = m.first_index as usize..(m.first_index + m.index_count) as usize;
        let triangles = one.indices()[range].chunks_exact(3);
        assert_eq!(triangles.len(), 6);
        for t in triangles {
            let [a, b, c] = [t[0], t[1], t[2]].map(|i| vertices[i as usize]);
            let p = |v: Vertex| Vec3::from(v.position);
            let facing = (p(b) - p(a)).cross(p(c) - p(a));
            let normal = Vec3::from(a.normal) + Vec3::from(b.normal) + Vec3::from(c.normal);
            assert!(
                facing.dot(normal) > 0.0,
                "{t:?}: faces {facing}, normals {normal}"
            );
        }
    }
}
