//! Harness for GPU end-to-end tests: every context runs with the Khronos validation layer and
//! synchronization validation and the best-practices checks, and [`Gpu`] fails the test on any
//! message the layer reported (but the reviewed `tilegraph_vk::SILENCED` ones).

use tilegraph_vk::{Context, ContextOptions, FeatureRequest, Validation, VkError};

/// A validated context for one test. Dropping it checks validation: any warning or error the
/// layer reported during the test, or when the device was destroyed (objects the test leaked),
/// panics (fails) the test, naming the messages.
pub struct Gpu {
    ctx: Option<Context>,
}

impl Gpu {
    /// A context checked at its end (see [`Gpu`]).
    pub fn new(ctx: Context) -> Self {
        Gpu { ctx: Some(ctx) }
    }
}

impl std::ops::Deref for Gpu {
    type Target = Context;
    fn deref(&self) -> &Context {
        self.ctx
            .as_ref()
            .expect("the context lives until the Gpu is dropped")
    }
}

/// Held while a test creates or destroys an instance and device: the tests of a binary run on
/// several threads, and a rare SIGSEGV of whole test binaries under `cargo test` (twice in CI,
/// never in a single-threaded run, no memcheck error) points at the loader, layer or driver
/// setting up or tearing down two devices at once. Serialized, they cost nothing measurable;
/// the frames in between still run in parallel.
static LIFECYCLE: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// Runs `f` with [`LIFECYCLE`] held (a test that panicked holding it does not poison the rest).
pub fn lifecycle<T>(f: impl FnOnce() -> T) -> T {
    let _held = LIFECYCLE
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    f()
}

/// A context with `options`, created under [`lifecycle`].
pub fn context(options: ContextOptions) -> Result<Context, VkError> {
    lifecycle(|| Context::new(options))
}

impl Drop for Gpu {
    fn drop(&mut self) {
        let Some(ctx) = self.ctx.take() else {
            return;
        };
        if std::thread::panicking() {
            lifecycle(|| drop(ctx));
            return;
        }
        if let Err(e) = lifecycle(|| ctx.wait_idle().and_then(|_| ctx.destroy_checked())) {
            panic!("Vulkan validation failed the test: {e}");
        }
    }
}

pub fn init_logging() {
    let _ = env_logger::builder().is_test(true).try_init();
}

/// Context options for tests: validation required, the named profile forced (or the detected one
/// when `None`), and the given features on top of the executor's.
pub fn options(profile: Option<&str>, features: FeatureRequest) -> ContextOptions {
    let mut o = ContextOptions::from_env();
    o.validation = Validation::Required;
    if let Some(p) = profile {
        o.profile = Some(p.to_string());
    }
    o.features.required.extend(features.required);
    o.features.optional.extend(features.optional);
    o
}

/// A validated context on the default device (lavapipe in CI), optionally forcing a profile.
pub fn gpu(profile: Option<&str>) -> Result<Gpu, VkError> {
    init_logging();
    Ok(Gpu::new(context(options(
        profile,
        FeatureRequest::default(),
    ))?))
}

/// Every device feature the culling techniques use (two-phase HiZ's visibility buffer oracle,
/// GPU draw counts, occlusion queries, conditional rendering, raster occlusion's flags).
pub fn culling_features() -> FeatureRequest {
    FeatureRequest::default().require([
        tilegraph_vk::Feature::GeometryShader,
        tilegraph_vk::Feature::DrawIndirectCount,
        tilegraph_vk::Feature::MultiDrawIndirect,
        tilegraph_vk::Feature::HostQueryReset,
        tilegraph_vk::Feature::ConditionalRendering,
        tilegraph_vk::Feature::FragmentStoresAndAtomics,
    ])
}

/// Same as [`gpu`] with extra features.
pub fn gpu_with(profile: Option<&str>, features: FeatureRequest) -> Result<Gpu, VkError> {
    init_logging();
    Ok(Gpu::new(context(options(profile, features))?))
}

pub mod engine;
pub mod frames;

/// A visible set of `scene` baked over its own camera path as the PVS tests bake it (40 m
/// cells, one viewpoint each, faces of `face_px`), on a validated device that can bake it
/// (the visibility buffer's features), with its spec.
pub fn bake_path_pvs(
    scene: &tilegraph_scene::Scene,
    face_px: u32,
) -> (Gpu, tilegraph_passes::pvs::BakeSpec, tilegraph_cull::Pvs) {
    use tilegraph_passes::pvs::{bake, path_region, BakeSpec};
    let features = tilegraph_passes::RenderOptions {
        technique: tilegraph_passes::Technique::Visbuf,
        ..Default::default()
    }
    .device_features();
    let g = gpu_with(None, features).expect("a device that bakes visible sets");
    let spec = BakeSpec {
        region: path_region(scene.camera_path(), 40.0),
        cell: 40.0,
        samples: 1,
        face_px,
        seed: 3,
    };
    let pvs = bake(&g, scene, &spec, |_, _| {}).expect("the bake");
    (g, spec, pvs)
}

/// Asserts that `refined` (a cluster technique) drew no more triangles than `whole` (the
/// instance technique it refines) in any frame of the same path: what a cluster technique
/// promises by construction.
pub fn assert_no_more_triangles(
    what: &str,
    whole: &tilegraph_passes::cullcheck::CullCheck,
    refined: &tilegraph_passes::cullcheck::CullCheck,
) {
    for (a, b) in whole.frames.iter().zip(&refined.frames) {
        assert!(
            b.triangles_drawn <= a.triangles_drawn,
            "{what} frame {}: {} draws {} triangles, {} {}",
            a.frame,
            refined.technique,
            b.triangles_drawn,
            whole.technique,
            a.triangles_drawn
        );
    }
}

/// `$TILEGRAPH_TEST_DATA` or `../shared/data` beside the repository.
pub fn test_data_dir() -> std::path::PathBuf {
    tilegraph_scene::test_data::dir()
}

/// A file of the test data, if the data directory is there; otherwise the skip is recorded
/// (`tilegraph_scene::test_data`: printed, logged for `cargo xtask test`'s summary, or a
/// failure with `TILEGRAPH_REQUIRE_DATA=1`).
pub fn test_data(relative: &str) -> Option<std::path::PathBuf> {
    tilegraph_scene::test_data::find(
        relative,
        &format!("the part of a test that reads {relative}"),
    )
}
pub mod golden;
pub mod textured;

/// A scene of closed meshes for cluster and cone culling: rows of UV spheres (1,280 triangles,
/// about a dozen clusters each) on a ground slab, so that spheres hide spheres and every sphere
/// shows its back half's clusters facing away. Some spheres are rotated and stretched; with
/// `exempt`, some are mirrored (a negative scale: the cone test must leave them alone) and every
/// fifth one is double-sided (no cone test either). The clusters are built and attached.
pub fn closed_spheres(rows: u32, columns: u32, exempt: bool) -> tilegraph_scene::Scene {
    use glam::{DVec3, Mat3, Vec3};
    use tilegraph_scene::{Material, SceneBuilder, Transform, Vertex};
    let (lat, lon) = (20u32, 32u32);
    let mut vertices = Vec::new();
    for i in 0..=lat {
        let theta = std::f32::consts::PI * i as f32 / lat as f32;
        for j in 0..=lon {
            let phi = std::f32::consts::TAU * j as f32 / lon as f32;
            let n = Vec3::new(
                theta.sin() * phi.cos(),
                theta.cos(),
                theta.sin() * phi.sin(),
            );
            vertices.push(Vertex {
                position: n.to_array(),
                normal: n.to_array(),
                uv: [j as f32 / lon as f32, i as f32 / lat as f32],
            });
        }
    }
    let at = |i: u32, j: u32| i * (lon + 1) + j;
    let mut indices = Vec::new();
    let mut push = |a: u32, b: u32, c: u32| {
        let p = |k: u32| Vec3::from(vertices[k as usize].position);
        let (pa, pb, pc) = (p(a), p(b), p(c));
        let normal = (pb - pa).cross(pc - pa);
        if normal.length_squared() < 1e-12 {
            return; // the poles' degenerate triangles
        }
        // Counter-clockwise seen from outside (glTF's front face).
        if normal.dot(pa + pb + pc) > 0.0 {
            indices.extend([a, b, c]);
        } else {
            indices.extend([a, c, b]);
        }
    };
    for i in 0..lat {
        for j in 0..lon {
            push(at(i, j), at(i + 1, j), at(i + 1, j + 1));
            push(at(i, j), at(i + 1, j + 1), at(i, j + 1));
        }
    }
    let mut b = SceneBuilder::new(format!("closed spheres {rows}x{columns}"));
    let one = b.add_material(Material::opaque([0.8, 0.3, 0.2, 1.0]));
    let mut two = Material::opaque([0.2, 0.6, 0.8, 1.0]);
    two.double_sided = true;
    let two = b.add_material(two);
    let ground_material = b.add_material(Material::opaque([0.4, 0.4, 0.4, 1.0]));
    let sphere = b
        .add_mesh(&vertices, &indices, one)
        .expect("a valid sphere");
    let sphere_two = b
        .add_mesh(&vertices, &indices, two)
        .expect("a valid sphere");
    let ground = {
        let c = |x: f32, z: f32| Vertex {
            position: [x, 0.0, z],
            normal: [0.0, 1.0, 0.0],
            uv: [0.0, 0.0],
        };
        let v = [c(-1.0, -1.0), c(-1.0, 1.0), c(1.0, 1.0), c(1.0, -1.0)];
        b.add_mesh(&v, &[0, 1, 2, 0, 2, 3], ground_material)
            .expect("a valid quad")
    };
    let extent = 4.0 * f64::from(rows.max(columns));
    b.add_instance(
        Transform::new(
            Mat3::from_diagonal(Vec3::new(extent as f32, 1.0, extent as f32)),
            DVec3::new(0.0, -1.0, 0.0),
        ),
        ground,
    )
    .expect("a valid instance");
    for r in 0..rows {
        for c in 0..columns {
            let k = r * columns + c;
            let radius = 0.6 + 0.15 * (k % 4) as f32;
            let linear = match k % 6 {
                1 => {
                    Mat3::from_rotation_y(0.7)
                        * Mat3::from_diagonal(Vec3::new(radius * 1.6, radius, radius))
                }
                3 if exempt => Mat3::from_diagonal(Vec3::new(-radius, radius, radius)), // mirrored
                _ => Mat3::from_diagonal(Vec3::splat(radius)),
            };
            let mesh = if exempt && k % 5 == 4 {
                sphere_two
            } else {
                sphere
            };
            let position = DVec3::new(
                (f64::from(c) - f64::from(columns) / 2.0) * 2.5,
                0.0,
                (f64::from(r) - f64::from(rows) / 2.0) * 2.5,
            );
            b.add_instance(Transform::new(linear, position), mesh)
                .expect("a valid instance");
        }
    }
    built_with_clusters(b)
}

/// `n` opaque walls, each its own mesh (so each its own draw bucket), one behind the other in
/// front of the camera and each covering its view: drawn back to front, every pixel is shaded
/// `n` times without a depth pre-pass.
pub fn stacked_walls(n: u32) -> tilegraph_scene::Scene {
    use glam::DVec3;
    use tilegraph_scene::{Camera, CameraPath, Material, PathKey, SceneBuilder, Transform, Vertex};
    let mut b = SceneBuilder::new(format!("{n} stacked walls"));
    for k in 0..n {
        let shade = 0.2 + 0.6 * k as f32 / n.max(1) as f32;
        let material = b.add_material(Material::opaque([shade, 0.5, 1.0 - shade, 1.0]));
        // Wall k at z = -(2 + k), wide enough to fill a 60-degree view from the origin.
        let z = -(2.0 + k as f32);
        let half = 2.0 * (2.0 + k as f32);
        let v = |x: f32, y: f32| Vertex {
            position: [x, y, z],
            normal: [0.0, 0.0, 1.0],
            uv: [0.0, 0.0],
        };
        let vertices = [
            v(-half, -half),
            v(half, -half),
            v(half, half),
            v(-half, half),
        ];
        let mesh = b
            .add_mesh(&vertices, &[0, 1, 2, 0, 2, 3], material)
            .expect("a valid wall");
        b.add_instance(Transform::IDENTITY, mesh)
            .expect("a valid instance");
    }
    let camera = Camera::looking_at(DVec3::ZERO, DVec3::new(0.0, 0.0, -1.0));
    let path = CameraPath::new("facing the walls", vec![PathKey { camera, cut: true }])
        .expect("a valid path");
    b.build(Some(path)).expect("a scene")
}

/// A level built as one mesh out of what breaks culling below the instance: thin blades
/// standing upright (edge-on from most views), long slivers on the ground, needles whose apex
/// lies 1e-6 of their length off the base line, zero-area triangles, tiny distant pieces, and
/// walls to occlude them — every triangle single-sided, counter-clockwise seen from its front,
/// all of it one mesh, drawn once at the origin and once more turned and moved (so the level is
/// one mesh and also an instance of it far from its origin). Clusters attached. Deterministic in
/// `seed`.
pub fn fragile_level(seed: u64) -> tilegraph_scene::Scene {
    use glam::{DVec3, Mat3, Vec3};
    use tilegraph_scene::{Material, SceneBuilder, Transform, Vertex};
    let mut state = seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 40) as f32 / (1u64 << 24) as f32
    };
    let mut vertices: Vec<Vertex> = Vec::new();
    let mut indices: Vec<u32> = Vec::new();
    let mut tri = |a: Vec3, b: Vec3, c: Vec3| {
        let n = (b - a).cross(c - a).normalize_or_zero();
        let base = vertices.len() as u32;
        for p in [a, b, c] {
            vertices.push(Vertex {
                position: p.to_array(),
                normal: n.to_array(),
                uv: [0.0, 0.0],
            });
        }
        indices.extend([base, base + 1, base + 2]);
    };
    let quad = |o: Vec3, u: Vec3, v: Vec3, tri: &mut dyn FnMut(Vec3, Vec3, Vec3)| {
        tri(o, o + u, o + u + v);
        tri(o, o + u + v, o + v);
    };
    // The ground, and walls in a grid with gaps (occluders with holes).
    quad(
        Vec3::new(-60.0, 0.0, 60.0),
        Vec3::new(120.0, 0.0, 0.0),
        Vec3::new(0.0, 0.0, -120.0),
        &mut tri,
    );
    for k in 0..12 {
        let x = -50.0 + 9.0 * k as f32;
        let z = -40.0 + 80.0 * next();
        // Both faces of a thin wall, each single-sided.
        quad(
            Vec3::new(x, 0.0, z),
            Vec3::new(6.0, 0.0, 0.0),
            Vec3::new(0.0, 4.0, 0.0),
            &mut tri,
        );
        quad(
            Vec3::new(x + 6.0, 0.0, z - 0.2),
            Vec3::new(-6.0, 0.0, 0.0),
            Vec3::new(0.0, 4.0, 0.0),
            &mut tri,
        );
    }
    for _ in 0..600 {
        let p = Vec3::new(-55.0 + 110.0 * next(), 0.0, -55.0 + 110.0 * next());
        let angle = std::f32::consts::TAU * next();
        let side = Vec3::new(angle.cos(), 0.0, angle.sin());
        match (next() * 5.0) as u32 {
            // A blade: 1-3 m tall, 1 mm wide at its foot.
            0 => tri(
                p,
                p + side * 1e-3,
                p + Vec3::new(0.0, 1.0 + 2.0 * next(), 0.0),
            ),
            // A sliver on the ground: 10 m long, 2 cm wide, facing up.
            1 => tri(
                p + Vec3::Y * 0.01,
                p + side * 10.0 + Vec3::Y * 0.01,
                p + side.cross(Vec3::Y) * -0.02 + Vec3::Y * 0.01,
            ),
            // A needle: its apex 1e-6 of its length off the base line, standing.
            2 => tri(
                p + Vec3::Y * 0.5,
                p + side * 2.0 + Vec3::Y * 0.5,
                p + side + Vec3::new(0.0, 0.5 + 2e-6, 0.0),
            ),
            // Zero area: three points on a line.
            3 => tri(p, p + side, p + side * 2.0),
            // A small piece far away (a distant pixel or less).
            _ => {
                let far = p * 4.0 + Vec3::new(0.0, 2.0 + 5.0 * next(), 0.0);
                tri(far, far + side * 0.05, far + Vec3::new(0.0, 0.05, 0.0));
            }
        }
    }
    let mut b = SceneBuilder::new(format!("fragile level {seed}"));
    let material = b.add_material(Material::opaque([0.7, 0.6, 0.5, 1.0]));
    let mesh = b
        .add_mesh(&vertices, &indices, material)
        .expect("a valid mesh");
    b.add_instance(Transform::new(Mat3::IDENTITY, DVec3::ZERO), mesh)
        .expect("a valid instance");
    b.add_instance(
        Transform::new(Mat3::from_rotation_y(2.0), DVec3::new(300.0, 0.0, -150.0)),
        mesh,
    )
    .expect("a valid instance");
    built_with_clusters(b)
}

/// The scene `b` builds (its default camera path), with clusters built and attached.
fn built_with_clusters(b: tilegraph_scene::SceneBuilder) -> tilegraph_scene::Scene {
    let mut scene = b.build(None).expect("a valid scene");
    let (clusters, _) = tilegraph_scene::clusters::build(&scene).expect("clusters build");
    scene
        .attach_clusters(clusters)
        .expect("clusters of this scene");
    scene
}
