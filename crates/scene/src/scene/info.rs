//! What `tilegraph scene-info` prints: counts per class, bounds, glTF counts, texture memory.

use std::fmt;

use serde::Serialize;

use super::{MaterialClass, Scene, SceneSource};

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
        }
    }
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
