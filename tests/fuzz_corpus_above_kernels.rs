//! Replays the committed corpora of the fuzz targets above the kernels (`fuzz/corpus/<target>/*`:
//! the scene loaders, image decoding, the eval cache) through the entry points
//! the cargo-fuzz targets call, so every `cargo test` re-checks what the fuzzer found
//! interesting, former crashes included. The kernels' corpora (the
//! rasterisers' among them) replay in `kernels/tests/fuzz_corpus.rs`.

use std::path::PathBuf;

use stereotrace::kernels::fuzzing::replay_dir;

fn replay(target: &str, run: fn(&[u8])) {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fuzz/corpus").join(target);
    replay_dir(&dir, 8, run);
}

#[test]
fn scene_folder_corpus() {
    replay("scene_folder", stereotrace::fuzzing::scene_folder);
}

#[test]
fn gltf_corpus() {
    replay("gltf", stereotrace::fuzzing::gltf);
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
