//! The shader preview scene of `rtsl preview`: a unit ball on a grey floor before a grey wall (for
//! reflections and refractions to show), seen a little from above, lit by a shadowed point light
//! from the upper right and a dim ambient light; its images are sRGB-encoded. The golden
//! images of the library's surface shaders are rendered in it too.

use rtsl_compiler::testshade::ParamArg;

/// The scene's RIB text at `width` by `height` pixels with `samples` by `samples` samples per
/// pixel; `ball` is the RIB statements that shade the ball (`Surface`, `Displacement`, `Color`...),
/// in the ball's own attribute block (its object space: z up through the poles).
pub fn scene(ball: &str, width: u32, height: u32, samples: u32) -> String {
    format!(
        r#"
Option "image" "string transfer" ["srgb"]
Format {width} {height} 1
PixelSamples {samples} {samples}
Projection "perspective" "fov" [30]
Rotate -10 1 0 0
Translate 0 -1.6 7.5
WorldBegin
  Attribute "light" "shadows" "on"
  LightSource "ambientlight" 1 "intensity" [0.1]
  LightSource "pointlight" 2 "intensity" [30] "from" [3 5 -4]
  AttributeBegin
    Surface "plastic"
    Color [.6 .6 .6]
    Polygon "P" [-20 0 -20  20 0 -20  20 0 20  -20 0 20]
    Polygon "P" [-20 0 12  -20 14 12  20 14 12  20 0 12]
  AttributeEnd
  AttributeBegin
    Translate 0 1 0
    Rotate -90 1 0 0
    {ball}
    Sphere 1 -1 1 360
  AttributeEnd
WorldEnd
"#
    )
}

/// A RIB shader statement (`request` is `Surface`, `Displacement`...) naming shader `name` with
/// parameter values as `rtsl shade --param` reads them: numbers are an array, anything else a
/// string. The RIB reader types them by the shader's declarations.
pub fn shader_statement(request: &str, name: &str, params: &[(String, ParamArg)]) -> Result<String, String> {
    let quoted = |s: &str| {
        if s.contains(['"', '\n', '\r', '\\']) {
            Err(format!("`{s}`: quotes, backslashes and line breaks cannot be passed"))
        } else {
            Ok(format!("\"{s}\""))
        }
    };
    let mut out = format!("{request} {}", quoted(name)?);
    for (param, value) in params {
        let value = match value {
            ParamArg::Floats(v) => format!("[{}]", v.iter().map(f32::to_string).collect::<Vec<_>>().join(" ")),
            ParamArg::String(s) => quoted(s)?,
        };
        out += &format!(" {} {value}", quoted(param)?);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parameters_become_rib_arrays_and_strings() {
        let params = [
            ("Kd".to_string(), ParamArg::Floats(vec![0.5])),
            ("specularcolor".to_string(), ParamArg::Floats(vec![1.0, 0.5, 0.25])),
            ("texturename".to_string(), ParamArg::String("grid.png".into())),
        ];
        assert_eq!(
            shader_statement("Surface", "texmap", &params).as_deref(),
            Ok(r#"Surface "texmap" "Kd" [0.5] "specularcolor" [1 0.5 0.25] "texturename" "grid.png""#)
        );
        let bad = [("texturename".to_string(), ParamArg::String("a\"b".into()))];
        assert!(shader_statement("Surface", "texmap", &bad).is_err());
    }
}
