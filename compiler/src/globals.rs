//! The shader globals, defined once for every shader type.
//!
//! RISpec 3.2 tables 12.1-12.5 give the globals of surface, light, displacement, volume and imager
//! shaders. rtsl adds `camera`, `lightfield` and the id/depth globals of `pixel` (imager) shaders; they
//! are specified here and documented in `docs/language.md`. The checker takes names, types and access
//! from this table; the back ends and the runtime take the SoA layout (the order of [`GLOBALS`]).
//!
//! Access is `Read` or `Write` (read and write). `L`, `Cl` and `Ol` hold the current light's values:
//! in surface, volume and lightfield shaders they may be read only inside `illuminance`.

use crate::ir::types::BaseType;
use crate::ir::ShaderKind;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Access {
    None,
    Read,
    Write,
}

/// A shader global variable.
#[derive(Clone, Copy, Debug)]
pub struct GlobalDef {
    pub name: &'static str,
    pub ty: BaseType,
    /// Whether the global is varying; [`GlobalDef::varying_in`] says where it is not.
    pub varying: bool,
    /// Access per shader kind, in the order of [`ShaderKind::ALL`]:
    /// surface, light, displacement, volume, imager, camera, lightfield.
    pub access: [Access; 7],
    pub doc: &'static str,
}

impl GlobalDef {
    pub fn access(&self, kind: ShaderKind) -> Access {
        self.access[kind_index(kind)]
    }

    /// Whether the global is varying in shaders of `kind` (`None`: a module without a shader).
    /// The lens sample (`u`, `v`) of a camera shader is uniform: the renderer gives every lane of
    /// a call one lens sample (`docs/cameras.md`), so a thin lens maps it onto its aperture once a
    /// call rather than once a lane.
    pub fn varying_in(&self, kind: Option<ShaderKind>) -> bool {
        self.varying && !(kind == Some(ShaderKind::Camera) && UNIFORM_IN_CAMERA.contains(&self.name))
    }

    /// Whether the value is only defined inside a light loop (`illuminance`).
    pub fn light_loop_only(&self) -> bool {
        matches!(self.name, "L" | "Cl" | "Ol")
    }
}

pub fn kind_index(kind: ShaderKind) -> usize {
    ShaderKind::ALL.iter().position(|k| *k == kind).unwrap_or(0)
}

/// The globals that are uniform in camera shaders although varying elsewhere.
pub const UNIFORM_IN_CAMERA: &[&str] = &["u", "v"];

use Access::{None as N, Read as R, Write as W};
use BaseType::*;

/// Every global, in SoA layout order. Index with [`Global`].
pub const GLOBALS: &[GlobalDef] = &[
    //                                              surf light disp vol img cam lf
    GlobalDef { name: "P", ty: Point, varying: true, access: [W, R, W, R, R, R, R], doc: "surface position; in light shaders the point on the light; in imager and camera shaders the raster position" },
    GlobalDef { name: "N", ty: Normal, varying: true, access: [W, R, W, N, N, N, R], doc: "shading normal" },
    GlobalDef { name: "Ng", ty: Normal, varying: true, access: [R, R, R, N, N, N, R], doc: "geometric normal" },
    GlobalDef { name: "I", ty: Vector, varying: true, access: [R, N, R, R, N, W, R], doc: "incident ray direction; in camera shaders the ray direction to generate" },
    GlobalDef { name: "E", ty: Point, varying: true, access: [R, R, R, R, N, W, R], doc: "ray origin (the eye for primary rays); in camera shaders the ray origin to generate" },
    GlobalDef { name: "Cs", ty: Color, varying: true, access: [R, N, N, N, N, N, N], doc: "surface colour (from the Color attribute)" },
    GlobalDef { name: "Os", ty: Color, varying: true, access: [R, N, N, N, N, N, N], doc: "surface opacity (from the Opacity attribute)" },
    GlobalDef { name: "s", ty: Float, varying: true, access: [R, R, R, N, N, R, R], doc: "texture coordinate s; in camera shaders the horizontal screen-window position (the shorter image side spans [-1,1])" },
    GlobalDef { name: "t", ty: Float, varying: true, access: [R, R, R, N, N, R, R], doc: "texture coordinate t; in camera shaders the vertical screen-window position, up (the shorter image side spans [-1,1])" },
    GlobalDef { name: "u", ty: Float, varying: true, access: [R, R, R, N, N, R, R], doc: "surface parameter u; in camera shaders the lens sample in [0,1), uniform there (one per call)" },
    GlobalDef { name: "v", ty: Float, varying: true, access: [R, R, R, N, N, R, R], doc: "surface parameter v; in camera shaders the lens sample in [0,1), uniform there (one per call)" },
    GlobalDef { name: "du", ty: Float, varying: true, access: [R, R, R, N, N, N, R], doc: "change in u between neighbouring samples (from ray differentials)" },
    GlobalDef { name: "dv", ty: Float, varying: true, access: [R, R, R, N, N, N, R], doc: "change in v between neighbouring samples" },
    GlobalDef { name: "dPdu", ty: Vector, varying: true, access: [R, R, R, N, N, N, R], doc: "derivative of P along u" },
    GlobalDef { name: "dPdv", ty: Vector, varying: true, access: [R, R, R, N, N, N, R], doc: "derivative of P along v" },
    GlobalDef { name: "dPdtime", ty: Vector, varying: true, access: [R, N, R, N, N, N, N], doc: "motion of P over the shutter interval" },
    GlobalDef { name: "L", ty: Vector, varying: true, access: [R, W, N, R, N, N, R], doc: "direction of the light (from the surface in illuminance; set by illuminate/solar in lights)" },
    GlobalDef { name: "Cl", ty: Color, varying: true, access: [R, W, N, R, N, N, R], doc: "light colour arriving (read in illuminance; set by light shaders)" },
    GlobalDef { name: "Ol", ty: Color, varying: true, access: [R, W, N, R, N, N, R], doc: "light opacity" },
    GlobalDef { name: "Ps", ty: Point, varying: true, access: [N, R, N, N, N, N, N], doc: "the surface point being illuminated (light shaders)" },
    GlobalDef { name: "Ci", ty: Color, varying: true, access: [W, N, N, W, W, W, W], doc: "output colour; in camera shaders the ray weight (0 marks the ray invalid)" },
    GlobalDef { name: "Oi", ty: Color, varying: true, access: [W, N, N, W, W, N, W], doc: "output opacity" },
    GlobalDef { name: "alpha", ty: Float, varying: true, access: [N, N, N, N, W, N, N], doc: "pixel coverage (imager/pixel shaders)" },
    GlobalDef { name: "zdepth", ty: Float, varying: true, access: [N, N, N, N, R, N, N], doc: "camera-space depth of the pixel's first surface opaque enough (`RenderOptions::depth_threshold`), infinite where none is (pixel shaders)" },
    GlobalDef { name: "objectid", ty: Float, varying: true, access: [N, N, N, N, R, N, N], doc: "id of the object first hit, -1 for none (pixel shaders)" },
    GlobalDef { name: "shaderid", ty: Float, varying: true, access: [N, N, N, N, R, N, N], doc: "id of the surface shader first hit, -1 for none (pixel shaders)" },
    GlobalDef { name: "ncomps", ty: Float, varying: false, access: [R, R, R, R, R, R, R], doc: "number of colour components (3)" },
    GlobalDef { name: "time", ty: Float, varying: true, access: [R, R, R, R, R, R, R], doc: "the time of the ray being shaded within the shutter interval (each primary ray has its own time sample; the rays it spawns inherit it)" },
    GlobalDef { name: "dtime", ty: Float, varying: false, access: [R, R, R, R, R, R, R], doc: "the length of the shutter interval" },
    GlobalDef { name: "Ns", ty: Normal, varying: true, access: [N, N, N, N, N, N, N], doc: "the normal of the surface being illuminated, faced toward the viewer (light shaders; Pixie's)" },
];

/// Globals that other renderers give shader types RISpec does not (or let them write where RISpec
/// only lets them read): accepted with warning W0012 naming the renderer, as `(shader type, name,
/// access, renderer, what rtsl gives)`.
pub const VENDOR_GLOBALS: &[(ShaderKind, &str, Access, &str, &str)] = &[
    (
        ShaderKind::Light,
        "I",
        Access::Read,
        "Pixie",
        "the direction from the ray's origin `E` to the lit point `Ps` (`Ps - E`)",
    ),
    (
        ShaderKind::Light,
        "Ns",
        Access::Read,
        "Pixie",
        "the lit surface's normal, faced toward the viewer (zero where no surface is lit)",
    ),
    (
        ShaderKind::Light,
        "N",
        Access::Write,
        "Pixie",
        "a copy the light shader may change; the renderer does not read it back",
    ),
    (
        ShaderKind::Surface,
        "I",
        Access::Write,
        "Pixie",
        "a copy the shader may change; the renderer does not read it back",
    ),
    (
        ShaderKind::Imager,
        "s",
        Access::Read,
        "Pixie",
        "the pixel's horizontal position over the image, 0 to 1 from the left",
    ),
    (
        ShaderKind::Imager,
        "t",
        Access::Read,
        "Pixie",
        "the pixel's vertical position over the image, 0 to 1 from the top",
    ),
];

/// The access another renderer gives `name` in shaders of `kind` beyond RISpec's, with the renderer
/// and what rtsl gives ([`VENDOR_GLOBALS`]).
pub fn vendor_access(kind: ShaderKind, name: &str) -> Option<(Access, &'static str, &'static str)> {
    VENDOR_GLOBALS.iter().find(|(k, n, ..)| *k == kind && *n == name).map(|&(_, _, a, r, m)| (a, r, m))
}

/// Index of a global in [`GLOBALS`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize, serde::Deserialize)]
#[serde(try_from = "u8", into = "u8")]
pub struct Global(pub u8);

/// Decoding (of a compiled artifact) accepts only indices of real globals, so [`Global::def`] cannot
/// fail on decoded IR.
impl TryFrom<u8> for Global {
    type Error = std::string::String;
    fn try_from(i: u8) -> Result<Global, std::string::String> {
        if (i as usize) < GLOBALS.len() {
            Ok(Global(i))
        } else {
            Err(format!("no global variable has index {i}"))
        }
    }
}

impl From<Global> for u8 {
    fn from(g: Global) -> u8 {
        g.0
    }
}

impl Global {
    pub fn def(self) -> &'static GlobalDef {
        &GLOBALS[self.0 as usize]
    }

    pub fn lookup(name: &str) -> Option<Global> {
        GLOBALS.iter().position(|g| g.name == name).map(|i| Global(i as u8))
    }
}
