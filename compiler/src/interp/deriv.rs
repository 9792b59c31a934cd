//! Forward-mode differentiation in the reference interpreter.
//!
//! The values `ir::deriv::analyse` marks are evaluated by [`Machine::dual`] as dual numbers
//! `(value, d/dx, d/dy)`: the tangents have the value's shape (a float, a triple, an array of
//! them; matrices, strings and bools have zero tangents). Marked variables keep tangents beside
//! their values (`Frame::dx`/`dy`), globals in `ShadingPoint::derivs` (the renderer's screen-space
//! derivatives). Unmarked values are evaluated by `Machine::expr` and have zero tangents: the
//! analysis guarantees that no derivative built-in can observe the difference.
//!
//! The rules (`docs/packet-abi.md`, "Derivatives"), mirrored operation for operation by the JIT:
//! sums and differences add; `a*b` gives `da*b + a*db`; `a/b` gives `(da*b - a*db) / (b*b)`;
//! `.` and `^` the product rule over their formulas; conversions and constructors move tangents
//! with the components; a space cast transforms a point's or vector's tangent as a vector and a
//! normal's as a normal (colour casts: zero); `?:` takes the chosen side's. Built-ins with rules:
//! `xcomp ycomp zcomp comp` (of triples), `abs sqrt sin cos exp`, `min max clamp` (the chosen
//! argument's), `mix`, `length normalize`; `noise`, the space transforms and a few other smooth built-ins by a
//! central difference (`ir::deriv::has_difference_rule`). Every other built-in, and the outputs a
//! built-in writes, have zero derivatives (setting a component of a triple is not a built-in call by
//! then: the checker makes it an assignment to the component), as do the derivative built-ins' own results (no second
//! derivatives).

use super::builtins::CallArgs;
use super::value::Value;
use super::{binary, convert, index_of, Frame, Machine, R};
use crate::builtins::Builtin;
use crate::ir::{self, BaseType, BinaryOp, ExprKind, Function};
use crate::shadeops::{deriv, geom, matrix, V3};

/// A value and its derivatives with respect to screen x and y.
pub(super) type Dual = (Value, Value, Value);

/// The zero tangent of a value's shape (matrices: all zero, not the identity).
pub(super) fn zero_like(v: &Value) -> Value {
    match v {
        Value::Triple(_) => Value::Triple([0.0; 3]),
        Value::Matrix(_) => Value::Matrix([0.0; 16]),
        Value::Array(items) => Value::Array(items.iter().map(zero_like).collect()),
        _ => Value::Float(0.0),
    }
}

fn zero_dual(v: Value) -> Dual {
    let z = zero_like(&v);
    (v, z.clone(), z)
}

fn numeric(v: &Value) -> bool {
    matches!(v, Value::Float(_) | Value::Triple(_))
}

fn is_zero(v: &Value) -> bool {
    match v {
        Value::Float(x) => *x == 0.0,
        Value::Triple(x) => x.iter().all(|c| *c == 0.0),
        Value::Array(items) => items.iter().all(is_zero),
        _ => true,
    }
}

/// `v + h * t` for floats and triples (arrays element by element); other values as they are.
fn perturb(v: &Value, t: &Value, h: f32) -> Value {
    match (v, t) {
        (Value::Float(x), Value::Float(d)) => Value::Float(x + d * h),
        (Value::Triple(x), Value::Triple(d)) => Value::Triple([0, 1, 2].map(|i| x[i] + d[i] * h)),
        (Value::Array(xs), Value::Array(ds)) if xs.len() == ds.len() => {
            Value::Array(xs.iter().zip(ds).map(|(x, d)| perturb(x, d, h)).collect())
        }
        _ => v.clone(),
    }
}

fn map2(a: &Value, b: &Value, g: impl Fn(f32, f32) -> f32) -> Value {
    match (a, b) {
        (Value::Triple(x), y) => {
            let y = y.v3();
            Value::Triple([g(x[0], y[0]), g(x[1], y[1]), g(x[2], y[2])])
        }
        (x, y) => Value::Float(g(x.f(), y.f())),
    }
}

fn map3(a: &Value, b: &Value, c: &Value, g: impl Fn(f32, f32, f32) -> f32) -> Value {
    match a {
        Value::Triple(x) => {
            let (y, z) = (b.v3(), c.v3());
            Value::Triple([g(x[0], y[0], z[0]), g(x[1], y[1], z[1]), g(x[2], y[2], z[2])])
        }
        x => Value::Float(g(x.f(), b.f(), c.f())),
    }
}

fn cross(x: V3, y: V3) -> V3 {
    [x[1] * y[2] - x[2] * y[1], x[2] * y[0] - x[0] * y[2], x[0] * y[1] - x[1] * y[0]]
}

fn add3(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

fn dot(a: V3, b: V3) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The tangent of `a op b` given the operands' tangents (`da`, `db`), for float and triple
/// operands; other operand types (matrices) have zero tangents.
pub(super) fn binary_tangent(op: BinaryOp, a: &Value, da: &Value, b: &Value, db: &Value) -> Value {
    use BinaryOp::*;
    if !numeric(a) || !numeric(b) {
        return zero_like(&binary(op, a, b));
    }
    match op {
        Add => map2(da, db, |x, y| x + y),
        Sub => map2(da, db, |x, y| x - y),
        Mul => {
            let l = map2(da, b, |x, y| x * y);
            let r = map2(a, db, |x, y| x * y);
            map2(&l, &r, |x, y| x + y)
        }
        Div => {
            let l = map2(da, b, |x, y| x * y);
            let r = map2(a, db, |x, y| x * y);
            let n = map2(&l, &r, |x, y| x - y);
            let bb = map2(b, b, |x, y| x * y);
            map2(&n, &bb, |x, y| x / y)
        }
        Dot => Value::Float(dot(da.v3(), b.v3()) + dot(a.v3(), db.v3())),
        Cross => Value::Triple(add3(cross(da.v3(), b.v3()), cross(a.v3(), db.v3()))),
        _ => Value::Float(0.0),
    }
}

/// The tangent of a built-in's result `r` along one direction, from its arguments and their
/// tangents in that direction (see the module docs for which built-ins have rules).
fn builtin_tangent(b: Builtin, vals: &[Value], t: &[Value], r: &Value) -> Value {
    let v = |i: usize| vals.get(i).cloned().unwrap_or(Value::Void);
    let d = |i: usize| t.get(i).cloned().unwrap_or(Value::Float(0.0));
    match b {
        Builtin::Xcomp => Value::Float(d(0).v3()[0]),
        Builtin::Ycomp => Value::Float(d(0).v3()[1]),
        Builtin::Zcomp => Value::Float(d(0).v3()[2]),
        Builtin::Comp if vals.len() == 2 => Value::Float(d(0).v3()[index_of(&v(1), 3)]),
        Builtin::Abs => map2(&v(0), &d(0), |x, dx| dx * geom::sign(x)),
        Builtin::Sqrt => map2(r, &d(0), |r, dx| if r > 0.0 { dx * 0.5 / r } else { 0.0 }),
        Builtin::Sin => map2(&v(0), &d(0), |x, dx| dx * crate::shadeops::transcendental::cos(x)),
        Builtin::Cos => map2(&v(0), &d(0), |x, dx| -(dx * crate::shadeops::transcendental::sin(x))),
        Builtin::Exp => map2(r, &d(0), |r, dx| dx * r),
        Builtin::Min | Builtin::Max if vals.len() >= 2 => {
            // The fold of `interp::builtins`: each step keeps the chosen operand's tangent.
            let pick: fn(f32, f32) -> bool =
                if b == Builtin::Min { |x, y| x < y || y.is_nan() } else { |x, y| x > y || y.is_nan() };
            let (mut acc, mut dacc) = (v(0), d(0));
            for k in 1..vals.len() {
                let keep = map2(&acc, &vals[k], |x, y| f32::from(u8::from(pick(x, y))));
                dacc = map3(&keep, &dacc, &t[k], |c, p, q| if c != 0.0 { p } else { q });
                acc = map2(&acc, &vals[k], if b == Builtin::Min { f32::min } else { f32::max });
            }
            dacc
        }
        Builtin::Clamp => {
            // `geom::clamp`: y = x > lo ? x : lo; y < hi ? y : (x >= lo ? hi : lo).
            let pick = |c: f32, p: f32, q: f32| if c != 0.0 { p } else { q };
            let y = map2(&v(0), &v(1), |x, lo| if x > lo { x } else { lo });
            let dy = map3(&map2(&v(0), &v(1), |x, lo| f32::from(u8::from(x > lo))), &d(0), &d(1), pick);
            let dbound = map3(&map2(&v(0), &v(1), |x, lo| f32::from(u8::from(x >= lo))), &d(2), &d(1), pick);
            map3(&map2(&y, &v(2), |y, hi| f32::from(u8::from(y < hi))), &dy, &dbound, pick)
        }
        Builtin::Mix => {
            // x * (1 - a) + y * a
            let (x, y, a) = (v(0), v(1), v(2));
            let (dx, dy, da) = (d(0), d(1), d(2));
            let one_minus = map2(&a, &a, |a, _| 1.0 - a);
            let l = map2(&map2(&dx, &one_minus, |p, q| p * q), &map2(&x, &da, |p, q| p * q), |p, q| p - q);
            let r = map2(&map2(&dy, &a, |p, q| p * q), &map2(&y, &da, |p, q| p * q), |p, q| p + q);
            map2(&l, &r, |p, q| p + q)
        }
        Builtin::Length => {
            let len = r.f();
            if len > 0.0 {
                Value::Float(dot(v(0).v3(), d(0).v3()) / len)
            } else {
                Value::Float(0.0)
            }
        }
        Builtin::Normalize => {
            // n = p / |p|: dn = (dp - n (n . dp)) / |p|.
            let p = v(0).v3();
            let len = geom::length(p);
            if len == 0.0 {
                return d(0);
            }
            let n = r.v3();
            let dp = d(0).v3();
            let k = dot(n, dp);
            Value::Triple([0, 1, 2].map(|i| (dp[i] - n[i] * k) / len))
        }
        _ => zero_like(r),
    }
}

impl Machine<'_> {
    fn uv_derivs(&self) -> [f32; 4] {
        let d = |name: &str| {
            crate::globals::Global::lookup(name)
                .map(|g| {
                    let [x, y] = &self.point.derivs[g.0 as usize];
                    (x.f(), y.f())
                })
                .unwrap_or((0.0, 0.0))
        };
        let (ux, uy) = d("u");
        let (vx, vy) = d("v");
        [ux, uy, vx, vy]
    }

    /// `(Du(f), Dv(f))` of a float or triple from its tangents.
    fn du_dv(&self, dx: &Value, dy: &Value) -> (Value, Value) {
        let uv = self.uv_derivs();
        let du = map2(dx, dy, |fx, fy| deriv::du_dv(fx, fy, uv).0);
        let dv = map2(dx, dy, |fx, fy| deriv::du_dv(fx, fy, uv).1);
        (du, dv)
    }

    /// The derivative built-ins: `args` are the evaluated arguments with their tangents.
    pub(super) fn deriv_builtin(&mut self, b: Builtin, vals: &[Value], tx: &[Value], ty: &[Value]) -> Value {
        let (dx, dy) = (tx[0].clone(), ty[0].clone());
        match b {
            Builtin::Du => self.du_dv(&dx, &dy).0,
            Builtin::Dv => self.du_dv(&dx, &dy).1,
            Builtin::Deriv => {
                let (nu, nv) = self.du_dv(&dx, &dy);
                let (du, dv) = self.du_dv(&tx[1], &ty[1]);
                let a = map2(&nu, &du, deriv::ratio);
                let c = map2(&nv, &dv, deriv::ratio);
                map2(&a, &c, |x, y| x + y)
            }
            Builtin::Area => {
                let (pu, pv) = self.du_dv(&dx, &dy);
                let du = self.global("du").f();
                let dv = self.global("dv").f();
                let a = pu.v3().map(|x| x * du);
                let c = pv.v3().map(|x| x * dv);
                Value::Float(geom::length(cross(a, c)))
            }
            Builtin::Calculatenormal => {
                let (pu, pv) = self.du_dv(&dx, &dy);
                let n = cross(pu.v3(), pv.v3());
                // RISpec: the normal follows the surface's orientation; ours is Ng's side of
                // dPdu ^ dPdv (flipped when the renderer's Ng points the other way).
                let g = cross(self.global("dPdu").v3(), self.global("dPdv").v3());
                if dot(g, self.global("Ng").v3()) < 0.0 {
                    Value::Triple(n.map(|x| -x))
                } else {
                    Value::Triple(n)
                }
            }
            _ => {
                // filterstep(edge, x, ...): RISpec's width |Du(x) du| + |Dv(x) dv|, times the
                // "width" parameter.
                let (xu, xv) = self.du_dv(&tx[1], &ty[1]);
                let du = self.global("du").f();
                let dv = self.global("dv").f();
                let w = (xu.f() * du).abs() + (xv.f() * dv).abs();
                let w = w * super::builtins::filter_scale(vals, 2);
                Value::Float(geom::filterstep(vals[0].f(), vals[1].f(), w))
            }
        }
    }

    /// The tangents of a built-in with a difference rule (`ir::deriv::has_difference_rule`):
    /// `f(x + t/2) - f(x - t/2)` along each direction, evaluated only where a tangent is not zero.
    pub(super) fn difference_tangents(&mut self, b: Builtin, call: CallArgs<'_>, r: &Value) -> (Value, Value) {
        let mut out = [zero_like(r), zero_like(r)];
        for (dir, t) in [call.tx, call.ty_].into_iter().enumerate() {
            if t.iter().all(is_zero) {
                continue;
            }
            let mut ends = Vec::with_capacity(2);
            for h in [0.5f32, -0.5] {
                let moved: Vec<Value> = call.vals.iter().zip(t).map(|(v, t)| perturb(v, t, h)).collect();
                let mut writes = Vec::new();
                match self.eval_builtin(b, CallArgs { vals: &moved, ..call }, &mut writes) {
                    Ok(v) => ends.push(v),
                    Err(_) => return (zero_like(r), zero_like(r)),
                }
            }
            if numeric(r) {
                out[dir] = map2(&ends[0], &ends[1], |p, q| p - q);
            }
        }
        let [dx, dy] = out;
        (dx, dy)
    }

    /// The tangents of a built-in's result.
    pub(super) fn builtin_tangents(
        b: Builtin,
        vals: &[Value],
        tx: &[Value],
        ty: &[Value],
        r: &Value,
    ) -> (Value, Value) {
        (builtin_tangent(b, vals, tx, r), builtin_tangent(b, vals, ty, r))
    }

    /// Evaluates an expression as a dual number (unmarked expressions: zero tangents).
    pub(super) fn dual(&mut self, f: &Function, frame: &mut Frame, id: ir::ExprId) -> R<Dual> {
        if !self.info.expr(frame.fid, id) {
            let v = self.expr(f, frame, id)?;
            return Ok(zero_dual(v));
        }
        let e = f.expr(id);
        Ok(match &e.kind {
            ExprKind::Var(v) => {
                let i = v.0 as usize;
                (frame.vars[i].clone(), frame.dx[i].clone(), frame.dy[i].clone())
            }
            ExprKind::Global(g) => {
                let i = g.0 as usize;
                let [dx, dy] = self.point.derivs[i].clone();
                (self.point.globals[i].clone(), dx, dy)
            }
            ExprKind::Index { base, index } => {
                let (b, bx, by) = self.dual(f, frame, *base)?;
                let i = self.expr(f, frame, *index)?;
                (pick(&b, &i), pick(&bx, &i), pick(&by, &i))
            }
            ExprKind::Unary { op: ir::UnaryOp::Neg, arg } => {
                let (a, ax, ay) = self.dual(f, frame, *arg)?;
                let neg = |v: Value| match v {
                    Value::Float(x) => Value::Float(-x),
                    Value::Triple(t) => Value::Triple(t.map(|x| -x)),
                    Value::Matrix(m) => Value::Matrix(m.map(|x| -x)),
                    other => other,
                };
                (neg(a), neg(ax), neg(ay))
            }
            ExprKind::Binary { op, lhs, rhs }
                if matches!(
                    op,
                    BinaryOp::Add | BinaryOp::Sub | BinaryOp::Mul | BinaryOp::Div | BinaryOp::Dot | BinaryOp::Cross
                ) =>
            {
                let (a, ax, ay) = self.dual(f, frame, *lhs)?;
                let (b, bx, by) = self.dual(f, frame, *rhs)?;
                let dx = binary_tangent(*op, &a, &ax, &b, &bx);
                let dy = binary_tangent(*op, &a, &ay, &b, &by);
                (binary(*op, &a, &b), dx, dy)
            }
            ExprKind::Convert { arg } => {
                let (a, ax, ay) = self.dual(f, frame, *arg)?;
                let v = convert(a, e.ty.base);
                if e.ty.base == BaseType::Matrix {
                    zero_dual(v)
                } else {
                    (v, convert(ax, e.ty.base), convert(ay, e.ty.base))
                }
            }
            ExprKind::Construct { args } if e.ty.base != BaseType::Matrix => {
                let mut c = [(0.0, 0.0, 0.0); 3];
                for (k, a) in args.iter().enumerate().take(3) {
                    let (x, dx, dy) = self.dual(f, frame, *a)?;
                    c[k] = (x.f(), dx.f(), dy.f());
                }
                (Value::Triple(c.map(|x| x.0)), Value::Triple(c.map(|x| x.1)), Value::Triple(c.map(|x| x.2)))
            }
            ExprKind::SpaceCast { space, arg } if e.ty.base.is_pointlike() => {
                let sp = self.expr(f, frame, *space)?;
                let (a, ax, ay) = self.dual(f, frame, *arg)?;
                let v = self.space_cast(e.ty.base, sp.s(), a);
                match self.host.matrix(sp.s(), "current") {
                    Some(m) => {
                        let t = |d: &Value| {
                            Value::Triple(if e.ty.base == BaseType::Normal {
                                matrix::transform_normal(&m, d.v3())
                            } else {
                                matrix::transform_vector(&m, d.v3())
                            })
                        };
                        (v, t(&ax), t(&ay))
                    }
                    None => (v, ax, ay),
                }
            }
            ExprKind::Select { cond, a, b } => {
                if self.expr(f, frame, *cond)?.b() {
                    self.dual(f, frame, *a)?
                } else {
                    self.dual(f, frame, *b)?
                }
            }
            ExprKind::CallBuiltin { builtin, overload, args } => {
                self.call_site = e.span;
                self.builtin(f, frame, *builtin, *overload, args, e.ty)?
            }
            ExprKind::Call { func, args } => {
                let (v, d) = self.call(f, frame, *func, args)?;
                match d {
                    Some((dx, dy)) => (v, dx, dy),
                    None => zero_dual(v),
                }
            }
            ExprKind::Assign { place, op, value } => {
                let (v, vx, vy) = self.dual(f, frame, *value)?;
                let (stored, sx, sy) = match op {
                    Some(op) => {
                        let (cur, cx, cy) = self.read_place_d(f, frame, place)?;
                        let dx = binary_tangent(*op, &cur, &cx, &v, &vx);
                        let dy = binary_tangent(*op, &cur, &cy, &v, &vy);
                        (binary(*op, &cur, &v), dx, dy)
                    }
                    None => (v, vx, vy),
                };
                self.write_place_d(f, frame, place, stored.clone(), Some((sx.clone(), sy.clone())))?;
                (stored, sx, sy)
            }
            ExprKind::ArrayLiteral { elements } => {
                let (mut v, mut x, mut y) = (Vec::new(), Vec::new(), Vec::new());
                for el in elements {
                    let d = self.dual(f, frame, *el)?;
                    v.push(d.0);
                    x.push(d.1);
                    y.push(d.2);
                }
                (Value::Array(v), Value::Array(x), Value::Array(y))
            }
            _ => {
                let v = self.expr(f, frame, id)?;
                zero_dual(v)
            }
        })
    }
}

/// An element of an array or a component of a triple (the interpreter's `Index`).
fn pick(b: &Value, i: &Value) -> Value {
    match b {
        Value::Array(items) => items.get(index_of(i, items.len())).cloned().unwrap_or(Value::Void),
        Value::Triple(t) => Value::Float(t[index_of(i, 3)]),
        other => other.clone(),
    }
}
