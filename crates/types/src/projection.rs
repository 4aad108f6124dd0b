//! Projections into Vulkan clip space, in tilegraph's conventions: right-handed view space
//! looking down -z, depth in [0, 1], and the y flip inside the projection, so NDC y = -1 is the
//! top row of the image.

use glam::{Mat4, Vec4};
use serde::{Deserialize, Serialize};

use crate::depth::DepthConvention;

/// A camera's projection into Vulkan clip space (y flipped, depth in [0, 1]), without the
/// viewport: the aspect (width / height) is given where a matrix or an NDC scale is computed,
/// so one camera serves a window of any shape. Symmetric frusta only (tilegraph has no
/// off-centre cameras).
///
/// Serialized with a `kind` tag (`"perspective"`, `"orthographic"`) beside the fields below;
/// stored camera data depends on that form.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Projection {
    Perspective {
        fov_y_rad: f32,
        near: f32,
        /// `None`: infinite far plane.
        far: Option<f32>,
        depth: DepthConvention,
    },
    Orthographic {
        /// Half the visible height in metres (glTF's `ymag`); the width follows the aspect.
        half_height: f32,
        near: f32,
        far: f32,
        depth: DepthConvention,
    },
}

impl Default for Projection {
    /// 60 degrees vertical, near 0.1 m, reverse-Z, infinite far plane.
    fn default() -> Self {
        Projection::tilegraph_default(60f32.to_radians(), 0.1)
    }
}

/// Multiplies the y row by -1: Vulkan's framebuffer y points down, glTF's world y points up.
const FLIP_Y: Mat4 = Mat4::from_cols(Vec4::X, Vec4::new(0.0, -1.0, 0.0, 0.0), Vec4::Z, Vec4::W);

impl Projection {
    /// tilegraph's default kind of projection: perspective, reverse-Z, infinite far plane.
    pub const fn tilegraph_default(fov_y_rad: f32, near: f32) -> Self {
        Projection::Perspective {
            fov_y_rad,
            near,
            far: None,
            depth: DepthConvention::Reverse,
        }
    }

    pub fn depth_convention(&self) -> DepthConvention {
        match *self {
            Projection::Perspective { depth, .. } | Projection::Orthographic { depth, .. } => depth,
        }
    }

    pub fn near(&self) -> f32 {
        match *self {
            Projection::Perspective { near, .. } | Projection::Orthographic { near, .. } => near,
        }
    }

    /// The far plane; `None` when it is at infinity.
    pub fn far(&self) -> Option<f32> {
        match *self {
            Projection::Perspective { far, .. } => far,
            Projection::Orthographic { far, .. } => Some(far),
        }
    }

    pub fn is_perspective(&self) -> bool {
        matches!(self, Projection::Perspective { .. })
    }

    /// The projection matrix for a viewport of `aspect` = width / height.
    ///
    /// Reverse-Z with a finite far plane is the standard matrix with near and far swapped, which
    /// maps near -> 1 and far -> 0 (the same trick for orthographic).
    pub fn matrix(&self, aspect: f32) -> Mat4 {
        let m = match *self {
            Projection::Perspective {
                fov_y_rad,
                near,
                far,
                depth,
            } => match (far, depth) {
                (None, DepthConvention::Reverse) => {
                    Mat4::perspective_infinite_reverse_rh(fov_y_rad, aspect, near)
                }
                (None, DepthConvention::Standard) => {
                    Mat4::perspective_infinite_rh(fov_y_rad, aspect, near)
                }
                (Some(far), DepthConvention::Standard) => {
                    Mat4::perspective_rh(fov_y_rad, aspect, near, far)
                }
                (Some(far), DepthConvention::Reverse) => {
                    Mat4::perspective_rh(fov_y_rad, aspect, far, near)
                }
            },
            Projection::Orthographic {
                half_height,
                near,
                far,
                depth,
            } => {
                let hw = half_height * aspect;
                match depth {
                    DepthConvention::Standard => {
                        Mat4::orthographic_rh(-hw, hw, -half_height, half_height, near, far)
                    }
                    DepthConvention::Reverse => {
                        Mat4::orthographic_rh(-hw, hw, -half_height, half_height, far, near)
                    }
                }
            }
        };
        FLIP_Y * m
    }

    /// NDC per view-space unit on a viewport of `aspect`, in f64 for the culling references:
    /// perspective `ndc = scale * xy / distance`, orthographic `ndc = scale * xy`. The y scale
    /// is negative (the flip).
    pub fn ndc_scale(&self, aspect: f32) -> (f64, f64) {
        match *self {
            Projection::Perspective { fov_y_rad, .. } => {
                let f = 1.0 / (f64::from(fov_y_rad) * 0.5).tan();
                (f / f64::from(aspect), -f)
            }
            Projection::Orthographic { half_height, .. } => {
                // The half width exactly as `matrix` rounds it to f32.
                let half_width = half_height * aspect;
                (1.0 / f64::from(half_width), -1.0 / f64::from(half_height))
            }
        }
    }

    /// The exact depth (f64) of a point at view distance `distance_m` (= -z_view), for
    /// distances at or beyond the near plane. Depth depends on the distance alone for every
    /// projection here, so the nearest depth of a volume is the depth at its nearest distance.
    pub fn depth_at_distance(&self, distance_m: f64) -> f64 {
        match *self {
            Projection::Perspective {
                near, far, depth, ..
            } => {
                let n = f64::from(near);
                match (far, depth) {
                    (Some(far), DepthConvention::Standard) => {
                        let f = f64::from(far);
                        f * (distance_m - n) / ((f - n) * distance_m)
                    }
                    (Some(far), DepthConvention::Reverse) => {
                        let f = f64::from(far);
                        n * (f - distance_m) / ((f - n) * distance_m)
                    }
                    (None, DepthConvention::Standard) => 1.0 - n / distance_m,
                    (None, DepthConvention::Reverse) => n / distance_m,
                }
            }
            Projection::Orthographic {
                near, far, depth, ..
            } => {
                let (n, f) = (f64::from(near), f64::from(far));
                match depth {
                    DepthConvention::Standard => (distance_m - n) / (f - n),
                    DepthConvention::Reverse => (f - distance_m) / (f - n),
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    /// Each projection with the aspect of the viewport it is used on.
    fn all_projections() -> Vec<(Projection, f32)> {
        let fov = 1.0;
        let perspective = |far, depth| Projection::Perspective {
            fov_y_rad: fov,
            near: 0.1,
            far,
            depth,
        };
        // 8 m x 6 m.
        let orthographic = |depth| Projection::Orthographic {
            half_height: 3.0,
            near: 0.5,
            far: 80.0,
            depth,
        };
        vec![
            (perspective(Some(500.0), DepthConvention::Standard), 1.5),
            (perspective(Some(500.0), DepthConvention::Reverse), 1.5),
            (perspective(None, DepthConvention::Standard), 1.5),
            (Projection::tilegraph_default(fov, 0.1), 1.5),
            (orthographic(DepthConvention::Standard), 8.0 / 6.0),
            (orthographic(DepthConvention::Reverse), 8.0 / 6.0),
        ]
    }

    #[test]
    fn analytic_depth_and_scale_match_the_matrix() {
        for (p, aspect) in all_projections() {
            let m = p.matrix(aspect);
            let (sx, sy) = p.ndc_scale(aspect);
            for dist in [0.1f32, 0.5, 1.0, 3.0, 40.0, 79.0] {
                if dist < p.near() {
                    continue;
                }
                let v = Vec3::new(0.3, 0.2, -dist);
                let clip = m * Vec4::new(v.x, v.y, v.z, 1.0);
                let ndc = clip / clip.w;
                let expect = p.depth_at_distance(f64::from(dist));
                assert!(
                    (f64::from(ndc.z) - expect).abs() < 1e-5,
                    "{p:?} at {dist}: {} vs {expect}",
                    ndc.z
                );
                let w = if p.is_perspective() {
                    f64::from(dist)
                } else {
                    1.0
                };
                assert!((f64::from(ndc.x) - sx * 0.3 / w).abs() < 1e-5);
                assert!((f64::from(ndc.y) - sy * 0.2 / w).abs() < 1e-5);
            }
        }
    }

    #[test]
    fn near_maps_to_the_near_value_of_each_convention() {
        for (p, _) in all_projections() {
            let near = p.depth_at_distance(f64::from(p.near()));
            let expect = match p.depth_convention() {
                DepthConvention::Standard => 0.0,
                DepthConvention::Reverse => 1.0,
            };
            assert!((near - expect).abs() < 1e-12, "{p:?}");
        }
    }

    #[test]
    fn y_up_in_view_is_the_top_row() {
        let p = Projection::tilegraph_default(1.0, 0.1);
        let clip = p.matrix(1.0) * Vec4::new(0.0, 1.0, -2.0, 1.0);
        assert!(clip.y / clip.w < 0.0, "view +y must map to NDC y < 0 (top)");
    }

    fn clip(m: Mat4, p: Vec3) -> Vec3 {
        let c = m * p.extend(1.0);
        c.truncate() / c.w
    }

    fn persp(far: Option<f32>, depth: DepthConvention) -> Projection {
        Projection::Perspective {
            fov_y_rad: 1.0,
            near: 0.5,
            far,
            depth,
        }
    }

    #[test]
    fn depth_ranges_follow_each_convention() {
        use DepthConvention::*;
        let cases = [
            (persp(None, Reverse), 1.0, None),
            (persp(None, Standard), 0.0, None),
            (persp(Some(100.0), Reverse), 1.0, Some(0.0)),
            (persp(Some(100.0), Standard), 0.0, Some(1.0)),
            (
                Projection::Orthographic {
                    half_height: 5.0,
                    near: 0.5,
                    far: 100.0,
                    depth: Reverse,
                },
                1.0,
                Some(0.0),
            ),
            (
                Projection::Orthographic {
                    half_height: 5.0,
                    near: 0.5,
                    far: 100.0,
                    depth: Standard,
                },
                0.0,
                Some(1.0),
            ),
        ];
        for (p, near_depth, far_depth) in cases {
            let m = p.matrix(1.5);
            let d_near = clip(m, Vec3::new(0.0, 0.0, -0.5)).z;
            assert!(
                (d_near - near_depth).abs() < 1e-5,
                "{p:?}: near -> {d_near}"
            );
            assert_eq!(p.depth_convention().near_depth(), near_depth);
            if let Some(fd) = far_depth {
                let d_far = clip(m, Vec3::new(0.0, 0.0, -100.0)).z;
                assert!((d_far - fd).abs() < 1e-4, "{p:?}: far -> {d_far}");
                assert_eq!(p.depth_convention().far_depth(), fd);
            } else {
                let d_inf = clip(m, Vec3::new(0.0, 0.0, -1e9)).z;
                assert!((d_inf - p.depth_convention().far_depth()).abs() < 1e-6);
            }
            // Something halfway is strictly between, and closer than the far end.
            let mid = clip(m, Vec3::new(0.0, 0.0, -10.0)).z;
            assert!(p
                .depth_convention()
                .is_closer(mid, p.depth_convention().far_depth()));
        }
    }

    #[test]
    fn projection_flips_y_so_up_is_the_top_row() {
        for p in [
            persp(None, DepthConvention::Reverse),
            persp(Some(10.0), DepthConvention::Standard),
            Projection::Orthographic {
                half_height: 1.0,
                near: 0.1,
                far: 10.0,
                depth: DepthConvention::Reverse,
            },
        ] {
            let above = clip(p.matrix(1.0), Vec3::new(0.0, 0.5, -2.0));
            assert!(
                above.y < 0.0,
                "{p:?}: world-up must map to NDC y < 0 (top row)"
            );
        }
    }

    #[test]
    fn default_projection_matches_glam_reverse_infinite_with_y_flip() {
        let p = Projection::default();
        let mut expected = Mat4::perspective_infinite_reverse_rh(60f32.to_radians(), 2.0, 0.1);
        expected.x_axis.y *= -1.0;
        expected.y_axis.y *= -1.0;
        expected.z_axis.y *= -1.0;
        expected.w_axis.y *= -1.0;
        assert!(p.matrix(2.0).abs_diff_eq(expected, 1e-6));
        assert_eq!(p.depth_convention(), DepthConvention::Reverse);
    }
}
