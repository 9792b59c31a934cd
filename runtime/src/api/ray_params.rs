//! `Context`'s ray parameters: named values the frame's rays carry, per pixel (a value, regions,
//! an image, a callback, a gaze point) and per object, which shaders read with `rayinfo`
//! (`render/ray_params.rs` says where a ray's value comes from; `docs/ray_parameters.md`).

use super::*;
use crate::render::{RayField, RayValue};

impl Context {
    /// Sets ray parameter `name` (`"user:name"` is the same name) for every ray of the frames
    /// from now on, where no field or object says otherwise. A parameter keeps its type: a value
    /// of another type is an error.
    pub fn set_ray_parameter(&mut self, name: &str, value: impl Into<RayValue>) -> Result<(), ApiError> {
        Ok(self.options.ray_parameters.set(name, value.into())?)
    }

    /// Makes ray parameter `name` vary over the image (`None`: it no longer does). Its values must
    /// be of the parameter's type (set it first with [`Context::set_ray_parameter`]).
    pub fn set_ray_field(&mut self, name: &str, field: Option<RayField>) -> Result<(), ApiError> {
        Ok(self.options.ray_parameters.set_field(name, field)?)
    }

    /// Makes ray parameter `name` vary over the image as `f(x, y)` says for each pixel, sampled
    /// now at the frame's size (call it again after changing the size). Floats or triples only.
    pub fn set_ray_parameter_fn(&mut self, name: &str, f: impl FnMut(u32, u32) -> RayValue) -> Result<(), ApiError> {
        let field = RayField::sample(self.options.width, self.options.height, f)?;
        self.set_ray_field(name, Some(field))
    }

    /// Ray parameter `name` no longer exists for the frames from now on.
    pub fn remove_ray_parameter(&mut self, name: &str) {
        self.options.ray_parameters.remove(name);
    }

    /// Sets ray parameter `name` for objects built from now on (an attribute, saved and restored
    /// by [`Context::push_attributes`]): rays that reach them, and the rays their shading spawns,
    /// read this value. `None` removes the object value.
    pub fn ray_attribute(&mut self, name: &str, value: Option<RayValue>) -> Result<(), ApiError> {
        let name = crate::render::ray_params::strip_user(name);
        if name.is_empty() {
            return Err(crate::render::RayParameterError("a parameter needs a name".into()).into());
        }
        let values = &mut self.appearance.ray_values;
        values.retain(|(n, _)| n != name);
        if let Some(v) = value {
            values.push((name.to_string(), v));
        }
        Ok(())
    }
}
