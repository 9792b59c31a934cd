//! What a shader holds and computes once every user function call is inlined, as the JIT inlines
//! them: the floats its variables hold at one shading point ([`STORAGE_BUDGET`]), and its size
//! with arrays counted by their floats (held to [`super::INLINE_BUDGET`]).
//!
//! The JIT keeps every float of every variable in a Cranelift variable of its own (three with
//! derivatives), and reads an array element at a computed index by looking at every element, so a
//! large array costs memory and code in proportion to its floats wherever it is used; the
//! interpreter gives every call a frame of its own. Each inlined copy of a function has variables
//! of its own, so the measure walks the tree of calls, not the call graph: an array parameter
//! without a length (`float a[]`) takes the length of each call's argument. The walk visits at
//! most as many copies as the shader has calls once inlined, which the inlining budget bounds.

use super::{Arg, ArrayLen, ExprId, ExprKind, FuncId, Function, Module, Place, PlaceBase, Span, Type, VarId};

/// The most floats a shader's variables may hold at one shading point, every inlined call's
/// variables included: a float or a string counts one, a triple three, a matrix sixteen, an array
/// its length times that; uniform and varying variables count alike. Past it the checker refuses
/// the shader (E0138), as the validator refuses a decoded artifact, the JIT a module and the
/// interpreter a run. Cranelift takes at most 65,535 values into a block, and the JIT may keep
/// three for each float (a value and two derivatives). The library and corpus shaders stay far
/// below it (`compiler/tests/corpus.rs` checks the margin).
pub const STORAGE_BUDGET: u64 = 4096;

/// The variable or expression that takes a shader past a budget.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Over {
    /// The function it belongs to.
    pub func: FuncId,
    pub what: Culprit,
    /// What it adds: floats of storage, or IR nodes.
    pub amount: u64,
    /// The shader's total up to and including it.
    pub total: u64,
    /// The call in the shader's body that inlines its function (`None`: the body's own).
    pub call: Option<Span>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Culprit {
    /// A variable, by its storage.
    Var(VarId),
    /// An expression whose value or target is an array, by the array's floats.
    Expr(ExprId),
    /// The function's own expressions and statements.
    Body,
}

/// The result of [`measure`].
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Measure {
    /// Floats the shader's variables hold at one shading point (up to `storage_over`'s when over).
    pub floats: u64,
    /// IR nodes once inlined, an array counting one per float (up to `nodes_over`'s when over).
    pub nodes: u64,
    /// The variable that takes the shader past [`STORAGE_BUDGET`].
    pub storage_over: Option<Over>,
    /// What takes the shader past [`super::INLINE_BUDGET`].
    pub nodes_over: Option<Over>,
    /// The walk gave up: a call cycle, which valid IR never has.
    pub gave_up: bool,
}

/// Floats of a value of type `ty`, with `unsized_len` elements for an unsized array.
pub fn floats(ty: Type, unsized_len: u64) -> u64 {
    let per = match ty.base {
        // A string is a handle, one float.
        super::BaseType::String => 1,
        b => b.components() as u64,
    };
    match ty.array {
        None => per,
        Some(ArrayLen::Fixed(n)) => per * u64::from(n),
        Some(ArrayLen::Unsized) => per.saturating_mul(unsized_len),
    }
}

/// One inlined copy of a function.
struct Inlined {
    func: FuncId,
    /// The element count each unsized array parameter takes in this copy (indexed by variable).
    lens: Vec<u64>,
    /// The call in the shader's body this copy is inlined by.
    call: Option<Span>,
}

impl Inlined {
    fn len(&self, var: usize) -> u64 {
        self.lens.get(var).copied().unwrap_or(0)
    }

    /// The elements of an unsized array value: the unsized parameter it reads, else the widest,
    /// since every unsized value comes from one of them.
    fn unsized_len(&self, f: &Function, e: ExprId) -> u64 {
        match f.exprs.get(e.0 as usize).map(|x| &x.kind) {
            Some(ExprKind::Var(v)) => self.len(v.0 as usize),
            _ => self.lens.iter().copied().max().unwrap_or(0),
        }
    }

    /// IR nodes an expression adds, beyond its own, for the arrays it handles: its value's floats
    /// and those of each array it writes an element of.
    fn array_nodes(&self, f: &Function, id: ExprId) -> u64 {
        let Some(e) = f.exprs.get(id.0 as usize) else { return 0 };
        let mut n = if e.ty.is_array() { floats(e.ty, self.unsized_len(f, id)) } else { 0 };
        let mut place = |p: &Place| {
            if let (PlaceBase::Var(v), Some(_)) = (p.base, p.index) {
                if let Some(var) = f.vars.get(v.0 as usize).filter(|var| var.ty.is_array()) {
                    n = n.saturating_add(floats(var.ty, self.len(v.0 as usize)));
                }
            }
        };
        match &e.kind {
            ExprKind::Assign { place: p, .. } => place(p),
            ExprKind::Call { args, .. } | ExprKind::CallBuiltin { args, .. } => {
                for a in args {
                    if let Arg::Ref(p) = a {
                        place(p);
                    }
                }
            }
            _ => {}
        }
        n
    }

    /// The copies of the functions this copy calls, in expression order.
    fn calls(&self, m: &Module, f: &Function) -> Vec<Inlined> {
        let mut out = Vec::new();
        for e in &f.exprs {
            let ExprKind::Call { func, args } = &e.kind else { continue };
            let Some(callee) = m.functions.get(func.0 as usize) else { continue };
            let mut lens = Vec::new();
            for (k, arg) in args.iter().enumerate() {
                let Some(p) = callee.params.get(k) else { continue };
                if callee.vars.get(p.0 as usize).is_none_or(|v| v.ty.array != Some(ArrayLen::Unsized)) {
                    continue;
                }
                let len = match arg {
                    Arg::Value(v) => match f.exprs.get(v.0 as usize).and_then(|x| x.ty.array) {
                        Some(ArrayLen::Fixed(n)) => u64::from(n),
                        _ => self.unsized_len(f, *v),
                    },
                    Arg::Ref(place) => match (place.ty.array, place.base, place.index) {
                        (Some(ArrayLen::Fixed(n)), _, _) => u64::from(n),
                        (_, PlaceBase::Var(v), None) => self.len(v.0 as usize),
                        _ => self.lens.iter().copied().max().unwrap_or(0),
                    },
                };
                if lens.len() <= p.0 as usize {
                    lens.resize(p.0 as usize + 1, 0);
                }
                lens[p.0 as usize] = len;
            }
            out.push(Inlined { func: *func, lens, call: self.call.or(Some(e.span)) });
        }
        out
    }
}

/// Measures a module's shader, walking its calls in the order the JIT inlines them (a function's
/// own variables and expressions, then its calls in expression order) and stopping once both
/// budgets are passed. A module without a shader holds nothing; handles out of range count nothing
/// (the validator reports them).
pub fn measure(m: &Module) -> Measure {
    let mut out = Measure::default();
    let Some(shader) = &m.shader else { return out };
    let mut stack = vec![Inlined { func: shader.body, lens: Vec::new(), call: None }];
    let mut copies = 0u64;
    let over = |copy: &Inlined, what, amount, total| Over { func: copy.func, what, amount, total, call: copy.call };
    while let Some(copy) = stack.pop() {
        copies += 1;
        // Each copy but the body's is a call the inlining budget counts: only a call cycle (IR
        // the validator refuses) gets here.
        if copies > super::INLINE_BUDGET + 1 {
            out.gave_up = true;
            return out;
        }
        let Some(f) = m.functions.get(copy.func.0 as usize) else { continue };
        if out.storage_over.is_none() {
            for (i, var) in f.vars.iter().enumerate() {
                let n = floats(var.ty, copy.len(i));
                out.floats = out.floats.saturating_add(n);
                if out.floats > STORAGE_BUDGET {
                    out.storage_over = Some(over(&copy, Culprit::Var(VarId(i as u32)), n, out.floats));
                    break;
                }
            }
        }
        if out.nodes_over.is_none() {
            let own = super::own_size(f);
            out.nodes = out.nodes.saturating_add(own);
            if out.nodes > super::INLINE_BUDGET {
                out.nodes_over = Some(over(&copy, Culprit::Body, own, out.nodes));
            }
            for i in 0..f.exprs.len() {
                if out.nodes_over.is_some() {
                    break;
                }
                let n = copy.array_nodes(f, ExprId(i as u32));
                out.nodes = out.nodes.saturating_add(n);
                if out.nodes > super::INLINE_BUDGET {
                    out.nodes_over = Some(over(&copy, Culprit::Expr(ExprId(i as u32)), n, out.nodes));
                }
            }
        }
        if out.storage_over.is_some() && out.nodes_over.is_some() {
            break;
        }
        stack.extend(copy.calls(m, f).into_iter().rev());
    }
    out
}

/// Why a module's shader is over a budget, in words naming the variable or expression (for the
/// validator, the JIT and the interpreter; the checker's diagnostics say the same with positions).
pub fn describe(m: &Module, measure: &Measure) -> Option<String> {
    let name = |o: &Over| m.functions.get(o.func.0 as usize).map_or("?", |f| f.name.as_str());
    if let Some(o) = &measure.storage_over {
        let f = m.functions.get(o.func.0 as usize);
        let var = match o.what {
            Culprit::Var(v) => f.and_then(|f| f.vars.get(v.0 as usize)),
            _ => None,
        };
        let what = var.map_or_else(|| "a variable".to_string(), |v| format!("`{}` ({})", v.name, v.ty));
        return Some(format!(
            "the shader needs more than {STORAGE_BUDGET} floats of storage at each shading point: {what} in `{}` \
             takes {} and brings it to {}",
            name(o),
            o.amount,
            o.total
        ));
    }
    if let Some(o) = &measure.nodes_over {
        return Some(format!(
            "the shader is larger than {} IR nodes once its calls are inlined and its arrays counted by their floats \
             (in `{}`)",
            super::INLINE_BUDGET,
            name(o)
        ));
    }
    measure.gave_up.then(|| "the shader's calls do not end (a call cycle)".to_string())
}
