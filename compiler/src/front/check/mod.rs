//! The checker: the AST becomes typed, checked IR.
//!
//! It resolves names (scopes, nested functions, `extern`), applies RSL's typing rules, resolves calls
//! against user functions and the built-in table, enforces the context rules of each shader type, and
//! lowers everything to [`crate::ir`]. Uniform/varying inference runs afterwards on the IR
//! ([`uniformity`]). Problems become diagnostics; checking goes on past them, and IR is only returned
//! when there was no error.
//!
//! Layout: this file holds the driver, items and scopes; `stmt.rs` statements; `expr.rs` expressions;
//! `call.rs` calls and overload resolution; `convert.rs` the implicit conversion rules.

mod call;
mod convert;
mod expr;
mod stmt;
pub mod uniformity;

use crate::diagnostic::{Code, Diagnostic, Diagnostics};
use crate::front::parse::ast::{self, ShaderKind};
use crate::globals::Global;
use crate::ir::{self, Block, FuncId, Function, Module, Type, VarId, VarKind, Variable};
use crate::source::Span;
use crate::symbol::{Interner, Symbol};
use rustc_hash::FxHashMap;

/// What a name in scope refers to.
#[derive(Clone, Copy, Debug)]
enum Binding {
    Var(VarId),
    /// `extern point P;`: an explicit reference to a shader global.
    Global(Global),
}

/// A user function as callers see it.
#[derive(Clone, Debug)]
struct FuncSig {
    id: FuncId,
    params: Vec<(Type, bool)>,
    ret: Type,
    span: Span,
    /// Variables of enclosing functions this function reaches through `extern`: the builder that
    /// owns each, and the variable there. Callers pass them after the declared arguments.
    captures: Vec<(usize, VarId)>,
}

/// One scope level: variables and nested functions declared in it.
#[derive(Default)]
struct Scope {
    vars: FxHashMap<Symbol, Binding>,
    funcs: FxHashMap<Symbol, Vec<usize>>,
}

/// The function being lowered.
struct FnBuilder {
    func: Function,
    scopes: Vec<Scope>,
    /// For each variable: read at least once.
    used: Vec<bool>,
    /// Captured variables: (owning builder, variable there) -> the capture variable here.
    captures: Vec<((usize, VarId), VarId)>,
    loop_depth: u32,
    light_loop_depth: u32,
    /// This builder lowers the shader body itself (not a function).
    is_shader: bool,
    /// Uses `illuminance`/`gather` (checked against the shader kind at the end).
    uses_light_loop: Option<Span>,
    /// Calls made, for the recursion check.
    calls: Vec<(usize, Span)>,
}

impl FnBuilder {
    fn new(name: String, return_type: Type, span: Span, is_shader: bool) -> FnBuilder {
        FnBuilder {
            func: Function {
                name,
                return_type,
                params: Vec::new(),
                // About one expression per eight bytes of source and a variable per hundred, so
                // that the arenas rarely regrow.
                vars: Vec::with_capacity(span.range().len() / 100),
                exprs: Vec::with_capacity(span.range().len() / 8),
                body: Block::default(),
                span,
                reads_varying: false,
            },
            scopes: vec![Scope::default()],
            used: Vec::new(),
            captures: Vec::new(),
            loop_depth: 0,
            light_loop_depth: 0,
            is_shader,
            uses_light_loop: None,
            calls: Vec::new(),
        }
    }

    fn add_var(&mut self, var: Variable) -> VarId {
        let id = VarId(self.func.vars.len() as u32);
        self.func.vars.push(var);
        self.used.push(false);
        id
    }
}

/// The result of checking one file.
#[derive(Debug)]
pub struct Checked {
    /// The IR, when there was no error.
    pub module: Option<Module>,
}

/// The state of checking one translation unit.
pub struct Checker<'a> {
    interner: &'a Interner,
    diags: &'a mut Diagnostics,
    /// Every user function; `sigs[i]` describes `functions[i]`.
    functions: Vec<Option<Function>>,
    sigs: Vec<FuncSig>,
    /// Top-level functions by name.
    top_funcs: FxHashMap<Symbol, Vec<usize>>,
    builders: Vec<FnBuilder>,
    /// The shader type of the file's shader, if it has one: the context for every function.
    kind: Option<ShaderKind>,
    shader: Option<ir::Shader>,
    /// Calls between user functions (caller function index, or `None` for the shader; callee; span).
    call_graph: Vec<(Option<usize>, usize, Span)>,
    /// Which function index each builder lowers (`None` for the shader body).
    builder_funcs: Vec<Option<usize>>,
    /// Errors against the shader type's context rules (a global it lacks, a light loop it cannot
    /// run) found in a function, by the function's index: reported only for functions the shader
    /// calls, so that a header's helpers for other shader types do not fail it (PRMan and Aqsis
    /// check context where a function is used).
    deferred: Vec<(usize, Diagnostic)>,
    /// The parser dropped statements: usage counts are incomplete, so unused warnings are off.
    incomplete: bool,
    /// How deeply expressions and statements nest at the point being checked.
    depth: u32,
    depth_reported: bool,
    /// Emptied scopes kept for reuse: their maps keep their capacity, so blocks rarely allocate.
    spare_scopes: Vec<Scope>,
}

/// Nesting deeper than this is refused: checking recurses, and so do the back ends.
const MAX_NESTING: u32 = 400;

/// Checks a parsed file and lowers it to IR.
pub fn check(unit: &ast::TranslationUnit, interner: &Interner, diags: &mut Diagnostics) -> Checked {
    let kind = unit.items.iter().find_map(|i| match i {
        ast::Item::Shader(s) => Some(s.kind),
        _ => None,
    });
    let incomplete = diags.has_errors();
    let mut c = Checker {
        interner,
        diags,
        functions: Vec::new(),
        sigs: Vec::new(),
        top_funcs: FxHashMap::default(),
        builders: Vec::new(),
        kind,
        shader: None,
        call_graph: Vec::new(),
        builder_funcs: Vec::new(),
        deferred: Vec::new(),
        incomplete,
        depth: 0,
        depth_reported: false,
        spare_scopes: Vec::new(),
    };
    let mut shader_seen: Option<Span> = None;
    for item in unit.items {
        match item {
            ast::Item::Function(f) => c.top_level_function(f),
            ast::Item::Shader(s) => {
                if let Some(first) = shader_seen {
                    c.diags.push(
                        Diagnostic::new(Code::MultipleShaders, s.name.span, "a file may define only one shader")
                            .with_label("second shader")
                            .with_secondary(first, "first shader defined here"),
                    );
                    continue;
                }
                shader_seen = Some(s.name.span);
                c.shader_def(s);
            }
        }
    }
    c.report_context_errors_of_called_functions();
    c.check_recursion();
    let had_errors = c.diags.has_errors();
    if had_errors {
        return Checked { module: None };
    }
    let mut functions: Vec<Function> = c.functions.into_iter().flatten().collect();
    let mut shader = c.shader;
    let needed = reachable(&functions, shader.as_ref());
    uniformity::infer(&mut functions, shader.as_ref(), &needed, c.diags);
    if c.diags.has_errors() {
        return Checked { module: None };
    }
    // Functions the shader never calls (most of a header's) have been checked; back ends need only
    // the rest.
    let functions = prune(functions, &needed, shader.as_mut());
    let module = Module { shader, functions };
    if !within_inline_budget(&module, c.diags)
        || !within_inlined_nesting(&module, c.diags)
        || !within_measured_budgets(&module, c.diags)
    {
        return Checked { module: None };
    }
    Checked { module: Some(module) }
}

/// The JIT inlines every user function call, so a shader's size after inlining is what it compiles;
/// nested calls can make that exponential in the source. Over [`ir::INLINE_BUDGET`] the shader is
/// refused, at the first call of its body that takes it over.
fn within_inline_budget(m: &Module, diags: &mut Diagnostics) -> bool {
    let Some(shader) = &m.shader else { return true };
    let sizes = ir::inlined_sizes(m);
    let body_id = shader.body.0 as usize;
    if sizes.get(body_id).is_none_or(|s| *s <= ir::INLINE_BUDGET) {
        return true;
    }
    let body = &m.functions[body_id];
    let mut total = ir::own_size(body);
    for e in &body.exprs {
        let ir::ExprKind::Call { func, .. } = e.kind else { continue };
        let callee = sizes.get(func.0 as usize).copied().unwrap_or(0);
        total = total.saturating_add(callee);
        if total > ir::INLINE_BUDGET {
            let name = m.functions.get(func.0 as usize).map_or("?", |f| f.name.as_str());
            diags.push(
                Diagnostic::new(
                    Code::InlineBudget,
                    e.span,
                    format!(
                        "the shader is too large once its function calls are inlined: this call of `{name}` \
                         inlines {callee} IR nodes, taking the shader past the limit of {}",
                        ir::INLINE_BUDGET
                    ),
                )
                .with_label("takes the shader over the limit")
                .with_note(
                    "every call of a user function is compiled as a copy of its body, and calls nest; \
                     call large functions from fewer places, or keep a result in a variable",
                ),
            );
            return false;
        }
    }
    // No call takes the body over: its own statements are.
    diags.push(Diagnostic::new(
        Code::InlineBudget,
        shader.span,
        format!("the shader is larger than the limit of {} IR nodes", ir::INLINE_BUDGET),
    ));
    false
}

/// Calls inline their callees' blocks inside the caller's, so nesting adds up along a call chain;
/// past [`ir::MAX_INLINED_NESTING`] the shader is refused (E0137) at the body's first call that
/// takes it over, rather than overflowing the stack of the back ends that recurse over blocks.
fn within_inlined_nesting(m: &Module, diags: &mut Diagnostics) -> bool {
    let Some(shader) = &m.shader else { return true };
    let depths = ir::inlined_nesting(m);
    let body_id = shader.body.0 as usize;
    if depths.get(body_id).is_none_or(|d| *d <= ir::MAX_INLINED_NESTING) {
        return true;
    }
    let body = &m.functions[body_id];
    let own = ir::block_depth(&body.body);
    let over = body.exprs.iter().find_map(|e| match e.kind {
        ir::ExprKind::Call { func, .. } => {
            let callee = depths.get(func.0 as usize).copied().unwrap_or(0);
            (own.saturating_add(callee) > ir::MAX_INLINED_NESTING).then_some((e.span, func, callee))
        }
        _ => None,
    });
    let limit = ir::MAX_INLINED_NESTING;
    let d = match over {
        Some((span, func, callee)) => {
            let name = m.functions.get(func.0 as usize).map_or("?", |f| f.name.as_str());
            Diagnostic::new(
                Code::InlineBudget,
                span,
                format!(
                    "the shader nests too deeply once its function calls are inlined: `{name}` and what it \
                     calls nest {callee} levels, inside a body {own} deep, past the limit of {limit}"
                ),
            )
            .with_label("takes the shader over the limit")
            .with_note(
                "a call is compiled as a copy of the callee's body where the call is, so nesting adds up \
                 along a chain of calls",
            )
        }
        None => Diagnostic::new(
            Code::InlineBudget,
            shader.span,
            format!("the shader nests deeper than the limit of {limit} levels once its calls are inlined"),
        ),
    };
    diags.push(d);
    false
}

/// A shader within the inlining budget can still hold or handle arrays the JIT cannot afford: its
/// variables' floats are held to [`ir::STORAGE_BUDGET`] (E0138, at the variable that takes it
/// over) and its size with arrays counted by their floats to [`ir::INLINE_BUDGET`] (E0137, at the
/// expression). A variable or expression of a function the body calls is shown with that call.
fn within_measured_budgets(m: &Module, diags: &mut Diagnostics) -> bool {
    use ir::storage::Culprit;
    let measure = ir::storage::measure(m);
    let Some(shader) = &m.shader else { return true };
    let function = |o: &ir::storage::Over| m.functions.get(o.func.0 as usize);
    let inlined_by = |d: Diagnostic, o: &ir::storage::Over| match (o.call, function(o)) {
        (Some(call), Some(f)) => d.with_secondary(call, format!("`{}` is inlined by this call", f.name)),
        _ => d,
    };
    if let Some(o) = &measure.storage_over {
        let var = match o.what {
            Culprit::Var(v) => function(o).and_then(|f| f.vars.get(v.0 as usize)),
            _ => None,
        };
        let (span, what) = match var {
            Some(v) => (v.span, format!("`{}` ({}) holds {} floats", v.name, v.ty, o.amount)),
            None => (shader.span, format!("a variable holds {} floats", o.amount)),
        };
        let d = Diagnostic::new(
            Code::StorageBudget,
            span,
            format!(
                "{what}, taking the shader's variables past the limit of {} floats per shading point",
                ir::STORAGE_BUDGET
            ),
        )
        .with_label("takes the shader over the limit")
        .with_note(
            "every component of every variable counts (a triple three floats, a matrix sixteen, an array its \
             length times that), in every call of a function, as each call is compiled as a copy; use smaller \
             arrays",
        );
        diags.push(inlined_by(d, o));
        return false;
    }
    if let Some(o) = &measure.nodes_over {
        let expr = match o.what {
            Culprit::Expr(e) => function(o).and_then(|f| f.exprs.get(e.0 as usize)),
            _ => None,
        };
        let d = match expr {
            Some(e) => Diagnostic::new(
                Code::InlineBudget,
                e.span,
                format!(
                    "the shader is too large once its function calls are inlined: this use of an array counts {} \
                     IR nodes, one per float of the array, taking the shader past the limit of {}",
                    o.amount,
                    ir::INLINE_BUDGET
                ),
            )
            .with_label("takes the shader over the limit")
            .with_note(
                "an array value, or an element read or written at an index computed at run time, is compiled \
                 as code for each float of the array; use smaller arrays, or index them in fewer places",
            ),
            None => Diagnostic::new(
                Code::InlineBudget,
                o.call.unwrap_or(shader.span),
                format!(
                    "the shader is larger than the limit of {} IR nodes once its function calls are inlined and \
                     every use of an array is counted by the array's floats",
                    ir::INLINE_BUDGET
                ),
            ),
        };
        diags.push(inlined_by(d, o));
        return false;
    }
    true
}

/// Which functions a shader can reach through calls (all of them in a file without a shader).
fn reachable(functions: &[Function], shader: Option<&ir::Shader>) -> Vec<bool> {
    let Some(shader) = shader else {
        return vec![true; functions.len()];
    };
    let mut seen = vec![false; functions.len()];
    let mut stack = vec![shader.body.0 as usize];
    while let Some(i) = stack.pop() {
        if i >= seen.len() || seen[i] {
            continue;
        }
        seen[i] = true;
        for e in &functions[i].exprs {
            if let ir::ExprKind::Call { func, .. } = e.kind {
                stack.push(func.0 as usize);
            }
        }
    }
    seen
}

/// Drops the functions not `needed`, renumbering calls and the shader's body.
fn prune(functions: Vec<Function>, needed: &[bool], shader: Option<&mut ir::Shader>) -> Vec<Function> {
    if needed.iter().all(|n| *n) {
        return functions;
    }
    let mut new_id = vec![u32::MAX; functions.len()];
    let mut next = 0;
    for (i, keep) in needed.iter().enumerate() {
        if *keep {
            new_id[i] = next;
            next += 1;
        }
    }
    if let Some(s) = shader {
        s.body = FuncId(new_id[s.body.0 as usize]);
    }
    functions
        .into_iter()
        .zip(needed)
        .filter(|(_, keep)| **keep)
        .map(|(mut f, _)| {
            for e in &mut f.exprs {
                if let ir::ExprKind::Call { func, .. } = &mut e.kind {
                    *func = FuncId(new_id[func.0 as usize]);
                }
            }
            f
        })
        .collect()
}

impl Checker<'_> {
    fn name(&self, sym: Symbol) -> &str {
        self.interner.resolve(sym)
    }

    /// Enters one level of nesting; false (with one error per file) when too deep.
    fn enter(&mut self, span: Span) -> bool {
        if self.depth >= MAX_NESTING {
            if !self.depth_reported {
                self.depth_reported = true;
                self.error(
                    Code::Syntax,
                    span,
                    format!("expressions or statements nest more than {MAX_NESTING} levels deep"),
                )
                .with_label("too deeply nested")
                .notes
                .push("split the expression with temporary variables".into());
            }
            return false;
        }
        self.depth += 1;
        true
    }

    fn b(&mut self) -> &mut FnBuilder {
        self.builders.last_mut().expect("a function is being lowered")
    }

    fn cur(&self) -> &FnBuilder {
        self.builders.last().expect("a function is being lowered")
    }

    fn error(&mut self, code: Code, span: Span, message: impl Into<String>) -> &mut Diagnostic {
        self.diags.push(Diagnostic::new(code, span, message));
        self.diags.list.last_mut().expect("just pushed")
    }

    /// An error against the shader type's context rules: in the shader's body at once, in a
    /// function only if the shader calls it (see [`Checker::deferred`]).
    fn context_error(&mut self, owner: Option<usize>, code: Code, span: Span, message: impl Into<String>) -> &mut Diagnostic {
        match owner {
            Some(index) => {
                self.deferred.push((index, Diagnostic::new(code, span, message)));
                &mut self.deferred.last_mut().expect("just pushed").1
            }
            None => self.error(code, span, message),
        }
    }

    /// The function whose body is being checked; `None` in the shader's.
    fn current_function(&self) -> Option<usize> {
        self.builder_funcs.last().copied().flatten()
    }

    /// Reports the deferred context errors of the functions the shader calls, directly or not.
    fn report_context_errors_of_called_functions(&mut self) {
        let n = self.sigs.len();
        let mut called = vec![false; n];
        let mut work: Vec<usize> =
            self.call_graph.iter().filter(|(caller, ..)| caller.is_none()).map(|(_, callee, _)| *callee).collect();
        while let Some(f) = work.pop() {
            if f < n && !called[f] {
                called[f] = true;
                work.extend(self.call_graph.iter().filter(|(caller, ..)| *caller == Some(f)).map(|(_, c, _)| *c));
            }
        }
        for (index, d) in std::mem::take(&mut self.deferred) {
            if called.get(index).copied().unwrap_or(false) {
                self.diags.push(d.with_note("in a function this shader calls"));
            }
        }
    }

    // ---- Items ----------------------------------------------------------------------------------

    fn resolve_type(&mut self, spec: &ast::TypeSpec) -> ir::BaseType {
        spec.name.into()
    }

    /// The array length of a declaration, which must be a positive integer constant.
    fn array_len(&mut self, spec: &Option<ast::ArraySpec>, allow_unsized: bool) -> Option<Option<ir::ArrayLen>> {
        match spec {
            None => Some(None),
            Some(ast::ArraySpec::Unsized(span)) => {
                if allow_unsized {
                    Some(Some(ir::ArrayLen::Unsized))
                } else {
                    self.error(Code::ArraySize, *span, "an array variable needs a length").label =
                        Some("length missing".into());
                    None
                }
            }
            Some(ast::ArraySpec::Sized(e)) => match const_number(e) {
                Some(v) if v >= 1.0 && v.fract() == 0.0 && v <= f64::from(ir::MAX_ARRAY_LEN) => {
                    Some(Some(ir::ArrayLen::Fixed(v as u32)))
                }
                Some(v) if v > f64::from(ir::MAX_ARRAY_LEN) => {
                    let max = ir::MAX_ARRAY_LEN;
                    self.error(Code::ArraySize, e.span, format!("array length {v} is over the limit of {max} elements"))
                        .label = Some("too long".into());
                    None
                }
                Some(v) => {
                    self.error(Code::ArraySize, e.span, format!("array length must be a positive integer, not {v}"))
                        .label = Some("invalid length".into());
                    None
                }
                None => {
                    self.error(Code::ArraySize, e.span, "array length must be a constant number").label =
                        Some("not a constant".into());
                    None
                }
            },
        }
    }

    fn top_level_function(&mut self, f: &ast::FunctionDef) {
        let Some(index) = self.declare_function(f) else { return };
        let sym = f.name.sym;
        self.top_funcs.entry(sym).or_default().push(index);
        self.lower_function(f, index);
    }

    /// Records a function's signature and returns its index, or reports a redefinition.
    fn declare_function(&mut self, f: &ast::FunctionDef) -> Option<usize> {
        let ret_base = self.resolve_type(&f.return_type);
        let mut params = Vec::new();
        for p in f.params {
            let base = self.resolve_type(&p.ty);
            let array = self.array_len(&p.array, true).unwrap_or(None);
            params.push((Type { base, array }, p.output));
        }
        let ret = Type::scalar(ret_base);
        // A function with the same name and parameter types in the same scope is a redefinition.
        let existing: Vec<usize> = match self.builders.last() {
            Some(b) => b.scopes.last().and_then(|s| s.funcs.get(&f.name.sym)).cloned().unwrap_or_default(),
            None => self.top_funcs.get(&f.name.sym).cloned().unwrap_or_default(),
        };
        for i in existing {
            let same = self.sigs[i].params.len() == params.len()
                && self.sigs[i].params.iter().zip(&params).all(|(a, b)| a.0 == b.0);
            if same {
                let prev = self.sigs[i].span;
                let name = self.name(f.name.sym).to_string();
                self.error(
                    Code::FunctionRedefinition,
                    f.name.span,
                    format!("function `{name}` is defined twice with the same parameter types"),
                )
                .with_label("redefined here")
                .secondary
                .push((prev, "first defined here".into()));
                return None;
            }
        }
        let index = self.sigs.len();
        self.sigs.push(FuncSig { id: FuncId(index as u32), params, ret, span: f.name.span, captures: Vec::new() });
        self.functions.push(None);
        Some(index)
    }

    fn lower_function(&mut self, f: &ast::FunctionDef, index: usize) {
        let name = self.name(f.name.sym).to_string();
        let ret = self.sigs[index].ret;
        let mut builder = FnBuilder::new(name, ret, f.span, false);
        // The function is visible inside its own body (so recursion is found and reported).
        builder.scopes[0].funcs.entry(f.name.sym).or_default().push(index);
        self.builders.push(builder);
        self.builder_funcs.push(Some(index));
        for (i, p) in f.params.iter().enumerate() {
            let ty = self.sigs[index].params[i].0;
            if let Some(d) = &p.default {
                self.error(Code::Syntax, d.span, "function parameters cannot have default values").label =
                    Some("remove this default".into());
            }
            let declared = p.ty.storage.map(|s| s == ast::Storage::Varying);
            if ty.base == ir::BaseType::String && declared == Some(true) {
                self.error(Code::VaryingString, p.ty.span, "strings are always uniform").label =
                    Some("`varying` string".into());
            }
            if ty.base == ir::BaseType::Void {
                self.error(Code::AssignTypeMismatch, p.ty.span, "a parameter cannot have type `void`");
            }
            let id = self.declare_var(p.name, ty, VarKind::Param { output: p.output }, declared);
            if let Some(id) = id {
                self.b().func.params.push(id);
            }
        }
        let body = self.block(&f.body, false);
        if ret.base != ir::BaseType::Void && !always_returns(&body) && !self.incomplete {
            let name = self.name(f.name.sym).to_string();
            self.error(
                Code::MissingReturn,
                f.name.span,
                format!("function `{name}` can reach its end without returning a `{}`", ret.base),
            )
            .with_label("in this function")
            .notes
            .push("add a `return` at the end of the function".into());
        }
        self.b().func.body = body;
        self.finish_builder(index);
    }

    /// Ends the current builder: warns about unused variables and stores the function.
    fn finish_builder(&mut self, index: usize) {
        let mut b = self.builders.pop().expect("builder to finish");
        self.builder_funcs.pop();
        self.warn_unused(&b);
        // Captured variables become trailing parameters.
        let mut captures = Vec::new();
        for (outer, local) in &b.captures {
            b.func.params.push(*local);
            captures.push(*outer);
        }
        self.sigs[index].captures = captures;
        for (callee, span) in &b.calls {
            self.call_graph.push((Some(index), *callee, *span));
        }
        if let Some(span) = b.uses_light_loop {
            self.check_light_loop_context(Some(index), span);
        }
        self.functions[index] = Some(b.func);
    }

    fn warn_unused(&mut self, b: &FnBuilder) {
        if self.incomplete {
            return;
        }
        for (i, var) in b.func.vars.iter().enumerate() {
            if b.used[i] || var.name.starts_with('_') {
                continue;
            }
            let (code, what) = match var.kind {
                VarKind::Local => (Code::UnusedVariable, "variable"),
                VarKind::Param { output: false } => (Code::UnusedParameter, "parameter"),
                VarKind::ShaderParam { output: false, .. } => (Code::UnusedParameter, "shader parameter"),
                _ => continue,
            };
            self.diags.push(
                Diagnostic::new(code, var.span, format!("unused {what} `{}`", var.name))
                    .with_label("never read")
                    .with_note(format!("if this is intentional, prefix it with an underscore: `_{}`", var.name)),
            );
        }
    }

    fn check_light_loop_context(&mut self, owner: Option<usize>, span: Span) {
        if let Some(kind) = self.kind {
            if !matches!(kind, ShaderKind::Surface | ShaderKind::Volume | ShaderKind::Lightfield) {
                self.context_error(
                    owner,
                    Code::IlluminanceContext,
                    span,
                    format!("`illuminance` and `gather` are not available in {} shaders", kind.name()),
                )
                .with_label("light loop here")
                .notes
                .push("light loops run in surface, volume and lightfield shaders".into());
            }
        }
    }

    fn shader_def(&mut self, s: &ast::ShaderDef) {
        let name = self.name(s.name.sym).to_string();
        let index = self.sigs.len();
        // The shader body is stored as a function too; it has no callers.
        self.sigs.push(FuncSig {
            id: FuncId(index as u32),
            params: Vec::new(),
            ret: Type::VOID,
            span: s.name.span,
            captures: Vec::new(),
        });
        self.functions.push(None);
        self.builders.push(FnBuilder::new(name.clone(), Type::VOID, s.span, true));
        self.builder_funcs.push(None);
        let mut params = Vec::new();
        for p in s.params {
            if let Some(param) = self.shader_param(p, params.len() as u32) {
                params.push(param);
            }
        }
        // The body is a scope of its own: a local may hide a parameter (with a warning).
        let body = self.block(&s.body, true);
        self.b().func.body = body;
        let b = self.builders.last().expect("shader builder");
        let calls = b.calls.clone();
        for (callee, span) in calls {
            self.call_graph.push((None, callee, span));
        }
        if let Some(span) = b.uses_light_loop {
            self.check_light_loop_context(None, span);
        }
        let b = self.builders.pop().expect("shader builder");
        self.builder_funcs.pop();
        self.warn_unused(&b);
        self.functions[index] = Some(b.func);
        // Function indices shift when unused slots are dropped; only failed functions leave `None`,
        // and then there are errors and no IR, so ids stay valid.
        self.shader = Some(ir::Shader { kind: s.kind, name, body: FuncId(index as u32), params, span: s.span });
    }

    fn shader_param(&mut self, p: &ast::ParamDecl, index: u32) -> Option<ir::ShaderParam> {
        let base = self.resolve_type(&p.ty);
        let array = self.array_len(&p.array, false)?;
        let ty = Type { base, array };
        let pname = self.name(p.name.sym).to_string();
        if base == ir::BaseType::Void {
            self.error(Code::AssignTypeMismatch, p.ty.span, "a parameter cannot have type `void`");
            return None;
        }
        let declared_varying = p.ty.storage == Some(ast::Storage::Varying);
        if base == ir::BaseType::String && declared_varying {
            self.error(Code::VaryingString, p.ty.span, "strings are always uniform").label =
                Some("`varying` string".into());
        }
        if let Some(g) = Global::lookup(&pname) {
            if self.kind.is_some_and(|k| g.def().access(k) != crate::globals::Access::None) {
                self.error(
                    Code::ShaderGlobalRedeclared,
                    p.name.span,
                    format!("shader parameter `{pname}` has the name of a shader global"),
                )
                .label = Some("rename this parameter".into());
                return None;
            }
        }
        let Some(default) = &p.default else {
            self.error(Code::MissingDefault, p.name.span, format!("shader parameter `{pname}` needs a default value"))
                .with_label("no default")
                .notes
                .push(format!("write e.g. `{} {pname} = {}`", base, example_default(base)));
            // Declare it anyway so that its uses do not cascade.
            let _ =
                self.declare_var(p.name, ty, VarKind::ShaderParam { index, output: p.output }, Some(declared_varying));
            return None;
        };
        // The default is checked before the parameter is in scope (earlier parameters are).
        let value = self.initializer(default, ty)?;
        let var =
            self.declare_var(p.name, ty, VarKind::ShaderParam { index, output: p.output }, Some(declared_varying))?;
        Some(ir::ShaderParam {
            name: pname,
            ty,
            varying: declared_varying,
            output: p.output,
            var,
            default: value,
            span: p.span,
        })
    }

    // ---- Scopes ---------------------------------------------------------------------------------

    fn push_scope(&mut self) {
        let scope = self.spare_scopes.pop().unwrap_or_default();
        self.b().scopes.push(scope);
    }

    fn pop_scope(&mut self) {
        if let Some(mut scope) = self.b().scopes.pop() {
            scope.vars.clear();
            scope.funcs.clear();
            self.spare_scopes.push(scope);
        }
    }

    /// Declares a variable in the innermost scope, reporting a redefinition.
    fn declare_var(
        &mut self,
        name: ast::Ident,
        ty: Type,
        kind: VarKind,
        declared_varying: Option<bool>,
    ) -> Option<VarId> {
        let text = self.name(name.sym).to_string();
        if let Some(Binding::Var(prev)) = self.cur().scopes.last().and_then(|s| s.vars.get(&name.sym)).copied() {
            let prev_span = self.cur().func.var(prev).span;
            let prev_is_param =
                matches!(self.cur().func.var(prev).kind, VarKind::Param { .. } | VarKind::ShaderParam { .. });
            let is_param = matches!(kind, VarKind::Param { .. } | VarKind::ShaderParam { .. });
            let (code, msg) = if is_param && prev_is_param {
                (Code::DuplicateParameter, format!("two parameters are named `{text}`"))
            } else {
                (Code::Redefinition, format!("`{text}` is already declared in this scope"))
            };
            self.error(code, name.span, msg)
                .with_label("declared again here")
                .secondary
                .push((prev_span, "first declared here".into()));
            return None;
        }
        if kind == VarKind::Local {
            self.warn_shadowing(name, &text);
        }
        let varying = declared_varying.unwrap_or(false);
        let id =
            self.b().add_var(Variable { name: text, ty, kind, varying, declared: declared_varying, span: name.span });
        self.b().scopes.last_mut().expect("scope").vars.insert(name.sym, Binding::Var(id));
        Some(id)
    }

    fn warn_shadowing(&mut self, name: ast::Ident, text: &str) {
        let shadowed = if let Some(g) = Global::lookup(text) {
            self.kind
                .is_some_and(|k| g.def().access(k) != crate::globals::Access::None)
                .then(|| format!("the shader global `{text}`"))
        } else {
            match self.lookup_var(name.sym) {
                Some(Binding::Var(v)) if matches!(self.cur().func.var(v).kind, VarKind::ShaderParam { .. }) => {
                    Some(format!("the shader parameter `{text}`"))
                }
                _ => None,
            }
        };
        if let Some(what) = shadowed {
            self.diags.push(
                Diagnostic::new(Code::ShadowedVariable, name.span, format!("local variable `{text}` hides {what}"))
                    .with_label("this declaration")
                    .with_note("rename the local variable to keep the outer one visible"),
            );
        }
    }

    fn lookup_var(&self, sym: Symbol) -> Option<Binding> {
        let b = self.cur();
        b.scopes.iter().rev().find_map(|s| s.vars.get(&sym).copied())
    }

    /// Finds a variable named `sym` visible in builder `level` (its scopes, then those of enclosing
    /// builders) and returns the owning builder and variable.
    fn lookup_outer(&self, level: usize, sym: Symbol) -> Option<(usize, Binding)> {
        for l in (0..=level).rev() {
            if let Some(binding) = self.builders[l].scopes.iter().rev().find_map(|s| s.vars.get(&sym).copied()) {
                return Some((l, binding));
            }
        }
        None
    }

    /// The variable in the current builder that stands for variable `var` of builder `owner`
    /// (creating capture parameters through every builder in between).
    fn access_outer(&mut self, level: usize, owner: usize, var: VarId) -> VarId {
        if level == owner {
            return var;
        }
        let parent_var = self.access_outer(level - 1, owner, var);
        let key = (level - 1, parent_var);
        if let Some((_, local)) = self.builders[level].captures.iter().find(|(k, _)| *k == key) {
            return *local;
        }
        let outer = self.builders[level - 1].func.var(parent_var).clone();
        self.builders[level - 1].used[parent_var.0 as usize] = true;
        let b = &mut self.builders[level];
        let local = b.add_var(Variable { kind: VarKind::Capture, ..outer });
        b.captures.push((key, local));
        local
    }

    /// The functions named `sym` visible here, innermost scope first.
    fn lookup_funcs(&self, sym: Symbol) -> Vec<usize> {
        let mut found = Vec::new();
        for b in self.builders.iter().rev() {
            for s in b.scopes.iter().rev() {
                if let Some(list) = s.funcs.get(&sym) {
                    found.extend(list.iter().copied());
                }
            }
        }
        if let Some(list) = self.top_funcs.get(&sym) {
            found.extend(list.iter().copied());
        }
        let mut unique = Vec::with_capacity(found.len());
        for f in found {
            if !unique.contains(&f) {
                unique.push(f);
            }
        }
        unique
    }

    fn check_recursion(&mut self) {
        let n = self.sigs.len();
        let mut edges: Vec<Vec<(usize, Span)>> = vec![Vec::new(); n];
        for (caller, callee, span) in &self.call_graph {
            if let Some(c) = caller {
                edges[*c].push((*callee, *span));
            }
        }
        // Depth-first search for a cycle from every function; report each function on a cycle once.
        let mut reported = vec![false; n];
        for start in 0..n {
            let mut stack = vec![(start, 0usize)];
            let mut on_path = vec![false; n];
            on_path[start] = true;
            let mut visited = vec![false; n];
            while let Some((node, edge)) = stack.pop() {
                if edge < edges[node].len() {
                    stack.push((node, edge + 1));
                    let (next, span) = edges[node][edge];
                    if next == start && !reported[start] {
                        reported[start] = true;
                        let name = self.functions[start].as_ref().map(|f| f.name.clone()).unwrap_or_default();
                        let def = self.sigs[start].span;
                        self.error(
                            Code::Recursion,
                            span,
                            format!("function `{name}` calls itself; recursion is not allowed"),
                        )
                        .with_label("recursive call")
                        .secondary
                        .push((def, "function defined here".into()));
                    } else if !on_path[next] && !visited[next] {
                        visited[next] = true;
                        on_path[next] = true;
                        stack.push((next, 0));
                    }
                } else {
                    on_path[node] = false;
                }
            }
        }
    }
}

trait WithLabel {
    fn with_label(&mut self, label: &str) -> &mut Self;
}

impl WithLabel for Diagnostic {
    fn with_label(&mut self, label: &str) -> &mut Self {
        self.label = Some(label.to_string());
        self
    }
}

fn example_default(base: ir::BaseType) -> &'static str {
    match base {
        ir::BaseType::String => "\"\"",
        ir::BaseType::Point => "point (0, 0, 0)",
        _ => "1",
    }
}

/// The value of a constant number expression (array sizes, `break` levels).
pub(crate) fn const_number(e: &ast::Expr) -> Option<f64> {
    use ast::{BinaryOp as B, ExprKind as K};
    match &e.kind {
        K::Number(v) => Some(*v),
        K::Unary(ast::UnaryOp::Neg, a) => const_number(a).map(|v| -v),
        K::Binary(op, a, b) => {
            let (a, b) = (const_number(a)?, const_number(b)?);
            match op {
                B::Add => Some(a + b),
                B::Sub => Some(a - b),
                B::Mul => Some(a * b),
                B::Div if b != 0.0 => Some(a / b),
                _ => None,
            }
        }
        K::Cast { ty: ast::TypeName::Float, space: None, expr } => const_number(expr),
        _ => None,
    }
}

/// Whether every path through the block ends in `return`.
fn always_returns(block: &Block) -> bool {
    block.stmts.iter().any(|s| match &s.kind {
        ir::StmtKind::Return(_) => true,
        ir::StmtKind::If { then, otherwise, .. } => always_returns(then) && always_returns(otherwise),
        _ => false,
    })
}
