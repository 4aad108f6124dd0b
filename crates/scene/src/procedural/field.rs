//! `field`: an open plain with scattered rocks, hay bales, sheds, fence panels and lone trees.
//! Almost nothing hides anything: the case where occlusion culling costs more than it saves.

use glam::{DVec3, Vec3};

use super::{path_projection, shapes, Gen};
use crate::camera::{CameraPath, Waypoint};
use crate::error::SceneError;
use crate::scene::{Material, MaterialClass};

/// Ground area per object, square metres.
const AREA_PER_OBJECT: f64 = 400.0;

pub(super) fn generate(g: &mut Gen, size: usize) -> Result<CameraPath, SceneError> {
    let grass = g
        .builder
        .add_material(Material::opaque([0.35, 0.55, 0.2, 1.0]));
    let stone = g
        .builder
        .add_material(Material::opaque([0.5, 0.5, 0.5, 1.0]));
    let straw = g
        .builder
        .add_material(Material::opaque([0.8, 0.7, 0.3, 1.0]));
    let planks = g
        .builder
        .add_material(Material::opaque([0.5, 0.35, 0.2, 1.0]));
    let bark = g
        .builder
        .add_material(Material::opaque([0.35, 0.25, 0.15, 1.0]));
    let leaves = g.builder.add_material(Material {
        base_color: [0.25, 0.5, 0.15, 1.0],
        class: MaterialClass::AlphaTested { cutoff: 0.5 },
        double_sided: true,
        base_color_texture: None,
        engine_material: None,
    });

    let ground = g.mesh(&shapes::ground_quad(), grass);
    let rock = g.mesh(&shapes::rock(), stone);
    let bale = g.mesh(&shapes::bale(), straw);
    let box_data = shapes::unit_box();
    let shed = g.mesh(&box_data, planks);
    let trunk = g.mesh(&shapes::trunk(), bark);
    let crown = g.mesh(&shapes::foliage_card(), leaves);

    let half = (size as f64 * AREA_PER_OBJECT).sqrt() * 0.5;
    g.place(
        ground,
        DVec3::ZERO,
        0.0,
        Vec3::splat((2.0 * half + 200.0) as f32).with_y(1.0),
    );

    while g.count() < size {
        let pos = DVec3::new(g.rng.range(-half, half), 0.0, g.rng.range(-half, half));
        let yaw = g.rng.yaw();
        let roll = g.rng.unit();
        if roll < 0.4 {
            let s = g.rng.range_f32(0.5, 2.5);
            g.place(rock, pos, yaw, Vec3::new(s, s * 0.6, s));
        } else if roll < 0.65 {
            g.place(bale, pos, yaw, Vec3::ONE);
        } else if roll < 0.75 {
            let h = g.rng.range_f32(2.5, 4.0);
            g.place(shed, pos, yaw, Vec3::new(4.0, h, 6.0));
        } else if roll < 0.85 {
            // A fence panel: long, low, thin.
            g.place(shed, pos, yaw, Vec3::new(3.0, 1.1, 0.08));
        } else if g.count() + 2 <= size {
            let h = g.rng.range_f32(4.0, 9.0);
            g.place(trunk, pos, yaw, Vec3::new(0.5, h, 0.5));
            let w = g.rng.range_f32(4.0, 7.0);
            g.place(
                crown,
                pos + DVec3::Y * f64::from(h) * 0.5,
                yaw,
                Vec3::new(w, h * 0.8, w),
            );
        } else {
            g.place(rock, pos, yaw, Vec3::splat(0.8));
        }
    }

    // A low fly-over across the plain with a gentle turn, then a cut to eye level looking
    // along the ground at the horizon.
    let r = half * 0.8;
    let fly = CameraPath::catmull_rom(
        "field fly-over",
        &[
            Waypoint::new(
                DVec3::new(-r, 30.0, -r * 0.2),
                DVec3::new(-r + 100.0, 10.0, -r * 0.2),
            ),
            Waypoint::new(
                DVec3::new(-r * 0.3, 35.0, 0.0),
                DVec3::new(-r * 0.3 + 100.0, 10.0, 20.0),
            ),
            Waypoint::new(
                DVec3::new(r * 0.3, 30.0, r * 0.2),
                DVec3::new(r * 0.3 + 60.0, 8.0, r * 0.2 + 80.0),
            ),
            Waypoint::new(
                DVec3::new(r * 0.6, 30.0, r * 0.6),
                DVec3::new(r * 0.6, 8.0, r * 0.6 + 100.0),
            ),
        ],
        60,
        path_projection(0.1),
    )?;
    let walk = CameraPath::catmull_rom(
        "field walk",
        &[
            Waypoint::new(DVec3::new(0.0, 1.7, 0.0), DVec3::new(0.0, 1.7, -100.0)),
            Waypoint::new(DVec3::new(10.0, 1.7, -20.0), DVec3::new(100.0, 1.7, -60.0)),
        ],
        120,
        path_projection(0.1),
    )?;
    Ok(fly.then_cut(walk))
}
