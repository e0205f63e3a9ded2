//! Support for the `check-scalar` feature and the agreement tests: bitwise comparison of a
//! SIMD result against its scalar reference.

use crate::frame::{Plane, RgbBuf, RgbPlanes};

/// An owned copy of `planes`: the input a `check-scalar` run hands the scalar reference of a
/// kernel that works in place.
pub fn rgb_copy(planes: &RgbPlanes<'_>) -> RgbBuf {
    let e = planes.extent();
    let mut copy = RgbBuf::new(e, 0.0);
    for y in 0..e.height() {
        for x in 0..e.width() {
            copy.set(x, y, planes.get(x, y));
        }
    }
    copy
}

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
    /// Whether the two values have the same bits (NaN payloads and signed zeros included).
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

/// A global allocator that forwards to the system allocator and counts allocations and
/// reallocations: the no-allocation-per-frame tests install it with
/// `#[global_allocator] static GLOBAL: CountingAllocator = CountingAllocator::new();` and
/// compare [`CountingAllocator::allocations`] around a frame. It sees every thread of the
/// process, so such a test file holds a single test.
pub struct CountingAllocator {
    count: std::sync::atomic::AtomicU64,
}

impl CountingAllocator {
    /// A counter at zero around the system allocator.
    pub const fn new() -> Self {
        Self { count: std::sync::atomic::AtomicU64::new(0) }
    }

    /// Allocations and reallocations so far.
    pub fn allocations(&self) -> u64 {
        self.count.load(std::sync::atomic::Ordering::SeqCst)
    }
}

impl Default for CountingAllocator {
    fn default() -> Self {
        Self::new()
    }
}

// SAFETY: forwards to the system allocator unchanged; only counts.
unsafe impl std::alloc::GlobalAlloc for CountingAllocator {
    unsafe fn alloc(&self, layout: std::alloc::Layout) -> *mut u8 {
        self.count.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        // SAFETY: same contract as the caller's.
        unsafe { std::alloc::System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: std::alloc::Layout) {
        // SAFETY: same contract as the caller's.
        unsafe { std::alloc::System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: std::alloc::Layout, new_size: usize) -> *mut u8 {
        self.count.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        // SAFETY: same contract as the caller's.
        unsafe { std::alloc::System.realloc(ptr, layout, new_size) }
    }
}
