//! Lat-long (equirectangular) environment maps: directions to texture coordinates.
//!
//! The mapping, in the space the direction is given in (the shader usually passes world or
//! camera space; RenderMan's camera space is left-handed, +y up, +z forward, +x right):
//!
//! - `t = acos(y) / pi`: the top row (`t = 0`) is straight up (+y), the bottom row straight down;
//! - `s = 0.5 + atan2(x, z) / (2 pi)`: the image centre (`s = 0.5`) looks along +z, `s = 0.75`
//!   along +x, `s = 0.25` along -x, and the left/right edges (`s = 0` and `1`) along -z.
//!
//! Seen from inside the sphere looking along +z with +y up, +x is to the right, as in the image.
//! Lookups wrap periodically in s and clamp in t, whatever the file or lookup says.

use std::f32::consts::PI;

use super::Footprint;

/// The (s, t) of a direction (need not be unit length); `None` for a zero or non-finite one.
pub fn direction_to_latlong(d: [f32; 3]) -> Option<(f32, f32)> {
    let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    if !len.is_finite() || len <= 0.0 {
        return None;
    }
    let t = (d[1] / len).clamp(-1.0, 1.0).acos() / PI;
    let s = 0.5 + d[0].atan2(d[2]) / (2.0 * PI);
    Some((s, t))
}

/// The unit direction at (s, t): the inverse of [`direction_to_latlong`].
pub fn latlong_to_direction(s: f32, t: f32) -> [f32; 3] {
    let (theta, phi) = (t * PI, (s - 0.5) * 2.0 * PI);
    [theta.sin() * phi.sin(), theta.cos(), theta.sin() * phi.cos()]
}

/// The (s, t) of `dir` and the footprint of the directions `dir + ddx` and `dir + ddy` (a
/// pixel step in x and y), measured by finite differences. A difference in s across the seam
/// is taken the short way round.
pub(crate) fn latlong_footprint(dir: [f32; 3], ddx: [f32; 3], ddy: [f32; 3]) -> Option<(f32, f32, Footprint)> {
    let (s, t) = direction_to_latlong(dir)?;
    let delta = |d: [f32; 3]| -> (f32, f32) {
        let moved = [dir[0] + d[0], dir[1] + d[1], dir[2] + d[2]];
        match direction_to_latlong(moved) {
            Some((s2, t2)) => {
                let ds = s2 - s;
                (ds - ds.round(), t2 - t)
            }
            None => (0.0, 0.0),
        }
    };
    let (dsdx, dtdx) = delta(ddx);
    let (dsdy, dtdy) = delta(ddy);
    Some((s, t, Footprint { dsdx, dtdx, dsdy, dtdy }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_axes_land_where_documented() {
        let at = |d| direction_to_latlong(d).unwrap();
        let close = |(s, t): (f32, f32), (ws, wt): (f32, f32)| (s - ws).abs() < 1e-6 && (t - wt).abs() < 1e-6;
        assert!(at([0.0, 1.0, 0.0]).1 < 1e-6, "up is the top row");
        assert!((at([0.0, -2.0, 0.0]).1 - 1.0).abs() < 1e-6, "down is the bottom row");
        assert!(close(at([0.0, 0.0, 1.0]), (0.5, 0.5)));
        assert!(close(at([3.0, 0.0, 0.0]), (0.75, 0.5)));
        assert!(close(at([-1.0, 0.0, 0.0]), (0.25, 0.5)));
        let back = at([0.0, 0.0, -1.0]).0;
        assert!(!(1e-6..=1.0 - 1e-6).contains(&back), "{back}");
        assert_eq!(direction_to_latlong([0.0; 3]), None);
        assert_eq!(direction_to_latlong([f32::NAN, 0.0, 1.0]), None);
    }

    #[test]
    fn directions_round_trip() {
        for &(s, t) in &[(0.1, 0.2), (0.5, 0.5), (0.9, 0.7), (0.3, 0.95)] {
            let (s2, t2) = direction_to_latlong(latlong_to_direction(s, t)).unwrap();
            assert!((s - s2).abs() < 1e-5 && (t - t2).abs() < 1e-5, "({s}, {t}) -> ({s2}, {t2})");
        }
    }

    #[test]
    fn footprints_cross_the_seam_the_short_way() {
        // Looking along -z, a step in +x crosses from s ~ 1 to s ~ 0.
        let (_, _, fp) = latlong_footprint([0.001, 0.0, -1.0], [-0.01, 0.0, 0.0], [0.0, 0.01, 0.0]).unwrap();
        assert!(fp.dsdx.abs() < 0.01, "{fp:?}");
        assert!(fp.dtdy < 0.0 && fp.dtdy > -0.01, "up is smaller t: {fp:?}");
    }
}
