//! Sampling helpers the light types need: piecewise-constant 1-D and 2-D distributions,
//! uniform sphere and cone directions, luminance.
//!
//! Sums are accumulated in `f64` so that the CDF of a million-entry table (a 4k environment
//! map) still ends exactly at 1 and tiny entries keep a non-zero probability.

use std::f32::consts::PI;

use glam::{Vec2, Vec3};

/// Rec. 709 luminance of linear RGB (`kernels::colour::luminance`).
#[inline]
pub fn luminance(c: Vec3) -> f32 {
    crate::kernels::colour::luminance(c.x, c.y, c.z)
}

/// A piecewise-constant distribution over `[0, 1)` with `n` equal-width bins.
#[derive(Clone, Debug, PartialEq)]
pub struct Distribution1D {
    /// Bin weights as given (non-negative, finite).
    pub func: Vec<f32>,
    /// `n + 1` entries from 0 to 1.
    pub cdf: Vec<f32>,
    /// Sum of the weights (before normalisation); 0 when all were zero.
    pub total: f64,
    /// The search's guide ([`Distribution1D::bin_of`]): `guide[k]` is the bin a `u` just
    /// below `k / cells` falls in, for `k` in `0 ..= cells + 2`.
    guide: Vec<u32>,
}

/// The most guide cells of a distribution. Up to this many, the cell that `u·cells` rounds
/// into and the one after it hold every `u` that maps there (see [`Distribution1D::bin_of`]).
const MAX_GUIDE_CELLS: usize = 1 << 19;

impl Distribution1D {
    /// Builds the CDF. Negative or non-finite weights count as zero; when every weight is
    /// zero the distribution is uniform (so sampling never fails) and `total` is 0.
    ///
    /// # Panics
    /// If `weights` is empty (callers always have at least one bin).
    pub fn new(weights: &[f32]) -> Self {
        assert!(!weights.is_empty(), "Distribution1D needs at least one bin");
        let func: Vec<f32> = weights.iter().map(|&w| if w.is_finite() && w > 0.0 { w } else { 0.0 }).collect();
        let total: f64 = func.iter().map(|&w| w as f64).sum();
        let n = func.len();
        let mut cdf = Vec::with_capacity(n + 1);
        cdf.push(0.0);
        let mut acc = 0.0f64;
        // Same summation order as `total`, so the last entry is exactly 1 (and a trailing
        // zero-weight bin keeps exactly zero probability).
        let denom = if total > 0.0 { total } else { n as f64 };
        for &w in &func {
            acc += if total > 0.0 { w as f64 } else { 1.0 };
            cdf.push((acc / denom) as f32);
        }
        let guide = guide(&cdf);
        Self { func, cdf, total, guide }
    }

    /// The first bin `i` with `cdf[i + 1] > u` (bins of zero width are skipped), or the last
    /// bin where none is; `u` in `[0, 1)`. The binary search over the whole CDF, with the same
    /// answer: an environment map's row of 2048 bins took eleven dependent loads, most of them
    /// cache misses (a fifth of a frame's time on a scene lit by its sky, measured), where the
    /// guide's cell narrows the search to a few neighbouring bins. `u` lies in cell
    /// `k = ⌊u·cells⌋` (as f32 computes it, so within `2⁻²⁴` of the exact product), hence at
    /// or above the guide's point of cell `k` and below that of cell `k + 2`; the answer is
    /// monotone in `u`, so it lies between their bins.
    #[inline]
    fn bin_of(&self, u: f32) -> usize {
        let cells = self.guide.len() - 3;
        let k = ((u * cells as f32) as usize).min(cells);
        let (lo, hi) = (self.guide[k] as usize, self.guide[k + 2] as usize);
        (lo + self.cdf[1 + lo..1 + hi].partition_point(|&c| c <= u)).min(self.len() - 1)
    }

    /// Number of bins.
    pub fn len(&self) -> usize {
        self.func.len()
    }

    /// True when there are no bins (never, by construction).
    pub fn is_empty(&self) -> bool {
        self.func.is_empty()
    }

    /// Probability of bin `i`.
    #[inline]
    pub fn pmf(&self, i: usize) -> f32 {
        self.cdf[i + 1] - self.cdf[i]
    }

    /// Samples a bin: `(index, probability of that bin, u remapped to [0, 1) inside the bin)`.
    /// Bins of zero probability are never returned.
    #[inline]
    pub fn sample_discrete(&self, u: f32) -> (usize, f32, f32) {
        let u = if u.is_finite() { u.clamp(0.0, 1.0 - f32::EPSILON / 2.0) } else { 0.0 };
        let i = self.bin_of(u);
        let p = self.pmf(i);
        let rem = if p > 0.0 { ((u - self.cdf[i]) / p).clamp(0.0, 1.0 - f32::EPSILON / 2.0) } else { 0.0 };
        (i, p, rem)
    }

    /// Samples a continuous value in `[0, 1)`: `(x, density at x, bin index)`.
    #[inline]
    pub fn sample_continuous(&self, u: f32) -> (f32, f32, usize) {
        let (i, p, rem) = self.sample_discrete(u);
        let n = self.len() as f32;
        ((i as f32 + rem) / n, p * n, i)
    }

    /// Density of the continuous distribution at `x` in `[0, 1)`.
    #[inline]
    pub fn pdf(&self, x: f32) -> f32 {
        let n = self.len();
        let i = ((x * n as f32) as usize).min(n - 1);
        self.pmf(i) * n as f32
    }
}

/// [`Distribution1D`]'s guide for `cdf` (non-decreasing, `n + 1` entries): one cell per bin
/// (at most [`MAX_GUIDE_CELLS`]), and for each `k` in `0 ..= cells + 2` the first bin `i`
/// with `cdf[i + 1] > x_k` (or `n`), where `x_k` is `k / cells` lowered by a millionth, more
/// than the rounding of `u·cells` (see [`Distribution1D::bin_of`]). One merge walk over the
/// CDF.
fn guide(cdf: &[f32]) -> Vec<u32> {
    let n = cdf.len() - 1;
    let cells = n.min(MAX_GUIDE_CELLS);
    let mut bin = 0;
    (0..cells + 3)
        .map(|k| {
            let x = (k as f64 / cells as f64 * (1.0 - 1e-6)) as f32;
            while bin < n && cdf[bin + 1] <= x {
                bin += 1;
            }
            bin as u32
        })
        .collect()
}

/// A piecewise-constant distribution over `[0, 1)²`: a marginal over rows and one
/// conditional per row (row-major weights, `rows * cols`).
#[derive(Clone, Debug, PartialEq)]
pub struct Distribution2D {
    /// One distribution over columns per row.
    pub conditional: Vec<Distribution1D>,
    /// Distribution over rows (weights = row sums).
    pub marginal: Distribution1D,
}

impl Distribution2D {
    /// Builds the tables from `rows * cols` weights, row-major.
    pub fn new(weights: &[f32], cols: usize, rows: usize) -> Self {
        assert!(cols > 0 && rows > 0 && weights.len() == cols * rows, "bad Distribution2D shape");
        let conditional: Vec<Distribution1D> = weights.chunks_exact(cols).map(Distribution1D::new).collect();
        let row_weights: Vec<f32> = conditional.iter().map(|c| c.total as f32).collect();
        Self { marginal: Distribution1D::new(&row_weights), conditional }
    }

    /// Samples `(x, y)` in `[0, 1)²` (x along columns, y along rows) and the density there.
    #[inline]
    pub fn sample(&self, u: Vec2) -> (Vec2, f32) {
        let (y, pdf_y, row) = self.marginal.sample_continuous(u.y);
        let (x, pdf_x, _) = self.conditional[row].sample_continuous(u.x);
        (Vec2::new(x, y), pdf_x * pdf_y)
    }

    /// Density at `(x, y)` in `[0, 1)²`.
    #[inline]
    pub fn pdf(&self, p: Vec2) -> f32 {
        let rows = self.conditional.len();
        let row = ((p.y * rows as f32) as usize).min(rows - 1);
        self.marginal.pdf(p.y) * self.conditional[row].pdf(p.x)
    }
}

/// Uniformly distributed unit vector (`pdf = 1 / 4π`).
#[inline]
pub fn uniform_sphere(u: Vec2) -> Vec3 {
    let z = 1.0 - 2.0 * u.x;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * PI * u.y;
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// Uniformly distributed unit vector inside the cone of half-angle `acos(cos_max)` around
/// `axis` (unit). Density `1 / (2π (1 - cos_max))`.
#[inline]
pub fn uniform_cone(axis: Vec3, cos_max: f32, u: Vec2) -> Vec3 {
    let cos_t = 1.0 - u.x * (1.0 - cos_max);
    let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
    let phi = 2.0 * PI * u.y;
    let (t, b) = axis.any_orthonormal_pair();
    (t * (sin_t * phi.cos()) + b * (sin_t * phi.sin()) + axis * cos_t).normalize()
}

/// Solid angle of a cone of half-angle `acos(cos_max)`.
#[inline]
pub fn cone_solid_angle(cos_max: f32) -> f32 {
    2.0 * PI * (1.0 - cos_max)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distribution_1d_matches_weights() {
        let d = Distribution1D::new(&[1.0, 0.0, 3.0, f32::NAN, -2.0]);
        assert_eq!(d.cdf.len(), 6);
        assert_eq!(*d.cdf.last().unwrap(), 1.0);
        assert!((d.pmf(0) - 0.25).abs() < 1e-6 && d.pmf(1) == 0.0 && (d.pmf(2) - 0.75).abs() < 1e-6);
        assert_eq!(d.pmf(3), 0.0);
        for k in 0..1000 {
            let (i, p, rem) = d.sample_discrete(k as f32 / 1000.0);
            assert!(p > 0.0 && (i == 0 || i == 2), "{i} {p}");
            assert!((0.0..1.0).contains(&rem));
        }
        let (x, pdf, _) = d.sample_continuous(0.5);
        assert!((pdf - d.pdf(x)).abs() < 1e-5);
        // Out-of-range and NaN inputs are clamped.
        assert!(d.sample_discrete(f32::NAN).1 > 0.0);
        assert!(d.sample_discrete(1.0).1 > 0.0);
    }

    /// The whole-CDF binary search [`Distribution1D::bin_of`] replaces.
    fn plain_bin_of(d: &Distribution1D, u: f32) -> usize {
        d.cdf[1..].partition_point(|&c| c <= u).min(d.len() - 1)
    }

    /// Weights with the shapes an environment map has: runs of zeros (a black ground), one
    /// bin far brighter than the rest (a sun), and tiny values beside large ones.
    fn shaped_weights(rng: &mut crate::kernels::synth::Rng, n: usize) -> Vec<f32> {
        let mut w: Vec<f32> = (0..n)
            .map(|_| match (rng.next_f32() * 6.0) as u32 {
                0 | 1 => 0.0,
                2 => rng.next_f32() * 1e-6,
                _ => rng.next_f32(),
            })
            .collect();
        let zeros = (rng.next_f32() * n as f32) as usize;
        w[..zeros / 2].fill(0.0);
        let sun = (rng.next_f32() * n as f32) as usize % n;
        w[sun] = 1e6;
        w
    }

    #[test]
    fn the_guided_search_finds_the_bins_of_the_whole_search() {
        let mut rng = crate::kernels::synth::Rng::new(41);
        for n in [1, 2, 3, 5, 8, 64, 255, 2048, 4097] {
            for _ in 0..8 {
                let d = Distribution1D::new(&shaped_weights(&mut rng, n));
                // Every CDF value and its neighbours (where the comparison flips), the ends
                // of the clamp, and random points.
                let mut us = vec![0.0, f32::MIN_POSITIVE, 0.5, 1.0 - f32::EPSILON / 2.0, 1.0 - f32::EPSILON];
                for &c in &d.cdf {
                    us.extend([c, c.next_up(), c.next_down()]);
                }
                us.extend((0..4 * n).map(|_| rng.next_f32()));
                for u in us.into_iter().filter(|u| (0.0..1.0).contains(u)) {
                    assert_eq!(d.bin_of(u), plain_bin_of(&d, u), "n = {n}, u = {u:e}");
                }
            }
        }
    }

    #[test]
    fn all_zero_weights_fall_back_to_uniform() {
        let d = Distribution1D::new(&[0.0; 4]);
        assert_eq!(d.total, 0.0);
        assert!((0..4).all(|i| (d.pmf(i) - 0.25).abs() < 1e-6));
    }

    #[test]
    fn distribution_2d_density_integrates_to_one() {
        let w: Vec<f32> = (0..12).map(|i| (i % 5) as f32).collect();
        let d = Distribution2D::new(&w, 4, 3);
        let n = 64;
        let mut s = 0.0;
        for j in 0..n {
            for i in 0..n {
                s += d.pdf(Vec2::new((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32));
            }
        }
        assert!((s / (n * n) as f32 - 1.0).abs() < 1e-4, "{s}");
        let (p, pdf) = d.sample(Vec2::new(0.3, 0.7));
        assert!((pdf - d.pdf(p)).abs() < 1e-4 * pdf);
    }

    #[test]
    fn cone_samples_stay_inside() {
        let axis = Vec3::new(0.3, 0.9, -0.2).normalize();
        let cos_max = 5f32.to_radians().cos();
        for i in 0..100 {
            let d = uniform_cone(axis, cos_max, Vec2::new(i as f32 / 100.0, (i * 37 % 100) as f32 / 100.0));
            assert!(d.dot(axis) >= cos_max - 1e-5);
            assert!((d.length() - 1.0).abs() < 1e-5);
        }
        assert!((uniform_sphere(Vec2::new(0.3, 0.8)).length() - 1.0).abs() < 1e-6);
    }
}
