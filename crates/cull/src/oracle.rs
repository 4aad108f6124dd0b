//! Oracle metrics: compare what a culling technique drew with what is exactly visible.
//!
//! The exact visible set V is every instance that owns at least one pixel of a full-resolution,
//! unculled id render. With D the drawn set: false negatives FN = V \ D (visible objects wrongly
//! culled: a correctness bug), false positives FP = D \ V (hidden objects drawn anyway: wasted
//! work).

use serde::{Deserialize, Serialize};

use crate::CullError;

/// A set of instance ids as a bitset (`Vec<u64>`, bit `id % 64` of word `id / 64`). Memory is
/// `max_id / 8` bytes, at most 512 MiB for `u32::MAX`.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct InstanceSet {
    words: Vec<u64>,
}

impl InstanceSet {
    pub fn new() -> Self {
        Self::default()
    }

    /// An empty set with room for ids below `instance_count` without reallocating.
    pub fn with_capacity(instance_count: u32) -> Self {
        InstanceSet {
            words: Vec::with_capacity((instance_count as usize).div_ceil(64)),
        }
    }

    /// Inserts `id`; returns whether it was new.
    pub fn insert(&mut self, id: u32) -> bool {
        let (w, b) = (id as usize / 64, id % 64);
        if w >= self.words.len() {
            self.words.resize(w + 1, 0);
        }
        let was = self.words[w] >> b & 1 == 1;
        self.words[w] |= 1 << b;
        !was
    }

    pub fn contains(&self, id: u32) -> bool {
        self.words
            .get(id as usize / 64)
            .is_some_and(|w| w >> (id % 64) & 1 == 1)
    }

    pub fn len(&self) -> usize {
        self.words.iter().map(|w| w.count_ones() as usize).sum()
    }

    pub fn is_empty(&self) -> bool {
        self.words.iter().all(|&w| w == 0)
    }

    /// Ids in increasing order.
    pub fn iter(&self) -> impl Iterator<Item = u32> + '_ {
        self.words.iter().enumerate().flat_map(|(wi, &word)| {
            let mut bits = word;
            std::iter::from_fn(move || {
                if bits == 0 {
                    return None;
                }
                let b = bits.trailing_zeros();
                bits &= bits - 1;
                Some(wi as u32 * 64 + b)
            })
        })
    }

    /// Ids in `self` and not in `other`.
    pub fn difference(&self, other: &InstanceSet) -> InstanceSet {
        let words = self
            .words
            .iter()
            .enumerate()
            .map(|(i, &w)| w & !other.words.get(i).copied().unwrap_or(0))
            .collect();
        InstanceSet { words }
    }

    /// Number of ids in both sets.
    pub fn intersection_len(&self, other: &InstanceSet) -> usize {
        self.words
            .iter()
            .zip(&other.words)
            .map(|(a, b)| (a & b).count_ones() as usize)
            .sum()
    }

    /// The largest id, if any.
    pub fn max_id(&self) -> Option<u32> {
        self.words
            .iter()
            .enumerate()
            .rev()
            .find(|(_, &w)| w != 0)
            .map(|(i, &w)| i as u32 * 64 + 63 - w.leading_zeros())
    }
}

impl FromIterator<u32> for InstanceSet {
    fn from_iter<I: IntoIterator<Item = u32>>(iter: I) -> Self {
        let mut s = InstanceSet::new();
        for id in iter {
            s.insert(id);
        }
        s
    }
}

/// The exact visible set: every id that owns at least one pixel, except `background`.
pub fn visible_set_from_id_buffer(ids: &[u32], background: u32) -> InstanceSet {
    ids.iter().copied().filter(|&id| id != background).collect()
}

/// Per-frame comparison of a drawn set with the exact visible set. Serialized into the frame
/// report.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct CullStats {
    pub instances: u32,
    /// |V|
    pub visible: u32,
    /// |D|
    pub drawn: u32,
    /// instances - |D|
    pub culled: u32,
    /// |V and D|
    pub visible_drawn: u32,
    /// |V \ D|: visible but culled. Any non-zero value is a culling bug.
    pub false_negatives: u32,
    /// |D \ V|: drawn though hidden.
    pub false_positives: u32,
    /// FN / |V| (0 when nothing is visible).
    pub false_negative_rate: f64,
    /// FP / (instances - |V|): share of the hidden instances that were drawn anyway (0 when
    /// nothing is hidden). 1 means no culling at all, 0 perfect culling.
    pub false_positive_rate_of_hidden: f64,
    /// FP / |D|: share of the draws that were wasted (0 when nothing was drawn).
    pub false_positive_share_of_drawn: f64,
    pub false_negative_ids: Vec<u32>,
    pub false_positive_ids: Vec<u32>,
}

fn ratio(num: u32, den: u32) -> f64 {
    if den == 0 {
        0.0
    } else {
        f64::from(num) / f64::from(den)
    }
}

impl CullStats {
    /// Compares `drawn` with the exact `visible` set over `instance_count` instances (ids
    /// `0..instance_count`; an id at or past it in either set is an error).
    pub fn compare(
        visible: &InstanceSet,
        drawn: &InstanceSet,
        instance_count: u32,
    ) -> Result<Self, CullError> {
        for (what, set) in [("visible set", visible), ("drawn set", drawn)] {
            if let Some(id) = set.max_id() {
                if id >= instance_count {
                    return Err(CullError::InstanceIdOutOfRange {
                        what,
                        id,
                        instance_count,
                    });
                }
            }
        }
        let fn_set = visible.difference(drawn);
        let fp_set = drawn.difference(visible);
        // Every count is bounded by instance_count (all ids are below it), so u32 holds it.
        let visible_n = visible.len() as u32;
        let drawn_n = drawn.len() as u32;
        let false_negatives = fn_set.len() as u32;
        let false_positives = fp_set.len() as u32;
        Ok(CullStats {
            instances: instance_count,
            visible: visible_n,
            drawn: drawn_n,
            culled: instance_count - drawn_n,
            visible_drawn: visible.intersection_len(drawn) as u32,
            false_negatives,
            false_positives,
            false_negative_rate: ratio(false_negatives, visible_n),
            false_positive_rate_of_hidden: ratio(false_positives, instance_count - visible_n),
            false_positive_share_of_drawn: ratio(false_positives, drawn_n),
            false_negative_ids: fn_set.iter().collect(),
            false_positive_ids: fp_set.iter().collect(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bitset_basics() {
        let mut s = InstanceSet::new();
        assert!(s.is_empty());
        assert!(s.insert(0));
        assert!(s.insert(63));
        assert!(s.insert(64));
        assert!(s.insert(1000));
        assert!(!s.insert(64));
        assert_eq!(s.len(), 4);
        assert!(s.contains(1000) && !s.contains(999) && !s.contains(u32::MAX));
        assert_eq!(s.iter().collect::<Vec<_>>(), vec![0, 63, 64, 1000]);
        assert_eq!(s.max_id(), Some(1000));
        let t: InstanceSet = [63, 5].into_iter().collect();
        assert_eq!(
            s.difference(&t).iter().collect::<Vec<_>>(),
            vec![0, 64, 1000]
        );
        assert_eq!(s.intersection_len(&t), 1);
        assert_eq!(InstanceSet::new().max_id(), None);
    }

    #[test]
    fn visible_set_skips_background() {
        let bg = u32::MAX;
        let ids = [bg, 3, 3, bg, 7, 0, bg];
        let v = visible_set_from_id_buffer(&ids, bg);
        assert_eq!(v.iter().collect::<Vec<_>>(), vec![0, 3, 7]);
    }

    #[test]
    fn stats_count_both_error_kinds() {
        let visible: InstanceSet = [1, 2, 3, 4].into_iter().collect();
        let drawn: InstanceSet = [2, 3, 4, 5, 6].into_iter().collect();
        let s = CullStats::compare(&visible, &drawn, 10).unwrap();
        assert_eq!(
            (s.visible, s.drawn, s.culled, s.visible_drawn),
            (4, 5, 5, 3)
        );
        assert_eq!(s.false_negative_ids, vec![1]);
        assert_eq!(s.false_positive_ids, vec![5, 6]);
        assert!((s.false_negative_rate - 0.25).abs() < 1e-12);
        assert!((s.false_positive_rate_of_hidden - 2.0 / 6.0).abs() < 1e-12);
        assert!((s.false_positive_share_of_drawn - 0.4).abs() < 1e-12);
        let json = serde_json::to_string(&s).unwrap();
        let back: CullStats = serde_json::from_str(&json).unwrap();
        assert_eq!(back, s);
        assert!(matches!(
            CullStats::compare(&visible, &drawn, 6),
            Err(CullError::InstanceIdOutOfRange {
                what: "drawn set",
                id: 6,
                ..
            })
        ));
    }
}
