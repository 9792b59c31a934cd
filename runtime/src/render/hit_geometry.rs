//! The geometry of hits: where a ray met a triangle of an instance, in world space, with what
//! shading needs of it (normals, surface coordinates and their derivatives along the triangle's
//! edges), and the screen-space derivatives that a ray differential gives at it.

use super::jobs::GroupRows;
use super::lanes::{Lanes, Lanes3};
use super::world::{InstanceShading, World};
use crate::ray::{Hit, PACKET_SIZE};
use glam::{Affine3A, BVec4A, Vec3, Vec3A, Vec4};
use wide::f32x8;

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
    /// Where the ray met the traced surface and that triangle's normal, when shading sees the
    /// surface as it was before a surface shader displaced it (`p` and `ng` are then the
    /// undisplaced ones; see [`UNDISPLACED_POSITIONS`]): what rays going on start from.
    pub(super) traced: Option<(Vec3A, Vec3A)>,
}

/// The vertex attribute of a mesh a surface shader displaced (`true_displacement.rs`): where
/// each point was before (object space, three floats), which its hits are shaded at. The surface
/// shader then moves them once, as the points of a REYES grid are, rather than a second time
/// from where it moved them already (a shader that bumps what it displaced would double the
/// bump).
pub const UNDISPLACED_POSITIONS: &str = "__undisplaced_P";

/// The screen-space derivatives of one hit's globals.
#[cfg(test)]
pub(super) struct HitDerivs {
    pub(super) dp: [Vec3A; 2],
    pub(super) dn: [Vec3A; 2],
    pub(super) du: [f32; 2],
    pub(super) dv: [f32; 2],
    pub(super) ds: [f32; 2],
    pub(super) dt: [f32; 2],
}

#[cfg(test)]
impl HitGeometry {
    /// The derivatives of the hit of lane `l` of `jobs`: the arithmetic [`derivs_four`] does
    /// four hits at a time.
    pub(super) fn derivs(&self, jobs: &GroupRows, l: usize) -> HitDerivs {
        use super::differential::barycentric_change;
        let (dpx, dpy) = jobs.diff(l).at_hit(jobs.direction(l), jobs.hit(l).t, self.ng);
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

/// What of a hit's geometry the shaders of its material read (see [`InstanceGeometry`]'s fields of
/// the same names). A BART material reads neither `dPdu`/`dPdv` nor the derivatives of `N`:
/// working them out for every hit was a tenth of the hit geometry's instructions.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct GeometryNeeds {
    pub(super) derivs: bool,
    pub(super) coords: bool,
    pub(super) dpduv: bool,
    pub(super) normal_derivs: bool,
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
    /// Whether they read `dPdu` or `dPdv`: without, a hit's `dpdu` and `dpdv` are zero.
    pub(super) dpduv: bool,
    /// Whether they read the derivatives of `N`: without, a hit's `dn` is zero.
    pub(super) normal_derivs: bool,
    /// The mesh's `st` (two floats), `Cs` and `Os` (three) attributes, found once for all hits.
    pub(super) st: Option<usize>,
    pub(super) cs: Option<usize>,
    pub(super) os: Option<usize>,
    /// The mesh's [`UNDISPLACED_POSITIONS`], where it has them for every point and stands still.
    pub(super) undisplaced: Option<&'a [f32]>,
}

impl<'a> InstanceGeometry<'a> {
    pub(super) fn new(
        world: &'a World,
        inst: &InstanceShading,
        index: u32,
        needs: GeometryNeeds,
    ) -> Option<InstanceGeometry<'a>> {
        let GeometryNeeds { derivs, coords, dpduv, normal_derivs } = needs;
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
            dpduv: dpduv && (coords || derivs),
            normal_derivs: normal_derivs && derivs,
            st: find("st", 2),
            cs: find("Cs", 3),
            os: find("Os", 3),
            undisplaced: find(UNDISPLACED_POSITIONS, 3)
                .map(|k| &mesh.attributes[k].data[..])
                .filter(|d| d.len() == 3 * mesh.positions.len() && mesh.deformation.is_none()),
        })
    }
}

/// The geometry of a group's hits by rows, a row per component and a lane per hit (zeros where a
/// hit has no geometry), as [`hit_geometries`] writes it four hits at a time: what a batch's
/// globals copy row by row instead of gathering them from each hit's [`HitGeometry`].
pub(super) struct HitRows {
    /// The lanes whose hit has geometry (its triangle is in the mesh).
    pub(super) valid: u64,
    pub(super) p: [[f32; PACKET_SIZE]; 3],
    pub(super) n: [[f32; PACKET_SIZE]; 3],
    pub(super) ng: [[f32; PACKET_SIZE]; 3],
    /// `uv`, which is also `st` (meshes with an `st` of their own go one hit at a time).
    pub(super) uv: [[f32; PACKET_SIZE]; 2],
    pub(super) dpdu: [[f32; PACKET_SIZE]; 3],
    pub(super) dpdv: [[f32; PACKET_SIZE]; 3],
    /// The screen-space derivatives, when the shaders want them (`InstanceGeometry::derivs`):
    /// dP/dx, dP/dy, dN/dx, dN/dy a row per component, d(u, v)/dx and /dy (also (s, t)'s). The
    /// normal's hold whatever an earlier group left unless `InstanceGeometry::normal_derivs`.
    pub(super) dp: [[[f32; PACKET_SIZE]; 3]; 2],
    pub(super) dn: [[[f32; PACKET_SIZE]; 3]; 2],
    pub(super) du: [[f32; PACKET_SIZE]; 2],
    pub(super) dv: [[f32; PACKET_SIZE]; 2],
}

impl Default for HitRows {
    fn default() -> Self {
        let rows = [[0.0; PACKET_SIZE]; 3];
        let pair = [[0.0; PACKET_SIZE]; 2];
        HitRows {
            valid: 0,
            p: rows,
            n: rows,
            ng: rows,
            uv: pair,
            dpdu: rows,
            dpdv: rows,
            dp: [rows; 2],
            dn: [rows; 2],
            du: pair,
            dv: pair,
        }
    }
}

impl HitRows {
    /// The derivatives of chunk `k` (lanes `4k..4k + 4`), as [`derivs_four`] gives them.
    #[inline(always)]
    pub(super) fn derivs(&self, k: usize) -> DerivsFour {
        // Written out: through `array::map` each row went through the stack several times.
        let at = |row: &[f32; PACKET_SIZE]| row.get(4 * k..4 * k + 4).map_or(Vec4::ZERO, Vec4::from_slice);
        let lanes = |rows: &[[f32; PACKET_SIZE]; 3]| Lanes3 { x: at(&rows[0]), y: at(&rows[1]), z: at(&rows[2]) };
        let (du, dv) = ([at(&self.du[0]), at(&self.du[1])], [at(&self.dv[0]), at(&self.dv[1])]);
        let (dp, dn) = ([lanes(&self.dp[0]), lanes(&self.dp[1])], [lanes(&self.dn[0]), lanes(&self.dn[1])]);
        DerivsFour { dp, dn, du, dv, ds: du, dt: dv }
    }
}

/// Writes the geometry of each of a group's hits into its slot of `geoms` (`None` where its
/// triangle is not in the mesh), the same as [`hit_geometry_into`] would, bit for bit. Instances
/// that stand still, with meshes without further attributes (all of a BART scene), are done four
/// hits at a time in vector arithmetic ([`hit_geometry_four`]): one hit at a time, each hit's
/// square roots and divisions would stand in a chain of their own. Those groups are also written
/// into `rows`, and then it returns `true`.
///
/// With `each` false the caller reads only the rows where there are rows ([`GroupHits::Rows`]),
/// and then the slots of `geoms` are left as they were: writing every hit's fields a lane at a
/// time, and holding all of them until then, would cost more than the rows. The rows alone are
/// worked out eight hits at a time ([`hit_rows_eight`]; the loads of corners stay a lane at a
/// time).
pub(super) fn hit_geometries(
    ig: &InstanceGeometry,
    group: &GroupRows,
    geoms: &mut [Option<HitGeometry>],
    rows: &mut HitRows,
    each: bool,
) -> bool {
    let len = group.len().min(geoms.len());
    let geoms = &mut geoms[..len];
    if ig.moving.is_some() || ig.mesh.deformation.is_some() || !ig.mesh.attributes.is_empty() {
        for (l, slot) in geoms.iter_mut().enumerate() {
            hit_geometry_into(ig, &group.hit(l), group.time(l), slot);
        }
        return false;
    }
    rows.valid = 0;
    if !each {
        for k in 0..len.div_ceil(8) {
            hit_rows_eight(ig, group, rows, k);
        }
        return true;
    }
    for (chunk, slots) in geoms.chunks_mut(4).enumerate() {
        hit_geometry_four(ig, group, (slots, each), (&mut *rows, chunk));
    }
    true
}

/// A group's hits as the batch around a surface shader reads them: each hit's [`HitGeometry`]
/// (with the rows [`hit_geometries`] wrote, where it wrote them), or the rows alone.
#[derive(Clone, Copy)]
pub(super) enum GroupHits<'a> {
    Each(&'a [Option<HitGeometry>], Option<&'a HitRows>),
    /// The rows of the group's first `usize` hits.
    Rows(&'a HitRows, usize),
}

/// What the batch around a surface shader reads of one hit (its globals, its lights, its
/// result): the fields of its [`HitGeometry`] of those names.
#[derive(Clone, Copy)]
pub(super) struct HitSurface {
    pub(super) p: Vec3A,
    pub(super) n: Vec3A,
    pub(super) ng: Vec3A,
    pub(super) uv: [f32; 2],
    pub(super) st: [f32; 2],
    pub(super) dpdu: Vec3A,
    pub(super) dpdv: Vec3A,
    pub(super) cs: Option<Vec3A>,
    pub(super) os: Option<Vec3A>,
}

impl<'a> GroupHits<'a> {
    pub(super) fn len(&self) -> usize {
        match self {
            GroupHits::Each(geoms, _) => geoms.len(),
            GroupHits::Rows(_, len) => *len,
        }
    }

    pub(super) fn rows(&self) -> Option<&'a HitRows> {
        match *self {
            GroupHits::Each(_, rows) => rows,
            GroupHits::Rows(rows, _) => Some(rows),
        }
    }

    /// The hit of `lane`, `None` where it has no geometry (or the group no such lane).
    #[inline(always)]
    pub(super) fn get(&self, lane: usize) -> Option<HitSurface> {
        match *self {
            GroupHits::Each(geoms, _) => geoms.get(lane)?.as_ref().map(|g| HitSurface {
                p: g.p,
                n: g.n,
                ng: g.ng,
                uv: g.uv,
                st: g.st,
                dpdu: g.dpdu,
                dpdv: g.dpdv,
                cs: g.cs,
                os: g.os,
            }),
            GroupHits::Rows(rows, len) => {
                if lane >= len.min(PACKET_SIZE) || rows.valid >> lane & 1 == 0 {
                    return None;
                }
                let v3 = |r: &[[f32; PACKET_SIZE]; 3]| Vec3A::new(r[0][lane], r[1][lane], r[2][lane]);
                let uv = [rows.uv[0][lane], rows.uv[1][lane]];
                Some(HitSurface {
                    p: v3(&rows.p),
                    n: v3(&rows.n),
                    ng: v3(&rows.ng),
                    uv,
                    st: uv,
                    dpdu: v3(&rows.dpdu),
                    dpdv: v3(&rows.dpdv),
                    cs: None,
                    os: None,
                })
            }
        }
    }

    /// Each lane's hit, as [`GroupHits::get`] gives it.
    pub(super) fn iter(&self) -> impl Iterator<Item = Option<HitSurface>> + '_ {
        (0..self.len()).map(|lane| self.get(lane))
    }
}

/// The screen-space derivatives of several hits' globals, a lane each.
pub(super) struct Derivs<V = Vec4> {
    pub(super) dp: [Lanes3<V>; 2],
    pub(super) dn: [Lanes3<V>; 2],
    pub(super) du: [V; 2],
    pub(super) dv: [V; 2],
    pub(super) ds: [V; 2],
    pub(super) dt: [V; 2],
}

/// The derivatives of four hits.
pub(super) type DerivsFour = Derivs<Vec4>;

/// The derivatives along x and y of four hits (`geoms`, of the rays of lanes `first..first + 4` of
/// `jobs`; where a lane has no geometry its values are not to be used), lane by lane the
/// arithmetic of one hit at a time (`RayDifferential::at_hit`, `barycentric_change`), so each
/// lane's bits are the same. One hit at a time, the six divisions of each would stand in a chain,
/// and writing the results a lane at a time would look up their rows again.
pub(super) fn derivs_four(jobs: &GroupRows, first: usize, geoms: [Option<&HitGeometry>; 4]) -> DerivsFour {
    let zero = HitGeometry::default();
    let geoms = geoms.map(|g| g.unwrap_or(&zero));
    let from_geometry = |f: fn(&HitGeometry) -> Vec3A| Lanes3::of(geoms, f);
    // `[d1.x, d1.y, d2.x, d2.y]` of a change `d` along the edges (`duv`, `dst`).
    let changes = |f: fn(&HitGeometry) -> [[f32; 2]; 2]| {
        let d = geoms.map(f);
        [(0, 0), (0, 1), (1, 0), (1, 1)].map(|(e, k)| Vec4::new(d[0][e][k], d[1][e][k], d[2][e][k], d[3][e][k]))
    };
    let surface = SurfaceChange {
        ng: from_geometry(|g| g.ng),
        edges: [from_geometry(|g| g.edges[0]), from_geometry(|g| g.edges[1])],
        dn: [from_geometry(|g| g.dn[0]), from_geometry(|g| g.dn[1])],
        duv: changes(|g| g.duv),
        dst: changes(|g| g.dst),
    };
    surface.derivs(jobs, first)
}

/// What the derivatives of four hits need of their surfaces, a lane each: world-space geometric
/// normals and edges, and the change of the normal, (u, v) and (s, t) along the edges (the
/// latter as `[d1.x, d1.y, d2.x, d2.y]`).
struct SurfaceChange<V: Lanes = Vec4> {
    ng: Lanes3<V>,
    edges: [Lanes3<V>; 2],
    dn: [Lanes3<V>; 2],
    duv: [V; 4],
    dst: [V; 4],
}

impl<V: Lanes> SurfaceChange<V> {
    /// The derivatives of the hits of the rays of lanes `first..first + V::LANES` of `jobs` on
    /// these surfaces.
    #[inline(always)]
    fn derivs(&self, jobs: &GroupRows, first: usize) -> Derivs<V> {
        let rows3 = |r: &[[f32; PACKET_SIZE]; 3]| Lanes3::<V>::load([&r[0], &r[1], &r[2]], first);
        let SurfaceChange { ng, edges: [e1, e2], dn: [dn1, dn2], duv, dst } = *self;
        let rays = &jobs.rays;
        let dir = Lanes3::<V>::load([&rays.dx.0, &rays.dy.0, &rays.dz.0], first);
        let t = V::load(&jobs.hits.t.0, first);
        // `at_hit`: the offsets at the hit, moved along the ray onto the tangent plane.
        let facing = dir.dot(ng);
        let along_plane = facing.abs().cmplt(V::splat(1e-6));
        let at_hit = |dodx: Lanes3<V>, dddx: Lanes3<V>| {
            let p = dodx.add(dddx.scale(t));
            Lanes3::select(along_plane, p, p.sub(dir.scale(p.dot(ng) / facing)))
        };
        let d = &jobs.diffs;
        let dpx = at_hit(rows3(&d.dodx), rows3(&d.dddx));
        let dpy = at_hit(rows3(&d.dody), rows3(&d.dddy));
        // `barycentric_change` of each.
        let (a, b, c) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
        let det = a * c - b * b;
        let degenerate = det.abs().cmplt(V::splat(1e-30));
        let barycentric = |dp: Lanes3<V>| {
            let (r1, r2) = (e1.dot(dp), e2.dot(dp));
            let (b1, b2) = ((c * r1 - b * r2) / det, (a * r2 - b * r1) / det);
            (V::select(degenerate, V::splat(0.0), b1), V::select(degenerate, V::splat(0.0), b2))
        };
        let (bx, by) = (barycentric(dpx), barycentric(dpy));
        let normal = |b: (V, V)| dn1.scale(b.0).add(dn2.scale(b.1));
        // `d[0][k] * b.0 + d[1][k] * b.1` of each hit's change `d`.
        let along = |d: [V; 4], k: usize| [d[k] * bx.0 + d[2 + k] * bx.1, d[k] * by.0 + d[2 + k] * by.1];
        Derivs {
            dp: [dpx, dpy],
            dn: [normal(bx), normal(by)],
            du: along(duv, 0),
            dv: along(duv, 1),
            ds: along(dst, 0),
            dt: along(dst, 1),
        }
    }
}

/// The geometry of `V::LANES` hits (lane `j` that of lane `first + j` of a group's jobs) on an instance that stands
/// still, with a mesh without further attributes, in world space: what [`hit_geometry_into`]
/// works out for one hit, bit for bit.
struct SurfaceLanes<V: Lanes> {
    /// Each lane's corners, where its triangle is in the mesh (the first `V::LANES`).
    tris: [Option<[usize; 3]>; 8],
    p: Lanes3<V>,
    n: Lanes3<V>,
    ng: Lanes3<V>,
    uv: [V; 2],
    /// The change of (u, v) along the edges, `[d1.x, d1.y, d2.x, d2.y]`.
    duv: [V; 4],
    dpdu: Lanes3<V>,
    dpdv: Lanes3<V>,
    dn: [Lanes3<V>; 2],
    edges: [Lanes3<V>; 2],
}

impl<V: Lanes> SurfaceLanes<V> {
    #[inline(always)]
    fn of(ig: &InstanceGeometry, jobs: &GroupRows, first: usize) -> SurfaceLanes<V> {
        let mesh = ig.mesh;
        // Each hit's corners, where its triangle is in the mesh. A plain loop: as `hits.map` of a
        // closure returning `Option`s it was an out-of-line call writing them through memory.
        let mut tris: [Option<[usize; 3]>; 8] = [None; 8];
        for (j, tri) in tris.iter_mut().enumerate().take(V::LANES) {
            let primitive = jobs.hits.primitive.0.get(first + j).map_or(usize::MAX, |&p| p as usize);
            if let Some(corners) = mesh.triangles.get(primitive) {
                let corners = [corners[0] as usize, corners[1] as usize, corners[2] as usize];
                if corners.iter().all(|&i| i < mesh.positions.len()) {
                    *tri = Some(corners);
                }
            }
        }
        let tri = |j: usize| tris[j].unwrap_or([0; 3]);
        let vertex = |data: &[Vec3], k: usize| V::gather3(data, |j| tri(j)[k]);
        let (xf, normal_xf) = (&ig.world_from_object, &ig.normal_xf);
        let (pa, pb, pc) = (vertex(&mesh.positions, 0), vertex(&mesh.positions, 1), vertex(&mesh.positions, 2));
        let (e1, e2) = (pb.sub(pa), pc.sub(pa));
        let (u, v) = (V::load(&jobs.hits.u.0, first), V::load(&jobs.hits.v.0, first));
        let (w0, w1, w2) = (V::splat(1.0) - u - v, u, v);
        let p_obj = pa.scale(w0).add(pb.scale(w1)).add(pc.scale(w2));
        let ng = e1.cross(e2).transformed(normal_xf).normalize_or(Lanes3::zero());
        let normals = mesh.normals.as_deref();
        let n = match normals {
            Some(ns) => {
                let (na, nb, nc) = (vertex(ns, 0), vertex(ns, 1), vertex(ns, 2));
                na.scale(w0).add(nb.scale(w1)).add(nc.scale(w2)).transformed(normal_xf).normalize_or(ng)
            }
            None => ng,
        };
        let p = p_obj.transformed(&xf.matrix3).add(Lanes3::splat(xf.translation));
        // Surface coordinates: (u, v) and their change along the edges, dP/du and dP/dv (object space).
        let (zero, one) = (V::splat(0.0), V::splat(1.0));
        let identity = [one, zero, zero, one];
        let (uv, duv, dpdu, dpdv) = match &mesh.uvs {
            _ if !ig.coords => ([u, v], identity, Lanes3::zero(), Lanes3::zero()),
            Some(uvs) => {
                let corner = |k: usize| {
                    let [x, y] = V::gather2(uvs, |j| tri(j)[k]);
                    (x, y)
                };
                let (ta, tb, tc) = (corner(0), corner(1), corner(2));
                let (d1, d2) = ((tb.0 - ta.0, tb.1 - ta.1), (tc.0 - ta.0, tc.1 - ta.1));
                let det = d1.0 * d2.1 - d1.1 * d2.0;
                let inv = one / det;
                let solvable = det.abs().cmpgt(V::splat(1e-12));
                let dpdu = e1.scale(d2.1).sub(e2.scale(d1.1)).scale(inv);
                let dpdv = e2.scale(d1.0).sub(e1.scale(d2.0)).scale(inv);
                let uv = [ta.0 * w0 + tb.0 * w1 + tc.0 * w2, ta.1 * w0 + tb.1 * w1 + tc.1 * w2];
                // Where the uvs do not span the triangle, it is parameterised by its barycentrics.
                let changes = [d1.0, d1.1, d2.0, d2.1];
                let duv = std::array::from_fn(|k| V::select(solvable, changes[k], identity[k]));
                (uv, duv, Lanes3::select(solvable, dpdu, e1), Lanes3::select(solvable, dpdv, e2))
            }
            None => ([u, v], identity, e1, e2),
        };
        let (dpdu, dpdv) = match (ig.coords, ig.dpduv) {
            (true, true) => (dpdu.transformed(&xf.matrix3), dpdv.transformed(&xf.matrix3)),
            (true, false) => (Lanes3::zero(), Lanes3::zero()),
            (false, _) => (dpdu, dpdv),
        };
        let dn = match normals {
            Some(ns) if ig.normal_derivs => {
                let (na, nb, nc) = (vertex(ns, 0), vertex(ns, 1), vertex(ns, 2));
                [nb.sub(na).transformed(normal_xf), nc.sub(na).transformed(normal_xf)]
            }
            _ => [Lanes3::zero(); 2],
        };
        let edges =
            if ig.derivs { [e1.transformed(&xf.matrix3), e2.transformed(&xf.matrix3)] } else { [Lanes3::zero(); 2] };
        SurfaceLanes { tris, p, n, ng, uv, duv, dpdu, dpdv, dn, edges }
    }

    /// Writes these hits, those of lanes `at..at + V::LANES` of `jobs`, into the same lanes of
    /// `rows` (zero in lanes not `valid`), with their screen-space derivatives when the shaders
    /// want them.
    #[inline(always)]
    fn put_rows(&self, ig: &InstanceGeometry, jobs: &GroupRows, rows: &mut HitRows, (at, valid): (usize, V::Mask)) {
        rows.valid |= u64::from(V::bitmask(valid)) << at;
        let zero = V::splat(0.0);
        let put =
            |row: &mut [f32; PACKET_SIZE], v: V| V::select(valid, v, zero).write_to(&mut row[at.min(PACKET_SIZE)..]);
        let put3 = |to: &mut [[f32; PACKET_SIZE]; 3], v: Lanes3<V>| {
            put(&mut to[0], v.x);
            put(&mut to[1], v.y);
            put(&mut to[2], v.z);
        };
        put3(&mut rows.p, self.p);
        put3(&mut rows.n, self.n);
        put3(&mut rows.ng, self.ng);
        put3(&mut rows.dpdu, self.dpdu);
        put3(&mut rows.dpdv, self.dpdv);
        put(&mut rows.uv[0], self.uv[0]);
        put(&mut rows.uv[1], self.uv[1]);
        if ig.derivs {
            // Without an `st` of the mesh's own, (s, t) changes as (u, v).
            let surface = SurfaceChange { ng: self.ng, edges: self.edges, dn: self.dn, duv: self.duv, dst: self.duv };
            let d = surface.derivs(jobs, at);
            for axis in 0..2 {
                put3(&mut rows.dp[axis], d.dp[axis]);
                // Unread without: then left as they were, and not worked out (from zeros).
                if ig.normal_derivs {
                    put3(&mut rows.dn[axis], d.dn[axis]);
                }
                put(&mut rows.du[axis], d.du[axis]);
                put(&mut rows.dv[axis], d.dv[axis]);
            }
        }
    }
}

/// [`hit_geometry_into`] for the four hits of chunk `k` of `jobs` (lanes `4k..4k + 4`), of an
/// instance that stands still, with a mesh that does not deform and has no further attributes,
/// into `slots` (up to four: lanes past them are computed and dropped) where `each`, and into
/// chunk `k` of `rows` (lanes past `slots`, and those without geometry, zero), with the hits'
/// screen-space derivatives when the shaders want them.
fn hit_geometry_four(
    ig: &InstanceGeometry,
    jobs: &GroupRows,
    (slots, each): (&mut [Option<HitGeometry>], bool),
    (rows, k): (&mut HitRows, usize),
) {
    let s = SurfaceLanes::<Vec4>::of(ig, jobs, 4 * k);
    let valid = BVec4A::from_array(std::array::from_fn(|j| j < slots.len() && s.tris[j].is_some()));
    s.put_rows(ig, jobs, rows, (4 * k, valid));
    // A loop of four with constant lanes, unrolled: each value is taken out of its register, where
    // a variable lane would go through memory (and loads across the stores there stall). `st` and
    // `dst` are written from the values, not read back from `g`, for the same reason: a load of
    // what narrower stores just wrote is not forwarded from them (a fifth of this function's time).
    if !each {
        return;
    }
    let SurfaceLanes { tris, p, n, ng, uv, duv, dpdu, dpdv, dn, edges } = s;
    for j in 0..4 {
        let Some(slot) = slots.get_mut(j) else { break };
        if tris[j].is_none() {
            *slot = None;
            continue;
        }
        let g = slot.get_or_insert_with(HitGeometry::default);
        let (uv, duv) = ([uv[0][j], uv[1][j]], [[duv[0][j], duv[1][j]], [duv[2][j], duv[3][j]]]);
        g.p = p.lane(j);
        g.n = n.lane(j);
        g.ng = ng.lane(j);
        g.uv = uv;
        g.st = uv;
        g.dpdu = dpdu.lane(j);
        g.dpdv = dpdv.lane(j);
        g.cs = None;
        g.os = None;
        g.attributes.clear();
        g.edges = [edges[0].lane(j), edges[1].lane(j)];
        g.duv = duv;
        g.dst = duv;
        g.dn = [dn[0].lane(j), dn[1].lane(j)];
        g.traced = None;
    }
}

/// [`hit_geometry_four`]'s rows, without the slots, for the eight hits of `jobs` from lane `8k`:
/// eight lanes at a time, in one AVX register a component, half the instructions of four at a
/// time.
fn hit_rows_eight(ig: &InstanceGeometry, jobs: &GroupRows, rows: &mut HitRows, k: usize) {
    let (first, lanes) = (8 * k, jobs.len().saturating_sub(8 * k).min(8));
    if lanes == 0 {
        return;
    }
    let s = SurfaceLanes::<f32x8>::of(ig, jobs, first);
    let valid = <f32x8 as Lanes>::mask_from_fn(|j| j < lanes && s.tris[j].is_some());
    s.put_rows(ig, jobs, rows, (first, valid));
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
    if [a, b, c].iter().any(|&k| k >= mesh.positions.len()) {
        return None;
    }
    let (mut pa, mut pb, mut pc) = (mesh.position_at(a, time), mesh.position_at(b, time), mesh.position_at(c, time));
    let (xf, normal_xf) = match ig.moving {
        None => (ig.world_from_object, ig.normal_xf),
        Some(d) => {
            let xf = d.world_from_object_at(time);
            (xf, xf.matrix3.inverse().transpose())
        }
    };
    let (w0, w1, w2) = (1.0 - hit.u - hit.v, hit.u, hit.v);
    let mut traced = None;
    if let Some(before) = ig.undisplaced {
        let at = |k: usize| Vec3::new(before[3 * k], before[3 * k + 1], before[3 * k + 2]);
        let p = Vec3A::from(pa) * w0 + Vec3A::from(pb) * w1 + Vec3A::from(pc) * w2;
        let ng = (normal_xf * Vec3A::from(pb - pa).cross(Vec3A::from(pc - pa))).normalize_or_zero();
        traced = Some((xf.transform_point3a(p), ng));
        (pa, pb, pc) = (at(a), at(b), at(c));
    }
    let (e1, e2) = (Vec3A::from(pb - pa), Vec3A::from(pc - pa));
    let p_obj = Vec3A::from(pa) * w0 + Vec3A::from(pb) * w1 + Vec3A::from(pc) * w2;
    let ng = (normal_xf * e1.cross(e2)).normalize_or_zero();
    let n = match mesh.interpolate_normal_at([a, b, c], [w0, w1, w2], time) {
        Some(ni) => (normal_xf * Vec3A::from(ni)).normalize_or(ng),
        None => ng,
    };
    let mut attributes = mesh.interpolate_attributes([a, b, c], [w0, w1, w2]);
    for (values, at) in attributes.iter_mut().zip(&mesh.attributes) {
        at.kind.transform(values, &xf, &normal_xf);
    }
    let surf_p = xf.transform_point3a(p_obj);
    let mut duv = [[1.0, 0.0], [0.0, 1.0]];
    let (uv, dpdu, dpdv) = match &mesh.uvs {
        _ if !ig.coords => ([hit.u, hit.v], Vec3A::ZERO, Vec3A::ZERO),
        Some(uvs) => {
            let (ta, tb, tc) = (uvs[a], uvs[b], uvs[c]);
            let (d1, d2) = (tb - ta, tc - ta);
            let det = d1.x * d2.y - d1.y * d2.x;
            // Where the uvs do not span the triangle (a RIB polygon's default (x, y) seen edge
            // on, an OBJ face whose texture coordinates coincide), derivatives along u and v would
            // be zero, and `calculatenormal` with them: the triangle is parameterised by its
            // barycentrics instead, as one without uvs.
            let (dpdu, dpdv) = if det.abs() > 1e-12 {
                duv = [d1.to_array(), d2.to_array()];
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
        Some(ns) if ig.normal_derivs => {
            [normal_xf * Vec3A::from(ns[b] - ns[a]), normal_xf * Vec3A::from(ns[c] - ns[a])]
        }
        _ => [Vec3A::ZERO; 2],
    };
    let (dpdu, dpdv) = match (ig.coords, ig.dpduv) {
        (true, true) => (xf.transform_vector3a(dpdu), xf.transform_vector3a(dpdv)),
        (true, false) => (Vec3A::ZERO, Vec3A::ZERO),
        (false, _) => (dpdu, dpdv),
    };
    *g = HitGeometry {
        p: surf_p,
        n,
        ng,
        uv,
        st,
        dpdu,
        dpdv,
        cs: color_attr(ig.cs),
        os: color_attr(ig.os),
        attributes,
        edges: if ig.derivs { [xf.transform_vector3a(e1), xf.transform_vector3a(e2)] } else { [Vec3A::ZERO; 2] },
        duv,
        dst,
        dn,
        traced,
    };
    Some(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Mesh;
    use crate::ray::Ray;
    use crate::render::differential::RayDifferential;
    use crate::render::jobs::{JobRows, Pending};
    use glam::Mat3A;

    /// A xorshift stream of floats in [-1, 1).
    fn stream(mut seed: u64) -> impl FnMut() -> f32 {
        move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 40) as f32 / (1u64 << 23) as f32 - 1.0
        }
    }

    fn bits(g: &HitGeometry) -> Vec<u32> {
        let v3 = |v: Vec3A| v.to_array();
        let floats = [v3(g.p), v3(g.n), v3(g.ng), v3(g.dpdu), v3(g.dpdv)]
            .into_iter()
            .chain(g.edges.map(v3))
            .chain(g.dn.map(v3))
            .flatten()
            .chain(g.uv)
            .chain(g.st)
            .chain(g.duv.into_iter().flatten())
            .chain(g.dst.into_iter().flatten());
        floats.map(f32::to_bits).collect()
    }

    /// Every value of the rows (and the valid lanes), as bits.
    fn row_bits(r: &HitRows) -> Vec<u32> {
        let mut rows: Vec<&[f32; PACKET_SIZE]> = Vec::new();
        rows.extend(r.p.iter().chain(&r.n).chain(&r.ng).chain(&r.uv).chain(&r.dpdu).chain(&r.dpdv));
        rows.extend(r.dp.iter().chain(&r.dn).flatten().chain(&r.du).chain(&r.dv));
        let bits = rows.into_iter().flatten().map(|v| v.to_bits());
        [r.valid as u32, (r.valid >> 32) as u32].into_iter().chain(bits).collect()
    }

    fn surface_bits(h: &HitSurface) -> Vec<u32> {
        let v3 = |v: Vec3A| v.to_array();
        let some = |v: Option<Vec3A>| v.map_or([f32::NAN; 3], |v| v.to_array());
        [v3(h.p), v3(h.n), v3(h.ng), v3(h.dpdu), v3(h.dpdv), some(h.cs), some(h.os)]
            .into_iter()
            .flatten()
            .chain(h.uv.into_iter().chain(h.st))
            .map(f32::to_bits)
            .collect()
    }

    fn deriv_bits(d: &HitDerivs) -> Vec<u32> {
        let v3 = |v: Vec3A| v.to_array();
        let floats = d.dp.map(v3).into_iter().chain(d.dn.map(v3)).flatten();
        floats.chain([d.du, d.dv, d.ds, d.dt].into_iter().flatten()).map(f32::to_bits).collect()
    }

    impl DerivsFour {
        fn lane(&self, j: usize) -> HitDerivs {
            let pair = |d: &[Vec4; 2]| [d[0][j], d[1][j]];
            HitDerivs {
                dp: self.dp.map(|v| v.lane(j)),
                dn: self.dn.map(|v| v.lane(j)),
                du: pair(&self.du),
                dv: pair(&self.dv),
                ds: pair(&self.ds),
                dt: pair(&self.dt),
            }
        }
    }

    /// Four hits at a time give every field the bits that one hit at a time gives: with and
    /// without normals and texture coordinates, surface coordinates and derivatives, degenerate
    /// texture coordinates and triangles, rays along a triangle's plane, and triangles the mesh
    /// does not have; and so do their screen-space derivatives ([`derivs_four`]).
    #[test]
    fn four_hits_at_a_time_match_one_at_a_time_bit_for_bit() {
        let mut r = stream(0x5EED_1234_ABCD_0001);
        for round in 0..48 {
            let vertices = 12;
            let positions: Vec<Vec3> = (0..vertices).map(|_| Vec3::new(r() * 5.0, r() * 5.0, r() * 5.0)).collect();
            let normals = (round % 2 == 0).then(|| (0..vertices).map(|_| Vec3::new(r(), r(), r())).collect());
            let uvs = (round % 3 != 0).then(|| {
                (0..vertices)
                    .map(|k| if k == 3 { glam::Vec2::splat(0.5) } else { glam::Vec2::new(r() * 4.0, r() * 4.0) })
                    .collect()
            });
            // Triangle 0 has texture coordinates all alike at two corners (vertex 3 twice).
            let mut triangles = vec![[3, 3, 5]];
            triangles.extend((0..9).map(|k| [k, (k + 1) % vertices, (k + 5) % vertices]));
            // Every fifth round's mesh has its own `st` (and goes one hit at a time).
            let attributes = match round % 5 {
                4 => vec![crate::geometry::mesh::Attribute::data(
                    "st",
                    2,
                    (0..2 * vertices).map(|_| r() * 3.0).collect(),
                )],
                _ => Vec::new(),
            };
            let st = (!attributes.is_empty()).then_some(0);
            let mesh = Mesh { positions, normals, uvs, attributes, triangles, deformation: None };
            let m = Mat3A::from_cols(
                Vec3A::new(r() * 2.0, r(), r()),
                Vec3A::new(r(), r() * 2.0, r()),
                Vec3A::new(r(), r(), r() * 2.0),
            );
            let xf = Affine3A { matrix3: m, translation: Vec3A::new(r() * 9.0, r() * 9.0, r() * 9.0) };
            let ig = InstanceGeometry {
                mesh: &mesh,
                world_from_object: xf,
                normal_xf: m.inverse().transpose(),
                moving: None,
                derivs: round % 4 < 2,
                coords: round % 4 != 3,
                // Round 4 of every 8 (with normals and derivatives) skips the normal's
                // derivatives, round 6 (with coordinates) dPdu and dPdv.
                dpduv: round % 8 != 6 && round % 4 != 3,
                normal_derivs: round % 8 != 4 && round % 4 < 2,
                st,
                cs: None,
                os: None,
                undisplaced: None,
            };
            let lanes = 1 + round % 11;
            let group: Vec<Pending> = (0..lanes)
                .map(|k| {
                    let (u, v) = ((r() + 1.0) * 0.5, (r() + 1.0) * 0.25);
                    // Lane 5 meets a triangle the mesh does not have.
                    let primitive = if k == 5 { 99 } else { ((r() + 1.0) * 5.0) as u32 % 10 };
                    let hit = Hit { t: 1.0, u, v, instance: 0, primitive };
                    let mut v3 = || Vec3A::new(r(), r(), r());
                    let (direction, dodx, dody, dddx, dddy) =
                        (v3(), v3() * 0.01, v3() * 0.01, v3() * 0.01, v3() * 0.01);
                    // Lane 2 grazes its triangle: its ray runs along an edge, in the plane.
                    let direction = match mesh.triangles.get(primitive as usize) {
                        Some(&[a, b, _]) if k == 2 => {
                            xf.matrix3 * Vec3A::from(mesh.positions[b as usize] - mesh.positions[a as usize])
                        }
                        _ => direction,
                    };
                    let hit = Hit { t: 1.0 + 4.0 * (r() + 1.0), ..hit };
                    let diff = RayDifferential { dodx, dody, dddx, dddy };
                    let budget = crate::render::ray_budget::RayBudget::NONE;
                    Pending { index: k, start: 0.0, ray: Ray::new(Vec3A::ZERO, direction), diff, hit, budget }
                })
                .collect();
            let mut jobs = JobRows::default();
            for p in &group {
                jobs.push(p, p.budget);
            }
            jobs.finish();
            let jobs = jobs.rows();
            let mut four: Vec<Option<HitGeometry>> = (0..lanes).map(|_| None).collect();
            let mut rows = HitRows::default();
            let by_rows = hit_geometries(&ig, &jobs, &mut four, &mut rows, true);
            assert_eq!(by_rows, mesh.attributes.is_empty(), "round {round}");
            let derivs: Vec<HitDerivs> = four
                .chunks(4)
                .enumerate()
                .flat_map(|(c, g)| {
                    let d = derivs_four(&jobs, 4 * c, std::array::from_fn(|j| g.get(j).and_then(Option::as_ref)));
                    (0..g.len()).map(move |j| d.lane(j))
                })
                .collect();
            // Without `each` the slots are left as they were, the rows are the same, and what
            // `GroupHits::Rows` gives of each hit is what `GroupHits::Each` gives of its slot.
            let mut untouched: Vec<Option<HitGeometry>> = (0..lanes).map(|_| None).collect();
            let mut only = HitRows { valid: u64::MAX, ..HitRows::default() };
            assert_eq!(hit_geometries(&ig, &jobs, &mut untouched, &mut only, false), by_rows, "round {round}");
            assert_eq!(untouched.iter().all(Option::is_none), by_rows, "round {round}");
            if by_rows {
                assert_eq!(row_bits(&only), row_bits(&rows), "round {round}");
                let (each, alone) = (GroupHits::Each(&four, Some(&rows)), GroupHits::Rows(&only, lanes));
                for k in 0..lanes + 2 {
                    assert_eq!(only.valid >> k & 1 != 0, four.get(k).is_some_and(Option::is_some), "round {round}");
                    let a = each.get(k).map(|h| surface_bits(&h));
                    assert_eq!(a, alone.get(k).map(|h| surface_bits(&h)), "round {round}, lane {k}");
                }
            }
            if by_rows {
                // The lanes past the group, up to a whole chunk, are zero.
                for k in lanes..lanes.div_ceil(4) * 4 {
                    let all = [&rows.p[..], &rows.n, &rows.ng, &rows.uv, &rows.dpdu, &rows.dpdv];
                    assert!(all.iter().all(|rows| rows.iter().all(|r| r[k] == 0.0)), "round {round}, lane {k}");
                }
            }
            for (k, p) in group.iter().enumerate() {
                let mut one = None;
                hit_geometry_into(&ig, &p.hit, 0.0, &mut one);
                let case = format!("round {round}, lane {k} of {lanes}, triangle {}", p.hit.primitive);
                assert_eq!(one.is_some(), four[k].is_some(), "{case}");
                if by_rows {
                    // The rows hold the same bits, and zeros for a hit without geometry.
                    let v3 = |v: Vec3A| v.to_array();
                    let at = |rows: &[[f32; PACKET_SIZE]]| rows.iter().map(|r| r[k].to_bits()).collect::<Vec<_>>();
                    let want = |f: &dyn Fn(&HitGeometry) -> Vec<f32>| {
                        let values = one.as_ref().map_or(vec![0.0; f(&HitGeometry::default()).len()], f);
                        values.into_iter().map(f32::to_bits).collect::<Vec<_>>()
                    };
                    assert_eq!(at(&rows.p), want(&|g| v3(g.p).to_vec()), "{case}");
                    assert_eq!(at(&rows.n), want(&|g| v3(g.n).to_vec()), "{case}");
                    assert_eq!(at(&rows.ng), want(&|g| v3(g.ng).to_vec()), "{case}");
                    assert_eq!(at(&rows.dpdu), want(&|g| v3(g.dpdu).to_vec()), "{case}");
                    assert_eq!(at(&rows.dpdv), want(&|g| v3(g.dpdv).to_vec()), "{case}");
                    assert_eq!(at(&rows.uv), want(&|g| g.uv.to_vec()), "{case}");
                    assert_eq!(at(&rows.uv), want(&|g| g.st.to_vec()), "{case}");
                }
                if let (Some(a), Some(b)) = (&one, &four[k]) {
                    assert_eq!(bits(a), bits(b), "{case}");
                    assert_eq!(deriv_bits(&a.derivs(&jobs, k)), deriv_bits(&derivs[k]), "{case}");
                    if by_rows && ig.derivs {
                        let (want, from_rows) = (a.derivs(&jobs, k), rows.derivs(k / 4).lane(k % 4));
                        // The normal's rows only where they are wanted (else left zero here).
                        let dn = if ig.normal_derivs { want.dn } else { [Vec3A::ZERO; 2] };
                        assert_eq!(deriv_bits(&HitDerivs { dn, ..want }), deriv_bits(&from_rows), "{case}");
                    }
                }
            }
        }
    }
}
