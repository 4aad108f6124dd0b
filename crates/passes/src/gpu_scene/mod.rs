//! The scene on the GPU.
//!
//! **Per frame slot**, in the profile's streaming memory type, written in place (seed 001: no
//! staging copy for data the CPU rewrites): the camera uniforms; one record per instance slot
//! ([`GpuInstance`], world space, split high + low: the shaders make it camera-relative); each
//! instance's draw entry (`order`); the draw lists' entries (the scene's buckets, then this
//! frame's CPU lists); the mesh and material tables. A slot's copies are brought up to date from
//! the scene's journal when the slot is reused — only what changed since that slot's last frame
//! is written — so a frame's CPU work follows what changed, not the scene's size.
//!
//! **Resident**, one copy in the static-geometry memory type: the vertices and indices. A mesh
//! added at run time is copied in at the start of the next frame from a staging buffer of the
//! slot ([`GpuScene::record_upload`], recorded before the frame's passes); when the arrays
//! outgrow the buffers, larger ones take over — the old content copied on the GPU, the old
//! buffers destroyed once the frames that read them are done. Nothing waits.

use ash::vk;
use bytemuck::{Pod, Zeroable};
use glam::{DVec3, Mat4, Vec3};
use tilegraph_cull::shadow::{MAX_CASCADES, MAX_CASTER_PLANES};
use tilegraph_profile::MemoryUse;
use tilegraph_scene::{
    DepthConvention, GpuInstance, GpuMaterial, GpuMesh, Scene, SceneCursor, SplitPoint, DRAW_LISTS,
};
use tilegraph_vk::ash;
use tilegraph_vk::pipeline::{create_set_layout_counted, write_buffer_set};
use tilegraph_vk::{Buffer, Context, VkError};

mod geometry;
pub mod shadow_atlas;
mod slots;
pub mod textures;
mod views;

pub(crate) use geometry::upload;
pub use geometry::GeometryUpload;
use geometry::{grown, upload_sized, Copy, GEOMETRY_USAGE};
use slots::{destroy_slot, SlotBuffers};
use textures::{GpuTextures, TEXTURE_BINDING};
use views::ViewBuffers;

use shadow_atlas::{AtlasDesc, ShadowAtlas, SHADOW_BINDING};

/// `Frame` uniform block of `shaders/common/scene.glsl` (std140, 1904 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
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
    /// The eye's world position split high + low ([`SplitPoint`]; w unused).
    pub eye_high: [f32; 4],
    pub eye_low: [f32; 4],
    /// xyz: the camera's unit view direction.
    pub view_forward: [f32; 4],
    /// The light's cascades ([`crate::shadow::ShadowFrame`]; zero without shadows).
    pub shadow_clip: [[[f32; 4]; 4]; MAX_CASCADES],
    pub shadow_far: [f32; 4],
    pub shadow_texel: [f32; 4],
    /// x: normal offset in texels, y: a cascade's side in texels, z: its reciprocal.
    pub shadow_params: [f32; 4],
    /// x: cascades, y/z: the atlas's columns and rows, w: PCF taps either side.
    pub shadow_info: [u32; 4],
    /// Per cascade, [`MAX_CASTER_PLANES`] caster-culling planes (camera-relative).
    pub caster_planes: [[f32; 4]; MAX_CASCADES * MAX_CASTER_PLANES],
    pub caster_counts: [u32; 4],
    /// Per cascade: how low (towards the light, camera-relative) a caster's shadow reaches,
    /// and what a lookup reaches past a receiver (`receivers-hiz`).
    pub caster_floor: [f32; 4],
    pub caster_reach: [f32; 4],
    /// x: texels each pixel reads at random ([`Lighting::random_reads`]); y: their weight in
    /// the colour, 0 (a uniform the shader cannot see is 0, so the reads are made).
    pub material_work: [u32; 4],
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
    /// Texels each pixel reads at random places of random textures of the scene, level 0 (0 =
    /// none): a memory-bound material (seed 000's "memory bound" test). Like the ALU loop it
    /// leaves the image as it is.
    pub random_reads: u32,
}

impl Default for Lighting {
    fn default() -> Self {
        Lighting {
            direction: Vec3::new(0.4, 0.8, 0.3).normalize(),
            color: Vec3::splat(0.85),
            ambient: 0.2,
            heavy_iterations: 0,
            random_reads: 0,
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
        eye: DVec3,
    ) -> Self {
        let (w, h) = (extent.0.max(1) as f32, extent.1.max(1) as f32);
        let near = match convention {
            DepthConvention::Reverse => 1.0,
            DepthConvention::Standard => 0.0,
        };
        let eye = SplitPoint::new(eye);
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
            eye_high: eye.high.extend(0.0).to_array(),
            eye_low: eye.low.extend(0.0).to_array(),
            material_work: [lighting.random_reads, 0, 0, 0],
            ..Zeroable::zeroed()
        }
    }
}

/// Bits of the visibility-buffer id given to the instance index: enough for every instance slot
/// with the all-ones value left free, the rest for the triangle. `None` when the largest mesh's
/// triangles do not fit in what is left.
pub fn visbuf_instance_bits(instances: usize, max_triangles_per_mesh: u32) -> Option<u32> {
    let needed = usize::BITS - instances.leading_zeros(); // values 0..=instances need this many
    let instance_bits = needed.max(1);
    let tri_bits = 32u32.checked_sub(instance_bits)?;
    let fits = tri_bits >= 32 || u64::from(max_triangles_per_mesh) <= (1u64 << tri_bits);
    fits.then_some(instance_bits)
}

/// An entry of `order` for an instance in no GPU list (hidden, blended, a free slot).
pub const NO_ENTRY: u32 = u32::MAX;

/// How much of a scene a renderer's buffers hold: instance slots and the draw lists' stride.
/// A scene that outgrows it needs new buffers ([`crate::SceneRenderer`] makes them).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Capacity {
    pub instances: u32,
    pub stride: u32,
    /// Draw buckets (the most draw groups, hence indirect commands, a list can hold).
    pub groups: u32,
    /// The views a frame renders (each has a CPU list of its own in the entry buffer).
    pub views: u32,
}

impl Capacity {
    /// Room for `scene` and for at least `instances` instance slots, rounded up to powers of
    /// two (a growing scene outgrows it a logarithmic number of times).
    pub fn for_scene(scene: &Scene, instances: u32) -> Self {
        let round = |n: u32| n.max(64).checked_next_power_of_two().unwrap_or(u32::MAX);
        let slots = u32::try_from(scene.instances().len()).unwrap_or(u32::MAX);
        let stride = scene.buckets().stride();
        let buckets = u32::try_from(scene.buckets().bucket_count()).unwrap_or(u32::MAX);
        Capacity {
            instances: round(slots.max(instances)),
            // A list may hold every instance slot: then no growth of the scene's buckets
            // outgrows the stride before its instances outgrow the slots.
            stride: round(stride.max(slots.max(instances).saturating_add(64))),
            groups: round(buckets),
            views: 1,
        }
    }

    /// This capacity for a frame of `views` views (at least one).
    pub fn with_views(self, views: usize) -> Self {
        Capacity {
            views: u32::try_from(views.max(1)).unwrap_or(u32::MAX),
            ..self
        }
    }

    /// Whether `scene` fits.
    pub fn holds(&self, scene: &Scene) -> bool {
        scene.instances().len() as u64 <= u64::from(self.instances)
            && scene.buckets().stride() <= self.stride
            && scene.buckets().bucket_count() as u64 <= u64::from(self.groups)
    }

    /// The largest storage buffer a renderer of this capacity binds, in bytes: what must fit
    /// the device's `maxStorageBufferRange` (2^27 on many phones and on lavapipe).
    /// `commands_per_group`: 1, or with levels of detail a command per group and level.
    pub fn largest_storage_buffer(&self, commands_per_group: u32) -> u64 {
        let lists = 2 * DRAW_LISTS as u64;
        let per_group = u64::from(commands_per_group.max(1));
        [
            u64::from(self.instances) * std::mem::size_of::<GpuInstance>() as u64,
            self.entries() * 4,
            u64::from(self.stride) * lists * 4,
            u64::from(self.groups) * per_group * lists * 20,
            // Survivors: a count per instance, phase and level.
            2 * u64::from(self.instances) * per_group * 4,
        ]
        .into_iter()
        .max()
        .unwrap_or(0)
    }

    /// The first entry of the frame's CPU lists (after the scene's lists).
    pub fn cpu_base(&self) -> u32 {
        DRAW_LISTS as u32 * self.stride
    }

    /// The first entry of view `view`'s CPU list (each view has room for every slot).
    pub fn cpu_base_of(&self, view: usize) -> u32 {
        let offset = u64::from(self.instances) * view as u64;
        self.cpu_base()
            .saturating_add(u32::try_from(offset).unwrap_or(u32::MAX))
    }

    /// Entries of a slot's entry buffer: the lists, then room for a CPU list of every slot per
    /// view.
    pub fn entries(&self) -> u64 {
        u64::from(self.cpu_base()) + u64::from(self.instances) * u64::from(self.views.max(1))
    }
}

/// Set 0's cluster runs (visbuf.vert's DrawRuns): where a draw list's cluster commands begin
/// and each one's first triangle in its mesh.
pub const RUNS_BINDING: u32 = 10;

/// Everything the scene passes bind: set 0 of `scene.glsl`, one per view and frame slot.
///
/// The scene's data (geometry, textures, records, lists, tables) is one copy shared by every
/// view; a view has its own camera uniforms, fragment counters, shadow atlas, CPU list region
/// and culled draw list, hence its own sets. The passes of a view bind the sets of the
/// **current** view ([`Self::enter_view`]; the renderer makes a pass's view current before
/// it records).
pub struct GpuScene {
    pub vertices: Buffer,
    pub indices: Buffer,
    /// The materials' textures (binding 8), uploaded once.
    pub textures: GpuTextures,
    /// Per view, the light's shadow atlas (binding 9).
    atlases: Vec<ShadowAtlas>,
    frames: Vec<SlotBuffers>,
    pub set_layout: vk::DescriptorSetLayout,
    pool: vk::DescriptorPool,
    capacity: Capacity,
    /// Per view, the culling shader's draw list, bound by its culled sets, and with cluster
    /// culling its runs' first triangles (`ClusterStage::run_triangles`).
    culled_draw_ids: Vec<Option<(vk::Buffer, Option<vk::Buffer>)>>,
    /// Bound as a set's runs where its draws have none (visbuf.vert's DrawRuns: where the
    /// cluster commands begin, past every draw-list slot).
    no_runs: Buffer,
    /// The view whose sets [`Self::set`] and [`Self::culled_set`] give.
    view: usize,
    /// The scene as the resident geometry holds it.
    geometry_cursor: Option<SceneCursor>,
    /// Bumped whenever the geometry buffers are replaced.
    geometry_serial: u64,
    /// Per view, the indices kept free at the end of the index buffer for per-triangle
    /// culling's packed triangles ([`Self::reserve_index_tail`]), one region after another.
    index_tails: Vec<u64>,
    /// Copies for the next frame's upload (kept: no allocation per frame).
    copies: Vec<Copy>,
    /// Bytes staged this frame (CPU side, copied into the slot's staging buffer).
    staged: Vec<u8>,
    /// Buffers replaced, and the frame count from which they may go.
    retired: Vec<(Buffer, u64)>,
    /// Frames written ([`Self::write_frame`] calls).
    frames_written: u64,
    /// Dedup of a frame's writes: the frame that last wrote each instance slot and entry.
    record_stamps: Vec<u64>,
    order_stamps: Vec<u64>,
    entry_stamps: Vec<u64>,
}

/// Creates `size` bytes for `use_`; names it.
fn buffer(
    ctx: &Context,
    name: &str,
    size: u64,
    usage: vk::BufferUsageFlags,
    use_: MemoryUse,
) -> Result<Buffer, VkError> {
    ctx.create_buffer(name, size.max(16), usage, use_)
}

/// A buffer spec: name, bytes, usage, memory.
pub(crate) type BufferSpec = (&'static str, u64, vk::BufferUsageFlags, MemoryUse);

/// A frame slot's scene buffers for `capacity` and tables of `meshes` and `materials` (what
/// [`GpuScene`] makes, and [`crate::scene_memory`] counts).
pub(crate) fn slot_specs(c: Capacity, meshes: usize, materials: usize) -> [BufferSpec; 5] {
    let storage = vk::BufferUsageFlags::STORAGE_BUFFER;
    let streaming = MemoryUse::Streaming;
    [
        (
            "instance records",
            u64::from(c.instances) * std::mem::size_of::<GpuInstance>() as u64,
            storage,
            streaming,
        ),
        (
            "instance entries",
            u64::from(c.instances) * 4,
            storage,
            streaming,
        ),
        ("draw entries", c.entries() * 4, storage, streaming),
        (
            "meshes",
            grown(meshes as u64) * std::mem::size_of::<GpuMesh>() as u64,
            storage,
            streaming,
        ),
        (
            "materials",
            grown(materials as u64) * std::mem::size_of::<GpuMaterial>() as u64,
            storage,
            streaming,
        ),
    ]
}

/// A view's buffers in a frame slot: its camera uniforms and its fragment counters.
pub(crate) fn view_specs() -> [BufferSpec; 2] {
    [
        (
            "frame uniforms",
            std::mem::size_of::<FrameUniforms>() as u64,
            vk::BufferUsageFlags::UNIFORM_BUFFER,
            MemoryUse::Streaming,
        ),
        (
            "fragment counters",
            16,
            vk::BufferUsageFlags::STORAGE_BUFFER,
            MemoryUse::Readback,
        ),
    ]
}

/// The resident vertex and index buffers' sizes for `scene` (room to grow).
pub(crate) fn geometry_sizes(scene: &Scene) -> [u64; 2] {
    [
        grown(scene.vertices().len() as u64) * 32,
        grown(scene.indices().len() as u64) * 4,
    ]
}

impl GpuScene {
    /// Uploads the scene's geometry and textures (bound as `textures` asks, where the device
    /// can) and creates `frames_in_flight` sets of per-slot buffers with room for `capacity`,
    /// for views with the shadow atlases `atlases` (one per view; `capacity.views` of them).
    pub fn new(
        ctx: &Context,
        scene: &Scene,
        frames_in_flight: usize,
        capacity: Capacity,
        textures: tilegraph_profile::TexturePolicy,
        atlases: &[AtlasDesc],
    ) -> Result<Self, VkError> {
        debug_assert_eq!(atlases.len(), capacity.views.max(1) as usize);
        let [vertex_bytes, index_bytes] = geometry_sizes(scene);
        let vertices = upload_sized(
            ctx,
            "scene vertices",
            bytemuck::cast_slice(scene.vertices()),
            vertex_bytes,
            vk::BufferUsageFlags::VERTEX_BUFFER | GEOMETRY_USAGE,
        )?;
        let indices = match upload_sized(
            ctx,
            "scene indices",
            bytemuck::cast_slice(scene.indices()),
            index_bytes,
            vk::BufferUsageFlags::INDEX_BUFFER | GEOMETRY_USAGE,
        ) {
            Ok(b) => b,
            Err(e) => {
                ctx.destroy_buffer(vertices);
                return Err(e);
            }
        };
        let no_runs = match upload(
            ctx,
            "no cluster runs",
            &u32::MAX.to_le_bytes(),
            vk::BufferUsageFlags::STORAGE_BUFFER,
        ) {
            Ok(b) => b,
            Err(e) => {
                ctx.destroy_buffer(vertices);
                ctx.destroy_buffer(indices);
                return Err(e);
            }
        };
        let textures = match GpuTextures::new(ctx, scene, textures) {
            Ok(t) => t,
            Err(e) => {
                for b in [vertices, indices, no_runs] {
                    ctx.destroy_buffer(b);
                }
                return Err(e);
            }
        };
        let slots = textures.slot_count();
        let mut gs = GpuScene {
            vertices,
            indices,
            textures,
            atlases: Vec::with_capacity(atlases.len()),
            frames: Vec::new(),
            set_layout: vk::DescriptorSetLayout::null(),
            pool: vk::DescriptorPool::null(),
            capacity,
            culled_draw_ids: vec![None; atlases.len()],
            no_runs,
            view: 0,
            geometry_cursor: Some(scene.cursor()),
            geometry_serial: 0,
            index_tails: Vec::new(),
            copies: Vec::new(),
            staged: Vec::new(),
            retired: Vec::new(),
            frames_written: 0,
            record_stamps: vec![0; capacity.instances as usize],
            order_stamps: vec![0; capacity.instances as usize],
            entry_stamps: vec![0; capacity.cpu_base() as usize],
        };
        if let Err(e) = gs.create_sets(ctx, scene, frames_in_flight, atlases, slots) {
            gs.destroy(ctx);
            return Err(e);
        }
        Ok(gs)
    }

    /// The atlases, the set layout, the pool, and every slot's buffers and sets.
    fn create_sets(
        &mut self,
        ctx: &Context,
        scene: &Scene,
        frames_in_flight: usize,
        atlases: &[AtlasDesc],
        texture_slots: u32,
    ) -> Result<(), VkError> {
        for desc in atlases {
            self.atlases.push(ShadowAtlas::new(ctx, *desc)?);
        }
        let all = vk::ShaderStageFlags::VERTEX
            | vk::ShaderStageFlags::FRAGMENT
            | vk::ShaderStageFlags::COMPUTE;
        let ssbo = vk::DescriptorType::STORAGE_BUFFER;
        let sampler = vk::DescriptorType::COMBINED_IMAGE_SAMPLER;
        let mut bindings = vec![(0, vk::DescriptorType::UNIFORM_BUFFER, all, 1)];
        bindings.extend((1..=7).map(|b| (b, ssbo, all, 1)));
        bindings.push((RUNS_BINDING, ssbo, vk::ShaderStageFlags::VERTEX, 1));
        bindings.push((
            TEXTURE_BINDING,
            sampler,
            vk::ShaderStageFlags::FRAGMENT,
            texture_slots,
        ));
        bindings.push((SHADOW_BINDING, sampler, vk::ShaderStageFlags::FRAGMENT, 1));
        self.set_layout = create_set_layout_counted(ctx, &bindings)?;
        // Two sets (plain and culled) per view and slot.
        let n = 2 * frames_in_flight.max(1) as u32 * atlases.len().max(1) as u32;
        let sizes = [
            vk::DescriptorPoolSize {
                ty: vk::DescriptorType::UNIFORM_BUFFER,
                descriptor_count: n,
            },
            vk::DescriptorPoolSize {
                ty: ssbo,
                descriptor_count: 8 * n,
            },
            vk::DescriptorPoolSize {
                ty: sampler,
                descriptor_count: (texture_slots + 1) * n,
            },
        ];
        let pool_info = vk::DescriptorPoolCreateInfo::default()
            .max_sets(n)
            .pool_sizes(&sizes);
        // SAFETY: valid create info.
        self.pool = unsafe { ctx.device.create_descriptor_pool(&pool_info, None) }
            .map_err(|r| VkError::call("vkCreateDescriptorPool", r))?;
        for i in 0..frames_in_flight.max(1) as u32 {
            let slot = self.slot_buffers(ctx, i, scene)?;
            self.frames.push(slot);
        }
        Ok(())
    }

    fn slot_buffers(&self, ctx: &Context, i: u32, scene: &Scene) -> Result<SlotBuffers, VkError> {
        let specs = slot_specs(self.capacity, scene.meshes().len(), scene.materials().len());
        let mut made: Vec<Buffer> = Vec::with_capacity(specs.len());
        for (name, size, usage, use_) in specs {
            match buffer(ctx, &format!("{name}[{i}]"), size, usage, use_) {
                Ok(b) => made.push(b),
                Err(e) => {
                    for b in made {
                        ctx.destroy_buffer(b);
                    }
                    return Err(e);
                }
            }
        }
        let mut it = made.into_iter();
        let (Some(records), Some(order), Some(entries), Some(meshes), Some(materials)) =
            (it.next(), it.next(), it.next(), it.next(), it.next())
        else {
            return Err(VkError::Invalid {
                what: "scene buffers".into(),
                reason: "not all made".into(),
            });
        };
        let mut slot = SlotBuffers {
            records,
            order,
            entries,
            meshes,
            materials,
            views: Vec::with_capacity(self.atlases.len()),
            staging: None,
            cursor: None,
            geometry_serial: self.geometry_serial,
        };
        for view in 0..self.atlases.len() {
            match self.view_buffers(ctx, i, view) {
                Ok(v) => slot.views.push(v),
                Err(e) => {
                    destroy_slot(ctx, slot);
                    return Err(e);
                }
            }
        }
        self.write_sets(ctx, &slot);
        Ok(slot)
    }

    /// Writes a slot's sets, every view's, over its buffers and the resident geometry.
    fn write_sets(&self, ctx: &Context, slot: &SlotBuffers) {
        let ssbo = vk::DescriptorType::STORAGE_BUFFER;
        for (view, v) in slot.views.iter().enumerate() {
            let culled = self.culled_draw_ids.get(view).copied().flatten();
            let no_runs = self.no_runs.raw;
            let sets = [(v.set, (slot.entries.raw, no_runs))].into_iter().chain(
                v.culled_set
                    .zip(culled.map(|(ids, runs)| (ids, runs.unwrap_or(no_runs)))),
            );
            // Every view has its atlas (made with the views).
            let Some(atlas) = self.atlases.get(view) else {
                continue;
            };
            let atlas = [atlas.descriptor()];
            for (set, (draw_list, runs)) in sets {
                write_buffer_set(
                    ctx,
                    set,
                    &[
                        (0, vk::DescriptorType::UNIFORM_BUFFER, v.uniforms.raw),
                        (1, ssbo, slot.records.raw),
                        (2, ssbo, draw_list),
                        (3, ssbo, slot.meshes.raw),
                        (4, ssbo, slot.materials.raw),
                        (5, ssbo, self.vertices.raw),
                        (6, ssbo, self.indices.raw),
                        (7, ssbo, v.counters.raw),
                        (RUNS_BINDING, ssbo, runs),
                    ],
                );
                let images = self.textures.image_infos();
                let write = [
                    vk::WriteDescriptorSet::default()
                        .dst_set(set)
                        .dst_binding(TEXTURE_BINDING)
                        .descriptor_type(vk::DescriptorType::COMBINED_IMAGE_SAMPLER)
                        .image_info(&images),
                    vk::WriteDescriptorSet::default()
                        .dst_set(set)
                        .dst_binding(SHADOW_BINDING)
                        .descriptor_type(vk::DescriptorType::COMBINED_IMAGE_SAMPLER)
                        .image_info(&atlas),
                ];
                // SAFETY: live views and samplers; the set is idle (the caller's guarantee).
                unsafe { ctx.device.update_descriptor_sets(&write, &[]) };
            }
        }
    }

    /// The instance entries (`order`) of a frame slot, which the culling shader reads.
    pub fn order(&self, slot: usize) -> Option<vk::Buffer> {
        self.frames.get(slot).map(|f| f.order.raw)
    }

    /// The room the per-slot buffers have.
    pub fn capacity(&self) -> Capacity {
        self.capacity
    }

    /// Brings `slot`'s buffers up to `scene` (what changed since the slot's last frame) and
    /// stages the geometry the scene added since the last frame (the caller guarantees the GPU
    /// finished the slot's previous frame, and records [`Self::record_upload`] before the
    /// frame's passes). Each view's uniforms and CPU list follow ([`Self::write_view`]).
    pub fn write_frame(
        &mut self,
        ctx: &Context,
        slot: usize,
        scene: &Scene,
    ) -> Result<(), VkError> {
        if !self.capacity.holds(scene) {
            return Err(VkError::Invalid {
                what: "scene buffers".into(),
                reason: format!(
                    "scene of {} instance slots and stride {} past the capacity {:?}",
                    scene.instances().len(),
                    scene.buckets().stride(),
                    self.capacity
                ),
            });
        }
        self.frames_written += 1;
        self.destroy_retired(ctx);
        self.sync_geometry(ctx, slot, scene)?;
        self.sync_slot(ctx, slot, scene)
    }
}

impl GpuScene {
    /// The instance entries (`order`) of the frame last written into `slot`, for its first
    /// `instances` slots (tests and tools; call once that frame completed).
    pub fn read_order(
        &self,
        ctx: &Context,
        slot: usize,
        instances: usize,
    ) -> Result<Vec<u32>, VkError> {
        let f = self.frames.get(slot).ok_or_else(|| no_slot(slot))?;
        ctx.invalidate_mapped(&f.order)?;
        let bytes = f.order.mapped().unwrap_or(&[]);
        Ok(bytes
            .chunks_exact(4)
            .take(instances)
            .map(|w| u32::from_le_bytes([w[0], w[1], w[2], w[3]]))
            .collect())
    }

    /// Device memory of the scene on the GPU, in bytes: the resident geometry, and each
    /// slot's records, entries, tables, staging and views' uniforms and counters.
    pub fn memory_bytes(&self) -> u64 {
        let slots: u64 = self
            .frames
            .iter()
            .map(|f| {
                [&f.records, &f.order, &f.entries, &f.meshes, &f.materials]
                    .iter()
                    .map(|b| b.size)
                    .sum::<u64>()
                    + f.views
                        .iter()
                        .map(|v| v.uniforms.size + v.counters.size)
                        .sum::<u64>()
                    + f.staging.as_ref().map_or(0, |s| s.size)
            })
            .sum();
        self.vertices.size + self.indices.size + slots
    }

    pub fn destroy(mut self, ctx: &Context) {
        self.textures.destroy(ctx);
        for a in self.atlases {
            a.destroy(ctx);
        }
        for f in self.frames {
            destroy_slot(ctx, f);
        }
        for (b, _) in self.retired {
            ctx.destroy_buffer(b);
        }
        // SAFETY: the caller waited for the GPU; sets are freed with the pool (a null pool or
        // layout is ignored).
        unsafe {
            ctx.device.destroy_descriptor_pool(self.pool, None);
            ctx.device
                .destroy_descriptor_set_layout(self.set_layout, None);
        }
        ctx.destroy_buffer(self.vertices);
        ctx.destroy_buffer(self.indices);
        ctx.destroy_buffer(self.no_runs);
    }
}

fn no_slot(slot: usize) -> VkError {
    VkError::Invalid {
        what: "frame slot".into(),
        reason: format!("{slot} out of range"),
    }
}
