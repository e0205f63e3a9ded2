//! The kernels on caller buffers: each function checks its arguments into the kernels'
//! views (see `views`), runs the SIMD body on the context's threads and copies the
//! statistics out. The semantics are the kernels' own (`stereotrace-kernels` documents the
//! definitions: reprojection tests and reason codes, the EMA with history reset, the blend,
//! the paper's 3-D SSIM); nothing here computes anything of its own.

use glam::DMat4;
use stereotrace_kernels::accumulate::{self, AccumulateStats, BlendParams, EmaInput, EmaParams, EmaState};
use stereotrace_kernels::gbuffer::{SurfaceLayout, encode_normal};
use stereotrace_kernels::reproject::{
    self, REASON_COUNT, ReprojectInput, ReprojectOutput, ReprojectParams, TapPolicy, Tolerances,
};
use stereotrace_kernels::ssim::{self, SsimParams, SsimVariant};
use stereotrace_kernels::{CameraModel, CompactGBuffer, Extent, GBuffer};
use stereotrace_runtime::source::Layout;

use crate::boundary::{Context, Failure, StStatus, guard};
use crate::context::StContext;
use crate::views::{
    Borrows, StPlaneF32, StPlaneMutF32, StPlaneMutU8, StPlaneU8, StPlaneU32, StRgb, StRgbMut, required,
};

/// A perspective camera as the kernels see it: `clip = view_proj · (X, 1)` with clip `w`
/// equal to the view-axis depth of `X` (what a right- or left-handed perspective matrix
/// times a view matrix gives); normalised device coordinates run from −1 (left, bottom) to
/// +1 (right, top); pixel `(i, j)` has its centre at `(i + 0.5, j + 0.5)`, rows counted from
/// the top. Singular, non-finite and non-pinhole (orthographic) matrices are refused.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct StCamera {
    /// The view-projection matrix, column-major (`view_proj[4 * column + row]`), in double
    /// precision so a camera far from the origin keeps its exact position.
    pub view_proj: [f64; 16],
    /// The frame width this camera renders, in pixels.
    pub width: u32,
    /// The frame height this camera renders, in pixels.
    pub height: u32,
}

impl StCamera {
    /// The validated camera (`what` names it in errors).
    pub(crate) fn model(&self, what: &str) -> Result<CameraModel, Failure> {
        let extent = Extent::new(self.width as usize, self.height as usize).about(what)?;
        CameraModel::from_f64(DMat4::from_cols_array(&self.view_proj), extent).about(what)
    }
}

/// How a G-buffer stores its surfaces: the values of [`StGBuffer::layout`]. (Enum values
/// cross the boundary as `uint32_t` and are checked: an out-of-range value from C is
/// refused, not undefined behaviour.)
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StLayout {
    /// Seven float planes: `depth`, `position[3]` (world xyz), `normal[3]` (world xyz).
    Full = 0,
    /// `depth` and `normal_octahedral` (see `stereotrace_encode_normal`); positions are
    /// rebuilt from depth through `camera`. 8 bytes per pixel instead of 28: the fast one.
    Compact = 1,
}

impl StLayout {
    /// The runtime's [`Layout`] of a `StLayout` value from C (`what` names the field): the
    /// one place the C ABI reads a layout, for the kernels and the pipeline alike.
    pub(crate) fn parse(value: u32, what: &str) -> Result<Layout, Failure> {
        match value {
            v if v == StLayout::Full as u32 => Ok(Layout::Full),
            v if v == StLayout::Compact as u32 => Ok(Layout::Compact),
            other => Err(Failure::invalid(format!("{what} {other} is not a StLayout (0 or 1)"))),
        }
    }
}

/// One eye's G-buffer for one frame: per pixel, the surface the pixel-centre ray hit.
/// `depth` is the view-axis depth (`+INFINITY` where the ray hit nothing). The planes a
/// layout does not use are ignored (their pointers may be null).
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct StGBuffer {
    /// A `StLayout` value.
    pub layout: u32,
    /// View-axis depth of the surface (`+INFINITY`: none).
    pub depth: StPlaneF32,
    /// `ST_LAYOUT_FULL` only: world x, y, z.
    pub position: [StPlaneF32; 3],
    /// `ST_LAYOUT_FULL` only: world x, y, z (need not be unit length).
    pub normal: [StPlaneF32; 3],
    /// `ST_LAYOUT_COMPACT` only: `stereotrace_encode_normal` of each pixel's normal.
    pub normal_octahedral: StPlaneU32,
    /// The camera that rendered this G-buffer (its extent must be the planes').
    pub camera: StCamera,
}

/// What to do with a pixel some of whose bilinear taps failed: the values of
/// [`StReprojectParams::policy`].
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StTapPolicy {
    /// Keep the accepted taps and renormalise their weights (the default).
    Renormalize = 0,
    /// Discard the pixel if any participating tap failed.
    Strict = 1,
}

/// Discard tests and schedule of one reprojection (see
/// [`stereotrace_reproject_params_default`]).
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct StReprojectParams {
    /// Largest accepted world distance between a tap's surface and the target's (scene
    /// units, `>= 0`; `INFINITY` disables the test).
    pub position_tolerance: f32,
    /// Largest accepted relative depth difference (`>= 0`; `INFINITY` disables).
    pub depth_relative_tolerance: f32,
    /// Smallest accepted cosine between the two normals, in [−1, 1] (−1 disables).
    pub normal_cos: f32,
    /// A `StTapPolicy` value.
    pub policy: u32,
    /// Rows per parallel band (`>= 1`).
    pub band_rows: u32,
}

/// Why each pixel was or was not reprojected: the codes the reason plane holds.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StReason {
    /// Reprojected: at least one tap passed every test.
    Reprojected = 0,
    /// Discarded: a tap's depth or position differed (occlusion or disocclusion).
    DepthOrPosition = 1,
    /// Discarded: the normals differed.
    Normal = 2,
    /// The footprint fell outside the source frame.
    OutOfFrame = 3,
    /// The target pixel shows no surface.
    Background = 4,
    /// Non-finite or non-positive data in the target or every usable tap (or a pixel the
    /// pixel mask skipped).
    Invalid = 5,
}

/// The number of reason codes.
pub const ST_REASON_COUNT: usize = 6;
const _: () = assert!(ST_REASON_COUNT == REASON_COUNT, "the C reason count follows the kernels'");

/// Pixels per reason, indexed by the reason code.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default)]
pub struct StReasonCounts {
    /// `pixels[r]`: pixels whose reason code is `r` (pixels a mask skipped are not counted).
    pub pixels: [u64; ST_REASON_COUNT],
}

/// What a reprojection reads besides the two G-buffers.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct StReprojectInput {
    /// The source frame's samples (the source G-buffer's extent).
    pub colour: StRgb,
    /// Optional fourth channel reprojected the same way (for example a history length);
    /// null for none.
    pub extra: *const StPlaneF32,
    /// Optional target-extent mask: only pixels where it is non-zero are reprojected; the
    /// others read `ST_REASON_INVALID` and keep their outputs. Null: every pixel.
    pub pixel_mask: *const StPlaneU8,
    /// Optional: null, or an array of three target-extent planes x, y, z, the world-space
    /// motion of each target pixel's surface since the source frame (scene units). The
    /// surface was at `position − motion` when the source was rendered, and is looked for
    /// there: moving objects keep their history. 0 is a still surface (the same result as
    /// null, bit for bit); a non-finite vector makes the pixel `ST_REASON_INVALID`.
    pub motion: *const StPlaneF32,
    /// Optional: null, or four floats: the target G-buffer's sub-pixel jitter x, y, then the
    /// source's, in pixels (each within [−1, 1]). The G-buffers were rendered with jittered
    /// cameras (pixel (x, y) shows what the unjittered camera sees at (x + 0.5 + j.x,
    /// y + 0.5 + j.y)), `source_camera` is the source's jittered one, and the colour is on the
    /// unjittered grid: it is read where each target pixel's unjittered centre lands.
    pub jitter: *const f32,
}

/// Where a reprojection writes (all of the target G-buffer's extent).
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct StReprojectOutput {
    /// The reprojected samples (0 where discarded).
    pub colour: StRgbMut,
    /// Required exactly when the input has an extra channel.
    pub extra: *const StPlaneMutF32,
    /// One `StReason` code per pixel.
    pub reason: StPlaneMutU8,
    /// Optional accepted bilinear weight per pixel, in [0, 1]; null for none.
    pub weight: *const StPlaneMutF32,
}

/// The default reprojection parameters: 5 cm, 2 % depth, 25° between normals, renormalised
/// taps, 16-row bands (room-scale scenes in metres).
#[unsafe(no_mangle)]
pub extern "C" fn stereotrace_reproject_params_default() -> StReprojectParams {
    let p = ReprojectParams::default();
    StReprojectParams {
        position_tolerance: p.tolerances.position,
        depth_relative_tolerance: p.tolerances.depth_relative,
        normal_cos: p.tolerances.normal_cos,
        policy: StTapPolicy::Renormalize as u32,
        band_rows: p.band_rows as u32,
    }
}

impl StReprojectParams {
    pub(crate) fn kernel(&self) -> Result<ReprojectParams, Failure> {
        if self.band_rows == 0 {
            return Err(Failure::invalid("band_rows must be at least 1"));
        }
        let tolerances = Tolerances {
            position: self.position_tolerance,
            depth_relative: self.depth_relative_tolerance,
            normal_cos: self.normal_cos,
        };
        tolerances.validate().about("params")?;
        let policy = match self.policy {
            0 => TapPolicy::Renormalize,
            1 => TapPolicy::Strict,
            other => return Err(Failure::invalid(format!("params.policy {other} is not a StTapPolicy (0 or 1)"))),
        };
        Ok(ReprojectParams { tolerances, policy, band_rows: self.band_rows as usize })
    }
}

/// Octahedral encoding of a normal for [`StLayout::Compact`] G-buffers (two 16-bit
/// signed-normalised components, x in the low half). The normal need not be unit length;
/// a zero or non-finite one gives the "no normal" code, which reprojection treats as
/// invalid.
#[unsafe(no_mangle)]
pub extern "C" fn stereotrace_encode_normal(x: f32, y: f32, z: f32) -> u32 {
    encode_normal([x, y, z])
}

/// Backward reprojection of `input`'s samples from the `source` G-buffer's frame into the
/// `target` G-buffer's frame: stereo (source = the other eye, same frame) and temporal
/// (source = the same eye's previous frame) are this one call with different G-buffers.
/// Both G-buffers must have the same layout. `params` may be null (the defaults);
/// `counts` may be null (not reported).
///
/// # Safety
/// Every non-null pointer, and every plane's `data`, must point to valid memory of the
/// size its description gives, for the duration of the call.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn stereotrace_reproject(
    context: *const StContext,
    target: *const StGBuffer,
    source: *const StGBuffer,
    input: *const StReprojectInput,
    output: *const StReprojectOutput,
    params: *const StReprojectParams,
    counts: *mut StReasonCounts,
) -> StStatus {
    // SAFETY: the entry-point contract (`boundary.rs`): the pointers read are this
    // function's arguments, valid per its `# Safety`, null-checked first; planes via `views.rs`.
    guard(|| unsafe {
        let context = required(context, "context")?;
        let (target, source) = (required(target, "target")?, required(source, "source")?);
        let (input, output) = (required(input, "input")?, required(output, "output")?);
        let params = match params.as_ref() {
            Some(p) => p.kernel()?,
            None => ReprojectParams::default(),
        };
        let (target_layout, source_layout) =
            (StLayout::parse(target.layout, "target.layout")?, StLayout::parse(source.layout, "source.layout")?);
        if target_layout != source_layout {
            return Err(Failure::invalid(format!(
                "target is {target_layout:?} but source is {source_layout:?}: both G-buffers must have the same layout"
            )));
        }
        let source_camera = source.camera.model("source.camera")?;
        let mut b = Borrows::new();
        let result = match target_layout {
            Layout::Full => {
                let t = full_gbuffer(target, ["target.depth", "target.position", "target.normal"], &mut b)?;
                let s = full_gbuffer(source, ["source.depth", "source.position", "source.normal"], &mut b)?;
                reproject_views(context, &t, &s, &source_camera, input, output, &params, &mut b)?
            }
            Layout::Compact => {
                let t = compact_gbuffer(target, ["target.depth", "target.normal_octahedral", "target.camera"], &mut b)?;
                let s = compact_gbuffer(source, ["source.depth", "source.normal_octahedral", "source.camera"], &mut b)?;
                reproject_views(context, &t, &s, &source_camera, input, output, &params, &mut b)?
            }
        };
        if let Some(counts) = counts.as_mut() {
            counts.pixels = result.0;
        }
        Ok(())
    })
}

/// # Safety
/// As [`stereotrace_reproject`].
unsafe fn full_gbuffer<'a>(g: &StGBuffer, what: [&'static str; 3], b: &mut Borrows) -> Result<GBuffer<'a>, Failure> {
    // SAFETY: the planes are the caller's, valid as `stereotrace_reproject` requires;
    // `view` checks each one's extent and stride.
    unsafe {
        let depth = g.depth.view(what[0], b)?;
        let position =
            [g.position[0].view(what[1], b)?, g.position[1].view(what[1], b)?, g.position[2].view(what[1], b)?];
        let normal = [g.normal[0].view(what[2], b)?, g.normal[1].view(what[2], b)?, g.normal[2].view(what[2], b)?];
        GBuffer::new(depth, position, normal).about(what[0])
    }
}

/// # Safety
/// As [`stereotrace_reproject`].
unsafe fn compact_gbuffer<'a>(
    g: &StGBuffer,
    what: [&'static str; 3],
    b: &mut Borrows,
) -> Result<CompactGBuffer<'a>, Failure> {
    // SAFETY: as in `full_gbuffer`.
    unsafe {
        let depth = g.depth.view(what[0], b)?;
        let normal = g.normal_octahedral.view(what[1], b)?;
        CompactGBuffer::new(depth, normal, g.camera.model(what[2])?).about(what[0])
    }
}

/// The layout-independent half of [`stereotrace_reproject`].
///
/// # Safety
/// As [`stereotrace_reproject`].
#[allow(clippy::too_many_arguments)]
unsafe fn reproject_views<L: SurfaceLayout>(
    context: &StContext,
    target: &L,
    source: &L,
    source_camera: &CameraModel,
    input: &StReprojectInput,
    output: &StReprojectOutput,
    params: &ReprojectParams,
    b: &mut Borrows,
) -> Result<reproject::ReasonCounts, Failure> {
    // SAFETY: the input planes are the caller's, as `stereotrace_reproject` requires, each
    // checked by `view`; the output views are claimed in `b` after the inputs, so none aliases.
    unsafe {
        let kernel_input = ReprojectInput {
            target,
            source,
            source_camera,
            colour: input.colour.view(["input.colour.r", "input.colour.g", "input.colour.b"], b)?,
            extra: input.extra.as_ref().map(|p| p.view("input.extra", b)).transpose()?,
            pixel_mask: input.pixel_mask.as_ref().map(|p| p.view("input.pixel_mask", b)).transpose()?,
            motion: match input.motion.is_null() {
                true => None,
                // SAFETY: the caller's contract: null or three planes.
                false => {
                    let m = std::slice::from_raw_parts(input.motion, 3);
                    Some([
                        m[0].view("input.motion[0]", b)?,
                        m[1].view("input.motion[1]", b)?,
                        m[2].view("input.motion[2]", b)?,
                    ])
                }
            },
            // SAFETY: the caller's contract: null or four floats.
            jitter: match input.jitter.is_null() {
                true => None,
                false => {
                    let j = std::slice::from_raw_parts(input.jitter, 4);
                    Some(reproject::Jitter { target: [j[0], j[1]], source: [j[2], j[3]] })
                }
            },
            // The C kernel keeps the paper's rule; the pipeline's setting reaches C through
            // its configuration.
            background: None,
        };
        let kernel_output = ReprojectOutput {
            colour: output.colour.view(["output.colour.r", "output.colour.g", "output.colour.b"], b)?,
            extra: output.extra.as_ref().map(|p| p.view("output.extra", b)).transpose()?,
            reason: output.reason.view("output.reason", b)?,
            weight: output.weight.as_ref().map(|p| p.view("output.weight", b)).transpose()?,
        };
        context
            .run("stereotrace_reproject", || reproject::reproject(&kernel_input, kernel_output, params))?
            .map_err(Failure::from)
    }
}

/// EMA parameters (see [`stereotrace_ema`]).
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct StEmaParams {
    /// Weight of the new sample, in (0, 1] (the paper: 0.2).
    pub alpha: f32,
    /// 1: use `alpha = max(alpha, 1 / (n + 1))` with the per-pixel history length `n` (needs
    /// `history_len`); 0: a fixed alpha.
    pub ramp: u32,
    /// Rows per parallel band (`>= 1`).
    pub band_rows: u32,
}

/// What an EMA step or a blend saw.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default)]
pub struct StAccumulateStats {
    /// New samples with a non-finite channel (kept out of the history).
    pub non_finite: u64,
    /// Pixels left without any valid value (written as 0).
    pub holes: u64,
    /// Pixels whose history was discarded (reset to the new sample).
    pub resets: u64,
}

impl From<AccumulateStats> for StAccumulateStats {
    fn from(s: AccumulateStats) -> Self {
        Self { non_finite: s.non_finite, holes: s.holes, resets: s.resets }
    }
}

/// The paper's EMA parameters: alpha 0.2, no ramp, 16-row bands.
#[unsafe(no_mangle)]
pub extern "C" fn stereotrace_ema_params_default() -> StEmaParams {
    let p = EmaParams::default();
    StEmaParams { alpha: p.alpha, ramp: u32::from(p.ramp), band_rows: p.band_rows as u32 }
}

/// One EMA step in place: where `reason` is `ST_REASON_REPROJECTED` the reprojected history
/// in `accum` moves towards the new sample by `alpha`; elsewhere it is reset to the new
/// sample. `has_new` (optional, null: everywhere) marks where a new sample exists.
/// `params` may be null (the defaults); `stats` may be null.
///
/// - `reason` (in): one `StReason` code per pixel; any other value (6 ..= 255) is refused
///   with the first such pixel named.
/// - `history_len` (in/out; optional unless `ramp`): samples accumulated per pixel, finite
///   and >= 0 (a negative, NaN or infinite length is refused). Per pixel it becomes
///   `c·n + 1` where the history was kept and a sample added, `1` where the history was reset
///   to a new sample, `n` where no usable new sample came (the history kept as it is) and
///   `0` for a hole (no history and no sample).
/// - `confidence` (in; optional, null: 1 everywhere): how far each pixel's history can be
///   trusted, in [0, 1] (NaN or outside is refused). Where the history is valid and a sample
///   arrives it counts as `c·n` samples with weight `1 − α' = c·(1 − α)`: 1 is the plain EMA,
///   bit for bit, 0 restarts from the new sample. For what reprojection cannot see (a light
///   that moved, an object whose motion the G-buffer lacks).
/// - A new sample with a non-finite channel never enters the history (counted in
///   `stats.non_finite`); the results are clamped to ±FLT_MAX.
///
/// # Safety
/// As [`stereotrace_reproject`].
#[unsafe(no_mangle)]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn stereotrace_ema(
    context: *const StContext,
    new_samples: *const StRgb,
    reason: *const StPlaneU8,
    has_new: *const StPlaneU8,
    confidence: *const StPlaneF32,
    accum: *const StRgbMut,
    history_len: *const StPlaneMutF32,
    params: *const StEmaParams,
    stats: *mut StAccumulateStats,
) -> StStatus {
    // SAFETY: forwarded; a null pixel mask is every pixel.
    unsafe {
        ema_call(
            "stereotrace_ema",
            EmaPointers { context, new_samples, reason, has_new, confidence, pixel_mask: std::ptr::null() },
            accum,
            history_len,
            params,
            stats,
        )
    }
}

/// [`stereotrace_ema`] on the pixels where `pixel_mask` (required) is non-zero only: the
/// others keep their `accum` and `history_len` as they were and are not counted in `stats`,
/// and their `confidence` and `history_len` are neither read nor checked. Inside the mask
/// the result is [`stereotrace_ema`]'s, bit for bit. For a caller that has already written
/// most of the history, as a stereo pipeline whose left eye restarts its history from the
/// stereo reprojection of the right eye's: reproject straight into the left history
/// (`stereotrace_reproject` flushes its samples as the EMA's restart would), then
/// run this with the stereo-discarded pixels as the mask.
///
/// # Safety
/// As [`stereotrace_reproject`].
#[unsafe(no_mangle)]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn stereotrace_ema_masked(
    context: *const StContext,
    new_samples: *const StRgb,
    reason: *const StPlaneU8,
    has_new: *const StPlaneU8,
    confidence: *const StPlaneF32,
    pixel_mask: *const StPlaneU8,
    accum: *const StRgbMut,
    history_len: *const StPlaneMutF32,
    params: *const StEmaParams,
    stats: *mut StAccumulateStats,
) -> StStatus {
    if pixel_mask.is_null() {
        // Refused before any other pointer is read; nothing is written.
        return guard(|| Err(Failure::invalid("pixel_mask is required (stereotrace_ema takes every pixel)")));
    }
    // SAFETY: forwarded.
    unsafe {
        ema_call(
            "stereotrace_ema_masked",
            EmaPointers { context, new_samples, reason, has_new, confidence, pixel_mask },
            accum,
            history_len,
            params,
            stats,
        )
    }
}

/// The read-only pointers of an EMA call.
struct EmaPointers {
    context: *const StContext,
    new_samples: *const StRgb,
    reason: *const StPlaneU8,
    has_new: *const StPlaneU8,
    confidence: *const StPlaneF32,
    pixel_mask: *const StPlaneU8,
}

/// The body of [`stereotrace_ema`] and [`stereotrace_ema_masked`] (`name` in the context's
/// messages; a null `pixel_mask` is every pixel).
///
/// # Safety
/// As [`stereotrace_reproject`], for the pointers given.
unsafe fn ema_call(
    name: &'static str,
    inputs: EmaPointers,
    accum: *const StRgbMut,
    history_len: *const StPlaneMutF32,
    params: *const StEmaParams,
    stats: *mut StAccumulateStats,
) -> StStatus {
    let EmaPointers { context, new_samples, reason, has_new, confidence, pixel_mask } = inputs;
    // SAFETY: the entry-point contract (`boundary.rs`): the pointers read are the calling
    // function's arguments, valid per its `# Safety`, null-checked first; planes via `views.rs`.
    guard(|| unsafe {
        let context = required(context, "context")?;
        let params = match params.as_ref() {
            Some(p) if p.band_rows == 0 => return Err(Failure::invalid("params.band_rows must be at least 1")),
            Some(p) if p.ramp > 1 => {
                return Err(Failure::invalid(format!("params.ramp must be 0 or 1, got {}", p.ramp)));
            }
            Some(p) => EmaParams { alpha: p.alpha, ramp: p.ramp == 1, band_rows: p.band_rows as usize },
            None => EmaParams::default(),
        };
        let mut b = Borrows::new();
        let input = EmaInput {
            new: required(new_samples, "new_samples")?
                .view(["new_samples.r", "new_samples.g", "new_samples.b"], &mut b)?,
            reason: required(reason, "reason")?.view("reason", &mut b)?,
            has_new: has_new.as_ref().map(|p| p.view("has_new", &mut b)).transpose()?,
            confidence: confidence.as_ref().map(|p| p.view("confidence", &mut b)).transpose()?,
            pixel_mask: pixel_mask.as_ref().map(|p| p.view("pixel_mask", &mut b)).transpose()?,
        };
        let state = EmaState {
            accum: required(accum, "accum")?.view(["accum.r", "accum.g", "accum.b"], &mut b)?,
            history_len: history_len.as_ref().map(|p| p.view("history_len", &mut b)).transpose()?,
        };
        let result = context.run(name, || accumulate::ema(&input, state, &params))??;
        if let Some(stats) = stats.as_mut() {
            *stats = result.into();
        }
        Ok(())
    })
}

/// The stereo blend in place: where `reason` is `ST_REASON_REPROJECTED`,
/// `reprojected = own + (1 - own_weight) * (reprojected - own)`; elsewhere `reprojected = own`.
/// `own_weight` is in [0, 1] (the paper: 0.5); `band_rows >= 1` (0 picks 16); `reason` holds
/// `StReason` codes only (any other value is refused). `stats` may be null.
///
/// # Safety
/// As [`stereotrace_reproject`].
#[unsafe(no_mangle)]
pub unsafe extern "C" fn stereotrace_blend(
    context: *const StContext,
    own: *const StRgb,
    reprojected: *const StRgbMut,
    reason: *const StPlaneU8,
    own_weight: f32,
    band_rows: u32,
    stats: *mut StAccumulateStats,
) -> StStatus {
    // SAFETY: the entry-point contract (`boundary.rs`): the pointers read are this
    // function's arguments, valid per its `# Safety`, null-checked first; planes via `views.rs`.
    guard(|| unsafe {
        let context = required(context, "context")?;
        let params = BlendParams { own_weight, band_rows: if band_rows == 0 { 16 } else { band_rows as usize } };
        let mut b = Borrows::new();
        let own = required(own, "own")?.view(["own.r", "own.g", "own.b"], &mut b)?;
        let reason = required(reason, "reason")?.view("reason", &mut b)?;
        let out =
            required(reprojected, "reprojected")?.view(["reprojected.r", "reprojected.g", "reprojected.b"], &mut b)?;
        let result = context.run("stereotrace_blend", || accumulate::blend(&own, out, &reason, &params))??;
        if let Some(stats) = stats.as_mut() {
            *stats = result.into();
        }
        Ok(())
    })
}

/// Which SSIM [`stereotrace_ssim`] computes: the values of its `variant` argument.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StSsimVariant {
    /// The paper's: MATLAB `ssim` on the H×W×3 array (a 3-D Gaussian window).
    Volume = 0,
    /// MATLAB `ssim` on each channel (11×11 window), averaged over the channels.
    PerChannel = 1,
}

/// What [`stereotrace_ssim`] measured.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default)]
pub struct StSsimResult {
    /// Mean SSIM over the usable voxels; NaN if none was usable.
    pub ssim: f64,
    /// Mean SSIM of each channel's voxels.
    pub per_channel: [f64; 3],
    /// RMSE over the positions where both samples are usable; NaN if none.
    pub rmse: f64,
    /// Voxels in the mean (at most H·W·3).
    pub voxels: u64,
    /// Positions in the RMSE.
    pub rmse_samples: u64,
    /// Unusable input samples (NaN, ±inf, huge), both images together.
    pub non_finite: u64,
}

/// SSIM and RMSE of two RGB images of one extent, at least `STEREOTRACE_SSIM_MIN_SIDE` (11,
/// the window) on each side: smaller images are refused, as their windows would see mostly
/// padding. `variant` is a [`StSsimVariant`] value. Non-finite samples are left out (and
/// counted in `non_finite`) rather than poisoning the mean.
///
/// # Safety
/// As [`stereotrace_reproject`].
#[unsafe(no_mangle)]
pub unsafe extern "C" fn stereotrace_ssim(
    context: *const StContext,
    a: *const StRgb,
    b: *const StRgb,
    variant: u32,
    result: *mut StSsimResult,
) -> StStatus {
    // SAFETY: the entry-point contract (`boundary.rs`): the pointers read are this
    // function's arguments, valid per its `# Safety`, null-checked first; planes via `views.rs`.
    guard(|| unsafe {
        let context = required(context, "context")?;
        if result.is_null() {
            return Err(Failure::null("result"));
        }
        let mut borrows = Borrows::new();
        let a = required(a, "a")?.view(["a.r", "a.g", "a.b"], &mut borrows)?;
        let b = required(b, "b")?.view(["b.r", "b.g", "b.b"], &mut borrows)?;
        let variant = match variant {
            0 => SsimVariant::Volume,
            1 => SsimVariant::PerChannel,
            other => return Err(Failure::invalid(format!("variant {other} is not a StSsimVariant (0 or 1)"))),
        };
        let r = context.run("stereotrace_ssim", || ssim::ssim(&a, &b, &SsimParams::with_variant(variant)))??;
        result.write(StSsimResult {
            ssim: r.ssim,
            per_channel: r.per_channel,
            rmse: r.rmse,
            voxels: r.voxels,
            rmse_samples: r.rmse_samples,
            non_finite: r.non_finite,
        });
        Ok(())
    })
}
