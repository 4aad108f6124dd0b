//! A scene in motion, scripted and replayable: what the suite and the bench use to hold the
//! culling techniques to their promises while things move (issue 34).
//!
//! [`Motion::new`] picks from a scene what moves: some of its small instances **slide** back
//! and forth along a street axis (out from behind whatever hides them and back), thin upright
//! ones **swing** about an edge like doors, and a few instances of its meshes **spawn** in front
//! of the camera path and despawn later; with [`MotionParams::mirrors`], some movers also turn
//! mirrored for half their period (an engine flipping a prop: its mesh's winding turns with
//! it, `Scene::set_transforms`). [`Motion::apply`] brings the scene to frame `n`'s state
//! from whatever frame it was at — every position is a function of the frame, spawned instances
//! are there exactly in their window — so a path can be rendered again from its start, and two
//! renderers fed the same frames see the same scene. Deterministic from its seed.

use glam::{DVec3, Mat3, Vec3};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;

use crate::camera::CameraPath;
use crate::error::SceneError;
use crate::scene::{InstanceFlags, InstanceHandle, InstanceId, MaterialClass, MeshHandle, Scene};
use crate::Transform;

/// The most instances a motion spawns along a path.
pub const MAX_SPAWNS: usize = 1 << 16;

/// How much moves.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotionParams {
    /// Share of the small instances that move (0..=1).
    pub movers: f64,
    /// Instances spawned along the camera path (each lives for a part of it), at most
    /// [`MAX_SPAWNS`] (more are not placed).
    pub spawns: usize,
    pub seed: u64,
    /// Share of the movers (0..=1) mirrored along their local x axis for half their period.
    pub mirrors: f64,
}

impl Default for MotionParams {
    fn default() -> Self {
        MotionParams {
            movers: 0.1,
            spawns: 12,
            seed: 1,
            mirrors: 0.0,
        }
    }
}

#[derive(Clone, Copy, Debug)]
enum Path {
    /// Back and forth along `axis` (unit, horizontal), `amplitude` metres either way.
    Slide {
        axis: DVec3,
        amplitude: f64,
        period: f64,
        phase: f64,
    },
    /// About the vertical axis through `pivot` (world), up to `angle` radians.
    Swing {
        pivot: DVec3,
        angle: f32,
        period: f64,
        phase: f64,
    },
}

#[derive(Clone, Copy, Debug)]
struct Mover {
    handle: InstanceHandle,
    base: Transform,
    path: Path,
    /// Mirrored along its local x axis while its path is in its second half.
    mirrors: bool,
}

#[derive(Clone, Copy, Debug)]
struct Spawn {
    mesh: MeshHandle,
    transform: Transform,
    frames: (usize, usize),
    handle: Option<InstanceHandle>,
}

/// A scene's scripted motion.
#[derive(Clone, Debug)]
pub struct Motion {
    movers: Vec<Mover>,
    spawns: Vec<Spawn>,
    /// The frame the scene was last brought to.
    frame: Option<usize>,
    /// This frame's moves (kept: no allocation per frame).
    batch: Vec<(InstanceHandle, Transform)>,
}

impl Motion {
    /// Picks the movers of `scene` and places spawns along `path`.
    pub fn new(scene: &Scene, path: &CameraPath, params: MotionParams) -> Self {
        let mut rng = Pcg64::seed_from_u64(params.seed);
        // Small: below the median bounding radius (buildings, walls and ground stay put).
        let mut radii: Vec<f32> = scene
            .instances()
            .iter()
            .filter(|i| i.flags.is_drawn())
            .map(|i| i.bounds.radius)
            .collect();
        radii.sort_unstable_by(f32::total_cmp);
        let median = radii.get(radii.len() / 2).copied().unwrap_or(0.0);
        let share = params.movers.clamp(0.0, 1.0);
        // Its own sequence: the movers and paths are those of the same seed without mirrors.
        let mut mirror_rng = Pcg64::seed_from_u64(params.seed ^ 0x6d69_7272_6f72);
        let mirrors = params.mirrors.clamp(0.0, 1.0);
        let mut movers = Vec::new();
        for (i, inst) in scene.instances().iter().enumerate() {
            if !inst.flags.is_drawn() || inst.bounds.radius > median || !rng.random_bool(share) {
                continue;
            }
            let Some(handle) = scene.instance_handle(InstanceId(i as u32)) else {
                continue;
            };
            let h = inst.bounds.half_extents;
            let r = f64::from(inst.bounds.radius);
            let period = rng.random_range(40.0..120.0);
            let phase = rng.random_range(0.0..std::f64::consts::TAU);
            // Thin and upright (a door, a pane): swings about the edge of its longer side.
            let path = if h.y > h.x.min(h.z) * 2.0 && h.x.min(h.z) * 3.0 < h.x.max(h.z) {
                let edge = if h.x > h.z {
                    DVec3::new(f64::from(h.x), 0.0, 0.0)
                } else {
                    DVec3::new(0.0, 0.0, f64::from(h.z))
                };
                Path::Swing {
                    pivot: inst.bounds.center - edge,
                    angle: rng.random_range(1.0..1.6),
                    period,
                    phase,
                }
            } else {
                let axis = if rng.random_bool(0.5) {
                    DVec3::X
                } else {
                    DVec3::Z
                };
                Path::Slide {
                    axis,
                    amplitude: (8.0 * r).clamp(2.0, 30.0),
                    period,
                    phase,
                }
            };
            movers.push(Mover {
                handle,
                base: inst.transform,
                path,
                mirrors: mirrors > 0.0 && mirror_rng.random_bool(mirrors),
            });
        }
        let spawns = place_spawns(scene, path, params.spawns.min(MAX_SPAWNS), &mut rng, median);
        Motion {
            movers,
            spawns,
            frame: None,
            batch: Vec::new(),
        }
    }

    /// Instances that move.
    pub fn movers(&self) -> usize {
        self.movers.len()
    }

    /// The instances that move (their slots).
    pub fn mover_ids(&self) -> impl Iterator<Item = InstanceId> + '_ {
        self.movers.iter().map(|m| m.handle.id())
    }

    /// Instances spawned at some point of the path.
    pub fn spawns(&self) -> usize {
        self.spawns.len()
    }

    /// Brings `scene` to frame `frame`: every mover where it is at that frame, exactly the
    /// spawns whose window holds it present.
    pub fn apply(&mut self, scene: &mut Scene, frame: usize) -> Result<(), SceneError> {
        self.batch.clear();
        let t = frame as f64;
        for m in &self.movers {
            let mut at = m.path.at(&m.base, t);
            if m.mirrors && m.path.second_half(t) {
                at.linear *= Mat3::from_diagonal(Vec3::new(-1.0, 1.0, 1.0));
            }
            self.batch.push((m.handle, at));
        }
        scene.set_transforms(&self.batch)?;
        for s in &mut self.spawns {
            let alive = (s.frames.0..s.frames.1).contains(&frame);
            match (alive, s.handle) {
                (true, None) => {
                    s.handle =
                        Some(scene.add_instance(s.mesh, s.transform, InstanceFlags::default())?);
                }
                (false, Some(h)) => {
                    scene.remove_instance(h)?;
                    s.handle = None;
                }
                _ => {}
            }
        }
        self.frame = Some(frame);
        Ok(())
    }
}

impl Path {
    /// Whether time `t` lies in the second half of the path's period.
    fn second_half(&self, t: f64) -> bool {
        let (Path::Slide { period, phase, .. } | Path::Swing { period, phase, .. }) = *self;
        (t / period + phase / std::f64::consts::TAU).rem_euclid(1.0) >= 0.5
    }

    fn at(&self, base: &Transform, t: f64) -> Transform {
        match *self {
            Path::Slide {
                axis,
                amplitude,
                period,
                phase,
            } => {
                let s = (std::f64::consts::TAU * t / period + phase).sin();
                Transform::new(base.linear, base.translation + axis * (amplitude * s))
            }
            Path::Swing {
                pivot,
                angle,
                period,
                phase,
            } => {
                // Opens and closes: 0 to `angle` and back.
                let s = 0.5 - 0.5 * (std::f64::consts::TAU * t / period + phase).cos();
                let r = Mat3::from_rotation_y(angle * s as f32);
                let offset = base.translation - pivot;
                Transform::new(r * base.linear, pivot + (r * offset.as_vec3()).as_dvec3())
            }
        }
    }
}

/// `n` spawns of small opaque meshes a few metres in front of the camera at evenly spaced
/// frames of `path`, each living for a fifth of it.
fn place_spawns(
    scene: &Scene,
    path: &CameraPath,
    n: usize,
    rng: &mut Pcg64,
    median: f32,
) -> Vec<Spawn> {
    let meshes: Vec<MeshHandle> = (0..scene.meshes().len() as u32)
        .filter_map(|m| {
            let id = crate::MeshId(m);
            let mesh = scene.mesh(id)?;
            let opaque = scene
                .material(mesh.material)
                .is_some_and(|mat| mat.class == MaterialClass::Opaque);
            let small = mesh.local_aabb.half_extents().length() <= median.max(0.5) * 2.0;
            (opaque && small).then(|| scene.mesh_handle(id)).flatten()
        })
        .collect();
    let frames = path.len();
    if meshes.is_empty() || frames == 0 {
        return Vec::new();
    }
    (0..n)
        .filter_map(|k| {
            let start = k * frames / n.max(1);
            let camera = path.camera(start)?;
            let forward = (camera.target - camera.eye).normalize_or_zero();
            let distance = rng.random_range(4.0..15.0);
            let side = rng.random_range(-2.0..2.0);
            let right = forward.cross(DVec3::Y).normalize_or_zero();
            let at = camera.eye + forward * distance + right * side;
            let mesh = meshes[rng.random_range(0..meshes.len())];
            let linear = Mat3::from_rotation_y(rng.random_range(0.0..std::f32::consts::TAU))
                * Mat3::from_diagonal(Vec3::ONE);
            Some(Spawn {
                mesh,
                transform: Transform::new(linear, at),
                frames: (start, (start + frames / 5 + 1).min(frames)),
                handle: None,
            })
        })
        .collect()
}
