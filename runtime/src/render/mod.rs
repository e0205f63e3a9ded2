//! Rendering: the BVH, the G-buffer pass and the path tracer with the paper's estimator.
//!
//! # The estimator (one sample)
//! One primary ray, one secondary ray, two shadow rays:
//! 1. the primary ray through a jittered point of the pixel; emission it sees counts (and
//!    the environment and sun where it escapes);
//! 2. next-event estimation at the primary hit: one light record chosen by power, one point
//!    on it, shadow ray 1;
//! 3. one BSDF-sampled secondary ray;
//! 4. next-event estimation at the secondary hit: shadow ray 2.
//!
//! Emission reached by the secondary ray (an emitter, the sun, the environment) counts only
//! where next-event estimation could not have sampled it, i.e. after a delta (mirror) lobe;
//! otherwise it would be counted twice. The result is an unbiased estimate of transport over
//! paths with up to two bounces. A mirror at the primary hit gets no next-event estimate (a
//! delta lobe has zero value towards any sampled light).
//!
//! # Specialisation
//! Every per-sample function is generic over the effect bits `E` ([`effects`]); the public
//! entry points dispatch on the scene's bits, or on [`effects::ALL`] for the general
//! integrator, which must give the same image.
//!
//! # Tracing
//! [`Renderer::trace`] runs the estimator on groups of eight pixels stage by stage and traces
//! the coherent stages (primary rays, shadow rays from the primary hits) as 8-lane packets
//! (module `packets`); [`Renderer::trace_single_rays`] is the single-ray reference
//! (`Renderer::radiance`, one pixel and sample at a time). Both give the same image except
//! where a ray hits two triangles at exactly the same distance.
//!
//! # Determinism
//! Random numbers are a pure function of (seed, eye, frame, pixel, sample, purpose)
//! ([`rng`]); rows run in parallel but each pixel's value depends only on its own numbers,
//! so images are identical across runs and thread counts.

pub mod bsdf;
pub mod effects;
mod estimator;
mod gbuffer;
pub mod lights;
mod packets;
pub mod raster;
mod renderer;
pub mod rng;
pub mod source;
pub mod spawn;
mod trace;
mod view;

pub use crate::kernels::gbuffer::GBufferBuf;
pub use lights::MOVING_LIGHT_MATERIAL;
pub use renderer::{RenderError, Renderer, pixel_centre_ray};
pub use source::{FirstSample, GBufferPass, RendererOptions, RendererSource};
pub use trace::PrimaryRays;
pub use view::FrameView;
