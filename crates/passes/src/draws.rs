//! Draw lists: instances grouped into one instanced draw per mesh (seed 002: batching and
//! instancing), in the order the profile wants — opaque front to back where early depth
//! rejection pays, by state where the hardware removes hidden surfaces itself, blended back to
//! front always.
//!
//! The vertex shaders read `draw_instances[gl_InstanceIndex]`; each draw's `first_instance` is
//! its offset in that list, so one list serves every pass of the frame.

use glam::DVec3;
use tilegraph_profile::SortOrder;
use tilegraph_scene::{MaterialClass, Scene};

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
    /// Instance ids, indexed by `gl_InstanceIndex`.
    pub instances: Vec<u32>,
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
}

#[derive(Debug, Clone, Copy)]
struct Item {
    instance: u32,
    mesh: u32,
    distance_sq: f64,
}

/// Builds the draw list for a camera at `eye`, with `visible` (if given) restricting which
/// instances are drawn (CPU culling results, or `None` for everything).
pub fn build(
    scene: &Scene,
    eye: DVec3,
    opaque_sort: SortOrder,
    visible: Option<&[bool]>,
) -> DrawList {
    let mut list = DrawList::default();
    DrawBuilder::default().build_into(scene, eye, opaque_sort, visible, &mut list);
    list
}

/// Builds draw lists frame after frame without allocating: its sorting buffers, and the
/// lists it fills, keep their capacity.
#[derive(Debug, Default)]
pub struct DrawBuilder {
    classes: [Vec<Item>; 3],
    groups: Vec<(f64, u32, std::ops::Range<usize>)>,
}

impl DrawBuilder {
    /// [`build`] into `list` (its vectors cleared and refilled).
    pub fn build_into(
        &mut self,
        scene: &Scene,
        eye: DVec3,
        opaque_sort: SortOrder,
        visible: Option<&[bool]>,
        list: &mut DrawList,
    ) {
        for c in &mut self.classes {
            c.clear();
        }
        for (i, inst) in scene.instances().iter().enumerate() {
            if visible.is_some_and(|v| !v.get(i).copied().unwrap_or(false)) {
                continue;
            }
            let class =
                DrawClass::of(scene.instance_material(inst).map(|m| m.class)).index() as usize;
            let d = inst.bounds.center - eye;
            self.classes[class].push(Item {
                instance: i as u32,
                mesh: inst.mesh.0,
                distance_sq: d.length_squared(),
            });
        }
        list.instances.clear();
        let [opaque, alpha, blended] = &mut self.classes;
        grouped(
            scene,
            opaque,
            opaque_sort,
            &mut self.groups,
            &mut list.instances,
            &mut list.opaque,
        );
        grouped(
            scene,
            alpha,
            opaque_sort,
            &mut self.groups,
            &mut list.instances,
            &mut list.alpha_tested,
        );
        back_to_front(scene, blended, &mut list.instances, &mut list.blended);
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

/// One draw per mesh. Front to back: instances sorted by distance inside each draw, draws by
/// their nearest instance — a mesh group cannot be both instanced and globally depth-sorted,
/// and nearest-first per group is what coarse front-to-back sorting means in practice. Every
/// sort key ends in a unique id (instance, mesh), so unstable sorts (which allocate nothing)
/// give the one order.
fn grouped(
    scene: &Scene,
    items: &mut [Item],
    order: SortOrder,
    groups: &mut Vec<(f64, u32, std::ops::Range<usize>)>,
    out: &mut Vec<u32>,
    draws: &mut Vec<Draw>,
) {
    match order {
        SortOrder::BackToFront => items.sort_unstable_by(|a, b| {
            a.mesh
                .cmp(&b.mesh)
                .then(b.distance_sq.total_cmp(&a.distance_sq))
                .then(a.instance.cmp(&b.instance))
        }),
        SortOrder::FrontToBack => items.sort_unstable_by(|a, b| {
            a.mesh
                .cmp(&b.mesh)
                .then(a.distance_sq.total_cmp(&b.distance_sq))
                .then(a.instance.cmp(&b.instance))
        }),
        SortOrder::ByState | SortOrder::None => {
            items.sort_unstable_by_key(|a| (a.mesh, a.instance))
        }
    }
    groups.clear();
    let mut start = 0;
    while start < items.len() {
        let mesh = items[start].mesh;
        let end = items[start..]
            .iter()
            .position(|i| i.mesh != mesh)
            .map_or(items.len(), |p| start + p);
        let nearest = items[start..end]
            .iter()
            .map(|i| i.distance_sq)
            .fold(f64::INFINITY, f64::min);
        groups.push((nearest, mesh, start..end));
        start = end;
    }
    match order {
        SortOrder::FrontToBack => {
            groups.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)))
        }
        SortOrder::BackToFront => {
            groups.sort_unstable_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)))
        }
        SortOrder::ByState | SortOrder::None => {}
    }
    draws.clear();
    for (_, mesh, range) in groups.iter() {
        let first = out.len() as u32;
        out.extend(items[range.clone()].iter().map(|i| i.instance));
        if let Some(d) = draw_for(scene, *mesh, first, range.len() as u32) {
            draws.push(d);
        }
    }
}

/// Blended geometry: one draw per instance, farthest first, so blending composes correctly.
fn back_to_front(scene: &Scene, items: &mut [Item], out: &mut Vec<u32>, draws: &mut Vec<Draw>) {
    items.sort_unstable_by(|a, b| {
        b.distance_sq
            .total_cmp(&a.distance_sq)
            .then(a.instance.cmp(&b.instance))
    });
    draws.clear();
    draws.extend(items.iter().filter_map(|i| {
        let first = out.len() as u32;
        out.push(i.instance);
        draw_for(scene, i.mesh, first, 1)
    }));
}
