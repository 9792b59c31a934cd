//! Compiled artifacts: they round-trip the IR exactly, notice changed sources and includes, recompile
//! or refuse as the situation allows, and turn every damaged file into an error.

mod common;

use rtsl_compiler::artifact::{self, ArtifactError, Loaded};
use rtsl_compiler::{compile_file, ir, Options};
use std::path::{Path, PathBuf};

fn options_with(include: &[&Path]) -> Options {
    let mut o = Options::default();
    o.preprocessor.include_paths = include.iter().map(|p| p.to_path_buf()).collect();
    o
}

/// A shader with a header, in a fresh directory; returns (dir, shader path, header path).
fn shader_with_header(tint: &str) -> (tempfile::TempDir, PathBuf, PathBuf) {
    let dir = tempfile::tempdir().expect("tempdir");
    let header = dir.path().join("tint.h");
    let shader = dir.path().join("tinted.sl");
    std::fs::write(&header, format!("#define TINT {tint}\n")).expect("write");
    std::fs::write(&shader, "#include \"tint.h\"\nsurface tinted(float k = 1;) { Oi = Os; Ci = k * TINT * Cs; }\n")
        .expect("write");
    (dir, shader, header)
}

fn compiled_artifact(shader: &Path, options: &Options) -> (PathBuf, Vec<u8>) {
    let c = compile_file(shader, options).expect("readable");
    assert!(c.ok(), "{}", c.render());
    let bytes = artifact::encode(&c, options).expect("a shader");
    let path = shader.with_extension(artifact::EXTENSION);
    artifact::write_atomically(&path, &bytes).expect("write");
    (path, bytes)
}

#[test]
fn every_library_and_corpus_shader_round_trips_exactly() {
    let corpus_include = Path::new("../tests/corpus/include");
    let mut files = common::shader_files(Path::new("../stdlib_shaders"));
    files.extend(common::shader_files(Path::new("../tests/corpus")));
    let options = options_with(&[corpus_include]);
    let mut checked = 0;
    for f in files {
        let c = compile_file(&f, &options).expect("readable");
        let (Some(module), Some(iface)) = (&c.module, &c.interface) else { continue };
        let bytes = artifact::encode(&c, &options).expect("encodes");
        let a = artifact::decode(&f, &bytes).unwrap_or_else(|e| panic!("{}: {e}", f.display()));
        assert_eq!(ir::print::module(&a.module), ir::print::module(module), "{}", f.display());
        assert_eq!(
            serde_json::to_value(&a.interface).expect("json"),
            serde_json::to_value(iface).expect("json"),
            "{}",
            f.display()
        );
        assert_eq!(a.options.include_paths, vec![corpus_include.to_path_buf()]);
        assert_eq!(a.compiler_version, env!("CARGO_PKG_VERSION"));
        checked += 1;
    }
    assert!(checked >= 90, "only {checked} shaders");
}

#[test]
fn an_up_to_date_artifact_loads_without_the_front_end() {
    let (_dir, shader, header) = shader_with_header("color(1, 0, 0)");
    let (path, _) = compiled_artifact(&shader, &Options::default());
    let Loaded::Artifact(a) = artifact::load(&path, &Options::default()).expect("loads") else {
        panic!("an unchanged artifact was recompiled")
    };
    assert_eq!(a.interface.name, "tinted");
    let recorded: Vec<PathBuf> = a.files.iter().filter_map(|f| f.path.clone()).collect();
    let canonical = |p: &Path| std::fs::canonicalize(p).expect("exists");
    assert_eq!(recorded, vec![canonical(&shader), canonical(&header)], "the source and its include, absolute");
    assert_eq!(a.source.as_deref(), Some(canonical(&shader).as_path()));
}

#[test]
fn a_changed_include_makes_the_artifact_recompile_from_source() {
    let (_dir, shader, header) = shader_with_header("color(1, 0, 0)");
    let (path, _) = compiled_artifact(&shader, &Options::default());
    let before = ir::print::module(&artifact::read(&path).expect("reads").module);
    std::fs::write(&header, "#define TINT color(0, 0, 1)\n").expect("write");
    match artifact::load(&path, &Options::default()).expect("loads") {
        Loaded::Recompiled { compilation, reason } => {
            assert!(reason.contains("tint.h"), "{reason}");
            assert!(compilation.ok(), "{}", compilation.render());
            let after = ir::print::module(compilation.module.as_ref().expect("module"));
            assert_ne!(before, after, "the new tint is compiled in");
        }
        Loaded::Artifact(_) => panic!("a stale artifact was used"),
    }
    // A changed main source too.
    std::fs::write(&shader, "surface tinted(float k = 2;) { Ci = k; }\n").expect("write");
    let Loaded::Recompiled { compilation, .. } = artifact::load(&path, &Options::default()).expect("loads") else {
        panic!("a stale artifact was used")
    };
    let iface = compilation.interface.as_ref().expect("interface");
    assert_eq!(iface.parameters[0].default, Some(rtsl_compiler::interface::Value::Float(2.0)));
}

#[test]
fn without_its_sources_an_artifact_is_used_unless_something_says_it_is_stale() {
    let (dir, shader, header) = shader_with_header("color(1, 0, 0)");
    let (path, _) = compiled_artifact(&shader, &Options::default());
    // A library shipped without sources: nothing to compare with, the artifact is used.
    std::fs::remove_file(&shader).expect("rm");
    std::fs::remove_file(&header).expect("rm");
    assert!(matches!(artifact::load(&path, &Options::default()), Ok(Loaded::Artifact(_))));
    // The header is back with other contents but the source is not: stale, and nothing to recompile.
    std::fs::write(&header, "#define TINT color(0, 1, 0)\n").expect("write");
    let err = artifact::load(&path, &Options::default()).expect_err("refused");
    assert!(matches!(err, ArtifactError::StaleWithoutSource { .. }), "{err}");
    let message = err.to_string();
    assert!(message.contains("tint.h") && message.contains("tinted.sl"), "{message}");
    drop(dir);
}

#[test]
fn an_artifact_of_another_format_is_recompiled_or_refused() {
    let (_dir, shader, _header) = shader_with_header("color(1, 0, 0)");
    let (path, mut bytes) = compiled_artifact(&shader, &Options::default());
    bytes[8] = bytes[8].wrapping_add(1); // the format version
    std::fs::write(&path, &bytes).expect("write");
    let loaded = artifact::load(&path, &Options::default()).expect("recompiled");
    let Loaded::Recompiled { compilation, reason } = loaded else { panic!("an old format was decoded") };
    assert!(compilation.ok() && reason.contains("format"), "{reason}");
    std::fs::remove_file(&shader).expect("rm");
    let err = artifact::load(&path, &Options::default()).expect_err("refused");
    assert!(matches!(err, ArtifactError::Outdated { .. }), "{err}");
    assert!(err.to_string().contains("tinted.sl"), "{err}");
}

#[test]
fn truncated_or_corrupted_artifacts_are_errors_never_a_crash_or_a_wrong_shader() {
    let (_dir, shader, _header) = shader_with_header("color(1, 0, 0)");
    let (path, bytes) = compiled_artifact(&shader, &Options::default());
    for len in 0..bytes.len() {
        let err = artifact::decode(&path, &bytes[..len]).expect_err("truncated");
        assert!(
            matches!(
                err,
                ArtifactError::Truncated { .. } | ArtifactError::NotAnArtifact { .. } | ArtifactError::Corrupt { .. }
            ),
            "{len}: {err}"
        );
    }
    let mut longer = bytes.clone();
    longer.push(0);
    assert!(matches!(artifact::decode(&path, &longer), Err(ArtifactError::Corrupt { .. })));
    // Flip every bit of the header and a spread of the payload's bytes: each is detected. (Bits of the
    // version or fingerprint read as another compiler's artifact.)
    let stride = (bytes.len() / 400).max(1);
    for i in (0..bytes.len()).filter(|i| *i < 120 || i % stride == 0) {
        for bit in 0..8 {
            let mut damaged = bytes.clone();
            damaged[i] ^= 1 << bit;
            let err = artifact::decode(&path, &damaged).expect_err("damage detected");
            assert!(!matches!(err, ArtifactError::Io { .. }), "{i}: {err}");
        }
    }
    assert!(matches!(artifact::decode(&path, b"surface plastic() {}"), Err(ArtifactError::NotAnArtifact { .. })));
}

#[test]
fn well_checksummed_nonsense_is_refused_by_decoding_or_validation() {
    // Forge artifacts whose checksum is right but whose payload is garbage or inconsistent IR: the
    // decoder or the validator must refuse them (the JIT must never see such IR).
    let (_dir, shader, _header) = shader_with_header("color(1, 0, 0)");
    let (path, bytes) = compiled_artifact(&shader, &Options::default());
    let source_len = u32::from_le_bytes(bytes[44..48].try_into().expect("4 bytes")) as usize;
    let at = 48 + source_len;
    let body = bytes[at + 40..].to_vec();
    let reseal = |body: &[u8]| {
        let mut out = bytes[..at].to_vec();
        out.extend_from_slice(&(body.len() as u64).to_le_bytes());
        let mut h = blake3::Hasher::new();
        h.update(&out);
        h.update(body);
        out.extend_from_slice(h.finalize().as_bytes());
        out.extend_from_slice(body);
        out
    };
    // Sanity: resealing the real payload gives a valid artifact.
    assert!(artifact::decode(&path, &reseal(&body)).is_ok());
    let mut seed = 0x9e37_79b9_u32;
    let mut refused = 0;
    for round in 0..300 {
        let mut forged = body.clone();
        for _ in 0..1 + round % 4 {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            let i = seed as usize % forged.len();
            forged[i] = (seed >> 8) as u8;
        }
        match artifact::decode(&path, &reseal(&forged)) {
            Err(ArtifactError::Undecodable { .. } | ArtifactError::Invalid { .. }) => refused += 1,
            Err(e) => panic!("unexpected error kind: {e}"),
            // A change that keeps the IR valid (a constant, a name) is a different but valid shader.
            Ok(a) => assert!(rtsl_compiler::valid::validate(&a.module).is_ok()),
        }
    }
    assert!(refused > 50, "only {refused} of 300 forgeries refused");
}

/// One place in a module that holds a handle, a count or a length the back ends index by.
enum Slot<'a> {
    Var(&'a mut u32),
    Expr(&'a mut u32),
    Func(&'a mut u32),
    ParamIndex(&'a mut u32),
    Overload(&'a mut u16),
    Levels(&'a mut u32),
    ArrayLen(&'a mut u32),
}

/// Calls `f` on every slot of `m`, in a fixed order.
fn visit_slots(m: &mut ir::Module, f: &mut dyn FnMut(Slot<'_>)) {
    use ir::{Arg, ArrayLen, ExprKind, PlaceBase, StmtKind, VarKind};
    fn ty(t: &mut ir::Type, f: &mut dyn FnMut(Slot<'_>)) {
        if let Some(ArrayLen::Fixed(n)) = &mut t.array {
            f(Slot::ArrayLen(n));
        }
    }
    fn place(p: &mut ir::Place, f: &mut dyn FnMut(Slot<'_>)) {
        if let PlaceBase::Var(v) = &mut p.base {
            f(Slot::Var(&mut v.0));
        }
        for e in [&mut p.index, &mut p.component].into_iter().flatten() {
            f(Slot::Expr(&mut e.0));
        }
        ty(&mut p.ty, f);
    }
    fn args(list: &mut [Arg], f: &mut dyn FnMut(Slot<'_>)) {
        for a in list {
            match a {
                Arg::Value(e) => f(Slot::Expr(&mut e.0)),
                Arg::Ref(p) => place(p, f),
            }
        }
    }
    fn block(b: &mut ir::Block, f: &mut dyn FnMut(Slot<'_>)) {
        for s in &mut b.stmts {
            match &mut s.kind {
                StmtKind::Expr(e) => f(Slot::Expr(&mut e.0)),
                StmtKind::If { cond, then, otherwise } => {
                    f(Slot::Expr(&mut cond.0));
                    block(then, f);
                    block(otherwise, f);
                }
                StmtKind::Loop { cond, body, step } => {
                    if let Some(c) = cond {
                        f(Slot::Expr(&mut c.0));
                    }
                    block(body, f);
                    block(step, f);
                }
                StmtKind::Break(n) | StmtKind::Continue(n) => f(Slot::Levels(n)),
                StmtKind::Return(v) => {
                    if let Some(e) = v {
                        f(Slot::Expr(&mut e.0));
                    }
                }
                StmtKind::Illuminance { category, position, cone, body } => {
                    if let Some(c) = category {
                        f(Slot::Expr(&mut c.0));
                    }
                    f(Slot::Expr(&mut position.0));
                    if let Some((a, b)) = cone {
                        f(Slot::Expr(&mut a.0));
                        f(Slot::Expr(&mut b.0));
                    }
                    block(body, f);
                }
                StmtKind::Illuminate { position, cone, body } => {
                    f(Slot::Expr(&mut position.0));
                    if let Some((a, b)) = cone {
                        f(Slot::Expr(&mut a.0));
                        f(Slot::Expr(&mut b.0));
                    }
                    block(body, f);
                }
                StmtKind::Solar { cone, body } => {
                    if let Some((a, b)) = cone {
                        f(Slot::Expr(&mut a.0));
                        f(Slot::Expr(&mut b.0));
                    }
                    block(body, f);
                }
                StmtKind::Gather { category, position, direction, angle, samples, params, body, otherwise } => {
                    for e in [category, position, direction, angle, samples] {
                        f(Slot::Expr(&mut e.0));
                    }
                    for (name, a) in params {
                        f(Slot::Expr(&mut name.0));
                        args(std::slice::from_mut(a), f);
                    }
                    block(body, f);
                    block(otherwise, f);
                }
            }
        }
    }
    if let Some(s) = &mut m.shader {
        f(Slot::Func(&mut s.body.0));
        for p in &mut s.params {
            f(Slot::Var(&mut p.var.0));
            f(Slot::Expr(&mut p.default.0));
            ty(&mut p.ty, f);
        }
    }
    for func in &mut m.functions {
        for p in &mut func.params {
            f(Slot::Var(&mut p.0));
        }
        for v in &mut func.vars {
            ty(&mut v.ty, f);
            if let VarKind::ShaderParam { index, .. } = &mut v.kind {
                f(Slot::ParamIndex(index));
            }
        }
        for e in &mut func.exprs {
            ty(&mut e.ty, f);
            match &mut e.kind {
                ExprKind::Const(_) | ExprKind::Global(_) => {}
                ExprKind::Var(v) => f(Slot::Var(&mut v.0)),
                ExprKind::Index { base, index } => {
                    f(Slot::Expr(&mut base.0));
                    f(Slot::Expr(&mut index.0));
                }
                ExprKind::Unary { arg, .. } | ExprKind::Convert { arg } => f(Slot::Expr(&mut arg.0)),
                ExprKind::Binary { lhs, rhs, .. } => {
                    f(Slot::Expr(&mut lhs.0));
                    f(Slot::Expr(&mut rhs.0));
                }
                ExprKind::Construct { args } | ExprKind::ArrayLiteral { elements: args } => {
                    for a in args {
                        f(Slot::Expr(&mut a.0));
                    }
                }
                ExprKind::SpaceCast { space, arg } => {
                    f(Slot::Expr(&mut space.0));
                    f(Slot::Expr(&mut arg.0));
                }
                ExprKind::Select { cond, a, b } => {
                    for e in [cond, a, b] {
                        f(Slot::Expr(&mut e.0));
                    }
                }
                ExprKind::CallBuiltin { overload, args: list, .. } => {
                    f(Slot::Overload(overload));
                    args(list, f);
                }
                ExprKind::Call { func: callee, args: list } => {
                    f(Slot::Func(&mut callee.0));
                    args(list, f);
                }
                ExprKind::Assign { place: p, value, .. } => {
                    place(p, f);
                    f(Slot::Expr(&mut value.0));
                }
            }
        }
        block(&mut func.body, f);
    }
}

/// A shader that puts a handle in every kind of slot: user functions with output and array
/// parameters, arrays, triple components, loops with `break`, built-ins, lights.
const EVERY_SLOT: &str = r#"
float total(float a[]; output float n) {
    float i, sum = 0;
    n = 3;
    for (i = 0; i < n; i += 1) {
        if (a[i] < 0) break;
        sum += a[i];
    }
    return sum;
}

surface slots(float k = 2; color tint = color(1, 0.5, 0.25); output varying float count = 0;) {
    float w[3] = {1, k, 3};
    point p = P;
    p[1] = s * k;
    point ps[2] = {P, p};
    ps[1][2] = t;
    float m = total(w, count);
    color c = 0;
    illuminance(P, N, PI / 2) {
        c += Cl * max(0, normalize(L) . normalize(N));
    }
    while (m > 1) { m = m / 2; if (m < 3) continue; }
    Ci = tint * c * noise(ps[1]) * (k > 1 ? m : 1);
    Oi = Os;
}
"#;

/// Encodes `module` as the payload of an artifact (the field order of `artifact`'s payload),
/// sealed with a correct checksum, as someone editing an artifact would.
fn forge(bytes: &[u8], a: &artifact::Artifact, module: &ir::Module) -> Vec<u8> {
    let payload = (&a.compiler_version, &a.options, &a.files, &a.warnings, module);
    let body = postcard::to_stdvec(&payload).expect("encodes");
    let source_len = u32::from_le_bytes(bytes[44..48].try_into().expect("4 bytes")) as usize;
    let mut out = bytes[..48 + source_len].to_vec();
    out.extend_from_slice(&(body.len() as u64).to_le_bytes());
    let mut h = blake3::Hasher::new();
    h.update(&out);
    h.update(&body);
    out.extend_from_slice(h.finalize().as_bytes());
    out.extend_from_slice(&body);
    out
}

/// Replaces slot `k` of `m` by what `value` makes of it; false when `m` has fewer slots.
fn mutate(m: &mut ir::Module, k: usize, value: &dyn Fn(u32) -> u32) -> bool {
    let mut seen = 0;
    let mut done = false;
    visit_slots(m, &mut |slot| {
        if seen == k {
            done = true;
            match slot {
                Slot::Var(x)
                | Slot::Expr(x)
                | Slot::Func(x)
                | Slot::ParamIndex(x)
                | Slot::Levels(x)
                | Slot::ArrayLen(x) => *x = value(*x),
                Slot::Overload(x) => *x = value(u32::from(*x)) as u16,
            }
        }
        seen += 1;
    });
    done
}

#[test]
fn forged_handles_and_sizes_are_refused_before_any_back_end_sees_them() {
    let dir = tempfile::tempdir().expect("tempdir");
    let shader = dir.path().join("slots.sl");
    std::fs::write(&shader, EVERY_SLOT).expect("write");
    let (path, bytes) = compiled_artifact(&shader, &Options::default());
    let a = artifact::decode(&path, &bytes).expect("the real artifact decodes");
    // Sanity: the forging itself keeps a valid artifact valid.
    assert!(artifact::decode(&path, &forge(&bytes, &a, &a.module)).is_ok());
    let mut kinds = std::collections::BTreeSet::new();
    visit_slots(&mut a.module.clone(), &mut |slot| {
        kinds.insert(match slot {
            Slot::Var(_) => "var",
            Slot::Expr(_) => "expr",
            Slot::Func(_) => "func",
            Slot::ParamIndex(_) => "param index",
            Slot::Overload(_) => "overload",
            Slot::Levels(_) => "levels",
            Slot::ArrayLen(_) => "array length",
        });
    });
    assert_eq!(kinds.len(), 7, "the shader exercises every kind of slot: {kinds:?}");
    // Out of range, in every slot: always an `Invalid` error, never a panic.
    let mut slots = 0;
    for k in 0.. {
        let mut forged = a.module.clone();
        if !mutate(&mut forged, k, &|_| 2_000_000) {
            break;
        }
        slots += 1;
        match artifact::decode(&path, &forge(&bytes, &a, &forged)) {
            Err(ArtifactError::Invalid { detail, .. }) => assert!(!detail.is_empty()),
            Err(e) => panic!("slot {k}: unexpected error {e}"),
            Ok(_) => panic!("slot {k}: an out-of-range value passed validation"),
        }
    }
    assert!(slots > 100, "only {slots} slots");
    // Zero-length arrays and `break 0` are out of range too; in-range but wrong values (another
    // variable, expression or function) may make a different valid shader, which both back ends
    // must then run without a panic.
    for k in 0..slots {
        let values: [&dyn Fn(u32) -> u32; 3] = [&|_| 0, &|x| x + 1, &|x| x.saturating_sub(1)];
        for value in values {
            let mut forged = a.module.clone();
            mutate(&mut forged, k, value);
            if let Ok(loaded) = artifact::decode(&path, &forge(&bytes, &a, &forged)) {
                let m = &loaded.module;
                let compiled = rtsl_compiler::back::jit::compile(m);
                let mut point = rtsl_compiler::interp::ShadingPoint::new(m.shader.as_ref().expect("a shader").kind);
                let mut host = rtsl_compiler::interp::TestHost::default();
                let _ = rtsl_compiler::interp::run(m, &[], &mut point, &mut host, Default::default());
                if let Ok(shader) = compiled {
                    let mut batch = shader.batch(4);
                    shader.shade_with(&mut batch, &mut rtsl_compiler::interp::TestHost::default());
                }
            }
        }
    }
}

/// An array within `MAX_ARRAY_LEN` whose floats take the shader past `ir::STORAGE_BUDGET` is
/// refused by the validator, naming the variable, as the checker refuses it in source; the JIT and
/// the interpreter refuse such a module too, rather than running out of memory.
#[test]
fn a_forged_array_past_the_storage_budget_is_refused_by_name() {
    let dir = tempfile::tempdir().expect("tempdir");
    let shader = dir.path().join("wide.sl");
    std::fs::write(&shader, "surface wide() { float ramp[3]; ramp[1] = s; Ci = ramp[floor(t * 3)]; }\n")
        .expect("write");
    let (path, bytes) = compiled_artifact(&shader, &Options::default());
    let a = artifact::decode(&path, &bytes).expect("the real artifact decodes");
    let mut forged = a.module.clone();
    visit_slots(&mut forged, &mut |slot| {
        if let Slot::ArrayLen(n) = slot {
            *n = ir::MAX_ARRAY_LEN;
        }
    });
    match artifact::decode(&path, &forge(&bytes, &a, &forged)) {
        Err(ArtifactError::Invalid { detail, .. }) => {
            assert!(detail.contains("`ramp`") && detail.contains(&ir::STORAGE_BUDGET.to_string()), "{detail}")
        }
        Err(e) => panic!("unexpected error {e}"),
        Ok(_) => panic!("an array of {} floats passed validation", ir::MAX_ARRAY_LEN),
    }
    let jit = rtsl_compiler::back::jit::compile(&forged);
    assert!(matches!(jit, Err(rtsl_compiler::back::jit::JitError::OverBudget(_))), "{jit:?}");
    let mut point = rtsl_compiler::interp::ShadingPoint::new(ir::ShaderKind::Surface);
    let mut host = rtsl_compiler::interp::TestHost::default();
    let run = rtsl_compiler::interp::run(&forged, &[], &mut point, &mut host, Default::default());
    assert!(matches!(run, Err(rtsl_compiler::interp::InterpError::OverBudget(_))), "{run:?}");
}

/// The artifact of `surface deep() { if (s > 0.5) { Ci = 1; } }` forged with its `if` inside
/// `blocks - 2` more (the shader's body is a block too), each with a condition of its own. Built,
/// encoded and dropped on a thread with a large stack: the IR's derived code recurses.
fn nested_artifact(blocks: u32) -> (tempfile::TempDir, PathBuf, Vec<u8>) {
    let dir = tempfile::tempdir().expect("tempdir");
    let shader = dir.path().join("deep.sl");
    std::fs::write(&shader, "surface deep() { if (s > 0.5) { Ci = 1; } }\n").expect("write");
    let (path, bytes) = compiled_artifact(&shader, &Options::default());
    let forged = std::thread::Builder::new()
        .stack_size(1 << 30)
        .spawn(move || {
            let a = artifact::decode(&path, &bytes).expect("the real artifact decodes");
            let mut m = a.module.clone();
            let body = m.shader.as_ref().expect("a shader").body.0 as usize;
            let f = &mut m.functions[body];
            let mut stmt = f.body.stmts.remove(0);
            let ir::StmtKind::If { cond, .. } = stmt.kind else { panic!("the body starts with its `if`") };
            let span = stmt.span;
            for _ in 2..blocks {
                // `s > 0.5` again: every expression is used once.
                let mut copy = f.exprs[cond.0 as usize].clone();
                if let ir::ExprKind::Binary { lhs, rhs, .. } = &mut copy.kind {
                    for side in [lhs, rhs] {
                        let operand = f.exprs[side.0 as usize].clone();
                        f.exprs.push(operand);
                        *side = ir::ExprId(f.exprs.len() as u32 - 1);
                    }
                }
                f.exprs.push(copy);
                let cond = ir::ExprId(f.exprs.len() as u32 - 1);
                let then = ir::Block { stmts: vec![stmt] };
                stmt = ir::Stmt { kind: ir::StmtKind::If { cond, then, otherwise: ir::Block::default() }, span };
            }
            f.body.stmts.insert(0, stmt);
            (path.clone(), forge(&bytes, &a, &m))
        })
        .expect("a thread")
        .join()
        .expect("forged");
    (dir, forged.0, forged.1)
}

/// A forged artifact whose statements nest 20,000 levels deep is refused as it is decoded, naming
/// the limit, instead of overflowing the stack of the thread that loads it.
#[test]
fn statements_nested_past_the_limit_are_refused_as_they_are_decoded() {
    for blocks in [ir::MAX_DECODED_NESTING + 1, 20_000] {
        let (_dir, path, forged) = nested_artifact(blocks);
        match artifact::decode(&path, &forged) {
            Err(ArtifactError::Undecodable { detail, .. }) => {
                let limit = format!("nest more than {} levels deep", ir::MAX_DECODED_NESTING);
                assert!(detail.contains(&limit), "{blocks} blocks: {detail}");
            }
            Err(e) => panic!("{blocks} blocks: unexpected error {e}"),
            Ok(_) => panic!("{blocks} blocks decoded"),
        }
    }
}

/// At the limit an artifact decodes and validates, and both back ends run it (on a large stack:
/// they recurse over blocks, and an unoptimised build takes kilobytes a level).
#[test]
fn statements_nested_to_the_limit_decode_and_run() {
    let (_dir, path, forged) = nested_artifact(ir::MAX_DECODED_NESTING);
    let a = artifact::decode(&path, &forged).expect("nested to the limit");
    std::thread::Builder::new()
        .stack_size(256 << 20)
        .spawn(move || {
            let m = &a.module;
            let shader = rtsl_compiler::back::jit::compile(m).expect("compiles");
            let mut batch = shader.batch(4);
            batch.set_global("s", 0, &[1.0]);
            shader.shade(&mut batch);
            assert_eq!(batch.global("Ci", 0), Some(vec![1.0; 3]));
            assert_eq!(batch.global("Ci", 1), Some(vec![0.0; 3]));
            let mut point = rtsl_compiler::interp::ShadingPoint::new(ir::ShaderKind::Surface);
            point.set("s", rtsl_compiler::interp::Value::Float(1.0));
            let mut host = rtsl_compiler::interp::TestHost::default();
            rtsl_compiler::interp::run(m, &[], &mut point, &mut host, Default::default()).expect("runs");
            assert_eq!(point.get("Ci"), Some(&rtsl_compiler::interp::Value::Triple([1.0; 3])));
        })
        .expect("a thread")
        .join()
        .expect("both back ends ran the shader");
}

/// `reframe` writes what a forger changing the payload would: a damaged payload, refused for its
/// checksum, then decodes as far as its bytes allow, and an intact artifact stays byte for byte
/// the same. Every byte of the payload flipped in turn must then decode or be refused, never
/// crash, and what decodes must compile.
#[test]
fn reframed_artifacts_reach_the_validator_and_never_crash() {
    let (dir, shader, _) = shader_with_header("color(1, 0.5, 0)");
    let (_, bytes) = compiled_artifact(&shader, &Options::default());
    assert_eq!(artifact::reframe(&bytes).as_deref(), Some(&bytes[..]), "an intact artifact is unchanged");
    assert_eq!(artifact::reframe(b"not an artifact"), None);
    let mut decoded = 0;
    let mut refused_for_checksum = 0;
    let tail = bytes.len().min(600);
    for k in bytes.len() - tail..bytes.len() {
        let mut damaged = bytes.clone();
        damaged[k] ^= 0x5a;
        if matches!(artifact::decode(&shader, &damaged), Err(ArtifactError::Corrupt { .. })) {
            refused_for_checksum += 1;
        }
        let Some(forged) = artifact::reframe(&damaged) else { continue };
        if let Ok(a) = artifact::decode(&shader, &forged) {
            decoded += 1;
            let _ = rtsl_compiler::back::jit::compile(&a.module);
        }
    }
    assert!(refused_for_checksum > tail / 2, "{refused_for_checksum} of {tail} damaged artifacts refused");
    assert!(decoded > 0, "some forged payloads decode");
    drop(dir);
}
