//! Replays the committed fuzz seed corpus (`fuzz/corpus/<target>/*`) through the same
//! entry points the cargo-fuzz targets call, so every `cargo test` re-checks what the
//! fuzzer found interesting (including former crashes kept as regression seeds).

use std::path::PathBuf;

use stereotrace_kernels::fuzzing::replay_dir;

fn replay(target: &str, run: fn(&[u8])) {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../fuzz/corpus").join(target);
    replay_dir(&dir, 8, run);
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
fn gradient_corpus() {
    replay("gradient", stereotrace_kernels::fuzzing::gradient);
}

#[test]
fn atrous_corpus() {
    replay("atrous", stereotrace_kernels::fuzzing::atrous);
}

#[test]
fn variance_blend_corpus() {
    replay("variance_blend", stereotrace_kernels::fuzzing::variance_blend);
}

#[test]
fn clamp_corpus() {
    replay("clamp", stereotrace_kernels::fuzzing::clamp);
}

#[test]
fn ssim_corpus() {
    replay("ssim", stereotrace_kernels::fuzzing::ssim);
}

#[test]
fn traverse_corpus() {
    replay("traverse", stereotrace_kernels::fuzzing::traverse);
}

#[test]
fn raster_corpus() {
    replay("raster", stereotrace_kernels::fuzzing::raster);
}

/// The fixed-point rasteriser decodes the same cases as the exact one: both corpora seed it.
#[test]
fn raster_fixed_corpus() {
    replay("raster_fixed", stereotrace_kernels::fuzzing::raster_fixed);
    replay("raster", stereotrace_kernels::fuzzing::raster_fixed);
}
