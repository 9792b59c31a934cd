//! A parsed AFF scene onto the API ([`Context`]), and its playback: [`BartScene::set_time`] moves
//! what the keyframes move, so a frame rebuilds only the top-level BVH (and the BVHs of animated
//! triangles).
//!
//! Geometry: every node is either animated (`x NAME`) or static (`xs`, the root). The geometry
//! under an animated node, down to the next animated node, is rigid in that node's space: it is
//! baked (static transforms applied to the vertices) into one object per material and texture,
//! with its own BVH, and instanced once with the node's world transform, which
//! [`BartScene::set_time`] updates with [`Context::set_instance_transform`]. The geometry outside
//! every animated node is the static world: one object per material and texture, never touched
//! again. Spheres and cones are tessellated (`geometry/quadric.rs`). Animated triangles (`tpa`)
//! move their corners, so they are objects of their own, redefined every frame (linear
//! interpolation between their keys). A node hidden by a visibility track, or whose transform
//! degenerates (a scale key through zero), has its instances removed until it is back.
//!
//! Materials (NFF's ambient, diffuse and specular colours, Phong exponent, transmittance T and
//! index of refraction) become library shaders:
//! - refractive (T > 0 and index > 1): `glass` (`eta` the index, `Kt` = T; the Fresnel terms
//!   split reflection and refraction, the diffuse colour is not used);
//! - reflective (untextured, opaque, every specular component at least 0.5, the metals and
//!   chrome of the scenes): `mirror` with the diffuse colour as `Cs`, the specular colour
//!   tinting both the highlight and the traced reflection, as NFF's `Ks` weighs the reflected
//!   ray. Weaker specular colours are highlights only: NFF would trace a reflection there too,
//!   but it adds little and costs a ray per hit;
//! - everything else: `material` (diffuse colour, specular colour with Phong exponent
//!   `128 * shininess` = the file's, `transparency` = T and `Os` = 1 - T for shadows, the
//!   texture). NFF's ambient term is ambient colour times ambient light, both constant, which
//!   `material` gets exactly as its `emissivecolor`; on textured surfaces it is
//!   `ambientintensity` times the (textured) diffuse colour instead, scaled to the ambient
//!   colour's mean, so that the texture shows in the shade.
//!
//! Highlights: `specular()`'s `roughness` is `1 / (4 * shine)` (a Blinn half-vector exponent is
//! about four times the Phong one).
//!
//! Lights: NFF lights do not fall off with distance, so each `l` becomes `nfflight`, a point light
//! without falloff compiled here (the library's `pointlight` divides by the squared distance).
//! The `am` colour is an `ambientlight`; without `am` the ambient light is white, so that `fm`
//! ambient colours show (the museum has none). Lights are placed where their nodes are at the
//! start of the animation.
//!
//! Camera: the keyframes named `camera`, when there are any, place it (translation and rotation;
//! the camera looks down its -z axis with +y up, as in OpenGL); otherwise the viewpoint's
//! `from`/`at`/`up`. The viewpoint's `angle` is the vertical field of view and `hither` the near
//! plane.
//!
//! Textures are looked for next to the file naming them, then in `../TextureFiles/` from there
//! and from the scene file (the BART layout). A missing texture is one warning, and its surfaces
//! are drawn untextured. NFF renderers (and BART's OpenGL viewer) shade display values: colours
//! and texels multiply as stored and the frame is shown as computed. So textures are given to the
//! context (`tex_image_2d`) with their stored values, not sRGB-decoded as the texture cache would,
//! and frames are written as computed (the project's default, no encoding).

use super::aff::{self, AffError, AffScene, AnimationParams, Geometry, Location, Material, NodeTransform, TriangleKey};
use super::animation::Keyframes;
use crate::api::{ApiError, Context, InstanceId, ObjectId, ShaderId};
use crate::geometry::quadric::Quadric;
use crate::geometry::{Mesh, MeshError};
use crate::render::CameraSetup;
use crate::shading::ParamValue;
use glam::{Affine3A, Mat3A, Quat, Vec2, Vec3, Vec3A};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Why a BART scene could not be loaded or played.
#[derive(Debug, thiserror::Error)]
pub enum BartError {
    #[error(transparent)]
    Aff(#[from] AffError),
    #[error(transparent)]
    Api(#[from] ApiError),
    #[error("{at}: invalid mesh")]
    Mesh { at: Location, source: MeshError },
}

/// The light of NFF's `l`: a point light whose light does not fall off with distance.
pub const NFF_LIGHT_SOURCE: &str = r#"
/* NFF's point light: the same light at every distance (no inverse-square falloff). */
light nfflight(color lightcolor = 1; point from = point "shader" (0, 0, 0);)
{
    illuminate(from)
        Cl = lightcolor;
}
"#;

/// Specular colours at least this strong in every channel make an untextured opaque material a
/// traced mirror.
pub const REFLECTIVE_SPECULAR: f32 = 0.5;

/// What was loaded.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Summary {
    /// Triangles rendered (spheres and cones tessellated), animated triangles included.
    pub triangles: usize,
    /// Triangles under an animated node (moved by instance transforms).
    pub moving_triangles: usize,
    /// Triangles whose corners move (`tpa`), rebuilt every frame.
    pub morphing_triangles: usize,
    /// Nodes animated by keyframes (`x NAME` with keyframes of that name).
    pub animated_nodes: usize,
    /// Objects (each with its own BVH, instanced once: one per rigid part of the scene), their
    /// parts (one per material and texture), and the parts shaded as traced mirrors and as glass.
    pub objects: usize,
    pub parts: usize,
    pub mirror_parts: usize,
    pub glass_parts: usize,
    /// Instances whose transform changes over time.
    pub moving_instances: usize,
    pub lights: usize,
    /// Distinct textures found, and those missing.
    pub textures: usize,
    pub missing_textures: usize,
    /// Whether keyframes named `camera` move the camera.
    pub animated_camera: bool,
}

#[derive(Clone, Copy, Debug)]
enum Local {
    Static(Affine3A),
    /// Index into the keyframes, `None` when no keyframes have the node's name (it stays still).
    Animated(Option<usize>),
}

#[derive(Clone, Copy, Debug)]
struct NodePlan {
    parent: Option<usize>,
    local: Local,
}

/// The shader and values of a material.
#[derive(Clone, Debug)]
struct Look {
    shader: ShaderId,
    params: Vec<(&'static str, ParamValue)>,
    color: [f32; 3],
    opacity: [f32; 3],
}

/// One object placed by one node: its instance, while shown.
#[derive(Clone, Copy, Debug)]
struct Placement {
    object: ObjectId,
    node: usize,
    instance: Option<InstanceId>,
}

/// Which object a shape's triangles go into: its rigid part (the nearest animated node, or the
/// root), its material and its texture.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
struct GroupKey {
    node: usize,
    material: usize,
    texture: Option<usize>,
}

impl Summary {
    /// Counts a part shaded by `look`.
    fn count_part(&mut self, look: &Look, shaders: &Shaders) {
        self.parts += 1;
        self.mirror_parts += usize::from(look.shader == shaders.mirror);
        self.glass_parts += usize::from(look.shader == shaders.glass);
    }
}

/// One animated triangle's keys, in its node's space.
type Morphing = Vec<TriangleKey>;

/// Triangles whose corners are keyed (`tpa`), under one node with one material.
#[derive(Clone, Debug)]
struct Morph {
    object: ObjectId,
    look: Look,
    triangles: Vec<Morphing>,
}

/// A BART scene in a [`Context`], ready to be played.
#[derive(Clone, Debug)]
pub struct BartScene {
    pub path: PathBuf,
    /// The animation's span and frame count (from the `a` line, or the keyframes' span at 30
    /// frames per second when there is none).
    pub animation: AnimationParams,
    pub summary: Summary,
    /// What could not be honoured, each with its location.
    pub warnings: Vec<String>,
    nodes: Vec<NodePlan>,
    keyframes: Vec<Keyframes>,
    camera_track: Option<usize>,
    viewpoint: aff::Viewpoint,
    placements: Vec<Placement>,
    morphs: Vec<Morph>,
}

/// The library and embedded shaders the materials and lights use.
struct Shaders {
    material: ShaderId,
    mirror: ShaderId,
    glass: ShaderId,
}

/// Loads the AFF file at `path` into `rt` (image size from its viewpoint, background, lights,
/// objects), placed at the animation's start time.
pub fn load_file(rt: &mut Context, path: &Path) -> Result<BartScene, BartError> {
    let scene = aff::parse_file(path)?;
    load_parsed(rt, scene, path)
}

/// Loads a parsed scene; `path` is the scene file (it anchors the texture search).
pub fn load_parsed(rt: &mut Context, mut scene: AffScene, path: &Path) -> Result<BartScene, BartError> {
    if scene.nodes.is_empty() {
        // The reader always makes the root; a hand-made scene may not.
        let at = aff::Location { file: std::sync::Arc::from(path), line: 0, column: 0 };
        scene.nodes.push(aff::Node { parent: None, transform: NodeTransform::Static(Affine3A::IDENTITY), at });
    }
    let mut warnings = scene.warnings.clone();
    let mut summary = Summary::default();
    let shaders = Shaders {
        material: rt.find_shader("material")?,
        mirror: rt.find_shader("mirror")?,
        glass: rt.find_shader("glass")?,
    };

    // Nodes and their keyframes.
    let mut warned_names = std::collections::HashSet::new();
    let nodes: Vec<NodePlan> = scene
        .nodes
        .iter()
        .map(|n| {
            let local = match &n.transform {
                NodeTransform::Static(m) => Local::Static(*m),
                NodeTransform::Animated(name) => {
                    let k = scene.keyframes.iter().position(|k| &k.name == name);
                    if k.is_none() && warned_names.insert(name.clone()) {
                        warnings
                            .push(format!("{}: warning: no keyframes are named `{name}`; the node stays still", n.at));
                    }
                    Local::Animated(k)
                }
            };
            NodePlan { parent: n.parent, local }
        })
        .enumerate()
        // The reader lists parents first; a hand-made scene that does not is read as if the node
        // hung from the root.
        .map(|(i, n)| NodePlan { parent: n.parent.filter(|&p| p < i), ..n })
        .collect();
    summary.animated_nodes = nodes.iter().filter(|n| matches!(n.local, Local::Animated(Some(_)))).count();
    let camera_track = scene.keyframes.iter().position(|k| k.name == "camera");
    summary.animated_camera = camera_track.is_some();
    let animation = scene.animation.unwrap_or_else(|| {
        let range = scene.keyframes.iter().filter_map(Keyframes::time_range).reduce(|a, b| (a.0.min(b.0), a.1.max(b.1)));
        let (start, end) = range.unwrap_or((0.0, 0.0));
        let frames = ((end - start) * 30.0).ceil().max(1.0) as u32;
        if range.is_some() {
            warnings.push(format!(
                "{}: warning: no animation line `a`; playing the keyframes' span {start}..{end} at 30 frames per second",
                path.display()
            ));
        }
        AnimationParams { start, end, frames }
    });

    let mut bart = BartScene {
        path: path.to_path_buf(),
        animation,
        summary,
        warnings: Vec::new(),
        nodes,
        keyframes: scene.keyframes.clone(),
        camera_track,
        viewpoint: scene.viewpoint.clone().unwrap_or_default(),
        placements: Vec::new(),
        morphs: Vec::new(),
    };

    // Where geometry is rigid: each node's nearest animated node (itself included; the root
    // otherwise) and the static transform from there.
    let mut anchor = vec![0usize; bart.nodes.len()];
    let mut from_anchor = vec![Affine3A::IDENTITY; bart.nodes.len()];
    for (i, n) in bart.nodes.iter().enumerate() {
        // A node named after keyframes that do not exist stays still: static, the identity.
        let local = match n.local {
            Local::Animated(Some(_)) => {
                anchor[i] = i;
                continue;
            }
            Local::Animated(None) => Affine3A::IDENTITY,
            Local::Static(m) => m,
        };
        match n.parent {
            Some(p) => {
                anchor[i] = anchor[p];
                from_anchor[i] = from_anchor[p] * local;
            }
            None => from_anchor[i] = local,
        }
    }

    // Options and lights.
    if let Some((w, h)) = bart.viewpoint.resolution.filter(|(w, h)| *w > 0 && *h > 0) {
        rt.options.width = w;
        rt.options.height = h;
    }
    if let Some(b) = scene.background {
        rt.options.background = b.to_array();
    }
    let (start_world, _) = bart.world_transforms(animation.start);
    let light = rt.compile_shader("nfflight", NFF_LIGHT_SOURCE)?;
    let ambient_light = rt.find_shader("ambientlight")?;
    let ambient = scene.ambient.unwrap_or(Vec3::ONE);
    rt.push_matrix();
    rt.load_identity();
    rt.light_source(ambient_light, &[("lightcolor", ParamValue::Color(ambient.to_array()))])?;
    let mut warned_moving_light = false;
    for l in &scene.lights {
        let node = if l.node < anchor.len() { l.node } else { 0 };
        if anchor[node] != 0 && !warned_moving_light {
            warned_moving_light = true;
            warnings.push(format!(
                "{}: warning: lights in animated nodes stay where they are at the start of the animation",
                l.at
            ));
        }
        let from = start_world[node].transform_point3(l.position);
        rt.light_source(
            light,
            &[("from", ParamValue::Point(from.to_array())), ("lightcolor", ParamValue::Color(l.color.to_array()))],
        )?;
    }
    rt.pop_matrix()?;
    bart.summary.lights = scene.lights.len();

    // Textures: each (directory, name) resolved once.
    let scene_dir = path.parent().unwrap_or(Path::new("")).to_path_buf();
    let mut texture_files: Vec<PathBuf> = Vec::new();
    let mut resolved: HashMap<(PathBuf, String), Option<usize>> = HashMap::new();
    let mut missing: std::collections::HashSet<String> = Default::default();
    let mut texture_of = |t: &aff::TextureRef, warnings: &mut Vec<String>| -> Option<usize> {
        let key = (t.dir.to_path_buf(), t.name.clone());
        if let Some(r) = resolved.get(&key) {
            return *r;
        }
        let candidates = [
            t.dir.join(&t.name),
            t.dir.join("..").join("TextureFiles").join(&t.name),
            scene_dir.join("..").join("TextureFiles").join(&t.name),
        ];
        let found = candidates.iter().find(|p| p.is_file()).map(|p| {
            let i = texture_files.iter().position(|f| f == p).unwrap_or(texture_files.len());
            if i == texture_files.len() {
                texture_files.push(p.clone());
            }
            i
        });
        if found.is_none() && missing.insert(t.name.clone()) {
            let looked: Vec<String> = candidates.iter().map(|p| p.display().to_string()).collect();
            warnings.push(format!(
                "{}: warning: texture {} not found (looked for {}); its surfaces are drawn untextured",
                t.at,
                t.name,
                looked.join(", ")
            ));
        }
        resolved.insert(key, found);
        found
    };

    // Geometry grouped by (anchor node, material, texture), baked into the anchor's space.
    let mut groups: Vec<(GroupKey, MeshBuilder)> = Vec::new();
    let mut group_index: HashMap<GroupKey, usize> = HashMap::new();
    let mut morph_groups: Vec<(GroupKey, Vec<Morphing>)> = Vec::new();
    let mut morph_index: HashMap<GroupKey, usize> = HashMap::new();
    for shape in &scene.shapes {
        // Shapes of nodes that do not exist (only in hand-made scenes) are on the root.
        let shape_node = if shape.node < anchor.len() { shape.node } else { 0 };
        let node = anchor[shape_node];
        let xf = from_anchor[shape_node];
        if let Geometry::AnimatedTriangle(keys) = &shape.geometry {
            if keys.is_empty() {
                continue;
            }
            let key = GroupKey { node, material: shape.material, texture: None };
            let i = *morph_index.entry(key).or_insert_with(|| {
                morph_groups.push((key, Vec::new()));
                morph_groups.len() - 1
            });
            let baked = keys
                .iter()
                .map(|k| TriangleKey {
                    time: k.time,
                    positions: k.positions.map(|p| xf.transform_point3(p)),
                    normals: k.normals.map(|n| normal_transform(&xf) * n),
                })
                .collect();
            morph_groups[i].1.push(baked);
            continue;
        }
        let texture = shape.texture.as_ref().and_then(|t| texture_of(t, &mut warnings));
        let key = GroupKey { node, material: shape.material, texture };
        let i = *group_index.entry(key).or_insert_with(|| {
            groups.push((key, MeshBuilder::default()));
            groups.len() - 1
        });
        let builder = &mut groups[i].1;
        let bad = |source: MeshError| BartError::Mesh { at: shape.at.clone(), source };
        match &shape.geometry {
            Geometry::Triangles(t) => {
                builder.add(&xf, &t.positions, t.normals.as_deref(), t.uvs.as_deref(), &t.triangles)
            }
            Geometry::Sphere { center, radius } => {
                let r = radius.abs();
                if r > 0.0 {
                    let q = Quadric::Sphere { radius: r, zmin: -r, zmax: r, thetamax: 360.0 };
                    let m = q.tessellate(q.default_tessellation()).map_err(bad)?;
                    builder.add_mesh(&(xf * Affine3A::from_translation(*center)), &m);
                }
            }
            Geometry::Cone { base, base_radius, apex, apex_radius } => {
                let axis = *apex - *base;
                let height = axis.length();
                if height > 0.0 && height.is_finite() {
                    let q = Quadric::Hyperboloid {
                        point1: Vec3::new(base_radius.abs(), 0.0, 0.0),
                        point2: Vec3::new(apex_radius.abs(), 0.0, height),
                        thetamax: 360.0,
                    };
                    let m = q.tessellate(q.default_tessellation()).map_err(bad)?;
                    let frame =
                        Affine3A::from_rotation_translation(Quat::from_rotation_arc(Vec3::Z, axis / height), *base);
                    builder.add_mesh(&(xf * frame), &m);
                }
            }
            Geometry::AnimatedTriangle(_) => {}
        }
    }
    bart.summary.textures = texture_files.len();
    bart.summary.missing_textures = missing.len();

    // Textures with their stored values (see the module documentation), named by their paths.
    let mut texture_names: Vec<Option<String>> = Vec::with_capacity(texture_files.len());
    for file in &texture_files {
        let name = file.display().to_string();
        match load_texture(rt, file, &name) {
            Ok(()) => texture_names.push(Some(name)),
            Err(e) => {
                warnings.push(format!("warning: texture {name}: {e}; its surfaces are drawn untextured"));
                texture_names.push(None);
            }
        }
    }

    // Objects and their instances, at the start of the animation.
    let look_of = |material: usize, texture: Option<usize>| {
        let m = scene.materials.get(material).copied().unwrap_or(Material::DEFAULT);
        look(&m, texture.and_then(|t| texture_names[t].as_deref()), ambient, &shaders)
    };
    // One object per rigid part, in parts of one material and texture each: one BVH per node
    // (objects of the static city per material overlapped, and rays entered many of them).
    let mut by_node: Vec<(usize, Vec<(Look, Mesh)>)> = Vec::new();
    let mut node_index: HashMap<usize, usize> = HashMap::new();
    for (GroupKey { node, material, texture }, builder) in groups {
        if builder.triangles.is_empty() {
            continue;
        }
        let count = builder.triangles.len();
        let look = look_of(material, texture);
        bart.summary.count_part(&look, &shaders);
        bart.summary.triangles += count;
        if node != 0 {
            bart.summary.moving_triangles += count;
        }
        let i = *node_index.entry(node).or_insert_with(|| {
            by_node.push((node, Vec::new()));
            by_node.len() - 1
        });
        by_node[i].1.push((look, builder.into_mesh()));
    }
    for (node, parts) in by_node {
        let object = make_object_of_parts(rt, &parts)?;
        bart.placements.push(Placement { object, node, instance: None });
    }
    for (GroupKey { node, material, .. }, triangles) in morph_groups {
        let look = look_of(material, None);
        bart.summary.count_part(&look, &shaders);
        let mesh = morph_mesh(&triangles, animation.start);
        let object = make_object(rt, &look, &mesh)?;
        bart.summary.triangles += triangles.len();
        bart.summary.morphing_triangles += triangles.len();
        bart.morphs.push(Morph { object, look, triangles });
        bart.placements.push(Placement { object, node, instance: None });
    }
    bart.summary.objects = bart.placements.len();
    bart.summary.moving_instances = bart.placements.iter().filter(|p| p.node != 0).count();
    bart.warnings = warnings;
    // Static placements are made here once; set_time makes and moves the others.
    let (world, visible) = bart.world_transforms(animation.start);
    for p in bart.placements.iter_mut() {
        if p.node == 0 {
            place(rt, p, world[0], visible[0])?;
        }
    }
    bart.set_time(rt, animation.start)?;
    Ok(bart)
}

/// Makes the image file at `path` the texture `name`, its values as stored (8-bit values over 255,
/// no sRGB decoding).
fn load_texture(rt: &mut Context, path: &Path, name: &str) -> Result<(), String> {
    let image = crate::image_io::read_image(path).map_err(|e| e.to_string())?;
    let rgb: Vec<f32> = image.pixels.chunks_exact(4).flat_map(|p| [p[0], p[1], p[2]]).collect();
    rt.tex_image_2d(name, image.width, image.height, 3, &rgb).map_err(|e| e.to_string())
}

/// The inverse transpose of `xf`'s linear part (for normals); zero when `xf` is singular, which
/// leaves the renderer's geometric normal.
fn normal_transform(xf: &Affine3A) -> Mat3A {
    let m = xf.matrix3.inverse().transpose();
    if m.is_finite() {
        m
    } else {
        Mat3A::ZERO
    }
}

/// An object of `mesh` shaded by `look`.
fn make_object(rt: &mut Context, look: &Look, mesh: &Mesh) -> Result<ObjectId, ApiError> {
    rt.push_attributes();
    rt.load_identity();
    apply_look(rt, look)?;
    let object = rt.begin_object()?;
    rt.mesh(mesh)?;
    rt.end_object()?;
    rt.pop_attributes()?;
    Ok(object)
}

/// One object of several meshes, each a part shaded by its own look ([`Context::end_part`]).
fn make_object_of_parts(rt: &mut Context, parts: &[(Look, Mesh)]) -> Result<ObjectId, ApiError> {
    rt.push_attributes();
    rt.load_identity();
    let object = rt.begin_object()?;
    for (look, mesh) in parts {
        rt.mesh(mesh)?;
        apply_look(rt, look)?;
        rt.end_part()?;
    }
    rt.end_object()?;
    rt.pop_attributes()?;
    Ok(object)
}

fn apply_look(rt: &mut Context, look: &Look) -> Result<(), ApiError> {
    rt.bind_shader(look.shader)?;
    for (name, value) in &look.params {
        rt.parameter(name, value.clone())?;
    }
    rt.color(look.color[0], look.color[1], look.color[2]);
    rt.opacity(look.opacity[0], look.opacity[1], look.opacity[2]);
    Ok(())
}

/// The shader and values reproducing an NFF material (see the module documentation).
fn look(m: &Material, texture: Option<&str>, ambient_light: Vec3, shaders: &Shaders) -> Look {
    let mean = |v: Vec3| (v.x + v.y + v.z) / 3.0;
    let roughness = 1.0 / (4.0 * m.shine.max(1.0));
    let t = m.transmittance.clamp(0.0, 1.0);
    if t > 0.0 && m.index_of_refraction > 1.0 {
        return Look {
            shader: shaders.glass,
            params: vec![
                ("eta", ParamValue::Float(m.index_of_refraction)),
                ("Kt", ParamValue::Float(t)),
                ("Kr", ParamValue::Float(1.0)),
                ("Ks", ParamValue::Float(m.specular.max_element())),
                ("roughness", ParamValue::Float(roughness)),
            ],
            color: [1.0; 3],
            opacity: [1.0; 3],
        };
    }
    if texture.is_none() && t == 0.0 && m.specular.min_element() >= REFLECTIVE_SPECULAR {
        let ka = if mean(m.diffuse) > 0.0 { mean(m.ambient) * mean(ambient_light) / mean(m.diffuse) } else { 0.0 };
        return Look {
            shader: shaders.mirror,
            params: vec![
                ("Ka", ParamValue::Float(ka)),
                ("Kd", ParamValue::Float(1.0)),
                ("Ks", ParamValue::Float(1.0)),
                ("Kr", ParamValue::Float(1.0)),
                ("roughness", ParamValue::Float(roughness)),
                ("specularcolor", ParamValue::Color(m.specular.to_array())),
            ],
            color: m.diffuse.to_array(),
            opacity: [1.0; 3],
        };
    }
    let mut params = vec![
        ("diffusecolor", ParamValue::Color(m.diffuse.to_array())),
        ("specularcolor", ParamValue::Color(m.specular.to_array())),
        ("shininess", ParamValue::Float(m.shine.max(1.0) / 128.0)),
        ("transparency", ParamValue::Float(t)),
    ];
    match texture {
        Some(name) if mean(m.diffuse) > 0.0 => {
            // The ambient light (an ambientlight of the `am` colour) times the textured diffuse
            // colour, at the ambient colour's strength.
            params.push(("ambientintensity", ParamValue::Float(mean(m.ambient) / mean(m.diffuse))));
            params.push(("texturename", ParamValue::String(name.to_string())));
        }
        _ => {
            params.push(("ambientintensity", ParamValue::Float(0.0)));
            params.push(("emissivecolor", ParamValue::Color((m.ambient * ambient_light).to_array())));
            if let Some(name) = texture {
                params.push(("texturename", ParamValue::String(name.to_string())));
            }
        }
    }
    Look { shader: shaders.material, params, color: [1.0; 3], opacity: [1.0 - t; 3] }
}

/// Puts a placement's instance where its node is, or removes it while the node is hidden or its
/// transform cannot be inverted.
fn place(rt: &mut Context, p: &mut Placement, world: Affine3A, visible: bool) -> Result<(), ApiError> {
    let det = world.matrix3.determinant();
    let usable = visible && world.is_finite() && det.is_finite() && det.abs() > 1e-20;
    match (usable, p.instance) {
        (true, Some(id)) => rt.set_instance_transform(id, world)?,
        (true, None) => {
            rt.push_matrix();
            rt.load_matrix(world);
            let id = rt.instantiate_object(p.object);
            rt.pop_matrix()?;
            p.instance = Some(id?);
        }
        (false, Some(id)) => {
            rt.delete_instance(id)?;
            p.instance = None;
        }
        (false, None) => {}
    }
    Ok(())
}

/// The mesh of animated triangles at time `t`: each corner and normal linear between the keys
/// around `t` (held before the first key and after the last).
fn morph_mesh(triangles: &[Morphing], t: f32) -> Mesh {
    let mut positions = Vec::with_capacity(3 * triangles.len());
    let mut normals = Vec::with_capacity(3 * triangles.len());
    for keys in triangles.iter().filter(|k| !k.is_empty()) {
        let after = keys.partition_point(|k| k.time <= t);
        let (a, b, u) = match (after.checked_sub(1), keys.get(after)) {
            (Some(i), Some(next)) => {
                let span = next.time - keys[i].time;
                let u = if span > 0.0 { (t - keys[i].time) / span } else { 0.0 };
                (&keys[i], next, u)
            }
            (Some(i), None) => (&keys[i], &keys[i], 0.0),
            (None, _) => (&keys[0], &keys[0], 0.0),
        };
        for c in 0..3 {
            positions.push(a.positions[c].lerp(b.positions[c], u));
            normals.push(a.normals[c].lerp(b.normals[c], u));
        }
    }
    let triangles = (0..positions.len() as u32 / 3).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
    Mesh { positions, normals: Some(normals), uvs: None, triangles, ..Default::default() }
}

impl BartScene {
    /// The scene time of frame `frame` of the animation: `start + frame * (end - start) / frames`
    /// (a fixed rate of `frames / (end - start)` frames per second from the start).
    pub fn frame_time(&self, frame: u32) -> f32 {
        let a = self.animation;
        if a.frames == 0 {
            return a.start;
        }
        a.start + (a.end - a.start) * (frame as f32 / a.frames as f32)
    }

    /// Every node's world transform at `t`, and whether it is shown.
    fn world_transforms(&self, t: f32) -> (Vec<Affine3A>, Vec<bool>) {
        let mut world = Vec::with_capacity(self.nodes.len());
        let mut visible = Vec::with_capacity(self.nodes.len());
        for n in &self.nodes {
            let (local, shown) = match n.local {
                Local::Static(m) => (m, true),
                Local::Animated(Some(k)) => (self.keyframes[k].transform_at(t), self.keyframes[k].visible_at(t)),
                Local::Animated(None) => (Affine3A::IDENTITY, true),
            };
            // Parents come before their children, so theirs are already there.
            let (parent, parent_shown) =
                n.parent.and_then(|p| Some((*world.get(p)?, *visible.get(p)?))).unwrap_or((Affine3A::IDENTITY, true));
            world.push(parent * local);
            visible.push(parent_shown && shown);
        }
        (world, visible)
    }

    /// The camera at time `t`, for an image of `width` x `height`.
    pub fn camera_at(&self, t: f32, width: u32, height: u32) -> CameraSetup {
        let v = &self.viewpoint;
        // The angle is vertical; the renderer's field of view spans the shorter side.
        let half = (0.5 * v.angle.clamp(1e-3, 179.0)).to_radians();
        let fov = if width >= height {
            v.angle
        } else {
            2.0 * (half.tan() * width as f32 / height.max(1) as f32).atan().to_degrees()
        };
        let mut camera = match self.camera_track {
            Some(k) => {
                let k = &self.keyframes[k];
                let eye = Vec3A::from(k.translation_at(t));
                let r = k.rotation_at(t);
                CameraSetup::look_at(eye, eye + Vec3A::from(r * Vec3::NEG_Z), Vec3A::from(r * Vec3::Y), fov)
            }
            None => CameraSetup::look_at(v.from.into(), v.at.into(), v.up.into(), fov),
        };
        if v.hither > 0.0 && v.hither.is_finite() {
            camera.near = v.hither;
        }
        camera
    }

    /// Moves everything to scene time `t`: instance transforms of animated nodes, animated
    /// triangles, the camera (for the context's current image size).
    pub fn set_time(&mut self, rt: &mut Context, t: f32) -> Result<(), ApiError> {
        let (world, visible) = self.world_transforms(t);
        for p in self.placements.iter_mut().filter(|p| p.node != 0) {
            place(rt, p, world[p.node], visible[p.node])?;
        }
        for m in &self.morphs {
            let mesh = morph_mesh(&m.triangles, t);
            rt.push_attributes();
            rt.load_identity();
            apply_look(rt, &m.look)?;
            rt.redefine_object(m.object)?;
            rt.mesh(&mesh)?;
            rt.end_object()?;
            rt.pop_attributes()?;
        }
        let camera = self.camera_at(t, rt.options.width, rt.options.height);
        rt.set_camera(camera);
        Ok(())
    }
}

/// Geometry gathered for one object, in its node's space.
#[derive(Default)]
struct MeshBuilder {
    positions: Vec<Vec3>,
    normals: Vec<Vec3>,
    uvs: Vec<Vec2>,
    has_normals: bool,
    has_uvs: bool,
    triangles: Vec<[u32; 3]>,
}

impl MeshBuilder {
    /// Adds triangles placed by `xf`. Parts without normals get zero normals, which the renderer
    /// replaces by the geometric normal; parts without texture coordinates get zeros.
    fn add(
        &mut self,
        xf: &Affine3A,
        positions: &[Vec3],
        normals: Option<&[Vec3]>,
        uvs: Option<&[Vec2]>,
        triangles: &[[u32; 3]],
    ) {
        let base = self.positions.len() as u32;
        self.positions.extend(positions.iter().map(|p| xf.transform_point3(*p)));
        match normals.filter(|n| n.len() == positions.len()) {
            Some(ns) => {
                let nx = normal_transform(xf);
                self.has_normals = true;
                self.normals.extend(ns.iter().map(|n| Vec3::from(nx * Vec3A::from(*n))));
            }
            None => self.normals.resize(self.positions.len(), Vec3::ZERO),
        }
        match uvs.filter(|t| t.len() == positions.len()) {
            Some(ts) => {
                self.has_uvs = true;
                self.uvs.extend_from_slice(ts);
            }
            None => self.uvs.resize(self.positions.len(), Vec2::ZERO),
        }
        self.triangles.extend(triangles.iter().map(|t| t.map(|i| i + base)));
    }

    fn add_mesh(&mut self, xf: &Affine3A, m: &Mesh) {
        self.add(xf, &m.positions, m.normals.as_deref(), m.uvs.as_deref(), &m.triangles);
    }

    fn into_mesh(self) -> Mesh {
        Mesh {
            positions: self.positions,
            normals: self.has_normals.then_some(self.normals),
            uvs: self.has_uvs.then_some(self.uvs),
            triangles: self.triangles,
            ..Default::default()
        }
    }
}
