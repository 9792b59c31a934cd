//! Loading meshes from files: Wavefront OBJ (via tobj) and PLY, ASCII or binary (via ply-rs-bw).
//!
//! Invariants: loading never panics on bad input. Every error names the file (and the line, for
//! OBJ and MTL files and where the PLY parser gives one), saying the cause once; the mesh returned
//! has passed [`Mesh::validate`]. OBJ groups are merged into one mesh; normals, texture coordinates
//! and vertex colours are kept only if every group has them. PLY vertex properties other than
//! positions, normals and texture coordinates become one-component attributes of the same name.

use crate::geometry::mesh::triangulate_into;
use crate::geometry::{Attribute, Mesh, MeshError};
use glam::{Vec2, Vec3};
use ply_rs_bw::parser::Parser;
use ply_rs_bw::ply::{DefaultElement, Property};
use std::path::{Path, PathBuf};

/// A failure to load a mesh file.
#[derive(Debug, thiserror::Error)]
pub enum MeshIoError {
    /// The file could not be read.
    #[error("cannot read {}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// The OBJ file, or a material library it names, is malformed.
    #[error("{}{}: {message}", path.display(), line.map(|l| format!(":{l}")).unwrap_or_default())]
    Obj {
        /// The OBJ or MTL file.
        path: PathBuf,
        /// The line (1-based), where one can be named.
        line: Option<usize>,
        /// What is wrong.
        message: String,
    },
    /// The PLY file is malformed or lacks what a mesh needs.
    #[error("{}{}: {message}", path.display(), line.map(|l| format!(":{l}")).unwrap_or_default())]
    Ply {
        /// The file.
        path: PathBuf,
        /// The line of the header or ASCII body (1-based), where the parser names one.
        line: Option<usize>,
        /// What is wrong.
        message: String,
    },
    /// The file's extension is neither `.obj` nor `.ply`.
    #[error("{}: unknown mesh format (expected a .obj or .ply file)", path.display())]
    UnknownFormat {
        /// The file.
        path: PathBuf,
    },
    /// The file parsed but its data is inconsistent.
    #[error("{}: invalid mesh", path.display())]
    Invalid {
        /// The file.
        path: PathBuf,
        /// The inconsistency.
        source: MeshError,
    },
}

/// Loads a mesh, choosing the format by the file extension.
pub fn load_mesh(path: impl AsRef<Path>) -> Result<Mesh, MeshIoError> {
    let path = path.as_ref();
    if let Err(source) = std::fs::metadata(path) {
        return Err(MeshIoError::Io { path: path.to_path_buf(), source });
    }
    let ext = path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase());
    match ext.as_deref() {
        Some("obj") => load_obj(path),
        Some("ply") => load_ply(path),
        _ => Err(MeshIoError::UnknownFormat { path: path.to_path_buf() }),
    }
}

/// Loads a Wavefront OBJ file (materials are ignored).
pub fn load_obj(path: &Path) -> Result<Mesh, MeshIoError> {
    let (models, _materials) = read_obj(path, false)?;
    let all = |f: &dyn Fn(&tobj::Mesh) -> bool| models.iter().all(|m| f(&m.mesh));
    let has_n = all(&|m| !m.normals.is_empty() && m.normals.len() == m.positions.len());
    let has_uv = all(&|m| !m.texcoords.is_empty() && m.texcoords.len() / 2 == m.positions.len() / 3);
    let has_c = all(&|m| !m.vertex_color.is_empty() && m.vertex_color.len() == m.positions.len());
    let mut mesh = Mesh::default();
    let mut normals = Vec::new();
    let mut uvs = Vec::new();
    let mut colors = Vec::new();
    for m in &models {
        let m = &m.mesh;
        let base = mesh.positions.len() as u32;
        mesh.positions.extend(m.positions.chunks_exact(3).map(|p| Vec3::new(p[0], p[1], p[2])));
        if has_n {
            normals.extend(m.normals.chunks_exact(3).map(|p| Vec3::new(p[0], p[1], p[2])));
        }
        if has_uv {
            uvs.extend(m.texcoords.chunks_exact(2).map(|p| Vec2::new(p[0], p[1])));
        }
        if has_c {
            colors.extend_from_slice(&m.vertex_color);
        }
        mesh.triangles.extend(m.indices.chunks_exact(3).map(|t| [t[0] + base, t[1] + base, t[2] + base]));
    }
    if has_n {
        mesh.normals = Some(normals);
    }
    if has_uv {
        mesh.uvs = Some(uvs);
    }
    if has_c {
        mesh.attributes.push(Attribute::data("Cs", 3, colors));
    }
    mesh.validate().map_err(|source| MeshIoError::Invalid { path: path.to_path_buf(), source })?;
    Ok(mesh)
}

/// Loads a PLY file (ASCII or binary).
pub fn load_ply(path: &Path) -> Result<Mesh, MeshIoError> {
    let err = |message: String| MeshIoError::Ply { path: path.to_path_buf(), line: None, message };
    let file = std::fs::File::open(path).map_err(|source| MeshIoError::Io { path: path.to_path_buf(), source })?;
    let mut reader = std::io::BufReader::new(file);
    let ply = Parser::<DefaultElement>::new().read_ply(&mut reader).map_err(|e| MeshIoError::Ply {
        path: path.to_path_buf(),
        line: e.line(),
        message: ply_message(&e.to_string()),
    })?;
    let vertices = ply.payload.get("vertex").ok_or_else(|| err("no `vertex` element".to_string()))?;
    let faces = ply.payload.get("face").ok_or_else(|| err("no `face` element".to_string()))?;
    let scalar = |e: &DefaultElement, k: &str| e.get(k).and_then(Property::to_f32_lossy);
    let first = vertices.first();
    let has = |k: &str| first.is_some_and(|e| scalar(e, k).is_some());
    let has_n = has("nx") && has("ny") && has("nz");
    let uv_keys = [("u", "v"), ("s", "t"), ("texture_u", "texture_v")].into_iter().find(|(a, b)| has(a) && has(b));
    let known = ["x", "y", "z", "nx", "ny", "nz", "u", "v", "s", "t", "texture_u", "texture_v"];
    let extra: Vec<String> = first
        .map(|e| {
            e.iter()
                .filter(|(k, p)| !known.contains(&k.as_str()) && p.to_f32_lossy().is_some())
                .map(|(k, _)| k.clone())
                .collect()
        })
        .unwrap_or_default();
    let mut mesh = Mesh { positions: Vec::with_capacity(vertices.len()), ..Default::default() };
    let mut normals = Vec::new();
    let mut uvs = Vec::new();
    let mut attrs: Vec<Attribute> =
        extra.iter().map(|name| Attribute::data(name.clone(), 1, Vec::with_capacity(vertices.len()))).collect();
    for (i, e) in vertices.iter().enumerate() {
        let get = |k: &str| scalar(e, k).ok_or_else(|| err(format!("vertex {i} has no scalar `{k}`")));
        mesh.positions.push(Vec3::new(get("x")?, get("y")?, get("z")?));
        if has_n {
            normals.push(Vec3::new(get("nx")?, get("ny")?, get("nz")?));
        }
        if let Some((a, b)) = uv_keys {
            uvs.push(Vec2::new(get(a)?, get(b)?));
        }
        for at in &mut attrs {
            at.data.push(get(&at.name)?);
        }
    }
    for (face, e) in faces.iter().enumerate() {
        let list = e
            .get("vertex_indices")
            .or_else(|| e.get("vertex_index"))
            .ok_or_else(|| err(format!("face {face} has no `vertex_indices` list")))?;
        let idx = list
            .to_u32_list()
            .ok_or_else(|| err(format!("face {face}: vertex indices are not a list of non-negative integers")))?;
        triangulate_into(face, &idx, &mut mesh.triangles)
            .map_err(|source| MeshIoError::Invalid { path: path.to_path_buf(), source })?;
    }
    if has_n {
        mesh.normals = Some(normals);
    }
    if uv_keys.is_some() {
        mesh.uvs = Some(uvs);
    }
    mesh.attributes = attrs;
    mesh.validate().map_err(|source| MeshIoError::Invalid { path: path.to_path_buf(), source })?;
    Ok(mesh)
}

/// A ply-rs parse error's message without the parser's own line prefix and the debug dumps it
/// appends (`Error: ParseError { .. }`): the first sentence, and the offending text when it names it.
fn ply_message(raw: &str) -> String {
    let mut parts = raw.split("\n\t");
    let head = parts.next().unwrap_or_default();
    // The parser prefixes `Line N: ` itself; the line travels in its own field.
    let head = match head.strip_prefix("Line ").and_then(|rest| rest.split_once(": ")) {
        Some((n, rest)) if n.bytes().all(|b| b.is_ascii_digit()) => rest,
        _ => head,
    };
    let head = head.trim().trim_end_matches('.');
    let text = parts.find_map(|p| p.strip_prefix("String: ").or_else(|| p.strip_prefix("Value: ")));
    match text {
        Some(t) => format!("{head}: `{}`", t.trim().trim_end_matches(',').trim_matches('\'').trim()),
        None => head.to_string(),
    }
}

/// An OBJ file's models (triangulated, one index per vertex) and, when `materials` is set, the
/// materials of the libraries its `mtllib` lines name. A library that cannot be opened gives no
/// materials; one that is malformed is an error with its file and line. tobj panics on a colour
/// line of fewer than three numbers, so every library is checked ([`check_mtl`]) before tobj
/// reads it from memory.
pub(crate) fn read_obj(path: &Path, materials: bool) -> Result<(Vec<tobj::Model>, Vec<tobj::Material>), MeshIoError> {
    read_obj_reading(path, materials).map(|(models, materials, _)| (models, materials))
}

/// An OBJ file's models and materials, and the material library files reading it tried (found
/// or not).
pub(crate) type ObjRead = (Vec<tobj::Model>, Vec<tobj::Material>, Vec<PathBuf>);

/// [`read_obj`], with the material library files it tried to read (found or not).
pub(crate) fn read_obj_reading(path: &Path, materials: bool) -> Result<ObjRead, MeshIoError> {
    // Read whole, so that a directory or an unreadable file is the system's error, not a line's.
    let bytes = std::fs::read(path).map_err(|source| MeshIoError::Io { path: path.to_path_buf(), source })?;
    let mut reader = LineCounter { inner: &bytes[..], line: 0 };
    let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let mtl_error = std::cell::RefCell::new(None);
    let libraries = std::cell::RefCell::new(Vec::new());
    let load_mtl = |name: &Path| {
        if !materials {
            return Err(tobj::LoadError::OpenFileFailed);
        }
        let mtl = dir.join(name);
        libraries.borrow_mut().push(mtl.clone());
        let bytes = std::fs::read(&mtl).map_err(|_| tobj::LoadError::OpenFileFailed)?;
        if let Err(e) = check_mtl(&mtl, &bytes) {
            mtl_error.borrow_mut().get_or_insert(e);
            return Err(tobj::LoadError::MaterialParseError);
        }
        tobj::load_mtl_buf(&mut &bytes[..])
    };
    let opts = tobj::LoadOptions { triangulate: true, single_index: true, ignore_points: true, ignore_lines: true };
    let loaded = tobj::load_obj_buf(&mut reader, &opts, load_mtl);
    if let Some(e) = mtl_error.into_inner() {
        return Err(e);
    }
    match loaded {
        Ok((models, mats)) => Ok((models, mats.unwrap_or_default(), libraries.into_inner())),
        Err(e) => Err(MeshIoError::Obj { path: path.to_path_buf(), line: Some(reader.line), message: obj_message(e) }),
    }
}

/// What a tobj error means, in the file's terms. Errors about indices are found when tobj closes a
/// group (at the next `o`, `g` or `usemtl` line, or the end of the file), so their line is where
/// the group ends.
fn obj_message(e: tobj::LoadError) -> String {
    use tobj::LoadError as E;
    let out_of_range = |what: &str| format!("a face in the group ending here refers to a {what} that does not exist");
    match e {
        E::PositionParseError => "`v` needs three numbers (x y z), optionally followed by w or by r g b".into(),
        E::ScalingByZeroError => "`v` has a w of zero".into(),
        E::ColorParseError => "`v` has a vertex colour of other than three numbers".into(),
        E::NormalParseError => "`vn` needs three numbers".into(),
        E::TexcoordParseError => "`vt` needs two numbers".into(),
        E::FaceParseError => "malformed `f` or `l`: each vertex is v, v/vt, v//vn or v/vt/vn, by integer index".into(),
        E::MaterialParseError => "`usemtl` needs a material name".into(),
        E::ReadError => "cannot read this line (the file is not UTF-8 text, or reading failed)".into(),
        E::FaceVertexOutOfBounds => out_of_range("vertex position"),
        E::FaceTexCoordOutOfBounds => out_of_range("texture coordinate"),
        E::FaceNormalOutOfBounds => out_of_range("normal"),
        E::FaceColorOutOfBounds => out_of_range("vertex colour"),
        E::InvalidPolygon => "a face in the group ending here has fewer than three vertices".into(),
        other => other.to_string(),
    }
}

/// Checks a material library line by line for what tobj's MTL reader rejects or panics on, so
/// that an error names the file and line.
fn check_mtl(path: &Path, bytes: &[u8]) -> Result<(), MeshIoError> {
    let err = |line: usize, message: String| MeshIoError::Obj { path: path.to_path_buf(), line: Some(line), message };
    let text = std::str::from_utf8(bytes).map_err(|e| {
        let line = bytes[..e.valid_up_to()].iter().filter(|&&b| b == b'\n').count() + 1;
        err(line, "not UTF-8 text".into())
    })?;
    for (i, raw) in text.lines().enumerate() {
        let line = raw.trim();
        let mut words = line.split_whitespace();
        let Some(key) = words.next() else { continue };
        let rest = line[key.len()..].trim();
        let number = |w: Option<&str>| w.is_some_and(|w| w.parse::<f32>().is_ok());
        let problem = match key {
            "newmtl" if rest.is_empty() => Some("`newmtl` needs a material name".to_string()),
            "Ka" | "Kd" | "Ks" | "Ke" if !(0..3).all(|_| number(words.next())) => {
                Some(format!("`{key}` needs three numbers (r g b)"))
            }
            "Ns" | "Ni" | "d" if !number(words.next()) => Some(format!("`{key}` needs a number")),
            "illum" if words.next().is_none_or(|w| w.parse::<u8>().is_err()) => {
                Some("`illum` needs an integer from 0 to 255".to_string())
            }
            "map_Ka" | "map_Kd" | "map_Ks" | "map_Bump" | "map_bump" | "map_Ns" | "map_ns" | "map_NS" | "bump"
            | "map_d"
                if rest.is_empty() =>
            {
                Some(format!("`{key}` needs a texture file name"))
            }
            _ => None,
        };
        if let Some(message) = problem {
            return Err(err(i + 1, message));
        }
    }
    Ok(())
}

/// A reader that counts the lines read through it, so that an error tobj reports can be placed.
struct LineCounter<R> {
    inner: R,
    line: usize,
}

impl<R: std::io::Read> std::io::Read for LineCounter<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        self.inner.read(buf)
    }
}

impl<R: std::io::BufRead> std::io::BufRead for LineCounter<R> {
    fn fill_buf(&mut self) -> std::io::Result<&[u8]> {
        self.inner.fill_buf()
    }

    fn consume(&mut self, amt: usize) {
        self.inner.consume(amt)
    }

    // tobj reads through `lines()`, which calls this once a line.
    fn read_line(&mut self, buf: &mut String) -> std::io::Result<usize> {
        let n = self.inner.read_line(buf)?;
        if n > 0 {
            self.line += 1;
        }
        Ok(n)
    }
}
