//! Counter-based random numbers: every number is a hash of
//! `(seed, eye, frame, pixel, sample, dimension)`.
//!
//! Nothing is carried from one number to the next, so an image can be re-rendered exactly,
//! a single pixel or sample can be reproduced on its own, results do not depend on thread
//! count or scheduling, and the specialised and general integrators consume identical
//! numbers even where one of them skips code (each purpose has a fixed [`Dim`]).

use glam::Vec2;

/// The purposes random numbers are drawn for; each owns a fixed dimension index.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u32)]
pub enum Dim {
    /// Sub-pixel jitter of the primary ray (2-D).
    PixelJitter = 0,
    /// Light selection for next-event estimation at the primary hit.
    LightPick1 = 2,
    /// Point on the chosen light (2-D).
    LightPoint1 = 3,
    /// Lobe choice of the secondary ray (diffuse or glossy).
    Lobe = 5,
    /// Direction of the secondary ray (2-D).
    Bounce = 6,
    /// Light selection at the secondary hit.
    LightPick2 = 8,
    /// Point on that light (2-D).
    LightPoint2 = 9,
}

/// splitmix64's finaliser: a fast, well-mixed 64-bit permutation.
#[inline(always)]
fn mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The random numbers of one (pixel, sample).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SampleStream {
    key: u64,
}

impl SampleStream {
    /// The stream of `sample` of `pixel` (row-major index) of `eye` at `frame`, for a render
    /// `seed` (references and comparison frames use different seeds).
    #[inline]
    pub fn new(seed: u64, eye: u32, frame: u32, pixel: u32, sample: u32) -> Self {
        let mut k = mix(seed ^ 0x5354_4552_454F_5452); // "STEREOTR"
        k = mix(k ^ (u64::from(eye) << 32 | u64::from(frame)));
        k = mix(k ^ (u64::from(pixel) << 32 | u64::from(sample)));
        Self { key: k }
    }

    #[inline(always)]
    fn bits(&self, dim: u32) -> u64 {
        mix(self.key.wrapping_add(u64::from(dim).wrapping_mul(0x9E37_79B9_7F4A_7C15)))
    }

    /// A number in [0, 1) for `dim`.
    #[inline(always)]
    pub fn get(&self, dim: Dim) -> f32 {
        to_unit((self.bits(dim as u32) >> 40) as u32)
    }

    /// Two numbers in [0, 1) for the 2-D purpose `dim`.
    #[inline(always)]
    pub fn get2(&self, dim: Dim) -> Vec2 {
        let b = self.bits(dim as u32);
        Vec2::new(to_unit((b >> 40) as u32), to_unit(((b >> 8) & 0xFF_FFFF) as u32))
    }
}

/// 24 random bits to a float in [0, 1) (exactly representable, never 1).
#[inline(always)]
fn to_unit(bits24: u32) -> f32 {
    bits24 as f32 * (1.0 / (1u32 << 24) as f32)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_are_in_range_and_reproducible() {
        let s = SampleStream::new(1, 0, 3, 12345, 7);
        for d in [Dim::PixelJitter, Dim::Lobe, Dim::Bounce] {
            let v = s.get2(d);
            assert!((0.0..1.0).contains(&v.x) && (0.0..1.0).contains(&v.y));
            assert_eq!(v, SampleStream::new(1, 0, 3, 12345, 7).get2(d));
        }
    }

    #[test]
    fn streams_differ_by_every_key_part_and_look_uniform() {
        let base = SampleStream::new(1, 0, 3, 100, 7).get(Dim::Lobe);
        for other in [
            SampleStream::new(2, 0, 3, 100, 7),
            SampleStream::new(1, 1, 3, 100, 7),
            SampleStream::new(1, 0, 4, 100, 7),
            SampleStream::new(1, 0, 3, 101, 7),
            SampleStream::new(1, 0, 3, 100, 8),
        ] {
            assert_ne!(other.get(Dim::Lobe), base);
        }
        // Mean and variance of 100k numbers: 1/2 and 1/12.
        let n = 100_000;
        let (mut sum, mut sum2) = (0.0f64, 0.0f64);
        for p in 0..n {
            let v = f64::from(SampleStream::new(9, 0, 0, p, 0).get(Dim::Bounce));
            sum += v;
            sum2 += v * v;
        }
        let mean = sum / f64::from(n);
        let var = sum2 / f64::from(n) - mean * mean;
        assert!((mean - 0.5).abs() < 0.005, "{mean}");
        assert!((var - 1.0 / 12.0).abs() < 0.002, "{var}");
    }
}
