//! tilegraph-types: the geometry vocabulary tilegraph's pure crates share, as wgpu-types is for
//! wgpu. Each type here used to be defined in two crates and converted by hand between them;
//! now `tilegraph-graph`, `tilegraph-cull` and `tilegraph-scene` use these definitions and
//! re-export them from their old paths.
//!
//! - [`Extent2d`]: width and height in pixels.
//!
//! Pure data and arithmetic: no Vulkan, no `unsafe`, no error type. Checks that report errors
//! stay in the crate whose error type they return, as functions or extension traits over these
//! types (`tilegraph_cull::ExtentExt`, for instance).

#![forbid(unsafe_code)]

mod extent;

pub use extent::Extent2d;
