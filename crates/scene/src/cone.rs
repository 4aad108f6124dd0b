//! A cluster's back-facing cone, built so that its verdict is safe on a rasterizer: when the cone
//! says "faces away", no triangle of the cluster can be drawn as front-facing — not even after the
//! GPU's f32 transform and the snapping of its vertices to the sub-pixel grid have moved them.
//!
//! The cone (axis `a`, half-angle `α` holding every triangle's unit normal, apex `A` behind every
//! triangle's plane) rejects an eye `e` when the direction from the eye to the apex lies within
//! `90° − α − γ` of the axis: then every triangle's plane lies at least `|A − e| sin γ` in front of
//! the eye. Perturbing a triangle's vertices by at most `ν` moves its plane, at distance `d`,
//! by at most `ν + 2 d ν P / area (1 + 2 ν / P)` (`P` its perimeter: its normal turns by at most
//! that much), so no perturbation flips it while `|A − e| sin γ` exceeds that. `γ` is computed per
//! test from the cluster's thinness (the largest perimeter / area of its triangles), its reach
//! (the farthest vertex from the apex) and `ν`: the sub-pixel snapping step at the farthest vertex's
//! distance plus the f32 transform's rounding. A cluster with a zero-area or numerically
//! degenerate triangle gets no cone: such a triangle has no reliable side.
//!
//! [`back_facing`] is the test `shaders/cluster_cull.comp` runs, in the same f32 steps.

use glam::{DVec3, Vec3};

/// Cutoff of a cluster without a cone (never rejects).
pub const NO_CONE: f32 = 2.0;

/// How far inside the cone the eye must be beyond what rounding and snapping need (the sine of
/// the extra angle): the cone's own f32 rounding and the eye's local position.
pub const CONE_MARGIN: f32 = 1e-3;

/// How far snapping moves a vertex, in sub-pixel steps: √2 (truncating in x and y; rounding
/// to nearest moves it half that), with room.
const SNAP: f32 = 1.5;

/// How far a triangle's plane turns per unit of vertex movement, in perimeter / area: 2 for
/// unit normals (|n̂' − n̂| ≤ 2 |n' − n| / |n|), grown by the second-order term, which stays below
/// 5 % wherever the test can reject at all (ν P / area < 0.45 there, and P / area ≥ 20.8 / P
/// for any triangle, so ν / P < 0.022).
const TILT: f32 = 2.2;

/// A triangle whose doubled area is below this fraction of its perimeter squared has no
/// reliable facing in f32 (its normal is mostly rounding): its cluster gets no cone.
const DEGENERATE: f64 = 1e-6;

/// The smallest cosine between the axis and a triangle's normal for which a cone is kept
/// (wider cones reject almost nothing).
const MIN_COS: f64 = 0.1;

/// A back-facing cone in a mesh's local space (the fields of `GpuCluster`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cone {
    pub apex: [f32; 3],
    pub axis: [f32; 3],
    /// sin α (rounded up); [`NO_CONE`] when the cluster has none.
    pub cutoff: f32,
    /// The farthest vertex from the apex (rounded up).
    pub reach: f32,
    /// The largest perimeter / area of the cluster's triangles (1 / local units, rounded up).
    pub thinness: f32,
}

impl Cone {
    pub const NONE: Cone = Cone {
        apex: [0.0; 3],
        axis: [0.0, 0.0, 1.0],
        cutoff: NO_CONE,
        reach: 0.0,
        thinness: 0.0,
    };

    /// The cone of `triangles` (counter-clockwise front faces, local positions), or
    /// [`Cone::NONE`] when one is degenerate or their normals spread too far.
    pub fn of_triangles(triangles: &[[[f32; 3]; 3]]) -> Cone {
        let mut normals = Vec::with_capacity(triangles.len());
        let mut thinness = 0.0f64;
        let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
        for t in triangles {
            let [a, b, c] = t.map(|p| Vec3::from(p).as_dvec3());
            if !(a.is_finite() && b.is_finite() && c.is_finite()) {
                return Cone::NONE;
            }
            let n = (b - a).cross(c - a);
            let double_area = n.length();
            let perimeter = (b - a).length() + (c - b).length() + (a - c).length();
            if double_area.is_nan() || double_area <= DEGENERATE * perimeter * perimeter {
                return Cone::NONE;
            }
            thinness = thinness.max(2.0 * perimeter / double_area);
            normals.push(n / double_area);
            for p in [a, b, c] {
                lo = lo.min(p);
                hi = hi.max(p);
            }
        }
        if normals.is_empty() {
            return Cone::NONE;
        }
        let sum: DVec3 = normals.iter().sum();
        if sum.length() < 1e-6 * normals.len() as f64 {
            return Cone::NONE;
        }
        // The axis as the shader reads it (f32), and the angles against that one.
        let axis32 = sum.normalize().as_vec3();
        let axis = axis32.as_dvec3().normalize();
        let min_cos = normals.iter().map(|n| n.dot(axis)).fold(1.0f64, f64::min);
        if min_cos <= MIN_COS {
            return Cone::NONE;
        }
        let cutoff = round_up((1.0 - min_cos * min_cos).max(0.0).sqrt());
        // The apex: from the box centre back along the axis until it lies behind every
        // triangle's plane (each vertex tested, so rounding in the plane does not matter), then
        // checked again as the f32 the shader reads.
        let center = (lo + hi) * 0.5;
        let size = (hi - lo).length() + center.length();
        let mut t = triangles
            .iter()
            .zip(&normals)
            .flat_map(|(tri, n)| {
                tri.iter().map(move |p| {
                    let p = Vec3::from(*p).as_dvec3();
                    n.dot(center - p) / n.dot(axis)
                })
            })
            .fold(f64::NEG_INFINITY, f64::max);
        let mut apex = (center - axis * t).as_vec3();
        let behind_all = |apex: Vec3| {
            let a = apex.as_dvec3();
            triangles.iter().zip(&normals).all(|(tri, n)| {
                tri.iter()
                    .all(|p| n.dot(a - Vec3::from(*p).as_dvec3()) <= 0.0)
            })
        };
        let mut step = 1e-6 * size.max(1e-30);
        let mut tries = 0;
        while !behind_all(apex) {
            tries += 1;
            if tries > 60 {
                return Cone::NONE;
            }
            t += step;
            step *= 2.0;
            apex = (center - axis * t).as_vec3();
        }
        let a = apex.as_dvec3();
        let reach = triangles
            .iter()
            .flatten()
            .map(|p| (Vec3::from(*p).as_dvec3() - a).length())
            .fold(0.0f64, f64::max);
        Cone {
            apex: apex.to_array(),
            axis: axis32.to_array(),
            cutoff,
            reach: round_up(reach),
            thinness: round_up(thinness),
        }
    }
}

/// `x` as an f32 no smaller than it.
fn round_up(x: f64) -> f32 {
    let f = x as f32;
    if f64::from(f) < x {
        f.next_up()
    } else {
        f
    }
}

/// Whether every triangle of the cluster faces away from the eye `eye` (local space), drawn with
/// `steps` sub-pixel steps per local unit of lateral offset at distance 1 (the focal length in
/// pixels times 2^subPixelPrecisionBits; the instance's scale is uniform, so it cancels). The
/// f32 twin of `back_facing` in `shaders/cluster_cull.comp`.
pub fn back_facing(cone: &Cone, eye: Vec3, steps: f32) -> bool {
    if cone.cutoff >= 1.0 {
        return false;
    }
    let apex = Vec3::from(cone.apex);
    let d = apex - eye;
    let len = d.length();
    if len.is_nan() || len <= cone.reach {
        return false;
    }
    // Farthest a vertex can be; how far the rasterizer may move it there (snapping) plus the
    // f32 transform's rounding (relative to the local coordinates and the eye's).
    let far = len + cone.reach;
    let rounding = 1e-6 * (apex.length() + cone.reach + eye.length());
    let nu = SNAP * far / steps + rounding;
    let sin_gamma = nu * (TILT * cone.thinness * far + 1.0) / len + CONE_MARGIN;
    // The eye must lie within 90° − α − γ of the axis: none left when γ ≥ 90° − α.
    let cos_alpha = (1.0 - cone.cutoff * cone.cutoff).max(0.0).sqrt();
    if sin_gamma.is_nan() || sin_gamma >= cos_alpha {
        return false;
    }
    let threshold = cone.cutoff * (1.0 - sin_gamma * sin_gamma).sqrt() + cos_alpha * sin_gamma;
    d.dot(Vec3::from(cone.axis)) >= threshold * len
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The facing of a triangle from `eye`, exactly (f64): its plane's signed distance.
    fn plane_distance(t: &[[f32; 3]; 3], eye: DVec3) -> f64 {
        let [a, b, c] = t.map(|p| Vec3::from(p).as_dvec3());
        let n = (b - a).cross(c - a);
        n.normalize_or_zero().dot(eye - a)
    }

    /// Triangles of a cluster: a patch of a surface, some thin, some near-degenerate, some
    /// exactly zero-area, at an offset from the mesh origin.
    fn cluster() -> impl Strategy<Value = Vec<[[f32; 3]; 3]>> {
        let tri = (
            prop::array::uniform3(-1.0f32..1.0),
            prop::array::uniform3(-1.0f32..1.0),
            prop::array::uniform3(-1.0f32..1.0),
            0u8..32,
        )
            .prop_map(|(a, b, c, kind)| {
                let (a, b, mut c) = (Vec3::from(a), Vec3::from(b), Vec3::from(c));
                // A bumpy patch facing +z mostly.
                let lift = |p: Vec3| Vec3::new(p.x, p.y, 0.2 * p.z);
                match kind {
                    // Zero area (collinear), near-degenerate, thin.
                    0 => c = a + (b - a) * 0.37,
                    1 => c = a + (b - a) * 0.5 + Vec3::new(0.0, 0.0, 1e-6),
                    2 | 3 => {
                        c = a + (b - a) * 0.5 + (b - a).cross(Vec3::Z).normalize_or_zero() * 1e-3
                    }
                    _ => {}
                }
                let (a, b, c) = (lift(a), lift(b), lift(c));
                // Counter-clockwise seen from +z.
                let n = (b - a).cross(c - a);
                if n.z < 0.0 {
                    [a.to_array(), c.to_array(), b.to_array()]
                } else {
                    [a.to_array(), b.to_array(), c.to_array()]
                }
            });
        (
            prop::collection::vec(tri, 1..24),
            prop::array::uniform3(-200.0f32..200.0),
            0.01f32..4.0,
        )
            .prop_map(|(tris, offset, scale)| {
                tris.into_iter()
                    .map(|t| t.map(|p| (Vec3::from(p) * scale + Vec3::from(offset)).to_array()))
                    .collect()
            })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2000))]

        /// The cone's verdict "faces away" holds for every triangle, with margin for the
        /// snapping and rounding it claims to cover; a cluster with a zero-area or
        /// near-degenerate triangle is never rejected.
        #[test]
        fn a_rejecting_cone_means_every_triangle_faces_away(
            tris in cluster(),
            dir in prop::array::uniform3(-1.0f32..1.0),
            distance in 0.01f32..3000.0,
            steps in prop::sample::select(vec![16.0f32 * 300.0, 256.0 * 300.0, 256.0 * 1000.0, 256.0 * 4000.0]),
        ) {
            let cone = Cone::of_triangles(&tris);
            let degenerate = tris.iter().any(|t| {
                let [a, b, c] = t.map(|p| Vec3::from(p).as_dvec3());
                let p = (b - a).length() + (c - b).length() + (a - c).length();
                (b - a).cross(c - a).length() <= DEGENERATE * p * p
            });
            if degenerate {
                prop_assert!(cone.cutoff >= 1.0);
            }
            let centre = tris.iter().flatten().fold(DVec3::ZERO, |s, p| s + Vec3::from(*p).as_dvec3())
                / (3 * tris.len()) as f64;
            let dir = Vec3::from(dir).as_dvec3().normalize_or_zero();
            prop_assume!(dir != DVec3::ZERO);
            let eye = (centre + dir * f64::from(distance)).as_vec3();
            if back_facing(&cone, eye, steps) {
                let e = eye.as_dvec3();
                for t in &tris {
                    let [a, b, c] = t.map(|p| Vec3::from(p).as_dvec3());
                    let area2 = (b - a).cross(c - a).length();
                    let perimeter = (b - a).length() + (c - b).length() + (a - c).length();
                    let far = [a, b, c].iter().map(|p| (*p - e).length()).fold(0.0, f64::max);
                    // What snapping may move a vertex at that distance, and the f32 transform.
                    let nu = std::f64::consts::SQRT_2 * far / f64::from(steps)
                        + 1e-6 * (a.length().max(b.length()).max(c.length()) + e.length());
                    // The plane moves by nu, its unit normal by 2 r, r = |n' - n| / |n|.
                    let area = 0.5 * area2;
                    let r = nu * perimeter / area * (1.0 + 2.0 * nu / perimeter);
                    let needed = nu + 2.0 * r * far;
                    let d = plane_distance(t, e);
                    prop_assert!(
                        d < -needed,
                        "triangle {t:?} from {eye}: plane distance {d}, needs below -{needed} ({cone:?})"
                    );
                }
            }
        }
    }

    /// Not a vacuous guarantee: bumpy patches of 16 triangles seen from behind, ten sizes away,
    /// on a 1080p screen with 8 sub-pixel bits, are rejected.
    #[test]
    fn patches_seen_from_behind_are_rejected() {
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 40) as f32 / (1u64 << 24) as f32
        };
        let (mut rejected, mut total) = (0, 0);
        for _ in 0..200 {
            let tris: Vec<[[f32; 3]; 3]> = (0..16)
                .map(|k| {
                    let (x, y) = ((k % 4) as f32, (k / 4) as f32);
                    let mut z =
                        |dx: f32, dy: f32| 0.15 * ((x + dx) * 1.3 + (y + dy) * 0.7 + next()).sin();
                    [
                        [x, y, z(0.0, 0.0)],
                        [x + 1.0, y, z(1.0, 0.0)],
                        [x, y + 1.0, z(0.0, 1.0)],
                    ]
                })
                .collect();
            let cone = Cone::of_triangles(&tris);
            let eye = Vec3::new(2.0, 2.0, -40.0);
            total += 1;
            if back_facing(&cone, eye, 256.0 * 940.0) {
                rejected += 1;
            }
        }
        assert!(rejected * 10 >= total * 9, "{rejected} of {total} rejected");
    }

    #[test]
    fn a_flat_patch_seen_from_behind_is_rejected_and_from_the_front_is_not() {
        let tris: Vec<[[f32; 3]; 3]> = (0..8)
            .map(|k| {
                let x = k as f32;
                [[x, 0.0, 0.0], [x + 1.0, 0.0, 0.0], [x, 1.0, 0.0]]
            })
            .collect();
        let cone = Cone::of_triangles(&tris);
        assert!(cone.cutoff < 1e-3, "{cone:?}");
        let steps = 256.0 * 1000.0;
        assert!(back_facing(&cone, Vec3::new(4.0, 0.5, -10.0), steps));
        assert!(!back_facing(&cone, Vec3::new(4.0, 0.5, 10.0), steps));
        // Edge-on: never.
        assert!(!back_facing(&cone, Vec3::new(4.0, 0.5, -1e-4), steps));
        // Far enough that the snapping could flip triangles of this size: not any more.
        assert!(!back_facing(&cone, Vec3::new(4.0, 0.5, -1e5), steps));
        // A zero-area triangle among them: no cone.
        let mut with = tris.clone();
        with.push([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]]);
        assert_eq!(Cone::of_triangles(&with).cutoff, NO_CONE);
    }
}
