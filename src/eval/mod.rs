//! The evaluation harness: effective spp of the pipeline's modes against path tracing,
//! after the paper's Sections III–IV.
//!
//! For every scene, pipeline variant (mode and order) and input spp, the pipeline runs
//! frames `0..frames` and its **left eye** is measured on the evaluated frames
//! `warmup..frames` (the paper: 60 frames, the first 10 warm-up) against a high-spp
//! reference of the same frame and eye. Each error is turned into an effective spp on that
//! frame's error curve of purely path-traced frames ([`effective`]), and the frames are
//! summarised as mean ± sample std per scene and over scenes ([`stats`]).
//!
//! | piece | module |
//! |---|---|
//! | error curves, the effective spp and its non-monotone policy | [`effective`] |
//! | progressive references and curves | [`curve`] |
//! | mean ± std with out-of-range frames as bounds | [`stats`] |
//! | the on-disk cache (keys, atomic writes, checksums) | [`cache`] |
//! | claims: concurrent shards compute each entry once | [`claim`] |
//! | work units, their cost, shards of them | [`units`] |
//! | the run: planning, caching, progress, resuming | [`run`] |
//! | the paper's numbers | [`paper`] |
//! | tables (Markdown, CSV), JSON, figures | [`report`], [`plots`] |
//!
//! # Seeds
//! Three independent random streams ([`Seeds`]): the pipeline's, the comparison curves' and
//! the references'. The curves are independent of the reference (as the paper requires) and
//! of the evaluated frames, whose path-traced pixels would otherwise be the curve's own
//! samples.

pub mod cache;
pub mod claim;
pub mod curve;
pub mod effective;
pub mod paper;
pub mod plots;
pub mod probes;
pub mod report;
pub mod results;
pub mod run;
pub mod spec;
pub mod stats;
pub mod units;

pub use effective::{EffectiveSpp, ErrorCurve, Grid, Metric};
pub use results::{EvalOutcome, WorkCounters};
pub use run::{Reporter, evaluate};
pub use spec::{EvalSpec, FigureSpec, Preset, REAL_SCENES, Seeds, SsimChoice, Variant};
