//! `interior`: a single storey of rooms on a grid, with a corridor every fourth row. Walls have
//! doors (a gap and a lintel), so what is visible from a room is what the doors let through:
//! portal-like occlusion. Rooms hold tables, chairs, shelves, potted plants (alpha-tested cards)
//! and glass partitions (blended).

use glam::{DVec3, Mat3, Vec3};

use super::{path_projection, shapes, Gen};
use crate::camera::{CameraPath, Waypoint};
use crate::error::SceneError;
use crate::scene::{Material, MaterialClass, MeshId};

const ROOM_W: f64 = 8.0;
const ROOM_D: f64 = 6.0;
const CORRIDOR_D: f64 = 3.0;
const HEIGHT: f64 = 3.0;
const WALL: f32 = 0.2;
const DOOR_W: f64 = 1.0;
const DOOR_H: f64 = 2.1;
/// Instances per cell the layout aims at (structure about 8, the rest props).
const PER_CELL: f64 = 20.0;

fn is_corridor(row: usize) -> bool {
    row % 4 == 3
}

struct Meshes {
    wall: MeshId,
    floor: MeshId,
    ceiling: MeshId,
}

pub(super) fn generate(g: &mut Gen, size: usize) -> Result<CameraPath, SceneError> {
    let plaster = g
        .builder
        .add_material(Material::opaque([0.85, 0.83, 0.8, 1.0]));
    let carpet = g
        .builder
        .add_material(Material::opaque([0.4, 0.35, 0.3, 1.0]));
    let ceiling_mat = g
        .builder
        .add_material(Material::opaque([0.95, 0.95, 0.95, 1.0]));
    let wood = g
        .builder
        .add_material(Material::opaque([0.5, 0.35, 0.2, 1.0]));
    let glass = g.builder.add_material(Material {
        base_color: [0.7, 0.85, 0.9, 0.3],
        class: MaterialClass::Blended,
        double_sided: true,
        base_color_texture: None,
        engine_material: None,
    });
    let leaves = g.builder.add_material(Material {
        base_color: [0.2, 0.5, 0.2, 1.0],
        class: MaterialClass::AlphaTested { cutoff: 0.5 },
        double_sided: true,
        base_color_texture: None,
        engine_material: None,
    });

    let box_data = shapes::unit_box();
    let quad = shapes::ground_quad();
    let m = Meshes {
        wall: g.mesh(&box_data, plaster),
        floor: g.mesh(&quad, carpet),
        ceiling: g.mesh(&quad, ceiling_mat),
    };
    let shelf = g.mesh_like(m.wall, &box_data, wood);
    let table = g.mesh(&shapes::table(), wood);
    let chair = g.mesh(&shapes::chair(), wood);
    let pane = g.mesh(&shapes::pane(), glass);
    let plant = g.mesh(&shapes::foliage_card(), leaves);

    let cells = (size as f64 / PER_CELL).max(8.0);
    let rows = (cells.sqrt().round() as usize).max(4);
    let cols = ((cells / rows as f64).round() as usize).max(2);
    // Row z origins: rooms are ROOM_D deep, corridors CORRIDOR_D.
    let mut row_z = Vec::with_capacity(rows + 1);
    let mut z = 0.0;
    for r in 0..rows {
        row_z.push(z);
        z += if is_corridor(r) { CORRIDOR_D } else { ROOM_D };
    }
    row_z.push(z);
    let (width, depth) = (cols as f64 * ROOM_W, z);
    let shift = DVec3::new(-width * 0.5, 0.0, -depth * 0.5);

    // Door positions (x offset inside the cell) on each cell's north wall, for the camera path.
    let mut north_door = vec![None; rows * cols];
    for r in 0..rows {
        let d = row_z[r + 1] - row_z[r];
        for c in 0..cols {
            let o = shift + DVec3::new(c as f64 * ROOM_W, 0.0, row_z[r]);
            g.place(
                m.floor,
                o + DVec3::new(ROOM_W * 0.5, 0.0, d * 0.5),
                0.0,
                Vec3::new(ROOM_W as f32, 1.0, d as f32),
            );
            // The ceiling is the floor quad turned over (a rotation, not a mirror, so that it
            // faces down with the right winding).
            g.place_linear(
                m.ceiling,
                o + DVec3::new(ROOM_W * 0.5, HEIGHT, d * 0.5),
                Mat3::from_rotation_x(std::f32::consts::PI)
                    * Mat3::from_diagonal(Vec3::new(ROOM_W as f32, 1.0, d as f32)),
            );
            // North wall (along x at the cell's z0), except on the first row's outside.
            if r > 0 {
                let corridor_side = is_corridor(r) || is_corridor(r - 1);
                let door = corridor_side || g.rng.chance(0.6);
                let at = door.then(|| g.rng.range(1.0, ROOM_W - 1.0 - DOOR_W));
                wall_x(g, &m, o, ROOM_W, at);
                north_door[r * cols + c] = at;
            }
            // West wall (along z at the cell's x0); corridors run through, so only rooms get one.
            if c > 0 && !is_corridor(r) {
                let at = g
                    .rng
                    .chance(0.5)
                    .then(|| g.rng.range(1.0, d - 1.0 - DOOR_W));
                wall_z(g, &m, o, d, at);
            }
        }
    }
    // The outer shell.
    for c in 0..cols {
        let x0 = shift.x + c as f64 * ROOM_W;
        wall_x(g, &m, DVec3::new(x0, 0.0, shift.z), ROOM_W, None);
        wall_x(g, &m, DVec3::new(x0, 0.0, shift.z + depth), ROOM_W, None);
    }
    for r in 0..rows {
        let d = row_z[r + 1] - row_z[r];
        let z0 = shift.z + row_z[r];
        wall_z(g, &m, DVec3::new(shift.x, 0.0, z0), d, None);
        wall_z(g, &m, DVec3::new(shift.x + width, 0.0, z0), d, None);
    }

    // Furniture fills the count exactly: rooms get most, corridors a plant now and then.
    let room_cells: Vec<(usize, usize)> = (0..rows)
        .flat_map(|r| (0..cols).map(move |c| (r, c)))
        .filter(|&(r, _)| !is_corridor(r))
        .collect();
    let remaining = size.saturating_sub(g.count());
    let n_cells = room_cells.len().max(1);
    for (k, &(r, c)) in room_cells.iter().enumerate() {
        let count = remaining / n_cells + usize::from(k < remaining % n_cells);
        let o = shift + DVec3::new(c as f64 * ROOM_W, 0.0, row_z[r]);
        for _ in 0..count {
            let p = o + DVec3::new(
                g.rng.range(0.8, ROOM_W - 0.8),
                0.0,
                g.rng.range(0.8, ROOM_D - 0.8),
            );
            let roll = g.rng.unit();
            let yaw = g.rng.yaw();
            if roll < 0.3 {
                g.place(table, p, yaw, Vec3::ONE);
            } else if roll < 0.7 {
                g.place(chair, p, yaw, Vec3::ONE);
            } else if roll < 0.82 {
                g.place(shelf, p, yaw, Vec3::new(1.2, 2.0, 0.4));
            } else if roll < 0.94 {
                g.place(plant, p, yaw, Vec3::new(0.8, 1.4, 0.8));
            } else {
                g.place(pane, p, yaw, Vec3::new(2.0, 2.4, 1.0));
            }
        }
    }

    interior_path(rows, cols, &row_z, shift, &north_door)
}

/// A wall along x from `o` for `len` metres, with an optional door starting `door` metres in.
fn wall_x(g: &mut Gen, m: &Meshes, o: DVec3, len: f64, door: Option<f64>) {
    wall(g, m, o, len, door, 0.0);
}

/// A wall along z from `o` for `len` metres.
fn wall_z(g: &mut Gen, m: &Meshes, o: DVec3, len: f64, door: Option<f64>) {
    wall(g, m, o, len, door, -std::f32::consts::FRAC_PI_2);
}

fn wall(g: &mut Gen, m: &Meshes, o: DVec3, len: f64, door: Option<f64>, yaw: f32) {
    // Local x runs along the wall; yaw -90 degrees turns +x into +z.
    let dir = if yaw == 0.0 { DVec3::X } else { DVec3::Z };
    let seg = |g: &mut Gen, from: f64, to: f64, y0: f64, y1: f64| {
        let mid = o + dir * ((from + to) * 0.5) + DVec3::Y * y0;
        g.place(
            m.wall,
            mid,
            yaw,
            Vec3::new((to - from) as f32, (y1 - y0) as f32, WALL),
        );
    };
    match door {
        None => seg(g, 0.0, len, 0.0, HEIGHT),
        Some(at) => {
            seg(g, 0.0, at, 0.0, HEIGHT);
            seg(g, at + DOOR_W, len, 0.0, HEIGHT);
            seg(g, at, at + DOOR_W, DOOR_H, HEIGHT);
        }
    }
}

/// Walk down the first corridor, turn fast through a door into the room north of it, cross
/// the room; cut to the next corridor (if any) and walk it the other way.
fn interior_path(
    rows: usize,
    cols: usize,
    row_z: &[f64],
    shift: DVec3,
    north_door: &[Option<f64>],
) -> Result<CameraPath, SceneError> {
    let eye_y = 1.6;
    let corridor = 3usize.min(rows - 1);
    let zc = shift.z + row_z[corridor] + CORRIDOR_D * 0.5;
    // The door into the room north of the corridor, in the column furthest along the walk.
    let col = (cols - 1).min(3);
    let door_x = shift.x
        + col as f64 * ROOM_W
        + north_door
            .get(corridor * cols + col)
            .copied()
            .flatten()
            .unwrap_or(ROOM_W * 0.5)
        + DOOR_W * 0.5;
    let start_x = shift.x + 1.0;
    let look = 10.0;
    let mut w = vec![Waypoint::new(
        DVec3::new(start_x, eye_y, zc),
        DVec3::new(start_x + look, eye_y, zc),
    )];
    let mut frames = Vec::new();
    let mut x = start_x;
    while door_x - 1.0 - x > 6.0 {
        x += 4.0;
        w.push(Waypoint::new(
            DVec3::new(x, eye_y, zc),
            DVec3::new(x + look, eye_y, zc),
        ));
        frames.push(30);
    }
    w.push(Waypoint::new(
        DVec3::new(door_x - 1.0, eye_y, zc),
        DVec3::new(door_x - 1.0 + look, eye_y, zc),
    ));
    frames.push(20);
    // Fast turn to face the door (north is -z), then through it and across the room.
    let z_wall = shift.z + row_z[corridor];
    w.push(Waypoint::new(
        DVec3::new(door_x, eye_y, zc),
        DVec3::new(door_x, eye_y, zc - look),
    ));
    frames.push(8);
    w.push(Waypoint::new(
        DVec3::new(door_x, eye_y, z_wall),
        DVec3::new(door_x, eye_y, z_wall - look),
    ));
    frames.push(20);
    w.push(Waypoint::new(
        DVec3::new(door_x, eye_y, z_wall - ROOM_D + 1.5),
        DVec3::new(door_x + 3.0, eye_y, z_wall - ROOM_D - look),
    ));
    frames.push(40);
    let first =
        CameraPath::catmull_rom_timed("interior corridor", &w, &frames, path_projection(0.05))?;

    let next = if rows > 7 { 7 } else { corridor };
    let zn = shift.z + row_z[next] + CORRIDOR_D * 0.5;
    let x_far = shift.x + cols as f64 * ROOM_W - 1.0;
    let x_near = (x_far - 3.0 * ROOM_W).max(shift.x + 1.0);
    let second = CameraPath::catmull_rom(
        "interior corridor 2",
        &[
            Waypoint::new(
                DVec3::new(x_far, eye_y, zn),
                DVec3::new(x_far - look, eye_y, zn),
            ),
            Waypoint::new(
                DVec3::new(x_near, eye_y, zn),
                DVec3::new(x_near - look, eye_y, zn),
            ),
        ],
        120,
        path_projection(0.05),
    )?;
    Ok(first.then_cut(second))
}
