//! The inner loop: which pixel centres of a tile lie robustly inside one edge, as a bit mask per
//! pixel row. A scalar reference and the SIMD paths (SSE2 on x86_64, NEON on aarch64; both are
//! baseline features of their architectures, so no runtime detection) compute the same masks
//! bit for bit: every value is an integer below 2^53 in f64, so every operation is exact and
//! the order of operations cannot change a result.

/// Subpixel units per pixel: vertices snap to 1/256 of a pixel (8 bits, as lavapipe and most
/// desktop rasterizers do; coarser GPUs are covered by the snapping margin).
pub(crate) const SUB: f64 = 256.0;

/// An edge function `e(X, Y) = a X + b Y + c` over subpixel coordinates, positive inside its
/// triangle; a pixel centre counts as inside only where `e >= margin`, the margin covering how
/// far the GPU's snapped edge can lie from this one.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Edge {
    pub a: f64,
    pub b: f64,
    pub c: f64,
    pub margin: f64,
}

impl Edge {
    #[inline]
    pub fn at(&self, x: f64, y: f64) -> f64 {
        self.a * x + self.b * y + self.c
    }

    /// Whether every pixel centre of the rectangle `[x0, x1] x [y0, y1]` (subpixel coordinates
    /// of the first and last centres) is robustly inside (`Some(true)`), none is
    /// (`Some(false)`), or some are (`None`): the edge is linear, so its corners decide.
    #[inline]
    pub fn classify(&self, x0: f64, y0: f64, x1: f64, y1: f64) -> Option<bool> {
        let (lo_x, hi_x) = if self.a >= 0.0 { (x0, x1) } else { (x1, x0) };
        let (lo_y, hi_y) = if self.b >= 0.0 { (y0, y1) } else { (y1, y0) };
        if self.at(lo_x, lo_y) >= self.margin {
            Some(true)
        } else if self.at(hi_x, hi_y) < self.margin {
            Some(false)
        } else {
            None
        }
    }
}

/// Which implementation computes the masks. `Simd` is the architecture's (SSE2, NEON) and falls
/// back to the scalar loop elsewhere; tests run both and compare.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Kernel {
    Scalar,
    #[default]
    Simd,
}

impl Kernel {
    /// The SIMD instruction set `Simd` uses on this build, or "scalar".
    pub fn simd_name() -> &'static str {
        if cfg!(target_arch = "x86_64") {
            "sse2"
        } else if cfg!(target_arch = "aarch64") {
            "neon"
        } else {
            "scalar"
        }
    }
}

/// The low `width` bits.
#[inline]
pub(crate) fn low_bits(width: u32) -> u32 {
    if width >= 32 {
        u32::MAX
    } else {
        (1u32 << width) - 1
    }
}

/// `out[r]` bit `k` set where the centre `(x0 + SUB k, y0 + SUB r)` is robustly inside `e`,
/// for `k < width` (at most 32) and every row of `out`.
#[inline]
pub(crate) fn edge_rows(kernel: Kernel, e: &Edge, x0: f64, y0: f64, width: u32, out: &mut [u32]) {
    debug_assert!(width <= 32);
    match kernel {
        Kernel::Scalar => edge_rows_scalar(e, x0, y0, width, out),
        Kernel::Simd => edge_rows_simd(e, x0, y0, width, out),
    }
}

/// The reference: one centre at a time.
pub(crate) fn edge_rows_scalar(e: &Edge, x0: f64, y0: f64, width: u32, out: &mut [u32]) {
    let step = e.a * SUB;
    for (r, m) in out.iter_mut().enumerate() {
        let row = e.at(x0, y0 + SUB * r as f64);
        let mut bits = 0u32;
        for k in 0..width {
            if row + step * f64::from(k) >= e.margin {
                bits |= 1 << k;
            }
        }
        *m = bits;
    }
}

#[cfg(target_arch = "x86_64")]
fn edge_rows_simd(e: &Edge, x0: f64, y0: f64, width: u32, out: &mut [u32]) {
    // SAFETY: SSE2 is part of the x86_64 baseline: every x86_64 CPU has it, and the intrinsics
    // below touch no memory.
    unsafe { edge_rows_sse2(e, x0, y0, width, out) }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "sse2")]
fn edge_rows_sse2(e: &Edge, x0: f64, y0: f64, width: u32, out: &mut [u32]) {
    use std::arch::x86_64::{
        _mm_add_pd, _mm_cmpge_pd, _mm_movemask_pd, _mm_mul_pd, _mm_set1_pd, _mm_set_pd,
    };
    let step = e.a * SUB;
    // Columns 0..8 of a row as four pairs (every value an exact integer, so adding a pair's
    // offset to the row gives what stepping column by column would).
    let s = _mm_set1_pd(step);
    let pairs = [
        _mm_mul_pd(s, _mm_set_pd(1.0, 0.0)),
        _mm_mul_pd(s, _mm_set_pd(3.0, 2.0)),
        _mm_mul_pd(s, _mm_set_pd(5.0, 4.0)),
        _mm_mul_pd(s, _mm_set_pd(7.0, 6.0)),
    ];
    let eight = _mm_set1_pd(8.0 * step);
    let margin = _mm_set1_pd(e.margin);
    let keep = low_bits(width);
    for (r, m) in out.iter_mut().enumerate() {
        let mut base = _mm_set1_pd(e.at(x0, y0 + SUB * r as f64));
        let mut bits = 0u32;
        let mut k = 0;
        while k < width {
            let ge = |p| _mm_movemask_pd(_mm_cmpge_pd(_mm_add_pd(base, p), margin)) as u32;
            bits |= (ge(pairs[0]) | ge(pairs[1]) << 2 | ge(pairs[2]) << 4 | ge(pairs[3]) << 6) << k;
            base = _mm_add_pd(base, eight);
            k += 8;
        }
        *m = bits & keep;
    }
}

#[cfg(target_arch = "aarch64")]
fn edge_rows_simd(e: &Edge, x0: f64, y0: f64, width: u32, out: &mut [u32]) {
    // SAFETY: NEON (Advanced SIMD) is part of the aarch64 baseline, and the intrinsics below
    // touch no memory.
    unsafe { edge_rows_neon(e, x0, y0, width, out) }
}

#[cfg(target_arch = "aarch64")]
#[target_feature(enable = "neon")]
fn edge_rows_neon(e: &Edge, x0: f64, y0: f64, width: u32, out: &mut [u32]) {
    use std::arch::aarch64::{
        float64x2_t, vaddq_f64, vcgeq_f64, vdupq_n_f64, vgetq_lane_u64, vmulq_f64, vsetq_lane_f64,
    };
    let step = e.a * SUB;
    // Columns 0..8 of a row as four pairs, as the SSE2 path.
    let s = vdupq_n_f64(step);
    let pair = |lo: f64, hi: f64| vmulq_f64(s, vsetq_lane_f64::<1>(hi, vdupq_n_f64(lo)));
    let pairs = [
        pair(0.0, 1.0),
        pair(2.0, 3.0),
        pair(4.0, 5.0),
        pair(6.0, 7.0),
    ];
    let eight = vdupq_n_f64(8.0 * step);
    let margin = vdupq_n_f64(e.margin);
    let keep = low_bits(width);
    for (r, m) in out.iter_mut().enumerate() {
        let mut base = vdupq_n_f64(e.at(x0, y0 + SUB * r as f64));
        let mut bits = 0u32;
        let mut k = 0;
        while k < width {
            let ge = |p: float64x2_t| {
                let c = vcgeq_f64(vaddq_f64(base, p), margin);
                ((vgetq_lane_u64::<0>(c) & 1) | ((vgetq_lane_u64::<1>(c) & 1) << 1)) as u32
            };
            bits |= (ge(pairs[0]) | ge(pairs[1]) << 2 | ge(pairs[2]) << 4 | ge(pairs[3]) << 6) << k;
            base = vaddq_f64(base, eight);
            k += 8;
        }
        *m = bits & keep;
    }
}

#[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
fn edge_rows_simd(e: &Edge, x0: f64, y0: f64, width: u32, out: &mut [u32]) {
    edge_rows_scalar(e, x0, y0, width, out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn simd_rows_equal_the_scalar_reference() {
        // Edges through a tile in every direction, margins of zero and more, widths odd and even.
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = |range: i64| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state % (2 * range as u64 + 1)) as i64 - range
        };
        for _ in 0..20_000 {
            let a = next(1 << 20) as f64;
            let b = next(1 << 20) as f64;
            let x0 = (next(4096) * 256 + 128) as f64;
            let y0 = (next(4096) * 256 + 128) as f64;
            let c = -(a * x0 + b * y0) + next(1 << 28) as f64;
            let e = Edge {
                a,
                b,
                c,
                margin: next(1 << 20).unsigned_abs() as f64,
            };
            let width = 1 + next(16).unsigned_abs() as u32 * 2 - (next(1).unsigned_abs() as u32);
            let width = width.clamp(1, 32);
            let mut s = [0u32; 9];
            let mut v = [0u32; 9];
            edge_rows_scalar(&e, x0, y0, width, &mut s);
            edge_rows(Kernel::Simd, &e, x0, y0, width, &mut v);
            assert_eq!(s, v, "{e:?} width {width}");
        }
    }

    #[test]
    fn classify_agrees_with_the_rows() {
        let e = Edge {
            a: 3.0,
            b: -2.0,
            c: 100.0,
            margin: 10.0,
        };
        let (x0, y0) = (128.0, 128.0 + 256.0 * 4.0);
        let mut rows = [0u32; 8];
        edge_rows_scalar(&e, x0, y0, 8, &mut rows);
        let all = rows.iter().all(|&r| r == 0xff);
        let none = rows.iter().all(|&r| r == 0);
        let got = e.classify(x0, y0, x0 + 7.0 * SUB, y0 + 7.0 * SUB);
        assert_eq!(
            got,
            if all {
                Some(true)
            } else if none {
                Some(false)
            } else {
                None
            }
        );
    }
}
