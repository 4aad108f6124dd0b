//! A loose grid over drawn instances: what the CPU must still look at every frame (blended
//! geometry sorted back to front — the scene keeps that grid —, the occlusion techniques' CPU
//! lists — their renderer keeps one of the opaque instances, refitted from the scene's changes)
//! is found by testing cells, then the members of the cells the frustum cuts (seed 002: a
//! spatial hierarchy, so the frame costs what is visible).
//!
//! Each instance sits in the cell of its bounds' centre (clamped into the grid); a cell's bounds
//! are the union of its members' boxes, grown as members arrive or move and reset when it
//! empties, so a cell may be looser than its members but never tighter. A move inside one
//! cell costs a box union, across cells a swap-remove and a push.
//!
//! A cell keeps its members' boxes and meshes beside their ids ([`GridMember`]): a frame's
//! frustum tests and back-to-front keys read the cells in order and touch no instance (at a
//! million instances, a visit that fetched each visible instance's bounds spent most of its
//! time waiting for memory).

use glam::{DVec3, Vec3};

use super::InstanceBounds;
use crate::bounds::DAabb;

const NONE: u32 = u32::MAX;

/// How a box lies against a volume (a frustum, for the renderer).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Overlap {
    Outside,
    /// Partly inside: the members are tested one by one.
    Partial,
    /// Wholly inside: so is every member.
    Inside,
}

/// A run of members of one cell in a list a visit filled: the cell's bounds (which hold every
/// member's) and where the run ends (it starts where the previous run ended).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CellRun {
    pub bounds: DAabb,
    pub end: u32,
}

/// A member of a grid cell: an instance with its world bounds and mesh.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridMember {
    pub instance: u32,
    pub mesh: u32,
    /// The bounds' centre (world space, f64) and half extents.
    pub center: DVec3,
    pub half_extents: Vec3,
}

impl GridMember {
    fn aabb(&self) -> DAabb {
        let h = self.half_extents.as_dvec3();
        DAabb::new(self.center - h, self.center + h)
    }
}

#[derive(Clone, Debug)]
struct Cell {
    bounds: DAabb,
    members: Vec<GridMember>,
}

/// A loose grid of instance slots.
#[derive(Clone, Debug)]
pub struct LooseGrid {
    origin: DVec3,
    inv_cell: f64,
    dims: [u32; 3],
    cells: Vec<Cell>,
    /// Per instance slot: its cell and position there, `NONE` when not in the grid.
    place: Vec<(u32, u32)>,
}

impl LooseGrid {
    /// An empty grid over `bounds` with about one cell per 16 of `expected` instances (at most
    /// 2^20 cells): cubes, sized from the ground plane's area for flat worlds.
    pub fn new(bounds: DAabb, expected: usize) -> Self {
        let (min, extent) = if bounds.is_empty() {
            (DVec3::ZERO, DVec3::ONE)
        } else {
            (
                bounds.min,
                (bounds.max - bounds.min).max(DVec3::splat(1e-3)),
            )
        };
        let target = (expected / 16).clamp(1, 1 << 16) as f64;
        let mut cell = (extent.x * extent.z / target)
            .sqrt()
            .max((extent.x * extent.y * extent.z / target).cbrt());
        let dims = loop {
            let d = (extent / cell)
                .ceil()
                .clamp(DVec3::ONE, DVec3::splat(4096.0));
            if d.x * d.y * d.z <= f64::from(1 << 20) {
                break [d.x as u32, d.y as u32, d.z as u32];
            }
            cell *= 2.0;
        };
        let count = dims.iter().map(|&d| d as usize).product();
        LooseGrid {
            origin: min,
            inv_cell: 1.0 / cell,
            dims,
            cells: vec![
                Cell {
                    bounds: DAabb::EMPTY,
                    members: Vec::new()
                };
                count
            ],
            place: Vec::new(),
        }
    }

    fn cell_of(&self, center: DVec3) -> u32 {
        let q = (center - self.origin) * self.inv_cell;
        // Truncation is the floor of a positive value (and `floor` is a libm call on x86-64
        // without SSE4.1: a tenth of a move's cost); below zero and NaN clamp to 0, past the
        // grid (and infinity) to its last cell.
        let c = |v: f64, d: u32| {
            if v > 0.0 {
                (v as u64).min(u64::from(d - 1)) as u32
            } else {
                0
            }
        };
        let [dx, dy, dz] = self.dims;
        let (x, y, z) = (c(q.x, dx), c(q.y, dy), c(q.z, dz));
        (z * dy + y) * dx + x
    }

    /// Whether `instance` is in the grid.
    pub fn contains(&self, instance: u32) -> bool {
        self.place
            .get(instance as usize)
            .is_some_and(|p| p.0 != NONE)
    }

    /// Puts `instance` (not in the grid) of `mesh` into the cell of its bounds' centre.
    pub fn insert(&mut self, instance: u32, mesh: u32, bounds: &InstanceBounds) {
        if self.place.len() <= instance as usize {
            self.place.resize(instance as usize + 1, (NONE, 0));
        }
        debug_assert_eq!(self.place[instance as usize].0, NONE);
        let member = GridMember {
            instance,
            mesh,
            center: bounds.center,
            half_extents: bounds.half_extents,
        };
        let c = self.cell_of(member.center);
        let cell = &mut self.cells[c as usize];
        self.place[instance as usize] = (c, cell.members.len() as u32);
        cell.members.push(member);
        cell.bounds = cell.bounds.union(member.aabb());
    }

    /// Takes `instance` out of the grid (if in it).
    pub fn remove(&mut self, instance: u32) {
        let Some(&(c, pos)) = self.place.get(instance as usize) else {
            return;
        };
        if c == NONE {
            return;
        }
        self.place[instance as usize] = (NONE, 0);
        let cell = &mut self.cells[c as usize];
        cell.members.swap_remove(pos as usize);
        if let Some(moved) = cell.members.get(pos as usize) {
            self.place[moved.instance as usize] = (c, pos);
        }
        if cell.members.is_empty() {
            cell.bounds = DAabb::EMPTY;
        }
    }

    /// `instance` now has `bounds`; false when it is not in this grid.
    pub fn update(&mut self, instance: u32, bounds: &InstanceBounds) -> bool {
        let Some(&(c, pos)) = self.place.get(instance as usize) else {
            return false;
        };
        if c == NONE {
            return false;
        }
        if self.cell_of(bounds.center) == c {
            let cell = &mut self.cells[c as usize];
            if let Some(m) = cell.members.get_mut(pos as usize) {
                m.center = bounds.center;
                m.half_extents = bounds.half_extents;
                cell.bounds = cell.bounds.union(m.aabb());
            }
        } else {
            let mesh = self.cells[c as usize]
                .members
                .get(pos as usize)
                .map_or(0, |m| m.mesh);
            self.remove(instance);
            self.insert(instance, mesh, bounds);
        }
        true
    }

    /// Calls `visit(member, overlap)` for every member of every cell `test` does not find
    /// outside, with the cell's overlap: `Inside` members are inside too, `Partial` ones are
    /// the caller's to test (their bounds are in the member).
    pub fn visit(
        &self,
        test: impl FnMut(&DAabb) -> Overlap,
        mut visit: impl FnMut(&GridMember, Overlap),
    ) {
        self.visit_cells(test, |_, members, overlap| {
            for m in members {
                visit(m, overlap);
            }
        });
    }

    /// Calls `visit(bounds, members, overlap)` for every occupied cell `test` does not find
    /// outside: a caller that tests the cell's box first (software occlusion) sees each cell
    /// whole.
    pub fn visit_cells(
        &self,
        mut test: impl FnMut(&DAabb) -> Overlap,
        mut visit: impl FnMut(&DAabb, &[GridMember], Overlap),
    ) {
        for cell in self.cells.iter().filter(|c| !c.members.is_empty()) {
            let overlap = test(&cell.bounds);
            if overlap != Overlap::Outside {
                visit(&cell.bounds, &cell.members, overlap);
            }
        }
    }

    /// Instances in the grid.
    pub fn len(&self) -> usize {
        self.cells.iter().map(|c| c.members.len()).sum()
    }

    pub fn is_empty(&self) -> bool {
        self.cells.iter().all(|c| c.members.is_empty())
    }

    /// Cells of the grid (occupied or not).
    pub fn cell_count(&self) -> usize {
        self.cells.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn boxed(x: f64, z: f64, h: f64) -> DAabb {
        DAabb::new(DVec3::new(x - h, 0.0, z - h), DVec3::new(x + h, 1.0, z + h))
    }

    fn placed(b: DAabb) -> InstanceBounds {
        let half = ((b.max - b.min) * 0.5).as_vec3();
        InstanceBounds {
            center: (b.min + b.max) * 0.5,
            half_extents: half,
            radius: half.length(),
        }
    }

    /// The grid finds exactly what a test of every box finds, as members move, leave and
    /// arrive, and out past the bounds it was made for.
    #[test]
    fn a_query_finds_what_testing_every_box_finds() {
        let bounds = DAabb::new(DVec3::ZERO, DVec3::new(100.0, 1.0, 100.0));
        let mut g = LooseGrid::new(bounds, 400);
        let mut boxes: Vec<Option<DAabb>> = Vec::new();
        for i in 0..400u32 {
            let b = boxed(f64::from(i % 20) * 5.0, f64::from(i / 20) * 5.0, 1.0);
            g.insert(i, 0, &placed(b));
            boxes.push(Some(b));
        }
        // A query box: x and z in 30..55.
        let q = DAabb::new(DVec3::new(30.0, -1.0, 30.0), DVec3::new(55.0, 2.0, 55.0));
        let test = |b: &DAabb| {
            if b.is_empty() || b.max.cmplt(q.min).any() || b.min.cmpgt(q.max).any() {
                Overlap::Outside
            } else if b.min.cmpge(q.min).all() && b.max.cmple(q.max).all() {
                Overlap::Inside
            } else {
                Overlap::Partial
            }
        };
        let check = |g: &LooseGrid, boxes: &[Option<DAabb>]| {
            let mut found = Vec::new();
            g.visit(test, |m, o| {
                let b = boxes[m.instance as usize].expect("a member of the grid has a box");
                assert_eq!(m.aabb(), b);
                if o == Overlap::Inside || test(&b) != Overlap::Outside {
                    found.push(m.instance);
                }
            });
            found.sort_unstable();
            let expected: Vec<u32> = (0..boxes.len() as u32)
                .filter(|&i| boxes[i as usize].is_some_and(|b| test(&b) != Overlap::Outside))
                .collect();
            assert_eq!(found, expected);
        };
        check(&g, &boxes);
        for step in 0..50u32 {
            let i = (step * 37) % 400;
            let b = boxed(f64::from(step) * 7.0 - 100.0, 40.0, 2.0);
            if boxes[i as usize].is_some() {
                g.update(i, &placed(b));
            } else {
                g.insert(i, 0, &placed(b));
            }
            boxes[i as usize] = Some(b);
            let gone = (step * 53 + 11) % 400;
            g.remove(gone);
            boxes[gone as usize] = None;
            check(&g, &boxes);
        }
        assert_eq!(g.len(), boxes.iter().flatten().count());
    }
}
