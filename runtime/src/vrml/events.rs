//! VRML 97 events (ISO/IEC 14772-1, 4.10 and 4.11): `ROUTE`s, TimeSensors, the interpolators and
//! exposed fields, run on the parsed documents.
//!
//! [`Events`] resolves a scene's routes once (a route naming an event the node type does not have,
//! or joining events of different types, is a warning and is not run), then runs one timestamp at a
//! time ([`Events::advance`]): each TimeSensor that is the source of a route is evaluated at the
//! new time, and the events it sends cascade along the routes. An event into an exposed field
//! writes the field's value into the document (the original is kept for [`Events::reset`]) and
//! sends `_changed`; the nodes whose fields changed are collected in [`Events::dirty`] for the
//! caller to show (`super::animate`). As the standard says, an eventOut sends at most one event
//! per timestamp, which breaks loops of routes; a cascade is also bounded by
//! [`VRML_EVENT_BUDGET`].
//!
//! Time is the file's: seconds, `now` being the time asked for. The world loads at time 0, an
//! instant after every `startTime` of 0 or less: as in a browser (whose clock counts from 1970), a
//! looping TimeSensor that started then is running, with its cycles counted from its startTime, and
//! a non-looping one has finished.

use super::parse::{Document, Field, Value};
use super::{location, Loc, NodeRef};
use crate::rib::{RibDiagnostic, Severity};
use glam::{Quat, Vec3};
use std::collections::{BTreeSet, HashMap, HashSet, VecDeque};
use std::path::Path;
use std::sync::Arc;

/// How many events one timestamp's cascade may deliver, all routes together; the rest of the
/// cascade is dropped with a warning.
pub const VRML_EVENT_BUDGET: usize = 1 << 16;

/// The type of a field or event.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum EventType {
    SFBool,
    SFInt32,
    SFFloat,
    SFTime,
    SFVec2f,
    SFVec3f,
    SFColor,
    SFRotation,
    MFFloat,
    MFVec3f,
    MFColor,
    MFRotation,
}

/// How a node's interface member is reached.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Access {
    ExposedField,
    EventIn,
    EventOut,
}

use Access::{EventIn, EventOut, ExposedField};
use EventType::*;

type Interface = &'static [(&'static str, Access, EventType)];

const INTERPOLATOR_FRACTION: (&str, Access, EventType) = ("set_fraction", EventIn, SFFloat);

/// The events of the node types this module runs: the animated fields of nodes the scene shows
/// (Transform, Material, Coordinate, Normal, Color, Switch, the lights, Viewpoint), the sensors
/// and the interpolators.
fn interface(type_name: &str) -> Option<Interface> {
    Some(match type_name {
        "TimeSensor" => &[
            ("cycleInterval", ExposedField, SFTime),
            ("enabled", ExposedField, SFBool),
            ("loop", ExposedField, SFBool),
            ("startTime", ExposedField, SFTime),
            ("stopTime", ExposedField, SFTime),
            ("cycleTime", EventOut, SFTime),
            ("fraction_changed", EventOut, SFFloat),
            ("isActive", EventOut, SFBool),
            ("time", EventOut, SFTime),
        ],
        "TouchSensor" => &[
            ("enabled", ExposedField, SFBool),
            ("isActive", EventOut, SFBool),
            ("isOver", EventOut, SFBool),
            ("touchTime", EventOut, SFTime),
            ("hitPoint_changed", EventOut, SFVec3f),
            ("hitNormal_changed", EventOut, SFVec3f),
            ("hitTexCoord_changed", EventOut, SFVec2f),
        ],
        "PlaneSensor" => &[
            ("autoOffset", ExposedField, SFBool),
            ("enabled", ExposedField, SFBool),
            ("maxPosition", ExposedField, SFVec2f),
            ("minPosition", ExposedField, SFVec2f),
            ("offset", ExposedField, SFVec3f),
            ("isActive", EventOut, SFBool),
            ("trackPoint_changed", EventOut, SFVec3f),
            ("translation_changed", EventOut, SFVec3f),
        ],
        "SphereSensor" => &[
            ("autoOffset", ExposedField, SFBool),
            ("enabled", ExposedField, SFBool),
            ("offset", ExposedField, SFRotation),
            ("isActive", EventOut, SFBool),
            ("rotation_changed", EventOut, SFRotation),
            ("trackPoint_changed", EventOut, SFVec3f),
        ],
        "CylinderSensor" => &[
            ("autoOffset", ExposedField, SFBool),
            ("diskAngle", ExposedField, SFFloat),
            ("enabled", ExposedField, SFBool),
            ("maxAngle", ExposedField, SFFloat),
            ("minAngle", ExposedField, SFFloat),
            ("offset", ExposedField, SFFloat),
            ("isActive", EventOut, SFBool),
            ("rotation_changed", EventOut, SFRotation),
            ("trackPoint_changed", EventOut, SFVec3f),
        ],
        "ProximitySensor" => &[
            ("center", ExposedField, SFVec3f),
            ("size", ExposedField, SFVec3f),
            ("enabled", ExposedField, SFBool),
            ("isActive", EventOut, SFBool),
            ("position_changed", EventOut, SFVec3f),
            ("orientation_changed", EventOut, SFRotation),
            ("enterTime", EventOut, SFTime),
            ("exitTime", EventOut, SFTime),
        ],
        "VisibilitySensor" => &[
            ("center", ExposedField, SFVec3f),
            ("enabled", ExposedField, SFBool),
            ("size", ExposedField, SFVec3f),
            ("enterTime", EventOut, SFTime),
            ("exitTime", EventOut, SFTime),
            ("isActive", EventOut, SFBool),
        ],
        "PositionInterpolator" => &[
            INTERPOLATOR_FRACTION,
            ("key", ExposedField, MFFloat),
            ("keyValue", ExposedField, MFVec3f),
            ("value_changed", EventOut, SFVec3f),
        ],
        "OrientationInterpolator" => &[
            INTERPOLATOR_FRACTION,
            ("key", ExposedField, MFFloat),
            ("keyValue", ExposedField, MFRotation),
            ("value_changed", EventOut, SFRotation),
        ],
        "ScalarInterpolator" => &[
            INTERPOLATOR_FRACTION,
            ("key", ExposedField, MFFloat),
            ("keyValue", ExposedField, MFFloat),
            ("value_changed", EventOut, SFFloat),
        ],
        "ColorInterpolator" => &[
            INTERPOLATOR_FRACTION,
            ("key", ExposedField, MFFloat),
            ("keyValue", ExposedField, MFColor),
            ("value_changed", EventOut, SFColor),
        ],
        "CoordinateInterpolator" | "NormalInterpolator" => &[
            INTERPOLATOR_FRACTION,
            ("key", ExposedField, MFFloat),
            ("keyValue", ExposedField, MFVec3f),
            ("value_changed", EventOut, MFVec3f),
        ],
        "Transform" => &[
            ("center", ExposedField, SFVec3f),
            ("rotation", ExposedField, SFRotation),
            ("scale", ExposedField, SFVec3f),
            ("scaleOrientation", ExposedField, SFRotation),
            ("translation", ExposedField, SFVec3f),
        ],
        "Material" => &[
            ("ambientIntensity", ExposedField, SFFloat),
            ("diffuseColor", ExposedField, SFColor),
            ("emissiveColor", ExposedField, SFColor),
            ("shininess", ExposedField, SFFloat),
            ("specularColor", ExposedField, SFColor),
            ("transparency", ExposedField, SFFloat),
        ],
        "Coordinate" => &[("point", ExposedField, MFVec3f)],
        "Normal" => &[("vector", ExposedField, MFVec3f)],
        "Color" => &[("color", ExposedField, MFColor)],
        "PointLight" => &[
            ("ambientIntensity", ExposedField, SFFloat),
            ("attenuation", ExposedField, SFVec3f),
            ("color", ExposedField, SFColor),
            ("intensity", ExposedField, SFFloat),
            ("location", ExposedField, SFVec3f),
            ("on", ExposedField, SFBool),
            ("radius", ExposedField, SFFloat),
        ],
        "SpotLight" => &[
            ("ambientIntensity", ExposedField, SFFloat),
            ("attenuation", ExposedField, SFVec3f),
            ("beamWidth", ExposedField, SFFloat),
            ("color", ExposedField, SFColor),
            ("cutOffAngle", ExposedField, SFFloat),
            ("direction", ExposedField, SFVec3f),
            ("intensity", ExposedField, SFFloat),
            ("location", ExposedField, SFVec3f),
            ("on", ExposedField, SFBool),
            ("radius", ExposedField, SFFloat),
        ],
        "DirectionalLight" => &[
            ("ambientIntensity", ExposedField, SFFloat),
            ("color", ExposedField, SFColor),
            ("direction", ExposedField, SFVec3f),
            ("intensity", ExposedField, SFFloat),
            ("on", ExposedField, SFBool),
        ],
        "Viewpoint" => &[
            ("fieldOfView", ExposedField, SFFloat),
            ("orientation", ExposedField, SFRotation),
            ("position", ExposedField, SFVec3f),
        ],
        "Switch" => &[("whichChoice", ExposedField, SFInt32)],
        _ => return None,
    })
}

/// The eventIn `name` of a node type: its canonical name (an exposed field's own name for `x` and
/// `set_x`) and type.
pub fn event_in(type_name: &str, name: &str) -> Option<(&'static str, EventType)> {
    let iface = interface(type_name)?;
    let base = name.strip_prefix("set_");
    iface.iter().find_map(|&(n, access, ty)| match access {
        EventIn if n == name => Some((n, ty)),
        ExposedField if n == name || base == Some(n) => Some((n, ty)),
        _ => None,
    })
}

/// The eventOut `name` of a node type: its canonical name (an exposed field's own name for `x` and
/// `x_changed`) and type.
pub fn event_out(type_name: &str, name: &str) -> Option<(&'static str, EventType)> {
    let iface = interface(type_name)?;
    let base = name.strip_suffix("_changed");
    iface.iter().find_map(|&(n, access, ty)| match access {
        EventOut if n == name => Some((n, ty)),
        ExposedField if n == name || base == Some(n) => Some((n, ty)),
        _ => None,
    })
}

/// The value an event carries.
#[derive(Clone, Debug, PartialEq)]
pub enum EventValue {
    Bool(bool),
    Int(i32),
    Float(f32),
    Time(f64),
    Vec2(glam::Vec2),
    /// `SFVec3f` and `SFColor`.
    Vec3(Vec3),
    /// An `SFRotation`: axis and angle.
    Rotation([f32; 4]),
    Floats(Vec<f32>),
    /// `MFVec3f` and `MFColor`.
    Vec3s(Vec<Vec3>),
    Rotations(Vec<[f32; 4]>),
}

impl EventValue {
    /// The value as a field of a document holds it.
    pub fn to_value(&self) -> Value {
        let numbers = |v: Vec<f64>| if v.is_empty() { Value::Empty } else { Value::Numbers(v) };
        match self {
            EventValue::Bool(b) => Value::Bools(vec![*b]),
            EventValue::Int(i) => Value::Numbers(vec![f64::from(*i)]),
            EventValue::Float(f) => Value::Numbers(vec![f64::from(*f)]),
            EventValue::Time(t) => Value::Numbers(vec![*t]),
            EventValue::Vec2(v) => Value::Numbers(v.to_array().map(f64::from).to_vec()),
            EventValue::Vec3(v) => Value::Numbers(v.to_array().map(f64::from).to_vec()),
            EventValue::Rotation(r) => Value::Numbers(r.map(f64::from).to_vec()),
            EventValue::Floats(v) => numbers(v.iter().map(|&x| f64::from(x)).collect()),
            EventValue::Vec3s(v) => numbers(v.iter().flat_map(|p| p.to_array()).map(f64::from).collect()),
            EventValue::Rotations(v) => numbers(v.iter().flatten().map(|&x| f64::from(x)).collect()),
        }
    }

    /// A field's value read as `ty`; `None` when it is not one (or not finite).
    pub fn from_value(value: &Value, ty: EventType) -> Option<EventValue> {
        let numbers: &[f64] = match value {
            Value::Numbers(n) => n,
            Value::Empty => &[],
            Value::Bools(b) if ty == SFBool && b.len() == 1 => return Some(EventValue::Bool(b[0])),
            _ => return None,
        };
        if numbers.iter().any(|x| !x.is_finite()) {
            return None;
        }
        let f = |x: f64| x as f32;
        let v3 = |c: &[f64]| Vec3::new(f(c[0]), f(c[1]), f(c[2]));
        let r4 = |c: &[f64]| [f(c[0]), f(c[1]), f(c[2]), f(c[3])];
        match (ty, numbers.len()) {
            (SFInt32, 1) if numbers[0].fract() == 0.0 && numbers[0].abs() <= f64::from(i32::MAX) => {
                Some(EventValue::Int(numbers[0] as i32))
            }
            (SFFloat, 1) => Some(EventValue::Float(f(numbers[0]))),
            (SFTime, 1) => Some(EventValue::Time(numbers[0])),
            (SFVec2f, 2) => Some(EventValue::Vec2(glam::Vec2::new(f(numbers[0]), f(numbers[1])))),
            (SFVec3f | SFColor, 3) => Some(EventValue::Vec3(v3(numbers))),
            (SFRotation, 4) => Some(EventValue::Rotation(r4(numbers))),
            (MFFloat, _) => Some(EventValue::Floats(numbers.iter().map(|&x| f(x)).collect())),
            (MFVec3f | MFColor, n) if n % 3 == 0 => Some(EventValue::Vec3s(numbers.chunks_exact(3).map(v3).collect())),
            (MFRotation, n) if n % 4 == 0 => Some(EventValue::Rotations(numbers.chunks_exact(4).map(r4).collect())),
            _ => None,
        }
    }
}

/// Where `fraction` falls among `keys` (4.6.8): the keys' values `i` and `j` to mix, and how far
/// from `i` to `j` (0 to 1). Before the first key it is the first key's value, after the last the
/// last's; at keys that repeat (a jump), the later one's.
pub fn key_segment(keys: &[f32], fraction: f32) -> Option<(usize, usize, f32)> {
    let last = keys.len().checked_sub(1)?;
    // A NaN fraction takes the first value too.
    if fraction.is_nan() || fraction <= keys[0] {
        return Some((0, 0, 0.0));
    }
    if fraction >= keys[last] {
        return Some((last, last, 0.0));
    }
    // The last key at or below the fraction; the next is above it.
    let i = keys.partition_point(|&k| k <= fraction).saturating_sub(1).min(last);
    let j = (i + 1).min(last);
    let span = keys[j] - keys[i];
    let t = if span > 0.0 { ((fraction - keys[i]) / span).clamp(0.0, 1.0) } else { 0.0 };
    Some((i, j, t))
}

/// An `SFRotation` as a unit quaternion (a zero axis is no rotation).
pub fn quat_of(r: [f32; 4]) -> Quat {
    let axis = Vec3::new(r[0], r[1], r[2]);
    if axis.length_squared() < 1e-20 || !r[3].is_finite() {
        return Quat::IDENTITY;
    }
    Quat::from_axis_angle(axis.normalize(), r[3])
}

/// A unit quaternion as an `SFRotation` (axis and angle; no rotation about +z).
pub fn rotation_of(q: Quat) -> [f32; 4] {
    let (axis, angle) = q.normalize().to_axis_angle();
    if angle.abs() < 1e-9 || !axis.is_finite() {
        return [0.0, 0.0, 1.0, 0.0];
    }
    [axis.x, axis.y, axis.z, angle]
}

/// Spherical linear interpolation from `a` to `b` along the shorter arc (6.32: rotations more
/// than half a turn apart are interpolated along the arc's complement).
pub fn slerp(a: Quat, b: Quat, t: f32) -> Quat {
    let b = if a.dot(b) < 0.0 { -b } else { b };
    let cos = a.dot(b).clamp(-1.0, 1.0);
    if cos > 0.9995 {
        return a.lerp(b, t).normalize();
    }
    let theta = cos.acos();
    let sin = theta.sin();
    (a * (((1.0 - t) * theta).sin() / sin) + b * ((t * theta).sin() / sin)).normalize()
}

/// Spherical linear interpolation of directions (NormalInterpolator, 6.31), normalized.
fn slerp_direction(a: Vec3, b: Vec3, t: f32) -> Vec3 {
    let (a, b) = (a.normalize_or_zero(), b.normalize_or_zero());
    let cos = a.dot(b).clamp(-1.0, 1.0);
    if !(-0.9995..=0.9995).contains(&cos) {
        return a.lerp(b, t).normalize_or(a);
    }
    let theta = cos.acos();
    let sin = theta.sin();
    (a * (((1.0 - t) * theta).sin() / sin) + b * ((t * theta).sin() / sin)).normalize_or(a)
}

/// The value an interpolator of `type_name` sends for `fraction`, from its `key` and `keyValue`;
/// `None` when it has no keys or the values do not fit them.
pub fn interpolate(type_name: &str, keys: &[f32], values: &Value, fraction: f32) -> Option<EventValue> {
    let (i, j, t) = key_segment(keys, fraction)?;
    let (_, ty) = event_in(type_name, "keyValue")?;
    match (type_name, EventValue::from_value(values, ty)?) {
        ("ScalarInterpolator", EventValue::Floats(v)) if v.len() >= keys.len() => {
            Some(EventValue::Float(v[i] + (v[j] - v[i]) * t))
        }
        ("PositionInterpolator" | "ColorInterpolator", EventValue::Vec3s(v)) if v.len() >= keys.len() => {
            Some(EventValue::Vec3(v[i].lerp(v[j], t)))
        }
        ("OrientationInterpolator", EventValue::Rotations(v)) if v.len() >= keys.len() => {
            Some(EventValue::Rotation(rotation_of(slerp(quat_of(v[i]), quat_of(v[j]), t))))
        }
        ("CoordinateInterpolator" | "NormalInterpolator", EventValue::Vec3s(v)) => {
            // keyValue holds one list of values per key.
            let n = v.len() / keys.len();
            if n == 0 || v.len() % keys.len() != 0 {
                return None;
            }
            let (a, b) = (&v[i * n..(i + 1) * n], &v[j * n..(j + 1) * n]);
            let out = if type_name == "NormalInterpolator" {
                a.iter().zip(b).map(|(&p, &q)| slerp_direction(p, q, t)).collect()
            } else {
                a.iter().zip(b).map(|(&p, &q)| p.lerp(q, t)).collect()
            };
            Some(EventValue::Vec3s(out))
        }
        _ => None,
    }
}

/// A TimeSensor's fields, as they stand.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TimeSensor {
    pub cycle_interval: f64,
    pub enabled: bool,
    pub looping: bool,
    pub start: f64,
    pub stop: f64,
}

impl Default for TimeSensor {
    fn default() -> Self {
        TimeSensor { cycle_interval: 1.0, enabled: true, looping: false, start: 0.0, stop: 0.0 }
    }
}

impl TimeSensor {
    /// When it runs, from `startTime` (6.50): a looping sensor until `stopTime` (for ever when that
    /// is not after `startTime`), a non-looping one for one cycle or until an earlier `stopTime`.
    pub fn interval(&self) -> (f64, f64) {
        let stop = if self.stop > self.start { self.stop } else { f64::INFINITY };
        let end = if self.looping { stop } else { stop.min(self.start + self.cycle_interval) };
        (self.start, end)
    }

    /// `fraction_changed` at `now`: the part of the current cycle gone, 1 at the end of a cycle.
    pub fn fraction(&self, now: f64) -> f32 {
        let f = (now - self.start).rem_euclid(self.cycle_interval);
        if f == 0.0 && now > self.start {
            1.0
        } else {
            (f / self.cycle_interval) as f32
        }
    }

    /// The number of the cycle `now` is in, counting from 0 at `startTime`.
    fn cycle(&self, now: f64) -> i64 {
        ((now - self.start) / self.cycle_interval).floor().clamp(-1e15, 1e15) as i64
    }
}

/// A TimeSensor's state between timestamps.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct SensorState {
    active: bool,
    cycle: i64,
    /// The `startTime` of the last run that ended: a run is not repeated (at load, the runs of
    /// non-looping sensors that started at or before time 0 count as ended).
    ended: Option<f64>,
}

/// An eventOut of a node.
type Source = (NodeRef, &'static str);

/// The routes of a scene and the state of its sensors: see the module's documentation.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Events {
    /// Each eventOut's routes: the node and canonical eventIn each reaches.
    routes: HashMap<Source, Vec<(NodeRef, &'static str)>>,
    /// The TimeSensors that send events, in file order.
    sensors: Vec<NodeRef>,
    state: HashMap<NodeRef, SensorState>,
    /// The last timestamp run (`None`: none yet).
    now: Option<f64>,
    /// Whether events were sent ([`Events::send`]) since that timestamp ran.
    sent_since: bool,
    /// Each changed node's fields as the file had them.
    originals: HashMap<NodeRef, Vec<Field>>,
    /// The nodes whose fields changed since the caller last took them.
    pub dirty: BTreeSet<NodeRef>,
    /// Messages since the caller last took them.
    pub warnings: Vec<RibDiagnostic>,
    warned: HashSet<String>,
    /// Each document's file, for messages.
    files: Vec<Arc<Path>>,
}

/// A node's type, through `DEF` name `name` of `doc`; `None` for a PROTO instance.
fn def_type<'d>(doc: &'d Document, name: &str) -> Option<(super::parse::NodeId, &'d super::parse::Node)> {
    let id = *doc.defs.get(name)?;
    let node = doc.node(id);
    Some((id, node))
}

impl Events {
    /// Resolves the routes of `documents` (`files` names them in messages); what cannot be run
    /// is in [`Events::warnings`].
    pub fn new(documents: &[(std::path::PathBuf, Document)], files: &[Arc<Path>]) -> Events {
        let mut events = Events { files: files.to_vec(), ..Events::default() };
        for (d, (_, doc)) in documents.iter().enumerate() {
            for route in &doc.routes {
                if route.in_proto {
                    let key = format!("route:{d}:{}:{}", route.loc.line, route.loc.column);
                    events.warn(d, route.loc, &key, "a ROUTE inside a PROTO body is not run".into());
                    continue;
                }
                // A name no node has was warned about by the parser.
                let (Some((from, from_node)), Some((to, to_node))) =
                    (def_type(doc, &route.from.0), def_type(doc, &route.to.0))
                else {
                    continue;
                };
                let text = format!("ROUTE {}.{} TO {}.{}", route.from.0, route.from.1, route.to.0, route.to.1);
                let mut problem = None;
                for (node, name) in [(from_node, &route.from.0), (to_node, &route.to.0)] {
                    if node.expansion.is_some() || node.extern_proto.is_some() {
                        problem = problem.or(Some(format!("{name} is a PROTO instance, whose events are not run")));
                    }
                }
                for node in [from_node, to_node] {
                    if node.type_name == "Script" {
                        problem = problem.or(Some("Scripts are not run".to_string()));
                    }
                }
                let out = event_out(&from_node.type_name, &route.from.1);
                let inp = event_in(&to_node.type_name, &route.to.1);
                let describe = |node: &super::parse::Node, event: &str, dir: &str| {
                    let known = super::nodes::node_type(&node.type_name)
                        .is_some_and(|(_, fields)| super::nodes::knows_field(fields, event));
                    if known {
                        format!("{}'s {dir} `{event}` is not run", node.type_name)
                    } else {
                        format!("{} has no {dir} `{event}`", node.type_name)
                    }
                };
                if problem.is_none() {
                    problem = match (out, inp) {
                        (None, _) => Some(describe(from_node, &route.from.1, "eventOut")),
                        (_, None) => Some(describe(to_node, &route.to.1, "eventIn")),
                        (Some((_, a)), Some((_, b))) if a != b => {
                            Some(format!("it joins an {a:?} eventOut to an {b:?} eventIn"))
                        }
                        _ => None,
                    };
                }
                if let Some(why) = problem {
                    events.warn(d, route.loc, &format!("route:{d}:{}:{}", route.loc.line, route.loc.column), {
                        format!("{text}: {why}; the route is not run")
                    });
                    continue;
                }
                let (Some((out, _)), Some((inp, _))) = (out, inp) else { continue };
                let from = NodeRef { doc: d, node: from };
                let to = NodeRef { doc: d, node: to };
                let targets = events.routes.entry((from, out)).or_default();
                if !targets.contains(&(to, inp)) {
                    targets.push((to, inp));
                }
                if from_node.type_name == "TimeSensor" && !events.sensors.contains(&from) {
                    events.sensors.push(from);
                }
            }
        }
        events.sensors.sort();
        events.reset_state(documents);
        events
    }

    /// Whether anything runs with time: a TimeSensor sends events along a route.
    pub fn is_animated(&self) -> bool {
        !self.sensors.is_empty()
    }

    /// The nodes routes leave from.
    pub fn sources(&self) -> impl Iterator<Item = NodeRef> + '_ {
        self.routes.keys().map(|(n, _)| *n)
    }

    /// Whether any route leaves a node of `r`'s (a TouchSensor's events go somewhere).
    pub fn has_routes_from(&self, r: NodeRef) -> bool {
        self.routes.keys().any(|(n, _)| *n == r)
    }

    /// The last timestamp run.
    pub fn now(&self) -> Option<f64> {
        self.now
    }

    /// A warning, once per `key`, at `loc` of document `doc`.
    pub fn warn(&mut self, doc: usize, loc: Loc, key: &str, message: String) {
        if self.warned.insert(key.to_string()) {
            let file = self.files.get(doc).cloned().unwrap_or_else(|| Arc::from(Path::new("")));
            self.warnings.push(RibDiagnostic { severity: Severity::Warning, loc: location(&file, loc), message });
        }
    }

    /// The sensors' state at load.
    fn reset_state(&mut self, documents: &[(std::path::PathBuf, Document)]) {
        self.state.clear();
        for &s in &self.sensors {
            let p = sensor(documents, s);
            let ended = (!p.looping && p.start <= 0.0).then_some(p.start);
            self.state.insert(s, SensorState { active: false, cycle: 0, ended });
        }
        self.now = None;
    }

    /// Back to the file's values: every field changed gets its value from the file again (its
    /// node is then dirty), and the sensors are as at load.
    pub fn reset(&mut self, documents: &mut [(std::path::PathBuf, Document)]) {
        for (r, fields) in std::mem::take(&mut self.originals) {
            if let Some((_, doc)) = documents.get_mut(r.doc) {
                if let Some(node) = doc.nodes.get_mut(r.node.0 as usize) {
                    node.fields = fields;
                    self.dirty.insert(r);
                }
            }
        }
        self.reset_state(documents);
    }

    /// Runs the timestamp `now`: the TimeSensors that send events are evaluated, and their events
    /// cascade. A time before the last one run is an error of the caller's (see `reset`): nothing
    /// is sent for it; the last one again runs only when events were sent since (a click may have
    /// started a sensor).
    pub fn advance(&mut self, documents: &mut [(std::path::PathBuf, Document)], now: f64) {
        if !now.is_finite() || self.now.is_some_and(|last| now < last) {
            return;
        }
        // The same timestamp again sends nothing new, unless events were sent at it since.
        if self.now == Some(now) && !std::mem::take(&mut self.sent_since) {
            return;
        }
        let previous = self.now.unwrap_or(0.0);
        self.now = Some(now);
        let mut sent: Vec<(Source, EventValue)> = Vec::new();
        for &s in &self.sensors.clone() {
            let p = sensor(documents, s);
            let mut state = self.state.get(&s).copied().unwrap_or_default();
            let (start, end) = p.interval();
            let runs_now = p.enabled && now >= start && now < end && state.ended != Some(start);
            if runs_now {
                let cycle = p.cycle(now);
                if !state.active {
                    state.active = true;
                    sent.push(((s, "isActive"), EventValue::Bool(true)));
                    sent.push(((s, "cycleTime"), EventValue::Time(now)));
                } else if cycle != state.cycle {
                    sent.push(((s, "cycleTime"), EventValue::Time(now)));
                }
                state.cycle = cycle;
                sent.push(((s, "fraction_changed"), EventValue::Float(p.fraction(now))));
                sent.push(((s, "time"), EventValue::Time(now)));
            } else {
                // It stopped since the last timestamp, or ran a whole run between the two: the
                // last fraction is the one where it stopped.
                let ran_between = !state.active
                    && p.enabled
                    && start > previous
                    && end <= now
                    && start < end
                    && state.ended != Some(start);
                if state.active || ran_between {
                    if end <= now {
                        let last = if !p.looping && end == start + p.cycle_interval { 1.0 } else { p.fraction(end) };
                        sent.push(((s, "fraction_changed"), EventValue::Float(last)));
                        sent.push(((s, "time"), EventValue::Time(now)));
                        state.ended = Some(start);
                    }
                    if state.active {
                        sent.push(((s, "isActive"), EventValue::Bool(false)));
                    }
                    state.active = false;
                }
            }
            self.state.insert(s, state);
        }
        self.cascade(documents, sent, now);
    }

    /// Sends events of `node` at time `now` (a TouchSensor's, as the viewer clicks it) and runs
    /// their cascade.
    pub fn send(
        &mut self,
        documents: &mut [(std::path::PathBuf, Document)],
        node: NodeRef,
        events: Vec<(&'static str, EventValue)>,
        now: f64,
    ) {
        let sent = events.into_iter().map(|(name, v)| ((node, name), v)).collect();
        self.cascade(documents, sent, now);
        self.sent_since = true;
    }

    /// Delivers `sent` along the routes, and what the deliveries send, until nothing is left or
    /// [`VRML_EVENT_BUDGET`] events have been delivered.
    fn cascade(&mut self, documents: &mut [(std::path::PathBuf, Document)], sent: Vec<(Source, EventValue)>, now: f64) {
        let mut fired: HashSet<Source> = HashSet::new();
        let mut queue: VecDeque<(Source, EventValue)> = sent.into();
        let mut delivered = 0usize;
        while let Some((source, value)) = queue.pop_front() {
            // An eventOut sends one event per timestamp: a loop of routes stops here.
            if !fired.insert(source) {
                continue;
            }
            let Some(targets) = self.routes.get(&source).cloned() else { continue };
            for (to, field) in targets {
                delivered += 1;
                if delivered > VRML_EVENT_BUDGET {
                    let loc = documents.get(source.0.doc).map_or_else(Loc::default, |(_, d)| d.node(source.0.node).loc);
                    self.warn(
                        source.0.doc,
                        loc,
                        "budget",
                        format!(
                            "the events of time {now} passed {VRML_EVENT_BUDGET} deliveries; the rest of the cascade is dropped"
                        ),
                    );
                    return;
                }
                for out in self.deliver(documents, to, field, &value, now) {
                    queue.push_back(((to, out.0), out.1));
                }
            }
        }
    }

    /// Delivers `value` to eventIn `field` of `to`; returns the events that sends.
    fn deliver(
        &mut self,
        documents: &mut [(std::path::PathBuf, Document)],
        to: NodeRef,
        field: &'static str,
        value: &EventValue,
        now: f64,
    ) -> Vec<(&'static str, EventValue)> {
        let Some((_, doc)) = documents.get_mut(to.doc) else { return Vec::new() };
        let type_name = doc.node(to.node).type_name.clone();
        if field == "set_fraction" {
            let EventValue::Float(fraction) = value else { return Vec::new() };
            let node = doc.node(to.node);
            let keys = match node.field("key").and_then(|f| EventValue::from_value(&f.value, MFFloat)) {
                Some(EventValue::Floats(k)) => k,
                _ => return Vec::new(),
            };
            let Some(values) = node.field("keyValue").map(|f| &f.value) else { return Vec::new() };
            return match interpolate(&type_name, &keys, values, *fraction) {
                Some(v) => vec![("value_changed", v)],
                None => {
                    let loc = node.loc;
                    self.warn(
                        to.doc,
                        loc,
                        &format!("keys:{}:{}", to.doc, to.node.0),
                        format!("{type_name}: its keyValue does not fit its key; it sends nothing"),
                    );
                    Vec::new()
                }
            };
        }
        if type_name == "TimeSensor" {
            // 6.50: startTime and cycleInterval do not change while it runs, nor stopTime when
            // that is not after startTime.
            let state = self.state.get(&to).copied().unwrap_or_default();
            if state.active {
                let p = sensor(documents, to);
                let ignored = match (field, value) {
                    ("startTime" | "cycleInterval", _) => true,
                    ("stopTime", EventValue::Time(t)) => *t <= p.start,
                    _ => false,
                };
                if ignored {
                    return Vec::new();
                }
            }
            if let ("cycleInterval", EventValue::Time(t)) = (field, value) {
                if *t <= 0.0 {
                    return Vec::new();
                }
            }
        }
        self.set_field(documents, to, field, value);
        // A startTime set anew starts a run, even at the time of one that ended.
        if type_name == "TimeSensor" && field == "startTime" {
            if let Some(state) = self.state.get_mut(&to) {
                state.ended = None;
            }
        }
        let mut out = vec![(field, value.clone())];
        // A running TimeSensor disabled stops at once.
        if type_name == "TimeSensor" && field == "enabled" && *value == EventValue::Bool(false) {
            if let Some(state) = self.state.get_mut(&to).filter(|s| s.active) {
                state.active = false;
                out.push(("isActive", EventValue::Bool(false)));
            }
        }
        let _ = now;
        out
    }

    /// Writes an exposed field's new value into its node (keeping the file's fields once), as a
    /// sensor does to its own `offset`.
    pub(super) fn set_field(
        &mut self,
        documents: &mut [(std::path::PathBuf, Document)],
        to: NodeRef,
        field: &str,
        value: &EventValue,
    ) {
        let Some((_, doc)) = documents.get_mut(to.doc) else { return };
        let Some(node) = doc.nodes.get_mut(to.node.0 as usize) else { return };
        self.originals.entry(to).or_insert_with(|| node.fields.clone());
        let value = value.to_value();
        match node.fields.iter_mut().rev().find(|f| f.name == field) {
            Some(f) => f.value = value,
            None => node.fields.push(Field { name: field.to_string(), loc: node.loc, value, is: None }),
        }
        self.dirty.insert(to);
    }
}

/// A TimeSensor's fields as they stand (defaults where absent or of the wrong type).
fn sensor(documents: &[(std::path::PathBuf, Document)], r: NodeRef) -> TimeSensor {
    let mut p = TimeSensor::default();
    let Some(node) = documents.get(r.doc).and_then(|(_, d)| d.nodes.get(r.node.0 as usize)) else { return p };
    let get = |name: &str, ty: EventType| node.field(name).and_then(|f| EventValue::from_value(&f.value, ty));
    if let Some(EventValue::Time(t)) = get("cycleInterval", SFTime) {
        if t > 0.0 {
            p.cycle_interval = t;
        }
    }
    if let Some(EventValue::Bool(b)) = get("enabled", SFBool) {
        p.enabled = b;
    }
    if let Some(EventValue::Bool(b)) = get("loop", SFBool) {
        p.looping = b;
    }
    if let Some(EventValue::Time(t)) = get("startTime", SFTime) {
        p.start = t;
    }
    if let Some(EventValue::Time(t)) = get("stopTime", SFTime) {
        p.stop = t;
    }
    p
}

#[cfg(test)]
mod tests {
    use super::*;

    fn load(text: &str) -> (Vec<(std::path::PathBuf, Document)>, Events) {
        let doc = super::super::parse::parse(&format!("#VRML V2.0 utf8\n{text}")).expect("parses");
        let docs = vec![(std::path::PathBuf::from("t.wrl"), doc)];
        let events = Events::new(&docs, &[Arc::from(Path::new("t.wrl"))]);
        (docs, events)
    }

    fn field(docs: &[(std::path::PathBuf, Document)], def: &str, name: &str, ty: EventType) -> Option<EventValue> {
        let doc = &docs[0].1;
        let node = doc.node(*doc.defs.get(def).expect("defined"));
        EventValue::from_value(&node.field(name)?.value, ty)
    }

    fn vec3(v: Option<EventValue>) -> Vec3 {
        match v {
            Some(EventValue::Vec3(v)) => v,
            other => panic!("not a vector: {other:?}"),
        }
    }

    #[test]
    fn keys_are_found_with_jumps_and_ends() {
        let keys = [0.0, 0.5, 0.5, 1.0];
        assert_eq!(key_segment(&keys, -1.0), Some((0, 0, 0.0)));
        assert_eq!(key_segment(&keys, 0.25), Some((0, 1, 0.5)));
        // At a repeated key the later value holds.
        assert_eq!(key_segment(&keys, 0.5), Some((2, 3, 0.0)));
        assert_eq!(key_segment(&keys, 0.75), Some((2, 3, 0.5)));
        assert_eq!(key_segment(&keys, 2.0), Some((3, 3, 0.0)));
        assert_eq!(key_segment(&[], 0.5), None);
        assert_eq!(key_segment(&[0.3], f32::NAN), Some((0, 0, 0.0)));
    }

    #[test]
    fn orientations_slerp_along_the_shorter_arc() {
        let values = Value::Numbers(vec![0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, std::f64::consts::FRAC_PI_2]);
        let Some(EventValue::Rotation(r)) = interpolate("OrientationInterpolator", &[0.0, 1.0], &values, 0.5) else {
            panic!("a rotation")
        };
        let q = quat_of(r);
        let expected = Quat::from_rotation_y(std::f32::consts::FRAC_PI_4);
        assert!(q.dot(expected).abs() > 0.99999, "{r:?}");
        // From 0 to 1.5 turns about z (the same as half a turn the other way): the midpoint is a
        // quarter turn the short way, -90 degrees, not 270.
        let values = Value::Numbers(vec![0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 3.0 * std::f64::consts::PI * 0.5]);
        let Some(EventValue::Rotation(r)) = interpolate("OrientationInterpolator", &[0.0, 1.0], &values, 0.5) else {
            panic!("a rotation")
        };
        let turned = quat_of(r) * Vec3::X;
        assert!(turned.abs_diff_eq(Vec3::new(0.70710677, -0.70710677, 0.0), 1e-4), "{turned}");
        // Normals stay unit length; coordinates mix value lists per key.
        let normals = Value::Numbers(vec![1.0, 0.0, 0.0, 0.0, 1.0, 0.0]);
        let Some(EventValue::Vec3s(n)) = interpolate("NormalInterpolator", &[0.0, 1.0], &normals, 0.5) else {
            panic!("normals")
        };
        assert!((n[0].length() - 1.0).abs() < 1e-5 && (n[0].x - n[0].y).abs() < 1e-5, "{n:?}");
        let points = Value::Numbers(vec![0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 2.0, 0.0, 0.0, 3.0, 3.0, 3.0]);
        assert_eq!(
            interpolate("CoordinateInterpolator", &[0.0, 1.0], &points, 0.5),
            Some(EventValue::Vec3s(vec![Vec3::new(1.0, 0.0, 0.0), Vec3::new(2.0, 2.0, 2.0)]))
        );
        // Values that do not fit the keys send nothing.
        assert_eq!(interpolate("PositionInterpolator", &[0.0, 1.0], &Value::Numbers(vec![1.0, 2.0, 3.0]), 0.5), None);
    }

    const MOVER: &str = "
        DEF T Transform { children Shape { geometry Box {} } }
        DEF P PositionInterpolator { key [0 1] keyValue [0 0 0, 4 0 0] }
        DEF C TimeSensor { cycleInterval 2 loop TRUE }
        ROUTE C.fraction_changed TO P.set_fraction
        ROUTE P.value_changed TO T.set_translation";

    #[test]
    fn a_looping_sensor_moves_a_transform() {
        let (mut docs, mut events) = load(MOVER);
        assert!(events.warnings.is_empty(), "{:?}", events.warnings);
        events.advance(&mut docs, 0.5);
        assert_eq!(vec3(field(&docs, "T", "translation", SFVec3f)), Vec3::new(1.0, 0.0, 0.0));
        assert_eq!(events.dirty.len(), 1);
        // The second cycle starts over.
        events.advance(&mut docs, 3.0);
        assert_eq!(vec3(field(&docs, "T", "translation", SFVec3f)), Vec3::new(2.0, 0.0, 0.0));
        events.reset(&mut docs);
        assert_eq!(field(&docs, "T", "translation", SFVec3f), None);
    }

    #[test]
    fn a_non_looping_sensor_runs_once_and_ends_at_one() {
        let (mut docs, mut events) = load(&MOVER.replace("loop TRUE", "loop FALSE startTime 1"));
        events.advance(&mut docs, 0.5);
        assert_eq!(field(&docs, "T", "translation", SFVec3f), None, "not started");
        events.advance(&mut docs, 2.0);
        assert_eq!(vec3(field(&docs, "T", "translation", SFVec3f)), Vec3::new(2.0, 0.0, 0.0));
        // Past its end: the last fraction sent is 1, and it stays.
        events.advance(&mut docs, 10.0);
        assert_eq!(vec3(field(&docs, "T", "translation", SFVec3f)), Vec3::new(4.0, 0.0, 0.0));
        events.dirty.clear();
        events.advance(&mut docs, 11.0);
        assert!(events.dirty.is_empty());
        // Jumping from load past the whole run sends its last fraction too.
        let (mut docs, mut events) = load(&MOVER.replace("loop TRUE", "startTime 1"));
        events.advance(&mut docs, 5.0);
        assert_eq!(vec3(field(&docs, "T", "translation", SFVec3f)), Vec3::new(4.0, 0.0, 0.0));
        // A non-looping sensor that started at 0 has finished before the load, as in a browser.
        let (mut docs, mut events) = load(&MOVER.replace("loop TRUE", ""));
        events.advance(&mut docs, 0.5);
        assert_eq!(field(&docs, "T", "translation", SFVec3f), None);
        // stopTime cuts a looping sensor: the fraction where it stopped stays.
        let (mut docs, mut events) = load(&MOVER.replace("loop TRUE", "loop TRUE stopTime 2.5"));
        events.advance(&mut docs, 1.0);
        events.advance(&mut docs, 7.0);
        assert_eq!(vec3(field(&docs, "T", "translation", SFVec3f)), Vec3::new(1.0, 0.0, 0.0));
    }

    #[test]
    fn a_cascade_runs_through_chained_nodes_and_stops_at_loops() {
        // The sensor drives a scalar, the scalar's value is routed on twice (an exposed field's
        // _changed re-sent) and a loop of two Transforms feeding each other stops.
        let (mut docs, mut events) = load(
            "DEF A Transform {} DEF B Transform {}
             DEF S ScalarInterpolator { key [0 1] keyValue [0 10] }
             DEF M Material {} DEF M2 Material {}
             DEF C TimeSensor { loop TRUE cycleInterval 10 }
             DEF P PositionInterpolator { key [0 1] keyValue [0 0 0, 10 0 0] }
             ROUTE C.fraction_changed TO S.set_fraction
             ROUTE C.fraction_changed TO P.set_fraction
             ROUTE S.value_changed TO M.set_transparency
             ROUTE M.transparency_changed TO M2.transparency
             ROUTE P.value_changed TO A.set_translation
             ROUTE A.translation_changed TO B.set_translation
             ROUTE B.translation_changed TO A.set_translation",
        );
        assert!(events.warnings.is_empty(), "{:?}", events.warnings);
        events.advance(&mut docs, 2.0);
        assert_eq!(field(&docs, "M2", "transparency", SFFloat), Some(EventValue::Float(2.0)));
        assert_eq!(vec3(field(&docs, "B", "translation", SFVec3f)), Vec3::new(2.0, 0.0, 0.0));
        assert_eq!(vec3(field(&docs, "A", "translation", SFVec3f)), Vec3::new(2.0, 0.0, 0.0));
    }

    #[test]
    fn bad_routes_are_warnings_with_their_place() {
        let (_, events) = load(
            "DEF T Transform {} DEF C TimeSensor {} DEF G Group {}
             ROUTE C.fraction_changed TO T.set_translation
             ROUTE C.fraction TO T.set_translation
             ROUTE C.time TO T.set_frobnicate
             ROUTE C.isActive TO G.addChildren
             ROUTE C.time TO Nobody.set_startTime",
        );
        let messages: Vec<String> = events.warnings.iter().map(ToString::to_string).collect();
        assert_eq!(messages.len(), 4, "{messages:#?}");
        assert!(messages[0].starts_with("t.wrl:3:14") && messages[0].contains("SFFloat eventOut to an SFVec3f"));
        assert!(messages[1].contains("TimeSensor has no eventOut `fraction`"), "{}", messages[1]);
        assert!(messages[2].contains("Transform has no eventIn `set_frobnicate`"), "{}", messages[2]);
        assert!(messages[3].contains("Group's eventIn `addChildren` is not run"), "{}", messages[3]);
        assert!(!events.is_animated());
    }

    #[test]
    fn touch_time_starts_a_sensor() {
        let (mut docs, mut events) = load(&format!(
            "{}\nDEF Touch TouchSensor {{}}\nROUTE Touch.touchTime TO C.set_startTime",
            MOVER.replace("loop TRUE", "")
        ));
        events.advance(&mut docs, 1.0);
        assert_eq!(field(&docs, "T", "translation", SFVec3f), None);
        let touch = NodeRef { doc: 0, node: docs[0].1.defs["Touch"] };
        events.send(&mut docs, touch, vec![("touchTime", EventValue::Time(1.5))], 1.5);
        events.advance(&mut docs, 2.5);
        assert_eq!(vec3(field(&docs, "T", "translation", SFVec3f)), Vec3::new(2.0, 0.0, 0.0));
        // While it runs, another touch does not restart it.
        events.send(&mut docs, touch, vec![("touchTime", EventValue::Time(3.0))], 3.0);
        events.advance(&mut docs, 3.0);
        assert_eq!(vec3(field(&docs, "T", "translation", SFVec3f)), Vec3::new(3.0, 0.0, 0.0));
        events.advance(&mut docs, 9.0);
        assert_eq!(vec3(field(&docs, "T", "translation", SFVec3f)), Vec3::new(4.0, 0.0, 0.0));
        // A touch at time 0, the startTime of the run that ended before the load, starts one.
        let (mut docs, mut events) = load(&format!(
            "{}\nDEF Touch TouchSensor {{}}\nROUTE Touch.touchTime TO C.set_startTime",
            MOVER.replace("loop TRUE", "")
        ));
        let touch = NodeRef { doc: 0, node: docs[0].1.defs["Touch"] };
        events.advance(&mut docs, 0.0);
        events.send(&mut docs, touch, vec![("touchTime", EventValue::Time(0.0))], 0.0);
        events.advance(&mut docs, 0.5);
        assert_eq!(vec3(field(&docs, "T", "translation", SFVec3f)), Vec3::new(1.0, 0.0, 0.0));
    }
}
