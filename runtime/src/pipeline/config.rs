//! What a pipeline computes and how: modes, orders, G-buffer passes and layouts, the
//! configuration and its validation, and the pipeline's errors.

use std::time::Duration;

use crate::kernels::reproject::{TapPolicy, Tolerances};
use crate::source::Layout;

/// The most samples per pixel a command or an embedder's configuration accepts (2²⁰: above
/// the paper's 4096-spp references by far; a larger count is a typo that would run for days,
/// or a wrapped negative number). [`check_spp`] is the one check of it.
pub const MAX_SPP: u32 = 1 << 20;

/// `spp` if it is in 1 ..= [`MAX_SPP`]: the one rule for a sample count, which
/// [`PipelineConfig::validate`], the CLI's parsers and the C ABI all apply.
pub fn check_spp(spp: u32) -> Result<u32, String> {
    if (1..=MAX_SPP).contains(&spp) {
        Ok(spp)
    } else {
        Err(format!("samples per pixel {spp} must be in 1..={MAX_SPP}"))
    }
}

/// The largest per-frame budget accepted, in milliseconds (1000 s).
pub const MAX_BUDGET_MS: f64 = 1e6;

/// A per-frame budget in milliseconds as a duration: finite, > 0 and at most
/// [`MAX_BUDGET_MS`] (NaN, infinite, zero or negative budgets have no meaning, and a huge one
/// overflows a duration).
pub fn budget_duration(ms: f64) -> Result<Duration, String> {
    if ms.is_finite() && ms > 0.0 && ms <= MAX_BUDGET_MS {
        Ok(Duration::from_secs_f64(ms / 1e3))
    } else {
        Err(format!("budget {} ms must be finite, > 0 and at most {MAX_BUDGET_MS} ms", readable(ms)))
    }
}

/// `v` as a person reads it: plain for ordinary magnitudes, in exponent form for huge or
/// tiny ones (`{}` of 1e300 prints 301 digits).
pub fn readable(v: f64) -> String {
    if v != 0.0 && v.is_finite() && !(1e-3..1e7).contains(&v.abs()) { format!("{v:e}") } else { format!("{v}") }
}

/// What the pipeline computes (see the table in the `pipeline` module notes).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "kebab-case")]
pub enum Mode {
    /// Both eyes fully path traced (the baseline).
    PathTraced,
    /// The left eye reprojected from the right one, traced where discarded.
    Stereo,
    /// Each eye accumulates its own temporally reprojected history (EMA).
    Temporal,
    /// Stereo and temporal reprojection combined (the paper's main mode).
    Spatiotemporal,
    /// Each eye blends its own samples with the other eye's reprojection.
    StereoBlend,
    /// The stereo blend over temporally accumulated histories.
    SpatiotemporalBlend,
}

impl Mode {
    /// Every mode, in the paper's order.
    pub const ALL: [Mode; 6] = [
        Mode::PathTraced,
        Mode::Stereo,
        Mode::Temporal,
        Mode::Spatiotemporal,
        Mode::StereoBlend,
        Mode::SpatiotemporalBlend,
    ];

    /// The CLI's and the tables' name (`path-traced`, `stereo`, ...).
    pub fn name(self) -> &'static str {
        match self {
            Mode::PathTraced => "path-traced",
            Mode::Stereo => "stereo",
            Mode::Temporal => "temporal",
            Mode::Spatiotemporal => "spatiotemporal",
            Mode::StereoBlend => "stereo-blend",
            Mode::SpatiotemporalBlend => "spatiotemporal-blend",
        }
    }

    /// Whether the mode accumulates over time (keeps a history).
    pub fn temporal(self) -> bool {
        matches!(self, Mode::Temporal | Mode::Spatiotemporal | Mode::SpatiotemporalBlend)
    }

    /// Whether the mode reprojects between the eyes.
    pub fn stereo(self) -> bool {
        !matches!(self, Mode::PathTraced | Mode::Temporal)
    }

    /// Whether the order of stereo and temporal reprojection matters for this mode.
    pub fn has_order(self) -> bool {
        matches!(self, Mode::Spatiotemporal | Mode::SpatiotemporalBlend)
    }
}

impl std::fmt::Display for Mode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Which reprojection comes first in the spatiotemporal modes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "kebab-case")]
pub enum Order {
    /// The paper's: temporal accumulation of the source, then stereo reprojection.
    #[default]
    Paper,
    /// Stereo reprojection of the fresh samples, then temporal accumulation.
    StereoFirst,
}

impl Order {
    /// The CLI's and the tables' name.
    pub fn name(self) -> &'static str {
        match self {
            Order::Paper => "paper",
            Order::StereoFirst => "stereo-first",
        }
    }
}

/// How far the EMA trusts a reprojected history.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "kebab-case")]
pub enum History {
    /// The paper's: wherever reprojection keeps it, which sees geometry only (a history
    /// lags a moving light by about 1/α frames).
    #[default]
    Paper,
    /// Also shortened where the lighting changed, measured by temporal gradients (A-SVGF):
    /// one re-shaded sample of the last frame per 3×3 stratum, traced inside the frame
    /// (`kernels::gradient`). A source whose scene cannot change between frames
    /// ([`crate::source::FrameSource::scene_changes`]) traces none, and the images are the
    /// paper's bit for bit.
    Gradient,
    /// Clamped before the EMA into the box this frame's samples around the pixel allow (TAA's
    /// variance clipping, as FSR2 clamps: `kernels::clamp`, γ = [`CLAMP_GAMMA`]): a history that disagrees
    /// with its 3×3 neighbourhood of new samples is pulled into their range. Traces nothing
    /// more; at 1 spp, where most single paths are darker than their mean, the box sits
    /// below it and the image converges too dark (RESULTS.md measures the gain and the bias).
    Clamp,
}

impl History {
    /// The CLI's and the tables' name.
    pub fn name(self) -> &'static str {
        match self {
            History::Paper => "paper",
            History::Gradient => "gradient",
            History::Clamp => "clamp",
        }
    }
}

/// How the stereo blend weighs an eye's own image against the other eye's reprojection.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "kebab-case")]
pub enum Blend {
    /// The paper's: `blend_own_weight` everywhere (½).
    #[default]
    Fixed,
    /// By inverse variance of the two accumulated estimates, from each eye's history length
    /// (`kernels::accumulate::blend_by_variance`): where one eye's history restarted, the
    /// other eye's longer one counts more. It changes only the paper-order
    /// `spatiotemporal-blend` mode (the other blends mix two single-frame images, whose
    /// lengths are equal); equal lengths give the fixed blend bit for bit.
    Variance,
}

impl Blend {
    /// The CLI's and the tables' name.
    pub fn name(self) -> &'static str {
        match self {
            Blend::Fixed => "fixed",
            Blend::Variance => "variance",
        }
    }
}

/// What reprojection does with background pixels (no surface: an environment map or a
/// constant sky seen past the geometry).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "kebab-case")]
pub enum Background {
    /// The paper's: discarded (its reprojection needs a surface), so every background pixel
    /// is traced again every frame, under a budget before anything else.
    #[default]
    Trace,
    /// Reprojected by view direction, as points at infinity, from taps that are background
    /// too (`kernels::reproject::ReprojectInput::background`): a sky that stays in view keeps
    /// its history in both eyes and costs no ray. For a background that does not change
    /// between frames (a built-in scene's environment map never does); an engine whose sky
    /// changes keeps the paper's setting.
    Reproject,
}

impl Background {
    /// The CLI's and the tables' name.
    pub fn name(self) -> &'static str {
        match self {
            Background::Trace => "trace",
            Background::Reproject => "reproject",
        }
    }
}

/// A spatial filter of each eye's shown image after accumulation.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "kebab-case")]
pub enum Filter {
    /// The paper's: none (the shown image is the reprojected and accumulated one).
    #[default]
    None,
    /// The edge-avoiding à-trous filter (`kernels::atrous`, SVGF's edge-stopping functions,
    /// [`ATROUS_ITERATIONS`] passes) guided by the eye's G-buffer. A display filter: the
    /// histories and the stereo reprojection read the unfiltered images.
    Atrous,
}

impl Filter {
    /// The CLI's and the tables' name.
    pub fn name(self) -> &'static str {
        match self {
            Filter::None => "none",
            Filter::Atrous => "atrous",
        }
    }
}

/// The width of `History::Clamp`'s box in standard deviations. On the quick preset γ = 2
/// gave 1.09× the effective spp of Salvi's γ = 1 (geometric mean over every scene, temporal
/// mode and spp; lower at 28 of 180 points, by at most 8 %; RESULTS.md): boxes of single
/// paths are noisy, and a narrow one cuts into the converged history.
pub const CLAMP_GAMMA: f32 = 2.0;

/// The à-trous filter's passes in the pipeline (SVGF's five: a 5×5 spline at steps 1 to 16,
/// reaching 64 pixels either side).
pub const ATROUS_ITERATIONS: u32 = 5;

/// Everything that decides a pipeline's images.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PipelineConfig {
    /// What is computed (see [`Mode`]).
    pub mode: Mode,
    /// Order of stereo and temporal reprojection (modes that have one).
    pub order: Order,
    /// Samples per traced pixel per frame.
    pub spp: u32,
    /// EMA weight of the new sample (the paper: 0.2).
    pub alpha: f32,
    /// `α = max(α, 1/(n+1))` with a per-pixel history length.
    pub ramp: bool,
    /// What reprojection does with a pixel some of whose taps failed.
    pub policy: TapPolicy,
    /// Reprojection discard thresholds, in scene units (see `SceneTolerances::at_height`).
    pub tolerances: Tolerances,
    /// Weight of an eye's own samples in the stereo blend (the paper: 0.5).
    pub blend_own_weight: f32,
    /// The G-buffer layout reprojection reads.
    pub layout: Layout,
    /// Seed of the path tracer's random numbers.
    pub seed: u64,
    /// Time budget for a whole frame; `None` traces everything.
    pub budget: Option<Duration>,
    /// Rows per tracing tile under a budget.
    pub tile_rows: usize,
    /// Give each G-buffer a history-confidence plane for the source to fill, which the EMA
    /// reads (see `kernels::accumulate::EmaInput::confidence`); off, the plain EMA.
    pub history_confidence: bool,
    /// Give each G-buffer motion planes (world-space motion of each pixel's surface since the
    /// last frame) for the source to fill, which temporal reprojection follows (see
    /// `kernels::reproject::ReprojectInput::motion`); off, every surface is taken as still.
    pub motion_vectors: bool,
    /// How far the EMA trusts a reprojected history (see [`History`]).
    pub history: History,
    /// How the stereo blend weighs the two eyes (see [`Blend`]).
    pub blend: Blend,
    /// A spatial filter of the shown images (see [`Filter`]).
    pub filter: Filter,
    /// What reprojection does with background pixels (see [`Background`]).
    pub background: Background,
}

impl PipelineConfig {
    /// Whether each eye keeps its per-pixel history length: for the α ramp, and for the
    /// variance-guided blend.
    pub fn tracks_history_length(&self) -> bool {
        self.ramp || self.blend == Blend::Variance
    }

    /// The paper's settings for `mode` at `spp` with `tolerances`.
    pub fn paper(mode: Mode, spp: u32, tolerances: Tolerances) -> Self {
        Self {
            mode,
            order: Order::Paper,
            spp,
            alpha: 0.2,
            ramp: false,
            policy: TapPolicy::Renormalize,
            tolerances,
            blend_own_weight: 0.5,
            layout: Layout::Compact,
            seed: 1,
            budget: None,
            tile_rows: 8,
            history_confidence: false,
            motion_vectors: false,
            history: History::Paper,
            blend: Blend::Fixed,
            filter: Filter::None,
            background: Background::Trace,
        }
    }

    /// Refuses what no pipeline can run: a sample count outside [`check_spp`], a budget
    /// above [`MAX_BUDGET_MS`] (what [`budget_duration`] makes of a number of milliseconds), an EMA weight outside (0, 1], a blend weight
    /// outside [0, 1], no rows per tile, or invalid tolerances. [`super::Pipeline`] calls it
    /// on construction; a command or an engine may call it first to report every field at
    /// its own boundary.
    pub fn validate(&self) -> Result<(), String> {
        check_spp(self.spp)?;
        // A duration is never NaN or negative; a tiny one (even zero after rounding to
        // nanoseconds) is a budget the always-run work overruns, which a frame reports.
        if let Some(ms) = self.budget.map(|b| b.as_secs_f64() * 1e3).filter(|&ms| ms > MAX_BUDGET_MS) {
            return Err(format!("budget {} ms must be at most {MAX_BUDGET_MS} ms", readable(ms)));
        }
        if !(self.alpha > 0.0 && self.alpha <= 1.0) {
            return Err(format!("EMA alpha must be in (0, 1], got {}", self.alpha));
        }
        if !(0.0..=1.0).contains(&self.blend_own_weight) {
            return Err(format!("blend weight must be in [0, 1], got {}", self.blend_own_weight));
        }
        if self.tile_rows == 0 {
            return Err("tile rows must be at least 1".into());
        }
        self.tolerances.validate().map_err(|e| e.to_string())
    }
}
