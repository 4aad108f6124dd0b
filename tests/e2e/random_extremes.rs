//! Randomized extremes on the GPU (lavapipe, validation on): beside the fixed extremes matrix
//! (`culling.rs`), proptest draws cases — a viewport from 1x1 to 512x512 (mostly odd sizes),
//! either depth convention, D32 or D16, a perspective near plane from 1e-4 to 1 m and a field
//! of view from a scope's 0.2 degrees to 179 (or an orthographic view), the camera inside an instance's box, on its surface, just past it
//! looking away, or out in the street, the world up to 10^6 m from the origin — and checks
//! every conservative culling technique (frustum, two-phase HiZ with random pyramid knobs and
//! bounds, same-frame queries, raster occlusion, and both cluster techniques on a scene of
//! closed spheres, some mirrored or double-sided, or on a level built as one mesh of thin,
//! near-degenerate, zero-area, edge-on and distant triangles, `fragile_level`; with either
//! `cluster_early` and `cluster_gap` 0 or 2) for no visible
//! instance — and for the cluster techniques no visible cluster — culled and an image
//! equal to the unculled one (the frustum and two-phase HiZ techniques, instance and cluster
//! level, which draw in the unculled order), on a
//! three-frame path whose last frame jumps elsewhere without a
//! cut (two-phase culling's history is then wrong, and must not matter); and renders the first
//! view with the visibility buffer and with forward shading (no pre-pass), which must be equal
//! bit for bit, and with deferred texturing, within 2 levels of 255 (its G-buffer's normal).
//!
//! 64 cases by default, the same ones every run; `PROPTEST_CASES` runs more of the same sequence. A failing case shrinks to a small one,
//! and its seed is written to `tests/proptest-regressions/random_extremes.txt`, which is
//! committed so that every later run tries it first.

use glam::{DVec3, Vec3};
use proptest::prelude::*;
use proptest::test_runner::{Config, FileFailurePersistence, TestCaseError, TestRng, TestRunner};
use tilegraph_cull::{DepthFormat, NpotMode};
use tilegraph_e2e::gpu_with;
use tilegraph_passes::cull::{ClusterEarly, CullBounds, Culling};
use tilegraph_passes::cullcheck::{cull_check_options, CheckExtras};
use tilegraph_passes::{RenderOptions, SceneRenderer, Technique};
use tilegraph_scene::{Camera, CameraPath, DepthConvention, PathKey, Projection, Scene};

/// Where a camera stands relative to instance `instance`'s bounding box.
#[derive(Debug, Clone, Copy)]
enum Placement {
    /// At the box's centre: the camera is inside the instance.
    Inside { instance: usize },
    /// On the box's surface (the face along `axis`), looking in direction `look`.
    Touching { instance: usize, axis: usize },
    /// Just outside the box, looking away from it: the instance is behind the camera.
    Behind { instance: usize, axis: usize },
    /// One of the scene's own path cameras: out in the open.
    Street { key: usize },
}

#[derive(Debug, Clone, Copy)]
struct ViewCase {
    placement: Placement,
    /// A direction to look in (normalized later; the placement may override it).
    look: (f64, f64, f64),
}

#[derive(Debug, Clone)]
struct Case {
    size: (u32, u32),
    reverse: bool,
    d16: bool,
    /// `None`: perspective; `Some(half height)`: orthographic.
    ortho: Option<f32>,
    near: f32,
    fov_y_rad: f32,
    finite_far: bool,
    /// Where the world is moved (x, z), up to 10^6 m.
    offset: (f64, f64),
    views: [ViewCase; 2],
    /// Two-phase HiZ's knobs: base level, sphere bounds, padded pyramid.
    hiz_base_level: u32,
    sphere: bool,
    padded: bool,
}

const INSTANCES: usize = 300;

fn placement() -> impl Strategy<Value = Placement> {
    let instance = 0..INSTANCES;
    prop_oneof![
        instance
            .clone()
            .prop_map(|instance| Placement::Inside { instance }),
        (instance.clone(), 0..3usize)
            .prop_map(|(instance, axis)| Placement::Touching { instance, axis }),
        (instance, 0..3usize).prop_map(|(instance, axis)| Placement::Behind { instance, axis }),
        (0..64usize).prop_map(|key| Placement::Street { key }),
    ]
}

fn view() -> impl Strategy<Value = ViewCase> {
    (placement(), (-1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64))
        .prop_map(|(placement, look)| ViewCase { placement, look })
}

fn side() -> impl Strategy<Value = u32> {
    // Mostly small and odd (lavapipe renders every pixel on the CPU), sometimes up to 512.
    prop_oneof![3 => 1..=64u32, 1 => 65..=512u32]
}

/// A perspective's vertical field of view: mostly 11-149 degrees, sometimes a scope's (0.2-3
/// degrees: distant boxes cover few pixels, the pyramid's texels are far apart in angle) or
/// nearly a half space (149-179 degrees: the frustum's side planes almost meet the eye's).
fn fov() -> impl Strategy<Value = f32> {
    prop_oneof![4 => 0.2..2.6f32, 1 => 0.0035..0.052f32, 1 => 2.6..3.124f32]
}

fn case() -> impl Strategy<Value = Case> {
    (
        (side(), side(), any::<bool>(), any::<bool>()),
        (
            prop_oneof![3 => Just(None), 1 => (0.5..200.0f32).prop_map(Some)],
            -4.0..0.0f32,
            fov(),
            any::<bool>(),
        ),
        (
            prop_oneof![Just(0.0), -1.0e6..1.0e6f64],
            prop_oneof![Just(0.0), -1.0e6..1.0e6f64],
        ),
        [view(), view()],
        (0..=2u32, any::<bool>(), any::<bool>()),
    )
        .prop_map(
            |(
                (w, h, reverse, d16),
                (ortho, log_near, fov_y_rad, finite_far),
                offset,
                views,
                (hiz_base_level, sphere, padded),
            )| Case {
                size: (w, h),
                reverse,
                d16,
                ortho,
                near: 10f32.powf(log_near),
                fov_y_rad,
                finite_far,
                offset,
                views,
                hiz_base_level,
                sphere,
                padded,
            },
        )
}

impl Case {
    /// Whether the cluster techniques run on the fragile one-mesh level (else on the closed
    /// spheres): half the cases, by the viewport's parity — derived, not drawn, so that the
    /// seeds in the regressions file keep making the cases they were saved for.
    fn fragile(&self) -> bool {
        (self.size.0 + self.size.1) % 2 == 1
    }

    fn projection(&self) -> Projection {
        let depth = if self.reverse {
            DepthConvention::Reverse
        } else {
            DepthConvention::Standard
        };
        match self.ortho {
            Some(half_height) => Projection::Orthographic {
                half_height,
                near: 0.01,
                far: 1000.0,
                depth,
            },
            None => Projection::Perspective {
                fov_y_rad: self.fov_y_rad,
                near: self.near,
                // A finite far plane far enough for the whole city (its bounds are ~200 m).
                far: self.finite_far.then_some(2000.0),
                depth,
            },
        }
    }

    fn camera(&self, scene: &Scene, v: &ViewCase) -> Camera {
        let mut look = DVec3::new(v.look.0, v.look.1, v.look.2);
        if look.length() < 1e-3 {
            look = DVec3::X;
        }
        let look = look.normalize();
        let instances = scene.instances();
        let axis_dir = |axis: usize| DVec3::AXES[axis % 3];
        let (eye, dir) = match v.placement {
            Placement::Inside { instance } => {
                (instances[instance % instances.len()].bounds.center, look)
            }
            Placement::Touching { instance, axis } => {
                let b = &instances[instance % instances.len()].bounds;
                let n = axis_dir(axis);
                (b.center + n * n.dot(b.half_extents.as_dvec3()), look)
            }
            Placement::Behind { instance, axis } => {
                let b = &instances[instance % instances.len()].bounds;
                let n = axis_dir(axis);
                let reach = n.dot(b.half_extents.as_dvec3());
                // Just past the face, looking straight away from the box.
                (b.center + n * (reach * 1.001 + 1e-3), n)
            }
            Placement::Street { key } => {
                let keys = scene.camera_path().keys();
                let c = keys[key % keys.len()].camera;
                (
                    c.eye,
                    (c.target - c.eye).try_normalize().unwrap_or(DVec3::NEG_Z),
                )
            }
        };
        // Never look straight up or down: `up` is +y.
        let dir = if dir.cross(DVec3::Y).length() < 1e-3 {
            (dir + DVec3::new(0.05, 0.0, 0.05)).normalize()
        } else {
            dir
        };
        Camera {
            eye,
            target: eye + dir,
            up: Vec3::Y,
            projection: self.projection(),
        }
    }

    /// First view, the same view moved a little, then the second view (a jump, no cut).
    fn path(&self, scene: &Scene) -> Result<CameraPath, TestCaseError> {
        let first = self.camera(scene, &self.views[0]);
        let mut nudged = first;
        nudged.eye += DVec3::new(0.05, 0.0, 0.03);
        nudged.target += DVec3::new(0.05, 0.0, 0.03);
        let jump = self.camera(scene, &self.views[1]);
        let keys = [first, nudged, jump]
            .into_iter()
            .map(|camera| PathKey { camera, cut: false })
            .collect();
        CameraPath::new("random extremes", keys)
            .map_err(|e| TestCaseError::fail(format!("the case's camera path: {e}")))
    }
}

fn cases() -> u32 {
    std::env::var("PROPTEST_CASES")
        .ok()
        .and_then(|c| c.parse().ok())
        .unwrap_or(64)
}

#[test]
fn conservative_culling_holds_at_random_extremes() {
    let features = tilegraph_e2e::culling_features();
    let g = gpu_with(None, features).unwrap();
    let city = tilegraph_scene::load(&format!("city:{INSTANCES}")).unwrap();
    // Cluster culling on closed meshes (cones reject clusters; mirrored and double-sided
    // spheres must be left alone), viewed from the same kinds of placement.
    let spheres = tilegraph_e2e::closed_spheres(4, 5, true);
    let fragile = tilegraph_e2e::fragile_level(11);
    let config = Config {
        cases: cases(),
        failure_persistence: Some(Box::new(FileFailurePersistence::Direct(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/proptest-regressions/random_extremes.txt"
        )))),
        source_file: Some(file!()),
        ..Config::default()
    };
    // The same cases every run (CI stays reproducible); PROPTEST_CASES explores further along
    // the same sequence.
    let rng = TestRng::deterministic_rng(config.rng_algorithm);
    let mut runner = TestRunner::new_with_rng(config, rng);
    let checked = std::cell::Cell::new(0usize);
    let result = runner.run(&case(), |case| {
        let mut scene = city.clone();
        scene.translate(DVec3::new(case.offset.0, 0.0, case.offset.1));
        let path = case.path(&scene)?;
        let bounds = if case.sphere {
            CullBounds::Sphere
        } else {
            CullBounds::Aabb
        };
        let mode = if case.padded {
            NpotMode::PadToPow2
        } else {
            NpotMode::EdgeAware
        };
        let mut clustered = if case.fragile() {
            fragile.clone()
        } else {
            spheres.clone()
        };
        clustered.translate(DVec3::new(case.offset.0, 0.0, case.offset.1));
        let clustered_path = case.path(&clustered)?;
        let techniques = [
            (Culling::Frustum, 0, bounds, NpotMode::EdgeAware),
            (Culling::HizTwoPhase, case.hiz_base_level, bounds, mode),
            (Culling::OqConditional, 0, CullBounds::Aabb, NpotMode::EdgeAware),
            (Culling::RasterOcclusion, 0, CullBounds::Aabb, NpotMode::EdgeAware),
            (Culling::FrustumClusters, 0, bounds, NpotMode::EdgeAware),
            (Culling::HizTwoPhaseClusters, case.hiz_base_level, bounds, mode),
            (Culling::SoftwareOcclusion, 0, bounds, mode),
        ];
        // Software occlusion runs on both scenes: the city's boxes, and the spheres or the
        // fragile one-mesh level as occluders.
        let runs = techniques.into_iter().flat_map(|t| {
            let both = t.0 == Culling::SoftwareOcclusion;
            [(t, t.0.clusters()), (t, true)]
                .into_iter()
                .take(if both { 2 } else { 1 })
        });
        for ((culling, base, bounds, mode), on_clustered) in runs {
            let (scene, path) = if on_clustered {
                (&clustered, &clustered_path)
            } else {
                (&scene, &path)
            };
            let options = RenderOptions {
                width: case.size.0,
                height: case.size.1,
                culling,
                depth_format: if case.d16 {
                    DepthFormat::D16Unorm
                } else {
                    DepthFormat::D32Float
                },
                hiz_base_level: base,
                cull_bounds: bounds,
                hiz_mode: mode,
                // The cluster knobs' other settings, from fields the case already draws (so a
                // saved seed still makes its case): the early phase of visible clusters where
                // the pyramid is padded, gaps drawn through where the bounds are spheres.
                cluster_early: if case.padded {
                    ClusterEarly::Clusters
                } else {
                    ClusterEarly::Instances
                },
                cluster_gap: if case.sphere { 2 } else { 0 },
                ..Default::default()
            };
            let r = cull_check_options(&g, scene, options, path, None, CheckExtras::default())
                .map_err(|e| TestCaseError::fail(format!("{}: {e}", culling.name())))?;
            for f in &r.frames {
                prop_assert_eq!(
                    f.false_negatives,
                    0,
                    "{} (base level {}, {}) frame {} culled visible instances {:?}",
                    culling.name(),
                    base,
                    bounds.name(),
                    f.frame,
                    f.false_negative_ids
                );
                if culling.clusters() {
                    let c = f.clusters.ok_or_else(|| {
                        TestCaseError::fail(format!(
                            "{} frame {}: no cluster comparison",
                            culling.name(),
                            f.frame
                        ))
                    })?;
                    prop_assert_eq!(
                        c.false_negatives,
                        0,
                        "{} on {} frame {} culled visible clusters",
                        culling.name(),
                        scene.name(),
                        f.frame
                    );
                }
                // Frustum, two-phase HiZ and software occlusion draw the survivors in the unculled order, so the
                // image is the reference's bit for bit. The query and raster techniques draw
                // last frame's visible set first, so where depth precision makes two surfaces
                // tie (standard depth with a tiny near plane, D16; docs/ACCURACY.md) the first
                // drawn of them may differ: every pixel that differs must hold the reference's
                // depth, bit for bit — the nearest surface is there.
                prop_assert_eq!(
                    f.image_diff_pixels,
                    f.image_diff_pixels_depth_tie,
                    "{} (base level {}, {}) frame {}: pixels differ from the unculled image at another depth",
                    culling.name(),
                    base,
                    bounds.name(),
                    f.frame
                );
                if matches!(
                    culling.base(),
                    Culling::Frustum | Culling::HizTwoPhase | Culling::SoftwareOcclusion
                ) {
                    prop_assert!(
                        f.image_equal,
                        "{} (base level {}, {}) frame {}: {} pixels differ from the unculled image ({} owned by drawn instances)",
                        culling.name(),
                        base,
                        bounds.name(),
                        f.frame,
                        f.image_diff_pixels,
                        f.image_diff_pixels_owner_drawn
                    );
                }
            }
            checked.set(checked.get() + 1);
        }
        // The visibility buffer against forward shading without a pre-pass, bit for bit (both
        // keep the first drawn of surfaces tied in depth; passes.rs says why the pre-pass
        // differs there); deferred texturing too, but for its G-buffer's rounding.
        let camera = case.camera(&scene, &case.views[0]);
        let mut images = Vec::new();
        for technique in [
            Technique::Forward,
            Technique::Visbuf,
            Technique::DeferredTexturing,
        ] {
            let options = RenderOptions {
                technique,
                width: case.size.0,
                height: case.size.1,
                depth_prepass: Some(false),
                depth_format: if case.d16 {
                    DepthFormat::D16Unorm
                } else {
                    DepthFormat::D32Float
                },
                ..Default::default()
            };
            let image = SceneRenderer::new(&g, &scene, options)
                .and_then(|mut r| {
                    let image = r.render(&g, &scene, &camera).and_then(|_| r.read_image(&g));
                    r.destroy(&g);
                    image
                })
                .map_err(|e| TestCaseError::fail(format!("{}: {e}", technique.name())))?;
            images.push(image);
        }
        prop_assert!(
            images[0] == images[1],
            "the visibility buffer differs from forward shading"
        );
        // The same surfaces win (the G-buffer pass draws in forward's order with its test);
        // only the 10-bit normal rounds the shading, by a level or two of 255.
        let largest = images[0]
            .pixels
            .iter()
            .zip(&images[2].pixels)
            .map(|(a, b)| a.abs_diff(*b))
            .max()
            .unwrap_or(0);
        prop_assert!(
            largest <= 2,
            "deferred texturing differs from forward shading by {} levels",
            largest
        );
        Ok(())
    });
    if let Err(e) = result {
        panic!("{e}");
    }
    println!(
        "{} cases, {} checks of three frames each: no visible instance culled",
        cases(),
        checked.get()
    );
}
