//! Shading speed per point, with criterion: the JIT, the reference interpreter and hand-written Rust
//! over the same SoA data (`rtsl::bench::shading::ShadingCase`; `rtsl bench shade` prints the same
//! comparison as ratios measured in one run).

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use rtsl::bench::shading::ShadingCase;

fn shading(c: &mut Criterion) {
    for name in ["plastic", "noisy"] {
        let Ok(mut case) = ShadingCase::new(name, 4096) else { continue };
        let mut group = c.benchmark_group(format!("shade_{name}"));
        group.throughput(Throughput::Elements(case.points() as u64));
        group.bench_function("jit", |b| b.iter(|| case.jit()));
        group.bench_function("rust", |b| b.iter(|| case.rust()));
        group.throughput(Throughput::Elements(1));
        let mut k = 0;
        group.bench_function("interpreter_per_point", |b| {
            b.iter(|| {
                k += 1;
                case.interpreter(k)
            })
        });
        group.finish();
    }
}

criterion_group!(benches, shading);
criterion_main!(benches);
