//! Views and projections in tilegraph's conventions: right-handed view space looking down -z,
//! Vulkan clip space (depth in [0, 1]) with the y flip inside the projection, so NDC y = -1 is
//! the top row.
//!
//! The projection is tilegraph-types' [`Projection`], the same value a scene's camera holds;
//! the aspect of the viewport travels beside it (`matrix(aspect)`, `ndc_scale(aspect)`), as
//! when the scene renders. [`ProjectionExt::validate`] checks both before a reference uses
//! them.

use glam::{Mat4, Vec3};

pub use tilegraph_types::Projection;

use crate::CullError;

/// The culling references' check of the shared [`Projection`] on a viewport of `aspect`
/// (width / height). A trait because the projection lives in tilegraph-types, which knows no
/// [`CullError`]; its fields are public, so every entry point here that takes a projection
/// checks it.
pub trait ProjectionExt {
    /// Perspective: `fov_y_rad` in (0, pi), `near` finite and > 0, a finite `far` above
    /// `near`. Orthographic: `half_height` finite and > 0, any finite `near` below a finite
    /// `far`. Both: `aspect` finite and > 0, and for orthographic a half width
    /// (`half_height * aspect`) that neither overflows nor vanishes in f32.
    fn validate(&self, aspect: f32) -> Result<(), CullError>;
}

fn invalid(parameter: &'static str, value: f32, reason: &'static str) -> CullError {
    CullError::InvalidProjection {
        parameter,
        value,
        reason,
    }
}

fn check_aspect(aspect: f32) -> Result<(), CullError> {
    if aspect.is_finite() && aspect > 0.0 {
        Ok(())
    } else {
        Err(invalid("aspect", aspect, "must be finite and > 0"))
    }
}

impl ProjectionExt for Projection {
    fn validate(&self, aspect: f32) -> Result<(), CullError> {
        match *self {
            Projection::Perspective {
                fov_y_rad,
                near,
                far,
                ..
            } => {
                if !(fov_y_rad.is_finite() && fov_y_rad > 0.0 && fov_y_rad < std::f32::consts::PI) {
                    return Err(invalid("fov_y_rad", fov_y_rad, "must lie in (0, pi)"));
                }
                check_aspect(aspect)?;
                if !(near.is_finite() && near > 0.0) {
                    return Err(invalid("near", near, "must be finite and > 0"));
                }
                if let Some(far) = far {
                    if !(far.is_finite() && far > near) {
                        return Err(invalid("far", far, "must be finite and > near"));
                    }
                }
            }
            Projection::Orthographic {
                half_height,
                near,
                far,
                ..
            } => {
                if !(half_height.is_finite() && half_height > 0.0) {
                    return Err(invalid(
                        "half_height",
                        half_height,
                        "must be finite and > 0",
                    ));
                }
                check_aspect(aspect)?;
                // The NDC scale divides by the half width the matrix uses: an infinite one
                // would squeeze every rect to the centre line, a zero one spread it to infinity.
                let half_width = half_height * aspect;
                if !(half_width.is_finite() && half_width > 0.0) {
                    return Err(invalid(
                        "aspect",
                        aspect,
                        "half_height * aspect must be finite and > 0",
                    ));
                }
                if !near.is_finite() {
                    return Err(invalid("near", near, "must be finite"));
                }
                if !(far.is_finite() && far > near) {
                    return Err(invalid("far", far, "must be finite and > near"));
                }
            }
        }
        Ok(())
    }
}

/// `Mat4::look_at_rh`, re-exported under the name the rest of tilegraph uses for the view.
pub fn view_look_at(eye: Vec3, target: Vec3, up: Vec3) -> Mat4 {
    Mat4::look_at_rh(eye, target, up)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::depth::DepthConvention;

    fn perspective(fov_y_rad: f32, near: f32, far: Option<f32>) -> Projection {
        Projection::Perspective {
            fov_y_rad,
            near,
            far,
            depth: DepthConvention::Reverse,
        }
    }

    fn orthographic(half_height: f32, near: f32, far: f32) -> Projection {
        Projection::Orthographic {
            half_height,
            near,
            far,
            depth: DepthConvention::Reverse,
        }
    }

    #[test]
    fn rejects_bad_parameters() {
        assert!(perspective(0.0, 0.1, None).validate(1.0).is_err());
        assert!(perspective(1.0, 0.1, None).validate(f32::NAN).is_err());
        assert!(perspective(1.0, 0.0, None).validate(1.0).is_err());
        assert!(perspective(1.0, 1.0, Some(1.0)).validate(1.0).is_err());
        assert!(orthographic(0.5, 5.0, 2.0).validate(1.0).is_err());
        assert!(matches!(
            orthographic(-0.5, 0.0, 2.0).validate(1.0),
            Err(CullError::InvalidProjection {
                parameter: "half_height",
                ..
            })
        ));
    }

    #[test]
    fn an_orthographic_width_past_f32_is_rejected() {
        assert!(orthographic(1e30, 0.0, 2.0).validate(1.0).is_ok());
        assert!(matches!(
            orthographic(1e30, 0.0, 2.0).validate(1e10),
            Err(CullError::InvalidProjection {
                parameter: "aspect",
                ..
            })
        ));
    }
}
