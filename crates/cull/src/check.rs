//! Input validation shared by the modules: every public entry point runs its inputs through
//! these before any arithmetic, so a NaN surfaces as a typed error instead of a silent
//! "visible" or "culled".

use glam::{Affine3A, Mat4, Vec3};

use crate::CullError;

pub(crate) fn finite_f32(
    what: &'static str,
    field: &'static str,
    value: f32,
) -> Result<(), CullError> {
    if value.is_finite() {
        Ok(())
    } else {
        Err(CullError::NonFiniteValue { what, field, value })
    }
}

pub(crate) fn finite_vec3(
    what: &'static str,
    field: &'static str,
    v: Vec3,
) -> Result<(), CullError> {
    for c in v.to_array() {
        finite_f32(what, field, c)?;
    }
    Ok(())
}

pub(crate) fn finite_mat4(what: &'static str, m: &Mat4) -> Result<(), CullError> {
    for (column, col) in m.to_cols_array_2d().iter().enumerate() {
        for (row, &value) in col.iter().enumerate() {
            if !value.is_finite() {
                return Err(CullError::NonFiniteMatrix {
                    what,
                    column,
                    row,
                    value,
                });
            }
        }
    }
    Ok(())
}

pub(crate) fn finite_affine(what: &'static str, m: &Affine3A) -> Result<(), CullError> {
    finite_mat4(what, &Mat4::from(*m))
}
