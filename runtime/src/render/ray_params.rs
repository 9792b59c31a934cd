//! Ray parameters: named values an application attaches to a frame's rays, which shaders read with
//! `rayinfo("name", var)`, so that rendering quality can follow relevance (where the user looks,
//! what the task needs), as the reference paper's API allowed (section 5.1.3).
//!
//! Where a ray's value comes from, first found first:
//! 1. the nearest object on the ray's path back to its camera sample that sets ray parameters
//!    ([`crate::api::Context::ray_attribute`], kept in its [`super::Material`]): a hit on such an
//!    object reads the object's values, and so do the rays its shading spawns;
//! 2. the frame's [`RayField`] of the parameter at the ray's camera sample's pixel: a reflection
//!    ray reads what the pixel it serves reads;
//! 3. the frame's value of the parameter ([`RayParameters::set`]);
//! 4. [`RELEVANCE`] reads 1 when the application sets nothing; other names are not found:
//!    `rayinfo` returns 0 and leaves its variable as it was (the shader's own default), and the
//!    frame reports the name once.
//!
//! Invariants: everything here is plain data (it travels to the workers of a distributed render
//! inside the [`super::RenderOptions`]); a callback the application gives is sampled into an image
//! when it is given. A field's values have its parameter's type (checked when set), and looking a
//! value up never fails on pixels outside a field's image or an empty one.

use serde::{Deserialize, Serialize};

/// The parameter the library shaders and the renderer read as relevance, from 0 (the least
/// quality) to 1 (full quality): shadow and reflection quality, and samples per pixel
/// (`docs/ray_parameters.md`). It reads 1 where nothing sets it.
pub const RELEVANCE: &str = "relevance";

/// The most values a field's image may hold (a 8192 x 4096 image of colours).
pub const MAX_RAY_FIELD_VALUES: usize = 3 << 25;

/// The value of a ray parameter.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum RayValue {
    Float(f32),
    Color([f32; 3]),
    Point([f32; 3]),
    String(String),
}

impl RayValue {
    /// The RenderMan type name (`float`, `color`, `point`, `string`).
    pub fn type_name(&self) -> &'static str {
        match self {
            RayValue::Float(_) => "float",
            RayValue::Color(_) => "color",
            RayValue::Point(_) => "point",
            RayValue::String(_) => "string",
        }
    }

    fn same_type(&self, other: &RayValue) -> bool {
        std::mem::discriminant(self) == std::mem::discriminant(other)
    }

    /// How many floats the value is (0 for a string).
    fn components(&self) -> usize {
        match self {
            RayValue::Float(_) => 1,
            RayValue::Color(_) | RayValue::Point(_) => 3,
            RayValue::String(_) => 0,
        }
    }

    /// `self` where `t` is 0 and `other` where it is 1, linearly between (a string: the nearer).
    fn blend(&self, other: &RayValue, t: f32) -> RayValue {
        let mix = |a: f32, b: f32| a + (b - a) * t;
        match (self, other) {
            (RayValue::Float(a), RayValue::Float(b)) => RayValue::Float(mix(*a, *b)),
            (RayValue::Color(a), RayValue::Color(b)) => RayValue::Color(std::array::from_fn(|k| mix(a[k], b[k]))),
            (RayValue::Point(a), RayValue::Point(b)) => RayValue::Point(std::array::from_fn(|k| mix(a[k], b[k]))),
            _ if t < 0.5 => self.clone(),
            _ => other.clone(),
        }
    }

    /// The value of `floats` read as this value's type.
    fn with_floats(&self, floats: &[f32]) -> RayValue {
        let at = |k: usize| floats.get(k).copied().unwrap_or(0.0);
        match self {
            RayValue::Float(_) => RayValue::Float(at(0)),
            RayValue::Color(_) => RayValue::Color([at(0), at(1), at(2)]),
            RayValue::Point(_) => RayValue::Point([at(0), at(1), at(2)]),
            RayValue::String(s) => RayValue::String(s.clone()),
        }
    }
}

impl From<f32> for RayValue {
    fn from(x: f32) -> RayValue {
        RayValue::Float(x)
    }
}

/// How a parameter varies over the image, in pixels of the frame (x right, y down, the top left
/// pixel's corner at 0, 0). Pixels the field does not cover take the parameter's value.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum RayField {
    /// Values inside rectangles of pixels `[x0, y0, x1, y1)`; the last rectangle holding a pixel
    /// wins.
    Regions(Vec<([u32; 4], RayValue)>),
    /// One value per pixel of a `width x height` image (rows from the top, `components` floats a
    /// pixel), stretched over the frame (nearest pixel): a relevance map, or what a callback gave
    /// at each pixel ([`RayField::sample`]).
    Image { width: u32, height: u32, components: u32, values: Vec<f32> },
    /// `inside` within `radius` pixels of `centre` (a gaze point), the parameter's value beyond
    /// `radius + falloff`, and a smooth blend (smoothstep) between.
    Gaze { centre: [f32; 2], radius: f32, falloff: f32, inside: RayValue },
}

impl RayField {
    /// The image of `f` at the centre of each pixel of a `width x height` frame (a callback's
    /// field). The values must all be floats or all triples.
    pub fn sample(
        width: u32,
        height: u32,
        mut f: impl FnMut(u32, u32) -> RayValue,
    ) -> Result<RayField, RayParameterError> {
        let n = width as usize * height as usize;
        let mut values = Vec::new();
        let mut components = None;
        for y in 0..height {
            for x in 0..width {
                let v = f(x, y);
                let c = v.components();
                if c == 0 || components.is_some_and(|k| k != c) {
                    return Err(RayParameterError(format!(
                        "a callback's values are floats or triples of one type throughout; it gave a {} at pixel {x}, {y}",
                        v.type_name()
                    )));
                }
                if components.is_none() {
                    if n.saturating_mul(c) > MAX_RAY_FIELD_VALUES {
                        return Err(too_many(n.saturating_mul(c)));
                    }
                    values.reserve_exact(n * c);
                }
                components = Some(c);
                match v {
                    RayValue::Float(a) => values.push(a),
                    RayValue::Color(a) | RayValue::Point(a) => values.extend(a),
                    RayValue::String(_) => {}
                }
            }
        }
        Ok(RayField::Image { width, height, components: components.unwrap_or(1) as u32, values })
    }

    /// Whether the field's values fit a parameter of `value`'s type, and its image is whole.
    fn check(&self, value: &RayValue) -> Result<(), RayParameterError> {
        let wrong = |got: &RayValue| {
            RayParameterError(format!("a {} value in the field of a {} parameter", got.type_name(), value.type_name()))
        };
        match self {
            RayField::Regions(regions) => {
                if let Some((_, v)) = regions.iter().find(|(_, v)| !v.same_type(value)) {
                    return Err(wrong(v));
                }
            }
            RayField::Gaze { inside, radius, falloff, centre } => {
                if !inside.same_type(value) {
                    return Err(wrong(inside));
                }
                if !(radius.is_finite() && falloff.is_finite() && centre.iter().all(|c| c.is_finite())) {
                    return Err(RayParameterError("a gaze's centre, radius and falloff are finite numbers".into()));
                }
            }
            RayField::Image { width, height, components, values } => {
                let c = value.components();
                if c == 0 || *components as usize != c {
                    return Err(RayParameterError(format!(
                        "an image of {components} values a pixel for a {} parameter",
                        value.type_name()
                    )));
                }
                let n = (*width as usize).saturating_mul(*height as usize).saturating_mul(c);
                if n > MAX_RAY_FIELD_VALUES {
                    return Err(too_many(n));
                }
                if values.len() != n {
                    return Err(RayParameterError(format!(
                        "an image of {width}x{height} pixels of {c} values needs {n} values, {} given",
                        values.len()
                    )));
                }
            }
        }
        Ok(())
    }

    /// The field's value at the centre of pixel `(x, y)` of a `size` frame, `base` where it
    /// gives none.
    fn at(&self, base: &RayValue, (x, y): (u32, u32), size: (u32, u32)) -> RayValue {
        match self {
            RayField::Regions(regions) => regions
                .iter()
                .rev()
                .find(|([x0, y0, x1, y1], _)| (*x0..*x1).contains(&x) && (*y0..*y1).contains(&y))
                .map_or_else(|| base.clone(), |(_, v)| v.clone()),
            RayField::Image { width, height, components, values } => {
                if *width == 0 || *height == 0 {
                    return base.clone();
                }
                let ix = (u64::from(x) * u64::from(*width) / u64::from(size.0.max(1))).min(u64::from(*width - 1));
                let iy = (u64::from(y) * u64::from(*height) / u64::from(size.1.max(1))).min(u64::from(*height - 1));
                let c = *components as usize;
                let at = (iy as usize * *width as usize + ix as usize) * c;
                values.get(at..at + c).map_or_else(|| base.clone(), |v| base.with_floats(v))
            }
            RayField::Gaze { centre, radius, falloff, inside } => {
                let (dx, dy) = (x as f32 + 0.5 - centre[0], y as f32 + 0.5 - centre[1]);
                let d = (dx * dx + dy * dy).sqrt();
                let t = if d <= *radius {
                    0.0
                } else if *falloff <= 0.0 || d >= radius + falloff {
                    1.0
                } else {
                    let u = (d - radius) / falloff;
                    u * u * (3.0 - 2.0 * u)
                };
                inside.blend(base, t)
            }
        }
    }
}

fn too_many(n: usize) -> RayParameterError {
    RayParameterError(format!("a field of {n} values is more than the {MAX_RAY_FIELD_VALUES} a field may hold"))
}

/// A ray parameter given a value or field that does not fit it.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("ray parameter: {0}")]
pub struct RayParameterError(pub String);

/// One parameter: its value, and how it varies over the image.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RayParameter {
    pub value: RayValue,
    pub field: Option<RayField>,
}

/// The frame's ray parameters, by name (a frame has few: a list).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct RayParameters {
    entries: Vec<(String, RayParameter)>,
}

/// `rayinfo("user:name")` is `rayinfo("name")`: RenderMan's namespace for user data (as in
/// `option("user:name")`).
pub fn strip_user(name: &str) -> &str {
    name.strip_prefix("user:").unwrap_or(name)
}

impl RayParameters {
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    pub fn get(&self, name: &str) -> Option<&RayParameter> {
        let name = strip_user(name);
        self.entries.iter().find(|(n, _)| n == name).map(|(_, p)| p)
    }

    /// Sets parameter `name`'s value everywhere its field does not reach. A parameter keeps its
    /// type: a value of another type is an error (remove it first).
    pub fn set(&mut self, name: &str, value: RayValue) -> Result<(), RayParameterError> {
        let name = strip_user(name);
        if name.is_empty() {
            return Err(RayParameterError("a parameter needs a name".into()));
        }
        match self.entries.iter_mut().find(|(n, _)| n == name) {
            Some((_, p)) if !p.value.same_type(&value) => Err(RayParameterError(format!(
                "`{name}` is a {} parameter, not a {} one (remove it to change its type)",
                p.value.type_name(),
                value.type_name()
            ))),
            Some((_, p)) => {
                p.value = value;
                Ok(())
            }
            None => {
                self.entries.push((name.to_string(), RayParameter { value, field: None }));
                Ok(())
            }
        }
    }

    /// Sets how parameter `name` varies over the image (`None`: it does not). The parameter must
    /// have a value already ([`RayParameters::set`]), of the field's values' type.
    pub fn set_field(&mut self, name: &str, field: Option<RayField>) -> Result<(), RayParameterError> {
        let name = strip_user(name);
        let Some((_, p)) = self.entries.iter_mut().find(|(n, _)| n == name) else {
            return Err(RayParameterError(format!("`{name}` has no value yet: set one before its field")));
        };
        if let Some(f) = &field {
            f.check(&p.value)?;
        }
        p.field = field;
        Ok(())
    }

    /// Removes parameter `name` (nothing if there is none).
    pub fn remove(&mut self, name: &str) {
        let name = strip_user(name);
        self.entries.retain(|(n, _)| n != name);
    }

    /// The names, in the order they were first set.
    pub fn names(&self) -> impl Iterator<Item = &str> {
        self.entries.iter().map(|(n, _)| n.as_str())
    }

    /// Parameter `name` at pixel `pixel` of a `size` frame (its value alone without a pixel).
    pub fn value_at(&self, name: &str, pixel: Option<(u32, u32)>, size: (u32, u32)) -> Option<RayValue> {
        let p = self.get(name)?;
        Some(match (&p.field, pixel) {
            (Some(f), Some(px)) => f.at(&p.value, px, size),
            _ => p.value.clone(),
        })
    }

    /// The float parameter `name` at a pixel (see [`RayParameters::value_at`]); `None` when it is
    /// not set or not a float.
    pub fn float_at(&self, name: &str, pixel: Option<(u32, u32)>, size: (u32, u32)) -> Option<f32> {
        match self.value_at(name, pixel, size)? {
            RayValue::Float(x) => Some(x),
            _ => None,
        }
    }
}

/// Ray parameter names shaders asked for that nothing sets: each is reported once, across the
/// frames of a context (which shares one with each world it builds).
#[derive(Debug, Default)]
pub struct RayParameterMisses {
    names: std::sync::Mutex<(Vec<String>, Vec<String>)>,
}

impl RayParameterMisses {
    /// Notes a name asked for and not found.
    pub fn note(&self, name: &str) {
        let Ok(mut names) = self.names.lock() else { return };
        let (new, reported) = &mut *names;
        if !new.iter().chain(reported.iter()).any(|n| n == name) {
            new.push(name.to_string());
        }
    }

    /// The names noted since the last call and never reported before.
    pub fn take_new(&self) -> Vec<String> {
        let Ok(mut names) = self.names.lock() else { return Vec::new() };
        let (new, reported) = &mut *names;
        let out = std::mem::take(new);
        reported.extend(out.iter().cloned());
        out
    }
}

/// How many of `n` samples a ray or pixel of relevance `r` takes: `ceil(n r)`, at least one.
pub fn samples_for_relevance(n: u32, r: f32) -> u32 {
    ((n as f32 * r.clamp(0.0, 1.0)).ceil() as u32).clamp(1, n.max(1))
}

/// An object's own ray parameter values (see the module's order of lookup).
pub fn object_value<'a>(values: &'a [(String, RayValue)], name: &str) -> Option<&'a RayValue> {
    let name = strip_user(name);
    values.iter().find(|(n, _)| n == name).map(|(_, v)| v)
}

/// The relevance a quality decision reads: the float [`RELEVANCE`] parameter clamped to [0, 1],
/// 1 where nothing sets it (or it is not a float).
pub fn relevance(value: Option<&RayValue>) -> f32 {
    match value {
        Some(RayValue::Float(x)) if x.is_finite() => x.clamp(0.0, 1.0),
        Some(RayValue::Float(_)) => 0.0,
        _ => 1.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const SIZE: (u32, u32) = (100, 50);

    #[test]
    fn a_parameter_keeps_its_type_and_its_field_must_fit_it() {
        let mut p = RayParameters::default();
        assert!(p.set_field("q", None).is_err(), "a field needs a value first");
        p.set("user:q", 0.25.into()).unwrap();
        assert_eq!(p.value_at("q", None, SIZE), Some(RayValue::Float(0.25)));
        assert!(p.set("q", RayValue::Color([1.0; 3])).is_err());
        let colour = RayField::Regions(vec![([0, 0, 1, 1], RayValue::Color([1.0; 3]))]);
        assert!(p.set_field("q", Some(colour)).is_err());
        let short = RayField::Image { width: 2, height: 2, components: 1, values: vec![0.0; 3] };
        assert!(p.set_field("q", Some(short)).is_err());
        let nan = RayField::Gaze { centre: [f32::NAN, 0.0], radius: 1.0, falloff: 1.0, inside: 1.0.into() };
        assert!(p.set_field("q", Some(nan)).is_err());
        p.remove("q");
        assert!(p.is_empty());
        assert!(p.set("", 1.0.into()).is_err());
    }

    #[test]
    fn regions_take_the_last_rectangle_holding_the_pixel() {
        let mut p = RayParameters::default();
        p.set("q", 0.0.into()).unwrap();
        let regions = vec![([0, 0, 50, 50], 0.5.into()), ([40, 0, 60, 10], 1.0.into())];
        p.set_field("q", Some(RayField::Regions(regions))).unwrap();
        assert_eq!(p.float_at("q", Some((10, 10)), SIZE), Some(0.5));
        assert_eq!(p.float_at("q", Some((45, 5)), SIZE), Some(1.0));
        assert_eq!(p.float_at("q", Some((70, 5)), SIZE), Some(0.0));
        assert_eq!(p.float_at("q", None, SIZE), Some(0.0), "a ray of no pixel reads the value");
    }

    #[test]
    fn a_gaze_is_its_inside_value_near_the_centre_and_blends_out() {
        let mut p = RayParameters::default();
        p.set("q", 0.0.into()).unwrap();
        let gaze = RayField::Gaze { centre: [50.0, 25.0], radius: 10.0, falloff: 10.0, inside: 1.0.into() };
        p.set_field("q", Some(gaze)).unwrap();
        assert_eq!(p.float_at("q", Some((50, 25)), SIZE), Some(1.0));
        assert_eq!(p.float_at("q", Some((90, 25)), SIZE), Some(0.0));
        let mid = p.float_at("q", Some((64, 25)), SIZE).unwrap();
        assert!(mid > 0.0 && mid < 1.0, "{mid}");
        let nearer = p.float_at("q", Some((62, 25)), SIZE).unwrap();
        assert!(nearer > mid, "relevance falls with distance: {nearer} {mid}");
    }

    #[test]
    fn an_image_is_stretched_over_the_frame_and_a_callback_is_sampled() {
        let mut p = RayParameters::default();
        p.set("tint", RayValue::Color([0.0; 3])).unwrap();
        let field = RayField::sample(2, 1, |x, _| RayValue::Color([x as f32, 0.0, 1.0])).unwrap();
        p.set_field("tint", Some(field)).unwrap();
        assert_eq!(p.value_at("tint", Some((10, 40)), SIZE), Some(RayValue::Color([0.0, 0.0, 1.0])));
        assert_eq!(p.value_at("tint", Some((99, 0)), SIZE), Some(RayValue::Color([1.0, 0.0, 1.0])));
        assert!(RayField::sample(2, 1, |x, _| if x == 0 { 1.0.into() } else { RayValue::Color([0.0; 3]) }).is_err());
        assert!(RayField::sample(1, 1, |_, _| RayValue::String("a".into())).is_err());
    }

    #[test]
    fn relevance_reads_one_unless_set() {
        assert_eq!(relevance(None), 1.0);
        assert_eq!(relevance(Some(&RayValue::Float(0.3))), 0.3);
        assert_eq!(relevance(Some(&RayValue::Float(7.0))), 1.0);
        assert_eq!(relevance(Some(&RayValue::String("x".into()))), 1.0);
        let values = vec![("relevance".to_string(), RayValue::Float(0.2))];
        assert_eq!(object_value(&values, "user:relevance"), Some(&RayValue::Float(0.2)));
    }
}
