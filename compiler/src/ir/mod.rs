//! The typed, checked intermediate representation that back ends consume.
//!
//! A [`Module`] is what one `.sl` file compiles to: at most one [`Shader`] and the user functions it
//! can call, all as [`Function`]s (functions a shader never reaches, such as most of an included
//! header's, are checked and then left out; a file without a shader keeps every function). Every function owns its variables and an arena of expressions; handles
//! ([`VarId`], [`ExprId`], [`FuncId`]) are plain indices into those vectors.
//!
//! ## Semantics
//! - **Expressions form trees.** Each `ExprId` is used by exactly one parent (an expression or a
//!   statement). Evaluation is left to right, depth first; expressions may have effects (assignments,
//!   calls with output arguments, `printf`), which happen in that order.
//! - **Statements form a tree** of [`Block`]s. `Loop` evaluates `cond` before each iteration, runs
//!   `body`, then `step` (where `continue` lands). `Break(n)`/`Continue(n)` leave `n` enclosing loops;
//!   light loops (`illuminance`, `gather`) count as loops.
//! - **Loops are budgeted per invocation** ([`LOOP_BUDGET`] by default): each time any `Loop` is
//!   about to test its condition, one counter for the whole invocation goes up; once it passes the
//!   budget, that loop and every loop reached afterwards is left as by `break` and the shader goes
//!   on. One counter rather than one per loop, so nesting cannot multiply the budget.
//! - **Types are explicit.** Every expression has its [`Type`]; implicit conversions of the source
//!   (float to triple or matrix, among point/vector/normal, relation to float) are `Convert` nodes, so
//!   operands of a `Binary` have the types its operator expects (see [`BinaryOp`]).
//! - **Uniform and varying.** `varying` on an expression means its value may differ between the lanes
//!   of a batch; a uniform value is the same for every lane and back ends keep it as one scalar. The
//!   checker infers it: a variable is varying if it was declared so, or (when not declared `uniform`)
//!   if any varying value or any assignment under varying control flow reaches it. A value flowing
//!   into a variable declared `uniform` is an error, so in valid IR a uniform variable is only ever
//!   assigned uniform values under uniform control flow.
//! - **Control flow and masks.** A condition that is varying makes its statement divergent: back ends
//!   run both branches under lane masks; uniform conditions are ordinary branches. Only lanes active
//!   at a statement are ever written by it.
//! - **Functions** are called by [`ExprKind::Call`]; arguments to `output` parameters are
//!   [`Place`]s (passed by reference). Nested functions that used `extern` variables of enclosing
//!   functions receive them as extra by-reference parameters (`Variable::kind == Capture`), appended
//!   after the declared ones; callers pass them. There is no recursion (the checker rejects it), so
//!   back ends may inline every call.

pub mod deriv;
mod kind;
pub mod print;
pub mod storage;
pub mod types;

use crate::builtins::Builtin;
use crate::globals::Global;
use crate::source::Span;
pub use kind::ShaderKind;
pub use storage::STORAGE_BUDGET;
pub use types::{ArrayLen, BaseType, Type};

/// The longest array the checker accepts (and the validator lets through).
pub const MAX_ARRAY_LEN: u32 = 1_000_000;

/// The loop iterations one shader invocation may run, all loops together (see the module doc).
pub const LOOP_BUDGET: u32 = 1 << 20;

/// Index of a function in [`Module::functions`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize, serde::Deserialize)]
pub struct FuncId(pub u32);

/// Index of a variable in [`Function::vars`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize, serde::Deserialize)]
pub struct VarId(pub u32);

/// Index of an expression in [`Function::exprs`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize, serde::Deserialize)]
pub struct ExprId(pub u32);

#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Module {
    pub shader: Option<Shader>,
    pub functions: Vec<Function>,
}

impl Module {
    pub fn function(&self, id: FuncId) -> &Function {
        &self.functions[id.0 as usize]
    }

    /// The IR as text (`rtsl compile --emit-ir`).
    pub fn to_text(&self) -> String {
        print::module(self)
    }
}

/// The shader a file defines: its interface and the function holding its body.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Shader {
    pub kind: ShaderKind,
    pub name: String,
    /// The body. Its variables include the parameters, as `VarKind::ShaderParam`.
    pub body: FuncId,
    pub params: Vec<ShaderParam>,
    pub span: Span,
}

#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct ShaderParam {
    pub name: String,
    pub ty: Type,
    /// Whether the parameter is varying (declared `varying`); parameters are uniform by default.
    pub varying: bool,
    pub output: bool,
    /// The variable in the body function that holds the parameter.
    pub var: VarId,
    /// The default value, an expression in the body function, evaluated when no value is bound
    /// (defaults are evaluated in order, and may use earlier parameters).
    pub default: ExprId,
    pub span: Span,
}

#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Function {
    pub name: String,
    pub return_type: Type,
    /// The parameters in call order: declared ones, then captured `extern` variables.
    pub params: Vec<VarId>,
    pub vars: Vec<Variable>,
    pub exprs: Vec<Expr>,
    pub body: Block,
    pub span: Span,
    /// Whether the result depends on varying state beyond its arguments (varying globals, varying
    /// built-ins, captured varying variables). A call's result is varying if this is set or any
    /// argument is varying.
    pub reads_varying: bool,
}

impl Function {
    pub fn var(&self, id: VarId) -> &Variable {
        &self.vars[id.0 as usize]
    }

    pub fn expr(&self, id: ExprId) -> &Expr {
        &self.exprs[id.0 as usize]
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum VarKind {
    Local,
    /// A declared parameter of a user function.
    Param {
        output: bool,
    },
    /// A shader parameter (index into [`Shader::params`]).
    ShaderParam {
        index: u32,
        output: bool,
    },
    /// An `extern` variable of an enclosing function, passed by reference.
    Capture,
}

#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Variable {
    pub name: String,
    pub ty: Type,
    pub kind: VarKind,
    /// Inferred (or declared) storage: see the module docs.
    pub varying: bool,
    /// Declared `uniform` (so a varying value reaching it is an error) or `varying`.
    pub declared: Option<bool>,
    pub span: Span,
}

#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Expr {
    pub kind: ExprKind,
    pub ty: Type,
    pub varying: bool,
    pub span: Span,
}

/// A compile-time constant.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum Constant {
    Float(f32),
    String(String),
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum UnaryOp {
    /// Negation of a float, triple or matrix.
    Neg,
    /// Logical not of a bool.
    Not,
}

/// Binary operators on checked operand types.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum BinaryOp {
    /// Component-wise on equal numeric types; on matrices, the element-wise sum.
    Add,
    Sub,
    /// Component-wise on equal numeric types; on matrices, the matrix product.
    Mul,
    /// Component-wise on equal numeric types; on matrices, `a * inverse(b)`.
    Div,
    /// Cross product of two point-like triples (or colours, component-wise formula).
    Cross,
    /// Dot product of two triples, a float.
    Dot,
    Lt,
    Gt,
    Le,
    Ge,
    /// Equality of equal types (floats, triples, matrices, strings), a bool.
    Eq,
    Ne,
    /// Logical, on bools; the right side is evaluated only where needed (lanes where it matters).
    And,
    Or,
}

/// Where a value is stored: an assignment target or an output argument.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Place {
    pub base: PlaceBase,
    /// An array element (when the base is an array) or a component of a triple (0-2).
    pub index: Option<ExprId>,
    /// For `a[i][j]` where `a` is an array of triples: the component `j` of element `i`.
    pub component: Option<ExprId>,
    /// The type of the place (after indexing).
    pub ty: Type,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum PlaceBase {
    Var(VarId),
    Global(Global),
}

#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub enum Arg {
    Value(ExprId),
    /// An output argument: the callee writes through it.
    Ref(Place),
}

#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub enum ExprKind {
    Const(Constant),
    Var(VarId),
    Global(Global),
    /// An element of an array, or a component of a triple (index is a float, truncated, checked
    /// against the bounds at run time: out-of-range indices are clamped).
    Index {
        base: ExprId,
        index: ExprId,
    },
    Unary {
        op: UnaryOp,
        arg: ExprId,
    },
    Binary {
        op: BinaryOp,
        lhs: ExprId,
        rhs: ExprId,
    },
    /// An implicit or explicit conversion to `self.ty` from the argument's type: float to triple
    /// (all components) or matrix (the diagonal), between point/vector/normal (no change), between
    /// colour and point-like (explicit typecasts only), bool to float, triple to float (the first
    /// component, with a warning).
    Convert {
        arg: ExprId,
    },
    /// A triple from three floats, or a matrix from sixteen.
    Construct {
        args: Vec<ExprId>,
    },
    /// The value `arg` (already of type `self.ty`) was written in `space`: transform it from that
    /// space to "current" (points, vectors, normals, matrices) or convert it from that colour space to
    /// RGB (colours).
    SpaceCast {
        space: ExprId,
        arg: ExprId,
    },
    /// `cond ? a : b`: only the chosen side is evaluated (per lane, when `cond` is varying).
    Select {
        cond: ExprId,
        a: ExprId,
        b: ExprId,
    },
    /// A built-in; `overload` indexes [`crate::builtins::signatures`].
    CallBuiltin {
        builtin: Builtin,
        overload: u16,
        args: Vec<Arg>,
    },
    Call {
        func: FuncId,
        args: Vec<Arg>,
    },
    /// Stores `value` (of the place's type) into the place; with `op`, stores `place op value`
    /// (compound assignment, computed in the place's type). The expression's value is the stored value.
    Assign {
        place: Place,
        op: Option<BinaryOp>,
        value: ExprId,
    },
    /// An array value from its elements (initialisers).
    ArrayLiteral {
        elements: Vec<ExprId>,
    },
}

/// Statements run in order. Decoding one counts its nesting (see [`MAX_DECODED_NESTING`]).
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct Block {
    pub stmts: Vec<Stmt>,
}

/// The most levels blocks may nest in IR decoded from outside (a compiled artifact), a function's
/// body counting as one. Source nests at most 400 levels (`front::check::MAX_NESTING`), so checked
/// IR nests at most 401. Deeper IR is refused as it is decoded, before the decoder's recursion, or
/// any later pass that recurses over blocks (validator, JIT, interpreter), can overflow the stack.
pub const MAX_DECODED_NESTING: u32 = 512;

thread_local! {
    /// Blocks being decoded on this thread, inside each other, and whether one was refused for
    /// nesting too deep since [`decode_nested`] began.
    static DECODING: std::cell::Cell<(u32, bool)> = const { std::cell::Cell::new((0, false)) };
}

/// Runs `decode`, which deserializes IR on this thread, and says whether blocks nested deeper
/// than [`MAX_DECODED_NESTING`] in it: the decoder's own error may not say so (postcard drops the
/// messages of such errors).
pub fn decode_nested<T>(decode: impl FnOnce() -> T) -> (T, bool) {
    let outer = DECODING.with(|d| d.replace((d.get().0, false)));
    let result = decode();
    let too_deep = DECODING.with(|d| d.replace((d.get().0, outer.1 || d.get().1)).1);
    (result, too_deep)
}

impl<'de> serde::Deserialize<'de> for Block {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Block, D::Error> {
        /// The derived encoding, whose recursion this impl counts.
        #[derive(serde::Deserialize)]
        #[serde(rename = "Block")]
        struct Plain {
            stmts: Vec<Stmt>,
        }
        /// Leaves the level on every way out, errors and unwinding included.
        struct Level;
        impl Drop for Level {
            fn drop(&mut self) {
                DECODING.with(|d| d.set((d.get().0.saturating_sub(1), d.get().1)));
            }
        }
        let depth = DECODING.with(|d| {
            let (depth, refused) = d.get();
            d.set((depth + 1, refused));
            depth + 1
        });
        let _level = Level;
        if depth > MAX_DECODED_NESTING {
            DECODING.with(|d| d.set((d.get().0, true)));
            return Err(serde::de::Error::custom(format!(
                "statements nest more than {MAX_DECODED_NESTING} levels deep"
            )));
        }
        Plain::deserialize(d).map(|p| Block { stmts: p.stmts })
    }
}

#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Stmt {
    pub kind: StmtKind,
    pub span: Span,
}

#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub enum StmtKind {
    /// Evaluates an expression for its effects.
    Expr(ExprId),
    If {
        cond: ExprId,
        then: Block,
        otherwise: Block,
    },
    Loop {
        cond: Option<ExprId>,
        body: Block,
        step: Block,
    },
    Break(u32),
    Continue(u32),
    Return(Option<ExprId>),
    /// Runs `body` once per light reaching the point, with `L` (from the point to the light) and `Cl`
    /// set. `category` filters lights; with `axis`/`angle`, only lights within the cone are used.
    Illuminance {
        category: Option<ExprId>,
        position: ExprId,
        cone: Option<(ExprId, ExprId)>,
        body: Block,
    },
    /// Light shaders: emits light from `position` (within the cone if given); `L` is set to the
    /// direction from the light to the surface point before `body` runs.
    Illuminate {
        position: ExprId,
        cone: Option<(ExprId, ExprId)>,
        body: Block,
    },
    /// Light shaders: a distant light, from every direction or along `axis` within `angle`.
    Solar {
        cone: Option<(ExprId, ExprId)>,
        body: Block,
    },
    /// Shoots `samples` rays within a cone; `body` runs for hits (with outputs named in the
    /// parameter list written), `otherwise` for misses.
    Gather {
        category: ExprId,
        position: ExprId,
        direction: ExprId,
        angle: ExprId,
        samples: ExprId,
        /// `"name", value` pairs: names with a `:` (`"surface:Ci"`) are outputs written on hits.
        params: Vec<(ExprId, Arg)>,
        body: Block,
        otherwise: Block,
    },
}

/// The most IR nodes (expressions and statements) a shader may hold once every user function call
/// is inlined, as the JIT inlines them. Calls nest, so a few lines of source can stand for
/// exponentially many nodes (each function calling the previous one twice); past this budget the
/// checker refuses the shader (E0137) instead of letting the JIT run out of memory. The largest
/// library and corpus shaders stay far below it (`compiler/tests/corpus.rs` checks the margin).
pub const INLINE_BUDGET: u64 = 20_000;

/// Whether a module's shader is within [`INLINE_BUDGET`] (its size once inlined, then with its
/// arrays counted by their floats) and [`STORAGE_BUDGET`]; why not, in words, when it is not. For
/// back ends given a module that may not have been checked; the checker says the same with
/// positions.
pub fn within_budgets(m: &Module) -> Result<(), String> {
    let Some(shader) = &m.shader else { return Ok(()) };
    let sizes = inlined_sizes(m);
    if let Some(size) = sizes.get(shader.body.0 as usize).filter(|n| **n > INLINE_BUDGET) {
        return Err(format!("the shader inlines to {size} IR nodes, over the budget of {INLINE_BUDGET}"));
    }
    if let Some(depth) = inlined_nesting(m).get(shader.body.0 as usize).filter(|d| **d > MAX_INLINED_NESTING) {
        return Err(format!(
            "the shader's blocks nest {depth} levels deep once calls are inlined, over the limit of \
             {MAX_INLINED_NESTING}"
        ));
    }
    let measure = storage::measure(m);
    match storage::describe(m, &measure) {
        Some(why) => Err(why),
        None => Ok(()),
    }
}

/// The most levels a shader's blocks may nest once every call is inlined, counted as if each call
/// sat at its caller's deepest level (an upper bound, so that no walk over the call graph's
/// nesting is needed). Each function nests at most 400 levels (`front::check::MAX_NESTING`), but
/// a call inside a deeply nested block inlines another deeply nested body there, and the JIT and
/// the interpreter recurse over the nesting they are given; this keeps them within the stack
/// [`MAX_DECODED_NESTING`] is chosen for. Real shaders nest a few levels a function.
pub const MAX_INLINED_NESTING: u32 = MAX_DECODED_NESTING;

/// How deep a block of `b` nests, `b` counting as one.
pub fn block_depth(b: &Block) -> u32 {
    1 + b
        .stmts
        .iter()
        .map(|s| match &s.kind {
            StmtKind::If { then: x, otherwise: y, .. }
            | StmtKind::Loop { body: x, step: y, .. }
            | StmtKind::Gather { body: x, otherwise: y, .. } => block_depth(x).max(block_depth(y)),
            StmtKind::Illuminance { body, .. } | StmtKind::Illuminate { body, .. } | StmtKind::Solar { body, .. } => {
                block_depth(body)
            }
            _ => 0,
        })
        .max()
        .unwrap_or(0)
}

/// Each function's block nesting once every call in it is inlined, as [`MAX_INLINED_NESTING`]
/// counts it: its own depth plus its deepest callee's (saturating).
pub fn inlined_nesting(m: &Module) -> Vec<u32> {
    over_call_graph(m, |f| u64::from(block_depth(&f.body)), |total, callee| total.max(callee), |own, callees| {
        own.saturating_add(callees)
    })
    .into_iter()
    .map(|d| u32::try_from(d).unwrap_or(u32::MAX))
    .collect()
}

/// Each function's size once every call in it is inlined: its own expressions and statements plus,
/// at each call site, the callee's inlined size (saturating).
pub fn inlined_sizes(m: &Module) -> Vec<u64> {
    over_call_graph(m, own_size, u64::saturating_add, u64::saturating_add)
}

/// A value per function folded over the call graph: `own` of the function, joined by `with` to
/// the fold (by `each`, from 0) of its callees' values at every call site. Memoised, so it costs
/// linear time however large the values are; a call cycle (which valid IR never has) or a call to
/// a missing function counts nothing for the call.
fn over_call_graph(
    m: &Module,
    own: impl Fn(&Function) -> u64,
    each: impl Fn(u64, u64) -> u64,
    with: impl Fn(u64, u64) -> u64,
) -> Vec<u64> {
    let n = m.functions.len();
    // 0: not started, 1: in progress, 2: done.
    let mut state = vec![0u8; n];
    let mut value = vec![0u64; n];
    for root in 0..n {
        if state[root] != 0 {
            continue;
        }
        // An explicit stack rather than recursion: call chains may be as long as the file is. Each
        // entry is a function and how far its expressions have been scanned for callees.
        let mut stack = vec![(root, 0usize)];
        state[root] = 1;
        while let Some(&mut (f, ref mut scanned)) = stack.last_mut() {
            let exprs = &m.functions[f].exprs;
            let pending = exprs[*scanned..].iter().position(|e| match e.kind {
                ExprKind::Call { func, .. } => state.get(func.0 as usize) == Some(&0),
                _ => false,
            });
            if let Some(k) = pending {
                *scanned += k + 1;
                if let ExprKind::Call { func, .. } = exprs[*scanned - 1].kind {
                    state[func.0 as usize] = 1;
                    stack.push((func.0 as usize, 0));
                }
                continue;
            }
            let func = &m.functions[f];
            let mut callees = 0u64;
            for e in &func.exprs {
                if let ExprKind::Call { func: callee, .. } = e.kind {
                    if state.get(callee.0 as usize) == Some(&2) {
                        callees = each(callees, value[callee.0 as usize]);
                    }
                }
            }
            value[f] = with(own(func), callees);
            state[f] = 2;
            stack.pop();
        }
    }
    value
}

/// A function's own expressions and statements, calls not inlined.
pub fn own_size(f: &Function) -> u64 {
    fn stmts(b: &Block) -> u64 {
        b.stmts
            .iter()
            .map(|s| {
                1 + match &s.kind {
                    StmtKind::If { then, otherwise, .. } => stmts(then) + stmts(otherwise),
                    StmtKind::Loop { body, step, .. } => stmts(body) + stmts(step),
                    StmtKind::Illuminance { body, .. }
                    | StmtKind::Illuminate { body, .. }
                    | StmtKind::Solar { body, .. } => stmts(body),
                    StmtKind::Gather { body, otherwise, .. } => stmts(body) + stmts(otherwise),
                    _ => 0,
                }
            })
            .sum()
    }
    f.exprs.len() as u64 + stmts(&f.body)
}
