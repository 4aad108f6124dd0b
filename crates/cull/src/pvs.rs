//! A precomputed visible set (seeds 000 and 004): for each cell of a grid over the region
//! cameras visit, the instances seen from sampled viewpoints inside it. Exact only at its
//! samples: a camera elsewhere in the cell can see what none of them saw (measured by
//! `cull-check --culling pvs`); dilation — the neighbouring cells' sets too — trades drawn
//! instances for misses. Baked on the GPU by `tilegraph pvs` (`tilegraph_passes::pvs`).

use glam::DVec3;
use serde::{Deserialize, Serialize};

use crate::CullError;

/// The file format's version (`tilegraph pvs` writes it as JSON).
pub const PVS_VERSION: u32 = 1;

/// A baked visible set.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Pvs {
    pub version: u32,
    /// The scene it was baked for (its geometry and placements hashed:
    /// `Scene::placement_fingerprint`) and its instance slots.
    pub scene_fingerprint: u64,
    pub instances: u32,
    /// The grid: its lowest corner, a cell's size per axis (m) and the cells per axis.
    pub origin: [f64; 3],
    pub cell: [f64; 3],
    pub dims: [u32; 3],
    /// Viewpoints sampled per cell, and the side in pixels of each of their six faces.
    pub samples: u32,
    pub face_px: u32,
    /// Per cell (x fastest, then y, then z): the visible instances, ascending.
    pub cells: Vec<Vec<u32>>,
    /// Seconds the bake took.
    pub bake_seconds: f64,
}

impl Pvs {
    /// Checks the grid against its cells and ids against the instance count.
    pub fn validate(&self) -> Result<(), CullError> {
        let bad = |reason: String| Err(CullError::InvalidPvs { reason });
        if self.version != PVS_VERSION {
            return bad(format!(
                "version {} (this build reads {PVS_VERSION})",
                self.version
            ));
        }
        if !(self.cell.iter().all(|c| c.is_finite() && *c > 0.0)
            && self.origin.iter().all(|v| v.is_finite()))
        {
            return bad(format!(
                "cell size {:?} at origin {:?}: not a grid",
                self.cell, self.origin
            ));
        }
        let n: u64 = self.dims.iter().map(|&d| u64::from(d)).product();
        if n != self.cells.len() as u64 || n == 0 {
            return bad(format!(
                "{} cells for dims {:?}",
                self.cells.len(),
                self.dims
            ));
        }
        if let Some((k, id)) = self
            .cells
            .iter()
            .enumerate()
            .find_map(|(k, c)| c.iter().find(|&&i| i >= self.instances).map(|&i| (k, i)))
        {
            return bad(format!(
                "cell {k} names instance {id} of {}",
                self.instances
            ));
        }
        Ok(())
    }

    /// Reads a set from its file (the JSON `tilegraph pvs` writes) and checks it
    /// ([`Pvs::validate`]).
    pub fn from_json(bytes: &[u8]) -> Result<Pvs, CullError> {
        let pvs: Pvs = serde_json::from_slice(bytes).map_err(|e| CullError::InvalidPvs {
            reason: format!("not a visible set written by `tilegraph pvs`: {e}"),
        })?;
        pvs.validate()?;
        Ok(pvs)
    }

    /// The set as its file holds it (JSON).
    pub fn to_json(&self) -> Result<String, CullError> {
        serde_json::to_string(self).map_err(|e| CullError::InvalidPvs {
            reason: format!("cannot be written: {e}"),
        })
    }

    /// The cell holding `p`, as grid coordinates; `None` outside the region.
    pub fn cell_at(&self, p: DVec3) -> Option<[u32; 3]> {
        let mut at = [0u32; 3];
        for a in 0..3 {
            let t = ((p[a] - self.origin[a]) / self.cell[a]).floor();
            if !(t >= 0.0 && t < f64::from(self.dims[a])) {
                return None;
            }
            at[a] = t as u32;
        }
        Some(at)
    }

    /// The index of cell `c` in [`Pvs::cells`].
    pub fn index(&self, c: [u32; 3]) -> usize {
        let [dx, dy, _] = self.dims.map(|d| d as usize);
        c[0] as usize + dx * (c[1] as usize + dy * c[2] as usize)
    }

    /// Gathers into `ids` (ascending, no repeats) what a camera at `eye` may see: the sets of
    /// its cell and of the cells within `dilation` of it. The cost follows those sets, not the
    /// scene. Returns `false` (and gathers nothing) when `eye` lies outside the baked region:
    /// the caller draws what the frustum holds.
    pub fn visible_from(&self, eye: DVec3, dilation: u32, ids: &mut Vec<u32>) -> bool {
        ids.clear();
        let Some(c) = self.cell_at(eye) else {
            return false;
        };
        let d = i64::from(dilation);
        let range = |a: usize| {
            let lo = (i64::from(c[a]) - d).max(0);
            let hi = (i64::from(c[a]) + d).min(i64::from(self.dims[a]) - 1);
            lo..=hi
        };
        for z in range(2) {
            for y in range(1) {
                for x in range(0) {
                    let k = self.index([x as u32, y as u32, z as u32]);
                    ids.extend_from_slice(self.cells.get(k).map_or(&[][..], Vec::as_slice));
                }
            }
        }
        ids.sort_unstable();
        ids.dedup();
        true
    }

    /// Ids stored over every cell (the file's payload).
    pub fn stored_ids(&self) -> usize {
        self.cells.iter().map(Vec::len).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid() -> Pvs {
        Pvs {
            version: PVS_VERSION,
            scene_fingerprint: 7,
            instances: 10,
            origin: [0.0, 0.0, 0.0],
            cell: [2.0, 2.0, 2.0],
            dims: [3, 1, 2],
            samples: 1,
            face_px: 8,
            cells: vec![vec![0], vec![1], vec![2], vec![3], vec![4], vec![5, 9]],
            bake_seconds: 0.0,
        }
    }

    #[test]
    fn lookup_and_dilation() {
        let p = grid();
        p.validate().unwrap();
        assert_eq!(p.cell_at(DVec3::new(2.5, 1.0, 3.0)), Some([1, 0, 1]));
        assert_eq!(p.cell_at(DVec3::new(-0.1, 1.0, 3.0)), None);
        assert_eq!(p.cell_at(DVec3::new(6.0, 1.0, 3.0)), None);
        let mut ids = Vec::new();
        assert!(p.visible_from(DVec3::new(2.5, 1.0, 3.0), 0, &mut ids));
        assert_eq!(ids, [4]);
        assert!(p.visible_from(DVec3::new(5.0, 1.0, 3.0), 1, &mut ids));
        assert_eq!(ids, [1, 2, 4, 5, 9]);
        assert!(!p.visible_from(DVec3::new(5.0, 3.0, 3.0), 1, &mut ids));
        assert!(ids.is_empty());
    }

    #[test]
    fn bad_files_are_typed_errors() {
        let mut p = grid();
        p.cells[5].push(10);
        assert!(p.validate().is_err());
        let mut p = grid();
        p.cells.pop();
        assert!(p.validate().is_err());
        let mut p = grid();
        p.version = 99;
        assert!(p.validate().is_err());
        let mut p = grid();
        p.cell[1] = f64::NAN;
        assert!(p.validate().is_err());
    }
}
