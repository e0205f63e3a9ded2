//! The one parallel schedule every image kernel uses: the output is cut into horizontal
//! bands of whole rows, and rayon runs the bands on the caller's current pool.
//!
//! Full-width bands rather than square tiles: planes are row-major, so a band streams every
//! plane it touches front to back (hardware prefetchers follow it), and the source rows a
//! band's reprojection reads are the same few rows for every pixel of the band, so they stay
//! in L2 while the band runs. Band height is a parameter; BENCHMARKS.md has the sweep.

use core::marker::PhantomData;
use core::ops::Range;

use rayon::prelude::*;

use crate::frame::{Extent, PlaneMut};

/// The rows of one mutable plane, shared between parallel bands. Each band borrows only the
/// rows of its own range, so no row is ever borrowed twice.
pub(crate) struct SharedRows<'a, T> {
    ptr: *mut T,
    len: usize,
    extent: Extent,
    stride: usize,
    _plane: PhantomData<&'a mut [T]>,
}

// SAFETY: SharedRows only hands out disjoint rows (see `row`), and T itself is Send.
unsafe impl<T: Send> Send for SharedRows<'_, T> {}
// SAFETY: as above; shared access never produces two live borrows of one row.
unsafe impl<T: Send> Sync for SharedRows<'_, T> {}

impl<'a, T: Copy + Send> SharedRows<'a, T> {
    pub(crate) fn new(plane: PlaneMut<'a, T>) -> Self {
        let (data, extent, stride) = plane.into_raw_parts();
        Self { ptr: data.as_mut_ptr(), len: data.len(), extent, stride, _plane: PhantomData }
    }

    /// Row `y` (exactly `width` elements).
    ///
    /// # Safety
    /// No other borrow of row `y` may be live. [`for_each_band`] gives every row to exactly
    /// one band, so a band may borrow the rows of its own range.
    #[allow(clippy::mut_from_ref)]
    #[inline(always)]
    pub(crate) unsafe fn row(&self, y: usize) -> &'a mut [T] {
        assert!(y < self.extent.height(), "row {y} outside height {}", self.extent.height());
        let start = y * self.stride;
        debug_assert!(start + self.extent.width() <= self.len);
        // SAFETY: the view was validated to hold (height − 1)·stride + width elements, so
        // the row is in bounds; disjointness is the caller's contract.
        unsafe { core::slice::from_raw_parts_mut(self.ptr.add(start), self.extent.width()) }
    }
}

/// Runs `band` over `0..height` in bands of `band_rows` rows, in parallel on the current
/// rayon pool, and folds the results with `combine` (in no particular order: `combine` must
/// be associative and commutative). Allocates nothing.
pub(crate) fn for_each_band<R, F, C>(height: usize, band_rows: usize, band: F, combine: C) -> R
where
    R: Send + Default,
    F: Fn(Range<usize>) -> R + Sync,
    C: Fn(R, R) -> R + Sync + Send,
{
    let rows = band_rows.max(1);
    let bands = height.div_ceil(rows);
    (0..bands).into_par_iter().map(|b| band(b * rows..((b + 1) * rows).min(height))).reduce(R::default, combine)
}

/// The first row of `0..height` for which `row_ok` is false, or `None`. The rows are checked
/// in parallel on the caller's current rayon pool: a kernel's whole-plane boundary check is a
/// pass over memory the kernel then reads again on every thread, so it runs as wide as the
/// kernel. The first bad row, not any, so the error names the same pixel every time.
pub(crate) fn first_bad_row(height: usize, row_ok: impl Fn(usize) -> bool + Sync) -> Option<usize> {
    (0..height).into_par_iter().with_min_len(16).find_first(|&y| !row_ok(y))
}

#[cfg(test)]
mod first_bad_row_tests {
    use super::first_bad_row;

    /// The first bad row whatever the others and the pool's split: an error names the same
    /// pixel every time.
    #[test]
    fn finds_the_first_bad_row() {
        for height in [0, 1, 15, 16, 17, 720] {
            assert_eq!(first_bad_row(height, |_| true), None, "height {height}");
            for first in (0..height).step_by(7) {
                let found = first_bad_row(height, |y| y < first || (y - first) % 5 == 3 && y != first);
                assert_eq!(found, Some(first), "height {height}");
            }
        }
    }
}
