//! Baking a precomputed visible set ([`tilegraph_cull::Pvs`]) with the exact oracle's id render:
//! for each cell of a grid over the region, `samples` viewpoints drawn inside it (a fixed
//! sequence: the same bake every run), each rendered as six 90° faces of a cube into the
//! visibility buffer (frustum-culled on heavy scenes, which changes no id); the instances that
//! own a pixel of any face are the cell's set. `Culling::Pvs` draws the camera cell's set (and its neighbours' with dilation)
//! that the frustum holds.

use std::time::Instant;

use glam::{DVec3, Vec3};
use tilegraph_cull::{Pvs, PVS_VERSION};
use tilegraph_scene::{Camera, DAabb, DepthConvention, Projection, Scene};
use tilegraph_vk::Context;

use crate::cull::Culling;
use crate::options::{RenderError, RenderOptions};
use crate::renderer::SceneRenderer;
use crate::setup::Technique;

/// What to bake.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BakeSpec {
    /// The region cameras visit: cells cover it.
    pub region: DAabb,
    /// A cell's side (m).
    pub cell: f64,
    /// Viewpoints per cell.
    pub samples: u32,
    /// Each face's side in pixels.
    pub face_px: u32,
    /// The sequence the viewpoints are drawn from.
    pub seed: u64,
}

/// The next number of a SplitMix64 sequence, as a fraction in [0, 1).
fn next_unit(state: &mut u64) -> f64 {
    *state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^= z >> 31;
    (z >> 11) as f64 / (1u64 << 53) as f64
}

/// The six faces of a cube around an eye: look direction and up.
const FACES: [(DVec3, Vec3); 6] = [
    (DVec3::X, Vec3::Y),
    (DVec3::NEG_X, Vec3::Y),
    (DVec3::Z, Vec3::Y),
    (DVec3::NEG_Z, Vec3::Y),
    (DVec3::Y, Vec3::Z),
    (DVec3::NEG_Y, Vec3::Z),
];

/// From this many triangles drawn unculled the bake frustum-culls its faces: on the H100 the
/// Godot rooms (65 M triangles) bake in 80 s instead of 215, while city:10000 (cheap instances,
/// where culling's fixed cost per face outweighs it) bakes slower culled (282 s against 173).
pub const BAKE_CULL_TRIANGLES: u64 = 8_000_000;

/// The bake's culling: frustum culling draws only a face's instances and never changes an id
/// (images equal, docs/ACCURACY.md), so the set is the unculled render's either way.
fn bake_culling(scene: &Scene) -> Culling {
    if scene.triangles_drawn() >= BAKE_CULL_TRIANGLES {
        Culling::Frustum
    } else {
        Culling::None
    }
}

/// A cell's size per axis: `spec.cell`, or the region's extent along an axis it spans less
/// than a cell of (an eye-height walk: viewpoints stay at the heights cameras take).
pub fn cell_size(spec: &BakeSpec) -> [f64; 3] {
    let size = spec.region.max - spec.region.min;
    let cell = spec.cell.max(1e-3);
    [0, 1, 2].map(|a| cell.min(size[a].max(1e-3)))
}

/// The grid over `spec.region` (cells per axis) and each cell's viewpoints, in the order the
/// bake renders them (cells x fastest, then y, then z).
pub fn viewpoints(spec: &BakeSpec) -> ([u32; 3], Vec<Vec<DVec3>>) {
    let size = spec.region.max - spec.region.min;
    let cell = cell_size(spec);
    let dims = [0, 1, 2].map(|a| ((size[a] / cell[a]).ceil().clamp(1.0, 1e6) as u32).max(1));
    let step = DVec3::from_array(cell);
    let mut state = spec.seed;
    let mut cells = Vec::new();
    for z in 0..dims[2] {
        for y in 0..dims[1] {
            for x in 0..dims[0] {
                let low =
                    spec.region.min + DVec3::new(f64::from(x), f64::from(y), f64::from(z)) * step;
                cells.push(
                    (0..spec.samples.max(1))
                        .map(|_| {
                            let jitter = DVec3::new(
                                next_unit(&mut state),
                                next_unit(&mut state),
                                next_unit(&mut state),
                            );
                            low + jitter * step
                        })
                        .collect(),
                );
            }
        }
    }
    (dims, cells)
}

/// The six cameras of a viewpoint (90° faces of a cube), as the bake renders them.
pub fn face_cameras(eye: DVec3) -> [Camera; 6] {
    let projection = Projection::Perspective {
        fov_y_rad: std::f32::consts::FRAC_PI_2,
        near: 0.05,
        far: None,
        depth: DepthConvention::Reverse,
    };
    FACES.map(|(dir, up)| Camera {
        eye,
        target: eye + dir,
        up,
        projection,
    })
}

/// Bakes `scene`'s visible set over `spec.region`; `progress(done, cells)` after each cell.
pub fn bake(
    ctx: &Context,
    scene: &Scene,
    spec: &BakeSpec,
    mut progress: impl FnMut(usize, usize),
) -> Result<Pvs, RenderError> {
    let started = Instant::now();
    let (dims, eyes) = viewpoints(spec);
    let options = RenderOptions {
        technique: Technique::Visbuf,
        width: spec.face_px.max(1),
        height: spec.face_px.max(1),
        culling: bake_culling(scene),
        capture_ids: true,
        ..Default::default()
    };
    let mut renderer = SceneRenderer::new(ctx, scene, options)?;
    let instances = scene.instances().len() as u32;
    let mut cells = Vec::with_capacity(eyes.len());
    let mut seen = vec![false; instances as usize];
    let result = (|| {
        for cell_eyes in &eyes {
            seen.fill(false);
            for &eye in cell_eyes {
                for camera in face_cameras(eye) {
                    renderer.render(ctx, scene, &camera)?;
                    for id in renderer.read_instance_ids(ctx)?.unwrap_or_default() {
                        if let Some(s) = seen.get_mut(id as usize) {
                            *s = true;
                        }
                    }
                }
            }
            cells.push(
                (0..instances)
                    .filter(|&i| seen[i as usize])
                    .collect::<Vec<u32>>(),
            );
            progress(cells.len(), eyes.len());
        }
        Ok::<(), RenderError>(())
    })();
    renderer.destroy(ctx);
    result?;
    Ok(Pvs {
        version: PVS_VERSION,
        scene_fingerprint: scene.placement_fingerprint(),
        instances,
        origin: spec.region.min.to_array(),
        cell: cell_size(spec),
        dims,
        samples: spec.samples.max(1),
        face_px: spec.face_px.max(1),
        cells,
        bake_seconds: started.elapsed().as_secs_f64(),
    })
}

/// The region of a camera path's eyes, grown by half a cell along each axis the path spans
/// (so that a sample can sit on either side of it) and by 0.1 m along one it keeps (an
/// eye-height walk's height: viewpoints below the floor see nothing cameras see).
pub fn path_region(path: &tilegraph_scene::CameraPath, cell: f64) -> DAabb {
    let mut lo = DVec3::splat(f64::INFINITY);
    let mut hi = DVec3::splat(f64::NEG_INFINITY);
    for k in path.keys() {
        lo = lo.min(k.camera.eye);
        hi = hi.max(k.camera.eye);
    }
    if lo.x > hi.x {
        return DAabb::new(DVec3::ZERO, DVec3::splat(cell));
    }
    let grow = (hi - lo)
        .to_array()
        .map(|e| if e >= cell { cell * 0.5 } else { 0.1 });
    let grow = DVec3::from_array(grow);
    DAabb::new(lo - grow, hi + grow)
}
