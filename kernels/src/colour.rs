//! Colour arithmetic every part of the project shares, written once so that the kernels'
//! bodies, the renderer and the evaluation weigh colour the same way.

/// The Rec. 709 (sRGB primaries) luminance weights of linear R, G and B.
pub const REC709_LUMINANCE: [f32; 3] = [0.2126, 0.7152, 0.0722];

/// Rec. 709 luminance of linear RGB, `0.2126·r + 0.7152·g + 0.0722·b`, in this operation
/// order: a SIMD body that must equal a scalar reference bit for bit evaluates the same
/// products and sums in the same order (see [`crate::simd`]).
#[inline(always)]
pub fn luminance(r: f32, g: f32, b: f32) -> f32 {
    let [wr, wg, wb] = REC709_LUMINANCE;
    wr * r + wg * g + wb * b
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn white_has_unit_luminance_and_the_weights_are_rec709s() {
        assert!((luminance(1.0, 1.0, 1.0) - 1.0).abs() <= f32::EPSILON);
        assert_eq!([luminance(1.0, 0.0, 0.0), luminance(0.0, 1.0, 0.0), luminance(0.0, 0.0, 1.0)], REC709_LUMINANCE);
    }
}
