//! Backward reprojection with bilinear taps, discard tests and reason codes.
//!
//! Stereo and temporal reprojection are this one kernel with different cameras: for stereo
//! the source is the other eye at the same frame, for temporal the same eye at the previous
//! frame. For every target pixel `p` with surface `X` (world position), `n` (normal):
//!
//! 1. Project `X` with the source view-projection: clip `(cx, cy, cz, cw)`, with `cw` the view
//!    depth `X` would have in the source camera. `sx = (cx/cw)·W/2 + W/2`,
//!    `sy = −(cy/cw)·H/2 + H/2` (continuous pixel coordinates, centres at `i + 0.5`).
//! 2. Bilinear footprint of `(sx, sy)` ([`crate::bilinear`]): four taps and weights.
//! 3. Each tap with a non-zero weight is tested, in this order: in frame; source surface
//!    present (`depth ≠ +inf`), else a depth/position failure (a disocclusion against the
//!    background); source surface and sample finite, else invalid; world-position distance
//!    `|X_tap − X| ≤ position` and relative depth `|d_tap − cw| ≤ depth_relative · cw`, else
//!    a depth/position failure; normals within the angle `acos(normal_cos)`, else a normal
//!    failure. The angle test does not need unit normals: with `d = n_tap · n` and
//!    `q = |n_tap|²·|n|²` it checks `d ≥ 0 ∧ d² ≥ cos²·q` for `cos ≥ 0` and
//!    `d ≥ 0 ∨ d² ≤ cos²·q` otherwise (no square root, no division).
//! 4. [`TapPolicy::Renormalize`] (default) keeps the accepted taps and divides by their total
//!    weight; [`TapPolicy::Strict`] rejects the pixel when any participating tap failed.
//!    A pixel with no accepted tap is discarded: its channels are written as 0 and its
//!    weight as 0. Written channels are clamped to the finite range and values below
//!    `f32::MIN_POSITIVE` in magnitude flushed to 0, as the EMA's results are
//!    ([`crate::accumulate`]), so a reprojected sample is already what an EMA restart from it
//!    writes and a history never walks through subnormals.
//! 5. Every pixel gets a [`Reason`]. Target-side reasons come first (background, invalid,
//!    projection out of frame); a discarded pixel's reason is the most informative failure
//!    among its taps: depth/position, then normal, then invalid, then out of frame.
//! 6. Beyond the paper, only with [`ReprojectInput::background`]: a background pixel (no
//!    surface) is a point at infinity. Its view direction `d` through the target camera's
//!    pixel centre is projected with the source view-projection as the homogeneous point
//!    `(d, 0)` (rotation only: a sky does not move with the camera's position), and its
//!    taps are accepted where they are in frame, background too (`depth = +inf`), and have
//!    finite samples. Renormalisation and the strict policy are as above; a pixel with no
//!    accepted tap keeps [`Reason::Background`] with 0 written. The SIMD bodies write every
//!    background pixel as the paper's rule does; the `background` module then takes the
//!    row's background pixels eight at a time (contiguous loads where the footprints are one
//!    source row, as the coherent path's), with the reference's operations in its order.
//!
//! The kernel reads one to four source channels (colour RGB, plus an optional extra channel,
//! for example a per-pixel history length) and writes the same number of target channels,
//! a reason code per pixel and, optionally, the accepted weight `Σ_accepted wᵢ` in [0, 1].
//!
//! Schedule: full-width row bands (see `bands`). Within a row the SIMD body takes 8 pixels
//! at a time. When the 8 footprints are coherent (same source row, consecutive source
//! columns, all taps in frame), which is the common case for stereo pairs and smooth camera
//! motion (98% of the groups of the stereo bench), each tap is an unaligned vector load per
//! plane instead of 8-lane gathers, and each source pixel is decoded once: tap 1 of lane `i`
//! is tap 0 of lane `i + 1` (taps 2 and 3 likewise), so tap 1 is tap 0's decoded surface
//! shifted by one lane with the next 8 pixels' first on top, and those next 8 are kept for
//! the next group, whose tap 0 usually starts there. The values are the same, so the result
//! is too. Tail: the remaining `width % 8` pixels of a row go through the scalar reference.
//!
//! Instruction set: on an AVX-512 CPU ([`Isa::active`]) the AVX-512 body is taken at run
//! time ([`reproject_with`] runs either body). Where both G-buffers are compact and no
//! pixel mask is given, it first tries 16 target pixels at a time in one `zmm` register
//! (the `wide` module): the coherent path's common case, every lane reprojected, with `k`
//! masks for the tests. A group that is anything else (a lane of sky or off frame, taps
//! that are not one row of consecutive pixels, a discarded lane) is refused before anything
//! is written and goes, with the group after it, through the 8-lane body, compiled a
//! second time with AVX-512 F/BW/DQ/VL (its comparisons land in mask registers, its
//! selects become masked moves). Both do the reference's lane-wise operations in its order,
//! so every body gives the same bits.

mod background;
mod scalar;
mod simd;
#[cfg(target_arch = "x86_64")]
mod wide;

use crate::bands::{SharedRows, for_each_band};
use crate::camera::CameraModel;
use crate::frame::{Extent, FrameError, Plane, PlaneMut, RgbPlanes, RgbPlanesMut, same_extent};
use crate::gbuffer::{SurfaceLayout, Surfel};
use crate::isa::Isa;
use crate::simd::F32s;
use background::BackgroundRays;
use scalar::{reproject_pixel_prepared, write_pixel};
use simd::simd_row;

/// Why a pixel was or was not reprojected. Stored as one byte per pixel.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[repr(u8)]
pub enum Reason {
    /// Reprojected: at least one tap accepted (all of them under the strict policy).
    Reprojected = 0,
    /// Discarded: depth or world position differs too much (occlusion / disocclusion).
    /// The paper's Figure 6 colours this yellow.
    DepthOrPosition = 1,
    /// Discarded: shading normals differ too much (green in Figure 6).
    Normal = 2,
    /// Discarded: the footprint falls outside the source frame (purple in Figure 6).
    OutOfFrame = 3,
    /// The target pixel shows background (no surface: `depth = +inf`).
    Background = 4,
    /// The target or every usable tap holds non-finite or non-positive data (NaN in a
    /// G-buffer, a non-finite source sample).
    Invalid = 5,
}

/// Number of [`Reason`] values.
pub const REASON_COUNT: usize = 6;

/// Refuses a reason plane holding a code outside the defined set (`0 .. REASON_COUNT`),
/// naming the first such pixel: a kernel that reads reasons would otherwise treat an
/// undefined code as one of its own (discarded), silently. One pass of byte maxima per row
/// (vectorised), so the check costs a small fraction of the kernel that reads the plane.
pub fn check_reason_plane(what: &'static str, reasons: &Plane<'_, u8>) -> Result<(), FrameError> {
    let row_ok = |y: usize| (reasons.row(y).iter().fold(0u8, |m, &c| m.max(c)) as usize) < REASON_COUNT;
    let Some(y) = crate::bands::first_bad_row(reasons.height(), row_ok) else {
        return Ok(());
    };
    let row = reasons.row(y);
    let x = row.iter().position(|&c| c as usize >= REASON_COUNT).expect("the maximum is in the row");
    Err(FrameError::ValueOutOfRange {
        what,
        x,
        y,
        value: f64::from(row[x]),
        allowed: "a reason code 0 ..= 5 (Reprojected .. Invalid)",
    })
}

impl Reason {
    /// Every reason in code order.
    pub const ALL: [Reason; REASON_COUNT] = [
        Reason::Reprojected,
        Reason::DepthOrPosition,
        Reason::Normal,
        Reason::OutOfFrame,
        Reason::Background,
        Reason::Invalid,
    ];

    /// The reason stored as `code`, if it is one.
    pub fn from_code(code: u8) -> Option<Self> {
        Self::ALL.get(code as usize).copied()
    }

    /// A short lower-case name for tables.
    pub fn name(self) -> &'static str {
        match self {
            Reason::Reprojected => "reprojected",
            Reason::DepthOrPosition => "depth/position",
            Reason::Normal => "normal",
            Reason::OutOfFrame => "out of frame",
            Reason::Background => "background",
            Reason::Invalid => "invalid",
        }
    }
}

/// Pixels per reason, indexed by the reason code.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ReasonCounts(pub [u64; REASON_COUNT]);

impl ReasonCounts {
    /// Pixels with `reason`.
    pub fn get(&self, reason: Reason) -> u64 {
        self.0[reason as usize]
    }

    /// Pixels counted.
    pub fn total(&self) -> u64 {
        self.0.iter().sum()
    }

    /// Pixels that were not reprojected although they show a surface (what must be traced
    /// because reprojection failed, as opposed to background).
    pub fn discarded(&self) -> u64 {
        self.total() - self.get(Reason::Reprojected) - self.get(Reason::Background)
    }

    fn merged(mut self, other: Self) -> Self {
        for (a, b) in self.0.iter_mut().zip(other.0) {
            *a += b;
        }
        self
    }
}

/// Per-scene discard thresholds (the paper sets them "manually based on the scale of each
/// test scene").
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tolerances {
    /// Largest accepted world-space distance between a tap's surface point and `X`
    /// (scene units; `+inf` disables the test).
    pub position: f32,
    /// Largest accepted `|d_tap − d_expected| / d_expected` (`+inf` disables).
    pub depth_relative: f32,
    /// Smallest accepted cosine between the tap's and the target's normals (−1 disables).
    pub normal_cos: f32,
}

impl Tolerances {
    /// Tolerances with the normal threshold given as an angle in degrees.
    pub fn new(position: f32, depth_relative: f32, normal_max_degrees: f32) -> Self {
        Self { position, depth_relative, normal_cos: normal_max_degrees.to_radians().cos() }
    }

    /// Refuses NaN, negative tolerances and cosines outside [−1, 1].
    pub fn validate(&self) -> Result<(), FrameError> {
        if !(self.position >= 0.0) {
            return Err(FrameError::InvalidParameter("position tolerance must be >= 0"));
        }
        if !(self.depth_relative >= 0.0) {
            return Err(FrameError::InvalidParameter("relative depth tolerance must be >= 0"));
        }
        if !(-1.0..=1.0).contains(&self.normal_cos) {
            return Err(FrameError::InvalidParameter("normal cosine threshold must be in [-1, 1]"));
        }
        Ok(())
    }
}

impl Default for Tolerances {
    /// Room-scale defaults: 5 cm, 2 % depth, 25°.
    fn default() -> Self {
        Self::new(0.05, 0.02, 25.0)
    }
}

/// What to do with a pixel some of whose taps failed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum TapPolicy {
    /// Keep the accepted taps and renormalise their weights (default).
    #[default]
    Renormalize,
    /// Discard the pixel if any participating tap failed.
    Strict,
}

/// Parameters of one reprojection call.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReprojectParams {
    /// Discard thresholds.
    pub tolerances: Tolerances,
    /// What to do with pixels some of whose taps failed.
    pub policy: TapPolicy,
    /// Rows per parallel band.
    pub band_rows: usize,
}

impl Default for ReprojectParams {
    fn default() -> Self {
        Self { tolerances: Tolerances::default(), policy: TapPolicy::Renormalize, band_rows: 16 }
    }
}

/// The most channels one call reprojects.
pub const MAX_CHANNELS: usize = 4;

/// One pixel's result in the scalar reference: its reason, channels and accepted weight.
type PixelResult = (Reason, [f32; MAX_CHANNELS], f32);

/// Source data of a reprojection.
pub struct ReprojectInput<'a, L: SurfaceLayout> {
    /// The G-buffer of the frame being filled.
    pub target: &'a L,
    /// The G-buffer of the frame the samples come from.
    pub source: &'a L,
    /// The camera that rendered `source`.
    pub source_camera: &'a CameraModel,
    /// The samples to carry over.
    pub colour: RgbPlanes<'a>,
    /// An optional fourth channel reprojected the same way (e.g. history length).
    pub extra: Option<Plane<'a>>,
    /// Optional target-extent mask: only pixels where it is non-zero are reprojected. The
    /// others are skipped: their reason becomes [`Reason::Invalid`], their colour, extra and
    /// weight outputs are left as they were, and they are not counted. A caller that needs a
    /// few scattered pixels (the paper-order left eye's history, needed only where its
    /// stereo reprojection failed) then pays for those pixels, not for the frame.
    pub pixel_mask: Option<Plane<'a, u8>>,
    /// Optional per-pixel motion of the target's surfaces since the source frame, in world
    /// units (x, y, z planes of the target extent): the surface seen at a target pixel was at
    /// `X − m` when the source frame was rendered, so that point is projected into the source
    /// and tested against its taps (position and depth), where `X` would be for static
    /// geometry. Zero is static geometry, bit for bit; a non-finite vector makes the pixel
    /// [`Reason::Invalid`], like any non-finite target data. Normals are compared as they are:
    /// a turning object fails the normal test once it has turned by more than its threshold.
    /// For temporal reprojection of moving objects; a stereo pair has none (one instant).
    pub motion: Option<[Plane<'a>; 3]>,
    /// Optional sub-pixel jitter of the two G-buffers (TAA-style camera jitter), whose cameras
    /// (the target's and `source_camera`) are the jittered ones ([`CameraModel::jittered`]):
    /// G-buffer pixel (x, y) shows the surface at (x + 0.5 + j.x, y + 0.5 + j.y) of the
    /// unjittered camera, while the source colour and the outputs are on the unjittered pixel
    /// grid (a path tracer's pixels, an accumulated history). The colour is read where the
    /// target pixel's unjittered centre lands, so the footprint moves by `source − target`;
    /// the geometric tests read the same taps (within a pixel of the exact ones, which the
    /// tolerances absorb on a smooth surface). `None` and equal offsets are the same, bit for
    /// bit. Each offset must be finite and at most one pixel.
    pub jitter: Option<Jitter>,
    /// Optional: the target G-buffer's camera, to reproject **background** pixels as points
    /// at infinity (module notes, item 6) instead of discarding them as the paper does. For a
    /// static background (an environment map, a constant sky): the samples of a direction are
    /// taken as the same in both frames. Its extent must be the target's.
    pub background: Option<&'a CameraModel>,
}

/// The sub-pixel offsets of the two G-buffers of a reprojection ([`ReprojectInput::jitter`]),
/// in pixels (x right, y down), each within [−1, 1].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Jitter {
    /// The target G-buffer's offset.
    pub target: [f32; 2],
    /// The source G-buffer's offset.
    pub source: [f32; 2],
}

impl Jitter {
    /// How far the colour footprint moves, or the refusal of an offset that is not finite or
    /// exceeds a pixel.
    fn shift(&self) -> Result<[f32; 2], FrameError> {
        crate::camera::check_jitter(self.target)?;
        crate::camera::check_jitter(self.source)?;
        Ok([self.source[0] - self.target[0], self.source[1] - self.target[1]])
    }
}

/// Where a reprojection writes.
pub struct ReprojectOutput<'a> {
    /// The reprojected samples (0 where discarded; finite, and flushed to 0 below
    /// `f32::MIN_POSITIVE` in magnitude).
    pub colour: RgbPlanesMut<'a>,
    /// Must be present exactly when the input has an extra channel.
    pub extra: Option<PlaneMut<'a>>,
    /// One [`Reason`] code per pixel.
    pub reason: PlaneMut<'a, u8>,
    /// Optional accepted weight per pixel.
    pub weight: Option<PlaneMut<'a>>,
}

impl ReprojectOutput<'_> {
    /// A shorter-lived view of the same buffers.
    pub fn reborrow(&mut self) -> ReprojectOutput<'_> {
        ReprojectOutput {
            colour: self.colour.reborrow(),
            extra: self.extra.as_mut().map(|p| p.reborrow()),
            reason: self.reason.reborrow(),
            weight: self.weight.as_mut().map(|p| p.reborrow()),
        }
    }
}

/// Validated, flattened form of the input that the row bodies read.
struct Prepared<'a, L: SurfaceLayout> {
    target: &'a L,
    source: &'a L,
    camera: &'a CameraModel,
    channels: [Plane<'a>; MAX_CHANNELS],
    channel_count: usize,
    pixel_mask: Option<Plane<'a, u8>>,
    motion: Option<[Plane<'a>; 3]>,
    /// How far the footprint moves for jitter (source − target), where it moves at all.
    jitter_shift: Option<[f32; 2]>,
    /// The target camera, where background pixels are reprojected by direction.
    background: Option<BackgroundRays>,
    source_extent: Extent,
    half_width: f32,
    half_height: f32,
    /// Squared position tolerance, clamped to f32::MAX (see `evaluate_taps`).
    position2: f32,
    depth_relative: f32,
    normal_cos2: f32,
    normal_cos_positive: bool,
    strict: bool,
    /// The same parameters splatted once per call: the SIMD body then reads each as one
    /// memory operand instead of a broadcast per use (measured: 8% fewer instructions).
    v: Splats,
}

/// Per-call constants as lanes (see [`Prepared::v`]).
struct Splats {
    /// Rows x, y and w of the source view-projection.
    rows: [[F32s; 4]; 3],
    half_width: F32s,
    half_height: F32s,
    source_width: F32s,
    source_height: F32s,
    position2: F32s,
    depth_relative: F32s,
    normal_cos2: F32s,
}

fn prepare<'a, L: SurfaceLayout>(
    input: &ReprojectInput<'a, L>,
    params: &ReprojectParams,
) -> Result<Prepared<'a, L>, FrameError> {
    params.tolerances.validate()?;
    let source = input.source.extent();
    same_extent("source colour", source, input.colour.extent())?;
    same_extent("source camera extent", source, input.source_camera.extent)?;
    if let Some(extra) = &input.extra {
        same_extent("extra source channel", source, extra.extent())?;
    }
    if let Some(mask) = &input.pixel_mask {
        same_extent("pixel mask", input.target.extent(), mask.extent())?;
    }
    if let Some(motion) = &input.motion {
        for (plane, what) in motion.iter().zip(["motion x", "motion y", "motion z"]) {
            same_extent(what, input.target.extent(), plane.extent())?;
        }
    }
    if let Some(camera) = input.background {
        same_extent("target camera extent (background)", input.target.extent(), camera.extent)?;
    }
    let c = input.colour;
    let tol = params.tolerances;
    Ok(Prepared {
        target: input.target,
        source: input.source,
        camera: input.source_camera,
        channels: [c.r(), c.g(), c.b(), input.extra.unwrap_or(c.r())],
        channel_count: if input.extra.is_some() { 4 } else { 3 },
        pixel_mask: input.pixel_mask,
        motion: input.motion,
        jitter_shift: input.jitter.map(|j| j.shift()).transpose()?.filter(|s| *s != [0.0; 2]),
        background: input.background.map(|c| BackgroundRays::new(*c)),
        source_extent: source,
        half_width: input.source_camera.half_extent().0,
        half_height: input.source_camera.half_extent().1,
        position2: (tol.position * tol.position).min(f32::MAX),
        depth_relative: tol.depth_relative,
        normal_cos2: tol.normal_cos * tol.normal_cos,
        normal_cos_positive: tol.normal_cos >= 0.0,
        strict: params.policy == TapPolicy::Strict,
        v: Splats {
            rows: [0, 1, 3].map(|i| input.source_camera.rows[i].map(F32s::splat)),
            half_width: F32s::splat(input.source_camera.half_extent().0),
            half_height: F32s::splat(input.source_camera.half_extent().1),
            source_width: F32s::splat(source.width() as f32),
            source_height: F32s::splat(source.height() as f32),
            position2: F32s::splat((tol.position * tol.position).min(f32::MAX)),
            depth_relative: F32s::splat(tol.depth_relative),
            normal_cos2: F32s::splat(tol.normal_cos * tol.normal_cos),
        },
    })
}

fn check_output<L: SurfaceLayout>(p: &Prepared<'_, L>, out: &ReprojectOutput<'_>) -> Result<(), FrameError> {
    let target = p.target.extent();
    same_extent("output colour", target, out.colour.extent())?;
    same_extent("reason plane", target, out.reason.extent())?;
    if let Some(w) = &out.weight {
        same_extent("weight plane", target, w.extent())?;
    }
    match (&out.extra, p.channel_count) {
        (Some(extra), 4) => same_extent("extra output channel", target, extra.extent()),
        (None, 3) => Ok(()),
        _ => Err(FrameError::InvalidParameter("extra channel must be given on both input and output")),
    }
}

/// Output rows shared between the parallel bands.
struct Rows<'a> {
    channels: [Option<SharedRows<'a, f32>>; MAX_CHANNELS],
    reason: SharedRows<'a, u8>,
    weight: Option<SharedRows<'a, f32>>,
}

/// Mutable slices of one output row.
struct RowOut<'r> {
    channels: [&'r mut [f32]; MAX_CHANNELS],
    count: usize,
    reason: &'r mut [u8],
    weight: Option<&'r mut [f32]>,
}

impl<'a> Rows<'a> {
    fn new(out: ReprojectOutput<'a>) -> Self {
        let ReprojectOutput { colour, extra, reason, weight } = out;
        let [r, g, b] = colour.into_channels();
        Self {
            channels: [Some(r), Some(g), Some(b), extra].map(|p| p.map(SharedRows::new)),
            reason: SharedRows::new(reason),
            weight: weight.map(SharedRows::new),
        }
    }

    /// # Safety
    /// Row `y` must not be borrowed elsewhere (each band takes only its own rows).
    unsafe fn row(&self, y: usize) -> RowOut<'a> {
        let mut count = 0;
        let channels = core::array::from_fn(|c| match &self.channels[c] {
            Some(rows) => {
                count += 1;
                // SAFETY: forwarded from the caller.
                unsafe { rows.row(y) }
            }
            // An absent extra channel: an empty row that is never indexed.
            None => Default::default(),
        });
        RowOut {
            channels,
            count,
            // SAFETY: forwarded from the caller.
            reason: unsafe { self.reason.row(y) },
            // SAFETY: forwarded from the caller.
            weight: self.weight.as_ref().map(|w| unsafe { w.row(y) }),
        }
    }
}

/// Scalar reference reprojection. Returns the number of pixels per reason.
pub fn reproject_scalar<L: SurfaceLayout>(
    input: &ReprojectInput<'_, L>,
    out: ReprojectOutput<'_>,
    params: &ReprojectParams,
) -> Result<ReasonCounts, FrameError> {
    let prepared = prepare(input, params)?;
    check_output(&prepared, &out)?;
    Ok(run(&prepared, out, params.band_rows, |p, y, mut row| {
        let mut counts = ReasonCounts::default();
        for x in 0..row.reason.len() {
            write_pixel(p, x, y, &mut row, &mut counts);
        }
        counts
    }))
}

/// SIMD reprojection, bit-identical to [`reproject_scalar`]. Returns the number of pixels
/// per reason.
///
/// Stereo reprojection of the right eye's image into the left eye, on an analytic scene:
///
/// ```
/// use glam::Vec3;
/// use stereotrace_kernels::reproject::{self, Reason, ReprojectInput, ReprojectOutput, ReprojectParams, Tolerances};
/// use stereotrace_kernels::synth::{AnalyticScene, camera_at};
/// use stereotrace_kernels::{Extent, PlaneBuf, RgbBuf};
///
/// let extent = Extent::new(64, 36)?;
/// let scene = AnalyticScene::room(6.0);
/// let left = scene.render(&camera_at(Vec3::new(-0.03, 0.0, 0.0), extent, 60.0), [0.0; 3]);
/// let right = scene.render(&camera_at(Vec3::new(0.03, 0.0, 0.0), extent, 60.0), [0.0; 3]);
/// let (target, source) = (left.compact(), right.compact());
/// let input = ReprojectInput {
///     target: &target,
///     source: &source,
///     source_camera: &right.surfaces.camera,
///     colour: right.colour.view(),
///     extra: None,
///     pixel_mask: None,
///     motion: None,
///     jitter: None,
///     background: None,
/// };
/// let mut colour = RgbBuf::new(extent, 0.0);
/// let mut reason = PlaneBuf::new(extent, 0u8);
/// let output = ReprojectOutput { colour: colour.view_mut(), extra: None, reason: reason.view_mut(), weight: None };
/// // A pixel of this 64-pixel view spans ~15 cm of the room: tolerances to match.
/// let params = ReprojectParams { tolerances: Tolerances::new(0.5, 0.05, 25.0), ..ReprojectParams::default() };
/// let counts = reproject::reproject(&input, output, &params)?;
/// assert_eq!(counts.total(), extent.pixels() as u64);
/// assert!(counts.get(Reason::Reprojected) > counts.discarded());
/// # Ok::<(), stereotrace_kernels::FrameError>(())
/// ```
pub fn reproject<L: SurfaceLayout>(
    input: &ReprojectInput<'_, L>,
    out: ReprojectOutput<'_>,
    params: &ReprojectParams,
) -> Result<ReasonCounts, FrameError> {
    reproject_with(input, out, params, Isa::active())
}

/// [`reproject`] with the body of a chosen instruction set (the 8-lane body where the CPU
/// lacks it, see [`Isa::is_supported`]). Both bodies give the same bits.
pub fn reproject_with<L: SurfaceLayout>(
    input: &ReprojectInput<'_, L>,
    mut out: ReprojectOutput<'_>,
    params: &ReprojectParams,
    isa: Isa,
) -> Result<ReasonCounts, FrameError> {
    let prepared = prepare(input, params)?;
    check_output(&prepared, &out)?;
    let avx512 = isa == Isa::Avx512 && isa.is_supported();
    let counts = run(&prepared, out.reborrow(), params.band_rows, |p, y, mut row| {
        if avx512 {
            // SAFETY: taken only where the CPU reports the features the function enables.
            unsafe { simd_row_avx512(p, y, &mut row) }
        } else {
            simd_row_any_channels::<L, false>(p, y, &mut row)
        }
    });
    #[cfg(feature = "check-scalar")]
    check_against_scalar(input, &out, params, counts);
    Ok(counts)
}

/// [`simd_row`] with the input's channel count. `AVX512` lets it take 16-pixel groups
/// (only inside [`simd_row_avx512`]).
#[inline(always)]
fn simd_row_any_channels<L: SurfaceLayout, const AVX512: bool>(
    p: &Prepared<'_, L>,
    y: usize,
    row: &mut RowOut<'_>,
) -> ReasonCounts {
    if p.channel_count == 4 { simd_row::<L, 4, AVX512>(p, y, row) } else { simd_row::<L, 3, AVX512>(p, y, row) }
}

/// [`simd_row_any_channels`] compiled with AVX-512 (see the module notes).
#[target_feature(enable = "avx512f,avx512bw,avx512dq,avx512vl")]
fn simd_row_avx512<L: SurfaceLayout>(p: &Prepared<'_, L>, y: usize, row: &mut RowOut<'_>) -> ReasonCounts {
    simd_row_any_channels::<L, true>(p, y, row)
}

#[cfg(feature = "check-scalar")]
fn check_against_scalar<L: SurfaceLayout>(
    input: &ReprojectInput<'_, L>,
    out: &ReprojectOutput<'_>,
    params: &ReprojectParams,
    counts: ReasonCounts,
) {
    use crate::check::assert_planes_equal;
    use crate::frame::{PlaneBuf, RgbBuf};
    let extent = out.reason.extent();
    // The reference starts from the SIMD body's output, so that the pixels a pixel mask
    // skips (left as they were by both) compare equal.
    let copy = |plane: Plane<'_>| {
        let data = (0..extent.height()).flat_map(|y| plane.row(y).iter().copied()).collect();
        PlaneBuf::from_vec(data, extent).expect("same extent")
    };
    let [r, g, b] = out.colour.as_planes().channels();
    let mut colour = RgbBuf::from_planes(copy(r), copy(g), copy(b)).expect("one extent");
    let mut extra = out.extra.as_ref().map(|p| copy(p.as_plane()));
    let mut reason = PlaneBuf::new(extent, 0u8);
    let mut weight = out.weight.as_ref().map(|p| copy(p.as_plane()));
    let reference = reproject_scalar(
        input,
        ReprojectOutput {
            colour: colour.view_mut(),
            extra: extra.as_mut().map(|p| p.view_mut()),
            reason: reason.view_mut(),
            weight: weight.as_mut().map(|p| p.view_mut()),
        },
        params,
    )
    .expect("validated input");
    assert_eq!(counts, reference, "reason counts differ");
    let simd = out.colour.as_planes().channels();
    for (c, plane) in colour.view().channels().iter().enumerate() {
        assert_planes_equal("reprojected colour", c, &simd[c], plane);
    }
    if let (Some(a), Some(b)) = (&out.extra, &extra) {
        assert_planes_equal("reprojected extra channel", 3, &a.as_plane(), &b.view());
    }
    assert_planes_equal("reason", 0, &out.reason.as_plane(), &reason.view());
    if let (Some(a), Some(b)) = (&out.weight, &weight) {
        assert_planes_equal("weight", 0, &a.as_plane(), &b.view());
    }
}

fn run<L, F>(p: &Prepared<'_, L>, out: ReprojectOutput<'_>, band_rows: usize, body: F) -> ReasonCounts
where
    L: SurfaceLayout,
    F: for<'r> Fn(&Prepared<'_, L>, usize, RowOut<'r>) -> ReasonCounts + Sync,
{
    let height = out.reason.height();
    let rows = Rows::new(out);
    for_each_band(
        height,
        band_rows,
        |range| {
            let mut counts = ReasonCounts::default();
            for y in range {
                // SAFETY: `for_each_band` hands each row to exactly one band.
                let row = unsafe { rows.row(y) };
                counts = counts.merged(body(p, y, row));
            }
            counts
        },
        ReasonCounts::merged,
    )
}

/// The scalar reference for one target pixel: its reason, its channels (the first three
/// are colour, the fourth the extra channel if the input has one) and its accepted weight.
pub fn reproject_pixel<L: SurfaceLayout>(
    input: &ReprojectInput<'_, L>,
    params: &ReprojectParams,
    x: usize,
    y: usize,
) -> Result<(Reason, [f32; MAX_CHANNELS], f32), FrameError> {
    let prepared = prepare(input, params)?;
    let e = prepared.target.extent();
    if x >= e.width() || y >= e.height() {
        return Err(FrameError::InvalidParameter("pixel outside the target extent"));
    }
    Ok(reproject_pixel_prepared(&prepared, x, y))
}

/// Whether a surfel is a usable surface: finite, in front of its camera, with a non-zero
/// normal (`normal_len2` is its squared length).
#[inline(always)]
fn usable(s: &Surfel, normal_len2: f32) -> bool {
    s.depth.is_finite()
        && s.depth > 0.0
        && s.position.iter().all(|v| v.is_finite())
        && s.normal.iter().all(|v| v.is_finite())
        && normal_len2 > 0.0
        && normal_len2.is_finite()
}

#[inline(always)]
fn len2(v: [f32; 3]) -> f32 {
    v[0] * v[0] + v[1] * v[1] + v[2] * v[2]
}

/// The angle test described in the module docs (scalar).
#[inline(always)]
fn normals_agree(dot: f32, q: f32, cos2: f32, cos_positive: bool) -> bool {
    let bound = cos2 * q;
    if cos_positive { dot >= 0.0 && dot * dot >= bound } else { dot >= 0.0 || dot * dot <= bound }
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum TapVerdict {
    Accepted,
    Geometry,
    Normal,
    Invalid,
}
