//! The fused f32x8 kernel.
//!
//! Work unit: a *tile* of at most [`BLOCK_ROWS`] rows × [`TILE`] columns of output voxels
//! (all three channels). For each input row the tile needs (its rows ± 5, clamped), the row
//! segment (columns ± [`PAD`]; borrowed from the images, or copied with replicate clamping
//! at the image borders) is sanitised (unusable samples become NaN, which then poisons
//! exactly the windows that contain them), turned into the four product planes `x'`, `y'`,
//! `x'² + y'²`, `(d − s_d)²` (with `x' = x − s`, `d = x − y`), and filtered horizontally into
//! one slot of a ring of 11 rows. As soon as an output row's 11 input rows are in the ring,
//! the vertical pass, the channel mixing, the map and the accumulation run for it. Scratch
//! is about 46 KB per band, on the stack; the ring (33 KB) and the planes stay in L1/L2.
//!
//! Every loop over a tile row runs over the whole tile (constant trip counts, so no bounds
//! checks survive). Tail strategy: a padded lane array. The lanes beyond the image width read
//! replicate-clamped pixels (finite work) and are masked out of the sums.
//!
//! Tried and measured choices are recorded next to the constants.

use wide::f64x4;

use super::{
    C1, C2, MAX_SAMPLE, Partial, RADIUS, REFINE_THRESHOLD, SsimParams, SsimResult, SsimVariant, TAPS,
    channel_mixing_matrix, exact_voxel, gaussian_weights, usable,
};
use crate::bands::{SharedRows, for_each_band};
use crate::frame::{PlaneMut, RgbPlanes};
use crate::simd::{F32s, LANES, lane_offsets, load, store};

/// Output columns per tile: a multiple of [`LANES`] and at most 64 (pending voxels are one
/// `u64` bit mask per row and channel). The ring is `11 × 3 × 4 × TILE` floats: 33 KB.
pub(super) const TILE: usize = 64;
/// Output rows per tile (and per local shift).
pub(super) const BLOCK_ROWS: usize = 64;
/// Columns of halo on each side of a row segment: at least [`RADIUS`], a multiple of
/// [`LANES`] so that the segment's interior starts on a vector.
const PAD: usize = 8;
const SEG: usize = TILE + 2 * PAD;
/// Product planes per channel: `x'`, `y'`, `x'² + y'²`, `(d − s_d)²`.
const PLANES: usize = 4;
/// At most this many parallel bands (their partial sums live on the caller's stack and are
/// added in order).
const MAX_BANDS: usize = 256;
/// Shifted passes over a tile before the exact fallback.
const PASSES: usize = 3;
/// Rows ahead that [`run_pass`] prefetches.
const PREFETCH_ROWS: usize = 2;
/// Typical rounding error of a cancelled f32 statistic (`σ² = E[x'²] − μ'²`), in units of
/// the roundoff `u = 2⁻²⁴` times the cancelled magnitude. Used for the refinement test; on the
/// calibration images of the tests the measured errors stay within 2× of this estimate.
const ERROR_UNITS: f64 = 4.0;
/// Worst-case bound of the same error (two 11-tap passes with ~8 rounded additions each on
/// `E[x'²]`, twice that on `μ'²` through the square): used where underestimating the
/// error would let a wrong `σ²` vouch for itself.
const BOUND_UNITS: f64 = 64.0;

/// Splatted constants.
struct Consts {
    /// `w[k]`: the weight at offsets ±k.
    w: [F32s; RADIUS + 1],
    m: [[F32s; 3]; 3],
    c1: F32s,
    c2: F32s,
    /// Refine where `num > limit · den` (see [`map`]).
    limit: F32s,
    limit_lum: F32s,
    limit_f64: f64,
    limit_lum_f64: f64,
    /// Worst-case relative error of a cancelled statistic ([`BOUND_UNITS`]).
    bound: F32s,
}

impl Consts {
    fn new() -> Self {
        let g = gaussian_weights();
        let m = channel_mixing_matrix();
        let unit = f64::from(f32::EPSILON) / 2.0;
        // Half of the threshold for each term (see [`map`]).
        let limit = REFINE_THRESHOLD / 2.0 / (ERROR_UNITS * unit);
        let limit_lum = REFINE_THRESHOLD / 2.0 / (6.0 * ERROR_UNITS * unit);
        Self {
            w: core::array::from_fn(|k| F32s::splat(g[RADIUS + k] as f32)),
            m: m.map(|row| row.map(|v| F32s::splat(v as f32))),
            c1: F32s::splat(C1 as f32),
            c2: F32s::splat(C2 as f32),
            limit: F32s::splat(limit as f32),
            limit_lum: F32s::splat(limit_lum as f32),
            limit_f64: limit,
            limit_lum_f64: limit_lum,
            bound: F32s::splat((BOUND_UNITS * unit) as f32),
        }
    }
}

/// Per-tile, per-channel shifts: `x' = x − s`, `d' = d − sd`.
#[derive(Clone, Copy, Debug, Default)]
struct Shifts {
    s: [f32; 3],
    sd: [f32; 3],
}

#[derive(Clone, Copy)]
struct Tile {
    r0: usize,
    r1: usize,
    c0: usize,
    c1: usize,
    /// Vectors per row.
    nv: usize,
}

struct Ctx<'a> {
    a: &'a RgbPlanes<'a>,
    b: &'a RgbPlanes<'a>,
    variant: SsimVariant,
    width: usize,
    height: usize,
    k: Consts,
}

struct Scratch {
    /// Row segments: `[image][channel][column − (c0 − PAD)]`.
    seg: [[[f32; SEG]; 3]; 2],
    /// Products: `[channel][plane][column − (c0 − PAD)]`.
    prod: [[[f32; SEG]; PLANES]; 3],
    /// Horizontally filtered rows: `[row % 11][channel][plane][column − c0]`.
    ring: [[[[f32; TILE]; PLANES]; 3]; TAPS],
    /// Vertically filtered statistics of the current output row: `[channel][plane][column − c0]`.
    vbuf: [[[f32; TILE]; PLANES]; 3],
    /// Voxels still to be computed after a pass: `[row − r0][channel]`, bit = column − c0.
    pending: [[u64; 3]; BLOCK_ROWS],
}

impl Scratch {
    fn new() -> Self {
        Self {
            seg: [[[0.0; SEG]; 3]; 2],
            prod: [[[0.0; SEG]; PLANES]; 3],
            ring: [[[[0.0; TILE]; PLANES]; 3]; TAPS],
            vbuf: [[[0.0; TILE]; PLANES]; 3],
            pending: [[0; 3]; BLOCK_ROWS],
        }
    }
}

/// f64 sums of one tile, vector-wide until the tile ends.
#[derive(Default)]
struct Sums {
    sum: [f64x4; 3],
    count: [u64; 3],
    sq: f64x4,
    sq_n: u64,
    non_finite: u64,
    refined: u64,
}

impl Sums {
    fn add_into(&self, p: &mut Partial) {
        for c in 0..3 {
            p.sum[c] += self.sum[c].reduce_add();
            p.count[c] += self.count[c];
        }
        p.sq += self.sq.reduce_add();
        p.sq_n += self.sq_n;
        p.non_finite += self.non_finite;
        p.refined += self.refined;
    }
}

#[inline(always)]
fn widen_add(acc: &mut f64x4, v: F32s) {
    let a = v.to_array();
    *acc += f64x4::new([a[0] as f64, a[1] as f64, a[2] as f64, a[3] as f64]);
    *acc += f64x4::new([a[4] as f64, a[5] as f64, a[6] as f64, a[7] as f64]);
}

/// All-ones lanes for the set bits of `bits` (bit i = lane i).
#[inline(always)]
fn bits_mask(bits: u32) -> F32s {
    let lane = F32s::from(core::array::from_fn::<f32, LANES, _>(|i| if bits >> i & 1 == 1 { 1.0 } else { 0.0 }));
    lane.simd_eq(F32s::ONE)
}

#[inline(always)]
fn count(mask: F32s) -> u32 {
    mask.to_bitmask().count_ones()
}

pub(super) fn run(a: &RgbPlanes<'_>, b: &RgbPlanes<'_>, params: &SsimParams) -> SsimResult {
    let (width, height) = (a.extent().width(), a.extent().height());
    let band_rows = params.band_rows.max(1).max(height.div_ceil(MAX_BANDS));
    let bands = height.div_ceil(band_rows);
    let ctx = Ctx { a, b, variant: params.variant, width, height, k: Consts::new() };
    let mut slots = [Partial::default(); MAX_BANDS];
    {
        // One slot per band, written by that band only (so the sums are added in a fixed
        // order afterwards, whatever the thread count).
        let plane = PlaneMut::packed(&mut slots[..bands], 1, bands).expect("1 × bands is a valid extent");
        let shared = SharedRows::new(plane);
        for_each_band(
            height,
            band_rows,
            |rows| {
                let band = rows.start / band_rows;
                let partial = band_sums(&ctx, rows);
                // SAFETY: `for_each_band` runs every band once, so slot `band` has one writer.
                let slot = unsafe { shared.row(band) };
                slot[0] = partial;
            },
            |(), ()| (),
        );
    }
    slots[..bands].iter().fold(Partial::default(), |acc, p| acc.merged(p)).finish(params.variant)
}

fn band_sums(ctx: &Ctx<'_>, rows: core::ops::Range<usize>) -> Partial {
    let mut p = Partial::default();
    let mut s = Scratch::new();
    let mut r0 = rows.start;
    while r0 < rows.end {
        let r1 = (r0 + BLOCK_ROWS).min(rows.end);
        let mut c0 = 0;
        while c0 < ctx.width {
            let c1 = (c0 + TILE).min(ctx.width);
            tile(ctx, &mut s, &Tile { r0, r1, c0, c1, nv: (c1 - c0).div_ceil(LANES) }, &mut p);
            c0 = c1;
        }
        r0 = r1;
    }
    p
}

fn median(v: &mut [f32]) -> f32 {
    v.sort_unstable_by(f32::total_cmp);
    match v.len() {
        0 => 0.0,
        n if n % 2 == 1 => v[n / 2],
        // Written symmetrically so that negating every sample negates the median exactly.
        n => (v[n / 2 - 1] + v[n / 2]) * 0.5,
    }
}

/// The first pass's shifts: per channel, the median of `(x + y)/2` and of `x − y` over a
/// 3×3 grid of the tile's usable samples.
fn initial_shifts(ctx: &Ctx<'_>, t: &Tile) -> Shifts {
    let rows = [t.r0, (t.r0 + t.r1 - 1) / 2, t.r1 - 1];
    let cols = [t.c0, (t.c0 + t.c1 - 1) / 2, t.c1 - 1];
    let mut sh = Shifts::default();
    for (c, (pa, pb)) in ctx.a.channels().iter().zip(ctx.b.channels().iter()).enumerate() {
        let (mut lv, mut dv) = ([0.0f32; 9], [0.0f32; 9]);
        let mut n = 0;
        for &y in &rows {
            for &x in &cols {
                let (u, v) = (pa.get(x, y), pb.get(x, y));
                if usable(u) && usable(v) {
                    lv[n] = (u + v) * 0.5;
                    dv[n] = u - v;
                    n += 1;
                }
            }
        }
        sh.s[c] = median(&mut lv[..n]);
        sh.sd[c] = median(&mut dv[..n]);
    }
    sh
}

fn tile(ctx: &Ctx<'_>, s: &mut Scratch, t: &Tile, p: &mut Partial) {
    let rows = t.r1 - t.r0;
    s.pending[..rows].iter_mut().for_each(|r| *r = [0; 3]);
    let mut sums = Sums::default();
    let mut shifts = initial_shifts(ctx, t);
    let mut left = true;
    for pass in 0..PASSES {
        match run_pass(ctx, s, t, pass, &shifts, &mut sums) {
            Some(next) => shifts = next,
            None => {
                left = false;
                break;
            }
        }
    }
    sums.add_into(p);
    if left {
        // Still ill-conditioned after every shift: the exact f64 window formula.
        for (i, row) in s.pending[..rows].iter().enumerate() {
            for (c, &bits) in row.iter().enumerate() {
                let mut bits = bits;
                while bits != 0 {
                    let col = bits.trailing_zeros() as usize;
                    bits &= bits - 1;
                    if let Some(v) = exact_voxel(ctx.a, ctx.b, ctx.variant, t.c0 + col, t.r0 + i, c) {
                        p.sum[c] += v;
                        p.count[c] += 1;
                        p.refined += 1;
                    }
                }
            }
        }
    }
}

/// The worst ill-conditioned voxel seen in a pass, per channel, and the local levels there.
struct Worst {
    score: [f64; 3],
    /// `(μx + μy)/2` of every channel at the worst voxel of channel `c`.
    level: [[f32; 3]; 3],
    /// `μx − μy` of every channel there.
    diff: [[f32; 3]; 3],
}

impl Worst {
    fn new() -> Self {
        Self { score: [-1.0; 3], level: [[0.0; 3]; 3], diff: [[0.0; 3]; 3] }
    }

    /// Shifts for the next pass, or `None` if nothing is pending.
    fn next(&self, variant: SsimVariant, current: &Shifts) -> Option<Shifts> {
        let worst = (0..3).fold(0, |best, c| if self.score[c] > self.score[best] { c } else { best });
        if self.score[worst] < 0.0 {
            return None;
        }
        Some(match variant {
            // A 3-D voxel depends on every channel's shift: take all three from the worst.
            SsimVariant::Volume => Shifts { s: self.level[worst], sd: self.diff[worst] },
            SsimVariant::PerChannel => {
                let mut next = *current;
                for c in 0..3 {
                    if self.score[c] >= 0.0 {
                        next.s[c] = self.level[c][c];
                        next.sd[c] = self.diff[c][c];
                    }
                }
                next
            }
        })
    }
}

/// One pass over a tile. Pass 0 considers every voxel; later passes only the pending ones.
/// Returns the shifts for the next pass if voxels are still pending.
fn run_pass(ctx: &Ctx<'_>, s: &mut Scratch, t: &Tile, pass: usize, shifts: &Shifts, sums: &mut Sums) -> Option<Shifts> {
    let first = t.r0.saturating_sub(RADIUS);
    let last = (t.r1 + RADIUS).min(ctx.height);
    let mut next_out = t.r0;
    let mut worst = Worst::new();
    for y in first..last {
        // The tile's rows are 5 KB apart in each of six planes: without a hint every row
        // segment waits for memory (measured: 16% of the time in the copy).
        if y + PREFETCH_ROWS < last {
            prefetch_segment(ctx, t.c0, y + PREFETCH_ROWS);
        } else if t.c1 < ctx.width {
            prefetch_segment(ctx, t.c1, first + (y + PREFETCH_ROWS - last));
        }
        let src = segment(ctx, &mut s.seg, t.c0, y);
        if pass == 0 && (t.r0..t.r1).contains(&y) {
            products::<true>(&mut s.prod, &src, shifts, t, sums);
        } else {
            products::<false>(&mut s.prod, &src, shifts, t, sums);
        }
        horizontal(&ctx.k, s, y % TAPS);
        while next_out < t.r1 && (next_out + RADIUS).min(ctx.height - 1) <= y {
            emit_row(ctx, s, t, pass, shifts, next_out, sums, &mut worst);
            next_out += 1;
        }
    }
    worst.next(ctx.variant, shifts)
}

/// Hints the row segment of row `y` starting at column `c0` into the cache.
#[inline(always)]
fn prefetch_segment(ctx: &Ctx<'_>, c0: usize, y: usize) {
    for planes in [ctx.a, ctx.b] {
        for plane in planes.channels() {
            let row = plane.row(y);
            let end = (c0 + TILE + PAD).min(row.len());
            let mut i = c0.saturating_sub(PAD);
            while i < end {
                prefetch(&row[i]);
                i += 64 / size_of::<f32>();
            }
            prefetch(&row[end - 1]);
        }
    }
}

#[inline(always)]
fn prefetch(v: &f32) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: SSE is part of the x86-64 baseline, and a prefetch is a hint: it never faults
    // and changes nothing the program can observe.
    unsafe {
        core::arch::x86_64::_mm_prefetch::<{ core::arch::x86_64::_MM_HINT_T0 }>((v as *const f32).cast::<i8>());
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = v;
}

/// Row `y` of every plane, columns `c0 − PAD ‥ c0 + TILE + PAD`: borrowed from the images
/// for interior tiles, copied with replicate clamping into `seg` at the borders. (Copying
/// every segment cost 7%: six small `memcpy` calls per row.)
#[inline(always)]
fn segment<'s>(ctx: &Ctx<'s>, seg: &'s mut [[[f32; SEG]; 3]; 2], c0: usize, y: usize) -> [[&'s [f32; SEG]; 3]; 2] {
    let rows = [ctx.a, ctx.b].map(|p| p.channels().map(|c| c.row(y)));
    if c0 >= PAD && c0 - PAD + SEG <= ctx.width {
        return rows.map(|img| img.map(|row| row[c0 - PAD..c0 - PAD + SEG].try_into().expect("SEG elements")));
    }
    let start = c0 as isize - PAD as isize;
    // Segment indices [lo, hi) hold in-image columns; lo ≤ PAD < hi because c0 < width.
    let lo = (-start).max(0) as usize;
    let hi = (ctx.width as isize - start).min(SEG as isize) as usize;
    for (img, planes) in rows.iter().enumerate() {
        for (c, row) in planes.iter().enumerate() {
            let dst = &mut seg[img][c];
            dst[lo..hi].copy_from_slice(&row[(start + lo as isize) as usize..(start + hi as isize) as usize]);
            dst[..lo].fill(row[0]);
            dst[hi..].fill(row[ctx.width - 1]);
        }
    }
    let [x, y] = seg;
    [[&x[0], &x[1], &x[2]], [&y[0], &y[1], &y[2]]]
}

/// Sanitises the segment and writes the four product planes (the whole segment: constant
/// trip counts let the compiler drop every bounds check). With `COUNT`, also adds the
/// tile's own columns of this row to the RMSE sums and the unusable-sample counts (a
/// separate pass over the row cost 4%).
#[inline(always)]
fn products<const COUNT: bool>(
    prod: &mut [[[f32; SEG]; PLANES]; 3],
    src: &[[&[f32; SEG]; 3]; 2],
    sh: &Shifts,
    t: &Tile,
    sums: &mut Sums,
) {
    let max = F32s::splat(MAX_SAMPLE);
    let nan = F32s::splat(f32::NAN);
    let mut sq = F32s::ZERO;
    let own = PAD / LANES..PAD / LANES + t.nv;
    for c in 0..3 {
        let shift = F32s::splat(sh.s[c]);
        let dshift = F32s::splat(sh.sd[c]);
        let (xs, ys) = (src[0][c], src[1][c]);
        let [px, py, ps, pd] = &mut prod[c];
        for v in 0..SEG / LANES {
            let i = v * LANES;
            let (x, y) = (load(xs, i), load(ys, i));
            // `abs ≤ MAX` is false for NaN: every unusable sample becomes NaN.
            let (ux, uy) = (x.abs().simd_le(max), y.abs().simd_le(max));
            let x = ux.select(x, nan);
            let y = uy.select(y, nan);
            let d = x - y;
            let (xp, yp) = (x - shift, y - shift);
            let dp = d - dshift;
            store(px, i, xp);
            store(py, i, yp);
            store(ps, i, xp * xp + yp * yp);
            store(pd, i, dp * dp);
            if COUNT && own.contains(&v) {
                let inside = lanes(t, v - PAD / LANES);
                let both = ux & uy & inside;
                sums.non_finite += u64::from(count(!ux & inside) + count(!uy & inside));
                sums.sq_n += u64::from(count(both));
                // At most 24 terms per lane in f32 before the f64 sum: relative error ≤ 1.5e-6.
                sq += both.select(d * d, F32s::ZERO);
            }
        }
    }
    if COUNT {
        widen_add(&mut sums.sq, sq);
    }
}

/// Lane mask of vector `j` of a tile (lanes inside the image).
#[inline(always)]
fn lanes(t: &Tile, j: usize) -> F32s {
    let inside = (t.c1 - t.c0 - j * LANES).min(LANES);
    lane_offsets().simd_lt(F32s::splat(inside as f32))
}

/// The horizontal 11-tap pass of every product plane into ring slot `slot` (whole tile).
#[inline(always)]
fn horizontal(k: &Consts, s: &mut Scratch, slot: usize) {
    let w = &k.w;
    for c in 0..3 {
        for q in 0..PLANES {
            let src = &s.prod[c][q];
            let dst = &mut s.ring[slot][c][q];
            for j in 0..TILE / LANES {
                let i = PAD + j * LANES;
                let mut acc = w[0] * load(src, i);
                for (r, &wr) in w.iter().enumerate().skip(1) {
                    acc += wr * (load(src, i - r) + load(src, i + r));
                }
                store(dst, j * LANES, acc);
            }
        }
    }
}

/// The vertical 11-tap pass of every plane for output row `o` into `vbuf` (whole tile).
#[inline(always)]
fn vertical(k: &Consts, s: &mut Scratch, slots: &[usize; TAPS]) {
    let w = &k.w;
    for c in 0..3 {
        for q in 0..PLANES {
            let ring = &s.ring;
            let at_slot = |i: usize| &ring[slots[i]][c][q];
            let rows = [
                at_slot(0),
                at_slot(1),
                at_slot(2),
                at_slot(3),
                at_slot(4),
                at_slot(5),
                at_slot(6),
                at_slot(7),
                at_slot(8),
                at_slot(9),
                at_slot(10),
            ];
            let dst = &mut s.vbuf[c][q];
            for j in 0..TILE / LANES {
                let col = j * LANES;
                let at = |i: usize| load(rows[i], col);
                let mut acc = w[0] * at(5);
                acc += w[1] * (at(4) + at(6));
                acc += w[2] * (at(3) + at(7));
                acc += w[3] * (at(2) + at(8));
                acc += w[4] * (at(1) + at(9));
                acc += w[5] * (at(0) + at(10));
                store(dst, col, acc);
            }
        }
    }
}

/// The window statistics of one vector of voxels and what the pass does with them.
#[derive(Default)]
struct Voxels {
    /// Map values, clamped to [−1, 1].
    val: [F32s; 3],
    /// Lanes whose window holds only usable samples.
    finite: [F32s; 3],
    /// Lanes whose estimated rounding error is above the threshold.
    flagged: [F32s; 3],
    /// The error estimates as fractions `[cs_num, cs_den, lum_num, lum_den]` (for ranking
    /// flagged voxels).
    score: [[F32s; 4]; 3],
    /// Per-channel 2-D means, for re-shifting.
    mx: [F32s; 3],
    my: [F32s; 3],
    md: [F32s; 3],
}

/// `max(v, 0)`. The voxel math uses the plain `maxps`/`minps` (`fast_max`/`fast_min`, one
/// instruction instead of three): NaN lanes may come out as numbers, but they are excluded
/// by the separate finiteness mask, never by these results.
#[inline(always)]
fn max0(v: F32s) -> F32s {
    v.fast_max(F32s::ZERO)
}

/// The (possibly mixed) window statistics of one vector of voxels.
#[derive(Clone, Copy)]
struct Window {
    /// Unshifted means and `μx − μy`.
    mx: F32s,
    my: F32s,
    md: F32s,
    /// `σx² + σy²` and `σd²`, clamped at 0.
    vs: F32s,
    vd: F32s,
    /// The magnitudes cancelled to get `vs` and `vd`: their rounding errors scale with them.
    mag_s: F32s,
    mag_d: F32s,
    /// `|μx'| + |μy'|`: the rounding error of `md` and of the means scales with it.
    mag_m: F32s,
}

/// What [`map`] returns: the value, the refinement flag and the two error estimates as
/// fractions (for ranking flagged voxels).
struct Mapped {
    val: F32s,
    flagged: F32s,
    cs_num: F32s,
    cs_den: F32s,
    lum_num: F32s,
    lum_den: F32s,
}

/// The map value and the conditioning test.
///
/// Structure term: the estimated error is `γu·(mag_d + (vd / cs_lo)·mag_s) / cs_lo`, with
/// `cs_lo` the smallest `σx² + σy² + C2` consistent with the worst-case rounding error of
/// `vs`. Luminance term: `md` and the means carry an absolute error of about
/// `γu·(|μx'| + |μy'|)`, which moves `1 − md²/(μx² + μy² + C1)` by at most about
/// `6γu·(|μx'| + |μy'|)·|md| / (μx² + μy² + C1)` (small unless the shift is far from the
/// local mean). Each is tested against half of [`REFINE_THRESHOLD`], without a division.
#[inline(always)]
fn map(k: &Consts, w: &Window) -> Mapped {
    let lum_den = w.mx * w.mx + w.my * w.my + k.c1;
    let lum_num = lum_den - w.md * w.md;
    let cs_den = w.vs + k.c2;
    // σd² ≤ 2(σx² + σy²) holds exactly, but `vs` may be the badly conditioned one of the two
    // (clamping to it would hide the deficit from the error estimate): clamp only as far as
    // the structure term needs to stay ≥ −1.
    let vd = w.vd.fast_min(cs_den + cs_den);
    let cs_num = cs_den - vd;
    let val = ((lum_num * cs_num) / (lum_den * cs_den)).fast_max(-F32s::ONE).fast_min(F32s::ONE);
    // The estimate must not trust `vs` itself: where its error exceeds it (a badly shifted
    // window), the computed `cs_den` can be far too large and would hide everything.
    let cs_lo = max0(w.vs - k.bound * w.mag_s) + k.c2;
    let e_num = w.mag_d * cs_lo + vd * w.mag_s;
    let e_den = cs_lo * cs_lo;
    let l_num = w.mag_m * w.md.abs();
    let flagged = e_num.simd_gt(k.limit * e_den) | l_num.simd_gt(k.limit_lum * lum_den);
    Mapped { val, flagged, cs_num: e_num, cs_den: e_den, lum_num: l_num, lum_den }
}

#[inline(always)]
fn voxels(k: &Consts, variant: SsimVariant, st: &[[F32s; PLANES]; 3], sh: &Shifts, ds: &[F32s; 3], v: &mut Voxels) {
    let mut win = [Window {
        mx: F32s::ZERO,
        my: F32s::ZERO,
        md: F32s::ZERO,
        vs: F32s::ZERO,
        vd: F32s::ZERO,
        mag_s: F32s::ZERO,
        mag_d: F32s::ZERO,
        mag_m: F32s::ZERO,
    }; 3];
    for c in 0..3 {
        let [xp, yp, s2, d2] = st[c];
        let shift = F32s::splat(sh.s[c]);
        v.mx[c] = xp + shift;
        v.my[c] = yp + shift;
        v.md[c] = xp - yp;
        let mdp = v.md[c] - F32s::splat(sh.sd[c]);
        let mag_m = xp.abs() + yp.abs();
        win[c] = Window {
            mx: v.mx[c],
            my: v.my[c],
            md: v.md[c],
            vs: max0(s2 - (xp * xp + yp * yp)),
            vd: max0(d2 - mdp * mdp),
            mag_s: s2,
            // `md` comes from two separately rounded means, so `mdp²` carries an error of
            // about 2|mdp|·γu(|x'| + |y'|).
            mag_d: d2 + (mdp + mdp).abs() * mag_m,
            mag_m,
        };
        // NaN or ±∞ anywhere in the window makes the sum non-finite.
        v.finite[c] = (xp + yp + s2 + d2).is_finite();
    }
    let out = |v: &mut Voxels, c: usize, w: &Window| {
        let m = map(k, w);
        v.val[c] = m.val;
        v.flagged[c] = m.flagged;
        v.score[c] = [m.cs_num, m.cs_den, m.lum_num, m.lum_den];
    };
    match variant {
        SsimVariant::PerChannel => {
            for (c, w) in win.iter().enumerate() {
                out(v, c, w);
            }
        }
        SsimVariant::Volume => {
            // Differences of the unshifted channel means for the pairs (1,0), (2,0), (2,1):
            // from the shifted means (small) plus the difference of the shifts (a constant),
            // so a large common level never enters.
            // (Plain arrays and loops: `[_; 3].map` is not inlined here and cost 10%.)
            const PAIRS: [(usize, usize); 3] = [(1, 0), (2, 0), (2, 1)];
            let mut dx = [F32s::ZERO; 3];
            let mut dy = [F32s::ZERO; 3];
            let mut dd = [F32s::ZERO; 3];
            let mut pxy = [F32s::ZERO; 3];
            let mut pd = [F32s::ZERO; 3];
            let mut dvs = [F32s::ZERO; 3];
            let mut dvd = [F32s::ZERO; 3];
            let mut dms = [F32s::ZERO; 3];
            let mut dmd = [F32s::ZERO; 3];
            let mut dmm = [F32s::ZERO; 3];
            for (i, &(a, b)) in PAIRS.iter().enumerate() {
                dx[i] = (st[a][0] - st[b][0]) + ds[i];
                dy[i] = (st[a][1] - st[b][1]) + ds[i];
                dd[i] = v.md[a] - v.md[b];
                pxy[i] = dx[i] * dx[i] + dy[i] * dy[i];
                pd[i] = dd[i] * dd[i];
                dvs[i] = win[a].vs - win[b].vs;
                dvd[i] = win[a].vd - win[b].vd;
                dms[i] = win[a].mag_s - win[b].mag_s;
                dmd[i] = win[a].mag_d - win[b].mag_d;
                dmm[i] = win[a].mag_m - win[b].mag_m;
            }
            let m = &k.m;
            // For channel c, `q₃ − q_c = Σ_{c'≠c} M[c][c']·(q_c' − q_c)` with the pair
            // differences signed accordingly; zero (exactly) when the channels agree.
            let e = |c: usize, d: &[F32s; 3]| match c {
                0 => m[0][1] * d[0] + m[0][2] * d[1],
                1 => m[1][2] * d[2] - m[1][0] * d[0],
                _ => -(m[2][0] * d[1] + m[2][1] * d[2]),
            };
            // `Σ_{c'≠c} M[c][c']·p(c, c')` for a symmetric pair quantity `p`.
            let side = |c: usize, p: &[F32s; 3]| match c {
                0 => m[0][1] * p[0] + m[0][2] * p[1],
                1 => m[1][0] * p[0] + m[1][2] * p[2],
                _ => m[2][0] * p[1] + m[2][1] * p[2],
            };
            for c in 0..3 {
                let (ex, ey, ed) = (e(c, &dx), e(c, &dy), e(c, &dd));
                // Law of total variance: Σ M·(μ_c' − μ₃)² = Σ M·(μ_c' − μ_c)² − (μ₃ − μ_c)²,
                // well conditioned because M[c][c] ≥ 0.27 (the subtracted square is at most
                // 73% of the sum).
                let between_s = max0(side(c, &pxy) - (ex * ex + ey * ey));
                let between_d = max0(side(c, &pd) - ed * ed);
                let mixed = Window {
                    mx: v.mx[c] + ex,
                    my: v.my[c] + ey,
                    md: v.md[c] + ed,
                    vs: (win[c].vs + e(c, &dvs)) + between_s,
                    vd: (win[c].vd + e(c, &dvd)) + between_d,
                    // The rounding errors mix like the statistics they belong to.
                    mag_s: (win[c].mag_s + e(c, &dms)) + between_s,
                    mag_d: (win[c].mag_d + e(c, &dmd)) + between_d,
                    mag_m: win[c].mag_m + e(c, &dmm),
                };
                out(v, c, &mixed);
            }
            let finite = v.finite[0] & v.finite[1] & v.finite[2];
            v.finite = [finite; 3];
        }
    }
}

/// Vertical pass, map and accumulation for output row `o`.
#[allow(clippy::too_many_arguments)]
fn emit_row(
    ctx: &Ctx<'_>,
    s: &mut Scratch,
    t: &Tile,
    pass: usize,
    sh: &Shifts,
    o: usize,
    sums: &mut Sums,
    worst: &mut Worst,
) {
    let k = &ctx.k;
    let mut slots = [0usize; TAPS];
    for (i, slot) in slots.iter_mut().enumerate() {
        *slot = (o + i).saturating_sub(RADIUS).min(ctx.height - 1) % TAPS;
    }
    let mut ds = [F32s::ZERO; 3];
    for (i, (a, b)) in [(1, 0), (2, 0), (2, 1)].into_iter().enumerate() {
        ds[i] = F32s::splat(sh.s[a] - sh.s[b]);
    }
    let row = o - t.r0;
    let pending = s.pending[row];
    if pass > 0 && pending == [0; 3] {
        return;
    }
    vertical(k, s, &slots);
    let mut st = [[F32s::ZERO; PLANES]; 3];
    let mut v = Voxels::default();
    let mut row_sum = [F32s::ZERO; 3];
    let mut row_count = [0u64; 3];
    for j in 0..t.nv.min(TILE / LANES) {
        let mut want = [0xffu32; 3];
        if pass > 0 {
            for (w, &p) in want.iter_mut().zip(&pending) {
                *w = ((p >> (j * LANES)) & 0xff) as u32;
            }
        }
        if want == [0; 3] {
            continue;
        }
        let col = j * LANES;
        for c in 0..3 {
            for q in 0..PLANES {
                st[c][q] = load(&s.vbuf[c][q], col);
            }
        }
        voxels(k, ctx.variant, &st, sh, &ds, &mut v);
        let inside = lanes(t, j);
        // Common case: eight usable, well-conditioned voxels in every channel.
        let ok = inside & v.finite[0] & v.finite[1] & v.finite[2] & !(v.flagged[0] | v.flagged[1] | v.flagged[2]);
        if pass == 0 && ok.all() {
            for c in 0..3 {
                row_sum[c] += v.val[c];
                row_count[c] += LANES as u64;
            }
            continue;
        }
        for (c, &want) in want.iter().enumerate() {
            let candidates = v.finite[c] & inside & if pass == 0 { inside } else { bits_mask(want) };
            let flagged = candidates & v.flagged[c];
            let accept = candidates & !flagged;
            let accepted = count(accept);
            if accepted > 0 {
                // At most 8 terms per lane in f32 before the f64 sum.
                row_sum[c] += accept.select(v.val[c], F32s::ZERO);
                row_count[c] += u64::from(accepted);
                if pass > 0 {
                    sums.refined += u64::from(accepted);
                }
            }
            let shift = j * LANES;
            if pass == 0 {
                s.pending[row][c] |= u64::from(flagged.to_bitmask()) << shift;
            } else {
                s.pending[row][c] &= !(u64::from(accept.to_bitmask()) << shift);
            }
            let mut bits = flagged.to_bitmask();
            while bits != 0 {
                let lane = bits.trailing_zeros() as usize;
                bits &= bits - 1;
                let f = v.score[c].map(|q| f64::from(q.to_array()[lane]));
                // In units of each test's limit.
                let score = f[0] / f[1] / k.limit_f64 + f[2] / f[3] / k.limit_lum_f64;
                if score > worst.score[c] {
                    worst.score[c] = score;
                    for q in 0..3 {
                        worst.level[c][q] = (v.mx[q].to_array()[lane] + v.my[q].to_array()[lane]) * 0.5;
                        worst.diff[c][q] = v.md[q].to_array()[lane];
                    }
                }
            }
        }
    }
    for c in 0..3 {
        widen_add(&mut sums.sum[c], row_sum[c]);
        sums.count[c] += row_count[c];
    }
}
