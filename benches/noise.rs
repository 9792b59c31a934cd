//! The four-lane gradient noise (`shadeops::noise::x4`) as the JIT's helpers call it, a chunk of four
//! points a call: the form this build runs (in AVX2 registers on the default `x86-64-v3` target)
//! against the portable lane loops, over the same points.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use rtsl_compiler::shadeops::noise::x4::{self, X4};
use std::hint::black_box;

const N: usize = 4096;

/// `N` points along a slanted line through a few hundred lattice cells.
fn points<const D: usize>() -> Vec<[X4; D]> {
    (0..N / 4)
        .map(|i| std::array::from_fn(|k| std::array::from_fn(|l| (4 * i + l) as f32 * 0.173 * (k + 1) as f32 - 300.0)))
        .collect()
}

fn noise(c: &mut Criterion) {
    let (p1, p3, p4) = (points::<1>(), points::<3>(), points::<4>());
    let mut group = c.benchmark_group("noise");
    group.throughput(Throughput::Elements(N as u64));
    group.bench_function("float_1d", |b| b.iter(|| p1.iter().map(|p| x4::noise(black_box(*p))[3]).sum::<f32>()));
    group.bench_function("float_1d_portable", |b| {
        b.iter(|| p1.iter().map(|p| x4::portable::noise(black_box(*p))[3]).sum::<f32>())
    });
    group.bench_function("float_3d", |b| b.iter(|| p3.iter().map(|p| x4::noise(black_box(*p))[3]).sum::<f32>()));
    group.bench_function("float_3d_portable", |b| {
        b.iter(|| p3.iter().map(|p| x4::portable::noise(black_box(*p))[3]).sum::<f32>())
    });
    group.bench_function("triple_3d", |b| b.iter(|| p3.iter().map(|p| x4::vnoise(black_box(*p))[2][3]).sum::<f32>()));
    group.bench_function("triple_3d_portable", |b| {
        b.iter(|| p3.iter().map(|p| x4::portable::vnoise(black_box(*p))[2][3]).sum::<f32>())
    });
    group.bench_function("float_4d", |b| b.iter(|| p4.iter().map(|p| x4::noise(black_box(*p))[3]).sum::<f32>()));
    group.bench_function("float_4d_portable", |b| {
        b.iter(|| p4.iter().map(|p| x4::portable::noise(black_box(*p))[3]).sum::<f32>())
    });
    group.finish();
}

criterion_group!(benches, noise);
criterion_main!(benches);
