//! Replays the committed corpora of the fuzz targets above the kernels (`fuzz/corpus/<target>/*`:
//! the rasteriser, the scene loaders, image decoding, the eval cache) through the entry points
//! the cargo-fuzz targets call, so every `cargo test` re-checks what the fuzzer found
//! interesting, former crashes included. The kernels' corpora replay in
//! `kernels/tests/fuzz_corpus.rs`.

use std::path::PathBuf;

fn replay(target: &str, run: fn(&[u8])) {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fuzz/corpus").join(target);
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
fn raster_corpus() {
    replay("raster", stereotrace::fuzzing::raster);
}

#[test]
fn scene_folder_corpus() {
    replay("scene_folder", stereotrace::fuzzing::scene_folder);
}

#[test]
fn manifest_corpus() {
    replay("manifest", stereotrace::fuzzing::manifest);
}

#[test]
fn image_corpus() {
    replay("image", stereotrace::fuzzing::image);
}

#[test]
fn cache_entry_corpus() {
    replay("cache_entry", stereotrace::fuzzing::cache_entry);
}

/// An open raster bug the fuzzer found with vertices up to 10³ units from the origin (the
/// target now keeps them within 100): at one pixel the raster shows a sliver 1.91 units away
/// while two triangles in front of it (f64: 0.46 and 0.76; the tracer: 0.76) are not shown.
/// `cargo test --release --test fuzz_corpus -- --ignored` replays it; see RELIABILITY.md.
#[test]
#[ignore = "open raster bug: a far sliver shown in front of nearer triangles (RELIABILITY.md)"]
fn raster_known_failures() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fuzz/known/raster");
    for entry in std::fs::read_dir(&dir).expect("known failures").flatten() {
        let data = std::fs::read(entry.path()).expect("readable input");
        let result = std::panic::catch_unwind(|| stereotrace::fuzzing::raster_within(&data, 1e3));
        assert!(result.is_ok(), "{} fails", entry.path().display());
    }
}
