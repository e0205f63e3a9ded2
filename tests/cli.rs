//! The command-line tool: every bad input gets a message and a non-zero exit, never a panic;
//! the main job writes what it says.

use std::path::PathBuf;
use std::process::{Command, Output};

fn stereotrace(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_stereotrace")).args(args).output().expect("the binary runs")
}

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("stereotrace-cli-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// Fails unless the command exited non-zero with `needle` in its error output and without a
/// panic.
fn assert_refused(out: &Output, needle: &str) {
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "expected failure, got success: {err}");
    assert!(err.contains(needle), "stderr does not mention '{needle}': {err}");
    assert!(!err.contains("panicked"), "the tool panicked: {err}");
}

#[test]
fn render_writes_exr_and_png_for_both_eyes() {
    let dir = temp_dir("render");
    let out =
        stereotrace(&["render", "--scene", "cornell", "--spp", "2", "--res", "32x18", "--out", dir.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    for eye in ["left", "right"] {
        for ext in ["exr", "png"] {
            let f = dir.join(format!("cornell/{eye}_000.{ext}"));
            assert!(f.metadata().map(|m| m.len() > 0).unwrap_or(false), "{} missing", f.display());
        }
    }
    let img = stereotrace::image_io::read_exr(&dir.join("cornell/left_000.exr")).unwrap();
    assert_eq!((img.extent().width(), img.extent().height()), (32, 18));
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn unknown_scenes_list_the_built_ins() {
    let out = stereotrace(&["render", "--scene", "no-such-scene", "--res", "8x8", "--out", "/tmp"]);
    assert_refused(&out, "atrium");
}

#[test]
fn bad_resolutions_and_counts_are_refused() {
    assert_refused(&stereotrace(&["render", "--res", "0x10"]), "zero");
    assert_refused(&stereotrace(&["render", "--res", "1280"]), "WIDTHxHEIGHT");
    assert_refused(&stereotrace(&["render", "--res", "99999x10"]), "too large");
    assert_refused(&stereotrace(&["render", "--res", "8x8", "--spp", "0", "--out", "/tmp"]), "spp");
    assert_refused(&stereotrace(&["render", "--res", "8x8", "--frames", "1000", "--out", "/tmp"]), "camera path");
    assert_refused(&stereotrace(&["render", "--res", "8x8", "--eye-separation=-1", "--out", "/tmp"]), "separation");
    assert_refused(&stereotrace(&["throughput", "--scene", "cornell", "--res", "16x9", "--frames", "0"]), "frames");
}

#[test]
fn malformed_scene_files_name_the_file() {
    let dir = temp_dir("bad-scene");
    std::fs::create_dir_all(&dir).unwrap();
    let manifest = dir.join("broken.toml");
    std::fs::write(&manifest, "name = \"x\"\nmesh = [1, 2\n").unwrap();
    let out =
        stereotrace(&["render", "--scene", manifest.to_str().unwrap(), "--res", "8x8", "--out", dir.to_str().unwrap()]);
    assert_refused(&out, "broken.toml");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn unwritable_output_is_an_error_not_a_panic() {
    let dir = temp_dir("unwritable");
    std::fs::create_dir_all(&dir).unwrap();
    // A file where the output folder should go.
    let blocker = dir.join("out");
    std::fs::write(&blocker, b"not a folder").unwrap();
    let out = stereotrace(&["render", "--res", "8x8", "--spp", "1", "--out", blocker.to_str().unwrap()]);
    assert_refused(&out, "out");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn throughput_reports_json_with_every_field() {
    let out = stereotrace(&[
        "throughput",
        "--scene",
        "cornell",
        "--res",
        "32x18",
        "--frames",
        "2",
        "--mode",
        "spatiotemporal",
        "--json",
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("one JSON object");
    for key in [
        "stereo_fps",
        "frame",
        "gbuffer",
        "reprojection",
        "tracing",
        "accumulation",
        "mrays_per_s",
        "left_traced_share",
        "speedup_over_full_stereo",
        "mono_frame_ms",
        "stereo_over_mono",
    ] {
        assert!(v.get(key).is_some(), "missing {key}: {v}");
    }
    assert!(v["left_traced_share"].as_f64().unwrap() < 0.5);
    assert_eq!(v["right_traced_share"].as_f64().unwrap(), 1.0);
    assert_eq!(v["gbuffer_pass"], "raster");
    let (frame, mono) = (v["frame"]["median_ms"].as_f64().unwrap(), v["mono_frame_ms"].as_f64().unwrap());
    assert!(mono > 0.0 && (v["stereo_over_mono"].as_f64().unwrap() - frame / mono).abs() < 1e-9);
}

/// Issue 36: the driver's three runs (the mode, full stereo, mono) share every setting, the
/// budget included, and a time ratio appears only when no run had a budget.
#[test]
fn no_throughput_ratio_mixes_a_budgeted_and_an_unbudgeted_run() {
    let args = ["throughput", "--scene", "cornell", "--res", "32x18", "--frames", "2", "--mode", "spatiotemporal"];
    let run = |extra: &[&str]| {
        let out = stereotrace(&[&args[..], extra].concat());
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        out.stdout
    };
    for budget in [None, Some(50.0)] {
        let budget_args = budget.map(|b: f64| vec!["--budget-ms".to_owned(), b.to_string()]).unwrap_or_default();
        let budget_args: Vec<&str> = budget_args.iter().map(String::as_str).collect();
        let v: serde_json::Value =
            serde_json::from_slice(&run(&[&budget_args[..], &["--json"]].concat())).expect("one JSON object");
        let schedules = v["schedules"].as_array().expect("schedules");
        let names: Vec<&str> = schedules.iter().map(|s| s["schedule"].as_str().unwrap()).collect();
        assert_eq!(names, ["spatiotemporal", "full stereo", "mono"], "{v}");
        for s in schedules {
            assert_eq!(s["budget_ms"].as_f64(), budget, "every run has the report's budget: {s}");
        }
        assert!(schedules[2]["traced_share"][0].is_null() && schedules[2]["traced_share"][1].as_f64() == Some(1.0));
        let median = |s: &serde_json::Value| s["frame"]["median_ms"].as_f64().unwrap();
        let (this, full, mono) = (median(&schedules[0]), median(&schedules[1]), median(&schedules[2]));
        assert_eq!(v["full_stereo_frame_ms"].as_f64(), Some(full));
        assert_eq!(v["mono_frame_ms"].as_f64(), Some(mono));
        let text = String::from_utf8(run(&budget_args)).unwrap();
        match budget {
            None => {
                assert_eq!(v["speedup_over_full_stereo"].as_f64(), Some(full / this));
                assert_eq!(v["stereo_over_mono"].as_f64(), Some(this / mono));
                assert!(text.contains("speed-up") && text.contains("stereo costs"), "{text}");
                assert!(text.contains("no budget): speed-up"), "the line says what both runs had: {text}");
            }
            Some(_) => {
                assert!(v["speedup_over_full_stereo"].is_null() && v["stereo_over_mono"].is_null(), "{v}");
                assert!(!text.contains("speed-up") && !text.contains("stereo costs"), "{text}");
                assert!(text.contains("every schedule under the same 50.00 ms budget"), "{text}");
                assert!(text.contains("stereotrace tradeoff"), "the quality side is named: {text}");
            }
        }
    }
}

#[test]
fn throughput_takes_the_traced_gbuffer_and_reports_budget_overruns() {
    let args = ["throughput", "--scene", "cornell", "--res", "32x18", "--frames", "2", "--no-baseline", "--json"];
    let out = stereotrace(&[&args[..], &["--gbuffer", "traced", "--budget-ms", "1000"]].concat());
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("one JSON object");
    assert_eq!(v["gbuffer_pass"], "traced");
    assert!(v["raster"].is_null(), "a traced pass has no raster steps: {v}");
    assert_eq!(v["budget_ms"].as_f64(), Some(1000.0));
    assert!(v["budget_misses_over_1ms"].as_u64().unwrap() <= v["budget_misses"].as_u64().unwrap());
    assert_refused(&stereotrace(&[&args[..], &["--gbuffer", "painted"]].concat()), "painted");
}

/// A rasterised pass reports where its time went: its four steps, each within the pass's
/// own time, and the triangles it was given against those it found visible.
#[test]
fn throughput_attributes_the_raster_pass_to_its_steps() {
    let args = ["throughput", "--scene", "atrium", "--res", "64x36", "--frames", "3", "--no-baseline", "--json"];
    let out = stereotrace(&args);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("one JSON object");
    assert_eq!(v["gbuffer_pass"], "raster");
    let steps = &v["raster"];
    let gbuffer_max = v["gbuffer"]["max_ms"].as_f64().unwrap();
    for step in ["setup", "binning", "fragments", "resolve"] {
        let median = steps[step]["median_ms"].as_f64().unwrap_or_else(|| panic!("{step} missing: {v}"));
        assert!(median >= 0.0 && median <= gbuffer_max, "{step}: {median} ms of a pass of at most {gbuffer_max} ms");
    }
    let (triangles, visible) = (steps["triangles"].as_u64().unwrap(), steps["visible"].as_u64().unwrap());
    assert!(triangles > 100_000 && 0 < visible && visible < triangles, "{triangles} triangles, {visible} visible");
    let text = String::from_utf8_lossy(&stereotrace(&args[..args.len() - 1]).stdout).into_owned();
    assert!(text.contains("raster       setup"), "{text}");
}

#[test]
fn scenes_lists_every_built_in() {
    let out = stereotrace(&["scenes"]);
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    for name in stereotrace::scene::builtin_names() {
        assert!(text.contains(name), "{name} missing from:\n{text}");
    }
}

#[test]
fn tradeoff_writes_its_table_and_plot_and_refuses_bad_budgets() {
    let dir = temp_dir("tradeoff");
    let (out_dir, cache) = (dir.join("out"), dir.join("cache"));
    let args = |budgets: &'static str| {
        vec![
            "tradeoff".to_owned(),
            "--scene=cornell".into(),
            "--res=32x18".into(),
            "--frames=4".into(),
            "--warmup=2".into(),
            "--spp=1".into(),
            "--reference-spp=8".into(),
            "--curve-spp=4".into(),
            format!("--budgets={budgets}"),
            format!("--out={}", out_dir.display()),
            format!("--cache={}", cache.display()),
        ]
    };
    let run = |a: Vec<String>| stereotrace(&a.iter().map(String::as_str).collect::<Vec<_>>());
    let out = run(args("0.5"));
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(String::from_utf8_lossy(&out.stdout).contains("Pareto front"));
    for f in ["tradeoff.md", "tradeoff.csv", "tradeoff.json", "tradeoff.png", "tradeoff.svg"] {
        assert!(out_dir.join(f).metadata().map(|m| m.len() > 0).unwrap_or(false), "{f} missing");
    }
    assert_refused(&run(args("2")), "budget fraction");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn exposures_and_frame_counts_that_would_write_nothing_useful_are_refused() {
    for bad in ["NaN", "inf", "-1", "0"] {
        let out = stereotrace(&["render", "--res", "8x8", &format!("--exposure={bad}"), "--out", "/tmp"]);
        assert_refused(&out, "exposure");
    }
    assert_refused(&stereotrace(&["render", "--res", "8x8", "--frames", "0", "--out", "/tmp"]), "frames");
    assert_refused(&stereotrace(&["render", "--res", "8x8", "--bounces", "2", "--out", "/tmp"]), "bounces");
}

#[test]
fn export_scene_round_trips_a_builtin_through_the_shared_folder_format() {
    let dir = temp_dir("export");
    let folder = dir.join("cornell");
    let out = stereotrace(&["export-scene", "cornell", "--out", folder.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    for file in ["scene.obj", "scene.mtl", "camera.json", "lights.json", "SOURCE.md"] {
        assert!(folder.join(file).is_file(), "{file} missing");
    }
    let original = stereotrace::scene::resolve("cornell").unwrap();
    let loaded = stereotrace::scene::resolve(folder.to_str().unwrap()).unwrap();
    // The export groups triangles by material; within a material they keep their order.
    let by_material = |s: &stereotrace::scene::Scene, m: usize| -> Vec<_> {
        (0..s.mesh.len()).filter(|&t| s.mesh.material[t] as usize == m).map(|t| s.mesh.positions[t]).collect()
    };
    assert_eq!(loaded.materials.len(), original.materials.len());
    for m in 0..original.materials.len() {
        assert_eq!(by_material(&loaded, m), by_material(&original, m), "material {m}: geometry bit for bit");
    }
    for (a, b) in loaded.materials.iter().zip(&original.materials) {
        assert_eq!((a.kind, a.albedo, a.emission), (b.kind, b.albedo, b.emission), "{}", b.name);
    }
    assert_eq!(loaded.units.meters_per_unit, 1.0);
    let (p, q) = (loaded.camera.pose_at(0.0), original.camera.pose_at(0.0));
    assert!((p.eye - q.eye).length() < 1e-5 && (p.forward - q.forward).length() < 1e-5);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn direct_lighting_only_is_the_first_part_of_the_paper_estimate() {
    let dir = temp_dir("bounces");
    let mean = |bounces: &str| {
        let out_dir = dir.join(bounces);
        let out = stereotrace(&[
            "render",
            "--scene",
            "cornell",
            "--res",
            "24x16",
            "--spp",
            "8",
            "--eye",
            "left",
            "--bounces",
            bounces,
            "--out",
            out_dir.to_str().unwrap(),
        ]);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let img = stereotrace::image_io::read_exr(&out_dir.join("cornell/left_000.exr")).unwrap();
        let v: Vec<f32> = img.planes().iter().flat_map(|p| p.as_slice().to_vec()).collect();
        (v.iter().all(|x| x.is_finite()), v.iter().map(|&x| f64::from(x)).sum::<f64>())
    };
    let ((finite0, direct), (finite1, paper)) = (mean("0"), mean("1"));
    assert!(finite0 && finite1);
    assert!(direct > 0.0 && paper > direct * 1.05, "the secondary bounce adds light: {direct} vs {paper}");
    std::fs::remove_dir_all(&dir).ok();
}

/// Numbers that used to panic (`--budget-ms NaN` in `Duration::from_secs_f64`), run for days
/// (`--spp 4000000000`), write nothing (`--frames 0`) or render black without a word (eye
/// separations of 10⁶ m and more) are refused with the bound in the message.
#[test]
fn hostile_numbers_are_refused_with_their_bounds() {
    let throughput = ["throughput", "--scene", "cornell", "--res", "16x9", "--frames", "1", "--no-baseline"];
    for budget in ["NaN", "inf", "1e30", "-5", "0"] {
        let flag = format!("--budget-ms={budget}");
        let args: Vec<&str> = throughput.iter().copied().chain([flag.as_str()]).collect();
        assert_refused(&stereotrace(&args), "budget");
    }
    // Issue 13: 1e300 is printed as 1e300, not with 301 digits.
    let args: Vec<&str> = throughput.iter().copied().chain(["--budget-ms", "1e300"]).collect();
    let out = stereotrace(&args);
    assert_refused(&out, "budget 1e300 ms");
    assert!(String::from_utf8_lossy(&out.stderr).len() < 300, "{}", String::from_utf8_lossy(&out.stderr));
    let args: Vec<&str> = throughput.iter().copied().chain(["--spp", "4000000000"]).collect();
    assert_refused(&stereotrace(&args), "1048576");
    let tradeoff = ["tradeoff", "--scene", "cornell", "--res", "16x9", "--budgets-ms", "NaN"];
    assert_refused(&stereotrace(&tradeoff), "budget");
    let dir = temp_dir("hostile");
    let out = dir.to_str().unwrap();
    let render = ["render", "--scene", "cornell", "--res", "8x8", "--out", out];
    for (extra, needle) in [
        (["--frames", "0"], "frames"),
        (["--spp", "4000000000"], "1048576"),
        (["--eye-separation", "1e6"], "eye separation"),
        (["--eye-separation", "3e38"], "eye separation"),
    ] {
        let args: Vec<&str> = render.iter().copied().chain(extra).collect();
        assert_refused(&stereotrace(&args), needle);
    }
    // Wider than the scene but within the bound: rendered, with a warning that says why the
    // eyes may see nothing; one image is "1 image".
    let args: Vec<&str> =
        render.iter().copied().chain(["--eye-separation", "500", "--eye", "left", "--spp", "1"]).collect();
    let run = stereotrace(&args);
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    assert!(String::from_utf8_lossy(&run.stderr).contains("wider than the scene"));
    assert!(String::from_utf8_lossy(&run.stdout).contains("wrote 1 image ("));
}

/// Issue 13: under a budget, stereo mode's right eye is traced in full whatever the budget;
/// the note on work that always runs counted only G-buffers, reprojection and accumulation.
#[test]
fn the_always_run_note_counts_the_fully_traced_eye() {
    let args = [
        "throughput",
        "--scene",
        "cornell",
        "--res",
        "32x18",
        "--frames",
        "2",
        "--mode",
        "stereo",
        "--budget-ms",
        "0.001",
        "--no-baseline",
        "--json",
    ];
    let out = stereotrace(&args);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let (always, g, r, a, tracing) = (
        report["always_run_ms"].as_f64().unwrap(),
        report["gbuffer"]["median_ms"].as_f64().unwrap(),
        report["reprojection"]["median_ms"].as_f64().unwrap(),
        report["accumulation"]["median_ms"].as_f64().unwrap(),
        report["tracing"]["median_ms"].as_f64().unwrap(),
    );
    // Medians of sums and sums of medians differ a little; the traced eye dominates both.
    assert!(always > 0.5 * (g + r + a + tracing), "always run {always} ms vs stages {g} + {r} + {a} + {tracing}");
    let text = stereotrace(&args[..args.len() - 1]);
    assert!(String::from_utf8_lossy(&text.stdout).contains("tracing the pixels without valid history"));
}

#[test]
fn an_unknown_or_unsupported_instruction_set_is_refused_and_avx2_is_taken() {
    let run = |isa: &str, args: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_stereotrace"))
            .args(args)
            .env("STEREOTRACE_ISA", isa)
            .output()
            .expect("the binary runs")
    };
    let out = run("sse9", &["scenes"]);
    assert_refused(&out, "STEREOTRACE_ISA=\"sse9\" is not an instruction set");
    // `--help` still works, and says what the variable does.
    let help = run("sse9", &["--help"]);
    assert!(help.status.success() && String::from_utf8_lossy(&help.stdout).contains("STEREOTRACE_ISA"));
    // The 8-lane bodies run anywhere; the JSON says which bodies a driver ran.
    let out = run("avx2", &["throughput", "--scene", "cornell", "--frames", "1", "--res", "64x36", "--json"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let json = String::from_utf8_lossy(&out.stdout);
    assert!(json.contains("\"simd_level\"") && !json.contains("AVX-512 bodies"), "{json}");
    if stereotrace::kernels::isa::Isa::Avx512.is_supported() {
        let out = run("avx512", &["throughput", "--scene", "cornell", "--frames", "1", "--res", "64x36", "--json"]);
        assert!(String::from_utf8_lossy(&out.stdout).contains("AVX-512 bodies at run time"));
    } else {
        assert_refused(&run("avx512", &["scenes"]), "lacks AVX-512");
    }
}
