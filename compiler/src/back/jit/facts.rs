//! What a shader's code does that a renderer plans around, worked out once at compile time: how a
//! light emits, and whether every lane of a batch gets the same results.

use super::Layout;
use crate::ir::{Block, ExprKind, Module, StmtKind};

/// How a light shader emits, read from its code: `illuminate` makes a local light (shadow rays end at
/// the light), `solar` a distant one (shadow rays are unbounded), neither an ambient light.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LightKind {
    Ambient,
    Local,
    Distant,
}

/// How a light shader's code emits (`Ambient` for other shader types).
pub(super) fn light_kind(m: &Module) -> LightKind {
    fn scan(b: &Block, kind: &mut LightKind) {
        for s in &b.stmts {
            match &s.kind {
                StmtKind::Illuminate { body, .. } => {
                    *kind = LightKind::Local;
                    scan(body, kind);
                }
                StmtKind::Solar { body, .. } => {
                    if *kind == LightKind::Ambient {
                        *kind = LightKind::Distant;
                    }
                    scan(body, kind);
                }
                StmtKind::If { then, otherwise, .. } => {
                    scan(then, kind);
                    scan(otherwise, kind);
                }
                StmtKind::Loop { body, step, .. } => {
                    scan(body, kind);
                    scan(step, kind);
                }
                StmtKind::Illuminance { body, .. } => scan(body, kind),
                StmtKind::Gather { body, otherwise, .. } => {
                    scan(body, kind);
                    scan(otherwise, kind);
                }
                StmtKind::Expr(_) | StmtKind::Break(_) | StmtKind::Continue(_) | StmtKind::Return(_) => {}
            }
        }
    }
    let mut kind = LightKind::Ambient;
    for f in &m.functions {
        scan(&f.body, &mut kind);
    }
    kind
}

/// See [`super::CompiledShader::lane_invariant`].
pub(super) fn lane_invariant(m: &Module, layout: &Layout) -> bool {
    fn plain(b: &Block) -> bool {
        b.stmts.iter().all(|s| match &s.kind {
            StmtKind::If { then, otherwise, .. } => plain(then) && plain(otherwise),
            StmtKind::Loop { body, step, .. } => plain(body) && plain(step),
            StmtKind::Expr(_) | StmtKind::Break(_) | StmtKind::Continue(_) | StmtKind::Return(_) => true,
            _ => false,
        })
    }
    let calls_nothing = m.functions.iter().all(|f| {
        plain(&f.body)
            && f.exprs.iter().all(|e| !matches!(e.kind, ExprKind::Call { .. } | ExprKind::CallBuiltin { .. }))
    });
    let reads_no_global = layout.globals.iter().all(|g| g.written && g.entry_unused);
    calls_nothing && reads_no_global && layout.seed.is_none()
}
