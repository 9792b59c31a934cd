//! VRML 97 animation shown through the [`Context`]: [`VrmlScene::advance_to`] runs the scene's
//! events ([`super::events`]) up to a time and changes what they changed.
//!
//! - a Transform's new fields move the instances of every Shape under it
//!   ([`Context::set_instance_transform`]); one that scales a shape to nothing deletes its
//!   instance, and a later one that makes it visible places a new one;
//! - a Material's, Coordinate's, Normal's or Color's new fields build the objects that use them
//!   again ([`Context::redefine_object`]), with the shader parameters and mesh they now give;
//! - a light's fields give its values again ([`Context::set_light_parameters`], `on` through
//!   [`Context::set_light`]);
//! - a Switch's `whichChoice` shows the shapes of the choice it names and hides the others' (a
//!   Switch that a ROUTE reaches has every choice placed at load, those not chosen hidden);
//! - lights under a moving Transform move with it ([`Context::set_light_transform`]: a light's
//!   space is the matrix of the Transforms above it), and Viewpoints are placed again, the bound
//!   one ([`VrmlScene::bind_viewpoint`]) moving the camera.
//!
//! [`VrmlScene::touch`] is a click on a shape: the TouchSensors of the innermost group above it
//! that has any send `isActive` (TRUE, then FALSE) and `touchTime`.

use super::events::EventValue;
use super::parse::Value;
use super::{build, NodeRef, VrmlScene};
use crate::api::{Context, InstanceId};
use crate::rib::RibDiagnostic;
use crate::scene_file::SceneFileError;
use glam::Affine3A;
use std::collections::BTreeSet;

impl VrmlScene {
    /// Whether anything in the scene runs with time (a TimeSensor routed somewhere).
    pub fn is_animated(&self) -> bool {
        self.events.is_animated()
    }

    /// Whether the user's input can change the scene: a pointing-device, proximity or visibility
    /// sensor is routed somewhere.
    pub fn senses(&self) -> bool {
        const SENSORS: [&str; 6] =
            ["TouchSensor", "PlaneSensor", "SphereSensor", "CylinderSensor", "ProximitySensor", "VisibilitySensor"];
        !self.view_nodes.is_empty()
            || self.events.sources().any(|r| {
                self.documents
                    .get(r.doc)
                    .and_then(|(_, d)| d.nodes.get(r.node.0 as usize))
                    .is_some_and(|n| SENSORS.contains(&n.type_name.as_str()))
            })
    }

    /// When the camera has moved since the last call: turns the headlight with it (VRML's
    /// headlight points where the user looks) and marks the Billboards, and the LODs whose level
    /// changes, for the animation pass. Returns whether the headlight moved.
    pub(super) fn follow_camera(&mut self, rt: &mut Context) -> Result<bool, SceneFileError> {
        let camera = rt.camera().world_from_camera;
        if self.placed_for_camera == Some(camera) {
            return Ok(false);
        }
        self.placed_for_camera = Some(camera);
        let mut moved = false;
        if let Some((light, made_for)) = self.headlight {
            let turn = camera * made_for.inverse();
            if turn.is_finite() {
                rt.set_light_transform(light, turn)?;
                moved = true;
            }
        }
        for r in self.view_nodes.clone() {
            let Some((_, doc)) = self.documents.get(r.doc) else { continue };
            if doc.node(r.node).type_name != "LOD" {
                self.events.dirty.insert(r);
                continue;
            }
            // The LOD's frame: the path of anything under it, up to it.
            let above = self
                .shapes
                .iter()
                .map(|p| &p.path)
                .chain(self.lights.iter().map(|p| &p.path))
                .find_map(|path| path.iter().position(|g| *g == r).map(|at| path[..at].to_vec()));
            let Some(above) = above else { continue };
            let level = build::lod_level_of(rt, self, r, &above);
            if self.lod_levels.insert(r, level) != Some(level) {
                self.events.dirty.insert(r);
            }
        }
        Ok(moved)
    }

    /// Runs the scene's events up to `time` (seconds; the scene loads at 0) and shows what they
    /// changed in `rt`. A time before the last one starts again from the file's values. Returns
    /// whether `rt`'s scene changed.
    pub fn advance_to(&mut self, time: f64, rt: &mut Context) -> Result<bool, SceneFileError> {
        if self.events.now().is_some_and(|last| time < last) {
            self.events.reset(&mut self.documents);
            self.reset_sensing();
        }
        if time.is_finite() {
            self.sense_camera(time, rt);
        }
        let turned = self.follow_camera(rt)?;
        self.events.advance(&mut self.documents, time);
        Ok(self.apply(rt)? | turned)
    }

    /// A click at `time` on `instance`: the enabled TouchSensors of the innermost group above its
    /// Shape that has any (the file's top level counting as a group) send `isActive` TRUE (the
    /// press), then `isActive` FALSE and `touchTime` (the release), and what that starts is shown. Returns whether `rt`'s scene changed.
    pub fn touch(&mut self, instance: InstanceId, time: f64, rt: &mut Context) -> Result<bool, SceneFileError> {
        let Some(shape) = self.shapes.iter().position(|p| p.made == instance) else { return Ok(false) };
        let placed = &self.shapes[shape];
        let doc_of_shape = placed.node.doc;
        let mut groups: Vec<Vec<NodeRef>> =
            placed.path.iter().rev().map(|g| children(&self.documents[g.doc].1, *g, "children").collect()).collect();
        groups.push(
            self.documents[doc_of_shape].1.roots.iter().map(|&node| NodeRef { doc: doc_of_shape, node }).collect(),
        );
        let time = self.events.now().map_or(time, |now| time.max(now));
        for group in groups {
            let sensors: Vec<NodeRef> = group
                .into_iter()
                .filter(|r| {
                    let node = self.documents[r.doc].1.node(r.node);
                    let enabled =
                        !matches!(node.field("enabled").map(|f| &f.value), Some(Value::Bools(b)) if b == &[false]);
                    node.type_name == "TouchSensor" && enabled
                })
                .collect();
            if sensors.is_empty() {
                continue;
            }
            // The press, then the release over the shape (6.51): isActive TRUE, then isActive FALSE
            // with touchTime, each press and release its own cascade.
            for &s in &sensors {
                self.events.send(&mut self.documents, s, vec![("isActive", EventValue::Bool(true))], time);
            }
            for s in sensors {
                let release = vec![("isActive", EventValue::Bool(false)), ("touchTime", EventValue::Time(time))];
                self.events.send(&mut self.documents, s, release, time);
            }
            return self.apply(rt);
        }
        Ok(false)
    }

    /// Binds viewpoint `k` of [`VrmlScene::viewpoints`] (a browser's viewpoint list): the camera
    /// goes to it, and follows it as animation moves it. Out of range, nothing changes.
    pub fn bind_viewpoint(&mut self, k: usize, rt: &mut Context) {
        if let Some(view) = self.viewpoints.get(k) {
            view.made.look(rt);
            self.bound_viewpoint = Some(k);
        }
    }

    /// The messages of animation so far (routes that are not run, events dropped), each once.
    pub fn take_warnings(&mut self) -> Vec<RibDiagnostic> {
        let mut out = std::mem::take(&mut self.warnings);
        out.append(&mut self.events.warnings);
        out
    }

    /// Shows the nodes the events changed.
    pub(super) fn apply(&mut self, rt: &mut Context) -> Result<bool, SceneFileError> {
        let dirty = std::mem::take(&mut self.events.dirty);
        if dirty.is_empty() {
            return Ok(false);
        }
        let is_type = |scene: &VrmlScene, r: &NodeRef, t: &str| {
            scene
                .documents
                .get(r.doc)
                .and_then(|(_, d)| d.nodes.get(r.node.0 as usize))
                .is_some_and(|n| n.type_name == t)
        };
        let moved: BTreeSet<NodeRef> =
            dirty.iter().filter(|r| is_type(self, r, "Transform") || is_type(self, r, "Billboard")).copied().collect();
        let switched: BTreeSet<NodeRef> =
            dirty.iter().filter(|r| is_type(self, r, "Switch") || is_type(self, r, "LOD")).copied().collect();
        let mut changed = false;
        if !moved.is_empty() || !switched.is_empty() {
            for i in 0..self.shapes.len() {
                let path = &self.shapes[i].path;
                let (is_moved, is_switched) =
                    (path.iter().any(|g| moved.contains(g)), path.iter().any(|g| switched.contains(g)));
                if !is_moved && !is_switched {
                    continue;
                }
                let world = if is_moved {
                    let path = path.clone();
                    build::world_of(rt, self, &path) * self.shapes[i].local
                } else {
                    self.shapes[i].world
                };
                let visible = self.chosen(i);
                changed |= self.place(rt, i, world, visible)?;
            }
        }
        // Lights and Viewpoints under a moved Transform, or whose own fields changed, are placed
        // again with their fields as they stand.
        for k in 0..self.lights.len() {
            let light = &self.lights[k];
            let (is_moved, is_changed) = (light.path.iter().any(|g| moved.contains(g)), dirty.contains(&light.node));
            if !is_moved && !is_changed {
                continue;
            }
            let world = if is_moved {
                let (path, local) = (light.path.clone(), light.local);
                build::world_of(rt, self, &path) * local
            } else {
                light.world
            };
            build::relight(rt, self, k, world)?;
            changed = true;
        }
        for k in 0..self.viewpoints.len() {
            let view = &self.viewpoints[k];
            let (is_moved, is_changed) = (view.path.iter().any(|g| moved.contains(g)), dirty.contains(&view.node));
            if !is_moved && !is_changed {
                continue;
            }
            let world = if is_moved {
                let (path, local) = (view.path.clone(), view.local);
                build::world_of(rt, self, &path) * local
            } else {
                view.world
            };
            build::replace_viewpoint(rt, self, k, world)?;
            changed |= self.bound_viewpoint == Some(k);
        }
        // Objects whose geometry or appearance reads a changed node.
        let remade: Vec<usize> = (0..self.objects.len())
            .filter(|&k| {
                let (geometry, appearance, _) = self.objects[k];
                let mut uses = vec![geometry];
                uses.extend(
                    ["coord", "normal", "color", "texCoord"].iter().filter_map(|f| field_node(self, geometry, f)),
                );
                if let Some(a) = appearance {
                    uses.push(a);
                    uses.extend(
                        ["material", "texture", "textureTransform"].iter().filter_map(|f| field_node(self, a, f)),
                    );
                }
                uses.iter().any(|u| dirty.contains(u))
            })
            .collect();
        for k in remade {
            let (geometry, appearance, id) = self.objects[k];
            build::remake_object(rt, self, geometry, appearance, id)?;
            changed = true;
        }
        Ok(changed)
    }

    /// Whether the Switches above shape `i` choose the way to it.
    fn chosen(&self, i: usize) -> bool {
        let placed = &self.shapes[i];
        for (k, g) in placed.path.iter().enumerate() {
            let Some(node) = self.documents.get(g.doc).and_then(|(_, d)| d.nodes.get(g.node.0 as usize)) else {
                continue;
            };
            let next = placed.path.get(k + 1).copied().unwrap_or(placed.node);
            if node.type_name == "LOD" {
                let level = self.lod_levels.get(g).copied().unwrap_or(0);
                if children(&self.documents[g.doc].1, *g, "level").position(|c| c == next) != Some(level) {
                    return false;
                }
                continue;
            }
            if node.type_name != "Switch" {
                continue;
            }
            let which = match node.field("whichChoice").map(|f| &f.value) {
                Some(Value::Numbers(n)) if n.len() == 1 => n[0],
                _ => -1.0,
            };
            let position = children(&self.documents[g.doc].1, *g, "choice").position(|c| c == next);
            if position.map(|p| p as f64) != Some(which) {
                return false;
            }
        }
        true
    }

    /// Places shape `i` with `world` when `visible`: moves its instance, deletes it when `world`
    /// scales it to nothing or it is not visible, places a new one when it was deleted so.
    /// Returns whether anything changed.
    fn place(&mut self, rt: &mut Context, i: usize, world: Affine3A, visible: bool) -> Result<bool, SceneFileError> {
        let hidden = self.hidden_shapes.contains(&i);
        let det = world.matrix3.determinant();
        let drawable = visible && world.is_finite() && det != 0.0 && det.is_finite() && world.inverse().is_finite();
        if world == self.shapes[i].world && drawable != hidden {
            return Ok(false);
        }
        self.shapes[i].world = world;
        match (drawable, hidden) {
            (true, false) => rt.set_instance_transform(self.shapes[i].made, world)?,
            (false, false) => {
                rt.delete_instance(self.shapes[i].made)?;
                self.hidden_shapes.insert(i);
            }
            (true, true) => {
                let Some(&object) = self.shape_objects.get(i) else { return Ok(false) };
                rt.push_matrix();
                rt.load_matrix(world);
                let made = rt.instantiate_object(object);
                rt.pop_matrix()?;
                self.shapes[i].made = made?;
                self.hidden_shapes.remove(&i);
            }
            (false, true) => return Ok(false),
        }
        Ok(true)
    }
}

/// The node an `SFNode` field of `r` holds, if any.
fn field_node(scene: &VrmlScene, r: NodeRef, field: &str) -> Option<NodeRef> {
    match scene.documents[r.doc].1.node(r.node).field(field).map(|f| &f.value) {
        Some(Value::Node(Some(n))) => Some(NodeRef { doc: r.doc, node: *n }),
        Some(Value::Nodes(v)) if v.len() == 1 => Some(NodeRef { doc: r.doc, node: v[0] }),
        _ => None,
    }
}

/// The nodes of an `MFNode` field of `r`.
fn children(doc: &super::Document, r: NodeRef, field: &str) -> impl Iterator<Item = NodeRef> {
    let nodes: Vec<NodeRef> = match doc.node(r.node).field(field).map(|f| &f.value) {
        Some(Value::Nodes(v)) => v.iter().map(|&node| NodeRef { doc: r.doc, node }).collect(),
        Some(Value::Node(Some(n))) => vec![NodeRef { doc: r.doc, node: *n }],
        _ => Vec::new(),
    };
    nodes.into_iter()
}

#[cfg(test)]
mod tests {
    use crate::api::Context;
    use crate::vrml::{build_str, VrmlScene};
    use glam::Vec3;
    use std::path::Path;

    fn load(text: &str) -> (Context, VrmlScene) {
        let mut rt = Context::new();
        let scene = build_str(&mut rt, &format!("#VRML V2.0 utf8\n{text}"), Path::new("test.wrl"))
            .unwrap_or_else(|e| panic!("{e}"));
        (rt, scene)
    }

    const MOVER: &str = "
        Viewpoint { position 0 0 10 }
        NavigationInfo { headlight TRUE }
        DEF T Transform { children Shape { appearance Appearance { material DEF M Material { diffuseColor 1 0 0 } }
                                          geometry Box {} } }
        DEF P PositionInterpolator { key [0 1] keyValue [-2 0 0, 2 0 0] }
        DEF C TimeSensor { cycleInterval 4 loop TRUE }
        ROUTE C.fraction_changed TO P.set_fraction
        ROUTE P.value_changed TO T.set_translation";

    #[test]
    fn a_transform_moves_its_instances_with_time() {
        let (mut rt, mut scene) = load(MOVER);
        assert!(scene.is_animated());
        let instance = scene.shapes[0].made;
        assert!(scene.advance_to(1.0, &mut rt).expect("runs"));
        let m = rt.instance_transform(instance).expect("placed");
        assert!(m.translation.abs_diff_eq(glam::Vec3A::new(-1.0, 0.0, 0.0), 1e-5), "{m:?}");
        scene.advance_to(3.0, &mut rt).expect("runs");
        assert!(rt.instance_transform(instance).expect("placed").translation.x > 0.99);
        // Back in time starts over from the file.
        scene.advance_to(0.0, &mut rt).expect("runs");
        assert!((rt.instance_transform(instance).expect("placed").translation.x + 2.0).abs() < 1e-5);
        assert!(scene.take_warnings().is_empty());
    }

    #[test]
    fn a_material_colour_and_coordinates_change_the_object() {
        let (mut rt, mut scene) = load(&format!(
            "{}
             DEF K ColorInterpolator {{ key [0 1] keyValue [1 0 0, 0 0 1] }}
             ROUTE C.fraction_changed TO K.set_fraction
             ROUTE K.value_changed TO M.set_diffuseColor
             Transform {{ translation 0 -3 0 children Shape {{ geometry IndexedFaceSet {{
                coord DEF Pts Coordinate {{ point [0 0 0, 1 0 0, 0 1 0] }} coordIndex [0 1 2 -1] }} }} }}
             DEF CI CoordinateInterpolator {{ key [0 1] keyValue [0 0 0, 1 0 0, 0 1 0,  0 0 0, 2 0 0, 0 2 0] }}
             ROUTE C.fraction_changed TO CI.set_fraction
             ROUTE CI.value_changed TO Pts.set_point",
            MOVER.replace("ROUTE P.value_changed TO T.set_translation", "")
        ));
        rt.options.width = 16;
        rt.options.height = 16;
        scene.advance_to(0.0, &mut rt).expect("runs");
        let (red, _) = rt.render_frame().expect("renders");
        let triangle =
            scene.objects.iter().find(|(g, _, _)| scene.documents[0].1.node(g.node).type_name == "IndexedFaceSet");
        let id = triangle.expect("the face set").2;
        let before = rt.object_mesh(id).expect("a mesh").positions.clone();
        scene.advance_to(2.0, &mut rt).expect("runs");
        let (mixed, _) = rt.render_frame().expect("renders");
        let after = rt.object_mesh(id).expect("a mesh").positions.clone();
        assert!(before.contains(&Vec3::new(1.0, 0.0, 0.0)) && after.contains(&Vec3::new(1.5, 0.0, 0.0)), "{after:?}");
        // The box at the middle of the image turned from red to purple.
        let (a, b) = (red.pixel(8, 8), mixed.pixel(8, 8));
        assert!(a[0] > 0.1 && a[2] < 0.01, "{a:?}");
        assert!(b[2] > 0.05 && b[0] < a[0], "{a:?} {b:?}");
    }

    /// The summed brightness of the left and right halves of a frame.
    fn halves(rt: &mut Context) -> (f32, f32) {
        let (fb, _) = rt.render_frame().expect("renders");
        let (mut left, mut right) = (0.0, 0.0);
        for y in 0..fb.height {
            for x in 0..fb.width {
                let p = fb.pixel(x, y);
                if x < fb.width / 2 {
                    left += p[0] + p[1] + p[2];
                } else {
                    right += p[0] + p[1] + p[2];
                }
            }
        }
        (left, right)
    }

    /// A grey floor seen from above, no headlight, and what `lights` adds.
    fn lit_floor(lights: &str) -> (Context, VrmlScene) {
        let (mut rt, scene) = load(&format!(
            "NavigationInfo {{ headlight FALSE }}
             Viewpoint {{ position 0 6 0 orientation 1 0 0 -1.5707963 fieldOfView 1.2 }}
             Shape {{ appearance Appearance {{ material Material {{}} }} geometry Box {{ size 8 0.1 6 }} }}
             {lights}"
        ));
        rt.options.width = 32;
        rt.options.height = 24;
        (rt, scene)
    }

    #[test]
    fn a_light_under_an_animated_transform_moves_with_it() {
        for light in [
            "PointLight { location 0 1 0 attenuation 0 0 1 }",
            "SpotLight { location 0 1 0 direction 0 -1 0 cutOffAngle 1.2 attenuation 0 0 1 }",
        ] {
            let (mut rt, mut scene) = lit_floor(&format!(
                "DEF T Transform {{ translation -2 0 0 children {light} }}
                 DEF P PositionInterpolator {{ key [0 1] keyValue [-2 0 0, 2 0 0] }}
                 DEF C TimeSensor {{ cycleInterval 4 loop TRUE }}
                 ROUTE C.fraction_changed TO P.set_fraction
                 ROUTE P.value_changed TO T.set_translation"
            ));
            scene.advance_to(0.0, &mut rt).expect("runs");
            let (left, right) = halves(&mut rt);
            assert!(left > 2.0 * right, "{light}: lit on the left at first: {left} {right}");
            assert!(scene.advance_to(3.9, &mut rt).expect("runs"), "the scene changed");
            let (left_after, right_after) = halves(&mut rt);
            assert!(right_after > 2.0 * left_after, "{light}: then on the right: {left_after} {right_after}");
            assert!(scene.take_warnings().is_empty());
            // Back at the start, lit as at first.
            scene.advance_to(0.0, &mut rt).expect("runs");
            let again = halves(&mut rt);
            assert!((again.0 - left).abs() <= 1e-3 * left, "{again:?} {left}");
        }
    }

    #[test]
    fn routed_light_fields_change_the_light() {
        let (mut rt, mut scene) = lit_floor(
            "DEF L PointLight { location -2 1 0 attenuation 0 0 1 }
             DEF D DirectionalLight { direction 0 -1 0 intensity 0.1 }
             DEF P PositionInterpolator { key [0 1] keyValue [-2 1 0, 2 1 0] }
             DEF S ScalarInterpolator { key [0 1] keyValue [1 3] }
             DEF K ColorInterpolator { key [0 1] keyValue [1 1 1, 1 0 0] }
             DEF C TimeSensor { cycleInterval 4 loop TRUE }
             ROUTE C.fraction_changed TO P.set_fraction
             ROUTE C.fraction_changed TO S.set_fraction
             ROUTE C.fraction_changed TO K.set_fraction
             ROUTE P.value_changed TO L.set_location
             ROUTE S.value_changed TO L.set_intensity
             ROUTE K.value_changed TO L.set_color
             ROUTE S.value_changed TO D.set_ambientIntensity",
        );
        let warnings = scene.take_warnings();
        assert!(warnings.iter().all(|w| w.message.contains("DirectionalLight lights the whole scene")), "{warnings:?}");
        // A routed ambientIntensity has its ambient light made at load, off while it is 0.
        assert_eq!(scene.ambient_lights.len(), 1);
        let lights_on = |rt: &mut Context| {
            let world = rt.build_world().expect("a world");
            let n = world.lights.len();
            rt.return_scene(world);
            n
        };
        let dark = lights_on(&mut rt);
        scene.advance_to(0.0, &mut rt).expect("runs");
        let (left, right) = halves(&mut rt);
        assert!(left > 2.0 * right, "{left} {right}");
        // Half way: the light is at x = 0, twice as bright and reddened, and the directional
        // light's ambient part is on.
        scene.advance_to(2.0, &mut rt).expect("runs");
        assert_eq!(lights_on(&mut rt), dark + 1);
        let (fb, _) = rt.render_frame().expect("renders");
        let centre = fb.pixel(16, 12);
        assert!(centre[0] > centre[1] * 1.5, "reddened: {centre:?}");
        let (left_after, right_after) = halves(&mut rt);
        assert!(
            left_after > 0.0 && (left_after - right_after).abs() < 0.2 * right_after,
            "centred: {left_after} {right_after}"
        );
        assert!(scene.take_warnings().is_empty());
    }

    #[test]
    fn the_bound_viewpoint_moves_the_camera_and_the_others_move_alone() {
        let (mut rt, mut scene) = load(
            "DEF T Transform { children [ DEF V Viewpoint { position 0 0 10 } Viewpoint { position 0 0 20 } ] }
             DEF P PositionInterpolator { key [0 1] keyValue [0 0 0, 4 0 0] }
             DEF F ScalarInterpolator { key [0 1] keyValue [0.5 1.0] }
             DEF C TimeSensor { cycleInterval 4 loop TRUE }
             ROUTE C.fraction_changed TO P.set_fraction
             ROUTE C.fraction_changed TO F.set_fraction
             ROUTE P.value_changed TO T.set_translation
             ROUTE F.value_changed TO V.set_fieldOfView",
        );
        assert_eq!(scene.bound_viewpoint, Some(0));
        assert!(scene.advance_to(2.0, &mut rt).expect("runs"));
        let camera = rt.camera();
        assert!(camera.eye().abs_diff_eq(glam::Vec3A::new(2.0, 0.0, 10.0), 1e-5), "{}", camera.eye());
        assert!((camera.fov_degrees - 0.75f32.to_degrees()).abs() < 1e-3, "{}", camera.fov_degrees);
        assert!(scene.viewpoints[1].made.eye.abs_diff_eq(glam::Vec3A::new(2.0, 0.0, 20.0), 1e-5));
        // Another one bound: the camera goes there and follows it.
        scene.bind_viewpoint(1, &mut rt);
        scene.advance_to(3.0, &mut rt).expect("runs");
        assert!(rt.camera().eye().abs_diff_eq(glam::Vec3A::new(3.0, 0.0, 20.0), 1e-5), "{}", rt.camera().eye());
        assert!(scene.viewpoints[0].made.eye.abs_diff_eq(glam::Vec3A::new(3.0, 0.0, 10.0), 1e-5));
        assert!(scene.take_warnings().is_empty());
    }

    #[test]
    fn a_scale_to_nothing_hides_and_a_later_one_shows_again() {
        let (mut rt, mut scene) = load(
            "DEF T Transform { children Shape { geometry Box {} } }
             DEF P PositionInterpolator { key [0 0.5 1] keyValue [1 1 1, 0 0 0, 1 1 1] }
             DEF C TimeSensor { loop TRUE }
             ROUTE C.fraction_changed TO P.set_fraction
             ROUTE P.value_changed TO T.scale",
        );
        scene.advance_to(0.5, &mut rt).expect("runs");
        assert!(rt.world_instance_ids().is_empty());
        scene.advance_to(0.75, &mut rt).expect("runs");
        assert_eq!(rt.world_instance_ids(), vec![scene.shapes[0].made]);
        rt.render_frame().expect("renders");
    }

    #[test]
    fn a_switch_that_routes_reach_shows_the_choice_it_names() {
        // VRML 97's nodes send no SFInt32 event (only a Script would): the Switch's field is set
        // here as a delivered event sets it.
        let (mut rt, mut scene) = load(
            "DEF Sw Switch { whichChoice 1 choice [ Shape { geometry Box {} } Shape { geometry Sphere {} } ] }
             DEF S Script { eventOut SFInt32 choice }
             ROUTE S.choice TO Sw.set_whichChoice",
        );
        assert_eq!(scene.shapes.len(), 2, "both choices are placed");
        assert_eq!(rt.world_instance_ids(), vec![scene.shapes[1].made], "the sphere is chosen");
        let switch = crate::vrml::NodeRef { doc: 0, node: scene.documents[0].1.defs["Sw"] };
        let node = &mut scene.documents[0].1.nodes[switch.node.0 as usize];
        node.fields.iter_mut().find(|f| f.name == "whichChoice").expect("written").value =
            crate::vrml::parse::Value::Numbers(vec![0.0]);
        scene.events.dirty.insert(switch);
        assert!(scene.advance_to(0.0, &mut rt).expect("runs"));
        assert_eq!(rt.world_instance_ids(), vec![scene.shapes[0].made], "the box is chosen");
        rt.render_frame().expect("renders");
    }

    #[test]
    fn a_click_under_a_touch_sensor_starts_its_animation() {
        let (mut rt, mut scene) = load(
            "DEF T Transform { children [ DEF Touch TouchSensor {} Shape { geometry Box {} } ] }
             Shape { geometry Sphere {} }
             DEF P PositionInterpolator { key [0 1] keyValue [0 0 0, 0 4 0] }
             DEF C TimeSensor { cycleInterval 2 }
             ROUTE Touch.touchTime TO C.startTime
             ROUTE C.fraction_changed TO P.set_fraction
             ROUTE P.value_changed TO T.translation
             DEF L PointLight { on FALSE }
             ROUTE Touch.isActive TO L.on",
        );
        let (boxed, sphere) = (scene.shapes[0].made, scene.shapes[1].made);
        scene.advance_to(1.0, &mut rt).expect("runs");
        assert!(!scene.touch(sphere, 1.0, &mut rt).expect("runs"), "nothing senses the sphere");
        scene.advance_to(2.0, &mut rt).expect("runs");
        assert_eq!(rt.instance_transform(boxed).expect("placed").translation.y, 0.0);
        scene.touch(boxed, 2.0, &mut rt).expect("runs");
        // The press switched the light on, the release off again.
        let lamp = &scene.documents[0].1.nodes[scene.documents[0].1.defs["L"].0 as usize];
        assert_eq!(lamp.field("on").map(|f| &f.value), Some(&crate::vrml::parse::Value::Bools(vec![false])));
        assert!(scene.events.dirty.is_empty(), "shown");
        scene.advance_to(3.0, &mut rt).expect("runs");
        assert!((rt.instance_transform(boxed).expect("placed").translation.y - 2.0).abs() < 1e-5);
    }
}
