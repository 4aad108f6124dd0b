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
//!
//! Nor is a degenerate triangle's coverage reproducible: lavapipe covers a sample on a sliver's
//! edge, or not, depending on the draw around it (a cluster technique draws a mesh in runs of
//! clusters, the unculled frame in one draw). So a differing pixel is also stray where the
//! oracle's owner there is a degenerate triangle (`Scene::degenerate_triangle_ids`) the
//! technique drew, and where the technique shows something nearer than the unculled frame —
//! culling draws a subset, so no culled surface shows as something nearer — on the footprint
//! (within a pixel) of a degenerate triangle it drew: the owner of the technique's pixel is
//! not known (forward shading keeps no ids), the triangle that can explain it is. These
//! judge images only; a culled owner counts as a false negative unless every pixel of it is
//! off its triangle's depth.

use glam::{Vec2, Vec3, Vec4};
use tilegraph_scene::{FrameMatrices, MeshId, Scene};

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
    /// The frame's size in pixels.
    pub size: (u32, u32),
    /// The scene's degenerate triangles, (mesh, triangle) in mesh order
    /// (`Scene::degenerate_triangle_ids`).
    pub degenerate: &'a [(MeshId, u32)],
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

    /// Whether pixel `p`, where the technique's image differs from the unculled one (depths
    /// `technique` and `reference`), is a degenerate triangle's doing (module doc): the
    /// oracle's pixel is stray, or its owner a degenerate triangle of an instance `drawn` says
    /// the technique drew, or the technique is nearer there on such a triangle's footprint.
    pub fn explains_difference(
        &self,
        p: usize,
        (technique, reference): (f32, f32),
        drawn: &[bool],
    ) -> bool {
        if self.is_stray(p) {
            return true;
        }
        let owner = (self.instances.get(p), self.triangles.get(p));
        if let (Some(&i), Some(&t)) = owner {
            let inst = self.scene.instances().get(i as usize);
            if inst.is_some_and(|inst| self.degenerate.binary_search(&(inst.mesh, t)).is_ok())
                && drawn.get(i as usize).copied().unwrap_or(false)
            {
                return true;
            }
        }
        self.matrices.depth.is_closer(technique, reference)
            && self.on_degenerate_footprint(p, drawn)
    }

    /// Whether a degenerate triangle of an instance `drawn` says was drawn passes within a
    /// pixel of `p`'s centre.
    fn on_degenerate_footprint(&self, p: usize, drawn: &[bool]) -> bool {
        let (width, height) = self.size;
        let degenerate = self.degenerate;
        if width == 0 {
            return false;
        }
        let centre = Vec2::new(
            (p % width as usize) as f32 + 0.5,
            (p / width as usize) as f32 + 0.5,
        );
        let size = Vec2::new(width as f32, height as f32);
        let instances = self.scene.instances().iter().enumerate();
        instances
            .filter(|(i, _)| drawn.get(*i).copied().unwrap_or(false))
            .any(|(i, inst)| {
                let first = degenerate.partition_point(|&(m, _)| m < inst.mesh);
                degenerate[first..]
                    .iter()
                    .take_while(|&&(m, _)| m == inst.mesh)
                    .any(|&(_, t)| {
                        footprint(self.scene, self.matrices, i as u32, t, size)
                            .is_some_and(|f| distance(centre, &f) <= 1.0)
                    })
            })
    }
}

/// The pixel positions of triangle `triangle` of instance `instance`'s mesh in a frame of
/// `size` pixels; `None` when a corner lies behind the eye (its footprint is then unbounded:
/// not judged) or the triangle does not exist.
fn footprint(
    scene: &Scene,
    m: &FrameMatrices,
    instance: u32,
    triangle: u32,
    size: Vec2,
) -> Option<[Vec2; 3]> {
    let clip = clip_corners(scene, m, instance, triangle)?;
    if clip.iter().any(|c| c.w <= 0.0) {
        return None;
    }
    Some(clip.map(|c| (Vec2::new(c.x, c.y) / c.w + 1.0) * 0.5 * size))
}

/// The clip-space corners of triangle `triangle` of instance `instance`'s mesh in the frame of
/// `m` (positions relative to the eye in f64, as the renderer's model matrices are);
/// `None`: no such instance or triangle.
fn clip_corners(
    scene: &Scene,
    m: &FrameMatrices,
    instance: u32,
    triangle: u32,
) -> Option<[Vec4; 3]> {
    let inst = scene.instances().get(instance as usize)?;
    let mesh = scene.mesh(inst.mesh)?;
    if triangle >= mesh.triangle_count() {
        return None;
    }
    let first = mesh.first_index as usize + 3 * triangle as usize;
    let corners = scene.indices().get(first..first + 3)?;
    let mut out = [Vec4::ZERO; 3];
    for (o, &index) in out.iter_mut().zip(corners) {
        let vertex = usize::try_from(i64::from(index) + i64::from(mesh.vertex_offset)).ok()?;
        let position = Vec3::from(scene.vertices().get(vertex)?.position);
        let world = (inst.transform.linear * position).as_dvec3() + inst.transform.translation;
        *o = m.view_projection * (world - m.eye).as_vec3().extend(1.0);
    }
    Some(out)
}

/// The distance from `p` to the triangle `t` (0 inside), degenerate ones included: the
/// nearest of its three edges where `p` is outside.
fn distance(p: Vec2, t: &[Vec2; 3]) -> f32 {
    let edge = |a: Vec2, b: Vec2| {
        let ab = b - a;
        let along = if ab.length_squared() > 0.0 {
            ((p - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0)
        } else {
            0.0
        };
        (a + ab * along).distance(p)
    };
    let side = |a: Vec2, b: Vec2| (b - a).perp_dot(p - a);
    let s = [side(t[0], t[1]), side(t[1], t[2]), side(t[2], t[0])];
    let inside = s.iter().all(|&x| x > 0.0) || s.iter().all(|&x| x < 0.0);
    if inside {
        return 0.0;
    }
    edge(t[0], t[1]).min(edge(t[1], t[2])).min(edge(t[2], t[0]))
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
    let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
    for clip in clip_corners(scene, m, instance, triangle)? {
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
                size: (1, 1),
                degenerate: &[],
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
                size: (3, 1),
                degenerate: &[],
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

    #[test]
    fn a_degenerate_triangles_pixel_explains_a_difference() {
        // Collinear corners 10-20 m away, seen in a 64x64 frame.
        let s = scene([[0.0, 0.0, -10.0], [0.0, 0.5, -15.0], [0.0, 1.0, -20.0]]);
        let m = frame(DVec3::ZERO);
        let degenerate = s.degenerate_triangle_ids();
        assert_eq!(degenerate.len(), 1);
        let size = (64u32, 64u32);
        let f = footprint(&s, &m, 0, 0, Vec2::new(64.0, 64.0)).unwrap();
        let on = |c: Vec2| c.y as usize * 64 + c.x as usize;
        let (lo, hi) = depth_range(&s, &m, 0, 0).unwrap();
        let oracle = OracleFrame {
            scene: &s,
            matrices: &m,
            instances: &[],
            triangles: &[],
            depth: &[],
            size,
            degenerate: &degenerate,
        };
        let p = on((f[0] + f[2]) / 2.0);
        // The technique shows something nearer there than the unculled frame's background: at
        // the near plane, or on the triangle itself (coverage the whole draw did not give).
        assert!(oracle.explains_difference(p, (1.0, 0.0), &[true]));
        assert!(oracle.explains_difference(p, ((lo + hi) / 2.0, 0.0), &[true]));
        // Not drawn, farther than the unculled frame, or far from the triangle: no.
        assert!(!oracle.explains_difference(p, (1.0, 0.0), &[false]));
        assert!(!oracle.explains_difference(p, (0.0, 1.0), &[true]));
        let away = on(Vec2::new((f[0].x + 20.0).rem_euclid(64.0), f[0].y));
        assert!(!oracle.explains_difference(away, (1.0, 0.0), &[true]));
        // The oracle's owner there is the degenerate triangle, drawn: its coverage, not culling.
        let owned = OracleFrame {
            instances: &[0],
            triangles: &[0],
            depth: &[(lo + hi) / 2.0],
            size: (1, 1),
            ..oracle
        };
        assert!(owned.explains_difference(0, (0.0, (lo + hi) / 2.0), &[true]));
        assert!(!owned.explains_difference(0, (0.0, (lo + hi) / 2.0), &[false]));
        // Distances: inside a plain triangle 0, else to the nearest edge.
        let t = [Vec2::ZERO, Vec2::new(4.0, 0.0), Vec2::new(0.0, 4.0)];
        assert_eq!(distance(Vec2::new(1.0, 1.0), &t), 0.0);
        assert_eq!(distance(Vec2::new(-2.0, 1.0), &t), 2.0);
        let line = [Vec2::ZERO, Vec2::new(2.0, 0.0), Vec2::new(4.0, 0.0)];
        assert_eq!(distance(Vec2::new(3.0, 0.5), &line), 0.5);
    }
}
