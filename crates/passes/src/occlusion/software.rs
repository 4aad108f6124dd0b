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
    Extent2d, ExtentExt, OccluderMesh, OcclusionView, SoftwareConfig, SoftwareOcclusion,
    SoftwareStats,
};
use tilegraph_scene::{CameraFrame, CellRun, GridMember, MaterialClass, Scene};

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
    /// Per member of the frame's list: whether it stays.
    keep: Vec<bool>,
    candidates: Vec<(f32, u32)>,
    pub last: SoftwareFrame,
    /// CPU milliseconds of the last frames (at most [`HISTORY`]; the renderer clears it with
    /// its timings).
    pub history: Vec<f64>,
}

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
        // Occluders: big opaque boxes, nearest first; one around the eye first of all. The
        // bounding sphere's size on screen (over-estimated) skips the small ones cheaply; the
        // boxes of the rest decide.
        let min_area = u64::from(width) * u64::from(height) / 1024;
        let px_per_unit =
            f64::from(projection.matrix(aspect).y_axis.y.abs()) * f64::from(height) * 0.5;
        let perspective = projection.is_perspective();
        self.candidates.clear();
        for (k, member) in visible.iter().enumerate() {
            let rel = member.center - m.eye;
            let half = member.half_extents.as_dvec3();
            let (r, d) = (half.length(), rel.length());
            let near = if perspective && d <= r {
                f32::NEG_INFINITY
            } else {
                let diameter = 2.0 * r * px_per_unit / if perspective { d - r } else { 1.0 };
                if diameter * diameter < min_area as f64 {
                    continue;
                }
                match buffer.project_box(rel, half) {
                    Some(b) if b.area_on(width, height) >= min_area => b.near_key,
                    Some(_) => continue,
                    None => f32::NEG_INFINITY,
                }
            };
            let occludes = scene
                .instances()
                .get(member.instance as usize)
                .is_some_and(|inst| {
                    scene.instance_material(inst).is_some_and(|mat| {
                        mat.class == MaterialClass::Opaque && mat.engine_material.is_none()
                    })
                });
            if occludes {
                self.candidates.push((near, k as u32));
            }
        }
        self.candidates
            .sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let mut budget = options.occluder_triangles;
        for &(_, k) in &self.candidates {
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
        self.keep.clear();
        self.keep.resize(visible.len(), true);
        let mut first = 0usize;
        for run in cells {
            let end = (run.end as usize).min(visible.len());
            let b = &run.bounds;
            let cell_hidden = hidden((b.min + b.max) * 0.5 - eye, (b.max - b.min) * 0.5);
            for k in first..end {
                self.keep[k] = !cell_hidden
                    && visible
                        .get(k)
                        .is_none_or(|v| !hidden(v.center - eye, v.half_extents.as_dvec3()));
            }
            first = end.max(first);
        }
        for k in first..visible.len() {
            self.keep[k] = visible
                .get(k)
                .is_none_or(|v| !hidden(v.center - eye, v.half_extents.as_dvec3()));
        }
        let mut k = 0;
        let keep = &self.keep;
        visible.retain(|_| {
            let kept = keep.get(k).copied().unwrap_or(true);
            k += 1;
            kept
        });
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
