//! The scalar reference of the fragment loop: one pixel at a time, the same f32 expressions
//! in the same order as [`super::simd`], so both produce the same buffers bit for bit.

use super::{AlphaTest, BandOut, EyeView, Record};

/// Walks `rec` over the rows of `out` in `eye`; returns how many fragments took the exact
/// path, and how many of those were near ties.
pub(crate) fn record<M: AlphaTest>(
    rec: &Record,
    eye: usize,
    view: &EyeView<'_, M>,
    out: &mut BandOut<'_>,
) -> (u64, u64) {
    let e = &rec.eyes[eye];
    let Some(((c0, c1), (y0, y1))) = rec.walk_span(eye, out) else { return (0, 0) };
    let edges = rec.n as usize;
    let band = rec.band;
    let (mut exact, mut ties) = (0, 0);
    for y in y0..=y1 {
        let py = (y - rec.rows.0) as f32 + 0.5;
        let c_row = [0, 1, 2, 3].map(|k| e.b[k] * py + e.c[k]);
        let q_row = e.qb * py + e.qc;
        for x in c0..=c1 {
            let px = (x - c0) as f32 + 0.5;
            let d = [0, 1, 2, 3].map(|k| e.a[k] * px + c_row[k]);
            let below = (0..edges).any(|k| d[k] < -band);
            let (inside, outside) = if rec.flat {
                (false, below && (0..edges).any(|k| d[k] > band))
            } else {
                ((0..edges).all(|k| d[k] > band), below)
            };
            if outside {
                continue;
            }
            let i = (y as usize - out.rows.start) * out.width + x as usize;
            let stored = (&mut out.prim[i], &mut out.q[i], &mut out.q_err[i]);
            if rec.masked || !inside {
                view.resolve_exact(rec.prim, x as usize, y as usize, stored);
                exact += 1;
                continue;
            }
            let q = e.qa * px + q_row;
            let tol = *stored.2 + e.q_err;
            if q - *stored.1 > tol {
                (*stored.0, *stored.1, *stored.2) = (rec.prim, q, e.q_err);
            } else if !(*stored.1 - q > tol) {
                // A near tie (or an empty pixel a surface this far cannot claim by q).
                view.resolve_exact(rec.prim, x as usize, y as usize, stored);
                exact += 1;
                ties += 1;
            }
        }
    }
    (exact, ties)
}
