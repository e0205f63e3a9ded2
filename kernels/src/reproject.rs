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
//!    weight as 0.
//! 5. Every pixel gets a [`Reason`]. Target-side reasons come first (background, invalid,
//!    projection out of frame); a discarded pixel's reason is the most informative failure
//!    among its taps: depth/position, then normal, then invalid, then out of frame.
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

use crate::bands::{SharedRows, for_each_band};
use crate::bilinear::{Footprint, Footprints, coherent_row, renormalise, renormalise_simd};
use crate::camera::CameraModel;
use crate::frame::{Extent, FrameError, Plane, PlaneMut, RgbPlanes, RgbPlanesMut, same_extent};
use crate::gbuffer::{SurfaceLayout, Surfel, Surfels};
use crate::simd::{F32s, LANES, TapCoords, store};

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
}

/// Where a reprojection writes.
pub struct ReprojectOutput<'a> {
    /// The reprojected samples (0 where discarded).
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
    let c = input.colour;
    let tol = params.tolerances;
    Ok(Prepared {
        target: input.target,
        source: input.source,
        camera: input.source_camera,
        channels: [c.r(), c.g(), c.b(), input.extra.unwrap_or(c.r())],
        channel_count: if input.extra.is_some() { 4 } else { 3 },
        pixel_mask: input.pixel_mask,
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
    mut out: ReprojectOutput<'_>,
    params: &ReprojectParams,
) -> Result<ReasonCounts, FrameError> {
    let prepared = prepare(input, params)?;
    check_output(&prepared, &out)?;
    let counts = run(&prepared, out.reborrow(), params.band_rows, |p, y, mut row| {
        if p.channel_count == 4 { simd_row::<L, 4>(p, y, &mut row) } else { simd_row::<L, 3>(p, y, &mut row) }
    });
    #[cfg(feature = "check-scalar")]
    check_against_scalar(input, &out, params, counts);
    Ok(counts)
}

/// One output row through the SIMD body (`C` channels), the tail through the scalar one.
#[inline(always)]
fn simd_row<L: SurfaceLayout, const C: usize>(p: &Prepared<'_, L>, y: usize, row: &mut RowOut<'_>) -> ReasonCounts {
    let mut counts = ReasonCounts::default();
    let width = row.reason.len();
    let mut cache = [SourceCache::EMPTY; 2];
    let mask_row = p.pixel_mask.map(|m| m.row(y));
    let mut x = 0;
    while x + LANES <= width {
        // Bit `i` set where lane `i` is to be reprojected.
        let wanted = match mask_row {
            None => ALL_LANES,
            Some(m) => m[x..x + LANES].iter().enumerate().fold(0, |bits, (i, &v)| bits | (u32::from(v != 0) << i)),
        };
        if wanted == 0 {
            row.reason[x..x + LANES].fill(Reason::Invalid as u8);
            x += LANES;
            continue;
        }
        let lanes = reproject_lanes::<L, C>(p, x, y, &mut cache);
        // Lanes outside the mask keep what the output held.
        let put = |dst: &mut [f32], v: F32s| {
            if wanted == ALL_LANES {
                store(dst, x, v);
            } else {
                for (i, (d, v)) in dst[x..x + LANES].iter_mut().zip(v.to_array()).enumerate() {
                    if wanted & (1 << i) != 0 {
                        *d = v;
                    }
                }
            }
        };
        for c in 0..C {
            put(row.channels[c], lanes.channels[c]);
        }
        if let Some(w) = row.weight.as_deref_mut() {
            put(w, lanes.weight);
        }
        let reasons = &mut row.reason[x..x + LANES];
        if wanted == ALL_LANES && lanes.ok_bits == ALL_LANES {
            // The common case: every lane reprojected (code 0).
            reasons.fill(Reason::Reprojected as u8);
            counts.0[Reason::Reprojected as usize] += LANES as u64;
        } else {
            for (i, (dst, code)) in reasons.iter_mut().zip(lanes.reason.to_array()).enumerate() {
                if wanted & (1 << i) != 0 {
                    *dst = code as u8;
                    counts.0[usize::from(*dst)] += 1;
                } else {
                    *dst = Reason::Invalid as u8;
                }
            }
        }
        x += LANES;
    }
    for x in x..width {
        write_pixel(p, x, y, row, &mut counts);
    }
    counts
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

/// Writes the scalar reference result for pixel `(x, y)`.
#[inline]
fn write_pixel<L: SurfaceLayout>(
    p: &Prepared<'_, L>,
    x: usize,
    y: usize,
    row: &mut RowOut<'_>,
    counts: &mut ReasonCounts,
) {
    if p.pixel_mask.is_some_and(|m| m.get(x, y) == 0) {
        row.reason[x] = Reason::Invalid as u8;
        return;
    }
    let (reason, values, weight) = reproject_pixel_prepared(p, x, y);
    for c in 0..row.count {
        row.channels[c][x] = values[c];
    }
    if let Some(w) = row.weight.as_deref_mut() {
        w[x] = weight;
    }
    row.reason[x] = reason as u8;
    counts.0[reason as usize] += 1;
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

#[inline(always)]
fn len2_simd(v: [F32s; 3]) -> F32s {
    v[0] * v[0] + v[1] * v[1] + v[2] * v[2]
}

/// The angle test described in the module docs (scalar).
#[inline(always)]
fn normals_agree(dot: f32, q: f32, cos2: f32, cos_positive: bool) -> bool {
    let bound = cos2 * q;
    if cos_positive { dot >= 0.0 && dot * dot >= bound } else { dot >= 0.0 || dot * dot <= bound }
}

fn reproject_pixel_prepared<L: SurfaceLayout>(
    p: &Prepared<'_, L>,
    x: usize,
    y: usize,
) -> (Reason, [f32; MAX_CHANNELS], f32) {
    const NONE: [f32; MAX_CHANNELS] = [0.0; MAX_CHANNELS];
    let t = p.target.surfel(x, y);
    if t.depth == f32::INFINITY {
        return (Reason::Background, NONE, 0.0);
    }
    let t_len2 = len2(t.normal);
    if !usable(&t, t_len2) {
        return (Reason::Invalid, NONE, 0.0);
    }
    let [cx, cy, _, cw] = p.camera.clip(t.position);
    if !(cw > 0.0) {
        return (Reason::OutOfFrame, NONE, 0.0);
    }
    let (hw, hh) = (p.half_width, p.half_height);
    let inv_w = 1.0 / cw;
    let sx = (cx * inv_w) * hw + hw;
    let sy = (-(cy * inv_w)) * hh + hh;
    let Some(fp) = Footprint::new(sx, sy, p.source_extent) else {
        return (Reason::OutOfFrame, NONE, 0.0);
    };
    let weights = fp.weights();
    let in_frame = fp.in_frame(p.source_extent);
    // Clamped so that an infinite tap depth can never pass (see `evaluate_taps`).
    let depth_tolerance = (p.depth_relative * cw).min(f32::MAX);

    let mut sum = NONE;
    let mut total = 0.0f32;
    let (mut any_accepted, mut any_failed) = (false, false);
    let (mut fail_geometry, mut fail_normal, mut fail_invalid) = (false, false, false);
    for (tap, &(tx, ty)) in fp.taps().iter().enumerate() {
        if weights[tap] == 0.0 {
            continue;
        }
        if !in_frame[tap] {
            any_failed = true;
            continue;
        }
        let (tx, ty) = (tx as usize, ty as usize);
        let s = p.source.surfel(tx, ty);
        let mut values = NONE;
        for c in 0..p.channel_count {
            values[c] = p.channels[c].get(tx, ty);
        }
        let s_len2 = len2(s.normal);
        let verdict = if s.depth == f32::INFINITY {
            TapVerdict::Geometry
        } else if !usable(&s, s_len2) || !values[..p.channel_count].iter().all(|v| v.is_finite()) {
            TapVerdict::Invalid
        } else {
            let d = [0, 1, 2].map(|i| s.position[i] - t.position[i]);
            let distance2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
            let dot = s.normal[0] * t.normal[0] + s.normal[1] * t.normal[1] + s.normal[2] * t.normal[2];
            if !(distance2 <= p.position2) || !((s.depth - cw).abs() <= depth_tolerance) {
                TapVerdict::Geometry
            } else if !normals_agree(dot, s_len2 * t_len2, p.normal_cos2, p.normal_cos_positive) {
                TapVerdict::Normal
            } else {
                TapVerdict::Accepted
            }
        };
        match verdict {
            TapVerdict::Accepted => {
                any_accepted = true;
                for c in 0..MAX_CHANNELS {
                    sum[c] += weights[tap] * values[c];
                }
                total += weights[tap];
            }
            TapVerdict::Geometry => fail_geometry = true,
            TapVerdict::Normal => fail_normal = true,
            TapVerdict::Invalid => fail_invalid = true,
        }
        any_failed |= verdict != TapVerdict::Accepted;
    }
    let ok = any_accepted && !(p.strict && any_failed);
    if ok {
        let inv_total = 1.0 / total;
        return (Reason::Reprojected, sum.map(|s| renormalise(s, inv_total)), total.min(1.0));
    }
    let reason = if fail_geometry {
        Reason::DepthOrPosition
    } else if fail_normal {
        Reason::Normal
    } else if fail_invalid {
        Reason::Invalid
    } else {
        Reason::OutOfFrame
    };
    (reason, NONE, 0.0)
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum TapVerdict {
    Accepted,
    Geometry,
    Normal,
    Invalid,
}

/// A lane bit set with every lane.
const ALL_LANES: u32 = (1 << LANES) - 1;

/// Results for `LANES` pixels.
struct Lanes<const C: usize> {
    channels: [F32s; C],
    weight: F32s,
    /// Reason codes as floats (exact small integers).
    reason: F32s,
    /// Bit `i` set where lane `i` was reprojected.
    ok_bits: u32,
}

/// All-ones where every value is finite. `v · 0` is ±0 for finite `v` and NaN for ±inf or
/// NaN, so one sum and one compare test them all (two instructions per value instead of
/// the four of a bit-pattern test).
#[inline(always)]
fn all_finite_simd<const N: usize>(values: [F32s; N]) -> F32s {
    let mut poison = F32s::ZERO;
    for v in values {
        poison += v * F32s::ZERO;
    }
    poison.simd_eq(F32s::ZERO)
}

#[inline(always)]
fn usable_simd(s: &Surfels, normal_len2: F32s) -> F32s {
    let [p0, p1, p2] = s.position;
    all_finite_simd([s.depth, p0, p1, p2, normal_len2]) & normal_len2.simd_gt(F32s::ZERO) & s.depth.simd_gt(F32s::ZERO)
}

/// Where the SIMD body loads a tap's surfels and samples from.
trait TapSource {
    /// Per-tap in-frame masks.
    fn in_frame<L: SurfaceLayout>(&self, p: &Prepared<'_, L>, fp: &Footprints) -> [F32s; 4];
    fn load<L: SurfaceLayout, const C: usize>(
        &self,
        p: &Prepared<'_, L>,
        tap: usize,
        fp: &Footprints,
    ) -> (Surfels, [F32s; C]);
}

/// Coherent footprints: tap `t` of lane `i` is source pixel `(x0 + i + (t & 1), y0 + (t >> 1))`,
/// so every plane is read with one unaligned vector load per tap.
struct RowLoads {
    x0: usize,
    y0: usize,
}

impl TapSource for RowLoads {
    /// `coherent_row` only picks this source when every tap of every lane is in frame.
    #[inline(always)]
    fn in_frame<L: SurfaceLayout>(&self, _: &Prepared<'_, L>, fp: &Footprints) -> [F32s; 4] {
        [fp.inside; 4]
    }

    #[inline(always)]
    fn load<L: SurfaceLayout, const C: usize>(
        &self,
        p: &Prepared<'_, L>,
        tap: usize,
        _: &Footprints,
    ) -> (Surfels, [F32s; C]) {
        let (x, y) = (self.x0 + (tap & 1), self.y0 + (tap >> 1));
        // SAFETY: `coherent_row` built this source only with x0 + LANES < width and
        // y0 + 1 < height of the source extent, which the source G-buffer and every channel
        // share (checked in `prepare`), so every lane of every tap is inside.
        unsafe {
            let values = core::array::from_fn(|c| F32s::from(p.channels[c].lanes_unchecked::<LANES>(x, y)));
            (p.source.surfels_row_unchecked(x, y), values)
        }
    }
}

/// Anything else: per-lane gathers from clamped coordinates.
struct Gathers;

impl TapSource for Gathers {
    #[inline(always)]
    fn in_frame<L: SurfaceLayout>(&self, p: &Prepared<'_, L>, fp: &Footprints) -> [F32s; 4] {
        fp.in_frame(p.source_extent)
    }

    #[inline(always)]
    fn load<L: SurfaceLayout, const C: usize>(
        &self,
        p: &Prepared<'_, L>,
        tap: usize,
        fp: &Footprints,
    ) -> (Surfels, [F32s; C]) {
        let (tx, ty) = fp.taps()[tap];
        let coords = TapCoords::clamped(tx, ty, p.source_extent.width(), p.source_extent.height());
        let values = core::array::from_fn(|c| coords.gather_f32(&p.channels[c]));
        (p.source.surfels_gather(&coords), values)
    }
}

/// The target side of `LANES` pixels: surface, projection into the source, footprint.
struct TargetLanes {
    surface: Surfels,
    normal_len2: F32s,
    /// Source view depth of the target point (clip w).
    depth_in_source: F32s,
    footprints: Footprints,
    weights: [F32s; 4],
    /// Lanes that go on to the tap tests.
    active: F32s,
    background: F32s,
}

/// Accumulated over the four taps of `LANES` pixels.
struct TapTotals<const C: usize> {
    sum: [F32s; C],
    total: F32s,
    any_accepted: F32s,
    any_failed: F32s,
}

/// Why taps failed (only worked out for groups with a discarded pixel).
#[derive(Default)]
struct Failures {
    geometry: F32s,
    normal: F32s,
    invalid: F32s,
}

/// The SIMD body for target pixels `x .. x + LANES` of row `y`.
///
/// Two passes keep the common case cheap. The first decides acceptance with the smallest
/// predicate that is equivalent to the reference's (see [`accepts`]); only when some lane
/// ends up discarded is the group evaluated again to classify why (a few percent of groups
/// in the paper's scenes).
#[inline(always)]
fn reproject_lanes<L: SurfaceLayout, const C: usize>(
    p: &Prepared<'_, L>,
    x: usize,
    y: usize,
    cache: &mut [SourceCache; 2],
) -> Lanes<C> {
    let code = |r: Reason| F32s::splat(r as u8 as f32);
    // Eight background pixels: what the general path below computes for them, without it
    // (skies, and the pixels a caller masked out by giving them no surface).
    if p.target.depth_row(x, y).simd_eq(F32s::splat(f32::INFINITY)).all() {
        return Lanes { channels: [F32s::ZERO; C], weight: F32s::ZERO, reason: code(Reason::Background), ok_bits: 0 };
    }
    let t = target_lanes(p, x, y);
    let coherent = coherent_row(&t.footprints, t.active, p.source_extent);
    let totals = match coherent {
        Some((x0, y0)) => coherent_taps::<L, C>(p, &t, x0, y0, cache),
        None => evaluate_taps::<L, C, _, false>(p, &t, &Gathers).0,
    };
    let ok = if p.strict { totals.any_accepted & !totals.any_failed } else { totals.any_accepted };
    let reason = if (ok | t.background).all() {
        t.background.select(code(Reason::Background), code(Reason::Reprojected))
    } else {
        let (_, failed) = match coherent {
            Some((x0, y0)) => evaluate_taps::<L, C, _, true>(p, &t, &RowLoads { x0, y0 }),
            None => evaluate_taps::<L, C, _, true>(p, &t, &Gathers),
        };
        let invalid_target = !t.background & !usable_simd(&t.surface, t.normal_len2);
        let discard_reason = failed.geometry.select(
            code(Reason::DepthOrPosition),
            failed
                .normal
                .select(code(Reason::Normal), failed.invalid.select(code(Reason::Invalid), code(Reason::OutOfFrame))),
        );
        t.background.select(
            code(Reason::Background),
            invalid_target.select(code(Reason::Invalid), ok.select(code(Reason::Reprojected), discard_reason)),
        )
    };
    let zero = F32s::ZERO;
    let inv_total = F32s::ONE / totals.total;
    Lanes {
        channels: totals.sum.map(|s| ok.select(renormalise_simd(s, inv_total), zero)),
        weight: ok.select(totals.total.min(F32s::ONE), zero),
        reason,
        ok_bits: ok.to_bitmask(),
    }
}

#[inline(always)]
fn target_lanes<L: SurfaceLayout>(p: &Prepared<'_, L>, x: usize, y: usize) -> TargetLanes {
    let surface = p.target.surfels_row(x, y);
    let inf = F32s::splat(f32::INFINITY);
    let background = surface.depth.simd_eq(inf);
    let normal_len2 = len2_simd(surface.normal);
    // Cheaper than `usable_simd` and equivalent for deciding which lanes go on: a non-finite
    // position makes the projection NaN or infinite, which fails the footprint test below.
    let plausible = surface.depth.simd_gt(F32s::ZERO)
        & surface.depth.simd_lt(inf)
        & normal_len2.simd_gt(F32s::ZERO)
        & normal_len2.simd_lt(inf);
    let r = &p.v.rows;
    let clip = |i: usize| {
        r[i][0] * surface.position[0] + r[i][1] * surface.position[1] + r[i][2] * surface.position[2] + r[i][3]
    };
    let (cx, cy, cw) = (clip(0), clip(1), clip(2));
    let (hw, hh) = (p.v.half_width, p.v.half_height);
    let inv_w = F32s::ONE / cw;
    let sx = (cx * inv_w) * hw + hw;
    let sy = (-(cy * inv_w)) * hh + hh;
    let mut footprints = Footprints::new_splat(sx, sy, p.v.source_width, p.v.source_height);
    // Lanes that already have a reason take no further part.
    let active = plausible & cw.simd_gt(F32s::ZERO) & footprints.inside;
    footprints.inside = active;
    TargetLanes {
        surface,
        normal_len2,
        depth_in_source: cw,
        weights: footprints.weights(),
        footprints,
        active,
        background,
    }
}

/// Runs the tap tests over the four taps. With `CLASSIFY`, also records why taps failed.
#[inline(always)]
fn evaluate_taps<L: SurfaceLayout, const C: usize, S: TapSource, const CLASSIFY: bool>(
    p: &Prepared<'_, L>,
    t: &TargetLanes,
    source: &S,
) -> (TapTotals<C>, Failures) {
    let zero = F32s::ZERO;
    let depth_tolerance = (p.v.depth_relative * t.depth_in_source).min(F32s::splat(f32::MAX));
    let mut acc = TapTotals { sum: [zero; C], total: zero, any_accepted: zero, any_failed: zero };
    let mut failed = Failures::default();
    let in_frame = source.in_frame(p, &t.footprints);
    evaluate_tap::<L, C, S, CLASSIFY, 0>(p, t, source, &in_frame, depth_tolerance, &mut acc, &mut failed);
    evaluate_tap::<L, C, S, CLASSIFY, 1>(p, t, source, &in_frame, depth_tolerance, &mut acc, &mut failed);
    evaluate_tap::<L, C, S, CLASSIFY, 2>(p, t, source, &in_frame, depth_tolerance, &mut acc, &mut failed);
    evaluate_tap::<L, C, S, CLASSIFY, 3>(p, t, source, &in_frame, depth_tolerance, &mut acc, &mut failed);
    (acc, failed)
}

/// One tap of [`evaluate_taps`]; `TAP` is a constant so each of the four copies knows its
/// offsets.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn evaluate_tap<L: SurfaceLayout, const C: usize, S: TapSource, const CLASSIFY: bool, const TAP: usize>(
    p: &Prepared<'_, L>,
    t: &TargetLanes,
    source: &S,
    in_frame: &[F32s; 4],
    depth_tolerance: F32s,
    acc: &mut TapTotals<C>,
    failed: &mut Failures,
) {
    let zero = F32s::ZERO;
    let tap = TAP;
    let weight = t.weights[tap];
    let participates = t.active & weight.simd_gt(zero);
    if participates.none() {
        return;
    }
    let tap_in_frame = participates & in_frame[tap];
    let (s, values) = source.load::<L, C>(p, tap, &t.footprints);
    let s_len2 = len2_simd(s.normal);
    let (geometry_ok, normal_ok) = surface_tests(p, t, &s, s_len2, depth_tolerance);
    // Equivalent to the reference's `usable ∧ finite samples ∧ geometry ∧ normal`: with
    // thresholds clamped to f32::MAX, passing the geometry test already implies a finite
    // tap depth and position (and so no background), and `s_len2 ≤ MAX` implies a finite
    // normal. The sign of the depth is the one thing left to check.
    let accepted = tap_in_frame
        & geometry_ok
        & normal_ok
        & s.depth.simd_gt(zero)
        & s_len2.simd_gt(zero)
        & s_len2.simd_le(F32s::splat(f32::MAX))
        & all_finite_simd(values);
    acc.any_failed |= participates & !accepted;
    acc.any_accepted |= accepted;
    for c in 0..C {
        acc.sum[c] += accepted.select(weight * values[c], zero);
    }
    acc.total += accepted.select(weight, zero);
    if CLASSIFY {
        let tap_background = s.depth.simd_eq(F32s::splat(f32::INFINITY));
        let usable_tap = !tap_background & usable_simd(&s, s_len2) & all_finite_simd(values);
        failed.geometry |= tap_in_frame & (tap_background | (usable_tap & !geometry_ok));
        failed.normal |= tap_in_frame & usable_tap & geometry_ok & !normal_ok;
        failed.invalid |= tap_in_frame & !tap_background & !usable_tap;
    }
}

/// The geometry (world-position distance and relative depth) and normal-angle tests of one
/// tap's source surfels `s` (with squared normal lengths `s_len2`) against the target
/// lanes: `(geometry_ok, normal_ok)`. Shared by the general and the coherent tap paths.
#[inline(always)]
fn surface_tests<L: SurfaceLayout>(
    p: &Prepared<'_, L>,
    t: &TargetLanes,
    s: &Surfels,
    s_len2: F32s,
    depth_tolerance: F32s,
) -> (F32s, F32s) {
    let tp = &t.surface.position;
    let d = [s.position[0] - tp[0], s.position[1] - tp[1], s.position[2] - tp[2]];
    let distance2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    let geometry_ok = distance2.simd_le(p.v.position2) & (s.depth - t.depth_in_source).abs().simd_le(depth_tolerance);
    let tn = &t.surface.normal;
    let dot = s.normal[0] * tn[0] + s.normal[1] * tn[1] + s.normal[2] * tn[2];
    let bound = p.v.normal_cos2 * (s_len2 * t.normal_len2);
    let facing = dot.simd_ge(F32s::ZERO);
    let normal_ok =
        if p.normal_cos_positive { facing & (dot * dot).simd_ge(bound) } else { facing | (dot * dot).simd_le(bound) };
    (geometry_ok, normal_ok)
}

/// What the tap tests need of `LANES` consecutive source pixels of one row, worked out once
/// per pixel: in a coherent group, tap 1 of lane `i` is tap 0 of lane `i + 1` (and tap 3 of
/// tap 2), and the next group's tap 0 is usually this group's tap-1 row shifted by `LANES`.
#[derive(Clone, Copy)]
struct SourceLanes {
    surface: Surfels,
    /// Squared length of the (unnormalised) normal.
    len2: F32s,
    /// All-ones where the pixel can be accepted at all: in front of its camera, a usable
    /// normal and finite samples in every channel (the part of [`evaluate_tap`]'s
    /// acceptance that does not depend on the target).
    usable: F32s,
}

/// A decoded [`SourceLanes`] of pixels `x .. x + LANES` of source row `y`, kept from one
/// group to the next.
#[derive(Clone, Copy)]
struct SourceCache {
    x: usize,
    y: usize,
    lanes: SourceLanes,
}

impl SourceCache {
    const EMPTY: Self = Self {
        x: usize::MAX,
        y: usize::MAX,
        lanes: SourceLanes {
            surface: Surfels { depth: F32s::ZERO, position: [F32s::ZERO; 3], normal: [F32s::ZERO; 3] },
            len2: F32s::ZERO,
            usable: F32s::ZERO,
        },
    };
}

/// Decodes source pixels `x .. x + LANES` of row `y` for the tap tests.
///
/// # Safety
/// `x + LANES <= width` and `y < height` of the source extent.
#[inline(always)]
unsafe fn source_lanes<L: SurfaceLayout, const C: usize>(p: &Prepared<'_, L>, x: usize, y: usize) -> SourceLanes {
    // SAFETY: forwarded from the caller; the source G-buffer and every channel share the
    // source extent (checked in `prepare`).
    let (surface, values) = unsafe {
        let values: [F32s; C] = core::array::from_fn(|c| F32s::from(p.channels[c].lanes_unchecked::<LANES>(x, y)));
        (p.source.surfels_row_unchecked(x, y), values)
    };
    let len2 = len2_simd(surface.normal);
    let usable = surface.depth.simd_gt(F32s::ZERO)
        & len2.simd_gt(F32s::ZERO)
        & len2.simd_le(F32s::splat(f32::MAX))
        & all_finite_simd(values);
    SourceLanes { surface, len2, usable }
}

/// `[a₁, …, a₇, b₀]`: the lanes of `a` moved down by one, with `b`'s first lane on top.
#[inline(always)]
fn shift_lanes(a: F32s, b: F32s) -> F32s {
    #[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
    {
        use core::arch::x86_64::{__m256, _mm256_blend_ps, _mm256_permutevar8x32_ps, _mm256_setr_epi32};
        // SAFETY: the intrinsics need AVX2, which this build targets (the cfg above).
        unsafe {
            // [b₀, a₁, …, a₇], then rotated down by one lane: two instructions.
            let merged = _mm256_blend_ps::<1>(__m256::from(a), __m256::from(b));
            F32s::from(_mm256_permutevar8x32_ps(merged, _mm256_setr_epi32(1, 2, 3, 4, 5, 6, 7, 0)))
        }
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "avx2")))]
    {
        let (a, b) = (a.to_array(), b.to_array());
        F32s::from([a[1], a[2], a[3], a[4], a[5], a[6], a[7], b[0]])
    }
}

impl SourceLanes {
    /// [`shift_lanes`] of every field.
    #[inline(always)]
    fn shifted(&self, next: &Self) -> Self {
        let (a, b) = (&self.surface, &next.surface);
        Self {
            surface: Surfels {
                depth: shift_lanes(a.depth, b.depth),
                position: [0, 1, 2].map(|i| shift_lanes(a.position[i], b.position[i])),
                normal: [0, 1, 2].map(|i| shift_lanes(a.normal[i], b.normal[i])),
            },
            len2: shift_lanes(self.len2, next.len2),
            usable: shift_lanes(self.usable, next.usable),
        }
    }
}

/// The first pass of [`evaluate_taps`] for a coherent group (see [`coherent_row`](crate::bilinear::coherent_row)), with
/// each source pixel decoded once: tap 0 of row `r` reads pixels `x0 ..`, tap 1 the same
/// lanes shifted by one with the next vector's first pixel on top; that next vector is kept
/// for the next group, whose tap 0 usually starts there. Same tests, same order, same bits.
#[inline(always)]
fn coherent_taps<L: SurfaceLayout, const C: usize>(
    p: &Prepared<'_, L>,
    t: &TargetLanes,
    x0: usize,
    y0: usize,
    cache: &mut [SourceCache; 2],
) -> TapTotals<C> {
    let zero = F32s::ZERO;
    let depth_tolerance = (p.v.depth_relative * t.depth_in_source).min(F32s::splat(f32::MAX));
    let mut acc = TapTotals { sum: [zero; C], total: zero, any_accepted: zero, any_failed: zero };
    let width = p.source_extent.width();
    for (r, slot) in cache.iter_mut().enumerate() {
        let (w0, w1) = (t.weights[2 * r], t.weights[2 * r + 1]);
        let (p0, p1) = (t.active & w0.simd_gt(zero), t.active & w1.simd_gt(zero));
        if (p0 | p1).none() {
            continue;
        }
        let y = y0 + r;
        // SAFETY (all `source_lanes` and channel loads below): `coherent_row` returned
        // (x0, y0) only with x0 + LANES < width and y0 + 1 < height of the source extent,
        // and the x0 + LANES (next vector) decode is guarded by its own bounds test.
        if slot.x != x0 || slot.y != y {
            *slot = SourceCache { x: x0, y, lanes: unsafe { source_lanes::<L, C>(p, x0, y) } };
        }
        if p0.any() {
            let values = unsafe { core::array::from_fn(|c| F32s::from(p.channels[c].lanes_unchecked::<LANES>(x0, y))) };
            tap_test(p, t, &slot.lanes, values, w0, p0, depth_tolerance, &mut acc);
        }
        if p1.any() {
            let b = if x0 + 2 * LANES <= width {
                let next = unsafe { source_lanes::<L, C>(p, x0 + LANES, y) };
                let b = slot.lanes.shifted(&next);
                *slot = SourceCache { x: x0 + LANES, y, lanes: next };
                b
            } else {
                unsafe { source_lanes::<L, C>(p, x0 + 1, y) }
            };
            let values =
                unsafe { core::array::from_fn(|c| F32s::from(p.channels[c].lanes_unchecked::<LANES>(x0 + 1, y))) };
            tap_test(p, t, &b, values, w1, p1, depth_tolerance, &mut acc);
        }
    }
    acc
}

/// One tap of [`coherent_taps`]: [`evaluate_tap`]'s first-pass tests on a decoded source.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn tap_test<L: SurfaceLayout, const C: usize>(
    p: &Prepared<'_, L>,
    t: &TargetLanes,
    src: &SourceLanes,
    values: [F32s; C],
    weight: F32s,
    participates: F32s,
    depth_tolerance: F32s,
    acc: &mut TapTotals<C>,
) {
    let zero = F32s::ZERO;
    let (geometry_ok, normal_ok) = surface_tests(p, t, &src.surface, src.len2, depth_tolerance);
    // Every tap of a coherent group is in frame, so `participates` stands for
    // `participates ∧ in frame` here (see `evaluate_tap` for why this is the reference's test).
    let accepted = participates & geometry_ok & normal_ok & src.usable;
    acc.any_failed |= participates & !accepted;
    acc.any_accepted |= accepted;
    for c in 0..C {
        acc.sum[c] += accepted.select(weight * values[c], zero);
    }
    acc.total += accepted.select(weight, zero);
}
