//! Broken, truncated or unsupported mesh files give errors that name the file, never panics; a
//! well-formed file loads with its triangles.

mod common;

use common::write;
use rtsl_runtime::load_mesh;

#[test]
fn bad_mesh_files_are_errors_naming_the_file() {
    let dir = tempfile::tempdir().expect("tempdir");
    let cases: &[(&str, &[u8])] = &[
        ("short_vertex.obj", b"v 0 0 0\nv 1 0\nf 1 2 3\n"),
        ("bad_index.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n"),
        ("garbage.obj", b"\x00\x01\x02 this is not a mesh \xff\xfe"),
        ("truncated.ply", b"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nend_header\n1 2\n"),
        ("not_ply.ply", b"hello\n"),
        ("mesh.xyz", b"v 0 0 0\n"),
    ];
    for (name, text) in cases {
        let path = write(dir.path(), name, text);
        let err = match load_mesh(&path) {
            Err(e) => e.to_string(),
            Ok(m) => panic!("{name} loaded as a mesh with {} triangles", m.triangle_count()),
        };
        assert!(err.contains(name), "{name}: the error does not name the file: {err}");
    }
    let missing = dir.path().join("missing.obj");
    let err = load_mesh(&missing).err().map(|e| e.to_string()).unwrap_or_default();
    assert!(err.contains("missing.obj"), "{err}");
}

#[test]
fn a_quad_obj_loads_as_two_triangles() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = write(dir.path(), "quad.obj", b"v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n");
    let mesh = load_mesh(&path).expect("loads");
    assert_eq!(mesh.triangle_count(), 2);
}
