//! Frame views: structure-of-arrays planes with width, height and stride.
//!
//! Every kernel takes its images as [`Plane`] / [`PlaneMut`] views over caller-owned
//! buffers. A view is validated once, when it is built: the extent is non-zero and not huge,
//! the stride covers the width, and the buffer holds every row. After that, kernels index
//! rows without further checks that could fail, so a validated view never makes a kernel
//! panic. Strides are in elements, not bytes.
//!
//! Owned buffers ([`PlaneBuf`], [`RgbBuf`]) exist for callers that want the crate to allocate
//! once at set-up; they hand out the same views.

use core::fmt;

/// The largest accepted width or height. 32768 covers 16K frames; anything above is almost
/// certainly a unit or parsing mistake, and `width * height` must stay well inside `u32`
/// lane indices used by the gathers.
pub const MAX_DIMENSION: usize = 1 << 15;

/// The largest accepted pixel count (2^28: 16K × 16K).
pub const MAX_PIXELS: usize = 1 << 28;

/// The largest accepted row stride, in elements. A stride may pad rows, but not absurdly: it
/// shares the dimension limit's reasoning.
pub const MAX_STRIDE: usize = 4 * MAX_DIMENSION;

/// Width and height of a frame in pixels. Only [`Extent::new`] builds one, so every extent in
/// circulation is non-zero and within [`MAX_DIMENSION`] / [`MAX_PIXELS`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Extent {
    width: usize,
    height: usize,
}

impl Extent {
    /// Validates a resolution.
    pub fn new(width: usize, height: usize) -> Result<Self, FrameError> {
        if width == 0 || height == 0 {
            return Err(FrameError::ZeroSize { width, height });
        }
        if width > MAX_DIMENSION || height > MAX_DIMENSION || width * height > MAX_PIXELS {
            return Err(FrameError::TooLarge { width, height });
        }
        Ok(Self { width, height })
    }

    /// Pixels per row.
    #[inline]
    pub fn width(self) -> usize {
        self.width
    }

    /// Rows.
    #[inline]
    pub fn height(self) -> usize {
        self.height
    }

    /// `width · height`.
    #[inline]
    pub fn pixels(self) -> usize {
        self.width * self.height
    }
}

impl fmt::Display for Extent {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}x{}", self.width, self.height)
    }
}

/// Why a view, a buffer or a kernel call was refused.
#[derive(Debug, Clone, PartialEq)]
pub enum FrameError {
    /// Width or height is zero.
    ZeroSize {
        /// The width given.
        width: usize,
        /// The height given.
        height: usize,
    },
    /// Width or height above [`MAX_DIMENSION`], or more than [`MAX_PIXELS`] pixels.
    TooLarge {
        /// The width (or stride) given.
        width: usize,
        /// The height given.
        height: usize,
    },
    /// The stride (in elements) is smaller than the width.
    StrideTooSmall {
        /// The width given.
        width: usize,
        /// The stride given.
        stride: usize,
    },
    /// The buffer is shorter than `(height − 1) · stride + width` elements.
    BufferTooSmall {
        /// Elements the view needs.
        needed: usize,
        /// Elements the buffer holds.
        got: usize,
    },
    /// Two views that a kernel combines pixel by pixel have different extents.
    ExtentMismatch {
        /// Which view.
        what: &'static str,
        /// The extent it must have.
        expected: Extent,
        /// The extent it has.
        got: Extent,
    },
    /// A kernel parameter is out of its documented range (the message names it).
    InvalidParameter(&'static str),
    /// A camera matrix is singular or not finite.
    SingularCamera,
    /// A value inside a buffer is outside what the kernel defines (a reason code above the
    /// last one, a negative or NaN history length): the kernel cannot compute with it
    /// honestly, so the call is refused before anything is written.
    ValueOutOfRange {
        /// Which buffer.
        what: &'static str,
        /// Where: column.
        x: usize,
        /// Where: row.
        y: usize,
        /// The value found.
        value: f64,
        /// What the kernel accepts.
        allowed: &'static str,
    },
    /// The image is smaller than the kernel's window along one side (SSIM's 11×11): its
    /// statistics would come from padding, not from the image.
    SmallerThanWindow {
        /// The extent given.
        extent: Extent,
        /// The smallest width and height accepted.
        window: usize,
    },
    /// Allocating an owned buffer failed: the allocator refused `bytes` bytes (an address-space
    /// limit, or not enough memory). Nothing was kept.
    OutOfMemory {
        /// The size of the allocation that failed.
        bytes: usize,
    },
}

impl fmt::Display for FrameError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::ZeroSize { width, height } => {
                write!(f, "frame size {width}x{height} has a zero dimension")
            }
            Self::TooLarge { width, height } => write!(
                f,
                "frame size {width}x{height} is too large (at most {MAX_DIMENSION} per side and {MAX_PIXELS} pixels)"
            ),
            Self::StrideTooSmall { width, stride } => {
                write!(f, "row stride {stride} is smaller than the width {width}")
            }
            Self::BufferTooSmall { needed, got } => {
                write!(f, "buffer holds {got} elements but the view needs {needed}")
            }
            Self::ExtentMismatch { what, expected, got } => {
                write!(f, "{what} is {got} but must be {expected}")
            }
            Self::InvalidParameter(what) => write!(f, "invalid parameter: {what}"),
            Self::SingularCamera => write!(f, "camera matrix is singular or not finite"),
            Self::ValueOutOfRange { what, x, y, value, allowed } => {
                write!(f, "{what} holds {value} at pixel ({x}, {y}): it must be {allowed}")
            }
            Self::SmallerThanWindow { extent, window } => write!(
                f,
                "image {extent} is smaller than the {window}x{window} window: both sides must be at least {window}"
            ),
            Self::OutOfMemory { bytes } => write!(f, "out of memory: could not allocate {bytes} bytes"),
        }
    }
}

impl std::error::Error for FrameError {}

/// Elements a view of this extent and stride must be able to index.
fn required_len(extent: Extent, stride: usize) -> usize {
    // Cannot overflow: height, stride and width are bounded by the checks in `validate`.
    (extent.height - 1) * stride + extent.width
}

fn validate(len: usize, width: usize, height: usize, stride: usize) -> Result<Extent, FrameError> {
    let extent = Extent::new(width, height)?;
    if stride < width {
        return Err(FrameError::StrideTooSmall { width, stride });
    }
    if stride > MAX_STRIDE {
        return Err(FrameError::TooLarge { width: stride, height });
    }
    let needed = required_len(extent, stride);
    if len < needed {
        return Err(FrameError::BufferTooSmall { needed, got: len });
    }
    Ok(extent)
}

/// A read-only plane of `T` (one channel of an image), row-major with a stride.
#[derive(Clone, Copy)]
pub struct Plane<'a, T = f32> {
    data: &'a [T],
    extent: Extent,
    stride: usize,
}

impl<'a, T: Copy> Plane<'a, T> {
    /// A view over `data` with rows `stride` elements apart.
    pub fn new(data: &'a [T], width: usize, height: usize, stride: usize) -> Result<Self, FrameError> {
        let extent = validate(data.len(), width, height, stride)?;
        Ok(Self { data: &data[..required_len(extent, stride)], extent, stride })
    }

    /// A view over a tightly packed buffer (`stride == width`).
    pub fn packed(data: &'a [T], width: usize, height: usize) -> Result<Self, FrameError> {
        Self::new(data, width, height, width)
    }

    /// The view's width and height.
    #[inline]
    pub fn extent(&self) -> Extent {
        self.extent
    }

    /// Pixels per row.
    #[inline]
    pub fn width(&self) -> usize {
        self.extent.width
    }

    /// Rows.
    #[inline]
    pub fn height(&self) -> usize {
        self.extent.height
    }

    /// Elements from one row's start to the next.
    #[inline]
    pub fn stride(&self) -> usize {
        self.stride
    }

    /// The underlying elements, from the first pixel to the last (padding between rows
    /// included, nothing after the last row).
    #[inline]
    pub fn as_slice(&self) -> &'a [T] {
        self.data
    }

    /// Row `y`, exactly `width` elements. Panics if `y >= height`.
    #[inline]
    pub fn row(&self, y: usize) -> &'a [T] {
        let start = y * self.stride;
        &self.data[start..start + self.extent.width]
    }

    /// Starts loading the cache line of pixel `(x, y)` (reads nothing; outside the extent,
    /// does nothing).
    #[inline(always)]
    pub fn prefetch(&self, x: usize, y: usize) {
        if x < self.extent.width && y < self.extent.height {
            crate::simd::prefetch(self.data.as_ptr().wrapping_add(y * self.stride + x));
        }
    }

    /// The pixel at `(x, y)`. Panics outside the extent.
    #[inline]
    pub fn get(&self, x: usize, y: usize) -> T {
        assert!(x < self.extent.width, "x {x} outside width {}", self.extent.width);
        self.data[y * self.stride + x]
    }

    /// Pixels `x .. x + N` of row `y` as an array: one bounds check for all `N` (the
    /// kernels' vector loads). Panics unless `x + N <= width` and `y < height`.
    #[inline(always)]
    pub fn lanes<const N: usize>(&self, x: usize, y: usize) -> [T; N] {
        // A plain message: formatting x and y would spill them before every load.
        assert!(x + N <= self.extent.width && y < self.extent.height, "vector load outside the plane");
        // SAFETY: the row holds `width` elements from `y · stride` (construction checked the
        // buffer length), and `x + N <= width` was just checked.
        unsafe { core::ptr::read_unaligned(self.data.as_ptr().add(y * self.stride + x).cast::<[T; N]>()) }
    }

    /// [`Plane::lanes`] without the bounds check.
    ///
    /// # Safety
    /// `x + N <= width` and `y < height`.
    #[inline(always)]
    pub unsafe fn lanes_unchecked<const N: usize>(&self, x: usize, y: usize) -> [T; N] {
        debug_assert!(x + N <= self.extent.width && y < self.extent.height);
        // SAFETY: the caller keeps the lanes inside the row (see `lanes`).
        unsafe { core::ptr::read_unaligned(self.data.as_ptr().add(y * self.stride + x).cast::<[T; N]>()) }
    }

    /// The pixel at `(x, y)` without bounds checks in release builds.
    ///
    /// # Safety
    /// `x < width` and `y < height`.
    #[inline(always)]
    pub unsafe fn get_unchecked(&self, x: usize, y: usize) -> T {
        debug_assert!(x < self.extent.width && y < self.extent.height);
        // SAFETY: the caller keeps (x, y) inside the extent, and construction checked that
        // the buffer holds `(height − 1)·stride + width` elements.
        unsafe { *self.data.get_unchecked(y * self.stride + x) }
    }
}

/// A mutable plane of `T`, row-major with a stride.
pub struct PlaneMut<'a, T = f32> {
    data: &'a mut [T],
    extent: Extent,
    stride: usize,
}

impl<'a, T: Copy + Send> PlaneMut<'a, T> {
    /// A view over `data` with rows `stride` elements apart.
    pub fn new(data: &'a mut [T], width: usize, height: usize, stride: usize) -> Result<Self, FrameError> {
        let extent = validate(data.len(), width, height, stride)?;
        let needed = required_len(extent, stride);
        Ok(Self { data: &mut data[..needed], extent, stride })
    }

    /// A view over a tightly packed buffer (`stride == width`).
    pub fn packed(data: &'a mut [T], width: usize, height: usize) -> Result<Self, FrameError> {
        Self::new(data, width, height, width)
    }

    /// The view's width and height.
    #[inline]
    pub fn extent(&self) -> Extent {
        self.extent
    }

    /// Pixels per row.
    #[inline]
    pub fn width(&self) -> usize {
        self.extent.width
    }

    /// Rows.
    #[inline]
    pub fn height(&self) -> usize {
        self.extent.height
    }

    /// Elements from one row's start to the next.
    #[inline]
    pub fn stride(&self) -> usize {
        self.stride
    }

    /// A read-only view of the same pixels.
    #[inline]
    pub fn as_plane(&self) -> Plane<'_, T> {
        Plane { data: self.data, extent: self.extent, stride: self.stride }
    }

    /// A shorter-lived mutable view of the same pixels.
    #[inline]
    pub fn reborrow(&mut self) -> PlaneMut<'_, T> {
        PlaneMut { data: self.data, extent: self.extent, stride: self.stride }
    }

    /// Row `y`, exactly `width` elements. Panics if `y >= height`.
    #[inline]
    pub fn row_mut(&mut self, y: usize) -> &mut [T] {
        let start = y * self.stride;
        &mut self.data[start..start + self.extent.width]
    }

    /// Row `y`, read-only.
    #[inline]
    pub fn row(&self, y: usize) -> &[T] {
        let start = y * self.stride;
        &self.data[start..start + self.extent.width]
    }

    /// Sets every pixel (not the padding) to `value`.
    pub fn fill(&mut self, value: T) {
        for y in 0..self.extent.height {
            self.row_mut(y).fill(value);
        }
    }

    /// Splits the plane into horizontal bands of `rows` rows (the last may be shorter), in
    /// order from the top. Each band is a valid plane of its own; this is how kernels hand
    /// disjoint rows to rayon without allocating.
    pub fn into_bands(self, rows: usize) -> impl Iterator<Item = PlaneMut<'a, T>> {
        let rows = rows.max(1);
        let (width, height, stride) = (self.extent.width, self.extent.height, self.stride);
        self.data.chunks_mut(rows * stride).enumerate().map(move |(band, chunk)| {
            let band_height = rows.min(height - band * rows);
            PlaneMut {
                data: chunk,
                // Every band has 1..=rows rows and the plane's width: a valid extent.
                extent: Extent { width, height: band_height },
                stride,
            }
        })
    }

    /// The buffer, extent and stride (for the band scheduler, which hands out rows).
    pub(crate) fn into_raw_parts(self) -> (&'a mut [T], Extent, usize) {
        (self.data, self.extent, self.stride)
    }
}

/// The three colour planes of a linear RGB image. All three share one extent: the fields
/// are private so that only [`RgbPlanes::new`] (which checks) and the owned buffers (whose
/// planes share an extent by construction) make one, and the kernels may load any channel
/// where they checked one.
///
/// Planes of different sizes cannot be combined by hand (this once let safe code make the
/// reprojection read past a small green plane):
///
/// ```compile_fail
/// use stereotrace_kernels::frame::{Plane, RgbPlanes};
/// let (big, small) = (vec![0.0f32; 64], vec![0.0f32; 1]);
/// let (big, small) = (Plane::packed(&big, 8, 8).unwrap(), Plane::packed(&small, 1, 1).unwrap());
/// let _ = RgbPlanes { r: big, g: small, b: big };
/// ```
///
/// ```
/// use stereotrace_kernels::frame::{Plane, RgbPlanes};
/// let (big, small) = (vec![0.0f32; 64], vec![0.0f32; 1]);
/// let (big, small) = (Plane::packed(&big, 8, 8).unwrap(), Plane::packed(&small, 1, 1).unwrap());
/// assert!(RgbPlanes::new(big, small, big).is_err());
/// ```
#[derive(Clone, Copy)]
pub struct RgbPlanes<'a> {
    r: Plane<'a>,
    g: Plane<'a>,
    b: Plane<'a>,
}

impl<'a> RgbPlanes<'a> {
    /// Combines three planes, checking that their extents agree.
    pub fn new(r: Plane<'a>, g: Plane<'a>, b: Plane<'a>) -> Result<Self, FrameError> {
        same_extent("green plane", r.extent(), g.extent())?;
        same_extent("blue plane", r.extent(), b.extent())?;
        Ok(Self { r, g, b })
    }

    /// The common extent of the three planes.
    #[inline]
    pub fn extent(&self) -> Extent {
        self.r.extent()
    }

    /// The planes in red, green, blue order.
    #[inline]
    pub fn channels(&self) -> [Plane<'a>; 3] {
        [self.r, self.g, self.b]
    }

    /// Red.
    #[inline]
    pub fn r(&self) -> Plane<'a> {
        self.r
    }

    /// Green.
    #[inline]
    pub fn g(&self) -> Plane<'a> {
        self.g
    }

    /// Blue.
    #[inline]
    pub fn b(&self) -> Plane<'a> {
        self.b
    }

    /// The pixel at `(x, y)` as `[r, g, b]`.
    #[inline]
    pub fn get(&self, x: usize, y: usize) -> [f32; 3] {
        [self.r.get(x, y), self.g.get(x, y), self.b.get(x, y)]
    }
}

/// Three mutable colour planes sharing one extent (private fields, as [`RgbPlanes`]).
pub struct RgbPlanesMut<'a> {
    r: PlaneMut<'a>,
    g: PlaneMut<'a>,
    b: PlaneMut<'a>,
}

impl<'a> RgbPlanesMut<'a> {
    /// Combines three planes, checking that their extents agree.
    pub fn new(r: PlaneMut<'a>, g: PlaneMut<'a>, b: PlaneMut<'a>) -> Result<Self, FrameError> {
        same_extent("green plane", r.extent(), g.extent())?;
        same_extent("blue plane", r.extent(), b.extent())?;
        Ok(Self { r, g, b })
    }

    /// The common extent of the three planes.
    #[inline]
    pub fn extent(&self) -> Extent {
        self.r.extent()
    }

    /// A read-only view of the same planes.
    #[inline]
    pub fn as_planes(&self) -> RgbPlanes<'_> {
        RgbPlanes { r: self.r.as_plane(), g: self.g.as_plane(), b: self.b.as_plane() }
    }

    /// A shorter-lived view of the same planes.
    #[inline]
    pub fn reborrow(&mut self) -> RgbPlanesMut<'_> {
        RgbPlanesMut { r: self.r.reborrow(), g: self.g.reborrow(), b: self.b.reborrow() }
    }

    /// The three planes, one extent.
    #[inline]
    pub fn into_channels(self) -> [PlaneMut<'a>; 3] {
        [self.r, self.g, self.b]
    }

    /// Horizontal bands of `rows` rows, as [`PlaneMut::into_bands`].
    pub fn into_bands(self, rows: usize) -> impl Iterator<Item = RgbPlanesMut<'a>> {
        self.r
            .into_bands(rows)
            .zip(self.g.into_bands(rows))
            .zip(self.b.into_bands(rows))
            .map(|((r, g), b)| RgbPlanesMut { r, g, b })
    }
}

/// Fails with [`FrameError::ExtentMismatch`] unless `got == expected`.
#[inline]
pub fn same_extent(what: &'static str, expected: Extent, got: Extent) -> Result<(), FrameError> {
    if expected == got { Ok(()) } else { Err(FrameError::ExtentMismatch { what, expected, got }) }
}

/// `len` copies of `value` in a vector allocated fallibly.
pub fn try_filled_vec<T: Copy>(len: usize, value: T) -> Result<Vec<T>, FrameError> {
    let mut data = Vec::new();
    data.try_reserve_exact(len)
        .map_err(|_| FrameError::OutOfMemory { bytes: len.saturating_mul(core::mem::size_of::<T>()) })?;
    data.resize(len, value);
    Ok(data)
}

/// An owned, tightly packed plane (`stride == width`), allocated once.
#[derive(Clone, Debug, PartialEq)]
pub struct PlaneBuf<T = f32> {
    data: Vec<T>,
    extent: Extent,
}

impl<T: Copy + Send + Sync> PlaneBuf<T> {
    /// A plane of `extent` filled with `value`.
    pub fn new(extent: Extent, value: T) -> Self {
        Self { data: vec![value; extent.pixels()], extent }
    }

    /// [`PlaneBuf::new`] that reports an allocation failure as [`FrameError::OutOfMemory`]
    /// instead of aborting the process: what every buffer sized by a caller's resolution
    /// uses (an engine may ask for 16K × 16K under a memory limit).
    pub fn try_new(extent: Extent, value: T) -> Result<Self, FrameError> {
        Ok(Self { data: try_filled_vec(extent.pixels(), value)?, extent })
    }

    /// Takes ownership of `data` (row-major, `width · height` elements).
    pub fn from_vec(data: Vec<T>, extent: Extent) -> Result<Self, FrameError> {
        if data.len() != extent.pixels() {
            return Err(FrameError::BufferTooSmall { needed: extent.pixels(), got: data.len() });
        }
        Ok(Self { data, extent })
    }

    /// The buffer's width and height.
    #[inline]
    pub fn extent(&self) -> Extent {
        self.extent
    }

    /// A read-only view (packed rows: stride = width).
    #[inline]
    pub fn view(&self) -> Plane<'_, T> {
        Plane { data: &self.data, extent: self.extent, stride: self.extent.width }
    }

    /// A writable view (packed rows).
    #[inline]
    pub fn view_mut(&mut self) -> PlaneMut<'_, T> {
        PlaneMut { data: &mut self.data, extent: self.extent, stride: self.extent.width }
    }

    /// The pixels, row after row.
    #[inline]
    pub fn as_slice(&self) -> &[T] {
        &self.data
    }

    /// The pixels, row after row, writable (the length cannot change).
    #[inline]
    pub fn as_mut_slice(&mut self) -> &mut [T] {
        &mut self.data
    }

    /// The allocation's capacity in elements (tests use it to prove no growth per frame).
    #[inline]
    pub fn capacity(&self) -> usize {
        self.data.capacity()
    }
}

/// An owned linear RGB image: three packed f32 planes of one extent. The fields are private
/// (a plane of another size must not be swapped in: the views it gives are trusted); the
/// values are read through [`RgbBuf::r`] and friends and written through the slices of
/// [`RgbBuf::r_mut`] and friends, which cannot change a plane's size.
///
/// ```compile_fail
/// use stereotrace_kernels::frame::{Extent, PlaneBuf, RgbBuf};
/// let mut img = RgbBuf::new(Extent::new(8, 8).unwrap(), 0.0);
/// img.g = PlaneBuf::new(Extent::new(1, 1).unwrap(), 0.0);
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct RgbBuf {
    r: PlaneBuf,
    g: PlaneBuf,
    b: PlaneBuf,
}

impl RgbBuf {
    /// An image of `extent` filled with `value` in every channel.
    pub fn new(extent: Extent, value: f32) -> Self {
        Self { r: PlaneBuf::new(extent, value), g: PlaneBuf::new(extent, value), b: PlaneBuf::new(extent, value) }
    }

    /// [`RgbBuf::new`] that reports an allocation failure instead of aborting (see
    /// [`PlaneBuf::try_new`]).
    pub fn try_new(extent: Extent, value: f32) -> Result<Self, FrameError> {
        Ok(Self {
            r: PlaneBuf::try_new(extent, value)?,
            g: PlaneBuf::try_new(extent, value)?,
            b: PlaneBuf::try_new(extent, value)?,
        })
    }

    /// Combines three planes, checking that their extents agree.
    pub fn from_planes(r: PlaneBuf, g: PlaneBuf, b: PlaneBuf) -> Result<Self, FrameError> {
        same_extent("green plane", r.extent(), g.extent())?;
        same_extent("blue plane", r.extent(), b.extent())?;
        Ok(Self { r, g, b })
    }

    /// The three planes (one extent), for the caller to keep.
    pub fn into_planes(self) -> [PlaneBuf; 3] {
        [self.r, self.g, self.b]
    }

    /// Red.
    #[inline]
    pub fn r(&self) -> &PlaneBuf {
        &self.r
    }

    /// Green.
    #[inline]
    pub fn g(&self) -> &PlaneBuf {
        &self.g
    }

    /// Blue.
    #[inline]
    pub fn b(&self) -> &PlaneBuf {
        &self.b
    }

    /// The three planes in channel order.
    #[inline]
    pub fn planes(&self) -> [&PlaneBuf; 3] {
        [&self.r, &self.g, &self.b]
    }

    /// The red values, packed row by row, to write in place.
    #[inline]
    pub fn r_mut(&mut self) -> &mut [f32] {
        self.r.as_mut_slice()
    }

    /// The green values, as [`RgbBuf::r_mut`].
    #[inline]
    pub fn g_mut(&mut self) -> &mut [f32] {
        self.g.as_mut_slice()
    }

    /// The blue values, as [`RgbBuf::r_mut`].
    #[inline]
    pub fn b_mut(&mut self) -> &mut [f32] {
        self.b.as_mut_slice()
    }

    /// The values of the three channels, packed row by row (pixel `(x, y)` at `y·w + x`).
    #[inline]
    pub fn slices(&self) -> [&[f32]; 3] {
        [self.r.as_slice(), self.g.as_slice(), self.b.as_slice()]
    }

    /// The values of the three channels, packed row by row, to write in place.
    #[inline]
    pub fn slices_mut(&mut self) -> [&mut [f32]; 3] {
        [self.r.as_mut_slice(), self.g.as_mut_slice(), self.b.as_mut_slice()]
    }

    /// The common extent of the three planes.
    #[inline]
    pub fn extent(&self) -> Extent {
        self.r.extent()
    }

    /// A read-only view of the three planes.
    #[inline]
    pub fn view(&self) -> RgbPlanes<'_> {
        RgbPlanes { r: self.r.view(), g: self.g.view(), b: self.b.view() }
    }

    /// A writable view of the three planes.
    #[inline]
    pub fn view_mut(&mut self) -> RgbPlanesMut<'_> {
        RgbPlanesMut { r: self.r.view_mut(), g: self.g.view_mut(), b: self.b.view_mut() }
    }

    /// The pixel at `(x, y)` as `[r, g, b]`.
    #[inline]
    pub fn get(&self, x: usize, y: usize) -> [f32; 3] {
        self.view().get(x, y)
    }

    /// Sets the pixel at `(x, y)`.
    #[inline]
    pub fn set(&mut self, x: usize, y: usize, rgb: [f32; 3]) {
        let i = y * self.extent().width() + x;
        self.r.as_mut_slice()[i] = rgb[0];
        self.g.as_mut_slice()[i] = rgb[1];
        self.b.as_mut_slice()[i] = rgb[2];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn extent_rejects_zero_and_huge() {
        assert_eq!(Extent::new(0, 5), Err(FrameError::ZeroSize { width: 0, height: 5 }));
        assert_eq!(Extent::new(5, 0), Err(FrameError::ZeroSize { width: 5, height: 0 }));
        assert!(matches!(Extent::new(MAX_DIMENSION + 1, 1), Err(FrameError::TooLarge { .. })));
        assert!(matches!(Extent::new(MAX_DIMENSION, MAX_DIMENSION), Err(FrameError::TooLarge { .. })));
        assert!(Extent::new(1, 1).is_ok());
        assert!(Extent::new(1280, 720).is_ok());
    }

    #[test]
    fn plane_validates_stride_and_length() {
        let data = vec![0.0f32; 10];
        assert_eq!(Plane::new(&data, 4, 2, 3).err(), Some(FrameError::StrideTooSmall { width: 4, stride: 3 }));
        // Two rows of width 4 with stride 6 need 6 + 4 = 10 elements: fits exactly.
        assert!(Plane::new(&data, 4, 2, 6).is_ok());
        assert_eq!(Plane::new(&data, 4, 2, 7).err(), Some(FrameError::BufferTooSmall { needed: 11, got: 10 }));
        assert!(matches!(Plane::new(&data, 0, 2, 6), Err(FrameError::ZeroSize { .. })));
    }

    #[test]
    fn rows_respect_stride() {
        let data: Vec<f32> = (0..14).map(|i| i as f32).collect();
        let p = Plane::new(&data, 3, 3, 5).unwrap();
        assert_eq!(p.row(0), &[0.0, 1.0, 2.0]);
        assert_eq!(p.row(2), &[10.0, 11.0, 12.0]);
        assert_eq!(p.get(1, 1), 6.0);
    }

    #[test]
    fn bands_cover_every_row_once() {
        let mut data: Vec<u32> = vec![0; 7 * 5 - 2];
        let plane = PlaneMut::new(&mut data, 5, 5, 7).unwrap();
        let mut seen = 0;
        for (i, mut band) in plane.into_bands(2).enumerate() {
            assert_eq!(band.height(), if i < 2 { 2 } else { 1 });
            for y in 0..band.height() {
                band.row_mut(y).fill(i as u32 * 10 + y as u32 + 1);
                seen += 1;
            }
        }
        assert_eq!(seen, 5);
        let plane = Plane::new(&data, 5, 5, 7).unwrap();
        assert_eq!(plane.row(0), &[1; 5]);
        assert_eq!(plane.row(3), &[12; 5]);
        assert_eq!(plane.row(4), &[21; 5]);
    }

    #[test]
    fn mismatched_extents_are_named() {
        let a = vec![0.0f32; 6];
        let b = vec![0.0f32; 8];
        let r = Plane::packed(&a, 3, 2).unwrap();
        let g = Plane::packed(&b, 4, 2).unwrap();
        let err = RgbPlanes::new(r, g, r).err().unwrap();
        assert!(err.to_string().contains("green plane is 4x2 but must be 3x2"), "{err}");
    }
}
