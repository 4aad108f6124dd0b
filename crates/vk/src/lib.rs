//! The Vulkan backend of tilegraph (ash). All `unsafe` and every Vulkan call of the project
//! live here; each `unsafe` block says which rule makes it sound.
//!
//! - [`Instance`]: loader, validation layer (with synchronization validation) whose messages go
//!   through `log` and are collected so a test fails on them, physical-device discovery.
//! - [`Context`]: the logical device with only the requested [`Feature`]s, the profile chosen for
//!   it (`tilegraph-profile`), and memory allocated in the type the profile picks per use.
//! - [`first_frame`]: the smallest end-to-end frame, used by tests and the demo.

mod commands;
mod context;
mod device_config;
mod error;
pub mod executor;
mod features;
pub mod first_frame;
pub mod frames;
mod instance;
mod memory;
pub mod pipeline;
pub mod queries;
pub mod readback;
pub mod shader;
pub mod shader_facts;
mod validation;

pub use ash;
pub use context::{AdoptedDevice, AsyncQueue, Context, ContextOptions, DeviceConfig, FaultSite};
pub use error::VkError;
pub use features::{Feature, FeatureRequest, FeatureTargets};
pub use instance::{DeviceLimits, Instance, PhysicalDevice, MIN_API_VERSION};
pub use memory::{Buffer, Image};
pub use validation::{silenced, Silenced, Validation, ValidationSink, SILENCED};
