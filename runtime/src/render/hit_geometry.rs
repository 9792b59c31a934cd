//! The geometry of hits: where a ray met a triangle of an instance, in world space, with what
//! shading needs of it (normals, surface coordinates and their derivatives along the triangle's
//! edges), and the screen-space derivatives that a ray differential gives at it.

use super::differential::barycentric_change;
use super::shade::Pending;
use super::world::{InstanceShading, World};
use crate::ray::Hit;
use glam::{Affine3A, Vec3A};

/// Surface details of one hit, in world space.
#[derive(Default)]
pub(super) struct HitGeometry {
    pub(super) p: Vec3A,
    pub(super) n: Vec3A,
    pub(super) ng: Vec3A,
    pub(super) uv: [f32; 2],
    pub(super) st: [f32; 2],
    pub(super) dpdu: Vec3A,
    pub(super) dpdv: Vec3A,
    pub(super) cs: Option<Vec3A>,
    pub(super) os: Option<Vec3A>,
    pub(super) attributes: Vec<Vec<f32>>,
    /// The triangle's world-space edges from its first corner, and how (u, v), (s, t) and the
    /// (unnormalised) shading normal change along them: what turns dP/dx into every derivative.
    /// `edges` and `dn` are zero unless the shaders want derivatives (`InstanceGeometry::derivs`).
    pub(super) edges: [Vec3A; 2],
    pub(super) duv: [[f32; 2]; 2],
    pub(super) dst: [[f32; 2]; 2],
    pub(super) dn: [Vec3A; 2],
}

/// The screen-space derivatives of one hit's globals.
pub(super) struct HitDerivs {
    pub(super) dp: [Vec3A; 2],
    pub(super) dn: [Vec3A; 2],
    pub(super) du: [f32; 2],
    pub(super) dv: [f32; 2],
    pub(super) ds: [f32; 2],
    pub(super) dt: [f32; 2],
}

impl HitGeometry {
    pub(super) fn derivs(&self, p: &Pending) -> HitDerivs {
        let (dpx, dpy) = p.diff.at_hit(p.ray.direction, p.hit.t, self.ng);
        let bx = barycentric_change(self.edges[0], self.edges[1], dpx);
        let by = barycentric_change(self.edges[0], self.edges[1], dpy);
        let lin = |d: &[[f32; 2]; 2], k: usize, b: (f32, f32)| d[0][k] * b.0 + d[1][k] * b.1;
        HitDerivs {
            dp: [dpx, dpy],
            dn: [self.dn[0] * bx.0 + self.dn[1] * bx.1, self.dn[0] * by.0 + self.dn[1] * by.1],
            du: [lin(&self.duv, 0, bx), lin(&self.duv, 0, by)],
            dv: [lin(&self.duv, 1, bx), lin(&self.duv, 1, by)],
            ds: [lin(&self.dst, 0, bx), lin(&self.dst, 0, by)],
            dt: [lin(&self.dst, 1, bx), lin(&self.dst, 1, by)],
        }
    }
}

/// What every hit on one instance shares: its mesh and transforms.
pub(super) struct InstanceGeometry<'a> {
    pub(super) mesh: &'a crate::geometry::Mesh,
    pub(super) world_from_object: Affine3A,
    pub(super) normal_xf: glam::Mat3A,
    /// The tracer's instance, when it moves (its transform then depends on the ray's time).
    pub(super) moving: Option<&'a crate::accel::top::InstanceData>,
    /// Whether the shaders want screen-space derivatives (then the triangle's edges and the change
    /// of its normal are kept per hit).
    pub(super) derivs: bool,
    /// Whether they read the surface coordinates (`u v s t dPdu dPdv`, or derivatives): without,
    /// a hit's `uv` and `st` are its barycentrics and `dpdu`, `dpdv` zero.
    pub(super) coords: bool,
    /// The mesh's `st` (two floats), `Cs` and `Os` (three) attributes, found once for all hits.
    pub(super) st: Option<usize>,
    pub(super) cs: Option<usize>,
    pub(super) os: Option<usize>,
}

impl<'a> InstanceGeometry<'a> {
    pub(super) fn new(
        world: &'a World,
        inst: &InstanceShading,
        index: u32,
        (derivs, coords): (bool, bool),
    ) -> Option<InstanceGeometry<'a>> {
        let mesh = world.scene.mesh(crate::scene::ObjectId(inst.object))?;
        let normal_xf = inst.world_from_object.matrix3.inverse().transpose();
        let moving = world.scene.instance_data(index).filter(|d| d.motion.is_some());
        let find = |name: &str, components: usize| {
            mesh.attributes.iter().position(|at| at.name == name && at.components == components)
        };
        Some(InstanceGeometry {
            mesh,
            world_from_object: inst.world_from_object,
            normal_xf,
            moving,
            derivs,
            coords: coords || derivs,
            st: find("st", 2),
            cs: find("Cs", 3),
            os: find("Os", 3),
        })
    }
}

/// Writes the geometry of `hit` (at the ray's `time`) into `slot`, or `None` when its triangle is not
/// in the mesh. In place: a hit's geometry is a few hundred bytes, and built apart and then moved
/// into the batch's buffer it costs a copy of each.
pub(super) fn hit_geometry_into(ig: &InstanceGeometry, hit: &Hit, time: f32, slot: &mut Option<HitGeometry>) {
    let g = slot.get_or_insert_with(HitGeometry::default);
    if hit_geometry(ig, hit, time, g).is_none() {
        *slot = None;
    }
}

/// Writes every field of `g` for `hit`; `None` (and `g` partly written) when its triangle is not in
/// the mesh.
pub(super) fn hit_geometry(ig: &InstanceGeometry, hit: &Hit, time: f32, g: &mut HitGeometry) -> Option<()> {
    let mesh = ig.mesh;
    let [a, b, c] = (*mesh.triangles.get(hit.primitive as usize)?).map(|i| i as usize);
    let (pa, pb, pc) = (*mesh.positions.get(a)?, *mesh.positions.get(b)?, *mesh.positions.get(c)?);
    let (xf, normal_xf) = match ig.moving {
        None => (ig.world_from_object, ig.normal_xf),
        Some(d) => {
            let xf = d.world_from_object_at(time);
            (xf, xf.matrix3.inverse().transpose())
        }
    };
    let (e1, e2) = (Vec3A::from(pb - pa), Vec3A::from(pc - pa));
    let (w0, w1, w2) = (1.0 - hit.u - hit.v, hit.u, hit.v);
    let p_obj = Vec3A::from(pa) * w0 + Vec3A::from(pb) * w1 + Vec3A::from(pc) * w2;
    let ng = (normal_xf * e1.cross(e2)).normalize_or_zero();
    let n = match mesh.interpolate_normal([a, b, c], [w0, w1, w2]) {
        Some(ni) => (normal_xf * Vec3A::from(ni)).normalize_or(ng),
        None => ng,
    };
    let attributes = mesh.interpolate_attributes([a, b, c], [w0, w1, w2]);
    let surf_p = xf.transform_point3a(p_obj);
    let mut duv = [[1.0, 0.0], [0.0, 1.0]];
    let (uv, dpdu, dpdv) = match &mesh.uvs {
        _ if !ig.coords => ([hit.u, hit.v], Vec3A::ZERO, Vec3A::ZERO),
        Some(uvs) => {
            let (ta, tb, tc) = (uvs[a], uvs[b], uvs[c]);
            duv = [(tb - ta).to_array(), (tc - ta).to_array()];
            let (d1, d2) = (tb - ta, tc - ta);
            let det = d1.x * d2.y - d1.y * d2.x;
            let (dpdu, dpdv) = if det.abs() > 1e-12 {
                let inv = 1.0 / det;
                ((e1 * d2.y - e2 * d1.y) * inv, (e2 * d1.x - e1 * d2.x) * inv)
            } else {
                (e1, e2)
            };
            let uv = ta * w0 + tb * w1 + tc * w2;
            ([uv.x, uv.y], dpdu, dpdv)
        }
        None => ([hit.u, hit.v], e1, e2),
    };
    let color_attr = |index: Option<usize>| {
        let v = attributes.get(index?)?;
        (v.len() == 3).then(|| Vec3A::new(v[0], v[1], v[2]))
    };
    let (st, dst) = match ig.st {
        Some(i) if ig.coords && attributes.get(i).is_some_and(|v| v.len() == 2) => {
            let d = &mesh.attributes[i].data;
            let delta = |k: usize, j: usize| d[2 * k + j] - d[2 * a + j];
            ([attributes[i][0], attributes[i][1]], [[delta(b, 0), delta(b, 1)], [delta(c, 0), delta(c, 1)]])
        }
        _ => (uv, duv),
    };
    let dn = match &mesh.normals {
        Some(ns) if ig.derivs => [normal_xf * Vec3A::from(ns[b] - ns[a]), normal_xf * Vec3A::from(ns[c] - ns[a])],
        _ => [Vec3A::ZERO; 2],
    };
    *g = HitGeometry {
        p: surf_p,
        n,
        ng,
        uv,
        st,
        dpdu: if ig.coords { xf.transform_vector3a(dpdu) } else { dpdu },
        dpdv: if ig.coords { xf.transform_vector3a(dpdv) } else { dpdv },
        cs: color_attr(ig.cs),
        os: color_attr(ig.os),
        attributes,
        edges: if ig.derivs { [xf.transform_vector3a(e1), xf.transform_vector3a(e2)] } else { [Vec3A::ZERO; 2] },
        duv,
        dst,
        dn,
    };
    Some(())
}
