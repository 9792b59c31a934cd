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
