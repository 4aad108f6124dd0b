//! Small shared meshes for the procedural worlds. Each stands on y = 0 (or is centred where
//! noted) and is sized in metres so that instance transforms are mostly yaw + scale.

use glam::{Vec2, Vec3};

use crate::scene::Vertex;

/// Geometry under construction: vertices and triangle indices (relative to this mesh).
#[derive(Clone, Debug, Default)]
pub(crate) struct MeshData {
    pub vertices: Vec<Vertex>,
    pub indices: Vec<u32>,
}

impl MeshData {
    fn vertex(&mut self, p: Vec3, n: Vec3, uv: Vec2) -> u32 {
        self.vertices.push(Vertex {
            position: p.to_array(),
            normal: n.to_array(),
            uv: uv.to_array(),
        });
        (self.vertices.len() - 1) as u32
    }

    /// A quad with corners `o`, `o + u`, `o + u + v`, `o + v`, facing `u x v`.
    pub fn quad(&mut self, o: Vec3, u: Vec3, v: Vec3) {
        let n = u.cross(v).normalize_or(Vec3::Y);
        let a = self.vertex(o, n, Vec2::new(0.0, 1.0));
        let b = self.vertex(o + u, n, Vec2::new(1.0, 1.0));
        let c = self.vertex(o + u + v, n, Vec2::new(1.0, 0.0));
        let d = self.vertex(o + v, n, Vec2::new(0.0, 0.0));
        self.indices.extend_from_slice(&[a, b, c, a, c, d]);
    }

    /// One triangle `a, b, c`, facing `(b - a) x (c - a)` (+y where that is zero: a
    /// degenerate triangle still carries a unit normal).
    pub fn triangle(&mut self, a: Vec3, b: Vec3, c: Vec3) {
        let n = (b - a).cross(c - a).normalize_or(Vec3::Y);
        let i = self.vertex(a, n, Vec2::new(0.0, 1.0));
        let j = self.vertex(b, n, Vec2::new(1.0, 1.0));
        let k = self.vertex(c, n, Vec2::new(0.5, 0.0));
        self.indices.extend_from_slice(&[i, j, k]);
    }

    /// An axis-aligned box from `min` to `max`, 6 faces with outward normals (CCW from outside).
    pub fn cuboid(&mut self, min: Vec3, max: Vec3) {
        let s = max - min;
        let (x, y, z) = (Vec3::X * s.x, Vec3::Y * s.y, Vec3::Z * s.z);
        self.quad(Vec3::new(min.x, min.y, max.z), x, y); // +z
        self.quad(Vec3::new(max.x, min.y, min.z), -x, y); // -z
        self.quad(Vec3::new(max.x, min.y, max.z), -z, y); // +x
        self.quad(min, z, y); // -x
        self.quad(Vec3::new(min.x, max.y, max.z), x, -z); // +y
        self.quad(min, x, z); // -y
    }

    /// A vertical cylinder of `segments` sides from y = `y0` to `y1`, with caps.
    pub fn cylinder(&mut self, radius: f32, y0: f32, y1: f32, segments: u32) {
        let segments = segments.max(3);
        let ring = |i: u32| {
            let a = std::f32::consts::TAU * i as f32 / segments as f32;
            Vec3::new(a.cos(), 0.0, -a.sin())
        };
        for i in 0..segments {
            let (d0, d1) = (ring(i), ring(i + 1));
            let p0 = d0 * radius;
            let p1 = d1 * radius;
            let u0 = i as f32 / segments as f32;
            let u1 = (i + 1) as f32 / segments as f32;
            let a = self.vertex(p0 + Vec3::Y * y0, d0, Vec2::new(u0, 1.0));
            let b = self.vertex(p1 + Vec3::Y * y0, d1, Vec2::new(u1, 1.0));
            let c = self.vertex(p1 + Vec3::Y * y1, d1, Vec2::new(u1, 0.0));
            let d = self.vertex(p0 + Vec3::Y * y1, d0, Vec2::new(u0, 0.0));
            self.indices.extend_from_slice(&[a, b, c, a, c, d]);
            let top_c = self.vertex(Vec3::Y * y1, Vec3::Y, Vec2::splat(0.5));
            let t0 = self.vertex(p0 + Vec3::Y * y1, Vec3::Y, Vec2::ZERO);
            let t1 = self.vertex(p1 + Vec3::Y * y1, Vec3::Y, Vec2::X);
            self.indices.extend_from_slice(&[top_c, t0, t1]);
            let bot_c = self.vertex(Vec3::Y * y0, Vec3::NEG_Y, Vec2::splat(0.5));
            let b0 = self.vertex(p0 + Vec3::Y * y0, Vec3::NEG_Y, Vec2::ZERO);
            let b1 = self.vertex(p1 + Vec3::Y * y0, Vec3::NEG_Y, Vec2::X);
            self.indices.extend_from_slice(&[bot_c, b1, b0]);
        }
    }
}

/// Unit cube standing on y = 0: x, z in [-0.5, 0.5], y in [0, 1]. Scaled per instance into
/// buildings, walls, slabs, tables.
pub(crate) fn unit_box() -> MeshData {
    let mut m = MeshData::default();
    m.cuboid(Vec3::new(-0.5, 0.0, -0.5), Vec3::new(0.5, 1.0, 0.5));
    m
}

/// A horizontal unit square at y = 0 facing +y (ground, floors, ceilings seen from below are
/// drawn by a flipped instance).
pub(crate) fn ground_quad() -> MeshData {
    let mut m = MeshData::default();
    m.quad(Vec3::new(-0.5, 0.0, 0.5), Vec3::X, Vec3::NEG_Z);
    m
}

/// A stepped tower: a wide base and a narrower top, 1 unit tall in total.
pub(crate) fn tower() -> MeshData {
    let mut m = MeshData::default();
    m.cuboid(Vec3::new(-0.5, 0.0, -0.5), Vec3::new(0.5, 0.7, 0.5));
    m.cuboid(Vec3::new(-0.35, 0.7, -0.35), Vec3::new(0.35, 1.0, 0.35));
    m
}

/// A car, about 4.2 x 1.5 x 1.8 m, long along x.
pub(crate) fn car() -> MeshData {
    let mut m = MeshData::default();
    m.cuboid(Vec3::new(-2.1, 0.25, -0.9), Vec3::new(2.1, 0.95, 0.9));
    m.cuboid(Vec3::new(-1.1, 0.95, -0.8), Vec3::new(1.0, 1.5, 0.8));
    for (x, z) in [(-1.4, -0.9), (1.4, -0.9), (-1.4, 0.75), (1.4, 0.75)] {
        m.cuboid(
            Vec3::new(x - 0.3, 0.0, z),
            Vec3::new(x + 0.3, 0.5, z + 0.15),
        );
    }
    m
}

/// A street lamp: a 5 m pole and a head.
pub(crate) fn lamp() -> MeshData {
    let mut m = MeshData::default();
    m.cylinder(0.08, 0.0, 5.0, 8);
    m.cuboid(Vec3::new(-0.1, 4.9, -0.1), Vec3::new(0.8, 5.1, 0.1));
    m
}

/// A bench, 1.8 m long along x.
pub(crate) fn bench() -> MeshData {
    let mut m = MeshData::default();
    m.cuboid(Vec3::new(-0.9, 0.42, -0.25), Vec3::new(0.9, 0.48, 0.25));
    m.cuboid(Vec3::new(-0.9, 0.48, 0.2), Vec3::new(0.9, 0.9, 0.25));
    for x in [-0.8, 0.7] {
        m.cuboid(Vec3::new(x, 0.0, -0.2), Vec3::new(x + 0.1, 0.42, 0.2));
    }
    m
}

/// A thin vertical pane, 1 x 1, centred on x, standing on y = 0 (glass: blended).
pub(crate) fn pane() -> MeshData {
    let mut m = MeshData::default();
    m.cuboid(Vec3::new(-0.5, 0.0, -0.01), Vec3::new(0.5, 1.0, 0.01));
    m
}

/// A tree trunk: a tapered-looking cylinder 1 unit tall, radius 0.5 (scaled per tree).
pub(crate) fn trunk() -> MeshData {
    let mut m = MeshData::default();
    m.cylinder(0.5, 0.0, 1.0, 10);
    m
}

/// A foliage card: three vertical quads crossed at 60 degrees, 1 x 1, standing on y = 0.
/// Alpha-tested and double-sided, like real vegetation cards.
pub(crate) fn foliage_card() -> MeshData {
    let mut m = MeshData::default();
    for k in 0..3 {
        let a = std::f32::consts::PI * k as f32 / 3.0;
        let u = Vec3::new(a.cos(), 0.0, a.sin());
        m.quad(-u * 0.5, u, Vec3::Y);
    }
    m
}

/// A rock: a squat irregular-looking pair of boxes, about 1 m wide.
pub(crate) fn rock() -> MeshData {
    let mut m = MeshData::default();
    m.cuboid(Vec3::new(-0.5, 0.0, -0.4), Vec3::new(0.4, 0.5, 0.45));
    m.cuboid(Vec3::new(-0.3, 0.4, -0.3), Vec3::new(0.25, 0.7, 0.2));
    m
}

/// A hay bale: a cylinder on its side would need a rotation; keep it upright, 1.2 m wide.
pub(crate) fn bale() -> MeshData {
    let mut m = MeshData::default();
    m.cylinder(0.6, 0.0, 1.2, 12);
    m
}

/// A table (1.6 x 0.8 m) with four legs.
pub(crate) fn table() -> MeshData {
    let mut m = MeshData::default();
    m.cuboid(Vec3::new(-0.8, 0.72, -0.4), Vec3::new(0.8, 0.76, 0.4));
    for (x, z) in [(-0.75, -0.35), (0.7, -0.35), (-0.75, 0.3), (0.7, 0.3)] {
        m.cuboid(Vec3::new(x, 0.0, z), Vec3::new(x + 0.05, 0.72, z + 0.05));
    }
    m
}

/// A chair.
pub(crate) fn chair() -> MeshData {
    let mut m = MeshData::default();
    m.cuboid(Vec3::new(-0.22, 0.44, -0.22), Vec3::new(0.22, 0.48, 0.22));
    m.cuboid(Vec3::new(-0.22, 0.48, 0.18), Vec3::new(0.22, 0.95, 0.22));
    for (x, z) in [(-0.22, -0.22), (0.18, -0.22), (-0.22, 0.18), (0.18, 0.18)] {
        m.cuboid(Vec3::new(x, 0.0, z), Vec3::new(x + 0.04, 0.44, z + 0.04));
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shapes_have_unit_normals_and_valid_indices() {
        for (name, m) in [
            ("box", unit_box()),
            ("ground", ground_quad()),
            ("tower", tower()),
            ("car", car()),
            ("lamp", lamp()),
            ("bench", bench()),
            ("pane", pane()),
            ("trunk", trunk()),
            ("card", foliage_card()),
            ("rock", rock()),
            ("bale", bale()),
            ("table", table()),
            ("chair", chair()),
        ] {
            assert!(!m.indices.is_empty() && m.indices.len() % 3 == 0, "{name}");
            assert!(
                m.indices.iter().all(|&i| (i as usize) < m.vertices.len()),
                "{name}"
            );
            for v in &m.vertices {
                let n = Vec3::from_array(v.normal);
                assert!((n.length() - 1.0).abs() < 1e-5, "{name}");
                assert!(v.position[1] >= -1e-6, "{name} goes below y = 0");
            }
        }
    }

    #[test]
    fn box_faces_wind_counter_clockwise_seen_from_outside() {
        let m = unit_box();
        for t in m.indices.chunks(3) {
            let p = |i: u32| Vec3::from_array(m.vertices[i as usize].position);
            let face_n = (p(t[1]) - p(t[0])).cross(p(t[2]) - p(t[0]));
            let n = Vec3::from_array(m.vertices[t[0] as usize].normal);
            assert!(
                face_n.dot(n) > 0.0,
                "triangle {t:?} winds against its normal"
            );
        }
    }
}
