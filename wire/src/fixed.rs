//! Quantisation of physical values to the integer fields of the payloads.
//!
//! Rounding is half away from zero; values outside a field's range saturate; NaN becomes 0.
//! Only `as` casts and `f32` arithmetic are used (no `std` maths), so firmware and host
//! quantise to the same integers.

/// `x * scale` rounded half away from zero, saturated to `i16`; NaN gives 0.
pub fn to_i16(x: f32, scale: f32) -> i16 {
    round(x * scale) as i16
}

/// `x * scale` rounded half away from zero, saturated to `u16`; NaN and negatives give 0.
pub fn to_u16(x: f32, scale: f32) -> u16 {
    round(x * scale) as u16
}

/// `x * scale` rounded half away from zero, saturated to `u32`; NaN and negatives give 0.
pub fn to_u32(x: f32, scale: f32) -> u32 {
    round(x * scale) as u32
}

/// `x * scale` rounded half away from zero, saturated to `u8`; NaN and negatives give 0.
pub fn to_u8(x: f32, scale: f32) -> u8 {
    round(x * scale) as u8
}

/// Rounds half away from zero; the result is a float holding an integer (or ±inf, NaN),
/// and the saturating `as` casts above do the rest.
fn round(y: f32) -> f32 {
    // For |y| >= 2^23 every f32 is already an integer; adding 0.5 could round up wrongly.
    if y.is_nan() || y.abs() >= 8_388_608.0 {
        return y;
    }
    let t = if y >= 0.0 { y + 0.5 } else { y - 0.5 };
    // Truncation towards zero through i32 is exact in this range.
    t as i32 as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rounds_half_away_and_saturates() {
        assert_eq!(to_i16(1.234_5, 100.0), 123);
        assert_eq!(to_i16(-0.005, 100.0), -1);
        assert_eq!(to_i16(0.004, 100.0), 0);
        assert_eq!(to_i16(1.0e9, 1.0), i16::MAX);
        assert_eq!(to_i16(-1.0e9, 1.0), i16::MIN);
        assert_eq!(to_i16(f32::NAN, 1.0), 0);
        assert_eq!(to_u16(-3.0, 1.0), 0);
        assert_eq!(to_u8(1.0, 255.0), 255);
        assert_eq!(to_u8(0.5, 255.0), 128);
        assert_eq!(to_u32(187.26, 100.0), 18726);
        assert_eq!(to_u32(f32::INFINITY, 1.0), u32::MAX);
    }
}
