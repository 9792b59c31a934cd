//! `Geometry "teapot"`: the Utah teapot, which PRMan, 3Delight and Aqsis provide as a built-in
//! `Geometry` (RISpec 3.2 section 5.8 gives it as the example). Other names draw nothing: the
//! request is skipped with a warning that counts as an omission.
//!
//! The teapot is Martin Newell's data set (1975, public domain): 306 control points and 32
//! bicubic Bezier patches (rim 4, body 8, handle 4, spout 4, lid 8, bottom 4). Its coordinates are
//! used as published, which is RenderMan's teapot: z up, the bottom on z = 0, the lid's knob up to
//! z = 3.15, the spout towards +x and the handle towards -x. The surface spans x from -3 (the
//! handle) to 3.433 (the spout's tip), y from -2 to 2 and z from 0 to 3.15.
//!
//! Each patch is a `Patch "bicubic"` through the patch builder (`patch.rs`), under the Bezier basis
//! whatever the current `Basis`: cut like any bicubic patch (8 segments a side by default), with
//! its own `(u, v)` from 0 to 1 (its texture coordinates mapped through `TextureCoordinates`, as a
//! patch's), and normals `dP/du x dP/dv`,
//! which point out of the pot. The body is open under the lid and the lid is a separate surface,
//! as in Newell's data; the spout and handle pass through the body without being cut.

use std::path::Path;
use std::sync::Arc;

use super::decl::{Class, Decl, Ty};
use super::mesh::MeshOptions;
use super::patch::{patch_mesh, patch_mesh_triangles};
use super::request::{Basis, Location, Param, ParamValue, PatchType, Wrap};
use crate::geometry::Mesh;

/// `Geometry name params`: the teapot, or an error for a name rtsl does not know.
pub fn geometry_mesh(
    name: &str,
    params: &[Param],
    options: &MeshOptions,
    warnings: &mut Vec<String>,
) -> Result<Mesh, String> {
    match name {
        "teapot" => teapot_mesh(params, options, warnings),
        other => Err(format!("unknown Geometry name \"{other}\" (rtsl provides \"teapot\"): it is skipped")),
    }
}

/// At most the triangles [`geometry_mesh`] makes of `Geometry name`.
pub fn geometry_triangles(name: &str, options: &MeshOptions) -> usize {
    if name == "teapot" {
        teapot_triangles(options)
    } else {
        0
    }
}

/// The teapot's mesh: its 32 patches one after the other.
pub fn teapot_mesh(params: &[Param], options: &MeshOptions, warnings: &mut Vec<String>) -> Result<Mesh, String> {
    for p in params.iter().filter(|p| !matches!(p.decl.class, Class::Constant | Class::Implicit)) {
        warnings.push(format!("\"{}\" ({}) is dropped: the teapot takes no data over its surface", p.name, p.decl));
    }
    // The patches' own texture coordinates are their parameters: the teapot's mapped ones are
    // made once, over the whole pot.
    let patches = MeshOptions { texture_coordinates: MeshOptions::default().texture_coordinates, ..bezier(options) };
    let mut mesh = Mesh { normals: Some(Vec::new()), uvs: Some(Vec::new()), ..Default::default() };
    for k in 0..PATCHES.len() {
        let part = patch_mesh(
            PatchType::Bicubic,
            4,
            Wrap::NonPeriodic,
            4,
            Wrap::NonPeriodic,
            &[patch_points(k)],
            &patches,
            warnings,
        )?;
        let offset = mesh.positions.len() as u32;
        mesh.positions.extend(part.positions);
        if let (Some(normals), Some(part)) = (mesh.normals.as_mut(), part.normals) {
            normals.extend(part);
        }
        if let (Some(uvs), Some(part)) = (mesh.uvs.as_mut(), part.uvs) {
            uvs.extend(part);
        }
        mesh.triangles.extend(part.triangles.into_iter().map(|t| t.map(|i| i + offset)));
    }
    super::mesh::route_attributes_parametric(&mut mesh, Vec::new(), options);
    mesh.validate().map_err(|e| e.to_string())?;
    Ok(mesh)
}

/// At most the triangles [`teapot_mesh`] makes.
pub fn teapot_triangles(options: &MeshOptions) -> usize {
    let one = (4, Wrap::NonPeriodic);
    PATCHES.len() * patch_mesh_triangles(PatchType::Bicubic, one, one, &[patch_points(0)], &bezier(options))
}

/// `options` under the Bezier basis.
fn bezier(options: &MeshOptions) -> MeshOptions {
    let basis = Basis::Named("bezier".into());
    MeshOptions { u_basis: basis.clone(), u_step: 3, v_basis: basis, v_step: 3, ..options.clone() }
}

/// Patch `k`'s control points as the `P` of a `Patch "bicubic"`.
fn patch_points(k: usize) -> Param {
    let floats = PATCHES[k].iter().flat_map(|&i| VERTICES[usize::from(i) - 1]).collect();
    Param {
        name: "P".into(),
        decl: Decl::new(Class::Vertex, Ty::Point),
        value: ParamValue::Floats(floats),
        loc: Location { file: Arc::from(Path::new("teapot")), line: 0, column: 0 },
    }
}

/// Newell's 306 control points (z up), as published.
#[rustfmt::skip]
const VERTICES: [[f32; 3]; 306] = [
    [1.4, 0.0, 2.4], [1.4, -0.784, 2.4], [0.784, -1.4, 2.4], [0.0, -1.4, 2.4],
    [1.3375, 0.0, 2.53125], [1.3375, -0.749, 2.53125], [0.749, -1.3375, 2.53125], [0.0, -1.3375, 2.53125],
    [1.4375, 0.0, 2.53125], [1.4375, -0.805, 2.53125], [0.805, -1.4375, 2.53125], [0.0, -1.4375, 2.53125],
    [1.5, 0.0, 2.4], [1.5, -0.84, 2.4], [0.84, -1.5, 2.4], [0.0, -1.5, 2.4],
    [-0.784, -1.4, 2.4], [-1.4, -0.784, 2.4], [-1.4, 0.0, 2.4], [-0.749, -1.3375, 2.53125],
    [-1.3375, -0.749, 2.53125], [-1.3375, 0.0, 2.53125], [-0.805, -1.4375, 2.53125], [-1.4375, -0.805, 2.53125],
    [-1.4375, 0.0, 2.53125], [-0.84, -1.5, 2.4], [-1.5, -0.84, 2.4], [-1.5, 0.0, 2.4],
    [-1.4, 0.784, 2.4], [-0.784, 1.4, 2.4], [0.0, 1.4, 2.4], [-1.3375, 0.749, 2.53125],
    [-0.749, 1.3375, 2.53125], [0.0, 1.3375, 2.53125], [-1.4375, 0.805, 2.53125], [-0.805, 1.4375, 2.53125],
    [0.0, 1.4375, 2.53125], [-1.5, 0.84, 2.4], [-0.84, 1.5, 2.4], [0.0, 1.5, 2.4],
    [0.784, 1.4, 2.4], [1.4, 0.784, 2.4], [0.749, 1.3375, 2.53125], [1.3375, 0.749, 2.53125],
    [0.805, 1.4375, 2.53125], [1.4375, 0.805, 2.53125], [0.84, 1.5, 2.4], [1.5, 0.84, 2.4],
    [1.75, 0.0, 1.875], [1.75, -0.98, 1.875], [0.98, -1.75, 1.875], [0.0, -1.75, 1.875],
    [2.0, 0.0, 1.35], [2.0, -1.12, 1.35], [1.12, -2.0, 1.35], [0.0, -2.0, 1.35],
    [2.0, 0.0, 0.9], [2.0, -1.12, 0.9], [1.12, -2.0, 0.9], [0.0, -2.0, 0.9],
    [-0.98, -1.75, 1.875], [-1.75, -0.98, 1.875], [-1.75, 0.0, 1.875], [-1.12, -2.0, 1.35],
    [-2.0, -1.12, 1.35], [-2.0, 0.0, 1.35], [-1.12, -2.0, 0.9], [-2.0, -1.12, 0.9],
    [-2.0, 0.0, 0.9], [-1.75, 0.98, 1.875], [-0.98, 1.75, 1.875], [0.0, 1.75, 1.875],
    [-2.0, 1.12, 1.35], [-1.12, 2.0, 1.35], [0.0, 2.0, 1.35], [-2.0, 1.12, 0.9],
    [-1.12, 2.0, 0.9], [0.0, 2.0, 0.9], [0.98, 1.75, 1.875], [1.75, 0.98, 1.875],
    [1.12, 2.0, 1.35], [2.0, 1.12, 1.35], [1.12, 2.0, 0.9], [2.0, 1.12, 0.9],
    [2.0, 0.0, 0.45], [2.0, -1.12, 0.45], [1.12, -2.0, 0.45], [0.0, -2.0, 0.45],
    [1.5, 0.0, 0.225], [1.5, -0.84, 0.225], [0.84, -1.5, 0.225], [0.0, -1.5, 0.225],
    [1.5, 0.0, 0.15], [1.5, -0.84, 0.15], [0.84, -1.5, 0.15], [0.0, -1.5, 0.15],
    [-1.12, -2.0, 0.45], [-2.0, -1.12, 0.45], [-2.0, 0.0, 0.45], [-0.84, -1.5, 0.225],
    [-1.5, -0.84, 0.225], [-1.5, 0.0, 0.225], [-0.84, -1.5, 0.15], [-1.5, -0.84, 0.15],
    [-1.5, 0.0, 0.15], [-2.0, 1.12, 0.45], [-1.12, 2.0, 0.45], [0.0, 2.0, 0.45],
    [-1.5, 0.84, 0.225], [-0.84, 1.5, 0.225], [0.0, 1.5, 0.225], [-1.5, 0.84, 0.15],
    [-0.84, 1.5, 0.15], [0.0, 1.5, 0.15], [1.12, 2.0, 0.45], [2.0, 1.12, 0.45],
    [0.84, 1.5, 0.225], [1.5, 0.84, 0.225], [0.84, 1.5, 0.15], [1.5, 0.84, 0.15],
    [-1.6, 0.0, 2.025], [-1.6, -0.3, 2.025], [-1.5, -0.3, 2.25], [-1.5, 0.0, 2.25],
    [-2.3, 0.0, 2.025], [-2.3, -0.3, 2.025], [-2.5, -0.3, 2.25], [-2.5, 0.0, 2.25],
    [-2.7, 0.0, 2.025], [-2.7, -0.3, 2.025], [-3.0, -0.3, 2.25], [-3.0, 0.0, 2.25],
    [-2.7, 0.0, 1.8], [-2.7, -0.3, 1.8], [-3.0, -0.3, 1.8], [-3.0, 0.0, 1.8],
    [-1.5, 0.3, 2.25], [-1.6, 0.3, 2.025], [-2.5, 0.3, 2.25], [-2.3, 0.3, 2.025],
    [-3.0, 0.3, 2.25], [-2.7, 0.3, 2.025], [-3.0, 0.3, 1.8], [-2.7, 0.3, 1.8],
    [-2.7, 0.0, 1.575], [-2.7, -0.3, 1.575], [-3.0, -0.3, 1.35], [-3.0, 0.0, 1.35],
    [-2.5, 0.0, 1.125], [-2.5, -0.3, 1.125], [-2.65, -0.3, 0.9375], [-2.65, 0.0, 0.9375],
    [-2.0, -0.3, 0.9], [-1.9, -0.3, 0.6], [-1.9, 0.0, 0.6], [-3.0, 0.3, 1.35],
    [-2.7, 0.3, 1.575], [-2.65, 0.3, 0.9375], [-2.5, 0.3, 1.125], [-1.9, 0.3, 0.6],
    [-2.0, 0.3, 0.9], [1.7, 0.0, 1.425], [1.7, -0.66, 1.425], [1.7, -0.66, 0.6],
    [1.7, 0.0, 0.6], [2.6, 0.0, 1.425], [2.6, -0.66, 1.425], [3.1, -0.66, 0.825],
    [3.1, 0.0, 0.825], [2.3, 0.0, 2.1], [2.3, -0.25, 2.1], [2.4, -0.25, 2.025],
    [2.4, 0.0, 2.025], [2.7, 0.0, 2.4], [2.7, -0.25, 2.4], [3.3, -0.25, 2.4],
    [3.3, 0.0, 2.4], [1.7, 0.66, 0.6], [1.7, 0.66, 1.425], [3.1, 0.66, 0.825],
    [2.6, 0.66, 1.425], [2.4, 0.25, 2.025], [2.3, 0.25, 2.1], [3.3, 0.25, 2.4],
    [2.7, 0.25, 2.4], [2.8, 0.0, 2.475], [2.8, -0.25, 2.475], [3.525, -0.25, 2.49375],
    [3.525, 0.0, 2.49375], [2.9, 0.0, 2.475], [2.9, -0.15, 2.475], [3.45, -0.15, 2.5125],
    [3.45, 0.0, 2.5125], [2.8, 0.0, 2.4], [2.8, -0.15, 2.4], [3.2, -0.15, 2.4],
    [3.2, 0.0, 2.4], [3.525, 0.25, 2.49375], [2.8, 0.25, 2.475], [3.45, 0.15, 2.5125],
    [2.9, 0.15, 2.475], [3.2, 0.15, 2.4], [2.8, 0.15, 2.4], [0.0, 0.0, 3.15],
    [0.0, -0.002, 3.15], [0.002, 0.0, 3.15], [0.8, 0.0, 3.15], [0.8, -0.45, 3.15],
    [0.45, -0.8, 3.15], [0.0, -0.8, 3.15], [0.0, 0.0, 2.85], [0.2, 0.0, 2.7],
    [0.2, -0.112, 2.7], [0.112, -0.2, 2.7], [0.0, -0.2, 2.7], [-0.002, 0.0, 3.15],
    [-0.45, -0.8, 3.15], [-0.8, -0.45, 3.15], [-0.8, 0.0, 3.15], [-0.112, -0.2, 2.7],
    [-0.2, -0.112, 2.7], [-0.2, 0.0, 2.7], [0.0, 0.002, 3.15], [-0.8, 0.45, 3.15],
    [-0.45, 0.8, 3.15], [0.0, 0.8, 3.15], [-0.2, 0.112, 2.7], [-0.112, 0.2, 2.7],
    [0.0, 0.2, 2.7], [0.45, 0.8, 3.15], [0.8, 0.45, 3.15], [0.112, 0.2, 2.7],
    [0.2, 0.112, 2.7], [0.4, 0.0, 2.55], [0.4, -0.224, 2.55], [0.224, -0.4, 2.55],
    [0.0, -0.4, 2.55], [1.3, 0.0, 2.55], [1.3, -0.728, 2.55], [0.728, -1.3, 2.55],
    [0.0, -1.3, 2.55], [1.3, 0.0, 2.4], [1.3, -0.728, 2.4], [0.728, -1.3, 2.4],
    [0.0, -1.3, 2.4], [-0.224, -0.4, 2.55], [-0.4, -0.224, 2.55], [-0.4, 0.0, 2.55],
    [-0.728, -1.3, 2.55], [-1.3, -0.728, 2.55], [-1.3, 0.0, 2.55], [-0.728, -1.3, 2.4],
    [-1.3, -0.728, 2.4], [-1.3, 0.0, 2.4], [-0.4, 0.224, 2.55], [-0.224, 0.4, 2.55],
    [0.0, 0.4, 2.55], [-1.3, 0.728, 2.55], [-0.728, 1.3, 2.55], [0.0, 1.3, 2.55],
    [-1.3, 0.728, 2.4], [-0.728, 1.3, 2.4], [0.0, 1.3, 2.4], [0.224, 0.4, 2.55],
    [0.4, 0.224, 2.55], [0.728, 1.3, 2.55], [1.3, 0.728, 2.55], [0.728, 1.3, 2.4],
    [1.3, 0.728, 2.4], [0.0, 0.0, 0.0], [1.5, 0.0, 0.15], [1.5, 0.84, 0.15],
    [0.84, 1.5, 0.15], [0.0, 1.5, 0.15], [1.5, 0.0, 0.075], [1.5, 0.84, 0.075],
    [0.84, 1.5, 0.075], [0.0, 1.5, 0.075], [1.425, 0.0, 0.0], [1.425, 0.798, 0.0],
    [0.798, 1.425, 0.0], [0.0, 1.425, 0.0], [-0.84, 1.5, 0.15], [-1.5, 0.84, 0.15],
    [-1.5, 0.0, 0.15], [-0.84, 1.5, 0.075], [-1.5, 0.84, 0.075], [-1.5, 0.0, 0.075],
    [-0.798, 1.425, 0.0], [-1.425, 0.798, 0.0], [-1.425, 0.0, 0.0], [-1.5, -0.84, 0.15],
    [-0.84, -1.5, 0.15], [0.0, -1.5, 0.15], [-1.5, -0.84, 0.075], [-0.84, -1.5, 0.075],
    [0.0, -1.5, 0.075], [-1.425, -0.798, 0.0], [-0.798, -1.425, 0.0], [0.0, -1.425, 0.0],
    [0.84, -1.5, 0.15], [1.5, -0.84, 0.15], [0.84, -1.5, 0.075], [1.5, -0.84, 0.075],
    [0.798, -1.425, 0.0], [1.425, -0.798, 0.0],
];

/// The 32 bicubic Bezier patches: 16 control points each (1-based, as published), in RIB's
/// order (u fastest).
#[rustfmt::skip]
const PATCHES: [[u16; 16]; 32] = [
    // rim
    [1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16],
    [4, 17, 18, 19, 8, 20, 21, 22, 12, 23, 24, 25, 16, 26, 27, 28],
    [19, 29, 30, 31, 22, 32, 33, 34, 25, 35, 36, 37, 28, 38, 39, 40],
    [31, 41, 42, 1, 34, 43, 44, 5, 37, 45, 46, 9, 40, 47, 48, 13],
    // upper body
    [13, 14, 15, 16, 49, 50, 51, 52, 53, 54, 55, 56, 57, 58, 59, 60],
    [16, 26, 27, 28, 52, 61, 62, 63, 56, 64, 65, 66, 60, 67, 68, 69],
    [28, 38, 39, 40, 63, 70, 71, 72, 66, 73, 74, 75, 69, 76, 77, 78],
    [40, 47, 48, 13, 72, 79, 80, 49, 75, 81, 82, 53, 78, 83, 84, 57],
    // lower body
    [57, 58, 59, 60, 85, 86, 87, 88, 89, 90, 91, 92, 93, 94, 95, 96],
    [60, 67, 68, 69, 88, 97, 98, 99, 92, 100, 101, 102, 96, 103, 104, 105],
    [69, 76, 77, 78, 99, 106, 107, 108, 102, 109, 110, 111, 105, 112, 113, 114],
    [78, 83, 84, 57, 108, 115, 116, 85, 111, 117, 118, 89, 114, 119, 120, 93],
    // handle
    [121, 122, 123, 124, 125, 126, 127, 128, 129, 130, 131, 132, 133, 134, 135, 136],
    [124, 137, 138, 121, 128, 139, 140, 125, 132, 141, 142, 129, 136, 143, 144, 133],
    [133, 134, 135, 136, 145, 146, 147, 148, 149, 150, 151, 152, 69, 153, 154, 155],
    [136, 143, 144, 133, 148, 156, 157, 145, 152, 158, 159, 149, 155, 160, 161, 69],
    // spout
    [162, 163, 164, 165, 166, 167, 168, 169, 170, 171, 172, 173, 174, 175, 176, 177],
    [165, 178, 179, 162, 169, 180, 181, 166, 173, 182, 183, 170, 177, 184, 185, 174],
    [174, 175, 176, 177, 186, 187, 188, 189, 190, 191, 192, 193, 194, 195, 196, 197],
    [177, 184, 185, 174, 189, 198, 199, 186, 193, 200, 201, 190, 197, 202, 203, 194],
    // lid knob
    [204, 204, 204, 204, 207, 208, 209, 210, 211, 211, 211, 211, 212, 213, 214, 215],
    [204, 204, 204, 204, 210, 217, 218, 219, 211, 211, 211, 211, 215, 220, 221, 222],
    [204, 204, 204, 204, 219, 224, 225, 226, 211, 211, 211, 211, 222, 227, 228, 229],
    [204, 204, 204, 204, 226, 230, 231, 207, 211, 211, 211, 211, 229, 232, 233, 212],
    // lid
    [212, 213, 214, 215, 234, 235, 236, 237, 238, 239, 240, 241, 242, 243, 244, 245],
    [215, 220, 221, 222, 237, 246, 247, 248, 241, 249, 250, 251, 245, 252, 253, 254],
    [222, 227, 228, 229, 248, 255, 256, 257, 251, 258, 259, 260, 254, 261, 262, 263],
    [229, 232, 233, 212, 257, 264, 265, 234, 260, 266, 267, 238, 263, 268, 269, 242],
    // bottom
    [270, 270, 270, 270, 279, 280, 281, 282, 275, 276, 277, 278, 271, 272, 273, 274],
    [270, 270, 270, 270, 282, 289, 290, 291, 278, 286, 287, 288, 274, 283, 284, 285],
    [270, 270, 270, 270, 291, 298, 299, 300, 288, 295, 296, 297, 285, 292, 293, 294],
    [270, 270, 270, 270, 300, 305, 306, 279, 297, 303, 304, 275, 294, 301, 302, 271],
];

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::quadric::Tessellation;
    use crate::rib::{mesh_from_request, mesh_from_request_with, parse_str, request_triangles};
    use glam::Vec3;

    fn teapot(options: &MeshOptions) -> Mesh {
        let parse = parse_str(r#"Geometry "teapot""#, "t.rib");
        let mut diagnostics = Vec::new();
        let mesh = mesh_from_request_with(&parse.requests[0], options, &mut diagnostics).expect("a teapot");
        assert!(diagnostics.is_empty(), "{diagnostics:?}");
        assert!(request_triangles(&parse.requests[0], options) >= mesh.triangle_count());
        mesh
    }

    #[test]
    fn the_data_is_newells() {
        assert!(PATCHES.iter().flatten().all(|&i| (1..=VERTICES.len()).contains(&usize::from(i))));
        // The pot is symmetric about y = 0: every point has its mirror image.
        for v in VERTICES {
            assert!(VERTICES.iter().any(|w| w[0] == v[0] && w[1] == -v[1] && w[2] == v[2]), "{v:?}");
        }
    }

    /// 32 patches of 8 x 8 cells, less the triangles of the rows that collapse at the knob's top and
    /// the bottom's middle; on the documented box; normals out of the pot.
    #[test]
    fn the_teapot_is_32_patches_in_its_box() {
        let mesh = teapot(&MeshOptions::default());
        assert_eq!(mesh.triangle_count(), 32 * 2 * 64 - 8 * 8);
        let normals = mesh.normals.as_ref().expect("normals");
        assert!(mesh.positions.iter().chain(normals).all(|v| v.is_finite()));
        assert!(normals.iter().all(|n| (n.length() - 1.0).abs() < 1e-5));
        let (lo, hi) =
            mesh.positions.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &p| (lo.min(p), hi.max(p)));
        let (box_lo, box_hi) = (Vec3::new(-3.0, -2.0, 0.0), Vec3::new(3.4332, 2.0, 3.15));
        assert!(lo.distance(box_lo) < 1e-3 && hi.distance(box_hi) < 1e-3, "{lo} {hi}");
        // Patch by patch (81 vertices each): the body's normals point away from the axis, the
        // bottom's down and out, the lid's up and out.
        let per_patch = 81;
        for (k, (points, normals)) in mesh.positions.chunks(per_patch).zip(normals.chunks(per_patch)).enumerate() {
            for (p, n) in points.iter().zip(normals) {
                let outward = match k {
                    4..12 => n.dot(Vec3::new(p.x, p.y, 0.0)) > 0.0,
                    // The lid's edge is a vertical step.
                    24..28 => n.z > -1e-5 && n.dot(Vec3::new(p.x, p.y, 0.0)) > -1e-5,
                    // The bottom rounds into the body.
                    28..32 => n.z < 1e-5 && n.dot(Vec3::new(p.x, p.y, 0.0)) > -1e-5,
                    _ => true,
                };
                assert!(outward, "patch {k}: normal {n} at {p}");
            }
        }
        // The tessellation follows the options, and the current basis does not matter.
        let options = MeshOptions {
            tessellation: Some(Tessellation { u_segments: 2, v_segments: 2 }),
            u_basis: Basis::Named("b-spline".into()),
            u_step: 1,
            ..MeshOptions::default()
        };
        let coarse = teapot(&options);
        assert_eq!(coarse.triangle_count(), 32 * 8 - 8 * 2);
        assert_eq!(coarse.positions[0], mesh.positions[0]);
    }

    #[test]
    fn other_geometry_names_and_surface_data_are_reported() {
        let parse =
            parse_str("Geometry \"bunny\"\nGeometry \"teapot\" \"Cs\" [1 0 0] \"constant float Kd\" 1", "g.rib");
        let mut diagnostics = Vec::new();
        assert!(mesh_from_request(&parse.requests[0], &mut diagnostics).is_none());
        assert!(
            diagnostics[0].to_string().starts_with("g.rib:1:1: error: unknown Geometry name \"bunny\""),
            "{diagnostics:?}"
        );
        let mut diagnostics = Vec::new();
        assert!(mesh_from_request(&parse.requests[1], &mut diagnostics).is_some());
        assert_eq!(diagnostics.len(), 1, "{diagnostics:?}");
        assert!(diagnostics[0].message.contains("\"Cs\" (varying color) is dropped"), "{diagnostics:?}");
    }
}
