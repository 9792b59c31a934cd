//! Criterion benchmark of the tracer: primary and shadow rays of one 64x64 block of the benchmark
//! view, with packet and with single-ray traversal, measured in the same process; prints the
//! packet/single ratios. Uses `RTSL_BENCH_MESH` (default `/tmp/s34k.obj`, made by
//! `shared/bench/gen_scene.rs`) and skips with a message when the mesh is missing.

use criterion::{criterion_group, criterion_main, Criterion};
use glam::Vec3A;
use rtsl_runtime::camera::{packet_lane_offset, PACKET_SIDE};
use rtsl_runtime::{
    load_mesh, offset_ray_origin, scene_from_mesh, BuildQuality, Camera, HitPacket, Ray, RayPacket, PACKET_SIZE,
};
use std::hint::black_box;
use std::time::Instant;

const BLOCK: u32 = 64;

fn bench(c: &mut Criterion) {
    let path = std::env::var("RTSL_BENCH_MESH").unwrap_or_else(|_| "/tmp/s34k.obj".to_string());
    let mesh = match load_mesh(&path) {
        Ok(m) => m,
        Err(e) => {
            eprintln!("skipping the trace benchmark: {e} (generate it with shared/bench/gen_scene.rs)");
            return;
        }
    };
    let scene = scene_from_mesh(mesh, BuildQuality::High);
    let cam = Camera::look_at(Vec3A::new(0.0, 130.0, -170.0), Vec3A::new(0.0, 0.0, -53.0), Vec3A::Y, 45.0, 1024, 768);
    let light = Vec3A::new(60.0, 220.0, 40.0);
    let (x0, y0) = (480, 352);
    let packets: Vec<RayPacket> = (0..BLOCK / PACKET_SIDE)
        .flat_map(|by| (0..BLOCK / PACKET_SIDE).map(move |bx| (bx, by)))
        .map(|(bx, by)| cam.packet(x0 + bx * PACKET_SIDE, y0 + by * PACKET_SIDE))
        .collect();
    let rays: Vec<Ray> = packets.iter().flat_map(|p| (0..PACKET_SIZE).map(|i| p.get(i))).collect();
    let shadow_packets: Vec<RayPacket> = packets
        .iter()
        .map(|p| {
            let mut hp = HitPacket::default();
            scene.intersect_packet(p, &mut hp);
            let mut sp = RayPacket::new();
            for i in 0..PACKET_SIZE {
                if let Some(s) = scene.surface(&hp.get(i)) {
                    let n = if s.ng.dot(light - s.p) < 0.0 { -s.ng } else { s.ng };
                    let o = offset_ray_origin(s.p, n);
                    sp.set(i, &Ray::segment(o, light - o, 0.0, 1.0));
                }
            }
            sp
        })
        .collect();
    let shadow_rays: Vec<Ray> = shadow_packets
        .iter()
        .flat_map(|p| (0..PACKET_SIZE).filter(move |i| p.active >> i & 1 != 0).map(|i| p.get(i)))
        .collect();
    let _ = packet_lane_offset(0);

    let mut g = c.benchmark_group("trace_64x64");
    g.bench_function("primary_packet", |b| {
        b.iter(|| {
            let mut hp = HitPacket::default();
            for p in &packets {
                scene.intersect_packet(p, &mut hp);
                black_box(&hp);
            }
        })
    });
    g.bench_function("primary_single", |b| b.iter(|| rays.iter().map(|r| scene.intersect(r).t).sum::<f32>()));
    g.bench_function("shadow_packet", |b| {
        b.iter(|| shadow_packets.iter().map(|p| scene.occluded_packet(p).count_ones()).sum::<u32>())
    });
    g.bench_function("shadow_single", |b| b.iter(|| shadow_rays.iter().filter(|r| scene.occluded(r)).count()));
    g.finish();

    // Ratios measured back to back in this process.
    let time = |f: &mut dyn FnMut()| {
        let t = Instant::now();
        for _ in 0..20 {
            f();
        }
        t.elapsed().as_secs_f64()
    };
    let pp = time(&mut || {
        let mut hp = HitPacket::default();
        for p in &packets {
            scene.intersect_packet(p, &mut hp);
            black_box(&hp);
        }
    });
    let ps = time(&mut || {
        black_box(rays.iter().map(|r| scene.intersect(r).t).sum::<f32>());
    });
    let sp = time(&mut || {
        black_box(shadow_packets.iter().map(|p| scene.occluded_packet(p).count_ones()).sum::<u32>());
    });
    let ss = time(&mut || {
        black_box(shadow_rays.iter().filter(|r| scene.occluded(r)).count());
    });
    println!("packet/single speed-up: primary {:.2}x, shadow {:.2}x", ps / pp, ss / sp);
}

criterion_group!(benches, bench);
criterion_main!(benches);
