//! The evaluation's work units, their estimated cost, and how a run is cut into shards.
//!
//! A run is made of independent, cached units (see [`super::run`]): per scene, the
//! reference of every frame that needs one, the error curve of each of those frames (needs
//! its reference), every (mode, order, input spp) configuration (needs every reference and
//! curve of its scene), and, for the scenes of Figure 7, the figure images (need the
//! configurations). `eval --plan` lists them with their cost; `eval --shard K/N` computes
//! shard `K`'s share into a shared cache; `eval --merge` builds every table, figure and
//! `results.json` from the cache alone.
//!
//! # Shards
//! Units are dealt to `N` shards by cost, largest first, each to the shard with the least
//! work so far (ties to the lower shard): deterministic, so every task of an array computes
//! the same assignment without talking to the others. A shard runs its units phase by phase
//! (references, curves, configurations, figures), so dependencies computed by other shards
//! are usually ready when needed. When one is not, the shard computes it itself if nobody
//! has claimed it, or waits for the claim's holder ([`super::claim`]), and says which.

use serde::Serialize;

use std::time::Instant;

use super::curve::MEASURED_EYE;
use super::probes::PROBE_SEED;
use super::spec::Variant;
use crate::camera::StereoRig;
use crate::kernels::Extent;
use crate::render::{FrameView, Renderer};

/// What a unit computes.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum UnitKind {
    /// The left-eye reference of one frame.
    Reference {
        /// Frame index, from 0.
        frame: u32,
    },
    /// The error curve of one frame (needs its reference).
    Curve {
        /// Frame index, from 0.
        frame: u32,
    },
    /// One configuration over all frames (needs every reference and curve of its scene).
    Config {
        /// The pipeline mode and order.
        variant: Variant,
        /// Input samples per pixel.
        spp: u32,
    },
    /// Figure 7's path-traced images of one scene.
    Figures,
}

impl UnitKind {
    /// The phase a shard runs it in (its dependencies are in earlier phases).
    pub fn phase(&self) -> u8 {
        match self {
            UnitKind::Reference { .. } => 0,
            UnitKind::Curve { .. } => 1,
            UnitKind::Config { .. } => 2,
            UnitKind::Figures => 3,
        }
    }

    /// The kind's name in plans (`reference`, `curve`, `config`, `figures`).
    pub fn label(&self) -> &'static str {
        match self {
            UnitKind::Reference { .. } => "reference",
            UnitKind::Curve { .. } => "curve",
            UnitKind::Config { .. } => "config",
            UnitKind::Figures => "figures",
        }
    }
}

/// One unit of a run.
#[derive(Clone, Debug, Serialize)]
pub struct Unit {
    /// Index of its scene in the spec.
    pub scene: usize,
    /// Its scene's own name (a manifest's `name`, a folder's name).
    pub scene_name: String,
    /// What it computes.
    #[serde(flatten)]
    pub kind: UnitKind,
    /// Path-traced pixel samples it computes (the cost model's unit).
    pub samples: u64,
    /// Estimated CPU seconds (samples at the scene's measured rate).
    pub cpu_seconds: f64,
    /// How many units it needs first.
    pub dependencies: usize,
    /// Its cache entry's file, relative to the cache root (none for figures: their keys
    /// depend on the configurations' results).
    pub entry: Option<String>,
}

impl std::fmt::Display for Unit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match &self.kind {
            UnitKind::Reference { frame } => write!(f, "reference of {} frame {frame}", self.scene_name),
            UnitKind::Curve { frame } => write!(f, "error curve of {} frame {frame}", self.scene_name),
            UnitKind::Config { variant, spp } => write!(f, "{} {variant} at {spp} spp", self.scene_name),
            UnitKind::Figures => write!(f, "figure images of {}", self.scene_name),
        }
    }
}

/// Shard `index` of `count` (0-based).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    /// This shard's index, below `count`.
    pub index: usize,
    /// Number of shards, at most [`MAX_SHARDS`].
    pub count: usize,
}

/// The largest shard count accepted (a sanity bound, far above any useful array).
pub const MAX_SHARDS: usize = 100_000;

impl Shard {
    /// Parses `K/N` (0 ≤ K < N), or `env`: Slurm's `SLURM_ARRAY_TASK_ID` (minus
    /// `SLURM_ARRAY_TASK_MIN`, default 0) of `SLURM_ARRAY_TASK_COUNT`, or Kubernetes'
    /// `JOB_COMPLETION_INDEX` of `STEREOTRACE_SHARDS` (an Indexed Job does not export its
    /// completion count; the manifest sets it).
    pub fn parse(text: &str) -> Result<Self, String> {
        if text == "env" {
            return Self::from_env(&|name| std::env::var(name).ok());
        }
        let (k, n) = text.split_once('/').ok_or_else(|| format!("shard '{text}' is not K/N (e.g. 0/4) or 'env'"))?;
        let num = |s: &str, what: &str| {
            s.trim().parse::<usize>().map_err(|_| format!("shard '{text}': {what} '{s}' is not a whole number"))
        };
        Self::new(num(k, "index")?, num(n, "count")?)
    }

    /// Shard `index` of `count`; refuses a count of 0 or above [`MAX_SHARDS`], and an
    /// index not below the count.
    pub fn new(index: usize, count: usize) -> Result<Self, String> {
        if count == 0 || count > MAX_SHARDS {
            return Err(format!("shard count {count} must be in 1..={MAX_SHARDS}"));
        }
        if index >= count {
            return Err(format!("shard index {index} must be below the count {count} (indices start at 0)"));
        }
        Ok(Self { index, count })
    }

    /// The shard a batch scheduler's environment names (see [`Shard::parse`]).
    pub fn from_env(var: &dyn Fn(&str) -> Option<String>) -> Result<Self, String> {
        let num = |name: &str| -> Result<Option<usize>, String> {
            var(name)
                .map(|v| v.trim().parse::<usize>().map_err(|_| format!("{name}='{v}' is not a whole number")))
                .transpose()
        };
        if let Some(id) = num("SLURM_ARRAY_TASK_ID")? {
            let count = num("SLURM_ARRAY_TASK_COUNT")?
                .ok_or("SLURM_ARRAY_TASK_ID is set but SLURM_ARRAY_TASK_COUNT is not (not an array job?)")?;
            let min = num("SLURM_ARRAY_TASK_MIN")?.unwrap_or(0);
            let index =
                id.checked_sub(min).ok_or_else(|| format!("SLURM_ARRAY_TASK_ID {id} is below its minimum {min}"))?;
            return Self::new(index, count);
        }
        if let Some(index) = num("JOB_COMPLETION_INDEX")? {
            let count = num("STEREOTRACE_SHARDS")?
                .ok_or("JOB_COMPLETION_INDEX is set but STEREOTRACE_SHARDS (the Job's completions) is not")?;
            return Self::new(index, count);
        }
        Err("--shard env: neither SLURM_ARRAY_TASK_ID (a Slurm array task) nor JOB_COMPLETION_INDEX (a \
             Kubernetes Indexed Job) is set"
            .into())
    }
}

impl std::fmt::Display for Shard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

/// Deals units to `count` shards by cost (see the module notes); returns each shard's unit
/// indices in the order it runs them (phase, then plan order).
pub fn assign(units: &[Unit], count: usize) -> Vec<Vec<usize>> {
    let mut order: Vec<usize> = (0..units.len()).collect();
    // Largest first; equal costs keep plan order (a stable sort), so the deal is deterministic.
    order.sort_by(|&a, &b| units[b].samples.cmp(&units[a].samples));
    let mut load = vec![0u64; count];
    let mut shards = vec![Vec::new(); count];
    for i in order {
        let k = (0..count).min_by_key(|&k| (load[k], k)).expect("count >= 1");
        load[k] += units[i].samples.max(1);
        shards[k].push(i);
    }
    for s in &mut shards {
        s.sort_by_key(|&i| (units[i].kind.phase(), i));
    }
    shards
}

/// A run's units and what they cost.
#[derive(Clone, Debug, Serialize)]
pub struct Plan {
    /// Every unit, in plan order (scene by scene: references, curves, configurations,
    /// figures).
    pub units: Vec<Unit>,
    /// Measured CPU seconds per path-traced pixel sample, per scene.
    pub seconds_per_sample: Vec<(String, f64)>,
}

impl Plan {
    /// Estimated CPU seconds of all units together.
    pub fn cpu_seconds(&self) -> f64 {
        self.units.iter().map(|u| u.cpu_seconds).sum()
    }

    /// The estimated wall time with `shards` shards of `cpus` cores each: the most loaded
    /// shard's CPU time over its cores (dependencies' waits not counted).
    pub fn wall_seconds(&self, shards: usize, cpus: usize) -> f64 {
        assign(&self.units, shards)
            .iter()
            .map(|s| s.iter().map(|&i| self.units[i].cpu_seconds).sum::<f64>())
            .fold(0.0, f64::max)
            / cpus.max(1) as f64
    }

    /// The plan as text: units per kind, the total, and wall times for a few array sizes.
    pub fn summary(&self, cpus_per_task: usize) -> String {
        let mut out = String::new();
        let kinds = ["reference", "curve", "config", "figures"];
        out.push_str("| units | count | G pixel samples | CPU hours |\n|---|--:|--:|--:|\n");
        for kind in kinds {
            let of: Vec<&Unit> = self.units.iter().filter(|u| u.kind.label() == kind).collect();
            let samples: u64 = of.iter().map(|u| u.samples).sum();
            let hours: f64 = of.iter().map(|u| u.cpu_seconds).sum::<f64>() / 3600.0;
            out.push_str(&format!("| {kind} | {} | {:.2} | {hours:.2} |\n", of.len(), samples as f64 / 1e9));
        }
        let samples: u64 = self.units.iter().map(|u| u.samples).sum();
        out.push_str(&format!(
            "| **all** | {} | {:.2} | {:.2} |\n\nEstimated wall time with {cpus_per_task} CPUs per task:",
            self.units.len(),
            samples as f64 / 1e9,
            self.cpu_seconds() / 3600.0
        ));
        for n in [1, 4, 16, 64, 256] {
            if n > 1 && n > self.units.len() {
                break;
            }
            out.push_str(&format!(" {n} tasks {};", hours_text(self.wall_seconds(n, cpus_per_task))));
        }
        out.pop();
        out.push_str(
            "\n(the slowest shard's share; a unit never splits, so past one unit per task more tasks do not help)\n",
        );
        out
    }
}

/// `1.5 h`, `12 min` or `40 s`.
pub fn hours_text(seconds: f64) -> String {
    if seconds >= 3600.0 {
        format!("{:.1} h", seconds / 3600.0)
    } else if seconds >= 60.0 {
        format!("{:.0} min", seconds / 60.0)
    } else {
        format!("{seconds:.0} s")
    }
}

/// Estimated path-tracing work of a configuration over `frames` frames.
pub(crate) fn config_work(pixels: u64, frames: u32, variant: Variant, spp: u32) -> u64 {
    pixels * u64::from(frames) * u64::from(spp) * variant.traced_eyes_x10() / 10
}

/// CPU seconds per left-eye pixel sample of frame 0 (wall time × threads of a render at
/// most 160×90, after one warm-up render).
pub(crate) fn seconds_per_sample(renderer: &Renderer, rig: &StereoRig, extent: Extent) -> Result<f64, String> {
    let scale = (160.0 / extent.width() as f64).min(90.0 / extent.height() as f64).min(1.0);
    let small = Extent::new(
        ((extent.width() as f64 * scale).round() as usize).max(1),
        ((extent.height() as f64 * scale).round() as usize).max(1),
    )
    .map_err(|e| e.to_string())?;
    let view = FrameView::new(renderer, rig, small, 0).map_err(|e| e.to_string())?;
    view.render(renderer, &view.request(MEASURED_EYE, 1, PROBE_SEED, 0), false).map_err(|e| e.to_string())?;
    let spp = 4;
    let t = Instant::now();
    view.render(renderer, &view.request(MEASURED_EYE, spp, PROBE_SEED, 0), false).map_err(|e| e.to_string())?;
    let cpu = t.elapsed().as_secs_f64() * rayon::current_num_threads() as f64;
    Ok(cpu / (small.pixels() as f64 * f64::from(spp)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit(samples: u64, kind: UnitKind) -> Unit {
        Unit {
            scene: 0,
            scene_name: "s".into(),
            kind,
            samples,
            cpu_seconds: samples as f64,
            dependencies: 0,
            entry: None,
        }
    }

    #[test]
    fn shards_parse_from_text_and_the_schedulers_environment() {
        assert_eq!(Shard::parse("2/7").unwrap(), Shard { index: 2, count: 7 });
        for bad in ["7/7", "1/0", "a/2", "3", "-1/2", "1/2/3"] {
            assert!(Shard::parse(bad).is_err(), "{bad}");
        }
        let env = |pairs: &'static [(&'static str, &'static str)]| {
            move |name: &str| pairs.iter().find(|(k, _)| *k == name).map(|(_, v)| (*v).to_owned())
        };
        let slurm =
            env(&[("SLURM_ARRAY_TASK_ID", "5"), ("SLURM_ARRAY_TASK_MIN", "1"), ("SLURM_ARRAY_TASK_COUNT", "8")]);
        assert_eq!(Shard::from_env(&slurm).unwrap(), Shard { index: 4, count: 8 });
        let k8s = env(&[("JOB_COMPLETION_INDEX", "3"), ("STEREOTRACE_SHARDS", "4")]);
        assert_eq!(Shard::from_env(&k8s).unwrap(), Shard { index: 3, count: 4 });
        let half = env(&[("JOB_COMPLETION_INDEX", "3")]);
        assert!(Shard::from_env(&half).unwrap_err().contains("STEREOTRACE_SHARDS"));
        assert!(Shard::from_env(&env(&[])).unwrap_err().contains("SLURM_ARRAY_TASK_ID"));
    }

    #[test]
    fn the_deal_covers_every_unit_once_balances_cost_and_runs_by_phase() {
        let mut units = Vec::new();
        for f in 0..10 {
            units.push(unit(100, UnitKind::Reference { frame: f }));
            units.push(unit(50, UnitKind::Curve { frame: f }));
        }
        units.push(unit(400, UnitKind::Figures));
        for n in [1, 3, 7, 40] {
            let shards = assign(&units, n);
            let mut all: Vec<usize> = shards.concat();
            all.sort_unstable();
            assert_eq!(all, (0..units.len()).collect::<Vec<_>>(), "{n} shards");
            for s in &shards {
                assert!(s.windows(2).all(|w| (units[w[0]].kind.phase(), w[0]) < (units[w[1]].kind.phase(), w[1])));
            }
            assert_eq!(assign(&units, n), shards, "deterministic");
        }
        // 1900 samples over 3 shards: the greedy deal stays within one unit of even.
        let loads: Vec<u64> = assign(&units, 3).iter().map(|s| s.iter().map(|&i| units[i].samples).sum()).collect();
        assert!(loads.iter().max().unwrap() - loads.iter().min().unwrap() <= 100, "{loads:?}");
    }
}
