//! Procedural scenes: exact sizes, determinism, the culling spectrum they claim (measured by
//! ray casts against their occluders), their camera paths, and a round trip through GLB.

use std::collections::HashSet;

use glam::{DVec3, Vec3};
use tilegraph_scene::{
    default_scene, export, generate, load, load_gltf_bytes, DAabb, Limits, MaterialClass,
    NoResources, ProceduralKind, ProceduralParams, Scene,
};

fn gen(kind: ProceduralKind, size: usize, seed: u64) -> Scene {
    generate(kind, ProceduralParams { size, seed }).unwrap()
}

#[test]
fn every_kind_places_exactly_the_requested_instances() {
    for kind in ProceduralKind::ALL {
        for size in [0, 300, 2_500] {
            let s = gen(kind, size, 3);
            let want = size.max(kind.minimum_size());
            assert_eq!(s.instances().len(), want, "{kind} size {size}");
            // A handful of shared meshes, many instances.
            assert!(
                s.meshes().len() <= 16,
                "{kind}: {} meshes",
                s.meshes().len()
            );
            let info = s.info();
            assert_eq!(info.instances as usize, want);
            assert!(info.triangles > info.unique_triangles, "{kind}: instancing");
            // Standing on y = 0: nothing below the ground.
            assert!(
                s.bounds().min.y >= -1e-4,
                "{kind}: min y {}",
                s.bounds().min.y
            );
            for i in s.instances() {
                assert!((i.mesh.0 as usize) < s.meshes().len());
                assert!(s.bounds().contains_box(&i.bounds.aabb(), 1e-6));
            }
        }
    }
}

#[test]
fn same_seed_same_scene_other_seed_other_scene() {
    for kind in ProceduralKind::ALL {
        let a = gen(kind, 1_000, 7);
        let b = gen(kind, 1_000, 7);
        let c = gen(kind, 1_000, 8);
        assert_eq!(a.instances(), b.instances(), "{kind}");
        assert_eq!(a.camera_path(), b.camera_path(), "{kind}");
        assert_ne!(a.instances(), c.instances(), "{kind}");
    }
}

#[test]
fn each_kind_has_the_material_mix_it_claims() {
    let city = gen(ProceduralKind::City, 3_000, 1).info();
    assert!(city.instances_by_class.blended > 0, "city glass");
    assert!(city.instances_by_class.opaque > 10 * city.instances_by_class.blended);
    let forest = gen(ProceduralKind::Forest, 3_000, 1).info();
    assert!(
        forest.instances_by_class.alpha_tested > forest.instances_by_class.opaque,
        "{forest}"
    );
    let interior = gen(ProceduralKind::Interior, 3_000, 1).info();
    let c = interior.instances_by_class;
    assert!(
        c.opaque > 0 && c.alpha_tested > 0 && c.blended > 0,
        "{interior}"
    );
    let forest_scene = gen(ProceduralKind::Forest, 500, 1);
    for m in forest_scene.materials() {
        if let MaterialClass::AlphaTested { cutoff } = m.class {
            assert!(m.double_sided && cutoff > 0.0 && cutoff < 1.0);
        }
    }
}

/// Segment-vs-box (slab method): does the segment from `a` to `b` pass through `bx`?
fn segment_hits(a: DVec3, b: DVec3, bx: &DAabb) -> bool {
    let d = b - a;
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for k in 0..3 {
        if d[k].abs() < 1e-12 {
            if a[k] < bx.min[k] || a[k] > bx.max[k] {
                return false;
            }
        } else {
            let (mut n, mut f) = ((bx.min[k] - a[k]) / d[k], (bx.max[k] - a[k]) / d[k]);
            if n > f {
                std::mem::swap(&mut n, &mut f);
            }
            t0 = t0.max(n);
            t1 = t1.min(f);
            if t0 > t1 {
                return false;
            }
        }
    }
    true
}

/// Share of the objects within `radius` of the path's first eye whose centre is hidden behind an
/// opaque occluder box (tall, wide boxes: buildings, walls, sheds), by ray casts. A crude but
/// honest proxy for "most objects hidden from street level".
fn hidden_share(s: &Scene, radius: f64) -> (f64, usize) {
    let eye = s.camera_path().camera(0).unwrap().eye;
    let opaque = |i: &tilegraph_scene::Instance| {
        matches!(
            s.instance_material(i).map(|m| m.class),
            Some(MaterialClass::Opaque)
        )
    };
    let occluders: Vec<(usize, DAabb)> = s
        .instances()
        .iter()
        .enumerate()
        .filter(|(_, i)| opaque(i))
        .filter(|(_, i)| {
            let h = i.bounds.half_extents;
            // Tall enough to hide a person-height view, and a real wall (not a post).
            h.y >= 1.2 && h.x.max(h.z) >= 1.5 && i.bounds.aabb().min.y < 0.5
        })
        .map(|(k, i)| (k, i.bounds.aabb()))
        .collect();
    let occluder_ids: HashSet<usize> = occluders.iter().map(|(k, _)| *k).collect();
    let mut hidden = 0;
    let mut total = 0;
    for (k, inst) in s.instances().iter().enumerate() {
        let c = inst.bounds.center;
        if occluder_ids.contains(&k)
            || (c - eye).length() > radius
            || inst.bounds.half_extents.y > 20.0
        {
            continue;
        }
        total += 1;
        if occluders
            .iter()
            .any(|(_, b)| segment_hits(eye, c, b) && !b.contains(eye))
        {
            hidden += 1;
        }
    }
    (hidden as f64 / total.max(1) as f64, total)
}

#[test]
fn kinds_span_the_culling_spectrum() {
    let city = gen(ProceduralKind::City, 20_000, 1);
    let interior = gen(ProceduralKind::Interior, 20_000, 1);
    let field = gen(ProceduralKind::Field, 20_000, 1);
    let (c, cn) = hidden_share(&city, 300.0);
    let (i, inn) = hidden_share(&interior, 60.0);
    let (f, fnn) = hidden_share(&field, 1_000.0);
    println!("hidden from the first camera: city {c:.2} of {cn}, interior {i:.2} of {inn}, field {f:.2} of {fnn}");
    assert!(cn > 100 && inn > 100 && fnn > 100, "too few samples");
    assert!(
        c > 0.6,
        "city: most props hidden from street level ({c:.2})"
    );
    assert!(i > 0.6, "interior: most objects behind walls ({i:.2})");
    assert!(f < 0.2, "field: little occlusion ({f:.2})");
}

#[test]
fn camera_paths_are_replayable_with_turns_and_cuts() {
    for kind in ProceduralKind::ALL {
        let s = gen(kind, 5_000, 2);
        let path = s.camera_path();
        assert!(path.len() >= 100, "{kind}: {} frames", path.len());
        let frames: Vec<_> = path.frames(16.0 / 9.0).collect();
        assert_eq!(frames.len(), path.len());
        assert!(frames.iter().skip(1).any(|f| f.cut), "{kind}: a cut");
        let b = s.bounds();
        let mut max_turn_deg = 0.0f32;
        for f in &frames {
            assert!(
                f.current.view_projection.is_finite() && f.reproject.is_finite(),
                "{kind}"
            );
            // The eye stays over the world (with a margin for approach shots).
            let e = f.camera.eye;
            let margin = 0.25 * (b.max - b.min).length();
            assert!(
                e.x > b.min.x - margin && e.x < b.max.x + margin,
                "{kind}: frame {} eye {e}",
                f.index
            );
            assert!(
                e.z > b.min.z - margin && e.z < b.max.z + margin,
                "{kind}: frame {} eye {e}",
                f.index
            );
            if f.index > 0 && !f.cut {
                let prev = path.camera(f.index - 1).unwrap().forward();
                max_turn_deg =
                    max_turn_deg.max(prev.angle_between(f.camera.forward()).to_degrees());
            }
        }
        println!(
            "{kind}: {} frames, fastest turn {max_turn_deg:.1} deg/frame",
            path.len()
        );
        if kind == ProceduralKind::City || kind == ProceduralKind::Interior {
            assert!(max_turn_deg > 5.0, "{kind}: a fast turn");
        }
    }
}

#[test]
fn city_street_camera_never_starts_inside_a_building() {
    let s = gen(ProceduralKind::City, 10_000, 5);
    let path = s.camera_path();
    let first_cut = (1..path.len()).find(|&i| path.keys()[i].cut).unwrap();
    for i in 0..first_cut {
        let eye = path.camera(i).unwrap().eye;
        assert!((eye.y - 1.7).abs() < 1e-9, "street level");
        for inst in s.instances() {
            let b = inst.bounds.aabb();
            if inst.bounds.half_extents.y > 5.0 {
                assert!(!b.contains(eye), "frame {i}: eye {eye} inside a building");
            }
        }
    }
}

#[test]
fn glb_export_round_trips_through_the_loader() {
    for kind in ProceduralKind::ALL {
        let s = gen(kind, 400, 9);
        let bytes = export::to_glb(&s);
        let back = load_gltf_bytes(&bytes, "export.glb", &NoResources, &Limits::default()).unwrap();
        let (a, b) = (s.info(), back.info());
        assert_eq!(a.instances, b.instances, "{kind}");
        assert_eq!(a.triangles, b.triangles, "{kind}");
        assert_eq!(a.meshes, b.meshes, "{kind}");
        assert_eq!(a.materials, b.materials, "{kind}");
        assert_eq!(a.instances_by_class, b.instances_by_class, "{kind}");
        for k in 0..3 {
            assert!((a.bounds.min[k] - b.bounds.min[k]).abs() < 1e-3, "{kind}");
            assert!((a.bounds.max[k] - b.bounds.max[k]).abs() < 1e-3, "{kind}");
        }
        let c = back.gltf_counts().unwrap();
        assert_eq!(c.nodes as u64, a.instances);
    }
}

#[test]
fn specs_and_the_default_scene() {
    let d = default_scene().unwrap();
    assert_eq!(d.name(), "city");
    assert_eq!(d.instances().len(), tilegraph_scene::DEFAULT_SCENE.size);
    assert_eq!(load("default").unwrap().instances(), d.instances());
    let a = load("forest:800:4").unwrap();
    assert_eq!(
        a.instances(),
        gen(ProceduralKind::Forest, 800, 4).instances()
    );
    let info_json = serde_json::to_value(a.info()).unwrap();
    assert_eq!(info_json["source"]["kind"], "procedural");
    assert!(
        info_json.get("nodes").is_none(),
        "no glTF counts for procedural scenes"
    );
    let shown = a.info().to_string();
    assert!(
        shown.contains("800") && shown.contains("alpha-tested"),
        "{shown}"
    );
}

#[test]
fn gpu_records_match_instances() {
    let s = gen(ProceduralKind::Interior, 70_000, 1);
    let eye = DVec3::new(3.0, 1.6, -2.0);
    let recs = s.gpu_instances(eye);
    assert_eq!(recs.len(), s.instances().len());
    let split = tilegraph_scene::SplitPoint::new(eye);
    let world = s.gpu_records();
    assert!(world
        .iter()
        .zip(&recs)
        .all(|(w, r)| w.relative(&split) == *r));
    let (meshes, materials) = (s.gpu_meshes(), s.gpu_materials());
    for (r, i) in recs.iter().zip(s.instances()) {
        assert_eq!(r.mesh, i.mesh.0);
        // Material and class through the mesh and material tables, as the shaders read them.
        let m = s.instance_material(i).unwrap();
        let gm = meshes[r.mesh as usize].material as usize;
        assert_eq!(materials[gm].class, m.class.gpu_code());
        let p = Vec3::new(0.3, 0.7, -0.2);
        let expect = (i.transform.transform_point(p) - eye).as_vec3();
        assert!((r.model_matrix().transform_point3(p) - expect).length() < 1e-4);
        assert!((Vec3::from_array(r.center) - (i.bounds.center - eye).as_vec3()).length() < 1e-4);
        // The record grows the bounds by a few ulps of its camera-relative magnitudes.
        let t = r.model_matrix().w_axis.truncate();
        let slack = 1e-6 * (t.length() + Vec3::from_array(r.center).length() + 1.0);
        assert!(r.radius >= i.bounds.radius && r.radius - i.bounds.radius < slack);
        let h = Vec3::from_array(r.half_extents);
        assert!(h.cmpge(i.bounds.half_extents).all());
        assert!((h - i.bounds.half_extents).max_element() < slack);
    }
}

/// The maze holds what breaks culling below the instance — triangles of zero area, needles
/// whose apex lies 1e-6 of their length off the base, millimetre wires — behind walls that hide
/// most of it, and keeps all of it when baked into one mesh per material.
#[test]
fn the_maze_holds_degenerate_and_thin_triangles_behind_walls() {
    let s = gen(ProceduralKind::Maze, 6_000, 4);
    let degenerate = s.degenerate_triangles();
    let (zero, needles) = (degenerate.zero_area, degenerate.slivers);
    let mut thin = 0;
    for m in s.meshes() {
        let first = m.first_index as usize;
        for t in s.indices()[first..first + m.index_count as usize].chunks_exact(3) {
            let p = |k: usize| {
                Vec3::from_array(s.vertices()[m.vertex_offset as usize + t[k] as usize].position)
            };
            let (a, b, c) = (p(0), p(1), p(2));
            let area = 0.5 * (b - a).cross(c - a).length();
            let longest = (b - a).length().max((c - b).length()).max((a - c).length());
            // Thin but not degenerate: wires, edge-on cards.
            let shape = area / (longest * longest);
            if (1e-5..1e-3).contains(&shape) {
                thin += 1;
            }
        }
    }
    assert!(
        zero >= 2 && needles >= 1 && thin >= 2,
        "{zero} {needles} {thin}"
    );
    // Each clutter mesh is placed.
    let used: HashSet<u32> = s.instances().iter().map(|i| i.mesh.0).collect();
    assert_eq!(used.len(), s.meshes().len(), "every mesh instanced");
    let (hidden, total) = hidden_share(&s, 40.0);
    println!("maze: {hidden:.2} of {total} hidden from the first camera");
    assert!(
        total > 100 && hidden > 0.5,
        "maze: most clutter behind walls ({hidden:.2})"
    );
    let one = s.one_mesh_per_material().unwrap();
    assert_eq!(one.triangles_drawn(), s.triangles_drawn());
    assert!(one.instances().len() <= s.materials().len());
}
