//! The oracle for shadow casters: which casters a frame's shadows need, and which drawn ones it
//! did not.
//!
//! A caster is **needed** in a cascade when its shadow can reach a surface the camera sees: its
//! box, projected into the cascade, covers a texel that the lookup of a visible pixel reads
//! (the pixel's receiver moved along its normal by the normal offset, the PCF taps and their
//! bilinear footprint around it), and lies nearer the light than that receiver. The receivers
//! are exact: each pixel of the oracle's visibility buffer names its instance and triangle, and
//! the pixel's ray meets that triangle's plane (f64). The casters are taken at box level, so
//! the needed set holds every caster whose removal could change the image — and perhaps some
//! whose triangles miss the texels their box covers: the false positives counted against it
//! are a lower bound of a technique's waste.
//!
//! A needed caster the technique culled is a **false negative** only where it changes the
//! image: those needed by a pixel where the technique's image differs from the reference are
//! the false negatives (none when the images are equal), the differing pixels attributed to
//! the casters that could cast there.

use glam::{DMat4, DVec3, DVec4};
use serde::Serialize;
use tilegraph_cull::shadow::{CascadeSettings, Cascades};
use tilegraph_scene::{CameraFrame, InstanceFlags, MaterialClass, Scene};

/// One frame's casters, summed over the cascades: needed (by the oracle), drawn by the
/// technique, drawn but not needed, needed and culled where the image differs.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct CasterCheck {
    pub needed: usize,
    pub drawn: usize,
    pub false_positives: usize,
    pub false_negatives: usize,
    /// Needed casters the technique culled, wherever their shadow falls (an image that stayed
    /// equal shows they changed nothing: box-level needs hold casters whose triangles miss).
    pub needed_culled: usize,
}

/// Texels a bin of the caster grid spans on a side.
const BIN: f64 = 16.0;

/// A caster's footprint in one cascade: its box's texel rectangle and its depth nearest the
/// light.
#[derive(Debug, Clone, Copy)]
struct Footprint {
    id: u32,
    lo: [f64; 2],
    hi: [f64; 2],
    nearest: f64,
}

/// One cascade's casters binned by texel rectangle.
struct CascadeGrid {
    bins: usize,
    /// Per bin, indices into `footprints`.
    cells: Vec<Vec<usize>>,
    footprints: Vec<Footprint>,
    /// Light-space depth per world metre (the clip matrix's z row).
    depth_per_metre: f64,
}

impl CascadeGrid {
    fn new(scene: &Scene, casters: &[u32], clip: &DMat4, resolution: f64) -> Self {
        let bins = ((resolution / BIN).ceil() as usize).max(1);
        let mut cells = vec![Vec::new(); bins * bins];
        let mut footprints = Vec::with_capacity(casters.len());
        let bin_of = |t: f64| ((t / BIN).floor().max(0.0) as usize).min(bins - 1);
        for &id in casters {
            let Some(inst) = scene.instances().get(id as usize) else {
                continue;
            };
            let (c, h) = (inst.bounds.center, inst.bounds.half_extents.as_dvec3());
            let mut f = Footprint {
                id,
                lo: [f64::INFINITY; 2],
                hi: [f64::NEG_INFINITY; 2],
                nearest: f64::INFINITY,
            };
            for k in 0..8 {
                let corner = c + DVec3::new(
                    if k & 1 == 0 { -h.x } else { h.x },
                    if k & 2 == 0 { -h.y } else { h.y },
                    if k & 4 == 0 { -h.z } else { h.z },
                );
                let p = clip.mul_vec4(corner.extend(1.0));
                let t = texel_of(p, resolution);
                for (a, &v) in t.iter().enumerate() {
                    f.lo[a] = f.lo[a].min(v);
                    f.hi[a] = f.hi[a].max(v);
                }
                f.nearest = f.nearest.min(p.z);
            }
            // Wholly off the cascade's square (with room for any lookup's reach): no lookup
            // of this cascade reads it.
            let margin = 2.0 * BIN;
            if f.hi[0] < -margin
                || f.hi[1] < -margin
                || f.lo[0] > resolution + margin
                || f.lo[1] > resolution + margin
            {
                continue;
            }
            let index = footprints.len();
            for by in bin_of(f.lo[1])..=bin_of(f.hi[1]) {
                for bx in bin_of(f.lo[0])..=bin_of(f.hi[0]) {
                    cells[by * bins + bx].push(index);
                }
            }
            footprints.push(f);
        }
        CascadeGrid {
            bins,
            cells,
            footprints,
            depth_per_metre: clip.row(2).truncate().length(),
        }
    }

    /// Marks in `needed` the casters whose footprint covers a texel within `reach` of `at`
    /// and lies nearer the light than `depth` (plus `slack`).
    fn mark(&self, at: [f64; 2], depth: f64, reach: f64, slack: f64, needed: &mut [bool]) {
        let bin_of = |t: f64| ((t / BIN).floor().max(0.0) as usize).min(self.bins - 1);
        let (lo, hi) = (
            [at[0] - reach, at[1] - reach],
            [at[0] + reach, at[1] + reach],
        );
        for by in bin_of(lo[1])..=bin_of(hi[1]) {
            for bx in bin_of(lo[0])..=bin_of(hi[0]) {
                for &k in &self.cells[by * self.bins + bx] {
                    let f = &self.footprints[k];
                    let overlaps = f.lo[0] <= hi[0]
                        && f.hi[0] >= lo[0]
                        && f.lo[1] <= hi[1]
                        && f.hi[1] >= lo[1];
                    if overlaps && f.nearest < depth + slack {
                        if let Some(n) = needed.get_mut(f.id as usize) {
                            *n = true;
                        }
                    }
                }
            }
        }
    }
}

/// Texel coordinates (x, y in texels of the cascade's square) of clip-space point `p`.
fn texel_of(p: DVec4, resolution: f64) -> [f64; 2] {
    [
        (p.x * 0.5 + 0.5) * resolution,
        (p.y * 0.5 + 0.5) * resolution,
    ]
}

/// The shadow casters of `scene`: drawn, casting, opaque or alpha-tested (what the shadow
/// culling considers).
pub fn casters(scene: &Scene) -> Vec<u32> {
    scene
        .instances()
        .iter()
        .enumerate()
        .filter(|(_, inst)| {
            inst.flags.is_drawn()
                && inst.flags.contains(InstanceFlags::CASTS_SHADOWS)
                && !scene
                    .instance_material(inst)
                    .is_some_and(|m| m.class == MaterialClass::Blended)
        })
        .map(|(i, _)| i as u32)
        .collect()
}

/// What the oracle's frame says of the casters: per cascade, the casters needed by the
/// visible pixels, and those needed by the pixels in `differing`.
pub struct CasterNeeds {
    pub needed: Vec<Vec<bool>>,
    pub needed_where_differing: Vec<Vec<bool>>,
}

/// The oracle's frame as the caster check needs it.
pub struct OracleFrame<'a> {
    pub frame: &'a CameraFrame,
    pub size: (u32, u32),
    /// Per pixel, its instance (`u32::MAX`: none) and the triangle of its mesh.
    pub instances: &'a [u32],
    pub triangles: &'a [u32],
    /// Per pixel, whether the technique's image differs from the reference there.
    pub differing: &'a [bool],
}

/// The casters of `casters` each cascade of `cascades` needs for the pixels of `oracle`.
pub fn needed_casters(
    scene: &Scene,
    oracle: &OracleFrame<'_>,
    cascades: &Cascades,
    settings: &CascadeSettings,
    casters: &[u32],
) -> CasterNeeds {
    let n = scene.instances().len();
    let resolution = f64::from(settings.resolution.max(1));
    let grids: Vec<CascadeGrid> = cascades
        .as_slice()
        .iter()
        .map(|c| CascadeGrid::new(scene, casters, &c.clip_from_world, resolution))
        .collect();
    let mut needs = CasterNeeds {
        needed: vec![vec![false; n]; grids.len()],
        needed_where_differing: vec![vec![false; n]; grids.len()],
    };
    let camera = &oracle.frame.camera;
    let eye = camera.eye;
    let forward = (camera.target - camera.eye).normalize_or_zero();
    let rays = Rays {
        unproject: oracle.frame.current.view_projection.as_dmat4().inverse(),
        near_depth: match oracle.frame.current.depth {
            tilegraph_scene::DepthConvention::Reverse => 1.0,
            tilegraph_scene::DepthConvention::Standard => 0.0,
        },
        eye,
        size: (oracle.size.0 as usize, oracle.size.1 as usize),
    };
    // What a lookup reaches beyond its receiver's texel: the normal offset, the PCF taps,
    // their bilinear footprint, and a texel for f32 rounding on the GPU.
    let reach = settings.normal_offset_texels + f64::from(settings.pcf_radius) + 2.0;
    let items = cascades.as_slice();
    for (p, (&inst, &tri)) in oracle.instances.iter().zip(oracle.triangles).enumerate() {
        let Some(q) = rays.receiver(scene, inst, tri, p) else {
            continue;
        };
        let dist = q.dot(forward);
        let differing = oracle.differing.get(p).copied().unwrap_or(false);
        for (c, (cascade, grid)) in items.iter().zip(&grids).enumerate() {
            // The GPU picks the first cascade whose far lies beyond the point, in f32: near a
            // boundary either side may be picked.
            let margin = 1e-3 * cascade.far.abs().max(1.0);
            let before = if c == 0 {
                f64::NEG_INFINITY
            } else {
                items[c - 1].far
            };
            if dist < before - margin || dist >= cascade.far + margin {
                continue;
            }
            let at = cascade.clip_from_world.mul_vec4((q + eye).extend(1.0));
            let slack = settings.normal_offset_texels * cascade.texel * grid.depth_per_metre + 1e-5;
            let texel = texel_of(at, resolution);
            grid.mark(texel, at.z, reach, slack, &mut needs.needed[c]);
            if differing {
                grid.mark(
                    texel,
                    at.z,
                    reach,
                    slack,
                    &mut needs.needed_where_differing[c],
                );
            }
        }
    }
    needs
}

/// The camera's pixel rays.
struct Rays {
    /// Camera-relative clip space to camera-relative space.
    unproject: DMat4,
    /// The depth of the near plane.
    near_depth: f64,
    eye: DVec3,
    size: (usize, usize),
}

impl Rays {
    /// The camera-relative point where pixel `p`'s ray meets the plane of triangle `tri` of
    /// instance `inst` (f64), or `None` for the background or a ray along the plane.
    fn receiver(&self, scene: &Scene, inst: u32, tri: u32, p: usize) -> Option<DVec3> {
        let instance = scene.instances().get(inst as usize)?;
        let mesh = scene.mesh(instance.mesh)?;
        let first = mesh.first_index.checked_add(tri.checked_mul(3)?)? as usize;
        let idx = scene.indices().get(first..first + 3)?;
        let relative = |i: u32| -> Option<DVec3> {
            let v = usize::try_from(i64::from(i) + i64::from(mesh.vertex_offset)).ok()?;
            let local = glam::Vec3::from_array(scene.vertices().get(v)?.position);
            let world =
                (instance.transform.linear * local).as_dvec3() + instance.transform.translation;
            Some(world - self.eye)
        };
        let [a, b, c] = [relative(idx[0])?, relative(idx[1])?, relative(idx[2])?];
        let (w, h) = (self.size.0.max(1), self.size.1.max(1));
        let (x, y) = (p % w, p / w);
        let at = |d: f64| {
            let clip = DVec4::new(
                (x as f64 + 0.5) / w as f64 * 2.0 - 1.0,
                (y as f64 + 0.5) / h as f64 * 2.0 - 1.0,
                d,
                1.0,
            );
            let v = self.unproject.mul_vec4(clip);
            v.truncate() / v.w
        };
        let origin = at(self.near_depth);
        let dir = at(0.5) - origin;
        Some(origin + dir * plane_hit(origin, dir, a, b, c)?)
    }
}

/// The ray parameter where `origin + t * dir` meets the plane of `a, b, c`, all given relative
/// to one point.
fn plane_hit(origin: DVec3, dir: DVec3, a: DVec3, b: DVec3, c: DVec3) -> Option<f64> {
    let n = (b - a).cross(c - a);
    let denom = n.dot(dir);
    (denom.abs() > 1e-30 * n.length() * dir.length()).then(|| n.dot(a - origin) / denom)
}

/// Sums a frame's caster check from the needs and the technique's drawn casters per cascade
/// (sorted ids).
pub fn check(needs: &CasterNeeds, drawn: &[Vec<u32>]) -> CasterCheck {
    let mut out = CasterCheck::default();
    for (c, needed) in needs.needed.iter().enumerate() {
        let drawn_c = drawn.get(c).map_or(&[][..], Vec::as_slice);
        let is_drawn = |i: usize| drawn_c.binary_search(&(i as u32)).is_ok();
        out.needed += needed.iter().filter(|&&n| n).count();
        out.drawn += drawn_c.len();
        out.false_positives += drawn_c
            .iter()
            .filter(|&&i| !needed.get(i as usize).copied().unwrap_or(false))
            .count();
        out.needed_culled += (0..needed.len())
            .filter(|&i| needed[i] && !is_drawn(i))
            .count();
        if let Some(diff) = needs.needed_where_differing.get(c) {
            out.false_negatives += (0..diff.len()).filter(|&i| diff[i] && !is_drawn(i)).count();
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_frame_check_counts_needed_drawn_waste_and_misses_per_cascade() {
        let needs = CasterNeeds {
            // Cascade 0 needs casters 0 and 2; cascade 1 needs 1.
            needed: vec![vec![true, false, true], vec![false, true, false]],
            // Where the image differs, caster 2 could have cast (cascade 0).
            needed_where_differing: vec![vec![false, false, true], vec![false; 3]],
        };
        // Cascade 0 drew 0 and 1 (1 not needed), missed 2; cascade 1 drew 1.
        let c = check(&needs, &[vec![0, 1], vec![1]]);
        assert_eq!(
            c,
            CasterCheck {
                needed: 3,
                drawn: 3,
                false_positives: 1,
                false_negatives: 1,
                needed_culled: 1,
            }
        );
        // Every caster drawn: no false negative whatever differs.
        let all = check(&needs, &[vec![0, 1, 2], vec![0, 1, 2]]);
        assert_eq!((all.false_negatives, all.needed_culled), (0, 0));
        assert_eq!(all.false_positives, 3);
    }

    #[test]
    fn a_pixel_ray_meets_its_triangle_plane() {
        let (o, d) = (DVec3::ZERO, DVec3::new(0.0, 0.0, 2.0));
        let t = plane_hit(
            o,
            d,
            DVec3::new(-1.0, -1.0, 5.0),
            DVec3::new(1.0, -1.0, 5.0),
            DVec3::new(0.0, 1.0, 5.0),
        );
        assert_eq!(t, Some(2.5));
        // Along the plane: no point.
        let along = DVec3::new(1.0, 0.0, 0.0);
        let z0 = [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
        ];
        assert_eq!(
            plane_hit(DVec3::new(0.0, 0.0, 1.0), along, z0[0], z0[1], z0[2]),
            None
        );
    }
}
