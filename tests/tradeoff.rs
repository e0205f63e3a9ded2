//! The trade-off sweep measures what the evaluation harness measures: for every mode at the
//! paper's settings its effective spp equals the harness's, bit for bit (same pipeline
//! images, same references and curves from the shared cache). Also: every setting is
//! measured, budgets are derived from the unbudgeted run, the Pareto front is consistent and
//! the files are written.

use std::path::PathBuf;

use stereotrace::commands::tradeoff::{TradeoffOptions, sweep};
use stereotrace::eval::cache::Cache;
use stereotrace::eval::run::{Limits, Quiet};
use stereotrace::eval::{Variant, evaluate};

fn temp(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("stereotrace-tradeoff-{tag}-{}", std::process::id()));
    std::fs::remove_dir_all(&d).ok();
    d
}

#[test]
fn the_sweep_measures_the_harness_images_and_marks_a_consistent_front() {
    let dir = temp("harness");
    let (cache, out) = (dir.join("cache"), dir.join("out"));
    let flags = [
        "--res=32x18",
        "--frames=4",
        "--warmup=2",
        "--spp=1",
        "--reference-spp=16",
        "--curve-spp=8",
        "--budgets=0.5",
        "--budgets-ms=50",
    ];
    let mut opts = TradeoffOptions::new("cornell", &flags).unwrap();
    (opts.references.cache, opts.out) = (cache, out);
    let report = sweep(&opts, &Quiet).unwrap();

    let mut spec = opts.eval_spec();
    spec.variants = Variant::ALL.to_vec();
    spec.figures.framewise_scene = None;
    spec.figures.discard_scene = None;
    spec.figures.comparison_scenes.clear();
    let outcome = evaluate(&spec, &Cache::open(&opts.references.cache).unwrap(), &Quiet, Limits::default()).unwrap();
    assert_eq!(outcome.counters.references + outcome.counters.curves, 0, "the sweep left the basis in the cache");
    let scene = &outcome.results.scenes[0];
    for v in Variant::ALL {
        let row = report.rows.iter().find(|r| r.mode == v.name() && r.change == "paper").unwrap();
        let config = scene.config(v, 1).unwrap();
        assert_eq!(row.effective_ssim, config.ssim, "{v}");
        assert_eq!(row.effective_rmse, config.rmse, "{v}");
    }

    // 1 path-traced + 7 modes + strict, ramp, full layout, traced G-buffer, centre first
    // sample, gradient history, clamp history, variance blend, à-trous filter, reprojected
    // background + 2 budgets.
    assert_eq!(report.rows.len(), 20);
    let unbudgeted = report.rows.iter().find(|r| r.mode == "spatiotemporal" && r.change == "paper").unwrap();
    let budgeted = report.rows.iter().find(|r| r.change == "budget 50%").unwrap();
    assert_eq!(budgeted.budget_ms, Some(0.5 * unbudgeted.frame.median_ms));
    let in_ms = report.rows.iter().find(|r| r.change == "budget 50 ms").unwrap();
    assert_eq!(in_ms.budget_ms, Some(50.0));
    // The traced G-buffer (the reference pass) gives the raster pass's quality.
    // Nothing moves in the Cornell box: the gradient history traces no gradient samples and
    // gives the paper's images, so the same quality.
    let gradient = report.rows.iter().find(|r| r.change == "gradient history").unwrap();
    assert_eq!(gradient.effective_ssim, unbudgeted.effective_ssim);
    // The Cornell box fills its view: no sky to keep, so the paper's images.
    let sky = report.rows.iter().find(|r| r.change == "reproject background").unwrap();
    assert_eq!(sky.mean_ssim, unbudgeted.mean_ssim);
    // The clamp moves histories toward single-path noise: its own images and quality.
    let clamp = report.rows.iter().find(|r| r.change == "clamp history").unwrap();
    assert_ne!(clamp.mean_ssim, unbudgeted.mean_ssim);
    // The filter is measured as a point of its own, with its own images.
    let filtered = report.rows.iter().find(|r| r.change == "atrous filter").unwrap();
    assert_ne!(filtered.mean_ssim, unbudgeted.mean_ssim);
    // The first sample at the pixel centre is another estimator: its own images.
    let centred = report.rows.iter().find(|r| r.change == "centre first sample").unwrap();
    assert_ne!(centred.mean_ssim, unbudgeted.mean_ssim);
    let traced = report.rows.iter().find(|r| r.change == "traced G-buffer").unwrap();
    let (a, b) = (traced.effective_ssim.mean.unwrap(), unbudgeted.effective_ssim.mean.unwrap());
    assert!((a - b).abs() <= 0.01 * b, "effective spp with a traced G-buffer {a}, rasterised {b}");
    for r in &report.rows {
        assert!(r.frame.median_ms > 0.0 && r.frame.p95_ms >= r.frame.median_ms, "{} {}", r.mode, r.change);
        assert!(r.effective_ssim.count == 2 && r.mean_ssim > 0.0 && r.mean_ssim <= 1.0);
    }
    let point = |r: &stereotrace::commands::tradeoff::TradeoffRow| (r.frame.median_ms, r.effective_ssim.mean);
    let front: Vec<_> = report.rows.iter().filter(|r| r.pareto).collect();
    assert!(!front.is_empty());
    for f in &front {
        let (t, q) = point(f);
        let q = q.unwrap();
        assert!(!report.rows.iter().any(|r| {
            let (tr, qr) = point(r);
            qr.is_some_and(|qr| tr <= t && qr >= q && (tr < t || qr > q))
        }));
    }
    // The fastest measured setting is always on the front.
    let fastest = report
        .rows
        .iter()
        .filter(|r| r.effective_ssim.mean.is_some())
        .min_by(|a, b| a.frame.median_ms.total_cmp(&b.frame.median_ms));
    assert!(fastest.unwrap().pareto);

    let written = report.write(&opts.out).unwrap();
    assert_eq!(written.len(), 5);
    for w in &written {
        assert!(std::fs::metadata(w).unwrap().len() > 0, "{}", w.display());
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn bad_options_are_refused_with_a_message() {
    // Values are refused where they are parsed, naming the value and the rule.
    let refused = |flags: &[&str]| TradeoffOptions::new("cornell", flags).unwrap_err();
    assert!(refused(&["--budgets=1.5"]).contains("budget fraction 1.5 is not in (0, 1]"));
    assert!(refused(&["--spp=0"]).contains("samples per pixel 0 must be in 1..="));
    assert!(refused(&["--budgets-ms=0"]).contains("budget 0 ms must be finite, > 0"));
    assert!(refused(&["--threads=0"]).contains("--threads"));
    assert!(refused(&["--frames=0"]).contains("frame count 0"));
    // And what only the sweep can know, when it runs.
    let opts = TradeoffOptions::new("cornell", &["--frames=1"]).unwrap();
    assert!(sweep(&opts, &Quiet).unwrap_err().contains("--frames must be at least 2"));
    let mut opts = TradeoffOptions::new("no-such-scene", &[]).unwrap();
    opts.references.cache = temp("bad").join("cache");
    assert!(sweep(&opts, &Quiet).is_err());
}
