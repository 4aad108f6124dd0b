//! Stray pixels: fragments a rasterizer gives a triangle at a depth the triangle never reaches.
//!
//! A degenerate triangle (collinear corners, a repeated corner) or a near-degenerate sliver
//! projects to a line. Once its corners are snapped to the sub-pixel grid a rasterizer may
//! still cover a sample with it, and interpolate that sample's depth from a plane equation
//! divided by an area of almost nothing: lavapipe at 333x77 draws a collinear triangle 15 m
//! away at depth 1.0 (the near plane, in front of everything) where its corners lie at
//! 0.0006. Such a pixel marks no place the triangle occupies. Occlusion culling, which
//! reasons about where geometry is, rightly drops its owner when the owner's bounds lie
//! behind an occluder; the H200 draws no such fragment on the same frame.
//!
//! The oracle therefore counts an instance or cluster as visible only through pixels that lie
//! on their triangle: within the triangle's depth range in this frame (clipped to the depth
//! range the frame keeps), widened by a slack far above depth precision. An owner seen only
//! through stray pixels is reported as such, not as visible, and a differing pixel whose
//! owner in the oracle is stray is counted apart from culling errors.

use glam::Vec3;
use tilegraph_scene::{FrameMatrices, Scene};

/// How far outside its triangle's depth range a pixel may lie and still be the triangle's:
/// absolute, and relative to the depths themselves. Depth-buffer steps (D16: 1.5e-5) and
/// interpolation round-off are orders of magnitude smaller; only a fragment clearly off its
/// triangle is stray.
const SLACK_ABSOLUTE: f32 = 1.0 / 1024.0;
const SLACK_RELATIVE: f32 = 0.01;

/// The oracle's frame: per pixel its owner (instance and triangle of its mesh's draw) and its
/// depth, and the matrices it was drawn with.
pub(super) struct OracleFrame<'a> {
    pub scene: &'a Scene,
    pub matrices: &'a FrameMatrices,
    pub instances: &'a [u32],
    pub triangles: &'a [u32],
    pub depth: &'a [f32],
}

impl OracleFrame<'_> {
    /// Whether pixel `p` is stray: owned, and its depth lies clearly outside its triangle's
    /// range. A pixel that cannot be judged (no owner, an unknown triangle) is not stray.
    pub fn is_stray(&self, p: usize) -> bool {
        let (Some(&instance), Some(&triangle), Some(&depth)) = (
            self.instances.get(p),
            self.triangles.get(p),
            self.depth.get(p),
        ) else {
            return false;
        };
        if instance == u32::MAX {
            return false;
        }
        depth_range(self.scene, self.matrices, instance, triangle)
            .is_some_and(|(lo, hi)| outside(depth, lo, hi))
    }

    /// Of `culled` (sorted keys of owners the technique did not draw), those whose every pixel
    /// is stray; `key_of(p)` is pixel `p`'s owner key, `None` for background. Culled owners are
    /// few, so only their pixels are judged.
    pub fn only_stray(&self, culled: &[u64], key_of: impl Fn(usize) -> Option<u64>) -> Vec<u64> {
        if culled.is_empty() {
            return Vec::new();
        }
        let mut shown = vec![false; culled.len()];
        for p in 0..self.instances.len() {
            let Some(j) = key_of(p).and_then(|k| culled.binary_search(&k).ok()) else {
                continue;
            };
            if !shown[j] && !self.is_stray(p) {
                shown[j] = true;
            }
        }
        culled
            .iter()
            .zip(shown)
            .filter(|(_, shown)| !shown)
            .map(|(&k, _)| k)
            .collect()
    }
}

/// Whether `depth` lies clearly outside `lo..=hi` (by more than the slack).
fn outside(depth: f32, lo: f32, hi: f32) -> bool {
    let slack = SLACK_ABSOLUTE + SLACK_RELATIVE * lo.abs().max(hi.abs());
    depth < lo - slack || depth > hi + slack
}

/// The depths triangle `triangle` of instance `instance`'s mesh spans in the frame of `m`:
/// its corners' depths, a corner past the near or far plane (or behind the eye) taking that
/// plane's depth, as the clipped triangle reaches it. `None`: no such instance or triangle.
pub(super) fn depth_range(
    scene: &Scene,
    m: &FrameMatrices,
    instance: u32,
    triangle: u32,
) -> Option<(f32, f32)> {
    let inst = scene.instances().get(instance as usize)?;
    let mesh = scene.mesh(inst.mesh)?;
    if triangle >= mesh.triangle_count() {
        return None;
    }
    let first = mesh.first_index as usize + 3 * triangle as usize;
    let corners = scene.indices().get(first..first + 3)?;
    let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
    for &index in corners {
        let vertex = usize::try_from(i64::from(index) + i64::from(mesh.vertex_offset)).ok()?;
        let position = Vec3::from(scene.vertices().get(vertex)?.position);
        let world = (inst.transform.linear * position).as_dvec3() + inst.transform.translation;
        let clip = m.view_projection * (world - m.eye).as_vec3().extend(1.0);
        let depth = if clip.w > 0.0 {
            (clip.z / clip.w).clamp(0.0, 1.0)
        } else {
            m.depth.near_depth()
        };
        lo = lo.min(depth);
        hi = hi.max(depth);
    }
    Some((lo, hi))
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;
    use tilegraph_scene::{Camera, Material, SceneBuilder, Transform, Vertex};

    /// One instance of one triangle whose corners are `corners`, 1 m to the side of the origin.
    fn scene(corners: [[f32; 3]; 3]) -> Scene {
        let mut b = SceneBuilder::new("one triangle");
        let m = b.add_material(Material::opaque([1.0; 4]));
        let vertices: Vec<Vertex> = corners
            .iter()
            .map(|&position| Vertex {
                position,
                normal: [0.0, 0.0, 1.0],
                uv: [0.0, 0.0],
            })
            .collect();
        let mesh = b.add_mesh(&vertices, &[0, 1, 2], m).unwrap();
        let offset = DVec3::new(1.0, 0.0, 0.0);
        b.add_instance(Transform::new(glam::Mat3::IDENTITY, offset), mesh)
            .unwrap();
        b.build(None).unwrap()
    }

    fn frame(eye: DVec3) -> FrameMatrices {
        Camera::looking_at(eye, eye + DVec3::NEG_Z).matrices(1.0)
    }

    #[test]
    fn a_triangle_spans_its_corners_depths_and_the_near_plane_it_crosses() {
        // Corners 10 m and 20 m in front of an eye at the origin (reverse depth: near / distance).
        let s = scene([[0.0, 0.0, -10.0], [0.0, 1.0, -20.0], [1.0, 0.0, -10.0]]);
        let m = frame(DVec3::ZERO);
        let near = match Camera::looking_at(DVec3::ZERO, DVec3::NEG_Z).projection {
            tilegraph_scene::Projection::Perspective { near, .. } => near,
            other => panic!("a default camera is perspective, got {other:?}"),
        };
        let (lo, hi) = depth_range(&s, &m, 0, 0).unwrap();
        assert!((lo - near / 20.0).abs() < 1e-6 && (hi - near / 10.0).abs() < 1e-6);
        assert!(!outside(near / 15.0, lo, hi));
        assert!(
            outside(1.0, lo, hi),
            "the near plane is far off a triangle 10-20 m away"
        );
        // The eye moved between the corners: the clipped triangle reaches the near plane.
        let (_, hi) = depth_range(&s, &frame(DVec3::new(0.0, 0.0, -15.0)), 0, 0).unwrap();
        assert_eq!(hi, 1.0);
        assert_eq!(depth_range(&s, &m, 0, 1), None, "one triangle only");
        assert_eq!(depth_range(&s, &m, 1, 0), None, "one instance only");
    }

    #[test]
    fn a_pixel_is_stray_only_where_its_depth_lies_off_its_triangle() {
        // Collinear corners: a zero-area triangle, 10-20 m away.
        let s = scene([[0.0, 0.0, -10.0], [0.0, 0.5, -15.0], [0.0, 1.0, -20.0]]);
        let m = frame(DVec3::ZERO);
        let (lo, hi) = depth_range(&s, &m, 0, 0).unwrap();
        let oracle = |depth: f32, instance: u32| {
            let frame = OracleFrame {
                scene: &s,
                matrices: &m,
                instances: &[instance],
                triangles: &[0],
                depth: &[depth],
            };
            frame.is_stray(0)
        };
        assert!(!oracle((lo + hi) / 2.0, 0));
        assert!(oracle(1.0, 0), "at the near plane: stray");
        assert!(!oracle(1.0, u32::MAX), "background is never stray");
        assert!(!oracle(1.0, 7), "an unknown owner cannot be judged");
        // Two pixels of the triangle, one on it: the owner is seen, not stray-only.
        let two = |depth: [f32; 2]| {
            let frame = OracleFrame {
                scene: &s,
                matrices: &m,
                instances: &[0, 0, u32::MAX],
                triangles: &[0, 0, 0],
                depth: &[depth[0], depth[1], 0.0],
            };
            let key = |p: usize| {
                frame
                    .instances
                    .get(p)
                    .filter(|&&i| i != u32::MAX)
                    .map(|&i| u64::from(i))
            };
            frame.only_stray(&[0], key)
        };
        assert_eq!(two([1.0, 1.0]), [0]);
        assert!(two([1.0, (lo + hi) / 2.0]).is_empty());
    }
}
