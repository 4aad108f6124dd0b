//! Cameras and camera paths, in tilegraph's conventions:
//!
//! - world space is glTF's: right-handed, y up, metres;
//! - the view matrix is `look_at_rh`, built with the eye at the origin (camera-relative
//!   rendering: instance translations have the eye subtracted in f64, see [`crate::Transform`]);
//! - projections map to Vulkan clip space, depth in [0, 1], and include the y flip, so NDC
//!   y = -1 is the top row of the image;
//! - the default projection is reverse-Z with an infinite far plane (near -> depth 1,
//!   infinity -> depth 0). [`DepthConvention`] tells culling code which compare to use.
//!
//! [`Projection`] and [`DepthConvention`] are tilegraph-types', shared with the culling
//! references; the checks a camera path applies to them are here.

use std::path::Path;

use glam::{DMat4, DVec3, Mat4, Vec3};
use serde::{Deserialize, Serialize};
use tilegraph_types::{DepthConvention, Projection};

use crate::bounds::DAabb;
use crate::error::SceneError;

/// Width / height of the most extreme viewports a projection must survive: 1 x 32768 to
/// 32768 x 1 px (32768 is above every driver's `maxImageDimension2D`).
const EXTREME_ASPECTS: [f32; 3] = [1.0 / 32768.0, 1.0, 32768.0];

/// Checks a camera's projection, which any caller can build (its fields are public) and a
/// camera path reads from JSON; `Err((field, reason))`.
fn check_projection(projection: &Projection) -> Result<(), (&'static str, String)> {
    let near = projection.near();
    if !near.is_finite() || near <= 0.0 {
        return Err(("near", format!("must be finite and > 0, got {near}")));
    }
    if let Some(far) = projection.far() {
        if !far.is_finite() {
            return Err(("far", format!("must be finite or null, got {far}")));
        }
        if far <= near {
            return Err(("far", format!("{far} must be greater than near {near}")));
        }
    }
    match *projection {
        Projection::Perspective { fov_y_rad, .. } => {
            let deg = fov_y_rad.to_degrees();
            if !(fov_y_rad.is_finite() && deg > 0.0 && deg < 180.0) {
                return Err(("fov_y_deg", format!("must be in (0, 180), got {deg}")));
            }
        }
        Projection::Orthographic { half_height, .. } => {
            if !(half_height.is_finite() && half_height > 0.0) {
                return Err(("half_height", format!("must be > 0, got {half_height}")));
            }
        }
    }
    // Each value in range can still overflow the matrix (a field of view of 1e-37 degrees,
    // planes near f32's limit), at some viewport shape if not at a square one: the GPU
    // would get infinities and NaN clip coordinates.
    if EXTREME_ASPECTS
        .iter()
        .any(|&a| !projection.matrix(a).is_finite())
    {
        let field = match projection {
            Projection::Perspective { .. } => "fov_y_deg",
            Projection::Orthographic { .. } => "half_height",
        };
        return Err((field, "the projection matrix overflows f32".into()));
    }
    Ok(())
}

/// A camera: where it is, what it looks at, and how it projects.
///
/// The eye and target are f64 so that a camera 10^6 m from the origin still resolves
/// millimetres; only the direction (a unit vector) is rounded to f32.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    pub eye: DVec3,
    pub target: DVec3,
    pub up: Vec3,
    pub projection: Projection,
}

impl Camera {
    /// A camera with the default projection (reverse-Z, infinite far, 60 degrees, near 0.1 m).
    pub fn looking_at(eye: DVec3, target: DVec3) -> Self {
        Camera {
            eye,
            target,
            up: Vec3::Y,
            projection: Projection::default(),
        }
    }

    /// Checks the camera: finite values, a view direction, an up not parallel to it, and a
    /// valid projection. `Err((field, reason))`.
    pub fn validate(&self) -> Result<(), (&'static str, String)> {
        if !self.eye.is_finite() {
            return Err(("eye", format!("non-finite value {:?}", self.eye.to_array())));
        }
        if !self.target.is_finite() {
            return Err((
                "target",
                format!("non-finite value {:?}", self.target.to_array()),
            ));
        }
        if !self.up.is_finite() {
            return Err(("up", format!("non-finite value {:?}", self.up.to_array())));
        }
        let dir = self.target - self.eye;
        if !dir.length().is_finite() {
            return Err((
                "target",
                "too far from the eye: the view direction overflows".into(),
            ));
        }
        // f64 direction: eye and target may be 10^6 apart from the origin yet centimetres apart.
        if dir.length() < 1e-9 {
            return Err(("target", "equals eye: zero-length view direction".into()));
        }
        let up = self.up.as_dvec3();
        if up.length() < 1e-9 {
            return Err(("up", "zero-length up vector".into()));
        }
        let sin = dir.normalize().cross(up.normalize()).length();
        if sin.is_nan() || sin < VERTICAL_SIN {
            return Err(("up", "parallel to the view direction".into()));
        }
        check_projection(&self.projection)
    }

    /// The unit view direction, computed in f64 before rounding.
    pub fn forward(&self) -> Vec3 {
        (self.target - self.eye)
            .normalize_or(DVec3::NEG_Z)
            .as_vec3()
    }

    /// The view matrix with the eye at the origin: what camera-relative model matrices pair with.
    pub fn view_relative(&self) -> Mat4 {
        // Normalized in f64 first: an up vector of 1e20 squares past f32 (the view collapses).
        let up = self.up.as_dvec3().normalize_or(DVec3::Y).as_vec3();
        Mat4::look_to_rh(Vec3::ZERO, self.forward(), up)
    }

    /// The absolute view matrix in f64 (`look_at_rh`), for CPU references on small worlds.
    pub fn view_world(&self) -> DMat4 {
        DMat4::look_at_rh(self.eye, self.target, self.up.as_dvec3())
    }

    pub fn matrices(&self, aspect: f32) -> FrameMatrices {
        let view = self.view_relative();
        let projection = self.projection.matrix(aspect);
        FrameMatrices {
            eye: self.eye,
            view,
            projection,
            view_projection: projection * view,
            depth: self.projection.depth_convention(),
        }
    }

    #[must_use]
    pub fn translated(mut self, offset: DVec3) -> Self {
        self.eye += offset;
        self.target += offset;
        self
    }
}

/// The matrices of one frame, camera-relative: they apply to positions from which the eye has
/// already been subtracted (in f64).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameMatrices {
    pub eye: DVec3,
    pub view: Mat4,
    pub projection: Mat4,
    pub view_projection: Mat4,
    pub depth: DepthConvention,
}

/// One frame of a camera path, with the previous frame's matrices for reprojection.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraFrame {
    pub index: usize,
    pub camera: Camera,
    /// The camera jumps here: history (last frame's visibility, reprojection) does not apply.
    pub cut: bool,
    pub current: FrameMatrices,
    /// Last frame's matrices; equal to `current` on the first frame and on a cut.
    pub previous: FrameMatrices,
    /// Maps a position relative to the *current* eye to the previous frame's clip space:
    /// `previous.view_projection * translate(current.eye - previous.eye)` (difference in f64).
    pub reproject: Mat4,
}

impl CameraFrame {
    /// Frame `index` seen by `camera` after `previous` (`None`: a cut — the first frame, or a
    /// jump — where nothing of the last frame applies), for a viewport of `aspect`.
    pub fn new(index: usize, camera: Camera, previous: Option<&Camera>, aspect: f32) -> Self {
        let current = camera.matrices(aspect);
        let prev = previous.map_or(current, |p| p.matrices(aspect));
        let delta = (current.eye - prev.eye).as_vec3();
        CameraFrame {
            index,
            camera,
            cut: previous.is_none(),
            current,
            previous: prev,
            reproject: prev.view_projection * Mat4::from_translation(delta),
        }
    }
}

/// One key of a camera path: a camera, and whether the path cuts (jumps) to it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PathKey {
    pub camera: Camera,
    pub cut: bool,
}

/// A sequence of cameras, one per frame, that a benchmark replays.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraPath {
    name: String,
    keys: Vec<PathKey>,
}

/// A point a fly-through passes: where the eye is and what it looks at.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Waypoint {
    pub eye: DVec3,
    pub target: DVec3,
}

impl Waypoint {
    pub fn new(eye: DVec3, target: DVec3) -> Self {
        Waypoint { eye, target }
    }
}

/// The centre and radius of `bounds`, and a 60-degree reverse-Z projection whose near plane is
/// a thousandth of that radius: the view of a path made from the bounds alone.
fn bounds_view(bounds: &DAabb) -> (DVec3, f64, Projection) {
    let r = bounds.half_extents().length().max(1e-3);
    let projection = Projection::Perspective {
        fov_y_rad: 60f32.to_radians(),
        near: (r * 1e-3) as f32,
        far: None,
        depth: DepthConvention::Reverse,
    };
    (bounds.center(), r, projection)
}

fn path_error(file: &str, frame: Option<usize>, field: &str, reason: String) -> SceneError {
    SceneError::CameraPath {
        file: file.to_string(),
        frame,
        field: field.to_string(),
        reason,
    }
}

/// Uniform Catmull-Rom between `p1` and `p2` at `t` in [0, 1].
fn catmull_rom(p0: DVec3, p1: DVec3, p2: DVec3, p3: DVec3, t: f64) -> DVec3 {
    let t2 = t * t;
    let t3 = t2 * t;
    0.5 * ((2.0 * p1)
        + (p2 - p0) * t
        + (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3) * t2
        + (3.0 * p1 - p0 - 3.0 * p2 + p3) * t3)
}

impl CameraPath {
    /// A path from explicit keys; every key is checked.
    pub fn new(name: impl Into<String>, keys: Vec<PathKey>) -> Result<Self, SceneError> {
        let name = name.into();
        if keys.is_empty() {
            return Err(path_error(&name, None, "frames", "no frame".into()));
        }
        for (i, k) in keys.iter().enumerate() {
            k.camera
                .validate()
                .map_err(|(field, reason)| path_error(&name, Some(i), field, reason))?;
        }
        Ok(CameraPath { name, keys })
    }

    pub fn name(&self) -> &str {
        &self.name
    }

    pub fn keys(&self) -> &[PathKey] {
        &self.keys
    }

    pub fn len(&self) -> usize {
        self.keys.len()
    }

    pub fn is_empty(&self) -> bool {
        self.keys.is_empty()
    }

    /// A Catmull-Rom fly-through: eye and target each follow a spline through the waypoints,
    /// `frames_per_segment` frames between consecutive waypoints, plus the last waypoint.
    pub fn catmull_rom(
        name: impl Into<String>,
        waypoints: &[Waypoint],
        frames_per_segment: usize,
        projection: Projection,
    ) -> Result<Self, SceneError> {
        let frames = vec![frames_per_segment; waypoints.len().saturating_sub(1)];
        CameraPath::catmull_rom_timed(name, waypoints, &frames, projection)
    }

    /// A Catmull-Rom fly-through with its own frame count per segment (`frames[i]` frames from
    /// waypoint i to i + 1): few frames on a segment whose target swings make a fast turn.
    pub fn catmull_rom_timed(
        name: impl Into<String>,
        waypoints: &[Waypoint],
        frames: &[usize],
        projection: Projection,
    ) -> Result<Self, SceneError> {
        let name = name.into();
        let n = waypoints.len();
        if n < 2 || frames.len() != n - 1 || frames.contains(&0) {
            return Err(path_error(
                &name,
                None,
                "waypoints",
                format!(
                    "a spline needs at least 2 waypoints and a positive frame count per segment \
                     (got {n} waypoints, {} counts)",
                    frames.len()
                ),
            ));
        }
        // Phantom end points continue the first and last segments straight on.
        let at = |i: isize, f: fn(&Waypoint) -> DVec3| -> DVec3 {
            if i < 0 {
                2.0 * f(&waypoints[0]) - f(&waypoints[1])
            } else if i as usize >= n {
                2.0 * f(&waypoints[n - 1]) - f(&waypoints[n - 2])
            } else {
                f(&waypoints[i as usize])
            }
        };
        let key = |eye: DVec3, target: DVec3| PathKey {
            camera: Camera {
                eye,
                target,
                up: Vec3::Y,
                projection,
            },
            cut: false,
        };
        let mut keys = Vec::with_capacity(frames.iter().sum::<usize>() + 1);
        for (s, &count) in frames.iter().enumerate() {
            let s = s as isize;
            for k in 0..count {
                let t = k as f64 / count as f64;
                let eye = catmull_rom(
                    at(s - 1, |w| w.eye),
                    at(s, |w| w.eye),
                    at(s + 1, |w| w.eye),
                    at(s + 2, |w| w.eye),
                    t,
                );
                let target = catmull_rom(
                    at(s - 1, |w| w.target),
                    at(s, |w| w.target),
                    at(s + 1, |w| w.target),
                    at(s + 2, |w| w.target),
                    t,
                );
                keys.push(key(eye, target));
            }
        }
        let last = waypoints[n - 1];
        keys.push(key(last.eye, last.target));
        CameraPath::new(name, keys)
    }

    /// An orbit around `center` at `radius` and `height` above it, `revolutions` turns over
    /// `frames` frames, always looking at the centre.
    pub fn orbit(
        name: impl Into<String>,
        center: DVec3,
        radius: f64,
        height: f64,
        frames: usize,
        revolutions: f64,
        projection: Projection,
    ) -> Result<Self, SceneError> {
        let keys = (0..frames)
            .map(|i| {
                let a = std::f64::consts::TAU * revolutions * i as f64 / frames.max(1) as f64;
                PathKey {
                    camera: Camera {
                        eye: center + DVec3::new(radius * a.cos(), height, radius * a.sin()),
                        target: center,
                        up: Vec3::Y,
                        projection,
                    },
                    cut: false,
                }
            })
            .collect();
        CameraPath::new(name, keys)
    }

    /// The default path of a scene without a designed one (glTF files): one orbit that keeps
    /// the whole bounds in view.
    pub(crate) fn orbit_bounds(bounds: &DAabb) -> Self {
        let (center, r, projection) = bounds_view(bounds);
        let frames = 240;
        let keys = (0..frames)
            .map(|i| {
                let a = std::f64::consts::TAU * i as f64 / frames as f64;
                PathKey {
                    camera: Camera {
                        eye: center + DVec3::new(2.5 * r * a.cos(), 0.6 * r, 2.5 * r * a.sin()),
                        target: center,
                        up: Vec3::Y,
                        projection,
                    },
                    cut: false,
                }
            })
            .collect();
        CameraPath {
            name: "orbit".into(),
            keys,
        }
    }

    /// A path no test or tuning run uses by default, from the bounds alone: half a low orbit
    /// close around the scene (1.1x the bounds' radius, a quarter of it above the centre,
    /// looking a little below the centre), starting at an angle no other path starts at. What
    /// `tilegraph tune` checks its pick on, to catch a setting that only suits its own path.
    pub fn held_out(bounds: &DAabb, frames: usize) -> Self {
        let (center, r, projection) = bounds_view(bounds);
        let target = center - DVec3::new(0.0, 0.2 * r, 0.0);
        let keys = (0..frames.max(1))
            .map(|i| {
                let a = 0.4 + std::f64::consts::PI * i as f64 / frames.max(1) as f64;
                PathKey {
                    camera: Camera {
                        eye: center + DVec3::new(1.1 * r * a.cos(), 0.25 * r, 1.1 * r * a.sin()),
                        target,
                        up: Vec3::Y,
                        projection,
                    },
                    cut: false,
                }
            })
            .collect();
        CameraPath {
            name: "held-out".into(),
            keys,
        }
    }

    /// A walk through the scene at eye height (1.7 above the bounds' floor, or mid-height in a
    /// scene lower than that), at a player's pace in metres: 5 cm a frame (3 m/s at 60 Hz; less
    /// in a scene smaller than 12 m), the view sweeping ±70° of yaw (up to 4° a frame) with a
    /// little pitch, turning back at the bounds, and a hard cut to another place every 24
    /// frames. Deterministic in `seed`. Not an orbit: the camera stands inside the scene, among
    /// what occludes, and turns faster than it moves — what a player does.
    pub fn eye_height_walk(bounds: &DAabb, frames: usize, seed: u64) -> Self {
        let (_, r, projection) = bounds_view(bounds);
        let projection = match projection {
            Projection::Perspective {
                fov_y_rad, depth, ..
            } => Projection::Perspective {
                fov_y_rad,
                near: (r * 1e-4).clamp(0.01, 0.1) as f32,
                far: None,
                depth,
            },
            other => other,
        };
        let mut state = seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let (lo, hi) = (bounds.min, bounds.max);
        let height = (lo.y + 1.7).min(0.5 * (lo.y + hi.y));
        let place = |next: &mut dyn FnMut() -> f64| {
            DVec3::new(
                lo.x + (0.1 + 0.8 * next()) * (hi.x - lo.x),
                height,
                lo.z + (0.1 + 0.8 * next()) * (hi.z - lo.z),
            )
        };
        let step = (0.004 * (hi - lo).length().max(1e-3)).min(0.05);
        let (mut eye, mut heading) = (place(&mut next), next() * std::f64::consts::TAU);
        let keys = (0..frames.max(1))
            .map(|i| {
                let cut = i > 0 && i % 24 == 0;
                if cut {
                    eye = place(&mut next);
                    heading = next() * std::f64::consts::TAU;
                } else if i > 0 {
                    eye += DVec3::new(heading.cos(), 0.0, heading.sin()) * step;
                    // Turn back at the edges of the bounds.
                    if eye.x < lo.x || eye.x > hi.x || eye.z < lo.z || eye.z > hi.z {
                        heading += std::f64::consts::PI;
                        eye = eye.clamp(lo, hi);
                    }
                }
                let yaw = heading + 1.2 * (i as f64 * 0.06).sin();
                let pitch = 0.15 * (i as f64 * 0.03).sin();
                let look = DVec3::new(
                    yaw.cos() * pitch.cos(),
                    pitch.sin(),
                    yaw.sin() * pitch.cos(),
                );
                PathKey {
                    camera: Camera {
                        eye,
                        target: eye + look,
                        up: Vec3::Y,
                        projection,
                    },
                    cut,
                }
            })
            .collect();
        CameraPath {
            name: format!("eye-height walk {seed}"),
            keys,
        }
    }

    /// This path followed by `next`, with a cut at the join.
    #[must_use]
    pub fn then_cut(mut self, next: CameraPath) -> Self {
        let start = self.keys.len();
        self.keys.extend(next.keys);
        if let Some(k) = self.keys.get_mut(start) {
            k.cut = true;
        }
        self
    }

    #[must_use]
    pub fn translated(&self, offset: DVec3) -> Self {
        CameraPath {
            name: self.name.clone(),
            keys: self
                .keys
                .iter()
                .map(|k| PathKey {
                    camera: k.camera.translated(offset),
                    cut: k.cut,
                })
                .collect(),
        }
    }

    pub fn camera(&self, index: usize) -> Option<Camera> {
        self.keys.get(index).map(|k| k.camera)
    }

    /// Frame `index` with the previous frame's matrices, for a viewport of `aspect`.
    pub fn frame(&self, index: usize, aspect: f32) -> Option<CameraFrame> {
        let key = self.keys.get(index)?;
        let previous = match index.checked_sub(1).and_then(|p| self.keys.get(p)) {
            Some(prev) if !key.cut => Some(&prev.camera),
            _ => None,
        };
        Some(CameraFrame::new(index, key.camera, previous, aspect))
    }

    /// Every frame in order.
    pub fn frames(&self, aspect: f32) -> impl Iterator<Item = CameraFrame> + '_ {
        (0..self.keys.len()).filter_map(move |i| self.frame(i, aspect))
    }

    /// Parses the JSON format documented in docs/SCENES.md; `source` names the file in errors.
    pub fn from_json_str(text: &str, source: &str) -> Result<Self, SceneError> {
        if text.trim_start().starts_with('[') {
            return Err(path_error(
                source,
                None,
                "<root>",
                "a bare array: a camera path is an object, {\"frames\": [{\"eye\": …, \"target\": …}, …]} (docs/SCENES.md)".into(),
            ));
        }
        let de = &mut serde_json::Deserializer::from_str(text);
        let doc: JsonPath = serde_path_to_error::deserialize(de).map_err(|e| {
            let key = e.path().to_string();
            let inner = e.into_inner();
            let (line, column) = (inner.line(), inner.column());
            // serde_json appends the location to its message; say it once.
            let message = inner.to_string();
            let message = message
                .rsplit_once(" at line ")
                .map_or(message.as_str(), |(m, _)| m)
                .to_string();
            let field = if key == "." { "json".to_string() } else { key };
            path_error(
                source,
                None,
                &field,
                format!("line {line}, column {column}: {message}"),
            )
        })?;
        if doc.frames.is_empty() {
            return Err(path_error(source, None, "frames", "empty array".into()));
        }
        let mut keys = Vec::with_capacity(doc.frames.len());
        for (i, f) in doc.frames.iter().enumerate() {
            let err = |field: &str, reason: String| path_error(source, Some(i), field, reason);
            let vec3 = |field: &str, v: [f64; 3]| -> Result<DVec3, SceneError> {
                let d = DVec3::from_array(v);
                if d.is_finite() {
                    Ok(d)
                } else {
                    Err(err(field, format!("non-finite value {v:?}")))
                }
            };
            let eye = vec3("eye", f.eye)?;
            let target = vec3("target", f.target)?;
            let up = match f.up {
                Some(up) => vec3("up", up)?,
                None => default_up(target - eye),
            };
            // f64 -> f32 can overflow to infinity (1e39); check after the cast.
            let up32 = up.as_vec3();
            if !up32.is_finite() {
                return Err(err("up", format!("{up:?} does not fit f32")));
            }
            let near = f.near as f32;
            let far = f.far.map(|x| x as f32);
            let fov_y_rad = (f.fov_y_deg as f32).to_radians();
            let projection = Projection::Perspective {
                fov_y_rad,
                near,
                far,
                depth: f.depth,
            };
            let camera = Camera {
                eye,
                target,
                up: up32,
                projection,
            };
            camera
                .validate()
                .map_err(|(field, reason)| err(field, reason))?;
            keys.push(PathKey { camera, cut: f.cut });
        }
        CameraPath::new(source, keys)
    }

    /// Loads a camera path JSON file.
    pub fn load_json(path: &Path) -> Result<Self, SceneError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| SceneError::Io {
            file: file.clone(),
            source,
        })?;
        CameraPath::from_json_str(&text, &file)
    }

    /// Writes the path in the JSON format (orthographic keys are not representable and are
    /// written with a 60-degree perspective, and logged).
    pub fn to_json(&self) -> String {
        let frames = self
            .keys
            .iter()
            .map(|k| {
                let c = &k.camera;
                let (fov_y_deg, near, far, depth) = match c.projection {
                    Projection::Perspective {
                        fov_y_rad,
                        near,
                        far,
                        depth,
                    } => (
                        f64::from(fov_y_rad.to_degrees()),
                        f64::from(near),
                        far.map(f64::from),
                        depth,
                    ),
                    Projection::Orthographic {
                        near, far, depth, ..
                    } => {
                        log::warn!(
                            "camera path {}: orthographic key written as perspective",
                            self.name
                        );
                        (60.0, f64::from(near), Some(f64::from(far)), depth)
                    }
                };
                JsonFrame {
                    eye: c.eye.to_array(),
                    target: c.target.to_array(),
                    up: Some(c.up.as_dvec3().to_array()),
                    fov_y_deg,
                    near,
                    far,
                    cut: k.cut,
                    depth,
                }
            })
            .collect();
        serde_json::to_string_pretty(&JsonPath { frames }).unwrap_or_default()
    }
}

/// A frame's up where the path gives none: +Y, unless the view is within [`Camera::validate`]'s
/// limit of straight down or up (a top-down camera), where +Y gives no orientation; there the
/// top of the image faces -Z looking down and +Z looking up, the limit of +Y for a camera that
/// faced -Z and pitched to the vertical.
fn default_up(direction: DVec3) -> DVec3 {
    let dir = direction.normalize_or_zero();
    if dir.cross(DVec3::Y).length() < VERTICAL_SIN {
        DVec3::new(0.0, 0.0, dir.y.signum())
    } else {
        DVec3::Y
    }
}

/// The sine of the smallest angle between the view direction and up that [`Camera::validate`]
/// accepts: below ~0.06 degrees the f32 cross product in `look_at` loses the right vector.
const VERTICAL_SIN: f64 = 1e-3;
fn default_fov() -> f64 {
    60.0
}
fn default_near() -> f64 {
    0.1
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct JsonPath {
    frames: Vec<JsonFrame>,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct JsonFrame {
    eye: [f64; 3],
    target: [f64; 3],
    #[serde(default, skip_serializing_if = "Option::is_none")]
    up: Option<[f64; 3]>,
    #[serde(default = "default_fov")]
    fov_y_deg: f64,
    #[serde(default = "default_near")]
    near: f64,
    #[serde(default)]
    far: Option<f64>,
    #[serde(default)]
    cut: bool,
    #[serde(default)]
    depth: DepthConvention,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_projection_that_overflows_at_an_extreme_viewport_is_rejected() {
        // Fine for a square viewport, infinite for a 32768 x 1 one.
        let ortho = Projection::Orthographic {
            half_height: 1e35,
            near: 0.1,
            far: 10.0,
            depth: DepthConvention::Reverse,
        };
        assert!(ortho.matrix(1.0).is_finite());
        assert_eq!(
            check_projection(&ortho).map_err(|(field, _)| field),
            Err("half_height")
        );
        let usual = Projection::Orthographic {
            half_height: 5.0,
            near: 0.1,
            far: 10.0,
            depth: DepthConvention::Reverse,
        };
        assert_eq!(check_projection(&usual), Ok(()));
    }

    /// Finite eye and target whose difference overflows: the direction is NaN, which no
    /// comparison may let through.
    #[test]
    fn an_overflowing_view_direction_is_rejected() {
        let cam = Camera::looking_at(DVec3::new(1e308, 0.0, 0.0), DVec3::new(-1e308, 0.0, 0.0));
        assert_eq!(cam.validate().map_err(|(field, _)| field), Err("target"));
    }

    #[test]
    fn relative_view_equals_absolute_view_near_the_origin() {
        let cam = Camera::looking_at(DVec3::new(3.0, 2.0, 5.0), DVec3::new(-1.0, 0.5, 0.0));
        let p = DVec3::new(0.3, 1.0, -2.0);
        let abs = cam.view_world().transform_point3(p);
        let rel = cam
            .view_relative()
            .transform_point3((p - cam.eye).as_vec3());
        assert!((abs.as_vec3() - rel).length() < 1e-5);
        let lookat = Mat4::look_at_rh(cam.eye.as_vec3(), cam.target.as_vec3(), Vec3::Y);
        assert!((lookat.transform_point3(p.as_vec3()) - rel).length() < 1e-5);
    }

    #[test]
    fn reprojection_maps_a_static_point_to_last_frames_clip_position() {
        let proj = Projection::default();
        let path = CameraPath::catmull_rom(
            "t",
            &[
                Waypoint::new(DVec3::new(1e6, 1.7, 0.0), DVec3::new(1e6, 1.7, -10.0)),
                Waypoint::new(
                    DVec3::new(1e6 + 5.0, 1.7, -5.0),
                    DVec3::new(1e6 + 10.0, 1.7, -5.0),
                ),
            ],
            10,
            proj,
        )
        .unwrap();
        let point = DVec3::new(1e6 + 1.0, 2.0, -20.0);
        for f in path.frames(1.0).skip(1) {
            let prev_cam = path.camera(f.index - 1).unwrap();
            let expected =
                f.previous.view_projection * (point - prev_cam.eye).as_vec3().extend(1.0);
            let got = f.reproject * (point - f.camera.eye).as_vec3().extend(1.0);
            let (e, g) = (expected / expected.w, got / got.w);
            // Relative: the point leaves the view (NDC x in the hundreds) as the camera turns.
            assert!(
                (e - g).length() < 1e-5 * e.length().max(1.0),
                "frame {}: {e} vs {g}",
                f.index
            );
        }
        let first = path.frame(0, 1.0).unwrap();
        assert!(first.cut);
        assert_eq!(first.previous, first.current);
    }

    #[test]
    fn catmull_rom_passes_through_waypoints_and_cuts_are_marked() {
        let w = [
            Waypoint::new(DVec3::ZERO, DVec3::NEG_Z),
            Waypoint::new(DVec3::X * 4.0, DVec3::new(4.0, 0.0, -1.0)),
            Waypoint::new(DVec3::new(4.0, 0.0, 4.0), DVec3::new(5.0, 0.0, 4.0)),
        ];
        let a = CameraPath::catmull_rom("a", &w, 8, Projection::default()).unwrap();
        assert_eq!(a.len(), 17);
        assert_eq!(a.camera(0).unwrap().eye, w[0].eye);
        assert!((a.camera(8).unwrap().eye - w[1].eye).length() < 1e-12);
        assert_eq!(a.camera(16).unwrap().eye, w[2].eye);
        let b =
            CameraPath::orbit("b", DVec3::ZERO, 10.0, 2.0, 5, 1.0, Projection::default()).unwrap();
        let ab = a.then_cut(b);
        assert_eq!(ab.len(), 22);
        let cut = ab.frame(17, 1.0).unwrap();
        assert!(cut.cut);
        assert_eq!(cut.previous, cut.current);
        assert!(!ab.frame(18, 1.0).unwrap().cut);
    }

    /// Camera paths and anything else that stores a projection keep this exact text: the
    /// types may move between crates, their serialized form may not.
    #[test]
    fn projection_and_depth_convention_serialize_to_a_fixed_form() {
        fn text<T: Serialize>(value: &T) -> String {
            serde_json::to_string(value).unwrap()
        }
        assert_eq!(text(&DepthConvention::Standard), r#""standard""#);
        assert_eq!(text(&DepthConvention::Reverse), r#""reverse""#);
        assert_eq!(
            text(&Projection::default()),
            r#"{"kind":"perspective","fov_y_rad":1.0471976,"near":0.1,"far":null,"depth":"reverse"}"#
        );
        let ortho = Projection::Orthographic {
            half_height: 5.0,
            near: 0.5,
            far: 100.0,
            depth: DepthConvention::Standard,
        };
        assert_eq!(
            text(&ortho),
            r#"{"kind":"orthographic","half_height":5.0,"near":0.5,"far":100.0,"depth":"standard"}"#
        );
        let back: Projection = serde_json::from_str(&text(&ortho)).unwrap();
        assert_eq!(back, ortho);
        let frame = CameraPath::new(
            "t",
            vec![PathKey {
                camera: Camera::looking_at(DVec3::ZERO, DVec3::NEG_Z),
                cut: false,
            }],
        )
        .unwrap()
        .to_json();
        assert!(frame.contains(r#""depth": "reverse""#), "{frame}");
    }

    #[test]
    fn json_round_trips_and_defaults_apply() {
        let text = r#"{"frames": [
            {"eye": [0, 1.7, 0], "target": [0, 1.7, -1], "up": [0, 1, 0], "fov_y_deg": 60, "near": 0.1, "far": null},
            {"eye": [1, 1.7, 0], "target": [1, 1.7, -1], "fov_y_deg": 90, "near": 0.5, "far": 1000, "cut": true}
        ]}"#;
        let p = CameraPath::from_json_str(text, "t.json").unwrap();
        assert_eq!(p.len(), 2);
        assert_eq!(p.camera(0).unwrap().projection.far(), None);
        assert_eq!(p.camera(1).unwrap().projection.far(), Some(1000.0));
        assert!(p.keys()[1].cut);
        let again = CameraPath::from_json_str(&p.to_json(), "t.json").unwrap();
        assert_eq!(again.keys(), p.keys());
    }

    #[test]
    fn a_huge_up_vector_still_gives_a_finite_view() {
        let text = r#"{"frames": [{"eye": [0,0,0], "target": [0,0,-1], "up": [0,1e20,0]}]}"#;
        let p = CameraPath::from_json_str(text, "t.json").unwrap();
        let cam = p.camera(0).unwrap();
        let m = cam.matrices(16.0 / 9.0);
        assert!(m.view.is_finite() && m.view_projection.is_finite(), "{m:?}");
        let small = Camera { up: Vec3::Y, ..cam };
        assert!(m.view.abs_diff_eq(small.view_relative(), 1e-6));
    }

    #[test]
    fn a_path_without_up_may_look_straight_down_or_up() {
        let text = r#"{"frames": [
            {"eye": [0, 10, 0], "target": [0, 0, 0]},
            {"eye": [0, 10, 0], "target": [0.000001, 0, 0]},
            {"eye": [0, 0, 0], "target": [0, 3, 0]},
            {"eye": [0, 10, 0], "target": [1, 0, 0]}
        ]}"#;
        let path = CameraPath::from_json_str(text, "top-down").unwrap();
        let ups: Vec<Vec3> = path.keys.iter().map(|k| k.camera.up).collect();
        assert_eq!(ups, [Vec3::NEG_Z, Vec3::NEG_Z, Vec3::Z, Vec3::Y]);
        // Looking down, the top of the image faces -Z: a point north of the target is above
        // the centre of the image.
        let view = path.keys[0].camera.view_relative();
        let north = view.transform_point3(Vec3::new(0.0, -10.0, -1.0));
        assert!(north.y > 0.0 && north.x.abs() < 1e-6, "{north}");
        // Written back with the up it used, the path reads the same.
        let again = CameraPath::from_json_str(&path.to_json(), "again").unwrap();
        let again_ups: Vec<Vec3> = again.keys.iter().map(|k| k.camera.up).collect();
        assert_eq!(again_ups, ups);
    }

    #[test]
    fn malformed_json_paths_name_the_frame_and_field() {
        let frame = |body: &str| {
            format!(r#"{{"frames": [{{"eye": [0,0,0], "target": [0,0,-1]}}, {{{body}}}]}}"#)
        };
        let cases = [
            (frame(r#""eye": [1,2,3], "target": [1,2,3]"#), "target"),
            (
                frame(r#""eye": [0,0,0], "target": [0,5,0], "up": [0,1,0]"#),
                "up",
            ),
            (
                frame(r#""eye": [0,0,0], "target": [0,0,-1], "up": [0,0,0]"#),
                "up",
            ),
            (
                frame(r#""eye": [0,0,0], "target": [0,0,-1], "near": 0"#),
                "near",
            ),
            (
                frame(r#""eye": [0,0,0], "target": [0,0,-1], "near": -1"#),
                "near",
            ),
            (
                frame(r#""eye": [0,0,0], "target": [0,0,-1], "near": 1, "far": 1"#),
                "far",
            ),
            (
                frame(r#""eye": [0,0,0], "target": [0,0,-1], "near": 1, "far": 0.5"#),
                "far",
            ),
            (
                frame(r#""eye": [0,0,0], "target": [0,0,-1], "fov_y_deg": 0"#),
                "fov_y_deg",
            ),
            // Accepted by the range checks, but the projection overflows f32.
            (
                frame(r#""eye": [0,0,0], "target": [0,0,-1], "fov_y_deg": 1e-37"#),
                "fov_y_deg",
            ),
            // Finite at a square viewport, infinite at 32768 x 1.
            (
                frame(r#""eye": [0,0,0], "target": [0,0,-1], "fov_y_deg": 1e-33"#),
                "fov_y_deg",
            ),
            (
                frame(r#""eye": [0,0,0], "target": [0,0,-1], "fov_y_deg": 180"#),
                "fov_y_deg",
            ),
            (
                frame(r#""eye": [0,0,0], "target": [0,0,-1], "fov_y_deg": -5"#),
                "fov_y_deg",
            ),
            (
                frame(r#""eye": [1e39,0,0], "target": [0,0,-1], "up": [0, 1e39, 0]"#),
                "up",
            ),
            (
                frame(r#""eye": [0,0,0], "target": [0,0,-1], "near": 1e-50"#),
                "near",
            ),
        ];
        for (text, field) in cases {
            match CameraPath::from_json_str(&text, "bad.json") {
                Err(SceneError::CameraPath {
                    frame: Some(1),
                    field: f,
                    file,
                    ..
                }) => {
                    assert_eq!(f, field, "{text}");
                    assert_eq!(file, "bad.json");
                }
                other => panic!("{text}: expected a camera-path error on frame 1, got {other:?}"),
            }
        }
        for text in [
            r#"{"frames": []}"#,
            r#"{"frames": [{"eye": [NaN, 0, 0], "target": [0,0,-1]}]}"#,
            r#"{"frames": [{"eye": [0, 0], "target": [0,0,-1]}]}"#,
            r#"{"frames": [{"eye": [0, 0, 0], "target": [0,0,-1], "fov": 3}]}"#,
            "not json",
        ] {
            assert!(
                matches!(
                    CameraPath::from_json_str(text, "bad.json"),
                    Err(SceneError::CameraPath { .. })
                ),
                "{text}"
            );
        }
        // The key is named and the location said once; a bare array says what is expected.
        let e = CameraPath::from_json_str(
            r#"{"frames": [{"eye": [0, 0], "target": [0,0,-1]}]}"#,
            "bad.json",
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.starts_with("bad.json: camera path: frames[0].eye: line 1"),
            "{e}"
        );
        assert_eq!(e.matches("line").count(), 1, "{e}");
        let e = CameraPath::from_json_str(r#"[{"eye": [0,0,0], "target": [0,0,-1]}]"#, "bare.json")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("a bare array: a camera path is an object"),
            "{e}"
        );
    }
}
