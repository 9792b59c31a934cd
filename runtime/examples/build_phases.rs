//! Times the phases of an object BVH build: `build_phases MESH [THREADS] [REPEATS]`.
//! Prints the phases (binary build: PLOC or binned SAH, which also does the collapse's first pass
//! where no reinsertion follows; reinsertion; collapse), the 8-wide copy, for each build-quality preset, then the
//! whole `ObjectBvh::build` (which adds boxes, the 4-wide conversion, the 8-wide copy and triangle
//! preparation). `QUALITY=fast|medium|high|best` picks one preset; `CONVERT_LOOPS=N` and
//! `WIDEN_LOOPS=N` repeat the 4-wide and 8-wide conversions of each build N times (the repeats
//! reuse freed memory, as repeated builds in a running renderer do).

use obvhs::{aabb::Aabb, bvh2::reinsertion::ReinsertionOptimizer, ploc::PlocBuilder};
use rtsl_runtime::accel::binned::{build_binned_summarised, build_binned_with_leaves, merged_leaf_size};
use rtsl_runtime::accel::bvh4::{BuildQuality, Bvh4, CollapseRule, LeafSlots};
use rtsl_runtime::accel::bvh8::Bvh8;
use rtsl_runtime::accel::object::{ObjectBvh, OBJECT_LEAF_SIZE};
use rtsl_runtime::load_mesh;
use std::time::Instant;

/// CPU time of all threads of this process so far, ms (from `/proc/self/task/*/schedstat`).
fn cpu_ms() -> f64 {
    let mut ns = 0u64;
    for e in std::fs::read_dir("/proc/self/task").into_iter().flatten().flatten() {
        if let Ok(s) = std::fs::read_to_string(e.path().join("schedstat")) {
            ns += s.split_whitespace().next().and_then(|v| v.parse::<u64>().ok()).unwrap_or(0);
        }
    }
    ns as f64 / 1e6
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// Keeps freed memory in the process, as the `rtsl` binary's allocator does between builds
/// (`keep_freed_memory_for_the_next_frames`): glibc's malloc, this example's, maps each large
/// array afresh and unmaps it when freed (and the pool's threads allocate from arenas of their
/// own, which it trims), so every repeat's phases would include the kernel faulting in and
/// zeroing a few hundred megabytes on the largest meshes. The first repeat still does.
fn keep_freed_memory() {
    #[cfg(target_os = "linux")]
    // SAFETY: `mallopt` only sets allocator parameters; called before any other thread exists.
    unsafe {
        libc::mallopt(libc::M_MMAP_MAX, 0);
        libc::mallopt(libc::M_TRIM_THRESHOLD, i32::MAX);
        libc::mallopt(libc::M_ARENA_MAX, 1);
    }
}

fn main() {
    keep_freed_memory();
    let args: Vec<String> = std::env::args().collect();
    let mesh = load_mesh(args.get(1).expect("usage: build_phases MESH [THREADS] [REPEATS]")).unwrap();
    let threads = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(2);
    let repeats = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(3);
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    pool.install(|| {
        let boxes: Vec<Aabb> = (0..mesh.triangle_count())
            .map(|i| {
                let [a, b, c] = mesh.corners(i);
                let (a, b, c) = (a.into(), b.into(), c.into());
                Aabb::new(glam::Vec3A::min(a, b).min(c), glam::Vec3A::max(a, b).max(c))
            })
            .collect();
        if std::env::var("SWEEP").is_ok() {
            sweep(&boxes);
            return;
        }
        let qualities = match std::env::var("QUALITY").as_deref() {
            Ok("fast") => vec![BuildQuality::Fast],
            Ok("medium") => vec![BuildQuality::Medium],
            Ok("high") => vec![BuildQuality::High],
            Ok("best") => vec![BuildQuality::Best],
            _ => vec![BuildQuality::Fast, BuildQuality::Medium, BuildQuality::High, BuildQuality::Best],
        };
        let convert_loops: usize = std::env::var("CONVERT_LOOPS").ok().and_then(|s| s.parse().ok()).unwrap_or(1);
        for q in qualities {
            for _ in 0..repeats {
                let p = q.params(OBJECT_LEAF_SIZE);
                // As `ObjectBvh::build`: leaves in blocks.
                let slots = LeafSlots::Blocks(OBJECT_LEAF_SIZE);
                let rule = CollapseRule::new(p.max_prims_per_leaf, p.collapse_traversal_cost, slots);
                // As `Bvh4::build`: without reinsertion, the binned build does the collapse's first pass.
                let summarised = q.is_binned() && p.reinsertion_batch_ratio == 0.0;
                let t = Instant::now();
                let mut bvh2 = if summarised {
                    let leaf = merged_leaf_size(p.max_prims_per_leaf, p.collapse_traversal_cost);
                    build_binned_summarised(&boxes, leaf, slots.block_width(), &|node, below| {
                        rule.summary(node, |j| below.node(j))
                    })
                } else if q.is_binned() {
                    // Single-primitive leaves where reinsertion follows.
                    build_binned_with_leaves(&boxes, 1)
                } else {
                    PlocBuilder::with_capacity(boxes.len()).build(
                        p.ploc_search_distance,
                        &boxes,
                        (0..boxes.len() as u32).collect::<Vec<_>>(),
                        p.sort_precision,
                        p.search_depth_threshold,
                    )
                };
                let t_ploc = ms(t);
                let t = Instant::now();
                if p.reinsertion_batch_ratio > 0.0 {
                    ReinsertionOptimizer::default().run(&mut bvh2, p.reinsertion_batch_ratio, None);
                }
                let t_re1 = ms(t);
                let convert = |bvh2: &mut _| match summarised {
                    true => Bvh4::from_summarised_bvh2(bvh2, rule),
                    false => Bvh4::from_bvh2_with(bvh2, p.max_prims_per_leaf, p.collapse_traversal_cost, slots),
                };
                let t = Instant::now();
                let mut b4 = convert(&mut bvh2);
                let t_conv = ms(t);
                for _ in 1..convert_loops {
                    let t = Instant::now();
                    b4 = convert(&mut bvh2);
                    println!("  convert again {:.1} ms", ms(t));
                }
                let t = Instant::now();
                let b8 = Bvh8::from_bvh4(&b4);
                let t_wide = ms(t);
                let widen_loops: usize = std::env::var("WIDEN_LOOPS").ok().and_then(|s| s.parse().ok()).unwrap_or(1);
                for _ in 1..widen_loops {
                    let t = Instant::now();
                    let again = Bvh8::from_bvh4(&b4);
                    assert_eq!(again.nodes.len(), b8.nodes.len());
                    println!("  widen again {:.1} ms", ms(t));
                }
                let t = Instant::now();
                let object = ObjectBvh::from_bvh4(&mesh, b4.clone());
                let t_triangles = ms(t) - t_wide;
                drop(object);
                let t = Instant::now();
                let full = ObjectBvh::build(&mesh, q);
                let t_full = ms(t);
                println!(
                    "{q:?}: binary ({}) {t_ploc:.1} reinsert {t_re1:.1} collapse+to4 {t_conv:.1} to8 {t_wide:.1} triangles {t_triangles:.1} | full ObjectBvh::build {t_full:.1} ms ({} 4-wide nodes, {} 8-wide, sah {:.2})",
                    if q.is_binned() { "binned SAH" } else { "PLOC" },
                    b4.nodes.len(),
                    b8.nodes.len(),
                    full.bvh.sah_cost()
                );
            }
        }
    });
}

/// `SWEEP=1`: obvhs parameter combinations, build time and SAH cost of the 4-wide result.
pub fn sweep(boxes: &[Aabb]) {
    use obvhs::ploc::PlocSearchDistance as D;
    for ratio in [0.0f32, 0.01, 0.02, 0.08] {
        let p = BuildQuality::Medium.params(OBJECT_LEAF_SIZE);
        let (mut best, mut best_cpu, mut sah, mut t_re) = (f64::INFINITY, f64::INFINITY, 0.0, 0.0);
        let mut bins = Vec::new();
        for _ in 0..3 {
            let c = cpu_ms();
            let t = Instant::now();
            let mut bvh2 = rtsl_runtime::accel::binned::build_binned(boxes);
            let t_bin = ms(t);
            let t1 = Instant::now();
            if ratio > 0.0 {
                ReinsertionOptimizer::default().run(&mut bvh2, ratio, None);
            }
            t_re = ms(t1);
            let b4 = Bvh4::from_bvh2(&mut bvh2, p.max_prims_per_leaf, p.collapse_traversal_cost);
            best = best.min(ms(t));
            best_cpu = best_cpu.min(cpu_ms() - c);
            sah = b4.sah_cost();
            bins.push(t_bin);
        }
        println!("binned reinsert {ratio}: {best:.1} ms (cpu {best_cpu:.1} ms, binned {bins:.1?}, reinsertion {t_re:.1}), sah {sah:.2}");
    }
    if std::env::var("SWEEP").as_deref() == Ok("binned") {
        return;
    }
    for (dist, thr) in [(D::Minimum, 0), (D::VeryLow, 0), (D::Low, 0), (D::Medium, 3), (D::Medium, 0)] {
        for ratio in [0.0f32, 0.01, 0.02] {
            let mut p = BuildQuality::Medium.params(OBJECT_LEAF_SIZE);
            p.ploc_search_distance = dist;
            p.search_depth_threshold = thr;
            p.reinsertion_batch_ratio = ratio;
            let mut best = f64::INFINITY;
            let mut best_cpu = f64::INFINITY;
            let mut sah = 0.0;
            for _ in 0..3 {
                let c = cpu_ms();
                let t = Instant::now();
                let mut bvh2 = rtsl_runtime::accel::bvh4::build_binary(boxes, &p);
                let b4 = Bvh4::from_bvh2(&mut bvh2, p.max_prims_per_leaf, p.collapse_traversal_cost);
                best = best.min(ms(t));
                best_cpu = best_cpu.min(cpu_ms() - c);
                sah = b4.sah_cost();
            }
            println!("{dist:?} thr {thr} reinsert {ratio}: {best:.1} ms (cpu {best_cpu:.1} ms), sah {sah:.2}");
        }
    }
}
