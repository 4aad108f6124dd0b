//! Draw lists: instances grouped into one instanced draw per bucket of the scene (a mesh of
//! one draw list, seed 002: batching and instancing), blended instances one by one back to
//! front (runs of one mesh in that order drawn instanced).
//!
//! The vertex shaders read `draw_instances[gl_InstanceIndex]`; each draw's `first_instance` is
//! its first entry in that list. Unculled, a draw is a bucket of the scene as it sits in the
//! resident lists ([`tilegraph_scene::DrawBuckets`]): nothing per instance is done on the CPU.
//! A frame whose CPU decides what is drawn (occlusion queries, raster occlusion's pre-pass, and
//! blended geometry always) writes its instances after the scene's lists (from `cpu_base`), in
//! the buckets' entry order: every technique draws in one order, so culled images equal
//! unculled ones.

use std::collections::HashMap;

use glam::DVec3;
use tilegraph_profile::SortOrder;
use tilegraph_scene::{DrawGroup, GridMember, MaterialClass, Scene};

/// One `vkCmdDrawIndexed`: a mesh, instanced over `instance_count` entries of the draw list
/// starting at `first_instance`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Draw {
    pub mesh: u32,
    pub first_index: u32,
    pub index_count: u32,
    pub vertex_offset: i32,
    pub first_instance: u32,
    pub instance_count: u32,
    pub double_sided: bool,
}

/// The material classes, in the order a frame draws them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum DrawClass {
    Opaque,
    AlphaTested,
    /// Blended: drawn back to front, never culled on the GPU.
    Blended,
}

impl DrawClass {
    /// The class's number in the shaders (`class` specialization constant, culling lists).
    pub const fn index(self) -> u32 {
        self as u32
    }

    /// The material class of a scene material.
    pub fn of(class: Option<MaterialClass>) -> Self {
        match class {
            Some(MaterialClass::AlphaTested { .. }) => DrawClass::AlphaTested,
            Some(MaterialClass::Blended) => DrawClass::Blended,
            Some(MaterialClass::Opaque) | None => DrawClass::Opaque,
        }
    }
}

/// The frame's draw list, split by material class.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct DrawList {
    /// The frame's CPU lists: instance ids of entries `cpu_base..`.
    pub instances: Vec<u32>,
    /// The first entry of the CPU lists (after the scene's lists).
    pub cpu_base: u32,
    pub opaque: Vec<Draw>,
    pub alpha_tested: Vec<Draw>,
    pub blended: Vec<Draw>,
}

impl DrawList {
    /// The draws of one material class.
    pub fn of(&self, class: DrawClass) -> &[Draw] {
        match class {
            DrawClass::Opaque => &self.opaque,
            DrawClass::AlphaTested => &self.alpha_tested,
            DrawClass::Blended => &self.blended,
        }
    }

    pub fn triangles(&self) -> u64 {
        [&self.opaque, &self.alpha_tested, &self.blended]
            .iter()
            .flat_map(|v| v.iter())
            .map(|d| u64::from(d.index_count / 3) * u64::from(d.instance_count))
            .sum()
    }

    /// The instance at `entry` of the frame's CPU lists.
    pub fn cpu_instance(&self, entry: u32) -> Option<u32> {
        let k = entry.checked_sub(self.cpu_base)?;
        self.instances.get(k as usize).copied()
    }
}

/// The scene's buckets in this frame's draw order, into `out`: list by list, and inside a list
/// by the profile's opaque order applied to the buckets' bounds — nearest first
/// (`front-to-back`), farthest first, or by mesh (`by-state`, `none`). Coarse: a bucket holds
/// every instance of a mesh in its list, so for instanced props its bounds span the scene; for
/// a level of one instance per mesh it is the instance's order. Each key ends in the mesh
/// (unique in a list): the order is one.
pub fn order_groups(scene: &Scene, eye: DVec3, order: SortOrder, out: &mut Vec<DrawGroup>) {
    out.clear();
    out.extend(scene.buckets().groups());
    let near = |g: &DrawGroup| {
        let b = g.bounds;
        let d = (b.min - eye).max(eye - b.max).max(DVec3::ZERO);
        d.length_squared()
    };
    match order {
        SortOrder::FrontToBack => out.sort_unstable_by(|a, b| {
            (a.list.cmp(&b.list))
                .then(near(a).total_cmp(&near(b)))
                .then(a.mesh.cmp(&b.mesh))
        }),
        SortOrder::BackToFront => out.sort_unstable_by(|a, b| {
            (a.list.cmp(&b.list))
                .then(near(b).total_cmp(&near(a)))
                .then(a.mesh.cmp(&b.mesh))
        }),
        SortOrder::ByState | SortOrder::None => {
            out.sort_unstable_by_key(|g| (g.list, g.mesh));
        }
    }
}

/// What the CPU found in the frustum this frame: the opaque and alpha-tested instances where the
/// CPU decides what is drawn (`None`: the scene's buckets are drawn as they are), and the
/// blended instances.
#[derive(Debug, Clone, Copy)]
pub struct Visible<'a> {
    pub opaque: Option<&'a [GridMember]>,
    pub blended: &'a [GridMember],
}

/// Builds draw lists frame after frame without allocating: its sorting buffers, and the
/// lists it fills, keep their capacity.
#[derive(Debug, Default)]
pub struct DrawBuilder {
    /// Visible opaque and alpha-tested instances: their bucket's place in the frame's order,
    /// their entry, their id.
    listed: Vec<(u32, u32, u32)>,
    /// Each bucket's (list, mesh) place in the frame's order.
    ranks: HashMap<(u32, u32), u32>,
    /// Visible blended instances as sort keys ([`blend_key`]), and the radix sort's scratch.
    blended: Vec<u64>,
    scratch: Vec<u64>,
    /// The ideal frame's clusters ([`keep_clusters`]), and its scratch list.
    keep: Option<Vec<u64>>,
    kept: Vec<Draw>,
}

/// The back-to-front sort key of a blended instance: the distance from the eye to its bounds'
/// centre (squared, as f32 bits: their order is the numbers' order for positive values),
/// inverted so that farther sorts first, then `index`, its place in the frame's visible list
/// (the grid's order, which every renderer of the scene sees alike: ties broken one way).
fn blend_key(distance_sq: f64, index: u32) -> u64 {
    let d = (distance_sq as f32).to_bits();
    (u64::from(!d) << 32) | u64::from(index)
}

/// Sorts `keys` ascending, least significant byte first; a byte every key shares is skipped
/// (the high bytes of instance ids, say). O(n) per pass: a frame's thousands of visible
/// blended instances sort in a fraction of a comparison sort's time.
fn radix_sort(keys: &mut Vec<u64>, scratch: &mut Vec<u64>) {
    scratch.clear();
    scratch.resize(keys.len(), 0);
    for shift in (0..64).step_by(8) {
        let mut count = [0usize; 256];
        for &k in keys.iter() {
            count[((k >> shift) & 0xff) as usize] += 1;
        }
        if count.contains(&keys.len()) {
            continue;
        }
        let mut at = 0;
        for c in &mut count {
            let n = *c;
            *c = at;
            at += n;
        }
        for &k in keys.iter() {
            let digit = ((k >> shift) & 0xff) as usize;
            scratch[count[digit]] = k;
            count[digit] += 1;
        }
        std::mem::swap(keys, scratch);
    }
}

impl DrawBuilder {
    /// From the next list on, [`Self::narrow`] keeps only these clusters (sorted
    /// [`cluster_key`]s; `None`: every triangle of the instances drawn), copied into a buffer
    /// kept from frame to frame.
    pub fn keep_only(&mut self, clusters: Option<&[u64]>) {
        match clusters {
            Some(c) => {
                let keep = self.keep.get_or_insert_with(Vec::new);
                keep.clear();
                keep.extend_from_slice(c);
            }
            None => self.keep = None,
        }
    }

    /// [`keep_clusters`] with the clusters [`Self::keep_only`] named, if any.
    pub fn narrow(&mut self, scene: &Scene, list: &mut DrawList) {
        if let Some(keep) = &self.keep {
            keep_clusters(scene, keep, list, &mut self.kept);
        }
    }

    /// Fills `list`: the opaque and alpha-tested draws — the scene's buckets in the frame's
    /// order `groups` (`visible` `None`), or the `visible` instances of them in that order and
    /// each bucket's entry order, written from `cpu_base` — and the `blended` instances
    /// farthest first.
    pub fn build_into(
        &mut self,
        scene: &Scene,
        eye: DVec3,
        groups: &[DrawGroup],
        visible: Visible<'_>,
        cpu_base: u32,
        list: &mut DrawList,
    ) {
        let Visible {
            opaque: visible,
            blended,
        } = visible;
        list.instances.clear();
        list.opaque.clear();
        list.alpha_tested.clear();
        list.blended.clear();
        list.cpu_base = cpu_base;
        let buckets = scene.buckets();
        let stride = buckets.stride();
        match visible {
            None => {
                for g in groups {
                    let first = g.list * stride + g.position;
                    push_draw(scene, list, g.list, g.mesh, first, g.len);
                }
            }
            Some(ids) => {
                self.ranks.clear();
                for (r, g) in groups.iter().enumerate() {
                    self.ranks.insert((g.list, g.mesh), r as u32);
                }
                self.listed.clear();
                let ranks = &self.ranks;
                self.listed.extend(ids.iter().filter_map(|m| {
                    let entry = buckets.entry(m.instance)?;
                    let rank = *ranks.get(&(entry / stride.max(1), m.mesh))?;
                    Some((rank, entry, m.instance))
                }));
                self.listed.sort_unstable();
                let mut k = 0;
                while let Some(&(rank, _, _)) = self.listed.get(k) {
                    let first = cpu_base + list.instances.len() as u32;
                    let mut n = 0;
                    while let Some(&(r, _, i)) = self.listed.get(k) {
                        if r != rank {
                            break;
                        }
                        list.instances.push(i);
                        n += 1;
                        k += 1;
                    }
                    if let Some(g) = groups.get(rank as usize) {
                        push_draw(scene, list, g.list, g.mesh, first, n);
                    }
                }
            }
        }
        self.blended.clear();
        self.blended.extend(
            (0u32..)
                .zip(blended)
                .map(|(k, m)| blend_key((m.center - eye).length_squared(), k)),
        );
        // Farthest first; the id breaks ties, so the order is one.
        radix_sort(&mut self.blended, &mut self.scratch);
        // Consecutive instances of one mesh are one instanced draw: a draw's instances are
        // drawn in instance order (primitive order), so the blend order is the same.
        for &key in &self.blended {
            let Some(m) = blended.get(key as u32 as usize) else {
                continue;
            };
            let first = cpu_base + list.instances.len() as u32;
            list.instances.push(m.instance);
            match list.blended.last_mut() {
                Some(d) if d.mesh == m.mesh && d.first_instance + d.instance_count == first => {
                    d.instance_count += 1;
                }
                _ => {
                    if let Some(d) = draw_for(scene, m.mesh, first, 1) {
                        list.blended.push(d);
                    }
                }
            }
        }
    }
}

/// One (instance, cluster) pair as a sortable key: the instance in the high word, the
/// cluster's global index ([`tilegraph_scene::Clusters::clusters`]) in the low one.
pub fn cluster_key(instance: u32, cluster: u32) -> u64 {
    (u64::from(instance) << 32) | u64::from(cluster)
}

/// Narrows the opaque and alpha-tested draws of `list` to the clusters `keep` names (sorted
/// [`cluster_key`]s): each instance of a draw becomes one draw per run of consecutive kept
/// clusters of its mesh, in cluster order (the order its whole draw had), and an instance with
/// none kept is not drawn. The ideal frame of a cluster technique: the oracle's visible
/// clusters drawn with no culling work. A scene without clusters keeps its draws.
pub fn keep_clusters(scene: &Scene, keep: &[u64], list: &mut DrawList, scratch: &mut Vec<Draw>) {
    let Some(clusters) = scene.clusters() else {
        return;
    };
    let buckets = scene.buckets();
    for draws in [&mut list.opaque, &mut list.alpha_tested] {
        scratch.clear();
        for d in draws.iter() {
            let Some(&[base, count]) = clusters.mesh_clusters.get(d.mesh as usize) else {
                continue;
            };
            let own = base..base.saturating_add(count);
            for entry in d.first_instance..d.first_instance + d.instance_count {
                let instance = if entry >= list.cpu_base {
                    list.instances
                        .get((entry - list.cpu_base) as usize)
                        .copied()
                } else {
                    buckets.instance_at(entry)
                };
                let Some(instance) = instance else {
                    continue;
                };
                let lo = keep.partition_point(|&k| k < cluster_key(instance, 0));
                let hi = keep.partition_point(|&k| k <= cluster_key(instance, u32::MAX));
                let mut run: Option<Draw> = None;
                let of_mesh = keep
                    .get(lo..hi)
                    .unwrap_or(&[])
                    .iter()
                    .map(|&k| k as u32)
                    .filter(|c| own.contains(c));
                for c in of_mesh {
                    let Some(c) = clusters.clusters.get(c as usize) else {
                        continue;
                    };
                    match run.as_mut() {
                        Some(r) if r.first_index + r.index_count == c.first_index => {
                            r.index_count += c.index_count;
                        }
                        _ => {
                            scratch.extend(run.take());
                            run = Some(Draw {
                                first_index: c.first_index,
                                index_count: c.index_count,
                                first_instance: entry,
                                instance_count: 1,
                                ..*d
                            });
                        }
                    }
                }
                scratch.extend(run);
            }
        }
        std::mem::swap(draws, scratch);
    }
}

/// A draw of `count` entries from `first` of mesh `mesh`, in the class of draw list `l`.
fn push_draw(scene: &Scene, list: &mut DrawList, l: u32, mesh: u32, first: u32, count: u32) {
    if let Some(d) = draw_for(scene, mesh, first, count) {
        if l >= 2 {
            list.alpha_tested.push(d);
        } else {
            list.opaque.push(d);
        }
    }
}

fn draw_for(scene: &Scene, mesh: u32, first_instance: u32, instance_count: u32) -> Option<Draw> {
    let m = scene.meshes().get(mesh as usize)?;
    let double_sided = scene
        .material(m.material)
        .is_some_and(|mat| mat.double_sided);
    Some(Draw {
        mesh,
        first_index: m.first_index,
        index_count: m.index_count,
        vertex_offset: m.vertex_offset,
        first_instance,
        instance_count,
        double_sided,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn radix_sort_orders_back_to_front_with_ids_breaking_ties() {
        let items = [
            (4.0, 7),
            (100.0, 3),
            (4.0, 2),
            (0.25, 9),
            (1e6, 1),
            (100.0, 0),
        ];
        let mut keys: Vec<u64> = items.iter().map(|&(d, i)| blend_key(d, i)).collect();
        let mut expected = keys.clone();
        expected.sort_unstable();
        radix_sort(&mut keys, &mut Vec::new());
        assert_eq!(keys, expected);
        let order: Vec<u32> = keys.iter().map(|&k| k as u32).collect();
        assert_eq!(order, [1, 0, 3, 2, 7, 9]);
    }
}
