//! `Blobby` (RISpec 3.2, section 5.6, "Implicit Surfaces") to triangle meshes: the isosurface of a
//! field built from primitive fields and operators, tessellated on a grid, not intersected exactly.
//!
//! `Blobby nleaf [code] [floats] [strings] params`: `code` is a program of instructions, numbered
//! from 0 in the order written, each an opcode and its operands. Primitive fields (leaves) read their
//! numbers from `floats` (by index) and names from `strings`:
//!
//! | opcode | operands | field |
//! |---|---|---|
//! | 1000 | float index | a constant |
//! | 1001 | float index | an ellipsoid: the 16 floats are the matrix (RenderMan's row-major order, translation last) that takes the unit sphere to it |
//! | 1002 | float index | a segment blob: 23 floats, the two ends and the radius of a capsule, then the matrix that places it |
//! | 1003 | string index, float index | a repelling ground plane read from a depth map: not supported (a warning; its field is 0) |
//! | 1004 | 5 operands | a field plug-in (PRMan): not supported (a warning; its field is 0) |
//!
//! Operators combine the results of earlier instructions (an operand is an instruction's number,
//! which must be lower than the operator's own): 0 add, 1 multiply, 2 maximum, 3 minimum (a count,
//! then that many operands, at least one), 4 subtract (the first less the second), 5 divide (the
//! first over the second; 0 where the second is 0), 6 negate, 7 identity. The last instruction is
//! the field. The program runs in order, each instruction once, so evaluating it costs at most its
//! length and cannot recurse or loop.
//!
//! RISpec leaves the primitive fields' falloff to the renderer; rtsl follows Aqsis (after K-3D):
//! a leaf's field is `(1 - r^2)^3` where `r` is the distance from the centre (from the segment, over
//! its radius, for a segment blob) in the leaf's own space, and 0 from `r = 1` out, and the surface
//! is where the field equals [`BLOBBY_THRESHOLD`], 0.421875 = `(1 - 0.25)^3`: a lone ellipsoid's
//! surface is its unit sphere at half size (`r = 0.5`), the inside is where the field is above it.
//!
//! Tessellation: the field is sampled on a grid of cubic cells over the box around every
//! ellipsoid's and segment blob's support (where its field is not 0), padded by a cell, whose
//! outermost samples count as outside, so every surface is closed. The longest side has
//! [`BLOBBY_CELLS_PER_VIEW`] cells for each image's shorter side the box spans
//! ([`View::fraction`](super::view::View::fraction)),
//! at least [`MIN_BLOBBY_CELLS`], at most [`MAX_BLOBBY_CELLS`], and fewer where the work would pass
//! [`BLOBBY_EVALUATION_BUDGET`] (a warning says so). The grid is sampled in blocks of `BLOCK`
//! samples a side, each with the program specialised to it (`Program::compile`: the leaves that do
//! not reach the block, and what only they make, left out), so a sample costs what reaches it, not
//! the whole program. Each cell is cut into six tetrahedra along its diagonal, and each
//! tetrahedron the surface crosses gives one or two triangles (marching tetrahedra): vertices
//! shared along the edges, placed on the surface by a few steps of regula falsi on the field along
//! their edge, with the field's analytic gradient as the normal, wound so `(P1 - P0) x (P2 - P0)`
//! points outside.
//!
//! Primitive variables: `vertex` and `varying` data have one value per leaf (`nleaf`), `uniform`
//! and `constant` data one for all. At each vertex a leaf's value weighs by the size of its field
//! there (RISpec: values "blended appropriately"), a uniform value holds all over. `nleaf` counts
//! the ellipsoids, segment blobs, planes and plug-ins, with or without the constants (both are
//! accepted: constants take a value only when counted).
//!
//! Invariants: bad code (an unknown opcode, operands past the end of `code`, an index past the end
//! of `floats` or `strings`, an operand that is not an earlier instruction, a singular or non-finite
//! matrix, a radius that is not positive, `nleaf` that counts neither way) is an `Err` naming the
//! instruction, never a panic. The grid has at most `(MAX_BLOBBY_CELLS + 2)^3` cells; the work
//! (specialisations, and evaluations times the length of the program evaluated) is bounded by
//! [`BLOBBY_EVALUATION_BUDGET`], the grids tried and given up included; nothing recurses.

use std::collections::HashMap;

use glam::{Affine3A, Mat3, Vec3};

use super::decl::Class;
use super::mesh::{per_vertex_params, reserve_mesh, route_attributes, ClassCounts, MeshOptions, PerVertex};
use super::request::Param;
use crate::geometry::Mesh;

/// The field value on the surface.
pub const BLOBBY_THRESHOLD: f32 = 0.421875;

/// The most grid cells along the longest side of a `Blobby`'s box.
pub const MAX_BLOBBY_CELLS: u32 = 128;

/// The fewest grid cells along the longest side of a `Blobby`'s box.
pub const MIN_BLOBBY_CELLS: u32 = 16;

/// Grid cells along the longest side of a `Blobby`'s box for each image's shorter side it spans.
pub const BLOBBY_CELLS_PER_VIEW: f32 = 128.0;

/// The work of tessellating one `Blobby`: each specialisation of its program to a block of the grid
/// counts the program's instructions and operands, each evaluation those of the specialised program
/// (four times that with the gradient). A grid is sampled only where that takes at most a quarter
/// of the work left, and its vertices placed only where they fit in the rest; a coarser grid is
/// tried otherwise (the work of the grids given up counts).
pub const BLOBBY_EVALUATION_BUDGET: usize = 1 << 28;

/// Regula falsi steps that move a vertex onto the surface along its edge.
const REFINE_STEPS: usize = 3;

/// A `Blobby` request's arguments.
#[derive(Clone, Copy, Debug)]
pub struct BlobbyInput<'a> {
    /// The leaves, as the request counts them.
    pub nleaf: i32,
    /// The program.
    pub code: &'a [i32],
    /// The leaves' numbers.
    pub floats: &'a [f32],
    /// The leaves' names.
    pub strings: &'a [String],
    /// Primitive variables.
    pub params: &'a [Param],
}

/// A primitive field.
#[derive(Clone, Debug)]
enum Field {
    Constant(f32),
    /// `inverse` takes object space to the leaf's space, where it is the unit sphere.
    Ellipsoid {
        inverse: Affine3A,
    },
    /// A capsule from `start` to `start + axis` (leaf space) of radius `1 / inv_radius`.
    Segment {
        inverse: Affine3A,
        start: Vec3,
        axis: Vec3,
        inv_radius2: f32,
    },
    /// An unsupported primitive: no field.
    Zero,
}

/// One instruction: a leaf or an operator on earlier instructions' results.
#[derive(Clone, Debug)]
enum Instruction {
    Leaf {
        field: Field,
        /// The object-space box outside which the field is 0 (`None`: no such box).
        support: Option<(Vec3, Vec3)>,
        /// Its number among the leaves that carry primitive variables.
        leaf: Option<usize>,
    },
    /// 0 add, 1 multiply, 2 maximum, 3 minimum over `operands[range]`.
    Many(u8, std::ops::Range<usize>),
    Subtract(usize, usize),
    Divide(usize, usize),
    Negate(usize),
    Identity(usize),
}

/// A checked program.
#[derive(Debug)]
struct Program {
    instructions: Vec<Instruction>,
    operands: Vec<usize>,
    /// Leaves that carry primitive variables: `nleaf`.
    leaves: usize,
    /// The instruction of each such leaf.
    leaf_instructions: Vec<usize>,
    /// The object-space box around every bounded leaf's support.
    bound: Option<(Vec3, Vec3)>,
    /// The work of one evaluation.
    cost: usize,
}

/// A value and its gradient.
type Dual = (f32, Vec3);

/// `(1 - r^2)^3` for `r^2 < 1`, with its derivative in `r^2`.
fn falloff(r2: f32) -> (f32, f32) {
    if r2 < 1.0 {
        let t = 1.0 - r2;
        (t * t * t, -3.0 * t * t)
    } else {
        (0.0, 0.0)
    }
}

impl Field {
    /// The field at `p` (object space) and, when `gradient`, its object-space gradient.
    fn eval(&self, p: Vec3, gradient: bool) -> Dual {
        let (inverse, d, inv_radius2) = match self {
            Field::Constant(c) => return (*c, Vec3::ZERO),
            Field::Zero => return (0.0, Vec3::ZERO),
            Field::Ellipsoid { inverse } => (inverse, inverse.transform_point3(p), 1.0),
            Field::Segment { inverse, start, axis, inv_radius2 } => {
                let q = inverse.transform_point3(p);
                let length2 = axis.length_squared();
                let t = if length2 > 0.0 { ((q - *start).dot(*axis) / length2).clamp(0.0, 1.0) } else { 0.0 };
                (inverse, q - (*start + t * *axis), *inv_radius2)
            }
        };
        let (value, slope) = falloff(d.length_squared() * inv_radius2);
        if !gradient || slope == 0.0 {
            return (value, Vec3::ZERO);
        }
        // d(r^2)/dq = 2 d / radius^2 (also past the segment's ends); q = L p + c.
        let in_leaf = slope * 2.0 * inv_radius2 * d;
        (value, Mat3::from(inverse.matrix3).transpose() * in_leaf)
    }
}

fn contains(b: &(Vec3, Vec3), p: Vec3) -> bool {
    p.cmpge(b.0).all() && p.cmple(b.1).all()
}

/// The object-space box around the leaf-space box `lo..hi` placed by `m`.
fn placed_box(m: &Affine3A, lo: Vec3, hi: Vec3) -> (Vec3, Vec3) {
    let mut out = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for k in 0..8 {
        let corner = Vec3::new(
            if k & 1 == 0 { lo.x } else { hi.x },
            if k & 2 == 0 { lo.y } else { hi.y },
            if k & 4 == 0 { lo.z } else { hi.z },
        );
        let p = m.transform_point3(corner);
        out = (out.0.min(p), out.1.max(p));
    }
    out
}

/// The matrix of 16 floats from `at` (RenderMan's order: rows, the translation in the last), checked.
fn matrix(values: &[f32], warnings: &mut Vec<String>, what: &str) -> Result<(Affine3A, Affine3A), String> {
    let m = values;
    if m.iter().any(|x| !x.is_finite()) {
        return Err(format!("{what}: its matrix is not finite"));
    }
    if m[3] != 0.0 || m[7] != 0.0 || m[11] != 0.0 || m[15] != 1.0 {
        warnings.push(format!("{what}: the projective column of its matrix is ignored"));
    }
    let placed = Affine3A::from_cols(
        Vec3::new(m[0], m[1], m[2]).into(),
        Vec3::new(m[4], m[5], m[6]).into(),
        Vec3::new(m[8], m[9], m[10]).into(),
        Vec3::new(m[12], m[13], m[14]).into(),
    );
    let det = placed.matrix3.determinant();
    if !det.is_finite() || det.abs() < 1e-12 {
        return Err(format!("{what}: its matrix is singular"));
    }
    let inverse = placed.inverse();
    if !inverse.is_finite() {
        return Err(format!("{what}: its matrix is singular"));
    }
    Ok((placed, inverse))
}

impl Program {
    fn new(input: &BlobbyInput, warnings: &mut Vec<String>) -> Result<Program, String> {
        let code = input.code;
        let mut instructions = Vec::new();
        let mut operands = Vec::new();
        let mut bound: Option<(Vec3, Vec3)> = None;
        // Whether each leaf instruction is a constant (counted as a leaf or not, as nleaf says).
        let mut leaf_kinds: Vec<(usize, bool)> = Vec::new();
        let mut unsupported: Vec<&str> = Vec::new();
        let mut c = 0;
        while c < code.len() {
            let index = instructions.len();
            let (opcode, at) = (code[c], c);
            c += 1;
            let what = format!("instruction {index} (opcode {opcode} at code[{at}])");
            let operand = |k: usize| -> Result<i32, String> {
                code.get(c + k).copied().ok_or_else(|| format!("{what} is missing operands past the end of the code"))
            };
            let floats_at = |i: i32, n: usize| -> Result<&[f32], String> {
                usize::try_from(i)
                    .ok()
                    .and_then(|i| input.floats.get(i..i.checked_add(n)?))
                    .ok_or_else(|| format!("{what} reads {n} floats from {i}, past the {} given", input.floats.len()))
            };
            let earlier = |i: i32| -> Result<usize, String> {
                usize::try_from(i).ok().filter(|&i| i < index).ok_or_else(|| {
                    format!("{what} has operand {i}, which is not an earlier instruction (0 to {})", index as i64 - 1)
                })
            };
            let instruction = match opcode {
                1000 => {
                    let value = floats_at(operand(0)?, 1)?[0];
                    c += 1;
                    leaf_kinds.push((index, true));
                    Instruction::Leaf { field: Field::Constant(value), support: None, leaf: None }
                }
                1001 => {
                    let (placed, inverse) = matrix(floats_at(operand(0)?, 16)?, warnings, &what)?;
                    c += 1;
                    let support = placed_box(&placed, Vec3::NEG_ONE, Vec3::ONE);
                    bound = Some(bound.map_or(support, |b| (b.0.min(support.0), b.1.max(support.1))));
                    leaf_kinds.push((index, false));
                    Instruction::Leaf { field: Field::Ellipsoid { inverse }, support: Some(support), leaf: None }
                }
                1002 => {
                    let f = floats_at(operand(0)?, 23)?;
                    c += 1;
                    let (start, end, radius) = (Vec3::from_slice(&f[0..3]), Vec3::from_slice(&f[3..6]), f[6]);
                    if !(start.is_finite() && end.is_finite() && radius > 0.0 && radius.is_finite()) {
                        return Err(format!("{what}: a segment blob needs finite ends and a positive radius"));
                    }
                    let (placed, inverse) = matrix(&f[7..23], warnings, &what)?;
                    let support = placed_box(&placed, start.min(end) - radius, start.max(end) + radius);
                    bound = Some(bound.map_or(support, |b| (b.0.min(support.0), b.1.max(support.1))));
                    leaf_kinds.push((index, false));
                    let field =
                        Field::Segment { inverse, start, axis: end - start, inv_radius2: 1.0 / (radius * radius) };
                    Instruction::Leaf { field, support: Some(support), leaf: None }
                }
                1003 => {
                    let name = operand(0)?;
                    floats_at(operand(1)?, 4)?;
                    usize::try_from(name)
                        .ok()
                        .filter(|&i| i < input.strings.len())
                        .ok_or_else(|| format!("{what} names string {name}, past the {} given", input.strings.len()))?;
                    c += 2;
                    unsupported.push("repelling ground planes (1003)");
                    leaf_kinds.push((index, false));
                    Instruction::Leaf { field: Field::Zero, support: None, leaf: None }
                }
                1004 => {
                    for k in 0..5 {
                        operand(k)?;
                    }
                    c += 5;
                    unsupported.push("field plug-ins (1004)");
                    leaf_kinds.push((index, false));
                    Instruction::Leaf { field: Field::Zero, support: None, leaf: None }
                }
                0..=3 => {
                    let count = operand(0)?;
                    let n = usize::try_from(count)
                        .ok()
                        .filter(|&n| n >= 1)
                        .ok_or_else(|| format!("{what} has {count} operands where it needs at least 1"))?;
                    let first = operands.len();
                    for k in 0..n {
                        operands.push(earlier(operand(1 + k)?)?);
                    }
                    c += 1 + n;
                    Instruction::Many(opcode as u8, first..operands.len())
                }
                4 | 5 => {
                    let (a, b) = (earlier(operand(0)?)?, earlier(operand(1)?)?);
                    c += 2;
                    if opcode == 4 {
                        Instruction::Subtract(a, b)
                    } else {
                        Instruction::Divide(a, b)
                    }
                }
                6 | 7 => {
                    let a = earlier(operand(0)?)?;
                    c += 1;
                    if opcode == 6 {
                        Instruction::Negate(a)
                    } else {
                        Instruction::Identity(a)
                    }
                }
                _ => return Err(format!("{what}: unknown opcode (0 to 7 operators, 1000 to 1004 fields)")),
            };
            instructions.push(instruction);
        }
        if instructions.is_empty() {
            return Err("the code has no instructions".into());
        }
        unsupported.dedup();
        for what in unsupported {
            warnings.push(format!("{what} are not supported: their field is 0"));
        }
        let fields = leaf_kinds.iter().filter(|(_, constant)| !constant).count();
        let with_constants = leaf_kinds.len();
        let count_constants = match usize::try_from(input.nleaf) {
            Ok(n) if n == fields => false,
            Ok(n) if n == with_constants => true,
            _ => {
                let constants = if with_constants > fields {
                    format!(" ({with_constants} with its constants)")
                } else {
                    String::new()
                };
                return Err(format!("nleaf is {} but the code has {fields} primitive fields{constants}", input.nleaf));
            }
        };
        let mut leaf_instructions = Vec::new();
        for &(index, constant) in &leaf_kinds {
            if count_constants || !constant {
                if let Instruction::Leaf { leaf, .. } = &mut instructions[index] {
                    *leaf = Some(leaf_instructions.len());
                }
                leaf_instructions.push(index);
            }
        }
        let cost = instructions.len() + operands.len();
        Ok(Program { instructions, operands, leaves: leaf_instructions.len(), leaf_instructions, bound, cost })
    }

    /// The program specialised to the box `lo..hi`: the instructions whose value is not 0 all over
    /// it (a leaf whose support misses the box is 0 there, and so are a sum, maximum or minimum of
    /// zeros, a product or quotient with a zero, the difference of two zeros), each with the
    /// operands that are not 0. A maximum or minimum that had a zero operand keeps one (the slot
    /// that always holds 0).
    fn compile(&self, lo: Vec3, hi: Vec3) -> Compiled<'_> {
        let n = self.instructions.len();
        let mut active = vec![false; n];
        let mut out = Compiled { steps: Vec::new(), operands: Vec::new(), zero: n };
        for (index, instruction) in self.instructions.iter().enumerate() {
            let step = match instruction {
                Instruction::Leaf { field, support, .. } => {
                    let reaches = support.as_ref().is_none_or(|(a, b)| a.cmple(hi).all() && b.cmpge(lo).all());
                    match field {
                        Field::Zero | Field::Constant(0.0) => None,
                        _ if !reaches => None,
                        _ => Some(Step::Leaf(field, *support)),
                    }
                }
                Instruction::Many(op, range) => {
                    let all = &self.operands[range.clone()];
                    let first = out.operands.len();
                    out.operands.extend(all.iter().copied().filter(|&i| active[i]));
                    let kept = out.operands.len() - first;
                    let on = match op {
                        1 => kept == all.len(),
                        _ => kept > 0,
                    };
                    if !on {
                        out.operands.truncate(first);
                        None
                    } else {
                        if *op >= 2 && kept < all.len() {
                            out.operands.push(out.zero);
                        }
                        Some(Step::Many(*op, first..out.operands.len()))
                    }
                }
                Instruction::Subtract(a, b) => (active[*a] || active[*b]).then_some(Step::Subtract(*a, *b)),
                Instruction::Divide(a, b) => (active[*a] && active[*b]).then_some(Step::Divide(*a, *b)),
                Instruction::Negate(a) => active[*a].then_some(Step::Negate(*a)),
                Instruction::Identity(a) => active[*a].then_some(Step::Identity(*a)),
            };
            if let Some(step) = step {
                active[index] = true;
                out.steps.push((index, step));
            }
        }
        out
    }
}

/// One instruction of a [`Compiled`] program.
#[derive(Clone, Debug)]
enum Step<'a> {
    Leaf(&'a Field, Option<(Vec3, Vec3)>),
    Many(u8, std::ops::Range<usize>),
    Subtract(usize, usize),
    Divide(usize, usize),
    Negate(usize),
    Identity(usize),
}

/// A program specialised to a box ([`Program::compile`]): its values are read from a vector of
/// one slot an instruction and one more, all 0 but those the steps write.
#[derive(Debug)]
struct Compiled<'a> {
    /// The instructions not 0 all over the box, with their numbers, in order.
    steps: Vec<(usize, Step<'a>)>,
    operands: Vec<usize>,
    /// The slot that holds 0: the instructions' count.
    zero: usize,
}

impl Compiled<'_> {
    /// The work of one evaluation.
    fn cost(&self) -> usize {
        self.steps.len() + self.operands.len() + 1
    }

    /// Values to evaluate with: all 0.
    fn fresh<T: Default + Clone>(&self, values: &mut Vec<T>) {
        values.clear();
        values.resize(self.zero + 1, T::default());
    }

    /// The field at `p` (`values` made by [`Compiled::fresh`] for this program).
    fn eval(&self, p: Vec3, values: &mut [f32]) -> f32 {
        for (index, step) in &self.steps {
            values[*index] = match step {
                Step::Leaf(field, support) => {
                    if support.as_ref().is_some_and(|b| !contains(b, p)) {
                        0.0
                    } else {
                        field.eval(p, false).0
                    }
                }
                Step::Many(op, range) => {
                    let args = self.operands[range.clone()].iter().map(|&i| values[i]);
                    match op {
                        0 => args.sum(),
                        1 => args.product(),
                        2 => args.fold(f32::NEG_INFINITY, f32::max),
                        _ => args.fold(f32::INFINITY, f32::min),
                    }
                }
                Step::Subtract(a, b) => values[*a] - values[*b],
                Step::Divide(a, b) => {
                    if values[*b] == 0.0 {
                        0.0
                    } else {
                        values[*a] / values[*b]
                    }
                }
                Step::Negate(a) => -values[*a],
                Step::Identity(a) => values[*a],
            };
        }
        values[self.zero - 1]
    }

    /// The field and its gradient at `p` (`values` made by [`Compiled::fresh`] for this program).
    fn eval_gradient(&self, p: Vec3, values: &mut [Dual]) -> Dual {
        for (index, step) in &self.steps {
            values[*index] = match step {
                Step::Leaf(field, support) => {
                    if support.as_ref().is_some_and(|b| !contains(b, p)) {
                        (0.0, Vec3::ZERO)
                    } else {
                        field.eval(p, true)
                    }
                }
                Step::Many(op, range) => {
                    let mut args = self.operands[range.clone()].iter().map(|&i| values[i]);
                    let first = args.next().unwrap_or((0.0, Vec3::ZERO));
                    args.fold(first, |(a, ga), (b, gb)| match op {
                        0 => (a + b, ga + gb),
                        1 => (a * b, ga * b + gb * a),
                        2 if b > a => (b, gb),
                        3 if b < a => (b, gb),
                        _ => (a, ga),
                    })
                }
                Step::Subtract(a, b) => (values[*a].0 - values[*b].0, values[*a].1 - values[*b].1),
                Step::Divide(a, b) => {
                    let ((x, gx), (y, gy)) = (values[*a], values[*b]);
                    if y == 0.0 {
                        (0.0, Vec3::ZERO)
                    } else {
                        (x / y, (gx * y - gy * x) / (y * y))
                    }
                }
                Step::Negate(a) => (-values[*a].0, -values[*a].1),
                Step::Identity(a) => values[*a],
            };
        }
        values[self.zero - 1]
    }
}

/// A `Blobby` checked and its grid sized, before any field is sampled.
struct Plan {
    program: Program,
    /// The box around the leaves' supports: its first corner and size.
    lo: Vec3,
    size: Vec3,
    /// Cells along the longest side the view asks for, and those of the grid being tried.
    wanted: u32,
    cells: u32,
}

/// A grid: its first corner, cell size, cells along each axis (the padding included).
struct Grid {
    origin: Vec3,
    cell: f32,
    cells: [usize; 3],
}

impl Grid {
    /// The position of sample `s`.
    fn point(&self, s: usize) -> Vec3 {
        let (sx, sy) = (self.cells[0] + 1, self.cells[1] + 1);
        let (i, j, k) = (s % sx, (s / sx) % sy, s / (sx * sy));
        self.origin + self.cell * Vec3::new(i as f32, j as f32, k as f32)
    }

    /// The blocks of [`BLOCK`] samples a side the grid is sampled in: the box of each one's
    /// samples and the ranges of its samples inside the grid's outermost layer.
    fn blocks(&self) -> impl Iterator<Item = (Vec3, Vec3, [std::ops::Range<usize>; 3])> + '_ {
        let n = self.cells.map(|c| c + 1);
        let count = n.map(|n| n.div_ceil(BLOCK));
        (0..count[0] * count[1] * count[2]).map(move |b| {
            let index = [b % count[0], (b / count[0]) % count[1], b / (count[0] * count[1])];
            let first = Vec3::new(index[0] as f32, index[1] as f32, index[2] as f32) * BLOCK as f32;
            let lo = self.origin + self.cell * first;
            let hi = lo + self.cell * (BLOCK - 1) as f32;
            let range = |axis: usize| (index[axis] * BLOCK).max(1)..((index[axis] + 1) * BLOCK).min(n[axis] - 1);
            (lo, hi, [range(0), range(1), range(2)])
        })
    }

    /// The work of sampling the field on the grid ([`tessellate`]), or `None` when working it out
    /// would take more than `work` (it takes a specialisation a block).
    fn sampling_work(&self, program: &Program, work: &mut usize) -> Option<usize> {
        let mut total = 0usize;
        for (lo, hi, [ri, rj, rk]) in self.blocks() {
            spend(work, program.cost)?;
            let compiled = program.compile(lo, hi);
            total = total.saturating_add(program.cost + ri.len() * rj.len() * rk.len() * compiled.cost());
        }
        Some(total)
    }
}

impl Plan {
    fn new(input: &BlobbyInput, options: &MeshOptions, warnings: &mut Vec<String>) -> Result<Plan, String> {
        let program = Program::new(input, warnings)?;
        let Some((lo, hi)) = program.bound else {
            return Err("no ellipsoid or segment blob bounds the surface: nothing to draw".into());
        };
        let size = hi - lo;
        let longest = size.max_element();
        if !longest.is_finite() || longest <= 0.0 || !lo.is_finite() {
            return Err("the leaves' bound is not finite".into());
        }
        let fraction = options.view.fraction(0.5 * (lo + hi), longest);
        let wanted = (BLOBBY_CELLS_PER_VIEW * fraction).ceil();
        let wanted = if wanted.is_finite() { wanted.min(MAX_BLOBBY_CELLS as f32) as u32 } else { MIN_BLOBBY_CELLS };
        let wanted = wanted.clamp(MIN_BLOBBY_CELLS, MAX_BLOBBY_CELLS);
        Ok(Plan { program, lo, size, wanted, cells: wanted })
    }

    /// The grid of `n` cells along the longest side, padded by a cell all round.
    fn grid(&self, n: u32) -> Grid {
        let cell = self.size.max_element() / n as f32;
        let along = |s: f32| ((s / cell).ceil() as usize).clamp(1, n as usize) + 2;
        Grid {
            origin: self.lo - Vec3::splat(cell),
            cell,
            cells: [along(self.size.x), along(self.size.y), along(self.size.z)],
        }
    }

    /// The next coarser grid to try, if any.
    fn coarser(&self) -> Option<u32> {
        Some(self.cells * 3 / 4).filter(|&n| n >= 4)
    }
}

/// At most the triangles [`blobby_mesh`] makes of the same request (two a tetrahedron, six
/// tetrahedra a cell), worked out without sampling the field (0 for a request it refuses).
pub fn blobby_triangles(input: &BlobbyInput, options: &MeshOptions) -> usize {
    Plan::new(input, options, &mut Vec::new())
        .map_or(0, |plan| 12 * plan.grid(plan.cells).cells.iter().product::<usize>())
}

/// The six tetrahedra of a cell, around its diagonal from corner 0 to corner 7 (corner bits: 1 x,
/// 2 y, 4 z): the same cut in every cell, so neighbours share their faces' diagonals.
const TETRAHEDRA: [[usize; 4]; 6] =
    [[0, 1, 3, 7], [0, 1, 5, 7], [0, 2, 3, 7], [0, 2, 6, 7], [0, 4, 5, 7], [0, 4, 6, 7]];

/// Samples along each side of the blocks the grid is sampled in, each block with the program
/// specialised to it ([`Program::compile`]).
const BLOCK: usize = 8;

/// Takes `n` from the work left, or says that there is not that much.
fn spend(work: &mut usize, n: usize) -> Option<()> {
    *work = work.checked_sub(n)?;
    Some(())
}

/// The mesh of the isosurface on `grid`, or `None` when it would take more than `work`.
///
/// The field is sampled (the outermost samples count as outside, so that every surface closes),
/// each cell cut into six tetrahedra and each tetrahedron the surface crosses gives one or two
/// triangles, their vertices on the edges it crosses (shared between cells), moved onto the
/// surface along their edge, with the gradient's normal and the leaves' values blended by field.
fn tessellate(program: &Program, grid: &Grid, data: &[PerVertex<'_>], work: &mut usize) -> Option<Mesh> {
    let [nx, ny, nz] = grid.cells;
    let (sx, sy, sz) = (nx + 1, ny + 1, nz + 1);
    let at = |i: usize, j: usize, k: usize| i + sx * (j + sy * k);
    let point = |s: usize| grid.point(s);
    let block_of = |s: usize| ((s % sx) / BLOCK, ((s / sx) % sy) / BLOCK, (s / (sx * sy)) / BLOCK);
    // The box of a block's samples, grown by `pad` cells.
    let block_box = |(bi, bj, bk): (usize, usize, usize), pad: f32| {
        let first = Vec3::new((bi * BLOCK) as f32, (bj * BLOCK) as f32, (bk * BLOCK) as f32);
        let lo = grid.origin + grid.cell * (first - pad);
        (lo, lo + grid.cell * Vec3::splat((BLOCK - 1) as f32 + 2.0 * pad))
    };

    let mut scratch: Vec<f32> = Vec::new();
    let mut samples = vec![0.0f32; sx * sy * sz];
    for (lo, hi, [ri, rj, rk]) in grid.blocks() {
        spend(work, program.cost)?;
        let compiled = program.compile(lo, hi);
        compiled.fresh(&mut scratch);
        spend(work, ri.len() * rj.len() * rk.len() * compiled.cost())?;
        for k in rk {
            for j in rj.clone() {
                for i in ri.clone() {
                    let s = at(i, j, k);
                    samples[s] = compiled.eval(point(s), &mut scratch);
                }
            }
        }
    }
    let inside = |v: f32| v > BLOBBY_THRESHOLD;

    // March: a vertex for each edge the surface crosses, two or one triangle a tetrahedron crossed,
    // each with a direction outwards across it (from its tetrahedron's inside corners to the
    // outside ones) to wind it by once its vertices are placed.
    let mut vertex_of: HashMap<(u32, u32), u32> = HashMap::new();
    let mut edges: Vec<(usize, usize)> = Vec::new();
    let mut triangles: Vec<([u32; 3], Vec3)> = Vec::new();
    let mut vertex = |a: usize, b: usize, edges: &mut Vec<(usize, usize)>| -> u32 {
        // Keyed inside-first, so both cells that share the edge find it.
        *vertex_of.entry((a as u32, b as u32)).or_insert_with(|| {
            edges.push((a, b));
            (edges.len() - 1) as u32
        })
    };
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let corner = |c: usize| at(i + (c & 1), j + ((c >> 1) & 1), k + ((c >> 2) & 1));
                let corners: [usize; 8] = std::array::from_fn(corner);
                let flags = corners.map(|s| inside(samples[s]));
                if flags.iter().all(|&f| f) || flags.iter().all(|&f| !f) {
                    continue;
                }
                for tet in TETRAHEDRA {
                    let ids = tet.map(|c| corners[c]);
                    let (ins, outs): (Vec<usize>, Vec<usize>) = ids.iter().partition(|&&s| inside(samples[s]));
                    let mut made: Vec<u32> = Vec::with_capacity(4);
                    match (ins.len(), outs.len()) {
                        (1, 3) => made.extend(outs.iter().map(|&o| vertex(ins[0], o, &mut edges))),
                        (3, 1) => made.extend(ins.iter().map(|&n| vertex(n, outs[0], &mut edges))),
                        (2, 2) => {
                            // The quad around the two inside corners, in cyclic order.
                            made.push(vertex(ins[0], outs[0], &mut edges));
                            made.push(vertex(ins[0], outs[1], &mut edges));
                            made.push(vertex(ins[1], outs[1], &mut edges));
                            made.push(vertex(ins[1], outs[0], &mut edges));
                        }
                        _ => continue,
                    }
                    let from_inside = ins.iter().map(|&s| point(s)).sum::<Vec3>() / ins.len() as f32;
                    let to_outside = outs.iter().map(|&s| point(s)).sum::<Vec3>() / outs.len() as f32;
                    let outward = to_outside - from_inside;
                    triangles.push(([made[0], made[1], made[2]], outward));
                    if made.len() == 4 {
                        triangles.push(([made[0], made[2], made[3]], outward));
                    }
                }
            }
        }
    }

    // Place and shade the vertices, block by block of their inside sample, with the program
    // specialised to the block grown by a cell (an edge reaches one cell out of it).
    let (mut mesh, mut attributes) = reserve_mesh(edges.len(), triangles.len(), data);
    mesh.uvs = None;
    mesh.positions.resize(edges.len(), Vec3::ZERO);
    let mut normals = vec![Vec3::Z; edges.len()];
    let mut values: Vec<Vec<f32>> = attributes.iter().map(|a| vec![0.0; a.components * edges.len()]).collect();
    let mut order: Vec<usize> = (0..edges.len()).collect();
    order.sort_by_key(|&v| block_of(edges[v].0));
    let mut duals: Vec<Dual> = Vec::new();
    let mut weights = vec![0.0f32; program.leaves];
    let groups = || order.chunk_by(|&x, &y| block_of(edges[x].0) == block_of(edges[y].0));
    // What placing them takes, worked out before any is placed.
    let mut placing = 0usize;
    for group in groups() {
        let (lo, hi) = block_box(block_of(edges[group[0]].0), 1.0);
        spend(work, program.cost)?;
        placing = placing.saturating_add(group.len() * (REFINE_STEPS + 4) * program.compile(lo, hi).cost());
    }
    spend(work, placing)?;
    for group in groups() {
        let (lo, hi) = block_box(block_of(edges[group[0]].0), 1.0);
        spend(work, program.cost)?;
        let compiled = program.compile(lo, hi);
        compiled.fresh(&mut scratch);
        compiled.fresh(&mut duals);
        for &v in group {
            let (a, b) = edges[v];
            let (pa, pb) = (point(a), point(b));
            let (mut fa, mut fb) = (samples[a] - BLOBBY_THRESHOLD, samples[b] - BLOBBY_THRESHOLD);
            let (mut lo, mut hi) = (0.0f32, 1.0f32);
            let crossing = |fa: f32, fb: f32, lo: f32, hi: f32| {
                let t = fa / (fa - fb);
                if t.is_finite() {
                    lo + (hi - lo) * t.clamp(0.0, 1.0)
                } else {
                    0.5 * (lo + hi)
                }
            };
            let mut t = crossing(fa, fb, lo, hi);
            for _ in 0..REFINE_STEPS {
                let f = compiled.eval(pa.lerp(pb, t), &mut scratch) - BLOBBY_THRESHOLD;
                if f > 0.0 {
                    (lo, fa) = (t, f);
                } else {
                    (hi, fb) = (t, f);
                }
                t = crossing(fa, fb, lo, hi);
            }
            // Off the samples, so that no two vertices coincide where the surface passes through one.
            let p = pa.lerp(pb, t.clamp(1e-3, 1.0 - 1e-3));
            let (_, gradient) = compiled.eval_gradient(p, &mut duals);
            mesh.positions[v] = p;
            // The field falls outwards; where its gradient vanishes the edge points out.
            normals[v] = (-gradient).try_normalize().or((pb - pa).try_normalize()).unwrap_or(Vec3::Z);
            for (w, &instruction) in weights.iter_mut().zip(&program.leaf_instructions) {
                let f = duals[instruction].0.abs();
                *w = if f.is_finite() { f } else { 0.0 };
            }
            let total: f32 = weights.iter().sum();
            for (out, d) in values.iter_mut().zip(data) {
                let n = d.components;
                let out = &mut out[v * n..(v + 1) * n];
                if d.class == Class::Uniform || program.leaves == 0 {
                    out.copy_from_slice(&d.values[..n]);
                    continue;
                }
                for (component, o) in out.iter_mut().enumerate() {
                    let value = |l: usize| d.values[l * n + component];
                    *o = if total > 0.0 {
                        weights.iter().enumerate().map(|(l, w)| w * value(l)).sum::<f32>() / total
                    } else {
                        (0..program.leaves).map(value).sum::<f32>() / program.leaves as f32
                    };
                }
            }
        }
    }
    mesh.normals = Some(normals);
    for (attribute, v) in attributes.iter_mut().zip(values) {
        attribute.data = v;
    }
    // Wound outwards; a triangle collapsed to a line or a point is left out.
    mesh.triangles = triangles
        .into_iter()
        .filter_map(|(t, outward)| {
            let p = t.map(|v| mesh.positions[v as usize]);
            let turn = (p[1] - p[0]).cross(p[2] - p[0]).dot(outward);
            (turn != 0.0).then_some(if turn < 0.0 { [t[0], t[2], t[1]] } else { t })
        })
        .collect();
    route_attributes(&mut mesh, attributes);
    Some(mesh)
}

/// `Blobby`: the isosurface of its field.
pub fn blobby_mesh(input: &BlobbyInput, options: &MeshOptions, warnings: &mut Vec<String>) -> Result<Mesh, String> {
    blobby_mesh_within(input, options, BLOBBY_EVALUATION_BUDGET, warnings)
}

/// [`blobby_mesh`] within `budget` ([`BLOBBY_EVALUATION_BUDGET`] says how it is spent).
fn blobby_mesh_within(
    input: &BlobbyInput,
    options: &MeshOptions,
    budget: usize,
    warnings: &mut Vec<String>,
) -> Result<Mesh, String> {
    let mut plan = Plan::new(input, options, warnings)?;
    let counts = ClassCounts { vertex: plan.program.leaves, varying: plan.program.leaves, face: 1, corner: None };
    let mut data: Vec<_> =
        per_vertex_params(input.params, &counts, warnings).into_iter().filter(|d| d.name != "N").collect();
    // PRMan's `vertex mpoint` data (read as matrices): a leaf's reference frame, from which a
    // renderer would work out a reference position per point; not modelled, so not set.
    data.retain(|d| {
        let frame = d.components == 16;
        if frame {
            warnings.push(format!(
                "\"{}\": a frame of 16 values per leaf (PRMan's mpoint) is not modelled; shaders do not get it",
                d.name
            ));
        }
        !frame
    });
    let mut work_left = budget;
    let too_long = |plan: &Plan| {
        format!(
            "its code ({} instructions and operands) is too long to tessellate on any grid within the budget",
            plan.program.cost
        )
    };
    let mesh = loop {
        let grid = plan.grid(plan.cells);
        // A grid whose sampling would take more than a quarter of the work left gives way to a
        // coarser one; so does one whose vertices would take more than the rest.
        let sampling = grid.sampling_work(&plan.program, &mut work_left).ok_or_else(|| too_long(&plan))?;
        if sampling <= work_left / 4 {
            let mut work = work_left;
            if let Some(mesh) = tessellate(&plan.program, &grid, &data, &mut work) {
                break mesh;
            }
            work_left = work;
        }
        plan.cells = plan.coarser().ok_or_else(|| too_long(&plan))?;
    };
    if plan.cells < plan.wanted {
        warnings.push(format!(
            "tessellated on {} cells along its longest side rather than {}: its code is long ({} instructions \
             and operands)",
            plan.cells, plan.wanted, plan.program.cost
        ));
    }
    mesh.validate().map_err(|e| e.to_string())?;
    Ok(mesh)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rib::{mesh_from_request_with, parse_str, request_triangles, RibDiagnostic, Severity};

    /// PRMan's `vertex mpoint Pref` (a reference frame per leaf) is read, and left out with a
    /// warning: the blobby itself renders.
    #[test]
    fn mpoint_frames_are_read_and_left_out_with_a_warning() {
        let m = sphere(1.0, [0.0, 0.0, 0.0]);
        let (mesh, diags) = build(&format!("Blobby 1 [1001 0] [{m}] [] \"vertex mpoint Pref\" [{m}]"));
        assert!(mesh.is_some_and(|m| m.triangle_count() > 0));
        assert!(diags.iter().any(|d| d.message.contains("\"Pref\"") && d.message.contains("mpoint")), "{diags:?}");
    }

    /// A unit sphere matrix scaled by `s` and moved to `at`, as RIB writes it.
    fn sphere(s: f32, at: [f32; 3]) -> String {
        format!("{s} 0 0 0  0 {s} 0 0  0 0 {s} 0  {} {} {} 1", at[0], at[1], at[2])
    }

    fn build(text: &str) -> (Option<Mesh>, Vec<RibDiagnostic>) {
        let parse = parse_str(text, "blobby.rib");
        assert!(!parse.has_errors(), "{:?}", parse.diagnostics);
        let mut diagnostics = Vec::new();
        let options = MeshOptions::default();
        let mesh = mesh_from_request_with(&parse.requests[0], &options, &mut diagnostics);
        if let Some(mesh) = &mesh {
            assert!(request_triangles(&parse.requests[0], &options) >= mesh.triangle_count(), "{text}");
            assert!(!mesh.triangles.is_empty(), "{text}");
        }
        (mesh, diagnostics)
    }

    fn mesh(text: &str) -> Mesh {
        let (mesh, diagnostics) = build(text);
        assert!(diagnostics.is_empty(), "{diagnostics:?}");
        mesh.expect("a mesh")
    }

    fn error(text: &str) -> String {
        let (mesh, diagnostics) = build(text);
        assert!(mesh.is_none(), "{text}");
        let e = diagnostics.iter().find(|d| d.severity == Severity::Error).expect("an error");
        assert_eq!((e.loc.line, e.loc.column), (1, 1), "at the request");
        e.message.clone()
    }

    /// The connected pieces of a mesh's triangles.
    fn pieces(mesh: &Mesh) -> usize {
        let mut parent: Vec<usize> = (0..mesh.positions.len()).collect();
        fn root(parent: &mut [usize], mut v: usize) -> usize {
            while parent[v] != v {
                parent[v] = parent[parent[v]];
                v = parent[v];
            }
            v
        }
        for t in &mesh.triangles {
            for e in [(t[0], t[1]), (t[1], t[2])] {
                let (a, b) = (root(&mut parent, e.0 as usize), root(&mut parent, e.1 as usize));
                parent[a] = b;
            }
        }
        let used: std::collections::BTreeSet<usize> =
            mesh.triangles.iter().flatten().map(|&v| root(&mut parent, v as usize)).collect();
        used.len()
    }

    /// Every triangle faces away from `centre`, and so does every normal.
    fn faces_out(mesh: &Mesh, centre: Vec3) {
        for t in &mesh.triangles {
            let p = t.map(|v| mesh.positions[v as usize]);
            let n = (p[1] - p[0]).cross(p[2] - p[0]);
            assert!(n.dot((p[0] + p[1] + p[2]) / 3.0 - centre) > 0.0, "{p:?}");
        }
        for (p, n) in mesh.positions.iter().zip(mesh.normals.as_ref().expect("normals")) {
            assert!(n.dot((*p - centre).normalize()) > 0.95, "{p} {n}");
        }
    }

    #[test]
    fn a_lone_ellipsoid_is_its_sphere_at_half_size() {
        let centre = Vec3::new(1.0, 2.0, 3.0);
        let m = mesh(&format!("Blobby 1 [1001 0] [{}] []", sphere(4.0, [1.0, 2.0, 3.0])));
        // The field is the threshold at r = 0.5 in the leaf's space: radius 2 here.
        for p in &m.positions {
            let r = (*p - centre).length();
            assert!((r - 2.0).abs() < 1e-3, "{p}: {r}");
        }
        faces_out(&m, centre);
        assert_eq!(pieces(&m), 1);
        // Closed: every edge is shared by two triangles.
        let mut edges = HashMap::new();
        for t in &m.triangles {
            for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
                *edges.entry((a.min(b), a.max(b))).or_insert(0) += 1;
            }
        }
        let open: Vec<_> = edges.iter().filter(|(_, &n)| n != 2).collect();
        assert!(open.is_empty(), "{} of {} edges: {:?}", open.len(), edges.len(), &open[..open.len().min(4)]);
        // An ellipsoid: stretched along x.
        let m = mesh("Blobby 1 [1001 0] [3 0 0 0  0 1 0 0  0 0 1 0  0 0 0 1] []");
        for p in &m.positions {
            let e = (p.x / 1.5).powi(2) + (p.y / 0.5).powi(2) + (p.z / 0.5).powi(2);
            assert!((e - 1.0).abs() < 1e-2, "{p}: {e}");
        }
    }

    #[test]
    fn a_segment_blob_is_a_capsule() {
        // From (0,0,0) to (2,0,0), radius 1 (surface at 0.5), placed by the identity.
        let m = mesh("Blobby 1 [1002 0] [0 0 0 2 0 0 1  1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1] []");
        for p in &m.positions {
            let d = (*p - Vec3::new(p.x.clamp(0.0, 2.0), 0.0, 0.0)).length();
            assert!((d - 0.5).abs() < 1e-3, "{p}: {d}");
        }
        assert!(m.positions.iter().any(|p| p.x > 2.49) && m.positions.iter().any(|p| p.x < -0.49));
    }

    #[test]
    fn blobs_added_merge_when_close_and_stay_apart_when_far() {
        let two = |d: f32| {
            format!("Blobby 2 [1001 0 1001 16 0 2 0 1] [{} {}] []", sphere(1.0, [0.0; 3]), sphere(1.0, [d, 0.0, 0.0]))
        };
        // Each alone reaches 0.5 from its centre; 1.2 apart their fields still sum above the
        // threshold between them.
        let close = mesh(&two(1.2));
        assert_eq!(pieces(&close), 1);
        let far = mesh(&two(3.0));
        assert_eq!(pieces(&far), 2);
        // Far apart, each is its own sphere.
        for p in &far.positions {
            let r = p.length().min((*p - Vec3::new(3.0, 0.0, 0.0)).length());
            assert!((r - 0.5).abs() < 1e-3, "{p}");
        }
    }

    #[test]
    fn maximum_is_the_union_and_minimum_the_intersection() {
        let (a, b) = (Vec3::ZERO, Vec3::new(0.6, 0.0, 0.0));
        let code = |op: i32| {
            format!(
                "Blobby 2 [1001 0 1001 16 {op} 2 0 1] [{} {}] []",
                sphere(1.0, [0.0; 3]),
                sphere(1.0, [0.6, 0.0, 0.0])
            )
        };
        let union = mesh(&code(2));
        for p in &union.positions {
            let (ra, rb) = ((*p - a).length(), (*p - b).length());
            assert!((ra.min(rb) - 0.5).abs() < 2e-3, "{p}");
        }
        assert_eq!(pieces(&union), 1);
        let intersection = mesh(&code(3));
        for p in &intersection.positions {
            let (ra, rb) = ((*p - a).length(), (*p - b).length());
            assert!((ra.max(rb) - 0.5).abs() < 2e-3, "{p}");
        }
        assert!(intersection.positions.iter().all(|p| p.x > 0.09 && p.x < 0.51));
    }

    #[test]
    fn subtract_bites_and_divide_and_negate_follow_their_operands() {
        // A sphere of radius 1 less a smaller field at its +x side.
        let text =
            format!("Blobby 2 [1001 0 1001 16 4 0 1] [{} {}] []", sphere(2.0, [0.0; 3]), sphere(1.0, [1.0, 0.0, 0.0]));
        let m = mesh(&text);
        assert!(m.positions.iter().any(|p| p.x < -0.99), "the far side stays");
        let reach = m.positions.iter().map(|p| p.x).fold(f32::NEG_INFINITY, f32::max);
        assert!(reach < 0.7, "the near side is bitten: {reach}");
        // On the axis the field less the bite falls to the threshold half way out.
        assert!(!m.positions.iter().any(|p| p.x > 0.55 && p.y.hypot(p.z) < 0.2), "a dent where it bit");
        // The operands the other way round: the small field less the big one is nowhere above
        // the threshold... but at the small one's centre (1 - 0.42 = 0.58): a small piece.
        let text =
            format!("Blobby 2 [1001 0 1001 16 4 1 0] [{} {}] []", sphere(2.0, [0.0; 3]), sphere(1.0, [1.0, 0.0, 0.0]));
        let m = mesh(&text);
        assert!(m.positions.iter().all(|p| p.x > 0.6), "{:?}", m.positions.first());
        // Negating twice and dividing by a constant 1 change nothing.
        let text = format!("Blobby 1 [1001 0 1000 16 6 0 6 2 5 3 1] [{} 1] []", sphere(1.0, [0.0; 3]));
        let m = mesh(&text);
        assert!(m.positions.iter().all(|p| (p.length() - 0.5).abs() < 1e-3));
        // Multiplying by a constant 2 grows the sphere to where the field is half the threshold.
        let text = format!("Blobby 1 [1001 0 1000 16 1 2 0 1] [{} 2] []", sphere(1.0, [0.0; 3]));
        let m = mesh(&text);
        let r = (1.0 - (BLOBBY_THRESHOLD / 2.0).cbrt()).sqrt();
        assert!(m.positions.iter().all(|p| (p.length() - r).abs() < 1e-3), "{r}");
    }

    #[test]
    fn vertex_colours_blend_by_each_leafs_field() {
        let text = format!(
            "Blobby 2 [1001 0 1001 16 0 2 0 1] [{} {}] [] \"Cs\" [1 0 0  0 0 1] \"uniform float k\" [7]",
            sphere(1.0, [0.0; 3]),
            sphere(1.0, [1.2, 0.0, 0.0])
        );
        let m = mesh(&text);
        let cs = m.attributes.iter().find(|a| a.name == "Cs").expect("Cs");
        let k = m.attributes.iter().find(|a| a.name == "k").expect("k");
        assert!(k.data.iter().all(|&v| v == 7.0));
        for (p, c) in m.positions.iter().zip(cs.data.chunks_exact(3)) {
            assert!((c[0] + c[2] - 1.0).abs() < 1e-5 && c[1] == 0.0, "{c:?}");
            if p.x < 0.1 {
                assert!(c[0] > 0.99, "only the first leaf reaches {p}: {c:?}");
            }
            if p.x > 1.1 {
                assert!(c[2] > 0.99, "only the second leaf reaches {p}: {c:?}");
            }
            if (p.x - 0.6).abs() < 0.01 {
                assert!((c[0] - 0.5).abs() < 0.1, "half way, about half each: {c:?}");
            }
        }
    }

    #[test]
    fn the_grid_follows_the_size_on_screen() {
        let parse = parse_str(&format!("Blobby 1 [1001 0] [{}] []", sphere(2.0, [0.0; 3])), "view.rib");
        let at = |z: f32| {
            let view = crate::rib::view::View {
                world_from_object: glam::Affine3A::from_translation(Vec3::new(0.0, 0.0, z)),
                ..Default::default()
            };
            let options = MeshOptions { view, ..MeshOptions::default() };
            let mesh = mesh_from_request_with(&parse.requests[0], &options, &mut Vec::new()).expect("a mesh");
            (mesh.triangle_count(), request_triangles(&parse.requests[0], &options))
        };
        // Near: the box spans the whole view, 128 cells; far: a speck, 16.
        let ((near, near_bound), (far, far_bound)) = (at(2.0), at(1000.0));
        assert_eq!(near_bound, 12 * 130 * 130 * 130);
        assert_eq!(far_bound, 12 * 18 * 18 * 18);
        assert!(far < near / 16 && far > 100, "{near} {far}");
    }

    #[test]
    fn bad_code_is_an_error_at_the_request() {
        let s = sphere(1.0, [0.0; 3]);
        assert!(error(&format!("Blobby 1 [1001 4] [{s}] []")).contains("past the 16 given"));
        assert!(error(&format!("Blobby 1 [1001] [{s}] []")).contains("missing operands"));
        assert!(error(&format!("Blobby 1 [1001 0 0 2 0 1] [{s}] []")).contains("not an earlier instruction"));
        assert!(error(&format!("Blobby 1 [1001 0 7 1] [{s}] []")).contains("not an earlier instruction"));
        assert!(error(&format!("Blobby 1 [1001 0 0 0] [{s}] []")).contains("at least 1"));
        assert!(error(&format!("Blobby 1 [1001 0 0 99999999] [{s}] []")).contains("missing operands"));
        assert!(error(&format!("Blobby 1 [1001 0 42 0] [{s}] []")).contains("unknown opcode"));
        assert!(error(&format!("Blobby 3 [1001 0] [{s}] []")).contains("nleaf is 3"));
        assert!(error(&format!("Blobby -1 [1001 0] [{s}] []")).contains("nleaf is -1"));
        assert!(error("Blobby 1 [1001 0] [0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 1] []").contains("singular"));
        assert!(error("Blobby 1 [1002 0] [0 0 0 1 0 0 -1  1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1] []").contains("radius"));
        assert!(error("Blobby 0 [] [] []").contains("no instructions"));
        assert!(error("Blobby 1 [1000 0] [1] []").contains("nothing to draw"));
        assert!(error(&format!("Blobby 1 [1001 0 1003 0 16] [{s} 1 2 3 4] []")).contains("string 0"));
    }

    #[test]
    fn unsupported_fields_warn_and_add_nothing() {
        let s = sphere(1.0, [0.0; 3]);
        let (m, diagnostics) = build(&format!("Blobby 2 [1001 0 1003 0 16 0 2 0 1] [{s} 1 2 3 4] [\"flat.zfile\"]"));
        let m = m.expect("a mesh");
        assert!(m.positions.iter().all(|p| (p.length() - 0.5).abs() < 1e-3));
        assert_eq!(diagnostics.len(), 1, "{diagnostics:?}");
        assert!(diagnostics[0].message.contains("repelling ground planes (1003) are not supported"));
        // nleaf may count the constants or not.
        assert_eq!(build(&format!("Blobby 2 [1001 0 1000 16 0 2 0 1] [{s} 0]")).1.len(), 0);
        assert_eq!(build(&format!("Blobby 1 [1001 0 1000 16 0 2 0 1] [{s} 0]")).1.len(), 0);
    }

    #[test]
    fn long_code_coarsens_the_grid_within_the_budget() {
        // 400 blobs along a line, each reaching 200 others: a small budget cuts the grid, with a
        // warning, and a smaller one refuses the request.
        let n = 400;
        let mut code = String::new();
        let mut floats = String::new();
        for k in 0..n {
            code.push_str(&format!("1001 {} ", 16 * k));
            floats.push_str(&sphere(0.5, [k as f32 * 0.005, 0.0, 0.0]));
            floats.push(' ');
        }
        code.push_str(&format!("0 {n} "));
        for k in 0..n {
            code.push_str(&format!("{k} "));
        }
        let parse = parse_str(&format!("Blobby {n} [{code}] [{floats}] []"), "long.rib");
        let crate::rib::RequestKind::Blobby { nleaf, code, floats, strings, params } = &parse.requests[0].kind else {
            panic!("{:?}", parse.diagnostics)
        };
        let input = BlobbyInput { nleaf: *nleaf, code, floats, strings, params };
        let options = MeshOptions::default();
        let mut warnings = Vec::new();
        let full = blobby_mesh_within(&input, &options, BLOBBY_EVALUATION_BUDGET, &mut warnings).expect("a mesh");
        warnings.clear();
        let coarse = blobby_mesh_within(&input, &options, 1 << 24, &mut warnings).expect("a mesh");
        assert!(warnings.iter().any(|w| w.contains("rather than")), "{warnings:?}");
        assert!(coarse.triangle_count() < full.triangle_count());
        assert!(blobby_mesh_within(&input, &options, 1 << 12, &mut Vec::new()).unwrap_err().contains("too long"));
        // A long chain of operators evaluates in one pass, whatever its depth.
        let chain: String = (1..=20000).map(|k| format!("7 {} ", k - 1)).collect();
        let (m, diagnostics) = build(&format!("Blobby 1 [1001 0 {chain}] [{}] []", sphere(1.0, [0.0; 3])));
        assert!(m.is_some(), "{diagnostics:?}");
    }

    #[test]
    fn a_program_specialised_to_a_box_keeps_what_reaches_it() {
        let s = |x: f32| sphere(1.0, [x, 0.0, 0.0]);
        // max(a, b) - (c * d): only a reaches the box around the origin.
        let text = format!(
            "Blobby 4 [1001 0 1001 16 1001 32 1001 48 2 2 0 1 1 2 2 3 4 4 5] [{} {} {} {}] []",
            s(0.0),
            s(5.0),
            s(5.5),
            s(-0.5)
        );
        let parse = parse_str(&text, "c.rib");
        let crate::rib::RequestKind::Blobby { nleaf, code, floats, strings, params } = &parse.requests[0].kind else {
            panic!()
        };
        let program = Program::new(&BlobbyInput { nleaf: *nleaf, code, floats, strings, params }, &mut Vec::new())
            .expect("a program");
        let compiled = program.compile(Vec3::splat(-0.2), Vec3::splat(0.2));
        let kept: Vec<usize> = compiled.steps.iter().map(|(i, _)| *i).collect();
        // a, d (reaches to -1.5..0.5), the maximum (with a zero for b), not the product (c is 0),
        // the difference.
        assert_eq!(kept, [0, 3, 4, 6]);
        let mut values = Vec::new();
        compiled.fresh(&mut values);
        let whole = program.compile(Vec3::splat(-10.0), Vec3::splat(10.0));
        let mut all = Vec::new();
        whole.fresh(&mut all);
        for p in [Vec3::ZERO, Vec3::new(0.1, -0.15, 0.2), Vec3::new(-0.2, 0.2, 0.0)] {
            assert_eq!(compiled.eval(p, &mut values), whole.eval(p, &mut all), "{p}");
        }
    }
}
