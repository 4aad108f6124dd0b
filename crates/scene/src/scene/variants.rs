//! A scene's opaque geometry spread over many materials: what the visibility buffer's
//! per-material resolves and material classification are measured on (`--materials N`).

use super::{Material, MaterialClass, MeshId, Scene, SceneBuilder, SceneError, Vertex};

impl Scene {
    /// This scene with each opaque instance drawn in one of `n` new opaque materials (of `n`
    /// hues), picked by a hash of the instance's index so that neighbours on screen differ: the
    /// materials spread over the whole screen. Each opaque mesh gets a copy per material over
    /// the same vertices; other geometry, the textures and the camera path are kept. Double-sided
    /// opaque meshes get double-sided copies (so up to `2 n` new materials).
    pub fn with_spread_materials(&self, n: u32) -> Result<Scene, SceneError> {
        let n = n.max(1);
        let mut b = self.builder_like(format!("{}+materials:{n}", self.name), true);
        // Variant k of sidedness s: made when first used.
        let mut variants = vec![[None; 2]; n as usize];
        let mut copies: Vec<Vec<MeshId>> = Vec::with_capacity(self.meshes.len());
        for mesh in &self.meshes {
            let first = mesh.first_index as usize;
            let indices = &self.indices[first..first + mesh.index_count as usize];
            let (vertex_offset, vertex_count) = (mesh.vertex_offset as u32, mesh.vertex_count);
            let own = b.push_mesh_range(vertex_offset, vertex_count, indices, mesh.material);
            let original = self.material(mesh.material);
            let Some(m) = original.filter(|m| m.class == MaterialClass::Opaque) else {
                copies.push(vec![own]);
                continue;
            };
            let sided = usize::from(m.double_sided);
            let mut ids = Vec::with_capacity(n as usize);
            for (k, v) in variants.iter_mut().enumerate() {
                let material = *v[sided].get_or_insert_with(|| {
                    let mut variant = Material::opaque(hue(k as u32, n));
                    variant.double_sided = m.double_sided;
                    b.add_material(variant)
                });
                if b.index_count() + indices.len() > u32::MAX as usize {
                    return Err(SceneError::BadSpec {
                        spec: format!("{}@materials:{n}", self.name),
                        reason: "a copy per material would exceed 32-bit index offsets".into(),
                    });
                }
                ids.push(b.push_mesh_range(vertex_offset, vertex_count, indices, material));
            }
            copies.push(ids);
        }
        for (i, inst) in self.instances.iter().enumerate() {
            let choices = copies.get(inst.mesh.index()).map_or(&[][..], |c| &c[..]);
            let Some(&first) = choices.first() else {
                continue;
            };
            let pick = spread(i as u32) as usize % choices.len();
            b.push_instance_trusted(inst.transform, choices.get(pick).copied().unwrap_or(first));
            if let Some(last) = b.instances.last_mut() {
                last.flags = inst.flags;
            }
        }
        b.build(Some(self.camera_path.clone()))
    }
}

impl Scene {
    /// This scene with fewer triangles or fewer instances, for the bottleneck finder: each
    /// mesh drawn with its first `1 / triangles` of its triangles (at least one), and every
    /// `instances`-th instance kept (the first of each run). 1 keeps everything. Materials,
    /// textures, vertices and the camera path are kept.
    pub fn thinned(&self, triangles: u32, instances: u32) -> Result<Scene, SceneError> {
        let (triangles, instances) = (triangles.max(1), instances.max(1));
        let mut b = self.builder_like(
            format!("{}/thinned:{triangles}x{instances}", self.name),
            true,
        );
        let mut meshes = Vec::with_capacity(self.meshes.len());
        for mesh in &self.meshes {
            let first = mesh.first_index as usize;
            let all = mesh.index_count / 3;
            let keep = (all.div_ceil(triangles).max(1).min(all) * 3) as usize;
            let indices = self.indices.get(first..first + keep).unwrap_or_default();
            meshes.push(b.push_mesh_range(
                mesh.vertex_offset as u32,
                mesh.vertex_count,
                indices,
                mesh.material,
            ));
        }
        for inst in self.instances.iter().step_by(instances as usize) {
            let Some(&mesh) = meshes.get(inst.mesh.index()) else {
                continue;
            };
            b.push_instance_trusted(inst.transform, mesh);
            if let Some(last) = b.instances.last_mut() {
                last.flags = inst.flags;
            }
        }
        b.build(Some(self.camera_path.clone()))
    }
}

impl Scene {
    /// This scene with every triangle split into `4^level` (a barycentric grid of `2^level`
    /// segments a side, the corners' attributes interpolated): the same surfaces, dense meshes
    /// (a bottleneck finder's constructed case, `@dense:LEVEL`). `level` is at most 5.
    pub fn densified(&self, level: u32) -> Result<Scene, SceneError> {
        let n = 1u32 << level.min(5);
        let mut b = self.builder_like(format!("{}@dense:{level}", self.name), false);
        let mut meshes = Vec::with_capacity(self.meshes.len());
        for mesh in &self.meshes {
            let first = mesh.first_index as usize;
            let indices = self
                .indices
                .get(first..first + mesh.index_count as usize)
                .unwrap_or_default();
            let base = mesh.vertex_offset.max(0) as usize;
            let corner = |i: u32| self.vertices.get(base + i as usize).copied();
            let (mut verts, mut idx) = (Vec::new(), Vec::new());
            for t in indices.chunks_exact(3) {
                let (Some(a), Some(c1), Some(c2)) = (corner(t[0]), corner(t[1]), corner(t[2]))
                else {
                    continue;
                };
                let start = verts.len() as u32;
                // Vertex (i, j): i steps toward the second corner, j toward the third.
                for i in 0..=n {
                    for j in 0..=n - i {
                        let (u, v) = (i as f32 / n as f32, j as f32 / n as f32);
                        let w = 1.0 - u - v;
                        let mix = |x: &[f32], y: &[f32], z: &[f32], k: usize| {
                            w * x[k] + u * y[k] + v * z[k]
                        };
                        let normal = glam::Vec3::from_array(std::array::from_fn(|k| {
                            mix(&a.normal, &c1.normal, &c2.normal, k)
                        }))
                        .normalize_or_zero();
                        verts.push(Vertex {
                            position: std::array::from_fn(|k| {
                                mix(&a.position, &c1.position, &c2.position, k)
                            }),
                            normal: normal.to_array(),
                            uv: std::array::from_fn(|k| mix(&a.uv, &c1.uv, &c2.uv, k)),
                        });
                    }
                }
                // Row i holds n - i + 1 vertices.
                let at = |i: u32, j: u32| start + i * (n + 1) - i * i.saturating_sub(1) / 2 + j;
                for i in 0..n {
                    for j in 0..n - i {
                        idx.extend([at(i, j), at(i + 1, j), at(i, j + 1)]);
                        if j + 1 < n - i {
                            idx.extend([at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)]);
                        }
                    }
                }
            }
            if b.vertex_count() + verts.len() > i32::MAX as usize
                || b.index_count() + idx.len() > u32::MAX as usize
            {
                return Err(SceneError::BadSpec {
                    spec: format!("{}@dense:{level}", self.name),
                    reason: "the dense meshes would exceed 32-bit buffer offsets".into(),
                });
            }
            let offset = b.push_vertices(&verts);
            meshes.push(b.push_mesh_range(offset, verts.len() as u32, &idx, mesh.material));
        }
        self.rebuilt_with(b, |i| meshes.get(i).copied())
    }

    /// This scene with a mesh of its own for every instance (the same vertices, a copy of the
    /// indices): as many draws as instances, where instancing would draw each mesh once (a
    /// bottleneck finder's constructed case, `@draws`).
    pub fn mesh_per_instance(&self) -> Result<Scene, SceneError> {
        let mut b = self.builder_like(format!("{}@draws", self.name), true);
        for inst in &self.instances {
            let Some(mesh) = self.meshes.get(inst.mesh.index()) else {
                continue;
            };
            let first = mesh.first_index as usize;
            let indices = self
                .indices
                .get(first..first + mesh.index_count as usize)
                .unwrap_or_default();
            if b.index_count() + indices.len() > u32::MAX as usize {
                return Err(SceneError::BadSpec {
                    spec: format!("{}@draws", self.name),
                    reason: "a mesh per instance would exceed 32-bit index offsets".into(),
                });
            }
            let own = b.push_mesh_range(
                mesh.vertex_offset as u32,
                mesh.vertex_count,
                indices,
                mesh.material,
            );
            b.push_instance_trusted(inst.transform, own);
            if let Some(last) = b.instances.last_mut() {
                last.flags = inst.flags;
            }
        }
        b.build(Some(self.camera_path.clone()))
    }

    /// A builder named `name` with this scene's textures and materials (same ids), and with
    /// `vertices` its vertex buffer too (same offsets: its meshes' ranges hold).
    fn builder_like(&self, name: String, vertices: bool) -> SceneBuilder {
        let mut b = SceneBuilder::new(name);
        for t in self.textures.iter() {
            b.add_texture(t.clone());
        }
        for m in &self.materials {
            b.add_material(*m);
        }
        if vertices {
            let offset = b.push_vertices(&self.vertices);
            debug_assert_eq!(offset, 0);
        }
        b
    }

    /// The scene's instances over the meshes `b` holds (`mesh(i)`: the new id of mesh `i`).
    fn rebuilt_with(
        &self,
        mut b: SceneBuilder,
        mesh: impl Fn(usize) -> Option<MeshId>,
    ) -> Result<Scene, SceneError> {
        for inst in &self.instances {
            let Some(m) = mesh(inst.mesh.index()) else {
                continue;
            };
            b.push_instance_trusted(inst.transform, m);
            if let Some(last) = b.instances.last_mut() {
                last.flags = inst.flags;
            }
        }
        b.build(Some(self.camera_path.clone()))
    }
}

/// A well-mixed hash of an instance index (neighbours land on unrelated materials).
fn spread(i: u32) -> u32 {
    let mut x = i.wrapping_mul(0x9E37_79B9);
    x ^= x >> 16;
    x = x.wrapping_mul(0x85EB_CA6B);
    x ^ (x >> 13)
}

/// Hue `k` of `n` around the colour wheel, fully saturated, in linear RGB.
fn hue(k: u32, n: u32) -> [f32; 4] {
    let h = k as f32 / n as f32 * 6.0;
    let c = |shift: f32| (((h + shift) % 6.0 - 3.0).abs() - 1.0).clamp(0.0, 1.0);
    [
        c(0.0) * 0.8 + 0.1,
        c(4.0) * 0.8 + 0.1,
        c(2.0) * 0.8 + 0.1,
        1.0,
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_spec_suffix_spreads_and_bad_counts_are_refused() {
        let s = crate::load("city:100@materials:5").unwrap();
        let plain = crate::load("city:100").unwrap();
        assert!(s.materials().len() >= plain.materials().len() + 5);
        for bad in [
            "city:100@materials:0",
            "city:100@materials:x",
            "city:100@materials:5000",
        ] {
            let e = crate::load(bad).unwrap_err().to_string();
            assert!(e.contains("material count"), "{bad}: {e}");
        }
    }

    #[test]
    fn thinning_keeps_a_share_of_triangles_and_of_instances() {
        let city = crate::load("city:400").unwrap();
        let same = city.thinned(1, 1).unwrap();
        assert_eq!(same.triangles_drawn(), city.triangles_drawn());
        assert_eq!(same.instances().len(), city.instances().len());
        let fewer = city.thinned(4, 1).unwrap();
        assert_eq!(fewer.instances().len(), city.instances().len());
        let (t, all) = (fewer.triangles_drawn(), city.triangles_drawn());
        assert!(t * 4 >= all && t * 3 < all, "{t} of {all} triangles");
        for m in fewer.meshes() {
            assert!(m.index_count >= 3 && m.index_count % 3 == 0);
        }
        let sparse = city.thinned(1, 4).unwrap();
        assert_eq!(sparse.instances().len(), city.instances().len().div_ceil(4));
        for (a, b) in city.instances().iter().step_by(4).zip(sparse.instances()) {
            assert_eq!(a.transform, b.transform);
        }
    }

    #[test]
    fn dense_meshes_keep_their_surfaces_and_draws_follow_instances() {
        let city = crate::load("city:100").unwrap();
        let dense = crate::load("city:100@dense:2").unwrap();
        assert_eq!(dense.instances().len(), city.instances().len());
        assert_eq!(dense.triangles_drawn(), 16 * city.triangles_drawn());
        for (a, b) in city.meshes().iter().zip(dense.meshes()) {
            assert_eq!(a.local_aabb, b.local_aabb);
            assert_eq!(16 * a.index_count, b.index_count);
        }
        // Each split triangle faces the way its parent did, and the split ones tile its area.
        let (m0, d0) = (&city.meshes()[0], &dense.meshes()[0]);
        let tri = |s: &Scene, m: &crate::Mesh, k: usize| {
            let at = |i: usize| {
                let v = s.indices()[m.first_index as usize + 3 * k + i];
                glam::Vec3::from(s.vertices()[(m.vertex_offset as u32 + v) as usize].position)
            };
            (at(1) - at(0)).cross(at(2) - at(0))
        };
        let parent = tri(&city, m0, 0);
        let mut area = glam::Vec3::ZERO;
        for k in 0..16 {
            let child = tri(&dense, d0, k);
            assert!(child.dot(parent) > 0.0, "child {k} flipped");
            area += child;
        }
        assert!(
            (area - parent).length() <= 1e-4 * parent.length(),
            "{area} {parent}"
        );

        let draws = crate::load("city:100@draws").unwrap();
        assert_eq!(draws.meshes().len(), city.instances().len());
        assert_eq!(draws.triangles_drawn(), city.triangles_drawn());
        for (a, b) in city.instances().iter().zip(draws.instances()) {
            assert_eq!(a.transform, b.transform);
        }
        for bad in ["city:100@dense:0", "city:100@dense:6", "city:100@dense:x"] {
            let e = crate::load(bad).unwrap_err().to_string();
            assert!(e.contains("@dense"), "{bad}: {e}");
        }
        // Each suffix makes a whole scene: a chain of them is bounded (not a deep recursion).
        let most = format!("city:4{}", "@draws".repeat(crate::MAX_SPEC_SUFFIXES));
        assert!(crate::load(&most).is_ok(), "{most}");
        let over = format!("city:4{}", "@draws".repeat(crate::MAX_SPEC_SUFFIXES + 1));
        let e = crate::load(&over).unwrap_err().to_string();
        assert!(e.contains("suffixes"), "{e}");
    }

    #[test]
    fn spreading_keeps_the_geometry_and_uses_every_material() {
        let city = crate::load("city:400").unwrap();
        let spread = city.with_spread_materials(8).unwrap();
        assert_eq!(spread.instances().len(), city.instances().len());
        assert_eq!(spread.triangles_drawn(), city.triangles_drawn());
        let added = spread.materials().len() - city.materials().len();
        assert!((8..=16).contains(&added), "{added} materials added");
        let mut used = std::collections::BTreeSet::new();
        for (a, b) in city.instances().iter().zip(spread.instances()) {
            assert_eq!(a.transform, b.transform);
            assert_eq!(a.bounds.center, b.bounds.center);
            let (ma, mb) = (city.mesh(a.mesh).unwrap(), spread.mesh(b.mesh).unwrap());
            assert_eq!(ma.index_count, mb.index_count);
            let class = city.material(ma.material).unwrap().class;
            if class == MaterialClass::Opaque {
                assert!(mb.material.index() >= city.materials().len());
                used.insert(mb.material);
            } else {
                assert_eq!(ma.material, mb.material);
            }
        }
        assert_eq!(used.len(), added, "every new material draws something");
    }
}
