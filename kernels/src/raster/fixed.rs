//! A stereo visibility buffer rasterised as GPUs rasterise: vertices snapped to fixed point,
//! integer edge functions with the top-left fill rule at pixel centres, a per-pixel depth
//! test on `q = 1/w` interpolated linearly in screen space. It answers "which triangle does
//! the surface at this pixel centre belong to" to within the snap of the vertices (1/256 px),
//! not bit for bit as the tracer does (that is [`super::Rasterizer`]'s job): a G-buffer
//! describes the surface at the pixel centre, every path-traced sample is jittered inside
//! its pixel anyway, and engines hand the pipeline G-buffers from GPU rasterisers, which
//! agree with no tracer bit for bit either.
//!
//! # Pipeline of one call ([`FixedRasterizer::rasterize`])
//! 1. **Setup** (parallel over fixed chunks of triangles, in triangle order): vertices move
//!    into the left camera's frame (camera-relative, f64), are clipped against the near plane
//!    `w > near` and, only if a vertex projects beyond the guard band (±2¹⁹ px around the
//!    frame) in either eye, against each eye's guard-band planes separately (each eye then
//!    gets records of its own); the polygon left is fanned into triangles. Each vertex is projected for both eyes (the parallel rig's eyes differ by a
//!    constant clip-space offset, so the right eye costs one more division per vertex) and
//!    snapped to [`SUBPIXEL_BITS`] fractional bits. A triangle whose snapped area is zero, or
//!    whose bounding box holds no pixel centre, in both eyes, keeps no record; nor does an
//!    eye whose box holds at most 2×2 pixel centres, none of them covered (tested with the
//!    walks' own integers: most of a dense mesh's far triangles). With [`Body::Simd`], an
//!    opaque triangle's eye whose box holds at most 2×2 centres keeps no record either: its
//!    covered centres become points (pixel, id and the depth key its walk would form), found
//!    four triangles at a time where both eyes are that small.
//!    [`Body::Simd`]
//!    takes four triangles at a time in `f64x4` lanes through the culls, the projection and
//!    the snap (the same operations, so the same vertices); a triangle that needs clipping
//!    goes through the scalar setup, which is [`Body::Scalar`]'s for every triangle. Before
//!    that, [`Body::Simd`] skips each run of 64 triangles whose bounding box lies
//!    beyond one side plane of each eye's frustum (`cluster_outside`): every triangle in it
//!    would be culled, so the records are the same.
//! 2. **Binning** to bands of rows per eye, in triangle order (as [`super::Rasterizer`]);
//!    points are copied into their band's list.
//! 3. **Fragments** (parallel over bands): each record's bounding box is walked eight pixel
//!    columns at a time ([`Body::Simd`]: eight `i32` lanes per edge where the steps allow,
//!    one block per row and no span for a record at most eight columns wide, two `i64x4`
//!    otherwise; [`Body::Scalar`]: the reference, a pixel at a time). Edge functions are exact integers, so coverage is
//!    decided without rounding: a pixel centre is covered when every edge function is
//!    positive, or zero on a top or left edge (shared edges cover each pixel exactly once).
//!    The depth key `q = qc + qb·y' + qa·x'` (f32, relative to the record's first pixel,
//!    the same two products and sums in both bodies) is tested against the stored one:
//!    larger `q` is nearer, equal `q` goes to the smaller triangle id, so the result does not
//!    depend on the order records arrive in, the band height or the thread count.
//!    Cut-out (masked) triangles are tested per covered fragment with the tracer's own pixel
//!    ray and triangle test (the barycentrics the mask needs). A band's points are
//!    depth-tested after its records, one at a time: on the 833k-triangle bunny grid they
//!    are 98 % of the band work, and the walks of their records were two thirds of the pass.
//!
//! # Limits
//! Screen coordinates stay within ±2²⁰ px after the guard-band clip, so every edge function
//! fits an `i64` with room to spare (|E| < 2⁶⁰). (A coordinate past ±2²¹ px after the clip,
//! which rounding alone cannot produce, would drop its triangle rather than overflow.) A vertex
//! that is NaN or infinite, or three collinear vertices, drop the triangle (the tracer never
//! hits one; snapped, a segment's image could cover a pixel centre).

use std::time::Instant;

use rayon::prelude::*;
use wide::{f64x4, i32x8, i64x4, u32x8};

use super::{
    AlphaTest, Body, EyeView, NO_PRIM, Projection, RasterStats, Triangles, VisibilityBuffer, band_range, bin_cursors,
};
use crate::camera::CameraModel;
use crate::frame::{Extent, FrameError, same_extent};
use crate::simd::{F32s, LANES, lane_offsets, prefetch};

/// Fractional bits of the snapped vertex coordinates: vertices land on a 1/256-pixel grid,
/// as on most GPUs.
pub const SUBPIXEL_BITS: u32 = 8;
/// One pixel in fixed point.
const ONE: i64 = 1 << SUBPIXEL_BITS;
/// Half the guard band, in pixels: polygons are clipped to screen coordinates within about
/// this far from the frame's centre.
const GUARD_HALF_PX: f64 = (1u64 << 19) as f64;
/// Coordinates past this (pixels) after the guard-band clip drop the triangle.
const HARD_LIMIT_PX: f64 = (1u64 << 21) as f64;
/// Triangles per setup chunk (fixed, so bin order does not depend on the thread count).
const CHUNK: usize = 4096;
/// Consecutive triangles whose bounding box the SIMD setup tests against both frusta before
/// setting any of them up ([`cluster_outside`]). Meshes list a model's triangles together, so
/// off-screen geometry comes in runs: on the real scenes 15–45 % of all triangles lie in
/// clusters of 64 that are wholly off screen.
const CLUSTER: usize = 64;
const _: () = assert!(CHUNK.is_multiple_of(CLUSTER) && CLUSTER.is_multiple_of(4));
/// The fewest records a chunk has room for (13 bytes per triangle), and the least headroom
/// it gets when it grows: enough that a moving camera does not make a chunk of few records
/// allocate.
const MIN_RECORDS: usize = CHUNK / 16;
/// A clipped triangle has at most 3 + 9 vertices (the near plane and each eye's four guard
/// planes add one each): at most ten fan triangles.
const MAX_POLYGON: usize = 12;

/// One eye's view of a record: the three edge functions with the fill rule folded in (the
/// pixel centre is covered when all three are ≥ 0) at the record's first pixel centre
/// `(cols.0, rows.0)`, their steps per pixel to the right and per row down, the depth-key
/// plane relative to the same pixel (`x' = x − cols.0`, `y' = y − rows.0`), and the columns
/// to visit.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct FixedEyeEdges {
    pub e0: [i64; 3],
    pub dx: [i64; 3],
    pub dy: [i64; 3],
    pub qa: f32,
    pub qb: f32,
    pub qc: f32,
    /// Columns `cols.0..=cols.1` (empty when the first exceeds the second).
    pub cols: (i32, i32),
}

impl FixedEyeEdges {
    /// `1 / dx[k]` (0 where `dx[k]` is 0): where each edge crosses a row, for the SIMD body's
    /// row spans. Worked out by the walks that use it, not kept in the record: most records
    /// are small enough to need no span, and a smaller record is less to write and read.
    #[inline(always)]
    fn inv_dx(&self) -> [f64; 3] {
        self.dx.map(|d| if d == 0 { 0.0 } else { 1.0 / d as f64 })
    }
}

/// One snapped triangle (a fan piece of a clipped one) for both eyes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct FixedRecord {
    pub eyes: [FixedEyeEdges; 2],
    /// Rows `rows.0..=rows.1` (the union of both eyes').
    pub rows: (i32, i32),
    pub prim: u32,
    pub masked: bool,
}

impl FixedRecord {
    fn visible_in(&self, eye: usize) -> bool {
        self.rows.0 <= self.rows.1 && self.eyes[eye].cols.0 <= self.eyes[eye].cols.1
    }
}

/// A vertex after clipping and projection: for each eye the snapped screen position (fixed
/// point) and the depth key `q = 1/w`.
#[derive(Clone, Copy, Debug, Default)]
struct Snapped {
    x: [i64; 2],
    y: [i64; 2],
    q: [f64; 2],
}

/// One covered pixel centre of a tiny opaque triangle, as the setup finds it: the fragment
/// its record's walk would have depth-tested, with the walk's own depth key.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct FixedPoint {
    /// The pixel's column, with the eye in the top bit.
    eye_x: u32,
    y: u32,
    prim: u32,
    q: f32,
}

/// A [`FixedPoint`] binned to its eye's band: `at` indexes the band's planes.
#[derive(Clone, Copy, Debug, Default)]
struct BandPoint {
    at: u32,
    prim: u32,
    q: f32,
}

/// The fixed-point stereo rasteriser; keeps its records and bins between calls (a second
/// frame of the same scene and size allocates nothing).
#[derive(Clone, Debug)]
pub struct FixedRasterizer {
    band_rows: usize,
    /// The records of each chunk of [`CHUNK`] triangles, in triangle order.
    records: Vec<Vec<FixedRecord>>,
    /// `counts[(chunk · 2 + eye) · bands + band]`, then the write cursor there.
    counts: Vec<u32>,
    bin_start: Vec<u32>,
    /// `chunk << 16 | index in the chunk` (a chunk holds at most 6 × 4096 records).
    bins: Vec<u32>,
    /// The point fragments of each chunk ([`Body::Simd`] only), and as for the records their
    /// counts per eye and band, their bins' starts and the bins (the points themselves).
    points: Vec<Vec<FixedPoint>>,
    point_counts: Vec<u32>,
    point_bin_start: Vec<u32>,
    point_bins: Vec<BandPoint>,
    /// Each row's band: looked up for every point, twice (in the setup's counts and in
    /// binning), where an integer division would sit on the path of each of a dense mesh's
    /// points.
    row_band: Vec<u32>,
}

impl Default for FixedRasterizer {
    fn default() -> Self {
        Self::new()
    }
}

impl FixedRasterizer {
    /// A rasteriser in bands of [`super::BAND_ROWS`] rows.
    pub fn new() -> Self {
        Self::with_band_rows(super::BAND_ROWS)
    }

    /// A rasteriser in bands of `rows` rows (at least 1): the same buffers, bit for bit, for
    /// any band height.
    pub fn with_band_rows(rows: usize) -> Self {
        Self {
            band_rows: rows.max(1),
            records: Vec::new(),
            counts: Vec::new(),
            bin_start: Vec::new(),
            bins: Vec::new(),
            points: Vec::new(),
            point_counts: Vec::new(),
            point_bin_start: Vec::new(),
            point_bins: Vec::new(),
            row_band: Vec::new(),
        }
    }

    /// Fills `out[0]` (left eye, `cameras[0]`) and `out[1]` with the triangle whose snapped
    /// image covers each pixel centre nearest the eye (`prim`) and its depth key (`q`, exact
    /// for the snapped triangle up to its f32 evaluation, so with no error bound:
    /// [`VisibilityBuffer::q_err`] is `None` after this pass). `near` is the nearest view
    /// depth rasterised. The cameras must be a parallel stereo pair of one extent, and each
    /// buffer of that extent.
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
        if tris.len() >= NO_PRIM as usize || tris.len().div_ceil(CHUNK) > 1 << 16 {
            return Err(FrameError::InvalidParameter("too many triangles for 32-bit ids"));
        }
        let proj = Projection::new(cameras[0], cameras[1])?;
        let start = Instant::now();
        let mut stats = self.setup(tris, &proj, mask, near, body);
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

    fn setup<M: AlphaTest>(
        &mut self,
        tris: Triangles<'_>,
        proj: &Projection,
        mask: &M,
        near: f32,
        body: Body,
    ) -> RasterStats {
        let n = tris.len();
        let chunks = n.div_ceil(CHUNK);
        let (band_rows, bands) = (self.band_rows, (proj.height as usize).div_ceil(self.band_rows));
        self.records.resize_with(chunks, Vec::new);
        self.points.resize_with(chunks, Vec::new);
        self.counts.clear();
        self.counts.resize(chunks * 2 * bands, 0);
        self.point_counts.clear();
        self.point_counts.resize(chunks * 2 * bands, 0);
        self.row_band.clear();
        self.row_band.extend((0..proj.height as usize).map(|y| (y / band_rows) as u32));
        let row_band = &self.row_band;
        self.records
            .par_iter_mut()
            .zip(self.points.par_iter_mut())
            .zip(self.counts.par_chunks_mut(2 * bands).zip(self.point_counts.par_chunks_mut(2 * bands)))
            .enumerate()
            .map(|(chunk, ((records, points), (counts, point_counts)))| {
                let (first, end) = (chunk * CHUNK, ((chunk + 1) * CHUNK).min(n));
                // Room for a point per triangle from the first frame on: a chunk that had
                // none (every triangle large, or off screen) may have some when the camera
                // moves, and growing then would allocate mid-session.
                if body == Body::Simd && points.capacity() < end - first + 4 {
                    points.reserve_exact(end - first + 4);
                }
                // Likewise a few records: where points take the small triangles, a chunk's
                // records can be none one frame and dozens the next.
                if records.capacity() < MIN_RECORDS {
                    records.reserve_exact(MIN_RECORDS);
                }
                let capacity = (records.capacity(), points.capacity());
                records.clear();
                points.clear();
                let mut stats = RasterStats::default();
                // Counts the records and points triangle `prim` pushed from `before` on.
                let mut finish =
                    |prim: u32, before: (usize, usize), out: &mut SetupOut<'_>, stats: &mut RasterStats| {
                        let points = out.points.as_deref().map_or(&[][..], |p| &p[before.1..]);
                        if out.records.len() == before.0 && points.is_empty() {
                            return;
                        }
                        stats.visible += 1;
                        for point in points {
                            let eye = (point.eye_x >> 31) as usize;
                            point_counts[eye * bands + row_band[point.y as usize] as usize] += 1;
                        }
                        let masked = mask.has_mask(prim);
                        for rec in &mut out.records[before.0..] {
                            rec.masked = masked;
                            for eye in 0..2 {
                                if rec.visible_in(eye) {
                                    for band in band_range(rec.rows, band_rows) {
                                        counts[eye * bands + band] += 1;
                                    }
                                }
                            }
                        }
                    };
                let mut prim = first;
                if body == Body::Simd {
                    let near64 = both_eyes_near(proj, near);
                    let mut snapped = [[Snapped::default(); 3]; 4];
                    let mut four_points = FourPoints::default();
                    while prim + 4 <= end {
                        // Chunks start on cluster boundaries (CHUNK is a multiple of CLUSTER).
                        if (prim - first).is_multiple_of(CLUSTER)
                            && prim + CLUSTER <= end
                            && cluster_outside((prim..prim + CLUSTER).map(|id| tris.get(id as u32)), proj)
                        {
                            stats.cluster_culled += CLUSTER as u64;
                            prim += CLUSTER;
                            continue;
                        }
                        let ids: [u32; 4] = core::array::from_fn(|i| (prim + i) as u32);
                        // Cut-out triangles keep records: their fragments need the mask.
                        // Asked only of groups with simple lanes (a lookup per triangle).
                        let opaque =
                            || (0..4).fold(0, |bits, lane| bits | u32::from(!mask.has_mask(ids[lane])) << lane);
                        let tris4 = ids.map(|id| tris.get(id));
                        let (culled, simple, pointed) =
                            setup_four(tris4, proj, near64, opaque, &mut snapped, &mut four_points);
                        for (lane, id) in ids.into_iter().enumerate() {
                            let before = (records.len(), points.len());
                            let taken = pointed >> lane & 1 != 0;
                            if taken {
                                four_points.push(lane, id, points);
                            }
                            // (A taken lane's points are in it already, for `finish` to count.)
                            let points = (taken || !mask.has_mask(id)).then_some(&mut *points);
                            let mut out = SetupOut { records: &mut *records, points };
                            if simple >> lane & 1 != 0 {
                                record(&snapped[lane], id, proj, [true; 2], &mut out);
                            } else if !taken && culled >> lane & 1 == 0 {
                                stats.clipped += u64::from(setup_triangle(tris.get(id), id, proj, near, &mut out));
                            }
                            finish(id, before, &mut out, &mut stats);
                        }
                        prim += 4;
                    }
                }
                for prim in prim..end {
                    let prim = prim as u32;
                    let before = (records.len(), points.len());
                    let points = (body == Body::Simd && !mask.has_mask(prim)).then_some(&mut *points);
                    let mut out = SetupOut { records: &mut *records, points };
                    stats.clipped += u64::from(setup_triangle(tris.get(prim), prim, proj, near, &mut out));
                    finish(prim, before, &mut out, &mut stats);
                }
                if records.capacity() != capacity.0 {
                    // It grew this frame: a quarter more room, so that a camera that moves a
                    // little does not make it grow again next frame.
                    records.reserve(records.len() / 4 + MIN_RECORDS);
                }
                if points.capacity() != capacity.1 {
                    // And room for the four slots `push_points` writes past the end.
                    points.reserve(points.len() / 4 + 4);
                }
                stats
            })
            .reduce(RasterStats::default, |a, b| a + b)
    }

    fn bin(&mut self, extent: Extent) {
        let (band_rows, bands) = (self.band_rows, self.bands(extent));
        let total = bin_cursors(&mut self.counts, bands, &mut self.bin_start);
        super::resize_with_headroom(&mut self.bins, total as usize, 0);
        self.bin_points(extent);
        let bins = super::SharedSlice::new(&mut self.bins);
        self.records.par_iter().zip(self.counts.par_chunks_mut(2 * bands)).enumerate().for_each(
            |(chunk, (records, cursors))| {
                for (i, rec) in records.iter().enumerate() {
                    for eye in 0..2 {
                        if rec.visible_in(eye) {
                            for band in band_range(rec.rows, band_rows) {
                                let at = &mut cursors[eye * bands + band];
                                // SAFETY: the prefix sum gave every (chunk, eye, band) its own
                                // range of `bins`, and this chunk's cursors only walk its own.
                                unsafe { bins.write(*at as usize, ((chunk as u32) << 16) | i as u32) };
                                *at += 1;
                            }
                        }
                    }
                }
            },
        );
    }

    /// [`Self::bin`] for the points: each copied into its eye's band, in triangle order.
    fn bin_points(&mut self, extent: Extent) {
        let (band_rows, bands, width) = (self.band_rows, self.bands(extent), extent.width());
        let total = bin_cursors(&mut self.point_counts, bands, &mut self.point_bin_start);
        // As much room as the chunks have: the bins grow only when a chunk's points do.
        let room: usize = self.points.iter().map(Vec::capacity).sum();
        if self.point_bins.capacity() < room {
            self.point_bins.reserve_exact(room - self.point_bins.len());
        }
        super::resize_with_headroom(&mut self.point_bins, total as usize, BandPoint::default());
        let bins = super::SharedSlice::new(&mut self.point_bins);
        let row_band = &self.row_band;
        self.points.par_iter().zip(self.point_counts.par_chunks_mut(2 * bands)).for_each(|(points, cursors)| {
            for point in points {
                let (eye, x, y) = ((point.eye_x >> 31) as usize, (point.eye_x & !(1 << 31)) as usize, point.y as usize);
                let band = row_band[y] as usize;
                let at = &mut cursors[eye * bands + band];
                let in_band = ((y - band * band_rows) * width + x) as u32;
                // SAFETY: as in `bin`: this chunk's cursors walk its own ranges of the bins.
                unsafe { bins.write(*at as usize, BandPoint { at: in_band, prim: point.prim, q: point.q }) };
                *at += 1;
            }
        });
    }

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
        let run = |eye: usize, band: usize, (prim, q): (&mut [u32], &mut [f32])| {
            prim.fill(NO_PRIM);
            q.fill(0.0);
            let at = eye * (bands + 1) + band;
            let list = &self.bins[self.bin_start[at] as usize..self.bin_start[at + 1] as usize];
            let rows = band * band_rows..(band * band_rows + band_rows).min(extent.height());
            let mut band_out = Band { prim, q, width: w, rows };
            let mut stats = RasterStats { band_records: list.len() as u64, ..RasterStats::default() };
            let record = |r: u32| &self.records[(r >> 16) as usize][(r & 0xffff) as usize];
            for (i, &r) in list.iter().enumerate() {
                // The records of a band are scattered over the frame's records: fetch ahead.
                if let Some(&ahead) = list.get(i + 6) {
                    let p = (&record(ahead).eyes[eye] as *const FixedEyeEdges).cast::<u8>();
                    prefetch(p);
                    prefetch(p.wrapping_add(64));
                }
                let rec = record(r);
                stats.exact += match body {
                    Body::Simd => walk_simd(rec, eye, &views[eye], &mut band_out),
                    Body::Scalar => walk_scalar(rec, eye, &views[eye], &mut band_out),
                };
            }
            // The points after the records: the depth test's order does not matter.
            let points = &self.point_bins[self.point_bin_start[at] as usize..self.point_bin_start[at + 1] as usize];
            stats.band_points = points.len() as u64;
            for point in points {
                let at = point.at as usize;
                if wins(point.q, point.prim, band_out.q[at], band_out.prim[at]) {
                    (band_out.q[at], band_out.prim[at]) = (point.q, point.prim);
                }
            }
            stats
        };
        let l = super::band_keys(left, w, band_rows).enumerate().map(|(band, bufs)| run(0, band, bufs));
        let r = super::band_keys(right, w, band_rows).enumerate().map(|(band, bufs)| run(1, band, bufs));
        l.chain(r).reduce(RasterStats::default, |a, b| a + b)
    }
}

/// One band of one eye's visibility buffer.
struct Band<'a> {
    prim: &'a mut [u32],
    q: &'a mut [f32],
    width: usize,
    rows: core::ops::Range<usize>,
}

/// Clips, projects and snaps one triangle, pushing its records (none when culled). Returns
/// whether it was clipped (by the near plane or the guard band) or dropped past the limits.
fn setup_triangle(t: &[f32; 9], prim: u32, p: &Projection, near: f32, out: &mut SetupOut<'_>) -> bool {
    let d: [[f64; 3]; 3] =
        core::array::from_fn(|k| core::array::from_fn(|c| f64::from(t[3 * k + c]) - f64::from(p.centre[c])));
    if !d.iter().flatten().all(|v| v.is_finite()) {
        return false;
    }
    // Collinear vertices: a segment, which the tracer never hits; snapped to the grid its image
    // could still cover a pixel centre. (Differences of f32 values are exact in f64.)
    let (e1, e2) = ([0, 1, 2].map(|c| d[1][c] - d[0][c]), [0, 1, 2].map(|c| d[2][c] - d[0][c]));
    let area = [e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]];
    if area == [0.0; 3] {
        return false;
    }
    let dot = |r: &[f32; 3], v: &[f64; 3]| f64::from(r[0]) * v[0] + f64::from(r[1]) * v[1] + f64::from(r[2]) * v[2];
    let clip = d.map(|v| [dot(&p.rx, &v), dot(&p.ry, &v), dot(&p.rw, &v)]);
    let offsets = [[0.0; 3], p.right_offset];
    // Outside the frustum for both eyes: all three vertices beyond one side plane (x = ±w,
    // y = ±w, planes through the eye, so this holds behind it too). No pixel centre lies
    // beyond them, nor within a snap of them.
    let outside = |o: &[f64; 3]| {
        let beyond = |f: &dyn Fn(&[f64; 3]) -> bool| clip.iter().all(f);
        let (x, y, w) = (|c: &[f64; 3]| c[0] + o[0], |c: &[f64; 3]| c[1] + o[1], |c: &[f64; 3]| c[2] + o[2]);
        beyond(&|c| x(c) > w(c)) || beyond(&|c| -x(c) > w(c)) || beyond(&|c| y(c) > w(c)) || beyond(&|c| -y(c) > w(c))
    };
    if outside(&offsets[0]) && outside(&offsets[1]) {
        return false;
    }
    let near = both_eyes_near(p, near);
    let (hw, hh) = (f64::from(p.hw), f64::from(p.hh));
    let (gx, gy) = (GUARD_HALF_PX / hw, GUARD_HALF_PX / hh);
    let beyond = |c: &[f64; 3], o: &[f64; 3]| {
        let w = c[2] + o[2];
        !((c[0] + o[0]).abs() <= gx * w && (c[1] + o[1]).abs() <= gy * w)
    };
    // Most triangles need no clipping: project them as they are.
    if clip.iter().all(|c| c[2] > near && !offsets.iter().any(|o| beyond(c, o))) {
        let mut verts = [Snapped::default(); 3];
        for (v, c) in verts.iter_mut().zip(&clip) {
            if !snap(v, c, p) {
                return true;
            }
        }
        record(&verts, prim, p, [true; 2], out);
        return false;
    }
    let mut poly = [[0.0f64; 3]; MAX_POLYGON];
    poly[..3].copy_from_slice(&clip);
    let mut n = 3;
    let mut clipped = false;
    if poly[..3].iter().any(|c| !(c[2] > near)) {
        if poly[..3].iter().all(|c| !(c[2] > near)) {
            return false;
        }
        n = clip_polygon(&mut poly, n, |c| c[2] - near);
        clipped = true;
    }
    if n < 3 {
        return clipped;
    }
    // The guard band: only polygons that reach past it pay for its planes, and then each eye
    // is clipped to its own (the right eye's clip coordinates are the left's plus
    // `right_offset`). Not to both at once: near the eye the two views part by far more than
    // the band, and one eye's band would cut away what the other sees.
    if poly[..n].iter().any(|c| offsets.iter().any(|o| beyond(c, o))) {
        for (eye, o) in offsets.iter().enumerate() {
            let mut own = poly;
            let mut m = n;
            for (axis, g, sign) in [(0, gx, 1.0), (0, gx, -1.0), (1, gy, 1.0), (1, gy, -1.0)] {
                if m >= 3 {
                    m = clip_polygon(&mut own, m, |c| g * (c[2] + o[2]) - sign * (c[axis] + o[axis]));
                }
            }
            fan(&own[..m], prim, p, [eye == 0, eye == 1], out);
        }
        return true;
    }
    fan(&poly[..n], prim, p, [true; 2], out);
    clipped
}

/// The near plane in the left eye's clip space: both eyes' `w` must exceed `near` (the right
/// eye's `w` differs by the rig's rounding noise).
fn both_eyes_near(p: &Projection, near: f32) -> f64 {
    f64::from(near).max(f64::from(near) - p.right_offset[2])
}

/// [`setup_triangle`]'s common case for four triangles at once, one per `f64x4` lane: the
/// same f64 operations in the same order (so the same snapped vertices, bit for bit), without
/// its branches. `near` is [`both_eyes_near`]'s. Returns three lane masks: the triangles
/// culled (outside both eyes' frusta, collinear or not finite, or tiny and covering no pixel
/// centre, unless taken as points: no record); those that need no clipping and land within
/// the coordinate limit, whose snapped vertices are in `out` (their record is [`record`]'s);
/// and those of the `opaque` lanes that `record` would make only points of (or nothing),
/// whose points are in `points`
/// ([`points_four`]: on the 833k-triangle bunny grid nearly every visible triangle, and
/// `record`'s scalar steps were half the setup). Lanes in none are [`setup_triangle`]'s to
/// do.
fn setup_four(
    ts: [&[f32; 9]; 4],
    p: &Projection,
    near: f64,
    opaque: impl FnOnce() -> u32,
    out: &mut [[Snapped; 3]; 4],
    points: &mut FourPoints,
) -> (u32, u32, u32) {
    type F = f64x4;
    let all = F::splat(f64::from_bits(u64::MAX));
    let comp = |k: usize, c: usize| F::from(ts.map(|t| f64::from(t[3 * k + c]))) - F::splat(f64::from(p.centre[c]));
    // The arrays here are written out, not built by `array::from_fn` or `map`: built that
    // way, some builds assembled them on the stack and copied them with `memcpy` calls, a
    // tenth of the setup's instructions on atrium.
    let vertex = |k: usize| [comp(k, 0), comp(k, 1), comp(k, 2)];
    let d: [[F; 3]; 3] = [vertex(0), vertex(1), vertex(2)];
    let finite = d.iter().flatten().fold(all, |acc, v| acc & v.is_finite());
    let (e1, e2) = ([0, 1, 2].map(|c| d[1][c] - d[0][c]), [0, 1, 2].map(|c| d[2][c] - d[0][c]));
    let area = [e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]];
    let collinear = area.iter().fold(all, |acc, a| acc & a.simd_eq(F::splat(0.0)));
    let row = |r: &[f32; 3]| r.map(|x| F::splat(f64::from(x)));
    let (rx, ry, rw) = (row(&p.rx), row(&p.ry), row(&p.rw));
    let dot = |r: &[F; 3], v: &[F; 3]| r[0] * v[0] + r[1] * v[1] + r[2] * v[2];
    let to_clip = |v: &[F; 3]| [dot(&rx, v), dot(&ry, v), dot(&rw, v)];
    let clip = [to_clip(&d[0]), to_clip(&d[1]), to_clip(&d[2])];
    // Per eye, the clip coordinates `(x, y, w)` of the three vertices.
    // (The left eye's offset is 0, added all the same, as `setup_triangle` adds it.)
    let eye = |o: [f64; 3]| {
        let o = o.map(F::splat);
        let shifted = |c: &[F; 3]| [c[0] + o[0], c[1] + o[1], c[2] + o[2]];
        [shifted(&clip[0]), shifted(&clip[1]), shifted(&clip[2])]
    };
    let eye_clip = [eye([0.0; 3]), eye(p.right_offset)];
    // All three vertices beyond one side plane of an eye's frustum.
    let outside = |v: &[[F; 3]; 3]| {
        let (mut right, mut left, mut up, mut down) = (all, all, all, all);
        for [x, y, w] in v {
            right &= x.simd_gt(*w);
            left &= (-*x).simd_gt(*w);
            up &= y.simd_gt(*w);
            down &= (-*y).simd_gt(*w);
        }
        right | left | up | down
    };
    let culled = !finite | collinear | (outside(&eye_clip[0]) & outside(&eye_clip[1]));
    let (hw, hh) = (F::splat(f64::from(p.hw)), F::splat(f64::from(p.hh)));
    let (gx, gy) = (F::splat(GUARD_HALF_PX / f64::from(p.hw)), F::splat(GUARD_HALF_PX / f64::from(p.hh)));
    let (limit, one) = (F::splat(HARD_LIMIT_PX), F::splat(ONE as f64));
    let simple = clip.iter().fold(all, |acc, c| acc & c[2].simd_gt(F::splat(near)));
    // One vertex in one eye: the snapped position (rounded, in f64) and q, and whether it
    // lies within the guard band and the coordinate limit.
    let snap = |[x, y, w]: [F; 3]| {
        let inside = x.abs().simd_le(gx * w) & y.abs().simd_le(gy * w);
        let q = F::splat(1.0) / w;
        let (sx, sy) = (x * q * hw + hw, -y * q * hh + hh);
        let inside = inside & sx.abs().simd_le(limit) & sy.abs().simd_le(limit);
        // `round` is f64::round's (half away from zero), lane for lane.
        ([(sx * one).round(), (sy * one).round(), q], inside)
    };
    // Written out (an array filled in a loop was zeroed first, with a `memset` call).
    let [[a, b, c], [d, e, f]] = eye_clip;
    let (a, b, c, d, e, f) = (snap(a), snap(b), snap(c), snap(d), snap(e), snap(f));
    let simple = simple & a.1 & b.1 & c.1 & d.1 & e.1 & f.1;
    // Per eye and vertex.
    let snapped = [[a.0, b.0, c.0], [d.0, e.0, f.0]];
    // Opaque simple lanes whose eyes `record` would turn wholly into points take them here
    // (a lane that covers no centre takes none: it is culled as well).
    let simple = simple & !culled;
    let pointed = if simple.any() { points_four(&snapped, p, simple.to_bitmask(), opaque, points) } else { 0 };
    let simple = simple.to_bitmask() & !pointed;
    // The simple lanes left whose tiny triangle covers no pixel centre in either eye get no
    // record (`record` would drop them after its scalar setup): cut-out triangles, and those
    // whose eyes' rows differ. On the 833k-triangle bunny grid, before points, 43 % of all
    // triangles. The right eye is tested only where the left eye's test culls a lane, and
    // each test stops at the box where no lane's is small.
    let lanes = lane_mask(simple);
    let none = F::splat(0.0).simd_ne(F::splat(0.0));
    let left_empty = if simple != 0 { lanes & covers_no_centre_four(&snapped[0]) } else { none };
    let tiny = if left_empty.any() { left_empty & covers_no_centre_four(&snapped[1]) } else { none };
    let culled = (culled | tiny).to_bitmask();
    let simple = simple & !culled;
    // The snapped integers to `i64` in lanes: adding 1.5·2⁵² puts an integer below 2⁵¹ in
    // magnitude into the low mantissa bits, so the difference of the bit patterns is the
    // integer (the scalar `as i64`, with its saturation checks, was a sixth of this function's
    // instructions). Exact for simple lanes (|x| ≤ 2²⁹); the others are not read.
    const MAGIC: f64 = 6_755_399_441_055_744.0;
    let magic_bits = i64x4::splat(MAGIC.to_bits() as i64);
    let to_i64 = |v: F| (bytemuck::cast::<F, i64x4>(v + F::splat(MAGIC)) - magic_bits).to_array();
    if simple == 0 {
        // No lane needs `record` (on a dense mesh, most groups: points or culled).
        return (culled, simple, pointed);
    }
    for (eye, v) in snapped.iter().enumerate() {
        for (k, [x, y, q]) in v.iter().enumerate() {
            let (x, y, q) = (to_i64(*x), to_i64(*y), q.to_array());
            for (lane, tri) in out.iter_mut().enumerate() {
                tri[k].x[eye] = x[lane];
                tri[k].y[eye] = y[lane];
                tri[k].q[eye] = q[lane];
            }
        }
    }
    (culled, simple, pointed)
}

/// The lanes of `bits` (bit `l` for lane `l`) as an `f64x4` mask.
#[inline(always)]
fn lane_mask(bits: u32) -> f64x4 {
    f64x4::from([0, 1, 2, 3].map(|l| if bits >> l & 1 != 0 { f64::from_bits(u64::MAX) } else { 0.0 }))
}

/// One eye's box of [`setup_four`]'s four triangles, from their snapped vertices (`[x, y, q]`
/// per vertex, fixed point as exact `f64` integers): the first and last pixel centres in
/// each axis, as `record`'s `centres` before the frame clamp, and twice the signed area.
#[derive(Clone, Copy)]
struct BoxFour {
    c0: f64x4,
    c1: f64x4,
    r0: f64x4,
    r1: f64x4,
    area2: f64x4,
}

impl BoxFour {
    #[inline(always)]
    fn of(v: &[[f64x4; 3]; 3]) -> Self {
        let half = f64x4::splat((ONE / 2) as f64);
        // Dividing by a power of two is multiplying by its exact inverse (a division costs a
        // dozen multiplies' time).
        let per_one = f64x4::splat(1.0 / ONE as f64);
        let (x, y) = ([v[0][0], v[1][0], v[2][0]], [v[0][1], v[1][1], v[2][1]]);
        let lo = |a: [f64x4; 3]| a[0].min(a[1]).min(a[2]);
        let hi = |a: [f64x4; 3]| a[0].max(a[1]).max(a[2]);
        Self {
            c0: ((lo(x) - half) * per_one).ceil(),
            c1: ((hi(x) - half) * per_one).floor(),
            r0: ((lo(y) - half) * per_one).ceil(),
            r1: ((hi(y) - half) * per_one).floor(),
            area2: (x[1] - x[0]) * (y[2] - y[0]) - (x[2] - x[0]) * (y[1] - y[0]),
        }
    }
}

/// `record`'s winding of four triangles' vertices: 1 and 2 swapped where the signed area
/// `area2` is negative.
#[inline(always)]
fn wound(a: [f64x4; 3], area2: f64x4) -> [f64x4; 3] {
    let flip = area2.simd_lt(f64x4::splat(0.0));
    [a[0], flip.select(a[2], a[1]), flip.select(a[1], a[2])]
}

/// Which of the 2×2 pixel centres from column `c0`, row `r0` (in pixels) four wound
/// triangles `(x, y)` cover, by `record`'s edge functions and top-left rule: entry
/// `2·dy + dx`, the second column only where `two_cols`, the second row only where
/// `two_rows`. Exact where every term is an integer below 2²¹ in magnitude, as in the
/// callers' lanes.
#[inline(always)]
fn centres_covered_four(
    x: [f64x4; 3],
    y: [f64x4; 3],
    (c0, r0): (f64x4, f64x4),
    two_cols: f64x4,
    two_rows: f64x4,
) -> [f64x4; 4] {
    let (one, half) = (f64x4::splat(ONE as f64), f64x4::splat((ONE / 2) as f64));
    let (px, py) = (c0 * one + half, r0 * one + half);
    let (px1, py1) = (px + one, py + one);
    let all = one.simd_eq(one);
    // Written out, not filled in a loop: see `setup_four`.
    [
        centre_inside(&x, &y, px, py, all),
        centre_inside(&x, &y, px1, py, two_cols),
        centre_inside(&x, &y, px, py1, two_rows),
        centre_inside(&x, &y, px1, py1, two_cols & two_rows),
    ]
}

/// The lanes of `wanted` where the pixel centre `(px, py)` (fixed point) is inside the wound
/// triangle `(x, y)` by `record`'s edge functions and top-left rule.
#[inline(always)]
fn centre_inside(x: &[f64x4; 3], y: &[f64x4; 3], px: f64x4, py: f64x4, wanted: f64x4) -> f64x4 {
    let (zero, unit) = (f64x4::splat(0.0), f64x4::splat(1.0));
    let mut inside = wanted;
    for k in 0..3 {
        let j = (k + 1) % 3;
        let (ex, ey) = (x[j] - x[k], y[j] - y[k]);
        let owns = (-ey).simd_gt(zero) | (ey.simd_eq(zero) & ex.simd_gt(zero));
        let e = ex * (py - y[k]) - ey * (px - x[k]) - owns.select(zero, unit);
        inside &= e.simd_ge(zero);
    }
    inside
}

/// The points of [`setup_four`]'s lanes that [`points_four`] took, per lane and eye: which of
/// the 2×2 centres from `(cols, row)` are covered (bit `2·dy + dx`), and the depth-key plane
/// there, rounded to `f32` as `record` rounds it.
#[derive(Clone, Copy, Debug, Default)]
struct FourPoints {
    covered: [[u8; 2]; 4],
    cols: [[i32; 2]; 4],
    row: [i32; 4],
    plane: [[[f32; 3]; 2]; 4],
}

impl FourPoints {
    /// Pushes lane `lane`'s points as [`record`] with [`push_points`] would: the left eye's,
    /// then the right's, each row by row.
    #[inline(always)]
    fn push(&self, lane: usize, prim: u32, points: &mut Vec<FixedPoint>) {
        for eye in 0..2 {
            let (col, row) = (self.cols[lane][eye], self.row[lane]);
            append_points(points, eye, (col, row), prim, self.plane[lane][eye], self.covered[lane][eye]);
        }
    }
}

/// Of [`setup_four`]'s `lanes` (snapped vertices per eye, fixed point as exact `f64`
/// integers), those of an opaque triangle (`opaque()`, asked only once some lane's left box
/// is small) that `record` would give no record but points (or nothing): each eye either not visible
/// (zero area, or a box between pixel centres) or a box of at most 2×2 centres inside the
/// frame, the rows of both eyes' boxes together at most two. Their coverage and depth-key
/// planes go to `out`; the lanes are returned as a bit mask. The same operations as
/// `record`'s, in lanes: the edge functions are exact (every term an integer below 2²¹, the
/// vertices lying within three pixels of the centres), and the plane's `f64` steps are
/// `record`'s, one for one. Other lanes (larger or clipped boxes, rows apart) are left to it.
#[inline(always)]
fn points_four(
    snapped: &[[[f64x4; 3]; 3]; 2],
    p: &Projection,
    lanes: u32,
    opaque: impl FnOnce() -> u32,
    out: &mut FourPoints,
) -> u32 {
    type F = f64x4;
    let (zero, one, half, unit) = (F::splat(0.0), F::splat(ONE as f64), F::splat((ONE / 2) as f64), F::splat(1.0));
    // `x / ONE`, exactly (see `BoxFour::of`).
    let per_one = F::splat(1.0 / ONE as f64);
    let (last_col, last_row) = (F::splat(f64::from(p.width - 1)), F::splat(f64::from(p.height - 1)));
    // Per eye: whether `record` sees the eye (nonzero area, centres in both axes), and whether
    // its box lies inside the frame and is at most two columns wide.
    let seen = |b: &BoxFour| {
        let visible = b.area2.simd_ne(zero) & b.c0.simd_le(b.c1) & b.r0.simd_le(b.r1);
        let fits = b.c0.simd_ge(zero) & b.c1.simd_le(last_col) & b.r0.simd_ge(zero) & b.r1.simd_le(last_row);
        (visible, fits & (b.c1 - b.c0).simd_le(unit))
    };
    let in_lanes = lane_mask(lanes);
    // The left eye alone first: in a scene of large triangles no lane passes, and the right
    // eye's box is not needed.
    let left = BoxFour::of(&snapped[0]);
    let (vis_l, fits_l) = seen(&left);
    if !(in_lanes & (!vis_l | (fits_l & (left.r1 - left.r0).simd_le(unit)))).any() {
        return 0;
    }
    // Only then the materials (a lookup per triangle): cut-out triangles keep records.
    let lanes = lanes & opaque();
    if lanes == 0 {
        return 0;
    }
    let in_lanes = lane_mask(lanes);
    let right = BoxFour::of(&snapped[1]);
    let (vis_r, fits_r) = seen(&right);
    // `record`'s rows: the union of the visible eyes'.
    let both = vis_l & vis_r;
    let r0 = both.select(left.r0.min(right.r0), vis_l.select(left.r0, right.r0));
    let r1 = both.select(left.r1.max(right.r1), vis_l.select(left.r1, right.r1));
    let take = in_lanes & (vis_l | vis_r) & (!vis_l | fits_l) & (!vis_r | fits_r) & (r1 - r0).simd_le(unit);
    let taken = take.to_bitmask();
    if taken == 0 {
        return 0;
    }
    let row = r0.to_array();
    for (lane, r) in row.iter().enumerate() {
        out.row[lane] = *r as i32;
    }
    let two_rows = (r1 - r0).simd_eq(unit);
    for (eye, (v, b, visible)) in [(&snapped[0], &left, vis_l), (&snapped[1], &right, vis_r)].into_iter().enumerate() {
        let x = wound([v[0][0], v[1][0], v[2][0]], b.area2);
        let y = wound([v[0][1], v[1][1], v[2][1]], b.area2);
        let q = wound([v[0][2], v[1][2], v[2][2]], b.area2);
        let centres = centres_covered_four(x, y, (b.c0, r0), (b.c1 - b.c0).simd_eq(unit), two_rows);
        let mut covered = [0u8; 4];
        for (bit, inside) in centres.into_iter().enumerate() {
            let bits = (inside & visible).to_bitmask();
            for (lane, c) in covered.iter_mut().enumerate() {
                *c |= ((bits >> lane & 1) as u8) << bit;
            }
        }
        // The depth-key plane through the three snapped vertices, relative to the first
        // centre, in `record`'s steps.
        let (px, py) = (b.c0 * one + half, r0 * one + half);
        let fx = [(x[0] - px) * per_one, (x[1] - px) * per_one, (x[2] - px) * per_one];
        let fy = [(y[0] - py) * per_one, (y[1] - py) * per_one, (y[2] - py) * per_one];
        let det = (fx[1] - fx[0]) * (fy[2] - fy[0]) - (fx[2] - fx[0]) * (fy[1] - fy[0]);
        let (dq1, dq2) = (q[1] - q[0], q[2] - q[0]);
        let qa = (dq1 * (fy[2] - fy[0]) - dq2 * (fy[1] - fy[0])) / det;
        let qb = (dq2 * (fx[1] - fx[0]) - dq1 * (fx[2] - fx[0])) / det;
        let qc = q[0] - qa * fx[0] - qb * fy[0];
        let (qa, qb, qc, c0) = (qa.to_array(), qb.to_array(), qc.to_array(), b.c0.to_array());
        for lane in 0..4 {
            out.covered[lane][eye] = covered[lane];
            out.cols[lane][eye] = c0[lane] as i32;
            out.plane[lane][eye] = [qa[lane] as f32, qb[lane] as f32, qc[lane] as f32];
        }
    }
    taken
}

/// [`covers_no_centre`] for one eye of [`setup_four`]'s four triangles, from their snapped
/// vertices (`[x, y, q]` per vertex, fixed point as exact `f64` integers): the lanes whose
/// box holds at most 2×2 pixel centres (or none) and whose triangle covers none of them, by
/// the edge functions, winding and top-left rule of [`record`]. In those lanes every term is
/// an integer below 2²¹ in magnitude (the vertices lie within three pixels of each other and
/// of the centres), so the `f64` arithmetic is exact and equals `record`'s `i64`; other lanes
/// (larger boxes, or not finite) are false, whatever their values.
#[inline(always)]
fn covers_no_centre_four(v: &[[f64x4; 3]; 3]) -> f64x4 {
    let unit = f64x4::splat(1.0);
    let b = BoxFour::of(v);
    let small = (b.c1 - b.c0).simd_le(unit) & (b.r1 - b.r0).simd_le(unit);
    if !small.any() {
        return small;
    }
    let x = wound([v[0][0], v[1][0], v[2][0]], b.area2);
    let y = wound([v[0][1], v[1][1], v[2][1]], b.area2);
    let [a, c, d, e] =
        centres_covered_four(x, y, (b.c0, b.r0), (b.c1 - b.c0).simd_eq(unit), (b.r1 - b.r0).simd_eq(unit));
    small & !(a | c | d | e)
}

/// Whether every triangle of a cluster is culled by [`setup_four`]'s frustum test (all three
/// vertices beyond one side plane of the left eye's frustum, and beyond one of the right
/// eye's), decided from the cluster's bounding box. A side test is linear in the position,
/// so a box whose eight corners all lie beyond one plane holds only points beyond it. The
/// corners must clear the plane by a margin far above the f64 rounding of the per-vertex
/// test, so a vertex the setup would keep is never skipped; a box that is not finite (a
/// NaN or infinite vertex, which the setup culls on its own) is never skipped either.
fn cluster_outside<'t>(tris: impl Iterator<Item = &'t [f32; 9]>, p: &Projection) -> bool {
    let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    for t in tris {
        for v in t.chunks_exact(3) {
            for c in 0..3 {
                // `min`/`max` skip NaN: a NaN vertex's triangle is culled by the setup anyway,
                // and its other vertices still bound the box.
                (lo[c], hi[c]) = (lo[c].min(v[c]), hi[c].max(v[c]));
            }
        }
    }
    if !lo.iter().chain(&hi).all(|v| v.is_finite()) {
        return false;
    }
    let rel = |c: usize, v: f32| f64::from(v) - f64::from(p.centre[c]);
    let (lo, hi) = ([0, 1, 2].map(|c| rel(c, lo[c])), [0, 1, 2].map(|c| rel(c, hi[c])));
    // The largest |coordinate| relative to the eye on each axis, anywhere in the box.
    let reach = [0, 1, 2].map(|c| lo[c].abs().max(hi[c].abs()));
    let bound = |r: &[f32; 3]| (0..3).map(|c| f64::from(r[c]).abs() * reach[c]).sum::<f64>();
    // Any clip coordinate of any point in the box, in either eye, is at most this in size;
    // 1e-9 of it is ~10⁷ times the rounding of the setup's few f64 operations.
    let scale = bound(&p.rx).max(bound(&p.ry)).max(bound(&p.rw)) + p.right_offset.iter().map(|o| o.abs()).sum::<f64>();
    let margin = 1e-9 * scale;
    let dot = |r: &[f32; 3], v: &[f64; 3]| (0..3).map(|c| f64::from(r[c]) * v[c]).sum::<f64>();
    let corners: [[f64; 3]; 8] = core::array::from_fn(|i| {
        let pick = |c: usize| if i >> c & 1 == 0 { lo[c] } else { hi[c] };
        let d = [pick(0), pick(1), pick(2)];
        [dot(&p.rx, &d), dot(&p.ry, &d), dot(&p.rw, &d)]
    });
    [[0.0; 3], p.right_offset].iter().all(|o| {
        let (mut right, mut left, mut up, mut down) = (true, true, true, true);
        for [x, y, w] in corners.map(|c| [c[0] + o[0], c[1] + o[1], c[2] + o[2]]) {
            right &= x - w > margin;
            left &= -x - w > margin;
            up &= y - w > margin;
            down &= -y - w > margin;
        }
        right || left || up || down
    })
}

/// Snaps the convex polygon `poly` (clip space) for `eyes`, and pushes the records of its fan
/// triangles. A vertex past the coordinate limit in an eye drops the polygon for that eye.
fn fan(poly: &[[f64; 3]], prim: u32, p: &Projection, eyes: [bool; 2], out: &mut SetupOut<'_>) {
    if poly.len() < 3 {
        return;
    }
    let mut verts = [Snapped::default(); MAX_POLYGON];
    for (v, c) in verts.iter_mut().zip(poly) {
        for eye in (0..2).filter(|&e| eyes[e]) {
            if !snap_eye(v, c, p, eye) {
                return;
            }
        }
    }
    for k in 1..poly.len() - 1 {
        record(&[verts[0], verts[k], verts[k + 1]], prim, p, eyes, out);
    }
}

/// Projects the clip-space point `c` (the left eye's) for both eyes and snaps it into `v`;
/// false when it lands past the coordinate limit.
#[inline(always)]
fn snap(v: &mut Snapped, c: &[f64; 3], p: &Projection) -> bool {
    snap_eye(v, c, p, 0) && snap_eye(v, c, p, 1)
}

/// [`snap`] for one eye.
#[inline(always)]
fn snap_eye(v: &mut Snapped, c: &[f64; 3], p: &Projection, eye: usize) -> bool {
    let (hw, hh) = (f64::from(p.hw), f64::from(p.hh));
    let o = if eye == 0 { [0.0; 3] } else { p.right_offset };
    let q = 1.0 / (c[2] + o[2]);
    let (x, y) = ((c[0] + o[0]) * q * hw + hw, -(c[1] + o[1]) * q * hh + hh);
    if !(x.abs() <= HARD_LIMIT_PX && y.abs() <= HARD_LIMIT_PX) {
        return false;
    }
    v.x[eye] = (x * ONE as f64).round() as i64;
    v.y[eye] = (y * ONE as f64).round() as i64;
    v.q[eye] = q;
    true
}

/// Sutherland–Hodgman: clips the convex polygon `poly[..n]` to `inside(c) > 0` in place and
/// returns the new vertex count (at most one more).
fn clip_polygon(poly: &mut [[f64; 3]; MAX_POLYGON], n: usize, inside: impl Fn(&[f64; 3]) -> f64) -> usize {
    let src = *poly;
    let mut m = 0;
    for k in 0..n {
        let (a, b) = (src[k], src[(k + 1) % n]);
        let (da, db) = (inside(&a), inside(&b));
        if da > 0.0 {
            poly[m] = a;
            m += 1;
        }
        if (da > 0.0) != (db > 0.0) && m < MAX_POLYGON {
            let s = da / (da - db);
            poly[m] = [a[0] + (b[0] - a[0]) * s, a[1] + (b[1] - a[1]) * s, a[2] + (b[2] - a[2]) * s];
            m += 1;
        }
    }
    m
}

/// Where the setup puts a triangle's work: records, and where `points` is given (the SIMD
/// body, for opaque triangles) the covered centres of eyes whose box holds at most 2×2 pixel
/// centres, as points instead of records ([`record`]).
struct SetupOut<'a> {
    records: &'a mut Vec<FixedRecord>,
    points: Option<&'a mut Vec<FixedPoint>>,
}

/// Pushes the record of one snapped triangle for `eyes` (the other eye's part empty) onto
/// `out`, or nothing when it covers no pixel centre in them (zero snapped area, a bounding
/// box between centres or off screen, or a box of a few centres none of which it covers).
/// With `out.points`, an eye whose box holds at most 2×2 centres gets, instead of its part
/// of the record, a point for each centre it covers, with the depth key its walk would form:
/// 16 bytes a point, read in order, where a record is 208 bytes fetched from anywhere and
/// walked (the depth test does not depend on order, so the buffers are the same). The record
/// is written where it lands in `out`: built elsewhere and moved there, its 208 bytes were
/// copied twice.
fn record(v: &[Snapped; 3], prim: u32, p: &Projection, eyes: [bool; 2], out: &mut SetupOut<'_>) {
    record_culling::<true>(v, prim, p, eyes, out);
}

/// [`record`], with `CULL_EMPTY` deciding whether an eye whose box of a few centres holds
/// none it covers is dropped ([`covers_no_centre`]); off only in the test that holds that
/// cull to the walk.
#[inline(always)]
fn record_culling<const CULL_EMPTY: bool>(
    v: &[Snapped; 3],
    prim: u32,
    p: &Projection,
    eyes: [bool; 2],
    setup_out: &mut SetupOut<'_>,
) {
    let out = &mut *setup_out.records;
    // Pixel centres `i + 1/2` inside [lo, hi] (fixed point), clamped to the frame.
    let centres = |lo: i64, hi: i64, size: i32| -> (i32, i32) {
        let first = (lo - ONE / 2).div_euclid(ONE) + i64::from((lo - ONE / 2).rem_euclid(ONE) != 0);
        let last = (hi - ONE / 2).div_euclid(ONE);
        let (a, b) = (first.max(0), last.min(i64::from(size) - 1));
        if a <= b { (a as i32, b as i32) } else { (1, 0) }
    };
    let mut rows = [(1, 0); 2];
    let mut cols = [(1, 0); 2];
    let mut order = [[0usize, 1, 2]; 2];
    for eye in (0..2).filter(|&e| eyes[e]) {
        let (x, y) = (v.map(|s| s.x[eye]), v.map(|s| s.y[eye]));
        let area2 = (x[1] - x[0]) * (y[2] - y[0]) - (x[2] - x[0]) * (y[1] - y[0]);
        if area2 == 0 {
            continue;
        }
        if area2 < 0 {
            order[eye] = [0, 2, 1];
        }
        let r = centres(*y.iter().min().unwrap(), *y.iter().max().unwrap(), p.height);
        let c = centres(*x.iter().min().unwrap(), *x.iter().max().unwrap(), p.width);
        if r.0 <= r.1 && c.0 <= c.1 {
            (rows[eye], cols[eye]) = (r, c);
        }
    }
    let visible = |eye: usize| cols[eye].0 <= cols[eye].1;
    if !(visible(0) || visible(1)) {
        return;
    }
    let rows = match (visible(0), visible(1)) {
        (true, true) => (rows[0].0.min(rows[1].0), rows[0].1.max(rows[1].1)),
        (true, false) => rows[0],
        _ => rows[1],
    };
    out.push(FixedRecord {
        eyes: [FixedEyeEdges { cols: (1, 0), ..Default::default() }; 2],
        rows,
        prim,
        masked: false,
    });
    let rec = out.last_mut().expect("just pushed");
    for eye in 0..2 {
        if !visible(eye) {
            continue;
        }
        let o = order[eye];
        let (x, y, q) = (o.map(|k| v[k].x[eye]), o.map(|k| v[k].y[eye]), o.map(|k| v[k].q[eye]));
        let e = &mut rec.eyes[eye];
        e.cols = cols[eye];
        // The first pixel centre, in fixed point.
        let (px, py) = (i64::from(e.cols.0) * ONE + ONE / 2, i64::from(rows.0) * ONE + ONE / 2);
        for k in 0..3 {
            let j = (k + 1) % 3;
            // E_k(P) = cross(V_j − V_k, P − V_k): positive towards the third vertex.
            let (ex, ey) = (x[j] - x[k], y[j] - y[k]);
            let (step_x, step_y) = (-ey, ex);
            // Top-left rule (rows grow downwards): an edge whose inside lies to its right
            // (a left edge), or a horizontal one with the inside below (a top edge), owns
            // the pixel centres exactly on it.
            let owns = step_x > 0 || (step_x == 0 && step_y > 0);
            e.e0[k] = ex * (py - y[k]) - ey * (px - x[k]) - i64::from(!owns);
            e.dx[k] = step_x * ONE;
            e.dy[k] = step_y * ONE;
        }
        if CULL_EMPTY && covers_no_centre(e, rows) {
            e.cols = (1, 0);
            continue;
        }
        // q is linear in screen space: the plane through the three snapped vertices,
        // relative to the first pixel centre.
        let fx = x.map(|x| (x - px) as f64 / ONE as f64);
        let fy = y.map(|y| (y - py) as f64 / ONE as f64);
        let det = (fx[1] - fx[0]) * (fy[2] - fy[0]) - (fx[2] - fx[0]) * (fy[1] - fy[0]);
        let (dq1, dq2) = (q[1] - q[0], q[2] - q[0]);
        let qa = (dq1 * (fy[2] - fy[0]) - dq2 * (fy[1] - fy[0])) / det;
        let qb = (dq2 * (fx[1] - fx[0]) - dq1 * (fx[2] - fx[0])) / det;
        let qc = q[0] - qa * fx[0] - qb * fy[0];
        (e.qa, e.qb, e.qc) = (qa as f32, qb as f32, qc as f32);
        if let Some(points) = setup_out.points.as_deref_mut()
            && push_points(e, rows, eye, prim, points)
        {
            e.cols = (1, 0);
        }
    }
    if !(rec.visible_in(0) || rec.visible_in(1)) {
        out.pop();
    }
}

/// Where the eye's box (columns `e.cols`, rows `rows`) holds at most 2×2 pixel centres,
/// pushes a [`FixedPoint`] for each it covers and returns true; otherwise pushes nothing and
/// returns false. The coverage and the depth key are [`walk_scalar`]'s, integer for integer
/// and product for product.
#[inline(always)]
fn push_points(e: &FixedEyeEdges, rows: (i32, i32), eye: usize, prim: u32, points: &mut Vec<FixedPoint>) -> bool {
    let (row_count, col_count) = (rows.1 - rows.0 + 1, e.cols.1 - e.cols.0 + 1);
    if row_count > 2 || col_count > 2 {
        return false;
    }
    let mut covered = 0u8;
    for (bit, (dy, dx)) in [(0, 0), (0, 1), (1, 0), (1, 1)].into_iter().enumerate() {
        let (dx64, dy64) = (i64::from(dx), i64::from(dy));
        let smallest = (0..3).map(|k| e.e0[k] + e.dy[k] * dy64 + e.dx[k] * dx64).fold(i64::MAX, i64::min);
        covered |= u8::from((dy < row_count) & (dx < col_count) & (smallest >= 0)) << bit;
    }
    append_points(points, eye, (e.cols.0, rows.0), prim, [e.qa, e.qb, e.qc], covered);
    true
}

/// Appends the points of one eye's box of at most 2×2 pixel centres from `(col, row)`: those
/// whose bit `2·dy + dx` is set in `covered`, with the depth key of the plane `[qa, qb, qc]`
/// formed as [`walk_scalar`] forms it. All four slots are written and the length advanced
/// past the covered ones: no branch per centre, whose outcome is a coin toss for a tiny
/// triangle.
#[inline(always)]
fn append_points(
    points: &mut Vec<FixedPoint>,
    eye: usize,
    (col, row): (i32, i32),
    prim: u32,
    [qa, qb, qc]: [f32; 3],
    covered: u8,
) {
    points.reserve(4);
    let spare = &mut points.spare_capacity_mut()[..4];
    let mut count = 0;
    for (bit, (dy, dx)) in [(0, 0), (0, 1), (1, 0), (1, 1)].into_iter().enumerate() {
        let q = (qc + qb * dy as f32) + qa * dx as f32;
        let x = (col + dx) as u32 | (eye as u32) << 31;
        spare[count].write(FixedPoint { eye_x: x, y: (row + dy) as u32, prim, q });
        count += usize::from(covered >> bit & 1);
    }
    // SAFETY: the first `count` spare slots were written just now.
    unsafe { points.set_len(points.len() + count) };
}

/// Whether the eye's edges `e` (from pixel centre `(cols.0, rows.0)`) cover none of the pixel
/// centres of its box, where the box is at most 2×2 centres; false for larger boxes, which
/// are left to the walks. A triangle much smaller than a pixel has a box of one to four
/// centres and usually covers none of them (42 % of the 833k-triangle bunny grid's records,
/// 16 % of courtyard's): deciding that here costs a few integer adds, where its record would
/// cost a write, a bin entry and a walk that writes nothing. The same integers as the walks
/// test, so the buffers are unchanged. No branch per centre: whether a tiny triangle covers
/// a centre is a coin toss for the predictor (with branches this cost more than it saved).
#[inline(always)]
fn covers_no_centre(e: &FixedEyeEdges, rows: (i32, i32)) -> bool {
    let (row_count, col_count) = (rows.1 - rows.0 + 1, e.cols.1 - e.cols.0 + 1);
    if row_count > 2 || col_count > 2 {
        return false;
    }
    // The smallest of the three edge values at each of the box's four centres (the right
    // column and the lower row masked off where the box has one).
    let at = |dx: i64, dy: i64| (0..3).map(|k| e.e0[k] + e.dx[k] * dx + e.dy[k] * dy).fold(i64::MAX, i64::min);
    let (two_cols, two_rows) = (col_count == 2, row_count == 2);
    let covered = (at(0, 0) >= 0)
        | (two_cols & (at(1, 0) >= 0))
        | (two_rows & (at(0, 1) >= 0))
        | (two_cols & two_rows & (at(1, 1) >= 0));
    !covered
}

/// The depth test: a fragment of `prim` at `q` replaces the stored one when nearer (larger
/// `q`), or as near with a smaller id.
#[inline(always)]
fn wins(q: f32, prim: u32, stored_q: f32, stored_prim: u32) -> bool {
    q > stored_q || (q == stored_q && prim < stored_prim)
}

/// Whether a masked triangle's fragment at `(x, y)` is opaque: the tracer's own pixel ray
/// and triangle test give the barycentrics (a ray that misses the triangle, at an edge the
/// two decide differently, counts as transparent).
#[inline(never)]
fn opaque<M: AlphaTest>(view: &EyeView<'_, M>, prim: u32, x: usize, y: usize) -> bool {
    view.pixel_ray(x, y).is_some_and(|r| view.exact_hit(&r, prim).is_some())
}

/// The rows of `rec` that `band` holds, for `eye`, with its columns; `None` when empty.
#[inline(always)]
fn span(rec: &FixedRecord, eye: usize, band: &Band<'_>) -> Option<((i32, i32), (i32, i32))> {
    let (c0, c1) = rec.eyes[eye].cols;
    let (y0, y1) = (rec.rows.0.max(band.rows.start as i32), rec.rows.1.min(band.rows.end as i32 - 1));
    (y0 <= y1 && c0 <= c1).then_some(((c0, c1), (y0, y1)))
}

/// The scalar reference: every pixel of the record's box, one at a time. Returns the masked
/// fragments tested.
fn walk_scalar<M: AlphaTest>(rec: &FixedRecord, eye: usize, view: &EyeView<'_, M>, band: &mut Band<'_>) -> u64 {
    let e = &rec.eyes[eye];
    let Some(((c0, c1), (y0, y1))) = span(rec, eye, band) else { return 0 };
    let mut masked = 0;
    for y in y0..=y1 {
        let dy = i64::from(y - rec.rows.0);
        let q_row = e.qc + e.qb * (y - rec.rows.0) as f32;
        let row = (y as usize - band.rows.start) * band.width;
        for x in c0..=c1 {
            let dx = i64::from(x - c0);
            if (0..3).any(|k| e.e0[k] + e.dy[k] * dy + e.dx[k] * dx < 0) {
                continue;
            }
            let q = q_row + e.qa * (x - c0) as f32;
            let at = row + x as usize;
            if !wins(q, rec.prim, band.q[at], band.prim[at]) {
                continue;
            }
            if rec.masked {
                masked += 1;
                if !opaque(view, rec.prim, x as usize, y as usize) {
                    continue;
                }
            }
            band.q[at] = q;
            band.prim[at] = rec.prim;
        }
    }
    masked
}

/// The columns of row `dy` (rows from the record's first) that can be covered, as offsets from
/// its first column, clamped to `0..width`: where each edge function crosses zero, in f64,
/// widened by a pixel on each side, so every covered pixel is inside (the lanes then test
/// each pixel exactly). `None` when no pixel can be.
#[inline(always)]
fn row_span(e: &FixedEyeEdges, inv_dx: &[f64; 3], dy: i64, width: usize) -> Option<(usize, usize)> {
    let (mut lo, mut hi) = (0.0f64, (width - 1) as f64);
    for k in 0..3 {
        let at = (e.e0[k] + e.dy[k] * dy) as f64;
        match e.dx[k].signum() {
            // E grows to the right: covered from its zero on.
            1 => lo = lo.max(-at * inv_dx[k] - 1.0),
            -1 => hi = hi.min(-at * inv_dx[k] + 1.0),
            // Parallel to the row: all of it or none.
            _ if at < 0.0 => return None,
            _ => {}
        }
    }
    (lo <= hi).then(|| (lo.floor() as usize, hi.ceil().min((width - 1) as f64) as usize))
}

/// The SIMD body: per row, the columns [`row_span`] leaves, eight at a time, each edge's
/// eight integer values as two `i64x4` (exact, as the reference's), the same f32 depth key
/// lane for lane. Identical buffers to [`walk_scalar`], bit for bit.
fn walk_simd<M: AlphaTest>(rec: &FixedRecord, eye: usize, view: &EyeView<'_, M>, band: &mut Band<'_>) -> u64 {
    let e = &rec.eyes[eye];
    if !rec.masked && e.dx.iter().all(|d| d.abs() < NARROW_STEP) {
        let fit = edges_fit_i32(rec, e);
        if fit && e.cols.1 - e.cols.0 < LANES as i32 && e.cols.0 as usize + LANES <= band.width {
            walk_small(rec, eye, band);
        } else if fit {
            walk_narrow::<true>(rec, eye, band);
        } else {
            walk_narrow::<false>(rec, eye, band);
        }
        return 0;
    }
    walk_wide(rec, eye, view, band)
}

/// Steps per pixel below this (edges spanning fewer than 2048 rows) let eight lanes of an
/// edge function live in `i32`: see [`walk_narrow`].
const NARROW_STEP: i64 = 1 << 27;

/// [`walk_simd`] for an opaque record whose edges step by less than [`NARROW_STEP`] per pixel
/// (almost all of them), with no branch per block: eight lanes of each edge function in one
/// `i32x8`. With `FIT` (every value fits `i32`, [`edges_fit_i32`]) the lanes are set once a
/// row and step by one add a block. Otherwise each block's comes from its exact `i64` value
/// clamped to ±2³⁰, which keeps every sign: a value past 2³⁰ stays past 2³⁰ − 7·2²⁷ > 0
/// across the block (likewise below), and values within it are exact. The depth test is a
/// blend and a store, taken or not.
fn walk_narrow<const FIT: bool>(rec: &FixedRecord, eye: usize, band: &mut Band<'_>) {
    let e = &rec.eyes[eye];
    let Some(((c0, c1), (y0, y1))) = span(rec, eye, band) else { return };
    let lane = i32x8::from([0, 1, 2, 3, 4, 5, 6, 7]);
    let lane_dx = e.dx.map(|d| lane * i32x8::splat(d as i32));
    let step = e.dx.map(|d| 8 * d);
    let step_lanes = step.map(|d| i32x8::splat(d as i32));
    let (prim, qa) = (u32x8::splat(rec.prim), F32s::splat(e.qa));
    let (c0, width) = (c0 as usize, (c1 - c0 + 1) as usize);
    // Where each edge crosses row dy, as a linear function of dy (the f64 form of
    // `row_span`, without its per-row products).
    let inv_dx = e.inv_dx();
    let crossing = |k: usize| (-(e.e0[k] as f64) * inv_dx[k], -(e.dy[k] as f64) * inv_dx[k]);
    let crossings = [crossing(0), crossing(1), crossing(2)];
    let last_column = (width - 1) as f64;
    for y in y0..=y1 {
        let dy = i64::from(y - rec.rows.0);
        let (mut lo, mut hi) = (0.0f64, last_column);
        let mut empty = false;
        for k in 0..3 {
            let at = crossings[k].0 + crossings[k].1 * dy as f64;
            match e.dx[k].signum() {
                1 => lo = lo.max(at - 1.0),
                -1 => hi = hi.min(at + 1.0),
                _ => empty |= e.e0[k] + e.dy[k] * dy < 0,
            }
        }
        if empty || !(lo <= hi) {
            continue;
        }
        let (first, last) = (lo.floor() as usize, hi.ceil().min(last_column) as usize);
        let q_row = F32s::splat(e.qc + e.qb * (y - rec.rows.0) as f32);
        let row = (y as usize - band.rows.start) * band.width;
        // Blocks of eight image columns from a multiple of eight: every record's loads and
        // stores of a pixel block then fall on the same 32 bytes (an unaligned load overlapping
        // an earlier unaligned store cannot be forwarded and waits for it).
        let (lo, hi) = (c0 + first, c0 + last);
        let mut bx = lo;
        let edge_at = |bx: usize| -> [i64; 3] {
            core::array::from_fn(|k| e.e0[k] + e.dy[k] * dy + e.dx[k] * (bx as i64 - c0 as i64))
        };
        let mut edge = edge_at(bx);
        let mut lanes: [i32x8; 3] = core::array::from_fn(|k| i32x8::splat(edge[k] as i32) + lane_dx[k]);
        while bx <= hi {
            let q = q_row + (F32s::splat((bx as i64 - c0 as i64) as f32) + lane_offsets()) * qa;
            if bx + LANES > band.width {
                // The image's right border: one lane at a time.
                let (from, to) = (lo.max(bx) - bx, hi - bx + 1);
                let edge = if FIT { edge_at(bx) } else { edge };
                scalar_lanes(rec, e, &edge, q, from..to, &mut band.q[row + bx..], &mut band.prim[row + bx..]);
                break;
            }
            // Negative where a lane is outside any edge.
            let outside = if FIT { lanes[0] | lanes[1] | lanes[2] } else { edge_signs(&edge, &lane_dx) };
            let xs = lane + i32x8::splat(bx as i32);
            let valid = xs.simd_ge(i32x8::splat(lo as i32)) & xs.simd_le(i32x8::splat(hi as i32));
            let covered: u32x8 = bytemuck::cast(valid & outside.simd_ge(i32x8::splat(0)));
            let at = row + bx;
            depth_test_block(band, at, q, prim, covered);
            for k in 0..3 {
                if FIT {
                    lanes[k] += step_lanes[k];
                } else {
                    edge[k] += step[k];
                }
            }
            bx += LANES;
        }
    }
}

/// Whether every edge function value the walks form for `e` (the record's rows, and its
/// columns plus the seven lanes a block may reach past the last) lies strictly within `i32`,
/// so they can keep and step them as `i32` lanes with no clamp. The bound is
/// `|E₀| + |dx|·(columns + 7) + |dy|·rows` per edge, in `i64` (each term is far below 2⁶³ for
/// snapped coordinates under the 2²¹-pixel limit). At 1280×720 nearly every record fits: an
/// edge 8 px wide and 700 rows tall stays near 2³⁰.
#[inline(always)]
fn edges_fit_i32(rec: &FixedRecord, e: &FixedEyeEdges) -> bool {
    let rows = i64::from(rec.rows.1 - rec.rows.0) + 1;
    let columns = i64::from(e.cols.1 - e.cols.0) + 1;
    (0..3).all(|k| {
        e.e0[k].abs() + e.dx[k].abs() * (columns + LANES as i64 - 1) + e.dy[k].abs() * rows < i64::from(i32::MAX)
    })
}

/// [`walk_narrow`] for a record at most eight columns wide that ends at least eight columns
/// before the image's right border and whose edge values fit `i32` ([`edges_fit_i32`]): most
/// of a detailed scene's triangles. One block per row at the record's first column, so a row
/// costs no span; each edge's eight lane values live in one `i32x8` and step by row with one
/// add, exact (nothing overflows, by the bound). Every row is depth-tested, covered or not
/// (its block blended and stored back unchanged when not): whether a small triangle's row
/// covers a pixel centre is a coin toss for the branch predictor, and the mispredictions
/// cost more than the loads and stores they skipped (BENCHMARKS.md).
fn walk_small(rec: &FixedRecord, eye: usize, band: &mut Band<'_>) {
    let e = &rec.eyes[eye];
    let Some(((c0, c1), (y0, y1))) = span(rec, eye, band) else { return };
    let lane = i32x8::from([0, 1, 2, 3, 4, 5, 6, 7]);
    let (prim, qa) = (u32x8::splat(rec.prim), F32s::splat(e.qa));
    // Lanes past the record's last column are never covered.
    let valid = lane.simd_le(i32x8::splat(c1 - c0));
    // The depth key's lanes relative to the row's: the reference's `qa · (x − c0)`.
    let q_lanes = lane_offsets() * qa;
    let first = i64::from(y0 - rec.rows.0);
    let mut edge: [i32x8; 3] = core::array::from_fn(|k| {
        i32x8::splat((e.e0[k] + e.dy[k] * first) as i32) + lane * i32x8::splat(e.dx[k] as i32)
    });
    let step: [i32x8; 3] = core::array::from_fn(|k| i32x8::splat(e.dy[k] as i32));
    let mut row = (y0 as usize - band.rows.start) * band.width + c0 as usize;
    for y in y0..=y1 {
        // Negative where a lane is outside any edge.
        let outside = edge[0] | edge[1] | edge[2];
        let covered = valid & outside.simd_ge(i32x8::splat(0));
        for k in 0..3 {
            edge[k] += step[k];
        }
        let q = F32s::splat(e.qc + e.qb * (y - rec.rows.0) as f32) + q_lanes;
        depth_test_block(band, row, q, prim, bytemuck::cast(covered));
        row += band.width;
    }
}

/// The three edge functions of a block's eight lanes OR-ed together (negative where a lane
/// is outside an edge): each from the block's exact `i64` value clamped to ±2³⁰ plus the lane
/// steps `lane_dx` (at most 7 steps of < [`NARROW_STEP`]), so every sign is exact (see
/// [`walk_narrow`]).
#[inline(always)]
fn edge_signs(edge: &[i64; 3], lane_dx: &[i32x8; 3]) -> i32x8 {
    const LIMIT: i64 = 1 << 30;
    (0..3).fold(i32x8::splat(0), |acc, k| acc | (i32x8::splat(edge[k].clamp(-LIMIT, LIMIT) as i32) + lane_dx[k]))
}

/// The depth test of the eight pixels from plane index `at` (all inside the band's row): the
/// `covered` lanes whose `q` wins ([`wins`], lane for lane) take `q` and `prim`. A blend and a
/// plain store of all eight, taken or not.
#[inline(always)]
fn depth_test_block(band: &mut Band<'_>, at: usize, q: F32s, prim: u32x8, covered: u32x8) {
    let stored_q = hidden(F32s::from(<[f32; LANES]>::try_from(&band.q[at..at + LANES]).expect("8 lanes")));
    let stored_p = hidden(u32x8::from(<[u32; LANES]>::try_from(&band.prim[at..at + LANES]).expect("8 lanes")));
    let nearer: u32x8 = bytemuck::cast(q.simd_gt(stored_q));
    let tie = bytemuck::cast::<F32s, u32x8>(q.simd_eq(stored_q)) & prim.simd_lt(stored_p);
    let wins = covered & (nearer | tie);
    band.q[at..at + LANES].copy_from_slice(&bytemuck::cast::<u32x8, F32s>(wins).select(q, stored_q).to_array());
    band.prim[at..at + LANES].copy_from_slice(&wins.select(prim, stored_p).to_array());
}

/// `v`, hidden from the optimiser (no instruction). The blocks store `select(wins, new,
/// loaded)` back where `loaded` came from, which LLVM turns into a masked store: one
/// instruction, but on Zen 2 a microcoded one that cost a quarter of the fragment walk.
/// Behind this, the blend and a plain store stay.
#[inline(always)]
fn hidden<T: Copy>(v: T) -> T {
    #[cfg(all(target_arch = "x86_64", target_feature = "avx"))]
    if size_of::<T>() == 32 {
        // SAFETY: `T` is a 32-byte vector type (f32x8 or u32x8), moved through a ymm register.
        unsafe {
            let mut r: core::arch::x86_64::__m256 = core::mem::transmute_copy(&v);
            core::arch::asm!("/* {0} */", inout(ymm_reg) r, options(pure, nomem, nostack, preserves_flags));
            return core::mem::transmute_copy(&r);
        }
    }
    v
}

/// The depth test of up to eight lanes of a block one at a time (the image's right border),
/// with the block's exact edge values.
fn scalar_lanes(
    rec: &FixedRecord,
    e: &FixedEyeEdges,
    edge: &[i64; 3],
    q: F32s,
    lanes: core::ops::Range<usize>,
    qs: &mut [f32],
    prims: &mut [u32],
) {
    let q = q.to_array();
    for i in lanes {
        if (0..3).all(|k| edge[k] + e.dx[k] * i as i64 >= 0) && wins(q[i], rec.prim, qs[i], prims[i]) {
            qs[i] = q[i];
            prims[i] = rec.prim;
        }
    }
}

/// [`walk_simd`] for masked records and records with steep edges: two `i64x4` per edge, the
/// covered lanes depth-tested (and alpha-tested) one at a time.
fn walk_wide<M: AlphaTest>(rec: &FixedRecord, eye: usize, view: &EyeView<'_, M>, band: &mut Band<'_>) -> u64 {
    let e = &rec.eyes[eye];
    let Some(((c0, c1), (y0, y1))) = span(rec, eye, band) else { return 0 };
    // Per edge, the lane offsets 0..7 steps to the right, and the step of a block of eight.
    let lanes_lo = |d: i64| i64x4::from([0, d, 2 * d, 3 * d]);
    let lanes_hi = |d: i64| i64x4::from([4 * d, 5 * d, 6 * d, 7 * d]);
    let (lo, hi) = (e.dx.map(lanes_lo), e.dx.map(lanes_hi));
    let prim = u32x8::splat(rec.prim);
    let lane_bits = u32x8::from([1, 2, 4, 8, 16, 32, 64, 128]);
    let width = (c1 - c0 + 1) as usize;
    let inv_dx = e.inv_dx();
    let mut masked = 0;
    for y in y0..=y1 {
        let dy = i64::from(y - rec.rows.0);
        let Some((first, last)) = row_span(e, &inv_dx, dy, width) else { continue };
        let q_row = e.qc + e.qb * (y - rec.rows.0) as f32;
        let row = (y as usize - band.rows.start) * band.width;
        let mut edge: [i64; 3] = core::array::from_fn(|k| e.e0[k] + e.dy[k] * dy + e.dx[k] * first as i64);
        let width = last + 1;
        let mut block = first;
        while block < width {
            // Lane i is column c0 + block + i; its edge values, OR-ed: the sign bit is set
            // where any edge function is negative (not covered).
            let mut out_lo = i64x4::splat(0);
            let mut out_hi = i64x4::splat(0);
            for k in 0..3 {
                let base = i64x4::splat(edge[k]);
                out_lo |= base + lo[k];
                out_hi |= base + hi[k];
                edge[k] += 8 * e.dx[k];
            }
            let outside = out_lo.to_bitmask() | (out_hi.to_bitmask() << 4);
            let lanes = (width - block).min(LANES);
            let mut covered = !outside & ((1u32 << lanes) - 1);
            if covered != 0 {
                // (x − c0) as f32 times qa, as the reference: exact lane offsets plus the
                // block's exact start, then one product and one sum.
                let xf = F32s::splat(block as f32) + lane_offsets();
                let q = F32s::splat(q_row) + xf * F32s::splat(e.qa);
                let at = row + c0 as usize + block;
                // Eight lanes' worth of buffer to the image's right border: one vector test
                // (lanes past the span are out of `covered`).
                if c0 as usize + block + LANES <= band.width && !rec.masked {
                    let stored_q = F32s::from(<[f32; LANES]>::try_from(&band.q[at..at + LANES]).expect("8 lanes"));
                    let stored_p = u32x8::from(<[u32; LANES]>::try_from(&band.prim[at..at + LANES]).expect("8 lanes"));
                    let nearer: u32x8 = bytemuck::cast(q.simd_gt(stored_q));
                    let tie = bytemuck::cast::<F32s, u32x8>(q.simd_eq(stored_q)) & prim.simd_lt(stored_p);
                    let lanes_covered = (u32x8::splat(covered) & lane_bits).simd_ne(u32x8::ZERO);
                    let wins = lanes_covered & (nearer | tie);
                    if wins.any() {
                        let new_q = bytemuck::cast::<u32x8, F32s>(wins).select(q, stored_q);
                        let new_p = wins.select(prim, stored_p);
                        band.q[at..at + LANES].copy_from_slice(&new_q.to_array());
                        band.prim[at..at + LANES].copy_from_slice(&new_p.to_array());
                    }
                } else {
                    let qs = q.to_array();
                    while covered != 0 {
                        let i = covered.trailing_zeros() as usize;
                        covered &= covered - 1;
                        let (qi, ati) = (qs[i], at + i);
                        if !wins(qi, rec.prim, band.q[ati], band.prim[ati]) {
                            continue;
                        }
                        if rec.masked {
                            masked += 1;
                            let x = c0 as usize + block + i;
                            if !opaque(view, rec.prim, x, y as usize) {
                                continue;
                            }
                        }
                        band.q[ati] = qi;
                        band.prim[ati] = rec.prim;
                    }
                }
            }
            block += LANES;
        }
    }
    masked
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clipping_keeps_the_inside_and_adds_the_crossings() {
        let mut poly = [[0.0; 3]; MAX_POLYGON];
        poly[..3].copy_from_slice(&[[0.0, 0.0, -1.0], [1.0, 0.0, 1.0], [0.0, 1.0, 1.0]]);
        let n = clip_polygon(&mut poly, 3, |c| c[2]);
        assert_eq!(n, 4);
        assert!(poly[..n].iter().all(|c| c[2] >= 0.0));
        assert!(poly[..n].contains(&[0.5, 0.0, 0.0]) && poly[..n].contains(&[0.0, 0.5, 0.0]));
    }

    /// A 1280×720 pair looking down −z with a 90° field of view, the right eye 6.5 cm to the
    /// right, its centre away from the origin (so the f64 differences are not trivial).
    fn rig() -> Projection {
        Projection {
            centre: [3.25, -1.5, 7.0],
            rx: [1.0, 0.0, 0.0],
            ry: [0.0, 1.0, 0.0],
            rw: [0.0, 0.0, -1.0],
            right_offset: [-0.065, 1e-9, -2e-9],
            hw: 640.0,
            hh: 360.0,
            ray_slack: 0.0,
            px_per_radian: 1500.0,
            m_inv: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -1.0]],
            centre_offset: [0.065, 0.0, 0.0],
            width: 1280,
            height: 720,
        }
    }

    /// The four-wide setup against the scalar one, triangle by triangle: the same records
    /// (bit for bit) and the same "clipped" count, on seeded random triangles around the
    /// eye (in front, behind, across the near plane, far off screen) and on edge cases:
    /// vertices on half-subpixel positions (the rounding's ties), non-finite and collinear
    /// vertices, a vertex past the guard band, a triangle exactly on the near plane. Tiny
    /// triangles, some with vertices on pixel centres and corners, hold the four-wide cull of
    /// those that cover no centre to `record`'s (it fails when a centre on an owned edge
    /// counts as outside, or the fill rule is mirrored).
    #[test]
    fn the_four_wide_setup_makes_the_scalar_setups_records() {
        let p = rig();
        let near = 1e-3f32;
        let mut rng = crate::synth::Rng::new(0x5e7_0f0);
        let mut tris: Vec<[f32; 9]> = Vec::new();
        let c = p.centre;
        for _ in 0..4000 {
            // A centre in front of, beside or behind the eye, and a size from sub-pixel to huge.
            let z = rng.range(-3.0, 40.0);
            let spread = [0.001, 0.05, 1.0, 30.0][rng.below(4)];
            let at = [rng.range(-1.2, 1.2) * z.abs(), rng.range(-0.7, 0.7) * z.abs(), -z];
            tris.push(core::array::from_fn(|i| c[i % 3] + at[i % 3] + rng.range(-spread, spread)));
        }
        // Tiny triangles on screen, a tenth of a pixel to two pixels across (at w = z, a
        // pixel is z / 640): most cover no pixel centre, and the four-wide setup culls them.
        let tiny_from = tris.len();
        for _ in 0..4000 {
            let z = rng.range(2.0, 10.0);
            let spread = z / 640.0 * [0.1, 0.5, 1.0, 2.0][rng.below(4)];
            let at = [rng.range(-0.9, 0.9) * z, rng.range(-0.5, 0.5) * z, -z];
            tris.push(core::array::from_fn(|i| c[i % 3] + at[i % 3] + rng.range(-spread, spread)));
        }
        // And tiny triangles with their vertices on pixel centres and corners (at w = 2), so
        // that centres fall exactly on edges and the fill rule decides.
        for _ in 0..4000 {
            let (i, j) = (rng.below(1200) as f32 + 20.0, rng.below(680) as f32 + 20.0);
            let corner = |rng: &mut crate::synth::Rng| {
                let (sx, sy) = (i + 0.5 * rng.below(5) as f32, j + 0.5 * rng.below(5) as f32);
                [c[0] + (sx - 640.0) / 640.0 * 2.0, c[1] - (sy - 360.0) / 360.0 * 2.0, c[2] - 2.0]
            };
            let (a, b, d) = (corner(&mut rng), corner(&mut rng), corner(&mut rng));
            tris.push([a[0], a[1], a[2], b[0], b[1], b[2], d[0], d[1], d[2]]);
        }
        let tiny = tiny_from..tris.len();
        // Vertices whose screen x lands exactly on k + 1/512 px (a tie of the 1/256 snap):
        // x_screen = X/w · 640 + 640 with w = 2.
        let tie = |k: f32| (k + 1.0 / 512.0 - 640.0) / 640.0 * 2.0;
        for k in [100.0, 101.0, 640.0, -3.0] {
            tris.push([
                c[0] + tie(k),
                c[1],
                c[2] - 2.0,
                c[0] + tie(k + 5.0),
                c[1] + 0.3,
                c[2] - 2.0,
                c[0] - tie(k),
                c[1] - 0.2,
                c[2] - 2.0,
            ]);
        }
        let front = |x: f32, y: f32, z: f32| [c[0] + x, c[1] + y, c[2] - z];
        let tri = |a: [f32; 3], b: [f32; 3], d: [f32; 3]| [a[0], a[1], a[2], b[0], b[1], b[2], d[0], d[1], d[2]];
        tris.push(tri(front(f32::NAN, 0.0, 2.0), front(1.0, 0.0, 2.0), front(0.0, 1.0, 2.0)));
        tris.push(tri(front(f32::INFINITY, 0.0, 2.0), front(1.0, 0.0, 2.0), front(0.0, 1.0, 2.0)));
        tris.push(tri(front(0.0, 0.0, 2.0), front(1.0, 1.0, 2.0), front(2.0, 2.0, 2.0)));
        tris.push(tri(front(0.0, 0.0, 2.0), front(1e7, 0.0, 2.0), front(0.0, 1.0, 2.0)));
        tris.push(tri(front(0.0, 0.0, near), front(1.0, 0.0, near), front(0.0, 1.0, near)));
        tris.push(tri(front(0.0, 0.0, 1.0), front(1.0, 0.0, -1.0), front(0.0, 1.0, 1.0)));
        while !tris.len().is_multiple_of(4) {
            tris.push(tris[tris.len() % 7]);
        }
        let near64 = both_eyes_near(&p, near);
        let (mut kinds, mut snapped, mut tiny_culled) = ([0usize; 4], [[Snapped::default(); 3]; 4], 0);
        let (mut four_points, mut covered_points) = (FourPoints::default(), 0);
        for (group, four) in tris.chunks_exact(4).enumerate() {
            let ts = [&four[0], &four[1], &four[2], &four[3]];
            // Every other group as cut-out (no points), so both kinds of lanes are met.
            let opaque = if group % 2 == 0 { 0b1111 } else { 0 };
            let (culled, simple, pointed) = setup_four(ts, &p, near64, || opaque, &mut snapped, &mut four_points);
            for lane in 0..4 {
                let prim = (group * 4 + lane) as u32;
                let mut want = Vec::new();
                let clipped =
                    setup_triangle(ts[lane], prim, &p, near, &mut SetupOut { records: &mut want, points: None });
                if pointed >> lane & 1 != 0 {
                    // The scalar setup with points makes the same points and no record.
                    kinds[3] += 1;
                    let (mut records, mut points, mut got) = (Vec::new(), Vec::new(), Vec::new());
                    let mut out = SetupOut { records: &mut records, points: Some(&mut points) };
                    assert!(!setup_triangle(ts[lane], prim, &p, near, &mut out), "triangle {prim}");
                    four_points.push(lane, prim, &mut got);
                    assert!(records.is_empty(), "triangle {prim}: records {records:?}");
                    assert_eq!(got, points, "triangle {prim}: {:?}", ts[lane]);
                    covered_points += got.len();
                    assert_eq!(opaque >> lane & 1, 1, "a cut-out triangle's lane made points");
                } else if simple >> lane & 1 != 0 {
                    kinds[0] += 1;
                    let mut got = Vec::new();
                    record(&snapped[lane], prim, &p, [true; 2], &mut SetupOut { records: &mut got, points: None });
                    assert_eq!((got, false), (want, clipped), "triangle {prim}: {:?}", ts[lane]);
                } else if culled >> lane & 1 != 0 {
                    kinds[1] += 1;
                    tiny_culled += usize::from(tiny.contains(&(prim as usize)));
                    assert_eq!((want.len(), clipped), (0, false), "triangle {prim} culled: {:?}", ts[lane]);
                } else {
                    kinds[2] += 1;
                }
            }
        }
        // Every kind of lane was met, or the comparison proved little.
        assert!(kinds.iter().all(|&k| k > 50), "simple, culled, left to the scalar setup, points: {kinds:?}");
        assert!(covered_points > 1000, "points made by the four-wide setup: {covered_points}");
        assert!(tiny_culled > 1000, "tiny triangles culled for covering no centre: {tiny_culled}");
    }

    /// The setup's cull of tiny triangles that cover no pixel centre, held to the walk: on
    /// seeded random triangles from a tenth of a pixel to three pixels across (every snapped
    /// position, so centres fall on edges and corners, both windings, slivers), an eye is
    /// dropped exactly where walking its record without the cull covers nothing and its box
    /// is at most 2×2 centres, and every eye kept is the record without the cull, bit for
    /// bit. With points, every such small eye is instead the pixels its walk wrote (place and
    /// depth key, bit for bit), and larger eyes keep their records.
    #[test]
    fn tiny_triangles_that_cover_no_centre_get_no_record_and_the_rest_points() {
        let p = rig();
        let mut rng = crate::synth::Rng::new(0x71_4e);
        let (mut dropped, mut kept_small, mut covering, mut points_checked) = (0, 0, 0, 0);
        let (w, h) = (p.width as usize, p.height as usize);
        let (mut prim_plane, mut q_plane) = (vec![NO_PRIM; w * h], vec![0.0f32; w * h]);
        for prim in 0..20_000u32 {
            let size = [26, 64, 256, 768][rng.below(4)] as i64;
            // Near pixel centres and corners alike: any 1/256 position.
            let base = [
                rng.below(1200) as i64 * ONE + rng.below(256) as i64,
                rng.below(700) as i64 * ONE + rng.below(256) as i64,
            ];
            let disparity = rng.below(3 * ONE as usize) as i64;
            let v: [Snapped; 3] = core::array::from_fn(|_| {
                let (x, y) = (base[0] + rng.below(size as usize) as i64, base[1] + rng.below(size as usize) as i64);
                let q = f64::from(rng.range(0.1, 1.0));
                Snapped { x: [x, x - disparity], y: [y, y], q: [q, q] }
            });
            let (mut with, mut without, mut pointed, mut points) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
            record_culling::<true>(&v, prim, &p, [true; 2], &mut SetupOut { records: &mut with, points: None });
            record_culling::<false>(&v, prim, &p, [true; 2], &mut SetupOut { records: &mut without, points: None });
            let mut out = SetupOut { records: &mut pointed, points: Some(&mut points) };
            record_culling::<true>(&v, prim, &p, [true; 2], &mut out);
            let Some(full) = without.first() else {
                assert!(
                    with.is_empty() && pointed.is_empty() && points.is_empty(),
                    "triangle {prim}: work where none was"
                );
                continue;
            };
            for eye in 0..2 {
                if !full.visible_in(eye) {
                    assert!(with.first().is_none_or(|r| !r.visible_in(eye)), "triangle {prim} eye {eye}");
                    continue;
                }
                let e = &full.eyes[eye];
                assert!(edges_fit_i32(full, e) && e.cols.0 as usize + LANES <= w, "a small record");
                let rows = full.rows.0 as usize..full.rows.1 as usize + 1;
                let mut band = Band {
                    prim: &mut prim_plane[rows.start * w..rows.end * w],
                    q: &mut q_plane[rows.start * w..rows.end * w],
                    width: w,
                    rows: rows.clone(),
                };
                walk_small(full, eye, &mut band);
                let covers = band.prim.contains(&prim);
                let small = full.rows.1 - full.rows.0 < 2 && e.cols.1 - e.cols.0 < 2;
                // With points, a small eye is its covered centres, as the walk wrote them
                // (depth keys bit for bit), and no record; a larger one, its record.
                let eye_points: Vec<_> = points.iter().filter(|t| (t.eye_x >> 31) as usize == eye).collect();
                if small {
                    assert!(pointed.first().is_none_or(|r| !r.visible_in(eye)), "triangle {prim} eye {eye}");
                    let written: Vec<_> = (0..band.prim.len()).filter(|&i| band.prim[i] == prim).collect();
                    assert_eq!(eye_points.len(), written.len(), "triangle {prim} eye {eye}: points");
                    for (t, &i) in eye_points.iter().zip(&written) {
                        let (x, y) = ((t.eye_x & !(1 << 31)) as usize, t.y as usize - rows.start);
                        assert_eq!((y * w + x, t.q.to_bits()), (i, band.q[i].to_bits()), "triangle {prim} eye {eye}");
                    }
                    points_checked += eye_points.len();
                } else {
                    assert!(eye_points.is_empty() && pointed[0].eyes[eye] == *e, "triangle {prim} eye {eye}");
                }
                band.prim.fill(NO_PRIM);
                band.q.fill(0.0);
                let kept = with.first().is_some_and(|r| r.visible_in(eye));
                assert_eq!(kept, covers || !small, "triangle {prim} eye {eye}: {v:?}");
                if kept {
                    assert_eq!(with[0].eyes[eye], *e, "triangle {prim} eye {eye}: the record kept");
                    assert_eq!((with[0].rows, with[0].prim), (full.rows, full.prim));
                    kept_small += usize::from(small);
                    covering += usize::from(covers);
                } else {
                    dropped += 1;
                }
            }
        }
        // Both outcomes, often, or the comparison proved little.
        assert!(dropped > 2000 && kept_small > 2000 && covering > 2000, "{dropped} {kept_small} {covering}");
        assert!(points_checked > 2000, "{points_checked}");
    }
}
