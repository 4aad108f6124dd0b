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

#[cfg(test)]
mod tests {
    use super::*;

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
