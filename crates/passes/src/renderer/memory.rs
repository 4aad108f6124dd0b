//! What a renderer's scene buffers take on the GPU: estimated before a renderer exists (from
//! the sizes the buffers are made with: `scene-info` prints it) and read off one that does.

use tilegraph_scene::Scene;

use super::SceneRenderer;
use crate::cull::CullState;
use crate::gpu_scene::{geometry_sizes, slot_specs, view_specs, Capacity};

/// Device memory of a renderer's scene buffers for `scene`, by what holds it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct SceneMemory {
    /// Instance slots the buffers hold ([`Capacity::for_scene`]).
    pub instance_slots: u32,
    pub frames_in_flight: u32,
    /// The resident vertices and indices.
    pub geometry_bytes: u64,
    /// Per frame slot: records, entries, tables, uniforms.
    pub slot_bytes: u64,
    /// GPU culling's lists (the instance techniques'; clusters and pyramids not counted).
    pub culling_bytes: u64,
    /// The materials' textures with their mip chains (RGBA8; as the scene holds them, which is
    /// what the indexed binding uploads; the layers binding resamples to one size).
    pub texture_bytes: u64,
}

impl SceneMemory {
    /// Every byte: the geometry, every slot's buffers, the culling lists, the textures.
    pub fn total_bytes(&self) -> u64 {
        self.geometry_bytes
            + self.slot_bytes * u64::from(self.frames_in_flight)
            + self.culling_bytes
            + self.texture_bytes
    }

    /// What an instance slot costs, the geometry and textures left out (they are per mesh and
    /// per material).
    pub fn bytes_per_instance(&self) -> f64 {
        (self.total_bytes() - self.geometry_bytes - self.texture_bytes) as f64
            / f64::from(self.instance_slots.max(1))
    }
}

/// The device memory a GPU-culling renderer with `frames_in_flight` slots allocates for
/// `scene`'s buffers: the same sizes the renderer makes its buffers with.
pub fn scene_memory(scene: &Scene, frames_in_flight: usize, instance_capacity: u32) -> SceneMemory {
    let capacity = Capacity::for_scene(scene, instance_capacity);
    let slot_bytes = slot_specs(capacity, scene.meshes().len(), scene.materials().len())
        .iter()
        .chain(&view_specs())
        .map(|s| s.1.max(16))
        .sum();
    SceneMemory {
        instance_slots: capacity.instances,
        frames_in_flight: frames_in_flight as u32,
        geometry_bytes: geometry_sizes(scene).iter().map(|b| b.max(&4)).sum(),
        slot_bytes,
        culling_bytes: CullState::list_bytes(capacity, frames_in_flight),
        texture_bytes: scene.texture_bytes(),
    }
}

impl SceneRenderer {
    /// How the scene's textures are bound on this device (the profile's choice, or layers where
    /// the device cannot index them), and the bytes their images take.
    pub fn texture_binding(&self) -> tilegraph_profile::TextureBinding {
        self.resources.scene.textures.binding
    }

    /// Device memory of the scene's buffers as they are now (geometry, every slot's records,
    /// entries, tables and views' uniforms, every view's instance lists of GPU culling), in the shape
    /// [`scene_memory`] estimates before a renderer exists.
    pub fn scene_memory(&self) -> SceneMemory {
        let scene = &self.resources.scene;
        let slots = self.executor.frames_in_flight() as u32;
        let geometry = scene.vertices.size + scene.indices.size;
        // Every view's culling lists.
        let culling = (0..self.resources.views())
            .filter_map(|k| self.resources.view_states(k))
            .filter_map(|s| s.get::<CullState>())
            .map(CullState::memory_bytes)
            .sum();
        SceneMemory {
            instance_slots: scene.capacity().instances,
            frames_in_flight: slots,
            geometry_bytes: geometry,
            slot_bytes: (scene.memory_bytes() - geometry) / u64::from(slots.max(1)),
            culling_bytes: culling,
            texture_bytes: scene.textures.bytes(),
        }
    }
}
