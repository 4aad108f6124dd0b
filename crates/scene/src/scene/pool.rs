//! Ranges of the scene's shared vertex and index arrays: a mesh added at run time takes the
//! first free range it fits in, a removed mesh's range becomes free, and the arrays grow only
//! when nothing fits (a renderer then grows its buffers, copying on the GPU).

/// Free ranges of a growable array: first fit, neighbours coalesced.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub(crate) struct RangePool {
    /// Free ranges `(start, len)`, sorted by start, never touching one another.
    free: Vec<(u32, u32)>,
    /// The array's length: a range that fits nowhere starts here.
    end: u32,
}

impl RangePool {
    /// A pool over an array of `end` elements, all of them taken.
    pub(crate) fn full(end: u32) -> Self {
        RangePool {
            free: Vec::new(),
            end,
        }
    }

    /// The array's length.
    #[cfg(test)]
    pub(crate) fn end(&self) -> u32 {
        self.end
    }

    /// Elements free inside the array.
    #[cfg(test)]
    pub(crate) fn free_len(&self) -> u64 {
        self.free.iter().map(|&(_, l)| u64::from(l)).sum()
    }

    /// The start of a range of `len` elements: the first free range that holds it, else the
    /// end of the array (which grows). `None` when the array would pass `u32::MAX` elements.
    /// Counts everything below `end` as taken: the array grew past the pool (levels of
    /// detail after a scene's indices).
    pub(crate) fn extend_to(&mut self, end: u32) {
        self.end = self.end.max(end);
    }

    pub(crate) fn allocate(&mut self, len: u32) -> Option<u32> {
        if len == 0 {
            return Some(self.end);
        }
        if let Some(i) = self.free.iter().position(|&(_, l)| l >= len) {
            let (start, l) = self.free[i];
            if l == len {
                self.free.remove(i);
            } else {
                self.free[i] = (start + len, l - len);
            }
            return Some(start);
        }
        let start = self.end;
        self.end = start.checked_add(len)?;
        Some(start)
    }

    /// Gives back `len` elements from `start` (a range [`Self::allocate`] returned, or part of
    /// the array as built).
    pub(crate) fn release(&mut self, start: u32, len: u32) {
        if len == 0 {
            return;
        }
        debug_assert!(start.checked_add(len).is_some_and(|e| e <= self.end));
        let i = self.free.partition_point(|&(s, _)| s < start);
        debug_assert!(i == 0 || self.free[i - 1].0 + self.free[i - 1].1 <= start);
        debug_assert!(i == self.free.len() || start + len <= self.free[i].0);
        let joins_prev = i > 0 && self.free[i - 1].0 + self.free[i - 1].1 == start;
        let joins_next = i < self.free.len() && start + len == self.free[i].0;
        match (joins_prev, joins_next) {
            (true, true) => {
                self.free[i - 1].1 += len + self.free[i].1;
                self.free.remove(i);
            }
            (true, false) => self.free[i - 1].1 += len,
            (false, true) => self.free[i] = (start, len + self.free[i].1),
            (false, false) => self.free.insert(i, (start, len)),
        }
    }
}

/// Writes `data` at `start` of `array`, growing it as needed.
pub(crate) fn write_range<T: Copy + Default>(array: &mut Vec<T>, start: u32, data: &[T]) {
    let start = start as usize;
    if array.len() < start + data.len() {
        array.resize(start + data.len(), T::default());
    }
    array[start..start + data.len()].copy_from_slice(data);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn freed_ranges_are_reused_first_fit_and_coalesce() {
        let mut p = RangePool::full(100);
        assert_eq!(p.allocate(10), Some(100));
        p.release(10, 5);
        p.release(20, 5);
        assert_eq!(p.free_len(), 10);
        // Too big for either hole: the array grows.
        assert_eq!(p.allocate(6), Some(110));
        // 15..20 freed joins both neighbours into 10..25.
        p.release(15, 5);
        assert_eq!(p.free, vec![(10, 15)]);
        assert_eq!(p.allocate(15), Some(10));
        assert!(p.free.is_empty());
        assert_eq!(p.end(), 116);
        let mut q = RangePool::full(u32::MAX - 1);
        assert_eq!(q.allocate(2), None);
    }
}
