//! Software occlusion culling (`Culling::SoftwareOcclusion`, seed 002): the frame's largest
//! opaque instances rasterized on the CPU into a low-resolution depth buffer
//! ([`tilegraph_cull::SoftwareOcclusion`], conservative at the frame's pixels), every instance
//! in the frustum tested against it, the CPU lists built from what survives. Same frame: no GPU
//! work, no readback, no latency; nothing is drawn a frame late.
//!
//! **Occluders** (the stated rule): instances in the frustum whose material is opaque with
//! tilegraph's shaders (alpha-tested and blended materials, and engine materials, whose shaders
//! may discard, never occlude), whose box covers at least 1/1024 of the frame, nearest first
//! until the triangle budget (knob `software_occluder_triangles`) is spent. Meshes are used as
//! they are: a simplified mesh is conservative only when its surface stays inside the original,
//! which meshoptimizer's simplifier does not promise, so none is made.

use std::sync::Arc;

use glam::{DVec3, Vec3};
use tilegraph_cull::{
    BoxRect, Extent2d, ExtentExt, OccluderMesh, OcclusionView, SoftwareConfig, SoftwareOcclusion,
    SoftwareStats,
};
use tilegraph_scene::{CameraFrame, CellRun, DAabb, GridMember, MaterialClass, Scene};

/// The knobs of software occlusion.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SoftwareOptions {
    /// The depth buffer's tiles across and down (knob `software_resolution`).
    pub resolution: (u32, u32),
    /// Threads rasterizing bands of tiles (knob `software_threads`).
    pub threads: usize,
    /// Occluder triangles per frame at most (knob `software_occluder_triangles`).
    pub occluder_triangles: u32,
}

impl Default for SoftwareOptions {
    fn default() -> Self {
        SoftwareOptions {
            resolution: (256, 128),
            threads: 1,
            occluder_triangles: 16384,
        }
    }
}

/// Parses `WxH`.
pub fn parse_resolution(s: &str) -> Option<(u32, u32)> {
    let (w, h) = s.split_once('x')?;
    Some((w.parse().ok()?, h.parse().ok()?))
}

/// The view software occlusion culls for.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SoftwareTarget {
    /// The frame's size in pixels.
    pub size: (u32, u32),
    pub format: tilegraph_cull::DepthFormat,
    pub knobs: SoftwareOptions,
    /// The GPU's `subPixelPrecisionBits`.
    pub subpixel_bits: u32,
}

/// What the last frame's software occlusion did.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SoftwareFrame {
    pub raster: SoftwareStats,
    /// Instances in the frustum, and those the buffer hid.
    pub tested: u32,
    pub culled: u32,
    /// CPU milliseconds: selecting, rasterizing and testing.
    pub cpu_ms: f64,
}

/// A view's software occlusion: the buffer, the occluder meshes prepared so far, the frame's
/// scratch.
#[derive(Debug, Default)]
pub struct SoftwareCull {
    buffer: Option<SoftwareOcclusion>,
    /// Per mesh id: its occluder form, made the first time the mesh occludes.
    meshes: Vec<Option<Arc<OccluderMesh>>>,
    /// Occluder candidates: nearest depth, index in the frame's list, box on screen.
    candidates: Vec<(f32, u32, Option<BoxRect>)>,
    pub last: SoftwareFrame,
    /// CPU milliseconds of the last frames (at most [`HISTORY`]; the renderer clears it with
    /// its timings).
    pub history: Vec<f64>,
}

/// Occluder triangles rasterized before the first box test of an occluder (the batches after
/// it double).
const FIRST_BATCH: u32 = 512;

/// Frames of CPU time [`SoftwareCull::history`] keeps.
pub const HISTORY: usize = 64;

/// Why a frame's software occlusion could not run (bad camera or mesh data); the caller keeps
/// every instance instead.
pub type SoftwareError = tilegraph_cull::CullError;

impl SoftwareCull {
    /// Removes from `visible` (the frame's opaque and alpha-tested instances in the frustum)
    /// those the occluders hide, for a view described by `target`. `cells`: the runs of
    /// `visible` that share a grid cell ([`crate::cull::cpu_frustum_visible_by_cell`]), whose
    /// boxes are tested first (members after the last run, or all without runs, one by one).
    pub fn cull(
        &mut self,
        scene: &Scene,
        frame: &CameraFrame,
        target: &SoftwareTarget,
        cells: &[CellRun],
        visible: &mut Vec<GridMember>,
    ) -> Result<(), SoftwareError> {
        let start = std::time::Instant::now();
        let (width, height) = target.size;
        let (format, options, subpixel_bits) = (target.format, &target.knobs, target.subpixel_bits);
        let m = frame.current;
        let projection = frame.camera.projection;
        let extent = Extent2d::try_new(width, height)?;
        let aspect = width as f32 / height as f32;
        let config = SoftwareConfig {
            resolution: options.resolution,
            subpixel_bits,
            threads: options.threads.max(1),
            ..SoftwareConfig::default()
        };
        let buffer = self
            .buffer
            .get_or_insert_with(|| SoftwareOcclusion::new(config));
        buffer.set_config(config);
        buffer.begin(OcclusionView {
            clip_from_relative: projection.matrix(aspect).as_dmat4() * m.view.as_dmat4(),
            extent,
            convention: m.depth,
            format,
        })?;
        // Occluders: big opaque boxes, nearest first; one around the eye first of all.
        let min_area = u64::from(width) * u64::from(height) / 1024;
        let px_per_unit =
            f64::from(projection.matrix(aspect).y_axis.y.abs()) * f64::from(height) * 0.5;
        let size = SizeTest {
            min_area,
            px_per_unit,
            perspective: projection.is_perspective(),
            eye: m.eye,
            reach: 2.0 * px_per_unit / (min_area as f64).sqrt() + 1.0,
        };
        self.candidates.clear();
        let mut consider = |k: usize, member: &GridMember| {
            if let Some((near, rect)) = size.candidate(buffer, member, (width, height)) {
                let occludes =
                    scene
                        .instances()
                        .get(member.instance as usize)
                        .is_some_and(|inst| {
                            scene.instance_material(inst).is_some_and(|mat| {
                                mat.class == MaterialClass::Opaque && mat.engine_material.is_none()
                            })
                        });
                if occludes {
                    self.candidates.push((near, k as u32, rect));
                }
            }
        };
        // A cell too small on screen for any member to be: its members are skipped unseen.
        let mut first = 0usize;
        for run in cells {
            let end = (run.end as usize).min(visible.len());
            if !size.all_too_small(&run.bounds) {
                for (k, member) in visible.iter().enumerate().take(end).skip(first) {
                    consider(k, member);
                }
            }
            first = end.max(first);
        }
        for (k, member) in visible.iter().enumerate().skip(first) {
            consider(k, member);
        }
        self.candidates
            .sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        // Nearest first, rasterized in batches that double: an occluder whose box the batches
        // before it already hide adds nothing nearer, so it is left out (and its triangles
        // stay in the budget).
        let mut budget = options.occluder_triangles;
        let (mut pending, mut batch) = (0u32, FIRST_BATCH);
        for &(_, k, rect) in &self.candidates {
            let Some(member) = visible.get(k as usize) else {
                continue;
            };
            let Some(inst) = scene.instances().get(member.instance as usize) else {
                continue;
            };
            let mesh_id = inst.mesh.0 as usize;
            let Some(mesh) = scene.meshes().get(mesh_id) else {
                continue;
            };
            let triangles = mesh.index_count / 3;
            if triangles > budget {
                continue;
            }
            if rect.is_some_and(|r| buffer.hides(&r)) {
                continue;
            }
            budget -= triangles;
            if self.meshes.len() <= mesh_id {
                self.meshes.resize(mesh_id + 1, None);
            }
            let occluder = match &self.meshes[mesh_id] {
                Some(o) => Arc::clone(o),
                None => {
                    let o = Arc::new(occluder_mesh(scene, mesh_id)?);
                    self.meshes[mesh_id] = Some(Arc::clone(&o));
                    o
                }
            };
            let t = &inst.transform;
            buffer.add_occluder(&occluder, t.linear.as_dmat3(), t.translation - m.eye);
            pending += triangles;
            if pending >= batch {
                buffer.rasterize();
                pending = 0;
                batch = batch.saturating_mul(2);
            }
        }
        buffer.rasterize();
        // A cell's box first: hidden, so are all its members.
        let tested = visible.len() as u32;
        let eye = m.eye;
        let hidden = |center: DVec3, half: DVec3| {
            buffer
                .project_box(center, half)
                .is_some_and(|r| buffer.hides(&r))
        };
        // Compacted in place: a hidden cell's members are dropped without a look.
        let mut kept = 0usize;
        let mut keep_if_seen = |visible: &mut Vec<GridMember>, k: usize| {
            if let Some(v) = visible.get(k).copied() {
                if !hidden(v.center - eye, v.half_extents.as_dvec3()) {
                    if let Some(slot) = visible.get_mut(kept) {
                        *slot = v;
                    }
                    kept += 1;
                }
            }
        };
        let mut first = 0usize;
        for run in cells {
            let end = (run.end as usize).min(visible.len());
            let b = &run.bounds;
            if !hidden((b.min + b.max) * 0.5 - eye, (b.max - b.min) * 0.5) {
                for k in first..end {
                    keep_if_seen(visible, k);
                }
            }
            first = end.max(first);
        }
        for k in first..visible.len() {
            keep_if_seen(visible, k);
        }
        visible.truncate(kept);
        self.last = SoftwareFrame {
            raster: buffer.stats(),
            tested,
            culled: tested - visible.len() as u32,
            cpu_ms: start.elapsed().as_secs_f64() * 1e3,
        };
        if self.history.len() >= HISTORY {
            self.history.remove(0);
        }
        self.history.push(self.last.cpu_ms);
        Ok(())
    }
}

/// Which instances are big enough on screen to occlude: those whose box covers at least
/// `min_area` pixels. The bounding sphere's size on screen (over-estimated) skips the small ones
/// cheaply, a whole cell of them at a time; the boxes of the rest decide.
struct SizeTest {
    min_area: u64,
    px_per_unit: f64,
    perspective: bool,
    eye: DVec3,
    /// `2 px_per_unit / sqrt(min_area) + 1`: a sphere of radius `r` farther than `reach * r`
    /// is too small (perspective).
    reach: f64,
}

impl SizeTest {
    /// Whether a sphere of radius `r` whose nearest point lies `gap` in front of the eye spans
    /// fewer pixels across than a square of `min_area`.
    fn too_small(&self, r: f64, gap: f64) -> bool {
        let diameter = 2.0 * r * self.px_per_unit / if self.perspective { gap } else { 1.0 };
        diameter * diameter < self.min_area as f64
    }

    /// Whether every box inside `cell` is too small. A member's box inside the cell's box `U`
    /// has a half-diagonal `r <= R` (U's) and, centred `a` from U's centre, `|a| + r <= sqrt(2)
    /// R`; so its sphere's nearest point is at least `D - sqrt(2) R` away (`D`: U's centre's
    /// distance) and spans at most what a sphere of radius `R` that far does.
    fn all_too_small(&self, cell: &DAabb) -> bool {
        let big_r = ((cell.max - cell.min) * 0.5).length();
        let gap =
            (((cell.min + cell.max) * 0.5) - self.eye).length() - std::f64::consts::SQRT_2 * big_r;
        (!self.perspective || gap > 0.0) && self.too_small(big_r, gap)
    }

    /// A member as an occluder candidate: its nearest depth key and its box on screen, or
    /// `None` when it is too small. One holding the eye comes first of all (no box).
    fn candidate(
        &self,
        buffer: &SoftwareOcclusion,
        member: &GridMember,
        (width, height): (u32, u32),
    ) -> Option<(f32, Option<BoxRect>)> {
        let rel = member.center - self.eye;
        let half = member.half_extents.as_dvec3();
        // Most members are small and far: no square root for them. With r1 = the half extents'
        // sum (at least the radius), a centre farther than `reach * r1` makes
        // 2 r1 px / (d - r1) < sqrt(min_area): the test below would say too small too.
        let reach = half.abs().element_sum() * self.reach;
        if self.perspective && reach * reach < rel.length_squared() {
            return None;
        }
        let (r, d) = (half.length(), rel.length());
        if self.perspective && d <= r {
            return Some((f32::NEG_INFINITY, None));
        }
        if self.too_small(r, d - r) {
            return None;
        }
        match buffer.project_box(rel, half) {
            Some(b) if b.area_on(width, height) >= self.min_area => Some((b.near_key, Some(b))),
            Some(_) => None,
            None => Some((f32::NEG_INFINITY, None)),
        }
    }
}

/// Mesh `id` of `scene` as an occluder.
fn occluder_mesh(scene: &Scene, id: usize) -> Result<OccluderMesh, SoftwareError> {
    let invalid = |reason: String| tilegraph_cull::CullError::InvalidOccluder { reason };
    let mesh = scene
        .meshes()
        .get(id)
        .ok_or_else(|| invalid(format!("mesh {id} does not exist")))?;
    let first = mesh.vertex_offset.max(0) as usize;
    let vertices = scene
        .vertices()
        .get(first..first + mesh.vertex_count as usize)
        .ok_or_else(|| invalid(format!("mesh {id}: vertex range out of the scene's")))?;
    let positions: Vec<Vec3> = vertices.iter().map(|v| Vec3::from(v.position)).collect();
    let i0 = mesh.first_index as usize;
    let indices = scene
        .indices()
        .get(i0..i0 + mesh.index_count as usize)
        .ok_or_else(|| invalid(format!("mesh {id}: index range out of the scene's")))?;
    let double_sided = scene
        .material(mesh.material)
        .is_some_and(|m| m.double_sided);
    OccluderMesh::new(&positions, indices, double_sided)
}
