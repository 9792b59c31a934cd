//! Shading on hits: hits are grouped by (material, instance) into batches, the globals are filled
//! from the hits, the surface shader's packet code runs, and its calls into the renderer (lights and
//! shadows, `trace`, `transmission`, spaces, messages) are answered by the [`HostTable`] made here.
//!
//! Invariants:
//! - A ray's colour is composited front to back: `C += w * Ci`, `w *= 1 - Oi` (RenderMan's `Ci` is
//!   premultiplied by `Oi`), continuing through surfaces while `w` is above 1/256 and fewer than
//!   `max_transparent_layers` were crossed; what is left of `w` sees the background.
//! - `trace` recursion stops at `RenderOptions::max_ray_depth`: deeper rays return black (RISpec).
//! - Everything here is deterministic per ray: random numbers (area light samples, occlusion rays,
//!   `random()` seeds) are hashes of the shading point, never of the thread or the order of work.
//! - Host callbacks never unwind into JIT code: they only index buffers whose sizes the packet ABI
//!   fixes and catch nothing because nothing in them panics on user data.

use super::differential::{barycentric_change, RayDifferential};
use super::native::{LightSeen, NativeSurface};
use super::world::{InstanceShading, LightSource, World, DEFAULT_MATERIAL};
use crate::ray::{offset_ray_origin, Hit, HitPacket, Ray, RayPacket, PACKET_SIZE};
use crate::shading::{get3, put1, put3, with_batch, LightKind, ShaderInstance, Slot};
use crate::texture::{Footprint, LookupOptions};
use glam::{Affine3A, Mat4, Vec3A};
use rtsl_compiler::back::jit::RawBatch;
use rtsl_compiler::back::jit::{HostLight, HostTable, MessageOut, StrRef, MAX_LIGHTS};
use rtsl_compiler::builtins::Builtin;
use std::ffi::c_void;
use std::sync::atomic::{AtomicU64, Ordering};

/// Counters of one frame, summed over threads.
#[derive(Debug, Default)]
pub struct Stats {
    pub primary_rays: AtomicU64,
    pub shadow_rays: AtomicU64,
    pub secondary_rays: AtomicU64,
    pub transparency_rays: AtomicU64,
    pub shaded_points: AtomicU64,
    pub light_evaluations: AtomicU64,
    /// Time spent shading (surface and light shaders and the renderer's side of their calls),
    /// tracing excluded, summed over threads.
    pub shading_ns: AtomicU64,
}

thread_local! {
    /// Nanoseconds this thread spent in tracer calls made while shading, and how deeply shading
    /// is nested on this thread (trace() shades recursively; only the outermost level is timed).
    static TRACE_NS: std::cell::Cell<u64> = const { std::cell::Cell::new(0) };
    static SHADE_NESTING: std::cell::Cell<u32> = const { std::cell::Cell::new(0) };
}

/// Runs a tracer query, counting its time as tracing rather than shading.
fn tracing<R>(f: impl FnOnce() -> R) -> R {
    let start = std::time::Instant::now();
    let r = f();
    let ns = start.elapsed().as_nanos() as u64;
    TRACE_NS.with(|t| t.set(t.get() + ns));
    r
}

/// Times the outermost shading on this thread, tracing excluded.
struct ShadingTimer<'a> {
    stats: &'a Stats,
    start: Option<(std::time::Instant, u64)>,
}

impl<'a> ShadingTimer<'a> {
    fn start(stats: &'a Stats) -> ShadingTimer<'a> {
        let outer = SHADE_NESTING.with(|n| {
            n.set(n.get() + 1);
            n.get() == 1
        });
        let start = outer.then(|| (std::time::Instant::now(), TRACE_NS.with(|t| t.get())));
        ShadingTimer { stats, start }
    }
}

impl Drop for ShadingTimer<'_> {
    fn drop(&mut self) {
        SHADE_NESTING.with(|n| n.set(n.get().saturating_sub(1)));
        if let Some((start, traced_before)) = self.start {
            let traced = TRACE_NS.with(|t| t.get()) - traced_before;
            let ns = (start.elapsed().as_nanos() as u64).saturating_sub(traced);
            self.stats.shading_ns.fetch_add(ns, Ordering::Relaxed);
        }
    }
}

impl Stats {
    fn add(counter: &AtomicU64, n: usize) {
        counter.fetch_add(n as u64, Ordering::Relaxed);
    }

    pub fn total_rays(&self) -> u64 {
        self.primary_rays.load(Ordering::Relaxed)
            + self.shadow_rays.load(Ordering::Relaxed)
            + self.secondary_rays.load(Ordering::Relaxed)
            + self.transparency_rays.load(Ordering::Relaxed)
    }
}

/// The frame being rendered: the world and the counters.
pub struct Frame<'w> {
    pub world: &'w World,
    pub stats: Stats,
    transparent_shadows: bool,
    camera_from_world: Affine3A,
    /// The camera's forward axis and how an unnormalised camera ray's direction changes per pixel.
    forward: Vec3A,
    pixel_dx: Vec3A,
    pixel_dy: Vec3A,
    /// The angle one pixel spans (radians, small-angle), for the cones of secondary rays.
    pixel_spread: f32,
}

impl<'w> Frame<'w> {
    pub fn new(world: &'w World) -> Frame<'w> {
        let cam = &world.camera;
        let (w, h) = (world.options.width.max(1) as f32, world.options.height.max(1) as f32);
        let tan = (cam.fov_degrees.to_radians() * 0.5).tan();
        let (ax, ay) = if w >= h { (w / h, 1.0) } else { (1.0, h / w) };
        let m = &cam.world_from_camera.matrix3;
        Frame {
            world,
            stats: Stats::default(),
            transparent_shadows: world.has_transparent_shadows(),
            camera_from_world: cam.world_from_camera.inverse(),
            forward: m.z_axis.normalize_or_zero(),
            pixel_dx: m.x_axis * (2.0 * tan * ax / w),
            pixel_dy: m.y_axis * (-2.0 * tan * ay / h),
            pixel_spread: 2.0 * tan * ay / h,
        }
    }
}

/// The colour seen along a ray and its coverage.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Sample {
    pub color: Vec3A,
    pub alpha: f32,
    /// Distance to the first surface (infinite on a miss).
    pub depth: f32,
    /// Object id of the first surface hit (`u32::MAX` on a miss), for pixel shaders and adaptive
    /// sampling.
    pub object_id: u32,
    /// Material (shader instance) of the first surface hit (`u32::MAX` on a miss).
    pub shader_id: u32,
}

/// Shades the rays of a primary packet (already intersected).
pub fn shade_packet(frame: &Frame, packet: &RayPacket, hits: &HitPacket, out: &mut [Sample; PACKET_SIZE]) {
    let mut rays = Vec::with_capacity(PACKET_SIZE);
    let mut hs = Vec::with_capacity(PACKET_SIZE);
    let mut lanes = Vec::with_capacity(PACKET_SIZE);
    for i in 0..PACKET_SIZE {
        if packet.active >> i & 1 != 0 {
            rays.push(packet.get(i));
            hs.push(hits.get(i));
            lanes.push(i);
        }
    }
    Stats::add(&frame.stats.primary_rays, rays.len());
    let diffs: Vec<RayDifferential> = rays
        .iter()
        .map(|r| {
            // The unnormalised camera direction has a forward component of 1.
            let along = r.direction.dot(frame.forward);
            let d = if along > 1e-6 { r.direction / along } else { r.direction };
            RayDifferential::from_camera(d, frame.pixel_dx, frame.pixel_dy)
        })
        .collect();
    let mut samples = vec![Sample::default(); rays.len()];
    shade_hits(frame, &rays, &diffs, &hs, 0, &mut samples);
    for (k, i) in lanes.into_iter().enumerate() {
        out[i] = samples[k];
    }
}

/// Traces and shades single rays (secondary rays: incoherent, traced one by one).
pub fn trace_rays(frame: &Frame, rays: &[Ray], depth: u32) -> Vec<Sample> {
    let hits: Vec<Hit> = tracing(|| rays.iter().map(|r| frame.world.scene.intersect(r)).collect());
    let eye = frame.world.camera.eye();
    let diffs: Vec<RayDifferential> = rays
        .iter()
        .map(|r| {
            let width = frame.pixel_spread * (r.origin - eye).length();
            RayDifferential::cone(r.direction, width, frame.pixel_spread)
        })
        .collect();
    let mut out = vec![Sample::default(); rays.len()];
    shade_hits(frame, rays, &diffs, &hits, depth, &mut out);
    out
}

struct Pending {
    index: usize,
    ray: Ray,
    diff: RayDifferential,
    hit: Hit,
}

/// What shading one hit produced.
#[derive(Clone, Copy, Debug, Default)]
struct Shaded {
    ci: Vec3A,
    oi: Vec3A,
    p: Vec3A,
    ng: Vec3A,
    /// The footprint of the hit: dP/dx, dP/dy.
    dpdx: Vec3A,
    dpdy: Vec3A,
}

fn shade_hits(frame: &Frame, rays: &[Ray], diffs: &[RayDifferential], hits: &[Hit], depth: u32, out: &mut [Sample]) {
    let world = frame.world;
    let background = Vec3A::from(world.options.background);
    let mut weight = vec![Vec3A::ONE; rays.len()];
    let mut current = Vec::with_capacity(rays.len());
    for (i, ((ray, hit), diff)) in rays.iter().zip(hits).zip(diffs).enumerate() {
        out[i] = Sample { color: Vec3A::ZERO, alpha: 0.0, depth: hit.t, object_id: u32::MAX, shader_id: u32::MAX };
        if hit.is_hit() {
            if let Some(inst) = world.instances.get(hit.instance as usize) {
                out[i].object_id = world.materials.get(inst.material as usize).map_or(0, |m| m.object_id);
                out[i].shader_id = inst.material;
            }
            current.push(Pending { index: i, ray: *ray, diff: *diff, hit: *hit });
        } else {
            out[i].color = background;
        }
    }
    let mut layer = 0;
    while !current.is_empty() {
        let key = |p: &Pending| {
            let inst = world.instances.get(p.hit.instance as usize);
            (inst.map_or(0, |i| i.material), p.hit.instance)
        };
        current.sort_by_key(key);
        let mut results = vec![Shaded::default(); current.len()];
        let mut start = 0;
        while start < current.len() {
            let k = key(&current[start]);
            let mut end = start + 1;
            while end < current.len() && end - start < PACKET_SIZE && key(&current[end]) == k {
                end += 1;
            }
            shade_group(frame, &current[start..end], depth, &mut results[start..end]);
            start = end;
        }
        Stats::add(&frame.stats.shaded_points, current.len());
        layer += 1;
        let mut next = Vec::new();
        for (p, r) in current.iter().zip(&results) {
            let w = weight[p.index];
            out[p.index].color += w * r.ci;
            let left = w * (Vec3A::ONE - r.oi.clamp(Vec3A::ZERO, Vec3A::ONE));
            weight[p.index] = left;
            if left.max_element() > 1.0 / 256.0 {
                if layer >= world.options.max_transparent_layers {
                    continue;
                }
                let side = if r.ng.dot(p.ray.direction) > 0.0 { r.ng } else { -r.ng };
                let ray = Ray::new(offset_ray_origin(r.p, side), p.ray.direction);
                Stats::add(&frame.stats.transparency_rays, 1);
                let hit = tracing(|| world.scene.intersect(&ray));
                if hit.is_hit() {
                    // The ray goes on unbent: its footprint starts where the surface's ended.
                    let diff = RayDifferential { dodx: r.dpdx, dody: r.dpdy, ..p.diff };
                    next.push(Pending { index: p.index, ray, diff, hit });
                } else {
                    out[p.index].color += left * background;
                }
            }
        }
        current = next;
    }
    for (s, w) in out.iter_mut().zip(&weight) {
        s.alpha = 1.0 - (w.x + w.y + w.z) / 3.0;
    }
}

/// Surface details of one hit, in world space.
struct HitGeometry {
    p: Vec3A,
    n: Vec3A,
    ng: Vec3A,
    uv: [f32; 2],
    st: [f32; 2],
    dpdu: Vec3A,
    dpdv: Vec3A,
    cs: Option<Vec3A>,
    os: Option<Vec3A>,
    attributes: Vec<Vec<f32>>,
    /// The triangle's world-space edges from its first corner, and how (u, v), (s, t) and the
    /// (unnormalised) shading normal change along them: what turns dP/dx into every derivative.
    edges: [Vec3A; 2],
    duv: [[f32; 2]; 2],
    dst: [[f32; 2]; 2],
    dn: [Vec3A; 2],
}

/// The screen-space derivatives of one hit's globals.
struct HitDerivs {
    dp: [Vec3A; 2],
    dn: [Vec3A; 2],
    du: [f32; 2],
    dv: [f32; 2],
    ds: [f32; 2],
    dt: [f32; 2],
}

impl HitGeometry {
    fn derivs(&self, p: &Pending) -> HitDerivs {
        let (dpx, dpy) = p.diff.at_hit(p.ray.direction, p.hit.t, self.ng);
        let bx = barycentric_change(self.edges[0], self.edges[1], dpx);
        let by = barycentric_change(self.edges[0], self.edges[1], dpy);
        let lin = |d: &[[f32; 2]; 2], k: usize, b: (f32, f32)| d[0][k] * b.0 + d[1][k] * b.1;
        HitDerivs {
            dp: [dpx, dpy],
            dn: [self.dn[0] * bx.0 + self.dn[1] * bx.1, self.dn[0] * by.0 + self.dn[1] * by.1],
            du: [lin(&self.duv, 0, bx), lin(&self.duv, 0, by)],
            dv: [lin(&self.duv, 1, bx), lin(&self.duv, 1, by)],
            ds: [lin(&self.dst, 0, bx), lin(&self.dst, 0, by)],
            dt: [lin(&self.dst, 1, bx), lin(&self.dst, 1, by)],
        }
    }
}

/// What every hit on one instance shares: its mesh and transforms.
struct InstanceGeometry<'a> {
    mesh: &'a crate::geometry::Mesh,
    world_from_object: glam::Affine3A,
    normal_xf: glam::Mat3A,
}

impl<'a> InstanceGeometry<'a> {
    fn new(world: &'a World, inst: &InstanceShading) -> Option<InstanceGeometry<'a>> {
        let mesh = world.scene.mesh(crate::scene::ObjectId(inst.object))?;
        let normal_xf = inst.world_from_object.matrix3.inverse().transpose();
        Some(InstanceGeometry { mesh, world_from_object: inst.world_from_object, normal_xf })
    }
}

fn hit_geometry(ig: &InstanceGeometry, hit: &Hit) -> Option<HitGeometry> {
    let mesh = ig.mesh;
    let [a, b, c] = (*mesh.triangles.get(hit.primitive as usize)?).map(|i| i as usize);
    let (pa, pb, pc) = (*mesh.positions.get(a)?, *mesh.positions.get(b)?, *mesh.positions.get(c)?);
    let xf = &ig.world_from_object;
    let normal_xf = ig.normal_xf;
    let (e1, e2) = (Vec3A::from(pb - pa), Vec3A::from(pc - pa));
    let (w0, w1, w2) = (1.0 - hit.u - hit.v, hit.u, hit.v);
    let p_obj = Vec3A::from(pa) * w0 + Vec3A::from(pb) * w1 + Vec3A::from(pc) * w2;
    let ng = (normal_xf * e1.cross(e2)).normalize_or_zero();
    let n = match &mesh.normals {
        Some(ns) => {
            let ni = Vec3A::from(ns[a] * w0 + ns[b] * w1 + ns[c] * w2);
            let n = (normal_xf * ni).normalize_or_zero();
            if n == Vec3A::ZERO {
                ng
            } else {
                n
            }
        }
        None => ng,
    };
    let attributes: Vec<Vec<f32>> = mesh
        .attributes
        .iter()
        .map(|at| {
            let k = at.components;
            (0..k).map(|j| at.data[a * k + j] * w0 + at.data[b * k + j] * w1 + at.data[c * k + j] * w2).collect()
        })
        .collect();
    let surf_p = xf.transform_point3a(p_obj);
    let mut duv = [[1.0, 0.0], [0.0, 1.0]];
    let (uv, dpdu, dpdv) = match &mesh.uvs {
        Some(uvs) => {
            let (ta, tb, tc) = (uvs[a], uvs[b], uvs[c]);
            duv = [(tb - ta).to_array(), (tc - ta).to_array()];
            let (d1, d2) = (tb - ta, tc - ta);
            let det = d1.x * d2.y - d1.y * d2.x;
            let (dpdu, dpdv) = if det.abs() > 1e-12 {
                let inv = 1.0 / det;
                ((e1 * d2.y - e2 * d1.y) * inv, (e2 * d1.x - e1 * d2.x) * inv)
            } else {
                (e1, e2)
            };
            let w = (1.0 - hit.u - hit.v, hit.u, hit.v);
            let uv = ta * w.0 + tb * w.1 + tc * w.2;
            ([uv.x, uv.y], dpdu, dpdv)
        }
        None => ([hit.u, hit.v], e1, e2),
    };
    let find = |name: &str| mesh.attributes.iter().position(|at| at.name == name);
    let color_attr = |name: &str| {
        let i = find(name)?;
        let v = attributes.get(i)?;
        (v.len() == 3).then(|| Vec3A::new(v[0], v[1], v[2]))
    };
    let (st, dst) = match find("st") {
        Some(i) if attributes[i].len() == 2 => {
            let d = &mesh.attributes[i].data;
            let delta = |k: usize, j: usize| d[2 * k + j] - d[2 * a + j];
            ([attributes[i][0], attributes[i][1]], [[delta(b, 0), delta(b, 1)], [delta(c, 0), delta(c, 1)]])
        }
        _ => (uv, duv),
    };
    let dn = match &mesh.normals {
        Some(ns) => [normal_xf * Vec3A::from(ns[b] - ns[a]), normal_xf * Vec3A::from(ns[c] - ns[a])],
        None => [Vec3A::ZERO; 2],
    };
    Some(HitGeometry {
        p: surf_p,
        n,
        ng,
        uv,
        st,
        dpdu: xf.transform_vector3a(dpdu),
        dpdv: xf.transform_vector3a(dpdv),
        cs: color_attr("Cs"),
        os: color_attr("Os"),
        attributes,
        edges: [xf.transform_vector3a(e1), xf.transform_vector3a(e2)],
        duv,
        dst,
        dn,
    })
}

/// A cheap well-mixed hash for deterministic sampling (SplitMix64's finaliser).
pub(crate) fn mix(mut x: u64) -> u64 {
    x = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    x = (x ^ (x >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    x ^ (x >> 31)
}

fn point_seed(p: Vec3A) -> u64 {
    mix(u64::from(p.x.to_bits()) ^ mix(u64::from(p.y.to_bits()) ^ mix(u64::from(p.z.to_bits()))))
}

fn unit(h: u64) -> f32 {
    (h >> 40) as f32 / (1u64 << 24) as f32
}

/// Shades hits that share material and instance.
fn shade_group(frame: &Frame, group: &[Pending], depth: u32, out: &mut [Shaded]) {
    let _timer = ShadingTimer::start(&frame.stats);
    let world = frame.world;
    let Some(inst) = world.instances.get(group[0].hit.instance as usize) else { return };
    let material = world.materials.get(inst.material as usize).unwrap_or(&DEFAULT_MATERIAL);
    let Some(ig) = InstanceGeometry::new(world, inst) else { return };
    let geoms: Vec<Option<HitGeometry>> = group.iter().map(|p| hit_geometry(&ig, &p.hit)).collect();
    let color = Vec3A::from(material.color);
    let opacity = Vec3A::from(material.opacity);
    if let Some(native) = &material.native {
        shade_native(frame, native, group, &geoms, color, opacity, depth, out);
        return;
    }
    let Some(surface) = &material.surface else {
        // RenderMan's default surface: a matte that faces the viewer.
        for ((p, g), o) in group.iter().zip(&geoms).zip(out.iter_mut()) {
            let Some(g) = g else { continue };
            let cs = g.cs.unwrap_or(color);
            let os = g.os.unwrap_or(opacity);
            let facing = g.n.dot(-p.ray.direction.normalize_or_zero()).abs();
            let (dpdx, dpdy) = p.diff.at_hit(p.ray.direction, p.hit.t, g.ng);
            *o = Shaded { ci: os * cs * (0.2 + 0.8 * facing), oi: os, p: g.p, ng: g.ng, dpdx, dpdy };
        }
        return;
    };
    let program = &surface.program;
    let slots = &program.slots;
    let vertex_params = world.vertex_params.get(group[0].hit.instance as usize);
    let deriv_slots = program.layout().deriv_slots;
    let needs_derivs = deriv_slots > 0 || slots.du.is_some() || slots.dv.is_some();
    let mut footprints = vec![[Vec3A::ZERO; 2]; group.len()];
    with_batch(program, group.len(), |batch| {
        {
            let mut raw = batch.raw_mut();
            surface.write_params(&mut raw);
            for (lane, (p, g)) in group.iter().zip(&geoms).enumerate() {
                let Some(g) = g else {
                    raw.mask[lane] = 0;
                    continue;
                };
                let e = p.ray.origin;
                put3(&mut raw, slots.p, lane, g.p);
                put3(&mut raw, slots.n, lane, g.n);
                put3(&mut raw, slots.ng, lane, g.ng);
                put3(&mut raw, slots.i, lane, g.p - e);
                put3(&mut raw, slots.e, lane, e);
                put1(&mut raw, slots.u, lane, g.uv[0]);
                put1(&mut raw, slots.v, lane, g.uv[1]);
                put1(&mut raw, slots.s, lane, g.st[0]);
                put1(&mut raw, slots.t, lane, g.st[1]);
                put3(&mut raw, slots.dpdu, lane, g.dpdu);
                put3(&mut raw, slots.dpdv, lane, g.dpdv);
                let os = g.os.unwrap_or(opacity);
                put3(&mut raw, slots.cs, lane, g.cs.unwrap_or(color));
                put3(&mut raw, slots.os, lane, os);
                put3(&mut raw, slots.oi, lane, os);
                put1(&mut raw, slots.ncomps, lane, 3.0);
                // The full set of derivatives only for shaders that use them (they cost a few
                // solves per hit); the footprint, for rays continuing through, always.
                if needs_derivs {
                    let d = g.derivs(p);
                    put1(&mut raw, slots.du, lane, d.du[0].abs().max(d.du[1].abs()));
                    put1(&mut raw, slots.dv, lane, d.dv[0].abs().max(d.dv[1].abs()));
                    if deriv_slots > 0 {
                        put_d3(&mut raw, slots.p, deriv_slots, lane, d.dp);
                        put_d3(&mut raw, slots.i, deriv_slots, lane, d.dp);
                        put_d3(&mut raw, slots.n, deriv_slots, lane, d.dn);
                        put_d1(&mut raw, slots.u, deriv_slots, lane, d.du);
                        put_d1(&mut raw, slots.v, deriv_slots, lane, d.dv);
                        put_d1(&mut raw, slots.s, deriv_slots, lane, d.ds);
                        put_d1(&mut raw, slots.t, deriv_slots, lane, d.dt);
                    }
                    footprints[lane] = d.dp;
                } else {
                    let (dx, dy) = p.diff.at_hit(p.ray.direction, p.hit.t, g.ng);
                    footprints[lane] = [dx, dy];
                }
                if let Some(vp) = vertex_params {
                    for &(param, attr) in vp {
                        let slot = &program.layout().params[param];
                        if let Some(values) = g.attributes.get(attr) {
                            for (k, v) in values.iter().enumerate() {
                                raw.varying[(slot.offset + k) * raw.stride + lane] = *v;
                            }
                            raw.bound[param] = 1;
                        }
                    }
                }
            }
            if let Some(seed) = program.layout().seed {
                for (lane, g) in geoms.iter().enumerate() {
                    let h = g.as_ref().map_or(0, |g| point_seed(g.p));
                    raw.varying[seed * raw.stride + lane] = f32::from_bits(h as u32);
                    raw.varying[(seed + 1) * raw.stride + lane] = f32::from_bits((h >> 32) as u32);
                }
            }
        }
        let mut call = ShadeCall::new(frame, surface, inst.world_from_object, depth);
        call.batch_points = geoms.iter().map(|g| g.as_ref().map_or(Vec3A::ZERO, |g| g.p)).collect();
        call.batch_mask = geoms.iter().map(|g| if g.is_some() { -1 } else { 0 }).collect();
        let table = call.table();
        program.code.shade_with_table(batch, &table);
        let raw = batch.raw_mut();
        for (lane, (g, o)) in geoms.iter().zip(out.iter_mut()).enumerate() {
            let Some(g) = g else { continue };
            let os = g.os.unwrap_or(opacity);
            let ci = get3(&raw, slots.ci, lane, Vec3A::ZERO);
            let oi = get3(&raw, slots.oi, lane, os);
            *o = Shaded {
                ci: finite_or_zero(ci),
                oi: finite_or_zero(oi),
                p: g.p,
                ng: g.ng,
                dpdx: footprints[lane][0],
                dpdy: footprints[lane][1],
            };
        }
    });
}

/// The hand-written Rust path: the same lights (shaders and shadows over the batch, as the JIT
/// path computes them) and the same compositing, Rust for the surface.
#[allow(clippy::too_many_arguments)]
fn shade_native(
    frame: &Frame,
    native: &NativeSurface,
    group: &[Pending],
    geoms: &[Option<HitGeometry>],
    color: Vec3A,
    opacity: Vec3A,
    depth: u32,
    out: &mut [Shaded],
) {
    let points: Vec<Vec3A> = geoms.iter().map(|g| g.as_ref().map_or(Vec3A::ZERO, |g| g.p)).collect();
    let mask: Vec<i32> = geoms.iter().map(|g| if g.is_some() { -1 } else { 0 }).collect();
    let table = BatchLights::compute(frame, &points, &mask, depth);
    let mut seen = Vec::new();
    for (k, g) in geoms.iter().enumerate() {
        let Some(g) = g else { continue };
        seen.clear();
        seen.extend((0..table.counts[k] as usize).map(|j| {
            let h = &table.lights[j * table.n + k];
            LightSeen { l: Vec3A::from(h.l), cl: Vec3A::from(h.cl), ambient: h.ambient != 0 }
        }));
        let i = g.p - group[k].ray.origin;
        let (ci, oi) = native.shade(g.n, i, g.cs.unwrap_or(color), g.os.unwrap_or(opacity), &seen);
        let (dpdx, dpdy) = group[k].diff.at_hit(group[k].ray.direction, group[k].hit.t, g.ng);
        out[k] = Shaded { ci, oi, p: g.p, ng: g.ng, dpdx, dpdy };
    }
}

/// The finished pixels of one tile, for the pixel shader: linear RGBA, camera-space depth (infinite
/// on a miss), and the object and shader ids of the first hit (`u32::MAX` for none).
pub struct TilePixels<'a> {
    pub x0: u32,
    pub y0: u32,
    pub width: u32,
    pub rgba: &'a mut [[f32; 4]],
    pub depth: &'a [f32],
    pub object_id: &'a [u32],
    pub shader_id: &'a [u32],
}

/// Runs the world's pixel shader (RenderMan's imager) over a finished tile, 64 pixels a batch: `Ci`,
/// `Oi` and `alpha` in, `P` the raster position of the pixel's centre, `zdepth`, `objectid` and
/// `shaderid` (-1 for none); `Ci` and `alpha` out.
pub fn shade_pixels(frame: &Frame, tile: TilePixels<'_>) {
    let Some(imager) = &frame.world.pixel else { return };
    let _timer = ShadingTimer::start(&frame.stats);
    let program = &imager.program;
    let slots = &program.slots;
    let n = tile.rgba.len();
    let id = |v: u32| if v == u32::MAX { -1.0 } else { v as f32 };
    for start in (0..n).step_by(PACKET_SIZE) {
        let lanes = PACKET_SIZE.min(n - start);
        with_batch(program, lanes, |batch| {
            {
                let mut raw = batch.raw_mut();
                imager.write_params(&mut raw);
                for lane in 0..lanes {
                    let k = start + lane;
                    let c = tile.rgba[k];
                    let (x, y) = (tile.x0 + k as u32 % tile.width, tile.y0 + k as u32 / tile.width);
                    put3(&mut raw, slots.ci, lane, Vec3A::new(c[0], c[1], c[2]));
                    put3(&mut raw, slots.oi, lane, Vec3A::splat(c[3]));
                    put1(&mut raw, slots.alpha, lane, c[3]);
                    put3(&mut raw, slots.p, lane, Vec3A::new(x as f32 + 0.5, y as f32 + 0.5, 0.0));
                    put1(&mut raw, slots.zdepth, lane, tile.depth[k]);
                    put1(&mut raw, slots.objectid, lane, id(tile.object_id[k]));
                    put1(&mut raw, slots.shaderid, lane, id(tile.shader_id[k]));
                    put1(&mut raw, slots.ncomps, lane, 3.0);
                }
            }
            let mut call = ShadeCall::new(frame, imager, imager.world_from_shader, 0);
            let table = call.table();
            program.code.shade_with_table(batch, &table);
            let raw = batch.raw_mut();
            for lane in 0..lanes {
                let k = start + lane;
                let c = tile.rgba[k];
                let ci = get3(&raw, slots.ci, lane, Vec3A::new(c[0], c[1], c[2]));
                let alpha = match slots.alpha {
                    Some(s) if s.varying => raw.varying[s.offset * raw.stride + lane],
                    _ => c[3],
                };
                tile.rgba[k] = [ci.x, ci.y, ci.z, alpha];
            }
        });
    }
}

/// Writes the screen-space derivatives of a varying global (only globals below `deriv_slots` have
/// them; see `docs/packet-abi.md`).
fn put_d1(raw: &mut RawBatch<'_>, slot: Option<Slot>, deriv_slots: usize, lane: usize, d: [f32; 2]) {
    if let Some(s) = slot.filter(|s| s.varying && s.offset < deriv_slots) {
        raw.derivs[2 * s.offset * raw.stride + lane] = d[0];
        raw.derivs[(2 * s.offset + 1) * raw.stride + lane] = d[1];
    }
}

fn put_d3(raw: &mut RawBatch<'_>, slot: Option<Slot>, deriv_slots: usize, lane: usize, d: [Vec3A; 2]) {
    if let Some(s) = slot.filter(|s| s.varying && s.offset + 2 < deriv_slots) {
        let (dx, dy) = (d[0].to_array(), d[1].to_array());
        for (k, (x, y)) in dx.into_iter().zip(dy).enumerate() {
            raw.derivs[2 * (s.offset + k) * raw.stride + lane] = x;
            raw.derivs[(2 * (s.offset + k) + 1) * raw.stride + lane] = y;
        }
    }
}

fn finite_or_zero(v: Vec3A) -> Vec3A {
    if v.is_finite() {
        v
    } else {
        Vec3A::ZERO
    }
}

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
    batch_points: Vec<Vec3A>,
    batch_mask: Vec<i32>,
    batch_lights: Option<BatchLights>,
    chunk_cursor: usize,
}

struct LightQuery {
    category: String,
    p: [u32; 12],
    mask: [i32; 4],
    lights: Vec<HostLight>,
    counts: [u32; 4],
}

impl<'f, 'w> ShadeCall<'f, 'w> {
    pub(crate) fn new(
        frame: &'f Frame<'w>,
        instance: &'f ShaderInstance,
        world_from_object: Affine3A,
        depth: u32,
    ) -> Self {
        ShadeCall {
            frame,
            instance,
            world_from_object,
            depth,
            light_cache: None,
            text: String::new(),
            batch_points: Vec::new(),
            batch_mask: Vec::new(),
            batch_lights: None,
            chunk_cursor: 0,
        }
    }

    /// The call table; valid while `self` is neither moved nor dropped.
    pub(crate) fn table(&mut self) -> HostTable {
        HostTable {
            ctx: self as *mut ShadeCall as *mut c_void,
            matrix: host_matrix,
            lights: host_lights,
            texture: host_texture,
            rays: host_rays,
            depth: host_depth,
            ray_depth: host_ray_depth,
            message: host_message,
            shader_name: host_shader_name,
            print: host_print,
        }
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
        let (ax, ay) = if w >= h { (w / h, 1.0) } else { (1.0, h / w) };
        // camera -> screen: x' = x / (z tan ax), y' likewise, z' = z (a projective matrix).
        let near = world.camera.near.max(1e-6);
        let far = world.camera.far.max(near * 2.0);
        let proj = Mat4::from_cols_array(&[
            1.0 / (tan * ax),
            0.0,
            0.0,
            0.0,
            0.0,
            1.0 / (tan * ay),
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
            "NDC" => {
                Mat4::from_cols_array(&[
                    0.5 / ax,
                    0.0,
                    0.0,
                    0.0,
                    0.0,
                    -0.5 / ay,
                    0.0,
                    0.0,
                    0.0,
                    0.0,
                    1.0,
                    0.0,
                    0.5,
                    0.5,
                    0.0,
                    1.0,
                ]) * proj
            }
            _ => {
                Mat4::from_cols_array(&[
                    0.5 * w / ax,
                    0.0,
                    0.0,
                    0.0,
                    0.0,
                    -0.5 * h / ay,
                    0.0,
                    0.0,
                    0.0,
                    0.0,
                    1.0,
                    0.0,
                    0.5 * w,
                    0.5 * h,
                    0.0,
                    1.0,
                ]) * proj
            }
        };
        let camera_from_screen = screen_from_camera.inverse();
        Some(Mat4::from(world.camera.world_from_camera) * camera_from_screen)
    }
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
    let m = (b.inverse() * a).to_cols_array();
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
    mask: *const i32,
    p: *const f32,
    out: *mut HostLight,
    counts: *mut u32,
) {
    // SAFETY: the table's contract: 4 mask entries, 12 floats of P, MAX_LIGHTS * 4 lights, 4 counts.
    let (c, category, mask, p, out, counts) = unsafe {
        (
            call(ctx),
            category.as_str(),
            &*(mask as *const [i32; 4]),
            slice(p, 12),
            std::slice::from_raw_parts_mut(out, MAX_LIGHTS * 4),
            &mut *(counts as *mut [u32; 4]),
        )
    };
    if category.is_empty() && !c.batch_points.is_empty() && serve_from_batch(c, mask, p, out, counts) {
        return;
    }
    let pbits: [u32; 12] = std::array::from_fn(|i| p[i].to_bits());
    if let Some(q) = &c.light_cache {
        if q.category == category && q.p == pbits && q.mask == *mask {
            out[..q.lights.len()].copy_from_slice(&q.lights);
            *counts = q.counts;
            return;
        }
    }
    *counts = [0; 4];
    let points: [Vec3A; 4] = std::array::from_fn(|l| lane3(p, 0, l));
    for light in &c.frame.world.lights {
        if !light.in_category(category) {
            continue;
        }
        eval_light(c.frame, light, mask, &points, c.depth, out, counts);
    }
    let used = 4 * counts.iter().copied().max().unwrap_or(0) as usize;
    c.light_cache = Some(LightQuery {
        category: category.to_string(),
        p: pbits,
        mask: *mask,
        lights: out[..used].to_vec(),
        counts: *counts,
    });
}

/// Answers a chunk's light query from the batch's lights when the chunk's points are the batch's
/// (bit for bit: a shader that moved `P` gets its lights computed afresh).
fn serve_from_batch(
    c: &mut ShadeCall,
    mask: &[i32; 4],
    p: &[f32],
    out: &mut [HostLight],
    counts: &mut [u32; 4],
) -> bool {
    let n = c.batch_points.len();
    let chunks = n.div_ceil(4);
    let matches = |chunk: usize| {
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
    };
    let Some(chunk) = (0..chunks).map(|k| (c.chunk_cursor + k) % chunks).find(|&k| matches(k)) else {
        return false;
    };
    c.chunk_cursor = chunk;
    if c.batch_lights.is_none() {
        c.batch_lights = Some(BatchLights::compute(c.frame, &c.batch_points, &c.batch_mask, c.depth));
    }
    let Some(table) = &c.batch_lights else { return false };
    for l in 0..4 {
        counts[l] = 0;
        let lane = 4 * chunk + l;
        if mask[l] == 0 || lane >= table.n {
            continue;
        }
        counts[l] = table.counts[lane];
        for k in 0..table.counts[lane] as usize {
            out[4 * k + l] = table.lights[k * table.n + lane];
        }
    }
    true
}

/// Runs one light's shader for the active lanes of a chunk and appends what reaches each lane, with
/// shadows traced.
fn eval_light(
    frame: &Frame,
    light: &LightSource,
    mask: &[i32; 4],
    points: &[Vec3A; 4],
    depth: u32,
    out: &mut [HostLight],
    counts: &mut [u32; 4],
) {
    eval_light_lanes(frame, light, mask, points, depth, |l, h| {
        if (counts[l] as usize) < MAX_LIGHTS {
            out[4 * counts[l] as usize + l] = h;
            counts[l] += 1;
        }
    });
}

/// Runs one light's shader over `points` (up to a packet of lanes, `mask` nonzero where a point
/// asks) and hands each lane's light to `sink`, its colour attenuated by traced shadows: a packet
/// of shadow rays when nothing in the scene is transparent, one transmission walk per ray
/// otherwise. Area lights give one light per sample.
fn eval_light_lanes(
    frame: &Frame,
    light: &LightSource,
    mask: &[i32],
    points: &[Vec3A],
    depth: u32,
    mut sink: impl FnMut(usize, HostLight),
) {
    let n = points.len().min(PACKET_SIZE);
    let instance = &light.shader;
    let program = &instance.program;
    let slots = &program.slots;
    let samples = light.area.as_ref().map_or(1, |a| a.samples);
    let eye = frame.world.camera.eye();
    let ambient = light.kind == LightKind::Ambient;
    let scale = 1.0 / samples as f32;
    let mut results = vec![(Vec3A::ZERO, Vec3A::ZERO, Vec3A::ZERO); n];
    for sample in 0..samples {
        Stats::add(&frame.stats.light_evaluations, 1);
        with_batch(program, n, |batch| {
            {
                let mut raw = batch.raw_mut();
                instance.write_params(&mut raw);
                raw.mask[..n].copy_from_slice(&mask[..n]);
                for (l, &point) in points.iter().enumerate().take(n) {
                    // The emitting point: the light's origin, or a sample of its geometry.
                    let (mut origin, mut normal) = (instance.world_from_shader.translation, Vec3A::ZERO);
                    if let Some(area) = &light.area {
                        let h = mix(point_seed(point) ^ u64::from(sample).wrapping_mul(0x2545_F491_4F6C_DD1D));
                        if let Some((q, nn)) = area.sample(unit(h), unit(mix(h)), unit(mix(h ^ 1))) {
                            (origin, normal) = (q, nn);
                        }
                    }
                    put3(&mut raw, slots.ps, l, point);
                    put3(&mut raw, slots.p, l, origin);
                    put3(&mut raw, slots.n, l, normal);
                    put3(&mut raw, slots.e, l, eye);
                    put1(&mut raw, slots.ncomps, l, 3.0);
                }
            }
            let mut call = ShadeCall::new(frame, instance, instance.world_from_shader, depth);
            let table = call.table();
            program.code.shade_with_table(batch, &table);
            let raw = batch.raw_mut();
            for (l, r) in results.iter_mut().enumerate() {
                *r = (
                    get3(&raw, slots.l, l, Vec3A::ZERO),
                    get3(&raw, slots.cl, l, Vec3A::ZERO),
                    get3(&raw, slots.ol, l, Vec3A::ZERO),
                );
            }
        });
        // Shadows: which lanes need a ray, then one packet (or a walk per ray).
        let mut attenuation = vec![Vec3A::ONE; n];
        if !ambient && light.shadows {
            let mut packet = RayPacket::new();
            for l in 0..n {
                let (to_surface, cl, _) = results[l];
                if mask[l] == 0 || to_surface == Vec3A::ZERO || cl == Vec3A::ZERO || !cl.is_finite() {
                    continue;
                }
                let to_light = -to_surface;
                let distance = if light.kind == LightKind::Distant { f32::INFINITY } else { to_light.length() };
                let dir = to_light.normalize_or_zero();
                if frame.transparent_shadows {
                    attenuation[l] = transmission_along(frame, points[l], dir, distance);
                } else if let Some(ray) = shadow_ray(points[l], dir, distance) {
                    packet.set(l, &ray);
                }
            }
            if packet.active != 0 {
                Stats::add(&frame.stats.shadow_rays, packet.active.count_ones() as usize);
                let blocked = tracing(|| frame.world.scene.occluded_packet(&packet));
                for (l, a) in attenuation.iter_mut().enumerate() {
                    if blocked >> l & 1 != 0 {
                        *a = Vec3A::ZERO;
                    }
                }
            }
        }
        for l in 0..n {
            let (to_surface, cl, ol) = results[l];
            // `illuminate` leaves L at zero where the point is outside its cone: no light there.
            if mask[l] == 0 || (!ambient && to_surface == Vec3A::ZERO) {
                continue;
            }
            let cl = finite_or_zero(cl) * scale * attenuation[l];
            sink(
                l,
                HostLight {
                    l: if ambient { [0.0; 3] } else { (-to_surface).to_array() },
                    cl: cl.to_array(),
                    ol: finite_or_zero(ol).to_array(),
                    ambient: u32::from(ambient),
                },
            );
        }
    }
}

/// The shadow ray from `from` along unit `dir` for `distance`, kept off both ends; `None` when the
/// segment is too short to hold anything.
fn shadow_ray(from: Vec3A, dir: Vec3A, distance: f32) -> Option<Ray> {
    if dir == Vec3A::ZERO {
        return None;
    }
    let eps = epsilon(from);
    let tmax = if distance.is_finite() { distance - 2.0 * eps } else { f32::INFINITY };
    (tmax > eps).then(|| Ray::segment(from, dir, eps, tmax))
}

/// The lights of every point of a surface batch, computed once for the whole batch when the shader
/// first asks (light shaders run over the batch, shadow rays go as packets): lane `l`'s light `k`
/// at `lights[k * n + l]`.
struct BatchLights {
    n: usize,
    counts: Vec<u32>,
    lights: Vec<HostLight>,
}

impl BatchLights {
    fn compute(frame: &Frame, points: &[Vec3A], mask: &[i32], depth: u32) -> BatchLights {
        let n = points.len();
        let slots: usize = frame.world.lights.iter().map(|l| l.area.as_ref().map_or(1, |a| a.samples as usize)).sum();
        let slots = slots.min(MAX_LIGHTS);
        let mut counts = vec![0u32; n];
        let mut lights = vec![HostLight::default(); slots * n];
        for light in &frame.world.lights {
            if light.in_category("") {
                eval_light_lanes(frame, light, mask, points, depth, |l, h| {
                    let k = counts[l] as usize;
                    if k < slots {
                        lights[k * n + l] = h;
                        counts[l] += 1;
                    }
                });
            }
        }
        BatchLights { n, counts, lights }
    }
}

/// A start offset for rays leaving `p` (its scale grows with the coordinates' magnitude).
fn epsilon(p: Vec3A) -> f32 {
    1e-4 * p.abs().max_element().max(1.0)
}

/// How much light gets from `from` along unit `dir` for `distance` (white where nothing blocks):
/// opaque blockers stop it, transparent ones filter it by their opacity.
fn transmission_along(frame: &Frame, from: Vec3A, dir: Vec3A, distance: f32) -> Vec3A {
    let Some(ray) = shadow_ray(from, dir, distance) else { return Vec3A::ONE };
    let (eps, tmax) = (ray.tmin, ray.tmax);
    let world = frame.world;
    Stats::add(&frame.stats.shadow_rays, 1);
    if !frame.transparent_shadows {
        return if tracing(|| world.scene.occluded(&ray)) { Vec3A::ZERO } else { Vec3A::ONE };
    }
    let mut through = Vec3A::ONE;
    let mut start = eps;
    for _ in 0..world.options.max_transparent_layers {
        let hit = tracing(|| world.scene.intersect(&Ray::segment(from, dir, start, tmax)));
        if !hit.is_hit() {
            return through;
        }
        let Some(inst) = world.instances.get(hit.instance as usize) else { return through };
        let material = world.materials.get(inst.material as usize).unwrap_or(&DEFAULT_MATERIAL);
        if material.is_opaque_for_shadows() {
            return Vec3A::ZERO;
        }
        let opacity = if material.shadow_by_shader {
            let ray = Ray::segment(from, dir, start, tmax);
            let mut shaded = [Shaded::default()];
            let diff = RayDifferential::cone(dir, 0.0, frame.pixel_spread);
            shade_group(frame, &[Pending { index: 0, ray, diff, hit }], world.options.max_ray_depth, &mut shaded);
            shaded[0].oi
        } else {
            Vec3A::from(material.opacity)
        };
        through *= Vec3A::ONE - opacity.clamp(Vec3A::ZERO, Vec3A::ONE);
        if through.max_element() < 1.0 / 256.0 {
            return Vec3A::ZERO;
        }
        start = hit.t + epsilon(from + dir * hit.t);
    }
    through
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
        1 => 3,
        _ => 1,
    };
    // SAFETY: the table's contract: 4 mask entries, 3 x 4 coordinates (2 x 4 for textures), 4 first
    // channels, `values` x 4 results and 4 flags.
    let (c, name, mask, coords, first, out, ok) = unsafe {
        (
            call(ctx),
            name.as_str(),
            &*(mask as *const [i32; 4]),
            slice(coords, if kind == 0 { 28 } else { 12 }),
            slice(first, 4),
            std::slice::from_raw_parts_mut(out, 4 * values),
            &mut *(ok as *mut [u32; 4]),
        )
    };
    let textures = &c.frame.world.textures;
    let mut lane_out = [0.0f32; 64];
    for l in 0..4 {
        ok[l] = 0;
        if mask[l] == 0 {
            continue;
        }
        let found = match kind {
            0 => {
                // Rows 2..6: the footprint from the coordinates' derivatives, widths applied, and blur.
                let row = |k: usize| coords[4 * k + l];
                let footprint = Footprint { dsdx: row(2), dtdx: row(3), dsdy: row(4), dtdy: row(5) };
                let blur = row(6).max(0.0);
                let opts = LookupOptions { sblur: blur, tblur: blur, ..LookupOptions::default() };
                let first = first[l].max(0.0) as usize;
                textures.texture(name, row(0), row(1), footprint, first, &mut lane_out[..values], &opts)
            }
            1 => {
                let dir = lane3(coords, 0, l).to_array();
                textures.environment(name, dir, [0.0; 3], [0.0; 3], 0, &mut lane_out[..3], &LookupOptions::default())
            }
            _ => {
                let p = lane3(coords, 0, l);
                let shadowed = if name == "raytrace" {
                    // Ray-traced shadows (BMRT's convention): towards the light's own origin.
                    let to = c.instance.world_from_shader.translation;
                    let d = to - p;
                    let t = transmission_along(c.frame, p, d.normalize_or_zero(), d.length());
                    Some(1.0 - (t.x + t.y + t.z) / 3.0)
                } else {
                    textures.shadow(name, p.to_array(), &LookupOptions::default())
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
    match kind {
        0 => {
            let mut rays = Vec::new();
            let mut lanes = Vec::new();
            for l in 0..4 {
                if mask[l] == 0 {
                    continue;
                }
                for r in 0..3 {
                    out[4 * r + l] = 0.0;
                }
                out[12 + l] = f32::INFINITY;
                let (from, dir) = (lane3(a, 0, l), lane3(b, 0, l).normalize_or_zero());
                if c.depth + 1 > max_depth || dir == Vec3A::ZERO || !from.is_finite() {
                    continue;
                }
                rays.push(Ray::segment(from, dir, epsilon(from), f32::INFINITY));
                lanes.push(l);
            }
            if rays.is_empty() {
                return;
            }
            Stats::add(&frame.stats.secondary_rays, rays.len());
            let seen = trace_rays(frame, &rays, c.depth + 1);
            for (s, l) in seen.iter().zip(lanes) {
                for r in 0..3 {
                    out[4 * r + l] = s.color[r];
                }
                out[12 + l] = s.depth;
            }
        }
        1 => {
            for l in 0..4 {
                if mask[l] == 0 {
                    continue;
                }
                let (from, to) = (lane3(a, 0, l), lane3(b, 0, l));
                let d = to - from;
                let t = transmission_along(frame, from, d.normalize_or_zero(), d.length());
                for r in 0..3 {
                    out[4 * r + l] = t[r];
                }
            }
        }
        _ => {
            for l in 0..4 {
                if mask[l] == 0 {
                    continue;
                }
                let (p, n) = (lane3(a, 0, l), lane3(b, 0, l).normalize_or_zero());
                let count = (samples[l].max(1.0) as u32).min(256);
                let (blocked, light) = hemisphere(frame, p, n, count, kind == 3, c.depth);
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

/// Cosine-weighted rays over the hemisphere around `n`: the fraction blocked, and (when `shade`)
/// the mean colour seen.
fn hemisphere(frame: &Frame, p: Vec3A, n: Vec3A, count: u32, shade: bool, depth: u32) -> (f32, Vec3A) {
    if n == Vec3A::ZERO {
        return (0.0, Vec3A::ZERO);
    }
    let (t1, t2) = orthonormal(n);
    let seed = point_seed(p);
    let mut rays = Vec::with_capacity(count as usize);
    for i in 0..count {
        let h = mix(seed ^ u64::from(i).wrapping_mul(0x9E37_79B9));
        let (r1, r2) = (unit(h), unit(mix(h)));
        let phi = std::f32::consts::TAU * r1;
        let (s, cz) = (r2.sqrt(), (1.0 - r2).sqrt());
        let dir = t1 * (s * phi.cos()) + t2 * (s * phi.sin()) + n * cz;
        rays.push(Ray::segment(p, dir, epsilon(p), f32::INFINITY));
    }
    Stats::add(&frame.stats.secondary_rays, rays.len());
    if shade && depth < frame.world.options.max_ray_depth {
        let seen = trace_rays(frame, &rays, depth + 1);
        let blocked = seen.iter().filter(|s| s.depth.is_finite()).count() as f32 / count as f32;
        let sum = seen.iter().fold(Vec3A::ZERO, |acc, s| acc + s.color);
        (blocked, sum / count as f32)
    } else {
        let blocked = tracing(|| rays.iter().filter(|r| frame.world.scene.occluded(r)).count()) as f32 / count as f32;
        (blocked, Vec3A::ZERO)
    }
}

fn orthonormal(n: Vec3A) -> (Vec3A, Vec3A) {
    let a = if n.x.abs() > 0.9 { Vec3A::Y } else { Vec3A::X };
    let t1 = n.cross(a).normalize();
    (t1, n.cross(t1))
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

unsafe extern "C" fn host_message(ctx: *mut c_void, which: u32, name: StrRef, out: *mut MessageOut) -> u32 {
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
        (Builtin::Option, "PixelSamples") => floats(out, &[options.samples.0 as f32, options.samples.1 as f32]),
        (Builtin::Rendererinfo, "renderer") => {
            c.text = "rtsl".to_string();
            out.kind = 4;
            out.len = 0;
            out.string = StrRef::new(&c.text);
            1
        }
        (Builtin::Rendererinfo, "version") => floats(out, &[0.0, 1.0, 0.0, 0.0]),
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

unsafe extern "C" fn host_shader_name(ctx: *mut c_void, has_kind: u32, _kind: StrRef) -> StrRef {
    // SAFETY: the table's contract.
    let c = unsafe { call(ctx) };
    c.text = if has_kind == 0 { c.instance.program.name.clone() } else { String::new() };
    StrRef::new(&c.text)
}

unsafe extern "C" fn host_print(_ctx: *mut c_void, text: StrRef) {
    use std::io::Write;
    // SAFETY: the table's contract.
    let text = unsafe { text.as_str() };
    let _ = std::io::stdout().lock().write_all(text.as_bytes());
}
