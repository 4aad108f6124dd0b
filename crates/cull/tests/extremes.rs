//! The extremes matrix: each numerically hard case from DESIGN.md run end to end against the
//! CPU references (frustum plane test + SAT, projection, HiZ in both NPOT fixes and the naive
//! reduction) and against an exact ray-cast render (does the object own a pixel?).
//!
//! `cargo test -p tilegraph-cull --test extremes -- --nocapture` prints the table that
//! docs/CULLING.md reproduces.

use glam::{DVec3, Mat4, Vec3};
use tilegraph_cull::reference::{look, render_boxes, Render};
use tilegraph_cull::{
    project_aabb, project_sphere, Aabb, AabbExt, DepthConvention, DepthFormat, Extent2d, ExtentExt,
    Frustum, FrustumPlane, HizOutcome, HizPyramid, NpotMode, PlaneTest, Projection, SatTest,
    ScreenProjection, Sphere,
};

struct World {
    view: Mat4,
    projection: Projection,
    /// The viewport's width / height the projection is used with.
    aspect: f32,
    extent: Extent2d,
    format: DepthFormat,
    occluders: Vec<Aabb>,
}

struct Probe {
    plane: PlaneTest,
    sat: SatTest,
    projection: ScreenProjection,
    edge: HizOutcome,
    pad: HizOutcome,
    naive: HizOutcome,
    /// Pixels the object owns in the exact render of occluders + object.
    visible_px: usize,
}

impl Probe {
    /// Culled by the shipped pipeline (frustum planes, then HiZ with either fix)?
    fn culled(&self) -> bool {
        self.plane.is_outside() || self.edge.is_culled() || self.pad.is_culled()
    }

    fn summary(&self) -> String {
        let hiz = |o: &HizOutcome| match o {
            HizOutcome::Occluded(p) => format!("Occluded@L{}", p.level),
            HizOutcome::Visible(p) => format!("Visible@L{}", p.level),
            HizOutcome::OffScreen => "OffScreen".into(),
            HizOutcome::NotProjectable => "NotProjectable".into(),
        };
        let proj = match self.projection {
            ScreenProjection::Projected(_) => "rect".to_string(),
            other => format!("{other:?}"),
        };
        format!(
            "planes {:?}; SAT {}; proj {}; HiZ edge {} / pad {}; {} px visible",
            self.plane,
            if self.sat.is_separated() {
                "separated"
            } else {
                "overlap"
            },
            proj,
            hiz(&self.edge),
            hiz(&self.pad),
            self.visible_px
        )
    }
}

impl World {
    fn new(
        view: Mat4,
        (projection, aspect): (Projection, f32),
        (w, h): (u32, u32),
        format: DepthFormat,
        occluders: Vec<Aabb>,
    ) -> Self {
        World {
            view,
            projection,
            aspect,
            extent: Extent2d::try_new(w, h).unwrap(),
            format,
            occluders,
        }
    }

    fn probe(&self, object: Aabb) -> Probe {
        let conv = self.projection.depth_convention();
        let frustum =
            Frustum::from_clip_from_world(&(self.projection.matrix(self.aspect) * self.view), conv)
                .unwrap();
        // HiZ is built from the occluders alone (phase 1 of two-phase occlusion); the exact
        // render includes the object.
        let occ: Render = render_boxes(
            &self.view,
            &self.projection,
            self.aspect,
            self.extent,
            self.format,
            &self.occluders,
        );
        let mut all = self.occluders.clone();
        all.push(object);
        let full = render_boxes(
            &self.view,
            &self.projection,
            self.aspect,
            self.extent,
            self.format,
            &all,
        );
        let object_id = self.occluders.len() as u32;
        let projection = project_aabb(&object, &self.view, &self.projection, self.aspect).unwrap();
        let test = |mode| {
            HizPyramid::build(&occ.depth, self.extent, conv, self.format, mode)
                .unwrap()
                .test_projection(&projection)
                .unwrap()
        };
        let probe = Probe {
            plane: frustum.test_aabb(&object).unwrap(),
            sat: frustum.sat_aabb(&object).unwrap(),
            projection,
            edge: test(NpotMode::EdgeAware),
            pad: test(NpotMode::PadToPow2),
            naive: test(NpotMode::NaiveBuggy),
            visible_px: full.ids.iter().filter(|&&id| id == object_id).count(),
        };
        // The invariant behind every row: nothing that owns a pixel is ever culled, by the
        // plane test, the SAT or either HiZ fix.
        assert!(
            probe.visible_px == 0 || (!probe.culled() && !probe.sat.is_separated()),
            "false negative: {}",
            probe.summary()
        );
        probe
    }
}

struct Row {
    case: &'static str,
    setup: String,
    expected: &'static str,
    got: String,
    pass: bool,
}

fn row(
    case: &'static str,
    setup: impl Into<String>,
    expected: &'static str,
    got: String,
    pass: bool,
) -> Row {
    Row {
        case,
        setup: setup.into(),
        expected,
        got,
        pass,
    }
}

fn forward() -> Mat4 {
    look(Vec3::ZERO, Vec3::NEG_Z)
}

/// A slab facing the camera at distance `dist` m (thickness 1% of it), `half` m wide.
fn wall(dist: f32, half: f32) -> Aabb {
    Aabb::try_new(
        Vec3::new(-half, -half, -dist * 1.01),
        Vec3::new(half, half, -dist),
    )
    .unwrap()
}

fn cube(center: Vec3, half: f32) -> Aabb {
    Aabb::from_center_half_extents(center, Vec3::splat(half)).unwrap()
}

const FOV: f32 = 1.0;

fn reverse_infinite_far() -> Vec<Row> {
    let (p, aspect) = (Projection::tilegraph_default(FOV, 0.1), 16.0 / 9.0);
    let w = World::new(
        forward(),
        (p, aspect),
        (160, 90),
        DepthFormat::D32Float,
        vec![wall(10.0, 100.0)],
    );
    let behind = w.probe(cube(Vec3::new(0.0, 0.0, -1e6), 1e4));
    let open = World::new(
        forward(),
        (p, aspect),
        (160, 90),
        DepthFormat::D32Float,
        vec![],
    )
    .probe(cube(Vec3::new(0.0, 0.0, -1e6), 1e4));
    let f =
        Frustum::from_clip_from_world(&(p.matrix(aspect) * forward()), DepthConvention::Reverse)
            .unwrap();
    vec![
        row(
            "reverse-Z, infinite far",
            "near 0.1; 20 km box at 10^6 m (about 2 px) behind a wall at 10 m, 160x90",
            "far plane absent (no NaN); frustum keeps; HiZ culls",
            format!(
                "far plane {:?}; {}",
                f.plane(FrustumPlane::Far).map(|_| "present"),
                behind.summary()
            ),
            f.plane(FrustumPlane::Far).is_none()
                && !behind.plane.is_outside()
                && behind.edge.is_culled()
                && behind.pad.is_culled(),
        ),
        row(
            "reverse-Z, infinite far",
            "same box, no wall (depth cleared to 0)",
            "kept (owns pixels)",
            open.summary(),
            !open.culled() && open.visible_px > 0,
        ),
    ]
}

fn reverse_finite_far() -> Vec<Row> {
    let (p, aspect) = (
        Projection::Perspective {
            fov_y_rad: FOV,
            near: 1e-3,
            far: Some(1e7),
            depth: DepthConvention::Reverse,
        },
        16.0 / 9.0,
    );
    let w = World::new(
        forward(),
        (p, aspect),
        (160, 90),
        DepthFormat::D32Float,
        vec![wall(10.0, 100.0)],
    );
    let behind = w.probe(cube(Vec3::new(0.0, 0.0, -5e6), 1e5));
    let beyond = w.probe(cube(Vec3::new(0.0, 0.0, -2e7), 1e5));
    let open = World::new(
        forward(),
        (p, aspect),
        (160, 90),
        DepthFormat::D32Float,
        vec![],
    )
    .probe(cube(Vec3::new(0.0, 0.0, -5e6), 1e5));
    vec![
        row(
            "reverse-Z, finite far",
            "near 1e-3, far 1e7; 200 km box at 5e6 m behind a wall at 10 m, 160x90",
            "frustum keeps; HiZ culls",
            behind.summary(),
            !behind.plane.is_outside() && behind.edge.is_culled() && behind.pad.is_culled(),
        ),
        row(
            "reverse-Z, finite far",
            "same box in the open",
            "kept (owns pixels)",
            open.summary(),
            !open.culled() && open.visible_px > 0,
        ),
        row(
            "reverse-Z, finite far",
            "box at 2e7 m (beyond far)",
            "far plane rejects",
            beyond.summary(),
            beyond.plane == PlaneTest::Outside(FrustumPlane::Far) && beyond.visible_px == 0,
        ),
    ]
}

fn standard_and_ortho() -> Vec<Row> {
    let mut rows = Vec::new();
    let (persp, persp_aspect) = (
        Projection::Perspective {
            fov_y_rad: FOV,
            near: 0.1,
            far: Some(1000.0),
            depth: DepthConvention::Standard,
        },
        4.0 / 3.0,
    );
    let w = World::new(
        forward(),
        (persp, persp_aspect),
        (64, 48),
        DepthFormat::D32Float,
        vec![wall(20.0, 100.0)],
    );
    let hidden = w.probe(cube(Vec3::new(0.0, 0.0, -200.0), 5.0));
    let front = w.probe(cube(Vec3::new(0.0, 0.0, -10.0), 1.0));
    rows.push(row(
        "standard Z, finite far",
        "near 0.1, far 1000; box at 200 m behind a wall at 20 m / box at 10 m in front",
        "culled / kept",
        format!("{} || {}", hidden.summary(), front.summary()),
        hidden.edge.is_culled()
            && hidden.pad.is_culled()
            && !front.culled()
            && front.visible_px > 0,
    ));
    for conv in [DepthConvention::Standard, DepthConvention::Reverse] {
        let (ortho, ortho_aspect) = (
            Projection::Orthographic {
                half_height: 15.0,
                near: 0.0,
                far: 500.0,
                depth: conv,
            },
            40.0 / 30.0,
        );
        let w = World::new(
            forward(),
            (ortho, ortho_aspect),
            (64, 48),
            DepthFormat::D32Float,
            vec![wall(20.0, 100.0)],
        );
        let hidden = w.probe(cube(Vec3::new(3.0, 2.0, -100.0), 4.0));
        let front = w.probe(cube(Vec3::new(3.0, 2.0, -10.0), 4.0));
        rows.push(row(
            if conv == DepthConvention::Standard {
                "orthographic, standard Z"
            } else {
                "orthographic, reverse Z"
            },
            "0..500 m; box at 100 m behind a wall at 20 m / box at 10 m in front",
            "culled / kept",
            format!("{} || {}", hidden.summary(), front.summary()),
            hidden.edge.is_culled()
                && hidden.pad.is_culled()
                && !front.culled()
                && front.visible_px > 0,
        ));
    }
    rows
}

fn tiny_near_plane() -> Vec<Row> {
    let (p, aspect) = (Projection::tilegraph_default(FOV, 1e-4), 1.0);
    let w = World::new(
        forward(),
        (p, aspect),
        (64, 64),
        DepthFormat::D32Float,
        vec![wall(1e-2, 1.0)],
    );
    let hidden = w.probe(cube(Vec3::new(0.0, 0.0, -2e-2), 1e-3));
    let front = w.probe(cube(Vec3::new(0.0, 0.0, -2e-3), 2e-4));
    // Beside the eye (x from 0.2 mm), so it crosses the near plane without containing the eye.
    let crossing = w.probe(cube(Vec3::new(7e-4, 0.0, -1e-4), 5e-4));
    vec![
        row(
            "near plane 1e-4 m",
            "1 mm box at 2 cm behind a wall at 1 cm",
            "culled",
            hidden.summary(),
            hidden.edge.is_culled() && hidden.pad.is_culled(),
        ),
        row(
            "near plane 1e-4 m",
            "0.2 mm box at 2 mm, in front of the wall",
            "kept",
            front.summary(),
            !front.culled() && front.visible_px > 0,
        ),
        row(
            "object crossing the near plane",
            "1 mm box beside the eye spanning z = -0.6 mm .. +0.4 mm (near plane at 0.1 mm)",
            "TouchesNearPlane -> kept",
            crossing.summary(),
            crossing.projection == ScreenProjection::TouchesNearPlane && !crossing.culled(),
        ),
    ]
}

/// The same near-plane cases for spheres (exact tangent-plane projection), against a HiZ of a
/// wall at 5 m.
fn spheres() -> Vec<Row> {
    let (p, aspect) = (Projection::tilegraph_default(FOV, 0.1), 1.0);
    let view = forward();
    let extent = Extent2d::try_new(64, 64).unwrap();
    let frustum =
        Frustum::from_clip_from_world(&(p.matrix(aspect) * view), DepthConvention::Reverse)
            .unwrap();
    let wall_depth = render_boxes(
        &view,
        &p,
        aspect,
        extent,
        DepthFormat::D32Float,
        &[wall(5.0, 50.0)],
    )
    .depth;
    let hiz = HizPyramid::build(
        &wall_depth,
        extent,
        DepthConvention::Reverse,
        DepthFormat::D32Float,
        NpotMode::EdgeAware,
    )
    .unwrap();
    let case = |c: Vec3, r: f32| {
        let s = Sphere::new(c, r).unwrap();
        let proj = project_sphere(&s, &view, &p, aspect).unwrap();
        (
            frustum.test_sphere(&s).unwrap(),
            proj,
            hiz.test_projection(&proj).unwrap(),
        )
    };
    let describe = |(plane, proj, hiz): &(PlaneTest, ScreenProjection, HizOutcome)| {
        let proj = match proj {
            ScreenProjection::Projected(_) => "rect".to_string(),
            other => format!("{other:?}"),
        };
        let hiz = match hiz {
            HizOutcome::Occluded(p) => format!("Occluded@L{}", p.level),
            HizOutcome::Visible(p) => format!("Visible@L{}", p.level),
            other => format!("{other:?}"),
        };
        format!("planes {plane:?}; proj {proj}; HiZ {hiz}")
    };
    let inside = case(Vec3::new(0.2, 0.1, -0.3), 1.0);
    let crossing = case(Vec3::new(0.05, 0.0, -0.1), 0.08);
    let behind = case(Vec3::new(0.0, 0.0, 30.0), 2.0);
    let hidden = case(Vec3::new(0.3, 0.2, -30.0), 0.05);
    let in_front = case(Vec3::new(0.3, 0.2, -3.0), 0.05);
    vec![
        row(
            "sphere: camera inside",
            "r = 1 m around the eye",
            "CameraInside -> kept",
            describe(&inside),
            inside.1 == ScreenProjection::CameraInside
                && !inside.0.is_outside()
                && !inside.2.is_culled(),
        ),
        row(
            "sphere: crossing the near plane",
            "r = 8 cm, centre 10 cm ahead (near 0.1 m), not containing the eye",
            "TouchesNearPlane -> kept",
            describe(&crossing),
            crossing.1 == ScreenProjection::TouchesNearPlane
                && !crossing.0.is_outside()
                && !crossing.2.is_culled(),
        ),
        row(
            "sphere: behind the camera",
            "r = 2 m, 30 m behind",
            "BeforeNearPlane (no rect); planes reject",
            describe(&behind),
            behind.1 == ScreenProjection::BeforeNearPlane
                && behind.0.is_outside()
                && !behind.2.is_culled(),
        ),
        row(
            "sphere: small, behind / in front of a wall",
            "r = 5 cm at 30 m / at 3 m, wall at 5 m, 64x64",
            "culled / kept",
            format!("{} || {}", describe(&hidden), describe(&in_front)),
            hidden.2.is_culled() && matches!(in_front.2, HizOutcome::Visible(_)),
        ),
    ]
}

fn camera_inside_and_behind() -> Vec<Row> {
    let (p, aspect) = (Projection::tilegraph_default(FOV, 0.1), 1.0);
    let w = World::new(
        forward(),
        (p, aspect),
        (64, 64),
        DepthFormat::D32Float,
        vec![wall(5.0, 50.0)],
    );
    let inside = w.probe(cube(Vec3::new(0.3, -0.2, 0.1), 2.0));
    let behind = w.probe(cube(Vec3::new(0.0, 0.0, 20.0), 3.0));
    vec![
        row(
            "camera inside the bounds",
            "eye inside a 4 m box, wall at 5 m",
            "CameraInside -> kept",
            inside.summary(),
            inside.projection == ScreenProjection::CameraInside && !inside.culled(),
        ),
        row(
            "object behind the camera",
            "6 m box centred 20 m behind the eye",
            "projection BeforeNearPlane (no rect); frustum rejects",
            behind.summary(),
            behind.projection == ScreenProjection::BeforeNearPlane
                && behind.plane.is_outside()
                && behind.sat.is_separated(),
        ),
    ]
}

fn zero_extent() -> Vec<Row> {
    let (p, aspect) = (Projection::tilegraph_default(FOV, 0.1), 1.0);
    let point = Aabb::try_new(Vec3::new(0.5, 0.25, -30.0), Vec3::new(0.5, 0.25, -30.0)).unwrap();
    let hidden = World::new(
        forward(),
        (p, aspect),
        (64, 64),
        DepthFormat::D32Float,
        vec![wall(10.0, 50.0)],
    )
    .probe(point);
    let open = World::new(
        forward(),
        (p, aspect),
        (64, 64),
        DepthFormat::D32Float,
        vec![],
    )
    .probe(point);
    let rect_px = match open.projection {
        ScreenProjection::Projected(b) => {
            let r = b
                .rect_ndc
                .to_pixel_rect(Extent2d::try_new(64, 64).unwrap())
                .unwrap();
            ((r.max_x - r.min_x + 1) * (r.max_y - r.min_y + 1)) as u32
        }
        _ => 0,
    };
    vec![
        row(
            "zero-extent bounds",
            "point box at 30 m behind a wall at 10 m",
            "culled",
            hidden.summary(),
            hidden.edge.is_culled() && hidden.pad.is_culled(),
        ),
        row(
            "zero-extent bounds",
            "same point in the open",
            "kept; rect of 1 px; frustum and SAT keep",
            format!("{}; rect {rect_px} px", open.summary()),
            !open.culled() && !open.sat.is_separated() && rect_px == 1,
        ),
    ]
}

/// The caller makes coordinates camera-relative in f64. Compared with the same scene at the
/// origin, results must be identical; the naive all-f32 world-space path is shown for scale.
fn large_coordinates() -> Vec<Row> {
    let (p, aspect) = (Projection::tilegraph_default(FOV, 0.1), 16.0 / 9.0);
    let extent = Extent2d::try_new(1920, 1080).unwrap();
    let offset = DVec3::new(1e6 + 0.37, 1e6 - 0.21, -1e6 + 0.55);
    let eye = offset;
    let target_rel = DVec3::new(0.3, -0.1, -1.0);
    let object_rel_min = DVec3::new(0.013, 0.021, -1.5);
    let object_rel_max = object_rel_min + DVec3::new(0.05, 0.04, 0.03);
    let wall_rel = (DVec3::new(-5.0, -5.0, -1.0), DVec3::new(5.0, 5.0, -0.9));

    let view_rel = look(Vec3::ZERO, target_rel.as_vec3());
    // Camera at 1e6: world coordinates in f64, made relative to the eye.
    let rel = |lo: DVec3, hi: DVec3| Aabb::from_world_f64(lo + offset, hi + offset, eye).unwrap();
    let far_obj = rel(object_rel_min, object_rel_max);
    let far_wall = rel(wall_rel.0, wall_rel.1);
    // Camera at the origin: the same relative coordinates directly.
    let org = |lo: DVec3, hi: DVec3| Aabb::from_world_f64(lo, hi, DVec3::ZERO).unwrap();
    let near_obj = org(object_rel_min, object_rel_max);

    let rect_of = |b: &Aabb, view: &Mat4| match project_aabb(b, view, &p, aspect).unwrap() {
        ScreenProjection::Projected(pb) => Some(pb.rect_ndc.to_pixel_rect(extent).unwrap()),
        _ => None,
    };
    let r_far = rect_of(&far_obj, &view_rel);
    let r_org = rect_of(&near_obj, &view_rel);
    // Naive: f32 world coordinates and an f32 view matrix with the 1e6 translation.
    let naive_eye = eye.as_vec3();
    let naive_view = Mat4::look_at_rh(naive_eye, naive_eye + target_rel.as_vec3(), Vec3::Y);
    let naive_obj = Aabb::try_new(
        (object_rel_min + offset).as_vec3(),
        (object_rel_max + offset).as_vec3(),
    )
    .unwrap();
    let r_naive = rect_of(&naive_obj, &naive_view);
    let shift = match (r_naive, r_org) {
        (Some(a), Some(b)) => (a.min_x - b.min_x).abs().max((a.min_y - b.min_y).abs()),
        _ => -1,
    };
    let w = World::new(
        view_rel,
        (p, aspect),
        (1920, 1080),
        DepthFormat::D32Float,
        vec![far_wall],
    );
    let hidden = w.probe(far_obj);
    vec![
        row(
            "world coordinates at 10^6 m",
            "camera at (1e6, 1e6, -1e6) vs origin, camera-relative f64 -> f32; 5 cm box at 1.5 m behind a wall at 0.9 m, 1920x1080",
            "identical pixel rects; behind a wall -> culled",
            format!("rect at 1e6 {r_far:?} == at origin {r_org:?}; naive f32 world path off by {shift} px; {}", hidden.summary()),
            r_far.is_some() && r_far == r_org && hidden.edge.is_culled() && hidden.pad.is_culled(),
        ),
    ]
}

/// Viewports: a wall covers every column except the last one; a box behind the wall whose rect
/// reaches the last column is visible through it. The naive reduction is reported too.
fn viewports() -> Vec<Row> {
    let mut rows = Vec::new();
    for (w, h) in [
        (1u32, 1u32),
        (2, 1),
        (3, 3),
        (27, 13),
        (1920, 1080),
        (4096, 1),
    ] {
        let aspect = w as f32 / h as f32;
        let p = Projection::tilegraph_default(FOV, 0.1);
        let (sx, _) = p.ndc_scale(aspect);
        let dist = 10.0f32;
        // NDC x of the left edge of the last column, as view x at the wall's distance.
        // Half the view's width/height at distance d is d / |scale|; walls reach twice that.
        let sy = p.ndc_scale(aspect).1.abs();
        let reach = |d: f32| (2.0 * f64::from(d) * (1.0 / sx).max(1.0 / sy)) as f32 + 1.0;
        // NDC x of the left edge of the last column, as view x at the wall's distance.
        let edge_ndc = (w as f64 - 1.0) / w as f64 * 2.0 - 1.0;
        let edge_x = (edge_ndc / sx * f64::from(dist)) as f32;
        let full_wall = wall(dist, reach(dist));
        // At 1 px wide there is no "all but the last column": the wall covers everything.
        let wall_box = if w > 1 {
            let r = reach(dist);
            Aabb::try_new(Vec3::new(-r, -r, -dist * 1.01), Vec3::new(edge_x, r, -dist)).unwrap()
        } else {
            full_wall
        };
        let r = reach(60.0);
        let right = Aabb::try_new(Vec3::new(-r, -r, -60.0), Vec3::new(r, r, -50.0)).unwrap();
        let world_gap = World::new(
            forward(),
            (p, aspect),
            (w, h),
            DepthFormat::D32Float,
            vec![wall_box],
        );
        let world_full = World::new(
            forward(),
            (p, aspect),
            (w, h),
            DepthFormat::D32Float,
            vec![full_wall],
        );
        let through_gap = world_gap.probe(right);
        let behind_full = world_full.probe(right);
        let gap_expected_visible = w > 1;
        rows.push(row(
            "viewport",
            format!(
                "{w}x{h}: wall over all but the last column; box behind it / behind a full wall"
            ),
            if w > 1 {
                "seen through the gap -> kept / culled"
            } else {
                "no gap at 1 px -> culled / culled"
            },
            format!(
                "gap: {} (naive: {}) || full: {}",
                through_gap.summary(),
                if through_gap.naive.is_culled() {
                    "CULLED"
                } else {
                    "kept"
                },
                behind_full.summary()
            ),
            (through_gap.visible_px > 0) == gap_expected_visible
                && through_gap.culled() != gap_expected_visible
                && behind_full.edge.is_culled()
                && behind_full.pad.is_culled(),
        ));
    }
    rows
}

fn depth_formats() -> Vec<Row> {
    let mut rows = Vec::new();
    let (p, aspect) = (Projection::tilegraph_default(FOV, 0.1), 1.0);
    for format in [DepthFormat::D32Float, DepthFormat::D16Unorm] {
        let w = World::new(
            forward(),
            (p, aspect),
            (32, 32),
            format,
            vec![wall(10.0, 50.0)],
        );
        // 1 mm behind the wall's front face: 0.1/10 vs 0.1/10.001, 1e-6 apart: below one D16
        // step (1.5e-5), above D32's resolution.
        let just_behind = w.probe(
            Aabb::try_new(Vec3::new(-0.5, -0.5, -10.2), Vec3::new(0.5, 0.5, -10.001)).unwrap(),
        );
        let well_behind = w.probe(cube(Vec3::new(0.0, 0.0, -40.0), 1.0));
        let expect_just = format == DepthFormat::D32Float;
        rows.push(row(
            if format == DepthFormat::D32Float {
                "D32F depth"
            } else {
                "D16 depth"
            },
            "box 1 mm behind a wall at 10 m / box at 40 m",
            if format == DepthFormat::D32Float {
                "culled / culled"
            } else {
                "kept (same code, conservative) / culled"
            },
            format!("{} || {}", just_behind.summary(), well_behind.summary()),
            just_behind.edge.is_culled() == expect_just
                && well_behind.edge.is_culled()
                && well_behind.pad.is_culled(),
        ));
    }
    // D16 with reverse infinite: depth 0.1/d is below half a code beyond 0.1 * 2 * 65535 m, so
    // far occluders and far objects collapse onto code 0/1 and cannot cull each other.
    let w = World::new(
        forward(),
        (p, aspect),
        (32, 32),
        DepthFormat::D16Unorm,
        vec![wall(5000.0, 1e5)],
    );
    let far = w.probe(cube(Vec3::new(0.0, 0.0, -20000.0), 10.0));
    rows.push(row(
        "D16 + reverse infinite, far range",
        "wall at 5 km (code 1), box at 20 km (code 0)",
        "kept: toward-near rounding of the box gives code 1, not behind",
        far.summary(),
        !far.culled(),
    ));
    rows
}

fn one_pixel_objects() -> Vec<Row> {
    let (p, aspect) = (Projection::tilegraph_default(FOV, 0.1), 16.0 / 9.0);
    let (w, h) = (1920u32, 1080u32);
    // A 1 cm cube at 20 m: about 0.47 px wide.
    let obj = cube(Vec3::new(0.05, 0.03, -20.0), 0.005);
    let hidden = World::new(
        forward(),
        (p, aspect),
        (w, h),
        DepthFormat::D32Float,
        vec![wall(10.0, 50.0)],
    )
    .probe(obj);
    let open = World::new(
        forward(),
        (p, aspect),
        (w, h),
        DepthFormat::D32Float,
        vec![],
    )
    .probe(obj);
    // A wall with a one-pixel hole exactly where the object is.
    let (sx, sy) = p.ndc_scale(aspect);
    let mut holed = Vec::new();
    let px = |x: f64| ((x + 1.0) * 0.5 * f64::from(w)).floor();
    let py = |y: f64| ((y + 1.0) * 0.5 * f64::from(h)).floor();
    let cx = px(sx * 0.05 / 20.0);
    let cy = py(sy * 0.03 / 20.0);
    // Pixel (cx, cy) bounds in view units at 10 m.
    let to_x = |pxl: f64| ((pxl / f64::from(w) * 2.0 - 1.0) / sx * 10.0) as f32;
    let to_y = |pyl: f64| ((pyl / f64::from(h) * 2.0 - 1.0) / sy * 10.0) as f32;
    let (x0, x1) = (to_x(cx), to_x(cx + 1.0));
    let (ya, yb) = (to_y(cy), to_y(cy + 1.0));
    let (y0, y1) = (ya.min(yb), ya.max(yb));
    let z = (-10.1, -10.0);
    holed.push(Aabb::try_new(Vec3::new(-50.0, -50.0, z.0), Vec3::new(x0, 50.0, z.1)).unwrap());
    holed.push(Aabb::try_new(Vec3::new(x1, -50.0, z.0), Vec3::new(50.0, 50.0, z.1)).unwrap());
    holed.push(Aabb::try_new(Vec3::new(x0, -50.0, z.0), Vec3::new(x1, y0, z.1)).unwrap());
    holed.push(Aabb::try_new(Vec3::new(x0, y1, z.0), Vec3::new(x1, 50.0, z.1)).unwrap());
    let through_hole =
        World::new(forward(), (p, aspect), (w, h), DepthFormat::D32Float, holed).probe(obj);
    vec![
        row(
            "one-pixel object",
            "1 cm cube at 20 m, 1920x1080 (owns the pixel whose centre it covers); behind a wall",
            "culled",
            hidden.summary(),
            hidden.edge.is_culled() && hidden.pad.is_culled(),
        ),
        row(
            "one-pixel object",
            "same, in the open",
            "kept",
            open.summary(),
            !open.culled(),
        ),
        row(
            "one-pixel object",
            "same, behind a wall with a 1-pixel hole at the object",
            "kept",
            through_hole.summary(),
            !through_hole.culled(),
        ),
    ]
}

#[test]
fn extremes_matrix() {
    let rows: Vec<Row> = [
        reverse_infinite_far(),
        reverse_finite_far(),
        standard_and_ortho(),
        tiny_near_plane(),
        camera_inside_and_behind(),
        spheres(),
        zero_extent(),
        large_coordinates(),
        viewports(),
        depth_formats(),
        one_pixel_objects(),
    ]
    .into_iter()
    .flatten()
    .collect();
    println!("| case | setup | expected | result | pass |");
    println!("|---|---|---|---|---|");
    for r in &rows {
        println!(
            "| {} | {} | {} | {} | {} |",
            r.case,
            r.setup,
            r.expected,
            r.got,
            if r.pass { "yes" } else { "**NO**" }
        );
    }
    let failed: Vec<&str> = rows.iter().filter(|r| !r.pass).map(|r| r.case).collect();
    assert!(failed.is_empty(), "failed cases: {failed:?}");
}
