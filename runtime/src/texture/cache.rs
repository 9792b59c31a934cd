//! The texture cache: textures and shadow maps by name, loaded on first use, shared by threads.
//!
//! Each name has a slot (`Arc<OnceLock<..>>`) made under a short write lock; the load then runs
//! inside `OnceLock::get_or_init`, so it happens once while other threads asking for the same
//! name wait for it, and threads asking for other names are not held up. A failed load is
//! cached as `None` with one warning, so later lookups of that name answer at once.
//!
//! Lookups take `&self`. The hot path is a read lock and a hash of the name; an engine that
//! shades a batch with one texture can instead take the [`MipMap`] once with
//! [`TextureCache::get_texture`] and call [`MipMap::filter`] per lane.
//!
//! A cache with a [`TextureSource`] reads no files: the first lookup of a name asks the source
//! (a distributed worker's link to its master, which reads the file and sends its bytes) and
//! decodes what comes back as the file would have been decoded here.

use std::collections::{BTreeSet, HashMap};
use std::fmt;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, OnceLock, PoisonError, RwLock};

use super::environment::latlong_footprint;
use super::grid::Grid;
use super::image::{decode_texture_file, load_texture_image, TexImage};
use super::mip::MipMap;
use super::remote::remote_map;
use super::shadow::ShadowMap;
use super::source::{
    error_chain, image_from_delivered, Delivered, TextureAnswer, TextureKind, TexturePart, TextureSource,
};
use super::{Footprint, LookupOptions, Wrap};
use crate::shared_files::SharedFiles;

type Slot<T> = Arc<OnceLock<Option<Arc<T>>>>;
type Slots<T> = RwLock<HashMap<String, Slot<T>>>;

/// A texture that could not be loaded: the name the shader used, the file it resolved to (if
/// any), and why.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TextureWarning {
    pub name: String,
    pub path: Option<PathBuf>,
    pub reason: String,
}

impl fmt::Display for TextureWarning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.path {
            Some(path) => write!(f, "texture \"{}\" ({}): {}", self.name, path.display(), self.reason),
            None => write!(f, "texture \"{}\": {}", self.name, self.reason),
        }
    }
}

/// What a name's loader is given.
enum Input<'a> {
    File(&'a Path),
    Bytes(&'a Path, &'a [u8]),
}

/// One lane of a batched texture lookup ([`TextureCache::texture_batch`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TextureQuery {
    pub s: f32,
    pub t: f32,
    pub footprint: Footprint,
    pub first_channel: usize,
}

/// What `textureinfo` reports about a texture file.
#[derive(Clone, Debug, PartialEq)]
pub struct TextureInfo {
    pub width: usize,
    pub height: usize,
    pub channels: usize,
    /// `worldToCamera` and `worldToNDC` (RSL's "viewingmatrix" and "projectionmatrix"), when the
    /// file carries them: shadow maps and rendered EXR frames.
    pub projection: Option<[[f32; 16]; 2]>,
}

/// Textures and shadow maps by name (see the module doc). `Send + Sync`.
pub struct TextureCache {
    /// Unique among the caches of this process, and renewed whenever a name comes to stand for
    /// something else (`clear`, `insert_texture`, `insert_grid`): what a texture handle kept
    /// outside the cache ([`TextureCache::generation`]) is valid for.
    generation: AtomicU64,
    search_paths: Vec<PathBuf>,
    /// Colour textures, indexed by [`LookupOptions::raw`]: one file may be used both ways.
    textures: [Slots<MipMap>; 2],
    shadows: Slots<ShadowMap>,
    /// 3-D grids for `texture3d` (`docs/volumes.md`).
    grids: Slots<Grid>,
    warnings: Mutex<Vec<TextureWarning>>,
    /// The files loads have read (or tried to), for watching them.
    files: Mutex<BTreeSet<PathBuf>>,
    /// Where names are fetched from instead of files, if anywhere.
    source: Option<Arc<dyn TextureSource>>,
    /// Files other caches decoded, and this one's for them.
    shared: Option<Arc<SharedFiles>>,
}

impl Default for TextureCache {
    fn default() -> TextureCache {
        TextureCache {
            generation: AtomicU64::new(next_generation()),
            search_paths: Vec::new(),
            textures: Default::default(),
            shadows: Default::default(),
            grids: Default::default(),
            warnings: Default::default(),
            files: Default::default(),
            source: None,
            shared: None,
        }
    }
}

/// A generation no cache has had yet.
fn next_generation() -> u64 {
    static NEXT: AtomicU64 = AtomicU64::new(1);
    NEXT.fetch_add(1, Ordering::Relaxed)
}

impl TextureCache {
    /// What the textures this cache gives out stay valid for: while it reads the same, a name
    /// stands for what it stood for (a caller may keep the handles it got, and skip the cache's
    /// lock and counts). Changes made between frames are seen by the next frame's threads.
    pub fn generation(&self) -> u64 {
        self.generation.load(Ordering::Acquire)
    }

    fn renew_generation(&self) {
        self.generation.store(next_generation(), Ordering::Release);
    }

    /// A cache resolving relative names against the current directory only.
    pub fn new() -> TextureCache {
        TextureCache::default()
    }

    /// A cache resolving relative names against `dirs`, in order, then the current directory.
    pub fn with_search_paths(dirs: impl IntoIterator<Item = PathBuf>) -> TextureCache {
        TextureCache { search_paths: dirs.into_iter().collect(), ..TextureCache::default() }
    }

    /// The same cache fetching what names stand for from `source` instead of reading files.
    pub fn with_source(self, source: Option<Arc<dyn TextureSource>>) -> TextureCache {
        TextureCache { source, ..self }
    }

    /// The same cache taking the files it reads from `shared` while they are unchanged, and
    /// leaving what it decodes there (see [`SharedFiles`]).
    pub fn with_shared(self, shared: Option<Arc<SharedFiles>>) -> TextureCache {
        TextureCache { shared, ..self }
    }

    pub fn search_paths(&self) -> &[PathBuf] {
        &self.search_paths
    }

    /// The file a name stands for: an absolute path as it is; a relative one in the first search
    /// directory that has it, else relative to the current directory. `None` when none exists.
    pub fn resolve(&self, name: &str) -> Option<PathBuf> {
        let name_path = Path::new(name);
        if name_path.is_absolute() {
            return name_path.is_file().then(|| name_path.to_path_buf());
        }
        self.search_paths.iter().map(|dir| dir.join(name_path)).chain([name_path.to_path_buf()]).find(|p| p.is_file())
    }

    /// The texture called `name`, loading it on first use; `None` when it cannot be loaded.
    pub fn get_texture(&self, name: &str, raw: bool) -> Option<Arc<MipMap>> {
        let slot = slot(&self.textures[raw as usize], name);
        if let Some(source) = &self.source {
            // A render thread asking ahead goes on without the texture; nothing is kept of it.
            if slot.get().is_none()
                && crate::accel::ask_ahead::asks_ahead()
                && source.ask_ahead(TexturePart::Pyramid { raw }, name)
            {
                crate::accel::ask_ahead::missed();
                return None;
            }
        }
        slot.get_or_init(|| match &self.source {
            Some(source) => self.fetch_texture(source, name, raw),
            None => self.load(name, (TextureKind::Texture, if raw { "raw texture" } else { "texture" }), |input| {
                let loaded = match input {
                    Input::File(path) => load_texture_image(path, raw),
                    Input::Bytes(path, bytes) => decode_texture_file(path, bytes, raw),
                };
                loaded
                    .map(|l| {
                        MipMap::with_wrap(l.image, l.wrap.unwrap_or([Wrap::Periodic; 2])).with_projection(l.projection)
                    })
                    .map_err(|e| error_chain(&e))
            }),
        })
        .clone()
    }

    /// Texture `name` from the cache's source: its pyramid, whose finer levels come when lookups
    /// first read them (`texture/remote.rs`), or the whole texture.
    fn fetch_texture(&self, source: &Arc<dyn TextureSource>, name: &str, raw: bool) -> Option<Arc<MipMap>> {
        let part = TexturePart::Pyramid { raw };
        let map = match source.fetch(part, name) {
            TextureAnswer::Whole(delivered) => match image_from_delivered(delivered, raw) {
                Ok(l) => {
                    let map = MipMap::with_wrap(l.image, l.wrap.unwrap_or([Wrap::Periodic; 2]));
                    Arc::new(map.with_projection(l.projection))
                }
                Err((path, reason)) => return self.warn(name, path, reason),
            },
            TextureAnswer::Pyramid(header) => match remote_map(header, source.clone(), name, raw) {
                Some(map) => Arc::new(map),
                None => {
                    source.failed(format!("texture \"{name}\": the description of its pyramid does not hold"));
                    return None;
                }
            },
            TextureAnswer::Unchanged => return kept(source, part, name),
            TextureAnswer::Level(_) => {
                source.failed(format!("texture \"{name}\": a level came where its pyramid was asked for"));
                return None;
            }
        };
        source.keep(part, name, map.clone());
        Some(map)
    }

    /// Records the warning that `name` cannot be loaded, and gives what its lookups get.
    fn warn<T>(&self, name: &str, path: Option<PathBuf>, reason: String) -> Option<T> {
        let warning = TextureWarning { name: name.to_string(), path, reason };
        self.warnings.lock().unwrap_or_else(PoisonError::into_inner).push(warning);
        None
    }

    /// The shadow map called `name`, loading it on first use; `None` when it cannot be loaded.
    pub fn get_shadow_map(&self, name: &str) -> Option<Arc<ShadowMap>> {
        let load = |input: Input| match input {
            Input::File(path) => ShadowMap::load(path).map_err(|e| error_chain(&e)),
            Input::Bytes(path, bytes) => ShadowMap::decode(path, bytes).map_err(|e| error_chain(&e)),
        };
        slot(&self.shadows, name).get_or_init(|| self.load(name, (TextureKind::Shadow, "shadow map"), load)).clone()
    }

    /// The 3-D grid called `name`, loading it on first use; `None` when it cannot be loaded.
    pub fn get_grid(&self, name: &str) -> Option<Arc<Grid>> {
        let load = |input: Input| match input {
            Input::File(path) => Grid::load(path).map_err(|e| error_chain(&e)),
            Input::Bytes(_, bytes) => Grid::parse(bytes),
        };
        slot(&self.grids, name).get_or_init(|| self.load(name, (TextureKind::Grid, "grid"), load)).clone()
    }

    /// The file `name` stands for, or the reason a lookup of it warns that there is none.
    pub fn locate(&self, name: &str) -> Result<PathBuf, String> {
        self.resolve(name).ok_or_else(|| {
            // An empty search path (a scene file's folder given as a bare file name) is the
            // current directory, which is searched anyway.
            let dirs: Vec<String> = self
                .search_paths
                .iter()
                .filter(|d| !d.as_os_str().is_empty())
                .map(|d| d.display().to_string())
                .collect();
            if dirs.is_empty() {
                "file not found".to_string()
            } else {
                format!("file not found (searched {} and the current directory)", dirs.join(", "))
            }
        })
    }

    /// Makes `name` stand for an image built in memory (the API's `tex_image_2d`), for both raw
    /// and decoded lookups, replacing whatever it stood for.
    pub fn insert_texture(&self, name: &str, image: TexImage, wrap: [Wrap; 2]) {
        let mip = Arc::new(MipMap::with_wrap(image, wrap));
        for slots in &self.textures {
            let filled = Arc::new(OnceLock::from(Some(mip.clone())));
            slots.write().unwrap_or_else(PoisonError::into_inner).insert(name.to_string(), filled);
        }
        self.renew_generation();
    }

    /// Makes `name` stand for a 3-D grid built in memory, replacing whatever it stood for.
    pub fn insert_grid(&self, name: &str, grid: Grid) {
        let filled = Arc::new(OnceLock::from(Some(Arc::new(grid))));
        self.grids.write().unwrap_or_else(PoisonError::into_inner).insert(name.to_string(), filled);
        self.renew_generation();
    }

    /// Forgets every texture and shadow map (they load again on next use, e.g. after files
    /// changed). Lookups running meanwhile finish with what they hold.
    pub fn clear(&self) {
        for slots in &self.textures {
            slots.write().unwrap_or_else(PoisonError::into_inner).clear();
        }
        self.shadows.write().unwrap_or_else(PoisonError::into_inner).clear();
        self.grids.write().unwrap_or_else(PoisonError::into_inner).clear();
        self.renew_generation();
    }

    /// Every file a texture, shadow map or grid was read from (or failed to decode from) since the
    /// cache was made, e.g. for watching them for changes.
    pub fn files(&self) -> Vec<PathBuf> {
        self.files.lock().unwrap_or_else(PoisonError::into_inner).iter().cloned().collect()
    }

    /// The warnings since the last call, oldest first: one per name that failed to load.
    pub fn take_warnings(&self) -> Vec<TextureWarning> {
        std::mem::take(&mut *self.warnings.lock().unwrap_or_else(PoisonError::into_inner))
    }

    /// Adds warnings raised elsewhere (a distributed render's workers, whose caches loaded the
    /// textures), each once however often it comes.
    pub fn add_warnings(&self, warnings: impl IntoIterator<Item = TextureWarning>) {
        let mut held = self.warnings.lock().unwrap_or_else(PoisonError::into_inner);
        for w in warnings {
            if !held.contains(&w) {
                held.push(w);
            }
        }
    }

    /// A filtered texture lookup (RSL's `texture()`): `out[c]` gets channel `first_channel + c`
    /// at `(s, t)` over `footprint` (see `MipMap::filter`). Returns false, leaving `out` alone,
    /// when the texture cannot be loaded: the caller then uses the `fill` value.
    #[allow(clippy::too_many_arguments)] // RSL's texture() call, argument for argument
    pub fn texture(
        &self,
        name: &str,
        s: f32,
        t: f32,
        footprint: Footprint,
        first_channel: usize,
        out: &mut [f32],
        opts: &LookupOptions,
    ) -> bool {
        let Some(mip) = self.get_texture(name, opts.raw) else { return false };
        mip.filter(s, t, footprint, first_channel, out, opts);
        true
    }

    /// Many lookups in one texture, the name resolved once: `out` holds `channels` values per
    /// query, query after query (`out[q * channels + c]`). Returns false, leaving `out` alone,
    /// when the texture cannot be loaded.
    pub fn texture_batch(
        &self,
        name: &str,
        queries: &[TextureQuery],
        channels: usize,
        out: &mut [f32],
        opts: &LookupOptions,
    ) -> bool {
        let Some(mip) = self.get_texture(name, opts.raw) else { return false };
        for (q, lane) in queries.iter().zip(out.chunks_exact_mut(channels.max(1))) {
            mip.filter(q.s, q.t, q.footprint, q.first_channel, lane, opts);
        }
        true
    }

    /// The size, channels and projection of a texture (RSL's `textureinfo`), loading it if
    /// needed; `None` when it cannot be loaded.
    pub fn texture_info(&self, name: &str) -> Option<TextureInfo> {
        let mip = self.get_texture(name, false)?;
        Some(TextureInfo {
            width: mip.width(),
            height: mip.height(),
            channels: mip.channels(),
            projection: mip.projection(),
        })
    }

    /// An environment lookup (RSL's `environment()`) in a lat-long map (see
    /// `texture::environment` for the mapping): `dir` is the direction, `ddx`/`ddy` how it
    /// changes over one pixel step in x and y (zero for a point sample). Returns false when the
    /// map cannot be loaded; a zero direction gives `opts.fill` in every channel.
    #[allow(clippy::too_many_arguments)] // RSL's environment() call, argument for argument
    pub fn environment(
        &self,
        name: &str,
        dir: [f32; 3],
        ddx: [f32; 3],
        ddy: [f32; 3],
        first_channel: usize,
        out: &mut [f32],
        opts: &LookupOptions,
    ) -> bool {
        let Some(mip) = self.get_texture(name, opts.raw) else { return false };
        match latlong_footprint(dir, ddx, ddy) {
            Some((s, t, footprint)) => {
                mip.filter_wrapped(s, t, footprint, first_channel, out, opts, [Wrap::Periodic, Wrap::Clamp])
            }
            None => out.fill(opts.fill),
        }
        true
    }

    /// A shadow-map lookup (RSL's `shadow()`): the fraction of the filter kernel around
    /// world-space `p` that is in shadow, 0 lit to 1 shadowed (see `texture::shadow`). `None` when
    /// the map cannot be loaded.
    pub fn shadow(&self, name: &str, p: [f32; 3], opts: &LookupOptions) -> Option<f32> {
        Some(self.get_shadow_map(name)?.shadow(p, opts))
    }

    /// [`TextureCache::shadow`] with a kernel that also covers the world-space `corners` (see
    /// [`ShadowMap::shadow_over`]).
    pub fn shadow_over(&self, name: &str, p: [f32; 3], corners: &[[f32; 3]], opts: &LookupOptions) -> Option<f32> {
        Some(self.get_shadow_map(name)?.shadow_over(p, corners, opts))
    }

    /// Resolves and loads `name` with `load`, turning a failure into one warning and `None`.
    /// Loads what `name` stands for as a `kind` with `load`: from the file it resolves to, or from
    /// what the cache's source delivers. A failure is one warning, and `None`.
    /// `variant` names what a file is decoded as, where it is shared with other caches.
    fn load<T: std::any::Any + Send + Sync, E: fmt::Display>(
        &self,
        name: &str,
        (kind, variant): (TextureKind, &'static str),
        load: impl FnOnce(Input) -> Result<T, E>,
    ) -> Option<Arc<T>> {
        let warn = |path: Option<PathBuf>, reason: String| self.warn(name, path, reason);
        let (path, loaded) = match &self.source {
            None => match self.locate(name) {
                Ok(path) => {
                    self.files.lock().unwrap_or_else(PoisonError::into_inner).insert(path.clone());
                    let loaded = match &self.shared {
                        Some(shared) => shared.get_or_load(&path, variant, || load(Input::File(&path))),
                        None => load(Input::File(&path)).map(Arc::new),
                    };
                    (Some(path), loaded)
                }
                Err(reason) => return warn(None, reason),
            },
            Some(source) => match source.fetch(TexturePart::Whole(kind), name) {
                TextureAnswer::Whole(Delivered::File { path, bytes }) => {
                    let loaded = load(Input::Bytes(&path, &bytes)).map(Arc::new);
                    if let Ok(value) = &loaded {
                        source.keep(TexturePart::Whole(kind), name, value.clone());
                    }
                    (Some(path), loaded)
                }
                TextureAnswer::Unchanged => return kept(source, TexturePart::Whole(kind), name),
                TextureAnswer::Whole(Delivered::Missing { path, reason }) => return warn(path, reason),
                TextureAnswer::Whole(Delivered::Image { .. } | Delivered::Image8 { .. }) => {
                    return warn(None, "an image built in memory is no shadow map or grid".into())
                }
                TextureAnswer::Pyramid(_) | TextureAnswer::Level(_) => {
                    source.failed(format!("\"{name}\": part of a texture came where the whole was asked for"));
                    return None;
                }
            },
        };
        match loaded {
            Ok(value) => Some(value),
            Err(e) => warn(path, e.to_string()),
        }
    }
}

/// What `source` kept of `part` of `name`, as it said it has ([`TextureAnswer::Unchanged`]); a
/// failure of the source where it has not, or not of this type.
fn kept<T: std::any::Any + Send + Sync>(
    source: &Arc<dyn TextureSource>,
    part: TexturePart,
    name: &str,
) -> Option<Arc<T>> {
    let kept = source.kept(part, name).and_then(|made| made.downcast::<T>().ok());
    if kept.is_none() {
        source.failed(format!("\"{name}\": the source said it was unchanged, and holds none of it"));
    }
    kept
}

/// The slot for `name`, made empty if it is new. The read lock covers the common case.
fn slot<T>(slots: &Slots<T>, name: &str) -> Slot<T> {
    if let Some(slot) = slots.read().unwrap_or_else(PoisonError::into_inner).get(name) {
        return slot.clone();
    }
    slots.write().unwrap_or_else(PoisonError::into_inner).entry(name.to_string()).or_default().clone()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::image_io::{write_image, WriteOptions};
    use crate::texture::shadow::tests::{half_occluded_map, ortho_light};
    use crate::texture::{latlong_to_direction, write_shadow_map};

    fn assert_send_sync<T: Send + Sync>() {}

    /// Every cache has a generation of its own, which changes whenever a name may come to stand
    /// for something else, and only then.
    #[test]
    fn generations_are_unique_and_renewed_by_changes() {
        let (a, b) = (TextureCache::new(), TextureCache::new());
        assert_ne!(a.generation(), b.generation());
        let first = a.generation();
        assert!(a.get_texture("missing.png", false).is_none());
        assert_eq!(a.generation(), first, "a lookup changes nothing");
        let mut seen = vec![first, b.generation()];
        a.insert_texture("mem", TexImage::new(1, 1, 1, vec![0.25]).unwrap(), [Wrap::Clamp; 2]);
        seen.push(a.generation());
        a.insert_grid("fog", Grid::new([1, 1, 1], [0.0; 3], [1.0; 3], vec![0.5]).unwrap());
        seen.push(a.generation());
        a.clear();
        seen.push(a.generation());
        let unique: std::collections::HashSet<u64> = seen.iter().copied().collect();
        assert_eq!(unique.len(), seen.len(), "{seen:?}");
    }

    #[test]
    fn the_cache_is_shareable() {
        assert_send_sync::<TextureCache>();
    }

    /// A 2x2 linear EXR: top row red then green, bottom row blue then white.
    fn quad(dir: &Path) -> PathBuf {
        let path = dir.join("quad.exr");
        let px = [1.0, 0.0, 0.0, 1.0, 0.0, 1.0, 0.0, 1.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0];
        write_image(&path, 2, 2, &px, &WriteOptions::default()).unwrap();
        path
    }

    #[test]
    fn lookups_by_name_through_search_paths() {
        let dir = tempfile::tempdir().unwrap();
        quad(dir.path());
        let cache = TextureCache::with_search_paths([PathBuf::from("/nonexistent"), dir.path().to_path_buf()]);
        let mut rgb = [0.0; 3];
        let opts = LookupOptions::default();
        assert!(cache.texture("quad.exr", 0.25, 0.25, Footprint::POINT, 0, &mut rgb, &opts));
        assert_eq!(rgb, [1.0, 0.0, 0.0], "t = 0.25 is the top row");
        assert!(cache.texture("quad.exr", 0.25, 0.75, Footprint::POINT, 0, &mut rgb, &opts));
        assert_eq!(rgb, [0.0, 0.0, 1.0]);
        let mut alpha = [0.0];
        assert!(cache.texture("quad.exr", 0.75, 0.25, Footprint::POINT, 3, &mut alpha, &opts));
        assert_eq!(alpha, [1.0]);
        // The same Arc every time.
        assert!(Arc::ptr_eq(
            &cache.get_texture("quad.exr", false).unwrap(),
            &cache.get_texture("quad.exr", false).unwrap()
        ));
        assert!(cache.take_warnings().is_empty());
    }

    #[test]
    fn a_missing_file_warns_once_and_then_fails_fast() {
        let cache = TextureCache::with_search_paths([PathBuf::from("/nonexistent-dir")]);
        let mut out = [9.0; 3];
        for _ in 0..5 {
            assert!(!cache.texture("nope.png", 0.5, 0.5, Footprint::POINT, 0, &mut out, &LookupOptions::default()));
            assert_eq!(cache.shadow("nope.shad", [0.0; 3], &LookupOptions::default()), None);
        }
        assert_eq!(out, [9.0; 3], "out untouched");
        let warnings = cache.take_warnings();
        assert_eq!(warnings.len(), 2, "{warnings:?}");
        assert!(warnings[0].to_string().contains("nope.png") && warnings[0].reason.contains("not found"));
        assert!(warnings[0].reason.contains("/nonexistent-dir"));
        assert!(cache.take_warnings().is_empty(), "drained");
        assert!(!cache.texture("nope.png", 0.5, 0.5, Footprint::POINT, 0, &mut out, &LookupOptions::default()));
        assert!(cache.take_warnings().is_empty(), "not warned again");
    }

    #[test]
    fn corrupt_files_warn_with_their_path() {
        let dir = tempfile::tempdir().unwrap();
        let bad = dir.path().join("bad.png");
        std::fs::write(&bad, b"\x89PNG\r\n\x1a\n\0\0\0\rIHDR truncated").unwrap();
        let cache = TextureCache::new();
        let name = bad.to_str().unwrap();
        assert!(!cache.texture(name, 0.5, 0.5, Footprint::POINT, 0, &mut [0.0], &LookupOptions::default()));
        assert_eq!(cache.shadow(name, [0.0; 3], &LookupOptions::default()), None);
        let warnings = cache.take_warnings();
        assert_eq!(warnings.len(), 2);
        assert_eq!(warnings[0].path.as_deref(), Some(bad.as_path()));
    }

    #[test]
    fn many_threads_load_once() {
        let dir = tempfile::tempdir().unwrap();
        let path = quad(dir.path());
        let cache = TextureCache::new();
        let name = path.to_str().unwrap();
        let maps: Vec<Arc<MipMap>> = std::thread::scope(|scope| {
            let handles: Vec<_> = (0..8).map(|_| scope.spawn(|| cache.get_texture(name, false).unwrap())).collect();
            handles.into_iter().map(|h| h.join().unwrap()).collect()
        });
        assert!(maps.iter().all(|m| Arc::ptr_eq(m, &maps[0])));
    }

    #[test]
    fn rayon_workers_share_loads_and_warnings() {
        use rayon::prelude::*;
        let dir = tempfile::tempdir().unwrap();
        quad(dir.path());
        let cache = TextureCache::with_search_paths([dir.path().to_path_buf()]);
        let names = ["quad.exr", "missing-a.png", "missing-b.exr"];
        let hits: usize = (0..2000)
            .into_par_iter()
            .map(|i| {
                let mut rgb = [0.0; 3];
                let s = (i % 97) as f32 / 97.0;
                let fp = Footprint { dsdx: 0.01, dtdx: 0.0, dsdy: 0.0, dtdy: 0.01 };
                let ok = cache.texture(names[i % 3], s, 0.3, fp, 0, &mut rgb, &LookupOptions::default());
                assert!(rgb.iter().all(|v| v.is_finite()));
                usize::from(ok)
            })
            .sum();
        assert_eq!(hits, (0..2000).filter(|i| i % 3 == 0).count());
        let mut warned: Vec<String> = cache.take_warnings().into_iter().map(|w| w.name).collect();
        warned.sort();
        assert_eq!(warned, ["missing-a.png", "missing-b.exr"], "one warning per missing name");
    }

    #[test]
    fn batches_and_info() {
        let dir = tempfile::tempdir().unwrap();
        quad(dir.path());
        let cache = TextureCache::with_search_paths([dir.path().to_path_buf()]);
        let queries = [
            TextureQuery { s: 0.25, t: 0.25, ..TextureQuery::default() },
            TextureQuery { s: 0.75, t: 0.75, first_channel: 1, ..TextureQuery::default() },
        ];
        let mut out = [0.0; 4];
        assert!(cache.texture_batch("quad.exr", &queries, 2, &mut out, &LookupOptions::default()));
        assert_eq!(out, [1.0, 0.0, 1.0, 1.0], "red's R, G; white's G, B");
        assert!(!cache.texture_batch("absent.exr", &queries, 2, &mut out, &LookupOptions::default()));

        let info = cache.texture_info("quad.exr").unwrap();
        assert_eq!((info.width, info.height, info.channels, info.projection), (2, 2, 4, None));
        let (depth, w, h) = half_occluded_map();
        let (cam, ndc) = ortho_light();
        write_shadow_map(dir.path().join("s.shad"), &depth, w, h, cam, ndc).unwrap();
        let info = cache.texture_info("s.shad").unwrap();
        assert_eq!((info.width, info.channels, info.projection), (8, 1, Some([cam, ndc])));
    }

    #[test]
    fn raw_and_decoded_lookups_of_one_png() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("grey.png");
        ::image::save_buffer(&path, &[128, 128, 128], 1, 1, ::image::ExtendedColorType::Rgb8).unwrap();
        let cache = TextureCache::new();
        let name = path.to_str().unwrap();
        let mut v = [0.0];
        cache.texture(name, 0.5, 0.5, Footprint::POINT, 0, &mut v, &LookupOptions::default());
        assert!((v[0] - 0.2158).abs() < 1e-3, "decoded: {}", v[0]);
        cache.texture(
            name,
            0.5,
            0.5,
            Footprint::POINT,
            0,
            &mut v,
            &LookupOptions { raw: true, ..LookupOptions::default() },
        );
        assert!((v[0] - 128.0 / 255.0).abs() < 1e-6, "raw: {}", v[0]);
    }

    #[test]
    fn in_memory_textures_and_clear() {
        let cache = TextureCache::new();
        cache.insert_texture("mem", TexImage::new(1, 1, 1, vec![0.25]).unwrap(), [Wrap::Clamp; 2]);
        let mut v = [0.0];
        assert!(cache.texture("mem", 3.0, 3.0, Footprint::POINT, 0, &mut v, &LookupOptions::default()));
        assert_eq!(v, [0.25]);
        cache.clear();
        assert!(!cache.texture("mem", 0.5, 0.5, Footprint::POINT, 0, &mut v, &LookupOptions::default()));
    }

    #[test]
    fn environment_lookups_follow_the_axes() {
        // 8x4 lat-long map whose texels hold their own direction, so a lookup returns (about)
        // the direction asked for.
        let (w, h) = (64, 32);
        let mut data = Vec::new();
        for y in 0..h {
            for x in 0..w {
                data.extend(latlong_to_direction((x as f32 + 0.5) / w as f32, (y as f32 + 0.5) / h as f32));
            }
        }
        let cache = TextureCache::new();
        cache.insert_texture("sky", TexImage::new(w, h, 3, data).unwrap(), [Wrap::Black; 2]);
        let opts = LookupOptions::default();
        for axis in
            [[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [0.0, -1.0, 0.0]]
        {
            let mut out = [0.0; 3];
            assert!(cache.environment("sky", axis, [0.0; 3], [0.0; 3], 0, &mut out, &opts));
            let dot: f32 = out.iter().zip(axis).map(|(a, b)| a * b).sum();
            assert!(dot > 0.95, "{axis:?} -> {out:?}");
        }
        // A zero direction gives the fill value.
        let mut out = [0.0; 3];
        cache.environment(
            "sky",
            [0.0; 3],
            [0.0; 3],
            [0.0; 3],
            0,
            &mut out,
            &LookupOptions { fill: 2.0, ..opts.clone() },
        );
        assert_eq!(out, [2.0; 3]);
        // A wide footprint averages a large part of the sphere: shorter than a unit vector.
        cache.environment("sky", [1.0, 0.0, 0.0], [0.0, 0.0, 1.5], [0.0, 1.5, 0.0], 0, &mut out, &opts);
        let len = out.iter().map(|v| v * v).sum::<f32>().sqrt();
        assert!(len < 0.9 && out[0] > 0.2, "{out:?}");
    }

    #[test]
    fn shadow_lookups_by_name() {
        let dir = tempfile::tempdir().unwrap();
        let (depth, w, h) = half_occluded_map();
        let (cam, ndc) = ortho_light();
        write_shadow_map(dir.path().join("light.shad"), &depth, w, h, cam, ndc).unwrap();
        let cache = TextureCache::with_search_paths([dir.path().to_path_buf()]);
        let opts = LookupOptions { bias: 0.01, ..LookupOptions::default() };
        assert_eq!(cache.shadow("light.shad", [-0.5, 0.0, 5.0], &opts), Some(1.0));
        assert_eq!(cache.shadow("light.shad", [0.5, 0.0, 5.0], &opts), Some(0.0));
        let half = cache.shadow("light.shad", [0.0, 0.0, 5.0], &opts).unwrap();
        assert!((half - 0.5).abs() < 1e-5);
        assert!(cache.take_warnings().is_empty());
    }
}
