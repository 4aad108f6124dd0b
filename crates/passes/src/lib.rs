//! The passes tilegraph ships, on top of the graph (`tilegraph-graph`) and the Vulkan backend
//! (`tilegraph-vk`), drawing the scenes of `tilegraph-scene`.
//!
//! - [`setup`]: which passes a frame needs, from the scene's content and the profile, with the
//!   reason for every pass included or left out.
//! - [`draws`]: instanced draw lists sorted as the profile asks.
//! - [`gpu_scene`]: the scene's buffers on the GPU and the per-frame data.

pub mod cull;
pub mod cullcheck;
pub mod draws;
pub mod gpu_scene;
pub mod hiz;
pub mod occlusion;
mod pipelines;
pub mod render;
pub mod setup;

pub use render::{required_features, FrameReport, RenderError, RenderOptions, SceneRenderer};
pub use setup::{decide, FrameSetup, PassDecision, PassKind, SceneContent, Technique};
