//! `seed-grid:N[:DETAIL]`: the scene of seed 000's geometry-culling tests (its author's
//! GeometryCulling-1/-2 scripts, AsEn-ShaderEditor `2ab4caf8`), rebuilt from its description:
//! `32 N³` spheres on a jittered `4N x 4N x 2N` grid spread over a 50 m wide field seen from a
//! fixed camera (vertical field of view 57°, near 1 m, far 200 m), the spheres growing with
//! distance (the seed's "emulated LOD") so that near ones hide far ones. Each sphere is a cube
//! of `2 DETAIL x 2 DETAIL` quads a face pushed onto the sphere: the seed's detail levels are
//! 8 (3072 triangles a sphere, desktop GPUs: 11 K spheres, 33 M triangles at N = 7) and 3 (432,
//! mobile). The placement's formulas are tilegraph's own reading of the seed's description, not
//! its code; its hash jitter comes from the procedural generators' deterministic stream.

use glam::{DVec3, Mat3, Vec3};

use super::shapes::MeshData;
use super::Rng;
use crate::camera::{Camera, CameraPath, PathKey};
use crate::error::SceneError;
use crate::scene::{Material, MaterialClass, Scene, SceneBuilder, SceneSource, Transform, Vertex};
use crate::texture::{Sampler, Texture};
use tilegraph_types::{DepthConvention, Projection};

/// The largest N accepted (32·N³ spheres: 10 is the seed's slider's end, 32 000 spheres).
pub const MAX_SEED_GRID: u32 = 16;
/// The seed's two detail levels' range.
pub const MAX_SEED_DETAIL: u32 = 16;
/// Most noise textures a grid takes, and the largest side of one.
pub const MAX_SEED_TEXTURES: u32 = 64;
pub const MAX_SEED_TEXTURE_SIDE: u32 = 4096;

/// Textures for the seed's memory-bound test: `count` textures of `side`² texels of white
/// noise (incompressible and without locality, as photographs read at random places are), the
/// spheres' material sampling the first; a material's random reads
/// (`Lighting::random_reads` in tilegraph-passes) pick among all of them. The seed binds 32
/// (8 images, 4 times each). `count` 0: no texture, the plain colour.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SeedTextures {
    pub count: u32,
    pub side: u32,
}

/// What to build: `n` (32·n³ spheres), each of `detail` (2·detail quads a cube face's side);
/// with `discard`, their material alpha-tested at a cutoff no fragment falls below (the
/// seed's "early ZS, discard": a shader that may discard and never does). The instances are in
/// the grid's order, row by row away from the camera (the seed's front to back: instanced in
/// one draw, they are drawn in that order), or with `back_to_front` the reverse.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SeedGrid {
    pub n: u32,
    pub detail: u32,
    pub discard: bool,
    pub back_to_front: bool,
    pub textures: SeedTextures,
}

impl Default for SeedGrid {
    fn default() -> Self {
        SeedGrid {
            n: 7,
            detail: 8,
            discard: false,
            back_to_front: false,
            textures: SeedTextures::default(),
        }
    }
}

/// Texture `index` of `t`: white noise, each texel a hash of its place and the texture.
fn noise_texture(index: u32, side: u32) -> Result<Texture, SceneError> {
    let mut rgba = Vec::with_capacity(side as usize * side as usize * 4);
    for y in 0..side {
        for x in 0..side {
            let h = (rng_unit_of(x, y, index) * f64::from(u32::MAX)) as u32;
            rgba.extend_from_slice(&[h as u8, (h >> 8) as u8, (h >> 16) as u8, 255]);
        }
    }
    Texture::from_rgba8(
        format!("seed-noise-{index}"),
        side,
        side,
        rgba,
        Sampler::default(),
    )
    .map_err(|e| SceneError::BadSpec {
        spec: format!("seed-grid noise texture {index}"),
        reason: e.to_string(),
    })
}

/// The sphere: a cube of `2 detail` quads a face's side, every vertex pushed onto the unit
/// sphere (normal = position), counter-clockwise seen from outside.
pub(crate) fn sphere(detail: u32) -> MeshData {
    let s = (2 * detail.max(1)) as usize;
    let mut vertices = Vec::with_capacity(6 * (s + 1) * (s + 1));
    let mut indices = Vec::with_capacity(6 * s * s * 6);
    // Each face: its normal axis n and two in-plane axes (u, v) with u x v = n.
    let faces = [
        (Vec3::X, Vec3::NEG_Z, Vec3::Y),
        (Vec3::NEG_X, Vec3::Z, Vec3::Y),
        (Vec3::Y, Vec3::X, Vec3::NEG_Z),
        (Vec3::NEG_Y, Vec3::X, Vec3::Z),
        (Vec3::Z, Vec3::X, Vec3::Y),
        (Vec3::NEG_Z, Vec3::NEG_X, Vec3::Y),
    ];
    for (n, u, v) in faces {
        let base = vertices.len() as u32;
        for j in 0..=s {
            for i in 0..=s {
                let (a, b) = (i as f32 / s as f32, j as f32 / s as f32);
                let p = (n + u * (2.0 * a - 1.0) + v * (2.0 * b - 1.0)).normalize();
                vertices.push(Vertex {
                    position: p.to_array(),
                    normal: p.to_array(),
                    uv: [a, b],
                });
            }
        }
        let at = |i: usize, j: usize| base + (j * (s + 1) + i) as u32;
        for j in 0..s {
            for i in 0..s {
                indices.extend([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
                indices.extend([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
            }
        }
    }
    MeshData { vertices, indices }
}

/// Builds the scene (`seed`: the jitter's stream).
pub fn generate(grid: SeedGrid, seed: u64) -> Result<Scene, SceneError> {
    let spec = format!("seed-grid:{}:{}", grid.n, grid.detail);
    if !(1..=MAX_SEED_GRID).contains(&grid.n) || !(1..=MAX_SEED_DETAIL).contains(&grid.detail) {
        return Err(SceneError::BadSpec {
            spec,
            reason: format!(
                "a grid size N from 1 to {MAX_SEED_GRID} and a detail from 1 to {MAX_SEED_DETAIL}"
            ),
        });
    }
    let SeedTextures {
        count: textures,
        side,
    } = grid.textures;
    if textures > MAX_SEED_TEXTURES
        || (textures > 0 && !(1..=MAX_SEED_TEXTURE_SIDE).contains(&side))
    {
        return Err(SceneError::BadSpec {
            spec,
            reason: format!(
                "up to {MAX_SEED_TEXTURES} textures of a side from 1 to {MAX_SEED_TEXTURE_SIDE}"
            ),
        });
    }
    let mut b = SceneBuilder::new(format!(
        "{spec}{}{}{}",
        if grid.discard { "+discard" } else { "" },
        if grid.back_to_front {
            "+back-to-front"
        } else {
            ""
        },
        if textures > 0 {
            format!("+textures:{textures}x{side}")
        } else {
            String::new()
        }
    ));
    let mut first_texture = None;
    for t in 0..textures {
        let id = b.add_texture(noise_texture(t, side)?);
        first_texture.get_or_insert(id);
    }
    let (nx, ny, nz) = (4 * grid.n, 4 * grid.n, 2 * grid.n);
    let count = (nx * ny * nz) as usize;
    b.set_source(SceneSource::Procedural {
        name: "seed-grid".into(),
        size: count,
        seed,
    });
    b.reserve_instances(count);
    let material = b.add_material(Material {
        base_color: [0.8, 0.55, 0.3, 1.0],
        class: if grid.discard {
            MaterialClass::AlphaTested { cutoff: 0.0 }
        } else {
            MaterialClass::Opaque
        },
        double_sided: false,
        base_color_texture: first_texture,
        engine_material: None,
    });
    let data = sphere(grid.detail);
    let offset = b.push_vertices(&data.vertices);
    let mesh = b.push_mesh_range(offset, data.vertices.len() as u32, &data.indices, material);
    let mut rng = Rng::new(seed);
    let mut jitter = || 2.0 * rng.unit() - 1.0;
    let aspect = 16.0 / 9.0;
    let turn = Mat3::from_rotation_y((-45f32).to_radians());
    let mut centre = DVec3::ZERO;
    let mut placed = Vec::with_capacity(count);
    for z in 0..nz {
        for y in 0..ny {
            for x in 0..nx {
                let cell = |i: u32, of: u32| (f64::from(i) + 0.5) / f64::from(of);
                let (mut ux, mut uy, mut uz) = (cell(x, nx), cell(y, ny), cell(z, nz));
                // Jitter: up to 0.4 of a cell across, a whole cell in height.
                ux += jitter() * 0.4 / f64::from(nx);
                uy += jitter() * 0.4 / f64::from(ny);
                uz = (2.0 * uz - 1.0) + jitter() * 2.0 / f64::from(nz);
                ux *= aspect;
                uy *= aspect;
                let reach = (ux * ux + uy * uy).sqrt();
                // Farther rows spread higher and their spheres grow (the seed's emulated LOD).
                uz *= reach * 2.1 + 0.3;
                // The field's near edge shifted toward the eye with the aspect (0.056 at 16:9).
                let shift = -0.1 + 0.35 * (aspect / 4.0);
                ux -= shift;
                uy -= shift;
                let radius = (1.0 + rng_unit_of(x, y, z)) * (reach * 1.1 + 0.1).clamp(0.1, 4.0);
                let local = Vec3::new((ux * 50.0) as f32, (uz * 10.0) as f32, (uy * 50.0) as f32);
                let p = (turn * local).as_dvec3();
                centre += p;
                placed.push(Transform::new(
                    Mat3::from_diagonal(Vec3::splat(radius as f32)),
                    p,
                ));
            }
        }
    }
    if grid.back_to_front {
        placed.reverse();
    }
    for t in placed {
        b.push_instance_trusted(t, mesh);
    }
    centre /= count as f64;
    let camera = Camera {
        eye: DVec3::ZERO,
        target: DVec3::new(centre.x, 0.0, centre.z),
        up: Vec3::Y,
        projection: Projection::Perspective {
            fov_y_rad: 57f32.to_radians(),
            near: 1.0,
            far: Some(200.0),
            depth: DepthConvention::Reverse,
        },
    };
    let path = CameraPath::new("seed-grid", vec![PathKey { camera, cut: false }])?;
    b.build(Some(path))
}

/// A per-sphere size factor in [0, 1): a hash of its cell, so that the sizes do not depend on
/// the jitter stream's order.
fn rng_unit_of(x: u32, y: u32, z: u32) -> f64 {
    let mut h = u64::from(x)
        .wrapping_mul(0x9E37_79B9_7F4A_7C15)
        .wrapping_add(u64::from(y).wrapping_mul(0xC2B2_AE3D_27D4_EB4F))
        .wrapping_add(u64::from(z).wrapping_mul(0x1656_67B1_9E37_79F9));
    h ^= h >> 31;
    h = h.wrapping_mul(0xBF58_476D_1CE4_E5B9);
    h ^= h >> 29;
    (h >> 11) as f64 / (1u64 << 53) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spheres_are_closed_outward_and_of_the_seeds_size() {
        for (detail, triangles) in [(3, 432), (8, 3072)] {
            let s = sphere(detail);
            assert_eq!(s.indices.len() / 3, triangles, "detail {detail}");
            for t in s.indices.chunks_exact(3) {
                let p = |i: u32| Vec3::from(s.vertices[i as usize].position);
                let (a, b, c) = (p(t[0]), p(t[1]), p(t[2]));
                let n = (b - a).cross(c - a);
                assert!(n.dot(a + b + c) > 0.0, "a triangle faces inward");
            }
            for v in &s.vertices {
                assert!((Vec3::from(v.position).length() - 1.0).abs() < 1e-5);
            }
        }
    }

    #[test]
    fn the_grid_holds_32_n_cubed_spheres_in_front_of_its_camera() {
        let scene = crate::load("seed-grid:2:3").unwrap();
        assert_eq!(scene.instances().len(), 32 * 8);
        assert_eq!(scene.triangles_drawn(), 32 * 8 * 432);
        let camera = scene.camera_path().camera(0).unwrap();
        let forward = (camera.target - camera.eye).normalize();
        let ahead = scene
            .instances()
            .iter()
            .filter(|i| (i.bounds.center - camera.eye).normalize().dot(forward) > 0.5)
            .count();
        assert!(ahead * 10 >= scene.instances().len() * 9, "{ahead} ahead");
        // Far spheres are bigger (the seed's emulated LOD).
        let radius = |i: &crate::Instance| f64::from(i.bounds.radius);
        let dist = |i: &crate::Instance| (i.bounds.center - camera.eye).length();
        let mut by_distance: Vec<_> = scene.instances().iter().collect();
        by_distance.sort_by(|a, b| dist(a).total_cmp(&dist(b)));
        let half = by_distance.len() / 2;
        let mean =
            |s: &[&crate::Instance]| s.iter().map(|i| radius(i)).sum::<f64>() / s.len() as f64;
        assert!(mean(&by_distance[half..]) > 1.5 * mean(&by_distance[..half]));

        let discard = generate(
            SeedGrid {
                n: 1,
                detail: 1,
                discard: true,
                back_to_front: false,
                textures: SeedTextures::default(),
            },
            1,
        )
        .unwrap();
        // Back to front: the same spheres in the opposite order.
        let reversed = generate(
            SeedGrid {
                n: 2,
                detail: 3,
                discard: false,
                back_to_front: true,
                textures: SeedTextures::default(),
            },
            1,
        )
        .unwrap();
        for (a, b) in scene
            .instances()
            .iter()
            .zip(reversed.instances().iter().rev())
        {
            assert_eq!(a.transform, b.transform);
        }
        // The grid's own order draws the near rows first: the first row is nearer than the
        // last of its layer.
        let row = 4 * 2;
        assert!(dist(&scene.instances()[0]) < dist(&scene.instances()[row * (row - 1)]));
        assert_eq!(
            discard.materials()[0].class,
            MaterialClass::AlphaTested { cutoff: 0.0 }
        );
        for bad in [
            "seed-grid:0",
            "seed-grid:2:0",
            "seed-grid:x",
            "seed-grid:2:3:4",
            "seed-grid7",
        ] {
            assert!(crate::load(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn the_memory_tests_textures_are_noise_and_the_spheres_sample_the_first() {
        let grid = |count, side| SeedGrid {
            n: 1,
            detail: 1,
            textures: SeedTextures { count, side },
            ..SeedGrid::default()
        };
        let scene = generate(grid(3, 64), 1).unwrap();
        assert_eq!(scene.textures().len(), 3);
        assert!(scene.name().ends_with("+textures:3x64"), "{}", scene.name());
        assert_eq!(
            scene.materials()[0].base_color_texture,
            Some(crate::texture::TextureId(0))
        );
        for t in scene.textures() {
            assert_eq!((t.width(), t.height()), (64, 64));
            // White noise: every channel's mean near the middle, neighbours unrelated.
            let texels = t.level_pixels(0).unwrap();
            let mean = texels.chunks(4).map(|p| f64::from(p[0])).sum::<f64>() / 4096.0;
            assert!((mean - 127.5).abs() < 8.0, "{mean}");
            let same = texels
                .chunks(4)
                .zip(texels.chunks(4).skip(1))
                .filter(|(a, b)| a[0] == b[0])
                .count();
            assert!(same < 64, "{same} neighbours alike");
        }
        assert_ne!(scene.textures()[0].pixels(), scene.textures()[1].pixels());
        assert!(generate(grid(0, 0), 1).unwrap().textures().is_empty());
        for (count, side) in [
            (MAX_SEED_TEXTURES + 1, 64),
            (2, 0),
            (2, MAX_SEED_TEXTURE_SIDE + 1),
        ] {
            assert!(generate(grid(count, side), 1).is_err(), "{count}x{side}");
        }
    }
}
