//! The scalar reference of the resampling kernel: one output pixel at a time.

use super::{Footprint, ResampleInput, renormalise};

/// The scalar reference for one output pixel.
pub fn resample_pixel(input: &ResampleInput<'_>, x: usize, y: usize) -> ([f32; 3], f32) {
    let extent = input.source.extent();
    let Some(fp) = Footprint::new(input.map_x.get(x, y), input.map_y.get(x, y), extent) else {
        return ([0.0; 3], 0.0);
    };
    let weights = fp.weights();
    let in_frame = fp.in_frame(extent);
    let mut sum = [0.0f32; 3];
    let mut total = 0.0f32;
    for (t, &(tx, ty)) in fp.taps().iter().enumerate() {
        if !in_frame[t] || weights[t] == 0.0 {
            continue;
        }
        let (tx, ty) = (tx as usize, ty as usize);
        if let Some(valid) = &input.source_valid
            && valid.get(tx, ty) == 0
        {
            continue;
        }
        let rgb = input.source.get(tx, ty);
        for c in 0..3 {
            sum[c] += weights[t] * rgb[c];
        }
        total += weights[t];
    }
    if total > 0.0 {
        let inv_total = 1.0 / total;
        (sum.map(|s| renormalise(s, inv_total)), total.min(1.0))
    } else {
        ([0.0; 3], 0.0)
    }
}
