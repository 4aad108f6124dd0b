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
use tilegraph_scene::{DrawGroup, MaterialClass, Scene};

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
    pub opaque: Option<&'a [u32]>,
    pub blended: &'a [u32],
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
    /// Visible blended instances with their distance.
    blended: Vec<(f64, u32)>,
}

impl DrawBuilder {
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
                self.listed.extend(ids.iter().filter_map(|&i| {
                    let entry = buckets.entry(i)?;
                    let mesh = scene.instances().get(i as usize)?.mesh.0;
                    let rank = *ranks.get(&(entry / stride.max(1), mesh))?;
                    Some((rank, entry, i))
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
        self.blended.extend(blended.iter().filter_map(|&i| {
            let inst = scene.instances().get(i as usize)?;
            Some(((inst.bounds.center - eye).length_squared(), i))
        }));
        // Farthest first; the id breaks ties, so the order is one.
        self.blended
            .sort_unstable_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        // Consecutive instances of one mesh are one instanced draw: a draw's instances are
        // drawn in instance order (primitive order), so the blend order is the same.
        for &(_, i) in &self.blended {
            let Some(inst) = scene.instances().get(i as usize) else {
                continue;
            };
            let first = cpu_base + list.instances.len() as u32;
            list.instances.push(i);
            match list.blended.last_mut() {
                Some(d)
                    if d.mesh == inst.mesh.0 && d.first_instance + d.instance_count == first =>
                {
                    d.instance_count += 1;
                }
                _ => {
                    if let Some(d) = draw_for(scene, inst.mesh.0, first, 1) {
                        list.blended.push(d);
                    }
                }
            }
        }
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
