//! # stereotrace-runtime
//!
//! What an engine embeds from stereotrace: scenes and their loaders, the BVH tracer, the
//! traced and rasterised G-buffer passes, and the per-frame stereo pipeline (reprojection,
//! accumulation, the budget planner) over the hand-vectorized kernels of
//! `stereotrace-kernels`, re-exported as [`kernels`]. The CLI and the evaluation harness
//! live in the `stereotrace` crate on top; nothing here depends on them, so this crate
//! pulls in no argument parser, progress bar or plotting library (the optional `clap`
//! feature only derives `clap::ValueEnum` on the pipeline's option enums).

#![warn(missing_docs)]

pub use stereotrace_kernels as kernels;

pub mod camera;
pub mod cpu;
pub mod engine;
pub mod image_io;
pub mod pipeline;
pub mod render;
pub mod scene;
pub mod session;
pub mod source;
