//! What an evaluation is: the pipeline [`Variant`]s it measures, its [`Seeds`], the SSIM
//! flavour, the figures, and the whole [`EvalSpec`] with its [`Preset`]s (quick, paper-lite,
//! paper).

use serde::{Deserialize, Serialize};

use crate::kernels::Extent;

use super::effective::Grid;
use crate::kernels::ssim::SsimVariant;
use crate::pipeline::{Mode, Order};
/// One evaluated pipeline configuration family: a mode and, where it matters, the order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Variant {
    /// The pipeline mode.
    pub mode: Mode,
    /// Which reprojection comes first; always [`Order::Paper`] for modes without an order.
    pub order: Order,
}

impl Variant {
    /// The seven the paper's tables need (and the other order of both spatiotemporal modes).
    pub const ALL: [Variant; 7] = [
        Variant { mode: Mode::Stereo, order: Order::Paper },
        Variant { mode: Mode::Temporal, order: Order::Paper },
        Variant { mode: Mode::Spatiotemporal, order: Order::Paper },
        Variant { mode: Mode::Spatiotemporal, order: Order::StereoFirst },
        Variant { mode: Mode::StereoBlend, order: Order::Paper },
        Variant { mode: Mode::SpatiotemporalBlend, order: Order::Paper },
        Variant { mode: Mode::SpatiotemporalBlend, order: Order::StereoFirst },
    ];

    /// `mode` with `order`, the order reset to [`Order::Paper`] where the mode has none.
    pub fn new(mode: Mode, order: Order) -> Self {
        Self { mode, order: if mode.has_order() { order } else { Order::Paper } }
    }

    /// `stereo`, `spatiotemporal`, `spatiotemporal-stereo-first`, ...
    pub fn name(&self) -> String {
        if self.mode.has_order() && self.order == Order::StereoFirst {
            format!("{}-stereo-first", self.mode.name())
        } else {
            self.mode.name().to_owned()
        }
    }

    /// Parses [`Variant::name`].
    pub fn parse(s: &str) -> Result<Self, String> {
        Self::ALL.into_iter().find(|v| v.name() == s).ok_or_else(|| {
            let names: Vec<_> = Self::ALL.iter().map(|v| v.name()).collect();
            format!("unknown mode '{s}' (expected one of: {})", names.join(", "))
        })
    }

    /// The paper's table for this mode (`table1`, ...), its title, and the name its CSV uses.
    pub fn paper_table(&self) -> (&'static str, &'static str, &'static str) {
        match self.mode {
            Mode::Stereo => ("table1", "stereo reprojection only (without stereo blending)", "stereo"),
            Mode::Temporal => ("table2", "temporal reprojection only (without stereo blending)", "temporal"),
            Mode::Spatiotemporal => {
                ("table3", "spatiotemporal reprojection (without stereo blending)", "spatiotemporal")
            }
            Mode::StereoBlend => ("table5", "stereo reprojection only (with stereo blending)", "stereo_blend"),
            Mode::SpatiotemporalBlend => {
                ("table6", "spatiotemporal reprojection (with stereo blending)", "spatiotemporal_blend")
            }
            Mode::PathTraced => ("table0", "path tracing", "path_traced"),
        }
    }

    /// Our table id: the paper's, with `b` for the stereo-first order.
    pub fn table_id(&self) -> String {
        let (t, ..) = self.paper_table();
        if self.mode.has_order() && self.order == Order::StereoFirst { format!("{t}b") } else { t.to_owned() }
    }

    /// Rough path-tracing work of one frame relative to one eye's full frame (for the ETA):
    /// modes that fill the left eye from the right trace ~10% of it.
    pub fn traced_eyes_x10(&self) -> u64 {
        match self.mode {
            Mode::Stereo | Mode::Spatiotemporal => 11,
            _ => 20,
        }
    }
}

impl std::fmt::Display for Variant {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.name())
    }
}

/// The independent random streams.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Seeds {
    /// Seed of the pipelines' path tracing
    /// ([`PipelineConfig::seed`](crate::pipeline::PipelineConfig::seed)).
    pub pipeline: u64,
    /// Seed of the error curves' path-traced frames and of the figures' path-traced images.
    pub curve: u64,
    /// Seed of the references.
    pub reference: u64,
}

impl Default for Seeds {
    fn default() -> Self {
        Self { pipeline: 1, curve: 0xC0_4E5, reference: 0x4EF_E4E7CE }
    }
}

/// Which SSIM (never swapped silently: the two give very different numbers).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum SsimChoice {
    /// The paper's: the RGB image as a 3-D volume.
    #[default]
    Volume,
    /// Per channel (2-D), averaged.
    PerChannel,
}

impl SsimChoice {
    /// The SSIM kernel variant this choice runs.
    pub fn kernel(self) -> SsimVariant {
        match self {
            SsimChoice::Volume => SsimVariant::Volume,
            SsimChoice::PerChannel => SsimVariant::PerChannel,
        }
    }
}

/// What the figures show.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FigureSpec {
    /// Figure 3: this scene gets references and short curves for every frame (warm-up
    /// included), and its framewise SSIM is plotted.
    pub framewise_scene: Option<String>,
    /// Figure 3's comparison lines: path-traced frames of these spp.
    pub framewise_spp: Vec<u32>,
    /// Figure 6: discard maps of this scene.
    pub discard_scene: Option<String>,
    /// Figure 7: frame comparison strips of these scenes.
    pub comparison_scenes: Vec<String>,
    /// The frame of Figures 6 and 7 (default: the middle evaluated frame).
    pub frame: Option<u32>,
}

/// Everything that defines an evaluation run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EvalSpec {
    /// The preset it started from (for reports).
    pub preset: String,
    /// Scene specs, each a built-in name, a manifest or a folder, in report order.
    pub scenes: Vec<String>,
    /// Pipeline variants to evaluate.
    pub variants: Vec<Variant>,
    /// Input samples per pixel each variant runs at (each at least 1).
    pub input_spp: Vec<u32>,
    /// Image width of each eye, in pixels.
    pub width: usize,
    /// Image height of each eye, in pixels.
    pub height: usize,
    /// The pipeline renders frames `0..frames`.
    pub frames: u32,
    /// Frames `warmup..frames` are evaluated.
    pub warmup: u32,
    /// Samples per pixel of each reference.
    pub reference_spp: u32,
    /// The error curves' last sample count `M`.
    pub curve_spp: u32,
    /// The sample counts each error curve is measured at.
    pub grid: Grid,
    /// Which SSIM every measurement uses.
    pub ssim: SsimChoice,
    /// The random streams of the pipelines, the curves and the references.
    pub seeds: Seeds,
    /// References and curves are checkpointed every this many samples.
    pub checkpoint_spp: u32,
    /// Distance between the eyes of the stereo rig, in metres.
    pub eye_separation: f32,
    /// How the pipelines make their G-buffers.
    pub gbuffer: crate::render::GBufferPass,
    /// Where each pixel's first sample starts (older specs: jittered, the paper's).
    #[serde(default)]
    pub first_sample: crate::render::FirstSample,
    /// Whether the pipelines get the surfaces' motion vectors (older specs: off).
    #[serde(default)]
    pub motion_vectors: bool,
    /// How far the pipelines' EMA trusts a reprojected history (older specs: the paper's).
    #[serde(default)]
    pub history: crate::pipeline::History,
    /// How the pipelines' stereo blend weighs the eyes (older specs: the paper's).
    #[serde(default)]
    pub blend: crate::pipeline::Blend,
    /// The spatial filter of the pipelines' shown images (older specs: none, the paper's).
    #[serde(default)]
    pub filter: crate::pipeline::Filter,
    /// What the pipelines' reprojection does with background pixels (older specs: the
    /// paper's, traced).
    #[serde(default)]
    pub background: crate::pipeline::Background,
    /// What the figures show.
    pub figures: FigureSpec,
}

/// The paper's scenes that exist as real scenes: manifests in the repository's `scenes/` over
/// the folders of `../shared/scenes`. Paths are relative to the working directory, so the
/// presets that use them run from the repository root.
pub const REAL_SCENES: [&str; 9] = [
    "scenes/real-sponza.toml",
    "scenes/real-sponza-glossy.toml",
    "scenes/real-sponza-moving-light.toml",
    "scenes/real-living-room.toml",
    "scenes/real-living-room-glossy.toml",
    "scenes/real-living-room-moving-light.toml",
    "scenes/real-classroom.toml",
    "scenes/real-classroom-glossy.toml",
    "scenes/real-classroom-mirror.toml",
];

/// The named presets.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Preset {
    /// The paper's setup: 1280×720, 60 frames (10 warm-up), 4096-spp references, input spp
    /// 1..512, every built-in scene and the nine real ones ([`REAL_SCENES`]). Thousands of
    /// CPU hours: run it on a cluster (README).
    Paper,
    /// The paper's setup scaled to one 2-core machine: three real scenes and their three
    /// stand-ins at 320×180, frames 0–15 (10 warm-up), 512-spp references, input spp 1..8.
    /// Its plan is about 2 CPU hours on an idle machine (`RESULTS.md` gives the measured time).
    PaperLite,
    /// Small enough for CI (see `README.md` for the measured time).
    Quick,
}

impl Preset {
    /// The preset's name (`paper`, `paper-lite`, `quick`), as the CLI and reports spell it.
    pub fn name(self) -> &'static str {
        match self {
            Preset::Paper => "paper",
            Preset::PaperLite => "paper-lite",
            Preset::Quick => "quick",
        }
    }

    /// The preset's evaluation spec.
    pub fn spec(self) -> EvalSpec {
        let builtins = crate::scene::builtin_names().into_iter().map(str::to_owned);
        let figures = FigureSpec {
            framewise_scene: Some("classroom-mirror".into()),
            framewise_spp: vec![1, 2, 8, 14, 20],
            discard_scene: Some("atrium".into()),
            comparison_scenes: ["atrium", "living-room-glossy", "classroom-mirror", "courtyard"]
                .map(str::to_owned)
                .to_vec(),
            frame: None,
        };
        let base = EvalSpec {
            preset: self.name().into(),
            scenes: builtins.collect(),
            variants: Variant::ALL.to_vec(),
            input_spp: vec![],
            width: 0,
            height: 0,
            frames: 0,
            warmup: 0,
            reference_spp: 0,
            curve_spp: 0,
            grid: Grid::Dense,
            ssim: SsimChoice::Volume,
            seeds: Seeds::default(),
            checkpoint_spp: 256,
            eye_separation: crate::camera::DEFAULT_EYE_SEPARATION,
            gbuffer: crate::render::GBufferPass::Raster,
            first_sample: crate::render::FirstSample::Jittered,
            motion_vectors: false,
            history: crate::pipeline::History::Paper,
            blend: crate::pipeline::Blend::Fixed,
            filter: crate::pipeline::Filter::None,
            background: crate::pipeline::Background::Trace,
            figures,
        };
        match self {
            Preset::Paper => EvalSpec {
                scenes: base.scenes.iter().cloned().chain(REAL_SCENES.map(str::to_owned)).collect(),
                // The figures of the paper's own scenes where they exist (San Miguel only as
                // its stand-in).
                figures: FigureSpec {
                    framewise_scene: Some("real-classroom-mirror".into()),
                    discard_scene: Some("real-sponza".into()),
                    comparison_scenes: ["real-sponza", "real-living-room-glossy", "real-classroom-mirror", "courtyard"]
                        .map(str::to_owned)
                        .to_vec(),
                    ..base.figures.clone()
                },
                input_spp: vec![1, 2, 4, 8, 16, 32, 64, 128, 256, 512],
                width: 1280,
                height: 720,
                frames: 60,
                warmup: 10,
                reference_spp: 4096,
                curve_spp: 2048,
                grid: Grid::Dense,
                ..base
            },
            // Each real scene beside its own stand-in, so the two can be compared; the
            // Classroom (Mirror) pair is Figure 3's, Sponza's Figure 6's.
            Preset::PaperLite => EvalSpec {
                scenes: ["atrium", "living-room", "classroom-mirror"]
                    .into_iter()
                    .chain([REAL_SCENES[0], REAL_SCENES[3], REAL_SCENES[8]])
                    .map(str::to_owned)
                    .collect(),
                input_spp: vec![1, 2, 4, 8],
                width: 320,
                height: 180,
                frames: 16,
                warmup: 10,
                reference_spp: 512,
                curve_spp: 256,
                grid: Grid::Dense,
                figures: FigureSpec {
                    framewise_scene: Some("real-classroom-mirror".into()),
                    discard_scene: Some("real-sponza".into()),
                    comparison_scenes: ["real-sponza", "real-living-room", "real-classroom-mirror"]
                        .map(str::to_owned)
                        .to_vec(),
                    ..base.figures.clone()
                },
                ..base
            },
            Preset::Quick => EvalSpec {
                input_spp: vec![1, 2, 4],
                width: 128,
                height: 72,
                frames: 14,
                warmup: 10,
                reference_spp: 256,
                curve_spp: 128,
                grid: Grid::Dense,
                ..base
            },
        }
    }
}

impl EvalSpec {
    /// `width` × `height` as an extent, or why it is not one.
    pub fn extent(&self) -> Result<Extent, String> {
        Extent::new(self.width, self.height).map_err(|e| e.to_string())
    }

    /// The evaluated frames.
    pub fn evaluated_frames(&self) -> std::ops::Range<u32> {
        self.warmup..self.frames
    }

    /// The frame of Figures 6 and 7.
    pub fn figure_frame(&self) -> u32 {
        self.figures.frame.unwrap_or(self.warmup + (self.frames - self.warmup) / 2)
    }

    /// Checks the spec for contradictions before any work starts; returns warnings.
    pub fn validate(&self) -> Result<Vec<String>, String> {
        let mut warnings = Vec::new();
        self.extent()?;
        if self.scenes.is_empty() {
            return Err("no scenes to evaluate".into());
        }
        if self.variants.is_empty() {
            return Err("no modes to evaluate".into());
        }
        if self.input_spp.is_empty() || self.input_spp.contains(&0) {
            return Err("input spp must be a non-empty list of values >= 1".into());
        }
        if self.warmup >= self.frames {
            return Err(format!(
                "warm-up of {} frames leaves nothing to evaluate in {} frames",
                self.warmup, self.frames
            ));
        }
        if self.reference_spp == 0 || self.curve_spp == 0 || self.checkpoint_spp == 0 {
            return Err("reference spp, curve spp and checkpoint spp must be at least 1".into());
        }
        if self.curve_spp > self.reference_spp {
            warnings.push(format!(
                "the curves ({} spp) go beyond the reference ({} spp); their upper end measures the reference's noise",
                self.curve_spp, self.reference_spp
            ));
        }
        if let Grid::Geometric { steps_per_octave: 0 } = self.grid {
            return Err("a geometric grid needs at least one step per octave".into());
        }
        if let Some(f) = self.figures.frame
            && !self.evaluated_frames().contains(&f)
        {
            return Err(format!("figure frame {f} is not an evaluated frame ({:?})", self.evaluated_frames()));
        }
        let mut seen = std::collections::HashSet::new();
        for s in &self.scenes {
            if !seen.insert(s) {
                return Err(format!("scene '{s}' is listed twice"));
            }
        }
        Ok(warnings)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn variants_round_trip_through_their_names() {
        for v in Variant::ALL {
            assert_eq!(Variant::parse(&v.name()).unwrap(), v);
        }
        assert!(Variant::parse("spatial").unwrap_err().contains("stereo-blend"));
        assert_eq!(Variant::new(Mode::Stereo, Order::StereoFirst), Variant::ALL[0]);
    }

    #[test]
    fn presets_are_valid_and_cover_every_mode_and_builtin() {
        let builtins = crate::scene::builtin_names();
        for p in [Preset::Quick, Preset::Paper, Preset::PaperLite] {
            let s = p.spec();
            s.validate().unwrap();
            assert_eq!(s.variants, Variant::ALL.to_vec());
            let real = s.scenes.iter().filter(|n| REAL_SCENES.contains(&n.as_str())).count();
            let stand_ins = s.scenes.iter().filter(|n| builtins.contains(&n.as_str())).count();
            assert_eq!(real + stand_ins, s.scenes.len(), "{p:?}: every scene is a built-in or a real one");
            let expected = match p {
                Preset::Quick => (0, builtins.len()),
                Preset::Paper => (REAL_SCENES.len(), builtins.len()),
                Preset::PaperLite => (3, 3),
            };
            assert_eq!((real, stand_ins), expected, "{p:?}");
        }
        let paper = Preset::Paper.spec();
        assert_eq!((paper.width, paper.height, paper.frames, paper.warmup), (1280, 720, 60, 10));
        assert_eq!(paper.evaluated_frames().len(), 50);
    }
}
