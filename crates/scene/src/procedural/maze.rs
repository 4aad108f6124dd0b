//! `maze`: square rooms on a grid, their walls pierced by doors at random, strewn with what
//! breaks culling below the instance: wires 1 mm and 2 cm wide, needles whose apex lies 1e-6 of
//! their length off the base line, zero-area triangles, upright cards seen edge-on, pillars 2 cm
//! to 30 cm wide, cubes of 5 mm and 3 cm. Every surface is opaque and, but for the cards,
//! single-sided. Baked into one mesh (`maze@one-mesh`) it is the kind of level on which a
//! cluster's bounds and back-facing cone must hold for triangles no artist tuned, walked at eye
//! height with yaw sweeps and cuts (`CameraPath::eye_height_walk`).

use glam::{DVec3, Mat3, Vec3};

use super::shapes::{self, MeshData};
use super::Gen;
use crate::bounds::DAabb;
use crate::camera::CameraPath;
use crate::error::SceneError;
use crate::scene::{Material, MeshId};

const ROOM: f64 = 8.0;
const HEIGHT: f32 = 3.0;
const WALL: f32 = 0.2;
const DOOR_W: f64 = 1.0;
/// Instances per room the layout aims at: a floor, about four wall pieces, the rest clutter.
const PER_ROOM: f64 = 30.0;
/// Length of the wires, needles, zero-area pieces and cards.
const WIRE_LEN: f32 = 6.0;
/// Frames of the default walk.
const PATH_FRAMES: usize = 240;

/// The clutter meshes: each lies along local x, centred on the origin, facing +z.
struct Clutter {
    pillar: MeshId,
    wires: [MeshId; 5],
    cubes: [MeshId; 2],
}

pub(super) fn generate(g: &mut Gen, size: usize) -> Result<CameraPath, SceneError> {
    let plaster = g
        .builder
        .add_material(Material::opaque([0.82, 0.8, 0.76, 1.0]));
    let stone = g
        .builder
        .add_material(Material::opaque([0.45, 0.42, 0.4, 1.0]));
    let metal = g
        .builder
        .add_material(Material::opaque([0.25, 0.3, 0.35, 1.0]));
    let paint = g
        .builder
        .add_material(Material::opaque([0.85, 0.55, 0.15, 1.0]));
    let card = g.builder.add_material(Material {
        double_sided: true,
        ..Material::opaque([0.3, 0.5, 0.8, 1.0])
    });

    let wall = g.mesh(&shapes::unit_box(), plaster);
    let floor = g.mesh(&shapes::ground_quad(), stone);
    let mut pillar = MeshData::default();
    pillar.cylinder(1.0, 0.0, 1.0, 6);
    let half = WIRE_LEN * 0.5;
    let strip = |width: f32| {
        let mut m = MeshData::default();
        m.quad(
            Vec3::new(-half, 0.0, 0.0),
            Vec3::X * WIRE_LEN,
            Vec3::Y * width,
        );
        m
    };
    let mut needle = MeshData::default();
    needle.triangle(
        Vec3::new(-half, 0.0, 0.0),
        Vec3::new(half, 0.0, 0.0),
        Vec3::new(0.0, WIRE_LEN * 1e-6, 0.0),
    );
    // Zero area twice over: three points on a line, and a repeated corner.
    let mut zero = MeshData::default();
    zero.triangle(
        Vec3::new(-half, 0.0, 0.0),
        Vec3::ZERO,
        Vec3::new(half, 0.0, 0.0),
    );
    zero.triangle(
        Vec3::new(-half, 0.0, 0.0),
        Vec3::new(-half, 0.0, 0.0),
        Vec3::new(half, 0.0, 0.0),
    );
    let mut upright = MeshData::default();
    upright.quad(Vec3::new(-half, 0.0, 0.0), Vec3::X * WIRE_LEN, Vec3::Y);
    let cube = |edge: f32| {
        let mut m = MeshData::default();
        m.cuboid(
            Vec3::new(-0.5, 0.0, -0.5) * edge,
            Vec3::new(0.5, 1.0, 0.5) * edge,
        );
        m
    };
    let clutter = Clutter {
        pillar: g.mesh(&pillar, metal),
        wires: [
            g.mesh(&strip(0.001), metal),
            g.mesh(&strip(0.02), metal),
            g.mesh(&needle, paint),
            g.mesh(&zero, paint),
            g.mesh(&upright, card),
        ],
        cubes: [g.mesh(&cube(0.005), paint), g.mesh(&cube(0.03), paint)],
    };

    let n = ((size as f64 / PER_ROOM).sqrt().round() as usize).max(2);
    let width = n as f64 * ROOM;
    let origin = DVec3::new(-width * 0.5, 0.0, -width * 0.5);
    for r in 0..n {
        for c in 0..n {
            let o = origin + DVec3::new(c as f64 * ROOM, 0.0, r as f64 * ROOM);
            let centre = o + DVec3::new(ROOM * 0.5, 0.0, ROOM * 0.5);
            g.place(floor, centre, 0.0, Vec3::new(ROOM as f32, 1.0, ROOM as f32));
            // The north and west walls inside the grid: three in four stand, most with a door.
            for (inside, along_x) in [(r > 0, true), (c > 0, false)] {
                if inside && g.rng.chance(0.75) {
                    let door = g
                        .rng
                        .chance(0.85)
                        .then(|| g.rng.range(0.5, ROOM - 0.5 - DOOR_W));
                    wall_run(g, wall, o, along_x, door);
                }
            }
        }
    }
    // The outer shell, solid.
    for k in 0..n {
        let along = origin + DVec3::X * (k as f64 * ROOM);
        let across = origin + DVec3::Z * (k as f64 * ROOM);
        wall_run(g, wall, along, true, None);
        wall_run(g, wall, along + DVec3::Z * width, true, None);
        wall_run(g, wall, across, false, None);
        wall_run(g, wall, across + DVec3::X * width, false, None);
    }

    // Clutter fills the count exactly, spread evenly over the rooms.
    let rooms = n * n;
    let remaining = size.saturating_sub(g.count());
    for k in 0..rooms {
        let o = origin + DVec3::new((k % n) as f64 * ROOM, 0.0, (k / n) as f64 * ROOM);
        for _ in 0..remaining / rooms + usize::from(k < remaining % rooms) {
            let at = o + DVec3::new(
                g.rng.range(0.3, ROOM - 0.3),
                0.0,
                g.rng.range(0.3, ROOM - 0.3),
            );
            place_clutter(g, &clutter, at);
        }
    }

    let bounds = DAabb::new(
        origin - DVec3::splat(f64::from(WALL)),
        origin + DVec3::new(width, f64::from(HEIGHT), width) + DVec3::splat(f64::from(WALL)),
    );
    let seed = g.rng.below(1 << 30) as u64;
    Ok(CameraPath::eye_height_walk(&bounds, PATH_FRAMES, seed))
}

/// One piece of clutter at `at` (on the floor of a room).
fn place_clutter(g: &mut Gen, m: &Clutter, at: DVec3) {
    let yaw = g.rng.yaw();
    let roll = g.rng.unit();
    if roll < 0.08 {
        let radius = [0.01, 0.05, 0.15][g.rng.below(3)];
        let height = g.rng.range_f32(0.3, HEIGHT);
        g.place(m.pillar, at, yaw, Vec3::new(radius, height, radius));
    } else if roll < 0.3 {
        // A wire at any height, tilted up to 4.6 degrees out of level (its ends 0.24 m up or
        // down), or a card standing on the floor.
        let kind = g.rng.below(m.wires.len());
        let (y, tilt) = if kind == 4 {
            (0.0, 0.0)
        } else {
            (g.rng.range(0.6, 2.7), g.rng.range_f32(-0.08, 0.08))
        };
        let linear = Mat3::from_rotation_y(yaw) * Mat3::from_rotation_z(tilt);
        g.place_linear(m.wires[kind], at + DVec3::Y * y, linear);
    } else {
        let cube = m.cubes[g.rng.below(2)];
        let y = g.rng.range(0.0, 2.5);
        g.place(cube, at + DVec3::Y * y, yaw, Vec3::ONE);
    }
}

/// A wall along x (or z) from `o` for a room's length, with a door `door` metres in.
fn wall_run(g: &mut Gen, wall: MeshId, o: DVec3, along_x: bool, door: Option<f64>) {
    let (dir, yaw) = if along_x {
        (DVec3::X, 0.0)
    } else {
        (DVec3::Z, -std::f32::consts::FRAC_PI_2)
    };
    let piece = |g: &mut Gen, from: f64, to: f64| {
        g.place(
            wall,
            o + dir * ((from + to) * 0.5),
            yaw,
            Vec3::new((to - from) as f32, HEIGHT, WALL),
        );
    };
    match door {
        None => piece(g, 0.0, ROOM),
        Some(at) => {
            piece(g, 0.0, at);
            piece(g, at + DOOR_W, ROOM);
        }
    }
}
