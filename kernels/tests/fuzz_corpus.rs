//! Replays the committed fuzz seed corpus (`fuzz/corpus/<target>/*`) through the same
//! entry points the cargo-fuzz targets call, so every `cargo test` re-checks what the
//! fuzzer found interesting (including former crashes kept as regression seeds).

use std::path::PathBuf;

fn replay(target: &str, run: fn(&[u8])) {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../fuzz/corpus").join(target);
    let mut entries: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("seed corpus {} is missing: {e}", dir.display()))
        .map(|entry| entry.expect("readable corpus entry").path())
        .collect();
    entries.sort();
    assert!(entries.len() >= 8, "corpus {} has only {} seeds", dir.display(), entries.len());
    for path in entries {
        let data = std::fs::read(&path).expect("readable seed");
        let result = std::panic::catch_unwind(|| run(&data));
        assert!(result.is_ok(), "seed {} fails", path.display());
    }
}

#[test]
fn reproject_corpus() {
    replay("reproject", stereotrace_kernels::fuzzing::reproject);
}

#[test]
fn bilinear_corpus() {
    replay("bilinear", stereotrace_kernels::fuzzing::bilinear);
}

#[test]
fn accumulate_corpus() {
    replay("accumulate", stereotrace_kernels::fuzzing::accumulate);
}

#[test]
fn ssim_corpus() {
    replay("ssim", stereotrace_kernels::fuzzing::ssim);
}

#[test]
fn bvh_corpus() {
    replay("bvh", stereotrace_kernels::fuzzing::bvh);
}
