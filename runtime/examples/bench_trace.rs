//! Runs the tracer benchmark (the library side of `rtsl bench trace`) on a mesh file.
//!
//! Usage: `bench_trace MESH [THREADS] [REPEATS] [WxH]`, with the benchmark view of
//! `shared/bench/README.md`. `PASSES=ss,ps` (environment) times only some passes, as
//! `rtsl bench trace --passes` does (`pp`, `ps`, `sp`, `ss`).

use rtsl_runtime::{run_bench, BenchOptions};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let Some(mesh) = args.get(1) else {
        eprintln!("usage: bench_trace MESH [THREADS] [REPEATS] [WxH]");
        std::process::exit(2);
    };
    let mut o = BenchOptions::new(mesh);
    if let Some(t) = args.get(2).and_then(|s| s.parse().ok()) {
        o.threads = t;
    }
    if let Some(r) = args.get(3).and_then(|s| s.parse().ok()) {
        o.repeats = r;
    }
    if let Some((w, h)) = args.get(4).and_then(|s| s.split_once('x')) {
        if let (Ok(w), Ok(h)) = (w.parse(), h.parse()) {
            o.width = w;
            o.height = h;
        }
    }
    if let Ok(p) = std::env::var("PASSES") {
        let on: Vec<&str> = p.split(',').collect();
        o.passes = ["pp", "ps", "sp", "ss"].map(|n| on.contains(&n));
    }
    match run_bench(&o) {
        Ok(r) => println!("{r:#?}"),
        Err(e) => {
            eprintln!("error: {e}");
            std::process::exit(1);
        }
    }
}
