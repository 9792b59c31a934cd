//! Calls: user functions and built-ins, with overload resolution.
//!
//! Overloads are ranked by the cost of converting each argument (exact, then point/vector/normal
//! interchange, then float promotion); the cheapest wins. When several overloads differ only in their
//! result (`noise`, `texture`, `random`), the type the context expects picks one, and otherwise the
//! first in table order (float for the noise family, as RSL specifies).

use super::convert::{array_compatible, conversion, Conversion};
use super::expr::closest;
use super::{Binding, Checker, WithLabel};
use crate::builtins::{self, flags, Builtin, Signature};
use crate::diagnostic::{Code, Diagnostic};
use crate::front::parse::ast;
use crate::ir::{Arg, ArrayLen, BaseType, Constant, ExprId, ExprKind, Place, PlaceBase, Type};
use crate::source::Span;

/// An argument after lowering: a value or a place, with its type.
#[derive(Clone, Debug)]
enum Lowered {
    Value(ExprId, Type),
    Place(Place),
}

impl Lowered {
    fn ty(&self) -> Type {
        match self {
            Lowered::Value(_, t) => *t,
            Lowered::Place(p) => p.ty,
        }
    }
}

/// One parameter of a candidate, normalised over user functions and built-ins.
#[derive(Clone, Copy, Debug)]
struct Param {
    /// `None` accepts any type.
    ty: Option<Type>,
    output: bool,
}

struct Candidate {
    params: Vec<Param>,
    repeat_last: bool,
    param_list: bool,
    ret: Type,
    describe: Describe,
}

/// How to show a candidate in messages: the text is made only when a call fails to match.
enum Describe {
    Builtin(Builtin, usize),
    /// The user function `sigs[index]`, called by this name.
    User {
        index: usize,
        name: crate::symbol::Symbol,
    },
}

/// A candidate and, for user functions, the function's index.
type Candidates = Vec<(Option<usize>, Candidate)>;

/// The candidates of every built-in, made once.
fn builtin_candidates(b: Builtin) -> &'static [(Option<usize>, Candidate)] {
    static TABLE: std::sync::OnceLock<Vec<Candidates>> = std::sync::OnceLock::new();
    let table = TABLE.get_or_init(|| {
        Builtin::ALL
            .iter()
            .map(|b| {
                builtins::signatures(*b).iter().enumerate().map(|(i, s)| (None, builtin_candidate(*b, i, s))).collect()
            })
            .collect()
    });
    &table[b as usize]
}

impl Candidate {
    fn param(&self, i: usize) -> Option<Param> {
        match self.params.get(i) {
            Some(p) => Some(*p),
            None if self.repeat_last => self.params.last().copied(),
            None => None,
        }
    }

    fn min_args(&self) -> usize {
        self.params.len() - usize::from(self.repeat_last)
    }

    /// The cost of calling this candidate with `args`, or `None` if it does not apply.
    fn cost(&self, args: &[Lowered]) -> Option<u32> {
        if args.len() < self.min_args() {
            return None;
        }
        let fixed = if self.repeat_last { args.len() } else { self.params.len().min(args.len()) };
        if args.len() > fixed {
            // The rest must be a `"name", value` parameter list.
            if !self.param_list || (args.len() - fixed) % 2 != 0 {
                return None;
            }
            for pair in args[fixed..].chunks(2) {
                if pair[0].ty() != Type::STRING {
                    return None;
                }
            }
        }
        let mut cost = 0;
        for (i, arg) in args[..fixed].iter().enumerate() {
            let p = self.param(i)?;
            let at = arg.ty();
            if p.output != matches!(arg, Lowered::Place(_)) {
                return None;
            }
            let Some(pt) = p.ty else { continue };
            if at.is_array() != pt.is_array() || !array_compatible(at, pt) {
                return None;
            }
            if at.is_array() || p.output {
                if at.base != pt.base && !(at.base.is_pointlike() && pt.base.is_pointlike()) {
                    return None;
                }
                cost += u32::from(at.base != pt.base);
                continue;
            }
            match conversion(at.base, pt.base) {
                Some(c @ (Conversion::Exact | Conversion::Pointlike | Conversion::Promote)) => cost += c.cost(),
                _ => return None,
            }
        }
        Some(cost)
    }
}

impl Checker<'_> {
    pub(super) fn call(
        &mut self,
        name: &ast::Ident,
        args: &[ast::Expr],
        span: Span,
        expected: Option<BaseType>,
    ) -> Option<ExprId> {
        // The interner outlives the checker's borrow of itself: no copy of the name is needed.
        let interner = self.interner;
        let text: &str = interner.resolve(name.sym);
        let user = self.lookup_funcs(name.sym);
        let mut builtin = builtins::lookup(text);
        if user.is_empty() && builtin.is_none() {
            if let Some((equivalent, renderer)) = builtins::vendor_equivalent(text) {
                builtin = builtins::lookup(equivalent);
                self.diags.push(
                    Diagnostic::new(
                        Code::VendorExtension,
                        name.span,
                        format!("`{text}` is {renderer}'s name for `{equivalent}`, which rtsl calls instead"),
                    )
                    .with_label(format!("read as `{equivalent}`")),
                );
            }
        }
        if user.is_empty() && builtin.is_none() {
            if let Some(Binding::Var(v)) = self.lookup_var(name.sym) {
                self.b().used[v.0 as usize] = true;
                self.error(Code::NotAFunction, name.span, format!("`{text}` is a variable, not a function"))
                    .with_label("cannot be called");
                return None;
            }
            let mut d = Diagnostic::new(Code::UndefinedFunction, name.span, format!("unknown function `{text}`"))
                .with_label("not a built-in or a defined function");
            let names: Vec<String> = builtins::Builtin::ALL
                .iter()
                .map(|b| b.name().to_string())
                .chain(self.sigs.iter().filter_map(|s| {
                    self.functions.get(s.id.0 as usize).and_then(|f| f.as_ref()).map(|f| f.name.clone())
                }))
                .chain(self.top_funcs.keys().map(|k| self.name(*k).to_string()))
                .collect();
            if let Some(best) = closest(text, names.iter().map(String::as_str)) {
                d = d.with_note(format!("did you mean `{best}`?"));
            }
            self.diags.push(d);
            // Check the arguments anyway, for their own errors.
            for a in args {
                let _ = self.expr(a, None);
            }
            return None;
        }
        let user_candidates: Candidates;
        let candidates: &[(Option<usize>, Candidate)] = if !user.is_empty() {
            user_candidates = user.iter().map(|&i| (Some(i), self.user_candidate(i, name.sym))).collect();
            &user_candidates
        } else {
            builtin_candidates(builtin.expect("checked above"))
        };
        let (lowered, extra) = self.lower_args(builtin.filter(|_| user.is_empty()), candidates, args)?;
        let mut lowered = lowered;
        lowered.extend(extra);
        if let Some(b) = builtin.filter(|_| user.is_empty()) {
            // Message passing names a parameter: a string is required (checked before overloads, for
            // a message that says so).
            if b.flags() & flags::MESSAGE != 0 && lowered.first().is_some_and(|a| a.ty() != Type::STRING) {
                self.error(
                    Code::MessagePassing,
                    args[0].span,
                    format!("`{text}` needs the name of a parameter as a string"),
                )
                .with_label("not a string");
                return None;
            }
        }

        let mut best: Option<(u32, usize)> = None;
        // Among the cheapest, the first whose result has the expected type.
        let mut best_expected: Option<(u32, usize)> = None;
        for (i, (_, c)) in candidates.iter().enumerate() {
            let Some(cost) = c.cost(&lowered) else { continue };
            if best.is_none_or(|(b, _)| cost < b) {
                best = Some((cost, i));
            }
            if expected == Some(c.ret.base) && best_expected.is_none_or(|(b, _)| cost < b) {
                best_expected = Some((cost, i));
            }
        }
        let Some((best_cost, first)) = best else {
            self.no_match(text, name.span, span, candidates, &lowered, !user.is_empty(), args);
            return None;
        };
        let chosen = match best_expected {
            Some((cost, i)) if cost == best_cost => i,
            _ => first,
        };
        let (user_index, cand) = &candidates[chosen];
        let ret = cand.ret;
        // Convert arguments to the chosen parameter types.
        let fixed = if cand.repeat_last { lowered.len() } else { cand.params.len().min(lowered.len()) };
        let mut out_args = Vec::with_capacity(lowered.len());
        for (i, arg) in lowered.into_iter().enumerate() {
            match arg {
                Lowered::Place(p) => out_args.push(Arg::Ref(p)),
                Lowered::Value(id, ty) => {
                    let target = if i < fixed { cand.param(i).and_then(|p| p.ty) } else { None };
                    let id = match target {
                        Some(t) if !ty.is_array() && t.base != ty.base => self.convert_node(id, t.base),
                        _ => id,
                    };
                    out_args.push(Arg::Value(id));
                }
            }
        }
        match user_index {
            Some(index) => {
                let index = *index;
                self.b().calls.push((index, span));
                let captures = self.sigs[index].captures.clone();
                let level = self.builders.len() - 1;
                for (owner, var) in captures {
                    let local = self.access_outer(level, owner, var);
                    let ty = self.cur().func.var(local).ty;
                    out_args.push(Arg::Ref(Place { base: PlaceBase::Var(local), index: None, component: None, ty }));
                }
                let func = self.sigs[index].id;
                Some(self.add_expr(ExprKind::Call { func, args: out_args }, ret, span))
            }
            None => {
                let b = builtin.expect("built-in candidate");
                // `texture3d` with a normal is PRMan's point-cloud lookup, which rtsl lacks; its
                // grid form (no normal) is supported.
                let point_cloud = b == Builtin::Texture3d && fixed == 3;
                if b.flags() & flags::UNSUPPORTED != 0 || point_cloud {
                    self.diags.push(
                        Diagnostic::new(
                            Code::Unsupported,
                            name.span,
                            format!("`{text}` is not supported by this renderer"),
                        )
                        .with_label("accepted, but does nothing")
                        .with_note(format!("at run time it reports this once and {}", unsupported_result(b))),
                    );
                }
                if b == Builtin::Turb {
                    self.diags.push(
                        Diagnostic::new(Code::VendorExtension, name.span, "`turb` is lucille's extension")
                            .with_label("accepted, as lucille defines it")
                            .with_note("rtsl gives lucille's sum over 15 octaves of scale * (2 noise(p / scale) - 1), scale 2 down to 1/8192 (a function of the name in the file is used instead)"),
                    );
                }
                if b == Builtin::Occlusion && cand.params.first().and_then(|p| p.ty) == Some(Type::STRING) {
                    self.diags.push(
                        Diagnostic::new(
                            Code::VendorExtension,
                            name.span,
                            "`occlusion` with an occlusion map's name first is Aqsis's form; rtsl traces the occlusion instead of reading the map",
                        )
                        .with_label("the map and the sample count before the options are not read")
                        .with_note("the \"samples\" option sets the rays per point (16 when absent), as Aqsis reads it"),
                    );
                }
                // Setting a component of a triple is an assignment to the component (`P[2] = z`
                // in the IR), so that what follows sees the component's derivatives as well as
                // its value (`calculatenormal` after `setzcomp(P, ...)`), in both back ends.
                if let Some(assign) = self.component_assignment(b, &out_args, span) {
                    return Some(assign);
                }
                // Built-in candidates are the expanded signatures in table order.
                let overload = chosen as u16;
                Some(self.add_expr(ExprKind::CallBuiltin { builtin: b, overload, args: out_args }, ret, span))
            }
        }
    }

    /// `setxcomp(t, v)`, `setycomp`, `setzcomp` and `setcomp(t, i, v)` of a triple `t` as the
    /// assignment of `v` to component `i` of `t` (`None` for other calls, and for a place that is
    /// already a component).
    fn component_assignment(&mut self, b: Builtin, args: &[Arg], span: Span) -> Option<ExprId> {
        let (place, index, value) = match (b, args) {
            (Builtin::SetXcomp | Builtin::SetYcomp | Builtin::SetZcomp, [Arg::Ref(p), Arg::Value(v)]) => {
                let k = match b {
                    Builtin::SetXcomp => 0.0,
                    Builtin::SetYcomp => 1.0,
                    _ => 2.0,
                };
                (p, self.add_expr(ExprKind::Const(Constant::Float(k)), Type::FLOAT, span), *v)
            }
            (Builtin::SetComp, [Arg::Ref(p), Arg::Value(i), Arg::Value(v)]) if p.ty.base.is_triple() => (p, *i, *v),
            _ => return None,
        };
        if !place.ty.base.is_triple() || place.ty.is_array() || place.component.is_some() {
            return None;
        }
        let mut target = place.clone();
        target.ty = Type::FLOAT;
        match target.index {
            // An element of an array of triples: its component.
            Some(_) => target.component = Some(index),
            None => target.index = Some(index),
        }
        Some(self.add_expr(ExprKind::Assign { place: target, op: None, value }, Type::FLOAT, span))
    }

    fn user_candidate(&self, index: usize, name: crate::symbol::Symbol) -> Candidate {
        let sig = &self.sigs[index];
        let params: Vec<Param> = sig.params.iter().map(|(t, o)| Param { ty: Some(*t), output: *o }).collect();
        Candidate {
            params,
            repeat_last: false,
            param_list: false,
            ret: sig.ret,
            describe: Describe::User { index, name },
        }
    }

    /// A candidate as a signature for messages: `color mix(color, color, float)`.
    fn describe(&self, c: &Candidate) -> String {
        match c.describe {
            Describe::Builtin(b, i) => builtins::describe(b, &builtins::signatures(b)[i]),
            Describe::User { index, name } => {
                let sig = &self.sigs[index];
                let params: Vec<String> =
                    sig.params.iter().map(|(t, o)| if *o { format!("output {t}") } else { t.to_string() }).collect();
                format!("{} {}({})", sig.ret, self.name(name), params.join(", "))
            }
        }
    }

    /// Lowers the arguments: as places where every candidate takes an output there, as values
    /// otherwise (with the parameter type as the expected type when all candidates agree). Also
    /// returns the parameter-list pair for a texture channel (`texture("file"[1], ...)`).
    fn lower_args(
        &mut self,
        builtin: Option<Builtin>,
        candidates: &[(Option<usize>, Candidate)],
        args: &[ast::Expr],
    ) -> Option<(Vec<Lowered>, Vec<Lowered>)> {
        let mut lowered = Vec::with_capacity(args.len());
        let mut extra = Vec::new();
        let mut ok = true;
        for (i, a) in args.iter().enumerate() {
            let params = || candidates.iter().filter_map(|(_, c)| c.param(i));
            let all_output = params().next().is_some() && params().all(|p| p.output);
            if all_output {
                match self.place(a, true) {
                    Some(p) => lowered.push(Lowered::Place(p)),
                    None => ok = false,
                }
                continue;
            }
            // `texture("name"[channel], ...)`: the channel becomes a parameter-list entry.
            // (An element of an array of strings, `names[i]`, is an ordinary index.)
            if i == 0 && builtin.is_some_and(|b| b.flags() & flags::TEXTURE != 0) {
                if let ast::ExprKind::Index(base, channel) = &a.kind {
                    let name = self.expr(base, Some(BaseType::String));
                    let ch = self.expr(channel, Some(BaseType::Float));
                    match (name, ch) {
                        (Some(n), Some(c))
                            if self.expr_ty(n).base == BaseType::String && self.expr_ty(n).is_array() =>
                        {
                            if self.expr_ty(c) != Type::FLOAT {
                                let t = self.expr_ty(c);
                                self.error(
                                    Code::BadIndex,
                                    channel.span,
                                    format!("an index must be a float, not a `{t}`"),
                                )
                                .with_label("not a number");
                                ok = false;
                                continue;
                            }
                            let element = self.add_expr(ExprKind::Index { base: n, index: c }, Type::STRING, a.span);
                            lowered.push(Lowered::Value(element, Type::STRING));
                            continue;
                        }
                        (Some(n), Some(c)) if self.expr_ty(n) == Type::STRING => {
                            lowered.push(Lowered::Value(n, Type::STRING));
                            let key = self.add_expr(
                                ExprKind::Const(Constant::String("channel".into())),
                                Type::STRING,
                                channel.span,
                            );
                            extra.push(Lowered::Value(key, Type::STRING));
                            let cty = self.expr_ty(c);
                            extra.push(Lowered::Value(c, cty));
                            continue;
                        }
                        (Some(_), Some(_)) => {
                            self.error(Code::BadIndex, base.span, "a channel index needs a texture name")
                                .with_label("not a string");
                            ok = false;
                            continue;
                        }
                        _ => {
                            ok = false;
                            continue;
                        }
                    }
                }
            }
            let first_ty = params().next().and_then(|p| p.ty).map(|t| t.base);
            let agree = params().all(|p| p.ty.map(|t| t.base) == first_ty);
            let expected = if agree { first_ty } else { None };
            match self.expr(a, expected) {
                Some(id) => {
                    let ty = self.expr_ty(id);
                    if ty.base == BaseType::Void {
                        self.error(Code::VoidValue, a.span, "a `void` function's result used as an argument")
                            .with_label("no value");
                        ok = false;
                    } else {
                        lowered.push(Lowered::Value(id, ty));
                    }
                }
                None => ok = false,
            }
        }
        ok.then_some((lowered, extra))
    }

    #[allow(clippy::too_many_arguments)]
    fn no_match(
        &mut self,
        text: &str,
        name_span: Span,
        span: Span,
        candidates: &[(Option<usize>, Candidate)],
        lowered: &[Lowered],
        is_user: bool,
        args: &[ast::Expr],
    ) {
        let given: Vec<String> = lowered
            .iter()
            .map(|l| match l {
                Lowered::Place(p) => format!("output {}", p.ty),
                Lowered::Value(_, t) => t.to_string(),
            })
            .collect();
        let given = format!("({})", given.join(", "));
        if is_user && candidates.len() == 1 {
            let c = &candidates[0].1;
            let declared = format!("declared as `{}`", self.describe(c));
            let count = c.params.len();
            if args.len() != count {
                self.error(
                    Code::ArgumentCount,
                    span,
                    format!(
                        "`{text}` takes {count} argument{} but {} were given",
                        if count == 1 { "" } else { "s" },
                        args.len()
                    ),
                )
                .with_label(&format!("called with {given}"))
                .notes
                .push(declared);
                if let Some(index) = candidates[0].0 {
                    let def = self.sigs[index].span;
                    if let Some(d) = self.diags.list.last_mut() {
                        d.secondary.push((def, "defined here".into()));
                    }
                }
                return;
            }
            self.error(
                Code::AssignTypeMismatch,
                span,
                format!("the arguments of `{text}` do not match its parameters"),
            )
            .with_label(&format!("called with {given}"))
            .notes
            .push(declared);
            return;
        }
        let mut d =
            Diagnostic::new(Code::NoMatchingOverload, name_span, format!("no version of `{text}` takes {given}"))
                .with_label("no matching signature");
        let mut shown: Vec<String> = Vec::new();
        for (_, c) in candidates {
            let text = self.describe(c);
            if !shown.contains(&text) {
                shown.push(text);
            }
        }
        const MAX: usize = 8;
        let mut list: Vec<String> = shown.iter().take(MAX).map(|s| format!("  {s}")).collect();
        if shown.len() > MAX {
            list.push(format!("  ... and {} more", shown.len() - MAX));
        }
        d = d.with_note(format!("the signatures are:\n{}", list.join("\n")));
        self.diags.push(d);
    }
}

fn builtin_candidate(b: Builtin, index: usize, s: &Signature) -> Candidate {
    Candidate {
        params: s
            .params
            .iter()
            .map(|p| Param {
                ty: p.ty.map(|base| Type { base, array: p.array.then_some(ArrayLen::Unsized) }),
                output: p.output,
            })
            .collect(),
        repeat_last: s.repeat_last,
        param_list: s.param_list,
        ret: Type::scalar(s.ret),
        describe: Describe::Builtin(b, index),
    }
}

fn unsupported_result(_: Builtin) -> &'static str {
    "returns 0"
}
