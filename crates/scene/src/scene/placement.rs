//! A hash of where the scene's instances sit, for data baked from one arrangement of them (a
//! precomputed visible set).

use super::{clusters, Scene};

impl Scene {
    /// [`Scene::geometry_fingerprint`] and, for every instance slot, its mesh, whether it is
    /// drawn and its transform, hashed (FNV-1a): equal for two scenes only when the same
    /// geometry sits in the same places.
    pub fn placement_fingerprint(&self) -> u64 {
        let mut h = clusters::fnv1a(
            clusters::FNV_OFFSET,
            &self.geometry_fingerprint().to_le_bytes(),
        );
        for inst in self.instances() {
            h = clusters::fnv1a(h, &inst.mesh.0.to_le_bytes());
            h = clusters::fnv1a(h, &[u8::from(inst.flags.is_drawn())]);
            for v in inst.transform.linear.to_cols_array() {
                h = clusters::fnv1a(h, &v.to_bits().to_le_bytes());
            }
            for v in inst.transform.translation.to_array() {
                h = clusters::fnv1a(h, &v.to_bits().to_le_bytes());
            }
        }
        h
    }
}
