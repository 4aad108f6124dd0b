//! Procedural worlds that span the culling spectrum, deterministic from a seed and a size.
//!
//! | kind       | what hides what                                    | classes            |
//! |------------|----------------------------------------------------|--------------------|
//! | `city`     | tall buildings hide the props between and behind   | opaque + a little glass |
//! | `forest`   | many alpha-tested foliage cards, trunks            | alpha-tested heavy |
//! | `field`    | almost nothing: an open plain                      | opaque + cards     |
//! | `interior` | walls with doors: portal-like occlusion            | opaque + glass + plants |
//! | `maze`     | walls with doors; wires, needles, zero-area and edge-on pieces below them | opaque |
//!
//! `size` is the number of instances: every generator places exactly `max(size, minimum)`
//! instances (a handful of shared meshes, many instances). Randomness comes only from
//! `rand_pcg::Pcg64Mcg` seeded with `seed`, through the helpers below (which use nothing but
//! `next_u64`), so the same seed and size give the same scene on every platform and build.

mod city;
mod field;
mod forest;
mod interior;
mod maze;
pub mod seed_grid;
pub(crate) mod shapes;

use std::fmt;
use std::str::FromStr;

use glam::{DVec3, Mat3, Vec3};
use rand::{RngCore, SeedableRng};
use rand_pcg::Pcg64Mcg;
use serde::Serialize;
use tilegraph_types::{DepthConvention, Projection};

use crate::error::SceneError;
use crate::scene::{MaterialId, MeshId, Scene, SceneBuilder, SceneSource, Transform};
use shapes::MeshData;

/// The five procedural worlds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ProceduralKind {
    City,
    Forest,
    Field,
    Interior,
    Maze,
}

impl ProceduralKind {
    pub const ALL: [ProceduralKind; 5] = [
        ProceduralKind::City,
        ProceduralKind::Forest,
        ProceduralKind::Field,
        ProceduralKind::Interior,
        ProceduralKind::Maze,
    ];

    pub fn name(self) -> &'static str {
        match self {
            ProceduralKind::City => "city",
            ProceduralKind::Forest => "forest",
            ProceduralKind::Field => "field",
            ProceduralKind::Interior => "interior",
            ProceduralKind::Maze => "maze",
        }
    }

    /// The smallest size the kind's layout supports; smaller requests are raised to it.
    pub fn minimum_size(self) -> usize {
        match self {
            ProceduralKind::City => 64,
            ProceduralKind::Forest => 64,
            ProceduralKind::Field => 16,
            ProceduralKind::Interior => 200,
            ProceduralKind::Maze => 200,
        }
    }
}

impl fmt::Display for ProceduralKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for ProceduralKind {
    type Err = ();
    fn from_str(s: &str) -> Result<Self, ()> {
        ProceduralKind::ALL
            .into_iter()
            .find(|k| k.name() == s)
            .ok_or(())
    }
}

/// What to generate: `size` instances (see the module docs) from `seed`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct ProceduralParams {
    pub size: usize,
    pub seed: u64,
}

impl Default for ProceduralParams {
    fn default() -> Self {
        ProceduralParams {
            size: 10_000,
            seed: 1,
        }
    }
}

/// The largest size accepted: 2^26 instances (about 7 GB of instance data) keeps a typo in a
/// spec from exhausting memory.
pub const MAX_PROCEDURAL_SIZE: usize = 1 << 26;

/// Generates a procedural scene with its default test camera path.
pub fn generate(kind: ProceduralKind, params: ProceduralParams) -> Result<Scene, SceneError> {
    let size = params.size.max(kind.minimum_size());
    if size != params.size {
        log::info!("{kind}: size {} raised to the minimum {size}", params.size);
    }
    if size > MAX_PROCEDURAL_SIZE {
        return Err(SceneError::BadSpec {
            spec: format!("{kind}:{size}"),
            reason: format!("size above the maximum of {MAX_PROCEDURAL_SIZE} instances"),
        });
    }
    let mut g = Gen::new(kind, size, params.seed);
    let path = match kind {
        ProceduralKind::City => city::generate(&mut g, size)?,
        ProceduralKind::Forest => forest::generate(&mut g, size)?,
        ProceduralKind::Field => field::generate(&mut g, size)?,
        ProceduralKind::Interior => interior::generate(&mut g, size)?,
        ProceduralKind::Maze => maze::generate(&mut g, size)?,
    };
    debug_assert_eq!(g.builder.instance_count(), size);
    g.builder.build(Some(path))
}

/// Deterministic random numbers from `Pcg64Mcg::next_u64` only (no distribution code whose
/// algorithm could change between `rand` releases).
pub(crate) struct Rng(Pcg64Mcg);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Rng(Pcg64Mcg::seed_from_u64(seed))
    }

    /// Uniform in [0, 1).
    pub fn unit(&mut self) -> f64 {
        (self.0.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Uniform in [a, b).
    pub fn range(&mut self, a: f64, b: f64) -> f64 {
        a + (b - a) * self.unit()
    }

    pub fn range_f32(&mut self, a: f32, b: f32) -> f32 {
        self.range(f64::from(a), f64::from(b)) as f32
    }

    /// Uniform integer in [0, n); 0 when n is 0.
    pub fn below(&mut self, n: usize) -> usize {
        ((u128::from(self.0.next_u64()) * n as u128) >> 64) as usize
    }

    pub fn chance(&mut self, p: f64) -> bool {
        self.unit() < p
    }

    /// A yaw angle in [0, 2 pi).
    pub fn yaw(&mut self) -> f32 {
        self.range_f32(0.0, std::f32::consts::TAU)
    }
}

/// Shared state of a generator: the builder and the random stream.
pub(crate) struct Gen {
    pub builder: SceneBuilder,
    pub rng: Rng,
}

impl Gen {
    fn new(kind: ProceduralKind, size: usize, seed: u64) -> Self {
        let mut builder = SceneBuilder::new(kind.name());
        builder.set_source(SceneSource::Procedural {
            name: kind.name().into(),
            size,
            seed,
        });
        builder.reserve_instances(size);
        Gen {
            builder,
            // Mix the kind into the seed so that city:N:1 and forest:N:1 are unrelated streams.
            rng: Rng::new(seed ^ (kind as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)),
        }
    }

    /// Adds a mesh with its own vertices (trusted: shapes are valid by construction, checked by
    /// the shapes tests).
    pub fn mesh(&mut self, data: &MeshData, material: MaterialId) -> MeshId {
        let offset = self.builder.push_vertices(&data.vertices);
        self.builder
            .push_mesh_range(offset, data.vertices.len() as u32, &data.indices, material)
    }

    /// Adds a second mesh over the vertices of `shared` (same geometry, another material).
    pub fn mesh_like(&mut self, shared: MeshId, data: &MeshData, material: MaterialId) -> MeshId {
        let (offset, count) = self.builder.mesh_vertex_range(shared).unwrap_or((0, 0));
        self.builder
            .push_mesh_range(offset, count, &data.indices, material)
    }

    /// Places `mesh` at `pos` turned by `yaw` about +y and scaled by `scale`.
    #[inline]
    pub fn place(&mut self, mesh: MeshId, pos: DVec3, yaw: f32, scale: Vec3) {
        let linear = Mat3::from_rotation_y(yaw) * Mat3::from_diagonal(scale);
        self.builder
            .push_instance_trusted(Transform::new(linear, pos), mesh);
    }

    /// Places `mesh` with an arbitrary linear part.
    #[inline]
    pub fn place_linear(&mut self, mesh: MeshId, pos: DVec3, linear: Mat3) {
        self.builder
            .push_instance_trusted(Transform::new(linear, pos), mesh);
    }

    pub fn count(&self) -> usize {
        self.builder.instance_count()
    }
}

/// The projection the procedural paths use: the tilegraph default (reverse-Z, infinite far).
pub(crate) fn path_projection(near: f32) -> Projection {
    Projection::Perspective {
        fov_y_rad: 60f32.to_radians(),
        near,
        far: None,
        depth: DepthConvention::Reverse,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rng_is_deterministic_and_in_range() {
        let mut a = Rng::new(7);
        let mut b = Rng::new(7);
        for _ in 0..1000 {
            let x = a.unit();
            assert_eq!(x, b.unit());
            assert!((0.0..1.0).contains(&x));
            let k = a.below(5);
            assert_eq!(k, b.below(5));
            assert!(k < 5);
        }
        assert_eq!(Rng::new(1).below(0), 0);
    }

    #[test]
    fn kind_names_round_trip() {
        for k in ProceduralKind::ALL {
            assert_eq!(k.name().parse::<ProceduralKind>(), Ok(k));
        }
        assert!("town".parse::<ProceduralKind>().is_err());
    }
}
