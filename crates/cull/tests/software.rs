//! Software occlusion: the rasterizer's bound never lies in front of what a GPU draws, on random
//! meshes built to break it (shared edges, box corners with split vertices, fans, slivers,
//! near-degenerate and edge-on triangles, soups), random cameras (either depth convention, D32
//! and D16, near planes down to 1e-4, orthographic) and viewports from 1x1; the SIMD kernel and
//! any number of threads give the scalar reference's buffers bit for bit.
//!
//! The GPU is modelled by a reference rasterizer written the way the Vulkan spec describes one:
//! f32 clip coordinates, vertices snapped to `subpixel_bits`, the top-left rule on exact
//! integer edge functions, depth interpolated in f32 and stored as the format stores it. The
//! check is the property the box test relies on: wherever the software buffer gives a bound
//! for a pixel, the reference drew a fragment there no farther than it.

use glam::{Mat3, Mat4, Vec3};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use tilegraph_cull::{
    project_aabb, Aabb, DepthConvention, DepthFormat, Extent2d, ExtentExt, Kernel, OccluderMesh,
    OcclusionView, Projection, SoftwareConfig, SoftwareOcclusion,
};

/// An occluder placed in the view: its mesh, object-space positions and indices (for the
/// reference), and its placement relative to the eye.
struct Placed {
    positions: Vec<Vec3>,
    indices: Vec<u32>,
    double_sided: bool,
    linear: Mat3,
    offset: Vec3,
}

struct Case {
    extent: Extent2d,
    projection: Projection,
    view: Mat4,
    format: DepthFormat,
    bits: u32,
    resolution: (u32, u32),
    occluders: Vec<Placed>,
}

impl Case {
    fn aspect(&self) -> f32 {
        self.extent.width_px as f32 / self.extent.height_px as f32
    }

    fn clip(&self) -> Mat4 {
        self.projection.matrix(self.aspect()) * self.view
    }

    fn occlusion_view(&self) -> OcclusionView {
        OcclusionView {
            clip_from_relative: self.clip().as_dmat4(),
            extent: self.extent,
            convention: self.projection.depth_convention(),
            format: self.format,
        }
    }

    fn software(&self, kernel: Kernel, threads: usize) -> SoftwareOcclusion {
        self.software_batched(kernel, threads, usize::MAX)
    }

    /// As `software`, rasterizing after every `every` occluders (as `tilegraph_passes` does,
    /// testing the next occluders' boxes in between).
    fn software_batched(&self, kernel: Kernel, threads: usize, every: usize) -> SoftwareOcclusion {
        let mut sw = SoftwareOcclusion::new(SoftwareConfig {
            resolution: self.resolution,
            subpixel_bits: self.bits,
            threads,
            // Every batch on the threads, however small: the split is what is tested.
            parallel_triangles: 0,
            kernel,
        });
        sw.begin(self.occlusion_view()).unwrap();
        for (k, o) in self.occluders.iter().enumerate() {
            let mesh = OccluderMesh::new(&o.positions, &o.indices, o.double_sided).unwrap();
            sw.add_occluder(&mesh, o.linear.as_dmat3(), o.offset.as_dvec3());
            if (k + 1) % every.max(1) == 0 {
                sw.rasterize();
            }
        }
        sw.rasterize();
        sw
    }

    /// The reference GPU's depth buffer (`None`: no fragment).
    fn reference(&self) -> Vec<Option<f32>> {
        let (w, h) = (self.extent.width_px as i64, self.extent.height_px as i64);
        let convention = self.projection.depth_convention();
        let clip = self.clip();
        let scale = 1i64 << self.bits;
        let mut depth = vec![None::<f32>; (w * h) as usize];
        for o in &self.occluders {
            for t in o.indices.chunks_exact(3) {
                let mut v = [(0i64, 0i64, 0f32); 3];
                let mut ok = true;
                for (k, &i) in t.iter().enumerate() {
                    let p = o.linear * o.positions[i as usize] + o.offset;
                    let c = clip * p.extend(1.0);
                    if !(c.w > 0.0 && c.z >= 0.0 && c.z <= c.w) {
                        ok = false;
                        break;
                    }
                    let fx = (c.x / c.w * 0.5 + 0.5) * w as f32;
                    let fy = (c.y / c.w * 0.5 + 0.5) * h as f32;
                    if fx.abs() > 1e6 || fy.abs() > 1e6 {
                        ok = false;
                        break;
                    }
                    let snap = |f: f32| (f64::from(f) * scale as f64).round() as i64;
                    v[k] = (snap(fx), snap(fy), c.z / c.w);
                }
                if !ok {
                    continue;
                }
                let [a, b, c] = v;
                let area = (b.0 - a.0) * (c.1 - a.1) - (c.0 - a.0) * (b.1 - a.1);
                // Vulkan: front-facing (counter-clockwise) when -area / 2 > 0.
                if area == 0 || (area > 0 && !o.double_sided) {
                    continue;
                }
                let v = if area < 0 { [a, c, b] } else { [a, b, c] };
                let area = area.abs();
                // Top-left rule with y down: a top edge is horizontal with the inside below, a
                // left edge goes down the screen on the inside's left; here inside is positive.
                let bias = |p: (i64, i64, f32), q: (i64, i64, f32)| {
                    let (dx, dy) = (q.0 - p.0, q.1 - p.1);
                    let top_left = (dy == 0 && dx > 0) || dy < 0;
                    if top_left {
                        0
                    } else {
                        -1
                    }
                };
                let edge = |p: (i64, i64, f32), q: (i64, i64, f32), x: i64, y: i64| {
                    (q.0 - p.0) * (y - p.1) - (q.1 - p.1) * (x - p.0)
                };
                let e_bias = [bias(v[0], v[1]), bias(v[1], v[2]), bias(v[2], v[0])];
                for py in 0..h {
                    for px in 0..w {
                        let (x, y) = ((2 * px + 1) * scale / 2, (2 * py + 1) * scale / 2);
                        let e = [
                            edge(v[0], v[1], x, y),
                            edge(v[1], v[2], x, y),
                            edge(v[2], v[0], x, y),
                        ];
                        if (0..3).any(|i| e[i] + e_bias[i] < 0) {
                            continue;
                        }
                        // Barycentric depth in f32: e[1] weighs v0, e[2] v1, e[0] v2.
                        let s = area as f32;
                        let z = (e[1] as f32 / s) * v[0].2
                            + (e[2] as f32 / s) * v[1].2
                            + (e[0] as f32 / s) * v[2].2;
                        let z = self.format.store(z.clamp(0.0, 1.0));
                        let slot = &mut depth[(py * w + px) as usize];
                        match slot {
                            Some(d) if !convention.is_strictly_behind(*d, z) => {}
                            _ => *slot = Some(z),
                        }
                    }
                }
            }
        }
        depth
    }
}

fn rotation(rng: &mut Pcg64) -> Mat3 {
    let axis = Vec3::new(
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
    )
    .try_normalize()
    .unwrap_or(Vec3::Y);
    Mat3::from_axis_angle(axis, rng.random_range(0.0..std::f32::consts::TAU))
}

/// A tessellated plane of `n x m` quads (shared edges), optionally bent.
fn grid(rng: &mut Pcg64) -> (Vec<Vec3>, Vec<u32>) {
    let (n, m) = (rng.random_range(1..6u32), rng.random_range(1..6u32));
    let bend = if rng.random_bool(0.5) {
        0.0
    } else {
        rng.random_range(0.0..0.4)
    };
    let mut p = Vec::new();
    for j in 0..=m {
        for i in 0..=n {
            let (u, v) = (i as f32 / n as f32 - 0.5, j as f32 / m as f32 - 0.5);
            p.push(Vec3::new(u, v, bend * (u * 7.0).sin() * (v * 5.0).cos()));
        }
    }
    let mut idx = Vec::new();
    for j in 0..m {
        for i in 0..n {
            let a = j * (n + 1) + i;
            let (b, c, d) = (a + 1, a + n + 2, a + n + 1);
            if rng.random_bool(0.5) {
                idx.extend([a, b, c, a, c, d]);
            } else {
                idx.extend([a, b, d, b, c, d]);
            }
        }
    }
    (p, idx)
}

/// A box with 4 vertices per face (as glTF exports it).
fn split_box() -> (Vec<Vec3>, Vec<u32>) {
    let faces = [
        (Vec3::X, Vec3::Y, Vec3::Z),
        (-Vec3::X, Vec3::Z, Vec3::Y),
        (Vec3::Y, Vec3::Z, Vec3::X),
        (-Vec3::Y, Vec3::X, Vec3::Z),
        (Vec3::Z, Vec3::X, Vec3::Y),
        (-Vec3::Z, Vec3::Y, Vec3::X),
    ];
    let mut p = Vec::new();
    let mut idx = Vec::new();
    for (n, u, v) in faces {
        let base = p.len() as u32;
        for (su, sv) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
            p.push((n + u * su + v * sv) * 0.5);
        }
        idx.extend([base, base + 1, base + 2, base, base + 2, base + 3]);
    }
    (p, idx)
}

/// A fan around a centre, some rim points nearly collinear (slivers).
fn fan(rng: &mut Pcg64) -> (Vec<Vec3>, Vec<u32>) {
    let k = rng.random_range(3..12u32);
    let mut p = vec![Vec3::ZERO];
    let mut angle = 0.0f32;
    for _ in 0..k {
        angle += if rng.random_bool(0.3) {
            1e-4
        } else {
            rng.random_range(0.1..1.2)
        };
        p.push(Vec3::new(angle.cos(), angle.sin(), rng.random_range(-0.05..0.05)) * 0.6);
    }
    let mut idx = Vec::new();
    for i in 1..k {
        idx.extend([0, i, i + 1]);
    }
    (p, idx)
}

/// A strip of needles: long triangles a hair wide sharing their long edges.
fn slivers(rng: &mut Pcg64) -> (Vec<Vec3>, Vec<u32>) {
    let n = rng.random_range(2..10u32);
    let width = 10f32.powf(rng.random_range(-6.0..-1.0));
    let mut p = Vec::new();
    for i in 0..=n {
        let x = i as f32 * width;
        p.push(Vec3::new(x, -0.5, 0.0));
        p.push(Vec3::new(x + rng.random_range(-1e-6..1e-6), 0.5, 0.0));
    }
    let mut idx = Vec::new();
    for i in 0..n {
        let a = 2 * i;
        idx.extend([a, a + 2, a + 1, a + 1, a + 2, a + 3]);
    }
    (p, idx)
}

fn soup(rng: &mut Pcg64) -> (Vec<Vec3>, Vec<u32>) {
    let n = rng.random_range(1..8u32);
    let p: Vec<Vec3> = (0..3 * n)
        .map(|_| {
            Vec3::new(
                rng.random_range(-0.5..0.5),
                rng.random_range(-0.5..0.5),
                rng.random_range(-0.5..0.5),
            )
        })
        .collect();
    (p, (0..3 * n).collect())
}

fn random_case(rng: &mut Pcg64) -> Case {
    let extent = match rng.random_range(0..8) {
        0 => Extent2d::try_new(1, 1),
        1 => Extent2d::try_new(rng.random_range(1..4), rng.random_range(1..4)),
        2 => Extent2d::try_new(rng.random_range(60..97), 1),
        _ => Extent2d::try_new(rng.random_range(8..97), rng.random_range(8..61)),
    }
    .unwrap();
    let depth = if rng.random_bool(0.5) {
        DepthConvention::Reverse
    } else {
        DepthConvention::Standard
    };
    let near = 10f32.powf(rng.random_range(-4.0..0.0));
    let projection = if rng.random_bool(0.15) {
        Projection::Orthographic {
            half_height: rng.random_range(0.5..6.0),
            near,
            far: rng.random_range(20.0..200.0),
            depth,
        }
    } else {
        Projection::Perspective {
            fov_y_rad: rng.random_range(20f32..150.0).to_radians(),
            near,
            far: if rng.random_bool(0.5) {
                None
            } else {
                Some(rng.random_range(5.0..1e4))
            },
            depth,
        }
    };
    let format = if rng.random_bool(0.3) {
        DepthFormat::D16Unorm
    } else {
        DepthFormat::D32Float
    };
    let mut occluders = Vec::new();
    for _ in 0..rng.random_range(1..7) {
        let (positions, indices) = match rng.random_range(0..5) {
            0 => grid(rng),
            1 => split_box(),
            2 => fan(rng),
            3 => slivers(rng),
            _ => soup(rng),
        };
        let scale = 10f32.powf(rng.random_range(-0.5..1.0));
        let distance = 10f32.powf(rng.random_range(-0.3..1.3));
        occluders.push(Placed {
            positions,
            indices,
            double_sided: rng.random_bool(0.25),
            linear: rotation(rng) * scale,
            offset: Vec3::new(
                rng.random_range(-0.6..0.6) * distance,
                rng.random_range(-0.6..0.6) * distance,
                -distance,
            ),
        });
    }
    Case {
        extent,
        projection,
        view: Mat4::IDENTITY,
        format,
        bits: if rng.random_bool(0.5) { 8 } else { 4 },
        resolution: (rng.random_range(1..40), rng.random_range(1..30)),
        occluders,
    }
}

#[test]
fn the_bound_is_never_in_front_of_what_the_gpu_draws() {
    let mut rng = Pcg64::seed_from_u64(0x50f7_0cc1);
    let cases: usize = std::env::var("SOFTWARE_CASES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(400);
    let (mut bounded, mut pixels) = (0u64, 0u64);
    for case_index in 0..cases {
        let case = random_case(&mut rng);
        let sw = case.software(Kernel::Simd, 1);
        let reference = case.reference();
        let convention = case.projection.depth_convention();
        let w = case.extent.width_px;
        for (i, d) in reference.iter().enumerate() {
            let (x, y) = (i as u32 % w, i as u32 / w);
            pixels += 1;
            let Some(bound) = sw.pixel_bound(x, y) else {
                continue;
            };
            bounded += 1;
            let Some(d) = d else {
                panic!("case {case_index}: pixel ({x}, {y}) bounded by {bound} but the reference drew nothing there ({:?}, {:?}, {} bits)", case.projection, case.format, case.bits);
            };
            assert!(
                !convention.is_strictly_behind(*d, bound),
                "case {case_index}: pixel ({x}, {y}): reference depth {d} behind the bound {bound} ({:?}, {:?})",
                case.projection,
                case.format
            );
        }
    }
    // The test means something only if the buffer bounds a fair share of the pixels.
    println!("{bounded} of {pixels} pixels bounded");
    assert!(bounded * 10 > pixels, "{bounded} of {pixels}");
}

#[test]
fn simd_and_threads_give_the_scalar_buffers_bit_for_bit() {
    let mut rng = Pcg64::seed_from_u64(0x51d);
    for case_index in 0..300 {
        let mut case = random_case(&mut rng);
        // Larger frames, so that several bands and many tiles take part.
        case.extent =
            Extent2d::try_new(rng.random_range(64..400), rng.random_range(32..300)).unwrap();
        case.resolution = (rng.random_range(8..128), rng.random_range(4..64));
        let scalar = case.software(Kernel::Scalar, 1);
        // Rasterized in batches, the triangles meet the tiles in the same order: the same
        // layers.
        for (kernel, threads, every) in [
            (Kernel::Simd, 1, usize::MAX),
            (Kernel::Simd, 3, usize::MAX),
            (Kernel::Scalar, 4, usize::MAX),
            (Kernel::Simd, 2, 1),
        ] {
            let other = case.software_batched(kernel, threads, every);
            let bits = |s: &SoftwareOcclusion| -> (Vec<u32>, Vec<u32>, Vec<u32>) {
                let (work, masks) = s.working_layer();
                (
                    s.full_layer().iter().map(|k| k.to_bits()).collect(),
                    work.iter().map(|k| k.to_bits()).collect(),
                    masks.to_vec(),
                )
            };
            assert_eq!(
                bits(&scalar),
                bits(&other),
                "case {case_index}: {kernel:?} x{threads}, batches of {every} ({})",
                Kernel::simd_name()
            );
        }
    }
}

/// A wall hides a box behind it and not one in front of it or peeking past its edge; a box the
/// wall's diagonal crosses is hidden too (the two triangles cover the centres between them).
#[test]
fn a_wall_hides_what_is_behind_it() {
    let (positions, indices) = {
        let p = vec![
            Vec3::new(-2.0, -1.0, 0.0),
            Vec3::new(2.0, -1.0, 0.0),
            Vec3::new(2.0, 1.0, 0.0),
            Vec3::new(-2.0, 1.0, 0.0),
        ];
        (p, vec![0, 1, 2, 0, 2, 3])
    };
    for convention in [DepthConvention::Reverse, DepthConvention::Standard] {
        for format in [DepthFormat::D32Float, DepthFormat::D16Unorm] {
            let case = Case {
                extent: Extent2d::try_new(320, 180).unwrap(),
                projection: Projection::Perspective {
                    fov_y_rad: 60f32.to_radians(),
                    near: 0.1,
                    far: None,
                    depth: convention,
                },
                view: Mat4::IDENTITY,
                format,
                bits: 8,
                resolution: (64, 32),
                occluders: vec![Placed {
                    positions: positions.clone(),
                    indices: indices.clone(),
                    double_sided: false,
                    linear: Mat3::IDENTITY,
                    offset: Vec3::new(0.0, 0.0, -5.0),
                }],
            };
            let sw = case.software(Kernel::Simd, 1);
            let aspect = case.aspect();
            let hidden = |center: Vec3, half: f32| {
                let b = Aabb::new(center - Vec3::splat(half), center + Vec3::splat(half));
                let p = project_aabb(&b, &Mat4::IDENTITY, &case.projection, aspect).unwrap();
                let fast = sw
                    .project_box(center.as_dvec3(), glam::DVec3::splat(f64::from(half)))
                    .is_some_and(|r| sw.hides(&r));
                assert_eq!(fast, sw.is_occluded(&p), "{center} {half}");
                fast
            };
            assert!(
                hidden(Vec3::new(0.0, 0.0, -8.0), 0.5),
                "{convention:?} {format:?}"
            );
            // On the diagonal of the quad.
            assert!(
                hidden(Vec3::new(0.4, 0.2, -7.0), 0.3),
                "{convention:?} {format:?}"
            );
            assert!(
                !hidden(Vec3::new(0.0, 0.0, -3.0), 0.5),
                "{convention:?} {format:?}"
            );
            assert!(
                !hidden(Vec3::new(4.0, 0.0, -8.0), 0.5),
                "{convention:?} {format:?}"
            );
            // Touching the wall's plane: not strictly behind.
            assert!(
                !hidden(Vec3::new(0.0, 0.0, -5.5), 0.5),
                "{convention:?} {format:?}"
            );
            // Seen from behind, the wall is a back face the GPU does not draw.
            let mut back = case;
            back.occluders[0].linear = Mat3::from_rotation_y(std::f32::consts::PI);
            let sw = back.software(Kernel::Simd, 1);
            let b = Aabb::new(Vec3::new(-0.5, -0.5, -8.5), Vec3::new(0.5, 0.5, -7.5));
            let p = project_aabb(&b, &Mat4::IDENTITY, &back.projection, aspect).unwrap();
            assert!(!sw.is_occluded(&p));
        }
    }
}

/// The fast box projection the renderer uses covers at least the pixels and depths of the
/// reference projection (`project_aabb`: the 8 corners, outward-rounded): its rectangle holds
/// that one's, its nearest depth is no farther.
#[test]
fn the_fast_box_projection_contains_the_reference_one() {
    let mut rng = Pcg64::seed_from_u64(0xb0c5);
    let mut compared = 0;
    for _ in 0..2000 {
        let case = random_case(&mut rng);
        let sw = case.software(Kernel::Simd, 1);
        let center = Vec3::new(
            rng.random_range(-20.0..20.0),
            rng.random_range(-20.0..20.0),
            rng.random_range(-60.0..5.0),
        );
        let half = Vec3::new(
            10f32.powf(rng.random_range(-3.0..1.0)),
            10f32.powf(rng.random_range(-3.0..1.0)),
            10f32.powf(rng.random_range(-3.0..1.0)),
        );
        let b = Aabb::new(center - half, center + half);
        let reference = project_aabb(&b, &Mat4::IDENTITY, &case.projection, case.aspect()).unwrap();
        let fast = sw.project_box(center.as_dvec3(), half.as_dvec3());
        let tilegraph_cull::ScreenProjection::Projected(p) = reference else {
            continue;
        };
        let Some(fast) = fast else {
            continue; // the fast path gives up near the near plane: never hides
        };
        let r = p.rect_ndc.to_pixel_rect(case.extent).unwrap();
        assert!(
            fast.min.0 <= i64::from(r.min_x)
                && fast.min.1 <= i64::from(r.min_y)
                && fast.max.0 >= i64::from(r.max_x)
                && fast.max.1 >= i64::from(r.max_y),
            "{fast:?} does not hold {r:?}"
        );
        let convention = case.projection.depth_convention();
        let near = case.format.toward_near(convention, p.nearest_depth);
        let key = match convention {
            DepthConvention::Standard => near,
            DepthConvention::Reverse => -near,
        };
        assert!(fast.near_key <= key, "{} > {key}", fast.near_key);
        compared += 1;
    }
    assert!(compared > 500, "{compared}");
}
