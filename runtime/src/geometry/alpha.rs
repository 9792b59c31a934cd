//! Alpha masks: cut-outs in geometry, such as leaves drawn as textured quads. A masked object's
//! triangles exist only where the mask's texel under the hit's texture coordinates is covered;
//! every query (closest hit, occlusion, packets, single rays, the brute-force reference) skips the
//! rest, so cut-outs are seen through and cast shaped shadows without any shading.
//!
//! The mask is a bit per texel of the texture's alpha (or single) channel, thresholded once when
//! the mask is made; a lookup is the nearest texel, wrapping periodically (as OBJ and glTF
//! textures do). Coordinates follow the renderer's `s, t` (t = 0 the image's top row).

use super::Mesh;
use crate::texture::TexImage;
use glam::Vec2;

/// Alpha at or above this covers a texel (the usual alpha-test cut-off).
pub const DEFAULT_CUTOFF: f32 = 0.5;

/// Texel coverage of an alpha-masked object (see the module doc).
#[derive(Clone, Debug, PartialEq)]
pub struct AlphaMask {
    width: usize,
    height: usize,
    /// One bit per texel, row-major, top row first.
    covered: Vec<u64>,
}

impl AlphaMask {
    /// The mask of `image`: its last channel (alpha; the only one of a grey image) at or above
    /// `cutoff`. `None` when the image has no uncovered texel, so that masking it would change
    /// nothing (an opaque RGBA texture, or an RGB one).
    pub fn from_image(image: &TexImage, cutoff: f32) -> Option<AlphaMask> {
        let (width, height, channels) = (image.width(), image.height(), image.channels());
        if channels == 3 {
            return None;
        }
        let mut covered = vec![0u64; (width * height).div_ceil(64)];
        let mut any_hole = false;
        for (i, texel) in image.data().chunks_exact(channels).enumerate() {
            // NaN alpha counts as a hole: never let bad data make a solid surface.
            if texel[channels - 1] >= cutoff {
                covered[i / 64] |= 1 << (i % 64);
            } else {
                any_hole = true;
            }
        }
        any_hole.then_some(AlphaMask { width, height, covered })
    }

    /// Whether the texel at `(s, t)` is covered (nearest texel, periodic wrap).
    pub fn covers_st(&self, st: Vec2) -> bool {
        if !st.is_finite() {
            return false;
        }
        let wrap = |x: f32, n: usize| {
            let i = (x.rem_euclid(1.0) * n as f32) as usize;
            i.min(n - 1)
        };
        let i = wrap(st.y, self.height) * self.width + wrap(st.x, self.width);
        self.covered[i / 64] >> (i % 64) & 1 != 0
    }

    /// Whether the point of triangle `primitive` of `mesh` at barycentrics `(u, v)` (weights of
    /// its second and third corners) is covered. A mesh without texture coordinates, or a stale
    /// primitive number, is covered everywhere.
    pub fn covers(&self, mesh: &Mesh, primitive: u32, u: f32, v: f32) -> bool {
        let (Some(uvs), Some(tri)) = (&mesh.uvs, mesh.triangles.get(primitive as usize)) else {
            return true;
        };
        let [a, b, c] = tri.map(|i| uvs.get(i as usize).copied().unwrap_or(Vec2::ZERO));
        self.covers_st(a * (1.0 - u - v) + b * u + c * v)
    }

    /// Heap bytes of the coverage bits.
    pub fn memory_bytes(&self) -> usize {
        self.covered.len() * size_of::<u64>()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    /// A 4x2 grey-alpha image whose left half is covered.
    fn left_half() -> TexImage {
        let mut data = Vec::new();
        for _y in 0..2 {
            for x in 0..4 {
                data.extend([1.0, if x < 2 { 1.0 } else { 0.0 }]);
            }
        }
        TexImage::new(4, 2, 2, data).unwrap()
    }

    #[test]
    fn texels_are_covered_by_their_alpha_and_wrap_periodically() {
        let m = AlphaMask::from_image(&left_half(), DEFAULT_CUTOFF).unwrap();
        assert!(m.covers_st(Vec2::new(0.1, 0.3)));
        assert!(m.covers_st(Vec2::new(0.49, 0.9)));
        assert!(!m.covers_st(Vec2::new(0.51, 0.3)));
        assert!(!m.covers_st(Vec2::new(0.99, 0.0)));
        assert!(m.covers_st(Vec2::new(1.1, 7.3)), "periodic in s and t");
        assert!(!m.covers_st(Vec2::new(-0.1, 0.5)), "negative s wraps to 0.9");
        assert!(!m.covers_st(Vec2::new(f32::NAN, 0.5)));
    }

    #[test]
    fn opaque_and_colour_only_images_make_no_mask() {
        let opaque = TexImage::new(2, 1, 4, vec![1.0; 8]).unwrap();
        assert_eq!(AlphaMask::from_image(&opaque, DEFAULT_CUTOFF), None);
        let rgb = TexImage::new(2, 1, 3, vec![0.0; 6]).unwrap();
        assert_eq!(AlphaMask::from_image(&rgb, DEFAULT_CUTOFF), None);
    }

    #[test]
    fn a_hit_is_covered_where_its_interpolated_coordinates_are() {
        let m = AlphaMask::from_image(&left_half(), DEFAULT_CUTOFF).unwrap();
        let mut mesh = Mesh::from_triangles(vec![Vec3::ZERO, Vec3::X, Vec3::Y], vec![[0, 1, 2]]).unwrap();
        assert!(m.covers(&mesh, 0, 0.9, 0.0), "no texture coordinates: covered everywhere");
        mesh.uvs = Some(vec![Vec2::new(0.0, 0.0), Vec2::new(1.0, 0.0), Vec2::new(0.0, 1.0)]);
        assert!(m.covers(&mesh, 0, 0.2, 0.3), "s = 0.2");
        assert!(!m.covers(&mesh, 0, 0.8, 0.1), "s = 0.8");
        assert!(m.covers(&mesh, 7, 0.8, 0.1), "a stale primitive is not cut");
    }
}
