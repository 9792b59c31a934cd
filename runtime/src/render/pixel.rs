//! The pixel shader's pass (RenderMan's imager): over a finished tile, 64 pixels a batch, after
//! the film has been filtered.

use super::host::ShadeCall;
use super::ray_budget::RayBudget;
use super::stats::ShadingTimer;
use super::work::{Frame, PixelImage};
use crate::ray::PACKET_SIZE;
use crate::shading::{get3, put1, put3, with_batch};
use glam::Vec3A;

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

/// Whether the world's pixel shader reads other pixels (`pixelvalue`): it then runs over the
/// whole image at once, after every tile is in.
pub fn reads_pixels(world: &super::World) -> bool {
    world.pixel.as_ref().is_some_and(|p| p.program.code.reads_pixels())
}

/// Runs the world's pixel shader (RenderMan's imager) over a finished tile, 64 pixels a batch: `Ci`,
/// `Oi` and `alpha` in, `P` the raster position of the pixel's centre, `zdepth`, `objectid` and
/// `shaderid` (-1 for none); `Ci` and `alpha` out (or where the shader sets `Oi` and not `alpha`,
/// the mean of `Oi`). `image`, the whole image as it was, is what
/// `pixelvalue` reads (without it, `pixelvalue` answers 0).
pub fn shade_pixels(frame: &Frame, tile: TilePixels<'_>, image: Option<&PixelImage>) {
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
                    // Pixie's `s` and `t` of imagers: the pixel's centre over the image, 0 to 1.
                    let (w, h) = (frame.world.options.width.max(1) as f32, frame.world.options.height.max(1) as f32);
                    put1(&mut raw, slots.s, lane, (x as f32 + 0.5) / w);
                    put1(&mut raw, slots.t, lane, (y as f32 + 0.5) / h);
                    put1(&mut raw, slots.zdepth, lane, tile.depth[k]);
                    put1(&mut raw, slots.objectid, lane, id(tile.object_id[k]));
                    put1(&mut raw, slots.shaderid, lane, id(tile.shader_id[k]));
                    put1(&mut raw, slots.ncomps, lane, 3.0);
                }
            }
            // Each pixel the root of the rays its shader spawns.
            let width = frame.world.options.width;
            let mut budgets: Vec<RayBudget> = (start..start + lanes)
                .map(|k| {
                    let (x, y) = (tile.x0 + k as u32 % tile.width, tile.y0 + k as u32 / tile.width);
                    RayBudget::from_pixel(y.saturating_mul(width).saturating_add(x))
                })
                .collect();
            let mut call = ShadeCall::new(frame, imager, imager.world_from_shader, 0, &mut budgets);
            call.pixels = image;
            let table = call.table();
            program.code.shade_with_table(batch, &table);
            let raw = batch.raw_mut();
            for lane in 0..lanes {
                let k = start + lane;
                let c = tile.rgba[k];
                let ci = get3(&raw, slots.ci, lane, Vec3A::new(c[0], c[1], c[2]));
                let alpha = match (slots.alpha, slots.oi) {
                    (Some(s), _) if s.written && s.varying => raw.varying[s.offset * raw.stride + lane],
                    (Some(s), _) if s.written => raw.uniform[s.offset],
                    // RISpec's `Oi` out is the output pixel's opacity: a shader that sets it and
                    // not `alpha` gives the pixel that coverage (the mean of its channels).
                    (_, Some(s)) if s.written => {
                        let oi = get3(&raw, Some(s), lane, Vec3A::splat(c[3]));
                        (oi.x + oi.y + oi.z) / 3.0
                    }
                    _ => c[3],
                };
                tile.rgba[k] = [ci.x, ci.y, ci.z, alpha];
            }
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An 8 x 8 image whose pixels all differ, with a pixel that sees nothing (ids `u32::MAX`, a
    /// zero normal) and ids that a float cannot hold exactly.
    fn image() -> PixelImage {
        let n = 64;
        let f = |i: usize, k: usize| i as f32 * 0.25 + k as f32 * 0.0625 - 3.0;
        let id = |i: usize| match i {
            9 => u32::MAX,
            10 => 16_777_217,
            11 => u32::MAX - 1,
            _ => 3 * i as u32 + 1,
        };
        PixelImage {
            width: 8,
            height: 8,
            rgba: (0..n).map(|i| [f(i, 0), f(i, 1), f(i, 2), f(i, 3)]).collect(),
            depth: (0..n).map(|i| f(i, 4)).collect(),
            object_id: (0..n).map(id).collect(),
            shader_id: (0..n).map(|i| id(i).wrapping_add(5)).collect(),
            normal: (0..n).map(|i| if i == 9 { [0.0; 3] } else { [f(i, 5), f(i, 6), f(i, 7)] }).collect(),
            outputs: vec![("glow".to_string(), (0..n).map(|i| [f(i, 8), f(i, 9), f(i, 10)]).collect())],
        }
    }

    /// The raster coordinates the probe reads at pixel `(i, j)`: inside, outside, on edges, huge,
    /// negative zero, and (column and row 7) infinite and NaN.
    fn probe_at(i: usize, j: usize) -> (f32, f32) {
        let xs = [-1e30, -1.5, -0.0, 0.5, 2.99, 7.0, 3e9, f32::INFINITY];
        let ys = [6.5, 1e30, -0.25, 7.999, 8.0, 3.0, -3e9, f32::NAN];
        (xs[i], ys[j])
    }

    const PROBE: &str = r#"
        pixel probe(string channel = "Ci"; float literal = 1; float scalar = 0)
        {
            float xs[8] = {-1e30, -1.5, -0.0, 0.5, 2.99, 7.0, 3e9, 0};
            float ys[8] = {6.5, 1e30, -0.25, 7.999, 8.0, 3.0, -3e9, 0};
            float i = floor(xcomp(P)), j = floor(ycomp(P));
            float cx = xs[i], cy = ys[j];
            float huge = 1e30 * 1e30;
            if (i == 7) cx = huge;
            if (j == 7) cy = huge - huge;
            color v = 0;
            if (literal == 0) {
                v = color pixelvalue(channel, cx, cy);
            } else if (scalar != 0) {
                float f = 0;
                if (channel == "alpha") f = pixelvalue("alpha", cx, cy);
                if (channel == "z") f = pixelvalue("z", cx, cy);
                if (channel == "objectid") f = pixelvalue("objectid", cx, cy);
                if (channel == "shaderid") f = pixelvalue("shaderid", cx, cy);
                if (channel == "Ci") f = pixelvalue("Ci", cx, cy);
                if (channel == "N") f = pixelvalue("N", cx, cy);
                if (channel == "glow") f = pixelvalue("glow", cx, cy);
                v = f;
            } else {
                if (channel == "alpha") v = color pixelvalue("alpha", cx, cy);
                if (channel == "z") v = color pixelvalue("z", cx, cy);
                if (channel == "objectid") v = color pixelvalue("objectid", cx, cy);
                if (channel == "shaderid") v = color pixelvalue("shaderid", cx, cy);
                if (channel == "Ci") v = color pixelvalue("Ci", cx, cy);
                if (channel == "N") v = color pixelvalue("N", cx, cy);
                if (channel == "glow") v = color pixelvalue("glow", cx, cy);
            }
            Ci = v;
        }
    "#;

    /// What the probe leaves in each pixel of the image for `channel`, read by name at run time
    /// (`literal` 0: through the renderer's `texture` callback) or named by a literal (read by
    /// the generated code from the image), as a colour or (`scalar`) a float.
    fn probe(channel: &str, literal: bool, scalar: bool) -> Vec<[u32; 3]> {
        let rib = format!(
            "Format 8 8 1\nImager \"probe\" \"string channel\" [\"{channel}\"] \"float literal\" [{}] \"float scalar\" [{}]\nWorldBegin\nWorldEnd\n",
            u8::from(literal),
            u8::from(scalar)
        );
        let mut rt = crate::api::Context::new();
        rt.compile_shader("probe", PROBE).expect("the probe compiles");
        crate::rib::load::load_str(&mut rt, &rib, std::path::Path::new("<test>")).expect("the test scene loads");
        let world = rt.build_world().expect("the test scene builds");
        assert!(reads_pixels(&world), "the probe reads other pixels");
        let frame = Frame::new(&world);
        let image = image();
        let mut rgba = vec![[0.0f32; 4]; 64];
        let tile = TilePixels {
            x0: 0,
            y0: 0,
            width: 8,
            rgba: &mut rgba,
            depth: &image.depth,
            object_id: &image.object_id,
            shader_id: &image.shader_id,
        };
        shade_pixels(&frame, tile, Some(&image));
        rgba.iter().map(|c| [c[0].to_bits(), c[1].to_bits(), c[2].to_bits()]).collect()
    }

    /// `pixelvalue` of a channel named by a literal, which generated code reads from the image
    /// itself, gives what the image's own lookup (`PixelImage::value`, the interpreter's and the
    /// renderer's callback's) gives, bit for bit: for every channel, as a colour and as a float,
    /// at coordinates inside, outside, huge, infinite and NaN. An output variable the image keeps
    /// (`glow`) is read through the callback either way; a channel it does not have is zero.
    #[test]
    fn pixelvalue_read_inline_is_the_images_own_lookup() {
        let image = image();
        assert!(image.value("glow", 2.5, 3.5).is_some_and(|v| v != [0.0; 3]), "the image keeps an output");
        for channel in ["Ci", "alpha", "z", "objectid", "shaderid", "N", "glow", "nosuch"] {
            for scalar in [false, true] {
                let expected: Vec<[u32; 3]> = (0..64)
                    .map(|k| {
                        let (x, y) = probe_at(k % 8, k / 8);
                        let v = image.value(channel, x, y).unwrap_or([0.0; 3]);
                        let v = if scalar { [v[0]; 3] } else { v };
                        v.map(f32::to_bits)
                    })
                    .collect();
                let by_callback = probe(channel, false, scalar);
                let inline = probe(channel, true, scalar);
                if !scalar {
                    assert_eq!(by_callback, expected, "{channel} through the callback");
                }
                assert_eq!(inline, expected, "{channel} read inline, scalar {scalar}");
            }
        }
        // The probe reaches the cases it is about.
        let ids: Vec<f32> =
            (0..64).filter_map(|k| image.value("objectid", (k % 8) as f32, (k / 8) as f32)).map(|v| v[0]).collect();
        assert!(ids.contains(&-1.0) && ids.contains(&16_777_216.0));
    }
}
