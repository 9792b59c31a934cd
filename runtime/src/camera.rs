//! A pinhole camera that generates primary rays, one at a time or as 8x8 packets.
//!
//! Invariants: the ray of pixel `(x, y)` passes through the pixel's centre, with `y` growing
//! downwards; directions are unit length, so hit distances are in world units. In a packet, lane
//! `i` covers pixel [`packet_lane_offset`]`(i)` from the packet's corner: lanes come in 2x2 quads
//! (one SIMD chunk each) laid out in Morton order, which keeps the active chunk ranges of packet
//! traversal compact.

use crate::ray::{Ray, RayPacket, PACKET_SIZE};
use glam::{Vec3A, Vec4};

/// Packet side in pixels.
pub const PACKET_SIDE: u32 = 8;

/// The pixel offset `(dx, dy)` within its 8x8 packet of lane `i`.
pub const fn packet_lane_offset(i: usize) -> (u32, u32) {
    let chunk = (i / 4) as u32;
    let j = (i % 4) as u32;
    // Morton decode of the chunk index on a 4x4 grid of 2x2 quads.
    let qx = (chunk & 1) | ((chunk >> 1) & 2);
    let qy = ((chunk >> 1) & 1) | ((chunk >> 2) & 2);
    (qx * 2 + (j & 1), qy * 2 + (j >> 1))
}

/// [`packet_lane_offset`] of every lane, for loops over a packet's lanes.
pub const PACKET_LANE_OFFSETS: [(u32, u32); PACKET_SIZE] = {
    let mut t = [(0, 0); PACKET_SIZE];
    let mut i = 0;
    while i < PACKET_SIZE {
        t[i] = packet_lane_offset(i);
        i += 1;
    }
    t
};

/// A pinhole camera.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    eye: Vec3A,
    forward: Vec3A,
    right: Vec3A,
    up: Vec3A,
    width: u32,
    height: u32,
}

impl Camera {
    /// A camera at `eye` looking at `look` with `up`, vertical field of view `fov_deg` degrees, for
    /// an image of `width` x `height` pixels.
    pub fn look_at(eye: Vec3A, look: Vec3A, up: Vec3A, fov_deg: f32, width: u32, height: u32) -> Self {
        let forward = (look - eye).normalize_or(Vec3A::NEG_Z);
        let right = forward.cross(up).normalize_or(Vec3A::X);
        let true_up = right.cross(forward);
        let tan = (fov_deg.to_radians() * 0.5).tan();
        let aspect = width.max(1) as f32 / height.max(1) as f32;
        Camera { eye, forward, right: right * (tan * aspect), up: true_up * tan, width, height }
    }

    /// Image width in pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Image height in pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The eye point.
    pub fn eye(&self) -> Vec3A {
        self.eye
    }

    /// The primary ray through the centre of pixel `(x, y)`.
    pub fn ray(&self, x: u32, y: u32) -> Ray {
        let sx = 2.0 * (x as f32 + 0.5) / self.width as f32 - 1.0;
        let sy = 1.0 - 2.0 * (y as f32 + 0.5) / self.height as f32;
        let (f, r, u) = (self.forward, self.right, self.up);
        let dx = (f.x + r.x * sx) + u.x * sy;
        let dy = (f.y + r.y * sx) + u.y * sy;
        let dz = (f.z + r.z * sx) + u.z * sy;
        let inv = 1.0 / ((dx * dx + dy * dy) + dz * dz).sqrt();
        Ray::new(self.eye, Vec3A::new(dx * inv, dy * inv, dz * inv))
    }

    /// The packet of the 8x8 pixels with top-left corner `(x0, y0)`; lanes outside the image are
    /// inactive. Lane `i` holds exactly [`Camera::ray`] of its pixel (the same operations, four
    /// lanes at a time).
    pub fn packet(&self, x0: u32, y0: u32) -> RayPacket {
        let mut p = RayPacket::new();
        let (f, r, u) = (self.forward, self.right, self.up);
        let (w, h) = (self.width as f32, self.height as f32);
        for c in 0..PACKET_SIZE / 4 {
            let mut px = [0.0f32; 4];
            let mut py = [0.0f32; 4];
            for j in 0..4 {
                let i = 4 * c + j;
                let (dx, dy) = packet_lane_offset(i);
                let (x, y) = (x0 + dx, y0 + dy);
                if x < self.width && y < self.height {
                    p.active |= 1 << i;
                }
                px[j] = x as f32;
                py[j] = y as f32;
            }
            let sx = Vec4::splat(2.0) * (Vec4::from_array(px) + Vec4::splat(0.5)) / Vec4::splat(w) - Vec4::ONE;
            let sy = Vec4::ONE - Vec4::splat(2.0) * (Vec4::from_array(py) + Vec4::splat(0.5)) / Vec4::splat(h);
            let dx = (Vec4::splat(f.x) + Vec4::splat(r.x) * sx) + Vec4::splat(u.x) * sy;
            let dy = (Vec4::splat(f.y) + Vec4::splat(r.y) * sx) + Vec4::splat(u.y) * sy;
            let dz = (Vec4::splat(f.z) + Vec4::splat(r.z) * sx) + Vec4::splat(u.z) * sy;
            let inv = Vec4::ONE / ((dx * dx + dy * dy) + dz * dz).sqrt();
            let lanes = 4 * c..4 * c + 4;
            (dx * inv).write_to_slice(&mut p.dx.0[lanes.clone()]);
            (dy * inv).write_to_slice(&mut p.dy.0[lanes.clone()]);
            (dz * inv).write_to_slice(&mut p.dz.0[lanes.clone()]);
            p.ox.0[lanes.clone()].fill(self.eye.x);
            p.oy.0[lanes.clone()].fill(self.eye.y);
            p.oz.0[lanes.clone()].fill(self.eye.z);
            p.tmax.0[lanes].fill(f32::INFINITY);
        }
        p
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lanes_cover_the_block_once() {
        let mut seen = [[false; 8]; 8];
        for i in 0..PACKET_SIZE {
            let (x, y) = packet_lane_offset(i);
            assert!(!seen[y as usize][x as usize]);
            seen[y as usize][x as usize] = true;
        }
    }

    #[test]
    fn packet_lanes_are_the_single_rays() {
        let cam = Camera::look_at(Vec3A::new(1.0, 2.0, 3.0), Vec3A::ZERO, Vec3A::Y, 50.0, 20, 13);
        let p = cam.packet(16, 8);
        for i in 0..PACKET_SIZE {
            let (dx, dy) = packet_lane_offset(i);
            let (x, y) = (16 + dx, 8 + dy);
            assert_eq!(p.active >> i & 1 != 0, x < 20 && y < 13);
            if x < 20 && y < 13 {
                assert_eq!(p.get(i), cam.ray(x, y));
            }
        }
    }
}
