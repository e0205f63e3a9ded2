//! G-buffer views and the two layouts the reprojection kernel reads.
//!
//! A G-buffer holds, per pixel, the view-axis depth, the world position and the shading
//! normal of the surface the pixel-centre primary ray hit (`depth = +inf` where it hit
//! nothing). The kernels read it through [`SurfaceLayout`], which has two implementations:
//!
//! * [`GBuffer`]: seven f32 planes (depth, position xyz, normal xyz). 28 bytes per pixel. The
//!   reference layout and what an engine with its own position buffer hands over.
//! * [`CompactGBuffer`]: an f32 depth plane and a u32 plane of octahedral normals (two 16-bit
//!   signed-normalised components). 8 bytes per pixel. The world position is rebuilt from the
//!   depth and the camera (`X = centre + depth · ray(pixel)`), which reproduces the hit point
//!   to f32 rounding because G-buffer rays go through pixel centres; the octahedral normal is
//!   within 0.01° of the stored one (tested). Reprojection is memory bound, so this layout is the
//!   fast one (measured in BENCHMARKS.md).
//!
//! Each layout gives one pixel as a scalar [`Surfel`] (the reference path), eight consecutive
//! pixels of a row, or eight gathered pixels as [`Surfels`]; the three agree bit for bit.

use crate::camera::CameraModel;
use crate::frame::{Extent, FrameError, Plane, PlaneBuf, same_extent};
use crate::simd::{F32s, LANES, TapCoords, lane_offsets};
use wide::{i32x8, u32x8};

/// One pixel's surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Surfel {
    /// View-axis depth (`+inf`: no surface).
    pub depth: f32,
    /// World position.
    pub position: [f32; 3],
    /// Shading normal (not necessarily unit length).
    pub normal: [f32; 3],
}

/// `LANES` pixels' surfaces.
#[derive(Clone, Copy, Debug)]
pub struct Surfels {
    /// View-axis depth per lane.
    pub depth: F32s,
    /// World position x, y, z per lane.
    pub position: [F32s; 3],
    /// Shading normal x, y, z per lane.
    pub normal: [F32s; 3],
}

impl Surfels {
    /// Lane `i` as a scalar surfel.
    pub fn lane(&self, i: usize) -> Surfel {
        Surfel {
            depth: self.depth.to_array()[i],
            position: self.position.map(|v| v.to_array()[i]),
            normal: self.normal.map(|v| v.to_array()[i]),
        }
    }
}

/// Read access to a G-buffer in one of the layouts above.
pub trait SurfaceLayout: Sync {
    /// Extent of every plane.
    fn extent(&self) -> Extent;
    /// The surface at pixel `(x, y)`. Panics outside the extent.
    fn surfel(&self, x: usize, y: usize) -> Surfel;
    /// The depth of pixel `(x, y)` alone (`+inf` for background), without decoding the
    /// rest of its surface. Panics outside the extent.
    fn depth(&self, x: usize, y: usize) -> f32 {
        self.surfel(x, y).depth
    }
    /// Pixels `x .. x + LANES` of row `y`. Panics unless `x + LANES <= width`.
    #[inline(always)]
    fn surfels_row(&self, x: usize, y: usize) -> Surfels {
        assert!(x + LANES <= self.extent().width() && y < self.extent().height(), "vector load outside the G-buffer");
        // SAFETY: checked on the line above.
        unsafe { self.surfels_row_unchecked(x, y) }
    }
    /// [`SurfaceLayout::surfels_row`] without the bounds check.
    ///
    /// # Safety
    /// `x + LANES <= width` and `y < height`.
    unsafe fn surfels_row_unchecked(&self, x: usize, y: usize) -> Surfels;
    /// The depths of pixels `x .. x + LANES` of row `y` alone (the reprojection skips groups
    /// that are all background before decoding anything else). Panics unless
    /// `x + LANES <= width`.
    fn depth_row(&self, x: usize, y: usize) -> F32s;
    /// The pixels at `taps` (already clamped into the extent).
    fn surfels_gather(&self, taps: &TapCoords) -> Surfels;
    /// The depths alone at `taps` (already clamped into the extent).
    fn depths_gather(&self, taps: &TapCoords) -> F32s {
        self.surfels_gather(taps).depth
    }
    /// Bytes read per pixel (for roofline figures).
    fn bytes_per_pixel(&self) -> usize;
    /// Starts loading the cache lines of pixel `(x, y)` in every plane (reads nothing; a
    /// pixel outside the extent is ignored). For sparse reads, which the hardware prefetcher
    /// cannot foresee. The default does nothing, so a layout that does not prefetch is still
    /// correct.
    #[inline(always)]
    fn prefetch(&self, _x: usize, _y: usize) {}
    /// This G-buffer as the compact layout, if it is one (the AVX-512 reprojection body
    /// decodes compact planes 16 pixels at a time).
    fn as_compact(&self) -> Option<&CompactGBuffer<'_>> {
        None
    }
}

/// The full-precision G-buffer of one eye and frame: seven f32 planes of one extent (the
/// fields are private so that only [`GBuffer::new`], which checks the extents, builds one).
#[derive(Clone, Copy)]
pub struct GBuffer<'a> {
    depth: Plane<'a>,
    position: [Plane<'a>; 3],
    normal: [Plane<'a>; 3],
}

impl<'a> GBuffer<'a> {
    /// Combines the seven planes, checking that their extents agree.
    pub fn new(depth: Plane<'a>, position: [Plane<'a>; 3], normal: [Plane<'a>; 3]) -> Result<Self, FrameError> {
        for p in &position {
            same_extent("world-position plane", depth.extent(), p.extent())?;
        }
        for n in &normal {
            same_extent("normal plane", depth.extent(), n.extent())?;
        }
        Ok(Self { depth, position, normal })
    }

    /// The depth plane.
    pub fn depth(&self) -> Plane<'a> {
        self.depth
    }

    /// The world-position planes x, y, z.
    pub fn position(&self) -> [Plane<'a>; 3] {
        self.position
    }

    /// The normal planes x, y, z.
    pub fn normal(&self) -> [Plane<'a>; 3] {
        self.normal
    }
}

/// # Safety
/// `x + LANES <= width` and `y < height` of `p`.
#[inline(always)]
unsafe fn load_row(p: &Plane<'_>, x: usize, y: usize) -> F32s {
    // SAFETY: forwarded from the caller.
    F32s::from(unsafe { p.lanes_unchecked::<LANES>(x, y) })
}

impl SurfaceLayout for GBuffer<'_> {
    fn extent(&self) -> Extent {
        self.depth.extent()
    }

    #[inline(always)]
    fn prefetch(&self, x: usize, y: usize) {
        self.depth.prefetch(x, y);
        for p in self.position.iter().chain(&self.normal) {
            p.prefetch(x, y);
        }
    }

    fn surfel(&self, x: usize, y: usize) -> Surfel {
        Surfel {
            depth: self.depth.get(x, y),
            position: self.position.map(|p| p.get(x, y)),
            normal: self.normal.map(|p| p.get(x, y)),
        }
    }

    fn depth(&self, x: usize, y: usize) -> f32 {
        self.depth.get(x, y)
    }

    #[inline(always)]
    fn depth_row(&self, x: usize, y: usize) -> F32s {
        assert!(x + LANES <= self.depth.width() && y < self.depth.height(), "vector load outside the G-buffer");
        // SAFETY: checked on the line above.
        unsafe { load_row(&self.depth, x, y) }
    }

    #[inline(always)]
    unsafe fn surfels_row_unchecked(&self, x: usize, y: usize) -> Surfels {
        // SAFETY: (all loads) every plane has the G-buffer's extent (checked by `new`) and
        // the caller keeps the lanes inside it.
        unsafe {
            Surfels {
                depth: load_row(&self.depth, x, y),
                position: self.position.map(|p| load_row(&p, x, y)),
                normal: self.normal.map(|p| load_row(&p, x, y)),
            }
        }
    }

    #[inline(always)]
    fn surfels_gather(&self, taps: &TapCoords) -> Surfels {
        Surfels {
            depth: taps.gather_f32(&self.depth),
            position: self.position.map(|p| taps.gather_f32(&p)),
            normal: self.normal.map(|p| taps.gather_f32(&p)),
        }
    }

    #[inline(always)]
    fn depths_gather(&self, taps: &TapCoords) -> F32s {
        taps.gather_f32(&self.depth)
    }

    fn bytes_per_pixel(&self) -> usize {
        7 * 4
    }
}

/// Depth plus octahedral normals; positions rebuilt from depth through `camera`. Built only
/// by [`CompactGBuffer::new`], which checks that the extents agree.
#[derive(Clone, Copy)]
pub struct CompactGBuffer<'a> {
    depth: Plane<'a>,
    /// [`encode_normal`] of each pixel's shading normal.
    normal: Plane<'a, u32>,
    /// The camera that rendered this G-buffer.
    camera: CameraModel,
    /// Its ray corner, per-pixel steps and centre, splatted once (the decode then reads each
    /// as a memory operand instead of broadcasting it on every use).
    rays: CameraLanes,
}

/// [`CameraModel`]'s position-rebuilding parameters as lanes.
#[derive(Clone, Copy)]
struct CameraLanes {
    corner: [F32s; 3],
    dx: [F32s; 3],
    dy: [F32s; 3],
    centre: [F32s; 3],
}

impl<'a> CompactGBuffer<'a> {
    /// Combines the planes and the camera, checking that their extents agree.
    pub fn new(depth: Plane<'a>, normal: Plane<'a, u32>, camera: CameraModel) -> Result<Self, FrameError> {
        same_extent("normal plane", depth.extent(), normal.extent())?;
        same_extent("camera extent", depth.extent(), camera.extent)?;
        let rays = CameraLanes {
            corner: camera.ray_origin_corner.map(F32s::splat),
            dx: camera.ray_dx.map(F32s::splat),
            dy: camera.ray_dy.map(F32s::splat),
            centre: camera.centre.map(F32s::splat),
        };
        Ok(Self { depth, normal, camera, rays })
    }

    /// The depth plane.
    pub fn depth(&self) -> Plane<'a> {
        self.depth
    }

    /// The octahedral-normal plane.
    pub fn normal(&self) -> Plane<'a, u32> {
        self.normal
    }

    /// The camera positions are rebuilt through.
    pub fn camera(&self) -> &CameraModel {
        &self.camera
    }

    #[inline(always)]
    fn positions(&self, depth: F32s, px: F32s, py: F32s) -> [F32s; 3] {
        let c = &self.rays;
        // The order of `CameraModel::unproject_pixel`: (corner + px·dx) + py·dy.
        let at = |i: usize| c.centre[i] + depth * ((c.corner[i] + px * c.dx[i]) + py * c.dy[i]);
        [at(0), at(1), at(2)]
    }
}

impl SurfaceLayout for CompactGBuffer<'_> {
    fn extent(&self) -> Extent {
        self.depth.extent()
    }

    #[inline(always)]
    fn prefetch(&self, x: usize, y: usize) {
        self.depth.prefetch(x, y);
        self.normal.prefetch(x, y);
    }

    fn surfel(&self, x: usize, y: usize) -> Surfel {
        let depth = self.depth.get(x, y);
        Surfel {
            depth,
            position: self.camera.unproject_pixel(x, y, depth),
            normal: decode_normal_raw(self.normal.get(x, y)),
        }
    }

    fn depth(&self, x: usize, y: usize) -> f32 {
        self.depth.get(x, y)
    }

    #[inline(always)]
    fn depth_row(&self, x: usize, y: usize) -> F32s {
        assert!(x + LANES <= self.depth.width() && y < self.depth.height(), "vector load outside the G-buffer");
        // SAFETY: checked on the line above.
        unsafe { load_row(&self.depth, x, y) }
    }

    #[inline(always)]
    unsafe fn surfels_row_unchecked(&self, x: usize, y: usize) -> Surfels {
        // SAFETY: both planes have the G-buffer's extent (checked by `new`) and the caller
        // keeps the lanes inside it.
        let depth = unsafe { load_row(&self.depth, x, y) };
        // Coordinates are below MAX_DIMENSION, so the i32 conversion (one instruction; usize
        // to f32 is several) is exact.
        let px = F32s::splat(x as i32 as f32) + lane_offsets() + F32s::splat(0.5);
        let py = F32s::splat(y as i32 as f32 + 0.5);
        // SAFETY: as above.
        let packed = u32x8::from(unsafe { self.normal.lanes_unchecked::<LANES>(x, y) });
        Surfels { depth, position: self.positions(depth, px, py), normal: decode_normals_raw(packed) }
    }

    #[inline(always)]
    fn surfels_gather(&self, taps: &TapCoords) -> Surfels {
        let depth = taps.gather_f32(&self.depth);
        let px = F32s::from(taps.x.map(|v| v as f32)) + F32s::splat(0.5);
        let py = F32s::from(taps.y.map(|v| v as f32)) + F32s::splat(0.5);
        let packed = taps.gather_u32(&self.normal);
        Surfels { depth, position: self.positions(depth, px, py), normal: decode_normals_raw(packed) }
    }

    #[inline(always)]
    fn depths_gather(&self, taps: &TapCoords) -> F32s {
        taps.gather_f32(&self.depth)
    }

    fn bytes_per_pixel(&self) -> usize {
        4 + 4
    }

    fn as_compact(&self) -> Option<&CompactGBuffer<'_>> {
        Some(self)
    }
}

/// An owned G-buffer of one eye and frame, the one type every producer fills (the
/// renderer's traced and rasterised passes, an engine's own pass, the analytic test scenes):
/// the full layout's planes (depth, position, normal), the compact layout's octahedral
/// normals, the camera that rendered it, and a material id per pixel (`u32::MAX` for
/// background; the producer's own, not read by the kernels). Allocated once, rewritten every
/// frame.
#[derive(Clone, Debug)]
pub struct GBufferBuf {
    /// The camera that rendered it (its extent is the planes'), jittered by `jitter`.
    pub camera: CameraModel,
    /// The sub-pixel jitter `camera` carries ([`CameraModel::jittered`]), in pixels; the
    /// colour images that go with this G-buffer are on the unjittered grid.
    pub jitter: [f32; 2],
    /// View-axis depth (`+inf`: no surface).
    pub depth: PlaneBuf,
    /// World position x, y, z (NaN: no surface).
    pub position: [PlaneBuf; 3],
    /// World shading normal x, y, z (NaN: no surface).
    pub normal: [PlaneBuf; 3],
    /// [`encode_normal`] of the shading normal ([`NO_NORMAL`]: no surface).
    pub normal_oct: PlaneBuf<u32>,
    /// The producer's material id (`u32::MAX`: no surface).
    pub material: PlaneBuf<u32>,
    /// Optional: how far each pixel's temporal history can be trusted, in [0, 1], from the
    /// producer (for what reprojection cannot see: a moved light, a disocclusion the producer
    /// knows of). Present only where its consumer asks for it (a pipeline configured with
    /// `history_confidence`); a producer that does not know it leaves it at 1.
    pub history_confidence: Option<PlaneBuf>,
    /// Optional: the world-space motion x, y, z of each pixel's surface since the previous
    /// frame (see `reproject::ReprojectInput::motion`). Present only where its consumer asks
    /// for it (a pipeline configured with `motion_vectors`); a producer that does not know it
    /// leaves it at zero (still).
    pub motion: Option<[PlaneBuf; 3]>,
}

impl GBufferBuf {
    /// Buffers for frames of `camera.extent`.
    pub fn new(camera: CameraModel) -> Self {
        let e = camera.extent;
        Self {
            camera,
            jitter: [0.0; 2],
            depth: PlaneBuf::new(e, f32::INFINITY),
            position: [0; 3].map(|_| PlaneBuf::new(e, f32::NAN)),
            normal: [0; 3].map(|_| PlaneBuf::new(e, f32::NAN)),
            normal_oct: PlaneBuf::new(e, NO_NORMAL),
            material: PlaneBuf::new(e, u32::MAX),
            history_confidence: None,
            motion: None,
        }
    }

    /// [`GBufferBuf::new`] that reports an allocation failure instead of aborting (see
    /// [`PlaneBuf::try_new`]).
    pub fn try_new(camera: CameraModel) -> Result<Self, FrameError> {
        let e = camera.extent;
        let nan = || PlaneBuf::try_new(e, f32::NAN);
        Ok(Self {
            camera,
            jitter: [0.0; 2],
            depth: PlaneBuf::try_new(e, f32::INFINITY)?,
            position: [nan()?, nan()?, nan()?],
            normal: [nan()?, nan()?, nan()?],
            normal_oct: PlaneBuf::try_new(e, NO_NORMAL)?,
            material: PlaneBuf::try_new(e, u32::MAX)?,
            history_confidence: None,
            motion: None,
        })
    }

    /// The planes' extent.
    pub fn extent(&self) -> Extent {
        self.depth.extent()
    }

    /// Copies every plane and the camera of `other` (of the same extent) into these
    /// buffers without allocating: how a producer that renders into buffers of its own hands
    /// a frame to a consumer's.
    pub fn copy_from(&mut self, other: &GBufferBuf) -> Result<(), FrameError> {
        same_extent("G-buffer", self.extent(), other.extent())?;
        (self.camera, self.jitter) = (other.camera, other.jitter);
        self.depth.as_mut_slice().copy_from_slice(other.depth.as_slice());
        for c in 0..3 {
            self.position[c].as_mut_slice().copy_from_slice(other.position[c].as_slice());
            self.normal[c].as_mut_slice().copy_from_slice(other.normal[c].as_slice());
        }
        self.normal_oct.as_mut_slice().copy_from_slice(other.normal_oct.as_slice());
        self.material.as_mut_slice().copy_from_slice(other.material.as_slice());
        // The confidence and motion where both have them (a consumer that asked for it keeps its plane).
        if let (Some(to), Some(from)) = (&mut self.history_confidence, &other.history_confidence) {
            to.as_mut_slice().copy_from_slice(from.as_slice());
        }
        if let (Some(to), Some(from)) = (&mut self.motion, &other.motion) {
            for (to, from) in to.iter_mut().zip(from) {
                to.as_mut_slice().copy_from_slice(from.as_slice());
            }
        }
        Ok(())
    }

    /// The full-precision kernel view.
    pub fn view(&self) -> GBuffer<'_> {
        GBuffer::new(
            self.depth.view(),
            self.position.each_ref().map(|p| p.view()),
            self.normal.each_ref().map(|p| p.view()),
        )
        .expect("planes of one extent")
    }

    /// The compact kernel view (depth + octahedral normals + camera).
    pub fn compact(&self) -> CompactGBuffer<'_> {
        CompactGBuffer::new(self.depth.view(), self.normal_oct.view(), self.camera).expect("planes of one extent")
    }
}

/// The encoded value of "no normal" (a background pixel or a non-finite normal); it decodes
/// to NaN so that reprojection treats it as invalid. −32768 lies outside the symmetric
/// signed-normalised range, so no real normal encodes to it.
pub const NO_NORMAL: u32 = 0x8000_8000;

pub(crate) const SNORM_MAX: f32 = 32767.0;

/// Octahedral encoding of a normal into two 16-bit signed-normalised components
/// (x in the low half, y in the high half). Zero-length or non-finite input gives
/// [`NO_NORMAL`]. Not performance critical: the G-buffer pass calls it once per pixel.
pub fn encode_normal(n: [f32; 3]) -> u32 {
    let l1 = n[0].abs() + n[1].abs() + n[2].abs();
    if !l1.is_finite() || l1 == 0.0 {
        return NO_NORMAL;
    }
    let (mut px, mut py) = (n[0] / l1, n[1] / l1);
    if n[2] < 0.0 {
        let sign = |v: f32| if v >= 0.0 { 1.0 } else { -1.0 };
        (px, py) = ((1.0 - py.abs()) * sign(px), (1.0 - px.abs()) * sign(py));
    }
    let q = |v: f32| (v.clamp(-1.0, 1.0) * SNORM_MAX).round() as i16 as u16 as u32;
    q(px) | (q(py) << 16)
}

/// [`encode_normal`] of eight normals (lane `i` of each component), bit for bit: the
/// rasterised G-buffer's resolve encodes eight pixels at once. `f32::round` (half away from
/// zero) lowers to a long sequence; here it is `trunc` plus one more unit where the exact
/// remainder `|v − trunc(v)|` is at least ½, which is the same function.
#[inline]
pub fn encode_normals(n: [F32s; 3]) -> [u32; LANES] {
    let l1 = n[0].abs() + n[1].abs() + n[2].abs();
    let valid = l1.simd_lt(F32s::splat(f32::INFINITY)) & l1.simd_ne(F32s::ZERO);
    let (mut px, mut py) = (n[0] / l1, n[1] / l1);
    let lower = n[2].simd_lt(F32s::ZERO);
    if lower.any() {
        let sign = |v: F32s| v.simd_ge(F32s::ZERO).select(F32s::ONE, -F32s::ONE);
        let (fx, fy) = ((F32s::ONE - py.abs()) * sign(px), (F32s::ONE - px.abs()) * sign(py));
        (px, py) = (lower.select(fx, px), lower.select(fy, py));
    }
    let quantise = |v: F32s| -> i32x8 {
        // v.clamp(-1, 1): NaN cannot reach here (invalid lanes are replaced below).
        let scaled = v.fast_max(-F32s::ONE).fast_min(F32s::ONE) * F32s::splat(SNORM_MAX);
        let t = scaled.trunc();
        let away = (scaled - t).abs().simd_ge(F32s::splat(0.5));
        let rounded = away.select(t + scaled.simd_lt(F32s::ZERO).select(-F32s::ONE, F32s::ONE), t);
        rounded.trunc_int()
    };
    // `q as i16 as u16 as u32` is the low 16 bits of `q` (|q| ≤ 32767), and `<< 16` drops
    // the high ones.
    let packed = (quantise(px) & i32x8::splat(0xFFFF)) | (quantise(py) << 16);
    let valid: i32x8 = bytemuck::cast(valid);
    bytemuck::cast(valid.select(packed, i32x8::splat(NO_NORMAL as i32)))
}

/// Scalar decoding of [`encode_normal`]: a unit vector, or NaN for [`NO_NORMAL`].
pub fn decode_normal(packed: u32) -> [f32; 3] {
    let [x, y, z] = decode_normal_raw(packed);
    let len = (x * x + y * y + z * z).sqrt();
    [x / len, y / len, z / len]
}

/// [`decode_normal`] without the final normalisation (length between 1/√3 and 1). The
/// reprojection kernel compares angles without normalising (see `reproject`), which saves a
/// square root and three divisions per tap.
pub fn decode_normal_raw(packed: u32) -> [f32; 3] {
    let lo = packed as u16 as i16;
    let hi = (packed >> 16) as u16 as i16;
    if lo == i16::MIN || hi == i16::MIN {
        return [f32::NAN; 3];
    }
    let mut x = lo as f32 * (1.0 / SNORM_MAX);
    let mut y = hi as f32 * (1.0 / SNORM_MAX);
    let z = 1.0 - x.abs() - y.abs();
    let t = (-z).max(0.0);
    x += if x >= 0.0 { -t } else { t };
    y += if y >= 0.0 { -t } else { t };
    [x, y, z]
}

/// SIMD decoding, lane for lane equal to [`decode_normal`].
#[inline(always)]
pub fn decode_normals(packed: u32x8) -> [F32s; 3] {
    let [x, y, z] = decode_normals_raw(packed);
    let len = (x * x + y * y + z * z).sqrt();
    [x / len, y / len, z / len]
}

/// SIMD decoding, lane for lane equal to [`decode_normal_raw`].
#[inline(always)]
pub fn decode_normals_raw(packed: u32x8) -> [F32s; 3] {
    let bits: i32x8 = bytemuck::cast(packed);
    let lo: i32x8 = (bits << 16) >> 16; // arithmetic shift sign-extends the low half
    let hi: i32x8 = bits >> 16;
    let invalid_lo: F32s = bytemuck::cast(lo.simd_eq(i32x8::splat(i16::MIN as i32)));
    let invalid_hi: F32s = bytemuck::cast(hi.simd_eq(i32x8::splat(i16::MIN as i32)));
    let invalid = invalid_lo | invalid_hi;
    let scale = F32s::splat(1.0 / SNORM_MAX);
    let mut x = lo.round_float() * scale;
    let mut y = hi.round_float() * scale;
    let z = F32s::ONE - x.abs() - y.abs();
    // z is never NaN here, so the plain max (no NaN fix-up) equals f32::max.
    let t = (-z).fast_max(F32s::ZERO);
    x += x.simd_ge(F32s::ZERO).select(-t, t);
    y += y.simd_ge(F32s::ZERO).select(-t, t);
    let nan = F32s::splat(f32::NAN);
    [invalid.select(nan, x), invalid.select(nan, y), invalid.select(nan, z)]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit(v: [f32; 3]) -> [f32; 3] {
        let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        v.map(|c| c / l)
    }

    #[test]
    fn octahedral_round_trip_is_within_a_hundredth_of_a_degree() {
        let mut rng = crate::synth::Rng::new(0x1234_5678);
        let mut next = || rng.range(-1.0, 1.0);
        let mut worst: f64 = 0.0;
        for i in 0..20_000 {
            let n = match i {
                0 => [0.0, 0.0, 1.0],
                1 => [0.0, 0.0, -1.0],
                2 => [1.0, 0.0, 0.0],
                3 => [0.0, -1.0, 0.0],
                _ => unit([next(), next(), next()]),
            };
            let d = decode_normal(encode_normal(n));
            let (n, d) = (n.map(f64::from), d.map(f64::from));
            let cross = [n[1] * d[2] - n[2] * d[1], n[2] * d[0] - n[0] * d[2], n[0] * d[1] - n[1] * d[0]];
            let sin = (cross[0] * cross[0] + cross[1] * cross[1] + cross[2] * cross[2]).sqrt();
            worst = worst.max(sin.asin().to_degrees());
        }
        // 16-bit components step 2/65534 in octahedral space: a few thousandths of a degree.
        assert!(worst < 0.01, "worst error {worst} degrees");
    }

    #[test]
    fn simd_decoding_equals_scalar_bitwise() {
        let mut values = vec![NO_NORMAL, 0, 0x7fff_7fff, 0x8001_8001, 0x0000_8000, 0x8000_0000, u32::MAX, 1];
        let mut s = 99u32;
        for _ in 0..4096 {
            s = s.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            values.push(s);
        }
        for chunk in values.chunks_exact(LANES) {
            let lanes = u32x8::from(<[u32; LANES]>::try_from(chunk).unwrap());
            for (simd, scalar) in [
                (decode_normals(lanes), decode_normal as fn(u32) -> [f32; 3]),
                (decode_normals_raw(lanes), decode_normal_raw),
            ] {
                for (i, &v) in chunk.iter().enumerate() {
                    let scalar = scalar(v);
                    for c in 0..3 {
                        let a = simd[c].to_array()[i];
                        assert!(a.to_bits() == scalar[c].to_bits() || (a.is_nan() && scalar[c].is_nan()), "{v:#x}");
                    }
                }
            }
        }
    }

    #[test]
    fn invalid_normals_encode_to_the_sentinel() {
        assert_eq!(encode_normal([0.0; 3]), NO_NORMAL);
        // The eight-lane encoder equals the scalar one, including halves that round away.
        let mut cases: Vec<[f32; 3]> = vec![
            [0.0; 3],
            [f32::NAN, 0.0, 1.0],
            [f32::INFINITY, 0.0, 1.0],
            [1.0, 0.0, 0.0],
            [-1.0, 0.0, 0.0],
            [0.0, 0.0, -1.0],
            [0.5 / 32767.0, 0.0, 1.0 - 0.5 / 32767.0],
            [-0.5 / 32767.0, 0.0, -1.0],
            [1.5 / 32767.0, -2.5 / 32767.0, 1.0],
        ];
        let mut seed = 9u32;
        let mut next = || {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (seed >> 8) as f32 / (1u32 << 24) as f32 * 2.0 - 1.0
        };
        for _ in 0..20_000 {
            cases.push([next(), next(), next()]);
        }
        for chunk in cases.chunks(LANES) {
            let lanes: [[f32; 3]; LANES] = core::array::from_fn(|i| chunk[i.min(chunk.len() - 1)]);
            let simd = encode_normals([0, 1, 2].map(|c| F32s::from(lanes.map(|n| n[c]))));
            for i in 0..chunk.len() {
                assert_eq!(simd[i], encode_normal(chunk[i]), "{:?}", chunk[i]);
            }
        }
        assert_eq!(encode_normal([f32::NAN, 0.0, 1.0]), NO_NORMAL);
        assert_eq!(encode_normal([f32::INFINITY, 0.0, 1.0]), NO_NORMAL);
        assert!(decode_normal(NO_NORMAL)[0].is_nan());
    }
}
