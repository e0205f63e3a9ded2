//! Everything an engine names to drive the pipeline over its own G-buffers and tracer, in one
//! module: the pipeline ([`Pipeline`], its configuration and statistics), the seam it
//! implements ([`FrameSource`] and the types of its calls) and the buffers and cameras both
//! speak. Nothing here is new: each item is re-exported from the module that defines it.
//! `runtime/examples/embed.rs` is a complete engine written against this module alone.

pub use crate::camera::Eye;
pub use crate::kernels::reproject::{Reason, Tolerances};
pub use crate::kernels::{CameraModel, Extent, FrameError, GBufferBuf, PlaneBuf, RgbBuf};
pub use crate::pipeline::{FrameStats, GBufferView, Mode, Order, Pipeline, PipelineConfig, StageTimes};
pub use crate::source::{
    FrameSource, Layout, PipelineError, PixelSelection, RasterPassStats, TraceRequest, TraceStats,
};
