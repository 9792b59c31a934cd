//! VRML 97's `Background` (ISO/IEC 14772-1, 6.5) as a latitude-longitude environment map: the
//! sky gradient, the ground gradient in front of it and the six panorama images in front of both,
//! seen from the Background's origin (its parents' rotations turn it; nothing moves it). The
//! library's `envbackground` imager looks it up along each pixel's camera ray.
//!
//! - Sky: `skyColor[0]` at the zenith, `skyColor[i]` at `skyAngle[i - 1]` from it, linear in the
//!   angle between, the last colour on to the nadir.
//! - Ground: `groundColor[0]` at the nadir, `groundColor[i]` at `groundAngle[i - 1]` from it, and
//!   nothing (the sky shows) past the last angle.
//! - Panorama: each image on a face of a cube around the origin (front -z, back +z, left -x, right
//!   +x, top +y, bottom -y), upright as the spec orients it: the four sides seen from the origin
//!   with +y up, the top looking up with +z up, the bottom looking down with -z up. An image's
//!   alpha lets the gradients show through.

use crate::texture::{latlong_to_direction, TexImage};
use glam::{Quat, Vec3};

/// The widest map made (its height is half that).
pub const MAX_BACKGROUND_WIDTH: usize = 2048;
/// The width of a map of gradients only.
const GRADIENT_WIDTH: usize = 256;

/// A panorama face: its image, the outward axis it faces, and its right and up directions.
pub struct Face {
    pub image: TexImage,
    pub axis: Vec3,
    pub right: Vec3,
    pub up: Vec3,
}

/// The face of each panorama field, by the spec's orientation.
pub const FACES: [(&str, Vec3, Vec3, Vec3); 6] = [
    ("frontUrl", Vec3::NEG_Z, Vec3::X, Vec3::Y),
    ("backUrl", Vec3::Z, Vec3::NEG_X, Vec3::Y),
    ("leftUrl", Vec3::NEG_X, Vec3::NEG_Z, Vec3::Y),
    ("rightUrl", Vec3::X, Vec3::Z, Vec3::Y),
    ("topUrl", Vec3::Y, Vec3::X, Vec3::Z),
    ("bottomUrl", Vec3::NEG_Y, Vec3::X, Vec3::NEG_Z),
];

/// What a Background shows, colours linear.
pub struct Backdrop {
    pub sky: Vec<[f32; 3]>,
    pub sky_angles: Vec<f32>,
    pub ground: Vec<[f32; 3]>,
    pub ground_angles: Vec<f32>,
    pub faces: Vec<Face>,
    /// World from the Background's frame (its parents' rotations).
    pub rotation: Quat,
}

impl Backdrop {
    /// The map's size: four faces' widths across when there are faces, else a small gradient map.
    pub fn size(&self) -> (usize, usize) {
        let face = self.faces.iter().map(|f| f.image.width()).max().unwrap_or(0);
        let w = if face == 0 { GRADIENT_WIDTH } else { (4 * face).clamp(64, MAX_BACKGROUND_WIDTH) };
        (w, w / 2)
    }

    /// The RGB texels of the map, rows from the top (the zenith).
    pub fn map(&self) -> (usize, usize, Vec<f32>) {
        let (w, h) = self.size();
        let to_local = self.rotation.inverse();
        let mut texels = Vec::with_capacity(w * h * 3);
        for j in 0..h {
            for i in 0..w {
                let d = latlong_to_direction((i as f32 + 0.5) / w as f32, (j as f32 + 0.5) / h as f32);
                texels.extend_from_slice(&self.colour(to_local * Vec3::from(d)));
            }
        }
        (w, h, texels)
    }

    /// The colour seen along the unit direction `d` of the Background's frame.
    pub fn colour(&self, d: Vec3) -> [f32; 3] {
        let from_zenith = d.y.clamp(-1.0, 1.0).acos();
        let mut c = gradient(&self.sky, &self.sky_angles, from_zenith).unwrap_or([0.0; 3]);
        // The ground reaches up to the angle of its last colour (nowhere with one colour alone).
        let from_nadir = std::f32::consts::PI - from_zenith;
        let reach = self.ground_angles.get(self.ground.len().saturating_sub(2)).filter(|_| self.ground.len() > 1);
        if let (Some(&reach), Some(g)) = (reach, gradient(&self.ground, &self.ground_angles, from_nadir)) {
            if from_nadir <= reach {
                c = g;
            }
        }
        if let Some((face, u, v)) = self.face_at(d) {
            let [r, g, b, a] = bilinear(&face.image, u, v);
            c = [r + (1.0 - a) * c[0], g + (1.0 - a) * c[1], b + (1.0 - a) * c[2]];
        }
        c
    }

    /// The face `d` points through, and where on it (u right, v down, 0 to 1).
    fn face_at(&self, d: Vec3) -> Option<(&Face, f32, f32)> {
        let face = self.faces.iter().max_by(|a, b| a.axis.dot(d).total_cmp(&b.axis.dot(d)))?;
        let major = face.axis.dot(d);
        // Only the face of the largest component: another face's image does not show here.
        let largest = d.x.abs().max(d.y.abs()).max(d.z.abs());
        if major <= 0.0 || major < largest {
            return None;
        }
        Some((face, 0.5 + 0.5 * face.right.dot(d) / major, 0.5 - 0.5 * face.up.dot(d) / major))
    }
}

/// The colour at `angle` of a gradient: `colours[0]` at 0, `colours[i]` at `angles[i - 1]`, linear
/// between, the last beyond; `None` without colours.
fn gradient(colours: &[[f32; 3]], angles: &[f32], angle: f32) -> Option<[f32; 3]> {
    let first = *colours.first()?;
    let mut prev = (0.0f32, first);
    for (k, c) in colours.iter().enumerate().skip(1) {
        let Some(&at) = angles.get(k - 1) else { break };
        if angle <= at {
            let t = if at > prev.0 { (angle - prev.0) / (at - prev.0) } else { 1.0 };
            return Some(std::array::from_fn(|i| prev.1[i] + t * (c[i] - prev.1[i])));
        }
        prev = (at, *c);
    }
    Some(prev.1)
}

/// Bilinear RGBA of `image` at (u, v), edges clamped; one or two channels read as grey.
fn bilinear(image: &TexImage, u: f32, v: f32) -> [f32; 4] {
    let (w, h, n) = (image.width(), image.height(), image.channels());
    let texel = |x: usize, y: usize| -> [f32; 4] {
        let p = &image.data()[(y * w + x) * n..(y * w + x + 1) * n];
        match n {
            1 => [p[0], p[0], p[0], 1.0],
            2 => [p[0], p[0], p[0], p[1]],
            3 => [p[0], p[1], p[2], 1.0],
            _ => [p[0], p[1], p[2], p[3]],
        }
    };
    let fx = (u * w as f32 - 0.5).clamp(0.0, (w - 1) as f32);
    let fy = (v * h as f32 - 0.5).clamp(0.0, (h - 1) as f32);
    let (x0, y0) = (fx.floor() as usize, fy.floor() as usize);
    let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
    let (tx, ty) = (fx - x0 as f32, fy - y0 as f32);
    let (a, b, c, d) = (texel(x0, y0), texel(x1, y0), texel(x0, y1), texel(x1, y1));
    std::array::from_fn(|i| {
        let top = a[i] + tx * (b[i] - a[i]);
        let bottom = c[i] + tx * (d[i] - c[i]);
        top + ty * (bottom - top)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn solid(r: f32, g: f32, b: f32) -> TexImage {
        TexImage::new(2, 2, 3, [r, g, b].repeat(4)).expect("an image")
    }

    #[test]
    fn gradients_follow_their_angles_and_the_ground_hides_the_sky() {
        let half = std::f32::consts::FRAC_PI_2;
        let b = Backdrop {
            sky: vec![[0.0, 0.0, 1.0], [1.0, 1.0, 1.0]],
            sky_angles: vec![half],
            ground: vec![[0.0, 1.0, 0.0], [1.0, 0.0, 0.0]],
            ground_angles: vec![0.5],
            faces: Vec::new(),
            rotation: Quat::IDENTITY,
        };
        assert_eq!(b.colour(Vec3::Y), [0.0, 0.0, 1.0], "the zenith");
        let at_45 = b.colour(Vec3::new(0.0, 1.0, 1.0).normalize());
        assert!((at_45[0] - 0.5).abs() < 1e-5 && (at_45[2] - 1.0).abs() < 1e-5, "halfway: {at_45:?}");
        assert_eq!(b.colour(Vec3::NEG_Y), [0.0, 1.0, 0.0], "the nadir is ground");
        // Past the ground's last angle (0.5 rad from the nadir) the sky's last colour shows.
        assert_eq!(b.colour(Vec3::new(0.0, -0.5, 1.0).normalize()), [1.0, 1.0, 1.0]);
    }

    #[test]
    fn each_panorama_face_is_seen_through_its_side_upright() {
        let faces = FACES
            .iter()
            .enumerate()
            .map(|(k, &(_, axis, right, up))| Face { image: solid(k as f32, 0.0, 0.0), axis, right, up })
            .collect();
        let b = Backdrop {
            sky: vec![[0.5; 3]],
            sky_angles: Vec::new(),
            ground: Vec::new(),
            ground_angles: Vec::new(),
            faces,
            rotation: Quat::IDENTITY,
        };
        for (k, &(name, axis, ..)) in FACES.iter().enumerate() {
            assert_eq!(b.colour(axis)[0], k as f32, "{name}");
        }
        // Orientation: on the front face, the image's left column is toward -x, its top toward +y.
        let mut texels = vec![0.0; 12];
        texels[0] = 1.0; // the top-left texel red
        let front = TexImage::new(2, 2, 3, texels).expect("an image");
        let b = Backdrop { faces: vec![Face { image: front, axis: Vec3::NEG_Z, right: Vec3::X, up: Vec3::Y }], ..b };
        assert!(b.colour(Vec3::new(-0.9, 0.9, -1.0).normalize())[0] > 0.9, "top left of the front face");
        assert!(b.colour(Vec3::new(0.9, -0.9, -1.0).normalize())[0] < 0.1, "bottom right");
        // A rotated Background turns its map.
        let turned = Backdrop { rotation: Quat::from_rotation_y(std::f32::consts::PI), ..b };
        let (w, h, texels) = turned.map();
        assert_eq!((w, h), (64, 32));
        assert_eq!(texels.len(), w * h * 3);
    }
}
