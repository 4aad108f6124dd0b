//! The engine's materials on a renderer (crate::materials): registering them, and each frame
//! which of the scene's meshes they draw.

use tilegraph_scene::Scene;
use tilegraph_vk::ash::vk;

use super::SceneRenderer;
use crate::cull::CullState;
use crate::materials::EngineMaterial;
use crate::options::RenderError;

impl SceneRenderer {
    /// The layout of set 0 (the scene): an engine material's pipeline layout starts with it.
    pub fn scene_set_layout(&self) -> vk::DescriptorSetLayout {
        self.resources.scene.set_layout
    }

    /// Registers an engine material; scene materials whose `engine_material` is the id returned
    /// are drawn with its shaders in the passes it has shaders for. The engine keeps its
    /// pipeline layout alive until the renderer is destroyed; tilegraph makes, caches and
    /// destroys the pipelines.
    pub fn add_material(&mut self, material: EngineMaterial) -> u32 {
        log::info!("engine material {:?} registered", material.name);
        self.resources.pipelines.add_material(material)
    }

    /// The materials the visibility buffer resolves one by one this frame (its declaration
    /// depends on them): the scene's, where the resolve is per material; else 0.
    pub(super) fn resolve_materials(&self, ctx: &tilegraph_vk::Context) -> u32 {
        let per_material = self.options.technique == crate::Technique::Visbuf
            && self.options.visbuf_resolve(ctx.profile()).0 != crate::VisbufResolve::Uber;
        if per_material {
            self.resources.frame.material_count
        } else {
            0
        }
    }

    /// Brings the frame's mesh -> engine material table up to `scene` and tells GPU culling
    /// whether this frame's lists are drawn in runs of pipelines. Nothing is done (or allocated)
    /// while no engine material is registered.
    pub(super) fn prepare_materials(&mut self, scene: &Scene) -> Result<(), RenderError> {
        let res = &mut self.resources;
        res.frame.material_count = scene.materials().len() as u32;
        let registered = res.pipelines.material_count();
        if registered == 0 {
            return Ok(());
        }
        let table = &mut res.frame.engine_of_mesh;
        table.clear();
        let mut any = false;
        for mesh in scene.meshes() {
            let engine = scene
                .material(mesh.material)
                .and_then(|m| m.engine_material);
            if let Some(k) = engine {
                if k as usize >= registered {
                    return Err(RenderError::UnknownEngineMaterial {
                        material: mesh.material.0,
                        engine: k,
                        registered,
                    });
                }
                any = true;
            }
            table.push(engine);
        }
        if let Some(cull) = res.states.get_mut::<CullState>() {
            if any && cull.clusters.is_some() {
                return Err(RenderError::EngineMaterialsWithClusters {
                    culling: cull.culling.name(),
                });
            }
            cull.group_runs = any;
        }
        Ok(())
    }
}
