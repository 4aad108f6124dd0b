//! Hand-built frames for executor tests: the classic mobile frame (depth pre-pass, opaque,
//! transparent, post into an imported target) and the visibility-buffer frame (id write, resolve
//! reading the id as an input attachment), drawn with tiny test shaders so the expected pixels
//! are known exactly.

use std::cell::RefCell;
use std::collections::HashMap;
use std::rc::Rc;

use tilegraph_graph::{
    AccessFlags, ClearColor, ClearDepthStencil, Coverage, Extent2d, Format, GraphBuilder,
    ImageDesc, ImageId, Import, InitialContent, Layout, PassClass, PipelineStages, ResourceId,
    ResourceState,
};
use tilegraph_vk::ash::vk;
use tilegraph_vk::executor::{External, Externals, ImageHandle, PassContext};
use tilegraph_vk::pipeline::{
    allocate_set, create_graphics_pipeline, create_pipeline_layout, create_set_layout, Blend,
    DepthState, GraphicsDesc, RenderTarget, Stage,
};
use tilegraph_vk::{Context, Image, VkError};

pub type Payload = Box<dyn FnMut(&mut PassContext<'_>) -> Result<(), VkError>>;

const QUAD_VS: &[u8] = include_bytes!("../../shaders/spv/test_quad.vert.spv");
const COLOR_FS: &[u8] = include_bytes!("../../shaders/spv/test_color.frag.spv");
const ID_FS: &[u8] = include_bytes!("../../shaders/spv/test_id.frag.spv");
const POST_FS: &[u8] = include_bytes!("../../shaders/spv/test_post_input.frag.spv");
const RESOLVE_FS: &[u8] = include_bytes!("../../shaders/spv/test_resolve_input.frag.spv");

/// Push constants of `shaders/common/test_push.glsl`.
#[repr(C)]
#[derive(Clone, Copy)]
pub struct Push {
    pub rect: [f32; 4],
    pub color: [f32; 4],
    pub depth: f32,
    pub id: u32,
    pub _pad: [u32; 2],
}

impl Push {
    fn bytes(&self) -> &[u8] {
        // SAFETY: plain-old-data repr(C) struct of f32/u32 without padding holes.
        unsafe {
            std::slice::from_raw_parts(
                (self as *const Push).cast::<u8>(),
                std::mem::size_of::<Push>(),
            )
        }
    }
}

#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug)]
pub enum Kind {
    DepthOnly,
    /// Colour with depth EQUAL, no depth writes (after a pre-pass).
    ColorEqual,
    /// Blended colour, depth tested, no writes.
    Blended,
    /// Uint id with depth GREATER and depth writes (the visibility-buffer id pass).
    Id,
    /// Full-screen input-attachment reads.
    Post,
    Resolve,
    /// Flat colour, no depth attachment.
    Flat,
}

/// Pipelines and descriptor sets shared by a frame's payloads, created on first use per
/// (render pass, subpass).
pub struct Kit {
    pub layout: vk::PipelineLayout,
    pub input_layout: vk::PipelineLayout,
    pub set_layout: vk::DescriptorSetLayout,
    pool: vk::DescriptorPool,
    /// By (render pass serial, subpass, kind): handles of destroyed render passes are reused.
    pipelines: HashMap<(u64, u32, Kind), vk::Pipeline>,
    sets: HashMap<(usize, ResourceId), vk::DescriptorSet>,
}

impl Kit {
    pub fn new(ctx: &Context) -> Result<Rc<RefCell<Kit>>, VkError> {
        let push = vk::PushConstantRange {
            stage_flags: vk::ShaderStageFlags::VERTEX | vk::ShaderStageFlags::FRAGMENT,
            offset: 0,
            size: std::mem::size_of::<Push>() as u32,
        };
        let layout = create_pipeline_layout(ctx, &[], Some(push))?;
        let set_layout = create_set_layout(
            ctx,
            &[(
                0,
                vk::DescriptorType::INPUT_ATTACHMENT,
                vk::ShaderStageFlags::FRAGMENT,
            )],
        )?;
        let input_layout = create_pipeline_layout(ctx, &[set_layout], Some(push))?;
        let sizes = [vk::DescriptorPoolSize {
            ty: vk::DescriptorType::INPUT_ATTACHMENT,
            descriptor_count: 64,
        }];
        let info = vk::DescriptorPoolCreateInfo::default()
            .max_sets(64)
            .pool_sizes(&sizes);
        // SAFETY: valid create info.
        let pool = unsafe { ctx.device.create_descriptor_pool(&info, None) }
            .map_err(|r| VkError::call("vkCreateDescriptorPool", r))?;
        Ok(Rc::new(RefCell::new(Kit {
            layout,
            input_layout,
            set_layout,
            pool,
            pipelines: HashMap::new(),
            sets: HashMap::new(),
        })))
    }

    fn pipeline(
        &mut self,
        pc: &PassContext<'_>,
        kind: Kind,
        color_count: u32,
    ) -> Result<vk::Pipeline, VkError> {
        let rp = pc.render_pass.ok_or_else(|| VkError::Invalid {
            what: pc.pass_name.into(),
            reason: "not in a render pass".into(),
        })?;
        if let Some(p) = self.pipelines.get(&(rp.serial, rp.subpass, kind)) {
            return Ok(*p);
        }
        let gt = vk::CompareOp::GREATER;
        let (fs, depth, blend, layout): (Option<&[u8]>, DepthState, Blend, vk::PipelineLayout) =
            match kind {
                Kind::DepthOnly => (
                    None,
                    DepthState {
                        test: true,
                        write: true,
                        compare: gt,
                        bias: 0,
                        slope_bias: 0.0,
                        clamp: false,
                    },
                    Blend::NoColorWrites,
                    self.layout,
                ),
                Kind::ColorEqual => (
                    Some(COLOR_FS),
                    DepthState {
                        test: true,
                        write: false,
                        compare: vk::CompareOp::EQUAL,
                        bias: 0,
                        slope_bias: 0.0,
                        clamp: false,
                    },
                    Blend::Opaque,
                    self.layout,
                ),
                Kind::Blended => (
                    Some(COLOR_FS),
                    DepthState {
                        test: true,
                        write: false,
                        compare: gt,
                        bias: 0,
                        slope_bias: 0.0,
                        clamp: false,
                    },
                    Blend::Alpha,
                    self.layout,
                ),
                Kind::Id => (
                    Some(ID_FS),
                    DepthState {
                        test: true,
                        write: true,
                        compare: gt,
                        bias: 0,
                        slope_bias: 0.0,
                        clamp: false,
                    },
                    Blend::Opaque,
                    self.layout,
                ),
                Kind::Post => (
                    Some(POST_FS),
                    DepthState::OFF,
                    Blend::Opaque,
                    self.input_layout,
                ),
                Kind::Resolve => (
                    Some(RESOLVE_FS),
                    DepthState::OFF,
                    Blend::Opaque,
                    self.input_layout,
                ),
                Kind::Flat => (Some(COLOR_FS), DepthState::OFF, Blend::Opaque, self.layout),
            };
        let p = create_graphics_pipeline(
            pc.ctx,
            &GraphicsDesc {
                name: pc.pass_name,
                vertex: Stage {
                    name: "test_quad.vert",
                    spirv: QUAD_VS,
                    specialization: &[],
                },
                fragment: fs.map(|f| Stage {
                    name: "test.frag",
                    spirv: f,
                    specialization: &[],
                }),
                vertex_layout: None,
                layout,
                target: RenderTarget::Subpass {
                    render_pass: rp.handle,
                    subpass: rp.subpass,
                    color_count,
                },
                depth,
                blend,
                cull: vk::CullModeFlags::NONE,
                samples: vk::SampleCountFlags::TYPE_1,
            },
        )?;
        self.pipelines.insert((rp.serial, rp.subpass, kind), p);
        Ok(p)
    }

    /// The input-attachment set for `image` in this frame slot (updated each frame: the view may
    /// change when the plan is rebuilt).
    fn input_set(
        &mut self,
        pc: &PassContext<'_>,
        image: ResourceId,
    ) -> Result<vk::DescriptorSet, VkError> {
        let key = (pc.frame_slot, image);
        let set = match self.sets.get(&key) {
            Some(s) => *s,
            None => {
                // The pool is sized for the test's sets.
                let s = allocate_set(pc.ctx, self.pool, self.set_layout)?;
                self.sets.insert(key, s);
                s
            }
        };
        let view = pc.image(image)?.view;
        let info = [vk::DescriptorImageInfo {
            sampler: vk::Sampler::null(),
            image_view: view,
            image_layout: vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL,
        }];
        let write = vk::WriteDescriptorSet::default()
            .dst_set(set)
            .dst_binding(0)
            .descriptor_type(vk::DescriptorType::INPUT_ATTACHMENT)
            .image_info(&info);
        // SAFETY: the slot's previous frame finished (executor guarantee), so the set is idle.
        unsafe { pc.ctx.device.update_descriptor_sets(&[write], &[]) };
        Ok(set)
    }

    pub fn destroy(&mut self, ctx: &Context) {
        // SAFETY: the GPU is idle (caller's guarantee).
        unsafe {
            for (_, p) in self.pipelines.drain() {
                ctx.device.destroy_pipeline(p, None);
            }
            ctx.device.destroy_descriptor_pool(self.pool, None);
            ctx.device.destroy_pipeline_layout(self.layout, None);
            ctx.device.destroy_pipeline_layout(self.input_layout, None);
            ctx.device
                .destroy_descriptor_set_layout(self.set_layout, None);
        }
    }
}

/// A quad draw.
#[derive(Clone, Copy)]
pub struct Quad {
    pub rect: [f32; 4],
    pub depth: f32,
    pub color: [f32; 4],
    pub id: u32,
}

fn draw(
    kit: &Rc<RefCell<Kit>>,
    kind: Kind,
    color_count: u32,
    quads: Vec<Quad>,
    input: Option<ResourceId>,
) -> Payload {
    let kit = kit.clone();
    Box::new(move |pc: &mut PassContext<'_>| {
        let mut k = kit.borrow_mut();
        let pipeline = k.pipeline(pc, kind, color_count)?;
        let layout = if input.is_some() {
            k.input_layout
        } else {
            k.layout
        };
        let set = match input {
            Some(i) => Some(k.input_set(pc, i)?),
            None => None,
        };
        pc.set_full_viewport();
        let d = &pc.ctx.device;
        // SAFETY: recording inside the subpass the pipeline was made for.
        unsafe {
            d.cmd_bind_pipeline(pc.cb, vk::PipelineBindPoint::GRAPHICS, pipeline);
            if let Some(s) = set {
                d.cmd_bind_descriptor_sets(
                    pc.cb,
                    vk::PipelineBindPoint::GRAPHICS,
                    layout,
                    0,
                    &[s],
                    &[],
                );
            }
            for q in &quads {
                let push = Push {
                    rect: q.rect,
                    color: q.color,
                    depth: q.depth,
                    id: q.id,
                    _pad: [0; 2],
                };
                d.cmd_push_constants(
                    pc.cb,
                    layout,
                    vk::ShaderStageFlags::VERTEX | vk::ShaderStageFlags::FRAGMENT,
                    0,
                    push.bytes(),
                );
                d.cmd_draw(pc.cb, 6, 1, 0, 0);
            }
        }
        Ok(())
    })
}

/// A full-screen post-process that reads `input` at the same pixel (an input attachment) and
/// writes `1 - rgb` with alpha 1 (`test_post_input.frag`): an engine's own pass.
pub fn post_invert(kit: &Rc<RefCell<Kit>>, input: ImageId) -> Payload {
    let quad = Quad {
        rect: FULL,
        depth: 0.0,
        color: [0.0; 4],
        id: 0,
    };
    draw(kit, Kind::Post, 1, vec![quad], Some(input.0))
}

pub const FULL: [f32; 4] = [-1.0, -1.0, 1.0, 1.0];
pub const LEFT: [f32; 4] = [-1.0, -1.0, 0.0, 1.0];
pub const CENTER: [f32; 4] = [-0.25, -0.25, 0.25, 0.25];

/// The imported target: an RGBA8 image the test creates and reads back; the frame leaves it in
/// TRANSFER_SRC for the readback.
pub fn target(ctx: &Context, w: u32, h: u32) -> Result<(Image, ImageHandle), VkError> {
    let info = vk::ImageCreateInfo::default()
        .image_type(vk::ImageType::TYPE_2D)
        .format(vk::Format::R8G8B8A8_UNORM)
        .extent(vk::Extent3D {
            width: w,
            height: h,
            depth: 1,
        })
        .mip_levels(1)
        .array_layers(1)
        .samples(vk::SampleCountFlags::TYPE_1)
        .tiling(vk::ImageTiling::OPTIMAL)
        .usage(
            vk::ImageUsageFlags::COLOR_ATTACHMENT
                | vk::ImageUsageFlags::TRANSFER_SRC
                | vk::ImageUsageFlags::TRANSFER_DST,
        )
        .initial_layout(vk::ImageLayout::UNDEFINED);
    let image = ctx.create_image("target", &info, tilegraph_profile::MemoryUse::GpuOnly)?;
    let view_info = vk::ImageViewCreateInfo::default()
        .image(image.raw)
        .view_type(vk::ImageViewType::TYPE_2D)
        .format(vk::Format::R8G8B8A8_UNORM)
        .subresource_range(vk::ImageSubresourceRange {
            aspect_mask: vk::ImageAspectFlags::COLOR,
            base_mip_level: 0,
            level_count: 1,
            base_array_layer: 0,
            layer_count: 1,
        });
    // SAFETY: live image.
    let view = unsafe { ctx.device.create_image_view(&view_info, None) }
        .map_err(|r| VkError::call("vkCreateImageView", r))?;
    let handle = ImageHandle {
        raw: image.raw,
        view,
        full_view: view,
        mip_views: Vec::new(),
        format: vk::Format::R8G8B8A8_UNORM,
        extent: vk::Extent2D {
            width: w,
            height: h,
        },
        mip_levels: 1,
        aspect: vk::ImageAspectFlags::COLOR,
    };
    Ok((image, handle))
}

pub fn destroy_target(ctx: &Context, image: Image, handle: ImageHandle) {
    // SAFETY: GPU idle (caller's guarantee).
    unsafe { ctx.device.destroy_image_view(handle.view, None) };
    ctx.destroy_image(image);
}

/// Import description of the target: content discarded, left in TRANSFER_SRC for readback.
pub fn target_import() -> Import {
    Import {
        initial: ResourceState::UNDEFINED,
        content: InitialContent::Discard,
        final_state: ResourceState::image(
            Layout::TransferSrc,
            PipelineStages::COPY,
            AccessFlags::TRANSFER_READ,
        ),
    }
}

pub struct Frame {
    pub graph: GraphBuilder<Payload>,
    pub target: ImageId,
}

/// Depth pre-pass + opaque (EQUAL) + transparent + post (input attachment) into the target.
/// Expected pixels: left half 1 - red, right half 1 - green, centre 1 - (blue over the rest).
pub fn classic_mobile_frame(kit: &Rc<RefCell<Kit>>, w: u32, h: u32) -> Frame {
    let extent = Extent2d::new(w, h);
    let mut g: GraphBuilder<Payload> = GraphBuilder::new();
    let target = g.import_image(
        "backbuffer",
        ImageDesc::new(extent, Format::R8G8B8A8_UNORM),
        target_import(),
    );
    let depth = g.create_image("depth", ImageDesc::new(extent, Format::D32_SFLOAT));
    let scene = g.create_image(
        "scene-color",
        ImageDesc::new(extent, Format::R8G8B8A8_UNORM),
    );
    let near_left = Quad {
        rect: LEFT,
        depth: 0.8,
        color: [1.0, 0.0, 0.0, 1.0],
        id: 1,
    };
    let far_full = Quad {
        rect: FULL,
        depth: 0.4,
        color: [0.0, 1.0, 0.0, 1.0],
        id: 2,
    };
    g.raster_pass(
        "depth-prepass",
        PassClass::DepthPrepass,
        draw(kit, Kind::DepthOnly, 0, vec![near_left, far_full], None),
    )
    .depth_stencil_clear(depth, ClearDepthStencil::REVERSE_Z);
    g.raster_pass(
        "opaque",
        PassClass::Opaque,
        draw(kit, Kind::ColorEqual, 1, vec![near_left, far_full], None),
    )
    .color_clear(scene, ClearColor::BLACK)
    .depth_stencil_read_only(depth);
    let glass = Quad {
        rect: CENTER,
        depth: 0.9,
        color: [0.0, 0.0, 1.0, 0.5],
        id: 3,
    };
    g.raster_pass(
        "transparent",
        PassClass::Transparent,
        draw(kit, Kind::Blended, 1, vec![glass], None),
    )
    .color(scene)
    .depth_stencil_read_only(depth);
    let post = Quad {
        rect: FULL,
        depth: 0.0,
        color: [0.0; 4],
        id: 0,
    };
    g.raster_pass(
        "post",
        PassClass::Post,
        draw(kit, Kind::Post, 1, vec![post], Some(scene.0)),
    )
    .input(scene)
    .color(target)
    .coverage(Coverage::Full);
    g.export(target);
    Frame { graph: g, target }
}

/// Visibility-buffer frame: ids written with depth, then resolved by a subpass reading the id
/// as an input attachment. Expected: left half id 7, right half id 9 (resolve colours them).
pub fn visbuf_frame(kit: &Rc<RefCell<Kit>>, w: u32, h: u32) -> Frame {
    let extent = Extent2d::new(w, h);
    let mut g: GraphBuilder<Payload> = GraphBuilder::new();
    let target = g.import_image(
        "backbuffer",
        ImageDesc::new(extent, Format::R8G8B8A8_UNORM),
        target_import(),
    );
    let depth = g.create_image("depth", ImageDesc::new(extent, Format::D32_SFLOAT));
    let ids = g.create_image("visbuf-id", ImageDesc::new(extent, Format::R32_UINT));
    let a = Quad {
        rect: LEFT,
        depth: 0.8,
        color: [0.0; 4],
        id: 7,
    };
    let b = Quad {
        rect: FULL,
        depth: 0.4,
        color: [0.0; 4],
        id: 9,
    };
    g.raster_pass(
        "visbuf-write",
        PassClass::Opaque,
        draw(kit, Kind::Id, 1, vec![a, b], None),
    )
    .color_clear(ids, ClearColor::ZERO_UINT)
    .depth_stencil_clear(depth, ClearDepthStencil::REVERSE_Z);
    let full = Quad {
        rect: FULL,
        depth: 0.0,
        color: [0.0; 4],
        id: 0,
    };
    g.raster_pass(
        "visbuf-resolve",
        PassClass::Opaque,
        draw(kit, Kind::Resolve, 1, vec![full], Some(ids.0)),
    )
    .input(ids)
    .color(target)
    .coverage(Coverage::Full);
    g.export(target);
    Frame { graph: g, target }
}

/// Copies all of `src` (in TRANSFER_SRC_OPTIMAL) into the `dst_x` column offset of `dst` (in
/// TRANSFER_DST_OPTIMAL), `width` pixels wide: the layouts the graph puts transfer uses in.
fn copy(src: ImageId, dst: ImageId, dst_x: i32, width: u32, height: u32) -> Payload {
    Box::new(move |pc: &mut PassContext<'_>| {
        let s = pc.image(src)?.raw;
        let d = pc.image(dst)?.raw;
        let layers = vk::ImageSubresourceLayers {
            aspect_mask: vk::ImageAspectFlags::COLOR,
            mip_level: 0,
            base_array_layer: 0,
            layer_count: 1,
        };
        let region = vk::ImageCopy::default()
            .src_subresource(layers)
            .dst_subresource(layers)
            .dst_offset(vk::Offset3D {
                x: dst_x,
                y: 0,
                z: 0,
            })
            .extent(vk::Extent3D {
                width,
                height,
                depth: 1,
            });
        // SAFETY: the plan put src in TRANSFER_SRC and dst in TRANSFER_DST before this pass.
        unsafe {
            pc.ctx.device.cmd_copy_image(
                pc.cb,
                s,
                vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
                d,
                vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                &[region],
            )
        };
        Ok(())
    })
}

/// Two frame-local images never alive together (A: draw, copy out; then B: draw, copy out), so
/// the graph lets them share memory. Expected: left half red (from A), right half blue (from B).
pub fn aliasing_frame(kit: &Rc<RefCell<Kit>>, w: u32, h: u32) -> Frame {
    let half = Extent2d::new(w / 2, h);
    let mut g: GraphBuilder<Payload> = GraphBuilder::new();
    let target = g.import_image(
        "backbuffer",
        ImageDesc::new(Extent2d::new(w, h), Format::R8G8B8A8_UNORM),
        target_import(),
    );
    let a = g.create_image("a", ImageDesc::new(half, Format::R8G8B8A8_UNORM));
    let b = g.create_image("b", ImageDesc::new(half, Format::R8G8B8A8_UNORM));
    let red = Quad {
        rect: FULL,
        depth: 0.0,
        color: [1.0, 0.0, 0.0, 1.0],
        id: 0,
    };
    let blue = Quad {
        rect: FULL,
        depth: 0.0,
        color: [0.0, 0.0, 1.0, 1.0],
        id: 0,
    };
    g.raster_pass(
        "draw-a",
        PassClass::Opaque,
        draw(kit, Kind::Flat, 1, vec![red], None),
    )
    .color_clear(a, ClearColor::BLACK);
    let copy_a = g
        .transfer_pass("copy-a", PassClass::Transfer, copy(a, target, 0, w / 2, h))
        .transfer_src(a)
        .transfer_dst(target)
        .id();
    // Explicit order: without it the profile's class order would draw both first, and a and b
    // would be alive together.
    g.raster_pass(
        "draw-b",
        PassClass::Opaque,
        draw(kit, Kind::Flat, 1, vec![blue], None),
    )
    .color_clear(b, ClearColor::BLACK)
    .after(copy_a);
    g.transfer_pass(
        "copy-b",
        PassClass::Transfer,
        copy(b, target, (w / 2) as i32, w / 2, h),
    )
    .transfer_src(b)
    .transfer_dst(target);
    g.export(target);
    Frame { graph: g, target }
}

/// Externals for a frame with one imported target.
pub fn externals(target: ImageId, handle: &ImageHandle) -> Externals {
    Externals::from_iter([(target, External::Image(handle.clone()))])
}
