//! Criterion benchmark of filtered texture lookups (`MipMap::filter`) on a 256x256 RGB texture
//! that wraps periodically, the kind BART's scenes tile over their surfaces. The footprints mix
//! magnified, nearly isotropic and strongly anisotropic ones at every angle, as a scene's
//! differentials make them, in packets of neighbouring pixels. Prints the time of a filtered lookup as a multiple of one bilinear
//! lookup on the finest level, measured in the same process (this host's speed drifts).

use criterion::{criterion_group, criterion_main, Criterion};
use glam::Vec4;
use rtsl_runtime::texture::{Footprint, LookupLanes, LookupOptions, MipMap, TexImage};
use std::hint::black_box;
use std::time::Instant;

const SIZE: usize = 256;
const LOOKUPS: usize = 4096;

/// A small xorshift generator: the same lookups every run.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> f32 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 40) as f32 / (1u64 << 24) as f32
    }
}

fn texture(rng: &mut Rng) -> MipMap {
    let data = (0..SIZE * SIZE * 3).map(|_| rng.next()).collect();
    MipMap::new(TexImage::new(SIZE, SIZE, 3, data).expect("the data fills the image"))
}

/// Lookups in packets of 8x8 neighbouring pixels, as the renderer makes them: each packet at
/// coordinates across a few tiles, one pixel's step apart, with one footprint. The footprint's
/// major axis spans half a texel to 32 texels; its aspect ratio is under 1.3 for half of the
/// packets, up to 4 for a third, up to 20 for the rest.
fn lookups(rng: &mut Rng) -> Vec<(f32, f32, Footprint)> {
    let mut lookups = Vec::with_capacity(LOOKUPS);
    while lookups.len() < LOOKUPS {
        let (s, t) = (rng.next() * 5.0 - 2.0, rng.next() * 5.0 - 2.0);
        let major = (rng.next() * 6.0 - 1.0).exp2() / SIZE as f32;
        let pick = rng.next();
        let ratio = if pick < 0.5 {
            1.0 + 0.3 * rng.next()
        } else if pick < 0.85 {
            1.3 + 2.7 * rng.next()
        } else {
            4.0 + 16.0 * rng.next()
        };
        let minor = major / ratio;
        let angle = rng.next() * std::f32::consts::TAU;
        let (sin, cos) = angle.sin_cos();
        let footprint = Footprint { dsdx: major * cos, dtdx: major * sin, dsdy: -minor * sin, dtdy: minor * cos };
        for y in 0..8 {
            for x in 0..8 {
                let (x, y) = (x as f32, y as f32);
                let (ps, pt) =
                    (s + x * footprint.dsdx + y * footprint.dsdy, t + x * footprint.dtdx + y * footprint.dtdy);
                lookups.push((ps, pt, footprint));
            }
        }
    }
    lookups
}

fn filtered(map: &MipMap, lookups: &[(f32, f32, Footprint)], opts: &LookupOptions) -> f32 {
    let mut out = [0.0; 3];
    let mut sum = 0.0;
    for &(s, t, footprint) in lookups {
        map.filter(s, t, footprint, 0, &mut out, opts);
        sum += out[0] + out[1] + out[2];
    }
    sum
}

/// The lookups four at a time, as a shader chunk makes them (the renderer's way).
fn filtered_lanes(map: &MipMap, lookups: &[(f32, f32, Footprint)], opts: &LookupOptions) -> f32 {
    let mut out = [0.0; 12];
    let mut sum = 0.0;
    for chunk in lookups.chunks_exact(4) {
        let lane = |f: &dyn Fn(&(f32, f32, Footprint)) -> f32| Vec4::from_array(std::array::from_fn(|l| f(&chunk[l])));
        let lanes = LookupLanes {
            s: lane(&|l| l.0),
            t: lane(&|l| l.1),
            dsdx: lane(&|l| l.2.dsdx),
            dtdx: lane(&|l| l.2.dtdx),
            dsdy: lane(&|l| l.2.dsdy),
            dtdy: lane(&|l| l.2.dtdy),
            sblur: Vec4::ZERO,
            tblur: Vec4::ZERO,
        };
        map.filter_lanes(&lanes, [true; 4], [0; 4], &mut out, opts);
        sum += out.iter().sum::<f32>();
    }
    sum
}

fn bilinear(map: &MipMap, lookups: &[(f32, f32, Footprint)], opts: &LookupOptions) -> f32 {
    let mut out = [0.0; 3];
    let mut sum = 0.0;
    for &(s, t, _) in lookups {
        map.filter(s, t, Footprint::POINT, 0, &mut out, opts);
        sum += out[0] + out[1] + out[2];
    }
    sum
}

fn bench(c: &mut Criterion) {
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    let map = texture(&mut rng);
    let lookups = lookups(&mut rng);
    let opts = LookupOptions::default();

    let mut g = c.benchmark_group("texture_256_rgb");
    g.bench_function("filtered", |b| b.iter(|| black_box(filtered(&map, black_box(&lookups), &opts))));
    g.bench_function("filtered_lanes", |b| b.iter(|| black_box(filtered_lanes(&map, black_box(&lookups), &opts))));
    g.bench_function("bilinear", |b| b.iter(|| black_box(bilinear(&map, black_box(&lookups), &opts))));
    g.finish();

    // Paired rounds, alternating, so that all see the same drift of the host.
    let mut rounds = Vec::new();
    for _ in 0..15 {
        let time = |f: &dyn Fn() -> f32| {
            let start = Instant::now();
            for _ in 0..20 {
                black_box(f());
            }
            start.elapsed().as_secs_f64() / (20 * LOOKUPS) as f64 * 1e9
        };
        let one = time(&|| filtered(&map, black_box(&lookups), &opts));
        let lanes = time(&|| filtered_lanes(&map, black_box(&lookups), &opts));
        let point = time(&|| bilinear(&map, black_box(&lookups), &opts));
        rounds.push([one, lanes, one / point, lanes / point]);
    }
    let median = |k: usize| {
        let mut v: Vec<f64> = rounds.iter().map(|r| r[k]).collect();
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    println!(
        "texture: a filtered lookup takes {:.0} ns one at a time, {:.0} ns four lanes at a time: {:.2} and {:.2} times one \
         bilinear lookup (medians of 15 paired rounds)",
        median(0),
        median(1),
        median(2),
        median(3)
    );
}

criterion_group!(benches, bench);
criterion_main!(benches);
