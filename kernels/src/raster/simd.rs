//! The SIMD body of the fragment loop: eight pixel columns of one row at a time (one
//! `f32x8` per edge), the same expressions as [`super::scalar`] lane for lane: `a·px` is
//! formed once per block of columns and `b·py + c` once per row, exactly the two products
//! and the sum the reference computes per pixel. Lanes that need the exact path (uncertain
//! coverage, near ties, masked triangles) go through the scalar code per pixel, and a block
//! reaching past the right image border is depth-tested one lane at a time; both compute
//! exactly what the reference does.

use wide::{i32x8, u32x8};

use super::{AlphaTest, BandOut, EyeEdges, EyeView, Record};
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
    let half = lane_offsets() + F32s::splat(0.5);
    let lane_x = i32x8::from([0, 1, 2, 3, 4, 5, 6, 7]);
    let band = F32s::splat(rec.band);
    let (q_err, prim) = (F32s::splat(e.q_err), u32x8::splat(rec.prim));
    let (mut exact, mut ties) = (0, 0);
    let mut bx = (c0 / 8) * 8;
    while bx <= c1 {
        let px = F32s::splat((bx - c0) as f32) + half;
        let apx: [F32s; N] = core::array::from_fn(|k| F32s::splat(e.a[k]) * px);
        let qpx = F32s::splat(e.qa) * px;
        let full = bx as usize + LANES <= out.width;
        // Lanes inside the record's column range.
        let xs = lane_x + i32x8::splat(bx);
        let cols = (!(xs.simd_lt(i32x8::splat(c0)) | xs.simd_gt(i32x8::splat(c1)))).to_bitmask();
        for y in y0..=y1 {
            let row = y as usize - out.rows.start;
            let py = (y - rec.rows.0) as f32 + 0.5;
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
                continue;
            }
            let at = row * out.width + bx as usize;
            let mut slow = if rec.masked { candidates } else { candidates & !inside };
            let fast = candidates & !slow;
            if fast != 0 {
                let q = qpx + F32s::splat(e.qb * py + e.qc);
                let near = if full {
                    depth_test(q, q_err, prim, fast, out, at)
                } else {
                    depth_test_lanes(rec.prim, e, q, fast, out, at)
                };
                ties += u64::from(near.count_ones());
                slow |= near;
            }
            let mut m = slow;
            while m != 0 {
                let lane = m.trailing_zeros() as usize;
                m &= m - 1;
                let i = at + lane;
                let stored = (&mut out.prim[i], &mut out.q[i], &mut out.q_err[i]);
                view.resolve_exact(rec.prim, bx as usize + lane, y as usize, stored);
                exact += 1;
            }
        }
        bx += 8;
    }
    (exact, ties)
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
