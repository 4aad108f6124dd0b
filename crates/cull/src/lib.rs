//! tilegraph-cull: the CPU ground truth that tilegraph's GPU culling passes are tested against.
//!
//! Pure Rust, no Vulkan. Conventions (shared with the rest of tilegraph; see docs/CULLING.md):
//! right-handed world, y up, metres; view from `Mat4::look_at_rh` (looking down -z); Vulkan clip
//! space with depth in [0, 1] and the y flip inside the projection (NDC y = -1 is row 0);
//! [`DepthConvention`] Standard (LESS, HiZ max) or Reverse (GREATER, HiZ min; the default, with
//! an infinite far plane).
//!
//! The shared vocabulary ([`Aabb`], [`DepthConvention`], [`Extent2d`], [`Projection`]) is
//! tilegraph-types', re-exported here; this crate adds its checks and conservative operations
//! over it ([`AabbExt`], [`ExtentExt`], [`ProjectionExt`]).
//!
//! - [`bounds`]: [`Sphere`], [`Obb`], and every volume's (outward-rounded) transforms.
//! - [`camera`]: the projection check; the viewport's aspect travels beside the projection.
//! - [`frustum`]: Gribb-Hartmann planes, conservative plane tests, exact SAT vs boxes.
//! - [`project`]: sphere / box -> NDC rect + conservative nearest depth.
//! - [`hiz`]: the pyramid (three [`NpotMode`]s) and the occlusion test.
//! - [`oracle`]: exact visible set from an id buffer, [`CullStats`].
//! - [`pvs`]: a precomputed visible set per cell of a grid ([`Pvs`]).
//! - [`software`]: software occlusion culling, a conservative CPU rasterizer (SIMD and scalar).

mod check;

pub mod bounds;
pub mod camera;
pub mod depth;
pub mod error;
pub mod frustum;
pub mod hiz;
pub mod oracle;
pub mod project;
pub mod pvs;
pub mod reference;
pub mod screen;
pub mod shadow;
pub mod software;

pub use bounds::{Aabb, AabbExt, Obb, Sphere};
pub use camera::{view_look_at, Projection, ProjectionExt};
pub use depth::{dequantize_d16, quantize_d16, DepthConvention, DepthFormat};
pub use error::CullError;
pub use frustum::{
    measure_plane_test_false_positives, Frustum, FrustumPlane, Plane, PlaneTest, PlaneTestAccuracy,
    SatTest, SeparatingAxis,
};
pub use hiz::{
    exact_is_occluded, level_extents, AxisScale, HizLevel, HizOutcome, HizProbe, HizPyramid,
    NpotMode, TexelMismatch, TexelRect,
};
pub use oracle::{visible_set_from_id_buffer, CullStats, InstanceSet};
pub use project::{
    project_aabb, project_obb, project_sphere, project_sphere_view, ProjectedBounds,
    ScreenProjection, DEPTH_MARGIN_ULPS,
};
pub use pvs::{Pvs, PVS_VERSION};
pub use screen::{ClampedRect, Extent2d, ExtentExt, NdcRect, PixelRect, MAX_EXTENT_PX};
pub use software::{
    BoxRect, Kernel, OccluderMesh, OcclusionView, SoftwareConfig, SoftwareOcclusion, SoftwareStats,
};
