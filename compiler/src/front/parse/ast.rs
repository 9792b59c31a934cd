//! The abstract syntax tree: what the parser produces and the checker consumes.
//!
//! It is a faithful tree of what was written, with a [`Span`] on every node, and no types or name
//! resolution yet. Constructs that failed to parse appear as `Error` nodes, so the checker can go on
//! with the rest of the file (it reports nothing about them: the parser already did).

use crate::source::Span;
use crate::symbol::Symbol;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Ident {
    pub sym: Symbol,
    pub span: Span,
}

/// The shader types of the language and our extensions.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ShaderKind {
    Surface,
    Light,
    Displacement,
    Volume,
    /// RenderMan's imager; `pixel` is a synonym.
    Imager,
    /// Generates primary rays (OpenRT extension).
    Camera,
    /// Looks up a light field on a surface (OpenRT extension).
    Lightfield,
}

impl ShaderKind {
    pub fn name(self) -> &'static str {
        match self {
            ShaderKind::Surface => "surface",
            ShaderKind::Light => "light",
            ShaderKind::Displacement => "displacement",
            ShaderKind::Volume => "volume",
            ShaderKind::Imager => "imager",
            ShaderKind::Camera => "camera",
            ShaderKind::Lightfield => "lightfield",
        }
    }

    pub const ALL: [ShaderKind; 7] = [
        ShaderKind::Surface,
        ShaderKind::Light,
        ShaderKind::Displacement,
        ShaderKind::Volume,
        ShaderKind::Imager,
        ShaderKind::Camera,
        ShaderKind::Lightfield,
    ];
}

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
pub struct TranslationUnit {
    pub items: Vec<Item>,
}

#[derive(Debug, Clone)]
pub enum Item {
    Function(Box<FunctionDef>),
    Shader(Box<ShaderDef>),
    /// Something that failed to parse at the top level.
    Error(Span),
}

#[derive(Debug, Clone)]
pub struct ShaderDef {
    pub kind: ShaderKind,
    pub kind_span: Span,
    pub name: Ident,
    pub params: Vec<ParamDecl>,
    pub body: Block,
    pub span: Span,
}

#[derive(Debug, Clone)]
pub struct FunctionDef {
    pub return_type: TypeSpec,
    pub name: Ident,
    pub params: Vec<ParamDecl>,
    pub body: Block,
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
pub enum ArraySpec {
    Sized(Box<Expr>),
    /// `float a[]`, allowed for function parameters.
    Unsized(Span),
}

/// One parameter of a shader or function (a group `float a = 1, b = 2` becomes several).
#[derive(Debug, Clone)]
pub struct ParamDecl {
    pub output: bool,
    pub ty: TypeSpec,
    pub name: Ident,
    pub array: Option<ArraySpec>,
    pub default: Option<Expr>,
    pub span: Span,
}

#[derive(Debug, Clone)]
pub struct Block {
    pub stmts: Vec<Stmt>,
    pub span: Span,
}

#[derive(Debug, Clone)]
pub struct Declarator {
    pub name: Ident,
    pub array: Option<ArraySpec>,
    pub init: Option<Expr>,
}

#[derive(Debug, Clone)]
pub struct VarDecl {
    pub is_extern: bool,
    pub ty: TypeSpec,
    pub vars: Vec<Declarator>,
    pub span: Span,
}

#[derive(Debug, Clone)]
pub struct Stmt {
    pub kind: StmtKind,
    pub span: Span,
}

#[derive(Debug, Clone)]
pub enum StmtKind {
    Decl(VarDecl),
    Expr(Expr),
    Block(Block),
    If {
        cond: Expr,
        then: Box<Stmt>,
        otherwise: Option<Box<Stmt>>,
    },
    While {
        cond: Expr,
        body: Box<Stmt>,
    },
    For {
        init: Option<Box<Stmt>>,
        cond: Option<Box<Expr>>,
        step: Option<Box<Expr>>,
        body: Box<Stmt>,
    },
    /// `break n;` (n defaults to 1), with the span of `n` when written.
    Break(u32, Option<Span>),
    Continue(u32, Option<Span>),
    Return(Option<Expr>),
    /// `illuminance ([category,] position [, axis, angle]) stmt`: the arguments as written.
    Illuminance {
        args: Vec<Expr>,
        body: Box<Stmt>,
    },
    /// `illuminate (position [, axis, angle]) stmt`.
    Illuminate {
        args: Vec<Expr>,
        body: Box<Stmt>,
    },
    /// `solar ([axis, angle]) stmt`.
    Solar {
        args: Vec<Expr>,
        body: Box<Stmt>,
    },
    /// `gather (category, P, dir, angle, samples, params...) stmt [else stmt]`.
    Gather {
        args: Vec<Expr>,
        body: Box<Stmt>,
        otherwise: Option<Box<Stmt>>,
    },
    Function(Box<FunctionDef>),
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
pub struct Expr {
    pub kind: ExprKind,
    pub span: Span,
}

#[derive(Debug, Clone)]
pub enum ExprKind {
    /// A number literal, with its spelling.
    Number(f64),
    /// A string literal (adjacent literals already joined).
    String(Symbol),
    Ident(Symbol),
    Index(Box<Expr>, Box<Expr>),
    Call {
        name: Ident,
        args: Vec<Expr>,
    },
    /// `(a, b, c)` or the 16 values of a matrix.
    Tuple(Vec<Expr>),
    /// `{a, b, c}`: an array initialiser.
    ArrayLiteral(Vec<Expr>),
    /// `type ["space"] expr`.
    Cast {
        ty: TypeName,
        space: Option<(Symbol, Span)>,
        expr: Box<Expr>,
    },
    Unary(UnaryOp, Box<Expr>),
    Binary(BinaryOp, Box<Expr>, Box<Expr>),
    Ternary(Box<Expr>, Box<Expr>, Box<Expr>),
    Assign(AssignOp, Box<Expr>, Box<Expr>),
    /// `++x`, `x++`, `--x`, `x--` (an extension: the value is the variable after the update for the
    /// prefix form and before it for the postfix form).
    IncDec {
        increment: bool,
        prefix: bool,
        target: Box<Expr>,
    },
    /// An expression that failed to parse.
    Error,
}

impl Expr {
    pub fn new(kind: ExprKind, span: Span) -> Expr {
        Expr { kind, span }
    }
}

/// Deeply nested trees (`1+1+1+...` with a hundred thousand terms, or long `if` chains) would overflow
/// the stack if dropped recursively. Drops recurse normally up to a depth, and past it move children
/// onto a heap stack that the outermost deep drop empties.
mod deep_drop {
    use std::cell::{Cell, RefCell};

    pub const LIMIT: u32 = 200;

    thread_local! {
        pub static DEPTH: Cell<u32> = const { Cell::new(0) };
        pub static PENDING_EXPRS: RefCell<Vec<super::Expr>> = const { RefCell::new(Vec::new()) };
        pub static PENDING_STMTS: RefCell<Vec<super::Stmt>> = const { RefCell::new(Vec::new()) };
    }
}

impl Drop for Expr {
    fn drop(&mut self) {
        if matches!(self.kind, ExprKind::Number(_) | ExprKind::String(_) | ExprKind::Ident(_) | ExprKind::Error) {
            return;
        }
        let kind = std::mem::replace(&mut self.kind, ExprKind::Error);
        let depth = deep_drop::DEPTH.with(|d| d.get());
        if depth >= deep_drop::LIMIT {
            // Too deep: leave the children for the drop below the limit to take care of.
            let mut kind = kind;
            deep_drop::PENDING_EXPRS.with(|p| take_children(&mut kind, &mut p.borrow_mut()));
            return;
        }
        deep_drop::DEPTH.with(|d| d.set(depth + 1));
        drop(kind);
        if depth == 0 {
            // The outermost drop empties what deeper drops left, without recursing deeply.
            while let Some(e) = deep_drop::PENDING_EXPRS.with(|p| p.borrow_mut().pop()) {
                drop(e);
            }
        }
        deep_drop::DEPTH.with(|d| d.set(depth));
    }
}

fn take_children(kind: &mut ExprKind, stack: &mut Vec<Expr>) {
    let placeholder = || Box::new(Expr { kind: ExprKind::Error, span: Span::default() });
    match kind {
        ExprKind::Index(a, b) | ExprKind::Binary(_, a, b) | ExprKind::Assign(_, a, b) => {
            stack.push(*std::mem::replace(a, placeholder()));
            stack.push(*std::mem::replace(b, placeholder()));
        }
        ExprKind::Ternary(a, b, c) => {
            stack.push(*std::mem::replace(a, placeholder()));
            stack.push(*std::mem::replace(b, placeholder()));
            stack.push(*std::mem::replace(c, placeholder()));
        }
        ExprKind::Cast { expr: a, .. } | ExprKind::Unary(_, a) | ExprKind::IncDec { target: a, .. } => {
            stack.push(*std::mem::replace(a, placeholder()));
        }
        ExprKind::Call { args, .. } | ExprKind::Tuple(args) | ExprKind::ArrayLiteral(args) => {
            stack.append(args);
        }
        ExprKind::Number(_) | ExprKind::String(_) | ExprKind::Ident(_) | ExprKind::Error => {}
    }
}

impl Drop for Stmt {
    fn drop(&mut self) {
        let kind = std::mem::replace(&mut self.kind, StmtKind::Empty);
        let depth = deep_drop::DEPTH.with(|d| d.get());
        if depth >= deep_drop::LIMIT {
            let mut kind = kind;
            deep_drop::PENDING_STMTS.with(|p| take_stmt_children(&mut kind, &mut p.borrow_mut()));
            return;
        }
        deep_drop::DEPTH.with(|d| d.set(depth + 1));
        drop(kind);
        if depth == 0 {
            while let Some(s) = deep_drop::PENDING_STMTS.with(|p| p.borrow_mut().pop()) {
                drop(s);
            }
            while let Some(e) = deep_drop::PENDING_EXPRS.with(|p| p.borrow_mut().pop()) {
                drop(e);
            }
        }
        deep_drop::DEPTH.with(|d| d.set(depth));
    }
}

fn take_stmt_children(kind: &mut StmtKind, stack: &mut Vec<Stmt>) {
    let placeholder = || Box::new(Stmt { kind: StmtKind::Empty, span: Span::default() });
    let mut take = |b: &mut Box<Stmt>| stack.push(*std::mem::replace(b, placeholder()));
    match kind {
        StmtKind::If { then, otherwise, .. } => {
            take(then);
            if let Some(o) = otherwise {
                take(o);
            }
        }
        StmtKind::While { body, .. }
        | StmtKind::Illuminance { body, .. }
        | StmtKind::Illuminate { body, .. }
        | StmtKind::Solar { body, .. } => take(body),
        StmtKind::For { init, body, .. } => {
            if let Some(i) = init {
                take(i);
            }
            take(body);
        }
        StmtKind::Gather { body, otherwise, .. } => {
            take(body);
            if let Some(o) = otherwise {
                take(o);
            }
        }
        StmtKind::Block(b) => stack.append(&mut b.stmts),
        _ => {}
    }
}
