//! The evaluation cache under real faults, through the command-line tool: a run killed with
//! SIGKILL at three moments (after its first, a middle and its last-but-one cache entry) and
//! resumed, and two runs racing on one cache. Each must end with the same tables and
//! `results.json`, byte for byte, as a run that was never disturbed. The in-process fault tests (interrupted
//! units, checkpoints, flipped bytes, truncation, failed writes) are in `tests/eval_run.rs` and
//! `src/eval/cache.rs`.

mod common;

use std::path::Path;
use std::time::{Duration, Instant};

use common::eval::{computed, entries, finish, report_files, spawn_eval, temp_dir};

fn spawn(out: &Path, cache: &Path) -> std::process::Child {
    spawn_eval(out, cache, &[])
}

/// Every table, `results.json` and `warnings.txt` of a run (byte for byte: nothing in them
/// depends on how the run went).
fn timeless_results(out: &Path) -> Vec<(String, Vec<u8>)> {
    report_files(out)
}

/// The results of an undisturbed run in its own folder (`tag`: the tests run in parallel).
fn undisturbed(tag: &str) -> Vec<(String, Vec<u8>)> {
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
        assert!(timeless_results(&out) == fresh, "{moment} (killed while running: {killed})");
        std::fs::remove_dir_all(&dir).ok();
    }
}

#[test]
fn two_runs_racing_on_one_cache_both_finish_with_the_same_results() {
    let fresh = undisturbed("race");
    let dir = temp_dir("race");
    let cache = dir.join("cache");
    let (a, b) = (spawn(&dir.join("a"), &cache), spawn(&dir.join("b"), &cache));
    let (a_text, b_text) = (finish(a), finish(b));
    // Claims: whatever one computed, the other loaded or waited for.
    let (x, y) = (computed(&a_text), computed(&b_text));
    assert_eq!((x.0 + y.0, x.1 + y.1, x.2 + y.2, x.3 + y.3), (4, 4, 2, 2), "{a_text}\n{b_text}");
    assert!(timeless_results(&dir.join("a")) == fresh);
    assert!(timeless_results(&dir.join("b")) == fresh);
    std::fs::remove_dir_all(&dir).ok();
}
