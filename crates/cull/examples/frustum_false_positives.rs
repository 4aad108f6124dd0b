//! How many boxes the plane test keeps that the exact SAT rejects, per projection.
//!
//! Boxes are scattered around a camera (centres up to 60 m ahead and 40 m to the sides, half
//! extents 0..6 m); the camera is yawed, pitched and rolled so box axes and frustum planes are
//! not aligned. Prints a markdown table.
//!
//! `cargo run --release -p tilegraph-cull --example frustum_false_positives`

use glam::{EulerRot, Mat4, Quat, Vec3};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use tilegraph_cull::{
    measure_plane_test_false_positives, Aabb, AabbExt, CullError, DepthConvention, Frustum,
    Projection, ProjectionExt,
};

fn main() -> Result<(), CullError> {
    let (s, r) = (DepthConvention::Standard, DepthConvention::Reverse);
    let wide = 16.0 / 9.0;
    let perspective = |fov_y_rad, near, far, depth| Projection::Perspective {
        fov_y_rad,
        near,
        far,
        depth,
    };
    let cases = [
        (
            "perspective reverse-Z infinite, fov 1.1",
            Projection::tilegraph_default(1.1, 0.1),
            wide,
        ),
        (
            "perspective reverse-Z far 60 m, fov 0.8",
            perspective(0.8, 0.05, Some(60.0), r),
            wide,
        ),
        (
            "perspective standard far 40 m, fov 1.4",
            perspective(1.4, 0.5, Some(40.0), s),
            wide,
        ),
        (
            "orthographic 30 x 20 m, 0..50 m",
            Projection::Orthographic {
                half_height: 10.0,
                near: 0.0,
                far: 50.0,
                depth: s,
            },
            30.0 / 20.0,
        ),
    ];
    let boxes_per_case = 100_000;
    println!("| projection | boxes | plane test rejects | SAT rejects | kept by planes but separated (share of kept) | plane rejects SAT keeps |");
    println!("|---|---|---|---|---|---|");
    for (name, p, aspect) in cases {
        p.validate(aspect)?;
        let mut rng = Pcg64::seed_from_u64(42);
        let rot = Quat::from_euler(EulerRot::YXZ, 0.4, 0.2, 0.7);
        let eye = Vec3::new(1.0, 2.0, 3.0);
        let forward = rot * Vec3::NEG_Z;
        let view = Mat4::look_at_rh(eye, eye + forward, rot * Vec3::Y);
        let frustum =
            Frustum::from_clip_from_world(&(p.matrix(aspect) * view), p.depth_convention())?;
        let boxes = (0..boxes_per_case)
            .map(|_| {
                let c = eye
                    + forward * rng.random_range(-5.0..60.0)
                    + Vec3::new(
                        rng.random_range(-40.0..40.0),
                        rng.random_range(-40.0..40.0),
                        rng.random_range(-40.0..40.0),
                    );
                let h = Vec3::new(
                    rng.random_range(0.0..6.0),
                    rng.random_range(0.0..6.0),
                    rng.random_range(0.0..6.0),
                );
                Aabb::from_center_half_extents(c, h)
            })
            .collect::<Result<Vec<_>, _>>()?;
        let acc = measure_plane_test_false_positives(&frustum, &boxes)?;
        println!(
            "| {name} | {} | {} | {} | {} ({:.1}%) | {} |",
            acc.boxes,
            acc.plane_outside,
            acc.sat_outside,
            acc.plane_false_positives,
            100.0 * acc.false_positive_share_of_kept,
            acc.plane_wrongly_rejected
        );
    }
    Ok(())
}
