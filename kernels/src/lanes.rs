//! A lane type a kernel body can be written against once and compiled at two widths: 8 lanes
//! (`wide::f32x8`, the baseline) and 16 lanes ([`avx512::F32x16`], taken at run time where the
//! CPU has AVX-512; see [`crate::isa`]).
//!
//! Every operation is lane-wise and means the same bits at both widths: comparisons give
//! all-ones lanes, `select` reads a mask lane's sign bit, `fast_max`/`fast_min` are the
//! `maxps`/`minps` instructions (the second operand where either is NaN), `mul_add` and
//! `mul_neg_add` are fused. So a body that does the same operations per lane gives the same
//! bits per lane at either width; only sums across lanes can differ in order.

use core::ops::{Add, AddAssign, BitAnd, BitOr, BitOrAssign, Div, Mul, Neg, Not, Sub};

use wide::f32x8;

/// Lane-wise f32 arithmetic at a width fixed by the implementing type.
pub(crate) trait Lanes:
    Copy
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + BitAnd<Output = Self>
    + BitOr<Output = Self>
    + Not<Output = Self>
    + AddAssign
    + BitOrAssign
{
    /// Lanes per vector.
    const LANES: usize;
    /// The lanes as an array (`[f32; LANES]`).
    type Array: Copy + AsRef<[f32]>;

    /// Every lane `v`.
    fn splat(v: f32) -> Self;
    /// The first `LANES` elements of `s`. Panics if fewer.
    fn load(s: &[f32]) -> Self;
    /// Writes the lanes into the first `LANES` elements of `s`. Panics if fewer.
    fn store(self, s: &mut [f32]);
    fn to_array(self) -> Self::Array;
    /// `0, 1, …, LANES − 1`.
    fn lane_offsets() -> Self;
    /// All-ones lanes where bit `i` of `bits` is set.
    fn from_bitmask(bits: u32) -> Self;
    /// Bit `i` set where lane `i`'s sign bit is (all-ones mask lanes).
    fn to_bitmask(self) -> u32;
    /// `self · m + a`, rounded once.
    fn mul_add(self, m: Self, a: Self) -> Self;
    /// `−(self · m) + a`, rounded once.
    fn mul_neg_add(self, m: Self, a: Self) -> Self;
    fn abs(self) -> Self;
    /// `maxps`: `other` where either is NaN.
    fn fast_max(self, other: Self) -> Self;
    /// `minps`: `other` where either is NaN.
    fn fast_min(self, other: Self) -> Self;
    /// Ordered comparisons (false where either is NaN), as all-ones lanes.
    fn simd_eq(self, other: Self) -> Self;
    fn simd_lt(self, other: Self) -> Self;
    fn simd_le(self, other: Self) -> Self;
    fn simd_gt(self, other: Self) -> Self;
    fn simd_ge(self, other: Self) -> Self;
    /// `if_true` in the lanes whose sign bit is set in `self`, `if_false` elsewhere.
    fn select(self, if_true: Self, if_false: Self) -> Self;

    /// `0.0` in every lane.
    #[inline(always)]
    fn zero() -> Self {
        Self::splat(0.0)
    }

    /// `1.0` in every lane.
    #[inline(always)]
    fn one() -> Self {
        Self::splat(1.0)
    }

    /// Bits of all lanes.
    #[inline(always)]
    fn lane_bits() -> u32 {
        ((1u64 << Self::LANES) - 1) as u32
    }

    /// Lane `i`. Panics if `i ≥ LANES`.
    #[inline(always)]
    fn lane(self, i: usize) -> f32 {
        self.to_array().as_ref()[i]
    }

    /// Every lane's mask bit set.
    #[inline(always)]
    fn all(self) -> bool {
        self.to_bitmask() == Self::lane_bits()
    }

    /// No lane's mask bit set.
    #[inline(always)]
    fn none(self) -> bool {
        self.to_bitmask() == 0
    }
}

impl Lanes for f32x8 {
    const LANES: usize = 8;
    type Array = [f32; 8];

    #[inline(always)]
    fn splat(v: f32) -> Self {
        f32x8::splat(v)
    }

    #[inline(always)]
    fn load(s: &[f32]) -> Self {
        f32x8::from(<[f32; 8]>::try_from(&s[..8]).expect("8 elements"))
    }

    #[inline(always)]
    fn store(self, s: &mut [f32]) {
        s[..8].copy_from_slice(&f32x8::to_array(self));
    }

    #[inline(always)]
    fn to_array(self) -> [f32; 8] {
        f32x8::to_array(self)
    }

    #[inline(always)]
    fn lane_offsets() -> Self {
        crate::simd::lane_offsets()
    }

    #[inline(always)]
    fn from_bitmask(bits: u32) -> Self {
        let lane = f32x8::from(core::array::from_fn::<f32, 8, _>(|i| if bits >> i & 1 == 1 { 1.0 } else { 0.0 }));
        f32x8::simd_eq(lane, f32x8::ONE)
    }

    #[inline(always)]
    fn to_bitmask(self) -> u32 {
        f32x8::to_bitmask(self)
    }

    #[inline(always)]
    fn mul_add(self, m: Self, a: Self) -> Self {
        f32x8::mul_add(self, m, a)
    }

    #[inline(always)]
    fn mul_neg_add(self, m: Self, a: Self) -> Self {
        f32x8::mul_neg_add(self, m, a)
    }

    #[inline(always)]
    fn abs(self) -> Self {
        f32x8::abs(self)
    }

    #[inline(always)]
    fn fast_max(self, other: Self) -> Self {
        f32x8::fast_max(self, other)
    }

    #[inline(always)]
    fn fast_min(self, other: Self) -> Self {
        f32x8::fast_min(self, other)
    }

    #[inline(always)]
    fn simd_eq(self, other: Self) -> Self {
        f32x8::simd_eq(self, other)
    }

    #[inline(always)]
    fn simd_lt(self, other: Self) -> Self {
        f32x8::simd_lt(self, other)
    }

    #[inline(always)]
    fn simd_le(self, other: Self) -> Self {
        f32x8::simd_le(self, other)
    }

    #[inline(always)]
    fn simd_gt(self, other: Self) -> Self {
        f32x8::simd_gt(self, other)
    }

    #[inline(always)]
    fn simd_ge(self, other: Self) -> Self {
        f32x8::simd_ge(self, other)
    }

    #[inline(always)]
    fn select(self, if_true: Self, if_false: Self) -> Self {
        f32x8::select(self, if_true, if_false)
    }
}

/// The 16-lane AVX-512 type.
///
/// # Safety invariant
/// Every method executes AVX-512 F/BW/DQ/VL instructions. The type is crate-private and used
/// only inside functions marked `#[target_feature(enable = "avx512f,avx512bw,avx512dq,avx512vl")]`
/// that are called after [`crate::isa::Isa::is_supported`] returned true for
/// [`crate::isa::Isa::Avx512`] (the dispatch of each kernel checks it), so no value of it exists
/// on a CPU without those features. Being inlined into those functions is also what makes the
/// intrinsics compile to single instructions.
#[cfg(target_arch = "x86_64")]
pub(crate) mod avx512 {
    use core::arch::x86_64::*;
    use core::ops::{Add, AddAssign, BitAnd, BitOr, BitOrAssign, Div, Mul, Neg, Not, Sub};

    use super::Lanes;

    /// Sixteen `f32` lanes in one `zmm` register.
    #[derive(Clone, Copy)]
    #[repr(transparent)]
    pub(crate) struct F32x16(pub(crate) __m512);

    /// A binary operator as one intrinsic.
    macro_rules! binary {
        ($trait:ident, $method:ident, $intrinsic:ident) => {
            impl $trait for F32x16 {
                type Output = Self;
                #[inline(always)]
                fn $method(self, other: Self) -> Self {
                    // SAFETY: the module's invariant (AVX-512 present wherever a value exists).
                    Self(unsafe { $intrinsic(self.0, other.0) })
                }
            }
        };
    }

    binary!(Add, add, _mm512_add_ps);
    binary!(Sub, sub, _mm512_sub_ps);
    binary!(Mul, mul, _mm512_mul_ps);
    binary!(Div, div, _mm512_div_ps);
    binary!(BitAnd, bitand, _mm512_and_ps);
    binary!(BitOr, bitor, _mm512_or_ps);

    impl Neg for F32x16 {
        type Output = Self;
        #[inline(always)]
        fn neg(self) -> Self {
            // SAFETY: the module's invariant. Flips the sign bit, as `wide` does.
            Self(unsafe { _mm512_xor_ps(self.0, _mm512_set1_ps(-0.0)) })
        }
    }

    impl Not for F32x16 {
        type Output = Self;
        #[inline(always)]
        fn not(self) -> Self {
            // SAFETY: the module's invariant.
            Self(unsafe { _mm512_xor_ps(self.0, _mm512_castsi512_ps(_mm512_set1_epi32(-1))) })
        }
    }

    impl AddAssign for F32x16 {
        #[inline(always)]
        fn add_assign(&mut self, other: Self) {
            *self = *self + other;
        }
    }

    impl BitOrAssign for F32x16 {
        #[inline(always)]
        fn bitor_assign(&mut self, other: Self) {
            *self = *self | other;
        }
    }

    impl F32x16 {
        /// All-ones lanes where `mask` has its bit set.
        #[inline(always)]
        fn from_mask(mask: __mmask16) -> Self {
            // SAFETY: the module's invariant.
            Self(unsafe { _mm512_castsi512_ps(_mm512_movm_epi32(mask)) })
        }

        #[inline(always)]
        fn sign_mask(self) -> __mmask16 {
            // SAFETY: the module's invariant.
            unsafe { _mm512_movepi32_mask(_mm512_castps_si512(self.0)) }
        }

        #[inline(always)]
        fn compare<const PREDICATE: i32>(self, other: Self) -> Self {
            // SAFETY: the module's invariant.
            Self::from_mask(unsafe { _mm512_cmp_ps_mask::<PREDICATE>(self.0, other.0) })
        }
    }

    impl Lanes for F32x16 {
        const LANES: usize = 16;
        type Array = [f32; 16];

        #[inline(always)]
        fn splat(v: f32) -> Self {
            // SAFETY: the module's invariant.
            Self(unsafe { _mm512_set1_ps(v) })
        }

        #[inline(always)]
        fn load(s: &[f32]) -> Self {
            let s = &s[..16];
            // SAFETY: the module's invariant; `s` holds 16 floats (checked by the slicing).
            Self(unsafe { _mm512_loadu_ps(s.as_ptr()) })
        }

        #[inline(always)]
        fn store(self, s: &mut [f32]) {
            let s = &mut s[..16];
            // SAFETY: the module's invariant; `s` holds 16 floats (checked by the slicing).
            unsafe { _mm512_storeu_ps(s.as_mut_ptr(), self.0) }
        }

        #[inline(always)]
        fn to_array(self) -> [f32; 16] {
            let mut out = [0.0; 16];
            self.store(&mut out);
            out
        }

        #[inline(always)]
        fn lane_offsets() -> Self {
            Self::load(&[0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0, 10.0, 11.0, 12.0, 13.0, 14.0, 15.0])
        }

        #[inline(always)]
        fn from_bitmask(bits: u32) -> Self {
            Self::from_mask(bits as __mmask16)
        }

        #[inline(always)]
        fn to_bitmask(self) -> u32 {
            u32::from(self.sign_mask())
        }

        #[inline(always)]
        fn mul_add(self, m: Self, a: Self) -> Self {
            // SAFETY: the module's invariant.
            Self(unsafe { _mm512_fmadd_ps(self.0, m.0, a.0) })
        }

        #[inline(always)]
        fn mul_neg_add(self, m: Self, a: Self) -> Self {
            // SAFETY: the module's invariant.
            Self(unsafe { _mm512_fnmadd_ps(self.0, m.0, a.0) })
        }

        #[inline(always)]
        fn abs(self) -> Self {
            // SAFETY: the module's invariant. Clears the sign bit, as `wide` does.
            Self(unsafe { _mm512_abs_ps(self.0) })
        }

        #[inline(always)]
        fn fast_max(self, other: Self) -> Self {
            // SAFETY: the module's invariant. `vmaxps`: `other` where either is NaN.
            Self(unsafe { _mm512_max_ps(self.0, other.0) })
        }

        #[inline(always)]
        fn fast_min(self, other: Self) -> Self {
            // SAFETY: the module's invariant. `vminps`: `other` where either is NaN.
            Self(unsafe { _mm512_min_ps(self.0, other.0) })
        }

        #[inline(always)]
        fn simd_eq(self, other: Self) -> Self {
            self.compare::<_CMP_EQ_OQ>(other)
        }

        #[inline(always)]
        fn simd_lt(self, other: Self) -> Self {
            self.compare::<_CMP_LT_OQ>(other)
        }

        #[inline(always)]
        fn simd_le(self, other: Self) -> Self {
            self.compare::<_CMP_LE_OQ>(other)
        }

        #[inline(always)]
        fn simd_gt(self, other: Self) -> Self {
            self.compare::<_CMP_GT_OQ>(other)
        }

        #[inline(always)]
        fn simd_ge(self, other: Self) -> Self {
            self.compare::<_CMP_GE_OQ>(other)
        }

        #[inline(always)]
        fn select(self, if_true: Self, if_false: Self) -> Self {
            // SAFETY: the module's invariant. The blend takes its second operand where the
            // mask bit (the lane's sign bit) is set.
            Self(unsafe { _mm512_mask_blend_ps(self.sign_mask(), if_false.0, if_true.0) })
        }
    }
}
