//! tilegraph: a render graph, in Rust on Vulkan, that compiles each frame into what a
//! tile-based GPU wants, ships the passes that decide what gets shaded, and measures every
//! culling technique against an exact oracle. This crate is the whole Rust API in one
//! dependency (as `wgpu` and `bevy` are): the crates it is made of, re-exported by role, and
//! the names an engine uses every frame at the top.
//!
//! A game's frame loop: change the scene through handles, then record — the renderer uploads
//! what changed since its last frame (docs/EMBEDDING.md).
//!
//! ```no_run
//! use tilegraph::{
//!     Context, ContextOptions, Culling, InstanceFlags, RenderOptions, SceneRenderer, Technique,
//!     Transform,
//! };
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let options = RenderOptions {
//!     technique: Technique::Prepass,
//!     culling: Culling::HizTwoPhase,
//!     ..Default::default()
//! };
//! let mut context = ContextOptions::from_env();
//! context.features = options.device_features();
//! let ctx = Context::new(context)?;
//! let mut scene = tilegraph::scene::load("city:10k")?;
//! let car = scene.mesh_handle(tilegraph::scene::MeshId(3)).expect("a mesh");
//! let spawned = scene.add_instance(car, Transform::IDENTITY, InstanceFlags::default())?;
//! let mut renderer = SceneRenderer::new(&ctx, &scene, options)?;
//! let path = scene.camera_path().clone();
//! for (i, frame) in path.frames(16.0 / 9.0).enumerate() {
//!     // The game's changes of this frame, one batch...
//!     let mut t = Transform::IDENTITY;
//!     t.translation.x = i as f64 * 0.5;
//!     scene.set_transforms(&[(spawned, t)])?;
//!     // ...then the frame: only what changed is uploaded.
//!     renderer.render_frame(&ctx, &scene, &frame)?;
//! }
//! renderer.destroy(&ctx);
//! # Ok(())
//! # }
//! ```

/// CPU reference culling: frustum, bounds projection, HiZ, oracle metrics (no Vulkan).
pub use tilegraph_cull as cull;
/// The render graph: declare passes and resources, compile to a plan (no Vulkan).
pub use tilegraph_graph as graph;
/// The shipped passes, each an `add_*` function, and the scene renderer.
pub use tilegraph_passes as passes;
/// Vendor profiles, device matching, memory types, knobs (no Vulkan).
pub use tilegraph_profile as profile;
/// Scenes: glTF and procedural, changed by handle; cameras and paths (no Vulkan).
pub use tilegraph_scene as scene;
/// The shared vocabulary: extents, depth convention, boxes, projection.
pub use tilegraph_types as types;
/// The Vulkan backend: device and adoption, memory, plan execution, queries.
pub use tilegraph_vk as vk;

pub use tilegraph_graph::{GraphBuilder, GraphError, Plan};
pub use tilegraph_passes::cull::Culling;
pub use tilegraph_passes::{
    EngineTarget, FrameGraph, FrameReport, GpuTiming, RenderError, RenderOptions, SceneRenderer,
    Technique,
};
pub use tilegraph_scene::{
    Camera, CameraFrame, CameraPath, InstanceFlags, InstanceHandle, Material, MeshHandle, Motion,
    MotionParams, Scene, SceneBuilder, SceneError, Transform, Vertex,
};
pub use tilegraph_vk::{AdoptedDevice, Context, ContextOptions, DeviceConfig, VkError};
