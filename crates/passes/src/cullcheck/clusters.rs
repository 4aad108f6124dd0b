//! The oracle below the instance: which clusters own a pixel, and which the technique drew.
//!
//! The oracle's visibility buffer holds each pixel's instance and triangle (the triangle's
//! index in its mesh's draw, which with clusters attached is in cluster order), so a pixel's
//! cluster is the one whose index range holds that triangle. A cluster technique's colour lists
//! say what it drew: each command one instance's index range, whole clusters. A visible cluster
//! not drawn is a false negative like a visible instance not drawn — on a level built as one
//! mesh, the only kind there is.

use serde::Serialize;
use tilegraph_scene::Scene;
use tilegraph_vk::Context;

use crate::cull::LISTS_PER_PHASE;
use crate::options::RenderError;
use crate::renderer::SceneRenderer;

use crate::cull::IndirectDraw;

use super::stray::OracleFrame;

/// One frame's clusters: visible (owning a pixel in the oracle), drawn by the technique, and the
/// differences, counted as (instance, cluster) pairs of the compared instances.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct ClusterCheck {
    pub visible: usize,
    pub drawn: usize,
    pub false_negatives: usize,
    pub false_positives: usize,
    /// Clusters the technique culled whose every pixel in the oracle is stray (a fragment at a
    /// depth its triangle never reaches: `stray.rs`), counted neither visible nor false
    /// negative.
    pub stray_only: usize,
}

use crate::draws::cluster_key as key;

/// The clusters of `scene` (global indices) whose index ranges overlap `first..first + count`
/// of mesh `mesh` (its clusters tile its range in order).
fn clusters_in(scene: &Scene, mesh: u32, first: u32, count: u32) -> std::ops::Range<u32> {
    let Some(c) = scene.clusters() else {
        return 0..0;
    };
    let Some(&[base, _]) = c.mesh_clusters.get(mesh as usize) else {
        return 0..0;
    };
    let own = c.of_mesh(mesh);
    let end = first.saturating_add(count);
    // The first cluster ending after `first`, up to the first starting at or after `end`.
    let lo = own.partition_point(|cl| cl.first_index + cl.index_count <= first);
    let hi = own.partition_point(|cl| cl.first_index < end);
    base + lo as u32..base + hi.max(lo) as u32
}

/// The clusters owning the oracle's pixels (`owners`: instance per pixel, `u32::MAX` for none;
/// `triangles`: the triangle of its mesh per pixel), as sorted (instance, cluster) keys
/// ([`crate::draws::cluster_key`]) of the compared instances (`compare[i]`: instance `i` is in
/// the comparison: drawn, not blended). `None` when the scene has no clusters.
pub fn visible_clusters(
    scene: &Scene,
    owners: &[u32],
    triangles: &[u32],
    compare: &[bool],
) -> Option<Vec<u64>> {
    scene.clusters()?;
    let mut visible: Vec<u64> = owners
        .iter()
        .zip(triangles)
        .filter_map(|(&i, &t)| pixel_cluster(scene, compare, i, t))
        .collect();
    visible.sort_unstable();
    visible.dedup();
    Some(visible)
}

/// The (instance, cluster) key of a pixel owned by instance `i`'s triangle `t`, if `i` is
/// compared and the triangle lies in a cluster.
fn pixel_cluster(scene: &Scene, compare: &[bool], i: u32, t: u32) -> Option<u64> {
    if !compare.get(i as usize).copied().unwrap_or(false) {
        return None;
    }
    let mesh_id = scene.instances().get(i as usize)?.mesh;
    let mesh = scene.mesh(mesh_id)?;
    let index = mesh.first_index.checked_add(t.checked_mul(3)?)?;
    let c = clusters_in(scene, mesh_id.0, index, 1);
    (!c.is_empty()).then(|| key(i, c.start))
}

/// A cluster technique's frame below the instance.
pub(super) struct Below {
    /// The triangles its colour lists drew.
    pub triangles: u64,
    /// Its clusters against the oracle's (`None`: the oracle has no triangle ids, or
    /// per-triangle culling packed the commands' triangles, whose ranges then name no cluster:
    /// the frame's images carry its exactness).
    pub check: Option<ClusterCheck>,
    /// The oracle's visible clusters ([`visible_clusters`]), for the ideal frame.
    pub visible: Option<Vec<u64>>,
}

/// Reads back what the cluster technique `tested` drew in its last frame and compares it with
/// the oracle's pixels (`owners`: instance and triangle per pixel).
pub(super) fn of_technique(
    ctx: &Context,
    tested: &mut SceneRenderer,
    scene: &Scene,
    owners: (&[u32], Option<&[u32]>),
    compare: &[bool],
    stray: Option<&OracleFrame<'_>>,
) -> Result<Below, RenderError> {
    let lists = tested.gpu_lists(ctx)?.ok_or(RenderError::MissingReadback {
        what: "the cluster technique's GPU lists",
    })?;
    let colour: Vec<_> = lists
        .lists
        .iter()
        .take(LISTS_PER_PHASE as usize)
        .flatten()
        .collect();
    let (ids, triangles) = owners;
    let mut visible = triangles.and_then(|t| visible_clusters(scene, ids, t, compare));
    let packed = tested.options().triangle_culling;
    let check = match (visible.as_mut(), triangles) {
        (Some(v), Some(t)) if !packed => {
            let drawn = drawn_clusters(scene, compare, &colour);
            // Culled clusters seen only through stray pixels are not visible.
            let only_stray = stray.map_or_else(Vec::new, |s| {
                let culled: Vec<u64> = v
                    .iter()
                    .filter(|k| drawn.binary_search(k).is_err())
                    .copied()
                    .collect();
                let key_of = |p: usize| pixel_cluster(scene, compare, *ids.get(p)?, *t.get(p)?);
                s.only_stray(&culled, key_of)
            });
            v.retain(|k| only_stray.binary_search(k).is_err());
            Some(ClusterCheck {
                stray_only: only_stray.len(),
                ..compared(v, &drawn)
            })
        }
        _ => None,
    };
    Ok(Below {
        triangles: lists.colour_triangles(),
        check,
        visible,
    })
}

/// Compares the visible clusters ([`visible_clusters`]) with the colour commands a cluster
/// technique drew.
pub fn cluster_check(
    scene: &Scene,
    visible: &[u64],
    compare: &[bool],
    colour: &[&IndirectDraw],
) -> ClusterCheck {
    compared(visible, &drawn_clusters(scene, compare, colour))
}

/// The clusters of compared instances that `colour`'s commands drew, as sorted keys.
fn drawn_clusters(scene: &Scene, compare: &[bool], colour: &[&IndirectDraw]) -> Vec<u64> {
    let mesh_of = |i: u32| scene.instances().get(i as usize).map(|inst| inst.mesh);
    let compared = |i: u32| compare.get(i as usize).copied().unwrap_or(false);
    let mut drawn: Vec<u64> = colour
        .iter()
        .flat_map(|d| d.instances.iter().map(move |&i| (i, *d)))
        .filter(|(i, _)| compared(*i))
        .filter_map(|(i, d)| {
            let mesh = mesh_of(i)?;
            Some(clusters_in(scene, mesh.0, d.first_index, d.index_count).map(move |c| key(i, c)))
        })
        .flatten()
        .collect();
    drawn.sort_unstable();
    drawn.dedup();
    drawn
}

/// Visible against drawn clusters (both sorted keys).
fn compared(visible: &[u64], drawn: &[u64]) -> ClusterCheck {
    let in_drawn = |k: &u64| drawn.binary_search(k).is_ok();
    let in_visible = |k: &u64| visible.binary_search(k).is_ok();
    ClusterCheck {
        visible: visible.len(),
        drawn: drawn.len(),
        false_negatives: visible.iter().filter(|k| !in_drawn(k)).count(),
        false_positives: drawn.iter().filter(|k| !in_visible(k)).count(),
        stray_only: 0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use tilegraph_scene::clusters::{ClusterData, GpuCluster};
    use tilegraph_scene::{Material, SceneBuilder, Transform, Vertex};

    /// One mesh of 6 triangles in three clusters of 2, drawn by instances 0 and 1.
    fn scene() -> Scene {
        let mut b = SceneBuilder::new("three clusters");
        let m = b.add_material(Material::opaque([1.0; 4]));
        let v = |x: f32| Vertex {
            position: [x, 0.0, 0.0],
            normal: [0.0, 0.0, 1.0],
            uv: [0.0, 0.0],
        };
        let vertices: Vec<Vertex> = (0..8).map(|k| v(k as f32)).collect();
        let mut vertices = vertices;
        vertices
            .iter_mut()
            .enumerate()
            .for_each(|(k, v)| v.position[1] = (k % 2) as f32);
        let indices: Vec<u32> = (0..6u32).flat_map(|t| [t, t + 1, t + 2]).collect();
        let mesh = b.add_mesh(&vertices, &indices, m).unwrap();
        for x in [0.0, 20.0] {
            b.add_instance(
                Transform::new(glam::Mat3::IDENTITY, glam::DVec3::new(x, 0.0, 0.0)),
                mesh,
            )
            .unwrap();
        }
        let mut scene = b.build(None).unwrap();
        let cluster = |first: u32| GpuCluster {
            first_index: first,
            index_count: 6,
            cone_cutoff: 2.0,
            ..GpuCluster::default()
        };
        let data = ClusterData {
            fingerprint: scene.geometry_fingerprint(),
            indices: scene.indices().to_vec(),
            clusters: vec![cluster(0), cluster(6), cluster(12)],
            mesh_clusters: vec![[0, 3]],
            lods: vec![tilegraph_scene::GpuLod::default(); tilegraph_scene::MAX_LODS],
        };
        scene.attach_clusters(data).unwrap();
        scene
    }

    fn draw(first_index: u32, index_count: u32, instances: &[u32]) -> IndirectDraw {
        IndirectDraw {
            index_count,
            first_index,
            instances: instances.to_vec(),
        }
    }

    fn check(
        s: &Scene,
        owners: &[u32],
        triangles: &[u32],
        compare: &[bool],
        colour: &[IndirectDraw],
    ) -> Option<ClusterCheck> {
        let visible = visible_clusters(s, owners, triangles, compare)?;
        let colour: Vec<_> = colour.iter().collect();
        Some(cluster_check(s, &visible, compare, &colour))
    }

    #[test]
    fn a_visible_cluster_left_out_is_a_false_negative() {
        let s = scene();
        // Pixels: instance 0 triangles 0 and 5 (clusters 0 and 2), instance 1 triangle 2
        // (cluster 1), background.
        let owners = [0, 0, 1, u32::MAX];
        let triangles = [0, 5, 2, 0];
        let compare = [true, true];
        // Everything drawn: exact, and the unseen clusters are false positives.
        let all = [draw(0, 18, &[0, 1])];
        let c = check(&s, &owners, &triangles, &compare, &all).unwrap();
        assert_eq!(
            c,
            ClusterCheck {
                visible: 3,
                drawn: 6,
                false_negatives: 0,
                false_positives: 3,
                stray_only: 0,
            }
        );
        // Instance 0's last cluster culled (its run ends at index 12): one false negative.
        let cut = [draw(0, 12, &[0]), draw(0, 18, &[1])];
        let c = check(&s, &owners, &triangles, &compare, &cut).unwrap();
        assert_eq!(c.false_negatives, 1);
        // Runs of single clusters cover exactly what they name.
        let runs = [draw(0, 6, &[0]), draw(12, 6, &[0]), draw(6, 6, &[1])];
        let c = check(&s, &owners, &triangles, &compare, &runs).unwrap();
        assert_eq!((c.false_negatives, c.false_positives, c.drawn), (0, 0, 3));
        // An instance outside the comparison counts neither way.
        let c = check(&s, &owners, &triangles, &[true, false], &cut).unwrap();
        assert_eq!((c.visible, c.false_negatives), (2, 1));
    }

    #[test]
    fn the_ideal_frame_draws_runs_of_the_visible_clusters() {
        use crate::draws::{order_groups, DrawBuilder, DrawList, Visible};
        let s = scene();
        let mut groups = Vec::new();
        order_groups(
            &s,
            glam::DVec3::ZERO,
            tilegraph_profile::SortOrder::ByState,
            &mut groups,
        );
        let mut builder = DrawBuilder::default();
        let mut list = DrawList::default();
        let build = |builder: &mut DrawBuilder, list: &mut DrawList| {
            let visible = Visible {
                opaque: None,
                blended: &[],
            };
            builder.build_into(&s, glam::DVec3::ZERO, &groups, visible, 1000, list);
            builder.narrow(&s, list);
            list.opaque
                .iter()
                .map(|d| {
                    (
                        d.first_index,
                        d.index_count,
                        d.first_instance,
                        d.instance_count,
                    )
                })
                .collect::<Vec<_>>()
        };
        let entry = |i: u32| s.buckets().entry(i).unwrap_or(u32::MAX);
        // No selection: the bucket whole, both instances in one draw.
        assert_eq!(build(&mut builder, &mut list), [(0, 18, entry(0), 2)]);
        // Instance 0's clusters 0 and 2 (two runs), instance 1's 0 and 1 (one run); a key of
        // a cluster past the mesh's is ignored.
        let keep = vec![key(0, 0), key(0, 2), key(1, 0), key(1, 1), key(1, 7)];
        builder.keep_only(Some(&keep));
        assert_eq!(
            build(&mut builder, &mut list),
            [
                (0, 6, entry(0), 1),
                (12, 6, entry(0), 1),
                (0, 12, entry(1), 1)
            ]
        );
        // Nothing visible: nothing drawn.
        builder.keep_only(Some(&[]));
        assert!(build(&mut builder, &mut list).is_empty());
    }
}
