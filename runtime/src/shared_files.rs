//! What was made of files (a texture's pyramid, a shadow map, a grid, a model file's meshes),
//! shared by the contexts of one run: the frames of a render each have a context, and so a texture
//! cache, of their own, and a file one frame read and decoded is reused by the next instead of
//! being read again.
//!
//! Invariants:
//! - what was made of a file is reused only while the file, and every other file the making read
//!   (an OBJ file's material library), has the `FileStamp` it had when it was read (length,
//!   modification time, and on Unix inode and change time), and until the renderer writes the
//!   file itself ([`SharedFiles::forget`]): a shadow map a later pass writes over is read again;
//! - what the store keeps is bounded by what the frames use: [`SharedFiles::end_frame`] lets go
//!   of everything the frame that ended did not ask for.

use crate::file_stamp::FileStamp;
use std::any::Any;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, PoisonError};

/// What was made of files, by path and kind (see the module doc), for
/// [`crate::api::Context::share_files`].
#[derive(Default)]
pub struct SharedFiles {
    state: Mutex<State>,
}

#[derive(Default)]
struct State {
    entries: HashMap<(PathBuf, &'static str), Entry>,
    /// Frames ended so far.
    frame: u64,
}

struct Entry {
    stamp: FileStamp,
    /// The other files the making read, as they were then.
    others: Vec<(PathBuf, Option<FileStamp>)>,
    value: Arc<dyn Any + Send + Sync>,
    /// The frame that last asked for it.
    used: u64,
}

/// The path a file is known by: its canonical path, where it has one.
fn canonical(path: &Path) -> PathBuf {
    std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf())
}

impl SharedFiles {
    pub fn new() -> SharedFiles {
        SharedFiles::default()
    }

    fn state(&self) -> std::sync::MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// File `path` decoded as `variant` (a texture, raw or not, a shadow map, a grid): from the
    /// store while the file is unchanged, else by `load` (outside the store's lock, so that other
    /// files load meanwhile), kept when it succeeds.
    pub(crate) fn get_or_load<T: Any + Send + Sync, E>(
        &self,
        path: &Path,
        variant: &'static str,
        load: impl FnOnce() -> Result<T, E>,
    ) -> Result<Arc<T>, E> {
        self.get_or_load_reading(path, variant, || load().map(|value| (value, Vec::new())))
    }

    /// [`SharedFiles::get_or_load`] of a making that reads other files besides `path` (an OBJ
    /// file's material library): `load` also says which, and they are stamped too.
    pub(crate) fn get_or_load_reading<T: Any + Send + Sync, E>(
        &self,
        path: &Path,
        variant: &'static str,
        load: impl FnOnce() -> Result<(T, Vec<PathBuf>), E>,
    ) -> Result<Arc<T>, E> {
        let Some(stamp) = FileStamp::of(path) else { return load().map(|(value, _)| Arc::new(value)) };
        let key = (canonical(path), variant);
        {
            let mut state = self.state();
            let frame = state.frame;
            let unchanged =
                |e: &Entry| e.stamp == stamp && e.others.iter().all(|(other, was)| FileStamp::of(other) == *was);
            if let Some(entry) = state.entries.get_mut(&key).filter(|e| unchanged(e)) {
                if let Ok(value) = entry.value.clone().downcast::<T>() {
                    entry.used = frame;
                    return Ok(value);
                }
            }
        }
        // Stamped before it is read: a file changed while it loads is read again next time (the
        // other files, known only once read, are stamped then).
        let (value, others) = load()?;
        let stamped = |other: PathBuf| {
            let was = FileStamp::of(&other);
            (other, was)
        };
        let others = others.into_iter().map(stamped).collect();
        let value = Arc::new(value);
        let mut state = self.state();
        let used = state.frame;
        state.entries.insert(key, Entry { stamp, others, value: value.clone(), used });
        Ok(value)
    }

    /// Forgets what was made of file `path`: the renderer is writing it (`MakeShadow`,
    /// `MakeTexture`).
    pub fn forget(&self, path: &Path) {
        let path = canonical(path);
        self.state().entries.retain(|(p, _), _| *p != path);
    }

    /// A frame ended: what it did not ask for is let go (it stays with the caches that hold it).
    pub fn end_frame(&self) {
        let mut state = self.state();
        let ended = state.frame;
        state.entries.retain(|_, e| e.used == ended);
        state.frame += 1;
    }

    /// How many things made of files it holds.
    pub fn len(&self) -> usize {
        self.state().entries.len()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::image_io::{write_image, WriteOptions};
    use crate::texture::TextureCache;

    /// Caches sharing a store decode a file once between them, again once it changes or the
    /// renderer writes it, and the store keeps only what the last frame asked for.
    #[test]
    fn caches_sharing_a_store_decode_a_file_once_until_it_changes() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("t.exr");
        let write = |grey: f32, size: usize| {
            let pixels = vec![grey; size * size * 4];
            write_image(&path, size, size, &pixels, &WriteOptions::default()).expect("a texture");
        };
        write(0.25, 4);
        let shared = Arc::new(SharedFiles::new());
        let cache = || TextureCache::with_search_paths([dir.path().to_path_buf()]).with_shared(Some(shared.clone()));
        let texture = |raw: bool| cache().get_texture("t.exr", raw).expect("the texture loads");
        let first = texture(false);
        assert!(Arc::ptr_eq(&first, &texture(false)), "decoded again by another cache");
        assert!(!Arc::ptr_eq(&first, &texture(true)), "raw and not are decoded apart");
        assert_eq!(shared.len(), 2);
        write(0.75, 8);
        let rewritten = texture(false);
        assert!(!Arc::ptr_eq(&first, &rewritten));
        assert_eq!(rewritten.width(), 8);
        shared.forget(&path);
        assert!(shared.is_empty());
        let again = texture(false);
        assert!(!Arc::ptr_eq(&rewritten, &again), "read again after the renderer wrote it");
        // A frame that used it keeps it for the next; a frame that did not lets it go.
        shared.end_frame();
        assert!(Arc::ptr_eq(&again, &texture(false)));
        shared.end_frame();
        assert_eq!(shared.len(), 1);
        shared.end_frame();
        assert!(shared.is_empty());
        // Missing files are not kept.
        assert!(cache().get_texture("missing.exr", false).is_none());
        assert!(shared.is_empty());
    }
}
