//! The transcendental kernels (`shadeops::transcendental`), four lanes a call as the JIT's helpers
//! run them (SSE2 on x86-64), against the same kernels written lane by lane (`portable`) and Rust's
//! `f32` functions (libm) lane by lane, the baselines, over the same inputs.
//! (`exp` and `log` are not here: glibc's ran faster than Cephes-style kernels, so rtsl uses them.
//! `pow` is glibc's algorithm, four lanes at once: `pow4` against `powf` lane by lane, over the
//! cosines and exponents of specular highlights.)

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use rtsl_compiler::shadeops::transcendental as tm;
use std::hint::black_box;

const N: usize = 4096;

fn inputs(lo: f32, hi: f32) -> Vec<[f32; 4]> {
    (0..N / 4).map(|i| std::array::from_fn(|l| lo + (hi - lo) * ((4 * i + l) as f32 / N as f32))).collect()
}

fn transcendental(c: &mut Criterion) {
    type Four = fn([f32; 4]) -> [f32; 4];
    type Case = (&'static str, f32, f32, Four, Four, fn(f32) -> f32);
    let cases: [Case; 6] = [
        ("sin", -10.0, 10.0, tm::sin4, tm::portable::sin4, f32::sin),
        ("cos", -10.0, 10.0, tm::cos4, tm::portable::cos4, f32::cos),
        ("tan", -1.5, 1.5, tm::tan4, tm::portable::tan4, f32::tan),
        ("asin", -1.0, 1.0, tm::asin4, tm::portable::asin4, f32::asin),
        ("acos", -1.0, 1.0, tm::acos4, tm::portable::acos4, f32::acos),
        ("atan", -10.0, 10.0, tm::atan4, tm::portable::atan4, f32::atan),
    ];
    for (name, lo, hi, four, portable, libm) in cases {
        let xs = inputs(lo, hi);
        let mut group = c.benchmark_group(name);
        group.throughput(Throughput::Elements(N as u64));
        group.bench_function("kernel_x4", |b| b.iter(|| xs.iter().map(|x| four(black_box(*x))[3]).sum::<f32>()));
        group.bench_function("portable_x4", |b| b.iter(|| xs.iter().map(|x| portable(black_box(*x))[3]).sum::<f32>()));
        group
            .bench_function("libm_per_lane", |b| b.iter(|| xs.iter().map(|x| black_box(*x).map(libm)[3]).sum::<f32>()));
        group.finish();
    }
    let (bases, exponents) = (inputs(0.5, 1.0), inputs(1.0, 100.0));
    let mut group = c.benchmark_group("pow");
    group.throughput(Throughput::Elements(N as u64));
    // Every lane summed: a lane left unread is a `powf` the compiler may drop.
    let lanes = |p: [f32; 4]| p[0] + p[1] + p[2] + p[3];
    group.bench_function("kernel_x4", |b| {
        b.iter(|| bases.iter().zip(&exponents).map(|(x, y)| lanes(tm::pow4(black_box(*x), *y))).sum::<f32>())
    });
    group.bench_function("libm_per_lane", |b| {
        b.iter(|| {
            bases
                .iter()
                .zip(&exponents)
                .map(|(x, y)| lanes(std::array::from_fn(|l| black_box(x[l]).powf(y[l]))))
                .sum::<f32>()
        })
    });
    group.finish();
}

criterion_group!(benches, transcendental);
criterion_main!(benches);
