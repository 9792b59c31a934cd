//! The viewer's render thread. It owns the scene (`Context`), the hot reloader and the
//! accumulation buffer; the window thread sends it input as [`Command`]s and shows the latest
//! [`Published`] image. Work is cut into pieces of about a display interval so input is taken up
//! between them: the window never waits on a render, and the render never runs long on a stale view.
//!
//! Two modes (key `F`):
//! - **progressive** frames: while the view moves, one preview pass at a stride (1, 2, 4 or 8
//!   pixels per sample) chosen from the measured speed so a pass fits the frame budget; once it
//!   has been still for [`SETTLE`], full passes add one sample per pixel each to the running mean,
//!   published as each pass completes.
//! - **frameless**: lattices in the frameless order, a chunk at a time with the latest camera,
//!   published every [`FRAMELESS_REFRESH`] whatever has been updated.

use super::navigation::Navigation;
use glam::{Affine3A, Vec3, Vec3A};
use rtsl_runtime::api::{Context, InstanceId};
use rtsl_runtime::distributed::{Master, Transport};
use rtsl_runtime::reload::{ShaderEvent, ShaderReloader};
use rtsl_runtime::render::progressive::{
    frameless_order, pass_lattices, trace_lattices_keeping, Accumulator, BatchReport, LatticeSamples, PixelLattice,
    RefineTest,
};
use rtsl_runtime::render::ray_params::samples_for_relevance;
use rtsl_runtime::render::{camera_ray, Antialiasing, LightPathCache, RayField, RayParameters, World, RELEVANCE};
use rtsl_runtime::vrml::sensors::{PointerHit, PointerRay};
use rtsl_runtime::{ByteTable, Transfer};
use std::sync::mpsc::{Receiver, RecvTimeoutError, TryRecvError};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// How long the view must be still before full-resolution passes start.
pub const SETTLE: Duration = Duration::from_millis(120);
/// The frame budget while moving: previews aim to take at most this long.
pub const MOVING_BUDGET: Duration = Duration::from_millis(33);
/// The display refresh of frameless mode.
pub const FRAMELESS_REFRESH: Duration = Duration::from_millis(33);
/// Progressive refinement stops after this many samples per pixel (the thread then sleeps until
/// input arrives).
pub const MAX_PASSES: u32 = 256;

/// The camera shaders `C` cycles through after the built-in pinhole camera.
const CAMERAS: [&str; 4] = ["fisheye", "cylindrical", "parabolic", "thinlens"];

/// Input, as the render thread understands it.
#[derive(Clone, Debug, PartialEq)]
pub enum Command {
    /// Orbit about the pivot by a mouse movement in pixels.
    Orbit {
        dx: f32,
        dy: f32,
    },
    /// Look around (fly mode) by a mouse movement in pixels.
    Look {
        dx: f32,
        dy: f32,
    },
    /// Fly along the camera's (right, up, forward) for `seconds` of flying speed.
    Fly {
        direction: [f32; 3],
        seconds: f32,
    },
    /// Scroll steps towards the pivot.
    Dolly {
        steps: f32,
    },
    /// Select the instance under a window pixel (none: deselect).
    Select {
        x: f32,
        y: f32,
    },
    /// The cursor moved to a window pixel with no button held (a VRML TouchSensor's `isOver`).
    Hover {
        x: f32,
        y: f32,
    },
    /// The left button pressed (no shift) at a window pixel: a VRML pointing-device sensor under
    /// it becomes active, and a drag sensor takes the drags that follow (`Orbit`) until release.
    Press {
        x: f32,
        y: f32,
    },
    /// The left button released at a window pixel.
    Release {
        x: f32,
        y: f32,
    },
    /// Move the selected instance in the view plane by a mouse movement in pixels.
    MoveSelected {
        dx: f32,
        dy: f32,
    },
    /// The next of the scene's viewpoints (a VRML scene's Viewpoints), in the order read.
    NextViewpoint,
    /// Relevance follows this window pixel (the gaze); `None`: back to the scene's own ray
    /// parameters.
    Gaze {
        at: Option<(f32, f32)>,
    },
    CycleAntialiasing,
    /// The next camera: the built-in pinhole, then the library's camera shaders.
    CycleCamera,
    ToggleFrameless,
    /// Back to the scene's own camera.
    ResetView,
}

/// An image for the window, and what to say about it.
#[derive(Clone, Debug)]
pub struct Published {
    pub width: u32,
    pub height: u32,
    /// `0x00RRGGBB`, rows top to bottom.
    pub pixels: Vec<u32>,
    /// The sequence number of the last command applied before this image was made.
    pub applied: u64,
    /// Full passes (progressive) or complete sweeps (frameless) since the view last changed.
    pub still_passes: u32,
    /// The image is a reduced-quality preview of a moving view.
    pub moving: bool,
    /// Overlay lines: status first, then shader diagnostics.
    pub status: Vec<String>,
    pub diagnostics: Vec<String>,
}

/// Frame rates measured over a session, still and moving apart (a published image counts for the
/// class of its render, over the time since the previous one).
#[derive(Clone, Copy, Debug, Default)]
pub struct Summary {
    pub still_frames: u64,
    pub still_time: Duration,
    pub moving_frames: u64,
    pub moving_time: Duration,
    /// Full-resolution passes (one sample per pixel each) or frameless sweeps completed.
    pub full_passes: u64,
    pub rays: u64,
    pub render_time: Duration,
    /// The threads that rendered: this process's, or all the MPI workers'.
    pub threads: usize,
}

impl std::fmt::Display for Summary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let fps = |n: u64, t: Duration| if t.is_zero() { 0.0 } else { n as f64 / t.as_secs_f64() };
        write!(
            f,
            "still: {} frames, {:.1} fps, {:.1} full passes/s; moving: {} frames, {:.1} fps; {:.2} M rays/s",
            self.still_frames,
            fps(self.still_frames, self.still_time),
            fps(self.full_passes, self.still_time),
            self.moving_frames,
            fps(self.moving_frames, self.moving_time),
            self.rays as f64 / self.render_time.as_secs_f64().max(1e-9) / 1e6
        )
    }
}

/// The render thread's state.
pub struct Renderer {
    /// The window's encoding table and the transfer it is for, made once rather than per frame.
    display: Option<(Transfer, ByteTable)>,
    rt: Context,
    world: Option<World>,
    reloader: Option<ShaderReloader>,
    nav: Navigation,
    home: Navigation,
    acc: Accumulator,
    /// The light paths of the pass being traced, shared by its pieces.
    light_paths: LightPathCache,
    frameless: bool,
    /// Full passes or sweeps after which a still view stops refining.
    still_limit: u32,
    /// The view changed at this time (camera, scene, mode).
    changed_at: Instant,
    scene_dirty: bool,
    selected: Option<Selection>,
    /// Progressive: the next lattice of the current full pass and the pass number.
    pass: u32,
    pass_cursor: usize,
    full_lattices: Vec<PixelLattice>,
    refine: Option<Vec<bool>>,
    /// Frameless: the order, where we are in it, and the sweeps done.
    order: Vec<PixelLattice>,
    order_cursor: usize,
    sweeps: u32,
    still_sweeps: u32,
    /// Seconds per primary ray (with its shading), smoothed, for sizing work.
    seconds_per_ray: f64,
    applied: u64,
    diagnostics: Vec<String>,
    /// Rays and time over the last second, for the overlay.
    window: (Instant, u64, u32),
    rate: (f64, f64),
    last_publish: Instant,
    summary: Summary,
    threads: usize,
    /// The scene's own ray parameters while relevance follows the cursor (`Command::Gaze`).
    before_gaze: Option<RayParameters>,
    /// A VRML scene's animation and its clock.
    playing: Option<Playing>,
    /// The scene's viewpoints (name, eye, forward, up, field of view in degrees) and the one
    /// shown last.
    viewpoints: Vec<Viewpoint>,
    viewpoint: usize,
    /// Where the cursor is while a VRML drag sensor holds the pointer (from a `Press`).
    grab: Option<(f32, f32)>,
}

/// A named view the viewer can jump to (a VRML Viewpoint).
#[derive(Clone, Debug, PartialEq)]
pub struct Viewpoint {
    /// Its place in the VRML scene's list (`VrmlScene::viewpoints`).
    pub index: usize,
    pub name: String,
    pub eye: Vec3A,
    pub forward: Vec3A,
    pub up: Vec3A,
    /// The field of view of the image's shorter side, in degrees.
    pub fov_degrees: f32,
}

/// A VRML scene's animation, played at wall-clock time from when the viewer started, or held at
/// one time.
pub struct Playing {
    scene: Box<rtsl_runtime::vrml::VrmlScene>,
    clock: Clock,
}

enum Clock {
    /// Playing: time 0 was then.
    Playing(Instant),
    /// Held at this time.
    Held(f64),
}

impl Playing {
    /// Plays `scene` from time 0 now, or holds it at `held`.
    pub fn new(scene: Box<rtsl_runtime::vrml::VrmlScene>, held: Option<f64>) -> Playing {
        Playing { scene, clock: held.map_or_else(|| Clock::Playing(Instant::now()), Clock::Held) }
    }

    fn time(&self) -> f64 {
        match self.clock {
            Clock::Playing(start) => start.elapsed().as_secs_f64(),
            Clock::Held(t) => t,
        }
    }
}

/// With `--mpi`, the master of the worker ranks that trace the lattices. It stays on the render
/// thread, the one thread that calls MPI.
type Workers = Option<Master<Box<dyn Transport>>>;

/// The render thread's world: taken out only while it is rebuilt, in `Renderer::rebuild`.
fn held(world: &Option<World>) -> &World {
    world.as_ref().expect("the render thread always holds a world between rebuilds")
}

/// Traces `lattices` (see [`trace_lattices_keeping`]) on `master`'s workers where there are any, else
/// here on `pool`. A distributed failure (a worker that cannot render) is reported once, in
/// `diagnostics` and on stderr, and the viewer goes on rendering here.
#[allow(clippy::too_many_arguments)]
fn trace(
    master: &mut Workers,
    pool: &rayon::ThreadPool,
    rt: &Context,
    world: &World,
    diagnostics: &mut Vec<String>,
    light_paths: &LightPathCache,
    lattices: &[PixelLattice],
    pass: u32,
    preview: bool,
    wanted: &(dyn Fn(u32, u32) -> bool + Sync),
) -> (Vec<LatticeSamples>, BatchReport) {
    if let Some(m) = master.as_mut() {
        match m.trace_lattices(rt, world, lattices, pass, preview, wanted) {
            Ok(traced) => return traced,
            Err(e) => {
                let message = format!("distributed rendering stopped ({e}); rendering on rank 0");
                eprintln!("error: {message}");
                diagnostics.push(message);
                *master = None;
            }
        }
    }
    pool.install(|| trace_lattices_keeping(world, lattices, pass, preview, wanted, light_paths))
}

#[derive(Clone, Copy, Debug)]
struct Selection {
    instance: InstanceId,
    /// Camera-space depth of the point grabbed.
    depth: f32,
}

/// A pixel for the window, encoded as `rtsl render` encodes 8-bit images (`table` is the scene's
/// transfer, `RenderOptions::transfer`).
fn pack(table: &ByteTable, c: [f32; 4]) -> u32 {
    let q = |v: f32| u32::from(table.byte(v));
    q(c[0]) << 16 | q(c[1]) << 8 | q(c[2])
}

fn aa_name(aa: Antialiasing) -> String {
    match aa {
        Antialiasing::Grid { jitter: false } => "regular".into(),
        Antialiasing::Grid { jitter: true } => "jittered".into(),
        Antialiasing::Interleaved => "interleaved".into(),
        Antialiasing::Adaptive { threshold } => format!("adaptive:{threshold}"),
    }
}

impl Renderer {
    /// A renderer for the scene in `rt` (its options give the image size). `watch` starts hot reload.
    /// Refinement stops after `still_limit` passes or sweeps (1 to [`MAX_PASSES`]): a scripted
    /// screenshot after N still frames then shows exactly N samples per pixel in either mode.
    pub fn new(
        mut rt: Context,
        watch: bool,
        frameless: bool,
        threads: usize,
        still_limit: u32,
    ) -> anyhow::Result<Renderer> {
        let world = rt.build_world()?;
        for w in rt.take_warnings() {
            eprintln!("warning: {w}");
        }
        let nav = Navigation::new(*rt.camera(), world.scene.bounds());
        let (w, h) = (rt.options.width, rt.options.height);
        let reloader = if watch {
            match ShaderReloader::new(&rt) {
                Ok(r) => Some(r),
                Err(e) => {
                    eprintln!("warning: hot reload is off: {e}");
                    None
                }
            }
        } else {
            None
        };
        let now = Instant::now();
        Ok(Renderer {
            world: Some(world),
            reloader,
            nav,
            home: nav,
            acc: Accumulator::new(w, h),
            display: None,
            light_paths: LightPathCache::default(),
            frameless,
            still_limit: still_limit.clamp(1, MAX_PASSES),
            changed_at: now,
            scene_dirty: false,
            selected: None,
            pass: 0,
            pass_cursor: 0,
            full_lattices: pass_lattices(w, h, 1),
            refine: None,
            order: frameless_order(w, h),
            order_cursor: 0,
            sweeps: 0,
            still_sweeps: 0,
            seconds_per_ray: 2e-6,
            applied: 0,
            diagnostics: Vec::new(),
            window: (now, 0, 0),
            rate: (0.0, 0.0),
            last_publish: now,
            summary: Summary::default(),
            threads,
            before_gaze: None,
            rt,
            playing: None,
            viewpoints: Vec::new(),
            viewpoint: 0,
            grab: None,
        })
    }

    /// The viewpoints `V` cycles through, the first being the one the scene starts at.
    pub fn set_viewpoints(&mut self, viewpoints: Vec<Viewpoint>) {
        self.viewpoints = viewpoints;
        self.viewpoint = 0;
    }

    /// Plays a VRML scene's animation (its events drive `rt`'s scene).
    pub fn play(&mut self, playing: Playing) {
        self.playing = Some(playing);
    }

    /// Advances the animation to the clock's time; the scene is rebuilt when it changed.
    fn animate(&mut self) {
        let Some(playing) = self.playing.as_mut() else { return };
        let t = playing.time();
        let camera = *self.rt.camera();
        match playing.scene.advance_to(t, &mut self.rt) {
            Ok(changed) => self.scene_dirty |= changed,
            Err(e) => self.diagnostics.push(format!("animation: {e}")),
        }
        // The bound Viewpoint moved: the view moves with it, keeping where the user has taken
        // it relative to the Viewpoint.
        let after = *self.rt.camera();
        if after != camera {
            let moved = after.world_from_camera * camera.world_from_camera.inverse();
            if moved.is_finite() {
                self.nav.camera.world_from_camera = moved * self.nav.camera.world_from_camera;
                self.nav.camera.fov_degrees = after.fov_degrees;
                self.nav.pivot = moved.transform_point3a(self.nav.pivot);
            }
            self.rt.set_camera(self.nav.camera);
            if let Some(world) = self.world.as_mut() {
                world.camera = self.nav.camera;
            }
        }
        for w in playing.scene.take_warnings() {
            eprintln!("{w}");
            self.diagnostics.push(w.to_string());
        }
        if after != camera {
            self.view_changed();
        }
    }

    fn size(&self) -> (u32, u32) {
        (self.rt.options.width, self.rt.options.height)
    }

    /// Something the image depends on changed: start a new epoch of samples.
    fn view_changed(&mut self) {
        self.acc.restart();
        self.changed_at = Instant::now();
        self.pass = 0;
        self.pass_cursor = 0;
        self.refine = None;
        self.still_sweeps = 0;
    }

    fn world(&self) -> &World {
        held(&self.world)
    }

    /// The camera ray through a window pixel, and what it hits: (world instance index, camera depth).
    fn pick(&self, x: f32, y: f32) -> Option<(usize, f32)> {
        let world = self.world();
        let (w, h) = self.size();
        if !(x >= 0.0 && y >= 0.0 && x < w as f32 && y < h as f32) {
            return None;
        }
        let (px, py) = (x as u32, y as u32);
        let ray = camera_ray(world, px, py, 0.5, 0.5);
        let hit = world.intersect(rtsl_runtime::render::RayKind::Camera, &ray);
        if !hit.is_hit() {
            return None;
        }
        let forward = world.camera.world_from_camera.matrix3.z_axis.normalize_or_zero();
        Some((hit.instance as usize, hit.t * ray.direction.dot(forward)))
    }

    /// The camera ray through a window pixel, and where it meets a shape of the VRML scene.
    fn pointer(&self, x: f32, y: f32) -> Option<(PointerRay, Option<PointerHit>)> {
        let playing = self.playing.as_ref()?;
        let world = self.world();
        let (w, h) = self.size();
        if !(x.is_finite() && y.is_finite()) {
            return None;
        }
        let (px, py) = (x.clamp(0.0, w as f32 - 1.0) as u32, y.clamp(0.0, h as f32 - 1.0) as u32);
        let ray = camera_ray(world, px, py, 0.5, 0.5);
        let pointer = PointerRay { origin: ray.origin, direction: ray.direction };
        let inside = x >= 0.0 && y >= 0.0 && x < w as f32 && y < h as f32;
        let hit = world.scene.intersect(&ray);
        if !inside || !hit.is_hit() {
            return Some((pointer, None));
        }
        let instance = self.rt.world_instance_ids().get(hit.instance as usize).copied();
        let found = instance.and_then(|i| playing.scene.pointer_hit(&self.rt, i, hit.primitive, (hit.u, hit.v)));
        Some((pointer, found))
    }

    /// The VRML scene's pointing-device sensors told of a hover, press, drag or release at a
    /// window pixel. Returns whether a drag sensor took the pointer (for a press).
    fn sense_pointer(&mut self, command: &Command) -> bool {
        let (x, y) = match *command {
            Command::Hover { x, y } | Command::Press { x, y } | Command::Release { x, y } => (x, y),
            _ => return false,
        };
        let Some((ray, hit)) = self.pointer(x, y) else { return false };
        let Some(playing) = self.playing.as_mut() else { return false };
        let t = playing.time();
        let (grabbed, changed) = match command {
            Command::Hover { .. } => (false, playing.scene.pointer_move(hit.as_ref(), t, &mut self.rt)),
            Command::Press { .. } => match hit {
                Some(hit) => match playing.scene.pointer_press(&hit, ray, t, &mut self.rt) {
                    Ok((grabbed, changed)) => (grabbed, Ok(changed)),
                    Err(e) => (false, Err(e)),
                },
                None => (false, Ok(false)),
            },
            _ => (false, playing.scene.pointer_release(hit.as_ref(), t, &mut self.rt)),
        };
        match changed {
            Ok(changed) => self.scene_dirty |= changed,
            Err(e) => self.diagnostics.push(format!("animation: {e}")),
        }
        grabbed
    }

    /// A drag sensor holding the pointer follows the cursor, moved by `(dx, dy)` pixels.
    fn drag_sensor(&mut self, dx: f32, dy: f32) {
        let Some((x, y)) = self.grab else { return };
        let (x, y) = (x + dx, y + dy);
        self.grab = Some((x, y));
        let Some((ray, _)) = self.pointer(x, y) else { return };
        let Some(playing) = self.playing.as_mut() else { return };
        let t = playing.time();
        match playing.scene.pointer_drag(ray, t, &mut self.rt) {
            Ok(changed) => self.scene_dirty |= changed,
            Err(e) => self.diagnostics.push(format!("animation: {e}")),
        }
    }

    fn apply(&mut self, command: Command) {
        let camera_before = self.nav.camera;
        match command {
            Command::Orbit { dx, dy } if self.grab.is_some() => self.drag_sensor(dx, dy),
            Command::Hover { .. } => {
                self.sense_pointer(&command);
            }
            Command::Press { x, y } => {
                self.grab = None;
                if self.sense_pointer(&command) {
                    self.grab = Some((x, y));
                }
            }
            Command::Release { .. } => {
                self.grab = None;
                self.sense_pointer(&command);
            }
            Command::Orbit { dx, dy } => self.nav.orbit(dx, dy),
            Command::Look { dx, dy } => self.nav.look(dx, dy),
            Command::Fly { direction, seconds } => self.nav.fly(Vec3A::from_array(direction), seconds),
            Command::Dolly { steps } => self.nav.dolly(steps),
            Command::ResetView => self.nav = self.home,
            Command::Select { x, y } => {
                self.selected = self.pick(x, y).and_then(|(index, depth)| {
                    let instance = *self.rt.world_instance_ids().get(index)?;
                    Some(Selection { instance, depth })
                });
            }
            Command::MoveSelected { dx, dy } => {
                let Some(sel) = self.selected else { return };
                let (w, h) = self.size();
                let offset = self.nav.view_plane_offset(sel.depth, dx, dy, w, h);
                if let Ok(m) = self.rt.instance_transform(sel.instance) {
                    let moved = Affine3A::from_translation(Vec3::from(offset)) * m;
                    if self.rt.set_instance_transform(sel.instance, moved).is_ok() {
                        self.scene_dirty = true;
                    }
                }
            }
            Command::CycleAntialiasing => {
                self.rt.options.antialiasing = match self.rt.options.antialiasing {
                    Antialiasing::Grid { jitter: true } => Antialiasing::Interleaved,
                    Antialiasing::Interleaved => Antialiasing::Adaptive { threshold: 0.05 },
                    Antialiasing::Adaptive { .. } => Antialiasing::Grid { jitter: false },
                    Antialiasing::Grid { jitter: false } => Antialiasing::Grid { jitter: true },
                };
                let aa = self.rt.options.antialiasing;
                if let Some(world) = self.world.as_mut() {
                    world.options.antialiasing = aa;
                }
                self.view_changed();
            }
            Command::NextViewpoint => {
                if self.viewpoints.is_empty() {
                    self.diagnostics.push("V: the scene has no viewpoints".to_string());
                } else {
                    self.viewpoint = (self.viewpoint + 1) % self.viewpoints.len();
                    let v = self.viewpoints[self.viewpoint].clone();
                    match self.playing.as_mut() {
                        // Bound in the scene, which moves the camera as animation moves it.
                        Some(playing) => playing.scene.bind_viewpoint(v.index, &mut self.rt),
                        None => self.rt.camera_look_at(v.eye, v.eye + v.forward, v.up, v.fov_degrees),
                    }
                    self.nav = Navigation::new(*self.rt.camera(), self.world().scene.bounds());
                    eprintln!("viewpoint {} of {}: {}", self.viewpoint + 1, self.viewpoints.len(), v.name);
                }
            }
            Command::Gaze { at } => {
                self.follow_gaze(at);
                self.view_changed();
            }
            Command::ToggleFrameless => {
                self.frameless = !self.frameless;
                self.view_changed();
            }
            Command::CycleCamera => {
                let current =
                    self.world.as_ref().and_then(|w| w.camera_shader.as_ref()).map(|c| c.program.name.clone());
                let at = CAMERAS.iter().position(|c| Some(*c) == current.as_deref()).map_or(0, |i| i + 1);
                let next = CAMERAS.get(at).copied();
                let bound = match next {
                    Some(name) => self.rt.find_shader(name).and_then(|id| self.rt.camera_shader(Some(id), &[])),
                    None => self.rt.camera_shader(None, &[]),
                };
                match bound.map_err(anyhow::Error::from).and_then(|()| self.rebuild()) {
                    Ok(()) => {}
                    Err(e) => self.diagnostics.push(format!("camera shader: {e}")),
                }
            }
        }
        if self.nav.camera != camera_before {
            self.rt.set_camera(self.nav.camera);
            if let Some(world) = self.world.as_mut() {
                world.camera = self.nav.camera;
            }
            self.view_changed();
        }
    }

    /// Sets relevance to follow window pixel `at`: 1 within a sixth of the shorter side of the
    /// image around it, falling to 0 over as much again (`None`: the scene's own parameters).
    fn follow_gaze(&mut self, at: Option<(f32, f32)>) {
        let params = &mut self.rt.options.ray_parameters;
        match at {
            Some((x, y)) => {
                let before = self.before_gaze.get_or_insert_with(|| params.clone());
                *params = before.clone();
                params.remove(RELEVANCE);
                let (w, h) = (self.rt.options.width, self.rt.options.height);
                let radius = w.min(h) as f32 / 6.0;
                let field = RayField::Gaze { centre: [x, y], radius, falloff: radius, inside: 1.0.into() };
                let set = params.set(RELEVANCE, 0.0.into()).and_then(|()| params.set_field(RELEVANCE, Some(field)));
                if let Err(e) = set {
                    self.diagnostics.push(format!("gaze: {e}"));
                }
            }
            None => {
                if let Some(before) = self.before_gaze.take() {
                    *params = before;
                }
            }
        }
        let params = self.rt.options.ray_parameters.clone();
        if let Some(world) = self.world.as_mut() {
            world.options.ray_parameters = params;
        }
    }

    /// Hot reload: swaps in what compiled, keeps diagnostics of what did not.
    fn reload(&mut self) {
        let Some(reloader) = self.reloader.as_mut() else { return };
        if reloader.apply(&mut self.rt).is_empty() {
            return;
        }
        for event in self.rt.take_shader_events() {
            match &event {
                ShaderEvent::Reloaded { name, compile_ms, .. } => {
                    self.diagnostics.retain(|d| !d.starts_with(&format!("{name}:")));
                    eprintln!("reloaded {name} ({compile_ms:.1} ms)");
                    self.scene_dirty = true;
                }
                ShaderEvent::Failed { name, diagnostics, .. } => {
                    eprintln!("{event}");
                    self.diagnostics.retain(|d| !d.starts_with(&format!("{name}:")));
                    let lines: Vec<&str> = diagnostics.lines().filter(|l| !l.trim().is_empty()).take(6).collect();
                    self.diagnostics.push(format!("{name}: does not compile; the last good version renders"));
                    self.diagnostics.extend(lines.into_iter().map(|l| format!("{name}:  {l}")));
                }
                ShaderEvent::ParameterDropped { .. } => {
                    eprintln!("warning: {event}");
                    self.diagnostics.push(format!("{event}"));
                }
            }
        }
    }

    /// The name of the camera in use, for the overlay.
    fn camera_name(&self) -> String {
        self.world
            .as_ref()
            .and_then(|w| w.camera_shader.as_ref())
            .map_or_else(|| "built-in pinhole".to_string(), |c| c.program.name.clone())
    }

    /// Rebuilds the world after a scene change (the top-level BVH only, unless geometry changed).
    fn rebuild(&mut self) -> anyhow::Result<()> {
        if let Some(old) = self.world.take() {
            self.rt.return_scene(old);
        }
        let world = self.rt.build_world()?;
        for w in self.rt.take_warnings() {
            self.diagnostics.push(w.clone());
            eprintln!("warning: {w}");
        }
        self.world = Some(world);
        self.scene_dirty = false;
        self.view_changed();
        Ok(())
    }

    fn account(&mut self, report: &BatchReport) {
        if report.primary_rays > 0 {
            let per_ray = report.elapsed.as_secs_f64() / report.primary_rays as f64;
            self.seconds_per_ray = 0.7 * self.seconds_per_ray + 0.3 * per_ray;
        }
        self.summary.rays += report.total_rays;
        self.summary.render_time += report.elapsed;
        self.window.1 += report.total_rays;
    }

    /// Primary rays that fit in `budget` at the measured speed.
    fn rays_in(&self, budget: Duration) -> usize {
        (budget.as_secs_f64() / self.seconds_per_ray.max(1e-9)) as usize
    }

    /// Does one piece of work (at most about a frame budget); returns whether to publish, and
    /// whether the view was moving.
    fn step(&mut self, pool: &rayon::ThreadPool, workers: &mut Workers) -> Option<bool> {
        let (w, h) = self.size();
        let moving = self.changed_at.elapsed() < SETTLE;
        if self.frameless {
            // A completed sweep since the last change is a still image, however soon it came.
            return self.step_frameless(pool, workers).then_some(moving && self.still_sweeps == 0);
        }
        if moving {
            // The smallest stride whose pass fits the budget.
            let pixels = (w as usize * h as usize).max(1);
            let fit = self.rays_in(MOVING_BUDGET);
            let stride = [1u32, 2, 4, 8].into_iter().find(|s| pixels / (s * s) as usize <= fit).unwrap_or(8);
            let lattices = pass_lattices(w, h, stride);
            let world = held(&self.world);
            let (results, report) = trace(
                workers,
                pool,
                &self.rt,
                world,
                &mut self.diagnostics,
                &self.light_paths,
                &lattices,
                0,
                stride > 1,
                &|_, _| true,
            );
            self.account(&report);
            // Previews replace, even at stride 1: counted as samples, the same pass-0 sample would
            // pile up once per preview frame and outweigh the still passes that follow.
            self.acc.add_lattices(&results, true);
            self.pass = 0;
            self.pass_cursor = 0;
            return Some(true);
        }
        if self.pass >= self.still_limit {
            return None;
        }
        // A slice of the current full pass, sized to the budget.
        if self.pass_cursor == 0 {
            self.refine = match self.world().options.antialiasing {
                Antialiasing::Adaptive { threshold } if self.pass > 0 => {
                    let test = RefineTest::of(self.world(), threshold);
                    Some(
                        (0..h)
                            .flat_map(|y| (0..w).map(move |x| (x, y)))
                            .map(|(x, y)| self.acc.needs_refinement(x, y, &test))
                            .collect(),
                    )
                }
                _ => None,
            };
        }
        let chunk = (self.rays_in(MOVING_BUDGET) / 64).max(self.threads * 2).max(1);
        let end = (self.pass_cursor + chunk).min(self.full_lattices.len());
        let lattices = &self.full_lattices[self.pass_cursor..end];
        let refine = self.refine.as_deref();
        let world = held(&self.world);
        // Under relevance, a pixel takes its share of the passes (as a frame's pixels take their
        // share of its samples), at least one.
        let (params, pass, limit) = (&world.options.ray_parameters, self.pass, self.still_limit);
        let by_relevance = params.get(RELEVANCE).is_some();
        let wanted = |x: u32, y: u32| {
            refine.is_none_or(|r| r[(y * w + x) as usize])
                && (!by_relevance || {
                    let r = params.float_at(RELEVANCE, Some((x, y)), (w, h)).unwrap_or(1.0);
                    pass < samples_for_relevance(limit, r)
                })
        };
        let (results, report) = trace(
            workers,
            pool,
            &self.rt,
            world,
            &mut self.diagnostics,
            &self.light_paths,
            lattices,
            self.pass,
            false,
            &wanted,
        );
        self.account(&report);
        self.acc.add_lattices(&results, false);
        self.pass_cursor = end;
        if self.pass_cursor >= self.full_lattices.len() {
            self.pass_cursor = 0;
            self.pass += 1;
            self.summary.full_passes += 1;
            return Some(false);
        }
        // A long pass still shows its progress now and then.
        (self.last_publish.elapsed() > Duration::from_millis(250)).then_some(false)
    }

    fn step_frameless(&mut self, pool: &rayon::ThreadPool, workers: &mut Workers) -> bool {
        if self.still_sweeps >= self.still_limit {
            return false;
        }
        // Half a refresh interval of work per step, so input is applied at least that often.
        let chunk = (self.rays_in(FRAMELESS_REFRESH / 2) / 64).max(self.threads * 2).max(1);
        let end = (self.order_cursor + chunk).min(self.order.len());
        let world = held(&self.world);
        let lattices = &self.order[self.order_cursor..end];
        let (results, report) = trace(
            workers,
            pool,
            &self.rt,
            world,
            &mut self.diagnostics,
            &self.light_paths,
            lattices,
            self.sweeps,
            false,
            &|_, _| true,
        );
        self.account(&report);
        self.acc.add_lattices(&results, false);
        self.order_cursor = end;
        if self.order_cursor >= self.order.len() {
            self.order_cursor = 0;
            self.sweeps = self.sweeps.wrapping_add(1);
            self.still_sweeps += 1;
            self.summary.full_passes += 1;
            if self.still_sweeps >= self.still_limit {
                // The last sweep: show it now, nothing comes after it to publish it.
                return true;
            }
        }
        self.last_publish.elapsed() >= FRAMELESS_REFRESH
    }

    fn publish(&mut self, moving: bool) -> Published {
        let now = Instant::now();
        let since = now - self.last_publish;
        self.last_publish = now;
        if moving {
            self.summary.moving_frames += 1;
            self.summary.moving_time += since;
        } else {
            self.summary.still_frames += 1;
            self.summary.still_time += since;
        }
        self.window.2 += 1;
        let age = self.window.0.elapsed();
        if age >= Duration::from_millis(500) {
            let secs = age.as_secs_f64();
            self.rate = (f64::from(self.window.2) / secs, self.window.1 as f64 / secs / 1e6);
            self.window = (now, 0, 0);
        }
        let transfer = self.world().options.transfer();
        if self.display.as_ref().is_none_or(|(t, _)| *t != transfer) {
            self.display = Some((transfer, transfer.byte_table()));
        }
        let world = self.world();
        let image = self.acc.resolve(world);
        let table = self.display.as_ref().map(|(_, table)| table).expect("made above");
        let pixels = image.rgba.chunks_exact(4).map(|c| pack(table, [c[0], c[1], c[2], c[3]])).collect();
        let (w, h) = self.size();
        let still_passes = if self.frameless { self.still_sweeps } else { self.pass };
        let mode = if self.frameless {
            format!("frameless, sweep {}", self.still_sweeps)
        } else if moving {
            "progressive, moving (preview)".to_string()
        } else {
            format!("progressive, {} spp", self.pass)
        };
        let mut status = vec![
            format!("{:.1} fps  {:.2} Mrays/s  {w}x{h}  {} threads", self.rate.0, self.rate.1, self.threads),
            format!("{mode}  aa {}  camera {}", aa_name(world.options.antialiasing), self.camera_name()),
        ];
        if let Some(sel) = self.selected {
            status.push(format!("selected instance {} (shift-drag moves it)", sel.instance.0));
        }
        if let Some(v) = self.viewpoints.get(self.viewpoint).filter(|_| self.viewpoints.len() > 1) {
            let name = if v.name.is_empty() { "(no description)" } else { v.name.as_str() };
            status.push(format!("viewpoint {} of {}: {name} (V: next)", self.viewpoint + 1, self.viewpoints.len()));
        }
        if self.before_gaze.is_some() {
            status.push("gaze: quality follows the cursor (G turns it off)".to_string());
        }
        for m in world.textures.take_warnings() {
            self.diagnostics.push(m.to_string());
        }
        // Keep the newest diagnostics only.
        let excess = self.diagnostics.len().saturating_sub(12);
        self.diagnostics.drain(..excess);
        Published {
            width: w,
            height: h,
            pixels,
            applied: self.applied,
            still_passes,
            moving,
            status,
            diagnostics: self.diagnostics.clone(),
        }
    }

    fn summary(&self) -> Summary {
        Summary { threads: self.threads, ..self.summary }
    }

    /// Runs until the command channel closes: applies input, renders (on `workers` where there
    /// are any, else on `pool`), publishes into `slot` and calls `notify` after each image.
    pub fn run(
        mut self,
        commands: Receiver<(u64, Command)>,
        slot: Arc<Mutex<Option<Published>>>,
        notify: impl Fn(),
        pool: &rayon::ThreadPool,
        mut workers: Workers,
    ) -> Summary {
        if let Some(m) = workers.as_ref().filter(|m| m.workers() > 0) {
            self.threads = m.worker_threads();
        }
        // The first image straight away, as a preview.
        self.changed_at = Instant::now();
        loop {
            let idle =
                if self.frameless { self.still_sweeps >= self.still_limit } else { self.pass >= self.still_limit };
            let first = if idle {
                // Converged: sleep until input arrives.
                match commands.recv_timeout(Duration::from_millis(100)) {
                    Ok(c) => Some(c),
                    Err(RecvTimeoutError::Timeout) => None,
                    Err(RecvTimeoutError::Disconnected) => return self.summary(),
                }
            } else {
                None
            };
            if let Some((seq, c)) = first {
                self.applied = seq;
                self.apply(c);
            }
            loop {
                match commands.try_recv() {
                    Ok((seq, c)) => {
                        self.applied = seq;
                        self.apply(c);
                    }
                    Err(TryRecvError::Empty) => break,
                    Err(TryRecvError::Disconnected) => return self.summary(),
                }
            }
            self.reload();
            self.animate();
            if self.scene_dirty {
                if let Err(e) = self.rebuild() {
                    // The API refused the change (it never should for a move); say so, keep going.
                    self.diagnostics.push(format!("scene update failed: {e:#}"));
                    self.scene_dirty = false;
                }
            }
            if let Some(moving) = self.step(pool, &mut workers) {
                let image = self.publish(moving);
                if let Ok(mut s) = slot.lock() {
                    *s = Some(image);
                }
                notify();
            }
        }
    }
}
