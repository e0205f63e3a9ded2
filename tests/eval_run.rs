//! The evaluation run: resuming after an interruption (between and inside units), corrupt
//! cache entries, and the reduced quick preset's tables and figures.

mod common;

use std::path::{Path, PathBuf};

use stereotrace::eval::cache::Cache;
use stereotrace::eval::results::EvalOutcome;
use stereotrace::eval::run::{EvalError, Limits, Quiet};
use stereotrace::eval::{EvalSpec, Grid, Preset, Variant, evaluate, plots, report};
use stereotrace::pipeline::{Mode, Order};
use stereotrace::scene::builtin_names;

fn temp(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("stereotrace-eval-{tag}-{}", std::process::id()));
    std::fs::remove_dir_all(&d).ok();
    d
}

/// A run small enough for a test: 32×18, frames 0..4 (2 evaluated), 16-spp references,
/// curves to 8 spp.
fn tiny(scenes: &[&str], variants: &[Variant], spp: &[u32]) -> EvalSpec {
    let mut spec = Preset::Quick.spec();
    spec.scenes = scenes.iter().map(|s| s.to_string()).collect();
    spec.variants = variants.to_vec();
    spec.input_spp = spp.to_vec();
    (spec.width, spec.height) = (32, 18);
    (spec.frames, spec.warmup) = (4, 2);
    (spec.reference_spp, spec.curve_spp, spec.checkpoint_spp) = (16, 8, 4);
    spec.figures.framewise_scene = Some(scenes[0].to_string());
    spec.figures.discard_scene = Some(scenes[0].to_string());
    spec.figures.comparison_scenes = vec![scenes[0].to_string()];
    spec
}

fn run(spec: &EvalSpec, cache: &Path, limits: Limits) -> Result<EvalOutcome, EvalError> {
    evaluate(spec, &Cache::open(cache).unwrap(), &Quiet, limits)
}

const VARIANTS: [Variant; 3] = [
    Variant { mode: Mode::Stereo, order: Order::Paper },
    Variant { mode: Mode::Temporal, order: Order::Paper },
    Variant { mode: Mode::Spatiotemporal, order: Order::Paper },
];

#[test]
fn the_gbuffer_pass_is_part_of_a_configurations_cache_key() {
    // The G-buffer pass is the renderer's option, not a pipeline setting: a run with traced
    // G-buffers must not load the rasterised run's results from a shared cache.
    let mut spec = tiny(&["cornell"], &VARIANTS[..1], &[1]);
    spec.figures.framewise_scene = None;
    spec.figures.discard_scene = None;
    spec.figures.comparison_scenes.clear();
    let cache = temp("gbuffer-key");
    let raster = run(&spec, &cache, Limits::default()).unwrap();
    assert_eq!(raster.counters.configs, 1, "{:?}", raster.counters);
    spec.gbuffer = stereotrace::render::GBufferPass::Traced;
    let traced = run(&spec, &cache, Limits::default()).unwrap();
    assert_eq!(traced.counters.configs, 1, "traced G-buffers loaded the raster run's result");
    assert_eq!((traced.counters.references, traced.counters.curves), (0, 0), "{:?}", traced.counters);
    spec.gbuffer = stereotrace::render::GBufferPass::Raster;
    assert_eq!(run(&spec, &cache, Limits::default()).unwrap().counters.configs, 0, "the raster entry is kept");
    std::fs::remove_dir_all(&cache).ok();
}

#[test]
fn an_interrupted_run_resumes_without_redoing_finished_work() {
    let spec = tiny(&["cornell"], &VARIANTS, &[1, 2]);
    // Units: 2 references, 2 curves (evaluated frames) + 2 more of each for the warm-up
    // frames of Figure 3's scene, and 3 × 2 configurations. The only cache reads are the
    // figure stage's: the 2 discard maps and 2 outputs the configurations stored.
    let fresh = run(&spec, &temp("fresh"), Limits::default()).unwrap();
    let c = fresh.counters;
    assert_eq!((c.references, c.curves, c.configs, c.cache_hits), (4, 4, 6, 4), "{c:?}");
    let total = c.computed_units();

    let cache = temp("resume");
    let Err(EvalError::Interrupted { computed, .. }) =
        run(&spec, &cache, Limits { max_computed_units: Some(5), ..Limits::default() })
    else {
        panic!("the limit did not stop the run")
    };
    assert_eq!(computed, 5);
    let resumed = run(&spec, &cache, Limits::default()).unwrap();
    assert_eq!(resumed.counters.computed_units(), total - 5, "{:?}", resumed.counters);
    assert_eq!(resumed.results, fresh.results);
    // Everything is cached now: a third run computes nothing.
    let again = run(&spec, &cache, Limits::default()).unwrap();
    assert_eq!(again.counters.computed_units() + again.counters.figure_images + again.counters.corrupt_entries, 0);
    assert_eq!(again.counters.samples, 0);
    assert_eq!(again.results, resumed.results, "cached results are returned as stored");
}

#[test]
fn a_run_killed_inside_a_reference_resumes_from_its_checkpoint() {
    let spec = tiny(&["atrium"], &VARIANTS[..1], &[1]);
    let fresh = run(&spec, &temp("ck-fresh"), Limits::default()).unwrap();
    let cache = temp("ck");
    // 10 passes of 32×18 pixels: inside the first reference (16 spp), after its 4- and 8-spp
    // checkpoints.
    let pixels = 32 * 18;
    let Err(EvalError::Interrupted { computed, counters }) =
        run(&spec, &cache, Limits { max_samples: Some(10 * pixels), ..Limits::default() })
    else {
        panic!("the sample limit did not stop the run")
    };
    assert_eq!((computed, counters.samples), (0, 10 * pixels), "{counters:?}");
    let resumed = run(&spec, &cache, Limits::default()).unwrap();
    assert_eq!(resumed.counters.samples + 10 * pixels, fresh.counters.samples, "no sample traced twice");
    assert_eq!(resumed.results, fresh.results, "resumed references are bit-identical");
    let partials = walk(&cache).into_iter().filter(|p| p.to_string_lossy().contains("partial")).count();
    assert_eq!(partials, 0, "finished units remove their checkpoints");
}

fn walk(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(dir).unwrap().flatten() {
        let p = e.path();
        if p.is_dir() { out.extend(walk(&p)) } else { out.push(p) }
    }
    out
}

#[test]
fn corrupt_cache_entries_are_detected_and_recomputed() {
    let spec = tiny(&["cornell"], &VARIANTS[..1], &[1]);
    let cache = temp("corrupt");
    let first = run(&spec, &cache, Limits::default()).unwrap();
    let files = walk(&cache);
    assert!(files.iter().all(|f| !f.to_string_lossy().contains(".tmp-")), "no temporary files are left");
    let curve = files.iter().find(|f| f.to_string_lossy().contains("/curve/")).unwrap();
    let mut bytes = std::fs::read(curve).unwrap();
    let n = bytes.len();
    bytes[n - 3] ^= 0x01;
    std::fs::write(curve, &bytes).unwrap();
    let second = run(&spec, &cache, Limits::default()).unwrap();
    let c = second.counters;
    assert_eq!((c.corrupt_entries, c.curves, c.references, c.configs), (1, 1, 0, 0), "{c:?}");
    assert!(second.warnings.iter().any(|w| w.contains("checksum mismatch")), "{:?}", second.warnings);
    assert_eq!(second.results, first.results);
}

#[test]
fn the_reduced_quick_preset_reports_every_mode_and_builtin() {
    // The quick preset with its scenes, modes and figures, shrunk to 32×18, 1 spp and one
    // evaluated frame (CI runs the real one).
    let quick = Preset::Quick.spec();
    let scenes: Vec<&str> = quick.scenes.iter().map(String::as_str).collect();
    assert_eq!(scenes, builtin_names());
    assert_eq!(quick.variants, Variant::ALL.to_vec());
    let mut spec = tiny(&scenes, &Variant::ALL, &[1]);
    (spec.frames, spec.warmup, spec.reference_spp, spec.curve_spp) = (3, 2, 8, 4);
    spec.figures = quick.figures.clone();
    spec.grid = Grid::Dense;
    let out = temp("quick");
    let outcome = run(&spec, &out.join("cache"), Limits::default()).unwrap();
    let written = report::write_reports(&outcome, &out).unwrap();
    let (figures, failed) = plots::write_figures(&outcome.results, &outcome.artifacts, &out);
    assert!(failed.is_empty(), "{failed:?}");
    let tables = std::fs::read_to_string(out.join("tables.md")).unwrap();
    for v in Variant::ALL {
        assert!(tables.contains(&format!("({}) — effective spp", v.name())), "no table for {v}");
        let csv =
            std::fs::read_to_string(out.join(format!("{}_{}_ssim.csv", v.table_id(), v.name().replace('-', "_"))))
                .unwrap();
        for s in builtin_names() {
            assert!(csv.lines().any(|l| l.starts_with(&format!("{s},"))), "{v}: no row for {s}");
        }
        assert!(csv.lines().any(|l| l.starts_with("Scene Average")));
    }
    for s in builtin_names() {
        let rows = tables.lines().filter(|l| l.starts_with(&format!("| {s} "))).count();
        // One row per effective-spp table (7 variants × 2 metrics) and two in Table 4.
        assert_eq!(rows, 2 * Variant::ALL.len() + 2, "{s}: {rows} rows");
    }
    assert!(tables.contains("Sponza (All scenes)") && tables.contains("| **San Miguel** |"));
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("results.json")).unwrap()).unwrap();
    assert_eq!(json["results"]["scenes"].as_array().unwrap().len(), builtin_names().len());
    for name in [
        "fig3_framewise_ssim.png",
        "fig3_framewise_ssim.svg",
        "fig4_effective_stereo_ssim.svg",
        "fig5_effective_spatiotemporal_ssim.png",
        "fig8_effective_spatiotemporal_blend_ssim.png",
        "fig6_discards_atrium_stereo.png",
        "fig6_discards_atrium_temporal.png",
        "fig7_comparison.png",
    ] {
        assert!(figures.contains(&out.join(name)), "{name} missing: {figures:?}");
        assert!(std::fs::metadata(out.join(name)).unwrap().len() > 1000, "{name} is empty");
    }
    assert!(written.len() >= 2 * 7 + 4);
    assert_eq!(outcome.artifacts.comparisons.len(), 4, "one Figure 7 row per comparison scene");
}

#[test]
fn the_embedded_paper_tables_are_the_shared_ones() {
    let shared = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/paper_tables");
    if !shared.is_dir() {
        common::skip(&format!("{} absent", shared.display()));
        return;
    }
    for (name, text) in stereotrace::eval::paper::embedded_csv() {
        assert_eq!(std::fs::read_to_string(shared.join(name)).unwrap(), text, "{name}");
    }
}

/// Issue 13: a resumed run's warnings lost those of the work it loaded from the cache (the
/// error curves' rises were reported only when a curve was computed).
#[test]
fn a_resumed_run_reports_the_warnings_of_the_work_it_loads() {
    let spec = tiny(&["atrium"], &VARIANTS[..1], &[1]);
    let cache = temp("warn-resume");
    let fresh = run(&spec, &cache, Limits::default()).unwrap();
    let rises = |o: &EvalOutcome| -> Vec<String> {
        o.warnings.iter().filter(|w| w.contains("error curve rises")).cloned().collect()
    };
    assert!(!rises(&fresh).is_empty(), "the spec must give a rising curve for this test: {:?}", fresh.warnings);
    let cached = run(&spec, &cache, Limits::default()).unwrap();
    assert_eq!(cached.counters.computed_units(), 0);
    assert_eq!(rises(&cached), rises(&fresh));
}
