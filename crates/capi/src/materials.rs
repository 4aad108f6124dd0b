//! Engine materials through C: the engine's own shaders drawing tilegraph's culled lists.
//!
//! The engine gives SPIR-V (compiled against `shaders/include/tilegraph_instance.glsl`), a
//! `VkPipelineLayout` whose set 0 is the renderer's scene set layout
//! (`tg_renderer_scene_set_layout`), and a callback that binds its own sets; tilegraph makes the
//! `VkPipeline`s. It takes shaders rather than the engine's `VkPipeline` because a graphics
//! pipeline is made for one render pass and subpass, and tilegraph's render passes are its
//! own: made per plan, merged into subpasses per profile, made again when the plan changes — a
//! pipeline the engine made beforehand would not be compatible with them. docs/EMBEDDING.md
//! holds the contract.

use std::ffi::{c_char, c_void};

use tilegraph_passes::materials::{
    EngineMaterial, EngineResolve, MaterialPass, MaterialShaders, ShaderCode,
};
use tilegraph_scene::{MaterialId, Scene};
use tilegraph_vk::ash::vk::{self, Handle};

use crate::registry::{self, Kind};
use crate::renderer::{RendererObject, TgRenderer};
use crate::scene::{material_desc, TgMaterial, TgScene};
use crate::status::{arg, boundary, out, string, Failure, TgStatus};

/// A scene material drawn by tilegraph's own shaders (`tg_scene_set_engine_material`).
pub const TG_ENGINE_MATERIAL_NONE: u32 = u32::MAX;

/// The pass an engine material's bind callback is called for.
#[repr(u32)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TgMaterialPass {
    /// The depth pre-pass.
    Depth = 0,
    /// The forward colour passes (opaque, alpha-tested, blended).
    Color = 1,
    /// The visibility buffer's resolve, after material classification.
    Resolve = 2,
}

/// One shader stage's SPIR-V; `code` null: the stage is absent.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct TgShader {
    /// A name for validation messages and the lint's findings (may be null).
    pub name: *const c_char,
    /// SPIR-V words (4-byte aligned).
    pub code: *const u32,
    /// Its size in bytes (a multiple of 4).
    pub code_size: usize,
}

/// Binds the engine's own descriptor sets (set 1 and up) and push constants into
/// `command_buffer` (a VkCommandBuffer), after tilegraph bound the material's pipeline and set
/// 0, before the material's draws; `pass` is a TgMaterialPass. Called while
/// `tg_renderer_record` runs, on its thread; it must not call tilegraph.
pub type TgBindMaterial =
    Option<unsafe extern "C" fn(user: *mut c_void, command_buffer: *mut c_void, pass: u32)>;

/// What an engine registers for a material.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct TgEngineMaterialDesc {
    /// The material's name (for logs and messages).
    pub name: *const c_char,
    /// VkPipelineLayout, owned by the engine and alive until the renderer is destroyed: set 0
    /// is the renderer's scene set layout, the engine's sets and push constants follow.
    pub layout: u64,
    /// Depth pre-pass shaders; a null vertex shader: tilegraph's pre-pass draws the
    /// material's instances. An opaque material's fragment shader may be absent.
    pub depth_vertex: TgShader,
    pub depth_fragment: TgShader,
    /// Colour shaders; a null vertex shader: tilegraph's colour passes draw them. With a
    /// vertex shader, a fragment shader is required.
    pub color_vertex: TgShader,
    pub color_fragment: TgShader,
    /// The visibility buffer's resolve (a fragment shader through
    /// `shaders/include/tilegraph_visbuf.glsl`; null code: tilegraph's resolve shades the
    /// material's pixels) and its VkPipelineLayout: set 0 the scene set layout, set 1
    /// `tg_renderer_resolve_set_layout`'s, the engine's own sets from 2. Runs with
    /// `visbuf_resolve = classified` (set in the profile's knobs).
    pub resolve_fragment: TgShader,
    pub resolve_layout: u64,
    /// Called before the material's draws in each pass (may be null: nothing to bind).
    pub bind: TgBindMaterial,
    /// Passed to `bind` unchanged.
    pub user: *mut c_void,
}

/// One stage's code, copied; `None` when absent.
///
/// # Safety
/// A non-null `s.code` points to `s.code_size` bytes; a non-null `s.name` is NUL-terminated.
unsafe fn shader(s: &TgShader, what: &str) -> Result<Option<ShaderCode>, Failure> {
    if s.code.is_null() {
        return Ok(None);
    }
    if s.code_size == 0 || !s.code_size.is_multiple_of(4) {
        return Err(Failure::invalid(format!(
            "`{what}.code_size` {} is not a positive multiple of 4",
            s.code_size
        )));
    }
    // SAFETY: the caller's contract (aligned and sized: checked by `array`).
    let words = unsafe { crate::status::array(s.code, s.code_size / 4, what) }?;
    if words.first() != Some(&0x0723_0203) {
        return Err(Failure::invalid(format!(
            "`{what}` does not start with the SPIR-V magic number"
        )));
    }
    let name = if s.name.is_null() {
        what.to_owned()
    } else {
        // SAFETY: the caller's contract.
        unsafe { string(s.name, &format!("{what}.name")) }?.to_owned()
    };
    Ok(Some(ShaderCode {
        name,
        spirv: words.iter().flat_map(|w| w.to_ne_bytes()).collect(),
    }))
}

/// A pass's shaders; `fragment_required`: a vertex shader without one is refused.
///
/// # Safety
/// As [`shader`], for both.
unsafe fn pass_shaders(
    vertex: &TgShader,
    fragment: &TgShader,
    pass: &str,
    fragment_required: bool,
) -> Result<Option<MaterialShaders>, Failure> {
    // SAFETY: the caller's contract.
    let (v, f) = unsafe {
        (
            shader(vertex, &format!("{pass}_vertex"))?,
            shader(fragment, &format!("{pass}_fragment"))?,
        )
    };
    match (v, f) {
        (None, None) => Ok(None),
        (None, Some(_)) => Err(Failure::invalid(format!(
            "`{pass}_fragment` is given without `{pass}_vertex`"
        ))),
        (Some(_), None) if fragment_required => Err(Failure::invalid(format!(
            "`{pass}_vertex` is given without `{pass}_fragment` (a colour pass needs one)"
        ))),
        (Some(vertex), fragment) => Ok(Some(MaterialShaders { vertex, fragment })),
    }
}

/// The layout of set 0 (the scene's) that an engine material's pipeline layout starts with:
/// a VkDescriptorSetLayout owned by the renderer.
///
/// # Safety
/// `out_layout` is writable.
#[no_mangle]
pub unsafe extern "C" fn tg_renderer_scene_set_layout(
    renderer: TgRenderer,
    out_layout: *mut u64,
) -> TgStatus {
    boundary("tg_renderer_scene_set_layout", || {
        // SAFETY: the caller's contract.
        let out_layout = unsafe { out(out_layout, "out_layout") }?;
        *out_layout = registry::with(
            renderer.raw,
            Kind::Renderer,
            "renderer",
            |r: &RendererObject| Ok(r.renderer.scene_set_layout().as_raw()),
        )?;
        Ok(())
    })
}

/// The layout of set 1 of an engine material's resolve pipeline layout (a
/// VkDescriptorSetLayout owned by the renderer): the ids and the classification's lists.
/// TG_STATUS_INVALID_ARGUMENT unless the renderer shades with the visibility buffer.
///
/// # Safety
/// `out_layout` is writable.
#[no_mangle]
pub unsafe extern "C" fn tg_renderer_resolve_set_layout(
    renderer: TgRenderer,
    out_layout: *mut u64,
) -> TgStatus {
    boundary("tg_renderer_resolve_set_layout", || {
        // SAFETY: the caller's contract.
        let out_layout = unsafe { out(out_layout, "out_layout") }?;
        *out_layout = 0;
        let layout = registry::with(
            renderer.raw,
            Kind::Renderer,
            "renderer",
            |r: &RendererObject| Ok(r.renderer.resolve_set_layout()),
        )?;
        *out_layout = layout
            .ok_or_else(|| {
                Failure::invalid(
                    "the renderer does not shade with the visibility buffer (TG_TECHNIQUE_VISBUF)",
                )
            })?
            .as_raw();
        Ok(())
    })
}

/// Registers an engine material on a renderer; its id (0, 1, ... per renderer) goes to
/// `out_engine_material`. Scene materials given that id (`tg_scene_set_engine_material`) are
/// drawn with its shaders in the passes it has shaders for, from the next record. The shaders
/// are copied; the layout and `user` stay the engine's. Every culling draws them, cluster
/// culling included (each draw group's surviving clusters with its pipeline).
///
/// # Safety
/// `desc` is valid (its shaders and name as `TgShader` says); `out_engine_material` writable.
#[no_mangle]
pub unsafe extern "C" fn tg_material_register(
    renderer: TgRenderer,
    desc: *const TgEngineMaterialDesc,
    out_engine_material: *mut u32,
) -> TgStatus {
    boundary("tg_material_register", || {
        // SAFETY: the caller's contract.
        let desc = unsafe { arg(desc, "desc") }?;
        // SAFETY: as above.
        let out_id = unsafe { out(out_engine_material, "out_engine_material") }?;
        *out_id = TG_ENGINE_MATERIAL_NONE;
        if desc.layout == 0 {
            return Err(Failure::new(
                TgStatus::NullPointer,
                "`desc->layout` is VK_NULL_HANDLE",
            ));
        }
        let name = if desc.name.is_null() {
            "engine material".to_owned()
        } else {
            // SAFETY: the caller's contract.
            unsafe { string(desc.name, "desc->name") }?.to_owned()
        };
        // SAFETY: as above.
        let (depth, color) = unsafe {
            (
                pass_shaders(&desc.depth_vertex, &desc.depth_fragment, "depth", false)?,
                pass_shaders(&desc.color_vertex, &desc.color_fragment, "color", true)?,
            )
        };
        // SAFETY: as above.
        let resolve = match unsafe { shader(&desc.resolve_fragment, "resolve_fragment") }? {
            None => None,
            Some(_) if desc.resolve_layout == 0 => {
                return Err(Failure::new(
                    TgStatus::NullPointer,
                    "`desc->resolve_layout` is VK_NULL_HANDLE but a resolve shader is given",
                ))
            }
            Some(fragment) => Some(EngineResolve {
                fragment,
                layout: vk::PipelineLayout::from_raw(desc.resolve_layout),
            }),
        };
        if depth.is_none() && color.is_none() && resolve.is_none() {
            return Err(Failure::invalid(format!(
                "engine material {name:?} has no shaders (give depth or colour shaders)"
            )));
        }
        let (callback, user) = (desc.bind, desc.user);
        let material = EngineMaterial {
            name,
            layout: vk::PipelineLayout::from_raw(desc.layout),
            depth,
            color,
            resolve,
            bind: Box::new(move |_ctx, cb, pass| {
                if let Some(f) = callback {
                    let pass = match pass {
                        MaterialPass::Depth => TgMaterialPass::Depth,
                        MaterialPass::Color => TgMaterialPass::Color,
                        MaterialPass::Resolve => TgMaterialPass::Resolve,
                    };
                    // SAFETY: the engine's callback, called as its contract says: during the
                    // record, with the command buffer it gave and its own `user`.
                    unsafe { f(user, cb.as_raw() as *mut c_void, pass as u32) };
                }
            }),
        };
        *out_id = registry::with_mut(
            renderer.raw,
            Kind::Renderer,
            "renderer",
            |r: &mut RendererObject| Ok(r.renderer.add_material(material)),
        )?;
        Ok(())
    })
}

/// Draws scene material `material_index` with engine material `engine_material` (an id from
/// `tg_material_register`, the same on every renderer that draws the scene), or with
/// tilegraph's own shaders again (TG_ENGINE_MATERIAL_NONE). Applies at the renderers' next
/// record; a renderer without that engine material refuses to record (TG_STATUS_INVALID_ARGUMENT
/// naming both).
#[no_mangle]
pub extern "C" fn tg_scene_set_engine_material(
    scene: TgScene,
    material_index: u32,
    engine_material: u32,
) -> TgStatus {
    boundary("tg_scene_set_engine_material", || {
        let engine = (engine_material != TG_ENGINE_MATERIAL_NONE).then_some(engine_material);
        registry::with_mut(scene.raw, Kind::Scene, "scene", |s: &mut Scene| {
            Ok(s.set_engine_material(MaterialId(material_index), engine)?)
        })
    })
}

/// The number of the scene's materials.
///
/// # Safety
/// `out_count` is writable.
#[no_mangle]
pub unsafe extern "C" fn tg_scene_material_count(scene: TgScene, out_count: *mut u32) -> TgStatus {
    boundary("tg_scene_material_count", || {
        // SAFETY: the caller's contract.
        let out_count = unsafe { out(out_count, "out_count") }?;
        *out_count = registry::with(scene.raw, Kind::Scene, "scene", |s: &Scene| {
            Ok(s.materials().len() as u32)
        })?;
        Ok(())
    })
}

/// Scene material `material_index` as a TgMaterial (its class, colour, cutoff, sides) and the
/// engine material that draws it (TG_ENGINE_MATERIAL_NONE: tilegraph's shaders).
///
/// # Safety
/// `out_material` is writable; `out_engine_material` writable or null.
#[no_mangle]
pub unsafe extern "C" fn tg_scene_material(
    scene: TgScene,
    material_index: u32,
    out_material: *mut TgMaterial,
    out_engine_material: *mut u32,
) -> TgStatus {
    boundary("tg_scene_material", || {
        // SAFETY: the caller's contract.
        let out_material = unsafe { out(out_material, "out_material") }?;
        registry::with(scene.raw, Kind::Scene, "scene", |s: &Scene| {
            let count = s.materials().len();
            let m = s.material(MaterialId(material_index)).ok_or_else(|| {
                Failure::invalid(format!(
                    "material {material_index} is past the scene's {count}"
                ))
            })?;
            *out_material = material_desc(m);
            if !out_engine_material.is_null() {
                // SAFETY: the caller's contract.
                unsafe {
                    *out(out_engine_material, "out_engine_material")? =
                        m.engine_material.unwrap_or(TG_ENGINE_MATERIAL_NONE)
                };
            }
            Ok(())
        })
    })
}
