//! The renderer: a scene with its BVH and effect bits, ready to render any frame and eye.
//! Its passes live beside it: the estimator (`estimator.rs`), the two trace loops
//! (`trace.rs`, `packets.rs`) and the G-buffer passes (`gbuffer.rs`, `raster.rs`).

use std::time::Duration;

use glam::Vec3;

use crate::kernels::bvh::{BuildQuality, BuildStats, BvhBuildParams, Ray, TriangleBvh};
use crate::kernels::{CameraModel, FrameError};
use crate::scene::Scene;

use super::effects;
use super::lights::FrameLights;

/// Why rendering could not start.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    #[error("BVH build failed: {0}")]
    /// The scene's BVH could not be built.
    Bvh(#[from] crate::kernels::bvh::BvhError),
    #[error(transparent)]
    /// A buffer, extent or camera was refused.
    Frame(#[from] FrameError),
    #[error("{0}")]
    /// An input was refused (the message says which).
    Invalid(String),
}

/// A scene with its BVH, ready to render any frame and eye.
pub struct Renderer {
    pub(super) scene: Scene,
    pub(super) bvh: TriangleBvh,
    pub(super) bvh_stats: BuildStats,
    pub(super) bits: u16,
    /// 1: the paper's estimator; 0: direct lighting only (see [`Renderer::set_bounces`]).
    pub(super) bounces: u32,
    /// The rasterised G-buffer's near plane: a millionth of the scene's size (the traced
    /// pass sees from depth 0; geometry nearer than this to the eye is not rasterised).
    pub(super) raster_near: f32,
    /// [`Mesh::geometric_normal`](crate::scene::Mesh::geometric_normal) of every triangle,
    /// computed once: every hit needs it, and a cross product, a square root and a division
    /// per hit were a tenth of a Cornell box render's profile. The same values bit for bit.
    pub(super) geometric_normals: Vec<Vec3>,
}

impl Renderer {
    /// Builds the BVH for `scene` (validated first) with the default [`BuildQuality`].
    pub fn new(scene: Scene) -> Result<Self, RenderError> {
        Self::with_bvh_quality(scene, BuildQuality::default())
    }

    /// [`Renderer::new`] with the tree built at `quality` (for example the fast PLOC build for
    /// a scene loaded for a few frames, or to compare trees on whole frames).
    ///
    /// # Errors
    /// Those of [`Renderer::new`].
    pub fn with_bvh_quality(scene: Scene, quality: BuildQuality) -> Result<Self, RenderError> {
        scene.validate().map_err(|e| RenderError::Invalid(e.to_string()))?;
        let built = TriangleBvh::build(&scene.mesh.positions, quality)?;
        Self::with_bvh(scene, built)
    }

    /// [`Renderer::new`] with the tree built from obvhs's parameters `params`: an engine that
    /// loads a scene once and traces it for many frames can pay a longer build for faster
    /// traversal (BENCHMARKS.md, "the tree's build parameters", measures the trade). Images
    /// are the same with any tree except which triangle wins an exact tie in `t`.
    ///
    /// # Errors
    /// Those of [`Renderer::new`], and `RenderError::Bvh` for parameters the builder refuses.
    pub fn with_bvh_params(scene: Scene, params: &BvhBuildParams) -> Result<Self, RenderError> {
        scene.validate().map_err(|e| RenderError::Invalid(e.to_string()))?;
        let built = TriangleBvh::build_with(&scene.mesh.positions, params)?;
        Self::with_bvh(scene, built)
    }

    /// The renderer of a validated `scene` over its built tree; an error when the normals'
    /// table cannot be allocated.
    fn with_bvh(scene: Scene, (bvh, bvh_stats): (TriangleBvh, BuildStats)) -> Result<Self, RenderError> {
        let bits = effects::bits_for(scene.effects);
        let raster_near = (scene.bounds().extent().length() * 1e-6).max(1e-9);
        let mesh = &scene.mesh;
        let mut geometric_normals = crate::kernels::frame::try_filled_vec(mesh.len(), Vec3::ZERO)?;
        for (tri, n) in geometric_normals.iter_mut().enumerate() {
            *n = mesh.geometric_normal(tri);
        }
        Ok(Self { scene, bvh, bvh_stats, bits, bounces: 1, raster_near, geometric_normals })
    }

    /// Chooses the estimator: `1` (the default) is the paper's, one primary and one secondary
    /// bounce; `0` stops after next-event estimation at the primary hit (direct lighting
    /// only: what a renderer with a maximum path depth of 2 computes). A `0` estimate is the
    /// first part of the `1` estimate with the same random numbers.
    pub fn set_bounces(&mut self, bounces: u32) -> Result<(), RenderError> {
        if bounces > 1 {
            return Err(RenderError::Invalid(format!("bounces {bounces}: the estimator supports 0 or 1")));
        }
        self.bounces = bounces;
        Ok(())
    }

    /// The estimator's bounces (see [`Renderer::set_bounces`]).
    pub fn bounces(&self) -> u32 {
        self.bounces
    }

    /// The scene being rendered.
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// The scene's BVH.
    pub fn bvh(&self) -> &TriangleBvh {
        &self.bvh
    }

    /// How long the BVH build took.
    pub fn bvh_build_time(&self) -> Duration {
        self.bvh_stats.total_time
    }

    /// How the BVH was built (time, nodes, quality).
    pub fn bvh_stats(&self) -> &BuildStats {
        &self.bvh_stats
    }

    /// The integrator effect bits of the scene.
    pub fn effect_bits(&self) -> u16 {
        self.bits
    }

    /// The light table of `frame`.
    pub fn frame_lights(&self, frame: u32) -> FrameLights {
        FrameLights::new(&self.scene, frame)
    }
}

/// Jitter-free ray through a pixel centre (what the G-buffer uses), for tests.
pub fn pixel_centre_ray(camera: &CameraModel, x: usize, y: usize) -> Ray {
    Ray::new(Vec3::from(camera.centre), Vec3::from(camera.ray(x as f32 + 0.5, y as f32 + 0.5)))
}
