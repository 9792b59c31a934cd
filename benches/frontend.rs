//! Front-end throughput: the shader library and the conformance corpus, from source to checked IR,
//! on one thread. Lexing alone over the same text is measured beside it, as the in-process baseline
//! (`rtsl bench frontend` prints lines per second directly).

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use rtsl_compiler::{compile_source_at, Options};
use std::path::{Path, PathBuf};

fn shaders() -> Vec<(PathBuf, String)> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut out = Vec::new();
    let mut stack = vec![root.join("stdlib_shaders"), root.join("tests/corpus")];
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir).expect("directory").flatten() {
            let p = entry.path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|e| e == "sl") {
                let text = std::fs::read_to_string(&p).expect("readable");
                out.push((p, text));
            }
        }
    }
    out.sort();
    out
}

fn frontend(c: &mut Criterion) {
    let files = shaders();
    let mut options = Options::default();
    options.preprocessor.include_paths.push(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/corpus/include"));
    let lines: usize = files.iter().map(|(p, t)| compile_source_at(p, t, &options).lines).sum();
    let own_lines: usize = files.iter().map(|(_, t)| t.lines().count()).sum();

    let mut group = c.benchmark_group("frontend");
    group.throughput(Throughput::Elements(lines as u64));
    group.bench_function("source to checked IR (lines incl. headers)", |b| {
        b.iter(|| {
            for (p, t) in &files {
                std::hint::black_box(compile_source_at(p, t, &options));
            }
        })
    });
    group.throughput(Throughput::Elements(own_lines as u64));
    group.bench_function("lex only, baseline (lines of the files themselves)", |b| {
        b.iter(|| {
            let mut interner = rtsl_compiler::symbol::Interner::new();
            for (_, t) in &files {
                std::hint::black_box(rtsl_compiler::front::lex::lex(
                    rtsl_compiler::source::FileId(0),
                    t,
                    &mut interner,
                ));
            }
        })
    });
    group.finish();
}

criterion_group!(benches, frontend);
criterion_main!(benches);
