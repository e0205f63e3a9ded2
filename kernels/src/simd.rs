//! Lane types and the few helpers every kernel uses.
//!
//! # Determinism policy
//! Kernels compute `a * b + c` as two rounded operations through [`mad`]; nothing in a
//! kernel is fused or approximated (no `mul_add`, no `recip`, no `recip_sqrt`). Rust never
//! contracts `a * b + c` on its own, so a scalar reference written in the same operation order
//! gives bit-identical results, which is what the agreement tests check. `wide`'s `mul_add`
//! fuses on some targets and not others, and its `recip` is an approximation on x86.
//!
//! The one exception is SSIM ([`crate::ssim`]): it is checked against its f64 reference to a
//! tolerance, not bitwise, and uses fused multiply-add (its module docs say where and why).
//!
//! # Width
//! [`F32s`] is `wide::f32x8`: one AVX register at the x86-64-v3 baseline, two SSE halves at
//! the SSE2 baseline. The kernels are written for [`LANES`] lanes and never assume more.

pub use wide::{f32x8, i32x8, u32x8};

use crate::frame::Plane;

/// The float lane type every kernel uses.
pub type F32s = f32x8;
/// The matching integer lane type.
pub type I32s = i32x8;

/// Lanes per vector.
pub const LANES: usize = 8;

/// Lane indices `0, 1, …, 7` as floats.
#[inline(always)]
pub fn lane_offsets() -> F32s {
    F32s::from([0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0])
}

/// Starts loading the cache line holding `p` into every cache level.
///
/// Safe for any address, even dangling or null: a prefetch is a hint that never faults and
/// changes nothing the program can observe. On targets without one it does nothing.
#[inline(always)]
pub fn prefetch<T>(p: *const T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: SSE is part of the x86-64 baseline, and a prefetch reads nothing.
    unsafe {
        core::arch::x86_64::_mm_prefetch::<{ core::arch::x86_64::_MM_HINT_T0 }>(p.cast::<i8>());
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = p;
}

/// `a * b + c`, rounded twice (see the determinism policy).
#[inline(always)]
pub fn mad(a: F32s, b: F32s, c: F32s) -> F32s {
    a * b + c
}

/// Scalar twin of [`mad`].
#[inline(always)]
pub fn mad1(a: f32, b: f32, c: f32) -> f32 {
    a * b + c
}

/// Clamps to ±`f32::MAX` (infinities become the largest finite value); NaN stays NaN.
#[inline(always)]
pub fn clamp_finite1(v: f32) -> f32 {
    v.clamp(-f32::MAX, f32::MAX)
}

/// SIMD twin of [`clamp_finite1`] (compare-and-select, so NaN passes through exactly as in
/// the scalar version; `wide`'s `min`/`max` would replace it).
#[inline(always)]
pub fn clamp_finite(v: F32s) -> F32s {
    let max = F32s::splat(f32::MAX);
    let v = v.simd_gt(max).select(max, v);
    v.simd_lt(-max).select(-max, v)
}

/// Whether any of the first `LANES` bytes of a per-pixel mask is non-zero: one 8-byte load
/// and compare, where a lane mask folds each byte (a masked kernel skips a group without
/// wanted pixels on it).
#[inline(always)]
pub(crate) fn any_nonzero(mask: &[u8]) -> bool {
    const { assert!(LANES == 8) };
    u64::from_ne_bytes(mask[..LANES].try_into().expect("8 mask bytes")) != 0
}

/// How many of `mask`'s first bytes are zero: a masked kernel's empty stretch, found 32
/// bytes at a time so that a sparse mask costs a few instructions per group of eight
/// instead of a group's bookkeeping each.
#[inline(always)]
pub(crate) fn leading_zero_bytes(mask: &[u8]) -> usize {
    const CHUNK: usize = 32;
    let word = |b: &[u8]| u64::from_le_bytes(b.try_into().expect("8 mask bytes"));
    let mut chunks = mask.chunks_exact(CHUNK);
    let mut zeros = 0;
    for chunk in &mut chunks {
        let words = [word(&chunk[..8]), word(&chunk[8..16]), word(&chunk[16..24]), word(&chunk[24..])];
        if words.iter().fold(0, |any, w| any | w) != 0 {
            // Little-endian: the first non-zero byte is the lowest set bit's.
            let (i, w) = words.iter().enumerate().find(|&(_, &w)| w != 0).expect("a non-zero word");
            return zeros + 8 * i + w.trailing_zeros() as usize / 8;
        }
        zeros += CHUNK;
    }
    zeros + chunks.remainder().iter().take_while(|&&b| b == 0).count()
}

/// Flushes a value below `f32::MIN_POSITIVE` in magnitude (a subnormal, or −0) to +0; NaN
/// and everything else pass through. Kernels that write a history flush it: an EMA decaying
/// towards 0 would otherwise walk through subnormals, which are slow on x86, and
/// flush-to-zero cannot be relied on.
#[inline(always)]
pub fn flush_subnormal1(v: f32) -> f32 {
    if v.abs() < f32::MIN_POSITIVE { 0.0 } else { v }
}

/// SIMD twin of [`flush_subnormal1`].
#[inline(always)]
pub fn flush_subnormal(v: F32s) -> F32s {
    v.abs().simd_lt(F32s::splat(f32::MIN_POSITIVE)).select(F32s::ZERO, v)
}

/// Loads `LANES` consecutive elements starting at `i`. Panics if fewer remain.
#[inline(always)]
pub fn load(slice: &[f32], i: usize) -> F32s {
    let chunk: [f32; LANES] = slice[i..i + LANES].try_into().expect("LANES elements");
    F32s::from(chunk)
}

/// Stores `v` into `LANES` consecutive elements starting at `i`. Panics if fewer remain.
#[inline(always)]
pub fn store(slice: &mut [f32], i: usize, v: F32s) {
    slice[i..i + LANES].copy_from_slice(&v.to_array());
}

/// Pixel coordinates of `LANES` taps, clamped into a plane's extent so that loading them
/// cannot go out of bounds. Build once per tap, use for every plane of the same extent.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TapCoords {
    /// Column of each lane's tap.
    pub x: [u32; LANES],
    /// Row of each lane's tap.
    pub y: [u32; LANES],
}

impl TapCoords {
    /// Clamps float pixel coordinates (exact integers, or anything: NaN becomes 0) into
    /// `[0, width − 1] × [0, height − 1]`.
    #[inline(always)]
    pub fn clamped(x: F32s, y: F32s, width: usize, height: usize) -> Self {
        let xmax = F32s::splat((width - 1) as f32);
        let ymax = F32s::splat((height - 1) as f32);
        // max(NaN, 0) picks 0 in wide's `max` (it checks the right-hand side for NaN).
        let (xc, yc) = (x.max(F32s::ZERO).min(xmax), y.max(F32s::ZERO).min(ymax));
        // Within [0, MAX_DIMENSION) (the widest extent), where truncating to i32 in one
        // vector instruction is `as u32` lane by lane.
        let int = |v: F32s| -> [u32; LANES] { bytemuck::cast(v.fast_trunc_int()) };
        Self { x: int(xc), y: int(yc) }
    }

    /// Loads the taps from `plane` (elements may be any `Copy` type).
    #[inline(always)]
    pub fn gather<T: Copy + Default>(&self, plane: &Plane<'_, T>) -> [T; LANES] {
        let (w, h) = (plane.width() as u32, plane.height() as u32);
        let mut out = [T::default(); LANES];
        for i in 0..LANES {
            // `min` keeps the load in bounds even for a plane of a smaller extent than the
            // coordinates were clamped for; for matching extents it changes nothing.
            let (x, y) = (self.x[i].min(w - 1), self.y[i].min(h - 1));
            // SAFETY: x < width and y < height by the line above.
            out[i] = unsafe { plane.get_unchecked(x as usize, y as usize) };
        }
        out
    }

    /// Loads float taps as a vector: [`TapCoords::gather`], as one AVX2 gather where the
    /// binary has AVX2 (the lanes' indices formed in one vector, not eight scalar ones).
    #[inline(always)]
    pub fn gather_f32(&self, plane: &Plane<'_, f32>) -> F32s {
        bytemuck::cast(self.gather_words(plane))
    }

    /// Loads `u32` taps as a vector, as [`TapCoords::gather_f32`] loads floats.
    #[inline(always)]
    pub fn gather_u32(&self, plane: &Plane<'_, u32>) -> u32x8 {
        bytemuck::cast(self.gather_words(plane))
    }

    /// [`TapCoords::gather`] of a plane of 4-byte elements, as their bits: one AVX2 gather
    /// where the binary has AVX2, its eight indices formed in one vector (not eight scalar
    /// ones), lane by lane where an index might not fit `i32`.
    #[inline(always)]
    fn gather_words<T: bytemuck::Pod + Default>(&self, plane: &Plane<'_, T>) -> [u32; LANES] {
        const { assert!(size_of::<T>() == 4, "4-byte elements") };
        #[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
        if plane.as_slice().len() <= i32::MAX as usize {
            use core::arch::x86_64::{__m256i, _mm256_i32gather_epi32};
            // Clamped into the plane as `gather` clamps (a no-op for matching extents).
            let (w, h) = (plane.width() as u32, plane.height() as u32);
            let x: i32x8 = bytemuck::cast(u32x8::from(self.x).min(u32x8::splat(w - 1)));
            let y: i32x8 = bytemuck::cast(u32x8::from(self.y).min(u32x8::splat(h - 1)));
            let indices = y * i32x8::splat(plane.stride() as i32) + x;
            // SAFETY: AVX2 is enabled at compile time; every index is `y·stride + x` with
            // `x < width` and `y < height` (clamped above), below the plane's length
            // ((height − 1)·stride + width, checked at construction), which fits `i32`; the
            // elements are 4 bytes (asserted above), the scale the gather reads with.
            let v = unsafe {
                _mm256_i32gather_epi32::<4>(plane.as_slice().as_ptr().cast(), bytemuck::cast::<i32x8, __m256i>(indices))
            };
            return bytemuck::cast(v);
        }
        self.gather(plane).map(|v| bytemuck::cast(v))
    }
}

/// Lane mask from per-lane booleans (all ones where true), for building masks in tests and
/// in the few places a kernel decides per lane in scalar code.
#[inline(always)]
pub fn mask_from_bools(b: [bool; LANES]) -> F32s {
    F32s::from(b.map(|t| if t { f32::from_bits(u32::MAX) } else { 0.0 }))
}

/// One bit per lane (bit `i` = lane `i`), for a mask produced by a comparison.
#[inline(always)]
pub fn bits(mask: F32s) -> u32 {
    mask.to_bitmask()
}

/// True if the kernels were compiled for 8-wide AVX registers (x86-64-v3 or higher).
pub const fn compiled_with_avx2() -> bool {
    cfg!(all(target_arch = "x86_64", target_feature = "avx2", target_feature = "fma"))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Against counting byte by byte, for every position of the first non-zero byte in
    /// masks of every length up to three chunks and some.
    #[test]
    fn leading_zero_bytes_counts_the_empty_stretch() {
        for len in 0..100 {
            for first in 0..=len {
                let mut mask = vec![0u8; len];
                if first < len {
                    mask[first] = 1 + (first % 255) as u8;
                    // Bytes after the first non-zero one do not matter.
                    mask[first..].iter_mut().skip(1).step_by(3).for_each(|b| *b = 7);
                }
                assert_eq!(leading_zero_bytes(&mask), first, "length {len}, first non-zero byte {first}");
            }
        }
    }

    #[test]
    fn mad_is_not_fused() {
        // With a fused multiply-add, 0.1 * 10 - 1 is the rounding error of 0.1 (≈1.49e-8);
        // rounded twice it is exactly 0. The scalar twin must agree lane for lane.
        let a = F32s::splat(0.1);
        let r = mad(a, F32s::splat(10.0), F32s::splat(-1.0));
        assert_eq!(r.to_array(), [mad1(0.1, 10.0, -1.0); LANES]);
        assert_eq!(mad1(0.1, 10.0, -1.0), 0.0);
    }

    /// The vector gathers load what the lane-by-lane one does: coordinates clamped into the
    /// extent (NaN, infinities, negatives, past the edge), rows with padding, and a plane
    /// smaller than the extent the coordinates were clamped for.
    #[test]
    fn vector_gathers_equal_the_lane_by_lane_gather() {
        let (width, height, stride) = (37, 11, 41);
        let floats: Vec<f32> = (0..stride * height).map(|i| i as f32 * 0.5 - 7.0).collect();
        let words: Vec<u32> = (0..stride * height).map(|i| (i as u32).wrapping_mul(2_654_435_761)).collect();
        let planes = [(width, height), (width - 5, height - 3)]
            .map(|(w, h)| (Plane::new(&floats, w, h, stride).unwrap(), Plane::new(&words, w, h, stride).unwrap()));
        let mut rng = crate::synth::Rng::new(0x9E37_79B9);
        let mut next = move || rng.next_u32();
        let specials = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, -1.0, -0.0, 1e9, 36.0, 36.999, 10.0, 11.0];
        for round in 0..500 {
            let coordinate = |next: &mut dyn FnMut() -> u32| -> f32 {
                let r = next();
                if round % 5 == 0 { specials[r as usize % specials.len()] } else { (r % 50) as f32 - 5.0 }
            };
            let xs: [f32; LANES] = core::array::from_fn(|_| coordinate(&mut next));
            let ys: [f32; LANES] = core::array::from_fn(|_| coordinate(&mut next));
            let taps = TapCoords::clamped(F32s::from(xs), F32s::from(ys), width, height);
            for (i, (&x, &y)) in xs.iter().zip(&ys).enumerate() {
                let clamp = |v: f32, max: usize| if v.is_nan() { 0 } else { v.clamp(0.0, max as f32) as u32 };
                assert_eq!((taps.x[i], taps.y[i]), (clamp(x, width - 1), clamp(y, height - 1)), "{x} {y}");
            }
            for (f, u) in &planes {
                assert_eq!(taps.gather_f32(f).to_array(), taps.gather(f), "{taps:?}");
                assert_eq!(taps.gather_u32(u).to_array(), taps.gather(u), "{taps:?}");
            }
        }
    }

    #[test]
    fn masks_round_trip() {
        let m = mask_from_bools([true, false, true, true, false, false, false, true]);
        assert_eq!(bits(m), 0b1000_1101);
    }
}
