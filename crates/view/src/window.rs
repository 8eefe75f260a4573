//! The interactive window (feature `window`, winit on X11): steps the simulation in real
//! time and draws every frame.
//!
//! Each frame takes as many steps as the wall time since the last one, times the speed
//! factor, allows, up to [`WindowOptions::max_steps_per_frame`] and 40 ms of stepping;
//! time that could not be simulated is dropped, so a slow scene runs slower than real time
//! instead of falling behind. The title shows the puncture state, simulated time, depth,
//! axial force and the ratio of simulated to wall time (there is no text in the picture).
//!
//! Keys: Space pauses; N or `.` takes one step while paused; R rebuilds the simulation;
//! `+`/`-` double or halve the speed; Escape or Q closes. Needle, while held: Up/Down
//! advance/withdraw along the needle, Left/Right turn it about the vertical (+z) through
//! the entry point (the base before contact), PageUp/PageDown tilt it up/down about the
//! same point. The first manual move ends the scene's script ([`Simulation::set_pose`]).
//! Mouse: drag with the left button to orbit, wheel to zoom; drag with the right button to
//! move the needle ([`WindowOptions::mouse_advance`] m per pixel up, advancing;
//! [`WindowOptions::mouse_turn`] degrees per pixel sideways, turning about the same pivot).
//!
//! With [`WindowOptions::share_gpu`] the simulation's GPU backend runs on the window's own
//! device (one adapter that can present, one device, one queue): the build closure gets
//! its [`GpuContext`]. Otherwise the closure gets `None` and picks its backend itself.

use crate::camera::Camera;
use crate::frame::Frame;
use crate::render::{device_on, request_adapter, view_limits, Renderer};
use crate::ViewError;
use glam::{DQuat, DVec3};
use needlesim_gpu::GpuContext;
use needlesim_needle::{PunctureState, Simulation};
use std::collections::HashSet;
use std::sync::Arc;
use std::time::{Duration, Instant};
use winit::application::ApplicationHandler;
use winit::event::{ElementState, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, ControlFlow, EventLoop};
use winit::keyboard::{Key, NamedKey};
use winit::window::{Window, WindowId};

/// Settings of [`run_window`].
#[derive(Debug, Clone, PartialEq)]
pub struct WindowOptions {
    /// Initial inner width, logical pixels.
    pub width: u32,
    /// Initial inner height, logical pixels.
    pub height: u32,
    /// Simulated seconds per wall second at the start (changed with `+`/`-`).
    pub speed: f64,
    /// Most simulation steps per drawn frame.
    pub max_steps_per_frame: u32,
    /// Needle speed of the Up/Down keys, m per simulated second.
    pub advance_speed: f64,
    /// Turn and tilt rate of the arrow and page keys, degrees per simulated second.
    pub turn_rate: f64,
    /// Needle advance per pixel of right-button drag upwards, m (applied at up to twice
    /// `advance_speed`; likewise the turn at up to twice `turn_rate`).
    pub mouse_advance: f64,
    /// Needle turn per pixel of right-button drag sideways, degrees.
    pub mouse_turn: f64,
    /// The window title's prefix (the scene name, say).
    pub title: String,
    /// `Some(bytes)`: run the simulation on the window's GPU device. The device is made
    /// with the kernels' limits for storage bindings of `bytes` (the scene's
    /// `needlesim_gpu::largest_buffer`) and the build closure receives its context.
    pub share_gpu: Option<u64>,
    /// Close the window after this many drawn frames (smoke tests); `None` runs until
    /// closed.
    pub frames: Option<u64>,
}

impl Default for WindowOptions {
    fn default() -> Self {
        WindowOptions {
            width: 1024,
            height: 768,
            speed: 1.0,
            max_steps_per_frame: 200,
            advance_speed: 0.05,
            turn_rate: 20.0,
            mouse_advance: 2e-4,
            mouse_turn: 0.2,
            title: "needlesim".into(),
            share_gpu: None,
            frames: None,
        }
    }
}

/// Builds the simulation: at the start and on every reset (R). The argument is the
/// window's GPU context when [`WindowOptions::share_gpu`] is set (build the GPU backend on
/// it), `None` otherwise.
pub type Build = Box<
    dyn FnMut(Option<&GpuContext>) -> Result<Simulation, Box<dyn std::error::Error + Send + Sync>>,
>;

/// What a window session did, returned when it closes.
#[derive(Debug, Clone, PartialEq)]
pub struct WindowReport {
    /// Frames drawn.
    pub frames: u64,
    /// Simulated time at the close (since the last reset), s.
    pub simulated: f64,
    /// Wall time from the first frame to the close, s.
    pub wall: f64,
    /// The adapter drawn on ([`GpuContext::describe`]'s form when shared).
    pub adapter: String,
    /// Whether the simulation ran on the window's device.
    pub shared_gpu: bool,
}

/// Wall time spent stepping per frame at most.
const STEP_BUDGET: Duration = Duration::from_millis(40);

/// Opens a window, steps the simulation that `build` makes in real time and draws it until
/// the window is closed (or [`WindowOptions::frames`] are drawn). Errors of the simulation
/// or the GPU close the window and come back here.
pub fn run_window(mut build: Build, options: WindowOptions) -> Result<WindowReport, ViewError> {
    // Without a shared device the simulation is built at once (a bad scene fails before a
    // window opens); with one, when the window's device exists.
    let sim = match options.share_gpu {
        None => Some(build(None).map_err(|e| ViewError::Build(e.to_string()))?),
        Some(_) => None,
    };
    let event_loop = EventLoop::new().map_err(|e| ViewError::Window(e.to_string()))?;
    event_loop.set_control_flow(ControlFlow::Poll);
    let mut app = App {
        speed: options.speed,
        options,
        build,
        sim,
        gfx: None,
        camera: None,
        paused: false,
        single_step: false,
        keys: HashSet::new(),
        dragging: false,
        steering: false,
        mouse_motion: [0.0; 3],
        cursor: None,
        last: Instant::now(),
        backlog: 0.0,
        ratio: Ratio::default(),
        title_at: Instant::now(),
        error: None,
        frames: 0,
        started: None,
    };
    event_loop
        .run_app(&mut app)
        .map_err(|e| ViewError::Window(e.to_string()))?;
    if let Some(e) = app.error {
        return Err(e);
    }
    Ok(WindowReport {
        frames: app.frames,
        simulated: app.sim.as_ref().map_or(0.0, |s| s.time()),
        wall: app.started.map_or(0.0, |t| t.elapsed().as_secs_f64()),
        adapter: app
            .gfx
            .as_ref()
            .map_or(String::new(), |g| g.adapter.clone()),
        shared_gpu: app.gfx.as_ref().is_some_and(|g| g.gpu.is_some()),
    })
}

/// The window and what draws into it.
struct Gfx {
    window: Arc<Window>,
    surface: wgpu::Surface<'static>,
    config: wgpu::SurfaceConfiguration,
    renderer: Renderer,
    /// The simulation's context when it shares the window's device.
    gpu: Option<GpuContext>,
    /// The adapter, in words.
    adapter: String,
}

impl Gfx {
    fn new(event_loop: &ActiveEventLoop, options: &WindowOptions) -> Result<Gfx, ViewError> {
        let attributes = Window::default_attributes()
            .with_title(options.title.clone())
            .with_inner_size(winit::dpi::LogicalSize::new(options.width, options.height));
        let window = Arc::new(
            event_loop
                .create_window(attributes)
                .map_err(|e| ViewError::Window(e.to_string()))?,
        );
        let instance =
            wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        let surface = instance
            .create_surface(window.clone())
            .map_err(|e| ViewError::Window(format!("creating the surface: {e}")))?;
        let adapter = request_adapter(&instance, Some(&surface))?;
        let (gpu, device, queue, name) = match options.share_gpu {
            Some(bytes) => {
                let ctx = GpuContext::on_adapter(&adapter, bytes, view_limits(&adapter))?;
                let (d, q, name) = (ctx.device.clone(), ctx.queue.clone(), ctx.describe());
                (Some(ctx), d, q, name)
            }
            None => {
                let (d, q) = device_on(&adapter)?;
                (None, d, q, adapter.get_info().name)
            }
        };
        let size = window.inner_size();
        let mut config = surface
            .get_default_config(&adapter, size.width.max(1), size.height.max(1))
            .ok_or_else(|| ViewError::Window("the adapter cannot present to this window".into()))?;
        // Plain 8-bit formats keep the colours of screenshots.
        let caps = surface.get_capabilities(&adapter);
        if let Some(&f) = caps.formats.iter().find(|f| {
            matches!(
                f,
                wgpu::TextureFormat::Bgra8Unorm | wgpu::TextureFormat::Rgba8Unorm
            )
        }) {
            config.format = f;
        }
        config.present_mode = wgpu::PresentMode::AutoVsync;
        surface.configure(&device, &config);
        let renderer = Renderer::with_format(&device, &queue, config.format);
        Ok(Gfx {
            window,
            surface,
            config,
            renderer,
            gpu,
            adapter: name,
        })
    }

    fn resize(&mut self, width: u32, height: u32) {
        self.config.width = width.max(1);
        self.config.height = height.max(1);
        self.surface.configure(self.renderer.device(), &self.config);
    }

    fn draw(&mut self, frame: &Frame, camera: &Camera) -> Result<(), ViewError> {
        let texture = match self.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(t)
            | wgpu::CurrentSurfaceTexture::Suboptimal(t) => t,
            wgpu::CurrentSurfaceTexture::Outdated | wgpu::CurrentSurfaceTexture::Lost => {
                let (w, h) = (self.config.width, self.config.height);
                self.resize(w, h);
                return Ok(());
            }
            wgpu::CurrentSurfaceTexture::Timeout | wgpu::CurrentSurfaceTexture::Occluded => {
                return Ok(())
            }
            wgpu::CurrentSurfaceTexture::Validation => {
                return Err(ViewError::Render(
                    "the surface texture failed validation".into(),
                ))
            }
        };
        let view = texture.texture.create_view(&Default::default());
        self.renderer
            .draw(frame, camera, &view, self.config.width, self.config.height)?;
        self.window.pre_present_notify();
        self.renderer.queue().present(texture);
        Ok(())
    }
}

/// Simulated and wall time over the last second or so, for the title.
#[derive(Debug, Default)]
struct Ratio {
    simulated: f64,
    wall: f64,
    shown: f64,
}

impl Ratio {
    fn add(&mut self, simulated: f64, wall: f64) {
        self.simulated += simulated;
        self.wall += wall;
        if self.wall > 1.0 {
            self.shown = self.simulated / self.wall;
            self.simulated = 0.0;
            self.wall = 0.0;
        }
    }
}

struct App {
    options: WindowOptions,
    build: Build,
    /// `None` until the window's device exists when the simulation shares it.
    sim: Option<Simulation>,
    gfx: Option<Gfx>,
    camera: Option<Camera>,
    speed: f64,
    paused: bool,
    single_step: bool,
    keys: HashSet<NamedKey>,
    dragging: bool,
    /// Right button held: the mouse moves the needle.
    steering: bool,
    /// Needle motion from the mouse not yet applied (advance m, turn rad, tilt rad).
    mouse_motion: [f64; 3],
    cursor: Option<(f64, f64)>,
    last: Instant,
    /// Simulated time owed to real time, s.
    backlog: f64,
    ratio: Ratio,
    title_at: Instant,
    error: Option<ViewError>,
    /// Frames drawn.
    frames: u64,
    /// When the first frame was drawn.
    started: Option<Instant>,
}

/// The needle's manual motion for one step from the held keys: (advance m, turn rad,
/// tilt rad), or `None` when no needle key is held.
fn manual_motion(keys: &HashSet<NamedKey>, o: &WindowOptions, dt: f64) -> Option<[f64; 3]> {
    let axis = |plus: NamedKey, minus: NamedKey| {
        keys.contains(&plus) as i32 as f64 - keys.contains(&minus) as i32 as f64
    };
    let advance = axis(NamedKey::ArrowUp, NamedKey::ArrowDown) * o.advance_speed * dt;
    let rate = o.turn_rate.to_radians() * dt;
    let turn = axis(NamedKey::ArrowLeft, NamedKey::ArrowRight) * rate;
    let tilt = axis(NamedKey::PageUp, NamedKey::PageDown) * rate;
    (advance != 0.0 || turn != 0.0 || tilt != 0.0).then_some([advance, turn, tilt])
}

/// The pose after moving the needle (`base`, unit `dir`) by `advance` along itself, turning
/// it by `turn` about +z and tilting it by `tilt` (positive lifts the tip) about `pivot`.
pub fn moved_pose(
    base: [f64; 3],
    dir: [f64; 3],
    pivot: [f64; 3],
    [advance, turn, tilt]: [f64; 3],
) -> ([f64; 3], [f64; 3]) {
    let (base, dir, pivot) = (DVec3::from(base), DVec3::from(dir), DVec3::from(pivot));
    let side = dir.cross(DVec3::Z);
    let side = if side.length() > 1e-9 {
        side.normalize()
    } else {
        DVec3::X
    };
    let rot = DQuat::from_axis_angle(DVec3::Z, turn) * DQuat::from_axis_angle(side, tilt);
    let base = pivot + rot * (base + dir * advance - pivot);
    let dir = (rot * dir).normalize();
    (base.into(), dir.into())
}

impl App {
    fn fail(&mut self, event_loop: &ActiveEventLoop, e: ViewError) {
        self.error = Some(e);
        event_loop.exit();
    }

    /// Builds (or rebuilds) the simulation, on the window's device when it is shared.
    fn rebuild(&mut self) -> Result<(), ViewError> {
        let ctx = self.gfx.as_ref().and_then(|g| g.gpu.as_ref());
        let sim = (self.build)(ctx).map_err(|e| ViewError::Build(e.to_string()))?;
        self.sim = Some(sim);
        self.camera = None;
        self.backlog = 0.0;
        Ok(())
    }

    /// One simulation step, with the held needle keys applied first.
    fn step(&mut self) -> Result<(), ViewError> {
        let Some(sim) = self.sim.as_mut() else {
            return Ok(());
        };
        let dt = sim.dt();
        let keys = manual_motion(&self.keys, &self.options, dt);
        // The mouse's motion is applied at most twice the keys' speed a step (the rest
        // later): a fast drag must not move the tip several node spacings in one step.
        let o = &self.options;
        let most = [
            2.0 * o.advance_speed * dt,
            2.0 * o.turn_rate.to_radians() * dt,
            0.0,
        ];
        let mouse: [f64; 3] =
            std::array::from_fn(|i| self.mouse_motion[i].clamp(-most[i], most[i]));
        for (left, m) in self.mouse_motion.iter_mut().zip(mouse) {
            *left -= m;
        }
        let motion = match keys {
            Some(k) => Some(std::array::from_fn(|i| k[i] + mouse[i])),
            None => (mouse != [0.0; 3]).then_some(mouse),
        };
        if let (Some(m), Some(n)) = (motion, sim.needle()) {
            let pivot = match (sim.state(), sim.entry_point()) {
                (PunctureState::Outside, _) | (_, None) => n.base(),
                (_, Some(e)) => e,
            };
            let (base, dir) = moved_pose(n.base(), n.direction(), pivot, m);
            sim.set_pose(base, dir)?;
        }
        sim.step()?;
        Ok(())
    }

    /// Steps for the wall time since the last frame, then draws.
    fn frame(&mut self) -> Result<(), ViewError> {
        let Some((dt, t0)) = self.sim.as_ref().map(|s| (s.dt(), s.time())) else {
            return Ok(());
        };
        let now = Instant::now();
        let wall = now.duration_since(self.last).as_secs_f64().min(0.25);
        self.last = now;
        if self.paused {
            self.backlog = 0.0;
            if std::mem::take(&mut self.single_step) {
                self.step()?;
            }
        } else {
            self.backlog += wall * self.speed;
            let mut steps = 0;
            while self.backlog >= dt
                && steps < self.options.max_steps_per_frame
                && now.elapsed() < STEP_BUDGET
            {
                self.step()?;
                self.backlog -= dt;
                steps += 1;
            }
            // What could not be simulated in time is dropped.
            self.backlog = self.backlog.min(dt);
        }
        let Some(sim) = self.sim.as_mut() else {
            return Ok(());
        };
        self.ratio.add(sim.time() - t0, wall);
        let frame = Frame::gather(sim)?;
        let camera = *self.camera.get_or_insert_with(|| Camera::frame(&frame));
        if self.title_at.elapsed() > Duration::from_millis(250) {
            self.title_at = Instant::now();
            let title = self.title();
            if let Some(g) = &self.gfx {
                g.window.set_title(&title);
            }
        }
        if let Some(g) = &mut self.gfx {
            g.draw(&frame, &camera)?;
            self.frames += 1;
            self.started.get_or_insert_with(Instant::now);
        }
        Ok(())
    }

    fn title(&self) -> String {
        let Some(sim) = self.sim.as_ref() else {
            return self.options.title.clone();
        };
        let mut t = format!(
            "{}  t = {:.3} s  x{:.2} real time (speed {})",
            self.options.title,
            sim.time(),
            self.ratio.shown,
            self.speed
        );
        if let Some(n) = sim.needle() {
            let depth = sim.depth_of(n.tip(), n.direction());
            t.push_str(&format!(
                "  {:?}  depth {:.1} mm  force {:.3} N",
                sim.state(),
                depth * 1e3,
                sim.needle_force().axial
            ));
        }
        if self.paused {
            t.push_str("  [paused]");
        }
        t
    }

    fn key(&mut self, key: &Key, pressed: bool) -> Result<bool, ViewError> {
        if let Key::Named(named) = key {
            if pressed {
                self.keys.insert(*named);
            } else {
                self.keys.remove(named);
            }
        }
        if !pressed {
            return Ok(false);
        }
        match key {
            Key::Named(NamedKey::Space) => self.paused = !self.paused,
            Key::Named(NamedKey::Escape) => return Ok(true),
            Key::Character(c) => match c.as_str() {
                "n" | "N" | "." => self.single_step = true,
                "q" | "Q" => return Ok(true),
                "+" | "=" => self.speed = (self.speed * 2.0).min(64.0),
                "-" | "_" => self.speed = (self.speed * 0.5).max(1.0 / 64.0),
                "r" | "R" => self.rebuild()?,
                _ => {}
            },
            _ => {}
        }
        self.title_at = Instant::now() - Duration::from_secs(1);
        Ok(false)
    }
}

impl ApplicationHandler for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.gfx.is_none() {
            match Gfx::new(event_loop, &self.options) {
                Ok(g) => {
                    g.window.request_redraw();
                    self.gfx = Some(g);
                    if self.sim.is_none() {
                        if let Err(e) = self.rebuild() {
                            return self.fail(event_loop, e);
                        }
                    }
                    self.last = Instant::now();
                }
                Err(e) => self.fail(event_loop, e),
            }
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        match event {
            WindowEvent::CloseRequested => event_loop.exit(),
            WindowEvent::Resized(size) => {
                if let Some(g) = &mut self.gfx {
                    g.resize(size.width, size.height);
                }
            }
            WindowEvent::KeyboardInput { event, .. } => {
                let pressed = event.state == ElementState::Pressed;
                match self.key(&event.logical_key, pressed) {
                    Ok(true) => event_loop.exit(),
                    Ok(false) => {}
                    Err(e) => self.fail(event_loop, e),
                }
            }
            WindowEvent::MouseInput {
                state,
                button: MouseButton::Left,
                ..
            } => self.dragging = state == ElementState::Pressed,
            WindowEvent::MouseInput {
                state,
                button: MouseButton::Right,
                ..
            } => self.steering = state == ElementState::Pressed,
            WindowEvent::CursorMoved { position, .. } => {
                if let (true, Some((x, y))) = (self.steering, self.cursor) {
                    let o = &self.options;
                    self.mouse_motion[0] -= (position.y - y) * o.mouse_advance;
                    self.mouse_motion[1] -= (position.x - x) * o.mouse_turn.to_radians();
                }
                if let (true, Some((x, y)), Some(c)) =
                    (self.dragging, self.cursor, self.camera.as_mut())
                {
                    c.orbit(
                        -(position.x - x) as f32 * 0.01,
                        (position.y - y) as f32 * 0.01,
                    );
                }
                self.cursor = Some((position.x, position.y));
            }
            WindowEvent::MouseWheel { delta, .. } => {
                let lines = match delta {
                    MouseScrollDelta::LineDelta(_, y) => y,
                    MouseScrollDelta::PixelDelta(p) => p.y as f32 / 40.0,
                };
                if let Some(c) = self.camera.as_mut() {
                    c.zoom(0.9f32.powf(lines));
                }
            }
            WindowEvent::RedrawRequested => {
                if let Err(e) = self.frame() {
                    self.fail(event_loop, e);
                } else if self.options.frames.is_some_and(|n| self.frames >= n) {
                    event_loop.exit();
                }
            }
            _ => {}
        }
    }

    fn about_to_wait(&mut self, _event_loop: &ActiveEventLoop) {
        if let Some(g) = &self.gfx {
            g.window.request_redraw();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn turning_keeps_the_pivot_on_the_needle_line() {
        let (base, dir) = moved_pose(
            [-0.2, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 0.0, 0.0],
            [0.0, 90f64.to_radians(), 0.0],
        );
        assert!((DVec3::from(base) - DVec3::new(0.0, -0.2, 0.0)).length() < 1e-12);
        assert!((DVec3::from(dir) - DVec3::Y).length() < 1e-12);
        let (base, dir) = moved_pose(base, dir, [0.0; 3], [0.01, 0.0, 10f64.to_radians()]);
        // The pivot stays on the needle's line.
        let (b, d) = (DVec3::from(base), DVec3::from(dir));
        assert!((b - d * b.dot(d)).length() < 1e-12);
        assert!(d.z > 0.0, "tilting up lifts the tip");
    }
}
