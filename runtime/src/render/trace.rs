//! The trace loops: the public entry points (`Renderer::trace`, `trace_rows`,
//! `trace_single_rays`), their checks, and the two loops over rows (the packet loop and the
//! single-ray reference) that share one schedule.

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use crate::kernels::bvh::Ray;
use crate::kernels::raster::VisibilityBuffer;
use crate::kernels::simd::LANES;
use crate::kernels::{CameraModel, RgbBuf};
use crate::source::{PixelSelection, TraceRequest, TraceStats};

use super::effects;
use super::lights::FrameLights;
use super::packets;
use super::renderer::{RenderError, Renderer};
use super::rng::{Dim, SampleStream};

/// Where each pixel's first sample (sample index 0 of a frame) starts, and how its primary
/// hit is found. Every other sample is jittered.
#[derive(Clone, Copy, Debug, Default)]
pub enum PrimaryRays<'a> {
    /// Through a uniformly jittered point of the pixel, traced (the paper's estimator).
    #[default]
    Jittered,
    /// Through the pixel centre, traced.
    Centre,
    /// Through the pixel centre, its hit read from this visibility buffer of the same camera
    /// and frame (the rasterised G-buffer pass's): the triangle the buffer names, intersected
    /// by the centre ray with the tracer's own watertight test, so the hit equals
    /// [`PrimaryRays::Centre`]'s wherever the raster saw the traced triangle (everywhere but
    /// depth ties). A pixel whose test misses its triangle (an edge function of exactly 0) is
    /// traced. Nothing else changes: the rest of the sample uses its own random numbers.
    CentreVisible(&'a VisibilityBuffer),
}

impl PrimaryRays<'_> {
    /// Whether sample `index` (counted from the frame's first) goes through the pixel centre.
    #[inline]
    pub(super) fn centred(&self, index: u32) -> bool {
        index == 0 && !matches!(self, PrimaryRays::Jittered)
    }

    /// Where in its pixel sample `index` goes, in [0, 1)²: the centre or the sample's own
    /// jitter (the one definition both row loops use).
    #[inline]
    pub(super) fn pixel_offset(&self, index: u32, rng: &SampleStream) -> glam::Vec2 {
        if self.centred(index) { glam::Vec2::splat(0.5) } else { rng.get2(Dim::PixelJitter) }
    }
}

/// How a tracing call traces its rays.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kernel {
    /// Groups of up to eight pixels, each stage of the estimator traced as one packet
    /// ([`packets`]).
    Packets,
    /// The single-ray reference.
    SingleRays,
}

impl Renderer {
    /// Path traces `request.spp` samples into `out` for the pixels `selection` names, with the
    /// integrator specialised for the scene's effects (`general = false`) or the general one.
    pub fn trace(
        &self,
        lights: &FrameLights,
        camera: &CameraModel,
        request: &TraceRequest,
        selection: PixelSelection<'_>,
        out: &mut RgbBuf,
        general: bool,
    ) -> Result<TraceStats, RenderError> {
        self.trace_rows(lights, camera, request, selection, 0..camera.extent.height(), out, general)
    }

    /// [`Renderer::trace`] restricted to the rows `rows` (the budgeted runtime traces the
    /// frame in row tiles).
    #[allow(clippy::too_many_arguments)]
    pub fn trace_rows(
        &self,
        lights: &FrameLights,
        camera: &CameraModel,
        request: &TraceRequest,
        selection: PixelSelection<'_>,
        rows: std::ops::Range<usize>,
        out: &mut RgbBuf,
        general: bool,
    ) -> Result<TraceStats, RenderError> {
        self.trace_rows_from(lights, camera, request, selection, rows, out, general, PrimaryRays::Jittered)
    }

    /// [`Renderer::trace_rows`] with each pixel's first sample started as `primary` says.
    /// Fails if a visibility buffer's extent is not the camera's.
    #[allow(clippy::too_many_arguments)]
    pub fn trace_rows_from(
        &self,
        lights: &FrameLights,
        camera: &CameraModel,
        request: &TraceRequest,
        selection: PixelSelection<'_>,
        rows: std::ops::Range<usize>,
        out: &mut RgbBuf,
        general: bool,
        primary: PrimaryRays<'_>,
    ) -> Result<TraceStats, RenderError> {
        if let PrimaryRays::CentreVisible(vis) = primary {
            crate::kernels::frame::same_extent("visibility buffer", camera.extent, vis.extent())?;
        }
        self.trace_with(lights, camera, request, selection, rows, out, general, Kernel::Packets, primary)
    }

    /// [`Renderer::trace`] by the single-ray reference loop: every ray traced alone, one
    /// pixel and sample at a time. It computes the same estimator with the same random
    /// numbers, so images equal [`Renderer::trace`]'s except where a ray hits two triangles at
    /// exactly the same distance (packet and single-ray traversal may pick different ones).
    /// The oracle for the packet loop's tests, and its bench baseline.
    pub fn trace_single_rays(
        &self,
        lights: &FrameLights,
        camera: &CameraModel,
        request: &TraceRequest,
        selection: PixelSelection<'_>,
        out: &mut RgbBuf,
        general: bool,
    ) -> Result<TraceStats, RenderError> {
        let rows = 0..camera.extent.height();
        self.trace_with(
            lights,
            camera,
            request,
            selection,
            rows,
            out,
            general,
            Kernel::SingleRays,
            PrimaryRays::Jittered,
        )
    }

    /// [`Renderer::trace_single_rays`] with each pixel's first sample through its centre
    /// ([`PrimaryRays::Centre`]): every primary ray traced, the oracle of
    /// [`PrimaryRays::CentreVisible`].
    pub fn trace_single_rays_centred(
        &self,
        lights: &FrameLights,
        camera: &CameraModel,
        request: &TraceRequest,
        selection: PixelSelection<'_>,
        out: &mut RgbBuf,
    ) -> Result<TraceStats, RenderError> {
        let rows = 0..camera.extent.height();
        self.trace_with(lights, camera, request, selection, rows, out, false, Kernel::SingleRays, PrimaryRays::Centre)
    }

    #[allow(clippy::too_many_arguments)]
    fn trace_with(
        &self,
        lights: &FrameLights,
        camera: &CameraModel,
        request: &TraceRequest,
        selection: PixelSelection<'_>,
        rows: std::ops::Range<usize>,
        out: &mut RgbBuf,
        general: bool,
        kernel: Kernel,
        primary: PrimaryRays<'_>,
    ) -> Result<TraceStats, RenderError> {
        crate::kernels::frame::same_extent("output image", camera.extent, out.extent())?;
        if rows.start > rows.end || rows.end > camera.extent.height() {
            return Err(RenderError::Invalid(format!(
                "rows {}..{} outside the image height {}",
                rows.start,
                rows.end,
                camera.extent.height()
            )));
        }
        if let PixelSelection::Mask(m) = selection {
            crate::kernels::frame::same_extent("pixel mask", camera.extent, m.extent())?;
        }
        if request.spp == 0 {
            return Err(RenderError::Invalid("samples per pixel must be at least 1".into()));
        }
        let bits = if general { effects::ALL } else { self.bits };
        macro_rules! call {
            ($e:literal) => {
                match kernel {
                    Kernel::Packets => self.trace_pass::<$e>(lights, camera, request, selection, rows, out, primary),
                    Kernel::SingleRays => {
                        self.trace_pass_single::<$e>(lights, camera, request, selection, rows, out, primary)
                    }
                }
            };
        }
        Ok(crate::dispatch_effects!(bits, call))
    }

    /// The packet loop: each row's selected pixels in groups of eight, each stage of a
    /// sample traced as one packet ([`packets`]). Rows run in parallel.
    #[allow(clippy::too_many_arguments)]
    fn trace_pass<const E: u16>(
        &self,
        lights: &FrameLights,
        camera: &CameraModel,
        request: &TraceRequest,
        selection: PixelSelection<'_>,
        rows: std::ops::Range<usize>,
        out: &mut RgbBuf,
        primary: PrimaryRays<'_>,
    ) -> TraceStats {
        let width = camera.extent.width();
        let pass = packets::Pass { lights, camera, request, primary };
        for_each_row(selection, rows, out, |y, mask_row, [rr, gr, br]| {
            let mut stats = TraceStats::default();
            let mut next = 0;
            loop {
                // The next (up to) eight selected pixels of the row; unused lanes repeat
                // the last one but stay inactive.
                let mut xs = [0usize; LANES];
                let mut n = 0;
                while next < width && n < LANES {
                    if mask_row.is_none_or(|m| m[next] != 0) {
                        xs[n] = next;
                        n += 1;
                    }
                    next += 1;
                }
                if n == 0 {
                    break;
                }
                for k in n..LANES {
                    xs[k] = xs[n - 1];
                }
                let active = (1u32 << n) - 1;
                let mut sums = [PixelSum::default(); LANES];
                for s in 0..request.spp {
                    let l = self.sample_group::<E>(&pass, y, &xs, active, s, &mut stats.rays);
                    for k in 0..n {
                        sums[k].add(l[k], &mut stats);
                    }
                }
                for k in 0..n {
                    let x = xs[k];
                    [rr[x], gr[x], br[x]] = sums[k].mean(request.spp);
                }
            }
            stats
        })
    }

    /// The single-ray reference loop: one pixel and sample at a time through
    /// [`Renderer::radiance`].
    #[allow(clippy::too_many_arguments)]
    fn trace_pass_single<const E: u16>(
        &self,
        lights: &FrameLights,
        camera: &CameraModel,
        request: &TraceRequest,
        selection: PixelSelection<'_>,
        rows: std::ops::Range<usize>,
        out: &mut RgbBuf,
        primary: PrimaryRays<'_>,
    ) -> TraceStats {
        let width = camera.extent.width();
        let origin = Vec3::from(camera.centre);
        for_each_row(selection, rows, out, |y, mask_row, [rr, gr, br]| {
            let mut stats = TraceStats::default();
            for x in 0..width {
                if mask_row.is_some_and(|m| m[x] == 0) {
                    continue;
                }
                let pixel = (y * width + x) as u32;
                let mut sum = PixelSum::default();
                for s in 0..request.spp {
                    let rng = SampleStream::new(
                        request.seed,
                        request.eye as u32,
                        request.frame,
                        pixel,
                        request.first_sample + s,
                    );
                    // The reference traces every primary ray, centred or not.
                    let j = primary.pixel_offset(request.first_sample + s, &rng);
                    let dir = Vec3::from(camera.ray(x as f32 + j.x, y as f32 + j.y));
                    let l = self.radiance::<E>(lights, Ray::new(origin, dir), &rng, &mut stats.rays);
                    sum.add(l, &mut stats);
                }
                [rr[x], gr[x], br[x]] = sum.mean(request.spp);
            }
            stats
        })
    }
}

/// The running sum of one pixel's samples, in f64: a mean of finite f32 samples is finite,
/// but their f32 sum is not (16 samples of 5e37 overflow), which wrote inf pixels.
#[derive(Clone, Copy, Default)]
struct PixelSum(DVec3);

impl PixelSum {
    /// Adds a sample; a non-finite one counts as zero and is counted in `stats`.
    #[inline]
    pub(super) fn add(&mut self, sample: Vec3, stats: &mut TraceStats) {
        stats.samples += 1;
        if sample.is_finite() {
            self.0 += sample.as_dvec3();
        } else {
            stats.non_finite += 1;
        }
    }

    /// The mean over `spp` samples.
    #[inline]
    pub(super) fn mean(&self, spp: u32) -> [f32; 3] {
        (self.0 / f64::from(spp)).as_vec3().to_array()
    }
}

/// Runs `row` on each row of `rows` in parallel, with that row's selection mask (`None`:
/// every pixel) and its three colour rows of `out`, and sums the rows' statistics: the
/// schedule the packet loop and the single-ray reference share.
fn for_each_row<F>(selection: PixelSelection<'_>, rows: std::ops::Range<usize>, out: &mut RgbBuf, row: F) -> TraceStats
where
    F: Fn(usize, Option<&[u8]>, [&mut [f32]; 3]) -> TraceStats + Sync + Send,
{
    let width = out.extent().width();
    let span = rows.start * width..rows.end * width;
    let [r, g, b] = out.slices_mut();
    (r[span.clone()].par_chunks_mut(width), g[span.clone()].par_chunks_mut(width), b[span].par_chunks_mut(width))
        .into_par_iter()
        .enumerate()
        .map(|(i, (rr, gr, br))| {
            let y = rows.start + i;
            let mask_row = match selection {
                PixelSelection::All => None,
                PixelSelection::Mask(m) => Some(m.view().row(y)),
            };
            row(y, mask_row, [rr, gr, br])
        })
        .sum()
}
