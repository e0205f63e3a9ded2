//! References and error curves, rendered progressively: one sample per pixel per pass.
//!
//! [`Progressive`] keeps a running f64 sum of passes that each trace exactly one sample
//! (`TraceRequest::first_sample` = the samples so far). Its mean after `m` passes is bit for
//! bit the image one `m`-spp render gives (the renderer sums the samples of a pixel in the
//! same order in f64 and divides by `m`; `tests/eval.rs` checks it). So an error curve
//! `E(1..=M)` costs `M` samples per pixel, the same as its last point alone, and a
//! reference can be checkpointed and resumed at any sample count.

use serde::{Deserialize, Serialize};

use super::effective::{ErrorCurve, Grid, Interpolation, Metric};
use crate::camera::Eye;
use crate::kernels::ssim::{SsimParams, SsimVariant, ssim};
use crate::kernels::{Extent, RgbBuf};
use crate::render::{FrameView, Renderer};
use crate::source::TraceStats;

/// The eye an evaluation measures: the left one, which the stereo modes fill by reprojection.
pub const MEASURED_EYE: Eye = Eye::Left;

/// Per-pixel sums of samples in f64 (interleaved RGB): the renderer sums a pixel's samples
/// in f64 too, so the mean of `n` one-sample passes is bit for bit an `n`-sample render.
#[derive(Clone, Debug, PartialEq)]
pub struct SampleSums {
    /// The image size the sums cover.
    pub extent: Extent,
    /// `3 · pixels` values: R, G, B of pixel 0, then pixel 1, ...
    pub rgb: Vec<f64>,
}

impl SampleSums {
    /// All zero.
    pub fn zero(extent: Extent) -> Self {
        Self { extent, rgb: vec![0.0; 3 * extent.pixels()] }
    }
}

/// A running sum of one-sample passes.
#[derive(Clone, Debug)]
pub struct Progressive {
    samples: u32,
    sum: SampleSums,
    pass: RgbBuf,
    mean: RgbBuf,
}

impl Progressive {
    /// No samples yet.
    pub fn new(extent: Extent) -> Self {
        Self::resume(0, SampleSums::zero(extent))
    }

    /// Continues from a checkpoint: `sum` of the first `samples` samples.
    pub fn resume(samples: u32, sum: SampleSums) -> Self {
        let e = sum.extent;
        Self { samples, sum, pass: RgbBuf::new(e, 0.0), mean: RgbBuf::new(e, 0.0) }
    }

    /// Samples per pixel summed so far.
    pub fn samples(&self) -> u32 {
        self.samples
    }

    /// The running sum (for checkpoints).
    pub fn sum(&self) -> &SampleSums {
        &self.sum
    }

    /// Traces sample number `self.samples()` of every pixel with `seed` and adds it.
    pub fn add_sample(
        &mut self,
        renderer: &Renderer,
        view: &FrameView,
        seed: u64,
        general: bool,
    ) -> Result<TraceStats, String> {
        let request = view.request(MEASURED_EYE, 1, seed, self.samples);
        let stats = view.trace(renderer, &request, &mut self.pass, general).map_err(|e| e.to_string())?;
        for (c, plane) in self.pass.planes().into_iter().enumerate() {
            for (i, &v) in plane.as_slice().iter().enumerate() {
                self.sum.rgb[3 * i + c] += f64::from(v);
            }
        }
        self.samples += 1;
        Ok(stats)
    }

    /// The mean of the samples so far: what one `samples()`-spp render gives.
    pub fn mean(&mut self) -> &RgbBuf {
        let n = f64::from(self.samples.max(1));
        for (c, plane) in self.mean.slices_mut().into_iter().enumerate() {
            for (i, m) in plane.iter_mut().enumerate() {
                *m = (self.sum.rgb[3 * i + c] / n) as f32;
            }
        }
        &self.mean
    }
}

/// SSIM and RMSE of an image against a reference.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Measurement {
    /// SSIM against the reference (1 = identical; NaN when nothing is usable).
    pub ssim: f64,
    /// RMSE against the reference over the H·W·3 values (NaN when none is usable).
    pub rmse: f64,
}

impl Measurement {
    /// The error of `metric`: `1 − SSIM` or the RMSE.
    pub fn error(&self, metric: Metric) -> f64 {
        match metric {
            Metric::Ssim => 1.0 - self.ssim,
            Metric::Rmse => self.rmse,
        }
    }
}

/// Measures `image` against `reference` with the SSIM `variant`.
pub fn measure(image: &RgbBuf, reference: &RgbBuf, variant: SsimVariant) -> Result<Measurement, String> {
    let r = ssim(&image.view(), &reference.view(), &SsimParams::with_variant(variant)).map_err(|e| e.to_string())?;
    Ok(Measurement { ssim: r.ssim, rmse: r.rmse })
}

/// One measured point of an error curve.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CurvePoint {
    /// Samples per pixel of the path-traced image measured.
    pub spp: u32,
    /// Its SSIM against the frame's reference.
    pub ssim: f64,
    /// Its RMSE against the frame's reference.
    pub rmse: f64,
}

/// The measured curve of one frame and eye: both metrics at the grid's sample counts.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FrameCurve {
    /// The frame measured (left eye in the evaluation).
    pub frame: u32,
    /// The grid of sample counts; it also decides the interpolation (linear when dense,
    /// log–log otherwise).
    pub grid: Grid,
    /// The measured points, ascending in spp from 1.
    pub points: Vec<CurvePoint>,
}

impl FrameCurve {
    /// The error curve of `metric`.
    pub fn curve(&self, metric: Metric) -> Result<ErrorCurve, String> {
        let spp = self.points.iter().map(|p| p.spp).collect();
        let err = self.points.iter().map(|p| Measurement { ssim: p.ssim, rmse: p.rmse }.error(metric)).collect();
        let interpolation = if self.grid == Grid::Dense { Interpolation::Linear } else { Interpolation::LogLog };
        ErrorCurve::new(spp, err, interpolation).map_err(|e| format!("frame {}: {metric:?} curve: {e}", self.frame))
    }

    /// The SSIM measured at `spp` samples, if it was.
    pub fn ssim_at(&self, spp: u32) -> Option<f64> {
        self.points.iter().find(|p| p.spp == spp).map(|p| p.ssim)
    }

    /// The last sample count measured, `M` (0 for a curve without points).
    pub fn max_spp(&self) -> u32 {
        self.points.last().map_or(0, |p| p.spp)
    }
}

/// Builds the curve of `view` measured at `points` (ascending, from 1) against `reference`,
/// progressively with `seed`, without checkpoints (the evaluation run adds those).
pub fn build_curve(
    renderer: &Renderer,
    view: &FrameView,
    seed: u64,
    grid: Grid,
    points: &[u32],
    reference: &RgbBuf,
    variant: SsimVariant,
) -> Result<FrameCurve, String> {
    let mut prog = Progressive::new(reference.extent());
    let mut out = Vec::with_capacity(points.len());
    let last = points.last().copied().unwrap_or(0);
    while prog.samples() < last {
        prog.add_sample(renderer, view, seed, false)?;
        let m = prog.samples();
        if points.binary_search(&m).is_ok() {
            let Measurement { ssim, rmse } = measure(prog.mean(), reference, variant)?;
            out.push(CurvePoint { spp: m, ssim, rmse });
        }
    }
    Ok(FrameCurve { frame: view.frame, grid, points: out })
}
