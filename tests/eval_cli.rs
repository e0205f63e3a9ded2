//! The `ssim` and `eval` subcommands: results, and a message plus a non-zero exit for every
//! bad input.

use std::path::PathBuf;
use std::process::{Command, Output};

use stereotrace::image_io::write_exr;
use stereotrace::kernels::{Extent, RgbBuf};

mod common;

fn stereotrace(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_stereotrace")).args(args).output().expect("the binary runs")
}

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("stereotrace-evalcli-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn assert_refused(out: &Output, needles: &[&str]) {
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "expected failure, got success: {err}");
    for n in needles {
        assert!(err.contains(n), "stderr does not mention '{n}': {err}");
    }
    assert!(!err.contains("panicked"), "the tool panicked: {err}");
}

fn gradient(w: usize, h: usize, scale: f32) -> RgbBuf {
    let mut img = RgbBuf::new(Extent::new(w, h).unwrap(), 0.0);
    for y in 0..h {
        for x in 0..w {
            let v = scale * (x + 2 * y) as f32 / (w + 2 * h) as f32;
            img.set(x, y, [v, 0.5 * v, 0.25 + v]);
        }
    }
    img
}

#[test]
fn ssim_prints_both_variants_and_the_rmse() {
    let dir = temp_dir("ssim");
    let (a, b) = (dir.join("a.exr"), dir.join("b.exr"));
    write_exr(&a, &gradient(40, 24, 1.0)).unwrap();
    write_exr(&b, &gradient(40, 24, 1.1)).unwrap();
    let out = stereotrace(&["ssim", a.to_str().unwrap(), b.to_str().unwrap()]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    for needle in ["SSIM (3-D RGB volume):", "SSIM (per channel):", "RMSE:", "40x24"] {
        assert!(text.contains(needle), "no '{needle}' in {text}");
    }
    // The same image: SSIM 1, RMSE 0.
    let same = stereotrace(&["ssim", a.to_str().unwrap(), a.to_str().unwrap()]);
    let text = String::from_utf8_lossy(&same.stdout);
    assert!(text.contains("volume): 1.000000") && text.contains("RMSE:                  0.000000\n"), "{text}");
    std::fs::remove_dir_all(&dir).ok();
}

/// Writes `img` with the samples `poison` says replaced by NaN (the project's own writer
/// refuses non-finite images, so this goes through the EXR crate directly).
fn write_exr_with_nan(path: &std::path::Path, img: &RgbBuf, poison: impl Fn(usize, usize) -> bool + Sync) {
    let e = img.extent();
    exr::prelude::write_rgb_file(path, e.width(), e.height(), |x, y| {
        let [r, g, b] = img.get(x, y);
        if poison(x, y) { (f32::NAN, g, b) } else { (r, g, b) }
    })
    .unwrap();
}

/// NaN samples used to be left out silently (SSIM 1.000000, RMSE 0, exit 0); they are an
/// error unless `--exclude-nonfinite` says to compare the rest, and an image with nothing
/// comparable is an error either way.
#[test]
fn ssim_fails_on_non_finite_samples_unless_told_to_exclude_them() {
    let dir = temp_dir("ssim-nan");
    let (a, b, all) = (dir.join("a.exr"), dir.join("b.exr"), dir.join("all-nan.exr"));
    let img = gradient(96, 80, 1.0);
    write_exr(&a, &img).unwrap();
    write_exr_with_nan(&b, &img, |x, y| x < 64 && y < 64);
    write_exr_with_nan(&all, &img, |_, _| true);
    let (a, b, all) = (a.to_str().unwrap(), b.to_str().unwrap(), all.to_str().unwrap());
    assert_refused(&stereotrace(&["ssim", a, b]), &["4096 of 23040 samples", "--exclude-nonfinite"]);
    let out = stereotrace(&["ssim", a, b, "--exclude-nonfinite"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(String::from_utf8_lossy(&out.stdout).contains("4096 non-finite or out-of-range samples were excluded"));
    for flag in [None, Some("--exclude-nonfinite")] {
        let args: Vec<&str> = ["ssim", a, all].into_iter().chain(flag).collect();
        assert_refused(&stereotrace(&args), &["all-nan.exr"]);
    }
    let out = stereotrace(&["ssim", a, all, "--exclude-nonfinite"]);
    assert!(String::from_utf8_lossy(&out.stderr).contains("nothing to compare"));
}

/// A header claiming 65536×65536 pixels (a file of a few hundred bytes) used to abort the
/// process allocating 51 GB.
#[test]
fn ssim_refuses_an_exr_claiming_billions_of_pixels() {
    let dir = temp_dir("ssim-huge");
    let huge = dir.join("huge.exr");
    common::exr_claiming(&huge, 65536);
    let huge = huge.to_str().unwrap();
    assert_refused(&stereotrace(&["ssim", huge, huge]), &["huge.exr", "too large"]);
}

#[test]
fn ssim_names_the_file_at_fault() {
    let dir = temp_dir("ssim-bad");
    let a = dir.join("a.exr");
    write_exr(&a, &gradient(40, 24, 1.0)).unwrap();
    let missing = dir.join("missing.exr");
    assert_refused(&stereotrace(&["ssim", a.to_str().unwrap(), missing.to_str().unwrap()]), &["missing.exr"]);
    assert_refused(&stereotrace(&["ssim", missing.to_str().unwrap(), a.to_str().unwrap()]), &["missing.exr"]);
    let small = dir.join("small.exr");
    write_exr(&small, &gradient(20, 24, 1.0)).unwrap();
    assert_refused(
        &stereotrace(&["ssim", a.to_str().unwrap(), small.to_str().unwrap()]),
        &["a.exr is 40x24", "small.exr is 20x24"],
    );
    let text = dir.join("not-an-image.exr");
    std::fs::write(&text, "hello").unwrap();
    assert_refused(&stereotrace(&["ssim", a.to_str().unwrap(), text.to_str().unwrap()]), &["not-an-image.exr"]);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn eval_runs_a_small_configuration_and_resumes_from_its_cache() {
    let dir = temp_dir("eval");
    let (out, cache) = (dir.join("out"), dir.join("cache"));
    let args = [
        "eval",
        "--scenes",
        "cornell",
        "--modes",
        "stereo,spatiotemporal",
        "--spp",
        "1",
        "--res",
        "32x18",
        "--frames",
        "4",
        "--warmup",
        "2",
        "--reference-spp",
        "8",
        "--curve-spp",
        "4",
        "--out",
        out.to_str().unwrap(),
        "--cache",
        cache.to_str().unwrap(),
    ];
    let first = stereotrace(&args);
    let text = String::from_utf8_lossy(&first.stdout);
    assert!(first.status.success(), "{}", String::from_utf8_lossy(&first.stderr));
    assert!(text.contains("| stereo |") && text.contains("computed: 4 references"), "{text}");
    for f in [
        "tables.md",
        "results.json",
        "table1_stereo_ssim.csv",
        "table3_spatiotemporal_ssim.csv",
        "fig3_framewise_ssim.svg",
    ] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    // Issue 13: a resumed run reports the warnings of the work it loads, and a stale
    // warnings.txt does not survive a run that reports none.
    let warnings = out.join("warnings.txt");
    let first_warnings = std::fs::read_to_string(&warnings).ok();
    if first_warnings.is_none() {
        std::fs::write(&warnings, "stale: from an earlier run\n").unwrap();
    }
    let second = stereotrace(&args);
    let text = String::from_utf8_lossy(&second.stdout);
    assert!(text.contains("computed: 0 references, 0 curves, 0 configurations"), "{text}");
    assert_eq!(std::fs::read_to_string(&warnings).ok(), first_warnings, "warnings.txt after the resumed run");
    let results: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("results.json")).unwrap()).unwrap();
    let reported = results["warnings"].as_array().map_or(0, Vec::len);
    assert_eq!(reported, first_warnings.map_or(0, |w| w.lines().count()), "results.json and warnings.txt agree");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn eval_refuses_bad_options_with_a_message() {
    let dir = temp_dir("eval-bad");
    let d = dir.to_str().unwrap();
    let run = |extra: &[&str]| {
        let mut args = vec!["eval", "--out", d, "--cache", d];
        args.extend_from_slice(extra);
        stereotrace(&args)
    };
    assert_refused(&run(&["--modes", "spatial"]), &["unknown mode 'spatial'", "stereo-blend"]);
    assert_refused(&run(&["--scenes", "no-such-scene"]), &["no-such-scene"]);
    assert_refused(&run(&["--frames", "5", "--warmup", "5"]), &["warm-up"]);
    assert_refused(&run(&["--spp", "0"]), &["--spp", "1..=1048576"]);
    assert_refused(&run(&["--scenes", "cornell", "--frames", "500"]), &["500 frames"]);
    std::fs::remove_dir_all(&dir).ok();
}

/// `compare` puts two runs side by side: the filtered run against the paper's shares their
/// references and curves from one cache (only the configurations are computed again: the
/// filter is in their cache key), `compare.md` has a row per scene, mode and spp with the
/// ratio, and the figures are written; runs of different resolutions are refused.
#[test]
fn compare_puts_a_filtered_run_beside_the_papers() {
    let dir = temp_dir("compare");
    let cache = dir.join("cache");
    let run = |name: &str, res: &str, extra: &[&str]| {
        let out = dir.join(name);
        let mut args = vec![
            "eval",
            "--scenes",
            "cornell",
            "--modes",
            "temporal,spatiotemporal",
            "--spp",
            "1,2",
            "--res",
            res,
            "--frames",
            "4",
            "--warmup",
            "2",
            "--reference-spp",
            "16",
            "--curve-spp",
            "8",
            "--no-figures",
            "--out",
            out.to_str().unwrap(),
            "--cache",
            cache.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        let result = stereotrace(&args);
        assert!(result.status.success(), "{}", String::from_utf8_lossy(&result.stderr));
        (out, String::from_utf8_lossy(&result.stdout).into_owned())
    };
    let (paper, _) = run("paper", "40x24", &[]);
    let (filtered, text) = run("filtered", "40x24", &["--filter", "atrous"]);
    assert!(text.contains("computed: 0 references, 0 curves, 4 configurations"), "{text}");
    let cmp = dir.join("cmp");
    let out =
        stereotrace(&["compare", paper.to_str().unwrap(), filtered.to_str().unwrap(), "--out", cmp.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let md = std::fs::read_to_string(cmp.join("compare.md")).unwrap();
    assert!(md.starts_with("# atrous filter against paper"), "{md}");
    for needle in ["| temporal | 1 |", "| spatiotemporal | 2 |", "| cornell | temporal | 2 |", "Geometric mean"] {
        assert!(md.contains(needle), "no '{needle}' in {md}");
    }
    for f in ["compare_ssim.png", "compare_ssim.svg", "compare_rmse.png", "compare_rmse.svg"] {
        assert!(cmp.join(f).is_file(), "{f} missing");
    }
    // A run at another resolution measured something else.
    let (small, _) = run("small", "32x18", &[]);
    let refused =
        stereotrace(&["compare", paper.to_str().unwrap(), small.to_str().unwrap(), "--out", cmp.to_str().unwrap()]);
    assert_refused(&refused, &["not comparable", "resolution 40x24 against 32x18"]);
    let missing = stereotrace(&[
        "compare",
        dir.join("nowhere").to_str().unwrap(),
        paper.to_str().unwrap(),
        "--out",
        cmp.to_str().unwrap(),
    ]);
    assert_refused(&missing, &["cannot read"]);
    std::fs::remove_dir_all(&dir).ok();
}
