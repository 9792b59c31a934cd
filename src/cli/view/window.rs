//! The viewer's window thread: winit events to [`Command`]s for the render thread, the latest
//! [`Published`] image to the window through softbuffer with the overlay on top, scripted input,
//! and the screenshot. Nothing here waits on rendering.

use super::overlay;
use super::renderer::{Command, Published};
use super::script::{DragButton, Step};
use std::collections::VecDeque;
use std::num::NonZeroU32;
use std::path::PathBuf;
use std::rc::Rc;
use std::sync::mpsc::Sender;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use winit::application::ApplicationHandler;
use winit::dpi::{PhysicalPosition, PhysicalSize};
use winit::event::{ElementState, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, ControlFlow};
use winit::keyboard::{Key, NamedKey};
use winit::window::{Window, WindowId};

/// The render thread has published an image.
#[derive(Debug, Clone, Copy)]
pub struct FrameReady;

/// A key as the viewer sees it (from winit or a script).
#[derive(Clone, Debug, PartialEq)]
enum ViewKey {
    Char(char),
    Escape,
    Shift,
    Other,
}

/// Mouse movement below this many pixels between press and release is a click.
const CLICK_SLOP: f32 = 3.0;
/// Fly keys: (key, direction along the camera's right, up, forward).
const FLY_KEYS: [(char, [f32; 3]); 6] = [
    ('w', [0.0, 0.0, 1.0]),
    ('s', [0.0, 0.0, -1.0]),
    ('a', [-1.0, 0.0, 0.0]),
    ('d', [1.0, 0.0, 0.0]),
    ('q', [0.0, -1.0, 0.0]),
    ('e', [0.0, 1.0, 0.0]),
];

/// What the command line asked of the window.
pub struct WindowOptions {
    pub title: String,
    pub width: u32,
    pub height: u32,
    pub screenshot: Option<PathBuf>,
    /// Exit after this many still frames (full passes or sweeps) once the script has run.
    pub frames: Option<u32>,
    pub script: Vec<Step>,
    pub overlay: bool,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Drag {
    Orbit,
    Look,
    Move,
}

pub struct App {
    options: WindowOptions,
    commands: Sender<(u64, Command)>,
    sent: u64,
    latest: Arc<Mutex<Option<Published>>>,
    shown: Option<Published>,
    window: Option<Rc<Window>>,
    surface: Option<softbuffer::Surface<Rc<Window>, Rc<Window>>>,
    cursor: (f32, f32),
    pressed: Option<(MouseButton, (f32, f32), bool)>,
    drag: Option<Drag>,
    shift: bool,
    held: Vec<char>,
    last_fly: Instant,
    overlay: bool,
    /// Whether relevance follows the cursor (key `G`).
    gaze: bool,
    script: VecDeque<Step>,
    waiting_frames: u32,
    /// The last error, reported after the event loop ends.
    pub error: Option<anyhow::Error>,
    pub screenshot_written: bool,
}

impl App {
    pub fn new(options: WindowOptions, commands: Sender<(u64, Command)>, latest: Arc<Mutex<Option<Published>>>) -> App {
        App {
            overlay: options.overlay,
            script: options.script.iter().cloned().collect(),
            options,
            commands,
            sent: 0,
            latest,
            shown: None,
            window: None,
            surface: None,
            cursor: (0.0, 0.0),
            gaze: false,
            pressed: None,
            drag: None,
            shift: false,
            held: Vec::new(),
            last_fly: Instant::now(),
            waiting_frames: 0,
            error: None,
            screenshot_written: false,
        }
    }

    fn send(&mut self, command: Command) {
        self.sent += 1;
        // The render thread ends only after the window, so a failed send means it died: its
        // panic is reported when it is joined.
        let _ = self.commands.send((self.sent, command));
    }

    fn cursor_moved(&mut self, x: f32, y: f32) {
        let (dx, dy) = (x - self.cursor.0, y - self.cursor.1);
        self.cursor = (x, y);
        if self.gaze && self.pressed.is_none() && (dx != 0.0 || dy != 0.0) {
            self.send(Command::Gaze { at: Some((x, y)) });
        }
        if self.pressed.is_none() && (dx != 0.0 || dy != 0.0) {
            self.send(Command::Hover { x, y });
        }
        let Some((button, start, _)) = self.pressed else { return };
        if self.drag.is_none() && ((x - start.0).abs() > CLICK_SLOP || (y - start.1).abs() > CLICK_SLOP) {
            self.drag = Some(match (button, self.shift) {
                (MouseButton::Left, true) => {
                    // Grab what is under the press point.
                    self.send(Command::Select { x: start.0, y: start.1 });
                    Drag::Move
                }
                (MouseButton::Left, false) => Drag::Orbit,
                _ => Drag::Look,
            });
            let (dx0, dy0) = (x - start.0 - dx, y - start.1 - dy);
            self.drag_by(dx0, dy0);
        }
        self.drag_by(dx, dy);
    }

    fn drag_by(&mut self, dx: f32, dy: f32) {
        if dx == 0.0 && dy == 0.0 {
            return;
        }
        match self.drag {
            Some(Drag::Orbit) => self.send(Command::Orbit { dx, dy }),
            Some(Drag::Look) => self.send(Command::Look { dx, dy }),
            Some(Drag::Move) => self.send(Command::MoveSelected { dx, dy }),
            None => {}
        }
    }

    fn mouse_button(&mut self, button: MouseButton, pressed: bool) {
        if pressed {
            if self.pressed.is_none() {
                self.pressed = Some((button, self.cursor, self.shift));
                self.drag = None;
                if button == MouseButton::Left && !self.shift {
                    self.send(Command::Press { x: self.cursor.0, y: self.cursor.1 });
                }
            }
            return;
        }
        if let Some((b, at, shift)) = self.pressed {
            if b == button {
                if self.drag.is_none() && button == MouseButton::Left {
                    self.send(Command::Select { x: at.0, y: at.1 });
                }
                if button == MouseButton::Left && !shift {
                    self.send(Command::Release { x: self.cursor.0, y: self.cursor.1 });
                }
                self.pressed = None;
                self.drag = None;
            }
        }
    }

    fn key(&mut self, key: ViewKey, pressed: bool, event_loop: &ActiveEventLoop) {
        match key {
            ViewKey::Shift => self.shift = pressed,
            ViewKey::Char(c) if FLY_KEYS.iter().any(|(k, _)| *k == c) => {
                if pressed && !self.held.contains(&c) {
                    if self.held.is_empty() {
                        self.last_fly = Instant::now();
                    }
                    self.held.push(c);
                } else if !pressed {
                    self.held.retain(|k| *k != c);
                }
            }
            _ if !pressed => {}
            ViewKey::Escape => event_loop.exit(),
            ViewKey::Char('x') => self.send(Command::CycleAntialiasing),
            ViewKey::Char('c') => self.send(Command::CycleCamera),
            ViewKey::Char('f') => self.send(Command::ToggleFrameless),
            ViewKey::Char('r') => self.send(Command::ResetView),
            ViewKey::Char('v') => self.send(Command::NextViewpoint),
            ViewKey::Char('g') => {
                self.gaze = !self.gaze;
                self.send(Command::Gaze { at: self.gaze.then_some(self.cursor) });
            }
            ViewKey::Char('h') => {
                self.overlay = !self.overlay;
                self.request_redraw();
            }
            ViewKey::Char(_) | ViewKey::Other => {}
        }
    }

    fn fly_tick(&mut self) {
        if self.held.is_empty() {
            return;
        }
        let now = Instant::now();
        // A stalled event loop must not throw the camera far: at most 0.1 s per tick.
        let seconds = (now - self.last_fly).as_secs_f32().min(0.1);
        self.last_fly = now;
        let mut direction = [0.0f32; 3];
        for c in &self.held {
            if let Some((_, d)) = FLY_KEYS.iter().find(|(k, _)| k == c) {
                for (a, b) in direction.iter_mut().zip(d) {
                    *a += b;
                }
            }
        }
        if direction != [0.0; 3] {
            self.send(Command::Fly { direction, seconds });
        }
    }

    fn request_redraw(&self) {
        if let Some(w) = &self.window {
            w.request_redraw();
        }
    }

    /// Plays one script step through the ordinary handlers.
    fn play(&mut self, step: Step, event_loop: &ActiveEventLoop) {
        match step {
            Step::Drag { button, from, to } => {
                let (b, shift) = match button {
                    DragButton::Left => (MouseButton::Left, false),
                    DragButton::Right => (MouseButton::Right, false),
                    DragButton::ShiftLeft => (MouseButton::Left, true),
                };
                self.shift = shift;
                self.cursor_moved(from.0, from.1);
                self.mouse_button(b, true);
                const STEPS: u32 = 8;
                for k in 1..=STEPS {
                    let t = k as f32 / STEPS as f32;
                    self.cursor_moved(from.0 + (to.0 - from.0) * t, from.1 + (to.1 - from.1) * t);
                }
                self.mouse_button(b, false);
                self.shift = false;
            }
            Step::Click { at } => {
                self.cursor_moved(at.0, at.1);
                self.mouse_button(MouseButton::Left, true);
                self.mouse_button(MouseButton::Left, false);
            }
            Step::Move { to } => self.cursor_moved(to.0, to.1),
            Step::Scroll { steps } => self.send(Command::Dolly { steps }),
            Step::Key { name } => {
                let key = match name.as_str() {
                    "escape" => ViewKey::Escape,
                    "shift" => ViewKey::Shift,
                    "tab" | "space" | "f1" => ViewKey::Other,
                    s => s.chars().next().map_or(ViewKey::Other, ViewKey::Char),
                };
                self.key(key.clone(), true, event_loop);
                self.key(key, false, event_loop);
            }
            Step::Hold { key, seconds } => {
                if let Some((_, direction)) = FLY_KEYS.iter().find(|(k, _)| *k == key) {
                    self.send(Command::Fly { direction: *direction, seconds });
                }
            }
            Step::Wait { frames } => self.waiting_frames = frames,
        }
    }

    /// After a new image: the next script step, or the screenshot and exit when due.
    fn after_frame(&mut self, event_loop: &ActiveEventLoop) {
        if self.waiting_frames > 0 {
            self.waiting_frames -= 1;
            return;
        }
        if let Some(step) = self.script.pop_front() {
            self.play(step, event_loop);
            return;
        }
        let Some(frames) = self.options.frames else { return };
        let Some(shown) = &self.shown else { return };
        if shown.applied < self.sent || shown.moving || shown.still_passes < frames {
            return;
        }
        if let Some(path) = self.options.screenshot.clone() {
            if let Err(e) = self.save_screenshot(&path) {
                self.error = Some(e);
            } else {
                self.screenshot_written = true;
            }
        }
        event_loop.exit();
    }

    /// Writes what the window shows (read back from the window; the presented buffer if that
    /// fails) as a PNG.
    fn save_screenshot(&mut self, path: &std::path::Path) -> anyhow::Result<()> {
        let (w, h) = self.buffer_size();
        let pixels = match self.surface.as_mut().map(|s| s.fetch()) {
            Some(Ok(p)) if p.len() == w as usize * h as usize => p,
            _ => self.compose(w, h),
        };
        let rgba: Vec<f32> = pixels
            .iter()
            .flat_map(|p| {
                [(p >> 16 & 0xFF) as f32 / 255.0, (p >> 8 & 0xFF) as f32 / 255.0, (p & 0xFF) as f32 / 255.0, 1.0]
            })
            .collect();
        // The window's pixels are display-encoded already.
        let opts = rtsl_runtime::WriteOptions { transfer: rtsl_runtime::Transfer::Linear, ..Default::default() };
        rtsl_runtime::write_image(path, w as usize, h as usize, &rgba, &opts)
            .map_err(|e| anyhow::anyhow!("writing the screenshot {}: {e}", path.display()))
    }

    fn buffer_size(&self) -> (u32, u32) {
        let size =
            self.window.as_ref().map_or(PhysicalSize::new(self.options.width, self.options.height), |w| w.inner_size());
        (size.width.max(1), size.height.max(1))
    }

    /// The window's pixels: the image at the top left (black around it if the window is larger),
    /// and the overlay.
    fn compose(&self, w: u32, h: u32) -> Vec<u32> {
        let (w, h) = (w as usize, h as usize);
        let mut out = vec![0u32; w * h];
        if let Some(img) = &self.shown {
            let (iw, ih) = (img.width as usize, img.height as usize);
            for y in 0..h.min(ih) {
                let n = w.min(iw);
                out[y * w..y * w + n].copy_from_slice(&img.pixels[y * iw..y * iw + n]);
            }
            if self.overlay {
                let mut lines: Vec<(String, u32)> = img.status.iter().map(|s| (s.clone(), overlay::WHITE)).collect();
                if !img.status.is_empty() {
                    lines.push(("drag orbit, rdrag look, WASDQE fly, wheel dolly".into(), overlay::YELLOW));
                    lines.push((
                        "click select, shift-drag move, X aa, F frameless, G gaze, V view, H overlay, R reset".into(),
                        overlay::YELLOW,
                    ));
                }
                lines.extend(img.diagnostics.iter().map(|d| (d.clone(), overlay::RED)));
                overlay::draw(&mut out, w, h, &lines);
            }
        }
        out
    }

    fn redraw(&mut self) -> anyhow::Result<()> {
        let (w, h) = self.buffer_size();
        let pixels = self.compose(w, h);
        let Some(surface) = self.surface.as_mut() else { return Ok(()) };
        let (Some(nw), Some(nh)) = (NonZeroU32::new(w), NonZeroU32::new(h)) else { return Ok(()) };
        surface.resize(nw, nh).map_err(|e| anyhow::anyhow!("resizing the window buffer: {e}"))?;
        let mut buffer = surface.buffer_mut().map_err(|e| anyhow::anyhow!("mapping the window buffer: {e}"))?;
        buffer.copy_from_slice(&pixels);
        buffer.present().map_err(|e| anyhow::anyhow!("presenting: {e}"))?;
        Ok(())
    }

    fn fail(&mut self, event_loop: &ActiveEventLoop, e: anyhow::Error) {
        self.error = Some(e);
        event_loop.exit();
    }
}

impl ApplicationHandler<FrameReady> for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.window.is_some() {
            return;
        }
        let attributes = Window::default_attributes()
            .with_title(self.options.title.clone())
            .with_inner_size(PhysicalSize::new(self.options.width, self.options.height))
            .with_resizable(false);
        let window = match event_loop.create_window(attributes) {
            Ok(w) => Rc::new(w),
            Err(e) => return self.fail(event_loop, anyhow::anyhow!("opening the window: {e}")),
        };
        let surface = softbuffer::Context::new(window.clone())
            .and_then(|context| softbuffer::Surface::new(&context, window.clone()));
        match surface {
            Ok(s) => self.surface = Some(s),
            Err(e) => return self.fail(event_loop, anyhow::anyhow!("creating the window's pixel buffer: {e}")),
        }
        self.window = Some(window);
    }

    fn user_event(&mut self, event_loop: &ActiveEventLoop, _: FrameReady) {
        let image = self.latest.lock().ok().and_then(|mut s| s.take());
        if let Some(image) = image {
            self.shown = Some(image);
            if let Err(e) = self.redraw() {
                return self.fail(event_loop, e);
            }
            self.after_frame(event_loop);
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _: WindowId, event: WindowEvent) {
        match event {
            WindowEvent::CloseRequested => event_loop.exit(),
            WindowEvent::RedrawRequested => {
                if let Err(e) = self.redraw() {
                    self.fail(event_loop, e);
                }
            }
            WindowEvent::CursorMoved { position: PhysicalPosition { x, y }, .. } => {
                self.cursor_moved(x as f32, y as f32)
            }
            WindowEvent::MouseInput { state, button, .. } => self.mouse_button(button, state == ElementState::Pressed),
            WindowEvent::MouseWheel { delta, .. } => {
                let steps = match delta {
                    MouseScrollDelta::LineDelta(_, y) => y,
                    MouseScrollDelta::PixelDelta(p) => p.y as f32 / 40.0,
                };
                self.send(Command::Dolly { steps });
            }
            WindowEvent::ModifiersChanged(m) => self.shift = m.state().shift_key(),
            WindowEvent::KeyboardInput { event, .. } => {
                let key = match &event.logical_key {
                    Key::Named(NamedKey::Escape) => ViewKey::Escape,
                    Key::Named(NamedKey::Shift) => ViewKey::Shift,
                    Key::Character(s) => {
                        s.chars().next().map_or(ViewKey::Other, |c| ViewKey::Char(c.to_ascii_lowercase()))
                    }
                    _ => ViewKey::Other,
                };
                self.key(key, event.state == ElementState::Pressed, event_loop);
            }
            _ => {}
        }
    }

    fn about_to_wait(&mut self, event_loop: &ActiveEventLoop) {
        self.fly_tick();
        if self.held.is_empty() {
            event_loop.set_control_flow(ControlFlow::Wait);
        } else {
            event_loop.set_control_flow(ControlFlow::WaitUntil(Instant::now() + Duration::from_millis(16)));
        }
    }
}
