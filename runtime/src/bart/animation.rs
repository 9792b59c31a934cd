//! Keyframe animation of BART's `k` blocks: translation, rotation and scale tracks interpolated
//! with Kochanek-Bartels splines (tension, continuity, bias per key), and visibility tracks.
//!
//! The spline is the one of 3D Studio's keyframer as Jochen Wilhelmy documented it ("spline
//! interpolation for 3DS keyframes"), which is what the BART tools used:
//!
//! - Between keys `i` and `i + 1` a value is the cubic Hermite curve from `P_i` to `P_(i+1)` with
//!   the outgoing tangent of key `i` and the incoming tangent of key `i + 1`, over the local
//!   parameter `u = (t - t_i) / (t_(i+1) - t_i)`.
//! - The tangents of an inner key are the Kochanek-Bartels combination of the differences to its
//!   neighbours, `d_in = P_i - P_(i-1)` and `d_out = P_(i+1) - P_i`:
//!   incoming `(1-T)(1-C)(1+B)/2 d_in + (1-T)(1+C)(1-B)/2 d_out`,
//!   outgoing `(1-T)(1+C)(1+B)/2 d_in + (1-T)(1-C)(1-B)/2 d_out`,
//!   each scaled for uneven key spacing by the length of its own segment over the mean of the two
//!   (`2 dt_in / (dt_in + dt_out)` and `2 dt_out / (dt_in + dt_out)`), moved towards 1 by
//!   `|C|`. With T = C = B = 0 and even spacing this is the Catmull-Rom spline.
//! - The first and last keys get "natural" ends (no second derivative there):
//!   `T_0 = (1.5 d - 0.5 T_1)(1 - tension)`; with only two keys, `T = d (1 - tension)`.
//! - Before the first key a track holds the first value, after the last the last value. Keys at
//!   the same time (BART files repeat their first and last keys) make an empty segment that is
//!   never interpolated, so they cause no division by zero.
//!
//! Rotations are keyed as an axis and an angle in degrees, absolute (not relative to the previous
//! key). They are interpolated as unit quaternions with the same tangents taken in the tangent
//! space of the rotation group (rotation vectors of the relative rotations between keys) and
//! Shoemake's `squad`. Consecutive keys are put on the same side of the quaternion sphere, so each
//! segment turns the short way (under 180 degrees): BART's wheels and guns spin by keys 90 degrees
//! apart, which this follows. For keys about one fixed axis this is exactly the Hermite spline of
//! the angle (squad's cubic has the same end values and end derivatives), which is what the tests
//! compare against.

use glam::{Affine3A, Quat, Vec3};

/// A key's tension, continuity and bias; all zero is Catmull-Rom.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Tcb {
    pub tension: f32,
    pub continuity: f32,
    pub bias: f32,
}

/// One key of a track.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Key<T> {
    pub time: f32,
    pub value: T,
    pub tcb: Tcb,
}

/// A rotation key's value as the files give it: an axis (any length) and an angle in degrees.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AxisAngle {
    pub axis: Vec3,
    pub degrees: f32,
}

impl AxisAngle {
    /// The rotation as a unit quaternion; an axis of zero length is no rotation.
    pub fn to_quat(self) -> Quat {
        match self.axis.try_normalize() {
            Some(axis) if self.degrees.is_finite() => Quat::from_axis_angle(axis, self.degrees.to_radians()),
            _ => Quat::IDENTITY,
        }
    }
}

/// The Kochanek-Bartels weights of key `i`'s tangents on its two neighbour differences:
/// `incoming = w[0] * d_in + w[1] * d_out`, `outgoing = w[2] * d_in + w[3] * d_out`.
fn inner_weights(t_prev: f32, t: f32, t_next: f32, k: Tcb) -> [f32; 4] {
    let half_span = 0.5 * (t_next - t_prev);
    if half_span.is_nan() || half_span <= 0.0 {
        // Three keys at one time: no motion to take a tangent from.
        return [0.0; 4];
    }
    let c = k.continuity.abs();
    let before = (t - t_prev) / half_span;
    let after = (t_next - t) / half_span;
    let before = before + c - c * before;
    let after = after + c - c * after;
    let tension = 0.5 * (1.0 - k.tension);
    let (c_minus, c_plus) = (1.0 - k.continuity, 1.0 + k.continuity);
    let (b_minus, b_plus) = (1.0 - k.bias, 1.0 + k.bias);
    [
        tension * c_minus * b_plus * before,
        tension * c_plus * b_minus * before,
        tension * c_plus * b_plus * after,
        tension * c_minus * b_minus * after,
    ]
}

/// The index of the segment `[keys[i], keys[i + 1]]` holding `t` and the parameter along it, or the
/// key whose value holds (before the first key, after the last, or a track of one key).
enum Place {
    Key(usize),
    Segment(usize, f32),
}

fn place<T>(keys: &[Key<T>], t: f32) -> Place {
    // The last key at or before t; the segment after it has positive length by construction.
    let after = keys.partition_point(|k| k.time <= t);
    if after == 0 {
        return Place::Key(0);
    }
    let i = after - 1;
    if i + 1 >= keys.len() {
        return Place::Key(i);
    }
    let (t0, t1) = (keys[i].time, keys[i + 1].time);
    let u = ((t - t0) / (t1 - t0)).clamp(0.0, 1.0);
    if u.is_nan() {
        Place::Key(i)
    } else {
        Place::Segment(i, u)
    }
}

/// Sorts keys by time (stable, so keys at one time keep their order) and drops keys whose time is
/// not finite.
fn sorted<T>(mut keys: Vec<Key<T>>) -> Vec<Key<T>> {
    keys.retain(|k| k.time.is_finite());
    keys.sort_by(|a, b| a.time.total_cmp(&b.time));
    keys
}

/// The cubic Hermite basis at `u`: weights of the start value, end value, start tangent and end
/// tangent.
fn hermite(u: f32) -> [f32; 4] {
    let (u2, u3) = (u * u, u * u * u);
    [2.0 * u3 - 3.0 * u2 + 1.0, -2.0 * u3 + 3.0 * u2, u3 - 2.0 * u2 + u, u3 - u2]
}

/// Incoming and outgoing tangents of every key, from the differences between neighbours (`delta(i)`
/// is the difference from key `i` to key `i + 1`), in any vector space.
fn tangents<T: Copy>(keys: &[Key<T>], delta: impl Fn(usize) -> Vec3) -> (Vec<Vec3>, Vec<Vec3>) {
    let n = keys.len();
    let mut incoming = vec![Vec3::ZERO; n];
    let mut outgoing = vec![Vec3::ZERO; n];
    if n < 2 {
        return (incoming, outgoing);
    }
    for i in 1..n - 1 {
        let w = inner_weights(keys[i - 1].time, keys[i].time, keys[i + 1].time, keys[i].tcb);
        let (d_in, d_out) = (delta(i - 1), delta(i));
        incoming[i] = w[0] * d_in + w[1] * d_out;
        outgoing[i] = w[2] * d_in + w[3] * d_out;
    }
    let slack = |k: &Key<T>| 1.0 - k.tcb.tension;
    if n == 2 {
        outgoing[0] = delta(0) * slack(&keys[0]);
        incoming[1] = delta(0) * slack(&keys[1]);
    } else {
        outgoing[0] = (1.5 * delta(0) - 0.5 * incoming[1]) * slack(&keys[0]);
        incoming[n - 1] = (1.5 * delta(n - 2) - 0.5 * outgoing[n - 2]) * slack(&keys[n - 1]);
    }
    (incoming, outgoing)
}

/// A track of 3-vectors (translation or scale).
#[derive(Clone, Debug, PartialEq)]
pub struct VectorTrack {
    keys: Vec<Key<Vec3>>,
    incoming: Vec<Vec3>,
    outgoing: Vec<Vec3>,
}

impl VectorTrack {
    /// A track from its keys (sorted by time here); `None` when no key has a finite time.
    pub fn new(keys: Vec<Key<Vec3>>) -> Option<VectorTrack> {
        let keys = sorted(keys);
        if keys.is_empty() {
            return None;
        }
        let (incoming, outgoing) = tangents(&keys, |i| keys[i + 1].value - keys[i].value);
        Some(VectorTrack { keys, incoming, outgoing })
    }

    pub fn keys(&self) -> &[Key<Vec3>] {
        &self.keys
    }

    /// The value at time `t`.
    pub fn at(&self, t: f32) -> Vec3 {
        match place(&self.keys, t) {
            Place::Key(i) => self.keys[i].value,
            Place::Segment(i, u) => {
                let h = hermite(u);
                h[0] * self.keys[i].value
                    + h[1] * self.keys[i + 1].value
                    + h[2] * self.outgoing[i]
                    + h[3] * self.incoming[i + 1]
            }
        }
    }
}

/// A track of rotations.
#[derive(Clone, Debug, PartialEq)]
pub struct RotationTrack {
    keys: Vec<Key<Quat>>,
    /// Squad's inner control points: towards the next key (`ahead`) and from the previous one
    /// (`behind`).
    ahead: Vec<Quat>,
    behind: Vec<Quat>,
}

/// The plain spherical interpolation from `a` to `b` (no flip to the short way: squad's control
/// points must be taken as they are for its curve to be smooth).
fn slerp_as_is(a: Quat, b: Quat, u: f32) -> Quat {
    let dot = a.dot(b).clamp(-1.0, 1.0);
    let theta = dot.acos();
    let sin = theta.sin();
    if sin < 1e-4 {
        return normalized_or(a * (1.0 - u) + b * u, a);
    }
    let wa = ((1.0 - u) * theta).sin() / sin;
    let wb = (u * theta).sin() / sin;
    normalized_or(a * wa + b * wb, a)
}

/// `q` scaled to unit length, or `fallback` when `q` has no usable length.
fn normalized_or(q: Quat, fallback: Quat) -> Quat {
    let len = q.length();
    if len > 1e-12 && len.is_finite() {
        q / len
    } else {
        fallback
    }
}

/// The rotation vector (axis times angle in radians, at most pi) of the rotation from `a` to `b`.
fn log_between(a: Quat, b: Quat) -> Vec3 {
    let mut rel = a.inverse() * b;
    if rel.w < 0.0 {
        rel = -rel;
    }
    rel.to_scaled_axis()
}

impl RotationTrack {
    /// A track from keys given as axis and angle (sorted by time here); `None` when no key has a
    /// finite time.
    pub fn new(keys: Vec<Key<AxisAngle>>) -> Option<RotationTrack> {
        let mut quats: Vec<Key<Quat>> =
            sorted(keys).into_iter().map(|k| Key { time: k.time, value: k.value.to_quat(), tcb: k.tcb }).collect();
        if quats.is_empty() {
            return None;
        }
        // One hemisphere along the track: each segment turns the short way.
        for i in 1..quats.len() {
            if quats[i].value.dot(quats[i - 1].value) < 0.0 {
                quats[i].value = -quats[i].value;
            }
        }
        let logs: Vec<Vec3> = quats.windows(2).map(|w| log_between(w[0].value, w[1].value)).collect();
        let (incoming, outgoing) = tangents(&quats, |i| logs[i]);
        let n = quats.len();
        let ahead = (0..n)
            .map(|i| {
                let d_out = logs.get(i).copied().unwrap_or(Vec3::ZERO);
                quats[i].value * Quat::from_scaled_axis(0.5 * (outgoing[i] - d_out))
            })
            .collect();
        let behind = (0..n)
            .map(|i| {
                let d_in = if i > 0 { logs[i - 1] } else { Vec3::ZERO };
                quats[i].value * Quat::from_scaled_axis(0.5 * (d_in - incoming[i]))
            })
            .collect();
        Some(RotationTrack { keys: quats, ahead, behind })
    }

    /// The keys as unit quaternions (after the hemisphere alignment).
    pub fn keys(&self) -> &[Key<Quat>] {
        &self.keys
    }

    /// The rotation at time `t`.
    pub fn at(&self, t: f32) -> Quat {
        match place(&self.keys, t) {
            Place::Key(i) => self.keys[i].value,
            Place::Segment(i, u) => {
                let (q0, q1) = (self.keys[i].value, self.keys[i + 1].value);
                let outer = slerp_as_is(q0, q1, u);
                let inner = slerp_as_is(self.ahead[i], self.behind[i + 1], u);
                slerp_as_is(outer, inner, 2.0 * u * (1.0 - u)).normalize()
            }
        }
    }
}

/// A visibility track: each key switches the node on (value > 0) or off from its time on.
#[derive(Clone, Debug, PartialEq)]
pub struct VisibilityTrack {
    keys: Vec<Key<bool>>,
}

impl VisibilityTrack {
    pub fn new(keys: Vec<Key<bool>>) -> Option<VisibilityTrack> {
        let keys = sorted(keys);
        (!keys.is_empty()).then_some(VisibilityTrack { keys })
    }

    /// Whether the node is visible at `t`: the value of the last key at or before `t` (the first
    /// key's before it).
    pub fn at(&self, t: f32) -> bool {
        let after = self.keys.partition_point(|k| k.time <= t);
        self.keys[after.saturating_sub(1)].value
    }
}

/// A named keyframe animation (`k NAME { ... }`): the node transform `T * R * S` (scale first,
/// then rotation, then translation), each part the identity when its track is absent.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Keyframes {
    pub name: String,
    pub translation: Option<VectorTrack>,
    pub rotation: Option<RotationTrack>,
    pub scale: Option<VectorTrack>,
    pub visibility: Option<VisibilityTrack>,
}

impl Keyframes {
    pub fn translation_at(&self, t: f32) -> Vec3 {
        self.translation.as_ref().map_or(Vec3::ZERO, |tr| tr.at(t))
    }

    pub fn rotation_at(&self, t: f32) -> Quat {
        self.rotation.as_ref().map_or(Quat::IDENTITY, |tr| tr.at(t))
    }

    pub fn scale_at(&self, t: f32) -> Vec3 {
        self.scale.as_ref().map_or(Vec3::ONE, |tr| tr.at(t))
    }

    /// The node's transform at `t` (parent from node).
    pub fn transform_at(&self, t: f32) -> Affine3A {
        Affine3A::from_scale_rotation_translation(self.scale_at(t), self.rotation_at(t), self.translation_at(t))
    }

    /// Whether the node is shown at `t` (always, without a visibility track).
    pub fn visible_at(&self, t: f32) -> bool {
        self.visibility.as_ref().is_none_or(|v| v.at(t))
    }

    /// The first and last key times over all tracks, if there are keys.
    pub fn time_range(&self) -> Option<(f32, f32)> {
        let mut range: Option<(f32, f32)> = None;
        let mut add = |times: &mut dyn Iterator<Item = f32>| {
            for t in times {
                range = Some(range.map_or((t, t), |(a, b)| (a.min(t), b.max(t))));
            }
        };
        if let Some(tr) = &self.translation {
            add(&mut tr.keys.iter().map(|k| k.time));
        }
        if let Some(tr) = &self.rotation {
            add(&mut tr.keys.iter().map(|k| k.time));
        }
        if let Some(tr) = &self.scale {
            add(&mut tr.keys.iter().map(|k| k.time));
        }
        if let Some(tr) = &self.visibility {
            add(&mut tr.keys.iter().map(|k| k.time));
        }
        range
    }
}
