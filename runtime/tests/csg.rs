//! Solids (RIB `SolidBegin`/`SolidEnd`): what rays of every kind meet, checked by number against
//! the geometry RISpec's set operations make of tessellated spheres.

mod common;

use glam::Vec3A;
use rtsl_runtime::ray::{HitPacket, Ray, RayPacket, INVALID_ID};
use rtsl_runtime::render::World;

/// A world of `body` (requests inside `WorldBegin`/`WorldEnd`), with the load's warnings.
fn world(body: &str) -> (World, Vec<String>) {
    let (mut rt, warnings) = common::load(&format!("Projection \"perspective\"\nWorldBegin\n{body}\nWorldEnd\n"));
    (rt.build_world().expect("a world"), warnings)
}

/// The unit sphere with a bite of radius 0.6 taken out where it meets +z.
const BITTEN: &str = "SolidBegin \"difference\"
  SolidBegin \"primitive\" Sphere 1 -1 1 360 SolidEnd
  SolidBegin \"primitive\" TransformBegin Color [1 0 0] Translate 0 0 1 Sphere 0.6 -0.6 0.6 360 TransformEnd SolidEnd
SolidEnd";

/// Where a ray from `o` along `d` first meets the world (t, and the world's geometric normal), or
/// `None`: single ray, and the same ray in a packet, which must agree.
fn first_hit(world: &World, o: [f32; 3], d: [f32; 3]) -> Option<(f32, Vec3A)> {
    let ray = Ray::new(Vec3A::from_array(o), Vec3A::from_array(d));
    let hit = world.scene.intersect(&ray);
    let mut packet = RayPacket::new();
    packet.set(0, &ray);
    let mut hits = HitPacket::default();
    world.scene.intersect_packet(&packet, &mut hits);
    assert_eq!(hits.instance.0[0], hit.instance, "packet and single ray meet the same instance");
    assert_eq!(world.scene.occluded(&ray), hit.is_hit());
    assert_eq!(world.scene.occluded_packet(&packet) & 1 == 1, hit.is_hit());
    if hit.instance == INVALID_ID {
        return None;
    }
    assert!((hits.t.0[0] - hit.t).abs() < 1e-5);
    let surface = world.scene.surface(&hit).expect("a surface");
    Some((hit.t, surface.ng))
}

fn close(a: f32, b: f32, tolerance: f32) -> bool {
    (a - b).abs() < tolerance
}

#[test]
fn a_sphere_minus_a_sphere_shows_the_bite() {
    let (w, warnings) = world(BITTEN);
    assert!(warnings.is_empty(), "{warnings:?}");
    // Straight down the axis: the sphere's top is bitten away, and the bite's floor, the inside
    // of the small sphere at z = 0.4, is what the ray meets, facing up the ray.
    let (t, ng) = first_hit(&w, [0.0, 0.0, 5.0], [0.0, 0.0, -1.0]).expect("the bite's floor");
    assert!(close(t, 4.6, 0.01), "t = {t}");
    assert!(ng.z > 0.99, "the bite faces out of the solid: {ng}");
    // Beside the bite the sphere is whole: x = 0.9 lies outside the small sphere.
    let (t, ng) = first_hit(&w, [0.9, 0.0, 5.0], [0.0, 0.0, -1.0]).expect("the sphere");
    assert!(close(t, 5.0 - (1.0f32 - 0.81).sqrt(), 0.01), "t = {t}");
    assert!(ng.z > 0.0);
    // Through the part of the small sphere outside the big one: nothing there (x = 0.5, where
    // the small sphere reaches z = 1.33 and the big one 0.87, the bite goes down to 0.67).
    let (t, _) = first_hit(&w, [0.5, 0.0, 5.0], [0.0, 0.0, -1.0]).expect("the bite's wall");
    assert!(close(t, 5.0 - (1.0 - (0.36f32 - 0.25).sqrt()), 0.01), "t = {t}");
    // From below, the sphere's bottom as ever.
    let (t, ng) = first_hit(&w, [0.0, 0.0, -5.0], [0.0, 0.0, 1.0]).expect("the bottom");
    assert!(close(t, 4.0, 0.01) && ng.z < -0.99, "t = {t}, ng = {ng}");
}

#[test]
fn shadow_rays_pass_through_the_bite() {
    let (w, _) = world(BITTEN);
    // A segment ending above the bite's floor crosses where the sphere's top was: not blocked.
    let through = Ray::segment(Vec3A::new(0.0, 0.0, 5.0), Vec3A::new(0.0, 0.0, -1.0), 0.0, 4.5);
    assert!(!w.scene.occluded(&through));
    let mut packet = RayPacket::new();
    packet.set(0, &through);
    packet.set(1, &Ray::segment(Vec3A::new(0.0, 0.0, 5.0), Vec3A::new(0.0, 0.0, -1.0), 0.0, 4.7));
    assert_eq!(w.scene.occluded_packet(&packet), 0b10, "only the segment reaching the floor is blocked");
    // The plain surfaces, with no solid: the sphere's top blocks.
    let (plain, _) = world("Sphere 1 -1 1 360");
    assert!(plain.scene.occluded(&through));
}

#[test]
fn an_intersection_of_two_spheres_is_a_lens() {
    let body = "SolidBegin \"intersection\"
  SolidBegin \"primitive\" TransformBegin Translate -0.5 0 0 Sphere 1 -1 1 360 TransformEnd SolidEnd
  SolidBegin \"primitive\" TransformBegin Translate 0.5 0 0 Sphere 1 -1 1 360 TransformEnd SolidEnd
SolidEnd";
    let (w, warnings) = world(body);
    assert!(warnings.is_empty(), "{warnings:?}");
    // Along x, the lens spans -0.5 to 0.5: its left face is the right sphere's.
    let (t, ng) = first_hit(&w, [-5.0, 0.0, 0.0], [1.0, 0.0, 0.0]).expect("the lens");
    assert!(close(t, 4.5, 0.01) && ng.x < -0.99, "t = {t}, ng = {ng}");
    // Along z through the middle, both spheres' caps meet at z = sqrt(0.75).
    let (t, _) = first_hit(&w, [0.0, 0.0, 5.0], [0.0, 0.0, -1.0]).expect("the lens");
    assert!(close(t, 5.0 - 0.75f32.sqrt(), 0.01), "t = {t}");
    // Inside one sphere only: nothing.
    assert!(first_hit(&w, [0.8, 0.0, 5.0], [0.0, 0.0, -1.0]).is_none());
    assert!(first_hit(&w, [-0.8, 0.0, 5.0], [0.0, 0.0, -1.0]).is_none());
}

#[test]
fn a_union_has_no_inner_faces() {
    let body = "SolidBegin \"union\"
  SolidBegin \"primitive\" TransformBegin Translate -0.5 0 0 Sphere 1 -1 1 360 TransformEnd SolidEnd
  SolidBegin \"primitive\" TransformBegin Translate 0.5 0 0 Sphere 1 -1 1 360 TransformEnd SolidEnd
SolidEnd";
    let (w, _) = world(body);
    // From outside, the near sphere as ever.
    let (t, _) = first_hit(&w, [-5.0, 0.0, 0.0], [1.0, 0.0, 0.0]).expect("the union");
    assert!(close(t, 3.5, 0.01), "t = {t}");
    // From the middle, inside both: the inner faces are gone, the ray leaves at x = 1.5.
    let (t, ng) = first_hit(&w, [0.0, 0.0, 0.0], [1.0, 0.0, 0.0]).expect("the far side");
    assert!(close(t, 1.5, 0.01) && ng.x > 0.99, "t = {t}, ng = {ng}");
    // As plain surfaces, the ray meets the left sphere's inside at x = 0.5.
    let (plain, _) = world("Translate -0.5 0 0 Sphere 1 -1 1 360 Translate 1 0 0 Sphere 1 -1 1 360");
    let (t, _) = first_hit(&plain, [0.0, 0.0, 0.0], [1.0, 0.0, 0.0]).expect("an inner face");
    assert!(close(t, 0.5, 0.01), "t = {t}");
}

#[test]
fn each_part_keeps_its_own_shading() {
    let (w, _) = world(BITTEN);
    let material = |x: f32| {
        let hit = w.scene.intersect(&Ray::new(Vec3A::new(x, 0.0, 5.0), Vec3A::new(0.0, 0.0, -1.0)));
        let inst = &w.instances[hit.instance as usize];
        w.materials[inst.material_at(hit.primitive) as usize].color
    };
    assert_eq!(material(0.0), [1.0, 0.0, 0.0], "the bite is the red sphere's surface");
    assert_eq!(material(0.9), [1.0, 1.0, 1.0], "the rest is the white sphere's");
}

#[test]
fn nested_operations_combine() {
    // (A - (B - C)): B's inside is taken out of A except where C fills it back.
    let body = "SolidBegin \"difference\"
  SolidBegin \"primitive\" Sphere 1 -1 1 360 SolidEnd
  SolidBegin \"difference\"
    SolidBegin \"primitive\" TransformBegin Translate 0 0 1 Sphere 0.6 -0.6 0.6 360 TransformEnd SolidEnd
    SolidBegin \"primitive\" TransformBegin Translate 0 0 0.5 Sphere 0.2 -0.2 0.2 360 TransformEnd SolidEnd
  SolidEnd
SolidEnd";
    let (w, warnings) = world(body);
    assert!(warnings.is_empty(), "{warnings:?}");
    // Down the axis: the bite's floor would be at 0.4, but C (0.3 to 0.7) fills it: its top at
    // 0.7, facing up (C is subtracted twice).
    let (t, ng) = first_hit(&w, [0.0, 0.0, 5.0], [0.0, 0.0, -1.0]).expect("C's top");
    assert!(close(t, 4.3, 0.01) && ng.z > 0.99, "t = {t}, ng = {ng}");
}

#[test]
fn misplaced_solid_requests_warn_and_load() {
    let count = |body: &str| world(body).1;
    assert_eq!(count("SolidEnd").len(), 1);
    let nested = count("SolidBegin \"primitive\" SolidBegin \"union\" SolidEnd Sphere 1 -1 1 360 SolidEnd");
    assert_eq!(nested.len(), 1, "{nested:?}");
    assert!(nested[0].contains("inside a \"primitive\""), "{nested:?}");
    let unknown = count("SolidBegin \"xor\" SolidBegin \"primitive\" Sphere 1 -1 1 360 SolidEnd SolidEnd");
    assert_eq!(unknown.len(), 1, "{unknown:?}");
    let loose = count("SolidBegin \"union\" Sphere 1 -1 1 360 SolidEnd");
    assert_eq!(loose.len(), 1, "{loose:?}");
    let open = count("SolidBegin \"primitive\" Sphere 1 -1 1 360");
    assert_eq!(open.len(), 1, "{open:?}");
    // The sphere of an unclosed primitive is still a solid, seen as ever.
    let (w, _) = world("SolidBegin \"primitive\" Sphere 1 -1 1 360");
    assert!(first_hit(&w, [0.0, 0.0, 5.0], [0.0, 0.0, -1.0]).is_some());
}

#[test]
fn a_replica_sees_the_solids() {
    use rtsl_runtime::api::{Context, Replicator};
    let (mut rt, _) = common::load(&format!("Projection \"perspective\"\nWorldBegin\n{BITTEN}\nWorldEnd\n"));
    let update = Replicator::new().update(&rt, None).expect("an update");
    let mut replica = Context::new();
    replica.apply_update(&update).expect("applies");
    let down = |w: &World| first_hit(w, [0.0, 0.0, 5.0], [0.0, 0.0, -1.0]).map(|(t, _)| t);
    let (here, there) = (rt.build_world().expect("a world"), replica.build_world().expect("a world"));
    assert_eq!(down(&here), down(&there));
    assert!(close(down(&there).expect("the bite's floor"), 4.6, 0.01));
}

#[test]
fn deep_nesting_loads_in_linear_time() {
    // A hundred thousand blocks around one sphere: each block's node is appended once, and the
    // chain of one-operand operations costs a hit nothing.
    let depth = 100_000;
    let body = format!(
        "{}SolidBegin \"primitive\" Sphere 1 -1 1 360 SolidEnd{}",
        "SolidBegin \"union\" ".repeat(depth),
        " SolidEnd".repeat(depth)
    );
    let start = std::time::Instant::now();
    let (w, warnings) = world(&body);
    assert!(warnings.is_empty(), "{warnings:?}");
    assert!(start.elapsed().as_secs() < 60, "{:?}", start.elapsed());
    let (t, _) = first_hit(&w, [0.0, 0.0, 5.0], [0.0, 0.0, -1.0]).expect("the sphere");
    assert!(close(t, 4.0, 0.01));
}

#[test]
fn a_block_ignored_inside_a_subtracted_primitive_is_part_of_it() {
    let body = "SolidBegin \"difference\"
  SolidBegin \"primitive\" Sphere 1 -1 1 360 SolidEnd
  SolidBegin \"primitive\"
    SolidBegin \"primitive\" TransformBegin Translate 0 0 1 Sphere 0.6 -0.6 0.6 360 TransformEnd SolidEnd
  SolidEnd
SolidEnd";
    let (w, warnings) = world(body);
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    // The bite as ever, its floor reversed with the rest of the subtracted part.
    let (t, ng) = first_hit(&w, [0.0, 0.0, 5.0], [0.0, 0.0, -1.0]).expect("the bite's floor");
    assert!(close(t, 4.6, 0.01) && ng.z > 0.99, "t = {t}, ng = {ng}");
}
