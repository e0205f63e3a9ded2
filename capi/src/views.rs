//! Caller-owned buffers as the C side describes them, and their checked conversion into the
//! kernels' views.
//!
//! A plane is `data` plus `width`, `height` and `stride` (in elements, not bytes): pixel
//! `(x, y)` is `data[y * stride + x]`, and the plane must hold `(height - 1) * stride + width`
//! elements. Before a slice is formed from a pointer, the conversion checks that the pointer
//! is not null, that it is aligned for its element type and that the extent and stride are
//! ones the kernels accept (the kernels' own limits, with their messages). A call then checks
//! that no output overlaps any other buffer of the same call ([`Borrows`], before the slice
//! is formed): Rust may assume a mutable buffer is not read through another pointer, so an
//! overlap is refused instead of computed.

use std::ops::Range;

use stereotrace_kernels::frame::{Plane, PlaneMut, RgbPlanes, RgbPlanesMut};
use stereotrace_kernels::{Extent, FrameError};

use crate::boundary::{Context, Failure, StStatus};

/// A read-only plane of `float`.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct StPlaneF32 {
    /// Pixel `(0, 0)`; pixel `(x, y)` is `data[y * stride + x]`.
    pub data: *const f32,
    /// Pixels per row (1 ..= `STEREOTRACE_MAX_DIMENSION`).
    pub width: u32,
    /// Rows (1 ..= `STEREOTRACE_MAX_DIMENSION`; at most `STEREOTRACE_MAX_PIXELS` in all).
    pub height: u32,
    /// Elements from one row's start to the next (`width` ..= `STEREOTRACE_MAX_STRIDE`).
    pub stride: u32,
}

/// A writable plane of `float`.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct StPlaneMutF32 {
    /// Pixel `(0, 0)`; pixel `(x, y)` is `data[y * stride + x]`.
    pub data: *mut f32,
    /// Pixels per row (1 ..= `STEREOTRACE_MAX_DIMENSION`).
    pub width: u32,
    /// Rows (1 ..= `STEREOTRACE_MAX_DIMENSION`; at most `STEREOTRACE_MAX_PIXELS` in all).
    pub height: u32,
    /// Elements from one row's start to the next (`width` ..= `STEREOTRACE_MAX_STRIDE`).
    pub stride: u32,
}

/// A read-only plane of bytes (reason codes, masks).
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct StPlaneU8 {
    /// Pixel `(0, 0)`; pixel `(x, y)` is `data[y * stride + x]`.
    pub data: *const u8,
    /// Pixels per row (1 ..= `STEREOTRACE_MAX_DIMENSION`).
    pub width: u32,
    /// Rows (1 ..= `STEREOTRACE_MAX_DIMENSION`; at most `STEREOTRACE_MAX_PIXELS` in all).
    pub height: u32,
    /// Elements from one row's start to the next (`width` ..= `STEREOTRACE_MAX_STRIDE`).
    pub stride: u32,
}

/// A writable plane of bytes (reason codes).
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct StPlaneMutU8 {
    /// Pixel `(0, 0)`; pixel `(x, y)` is `data[y * stride + x]`.
    pub data: *mut u8,
    /// Pixels per row (1 ..= `STEREOTRACE_MAX_DIMENSION`).
    pub width: u32,
    /// Rows (1 ..= `STEREOTRACE_MAX_DIMENSION`; at most `STEREOTRACE_MAX_PIXELS` in all).
    pub height: u32,
    /// Elements from one row's start to the next (`width` ..= `STEREOTRACE_MAX_STRIDE`).
    pub stride: u32,
}

/// A read-only plane of `uint32_t` (octahedral normals).
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct StPlaneU32 {
    /// Pixel `(0, 0)`; pixel `(x, y)` is `data[y * stride + x]`.
    pub data: *const u32,
    /// Pixels per row (1 ..= `STEREOTRACE_MAX_DIMENSION`).
    pub width: u32,
    /// Rows (1 ..= `STEREOTRACE_MAX_DIMENSION`; at most `STEREOTRACE_MAX_PIXELS` in all).
    pub height: u32,
    /// Elements from one row's start to the next (`width` ..= `STEREOTRACE_MAX_STRIDE`).
    pub stride: u32,
}

/// Three read-only planes of one extent: red, green, blue.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct StRgb {
    /// Red.
    pub r: StPlaneF32,
    /// Green.
    pub g: StPlaneF32,
    /// Blue.
    pub b: StPlaneF32,
}

/// Three writable planes of one extent: red, green, blue.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct StRgbMut {
    /// Red.
    pub r: StPlaneMutF32,
    /// Green.
    pub g: StPlaneMutF32,
    /// Blue.
    pub b: StPlaneMutF32,
}

/// The most buffers one call takes (a full-layout reprojection: 2 × 7 G-buffer planes,
/// 3 + 1 + 1 inputs, 3 + 1 + 1 + 1 outputs).
const MAX_BORROWS: usize = 32;

/// The byte ranges a call was given, to refuse outputs that overlap anything else. A fixed
/// array: checking a call allocates nothing.
pub(crate) struct Borrows {
    spans: [(Range<usize>, bool, &'static str); MAX_BORROWS],
    len: usize,
}

impl Borrows {
    pub fn new() -> Self {
        Self { spans: std::array::from_fn(|_| (0..0, false, "")), len: 0 }
    }

    /// Records a buffer of the call, refusing it if it overlaps an earlier one and either
    /// of the two is writable. Runs before the buffer's slice is formed, so no two
    /// references the kernels receive ever alias a mutable one.
    fn claim(&mut self, bytes: Range<usize>, writable: bool, what: &'static str) -> Result<(), Failure> {
        for (earlier, earlier_writable, earlier_what) in &self.spans[..self.len] {
            if (writable || *earlier_writable) && bytes.start < earlier.end && earlier.start < bytes.end {
                return Err(Failure::new(
                    StStatus::Aliasing,
                    format!("{what} overlaps {earlier_what}: an output may not share memory with another buffer"),
                ));
            }
        }
        assert!(self.len < MAX_BORROWS, "more buffers than a call takes");
        self.spans[self.len] = (bytes, writable, what);
        self.len += 1;
        Ok(())
    }
}

/// Checks a plane's pointer, extent and stride and returns its element count and byte range.
fn span<T>(data: *const T, width: u32, height: u32, stride: u32, what: &str) -> Result<(usize, Range<usize>), Failure> {
    if data.is_null() {
        return Err(Failure::null(what));
    }
    if !(data as usize).is_multiple_of(align_of::<T>()) {
        return Err(Failure::new(
            StStatus::Misaligned,
            format!("{what} is not aligned to {} bytes (address {data:p})", align_of::<T>()),
        ));
    }
    let (width, height, stride) = (width as usize, height as usize, stride as usize);
    Extent::new(width, height).about(what)?;
    if stride < width {
        return Err(FrameError::StrideTooSmall { width, stride }).about(what);
    }
    // Bounded by the extent limits and the u32 stride, so this cannot overflow on 64 bits.
    let len = (height - 1) * stride + width;
    let start = data as usize;
    let end = len
        .checked_mul(size_of::<T>())
        .and_then(|bytes| start.checked_add(bytes))
        .filter(|&end| end - start <= isize::MAX as usize)
        .ok_or_else(|| Failure::invalid(format!("{what}: the plane does not fit the address space")))?;
    Ok((len, start..end))
}

/// A read-only kernel view of a C plane.
///
/// # Safety
/// `data` must point to `(height - 1) * stride + width` readable elements that nothing
/// writes while the view lives (what every function of the header asks of its caller).
pub(crate) unsafe fn plane<'a, T: Copy>(
    data: *const T,
    width: u32,
    height: u32,
    stride: u32,
    what: &'static str,
    borrows: &mut Borrows,
) -> Result<Plane<'a, T>, Failure> {
    let (len, bytes) = span(data, width, height, stride, what)?;
    borrows.claim(bytes, false, what)?;
    // SAFETY: non-null, aligned, within one allocation of `len` elements (the caller's
    // contract), and no writable view of this call overlaps it (`claim`).
    let slice = unsafe { std::slice::from_raw_parts(data, len) };
    Plane::new(slice, width as usize, height as usize, stride as usize).about(what)
}

/// A writable kernel view of a C plane.
///
/// # Safety
/// As [`plane`], and the elements must be writable.
pub(crate) unsafe fn plane_mut<'a, T: Copy + Send>(
    data: *mut T,
    width: u32,
    height: u32,
    stride: u32,
    what: &'static str,
    borrows: &mut Borrows,
) -> Result<PlaneMut<'a, T>, Failure> {
    let (len, bytes) = span(data.cast_const(), width, height, stride, what)?;
    borrows.claim(bytes, true, what)?;
    // SAFETY: as in `plane`; `claim` refused it if it overlaps any other view of the call,
    // so this slice is the only access to its memory while the call runs.
    let slice = unsafe { std::slice::from_raw_parts_mut(data, len) };
    PlaneMut::new(slice, width as usize, height as usize, stride as usize).about(what)
}

impl StPlaneF32 {
    /// # Safety
    /// See [`plane`].
    pub(crate) unsafe fn view<'a>(&self, what: &'static str, b: &mut Borrows) -> Result<Plane<'a>, Failure> {
        // SAFETY: this method's contract is `plane`'s, which it forwards.
        unsafe { plane(self.data, self.width, self.height, self.stride, what, b) }
    }
}

impl StPlaneMutF32 {
    /// # Safety
    /// See [`plane_mut`].
    pub(crate) unsafe fn view<'a>(&self, what: &'static str, b: &mut Borrows) -> Result<PlaneMut<'a>, Failure> {
        // SAFETY: this method's contract is `plane_mut`'s, which it forwards.
        unsafe { plane_mut(self.data, self.width, self.height, self.stride, what, b) }
    }
}

impl StPlaneU8 {
    /// # Safety
    /// See [`plane`].
    pub(crate) unsafe fn view<'a>(&self, what: &'static str, b: &mut Borrows) -> Result<Plane<'a, u8>, Failure> {
        // SAFETY: this method's contract is `plane`'s, which it forwards.
        unsafe { plane(self.data, self.width, self.height, self.stride, what, b) }
    }
}

impl StPlaneMutU8 {
    /// # Safety
    /// See [`plane_mut`].
    pub(crate) unsafe fn view<'a>(&self, what: &'static str, b: &mut Borrows) -> Result<PlaneMut<'a, u8>, Failure> {
        // SAFETY: this method's contract is `plane_mut`'s, which it forwards.
        unsafe { plane_mut(self.data, self.width, self.height, self.stride, what, b) }
    }
}

impl StPlaneU32 {
    /// # Safety
    /// See [`plane`].
    pub(crate) unsafe fn view<'a>(&self, what: &'static str, b: &mut Borrows) -> Result<Plane<'a, u32>, Failure> {
        // SAFETY: this method's contract is `plane`'s, which it forwards.
        unsafe { plane(self.data, self.width, self.height, self.stride, what, b) }
    }
}

impl StRgb {
    /// # Safety
    /// See [`plane`], for each channel.
    pub(crate) unsafe fn view<'a>(&self, what: [&'static str; 3], b: &mut Borrows) -> Result<RgbPlanes<'a>, Failure> {
        // SAFETY: each channel under this method's contract, `plane`'s.
        let (r, g, bl) = unsafe { (self.r.view(what[0], b)?, self.g.view(what[1], b)?, self.b.view(what[2], b)?) };
        RgbPlanes::new(r, g, bl).about(what[0])
    }
}

impl StRgbMut {
    /// # Safety
    /// See [`plane_mut`], for each channel.
    pub(crate) unsafe fn view<'a>(
        &self,
        what: [&'static str; 3],
        b: &mut Borrows,
    ) -> Result<RgbPlanesMut<'a>, Failure> {
        // SAFETY: each channel under this method's contract, `plane_mut`'s.
        let (r, g, bl) = unsafe { (self.r.view(what[0], b)?, self.g.view(what[1], b)?, self.b.view(what[2], b)?) };
        RgbPlanesMut::new(r, g, bl).about(what[0])
    }
}

/// The value behind a required pointer argument.
///
/// # Safety
/// `p` must be null or point to a valid `T` for the duration of the call.
pub(crate) unsafe fn required<'a, T>(p: *const T, what: &str) -> Result<&'a T, Failure> {
    // SAFETY: the caller's contract.
    unsafe { p.as_ref() }.ok_or_else(|| Failure::null(what))
}
