//! Compiled shaders shared by contexts: the frames of one render are loaded each into a context of
//! its own, and a shader they find by name is compiled once for all of them; a distributed
//! render's worker starts a context for each scene the master sends, and a program that comes as
//! the same artifact is compiled once for all of them.
//!
//! Invariants:
//! - a program found by name is taken from the cache only while every file its compilation read
//!   (the source and its includes, `ShaderProgram::files`) has the stamp it had when the program
//!   was compiled (`FileStamp`: length, modification time, and on Unix inode and change time), and only for the same include paths; a library
//!   shader's source is part of the binary and never changes;
//! - a program made from an artifact is taken for the same artifact, byte for byte;
//! - artifacts no context asked for between two [`ShaderCache::end_scene`]s are let go.

use super::{Program, ShaderLocation};
use crate::file_stamp::FileStamp;
use std::collections::HashMap;
use std::path::PathBuf;
use std::sync::Mutex;

/// Compiled shaders by where they were found, for [`super::Context::share_shader_cache`].
#[derive(Default)]
pub struct ShaderCache {
    programs: Mutex<HashMap<Key, Entry>>,
    artifacts: Mutex<Artifacts>,
}

/// Programs by the artifact they were made from, with the scene that last asked for each.
#[derive(Default)]
struct Artifacts {
    programs: HashMap<Vec<u8>, (Program, u64)>,
    scene: u64,
}

/// Where a program was compiled from, and with which include paths.
#[derive(Clone, PartialEq, Eq, Hash)]
struct Key {
    /// The source file, or the library shader's path in the library.
    source: Source,
    include_paths: Vec<PathBuf>,
}

#[derive(Clone, PartialEq, Eq, Hash)]
enum Source {
    File(PathBuf),
    Library(&'static str),
}

struct Entry {
    program: Program,
    /// Every file the compilation read, as it was then.
    files: Vec<(PathBuf, Option<FileStamp>)>,
}

fn key(location: &ShaderLocation, include_paths: &[PathBuf]) -> Key {
    let source = match location {
        ShaderLocation::File(path) => Source::File(path.clone()),
        ShaderLocation::Library(shader) => Source::Library(shader.path),
    };
    Key { source, include_paths: include_paths.to_vec() }
}

impl ShaderCache {
    pub fn new() -> ShaderCache {
        ShaderCache::default()
    }

    /// The program compiled from `location` with `include_paths`, if its files are unchanged.
    pub(super) fn get(&self, location: &ShaderLocation, include_paths: &[PathBuf]) -> Option<Program> {
        let programs = self.programs.lock().unwrap_or_else(|e| e.into_inner());
        let entry = programs.get(&key(location, include_paths))?;
        entry.files.iter().all(|(path, was)| FileStamp::of(path) == *was).then(|| entry.program.clone())
    }

    /// Keeps `program`, compiled from `location` with `include_paths`, with its files as they are
    /// now. Files stamped after the compilation read them make the entry miss at worst (a file
    /// changed in between is compiled again next time).
    pub(super) fn insert(&self, location: &ShaderLocation, include_paths: &[PathBuf], program: &Program) {
        let own = match location {
            ShaderLocation::File(path) if !program.files.contains(path) => Some(path),
            _ => None,
        };
        let files = program.files.iter().chain(own).map(|path| (path.clone(), FileStamp::of(path))).collect();
        let entry = Entry { program: program.clone(), files };
        let mut programs = self.programs.lock().unwrap_or_else(|e| e.into_inner());
        programs.insert(key(location, include_paths), entry);
    }

    /// The program made from artifact `bytes`, if one was.
    pub(super) fn artifact(&self, bytes: &[u8]) -> Option<Program> {
        let mut artifacts = self.artifacts.lock().unwrap_or_else(|e| e.into_inner());
        let scene = artifacts.scene;
        let (program, used) = artifacts.programs.get_mut(bytes)?;
        *used = scene;
        Some(program.clone())
    }

    /// Keeps `program`, made from artifact `bytes`.
    pub(super) fn insert_artifact(&self, bytes: &[u8], program: &Program) {
        let mut artifacts = self.artifacts.lock().unwrap_or_else(|e| e.into_inner());
        let scene = artifacts.scene;
        artifacts.programs.insert(bytes.to_vec(), (program.clone(), scene));
    }

    /// A scene ended: the programs made from artifacts that it did not ask for are let go.
    pub fn end_scene(&self) {
        let mut artifacts = self.artifacts.lock().unwrap_or_else(|e| e.into_inner());
        let ended = artifacts.scene;
        artifacts.programs.retain(|_, (_, used)| *used == ended);
        artifacts.scene += 1;
    }

    /// How many programs it holds (found by name, and made from artifacts).
    pub fn len(&self) -> usize {
        let by_name = self.programs.lock().unwrap_or_else(|e| e.into_inner()).len();
        by_name + self.artifacts.lock().unwrap_or_else(|e| e.into_inner()).programs.len()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::api::Context;
    use std::sync::Arc;

    /// Contexts sharing a cache compile a shader found by name once, library and file alike, and
    /// again once its file or an include it read changes.
    #[test]
    fn shared_contexts_compile_a_shader_once_until_its_files_change() {
        let dir = tempfile::tempdir().expect("tempdir");
        let include = dir.path().join("inc");
        std::fs::create_dir(&include).expect("mkdir");
        std::fs::write(include.join("k.h"), "#define K 0.5\n").expect("write");
        std::fs::write(dir.path().join("tint.sl"), "#include \"k.h\"\nsurface tint() { Ci = K; }\n").expect("write");
        let cache = Arc::new(ShaderCache::new());
        let context = || {
            let mut rt = Context::new();
            rt.set_shader_search_path([dir.path()]);
            rt.set_include_paths([&include]);
            rt.share_shader_cache(cache.clone());
            rt
        };
        let found = |rt: &mut Context, name: &str| {
            let id = rt.find_shader(name).expect("the shader compiles");
            rt.program(id).expect("a program").clone()
        };
        let (mut a, mut b) = (context(), context());
        for name in ["tint", "plastic"] {
            assert!(Arc::ptr_eq(&found(&mut a, name), &found(&mut b, name)), "{name} compiled twice");
        }
        assert_eq!(cache.len(), 2);
        let before = found(&mut context(), "tint");
        // A longer include: the program is compiled again, and kept in its place.
        std::fs::write(include.join("k.h"), "#define K 0.25 \n").expect("write");
        let after = found(&mut context(), "tint");
        assert!(!Arc::ptr_eq(&before, &after), "compiled again after its include changed");
        assert!(Arc::ptr_eq(&after, &found(&mut context(), "tint")));
        // Another include path is another program.
        let mut other = Context::new();
        other.set_shader_search_path([dir.path()]);
        other.share_shader_cache(cache.clone());
        assert!(other.find_shader("tint").is_err(), "k.h is not on its include path");
        assert_eq!(cache.len(), 2);
    }

    /// Contexts that share a cache make a program from an artifact once (a worker's scenes, each
    /// in a context of its own), and the cache lets go of artifacts a scene did not use.
    #[test]
    fn replicas_sharing_a_cache_make_a_program_from_an_artifact_once() {
        let mut master = Context::new();
        master.find_shader("plastic").expect("the library's plastic");
        let update = crate::api::Replicator::new().update(&master, None).expect("an update");
        let cache = Arc::new(ShaderCache::new());
        let replica = || {
            let mut rt = Context::new();
            rt.share_shader_cache(cache.clone());
            rt.apply_update(&update).expect("the update applies");
            rt.programs_by_id().into_iter().map(|(_, p)| p).collect::<Vec<_>>()
        };
        let (first, second) = (replica(), replica());
        assert_eq!(first.len(), 1);
        assert!(Arc::ptr_eq(&first[0], &second[0]), "made twice from one artifact");
        assert_eq!(cache.len(), 1);
        // A scene that used it keeps it for the next; a scene that did not lets it go.
        cache.end_scene();
        assert!(Arc::ptr_eq(&first[0], &replica()[0]));
        cache.end_scene();
        assert_eq!(cache.len(), 1);
        cache.end_scene();
        assert!(cache.is_empty());
        assert!(!Arc::ptr_eq(&first[0], &replica()[0]), "made again once let go");
    }
}
