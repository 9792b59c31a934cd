//! 3-D scalar grids for volume shaders: the `RTSLGRID` file format (`docs/volumes.md`), its reader
//! and writer, and trilinear lookups (RSL's `texture3d(name, p)`).
//!
//! Conventions:
//! - **Samples sit on the nodes** of a regular lattice spanning the header's bounds: sample
//!   `(i, j, k)` of an `nx x ny x nz` grid is at `min + (i/(nx-1), j/(ny-1), k/(nz-1)) * (max - min)`,
//!   so the bounds' corners are exactly the corner samples (an axis of one sample is constant).
//! - **Order**: x varies fastest, then y, then z (`index = i + nx * (j + ny * k)`).
//! - **Values**: `u8` samples read as `v / 255`, `f32` samples as they are (little-endian).
//! - **Outside** the bounds a lookup is 0: the grid is an empty medium there.
//! - **Errors** name the file and what is wrong; the header's counts never size an allocation
//!   beyond what the file holds (the data's length is checked against them first).

use glam::{BVec4A, Vec4};
use std::path::{Path, PathBuf};

/// The first line of every grid file.
pub const GRID_MAGIC: &str = "RTSLGRID 1";

/// The most bytes the text header may take before its `data` line.
const MAX_HEADER: usize = 4096;

/// How each sample is stored in a grid file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GridType {
    U8,
    F32,
}

impl GridType {
    fn bytes(self) -> usize {
        match self {
            GridType::U8 => 1,
            GridType::F32 => 4,
        }
    }

    fn name(self) -> &'static str {
        match self {
            GridType::U8 => "u8",
            GridType::F32 => "f32",
        }
    }
}

/// A grid file that cannot be read: the file and what is wrong with it.
#[derive(Debug, thiserror::Error)]
#[error("grid {}: {reason}", path.display())]
pub struct GridError {
    pub path: PathBuf,
    pub reason: String,
}

/// A regular 3-D grid of scalar samples over an axis-aligned box.
#[derive(Clone, Debug, PartialEq)]
pub struct Grid {
    dims: [usize; 3],
    min: [f32; 3],
    max: [f32; 3],
    values: Vec<f32>,
    /// Lattice steps per unit along each axis: `(dims - 1) / (max - min)` (`1 / (max - min)` for
    /// an axis of one sample, so that the bounds test still sees the box).
    scale: [f32; 3],
}

impl Grid {
    /// A grid of `dims` samples (x fastest) spanning `min..max`; `None` when the sizes disagree, a
    /// dimension is 0 or a bound is not finite or not increasing.
    pub fn new(dims: [usize; 3], min: [f32; 3], max: [f32; 3], values: Vec<f32>) -> Option<Grid> {
        let count = dims.iter().try_fold(1usize, |acc, d| acc.checked_mul(*d))?;
        let bounds_ok = (0..3).all(|a| min[a].is_finite() && max[a].is_finite() && max[a] > min[a]);
        let scale = std::array::from_fn(|a| (dims[a].max(2) - 1) as f32 / (max[a] - min[a]));
        (count == values.len() && count > 0 && bounds_ok).then_some(Grid { dims, min, max, values, scale })
    }

    pub fn dims(&self) -> [usize; 3] {
        self.dims
    }

    pub fn bounds(&self) -> ([f32; 3], [f32; 3]) {
        (self.min, self.max)
    }

    /// The sample at node `(i, j, k)`.
    pub fn sample(&self, i: usize, j: usize, k: usize) -> f32 {
        self.values[i + self.dims[0] * (j + self.dims[1] * k)]
    }

    /// The trilinear interpolation of the samples at `p` (0 outside the bounds; NaN reads as 0).
    pub fn lookup(&self, p: [f32; 3]) -> f32 {
        let mut base = [0usize; 3];
        let mut frac = [0.0f32; 3];
        for a in 0..3 {
            let last = self.dims[a] - 1;
            let x = (p[a] - self.min[a]) * self.scale[a];
            // `!(..)` also sends NaN outside.
            if !(0.0..=last.max(1) as f32).contains(&x) {
                return 0.0;
            }
            // `x >= 0`, so truncation is floor (and no libm call).
            let i = (x as usize).min(last.saturating_sub(1));
            base[a] = i;
            frac[a] = if last == 0 { 0.0 } else { (x - i as f32).clamp(0.0, 1.0) };
        }
        let [nx, ny, _] = self.dims;
        // The strides to the next node along each axis (0 along an axis of one sample).
        let dx = usize::from(nx > 1);
        let dy = if ny > 1 { nx } else { 0 };
        let dz = if self.dims[2] > 1 { nx * ny } else { 0 };
        let at = base[0] + nx * (base[1] + ny * base[2]);
        let v = |i: usize| self.values.get(i).copied().unwrap_or(0.0);
        let lerp = |a: f32, b: f32, t: f32| a + (b - a) * t;
        let along_x = |i: usize| lerp(v(i), v(i + dx), frac[0]);
        let c0 = lerp(along_x(at), along_x(at + dy), frac[1]);
        let c1 = lerp(along_x(at + dz), along_x(at + dz + dy), frac[1]);
        lerp(c0, c1, frac[2])
    }

    /// [`Grid::lookup`] at four points (`p[a]`: the points' coordinates along axis `a`), the same
    /// value in each lane: the lanes' cells and weights are worked out together, in vector
    /// arithmetic (the same IEEE operations lane by lane), and only the samples are read lane by
    /// lane. A volume's march asks for a chunk's four points at every step.
    pub fn lookup_lanes(&self, p: [Vec4; 3]) -> [f32; 4] {
        if self.dims.iter().any(|&d| d > 1 << 24) {
            // Cells past what a float counts exactly (and the vector conversion holds): lane by lane.
            return std::array::from_fn(|l| self.lookup([p[0][l], p[1][l], p[2][l]]));
        }
        let mut inside = BVec4A::splat(true);
        let mut base = [[0usize; 4]; 3];
        let mut frac = [Vec4::ZERO; 3];
        for a in 0..3 {
            let last = self.dims[a] - 1;
            let x = (p[a] - Vec4::splat(self.min[a])) * Vec4::splat(self.scale[a]);
            // Compared as `lookup` does: NaN is outside.
            let ok = x.cmpge(Vec4::ZERO) & x.cmple(Vec4::splat(last.max(1) as f32));
            inside &= ok;
            // Outside lanes read cell 0 (their value is dropped): every index stays in the grid.
            let x = Vec4::select(ok, x, Vec4::ZERO);
            let cell = truncated(x).map(|i| i.min(last.saturating_sub(1)));
            base[a] = cell;
            frac[a] = if last == 0 {
                Vec4::ZERO
            } else {
                (x - Vec4::from_array(cell.map(|i| i as f32))).clamp(Vec4::ZERO, Vec4::ONE)
            };
        }
        let [nx, ny, _] = self.dims;
        let dx = usize::from(nx > 1);
        let dy = if ny > 1 { nx } else { 0 };
        let dz = if self.dims[2] > 1 { nx * ny } else { 0 };
        let at: [usize; 4] = std::array::from_fn(|l| base[0][l] + nx * (base[1][l] + ny * base[2][l]));
        let v = |offset: usize| {
            Vec4::from_array(std::array::from_fn(|l| self.values.get(at[l] + offset).copied().unwrap_or(0.0)))
        };
        let lerp = |a: Vec4, b: Vec4, t: Vec4| a + (b - a) * t;
        let along_x = |offset: usize| lerp(v(offset), v(offset + dx), frac[0]);
        let c0 = lerp(along_x(0), along_x(dy), frac[1]);
        let c1 = lerp(along_x(dz), along_x(dz + dy), frac[1]);
        Vec4::select(inside, lerp(c0, c1, frac[2]), Vec4::ZERO).to_array()
    }

    /// The file's bytes: the text header, then the samples (`u8`: `round(clamp(v, 0, 1) * 255)`).
    pub fn to_bytes(&self, ty: GridType) -> Vec<u8> {
        let [nx, ny, nz] = self.dims;
        let (a, b) = (self.min, self.max);
        let mut out = format!(
            "{GRID_MAGIC}\ndims {nx} {ny} {nz}\ntype {}\nbounds {} {} {} {} {} {}\ndata\n",
            ty.name(),
            a[0],
            a[1],
            a[2],
            b[0],
            b[1],
            b[2]
        )
        .into_bytes();
        for v in &self.values {
            match ty {
                GridType::U8 => out.push((v.clamp(0.0, 1.0) * 255.0).round() as u8),
                GridType::F32 => out.extend_from_slice(&v.to_le_bytes()),
            }
        }
        out
    }

    /// Reads a grid file.
    pub fn load(path: &Path) -> Result<Grid, GridError> {
        let bytes = std::fs::read(path).map_err(|e| GridError { path: path.to_path_buf(), reason: e.to_string() })?;
        Grid::parse(&bytes).map_err(|reason| GridError { path: path.to_path_buf(), reason })
    }

    /// Parses a grid file's bytes; the error says what is wrong.
    pub fn parse(bytes: &[u8]) -> Result<Grid, String> {
        let mut dims = None;
        let mut ty = None;
        let mut bounds = None;
        let mut pos = 0;
        let mut line_no = 0;
        let data_start = loop {
            let rest = &bytes[pos..];
            let Some(end) = rest.iter().position(|b| *b == b'\n') else {
                return Err(if line_no == 0 && !bytes.starts_with(GRID_MAGIC.as_bytes()) {
                    format!("not a grid file (it does not start with `{GRID_MAGIC}`)")
                } else {
                    "the header ends before its `data` line".into()
                });
            };
            if pos + end > MAX_HEADER {
                return Err(format!("no `data` line in the first {MAX_HEADER} bytes"));
            }
            let line =
                std::str::from_utf8(&rest[..end]).map_err(|_| format!("header line {} is not text", line_no + 1))?;
            let line = line.trim();
            line_no += 1;
            pos += end + 1;
            if line_no == 1 {
                if line != GRID_MAGIC {
                    return Err(format!("not a grid file (its first line is not `{GRID_MAGIC}`)"));
                }
                continue;
            }
            let mut words = line.split_whitespace();
            let Some(key) = words.next() else { continue };
            let args: Vec<&str> = words.collect();
            let bad = |what: &str| format!("header line {line_no}: {what}");
            match key {
                k if k.starts_with('#') => {}
                "dims" => {
                    let d: Vec<usize> = args.iter().filter_map(|a| a.parse().ok()).collect();
                    if args.len() != 3 || d.len() != 3 || d.contains(&0) {
                        return Err(bad("`dims` takes three whole numbers, each at least 1"));
                    }
                    dims = Some([d[0], d[1], d[2]]);
                }
                "type" => {
                    ty = Some(match args.as_slice() {
                        ["u8"] => GridType::U8,
                        ["f32"] => GridType::F32,
                        _ => return Err(bad("`type` is `u8` or `f32`")),
                    });
                }
                "bounds" => {
                    let b: Vec<f32> = args.iter().filter_map(|a| a.parse().ok()).collect();
                    let ok = args.len() == 6
                        && b.len() == 6
                        && b.iter().all(|x| x.is_finite())
                        && (0..3).all(|a| b[a + 3] > b[a]);
                    if !ok {
                        return Err(bad(
                            "`bounds` takes six numbers, xmin ymin zmin xmax ymax zmax, each max above its min",
                        ));
                    }
                    bounds = Some(([b[0], b[1], b[2]], [b[3], b[4], b[5]]));
                }
                "data" if args.is_empty() => break pos,
                other => return Err(bad(&format!("unknown header key `{other}` (dims, type, bounds, data)"))),
            }
        };
        let dims = dims.ok_or("the header has no `dims` line")?;
        let ty = ty.ok_or("the header has no `type` line")?;
        let (min, max) = bounds.ok_or("the header has no `bounds` line")?;
        let data = &bytes[data_start..];
        // Sizes are checked against the data present before anything is allocated.
        let count = dims.iter().try_fold(1usize, |acc, d| acc.checked_mul(*d));
        let need = count.and_then(|c| c.checked_mul(ty.bytes()));
        let (Some(count), Some(need)) = (count, need) else {
            return Err(format!("`dims {} {} {}` is too large", dims[0], dims[1], dims[2]));
        };
        if data.len() < need {
            return Err(format!(
                "truncated: the header promises {count} {} samples ({need} bytes) but {} bytes follow `data`",
                ty.name(),
                data.len()
            ));
        }
        if data.len() > need {
            return Err(format!("{} bytes follow the {need} bytes of samples", data.len() - need));
        }
        let values: Vec<f32> = match ty {
            GridType::U8 => data.iter().map(|b| f32::from(*b) / 255.0).collect(),
            GridType::F32 => data
                .chunks_exact(4)
                .map(|c| {
                    let v = f32::from_le_bytes([c[0], c[1], c[2], c[3]]);
                    if v.is_finite() {
                        v
                    } else {
                        0.0
                    }
                })
                .collect(),
        };
        Grid::new(dims, min, max, values).ok_or_else(|| "inconsistent header".to_string())
    }
}

/// Each lane of `x` (in `[0, 2^31)`) truncated to an integer.
#[inline(always)]
fn truncated(x: Vec4) -> [usize; 4] {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{__m128, _mm_cvttps_epi32};
        // SAFETY: SSE2 is part of x86-64.
        let v = unsafe { _mm_cvttps_epi32(__m128::from(x)) };
        let lanes: [i32; 4] = bytemuck::cast(v);
        lanes.map(|i| i.max(0) as usize)
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        x.to_array().map(|v| v as usize)
    }
}

#[cfg(test)]
mod tests {
    /// Four lanes at once give each lane what `lookup` gives it, bit for bit: inside, on the
    /// faces, outside, at NaN, and on grids with an axis of one sample.
    #[test]
    fn four_lanes_at_once_look_up_what_each_lane_looks_up() {
        // An additive recurrence by an irrational step: points spread evenly over [0, 1).
        let mut k = 0u32;
        let mut next = || {
            k += 1;
            (f64::from(k) * 0.618_033_988_749_895).fract() as f32
        };
        for dims in [[5, 4, 3], [1, 6, 2], [7, 1, 1], [2, 2, 2]] {
            let count = dims[0] * dims[1] * dims[2];
            let values: Vec<f32> = (0..count).map(|i| (i as f32 * 0.37).sin()).collect();
            let grid = Grid::new(dims, [-1.0, 0.5, 2.0], [1.5, 2.0, 4.0], values).expect("a valid grid");
            for round in 0..500 {
                let mut p: [Vec4; 3] = std::array::from_fn(|a| {
                    let (lo, hi) = ([-1.0, 0.5, 2.0][a], [1.5, 2.0, 4.0][a]);
                    Vec4::from_array(std::array::from_fn(|_| lo - 0.3 + (hi - lo + 0.6) * next()))
                });
                match round % 7 {
                    0 => p[1] = Vec4::new(f32::NAN, 0.5, 2.0, f32::INFINITY),
                    1 => p[0] = Vec4::new(-1.0, 1.5, 1.5000001, -1.0000001),
                    _ => {}
                }
                let lanes = grid.lookup_lanes(p);
                for (l, &got) in lanes.iter().enumerate() {
                    let want = grid.lookup([p[0][l], p[1][l], p[2][l]]);
                    assert_eq!(got.to_bits(), want.to_bits(), "{dims:?} lane {l}: {got} against {want}");
                }
            }
        }
    }

    use super::*;

    /// A 2x3x2 grid whose sample is `i + 10 j + 100 k`, over (0,0,0)..(1,2,4).
    fn ramp() -> Grid {
        let mut v = Vec::new();
        for k in 0..2 {
            for j in 0..3 {
                for i in 0..2 {
                    v.push((i + 10 * j + 100 * k) as f32);
                }
            }
        }
        Grid::new([2, 3, 2], [0.0; 3], [1.0, 2.0, 4.0], v).unwrap()
    }

    #[test]
    fn round_trips_f32_and_u8() {
        let g = ramp();
        assert_eq!(Grid::parse(&g.to_bytes(GridType::F32)).unwrap(), g);
        let small = Grid::new([2, 1, 1], [-1.0; 3], [1.0; 3], vec![0.0, 0.5]).unwrap();
        let back = Grid::parse(&small.to_bytes(GridType::U8)).unwrap();
        assert_eq!(back.sample(0, 0, 0), 0.0);
        assert!((back.sample(1, 0, 0) - 128.0 / 255.0).abs() < 1e-6);
        assert_eq!(back.bounds(), ([-1.0; 3], [1.0; 3]));
    }

    #[test]
    fn trilinear_at_corners_and_centres() {
        let g = ramp();
        // Corners are exactly the corner samples.
        assert_eq!(g.lookup([0.0, 0.0, 0.0]), 0.0);
        assert_eq!(g.lookup([1.0, 2.0, 4.0]), 121.0);
        assert_eq!(g.lookup([1.0, 0.0, 0.0]), 1.0);
        // A node in the middle of y: sample (0, 1, 1).
        assert_eq!(g.lookup([0.0, 1.0, 4.0]), 110.0);
        // The centre of the box: the mean of the linear ramp.
        assert!((g.lookup([0.5, 1.0, 2.0]) - 60.5).abs() < 1e-4);
        // Between nodes along each axis.
        assert!((g.lookup([0.25, 0.5, 1.0]) - (0.25 + 5.0 + 25.0)).abs() < 1e-4);
        // Outside the bounds: empty.
        assert_eq!(g.lookup([-0.01, 1.0, 1.0]), 0.0);
        assert_eq!(g.lookup([0.5, 1.0, 4.5]), 0.0);
        assert_eq!(g.lookup([f32::NAN, 1.0, 1.0]), 0.0);
    }

    #[test]
    fn a_single_sample_axis_is_constant() {
        let g = Grid::new([2, 1, 1], [0.0; 3], [1.0; 3], vec![2.0, 4.0]).unwrap();
        assert_eq!(g.lookup([0.5, 0.9, 0.1]), 3.0);
    }

    #[test]
    fn truncated_and_overlong_files_are_refused() {
        let bytes = ramp().to_bytes(GridType::F32);
        let err = Grid::parse(&bytes[..bytes.len() - 3]).unwrap_err();
        assert!(err.contains("truncated") && err.contains("48 bytes"), "{err}");
        let mut long = bytes.clone();
        long.push(0);
        assert!(Grid::parse(&long).unwrap_err().contains("1 bytes follow"));
    }

    #[test]
    fn bad_headers_say_what_is_wrong() {
        let cases: &[(&[u8], &str)] = &[
            (b"P6\n2 2\n255\n", "not a grid file"),
            (b"RTSLGRID 2\ndata\n", "not a grid file"),
            (b"RTSLGRID 1\ndims 2 2\ntype u8\n", "`dims` takes three"),
            (b"RTSLGRID 1\ndims 2 0 2\n", "`dims` takes three"),
            (b"RTSLGRID 1\ntype u16\n", "`type` is"),
            (b"RTSLGRID 1\nbounds 0 0 0 1 1 0\n", "`bounds` takes six"),
            (b"RTSLGRID 1\nspacing 1 1 1\n", "unknown header key `spacing`"),
            (b"RTSLGRID 1\ndims 1 1 1\ntype u8\n", "ends before its `data`"),
            (b"RTSLGRID 1\ntype u8\nbounds 0 0 0 1 1 1\ndata\n\x00", "no `dims`"),
            (b"", "not a grid file"),
        ];
        for (bytes, want) in cases {
            let err = Grid::parse(bytes).unwrap_err();
            assert!(err.contains(want), "{:?}: {err}", String::from_utf8_lossy(bytes));
        }
    }

    #[test]
    fn huge_counts_do_not_allocate() {
        let header = b"RTSLGRID 1\ndims 100000 100000 100000\ntype f32\nbounds 0 0 0 1 1 1\ndata\n\x00\x00";
        assert!(Grid::parse(header).unwrap_err().contains("truncated"));
        let overflow = b"RTSLGRID 1\ndims 18446744073709551615 2 2\ntype f32\nbounds 0 0 0 1 1 1\ndata\n";
        assert!(Grid::parse(overflow).unwrap_err().contains("too large"));
    }

    #[test]
    fn load_names_the_file() {
        let dir = std::env::temp_dir().join(format!("rtsl-grid-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("bad.grid");
        std::fs::write(&path, b"RTSLGRID 1\ndims 2 2 2\ntype u8\nbounds 0 0 0 1 1 1\ndata\n\x01").unwrap();
        let err = Grid::load(&path).unwrap_err().to_string();
        assert!(err.contains("bad.grid") && err.contains("truncated"), "{err}");
        let missing = Grid::load(&dir.join("none.grid")).unwrap_err().to_string();
        assert!(missing.contains("none.grid"), "{missing}");
        std::fs::remove_dir_all(&dir).ok();
    }
}
