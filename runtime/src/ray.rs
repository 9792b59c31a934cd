//! Rays, ray packets and hit records: the data that flows into and out of the tracer.
//!
//! Invariants:
//! - A [`Ray`] covers the open interval `(tmin, tmax)` of its parameter `t`; a hit at `t` lies at
//!   `origin + t * direction`. Directions need not be normalised: `t` is then measured in units of
//!   the direction's length, and it is the same number in world and object space (instance
//!   transforms are applied to origin and direction alike).
//! - A [`RayPacket`] holds [`PACKET_SIZE`] rays in SoA form. Lane `i` takes part in a query only if
//!   bit `i` of `active` is set; the tracer never reads or writes the results of inactive lanes.
//! - A [`Hit`] with `instance == INVALID_ID` is a miss; its other fields are then unspecified.
//!
//! Self-intersection policy: the tracer itself uses `tmin` as given (no hidden epsilon). Secondary
//! rays should start at [`offset_ray_origin`] of the surface point, which moves the point a few
//! floating-point ULPs off the surface along the geometric normal (Wächter and Binder, "A Fast and
//! Robust Method for Avoiding Self-Intersection", Ray Tracing Gems, chapter 6).

use glam::Vec3A;

/// Rays per packet: an 8x8 block of pixels.
pub const PACKET_SIZE: usize = 64;
/// Identifier used for "no instance" / "no primitive".
pub const INVALID_ID: u32 = u32::MAX;

/// A single ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Ray origin.
    pub origin: Vec3A,
    /// Ray direction (not necessarily normalised).
    pub direction: Vec3A,
    /// Start of the valid interval (exclusive).
    pub tmin: f32,
    /// End of the valid interval (exclusive).
    pub tmax: f32,
    /// The ray's time within the shutter interval: moving instances are where they are at this
    /// time (motion blur).
    pub time: f32,
}

impl Ray {
    /// A ray over `(0, inf)` at time 0.
    pub fn new(origin: Vec3A, direction: Vec3A) -> Self {
        Self { origin, direction, tmin: 0.0, tmax: f32::INFINITY, time: 0.0 }
    }

    /// A ray over `(tmin, tmax)` at time 0.
    pub fn segment(origin: Vec3A, direction: Vec3A, tmin: f32, tmax: f32) -> Self {
        Self { origin, direction, tmin, tmax, time: 0.0 }
    }

    /// The same ray at time `time`.
    pub fn at_time(self, time: f32) -> Self {
        Self { time, ..self }
    }

    /// The point at parameter `t`.
    pub fn at(&self, t: f32) -> Vec3A {
        self.origin + self.direction * t
    }
}

/// The result of a closest-hit query: which triangle of which instance, where along the ray, and
/// where on the triangle. Surface details (normals, attributes) come from
/// [`crate::Scene::surface`], computed only for the hits that need them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Ray parameter of the hit.
    pub t: f32,
    /// Barycentric coordinate of vertex 1.
    pub u: f32,
    /// Barycentric coordinate of vertex 2.
    pub v: f32,
    /// Index of the instance hit, or [`INVALID_ID`] for a miss.
    pub instance: u32,
    /// Index of the triangle within the instance's object.
    pub primitive: u32,
}

impl Hit {
    /// A miss.
    pub const MISS: Hit = Hit { t: f32::INFINITY, u: 0.0, v: 0.0, instance: INVALID_ID, primitive: INVALID_ID };

    /// Whether this record is a hit.
    pub fn is_hit(&self) -> bool {
        self.instance != INVALID_ID
    }
}

/// A candidate intersection passed to a hit filter (e.g. alpha-masked leaves). Returning `false`
/// from the filter makes the tracer ignore the candidate and continue.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HitCandidate {
    /// Ray parameter of the candidate.
    pub t: f32,
    /// Barycentric coordinate of vertex 1.
    pub u: f32,
    /// Barycentric coordinate of vertex 2.
    pub v: f32,
    /// Instance index.
    pub instance: u32,
    /// Object index (the instance's object).
    pub object: u32,
    /// Triangle index within the object.
    pub primitive: u32,
    /// Packet lane, or 0 for single rays.
    pub lane: u32,
}

/// An optional per-hit filter callback. `None` accepts every hit.
pub type HitFilter<'a> = Option<&'a (dyn Fn(&HitCandidate) -> bool + Sync)>;

/// `PACKET_SIZE` floats, aligned for SIMD loads.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
pub struct Lanes(pub [f32; PACKET_SIZE]);

impl Default for Lanes {
    fn default() -> Self {
        Lanes([0.0; PACKET_SIZE])
    }
}

impl Lanes {
    /// All lanes set to `v`.
    pub fn splat(v: f32) -> Self {
        Lanes([v; PACKET_SIZE])
    }
}

/// `PACKET_SIZE` ids.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
pub struct IdLanes(pub [u32; PACKET_SIZE]);

impl Default for IdLanes {
    fn default() -> Self {
        IdLanes([INVALID_ID; PACKET_SIZE])
    }
}

/// A packet of up to [`PACKET_SIZE`] rays in SoA layout with an active mask.
///
/// Packet traversal is fastest when the rays are coherent: the same direction signs on every axis
/// and neighbouring lanes close together (the camera fills lanes in 2x2 quads in Morton order).
/// Incoherent packets are still answered correctly, by single-ray traversal per lane.
#[derive(Clone, Debug, Default)]
pub struct RayPacket {
    /// Origin x per lane.
    pub ox: Lanes,
    /// Origin y per lane.
    pub oy: Lanes,
    /// Origin z per lane.
    pub oz: Lanes,
    /// Direction x per lane.
    pub dx: Lanes,
    /// Direction y per lane.
    pub dy: Lanes,
    /// Direction z per lane.
    pub dz: Lanes,
    /// Interval start per lane.
    pub tmin: Lanes,
    /// Interval end per lane.
    pub tmax: Lanes,
    /// Time per lane (see [`Ray::time`]).
    pub time: Lanes,
    /// Bit `i` set: lane `i` takes part.
    pub active: u64,
}

impl RayPacket {
    /// An empty packet (no active lanes).
    pub fn new() -> Self {
        Self::default()
    }

    /// Sets lane `i` to `ray` and marks it active.
    pub fn set(&mut self, i: usize, ray: &Ray) {
        self.ox.0[i] = ray.origin.x;
        self.oy.0[i] = ray.origin.y;
        self.oz.0[i] = ray.origin.z;
        self.dx.0[i] = ray.direction.x;
        self.dy.0[i] = ray.direction.y;
        self.dz.0[i] = ray.direction.z;
        self.tmin.0[i] = ray.tmin;
        self.tmax.0[i] = ray.tmax;
        self.time.0[i] = ray.time;
        self.active |= 1u64 << i;
    }

    /// The ray in lane `i` (whether active or not).
    pub fn get(&self, i: usize) -> Ray {
        Ray {
            origin: Vec3A::new(self.ox.0[i], self.oy.0[i], self.oz.0[i]),
            direction: Vec3A::new(self.dx.0[i], self.dy.0[i], self.dz.0[i]),
            tmin: self.tmin.0[i],
            tmax: self.tmax.0[i],
            time: self.time.0[i],
        }
    }
}

/// Closest-hit results for a packet, in SoA layout. Only active lanes are written.
#[derive(Clone, Debug, Default)]
pub struct HitPacket {
    /// Ray parameter per lane (`inf` for a miss).
    pub t: Lanes,
    /// Barycentric u per lane.
    pub u: Lanes,
    /// Barycentric v per lane.
    pub v: Lanes,
    /// Instance per lane ([`INVALID_ID`] for a miss).
    pub instance: IdLanes,
    /// Primitive per lane.
    pub primitive: IdLanes,
}

impl HitPacket {
    /// The hit of lane `i`.
    pub fn get(&self, i: usize) -> Hit {
        Hit {
            t: self.t.0[i],
            u: self.u.0[i],
            v: self.v.0[i],
            instance: self.instance.0[i],
            primitive: self.primitive.0[i],
        }
    }
}

/// Moves a surface point `p` with geometric normal `n` slightly off the surface, to the side that `n`
/// points to, so that a ray leaving from it does not re-hit the surface it starts on. The offset is a
/// few ULPs of `p`'s coordinates (integer arithmetic on the float bits), with a small absolute offset
/// near the origin (Wächter and Binder 2019). Flip `n` to leave from the other side.
pub fn offset_ray_origin(p: Vec3A, n: Vec3A) -> Vec3A {
    const ORIGIN: f32 = 1.0 / 32.0;
    const FLOAT_SCALE: f32 = 1.0 / 65536.0;
    const INT_SCALE: f32 = 256.0;
    let n = n.normalize_or_zero();
    let off = |pc: f32, nc: f32| -> f32 {
        let of_i = (INT_SCALE * nc) as i32;
        let bits = pc.to_bits() as i32;
        let moved = f32::from_bits((bits + if pc < 0.0 { -of_i } else { of_i }) as u32);
        if pc.abs() < ORIGIN {
            pc + FLOAT_SCALE * nc
        } else {
            moved
        }
    };
    Vec3A::new(off(p.x, n.x), off(p.y, n.y), off(p.z, n.z))
}
