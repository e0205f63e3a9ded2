//! The SIMD body of the fragment loop: eight pixel columns of one row at a time (one
//! `f32x8` per edge), the same expressions as [`super::scalar`] lane for lane: `b·py + c`
//! is formed once per row and `a·px` once per block, exactly the two products and the sum
//! the reference computes per pixel. Each row walks only the blocks of its span (where the
//! edges allow a pixel), not the record's whole box. Lanes that need the exact path (uncertain
//! coverage, near ties, masked triangles) go through the scalar code per pixel, and a block
//! reaching past the right image border is depth-tested one lane at a time; both compute
//! exactly what the reference does.

use wide::{i32x8, u32x8};

use super::{AlphaTest, BandOut, EyeEdges, EyeView, Record, U};
use crate::simd::{F32s, LANES, lane_offsets};

/// [`super::scalar::record`]'s SIMD twin.
pub(crate) fn record<M: AlphaTest>(
    rec: &Record,
    eye: usize,
    view: &EyeView<'_, M>,
    out: &mut BandOut<'_>,
) -> (u64, u64) {
    if rec.n == 4 { walk::<4, M>(rec, eye, view, out) } else { walk::<3, M>(rec, eye, view, out) }
}

#[inline(always)]
fn walk<const N: usize, M: AlphaTest>(
    rec: &Record,
    eye: usize,
    view: &EyeView<'_, M>,
    out: &mut BandOut<'_>,
) -> (u64, u64) {
    let e = &rec.eyes[eye];
    let Some(((c0, c1), (y0, y1))) = rec.walk_span(eye, out) else { return (0, 0) };
    let walk = Walk { rec, e, view, c0, c1, half: lane_offsets() + F32s::splat(0.5) };
    let mut counts = (0, 0);
    if c1 - c0 < SPAN_MIN_COLUMNS {
        // A narrow box: column blocks outside, rows inside, `a·px` once per block column.
        let mut bx = (c0 / 8) * 8;
        while bx <= c1 {
            let px = walk.px(bx);
            let apx: [F32s; N] = core::array::from_fn(|k| F32s::splat(e.a[k]) * px);
            for y in y0..=y1 {
                walk.block(bx, y, px, &apx, &mut counts, out);
            }
            bx += 8;
        }
    } else {
        // A wide box: rows outside, and only the blocks of each row's span (a long thin
        // triangle's box is mostly outside it).
        let spans = RowSpans::<N>::new(rec, e, (c0, c1));
        for y in y0..=y1 {
            let Some((lo, hi)) = spans.row(y) else { continue };
            // Blocks start at multiples of 8 columns, whatever the span (aligned stores).
            let mut bx = (lo / 8) * 8;
            while bx <= hi {
                let px = walk.px(bx);
                let apx: [F32s; N] = core::array::from_fn(|k| F32s::splat(e.a[k]) * px);
                walk.block(bx, y, px, &apx, &mut counts, out);
                bx += 8;
            }
        }
    }
    counts
}

/// One record's walk over one eye: what every block of it shares.
struct Walk<'r, 'v, M: AlphaTest> {
    rec: &'r Record,
    e: &'r EyeEdges,
    view: &'r EyeView<'v, M>,
    c0: i32,
    c1: i32,
    /// `lane + ½` per lane.
    half: F32s,
}

impl<M: AlphaTest> Walk<'_, '_, M> {
    /// The lanes' `px` in the block at column `bx`.
    #[inline(always)]
    fn px(&self, bx: i32) -> F32s {
        F32s::splat((bx - self.c0) as f32) + self.half
    }

    /// The block of eight columns from `bx` in row `y` (`apx`: each edge's `a·px`): coverage,
    /// the depth test of the certainly covered lanes, the exact path for the rest; adds to
    /// `counts` the fragments that took the exact path and the near ties among them.
    #[inline(always)]
    fn block<const N: usize>(
        &self,
        bx: i32,
        y: i32,
        px: F32s,
        apx: &[F32s; N],
        counts: &mut (u64, u64),
        out: &mut BandOut<'_>,
    ) {
        let (rec, e) = (self.rec, self.e);
        let band = F32s::splat(rec.band);
        let py = (y - rec.rows.0) as f32 + 0.5;
        let lane_x = i32x8::from([0, 1, 2, 3, 4, 5, 6, 7]);
        // Lanes inside the record's column range.
        let xs = lane_x + i32x8::splat(bx);
        let cols = (!(xs.simd_lt(i32x8::splat(self.c0)) | xs.simd_gt(i32x8::splat(self.c1)))).to_bitmask();
        let mut above_all = F32s::splat(f32::from_bits(u32::MAX));
        let mut above_any = F32s::ZERO;
        let mut below_any = F32s::ZERO;
        for k in 0..N {
            let d = apx[k] + F32s::splat(e.b[k] * py + e.c[k]);
            let above = d.simd_gt(band);
            above_all &= above;
            above_any |= above;
            below_any |= d.simd_lt(-band);
        }
        let (inside, outside) = if rec.flat {
            (0, (below_any & above_any).to_bitmask())
        } else {
            (above_all.to_bitmask(), below_any.to_bitmask())
        };
        let candidates = cols & !outside;
        if candidates == 0 {
            return;
        }
        let at = (y as usize - out.rows.start) * out.width + bx as usize;
        let mut slow = if rec.masked { candidates } else { candidates & !inside };
        let fast = candidates & !slow;
        if fast != 0 {
            let q = F32s::splat(e.qa) * px + F32s::splat(e.qb * py + e.qc);
            let near = if bx as usize + LANES <= out.width {
                depth_test(q, F32s::splat(e.q_err), u32x8::splat(rec.prim), fast, out, at)
            } else {
                depth_test_lanes(rec.prim, e, q, fast, out, at)
            };
            counts.1 += u64::from(near.count_ones());
            slow |= near;
        }
        let mut m = slow;
        while m != 0 {
            let lane = m.trailing_zeros() as usize;
            m &= m - 1;
            let i = at + lane;
            let stored = (&mut out.prim[i], &mut out.q[i], &mut out.q_err[i]);
            self.view.resolve_exact(rec.prim, bx as usize + lane, y as usize, stored);
            counts.0 += 1;
        }
    }
}

/// Records narrower than this many columns walk their whole box: a span costs more than
/// the blocks it would skip.
const SPAN_MIN_COLUMNS: i32 = 24;

/// The columns of each row, within the record's `c0..=c1`, that may hold a pixel not
/// certainly outside the polygon: where every edge's line equation, as the lanes evaluate it
/// in f32, can reach `−band`. Each edge bounds the column on one side by a line in the row,
/// `x ≥ α + β·py` or `x ≤ α + β·py`, with `α` moved by the f32 evaluation's largest rounding
/// over the record and each bound widened by a column: a superset of the lanes' own answer,
/// so walking only these blocks decides every pixel exactly as walking the whole box does.
/// A flat record (no certain orientation) and an edge parallel to the rows (or whose line
/// does not give finite bounds) bound nothing.
struct RowSpans<const N: usize> {
    cols: (i32, i32),
    first_row: i32,
    /// Per edge: `α`, `β`, and whether it bounds from below (`a > 0`); `None`: no bound.
    bounds: [Option<(f64, f64, bool)>; N],
}

impl<const N: usize> RowSpans<N> {
    #[inline(always)]
    fn new(rec: &Record, e: &EyeEdges, (c0, c1): (i32, i32)) -> Self {
        let mut bounds = [None; N];
        if !rec.flat {
            let band = f64::from(rec.band);
            // The largest `px` and `py` a lane of this record evaluates.
            let reach_x = f64::from(c1 - c0) + 8.5;
            let reach_y = f64::from(rec.rows.1 - rec.rows.0) + 0.5;
            for (k, bound) in bounds.iter_mut().enumerate() {
                let (a, b, c) = (f64::from(e.a[k]), f64::from(e.b[k]), f64::from(e.c[k]));
                // `a·px + (b·py + c)` in f32 rounds four times, each by at most u of a partial
                // sum no larger than the sum of the terms' magnitudes.
                let rounding = 4.0 * f64::from(U) * (a.abs() * reach_x + b.abs() * reach_y + c.abs());
                // Not certainly outside: `a·px + b·py + c ≥ −band − rounding`, `px = x − c0 + ½`.
                let alpha = (-band - rounding - c) / a + f64::from(c0) - 0.5;
                let beta = -b / a;
                if a != 0.0 && alpha.is_finite() && beta.is_finite() {
                    *bound = Some((alpha, beta, a > 0.0));
                }
            }
        }
        Self { cols: (c0, c1), first_row: rec.rows.0, bounds }
    }

    /// Row `y`'s columns, or `None` when no column can hold a pixel.
    #[inline(always)]
    fn row(&self, y: i32) -> Option<(i32, i32)> {
        let py = f64::from(y - self.first_row) + 0.5;
        let (mut lo, mut hi) = (f64::from(self.cols.0), f64::from(self.cols.1));
        for &(alpha, beta, lower) in self.bounds.iter().flatten() {
            let x = alpha + beta * py;
            if lower {
                lo = lo.max((x - 1.0).floor());
            } else {
                hi = hi.min((x + 1.0).ceil());
            }
        }
        (lo <= hi).then_some((lo as i32, hi as i32))
    }
}

/// Lane mask (bit `i` ⇒ all ones) as a float mask.
#[inline(always)]
fn lanes_mask(bits: u32) -> F32s {
    let bit = i32x8::from([1, 2, 4, 8, 16, 32, 64, 128]);
    let set = (i32x8::splat(bits as i32) & bit).simd_eq(bit);
    bytemuck::cast(set)
}

/// The depth test of the lanes `fast` (certainly inside, not masked) of a full block at
/// plane index `at`: nearer by more than both error bounds writes (as a blend); returns
/// the near ties.
#[inline(always)]
fn depth_test(q: F32s, q_err: F32s, prim: u32x8, fast: u32, out: &mut BandOut<'_>, at: usize) -> u32 {
    let sq_slice: &mut [f32; LANES] = (&mut out.q[at..at + LANES]).try_into().expect("8 lanes");
    let stored_q = F32s::from(*sq_slice);
    let se_slice: &mut [f32; LANES] = (&mut out.q_err[at..at + LANES]).try_into().expect("8 lanes");
    let stored_e = F32s::from(*se_slice);
    let tol = stored_e + q_err;
    let win_mask = (q - stored_q).simd_gt(tol) & lanes_mask(fast);
    let win = win_mask.to_bitmask();
    let lose = (stored_q - q).simd_gt(tol).to_bitmask() & fast;
    if win != 0 {
        *sq_slice = win_mask.select(q, stored_q).to_array();
        *se_slice = win_mask.select(q_err, stored_e).to_array();
        let sp_slice: &mut [u32; LANES] = (&mut out.prim[at..at + LANES]).try_into().expect("8 lanes");
        let w: u32x8 = bytemuck::cast(win_mask);
        *sp_slice = w.bitselect(prim, u32x8::from(*sp_slice)).to_array();
    }
    fast & !win & !lose
}

/// [`depth_test`] one lane at a time (a block reaching past the right border).
#[inline(never)]
fn depth_test_lanes(prim: u32, e: &EyeEdges, q: F32s, fast: u32, out: &mut BandOut<'_>, at: usize) -> u32 {
    let q = q.to_array();
    let mut ties = 0;
    let mut m = fast;
    while m != 0 {
        let lane = m.trailing_zeros() as usize;
        m &= m - 1;
        let (sq, se) = (out.q[at + lane], out.q_err[at + lane]);
        let tol = se + e.q_err;
        if q[lane] - sq > tol {
            out.prim[at + lane] = prim;
            out.q[at + lane] = q[lane];
            out.q_err[at + lane] = e.q_err;
        } else if !(sq - q[lane] > tol) {
            ties |= 1 << lane;
        }
    }
    ties
}
