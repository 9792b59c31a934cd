//! Depth shadow maps, RenderMan style, stored as OpenEXR.
//!
//! A shadow map is a float EXR holding, per pixel, the **camera-space z** (depth along the view
//! axis of the light's camera) of the nearest surface, in channel `Z` (or, when there is none, the
//! file's first channel), plus two standard OpenEXR header attributes describing the projection:
//!
//! - `worldToCamera`: world to the light's camera space (z > 0 in front of the camera);
//! - `worldToNDC`: world to RenderMan's NDC space, after the homogeneous divide: `x` and `y` in
//!   `[0, 1]` with `(0, 0)` the **top-left** pixel of the map, so that `(x, y)` are directly the
//!   map's `(s, t)`.
//!
//! Both use OpenEXR's (Imath's) row-vector convention: `p' = [x y z 1] M`, so `M[12..15]` hold
//! the translation; a point's result is divided by its `w`.
//!
//! A lookup ([`ShadowMap::shadow`]) answers the fraction of the filter kernel in shadow (0 lit, 1
//! shadowed) by percentage-closer filtering: `samples` points on a square grid over the kernel
//! (at least 2 texels wide, widened by `sblur`/`tblur` in map coordinates), each comparing the
//! four nearest depths with the point's depth less `bias` and blending those four verdicts
//! bilinearly, so the answer varies smoothly across a shadow's edge. A point behind the light's
//! camera or outside the map is lit.

use std::path::Path;

use super::image::TexImage;
use super::LookupOptions;
use crate::image_io::{self, ExrLayer, ImageError};

/// The most percentage-closer samples one lookup takes, whatever a shader asks for.
pub const MAX_SAMPLES: u32 = 1024;

/// A loaded depth map with its projection.
#[derive(Clone, Debug, PartialEq)]
pub struct ShadowMap {
    depth: TexImage,
    world_to_camera: [f32; 16],
    world_to_ndc: [f32; 16],
}

impl ShadowMap {
    /// A shadow map from depths (`width * height`, top row first) and its matrices (see the
    /// module doc for their convention). `None` when the size does not match.
    pub fn new(
        depth: Vec<f32>,
        width: usize,
        height: usize,
        world_to_camera: [f32; 16],
        world_to_ndc: [f32; 16],
    ) -> Option<ShadowMap> {
        let depth = TexImage::new(width, height, 1, depth)?;
        Some(ShadowMap { depth, world_to_camera, world_to_ndc })
    }

    /// Reads a shadow map written by [`write_shadow_map`] (or any EXR with the two attributes).
    pub fn load(path: &Path) -> Result<ShadowMap, ImageError> {
        ShadowMap::from_layer(path, image_io::read_exr(path)?)
    }

    /// Reads a shadow map file's bytes held in memory; `name` is what errors call it.
    pub fn decode(name: &Path, bytes: &[u8]) -> Result<ShadowMap, ImageError> {
        ShadowMap::from_layer(name, image_io::read_exr_bytes(name, bytes)?)
    }

    fn from_layer(path: &Path, layer: image_io::ExrLayer) -> Result<ShadowMap, ImageError> {
        let missing =
            |what: &str| ImageError::Decode { path: path.into(), message: format!("not a shadow map: no {what}") };
        let world_to_camera = layer.world_to_camera.ok_or_else(|| missing("worldToCamera attribute"))?;
        let world_to_ndc = layer.world_to_ndc.ok_or_else(|| missing("worldToNDC attribute"))?;
        let depth = layer.channel("Z").or_else(|| layer.channels.first().map(|(_, v)| v.as_slice()));
        let depth = depth.ok_or_else(|| missing("channel"))?.to_vec();
        ShadowMap::new(depth, layer.width, layer.height, world_to_camera, world_to_ndc).ok_or_else(|| missing("pixels"))
    }

    pub fn width(&self) -> usize {
        self.depth.width()
    }

    pub fn height(&self) -> usize {
        self.depth.height()
    }

    /// The fraction of the kernel around world-space point `p` that is in shadow: 0 lit, 1
    /// shadowed (see the module doc).
    pub fn shadow(&self, p: [f32; 3], opts: &LookupOptions) -> f32 {
        self.shadow_over(p, &[], opts)
    }

    /// [`ShadowMap::shadow`] over a region: the kernel, centred on `p`'s place in the map, also
    /// covers the world-space `corners` (RSL's four-point `shadow()`, or a shading point's pixel
    /// footprint), its extent scaled by `swidth`/`twidth` before the blur is added. Corners behind
    /// the light's camera are left out.
    pub fn shadow_over(&self, p: [f32; 3], corners: &[[f32; 3]], opts: &LookupOptions) -> f32 {
        let Some(camera) = transform_point(&self.world_to_camera, p) else { return 0.0 };
        let Some(ndc) = transform_point(&self.world_to_ndc, p) else { return 0.0 };
        let depth = camera[2];
        let (x, y) = (ndc[0], ndc[1]);
        if depth.is_nan() || depth <= 0.0 || !(0.0..=1.0).contains(&x) || !(0.0..=1.0).contains(&y) {
            return 0.0;
        }
        let (w, h) = (self.width() as f32, self.height() as f32);
        // Half the corners' extent around the centre, in map coordinates.
        let (mut reach_s, mut reach_t) = (0.0f32, 0.0f32);
        for c in corners.iter().filter_map(|c| transform_point(&self.world_to_ndc, *c)) {
            reach_s = reach_s.max((c[0] - x).abs());
            reach_t = reach_t.max((c[1] - y).abs());
        }
        // At least 2 texels, so the answer varies smoothly across an edge; at most twice the map,
        // so that absurd options (infinite, NaN) still give a finite answer.
        let extent = |reach: f32, scale: f32, blur: f32, texels: f32| {
            let spread = (2.0 * reach * scale).max(0.0) + blur;
            (spread * texels).max(2.0).min(2.0 * texels.max(1.0))
        };
        let kernel = [extent(reach_s, opts.swidth, opts.sblur, w), extent(reach_t, opts.twidth, opts.tblur, h)];
        let n = (opts.samples.clamp(1, MAX_SAMPLES) as f32).sqrt().ceil() as usize;
        let compare = DepthCompare::new(depth, opts.bias, opts.bias_ramp);
        let mut shadowed = 0.0;
        for j in 0..n {
            for i in 0..n {
                let offset = |k: usize, width: f32| ((k as f32 + 0.5) / n as f32 - 0.5) * width;
                let tx = x * w + offset(i, kernel[0]) - 0.5;
                let ty = y * h + offset(j, kernel[1]) - 0.5;
                shadowed += self.compare_bilinear(tx, ty, &compare);
            }
        }
        shadowed / (n * n) as f32
    }

    /// The bilinear blend of the four depth comparisons around continuous texel position
    /// (x, y) (texel centres at integers); edges clamp.
    fn compare_bilinear(&self, x: f32, y: f32, compare: &DepthCompare) -> f32 {
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let clamp = |i: f32, n: usize| (i.max(0.0) as usize).min(n - 1);
        let mut sum = 0.0;
        for (dy, wy) in [(0.0, 1.0 - fy), (1.0, fy)] {
            for (dx, wx) in [(0.0, 1.0 - fx), (1.0, fx)] {
                let stored = self.depth.texel(clamp(x0 + dx, self.width()), clamp(y0 + dy, self.height()))[0];
                sum += wx * wy * compare.shadowed(stored);
            }
        }
        sum
    }
}

/// How much a point at camera depth `depth` is in shadow of a stored depth: a step where there is
/// no ramp (behind it by more than the bias), else the fraction of the ramp it is behind it by
/// (Aqsis's `bias0` and `bias1`).
struct DepthCompare {
    /// The depth a stored depth must be under for any shadow: `depth - bias`.
    reference: f32,
    /// One over the ramp's width; `None` for a step.
    inverse_ramp: Option<f32>,
}

impl DepthCompare {
    fn new(depth: f32, bias: f32, ramp: f32) -> DepthCompare {
        let inverse_ramp = (ramp > 0.0 && ramp.is_finite()).then(|| 1.0 / ramp);
        DepthCompare { reference: depth - bias, inverse_ramp }
    }

    #[inline]
    fn shadowed(&self, stored: f32) -> f32 {
        match self.inverse_ramp {
            // Past the ramp's top the ratio is above 1; a NaN stored depth stays lit.
            Some(inverse) if stored < self.reference => ((self.reference - stored) * inverse).min(1.0),
            None if stored < self.reference => 1.0,
            _ => 0.0,
        }
    }
}

/// `p` (a point, w = 1) through a row-vector matrix, divided by the resulting w; `None` when w
/// is not positive (behind a projection) or the result is not finite.
fn transform_point(m: &[f32; 16], p: [f32; 3]) -> Option<[f32; 3]> {
    let column = |c: usize| p[0] * m[c] + p[1] * m[4 + c] + p[2] * m[8 + c] + m[12 + c];
    let w = column(3);
    if w.is_nan() || w <= 0.0 {
        return None;
    }
    let out = [column(0) / w, column(1) / w, column(2) / w];
    out.iter().all(|v| v.is_finite()).then_some(out)
}

/// Writes a shadow map: `depth` (camera-space z, `width * height`, top row first) as a 32-bit
/// float channel `Z`, with the `worldToCamera` and `worldToNDC` attributes (row-vector
/// convention, NDC as in the module doc).
pub fn write_shadow_map(
    path: impl AsRef<Path>,
    depth: &[f32],
    width: usize,
    height: usize,
    world_to_camera: [f32; 16],
    world_to_ndc: [f32; 16],
) -> Result<(), ImageError> {
    let layer = ExrLayer {
        width,
        height,
        channels: vec![("Z".into(), depth.to_vec())],
        world_to_camera: Some(world_to_camera),
        world_to_ndc: Some(world_to_ndc),
        wrap_modes: None,
    };
    image_io::write_exr(path.as_ref(), &layer, false)
}

/// RIB `MakeShadow`: the depth map at `from` (a `zfile` or `shadow` display, or any EXR with the
/// two projection attributes) made into the shadow map at `to`, which is the same map: rtsl's
/// shadow maps are depth maps. Its depths and matrices are checked by loading it first.
pub fn make_shadow(from: &Path, to: &Path) -> Result<(), ImageError> {
    let layer = image_io::read_exr(from)?;
    ShadowMap::from_layer(from, layer.clone())?;
    image_io::write_exr(to, &layer, false)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A light at the origin looking down +z with an orthographic view of x, y in [-1, 1]:
    /// camera space is world space; NDC maps x -1..1 to 0..1 and y 1..-1 to 0..1 (top row up).
    pub(crate) fn ortho_light() -> ([f32; 16], [f32; 16]) {
        let identity = [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0];
        let to_ndc = [0.5, 0.0, 0.0, 0.0, 0.0, -0.5, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.5, 0.5, 0.0, 1.0];
        (identity, to_ndc)
    }

    /// 8x8 map: an occluder at depth 1 over the left half (x < 0), nothing (depth 1e30) on the right.
    pub(crate) fn half_occluded_map() -> (Vec<f32>, usize, usize) {
        let depth = (0..64).map(|i| if i % 8 < 4 { 1.0 } else { 1e30 }).collect();
        (depth, 8, 8)
    }

    fn map() -> ShadowMap {
        let (depth, w, h) = half_occluded_map();
        let (cam, ndc) = ortho_light();
        ShadowMap::new(depth, w, h, cam, ndc).unwrap()
    }

    #[test]
    fn lit_shadowed_and_half_way() {
        let m = map();
        let opts = LookupOptions { bias: 0.01, ..LookupOptions::default() };
        assert_eq!(m.shadow([-0.5, 0.2, 5.0], &opts), 1.0, "behind the occluder");
        assert_eq!(m.shadow([-0.5, 0.2, 0.5], &opts), 0.0, "in front of the occluder");
        assert_eq!(m.shadow([0.5, -0.2, 5.0], &opts), 0.0, "beside it");
        let edge = m.shadow([0.0, 0.3, 5.0], &opts);
        assert!((edge - 0.5).abs() < 1e-5, "on the edge: {edge}");
        // Across the edge the answer falls off smoothly and monotonically.
        let xs: Vec<f32> = (0..9).map(|i| m.shadow([-0.4 + 0.1 * i as f32, 0.0, 5.0], &opts)).collect();
        assert!(xs.windows(2).all(|p| p[0] >= p[1]), "{xs:?}");
    }

    #[test]
    fn bias_lifts_self_shadowing_and_outside_is_lit() {
        let m = map();
        // A point on the occluder's own surface.
        let on_surface = [-0.5, 0.0, 1.0001];
        assert_eq!(m.shadow(on_surface, &LookupOptions::default()), 1.0);
        assert_eq!(m.shadow(on_surface, &LookupOptions { bias: 0.01, ..LookupOptions::default() }), 0.0);
        assert_eq!(m.shadow([-5.0, 0.0, 5.0], &LookupOptions::default()), 0.0, "outside the map");
        assert_eq!(m.shadow([-0.5, 0.0, -5.0], &LookupOptions::default()), 0.0, "behind the light");
        assert_eq!(m.shadow([f32::NAN, 0.0, 5.0], &LookupOptions::default()), 0.0);
    }

    #[test]
    fn a_bias_ramp_shadows_by_how_far_past_its_start_a_point_is() {
        let m = map();
        // 4 behind the occluder (depth 1).
        let p = [-0.5, 0.2, 5.0];
        let with =
            |bias: f32, bias_ramp: f32| m.shadow(p, &LookupOptions { bias, bias_ramp, ..LookupOptions::default() });
        assert_eq!(with(3.0, 2.0), 0.5, "half-way up the ramp");
        assert_eq!(with(1.0, 2.0), 1.0, "past its top");
        assert_eq!(with(5.0, 2.0), 0.0, "short of its start");
        assert_eq!(with(3.0, 0.0), 1.0, "no ramp: a step");
        assert_eq!(with(3.0, f32::NAN), 1.0, "no ramp: a step");
    }

    #[test]
    fn a_region_widens_the_kernel_and_its_widths_scale_it() {
        let m = map();
        let opts = LookupOptions { bias: 0.01, ..LookupOptions::default() };
        // Two texels inside the shadow: the default kernel sees only the occluder...
        let p = [-0.5, 0.0, 5.0];
        assert_eq!(m.shadow_over(p, &[], &opts), 1.0);
        // ...a region reaching across the edge sees the lit half too...
        let region = [[-1.1, 0.0, 5.0], [0.1, 0.0, 5.0], [-1.1, 0.1, 5.0], [0.1, 0.1, 5.0]];
        let wide = m.shadow_over(p, &region, &opts);
        assert!(wide > 0.5 && wide < 1.0, "{wide}");
        // ...and a zero width shrinks it back to the default kernel.
        let narrow = LookupOptions { swidth: 0.0, ..opts };
        assert_eq!(m.shadow_over(p, &region, &narrow), 1.0);
        // Absurd options still answer a fraction, at a bounded cost.
        for absurd in [
            LookupOptions { swidth: f32::NAN, twidth: f32::INFINITY, ..opts },
            LookupOptions { sblur: f32::INFINITY, samples: u32::MAX, ..opts },
            LookupOptions { sblur: f32::NAN, tblur: -3.0, ..opts },
        ] {
            let v = m.shadow_over(p, &region, &absurd);
            assert!((0.0..=1.0).contains(&v), "{absurd:?}: {v}");
        }
    }

    #[test]
    fn written_maps_read_back() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("shadow.exr");
        let (depth, w, h) = half_occluded_map();
        let (cam, ndc) = ortho_light();
        write_shadow_map(&path, &depth, w, h, cam, ndc).unwrap();
        assert_eq!(ShadowMap::load(&path).unwrap(), map());

        // A plain image is not a shadow map.
        let plain = dir.path().join("plain.exr");
        image_io::write_image(&plain, 1, 1, &[0.0; 4], &image_io::WriteOptions::default()).unwrap();
        let err = ShadowMap::load(&plain).unwrap_err();
        assert!(err.to_string().contains("worldToCamera"), "{err}");
    }
}
