//! The window around a [`Viewer`]: winit for the window and its input, softbuffer for CPU
//! pixels (no GPU). One loop iteration moves the camera by the keys held and the mouse
//! dragged, renders a frame on the viewer's thread pool, composes it and presents it.

use std::num::NonZeroU32;
use std::path::{Path, PathBuf};
use std::rc::Rc;
use std::time::Instant;

use winit::application::ApplicationHandler;
use winit::dpi::PhysicalSize;
use winit::event::{ElementState, KeyEvent, MouseButton, WindowEvent};
use winit::event_loop::{ActiveEventLoop, ControlFlow, EventLoop};
use winit::keyboard::{KeyCode, PhysicalKey};
use winit::window::{Window, WindowId};

use super::{Action, Controls, MODE_KEYS, Viewer};

/// When to stop and what to write.
#[derive(Clone, Debug, Default)]
pub struct RunOptions {
    /// Exit after this many frames (`None`: when the window is closed or Esc pressed).
    pub frames: Option<u32>,
    /// Write the last frame shown as a PNG at exit.
    pub screenshot: Option<PathBuf>,
    /// Write every frame shown as `DIR/frame_00000.png`, ...
    pub record: Option<PathBuf>,
}

/// What a run measured: loop iterations after the first two (which build and warm up).
#[derive(Clone, Debug, Default)]
pub struct RunSummary {
    /// Frames shown.
    pub frames: u32,
    /// Whole loop iterations (frame, composition, presentation), milliseconds.
    pub loop_ms: Vec<f64>,
    /// Pipeline frame times, milliseconds.
    pub frame_ms: Vec<f64>,
    /// Composition (tone mapping, layout, mask, heads-up lines), milliseconds.
    pub compose_ms: Vec<f64>,
    /// Handing the pixels to the window system, milliseconds.
    pub present_ms: Vec<f64>,
    /// Frames over budget.
    pub budget_misses: u64,
}

/// Whether a display is there to open a window on, with the error a user can act on.
pub fn check_display() -> Result<(), String> {
    let set = |v: &str| std::env::var_os(v).is_some_and(|s| !s.is_empty());
    if cfg!(target_os = "linux") && !set("DISPLAY") && !set("WAYLAND_DISPLAY") {
        return Err("no display to open a window on (DISPLAY and WAYLAND_DISPLAY are unset). Without a screen, run \
                    it under a virtual one and keep the image: xvfb-run -s '-screen 0 2560x1440x24' stereotrace view \
                    --frames 30 --screenshot view.png"
            .into());
    }
    Ok(())
}

/// Opens the window and runs until it is closed, Esc, or `options.frames`.
pub fn run(viewer: Viewer<'_>, pool: &rayon::ThreadPool, options: RunOptions) -> Result<RunSummary, String> {
    check_display()?;
    let event_loop = EventLoop::new().map_err(|e| {
        format!(
            "cannot open a window: {e}. Without a screen, run it under xvfb-run with --frames N --screenshot FILE.png"
        )
    })?;
    event_loop.set_control_flow(ControlFlow::Poll);
    if let Some(dir) = &options.record {
        std::fs::create_dir_all(dir).map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
    }
    let (width, height) = viewer.size();
    let capacity = options.frames.map_or(10_000, |f| f as usize);
    let mut app = App {
        viewer,
        pool,
        options,
        window: None,
        pixels: vec![0; width * height],
        held: Held::default(),
        dragging: false,
        cursor: None,
        turn: (0.0, 0.0),
        last: None,
        summary: RunSummary {
            loop_ms: Vec::with_capacity(capacity),
            frame_ms: Vec::with_capacity(capacity),
            ..Default::default()
        },
        error: None,
    };
    event_loop.run_app(&mut app).map_err(|e| format!("the window's event loop failed: {e}"))?;
    if let Some(e) = app.error {
        return Err(e);
    }
    if let Some(path) = &app.options.screenshot {
        write_png(path, &app.pixels, width, height)?;
    }
    app.summary.budget_misses = app.viewer.budget_misses();
    Ok(app.summary)
}

/// Writes `0RGB` pixels as an RGB PNG.
pub fn write_png(path: &Path, pixels: &[u32], width: usize, height: usize) -> Result<(), String> {
    let rgb: Vec<u8> = pixels.iter().flat_map(|p| [(p >> 16) as u8, (p >> 8) as u8, *p as u8]).collect();
    let image = image::RgbImage::from_raw(width as u32, height as u32, rgb).ok_or("image size mismatch")?;
    image.save(path).map_err(|e| format!("cannot write {}: {e}", path.display()))
}

/// Movement keys held down.
#[derive(Default)]
struct Held {
    forward: bool,
    back: bool,
    left: bool,
    right: bool,
    up: bool,
    down: bool,
}

struct Shown {
    window: Rc<Window>,
    surface: softbuffer::Surface<Rc<Window>, Rc<Window>>,
}

struct App<'v, 'r> {
    viewer: Viewer<'r>,
    pool: &'v rayon::ThreadPool,
    options: RunOptions,
    window: Option<Shown>,
    pixels: Vec<u32>,
    held: Held,
    dragging: bool,
    cursor: Option<(f64, f64)>,
    /// Mouse motion since the last frame while dragging, in pixels.
    turn: (f64, f64),
    last: Option<Instant>,
    summary: RunSummary,
    error: Option<String>,
}

impl App<'_, '_> {
    fn fail(&mut self, event_loop: &ActiveEventLoop, message: String) {
        self.error.get_or_insert(message);
        event_loop.exit();
    }

    fn open(&mut self, event_loop: &ActiveEventLoop) -> Result<(), String> {
        let (width, height) = self.viewer.size();
        let attributes = Window::default_attributes()
            .with_title("stereotrace")
            .with_inner_size(PhysicalSize::new(width as u32, height as u32))
            .with_resizable(false);
        let window = Rc::new(event_loop.create_window(attributes).map_err(|e| format!("cannot open a window: {e}"))?);
        let context = softbuffer::Context::new(window.clone()).map_err(|e| format!("softbuffer: {e}"))?;
        let mut surface = softbuffer::Surface::new(&context, window.clone()).map_err(|e| format!("softbuffer: {e}"))?;
        let size = |v: usize| NonZeroU32::new(v as u32).ok_or("zero-sized window");
        surface.resize(size(width)?, size(height)?).map_err(|e| format!("softbuffer: {e}"))?;
        self.window = Some(Shown { window, surface });
        Ok(())
    }

    /// One loop iteration: move, render, compose, present, and record or stop.
    fn frame(&mut self, event_loop: &ActiveEventLoop) -> Result<(), String> {
        let now = Instant::now();
        let seconds = self.last.map_or(0.0, |t| now.duration_since(t).as_secs_f32());
        let axis = |plus: bool, minus: bool| f32::from(u8::from(plus)) - f32::from(u8::from(minus));
        let h = &self.held;
        // A drag across the window's height turns the view by about 90 degrees.
        let radians_per_pixel = std::f32::consts::FRAC_PI_2 / self.viewer.size().1 as f32;
        let controls = Controls {
            forward: axis(h.forward, h.back),
            right: axis(h.right, h.left),
            up: axis(h.up, h.down),
            yaw: self.turn.0 as f32 * radians_per_pixel,
            pitch: -(self.turn.1 as f32) * radians_per_pixel,
            seconds,
        };
        self.turn = (0.0, 0.0);
        let viewer = &mut self.viewer;
        let frame_ms = self.pool.install(|| viewer.step(&controls).map(|s| s.times.total.as_secs_f64() * 1e3))?;
        let composing = Instant::now();
        let (viewer, pixels) = (&mut self.viewer, &mut self.pixels);
        self.pool.install(|| viewer.compose(pixels));
        let presenting = Instant::now();
        let shown = self.window.as_mut().ok_or("no window")?;
        let mut buffer = shown.surface.buffer_mut().map_err(|e| format!("softbuffer: {e}"))?;
        buffer.copy_from_slice(&self.pixels);
        buffer.present().map_err(|e| format!("softbuffer: {e}"))?;
        let presented = Instant::now();
        let ms = |from: Instant, to: Instant| to.duration_since(from).as_secs_f64() * 1e3;
        let (width, height) = self.viewer.size();
        if let Some(dir) = &self.options.record {
            let path = dir.join(format!("frame_{:05}.png", self.summary.frames));
            write_png(&path, &self.pixels, width, height)?;
        }
        if let Some(t) = self.last {
            let loop_ms = now.duration_since(t).as_secs_f64() * 1e3;
            self.viewer.record_loop(loop_ms);
            // The first two frames build and warm up; the capacity bounds the record.
            if self.summary.frames >= 2 && self.summary.loop_ms.len() < self.summary.loop_ms.capacity() {
                self.summary.loop_ms.push(loop_ms);
                self.summary.frame_ms.push(frame_ms);
                self.summary.compose_ms.push(ms(composing, presenting));
                self.summary.present_ms.push(ms(presenting, presented));
            }
        }
        self.last = Some(now);
        self.summary.frames += 1;
        if self.options.frames.is_some_and(|n| self.summary.frames >= n) {
            event_loop.exit();
        }
        Ok(())
    }

    fn key(&mut self, event_loop: &ActiveEventLoop, code: KeyCode, pressed: bool, repeat: bool) -> Result<(), String> {
        let h = &mut self.held;
        match code {
            KeyCode::KeyW | KeyCode::ArrowUp => h.forward = pressed,
            KeyCode::KeyS | KeyCode::ArrowDown => h.back = pressed,
            KeyCode::KeyA | KeyCode::ArrowLeft => h.left = pressed,
            KeyCode::KeyD | KeyCode::ArrowRight => h.right = pressed,
            KeyCode::KeyE | KeyCode::PageUp => h.up = pressed,
            KeyCode::KeyQ | KeyCode::PageDown => h.down = pressed,
            _ if !pressed || repeat => {}
            KeyCode::Escape => event_loop.exit(),
            KeyCode::Digit1 => self.viewer.act(Action::Mode(MODE_KEYS[0]))?,
            KeyCode::Digit2 => self.viewer.act(Action::Mode(MODE_KEYS[1]))?,
            KeyCode::Digit3 => self.viewer.act(Action::Mode(MODE_KEYS[2]))?,
            KeyCode::Equal | KeyCode::NumpadAdd => self.viewer.act(Action::Budget(5.0))?,
            KeyCode::Minus | KeyCode::NumpadSubtract => self.viewer.act(Action::Budget(-5.0))?,
            KeyCode::KeyM => self.viewer.act(Action::ToggleMask)?,
            KeyCode::KeyH => self.viewer.act(Action::ToggleHud)?,
            KeyCode::KeyR => self.viewer.act(Action::Reset)?,
            KeyCode::KeyP => self.viewer.act(Action::TogglePath)?,
            _ => {}
        }
        Ok(())
    }
}

impl ApplicationHandler for App<'_, '_> {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.window.is_none()
            && let Err(e) = self.open(event_loop)
        {
            self.fail(event_loop, e);
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _: WindowId, event: WindowEvent) {
        let result = match event {
            WindowEvent::CloseRequested => {
                event_loop.exit();
                Ok(())
            }
            WindowEvent::RedrawRequested => self.frame(event_loop),
            WindowEvent::KeyboardInput {
                event: KeyEvent { physical_key: PhysicalKey::Code(code), state, repeat, .. },
                ..
            } => self.key(event_loop, code, state == ElementState::Pressed, repeat),
            WindowEvent::MouseInput { state, button: MouseButton::Left, .. } => {
                self.dragging = state == ElementState::Pressed;
                Ok(())
            }
            WindowEvent::CursorMoved { position, .. } => {
                if let (true, Some((x, y))) = (self.dragging, self.cursor) {
                    self.turn.0 += position.x - x;
                    self.turn.1 += position.y - y;
                }
                self.cursor = Some((position.x, position.y));
                Ok(())
            }
            _ => Ok(()),
        };
        if let Err(e) = result {
            self.fail(event_loop, e);
        }
    }

    fn about_to_wait(&mut self, _: &ActiveEventLoop) {
        if let Some(shown) = &self.window {
            shown.window.request_redraw();
        }
    }
}
