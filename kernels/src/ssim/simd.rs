//! The fused SIMD kernel, written once against [`Lanes`] and compiled at 8 lanes (`f32x8`,
//! the baseline) and at 16 (AVX-512, chosen at run time: [`crate::isa`]).
//!
//! Work unit: a *tile* of at most [`BLOCK_ROWS`] rows × [`TILE`] columns of output voxels
//! (all three channels). For each input row the tile needs (its rows ± 5, clamped), the row
//! segment (columns ± [`PAD`]; borrowed from the images, or copied with replicate clamping
//! at the image borders) is sanitised (unusable samples become NaN, which then poisons
//! exactly the windows that contain them), turned into the four product planes `x'`, `y'`,
//! `x'² + y'²`, `(d − s_d)²` (with `x' = x − s`, `d = x − y`), and filtered horizontally into
//! one slot of a ring of [`RING`] rows. As soon as the last of [`KB`] output rows has its 11
//! input rows in the ring, one vertical pass filters all `KB` of them (each ring row loaded
//! once for all of them), then the channel mixing, the map and the accumulation run row by
//! row. Scratch is about 62 KB per band, on the stack; the ring (43 KB) and the planes stay
//! in L1/L2.
//!
//! Fused multiply-add: the filters, the mixing and the map use `mul_add` where it saves an
//! operation (see the module docs of `ssim` for why SSIM, unlike every other kernel, may);
//! sums whose operands swap when the two images swap (`x'² + y'²`, `μx² + μy²`, …) stay
//! unfused, because only that keeps the kernel symmetric bit for bit.
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

use crate::isa::Isa;
use crate::lanes::Lanes;
use crate::simd::{F32s, prefetch};

/// Loads one vector from `a[i..]` (callers use constant trip counts, so the bounds
/// checks fold away).
#[inline(always)]
fn load<V: Lanes, const N: usize>(a: &[f32; N], i: usize) -> V {
    V::load(&a[i..])
}

#[inline(always)]
fn store<V: Lanes, const N: usize>(a: &mut [f32; N], i: usize, v: V) {
    v.store(&mut a[i..]);
}

/// Output columns per tile: a multiple of every body's lane count (16) and at most 64 (pending voxels are one
/// `u64` bit mask per row and channel).
pub(super) const TILE: usize = 64;
/// Output rows per tile (and per local shift).
pub(super) const BLOCK_ROWS: usize = 64;
/// Columns of halo on each side of a row segment: at least [`RADIUS`], and `SEG` a multiple
/// of every body's lane count.
const PAD: usize = 8;
const SEG: usize = TILE + 2 * PAD;
/// Product planes per channel: `x'`, `y'`, `x'² + y'²`, `(d − s_d)²`.
const PLANES: usize = 4;
/// The narrowest lane count a body uses (sizes the per-vector arrays).
const MIN_LANES: usize = 8;
/// Output rows per vertical pass. The vertical pass loads each ring row once for `KB`
/// output rows instead of once per output row (11 loads per output vector become
/// `(KB + 10) / KB`): 1 → 4 took 22% off the kernel's time; 8 was no faster than 4.
const KB: usize = 4;
/// Ring rows: the `KB + 10` input rows of the `KB` output rows of one vertical pass.
const RING: usize = TAPS + KB - 1;
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
/// Relative slack of the refinement screen ([`screen`]): its magnitude bounds are inflated
/// by this and its limits deflated by twice this, far more than the few roundings in which
/// the screen and the exact test can differ, so the screen never passes a voxel the exact
/// test would flag.
const SCREEN_SLACK: f64 = 1.0 / 1024.0;

/// Splatted constants.
struct Consts<V> {
    /// `w[k]`: the weight at offsets ±k.
    w: [V; RADIUS + 1],
    m: [[V; 3]; 3],
    c1: V,
    c2: V,
    /// Refine where `num > limit · den` (see [`flags`]).
    limit: V,
    limit_lum: V,
    limit_f64: f64,
    limit_lum_f64: f64,
    /// Worst-case relative error of a cancelled statistic ([`BOUND_UNITS`]).
    bound: V,
    /// The screen's inflation of magnitude bounds and its deflated limits.
    slack: V,
    screen_limit: V,
    screen_limit_lum: V,
}

impl<V: Lanes> Consts<V> {
    #[inline(always)]
    fn new() -> Self {
        let g = gaussian_weights();
        let m = channel_mixing_matrix();
        let unit = f64::from(f32::EPSILON) / 2.0;
        // Half of the threshold for each term (see [`flags`]).
        let limit = REFINE_THRESHOLD / 2.0 / (ERROR_UNITS * unit);
        let limit_lum = REFINE_THRESHOLD / 2.0 / (6.0 * ERROR_UNITS * unit);
        let deflate = 1.0 - 2.0 * SCREEN_SLACK;
        Self {
            w: core::array::from_fn(|k| V::splat(g[RADIUS + k] as f32)),
            m: m.map(|row| row.map(|v| V::splat(v as f32))),
            c1: V::splat(C1 as f32),
            c2: V::splat(C2 as f32),
            limit: V::splat(limit as f32),
            limit_lum: V::splat(limit_lum as f32),
            limit_f64: limit,
            limit_lum_f64: limit_lum,
            bound: V::splat((BOUND_UNITS * unit) as f32),
            slack: V::splat((1.0 + SCREEN_SLACK) as f32),
            screen_limit: V::splat((limit * deflate) as f32),
            screen_limit_lum: V::splat((limit_lum * deflate) as f32),
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

impl Tile {
    /// Vectors of `lanes` lanes in a row whose lanes all lie inside the image.
    #[inline(always)]
    fn full_vectors(&self, lanes: usize) -> usize {
        (self.c1 - self.c0) / lanes
    }
}

/// The two images and what every band reads of them.
struct Frame<'a> {
    a: &'a RgbPlanes<'a>,
    b: &'a RgbPlanes<'a>,
    variant: SsimVariant,
    width: usize,
    height: usize,
}

/// A band's view: the frame and the constants splatted at the band's lane width.
struct Ctx<'a, V> {
    a: &'a RgbPlanes<'a>,
    b: &'a RgbPlanes<'a>,
    variant: SsimVariant,
    width: usize,
    height: usize,
    k: Consts<V>,
}

/// Horizontally filtered rows of one product plane: `[row % RING][column − c0]`.
type RingPlane = [[f32; TILE]; RING];

struct Scratch {
    /// Row segments: `[image][channel][column − (c0 − PAD)]`.
    seg: [[[f32; SEG]; 3]; 2],
    /// Products: `[channel][plane][column − (c0 − PAD)]`.
    prod: [[[f32; SEG]; PLANES]; 3],
    /// Horizontally filtered rows, `[channel][plane]`: plane-major, so that the vertical
    /// pass reads each plane's `RING` rows from one contiguous 3.5 KB block.
    ring: [[RingPlane; PLANES]; 3],
    /// Vertically filtered statistics of the current output rows:
    /// `[row − o][channel][plane][column − c0]`.
    vbuf: [[[[f32; TILE]; PLANES]; 3]; KB],
    /// Voxels still to be computed after a pass: `[row − r0][channel]`, bit = column − c0.
    pending: [[u64; 3]; BLOCK_ROWS],
}

impl Scratch {
    fn new() -> Self {
        Self {
            seg: [[[0.0; SEG]; 3]; 2],
            prod: [[[0.0; SEG]; PLANES]; 3],
            ring: [[[[0.0; TILE]; RING]; PLANES]; 3],
            vbuf: [[[[0.0; TILE]; PLANES]; 3]; KB],
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
fn widen_add<V: Lanes>(acc: &mut f64x4, v: V) {
    let a = v.to_array();
    for q in a.as_ref().chunks_exact(4) {
        *acc += f64x4::new([q[0] as f64, q[1] as f64, q[2] as f64, q[3] as f64]);
    }
}

#[inline(always)]
fn count<V: Lanes>(mask: V) -> u32 {
    mask.to_bitmask().count_ones()
}

/// The kernel on the current rayon pool with the body for `isa` (the 8-lane body where this
/// CPU lacks `isa`).
pub(super) fn run(a: &RgbPlanes<'_>, b: &RgbPlanes<'_>, params: &SsimParams, isa: Isa) -> SsimResult {
    let (width, height) = (a.extent().width(), a.extent().height());
    let band_rows = params.band_rows.max(1).max(height.div_ceil(MAX_BANDS));
    let bands = height.div_ceil(band_rows);
    let frame = Frame { a, b, variant: params.variant, width, height };
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
                let partial = band_sums_with(isa, &frame, rows);
                // SAFETY: `for_each_band` runs every band once, so slot `band` has one writer.
                let slot = unsafe { shared.row(band) };
                slot[0] = partial;
            },
            |(), ()| (),
        );
    }
    slots[..bands].iter().fold(Partial::default(), |acc, p| acc.merged(p)).finish(params.variant)
}

/// One band's sums with the body for `isa`.
fn band_sums_with(isa: Isa, frame: &Frame<'_>, rows: core::ops::Range<usize>) -> Partial {
    #[cfg(target_arch = "x86_64")]
    if isa == Isa::Avx512 && isa.is_supported() {
        // SAFETY: the CPU has every feature the function enables (checked on this line).
        return unsafe { band_sums_avx512(frame, rows) };
    }
    let _ = isa;
    band_sums::<F32s>(frame, rows)
}

/// [`band_sums`] at 16 lanes, compiled for AVX-512 (everything below it is inlined into it,
/// so the whole band runs with these features; see [`crate::lanes::avx512`]).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512bw,avx512dq,avx512vl")]
fn band_sums_avx512(frame: &Frame<'_>, rows: core::ops::Range<usize>) -> Partial {
    band_sums::<crate::lanes::avx512::F32x16>(frame, rows)
}

/// The sums of the rows `rows`, tile by tile. This and everything it calls are inlined into
/// the instruction set's entry above, so that the lane type's operations compile to single
/// instructions of that set.
#[inline(always)]
fn band_sums<V: Lanes>(frame: &Frame<'_>, rows: core::ops::Range<usize>) -> Partial {
    let ctx = &Ctx::<V> {
        a: frame.a,
        b: frame.b,
        variant: frame.variant,
        width: frame.width,
        height: frame.height,
        k: Consts::new(),
    };
    let mut p = Partial::default();
    let mut s = Scratch::new();
    let mut r0 = rows.start;
    while r0 < rows.end {
        let r1 = (r0 + BLOCK_ROWS).min(rows.end);
        let mut c0 = 0;
        while c0 < ctx.width {
            let c1 = (c0 + TILE).min(ctx.width);
            tile(ctx, &mut s, &Tile { r0, r1, c0, c1, nv: (c1 - c0).div_ceil(V::LANES) }, &mut p);
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
fn initial_shifts<V: Lanes>(ctx: &Ctx<'_, V>, t: &Tile) -> Shifts {
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

#[inline(always)]
fn tile<V: Lanes>(ctx: &Ctx<'_, V>, s: &mut Scratch, t: &Tile, p: &mut Partial) {
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
#[inline(always)]
fn run_pass<V: Lanes>(
    ctx: &Ctx<'_, V>,
    s: &mut Scratch,
    t: &Tile,
    pass: usize,
    shifts: &Shifts,
    sums: &mut Sums,
) -> Option<Shifts> {
    let first = t.r0.saturating_sub(RADIUS);
    let last = (t.r1 + RADIUS).min(ctx.height);
    let mut next_out = t.r0;
    let mut worst = Worst::new();
    let own = OwnColumns::new(t);
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
            products::<V, true>(&mut s.prod, &src, shifts, &own, sums);
        } else {
            products::<V, false>(&mut s.prod, &src, shifts, &own, sums);
        }
        horizontal(&ctx.k, s, y % RING);
        // Output rows go out `KB` at a time, as soon as the last one's window is complete
        // (fewer at the tile's end). The ring holds the `KB + 10` rows they read.
        while next_out < t.r1 {
            let n = KB.min(t.r1 - next_out);
            if (next_out + n - 1 + RADIUS).min(ctx.height - 1) > y {
                break;
            }
            match n {
                1 => emit_rows::<V, 1>(ctx, s, t, pass, shifts, next_out, sums, &mut worst),
                2 => emit_rows::<V, 2>(ctx, s, t, pass, shifts, next_out, sums, &mut worst),
                3 => emit_rows::<V, 3>(ctx, s, t, pass, shifts, next_out, sums, &mut worst),
                _ => emit_rows::<V, KB>(ctx, s, t, pass, shifts, next_out, sums, &mut worst),
            }
            next_out += n;
        }
    }
    worst.next(ctx.variant, shifts)
}

/// Hints the row segment of row `y` starting at column `c0` into the cache.
#[inline(always)]
fn prefetch_segment<V: Lanes>(ctx: &Ctx<'_, V>, c0: usize, y: usize) {
    let start = c0.saturating_sub(PAD);
    let end = (c0 + TILE + PAD).min(ctx.width);
    for planes in [ctx.a, ctx.b] {
        for plane in planes.channels() {
            // Pointer arithmetic, not indexing: a prefetch needs no bounds check (it never
            // faults), and the checks were a third of this function's time.
            let row = plane.row(y).as_ptr();
            let mut i = start;
            while i < end {
                prefetch(row.wrapping_add(i));
                i += 64 / size_of::<f32>();
            }
            prefetch(row.wrapping_add(end - 1));
        }
    }
}

/// Row `y` of every plane, columns `c0 − PAD ‥ c0 + TILE + PAD`: borrowed from the images
/// for interior tiles, copied with replicate clamping into `seg` at the borders. (Copying
/// every segment cost 7%: six small `memcpy` calls per row.)
#[inline(always)]
fn segment<'s, V: Lanes>(
    ctx: &Ctx<'s, V>,
    seg: &'s mut [[[f32; SEG]; 3]; 2],
    c0: usize,
    y: usize,
) -> [[&'s [f32; SEG]; 3]; 2] {
    // (Written out: `[_; N].map` here was not inlined and cost 4%.)
    let (a, b) = (&ctx.a, &ctx.b);
    let rows = [[a.r().row(y), a.g().row(y), a.b().row(y)], [b.r().row(y), b.g().row(y), b.b().row(y)]];
    if c0 >= PAD && c0 - PAD + SEG <= ctx.width {
        let cut =
            |i: usize, c: usize| -> &'s [f32; SEG] { rows[i][c][c0 - PAD..][..SEG].try_into().expect("SEG elements") };
        return [[cut(0, 0), cut(0, 1), cut(0, 2)], [cut(1, 0), cut(1, 1), cut(1, 2)]];
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
///
/// `x'² + y'²` is two products and a sum, not a fused multiply-add: swapping the images
/// swaps `x'` and `y'`, and only the unfused form gives the same bits both ways (the kernel
/// is symmetric bit for bit).
#[inline(always)]
fn products<V: Lanes, const COUNT: bool>(
    prod: &mut [[[f32; SEG]; PLANES]; 3],
    src: &[[&[f32; SEG]; 3]; 2],
    sh: &Shifts,
    own: &OwnColumns<V>,
    sums: &mut Sums,
) {
    let max = V::splat(MAX_SAMPLE);
    let nan = V::splat(f32::NAN);
    let mut sq = V::zero();
    // Lanes of the tile's own columns that hold an unusable sample in this row.
    let mut bad = V::zero();
    for c in 0..3 {
        let shift = V::splat(sh.s[c]);
        let dshift = V::splat(sh.sd[c]);
        let (xs, ys) = (src[0][c], src[1][c]);
        let [px, py, ps, pd] = &mut prod[c];
        for v in 0..SEG / V::LANES {
            let i = v * V::LANES;
            let (x, y): (V, V) = (load(xs, i), load(ys, i));
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
            if COUNT {
                let inside = own.mask[v];
                bad |= inside & !(ux & uy);
                // NaN where a sample is unusable: then `bad` is set and the row is recounted.
                // At most 3·SEG/8 terms per lane in f32 before the f64 sum: relative
                // error ≤ 1.5e-6.
                sq += inside.select(d * d, V::zero());
            }
        }
    }
    if COUNT {
        if bad.none() {
            // The common case: every own sample of the row usable.
            widen_add(&mut sums.sq, sq);
            sums.sq_n += 3 * own.count;
        } else {
            count_row(src, own, sums);
        }
    }
}

/// The tile's own columns within a row segment.
struct OwnColumns<V> {
    /// Per segment vector: all-ones in the lanes of columns `c0 ..< c1`.
    mask: [V; SEG / MIN_LANES],
    /// `c1 − c0`.
    count: u64,
}

impl<V: Lanes> OwnColumns<V> {
    #[inline(always)]
    fn new(t: &Tile) -> Self {
        let width = V::splat((t.c1 - t.c0) as f32);
        let mut mask = [V::zero(); SEG / MIN_LANES];
        for (v, m) in mask.iter_mut().enumerate().take(SEG / V::LANES) {
            let col = V::lane_offsets() + V::splat(v as f32 * V::LANES as f32 - PAD as f32);
            *m = col.simd_ge(V::zero()) & col.simd_lt(width);
        }
        Self { mask, count: (t.c1 - t.c0) as u64 }
    }
}

/// The RMSE sums and unusable-sample counts of a row with unusable samples.
#[inline(always)]
fn count_row<V: Lanes>(src: &[[&[f32; SEG]; 3]; 2], own: &OwnColumns<V>, sums: &mut Sums) {
    let max = V::splat(MAX_SAMPLE);
    let mut sq = V::zero();
    for c in 0..3 {
        for v in 0..SEG / V::LANES {
            let i = v * V::LANES;
            let (x, y): (V, V) = (load(src[0][c], i), load(src[1][c], i));
            let (ux, uy) = (x.abs().simd_le(max), y.abs().simd_le(max));
            let inside = own.mask[v];
            let both = ux & uy & inside;
            sums.non_finite += u64::from(count(!ux & inside) + count(!uy & inside));
            sums.sq_n += u64::from(count(both));
            let d = x - y;
            sq += both.select(d * d, V::zero());
        }
    }
    widen_add(&mut sums.sq, sq);
}

/// Lane mask of vector `j` of a tile (lanes inside the image).
#[inline(always)]
fn lanes<V: Lanes>(t: &Tile, j: usize) -> V {
    let inside = (t.c1 - t.c0 - j * V::LANES).min(V::LANES);
    V::lane_offsets().simd_lt(V::splat(inside as f32))
}

/// The horizontal 11-tap pass of every product plane into ring slot `slot` (whole tile).
#[inline(always)]
fn horizontal<V: Lanes>(k: &Consts<V>, s: &mut Scratch, slot: usize) {
    let w = &k.w;
    for c in 0..3 {
        for q in 0..PLANES {
            let src = &s.prod[c][q];
            let dst = &mut s.ring[c][q][slot];
            for j in 0..TILE / V::LANES {
                let i = PAD + j * V::LANES;
                let mut acc = w[0] * load(src, i);
                for (r, &wr) in w.iter().enumerate().skip(1) {
                    acc = wr.mul_add(load::<V, SEG>(src, i - r) + load(src, i + r), acc);
                }
                store(dst, j * V::LANES, acc);
            }
        }
    }
}

/// The vertical 11-tap pass of every plane for the `K` output rows `o .. o + K` into `vbuf`
/// (whole tile); `slots[i]` is the ring slot of input row `o − 5 + i` (clamped).
#[inline(always)]
fn vertical<V: Lanes, const K: usize>(k: &Consts<V>, s: &mut Scratch, slots: &[usize; RING]) {
    let w = &k.w;
    for c in 0..3 {
        for q in 0..PLANES {
            let ring = &s.ring[c][q];
            let vbuf = &mut s.vbuf;
            for j in 0..TILE / V::LANES {
                let col = j * V::LANES;
                // Every row loaded once, before any store: the compiler cannot tell that the
                // stores into `vbuf` leave the ring alone, and would reload otherwise.
                let mut at = [V::zero(); RING];
                for (i, v) in at.iter_mut().enumerate().take(K + 2 * RADIUS) {
                    *v = load(&ring[slots[i] % RING], col);
                }
                let mut out = [V::zero(); K];
                for (r, o) in out.iter_mut().enumerate() {
                    let mut acc = w[0] * at[r + 5];
                    acc = w[1].mul_add(at[r + 4] + at[r + 6], acc);
                    acc = w[2].mul_add(at[r + 3] + at[r + 7], acc);
                    acc = w[3].mul_add(at[r + 2] + at[r + 8], acc);
                    acc = w[4].mul_add(at[r + 1] + at[r + 9], acc);
                    *o = w[5].mul_add(at[r] + at[r + 10], acc);
                }
                for (r, &o) in out.iter().enumerate() {
                    store(&mut vbuf[r][c][q], col, o);
                }
            }
        }
    }
}

/// `max(v, 0)`. The voxel math uses the plain `maxps`/`minps` (`fast_max`/`fast_min`, one
/// instruction instead of three): NaN lanes may come out as numbers, but they are excluded
/// by the separate finiteness mask, never by these results.
#[inline(always)]
fn max0<V: Lanes>(v: V) -> V {
    v.fast_max(V::zero())
}

/// Filtered statistics of one vector of voxels in one channel: `x = E[x']`, `y = E[y']`,
/// `s = E[x'² + y'²]`, `d = E[(d − s_d)²]`.
#[derive(Clone, Copy)]
struct Stats<V> {
    x: V,
    y: V,
    s: V,
    d: V,
}

#[inline(always)]
fn stats<V: Lanes>(planes: &[[f32; TILE]; PLANES], col: usize) -> Stats<V> {
    Stats { x: load(&planes[0], col), y: load(&planes[1], col), s: load(&planes[2], col), d: load(&planes[3], col) }
}

/// The window statistics of one channel's voxels: for the 2-D window of the channel itself
/// ([`own`]) or mixed over the 3-D window ([`mix`]).
#[derive(Clone, Copy)]
struct Window<V> {
    /// Unshifted means and `μx − μy`.
    mx: V,
    my: V,
    md: V,
    /// `σx² + σy²` and `σd²`, clamped at 0.
    vs: V,
    vd: V,
    /// The between-channel parts of `vs` and `vd` (0 for a 2-D window).
    bs: V,
    bd: V,
}

/// The channel's own 2-D window.
#[inline(always)]
fn own<V: Lanes>(st: &Stats<V>, shift: V, dshift: V) -> Window<V> {
    let md = st.x - st.y;
    let mdp = md - dshift;
    Window {
        mx: st.x + shift,
        my: st.y + shift,
        md,
        // Unfused, for the symmetry (see [`products`]).
        vs: max0(st.s - (st.x * st.x + st.y * st.y)),
        vd: max0(mdp.mul_neg_add(mdp, st.d)),
        bs: V::zero(),
        bd: V::zero(),
    }
}

/// The channel pairs whose differences the mixing uses.
const PAIRS: [(usize, usize); 3] = [(1, 0), (2, 0), (2, 1)];

/// For channel `c`, `q₃ − q_c = Σ_{c'≠c} M[c][c']·(q_c' − q_c)` from the pair differences
/// `d` (signed accordingly); zero (exactly) when the channels agree.
#[inline(always)]
fn spread<V: Lanes>(m: &[[V; 3]; 3], c: usize, d: &[V; 3]) -> V {
    match c {
        0 => m[0][1].mul_add(d[0], m[0][2] * d[1]),
        1 => m[1][0].mul_neg_add(d[0], m[1][2] * d[2]),
        _ => -m[2][0].mul_add(d[1], m[2][1] * d[2]),
    }
}

/// `Σ_{c'≠c} M[c][c']·p(c, c')` for a symmetric pair quantity `p`.
#[inline(always)]
fn side<V: Lanes>(m: &[[V; 3]; 3], c: usize, p: &[V; 3]) -> V {
    match c {
        0 => m[0][1].mul_add(p[0], m[0][2] * p[1]),
        1 => m[1][0].mul_add(p[0], m[1][2] * p[2]),
        _ => m[2][0].mul_add(p[1], m[2][1] * p[2]),
    }
}

/// The 3-D windows of all three channels from their 2-D windows.
///
/// Differences of the unshifted channel means come from the shifted means (small) plus the
/// difference of the shifts (a constant, `ds`), so a large common level never enters. The
/// variances mix by the law of total variance: `Σ M·(μ_c' − μ₃)² = Σ M·(μ_c' − μ_c)² −
/// (μ₃ − μ_c)²`, well conditioned because `M[c][c] ≥ 0.27` (the subtracted square is at
/// most 73% of the sum).
#[inline(always)]
fn mix<V: Lanes>(m: &[[V; 3]; 3], st: &[Stats<V>; 3], w: &[Window<V>; 3], ds: &[V; 3]) -> [Window<V>; 3] {
    let mut dx = [V::zero(); 3];
    let mut dy = [V::zero(); 3];
    let mut dd = [V::zero(); 3];
    let mut pxy = [V::zero(); 3];
    let mut pd = [V::zero(); 3];
    let mut dvs = [V::zero(); 3];
    let mut dvd = [V::zero(); 3];
    for (i, &(a, b)) in PAIRS.iter().enumerate() {
        dx[i] = (st[a].x - st[b].x) + ds[i];
        dy[i] = (st[a].y - st[b].y) + ds[i];
        dd[i] = w[a].md - w[b].md;
        // Unfused, for the symmetry (swapping the images swaps dx and dy).
        pxy[i] = dx[i] * dx[i] + dy[i] * dy[i];
        pd[i] = dd[i] * dd[i];
        dvs[i] = w[a].vs - w[b].vs;
        dvd[i] = w[a].vd - w[b].vd;
    }
    let d = Diffs { dx, dy, dd, pxy, pd, dvs, dvd };
    [mixed(m, 0, &w[0], &d), mixed(m, 1, &w[1], &d), mixed(m, 2, &w[2], &d)]
}

/// The pair differences [`mix`] works from.
struct Diffs<V> {
    dx: [V; 3],
    dy: [V; 3],
    dd: [V; 3],
    pxy: [V; 3],
    pd: [V; 3],
    dvs: [V; 3],
    dvd: [V; 3],
}

/// Channel `c`'s 3-D window from its 2-D window `w`. (A function, not a closure: closures
/// returning a window were not inlined, which cost 20%.)
#[inline(always)]
fn mixed<V: Lanes>(m: &[[V; 3]; 3], c: usize, w: &Window<V>, d: &Diffs<V>) -> Window<V> {
    let (ex, ey, ed) = (spread(m, c, &d.dx), spread(m, c, &d.dy), spread(m, c, &d.dd));
    let bs = max0(side(m, c, &d.pxy) - (ex * ex + ey * ey));
    let bd = max0(ed.mul_neg_add(ed, side(m, c, &d.pd)));
    Window {
        mx: w.mx + ex,
        my: w.my + ey,
        md: w.md + ed,
        vs: (w.vs + spread(m, c, &d.dvs)) + bs,
        vd: (w.vd + spread(m, c, &d.dvd)) + bd,
        bs,
        bd,
    }
}

/// The map value of one window and the parts of it the refinement test reuses.
struct Mapped<V> {
    /// Clamped to [−1, 1].
    val: V,
    lum_den: V,
    /// `σd²` clamped to `2(σx² + σy² + C2)`.
    vdc: V,
}

/// The map in the difference form (module docs).
#[inline(always)]
fn map<V: Lanes>(k: &Consts<V>, w: &Window<V>) -> Mapped<V> {
    let lum_den = (w.mx * w.mx + w.my * w.my) + k.c1;
    let lum_num = w.md.mul_neg_add(w.md, lum_den);
    let cs_den = w.vs + k.c2;
    // σd² ≤ 2(σx² + σy²) holds exactly, but `vs` may be the badly conditioned one of the two
    // (clamping to it would hide the deficit from the error estimate): clamp only as far as
    // the structure term needs to stay ≥ −1.
    let vdc = w.vd.fast_min(cs_den + cs_den);
    let cs_num = cs_den - vdc;
    let val = ((lum_num * cs_num) / (lum_den * cs_den)).fast_max(-V::one()).fast_min(V::one());
    Mapped { val, lum_den, vdc }
}

/// The magnitudes cancelled in a window's statistics: their rounding errors scale with them.
#[derive(Clone, Copy)]
struct Mags<V> {
    /// Cancelled to get `vs` (`E[x'² + y'²]`).
    s: V,
    /// Cancelled to get `vd`. `md` comes from two separately rounded means, so `mdp²`
    /// carries an error of about `2|mdp|·γu(|x'| + |y'|)`.
    d: V,
    /// `|μx'| + |μy'|`: the rounding error of `md` and of the means scales with it.
    m: V,
}

#[inline(always)]
fn own_mags<V: Lanes>(st: &Stats<V>, w: &Window<V>, dshift: V) -> Mags<V> {
    let m = st.x.abs() + st.y.abs();
    let mdp = w.md - dshift;
    Mags { s: st.s, d: (mdp + mdp).abs().mul_add(m, st.d), m }
}

/// The magnitudes of the 3-D windows: they mix like the statistics they belong to.
#[inline(always)]
fn mix_mags<V: Lanes>(m: &[[V; 3]; 3], g: &[Mags<V>; 3], win: &[Window<V>; 3]) -> [Mags<V>; 3] {
    let mut ds = [V::zero(); 3];
    let mut dd = [V::zero(); 3];
    let mut dm = [V::zero(); 3];
    for (i, &(a, b)) in PAIRS.iter().enumerate() {
        ds[i] = g[a].s - g[b].s;
        dd[i] = g[a].d - g[b].d;
        dm[i] = g[a].m - g[b].m;
    }
    let mut out = *g;
    for c in 0..3 {
        out[c] = Mags {
            s: (g[c].s + spread(m, c, &ds)) + win[c].bs,
            d: (g[c].d + spread(m, c, &dd)) + win[c].bd,
            m: g[c].m + spread(m, c, &dm),
        };
    }
    out
}

/// The refinement test of one window's voxels: the flag and the two error estimates as
/// fractions `[cs_num, cs_den, lum_num, lum_den]` (for ranking flagged voxels).
///
/// Structure term: the estimated error is `γu·(mag_d + (vd / cs_lo)·mag_s) / cs_lo`, with
/// `cs_lo` the smallest `σx² + σy² + C2` consistent with the worst-case rounding error of
/// `vs`. Luminance term: `md` and the means carry an absolute error of about
/// `γu·(|μx'| + |μy'|)`, which moves `1 − md²/(μx² + μy² + C1)` by at most about
/// `6γu·(|μx'| + |μy'|)·|md| / (μx² + μy² + C1)` (small unless the shift is far from the
/// local mean). Each is tested against half of [`REFINE_THRESHOLD`], without a division.
#[inline(always)]
fn flags<V: Lanes>(k: &Consts<V>, w: &Window<V>, g: &Mags<V>, mp: &Mapped<V>) -> (V, [V; 4]) {
    // The estimate must not trust `vs` itself: where its error exceeds it (a badly shifted
    // window), the computed `cs_den` can be far too large and would hide everything.
    let cs_lo = max0(k.bound.mul_neg_add(g.s, w.vs)) + k.c2;
    let e_num = g.d.mul_add(cs_lo, mp.vdc * g.s);
    let e_den = cs_lo * cs_lo;
    let l_num = g.m * w.md.abs();
    let flagged = e_num.simd_gt(k.limit * e_den) | l_num.simd_gt(k.limit_lum * mp.lum_den);
    (flagged, [e_num, e_den, l_num, mp.lum_den])
}

/// A cheap stand-in for [`flags`] over the three mixed windows of the 3-D variant: true in
/// every lane where [`flags`] flags some channel (and in a few more). It bounds each mixed
/// magnitude by the largest per-channel one (the mixing is a convex combination plus the
/// between-channel part) instead of mixing them, with [`SCREEN_SLACK`] to spare; the test is
/// monotonic in those bounds. Only vectors it fires on pay for the exact test (none on LDR
/// content), so the refined voxels are the same as with the exact test everywhere.
#[inline(always)]
fn screen<V: Lanes>(
    k: &Consts<V>,
    st: &[Stats<V>; 3],
    own: &[Window<V>; 3],
    win: &[Window<V>; 3],
    mp: &[Mapped<V>; 3],
    sd: &[V; 3],
) -> V {
    let max3 = |a: [V; 3]| a[0].fast_max(a[1]).fast_max(a[2]);
    let mut mag_m = [V::zero(); 3];
    let mut mdp = [V::zero(); 3];
    for c in 0..3 {
        mag_m[c] = st[c].x.abs() + st[c].y.abs();
        mdp[c] = (own[c].md - sd[c]).abs();
    }
    let mm = max3(mag_m) * k.slack;
    let ms = max3([st[0].s, st[1].s, st[2].s]) * k.slack;
    let mdp = max3(mdp);
    let md = (mdp + mdp).mul_add(mm, max3([st[0].d, st[1].d, st[2].d])) * k.slack;
    let mut fire = V::zero();
    for c in 0..3 {
        let (s, d) = (ms + win[c].bs, md + win[c].bd);
        let lo = max0(k.bound.mul_neg_add(s, win[c].vs)) + k.c2;
        let e = d.mul_add(lo, mp[c].vdc * s);
        // `≥`, not `>`: where both sides overflow to +∞, the exact test must decide.
        fire |=
            e.simd_ge(k.screen_limit * (lo * lo)) | (mm * win[c].md.abs()).simd_ge(k.screen_limit_lum * mp[c].lum_den);
    }
    fire
}

/// The windows of one vector of voxels in all three channels: each channel's own and the
/// ones the map uses (mixed for the 3-D variant).
#[inline(always)]
fn windows<V: Lanes>(
    k: &Consts<V>,
    variant: SsimVariant,
    st: &[Stats<V>; 3],
    sh: &Shifts,
    ds: &[V; 3],
) -> ([Window<V>; 3], [Window<V>; 3]) {
    // (Plain arrays, not `core::array::from_fn` or `[_; 3].map`: those closures are not
    // always inlined here, which cost 60%.)
    let own = [
        own(&st[0], V::splat(sh.s[0]), V::splat(sh.sd[0])),
        own(&st[1], V::splat(sh.s[1]), V::splat(sh.sd[1])),
        own(&st[2], V::splat(sh.s[2]), V::splat(sh.sd[2])),
    ];
    let win = match variant {
        SsimVariant::PerChannel => own,
        SsimVariant::Volume => mix(&k.m, st, &own, ds),
    };
    (own, win)
}

/// Lanes whose windows hold only usable samples, per channel. An unusable sample is NaN
/// after [`products`], which makes its channel's `x'² + y'²` plane NaN wherever a window
/// holds it, so that one plane tells (usable samples cannot overflow any statistic).
#[inline(always)]
fn finite<V: Lanes>(variant: SsimVariant, st: &[Stats<V>; 3]) -> [V; 3] {
    match variant {
        SsimVariant::PerChannel => [st[0].s.simd_eq(st[0].s), st[1].s.simd_eq(st[1].s), st[2].s.simd_eq(st[2].s)],
        SsimVariant::Volume => {
            let all = st[0].s + st[1].s + st[2].s;
            [all.simd_eq(all); 3]
        }
    }
}

/// The common case of pass 0: the map values, and the lanes that are usable and pass the
/// refinement test in every channel.
#[inline(always)]
fn fast_voxels<V: Lanes>(
    k: &Consts<V>,
    variant: SsimVariant,
    st: &[Stats<V>; 3],
    sh: &Shifts,
    ds: &[V; 3],
) -> ([V; 3], V) {
    let (own, win) = windows(k, variant, st, sh, ds);
    let mp = [map(k, &win[0]), map(k, &win[1]), map(k, &win[2])];
    let fin = finite(variant, st);
    let fire = match variant {
        SsimVariant::Volume => {
            let sd = [V::splat(sh.sd[0]), V::splat(sh.sd[1]), V::splat(sh.sd[2])];
            screen(k, st, &own, &win, &mp, &sd)
        }
        SsimVariant::PerChannel => {
            let mut any = V::zero();
            for c in 0..3 {
                let g = own_mags(&st[c], &own[c], V::splat(sh.sd[c]));
                any |= flags(k, &win[c], &g, &mp[c]).0;
            }
            any
        }
    };
    ([mp[0].val, mp[1].val, mp[2].val], fin[0] & fin[1] & fin[2] & !fire)
}

/// Everything a pass needs to decide about one vector of voxels.
struct Voxels<V> {
    /// Map values, clamped to [−1, 1].
    val: [V; 3],
    /// Lanes whose window holds only usable samples.
    finite: [V; 3],
    /// Lanes whose estimated rounding error is above the threshold.
    flagged: [V; 3],
    /// The error estimates as fractions (see [`flags`]).
    score: [[V; 4]; 3],
    /// Per-channel 2-D windows, for re-shifting.
    own: [Window<V>; 3],
}

/// The map values with the exact refinement test (the values are the same bits as
/// [`fast_voxels`]'s: the same code computes them).
#[inline(always)]
fn exact_voxels<V: Lanes>(
    k: &Consts<V>,
    variant: SsimVariant,
    st: &[Stats<V>; 3],
    sh: &Shifts,
    ds: &[V; 3],
) -> Voxels<V> {
    let (own, win) = windows(k, variant, st, sh, ds);
    let mp = [map(k, &win[0]), map(k, &win[1]), map(k, &win[2])];
    let g = [
        own_mags(&st[0], &own[0], V::splat(sh.sd[0])),
        own_mags(&st[1], &own[1], V::splat(sh.sd[1])),
        own_mags(&st[2], &own[2], V::splat(sh.sd[2])),
    ];
    let g = match variant {
        SsimVariant::PerChannel => g,
        SsimVariant::Volume => mix_mags(&k.m, &g, &win),
    };
    let f = [flags(k, &win[0], &g[0], &mp[0]), flags(k, &win[1], &g[1], &mp[1]), flags(k, &win[2], &g[2], &mp[2])];
    Voxels {
        val: [mp[0].val, mp[1].val, mp[2].val],
        finite: finite(variant, st),
        flagged: [f[0].0, f[1].0, f[2].0],
        score: [f[0].1, f[1].1, f[2].1],
        own,
    }
}

/// Vertical pass for output rows `o .. o + K`, then the map and accumulation of each.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn emit_rows<V: Lanes, const K: usize>(
    ctx: &Ctx<'_, V>,
    s: &mut Scratch,
    t: &Tile,
    pass: usize,
    sh: &Shifts,
    o: usize,
    sums: &mut Sums,
    worst: &mut Worst,
) {
    let rows = o - t.r0..o - t.r0 + K;
    if pass > 0 && s.pending[rows].iter().all(|p| *p == [0; 3]) {
        return;
    }
    let mut slots = [0usize; RING];
    for (i, slot) in slots.iter_mut().enumerate() {
        *slot = (o + i).saturating_sub(RADIUS).min(ctx.height - 1) % RING;
    }
    vertical::<V, K>(&ctx.k, s, &slots);
    for r in 0..K {
        emit_row(ctx, s, t, pass, sh, o + r, r, sums, worst);
    }
}

/// Map and accumulation for output row `o`, whose vertical statistics are in `vbuf[vb]`.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn emit_row<V: Lanes>(
    ctx: &Ctx<'_, V>,
    s: &mut Scratch,
    t: &Tile,
    pass: usize,
    sh: &Shifts,
    o: usize,
    vb: usize,
    sums: &mut Sums,
    worst: &mut Worst,
) {
    let k = &ctx.k;
    let row = o - t.r0;
    let pending = s.pending[row];
    if pass > 0 && pending == [0; 3] {
        return;
    }
    let mut ds = [V::zero(); 3];
    for (i, &(a, b)) in PAIRS.iter().enumerate() {
        ds[i] = V::splat(sh.s[a] - sh.s[b]);
    }
    let full = t.full_vectors(V::LANES);
    let mut row_sum = [V::zero(); 3];
    let mut row_count = [0u64; 3];
    for j in 0..t.nv.min(TILE / V::LANES) {
        let mut want = [V::lane_bits(); 3];
        if pass > 0 {
            for (w, &p) in want.iter_mut().zip(&pending) {
                *w = ((p >> (j * V::LANES)) & u64::from(V::lane_bits())) as u32;
            }
        }
        if want == [0; 3] {
            continue;
        }
        let col = j * V::LANES;
        let vbuf = &s.vbuf[vb];
        let st = [stats(&vbuf[0], col), stats(&vbuf[1], col), stats(&vbuf[2], col)];
        // Common case: a full vector of usable, well-conditioned voxels in every channel.
        if pass == 0 && j < full {
            let (val, ok) = fast_voxels(k, ctx.variant, &st, sh, &ds);
            if ok.all() {
                for c in 0..3 {
                    row_sum[c] += val[c];
                    row_count[c] += V::LANES as u64;
                }
                continue;
            }
        }
        let v = exact_voxels(k, ctx.variant, &st, sh, &ds);
        let inside = lanes(t, j);
        for (c, &want) in want.iter().enumerate() {
            let candidates = v.finite[c] & inside & if pass == 0 { inside } else { V::from_bitmask(want) };
            let flagged = candidates & v.flagged[c];
            let accept = candidates & !flagged;
            let accepted = count(accept);
            if accepted > 0 {
                // At most TILE / 8 terms per lane in f32 before the f64 sum.
                row_sum[c] += accept.select(v.val[c], V::zero());
                row_count[c] += u64::from(accepted);
                if pass > 0 {
                    sums.refined += u64::from(accepted);
                }
            }
            let shift = j * V::LANES;
            if pass == 0 {
                s.pending[row][c] |= u64::from(flagged.to_bitmask()) << shift;
            } else {
                s.pending[row][c] &= !(u64::from(accept.to_bitmask()) << shift);
            }
            let mut bits = flagged.to_bitmask();
            while bits != 0 {
                let lane = bits.trailing_zeros() as usize;
                bits &= bits - 1;
                let f = v.score[c].map(|q| f64::from(q.lane(lane)));
                // In units of each test's limit.
                let score = f[0] / f[1] / k.limit_f64 + f[2] / f[3] / k.limit_lum_f64;
                if score > worst.score[c] {
                    worst.score[c] = score;
                    for q in 0..3 {
                        let w = &v.own[q];
                        worst.level[c][q] = (w.mx.lane(lane) + w.my.lane(lane)) * 0.5;
                        worst.diff[c][q] = w.md.lane(lane);
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
