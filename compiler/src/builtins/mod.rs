//! The one table of built-in functions.
//!
//! Every built-in is declared once, in the [`builtins!`] invocation below: its name, every overload
//! signature in a compact notation, its flags, and how it runs. The `Builtin` enum is generated from
//! the table, so back ends that `match` on it without a wildcard arm fail to build until they handle a
//! new built-in. The checker resolves overloads against [`signatures`]; the docs and `rtsl builtins`
//! list the same table.
//!
//! ## Signature notation
//! `ret(arg,arg,...)`, one letter a type: `f` float, `c` color, `p` point, `v` vector, `n` normal,
//! `m` matrix, `s` string, `x` void, `?` any type. Generic letters expand to one overload per member
//! (the same member throughout one signature): `T` is any of `f c p v n`, `G` any triple `c p v n`,
//! `V` any of `p v n`, `R` a result of `f c p v` (chosen by context, as RSL's `noise` is).
//! `&t` is an output argument; `t[]` an array of any length; a final `t*` repeats zero or more times;
//! a final `...` takes a parameter list of `"name", value` pairs.

use crate::ir::types::{ArrayLen, BaseType, Type};
use std::sync::OnceLock;

/// How a built-in runs in compiled code.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Exec {
    /// Expanded into IR instructions by the back end.
    Inline,
    /// A vectorised helper over one chunk of lanes (`extern "C" fn` over `f32x4` values).
    Lane,
    /// A call into the renderer's services with the whole batch (SoA pointers and the mask).
    Host,
}

/// Properties of a built-in the checker and back ends rely on.
pub mod flags {
    /// The result is varying even when every argument is uniform (it reads varying state).
    pub const VARYING: u16 = 1;
    /// Needs derivatives of some argument (the back end computes them from ray differentials).
    pub const DERIVS: u16 = 2;
    /// Has an effect besides its result (`printf`, writes through output arguments).
    pub const SIDE_EFFECTS: u16 = 4;
    /// Message passing: the first argument names a value to fetch into the second.
    pub const MESSAGE: u16 = 8;
    /// Accepted but not supported by this renderer: warns, and returns a documented value.
    pub const UNSUPPORTED: u16 = 16;
    /// Texture-style lookups: filter width from derivatives of the coordinates.
    pub const TEXTURE: u16 = 32;
    /// Uses the light loop or lights (`ambient`, `diffuse`, `specular`, ...).
    pub const LIGHTS: u16 = 64;
    /// Shoots rays.
    pub const RAYS: u16 = 128;
}

macro_rules! builtins {
    ($($variant:ident $name:literal [$($sig:literal),* $(,)?] $flags:expr, $exec:ident, $doc:literal;)*) => {
        /// Every built-in function, generated from the table.
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize, serde::Deserialize)]
        pub enum Builtin { $($variant,)* }

        impl Builtin {
            pub const ALL: &'static [Builtin] = &[$(Builtin::$variant,)*];

            pub fn name(self) -> &'static str {
                match self { $(Builtin::$variant => $name,)* }
            }

            /// The overloads as written in the table.
            pub fn signature_texts(self) -> &'static [&'static str] {
                match self { $(Builtin::$variant => &[$($sig),*],)* }
            }

            pub fn flags(self) -> u16 {
                match self { $(Builtin::$variant => $flags,)* }
            }

            pub fn exec(self) -> Exec {
                match self { $(Builtin::$variant => Exec::$exec,)* }
            }

            /// One line of documentation.
            pub fn doc(self) -> &'static str {
                match self { $(Builtin::$variant => $doc,)* }
            }
        }
    };
}

use flags::*;

builtins! {
    // ---- Math (RISpec 3.2 section 15.1) ----
    Abs "abs" ["T(T)"] 0, Inline, "absolute value, per component";
    Sign "sign" ["T(T)"] 0, Inline, "-1, 0 or 1 by sign, per component";
    Floor "floor" ["T(T)"] 0, Inline, "largest integer not above x";
    Ceil "ceil" ["T(T)"] 0, Inline, "smallest integer not below x";
    Round "round" ["T(T)"] 0, Inline, "nearest integer";
    Sqrt "sqrt" ["T(T)"] 0, Inline, "square root (0 for negative x)";
    InverseSqrt "inversesqrt" ["T(T)"] 0, Inline, "1/sqrt(x) (0 for x ≤ 0, as `sqrt` gives 0 for negative x: no infinities)";
    Exp "exp" ["T(T)"] 0, Lane, "e to the x";
    Log "log" ["T(T)", "T(T,T)"] 0, Lane, "natural logarithm, or logarithm to a base";
    Pow "pow" ["T(T,T)"] 0, Lane, "x to the y";
    Sin "sin" ["T(T)"] 0, Lane, "sine (radians)";
    Cos "cos" ["T(T)"] 0, Lane, "cosine (radians)";
    Tan "tan" ["T(T)"] 0, Lane, "tangent (radians)";
    Asin "asin" ["T(T)"] 0, Lane, "arc sine";
    Acos "acos" ["T(T)"] 0, Lane, "arc cosine";
    Atan "atan" ["T(T)", "T(T,T)"] 0, Lane, "arc tangent of y, or of y/x in the right quadrant";
    Radians "radians" ["T(T)"] 0, Inline, "degrees to radians";
    Degrees "degrees" ["T(T)"] 0, Inline, "radians to degrees";
    Mod "mod" ["T(T,T)"] 0, Inline, "a - b*floor(a/b)";
    Min "min" ["T(T,T,T*)"] 0, Inline, "smallest argument, per component";
    Max "max" ["T(T,T,T*)"] 0, Inline, "largest argument, per component";
    Clamp "clamp" ["T(T,T,T)"] 0, Inline, "lo below lo, hi above hi, else a";
    Mix "mix" ["T(T,T,f)", "G(G,G,G)"] 0, Inline, "x*(1-a) + y*a";
    Step "step" ["T(T,T)"] 0, Inline, "0 if value < min, else 1";
    Smoothstep "smoothstep" ["T(T,T,T)"] 0, Inline, "Hermite step from min to max";
    Filterstep "filterstep" ["f(f,f,...)", "f(f,f,f,...)"] DERIVS, Lane, "step antialiased over the filter width of its argument";
    Spline "spline" ["T(f,T,T,T,T,T*)", "T(s,f,T,T,T,T,T*)", "T(f,T[])", "T(s,f,T[])"] 0, Lane, "spline through control values (catmull-rom by default)";
    Noise "noise" ["R(f)", "R(f,f)", "R(p)", "R(p,f)"] 0, Lane, "Perlin noise in [0,1], 1 to 4 dimensions";
    Turb "turb" ["R(p)"] 0, Lane, "lucille's fractal noise: the sum over 15 octaves (scale 2 down to 1/8192) of scale * (2 noise(p / scale) - 1); a triple is that value in each component";
    Pnoise "pnoise" ["R(f,f)", "R(f,f,f,f)", "R(p,p)", "R(p,f,p,f)"] 0, Lane, "periodic noise";
    Cellnoise "cellnoise" ["R(f)", "R(f,f)", "R(p)", "R(p,f)"] 0, Lane, "a random value constant over each unit cell";
    Random "random" ["R()"] VARYING, Lane, "a random value in [0,1) per lane";
    Du "Du" ["T(T)"] DERIVS, Inline, "derivative with respect to u";
    Dv "Dv" ["T(T)"] DERIVS, Inline, "derivative with respect to v";
    Deriv "Deriv" ["T(T,f)"] DERIVS, Inline, "derivative of num with respect to den";
    // ---- Geometry (15.2) ----
    Xcomp "xcomp" ["f(V)"] 0, Inline, "x component";
    Ycomp "ycomp" ["f(V)"] 0, Inline, "y component";
    Zcomp "zcomp" ["f(V)"] 0, Inline, "z component";
    SetXcomp "setxcomp" ["x(&V,f)"] SIDE_EFFECTS, Inline, "set the x component";
    SetYcomp "setycomp" ["x(&V,f)"] SIDE_EFFECTS, Inline, "set the y component";
    SetZcomp "setzcomp" ["x(&V,f)"] SIDE_EFFECTS, Inline, "set the z component";
    Length "length" ["f(V)"] 0, Inline, "Euclidean length";
    Normalize "normalize" ["V(V)"] 0, Inline, "unit vector in the same direction (0 stays 0)";
    Distance "distance" ["f(p,p)"] 0, Inline, "distance between two points";
    Ptlined "ptlined" ["f(p,p,p)"] 0, Inline, "distance from a point to a line segment";
    Rotate "rotate" ["p(p,f,p,p)", "m(m,f,v)"] 0, Lane, "rotate a point about an axis through two points, or apply a rotation before a matrix";
    Translate "translate" ["m(m,v)"] 0, Inline, "the matrix with a translation applied to points before it (RiTranslate order)";
    Scale "scale" ["m(m,p)"] 0, Inline, "the matrix with a scale applied to points before it (RiScale order)";
    Area "area" ["f(V)"] DERIVS, Inline, "differential surface area of a point";
    Faceforward "faceforward" ["V(V,V)", "V(V,V,V)"] 0, Inline, "flip N to face opposite to I";
    Reflect "reflect" ["v(v,v)"] 0, Inline, "reflection direction";
    Refract "refract" ["v(v,v,f)"] 0, Inline, "refraction direction (0 at total internal reflection)";
    Fresnel "fresnel" ["x(v,v,f,&f,&f)", "x(v,v,f,&f,&f,&v,&v)"] SIDE_EFFECTS, Lane, "Fresnel reflection and transmission coefficients";
    Depth "depth" ["f(p)"] 0, Host, "normalised camera depth of a point";
    Calculatenormal "calculatenormal" ["n(V)"] DERIVS, Inline, "the normal of a displaced surface: Du(P) ^ Dv(P)";
    Transform "transform" ["p(s,p)", "p(s,s,p)", "p(m,p)", "p(s,m,p)"] 0, Host, "transform a point between coordinate systems";
    Vtransform "vtransform" ["v(s,v)", "v(s,s,v)", "v(m,v)", "v(s,m,v)"] 0, Host, "transform a vector between coordinate systems";
    Ntransform "ntransform" ["n(s,n)", "n(s,s,n)", "n(m,n)", "n(s,m,n)"] 0, Host, "transform a normal between coordinate systems";
    // ---- Colour (15.3) ----
    Comp "comp" ["f(G,f)", "f(m,f,f)"] 0, Inline, "a component of a triple, or an element of a matrix (an index past the ends reads the nearest one, a NaN index the first)";
    SetComp "setcomp" ["x(&G,f,f)", "x(&m,f,f,f)"] SIDE_EFFECTS, Inline, "set a component of a triple or an element of a matrix (indices as `comp` reads them)";
    Ctransform "ctransform" ["c(s,c)", "c(s,s,c)"] 0, Lane, "convert a colour between colour spaces";
    // ---- Matrix (15.4) ----
    Determinant "determinant" ["f(m)"] 0, Lane, "determinant";
    Mtransform "mtransform" ["m(s,m)", "m(s,s,m)"] 0, Host, "transform a matrix between coordinate systems";
    // ---- String (15.5) ----
    Concat "concat" ["s(s,s,s*)"] 0, Host, "concatenation";
    Format "format" ["s(s,?*)"] 0, Host, "printf-style formatting into a string";
    Printf "printf" ["x(s,?*)"] SIDE_EFFECTS, Host, "print to the renderer's log";
    Match "match" ["f(s,s)"] 0, Host, "1 if the regular expression (extended syntax) matches anywhere in the subject";
    Shadername "shadername" ["s()", "s(s)"] 0, Host, "the name of this shader, or of the one bound as the given type";
    // ---- Shading and lighting (15.6) ----
    Ambient "ambient" ["c()"] VARYING | LIGHTS, Host, "the ambient light reaching the point";
    Diffuse "diffuse" ["c(n)"] VARYING | LIGHTS, Host, "Lambertian diffuse light over all lights";
    Specular "specular" ["c(n,v,f)"] VARYING | LIGHTS, Host, "specular highlights over all lights (RenderMan's model)";
    Specularbrdf "specularbrdf" ["c(v,n,v,f)"] VARYING, Inline, "the specular weight of one light direction";
    Phong "phong" ["c(n,v,f)"] VARYING | LIGHTS, Host, "Phong highlights over all lights";
    Trace "trace" ["c(p,v,...)", "f(p,v,...)"] VARYING | RAYS, Host, "colour (or hit distance) seen along a ray";
    Transmission "transmission" ["c(p,p,...)"] VARYING | RAYS, Host, "how much light passes between two points (coloured shadows)";
    Visibility "visibility" ["c(p,p)", "f(p,p)"] VARYING | RAYS, Host, "1 if nothing blocks the segment between two points";
    Occlusion "occlusion" ["f(p,n,f,...)", "f(p,n,...)", "f(s,p,n,f,...)"] VARYING | RAYS, Host, "fraction of the hemisphere that is blocked; Aqsis's form with an occlusion map's name first is traced the same way (the map and the positional sample count are not read: the \"samples\" option is, as Aqsis reads it)";
    Indirectdiffuse "indirectdiffuse" ["c(p,n,f,...)", "c(p,n,...)"] VARYING | RAYS, Host, "diffuse light arriving from other surfaces";
    Raydepth "raydepth" ["f()"] 0, Host, "how many bounces led to this ray (uniform: a batch holds rays of one depth)";
    // ---- Texture (15.7) ----
    Texture "texture" ["R(s,...)", "R(s,f,f,...)", "R(s,f,f,f,f,f,f,f,f,...)"] VARYING | DERIVS | TEXTURE, Host, "filtered texture lookup";
    Environment "environment" ["R(s,v,...)", "R(s,v,v,v,v,...)"] VARYING | DERIVS | TEXTURE, Host, "environment map lookup by direction";
    Shadow "shadow" ["R(s,p,...)", "R(s,p,p,p,p,...)"] VARYING | DERIVS | TEXTURE, Host, "shadow map lookup: the fraction in shadow";
    Bump "bump" ["p(s,n,v,v,...)"] VARYING | DERIVS | TEXTURE, Host, "the normal of the surface bumped by a height map (channel 0) at (s, t) (RISpec 3.0; options ignored)";
    Texture3d "texture3d" ["f(s,p,n,...)", "R(s,p,...)"] VARYING, Host, "trilinear lookup in a 3-D grid file at a point (OSL's form); PRMan's point-cloud form (with a normal) is unsupported: returns 0 and leaves outputs unchanged";
    Bake3d "bake3d" ["f(s,s,p,n,...)"] VARYING | SIDE_EFFECTS | UNSUPPORTED, Host, "point-cloud baking; unsupported: returns 0 and writes nothing";
    Bake "bake" ["f(s,f,f,f)", "f(s,f,f,c)", "f(s,f,f,p)", "f(s,f,f,v)", "f(s,f,f,n)"] VARYING | SIDE_EFFECTS | UNSUPPORTED, Host, "PRMan's texture baking (a value at (s, t) into a bake file); unsupported: returns 0 and writes nothing";
    Photonmap "photonmap" ["c(s,p,...)", "c(s,p,n,...)"] VARYING, Host, "the irradiance a photon map estimates at a point (facing the normal): \"caustic\" and \"global\", the frame's caustic and global photon maps (docs/global_illumination.md); other names black; option \"estimator\" (50), the photons gathered";
    Textureinfo "textureinfo" ["f(s,s,&?)"] SIDE_EFFECTS, Host, "information about a texture file";
    // ---- Message passing and renderer information (15.8) ----
    Atmosphere "atmosphere" ["f(s,&?)"] MESSAGE | SIDE_EFFECTS, Host, "a parameter of the atmosphere shader";
    Displacement "displacement" ["f(s,&?)"] MESSAGE | SIDE_EFFECTS, Host, "a parameter of the displacement shader";
    Lightsource "lightsource" ["f(s,&?)"] MESSAGE | SIDE_EFFECTS, Host, "a parameter of the current light (inside illuminance)";
    Surface "surface" ["f(s,&?)"] MESSAGE | SIDE_EFFECTS, Host, "a parameter of the surface shader";
    Incident "incident" ["f(s,&?)"] MESSAGE | SIDE_EFFECTS, Host, "a parameter of the incident volume shader";
    Opposite "opposite" ["f(s,&?)"] MESSAGE | SIDE_EFFECTS, Host, "a parameter of the opposite volume shader";
    Attribute "attribute" ["f(s,&?)"] MESSAGE | SIDE_EFFECTS, Host, "an attribute of the primitive being shaded";
    Option "option" ["f(s,&?)"] MESSAGE | SIDE_EFFECTS, Host, "a rendering option";
    Rendererinfo "rendererinfo" ["f(s,&?)"] MESSAGE | SIDE_EFFECTS, Host, "information about the renderer";
    Rayinfo "rayinfo" ["f(s,&?)"] MESSAGE | SIDE_EFFECTS, Host, "information about the ray being shaded: its depth, and the application's ray parameters (`docs/ray_parameters.md`)";
    // ---- rtsl: the image a pixel shader finishes ----
    Pixelvalue "pixelvalue" ["f(s,f,f)", "c(s,f,f)"] VARYING, Host, "a channel of the pixel at raster x, y of the image a pixel shader finishes (\"Ci\", \"alpha\", \"z\", \"objectid\", \"shaderid\", \"N\": the unit geometric normal of the first surface seen, facing the camera, 0 where none; any other name: the output variable of that name of the surface the pixel sees, its mean over the pixel's samples, which the renderer keeps for every pixel when the shader names it by a literal): the nearest pixel inside the image; 0 outside pixel shaders and for a channel the image does not have";
}

/// One argument position of a signature.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ParamSpec {
    /// `None` accepts any type (`?`).
    pub ty: Option<BaseType>,
    pub array: bool,
    pub output: bool,
}

/// One overload with generic letters expanded.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Signature {
    pub ret: BaseType,
    pub params: Vec<ParamSpec>,
    /// The last parameter repeats zero or more times.
    pub repeat_last: bool,
    /// A trailing `"name", value` parameter list is accepted.
    pub param_list: bool,
    /// Which overload of the table (before expansion) this came from.
    pub overload: u16,
}

impl Signature {
    pub fn min_args(&self) -> usize {
        self.params.len() - usize::from(self.repeat_last)
    }

    /// The parameter an argument at `index` matches, if any (parameter-list arguments have none).
    pub fn param(&self, index: usize) -> Option<ParamSpec> {
        match self.params.get(index) {
            Some(p) => Some(*p),
            None if self.repeat_last => self.params.last().copied(),
            None => None,
        }
    }
}

fn letter(c: char) -> Option<BaseType> {
    Some(match c {
        'f' => BaseType::Float,
        'c' => BaseType::Color,
        'p' => BaseType::Point,
        'v' => BaseType::Vector,
        'n' => BaseType::Normal,
        'm' => BaseType::Matrix,
        's' => BaseType::String,
        'x' => BaseType::Void,
        _ => return None,
    })
}

fn generic(c: char) -> Option<&'static [BaseType]> {
    use BaseType::*;
    Some(match c {
        'T' => &[Float, Color, Point, Vector, Normal],
        'G' => &[Color, Point, Vector, Normal],
        'V' => &[Point, Vector, Normal],
        'R' => &[Float, Color, Point, Vector],
        _ => return None,
    })
}

/// Expands one signature text into its overloads. Panics on a malformed text: the table is ours, and
/// a test parses every entry.
fn expand(text: &str, overload: u16) -> Vec<Signature> {
    let open = text.find('(').expect("signature has `(`");
    let ret_text = &text[..open];
    let args_text = text[open + 1..].strip_suffix(')').expect("signature ends with `)`");
    let gen = text.chars().find(|c| generic(*c).is_some());
    let members: Vec<Option<BaseType>> = match gen.and_then(generic) {
        Some(list) => list.iter().map(|b| Some(*b)).collect(),
        None => vec![None],
    };
    let resolve = |c: char, member: Option<BaseType>| -> Option<BaseType> {
        if Some(c) == gen {
            member
        } else if c == '?' {
            None
        } else {
            Some(letter(c).expect("known type letter"))
        }
    };
    members
        .into_iter()
        .map(|member| {
            let ret_char = ret_text.chars().next().expect("return type");
            let ret = resolve(ret_char, member).unwrap_or(BaseType::Void);
            let mut params = Vec::new();
            let mut repeat_last = false;
            let mut param_list = false;
            for part in args_text.split(',').filter(|p| !p.is_empty()) {
                if part == "..." {
                    param_list = true;
                    continue;
                }
                let mut p = part;
                let output = p.starts_with('&');
                if output {
                    p = &p[1..];
                }
                let mut chars = p.chars();
                let c = chars.next().expect("type letter");
                let rest: String = chars.collect();
                let array = rest.contains("[]");
                if rest.ends_with('*') {
                    repeat_last = true;
                }
                params.push(ParamSpec { ty: resolve(c, member), array, output });
            }
            Signature { ret, params, repeat_last, param_list, overload }
        })
        .collect()
}

/// All overloads of a built-in, generic letters expanded, in table order.
pub fn signatures(b: Builtin) -> &'static [Signature] {
    static TABLE: OnceLock<Vec<Vec<Signature>>> = OnceLock::new();
    let table = TABLE.get_or_init(|| {
        Builtin::ALL
            .iter()
            .map(|b| b.signature_texts().iter().enumerate().flat_map(|(i, t)| expand(t, i as u16)).collect())
            .collect()
    });
    &table[b as usize]
}

/// Built-ins other renderers define under their own names, each with rtsl's equivalent and the
/// renderer: a call is read as the equivalent, with warning W0012 (a user function of the name
/// wins).
pub const VENDOR_EQUIVALENTS: &[(&str, &str, &str)] = &[("raylevel", "raydepth", "BMRT")];

/// rtsl's equivalent of another renderer's built-in `name`, and the renderer.
pub fn vendor_equivalent(name: &str) -> Option<(&'static str, &'static str)> {
    VENDOR_EQUIVALENTS.iter().find(|(n, ..)| *n == name).map(|&(_, equivalent, renderer)| (equivalent, renderer))
}

/// Looks a built-in up by name.
pub fn lookup(name: &str) -> Option<Builtin> {
    static MAP: OnceLock<rustc_hash::FxHashMap<&'static str, Builtin>> = OnceLock::new();
    MAP.get_or_init(|| Builtin::ALL.iter().map(|b| (b.name(), *b)).collect()).get(name).copied()
}

/// Formats a signature the way RSL writes it: `color mix(color, color, float)`.
pub fn describe(b: Builtin, sig: &Signature) -> String {
    let mut args: Vec<String> = sig
        .params
        .iter()
        .map(|p| {
            let t = p.ty.map(|t| t.name()).unwrap_or("any");
            let mut s = String::new();
            if p.output {
                s.push_str("output ");
            }
            s.push_str(t);
            if p.array {
                s.push_str("[]");
            }
            s
        })
        .collect();
    if sig.repeat_last {
        if let Some(last) = args.last_mut() {
            last.push_str(", ...");
        }
    }
    if sig.param_list {
        args.push("\"name\", value...".to_string());
    }
    format!("{} {}({})", sig.ret.name(), b.name(), args.join(", "))
}

/// The type of an array parameter, for messages.
pub fn param_type(p: &ParamSpec) -> Option<Type> {
    p.ty.map(|base| Type { base, array: p.array.then_some(ArrayLen::Unsized) })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_signature_parses_and_names_are_unique() {
        let mut names = std::collections::HashSet::new();
        for b in Builtin::ALL {
            assert!(names.insert(b.name()), "duplicate {}", b.name());
            assert!(!signatures(*b).is_empty(), "{} has no signature", b.name());
            assert_eq!(lookup(b.name()), Some(*b));
        }
    }

    #[test]
    fn generic_letters_expand() {
        let mix = signatures(Builtin::Mix);
        assert_eq!(mix.len(), 5 + 4);
        assert_eq!(describe(Builtin::Mix, &mix[1]), "color mix(color, color, float)");
        let noise = signatures(Builtin::Noise);
        assert_eq!(noise[0].ret, BaseType::Float);
        assert_eq!(describe(Builtin::Noise, &noise[2]), "point noise(float)");
        let fresnel = signatures(Builtin::Fresnel);
        assert!(fresnel[0].params[3].output);
    }

    #[test]
    fn the_design_notes_list_is_covered() {
        let required = "Deriv Du Dv abs acos ambient area asin atan atmosphere attribute bake3d bump \
            calculatenormal ceil cellnoise clamp comp concat cos ctransform degrees depth determinant diffuse \
            displacement distance environment exp faceforward filterstep floor format fresnel incident \
            indirectdiffuse inversesqrt length lightsource log match max min mix mod mtransform noise normalize \
            ntransform occlusion opposite option phong photonmap pnoise pow printf ptlined radians random raydepth \
            rayinfo reflect refract rendererinfo rotate round scale setcomp setxcomp setycomp setzcomp shadername \
            shadow sign sin smoothstep specular specularbrdf spline sqrt step surface tan texture texture3d \
            textureinfo trace transform translate transmission visibility vtransform xcomp ycomp zcomp";
        for name in required.split_whitespace() {
            assert!(lookup(name).is_some(), "missing built-in {name}");
        }
    }
}
