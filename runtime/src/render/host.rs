//! The renderer's side of the packet ABI: the `HostTable` a shader call gets (`ShadeCall`), and its
//! callbacks: named spaces, lights (served from the batch's light table), textures, rays (`trace`,
//! `transmission`, `occlusion`, `indirectdiffuse`), depth, messages, names and `printf`.
//!
//! Invariant: callbacks never unwind into JIT code; they index only buffers whose sizes the packet
//! ABI fixes, and nothing in them panics on user data.

use super::ray_budget::{Bounce, RayBudget, RayOrigin};
use super::ray_params::{object_value, strip_user, RayValue, RELEVANCE};
use super::stats::{tracing, Stats};
use super::trace_ahead::{GatherAt, OcclusionAt, RayLog};
use super::virtual_lights;
use super::work::{launch_epsilon, BatchLights, Frame, PixelImage, Sample};
use crate::ray::Ray;
use crate::shading::ShaderInstance;
use crate::texture::{Grid, LookupLanes, LookupOptions, MipMap, TextureCache};
use glam::{Affine3A, Mat4, Vec3A, Vec4};
use rtsl_compiler::abi::{
    environment_query_of, same_category, shadow_query_of, BatchLightsView, Builtin, GatherHit, HostTable, LightLanes,
    MessageOut, PixelChannel, PixelOutputs, PixelView, StrRef, CONE_ROWS, ENVIRONMENT_ROWS, MAX_LIGHTS, SHADOW_ROWS,
    TEXTURE_ROWS,
};
use std::cell::RefCell;
use std::collections::HashMap;
use std::ffi::c_void;
use std::sync::Arc;

/// The renderer side of one shader call: what the host callbacks need to answer it.
pub(crate) struct ShadeCall<'f, 'w> {
    frame: &'f Frame<'w>,
    instance: &'f ShaderInstance,
    world_from_object: Affine3A,
    depth: u32,
    /// The last light query (diffuse() and specular() of one chunk ask for the same lights).
    light_cache: Option<LightQuery>,
    text: String,
    /// For a surface batch: each lane's `P` as filled and whether it is shaded, so the lights of
    /// the whole batch are computed at the first light query and chunks are served from them.
    pub(super) batch_points: Vec<Vec3A>,
    pub(super) batch_mask: Vec<i32>,
    /// Each lane's ray time (rays the shader spawns keep it).
    pub(super) batch_times: Vec<f32>,
    /// Each lane's normal faced toward the eye (empty when unknown): the lights in front of it get
    /// their shadows traced with the batch's, the others when a query asks for them.
    pub(super) batch_front: Vec<Vec3A>,
    batch_lights: Option<BatchLights>,
    /// `batch_lights` as generated code reads it in place ([`HostTable::batch_lights`]), once
    /// computed, with the batch's points and lanes by chunk (`chunk_points`, `chunk_lanes`).
    light_view: BatchLightsView,
    chunk_points: Vec<[f32; 12]>,
    chunk_lanes: Vec<[i32; 4]>,
    chunk_cursor: usize,
    /// Where the next chunk search starts.
    chunk_next: usize,
    /// The grid last looked up, by name: a volume's march asks for the same grid at every step,
    /// and finding it in the shared cache costs a lock, a hash and an atomic count.
    last_grid: Option<(String, Option<Arc<Grid>>)>,
    /// The textures looked up, by name (this thread's, where the call took its buffers).
    textures: TextureHandles,
    /// The material of the surface being shaded (for the surface's own shaders and the lights
    /// that light it): what `surface()` and `displacement()` messages read.
    pub(super) material: Option<u32>,
    /// What `trace` does with its rays: traces them, or (running a batch twice) notes them or
    /// answers them from the notes (`trace_ahead.rs`).
    pub(super) rays_log: RayLog,
    /// For a pixel shader: the image it finishes, as it was before the shader ran (`pixelvalue`).
    pub(super) pixels: Option<&'f PixelImage>,
    /// The view of `pixels` the call table points generated code to, made by [`ShadeCall::table`],
    /// and the arrays of the output variables the shader reads that it points to.
    pixel_view: Option<PixelView>,
    pixel_outputs: Option<PixelOutputs>,
    /// What each lane's ray tree may still spawn (`ray_budget.rs`); a lane past its end may
    /// spawn nothing.
    pub(super) budgets: &'f mut [RayBudget],
}

/// The buffers of a [`ShadeCall`], reused from call to call: a call is made for every batch, and
/// allocating them afresh would be tens of thousands of allocations a frame.
#[derive(Default)]
struct CallBuffers {
    points: Vec<Vec3A>,
    mask: Vec<i32>,
    times: Vec<f32>,
    front: Vec<Vec3A>,
    chunk_points: Vec<[f32; 12]>,
    chunk_lanes: Vec<[i32; 4]>,
    textures: TextureHandles,
}

/// Textures found in the frame's texture cache, kept by name for as long as the cache's
/// [generation](crate::texture::TextureCache::generation) stays the same, and from call to call
/// (in a thread's [`CallBuffers`]). Looked up in the shared cache for every batch, the cache's lock
/// and the counts of the texture's `Arc` would be taken and dropped by every thread at every
/// batch, each waiting for the other threads' writes to those counts. The handles keep their textures alive until a lookup through them
/// finds the generation changed: after a scene is dropped, a thread may hold its textures until
/// it next shades a textured batch.
#[derive(Default)]
struct TextureHandles {
    generation: u64,
    /// Whether the handles are of textures read as stored (`TextureCache::get_texture`'s `raw`).
    raw: bool,
    by_name: HashMap<String, Option<Arc<MipMap>>>,
    /// The name looked up last, and what it stands for (most lookups repeat it).
    last: Option<(String, Option<Arc<MipMap>>)>,
}

impl TextureHandles {
    fn get(&mut self, cache: &TextureCache, name: &str, raw: bool) -> Option<&MipMap> {
        let generation = cache.generation();
        if generation != self.generation || raw != self.raw {
            self.by_name.clear();
            self.last = None;
            self.generation = generation;
            self.raw = raw;
        }
        if self.last.as_ref().is_none_or(|(last, _)| last != name) {
            if let Some((last, texture)) = self.last.take() {
                self.by_name.insert(last, texture);
            }
            let texture = match self.by_name.remove_entry(name) {
                Some(found) => found,
                None => {
                    let texture = cache.get_texture(name, raw);
                    if texture.is_none() && crate::accel::ask_ahead::asks_ahead() {
                        // Perhaps asked for ahead and not here yet: not kept, asked again.
                        return None;
                    }
                    (name.to_string(), texture)
                }
            };
            self.last = Some(texture);
        }
        self.last.as_ref().and_then(|(_, t)| t.as_deref())
    }
}

thread_local! {
    /// A stack, because calls nest (a surface's light shaders, shading the hits of traced rays).
    static CALL_BUFFERS: RefCell<Vec<CallBuffers>> = const { RefCell::new(Vec::new()) };
}

impl Drop for ShadeCall<'_, '_> {
    fn drop(&mut self) {
        if self.batch_points.capacity() == 0 {
            return;
        }
        let buffers = CallBuffers {
            points: std::mem::take(&mut self.batch_points),
            mask: std::mem::take(&mut self.batch_mask),
            times: std::mem::take(&mut self.batch_times),
            front: std::mem::take(&mut self.batch_front),
            chunk_points: std::mem::take(&mut self.chunk_points),
            chunk_lanes: std::mem::take(&mut self.chunk_lanes),
            textures: std::mem::take(&mut self.textures),
        };
        super::scratch::give(&CALL_BUFFERS, buffers);
    }
}

struct LightQuery {
    category: String,
    p: [u32; 12],
    mask: [i32; 4],
    lights: Vec<LightLanes>,
    counts: [u32; 4],
}

impl<'f, 'w> ShadeCall<'f, 'w> {
    pub(crate) fn new(
        frame: &'f Frame<'w>,
        instance: &'f ShaderInstance,
        world_from_object: Affine3A,
        depth: u32,
        budgets: &'f mut [RayBudget],
    ) -> Self {
        ShadeCall {
            budgets,
            frame,
            instance,
            world_from_object,
            depth,
            light_cache: None,
            text: String::new(),
            batch_points: Vec::new(),
            batch_mask: Vec::new(),
            batch_times: Vec::new(),
            batch_front: Vec::new(),
            batch_lights: None,
            light_view: BatchLightsView::default(),
            chunk_points: Vec::new(),
            chunk_lanes: Vec::new(),
            chunk_cursor: 0,
            chunk_next: 0,
            last_grid: None,
            textures: TextureHandles::default(),
            material: None,
            rays_log: RayLog::Direct,
            pixels: None,
            pixel_view: None,
            pixel_outputs: None,
        }
    }

    /// Takes this thread's spare buffers for the batch's lanes (empty) and texture names. Only the
    /// calls that use them take them: most calls (light shaders, small batches) need none, and
    /// a call that takes nothing gives nothing back.
    pub(super) fn take_buffers(&mut self) {
        let CallBuffers { mut points, mut mask, mut times, mut front, chunk_points, chunk_lanes, textures } =
            super::scratch::take(&CALL_BUFFERS);
        points.clear();
        mask.clear();
        times.clear();
        front.clear();
        (self.batch_points, self.batch_mask, self.batch_times, self.batch_front) = (points, mask, times, front);
        (self.chunk_points, self.chunk_lanes) = (chunk_points, chunk_lanes);
        self.textures = textures;
    }

    /// The budget of lane `l` of chunk `chunk` (`None` past the batch's lanes).
    fn budget(&mut self, chunk: u32, l: usize) -> Option<&mut RayBudget> {
        let lane = (chunk as usize).checked_mul(4)?.checked_add(l)?;
        self.budgets.get_mut(lane)
    }

    /// Takes a ray from the budget of lane `l` of chunk `chunk`: what the ray is lent, with its
    /// bounce of `kind` if it takes one, or `None` (a ray cut, counted) when the lane has nothing
    /// left.
    fn spawn(&mut self, chunk: u32, l: usize, kind: Option<Bounce>) -> Option<RayBudget> {
        let frame = self.frame;
        if let Some(budget) = self.budget(chunk, l) {
            if budget.take(1) {
                let lent = budget.lend();
                return Some(kind.map_or(lent, |kind| lent.bounced(kind)));
            }
        }
        Stats::add(&frame.stats.rays_cut, 1);
        None
    }

    /// Whether lane `l` of chunk `chunk` may spawn a ray that takes a bounce of `kind` (not past
    /// the batch's lanes).
    fn may_bounce(&mut self, chunk: u32, l: usize, kind: Bounce) -> bool {
        self.budget(chunk, l).is_some_and(|b| b.bounces.allow(kind))
    }

    /// The budgets of chunk `chunk`'s lanes (nothing to spend past the batch's).
    fn chunk_budgets(&mut self, chunk: u32) -> [RayBudget; 4] {
        std::array::from_fn(|l| self.budget(chunk, l).map_or(RayBudget::NONE, |b| *b))
    }

    fn set_chunk_budgets(&mut self, chunk: u32, budgets: [RayBudget; 4]) {
        for (l, b) in budgets.into_iter().enumerate() {
            if let Some(lane) = self.budget(chunk, l) {
                *lane = b;
            }
        }
    }

    fn grid(&mut self, name: &str) -> Option<&Grid> {
        if self.last_grid.as_ref().is_none_or(|(last, _)| last != name) {
            self.last_grid = Some((name.to_string(), self.frame.world.textures.get_grid(name)));
        }
        self.last_grid.as_ref().and_then(|(_, g)| g.as_deref())
    }

    fn texture(&mut self, name: &str) -> Option<&MipMap> {
        let raw = self.frame.world.options.textures_as_stored();
        self.textures.get(&self.frame.world.textures, name, raw)
    }

    /// The ray time of lane `l` of the current chunk (the batch's first lane's when out of range;
    /// 0 without a batch).
    pub(super) fn lane_time(&self, l: usize) -> f32 {
        let t = &self.batch_times;
        t.get(4 * self.chunk_cursor + l).or(t.first()).copied().unwrap_or(0.0)
    }

    /// The call table; valid while `self` is neither moved nor dropped.
    pub(crate) fn table(&mut self) -> HostTable {
        let (image, names) = (self.pixels, self.instance.program.code.pixel_outputs());
        self.pixel_outputs = match image {
            Some(image) if !names.is_empty() => {
                let pixels = image.width as usize * image.height as usize;
                PixelOutputs::new(pixels, names.iter().map(|name| image.output(name)))
            }
            _ => None,
        };
        self.pixel_view = image.and_then(PixelImage::view).map(|view| match &self.pixel_outputs {
            Some(outputs) => view.with_outputs(outputs),
            None => view,
        });
        let ctx = self as *mut ShadeCall;
        HostTable {
            ctx: ctx as *mut c_void,
            matrix: host_matrix,
            lights: host_lights,
            texture: host_texture,
            rays: host_rays,
            gather: host_gather,
            depth: host_depth,
            ray_depth: host_ray_depth,
            message: host_message,
            light_message: host_light_message,
            volume_message: host_volume_message,
            shader_name: host_shader_name,
            print: host_print,
            pixels: self.pixel_view.as_ref().map_or(std::ptr::null(), |v| v as *const PixelView),
            // From `ctx` itself: the host calls write the view through `ctx` between the reads
            // generated code makes through this pointer.
            // SAFETY: `ctx` points to `self`, alive and unmoved while the table is used.
            batch_lights: unsafe { std::ptr::addr_of!((*ctx).light_view) },
        }
    }

    /// Points generated code to the batch's lights (`light_view`), once computed: the batch's
    /// points and lanes by chunk, and the table's arrays, which stay where they are until the
    /// call ends (`resolve` changes rows and pending masks in place).
    fn publish_batch_lights(&mut self) {
        let Some(table) = &self.batch_lights else { return };
        let chunks = table.counts.len().min(table.pending.len()).min(self.batch_points.len().div_ceil(4));
        if chunks.checked_mul(table.slots).is_none_or(|rows| rows > table.lights.len()) || chunks > u32::MAX as usize {
            return;
        }
        let (points, mask) = (&self.batch_points, &self.batch_mask);
        self.chunk_points.clear();
        self.chunk_lanes.clear();
        for c in 0..chunks {
            let lane = |l: usize| {
                (4 * c + l < points.len() && mask.get(4 * c + l).is_some_and(|&m| m != 0)).then(|| points[4 * c + l])
            };
            self.chunk_points.push(std::array::from_fn(|i| lane(i % 4).map_or(0.0, |p| p[i / 4])));
            self.chunk_lanes.push(std::array::from_fn(|l| if lane(l).is_some() { -1 } else { 0 }));
        }
        self.light_view = BatchLightsView {
            chunks: chunks as u32,
            slots: table.slots as u32,
            points: self.chunk_points.as_ptr(),
            lanes: self.chunk_lanes.as_ptr(),
            counts: table.counts.as_ptr(),
            pending: table.pending.as_ptr(),
            lights: table.lights.as_ptr(),
        };
    }

    /// World from a named space, `None` for an unknown name.
    fn world_from(&self, space: &str) -> Option<Mat4> {
        let world = self.frame.world;
        let m = match space {
            "current" | "world" => Affine3A::IDENTITY,
            "object" => self.world_from_object,
            "shader" => self.instance.world_from_shader,
            "camera" => world.camera.world_from_camera,
            "screen" | "NDC" | "raster" => return self.world_from_projected(space),
            other => *world.spaces.get(other)?,
        };
        Some(Mat4::from(m))
    }

    fn world_from_projected(&self, space: &str) -> Option<Mat4> {
        let world = self.frame.world;
        let (w, h) = (world.options.width.max(1) as f32, world.options.height.max(1) as f32);
        let tan = (world.camera.fov_degrees.to_radians() * 0.5).tan();
        let e = world.options.screen_extent();
        let ((ax, ay), (cx, cy)) = (e.half, e.centre);
        // camera -> screen: x' = x / (z tan), y' likewise, z' = z (a projective matrix); the
        // screen window [cx - ax, cx + ax] x [cy - ay, cy + ay] is the image.
        let near = world.camera.near.max(1e-6);
        let far = world.camera.far.max(near * 2.0);
        let proj = Mat4::from_cols_array(&[
            1.0 / tan,
            0.0,
            0.0,
            0.0,
            0.0,
            1.0 / tan,
            0.0,
            0.0,
            0.0,
            0.0,
            far / (far - near),
            1.0,
            0.0,
            0.0,
            -far * near / (far - near),
            0.0,
        ]);
        let screen_from_camera = match space {
            "screen" => proj,
            // NDC and raster are screen space scaled and moved: x right from 0, y down from 0.
            "NDC" => window(0.5 / ax, -0.5 / ay, 0.5 - 0.5 * cx / ax, 0.5 + 0.5 * cy / ay) * proj,
            _ => window(0.5 * w / ax, -0.5 * h / ay, (0.5 - 0.5 * cx / ax) * w, (0.5 + 0.5 * cy / ay) * h) * proj,
        };
        let camera_from_screen = screen_from_camera.inverse();
        Some(Mat4::from(world.camera.world_from_camera) * camera_from_screen)
    }
}

/// Scales x and y, then moves them: screen space to NDC or raster space.
fn window(sx: f32, sy: f32, ox: f32, oy: f32) -> Mat4 {
    Mat4::from_translation(glam::Vec3::new(ox, oy, 0.0)) * Mat4::from_scale(glam::Vec3::new(sx, sy, 1.0))
}

/// # Safety
/// `ctx` is the `ctx` of a table made by [`ShadeCall::table`] whose call is alive.
unsafe fn call<'x>(ctx: *mut c_void) -> &'x mut ShadeCall<'x, 'x> {
    // SAFETY: the caller's contract.
    unsafe { &mut *(ctx as *mut ShadeCall<'x, 'x>) }
}

/// # Safety
/// `p` points to `n` floats.
unsafe fn slice<'x>(p: *const f32, n: usize) -> &'x [f32] {
    // SAFETY: the caller's contract.
    unsafe { std::slice::from_raw_parts(p, n) }
}

fn lane3(v: &[f32], k: usize, l: usize) -> Vec3A {
    Vec3A::new(v[4 * k + l], v[4 * (k + 1) + l], v[4 * (k + 2) + l])
}

unsafe extern "C" fn host_matrix(ctx: *mut c_void, from: StrRef, to: StrRef, out: *mut f32) -> u32 {
    // SAFETY: the table's contract: `ctx` is alive, the strings valid, `out` holds 16 floats.
    let (c, from, to) = unsafe { (call(ctx), from.as_str(), to.as_str()) };
    let (Some(a), Some(b)) = (c.world_from(from), c.world_from(to)) else { return 0 };
    // Points go from `from` to world, then from world to `to`. glam's column-major array of a
    // column-vector matrix is RenderMan's row-major array of the row-vector one.
    // Most spaces are asked for into world ("current") space: no inverse to work out then.
    let m = if b == Mat4::IDENTITY { a } else { b.inverse() * a }.to_cols_array();
    if !m.iter().all(|x| x.is_finite()) {
        return 0;
    }
    // SAFETY: `out` holds 16 floats.
    unsafe { std::ptr::copy_nonoverlapping(m.as_ptr(), out, 16) };
    1
}

unsafe extern "C" fn host_lights(
    ctx: *mut c_void,
    category: StrRef,
    chunk: u32,
    mask: *const i32,
    p: *const f32,
    cone: *const f32,
    out: *mut LightLanes,
    counts: *mut u32,
    pending: *mut u32,
) {
    // SAFETY: the table's contract: 4 mask entries, 12 floats of P, CONE_ROWS x 4 floats of cone,
    // MAX_LIGHTS rows of lights, 4 counts, 4 pending masks.
    let (c, category, mask, p, cone, out, counts, pending) = unsafe {
        (
            call(ctx),
            category.as_str(),
            &*(mask as *const [i32; 4]),
            slice(p, 12),
            slice(cone, 4 * CONE_ROWS),
            std::slice::from_raw_parts_mut(out, MAX_LIGHTS),
            &mut *(counts as *mut [u32; 4]),
            &mut *(pending as *mut [u32; 4]),
        )
    };
    *pending = [0; 4];
    if category.is_empty()
        && !c.batch_points.is_empty()
        && serve_from_batch(c, chunk, mask, p, cone, out, (counts, pending))
    {
        return;
    }
    let pbits: [u32; 12] = std::array::from_fn(|i| p[i].to_bits());
    if let Some(q) = &c.light_cache {
        if same_category(&q.category, category) && q.p == pbits && q.mask == *mask {
            out[..q.lights.len()].copy_from_slice(&q.lights);
            *counts = q.counts;
            return;
        }
    }
    *counts = [0; 4];
    let points: [Vec3A; 4] = std::array::from_fn(|l| lane3(p, 0, l));
    locate_chunk(c, mask, p);
    let times: [f32; 4] = std::array::from_fn(|l| c.lane_time(l));
    let mut budgets = c.chunk_budgets(chunk);
    for light in &c.frame.world.lights {
        if !light.in_category(category) {
            continue;
        }
        let stages = &c.frame.stages;
        (stages.eval_light)(c.frame, light, c.material, mask, &points, &times, c.depth, &mut budgets, out, counts);
    }
    c.set_chunk_budgets(chunk, budgets);
    let used = counts.iter().copied().max().unwrap_or(0) as usize;
    c.light_cache = Some(LightQuery {
        category: category.to_string(),
        p: pbits,
        mask: *mask,
        lights: out[..used].to_vec(),
        counts: *counts,
    });
}

/// Finds the chunk of the surface batch whose points are `p` (bit for bit, in the lanes of `mask`)
/// and makes it the current chunk; false (the current chunk unchanged) when none is.
fn locate_chunk(c: &mut ShadeCall, mask: &[i32; 4], p: &[f32]) -> bool {
    let chunks = c.batch_points.len().div_ceil(4);
    let matches = |chunk: usize| chunk_matches(c, chunk, mask, p);
    // The shader asks chunk after chunk, several times per chunk (`ambient()`, then `diffuse()`):
    // the search starts at the last chunk found, then goes on after it.
    if c.chunk_cursor < chunks && matches(c.chunk_cursor) {
        return true;
    }
    match (0..chunks).map(|k| (c.chunk_next + k) % chunks).find(|&k| matches(k)) {
        Some(chunk) => {
            c.chunk_cursor = chunk;
            c.chunk_next = chunk + 1;
            true
        }
        None => false,
    }
}

/// Whether the active lanes of chunk `chunk` of the batch are at the points `p` (bit for bit).
fn chunk_matches(c: &ShadeCall, chunk: usize, mask: &[i32; 4], p: &[f32]) -> bool {
    let n = c.batch_points.len();
    (0..4).all(|l| {
        let lane = 4 * chunk + l;
        mask[l] == 0
            || (lane < n && c.batch_mask[lane] != 0 && {
                let q = c.batch_points[lane];
                q.x.to_bits() == p[l].to_bits()
                    && q.y.to_bits() == p[4 + l].to_bits()
                    && q.z.to_bits() == p[8 + l].to_bits()
            })
    })
}

/// Answers a chunk's light query from the batch's lights when the chunk's points are the batch's
/// (bit for bit: a shader that moved `P` gets its lights computed afresh).
#[allow(clippy::too_many_arguments)]
fn serve_from_batch(
    c: &mut ShadeCall,
    chunk: u32,
    mask: &[i32; 4],
    p: &[f32],
    cone: &[f32],
    out: &mut [LightLanes],
    (counts, pending): (&mut [u32; 4], &mut [u32; 4]),
) -> bool {
    let found = match chunk as usize {
        k if k < c.batch_points.len().div_ceil(4) => {
            chunk_matches(c, k, mask, p) && {
                c.chunk_cursor = k;
                true
            }
        }
        _ => locate_chunk(c, mask, p),
    };
    if !found {
        return false;
    }
    let chunk = c.chunk_cursor;
    if c.batch_lights.is_none() {
        let front = (c.batch_front.len() == c.batch_points.len()).then_some(&c.batch_front[..]);
        c.batch_lights = Some((c.frame.stages.batch_lights)(
            c.frame,
            c.material,
            &c.batch_points,
            &c.batch_mask,
            &c.batch_times,
            front,
            c.depth,
            c.budgets,
        ));
        c.publish_batch_lights();
    }
    let Some(table) = &mut c.batch_lights else { return false };
    if (0..4).any(|l| mask[l] != 0 && table.pending_of(4 * chunk + l) != 0) {
        let queries = (0..4)
            .filter(|&l| mask[l] != 0)
            .map(|l| (4 * chunk + l, [cone[l], cone[4 + l], cone[8 + l]], cone[12 + l]));
        table.resolve(c.frame, &c.batch_points, &c.batch_times, queries);
    }
    for l in 0..4 {
        counts[l] = 0;
        let lane = 4 * chunk + l;
        if mask[l] == 0 || lane >= table.n {
            continue;
        }
        counts[l] = table.count_of(lane);
        pending[l] = table.pending_of(lane);
    }
    // The chunk's rows as they lie: lanes past their count hold whatever, which the ABI allows.
    let rows = table.chunk_lights(chunk, counts.iter().copied().max().unwrap_or(0) as usize);
    out[..rows.len()].copy_from_slice(rows);
    true
}

/// Each lane's first channel, `first[l].max(0.0) as usize` (NaN and negatives 0), four lanes in
/// one conversion: clamped to 2^24 first, which changes nothing a lookup does (a texture has
/// fewer channels, and a first channel past them reads none). Lane by lane, the saturating
/// conversions were a third of this function's instructions (BART's robots).
#[inline(always)]
fn first_channels(first: &[f32]) -> [usize; 4] {
    let Some(first) = first.first_chunk::<4>() else { return [0; 4] };
    // `max` with the lanes first: where one is NaN, SSE's `max` gives the second operand, 0.
    let clamped = Vec4::from_array(*first).max(Vec4::ZERO).min(Vec4::splat(16_777_216.0));
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_cvttps_epi32, _mm_storeu_si128};
        let mut lanes = [0i32; 4];
        // SAFETY: SSE2 is part of x86-64; `lanes` is 16 writable bytes, and the store needs no
        // alignment. The lanes are whole numbers in [0, 2^24] once truncated.
        unsafe { _mm_storeu_si128(lanes.as_mut_ptr().cast(), _mm_cvttps_epi32(clamped.into())) };
        lanes.map(|v| v as usize)
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        clamped.to_array().map(|v| v as usize)
    }
}

unsafe extern "C" fn host_texture(
    ctx: *mut c_void,
    kind: u32,
    name: StrRef,
    mask: *const i32,
    coords: *const f32,
    first: *const f32,
    channels: u32,
    out: *mut f32,
    ok: *mut u32,
) {
    let values = match kind {
        0 => channels.min(64) as usize,
        1 => channels.clamp(1, 3) as usize,
        4 | 5 => 3,
        // 2 shadow, 3 a texture3d grid: one value.
        _ => 1,
    };
    let rows = match kind {
        0 => TEXTURE_ROWS,
        1 => ENVIRONMENT_ROWS,
        5 => 7,
        2 => SHADOW_ROWS,
        _ => 3,
    };
    // SAFETY: the table's contract: 4 mask entries, `rows` x 4 coordinates, 4 first channels,
    // `values` x 4 results and 4 flags.
    let (c, name, mask, coords, first, out, ok) = unsafe {
        (
            call(ctx),
            name.as_str(),
            &*(mask as *const [i32; 4]),
            slice(coords, 4 * rows),
            slice(first, 4),
            std::slice::from_raw_parts_mut(out, 4 * values),
            &mut *(ok as *mut [u32; 4]),
        )
    };
    let active = || (0..4).filter(|&l| mask[l] != 0);
    *ok = [0; 4];
    match kind {
        0 => {
            let Some(mip) = c.texture(name) else { return };
            // Rows 0..1 the coordinates; 2..5 the footprint from their derivatives (widths
            // applied); 6 and 7 the blur in s and t; 8 the fill.
            let row = |k: usize| Vec4::from_slice(&coords[4 * k..4 * k + 4]);
            let lanes = LookupLanes {
                s: row(0),
                t: row(1),
                dsdx: row(2),
                dtdx: row(3),
                dsdy: row(4),
                dtdy: row(5),
                sblur: row(6).max(Vec4::ZERO),
                tblur: row(7).max(Vec4::ZERO),
            };
            let active = mask.map(|m| m != 0);
            let (first, fill) = (first_channels(first), row(8).to_array());
            // One fill for the lookup (what a lane with no texel reads), then each lane's own for
            // the channels the texture lacks.
            let shared_fill = active.iter().position(|&a| a).map_or(0.0, |l| fill[l]);
            mip.filter_lanes(
                &lanes,
                active,
                first,
                out,
                &LookupOptions { fill: shared_fill, ..LookupOptions::default() },
            );
            for l in (0..4).filter(|&l| active[l]) {
                for c in (0..values).filter(|&c| first[l] + c >= mip.channels()) {
                    out[4 * c + l] = fill[l];
                }
                ok[l] = 1;
            }
            return;
        }
        3 => {
            let Some(grid) = c.grid(name) else { return };
            let row = |k: usize| Vec4::from_slice(&coords[4 * k..4 * k + 4]);
            let values = grid.lookup_lanes([row(0), row(1), row(2)]);
            for l in active() {
                out[l] = values[l];
                ok[l] = 1;
            }
            return;
        }
        5 => {
            // The frame's own maps by name: "caustic" and "global"; none while they are traced.
            let (frame, gi) = (c.frame, c.frame.world.options.gi);
            if frame.tracing_light_paths.load(std::sync::atomic::Ordering::Acquire) {
                return;
            }
            let map = match name {
                "caustic" if gi.caustic_photons > 0 => frame
                    .caustics
                    .get_or_init(|| Arc::new(virtual_lights::timed(frame, || virtual_lights::trace_caustics(frame)))),
                "global" if gi.global_photons > 0 => frame
                    .global_photons
                    .get_or_init(|| Arc::new(virtual_lights::timed(frame, || virtual_lights::trace_global(frame)))),
                _ => return,
            };
            let radius = virtual_lights::photon_search_radius(frame);
            for l in active() {
                let (p, n) = (lane3(coords, 0, l), lane3(coords, 3, l).normalize_or_zero());
                let estimator = coords[24 + l];
                let k = if estimator.is_finite() && estimator >= 1.0 { estimator as usize } else { 50 };
                let e = map.irradiance(p, n, k, radius);
                ok[l] = 1;
                for r in 0..3 {
                    out[4 * r + l] = e[r];
                }
            }
            return;
        }
        4 => {
            let Some(image) = c.pixels else { return };
            // One of the image's own channels, else an output variable it keeps, by name.
            let channel = PixelChannel::of(name);
            let output = if channel.is_none() { image.output(name) } else { None };
            for l in active() {
                let (x, y) = (coords[l], coords[4 + l]);
                let value = match (channel, output) {
                    (Some(channel), _) => image.channel_value(channel, x, y),
                    (None, Some(values)) => image.index(x, y).and_then(|i| values.get(i).copied()),
                    (None, None) => None,
                };
                if let Some(v) = value {
                    ok[l] = 1;
                    for (k, x) in v.iter().enumerate() {
                        out[4 * k + l] = *x;
                    }
                }
            }
            return;
        }
        _ => {}
    }
    let textures = &c.frame.world.textures;
    let channel_lanes = first_channels(first);
    let mut lane_out = [0.0f32; 64];
    for l in active() {
        let found = match kind {
            1 => {
                let query = environment_query_of(coords, l);
                let opts = LookupOptions {
                    sblur: query.sblur.max(0.0),
                    tblur: query.tblur.max(0.0),
                    swidth: query.swidth,
                    twidth: query.twidth,
                    fill: query.fill,
                    raw: c.frame.world.options.textures_as_stored(),
                    ..LookupOptions::default()
                };
                let (dir, ddx, ddy) = (query.dir, query.ddx, query.ddy);
                textures.environment(name, dir, ddx, ddy, channel_lanes[l], &mut lane_out[..values], &opts)
            }
            _ => {
                let query = shadow_query_of(coords, l);
                let p = Vec3A::from(query.p);
                let shadowed = if name == "raytrace" {
                    // Ray-traced shadows (BMRT's convention): towards the light's own origin.
                    let to = c.instance.world_from_shader.translation;
                    let mut t = [Vec3A::ONE];
                    (c.frame.stages.transmission_between)(c.frame, &[Some((p, to, c.lane_time(l)))], &mut t);
                    Some(1.0 - (t[0].x + t[0].y + t[0].z) / 3.0)
                } else {
                    // A query without a bias of its own (NaN) takes the frame's.
                    let [low, high] = match query.bias {
                        b if b.is_nan() => c.frame.world.options.shadow_bias,
                        b => [b; 2],
                    };
                    let opts = LookupOptions {
                        sblur: query.sblur,
                        tblur: query.tblur,
                        swidth: query.swidth,
                        twidth: query.twidth,
                        bias: low.min(high),
                        bias_ramp: (high - low).abs(),
                        // Saturating: NaN and negative counts are 0, then at least one sample.
                        samples: query.samples as u32,
                        ..LookupOptions::default()
                    };
                    textures.shadow_over(name, query.p, &query.corners, &opts)
                };
                if let Some(v) = shadowed {
                    lane_out[0] = v;
                }
                shadowed.is_some()
            }
        };
        if found {
            ok[l] = 1;
            for (k, v) in lane_out[..values].iter().enumerate() {
                out[4 * k + l] = *v;
            }
        }
    }
}

unsafe extern "C" fn host_rays(
    ctx: *mut c_void,
    kind: u32,
    chunk: u32,
    mask: *const i32,
    a: *const f32,
    b: *const f32,
    samples: *const f32,
    out: *mut f32,
) {
    // SAFETY: the table's contract: 4 mask entries, 12 floats each of a and b, 4 samples, and room
    // for the kind's results (at most 4 x 4 floats).
    let (c, mask, a, b, samples) =
        unsafe { (call(ctx), &*(mask as *const [i32; 4]), slice(a, 12), slice(b, 12), slice(samples, 4)) };
    let results = match kind {
        0 => 4,
        1 | 3 => 3,
        _ => 1,
    };
    // SAFETY: as above.
    let out = unsafe { std::slice::from_raw_parts_mut(out, 4 * results) };
    let frame = c.frame;
    let max_depth = frame.world.options.max_ray_depth;
    // Spawned rays keep the time of the ray that reached their lane (found from the points when
    // they are the batch's; otherwise the chunk last served).
    locate_chunk(c, mask, a);
    let times: [f32; 4] = std::array::from_fn(|l| c.lane_time(l));
    match kind {
        0 => {
            let mut requested: [Option<Ray>; 4] = [None; 4];
            for l in 0..4 {
                if mask[l] == 0 {
                    continue;
                }
                for r in 0..3 {
                    out[4 * r + l] = 0.0;
                }
                out[12 + l] = f32::INFINITY;
                let (from, dir) = (lane3(a, 0, l), lane3(b, 0, l).normalize_or_zero());
                // Past the ray depth, or past the specular bounces the lane's path may take, the ray
                // sees nothing.
                if c.depth + 1 > max_depth
                    || dir == Vec3A::ZERO
                    || !from.is_finite()
                    || !c.may_bounce(chunk, l, Bounce::Specular)
                {
                    continue;
                }
                requested[l] = Some(Ray::segment(from, dir, launch_epsilon(from), f32::INFINITY).at_time(times[l]));
            }
            if let RayLog::Record(noted) = &mut c.rays_log {
                // Answered as if nothing were hit, until the second run; nothing is spent yet.
                noted.note(chunk, requested);
                return;
            }
            // Each ray costs its lane one and is lent what the lane has left; past the budget it
            // is answered as past the ray depth.
            let mut lent = [RayBudget::NONE; 4];
            for l in 0..4 {
                if requested[l].is_none() {
                    continue;
                }
                match c.spawn(chunk, l, Some(Bounce::Specular)) {
                    Some(budget) => lent[l] = budget,
                    None => requested[l] = None,
                }
            }
            let answer = |out: &mut [f32], l: usize, s: &Sample| {
                for r in 0..3 {
                    out[4 * r + l] = s.color[r];
                }
                out[12 + l] = s.depth;
            };
            // Lanes answered from a first run's notes need no ray now.
            let mut left = requested;
            if let RayLog::Replay(replayed) = &mut c.rays_log {
                for (l, seen) in replayed.answers(&requested, &lent).into_iter().enumerate() {
                    if let Some((s, spent, cut)) = seen {
                        answer(out, l, &s);
                        left[l] = None;
                        if let Some(budget) = c.budget(chunk, l) {
                            budget.charge(spent, cut);
                        }
                    }
                }
            }
            let (lanes, rays): (Vec<usize>, Vec<Ray>) =
                left.iter().enumerate().filter_map(|(l, r)| Some((l, (*r)?))).unzip();
            if rays.is_empty() {
                return;
            }
            Stats::add(&frame.stats.secondary_rays, rays.len());
            let mut budgets: Vec<RayBudget> = lanes.iter().map(|&l| lent[l]).collect();
            let seen = (frame.stages.trace_rays)(frame, &rays, &mut budgets, c.depth + 1);
            for ((s, l), after) in seen.iter().zip(lanes).zip(budgets) {
                answer(out, l, s);
                if let Some(budget) = c.budget(chunk, l) {
                    budget.settle(lent[l], after);
                }
            }
        }
        1 => {
            // The chunk's segments go as one packet.
            let segments: [Option<(Vec3A, Vec3A, f32)>; 4] =
                std::array::from_fn(|l| (mask[l] != 0).then(|| (lane3(a, 0, l), lane3(b, 0, l), times[l])));
            let mut through = [Vec3A::ONE; 4];
            (frame.stages.transmission_between)(frame, &segments, &mut through);
            for (l, t) in through.iter().enumerate().filter(|(l, _)| mask[*l] != 0) {
                for r in 0..3 {
                    out[4 * r + l] = t[r];
                }
            }
        }
        3 if frame.world.options.gi.virtual_lights > 0 => {
            // Instant radiosity: the frame's virtual lights, this point's set of them.
            let lights = virtual_lights::of_frame(frame);
            let mut at: [Option<GatherAt>; 4] = [None; 4];
            for l in (0..4).filter(|&l| mask[l] != 0) {
                // Past the diffuse bounces the lane's path may take, no light comes back.
                if !c.may_bounce(chunk, l, Bounce::Diffuse) {
                    for r in 0..3 {
                        out[4 * r + l] = 0.0;
                    }
                    continue;
                }
                let (p, n) = (lane3(a, 0, l), lane3(b, 0, l).normalize_or_zero());
                if n != Vec3A::ZERO && p.is_finite() {
                    at[l] = Some(GatherAt { p, n, time: times[l] });
                }
            }
            // A first run notes its points (answering black), and the second takes what they
            // gathered together (`trace_ahead.rs`).
            match &mut c.rays_log {
                RayLog::Record(noted) => {
                    noted.note_gathers(at);
                    for l in (0..4).filter(|&l| at[l].is_some()) {
                        for r in 0..3 {
                            out[4 * r + l] = 0.0;
                        }
                    }
                    return;
                }
                RayLog::Replay(replayed) => {
                    for (l, light) in replayed.gathered(&at).into_iter().enumerate() {
                        let Some(light) = light else { continue };
                        for r in 0..3 {
                            out[4 * r + l] = light[r];
                        }
                        at[l] = None;
                    }
                }
                RayLog::Direct => {}
            }
            let start = frame.stats.timed.then(std::time::Instant::now);
            let mut lanes = Vec::with_capacity(4);
            let mut points = Vec::with_capacity(4);
            for (l, g) in at.iter().enumerate() {
                let Some(g) = g else { continue };
                let set = virtual_lights::set_of(lights, frame, g.p);
                points.push(virtual_lights::Gatherer { p: g.p, n: g.n, time: g.time, set });
                lanes.push(l);
            }
            if points.is_empty() {
                return;
            }
            let mut light = [Vec3A::ZERO; 4];
            virtual_lights::gather(lights, frame, &points, &mut light);
            for (k, &l) in lanes.iter().enumerate() {
                for r in 0..3 {
                    out[4 * r + l] = light[k][r];
                }
            }
            if let Some(start) = start {
                let ns = start.elapsed().as_nanos() as u64;
                frame.stats.gathering_ns.add(ns as usize);
            }
        }
        2 if !matches!(c.rays_log, RayLog::Direct) => {
            // A first run notes its points (answering unoccluded), and the second takes what
            // their rays found, traced together (`trace_ahead.rs`); lanes noted otherwise are
            // traced here.
            let at: [Option<OcclusionAt>; 4] = std::array::from_fn(|l| {
                let (p, n) = (lane3(a, 0, l), lane3(b, 0, l).normalize_or_zero());
                let count = (samples[l].max(1.0) as u32).min(256);
                (mask[l] != 0).then_some(OcclusionAt { p, n, count, time: times[l] })
            });
            let found = match &mut c.rays_log {
                RayLog::Record(noted) => {
                    noted.note_occlusions(at);
                    [Some(0.0); 4]
                }
                RayLog::Replay(replayed) => replayed.occluded(&at),
                RayLog::Direct => [None; 4],
            };
            for (l, g) in at.iter().enumerate() {
                let Some(g) = g else { continue };
                out[l] = match found[l] {
                    Some(blocked) => blocked,
                    None => hemisphere(frame, g.p, g.n, g.count, None, c.depth, g.time).0,
                };
            }
        }
        _ => {
            for l in 0..4 {
                if mask[l] == 0 {
                    continue;
                }
                if kind == 3 && !c.may_bounce(chunk, l, Bounce::Diffuse) {
                    // Past the diffuse bounces the lane's path may take, no light comes back.
                    for r in 0..3 {
                        out[4 * r + l] = 0.0;
                    }
                    continue;
                }
                let (p, n) = (lane3(a, 0, l), lane3(b, 0, l).normalize_or_zero());
                let count = (samples[l].max(1.0) as u32).min(256);
                let depth = c.depth;
                let budget = if kind == 3 { c.budget(chunk, l) } else { None };
                let (blocked, light) = hemisphere(frame, p, n, count, budget, depth, times[l]);
                if kind == 3 {
                    for r in 0..3 {
                        out[4 * r + l] = light[r];
                    }
                } else {
                    out[l] = blocked;
                }
            }
        }
    }
}

/// Cosine-weighted rays over the hemisphere around `n`: the fraction blocked, and (when `shade`
/// gives the lane's budget) the mean colour seen. Shaded, the rays cost the lane one each and
/// share what it has left; past the budget they go unshaded, as past the ray depth.
fn hemisphere(
    frame: &Frame,
    p: Vec3A,
    n: Vec3A,
    count: u32,
    shade: Option<&mut RayBudget>,
    depth: u32,
    time: f32,
) -> (f32, Vec3A) {
    if n == Vec3A::ZERO {
        return (0.0, Vec3A::ZERO);
    }
    let mut rays = Vec::with_capacity(count as usize);
    super::hemisphere::hemisphere_rays(p, n, count, time, &mut rays);
    Stats::add(&frame.stats.secondary_rays, rays.len());
    let shade = shade.filter(|_| depth < frame.world.options.max_ray_depth);
    let paid = shade.and_then(|budget| {
        if budget.take(count) {
            Some(budget)
        } else {
            Stats::add(&frame.stats.rays_cut, count as usize);
            None
        }
    });
    if let Some(budget) = paid {
        let share = budget.share(count).bounced(Bounce::Diffuse);
        let mut budgets = vec![share; rays.len()];
        let seen = (frame.stages.trace_rays)(frame, &rays, &mut budgets, depth + 1);
        for after in budgets {
            budget.settle(share, after);
        }
        let blocked = seen.iter().filter(|s| s.depth.is_finite()).count() as f32 / count as f32;
        let sum = seen.iter().fold(Vec3A::ZERO, |acc, s| acc + s.color);
        (blocked, sum / count as f32)
    } else {
        let mut blocked = Vec::new();
        tracing(|| frame.world.occluded_rays(super::RayKind::Trace, &rays, &mut blocked));
        let blocked = blocked.iter().filter(|&&b| b).count() as f32 / count as f32;
        (blocked, Vec3A::ZERO)
    }
}

unsafe extern "C" fn host_gather(
    ctx: *mut c_void,
    _category: StrRef,
    chunk: u32,
    mask: *const i32,
    from: *const f32,
    dir: *const f32,
    maxdist: *const f32,
    out: *mut f32,
) {
    // SAFETY: the table's contract: 4 mask entries, 12 floats of `from` and `dir`, 4 of `maxdist`,
    // room for 14 x 4 results.
    let (c, mask, from, dir, maxdist, out) = unsafe {
        (
            call(ctx),
            &*(mask as *const [i32; 4]),
            slice(from, 12),
            slice(dir, 12),
            slice(maxdist, 4),
            std::slice::from_raw_parts_mut(out, 4 * (1 + GatherHit::ROWS)),
        )
    };
    let frame = c.frame;
    locate_chunk(c, mask, from);
    let times: [f32; 4] = std::array::from_fn(|l| c.lane_time(l));
    // Rays past the ray depth are reported unshaded: they spawn nothing, and cost nothing.
    let shaded = c.depth < frame.world.options.max_ray_depth;
    let mut rays = Vec::with_capacity(4);
    let mut lanes = Vec::with_capacity(4);
    let mut lent = Vec::with_capacity(4);
    for l in 0..4 {
        if mask[l] == 0 {
            continue;
        }
        out[l] = 0.0;
        let (o, d) = (lane3(from, 0, l), lane3(dir, 0, l));
        if !o.is_finite() || !d.is_finite() || d == Vec3A::ZERO {
            continue;
        }
        let budget = if shaded {
            // Past the budget the ray misses.
            match c.spawn(chunk, l, None) {
                Some(budget) => budget,
                None => continue,
            }
        } else {
            RayBudget::NONE
        };
        let far = if maxdist[l] > 0.0 { maxdist[l] } else { f32::INFINITY };
        rays.push(Ray::segment(o, d, launch_epsilon(o), far).at_time(times[l]));
        lanes.push(l);
        lent.push(budget);
    }
    if rays.is_empty() {
        return;
    }
    Stats::add(&frame.stats.secondary_rays, rays.len());
    let mut budgets = lent.clone();
    let seen = (frame.stages.gather_rays)(frame, &rays, &mut budgets, c.depth + 1);
    for (((seen, l), lent), after) in seen.into_iter().zip(lanes).zip(lent).zip(budgets) {
        if shaded {
            if let Some(budget) = c.budget(chunk, l) {
                budget.settle(lent, after);
            }
        }
        let Some((t, s)) = seen else { continue };
        out[l] = 1.0;
        let rows = [t, s.ci.x, s.ci.y, s.ci.z, s.oi.x, s.oi.y, s.oi.z, s.p.x, s.p.y, s.p.z, s.ng.x, s.ng.y, s.ng.z];
        for (j, x) in rows.into_iter().enumerate() {
            out[4 * (j + 1) + l] = x;
        }
    }
}

unsafe extern "C" fn host_depth(ctx: *mut c_void, mask: *const i32, p: *const f32, out: *mut f32) {
    // SAFETY: the table's contract.
    let (c, mask, p, out) =
        unsafe { (call(ctx), &*(mask as *const [i32; 4]), slice(p, 12), std::slice::from_raw_parts_mut(out, 4)) };
    let cam = &c.frame.world.camera;
    for l in 0..4 {
        if mask[l] != 0 {
            let z = c.frame.camera_from_world.transform_point3a(lane3(p, 0, l)).z;
            out[l] = ((z - cam.near) / (cam.far - cam.near)).clamp(0.0, 1.0);
        }
    }
}

unsafe extern "C" fn host_ray_depth(ctx: *mut c_void) -> f32 {
    // SAFETY: the table's contract.
    unsafe { call(ctx) }.depth as f32
}

unsafe extern "C" fn host_message(
    ctx: *mut c_void,
    which: u32,
    chunk: u32,
    lane: u32,
    name: StrRef,
    out: *mut MessageOut,
) -> u32 {
    // SAFETY: the table's contract.
    let (c, name, out) = unsafe { (call(ctx), name.as_str(), &mut *out) };
    let Some(b) = Builtin::ALL.get(which as usize) else { return 0 };
    let options = &c.frame.world.options;
    let floats = |out: &mut MessageOut, v: &[f32]| {
        out.kind = 1;
        out.len = if v.len() == 1 { 0 } else { v.len() as u32 };
        out.floats[..v.len()].copy_from_slice(v);
        1
    };
    match (b, name) {
        (Builtin::Option, "Format") => floats(out, &[options.width as f32, options.height as f32, 1.0]),
        (Builtin::Option, "PixelSamples") => {
            let (sx, sy) = options.pixel_samples();
            floats(out, &[sx as f32, sy as f32])
        }
        (Builtin::Option, "FieldOfView") => floats(out, &[c.frame.world.camera.fov_degrees]),
        (Builtin::Option, "Clipping") => floats(out, &[c.frame.world.camera.near, c.frame.world.camera.far]),
        (Builtin::Option, "Shutter") => floats(out, &[options.shutter.0, options.shutter.1]),
        (Builtin::Option, "DepthOfField") => match options.depth_of_field {
            Some(dof) => floats(out, &dof),
            None => 0,
        },
        // RenderMan's user data: `Option "user"` (the frame's value of the ray parameter of that
        // name) and `Attribute "user"` (the shaded object's own value).
        (Builtin::Option, _) if name.starts_with("user:") => {
            match options.ray_parameters.get(name).map(|p| p.value.clone()) {
                Some(value) => value_message(value, out, &mut c.text),
                None => 0,
            }
        }
        (Builtin::Attribute, _) => {
            let material = c.material.and_then(|m| c.frame.world.materials.get(m as usize));
            let Some(material) = material else { return 0 };
            match name {
                // PRMan prefers the `Ri:` names.
                "Sides" | "Ri:Sides" => floats(out, &[if material.one_sided { 1.0 } else { 2.0 }]),
                "Matte" | "Ri:Matte" => floats(out, &[if material.matte { 1.0 } else { 0.0 }]),
                "Ri:Color" => value_message(RayValue::Color(material.color), out, &mut c.text),
                "Ri:Opacity" => value_message(RayValue::Color(material.opacity), out, &mut c.text),
                "trace:bias" => floats(out, &[material.trace_bias]),
                "trace:maxdiffusedepth" | "trace:maxspeculardepth" => {
                    let d = material.trace_depths;
                    let bounces = if name == "trace:maxdiffusedepth" { d.diffuse } else { d.specular };
                    // Unbounded reads as the largest integer a float holds exactly.
                    floats(out, &[bounces.min(1 << 24) as f32])
                }
                "identifier:name" => match &material.identifier {
                    Some(name) => value_message(RayValue::String(name.to_string()), out, &mut c.text),
                    None => 0,
                },
                _ if name.starts_with("user:") => match object_value(&material.ray_values, name) {
                    Some(value) => value_message(value.clone(), out, &mut c.text),
                    None => 0,
                },
                _ => 0,
            }
        }
        (Builtin::Rendererinfo, "renderer") => {
            c.text = "rtsl".to_string();
            out.kind = 4;
            out.len = 0;
            out.string = StrRef::new(&c.text);
            1
        }
        (Builtin::Rendererinfo, "version") => floats(out, &[0.0, 1.0, 0.0, 0.0]),
        (Builtin::Rayinfo, "depth") => floats(out, &[c.depth as f32]),
        (Builtin::Rayinfo, "diffusedepth" | "speculardepth") => {
            let bounces = c.budget(chunk, lane as usize).map(|b| b.bounces);
            let taken = bounces.map_or(0, |b| if name == "diffusedepth" { b.diffuse } else { b.specular });
            floats(out, &[taken as f32])
        }
        (Builtin::Rayinfo, _) => ray_parameter(c, chunk, lane, name, out),
        // Message passing: the parameters of the shaders bound with the one running, as bound
        // (or their constant defaults). Outputs a shader computes are not seen.
        (Builtin::Surface | Builtin::Displacement, _) => {
            let world = c.frame.world;
            let material = c.material.and_then(|m| world.materials.get(m as usize));
            let shader = match b {
                Builtin::Surface => material.and_then(|m| m.surface.as_deref()),
                _ => material.and_then(|m| m.displacement.as_deref()),
            };
            shader.map_or(0, |s| param_message(s, name, out, &mut c.text))
        }
        (Builtin::Atmosphere, _) => {
            c.frame.world.atmosphere.as_deref().map_or(0, |s| param_message(s, name, out, &mut c.text))
        }
        (Builtin::Rendererinfo, "versionstring") => {
            c.text = env!("CARGO_PKG_VERSION").to_string();
            out.kind = 4;
            out.len = 0;
            out.string = StrRef::new(&c.text);
            1
        }
        _ => 0,
    }
}

/// `rayinfo(name)` of lane `lane` of chunk `chunk`: the ray parameter as its ray reads it
/// (`ray_params.rs` says in which order the sources are asked). 0 when nothing sets it (noted for
/// the frame's report), except [`RELEVANCE`], which reads 1.
fn ray_parameter(c: &mut ShadeCall, chunk: u32, lane: u32, name: &str, out: &mut MessageOut) -> u32 {
    let world = c.frame.world;
    let origin = c.budget(chunk, lane as usize).map_or(RayOrigin::NONE, |b| b.origin);
    match ray_value(c.frame, origin, name) {
        Some(value) => value_message(value, out, &mut c.text),
        None if strip_user(name) == RELEVANCE => {
            out.kind = 1;
            out.len = 0;
            out.floats[0] = 1.0;
            1
        }
        None => {
            world.ray_parameter_misses.note(strip_user(name));
            0
        }
    }
}

/// `value` as a message answer (1).
fn value_message(value: RayValue, out: &mut MessageOut, text: &mut String) -> u32 {
    out.len = 0;
    match value {
        RayValue::Float(x) => {
            out.kind = 1;
            out.floats[0] = x;
        }
        RayValue::Color(v) | RayValue::Point(v) => {
            out.kind = 2;
            out.floats[..3].copy_from_slice(&v);
        }
        RayValue::String(s) => {
            *text = s;
            out.kind = 4;
            out.string = StrRef::new(text);
        }
    }
    1
}

/// Ray parameter `name` of a ray from `origin` (`ray_params.rs` gives the order of lookup), `None`
/// where nothing sets it (`relevance` included).
pub(super) fn ray_value(frame: &Frame, origin: RayOrigin, name: &str) -> Option<RayValue> {
    let world = frame.world;
    let options = &world.options;
    if let Some(v) = world.materials.get(origin.material as usize).and_then(|m| object_value(&m.ray_values, name)) {
        return Some(v.clone());
    }
    let (w, h) = (options.width.max(1), options.height.max(1));
    let pixel = (origin.pixel != RayOrigin::NO_PIXEL).then(|| (origin.pixel % w, origin.pixel / w));
    options.ray_parameters.value_at(name, pixel, (w, h))
}

/// The relevance of a ray from `origin`, in [0, 1] (1 where nothing sets it).
pub(super) fn ray_relevance(frame: &Frame, origin: RayOrigin) -> f32 {
    super::ray_params::relevance(ray_value(frame, origin, RELEVANCE).as_ref())
}

/// Parameter `name` of `shader` (bound, or its constant default) as a message answer: 1 when found.
fn param_message(shader: &ShaderInstance, name: &str, out: &mut MessageOut, text: &mut String) -> u32 {
    use rtsl_compiler::interface::Value;
    let Some((index, _)) = shader.program.layout().param(name) else { return 0 };
    let Some(info) = shader.program.interface.parameters.get(index) else { return 0 };
    let kind = match info.base {
        rtsl_compiler::interface::BaseType::Float => 1,
        rtsl_compiler::interface::BaseType::Matrix => 3,
        rtsl_compiler::interface::BaseType::String => 4,
        b if b.is_triple() => 2,
        _ => return 0,
    };
    let bound = shader.params.iter().find(|p| p.index == index);
    if kind == 4 {
        let s = match (bound, &info.default) {
            (Some(b), _) => b.string.clone(),
            (None, Some(Value::String(s))) => Some(s.clone()),
            _ => None,
        };
        let Some(s) = s.filter(|_| info.array_length.is_none()) else { return 0 };
        *text = s;
        out.kind = 4;
        out.len = 0;
        out.string = StrRef::new(text);
        return 1;
    }
    // Constant defaults in the current space only (a default in a named space needs its matrix).
    fn flatten(v: &Value, into: &mut Vec<f32>) -> bool {
        match v {
            Value::Float(x) => into.push(*x),
            Value::Triple(t) if t.space.is_none() => into.extend(t.value),
            Value::Matrix(m) if m.space.is_none() => into.extend(m.value),
            Value::Array(items) => return items.iter().all(|x| flatten(x, into)),
            _ => return false,
        }
        true
    }
    let mut floats = Vec::new();
    match (bound, &info.default) {
        (Some(b), _) => floats.extend_from_slice(&b.floats),
        (None, Some(v)) if flatten(v, &mut floats) => {}
        _ => return 0,
    }
    let per = match kind {
        1 => 1,
        2 => 3,
        _ => 16,
    };
    let len = info.array_length.unwrap_or(0);
    if floats.len() != per * len.max(1) as usize || floats.len() > out.floats.len() {
        return 0;
    }
    out.kind = kind;
    out.len = len;
    out.floats[..floats.len()].copy_from_slice(&floats);
    1
}

unsafe extern "C" fn host_light_message(ctx: *mut c_void, light: u32, name: StrRef, out: *mut MessageOut) -> u32 {
    // SAFETY: the table's contract.
    let (c, name, out) = unsafe { (call(ctx), name.as_str(), &mut *out) };
    let Some(light) = c.frame.world.lights.get(light as usize) else { return 0 };
    param_message(&light.shader, name, out, &mut c.text)
}

/// `incident()`/`opposite()`: the surface's interior shader inside, the atmosphere outside (an
/// `Exterior` shader is not rendered, so the atmosphere is what fills the space around objects).
unsafe extern "C" fn host_volume_message(ctx: *mut c_void, interior: u32, name: StrRef, out: *mut MessageOut) -> u32 {
    // SAFETY: the table's contract.
    let (c, name, out) = unsafe { (call(ctx), name.as_str(), &mut *out) };
    let world = c.frame.world;
    let shader = if interior != 0 {
        c.material.and_then(|m| world.materials.get(m as usize)).and_then(|m| m.interior.as_deref())
    } else {
        world.atmosphere.as_deref()
    };
    shader.map_or(0, |s| param_message(s, name, out, &mut c.text))
}

unsafe extern "C" fn host_shader_name(ctx: *mut c_void, has_kind: u32, _kind: StrRef) -> StrRef {
    // SAFETY: the table's contract.
    let c = unsafe { call(ctx) };
    c.text = if has_kind == 0 { c.instance.program.name.clone() } else { String::new() };
    StrRef::new(&c.text)
}

unsafe extern "C" fn host_print(ctx: *mut c_void, text: StrRef) {
    use std::io::Write;
    // SAFETY: the table's contract.
    let (c, text) = unsafe { (call(ctx), text.as_str()) };
    if let RayLog::Record(noted) = &mut c.rays_log {
        // A first run (`trace_ahead.rs`): the second one prints.
        noted.silenced = true;
        return;
    }
    // A unit rendered asking ahead prints only if it is kept (`accel/ask_ahead.rs`).
    if crate::accel::ask_ahead::hold_output(text) {
        return;
    }
    let _ = std::io::stdout().lock().write_all(text.as_bytes());
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::texture::{TexImage, Wrap};

    /// The four-lane first channels are the lane-by-lane conversion wherever a lookup can tell:
    /// the same below 2^24, and at least 2^24 (past any texture's channels) above it.
    #[test]
    fn first_channels_convert_as_lane_by_lane() {
        let values = [0.0f32, -0.0, 0.5, 1.0, 2.999, 3.0, 63.0, -1.0, -1e30, f32::NAN, f32::NEG_INFINITY, 16_777_215.0];
        let large = [16_777_216.0f32, 1e30, f32::INFINITY];
        for w in values.windows(4).chain(large.windows(1)) {
            let first: [f32; 4] = std::array::from_fn(|l| w[l % w.len()]);
            let got = first_channels(&first);
            for l in 0..4 {
                let want = first[l].max(0.0) as usize;
                if want < 1 << 24 {
                    assert_eq!(got[l], want, "{first:?}");
                } else {
                    assert_eq!(got[l], 1 << 24, "{first:?}");
                }
            }
        }
        assert_eq!(first_channels(&[1.0]), [0; 4]);
    }

    fn value(handles: &mut TextureHandles, cache: &TextureCache, name: &str) -> Option<f32> {
        handles.get(cache, name, false).map(|m| m.level(0).data()[0])
    }

    /// Handles kept from call to call give what the cache gives, and follow it when a name comes
    /// to stand for another texture, or the handles are used with another cache.
    #[test]
    fn texture_handles_follow_the_cache() {
        let image = |v: f32| TexImage::new(1, 1, 1, vec![v]).unwrap();
        let cache = TextureCache::new();
        cache.insert_texture("a", image(0.25), [Wrap::Clamp; 2]);
        cache.insert_texture("b", image(0.5), [Wrap::Clamp; 2]);
        let mut handles = TextureHandles::default();
        assert_eq!(value(&mut handles, &cache, "a"), Some(0.25));
        assert_eq!(value(&mut handles, &cache, "b"), Some(0.5));
        assert_eq!(value(&mut handles, &cache, "a"), Some(0.25));
        assert_eq!(value(&mut handles, &cache, "missing.tex"), None);
        assert_eq!(value(&mut handles, &cache, "b"), Some(0.5));
        cache.insert_texture("a", image(0.75), [Wrap::Clamp; 2]);
        assert_eq!(value(&mut handles, &cache, "a"), Some(0.75));
        assert_eq!(value(&mut handles, &cache, "b"), Some(0.5));
        let other = TextureCache::new();
        other.insert_texture("b", image(1.0), [Wrap::Clamp; 2]);
        assert_eq!(value(&mut handles, &other, "b"), Some(1.0));
        assert_eq!(value(&mut handles, &cache, "b"), Some(0.5));
        cache.clear();
        assert_eq!(value(&mut handles, &cache, "b"), None, "no file is called b");
    }
}
