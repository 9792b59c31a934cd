//! BART: the AFF reader (every construct, errors with their location, no panic on broken input),
//! the keyframe splines against hand-computed values, the loader on small scenes, and the three
//! real scenes of `../shared/scenes/bart` (skipped when absent) played at two times.

mod common;

use common::render;
use glam::{Quat, Vec3};
use rtsl_runtime::api::Context;
use rtsl_runtime::bart::aff::{parse_str, AffError, Geometry, NodeTransform};
use rtsl_runtime::bart::animation::{AxisAngle, Key, Keyframes, RotationTrack, Tcb, VectorTrack, VisibilityTrack};
use rtsl_runtime::bart::{load_file, load_parsed, BartScene};
use rtsl_runtime::render::Framebuffer;
use std::path::{Path, PathBuf};

fn parse(text: &str) -> rtsl_runtime::bart::AffScene {
    match parse_str(text, Path::new("test.aff")) {
        Ok(s) => s,
        Err(e) => panic!("{e}"),
    }
}

fn parse_error(text: &str) -> String {
    match parse_str(text, Path::new("test.aff")) {
        Ok(_) => panic!("expected an error for:\n{text}"),
        Err(e) => e.to_string(),
    }
}

fn close(a: f32, b: f32) -> bool {
    (a - b).abs() <= 1e-4 * (1.0 + b.abs())
}

fn close3(a: Vec3, b: Vec3) -> bool {
    close(a.x, b.x) && close(a.y, b.y) && close(a.z, b.z)
}

// ---- the reader ----

/// One statement of every kind, with both comment styles, also after values.
const EVERY_CONSTRUCT: &str = "\
% a comment
# another comment
v
from 0 1 -5
at 0 1 0   % trailing comment
up 0 1 0
angle 40
hither 0.01
resolution 320 240
b 0.1 0.2 0.3
am 0.5 0.5 0.5
l 1 2 3
l 4 5 6 0.5 0.25 1
f 1 0.5 0 0.8 0.2 30 0 1
s 0 0 0 1
fm 0.1 0.1 0.1  0.2 0.3 0.4  0.5 0.5 0.5  20 0.5 1.5  # glass
c 0 0 0 0.5  0 2 0 0.25
p 4
 0 0 0
 1 0 0
 1 1 0
 0 1 0
pp 3
 0 0 0 0 0 1
 1 0 0 0 0 1
 0 1 0 0 0 1
tt wood.ppm
 0 0 0 0 1
 1 0 0 1 1
 0 1 0 0 0
ttp wood.ppm
 0 0 0 0 0 1 0 1
 1 0 0 0 0 1 1 1
 0 1 0 0 0 1 0 0
tpa 2
 0
 0 0 0 0 0 1
 1 0 0 0 0 1
 0 1 0 0 0 1
 1
 0 0 1 0 0 1
 1 0 1 0 0 1
 0 1 1 0 0 1
m
vertices 4
 0 0 0
 1 0 0
 1 1 0
 0 1 0
normals 1
 0 0 1
texturecoords 4 tiles.ppm
 0 0
 1 0
 1 1
 0 1
triangles 2
 0 1 2 0 0 0 0 1 2
 0 2 3 0 0 0 0 2 3
a 0 10 100
xs 2 2 2  0 1 0 90  1 0 0
{
  x spinner
  {
    m
    vertices 3
    0 0 0
    1 0 0
    0 1 0
    triangles 1
    0 1 2
  }
}
k spinner
{
  transl 2
   0  0 0 0  0 0 0
   10 5 0 0  0 0 0
  rot 2
   0  0 1 0 0    0 0 0
   10 0 1 0 90   0 0 0
  scale 2
   0  1 1 1  0 0 0
   10 2 2 2  0 0 0
  visibility 2
   0 1
   5 0
}
";

#[test]
fn every_construct_is_read() {
    let s = parse(EVERY_CONSTRUCT);
    assert!(s.warnings.is_empty(), "{:?}", s.warnings);
    let v = s.viewpoint.as_ref().expect("viewpoint");
    assert_eq!((v.from, v.at, v.up), (Vec3::new(0.0, 1.0, -5.0), Vec3::new(0.0, 1.0, 0.0), Vec3::Y));
    assert_eq!((v.angle, v.hither, v.resolution), (40.0, 0.01, Some((320, 240))));
    assert_eq!(s.background, Some(Vec3::new(0.1, 0.2, 0.3)));
    assert_eq!(s.ambient, Some(Vec3::splat(0.5)));
    assert_eq!(s.lights.len(), 2);
    assert_eq!((s.lights[0].position, s.lights[0].color), (Vec3::new(1.0, 2.0, 3.0), Vec3::ONE));
    assert_eq!(s.lights[1].color, Vec3::new(0.5, 0.25, 1.0));
    // The default material, `f` and `fm`.
    assert_eq!(s.materials.len(), 3);
    let f = s.materials[1];
    assert!(close3(f.diffuse, Vec3::new(0.8, 0.4, 0.0)) && f.specular == Vec3::splat(0.2) && f.shine == 30.0);
    let fm = s.materials[2];
    assert_eq!((fm.ambient, fm.diffuse, fm.specular), (Vec3::splat(0.1), Vec3::new(0.2, 0.3, 0.4), Vec3::splat(0.5)));
    assert_eq!((fm.shine, fm.transmittance, fm.index_of_refraction), (20.0, 0.5, 1.5));
    let kinds: Vec<&str> = s
        .shapes
        .iter()
        .map(|sh| match &sh.geometry {
            Geometry::Sphere { .. } => "s",
            Geometry::Cone { .. } => "c",
            Geometry::Triangles(_) => "t",
            Geometry::AnimatedTriangle(_) => "tpa",
        })
        .collect();
    assert_eq!(kinds, ["s", "c", "t", "t", "t", "t", "tpa", "t", "t"]);
    assert_eq!(s.shapes[0].material, 1, "the sphere follows `f`");
    assert_eq!(s.shapes[1].material, 2, "the cone follows `fm`");
    let Geometry::Triangles(poly) = &s.shapes[2].geometry else { unreachable!() };
    assert_eq!(poly.triangles, [[0, 1, 2], [0, 2, 3]], "the quad is a fan of two triangles");
    let Geometry::Triangles(patch) = &s.shapes[3].geometry else { unreachable!() };
    assert_eq!(patch.normals.as_ref().map(Vec::len), Some(3));
    let tt = &s.shapes[4];
    assert_eq!(tt.texture.as_ref().map(|t| t.name.as_str()), Some("wood.ppm"));
    let Geometry::Triangles(t) = &tt.geometry else { unreachable!() };
    assert_eq!(t.uvs.as_deref(), Some(&[glam::Vec2::new(0.0, 1.0), glam::Vec2::new(1.0, 1.0), glam::Vec2::ZERO][..]));
    let Geometry::AnimatedTriangle(keys) = &s.shapes[6].geometry else { unreachable!() };
    assert_eq!((keys.len(), keys[1].time, keys[1].positions[2]), (2, 1.0, Vec3::new(0.0, 1.0, 1.0)));
    let mesh = &s.shapes[7];
    assert_eq!(mesh.texture.as_ref().map(|t| t.name.as_str()), Some("tiles.ppm"));
    let Geometry::Triangles(m) = &mesh.geometry else { unreachable!() };
    assert_eq!((m.positions.len(), m.triangles.len()), (4, 2), "corners with the same indices share a vertex");
    assert_eq!(m.normals.as_deref(), Some(&[Vec3::Z; 4][..]));
    assert_eq!(s.triangle_count(), 2 + 1 + 1 + 1 + 1 + 2 + 1);
    let a = s.animation.expect("a");
    assert_eq!((a.start, a.end, a.frames), (0.0, 10.0, 100));
    // Nodes: root, xs, x spinner; the last mesh is in the spinner.
    assert_eq!(s.nodes.len(), 3);
    assert!(matches!(&s.nodes[1].transform, NodeTransform::Static(_)));
    assert_eq!(s.nodes[2].transform, NodeTransform::Animated("spinner".into()));
    assert_eq!((s.nodes[2].parent, s.shapes[8].node), (Some(1), 2));
    let NodeTransform::Static(xs) = s.nodes[1].transform else { unreachable!() };
    // Scale, then rotate 90 degrees about y, then translate: x -> 2x -> -2z -> (1, 0, -2).
    assert!(close3(xs.transform_point3(Vec3::X), Vec3::new(1.0, 0.0, -2.0)));
    let k = s.keyframes("spinner").expect("keyframes");
    assert!(k.translation.is_some() && k.rotation.is_some() && k.scale.is_some());
    assert!(k.visible_at(4.9) && !k.visible_at(5.0));
    assert!(close3(k.translation_at(10.0), Vec3::new(5.0, 0.0, 0.0)));
}

#[test]
fn errors_name_the_file_line_and_column() {
    let cases = [
        ("p 3\n0 0 0\n1 0 0\n0 oops 0\n", "test.aff:4:3:", "a number"),
        ("fm 1 1 1 1 1 1\n", "test.aff:2:1:", "end of the file"),
        ("}\n", "test.aff:1:1:", "without an open"),
        ("xs 1 1 1 0 0 1 0 0 0 0\n{\n s 0 0 0 1\n", "test.aff:1:1:", "not closed"),
        ("x spin\ns 0 0 0 1\n", "test.aff:2:1:", "`{`"),
        ("m\nvertices 3\n0 0 0\n1 0 0\n0 1 0\ntriangles 1\n0 1 3\n", "test.aff:7:5:", "out of range"),
        ("m\nvertices 1\n0 0 0\nbogus 1\n", "test.aff:4:1:", "mesh block"),
        ("p -2\n", "test.aff:1:3:", "whole number"),
        ("k cam\n{\n  wiggle 2\n}\n", "test.aff:3:3:", "a track"),
        ("l 0 0 nan\n", "test.aff:1:7:", "a number"),
        ("m\nvertices 99999999999\n", "test.aff:2:10:", "more than"),
    ];
    for (text, at, what) in cases {
        let e = parse_error(text);
        assert!(e.starts_with(at) && e.contains(what), "{text:?}: {e}");
    }
}

#[test]
fn what_cannot_be_honoured_is_warned_once_and_skipped() {
    let s = parse("d 3\nd 4\nzz 1 2 3\n4 5 6\ns 0 0 0 1\np 2\n0 0 0\n1 1 1\ni 0 no-such-file.aff\n");
    assert_eq!(s.shapes.len(), 1, "the sphere after the unknown commands is read");
    let joined = s.warnings.join("\n");
    assert_eq!(s.warnings.len(), 4, "{joined}");
    assert!(s.warnings[0].starts_with("test.aff:1:1: warning: unknown command `d`"), "{joined}");
    assert!(s.warnings[1].starts_with("test.aff:3:1: warning: unknown command `zz`"), "{joined}");
    assert!(joined.contains("test.aff:6:1: warning: a polygon of 2 vertices"), "{joined}");
    assert!(joined.contains("test.aff:9:5: warning: cannot read the included file"), "{joined}");
}

#[test]
fn includes_are_relative_to_the_including_file_and_share_the_material_state() {
    let dir = tempfile::tempdir().expect("tempdir");
    let sub = dir.path().join("parts");
    std::fs::create_dir(&sub).expect("mkdir");
    std::fs::write(sub.join("paint.aff"), "fm 0 0 0 1 0 0 0 0 0 1 0 0\n").expect("write");
    std::fs::write(sub.join("part.aff"), "i 0 paint.aff\nxs 1 1 1 0 0 1 0 0 0 1\n{\ns 0 0 0 1\n}\n").expect("write");
    std::fs::write(dir.path().join("scene.aff"), "i 0 parts/part.aff\ns 5 0 0 1\ni 0 parts/part.aff\n").expect("write");
    let s = rtsl_runtime::bart::parse_file(&dir.path().join("scene.aff")).expect("parse");
    assert_eq!(s.shapes.len(), 3);
    assert!(s.shapes.iter().all(|sh| sh.material == 1), "the included `fm` stays current");
    assert_eq!(s.nodes.len(), 3, "each include makes its own node");
    assert_eq!(s.files.len(), 3);
    // A file including itself is stopped.
    std::fs::write(dir.path().join("loop.aff"), "s 0 0 0 1\ni 0 loop.aff\n").expect("write");
    let e = rtsl_runtime::bart::parse_file(&dir.path().join("loop.aff")).expect_err("a loop");
    assert!(e.to_string().contains("nest deeper"), "{e}");
    assert!(matches!(rtsl_runtime::bart::parse_file(&dir.path().join("absent.aff")), Err(AffError::Read { .. })));
}

#[test]
fn broken_input_never_panics() {
    // Every prefix of a file using every construct, and bytes changed at random (a fixed seed).
    let text = EVERY_CONSTRUCT.as_bytes();
    for end in 0..text.len() {
        let _ = parse_str(&String::from_utf8_lossy(&text[..end]), Path::new("cut.aff"));
    }
    let mut seed = 0x2545_f491_4f6c_dd1du64;
    let mut next = || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        seed
    };
    let alphabet = b" \n\t{}%#-.0123456789eExsmptkvlfcbai";
    for _ in 0..2000 {
        let mut bytes = text.to_vec();
        for _ in 0..1 + next() % 6 {
            let at = (next() % bytes.len() as u64) as usize;
            bytes[at] = alphabet[(next() % alphabet.len() as u64) as usize];
        }
        let _ = parse_str(&String::from_utf8_lossy(&bytes), Path::new("mutated.aff"));
    }
}

// ---- the splines ----

fn key(time: f32, x: f32) -> Key<Vec3> {
    Key { time, value: Vec3::new(x, 0.0, 0.0), tcb: Tcb::default() }
}

fn track(keys: &[(f32, f32)]) -> VectorTrack {
    VectorTrack::new(keys.iter().map(|&(t, x)| key(t, x)).collect()).expect("keys")
}

#[test]
fn catmull_rom_when_tension_continuity_and_bias_are_zero() {
    // x = t^2 at t = 0..3. Inner tangents are Catmull-Rom's (P[i+1] - P[i-1]) / 2, which follow a
    // parabola exactly on even spacing: x(1.5) = 0.5*1 + 0.5*4 + 0.125*2 - 0.125*4 = 2.25.
    let tr = track(&[(0.0, 0.0), (1.0, 1.0), (2.0, 4.0), (3.0, 9.0)]);
    assert!(close(tr.at(1.5).x, 2.25));
    // Keys 0, 10, 60, 70: tangents 30 at both inner keys; at u = 0.25 the Hermite weights are
    // 0.84375, 0.15625, 0.140625, -0.046875: 8.4375 + 9.375 + 4.21875 - 1.40625 = 20.625.
    let tr2 = track(&[(0.0, 0.0), (1.0, 10.0), (2.0, 60.0), (3.0, 70.0)]);
    assert!(close(tr2.at(1.25).x, 20.625), "{}", tr2.at(1.25).x);
}

#[test]
fn natural_ends_and_values_held_outside_the_keys() {
    let tr = track(&[(0.0, 0.0), (1.0, 1.0), (2.0, 4.0), (3.0, 9.0)]);
    // First key: T0 = 1.5 * (1 - 0) - 0.5 * 2 = 0.5; x(0.5) = 0.5 + 0.125 * 0.5 - 0.125 * 2.
    assert!(close(tr.at(0.5).x, 0.3125), "{}", tr.at(0.5).x);
    // Last key: T3 = 1.5 * (9 - 4) - 0.5 * 4 = 5.5; x(2.5) = 6.5 + 0.125 * 4 - 0.125 * 5.5.
    assert!(close(tr.at(2.5).x, 6.3125), "{}", tr.at(2.5).x);
    for (t, x) in [(-1.0, 0.0), (0.0, 0.0), (1.0, 1.0), (2.0, 4.0), (3.0, 9.0), (7.0, 9.0)] {
        assert!(close(tr.at(t).x, x), "x({t}) = {}", tr.at(t).x);
    }
    // Two keys: both tangents are the difference, so the motion is linear.
    let two = track(&[(0.0, 2.0), (4.0, 6.0)]);
    assert!(close(two.at(1.0).x, 3.0));
    // One key: constant.
    assert_eq!(track(&[(1.0, 5.0)]).at(0.0).x, 5.0);
}

#[test]
fn uneven_key_spacing_keeps_a_constant_speed_constant() {
    // Keys on a line at uneven times: the tangents are scaled by their segments' lengths, so the
    // motion stays linear everywhere.
    let tr = track(&[(0.0, 0.0), (1.0, 1.0), (3.0, 3.0)]);
    for t in [0.25, 0.5, 1.5, 2.0, 2.7] {
        assert!(close(tr.at(t).x, t), "x({t}) = {}", tr.at(t).x);
    }
}

#[test]
fn tension_continuity_and_bias_change_the_tangents() {
    // Tension 1 everywhere: zero tangents, x follows the Hermite weight h2 (ease in and out).
    let eased = VectorTrack::new(vec![
        Key { time: 0.0, value: Vec3::ZERO, tcb: Tcb { tension: 1.0, ..Tcb::default() } },
        Key { time: 1.0, value: Vec3::X, tcb: Tcb { tension: 1.0, ..Tcb::default() } },
    ])
    .expect("keys");
    assert!(close(eased.at(0.25).x, 0.15625));
    // Bias 1 at the middle key of 0, 1, 3: both its tangents are the incoming difference (1), so
    // on [1, 2] with the last key's natural tangent 1.5 * 2 - 0.5 * 1 = 2.5:
    // x(1.5) = 0.5 * 1 + 0.5 * 3 + 0.125 * 1 - 0.125 * 2.5 = 1.8125.
    let biased = VectorTrack::new(vec![
        key(0.0, 0.0),
        Key { time: 1.0, value: Vec3::X, tcb: Tcb { bias: 1.0, ..Tcb::default() } },
        key(2.0, 3.0),
    ])
    .expect("keys");
    assert!(close(biased.at(1.5).x, 1.8125), "{}", biased.at(1.5).x);
    // Continuity -1 at the middle key: a corner, the incoming tangent is the incoming difference
    // (1) and the outgoing tangent the outgoing difference (2).
    let corner = VectorTrack::new(vec![
        key(0.0, 0.0),
        Key { time: 1.0, value: Vec3::X, tcb: Tcb { continuity: -1.0, ..Tcb::default() } },
        key(2.0, 3.0),
    ])
    .expect("keys");
    // On [1, 2]: P1 = 1, P2 = 3, T1 = 2, T2 = 1.5 * 2 - 0.5 * 2 = 2: the straight line 1 + 2u.
    assert!(close(corner.at(1.5).x, 2.0), "{}", corner.at(1.5).x);
}

#[test]
fn repeated_key_times_give_no_nan() {
    // BART files repeat their first and last keys.
    let tr = track(&[(0.0, 1.0), (0.0, 1.0), (1.0, 3.0), (2.0, 2.0), (2.0, 2.0)]);
    for i in -5..=25 {
        let x = tr.at(i as f32 * 0.1).x;
        assert!(x.is_finite(), "x({}) = {x}", i as f32 * 0.1);
    }
    assert_eq!(tr.at(0.0).x, 1.0);
    assert_eq!(tr.at(2.0).x, 2.0);
    let same = track(&[(1.0, 1.0), (1.0, 2.0), (1.0, 3.0)]);
    assert!(same.at(1.0).x.is_finite() && same.at(0.0).x.is_finite());
}

fn rot_track(axis: Vec3, keys: &[(f32, f32)]) -> RotationTrack {
    RotationTrack::new(
        keys.iter()
            .map(|&(time, degrees)| Key { time, value: AxisAngle { axis, degrees }, tcb: Tcb::default() })
            .collect(),
    )
    .expect("keys")
}

fn angle_about_z(q: Quat) -> f32 {
    let v = q * Vec3::X;
    v.y.atan2(v.x).to_degrees()
}

#[test]
fn rotations_about_one_axis_follow_the_spline_of_the_angle() {
    // Same keys as the Catmull-Rom case: squad with these tangents is the Hermite cubic of the angle.
    let tr = rot_track(Vec3::Z, &[(0.0, 0.0), (1.0, 10.0), (2.0, 60.0), (3.0, 70.0)]);
    assert!(close(angle_about_z(tr.at(1.25)), 20.625), "{}", angle_about_z(tr.at(1.25)));
    // First segment: T0 = 1.5 * 10 - 0.5 * 30 = 0, so at u = 0.5: 0.5 * 10 - 0.125 * 30 = 1.25.
    assert!(close(angle_about_z(tr.at(0.5)), 1.25), "{}", angle_about_z(tr.at(0.5)));
    for (t, a) in [(-1.0, 0.0), (1.0, 10.0), (2.0, 60.0), (3.0, 70.0), (9.0, 70.0)] {
        assert!(close(angle_about_z(tr.at(t)), a), "angle({t}) = {}", angle_about_z(tr.at(t)));
    }
    // Keys a quarter turn apart spin on through whole turns (the wheels of the kitchen's car): at
    // t = 2.5 the angle is 225 degrees, i.e. -135.
    let spin = rot_track(-Vec3::Z, &[(0.0, 0.0), (1.0, 90.0), (2.0, 180.0), (3.0, 270.0), (4.0, 360.0), (5.0, 450.0)]);
    assert!(close(angle_about_z(spin.at(2.5)), 135.0), "{}", angle_about_z(spin.at(2.5)));
    assert!(close(angle_about_z(spin.at(4.5)), -45.0), "{}", angle_about_z(spin.at(4.5)));
}

#[test]
fn rotations_hit_their_keys_and_stay_unit() {
    let keys = [
        (0.0, Vec3::new(0.0, 1.0, 0.0), 180.0),
        (1.0, Vec3::new(0.99741, 0.07088, -0.01186), -19.0),
        (2.0, Vec3::new(0.0, -1.0, 0.0), -90.0),
        (3.5, Vec3::new(-0.02866, 0.98774, -0.15348), -163.7),
    ];
    let tr = RotationTrack::new(
        keys.iter()
            .map(|&(time, axis, degrees)| Key { time, value: AxisAngle { axis, degrees }, tcb: Tcb::default() })
            .collect(),
    )
    .expect("keys");
    for &(t, axis, degrees) in &keys {
        let want = Quat::from_axis_angle(axis.normalize(), degrees.to_radians());
        let got = tr.at(t);
        assert!(close3(got * Vec3::X, want * Vec3::X) && close3(got * Vec3::Y, want * Vec3::Y), "key at {t}");
    }
    for i in 0..=40 {
        let q = tr.at(i as f32 * 0.1);
        assert!(q.is_finite() && close(q.length(), 1.0), "{q:?}");
    }
}

#[test]
fn keyframes_scale_then_rotate_then_translate() {
    let k = Keyframes {
        name: "n".into(),
        translation: VectorTrack::new(vec![Key { time: 0.0, value: Vec3::X, tcb: Tcb::default() }]),
        rotation: RotationTrack::new(vec![Key {
            time: 0.0,
            value: AxisAngle { axis: Vec3::Z, degrees: 90.0 },
            tcb: Tcb::default(),
        }]),
        scale: VectorTrack::new(vec![Key { time: 0.0, value: Vec3::new(2.0, 1.0, 1.0), tcb: Tcb::default() }]),
        visibility: VisibilityTrack::new(vec![
            Key { time: 1.0, value: false, tcb: Tcb::default() },
            Key { time: 2.0, value: true, tcb: Tcb::default() },
        ]),
    };
    // (1, 0, 0) -> scaled (2, 0, 0) -> rotated (0, 2, 0) -> translated (1, 2, 0).
    assert!(close3(k.transform_at(0.0).transform_point3(Vec3::X), Vec3::new(1.0, 2.0, 0.0)));
    assert!(!k.visible_at(0.0) && !k.visible_at(1.5) && k.visible_at(2.0), "the first key holds before it");
    assert_eq!(k.time_range(), Some((0.0, 2.0)));
    assert!(Keyframes::default().transform_at(3.0).abs_diff_eq(glam::Affine3A::IDENTITY, 0.0));
}

// ---- the loader ----

/// Pixels whose colour differs by more than a small amount.
fn differing_pixels(a: &Framebuffer, b: &Framebuffer) -> usize {
    a.rgba
        .chunks(4)
        .zip(b.rgba.chunks(4))
        .filter(|(p, q)| p.iter().zip(q.iter()).any(|(x, y)| (x - y).abs() > 1e-3))
        .count()
}

fn lit(fb: &Framebuffer) -> usize {
    fb.rgba.chunks(4).filter(|p| p[0] + p[1] + p[2] > 0.05).count()
}

/// A floor, a box moved by keyframes, an animated triangle, a light and a fixed viewpoint.
const SMALL_SCENE: &str = "\
v
from 0 3 8
at 0 0.5 0
up 0 1 0
angle 45
hither 0.01
resolution 64 48
b 0 0 0
l 0 10 5
fm 0.2 0.2 0.2  0.6 0.6 0.6  0 0 0  1 0 0
p 4
 -5 0 5
 5 0 5
 5 0 -5
 -5 0 -5
x mover
{
  fm 0.2 0.05 0.05  0.9 0.2 0.1  0.3 0.3 0.3  30 0 0
  xs 0.5 0.5 0.5  0 1 0 0  0 0.5 0
  {
    s 0 0 0 1
  }
}
tpa 2
 0
 -3 0.1 0 0 1 0
 -2 0.1 0 0 1 0
 -3 0.1 1 0 1 0
 2
 -3 2 0 0 0 1
 -2 2 0 0 0 1
 -3 3 0 0 0 1
a 0 2 20
k mover
{
  transl 3
   0  -2 0 0  0 0 0
   1   0 0 0  0 0 0
   2   2 0 0  0 0 0
}
";

fn small_scene(dir: &Path) -> PathBuf {
    let path = dir.join("small.aff");
    std::fs::write(&path, SMALL_SCENE).expect("write");
    path
}

#[test]
fn a_small_scene_plays_with_instances_moved_and_triangles_morphed() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut rt = Context::new();
    let mut scene = load_file(&mut rt, &small_scene(dir.path())).unwrap_or_else(|e| panic!("{e}"));
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    assert_eq!((rt.options.width, rt.options.height), (64, 48), "the viewpoint's resolution");
    let s = &scene.summary;
    assert_eq!((s.animated_nodes, s.moving_instances, s.morphing_triangles, s.lights), (1, 1, 1, 1));
    assert!(s.triangles > 2 + 1 + 100, "the sphere is tessellated: {}", s.triangles);
    assert_eq!(scene.frame_time(10), 1.0, "20 frames over 2 s");
    let camera = *rt.camera();
    let first = render(&mut rt);
    assert!(lit(&first) > 100, "the scene is lit and in view");
    scene.set_time(&mut rt, 1.0).expect("set_time");
    assert_eq!(*rt.camera(), camera, "no camera keyframes: the viewpoint stays");
    let second = render(&mut rt);
    assert!(differing_pixels(&first, &second) > 20, "the ball and the triangle moved");
    scene.set_time(&mut rt, 0.0).expect("set_time");
    let again = render(&mut rt);
    assert_eq!(differing_pixels(&first, &again), 0, "time 0 again is the same frame");
}

#[test]
fn camera_keyframes_move_the_camera_and_missing_keyframes_are_warned() {
    let text = format!(
        "{SMALL_SCENE}\nx nobody\n{{\n s 0 0 0 1\n}}\nk camera\n{{\n transl 2\n 0 0 1 8 0 0 0\n 2 0 1 4 0 0 0\n rot 2\n 0 0 1 0 0 0 0 0\n 2 0 1 0 30 0 0 0\n}}\n"
    );
    let parsed = parse(&text);
    let mut rt = Context::new();
    let scene: BartScene = load_parsed(&mut rt, parsed, Path::new("mem.aff")).unwrap_or_else(|e| panic!("{e}"));
    assert!(scene.summary.animated_camera);
    assert!(scene.warnings.iter().any(|w| w.contains("no keyframes are named `nobody`")), "{:?}", scene.warnings);
    let c0 = scene.camera_at(0.0, 64, 48);
    let c2 = scene.camera_at(2.0, 64, 48);
    assert!(close3(c0.eye().into(), Vec3::new(0.0, 1.0, 8.0)) && close3(c2.eye().into(), Vec3::new(0.0, 1.0, 4.0)));
    // Looking down -z, turned 30 degrees about +y at the end: towards (-sin 30, 0, -cos 30).
    let forward = |c: &rtsl_runtime::render::CameraSetup| Vec3::from(c.world_from_camera.matrix3.z_axis).normalize();
    assert!(close3(forward(&c0), Vec3::NEG_Z));
    assert!(close3(forward(&c2), Vec3::new(-0.5, 0.0, -(3f32.sqrt()) / 2.0)), "{}", forward(&c2));
    assert_eq!(c0.fov_degrees, 45.0, "the angle is vertical, the shorter side of a landscape image");
    let portrait = scene.camera_at(0.0, 48, 64);
    assert!(portrait.fov_degrees < 45.0, "a portrait image keeps the vertical angle: {}", portrait.fov_degrees);
}

// ---- the real scenes ----

fn shared_bart() -> Option<PathBuf> {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/scenes/bart");
    if p.is_dir() {
        Some(p)
    } else {
        eprintln!("skipped: {} is absent (the shared BART scenes are not here)", p.display());
        None
    }
}

/// Loads a real scene, renders 64x48 at `t0` and `t1` with the camera of `t0`, and returns the
/// scene and the number of pixels that changed.
fn play_real(file: &Path, t0: f32, t1: f32) -> (BartScene, usize) {
    let mut rt = Context::new();
    let mut scene = load_file(&mut rt, file).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
    rt.options.width = 64;
    rt.options.height = 48;
    scene.set_time(&mut rt, t0).expect("set_time");
    let camera = *rt.camera();
    let a = render(&mut rt);
    assert!(lit(&a) > 64 * 48 / 10, "{}: the frame at {t0} shows something", file.display());
    scene.set_time(&mut rt, t1).expect("set_time");
    rt.set_camera(camera);
    let b = render(&mut rt);
    let changed = differing_pixels(&a, &b);
    eprintln!("{}: {changed} of {} pixels changed from t = {t0} to {t1}", file.display(), 64 * 48);
    (scene, changed)
}

#[test]
fn robots_walk() {
    let Some(root) = shared_bart() else { return };
    let (scene, changed) = play_real(&root.join("robot/aff/Robot.aff"), 0.0, 3.0);
    let s = &scene.summary;
    assert_eq!(s.triangles, 71_708, "the README's count");
    assert!(s.animated_nodes >= 150 && s.moving_instances > 100 && s.animated_camera, "{s:?}");
    assert_eq!(s.missing_textures, 0);
    assert_eq!((scene.animation.start, scene.animation.end, scene.animation.frames), (0.0, 50.0, 800));
    assert!(changed > 20, "robots moved in front of the fixed camera: {changed} pixels");
}

#[test]
fn the_toy_car_drives_through_the_kitchen() {
    let Some(root) = shared_bart() else { return };
    let (scene, changed) = play_real(&root.join("kitchen/aff/kitchen.aff"), 5.0, 6.0);
    let s = &scene.summary;
    assert_eq!(s.triangles, 110_561, "the README's count");
    assert!(s.animated_nodes >= 5 && s.moving_instances >= 5 && s.animated_camera, "{s:?}");
    assert!(changed > 5, "the car moved in front of the fixed camera: {changed} pixels");
}

#[test]
fn the_museum_sculpture_morphs() {
    let Some(root) = shared_bart() else { return };
    let (scene, changed) = play_real(&root.join("museum/aff/museum5.aff"), 2.0, 3.0);
    let s = &scene.summary;
    assert_eq!(s.morphing_triangles, 1_024, "the README's animated triangles");
    // 10,284 static triangles plus 8 tessellated cones.
    assert!(s.triangles > 10_284 + 1_024, "{s:?}");
    assert_eq!(s.missing_textures, 0);
    assert!(changed > 20, "the sculpture changed in front of the fixed camera: {changed} pixels");
}

#[test]
fn broken_scenes_that_parse_load_and_play_without_panicking() {
    // Mutated numbers can make singular or enormous transforms, empty polygons, odd keys: loading
    // and playing them must give errors or warnings, never a panic.
    let mut rt = Context::new();
    let mut seed = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        seed
    };
    let replacements = ["0", "-1", "1e30", "-1e30", "1e-30", "3", "0.5", "-0"];
    let words: Vec<&str> = SMALL_SCENE.split_whitespace().collect();
    let mut played = 0;
    for _ in 0..60 {
        let mut text: Vec<String> = words.iter().map(|w| w.to_string()).collect();
        for _ in 0..1 + next() % 4 {
            let at = (next() % text.len() as u64) as usize;
            if text[at].parse::<f32>().is_ok() {
                text[at] = replacements[(next() % replacements.len() as u64) as usize].to_string();
            }
        }
        // Statements span lines freely, so one word per line keeps the scene's meaning.
        let Ok(parsed) = parse_str(&text.join("\n"), Path::new("mutated.aff")) else { continue };
        let Ok(mut scene) = load_parsed(&mut rt, parsed, Path::new("mutated.aff")) else { continue };
        for t in [-1.0, 0.5, 1.0, 5.0] {
            let _ = scene.set_time(&mut rt, t);
        }
        played += 1;
    }
    assert!(played > 30, "most mutations still parse and load: {played} of 60");
    // A hand-made scene without the root node, with a shape on a node that does not exist.
    let mut odd = parse("s 0 0 0 1\n");
    odd.nodes.clear();
    odd.shapes[0].node = 7;
    odd.materials.clear();
    assert!(load_parsed(&mut rt, odd, Path::new("odd.aff")).is_ok());
    rt.options.width = 8;
    rt.options.height = 6;
    let _ = render(&mut rt);
}
