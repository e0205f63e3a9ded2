//! The SIMD body of the resampling kernel: eight output pixels at a time, the same
//! expressions as [`super::scalar`] lane for lane.

use super::scalar::resample_pixel;
use super::{Footprints, ResampleInput, coherent_row, renormalise_simd};
use crate::simd::{F32s, LANES, TapCoords, load, store};

/// One output row of [`super::resample`]: eight pixels at a time, the tail through the
/// scalar reference.
#[inline(always)]
pub(super) fn resample_row(input: &ResampleInput<'_>, y: usize, colour: [&mut [f32]; 3], weight: &mut [f32]) {
    let width = weight.len();
    let mut x = 0;
    while x + LANES <= width {
        let (rgb, w) = resample_lanes(input, x, y);
        for c in 0..3 {
            store(colour[c], x, rgb[c]);
        }
        store(weight, x, w);
        x += LANES;
    }
    for x in x..width {
        let (rgb, w) = resample_pixel(input, x, y);
        for c in 0..3 {
            colour[c][x] = rgb[c];
        }
        weight[x] = w;
    }
}

/// The SIMD body for `LANES` output pixels starting at `(x, y)`.
#[inline(always)]
fn resample_lanes(input: &ResampleInput<'_>, x: usize, y: usize) -> ([F32s; 3], F32s) {
    let extent = input.source.extent();
    let fp = Footprints::new(load(input.map_x.row(y), x), load(input.map_y.row(y), x), extent);
    let weights = fp.weights();
    let in_frame = fp.in_frame(extent);
    let mut sum = [F32s::ZERO; 3];
    let mut total = F32s::ZERO;
    let planes = input.source.channels();
    // A coherent group (consecutive source columns on one row, all taps inside) loads each
    // tap as a contiguous vector instead of gathering lane by lane: same values, same bits.
    let coherent = coherent_row(&fp, fp.inside, extent);
    for (t, &(tx, ty)) in fp.taps().iter().enumerate() {
        let mut accept = in_frame[t] & weights[t].simd_gt(F32s::ZERO);
        if accept.none() {
            continue;
        }
        let values: [F32s; 3] = match coherent {
            Some((x0, y0)) => {
                let (x, y) = (x0 + t % 2, y0 + t / 2);
                if let Some(valid) = &input.source_valid {
                    let v = &valid.row(y)[x..x + LANES];
                    accept &= F32s::from(core::array::from_fn::<f32, LANES, _>(|i| {
                        if v[i] != 0 { f32::from_bits(u32::MAX) } else { 0.0 }
                    }));
                }
                [0, 1, 2].map(|c| load(planes[c].row(y), x))
            }
            None => {
                let coords = TapCoords::clamped(tx, ty, extent.width(), extent.height());
                if let Some(valid) = &input.source_valid {
                    let v = coords.gather(valid).map(|b| if b != 0 { f32::from_bits(u32::MAX) } else { 0.0 });
                    accept &= F32s::from(v);
                }
                [0, 1, 2].map(|c| coords.gather_f32(&planes[c]))
            }
        };
        for c in 0..3 {
            sum[c] += accept.select(weights[t] * values[c], F32s::ZERO);
        }
        total += accept.select(weights[t], F32s::ZERO);
    }
    let any = total.simd_gt(F32s::ZERO);
    let inv_total = F32s::ONE / total;
    let colour = sum.map(|s| any.select(renormalise_simd(s, inv_total), F32s::ZERO));
    (colour, any.select(total.min(F32s::ONE), F32s::ZERO))
}
