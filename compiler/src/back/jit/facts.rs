//! What a shader's code does that a renderer plans around, worked out once at compile time: how a
//! light emits, whether every lane of a batch gets the same results, and which output variables
//! a pixel shader reads.

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

/// See [`super::CompiledShader::pixel_outputs`]: the channels named by literals in `pixelvalue`
/// calls that are none of the image's own (`PixelChannel::of`), each once, in order of appearance.
pub(super) fn pixel_outputs(m: &Module) -> Vec<String> {
    let mut names: Vec<String> = Vec::new();
    for f in &m.functions {
        for e in &f.exprs {
            let ExprKind::CallBuiltin { builtin: crate::builtins::Builtin::Pixelvalue, args, .. } = &e.kind else {
                continue;
            };
            let Some(crate::ir::Arg::Value(first)) = args.first() else { continue };
            let Some(ExprKind::Const(crate::ir::Constant::String(name))) = f.exprs.get(first.0 as usize).map(|x| &x.kind)
            else {
                continue;
            };
            if super::host::PixelChannel::of(name).is_none() && !names.contains(name) {
                names.push(name.clone());
            }
        }
    }
    names
}

