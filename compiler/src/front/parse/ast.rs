//! The abstract syntax tree: what the parser produces and the checker consumes.
//!
//! It is a faithful tree of what was written, with a [`Span`] on every node, and no types or name
//! resolution yet. Constructs that failed to parse appear as `Error` nodes, so the checker can go on
//! with the rest of the file (it reports nothing about them: the parser already did).
//!
//! Nodes are allocated in a bump arena that the caller of [`parse`](super::parse) owns, and freed
//! all at once when it is reset: no node is dropped on its own, which also means that trees of any
//! depth (`1+1+1+...` with a hundred thousand terms) cannot overflow the stack when they go away.

use crate::source::Span;
use crate::symbol::Symbol;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Ident {
    pub sym: Symbol,
    pub span: Span,
}

pub use crate::ir::ShaderKind;

/// The base types a declaration can name.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum TypeName {
    Float,
    Color,
    Point,
    Vector,
    Normal,
    Matrix,
    String,
    Void,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Storage {
    Uniform,
    Varying,
}

#[derive(Debug, Clone)]
pub struct TranslationUnit<'a> {
    pub items: &'a [Item<'a>],
}

#[derive(Debug, Clone)]
pub enum Item<'a> {
    Function(&'a FunctionDef<'a>),
    Shader(&'a ShaderDef<'a>),
}

#[derive(Debug, Clone)]
pub struct ShaderDef<'a> {
    pub kind: ShaderKind,
    pub name: Ident,
    pub params: &'a [ParamDecl<'a>],
    pub body: Block<'a>,
    pub span: Span,
}

#[derive(Debug, Clone)]
pub struct FunctionDef<'a> {
    pub return_type: TypeSpec,
    pub name: Ident,
    pub params: &'a [ParamDecl<'a>],
    pub body: Block<'a>,
    pub span: Span,
}

/// A type as written: storage class, base type and where it was written.
#[derive(Debug, Clone, Copy)]
pub struct TypeSpec {
    pub storage: Option<Storage>,
    pub name: TypeName,
    pub span: Span,
}

#[derive(Debug, Clone)]
pub enum ArraySpec<'a> {
    Sized(&'a Expr<'a>),
    /// `float a[]`, allowed for function parameters.
    Unsized(Span),
}

/// One parameter of a shader or function (a group `float a = 1, b = 2` becomes several).
#[derive(Debug, Clone)]
pub struct ParamDecl<'a> {
    pub output: bool,
    pub ty: TypeSpec,
    pub name: Ident,
    pub array: Option<ArraySpec<'a>>,
    pub default: Option<Expr<'a>>,
    pub span: Span,
}

#[derive(Debug, Clone)]
pub struct Block<'a> {
    pub stmts: &'a [Stmt<'a>],
}

#[derive(Debug, Clone)]
pub struct Declarator<'a> {
    pub name: Ident,
    pub array: Option<ArraySpec<'a>>,
    pub init: Option<Expr<'a>>,
}

#[derive(Debug, Clone)]
pub struct VarDecl<'a> {
    pub is_extern: bool,
    pub ty: TypeSpec,
    pub vars: &'a [Declarator<'a>],
}

#[derive(Debug, Clone)]
pub struct Stmt<'a> {
    pub kind: StmtKind<'a>,
    pub span: Span,
}

#[derive(Debug, Clone)]
pub enum StmtKind<'a> {
    Decl(VarDecl<'a>),
    Expr(Expr<'a>),
    Block(Block<'a>),
    If {
        cond: Expr<'a>,
        then: &'a Stmt<'a>,
        otherwise: Option<&'a Stmt<'a>>,
    },
    While {
        cond: Expr<'a>,
        body: &'a Stmt<'a>,
    },
    For {
        init: Option<&'a Stmt<'a>>,
        cond: Option<&'a Expr<'a>>,
        step: Option<&'a Expr<'a>>,
        body: &'a Stmt<'a>,
    },
    /// `break n;` (n defaults to 1), with the span of `n` when written.
    Break(u32, Option<Span>),
    Continue(u32, Option<Span>),
    Return(Option<Expr<'a>>),
    /// `illuminance ([category,] position [, axis, angle]) stmt`: the arguments as written.
    Illuminance {
        args: &'a [Expr<'a>],
        body: &'a Stmt<'a>,
    },
    /// `illuminate (position [, axis, angle]) stmt`.
    Illuminate {
        args: &'a [Expr<'a>],
        body: &'a Stmt<'a>,
    },
    /// `solar ([axis, angle]) stmt`.
    Solar {
        args: &'a [Expr<'a>],
        body: &'a Stmt<'a>,
    },
    /// `gather (category, P, dir, angle, samples, params...) stmt [else stmt]`.
    Gather {
        args: &'a [Expr<'a>],
        body: &'a Stmt<'a>,
        otherwise: Option<&'a Stmt<'a>>,
    },
    Function(&'a FunctionDef<'a>),
    Empty,
    /// A statement that failed to parse.
    Error,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum BinaryOp {
    Add,
    Sub,
    Mul,
    Div,
    /// `^`: the cross product.
    Cross,
    /// `.`: the dot product.
    Dot,
    Lt,
    Gt,
    Le,
    Ge,
    Eq,
    Ne,
    And,
    Or,
}

impl BinaryOp {
    pub fn spelling(self) -> &'static str {
        use BinaryOp::*;
        match self {
            Add => "+",
            Sub => "-",
            Mul => "*",
            Div => "/",
            Cross => "^",
            Dot => ".",
            Lt => "<",
            Gt => ">",
            Le => "<=",
            Ge => ">=",
            Eq => "==",
            Ne => "!=",
            And => "&&",
            Or => "||",
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum UnaryOp {
    Neg,
    Not,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum AssignOp {
    Assign,
    Add,
    Sub,
    Mul,
    Div,
}

impl AssignOp {
    pub fn binary(self) -> Option<BinaryOp> {
        match self {
            AssignOp::Assign => None,
            AssignOp::Add => Some(BinaryOp::Add),
            AssignOp::Sub => Some(BinaryOp::Sub),
            AssignOp::Mul => Some(BinaryOp::Mul),
            AssignOp::Div => Some(BinaryOp::Div),
        }
    }
}

#[derive(Debug, Clone)]
pub struct Expr<'a> {
    pub kind: ExprKind<'a>,
    pub span: Span,
}

#[derive(Debug, Clone)]
pub enum ExprKind<'a> {
    /// A number literal, with its spelling.
    Number(f64),
    /// A string literal (adjacent literals already joined).
    String(Symbol),
    Ident(Symbol),
    Index(&'a Expr<'a>, &'a Expr<'a>),
    Call {
        name: Ident,
        args: &'a [Expr<'a>],
    },
    /// `(a, b, c)` or the 16 values of a matrix.
    Tuple(&'a [Expr<'a>]),
    /// `{a, b, c}`: an array initialiser.
    ArrayLiteral(&'a [Expr<'a>]),
    /// `type ["space"] expr`.
    Cast {
        ty: TypeName,
        space: Option<(Symbol, Span)>,
        expr: &'a Expr<'a>,
    },
    Unary(UnaryOp, &'a Expr<'a>),
    Binary(BinaryOp, &'a Expr<'a>, &'a Expr<'a>),
    Ternary(&'a Expr<'a>, &'a Expr<'a>, &'a Expr<'a>),
    Assign(AssignOp, &'a Expr<'a>, &'a Expr<'a>),
    /// `++x`, `x++`, `--x`, `x--` (an extension: the value is the variable after the update for the
    /// prefix form and before it for the postfix form).
    IncDec {
        increment: bool,
        prefix: bool,
        target: &'a Expr<'a>,
    },
    /// An expression that failed to parse.
    Error,
}

impl<'a> Expr<'a> {
    pub fn new(kind: ExprKind<'a>, span: Span) -> Expr<'a> {
        Expr { kind, span }
    }
}

// Nodes live in the parse arena and are never dropped one by one, so these do nothing. Having drop
// glue is still the point: lalrpop moves a popped payload out of its stack symbol only when the
// payload needs dropping; otherwise it drops the whole symbol through an out-of-line call (see
// `parse::Tok`).
impl Drop for Expr<'_> {
    fn drop(&mut self) {}
}

impl Drop for Stmt<'_> {
    fn drop(&mut self) {}
}

impl Drop for Block<'_> {
    fn drop(&mut self) {}
}

impl Drop for VarDecl<'_> {
    fn drop(&mut self) {}
}
