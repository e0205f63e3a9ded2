//! `stereotrace view`: the pipeline live in a window.
//!
//! [`Viewer`] is everything but the window: a [`Session`] (the frame loop every command
//! uses, here driven by a free camera through [`Session::next_frame_at`]), the camera, the
//! keys' settings, and the composition of both eyes, the traced-pixel mask and the heads-up
//! lines into one `0RGB` image. [`window`] is the winit + softbuffer shell around it. After
//! the first frame, a step and a composition allocate nothing (`tests/viewer.rs` counts).

pub mod display;
pub mod hud;
pub mod window;

use std::fmt::Write as _;

use glam::Vec3;
use rayon::prelude::*;

use crate::camera::{CameraPose, Eye, StereoRig};
use crate::kernels::Extent;
use crate::pipeline::{FrameStats, Mode, Pipeline, PipelineConfig};
use crate::render::{Renderer, RendererOptions};
use crate::session::{CameraWalk, Session};

/// How the two eyes are shown.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum StereoLayout {
    /// Left eye on the left, right eye on the right (the window is two eyes wide).
    SideBySide,
    /// The left eye only.
    Left,
    /// The right eye only.
    Right,
    /// Red from the left eye, green and blue from the right (red-cyan glasses).
    Anaglyph,
}

/// What the user does between two frames.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Controls {
    /// Forward (+) or back (−), in `[-1, 1]`.
    pub forward: f32,
    /// Right (+) or left (−).
    pub right: f32,
    /// Up (+) or down (−).
    pub up: f32,
    /// Turn to the right, radians.
    pub yaw: f32,
    /// Look up, radians.
    pub pitch: f32,
    /// Seconds since the last frame (scales the motion).
    pub seconds: f32,
}

/// A free-flying camera: a position, a heading and a pitch (no roll).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FlyCamera {
    eye: Vec3,
    yaw: f32,
    pitch: f32,
    vfov_deg: f32,
    /// Metres per second at full speed.
    speed: f32,
}

impl FlyCamera {
    /// Starts at `pose`, moving `speed` metres per second.
    pub fn new(pose: &CameraPose, speed: f32) -> Self {
        let f = pose.forward;
        Self { eye: pose.eye, yaw: f.x.atan2(-f.z), pitch: f.y.clamp(-1.0, 1.0).asin(), vfov_deg: pose.vfov_deg, speed }
    }

    /// The head pose.
    pub fn pose(&self) -> CameraPose {
        let forward =
            Vec3::new(self.yaw.sin() * self.pitch.cos(), self.pitch.sin(), -self.yaw.cos() * self.pitch.cos());
        let right = forward.cross(Vec3::Y).try_normalize().unwrap_or(Vec3::X);
        let up = right.cross(forward);
        CameraPose { eye: self.eye, forward, up, right, vfov_deg: self.vfov_deg }
    }

    /// Moves and turns by `controls`.
    pub fn apply(&mut self, controls: &Controls) {
        let limit = 89f32.to_radians();
        self.yaw += controls.yaw;
        self.pitch = (self.pitch + controls.pitch).clamp(-limit, limit);
        let pose = self.pose();
        let step = self.speed * controls.seconds.clamp(0.0, 0.25);
        self.eye += (pose.forward * controls.forward + pose.right * controls.right + Vec3::Y * controls.up) * step;
    }
}

/// A key's action.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Action {
    /// Switch the pipeline's mode (the history starts again).
    Mode(Mode),
    /// Change the budget by this many milliseconds (at least 1 ms).
    Budget(f64),
    /// Show or hide the pixels traced this frame.
    ToggleMask,
    /// Show or hide the heads-up lines.
    ToggleHud,
    /// Forget the history.
    Reset,
    /// Follow the scene's camera path back and forth (as `throughput` does), or stop.
    TogglePath,
}

/// The modes the keys 1, 2 and 3 pick.
pub const MODE_KEYS: [Mode; 3] = [Mode::PathTraced, Mode::Spatiotemporal, Mode::SpatiotemporalBlend];

/// How many of the last frames the heads-up averages.
const WINDOW: usize = 32;

/// The pipeline, its camera and what the window shows.
pub struct Viewer<'r> {
    session: Session<&'r Renderer>,
    camera: FlyCamera,
    layout: StereoLayout,
    exposure: f32,
    show_mask: bool,
    show_hud: bool,
    follow_path: bool,
    scene: String,
    last: Option<FrameStats>,
    /// Whole loop iterations (frame, composition, presentation), milliseconds, a ring.
    loop_ms: [f64; WINDOW],
    loops: usize,
    budget_misses: u64,
    /// The right eye tone mapped, for the anaglyph (empty in other layouts).
    right_eye: Vec<u32>,
    hud: String,
}

impl<'r> Viewer<'r> {
    /// A viewer of `renderer`'s scene in `layout`, each eye `extent`, starting at the scene's
    /// first camera pose.
    pub fn new(
        renderer: &'r Renderer,
        options: RendererOptions,
        config: PipelineConfig,
        extent: Extent,
        layout: StereoLayout,
    ) -> Result<Self, String> {
        let pipeline = Pipeline::with_options(renderer, options, config, StereoRig::default(), extent)
            .map_err(|e| e.to_string())?;
        let scene = renderer.scene();
        // A tenth of the scene's size per second: a room is crossed in a few seconds.
        let speed = (0.1 * scene.bounds().extent().length()).clamp(0.05, 20.0);
        Ok(Self {
            session: Session::new(pipeline, CameraWalk::BackAndForth),
            camera: FlyCamera::new(&scene.camera.pose(0), speed),
            layout,
            exposure: 1.0,
            show_mask: false,
            show_hud: true,
            follow_path: false,
            scene: scene.name.clone(),
            last: None,
            loop_ms: [0.0; WINDOW],
            loops: 0,
            budget_misses: 0,
            right_eye: if layout == StereoLayout::Anaglyph { vec![0; extent.pixels()] } else { Vec::new() },
            hud: String::with_capacity(1024),
        })
    }

    /// The composed image's width and height.
    pub fn size(&self) -> (usize, usize) {
        let e = self.session.pipeline().extent();
        let eyes = if self.layout == StereoLayout::SideBySide { 2 } else { 1 };
        (eyes * e.width(), e.height())
    }

    /// Moves the camera by `controls` (or along the scene's camera path, when following it)
    /// and renders one stereo frame.
    pub fn step(&mut self, controls: &Controls) -> Result<&FrameStats, String> {
        let stats = if self.follow_path {
            let stats = self.session.next_frame().map_err(|e| e.to_string())?;
            // Leaving the path later starts where it is now.
            let path = &self.session.pipeline().source().renderer().scene().camera;
            self.camera = FlyCamera::new(&path.pose_back_and_forth(stats.frame), self.camera.speed);
            stats
        } else {
            self.camera.apply(controls);
            self.session.next_frame_at(&self.camera.pose()).map_err(|e| e.to_string())?
        };
        self.budget_misses += u64::from(stats.budget.is_some() && !stats.budget_met);
        Ok(self.last.insert(stats))
    }

    /// Records how long one whole loop iteration took (for the heads-up's frame rate).
    pub fn record_loop(&mut self, milliseconds: f64) {
        self.loop_ms[self.loops % WINDOW] = milliseconds;
        self.loops += 1;
    }

    /// Frames per second over the last loop iterations (0 before any).
    pub fn fps(&self) -> f64 {
        let n = self.loops.min(WINDOW);
        let total: f64 = self.loop_ms[..n].iter().sum();
        if total > 0.0 { 1e3 * n as f64 / total } else { 0.0 }
    }

    /// Budget misses so far.
    pub fn budget_misses(&self) -> u64 {
        self.budget_misses
    }

    /// The last frame's statistics.
    pub fn last_frame(&self) -> Option<&FrameStats> {
        self.last.as_ref()
    }

    /// Applies a key's action.
    pub fn act(&mut self, action: Action) -> Result<(), String> {
        let config = *self.session.pipeline().config();
        match action {
            Action::Mode(mode) => self.reconfigure(PipelineConfig { mode, ..config })?,
            Action::Budget(delta) => {
                let current = config.budget.map_or(50.0, |b| b.as_secs_f64() * 1e3);
                let budget = crate::pipeline::budget_duration((current + delta).max(1.0))?;
                self.reconfigure(PipelineConfig { budget: Some(budget), ..config })?;
            }
            Action::ToggleMask => self.show_mask = !self.show_mask,
            Action::ToggleHud => self.show_hud = !self.show_hud,
            Action::Reset => self.session.pipeline_mut().reset(),
            Action::TogglePath => self.follow_path = !self.follow_path,
        }
        Ok(())
    }

    fn reconfigure(&mut self, config: PipelineConfig) -> Result<(), String> {
        self.session.pipeline_mut().reconfigure(config).map_err(|e| e.to_string())
    }

    /// Draws the last frame into `out` (`size()` pixels, `0RGB`): the eyes in the layout, the
    /// traced mask if on, and the heads-up lines if on. Rows are shared out over the current
    /// rayon pool.
    pub fn compose(&mut self, out: &mut [u32]) {
        let (width, height) = self.size();
        assert_eq!(out.len(), width * height, "compose: the output must be size() pixels");
        let pipeline = self.session.pipeline();
        let eye_width = pipeline.extent().width();
        let (exposure, show_mask) = (self.exposure, self.show_mask);
        let row_of = |eye: Eye, y: usize, into: &mut [u32]| {
            let img = pipeline.output(eye);
            let span = y * eye_width..(y + 1) * eye_width;
            let (r, g, b) =
                (&img.r().as_slice()[span.clone()], &img.g().as_slice()[span.clone()], &img.b().as_slice()[span]);
            display::tonemap_row(r, g, b, exposure, into);
            if show_mask {
                let mask = &pipeline.traced_mask(eye).as_slice()[y * eye_width..(y + 1) * eye_width];
                for (p, &m) in into.iter_mut().zip(mask) {
                    if m != 0 {
                        *p = ((*p >> 1) & 0x007f_7f7f) + 0x0000_7f00;
                    }
                }
            }
        };
        let rows = out.par_chunks_mut(width).enumerate();
        match self.layout {
            StereoLayout::SideBySide => rows.for_each(|(y, row)| {
                let (left, right) = row.split_at_mut(eye_width);
                row_of(Eye::Left, y, left);
                row_of(Eye::Right, y, right);
            }),
            StereoLayout::Left => rows.for_each(|(y, row)| row_of(Eye::Left, y, row)),
            StereoLayout::Right => rows.for_each(|(y, row)| row_of(Eye::Right, y, row)),
            StereoLayout::Anaglyph => rows.zip(self.right_eye.par_chunks_mut(width)).for_each(|((y, row), right)| {
                row_of(Eye::Left, y, row);
                row_of(Eye::Right, y, right);
                for (p, r) in row.iter_mut().zip(right.iter()) {
                    *p = (*p & 0x00ff_0000) | (r & 0x0000_ffff);
                }
            }),
        }
        if self.show_hud {
            self.write_hud();
            hud::draw(out, width, &self.hud);
        }
    }

    /// The heads-up lines, written into the reused string.
    fn write_hud(&mut self) {
        self.hud.clear();
        let config = self.session.pipeline().config();
        let pixels = self.session.pipeline().extent().pixels() as f64;
        let budget = config.budget.map_or(-1.0, |b| b.as_secs_f64() * 1e3);
        let _ = write!(self.hud, "{} | {} | budget ", self.scene, config.mode.name());
        if budget < 0.0 {
            let _ = write!(self.hud, "none");
        } else {
            let _ = write!(self.hud, "{budget:.0} ms");
        }
        let _ = write!(self.hud, " | {:.1} fps", self.fps());
        if let Some(s) = &self.last {
            let ms = |d: std::time::Duration| d.as_secs_f64() * 1e3;
            let t = &s.times;
            let _ = write!(
                self.hud,
                "\nframe {:.1} ms: G-buffer {:.1}, reprojection {:.1}, tracing {:.1}, accumulation {:.1} | traced L {:.0} % R {:.0} % | misses {}",
                ms(t.total),
                ms(t.gbuffer),
                ms(t.reprojection),
                ms(t.tracing + t.urgent_tracing),
                ms(t.accumulation),
                100.0 * s.pixels_traced(0) as f64 / pixels,
                100.0 * s.pixels_traced(1) as f64 / pixels,
                self.budget_misses
            );
        }
        let _ = write!(
            self.hud,
            "\nWASD QE move, drag to look | P follow the path | 1 path traced, 2 spatiotemporal, 3 blend | +/- budget | M traced | H hud | R reset | Esc quit"
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_fly_camera_moves_along_its_heading_and_keeps_level() {
        let start = crate::scene::resolve("cornell").unwrap().camera.pose(0);
        let mut camera = FlyCamera::new(&start, 2.0);
        let pose = camera.pose();
        assert!(pose.forward.abs_diff_eq(start.forward, 1e-5), "{} vs {}", pose.forward, start.forward);
        assert!(pose.eye == start.eye);
        camera.apply(&Controls { forward: 1.0, seconds: 0.1, ..Controls::default() });
        assert!((camera.pose().eye - (start.eye + start.forward * 0.2)).length() < 1e-5);
        // A quarter turn to the right: the old right is the new forward; never any roll.
        camera.apply(&Controls { yaw: std::f32::consts::FRAC_PI_2, ..Controls::default() });
        let turned = camera.pose();
        let heading = Vec3::new(turned.forward.x, 0.0, turned.forward.z).normalize();
        assert!(heading.abs_diff_eq(pose.right, 1e-5), "{heading} vs {}", pose.right);
        assert!((turned.forward.y - pose.forward.y).abs() < 1e-6, "the pitch is kept");
        assert!(turned.right.y.abs() < 1e-6 && turned.up.y > 0.99);
        // Pitch stops short of straight up.
        camera.apply(&Controls { pitch: 10.0, ..Controls::default() });
        assert!(camera.pose().forward.y < 0.9999 && camera.pose().forward.y > 0.99);
    }
}
