//! Stereo visibility buffer by rasterisation: which triangle each pixel centre of both eyes
//! sees, the same answer the ray tracer's G-buffer pass gives, at a fraction of its cost.
//!
//! # Pipeline of one call ([`Rasterizer::rasterize`])
//! 1. **Setup** (parallel over fixed chunks of triangles): each triangle's vertices are moved
//!    into the left eye's camera frame once (camera-relative and in f64, so the projection
//!    is exact to ~1e-9 px wherever the scene sits), projected, clipped against a near plane `w > near` (a triangle
//!    crossing it becomes a quad), and turned into one `Record` that holds both eyes:
//!    the parallel rig's eyes differ only by a constant offset of clip-space `x`, so the
//!    right eye's screen `x` is the left eye's plus `Δ/w`. Triangles whose pixel-centre
//!    bounding box is empty in both eyes (behind the camera, off screen, sub-pixel between
//!    centres) cost only this: no record is kept for them (each chunk keeps its visible
//!    records at its front, in triangle order).
//! 2. **Binning**: records are counted per (eye, band of [`BAND_ROWS`] rows by default) per chunk, and
//!    a prefix sum lays out one index list per band in triangle order. Fixed chunks keep
//!    the order independent of the thread count.
//! 3. **Fragments** (parallel over bands of both eyes): each record of a band is walked in
//!    blocks of 8 pixel columns (`simd`, the scalar reference in `scalar`); edge
//!    functions and `q = 1/w` are evaluated in f32 at pixel centres `(x + 0.5, y + 0.5)`,
//!    relative to the record's first pixel (so their rounding scales with the triangle's
//!    size, not the screen's), and depth-tested (larger `q` is nearer).
//!
//! # Agreeing with the tracer instead of a fill convention
//! A screen-space raster decides a pixel whose centre lies within ~1e-3 px of an edge by
//! rounding, while the tracer decides it with its own f32 ray, which itself deviates from
//! the exact pixel centre by up to a few 1e-4 px. No fill rule (top-left or otherwise) can
//! make those decisions agree. So every test here has an **error band**, computed per
//! triangle from the magnitudes involved (`Record::band`, `Record::q_err`): the raster's own
//! rounding, how far the tracer's f32 pixel rays stray, and how far its f32 triangle test
//! may move an edge (negligible broadside, ~10⁻² px for an edge seen end-on whose vertices
//! lie 10³ units away; `tracer_edge_slack`):
//!
//! * a pixel is *inside* when every edge function exceeds its band, *outside* when one is
//!   below minus its band, and *uncertain* otherwise;
//! * a depth test is decided by `q` when the two values differ by more than their error
//!   bounds, and is a *near tie* otherwise;
//! * fragments of alpha-masked triangles ([`AlphaTest`]) need their barycentrics.
//!
//! Uncertain pixels, near ties and masked fragments (rare: a ~1e-3 px band along edges,
//! coplanar surfaces, foliage) take the **exact path**: the tracer's own watertight test
//! ([`crate::bvh::intersect_triangle`]) on the tracer's own pixel ray, and, for a tie, the
//! smaller `t` with the smaller primitive id on equal `t` (the tracer's closest hit; which of
//! two triangles at exactly equal `t` a BVH returns depends on its traversal order, so those
//! pixels are the one place the two may differ). The fast path never decides a case it
//! could get wrong, so raster and traced visibility agree on every pixel that is not an
//! exact depth tie; the root crate's `tests/raster_gbuffers.rs` checks this on every scene.
//! The one exception is the tracer's own rounding: where its f32 test misses a triangle
//! the fast path found certainly covering a pixel (slivers with vertices hundreds of units
//! away), the exact path keeps the stored triangle against any hit certainly behind it, as
//! exact geometry does.
//!
//! # Determinism and the scalar reference
//! Both bodies evaluate the same f32 expressions in the same order (`a * b + c`, two
//! roundings, see [`crate::simd`]) and send the same pixels down the same exact path, so
//! their buffers are equal bit for bit; a band is processed by one thread in bin order, and
//! near ties are decided by `t` and id, so results do not depend on the thread count.
//!
//! # Buffers
//! The [`Rasterizer`] keeps its records and bins between calls and grows them only when a
//! frame needs more than any before (a second frame of the same size allocates nothing).

pub mod fixed;
mod scalar;
mod simd;

use core::ops::Range;
use std::time::{Duration, Instant};

use rayon::prelude::*;

use crate::bvh::{PreparedRay, Ray, TriHit, TriVerts, intersect_triangle};
use crate::camera::CameraModel;
use crate::frame::{Extent, FrameError, PlaneBuf, same_extent};

/// Rows per band by default: the unit of binning and of parallel work. Larger bands mean
/// fewer (record, band) pairs, each with its per-record setup: 32 rows walk fragments 4–9 %
/// faster than 8 at 1280×720 (atrium 15.3 → 14.1 ms, courtyard 28.4 → 25.8 ms, BENCHMARKS),
/// and still give 46 bands over both eyes to balance across threads. The buffers do not
/// depend on it ([`Rasterizer::with_band_rows`]).
pub const BAND_ROWS: usize = 32;
/// Triangles per setup chunk (fixed, so that bin order does not depend on the thread count).
const CHUNK: usize = 4096;
/// The id stored for pixels that see no triangle.
pub const NO_PRIM: u32 = u32::MAX;
/// Unit roundoff of f32.
pub(crate) const U: f32 = f32::EPSILON * 0.5;

/// Which triangles have cut-out masks, and whether a hit on one is opaque. Masked triangles
/// are tested per fragment with the hit's barycentrics, as the tracer tests its hits.
pub trait AlphaTest: Sync {
    /// Whether triangle `prim` has a mask (only those pay for the per-fragment test).
    fn has_mask(&self, prim: u32) -> bool;
    /// Whether the hit at barycentrics `(u, v)` (the weights of vertices 1 and 2) is kept.
    fn opaque(&self, prim: u32, u: f32, v: f32) -> bool;
}

/// No cut-outs: every triangle is opaque.
pub struct NoMasks;

impl AlphaTest for NoMasks {
    #[inline(always)]
    fn has_mask(&self, _prim: u32) -> bool {
        false
    }
    #[inline(always)]
    fn opaque(&self, _prim: u32, _u: f32, _v: f32) -> bool {
        true
    }
}

/// One eye's visibility: the triangle seen at each pixel centre ([`NO_PRIM`] for none) and
/// the depth key used to find it (`q = 1/view depth`, and, from the exact pass, its error
/// bound).
#[derive(Clone, Debug)]
pub struct VisibilityBuffer {
    /// The triangle seen at each pixel centre.
    pub prim: PlaneBuf<u32>,
    /// Its depth key `1 / view depth` (larger is nearer).
    pub q: PlaneBuf<f32>,
    /// The error bound of `q` ([`VisibilityBuffer::q_err`]).
    q_err: PlaneBuf<f32>,
    /// Whether `q_err` is this buffer's: the exact pass writes it; the fixed-point pass's keys
    /// are exact for its snapped triangles, so it leaves the plane alone (writing zeros
    /// there cost a plane of stores a frame that nothing reads).
    bounded: bool,
}

impl PartialEq for VisibilityBuffer {
    fn eq(&self, other: &Self) -> bool {
        self.prim == other.prim && self.q == other.q && self.q_err() == other.q_err()
    }
}

impl VisibilityBuffer {
    /// Buffers for one eye of `extent`, showing nothing.
    pub fn new(extent: Extent) -> Self {
        Self {
            prim: PlaneBuf::new(extent, NO_PRIM),
            q: PlaneBuf::new(extent, 0.0),
            q_err: PlaneBuf::new(extent, 0.0),
            bounded: true,
        }
    }

    /// [`VisibilityBuffer::new`] that reports an allocation failure instead of aborting.
    pub fn try_new(extent: Extent) -> Result<Self, FrameError> {
        Ok(Self {
            prim: PlaneBuf::try_new(extent, NO_PRIM)?,
            q: PlaneBuf::try_new(extent, 0.0)?,
            q_err: PlaneBuf::try_new(extent, 0.0)?,
            bounded: true,
        })
    }

    /// The buffers' width and height.
    pub fn extent(&self) -> Extent {
        self.prim.extent()
    }

    /// The error bound of each pixel's `q`, where the pass that filled the buffer has one:
    /// the exact pass ([`Rasterizer`]) bounds its f32 keys; the fixed-point pass
    /// ([`fixed::FixedRasterizer`]) has none to give (`None`), its keys being exact for
    /// the snapped triangle.
    pub fn q_err(&self) -> Option<&PlaneBuf<f32>> {
        self.bounded.then_some(&self.q_err)
    }
}

/// Which fragment loop runs (the SIMD body or its scalar reference).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Body {
    /// The `wide` body (the default).
    #[default]
    Simd,
    /// The scalar reference.
    Scalar,
}

/// What one call did (summed over both eyes).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RasterStats {
    /// Triangles given.
    pub triangles: u64,
    /// Records with a non-empty pixel range in at least one eye.
    pub visible: u64,
    /// Triangles that crossed the near plane and were clipped.
    pub clipped: u64,
    /// Triangles the fixed-point pass's SIMD setup skipped because their whole cluster lies
    /// outside both frusta (0 for the exact pass and the scalar bodies, which set up every
    /// triangle; the skipped ones would have been culled, so the output is the same).
    pub cluster_culled: u64,
    /// (record, band) pairs walked.
    pub band_records: u64,
    /// Covered pixel centres of tiny triangles depth-tested as points instead of records
    /// (the fixed-point pass's SIMD body; see its module notes).
    pub band_points: u64,
    /// Fragments decided on the exact path (uncertain coverage, near ties, masks).
    pub exact: u64,
    /// Of those, the near ties (certainly covered, depth too close for `q` to decide).
    pub exact_ties: u64,
    /// Wall time of the three steps (see the module notes).
    pub setup: Duration,
    /// Wall time of binning.
    pub binning: Duration,
    /// Wall time of the fragment loop.
    pub fragments: Duration,
}

impl core::ops::Add for RasterStats {
    type Output = Self;
    fn add(self, o: Self) -> Self {
        Self {
            triangles: self.triangles + o.triangles,
            visible: self.visible + o.visible,
            clipped: self.clipped + o.clipped,
            cluster_culled: self.cluster_culled + o.cluster_culled,
            band_records: self.band_records + o.band_records,
            band_points: self.band_points + o.band_points,
            exact: self.exact + o.exact,
            exact_ties: self.exact_ties + o.exact_ties,
            setup: self.setup + o.setup,
            binning: self.binning + o.binning,
            fragments: self.fragments + o.fragments,
        }
    }
}

/// The triangles a call rasterises: `main` (ids `0..main.len()`) and `extra` (ids following
/// them), so a caller can add a few per-frame triangles (moving lights) without copying.
#[derive(Clone, Copy, Debug)]
pub struct Triangles<'a> {
    /// Triangles with ids `0..main.len()`.
    pub main: &'a [TriVerts],
    /// Triangles with ids following `main`'s.
    pub extra: &'a [TriVerts],
}

impl Triangles<'_> {
    /// Triangles in both lists.
    pub fn len(&self) -> usize {
        self.main.len() + self.extra.len()
    }

    /// Whether there is no triangle.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The triangle with id `prim`. Panics past the end.
    #[inline(always)]
    pub fn get(&self, prim: u32) -> &TriVerts {
        let i = prim as usize;
        if i < self.main.len() { &self.main[i] } else { &self.extra[i - self.main.len()] }
    }
}

/// One eye's view of a record: edge `k` as a line equation in pixel coordinates relative to
/// the record's first pixel `(cols.0, rows.0)`, `E_k(x', y') = a[k]·x' + b[k]·y' + c[k]` at
/// the pixel centre `x' = x − cols.0 + 0.5`, `y' = y − rows.0 + 0.5`, normalised so that `E_k`
/// is the signed distance in pixels and positive inside; the depth plane
/// `q(x', y') = qa·x' + qb·y' + qc` with an error bound `q_err` over the record; and the
/// pixel columns to visit.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct EyeEdges {
    pub a: [f32; 4],
    pub b: [f32; 4],
    pub c: [f32; 4],
    pub qa: f32,
    pub qb: f32,
    pub qc: f32,
    pub q_err: f32,
    /// Columns `cols.0..=cols.1` (empty when the first exceeds the second).
    pub cols: (i32, i32),
}

/// A triangle (or the quad left of it after near clipping) projected for both eyes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Record {
    pub eyes: [EyeEdges; 2],
    /// Pixel rows `rows.0..=rows.1` (shared: the eyes differ only in x).
    pub rows: (i32, i32),
    /// 3 for a triangle, 4 for a clipped quad (a triangle's 4th edge always passes).
    pub n: u32,
    pub prim: u32,
    /// Half-width of every edge's uncertainty band, in pixels.
    pub band: f32,
    pub masked: bool,
    /// The orientation is not certain (a sliver thinner than its vertices' error): no pixel
    /// is certainly inside, and a pixel is certainly outside only when it is so for both
    /// orientations (one edge below minus the band and another above it).
    pub flat: bool,
}

impl Record {
    pub(crate) const CULLED: Record = Record {
        eyes: [EyeEdges { a: [0.0; 4], b: [0.0; 4], c: [0.0; 4], qa: 0.0, qb: 0.0, qc: 0.0, q_err: 0.0, cols: (1, 0) };
            2],
        rows: (1, 0),
        n: 0,
        prim: NO_PRIM,
        band: 0.0,
        masked: false,
        flat: false,
    };

    /// The columns and rows `eye`'s walk of this record visits in the band `out` (both
    /// inclusive), or `None` when there are none: the one span both fragment bodies walk.
    #[inline(always)]
    pub(crate) fn walk_span(&self, eye: usize, out: &BandOut<'_>) -> Option<((i32, i32), (i32, i32))> {
        let (c0, c1) = self.eyes[eye].cols;
        let (y0, y1) = (self.rows.0.max(out.rows.start as i32), self.rows.1.min(out.rows.end as i32 - 1));
        (y0 <= y1 && c0 <= c1).then_some(((c0, c1), (y0, y1)))
    }

    #[inline(always)]
    pub(crate) fn visible_in(&self, eye: usize) -> bool {
        self.rows.0 <= self.rows.1 && self.eyes[eye].cols.0 <= self.eyes[eye].cols.1
    }
}

/// What the exact path needs to know about one eye.
pub(crate) struct EyeView<'a, M: AlphaTest> {
    pub camera: &'a CameraModel,
    pub tris: Triangles<'a>,
    pub mask: &'a M,
}

impl<M: AlphaTest> EyeView<'_, M> {
    /// The tracer's pixel-centre ray of `(x, y)`, prepared for triangle tests.
    #[inline]
    pub(crate) fn pixel_ray(&self, x: usize, y: usize) -> Option<PreparedRay> {
        let cam = self.camera;
        let d = cam.ray(x as f32 + 0.5, y as f32 + 0.5);
        PreparedRay::for_triangles(&Ray::new(cam.centre.into(), d.into()))
    }

    /// The tracer's hit of the ray `r` on `prim`, if any (and opaque where masked).
    #[inline]
    pub(crate) fn exact_hit(&self, r: &PreparedRay, prim: u32) -> Option<TriHit> {
        let hit = intersect_triangle(r, self.tris.get(prim), f32::INFINITY)?;
        if self.mask.has_mask(prim) {
            let (u, v) = hit.uv();
            if !self.mask.opaque(prim, u, v) {
                return None;
            }
        }
        Some(hit)
    }

    /// The exact path for one fragment of `prim` at `(x, y)` against the stored
    /// `(prim, q, q_err)`: the tracer's closest hit wins (equal `t`: the smaller id).
    /// Returns whether the pixel changed.
    #[inline(never)]
    pub(crate) fn resolve_exact(&self, prim: u32, x: usize, y: usize, stored: (&mut u32, &mut f32, &mut f32)) -> bool {
        let (sp, sq, se) = stored;
        let Some(r) = self.pixel_ray(x, y) else { return false };
        let Some(new) = self.exact_hit(&r, prim) else { return false };
        let keep_old = if *sp == NO_PRIM {
            false
        } else {
            match self.exact_hit(&r, *sp) {
                Some(old) => old.t < new.t || (old.t == new.t && *sp < prim),
                // The tracer misses the stored triangle here. The fast path stores only
                // certain coverage, so this is the tracer's own rounding (a sliver with
                // far vertices): the stored depth is still the geometry's, and a hit
                // certainly behind it must not replace it.
                None => {
                    let q_new = 1.0 / new.t;
                    *sq - q_new > *se + 4.0 * U * q_new
                }
            }
        };
        if keep_old {
            return false;
        }
        *sp = prim;
        *sq = 1.0 / new.t;
        *se = self.hit_q_err(prim, new.t);
        true
    }

    /// The error bound of `q = 1/t` for the tracer's hit on `prim` at `t`. The watertight
    /// test's `t` errs by a few roundings of the vertices' coordinates relative to the ray
    /// origin, not of `t` itself, so near the eye (small `t`, large `q`) its relative error
    /// is far above one rounding: `|Δt| ≤ 32·u·max_k ‖v_k − o‖₁` (generous against pbrt-v4's
    /// bound), hence `|Δq| ≈ q²·|Δt|`, plus the rounding of the division.
    fn hit_q_err(&self, prim: u32, t: f32) -> f32 {
        let o = self.camera.centre;
        let v = self.tris.get(prim);
        let reach = (0..3).map(|k| (0..3).map(|c| (v[3 * k + c] - o[c]).abs()).sum::<f32>()).fold(0.0f32, f32::max);
        let q = 1.0 / t;
        let err = q * q * 32.0 * U * reach + 4.0 * U * q;
        if err.is_finite() { err } else { f32::MAX }
    }
}

/// Rasterises triangles into the visibility buffers of both eyes; keeps its records and bins
/// between calls (see the module notes).
#[derive(Clone, Debug)]
pub struct Rasterizer {
    /// Rows per band ([`BAND_ROWS`] unless set).
    band_rows: usize,
    /// Per chunk of [`CHUNK`] triangles, its slice of `records` starts with the records of
    /// its visible triangles, in triangle order; `kept[chunk]` says how many.
    records: Vec<Record>,
    kept: Vec<u32>,
    /// `counts[(chunk · 2 + eye) · bands + band]`, then (after the prefix sum) the write
    /// cursor of that chunk in that band.
    counts: Vec<u32>,
    /// `bin_start[eye · (bands + 1) + band]`: where each band's list starts in `bins`.
    bin_start: Vec<u32>,
    bins: Vec<u32>,
}

/// The per-camera numbers setup needs, in f32 (camera-relative transform).
#[derive(Clone, Copy, Debug)]
struct Projection {
    centre: [f32; 3],
    /// Rows x, y, w of the view-projection, without translation.
    rx: [f32; 3],
    ry: [f32; 3],
    rw: [f32; 3],
    /// The right eye's clip `(x, y, w)` minus the left eye's, for any point: `R·(c_L − c_R)`.
    right_offset: [f64; 3],
    hw: f32,
    hh: f32,
    /// How far (pixels) the tracer's f32 pixel rays may stray from exact pixel centres.
    ray_slack: f32,
    /// Pixels per radian of a ray's direction, at most, anywhere on screen: an angle `δ`
    /// moves a unit-view-depth ray's image point by at most `δ·|d|²`, and a pixel is at
    /// least `min(|ray_dx|, |ray_dy|)` wide (see [`tracer_edge_slack`]).
    px_per_radian: f64,
    /// The inverse of the 3×3 matrix with rows `rx`, `ry`, `rw` (clip = M·d), for the depth
    /// planes, and the left centre minus the right one.
    m_inv: [[f64; 3]; 3],
    centre_offset: [f64; 3],
    width: i32,
    height: i32,
}

impl Projection {
    /// Refuses cameras that are not a parallel rig: equal rotation and projection (the 3×3
    /// parts of the x, y and w rows bit for bit), centres offset along the camera's x axis
    /// (what `StereoRig` makes; the y and w offsets of its f32 centres are rounding noise).
    fn new(left: &CameraModel, right: &CameraModel) -> Result<Self, FrameError> {
        let (l, r) = (&left.rows, &right.rows);
        let same = |i: usize| l[i][..3] == r[i][..3];
        let not_a_rig = FrameError::InvalidParameter(
            "the two cameras are not a parallel stereo pair (same rotation and projection, offset along x)",
        );
        if !(same(0) && same(1) && same(3)) {
            return Err(not_a_rig);
        }
        let c = left.centre;
        // Clip coordinates are R·(X − centre): the right eye's x is the left eye's plus
        // R_x·(c_L − c_R), the same for every point; its y and w must not move.
        let offset = |row: &[f32; 4]| {
            (0..3).map(|k| f64::from(row[k]) * (f64::from(c[k]) - f64::from(right.centre[k]))).sum::<f64>()
        };
        // In a rig made in f64 and rounded to f32 centres, the y and w offsets are rounding
        // noise (~1e-6 m), but they are applied, not assumed zero: near the eye they matter.
        let (dx, dy, dw) = (offset(&l[0]), offset(&l[1]), offset(&l[3]));
        if !(dy.abs() <= 1e-3 * dx.abs() && dw.abs() <= 1e-3 * dx.abs()) {
            return Err(not_a_rig);
        }
        let right_offset = [dx, dy, dw];
        let slack = |cam: &CameraModel| {
            let n = |v: [f32; 3]| v.iter().map(|x| x.abs()).sum::<f32>();
            let (w, h) = (cam.extent.width() as f32, cam.extent.height() as f32);
            let pixel = n(cam.ray_dx).min(n(cam.ray_dy)).max(f32::MIN_POSITIVE);
            4.0 * U * (n(cam.ray_origin_corner) + w * n(cam.ray_dx) + h * n(cam.ray_dy)) / pixel
        };
        // Rows x, y, w of the view-projection's 3×3 part (columns of the transpose).
        let row = |i: usize| glam::DVec3::new(f64::from(l[i][0]), f64::from(l[i][1]), f64::from(l[i][2]));
        let m = glam::DMat3::from_cols(row(0), row(1), row(3)).transpose();
        let inv = m.inverse();
        if !inv.is_finite() {
            return Err(FrameError::SingularCamera);
        }
        let m_inv = [inv.row(0).to_array(), inv.row(1).to_array(), inv.row(2).to_array()];
        let centre_offset = [0, 1, 2].map(|k| f64::from(c[k]) - f64::from(right.centre[k]));
        let (hw, hh) = left.half_extent();
        let px_per_radian = {
            let v = |a: [f32; 3]| glam::DVec3::from(a.map(f64::from));
            let (corner, dx, dy) = (v(left.ray_origin_corner), v(left.ray_dx), v(left.ray_dy));
            let (w, h) = (f64::from(left.extent.width() as u32), f64::from(left.extent.height() as u32));
            let farthest = [corner, corner + w * dx, corner + h * dy, corner + w * dx + h * dy]
                .iter()
                .map(|d| d.length_squared())
                .fold(0.0, f64::max);
            farthest / dx.length().min(dy.length())
        };
        Ok(Self {
            centre: c,
            rx: [l[0][0], l[0][1], l[0][2]],
            ry: [l[1][0], l[1][1], l[1][2]],
            rw: [l[3][0], l[3][1], l[3][2]],
            right_offset,
            hw,
            hh,
            ray_slack: slack(left).max(slack(right)),
            px_per_radian,
            m_inv,
            centre_offset,
            width: left.extent.width() as i32,
            height: left.extent.height() as i32,
        })
    }
}

impl Default for Rasterizer {
    fn default() -> Self {
        Self::new()
    }
}

impl Rasterizer {
    /// A rasteriser with empty buffers (they grow with the first frame).
    pub fn new() -> Self {
        Self {
            band_rows: BAND_ROWS,
            records: Vec::new(),
            kept: Vec::new(),
            counts: Vec::new(),
            bin_start: Vec::new(),
            bins: Vec::new(),
        }
    }

    /// A rasteriser whose bands are `rows` rows high (at least 1). Which triangle each pixel
    /// sees does not depend on it, bit for bit: every pixel meets the records covering it in
    /// triangle order whatever the bands. Small bands let small frames (tests, fuzzing)
    /// cross band boundaries; larger ones cost less per triangle.
    pub fn with_band_rows(rows: usize) -> Self {
        Self { band_rows: rows.max(1), ..Self::new() }
    }

    /// Fills `out[0]` (left eye, `cameras[0]`) and `out[1]` (right eye) with the triangle seen
    /// at each pixel centre. `near` is the smallest view depth rasterised (the tracer sees
    /// from depth 0; keep it far below the scene's scale). The cameras must be a parallel
    /// stereo pair of one extent, and each buffer of that extent.
    pub fn rasterize<M: AlphaTest>(
        &mut self,
        tris: Triangles<'_>,
        cameras: [&CameraModel; 2],
        mask: &M,
        near: f32,
        out: [&mut VisibilityBuffer; 2],
        body: Body,
    ) -> Result<RasterStats, FrameError> {
        let extent = cameras[0].extent;
        same_extent("right camera", extent, cameras[1].extent)?;
        for buf in &out {
            same_extent("visibility buffer", extent, buf.extent())?;
        }
        if !(near > 0.0 && near.is_finite()) {
            return Err(FrameError::InvalidParameter("near plane must be finite and > 0"));
        }
        if tris.len() >= NO_PRIM as usize {
            return Err(FrameError::InvalidParameter("too many triangles for 32-bit ids"));
        }
        let proj = Projection::new(cameras[0], cameras[1])?;
        let start = Instant::now();
        let mut stats = self.setup(tris, &proj, mask, near);
        let setup_done = Instant::now();
        self.bin(extent);
        let binned = Instant::now();
        stats = stats + self.fragments(tris, cameras, mask, out, body);
        stats.triangles = tris.len() as u64;
        (stats.setup, stats.binning, stats.fragments) = (setup_done - start, binned - setup_done, binned.elapsed());
        Ok(stats)
    }

    fn bands(&self, extent: Extent) -> usize {
        extent.height().div_ceil(self.band_rows)
    }

    /// Step 1: one record per triangle, and per-chunk band counts.
    fn setup<M: AlphaTest>(&mut self, tris: Triangles<'_>, proj: &Projection, mask: &M, near: f32) -> RasterStats {
        let n = tris.len();
        self.records.resize(n, Record::CULLED);
        let band_rows = self.band_rows;
        let bands = (proj.height as usize).div_ceil(band_rows);
        let chunks = n.div_ceil(CHUNK);
        self.counts.clear();
        self.counts.resize(chunks * 2 * bands, 0);
        self.kept.clear();
        self.kept.resize(chunks, 0);
        // Only visible records are kept (compacted to the front of their chunk): culled
        // triangles (half of atrium's) cost no record write, and the fragment walk reads
        // denser memory.
        self.records
            .par_chunks_mut(CHUNK)
            .zip(self.counts.par_chunks_mut(2 * bands))
            .zip(self.kept.par_iter_mut())
            .enumerate()
            .map(|(chunk, ((records, counts), kept))| {
                let mut stats = RasterStats::default();
                for i in 0..records.len() {
                    let prim = (chunk * CHUNK + i) as u32;
                    let (mut rec, clipped) = setup_triangle(tris.get(prim), prim, proj, near);
                    stats.clipped += u64::from(clipped);
                    if !(rec.visible_in(0) || rec.visible_in(1)) {
                        continue;
                    }
                    rec.masked = mask.has_mask(prim);
                    stats.visible += 1;
                    for eye in 0..2 {
                        if rec.visible_in(eye) {
                            for band in band_range(rec.rows, band_rows) {
                                counts[eye * bands + band] += 1;
                            }
                        }
                    }
                    records[*kept as usize] = rec;
                    *kept += 1;
                }
                stats
            })
            .reduce(RasterStats::default, |a, b| a + b)
    }

    /// Step 2: prefix sums over (eye, band, chunk) and the index lists.
    fn bin(&mut self, extent: Extent) {
        let (band_rows, bands) = (self.band_rows, self.bands(extent));
        let total = bin_cursors(&mut self.counts, bands, &mut self.bin_start);
        resize_with_headroom(&mut self.bins, total as usize, 0);
        // Each chunk writes its records at its own cursors: disjoint ranges of `bins`.
        let bins = SharedSlice::new(&mut self.bins);
        self.records.par_chunks(CHUNK).zip(self.counts.par_chunks_mut(2 * bands)).zip(&self.kept).enumerate().for_each(
            |(chunk, ((records, cursors), &kept))| {
                for (i, rec) in records[..kept as usize].iter().enumerate() {
                    for eye in 0..2 {
                        if rec.visible_in(eye) {
                            for band in band_range(rec.rows, band_rows) {
                                let at = &mut cursors[eye * bands + band];
                                // SAFETY: the prefix sum gave this (chunk, eye, band) its own
                                // range of `bins`; the cursor stays inside it.
                                unsafe { bins.write(*at as usize, (chunk * CHUNK + i) as u32) };
                                *at += 1;
                            }
                        }
                    }
                }
            },
        );
    }

    /// Step 3: every band of both eyes.
    fn fragments<M: AlphaTest>(
        &self,
        tris: Triangles<'_>,
        cameras: [&CameraModel; 2],
        mask: &M,
        out: [&mut VisibilityBuffer; 2],
        body: Body,
    ) -> RasterStats {
        let extent = cameras[0].extent;
        let (w, band_rows, bands) = (extent.width(), self.band_rows, self.bands(extent));
        let [left, right] = out;
        let views = [0, 1].map(|eye| EyeView { camera: cameras[eye], tris, mask });
        let run = |eye: usize, band: usize, ((prim, q), q_err): ((&mut [u32], &mut [f32]), &mut [f32])| {
            prim.fill(NO_PRIM);
            q.fill(0.0);
            q_err.fill(0.0);
            let list = &self.bins[self.bin_start[eye * (bands + 1) + band] as usize
                ..self.bin_start[eye * (bands + 1) + band + 1] as usize];
            let rows = band * band_rows..(band * band_rows + band_rows).min(extent.height());
            let mut band_out = BandOut { prim, q, q_err, width: w, rows };
            let mut stats = RasterStats { band_records: list.len() as u64, ..RasterStats::default() };
            for &r in list {
                let rec = &self.records[r as usize];
                let (exact, ties) = match body {
                    Body::Simd => simd::record(rec, eye, &views[eye], &mut band_out),
                    Body::Scalar => scalar::record(rec, eye, &views[eye], &mut band_out),
                };
                stats.exact += exact;
                stats.exact_ties += ties;
            }
            stats
        };
        let l = band_planes(left, w, band_rows).enumerate().map(|(band, bufs)| run(0, band, bufs));
        let r = band_planes(right, w, band_rows).enumerate().map(|(band, bufs)| run(1, band, bufs));
        l.chain(r).reduce(RasterStats::default, |a, b| a + b)
    }
}

/// The three planes of `v` cut into bands of `band_rows` rows of `width` pixels (the exact
/// pass's: it writes the error bounds).
fn band_planes(
    v: &mut VisibilityBuffer,
    width: usize,
    band_rows: usize,
) -> impl IndexedParallelIterator<Item = ((&mut [u32], &mut [f32]), &mut [f32])> {
    v.bounded = true;
    let VisibilityBuffer { prim, q, q_err, .. } = v;
    let n = band_rows * width;
    prim.as_mut_slice()
        .par_chunks_mut(n)
        .zip(q.as_mut_slice().par_chunks_mut(n))
        .zip(q_err.as_mut_slice().par_chunks_mut(n))
}

/// The ids and keys of `v` cut into bands of `band_rows` rows of `width` pixels (the
/// fixed-point pass's: it has no error bounds, so `v` says it has none).
fn band_keys(
    v: &mut VisibilityBuffer,
    width: usize,
    band_rows: usize,
) -> impl IndexedParallelIterator<Item = (&mut [u32], &mut [f32])> {
    v.bounded = false;
    let n = band_rows * width;
    v.prim.as_mut_slice().par_chunks_mut(n).zip(v.q.as_mut_slice().par_chunks_mut(n))
}

/// One band's rows of the three output planes (row `y` starts at `(y − rows.start)·width`).
pub(crate) struct BandOut<'a> {
    pub prim: &'a mut [u32],
    pub q: &'a mut [f32],
    pub q_err: &'a mut [f32],
    pub width: usize,
    pub rows: Range<usize>,
}

/// The prefix sum that lays out the bins: `counts[(chunk · 2 + eye) · bands + band]` (what
/// each chunk put in each eye's band) becomes where that chunk's part of the bin starts,
/// bins ordered by eye, then band, then chunk (so each bin lists its work in triangle order);
/// `start[eye · (bands + 1) + band]` gets where each bin starts, and `start[eye · (bands +
/// 1) + bands]` where the eye's bins end. Returns the total.
fn bin_cursors(counts: &mut [u32], bands: usize, start: &mut Vec<u32>) -> u32 {
    let chunks = counts.len() / (2 * bands);
    start.clear();
    start.resize(2 * (bands + 1), 0);
    let mut total = 0u32;
    for eye in 0..2 {
        for band in 0..bands {
            start[eye * (bands + 1) + band] = total;
            for chunk in 0..chunks {
                let c = &mut counts[(chunk * 2 + eye) * bands + band];
                let count = *c;
                *c = total;
                total += count;
            }
        }
        start[eye * (bands + 1) + bands] = total;
    }
    total
}

/// The bands of `band_rows` rows that the pixel rows `rows.0..=rows.1` touch.
fn band_range(rows: (i32, i32), band_rows: usize) -> Range<usize> {
    rows.0 as usize / band_rows..rows.1 as usize / band_rows + 1
}

/// Projects one triangle for both eyes (see the module notes). Returns the record (culled
/// when invisible) and whether the near plane clipped it.
///
/// Everything runs in f64 on camera-relative coordinates (the difference of two f32 values
/// is exact in f64), so the projected vertices are exact to far below a pixel's 1e-9 even
/// where near clipping puts them far off screen; the edges are stored as normalised line
/// equations relative to the record's first pixel, so neither huge off-screen coordinates
/// nor the screen's size enter the per-pixel f32 arithmetic.
fn setup_triangle(t: &TriVerts, prim: u32, p: &Projection, near: f32) -> (Record, bool) {
    let d: [[f64; 3]; 3] =
        core::array::from_fn(|k| core::array::from_fn(|c| f64::from(t[3 * k + c]) - f64::from(p.centre[c])));
    let dot = |r: &[f32; 3], v: &[f64; 3]| f64::from(r[0]) * v[0] + f64::from(r[1]) * v[1] + f64::from(r[2]) * v[2];
    let clip: [[f64; 3]; 3] = d.map(|v| [dot(&p.rx, &v), dot(&p.ry, &v), dot(&p.rw, &v)]);
    // The right eye's w is the left eye's plus the rig's `dw`, rounding noise of the f32
    // centres (~1e-7 of their size) that may exceed a tiny `near`. Clipping the left eye at
    // `near` alone would leave the right eye's clipped vertices behind it (w < 0, projected to
    // the opposite side of the screen), so clip where both eyes are in front of `near`.
    let near = f64::from(near).max(f64::from(near) - p.right_offset[2]);
    let inside = clip.map(|c| c[2] > near);
    if !inside.iter().any(|&i| i) {
        return (Record::CULLED, false);
    }
    let clipped = !inside.iter().all(|&i| i);
    // Sutherland–Hodgman against w = near: a crossing triangle leaves a triangle or a quad.
    let mut poly = [[0.0f64; 3]; 4];
    let mut n = 0;
    for k in 0..3 {
        let (a, b) = (clip[k], clip[(k + 1) % 3]);
        if inside[k] {
            poly[n] = a;
            n += 1;
        }
        if inside[k] != inside[(k + 1) % 3] {
            let s = (near - a[2]) / (b[2] - a[2]);
            poly[n] = [a[0] + (b[0] - a[0]) * s, a[1] + (b[1] - a[1]) * s, near];
            n += 1;
        }
    }
    let mut verts = [ScreenVertex::default(); 4];
    let (hw, hh) = (f64::from(p.hw), f64::from(p.hh));
    for (v, c) in verts.iter_mut().zip(&poly[..n]) {
        for eye in 0..2 {
            let o = if eye == 0 { [0.0; 3] } else { p.right_offset };
            let inv_w = 1.0 / (c[2] + o[2]);
            v.x[eye] = (c[0] + o[0]) * inv_w * hw + hw;
            v.y[eye] = -(c[1] + o[1]) * inv_w * hh + hh;
        }
    }
    (finish_record(&verts[..n], &d, prim, p), clipped)
}

/// A projected vertex: screen x and y per eye.
#[derive(Clone, Copy, Debug, Default)]
struct ScreenVertex {
    x: [f64; 2],
    y: [f64; 2],
}

/// The record of a projected polygon (3 or 4 vertices; `d` the triangle's camera-relative
/// vertices, for its depth plane): pixel ranges first (a polygon that covers no pixel
/// centre in either eye costs only those), then line equations, depth planes and the band
/// (f64, stored as f32 relative to the record's first pixel; see [`EyeEdges`]).
fn finish_record(v: &[ScreenVertex], d: &[[f64; 3]; 3], prim: u32, p: &Projection) -> Record {
    let n = v.len();
    let mut rec = Record { n: n as u32, prim, ..Record::CULLED };
    // Rounding of the f64 projection, in pixels (relative 1e-13 of the largest coordinate).
    let largest = v.iter().flat_map(|v| v.x.iter().chain(&v.y)).fold(0.0f64, |m, c| m.max(c.abs()));
    let vertex_err = 1e-9 + 1e-13 * largest;
    // The tracer's pixel rays and its triangle test both err; twice the larger of the two
    // (the margin below) bounds their sum.
    let slack = f64::from(p.ray_slack).max(tracer_edge_slack(d, p));
    // Pixel ranges, widened by the largest band a record of this screen can have (the
    // record's own band, below, needs its ranges first).
    let screen_evaluation = 10.0 * f64::from(U) * f64::from(p.width + p.height + 9);
    let margin = 2.0 * (2.0 * vertex_err + slack + screen_evaluation) + 1e-5;
    let range = |lo: f64, hi: f64, size: i32| -> (i32, i32) {
        let a = (lo - 0.5 - margin).ceil().max(0.0);
        let b = (hi - 0.5 + margin).floor().min(f64::from(size - 1));
        if !(a <= b) { (1, 0) } else { (a as i32, b as i32) }
    };
    let extent = |eye: usize, y: bool| {
        v.iter()
            .map(|v| if y { v.y[eye] } else { v.x[eye] })
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), c| (a.min(c), b.max(c)))
    };
    let mut any = false;
    let mut rows = [(1, 0); 2];
    for eye in 0..2 {
        let (y0, y1) = extent(eye, true);
        rows[eye] = range(y0, y1, p.height);
        if rows[eye].0 <= rows[eye].1 {
            let (x0, x1) = extent(eye, false);
            rec.eyes[eye].cols = range(x0, x1, p.width);
            any |= rec.eyes[eye].cols.0 <= rec.eyes[eye].cols.1;
        }
    }
    if !any {
        return Record::CULLED;
    }
    rec.rows = (rows[0].0.min(rows[1].0), rows[0].1.max(rows[1].1));
    let oy = f64::from(rec.rows.0);
    let span_y = f64::from(rec.rows.1 - rec.rows.0) + 1.0;
    // The band: both vertices of an edge, the tracer's ray slack, and the f32 evaluation
    // of a line equation relative to the record's first pixel, `a·x' + (b·y' + c')` with
    // `|a|, |b| ≤ 1`: five roundings of terms no larger than the block's width (+7 columns
    // of the first SIMD block) and height, and `|c'|` no larger than those where the
    // classification is close; twice that, for margin.
    let mut widest = 0.0f64;
    for eye in 0..2 {
        let e = &mut rec.eyes[eye];
        if e.cols.0 > e.cols.1 {
            e.cols = (1, 0);
            continue;
        }
        widest = widest.max(f64::from(e.cols.1 - e.cols.0) + 8.0);
        // Orientation from the f64 area; a sliver whose area the vertex error could flip is flat.
        let (mut area2, mut perimeter) = (0.0f64, 0.0f64);
        for k in 0..n {
            let j = (k + 1) % n;
            area2 += v[k].x[eye] * v[j].y[eye] - v[j].x[eye] * v[k].y[eye];
            perimeter += (v[j].x[eye] - v[k].x[eye]).abs() + (v[j].y[eye] - v[k].y[eye]).abs();
        }
        if !(area2.is_finite() && perimeter.is_finite()) {
            return Record::CULLED;
        }
        if area2.abs() <= 4.0 * vertex_err * perimeter || area2 == 0.0 {
            rec.flat = true;
        }
        let sign = if area2 < 0.0 { -1.0 } else { 1.0 };
        let ox = f64::from(e.cols.0);
        for k in 0..4 {
            if k >= n {
                (e.a[k], e.b[k], e.c[k]) = (0.0, 0.0, 1e30);
                continue;
            }
            let j = (k + 1) % n;
            let (a, b) = (sign * (v[k].y[eye] - v[j].y[eye]), sign * (v[j].x[eye] - v[k].x[eye]));
            let len = (a * a + b * b).sqrt();
            let (a, b) = if len > 0.0 { (a / len, b / len) } else { (0.0, 0.0) };
            e.a[k] = a as f32;
            e.b[k] = b as f32;
            e.c[k] = (-(a * (v[k].x[eye] - ox) + b * (v[k].y[eye] - oy))) as f32;
        }
        // The depth plane, from the triangle's plane (see `depth_plane`), not from the
        // projected vertices: a clipped vertex far off screen makes a fit through them
        // ill-conditioned even in f64. Moved to the record's first pixel.
        let (qa, qb, qc, rel) = depth_plane(d, p, eye);
        let qc = qc + qa * ox + qb * oy;
        (e.qa, e.qb, e.qc) = (qa as f32, qb as f32, qc as f32);
        // Its error over the record, with `terms = |qa|·w + |qb|·h + |qc|` bounding every
        // partial sum: rounding the coefficients to f32 moves q by at most u·terms, and the
        // evaluation `qa·x' + (qb·y' + qc)` rounds four times, each by at most u·terms; the
        // f64 setup adds `rel·terms`. Twice that, for margin.
        let w = f64::from(e.cols.1 - e.cols.0) + 8.0;
        let terms = qa.abs() * w + qb.abs() * span_y + qc.abs();
        let err = 2.0 * (5.0 * f64::from(U) * terms + rel * terms);
        e.q_err = if err.is_finite() { err.min(f64::from(f32::MAX)) as f32 } else { f32::MAX };
    }
    let evaluation = 10.0 * f64::from(U) * (widest + span_y + 1.0);
    rec.band = (2.0 * (2.0 * vertex_err + slack + evaluation) + 1e-5) as f32;
    rec
}

/// How far (pixels) the tracer's own f32 triangle test may move an edge of the triangle `d`
/// (vertices relative to the left eye) away from the exact one, in either eye.
///
/// The watertight test decides the side of edge `(a, b)` by the sign of `bx·ay − by·ax`, with
/// the vertices relative to the ray origin and sheared along the ray. Rounding the
/// subtraction and the shear errs by about `2·u·|p|₁` per coordinate. For a ray through a
/// point of the edge that splits it into `s·L` and `(1 − s)·L` (`L` its length), the sheared
/// coordinates of `a` and `b` are at most `√6·s·L` and `√6·(1 − s)·L` in 1-norm (`√3` for the
/// shear), so the function errs by about `5·u·L·max(|a|₁, |b|₁)`. Its value is
/// `|a × b|·sin θ` or more, `θ` the ray's angle to the plane through the eye and the edge,
/// so the tracer's edge lies within `5·u·L·max(|a|₁, |b|₁)/|a × b|` radians of the exact one.
/// For an edge seen broadside that is ~8·u, of the order of the pixel rays' slack; it grows for long
/// edges seen end-on whose far vertex lies hundreds of units away (a near-clipped sliver with
/// vertices 10³ units off, where the fast path would otherwise call a pixel certainly outside
/// that the tracer's test takes as inside). Capped at the screen's size (every pixel is then
/// uncertain: an edge whose line passes through an eye).
fn tracer_edge_slack(d: &[[f64; 3]; 3], p: &Projection) -> f64 {
    use wide::f64x4;
    let px_per_ratio = TRACER_EDGE_ERROR * f64::from(U) * p.px_per_radian;
    // Below this squared ratio the rays' own slack is the larger (the caller takes the
    // larger of the two). At 1280×720 a fifth of the triangles stay below it: broadside
    // edges are near it, as the two errors are of the same order there.
    let below = f64x4::splat((f64::from(p.ray_slack) / px_per_ratio).powi(2));
    // Edge k runs from vertex k to vertex k + 1; one lane per edge (the fourth repeats the
    // first). Written out: array `map`s here are not inlined, and this runs per triangle.
    let lanes = |c: usize, first: usize| {
        f64x4::new([d[first % 3][c], d[(first + 1) % 3][c], d[(first + 2) % 3][c], d[first % 3][c]])
    };
    let a = [lanes(0, 0), lanes(1, 0), lanes(2, 0)];
    let b = [lanes(0, 1), lanes(1, 1), lanes(2, 1)];
    let s = [f64x4::splat(p.centre_offset[0]), f64x4::splat(p.centre_offset[1]), f64x4::splat(p.centre_offset[2])];
    let cross = |u: &[f64x4; 3], v: &[f64x4; 3]| {
        [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]
    };
    let dot = |u: &[f64x4; 3]| u[0] * u[0] + u[1] * u[1] + u[2] * u[2];
    let norm1 = |v: &[f64x4; 3]| v[0].abs() + v[1].abs() + v[2].abs();
    let shifted = |v: &[f64x4; 3]| [v[0] + s[0], v[1] + s[1], v[2] + s[2]];
    let edge = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let length2 = dot(&edge);
    // The right eye sees `a + s` and `b + s`, whose cross product is `a × b + s × (b − a)`.
    let (left_cross, shift) = (cross(&a, &b), cross(&s, &edge));
    let right_cross = [left_cross[0] + shift[0], left_cross[1] + shift[1], left_cross[2] + shift[2]];
    let ratio2 = |reach: f64x4, cross: &[f64x4; 3]| (length2 * reach * reach, dot(cross));
    let (n_left, c_left) = ratio2(norm1(&a).max(norm1(&b)), &left_cross);
    let (n_right, c_right) = ratio2(norm1(&shifted(&a)).max(norm1(&shifted(&b))), &right_cross);
    // `!(n ≤ …)` also takes NaN; 0 ≤ 0 (a zero-length edge) stays out.
    let within = n_left.simd_le(below * c_left) & n_right.simd_le(below * c_right);
    if within.to_bitmask() == 0b1111 {
        return 0.0;
    }
    // The squared ratios in lanes: 0 for a zero-length edge (n = 0), NaN (non-finite
    // vertices) counted as unbounded.
    let ratio = |n: f64x4, c: f64x4| n.simd_le(f64x4::ZERO).select(f64x4::ZERO, n / c);
    let (left, right) = (ratio(n_left, c_left).to_array(), ratio(n_right, c_right).to_array());
    let worst = left.iter().chain(&right).fold(0.0f64, |m, &r| if r.is_nan() { f64::INFINITY } else { m.max(r) });
    (px_per_ratio * worst.sqrt()).min(f64::from(p.width + p.height))
}

/// The tracer's edge error in radians per unit of the ratio `L·max(|a|₁, |b|₁)/|a × b|`,
/// in units of `u` ([`tracer_edge_slack`]).
const TRACER_EDGE_ERROR: f64 = 5.0;

/// The depth plane `q = qa·x + qb·y + qc` (`q = 1/w`) of a triangle's plane in `eye`'s screen
/// coordinates, and the relative error of its f64 evaluation.
///
/// With `d` a point relative to the left eye's centre and clip `(x, y, w) = M·d`, the plane
/// `N·d = D` gives `(N·M⁻¹)·(x, y, w) = D`, so `q = (g₀·x/w + g₁·y/w + g₂)/D` with `g = N·M⁻¹`:
/// affine in normalised device coordinates, hence in pixels. The right eye's points are
/// `d + (c_L − c_R)` in its own frame, which moves only `D`.
fn depth_plane(d: &[[f64; 3]; 3], p: &Projection, eye: usize) -> (f64, f64, f64, f64) {
    let (e1, e2) = ([0, 1, 2].map(|c| d[1][c] - d[0][c]), [0, 1, 2].map(|c| d[2][c] - d[0][c]));
    let n = [e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]];
    let mut d0 = d[0];
    if eye == 1 {
        for c in 0..3 {
            d0[c] += p.centre_offset[c];
        }
    }
    let dot = n[0] * d0[0] + n[1] * d0[1] + n[2] * d0[2];
    let scale = n.iter().zip(&d0).map(|(a, b)| (a * b).abs()).sum::<f64>();
    let g: [f64; 3] = core::array::from_fn(|j| (0..3).map(|i| n[i] * p.m_inv[i][j]).sum());
    let (hw, hh) = (f64::from(p.hw), f64::from(p.hh));
    // x/w = (sx − hw)/hw, y/w = (hh − sy)/hh.
    let qa = g[0] / (hw * dot);
    let qb = -g[1] / (hh * dot);
    let qc = (g[2] - g[0] + g[1]) / dot;
    // f64 rounding, amplified where the plane passes near the eye (D small against its terms).
    let rel = 64.0 * f64::EPSILON * scale / dot.abs();
    (qa, qb, qc, rel)
}

/// Resizes `v` to `len`, and when that needs a larger allocation takes a quarter more than
/// asked: the binning buffers follow the camera, so a frame that needs a few more entries
/// than the last would otherwise allocate again (frames after the first allocate nothing
/// unless the load grows by more than that).
pub(crate) fn resize_with_headroom<T: Clone>(v: &mut Vec<T>, len: usize, value: T) {
    if len > v.capacity() {
        v.reserve_exact(len + len / 4 - v.len());
    }
    v.resize(len, value);
}

/// A slice written at disjoint indices from several threads (the binning pass).
struct SharedSlice<T> {
    ptr: *mut T,
    len: usize,
}

// SAFETY: writes go to disjoint indices (see `bin`), and T is Send.
unsafe impl<T: Send> Sync for SharedSlice<T> {}

impl<T> SharedSlice<T> {
    fn new(s: &mut [T]) -> Self {
        Self { ptr: s.as_mut_ptr(), len: s.len() }
    }

    /// # Safety
    /// No other thread may write index `i` concurrently.
    unsafe fn write(&self, i: usize, v: T) {
        assert!(i < self.len, "bin index {i} outside {}", self.len);
        // SAFETY: in bounds (checked); exclusivity is the caller's contract.
        unsafe { self.ptr.add(i).write(v) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A projection with only what [`tracer_edge_slack`] reads set.
    fn projection(centre_offset: [f64; 3], ray_slack: f32) -> Projection {
        Projection {
            centre: [0.0; 3],
            rx: [1.0, 0.0, 0.0],
            ry: [0.0, 1.0, 0.0],
            rw: [0.0, 0.0, -1.0],
            right_offset: [0.0; 3],
            hw: 640.0,
            hh: 360.0,
            ray_slack,
            px_per_radian: 1500.0,
            m_inv: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -1.0]],
            centre_offset,
            width: 1280,
            height: 720,
        }
    }

    /// [`tracer_edge_slack`] edge by edge, eye by eye, as its documentation states it.
    fn reference(d: &[[f64; 3]; 3], p: &Projection) -> f64 {
        let mut worst = 0.0f64;
        for offset in [glam::DVec3::ZERO, glam::DVec3::from_array(p.centre_offset)] {
            for k in 0..3 {
                let (a, b) = (glam::DVec3::from_array(d[k]) + offset, glam::DVec3::from_array(d[(k + 1) % 3]) + offset);
                let reach = a.abs().element_sum().max(b.abs().element_sum());
                let length = (b - a).length();
                if length > 0.0 {
                    worst = worst.max(length * reach / a.cross(b).length());
                }
            }
        }
        let px = TRACER_EDGE_ERROR * f64::from(U) * worst * p.px_per_radian;
        let cap = f64::from(p.width + p.height);
        if px.is_nan() { cap } else { px.min(cap) }
    }

    #[test]
    fn tracer_edge_slack_is_its_scalar_statement() {
        let p = projection([-0.064, 0.0, 0.0], 0.0);
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = || {
            state = state.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
            (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        for case in 0..2000 {
            let scale = [0.01, 1.0, 100.0, 1000.0][case % 4];
            let d: [[f64; 3]; 3] = core::array::from_fn(|_| core::array::from_fn(|_| next() * scale));
            let (got, want) = (tracer_edge_slack(&d, &p), reference(&d, &p));
            assert!((got - want).abs() <= 1e-9 * want, "case {case}: {got} against {want} for {d:?}");
        }
        // An edge whose line passes through the eye, a zero-length edge, a NaN vertex.
        let cap = 2000.0;
        assert_eq!(tracer_edge_slack(&[[0.0, 0.0, -1.0], [0.0, 0.0, -2.0], [1.0, 0.0, -2.0]], &p), cap);
        let degenerate = [[1.0, 0.0, -2.0], [1.0, 0.0, -2.0], [0.0, 1.0, -2.0]];
        assert_eq!(tracer_edge_slack(&degenerate, &p), reference(&degenerate, &p));
        assert_eq!(tracer_edge_slack(&[[f64::NAN, 0.0, -1.0], [0.0, 0.0, -2.0], [1.0, 0.0, -2.0]], &p), cap);
    }

    #[test]
    fn the_tracer_slack_is_small_broadside_and_large_end_on_with_far_vertices() {
        let p = projection([-0.064, 0.0, 0.0], 0.0);
        // A unit triangle 5 units ahead, facing the eye: a few u per radian.
        let broadside = tracer_edge_slack(&[[-0.5, -0.5, -5.0], [0.5, -0.5, -5.0], [0.0, 0.5, -5.0]], &p);
        assert!(broadside < 1e-3, "{broadside}");
        // An edge from 1000 units ahead to 1000 behind, passing 0.5 units beside the eye.
        let end_on = tracer_edge_slack(&[[0.5, 0.0, -1000.0], [0.5, 0.0, 1000.0], [4.0, 1.0, -3.0]], &p);
        assert!(end_on > 100.0 * broadside && end_on > 1e-2, "{end_on} against {broadside}");
    }
}
