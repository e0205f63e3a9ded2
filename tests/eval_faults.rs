//! The evaluation cache under real faults, through the command-line tool: a run killed with
//! SIGKILL at three moments (after its first, a middle and its last-but-one cache entry) and
//! resumed, and two runs racing on one cache. Each must end with the same `results.json` as a
//! run that was never disturbed (wall times aside). The in-process fault tests (interrupted
//! units, checkpoints, flipped bytes, truncation, failed writes) are in `tests/eval_run.rs` and
//! `src/eval/cache.rs`.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("stereotrace-faults-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A configuration of a few seconds: 14 cache entries (references, curves, configurations).
fn eval_args(out: &Path, cache: &Path) -> Vec<String> {
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
    .map(|s| s.to_string())
    .chain(["--out".into(), out.display().to_string(), "--cache".into(), cache.display().to_string()])
    .collect()
}

fn spawn(out: &Path, cache: &Path) -> Child {
    Command::new(env!("CARGO_BIN_EXE_stereotrace"))
        .args(eval_args(out, cache))
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the binary starts")
}

fn finish(child: Child) {
    let out = child.wait_with_output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
}

/// Cache entries written so far (finished units; temporaries excluded).
fn entries(cache: &Path) -> usize {
    fn walk(d: &Path) -> usize {
        std::fs::read_dir(d).map_or(0, |rd| {
            rd.flatten()
                .map(|e| {
                    let p = e.path();
                    if p.is_dir() {
                        walk(&p)
                    } else {
                        usize::from(p.extension().is_some_and(|x| x == "bin") && !p.to_string_lossy().contains(".tmp-"))
                    }
                })
                .sum()
        })
    }
    walk(cache)
}

/// `results.json` without wall times (the only fields that differ between runs).
fn timeless_results(out: &Path) -> serde_json::Value {
    fn strip(v: &mut serde_json::Value) {
        match v {
            serde_json::Value::Object(m) => {
                m.remove("seconds");
                m.values_mut().for_each(strip);
            }
            serde_json::Value::Array(a) => a.iter_mut().for_each(strip),
            _ => {}
        }
    }
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("results.json")).unwrap()).unwrap();
    let mut results = v["results"].take();
    strip(&mut results);
    results
}

/// The results of an undisturbed run in its own folder (`tag`: the tests run in parallel).
fn undisturbed(tag: &str) -> serde_json::Value {
    let dir = temp_dir(&format!("fresh-{tag}"));
    finish(spawn(&dir.join("out"), &dir.join("cache")));
    let results = timeless_results(&dir.join("out"));
    std::fs::remove_dir_all(&dir).ok();
    results
}

#[test]
fn a_run_killed_at_three_moments_resumes_to_the_same_results() {
    let fresh = undisturbed("killed");
    for (moment, after_entries) in [("early", 1), ("middle", 7), ("late", 13)] {
        let dir = temp_dir(moment);
        let (out, cache) = (dir.join("out"), dir.join("cache"));
        let mut child = spawn(&out, &cache);
        let start = Instant::now();
        while entries(&cache) < after_entries && child.try_wait().unwrap().is_none() {
            assert!(start.elapsed() < Duration::from_secs(120), "{moment}: the run made no progress");
            std::thread::sleep(Duration::from_millis(2));
        }
        let killed = child.try_wait().unwrap().is_none();
        child.kill().ok(); // SIGKILL: no destructor, no flush, no cleanup runs.
        child.wait().unwrap();
        finish(spawn(&out, &cache));
        assert_eq!(timeless_results(&out), fresh, "{moment} (killed while running: {killed})");
        std::fs::remove_dir_all(&dir).ok();
    }
}

#[test]
fn two_runs_racing_on_one_cache_both_finish_with_the_same_results() {
    let fresh = undisturbed("race");
    let dir = temp_dir("race");
    let cache = dir.join("cache");
    let (a, b) = (spawn(&dir.join("a"), &cache), spawn(&dir.join("b"), &cache));
    finish(a);
    finish(b);
    assert_eq!(timeless_results(&dir.join("a")), fresh);
    assert_eq!(timeless_results(&dir.join("b")), fresh);
    std::fs::remove_dir_all(&dir).ok();
}
