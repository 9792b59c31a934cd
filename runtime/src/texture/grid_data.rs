//! Small synthetic data sets for volume rendering, written by `rtsl volume generate`
//! (`docs/volumes.md`). Each is a pure function of its size, so the shipped files can be
//! regenerated bit for bit.

use super::grid::Grid;
use rtsl_compiler::shadeops::noise::noise3;

/// What `rtsl volume generate --kind` makes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GridKind {
    /// A puffy cloud: a ball whose edge is eaten by three octaves of Perlin noise.
    Cloud,
    /// In the spirit of the "neghip" data set (the electrostatic potential of a protein): the
    /// potential of eight point charges, four positive and four negative, squashed into 0..1.
    NeghipLike,
}

/// The data set `kind` on a `size`^3 lattice over (-1, -1, -1)..(1, 1, 1); `None` for a size
/// below 2.
pub fn generate(kind: GridKind, size: usize) -> Option<Grid> {
    if size < 2 {
        return None;
    }
    let at = |i: usize| -1.0 + 2.0 * i as f32 / (size - 1) as f32;
    let mut values = Vec::with_capacity(size * size * size);
    for k in 0..size {
        for j in 0..size {
            for i in 0..size {
                let p = [at(i), at(j), at(k)];
                values.push(match kind {
                    GridKind::Cloud => cloud(p),
                    GridKind::NeghipLike => neghip_like(p),
                });
            }
        }
    }
    Grid::new([size; 3], [-1.0; 3], [1.0; 3], values)
}

fn cloud(p: [f32; 3]) -> f32 {
    let r = (p[0] * p[0] + p[1] * p[1] * 1.6 + p[2] * p[2]).sqrt();
    let mut n = 0.0;
    let mut scale = 1.0;
    for octave in 0..3 {
        let f = 2.5 * (1 << octave) as f32;
        n += scale * (noise3([p[0] * f + 7.1, p[1] * f + 3.3, p[2] * f + 1.7]) - 0.5);
        scale *= 0.5;
    }
    // Distance from the ball's surface, perturbed by the noise: 1 deep inside, 0 outside.
    let inside = (0.75 + 0.9 * n - r) / 0.35;
    inside.clamp(0.0, 1.0)
}

const CHARGES: [([f32; 3], f32); 8] = [
    ([0.35, 0.3, 0.2], 1.0),
    ([-0.4, 0.25, -0.1], 1.0),
    ([0.1, -0.45, 0.35], 1.0),
    ([-0.15, -0.2, -0.45], 1.0),
    ([-0.35, -0.4, 0.3], -1.0),
    ([0.4, -0.15, -0.35], -1.0),
    ([0.0, 0.45, -0.4], -1.0),
    ([-0.05, 0.05, 0.45], -1.0),
];

fn neghip_like(p: [f32; 3]) -> f32 {
    let mut v = 0.0;
    for (c, q) in CHARGES {
        let d = ((p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2) + (p[2] - c[2]).powi(2)).sqrt();
        v += q / d.max(0.05);
    }
    // Positive lobes towards 1, negative towards 0, neutral 0.5, fading to 0 at the box's edge.
    let edge = ((1.0 - p[0].abs().max(p[1].abs()).max(p[2].abs())) / 0.2).clamp(0.0, 1.0);
    (edge * (0.5 + 0.5 * (0.4 * v).tanh())).clamp(0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn data_sets_are_in_range_and_not_flat() {
        for kind in [GridKind::Cloud, GridKind::NeghipLike] {
            let g = generate(kind, 12).unwrap();
            assert_eq!(g.dims(), [12; 3]);
            let vals: Vec<f32> = (0..12)
                .flat_map(|k| (0..12).map(move |j| (j, k)))
                .flat_map(|(j, k)| (0..12).map(move |i| (i, j, k)))
                .map(|(i, j, k)| g.sample(i, j, k))
                .collect();
            assert!(vals.iter().all(|v| (0.0..=1.0).contains(v)), "{kind:?}");
            let (lo, hi) = vals.iter().fold((1.0f32, 0.0f32), |(a, b), v| (a.min(*v), b.max(*v)));
            assert!(hi - lo > 0.5, "{kind:?}: {lo}..{hi}");
            // Empty at the corners of the box.
            assert_eq!(g.sample(0, 0, 0), 0.0, "{kind:?}");
        }
        assert!(generate(GridKind::Cloud, 1).is_none());
    }
}
