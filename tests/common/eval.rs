//! Running `stereotrace eval` as a process on a tiny spec (the fault and shard tests).

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};

/// A fresh folder for one test (`name` unique per test: tests run in parallel).
pub fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("stereotrace-eval-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A run of a few seconds: 4 references, 4 curves, 2 configurations, 2 figure images.
pub fn tiny_eval_args(out: &Path, cache: &Path, extra: &[&str]) -> Vec<String> {
    [
        "eval",
        "--scenes",
        "cornell",
        "--modes",
        "stereo,spatiotemporal",
        "--spp",
        "1",
        "--res",
        "64x36",
        "--frames",
        "4",
        "--warmup",
        "2",
        "--reference-spp",
        "256",
        "--curve-spp",
        "16",
    ]
    .iter()
    .chain(extra)
    .map(|s| s.to_string())
    .chain(["--out".into(), out.display().to_string(), "--cache".into(), cache.display().to_string()])
    .collect()
}

/// Starts the tiny run (stdout piped, for its report).
pub fn spawn_eval(out: &Path, cache: &Path, extra: &[&str]) -> Child {
    Command::new(env!("CARGO_BIN_EXE_stereotrace"))
        .args(tiny_eval_args(out, cache, extra))
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the binary starts")
}

/// Waits for a run that must succeed; its stdout.
pub fn finish(child: Child) -> String {
    let out = child.wait_with_output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// Runs the tiny run to its end, whatever its exit status.
pub fn run_eval(out: &Path, cache: &Path, extra: &[&str]) -> Output {
    spawn_eval(out, cache, extra).wait_with_output().unwrap()
}

/// Cache entries written so far (finished units; temporaries and claims excluded).
pub fn entries(cache: &Path) -> usize {
    std::fs::read_dir(cache).map_or(0, |rd| {
        rd.flatten()
            .map(|e| {
                let p = e.path();
                if p.is_dir() { entries(&p) } else { usize::from(p.extension().is_some_and(|x| x == "bin")) }
            })
            .sum()
    })
}

/// The files a run writes that must not depend on how it ran: every table, the long CSV,
/// `results.json` and `warnings.txt` (name, bytes), sorted by name.
pub fn report_files(out: &Path) -> Vec<(String, Vec<u8>)> {
    let mut files: Vec<(String, Vec<u8>)> = std::fs::read_dir(out)
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".md") || n.ends_with(".csv") || n == "results.json" || n == "warnings.txt")
        .map(|n| {
            let bytes = std::fs::read(out.join(&n)).unwrap();
            (n, bytes)
        })
        .collect();
    files.sort();
    assert!(files.iter().any(|(n, _)| n == "results.json"), "no results.json in {}", out.display());
    files
}

/// What a report on stdout says was computed: (references, curves, configurations, figure images).
pub fn computed(out_or_report: &str) -> (usize, usize, usize, usize) {
    // "computed 2 references, 0 curves, 0 configurations, 0 figure images" (shard report) or
    // "computed: 4 references, ..." (whole run).
    let at = out_or_report.find("computed").expect("a 'computed' line");
    let nums: Vec<usize> = out_or_report[at..]
        .split(|c: char| !c.is_ascii_digit())
        .filter(|s| !s.is_empty())
        .take(4)
        .map(|s| s.parse().unwrap())
        .collect();
    (nums[0], nums[1], nums[2], nums[3])
}
