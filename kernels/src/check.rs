//! Support for the `check-scalar` feature and the agreement tests: bitwise comparison of a
//! SIMD result against its scalar reference.

use crate::frame::Plane;

/// Bitwise equality, treating every NaN as equal to every other NaN.
#[inline]
pub fn same_bits(a: f32, b: f32) -> bool {
    a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan())
}

/// Panics with the first differing pixel unless the planes agree bit for bit.
pub fn assert_planes_equal<T: Copy + PartialEq + core::fmt::Debug + BitEq>(
    what: &str,
    channel: usize,
    simd: &Plane<'_, T>,
    scalar: &Plane<'_, T>,
) {
    assert_eq!(simd.extent(), scalar.extent(), "{what}: extents differ");
    for y in 0..simd.height() {
        for (x, (a, b)) in simd.row(y).iter().zip(scalar.row(y)).enumerate() {
            assert!(a.bit_eq(b), "{what} channel {channel}: SIMD {a:?} != scalar {b:?} at ({x}, {y})");
        }
    }
}

/// Bitwise equality for plane element types.
pub trait BitEq {
    fn bit_eq(&self, other: &Self) -> bool;
}

impl BitEq for f32 {
    fn bit_eq(&self, other: &Self) -> bool {
        same_bits(*self, *other)
    }
}

impl BitEq for u8 {
    fn bit_eq(&self, other: &Self) -> bool {
        self == other
    }
}

impl BitEq for u16 {
    fn bit_eq(&self, other: &Self) -> bool {
        self == other
    }
}
