//! Triangle setup and the tile loop of [`super::SoftwareOcclusion`].

use glam::{DMat3, DVec3};
use tilegraph_types::round::{ceil_f64, floor_f64};

use super::kernel::{edge_rows, low_bits, Edge, Kernel, SUB};
use super::mesh::{OccluderMesh, NONE};
use super::{OcclusionView, MAX_TILE_PX};
use crate::depth::DepthConvention;
use crate::screen::Extent2d;

/// Pixels past the viewport a vertex may lie and still be taken (the GPU clips beyond its own
/// guard band; here a triangle reaching farther is left out, which only loses occlusion). Keeps
/// every edge-function value an exact integer in f64: coordinates stay below 2^23 units.
const GUARD_PX: f64 = 8192.0;

/// A vertex in subpixel units (integers) and its depth key, or `None` where the GPU would
/// clip it (behind the near plane, past the far plane, outside the guard band).
pub(crate) type Vert = Option<(f64, f64, f64)>;

pub(crate) struct Frame<'a> {
    pub view: &'a OcclusionView,
    pub delta: f64,
}

/// A triangle ready to rasterize.
#[derive(Clone, Debug)]
pub(crate) struct Tri {
    /// Edge `i` runs from oriented vertex `i` to `i + 1`; positive inside.
    edges: [Edge; 3],
    /// Welded vertex ids in that order (the mesh's serial number in the high bits, so ids of
    /// different occluders never match).
    ids: [u64; 3],
    /// Across edge `i`: the triangle (index into the frame's list) and its edge that runs the
    /// other way, when both are drawn and lie on the two sides of it.
    across: [(u32, u8); 3],
    /// Inclusive pixel rectangle of the centres it can cover, on screen.
    px: [u32; 4],
    /// Its vertices (subpixel units), for its extent in each row of tiles.
    verts: [(f64, f64); 3],
    /// The depth key's plane `k = k0 + gx (X - x0) + gy (Y - y0)`, the GPU's possible
    /// difference from it, and the farthest vertex key.
    origin: (f64, f64),
    k0: f64,
    gx: f64,
    gy: f64,
    plane_margin: f64,
    kmax: f64,
    drawn: bool,
}

/// Projects the mesh's welded vertices.
pub(crate) fn project_vertices(
    frame: &Frame<'_>,
    mesh: &OccluderMesh,
    linear: DMat3,
    offset: DVec3,
    out: &mut Vec<Vert>,
) {
    let view = frame.view;
    let (w, h) = (
        f64::from(view.extent.width_px),
        f64::from(view.extent.height_px),
    );
    out.clear();
    out.extend(mesh.positions.iter().map(|p| {
        let rel = linear * p.as_dvec3() + offset;
        let c = view.clip_from_relative * rel.extend(1.0);
        if !(c.w > 0.0 && c.z >= 0.0 && c.z <= c.w && c.is_finite()) {
            return None;
        }
        let x = (c.x / c.w + 1.0) * 0.5 * w;
        let y = (c.y / c.w + 1.0) * 0.5 * h;
        if !(-GUARD_PX..=w + GUARD_PX).contains(&x) || !(-GUARD_PX..=h + GUARD_PX).contains(&y) {
            return None;
        }
        let d = c.z / c.w;
        let key = match view.convention {
            DepthConvention::Standard => d,
            DepthConvention::Reverse => -d,
        };
        Some(((x * SUB).round(), (y * SUB).round(), key))
    }));
}

/// Sets up the mesh's triangles after those already in `tris`; returns how many the GPU draws.
pub(crate) fn setup(
    frame: &Frame<'_>,
    mesh: &OccluderMesh,
    verts: &[Vert],
    tris: &mut Vec<Tri>,
) -> u32 {
    let base = tris.len() as u32;
    let serial = u64::from(base) << 32;
    let mut drawn = 0;
    for (t, tri) in mesh.triangles.iter().enumerate() {
        let nb = mesh.neighbours.get(t).copied().unwrap_or([NONE; 3]);
        let v = tri.map(|i| verts.get(i as usize).copied().flatten());
        let made = match v {
            [Some(a), Some(b), Some(c)] => triangle(frame, mesh.double_sided, [a, b, c]),
            _ => None,
        };
        let Some((mut tri_out, swapped)) = made else {
            tris.push(Tri::skipped());
            continue;
        };
        // Oriented edge i joins oriented vertices i and i + 1; with v1 and v2 swapped, oriented
        // edge 0 is the mesh's edge 2, 1 is 1 and 2 is 0.
        let order = if swapped { [0, 2, 1] } else { [0, 1, 2] };
        tri_out.ids = order.map(|k| serial | u64::from(tri[k]));
        let edge_of = if swapped { [2, 1, 0] } else { [0, 1, 2] };
        for i in 0..3 {
            let n = nb[edge_of[i]];
            tri_out.across[i] = if n == NONE { (NONE, 0) } else { (base + n, 0) };
        }
        drawn += 1;
        tris.push(tri_out);
    }
    // Across each edge: the neighbour must be drawn and run the edge the other way (the two lie
    // on its two sides); otherwise the edge is a boundary.
    let new = base as usize..tris.len();
    for t in new.clone() {
        for i in 0..3 {
            let (n, _) = tris[t].across[i];
            let (a, b) = (tris[t].ids[i], tris[t].ids[(i + 1) % 3]);
            let found = tris
                .get(n as usize)
                .filter(|o| o.drawn)
                .and_then(|o| (0..3).find(|&j| o.ids[j] == b && o.ids[(j + 1) % 3] == a));
            tris[t].across[i] = match found {
                Some(j) => (n, j as u8),
                None => (NONE, 0),
            };
        }
    }
    drawn
}

impl Tri {
    fn skipped() -> Tri {
        let e = Edge {
            a: 0.0,
            b: 0.0,
            c: -1.0,
            margin: 0.0,
        };
        Tri {
            edges: [e; 3],
            ids: [u64::MAX; 3],
            across: [(NONE, 0); 3],
            px: [1, 1, 0, 0],
            verts: [(0.0, 0.0); 3],
            origin: (0.0, 0.0),
            k0: 0.0,
            gx: 0.0,
            gy: 0.0,
            plane_margin: 0.0,
            kmax: 0.0,
            drawn: false,
        }
    }

    /// The pixel columns whose centres the triangle can reach between the rows at subpixel
    /// heights `y0..=y1` (a triangle is convex: its extent there is that of its vertices and
    /// edge crossings inside the band), widened by a pixel; `None` when it misses the band.
    fn columns(&self, y0: f64, y1: f64) -> Option<(u32, u32)> {
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for (i, &(x, y)) in self.verts.iter().enumerate() {
            if (y0..=y1).contains(&y) {
                lo = lo.min(x);
                hi = hi.max(x);
            }
            let (qx, qy) = self.verts[(i + 1) % 3];
            for h in [y0, y1] {
                if (y - h) * (qy - h) <= 0.0 && y != qy {
                    let at = x + (h - y) * (qx - x) / (qy - y);
                    lo = lo.min(at);
                    hi = hi.max(at);
                }
            }
        }
        if lo > hi {
            return None;
        }
        let [px0, _, px1, _] = self.px;
        let first = (floor_f64((lo - 128.0) / SUB) - 1.0).max(f64::from(px0));
        let last = (ceil_f64((hi - 128.0) / SUB) + 1.0).min(f64::from(px1));
        (first <= last).then_some((first as u32, last as u32))
    }

    /// The farthest key the GPU can store for this triangle over the pixel centres
    /// `[x0, x1] x [y0, y1]` (subpixel units).
    fn depth_over(&self, x0: f64, y0: f64, x1: f64, y1: f64) -> f64 {
        let x = if self.gx > 0.0 { x1 } else { x0 };
        let y = if self.gy > 0.0 { y1 } else { y0 };
        let plane = self.k0 + self.gx * (x - self.origin.0) + self.gy * (y - self.origin.1);
        (plane + self.plane_margin).min(self.kmax)
    }
}

/// One triangle's setup, and whether its second and third vertices were swapped to make it
/// counter-clockwise in the edge functions' sense. `None` when the GPU does not draw it (back
/// face, zero area, a facing the snapping could flip) or it covers no pixel centre.
fn triangle(frame: &Frame<'_>, double_sided: bool, v: [(f64, f64, f64); 3]) -> Option<(Tri, bool)> {
    let (w, h) = (frame.view.extent.width_px, frame.view.extent.height_px);
    let [p0, p1, p2] = v;
    let area2 = (p1.0 - p0.0) * (p2.1 - p0.1) - (p2.0 - p0.0) * (p1.1 - p0.1);
    let min_x = p0.0.min(p1.0).min(p2.0);
    let max_x = p0.0.max(p1.0).max(p2.0);
    let min_y = p0.1.min(p1.1).min(p2.1);
    let max_y = p0.1.max(p1.1).max(p2.1);
    let span = (max_x - min_x) + (max_y - min_y);
    let delta = frame.delta;
    // Vulkan's facing: a = -area2 / 2 in framebuffer coordinates (y down); counter-clockwise
    // (the pipelines' front face) is a > 0. Moving each vertex by delta changes area2 by at
    // most about 2 delta per unit of the bounding box's half perimeter.
    let front = area2 < 0.0;
    let certain = area2.abs() > 4.0 * delta * span + 8.0 * delta * delta;
    if area2 == 0.0 || !(double_sided || (front && certain)) {
        return None;
    }
    let swapped = area2 < 0.0;
    let v = if swapped { [p0, p2, p1] } else { [p0, p1, p2] };
    // A pixel centre inside the edge by this much is inside the GPU's edge: its endpoints move by
    // at most delta per coordinate and the centre lies within the bounding box.
    let margin = 3.0 * delta * span + 4.0 * delta * delta;
    let edges = [0, 1, 2].map(|i| {
        let (a0, a1) = (v[i], v[(i + 1) % 3]);
        let a = -(a1.1 - a0.1);
        let b = a1.0 - a0.0;
        Edge {
            a,
            b,
            c: -(a * a0.0 + b * a0.1),
            margin,
        }
    });
    // Pixel centres sit at 256 p + 128.
    let first = |lo: f64| ceil_f64((lo - 128.0) / SUB).max(0.0);
    let last = |hi: f64, n: u32| floor_f64((hi - 128.0) / SUB).min(f64::from(n) - 1.0);
    let (x0, x1) = (first(min_x), last(max_x, w));
    let (y0, y1) = (first(min_y), last(max_y, h));
    if x0 > x1 || y0 > y1 {
        return None;
    }
    let [q0, q1, q2] = v;
    let det = (q1.0 - q0.0) * (q2.1 - q0.1) - (q2.0 - q0.0) * (q1.1 - q0.1);
    let (dk1, dk2) = (q1.2 - q0.2, q2.2 - q0.2);
    let gx = (dk1 * (q2.1 - q0.1) - dk2 * (q1.1 - q0.1)) / det;
    let gy = ((q1.0 - q0.0) * dk2 - (q2.0 - q0.0) * dk1) / det;
    let kmax = q0.2.max(q1.2).max(q2.2);
    let kmin = q0.2.min(q1.2).min(q2.2);
    // The GPU's snapped vertices move each barycentric coordinate by about
    // delta * perimeter / area; the key moves by that times its range.
    let plane_margin = (kmax - kmin) * (12.0 * delta * span / det.abs()).min(1.0);
    Some((
        Tri {
            edges,
            ids: [0; 3],
            across: [(NONE, 0); 3],
            px: [x0 as u32, y0 as u32, x1 as u32, y1 as u32],
            verts: [(q0.0, q0.1), (q1.0, q1.1), (q2.0, q2.1)],
            origin: (q0.0, q0.1),
            k0: q0.2,
            gx,
            gy,
            plane_margin,
            kmax,
            drawn: true,
        },
        swapped,
    ))
}

pub(crate) struct Grid {
    pub tile_w: u32,
    pub tile_h: u32,
    pub tiles_x: u32,
    pub extent: Extent2d,
    pub kernel: Kernel,
}

type Rows = [u32; MAX_TILE_PX as usize];

/// A band of tile rows one thread rasterizes: its first row and its tiles' layers.
pub(crate) struct Band<'a> {
    pub first_row: u32,
    pub full: &'a mut [f32],
    pub work: &'a mut [f32],
    pub masks: &'a mut [u32],
}

/// Rasterizes `tris[start..]` (their neighbours anywhere in `tris`) into `band`.
pub(crate) fn band(grid: &Grid, tris: &[Tri], start: usize, band: Band<'_>, view: &OcclusionView) {
    let Band {
        first_row,
        full,
        work,
        masks,
    } = band;
    let (tw, th) = (grid.tile_w, grid.tile_h);
    let rows = (full.len() as u32) / grid.tiles_x.max(1);
    let last_row = first_row + rows;
    // A triangle's coverage of one tile, and the rows it is made of (each row written before
    // it is read, so nothing is cleared per tile).
    let mut cover = [0u32; MAX_TILE_PX as usize];
    let mut scratch = Scratch::default();
    for tri in tris.iter().skip(start).filter(|t| t.drawn) {
        let [_, py0, _, py1] = tri.px;
        let ty0 = (py0 / th).max(first_row);
        let ty1 = (py1 / th).min(last_row.saturating_sub(1));
        if ty0 > ty1 || py0 / th >= last_row {
            continue;
        }
        for ty in ty0..=ty1 {
            let band_y0 = f64::from(ty * th) * SUB + 128.0;
            let band_y1 = band_y0 + f64::from(th - 1) * SUB;
            let Some((c0, c1)) = tri.columns(band_y0, band_y1) else {
                continue;
            };
            let (tx0, tx1) = (c0 / tw, c1 / tw);
            // Nothing this triangle adds to a tile can be nearer than its own bound there (the
            // farthest key it can store over the tile, below): where the tile's full layer is
            // already at or nearer than that, the coverage is not worth computing. The bound
            // grows along the row toward one end, so the row's least is that end tile's, and a
            // full layer at or nearer than it skips the tile for a compare.
            let nearest_end = Place::new(grid, if tri.gx > 0.0 { tx0 } else { tx1 }, ty);
            let row_least = super::far_key(
                view,
                tri.depth_over(
                    nearest_end.x0,
                    nearest_end.y0,
                    nearest_end.x1,
                    nearest_end.y1,
                ),
            );
            let row = ((ty - first_row) * grid.tiles_x) as usize;
            // The tiles that may take something: where the row's least depth is in front.
            let open =
                |full: &[f32], tx: u32| full.get(row + tx as usize).is_some_and(|&f| row_least < f);
            let Some(first_open) = (tx0..=tx1).find(|&tx| open(full, tx)) else {
                continue;
            };
            // Tiles inside all three edges are covered whole: no coverage to compute there.
            let whole = interior(grid, tri, first_open, tx1, ty);
            for tx in first_open..=tx1 {
                let local = row + tx as usize;
                if !open(full, tx) {
                    continue;
                }
                let tile = Place::new(grid, tx, ty);
                let own_depth = tri.depth_over(tile.x0, tile.y0, tile.x1, tile.y1);
                let own = super::far_key(view, own_depth);
                if full.get(local).is_none_or(|&f| own >= f) {
                    continue;
                }
                let found = if whole.0 <= tx && tx <= whole.1 {
                    Cover::Full
                } else {
                    coverage(grid, tris, tri, &tile, &mut cover, &mut scratch)
                };
                let far = |key: f64| {
                    if key == own_depth {
                        own
                    } else {
                        super::far_key(view, key)
                    }
                };
                let base = local * th as usize;
                let (Some(f), Some(w), Some(m)) = (
                    full.get_mut(local),
                    work.get_mut(local),
                    masks.get_mut(base..base + th as usize),
                ) else {
                    continue;
                };
                match found {
                    Cover::None => {}
                    // Every centre: at the triangle's own depth here.
                    Cover::Full => merge_full(own, f, w),
                    Cover::FullAt(key) => merge_full(far(key), f, w),
                    Cover::Rows(key) => merge(&tile, &cover, far(key), f, w, m),
                }
            }
        }
    }
}

/// The tiles of row `ty` between `tx0` and `tx1` that every edge of `tri` holds whole (as
/// [`Edge::classify`] says of each), as `(first, last)` (`first > last`: none). Found by
/// bisection: along a row, an edge's test of a tile is monotonic (it looks at the corner its
/// normal points away from, which moves one way). Short rows are left to the tile loop.
fn interior(grid: &Grid, tri: &Tri, tx0: u32, tx1: u32, ty: u32) -> (u32, u32) {
    const EMPTY: (u32, u32) = (1, 0);
    if tx1 < tx0 + 4 {
        return EMPTY;
    }
    let (mut lo, mut hi) = (tx0, tx1);
    for e in &tri.edges {
        let inside = |tx: u32| {
            let p = Place::new(grid, tx, ty);
            e.classify(p.x0, p.y0, p.x1, p.y1) == Some(true)
        };
        // The first tile in [a, b) where `pred` turns true, or b (`pred` false then true).
        let turn = |mut a: u32, mut b: u32, pred: &dyn Fn(u32) -> bool| {
            while a < b {
                let m = a + (b - a) / 2;
                if pred(m) {
                    b = m;
                } else {
                    a = m + 1;
                }
            }
            a
        };
        if e.a >= 0.0 {
            // Outside, then inside.
            lo = turn(lo, hi + 1, &inside);
        } else {
            // Inside, then outside.
            let end = turn(lo, hi + 1, &|tx| !inside(tx));
            if end == lo {
                return EMPTY;
            }
            hi = end - 1;
        }
        if lo > hi {
            return EMPTY;
        }
    }
    (lo, hi)
}

/// A tile's pixel centres: the first and last (subpixel units), its valid columns and rows.
struct Place {
    x0: f64,
    y0: f64,
    x1: f64,
    y1: f64,
    width: u32,
    rows: usize,
}

impl Place {
    fn new(grid: &Grid, tx: u32, ty: u32) -> Place {
        let (px, py) = (tx * grid.tile_w, ty * grid.tile_h);
        let width = grid.tile_w.min(grid.extent.width_px - px);
        let rows = grid.tile_h.min(grid.extent.height_px - py);
        let c = |p: u32| f64::from(p) * SUB + 128.0;
        Place {
            x0: c(px),
            y0: c(py),
            x1: c(px + width - 1),
            y1: c(py + rows - 1),
            width,
            rows: rows as usize,
        }
    }
}

/// What a triangle covers of a tile.
enum Cover {
    None,
    /// Every pixel centre, with the triangle alone (its own depth there holds).
    Full,
    /// Every pixel centre, with the triangle and a neighbour, at this farthest key.
    FullAt(f64),
    /// The rows written to `cover`, at this farthest key.
    Rows(f64),
}

/// The centres of `tile` the GPU covers with `tri` (or with a neighbour across one of its shared
/// edges): all of them, or those written into `cover` and the farthest key there.
fn coverage(
    grid: &Grid,
    tris: &[Tri],
    tri: &Tri,
    tile: &Place,
    cover: &mut Rows,
    scratch: &mut Scratch,
) -> Cover {
    let k = grid.kernel;
    let rows = tile.rows;
    let all = low_bits(tile.width);
    // The corners decide most tiles: wholly inside, or outside an edge no neighbour can
    // cover past (the pair's coverage needs this triangle's other two edges).
    let class = tri
        .edges
        .map(|e| e.classify(tile.x0, tile.y0, tile.x1, tile.y1));
    if class.iter().all(|c| *c == Some(true)) {
        return Cover::Full;
    }
    // Inside two edges, and across the third (shared) from a neighbour that holds the tile inside
    // its other two: the pair covers every centre, at the farther of their depths — what the
    // rows below would find, without computing them (a quad's diagonal through its middle).
    for i in 0..3 {
        let (b, c) = ((i + 1) % 3, (i + 2) % 3);
        let (n, j) = tri.across[i];
        if class[i].is_some() || class[b] != Some(true) || class[c] != Some(true) || n == NONE {
            continue;
        }
        let Some(other) = tris.get(n as usize) else {
            break;
        };
        let held = [(j as usize + 1) % 3, (j as usize + 2) % 3]
            .iter()
            .all(|&o| other.edges[o].classify(tile.x0, tile.y0, tile.x1, tile.y1) == Some(true));
        if held {
            return Cover::FullAt(
                tri.depth_over(tile.x0, tile.y0, tile.x1, tile.y1)
                    .max(other.depth_over(tile.x0, tile.y0, tile.x1, tile.y1)),
            );
        }
        break;
    }
    let mut outside = (0..3).filter(|&i| class[i] == Some(false));
    match (outside.next(), outside.next()) {
        (None, _) => {}
        (Some(i), None) if tri.across[i].0 != NONE => {}
        _ => return Cover::None,
    }
    // Each edge's rows (all set where the corners say so; unused where outside).
    let Scratch {
        masks,
        acc,
        other_rows,
    } = scratch;
    for (i, m) in masks.iter_mut().enumerate() {
        match class[i] {
            Some(true) => m[..rows].fill(all),
            Some(false) => m[..rows].fill(0),
            None => edge_rows(
                k,
                &tri.edges[i],
                tile.x0,
                tile.y0,
                tile.width,
                &mut m[..rows],
            ),
        }
    }
    let mut key = f64::NEG_INFINITY;
    let mut any = 0;
    for r in 0..rows {
        let c = masks[0][r] & masks[1][r] & masks[2][r];
        cover[r] = c;
        any |= c;
    }
    if any != 0 {
        key = tri.depth_over(tile.x0, tile.y0, tile.x1, tile.y1);
    }
    // Across a shared edge i: inside this triangle's other two edges and the neighbour's other
    // two, the GPU covers the centre with one of the pair.
    for i in 0..3 {
        let (n, j) = tri.across[i];
        let (b, c) = ((i + 1) % 3, (i + 2) % 3);
        if n == NONE || class[i] == Some(true) || class[b] == Some(false) || class[c] == Some(false)
        {
            continue;
        }
        let Some(other) = tris.get(n as usize) else {
            continue;
        };
        let mut any = 0;
        for r in 0..rows {
            acc[r] = masks[b][r] & masks[c][r];
            any |= acc[r];
        }
        for o in [(j as usize + 1) % 3, (j as usize + 2) % 3] {
            if any == 0 {
                break;
            }
            let e = &other.edges[o];
            match e.classify(tile.x0, tile.y0, tile.x1, tile.y1) {
                Some(true) => continue,
                Some(false) => any = 0,
                None => {
                    edge_rows(k, e, tile.x0, tile.y0, tile.width, &mut other_rows[..rows]);
                    any = 0;
                    for r in 0..rows {
                        acc[r] &= other_rows[r];
                        any |= acc[r];
                    }
                }
            }
        }
        if any == 0 {
            continue;
        }
        let mut added = 0;
        for r in 0..rows {
            added |= acc[r] & !cover[r];
            cover[r] |= acc[r];
        }
        if added != 0 {
            key = key
                .max(tri.depth_over(tile.x0, tile.y0, tile.x1, tile.y1))
                .max(other.depth_over(tile.x0, tile.y0, tile.x1, tile.y1));
        }
    }
    if key > f64::NEG_INFINITY {
        Cover::Rows(key)
    } else {
        Cover::None
    }
}

/// Rows [`coverage`] builds a tile's coverage from: each edge's, a shared edge's pair, a
/// neighbour's edge.
struct Scratch {
    masks: [Rows; 3],
    acc: Rows,
    other_rows: Rows,
}

impl Default for Scratch {
    fn default() -> Self {
        let rows = [0u32; MAX_TILE_PX as usize];
        Scratch {
            masks: [rows; 3],
            acc: rows,
            other_rows: rows,
        }
    }
}

/// Folds a triangle covering every pixel centre of a tile at `key` into its layers: as
/// [`merge`] with every row set. A working layer it empties keeps its stale masks.
fn merge_full(key: f32, full: &mut f32, work: &mut f32) {
    if key < *full {
        *full = key;
        if *work >= key {
            *work = f32::NEG_INFINITY;
        }
    }
}

/// Folds a triangle's coverage (`cover`, farthest key `key`) into a tile's layers.
fn merge(tile: &Place, cover: &Rows, key: f32, full: &mut f32, work: &mut f32, masks: &mut [u32]) {
    if key >= *full {
        return;
    }
    let all = low_bits(tile.width);
    let rows = tile.rows;
    if cover[..rows].iter().all(|&r| r == all) {
        *full = key;
        if *work >= *full {
            *work = f32::NEG_INFINITY;
        }
        return;
    }
    // An empty working layer's masks are stale.
    if *work == f32::NEG_INFINITY {
        masks.fill(0);
    }
    let mut filled = true;
    for (r, m) in masks.iter_mut().enumerate().take(rows) {
        *m |= cover[r];
        filled &= *m == all;
    }
    *work = work.max(key);
    if filled {
        *full = full.min(*work);
        *work = f32::NEG_INFINITY;
    }
}
