//! Directed rounding from f64 to f32, and f32 steps: what keeps the culling references
//! conservative. They compute in f64 from f32 inputs and round each result away from the volume
//! or toward the camera, so the f32 they report is never on the wrong side of the exact value.

/// The next f32 toward +infinity (`f32::next_up`, stable only since Rust 1.86).
pub fn next_f32_up(x: f32) -> f32 {
    if x.is_nan() || x == f32::INFINITY {
        return x;
    }
    if x == 0.0 {
        return f32::from_bits(1);
    }
    let bits = x.to_bits();
    if x > 0.0 {
        f32::from_bits(bits + 1)
    } else {
        f32::from_bits(bits - 1)
    }
}

/// The next f32 toward -infinity.
pub fn next_f32_down(x: f32) -> f32 {
    -next_f32_up(-x)
}

/// Largest f32 not above `x`.
pub fn f64_to_f32_round_down(x: f64) -> f32 {
    let y = x as f32;
    if f64::from(y) > x {
        next_f32_down(y)
    } else {
        y
    }
}

/// Smallest f32 not below `x`.
pub fn f64_to_f32_round_up(x: f64) -> f32 {
    let y = x as f32;
    if f64::from(y) < x {
        next_f32_up(y)
    } else {
        y
    }
}

/// `x.floor()` for finite `x` below 2^63 in magnitude, without the libm call that `f64::floor`
/// becomes on baseline x86-64 (no SSE4.1 `roundsd`): the truncation, one lower where it went
/// up. Hot loops of the software rasterizer round screen coordinates with it.
#[inline]
pub fn floor_f64(x: f64) -> f64 {
    let t = (x as i64) as f64;
    if t > x {
        t - 1.0
    } else {
        t
    }
}

/// `x.ceil()` under [`floor_f64`]'s conditions.
#[inline]
pub fn ceil_f64(x: f64) -> f64 {
    let t = (x as i64) as f64;
    if t < x {
        t + 1.0
    } else {
        t
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floor_and_ceil_equal_the_standard_ones() {
        let mut values = vec![
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            2.5e-300,
            -2.5e-300,
            4_503_599_627_370_495.5,
            -4_503_599_627_370_495.5,
            9.0e15,
            -9.0e15,
            1e18,
            -1e18,
        ];
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        for _ in 0..10_000 {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let unit = (state >> 11) as f64 / (1u64 << 53) as f64;
            values.push((unit - 0.5) * 2e6);
            values.push(
                ((unit - 0.5) * 1e3).round()
                    + [0.0, 0.25, 0.5, 1.0 - f64::EPSILON][(state & 3) as usize],
            );
        }
        for x in values {
            assert_eq!(floor_f64(x), x.floor(), "floor {x}");
            assert_eq!(ceil_f64(x), x.ceil(), "ceil {x}");
        }
    }

    #[test]
    fn directed_rounding_brackets_the_exact_value() {
        for x in [1.0 / 3.0, 1e-30, -2.5e-7, 0.999_999_999_9, 1e7 + 0.1] {
            let down = f64_to_f32_round_down(x);
            let up = f64_to_f32_round_up(x);
            assert!(f64::from(down) <= x && x <= f64::from(up), "{x}");
            assert!(f64::from(up) - f64::from(down) <= f64::from(next_f32_up(up)) - f64::from(up));
        }
        assert_eq!(next_f32_up(0.0), f32::from_bits(1));
        assert_eq!(next_f32_down(0.0), -f32::from_bits(1));
        assert_eq!(next_f32_up(-f32::from_bits(1)), -0.0);
    }
}
