use super::{ClusterLayout, ClusterRoom, CHUNK};
use tilegraph_scene::clusters::{ClusterData, GpuCluster};
use tilegraph_scene::{
    InstanceFlags, InstanceId, Material, MeshId, Scene, SceneBuilder, Transform, Vertex,
};

/// Two opaque meshes: mesh 0 of 130 clusters (three chunks), mesh 1 of one; a blended mesh 2
/// of two. Instances: 0, 1, 0, 2, 1.
fn scene() -> Scene {
    let mut b = SceneBuilder::new("cluster layout");
    let opaque = b.add_material(Material::opaque([1.0; 4]));
    let blended = b.add_material(Material {
        class: tilegraph_scene::MaterialClass::Blended,
        ..Material::opaque([1.0, 1.0, 1.0, 0.5])
    });
    let v = |k: usize| Vertex {
        position: [k as f32, (k % 2) as f32, 0.0],
        normal: [0.0, 0.0, 1.0],
        uv: [0.0, 0.0],
    };
    let strip = |triangles: u32| -> (Vec<Vertex>, Vec<u32>) {
        let vertices = (0..triangles as usize + 2).map(v).collect();
        let indices = (0..triangles).flat_map(|t| [t, t + 1, t + 2]).collect();
        (vertices, indices)
    };
    let mut meshes = Vec::new();
    for (triangles, material) in [(130, opaque), (1, opaque), (2, blended)] {
        let (vertices, indices) = strip(triangles);
        meshes.push(b.add_mesh(&vertices, &indices, material).unwrap());
    }
    for (k, mesh) in [0usize, 1, 0, 2, 1].into_iter().enumerate() {
        let at = glam::DVec3::new(200.0 * k as f64, 0.0, 0.0);
        b.add_instance(Transform::new(glam::Mat3::IDENTITY, at), meshes[mesh])
            .unwrap();
    }
    let mut scene = b.build(None).unwrap();
    // One cluster per triangle.
    let mut clusters = Vec::new();
    let mut mesh_clusters = Vec::new();
    for m in scene.meshes() {
        mesh_clusters.push([clusters.len() as u32, m.index_count / 3]);
        for t in 0..m.index_count / 3 {
            clusters.push(GpuCluster {
                first_index: m.first_index + 3 * t,
                index_count: 3,
                cone_cutoff: 2.0,
                ..GpuCluster::default()
            });
        }
    }
    let data = ClusterData {
        fingerprint: scene.geometry_fingerprint(),
        indices: scene.indices().to_vec(),
        clusters,
        mesh_clusters,
        lods: Vec::new(),
    };
    scene.attach_clusters(data).unwrap();
    scene
}

/// What every layout must be, however it came about: each slot's range holds its mesh's
/// clusters, its chunks cover the range and name it, and each list's capacity is the ranges of
/// its slots.
fn check(layout: &ClusterLayout, scene: &Scene) {
    let clusters = scene.clusters().unwrap();
    assert_eq!(layout.slots() as usize, scene.instances().len());
    assert_eq!(layout.chunk_base.len(), layout.base.len() + 1);
    let mut capacity = [0u32; 4];
    for (i, inst) in scene.instances().iter().enumerate() {
        let range = layout.allocated(i as u32);
        let need = clusters.of_mesh(inst.mesh.0).len() as u32;
        assert!(range >= need, "slot {i}: {range} clusters for {need}");
        let chunks = layout.chunk_base[i]..layout.chunk_base[i + 1];
        assert_eq!(chunks.len() as u32, range.div_ceil(CHUNK), "slot {i}");
        assert!(chunks
            .clone()
            .all(|w| layout.chunk_instance[w as usize] == i as u32));
        let blended = scene
            .instance_material(inst)
            .is_some_and(|m| m.class == tilegraph_scene::MaterialClass::Blended);
        if !blended {
            capacity[0] += range;
        }
    }
    assert_eq!(layout.capacity, capacity);
    assert_eq!(
        layout.chunks() as usize,
        *layout.chunk_base.last().unwrap() as usize
    );
}

/// Follows `scene` from `cursor`.
fn follow(layout: &mut ClusterLayout, scene: &Scene, cursor: tilegraph_scene::SceneCursor) {
    assert!(layout.follow(scene, scene.changes_since(cursor)));
    check(layout, scene);
}

#[test]
fn a_layout_of_every_slot() {
    let scene = scene();
    let layout = ClusterLayout::of(&scene).unwrap();
    check(&layout, &scene);
    assert_eq!(layout.base, [0, 130, 131, 261, 263]);
    assert_eq!(layout.chunk_base, [0, 3, 4, 7, 8, 9]);
    // The blended instance keeps its place and counts into no list.
    assert_eq!(layout.capacity, [262, 0, 0, 0]);
}

#[test]
fn instances_that_go_and_come_back_in_place_keep_every_range() {
    let mut scene = scene();
    let mut layout = ClusterLayout::of(&scene).unwrap();
    let made = layout.clone();
    // A removed instance keeps its slot's range.
    let cursor = scene.cursor();
    let h = scene.instance_handle(InstanceId(2)).unwrap();
    scene.remove_instance(h).unwrap();
    follow(&mut layout, &scene, cursor);
    assert_eq!(layout, made);
    // A small mesh in the freed slot of a large one: in place, the rest of the range idle.
    let cursor = scene.cursor();
    let small = scene.mesh_handle(MeshId(1)).unwrap();
    let t = Transform::new(glam::Mat3::IDENTITY, glam::DVec3::ZERO);
    let added = scene.add_instance(small, t, InstanceFlags::NONE).unwrap();
    assert_eq!(added.id(), InstanceId(2), "the freed slot is taken again");
    follow(&mut layout, &scene, cursor);
    assert_eq!(layout, made);
    // A new slot is appended, in the same epoch.
    let cursor = scene.cursor();
    let large = scene.mesh_handle(MeshId(0)).unwrap();
    scene.add_instance(large, t, InstanceFlags::NONE).unwrap();
    follow(&mut layout, &scene, cursor);
    assert_eq!(layout.epoch, made.epoch);
    assert_eq!(layout.base[..5], made.base[..]);
    assert_eq!(layout.base[5], made.total);
    assert_eq!(layout.capacity[0], made.capacity[0] + 130);
}

#[test]
fn a_slot_that_needs_more_than_its_range_lays_everything_out_anew() {
    let mut scene = scene();
    let mut layout = ClusterLayout::of(&scene).unwrap();
    let cursor = scene.cursor();
    let h = scene.instance_handle(InstanceId(1)).unwrap();
    scene.remove_instance(h).unwrap();
    let large = scene.mesh_handle(MeshId(0)).unwrap();
    let t = Transform::new(glam::Mat3::IDENTITY, glam::DVec3::ZERO);
    scene.add_instance(large, t, InstanceFlags::NONE).unwrap();
    follow(&mut layout, &scene, cursor);
    assert_eq!(layout.epoch, 1);
    assert_eq!(layout.base, [0, 130, 260, 390, 392]);
    // A scene that lost track of its changes: anew too.
    assert!(layout.follow(&scene, None));
    assert_eq!(layout.epoch, 2);
    check(&layout, &scene);
    // Anew, no range shrinks: slot 2 keeps room for the large mesh it held, slot 4 grows.
    let cursor = scene.cursor();
    for slot in [2, 4] {
        let h = scene.instance_handle(InstanceId(slot)).unwrap();
        scene.remove_instance(h).unwrap();
    }
    let small = scene.mesh_handle(MeshId(1)).unwrap();
    scene.add_instance(large, t, InstanceFlags::NONE).unwrap(); // slot 4
    scene.add_instance(small, t, InstanceFlags::NONE).unwrap(); // slot 2
    follow(&mut layout, &scene, cursor);
    assert_eq!(layout.epoch, 3);
    assert_eq!(layout.base, [0, 130, 260, 390, 392]);
    assert_eq!(layout.total, 522);
}

#[test]
fn a_slot_reused_by_another_list_moves_its_range_between_capacities() {
    let mut scene = scene();
    let mut layout = ClusterLayout::of(&scene).unwrap();
    // The blended instance (slot 3, two clusters) goes; an opaque one of one cluster takes
    // its slot: its range of two now counts into the opaque list.
    let cursor = scene.cursor();
    let h = scene.instance_handle(InstanceId(3)).unwrap();
    scene.remove_instance(h).unwrap();
    let small = scene.mesh_handle(MeshId(1)).unwrap();
    let t = Transform::new(glam::Mat3::IDENTITY, glam::DVec3::ZERO);
    scene.add_instance(small, t, InstanceFlags::NONE).unwrap();
    follow(&mut layout, &scene, cursor);
    assert_eq!(layout.epoch, 0);
    assert_eq!(layout.capacity, [264, 0, 0, 0]);
}

/// `words` (room-placed base words) after applying `writes`.
fn apply(words: &mut [u32], writes: [(u32, &[u32]); 3]) {
    for (at, w) in writes {
        words[at as usize..at as usize + w.len()].copy_from_slice(w);
    }
}

#[test]
fn base_words_take_only_what_was_appended_within_an_epoch() {
    let mut scene = scene();
    let mut layout = ClusterLayout::of(&scene).unwrap();
    let room = ClusterRoom::for_layout(&layout, 16);
    let mut words = vec![u32::MAX; (room.base_bytes() / 4) as usize];
    apply(&mut words, room.base_writes(&layout, None));
    let written = Some((layout.epoch, layout.slots(), layout.chunks()));
    let cursor = scene.cursor();
    let small = scene.mesh_handle(MeshId(1)).unwrap();
    let t = Transform::new(glam::Mat3::IDENTITY, glam::DVec3::ZERO);
    scene.add_instance(small, t, InstanceFlags::NONE).unwrap();
    follow(&mut layout, &scene, cursor);
    assert!(room.holds(&layout));
    // The new slot's first cluster, its first chunk (the old end) and the new end, its chunk.
    let writes = room.base_writes(&layout, written);
    assert_eq!(writes.map(|(_, w)| w.len()), [1, 2, 1]);
    apply(&mut words, writes);
    let mut whole = vec![u32::MAX; words.len()];
    apply(&mut whole, room.base_writes(&layout, None));
    assert_eq!(words, whole);
    // Words of another epoch are written whole.
    let stale = Some((layout.epoch + 1, layout.slots(), layout.chunks()));
    assert_eq!(room.base_writes(&layout, stale)[0].1.len(), 6);
}

#[test]
fn a_room_holds_its_layout_and_a_quarter_more() {
    let mut scene = scene();
    let made = ClusterLayout::of(&scene).unwrap();
    let room = ClusterRoom::for_layout(&made, 8);
    assert!(room.holds(&made));
    let t = Transform::new(glam::Mat3::IDENTITY, glam::DVec3::ZERO);
    // One more small instance: within a quarter and 64 more.
    let small = scene.mesh_handle(MeshId(1)).unwrap();
    scene.add_instance(small, t, InstanceFlags::NONE).unwrap();
    assert!(room.holds(&ClusterLayout::of(&scene).unwrap()));
    // A large one does not fit (262 + 1 + 130 clusters against 262 + 65 + 64): new buffers.
    let large = scene.mesh_handle(MeshId(0)).unwrap();
    scene.add_instance(large, t, InstanceFlags::NONE).unwrap();
    assert!(!room.holds(&ClusterLayout::of(&scene).unwrap()));
    // Nor do more instance slots than the base words have room for.
    assert!(!ClusterRoom::for_layout(&made, 5).holds(&ClusterLayout::of(&scene).unwrap()));
    // The commands of each list start after the lists before, both phases alike.
    assert_eq!(room.cmd_base[1], room.capacity[0]);
    assert_eq!(room.cmd_base[4], room.capacity.iter().sum::<u32>());
    assert_eq!(room.commands(), 2 * room.capacity[0]);
    // An empty list stays empty.
    assert_eq!(room.capacity[1..], [0, 0, 0]);
}
