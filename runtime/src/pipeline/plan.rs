//! A mode's schedule as data: the steps a frame runs after the G-buffers and the temporal
//! reprojection of the histories.

use super::{Mode, Order};
use crate::camera::Eye;

/// One step of a frame after the G-buffers and the temporal reprojection of the histories.
/// A mode's schedule is a list of them ([`plan`]), so it can be printed and tested.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Step {
    /// Path trace every pixel of the eye into its `traced` image (under a budget: those
    /// without valid history first).
    Trace(Eye),
    /// Stereo-reproject the right eye's image (`traced` or accumulated `history`) into the
    /// left eye's `work` image, then trace the left pixels it discarded.
    StereoFillLeft(StereoSource),
    /// The eye's `work` = blend of its own image and the other eye's reprojected one.
    StereoBlend(Eye, StereoSource),
    /// The left eye's EMA validity: invalid where stereo reprojection succeeded (those
    /// pixels restart from the stereo sample), the temporal reason elsewhere. With the
    /// paper's history rule the restart is fused into the stereo step and this step has
    /// nothing to do (the pipeline's module notes).
    CombineLeftValidity,
    /// EMA of the eye's reprojected history with new samples from the named image.
    Accumulate(Eye, Source),
}

/// The schedule of `mode` in `order` (the table in the module notes, as data).
pub fn plan(mode: Mode, order: Order) -> &'static [Step] {
    use Eye::{Left, Right};
    use Step::*;
    match (mode, order) {
        (Mode::PathTraced, _) => &[Trace(Left), Trace(Right)],
        (Mode::Stereo, _) => &[Trace(Right), StereoFillLeft(StereoSource::Traced)],
        (Mode::Temporal, _) => {
            &[Trace(Left), Accumulate(Left, Source::Traced), Trace(Right), Accumulate(Right, Source::Traced)]
        }
        (Mode::Spatiotemporal, Order::Paper) => &[
            Trace(Right),
            Accumulate(Right, Source::Traced),
            StereoFillLeft(StereoSource::History),
            CombineLeftValidity,
            Accumulate(Left, Source::WorkCombined),
        ],
        (Mode::Spatiotemporal, Order::StereoFirst) => &[
            Trace(Right),
            StereoFillLeft(StereoSource::Traced),
            Accumulate(Right, Source::Traced),
            Accumulate(Left, Source::Work),
        ],
        (Mode::StereoBlend, _) => &[
            Trace(Left),
            Trace(Right),
            StereoBlend(Left, StereoSource::Traced),
            StereoBlend(Right, StereoSource::Traced),
        ],
        (Mode::SpatiotemporalBlend, Order::Paper) => &[
            Trace(Left),
            Accumulate(Left, Source::Traced),
            Trace(Right),
            Accumulate(Right, Source::Traced),
            StereoBlend(Left, StereoSource::History),
            StereoBlend(Right, StereoSource::History),
        ],
        (Mode::SpatiotemporalBlend, Order::StereoFirst) => &[
            Trace(Left),
            Trace(Right),
            StereoBlend(Left, StereoSource::Traced),
            StereoBlend(Right, StereoSource::Traced),
            Accumulate(Left, Source::Work),
            Accumulate(Right, Source::Work),
        ],
    }
}

/// Which image of the other eye a stereo reprojection reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StereoSource {
    /// This frame's path-traced samples.
    Traced,
    /// The accumulated history (this frame's EMA output).
    History,
}

/// Where new samples for the EMA come from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Source {
    /// The eye's `traced` image.
    Traced,
    /// The eye's `work` image (stereo reprojection or blend output).
    Work,
    /// `work`, with the combined validity plane (paper-order spatiotemporal left eye).
    WorkCombined,
}

/// Which buffer tracing writes.
#[derive(Clone, Copy)]
pub(super) enum Target {
    Traced,
    Work,
}
