//! Camera shaders and motion blur through the API and RIB: the `pinhole` shader makes the built-in
//! camera's image, the other library cameras see what their mappings promise, invalid rays are
//! empty pixels, depth of field blurs only what is off the focal plane, and moving instances smear
//! over the shutter interval.

mod common;

use common::luminance as sum;
use common::{quad, H, W};
use glam::{Affine3A, Vec3, Vec3A};
use rtsl_runtime::api::{ApiError, Context, Deformation, Mesh, ObjectId};
use rtsl_runtime::render::{Antialiasing, FrameReport, Framebuffer};
use rtsl_runtime::shading::ParamValue;

/// The shared context, sampled on a fixed grid.
fn context() -> Context {
    let mut rt = common::context();
    rt.options.antialiasing = Antialiasing::Grid { jitter: false };
    rt
}

/// A square of side 2 facing +z at the origin, with a `constant` shader of colour `c`.
fn card(rt: &mut Context, c: [f32; 3]) -> Result<ObjectId, ApiError> {
    let constant = rt.find_shader("constant")?;
    let id = rt.begin_object()?;
    rt.bind_shader(constant)?;
    rt.color(c[0], c[1], c[2]);
    quad(rt, [[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [-1.0, 1.0, 0.0]])?;
    rt.end_object()?;
    Ok(id)
}

/// An unlit checkerboard in world x and y, `frequency` squares per unit.
const CHECKS: &str = "surface checks(float frequency = 2) {
    point Pw = transform(\"world\", P);
    Ci = mod(floor(xcomp(Pw) * frequency) + floor(ycomp(Pw) * frequency), 2);
    Oi = 1;
}";

/// A checkerboard wall facing -z at depth `z`.
fn checker_wall(rt: &mut Context, z: f32, size: f32) -> Result<(), ApiError> {
    let checker = rt.compile_shader("checks", CHECKS)?;
    let id = rt.begin_object()?;
    rt.bind_shader(checker)?;
    let s = size;
    quad(rt, [[-s, -s, z], [s, -s, z], [s, s, z], [-s, s, z]])?;
    rt.end_object()?;
    rt.instantiate_object(id)?;
    Ok(())
}

fn bind_camera(rt: &mut Context, name: &str, params: &[(&str, ParamValue)]) -> Result<(), ApiError> {
    let id = rt.find_shader(name)?;
    rt.camera_shader(Some(id), params)
}

#[test]
fn the_pinhole_shader_makes_the_built_in_cameras_image() -> Result<(), ApiError> {
    let mut rt = context();
    rt.camera_look_at(Vec3A::new(0.3, 0.5, -5.0), Vec3A::ZERO, Vec3A::Y, 50.0);
    checker_wall(&mut rt, 0.0, 3.0)?;
    let (builtin, _) = rt.render_frame()?;
    bind_camera(&mut rt, "pinhole", &[])?;
    let (shader, report) = rt.render_frame()?;
    assert_eq!(report.primary_rays, u64::from(W * H));
    let mut worst = 0.0f32;
    for (a, b) in builtin.rgba.iter().zip(&shader.rgba) {
        worst = worst.max((a - b).abs());
    }
    // The rays agree to rounding; a checker edge may fall on the other side in a pixel or two.
    let differing =
        builtin.rgba.chunks(4).zip(shader.rgba.chunks(4)).filter(|(a, b)| (a[0] - b[0]).abs() > 1e-3).count();
    assert!(differing <= 4, "{differing} pixels differ (worst {worst})");
    // And back to the built-in camera.
    rt.camera_shader(None, &[])?;
    let (again, _) = rt.render_frame()?;
    assert_eq!(again.rgba, builtin.rgba);
    Ok(())
}

/// The `pinhole` shader's rays are the built-in camera's, and so are their differentials (the
/// shader's come from differences across each 2x2 quad of the packet, the built-in camera's are
/// exact); a tile's packets made in one shader call are each packet's made alone, bit for bit.
#[test]
fn the_pinhole_shaders_rays_and_differentials_are_the_built_in_cameras() -> Result<(), ApiError> {
    use rtsl_runtime::render::primary::{pinhole_ray, primary_rays_of_packets, PacketSamples};
    use rtsl_runtime::render::{camera_samples, primary_rays, Frame, PrimaryRays};
    let mut rt = context();
    rt.camera_look_at(Vec3A::new(0.3, 0.5, -5.0), Vec3A::ZERO, Vec3A::Y, 50.0);
    checker_wall(&mut rt, 0.0, 3.0)?;
    bind_camera(&mut rt, "pinhole", &[])?;
    let mut world = rt.build_world()?;
    let shader = world.camera_shader.clone();
    let corners = [(0, 0), (8, 0), (0, 8), (56, 40)];
    let packets: Vec<PacketSamples> = corners
        .iter()
        .map(|&(x, y)| {
            let (samples, active) = camera_samples(&world, x, y, (0, 0));
            PacketSamples::new(samples, active)
        })
        .collect();
    let mut together = vec![PrimaryRays::default(); packets.len()];
    primary_rays_of_packets(&Frame::new(&world), &packets, &mut together);
    for (p, made) in packets.iter().zip(&together) {
        let alone = primary_rays(&Frame::new(&world), &p.samples, p.active);
        assert_eq!(alone.packet.active, made.packet.active);
        for lane in (0..64).filter(|l| alone.packet.active >> l & 1 != 0) {
            assert_eq!(alone.packet.get(lane), made.packet.get(lane), "lane {lane}");
            assert_eq!(alone.diffs.lane(lane), made.diffs.lane(lane), "lane {lane}");
        }
    }
    // A frame's packets say that their samples are one pixel apart (`unit_steps`), which skips
    // working the steps out from the raster positions: the same differentials.
    let on_grid: Vec<PacketSamples> = packets.iter().map(|p| PacketSamples { unit_steps: true, ..*p }).collect();
    let mut by_grid = vec![PrimaryRays::default(); packets.len()];
    primary_rays_of_packets(&Frame::new(&world), &on_grid, &mut by_grid);
    for (p, (made, grid)) in packets.iter().zip(together.iter().zip(&by_grid)) {
        assert_eq!(made.packet.active, grid.packet.active);
        for lane in (0..64).filter(|l| p.active >> l & 1 != 0) {
            assert_eq!(made.packet.get(lane), grid.packet.get(lane), "lane {lane}");
            let (a, b) = (made.diffs.lane(lane), grid.diffs.lane(lane));
            for (x, y) in [(a.dddx, b.dddx), (a.dddy, b.dddy), (a.dodx, b.dodx), (a.dody, b.dody)] {
                assert!((x - y).length() <= 1e-6 * x.length().max(1e-6), "lane {lane}: {x} {y}");
            }
        }
    }
    world.camera_shader = None;
    for (p, made) in packets.iter().zip(&together) {
        let builtin = primary_rays(&Frame::new(&world), &p.samples, p.active);
        assert_eq!(builtin.packet.active, made.packet.active);
        for lane in (0..64).filter(|l| builtin.packet.active >> l & 1 != 0) {
            // The built-in camera's own differentials are its rays' change per pixel (central
            // differences over a pixel's step, raster y down).
            let (x, y) = p.samples[lane].raster;
            let along = |dx: f32, dy: f32| {
                pinhole_ray(&world, (x + dx / 2.0, y + dy / 2.0)).direction
                    - pinhole_ray(&world, (x - dx / 2.0, y - dy / 2.0)).direction
            };
            let d = builtin.diffs.lane(lane);
            for (want, got) in [(along(1.0, 0.0), d.dddx), (along(0.0, 1.0), d.dddy)] {
                assert!((want - got).length() <= 1e-3 * want.length(), "lane {lane}: {want} {got}");
            }
            let (a, b) = (builtin.packet.get(lane), made.packet.get(lane));
            assert!((a.origin - b.origin).length() < 1e-5 && (a.direction - b.direction).length() < 1e-5);
            let (da, db) = (builtin.diffs.lane(lane), made.diffs.lane(lane));
            // A pixel's step turns the ray by about 0.9 degrees: finite differences over one step
            // agree with the derivative to a few per cent.
            for (x, y) in [(da.dddx, db.dddx), (da.dddy, db.dddy)] {
                assert!((x - y).length() <= 0.05 * x.length(), "lane {lane}: {x} {y}");
            }
            assert!(db.dodx.length() < 1e-6 && db.dody.length() < 1e-6);
        }
    }
    world.camera_shader = shader;
    rt.return_scene(world);
    Ok(())
}

#[test]
fn the_fisheye_leaves_the_corners_empty_and_sees_wider() -> Result<(), ApiError> {
    let mut rt = context();
    rt.camera_look_at(Vec3A::ZERO, Vec3A::Z, Vec3A::Y, 40.0);
    // A card far off to the side: outside a 40 degree view, inside a 180 degree fisheye.
    let id = card(&mut rt, [1.0, 0.0, 0.0])?;
    rt.push_matrix();
    rt.translate(4.0, 0.0, 2.0);
    rt.rotate(-90.0, 0.0, 1.0, 0.0);
    rt.instantiate_object(id)?;
    rt.pop_matrix()?;
    let (narrow, _) = rt.render_frame()?;
    assert!(narrow.rgba.chunks(4).all(|p| p[0] == 0.0), "the pinhole camera does not see the card");
    bind_camera(&mut rt, "fisheye", &[("fov", ParamValue::Float(180.0))])?;
    let (fish, report) = rt.render_frame()?;
    // Corners are outside the image circle: no ray, alpha 0.
    for (x, y) in [(0, 0), (W - 1, 0), (0, H - 1), (W - 1, H - 1)] {
        assert_eq!(fish.pixel(x, y), [0.0; 4], "corner {x},{y}");
    }
    assert!(report.primary_rays < u64::from(W * H), "rays outside the circle are not traced");
    // The card, 63 degrees off the axis towards world +x (the camera looks down +z with y up, so
    // world +x is the image's left), lands in the left half.
    let red: Vec<(u32, u32)> =
        (0..H).flat_map(|y| (0..W).map(move |x| (x, y))).filter(|&(x, y)| fish.pixel(x, y)[0] > 0.5).collect();
    assert!(!red.is_empty(), "the fisheye sees the card");
    assert!(red.iter().all(|&(x, _)| x < W / 2), "{red:?}");
    Ok(())
}

/// A full-frame fisheye (fit "diagonal") spans its angle from corner to corner: the corners look
/// `fov / 2` off the axis, every pixel makes a ray, and the edge's middle looks at its share of
/// the half diagonal.
#[test]
fn the_full_frame_fisheye_spans_its_angle_corner_to_corner() -> Result<(), ApiError> {
    use rtsl_runtime::render::{primary_rays, CameraSample, Frame};
    let mut rt = context();
    rt.camera_look_at(Vec3A::ZERO, Vec3A::Z, Vec3A::Y, 40.0);
    let fit = ("fit", ParamValue::String("diagonal".into()));
    bind_camera(&mut rt, "fisheye", &[("fov", ParamValue::Float(180.0)), fit])?;
    let (image, report) = rt.render_frame()?;
    assert_eq!(report.primary_rays, u64::from(W * H), "every pixel sees");
    assert_eq!(image.width, W);
    let world = rt.build_world()?;
    let mut samples = [CameraSample::default(); rtsl_runtime::ray::PACKET_SIZE];
    let (w, h) = (W as f32, H as f32);
    for (sample, raster) in samples.iter_mut().zip([(0.0, 0.0), (w / 2.0, h / 2.0), (w, h / 2.0)]) {
        sample.raster = raster;
    }
    let rays = primary_rays(&Frame::new(&world), &samples, 0b111);
    rt.return_scene(world);
    assert_eq!(rays.packet.active, 0b111);
    let angle = |l: usize| {
        let d = Vec3A::new(rays.packet.dx.0[l], rays.packet.dy.0[l], rays.packet.dz.0[l]);
        d.angle_between(Vec3A::Z).to_degrees()
    };
    let aspect = w / h;
    let edge = 90.0 * aspect / (1.0 + aspect * aspect).sqrt();
    for (lane, want) in [(0, 90.0), (1, 0.0), (2, edge)] {
        assert!((angle(lane) - want).abs() < 0.05, "lane {lane}: {} degrees, not {want}", angle(lane));
    }
    Ok(())
}

#[test]
fn the_cylindrical_panorama_sees_behind_the_camera() -> Result<(), ApiError> {
    let mut rt = context();
    rt.camera_look_at(Vec3A::ZERO, Vec3A::Z, Vec3A::Y, 40.0);
    let id = card(&mut rt, [0.0, 1.0, 0.0])?;
    rt.push_matrix();
    rt.translate(0.0, 0.0, -4.0);
    rt.instantiate_object(id)?;
    rt.pop_matrix()?;
    bind_camera(&mut rt, "cylindrical", &[("hfov", ParamValue::Float(360.0))])?;
    let (pano, _) = rt.render_frame()?;
    // Behind the camera is the image's left and right edges; its front, the centre, sees nothing.
    assert!(pano.pixel(0, H / 2)[1] > 0.5 && pano.pixel(W - 1, H / 2)[1] > 0.5);
    assert_eq!(pano.pixel(W / 2, H / 2)[1], 0.0);
    Ok(())
}

#[test]
fn the_parabolic_mirror_sees_more_than_a_hemisphere_in_a_disc() -> Result<(), ApiError> {
    let mut rt = context();
    rt.camera_look_at(Vec3A::ZERO, Vec3A::Z, Vec3A::Y, 40.0);
    let id = card(&mut rt, [0.0, 0.0, 1.0])?;
    // A card beside and a little behind the camera (110 degrees off the axis).
    rt.push_matrix();
    rt.translate(-4.0, 0.0, -1.5);
    rt.rotate(90.0, 0.0, 1.0, 0.0);
    rt.instantiate_object(id)?;
    rt.pop_matrix()?;
    bind_camera(&mut rt, "parabolic", &[("scale", ParamValue::Float(1.6)), ("radius", ParamValue::Float(1.0))])?;
    let (para, _) = rt.render_frame()?;
    let blue: Vec<(u32, u32)> =
        (0..H).flat_map(|y| (0..W).map(move |x| (x, y))).filter(|&(x, y)| para.pixel(x, y)[2] > 0.5).collect();
    assert!(!blue.is_empty(), "the mirror sees behind the camera's side");
    assert!(blue.iter().all(|&(x, _)| x > W / 2), "the card (world -x) is on the image's right: {blue:?}");
    assert_eq!(para.pixel(0, 0), [0.0; 4], "outside the image circle");
    Ok(())
}

/// The mean absolute difference of neighbouring pixels in a row band: high for a sharp checker,
/// low once it is blurred.
fn contrast(fb: &Framebuffer, rows: std::ops::Range<u32>, cols: std::ops::Range<u32>) -> f32 {
    let mut total = 0.0;
    let mut n = 0;
    for y in rows {
        for x in cols.clone().skip(1) {
            total += (sum(fb, x, y) - sum(fb, x - 1, y)).abs();
            n += 1;
        }
    }
    total / n as f32
}

#[test]
fn depth_of_field_blurs_only_what_is_off_the_focal_plane() -> Result<(), ApiError> {
    let mut rt = context();
    rt.options.samples = (4, 4);
    rt.camera_look_at(Vec3A::new(0.0, 0.0, -5.0), Vec3A::ZERO, Vec3A::Y, 40.0);
    // Two checker walls, side by side: on the image's right (world -x: the camera looks down +z)
    // one on the focal plane (5 away), on the left one far behind (30 away).
    let checker = rt.compile_shader("checks", CHECKS)?;
    for (x0, z, s) in [(-3.0f32, 0.0f32, 3.0f32), (0.0, 25.0, 18.0)] {
        let id = rt.begin_object()?;
        rt.bind_shader(checker)?;
        rt.parameter("frequency", ParamValue::Float(if z > 0.0 { 1.0 } else { 6.0 }))?;
        let x1 = if x0 < 0.0 { 0.0 } else { 2.0 * s };
        quad(&mut rt, [[x0 * s / 3.0, -s, z], [x1, -s, z], [x1, s, z], [x0 * s / 3.0, s, z]])?;
        rt.end_object()?;
        rt.instantiate_object(id)?;
    }
    let (sharp, _) = rt.render_frame()?;
    bind_camera(
        &mut rt,
        "thinlens",
        &[
            ("fstop", ParamValue::Float(0.5)),
            ("focallength", ParamValue::Float(1.0)),
            ("focaldistance", ParamValue::Float(5.0)),
        ],
    )?;
    let (dof, _) = rt.render_frame()?;
    let (far, near) = (4..W / 2 - 4, W / 2 + 4..W - 4);
    let rows = 8..H - 8;
    let (sn, sf) = (contrast(&sharp, rows.clone(), near.clone()), contrast(&sharp, rows.clone(), far.clone()));
    let (dn, df) = (contrast(&dof, rows.clone(), near), contrast(&dof, rows, far));
    assert!(sn > 0.05 && sf > 0.05, "both walls show their checks without depth of field: {sn} {sf}");
    assert!(dn > 0.7 * sn, "the focal plane stays sharp: {dn} vs {sn}");
    assert!(df < 0.5 * sf, "the far wall is blurred: {df} vs {sf}");
    Ok(())
}

/// The lens sample is uniform in camera shaders. A frame gives every packet of a tile one lens
/// sample (so a tile's rays take one call of the thin lens); a packet whose lanes have different
/// lens samples (an application's own) still gives each lane the ray of its own lens sample.
#[test]
fn each_lane_gets_the_ray_of_its_own_lens_sample() -> Result<(), ApiError> {
    use rtsl_runtime::render::{camera_samples, primary_rays, Frame, TILE_SIZE};
    let mut rt = context();
    rt.camera_look_at(Vec3A::new(0.0, 0.0, -5.0), Vec3A::ZERO, Vec3A::Y, 40.0);
    checker_wall(&mut rt, 0.0, 3.0)?;
    let lens = [("fstop", ParamValue::Float(0.5)), ("focallength", ParamValue::Float(1.0))];
    bind_camera(&mut rt, "thinlens", &lens)?;
    let world = rt.build_world()?;
    let frame = Frame::new(&world);
    let (first, _) = camera_samples(&world, 0, 0, (0, 0));
    for corner in [(8, 0), (0, 8), (8, 8)] {
        let (other, _) = camera_samples(&world, corner.0, corner.1, (0, 0));
        assert_eq!(first[0].lens, other[0].lens, "the packets of a tile share a lens sample");
    }
    let (next_tile, _) = camera_samples(&world, TILE_SIZE, 0, (0, 0));
    assert_ne!(first[0].lens, next_tile[0].lens, "the next tile has its own");
    let choices = [(0.1, 0.2), (0.7, 0.9), (0.5, 0.5), (0.95, 0.3)];
    let mut mixed = first;
    for (l, s) in mixed.iter_mut().enumerate() {
        s.lens = choices[(l / 3) % choices.len()];
    }
    let rays = primary_rays(&frame, &mixed, u64::MAX);
    for lens in choices {
        let mut same = mixed;
        for s in same.iter_mut() {
            s.lens = lens;
        }
        let alone = primary_rays(&frame, &same, u64::MAX);
        for l in (0..64).filter(|&l| mixed[l].lens == lens) {
            assert_eq!(rays.packet.get(l), alone.packet.get(l), "lane {l}");
            assert_eq!(rays.weight(l), alone.weight(l), "lane {l}");
        }
    }
    // The lens sample matters: lanes with different ones start from different points.
    assert_ne!(rays.packet.get(0).origin, rays.packet.get(3).origin);
    rt.return_scene(world);
    Ok(())
}

/// A checker wall seen through the camera shader `src` (named `name`) and through the built-in
/// camera: the frame (with its report) and the built-in camera's image.
fn weighted_and_plain(name: &str, src: &str) -> Result<(Framebuffer, FrameReport, Framebuffer), ApiError> {
    let mut rt = context();
    rt.camera_look_at(Vec3A::new(0.0, 0.0, -5.0), Vec3A::ZERO, Vec3A::Y, 40.0);
    checker_wall(&mut rt, 0.0, 5.0)?;
    let id = rt.compile_shader(name, src)?;
    rt.camera_shader(Some(id), &[])?;
    let (weighted, report) = rt.render_frame()?;
    rt.camera_shader(None, &[])?;
    let (plain, _) = rt.render_frame()?;
    Ok((weighted, report, plain))
}

#[test]
fn a_zero_weight_makes_an_empty_pixel() -> Result<(), ApiError> {
    // A camera shader that keeps only the left half of the image, at half weight.
    let src = r#"camera halfleft() { Ci = (s < 0) ? color(.5, .5, .5) : 0; }"#;
    let (half, report, full) = weighted_and_plain("halfleft", src)?;
    assert_eq!(report.primary_rays, u64::from(W * H / 2));
    for y in 0..H {
        for x in 0..W {
            let (a, b) = (half.pixel(x, y), full.pixel(x, y));
            if x < W / 2 {
                for c in 0..4 {
                    assert!((a[c] - 0.5 * b[c]).abs() < 1e-4, "{x},{y}: {a:?} vs {b:?}");
                }
            } else {
                assert_eq!(a, [0.0; 4], "{x},{y}");
            }
        }
    }
    Ok(())
}

/// Each ray keeps its own weight: a camera weighting odd and even columns differently (every 2x2
/// quad of a packet mixes both) scales each pixel of the built-in camera's image by its own.
#[test]
fn each_ray_keeps_its_own_weight() -> Result<(), ApiError> {
    let src = r#"camera columns() { Ci = (mod(floor(xcomp(P)), 2) == 0) ? color(.5, .25, 1) : color(.25, 1, .5); }"#;
    let (weighted, _, full) = weighted_and_plain("columns", src)?;
    for y in 0..H {
        for x in 0..W {
            let w = if x % 2 == 0 { [0.5, 0.25, 1.0] } else { [0.25, 1.0, 0.5] };
            let (a, b) = (weighted.pixel(x, y), full.pixel(x, y));
            for c in 0..3 {
                assert!((a[c] - w[c] * b[c]).abs() < 1e-4, "{x},{y}: {a:?} vs {b:?}");
            }
        }
    }
    Ok(())
}

#[test]
fn a_camera_shader_of_the_wrong_kind_is_refused() -> Result<(), ApiError> {
    let mut rt = context();
    let plastic = rt.find_shader("plastic")?;
    assert!(matches!(rt.camera_shader(Some(plastic), &[]), Err(ApiError::WrongKind { .. })));
    Ok(())
}

/// A small white card moving from x = -2 to x = 2 over the shutter, in front of a black
/// background.
fn moving_card(rt: &mut Context) -> Result<(), ApiError> {
    rt.camera_look_at(Vec3A::new(0.0, 0.0, -6.0), Vec3A::ZERO, Vec3A::Y, 60.0);
    let id = card(rt, [1.0, 1.0, 1.0])?;
    rt.push_matrix();
    rt.scale(0.5, 0.5, 0.5);
    rt.motion_transform(
        Affine3A::from_translation(Vec3::new(-4.0, 0.0, 0.0)),
        Affine3A::from_translation(Vec3::new(4.0, 0.0, 0.0)),
    );
    rt.instantiate_object(id)?;
    rt.pop_matrix()?;
    Ok(())
}

fn coverage_columns(fb: &Framebuffer) -> Vec<f32> {
    (0..fb.width).map(|x| (0..fb.height).map(|y| fb.pixel(x, y)[3]).sum()).collect()
}

#[test]
fn a_moving_instance_is_smeared_over_the_shutter_interval() -> Result<(), ApiError> {
    let mut rt = context();
    rt.options.samples = (4, 4);
    moving_card(&mut rt)?;
    // No shutter interval: the card is where it is at the opening, sharp.
    let (still, _) = rt.render_frame()?;
    let cols = coverage_columns(&still);
    let covered: Vec<usize> = (0..cols.len()).filter(|&x| cols[x] > 0.0).collect();
    assert!(!covered.is_empty());
    // At the opening the card is at world x = -2: the image's right.
    assert!(covered.iter().all(|&x| x > W as usize / 2), "{covered:?}");
    rt.options.shutter = (0.0, 1.0);
    let (blurred, _) = rt.render_frame()?;
    let bcols = coverage_columns(&blurred);
    let bcovered: Vec<usize> = (0..bcols.len()).filter(|&x| bcols[x] > 0.0).collect();
    // The smear spans both halves, with partial coverage (no pixel fully covered in the middle),
    // and about the same total coverage per unit of time... at least as many columns as the card.
    assert!(bcovered.len() > 2 * covered.len(), "{} vs {} columns", bcovered.len(), covered.len());
    assert!(bcovered.iter().any(|&x| x > W as usize / 2) && bcovered.iter().any(|&x| x < W as usize / 2));
    let mid = blurred.pixel(W / 2, H / 2)[3];
    assert!(mid > 0.0 && mid < 0.9, "partial coverage in the middle: {mid}");
    Ok(())
}

/// The card of [`moving_card`], its motion given as a deforming mesh instead of a moving
/// transform: a `constant` square whose corners go from x - 2 to x + 2 over the shutter.
fn deforming_card(rt: &mut Context) -> Result<(), ApiError> {
    rt.camera_look_at(Vec3A::new(0.0, 0.0, -6.0), Vec3A::ZERO, Vec3A::Y, 60.0);
    let constant = rt.find_shader("constant")?;
    let id = rt.begin_object()?;
    rt.bind_shader(constant)?;
    rt.color(1.0, 1.0, 1.0);
    let corners =
        [Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, -1.0, 0.0), Vec3::new(1.0, 1.0, 0.0), Vec3::new(-1.0, 1.0, 0.0)];
    let at = |dx: f32| corners.iter().map(|c| (*c + Vec3::new(dx, 0.0, 0.0)) * 0.5).collect::<Vec<_>>();
    let mut mesh = Mesh::from_polygons(at(-4.0), &[[0u32, 1, 2, 3]])?;
    mesh.deformation = Some(Deformation { positions: at(4.0), normals: None, open: 0.0, close: 1.0 });
    rt.mesh(&mesh)?;
    rt.end_object()?;
    rt.instantiate_object(id)?;
    Ok(())
}

/// Deformation blur: a mesh whose vertices move is smeared as an instance moved the same way
/// is, ray time by ray time (the same rays meet the same squares, up to rounding at edges).
#[test]
fn a_deforming_mesh_is_smeared_as_the_same_motion_of_its_transform() -> Result<(), ApiError> {
    let render = |make: fn(&mut Context) -> Result<(), ApiError>, shutter| -> Result<Framebuffer, ApiError> {
        let mut rt = context();
        rt.options.samples = (4, 4);
        rt.options.shutter = shutter;
        make(&mut rt)?;
        Ok(rt.render_frame()?.0)
    };
    let (moved, deformed) = (render(moving_card, (0.0, 1.0))?, render(deforming_card, (0.0, 1.0))?);
    let cols = coverage_columns(&deformed);
    assert!(cols.iter().filter(|&&c| c > 0.0).count() > W as usize / 2, "smeared across the image: {cols:?}");
    let mut differing = 0;
    for y in 0..H {
        for x in 0..W {
            let (a, b) = (moved.pixel(x, y)[3], deformed.pixel(x, y)[3]);
            // A pixel differs by a sample at most (a sample on an edge, rounded either way).
            assert!((a - b).abs() <= 1.0 / 16.0 + 1e-4, "{x},{y}: {a} vs {b}");
            differing += usize::from(a != b);
        }
    }
    assert!(differing <= (W * H / 50) as usize, "{differing} pixels differ");
    // No shutter: rays at time 0 see the first sample, where the moving card's opening is.
    let (moved, deformed) = (render(moving_card, (0.0, 0.0))?, render(deforming_card, (0.0, 0.0))?);
    assert_eq!(coverage_columns(&moved), coverage_columns(&deformed));
    Ok(())
}

/// Meshes that deform over different intervals cannot share an object; still meshes can join a
/// deforming one, and a bad deformation is refused with the object left as it was.
#[test]
fn deformations_in_one_object_share_their_interval() -> Result<(), ApiError> {
    let mut rt = context();
    let square = |dx: f32| {
        Mesh::from_polygons(
            vec![
                Vec3::new(dx, 0.0, 0.0),
                Vec3::new(dx + 1.0, 0.0, 0.0),
                Vec3::new(dx + 1.0, 1.0, 0.0),
                Vec3::new(dx, 1.0, 0.0),
            ],
            &[[0u32, 1, 2, 3]],
        )
    };
    let deforming = |dx: f32, open: f32, close: f32| -> Result<Mesh, ApiError> {
        let mut m = square(dx)?;
        let up = m.positions.iter().map(|p| *p + Vec3::Z).collect();
        m.deformation = Some(Deformation { positions: up, normals: None, open, close });
        Ok(m)
    };
    let id = rt.begin_object()?;
    rt.mesh(&square(-3.0)?)?;
    rt.mesh(&deforming(0.0, 0.0, 1.0)?)?;
    let other = rt.mesh(&deforming(2.0, 0.0, 0.5)?);
    assert!(matches!(other, Err(ApiError::DeformationTimes { .. })), "{other:?}");
    let mut short = deforming(2.0, 0.0, 1.0)?;
    short.deformation.as_mut().map(|d| d.positions.pop());
    assert!(matches!(rt.mesh(&short), Err(ApiError::Mesh(_))));
    for (open, close) in [(1.0, 0.0), (0.0, 0.0), (f32::NAN, 1.0), (0.0, f32::INFINITY)] {
        let bad = deforming(2.0, open, close)?;
        let e = rt.mesh(&bad).expect_err("times must increase");
        assert!(e.to_string().contains("finite and increasing"), "{e}");
    }
    let mut far = deforming(2.0, 0.0, 1.0)?;
    if let Some(d) = far.deformation.as_mut() {
        d.positions[0].x = f32::NAN;
    }
    assert!(matches!(rt.mesh(&far), Err(ApiError::Mesh(_))));
    rt.mesh(&square(5.0)?)?;
    rt.end_object()?;
    let mesh = rt.object_mesh(id).expect("built").clone();
    let d = mesh.deformation.as_ref().expect("deforms");
    assert_eq!((mesh.positions.len(), d.positions.len(), d.open, d.close), (12, 12, 0.0, 1.0));
    // The still squares stay where they are; the deforming one rises by one.
    for k in 0..12 {
        let rise = if (4..8).contains(&k) { Vec3::Z } else { Vec3::ZERO };
        assert_eq!(d.positions[k], mesh.positions[k] + rise, "vertex {k}");
    }
    Ok(())
}

#[test]
fn rib_binds_cameras_depth_of_field_and_motion_blocks() -> Result<(), Box<dyn std::error::Error>> {
    let rib = r#"
        Format 48 32 1
        PixelSamples 2 2
        Shutter 0 1
        Projection "perspective" "fov" 60
        Camera "fisheye" "float fov" 200
        Translate 0 0 6
        WorldBegin
          Surface "constant"
          AttributeBegin
            MotionBegin [0 1]
              Translate -2 0 0
              Translate 2 0 0
            MotionEnd
            Polygon "P" [-0.5 -0.5 0  0.5 -0.5 0  0.5 0.5 0  -0.5 0.5 0]
          AttributeEnd
        WorldEnd
    "#;
    let mut rt = Context::new();
    let loaded = rtsl_runtime::rib::load::load_str(&mut rt, rib, std::path::Path::new("."))?;
    assert!(loaded.warnings.iter().all(|w| !w.message.contains("not rendered")), "{:?}", loaded.warnings);
    assert!(rt.camera_shader_id().is_some());
    assert_eq!(rt.options.shutter, (0.0, 1.0));
    let world = rt.build_world()?;
    let data = world.scene.instance_data(0).copied().ok_or("no instance")?;
    let motion = data.motion.ok_or("the polygon moves")?;
    let moved = motion.close_transform.translation - data.world_from_object.translation;
    assert!((moved - Vec3A::new(4.0, 0.0, 0.0)).length() < 1e-5, "{moved}");
    rt.return_scene(world);

    // DepthOfField with no Camera shader binds thinlens.
    let mut rt = Context::new();
    rtsl_runtime::rib::load::load_str(
        &mut rt,
        "DepthOfField 2.8 0.1 4\nWorldBegin\nWorldEnd\n",
        std::path::Path::new("."),
    )?;
    let id = rt.camera_shader_id().ok_or("thinlens bound")?;
    assert_eq!(rt.program(id)?.name, "thinlens");
    assert_eq!(rt.options.depth_of_field, Some([2.8, 0.1, 4.0]));
    Ok(())
}

/// RIB `MotionBegin` around geometry: the first sample deforms into the last over the block's
/// times; samples that are not one primitive changing shape are a part missing.
#[test]
fn rib_motion_blocks_around_geometry_deform_it() -> Result<(), Box<dyn std::error::Error>> {
    let rib = r#"
        Format 48 32 1
        Shutter 0 1
        Projection "perspective" "fov" 60
        Translate 0 0 6
        WorldBegin
          Surface "constant"
          MotionBegin [0 1]
            Polygon "P" [-2.5 -0.5 0  -1.5 -0.5 0  -1.5 0.5 0  -2.5 0.5 0]
            Polygon "P" [1.5 -0.5 0  2.5 -0.5 0  2.5 0.5 0  1.5 0.5 0]
          MotionEnd
          MotionBegin [0.25 0.5]
            Sphere 0.5 -0.5 0.5 360
            Sphere 1 -1 1 360
          MotionEnd
          MotionBegin [0 1]
            Sphere 1 -1 1 360
            Polygon "P" [0 0 0  1 0 0  1 1 0]
          MotionEnd
          # As in Aqsis's deformation example: samples whose own tessellations would differ.
          MotionBegin [0 1]
            Sphere 1 -1 1 360
            Sphere 0.8 -0.8 0.8 270
          MotionEnd
          MotionBegin [0 1]
            Points "P" [0 0 0  1 0 0] "width" [0.01 0.01]
            Points "P" [0 1 0  1 1 0] "width" [0.8 0.8]
          MotionEnd
          MotionBegin [1 0]
            Sphere 1 -1 1 360
            Sphere 2 -2 2 360
          MotionEnd
        WorldEnd
    "#;
    let mut rt = Context::new();
    let loaded = rtsl_runtime::rib::load::load_str(&mut rt, rib, std::path::Path::new("."))?;
    let mismatch: Vec<_> = loaded.warnings.iter().filter(|w| w.message.contains("not one primitive")).collect();
    assert_eq!(mismatch.len(), 1, "{:?}", loaded.warnings);
    assert!(
        loaded.warnings.iter().any(|w| w.message.contains("times 1 and 0 do not increase")),
        "{:?}",
        loaded.warnings
    );
    assert_eq!(loaded.omissions(), 1);
    let meshes: Vec<_> = (0..8).filter_map(|k| rt.object_mesh(ObjectId(k)).cloned()).collect();
    assert_eq!(meshes.len(), 6, "four deforming samples, the mismatched block's first sample, a still sphere");
    assert!(meshes[5].deformation.is_none(), "times that do not increase render the first sample");
    let square = meshes[0].deformation.as_ref().ok_or("the square deforms")?;
    assert_eq!((square.open, square.close), (0.0, 1.0));
    for (open, close) in meshes[0].positions.iter().zip(&square.positions) {
        assert!((*close - *open - Vec3::new(4.0, 0.0, 0.0)).length() < 1e-5, "{open} -> {close}");
    }
    let sphere = meshes[1].deformation.as_ref().ok_or("the sphere deforms")?;
    assert_eq!((sphere.open, sphere.close), (0.25, 0.5));
    for (open, close) in meshes[1].positions.iter().zip(&sphere.positions) {
        assert!((*close - *open * 2.0).length() < 1e-4, "the sphere doubles: {open} -> {close}");
    }
    let normals = (meshes[1].normals.as_ref(), sphere.normals.as_ref());
    assert!(matches!(normals, (Some(a), Some(b)) if a.len() == b.len()), "normals at both ends");
    assert!(meshes[2].deformation.is_none());
    // The sphere's sweep closes from a full turn to three quarters: the vertex at each (u, v)
    // moves to where the smaller sphere has it.
    let swept = meshes[3].deformation.as_ref().ok_or("the sweep changes")?;
    let longitude = |p: Vec3| p.y.atan2(p.x).rem_euclid(std::f32::consts::TAU);
    for (open, close) in meshes[3].positions.iter().zip(&swept.positions) {
        assert!((close.length() - 0.8).abs() < 1e-4, "{close}");
        assert!(longitude(*close) <= 1.5 * std::f32::consts::PI + 1e-4 || close.x.hypot(close.y) < 1e-4, "{close}");
        let (a, b) = (longitude(*open), longitude(*close));
        // (The seam at a full turn reads as longitude 0.)
        let three_quarters = |a: f32| (b - 0.75 * a).abs() < 1e-3;
        let pole = open.x.hypot(open.y) < 1e-4;
        assert!(pole || three_quarters(a) || three_quarters(a + std::f32::consts::TAU), "{open} -> {close}");
    }
    // The points grow and rise; each keeps its disk's vertices.
    let points = meshes[4].deformation.as_ref().ok_or("the points move")?;
    assert_eq!(points.positions.len(), meshes[4].positions.len());
    Ok(())
}

#[test]
fn an_orthographic_projection_keeps_sizes_at_every_distance() {
    // Two squares of side 1, one twice as far as the other, side by side: seen orthographically
    // they cover the same number of pixels; in perspective the far one covers about a quarter.
    let scene = |projection: &str| {
        format!(
            r#"Format 64 64 1
            {projection}
            ScreenWindow -2 2 -2 2
            Translate 0 0 2
            WorldBegin
              Surface "constant"
              Polygon "P" [-1.5 -0.5 0  -0.5 -0.5 0  -0.5 0.5 0  -1.5 0.5 0]
              Polygon "P" [0.5 -0.5 2  1.5 -0.5 2  1.5 0.5 2  0.5 0.5 2]
            WorldEnd"#
        )
    };
    let covered = |projection: &str| {
        let mut rt = Context::new();
        let loaded = rtsl_runtime::rib::load::load_str(&mut rt, &scene(projection), std::path::Path::new("o.rib"))
            .expect("loads");
        assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
        let world = rt.build_world().expect("a world");
        let (fb, _) = rtsl_runtime::render::render_frame(&world, None);
        let lit = |x0: u32, x1: u32| {
            (0..64).flat_map(|y| (x0..x1).map(move |x| (x, y))).filter(|&(x, y)| fb.pixel(x, y)[3] > 0.5).count()
        };
        (lit(0, 32), lit(32, 64))
    };
    // 1 unit of a 4-unit window over 64 pixels: 16 x 16.
    assert_eq!(covered(r#"Projection "orthographic""#), (256, 256));
    let (near, far) = covered(r#"Projection "perspective" "fov" [90]"#);
    assert!(far * 3 < near, "perspective shrinks the far square: {near} {far}");
}
