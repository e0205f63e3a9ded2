//! Running an evaluation: planning, the cache, progress and resuming.
//!
//! # Work units
//! Per scene, in order: the references of the frames that need one, the error curves of
//! those frames, then every (variant, input spp) configuration (the pipeline over all
//! frames, measured on the frames with a reference), then the figure renders. Each unit is
//! a cache entry (see [`super::cache`] for the format); a run first loads what exists, so
//! an interrupted run resumes at the first missing unit. References and curves are also
//! checkpointed every [`EvalSpec::checkpoint_spp`] samples (a `*-partial` entry holding the
//! running sum), so at the paper's 4096 spp an interruption loses at most one chunk. A
//! configuration is one unit: the pipeline's history is not serialisable, so an interrupted
//! configuration starts again from frame 0.
//!
//! # Keys and the code version
//! Every key holds the scene's fingerprint, the resolution, the eye, the eye separation,
//! frame, spp and seed as they apply, and a code version: [`CACHE_FORMAT`], the crate
//! version, and two behavioural probes. The global probe runs the pipeline in every mode
//! on a tiny Cornell box and measures SSIM between its outputs; the scene probe path traces
//! a tiny image of the scene at its first and last frame. Their output bits change when the
//! renderer, the kernels or the pipeline change what they compute, so stale entries are not
//! reused even if nobody bumps the format. (A change that leaves both probes bit-identical
//! is not detected: bump [`CACHE_FORMAT`] for those.) A configuration's key also holds the
//! full pipeline configuration and the keys of the curves it is measured on.
//!
//! # Progress
//! Work is counted in path-traced pixel samples (the estimate for a configuration counts a
//! left eye filled from the right as a tenth of a frame). Cached units are left out of the
//! total before the run starts, so the ETA only covers what will be computed.

use std::collections::BTreeMap;
use std::time::Instant;

use super::cache::{
    CACHE_FORMAT, Cache, CacheKey, Lookup, Reader, checksum, decode_image, decode_mask, decode_partial, encode_image,
    encode_mask, encode_partial,
};
use super::claim::{Attempt, Claim, clear_orphan, try_claim};
use super::curve::{CurvePoint, FrameCurve, MEASURED_EYE, Measurement, Progressive, measure};
use super::effective::{EffectiveSpp, Grid, Metric};
use super::probes::{code_probe, scene_probe};
use super::results::{
    Artifacts, ComparisonRow, ConfigResult, DiscardMap, EvalOutcome, EvalResults, FrameReasons, FrameResult,
    SceneResult, WorkCounters,
};
use super::spec::{EvalSpec, Variant};
use super::stats::Summary;
use super::units::{Plan, Shard, Unit, UnitKind, assign, config_work, seconds_per_sample};
use crate::camera::{Eye, StereoRig};
use crate::kernels::{Extent, PlaneBuf, RgbBuf};
use crate::pipeline::{Mode, Pipeline, PipelineConfig};
use crate::render::{FrameView, Renderer, RendererOptions};
use crate::session::{CameraWalk, Session};

/// Where a run reports progress and warnings (the CLI shows a progress bar).
pub trait Reporter: Sync {
    /// The run starts; `total` units of work (pixel samples) remain to be computed.
    fn begin(&self, _total: u64) {}
    /// More work than planned (a corrupt cache entry, figure renders).
    fn add_work(&self, _extra: u64) {}
    /// Planned work that turned out not to be needed (resumed from a checkpoint).
    fn skip_work(&self, _work: u64) {}
    /// `done` units of work were computed.
    fn advance(&self, _done: u64) {}
    /// What is being computed now.
    fn status(&self, _message: &str) {}
    /// A non-fatal problem (also collected in [`EvalOutcome::warnings`]).
    fn warn(&self, message: &str) {
        eprintln!("warning: {message}");
    }
}

/// A reporter that shows nothing.
pub struct Quiet;

impl Reporter for Quiet {
    fn warn(&self, _message: &str) {}
}

/// Stops a run early (tests; splitting a long run into sessions).
#[derive(Clone, Copy, Debug, Default)]
pub struct Limits {
    /// Stop with [`EvalError::Interrupted`] before computing more than this many units
    /// (references, curves, configurations).
    pub max_computed_units: Option<usize>,
    /// Stop with [`EvalError::Interrupted`] once this many pixel samples have been traced,
    /// even inside a reference or curve (after writing its checkpoint): simulates a run
    /// killed mid-unit.
    pub max_samples: Option<u64>,
}

/// Why a run stopped.
#[derive(Debug, thiserror::Error)]
pub enum EvalError {
    /// The run cannot go on; the message says why.
    #[error("{0}")]
    Failed(String),
    /// A [`Limits`] limit was reached; finished units are cached, so a rerun resumes.
    #[error("stopped after computing {computed} units (limit reached); run again to resume")]
    Interrupted {
        /// Units computed before the stop.
        computed: usize,
        /// Work done before the stop.
        counters: WorkCounters,
    },
    /// A merge found entries missing from the cache (each named: kind, scene, what).
    #[error("the cache lacks {} of the run's entries (run the missing shards first):\n  {}", .0.len(), .0.join("\n  "))]
    Missing(Vec<String>),
}

impl From<String> for EvalError {
    fn from(s: String) -> Self {
        EvalError::Failed(s)
    }
}

/// How often a process waiting for another's claim looks again.
const CLAIM_POLL: std::time::Duration = std::time::Duration::from_millis(500);
/// How often a wait is reported again.
const WAIT_REPORT: std::time::Duration = std::time::Duration::from_secs(30);

/// A scene's references and curves, held while a shard runs that scene's units.
struct SceneInputs {
    scene: usize,
    references: BTreeMap<u32, RgbBuf>,
    curves: BTreeMap<u32, FrameCurve>,
}

/// What to do for one configuration.
struct ConfigPlan {
    variant: Variant,
    spp: u32,
    key: CacheKey,
    /// Keep the left-eye output at the figure frame (Figure 7).
    keep_output: bool,
    /// Keep the reason planes at the figure frame (Figure 6).
    keep_reasons: bool,
}

impl ConfigPlan {
    fn output_key(&self, frame: u32) -> CacheKey {
        self.key.derive("artifact", &[("what", "left-output".into()), ("frame", frame.to_string())])
    }
    fn reasons_key(&self, frame: u32, kind: &str) -> CacheKey {
        self.key.derive("artifact", &[("what", format!("{kind}-reasons")), ("frame", frame.to_string())])
    }
    /// Which reason planes Figure 6 keeps of this configuration.
    fn reasons_kind(&self) -> &'static str {
        if self.variant.mode == Mode::Stereo { "stereo" } else { "temporal" }
    }
}

/// One scene's units and keys.
struct ScenePlan {
    renderer: Renderer,
    name: String,
    base: Vec<(&'static str, String)>,
    fingerprint: u64,
    /// Frames with a reference, with the curve length each gets and the two keys.
    frames: Vec<(u32, u32, CacheKey, CacheKey)>,
    /// Extra sample counts every curve of this scene measures (Figure 3's).
    extra_points: Vec<u32>,
    configs: Vec<ConfigPlan>,
    comparison: bool,
}

fn grid_points(grid: Grid, max_spp: u32, extra: &[u32]) -> Vec<u32> {
    let mut pts = grid.points(max_spp);
    pts.extend(extra.iter().copied().filter(|&m| m >= 1 && m <= max_spp));
    pts.sort_unstable();
    pts.dedup();
    pts
}

struct Runner<'a> {
    spec: &'a EvalSpec,
    cache: &'a Cache,
    reporter: &'a dyn Reporter,
    limits: Limits,
    extent: Extent,
    rig: StereoRig,
    counters: WorkCounters,
    warnings: Vec<String>,
    /// Compute nothing: every entry must be in the cache (`eval --merge`).
    merge_only: bool,
}

impl Runner<'_> {
    fn warn(&mut self, message: String) {
        self.reporter.warn(&message);
        self.warnings.push(message);
    }

    fn pixels(&self) -> u64 {
        self.extent.pixels() as u64
    }

    /// The verified payload of `key`, counting hits and warning about corrupt entries.
    fn load(&mut self, key: &CacheKey) -> Option<Vec<u8>> {
        match self.cache.get(key) {
            Lookup::Hit(b) => {
                self.counters.cache_hits += 1;
                Some(b)
            }
            Lookup::Miss => None,
            Lookup::Corrupt(why) => {
                self.counters.corrupt_entries += 1;
                self.warn(format!("corrupt cache entry, recomputing: {why}"));
                None
            }
        }
    }

    /// Decodes a verified payload; a payload that verifies but does not decode (an older
    /// layout under the same format number) is treated like a corrupt entry.
    fn load_with<T>(&mut self, key: &CacheKey, decode: impl FnOnce(&[u8]) -> Result<T, String>) -> Option<T> {
        let bytes = self.load(key)?;
        match decode(&bytes) {
            Ok(v) => Some(v),
            Err(why) => {
                self.counters.cache_hits -= 1;
                self.counters.corrupt_entries += 1;
                self.warn(format!("undecodable cache entry, recomputing: {}: {why}", self.cache.path(key).display()));
                None
            }
        }
    }

    fn load_image(&mut self, key: &CacheKey) -> Option<RgbBuf> {
        self.load_with(key, |b| {
            let mut r = Reader::new(b);
            let img = decode_image(&mut r)?;
            if r.finished() { Ok(img) } else { Err("trailing bytes".into()) }
        })
    }

    fn load_mask(&mut self, key: &CacheKey) -> Option<PlaneBuf<u8>> {
        self.load_with(key, |b| {
            let mut r = Reader::new(b);
            let m = decode_mask(&mut r)?;
            if r.finished() { Ok(m) } else { Err("trailing bytes".into()) }
        })
    }

    fn put_image(&mut self, key: &CacheKey, img: &RgbBuf) -> Result<(), String> {
        let mut bytes = Vec::new();
        encode_image(img, &mut bytes);
        self.cache.put(key, &bytes)
    }

    fn put_mask(&mut self, key: &CacheKey, m: &PlaneBuf<u8>) -> Result<(), String> {
        let mut bytes = Vec::new();
        encode_mask(m, &mut bytes);
        self.cache.put(key, &bytes)
    }

    /// Refuses to start another unit once a limit is reached.
    fn start_unit(&self) -> Result<(), EvalError> {
        let computed = self.counters.computed_units();
        let units = self.limits.max_computed_units.is_some_and(|max| computed >= max);
        if units || self.samples_exhausted() {
            return Err(EvalError::Interrupted { computed, counters: self.counters });
        }
        Ok(())
    }

    /// The entry of `key`: loaded when it is in the cache; otherwise computed under a claim
    /// (see [`super::claim`]), or waited for while another process holds the claim. A merge
    /// computes nothing and reports the entry missing.
    fn obtain<T>(
        &mut self,
        key: &CacheKey,
        what: &str,
        mut load: impl FnMut(&mut Self) -> Option<T>,
        compute: impl FnOnce(&mut Self, &mut Claim) -> Result<T, EvalError>,
    ) -> Result<T, EvalError> {
        // When the wait for another holder began, and when it was last reported.
        let mut waiting_since: Option<(Instant, Option<Instant>)> = None;
        loop {
            if let Some(v) = load(self) {
                if !self.merge_only {
                    clear_orphan(&self.cache.path(key));
                }
                return Ok(v);
            }
            if self.merge_only {
                return Err(EvalError::Missing(vec![format!("{} {what}", key.kind())]));
            }
            match try_claim(&self.cache.path(key))? {
                Attempt::Acquired(mut claim) => {
                    // Another process may have written the entry and released its claim
                    // between our load and our claim: then it is not computed twice.
                    if self.cache.contains(key)
                        && matches!(self.cache.get(key), Lookup::Hit(_))
                        && let Some(v) = load(self)
                    {
                        return Ok(v);
                    }
                    return compute(self, &mut claim);
                }
                Attempt::HeldBy(holder) => {
                    // Said when the wait starts and every half minute (a log is not a ticker).
                    let now = Instant::now();
                    let (since, said) = waiting_since.get_or_insert((now, None));
                    if said.is_none_or(|t: Instant| now - t >= WAIT_REPORT) {
                        *said = Some(now);
                        self.reporter.status(&format!(
                            "waiting for the {what}: {holder} is computing it (waited {:.0} s)",
                            (now - *since).as_secs_f64()
                        ));
                    }
                    std::thread::sleep(CLAIM_POLL);
                }
            }
        }
    }

    fn samples_exhausted(&self) -> bool {
        self.limits.max_samples.is_some_and(|max| self.counters.samples >= max)
    }

    /// Inside a progressive unit: checkpoints and stops once the sample limit is reached.
    fn check_samples(&self, partial: &CacheKey, prog: &Progressive, points: &[CurvePoint]) -> Result<(), EvalError> {
        if self.samples_exhausted() {
            self.cache.put(partial, &encode_partial(prog.samples(), points, prog.sum()))?;
            return Err(EvalError::Interrupted { computed: self.counters.computed_units(), counters: self.counters });
        }
        Ok(())
    }

    /// Loads the scene `scene_spec` (a built-in name, a manifest or a folder) and plans its
    /// units. From here on the scene is known by its own name (a manifest's `name`, a folder's
    /// name), which keys its cache entries and names it in every report.
    fn plan_scene(&mut self, scene_spec: &str, global_probe: u64) -> Result<ScenePlan, String> {
        let spec = self.spec;
        self.reporter.status(&format!("{scene_spec}: building the scene and its BVH"));
        let scene = crate::scene::resolve(scene_spec).map_err(|e| format!("scene '{scene_spec}': {e}"))?;
        let name = scene.name.clone();
        let name = name.as_str();
        for w in &scene.warnings {
            self.warn(format!("{name}: {w}"));
        }
        if spec.frames > scene.frame_count() {
            return Err(format!(
                "{name}: {} frames asked for, but its camera path has {}",
                spec.frames,
                scene.frame_count()
            ));
        }
        let fingerprint = scene.fingerprint();
        let renderer = Renderer::new(scene).map_err(|e| format!("{name}: {e}"))?;
        let probe = scene_probe(&renderer, &self.rig)?;
        let code = format!("{CACHE_FORMAT}/{}/{global_probe:016x}", env!("CARGO_PKG_VERSION"));
        let base: Vec<(&'static str, String)> = vec![
            ("code", code),
            ("fingerprint", format!("{fingerprint:016x}")),
            ("probe", format!("{probe:016x}")),
            ("extent", self.extent.to_string()),
            ("eye", "left".into()),
            ("separation", format!("{:08x}", spec.eye_separation.to_bits())),
            ("integrator", "specialised".into()),
        ];
        let framewise = spec.figures.framewise_scene.as_deref() == Some(name);
        let extra_points = if framewise { spec.figures.framewise_spp.clone() } else { Vec::new() };
        let short = spec.figures.framewise_spp.iter().copied().max().unwrap_or(1).min(spec.curve_spp);
        let frame_list: Vec<u32> =
            if framewise { (0..spec.frames).collect() } else { spec.evaluated_frames().collect() };
        let mut frames = Vec::new();
        for f in frame_list {
            let max_spp = if spec.evaluated_frames().contains(&f) { spec.curve_spp } else { short };
            let mut fields = base.clone();
            fields.extend([
                ("frame", f.to_string()),
                ("spp", spec.reference_spp.to_string()),
                ("seed", spec.seeds.reference.to_string()),
            ]);
            let reference = CacheKey::new("reference", name, &fields);
            let points = grid_points(spec.grid, max_spp, &extra_points);
            let curve = reference.derive(
                "curve",
                &[
                    ("max-spp", max_spp.to_string()),
                    ("grid", spec.grid.describe()),
                    ("points", format!("{:016x}", checksum(&[format!("{points:?}").as_bytes()]))),
                    ("seed", spec.seeds.curve.to_string()),
                    ("ssim", format!("{:?}", spec.ssim)),
                ],
            );
            frames.push((f, max_spp, reference, curve));
        }
        let curve_keys: Vec<&str> = frames.iter().map(|(.., c)| c.text()).collect();
        let curves_hash = checksum(&[curve_keys.join("|").as_bytes()]);
        let figure_frame = spec.figure_frame();
        let comparison = spec.figures.comparison_scenes.iter().any(|s| s == name);
        let discard = spec.figures.discard_scene.as_deref() == Some(name);
        let tol = renderer.scene().tolerances.at_height(self.extent.height());
        let first_spp = spec.input_spp.iter().copied().min().unwrap_or(1);
        let mut configs = Vec::new();
        for &variant in &spec.variants {
            for &spp in &spec.input_spp {
                let keep_output = comparison && variant == Variant::ALL[2];
                let keep_reasons = discard && spp == first_spp && matches!(variant.mode, Mode::Stereo | Mode::Temporal);
                let cfg = pipeline_config(spec, variant, spp, tol);
                let mut fields = base.clone();
                fields.extend([
                    ("variant", variant.name()),
                    ("pipeline", format!("{cfg:?}")),
                    // The renderer's own option, not a pipeline setting: its images differ
                    // within the pass's tolerance, so its results are their own entries.
                    ("gbuffer", spec.gbuffer.cache_key().into()),
                    ("frames", spec.frames.to_string()),
                    ("warmup", spec.warmup.to_string()),
                    ("curves", format!("{curves_hash:016x}")),
                    ("artifacts", format!("{keep_output}/{keep_reasons}/{figure_frame}")),
                ]);
                // A constant of the pipeline, not a field of its configuration: named here so
                // that a change of it is a new entry (the paper's configurations' keys stay).
                // The renderer's option too; named only when it is not the paper's, so that
                // the paper's entries keep their keys.
                if spec.first_sample != crate::render::FirstSample::Jittered {
                    fields.push(("first-sample", spec.first_sample.name().into()));
                }
                if cfg.history == crate::pipeline::History::Clamp {
                    fields.push(("clamp-gamma", crate::pipeline::CLAMP_GAMMA.to_string()));
                }
                let key = CacheKey::new("config", name, &fields);
                configs.push(ConfigPlan { variant, spp, key, keep_output, keep_reasons });
            }
        }
        Ok(ScenePlan {
            renderer,
            name: name.to_owned(),
            base,
            fingerprint,
            frames,
            extra_points,
            configs,
            comparison: comparison && spec.variants.contains(&Variant::ALL[2]),
        })
    }

    /// Work left in a plan (entries that exist count as done; checkpoints are ignored).
    fn pending_work(&self, plan: &ScenePlan) -> u64 {
        let p = self.pixels();
        let mut work = 0;
        for (_, max_spp, reference, curve) in &plan.frames {
            if !self.cache.contains(reference) {
                work += p * u64::from(self.spec.reference_spp);
            }
            if !self.cache.contains(curve) {
                work += p * u64::from(*max_spp);
            }
        }
        for c in &plan.configs {
            if !self.cache.contains(&c.key) {
                work += config_work(p, self.spec.frames, c.variant, c.spp);
            }
        }
        work
    }

    /// Renders (or loads, or resumes, or waits for) the reference of frame `f`.
    fn reference(&mut self, plan: &ScenePlan, f: u32, key: &CacheKey) -> Result<RgbBuf, EvalError> {
        let what = format!("reference of {} frame {f}", plan.name);
        self.obtain(key, &what, |s| s.load_image(key), |s, claim| s.compute_reference(plan, f, key, claim))
    }

    fn compute_reference(
        &mut self,
        plan: &ScenePlan,
        f: u32,
        key: &CacheKey,
        claim: &mut Claim,
    ) -> Result<RgbBuf, EvalError> {
        self.start_unit()?;
        let r = self.spec.reference_spp;
        self.reporter.status(&format!("{}: reference of frame {f} ({r} spp)", plan.name));
        let partial = key.derive("reference-partial", &[]);
        let (mut prog, _) = self.resume(&partial, r)?;
        let view = FrameView::new(&plan.renderer, &self.rig, self.extent, f).map_err(|e| e.to_string())?;
        while prog.samples() < r {
            let stats = prog.add_sample(&plan.renderer, &view, self.spec.seeds.reference, false)?;
            self.counters.samples += stats.samples;
            self.reporter.advance(self.pixels());
            claim.heartbeat();
            if prog.samples() % self.spec.checkpoint_spp == 0 && prog.samples() < r {
                self.cache.put(&partial, &encode_partial(prog.samples(), &[], prog.sum()))?;
            }
            if prog.samples() < r {
                self.check_samples(&partial, &prog, &[])?;
            }
        }
        let img = prog.mean().clone();
        self.put_image(key, &img)?;
        self.cache.remove(&partial);
        self.counters.references += 1;
        Ok(img)
    }

    /// A progressive state from a checkpoint, or empty.
    fn resume(&mut self, partial: &CacheKey, target: u32) -> Result<(Progressive, Vec<CurvePoint>), String> {
        if let Some((samples, points, sum)) = self.load_with(partial, decode_partial)
            && sum.extent == self.extent
            && samples <= target
        {
            self.reporter.skip_work(self.pixels() * u64::from(samples));
            return Ok((Progressive::resume(samples, sum), points));
        }
        Ok((Progressive::new(self.extent), Vec::new()))
    }

    /// Warns where `curve` rises (more samples, more error), whether it was computed in this
    /// run or loaded from the cache, so a resumed run reports what a fresh one does.
    fn note_rises(&mut self, scene: &str, curve: &FrameCurve) -> Result<(), EvalError> {
        for metric in Metric::ALL {
            let rises = curve.curve(metric)?.rises();
            if !rises.is_empty() {
                let at: Vec<u32> = rises.iter().map(|&i| curve.points[i + 1].spp).collect();
                let message = format!(
                    "{scene}: frame {}: the {} error curve rises at {} of {} steps (spp {:?}); the first-crossing \
                     policy applies",
                    curve.frame,
                    metric.label(),
                    at.len(),
                    curve.points.len() - 1,
                    &at[..at.len().min(8)]
                );
                // Once per curve, however often this run looks it up.
                if !self.warnings.contains(&message) {
                    self.warnings.push(message);
                }
            }
        }
        Ok(())
    }

    /// Builds (or loads, or resumes) the error curve of frame `f`.
    fn curve(
        &mut self,
        plan: &ScenePlan,
        f: u32,
        max_spp: u32,
        key: &CacheKey,
        reference: &RgbBuf,
    ) -> Result<FrameCurve, EvalError> {
        let points_wanted = grid_points(self.spec.grid, max_spp, &plan.extra_points);
        let load = |s: &mut Self| {
            let c = s.load_with(key, |b| serde_json::from_slice::<FrameCurve>(b).map_err(|e| e.to_string()))?;
            if c.frame == f && c.points.iter().map(|p| p.spp).eq(points_wanted.iter().copied()) {
                return Some(c);
            }
            s.warn(format!("cache entry {} holds another curve; rebuilding", s.cache.path(key).display()));
            None
        };
        let what = format!("error curve of {} frame {f}", plan.name);
        let curve = self.obtain(key, &what, load, |s, claim| {
            s.compute_curve(plan, f, max_spp, &points_wanted, key, reference, claim)
        })?;
        // Loaded or computed, a curve warns the same (a resumed run reports what a fresh one does).
        self.note_rises(&plan.name, &curve)?;
        Ok(curve)
    }

    #[allow(clippy::too_many_arguments)]
    fn compute_curve(
        &mut self,
        plan: &ScenePlan,
        f: u32,
        max_spp: u32,
        points_wanted: &[u32],
        key: &CacheKey,
        reference: &RgbBuf,
        claim: &mut Claim,
    ) -> Result<FrameCurve, EvalError> {
        self.start_unit()?;
        self.reporter.status(&format!("{}: error curve of frame {f} (1..{max_spp} spp)", plan.name));
        let partial = key.derive("curve-partial", &[]);
        let (mut prog, mut points) = self.resume(&partial, max_spp)?;
        if points.len() != points_wanted.iter().filter(|&&m| m <= prog.samples()).count() {
            // A checkpoint whose points do not match its sample count: start over.
            self.reporter.add_work(self.pixels() * u64::from(prog.samples()));
            (prog, points) = (Progressive::new(self.extent), Vec::new());
        }
        let view = FrameView::new(&plan.renderer, &self.rig, self.extent, f).map_err(|e| e.to_string())?;
        let variant = self.spec.ssim.kernel();
        while prog.samples() < max_spp {
            let stats = prog.add_sample(&plan.renderer, &view, self.spec.seeds.curve, false)?;
            self.counters.samples += stats.samples;
            let m = prog.samples();
            if points_wanted.binary_search(&m).is_ok() {
                let Measurement { ssim, rmse } = measure(prog.mean(), reference, variant)?;
                points.push(CurvePoint { spp: m, ssim, rmse });
            }
            self.reporter.advance(self.pixels());
            claim.heartbeat();
            if m % self.spec.checkpoint_spp == 0 && m < max_spp {
                self.cache.put(&partial, &encode_partial(m, &points, prog.sum()))?;
            }
            if m < max_spp {
                self.check_samples(&partial, &prog, &points)?;
            }
        }
        let curve = FrameCurve { frame: f, grid: self.spec.grid, points };
        self.cache.put(key, &serde_json::to_vec(&curve).map_err(|e| e.to_string())?)?;
        self.cache.remove(&partial);
        self.counters.curves += 1;
        Ok(curve)
    }

    /// Runs (or loads) one configuration.
    fn config(
        &mut self,
        plan: &ScenePlan,
        c: &ConfigPlan,
        references: &BTreeMap<u32, RgbBuf>,
        curves: &BTreeMap<u32, FrameCurve>,
    ) -> Result<ConfigResult, EvalError> {
        let figure_frame = self.spec.figure_frame();
        let load = |s: &mut Self| {
            // The artifacts are written before the result, so a result implies them; checked
            // anyway, for a cache that lost files.
            let artifacts_present = (!c.keep_output || s.cache.contains(&c.output_key(figure_frame)))
                && (!c.keep_reasons || s.cache.contains(&c.reasons_key(figure_frame, c.reasons_kind())));
            if !artifacts_present {
                return None;
            }
            s.load_with(&c.key, |b| serde_json::from_slice::<ConfigResult>(b).map_err(|e| e.to_string()))
        };
        let what = format!("{} {} at {} spp", plan.name, c.variant, c.spp);
        self.obtain(&c.key, &what, load, |s, claim| s.compute_config(plan, c, references, curves, claim))
    }

    fn compute_config(
        &mut self,
        plan: &ScenePlan,
        c: &ConfigPlan,
        references: &BTreeMap<u32, RgbBuf>,
        curves: &BTreeMap<u32, FrameCurve>,
        claim: &mut Claim,
    ) -> Result<ConfigResult, EvalError> {
        let figure_frame = self.spec.figure_frame();
        self.start_unit()?;
        self.reporter.status(&format!("{}: {} at {} spp", plan.name, c.variant, c.spp));
        let spec = self.spec;
        let tol = plan.renderer.scene().tolerances.at_height(self.extent.height());
        let cfg = pipeline_config(spec, c.variant, c.spp, tol);
        let options = RendererOptions::with_first_sample(spec.gbuffer, spec.first_sample);
        let pipeline =
            Pipeline::with_options(&plan.renderer, options, cfg, self.rig, self.extent).map_err(|e| e.to_string())?;
        let mut session = Session::new(pipeline, CameraWalk::Path);
        let mut result = ConfigResult {
            variant: c.variant,
            spp: c.spp,
            frames: Vec::new(),
            stereo_reasons: Vec::new(),
            temporal_reasons: Vec::new(),
            ssim: Summary::of_values(&[]),
            rmse: Summary::of_values(&[]),
            traced_left_pixels: 0,
        };
        let per_frame = config_work(self.pixels(), 1, c.variant, c.spp);
        let variant = spec.ssim.kernel();
        for f in 0..spec.frames {
            let stats = session.next_frame().map_err(|e| format!("{}: frame {f}: {e}", plan.name))?;
            let p = session.pipeline();
            self.counters.samples += stats.trace.samples;
            result.traced_left_pixels += stats.pixels_traced(Eye::Left as usize);
            result.stereo_reasons.push(FrameReasons { frame: f, counts: stats.stereo_reasons[Eye::Left as usize].0 });
            result
                .temporal_reasons
                .push(FrameReasons { frame: f, counts: stats.temporal_reasons[Eye::Left as usize].0 });
            if let Some(reference) = references.get(&f) {
                let m = measure(p.output(Eye::Left), reference, variant)?;
                let evaluated = spec.evaluated_frames().contains(&f);
                let eff = |metric| -> Result<Option<EffectiveSpp>, String> {
                    if !evaluated {
                        return Ok(None);
                    }
                    let curve = curves.get(&f).ok_or_else(|| format!("no curve for frame {f}"))?;
                    Ok(Some(curve.curve(metric)?.effective_spp(m.error(metric))))
                };
                result.frames.push(FrameResult {
                    frame: f,
                    evaluated,
                    ssim: m.ssim,
                    rmse: m.rmse,
                    effective_ssim: eff(Metric::Ssim)?,
                    effective_rmse: eff(Metric::Rmse)?,
                });
            }
            if f == figure_frame {
                if c.keep_output {
                    self.put_image(&c.output_key(f), p.output(Eye::Left))?;
                }
                if c.keep_reasons {
                    let plane = if c.variant.mode == Mode::Stereo {
                        p.stereo_reasons(Eye::Left)
                    } else {
                        p.temporal_reasons(Eye::Left)
                    };
                    let plane = plane.clone();
                    self.put_mask(&c.reasons_key(f, c.reasons_kind()), &plane)?;
                }
            }
            self.reporter.advance(per_frame);
            claim.heartbeat();
        }
        let evaluated: Vec<&FrameResult> = result.frames.iter().filter(|r| r.evaluated).collect();
        let of = |metric| Summary::of_frames(&evaluated.iter().filter_map(|r| r.effective(metric)).collect::<Vec<_>>());
        result.ssim = of(Metric::Ssim);
        result.rmse = of(Metric::Rmse);
        self.cache.put(&c.key, &serde_json::to_vec(&result).map_err(|e| e.to_string())?)?;
        self.counters.configs += 1;
        Ok(result)
    }

    /// A path-traced figure image of the figure frame (cached).
    fn figure_image(&mut self, plan: &ScenePlan, frame: u32, spp: u32) -> Result<RgbBuf, EvalError> {
        let mut fields = plan.base.clone();
        fields.extend([
            ("frame", frame.to_string()),
            ("spp", spp.to_string()),
            ("seed", self.spec.seeds.curve.to_string()),
        ]);
        let key = CacheKey::new("figure-image", &plan.name, &fields);
        let what = format!("figure image of {} frame {frame} at {spp} spp", plan.name);
        self.obtain(&key, &what, |s| s.load_image(&key), |s, _claim| s.compute_figure_image(plan, frame, spp, &key))
    }

    fn compute_figure_image(
        &mut self,
        plan: &ScenePlan,
        frame: u32,
        spp: u32,
        key: &CacheKey,
    ) -> Result<RgbBuf, EvalError> {
        let work = self.pixels() * u64::from(spp);
        self.reporter.add_work(work);
        self.reporter.status(&format!("{}: figure frame {frame} at {spp} spp", plan.name));
        let view = FrameView::new(&plan.renderer, &self.rig, self.extent, frame).map_err(|e| e.to_string())?;
        let request = view.request(MEASURED_EYE, spp, self.spec.seeds.curve, 0);
        let (img, stats) = view.render(&plan.renderer, &request, false).map_err(|e| e.to_string())?;
        self.counters.samples += stats.samples;
        self.counters.figure_images += 1;
        self.reporter.advance(work);
        self.put_image(key, &img)?;
        Ok(img)
    }

    fn run_scene(&mut self, plan: &ScenePlan, artifacts: &mut Artifacts) -> Result<SceneResult, EvalError> {
        let mut references = BTreeMap::new();
        for (f, _, key, _) in &plan.frames {
            let img = self.reference(plan, *f, key)?;
            references.insert(*f, img);
        }
        let mut curves = BTreeMap::new();
        for (f, max_spp, _, key) in &plan.frames {
            let c = self.curve(plan, *f, *max_spp, key, &references[f])?;
            curves.insert(*f, c);
        }
        let mut configs = Vec::new();
        for c in &plan.configs {
            configs.push(self.config(plan, c, &references, &curves)?);
        }
        let scene = plan.renderer.scene();
        let result = SceneResult {
            name: plan.name.clone(),
            display_name: scene.display_name.clone(),
            paper_scene: scene.paper_scene.clone(),
            fingerprint: format!("{:016x}", plan.fingerprint),
            curves: curves.into_values().collect(),
            configs,
        };
        self.figures(plan, &result, &references, artifacts)?;
        Ok(result)
    }

    /// The units of a run in plan order (scene by scene: references, curves,
    /// configurations, figures), with their CPU time when the scenes' rates are given.
    fn units(&self, plans: &[ScenePlan], seconds_per_sample: Option<&[f64]>) -> Vec<Unit> {
        let p = self.pixels();
        let mut units = Vec::new();
        let entry = |key: &CacheKey| {
            let path = self.cache.path(key);
            Some(path.strip_prefix(self.cache.root()).unwrap_or(&path).display().to_string())
        };
        for (scene, plan) in plans.iter().enumerate() {
            let rate = seconds_per_sample.map_or(0.0, |r| r[scene]);
            let mut push = |kind: UnitKind, samples: u64, dependencies: usize, entry: Option<String>| {
                let cpu_seconds = samples as f64 * rate;
                let scene_name = plan.name.clone();
                units.push(Unit { scene, scene_name, kind, samples, cpu_seconds, dependencies, entry });
            };
            for (f, _, key, _) in &plan.frames {
                push(UnitKind::Reference { frame: *f }, p * u64::from(self.spec.reference_spp), 0, entry(key));
            }
            for (f, max_spp, _, key) in &plan.frames {
                push(UnitKind::Curve { frame: *f }, p * u64::from(*max_spp), 1, entry(key));
            }
            let inputs = 2 * plan.frames.len();
            for c in &plan.configs {
                let samples = config_work(p, self.spec.frames, c.variant, c.spp);
                push(UnitKind::Config { variant: c.variant, spp: c.spp }, samples, inputs, entry(&c.key));
            }
            if plan.comparison {
                // Each row: its input spp and its effective spp (unknown before the run;
                // counted as 8× the input).
                let rows: u64 = plan.configs.iter().filter(|c| c.keep_output).map(|c| 9 * u64::from(c.spp)).sum();
                push(UnitKind::Figures, p * rows, inputs + plan.configs.len(), None);
            }
        }
        units
    }

    /// The references and curves of `plan`'s scene (kept between units of one scene).
    fn inputs<'s>(
        &mut self,
        plan: &ScenePlan,
        scene: usize,
        held: &'s mut Option<SceneInputs>,
    ) -> Result<&'s SceneInputs, EvalError> {
        if held.as_ref().is_none_or(|h| h.scene != scene) {
            *held = None;
            let mut references = BTreeMap::new();
            for (f, _, key, _) in &plan.frames {
                references.insert(*f, self.reference(plan, *f, key)?);
            }
            let mut curves = BTreeMap::new();
            for (f, max_spp, _, key) in &plan.frames {
                curves.insert(*f, self.curve(plan, *f, *max_spp, key, &references[f])?);
            }
            *held = Some(SceneInputs { scene, references, curves });
        }
        Ok(held.as_ref().expect("just filled"))
    }

    /// Computes (or loads, or waits for) one unit of a shard, and what it needs first.
    fn run_unit(&mut self, plan: &ScenePlan, unit: &Unit, held: &mut Option<SceneInputs>) -> Result<(), EvalError> {
        let frame_keys = |f: u32| plan.frames.iter().find(|(g, ..)| *g == f).expect("a planned frame");
        match &unit.kind {
            UnitKind::Reference { frame } => {
                let (f, _, key, _) = frame_keys(*frame);
                self.reference(plan, *f, key)?;
            }
            UnitKind::Curve { frame } => {
                let (f, max_spp, reference, curve) = frame_keys(*frame);
                let image = self.reference(plan, *f, reference)?;
                self.curve(plan, *f, *max_spp, curve, &image)?;
            }
            UnitKind::Config { variant, spp } => {
                let c = plan.configs.iter().find(|c| c.variant == *variant && c.spp == *spp).expect("a planned config");
                let inputs = self.inputs(plan, unit.scene, held)?;
                self.config(plan, c, &inputs.references, &inputs.curves)?;
            }
            UnitKind::Figures => {
                // The scene's results decide which images Figure 7 needs.
                let mut artifacts = Artifacts::default();
                self.run_scene(plan, &mut artifacts)?;
            }
        }
        Ok(())
    }

    /// Collects the images of Figures 6 and 7 for this scene.
    fn figures(
        &mut self,
        plan: &ScenePlan,
        result: &SceneResult,
        references: &BTreeMap<u32, RgbBuf>,
        artifacts: &mut Artifacts,
    ) -> Result<(), EvalError> {
        let frame = self.spec.figure_frame();
        for c in plan.configs.iter().filter(|c| c.keep_reasons) {
            let kind = c.reasons_kind();
            if let Some(reasons) = self.load_mask(&c.reasons_key(frame, kind)) {
                artifacts.discard_maps.push(DiscardMap {
                    scene: plan.name.clone(),
                    frame,
                    kind,
                    reasons,
                    background: references[&frame].clone(),
                });
            }
        }
        if !plan.comparison {
            return Ok(());
        }
        for c in plan.configs.iter().filter(|c| c.keep_output) {
            let Some(reprojected) = self.load_image(&c.output_key(frame)) else { continue };
            let Some(effective) = result
                .config(c.variant, c.spp)
                .and_then(|r| r.frames.iter().find(|fr| fr.frame == frame))
                .and_then(|fr| fr.effective_ssim)
            else {
                continue;
            };
            let comparison_spp = match effective {
                EffectiveSpp::InRange { spp, .. } => (spp.round() as u32).max(1),
                EffectiveSpp::AboveRange { max_spp } => max_spp,
                EffectiveSpp::BelowRange | EffectiveSpp::Undefined => 1,
            };
            let path_traced = self.figure_image(plan, frame, c.spp)?;
            let comparison = self.figure_image(plan, frame, comparison_spp)?;
            artifacts.comparisons.push(ComparisonRow {
                scene: plan.name.clone(),
                frame,
                spp: c.spp,
                path_traced,
                reprojected,
                effective,
                comparison_spp,
                comparison,
            });
        }
        Ok(())
    }
}

/// The pipeline configuration of a variant at `spp` (the paper's settings; the spec's
/// G-buffer pass is the renderer's option, [`RendererOptions`]).
pub fn pipeline_config(
    spec: &EvalSpec,
    variant: Variant,
    spp: u32,
    tolerances: crate::kernels::reproject::Tolerances,
) -> PipelineConfig {
    let mut cfg = PipelineConfig::paper(variant.mode, spp, tolerances);
    cfg.order = variant.order;
    cfg.seed = spec.seeds.pipeline;
    cfg.motion_vectors = spec.motion_vectors;
    cfg.history = spec.history;
    cfg.blend = spec.blend;
    cfg.filter = spec.filter;
    cfg.background = spec.background;
    cfg
}

/// The runner and the scenes' plans of a run (every scope starts here).
fn prepare<'a>(
    spec: &'a EvalSpec,
    cache: &'a Cache,
    reporter: &'a dyn Reporter,
    limits: Limits,
) -> Result<(Runner<'a>, Vec<ScenePlan>, u64), EvalError> {
    let spec_warnings = spec.validate()?;
    let mut runner = Runner {
        spec,
        cache,
        reporter,
        limits,
        extent: spec.extent()?,
        rig: StereoRig::new(spec.eye_separation)?,
        counters: WorkCounters::default(),
        warnings: Vec::new(),
        merge_only: false,
    };
    for w in spec_warnings {
        runner.warn(w);
    }
    reporter.status("probing the code version");
    let global_probe = code_probe()?;
    let mut plans: Vec<ScenePlan> = Vec::new();
    for scene_spec in &spec.scenes {
        let plan = runner.plan_scene(scene_spec, global_probe)?;
        if let Some(j) = plans.iter().position(|p| p.name == plan.name) {
            return Err(EvalError::Failed(format!(
                "scenes '{}' and '{scene_spec}' are both named '{}': every scene of a run needs its own name",
                spec.scenes[j], plan.name
            )));
        }
        plans.push(plan);
    }
    let figures = &spec.figures;
    for figure_scene in figures.framewise_scene.iter().chain(&figures.discard_scene).chain(&figures.comparison_scenes) {
        if !plans.iter().any(|p| &p.name == figure_scene) {
            let names: Vec<&str> = plans.iter().map(|p| p.name.as_str()).collect();
            return Err(EvalError::Failed(format!(
                "figure scene '{figure_scene}' is not one of the run's scenes ({})",
                names.join(", ")
            )));
        }
    }
    Ok((runner, plans, global_probe))
}

/// Every scene's results (computing, loading or waiting for each unit), in spec order.
fn assemble(
    mut runner: Runner<'_>,
    plans: &[ScenePlan],
    global_probe: u64,
    start: Instant,
) -> Result<EvalOutcome, EvalError> {
    let mut scenes = Vec::new();
    let mut artifacts = Artifacts::default();
    for plan in plans {
        scenes.push(runner.run_scene(plan, &mut artifacts)?);
    }
    let code_version = format!("{CACHE_FORMAT}/{}/{global_probe:016x}", env!("CARGO_PKG_VERSION"));
    Ok(EvalOutcome {
        results: EvalResults { spec: runner.spec.clone(), code_version, scenes },
        artifacts,
        counters: runner.counters,
        warnings: runner.warnings,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// Runs the evaluation `spec` with `cache`: every unit, then every result.
pub fn evaluate(
    spec: &EvalSpec,
    cache: &Cache,
    reporter: &dyn Reporter,
    limits: Limits,
) -> Result<EvalOutcome, EvalError> {
    let start = Instant::now();
    let (runner, plans, global_probe) = prepare(spec, cache, reporter, limits)?;
    reporter.begin(plans.iter().map(|p| runner.pending_work(p)).sum());
    assemble(runner, &plans, global_probe, start)
}

/// Builds every result of `spec` from the cache alone (after the shards of `eval --shard`);
/// fails with [`EvalError::Missing`] naming every entry that is not there.
pub fn merge(spec: &EvalSpec, cache: &Cache, reporter: &dyn Reporter) -> Result<EvalOutcome, EvalError> {
    let start = Instant::now();
    let (mut runner, plans, global_probe) = prepare(spec, cache, reporter, Limits::default())?;
    runner.merge_only = true;
    let units = runner.units(&plans, None);
    let missing: Vec<String> = units
        .iter()
        .filter(|u| u.entry.as_ref().is_some_and(|e| !cache.root().join(e).is_file()))
        .map(|u| format!("{u} ({})", u.entry.as_deref().unwrap_or("")))
        .collect();
    if !missing.is_empty() {
        return Err(EvalError::Missing(missing));
    }
    assemble(runner, &plans, global_probe, start)
}

/// What one shard did.
#[derive(Clone, Debug)]
pub struct ShardOutcome {
    /// The shard that ran.
    pub shard: Shard,
    /// Units dealt to this shard, and how many units the whole run has.
    pub units: usize,
    /// Units of the whole run.
    pub total_units: usize,
    /// Everything computed (its own units, and dependencies nobody else had claimed).
    pub counters: WorkCounters,
    /// Non-fatal problems, in the order they were reported.
    pub warnings: Vec<String>,
    /// Wall time of the shard, in seconds.
    pub seconds: f64,
}

/// Computes shard `shard`'s units of `spec` into `cache` (see [`super::units`]).
pub fn run_shard(
    spec: &EvalSpec,
    cache: &Cache,
    reporter: &dyn Reporter,
    shard: Shard,
    limits: Limits,
) -> Result<ShardOutcome, EvalError> {
    let start = Instant::now();
    let (mut runner, plans, _) = prepare(spec, cache, reporter, limits)?;
    let units = runner.units(&plans, None);
    let mine = assign(&units, shard.count).swap_remove(shard.index);
    let pending: u64 = mine
        .iter()
        .filter(|&&i| units[i].entry.as_ref().is_none_or(|e| !cache.root().join(e).is_file()))
        .map(|&i| units[i].samples)
        .sum();
    reporter.begin(pending);
    let mut inputs = None;
    for &i in &mine {
        runner.run_unit(&plans[units[i].scene], &units[i], &mut inputs)?;
    }
    Ok(ShardOutcome {
        shard,
        units: mine.len(),
        total_units: units.len(),
        counters: runner.counters,
        warnings: runner.warnings,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// The units of `spec` and their estimated CPU time, from each scene's path-tracing rate
/// measured on a small render of its first frame.
pub fn plan(spec: &EvalSpec, cache: &Cache, reporter: &dyn Reporter) -> Result<Plan, EvalError> {
    let (runner, plans, _) = prepare(spec, cache, reporter, Limits::default())?;
    let mut rates = Vec::new();
    for p in &plans {
        reporter.status(&format!("{}: measuring its path-tracing rate", p.name));
        rates.push(seconds_per_sample(&p.renderer, &runner.rig, runner.extent)?);
    }
    let units = runner.units(&plans, Some(&rates));
    Ok(Plan { units, seconds_per_sample: plans.iter().map(|p| p.name.clone()).zip(rates).collect() })
}

/// A scene's measuring stick under a spec: the renderer, and the reference and error curve
/// of every evaluated frame (left eye), from the cache where they exist.
pub struct SceneBasis {
    /// The scene's renderer (scene and BVH built).
    pub renderer: Renderer,
    /// Left-eye reference of each evaluated frame.
    pub references: BTreeMap<u32, RgbBuf>,
    /// Error curve of each evaluated frame.
    pub curves: BTreeMap<u32, FrameCurve>,
    /// What was computed rather than loaded.
    pub counters: WorkCounters,
    /// Non-fatal problems, in the order they were reported.
    pub warnings: Vec<String>,
}

/// Builds (or loads) the references and error curves of `scene` exactly as [`evaluate`]
/// does, so other measurements (the trade-off sweep) share the harness's cache entries and
/// its definition of the effective spp. Figure 3's extra curve points are left out.
pub fn scene_basis(
    spec: &EvalSpec,
    scene: &str,
    cache: &Cache,
    reporter: &dyn Reporter,
) -> Result<SceneBasis, EvalError> {
    let mut spec = spec.clone();
    spec.scenes = vec![scene.to_owned()];
    spec.figures.framewise_scene = None;
    spec.validate()?;
    let mut runner = Runner {
        spec: &spec,
        cache,
        reporter,
        limits: Limits::default(),
        extent: spec.extent()?,
        rig: StereoRig::new(spec.eye_separation)?,
        counters: WorkCounters::default(),
        warnings: Vec::new(),
        merge_only: false,
    };
    let global_probe = code_probe()?;
    let plan = runner.plan_scene(scene, global_probe)?;
    reporter.begin(runner.pending_work(&plan));
    let mut references = BTreeMap::new();
    for (f, _, key, _) in &plan.frames {
        references.insert(*f, runner.reference(&plan, *f, key)?);
    }
    let mut curves = BTreeMap::new();
    for (f, max_spp, _, key) in &plan.frames {
        curves.insert(*f, runner.curve(&plan, *f, *max_spp, key, &references[f])?);
    }
    let (counters, warnings) = (runner.counters, runner.warnings);
    Ok(SceneBasis { renderer: plan.renderer, references, curves, counters, warnings })
}
