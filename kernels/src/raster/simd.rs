//! The SIMD body of the fragment loop: eight pixel columns of one row at a time (one
//! `f32x8` per edge), the same expressions as [`super::scalar`] lane for lane. Lanes that
//! need the exact path (uncertain coverage, near ties, masked triangles) go through the
//! scalar code per pixel, and a block reaching past the right image border is depth-tested
//! one lane at a time, both computing exactly what the reference does.

use wide::i32x8;

use super::{AlphaTest, BandOut, EyeEdges, EyeView, Record};
use crate::simd::{F32s, LANES, lane_offsets};

/// [`super::scalar::record`]'s SIMD twin.
pub(crate) fn record<M: AlphaTest>(rec: &Record, eye: usize, view: &EyeView<'_, M>, out: &mut BandOut<'_>) -> u64 {
    let e = &rec.eyes[eye];
    let (c0, c1) = e.cols;
    let (y0, y1) = (rec.rows.0.max(out.rows.start as i32), rec.rows.1.min(out.rows.end as i32 - 1));
    if y0 > y1 || c0 > c1 {
        return 0;
    }
    let half = lane_offsets() + F32s::splat(0.5);
    let lane_x = i32x8::from([0, 1, 2, 3, 4, 5, 6, 7]);
    let mut exact = 0;
    let mut bx = (c0 / 8) * 8;
    while bx <= c1 {
        let px = F32s::splat(bx as f32) + half;
        let full = bx as usize + LANES <= out.width;
        // Lanes inside the record's column range.
        let xs = lane_x + i32x8::splat(bx);
        let cols = (!(xs.simd_lt(i32x8::splat(c0)) | xs.simd_gt(i32x8::splat(c1)))).to_bitmask();
        for y in y0..=y1 {
            let row = y as usize - out.rows.start;
            let py = y as f32 + 0.5;
            let (inside, outside) =
                if rec.n == 4 { classify::<4>(rec, e, px, py) } else { classify::<3>(rec, e, px, py) };
            let candidates = cols & !outside;
            if candidates == 0 {
                continue;
            }
            let mut slow = if rec.masked { candidates } else { candidates & !inside };
            let fast = candidates & !slow;
            let at = row * out.width + bx as usize;
            if fast != 0 {
                slow |= if full {
                    depth_test(rec.prim, e, px, py, fast, out, at)
                } else {
                    depth_test_lanes(rec.prim, e, bx, py, fast, out, at)
                };
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
    exact
}

/// Inside (every edge above the band) and outside (one below minus the band) lane masks;
/// for a flat record nothing is inside and outside needs one edge below and another above.
#[inline(always)]
fn classify<const N: usize>(rec: &Record, e: &EyeEdges, px: F32s, py: f32) -> (u32, u32) {
    let band = F32s::splat(rec.band);
    let mut above_all = F32s::splat(f32::from_bits(u32::MAX));
    let mut above_any = F32s::ZERO;
    let mut below_any = F32s::ZERO;
    for k in 0..N {
        let c_row = e.b[k] * py + e.c[k];
        let d = F32s::splat(e.a[k]) * px + F32s::splat(c_row);
        let above = d.simd_gt(band);
        above_all &= above;
        above_any |= above;
        below_any |= d.simd_lt(-band);
    }
    if rec.flat { (0, (below_any & above_any).to_bitmask()) } else { (above_all.to_bitmask(), below_any.to_bitmask()) }
}

/// The depth test of the lanes `fast` (certainly inside, not masked) of a full block at
/// plane index `at`: nearer by more than both error bounds writes; returns the near ties.
#[inline(always)]
fn depth_test(prim: u32, e: &EyeEdges, px: F32s, py: f32, fast: u32, out: &mut BandOut<'_>, at: usize) -> u32 {
    let q_row = e.qb * py + e.qc;
    let q = F32s::splat(e.qa) * px + F32s::splat(q_row);
    let stored_q = F32s::from(<[f32; 8]>::try_from(&out.q[at..at + LANES]).expect("8 lanes"));
    let stored_e = F32s::from(<[f32; 8]>::try_from(&out.q_err[at..at + LANES]).expect("8 lanes"));
    let tol = stored_e + F32s::splat(e.q_err);
    let win = (q - stored_q).simd_gt(tol).to_bitmask() & fast;
    let lose = (stored_q - q).simd_gt(tol).to_bitmask() & fast;
    if win != 0 {
        let q = q.to_array();
        let mut m = win;
        while m != 0 {
            let lane = m.trailing_zeros() as usize;
            m &= m - 1;
            out.prim[at + lane] = prim;
            out.q[at + lane] = q[lane];
            out.q_err[at + lane] = e.q_err;
        }
    }
    fast & !win & !lose
}

/// [`depth_test`] one lane at a time (a block reaching past the right border).
#[inline(never)]
fn depth_test_lanes(prim: u32, e: &EyeEdges, bx: i32, py: f32, fast: u32, out: &mut BandOut<'_>, at: usize) -> u32 {
    let q_row = e.qb * py + e.qc;
    let mut ties = 0;
    let mut m = fast;
    while m != 0 {
        let lane = m.trailing_zeros() as usize;
        m &= m - 1;
        let q = e.qa * ((bx + lane as i32) as f32 + 0.5) + q_row;
        let (sq, se) = (out.q[at + lane], out.q_err[at + lane]);
        let tol = se + e.q_err;
        if q - sq > tol {
            out.prim[at + lane] = prim;
            out.q[at + lane] = q;
            out.q_err[at + lane] = e.q_err;
        } else if !(sq - q > tol) {
            ties |= 1 << lane;
        }
    }
    ties
}
