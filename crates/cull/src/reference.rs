//! The CPU reference of what a frame shows: a ray caster that renders axis-aligned boxes into a
//! depth buffer and an id buffer the way a rasterizer with depth clipping at the near plane and
//! no back-face culling would (one sample at each pixel centre, in f64), so tests can compare
//! culling — and the GPU oracle itself — with the exact visible set.

use crate::{Aabb, DepthFormat, Extent2d, ExtentExt, Projection};
use glam::{DMat4, DVec3, Mat4, Vec3};

pub const BACKGROUND_ID: u32 = u32::MAX;

pub struct Render {
    pub extent: Extent2d,
    pub depth: Vec<f32>,
    pub ids: Vec<u32>,
}

/// The ray through pixel centre (px, py): origin and direction in world space. The direction
/// is scaled so that its view-space z is -1 (perspective), so the ray parameter t IS the view
/// distance of the point. Orthographic: origin on the z = 0 view plane, direction = view -z.
fn pixel_ray(
    world_from_view: &DMat4,
    (projection, aspect): (&Projection, f32),
    extent: Extent2d,
    px: u32,
    py: u32,
) -> (DVec3, DVec3) {
    let (sx, sy) = projection.ndc_scale(aspect);
    let ndc_x = (f64::from(px) + 0.5) / f64::from(extent.width_px) * 2.0 - 1.0;
    let ndc_y = (f64::from(py) + 0.5) / f64::from(extent.height_px) * 2.0 - 1.0;
    if projection.is_perspective() {
        let dir_view = DVec3::new(ndc_x / sx, ndc_y / sy, -1.0);
        let origin = world_from_view.transform_point3(DVec3::ZERO);
        (origin, world_from_view.transform_vector3(dir_view))
    } else {
        let origin = world_from_view.transform_point3(DVec3::new(ndc_x / sx, ndc_y / sy, 0.0));
        (
            origin,
            world_from_view.transform_vector3(DVec3::new(0.0, 0.0, -1.0)),
        )
    }
}

/// Slab intersection; returns (t_enter, t_exit) when the ray line meets the box.
fn ray_box(origin: DVec3, dir: DVec3, b: &Aabb) -> Option<(f64, f64)> {
    let (lo, hi) = (b.min.as_dvec3(), b.max.as_dvec3());
    let mut t0 = f64::NEG_INFINITY;
    let mut t1 = f64::INFINITY;
    for a in 0..3 {
        let (o, d) = (origin[a], dir[a]);
        if d == 0.0 {
            if o < lo[a] || o > hi[a] {
                return None;
            }
        } else {
            let (ta, tb) = ((lo[a] - o) / d, (hi[a] - o) / d);
            t0 = t0.max(ta.min(tb));
            t1 = t1.min(ta.max(tb));
        }
    }
    (t0 <= t1).then_some((t0, t1))
}

/// Renders `boxes` (ids = indices). The nearest surface at or beyond the near plane wins; a box
/// cut by the near plane shows its far side (no back-face culling). A finite far plane clips.
/// `aspect` is the viewport's width / height the projection is used with.
pub fn render_boxes(
    view: &Mat4,
    projection: &Projection,
    aspect: f32,
    extent: Extent2d,
    format: DepthFormat,
    boxes: &[Aabb],
) -> Render {
    let convention = projection.depth_convention();
    let near = f64::from(projection.near());
    let mut depth = vec![convention.far_depth(); extent.buffer_len()];
    let mut ids = vec![BACKGROUND_ID; extent.buffer_len()];
    let world_from_view = view.as_dmat4().inverse();
    for py in 0..extent.height_px {
        for px in 0..extent.width_px {
            let (o, d) = pixel_ray(&world_from_view, (projection, aspect), extent, px, py);
            let mut best: Option<(f64, u32)> = None;
            for (i, b) in boxes.iter().enumerate() {
                let Some((t0, t1)) = ray_box(o, d, b) else {
                    continue;
                };
                let t = if t0 >= near {
                    t0
                } else if t1 >= near {
                    t1
                } else {
                    continue;
                };
                let z = projection.depth_at_distance(t);
                if !(0.0..=1.0).contains(&z) {
                    continue; // beyond a finite far plane
                }
                let closer = match best {
                    None => true,
                    Some((bt, _)) => t < bt,
                };
                if closer {
                    best = Some((t, i as u32));
                }
            }
            if let Some((t, id)) = best {
                let idx = (py * extent.width_px + px) as usize;
                depth[idx] = format.store(projection.depth_at_distance(t) as f32);
                ids[idx] = id;
            }
        }
    }
    Render { extent, depth, ids }
}

/// A view matrix that looks from `eye` to `target`, y up.
pub fn look(eye: Vec3, target: Vec3) -> Mat4 {
    Mat4::look_at_rh(eye, target, Vec3::Y)
}
