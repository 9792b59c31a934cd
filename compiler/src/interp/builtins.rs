//! Built-in functions in the reference interpreter: one exhaustive `match` over [`Builtin`], so a
//! new built-in does not build until it has reference semantics here.

use super::deriv::{zero_like, Dual};
use super::value::Value;
use super::{dot, normalize, Frame, Machine, R};
use crate::builtins::{self, Builtin};
use crate::interp::host::{EnvironmentQuery, LightSample, ShadowQuery, TextureFootprint};
use crate::ir::{Arg, BaseType, Function, Type};
use crate::shadeops::{color, format, geom, matrix, noise, spline, transcendental as tm, V3};
use std::rc::Rc;

/// Applies a scalar function to a float or each component of a triple.
fn map1(v: &Value, g: impl Fn(f32) -> f32) -> Value {
    match v {
        Value::Triple(t) => Value::Triple(t.map(g)),
        other => Value::Float(g(other.f())),
    }
}

/// Applies a binary scalar function component-wise; the result has the first argument's shape.
fn map2(a: &Value, b: &Value, g: impl Fn(f32, f32) -> f32) -> Value {
    match a {
        Value::Triple(x) => {
            let y = b.v3();
            Value::Triple([g(x[0], y[0]), g(x[1], y[1]), g(x[2], y[2])])
        }
        other => Value::Float(g(other.f(), b.f())),
    }
}

fn map3(a: &Value, b: &Value, c: &Value, g: impl Fn(f32, f32, f32) -> f32) -> Value {
    match a {
        Value::Triple(x) => {
            let (y, z) = (b.v3(), c.v3());
            Value::Triple([g(x[0], y[0], z[0]), g(x[1], y[1], z[1]), g(x[2], y[2], z[2])])
        }
        other => Value::Float(g(other.f(), b.f(), c.f())),
    }
}

/// The `"name", value` pairs after `fixed` arguments.
/// `filterstep`'s `"width"` parameter (RISpec: also called `"swidth"`), which multiplies the width
/// of the interval filtered; 1 without one.
pub(super) fn filter_scale(vals: &[Value], fixed: usize) -> f32 {
    param(vals, fixed, "width").or_else(|| param(vals, fixed, "swidth")).map_or(1.0, Value::f)
}

fn param<'v>(vals: &'v [Value], fixed: usize, name: &str) -> Option<&'v Value> {
    vals.get(fixed..)?.chunks(2).find(|p| p.len() == 2 && p[0].s() == name).map(|p| &p[1])
}

/// A `shadow()` call's query: the point and its region (the four points, or the point's pixel
/// footprint from its derivatives `tx`/`ty`), and its options. The JIT computes the same values
/// with the same operations in the same order (`back/jit/lower/builtins/texture.rs`).
fn shadow_query(vals: &[Value], tx: &[Value], ty: &[Value], fixed: usize) -> ShadowQuery {
    let arg = |k: usize| vals.get(k).map(Value::v3).unwrap_or([0.0; 3]);
    let (p, corners) = if fixed == 5 {
        let corners = [arg(1), arg(2), arg(3), arg(4)];
        let centre =
            std::array::from_fn(|i| (((corners[0][i] + corners[1][i]) + corners[2][i]) + corners[3][i]) * 0.25);
        (centre, corners)
    } else {
        let p = arg(1);
        let half = |d: Option<&Value>| d.map(Value::v3).unwrap_or([0.0; 3]).map(|x| x * 0.5);
        let (hx, hy) = (half(tx.get(1)), half(ty.get(1)));
        let corner = |sx: f32, sy: f32| std::array::from_fn(|i| (p[i] + sx * hx[i]) + sy * hy[i]);
        (p, [corner(-1.0, -1.0), corner(1.0, -1.0), corner(-1.0, 1.0), corner(1.0, 1.0)])
    };
    let option = |name: &str, default: f32| param(vals, fixed, name).map(Value::f).unwrap_or(default);
    let (blur, width) = (option("blur", 0.0), option("width", 1.0));
    ShadowQuery {
        p,
        corners,
        samples: option("samples", 16.0),
        sblur: option("sblur", blur),
        tblur: option("tblur", blur),
        swidth: option("swidth", width),
        twidth: option("twidth", width),
        bias: option("bias", f32::NAN),
    }
}

/// An `environment()` call's query (the JIT computes the same values in `lower::deriv`): the
/// direction and its screen derivatives, or the four-direction form's mean and the differences
/// `D2 - D1` (along x) and `D3 - D1` (along y), and its options.
fn environment_query(vals: &[Value], tx: &[Value], ty: &[Value], fixed: usize) -> EnvironmentQuery {
    let arg = |k: usize| vals.get(k).map(Value::v3).unwrap_or([0.0; 3]);
    let (dir, ddx, ddy) = if fixed == 5 {
        let d = [arg(1), arg(2), arg(3), arg(4)];
        let mean = std::array::from_fn(|i| (((d[0][i] + d[1][i]) + d[2][i]) + d[3][i]) * 0.25);
        (mean, std::array::from_fn(|i| d[1][i] - d[0][i]), std::array::from_fn(|i| d[2][i] - d[0][i]))
    } else {
        let tangent = |t: &[Value]| t.get(1).map(Value::v3).unwrap_or([0.0; 3]);
        (arg(1), tangent(tx), tangent(ty))
    };
    let option = |name: &str, default: f32| param(vals, fixed, name).map(Value::f).unwrap_or(default);
    let (blur, width) = (option("blur", 0.0), option("width", 1.0));
    EnvironmentQuery {
        dir,
        ddx,
        ddy,
        sblur: option("sblur", blur),
        tblur: option("tblur", blur),
        swidth: option("swidth", width),
        twidth: option("twidth", width),
        fill: option("fill", 0.0),
    }
}

/// A value of type `ty` made from a triple or float result.
fn shaped(ty: Type, v: V3) -> Value {
    if ty.base == BaseType::Float {
        Value::Float(v[0])
    } else {
        Value::Triple(v)
    }
}

/// A built-in call's evaluated arguments: values and their tangents along screen x and y, how
/// many are positional (the rest are name/value pairs), and the result type.
#[derive(Clone, Copy)]
pub(super) struct CallArgs<'a> {
    pub vals: &'a [Value],
    pub tx: &'a [Value],
    pub ty_: &'a [Value],
    pub fixed: usize,
    pub ty: Type,
}

impl Machine<'_> {
    /// Evaluates a built-in call's arguments, then the call; the caller sets `call_site` to the
    /// call's span.
    pub(super) fn builtin(
        &mut self,
        f: &Function,
        frame: &mut Frame,
        b: Builtin,
        overload: u16,
        args: &[Arg],
        ty: Type,
    ) -> R<Dual> {
        // The caller set the call's place; the arguments' own calls set theirs.
        let site = self.call_site;
        // Evaluate every argument left to right (places too: their current value); the arguments
        // `ir::deriv` marks with their tangents.
        let mut vals = Vec::with_capacity(args.len());
        let (mut tx, mut ty_) = (Vec::with_capacity(args.len()), Vec::with_capacity(args.len()));
        for a in args {
            let (v, dx, dy) = match a {
                Arg::Value(e) => self.dual(f, frame, *e)?,
                Arg::Ref(p) => {
                    let v = self.read_place(f, frame, p)?;
                    let z = zero_like(&v);
                    (v, z.clone(), z)
                }
            };
            vals.push(v);
            tx.push(dx);
            ty_.push(dy);
        }
        let sig = &builtins::signatures(b)[overload as usize];
        let fixed = if sig.repeat_last { vals.len() } else { sig.params.len().min(vals.len()) };
        let mut writes: Vec<(usize, Value)> = Vec::new();
        let call = CallArgs { vals: &vals, tx: &tx, ty_: &ty_, fixed, ty };
        self.call_site = site;
        let result = self.eval_builtin(b, call, &mut writes)?;
        for (i, value) in writes {
            if let Some(Arg::Ref(p)) = args.get(i) {
                self.write_place(f, frame, p, value)?;
            }
        }
        // (Callers that need no derivative drop them.)
        let (dx, dy) = if crate::ir::deriv::has_difference_rule(b) {
            self.difference_tangents(b, call, &result)
        } else {
            Self::builtin_tangents(b, &vals, &tx, &ty_, &result)
        };
        Ok((result, dx, dy))
    }

    /// A built-in's result from its evaluated arguments (with their tangents, for the built-ins
    /// that filter by them); the values it writes to output arguments go to `writes`.
    pub(super) fn eval_builtin(
        &mut self,
        b: Builtin,
        call: CallArgs<'_>,
        writes: &mut Vec<(usize, Value)>,
    ) -> R<Value> {
        let CallArgs { vals, tx, ty_, fixed, ty } = call;
        let v = |i: usize| vals.get(i).cloned().unwrap_or(Value::Void);
        Ok(match b {
            Builtin::Abs => map1(&v(0), f32::abs),
            Builtin::Sign => map1(&v(0), |x| {
                if x > 0.0 {
                    1.0
                } else if x < 0.0 {
                    -1.0
                } else {
                    0.0
                }
            }),
            Builtin::Floor => map1(&v(0), f32::floor),
            Builtin::Ceil => map1(&v(0), f32::ceil),
            Builtin::Round => map1(&v(0), f32::round),
            Builtin::Sqrt => map1(&v(0), |x| if x > 0.0 { x.sqrt() } else { 0.0 }),
            Builtin::InverseSqrt => map1(&v(0), |x| if x > 0.0 { 1.0 / x.sqrt() } else { 0.0 }),
            // The JIT's helpers compute the same bits (`shadeops::transcendental`).
            Builtin::Exp => map1(&v(0), tm::exp),
            Builtin::Log if vals.len() == 2 => map2(&v(0), &v(1), |x, base| tm::ln(x) / tm::ln(base)),
            Builtin::Log => map1(&v(0), tm::ln),
            Builtin::Pow => map2(&v(0), &v(1), tm::pow),
            Builtin::Sin => map1(&v(0), tm::sin),
            Builtin::Cos => map1(&v(0), tm::cos),
            Builtin::Tan => map1(&v(0), tm::tan),
            Builtin::Asin => map1(&v(0), tm::asin),
            Builtin::Acos => map1(&v(0), tm::acos),
            Builtin::Atan if vals.len() == 2 => map2(&v(0), &v(1), tm::atan2),
            Builtin::Atan => map1(&v(0), tm::atan),
            Builtin::Radians => map1(&v(0), f32::to_radians),
            Builtin::Degrees => map1(&v(0), f32::to_degrees),
            Builtin::Mod => map2(&v(0), &v(1), geom::mod_),
            Builtin::Min => vals.iter().skip(1).fold(v(0), |acc, x| map2(&acc, x, f32::min)),
            Builtin::Max => vals.iter().skip(1).fold(v(0), |acc, x| map2(&acc, x, f32::max)),
            Builtin::Clamp => map3(&v(0), &v(1), &v(2), geom::clamp),
            Builtin::Mix => map3(&v(0), &v(1), &v(2), |x, y, a| x * (1.0 - a) + y * a),
            Builtin::Step => map2(&v(0), &v(1), geom::step),
            Builtin::Smoothstep => map3(&v(0), &v(1), &v(2), geom::smoothstep),
            Builtin::Filterstep => match fixed {
                3 => Value::Float(geom::filterstep_interval(v(0).f(), v(1).f(), v(2).f(), filter_scale(vals, fixed))),
                _ => self.deriv_builtin(b, vals, tx, ty_),
            },
            Builtin::Spline => {
                let (basis, rest) = match &vals[0] {
                    Value::String(s) => (s.to_string(), 1),
                    _ => ("catmull-rom".to_string(), 0),
                };
                let x = v(rest).f();
                let knots: Vec<Value> = match vals.get(rest + 1) {
                    Some(Value::Array(items)) => items.clone(),
                    _ => vals[rest + 1..].to_vec(),
                };
                if ty.base == BaseType::Float {
                    let k: Vec<f32> = knots.iter().map(Value::f).collect();
                    Value::Float(spline::spline(&basis, x, &k))
                } else {
                    let k: Vec<V3> = knots.iter().map(Value::v3).collect();
                    Value::Triple(spline::spline3(&basis, x, &k))
                }
            }
            Builtin::Turb => {
                let n = noise::lucille_turb(v(0).v3());
                if ty.base == BaseType::Float {
                    Value::Float(n)
                } else {
                    Value::Triple([n; 3])
                }
            }
            Builtin::Noise => {
                let triple = ty.base != BaseType::Float;
                let r = match (&v(0), vals.len()) {
                    (Value::Triple(p), 2) => {
                        if triple {
                            noise::vnoise4(*p, v(1).f())
                        } else {
                            [noise::noise4(*p, v(1).f()); 3]
                        }
                    }
                    (Value::Triple(p), _) => {
                        if triple {
                            noise::vnoise3(*p)
                        } else {
                            [noise::noise3(*p); 3]
                        }
                    }
                    (x, 2) => {
                        if triple {
                            noise::vnoise2(x.f(), v(1).f())
                        } else {
                            [noise::noise2(x.f(), v(1).f()); 3]
                        }
                    }
                    (x, _) => {
                        if triple {
                            noise::vnoise1(x.f())
                        } else {
                            [noise::noise1(x.f()); 3]
                        }
                    }
                };
                shaped(ty, r)
            }
            Builtin::Pnoise => {
                let triple = ty.base != BaseType::Float;
                let r = match (&v(0), vals.len()) {
                    (Value::Triple(p), 4) => {
                        let (t, pp, pt) = (v(1).f(), v(2).v3(), v(3).f());
                        if triple {
                            noise::vpnoise4(*p, t, pp, pt)
                        } else {
                            [noise::pnoise4(*p, t, pp, pt); 3]
                        }
                    }
                    (Value::Triple(p), _) => {
                        let pp = v(1).v3();
                        if triple {
                            noise::vpnoise3(*p, pp)
                        } else {
                            [noise::pnoise3(*p, pp); 3]
                        }
                    }
                    (x, 4) => {
                        let (y, px, py) = (v(1).f(), v(2).f(), v(3).f());
                        if triple {
                            noise::vpnoise2(x.f(), y, px, py)
                        } else {
                            [noise::pnoise2(x.f(), y, px, py); 3]
                        }
                    }
                    (x, _) => {
                        if triple {
                            noise::vpnoise1(x.f(), v(1).f())
                        } else {
                            [noise::pnoise1(x.f(), v(1).f()); 3]
                        }
                    }
                };
                shaped(ty, r)
            }
            Builtin::Cellnoise => {
                let triple = ty.base != BaseType::Float;
                let r = match (&v(0), vals.len()) {
                    (Value::Triple(p), 2) => {
                        if triple {
                            noise::vcellnoise4(*p, v(1).f())
                        } else {
                            [noise::cellnoise4(*p, v(1).f()); 3]
                        }
                    }
                    (Value::Triple(p), _) => {
                        if triple {
                            noise::vcellnoise3(*p)
                        } else {
                            [noise::cellnoise3(*p); 3]
                        }
                    }
                    (x, 2) => {
                        if triple {
                            noise::vcellnoise2(x.f(), v(1).f())
                        } else {
                            [noise::cellnoise2(x.f(), v(1).f()); 3]
                        }
                    }
                    (x, _) => {
                        if triple {
                            noise::vcellnoise1(x.f())
                        } else {
                            [noise::cellnoise1(x.f()); 3]
                        }
                    }
                };
                shaped(ty, r)
            }
            Builtin::Random => {
                let seed = self.point.seed.wrapping_mul(0x9E37_79B9_7F4A_7C15).wrapping_add(self.random_calls);
                self.random_calls += 1;
                if ty.base == BaseType::Float {
                    Value::Float(noise::random(seed))
                } else {
                    Value::Triple(noise::vrandom(seed))
                }
            }
            Builtin::Du | Builtin::Dv | Builtin::Deriv | Builtin::Area | Builtin::Calculatenormal => {
                self.deriv_builtin(b, vals, tx, ty_)
            }
            Builtin::Xcomp => Value::Float(v(0).v3()[0]),
            Builtin::Ycomp => Value::Float(v(0).v3()[1]),
            Builtin::Zcomp => Value::Float(v(0).v3()[2]),
            Builtin::SetXcomp | Builtin::SetYcomp | Builtin::SetZcomp => {
                let k = match b {
                    Builtin::SetXcomp => 0,
                    Builtin::SetYcomp => 1,
                    _ => 2,
                };
                let mut t = v(0).v3();
                t[k] = v(1).f();
                writes.push((0, Value::Triple(t)));
                Value::Void
            }
            Builtin::Length => Value::Float(geom::length(v(0).v3())),
            Builtin::Normalize => Value::Triple(normalize(v(0).v3())),
            Builtin::Distance => Value::Float(geom::distance(v(0).v3(), v(1).v3())),
            Builtin::Ptlined => Value::Float(geom::ptlined(v(0).v3(), v(1).v3(), v(2).v3())),
            Builtin::Rotate if ty.base == BaseType::Matrix => {
                Value::Matrix(matrix::rotate(&v(0).m4(), v(1).f(), v(2).v3()))
            }
            Builtin::Rotate => Value::Triple(geom::rotate_point(v(0).v3(), v(1).f(), v(2).v3(), v(3).v3())),
            Builtin::Translate => Value::Matrix(matrix::translate(&v(0).m4(), v(1).v3())),
            Builtin::Scale => Value::Matrix(matrix::scale(&v(0).m4(), v(1).v3())),
            Builtin::Faceforward => {
                let nref = if vals.len() == 3 { v(2).v3() } else { self.global("Ng").v3() };
                Value::Triple(geom::faceforward(v(0).v3(), v(1).v3(), nref))
            }
            Builtin::Reflect => Value::Triple(geom::reflect(v(0).v3(), v(1).v3())),
            Builtin::Refract => Value::Triple(geom::refract(v(0).v3(), v(1).v3(), v(2).f())),
            Builtin::Fresnel => {
                let (kr, kt, r, t) = geom::fresnel(v(0).v3(), v(1).v3(), v(2).f());
                writes.push((3, Value::Float(kr)));
                writes.push((4, Value::Float(kt)));
                if vals.len() == 7 {
                    writes.push((5, Value::Triple(r)));
                    writes.push((6, Value::Triple(t)));
                }
                Value::Void
            }
            Builtin::Depth => Value::Float(self.host.depth(v(0).v3())),
            Builtin::Transform | Builtin::Vtransform | Builtin::Ntransform => {
                let p = v(vals.len() - 1).v3();
                let m = match (&v(0), vals.len()) {
                    (Value::Matrix(m), 2) => Some(*m),
                    (Value::String(from), 3) => match &v(1) {
                        // From `from` into "current", then through `m` (PRMan: "from the FROM
                        // coordinate system and then through matrix M"; row vectors).
                        Value::Matrix(m) => {
                            self.host.matrix(from, "current").map(|to_current| matrix::mul(&to_current, m))
                        }
                        to => self.host.matrix(from, to.s()),
                    },
                    (Value::String(to), _) => self.host.matrix("current", to),
                    _ => None,
                };
                match m {
                    Some(m) => Value::Triple(match b {
                        Builtin::Transform => matrix::transform_point(&m, p),
                        Builtin::Vtransform => matrix::transform_vector(&m, p),
                        _ => matrix::transform_normal(&m, p),
                    }),
                    None => Value::Triple(p),
                }
            }
            Builtin::Comp if vals.len() == 3 => Value::Float(matrix::comp(&v(0).m4(), v(1).f(), v(2).f())),
            Builtin::Comp => Value::Float(v(0).v3()[super::index_of(&v(1), 3)]),
            Builtin::SetComp if vals.len() == 4 => {
                let mut m = v(0).m4();
                matrix::set_comp(&mut m, v(1).f(), v(2).f(), v(3).f());
                writes.push((0, Value::Matrix(m)));
                Value::Void
            }
            Builtin::SetComp => {
                let mut t = v(0).v3();
                t[super::index_of(&v(1), 3)] = v(2).f();
                writes.push((0, Value::Triple(t)));
                Value::Void
            }
            Builtin::Ctransform => {
                let c = v(vals.len() - 1).v3();
                let r = if vals.len() == 3 {
                    color::ctransform(v(0).s(), v(1).s(), c)
                } else {
                    color::from_rgb(v(0).s(), c)
                };
                Value::Triple(r.unwrap_or(c))
            }
            Builtin::Determinant => Value::Float(matrix::determinant(&v(0).m4())),
            Builtin::Mtransform => {
                let m = v(vals.len() - 1).m4();
                let space = if vals.len() == 3 {
                    self.host.matrix(v(0).s(), v(1).s())
                } else {
                    self.host.matrix("current", v(0).s())
                };
                Value::Matrix(space.map(|s| matrix::mul(&m, &s)).unwrap_or(m))
            }
            Builtin::Concat if vals.len() < 2 => Value::String(Rc::from(v(0).s())),
            Builtin::Concat => {
                let (text, cut) = format::concat(vals.iter().map(|x| x.s()));
                self.made_string(text, cut)
            }
            Builtin::Format | Builtin::Printf => {
                let fmt_args: Vec<format::FormatArg> = vals[1..]
                    .iter()
                    .map(|x| match x {
                        Value::Float(f) => format::FormatArg::Float(*f),
                        Value::Triple(t) => format::FormatArg::Triple(*t),
                        Value::Matrix(m) => format::FormatArg::Matrix(m),
                        Value::String(s) => format::FormatArg::Str(s),
                        Value::Bool(b) => format::FormatArg::Float(f32::from(u8::from(*b))),
                        _ => format::FormatArg::Str(""),
                    })
                    .collect();
                let (text, cut) = format::format_cut(v(0).s(), &fmt_args);
                if b == Builtin::Printf {
                    if cut {
                        self.note(super::StringLimit::Cut);
                    }
                    self.host.print(&text);
                    Value::Void
                } else {
                    self.made_string(text, cut)
                }
            }
            Builtin::Match => Value::Float(f32::from(u8::from(format::regex_match(v(0).s(), v(1).s())))),
            Builtin::Shadername => {
                let kind = if vals.is_empty() { None } else { Some(v(0).s().to_string()) };
                Value::String(Rc::from(self.host.shader_name(kind.as_deref())))
            }
            Builtin::Ambient => {
                let p = self.global("P").v3();
                let lights = self.host.lights("", p);
                Value::Triple(lights.iter().filter(|l| l.ambient).fold([0.0; 3], |acc, l| add(acc, l.cl)))
            }
            Builtin::Diffuse => {
                let n = normalize(v(0).v3());
                let sum = self.sum_lights(n, |l, _| dot(normalize(l.l), n).max(0.0) * (1.0 - l.nondiffuse));
                Value::Triple(sum)
            }
            Builtin::Specular => {
                let (n, view, rough) = (normalize(v(0).v3()), normalize(v(1).v3()), v(2).f());
                Value::Triple(self.sum_lights(n, |l, _| {
                    geom::specular_weight(normalize(l.l), n, view, rough) * (1.0 - l.nonspecular)
                }))
            }
            Builtin::Specularbrdf => Value::Triple(
                [specular_brdf(normalize(v(0).v3()), normalize(v(1).v3()), normalize(v(2).v3()), v(3).f()); 3],
            ),
            Builtin::Phong => {
                let (n, view, size) = (normalize(v(0).v3()), normalize(v(1).v3()), v(2).f());
                let r = geom::reflect(view.map(|x| -x), n);
                Value::Triple(
                    self.sum_lights(n, |l, _| tm::pow(dot(r, normalize(l.l)).max(0.0), size) * (1.0 - l.nonspecular)),
                )
            }
            Builtin::Trace => {
                let (c, dist) = self.host.trace(v(0).v3(), v(1).v3());
                if ty.base == BaseType::Float {
                    Value::Float(dist)
                } else {
                    Value::Triple(c)
                }
            }
            Builtin::Transmission => Value::Triple(self.host.transmission(v(0).v3(), v(1).v3())),
            Builtin::Visibility => {
                let t = self.host.transmission(v(0).v3(), v(1).v3());
                if ty.base == BaseType::Float {
                    Value::Float(f32::from(u8::from(t.iter().any(|x| *x > 0.0))))
                } else {
                    Value::Triple(t)
                }
            }
            Builtin::Occlusion => {
                let samples =
                    if fixed == 3 { v(2).f() } else { param(vals, fixed, "samples").map(Value::f).unwrap_or(16.0) };
                // Aqsis's form: an occlusion map's name, then P and N.
                let at = usize::from(fixed == 4);
                Value::Float(self.host.occlusion(v(at).v3(), v(at + 1).v3(), samples))
            }
            Builtin::Indirectdiffuse => {
                let samples =
                    if fixed == 3 { v(2).f() } else { param(vals, fixed, "samples").map(Value::f).unwrap_or(16.0) };
                Value::Triple(self.host.indirect_diffuse(v(0).v3(), v(1).v3(), samples))
            }
            Builtin::Raydepth => Value::Float(self.host.ray_depth()),
            Builtin::Texture => {
                let (s, t) = match fixed {
                    1 => (self.global("s").f(), self.global("t").f()),
                    3 => (v(1).f(), v(2).f()),
                    // Four corners: the centre of the quadrilateral.
                    _ => (
                        (v(1).f() + v(3).f() + v(5).f() + v(7).f()) / 4.0,
                        (v(2).f() + v(4).f() + v(6).f() + v(8).f()) / 4.0,
                    ),
                };
                let first = param(vals, fixed, "channel").map(|c| c.f().max(0.0) as usize).unwrap_or(0);
                let fill = param(vals, fixed, "fill").map(Value::f).unwrap_or(0.0);
                let n = if ty.base == BaseType::Float { 1 } else { 3 };
                let fp = self.footprint(vals, tx, ty_, fixed);
                let got = self.host.texture_filtered(v(0).s(), s, t, &fp, first, n).unwrap_or_default();
                let at = |k: usize| got.get(k).copied().unwrap_or(fill);
                if n == 1 {
                    Value::Float(at(0))
                } else {
                    Value::Triple([at(0), at(1), at(2)])
                }
            }
            Builtin::Environment => {
                let query = environment_query(vals, tx, ty_, fixed);
                let first = param(vals, fixed, "channel").map(|c| c.f().max(0.0) as usize).unwrap_or(0);
                let n = if ty.base == BaseType::Float { 1 } else { 3 };
                let got = self.host.environment(v(0).s(), &query, first, n).unwrap_or_else(|| vec![query.fill; n]);
                let at = |k: usize| got.get(k).copied().unwrap_or(query.fill);
                if n == 1 {
                    Value::Float(at(0))
                } else {
                    shaped(ty, [at(0), at(1), at(2)])
                }
            }
            Builtin::Shadow => {
                let query = shadow_query(vals, tx, ty_, fixed);
                let s = self.host.shadow(v(0).s(), &query);
                if ty.base == BaseType::Float {
                    Value::Float(s)
                } else {
                    Value::Triple([s; 3])
                }
            }
            Builtin::Bump => {
                // Point samples of the height map, as the JIT's helper asks for them.
                let (s, t) = (self.global("s").f(), self.global("t").f());
                let mut height = |s: f32, t: f32| {
                    let fp = crate::interp::TextureFootprint::default();
                    self.host
                        .texture_filtered(v(0).s(), s, t, &fp, 0, 1)
                        .and_then(|h| h.first().copied())
                        .unwrap_or(0.0)
                };
                let (h, hs, ht) = (height(s, t), height(s + geom::BUMP_STEP, t), height(s, t + geom::BUMP_STEP));
                Value::Triple(geom::bump(v(1).v3(), v(2).v3(), v(3).v3(), h, hs, ht))
            }
            Builtin::Texture3d if fixed == 2 => {
                // The grid form: one scalar, every component of a triple result alike.
                let fill = param(vals, fixed, "fill").map(Value::f).unwrap_or(0.0);
                let x = self.host.texture3d(v(0).s(), v(1).v3()).unwrap_or(fill);
                if ty.base == BaseType::Float {
                    Value::Float(x)
                } else {
                    Value::Triple([x; 3])
                }
            }
            Builtin::Texture3d | Builtin::Bake3d | Builtin::Bake => {
                self.host.unsupported(b);
                Value::Float(0.0)
            }
            Builtin::Photonmap => {
                let n = if fixed == 3 { v(2).v3() } else { [0.0; 3] };
                let estimator = param(vals, fixed, "estimator").map(Value::f).unwrap_or(50.0);
                Value::Triple(self.host.photonmap(v(0).s(), v(1).v3(), n, estimator).unwrap_or([0.0; 3]))
            }
            Builtin::Pixelvalue => {
                let c = self.host.pixel_value(v(0).s(), v(1).f(), v(2).f()).unwrap_or([0.0; 3]);
                if ty.base == BaseType::Float {
                    Value::Float(c[0])
                } else {
                    Value::Triple(c)
                }
            }
            Builtin::Incident | Builtin::Opposite => {
                let interior =
                    geom::asks_interior(self.global("I").v3(), self.global("Ng").v3(), b == Builtin::Opposite);
                match self.host.volume_message(interior, v(0).s()) {
                    Some(x) if same_shape(&x, &v(1)) => {
                        writes.push((1, x));
                        Value::Float(1.0)
                    }
                    _ => Value::Float(0.0),
                }
            }
            Builtin::Textureinfo => match self.host.message(b, v(1).s()) {
                Some(x) if Value::zero(Type::scalar(kind_of(&x))) == Value::zero(Type::scalar(kind_of(&v(2)))) => {
                    writes.push((2, x));
                    Value::Float(1.0)
                }
                _ => Value::Float(0.0),
            },
            Builtin::Atmosphere
            | Builtin::Displacement
            | Builtin::Lightsource
            | Builtin::Surface
            | Builtin::Attribute
            | Builtin::Option
            | Builtin::Rendererinfo
            | Builtin::Rayinfo => match self.host.message(b, v(0).s()) {
                // The value is written only when its type fits the variable.
                Some(x) if same_shape(&x, &v(1)) => {
                    writes.push((1, x));
                    Value::Float(1.0)
                }
                _ => Value::Float(0.0),
            },
        })
    }

    /// A `texture` call's footprint: the derivatives of its coordinates (of the globals s and t
    /// without coordinates; the corners' differences `(s2 - s1, t2 - t1)` along x and
    /// `(s3 - s1, t3 - t1)` along y for the four-corner form), scaled by `"swidth"`/`"twidth"`
    /// (default `"width"`, default 1), and `"sblur"`/`"tblur"` (default `"blur"`, default 0).
    fn footprint(&self, vals: &[Value], tx: &[Value], ty: &[Value], fixed: usize) -> TextureFootprint {
        let [dsdx, dtdx, dsdy, dtdy] = match fixed {
            1 => {
                let d = |name: &str| self.point.derivs(name).map(|[x, y]| (x.f(), y.f())).unwrap_or((0.0, 0.0));
                let ((sx, sy), (tx_, ty_)) = (d("s"), d("t"));
                [sx, tx_, sy, ty_]
            }
            3 => [tx[1].f(), tx[2].f(), ty[1].f(), ty[2].f()],
            _ => {
                let c = |k: usize| vals.get(k).map(Value::f).unwrap_or(0.0);
                [c(3) - c(1), c(4) - c(2), c(5) - c(1), c(6) - c(2)]
            }
        };
        let width = param(vals, fixed, "width").map(Value::f).unwrap_or(1.0);
        let sw = param(vals, fixed, "swidth").map(Value::f).unwrap_or(width);
        let tw = param(vals, fixed, "twidth").map(Value::f).unwrap_or(width);
        let blur = param(vals, fixed, "blur").map(Value::f).unwrap_or(0.0);
        TextureFootprint {
            dsdx: dsdx * sw,
            dtdx: dtdx * tw,
            dsdy: dsdy * sw,
            dtdy: dtdy * tw,
            sblur: param(vals, fixed, "sblur").map(Value::f).unwrap_or(blur),
            tblur: param(vals, fixed, "tblur").map(Value::f).unwrap_or(blur),
        }
    }

    /// The sum over non-ambient lights of `Cl * weight(light)`, for the lights facing `n`'s
    /// hemisphere (the `illuminance(P, N, PI/2)` of RISpec's `diffuse` and `specular`).
    fn sum_lights(&mut self, n: V3, weight: impl Fn(&LightSample, V3) -> f32) -> V3 {
        let p = self.global("P").v3();
        let mut sum = [0.0; 3];
        for l in self.host.lights("", p).iter().filter(|l| !l.ambient) {
            if !crate::shadeops::geom::in_hemisphere(l.l, n) {
                continue;
            }
            let w = weight(l, n);
            sum = add(sum, l.cl.map(|c| c * w));
        }
        sum
    }
}

fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

use geom::specular_brdf;

fn kind_of(v: &Value) -> BaseType {
    match v {
        Value::Float(_) => BaseType::Float,
        Value::Triple(_) => BaseType::Color,
        Value::Matrix(_) => BaseType::Matrix,
        Value::String(_) => BaseType::String,
        Value::Bool(_) => BaseType::Bool,
        _ => BaseType::Void,
    }
}

fn same_shape(a: &Value, b: &Value) -> bool {
    match (a, b) {
        (Value::Array(x), Value::Array(y)) => x.len() == y.len() && x.iter().zip(y).all(|(p, q)| same_shape(p, q)),
        _ => kind_of(a) == kind_of(b),
    }
}
