//! What an evaluation produces: per-frame, per-configuration and per-scene results, the
//! discard maps and comparison rows of the figures, and the outcome of a run (with what it
//! computed rather than loaded).

use serde::{Deserialize, Serialize};

use super::curve::FrameCurve;
use super::effective::{EffectiveSpp, Metric};
use super::spec::{EvalSpec, Variant};
use super::stats::Summary;
use crate::kernels::reproject::REASON_COUNT;
use crate::kernels::{PlaneBuf, RgbBuf};

/// What a run computed (as opposed to loading it from the cache).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct WorkCounters {
    /// References rendered (or finished from a checkpoint).
    pub references: usize,
    /// Error curves built (or finished from a checkpoint).
    pub curves: usize,
    /// Configurations run through the pipeline.
    pub configs: usize,
    /// Figure images rendered.
    pub figure_images: usize,
    /// Entries loaded from the cache.
    pub cache_hits: usize,
    /// Entries that failed verification and were recomputed.
    pub corrupt_entries: usize,
    /// Pixel samples path traced.
    pub samples: u64,
}

impl WorkCounters {
    /// References, curves and configurations computed.
    pub fn computed_units(&self) -> usize {
        self.references + self.curves + self.configs
    }
}

/// Pixels of one frame per reason, indexed by the reason code.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct FrameReasons {
    /// Frame index, from 0.
    pub frame: u32,
    /// Left-eye pixels per reason code (Table 4's input), indexed as
    /// [`Reason`](crate::kernels::reproject::Reason).
    pub counts: [u64; REASON_COUNT],
}

/// One measured frame of a configuration.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct FrameResult {
    /// Frame index, from 0.
    pub frame: u32,
    /// Whether the frame is after the warm-up (only those are summarised).
    pub evaluated: bool,
    /// SSIM of the left-eye output against the frame's reference.
    pub ssim: f64,
    /// RMSE of the left-eye output against the frame's reference.
    pub rmse: f64,
    /// Effective spp (evaluated frames only).
    pub effective_ssim: Option<EffectiveSpp>,
    /// Effective spp by RMSE (evaluated frames only).
    pub effective_rmse: Option<EffectiveSpp>,
}

impl FrameResult {
    /// The effective spp by `metric` (`None` for a warm-up frame).
    pub fn effective(&self, metric: Metric) -> Option<EffectiveSpp> {
        match metric {
            Metric::Ssim => self.effective_ssim,
            Metric::Rmse => self.effective_rmse,
        }
    }
}

/// One (variant, input spp) of one scene.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ConfigResult {
    /// The pipeline mode and order.
    pub variant: Variant,
    /// Input samples per pixel.
    pub spp: u32,
    /// The frames with a reference (the evaluated ones; every frame for Figure 3's scene).
    pub frames: Vec<FrameResult>,
    /// Left eye, every frame: stereo reprojection into it (zero where the mode has none).
    pub stereo_reasons: Vec<FrameReasons>,
    /// Left eye, every frame: temporal reprojection of its history (zero on frame 0).
    pub temporal_reasons: Vec<FrameReasons>,
    /// Effective spp over the evaluated frames.
    pub ssim: Summary,
    /// Effective spp by RMSE over the evaluated frames.
    pub rmse: Summary,
    /// Left-eye pixels path traced over all frames.
    pub traced_left_pixels: u64,
}

impl ConfigResult {
    /// The effective spp summary by `metric`.
    pub fn summary(&self, metric: Metric) -> &Summary {
        match metric {
            Metric::Ssim => &self.ssim,
            Metric::Rmse => &self.rmse,
        }
    }
}

/// Everything measured on one scene.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SceneResult {
    /// The scene's own name (a manifest's `name`, a folder's name), keying its cache entries.
    pub name: String,
    /// Human-readable name for tables and figures.
    pub display_name: String,
    /// The paper scene it stands for (Figure 2 label); `None` for a scene the paper lacks.
    pub paper_scene: Option<String>,
    /// [`Scene::fingerprint`](crate::scene::Scene::fingerprint) as 16 hex digits.
    pub fingerprint: String,
    /// The error curves of the frames with a reference.
    pub curves: Vec<FrameCurve>,
    /// One result per (variant, input spp), variants outermost.
    pub configs: Vec<ConfigResult>,
}

impl SceneResult {
    /// The result of `variant` at input `spp`, if the run has it.
    pub fn config(&self, variant: Variant, spp: u32) -> Option<&ConfigResult> {
        self.configs.iter().find(|c| c.variant == variant && c.spp == spp)
    }
}

/// The machine-readable result of a run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EvalResults {
    /// The spec evaluated.
    pub spec: EvalSpec,
    /// `<cache format>/<crate version>/<global probe>`, as in every cache key.
    pub code_version: String,
    /// Per-scene results, in spec order.
    pub scenes: Vec<SceneResult>,
}

/// Figure 6's input: one eye's reason codes at one frame, over its reference.
#[derive(Clone, Debug)]
pub struct DiscardMap {
    /// The scene's own name ([`SceneResult::name`]).
    pub scene: String,
    /// The figure frame ([`EvalSpec::figure_frame`]).
    pub frame: u32,
    /// `stereo` or `temporal`.
    pub kind: &'static str,
    /// The left eye's reason code per pixel.
    pub reasons: PlaneBuf<u8>,
    /// The frame's left-eye reference, shown darkened under reprojected and background
    /// pixels.
    pub background: RgbBuf,
}

/// One row of Figure 7.
#[derive(Clone, Debug)]
pub struct ComparisonRow {
    /// The scene's own name ([`SceneResult::name`]).
    pub scene: String,
    /// The figure frame ([`EvalSpec::figure_frame`]).
    pub frame: u32,
    /// Input samples per pixel.
    pub spp: u32,
    /// The frame path traced at `spp`.
    pub path_traced: RgbBuf,
    /// The spatiotemporal pipeline's left-eye output at `spp` (paper order).
    pub reprojected: RgbBuf,
    /// The reprojected image's effective spp by SSIM.
    pub effective: EffectiveSpp,
    /// The effective spp rounded, at least 1 (`M` above the curve's range; 1 below it
    /// or when undefined).
    pub comparison_spp: u32,
    /// The frame path traced at `comparison_spp`.
    pub comparison: RgbBuf,
}

/// Images for the figures (kept out of the JSON).
#[derive(Clone, Debug, Default)]
pub struct Artifacts {
    /// Figure 6's discard maps.
    pub discard_maps: Vec<DiscardMap>,
    /// Figure 7's rows.
    pub comparisons: Vec<ComparisonRow>,
}

/// What [`evaluate`](super::run::evaluate) returns.
pub struct EvalOutcome {
    /// The measured results (`results.json`).
    pub results: EvalResults,
    /// Images for the figures.
    pub artifacts: Artifacts,
    /// What this run computed rather than loaded.
    pub counters: WorkCounters,
    /// Non-fatal problems, in the order they were reported.
    pub warnings: Vec<String>,
    /// Wall time of the run, in seconds.
    pub seconds: f64,
}
