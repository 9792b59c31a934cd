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
/// `shaderid` (-1 for none); `Ci` and `alpha` out. `image`, the whole image as it was, is what
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
                let alpha = match slots.alpha {
                    Some(s) if s.varying => raw.varying[s.offset * raw.stride + lane],
                    _ => c[3],
                };
                tile.rgba[k] = [ci.x, ci.y, ci.z, alpha];
            }
        });
    }
}
