//! A scene's opaque geometry spread over many materials: what the visibility buffer's
//! per-material resolves and material classification are measured on (`--materials N`).

use super::{Material, MaterialClass, MeshId, Scene, SceneBuilder, SceneError};

impl Scene {
    /// This scene with each opaque instance drawn in one of `n` new opaque materials (of `n`
    /// hues), picked by a hash of the instance's index so that neighbours on screen differ: the
    /// materials spread over the whole screen. Each opaque mesh gets a copy per material over
    /// the same vertices; other geometry, the textures and the camera path are kept. Double-sided
    /// opaque meshes get double-sided copies (so up to `2 n` new materials).
    pub fn with_spread_materials(&self, n: u32) -> Result<Scene, SceneError> {
        let n = n.max(1);
        let mut b = SceneBuilder::new(format!("{}+materials:{n}", self.name));
        for t in self.textures.iter() {
            b.add_texture(t.clone());
        }
        for m in &self.materials {
            b.add_material(*m);
        }
        // Variant k of sidedness s: made when first used.
        let mut variants = vec![[None; 2]; n as usize];
        let offset = b.push_vertices(&self.vertices);
        debug_assert_eq!(offset, 0);
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
