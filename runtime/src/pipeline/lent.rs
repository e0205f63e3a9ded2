//! G-buffers lent by the caller for one frame (zero-copy input).
//!
//! An engine that rasterises its own G-buffers need not copy them into the pipeline's planes
//! (the [`FrameSource::fill_gbuffers`](crate::source::FrameSource::fill_gbuffers) way): it
//! lends views of its own planes, any stride, to
//! [`Pipeline::render_frame_lent`](super::Pipeline::render_frame_lent). Temporal
//! reprojection reads the previous frame's G-buffer as its source, so the engine keeps that
//! one too (engines double-buffer their G-buffers for TAA anyway) and lends both. Only the
//! planes are lent: the cameras and jitter are the pipeline's record of each frame.

use crate::kernels::frame::same_extent;
use crate::kernels::{Extent, Plane};

use super::{Layout, PipelineConfig, PipelineError};

/// One eye's G-buffer planes, borrowed from the caller for one frame. Which planes must be
/// present follows the pipeline's configuration: `normal_oct` with [`Layout::Compact`],
/// `position` and `normal` with [`Layout::Full`], `history_confidence` exactly when
/// `config.history_confidence`, `motion` exactly when `config.motion_vectors`. Values mean
/// what the same planes of a [`crate::kernels::GBufferBuf`] mean.
#[derive(Clone, Copy)]
pub struct GBufferView<'a> {
    /// View-axis depth (`+inf`: no surface).
    pub depth: Plane<'a>,
    /// Octahedral shading normals (compact layout).
    pub normal_oct: Option<Plane<'a, u32>>,
    /// World position x, y, z (full layout).
    pub position: Option<[Plane<'a>; 3]>,
    /// World shading normal x, y, z (full layout).
    pub normal: Option<[Plane<'a>; 3]>,
    /// History confidence in [0, 1] (with `config.history_confidence`).
    pub history_confidence: Option<Plane<'a>>,
    /// World-space motion x, y, z since the previous frame (with `config.motion_vectors`).
    pub motion: Option<[Plane<'a>; 3]>,
}

impl<'a> GBufferView<'a> {
    /// A compact-layout view: depth and octahedral normals, no optional planes.
    pub fn compact(depth: Plane<'a>, normal_oct: Plane<'a, u32>) -> Self {
        Self {
            depth,
            normal_oct: Some(normal_oct),
            position: None,
            normal: None,
            history_confidence: None,
            motion: None,
        }
    }

    /// Checks that the planes `config` reads are present, every present plane has the
    /// pipeline's `extent`, and no plane is given that the configuration would ignore.
    /// `what` names the view in messages (`"left G-buffer"`).
    pub(super) fn check(&self, what: &str, extent: Extent, config: &PipelineConfig) -> Result<(), PipelineError> {
        let missing = |plane: &str| PipelineError::Lent(format!("{what}: the {plane} plane is missing"));
        let unused = |plane: &str, setting: &str| {
            PipelineError::Lent(format!("{what}: a {plane} plane was given but the pipeline has no {setting}"))
        };
        same_extent("lent G-buffer depth", extent, self.depth.extent())?;
        match config.layout {
            Layout::Compact => {
                same_extent(
                    "lent G-buffer normals",
                    extent,
                    self.normal_oct.ok_or_else(|| missing("normal_oct"))?.extent(),
                )?;
            }
            Layout::Full => {
                for p in self.position.ok_or_else(|| missing("position"))?.iter() {
                    same_extent("lent G-buffer position", extent, p.extent())?;
                }
                for p in self.normal.ok_or_else(|| missing("normal"))?.iter() {
                    same_extent("lent G-buffer normal", extent, p.extent())?;
                }
            }
        }
        match (self.history_confidence, config.history_confidence) {
            (Some(c), true) => same_extent("lent history confidence", extent, c.extent())?,
            (None, true) => return Err(missing("history_confidence")),
            (Some(_), false) => return Err(unused("history_confidence", "history_confidence")),
            (None, false) => {}
        }
        match (self.motion, config.motion_vectors) {
            (Some(m), true) => {
                for p in &m {
                    same_extent("lent motion", extent, p.extent())?;
                }
            }
            (None, true) => return Err(missing("motion")),
            (Some(_), false) => return Err(unused("motion", "motion_vectors")),
            (None, false) => {}
        }
        Ok(())
    }
}

/// Both eyes' lent G-buffers of one frame, and the previous frame's where the pipeline's
/// own planes do not hold it.
#[derive(Clone, Copy)]
pub(super) struct Lent<'a> {
    pub current: [GBufferView<'a>; 2],
    pub previous: Option<[GBufferView<'a>; 2]>,
}
