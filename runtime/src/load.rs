//! Any scene file, its loader chosen by its extension: a RIB file (`.rib`), a VRML 97 or 1.0 file
//! (`.wrl`, gzip-compressed `.wrz` or `.wrl.gz`: [`crate::vrml`]), or a model file (`.obj`, `.ply`,
//! `.gltf`, `.glb`) that gets a camera framing it and the default light rig
//! ([`crate::scene_file`]).

use crate::api::Context;
use crate::rib::{RibDiagnostic, Severity};
use crate::scene_file::{add_model_file, frame_bounds, SceneFileError};
use std::path::{Path, PathBuf};

/// What loading a scene file left besides the scene.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LoadedScene {
    /// The image the scene names (a RIB `Display`), resolved against the scene file's directory.
    pub display: Option<PathBuf>,
    /// Every image the scene asks for (RIB `Display` and `+name` displays), names resolved
    /// against the scene file's directory.
    pub displays: Vec<crate::rib::load::RibDisplay>,
    /// What was skipped, ignored or approximated, each naming where (see
    /// [`crate::rib::load::LoadedRib::warnings`]).
    pub warnings: Vec<RibDiagnostic>,
    /// The files the scene was read from: the scene file, its RIB archives and model files (not
    /// textures, which load as rendering needs them: `TextureCache::files`).
    pub files: Vec<PathBuf>,
    /// How many images the scene file asks for (a RIB file's frames; 1 for a model file, and
    /// 0 when unknown, as for a [`LoadedScene::default`]).
    pub frames: usize,
    /// The number of the image loaded (see [`crate::rib::load::LoadedRib::frame_number`]).
    pub frame_number: i32,
    /// A VRML scene's graph, routes and sensors, to animate it
    /// ([`crate::vrml::VrmlScene::advance_to`]); its warnings are in `warnings`.
    pub vrml: Option<Box<crate::vrml::VrmlScene>>,
}

impl LoadedScene {
    /// How many of the diagnostics say that part of the scene is missing from the picture (a request
    /// skipped or unreadable; a shader, archive or model not found).
    pub fn omissions(&self) -> usize {
        self.warnings.iter().filter(|d| d.severity >= Severity::Omission).count()
    }

    /// How many requests could not be read (syntax errors in a RIB file), each skipped.
    pub fn errors(&self) -> usize {
        self.warnings.iter().filter(|d| d.severity == Severity::Error).count()
    }
}

/// Loads the scene in `path` into `rt` by its extension (case-insensitive); of a RIB file with
/// several frames, the first.
pub fn load_scene(rt: &mut Context, path: impl AsRef<Path>) -> Result<LoadedScene, SceneFileError> {
    load_scene_frame(rt, path, 0)
}

/// How a scene file is read, beyond its own content.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LoadOptions {
    /// VRML: the library surface shader every shape gets instead of `material`, VRML's lighting
    /// model, as the paper's browser swapped it (`crate::vrml::VrmlOptions`).
    pub vrml_surface: Option<String>,
}

/// [`load_scene`] of the image at `index` (counting from 0) of a file with several.
pub fn load_scene_frame(rt: &mut Context, path: impl AsRef<Path>, index: usize) -> Result<LoadedScene, SceneFileError> {
    load_scene_with(rt, path, index, &LoadOptions::default())
}

/// [`load_scene_frame`] with [`LoadOptions`].
pub fn load_scene_with(
    rt: &mut Context,
    path: impl AsRef<Path>,
    index: usize,
    options: &LoadOptions,
) -> Result<LoadedScene, SceneFileError> {
    let path = path.as_ref();
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    if crate::vrml::is_vrml_path(path) {
        if index > 0 {
            return Err(SceneFileError::Rib {
                path: path.to_path_buf(),
                message: format!("a VRML file is one image; there is no image {}", index + 1),
            });
        }
        let vrml = crate::vrml::VrmlOptions { surface: options.vrml_surface.clone() };
        let mut scene = crate::vrml::load_file_with(rt, path, &vrml)?;
        return Ok(LoadedScene {
            files: scene.files(),
            warnings: std::mem::take(&mut scene.warnings),
            frames: 1,
            frame_number: 1,
            vrml: Some(Box::new(scene)),
            ..LoadedScene::default()
        });
    }
    match ext.as_deref() {
        Some("rib") => Ok(rib_scene(path, crate::rib::load::load_file_frame(rt, path, index)?)),
        Some("obj" | "ply" | "gltf" | "glb") if index == 0 => {
            let bounds = add_model_file(rt, path)?;
            frame_bounds(rt, bounds)?;
            Ok(LoadedScene { files: vec![path.to_path_buf()], frames: 1, frame_number: 1, ..LoadedScene::default() })
        }
        Some("obj" | "ply" | "gltf" | "glb") => Err(SceneFileError::Rib {
            path: path.to_path_buf(),
            message: format!("a model file is one image; there is no image {}", index + 1),
        }),
        _ => Err(SceneFileError::UnknownType { path: path.to_path_buf() }),
    }
}

/// Whether `path` names a RIB file (by its extension, as [`load_scene`] chooses).
pub fn is_rib_path(path: &Path) -> bool {
    path.extension().is_some_and(|e| e.eq_ignore_ascii_case("rib"))
}

/// [`load_scene_frame`] of each image of a RIB file that `wanted` takes (by its index and
/// number), in one reading of the file ([`crate::rib::load::load_file_frames`]): each is loaded
/// into a context `new_context` makes and handed to `each` with its index as soon as its last
/// request is read. Returns the numbers of the images read and what reading found after the last
/// image loaded.
pub fn load_rib_frames<E: From<SceneFileError>>(
    path: impl AsRef<Path>,
    new_context: impl FnMut() -> Context,
    wanted: impl FnMut(usize, i32) -> bool,
    mut each: impl FnMut(usize, Context, LoadedScene) -> Result<std::ops::ControlFlow<()>, E>,
) -> Result<crate::rib::load::RibImages, E> {
    let path = path.as_ref();
    crate::rib::load::load_file_frames(path, new_context, wanted, |image| {
        each(image.index, image.rt, rib_scene(path, image.loaded))
    })
}

/// What loading an image of the RIB file `path` left, its names resolved against the file's
/// directory.
fn rib_scene(path: &Path, loaded: crate::rib::load::LoadedRib) -> LoadedScene {
    let dir = path.parent().unwrap_or(Path::new("."));
    let displays =
        loaded.displays.into_iter().map(|d| crate::rib::load::RibDisplay { name: dir.join(&d.name), ..d }).collect();
    LoadedScene {
        display: loaded.display.map(|d| dir.join(d)),
        displays,
        warnings: loaded.warnings,
        files: std::iter::once(path.to_path_buf()).chain(loaded.files).collect(),
        frames: loaded.frames,
        frame_number: loaded.frame_number,
        vrml: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_extension_chooses_the_loader() {
        let dir = tempfile::tempdir().expect("a temporary directory");
        let rib = dir.path().join("Scene.RIB");
        std::fs::write(&rib, "Display \"out.png\" \"file\" \"rgba\"\nWorldBegin\nSphere 1 -1 1 360\nWorldEnd\n")
            .expect("written");
        let loaded = load_scene(&mut Context::new(), &rib).expect("a RIB file loads");
        assert_eq!(loaded.display, Some(dir.path().join("out.png")));

        let obj = dir.path().join("tri.obj");
        std::fs::write(&obj, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").expect("written");
        let mut rt = Context::new();
        let loaded = load_scene(&mut rt, &obj).expect("an OBJ file loads");
        assert_eq!(
            loaded,
            LoadedScene { files: vec![obj.clone()], frames: 1, frame_number: 1, ..LoadedScene::default() }
        );
        assert_eq!(rt.world_instance_ids().len(), 1);

        // The files read: the scene, its RIB archives and its model files.
        std::fs::write(dir.path().join("inner.rib"), "ReadArchive \"tri.obj\"\n").expect("written");
        let outer = dir.path().join("outer.rib");
        std::fs::write(&outer, "WorldBegin\nReadArchive \"inner.rib\"\nWorldEnd\n").expect("written");
        let loaded = load_scene(&mut Context::new(), &outer).expect("the archives load");
        let canonical = |p: PathBuf| std::fs::canonicalize(p).expect("exists");
        let files: Vec<PathBuf> = loaded.files.into_iter().map(canonical).collect();
        assert_eq!(files, [outer, dir.path().join("inner.rib"), obj].map(canonical));

        let other = dir.path().join("scene.txt");
        std::fs::write(&other, "nothing").expect("written");
        let err = load_scene(&mut Context::new(), &other).expect_err("an unknown type is an error");
        assert!(err.to_string().contains("scene.txt: unknown scene file type"), "{err}");
    }
}
