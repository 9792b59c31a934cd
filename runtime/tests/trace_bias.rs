//! RenderMan's `Attribute "trace" "bias"`: the rays a surface's shading spawns start that far
//! along, so that they pass what lies closer (`Context::trace_bias`).

mod common;

use common::{context, luminance, render, shadow_scene_with, H, W};
use rtsl_runtime::api::{ApiError, Context};
use rtsl_runtime::rib::load::load_str;

/// A surface that shows what a ray traced from it along +z sees.
const PROBE: &str = "surface probe() { Oi = 1; Ci = trace(P, vector \"world\" (0, 0, 1)); }";

/// The centre pixel of a frame looking along +z at a probe at z = 2, a red square half a unit
/// behind it and a green one far behind; `probe_attributes` and `red_attributes` are given in the
/// probe's and the red square's attribute blocks.
fn behind_the_probe(probe_attributes: &str, red_attributes: &str) -> [f32; 4] {
    let square = |z: f32| format!("Polygon \"P\" [-9 -9 {z}  9 -9 {z}  9 9 {z}  -9 9 {z}]");
    let rib = format!(
        "Format 4 4 1\nProjection \"perspective\" \"fov\" [30]\nWorldBegin\n\
         AttributeBegin {probe_attributes} Surface \"probe\" {} AttributeEnd\n\
         AttributeBegin {red_attributes} Surface \"constant\" Color [1 0 0] {} AttributeEnd\n\
         AttributeBegin Surface \"constant\" Color [0 1 0] {} AttributeEnd\nWorldEnd\n",
        square(2.0),
        square(2.5),
        square(12.0)
    );
    let mut rt = Context::new();
    rt.compile_shader("probe.sl", PROBE).expect("the probe compiles");
    let loaded = load_str(&mut rt, &rib, "bias.rib").expect("loads");
    assert_eq!(loaded.warnings.len(), 0, "{:?}", loaded.warnings);
    render(&mut rt).pixel(2, 2)
}

#[test]
fn traced_rays_start_past_the_bias_of_the_surface_that_spawns_them() {
    // Unbiased, the ray meets the red square half a unit on.
    assert_eq!(behind_the_probe("", "")[..3], [1.0, 0.0, 0.0]);
    assert_eq!(behind_the_probe("Attribute \"trace\" \"float bias\" [0.25]", "")[..3], [1.0, 0.0, 0.0]);
    // A bias longer than that starts it past the red square.
    assert_eq!(behind_the_probe("Attribute \"trace\" \"float bias\" [1]", "")[..3], [0.0, 1.0, 0.0]);
    // The bias is the spawning surface's, not the one hit.
    assert_eq!(behind_the_probe("", "Attribute \"trace\" \"float bias\" [1]")[..3], [1.0, 0.0, 0.0]);
}

#[test]
fn a_bad_trace_bias_warns_and_changes_nothing() {
    for bad in ["-1", "\"x\""] {
        let mut rt = Context::new();
        let rib = format!("WorldBegin\nAttribute \"trace\" \"bias\" [{bad}]\nWorldEnd\n");
        let loaded = load_str(&mut rt, &rib, "bad.rib").expect("loads");
        assert_eq!(loaded.warnings.len(), 1, "{bad}: {:?}", loaded.warnings);
        assert!(loaded.warnings[0].message.contains("\"trace\" \"bias\""), "{:?}", loaded.warnings);
    }
}

#[test]
fn light_shadow_rays_start_past_the_bias_of_the_surface_they_light() -> Result<(), ApiError> {
    let image = |floor: f32, cube: f32| -> Result<Vec<f32>, ApiError> {
        let mut rt = context();
        shadow_scene_with(&mut rt, 1.0, (floor, cube))?;
        let fb = render(&mut rt);
        Ok((0..H).flat_map(|y| (0..W).map(move |x| (x, y))).map(|(x, y)| luminance(&fb, x, y)).collect())
    };
    let plain = image(0.0, 0.0)?;
    // The floor's shadow rays meet the cube about 2 units up: a bias of 3 starts them past it.
    let biased = image(3.0, 0.0)?;
    let lit = plain.iter().zip(&biased).filter(|(a, b)| **b > **a + 0.05).count();
    assert!(lit > 20, "the cube's shadow is gone from {lit} pixels only");
    assert!(plain.iter().zip(&biased).all(|(a, b)| *b >= *a - 1e-6), "a bias lights, never darkens");
    // A bias shorter than the gap changes nothing, nor does the cube's own.
    assert_eq!(image(0.5, 0.0)?, plain);
    assert_eq!(image(0.0, 3.0)?, plain);
    Ok(())
}
