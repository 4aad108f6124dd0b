//! A scene changed by handle: instances added, removed, moved, hidden, mirrored and turned
//! back; meshes added and removed. Every change is checked against a plain model of the scene, and a mirror that
//! follows the scene's journal (as a renderer's upload does) must end up holding exactly what a
//! full upload would.

use std::collections::HashMap;

use glam::{DVec3, Mat3, Vec3};
use proptest::prelude::*;
use tilegraph_scene::{
    Aabb, Change, GpuInstance, GpuMaterial, GpuMesh, InstanceFlags, InstanceHandle, Material,
    MaterialClass, MaterialId, MeshHandle, Overlap, Scene, SceneBuilder, SceneCursor, SceneError,
    Transform, Vertex, DRAW_LISTS,
};

fn quad(size: f32) -> (Vec<Vertex>, Vec<u32>) {
    let v = |x: f32, z: f32| Vertex {
        position: [x * size, 0.0, z * size],
        normal: [0.0, 1.0, 0.0],
        uv: [x, z],
    };
    (
        vec![v(0.0, 0.0), v(1.0, 0.0), v(1.0, 1.0), v(0.0, 1.0)],
        vec![0, 1, 2, 0, 2, 3],
    )
}

/// A small built scene: three materials (opaque, alpha-tested double-sided, blended), a mesh
/// of each, 12 instances.
fn base() -> Scene {
    let mut b = SceneBuilder::new("dynamic");
    let opaque = b.add_material(Material::opaque([1.0, 0.0, 0.0, 1.0]));
    let leaves = b.add_material(Material {
        base_color: [0.0, 1.0, 0.0, 1.0],
        class: MaterialClass::AlphaTested { cutoff: 0.5 },
        double_sided: true,
        base_color_texture: None,
        engine_material: None,
    });
    let glass = b.add_material(Material {
        base_color: [0.0, 0.0, 1.0, 0.5],
        class: MaterialClass::Blended,
        double_sided: false,
        base_color_texture: None,
        engine_material: None,
    });
    let (v, i) = quad(1.0);
    let meshes: Vec<_> = [opaque, leaves, glass]
        .into_iter()
        .map(|m| b.add_mesh(&v, &i, m).expect("a valid mesh"))
        .collect();
    for k in 0..12u32 {
        let t = Transform::from_translation(DVec3::new(f64::from(k) * 3.0, 0.0, 0.0));
        b.add_instance(t, meshes[k as usize % 3])
            .expect("a valid instance");
    }
    b.build(None).expect("a scene")
}

/// What a renderer mirrors, kept up to date from the journal.
#[derive(Default)]
struct Mirror {
    cursor: Option<SceneCursor>,
    records: Vec<GpuInstance>,
    order: Vec<u32>,
    entries: Vec<u32>,
    meshes: Vec<GpuMesh>,
    materials: Vec<GpuMaterial>,
    vertices: Vec<Vertex>,
    indices: Vec<u32>,
    full_uploads: usize,
}

impl Mirror {
    fn sync(&mut self, s: &Scene) {
        let slots = s.instances().len();
        self.records.resize(slots, GpuInstance::default());
        self.order.resize(slots, u32::MAX);
        let stride = s.buckets().stride() as usize;
        self.entries.resize(DRAW_LISTS * stride, u32::MAX);
        self.meshes.resize(s.meshes().len(), GpuMesh::default());
        self.materials
            .resize(s.materials().len(), GpuMaterial::default());
        self.vertices.resize(s.vertices().len(), Vertex::default());
        self.indices.resize(s.indices().len(), 0);
        let changes = self.cursor.and_then(|c| s.changes_since(c));
        let all = changes.is_none_or(|l| {
            l.iter()
                .any(|c| matches!(c, Change::Layout | Change::Everything))
        });
        if all {
            self.full_uploads += 1;
            self.records = s.gpu_records();
            for i in 0..slots as u32 {
                self.order[i as usize] = s.buckets().entry(i).unwrap_or(u32::MAX);
            }
            for e in 0..self.entries.len() as u32 {
                self.entries[e as usize] = s.buckets().instance_at(e).unwrap_or(u32::MAX);
            }
            self.meshes = s.gpu_meshes();
            self.materials = s.gpu_materials();
            self.vertices = s.vertices().to_vec();
            self.indices = s.indices().to_vec();
        } else if let Some(list) = changes {
            for &c in list {
                match c {
                    Change::Moved(i) => {
                        self.records[i as usize] = s.instances()[i as usize].gpu_record();
                    }
                    Change::Instance(i) => {
                        self.records[i as usize] = s.instances()[i as usize].gpu_record();
                        self.order[i as usize] = s.buckets().entry(i).unwrap_or(u32::MAX);
                    }
                    Change::Entry(e) => {
                        self.entries[e as usize] = s.buckets().instance_at(e).unwrap_or(u32::MAX)
                    }
                    Change::Mesh(m) => self.meshes[m as usize] = s.meshes()[m as usize].gpu(),
                    Change::Material(m) => {
                        self.materials[m as usize] = s.materials()[m as usize].gpu()
                    }
                    Change::Vertices { start, len } => {
                        let r = start as usize..(start + len) as usize;
                        self.vertices[r.clone()].copy_from_slice(&s.vertices()[r]);
                    }
                    Change::Indices { start, len } => {
                        let r = start as usize..(start + len) as usize;
                        self.indices[r.clone()].copy_from_slice(&s.indices()[r]);
                    }
                    Change::Layout | Change::Everything => {}
                }
            }
        }
        self.cursor = Some(s.cursor());
    }

    /// What a full upload holds, where the GPU reads it: every record and entry of an
    /// instance, every bucket member's list entry, every table, every live mesh's geometry.
    fn check(&self, s: &Scene) {
        assert_eq!(self.records, s.gpu_records());
        for i in 0..s.instances().len() as u32 {
            assert_eq!(
                self.order[i as usize],
                s.buckets().entry(i).unwrap_or(u32::MAX),
                "instance {i}"
            );
        }
        for g in s.buckets().groups() {
            for (k, &m) in s.buckets().members(&g).iter().enumerate() {
                let e = (g.list * s.buckets().stride() + g.position) as usize + k;
                assert_eq!(self.entries[e], m, "entry {e}");
            }
        }
        assert_eq!(self.meshes, s.gpu_meshes());
        assert_eq!(self.materials, s.gpu_materials());
        for m in s.meshes().iter().filter(|m| m.index_count > 0) {
            let ix = m.first_index as usize..(m.first_index + m.index_count) as usize;
            assert_eq!(self.indices[ix.clone()], s.indices()[ix]);
            let vx = m.vertex_offset as usize..m.vertex_offset as usize + m.vertex_count as usize;
            assert_eq!(self.vertices[vx.clone()], s.vertices()[vx]);
        }
    }
}

/// The model: what the scene should hold (per instance: the mesh it was given, its flags,
/// and whether its transform mirrors).
struct Model {
    instances: HashMap<InstanceHandle, (MeshHandle, InstanceFlags, bool)>,
    meshes: Vec<(MeshHandle, MaterialId)>,
    removed: Vec<InstanceHandle>,
}

impl Model {
    fn of(s: &Scene) -> Self {
        let mut instances = HashMap::new();
        for (i, inst) in s.instances().iter().enumerate() {
            let h = s
                .instance_handle(tilegraph_scene::InstanceId(i as u32))
                .expect("built instances are live");
            let mesh = s.mesh_handle(inst.mesh).expect("its mesh is live");
            instances.insert(h, (mesh, inst.flags, false));
        }
        let meshes = (0..s.meshes().len() as u32)
            .filter_map(|m| {
                let id = tilegraph_scene::MeshId(m);
                Some((s.mesh_handle(id)?, s.mesh(id)?.material))
            })
            .collect();
        Model {
            instances,
            meshes,
            removed: Vec::new(),
        }
    }

    /// Buckets hold the drawn opaque and alpha-tested instances (in their mesh's list), the
    /// grids the drawn ones of each kind.
    fn check(&self, s: &Scene) {
        let mut in_buckets = HashMap::new();
        for g in s.buckets().groups() {
            for &m in s.buckets().members(&g) {
                assert!(in_buckets.insert(m, (g.list, g.mesh)).is_none());
            }
        }
        // The blended grid holds the drawn blended instances, with their meshes and bounds.
        let mut in_grids: HashMap<u32, bool> = HashMap::new();
        s.blended_grid().visit(
            |_| Overlap::Inside,
            |m, _| {
                let inst = &s.instances()[m.instance as usize];
                assert_eq!(m.mesh, inst.mesh.0, "instance {}", m.instance);
                assert_eq!(m.center, inst.bounds.center, "instance {}", m.instance);
                assert!(in_grids.insert(m.instance, true).is_none());
            },
        );
        let mut drawn = 0;
        for (&h, &(mesh, flags, mirrored)) in &self.instances {
            let inst = s.instance(h).expect("a live handle");
            assert_eq!(inst.transform.linear.determinant() < 0.0, mirrored);
            if mirrored {
                // Its mesh's copy with every triangle turned: same vertices and material.
                let (given, drawn) = (
                    s.mesh(mesh.id()).expect("mesh"),
                    s.mesh(inst.mesh).expect("copy"),
                );
                assert_ne!(inst.mesh, mesh.id());
                assert_eq!(
                    (drawn.vertex_offset, drawn.material),
                    (given.vertex_offset, given.material)
                );
                let of = |m: &tilegraph_scene::Mesh| {
                    s.indices()[m.first_index as usize..(m.first_index + m.index_count) as usize]
                        .to_vec()
                };
                let turned: Vec<u32> = of(given)
                    .chunks(3)
                    .flat_map(|t| [t[0], t[2], t[1]])
                    .collect();
                assert_eq!(of(drawn), turned);
            } else {
                assert_eq!(inst.mesh, mesh.id());
            }
            assert_eq!(inst.flags, flags);
            let material = s.material(s.mesh(inst.mesh).expect("mesh").material);
            let material = material.expect("material");
            let slot = h.id().0;
            if !flags.is_drawn() {
                assert!(!in_buckets.contains_key(&slot) && !in_grids.contains_key(&slot));
                continue;
            }
            drawn += 1;
            let blended = material.class == MaterialClass::Blended;
            assert_eq!(in_grids.contains_key(&slot), blended, "instance {slot}");
            if blended {
                assert!(!in_buckets.contains_key(&slot));
            } else {
                let class = u32::from(matches!(material.class, MaterialClass::AlphaTested { .. }));
                let list = class * 2 + u32::from(material.double_sided);
                assert_eq!(in_buckets.get(&slot), Some(&(list, inst.mesh.0)));
            }
        }
        assert!(in_grids.len() <= drawn);
        assert_eq!(s.live_instances(), self.instances.len());
        for h in &self.removed {
            assert!(matches!(
                s.instance(*h),
                Err(SceneError::StaleHandle { .. })
            ));
        }
    }
}

#[derive(Debug, Clone)]
enum Op {
    Add {
        mesh: usize,
        x: f64,
        mirrored: bool,
    },
    Remove(usize),
    Move {
        picks: Vec<usize>,
        dx: f64,
        flip: bool,
    },
    Hide(usize, bool),
    AddMesh {
        material: u32,
        size: f32,
    },
    RemoveMesh(usize),
    Sync,
}

fn op() -> impl Strategy<Value = Op> {
    prop_oneof![
        4 => (0usize..8, -50.0f64..50.0, proptest::bool::weighted(0.25))
            .prop_map(|(mesh, x, mirrored)| Op::Add { mesh, x, mirrored }),
        3 => any::<usize>().prop_map(Op::Remove),
        3 => (proptest::collection::vec(any::<usize>(), 1..6), -5.0f64..5.0, proptest::bool::weighted(0.2))
            .prop_map(|(picks, dx, flip)| Op::Move { picks, dx, flip }),
        2 => (any::<usize>(), any::<bool>()).prop_map(|(i, h)| Op::Hide(i, h)),
        1 => (0u32..3, 0.5f32..4.0).prop_map(|(material, size)| Op::AddMesh { material, size }),
        1 => any::<usize>().prop_map(Op::RemoveMesh),
        2 => Just(Op::Sync),
    ]
}

fn sorted_handles(m: &Model) -> Vec<InstanceHandle> {
    let mut v: Vec<_> = m.instances.keys().copied().collect();
    v.sort_unstable();
    v
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn a_mirror_following_the_journal_holds_what_a_full_upload_holds(
        ops in proptest::collection::vec(op(), 1..120),
    ) {
        let mut s = base();
        let mut model = Model::of(&s);
        let mut mirror = Mirror::default();
        mirror.sync(&s);
        for op in ops {
            match op {
                Op::Add { mesh, x, mirrored } => {
                    let (m, _) = model.meshes[mesh % model.meshes.len()];
                    let scale = Vec3::new(if mirrored { -1.0 } else { 1.0 }, 1.0, 1.0);
                    let linear = Mat3::from_rotation_y(x as f32) * Mat3::from_diagonal(scale);
                    let t = Transform::new(linear, DVec3::new(x, 1.0, -x));
                    let h = s.add_instance(m, t, InstanceFlags::default()).expect("add");
                    model.instances.insert(h, (m, InstanceFlags::default(), mirrored));
                }
                Op::Remove(k) => {
                    let hs = sorted_handles(&model);
                    if let Some(&h) = hs.get(k % hs.len().max(1)) {
                        s.remove_instance(h).expect("remove");
                        model.instances.remove(&h);
                        model.removed.push(h);
                    }
                }
                Op::Move { picks, dx, flip } => {
                    let hs = sorted_handles(&model);
                    if hs.is_empty() {
                        continue;
                    }
                    let moves: Vec<_> = picks
                        .iter()
                        .map(|&k| {
                            let h = hs[k % hs.len()];
                            let mut t = s.instance(h).expect("live").transform;
                            t.translation.x += dx;
                            if flip {
                                t.linear *= Mat3::from_diagonal(Vec3::new(1.0, 1.0, -1.0));
                            }
                            (h, t)
                        })
                        .collect();
                    s.set_transforms(&moves).expect("move");
                    for (h, t) in &moves {
                        if let Some(e) = model.instances.get_mut(h) {
                            e.2 = t.linear.determinant() < 0.0;
                        }
                    }
                }
                Op::Hide(k, hidden) => {
                    let hs = sorted_handles(&model);
                    if let Some(&h) = hs.get(k % hs.len().max(1)) {
                        let flags = if hidden { InstanceFlags::HIDDEN } else { InstanceFlags::CASTS_SHADOWS };
                        s.set_flags(h, flags).expect("flags");
                        if let Some(e) = model.instances.get_mut(&h) {
                            e.1 = flags;
                        }
                    }
                }
                Op::AddMesh { material, size } => {
                    let (v, i) = quad(size);
                    let h = s.add_mesh(&v, &i, MaterialId(material)).expect("mesh");
                    model.meshes.push((h, MaterialId(material)));
                }
                Op::RemoveMesh(k) => {
                    let (h, _) = model.meshes[k % model.meshes.len()];
                    let users = model.instances.values().filter(|(m, _, _)| *m == h).count();
                    match s.remove_mesh(h) {
                        Ok(()) => {
                            prop_assert_eq!(users, 0);
                            model.meshes.retain(|(m, _)| *m != h);
                            if model.meshes.is_empty() {
                                let (v, i) = quad(1.0);
                                let h = s.add_mesh(&v, &i, MaterialId(0)).expect("mesh");
                                model.meshes.push((h, MaterialId(0)));
                            }
                        }
                        Err(SceneError::MeshInUse { instances, .. }) => {
                            prop_assert_eq!(instances as usize, users);
                        }
                        Err(e) => prop_assert!(false, "{e}"),
                    }
                }
                Op::Sync => {
                    mirror.sync(&s);
                    mirror.check(&s);
                }
            }
            model.check(&s);
        }
        mirror.sync(&s);
        mirror.check(&s);
    }
}

#[test]
fn a_stale_handle_or_a_nan_changes_nothing_and_says_which() {
    let mut s = base();
    let h0 = s
        .instance_handle(tilegraph_scene::InstanceId(0))
        .expect("live");
    let h1 = s
        .instance_handle(tilegraph_scene::InstanceId(1))
        .expect("live");
    let before = s.gpu_records();
    let cursor = s.cursor();
    let good = Transform::from_translation(DVec3::new(5.0, 0.0, 0.0));
    let bad = Transform::from_translation(DVec3::new(f64::NAN, 0.0, 0.0));
    let e = s
        .set_transforms(&[(h0, good), (h1, bad)])
        .expect_err("a NaN is refused");
    let text = e.to_string();
    assert!(
        matches!(e, SceneError::NonFinite { .. })
            && text.contains("/instances/1")
            && text.contains("entry 1"),
        "{text}"
    );
    // Nothing moved, nothing was written to the journal.
    assert_eq!(s.gpu_records(), before);
    assert_eq!(s.changes_since(cursor), Some(&[][..]));
    s.remove_instance(h0).expect("remove");
    let e = s.set_transforms(&[(h0, good)]).expect_err("stale");
    assert!(matches!(e, SceneError::StaleHandle { index: 0, .. }), "{e}");
    // The slot comes back under a new generation; the old handle stays stale.
    let mesh = s.mesh_handle(tilegraph_scene::MeshId(0)).expect("mesh");
    let again = s
        .add_instance(mesh, good, InstanceFlags::default())
        .expect("add");
    assert_eq!(again.id(), h0.id());
    assert_ne!(again, h0);
    assert!(s.instance(h0).is_err());
    assert_eq!(s.instance(again).map(|i| i.transform).ok(), Some(good));
    // Local bounds an engine gives (a skinned mesh's) make the world box.
    let local = Aabb::new(Vec3::splat(-2.0), Vec3::splat(2.0));
    s.set_local_bounds(again, Some(local)).expect("bounds");
    let b = s.instance(again).expect("live").bounds;
    assert!(
        b.half_extents.cmpge(Vec3::splat(2.0)).all()
            && b.half_extents.cmplt(Vec3::splat(2.001)).all()
    );
    let bad_box = Aabb::new(Vec3::splat(1.0), Vec3::splat(f32::INFINITY));
    assert!(s.set_local_bounds(again, Some(bad_box)).is_err());
    assert_eq!(s.instance(again).expect("live").bounds, b);
}

#[test]
fn removed_mesh_geometry_is_reused_and_a_used_mesh_is_refused() {
    let mut s = base();
    let material = MaterialId(0);
    let (v, i) = quad(2.0);
    let m = s.add_mesh(&v, &i, material).expect("mesh");
    let vertices = s.vertices().len();
    let h = s
        .add_instance(m, Transform::IDENTITY, InstanceFlags::default())
        .expect("instance");
    assert!(matches!(
        s.remove_mesh(m),
        Err(SceneError::MeshInUse { instances: 1, .. })
    ));
    s.remove_instance(h).expect("remove");
    s.remove_mesh(m).expect("unused now");
    assert!(s.remove_mesh(m).is_err());
    let again = s.add_mesh(&v, &i, material).expect("mesh");
    // Same size: the freed ranges took it; the arrays did not grow.
    assert_eq!(s.vertices().len(), vertices);
    assert_eq!(again.id(), m.id());
    assert_ne!(again, m);
}

/// The live instances' places, as a sorted list (slots may differ between two histories).
fn places(s: &Scene) -> Vec<[i64; 4]> {
    let mut v: Vec<[i64; 4]> = s
        .instances()
        .iter()
        .filter(|i| i.flags.is_drawn())
        .map(|i| {
            let t = i.transform.translation * 1e4;
            [t.x as i64, t.y as i64, t.z as i64, i64::from(i.mesh.0)]
        })
        .collect();
    v.sort_unstable();
    v
}

#[test]
fn motion_brings_the_scene_to_a_frame_from_any_frame() {
    let city = tilegraph_scene::load("city:2k").expect("city");
    let path = city.camera_path().clone();
    let params = tilegraph_scene::MotionParams::default();
    let mut walked = city.clone();
    let mut motion = tilegraph_scene::Motion::new(&walked, &path, params);
    assert!(
        motion.movers() > 20 && motion.spawns() > 0,
        "{}",
        motion.movers()
    );
    let mut seen = Vec::new();
    for f in 0..path.len() {
        motion.apply(&mut walked, f).expect("apply");
        seen.push(places(&walked));
    }
    // Spawns came and went; movers moved.
    assert!(seen.windows(2).any(|w| w[0].len() != w[1].len()));
    assert_ne!(seen[0], seen[path.len() / 2]);
    // Back to the start, and to a frame in the middle straight from the built scene.
    motion.apply(&mut walked, 0).expect("apply");
    assert_eq!(places(&walked), seen[0]);
    let mut fresh = city.clone();
    let mut other = tilegraph_scene::Motion::new(&fresh, &path, params);
    let mid = path.len() / 2;
    other.apply(&mut fresh, mid).expect("apply");
    assert_eq!(places(&fresh), seen[mid]);
}

/// One cluster per mesh over its whole range, and one level of detail: the mesh's first
/// triangle (after the scene's indices). Enough for the scene to count as clustered.
fn whole_mesh_clusters(s: &Scene) -> tilegraph_scene::clusters::ClusterData {
    use tilegraph_scene::clusters::{GpuCluster, GpuLod, MAX_LODS};
    let clusters: Vec<_> = s
        .meshes()
        .iter()
        .map(|m| GpuCluster {
            first_index: m.first_index,
            index_count: m.index_count,
            cone_cutoff: 1.0,
            ..Default::default()
        })
        .collect();
    let mut indices = s.indices().to_vec();
    let mut lods = vec![GpuLod::default(); s.meshes().len() * MAX_LODS];
    for (k, m) in s
        .meshes()
        .iter()
        .enumerate()
        .filter(|(_, m)| m.index_count > 0)
    {
        let first = m.first_index as usize;
        lods[k * MAX_LODS] = GpuLod {
            first_index: indices.len() as u32,
            index_count: 3,
            error: 1.0,
            _pad: 0,
        };
        indices.extend_from_slice(&s.indices()[first..first + 3]);
    }
    tilegraph_scene::clusters::ClusterData {
        fingerprint: s.geometry_fingerprint(),
        indices,
        mesh_clusters: (0..clusters.len() as u32).map(|k| [k, 1]).collect(),
        clusters,
        lods,
    }
}

/// A mirroring transform (negative determinant) draws its mesh's copy with every triangle
/// turned, one copy shared by all mirroring instances of the mesh, whichever way the instance
/// got its transform; turning back draws the mesh again. With clusters attached, the copy
/// gets the mesh's clusters over its own indices, each cone made for the turned triangles.
#[test]
fn mirroring_instances_draw_their_mesh_turned() {
    use tilegraph_scene::MeshId;
    let mut b = SceneBuilder::new("mirrors");
    let material = b.add_material(Material::opaque([1.0, 1.0, 1.0, 1.0]));
    let (v, i) = quad(1.0);
    let plain = b.add_mesh(&v, &i, material).expect("mesh");
    let flip = Mat3::from_diagonal(Vec3::new(-1.0, 1.0, 1.0));
    let at = |x: f64| DVec3::new(x, 0.0, 0.0);
    b.add_instance(Transform::from_translation(at(0.0)), plain)
        .expect("plain");
    b.add_instance(Transform::new(flip, at(3.0)), plain)
        .expect("mirroring");
    b.add_instance(Transform::new(flip * 2.0, at(6.0)), plain)
        .expect("mirroring, larger");
    let mut s = b.build(None).expect("scene");
    assert_eq!(s.meshes().len(), 2, "one copy for both mirroring instances");
    let copy = MeshId(1);
    let drawn: Vec<MeshId> = s.instances().iter().map(|i| i.mesh).collect();
    assert_eq!(drawn, [plain, copy, copy]);
    let of = |s: &Scene, m: MeshId| {
        let m = s.mesh(m).expect("mesh");
        s.indices()[m.first_index as usize..(m.first_index + m.index_count) as usize].to_vec()
    };
    assert_eq!(of(&s, copy), [0, 2, 1, 0, 3, 2]);
    assert_eq!(s.mesh(copy).expect("copy").vertex_offset, 0);

    // At run time: a mesh mirrored first by a move, and back.
    let other = s.add_mesh(&v, &i, material).expect("mesh");
    let prepared = s.add_mesh(&v, &i, material).expect("mesh");
    let h = s
        .add_instance(
            other,
            Transform::from_translation(at(9.0)),
            InstanceFlags::default(),
        )
        .expect("plain");
    let plain_h = s.mesh_handle(plain).expect("live");
    let g = s
        .add_instance(
            plain_h,
            Transform::new(flip, at(12.0)),
            InstanceFlags::default(),
        )
        .expect("mirroring");
    assert_eq!(
        s.instance(g).expect("live").mesh,
        copy,
        "the builder's copy"
    );
    s.set_transforms(&[(h, Transform::new(flip, at(9.0)))])
        .expect("turned mirroring");
    let turned = s.instance(h).expect("live").mesh;
    assert_ne!(turned, other.id());
    assert_eq!(of(&s, turned), [0, 2, 1, 0, 3, 2]);
    s.set_transforms(&[(h, Transform::from_translation(at(9.5)))])
        .expect("turned back");
    assert_eq!(s.instance(h).expect("live").mesh, other.id());
    // Removing a mesh counts its copy's instances, and takes the copy with it.
    s.remove_instance(h).expect("remove");
    let e = s
        .remove_mesh(plain_h)
        .expect_err("in use by its copy's instances");
    assert!(
        matches!(e, SceneError::MeshInUse { instances: 4, .. }),
        "{e}"
    );
    s.remove_mesh(other)
        .expect("no instance draws it or its copy");
    assert!(s.mesh_handle(turned).is_none(), "the copy went with it");

    // Clusters attached: a copy made before, or made now with the mesh's clusters turned.
    s.prepare_mirroring(prepared).expect("made now");
    let lone = s.add_mesh(&v, &i, material).expect("mesh");
    s.attach_clusters(whole_mesh_clusters(&s))
        .expect("clusters");
    let mirroring = Transform::new(flip, at(15.0));
    let p = s
        .add_instance(prepared, mirroring, InstanceFlags::default())
        .expect("its copy exists");
    assert_ne!(s.instance(p).expect("live").mesh, prepared.id());
    let q = s
        .add_instance(
            lone,
            Transform::from_translation(at(18.0)),
            InstanceFlags::default(),
        )
        .expect("plain");
    let indices_before = s.indices().len();
    s.set_transforms(&[(g, Transform::from_translation(at(1.0))), (q, mirroring)])
        .expect("both turned");
    assert_eq!(s.instance(g).expect("live").mesh, plain);
    let copy = s.instance(q).expect("live").mesh;
    assert_ne!(copy, lone.id());
    let clusters = s.clusters().expect("attached");
    let (c, m) = (clusters.of_mesh(copy.0), s.mesh(copy).expect("copy"));
    assert_eq!(c.len(), 1);
    assert_eq!(
        (c[0].first_index, c[0].index_count),
        (m.first_index, m.index_count)
    );
    // The quad's triangles face -y; turned, +y: the copy's cone is made for those.
    assert!(
        c[0].cone_cutoff < 1.0 && c[0].cone_axis[1] > 0.99,
        "{:?}",
        c[0]
    );
    assert_eq!(of(&s, copy), [0, 2, 1, 0, 3, 2]);
    // Its level of detail: the mesh's, turned.
    let (own, turned) = (clusters.lods_of(lone.id().0), clusters.lods_of(copy.0));
    assert_eq!((own.len(), turned.len()), (1, 1));
    assert_eq!((turned[0].index_count, turned[0].error), (3, own[0].error));
    let level = |l: &tilegraph_scene::clusters::GpuLod| {
        s.indices()[l.first_index as usize..(l.first_index + l.index_count) as usize].to_vec()
    };
    assert_eq!(
        (level(&own[0]), level(&turned[0])),
        (vec![0, 1, 2], vec![0, 2, 1])
    );
    // No two ranges of the index array overlap: live meshes and levels of detail, the copies'
    // past the levels the clusters brought.
    let mut ranges: Vec<(u32, u32)> = s
        .meshes()
        .iter()
        .enumerate()
        .filter(|(_, m)| m.index_count > 0)
        .flat_map(|(k, m)| {
            let levels = clusters.lods_of(k as u32).iter();
            std::iter::once((m.first_index, m.index_count))
                .chain(levels.map(|l| (l.first_index, l.index_count)))
        })
        .collect();
    ranges.sort_unstable();
    for w in ranges.windows(2) {
        assert!(w[0].0 + w[0].1 <= w[1].0, "{:?} overlaps {:?}", w[0], w[1]);
    }
    assert!(turned[0].first_index as usize >= indices_before);
}

/// A cluster file whose counts wrap round 2^32 back to a mesh's end is refused: each cluster
/// must follow on from the last inside its mesh.
#[test]
fn clusters_whose_counts_wrap_round_are_refused() {
    use tilegraph_scene::clusters::GpuCluster;
    let s = base();
    let mut data = whole_mesh_clusters(&s);
    let Some(m) = s.meshes().iter().position(|m| m.index_count >= 3) else {
        panic!("the base scene has a mesh with triangles");
    };
    let mesh = s.meshes()[m];
    // Counts of 2^32 - 1 (a multiple of 3) three times, then what brings `at` back to the end.
    let big = u32::MAX;
    let mut at = mesh.first_index;
    let mut wrapped = Vec::new();
    for _ in 0..3 {
        wrapped.push(GpuCluster {
            first_index: at,
            index_count: big,
            cone_cutoff: 1.0,
            ..Default::default()
        });
        at = at.wrapping_add(big);
    }
    let end = mesh.first_index.wrapping_add(mesh.index_count);
    wrapped.push(GpuCluster {
        first_index: at,
        index_count: end.wrapping_sub(at),
        cone_cutoff: 1.0,
        ..Default::default()
    });
    assert_eq!(
        end.wrapping_sub(at) % 3,
        0,
        "the last count is whole triangles"
    );
    let first = data.clusters.len() as u32;
    data.clusters.extend(wrapped);
    data.mesh_clusters[m] = [first, 4];
    let mut s = s;
    let e = s
        .attach_clusters(data)
        .expect_err("counts that wrap round must not tile the mesh");
    assert!(matches!(e, SceneError::Clusters { .. }), "{e}");
    assert!(e.to_string().contains("past the mesh's end"), "{e}");
}

/// Meshes over one vertex range share its vertices (no copy per mesh); their indices are
/// checked against the shared range.
#[test]
fn meshes_sharing_vertices_add_them_once() {
    let mut b = SceneBuilder::new("shared");
    let m = b.add_material(Material::opaque([1.0, 1.0, 1.0, 1.0]));
    let (v, i) = quad(1.0);
    let first = b.add_mesh(&v, &i, m).expect("first mesh");
    let second = b
        .add_mesh_sharing(first, &[2, 1, 0], m)
        .expect("same vertices");
    let e = b
        .add_mesh_sharing(first, &[0, 1, 4], m)
        .expect_err("index 4 is past the 4 shared vertices");
    assert!(
        matches!(e, SceneError::IndexOutOfRange { index: 4, .. }),
        "{e}"
    );
    let e = b
        .add_mesh_sharing(tilegraph_scene::MeshId(9), &[0, 1, 2], m)
        .expect_err("no mesh 9");
    assert!(e.to_string().contains("mesh 9"), "{e}");
    b.add_instance(Transform::IDENTITY, second)
        .expect("instance");
    let s = b.build(None).expect("scene");
    assert_eq!(s.vertices().len(), 4, "the vertices once");
    assert_eq!(s.meshes()[1].vertex_offset, s.meshes()[0].vertex_offset);
    assert_eq!(s.meshes()[1].index_count, 3);
}
