//! The "never written" fill word for GPU output buffers.

/// Word every output buffer is filled with before a pass runs: a quiet NaN with a payload no
/// arithmetic produces (hardware NaNs are canonical, `0x7fc0_0000`), so a surviving sentinel
/// means "never written". Upload it as raw bits so no float conversion canonicalises the NaN.
pub const SENTINEL: u32 = 0x7fc0_c01f;

/// [`SENTINEL`] as a float.
pub const SENTINEL_F32: f32 = f32::from_bits(SENTINEL);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sentinel_is_a_non_canonical_nan() {
        assert!(SENTINEL_F32.is_nan());
        assert_ne!(SENTINEL, f32::NAN.to_bits());
        assert_eq!(SENTINEL_F32.to_bits(), SENTINEL);
    }
}
