//! Linear RGB planes to a window's pixels: exposure, Reinhard tone mapping and the sRGB curve
//! ([`crate::image_io::tonemap`], the PNG previews' mapping), packed as softbuffer's `0RGB`
//! `u32`. Eight pixels at a time with `wide`; [`tonemap_row_scalar`] is the reference the
//! tests compare it with (within one step of 255: the vector body fits the sRGB curve with
//! square roots, see `encode`).
//! Non-finite pixels show magenta, as in the previews.

use wide::{f32x8, i32x8};

use crate::image_io::tonemap;

/// Magenta, for pixels that are not finite.
pub const NON_FINITE: u32 = 0x00ff_00ff;

/// Packs 8-bit channels as `0RGB`.
#[inline]
pub fn pack(rgb: [u8; 3]) -> u32 {
    (u32::from(rgb[0]) << 16) | (u32::from(rgb[1]) << 8) | u32::from(rgb[2])
}

/// The reference: [`tonemap`] pixel by pixel. `r`, `g`, `b` and `out` have one length.
pub fn tonemap_row_scalar(r: &[f32], g: &[f32], b: &[f32], exposure: f32, out: &mut [u32]) {
    for (i, o) in out.iter_mut().enumerate() {
        *o = pack(tonemap([r[i], g[i], b[i]], exposure));
    }
}

/// The sRGB-encoded value times 255 of linear `v` scaled by `exposure`, tone mapped.
#[inline(always)]
fn encode(v: f32x8, exposure: f32x8) -> f32x8 {
    let x = (v * exposure).max(f32x8::ZERO);
    let mapped = x / (f32x8::ONE + x);
    let linear = mapped * f32x8::splat(12.92);
    // The curve `1.055 x^(1/2.4) - 0.055` as a fit in x^(1/2), x^(1/4), x^(1/8) (three square
    // roots instead of a log and an exp, 4x faster here): off by at most 0.25 of an 8-bit
    // step on [0.0031308, 1], so the packed byte is the reference's or one next to it.
    let (s1, s2) = (mapped.sqrt(), mapped.sqrt().sqrt());
    let s3 = s2.sqrt();
    let curve = f32x8::splat(0.662_002_7) * s1 + f32x8::splat(0.684_122_1) * s2
        - f32x8::splat(0.323_583_6) * s3
        - f32x8::splat(0.022_541_147) * mapped;
    let srgb = mapped.simd_le(f32x8::splat(0.003_130_8)).select(linear, curve);
    (srgb * f32x8::splat(255.0) + f32x8::splat(0.5)).max(f32x8::ZERO).min(f32x8::splat(255.0))
}

/// [`tonemap_row_scalar`], eight pixels at a time (packing included).
pub fn tonemap_row(r: &[f32], g: &[f32], b: &[f32], exposure: f32, out: &mut [u32]) {
    let n = out.len();
    assert!(r.len() == n && g.len() == n && b.len() == n, "tonemap_row: planes and output of one length");
    let full = n - n % 8;
    let e = f32x8::splat(exposure);
    let load = |p: &[f32], i: usize| f32x8::from(<[f32; 8]>::try_from(&p[i..i + 8]).expect("8 lanes"));
    let magenta = i32x8::splat(NON_FINITE as i32);
    for i in (0..full).step_by(8) {
        let (vr, vg, vb) = (load(r, i), load(g, i), load(b, i));
        let finite: i32x8 = bytemuck::cast(vr.is_finite() & vg.is_finite() & vb.is_finite());
        // `encode` is in [0.5, 255.5): truncation rounds, as the scalar `as u8` of `+ 0.5` does.
        let (cr, cg, cb) = (encode(vr, e).trunc_int(), encode(vg, e).trunc_int(), encode(vb, e).trunc_int());
        let packed = finite.select(cr << 16 | cg << 8 | cb, magenta);
        out[i..i + 8].copy_from_slice(&bytemuck::cast::<[i32; 8], [u32; 8]>(packed.to_array()));
    }
    tonemap_row_scalar(&r[full..], &g[full..], &b[full..], exposure, &mut out[full..]);
}

#[cfg(test)]
mod tests {
    use super::*;

    fn channels(p: u32) -> [i32; 3] {
        [(p >> 16) as i32 & 255, (p >> 8) as i32 & 255, p as i32 & 255]
    }

    fn agree(values: &[f32], exposure: f32) {
        let n = values.len();
        let (r, g, b): (Vec<f32>, Vec<f32>, Vec<f32>) =
            (values.to_vec(), values.iter().rev().copied().collect(), values.iter().map(|v| v * 0.5).collect());
        let (mut fast, mut reference) = (vec![0; n], vec![0; n]);
        tonemap_row(&r, &g, &b, exposure, &mut fast);
        tonemap_row_scalar(&r, &g, &b, exposure, &mut reference);
        for i in 0..n {
            let (a, e) = (channels(fast[i]), channels(reference[i]));
            assert!(
                (0..3).all(|c| (a[c] - e[c]).abs() <= 1),
                "pixel {i} ({}, {}, {}): {a:?} vs {e:?}",
                r[i],
                g[i],
                b[i]
            );
            assert_eq!(fast[i] == NON_FINITE, reference[i] == NON_FINITE, "pixel {i}");
        }
    }

    #[test]
    fn the_vector_body_matches_the_reference_on_edge_values() {
        let edges = [
            0.0,
            -0.0,
            -1.0,
            1e-9,
            0.003_130_8 / 0.996_869,
            0.003_2,
            0.5,
            1.0,
            2.0,
            1e3,
            1e30,
            f32::MAX,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            f32::MIN_POSITIVE,
            0.25,
        ];
        for exposure in [1.0, 0.25, 8.0] {
            agree(&edges, exposure);
        }
        // Exact on the values that matter most: black, white-ish and NaN.
        let mut out = [0; 9];
        tonemap_row(&[0.0; 9], &[0.0; 9], &[f32::NAN; 9], 1.0, &mut out);
        assert!(out.iter().all(|&p| p == NON_FINITE));
        tonemap_row(&[0.0; 9], &[0.0; 9], &[0.0; 9], 1.0, &mut out);
        assert!(out.iter().all(|&p| p == 0));
    }

    #[test]
    fn the_vector_body_matches_the_reference_on_seeded_random_values() {
        let mut rng = stereotrace_kernels::synth::Rng::new(0x2545_f491_4f6c_dd1d);
        let mut next = || rng.next_f32();
        let values: Vec<f32> = (0..4099).map(|_| next().powi(3) * 20.0).collect();
        agree(&values, 1.0);
        agree(&values, 3.0);
    }
}
