//! Projections in tilegraph's conventions: right-handed view space looking down -z, Vulkan clip
//! space (depth in [0, 1]) with the y flip inside the projection so NDC y = -1 is the top row.

use glam::{Mat4, Vec3};

use crate::depth::DepthConvention;
use crate::CullError;

/// Where the far plane is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FarPlane {
    Finite {
        far_m: f32,
    },
    /// No far plane: depth tends to the far value (0 reverse, 1 standard) as distance grows.
    Infinite,
}

/// The shape of a projection (symmetric frusta only: tilegraph has no off-centre cameras).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ProjectionKind {
    Perspective {
        fov_y_rad: f32,
        aspect: f32,
        near_m: f32,
        far: FarPlane,
    },
    Orthographic {
        width_m: f32,
        height_m: f32,
        near_m: f32,
        far_m: f32,
    },
}

/// A validated projection plus its depth convention.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Projection {
    kind: ProjectionKind,
    depth: DepthConvention,
}

fn invalid(parameter: &'static str, value: f32, reason: &'static str) -> CullError {
    CullError::InvalidProjection {
        parameter,
        value,
        reason,
    }
}

/// Vulkan's framebuffer y grows downward; flipping y in the projection keeps view space y-up
/// while NDC y = -1 lands on row 0.
const FLIP_Y: Mat4 = Mat4::from_cols_array(&[
    1.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0,
]);

impl Projection {
    /// A perspective projection. `near_m > 0`; a finite `far_m` must exceed `near_m`.
    pub fn perspective(
        fov_y_rad: f32,
        aspect: f32,
        near_m: f32,
        far: FarPlane,
        depth: DepthConvention,
    ) -> Result<Self, CullError> {
        if !(fov_y_rad.is_finite() && fov_y_rad > 0.0 && fov_y_rad < std::f32::consts::PI) {
            return Err(invalid("fov_y_rad", fov_y_rad, "must lie in (0, pi)"));
        }
        if !(aspect.is_finite() && aspect > 0.0) {
            return Err(invalid("aspect", aspect, "must be finite and > 0"));
        }
        if !(near_m.is_finite() && near_m > 0.0) {
            return Err(invalid("near_m", near_m, "must be finite and > 0"));
        }
        if let FarPlane::Finite { far_m } = far {
            if !(far_m.is_finite() && far_m > near_m) {
                return Err(invalid("far_m", far_m, "must be finite and > near_m"));
            }
        }
        Ok(Projection {
            kind: ProjectionKind::Perspective {
                fov_y_rad,
                aspect,
                near_m,
                far,
            },
            depth,
        })
    }

    /// tilegraph's default: reverse-Z, infinite far plane.
    pub fn tilegraph_default(fov_y_rad: f32, aspect: f32, near_m: f32) -> Result<Self, CullError> {
        Projection::perspective(
            fov_y_rad,
            aspect,
            near_m,
            FarPlane::Infinite,
            DepthConvention::Reverse,
        )
    }

    /// A symmetric orthographic projection of `width_m` x `height_m`, looking down -z from
    /// `near_m` to `far_m` (any finite `near_m < far_m`).
    pub fn orthographic(
        width_m: f32,
        height_m: f32,
        near_m: f32,
        far_m: f32,
        depth: DepthConvention,
    ) -> Result<Self, CullError> {
        if !(width_m.is_finite() && width_m > 0.0) {
            return Err(invalid("width_m", width_m, "must be finite and > 0"));
        }
        if !(height_m.is_finite() && height_m > 0.0) {
            return Err(invalid("height_m", height_m, "must be finite and > 0"));
        }
        if !near_m.is_finite() {
            return Err(invalid("near_m", near_m, "must be finite"));
        }
        if !(far_m.is_finite() && far_m > near_m) {
            return Err(invalid("far_m", far_m, "must be finite and > near_m"));
        }
        Ok(Projection {
            kind: ProjectionKind::Orthographic {
                width_m,
                height_m,
                near_m,
                far_m,
            },
            depth,
        })
    }

    pub fn kind(&self) -> ProjectionKind {
        self.kind
    }

    pub fn depth_convention(&self) -> DepthConvention {
        self.depth
    }

    pub fn near_m(&self) -> f32 {
        match self.kind {
            ProjectionKind::Perspective { near_m, .. }
            | ProjectionKind::Orthographic { near_m, .. } => near_m,
        }
    }

    pub fn is_perspective(&self) -> bool {
        matches!(self.kind, ProjectionKind::Perspective { .. })
    }

    /// The clip-from-view matrix, built with glam's 0..1-depth constructors (reverse finite =
    /// near and far swapped), then y-flipped.
    pub fn matrix(&self) -> Mat4 {
        let p = match (self.kind, self.depth) {
            (
                ProjectionKind::Perspective {
                    fov_y_rad,
                    aspect,
                    near_m,
                    far,
                },
                depth,
            ) => match (far, depth) {
                (FarPlane::Finite { far_m }, DepthConvention::Standard) => {
                    Mat4::perspective_rh(fov_y_rad, aspect, near_m, far_m)
                }
                (FarPlane::Finite { far_m }, DepthConvention::Reverse) => {
                    Mat4::perspective_rh(fov_y_rad, aspect, far_m, near_m)
                }
                (FarPlane::Infinite, DepthConvention::Standard) => {
                    Mat4::perspective_infinite_rh(fov_y_rad, aspect, near_m)
                }
                (FarPlane::Infinite, DepthConvention::Reverse) => {
                    Mat4::perspective_infinite_reverse_rh(fov_y_rad, aspect, near_m)
                }
            },
            (
                ProjectionKind::Orthographic {
                    width_m,
                    height_m,
                    near_m,
                    far_m,
                },
                depth,
            ) => {
                let (hw, hh) = (width_m * 0.5, height_m * 0.5);
                match depth {
                    DepthConvention::Standard => {
                        Mat4::orthographic_rh(-hw, hw, -hh, hh, near_m, far_m)
                    }
                    DepthConvention::Reverse => {
                        Mat4::orthographic_rh(-hw, hw, -hh, hh, far_m, near_m)
                    }
                }
            }
        };
        FLIP_Y * p
    }

    /// NDC per view-space unit: perspective `ndc = scale * xy / distance`, orthographic
    /// `ndc = scale * xy`. The y scale is negative (the flip).
    pub fn ndc_scale(&self) -> (f64, f64) {
        match self.kind {
            ProjectionKind::Perspective {
                fov_y_rad, aspect, ..
            } => {
                let f = 1.0 / (f64::from(fov_y_rad) * 0.5).tan();
                (f / f64::from(aspect), -f)
            }
            ProjectionKind::Orthographic {
                width_m, height_m, ..
            } => (2.0 / f64::from(width_m), -2.0 / f64::from(height_m)),
        }
    }

    /// The exact depth (f64) of a point at view distance `distance_m` (= -z_view), for
    /// distances at or beyond the near plane. Depth depends on the distance alone for every
    /// projection here, so the nearest depth of a volume is the depth at its nearest distance.
    pub fn depth_at_distance(&self, distance_m: f64) -> f64 {
        match self.kind {
            ProjectionKind::Perspective { near_m, far, .. } => {
                let n = f64::from(near_m);
                match (far, self.depth) {
                    (FarPlane::Finite { far_m }, DepthConvention::Standard) => {
                        let f = f64::from(far_m);
                        f * (distance_m - n) / ((f - n) * distance_m)
                    }
                    (FarPlane::Finite { far_m }, DepthConvention::Reverse) => {
                        let f = f64::from(far_m);
                        n * (f - distance_m) / ((f - n) * distance_m)
                    }
                    (FarPlane::Infinite, DepthConvention::Standard) => 1.0 - n / distance_m,
                    (FarPlane::Infinite, DepthConvention::Reverse) => n / distance_m,
                }
            }
            ProjectionKind::Orthographic { near_m, far_m, .. } => {
                let (n, f) = (f64::from(near_m), f64::from(far_m));
                match self.depth {
                    DepthConvention::Standard => (distance_m - n) / (f - n),
                    DepthConvention::Reverse => (f - distance_m) / (f - n),
                }
            }
        }
    }
}

/// `Mat4::look_at_rh`, re-exported under the name the rest of tilegraph uses for the view.
pub fn view_look_at(eye: Vec3, target: Vec3, up: Vec3) -> Mat4 {
    Mat4::look_at_rh(eye, target, up)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec4;

    fn all_projections() -> Vec<Projection> {
        let fov = 1.0;
        vec![
            Projection::perspective(
                fov,
                1.5,
                0.1,
                FarPlane::Finite { far_m: 500.0 },
                DepthConvention::Standard,
            )
            .unwrap(),
            Projection::perspective(
                fov,
                1.5,
                0.1,
                FarPlane::Finite { far_m: 500.0 },
                DepthConvention::Reverse,
            )
            .unwrap(),
            Projection::perspective(fov, 1.5, 0.1, FarPlane::Infinite, DepthConvention::Standard)
                .unwrap(),
            Projection::tilegraph_default(fov, 1.5, 0.1).unwrap(),
            Projection::orthographic(8.0, 6.0, 0.5, 80.0, DepthConvention::Standard).unwrap(),
            Projection::orthographic(8.0, 6.0, 0.5, 80.0, DepthConvention::Reverse).unwrap(),
        ]
    }

    #[test]
    fn analytic_depth_and_scale_match_the_matrix() {
        for p in all_projections() {
            let m = p.matrix();
            let (sx, sy) = p.ndc_scale();
            for dist in [0.1f32, 0.5, 1.0, 3.0, 40.0, 79.0] {
                if dist < p.near_m() {
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
        for p in all_projections() {
            let near = p.depth_at_distance(f64::from(p.near_m()));
            let expect = match p.depth_convention() {
                DepthConvention::Standard => 0.0,
                DepthConvention::Reverse => 1.0,
            };
            assert!((near - expect).abs() < 1e-12, "{p:?}");
        }
    }

    #[test]
    fn y_up_in_view_is_the_top_row() {
        let p = Projection::tilegraph_default(1.0, 1.0, 0.1).unwrap();
        let clip = p.matrix() * Vec4::new(0.0, 1.0, -2.0, 1.0);
        assert!(clip.y / clip.w < 0.0, "view +y must map to NDC y < 0 (top)");
    }

    #[test]
    fn rejects_bad_parameters() {
        let r = DepthConvention::Reverse;
        assert!(Projection::perspective(0.0, 1.0, 0.1, FarPlane::Infinite, r).is_err());
        assert!(Projection::perspective(1.0, f32::NAN, 0.1, FarPlane::Infinite, r).is_err());
        assert!(Projection::perspective(1.0, 1.0, 0.0, FarPlane::Infinite, r).is_err());
        assert!(
            Projection::perspective(1.0, 1.0, 1.0, FarPlane::Finite { far_m: 1.0 }, r).is_err()
        );
        assert!(Projection::orthographic(1.0, 1.0, 5.0, 2.0, r).is_err());
        assert!(matches!(
            Projection::orthographic(-1.0, 1.0, 0.0, 2.0, r),
            Err(CullError::InvalidProjection {
                parameter: "width_m",
                ..
            })
        ));
    }
}
