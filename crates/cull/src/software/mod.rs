//! Software occlusion culling (seed 002): known occluders rasterized on the CPU into a
//! low-resolution depth buffer, boxes tested against it — in the frame that draws them, no GPU
//! work, no readback, no latency.
//!
//! **Conservative at the frame's own pixels.** The buffer is a grid of tiles (the resolution
//! knob: 256x128 tiles over a 1920x1080 frame are 8x9-pixel tiles). Coverage is kept per pixel
//! centre of the frame, as bit masks, and depth per tile, so a tile's depth is a bound on every
//! pixel the GPU will shade there:
//!
//! - A pixel centre counts as covered by a triangle only when it lies inside every edge by a
//!   margin that covers the distance between this rasterizer's vertex snapping (1/256 px) and
//!   any GPU's (`subpixel_bits`, 4 at least by the Vulkan spec), so the GPU covers it too. Only
//!   triangles the GPU draws count: front-facing by Vulkan's area rule with a facing the
//!   snapping cannot flip (or any facing, double-sided), every vertex inside the near and far
//!   planes and a guard band.
//! - Where two triangles of one occluder share a manifold edge and lie on its two sides on
//!   screen, a pixel near that edge is covered by one of them on the GPU whichever way its
//!   snapping decides: it counts when it is inside both triangles' *other* edges by the margin,
//!   at the farther of the two depths. That is what makes a tile full where a box's two faces
//!   meet, or across a quad's diagonal.
//! - Depth: the triangle's plane at the tile's farthest covered corner, plus a bound on how far
//!   the GPU's snapped plane can differ, clamped to the triangle's farthest vertex; then moved
//!   64 f32 steps farther (the GPU's own f32 arithmetic) and, for D16, to the code on the far
//!   side. A box's nearest depth goes the other way ([`DepthFormat::toward_near`]).
//! - A tile keeps a *full* layer (a depth every pixel of it is in front of) and a *working*
//!   layer (a mask and the farthest depth of what is in it) in the manner of Intel's Masked
//!   Occlusion Culling; when the working layer's mask fills the tile, its depth becomes the
//!   full layer's if nearer. A box is occluded only when its nearest depth is strictly behind
//!   the full layer of every tile its pixel rectangle touches (the working layer's depth, when
//!   the mask holds every pixel of the rectangle in that tile).
//!
//! The masks are computed by [`Kernel`]: a scalar reference and SIMD paths (SSE2, NEON) equal to
//! it bit for bit. Tile rows are split among threads (each band sees every triangle in the same
//! order, so the result does not depend on the thread count).

mod kernel;
mod mesh;
mod raster;

use glam::{DMat3, DMat4, DVec3};
use tilegraph_types::round::{f64_to_f32_round_up, floor_f64};

pub use kernel::Kernel;
pub use mesh::OccluderMesh;

use crate::depth::{dequantize_d16, DepthConvention, DepthFormat, D16_MAX_CODE};
use crate::project::ScreenProjection;
use crate::screen::{Extent2d, ExtentExt};
use crate::CullError;
use kernel::{low_bits, SUB};
use raster::Tri;

/// The most pixels a tile spans in either direction (a row of a tile is one `u32` mask).
pub const MAX_TILE_PX: u32 = 32;

/// How the rasterizer is set up.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SoftwareConfig {
    /// Tiles across and down: the depth buffer's resolution. A tile spans
    /// `ceil(frame / resolution)` pixels (at most [`MAX_TILE_PX`], so a coarser request gets
    /// more tiles).
    pub resolution: (u32, u32),
    /// The GPU's viewport subpixel precision (`VkPhysicalDeviceLimits::subPixelPrecisionBits`;
    /// the spec's minimum, 4, when unknown): sets the snapping margin.
    pub subpixel_bits: u32,
    /// Threads that rasterize bands of tile rows (1: the caller's thread only).
    pub threads: usize,
    /// Triangles a rasterization takes from which it starts the threads (a small batch is not
    /// worth their start): 2048 by default; tests set 0 to run every batch on them.
    pub parallel_triangles: usize,
    pub kernel: Kernel,
}

impl Default for SoftwareConfig {
    fn default() -> Self {
        SoftwareConfig {
            resolution: (256, 128),
            subpixel_bits: 4,
            threads: 1,
            parallel_triangles: 2048,
            kernel: Kernel::Simd,
        }
    }
}

/// The frame the occluders are rasterized for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OcclusionView {
    /// Clip space from positions relative to the eye (projection * camera-relative view), f64.
    pub clip_from_relative: DMat4,
    pub extent: Extent2d,
    pub convention: DepthConvention,
    pub format: DepthFormat,
}

/// What one frame's rasterization did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SoftwareStats {
    pub occluders: u32,
    pub triangles: u32,
    /// Triangles the GPU draws and this rasterizer took (front-facing, inside the clip volume).
    pub rasterized: u32,
    /// Tiles with a full layer after [`SoftwareOcclusion::rasterize`].
    pub full_tiles: u32,
    pub tiles: u32,
}

/// A tile's layers: keys grow with distance (the depth for the standard convention, its
/// negation for reverse-Z), `+inf` where nothing is known.
#[derive(Clone, Debug, Default)]
struct Tiles {
    full: Vec<f32>,
    work: Vec<f32>,
    /// `tile_h` row masks per tile: the working layer's pixels where its key is above -inf,
    /// stale (never read) where it is -inf.
    masks: Vec<u32>,
    /// Per block of `BLOCK x BLOCK` tiles, the farthest full-layer key: a box behind it is
    /// behind every tile of the block (box tests skip them). Updated by each rasterization.
    blocks: Vec<f32>,
}

/// Tiles on a side of a block of [`Tiles::blocks`].
const BLOCK: u32 = 8;

/// The software occlusion buffer of one view. Reused frame after frame without allocating once
/// its buffers have grown.
#[derive(Clone, Debug)]
pub struct SoftwareOcclusion {
    config: SoftwareConfig,
    view: Option<OcclusionView>,
    tile_w: u32,
    tile_h: u32,
    tiles_x: u32,
    tiles_y: u32,
    /// The snapping margin: how far (subpixel units, per coordinate) the GPU's vertex may lie
    /// from this rasterizer's.
    delta: f64,
    tiles: Tiles,
    tris: Vec<Tri>,
    /// `tris[..rasterized]` are in the tiles.
    rasterized: usize,
    verts: Vec<raster::Vert>,
    stats: SoftwareStats,
}

impl SoftwareOcclusion {
    pub fn new(config: SoftwareConfig) -> Self {
        SoftwareOcclusion {
            config,
            view: None,
            tile_w: 1,
            tile_h: 1,
            tiles_x: 0,
            tiles_y: 0,
            delta: 0.0,
            tiles: Tiles::default(),
            tris: Vec::new(),
            rasterized: 0,
            verts: Vec::new(),
            stats: SoftwareStats::default(),
        }
    }

    pub fn config(&self) -> SoftwareConfig {
        self.config
    }

    pub fn set_config(&mut self, config: SoftwareConfig) {
        self.config = config;
    }

    /// Starts a frame: an empty buffer for `view`.
    pub fn begin(&mut self, view: OcclusionView) -> Result<(), CullError> {
        view.extent.validate("software occlusion extent")?;
        crate::check::finite_mat4("clip_from_relative", &view.clip_from_relative.as_mat4())?;
        let (rx, ry) = self.config.resolution;
        let (w, h) = (view.extent.width_px, view.extent.height_px);
        self.tile_w = w.div_ceil(rx.max(1)).clamp(1, MAX_TILE_PX);
        self.tile_h = h.div_ceil(ry.max(1)).clamp(1, MAX_TILE_PX);
        self.tiles_x = w.div_ceil(self.tile_w);
        self.tiles_y = h.div_ceil(self.tile_h);
        // Ours rounds to the nearest 1/256 px (half a unit), the GPU's to the nearest of its
        // grid, and both compute positions in floating point (a few thousandths of a pixel
        // apart at the guard band's edge): 4 units of slack.
        let bits = self.config.subpixel_bits.clamp(1, 8);
        self.delta = 0.5 + SUB / f64::from(1u32 << (bits + 1)) + 4.0;
        let n = (self.tiles_x * self.tiles_y) as usize;
        self.tiles.full.clear();
        self.tiles.full.resize(n, f32::INFINITY);
        self.tiles.work.clear();
        self.tiles.work.resize(n, f32::NEG_INFINITY);
        // Masks are read only where the working layer holds a key: no clearing per frame.
        self.tiles.masks.resize(n * self.tile_h as usize, 0);
        let blocks = self.tiles_x.div_ceil(BLOCK) * self.tiles_y.div_ceil(BLOCK);
        self.tiles.blocks.clear();
        self.tiles.blocks.resize(blocks as usize, f32::INFINITY);
        self.tris.clear();
        self.rasterized = 0;
        self.stats = SoftwareStats {
            tiles: n as u32,
            ..SoftwareStats::default()
        };
        self.view = Some(view);
        Ok(())
    }

    /// Adds an occluder: `mesh` placed by `linear` and `offset` (its translation minus the eye,
    /// computed in f64 by the caller). Triangles are set up now and rasterized by the next
    /// [`SoftwareOcclusion::rasterize`], in the order they were added (nearest first rasterizes
    /// best). Ignored before [`SoftwareOcclusion::begin`].
    pub fn add_occluder(&mut self, mesh: &OccluderMesh, linear: DMat3, offset: DVec3) {
        let Some(view) = self.view else {
            return;
        };
        self.stats.occluders += 1;
        self.stats.triangles += mesh.triangles.len() as u32;
        let frame = raster::Frame {
            view: &view,
            delta: self.delta,
        };
        raster::project_vertices(&frame, mesh, linear, offset, &mut self.verts);
        self.stats.rasterized += raster::setup(&frame, mesh, &self.verts, &mut self.tris);
    }

    /// Rasterizes the triangles added since the last call into the tiles. Between calls the
    /// buffer can already test boxes: an occluder whose box it hides adds nothing nearer, and a
    /// caller adding occluders nearest first skips it (what `tilegraph_passes` does). The result
    /// depends on where the calls fall, never on the thread count.
    pub fn rasterize(&mut self) {
        let Some(view) = self.view else {
            return;
        };
        let grid = raster::Grid {
            tile_w: self.tile_w,
            tile_h: self.tile_h,
            tiles_x: self.tiles_x,
            extent: view.extent,
            kernel: self.config.kernel,
        };
        // A small batch is not worth the threads' start.
        let threads = if self.tris.len() - self.rasterized < self.config.parallel_triangles {
            1
        } else {
            self.config.threads.max(1)
        };
        let rows_per_band = self.tiles_y.div_ceil(threads as u32).max(1) as usize;
        let (tx, th) = (self.tiles_x as usize, self.tile_h as usize);
        let Tiles {
            full, work, masks, ..
        } = &mut self.tiles;
        let bands = full
            .chunks_mut(rows_per_band * tx)
            .zip(work.chunks_mut(rows_per_band * tx))
            .zip(masks.chunks_mut(rows_per_band * tx * th))
            .enumerate();
        let (tris, start) = (&self.tris, self.rasterized);
        self.rasterized = tris.len();
        if start == tris.len() {
            return;
        }
        let bands = bands.map(|(b, ((full, work), masks))| raster::Band {
            first_row: (b * rows_per_band) as u32,
            full,
            work,
            masks,
        });
        if threads <= 1 || self.tiles_y as usize <= rows_per_band {
            for band in bands {
                raster::band(&grid, tris, start, band, &view);
            }
        } else {
            std::thread::scope(|s| {
                for band in bands {
                    let (grid, view) = (&grid, &view);
                    s.spawn(move || raster::band(grid, tris, start, band, view));
                }
            });
        }
        self.update_blocks();
    }

    pub fn stats(&self) -> SoftwareStats {
        SoftwareStats {
            full_tiles: self.tiles.full.iter().filter(|k| k.is_finite()).count() as u32,
            ..self.stats
        }
    }

    /// The full layer's keys, row-major over `tiles()` (tests compare kernels with it).
    pub fn full_layer(&self) -> &[f32] {
        &self.tiles.full
    }

    /// The working layer: keys and row masks (a tile's masks mean nothing where its key is
    /// -inf: an emptied layer keeps its stale masks).
    pub fn working_layer(&self) -> (&[f32], &[u32]) {
        (&self.tiles.work, &self.tiles.masks)
    }

    /// Tiles across and down, and the pixels a tile spans.
    pub fn tiles(&self) -> ((u32, u32), (u32, u32)) {
        ((self.tiles_x, self.tiles_y), (self.tile_w, self.tile_h))
    }

    /// A bound on the depth of whatever the GPU draws at pixel `(x, y)` after the occluders:
    /// the tile's full layer, or its working layer where the pixel is in its mask (as a depth
    /// in the view's convention; `None` where nothing is known). For tests and tools.
    pub fn pixel_bound(&self, x: u32, y: u32) -> Option<f32> {
        let view = self.view?;
        let (t, r, bit) = self.locate(x, y)?;
        let mut key = *self.tiles.full.get(t)?;
        let mask = *self.tiles.masks.get(t * self.tile_h as usize + r)?;
        let work = *self.tiles.work.get(t)?;
        if work > f32::NEG_INFINITY && mask & bit != 0 {
            key = key.min(work);
        }
        key.is_finite().then(|| match view.convention {
            DepthConvention::Standard => key,
            DepthConvention::Reverse => -key,
        })
    }

    fn locate(&self, x: u32, y: u32) -> Option<(usize, usize, u32)> {
        let view = self.view?;
        if x >= view.extent.width_px || y >= view.extent.height_px {
            return None;
        }
        let (tx, ty) = (x / self.tile_w, y / self.tile_h);
        let t = (ty * self.tiles_x + tx) as usize;
        Some((t, (y % self.tile_h) as usize, 1 << (x % self.tile_w)))
    }

    /// Whether the occluders hide everything a volume projected to `projection` can draw:
    /// its nearest depth strictly behind the bound of every tile its pixel rectangle touches.
    /// A volume that draws no pixel centre at all counts as hidden; one touching the near plane
    /// or holding the eye never does.
    pub fn is_occluded(&self, projection: &ScreenProjection) -> bool {
        let (Some(view), ScreenProjection::Projected(b)) = (self.view, projection) else {
            return false;
        };
        let Ok(rect) = b.rect_ndc.to_pixel_rect(view.extent) else {
            return false;
        };
        let near = view.format.toward_near(view.convention, b.nearest_depth);
        let key = match view.convention {
            DepthConvention::Standard => near,
            DepthConvention::Reverse => -near,
        };
        self.hides(&BoxRect {
            min: (i64::from(rect.min_x), i64::from(rect.min_y)),
            max: (i64::from(rect.max_x), i64::from(rect.max_y)),
            near_key: key,
        })
    }

    /// A box (centre relative to the eye, half extents; f64) as the buffer tests it: the pixels
    /// whose square its projection overlaps and its nearest depth, moved toward the eye by more
    /// than the GPU's f32 arithmetic can err; `None` when part of it is nearer than the near
    /// plane (or behind the eye), which no occluder can hide. The fast path of
    /// [`SoftwareOcclusion::is_occluded`] for a frame's thousands of boxes.
    pub fn project_box(&self, center: DVec3, half: DVec3) -> Option<BoxRect> {
        let view = self.view?;
        let m = view.clip_from_relative;
        let c = m * center.extend(1.0);
        let axes = [m.x_axis * half.x, m.y_axis * half.y, m.z_axis * half.z];
        // Each clip coordinate's range over the box: centre +- the axes' absolute sums.
        let e = axes[0].abs() + axes[1].abs() + axes[2].abs();
        let (w_lo, w_hi) = (c.w - e.w, c.w + e.w);
        // (A w so small that its reciprocal overflows counts as crossing the near plane.)
        if !(w_lo >= f64::MIN_POSITIVE && c.z - e.z >= 0.0 && c.is_finite() && e.is_finite()) {
            return None;
        }
        // x / w over x in [x_lo, x_hi], w in [w_lo, w_hi] (w > 0): its extremes are at the
        // interval's corners. A superset of the 8 corners' rectangle, for 2 divisions (the
        // reciprocals' rounding, 2^-52 relative, is far inside the rectangle's 1/1000 pixel).
        let (inv_lo, inv_hi) = (1.0 / w_lo, 1.0 / w_hi);
        let range = |lo: f64, hi: f64| {
            let q = [lo * inv_lo, lo * inv_hi, hi * inv_lo, hi * inv_hi];
            (q[0].min(q[1]).min(q[2]), q[1].max(q[2]).max(q[3]).max(q[0]))
        };
        let (x0, x1) = range(c.x - e.x, c.x + e.x);
        let (y0, y1) = range(c.y - e.y, c.y + e.y);
        let (w, h) = (
            f64::from(view.extent.width_px),
            f64::from(view.extent.height_px),
        );
        let lo = ((x0 + 1.0) * 0.5 * w, (y0 + 1.0) * 0.5 * h);
        let hi = ((x1 + 1.0) * 0.5 * w, (y1 + 1.0) * 0.5 * h);
        // The nearest depth: perspective depth follows the view distance, w, so it is the
        // depth of the corner of least w; orthographic depth is z's extreme on the eye's side.
        let near = if e.w == 0.0 {
            match view.convention {
                DepthConvention::Standard => (c.z - e.z) / c.w,
                DepthConvention::Reverse => -(c.z + e.z) / c.w,
            }
        } else {
            let toward = |a: glam::DVec4| if a.w > 0.0 { -a } else { a };
            let p = c + toward(axes[0]) + toward(axes[1]) + toward(axes[2]);
            let d = p.z / p.w;
            match view.convention {
                DepthConvention::Standard => d,
                DepthConvention::Reverse => -d,
            }
        };
        // A thousandth of a pixel outward (the rect's own rounding); 2^-20 of the depth and
        // 2^-22 more nearer (the GPU's f32 depth of the box's object: an orthographic depth
        // cancels to an absolute error), then the format's code on the near side.
        let px = |v: f64| floor_f64(v.clamp(-1e12, 1e12)) as i64;
        let near = near - near.abs() * f64::from(2.0f32.powi(-20)) - f64::from(2.0f32.powi(-22));
        let near = tilegraph_types::round::f64_to_f32_round_down(near);
        let depth = match view.convention {
            DepthConvention::Standard => near,
            DepthConvention::Reverse => -near,
        };
        let depth = view.format.toward_near(view.convention, depth);
        Some(BoxRect {
            min: (px(lo.0 - 1e-3), px(lo.1 - 1e-3)),
            max: (px(hi.0 + 1e-3), px(hi.1 + 1e-3)),
            near_key: match view.convention {
                DepthConvention::Standard => depth,
                DepthConvention::Reverse => -depth,
            },
        })
    }

    /// Whether the occluders hide everything in `rect` at its nearest depth or behind: its
    /// key strictly behind the bound of every tile the rectangle touches (the working layer's,
    /// where its mask holds every pixel of the rectangle in that tile). A rectangle wholly off
    /// screen covers no pixel centre, so it counts as hidden.
    pub fn hides(&self, rect: &BoxRect) -> bool {
        let Some(view) = self.view else {
            return false;
        };
        let (w, h) = (
            i64::from(view.extent.width_px),
            i64::from(view.extent.height_px),
        );
        if rect.max.0 < 0 || rect.max.1 < 0 || rect.min.0 >= w || rect.min.1 >= h {
            return true;
        }
        let clamp = |v: i64, n: i64| v.clamp(0, n - 1) as u32;
        let (min_x, max_x) = (clamp(rect.min.0, w), clamp(rect.max.0, w));
        let (min_y, max_y) = (clamp(rect.min.1, h), clamp(rect.max.1, h));
        let key = rect.near_key;
        let (tw, th) = (self.tile_w, self.tile_h);
        let (tx0, tx1, ty0, ty1) = (min_x / tw, max_x / tw, min_y / th, max_y / th);
        let blocks_x = self.tiles_x.div_ceil(BLOCK);
        for by in ty0 / BLOCK..=ty1 / BLOCK {
            for bx in tx0 / BLOCK..=tx1 / BLOCK {
                // Behind the block's farthest full layer: behind every tile of it.
                let farthest = self.tiles.blocks.get((by * blocks_x + bx) as usize);
                if farthest.is_some_and(|&f| key > f) {
                    continue;
                }
                for ty in (by * BLOCK).max(ty0)..=(by * BLOCK + BLOCK - 1).min(ty1) {
                    for tx in (bx * BLOCK).max(tx0)..=(bx * BLOCK + BLOCK - 1).min(tx1) {
                        if !self.tile_hides(tx, ty, (min_x, min_y), (max_x, max_y), key) {
                            return false;
                        }
                    }
                }
            }
        }
        true
    }

    /// Whether tile `(tx, ty)` hides the part of the pixel rectangle `min..=max` in it at `key`.
    fn tile_hides(&self, tx: u32, ty: u32, min: (u32, u32), max: (u32, u32), key: f32) -> bool {
        let (tw, th) = (self.tile_w, self.tile_h);
        let t = (ty * self.tiles_x + tx) as usize;
        let full = self.tiles.full.get(t).copied().unwrap_or(f32::INFINITY);
        if key > full {
            return true;
        }
        // Keys are never NaN. An empty working layer (-inf; its masks are stale) holds no
        // pixel.
        let work = self.tiles.work.get(t).copied().unwrap_or(f32::INFINITY);
        if key <= work || work == f32::NEG_INFINITY {
            return false;
        }
        // The working layer decides where it holds every pixel of the rectangle here.
        let x0 = min.0.max(tx * tw) - tx * tw;
        let x1 = max.0.min(tx * tw + tw - 1) - tx * tw;
        let cols = low_bits(x1 + 1) & !low_bits(x0);
        let y0 = min.1.max(ty * th) - ty * th;
        let y1 = max.1.min(ty * th + th - 1) - ty * th;
        let base = t * th as usize;
        (y0..=y1).all(|r| {
            let m = self
                .tiles
                .masks
                .get(base + r as usize)
                .copied()
                .unwrap_or(0);
            cols & !m == 0
        })
    }

    /// Each block's farthest full-layer key, after rasterizing.
    fn update_blocks(&mut self) {
        let blocks_x = self.tiles_x.div_ceil(BLOCK) as usize;
        let Tiles { full, blocks, .. } = &mut self.tiles;
        blocks.fill(f32::NEG_INFINITY);
        for (ty, row) in full.chunks(self.tiles_x.max(1) as usize).enumerate() {
            let base = ty / BLOCK as usize * blocks_x;
            for (bx, keys) in row.chunks(BLOCK as usize).enumerate() {
                if let Some(b) = blocks.get_mut(base + bx) {
                    *b = keys.iter().fold(*b, |m, &k| m.max(k));
                }
            }
        }
    }
}

/// A box as the buffer tests it ([`SoftwareOcclusion::project_box`]): the inclusive pixel
/// rectangle its projection overlaps (possibly past the screen) and its nearest depth's key
/// (the depth for the standard convention, its negation for reverse-Z; already on the near
/// side of what the attachment can hold).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoxRect {
    pub min: (i64, i64),
    pub max: (i64, i64),
    pub near_key: f32,
}

impl BoxRect {
    /// Pixels the rectangle spans on a screen of `width x height`.
    pub fn area_on(&self, width: u32, height: u32) -> u64 {
        let span =
            |lo: i64, hi: i64, n: u32| (hi.min(i64::from(n) - 1) - lo.max(0) + 1).max(0) as u64;
        span(self.min.0, self.max.0, width) * span(self.min.1, self.max.1, height)
    }
}

/// `k` (a key: larger is farther) as the f32 key of a depth the GPU's fragment can not lie
/// behind: 64 f32 steps of the value and 2^-22 farther (the GPU's f32 arithmetic, absolute where
/// an orthographic depth cancels), rounded up, and for D16 the code on the far side.
#[inline]
fn far_key(view: &OcclusionView, k: f64) -> f32 {
    let k = k + k.abs() * (1.0 / 262_144.0) + 1.0 / 4_194_304.0; // 2^-18, 2^-22
    match view.format {
        DepthFormat::D32Float => f64_to_f32_round_up(k),
        DepthFormat::D16Unorm => {
            let max = f64::from(D16_MAX_CODE);
            let code = match view.convention {
                DepthConvention::Standard => (k.clamp(0.0, 1.0) * max).ceil(),
                DepthConvention::Reverse => ((-k).clamp(0.0, 1.0) * max).floor(),
            };
            let d = dequantize_d16(code as u16);
            match view.convention {
                DepthConvention::Standard => d,
                DepthConvention::Reverse => -d,
            }
        }
    }
}
