//! tilegraph's C ABI: what an engine written in C or C++ links (`libtilegraph.so` or
//! `libtilegraph.a`) and includes (`include/tilegraph.h`, generated from this crate by
//! cbindgen and checked stale by the tests).
//!
//! Every exported function goes through [`status::boundary`]: it returns a [`TgStatus`], its
//! failure leaves a message for `tg_last_error`, and a panic is caught there — nothing unwinds
//! into C. Arguments are checked before use: null pointers, misaligned arrays, zero sizes,
//! unknown enum values; handles are numbers checked against a per-thread registry
//! (`registry.rs`), so a destroyed or foreign handle is a status, never undefined behaviour.
//!
//! - `context.rs`: what to enable on the engine's device, adopting it, the profile, a memory
//!   budget;
//! - `scene.rs`: scenes from plain arrays or a glTF file, cameras;
//! - `changes.rs`: a scene a game changes every frame, by handle (meshes, instances, batched
//!   transforms, flags, animated bounds);
//! - `materials.rs`: the engine's own shaders drawing tilegraph's culled lists;
//! - `pvs.rs`: precomputed visible sets baked by `tilegraph pvs`, from a file or memory;
//! - `renderer.rs`: recording a scene's frame into the engine's command buffer, statistics;
//! - `graph.rs`, `plan.rs`: the compiler alone — declare, compile, walk the plan;
//! - `features.rs`: tilegraph's features set in the engine's own feature structs.

pub mod changes;
pub mod context;
pub mod features;
pub mod graph;
pub mod materials;
pub mod options;
pub mod plan;
pub mod pvs;
mod registry;
pub mod renderer;
pub mod scene;
pub mod status;
pub mod views;

#[cfg(test)]
mod cluster_tests;

pub use changes::{TgInstanceDesc, TgTransform, TG_INSTANCE_CASTS_SHADOWS, TG_INSTANCE_HIDDEN};
pub use context::{
    TgAdoptInfo, TgContext, TgCulling, TgDeviceQuery, TgDeviceRequirements, TgFaultSite, TgFeature,
    TgTechnique,
};
pub use features::TgFeatureStructs;
pub use graph::{TgGraph, TgPassClass, TgUse};
pub use materials::{
    TgBindMaterial, TgEngineMaterialDesc, TgMaterialPass, TgShader, TG_ENGINE_MATERIAL_NONE,
};
pub use plan::{
    TgAttachment, TgBarrier, TgPlan, TgPlanSummary, TgResidency, TgStep, TgStepKind, TgSubpass,
};
pub use pvs::{TgPvs, TgPvsInfo};
pub use renderer::{
    TgEngineFrame, TgFrameStats, TgGpuTiming, TgImageState, TgPassTime, TgRenderer, TgRendererDesc,
    TgTarget,
};
pub use scene::{
    TgCamera, TgInstance, TgMaterial, TgMaterialClass, TgMesh, TgScene, TgSceneDesc, TgVertex,
};
pub use status::TgStatus;
