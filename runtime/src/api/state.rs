//! `Context`'s graphics state: attributes (colour, opacity, alpha masks) and their stack, the
//! current matrix and its stack (with motion), named coordinate systems, the camera.

use super::*;

impl Context {
    /// The current colour (`Cs`) for objects built from now on.
    pub fn color(&mut self, r: f32, g: f32, b: f32) {
        self.appearance.color = [r, g, b];
    }

    /// The current opacity (`Os`).
    pub fn opacity(&mut self, r: f32, g: f32, b: f32) {
        self.appearance.opacity = [r, g, b];
    }

    /// How light paths (virtual lights, caustic photons) meet objects built from now on: their
    /// shaders are not run on them (`docs/global_illumination.md`).
    pub fn photon_shading_model(&mut self, model: crate::render::world::PhotonModel) {
        self.appearance.photon = model;
    }

    /// Shadow rays run the surface shader to find the opacity of objects built from now on.
    pub fn shadows_from_shader(&mut self, on: bool) {
        self.appearance.shadow_by_shader = on;
    }

    /// Cuts objects built from now on where the alpha of texture `name` (at their texture
    /// coordinates) is below one half, for every ray: cut-outs such as leaves drawn on quads are
    /// seen through and cast shaped shadows, with no shading. `None` makes them solid again. The
    /// texture is found as shader textures are; one that cannot be read, or has no transparent
    /// texel, leaves the object solid (a missing one with a warning).
    pub fn alpha_mask(&mut self, name: Option<&str>) {
        self.alpha_mask_with_cutoff(name, ALPHA_CUTOFF);
    }

    /// [`Context::alpha_mask`] with the alpha below which a texel is cut (glTF's `alphaCutoff`).
    pub fn alpha_mask_with_cutoff(&mut self, name: Option<&str>, cutoff: f32) {
        self.appearance.alpha_mask = name.map(|n| (n.to_string(), cutoff));
    }

    /// Makes objects built from now on one-sided (RenderMan's `Sides 1`) or two-sided (`Sides
    /// 2`, the default): no ray (camera, reflection, refraction, shadow) sees the back of a
    /// one-sided object's triangles, the side their winding's normal `(b - a) x (c - a)` points
    /// away from.
    pub fn one_sided(&mut self, one_sided: bool) {
        self.appearance.one_sided = one_sided;
    }

    /// Makes objects built from now on seen, or not, by rays of `kind` (RenderMan's `Attribute
    /// "visibility"`): a surface the camera does not see still casts shadows and shows in
    /// reflections, one shadow rays do not see casts no shadow. Every kind sees them at first.
    pub fn ray_visibility(&mut self, kind: crate::render::RayKind, visible: bool) {
        self.appearance.visibility = self.appearance.visibility.with(kind, visible);
    }

    /// Makes objects built from now on holdouts (RenderMan's `Matte 1`) or not: where camera rays
    /// meet one, the image is transparent black (alpha 0) and nothing behind it shows, so that it
    /// can be composited with a picture of the real object; it is not shaded for those rays, and
    /// other rays (shadows, reflections) meet it as any surface.
    pub fn matte(&mut self, on: bool) {
        self.appearance.matte = on;
    }

    /// Bounds the diffuse bounces (`indirectdiffuse()` rays) rays may take beyond objects built
    /// from now on (RenderMan's `Attribute "trace" "maxdiffusedepth"`; see
    /// [`TraceDepths`](crate::render::TraceDepths)). Unbounded at first, but for the ray depth.
    pub fn max_diffuse_depth(&mut self, bounces: u32) {
        self.appearance.trace_depths.diffuse = bounces;
    }

    /// Bounds the specular bounces (`trace()` rays: reflections, refractions) rays may take beyond
    /// objects built from now on (RenderMan's `Attribute "trace" "maxspeculardepth"`).
    /// Unbounded at first, but for the ray depth.
    pub fn max_specular_depth(&mut self, bounces: u32) {
        self.appearance.trace_depths.specular = bounces;
    }

    /// Starts the rays that the shading of objects built from now on spawns (`trace()`,
    /// `gather()`, `occlusion()`, `indirectdiffuse()`, `transmission()`, their lights' shadow
    /// rays) `bias` along their direction, in world units (RenderMan's `Attribute "trace"
    /// "bias"`), where rtsl's own offset is shorter: against hits on the surface itself where its
    /// shading and its triangles disagree (bumped, displaced or coarsely tessellated surfaces).
    /// 0 at first; a negative or non-finite bias is taken as 0.
    pub fn trace_bias(&mut self, bias: f32) {
        self.appearance.trace_bias = if bias.is_finite() { bias.max(0.0) } else { 0.0 };
    }

    /// Whether displacement shaders move the geometry of objects built from now on (true
    /// displacement: RenderMan's `Attribute "trace" "displacements"`, BMRT's `"render"
    /// "truedisplacement"`), or bend their shading normals only (bump mapping). `None` leaves it
    /// to [`Context::displacement_bound`]: they move objects displaced by a bound above 0.
    pub fn true_displacement(&mut self, on: Option<bool>) {
        self.appearance.true_displacement = on;
    }

    /// How far displacement shaders may move objects built from now on, in world units
    /// (RenderMan's `Attribute "displacementbound" "sphere"`). A bound above 0 says the shaders
    /// move the geometry (see [`Context::true_displacement`]); a negative or non-finite bound
    /// is taken as 0.
    pub fn displacement_bound(&mut self, bound: f32) {
        self.appearance.displacement_bound = if bound.is_finite() { bound.max(0.0) } else { 0.0 };
    }

    /// The area in pixels of the micropolygons that truly displaced objects built from now on
    /// are diced into (RenderMan's `ShadingRate`, 1 at first): their edges are about its square
    /// root in pixels long. A rate that is not a positive number is taken as 1.
    pub fn shading_rate(&mut self, area: f32) {
        self.appearance.shading_rate = if area.is_finite() && area > 0.0 { area } else { 1.0 };
    }

    /// Names objects built from now on (RenderMan's `Attribute "identifier" "name"`; `None`: no
    /// name), which their shaders read with `attribute("identifier:name", s)`.
    pub fn identifier(&mut self, name: Option<&str>) {
        self.appearance.identifier = name.map(str::to_string);
    }

    /// A copy of the attribute state and the matrix, to restore later in part or whole
    /// ([`Context::restore_attributes`]; PRMan's `Resource "name" "attributes"`).
    pub fn saved_attributes(&self) -> SavedAttributes {
        SavedAttributes { appearance: self.appearance.clone(), matrix: self.matrix, close_matrix: self.close_matrix }
    }

    /// Restores the parts of a saved state that `parts` names: the shading (colour, opacity,
    /// surface, displacement and interior shaders, how shadows and light paths meet the surface,
    /// the alpha mask, ray visibility, holdouts, the name), the geometry's sidedness, the matrix.
    pub fn restore_attributes(&mut self, saved: &SavedAttributes, parts: AttributeParts) {
        let (a, s) = (&mut self.appearance, &saved.appearance);
        if parts.shading {
            a.color = s.color;
            a.opacity = s.opacity;
            a.surface = s.surface.clone();
            a.interior = s.interior.clone();
            a.displacement = s.displacement.clone();
            a.shadow_by_shader = s.shadow_by_shader;
            a.photon = s.photon;
            a.alpha_mask = s.alpha_mask.clone();
            a.visibility = s.visibility;
            a.matte = s.matte;
            a.identifier = s.identifier.clone();
        }
        if parts.sides {
            a.one_sided = s.one_sided;
        }
        if parts.transform {
            self.matrix = saved.matrix;
            self.close_matrix = saved.close_matrix;
        }
    }

    /// The matrix a named space was given ([`Context::coordinate_system`]), if any.
    pub fn coordinate_system_matrix(&self, name: &str) -> Option<Affine3A> {
        self.spaces.get(name).copied()
    }

    /// Gives a named space a matrix, or (with `None`) removes the name.
    pub fn set_coordinate_system(&mut self, name: &str, matrix: Option<Affine3A>) {
        match matrix {
            Some(m) => self.spaces.insert(name.to_string(), m),
            None => self.spaces.remove(name),
        };
    }

    /// Saves the attribute state (colour, opacity, shader binding) and the matrix.
    pub fn push_attributes(&mut self) {
        self.appearance_stack.push(self.appearance.clone());
        self.stack.push((self.matrix, self.close_matrix));
    }

    pub fn pop_attributes(&mut self) -> Result<(), ApiError> {
        self.appearance =
            self.appearance_stack.pop().ok_or(ApiError::Unbalanced("pop_attributes", "push_attributes"))?;
        (self.matrix, self.close_matrix) = self.stack.pop().ok_or(ApiError::MatrixStackEmpty)?;
        Ok(())
    }

    pub fn push_matrix(&mut self) {
        self.stack.push((self.matrix, self.close_matrix));
    }

    pub fn pop_matrix(&mut self) -> Result<(), ApiError> {
        (self.matrix, self.close_matrix) = self.stack.pop().ok_or(ApiError::MatrixStackEmpty)?;
        Ok(())
    }

    pub fn load_identity(&mut self) {
        self.matrix = Affine3A::IDENTITY;
        self.close_matrix = None;
    }

    pub fn current_matrix(&self) -> Affine3A {
        self.matrix
    }

    pub fn load_matrix(&mut self, m: Affine3A) {
        self.matrix = m;
        self.close_matrix = None;
    }

    /// Post-multiplies the current matrix (OpenGL's order: the last call applies first to points).
    pub fn mult_matrix(&mut self, m: Affine3A) {
        self.matrix *= m;
        if let Some(close) = &mut self.close_matrix {
            *close *= m;
        }
    }

    /// A transform that moves during the shutter interval (RIB's `MotionBegin` around a
    /// transform): post-multiplies the current matrix by `open` for the shutter's opening and by
    /// `close` for its closing. Instances placed from now on (within the current matrix scope) move
    /// between the two, so they are motion-blurred when the shutter interval
    /// ([`crate::render::RenderOptions::shutter`]) is not empty.
    pub fn motion_transform(&mut self, open: Affine3A, close: Affine3A) {
        let before = self.matrix;
        let close_before = self.close_matrix.unwrap_or(before);
        self.matrix = before * open;
        let close = close_before * close;
        self.close_matrix = (close != self.matrix).then_some(close);
    }

    /// The current matrix at the shutter's close (the current matrix unless a motion transform
    /// applies).
    pub fn close_matrix(&self) -> Affine3A {
        self.close_matrix.unwrap_or(self.matrix)
    }

    /// Places instance `id` at `open` when the shutter opens and at `close` when it closes (motion
    /// blur; see [`Context::motion_transform`]).
    pub fn set_instance_motion(&mut self, id: InstanceId, open: Affine3A, close: Affine3A) -> Result<(), ApiError> {
        let rec =
            self.instances.get_mut(id.0 as usize).filter(|i| !i.deleted).ok_or(ApiError::UnknownInstance(id.0))?;
        rec.transform = open;
        rec.close_transform = (close != open).then_some(close);
        Ok(())
    }

    pub fn translate(&mut self, x: f32, y: f32, z: f32) {
        self.mult_matrix(Affine3A::from_translation(Vec3::new(x, y, z)));
    }

    /// Rotation by `degrees` about the axis.
    pub fn rotate(&mut self, degrees: f32, x: f32, y: f32, z: f32) {
        let axis = Vec3::new(x, y, z).normalize_or_zero();
        if axis != Vec3::ZERO {
            self.mult_matrix(Affine3A::from_quat(Quat::from_axis_angle(axis, degrees.to_radians())));
        }
    }

    pub fn scale(&mut self, x: f32, y: f32, z: f32) {
        self.mult_matrix(Affine3A::from_mat3(glam::Mat3::from_diagonal(Vec3::new(x, y, z))));
    }

    /// Names the current space (RenderMan's `CoordinateSystem`), for shaders' space casts.
    pub fn coordinate_system(&mut self, name: &str) {
        self.spaces.insert(name.to_string(), self.matrix);
    }

    /// Makes a named space current (RenderMan's `CoordSysTransform`): a space named with
    /// [`Context::coordinate_system`], or one of RISpec's affine standard spaces, `"world"` and
    /// `"camera"` (the camera set now), and `"object"` or `"current"`, the current space itself.
    /// False for any other name (the projective spaces `"screen"`, `"NDC"` and `"raster"` among
    /// them), which leaves the current space as it was.
    pub fn load_coordinate_system(&mut self, name: &str) -> bool {
        let m = match (self.spaces.get(name), name) {
            (Some(m), _) => *m,
            (None, "world") => Affine3A::IDENTITY,
            (None, "camera") => self.camera.world_from_camera,
            (None, "object" | "current") => return true,
            (None, _) => return false,
        };
        self.matrix = m;
        self.close_matrix = None;
        true
    }

    /// A pinhole camera at `eye` looking at `target`; `fov_degrees` spans the image's shorter side.
    /// Points and the up direction are glam vectors (`Vec3A`, `Vec3`) or `[f32; 3]` arrays.
    pub fn camera_look_at(
        &mut self,
        eye: impl Into<Vec3A>,
        target: impl Into<Vec3A>,
        up: impl Into<Vec3A>,
        fov_degrees: f32,
    ) {
        self.camera = CameraSetup::look_at(eye.into(), target.into(), up.into(), fov_degrees);
    }

    /// Sets the camera directly (RenderMan's convention: camera space x right, y up, z forward).
    pub fn set_camera(&mut self, camera: CameraSetup) {
        self.camera = camera;
    }

    pub fn camera(&self) -> &CameraSetup {
        &self.camera
    }

    /// How a depth map rendered from this context's camera projects the world: `worldToCamera`
    /// and `worldToNDC` as [`crate::texture::write_shadow_map`] stores them (row vectors, NDC
    /// with (0, 0) the top-left pixel), for the built-in pinhole camera (`fov_degrees`) or the
    /// library's `orthographic` camera shader, over the options' screen window. `None` for any
    /// other camera shader, whose rays no matrix describes.
    pub fn depth_map_projection(&self) -> Option<([f32; 16], [f32; 16])> {
        let orthographic = match self.camera_shader_id() {
            None => false,
            Some(id) => match self.program(id) {
                Ok(p) if p.name == "orthographic" => true,
                _ => return None,
            },
        };
        let e = self.options.screen_extent();
        let ((ax, ay), (cx, cy)) = (e.half, e.centre);
        // Column vectors here: screen x runs from cx - ax (NDC 0) to cx + ax (NDC 1), screen y from
        // cy + ay (NDC 0, the top row) to cy - ay.
        let to_ndc = if orthographic {
            glam::Mat4::from_cols_array_2d(&[
                [0.5 / ax, 0.0, 0.0, 0.0],
                [0.0, -0.5 / ay, 0.0, 0.0],
                [0.0, 0.0, 1.0, 0.0],
                [-(cx - ax) * 0.5 / ax, (cy + ay) * 0.5 / ay, 0.0, 1.0],
            ])
        } else {
            // Screen position is camera (x, y) / (z tan(fov / 2)); w is z.
            let tan = (self.camera.fov_degrees.to_radians() * 0.5).tan();
            glam::Mat4::from_cols_array_2d(&[
                [0.5 / (ax * tan), 0.0, 0.0, 0.0],
                [0.0, -0.5 / (ay * tan), 0.0, 0.0],
                [-(cx - ax) * 0.5 / ax, (cy + ay) * 0.5 / ay, 1.0, 1.0],
                [0.0, 0.0, 0.0, 0.0],
            ])
        };
        let world_to_camera = glam::Mat4::from(self.camera.world_from_camera.inverse());
        let finite = |m: glam::Mat4| m.is_finite().then(|| m.to_cols_array());
        // A column-vector matrix's columns are the row-vector matrix's rows.
        Some((finite(world_to_camera)?, finite(to_ndc * world_to_camera)?))
    }
}

/// An attribute state and matrix saved by [`Context::saved_attributes`].
#[derive(Clone, Debug)]
pub struct SavedAttributes {
    appearance: super::Appearance,
    matrix: Affine3A,
    close_matrix: Option<Affine3A>,
}

/// Which parts of its appearance an instance takes from the state where it is placed
/// ([`Context::instantiate_object_inheriting`]); the others are its object's.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct InheritedAppearance {
    pub color: bool,
    pub opacity: bool,
    pub surface: bool,
    pub displacement: bool,
    pub interior: bool,
    /// One- or two-sidedness.
    pub sides: bool,
    /// Whether it is a holdout.
    pub matte: bool,
    /// The area micropolygons are diced to (RIB `ShadingRate`).
    pub shading_rate: bool,
    /// The rest, what RIB `Attribute`s set: how shadows and light paths meet the surface, ray
    /// visibility and ray parameters, trace depths and bias, the name, the displacement bound
    /// and whether displacement moves the geometry. (The alpha mask cuts the object's geometry,
    /// which its instances share: it is always the object's.)
    pub attributes: bool,
}

impl InheritedAppearance {
    /// Every part: the instance is shaded as the state where it stands says.
    pub const ALL: InheritedAppearance = InheritedAppearance {
        color: true,
        opacity: true,
        surface: true,
        displacement: true,
        interior: true,
        sides: true,
        matte: true,
        shading_rate: true,
        attributes: true,
    };
    /// No part: the instance is shaded as its object.
    pub const NONE: InheritedAppearance = InheritedAppearance {
        color: false,
        opacity: false,
        surface: false,
        displacement: false,
        interior: false,
        sides: false,
        matte: false,
        shading_rate: false,
        attributes: false,
    };
}

/// Which parts of a [`SavedAttributes`] [`Context::restore_attributes`] restores.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct AttributeParts {
    /// Colour, opacity, shaders, shadow and light-path behaviour, alpha mask.
    pub shading: bool,
    /// One- or two-sidedness.
    pub sides: bool,
    /// The matrix.
    pub transform: bool,
}

impl AttributeParts {
    /// Every part.
    pub const ALL: AttributeParts = AttributeParts { shading: true, sides: true, transform: true };
}
