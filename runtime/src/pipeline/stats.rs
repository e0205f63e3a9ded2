//! What one frame did: stage times, pixels traced, reasons, accumulation counts.

use std::time::Duration;

use crate::kernels::accumulate::AccumulateStats;
use crate::kernels::reproject::ReasonCounts;
use crate::source::{RasterPassStats, TraceStats};

/// Time per stage of one frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StageTimes {
    /// Both eyes' G-buffers.
    pub gbuffer: Duration,
    /// Stereo and temporal reprojection.
    pub reprojection: Duration,
    /// Path tracing.
    pub tracing: Duration,
    /// The part of `tracing` that a budget cannot cut: under a budget, the pixels traced
    /// first because they have no valid history (all of a mode's fully traced eye); zero
    /// without a budget.
    pub urgent_tracing: Duration,
    /// EMA and blends (and the neighbourhood clamp, `History::Clamp`).
    pub accumulation: Duration,
    /// Temporal gradients (`History::Gradient`) outside their traced samples: choosing the
    /// samples, and turning their luminance pairs into history confidence.
    pub gradients: Duration,
    /// The spatial filter of both eyes' shown images (`Filter::Atrous`).
    pub filter: Duration,
    /// The whole frame.
    pub total: Duration,
}

/// What one frame did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FrameStats {
    /// The frame number given to the render call.
    pub frame: u32,
    /// Time per stage.
    pub times: StageTimes,
    /// Pixels path traced per eye (left, right).
    pub traced_pixels: [u64; 2],
    /// Gradient samples re-shaded per eye (left, right): one per 3×3 stratum with a usable
    /// sample of the last frame, traced at `spp` like a pixel (`History::Gradient`; zero
    /// otherwise). Not part of `traced_pixels`.
    pub gradient_samples: [u64; 2],
    /// Strata per eye whose gradient shortened the history (lighting changed there).
    pub gradient_changed: [u64; 2],
    /// Pixels each eye would have traced without a budget.
    pub wanted_pixels: [u64; 2],
    /// Rays traced.
    pub trace: TraceStats,
    /// Stereo reprojection into each eye (left, right), by reason; zero where unused.
    pub stereo_reasons: [ReasonCounts; 2],
    /// Temporal reprojection of each eye's history, by reason; zero where unused or on the
    /// first frame (paper-order spatiotemporal left eye: only the pixels whose stereo
    /// reprojection failed).
    pub temporal_reasons: [ReasonCounts; 2],
    /// What each eye's EMA saw (left, right).
    pub accumulation: [AccumulateStats; 2],
    /// Pixels per eye whose history the neighbourhood clamp moved before the EMA
    /// (`History::Clamp`; zero otherwise).
    pub history_clamped: [u64; 2],
    /// Colour values each eye's filter clamped (`Filter::Atrous`; `kernels::atrous`).
    pub filter_out_of_range: [u64; 2],
    /// The frame's budget, if any.
    pub budget: Option<Duration>,
    /// False when the budget was set and the frame took longer.
    pub budget_met: bool,
    /// The rasterised G-buffer pass's counts and step times, from a source that rasterises (`None` otherwise).
    pub raster: Option<RasterPassStats>,
}

impl FrameStats {
    /// Pixel samples traced for eye `eye` (0 left, 1 right), in pixels: the pixels traced
    /// and the gradient samples, each `spp` samples (the share of a frame that was traced).
    pub fn pixels_traced(&self, eye: usize) -> u64 {
        self.traced_pixels[eye] + self.gradient_samples[eye]
    }
}
