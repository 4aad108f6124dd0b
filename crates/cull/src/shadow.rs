//! Cascaded shadow maps of a directional light: the cascades' fitting and the planes that
//! cull shadow casters, in f64 world space (the GPU gets them camera-relative in f32).
//!
//! **Fitting** (stable, after the "sphere + texel snapping" scheme every shipped CSM uses): the
//! camera's depth range `[near, distance]` is split between a logarithmic and a uniform
//! scheme (`split_lambda`); each slice is bounded by the smallest sphere around it, which
//! depends on the slice's depths and the projection only — a camera that turns keeps its
//! cascades' size — and the sphere's centre, in light space, is snapped to whole texels, so a
//! camera that moves shifts the shadow map by whole texels and its edges do not shimmer. The
//! orthographic box is the sphere grown by the texels that sampling may reach past a receiver
//! (PCF kernel, normal offset, the snap), so every lookup of a cascade stays in its own region
//! of the atlas. Towards the light the box reaches the scene's top, so every caster above a
//! receiver is in it.
//!
//! **Caster culling** ([`CasterCulling`]): a caster is drawn into a cascade unless its box lies
//! outside one of the cascade's planes, each tested conservatively (the box's nearest corner):
//! - `Cascade`: the cascade's box — four sides and its bottom (a caster wholly below the
//!   cascade's receivers shades none of them).
//! - `Receivers`: those planes and the camera's frustum slice extruded towards the light — the
//!   slice's corners in light space, their 2D convex hull and the lowest of them — grown by
//!   what a lookup may reach (PCF, normal offset, a texel's coverage). A caster outside them
//!   darkens no texel that a pixel of the slice reads: dropping it changes no pixel.
//!
//! Both are exact in the sense the oracle checks: the image with the culled set equals the
//! image with every caster.

use glam::{DMat4, DVec2, DVec3, DVec4};
use tilegraph_types::Projection;

/// The most cascades a light has.
pub const MAX_CASCADES: usize = 4;

/// The most planes a cascade's caster culling tests (5 of the box, up to 8 hull edges, the
/// hull's 4 bounds, the receivers' bottom).
pub const MAX_CASTER_PLANES: usize = 20;

/// What culls a cascade's shadow casters.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum CasterCulling {
    /// Every caster into every cascade.
    None,
    /// The cascade's box.
    #[default]
    Cascade,
    /// The cascade's box and the camera's frustum slice extruded towards the light.
    Receivers,
    /// `Receivers`, then (on the GPU, where the frame has this frame's camera depth pyramid
    /// before its colour: two-phase culling with a pre-pass or the visibility buffer) the
    /// volume a caster's shadow can darken tested against the pyramid: a caster whose shadow
    /// falls only on what the camera cannot see is dropped (seed 004's second pass).
    ReceiversHiz,
}

impl CasterCulling {
    pub const ALL: [CasterCulling; 4] = [
        CasterCulling::None,
        CasterCulling::Cascade,
        CasterCulling::Receivers,
        CasterCulling::ReceiversHiz,
    ];

    pub const fn name(self) -> &'static str {
        match self {
            CasterCulling::None => "none",
            CasterCulling::Cascade => "cascade",
            CasterCulling::Receivers => "receivers",
            CasterCulling::ReceiversHiz => "receivers-hiz",
        }
    }

    pub fn parse(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|c| c.name() == name)
    }
}

/// How a light's cascades are fitted and sampled.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CascadeSettings {
    /// 1 to [`MAX_CASCADES`].
    pub count: u32,
    /// Texels on a side of each cascade.
    pub resolution: u32,
    /// How far from the eye receivers get shadows, in metres; 0 or less: to the farthest
    /// corner of the scene's bounds (and never past the far plane).
    pub distance: f64,
    /// The splits' blend of logarithmic (1) and uniform (0) spacing.
    pub split_lambda: f64,
    /// PCF reach either side of the lookup, in texels (1: the 3x3 texels around it, read as
    /// 2x2 bilinear compare taps).
    pub pcf_radius: u32,
    /// How far along its normal a receiver's lookup moves, in texels of its cascade.
    pub normal_offset_texels: f64,
}

impl Default for CascadeSettings {
    fn default() -> Self {
        CascadeSettings {
            count: 3,
            resolution: 1024,
            distance: 0.0,
            split_lambda: 0.75,
            pcf_radius: 1,
            normal_offset_texels: 1.5,
        }
    }
}

impl CascadeSettings {
    /// Texels between a receiver's sphere and the cascade's box edge: what PCF, the normal
    /// offset and the snap may reach.
    fn border_texels(&self) -> f64 {
        f64::from(self.pcf_radius) + 2.0 + self.normal_offset_texels + 1.0
    }
}

/// The camera the cascades cover: where it is, where it looks, its projection and aspect.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ShadowCamera {
    pub eye: DVec3,
    /// Unit view direction.
    pub forward: DVec3,
    /// The camera's up (need not be orthogonal to `forward`).
    pub up: DVec3,
    pub projection: Projection,
    /// Width / height.
    pub aspect: f64,
}

impl ShadowCamera {
    /// The four corners of the view's cross-section at distance `d`, world space.
    fn section(&self, basis: (DVec3, DVec3, DVec3), d: f64) -> [DVec3; 4] {
        let (f, up, right) = basis;
        let (hh, _) = self.half_extent(d);
        let hw = hh * self.aspect;
        let c = self.eye + f * d;
        [
            c - right * hw - up * hh,
            c + right * hw - up * hh,
            c - right * hw + up * hh,
            c + right * hw + up * hh,
        ]
    }

    /// Half the height of the section at distance `d`, and whether it grows with `d`.
    fn half_extent(&self, d: f64) -> (f64, bool) {
        match self.projection {
            Projection::Perspective { fov_y_rad, .. } => {
                ((f64::from(fov_y_rad) * 0.5).tan() * d, true)
            }
            Projection::Orthographic { half_height, .. } => (f64::from(half_height), false),
        }
    }

    /// Forward, the up orthogonal to it, and right; `None` for a degenerate camera.
    fn basis(&self) -> Option<(DVec3, DVec3, DVec3)> {
        let f = self.forward.try_normalize()?;
        let right = f.cross(self.up).try_normalize()?;
        Some((f, right.cross(f), right))
    }
}

/// The light's fixed frame: `u`, `v` across the light's view and `l` towards the light. It
/// depends on the light's direction alone, so the cascades' texel grid only moves with it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LightBasis {
    pub u: DVec3,
    pub v: DVec3,
    pub l: DVec3,
}

impl LightBasis {
    /// The basis of a light shining from `to_light` (any length); `None` for a zero or
    /// non-finite direction.
    pub fn new(to_light: DVec3) -> Option<Self> {
        let l = to_light.try_normalize()?;
        // The world axis least parallel to the light: a fixed choice per direction.
        let a = l.abs();
        let axis = if a.x <= a.y && a.x <= a.z {
            DVec3::X
        } else if a.y <= a.z {
            DVec3::Y
        } else {
            DVec3::Z
        };
        let u = axis.cross(l).normalize();
        let v = l.cross(u);
        Some(LightBasis { u, v, l })
    }

    /// `p` in light space: (u, v, height towards the light).
    pub fn to_light(&self, p: DVec3) -> DVec3 {
        DVec3::new(p.dot(self.u), p.dot(self.v), p.dot(self.l))
    }
}

/// One cascade of a frame.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Cascade {
    /// The view distances of the receivers it shades: `[near, far)`.
    pub near: f64,
    pub far: f64,
    /// World to the cascade's clip space: x, y in [-1, 1] across its box, depth 0 at its top
    /// (nearest the light) and 1 at its bottom.
    pub clip_from_world: DMat4,
    /// One texel's side, metres.
    pub texel: f64,
    /// The box in light space: centre (snapped) and half side across, top and bottom heights.
    pub center: DVec2,
    pub half: f64,
    pub top: f64,
    pub bottom: f64,
    /// The slice's eight corners (world), its depth range grown by a thousandth each way.
    pub corners: [DVec3; 8],
}

/// A frame's cascades (no allocation: a render thread fits them every frame).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Cascades {
    pub count: usize,
    pub items: [Cascade; MAX_CASCADES],
    pub basis: Option<LightBasis>,
    /// The lowest height (towards the light) of the scene's bounds: no receiver lies below.
    pub scene_floor: f64,
}

impl Cascades {
    pub fn as_slice(&self) -> &[Cascade] {
        &self.items[..self.count]
    }
}

/// Fits `settings.count` cascades of the light shining from `to_light` to `camera`, over a
/// scene within `scene_bounds` (min, max; world). No cascades when the light, the camera or
/// the bounds are degenerate, or nothing lies beyond the near plane.
pub fn fit_cascades(
    camera: &ShadowCamera,
    to_light: DVec3,
    scene_bounds: (DVec3, DVec3),
    settings: &CascadeSettings,
) -> Cascades {
    let mut out = Cascades::default();
    let (Some(basis), Some(view)) = (LightBasis::new(to_light), camera.basis()) else {
        return out;
    };
    let (lo, hi) = scene_bounds;
    if !(lo.is_finite() && hi.is_finite() && lo.cmple(hi).all() && camera.eye.is_finite()) {
        return out;
    }
    let near = f64::from(camera.projection.near()).max(1e-6);
    let corners = box_corners(lo, hi);
    let farthest = corners
        .iter()
        .map(|c| (*c - camera.eye).dot(view.0))
        .fold(0.0, f64::max);
    let mut distance = if settings.distance > 0.0 {
        settings.distance
    } else {
        farthest
    };
    if let Some(far) = camera.projection.far() {
        distance = distance.min(f64::from(far));
    }
    let count = (settings.count as usize).clamp(1, MAX_CASCADES);
    let res = f64::from(settings.resolution.max(64));
    if distance.is_nan() || distance <= near {
        return out;
    }
    let heights = corners.map(|c| basis.to_light(c).z);
    let top_of_scene = heights.iter().copied().fold(f64::MIN, f64::max);
    out.scene_floor = heights.iter().copied().fold(f64::MAX, f64::min);
    let border = settings.border_texels();
    out.basis = Some(basis);
    let mut a = near;
    for (i, cascade) in out.items.iter_mut().enumerate().take(count) {
        let t = (i + 1) as f64 / count as f64;
        let log = near * (distance / near).powf(t);
        let uniform = near + (distance - near) * t;
        let b = if i + 1 == count {
            distance
        } else {
            settings.split_lambda * log + (1.0 - settings.split_lambda) * uniform
        };
        let (c, r) = slice_sphere(camera, a, b);
        let half = r * res / (res - 2.0 * border);
        let texel = 2.0 * half / res;
        let centre = basis.to_light(camera.eye + view.0 * c);
        let snapped = DVec2::new(
            (centre.x / texel).floor() * texel,
            (centre.y / texel).floor() * texel,
        );
        let bottom = centre.z - half;
        let top = top_of_scene.max(centre.z + half);
        let mut slice = [DVec3::ZERO; 8];
        let near_section = camera.section(view, a * (1.0 - 1e-3));
        let far_section = camera.section(view, b * (1.0 + 1e-3));
        slice[..4].copy_from_slice(&near_section);
        slice[4..].copy_from_slice(&far_section);
        *cascade = Cascade {
            near: a,
            far: b,
            clip_from_world: clip_from_world(&basis, snapped, half, top, bottom),
            texel,
            center: snapped,
            half,
            top,
            bottom,
            corners: slice,
        };
        a = b;
    }
    out.count = count;
    out
}

/// The smallest sphere around the camera's slice `[a, b]`: its centre's distance along the
/// view and its radius. It depends on `a`, `b` and the projection only.
fn slice_sphere(camera: &ShadowCamera, a: f64, b: f64) -> (f64, f64) {
    let (hh_a, perspective) = camera.half_extent(a);
    let (hh_b, _) = camera.half_extent(b);
    let diag = |hh: f64| hh * (1.0 + camera.aspect * camera.aspect).sqrt();
    let (ra, rb) = (diag(hh_a), diag(hh_b));
    let c = if perspective {
        // Equidistant from the near and far corners: (c - a)^2 + ra^2 = (b - c)^2 + rb^2.
        ((b * b + rb * rb - a * a - ra * ra) / (2.0 * (b - a))).clamp(a, b)
    } else {
        0.5 * (a + b)
    };
    let r = ((c - a).powi(2) + ra * ra)
        .sqrt()
        .max(((b - c).powi(2) + rb * rb).sqrt());
    (c, r)
}

fn box_corners(lo: DVec3, hi: DVec3) -> [DVec3; 8] {
    std::array::from_fn(|i| {
        DVec3::new(
            if i & 1 == 0 { lo.x } else { hi.x },
            if i & 2 == 0 { lo.y } else { hi.y },
            if i & 4 == 0 { lo.z } else { hi.z },
        )
    })
}

fn clip_from_world(basis: &LightBasis, centre: DVec2, half: f64, top: f64, bottom: f64) -> DMat4 {
    let depth = (top - bottom).max(1e-9);
    let rows = [
        (basis.u / half).extend(-centre.x / half),
        (basis.v / half).extend(-centre.y / half),
        (-basis.l / depth).extend(top / depth),
        DVec4::W,
    ];
    DMat4::from_cols_array_2d(&[
        [rows[0].x, rows[1].x, rows[2].x, rows[3].x],
        [rows[0].y, rows[1].y, rows[2].y, rows[3].y],
        [rows[0].z, rows[1].z, rows[2].z, rows[3].z],
        [rows[0].w, rows[1].w, rows[2].w, rows[3].w],
    ])
}

/// A cascade's caster planes: a box is culled when it lies wholly on the negative side of one
/// (`n . p + d < 0` for every point; unit `n`, world space).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CasterPlanes {
    pub count: usize,
    pub planes: [DVec4; MAX_CASTER_PLANES],
}

impl CasterPlanes {
    pub fn as_slice(&self) -> &[DVec4] {
        &self.planes[..self.count]
    }

    fn push(&mut self, n: DVec3, d: f64) {
        if self.count < MAX_CASTER_PLANES {
            self.planes[self.count] = n.extend(d);
            self.count += 1;
        }
    }

    /// Whether the box at `center` with half extents `half` (world, axis-aligned) is culled:
    /// wholly outside one plane. The GPU runs the same test (`shadow_cull.comp`).
    pub fn culls(&self, center: DVec3, half: DVec3) -> bool {
        self.as_slice().iter().any(|p| {
            let n = p.truncate();
            n.dot(center) + n.abs().dot(half) + p.w < 0.0
        })
    }

    /// The planes moved to coordinates relative to `eye` (what the GPU tests).
    pub fn relative_to(&self, eye: DVec3) -> CasterPlanes {
        let mut out = *self;
        for p in &mut out.planes[..self.count] {
            p.w += p.truncate().dot(eye);
        }
        out
    }
}

/// The planes that cull `cascade`'s casters under `culling`.
pub fn caster_planes(
    cascades: &Cascades,
    index: usize,
    settings: &CascadeSettings,
    culling: CasterCulling,
) -> CasterPlanes {
    let mut out = CasterPlanes::default();
    let (Some(basis), Some(c)) = (cascades.basis, cascades.as_slice().get(index)) else {
        return out;
    };
    if culling == CasterCulling::None {
        return out;
    }
    let LightBasis { u, v, l } = basis;
    // The box: across, and its bottom.
    out.push(u, c.half - c.center.x);
    out.push(-u, c.half + c.center.x);
    out.push(v, c.half - c.center.y);
    out.push(-v, c.half + c.center.y);
    out.push(l, -c.bottom);
    if culling == CasterCulling::Cascade {
        return out;
    }
    let reach = lookup_reach(c, settings);
    let points: [DVec2; 8] = std::array::from_fn(|i| {
        let p = basis.to_light(c.corners[i]);
        DVec2::new(p.x, p.y)
    });
    let lowest = lowest_receiver(cascades, index);
    let mut hull = [DVec2::ZERO; 9];
    let n = convex_hull(&points, &mut hull);
    for i in 0..n {
        let (p, q) = (hull[i], hull[(i + 1) % n]);
        let e = q - p;
        // Counter-clockwise hull: the outward normal is the edge turned clockwise.
        let Some(outward) = DVec2::new(e.y, -e.x).try_normalize() else {
            continue;
        };
        let n3 = u * outward.x + v * outward.y;
        out.push(-n3, n3.dot(u * p.x + v * p.y) + reach);
    }
    let (lo, hi) = points.iter().fold((DVec2::MAX, DVec2::MIN), |(lo, hi), p| {
        (lo.min(*p), hi.max(*p))
    });
    out.push(u, reach - lo.x);
    out.push(-u, hi.x + reach);
    out.push(v, reach - lo.y);
    out.push(-v, hi.y + reach);
    out.push(l, reach - lowest);
    out
}

/// What a lookup may reach past a receiver in cascade `c`, metres: the PCF kernel (its taps
/// and their bilinear texels), a texel's coverage, the normal offset.
pub fn lookup_reach(c: &Cascade, settings: &CascadeSettings) -> f64 {
    let normal_offset = settings.normal_offset_texels * c.texel;
    (f64::from(settings.pcf_radius) + 3.0) * c.texel + normal_offset
}

/// The height (towards the light) below which cascade `index` has no receiver: the lowest
/// point of its slice, or of the scene where that is higher.
pub fn lowest_receiver(cascades: &Cascades, index: usize) -> f64 {
    let (Some(basis), Some(c)) = (cascades.basis, cascades.as_slice().get(index)) else {
        return f64::MAX;
    };
    c.corners
        .iter()
        .map(|p| p.dot(basis.l))
        .fold(f64::MAX, f64::min)
        .max(cascades.scene_floor)
}

/// The convex hull of `points` counter-clockwise into `out` (Andrew's monotone chain); its
/// vertex count.
fn convex_hull(points: &[DVec2; 8], out: &mut [DVec2; 9]) -> usize {
    let mut p = *points;
    p.sort_unstable_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    let cross = |o: DVec2, a: DVec2, b: DVec2| (a - o).perp_dot(b - o);
    let mut k = 0;
    for &pt in &p {
        while k >= 2 && cross(out[k - 2], out[k - 1], pt) <= 0.0 {
            k -= 1;
        }
        out[k] = pt;
        k += 1;
    }
    let lower = k + 1;
    for &pt in p.iter().rev().skip(1) {
        while k >= lower && cross(out[k - 2], out[k - 1], pt) <= 0.0 {
            k -= 1;
        }
        out[k] = pt;
        k += 1;
    }
    k.saturating_sub(1).max(1)
}

#[cfg(test)]
mod tests;
