//! Hostile input to the runtime's readers and writers: each is a clear error (or warning) naming
//! the file and, where there is one, the line, never a panic, a hang or memory exhausted.

mod common;

use common::write;
use rtsl_runtime::api::Context;
use rtsl_runtime::load_mesh;
use rtsl_runtime::render::{check_image_size, MAX_IMAGE_PIXELS, MAX_IMAGE_SIDE};
use rtsl_runtime::rib::load::load_str;
use rtsl_runtime::rib::MAX_RIB_TRIANGLES;
use rtsl_runtime::scene_file::{add_model_file, MAX_GLTF_NODE_DEPTH};
use std::path::{Path, PathBuf};

const TRIANGLE_OBJ: &str = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\n";

#[test]
fn a_short_colour_line_in_a_material_library_is_an_error_with_its_file_and_line() {
    let dir = tempfile::tempdir().expect("tempdir");
    let obj = write(dir.path(), "model.obj", TRIANGLE_OBJ);
    for (mtl, line, key) in [("newmtl a\nKd 0.5 0.5\n", 2, "Kd"), ("newmtl a\nKd 1 1 1\n\nKs\n", 4, "Ks")] {
        write(dir.path(), "m.mtl", mtl);
        let err = add_model_file(&mut Context::new(), &obj).expect_err("a malformed material library").to_string();
        assert!(err.contains(&format!("m.mtl:{line}: `{key}` needs three numbers")), "{err}");
        // The mesh alone does not read the materials, so it loads.
        assert_eq!(load_mesh(&obj).expect("the mesh").triangle_count(), 1);
        // Through a RIB archive the model is skipped with a warning at the request.
        let mut rt = Context::new();
        let loaded = load_str(&mut rt, "WorldBegin\nReadArchive \"model.obj\"\nWorldEnd\n", dir.path().join("s.rib"))
            .expect("the RIB loads");
        assert!(
            loaded
                .warnings
                .iter()
                .map(ToString::to_string)
                .any(|w| w.contains("s.rib:2:") && w.contains(&format!("m.mtl:{line}:"))),
            "{:?}",
            loaded.warnings
        );
    }
    // A library that is well formed still gives the model its material.
    write(dir.path(), "m.mtl", "newmtl a\nKd 0.5 0.5 0.5\n");
    add_model_file(&mut Context::new(), &obj).expect("a good material library");
}

#[test]
fn obj_errors_name_the_line_and_say_what_is_wrong_once() {
    let dir = tempfile::tempdir().expect("tempdir");
    for (text, expected) in [
        ("v 0 0 0\nv 1 0\nf 1 2 3\n", "bad.obj:2: `v` needs three numbers"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0\n", "bad.obj:4: `vn` needs three numbers"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x\n", "bad.obj:4: malformed `f`"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\ng next\nf 1 2 3\n", "bad.obj:5: a face in the group ending here"),
    ] {
        let path = write(dir.path(), "bad.obj", text);
        for err in [
            load_mesh(&path).expect_err("a malformed OBJ").to_string(),
            add_model_file(&mut Context::new(), &path).expect_err("a malformed OBJ").to_string(),
        ] {
            assert_eq!(err.matches(expected).count(), 1, "said once: {err}");
        }
    }
}

#[test]
fn ply_errors_carry_no_debug_dumps() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = write(
        dir.path(),
        "bad.ply",
        "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n1 2 zz\n",
    );
    let err = load_mesh(&path).expect_err("a malformed PLY").to_string();
    assert!(err.starts_with(&format!("{}:", path.display())), "{err}");
    for debug in ["ParseError", "{ ", "\n", "\t", "Kind"] {
        assert!(!err.contains(debug), "`{debug}` in {err:?}");
    }
}

/// A glTF file of one triangle whose positions are in `tri.bin` (written beside it), with the
/// given nodes and buffer `uri`, and the position accessor claiming `count` vertices.
fn write_gltf(dir: &Path, nodes: &str, uri: &str, count: u64) -> PathBuf {
    let floats: [f32; 9] = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0];
    let bytes: Vec<u8> = floats.iter().flat_map(|f| f.to_le_bytes()).collect();
    std::fs::write(dir.join("tri.bin"), bytes).expect("write the buffer");
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":{nodes},
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}}}}]}}],
        "buffers":[{{"uri":"{uri}","byteLength":36}}],"bufferViews":[{{"buffer":0,"byteLength":36}}],
        "accessors":[{{"bufferView":0,"componentType":5126,"count":{count},"type":"VEC3","min":[0,0,0],"max":[1,1,0]}}]}}"#
    );
    write(dir, "model.gltf", &json)
}

fn gltf_error(path: &Path) -> String {
    match add_model_file(&mut Context::new(), path) {
        Err(e) => e.to_string(),
        Ok(_) => panic!("{} loaded", path.display()),
    }
}

#[test]
fn gltf_node_cycles_and_deep_hierarchies_are_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    let good = write_gltf(dir.path(), r#"[{"mesh":0,"children":[1]},{"mesh":0}]"#, "tri.bin", 3);
    add_model_file(&mut Context::new(), &good).expect("a tree of two nodes");

    let own_child = write_gltf(dir.path(), r#"[{"mesh":0,"children":[0]}]"#, "tri.bin", 3);
    assert!(gltf_error(&own_child).contains("node 0 lists itself as a child"), "{}", gltf_error(&own_child));

    let cycle = write_gltf(dir.path(), r#"[{"mesh":0},{"children":[2]},{"children":[1]}]"#, "tri.bin", 3);
    assert!(gltf_error(&cycle).contains("cycle"), "{}", gltf_error(&cycle));

    let two_parents = write_gltf(dir.path(), r#"[{"mesh":0,"children":[2]},{"children":[2]},{}]"#, "tri.bin", 3);
    assert!(gltf_error(&two_parents).contains("child of both"), "{}", gltf_error(&two_parents));

    let chain = |n: usize| {
        let nodes: Vec<String> = (0..n)
            .map(|i| if i + 1 < n { format!(r#"{{"mesh":0,"children":[{}]}}"#, i + 1) } else { "{}".into() })
            .collect();
        format!("[{}]", nodes.join(","))
    };
    let at_limit = write_gltf(dir.path(), &chain(MAX_GLTF_NODE_DEPTH), "tri.bin", 3);
    add_model_file(&mut Context::new(), &at_limit).expect("a chain as deep as the limit");
    let deep = write_gltf(dir.path(), &chain(20_000), "tri.bin", 3);
    let err = gltf_error(&deep);
    assert!(err.contains(&format!("nest deeper than {MAX_GLTF_NODE_DEPTH}")), "{err}");
}

#[test]
fn gltf_buffers_outside_the_models_folder_are_refused() {
    let root = tempfile::tempdir().expect("tempdir");
    let dir = root.path().join("model");
    std::fs::create_dir(&dir).expect("mkdir");
    let outside = root.path().join("secret.bin");
    std::fs::write(&outside, [0u8; 36]).expect("write");
    for (uri, why) in [
        (outside.display().to_string(), "absolute path"),
        ("../secret.bin".to_string(), "out of the model's folder"),
        ("sub/../../secret.bin".to_string(), "out of the model's folder"),
        (format!("file://{}", outside.display()), "not a data URI or a relative path"),
        ("tri%FF.bin".to_string(), "UTF-8"),
    ] {
        let path = write_gltf(&dir, r#"[{"mesh":0}]"#, &uri, 3);
        let err = gltf_error(&path);
        assert!(err.contains("buffer 0") && err.contains(why), "{uri}: {err}");
    }
    std::fs::create_dir(dir.join("sub")).expect("mkdir");
    let path = write_gltf(&dir, r#"[{"mesh":0}]"#, "./sub/../tri.bin", 3);
    add_model_file(&mut Context::new(), &path).expect("a relative path inside the folder");
}

#[test]
fn gltf_accessors_claiming_more_than_their_buffer_are_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    for count in [4, 4_000_000_000] {
        let path = write_gltf(dir.path(), r#"[{"mesh":0}]"#, "tri.bin", count);
        let err = gltf_error(&path);
        assert!(err.contains(&format!("accessor 0 claims {count} elements")), "{err}");
    }
}

/// A binary glTF (GLB) holding `json` as its one chunk, with `length` in its header (`None`: the
/// file's true length).
fn glb(json: &str, length: Option<u32>) -> Vec<u8> {
    let mut chunk = json.as_bytes().to_vec();
    chunk.resize(chunk.len().next_multiple_of(4), b' ');
    let total = 12 + 8 + chunk.len() as u32;
    let mut out = b"glTF".to_vec();
    for word in [2, length.unwrap_or(total), chunk.len() as u32, 0x4E4F_534A] {
        out.extend_from_slice(&u32::to_le_bytes(word));
    }
    out.extend_from_slice(&chunk);
    out
}

/// A GLB header's length is checked against the file before the glTF library reads by it (it
/// subtracted the header's size from a smaller one and overflowed, and sized a buffer by it).
#[test]
fn glb_lengths_beyond_the_file_or_below_its_header_are_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    let json = std::fs::read_to_string(write_gltf(dir.path(), r#"[{"mesh":0}]"#, "tri.bin", 3)).expect("read");
    let good = dir.path().join("model.glb");
    std::fs::write(&good, glb(&json, None)).expect("write");
    add_model_file(&mut Context::new(), &good).expect("a well-formed GLB");
    let size = glb(&json, None).len();
    for length in [0, 11, size as u32 + 1, u32::MAX] {
        let path = dir.path().join("bad.glb");
        std::fs::write(&path, glb(&json, Some(length))).expect("write");
        let err = gltf_error(&path);
        let want = format!("the GLB header gives a length of {length} bytes, but the file has {size}");
        assert!(err.contains(&want), "{err}");
    }
    let cut = dir.path().join("cut.glb");
    std::fs::write(&cut, b"glTF\x02\0\0\0").expect("write");
    assert!(gltf_error(&cut).contains("the GLB header is cut short: 8 bytes of 12"), "{}", gltf_error(&cut));
}

/// A primitive whose POSITION names an accessor the file lacks is an error naming it (the glTF
/// library's own validation panicked on it).
#[test]
fn gltf_positions_from_a_missing_accessor_are_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    let good = write_gltf(dir.path(), r#"[{"mesh":0}]"#, "tri.bin", 3);
    let text = std::fs::read_to_string(&good).expect("read");
    for index in [1, 5, 4_000_000_000u64] {
        let bad = text.replace(r#""POSITION":0"#, &format!(r#""POSITION":{index}"#));
        let path = write(dir.path(), "missing.gltf", &bad);
        let err = gltf_error(&path);
        assert!(err.contains(&format!("POSITION is accessor {index}, but the file has 1 accessors")), "{err}");
    }
}

#[test]
fn image_sizes_beyond_the_limits_are_refused_before_anything_is_allocated() {
    assert!(check_image_size(1920, 1080).is_ok());
    assert!(check_image_size(u64::from(MAX_IMAGE_SIDE), MAX_IMAGE_PIXELS / u64::from(MAX_IMAGE_SIDE)).is_ok());
    let side = check_image_size(u64::from(MAX_IMAGE_SIDE) + 1, 1).expect_err("too wide");
    assert!(side.contains("at most 32768 pixels a side"), "{side}");
    let pixels = check_image_size(16384, 16384).expect_err("too many pixels");
    assert!(pixels.contains("16384x16384") && pixels.contains("at most"), "{pixels}");

    let mut rt = Context::new();
    let loaded = load_str(&mut rt, "Format 100000 100000 1\nWorldBegin\nWorldEnd\n", Path::new("big.rib"));
    loaded.expect("the RIB loads: the size is refused when a frame is made");
    let err = rt.build_world().map(drop).expect_err("a frame of 10^10 pixels").to_string();
    assert!(err.contains("100000x100000") && err.contains("too large"), "{err}");
    rt.options.width = 64;
    rt.options.height = 48;
    rt.build_world().expect("a size within the limits");
}

#[test]
fn a_rib_tessellating_past_the_triangle_budget_stops_with_an_error() {
    let spheres_needed = MAX_RIB_TRIANGLES / 3000;
    let mut rib = String::from("WorldBegin\n");
    for _ in 0..spheres_needed {
        rib.push_str("Sphere 1 -1 1 360\n");
    }
    rib.push_str("WorldEnd\n");
    let err = load_str(&mut Context::new(), &rib, Path::new("many.rib")).expect_err("past the budget").to_string();
    assert!(err.starts_with("many.rib:") && err.contains(&format!("passes {MAX_RIB_TRIANGLES} triangles")), "{err}");
}

/// One request that alone makes more triangles than a RIB load may: refused at the request from
/// its count, before it is tessellated (a bilinear patch mesh of saddle-shaped patches, 128
/// triangles each).
#[test]
fn a_patch_mesh_past_the_triangle_budget_is_refused_before_it_is_tessellated() {
    let side = 364usize;
    let patches = (side - 1) * (side - 1);
    assert!(128 * patches > MAX_RIB_TRIANGLES);
    let heights: Vec<&str> = (0..side * side).map(|k| if (k % side + k / side) % 2 == 0 { "0" } else { "1" }).collect();
    let rib = format!(
        "WorldBegin\nPatchMesh \"bilinear\" {side} \"nonperiodic\" {side} \"nonperiodic\" \"Pz\" [{}]\nWorldEnd\n",
        heights.join(" ")
    );
    let start = std::time::Instant::now();
    let err = load_str(&mut Context::new(), &rib, Path::new("patches.rib")).expect_err("past the budget").to_string();
    assert!(err.starts_with("patches.rib:2:"), "{err}");
    assert!(
        err.contains(&format!("passes {MAX_RIB_TRIANGLES} triangles with this request's {}", 128 * patches)),
        "{err}"
    );
    assert!(start.elapsed() < std::time::Duration::from_secs(20), "{:?}", start.elapsed());
}

/// A mesh of 100,000 copies of one triangle (and one triangle in front of part of them) builds its
/// BVH in n log n, and rays still find the nearest triangle.
#[test]
fn a_mesh_of_many_coincident_triangles_builds_and_is_hit() {
    use glam::{Affine3A, Vec3, Vec3A};
    use rtsl_runtime::{Mesh, Ray, Scene};
    let copies = 100_000u32;
    let mut positions = vec![Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, -1.0, 0.0), Vec3::new(-1.0, 1.0, 0.0)];
    let mut triangles = vec![[0, 1, 2]; copies as usize];
    positions.extend([Vec3::new(-1.0, -1.0, 1.0), Vec3::new(0.0, -1.0, 1.0), Vec3::new(-1.0, 0.0, 1.0)]);
    triangles.push([3, 4, 5]);
    let mesh = Mesh::from_triangles(positions, triangles).expect("valid triangles");
    let mut scene = Scene::new();
    let id = scene.add_object(mesh);
    scene.add_instance(id, Affine3A::IDENTITY).expect("identity");
    scene.commit();
    let down = |x: f32, y: f32| Ray::new(Vec3A::new(x, y, 5.0), Vec3A::NEG_Z);
    let front = scene.intersect(&down(-0.8, -0.8));
    assert!(front.is_hit() && front.primitive == copies && (front.t - 4.0).abs() < 1e-5, "{front:?}");
    let behind = scene.intersect(&down(0.3, -0.5));
    assert!(behind.is_hit() && behind.primitive < copies && (behind.t - 5.0).abs() < 1e-5, "{behind:?}");
    assert!(!scene.intersect(&down(0.9, 0.9)).is_hit());
    assert!(scene.occluded(&down(0.3, -0.5)));
}
