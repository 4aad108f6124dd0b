use glam::{DMat4, DQuat, DVec3};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use tilegraph_types::{DepthConvention, Projection};

use super::*;

fn camera(eye: DVec3, forward: DVec3) -> ShadowCamera {
    ShadowCamera {
        eye,
        forward: forward.normalize(),
        up: DVec3::Y,
        projection: Projection::tilegraph_default(60f32.to_radians(), 0.1),
        aspect: 16.0 / 9.0,
    }
}

const LIGHT: DVec3 = DVec3::new(0.4, 0.8, 0.3);
const BOUNDS: (DVec3, DVec3) = (
    DVec3::new(-200.0, 0.0, -200.0),
    DVec3::new(200.0, 60.0, 200.0),
);

fn settings() -> CascadeSettings {
    CascadeSettings {
        distance: 150.0,
        ..CascadeSettings::default()
    }
}

fn clip(m: &DMat4, p: DVec3) -> DVec3 {
    m.project_point3(p)
}

#[test]
fn every_slice_lies_inside_its_cascade_with_room_for_lookups() {
    for forward in [
        DVec3::new(0.0, -0.3, -1.0),
        DVec3::X,
        DVec3::new(-1.0, -1.0, 0.2),
    ] {
        let cam = camera(DVec3::new(10.0, 2.0, 5.0), forward);
        let cs = fit_cascades(&cam, LIGHT, BOUNDS, &settings());
        assert_eq!(cs.count, 3);
        let mut last_far = f64::from(0.1f32);
        for c in cs.as_slice() {
            assert_eq!(c.near, last_far, "slices are contiguous");
            last_far = c.far;
            // The slice's corners, a texel's snap and the lookups' reach inside the box.
            let room = 1.0 - 2.0 * (1.0 + 2.0 + 1.5) / 1024.0;
            for p in c.corners {
                let q = clip(&c.clip_from_world, p);
                assert!(q.x.abs() <= room + 1e-3 && q.y.abs() <= room + 1e-3, "{q}");
                assert!((0.0..=1.0).contains(&q.z), "{q}");
            }
        }
        assert_eq!(last_far, 150.0);
    }
}

#[test]
fn cascades_keep_their_size_as_the_camera_turns_and_snap_to_texels_as_it_moves() {
    let s = settings();
    let base = fit_cascades(
        &camera(DVec3::new(3.0, 2.0, 1.0), DVec3::NEG_Z),
        LIGHT,
        BOUNDS,
        &s,
    );
    for k in 1..20 {
        let turn =
            DQuat::from_rotation_y(0.31 * k as f64) * DQuat::from_rotation_x(0.05 * k as f64);
        let eye = DVec3::new(3.0 + 0.037 * k as f64, 2.0, 1.0 - 0.011 * k as f64);
        let moved = fit_cascades(&camera(eye, turn * DVec3::NEG_Z), LIGHT, BOUNDS, &s);
        for (a, b) in base.as_slice().iter().zip(moved.as_slice()) {
            assert_eq!(a.half, b.half, "turning or moving keeps the cascade's size");
            assert_eq!(a.texel, b.texel);
            let grid = b.center / b.texel;
            assert!((grid - grid.round()).abs().max_element() < 1e-6, "{grid}");
        }
    }
}

#[test]
fn degenerate_inputs_give_no_cascades() {
    let s = settings();
    let cam = camera(DVec3::ZERO, DVec3::NEG_Z);
    assert_eq!(fit_cascades(&cam, DVec3::ZERO, BOUNDS, &s).count, 0);
    assert_eq!(
        fit_cascades(&cam, DVec3::splat(f64::NAN), BOUNDS, &s).count,
        0
    );
    let inverted = (DVec3::ONE, DVec3::ZERO);
    assert_eq!(fit_cascades(&cam, LIGHT, inverted, &s).count, 0);
    let mut up = cam;
    up.forward = DVec3::Y;
    assert_eq!(fit_cascades(&up, LIGHT, BOUNDS, &s).count, 0);
    // Nothing past the near plane when the distance comes from bounds behind the eye.
    let behind = (DVec3::new(-1.0, -1.0, 5.0), DVec3::new(1.0, 1.0, 6.0));
    let derived = CascadeSettings { distance: 0.0, ..s };
    assert_eq!(fit_cascades(&cam, LIGHT, behind, &derived).count, 0);
}

#[test]
fn orthographic_and_finite_far_cameras_are_covered() {
    let mut cam = camera(DVec3::new(0.0, 5.0, 0.0), DVec3::new(0.0, -0.2, -1.0));
    cam.projection = Projection::Orthographic {
        half_height: 8.0,
        near: 0.5,
        far: 60.0,
        depth: DepthConvention::Standard,
    };
    let cs = fit_cascades(&cam, LIGHT, BOUNDS, &settings());
    assert_eq!(cs.count, 3);
    assert_eq!(
        cs.as_slice()[2].far,
        60.0,
        "the far plane caps the distance"
    );
    for c in cs.as_slice() {
        for p in c.corners {
            let q = clip(&c.clip_from_world, p);
            assert!(q.x.abs() < 1.0 && q.y.abs() < 1.0 && (0.0..=1.0).contains(&q.z));
        }
    }
}

/// Whether a caster point `b` may darken a lookup of receiver `r`: above it (towards the
/// light) and within `reach` of it across the light.
fn shadows(basis: &LightBasis, b: DVec3, r: DVec3, reach: f64) -> bool {
    let d = basis.to_light(b - r);
    d.z >= 0.0 && d.x.hypot(d.y) <= reach
}

fn grid(lo: DVec3, hi: DVec3, n: usize) -> impl Iterator<Item = DVec3> {
    let step = (hi - lo) / (n - 1) as f64;
    (0..n * n * n).map(move |i| {
        lo + step * DVec3::new((i % n) as f64, ((i / n) % n) as f64, (i / (n * n)) as f64)
    })
}

/// Receiver points of a cascade's slice: the frustum between its near and far distances.
fn receivers(cam: &ShadowCamera, c: &Cascade) -> Vec<DVec3> {
    let (f, up, right) = cam.basis().unwrap_or((DVec3::Z, DVec3::Y, DVec3::X));
    let mut out = Vec::new();
    for i in 0..6 {
        let d = c.near + (c.far - c.near) * f64::from(i) / 5.0;
        let hh = (30f64.to_radians()).tan() * d;
        let hw = hh * cam.aspect;
        for j in 0..5 {
            for k in 0..5 {
                let x = (f64::from(j) / 2.0 - 1.0) * hw;
                let y = (f64::from(k) / 2.0 - 1.0) * hh;
                out.push(cam.eye + f * d + right * x + up * y);
            }
        }
    }
    out
}

#[test]
fn receiver_culling_never_drops_a_caster_that_shadows_the_slice_and_drops_many() {
    let s = settings();
    let mut rng = Pcg64::seed_from_u64(38);
    let (mut culled, mut kept, mut cascade_culled) = (0usize, 0usize, 0usize);
    for trial in 0..12 {
        let eye = DVec3::new(
            rng.random_range(-50.0..50.0),
            rng.random_range(1.5..20.0),
            rng.random_range(-50.0..50.0),
        );
        let yaw: f64 = rng.random_range(0.0..std::f64::consts::TAU);
        let pitch: f64 = rng.random_range(-0.6..0.2);
        let forward = DVec3::new(
            yaw.cos() * pitch.cos(),
            pitch.sin(),
            yaw.sin() * pitch.cos(),
        );
        let light = DVec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(0.2..1.0),
            rng.random_range(-1.0..1.0),
        );
        let cam = camera(eye, forward);
        let cs = fit_cascades(&cam, light, BOUNDS, &s);
        let Some(basis) = cs.basis else {
            panic!("trial {trial}: no basis");
        };
        for (i, c) in cs.as_slice().iter().enumerate() {
            let planes = caster_planes(&cs, i, &s, CasterCulling::Receivers);
            let box_planes = caster_planes(&cs, i, &s, CasterCulling::Cascade);
            assert!(caster_planes(&cs, i, &s, CasterCulling::None)
                .as_slice()
                .is_empty());
            let recv = receivers(&cam, c);
            // What the test may rely on: a texel of reach, well inside the planes' margin.
            let reach = c.texel;
            for _ in 0..150 {
                // Boxes anywhere, and boxes right above a receiver (which must be kept).
                let centre = if rng.random_bool(0.5) {
                    recv[rng.random_range(0..recv.len())] + basis.l * rng.random_range(0.0..30.0)
                } else {
                    eye + DVec3::new(
                        rng.random_range(-200.0..200.0),
                        rng.random_range(-20.0..60.0),
                        rng.random_range(-200.0..200.0),
                    )
                };
                let half = DVec3::new(
                    rng.random_range(0.05..6.0),
                    rng.random_range(0.05..6.0),
                    rng.random_range(0.05..6.0),
                );
                let drop = planes.culls(centre, half);
                if box_planes.culls(centre, half) {
                    cascade_culled += 1;
                    assert!(drop, "receiver culling keeps the box's planes");
                }
                if drop {
                    culled += 1;
                    for b in grid(centre - half, centre + half, 4) {
                        for r in &recv {
                            assert!(
                                !shadows(&basis, b, *r, reach),
                                "trial {trial} cascade {i}: culled box {centre} {half} shadows {r}"
                            );
                        }
                    }
                } else {
                    kept += 1;
                }
            }
        }
    }
    assert!(culled > kept / 4, "culled {culled}, kept {kept}");
    assert!(
        culled > cascade_culled,
        "receivers {culled} vs cascade {cascade_culled}"
    );
}

#[test]
fn planes_relative_to_the_eye_cull_the_same_boxes() {
    let s = settings();
    let eye = DVec3::new(12_345.5, 3.0, -54_321.25);
    let cam = camera(eye, DVec3::new(1.0, -0.2, 0.3));
    let bounds = (eye - DVec3::splat(300.0), eye + DVec3::splat(300.0));
    let cs = fit_cascades(&cam, LIGHT, bounds, &s);
    let planes = caster_planes(&cs, 1, &s, CasterCulling::Receivers);
    let rel = planes.relative_to(eye);
    let mut rng = Pcg64::seed_from_u64(7);
    for _ in 0..500 {
        let c = DVec3::new(
            rng.random_range(-150.0..150.0),
            rng.random_range(-20.0..40.0),
            rng.random_range(-150.0..150.0),
        );
        let h = DVec3::splat(rng.random_range(0.1..4.0));
        assert_eq!(planes.culls(eye + c, h), rel.culls(c, h));
    }
}

#[test]
fn caster_culling_names_round_trip() {
    for c in CasterCulling::ALL {
        assert_eq!(CasterCulling::parse(c.name()), Some(c));
    }
    assert_eq!(CasterCulling::parse("hiz"), None);
}
