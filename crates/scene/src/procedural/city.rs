//! `city`: a grid of blocks with tall buildings (strong occluders) and many small props (cars,
//! lamps, benches, crates, glass bus-stop panes) on the streets between them and in the alleys
//! behind them. From street level most props are hidden.

use glam::{DVec3, Vec3};

use super::{path_projection, shapes, Gen};
use crate::camera::{CameraPath, Waypoint};
use crate::error::SceneError;
use crate::scene::{Material, MaterialClass, MeshId};

/// Block pitch (lot + street), metres.
const PITCH: f64 = 64.0;
/// Lot side inside a block; the rest of the pitch is street.
const LOT: f64 = 48.0;
/// The sidewalk slab reaches this far beyond the lot on every side.
const SIDEWALK: f64 = 2.0;
const SLAB_HEIGHT: f64 = 0.15;
/// Instances per block the layout aims at (buildings + props).
const PER_BLOCK: f64 = 40.0;

pub(super) fn generate(g: &mut Gen, size: usize) -> Result<CameraPath, SceneError> {
    let grid = ((size as f64 / PER_BLOCK).sqrt().round() as usize).max(2);
    let half = grid as f64 * PITCH * 0.5;
    let origin =
        |bx: usize, bz: usize| DVec3::new(bx as f64 * PITCH - half, 0.0, bz as f64 * PITCH - half);

    let concrete = g
        .builder
        .add_material(Material::opaque([0.6, 0.6, 0.62, 1.0]));
    let asphalt = g
        .builder
        .add_material(Material::opaque([0.2, 0.2, 0.22, 1.0]));
    let pavement = g
        .builder
        .add_material(Material::opaque([0.5, 0.48, 0.45, 1.0]));
    let paint = g
        .builder
        .add_material(Material::opaque([0.7, 0.1, 0.1, 1.0]));
    let metal = g
        .builder
        .add_material(Material::opaque([0.3, 0.3, 0.35, 1.0]));
    let wood = g
        .builder
        .add_material(Material::opaque([0.45, 0.3, 0.15, 1.0]));
    let glass = g.builder.add_material(Material {
        base_color: [0.6, 0.8, 0.9, 0.35],
        class: MaterialClass::Blended,
        double_sided: true,
        base_color_texture: None,
        engine_material: None,
    });

    let box_data = shapes::unit_box();
    let building = g.mesh(&box_data, concrete);
    let slab = g.mesh_like(building, &box_data, pavement);
    let crate_ = g.mesh_like(building, &box_data, wood);
    let tower = g.mesh(&shapes::tower(), concrete);
    let ground = g.mesh(&shapes::ground_quad(), asphalt);
    let car = g.mesh(&shapes::car(), paint);
    let lamp = g.mesh(&shapes::lamp(), metal);
    let bench = g.mesh(&shapes::bench(), wood);
    let pane = g.mesh(&shapes::pane(), glass);

    // Ground under the whole city and one street width around it.
    let extent = (grid as f64 * PITCH + 2.0 * PITCH) as f32;
    g.place(ground, DVec3::ZERO, 0.0, Vec3::new(extent, 1.0, extent));

    // Structure: a sidewalk slab and 1, 2 or 4 buildings per block; taller towards the centre.
    // Remember each block's alleys (gaps between its buildings) for props "behind" them.
    let mut split = vec![1usize; grid * grid];
    for bz in 0..grid {
        for bx in 0..grid {
            let o = origin(bx, bz);
            let side = (LOT + 2.0 * SIDEWALK) as f32;
            g.place(
                slab,
                o + DVec3::new(LOT * 0.5, 0.0, LOT * 0.5),
                0.0,
                Vec3::new(side, SLAB_HEIGHT as f32, side),
            );
            let centre = DVec3::new(o.x + LOT * 0.5, 0.0, o.z + LOT * 0.5);
            let closeness = 1.0 - (centre.length() / (half * 1.5)).min(1.0);
            let n = match g.rng.below(3) {
                0 => 1,
                1 => 2,
                _ => 4,
            };
            split[bz * grid + bx] = n;
            let cells: &[(f64, f64, f64, f64)] = match n {
                1 => &[(0.0, 0.0, 1.0, 1.0)],
                2 => &[(0.0, 0.0, 0.5, 1.0), (0.5, 0.0, 1.0, 1.0)],
                _ => &[
                    (0.0, 0.0, 0.5, 0.5),
                    (0.5, 0.0, 1.0, 0.5),
                    (0.0, 0.5, 0.5, 1.0),
                    (0.5, 0.5, 1.0, 1.0),
                ],
            };
            for &(x0, z0, x1, z1) in cells {
                // 2 m inset on each side leaves 4 m alleys between neighbouring buildings.
                let w = (x1 - x0) * LOT - 4.0;
                let d = (z1 - z0) * LOT - 4.0;
                let height = g.rng.range(12.0, 40.0) + 80.0 * closeness * g.rng.unit();
                let pos = o + DVec3::new((x0 + x1) * 0.5 * LOT, SLAB_HEIGHT, (z0 + z1) * 0.5 * LOT);
                let mesh = if g.rng.chance(0.3) { tower } else { building };
                g.place(mesh, pos, 0.0, Vec3::new(w as f32, height as f32, d as f32));
            }
        }
    }

    // Props: exactly the remaining count, spread evenly over the blocks.
    let blocks = grid * grid;
    let remaining = size.saturating_sub(g.count());
    for (b, &split) in split.iter().enumerate() {
        let count = remaining / blocks + usize::from(b < remaining % blocks);
        let o = origin(b % grid, b / grid);
        for _ in 0..count {
            place_prop(g, o, split, [crate_, car, lamp, bench, pane]);
        }
    }

    street_path(grid, &origin)
}

/// One prop on the street along the block's +x or +z side, on its sidewalk, or in an alley.
fn place_prop(g: &mut Gen, o: DVec3, split: usize, [crate_, car, lamp, bench, pane]: [MeshId; 5]) {
    let along = g.rng.range(0.0, PITCH);
    let along_x = g.rng.chance(0.5);
    // Position on a street running along z at x = `across` (or along x, swapped).
    let at = |across: f64, y: f64| {
        if along_x {
            o + DVec3::new(along, y, across)
        } else {
            o + DVec3::new(across, y, along)
        }
    };
    let street_yaw = if along_x {
        0.0
    } else {
        std::f32::consts::FRAC_PI_2
    };
    let kerb = LOT + SIDEWALK - 0.6;
    let roll = g.rng.unit();
    if roll < 0.4 {
        // A car in one of the two lanes, either direction.
        let lane = if g.rng.chance(0.5) { 3.5 } else { 8.5 };
        let flip = if g.rng.chance(0.5) {
            std::f32::consts::PI
        } else {
            0.0
        };
        let jitter = g.rng.range_f32(-0.1, 0.1);
        g.place(
            car,
            at(LOT + SIDEWALK + lane, 0.0),
            street_yaw + flip + jitter,
            Vec3::ONE,
        );
    } else if roll < 0.55 {
        g.place(
            lamp,
            at(kerb, SLAB_HEIGHT),
            street_yaw + std::f32::consts::FRAC_PI_2,
            Vec3::ONE,
        );
    } else if roll < 0.7 {
        g.place(bench, at(LOT + 0.6, SLAB_HEIGHT), street_yaw, Vec3::ONE);
    } else if roll < 0.75 {
        // Bus-stop glass: the blended share of the city.
        let w = g.rng.range_f32(2.0, 4.0);
        g.place(
            pane,
            at(kerb - 0.6, SLAB_HEIGHT),
            street_yaw,
            Vec3::new(w, 2.2, 1.0),
        );
    } else if split > 1 && roll < 0.9 {
        // In an alley between buildings: hidden from every street.
        let s = g.rng.range_f32(0.5, 1.2);
        let pos = if split == 2 || g.rng.chance(0.5) {
            o + DVec3::new(
                LOT * 0.5 + g.rng.range(-1.0, 1.0),
                SLAB_HEIGHT,
                g.rng.range(2.0, LOT - 2.0),
            )
        } else {
            o + DVec3::new(
                g.rng.range(2.0, LOT - 2.0),
                SLAB_HEIGHT,
                LOT * 0.5 + g.rng.range(-1.0, 1.0),
            )
        };
        let yaw = g.rng.yaw();
        g.place(crate_, pos, yaw, Vec3::splat(s));
    } else {
        // Crates and bins along the building fronts.
        let s = g.rng.range_f32(0.5, 1.0);
        let pos = at(LOT + g.rng.range(0.3, 1.4), SLAB_HEIGHT);
        let yaw = g.rng.yaw();
        g.place(crate_, pos, yaw, Vec3::splat(s));
    }
}

/// Street-level fly-through: down a street along +z, a fast 90-degree turn at an intersection
/// into a cross street along +x, then a cut to a second street run the other way, then a cut to
/// a view over the rooftops.
fn street_path(
    grid: usize,
    origin: &dyn Fn(usize, usize) -> DVec3,
) -> Result<CameraPath, SceneError> {
    let eye_y = 1.7;
    let look = 25.0;
    // The street east of block column 0 (x between the lots of columns 0 and 1), road centre.
    let road = LOT + SIDEWALK + (PITCH - LOT - 2.0 * SIDEWALK) * 0.5;
    let x = origin(0, 0).x + road;
    let blocks = (grid - 1).min(3) as f64;
    let z0 = origin(0, 0).z - 10.0;
    // The intersection with the cross street south of block row `blocks - 1`.
    let zi = origin(0, 0).z + (blocks - 1.0) * PITCH + road;
    let run = |p: DVec3, d: DVec3| Waypoint::new(p, p + d * look);
    let (pz, px) = (DVec3::Z, DVec3::X);
    let mut w = Vec::new();
    let mut frames = Vec::new();
    let mut z = z0;
    w.push(run(DVec3::new(x, eye_y, z), pz));
    while zi - z > 24.0 {
        z += 16.0;
        w.push(run(DVec3::new(x, eye_y, z), pz));
        frames.push(24);
    }
    w.push(run(DVec3::new(x, eye_y, zi - 4.0), pz));
    frames.push(((zi - 4.0 - z) * 1.5).max(4.0) as usize);
    // The fast turn: the target swings 90 degrees in 8 frames.
    w.push(run(DVec3::new(x + 4.0, eye_y, zi), px));
    frames.push(8);
    let x_end = x + 4.0 + 2.0 * PITCH.min(blocks * PITCH);
    let mut xx = x + 4.0;
    while x_end - xx > 8.0 {
        xx += 16.0;
        w.push(run(DVec3::new(xx, eye_y, zi), px));
        frames.push(24);
    }
    let first = CameraPath::catmull_rom_timed("city street", &w, &frames, path_projection(0.1))?;

    // Second run after a cut: the last street of the grid, driving -x.
    let gl = grid - 1;
    let zb = origin(0, gl).z - (PITCH - LOT - 2.0 * SIDEWALK) * 0.5 - SIDEWALK;
    let xs = origin(gl, 0).x + road;
    let second = CameraPath::catmull_rom(
        "city street 2",
        &[
            run(DVec3::new(xs, eye_y, zb), -px),
            run(DVec3::new(xs - PITCH, eye_y, zb), -px),
            run(
                DVec3::new(xs - 2.0 * PITCH.min(blocks * PITCH), eye_y, zb),
                -px,
            ),
        ],
        40,
        path_projection(0.1),
    )?;

    // Third, after another cut: a slow pass over the rooftops, looking down the avenues.
    let h = 160.0;
    let c = DVec3::new(0.0, 0.0, 0.0);
    let span = (grid as f64 * PITCH * 0.4).min(400.0);
    let third = CameraPath::catmull_rom(
        "city rooftops",
        &[
            Waypoint::new(c + DVec3::new(-span, h, -span), c),
            Waypoint::new(c + DVec3::new(0.0, h, -span * 1.2), c),
            Waypoint::new(c + DVec3::new(span, h, -span), c),
        ],
        60,
        path_projection(0.5),
    )?;
    Ok(first.then_cut(second).then_cut(third))
}
