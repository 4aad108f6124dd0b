//! Occlusion tested by rasterizing bounding boxes against this frame's depth: hardware
//! occlusion queries ([`queries`]) and raster occlusion ([`raster`]), which draw the same proxy
//! boxes (`Proxy` in `pipelines.rs`); and software occlusion ([`software`]), which rasterizes
//! occluders on the CPU instead.

pub mod queries;
pub mod raster;
pub mod software;

pub use queries::{
    add_occlusion_queries, build_groups, crosses_near_plane, import_query_results, proxy_corner,
    OqState,
};
pub use raster::{add_raster_occlusion, RasterOcclusion};
pub use software::{SoftwareCull, SoftwareFrame, SoftwareOptions, SoftwareTarget};
