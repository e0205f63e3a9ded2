//! # stereotrace
//!
//! Real-time stereoscopic path tracing with spatiotemporal sample reprojection, after
//! Mäkitalo, Kivi and Jääskeläinen (IEEE Access 2020): the CLI's commands and the
//! evaluation harness. They sit on two crates an engine can take alone:
//! `stereotrace-kernels` (the hand-vectorized kernels, re-exported as [`kernels`]) and
//! `stereotrace-runtime` (scenes, tracing, G-buffers and the frame pipeline, whose modules
//! are re-exported here under their own names). Imports flow one way:
//! kernels ← runtime ← harness ← CLI.

#![warn(missing_docs)]

pub use stereotrace_runtime::{camera, cpu, image_io, kernels, pipeline, render, scene, session, source};

pub mod commands;
pub mod eval;
pub mod fuzzing;
pub mod viewer;
