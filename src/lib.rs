//! # stereotrace
//!
//! Real-time stereoscopic path tracing with spatiotemporal sample reprojection, after
//! Mäkitalo, Kivi and Jääskeläinen (IEEE Access 2020): scenes, BVH and tracing, the per-frame
//! pipelines, the evaluation harness and the CLI. The hand-vectorized kernels live in the
//! `stereotrace-kernels` crate, re-exported as [`kernels`].

pub use stereotrace_kernels as kernels;

pub mod camera;
pub mod commands;
pub mod cpu;
pub mod eval;
pub mod image_io;
pub mod pipeline;
pub mod render;
pub mod scene;
