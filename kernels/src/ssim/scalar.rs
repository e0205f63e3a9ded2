//! The scalar reference (f64, whole-image planes) and the exact per-voxel formula.
//!
//! Both compute *centred* second moments, so no cancellation is involved:
//! * [`run`] filters separably in two levels (law of total variance): per row, the
//!   horizontal mean `m` and the centred moments `Σ w (x − m)²`, `Σ w (x − m)(y − m_y)`; per
//!   column, `σ² = Σ w (v + (m − μ)²)`;
//! * [`exact_voxel`] evaluates the 11×11 window directly, mean first, then the centred sums.
//!
//! Both mix the channels of the 3-D variant with `M` and the law of total variance, and use
//! the textbook map `((2μxμy + C1)(2σxy + C2)) / ((μx² + μy² + C1)(σx² + σy² + C2))`.
//! Exclusion follows the definition literally: an explicit mask of unusable samples,
//! dilated by the window.

use super::{C1, C2, Partial, RADIUS, SsimVariant, TAPS, channel_mixing_matrix, gaussian_weights, usable};
use crate::frame::{Plane, RgbPlanes};

/// Window statistics of one channel at one pixel: `[μx, μy, σx², σy², σxy]`.
type Stats = [f64; 5];

#[inline]
fn clamp_index(i: isize, n: usize) -> usize {
    i.clamp(0, n as isize - 1) as usize
}

/// The SSIM map value from (possibly mixed) window statistics.
#[inline]
fn map_value(s: &Stats) -> f64 {
    let [mx, my, vx, vy, cxy] = *s;
    let (c1, c2) = (C1, C2);
    ((2.0 * (mx * my) + c1) * (2.0 * cxy + c2)) / ((mx * mx + my * my + c1) * (vx + vy + c2))
}

/// Mixes the per-channel statistics of one pixel into the 3-D statistics of channel `c`:
/// `μ₃ = Σ M μ`, `σ²₃ = Σ M (σ² + (μ − μ₃)²)`, `σxy₃ = Σ M (σxy + (μx − μx₃)(μy − μy₃))`.
#[inline]
fn mix(stats: &[Stats; 3], m: &[[f64; 3]; 3], c: usize) -> Stats {
    let mut mx = 0.0;
    let mut my = 0.0;
    for k in 0..3 {
        mx += m[c][k] * stats[k][0];
        my += m[c][k] * stats[k][1];
    }
    let (mut vx, mut vy, mut cxy) = (0.0, 0.0, 0.0);
    for k in 0..3 {
        let (dx, dy) = (stats[k][0] - mx, stats[k][1] - my);
        vx += m[c][k] * (stats[k][2] + dx * dx);
        vy += m[c][k] * (stats[k][3] + dy * dy);
        cxy += m[c][k] * (stats[k][4] + dx * dy);
    }
    [mx, my, vx, vy, cxy]
}

/// 2-D window statistics of one channel at `(px, py)` by the direct formula; `None` if the
/// window holds an unusable sample. The window is gathered once (clamped indices, one row
/// slice per tap row), then summed twice in row-major order.
fn window_stats(a: &Plane<'_>, b: &Plane<'_>, px: usize, py: usize, w: &[f64; TAPS]) -> Option<Stats> {
    let clamped = |p: usize, k: usize, n: usize| clamp_index(p as isize + k as isize - RADIUS as isize, n);
    let xs: [usize; TAPS] = core::array::from_fn(|k| clamped(px, k, a.width()));
    let mut window = [[0.0f64; 2]; TAPS * TAPS];
    for ky in 0..TAPS {
        let y = clamped(py, ky, a.height());
        let (row_a, row_b) = (a.row(y), b.row(y));
        for (kx, &x) in xs.iter().enumerate() {
            let (u, v) = (row_a[x], row_b[x]);
            if !usable(u) || !usable(v) {
                return None;
            }
            window[ky * TAPS + kx] = [f64::from(u), f64::from(v)];
        }
    }
    let weighted = || (0..TAPS * TAPS).map(|k| (w[k % TAPS] * w[k / TAPS], window[k]));
    let (mut mx, mut my) = (0.0, 0.0);
    for (wt, [u, v]) in weighted() {
        mx += wt * u;
        my += wt * v;
    }
    let (mut vx, mut vy, mut cxy) = (0.0, 0.0, 0.0);
    for (wt, [u, v]) in weighted() {
        let (du, dv) = (u - mx, v - my);
        vx += wt * du * du;
        vy += wt * dv * dv;
        cxy += wt * du * dv;
    }
    Some([mx, my, vx, vy, cxy])
}

/// The exact SSIM map value of voxel `(x, y, channel)` (f64, direct window, centred
/// moments), or `None` if the voxel is excluded (its window holds an unusable sample).
/// This is the fast kernel's last-resort refinement and a per-voxel oracle for tests.
/// Panics if the position is outside the images or the extents differ.
pub fn exact_voxel(
    a: &RgbPlanes<'_>,
    b: &RgbPlanes<'_>,
    variant: SsimVariant,
    x: usize,
    y: usize,
    channel: usize,
) -> Option<f64> {
    assert_eq!(a.extent(), b.extent(), "images differ in size");
    assert!(x < a.extent().width() && y < a.extent().height() && channel < 3, "voxel outside the image");
    let w = gaussian_weights();
    let (pa, pb) = (a.channels(), b.channels());
    match variant {
        SsimVariant::PerChannel => window_stats(&pa[channel], &pb[channel], x, y, &w).map(|s| map_value(&s)),
        SsimVariant::Volume => {
            let mut stats = [[0.0; 5]; 3];
            for c in 0..3 {
                stats[c] = window_stats(&pa[c], &pb[c], x, y, &w)?;
            }
            Some(map_value(&mix(&stats, &channel_mixing_matrix(), channel)))
        }
    }
}

/// Horizontal pass of one channel: per pixel, `[m_x, m_y, Σw(x−m_x)², Σw(y−m_y)², Σw(x−m_x)(y−m_y)]`
/// over the row window. Unusable samples are read as 0 (their voxels are excluded anyway).
fn horizontal(x: &[f64], y: &[f64], width: usize, height: usize, w: &[f64; TAPS]) -> Vec<Stats> {
    let mut out = vec![[0.0; 5]; width * height];
    for row in 0..height {
        let (xr, yr) = (&x[row * width..][..width], &y[row * width..][..width]);
        for col in 0..width {
            let at = |k: usize| clamp_index(col as isize + k as isize - RADIUS as isize, width);
            let (mut mx, mut my) = (0.0, 0.0);
            for k in 0..TAPS {
                mx += w[k] * xr[at(k)];
                my += w[k] * yr[at(k)];
            }
            let (mut vx, mut vy, mut cxy) = (0.0, 0.0, 0.0);
            for k in 0..TAPS {
                let (du, dv) = (xr[at(k)] - mx, yr[at(k)] - my);
                vx += w[k] * du * du;
                vy += w[k] * dv * dv;
                cxy += w[k] * du * dv;
            }
            out[row * width + col] = [mx, my, vx, vy, cxy];
        }
    }
    out
}

/// Vertical pass at `(col, row)` over the horizontal statistics (law of total variance).
fn vertical(h: &[Stats], width: usize, height: usize, col: usize, row: usize, w: &[f64; TAPS]) -> Stats {
    let at = |k: usize| &h[clamp_index(row as isize + k as isize - RADIUS as isize, height) * width + col];
    let (mut mx, mut my) = (0.0, 0.0);
    for (k, &wk) in w.iter().enumerate() {
        mx += wk * at(k)[0];
        my += wk * at(k)[1];
    }
    let (mut vx, mut vy, mut cxy) = (0.0, 0.0, 0.0);
    for (k, &wk) in w.iter().enumerate() {
        let s = at(k);
        let (dx, dy) = (s[0] - mx, s[1] - my);
        vx += wk * (s[2] + dx * dx);
        vy += wk * (s[3] + dy * dy);
        cxy += wk * (s[4] + dx * dy);
    }
    [mx, my, vx, vy, cxy]
}

/// `true` where the 11×11 window around a pixel holds a `true` of `bad` (replicate padding
/// adds no new samples, so the window is the clamped rectangle).
fn dilate(bad: &[bool], width: usize, height: usize) -> Vec<bool> {
    let mut rows = vec![false; width * height];
    for r in 0..height {
        for c in 0..width {
            let lo = c.saturating_sub(RADIUS);
            let hi = (c + RADIUS).min(width - 1);
            rows[r * width + c] = bad[r * width + lo..=r * width + hi].iter().any(|&b| b);
        }
    }
    let mut out = vec![false; width * height];
    for r in 0..height {
        let lo = r.saturating_sub(RADIUS);
        let hi = (r + RADIUS).min(height - 1);
        for c in 0..width {
            out[r * width + c] = (lo..=hi).any(|rr| rows[rr * width + c]);
        }
    }
    out
}

/// The scalar reference: sums over the whole image.
pub(super) fn run(a: &RgbPlanes<'_>, b: &RgbPlanes<'_>, variant: SsimVariant) -> Partial {
    let (width, height) = (a.extent().width(), a.extent().height());
    let n = width * height;
    let w = gaussian_weights();
    let m = channel_mixing_matrix();
    let mut p = Partial::default();

    let mut hstats = Vec::with_capacity(3);
    let mut bad = Vec::with_capacity(3);
    for (pa, pb) in a.channels().iter().zip(b.channels().iter()) {
        let mut xs = vec![0.0f64; n];
        let mut ys = vec![0.0f64; n];
        let mut bd = vec![false; n];
        for r in 0..height {
            for (c, (&u, &v)) in pa.row(r).iter().zip(pb.row(r)).enumerate() {
                let i = r * width + c;
                p.non_finite += u64::from(!usable(u)) + u64::from(!usable(v));
                if usable(u) && usable(v) {
                    let d = f64::from(u) - f64::from(v);
                    p.sq += d * d;
                    p.sq_n += 1;
                    xs[i] = f64::from(u);
                    ys[i] = f64::from(v);
                } else {
                    bd[i] = true;
                }
            }
        }
        hstats.push(horizontal(&xs, &ys, width, height, &w));
        bad.push(dilate(&bd, width, height));
    }

    for r in 0..height {
        for col in 0..width {
            let i = r * width + col;
            let stats = [0, 1, 2].map(|k| vertical(&hstats[k], width, height, col, r, &w));
            for c in 0..3 {
                let v = match variant {
                    SsimVariant::PerChannel if bad[c][i] => continue,
                    SsimVariant::PerChannel => map_value(&stats[c]),
                    SsimVariant::Volume if bad[0][i] || bad[1][i] || bad[2][i] => continue,
                    SsimVariant::Volume => map_value(&mix(&stats, &m, c)),
                };
                p.sum[c] += v;
                p.count[c] += 1;
            }
        }
    }
    p
}
