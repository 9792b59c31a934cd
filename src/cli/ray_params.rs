//! Ray parameters from the command line (`--ray-param`, `--gaze`): values the frame's rays carry
//! and shaders read with `rayinfo`, and relevance-driven quality around a point
//! (docs/ray_parameters.md).

use rtsl_runtime::api::{ApiError, Context};
use rtsl_runtime::render::{RayField, RayValue, RELEVANCE};

/// The ray parameter flags `render`, `view` and `bench render` share.
#[derive(clap::Args, Debug, Clone, Default)]
pub struct RayParamArgs {
    /// A ray parameter that shaders read with `rayinfo`, `NAME=VALUE`: a number, three numbers
    /// separated by commas (a colour), or text; repeatable (docs/ray_parameters.md).
    #[arg(long = "ray-param", value_name = "NAME=VALUE", value_parser = parse_ray_param)]
    pub ray_params: Vec<(String, RayValue)>,
    /// Quality that follows relevance around a point, `X,Y,RADIUS[,FALLOFF[,OUTSIDE]]` in pixels:
    /// relevance 1 within RADIUS of pixel (X, Y), falling smoothly over FALLOFF more pixels
    /// (RADIUS by default) to OUTSIDE (0 by default) beyond. The library shaders and the renderer
    /// lower samples per pixel, reflection depth and shadow samples with it.
    #[arg(long, value_name = "X,Y,RADIUS[,FALLOFF[,OUTSIDE]]", value_parser = Gaze::parse)]
    pub gaze: Option<Gaze>,
}

/// A gaze point: full relevance around it, `outside` far from it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Gaze {
    pub centre: [f32; 2],
    pub radius: f32,
    pub falloff: f32,
    pub outside: f32,
}

impl Gaze {
    pub fn parse(s: &str) -> Result<Gaze, String> {
        let v: Vec<f32> = s
            .split(',')
            .map(|x| x.trim().parse::<f32>().map_err(|_| format!("`{x}` in `{s}` is not a number")))
            .collect::<Result<_, _>>()?;
        if !(3..=5).contains(&v.len()) || v.iter().any(|x| !x.is_finite()) {
            return Err(format!("`{s}` is not X,Y,RADIUS[,FALLOFF[,OUTSIDE]] (three to five finite numbers)"));
        }
        let gaze = Gaze {
            centre: [v[0], v[1]],
            radius: v[2],
            falloff: v.get(3).copied().unwrap_or(v[2]),
            outside: v.get(4).copied().unwrap_or(0.0),
        };
        if gaze.radius < 0.0 || gaze.falloff < 0.0 || !(0.0..=1.0).contains(&gaze.outside) {
            return Err(format!("`{s}`: the radius and falloff are at least 0, and OUTSIDE is from 0 to 1"));
        }
        Ok(gaze)
    }

    /// Sets the relevance of `rt`'s frames to follow this gaze point.
    pub fn apply(&self, rt: &mut Context) -> Result<(), ApiError> {
        rt.set_ray_parameter(RELEVANCE, self.outside)?;
        let field =
            RayField::Gaze { centre: self.centre, radius: self.radius, falloff: self.falloff, inside: 1.0.into() };
        rt.set_ray_field(RELEVANCE, Some(field))
    }

    /// Whether pixel `(x, y)` (its centre) lies within the full-relevance radius, and beyond the
    /// falloff.
    pub fn inside(&self, x: u32, y: u32) -> bool {
        self.distance(x, y) <= self.radius
    }

    pub fn outside(&self, x: u32, y: u32) -> bool {
        self.distance(x, y) >= self.radius + self.falloff
    }

    fn distance(&self, x: u32, y: u32) -> f32 {
        let (dx, dy) = (x as f32 + 0.5 - self.centre[0], y as f32 + 0.5 - self.centre[1]);
        (dx * dx + dy * dy).sqrt()
    }
}

/// `NAME=VALUE` of `--ray-param`.
fn parse_ray_param(arg: &str) -> Result<(String, RayValue), String> {
    let (name, value) = arg.split_once('=').ok_or_else(|| format!("expected NAME=VALUE, got `{arg}`"))?;
    let name = name.trim();
    if name.is_empty() {
        return Err(format!("no parameter name in `{arg}`"));
    }
    let numbers: Result<Vec<f32>, _> = value.split(',').map(|v| v.trim().parse::<f32>()).collect();
    let value = match numbers {
        Ok(n) if n.len() == 1 => RayValue::Float(n[0]),
        Ok(n) if n.len() == 3 => RayValue::Color([n[0], n[1], n[2]]),
        Ok(n) => return Err(format!("`{arg}`: a ray parameter is one number or three, not {}", n.len())),
        Err(_) => RayValue::String(value.to_string()),
    };
    Ok((name.to_string(), value))
}

impl RayParamArgs {
    /// Sets the parameters and the gaze on `rt`'s frames.
    pub fn apply(&self, rt: &mut Context) -> Result<(), ApiError> {
        for (name, value) in &self.ray_params {
            rt.set_ray_parameter(name, value.clone())?;
        }
        if let Some(g) = &self.gaze {
            g.apply(rt)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flags_parse_into_values_and_a_gaze() {
        assert_eq!(parse_ray_param("q=0.5"), Ok(("q".into(), RayValue::Float(0.5))));
        assert_eq!(parse_ray_param("c=1,0,0"), Ok(("c".into(), RayValue::Color([1.0, 0.0, 0.0]))));
        assert_eq!(parse_ray_param("s=hero"), Ok(("s".into(), RayValue::String("hero".into()))));
        assert!(parse_ray_param("c=1,2").is_err());
        assert!(parse_ray_param("=1").is_err());
        let g = Gaze::parse("320,240,80").unwrap();
        assert_eq!((g.radius, g.falloff, g.outside), (80.0, 80.0, 0.0));
        assert!(g.inside(320, 240) && !g.inside(320, 400) && g.outside(320, 479) && !g.outside(330, 250));
        assert_eq!(Gaze::parse("1,2,3,4,0.25").unwrap().outside, 0.25);
        for bad in ["1,2", "1,2,3,4,5,6", "1,2,-3", "1,2,3,4,2", "1,x,3", "1,2,inf"] {
            assert!(Gaze::parse(bad).is_err(), "{bad}");
        }
    }
}
