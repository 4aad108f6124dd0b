//! tilegraph-types: the geometry vocabulary tilegraph's pure crates share, as wgpu-types is for
//! wgpu. A value made by one crate (a scene's camera, a graph's extent) is handed to another
//! (the culling references, the passes) as it is: there is one definition of each type and no
//! conversion between copies. `tilegraph-graph`, `tilegraph-cull` and `tilegraph-scene`
//! re-export these types from their own paths, so their users name them as before.
//!
//! - [`Extent2d`]: width and height in pixels.
//! - [`DepthConvention`]: which end of [0, 1] is near (reverse-Z by default), with the compares
//!   and conservative roundings that follow from it; [`round`] has the directed f64 -> f32
//!   roundings behind them.
//! - [`Aabb`]: an axis-aligned box in f32.
//! - [`Projection`]: a camera's projection into Vulkan clip space (y flipped, depth in
//!   [0, 1]), perspective or orthographic; the viewport's aspect is given where a matrix or an
//!   NDC scale is computed.
//!
//! Pure data and arithmetic: no Vulkan, no `unsafe`, no error type. Checks that report errors
//! stay in the crate whose error type they return, as functions or extension traits over these
//! types (`tilegraph_cull::ExtentExt`, for instance).

#![forbid(unsafe_code)]

mod bounds;
mod depth;
mod extent;
mod projection;
pub mod round;

pub use bounds::Aabb;
pub use depth::DepthConvention;
pub use extent::Extent2d;
pub use projection::Projection;
