//! `docs/limits.md` lists every limit rtsl puts on what its input can make it do. A limit is added
//! as a `MAX_` constant or a `_BUDGET` constant far more often than the page is reread, so this test
//! reads the sources: each such constant must be named on the page by its path (crate, modules,
//! the type for an associated constant, name) or be in [`INTERNAL`] with the reason it bounds no
//! input. And each constant path the page names must still be declared where it says, so a rename
//! or a move cannot leave the page pointing at nothing.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

/// Constants that bound rtsl's own work rather than its input, each with why.
const INTERNAL: &[(&str, &str)] = &[
    ("rtsl_runtime::accel::bvh4::MAX_LEAF_SIZE", "primitives per BVH leaf: a build parameter"),
    ("rtsl::bench::trace::MAX_WARMUP_BUILDS", "untimed builds before a benchmark times its own"),
    ("rtsl_runtime::render::group::MAX_BUCKETED_KEYS", "when grouping by shader sorts instead of bucketing"),
    ("rtsl_runtime::render::primary::MAX_PACKETS_PER_CALL", "packets per camera-shader batch: a batching size"),
    ("rtsl_runtime::texture::mip::MAX_LANE_VALUES", "values a lookup returns per lane: the shading ABI's width"),
    (
        "rtsl_compiler::back::jit::host::MAX_TEXTURE_CHANNELS",
        "channels of the widest lookup result type (colour and alpha)",
    ),
    ("rtsl_compiler::back::jit::lower::RUNTIME_LOOP_BUDGET", "the code of the loop-budget runtime error, not a count"),
    ("rtsl::cli::view::renderer::MOVING_BUDGET", "the viewer's frame time while the view moves: a preview target"),
    (
        "rtsl_runtime::distributed::worker::MAX_SET_ASIDE",
        "times a worker renders a tile again for what it asked ahead for before it waits instead",
    ),
];

/// The source trees scanned, with the crate each is.
const TREES: &[(&str, &str)] = &[("runtime/src", "rtsl_runtime"), ("compiler/src", "rtsl_compiler"), ("src", "rtsl")];

/// A `const` declared in the sources.
struct Declared {
    /// `crate::module::path`, without the constant.
    module: String,
    name: String,
    /// `file:line`, for messages.
    at: String,
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<PathBuf> =
        std::fs::read_dir(dir).expect("a source directory").map(|e| e.expect("a directory entry").path()).collect();
    entries.sort();
    for path in entries {
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// `rtsl_runtime::render::world` for `runtime/src/render/world.rs`; `mod.rs`, `lib.rs` and
/// `main.rs` are their folder's module.
fn module_of(krate: &str, root: &Path, file: &Path) -> String {
    let relative = file.strip_prefix(root).expect("under its tree").with_extension("");
    let mut parts: Vec<String> = relative.iter().map(|p| p.to_string_lossy().into_owned()).collect();
    if parts.last().is_some_and(|p| p == "mod" || (parts.len() == 1 && (p == "lib" || p == "main"))) {
        parts.pop();
    }
    std::iter::once(krate.to_string()).chain(parts).collect::<Vec<_>>().join("::")
}

/// The name of the constant a line declares, if it declares one (`pub(crate) const NAME: T = ...`).
fn declared_name(line: &str) -> Option<&str> {
    let mut rest = line.trim_start();
    if let Some(after) = rest.strip_prefix("pub") {
        rest = match after.strip_prefix('(') {
            Some(scoped) => scoped.split_once(')')?.1,
            None => after,
        }
        .trim_start();
    }
    let rest = rest.strip_prefix("const ")?;
    let name = rest.split(':').next()?.trim();
    (!name.is_empty() && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')).then_some(name)
}

fn declarations() -> Vec<Declared> {
    let base = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut out = Vec::new();
    for (tree, krate) in TREES {
        let root = base.join(tree);
        let mut files = Vec::new();
        rust_files(&root, &mut files);
        for file in files {
            let text = std::fs::read_to_string(&file).expect("a readable source file");
            let module = module_of(krate, &root, &file);
            for (i, line) in text.lines().enumerate() {
                if let Some(name) = declared_name(line) {
                    let at = format!("{}:{}", file.strip_prefix(base).unwrap_or(&file).display(), i + 1);
                    out.push(Declared { module: module.clone(), name: name.to_string(), at });
                }
            }
        }
    }
    out
}

/// Whether the constant is a limit the page must list.
fn is_limit(name: &str) -> bool {
    name.starts_with("MAX_") || name.ends_with("_BUDGET")
}

/// Everything the page writes as code (between backticks).
fn code_spans(doc: &str) -> BTreeSet<String> {
    doc.split('`').skip(1).step_by(2).map(str::to_string).collect()
}

/// Whether `span` names the constant: `module::NAME`, or `module::Type::NAME` for an associated one.
fn names(span: &str, d: &Declared) -> bool {
    let Some(middle) = span.strip_prefix(&format!("{}::", d.module)).and_then(|s| s.strip_suffix(&d.name)) else {
        return false;
    };
    middle.is_empty()
        || middle.strip_suffix("::").is_some_and(|ty| {
            ty.starts_with(|c: char| c.is_ascii_uppercase()) && ty.chars().all(|c| c.is_ascii_alphanumeric())
        })
}

/// A span that looks like a path to a constant: a crate of ours, then modules, then an upper-case name.
fn is_constant_path(span: &str) -> bool {
    let krate = span.split("::").next().unwrap_or_default();
    let last = span.rsplit("::").next().unwrap_or_default();
    span.contains("::")
        && TREES.iter().any(|(_, k)| *k == krate)
        && last.chars().any(|c| c.is_ascii_uppercase())
        && last.chars().all(|c| c.is_ascii_uppercase() || c.is_ascii_digit() || c == '_')
}

#[test]
fn every_limit_constant_is_on_the_limits_page() {
    let doc =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/limits.md")).expect("docs/limits.md");
    let spans = code_spans(&doc);
    let declared = declarations();

    let mut missing = Vec::new();
    for d in declared.iter().filter(|d| is_limit(&d.name)) {
        let internal = INTERNAL.iter().any(|(path, _)| names(path, d));
        if !internal && !spans.iter().any(|s| names(s, d)) {
            missing.push(format!("  {}::{} ({})", d.module, d.name, d.at));
        }
    }
    assert!(
        missing.is_empty(),
        "constants that look like limits on input but are not in docs/limits.md:\n{}\n\
         add a row naming each (its path, value and what happens past it), or, if it bounds no input, \
         add it to INTERNAL in tests/docs_limits.rs with the reason",
        missing.join("\n")
    );

    let gone: Vec<&str> = spans
        .iter()
        .map(String::as_str)
        .filter(|s| is_constant_path(s))
        .chain(INTERNAL.iter().map(|(path, _)| *path))
        .filter(|s| !declared.iter().any(|d| names(s, d)))
        .collect();
    assert!(gone.is_empty(), "docs/limits.md or INTERNAL names constants that are not declared there: {gone:?}");
}

#[test]
fn module_paths_follow_the_files() {
    let root = Path::new("runtime/src");
    assert_eq!(
        module_of("rtsl_runtime", root, Path::new("runtime/src/render/world.rs")),
        "rtsl_runtime::render::world"
    );
    assert_eq!(module_of("rtsl_runtime", root, Path::new("runtime/src/rib/mod.rs")), "rtsl_runtime::rib");
    assert_eq!(module_of("rtsl", Path::new("src"), Path::new("src/main.rs")), "rtsl");
    assert_eq!(declared_name("    pub(super) const MAX_NOTED_CALLS: usize = 4096;"), Some("MAX_NOTED_CALLS"));
    assert_eq!(declared_name("const fn max_of(a: u32) -> u32 {"), None);
    assert_eq!(declared_name("let x = 1; // const MAX_X: u32"), None);
    let width = Declared { module: "rtsl_runtime::render::filter".into(), name: "MAX_WIDTH".into(), at: String::new() };
    assert!(names("rtsl_runtime::render::filter::PixelFilter::MAX_WIDTH", &width));
    assert!(names("rtsl_runtime::render::filter::MAX_WIDTH", &width));
    assert!(!names("rtsl_runtime::render::MAX_WIDTH", &width));
    assert!(!names("rtsl_runtime::render::filter::film::MAX_WIDTH", &width));
}
