//! `forest`: trees on a jittered grid — an opaque trunk and two or three alpha-tested,
//! double-sided foliage cards each — with bushes (small cards) and rocks between them.
//! Most coverage is alpha-tested: the case for the alpha-tested pre-pass.

use glam::{DVec3, Vec3};

use super::{path_projection, shapes, Gen};
use crate::camera::{CameraPath, Waypoint};
use crate::error::SceneError;
use crate::scene::{Material, MaterialClass};

/// Tree spacing on the grid, metres.
const SPACING: f64 = 5.0;
/// Share of the instances that belong to trees; the rest are bushes and rocks.
const TREE_SHARE: f64 = 0.8;

pub(super) fn generate(g: &mut Gen, size: usize) -> Result<CameraPath, SceneError> {
    let bark = g
        .builder
        .add_material(Material::opaque([0.35, 0.25, 0.15, 1.0]));
    let soil = g
        .builder
        .add_material(Material::opaque([0.25, 0.3, 0.15, 1.0]));
    let stone = g
        .builder
        .add_material(Material::opaque([0.45, 0.45, 0.45, 1.0]));
    let leaves = g.builder.add_material(Material {
        base_color: [0.2, 0.5, 0.15, 1.0],
        class: MaterialClass::AlphaTested { cutoff: 0.5 },
        double_sided: true,
        base_color_texture: None,
        engine_material: None,
    });
    let undergrowth = g.builder.add_material(Material {
        base_color: [0.3, 0.55, 0.2, 1.0],
        class: MaterialClass::AlphaTested { cutoff: 0.35 },
        double_sided: true,
        base_color_texture: None,
        engine_material: None,
    });

    let trunk = g.mesh(&shapes::trunk(), bark);
    let card_data = shapes::foliage_card();
    let card = g.mesh(&card_data, leaves);
    let bush = g.mesh_like(card, &card_data, undergrowth);
    let rock = g.mesh(&shapes::rock(), stone);
    let ground = g.mesh(&shapes::ground_quad(), soil);

    // About 3.5 instances per tree: size the grid to hold the expected number of trees.
    let trees = ((size as f64 * TREE_SHARE) / 3.5).max(4.0);
    let side = trees.sqrt().ceil() as usize;
    let half = side as f64 * SPACING * 0.5;
    let extent = (side as f64 * SPACING + 40.0) as f32;
    g.place(ground, DVec3::ZERO, 0.0, Vec3::new(extent, 1.0, extent));

    let tree_budget = (size as f64 * TREE_SHARE) as usize;
    let mut cell = 0usize;
    while g.count() + 4 <= tree_budget.max(5) && cell < side * side {
        let (i, j) = (cell % side, cell / side);
        cell += 1;
        let pos = DVec3::new(
            i as f64 * SPACING - half + g.rng.range(0.5, SPACING - 0.5),
            0.0,
            j as f64 * SPACING - half + g.rng.range(0.5, SPACING - 0.5),
        );
        let height = g.rng.range_f32(6.0, 14.0);
        let radius = g.rng.range_f32(0.15, 0.35);
        let yaw = g.rng.yaw();
        g.place(
            trunk,
            pos,
            yaw,
            Vec3::new(2.0 * radius, height, 2.0 * radius),
        );
        let cards = 2 + g.rng.below(2);
        for c in 0..cards {
            let w = g.rng.range_f32(3.5, 6.0);
            let h = g.rng.range_f32(3.0, 5.0);
            let y = f64::from(height) * (0.35 + 0.2 * c as f64);
            let yaw = g.rng.yaw();
            g.place(card, pos + DVec3::Y * y, yaw, Vec3::new(w, h, w));
        }
    }

    // Bushes and rocks fill the count exactly, anywhere on the forest floor.
    while g.count() < size {
        let pos = DVec3::new(g.rng.range(-half, half), 0.0, g.rng.range(-half, half));
        if g.rng.chance(0.7) {
            let s = g.rng.range_f32(0.8, 1.6);
            let yaw = g.rng.yaw();
            g.place(bush, pos, yaw, Vec3::splat(s));
        } else {
            let s = g.rng.range_f32(0.4, 1.5);
            let yaw = g.rng.yaw();
            g.place(rock, pos, yaw, Vec3::new(s, s * 0.7, s));
        }
    }

    // A walk at eye height that weaves through the trees, then a cut to a pass just above the
    // canopy looking down the slope of it.
    let walk_len = (half * 1.6).max(20.0);
    let mut w = Vec::new();
    let steps = 8;
    for k in 0..=steps {
        let t = k as f64 / steps as f64;
        let x = -walk_len * 0.5 + walk_len * t;
        let z = (t * std::f64::consts::TAU).sin() * walk_len * 0.15;
        let eye = DVec3::new(x, 1.7, z);
        let ahead = DVec3::new(
            x + 10.0,
            1.5,
            (t * std::f64::consts::TAU + 0.4).sin() * walk_len * 0.15,
        );
        w.push(Waypoint::new(eye, ahead));
    }
    let per = ((walk_len / steps as f64) * 3.0).max(6.0) as usize;
    let walk = CameraPath::catmull_rom("forest walk", &w, per, path_projection(0.05))?;
    let over = CameraPath::catmull_rom(
        "forest canopy",
        &[
            Waypoint::new(
                DVec3::new(-half * 0.8, 25.0, -half * 0.8),
                DVec3::new(0.0, 5.0, 0.0),
            ),
            Waypoint::new(
                DVec3::new(0.0, 22.0, -half * 0.9),
                DVec3::new(0.0, 5.0, 0.0),
            ),
            Waypoint::new(
                DVec3::new(half * 0.8, 25.0, -half * 0.8),
                DVec3::new(0.0, 5.0, 0.0),
            ),
        ],
        60,
        path_projection(0.1),
    )?;
    Ok(walk.then_cut(over))
}
