//! What `tilegraph scene-info` prints: counts per class, bounds, glTF counts, texture memory.

use std::fmt;

use serde::Serialize;

use super::{MaterialClass, MeshId, Scene, SceneSource};

impl Scene {
    /// The counts the CLI prints (`tilegraph scene info`).
    pub fn info(&self) -> SceneInfo {
        let mut materials = ClassCounts::default();
        for m in &self.materials {
            materials.add(m.class);
        }
        let mut instances_by_class = ClassCounts::default();
        for i in self.instances.iter().filter(|i| !i.flags.is_free()) {
            if let Some(m) = self.instance_material(i) {
                instances_by_class.add(m.class);
            }
        }
        let (min, max) = if self.bounds.is_empty() {
            ([0.0; 3], [0.0; 3])
        } else {
            (self.bounds.min.to_array(), self.bounds.max.to_array())
        };
        SceneInfo {
            name: self.name.clone(),
            source: self.source.clone(),
            instances: self.live_instances() as u64,
            meshes: self.meshes.iter().filter(|m| m.index_count > 0).count() as u64,
            triangles: self.triangles_drawn(),
            bounds: BoundsInfo { min, max },
            materials,
            instances_by_class,
            unique_triangles: self
                .meshes
                .iter()
                .map(|m| u64::from(m.triangle_count()))
                .sum(),
            vertices: self.vertices.len() as u64,
            indices: self.indices.len() as u64,
            material_count: self.materials.len() as u64,
            nodes: self.gltf_counts.map(|c| c.nodes as u64),
            gltf_meshes: self.gltf_counts.map(|c| c.meshes as u64),
            primitives: self.gltf_counts.map(|c| c.primitives as u64),
            camera_path_frames: self.camera_path.len() as u64,
            textures: self.textures.len() as u64,
            texture_bytes: self.texture_bytes(),
            degenerate: self.degenerate_triangles(),
        }
    }

    /// The meshes' triangles (each once) that cover nothing or almost nothing
    /// ([`Degenerate`]).
    pub fn degenerate_triangles(&self) -> Degenerate {
        let mut count = Degenerate::default();
        self.each_degenerate(|_, _, zero_area| match zero_area {
            true => count.zero_area += 1,
            false => count.slivers += 1,
        });
        count
    }

    /// Every degenerate triangle ([`Degenerate`]) as (mesh, triangle of the mesh's draw), in
    /// mesh order.
    pub fn degenerate_triangle_ids(&self) -> Vec<(MeshId, u32)> {
        let mut ids = Vec::new();
        self.each_degenerate(|mesh, triangle, _| ids.push((mesh, triangle)));
        ids
    }

    /// Calls `f(mesh, triangle, zero_area)` for each degenerate triangle.
    fn each_degenerate(&self, mut f: impl FnMut(MeshId, u32, bool)) {
        for (m, mesh) in self.meshes.iter().enumerate() {
            let first = mesh.first_index as usize;
            let Some(indices) = self.indices.get(first..first + mesh.index_count as usize) else {
                continue;
            };
            let corner = |i: u32| {
                let v = usize::try_from(i64::from(i) + i64::from(mesh.vertex_offset)).ok()?;
                self.vertices.get(v).map(|v| glam::Vec3::from(v.position))
            };
            for (t, corners) in indices.chunks_exact(3).enumerate() {
                let [Some(a), Some(b), Some(c)] = [0, 1, 2].map(|k| corner(corners[k])) else {
                    continue;
                };
                let twice_area = (b - a).cross(c - a).length();
                let longest = (b - a)
                    .length_squared()
                    .max((c - b).length_squared())
                    .max((a - c).length_squared());
                if twice_area < 2.0 * SLIVER * longest || twice_area == 0.0 {
                    f(MeshId(m as u32), t as u32, twice_area == 0.0);
                }
            }
        }
    }
}

/// Area over the longest edge squared below which a triangle is a sliver: a needle whose apex
/// lies 2e-5 of its length off its base. Thin geometry meant as such (a 1 mm wire 8 m long,
/// 1.25e-4) stays above it.
const SLIVER: f32 = 1e-5;

/// Triangles that cover nothing (`zero_area`: collinear or repeated corners, exactly, in
/// f32) or almost nothing (`slivers`: area under [`SLIVER`] of the longest edge squared). They
/// add nothing to an image, yet a rasterizer may draw a pixel of one at a depth it never
/// reaches (docs/ACCURACY.md, "Stray pixels"): a mesh to clean.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct Degenerate {
    pub zero_area: u64,
    pub slivers: u64,
}

/// Counts per material class.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct ClassCounts {
    pub opaque: u64,
    pub alpha_tested: u64,
    pub blended: u64,
}

impl ClassCounts {
    pub(super) fn add(&mut self, class: MaterialClass) {
        *self.of(class) += 1;
    }

    pub(super) fn remove(&mut self, class: MaterialClass) {
        let n = self.of(class);
        *n = n.saturating_sub(1);
    }

    fn of(&mut self, class: MaterialClass) -> &mut u64 {
        match class {
            MaterialClass::Opaque => &mut self.opaque,
            MaterialClass::AlphaTested { .. } => &mut self.alpha_tested,
            MaterialClass::Blended => &mut self.blended,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct BoundsInfo {
    pub min: [f64; 3],
    pub max: [f64; 3],
}

/// What `tilegraph scene info` prints, as JSON (serde) or as a table (`Display`).
///
/// `triangles` counts triangles drawn over all instances; `unique_triangles` counts them once per
/// mesh. `materials` counts materials per class; `instances_by_class` counts instances.
/// `nodes`, `gltf_meshes` and `primitives` are glTF document counts and are absent for
/// procedural scenes.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SceneInfo {
    pub name: String,
    pub source: SceneSource,
    pub instances: u64,
    pub meshes: u64,
    pub triangles: u64,
    pub bounds: BoundsInfo,
    pub materials: ClassCounts,
    pub instances_by_class: ClassCounts,
    pub unique_triangles: u64,
    pub vertices: u64,
    pub indices: u64,
    pub material_count: u64,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub nodes: Option<u64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gltf_meshes: Option<u64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub primitives: Option<u64>,
    pub camera_path_frames: u64,
    /// Textures and the bytes of their mip chains (RGBA8): the GPU memory they take.
    pub textures: u64,
    pub texture_bytes: u64,
    /// Triangles that cover nothing or almost nothing, once per mesh.
    pub degenerate: Degenerate,
}

impl fmt::Display for SceneInfo {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let [x0, y0, z0] = self.bounds.min;
        let [x1, y1, z1] = self.bounds.max;
        writeln!(f, "scene              {}", self.name)?;
        match &self.source {
            SceneSource::Gltf { path } => writeln!(f, "source             glTF {path}")?,
            SceneSource::Procedural { name, size, seed } => writeln!(
                f,
                "source             procedural {name} size={size} seed={seed}"
            )?,
            SceneSource::Built => writeln!(f, "source             built in code")?,
        }
        if let (Some(n), Some(m), Some(p)) = (self.nodes, self.gltf_meshes, self.primitives) {
            writeln!(
                f,
                "glTF               {n} nodes, {m} meshes, {p} primitives"
            )?;
        }
        writeln!(f, "instances          {}", self.instances)?;
        writeln!(f, "meshes             {}", self.meshes)?;
        writeln!(
            f,
            "triangles          {} drawn ({} unique)",
            self.triangles, self.unique_triangles
        )?;
        let Degenerate { zero_area, slivers } = self.degenerate;
        let clean = if zero_area + slivers > 0 {
            " (they cover nothing, or almost, and may rasterize stray pixels: a mesh to clean)"
        } else {
            ""
        };
        writeln!(
            f,
            "degenerate         {zero_area} zero-area, {slivers} slivers{clean}"
        )?;
        writeln!(f, "vertices / indices {} / {}", self.vertices, self.indices)?;
        writeln!(
            f,
            "materials          {} opaque, {} alpha-tested, {} blended",
            self.materials.opaque, self.materials.alpha_tested, self.materials.blended
        )?;
        writeln!(
            f,
            "instances by class {} opaque, {} alpha-tested, {} blended",
            self.instances_by_class.opaque,
            self.instances_by_class.alpha_tested,
            self.instances_by_class.blended
        )?;
        writeln!(
            f,
            "textures           {} ({:.1} MiB with mips)",
            self.textures,
            self.texture_bytes as f64 / (1024.0 * 1024.0)
        )?;
        writeln!(
            f,
            "bounds             [{x0:.3}, {y0:.3}, {z0:.3}] .. [{x1:.3}, {y1:.3}, {z1:.3}]"
        )?;
        write!(f, "camera path        {} frames", self.camera_path_frames)
    }
}

#[cfg(test)]
mod tests {
    use crate::{Material, SceneBuilder, Transform, Vertex};

    #[test]
    fn zero_area_triangles_and_needles_are_degenerate_wires_are_not() {
        let mut b = SceneBuilder::new("degenerate");
        let m = b.add_material(Material::opaque([1.0; 4]));
        let v = |x: f32, y: f32, z: f32| Vertex {
            position: [x, y, z],
            normal: [0.0, 0.0, 1.0],
            uv: [0.0, 0.0],
        };
        let vertices = [
            // 0-2: a plain triangle; 3: collinear with 0 and 1.
            v(0.0, 0.0, 0.0),
            v(1.0, 0.0, 0.0),
            v(0.0, 1.0, 0.0),
            v(2.0, 0.0, 0.0),
            // 4: a needle's apex 1e-6 of its length off the base 0-1 (at its middle).
            v(0.5, 1e-6, 0.0),
            // 5, 6: a wire 1 mm wide and 8 m long with 0.
            v(8.0, 0.0, 0.0),
            v(8.0, 0.001, 0.0),
        ];
        let indices = [0, 1, 2, 0, 1, 3, 0, 0, 2, 0, 1, 4, 0, 5, 6];
        let mesh = b.add_mesh(&vertices, &indices, m).unwrap();
        b.add_instance(Transform::IDENTITY, mesh).unwrap();
        let scene = b.build(None).unwrap();
        let d = scene.degenerate_triangles();
        assert_eq!((d.zero_area, d.slivers), (2, 1), "{d:?}");
        assert_eq!(scene.info().degenerate, d);
        let ids: Vec<u32> = scene
            .degenerate_triangle_ids()
            .iter()
            .map(|&(_, t)| t)
            .collect();
        assert_eq!(
            ids,
            [1, 2, 3],
            "the collinear, repeated-corner and needle triangles"
        );
    }
}
