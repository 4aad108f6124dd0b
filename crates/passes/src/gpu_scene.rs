//! The scene on the GPU: static geometry and tables uploaded once, per-frame data (camera
//! uniforms, camera-relative instance records, the draw list) in one set of buffers per frame in
//! flight, written in place in the profile's streaming memory type (seed 001: no staging copy
//! for data the CPU rewrites every frame).

use ash::vk;
use bytemuck::{Pod, Zeroable};
use glam::{DVec3, Mat4, Vec3};
use tilegraph_profile::MemoryUse;
use tilegraph_scene::{DepthConvention, GpuInstance, Scene};
use tilegraph_vk::ash;
use tilegraph_vk::pipeline::{allocate_set, create_set_layout, write_buffer_set};
use tilegraph_vk::{Buffer, Context, VkError};

use crate::draws::DrawList;

/// `Frame` uniform block of `shaders/common/scene.glsl` (std140, 208 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct FrameUniforms {
    pub view_proj: [[f32; 4]; 4],
    pub light_dir: [f32; 4],
    pub light_color: [f32; 4],
    /// x: heavy ALU iterations, y: visbuf instance-id bits, z/w: viewport px.
    pub params: [u32; 4],
    /// xy: viewport size, zw: its reciprocal.
    pub viewport: [f32; 4],
    pub inv_view_proj: [[f32; 4]; 4],
    /// x: depth of the near plane, y: a depth strictly between near and far.
    pub depth_params: [f32; 4],
}

/// Per-frame shading parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lighting {
    /// Unit direction towards the light (world space).
    pub direction: Vec3,
    pub color: Vec3,
    pub ambient: f32,
    /// Iterations of the heavy-material ALU loop (0 = plain Lambert).
    pub heavy_iterations: u32,
}

impl Default for Lighting {
    fn default() -> Self {
        Lighting {
            direction: Vec3::new(0.4, 0.8, 0.3).normalize(),
            color: Vec3::splat(0.85),
            ambient: 0.2,
            heavy_iterations: 0,
        }
    }
}

impl FrameUniforms {
    pub fn new(
        view_proj: Mat4,
        convention: DepthConvention,
        extent: (u32, u32),
        lighting: &Lighting,
        visbuf_instance_bits: u32,
    ) -> Self {
        let (w, h) = (extent.0.max(1) as f32, extent.1.max(1) as f32);
        let near = match convention {
            DepthConvention::Reverse => 1.0,
            DepthConvention::Standard => 0.0,
        };
        FrameUniforms {
            view_proj: view_proj.to_cols_array_2d(),
            light_dir: lighting
                .direction
                .normalize_or_zero()
                .extend(lighting.ambient)
                .to_array(),
            light_color: lighting.color.extend(1.0).to_array(),
            params: [
                lighting.heavy_iterations,
                visbuf_instance_bits,
                extent.0,
                extent.1,
            ],
            viewport: [w, h, 1.0 / w, 1.0 / h],
            inv_view_proj: view_proj.inverse().to_cols_array_2d(),
            depth_params: [near, 0.5, 0.0, 0.0],
        }
    }
}

/// Bits of the visibility-buffer id given to the instance index: enough for every instance with
/// the all-ones value left free, the rest for the triangle. `None` when the largest mesh's
/// triangles do not fit in what is left.
pub fn visbuf_instance_bits(instances: usize, max_triangles_per_mesh: u32) -> Option<u32> {
    let needed = usize::BITS - instances.leading_zeros(); // values 0..=instances need this many
    let instance_bits = needed.max(1);
    let tri_bits = 32u32.checked_sub(instance_bits)?;
    let fits = tri_bits >= 32 || u64::from(max_triangles_per_mesh) <= (1u64 << tri_bits);
    fits.then_some(instance_bits)
}

struct FrameBuffers {
    uniforms: Buffer,
    instances: Buffer,
    draw_list: Buffer,
    /// `Counters` of `forward_count.frag`: fragments shaded per material class.
    counters: Buffer,
    set: vk::DescriptorSet,
    /// Set 0 for GPU-culled draws (binding 2 = the culling shader's draw list).
    culled_set: Option<vk::DescriptorSet>,
}

/// Everything the scene passes bind: set 0 of `scene.glsl`.
pub struct GpuScene {
    pub vertices: Buffer,
    pub indices: Buffer,
    meshes: Buffer,
    materials: Buffer,
    frames: Vec<FrameBuffers>,
    pub set_layout: vk::DescriptorSetLayout,
    pool: vk::DescriptorPool,
    instance_count: usize,
    scratch: Vec<GpuInstance>,
}

pub(crate) fn upload(
    ctx: &Context,
    name: &str,
    bytes: &[u8],
    usage: vk::BufferUsageFlags,
) -> Result<Buffer, VkError> {
    let size = (bytes.len() as u64).max(4);
    let mut buffer = ctx.create_buffer(
        name,
        size,
        usage | vk::BufferUsageFlags::TRANSFER_DST,
        MemoryUse::StaticGeometry,
    )?;
    if buffer.mapped().is_some() {
        return match ctx.write_mapped(&mut buffer, 0, bytes) {
            Ok(()) => Ok(buffer),
            Err(e) => {
                ctx.destroy_buffer(buffer);
                Err(e)
            }
        };
    }
    let mut staging = match ctx.create_buffer(
        &format!("{name} staging"),
        size,
        vk::BufferUsageFlags::TRANSFER_SRC,
        MemoryUse::Staging,
    ) {
        Ok(s) => s,
        Err(e) => {
            ctx.destroy_buffer(buffer);
            return Err(e);
        }
    };
    let copied = match ctx.write_mapped(&mut staging, 0, bytes) {
        Ok(()) => {
            ctx.submit_and_wait(|cb| {
                let region = vk::BufferCopy {
                    src_offset: 0,
                    dst_offset: 0,
                    size,
                };
                // SAFETY: both buffers are live and at least `size` bytes.
                unsafe {
                    ctx.device
                        .cmd_copy_buffer(cb, staging.raw, buffer.raw, &[region])
                };
                Ok(())
            })
        }
        Err(e) => Err(e),
    };
    ctx.destroy_buffer(staging);
    match copied {
        Ok(()) => Ok(buffer),
        Err(e) => {
            ctx.destroy_buffer(buffer);
            Err(e)
        }
    }
}

impl GpuScene {
    /// Uploads the scene and creates `frames_in_flight` sets of per-frame buffers.
    pub fn new(ctx: &Context, scene: &Scene, frames_in_flight: usize) -> Result<Self, VkError> {
        let storage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let vertices = upload(
            ctx,
            "scene vertices",
            bytemuck::cast_slice(scene.vertices()),
            vk::BufferUsageFlags::VERTEX_BUFFER | storage,
        )?;
        let indices = upload(
            ctx,
            "scene indices",
            bytemuck::cast_slice(scene.indices()),
            vk::BufferUsageFlags::INDEX_BUFFER | storage,
        )?;
        let meshes = upload(
            ctx,
            "scene meshes",
            bytemuck::cast_slice(&scene.gpu_meshes()),
            storage,
        )?;
        let materials = upload(
            ctx,
            "scene materials",
            bytemuck::cast_slice(&scene.gpu_materials()),
            storage,
        )?;
        let all = vk::ShaderStageFlags::VERTEX
            | vk::ShaderStageFlags::FRAGMENT
            | vk::ShaderStageFlags::COMPUTE;
        let ssbo = vk::DescriptorType::STORAGE_BUFFER;
        let set_layout = create_set_layout(
            ctx,
            &[
                (0, vk::DescriptorType::UNIFORM_BUFFER, all),
                (1, ssbo, all),
                (2, ssbo, all),
                (3, ssbo, all),
                (4, ssbo, all),
                (5, ssbo, all),
                (6, ssbo, all),
                (7, ssbo, all),
            ],
        )?;
        let n = frames_in_flight.max(1) as u32;
        let sizes = [
            vk::DescriptorPoolSize {
                ty: vk::DescriptorType::UNIFORM_BUFFER,
                descriptor_count: 2 * n,
            },
            vk::DescriptorPoolSize {
                ty: ssbo,
                descriptor_count: 2 * 7 * n,
            },
        ];
        let pool_info = vk::DescriptorPoolCreateInfo::default()
            .max_sets(2 * n)
            .pool_sizes(&sizes);
        // SAFETY: valid create info.
        let pool = unsafe { ctx.device.create_descriptor_pool(&pool_info, None) }
            .map_err(|r| VkError::call("vkCreateDescriptorPool", r))?;
        let mut gs = GpuScene {
            vertices,
            indices,
            meshes,
            materials,
            frames: Vec::new(),
            set_layout,
            pool,
            instance_count: scene.instances().len(),
            scratch: Vec::new(),
        };
        for i in 0..n {
            let fb = gs.frame_buffers(ctx, i)?;
            gs.frames.push(fb);
        }
        Ok(gs)
    }

    fn frame_buffers(&self, ctx: &Context, i: u32) -> Result<FrameBuffers, VkError> {
        let count = self.instance_count.max(1) as u64;
        let uniforms = ctx.create_buffer(
            &format!("frame uniforms[{i}]"),
            std::mem::size_of::<FrameUniforms>() as u64,
            vk::BufferUsageFlags::UNIFORM_BUFFER,
            MemoryUse::Streaming,
        )?;
        let instances = ctx.create_buffer(
            &format!("instances[{i}]"),
            count * std::mem::size_of::<GpuInstance>() as u64,
            vk::BufferUsageFlags::STORAGE_BUFFER,
            MemoryUse::Streaming,
        )?;
        let draw_list = ctx.create_buffer(
            &format!("draw list[{i}]"),
            count * 4,
            vk::BufferUsageFlags::STORAGE_BUFFER,
            MemoryUse::Streaming,
        )?;
        let counters = ctx.create_buffer(
            &format!("fragment counters[{i}]"),
            16,
            vk::BufferUsageFlags::STORAGE_BUFFER,
            MemoryUse::Readback,
        )?;
        let set = self.scene_set(
            ctx,
            [uniforms.raw, instances.raw, draw_list.raw, counters.raw],
        )?;
        Ok(FrameBuffers {
            uniforms,
            instances,
            draw_list,
            counters,
            set,
            culled_set: None,
        })
    }

    /// Allocates and writes a set 0 over `[uniforms, instances, draw list, counters]` and the
    /// scene's static buffers.
    fn scene_set(
        &self,
        ctx: &Context,
        per_frame: [vk::Buffer; 4],
    ) -> Result<vk::DescriptorSet, VkError> {
        // The pool holds two sets per frame slot (plain and culled).
        let set = allocate_set(ctx, self.pool, self.set_layout)?;
        let [uniforms, instances, draw_list, counters] = per_frame;
        let ssbo = vk::DescriptorType::STORAGE_BUFFER;
        write_buffer_set(
            ctx,
            set,
            &[
                (0, vk::DescriptorType::UNIFORM_BUFFER, uniforms),
                (1, ssbo, instances),
                (2, ssbo, draw_list),
                (3, ssbo, self.meshes.raw),
                (4, ssbo, self.materials.raw),
                (5, ssbo, self.vertices.raw),
                (6, ssbo, self.indices.raw),
                (7, ssbo, counters),
            ],
        );
        Ok(set)
    }

    /// Creates, per frame slot, the set that GPU-culled draws bind: the same as the plain one
    /// but with the draw list the culling shader writes (`draw_ids`).
    pub fn add_culled_sets(&mut self, ctx: &Context, draw_ids: vk::Buffer) -> Result<(), VkError> {
        for i in 0..self.frames.len() {
            let f = &self.frames[i];
            let set = self.scene_set(
                ctx,
                [f.uniforms.raw, f.instances.raw, draw_ids, f.counters.raw],
            )?;
            self.frames[i].culled_set = Some(set);
        }
        Ok(())
    }

    /// The culled-draw set of a frame slot (after [`Self::add_culled_sets`]).
    pub fn culled_set(&self, slot: usize) -> Option<vk::DescriptorSet> {
        self.frames.get(slot).and_then(|f| f.culled_set)
    }

    /// Writes this frame's uniforms, camera-relative instances and draw list into `slot`'s
    /// buffers (the caller guarantees the GPU finished the slot's previous frame).
    pub fn write_frame(
        &mut self,
        ctx: &Context,
        slot: usize,
        scene: &Scene,
        eye: DVec3,
        uniforms: &FrameUniforms,
        draws: &DrawList,
    ) -> Result<(), VkError> {
        scene.write_gpu_instances(eye, &mut self.scratch);
        let bad = |what: &str| VkError::Invalid {
            what: what.to_string(),
            reason: "per-frame buffer is not host-visible or too small".into(),
        };
        let f = self.frames.get_mut(slot).ok_or_else(|| bad("frame slot"))?;
        ctx.write_mapped(&mut f.uniforms, 0, bytemuck::bytes_of(uniforms))?;
        ctx.write_mapped(&mut f.instances, 0, bytemuck::cast_slice(&self.scratch))?;
        ctx.write_mapped(&mut f.draw_list, 0, bytemuck::cast_slice(&draws.instances))?;
        ctx.write_mapped(&mut f.counters, 0, &[0u8; 16])?;
        Ok(())
    }

    /// Fragments shaded per material class (opaque, alpha-tested, blended) by the frame last
    /// recorded into `slot`, when it counted them (`forward_count.frag`). Call after the frame
    /// completed.
    pub fn fragment_counts(&self, ctx: &Context, slot: usize) -> Result<[u32; 3], VkError> {
        let f = self.frames.get(slot).ok_or_else(|| VkError::Invalid {
            what: "frame slot".into(),
            reason: format!("{slot} out of range"),
        })?;
        ctx.invalidate_mapped(&f.counters)?;
        let m = f.counters.mapped().ok_or_else(|| VkError::Invalid {
            what: "fragment counters".into(),
            reason: "not host-visible".into(),
        })?;
        let word =
            |i: usize| u32::from_le_bytes([m[4 * i], m[4 * i + 1], m[4 * i + 2], m[4 * i + 3]]);
        Ok([word(0), word(1), word(2)])
    }

    /// The descriptor set (set 0) of a frame slot.
    pub fn set(&self, slot: usize) -> Option<vk::DescriptorSet> {
        self.frames.get(slot).map(|f| f.set)
    }

    pub fn destroy(self, ctx: &Context) {
        for f in self.frames {
            ctx.destroy_buffer(f.uniforms);
            ctx.destroy_buffer(f.instances);
            ctx.destroy_buffer(f.draw_list);
            ctx.destroy_buffer(f.counters);
        }
        // SAFETY: the caller waited for the GPU; sets are freed with the pool.
        unsafe {
            ctx.device.destroy_descriptor_pool(self.pool, None);
            ctx.device
                .destroy_descriptor_set_layout(self.set_layout, None);
        }
        ctx.destroy_buffer(self.vertices);
        ctx.destroy_buffer(self.indices);
        ctx.destroy_buffer(self.meshes);
        ctx.destroy_buffer(self.materials);
    }
}
