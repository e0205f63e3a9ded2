//! The SIMD body of backward reprojection: eight target pixels at a time, with the
//! coherent path of the module notes; the row tail goes through [`super::scalar`].

use super::scalar::write_pixel;
use super::{Prepared, Reason, ReasonCounts, RowOut};
use crate::bilinear::{Footprints, coherent_row, renormalise_simd};
use crate::frame::Plane;
use crate::gbuffer::{SurfaceLayout, Surfels};
use crate::simd::{F32s, LANES, TapCoords, any_nonzero, flush_subnormal, leading_zero_bytes, store};

/// One output row through the SIMD body (`C` channels), the tail through the scalar one.
#[inline(always)]
pub(super) fn simd_row<L: SurfaceLayout, const C: usize, const AVX512: bool>(
    p: &Prepared<'_, L>,
    y: usize,
    row: &mut RowOut<'_>,
) -> ReasonCounts {
    let mut counts = ReasonCounts::default();
    let width = row.reason.len();
    let mut cache = [SourceCache::EMPTY; 2];
    let mask_row = p.pixel_mask.map(|m| m.row(y));
    // Both G-buffers compact and no pixel mask: the AVX-512 body tries 16 pixels at a time.
    #[cfg(target_arch = "x86_64")]
    let compact = match (AVX512, p.target.as_compact(), p.source.as_compact(), mask_row) {
        (true, Some(target), Some(source), None) => Some((target, source)),
        _ => None,
    };
    // After a group the 16-pixel path refused, the next one goes to the 8-lane body too
    // (refusals come in runs: edges, skies, disocclusions).
    #[cfg(target_arch = "x86_64")]
    let mut wide_from = 0;
    // Prefetches of the wanted groups, running a few groups ahead of the walk.
    let mut ahead = p.pixel_mask.as_ref().map(|m| WantedAhead::new(m, y));
    if let Some(ahead) = &mut ahead {
        for _ in 0..WANTED_AHEAD_GROUPS {
            ahead.advance(p, row);
        }
    }
    let mut x = 0;
    while x + LANES <= width {
        #[cfg(target_arch = "x86_64")]
        if let Some((target, source)) = compact
            && x >= wide_from
            && x + super::wide::WIDE <= width
        {
            // SAFETY: `compact` is `Some` only with `AVX512`, which only `simd_row_avx512`
            // sets, after checking the CPU; x + 16 <= width is tested above.
            if unsafe { super::wide::group::<L, C>(p, target, source, x, y, row, &mut counts) } {
                x += super::wide::WIDE;
                continue;
            }
            wide_from = x + super::wide::WIDE;
        }
        // Bit `i` set where lane `i` is to be reprojected.
        let wanted = match mask_row {
            None => ALL_LANES,
            Some(m) if !any_nonzero(&m[x..x + LANES]) => {
                // An empty stretch of the mask at once: its reasons, then the group with the
                // next wanted pixel (or the row's tail).
                let groups = leading_zero_bytes(&m[x..width - width % LANES]) / LANES;
                row.reason[x..x + groups * LANES].fill(Reason::Invalid as u8);
                x += groups * LANES;
                continue;
            }
            Some(m) => {
                // One wanted group reached: one more prefetched ahead.
                if let Some(ahead) = &mut ahead {
                    ahead.advance(p, row);
                }
                wanted_bits(&m[x..x + LANES])
            }
        };
        let lanes = reproject_lanes::<L, C>(p, x, y, &mut cache);
        // Lanes outside the mask keep what the output held.
        let put = |dst: &mut [f32], v: F32s| {
            if wanted == ALL_LANES {
                store(dst, x, v);
            } else {
                for (i, (d, v)) in dst[x..x + LANES].iter_mut().zip(v.to_array()).enumerate() {
                    if wanted & (1 << i) != 0 {
                        *d = v;
                    }
                }
            }
        };
        for c in 0..C {
            put(row.channels[c], lanes.channels[c]);
        }
        if let Some(w) = row.weight.as_deref_mut() {
            put(w, lanes.weight);
        }
        let reasons = &mut row.reason[x..x + LANES];
        if wanted == ALL_LANES && lanes.ok_bits == ALL_LANES {
            // The common case: every lane reprojected (code 0).
            reasons.fill(Reason::Reprojected as u8);
            counts.0[Reason::Reprojected as usize] += LANES as u64;
        } else {
            for (i, (dst, code)) in reasons.iter_mut().zip(lanes.reason.to_array()).enumerate() {
                if wanted & (1 << i) != 0 {
                    *dst = code as u8;
                    counts.0[usize::from(*dst)] += 1;
                } else {
                    *dst = Reason::Invalid as u8;
                }
            }
        }
        x += LANES;
    }
    super::background::background_row::<L, C>(p, y, x, row, &mut counts);
    for x in x..width {
        write_pixel(p, x, y, row, &mut counts);
    }
    counts
}

/// How many wanted groups a masked walk prefetches ahead of the one it reprojects.
const WANTED_AHEAD_GROUPS: usize = 4;

/// A cursor over a sparse pixel mask that prefetches the planes of the groups it wants, some
/// wanted groups before the walk reaches them. Those planes are uncached (nothing near them
/// was read this frame) and scattered along silhouettes, a pattern the hardware prefetcher
/// cannot foresee but the mask names in advance. The cursor runs from row `y` into row
/// `y + 1`, so a row's first wanted groups were prefetched by the row before.
struct WantedAhead<'m> {
    rows: [&'m [u8]; 2],
    y: usize,
    /// Which of `rows` the cursor is in.
    row: usize,
    /// The first column (a group's) not yet searched.
    x: usize,
}

impl<'m> WantedAhead<'m> {
    fn new(mask: &Plane<'m, u8>, y: usize) -> Self {
        let next = if y + 1 < mask.height() { mask.row(y + 1) } else { &[] };
        Self { rows: [mask.row(y), next], y, row: 0, x: 0 }
    }

    /// Prefetches the next wanted group after the cursor, if the two rows hold one (their
    /// scalar tails are left out: the walk reads those a pixel at a time).
    #[inline(always)]
    fn advance<L: SurfaceLayout>(&mut self, p: &Prepared<'_, L>, out: &RowOut<'_>) {
        while self.row < 2 {
            let mask = self.rows[self.row];
            let end = mask.len() - mask.len() % LANES;
            if self.x < end {
                let group = self.x + leading_zero_bytes(&mask[self.x..end]) / LANES * LANES;
                if group < end {
                    prefetch_group(p, group, self.y + self.row);
                    if self.row == 0 {
                        // The output lines it will write (a group writes only some lanes,
                        // so each line is read first).
                        out.channels[..p.channel_count].iter().for_each(|c| crate::simd::prefetch(&c[group]));
                    }
                    self.x = group + LANES;
                    return;
                }
            }
            (self.row, self.x) = (self.row + 1, 0);
        }
    }
}

/// Bit `i` set where `mask[i]` is non-zero (the first `LANES` bytes).
#[inline(always)]
fn wanted_bits(mask: &[u8]) -> u32 {
    mask[..LANES].iter().enumerate().fold(0, |bits, (i, &v)| bits | (u32::from(v != 0) << i))
}

/// Prefetches what the group at `(x, y)` will read: the target's planes, and the source's
/// planes and samples on rows `y − 1 ..= y + 1`.
#[inline(always)]
fn prefetch_group<L: SurfaceLayout>(p: &Prepared<'_, L>, x: usize, y: usize) {
    p.target.prefetch(x, y);
    if let Some(motion) = &p.motion {
        motion.iter().for_each(|m| m.prefetch(x, y));
    }
    for sy in y.saturating_sub(1)..=y + 1 {
        p.source.prefetch(x, sy);
        p.channels[..p.channel_count].iter().for_each(|c| c.prefetch(x, sy));
    }
}

#[inline(always)]
fn len2_simd(v: [F32s; 3]) -> F32s {
    v[0] * v[0] + v[1] * v[1] + v[2] * v[2]
}

/// A lane bit set with every lane.
const ALL_LANES: u32 = (1 << LANES) - 1;

/// Results for `LANES` pixels.
struct Lanes<const C: usize> {
    channels: [F32s; C],
    weight: F32s,
    /// Reason codes as floats (exact small integers).
    reason: F32s,
    /// Bit `i` set where lane `i` was reprojected.
    ok_bits: u32,
}

/// All-ones where every value is finite. `v · 0` is ±0 for finite `v` and NaN for ±inf or
/// NaN, so one sum and one compare test them all (two instructions per value instead of
/// the four of a bit-pattern test).
#[inline(always)]
pub(super) fn all_finite_simd<const N: usize>(values: [F32s; N]) -> F32s {
    let mut poison = F32s::ZERO;
    for v in values {
        poison += v * F32s::ZERO;
    }
    poison.simd_eq(F32s::ZERO)
}

#[inline(always)]
fn usable_simd(s: &Surfels, normal_len2: F32s) -> F32s {
    let [p0, p1, p2] = s.position;
    all_finite_simd([s.depth, p0, p1, p2, normal_len2]) & normal_len2.simd_gt(F32s::ZERO) & s.depth.simd_gt(F32s::ZERO)
}

/// Where the SIMD body loads a tap's surfels and samples from.
trait TapSource {
    /// Per-tap in-frame masks.
    fn in_frame<L: SurfaceLayout>(&self, p: &Prepared<'_, L>, fp: &Footprints) -> [F32s; 4];
    fn load<L: SurfaceLayout, const C: usize>(
        &self,
        p: &Prepared<'_, L>,
        tap: usize,
        fp: &Footprints,
    ) -> (Surfels, [F32s; C]);
}

/// Coherent footprints: tap `t` of lane `i` is source pixel `(x0 + i + (t & 1), y0 + (t >> 1))`,
/// so every plane is read with one unaligned vector load per tap.
struct RowLoads {
    x0: usize,
    y0: usize,
}

impl TapSource for RowLoads {
    /// `coherent_row` only picks this source when every tap of every lane is in frame.
    #[inline(always)]
    fn in_frame<L: SurfaceLayout>(&self, _: &Prepared<'_, L>, fp: &Footprints) -> [F32s; 4] {
        [fp.inside; 4]
    }

    #[inline(always)]
    fn load<L: SurfaceLayout, const C: usize>(
        &self,
        p: &Prepared<'_, L>,
        tap: usize,
        _: &Footprints,
    ) -> (Surfels, [F32s; C]) {
        let (x, y) = (self.x0 + (tap & 1), self.y0 + (tap >> 1));
        // SAFETY: `coherent_row` built this source only with x0 + LANES < width and
        // y0 + 1 < height of the source extent, which the source G-buffer and every channel
        // share (checked in `prepare`), so every lane of every tap is inside.
        unsafe {
            let values = core::array::from_fn(|c| F32s::from(p.channels[c].lanes_unchecked::<LANES>(x, y)));
            (p.source.surfels_row_unchecked(x, y), values)
        }
    }
}

/// Anything else: per-lane gathers from clamped coordinates.
struct Gathers;

impl TapSource for Gathers {
    #[inline(always)]
    fn in_frame<L: SurfaceLayout>(&self, p: &Prepared<'_, L>, fp: &Footprints) -> [F32s; 4] {
        fp.in_frame(p.source_extent)
    }

    #[inline(always)]
    fn load<L: SurfaceLayout, const C: usize>(
        &self,
        p: &Prepared<'_, L>,
        tap: usize,
        fp: &Footprints,
    ) -> (Surfels, [F32s; C]) {
        let (tx, ty) = fp.taps()[tap];
        let coords = TapCoords::clamped(tx, ty, p.source_extent.width(), p.source_extent.height());
        let values = core::array::from_fn(|c| coords.gather_f32(&p.channels[c]));
        (p.source.surfels_gather(&coords), values)
    }
}

/// The target side of `LANES` pixels: surface, projection into the source, footprint.
struct TargetLanes {
    surface: Surfels,
    normal_len2: F32s,
    /// Source view depth of the target point (clip w).
    depth_in_source: F32s,
    footprints: Footprints,
    weights: [F32s; 4],
    /// Lanes that go on to the tap tests.
    active: F32s,
    background: F32s,
}

/// Accumulated over the four taps of `LANES` pixels.
struct TapTotals<const C: usize> {
    sum: [F32s; C],
    total: F32s,
    any_accepted: F32s,
    any_failed: F32s,
}

/// Why taps failed (only worked out for groups with a discarded pixel).
#[derive(Default)]
struct Failures {
    geometry: F32s,
    normal: F32s,
    invalid: F32s,
}

/// The SIMD body for target pixels `x .. x + LANES` of row `y`.
///
/// Two passes keep the common case cheap. The first decides acceptance with the smallest
/// predicate that is equivalent to the reference's (see [`accepts`]); only when some lane
/// ends up discarded is the group evaluated again to classify why (a few percent of groups
/// in the paper's scenes).
#[inline(always)]
fn reproject_lanes<L: SurfaceLayout, const C: usize>(
    p: &Prepared<'_, L>,
    x: usize,
    y: usize,
    cache: &mut [SourceCache; 2],
) -> Lanes<C> {
    let code = |r: Reason| F32s::splat(r as u8 as f32);
    // Eight background pixels: what the general path below computes for them, without it
    // (skies, and the pixels a caller masked out by giving them no surface).
    if p.target.depth_row(x, y).simd_eq(F32s::splat(f32::INFINITY)).all() {
        return Lanes { channels: [F32s::ZERO; C], weight: F32s::ZERO, reason: code(Reason::Background), ok_bits: 0 };
    }
    let t = target_lanes(p, x, y);
    let coherent = coherent_row(&t.footprints, t.active, p.source_extent);
    let totals = match coherent {
        Some((x0, y0)) => coherent_taps::<L, C>(p, &t, x0, y0, cache),
        None => evaluate_taps::<L, C, _, false>(p, &t, &Gathers).0,
    };
    let ok = if p.strict { totals.any_accepted & !totals.any_failed } else { totals.any_accepted };
    let reason = if (ok | t.background).all() {
        t.background.select(code(Reason::Background), code(Reason::Reprojected))
    } else {
        let (_, failed) = match coherent {
            Some((x0, y0)) => evaluate_taps::<L, C, _, true>(p, &t, &RowLoads { x0, y0 }),
            None => evaluate_taps::<L, C, _, true>(p, &t, &Gathers),
        };
        let invalid_target = !t.background & !usable_simd(&t.surface, t.normal_len2);
        let discard_reason = failed.geometry.select(
            code(Reason::DepthOrPosition),
            failed
                .normal
                .select(code(Reason::Normal), failed.invalid.select(code(Reason::Invalid), code(Reason::OutOfFrame))),
        );
        t.background.select(
            code(Reason::Background),
            invalid_target.select(code(Reason::Invalid), ok.select(code(Reason::Reprojected), discard_reason)),
        )
    };
    let zero = F32s::ZERO;
    let inv_total = F32s::ONE / totals.total;
    Lanes {
        channels: totals.sum.map(|s| ok.select(flush_subnormal(renormalise_simd(s, inv_total)), zero)),
        weight: ok.select(totals.total.min(F32s::ONE), zero),
        reason,
        ok_bits: ok.to_bitmask(),
    }
}

#[inline(always)]
fn target_lanes<L: SurfaceLayout>(p: &Prepared<'_, L>, x: usize, y: usize) -> TargetLanes {
    let mut surface = p.target.surfels_row(x, y);
    if let Some(motion) = &p.motion {
        // Where the surfaces were when the source frame was rendered (as the reference).
        for i in 0..3 {
            surface.position[i] -= F32s::from(motion[i].lanes::<LANES>(x, y));
        }
    }
    let inf = F32s::splat(f32::INFINITY);
    let background = surface.depth.simd_eq(inf);
    let normal_len2 = len2_simd(surface.normal);
    // Cheaper than `usable_simd` and equivalent for deciding which lanes go on: a non-finite
    // position makes the projection NaN or infinite, which fails the footprint test below.
    let plausible = surface.depth.simd_gt(F32s::ZERO)
        & surface.depth.simd_lt(inf)
        & normal_len2.simd_gt(F32s::ZERO)
        & normal_len2.simd_lt(inf);
    let r = &p.v.rows;
    let clip = |i: usize| {
        r[i][0] * surface.position[0] + r[i][1] * surface.position[1] + r[i][2] * surface.position[2] + r[i][3]
    };
    let (cx, cy, cw) = (clip(0), clip(1), clip(2));
    let mut footprints = footprints_at(p, cx, cy, cw);
    // Lanes that already have a reason take no further part.
    let active = plausible & cw.simd_gt(F32s::ZERO) & footprints.inside;
    footprints.inside = active;
    TargetLanes {
        surface,
        normal_len2,
        depth_in_source: cw,
        weights: footprints.weights(),
        footprints,
        active,
        background,
    }
}

/// The bilinear footprints in the source of clip coordinates `(cx, cy, ·, cw)`, as the
/// reference's `footprint_at` computes them lane by lane (lanes with `cw ≤ 0` are the
/// caller's to mask).
#[inline(always)]
pub(super) fn footprints_at<L: SurfaceLayout>(p: &Prepared<'_, L>, cx: F32s, cy: F32s, cw: F32s) -> Footprints {
    let (hw, hh) = (p.v.half_width, p.v.half_height);
    let inv_w = F32s::ONE / cw;
    let mut sx = (cx * inv_w) * hw + hw;
    let mut sy = (-(cy * inv_w)) * hh + hh;
    if let Some([dx, dy]) = p.jitter_shift {
        // As the reference: the unjittered centre on the unjittered colour grid.
        (sx, sy) = (sx + F32s::splat(dx), sy + F32s::splat(dy));
    }
    Footprints::new_splat(sx, sy, p.v.source_width, p.v.source_height)
}

/// Runs the tap tests over the four taps. With `CLASSIFY`, also records why taps failed.
#[inline(always)]
fn evaluate_taps<L: SurfaceLayout, const C: usize, S: TapSource, const CLASSIFY: bool>(
    p: &Prepared<'_, L>,
    t: &TargetLanes,
    source: &S,
) -> (TapTotals<C>, Failures) {
    let zero = F32s::ZERO;
    let depth_tolerance = (p.v.depth_relative * t.depth_in_source).min(F32s::splat(f32::MAX));
    let mut acc = TapTotals { sum: [zero; C], total: zero, any_accepted: zero, any_failed: zero };
    let mut failed = Failures::default();
    let in_frame = source.in_frame(p, &t.footprints);
    evaluate_tap::<L, C, S, CLASSIFY, 0>(p, t, source, &in_frame, depth_tolerance, &mut acc, &mut failed);
    evaluate_tap::<L, C, S, CLASSIFY, 1>(p, t, source, &in_frame, depth_tolerance, &mut acc, &mut failed);
    evaluate_tap::<L, C, S, CLASSIFY, 2>(p, t, source, &in_frame, depth_tolerance, &mut acc, &mut failed);
    evaluate_tap::<L, C, S, CLASSIFY, 3>(p, t, source, &in_frame, depth_tolerance, &mut acc, &mut failed);
    (acc, failed)
}

/// One tap of [`evaluate_taps`]; `TAP` is a constant so each of the four copies knows its
/// offsets.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn evaluate_tap<L: SurfaceLayout, const C: usize, S: TapSource, const CLASSIFY: bool, const TAP: usize>(
    p: &Prepared<'_, L>,
    t: &TargetLanes,
    source: &S,
    in_frame: &[F32s; 4],
    depth_tolerance: F32s,
    acc: &mut TapTotals<C>,
    failed: &mut Failures,
) {
    let zero = F32s::ZERO;
    let tap = TAP;
    let weight = t.weights[tap];
    let participates = t.active & weight.simd_gt(zero);
    if participates.none() {
        return;
    }
    let tap_in_frame = participates & in_frame[tap];
    let (s, values) = source.load::<L, C>(p, tap, &t.footprints);
    let s_len2 = len2_simd(s.normal);
    let (geometry_ok, normal_ok) = surface_tests(p, t, &s, s_len2, depth_tolerance);
    // Equivalent to the reference's `usable ∧ finite samples ∧ geometry ∧ normal`: with
    // thresholds clamped to f32::MAX, passing the geometry test already implies a finite
    // tap depth and position (and so no background), and `s_len2 ≤ MAX` implies a finite
    // normal. The sign of the depth is the one thing left to check.
    let accepted = tap_in_frame
        & geometry_ok
        & normal_ok
        & s.depth.simd_gt(zero)
        & s_len2.simd_gt(zero)
        & s_len2.simd_le(F32s::splat(f32::MAX))
        & all_finite_simd(values);
    acc.any_failed |= participates & !accepted;
    acc.any_accepted |= accepted;
    for c in 0..C {
        acc.sum[c] += accepted.select(weight * values[c], zero);
    }
    acc.total += accepted.select(weight, zero);
    if CLASSIFY {
        let tap_background = s.depth.simd_eq(F32s::splat(f32::INFINITY));
        let usable_tap = !tap_background & usable_simd(&s, s_len2) & all_finite_simd(values);
        failed.geometry |= tap_in_frame & (tap_background | (usable_tap & !geometry_ok));
        failed.normal |= tap_in_frame & usable_tap & geometry_ok & !normal_ok;
        failed.invalid |= tap_in_frame & !tap_background & !usable_tap;
    }
}

/// The geometry (world-position distance and relative depth) and normal-angle tests of one
/// tap's source surfels `s` (with squared normal lengths `s_len2`) against the target
/// lanes: `(geometry_ok, normal_ok)`. Shared by the general and the coherent tap paths.
#[inline(always)]
fn surface_tests<L: SurfaceLayout>(
    p: &Prepared<'_, L>,
    t: &TargetLanes,
    s: &Surfels,
    s_len2: F32s,
    depth_tolerance: F32s,
) -> (F32s, F32s) {
    let tp = &t.surface.position;
    let d = [s.position[0] - tp[0], s.position[1] - tp[1], s.position[2] - tp[2]];
    let distance2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    let geometry_ok = distance2.simd_le(p.v.position2) & (s.depth - t.depth_in_source).abs().simd_le(depth_tolerance);
    let tn = &t.surface.normal;
    let dot = s.normal[0] * tn[0] + s.normal[1] * tn[1] + s.normal[2] * tn[2];
    let bound = p.v.normal_cos2 * (s_len2 * t.normal_len2);
    let facing = dot.simd_ge(F32s::ZERO);
    let normal_ok =
        if p.normal_cos_positive { facing & (dot * dot).simd_ge(bound) } else { facing | (dot * dot).simd_le(bound) };
    (geometry_ok, normal_ok)
}

/// What the tap tests need of `LANES` consecutive source pixels of one row, worked out once
/// per pixel: in a coherent group, tap 1 of lane `i` is tap 0 of lane `i + 1` (and tap 3 of
/// tap 2), and the next group's tap 0 is usually this group's tap-1 row shifted by `LANES`.
#[derive(Clone, Copy)]
struct SourceLanes {
    surface: Surfels,
    /// Squared length of the (unnormalised) normal.
    len2: F32s,
    /// All-ones where the pixel can be accepted at all: in front of its camera, a usable
    /// normal and finite samples in every channel (the part of [`evaluate_tap`]'s
    /// acceptance that does not depend on the target).
    usable: F32s,
}

/// A decoded [`SourceLanes`] of pixels `x .. x + LANES` of source row `y`, kept from one
/// group to the next.
#[derive(Clone, Copy)]
struct SourceCache {
    x: usize,
    y: usize,
    lanes: SourceLanes,
}

impl SourceCache {
    const EMPTY: Self = Self {
        x: usize::MAX,
        y: usize::MAX,
        lanes: SourceLanes {
            surface: Surfels { depth: F32s::ZERO, position: [F32s::ZERO; 3], normal: [F32s::ZERO; 3] },
            len2: F32s::ZERO,
            usable: F32s::ZERO,
        },
    };
}

/// Decodes source pixels `x .. x + LANES` of row `y` for the tap tests.
///
/// # Safety
/// `x + LANES <= width` and `y < height` of the source extent.
#[inline(always)]
unsafe fn source_lanes<L: SurfaceLayout, const C: usize>(p: &Prepared<'_, L>, x: usize, y: usize) -> SourceLanes {
    // SAFETY: forwarded from the caller; the source G-buffer and every channel share the
    // source extent (checked in `prepare`).
    let (surface, values) = unsafe {
        let values: [F32s; C] = core::array::from_fn(|c| F32s::from(p.channels[c].lanes_unchecked::<LANES>(x, y)));
        (p.source.surfels_row_unchecked(x, y), values)
    };
    let len2 = len2_simd(surface.normal);
    let usable = surface.depth.simd_gt(F32s::ZERO)
        & len2.simd_gt(F32s::ZERO)
        & len2.simd_le(F32s::splat(f32::MAX))
        & all_finite_simd(values);
    SourceLanes { surface, len2, usable }
}

/// `[a₁, …, a₇, b₀]`: the lanes of `a` moved down by one, with `b`'s first lane on top.
#[inline(always)]
fn shift_lanes(a: F32s, b: F32s) -> F32s {
    #[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
    {
        use core::arch::x86_64::{__m256, _mm256_blend_ps, _mm256_permutevar8x32_ps, _mm256_setr_epi32};
        // SAFETY: the intrinsics need AVX2, which this build targets (the cfg above).
        unsafe {
            // [b₀, a₁, …, a₇], then rotated down by one lane: two instructions.
            let merged = _mm256_blend_ps::<1>(__m256::from(a), __m256::from(b));
            F32s::from(_mm256_permutevar8x32_ps(merged, _mm256_setr_epi32(1, 2, 3, 4, 5, 6, 7, 0)))
        }
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "avx2")))]
    {
        let (a, b) = (a.to_array(), b.to_array());
        F32s::from([a[1], a[2], a[3], a[4], a[5], a[6], a[7], b[0]])
    }
}

impl SourceLanes {
    /// [`shift_lanes`] of every field.
    #[inline(always)]
    fn shifted(&self, next: &Self) -> Self {
        let (a, b) = (&self.surface, &next.surface);
        Self {
            surface: Surfels {
                depth: shift_lanes(a.depth, b.depth),
                position: [0, 1, 2].map(|i| shift_lanes(a.position[i], b.position[i])),
                normal: [0, 1, 2].map(|i| shift_lanes(a.normal[i], b.normal[i])),
            },
            len2: shift_lanes(self.len2, next.len2),
            usable: shift_lanes(self.usable, next.usable),
        }
    }
}

/// The first pass of [`evaluate_taps`] for a coherent group (see [`coherent_row`](crate::bilinear::coherent_row)), with
/// each source pixel decoded once: tap 0 of row `r` reads pixels `x0 ..`, tap 1 the same
/// lanes shifted by one with the next vector's first pixel on top; that next vector is kept
/// for the next group, whose tap 0 usually starts there. Same tests, same order, same bits.
#[inline(always)]
fn coherent_taps<L: SurfaceLayout, const C: usize>(
    p: &Prepared<'_, L>,
    t: &TargetLanes,
    x0: usize,
    y0: usize,
    cache: &mut [SourceCache; 2],
) -> TapTotals<C> {
    let zero = F32s::ZERO;
    let depth_tolerance = (p.v.depth_relative * t.depth_in_source).min(F32s::splat(f32::MAX));
    let mut acc = TapTotals { sum: [zero; C], total: zero, any_accepted: zero, any_failed: zero };
    let width = p.source_extent.width();
    for (r, slot) in cache.iter_mut().enumerate() {
        let (w0, w1) = (t.weights[2 * r], t.weights[2 * r + 1]);
        let (p0, p1) = (t.active & w0.simd_gt(zero), t.active & w1.simd_gt(zero));
        if (p0 | p1).none() {
            continue;
        }
        let y = y0 + r;
        // Bounds (for every `source_lanes` and channel load below): `coherent_row` returned
        // (x0, y0) only with x0 + LANES < width and y0 + 1 < height of the source extent,
        // and the x0 + LANES (next vector) decode is guarded by its own bounds test.
        if slot.x != x0 || slot.y != y {
            // SAFETY: (x0, y) is within the source as above.
            *slot = SourceCache { x: x0, y, lanes: unsafe { source_lanes::<L, C>(p, x0, y) } };
        }
        if p0.any() {
            // SAFETY: as above; every channel has the source's extent (checked in `prepare`).
            let values = unsafe { core::array::from_fn(|c| F32s::from(p.channels[c].lanes_unchecked::<LANES>(x0, y))) };
            tap_test(p, t, &slot.lanes, values, w0, p0, depth_tolerance, &mut acc);
        }
        if p1.any() {
            let b = if x0 + 2 * LANES <= width {
                // SAFETY: x0 + 2·LANES <= width (the test above) and y as above.
                let next = unsafe { source_lanes::<L, C>(p, x0 + LANES, y) };
                let b = slot.lanes.shifted(&next);
                *slot = SourceCache { x: x0 + LANES, y, lanes: next };
                b
            } else {
                // SAFETY: x0 + LANES < width (`coherent_row`), so x0 + 1 + LANES <= width.
                unsafe { source_lanes::<L, C>(p, x0 + 1, y) }
            };
            // SAFETY: as for the decode above; the channels share the source's extent.
            let values =
                unsafe { core::array::from_fn(|c| F32s::from(p.channels[c].lanes_unchecked::<LANES>(x0 + 1, y))) };
            tap_test(p, t, &b, values, w1, p1, depth_tolerance, &mut acc);
        }
    }
    acc
}

/// One tap of [`coherent_taps`]: [`evaluate_tap`]'s first-pass tests on a decoded source.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn tap_test<L: SurfaceLayout, const C: usize>(
    p: &Prepared<'_, L>,
    t: &TargetLanes,
    src: &SourceLanes,
    values: [F32s; C],
    weight: F32s,
    participates: F32s,
    depth_tolerance: F32s,
    acc: &mut TapTotals<C>,
) {
    let zero = F32s::ZERO;
    let (geometry_ok, normal_ok) = surface_tests(p, t, &src.surface, src.len2, depth_tolerance);
    // Every tap of a coherent group is in frame, so `participates` stands for
    // `participates ∧ in frame` here (see `evaluate_tap` for why this is the reference's test).
    let accepted = participates & geometry_ok & normal_ok & src.usable;
    acc.any_failed |= participates & !accepted;
    acc.any_accepted |= accepted;
    for c in 0..C {
        acc.sum[c] += accepted.select(weight * values[c], zero);
    }
    acc.total += accepted.select(weight, zero);
}
