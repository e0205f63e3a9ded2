//! An engine may ask for any frame size the limits allow (16384 × 16384 is one), and a host
//! under a memory limit must get a status back, not a SIGABRT. The parent test runs the
//! ignored child test in a new process under a 6 GiB address-space limit (`ulimit -v`), where
//! such a pipeline cannot be allocated: every create returns `ST_STATUS_OUT_OF_MEMORY`, and the
//! process goes on to build and render a small pipeline.

// These call the C ABI on pointers made a few lines before each call, as a C caller would;
// what each call requires is its documentation in the header.
#![allow(clippy::undocumented_unsafe_blocks)]

mod common;

use std::process::Command;

use common::{RoomEngine, camera, expect, room_pipeline};
use stereotrace_capi::*;

/// 6 GiB, in the KiB `ulimit -v` counts.
const LIMIT_KIB: u64 = 6 * 1024 * 1024;

#[test]
fn a_16k_pipeline_under_a_6_gib_address_space_limit_returns_out_of_memory() {
    let exe = std::env::current_exe().expect("the test binary's path");
    let out = Command::new("bash")
        .arg("-c")
        .arg(format!(
            "ulimit -v {LIMIT_KIB} && exec \"$0\" --exact child_under_the_limit --include-ignored --nocapture"
        ))
        .arg(exe)
        .output()
        .expect("bash runs");
    let (stdout, stderr) = (String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success(), "the child died or failed ({:?}):\n{stdout}\n{stderr}", out.status);
    assert!(stdout.contains("1 passed"), "the child test did not run:\n{stdout}");
    assert!(stdout.contains("lives on after OUT_OF_MEMORY"), "{stdout}");
}

#[test]
#[ignore = "run by the test above, in a process under an address-space limit"]
fn child_under_the_limit() {
    const SIDE: u32 = 16384;
    // A callback pipeline: the engine's own G-buffers and tracer.
    let mut engine = RoomEngine::new();
    let callbacks = engine.callbacks();
    let mut config = stereotrace_pipeline_config_default();
    (config.width, config.height, config.threads) = (SIDE, SIDE, 1);
    let cameras = [camera(-0.03, SIDE, SIDE), camera(0.03, SIDE, SIDE)];
    let mut p = std::ptr::null_mut();
    let status = unsafe { stereotrace_pipeline_create_callbacks(&callbacks, &config, cameras.as_ptr(), &mut p) };
    let message = expect(status, StStatus::OutOfMemory);
    assert!(message.contains("out of memory: could not allocate 1073741824 bytes"), "{message}");
    assert!(p.is_null(), "a refused create wrote a pipeline");

    // A scene pipeline of the same size (our renderer's buffers too).
    let status = unsafe { stereotrace_pipeline_create_scene(c"cornell".as_ptr(), &config, &mut p) };
    expect(status, StStatus::OutOfMemory);
    assert!(p.is_null());

    // The process lives on: a small pipeline renders; resized to 16K it refuses, and renders
    // on at its own size.
    let mut engine = RoomEngine::new();
    let p = room_pipeline(&mut engine, StMode::Spatiotemporal, 64, 36);
    let cameras = [camera(-0.03, 64, 36), camera(0.03, 64, 36)];
    let status = unsafe { stereotrace_pipeline_render_frame_at(p, 0, cameras.as_ptr(), std::ptr::null_mut()) };
    expect(status, StStatus::Ok);
    expect(unsafe { stereotrace_pipeline_resize(p, SIDE, SIDE) }, StStatus::OutOfMemory);
    let status = unsafe { stereotrace_pipeline_render_frame_at(p, 1, cameras.as_ptr(), std::ptr::null_mut()) };
    expect(status, StStatus::Ok);
    expect(unsafe { stereotrace_pipeline_destroy(p) }, StStatus::Ok);
    println!("lives on after OUT_OF_MEMORY");
}
