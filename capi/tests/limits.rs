//! Every limit the C ABI enforces is an exported constant, the header states it with the
//! same value, and validation refuses exactly past it: the value at each limit is accepted,
//! the next one refused with a message naming the limit.

// These call the C ABI on pointers made a few lines before each call, as a C caller would;
// what each call requires is its documentation in the header.
#![allow(clippy::undocumented_unsafe_blocks)]

mod common;

use common::{RoomEngine, camera, expect};
use stereotrace_capi::*;

/// The value of `#define NAME value` in the committed header.
fn header_define(name: &str) -> String {
    let header = include_str!("../include/stereotrace.h");
    let prefix = format!("#define {name} ");
    let line = header.lines().find(|l| l.starts_with(&prefix)).unwrap_or_else(|| panic!("{name} is not in the header"));
    line[prefix.len()..].trim().to_owned()
}

#[test]
fn the_header_states_every_limit_with_the_value_validation_uses() {
    for (name, value) in [
        ("STEREOTRACE_MAX_DIMENSION", f64::from(STEREOTRACE_MAX_DIMENSION)),
        ("STEREOTRACE_MAX_PIXELS", STEREOTRACE_MAX_PIXELS as f64),
        ("STEREOTRACE_MAX_STRIDE", f64::from(STEREOTRACE_MAX_STRIDE)),
        ("STEREOTRACE_MAX_THREADS", f64::from(STEREOTRACE_MAX_THREADS)),
        ("STEREOTRACE_MAX_SPP", f64::from(STEREOTRACE_MAX_SPP)),
        ("STEREOTRACE_MAX_BUDGET_MS", STEREOTRACE_MAX_BUDGET_MS),
        ("STEREOTRACE_SSIM_MIN_SIDE", f64::from(STEREOTRACE_SSIM_MIN_SIDE)),
        ("ST_REASON_COUNT", ST_REASON_COUNT as f64),
    ] {
        let stated: f64 = header_define(name).parse().unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(stated, value, "{name}");
    }
    // And the kernels' and the runtime's own (the crate also asserts these at compile time).
    assert_eq!(STEREOTRACE_MAX_DIMENSION as usize, stereotrace_kernels::frame::MAX_DIMENSION);
    assert_eq!(STEREOTRACE_MAX_PIXELS as usize, stereotrace_kernels::frame::MAX_PIXELS);
    assert_eq!(STEREOTRACE_MAX_STRIDE as usize, stereotrace_kernels::frame::MAX_STRIDE);
    assert_eq!(STEREOTRACE_MAX_SPP, stereotrace_runtime::pipeline::MAX_SPP);
    assert_eq!(STEREOTRACE_MAX_BUDGET_MS, stereotrace_runtime::pipeline::MAX_BUDGET_MS);
    assert_eq!(STEREOTRACE_SSIM_MIN_SIDE as usize, stereotrace_kernels::ssim::MIN_SIDE);
}

/// Creates a callback pipeline of `width`×`height` with `edit` applied to the config.
fn create(width: u32, height: u32, edit: impl Fn(&mut StPipelineConfig)) -> (StStatus, String) {
    let mut engine = RoomEngine::new();
    let callbacks = engine.callbacks();
    let mut config = stereotrace_pipeline_config_default();
    (config.width, config.height, config.threads) = (width, height, 1);
    edit(&mut config);
    let cameras = [camera(-0.03, width.max(1), height.max(1)), camera(0.03, width.max(1), height.max(1))];
    let mut p = std::ptr::null_mut();
    let status = unsafe { stereotrace_pipeline_create_callbacks(&callbacks, &config, cameras.as_ptr(), &mut p) };
    let message = common::last_error();
    if !p.is_null() {
        expect(unsafe { stereotrace_pipeline_destroy(p) }, StStatus::Ok);
    }
    (status, message)
}

#[test]
fn frame_sizes_up_to_the_dimension_and_pixel_limits() {
    let max = STEREOTRACE_MAX_DIMENSION;
    assert_eq!(create(max, 1, |_| ()).0, StStatus::Ok);
    assert_eq!(create(1, max, |_| ()).0, StStatus::Ok);
    for (w, h) in [(max + 1, 1), (1, max + 1)] {
        let (status, message) = create(w, h, |_| ());
        assert_eq!(status, StStatus::InvalidArgument, "{message}");
        assert!(message.contains("at most 32768 per side"), "{message}");
    }
    // 16384 × 16385 is one row past STEREOTRACE_MAX_PIXELS (16384² itself is accepted and
    // allocated: tests/out_of_memory.rs).
    let (status, message) = create(16384, 16385, |_| ());
    assert_eq!(status, StStatus::InvalidArgument, "{message}");
    assert!(message.contains("268435456 pixels"), "{message}");
}

#[test]
fn strides_up_to_the_stride_limit() {
    let ctx = {
        let mut ctx = std::ptr::null_mut();
        expect(unsafe { stereotrace_context_create(1, &mut ctx) }, StStatus::Ok);
        ctx
    };
    let (w, h) = (4u32, 2u32);
    for stride in [STEREOTRACE_MAX_STRIDE, STEREOTRACE_MAX_STRIDE + 1] {
        let len = (stride + w) as usize;
        let new: Vec<Vec<f32>> = vec![vec![1.0; len]; 3];
        let mut accum: [Vec<f32>; 3] = [vec![0.0; len], vec![0.0; len], vec![0.0; len]];
        let reasons = vec![0u8; len];
        let plane = |p: &Vec<f32>| StPlaneF32 { data: p.as_ptr(), width: w, height: h, stride };
        let new_c = StRgb { r: plane(&new[0]), g: plane(&new[1]), b: plane(&new[2]) };
        let [r, g, b] = accum.each_mut().map(|p| StPlaneMutF32 { data: p.as_mut_ptr(), width: w, height: h, stride });
        let accum_c = StRgbMut { r, g, b };
        let reason = StPlaneU8 { data: reasons.as_ptr(), width: w, height: h, stride };
        let status = unsafe {
            stereotrace_ema(
                ctx,
                &new_c,
                &reason,
                std::ptr::null(),
                std::ptr::null(),
                &accum_c,
                std::ptr::null(),
                std::ptr::null(),
                std::ptr::null_mut(),
            )
        };
        if stride == STEREOTRACE_MAX_STRIDE {
            expect(status, StStatus::Ok);
        } else {
            let message = expect(status, StStatus::InvalidArgument);
            assert!(message.contains("131073"), "{message}");
        }
    }
    expect(unsafe { stereotrace_context_destroy(ctx) }, StStatus::Ok);
}

#[test]
fn threads_up_to_the_thread_limit() {
    let mut ctx = std::ptr::null_mut();
    let message =
        expect(unsafe { stereotrace_context_create(STEREOTRACE_MAX_THREADS + 1, &mut ctx) }, StStatus::InvalidArgument);
    assert!(message.contains("STEREOTRACE_MAX_THREADS (1024)"), "{message}");
    assert!(ctx.is_null());
    let (status, message) = create(8, 8, |c| c.threads = STEREOTRACE_MAX_THREADS + 1);
    assert_eq!(status, StStatus::InvalidArgument, "{message}");
    assert!(message.contains("config.threads must be at most STEREOTRACE_MAX_THREADS (1024)"), "{message}");
    expect(unsafe { stereotrace_context_create(STEREOTRACE_MAX_THREADS, &mut ctx) }, StStatus::Ok);
    expect(unsafe { stereotrace_context_destroy(ctx) }, StStatus::Ok);
}

#[test]
fn spp_and_budget_up_to_their_limits() {
    assert_eq!(create(8, 8, |c| c.spp = STEREOTRACE_MAX_SPP).0, StStatus::Ok);
    let (status, message) = create(8, 8, |c| c.spp = STEREOTRACE_MAX_SPP + 1);
    assert_eq!(status, StStatus::InvalidArgument, "{message}");
    assert!(message.contains("STEREOTRACE_MAX_SPP (1048576)"), "{message}");
    assert_eq!(create(8, 8, |c| c.spp = 0).0, StStatus::InvalidArgument);

    assert_eq!(create(8, 8, |c| c.budget_ms = STEREOTRACE_MAX_BUDGET_MS).0, StStatus::Ok);
    assert_eq!(create(8, 8, |c| c.budget_ms = 0.0).0, StStatus::Ok, "0 is no budget");
    assert_eq!(create(8, 8, |c| c.budget_ms = f64::MIN_POSITIVE).0, StStatus::Ok);
    for bad in [STEREOTRACE_MAX_BUDGET_MS.next_up(), -1.0, f64::NAN, f64::INFINITY] {
        let (status, message) = create(8, 8, |c| c.budget_ms = bad);
        assert_eq!(status, StStatus::InvalidArgument, "{bad}: {message}");
        assert!(message.contains("at most 1000000 ms"), "{message}");
    }
}
