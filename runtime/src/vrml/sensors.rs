//! VRML 97's sensors of the user (ISO/IEC 14772-1, 4.6.7): the pointing-device sensors
//! (TouchSensor 6.51, PlaneSensor 6.34, SphereSensor 6.44, CylinderSensor 6.15), driven by the
//! caller's pointer ([`VrmlScene::pointer_move`], [`VrmlScene::pointer_press`],
//! [`VrmlScene::pointer_drag`], [`VrmlScene::pointer_release`]), and the ProximitySensor (6.38) and
//! VisibilitySensor (6.54), sensed against the camera at each timestamp of
//! [`VrmlScene::advance_to`].
//!
//! - The pointing-device sensors a pointer over a shape reaches are the enabled ones among the
//!   children of the innermost group above the shape that has any (4.6.7.5; the file's top level
//!   counts as a group). They sense in that group's space: the Transforms above them.
//! - A VisibilitySensor's box counts as visible when it is not wholly outside one of the view
//!   frustum's planes: nothing hidden behind other shapes is told apart, and a box near a corner
//!   of the frustum may count as visible when it is just outside.

use super::events::{quat_of, rotation_of, EventType, EventValue};
use super::{build, NodeRef, VrmlScene};
use crate::api::{Context, InstanceId};
use crate::scene_file::SceneFileError;
use glam::{Affine3A, Quat, Vec2, Vec3, Vec3A};
use std::collections::{HashMap, HashSet};

/// The node types that sense the pointer.
const POINTING: [&str; 4] = ["TouchSensor", "PlaneSensor", "SphereSensor", "CylinderSensor"];

/// A ray from the eye through the pointer, in world space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointerRay {
    pub origin: Vec3A,
    pub direction: Vec3A,
}

/// Where a pointer ray meets a shape, in world space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointerHit {
    pub instance: InstanceId,
    pub point: Vec3A,
    /// The unit normal there (the shading normal where the mesh has normals).
    pub normal: Vec3A,
    /// The texture coordinate there, VRML's (t up); 0 where the mesh has none.
    pub tex_coord: Vec2,
}

/// The sensors' state between events.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Sensing {
    /// The TouchSensors the pointer is over (`isOver` TRUE sent).
    over: Vec<NodeRef>,
    /// The sensors the button's press activated, and what each tracks.
    active: Vec<(NodeRef, Drag)>,
    /// The ProximitySensors the camera is inside, with the position and orientation last sent.
    inside: HashMap<NodeRef, (Vec3, [f32; 4])>,
    /// The VisibilitySensors whose boxes are in view.
    visible: HashSet<NodeRef>,
}

/// What an active pointing-device sensor tracks.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Drag {
    Touch,
    /// The tracking plane through `start`, parallel to the local z = 0 plane.
    Plane {
        local_from_world: Affine3A,
        start: Vec3,
        last: Option<Vec3>,
    },
    /// The sphere about the local origin through `start`.
    Sphere {
        local_from_world: Affine3A,
        start: Vec3,
        last: Option<Quat>,
    },
    /// The disk at local height `disk` (looking along the axis), or the cylinder about the local
    /// y axis through `start`.
    Cylinder {
        local_from_world: Affine3A,
        start: Vec3,
        disk: bool,
        last: Option<f32>,
    },
}

/// The angle of `p` about the local y axis, as a rotation about +y turns it (0 along +z).
fn angle_about_y(p: Vec3) -> f32 {
    p.x.atan2(p.z)
}

/// The nearest point at or after the ray's origin where it meets the sphere of `radius` about
/// the origin; where it misses, the sphere's point nearest the ray.
fn on_sphere(o: Vec3, d: Vec3, radius: f32) -> Option<Vec3> {
    let a = d.length_squared();
    if a <= 0.0 || radius <= 0.0 {
        return None;
    }
    let b = o.dot(d);
    let c = o.length_squared() - radius * radius;
    let disc = b * b - a * c;
    let p = if disc >= 0.0 {
        let sq = disc.sqrt();
        let t = if (-b - sq) / a >= 0.0 { (-b - sq) / a } else { (-b + sq) / a };
        if t < 0.0 {
            return None;
        }
        o + d * t
    } else {
        (o + d * (-b / a).max(0.0)).normalize_or_zero() * radius
    };
    p.is_finite().then_some(p)
}

/// The ray's point on the cylinder of `radius` about the y axis (the nearest at or after its
/// origin; where it misses, the cylinder's point nearest the ray).
fn on_cylinder(o: Vec3, d: Vec3, radius: f32) -> Option<Vec3> {
    let (o2, d2) = (Vec2::new(o.x, o.z), Vec2::new(d.x, d.z));
    let flat = on_circle(o2, d2, radius)?;
    // The height where the ray passes nearest that point.
    let t = if d2.length_squared() > 0.0 { (flat - o2).dot(d2) / d2.length_squared() } else { 0.0 };
    let p = Vec3::new(flat.x, o.y + d.y * t.max(0.0), flat.y);
    p.is_finite().then_some(p)
}

fn on_circle(o: Vec2, d: Vec2, radius: f32) -> Option<Vec2> {
    let a = d.length_squared();
    if a <= 0.0 || radius <= 0.0 {
        return None;
    }
    let b = o.dot(d);
    let c = o.length_squared() - radius * radius;
    let disc = b * b - a * c;
    if disc >= 0.0 {
        let sq = disc.sqrt();
        let t = if (-b - sq) / a >= 0.0 { (-b - sq) / a } else { (-b + sq) / a };
        if t >= 0.0 {
            return Some(o + d * t);
        }
    }
    Some((o + d * (-b / a).max(0.0)).normalize_or_zero() * radius)
}

/// The ray's point on the plane where coordinate `axis` is `at` (none when it runs along it or
/// away from it).
fn on_plane(o: Vec3, d: Vec3, axis: usize, at: f32) -> Option<Vec3> {
    if d[axis].abs() < 1e-9 {
        return None;
    }
    let t = (at - o[axis]) / d[axis];
    (t >= 0.0 && t.is_finite()).then(|| o + d * t)
}

impl VrmlScene {
    /// A field of `r` read as `ty`, if it has one of that type.
    fn sensor_field(&self, r: NodeRef, name: &str, ty: EventType) -> Option<EventValue> {
        let node = self.documents.get(r.doc)?.1.nodes.get(r.node.0 as usize)?;
        EventValue::from_value(&node.field(name)?.value, ty)
    }

    fn flag(&self, r: NodeRef, name: &str, default: bool) -> bool {
        match self.sensor_field(r, name, EventType::SFBool) {
            Some(EventValue::Bool(b)) => b,
            _ => default,
        }
    }

    fn number(&self, r: NodeRef, name: &str, default: f32) -> f32 {
        match self.sensor_field(r, name, EventType::SFFloat) {
            Some(EventValue::Float(f)) => f,
            _ => default,
        }
    }

    fn vector(&self, r: NodeRef, name: &str, default: Vec3) -> Vec3 {
        match self.sensor_field(r, name, EventType::SFVec3f) {
            Some(EventValue::Vec3(v)) => v,
            _ => default,
        }
    }

    fn vector2(&self, r: NodeRef, name: &str, default: Vec2) -> Vec2 {
        match self.sensor_field(r, name, EventType::SFVec2f) {
            Some(EventValue::Vec2(v)) => v,
            _ => default,
        }
    }

    fn type_of(&self, r: NodeRef) -> &str {
        self.documents.get(r.doc).and_then(|(_, d)| d.nodes.get(r.node.0 as usize)).map_or("", |n| n.type_name.as_str())
    }

    /// Where shape `shape`'s pointer ray meets it: the point of triangle `primitive` at
    /// barycentrics `(u, v)` (of its second and third corners), with the normal and texture
    /// coordinate there. `None` for an instance that is not one of the scene's shapes.
    pub fn pointer_hit(
        &self,
        rt: &Context,
        instance: InstanceId,
        primitive: u32,
        (u, v): (f32, f32),
    ) -> Option<PointerHit> {
        let shape = self.shapes.iter().position(|p| p.made == instance)?;
        let world = rt.instance_transform(instance).ok()?;
        let mesh = rt.object_mesh(*self.shape_objects.get(shape)?)?;
        let tri = *mesh.triangles.get(primitive as usize)?;
        let w = 1.0 - u - v;
        let corner = |i: usize| tri[i] as usize;
        let at = |values: &[Vec3]| -> Option<Vec3> {
            Some(values.get(corner(0))? * w + *values.get(corner(1))? * u + *values.get(corner(2))? * v)
        };
        let point = world.transform_point3a(Vec3A::from(at(&mesh.positions)?));
        let local_normal = match mesh.normals.as_deref().and_then(at) {
            Some(n) => n,
            None => {
                let [a, b, c] = [0, 1, 2].map(|i| mesh.positions.get(corner(i)).copied().unwrap_or_default());
                (b - a).cross(c - a)
            }
        };
        let normal_matrix = world.matrix3.inverse().transpose();
        let normal = (normal_matrix * Vec3A::from(local_normal)).normalize_or_zero();
        let tex_coord = match mesh.uvs.as_deref() {
            Some(uvs) => {
                let uv = |i: usize| uvs.get(corner(i)).copied().unwrap_or_default();
                let t = uv(0) * w + uv(1) * u + uv(2) * v;
                // rtsl's t runs down the image, VRML's up.
                Vec2::new(t.x, 1.0 - t.y)
            }
            None => Vec2::ZERO,
        };
        Some(PointerHit { instance, point, normal, tex_coord })
    }

    /// The pointing-device sensors a pointer over `instance` reaches (see the module's notes),
    /// with the world-from-local matrix of their space.
    fn pointing_sensors(&mut self, rt: &mut Context, instance: InstanceId) -> (Vec<NodeRef>, Affine3A) {
        let Some(shape) = self.shapes.iter().position(|p| p.made == instance) else {
            return (Vec::new(), Affine3A::IDENTITY);
        };
        let placed = &self.shapes[shape];
        let (path, doc) = (placed.path.clone(), placed.node.doc);
        let children = |scene: &VrmlScene, g: NodeRef| -> Vec<NodeRef> {
            let doc = &scene.documents[g.doc].1;
            match doc.node(g.node).field("children").map(|f| &f.value) {
                Some(super::parse::Value::Nodes(v)) => v.iter().map(|&node| NodeRef { doc: g.doc, node }).collect(),
                Some(super::parse::Value::Node(Some(n))) => vec![NodeRef { doc: g.doc, node: *n }],
                _ => Vec::new(),
            }
        };
        let mut groups: Vec<(Vec<NodeRef>, usize)> =
            (0..path.len()).rev().map(|i| (children(self, path[i]), i + 1)).collect();
        // The top level of the shape's file, below the Inlines that brought it.
        let outside = path.iter().position(|g| g.doc == doc).unwrap_or(path.len());
        let roots = self.documents.get(doc).map(|(_, d)| d.roots.clone()).unwrap_or_default();
        groups.push((roots.into_iter().map(|node| NodeRef { doc, node }).collect(), outside));
        for (group, depth) in groups {
            let sensors: Vec<NodeRef> = group
                .into_iter()
                .filter(|&r| POINTING.contains(&self.type_of(r)) && self.flag(r, "enabled", true))
                .collect();
            if !sensors.is_empty() {
                let prefix = path[..depth].to_vec();
                return (sensors, build::world_of(rt, self, &prefix));
            }
        }
        (Vec::new(), Affine3A::IDENTITY)
    }

    /// The time events are stamped with: `time`, or the last timestamp run if that is later.
    fn event_time(&self, time: f64) -> f64 {
        self.events.now().map_or(time, |now| time.max(now))
    }

    fn send(&mut self, r: NodeRef, events: Vec<(&'static str, EventValue)>, time: f64) {
        self.events.send(&mut self.documents, r, events, time);
    }

    /// The pointer moved to `hit` (`None`: over no shape) without a button held: the TouchSensors
    /// it leaves send `isOver` FALSE, those it comes over `isOver` TRUE, and those it is over
    /// `hitPoint_changed`, `hitNormal_changed` and `hitTexCoord_changed` in their space. While a
    /// press is active nothing is sent ([`VrmlScene::pointer_drag`] is). Returns whether `rt`'s
    /// scene changed.
    pub fn pointer_move(
        &mut self,
        hit: Option<&PointerHit>,
        time: f64,
        rt: &mut Context,
    ) -> Result<bool, SceneFileError> {
        if !self.sensing.active.is_empty() {
            return Ok(false);
        }
        self.hover(hit, time, rt);
        self.apply(rt)
    }

    fn hover(&mut self, hit: Option<&PointerHit>, time: f64, rt: &mut Context) {
        let time = self.event_time(time);
        let (sensors, world) = match hit {
            Some(h) => self.pointing_sensors(rt, h.instance),
            None => (Vec::new(), Affine3A::IDENTITY),
        };
        let touch: Vec<NodeRef> = sensors.into_iter().filter(|&r| self.type_of(r) == "TouchSensor").collect();
        for r in std::mem::take(&mut self.sensing.over) {
            if !touch.contains(&r) {
                self.send(r, vec![("isOver", EventValue::Bool(false))], time);
            }
        }
        let Some(hit) = hit else { return };
        let local_from_world = world.inverse();
        let point = Vec3::from(local_from_world.transform_point3a(hit.point));
        let normal = Vec3::from(world.matrix3.transpose() * hit.normal).normalize_or_zero();
        for &r in &touch {
            let mut events = Vec::new();
            if !self.sensing.over.contains(&r) {
                events.push(("isOver", EventValue::Bool(true)));
            }
            if point.is_finite() && normal.is_finite() {
                events.push(("hitPoint_changed", EventValue::Vec3(point)));
                events.push(("hitNormal_changed", EventValue::Vec3(normal)));
                events.push(("hitTexCoord_changed", EventValue::Vec2(hit.tex_coord)));
            }
            self.send(r, events, time);
        }
        self.sensing.over = touch;
    }

    /// The button pressed with the pointer at `hit` along `ray`: the sensors the pointer reaches
    /// become active (`isActive` TRUE), each drag sensor setting up what it tracks from the point
    /// pressed. Returns whether a drag sensor took the pointer (the caller then sends the
    /// pointer's moves to [`VrmlScene::pointer_drag`] rather than navigating), and whether `rt`'s
    /// scene changed.
    pub fn pointer_press(
        &mut self,
        hit: &PointerHit,
        ray: PointerRay,
        time: f64,
        rt: &mut Context,
    ) -> Result<(bool, bool), SceneFileError> {
        self.hover(Some(hit), time, rt);
        let time = self.event_time(time);
        let (sensors, world) = self.pointing_sensors(rt, hit.instance);
        let local_from_world = world.inverse();
        if !local_from_world.is_finite() {
            return Ok((false, self.apply(rt)?));
        }
        let start = Vec3::from(local_from_world.transform_point3a(hit.point));
        let bearing = Vec3::from(local_from_world.transform_vector3a(ray.direction));
        let mut grabbed = false;
        for r in sensors {
            let drag = match self.type_of(r) {
                "PlaneSensor" => Drag::Plane { local_from_world, start, last: None },
                "SphereSensor" => Drag::Sphere { local_from_world, start, last: None },
                "CylinderSensor" => {
                    // Looking along the axis (within diskAngle of it), the sensor is a disk.
                    let disk_angle = self.number(r, "diskAngle", 0.262);
                    let along = (bearing.y.abs() / bearing.length().max(1e-20)).clamp(0.0, 1.0).acos();
                    Drag::Cylinder { local_from_world, start, disk: along < disk_angle, last: None }
                }
                _ => Drag::Touch,
            };
            grabbed |= drag != Drag::Touch;
            self.sensing.active.retain(|(s, _)| *s != r);
            self.sensing.active.push((r, drag));
            self.send(r, vec![("isActive", EventValue::Bool(true))], time);
        }
        Ok((grabbed, self.apply(rt)?))
    }

    /// The pointer moved to `ray` with the button held: each active drag sensor sends
    /// `trackPoint_changed` and its `translation_changed` or `rotation_changed` (the offset, and
    /// the limits, as the standard says). Returns whether `rt`'s scene changed.
    pub fn pointer_drag(&mut self, ray: PointerRay, time: f64, rt: &mut Context) -> Result<bool, SceneFileError> {
        let time = self.event_time(time);
        // A sensor disabled while active stops (isActive FALSE) and tracks no more.
        let (on, off): (Vec<_>, Vec<_>) =
            std::mem::take(&mut self.sensing.active).into_iter().partition(|(r, _)| self.flag(*r, "enabled", true));
        self.sensing.active = on;
        for (r, _) in off {
            self.send(r, vec![("isActive", EventValue::Bool(false))], time);
        }
        for k in 0..self.sensing.active.len() {
            let (r, drag) = self.sensing.active[k];
            let (drag, events) = self.track(r, drag, ray);
            self.sensing.active[k].1 = drag;
            if !events.is_empty() {
                self.send(r, events, time);
            }
        }
        self.apply(rt)
    }

    /// What drag sensor `r` sends for the pointer along `ray`, and its new state.
    fn track(&self, r: NodeRef, drag: Drag, ray: PointerRay) -> (Drag, Vec<(&'static str, EventValue)>) {
        let local = |m: Affine3A| {
            (Vec3::from(m.transform_point3a(ray.origin)), Vec3::from(m.transform_vector3a(ray.direction)))
        };
        match drag {
            Drag::Touch => (drag, Vec::new()),
            Drag::Plane { local_from_world, start, .. } => {
                let (o, d) = local(local_from_world);
                let Some(p) = on_plane(o, d, 2, start.z) else { return (drag, Vec::new()) };
                let mut t = p - start + self.vector(r, "offset", Vec3::ZERO);
                let (min, max) =
                    (self.vector2(r, "minPosition", Vec2::ZERO), self.vector2(r, "maxPosition", Vec2::NEG_ONE));
                // A limit applies where the minimum is not above the maximum.
                if min.x <= max.x {
                    t.x = t.x.clamp(min.x, max.x);
                }
                if min.y <= max.y {
                    t.y = t.y.clamp(min.y, max.y);
                }
                let events =
                    vec![("trackPoint_changed", EventValue::Vec3(p)), ("translation_changed", EventValue::Vec3(t))];
                (Drag::Plane { local_from_world, start, last: Some(t) }, events)
            }
            Drag::Sphere { local_from_world, start, .. } => {
                let (o, d) = local(local_from_world);
                let Some(p) = on_sphere(o, d, start.length()) else { return (drag, Vec::new()) };
                let offset = match self.sensor_field(r, "offset", EventType::SFRotation) {
                    Some(EventValue::Rotation(q)) => quat_of(q),
                    _ => Quat::IDENTITY,
                };
                let turn = Quat::from_rotation_arc(start.normalize_or(Vec3::Z), p.normalize_or(Vec3::Z));
                let q = (turn * offset).normalize();
                let events = vec![
                    ("trackPoint_changed", EventValue::Vec3(p)),
                    ("rotation_changed", EventValue::Rotation(rotation_of(q))),
                ];
                (Drag::Sphere { local_from_world, start, last: Some(q) }, events)
            }
            Drag::Cylinder { local_from_world, start, disk, .. } => {
                let (o, d) = local(local_from_world);
                let radius = Vec2::new(start.x, start.z).length();
                let p = if disk { on_plane(o, d, 1, start.y) } else { on_cylinder(o, d, radius) };
                let Some(p) = p else { return (drag, Vec::new()) };
                let turn = angle_about_y(p) - angle_about_y(start);
                // The shorter way round from where the press was.
                let turn = (turn + std::f32::consts::PI).rem_euclid(std::f32::consts::TAU) - std::f32::consts::PI;
                let mut angle = turn + self.number(r, "offset", 0.0);
                let (min, max) = (self.number(r, "minAngle", 0.0), self.number(r, "maxAngle", -1.0));
                if min <= max {
                    angle = angle.clamp(min, max);
                }
                let events = vec![
                    ("trackPoint_changed", EventValue::Vec3(p)),
                    ("rotation_changed", EventValue::Rotation([0.0, 1.0, 0.0, angle])),
                ];
                (Drag::Cylinder { local_from_world, start, disk, last: Some(angle) }, events)
            }
        }
    }

    /// The button released with the pointer at `hit` (`None`: over no shape): the active sensors
    /// send `isActive` FALSE; a TouchSensor the pointer is still over sends `touchTime`; a drag
    /// sensor with `autoOffset` keeps its last value as its `offset` (and sends
    /// `offset_changed`). Returns whether `rt`'s scene changed.
    pub fn pointer_release(
        &mut self,
        hit: Option<&PointerHit>,
        time: f64,
        rt: &mut Context,
    ) -> Result<bool, SceneFileError> {
        let time = self.event_time(time);
        let over: Vec<NodeRef> = match hit {
            Some(h) => self.pointing_sensors(rt, h.instance).0,
            None => Vec::new(),
        };
        for (r, drag) in std::mem::take(&mut self.sensing.active) {
            let mut events = vec![("isActive", EventValue::Bool(false))];
            let offset = match drag {
                Drag::Touch => {
                    if over.contains(&r) {
                        events.push(("touchTime", EventValue::Time(time)));
                    }
                    None
                }
                Drag::Plane { last, .. } => last.map(EventValue::Vec3),
                Drag::Sphere { last, .. } => last.map(|q| EventValue::Rotation(rotation_of(q))),
                Drag::Cylinder { last, .. } => last.map(EventValue::Float),
            };
            if let Some(offset) = offset.filter(|_| self.flag(r, "autoOffset", true)) {
                self.events.set_field(&mut self.documents, r, "offset", &offset);
                events.push(("offset", offset));
            }
            self.send(r, events, time);
        }
        self.hover(hit, time, rt);
        self.apply(rt)
    }

    /// The ProximitySensors and VisibilitySensors against `rt`'s camera at `time`.
    pub(super) fn sense_camera(&mut self, time: f64, rt: &mut Context) {
        let camera = *rt.camera();
        let (width, height) = (rt.options.width.max(1) as f32, rt.options.height.max(1) as f32);
        let tan = (camera.fov_degrees.to_radians() * 0.5).tan();
        let (tan_x, tan_y) = if width >= height { (tan * width / height, tan) } else { (tan, tan * height / width) };
        let camera_from_world = camera.world_from_camera.inverse();
        for k in 0..self.sensors.len() {
            let (r, path) = (self.sensors[k].node, self.sensors[k].path.clone());
            let kind = self.type_of(r).to_string();
            let world = build::world_of(rt, self, &path);
            self.sensors[k].world = world;
            let (center, size) = (self.vector(r, "center", Vec3::ZERO), self.vector(r, "size", Vec3::ZERO));
            let enabled = self.flag(r, "enabled", true);
            if kind == "ProximitySensor" {
                let local_from_world = world.inverse();
                let eye = Vec3::from(local_from_world.transform_point3a(camera.eye()));
                let half = size * 0.5;
                let inside = enabled
                    && size.cmpgt(Vec3::ZERO).all()
                    && (eye - center).abs().cmple(half).all()
                    && local_from_world.is_finite();
                let was = self.sensing.inside.get(&r).copied();
                let mut events = Vec::new();
                if inside {
                    let forward =
                        Vec3::from(local_from_world.transform_vector3a(camera.world_from_camera.matrix3.z_axis));
                    let up = Vec3::from(local_from_world.transform_vector3a(camera.world_from_camera.matrix3.y_axis));
                    let back = -forward.normalize_or(Vec3::NEG_Z);
                    let right = up.cross(back).normalize_or(Vec3::X);
                    let up = back.cross(right);
                    let orientation = rotation_of(Quat::from_mat3(&glam::Mat3::from_cols(right, up, back)));
                    if was.is_none() {
                        events.push(("isActive", EventValue::Bool(true)));
                        events.push(("enterTime", EventValue::Time(time)));
                    }
                    if was.map(|w| w.0) != Some(eye) {
                        events.push(("position_changed", EventValue::Vec3(eye)));
                    }
                    if was.map(|w| w.1) != Some(orientation) {
                        events.push(("orientation_changed", EventValue::Rotation(orientation)));
                    }
                    self.sensing.inside.insert(r, (eye, orientation));
                } else if was.is_some() {
                    events.push(("isActive", EventValue::Bool(false)));
                    events.push(("exitTime", EventValue::Time(time)));
                    self.sensing.inside.remove(&r);
                }
                if !events.is_empty() {
                    self.send(r, events, time);
                }
            } else {
                let corners = (0..8).map(|i| {
                    let c = Vec3::new(
                        if i & 1 == 0 { -0.5 } else { 0.5 },
                        if i & 2 == 0 { -0.5 } else { 0.5 },
                        if i & 4 == 0 { -0.5 } else { 0.5 },
                    );
                    camera_from_world.transform_point3a(world.transform_point3a(Vec3A::from(center + c * size)))
                });
                let corners: Vec<Vec3A> = corners.collect();
                // Wholly outside one plane of the frustum: out of view.
                let outside = |f: &dyn Fn(Vec3A) -> bool| corners.iter().all(|&c| f(c));
                let out = outside(&|c| c.z < camera.near)
                    || outside(&|c| c.x > tan_x * c.z)
                    || outside(&|c| c.x < -tan_x * c.z)
                    || outside(&|c| c.y > tan_y * c.z)
                    || outside(&|c| c.y < -tan_y * c.z);
                let visible = enabled && size.cmpgt(Vec3::ZERO).any() && size.cmpge(Vec3::ZERO).all() && !out;
                let was = self.sensing.visible.contains(&r);
                if visible && !was {
                    self.sensing.visible.insert(r);
                    self.send(
                        r,
                        vec![("isActive", EventValue::Bool(true)), ("enterTime", EventValue::Time(time))],
                        time,
                    );
                } else if !visible && was {
                    self.sensing.visible.remove(&r);
                    self.send(
                        r,
                        vec![("isActive", EventValue::Bool(false)), ("exitTime", EventValue::Time(time))],
                        time,
                    );
                }
            }
        }
    }

    /// Forgets what the proximity and visibility sensors sensed (the scene starts over).
    pub(super) fn reset_sensing(&mut self) {
        self.sensing.inside.clear();
        self.sensing.visible.clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::vrml::build_str;
    use std::path::Path;

    fn load(text: &str) -> (Context, VrmlScene) {
        let mut rt = Context::new();
        let scene = build_str(&mut rt, &format!("#VRML V2.0 utf8\n{text}"), Path::new("test.wrl"))
            .unwrap_or_else(|e| panic!("{e}"));
        (rt, scene)
    }

    fn field(scene: &VrmlScene, def: &str, name: &str, ty: EventType) -> Option<EventValue> {
        let doc = &scene.documents[0].1;
        EventValue::from_value(&doc.node(doc.defs[def]).field(name)?.value, ty)
    }

    fn ray(origin: [f32; 3], direction: [f32; 3]) -> PointerRay {
        PointerRay { origin: Vec3A::from_array(origin), direction: Vec3A::from_array(direction) }
    }

    /// The hit of a ray along -z from `(x, y, 10)` on shape `shape`'s front face at z = `z`.
    fn front(scene: &VrmlScene, shape: usize, x: f32, y: f32, z: f32) -> PointerHit {
        PointerHit {
            instance: scene.shapes[shape].made,
            point: Vec3A::new(x, y, z),
            normal: Vec3A::Z,
            tex_coord: Vec2::new(0.25, 0.75),
        }
    }

    #[test]
    fn a_touch_sensor_tells_when_the_pointer_is_over_it_and_where() {
        let (mut rt, mut scene) = load(
            "DEF G Transform { translation 1 0 0 children [ DEF Touch TouchSensor {} Shape { geometry Box {} } ] }
             Shape { geometry Sphere {} }
             DEF Marker Transform {}
             DEF L PointLight { on FALSE }
             ROUTE Touch.isOver TO L.on
             ROUTE Touch.hitPoint_changed TO Marker.set_translation
             ROUTE Touch.hitNormal_changed TO Marker.set_scale",
        );
        assert!(scene.senses() && scene.take_warnings().is_empty());
        let on = |scene: &VrmlScene| field(scene, "L", "on", EventType::SFBool);
        let over = front(&scene, 0, 1.5, 0.25, 1.0);
        assert!(scene.pointer_move(Some(&over), 0.0, &mut rt).expect("runs"));
        assert_eq!(on(&scene), Some(EventValue::Bool(true)));
        // The hit point in the sensor's space: the Transform's translation taken off.
        assert_eq!(
            field(&scene, "Marker", "translation", EventType::SFVec3f),
            Some(EventValue::Vec3(Vec3::new(0.5, 0.25, 1.0)))
        );
        assert_eq!(field(&scene, "Marker", "scale", EventType::SFVec3f), Some(EventValue::Vec3(Vec3::Z)));
        // Over the sphere, which no sensor senses: isOver FALSE.
        let sphere = front(&scene, 1, 0.0, 0.0, 1.0);
        scene.pointer_move(Some(&sphere), 0.1, &mut rt).expect("runs");
        assert_eq!(on(&scene), Some(EventValue::Bool(false)));
        // A press and a release over the box: isActive, then touchTime.
        scene.pointer_move(Some(&over), 0.2, &mut rt).expect("runs");
        let (grabbed, _) =
            scene.pointer_press(&over, ray([1.5, 0.25, 10.0], [0.0, 0.0, -1.0]), 0.3, &mut rt).expect("runs");
        assert!(!grabbed, "a TouchSensor does not take the pointer's drags");
        scene.pointer_release(None, 0.4, &mut rt).expect("runs");
        assert!(scene.sensing.over.is_empty(), "released over nothing");
    }

    const PLANE: &str = "
        DEF T Transform { children [ DEF Drag PlaneSensor { } Shape { geometry Box { } } ] }";

    #[test]
    fn a_plane_sensor_drags_its_transform_in_its_plane() {
        let (mut rt, mut scene) = load(&format!("{PLANE} ROUTE Drag.translation_changed TO T.set_translation"));
        let instance = scene.shapes[0].made;
        let hit = front(&scene, 0, 0.0, 0.0, 1.0);
        let (grabbed, _) =
            scene.pointer_press(&hit, ray([0.0, 0.0, 10.0], [0.0, 0.0, -1.0]), 0.0, &mut rt).expect("runs");
        assert!(grabbed);
        // The pointer's ray now from the eye at (0, 0, 10) through (2, 1, 1): the plane z = 1.
        assert!(scene.pointer_drag(ray([0.0, 0.0, 10.0], [2.0, 1.0, -9.0]), 0.1, &mut rt).expect("runs"));
        let m = rt.instance_transform(instance).expect("placed");
        assert!(m.translation.abs_diff_eq(Vec3A::new(2.0, 1.0, 0.0), 1e-5), "{m:?}");
        scene.pointer_release(None, 0.2, &mut rt).expect("runs");
        assert_eq!(
            field(&scene, "Drag", "offset", EventType::SFVec3f),
            Some(EventValue::Vec3(Vec3::new(2.0, 1.0, 0.0)))
        );
        // A second drag goes on from there (autoOffset), the box pressed where it now stands.
        let hit = front(&scene, 0, 2.0, 1.0, 1.0);
        scene.pointer_press(&hit, ray([0.0, 0.0, 10.0], [2.0, 1.0, -9.0]), 0.3, &mut rt).expect("runs");
        scene.pointer_drag(ray([0.0, 0.0, 10.0], [-1.0, 1.0, -9.0]), 0.4, &mut rt).expect("runs");
        let m = rt.instance_transform(instance).expect("placed");
        assert!(m.translation.abs_diff_eq(Vec3A::new(-1.0, 1.0, 0.0), 1e-5), "{m:?}");
        scene.pointer_release(None, 0.5, &mut rt).expect("runs");

        // Limits: x between -1 and 1, y held at 0.
        let (mut rt, mut scene) = load(&format!(
            "{} ROUTE Drag.translation_changed TO T.set_translation",
            PLANE.replace("PlaneSensor { }", "PlaneSensor { minPosition -1 0 maxPosition 1 0 }")
        ));
        let hit = front(&scene, 0, 0.0, 0.0, 1.0);
        scene.pointer_press(&hit, ray([0.0, 0.0, 10.0], [0.0, 0.0, -1.0]), 0.0, &mut rt).expect("runs");
        scene.pointer_drag(ray([0.0, 0.0, 10.0], [3.0, 2.0, -9.0]), 0.1, &mut rt).expect("runs");
        let m = rt.instance_transform(scene.shapes[0].made).expect("placed");
        assert!(m.translation.abs_diff_eq(Vec3A::new(1.0, 0.0, 0.0), 1e-5), "{m:?}");
        // Disabled while active: it stops, and the drag moves nothing more.
        let drag = NodeRef { doc: 0, node: scene.documents[0].1.defs["Drag"] };
        scene.events.set_field(&mut scene.documents, drag, "enabled", &EventValue::Bool(false));
        scene.pointer_drag(ray([0.0, 0.0, 10.0], [-3.0, 0.0, -9.0]), 0.2, &mut rt).expect("runs");
        assert!(scene.sensing.active.is_empty());
        let m = rt.instance_transform(scene.shapes[0].made).expect("placed");
        assert!(m.translation.abs_diff_eq(Vec3A::new(1.0, 0.0, 0.0), 1e-5), "{m:?}");
    }

    #[test]
    fn sphere_and_cylinder_sensors_turn_their_transforms() {
        let (mut rt, mut scene) = load(
            "DEF T Transform { children [ DEF Ball SphereSensor { } Shape { geometry Sphere { } } ] }
             ROUTE Ball.rotation_changed TO T.set_rotation",
        );
        let hit = front(&scene, 0, 0.0, 0.0, 1.0);
        scene.pointer_press(&hit, ray([0.0, 0.0, 10.0], [0.0, 0.0, -1.0]), 0.0, &mut rt).expect("runs");
        // To the sphere's point at 45 degrees to the right: a turn of 45 degrees about +y.
        let s = std::f32::consts::FRAC_1_SQRT_2;
        scene.pointer_drag(ray([s, 0.0, 10.0], [0.0, 0.0, -1.0]), 0.1, &mut rt).expect("runs");
        let m = rt.instance_transform(scene.shapes[0].made).expect("placed");
        let turned = m.transform_vector3a(Vec3A::Z);
        assert!(turned.abs_diff_eq(Vec3A::new(s, 0.0, s), 1e-4), "{turned}");

        let (mut rt, mut scene) = load(
            "DEF T Transform { children [ DEF Knob CylinderSensor { maxAngle 0.5 } Shape { geometry Cylinder { } } ] }
             ROUTE Knob.rotation_changed TO T.set_rotation",
        );
        // Seen from the side (far from the axis): the cylinder of radius 1 through the press.
        let hit = front(&scene, 0, 0.0, 0.0, 1.0);
        scene.pointer_press(&hit, ray([0.0, 0.0, 10.0], [0.0, 0.0, -1.0]), 0.0, &mut rt).expect("runs");
        scene.pointer_drag(ray([0.25_f32.sin(), 0.0, 10.0], [0.0, 0.0, -1.0]), 0.1, &mut rt).expect("runs");
        let Some(EventValue::Rotation(r)) = field(&scene, "T", "rotation", EventType::SFRotation) else {
            panic!("turned")
        };
        assert!((r[3] - 0.25).abs() < 1e-4 && r[1] > 0.99, "{r:?}");
        // Past maxAngle it stops there (minAngle 0 is below it).
        scene.pointer_drag(ray([0.9, 0.0, 10.0], [0.0, 0.0, -1.0]), 0.2, &mut rt).expect("runs");
        let Some(EventValue::Rotation(r)) = field(&scene, "T", "rotation", EventType::SFRotation) else {
            panic!("turned")
        };
        assert!((r[3] - 0.5).abs() < 1e-5, "{r:?}");
        // Looking down the axis: a disk in the plane y = 1, a dial.
        scene.pointer_release(None, 0.3, &mut rt).expect("runs");
        let top = PointerHit { point: Vec3A::new(0.0, 1.0, 0.5), normal: Vec3A::Y, ..front(&scene, 0, 0.0, 0.0, 0.0) };
        scene.pointer_press(&top, ray([0.0, 10.0, 0.5], [0.0, -1.0, 0.0]), 0.4, &mut rt).expect("runs");
        assert!(matches!(scene.sensing.active[0].1, Drag::Cylinder { disk: true, .. }));
    }

    #[test]
    fn a_proximity_sensor_senses_the_camera_and_a_visibility_sensor_the_view() {
        let (mut rt, mut scene) = load(
            "Viewpoint { position 0 0 10 }
             DEF Near Transform { translation 0 0 10 children DEF P ProximitySensor { size 4 4 4 } }
             DEF Seen VisibilitySensor { center 0 0 0 size 1 1 1 }
             DEF Behind VisibilitySensor { center 0 0 20 size 1 1 1 }
             DEF L PointLight { on FALSE }
             DEF L2 PointLight { on FALSE }
             DEF L3 PointLight { on TRUE }
             DEF Where Transform {}
             ROUTE P.isActive TO L.on
             ROUTE P.position_changed TO Where.set_translation
             ROUTE Seen.isActive TO L2.on
             ROUTE Behind.isActive TO L3.on",
        );
        assert!(scene.senses());
        rt.options.width = 32;
        rt.options.height = 24;
        let on = |scene: &VrmlScene, l: &str| field(scene, l, "on", EventType::SFBool);
        scene.advance_to(0.0, &mut rt).expect("runs");
        assert_eq!(on(&scene, "L"), Some(EventValue::Bool(true)), "the camera is in the box");
        assert_eq!(field(&scene, "Where", "translation", EventType::SFVec3f), Some(EventValue::Vec3(Vec3::ZERO)));
        assert_eq!(on(&scene, "L2"), Some(EventValue::Bool(true)), "the box ahead is seen");
        assert_eq!(on(&scene, "L3"), Some(EventValue::Bool(true)), "nothing was sent for the box behind");
        // The camera moves out of the box, and turns round.
        rt.camera_look_at(Vec3A::new(0.0, 0.0, 14.0), Vec3A::new(0.0, 0.0, 20.0), Vec3A::Y, 45.0);
        scene.advance_to(1.0, &mut rt).expect("runs");
        assert_eq!(on(&scene, "L"), Some(EventValue::Bool(false)));
        assert_eq!(on(&scene, "L2"), Some(EventValue::Bool(false)), "the box at the origin is behind now");
        // Back into the box, 1 to the right of its centre.
        rt.camera_look_at(Vec3A::new(1.0, 0.0, 10.0), Vec3A::new(1.0, 0.0, 0.0), Vec3A::Y, 45.0);
        scene.advance_to(2.0, &mut rt).expect("runs");
        assert_eq!(on(&scene, "L"), Some(EventValue::Bool(true)));
        assert_eq!(field(&scene, "Where", "translation", EventType::SFVec3f), Some(EventValue::Vec3(Vec3::X)));
    }
}
