//! The runtime's modules import each other without cycles: the stages of a frame, the RIB
//! reader's builders and the rest form a graph that can be read from the bottom up.
//!
//! A module is a file of `runtime/src`; it depends on another when its code (not its comments)
//! names a path into it (`crate::a::b`, `super::x`, `use super::{x, y}`). A module's references to
//! its own ancestors (a file using what its parent module declares) are not counted.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

fn modules(dir: &Path, root: &Path, out: &mut BTreeMap<String, String>) {
    let mut entries: Vec<_> = std::fs::read_dir(dir).expect("a source directory").flatten().collect();
    entries.sort_by_key(|e| e.path());
    for e in entries {
        let path = e.path();
        if path.is_dir() {
            modules(&path, root, out);
        } else if path.extension().is_some_and(|x| x == "rs") {
            let relative = path.strip_prefix(root).expect("under the root").with_extension("");
            let mut parts: Vec<String> = relative.iter().map(|p| p.to_string_lossy().into_owned()).collect();
            if parts.last().is_some_and(|p| p == "mod" || p == "lib") {
                parts.pop();
            }
            let text = std::fs::read_to_string(&path).expect("a source file");
            out.insert(parts.join("::"), code_only(&text));
        }
    }
}

/// The text without comments (line comments, doc comments, block comments) and without the unit
/// tests at the end of a file.
fn code_only(text: &str) -> String {
    let text = text.split("#[cfg(test)]\nmod tests").next().unwrap_or(text);
    let mut out = String::with_capacity(text.len());
    let mut in_block = false;
    for line in text.lines() {
        let mut rest = line;
        if in_block {
            match rest.find("*/") {
                Some(end) => {
                    in_block = false;
                    rest = &rest[end + 2..];
                }
                None => continue,
            }
        }
        if let Some(start) = rest.find("/*") {
            in_block = !rest[start..].contains("*/");
            rest = &rest[..start];
        }
        let code = match rest.find("//") {
            Some(at) => &rest[..at],
            None => rest,
        };
        out.push_str(code);
        out.push('\n');
    }
    out
}

/// The module a path from module `from` leads into: the longest prefix that is a module.
fn resolve(from: &str, path: &[&str], known: &BTreeMap<String, String>) -> Option<String> {
    let mut base: Vec<&str> = if from.is_empty() { Vec::new() } else { from.split("::").collect() };
    let mut rest = path;
    match rest.first() {
        Some(&"crate") => {
            base.clear();
            rest = &rest[1..];
        }
        Some(&"super") | Some(&"self") => {
            while let Some(&head) = rest.first() {
                match head {
                    "super" => {
                        base.pop();
                    }
                    "self" => {}
                    _ => break,
                }
                rest = &rest[1..];
            }
        }
        _ => return None,
    }
    (0..=rest.len()).rev().find_map(|k| {
        let candidate: Vec<&str> = base.iter().copied().chain(rest[..k].iter().copied()).collect();
        let name = candidate.join("::");
        known.contains_key(&name).then_some(name)
    })
}

fn is_ident(c: char) -> bool {
    c.is_alphanumeric() || c == '_'
}

/// The paths a module's code names: `crate::`, `super::`, `self::` and `rtsl_compiler::` paths,
/// with `use` groups expanded one level.
fn paths(code: &str) -> Vec<Vec<String>> {
    let mut out = Vec::new();
    let chars: Vec<char> = code.chars().collect();
    let mut i = 0;
    while i < chars.len() {
        let starts_word = i == 0 || !is_ident(chars[i - 1]) && chars[i - 1] != ':';
        let word: String = chars[i..].iter().take_while(|&&c| is_ident(c)).collect();
        if starts_word && matches!(word.as_str(), "crate" | "super" | "self" | "rtsl_compiler") {
            let mut parts = vec![word.clone()];
            let mut j = i + word.len();
            loop {
                if chars.get(j) == Some(&':') && chars.get(j + 1) == Some(&':') {
                    j += 2;
                    if chars.get(j) == Some(&'{') {
                        let end = chars[j..].iter().position(|&c| c == '}').map_or(chars.len(), |e| j + e);
                        let group: String = chars[j + 1..end].iter().collect();
                        for item in group.split(',') {
                            let first = item.trim().split("::").next().unwrap_or("").trim();
                            let first: String = first.chars().take_while(|&c| is_ident(c)).collect();
                            if !first.is_empty() && first != "self" {
                                let mut p = parts.clone();
                                p.push(first);
                                out.push(p);
                            }
                        }
                        j = end;
                        break;
                    }
                    let next: String = chars[j..].iter().take_while(|&&c| is_ident(c)).collect();
                    if next.is_empty() {
                        break;
                    }
                    j += next.len();
                    parts.push(next);
                } else {
                    break;
                }
            }
            out.push(parts);
            i = j.max(i + 1);
        } else {
            i += word.len().max(1);
        }
    }
    out
}

/// Strongly connected components of more than one module (Tarjan's algorithm, iterative).
fn cycles(graph: &BTreeMap<String, BTreeSet<String>>) -> Vec<Vec<String>> {
    let names: Vec<&String> = graph.keys().collect();
    let index_of: BTreeMap<&String, usize> = names.iter().enumerate().map(|(i, n)| (*n, i)).collect();
    let n = names.len();
    let edges: Vec<Vec<usize>> = names.iter().map(|m| graph[*m].iter().map(|t| index_of[t]).collect()).collect();
    let (mut index, mut low, mut on_stack) = (vec![usize::MAX; n], vec![0; n], vec![false; n]);
    let (mut stack, mut out, mut next) = (Vec::new(), Vec::new(), 0);
    for root in 0..n {
        if index[root] != usize::MAX {
            continue;
        }
        let mut work = vec![(root, 0usize)];
        while let Some((v, edge)) = work.pop() {
            if edge == 0 {
                index[v] = next;
                low[v] = next;
                next += 1;
                stack.push(v);
                on_stack[v] = true;
            }
            if let Some(&w) = edges[v].get(edge) {
                work.push((v, edge + 1));
                if index[w] == usize::MAX {
                    work.push((w, 0));
                } else if on_stack[w] {
                    low[v] = low[v].min(index[w]);
                }
                continue;
            }
            if low[v] == index[v] {
                let mut component = Vec::new();
                while let Some(w) = stack.pop() {
                    on_stack[w] = false;
                    component.push(names[w].clone());
                    if w == v {
                        break;
                    }
                }
                if component.len() > 1 {
                    component.sort();
                    out.push(component);
                }
            }
            if let Some(&(parent, _)) = work.last() {
                low[parent] = low[parent].min(low[v]);
            }
        }
    }
    out.sort();
    out
}

fn module_graph() -> BTreeMap<String, BTreeSet<String>> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut sources = BTreeMap::new();
    modules(&root, &root, &mut sources);
    let mut graph: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for (module, code) in &sources {
        let targets = graph.entry(module.clone()).or_default();
        for path in paths(code) {
            let parts: Vec<&str> = path.iter().map(String::as_str).collect();
            let Some(target) = resolve(module, &parts, &sources) else { continue };
            let ancestor = target.is_empty() || module.starts_with(&format!("{target}::"));
            if &target != module && !ancestor {
                targets.insert(target);
            }
        }
    }
    graph
}

#[test]
fn the_runtime_has_no_import_cycles() {
    let graph = module_graph();
    assert!(graph.len() > 50, "the module graph was not read: {} modules", graph.len());
    // The reader sees the edges it must: a module that imports a sibling.
    assert!(graph["distributed::worker"].contains("distributed::fetch"), "{:?}", graph["distributed::worker"]);
    let found: Vec<String> = cycles(&graph).iter().map(|c| c.join(" <-> ")).collect();
    assert!(found.is_empty(), "import cycles: {found:#?}");
}

#[test]
fn cycles_are_found() {
    let edge = |a: &str, b: &str| (a.to_string(), b.to_string());
    let mut graph: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for (a, b) in [edge("a", "b"), edge("b", "c"), edge("c", "a"), edge("c", "d"), edge("d", "e")] {
        graph.entry(a).or_default().insert(b.clone());
        graph.entry(b).or_default();
    }
    assert_eq!(cycles(&graph), vec![vec!["a".to_string(), "b".to_string(), "c".to_string()]]);
    let code =
        "use super::{fetch::FetchLink, message::Message};\nlet x = crate::api::Context::new(); // crate::nothing";
    let found = paths(&code_only(code));
    assert!(found.contains(&vec!["super".to_string(), "fetch".to_string()]), "{found:?}");
    assert!(found.iter().any(|p| p.join("::") == "crate::api::Context::new"), "{found:?}");
    assert!(!found.iter().any(|p| p.join("::").contains("nothing")), "{found:?}");
    let compiler = paths("use rtsl_compiler::{jit::Layout, ir};");
    assert!(compiler.contains(&vec!["rtsl_compiler".to_string(), "ir".to_string()]), "{compiler:?}");
}

/// The runtime and the command line reach the compiler through its public API only (the compile
/// API, the interface, artifacts, `jit` and `abi`): the front end, IR, validator and back ends are
/// internals. Tests of the workspace build the compiler with its `internals` feature (its own tests
/// need them), so the compiler's privacy alone would not catch a runtime naming them.
#[test]
fn the_compilers_internals_stay_inside_it() {
    let workspace = Path::new(env!("CARGO_MANIFEST_DIR")).parent().expect("the workspace root").to_path_buf();
    let mut offenders = Vec::new();
    for dir in [workspace.join("runtime/src"), workspace.join("src")] {
        let mut sources = BTreeMap::new();
        modules(&dir, &dir, &mut sources);
        assert!(!sources.is_empty(), "no sources under {}", dir.display());
        for (module, code) in &sources {
            for path in paths(code) {
                let internal = path.len() > 1
                    && path[0] == "rtsl_compiler"
                    && ["front", "back", "ir", "valid"].contains(&path[1].as_str());
                if internal {
                    offenders.push(format!("{} {module}: {}", dir.display(), path.join("::")));
                }
            }
        }
    }
    assert!(offenders.is_empty(), "compiler internals named outside the compiler: {offenders:#?}");
}
