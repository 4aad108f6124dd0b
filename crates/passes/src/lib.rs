//! The passes tilegraph ships, on top of the graph (`tilegraph-graph`) and the Vulkan backend
//! (`tilegraph-vk`), drawing the scenes of `tilegraph-scene`.
//!
//! Each pass module owns its pass: an `add_*` function declares it on a [`FrameGraph`] with its
//! recording ([`frame`] says how payloads get what they record with), and an engine can call the
//! same functions with its own passes in between.
//!
//! - passes: [`prepass`] (depth pre-pass), [`forward`] (colour, blended, clear), [`visbuf`] (ids
//!   and resolve), [`gbuffer`] (deferred texturing's G-buffer and resolve), [`cull`] (GPU
//!   frustum, HiZ and two-phase culling into indirect lists), [`hiz`] (the pyramid build),
//!   [`occlusion`] (hardware queries, raster occlusion);
//! - what they share: [`targets`] (colour, depth, ids and their first-use clears), [`draws`]
//!   (draw lists), [`recording`] (draw recording), [`pipelines`] (every graphics pipeline, in one
//!   cache), [`gpu_scene`] (the scene's buffers);
//! - the frame: [`setup`] (which passes, and why), [`renderer`] (the composition, frame after
//!   frame), [`cullcheck`] (a culling technique against the exact oracle), [`lint`] (the
//!   profile's state rules over what a frame recorded).

pub mod compose;
pub mod cull;
pub mod cullcheck;
mod depth_test;
pub mod draws;
pub mod forward;
pub mod frame;
pub mod gbuffer;
pub mod gpu_scene;
pub mod hiz;
mod images;
pub mod knobs;
pub mod lint;
pub mod materials;
pub mod occlusion;
pub mod options;
pub mod pipelines;
pub mod prepass;
mod probe;
pub mod pvs;
pub mod recording;
pub mod renderer;
pub mod setup;
pub mod shadow;
pub(crate) mod spv;
pub mod targets;
pub mod visbuf;

pub use frame::{DrawSource, FrameData, FrameGraph, Payload, SceneResources};
pub use options::{FrameReport, RenderError, RenderOptions, WantedBy};
pub use probe::StageProbe;
pub use renderer::{scene_memory, EngineTarget, SceneMemory, SceneRenderer, ViewId};
pub use setup::{
    decide, FrameSetup, PassDecision, PassKind, SceneContent, Technique, VisbufResolve,
};
pub use targets::SceneTargets;
pub use tilegraph_vk::queries::GpuTiming;
