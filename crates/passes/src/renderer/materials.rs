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

    /// The layout of set 1 of an engine material's visibility-buffer resolve (the ids and the
    /// classification's lists; `shaders/include/tilegraph_visbuf.glsl`): `None` unless the
    /// renderer shades with the visibility buffer.
    pub fn resolve_set_layout(&self) -> Option<vk::DescriptorSetLayout> {
        self.resources
            .states
            .get::<crate::visbuf::classify::ClassifyState>()
            .map(|c| c.set_layout())
    }

    /// The materials the visibility buffer resolves one by one this frame in a view of
    /// `options` (its declaration depends on them): the scene's, where the resolve is per
    /// material; else 0.
    pub(super) fn resolve_materials(
        &self,
        ctx: &tilegraph_vk::Context,
        options: &crate::RenderOptions,
    ) -> u32 {
        let per_material = options.technique == crate::Technique::Visbuf
            && options.visbuf_resolve(ctx.profile()).0 != crate::VisbufResolve::Uber;
        if per_material {
            self.resources.frame.material_count
        } else {
            0
        }
    }

    /// Brings the frame's mesh -> engine material table up to `scene` and tells each view's
    /// GPU culling whether this frame's lists are drawn in runs of pipelines. Nothing is done
    /// (or allocated) while no engine material is registered.
    pub(super) fn prepare_materials(
        &mut self,
        ctx: &tilegraph_vk::Context,
        scene: &Scene,
    ) -> Result<(), RenderError> {
        // A visibility buffer that resolves without classifying cannot run an engine resolve.
        let unclassified_visbuf = self.views.iter().any(|v| {
            v.options.technique == crate::Technique::Visbuf
                && v.options.visbuf_resolve(ctx.profile()).0 != crate::VisbufResolve::Classified
        });
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
        // Which scene materials an engine resolve shades (after classification only).
        let resolves = &mut res.frame.engine_resolve;
        resolves.clear();
        for (i, m) in scene.materials().iter().enumerate() {
            let engine = m.engine_material.filter(|&k| {
                res.pipelines
                    .engine_material(k)
                    .is_some_and(|e| e.resolve.is_some())
            });
            if let (Some(k), true) = (engine, unclassified_visbuf) {
                return Err(RenderError::EngineResolveNeedsClassification {
                    material: i as u32,
                    engine: k,
                });
            }
            resolves.push(engine);
        }
        for k in 0..res.views() {
            res.enter_view(k);
            if let Some(cull) = res.states.get_mut::<CullState>() {
                cull.group_runs = any;
            }
        }
        res.enter_view(0);
        Ok(())
    }
}
