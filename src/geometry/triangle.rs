//! Watertight ray–triangle intersection after Woop, Benthin, Wald 2013, "Watertight Ray/Triangle
//! Intersection", JCGT 2(1).
//!
//! The test translates the vertices to the ray origin, shears them so that the ray becomes the +z axis
//! (the permutation and shear), evaluates the three 2D edge functions of the projected triangle and
//! re-evaluates them in double precision when one of them is exactly zero. Because a vertex's sheared
//! coordinates depend only on that vertex and the ray, two triangles sharing an edge see bit-identical
//! edge-function inputs along it, so a ray can never slip between them. (Section numbers of the papers
//! are not cited because they were not checked against the published PDFs.)
//!
//! Triangles are hit from both sides; face culling is the integrator's job. A hit closer to the origin than the
//! distance's own rounding error is rejected, so a ray spawned off a surface never re-hits it.

use crate::math::{gamma, Ray, Vec3, Vec4};
use glam::{BVec3A, BVec4A, Vec3A, Vec3Swizzles};

/// A closest hit found by [`crate::geometry::Bvh::intersect`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleHit {
    /// Distance along the ray (the ray direction is unit length, so a world-space distance).
    pub t: f32,
    /// Index of the triangle in the list given to [`crate::geometry::Bvh::build`].
    pub prim: u32,
    /// Barycentric weight of the second vertex: `p = (1 - b1 - b2)·v0 + b1·v1 + b2·v2`.
    pub b1: f32,
    /// Barycentric weight of the third vertex.
    pub b2: f32,
}

/// The per-ray constants of the watertight test (Woop et al. 2013): the origin, and the rows of the
/// permute-and-shear transform that maps the ray direction onto +z.
///
/// Computing this once per ray and reusing it for every triangle is what makes the test cheap.
#[derive(Clone, Copy, Debug)]
pub struct WatertightRay {
    origin: Vec3,
    /// Row giving the sheared x: `A[kx] - Sx·A[kz]`, written as the dot product `(A.x·s.x + A.y·s.y) +
    /// A.z·s.z` with one exact 1 and one exact 0 in `s`, so it rounds exactly like the paper's form.
    shear_x: Vec3,
    /// Row giving the sheared y: `A[ky] - Sy·A[kz]`.
    shear_y: Vec3,
    /// Row giving the scaled z: `Sz·A[kz]`.
    scale_z: Vec3,
    /// The origin and the three rows above with each of their coordinates splatted across four lanes, for
    /// [`Triangle4::intersect`]: `splat[0]` the origin, `splat[1..4]` the rows, `splat[r][a]` coordinate `a`.
    splat: [[Vec4; 3]; 4],
}

impl WatertightRay {
    /// Precomputes the permutation (largest direction component becomes z, winding preserved) and the
    /// shear constants `Sx = dx/dz`, `Sy = dy/dz`, `Sz = 1/dz` of Woop et al. 2013.
    ///
    /// Branch-free: the axes come from comparisons and small tables, and each row is selected lane by lane
    /// with SIMD masks, so the rows hold exactly `1`, the shear and `+0`, whatever the ray.
    #[inline(always)]
    pub fn new(ray: &Ray) -> Self {
        let d = ray.dir.to_array();
        let a = ray.dir.abs();
        // The largest component (the first of equal ones), then the two others in cyclic order, swapped
        // for a negative largest component so that the winding is kept.
        let x_largest = a.x >= a.y && a.x >= a.z;
        let y_largest = !x_largest && a.y >= a.z;
        let kz = usize::from(!x_largest) + usize::from(!x_largest && !y_largest);
        const OTHERS: [[(usize, usize); 2]; 3] =
            [[(1, 2), (2, 1)], [(2, 0), (0, 2)], [(0, 1), (1, 0)]];
        let (kx, ky) = OTHERS[kz][usize::from(d[kz] < 0.0)];
        let sz = 1.0 / d[kz];
        // Each row holds one exact 1 (or `Sz`) and the shear at `kz`, +0 elsewhere.
        const AXIS: [BVec3A; 3] = [
            BVec3A::new(true, false, false),
            BVec3A::new(false, true, false),
            BVec3A::new(false, false, true),
        ];
        let row = |k: usize, at_k: f32, at_kz: f32| {
            let at_kz = Vec3A::select(AXIS[kz], Vec3A::splat(at_kz), Vec3A::ZERO);
            Vec3::from(Vec3A::select(AXIS[k], Vec3A::splat(at_k), at_kz))
        };
        let (shear_x, shear_y, scale_z) = (
            row(kx, 1.0, 0.0 - d[kx] * sz),
            row(ky, 1.0, 0.0 - d[ky] * sz),
            row(kz, sz, sz),
        );
        let splat = |v: Vec3| [Vec4::splat(v.x), Vec4::splat(v.y), Vec4::splat(v.z)];
        Self {
            origin: ray.origin,
            shear_x,
            shear_y,
            scale_z,
            splat: [
                splat(ray.origin),
                splat(shear_x),
                splat(shear_y),
                splat(scale_z),
            ],
        }
    }
}

/// Intersects the ray with triangle `tri` (Woop et al. 2013), from either side.
///
/// Returns `(t, b1, b2)` for a hit with `t_min <= t <= t_max`, where `p = (1-b1-b2)·v0 + b1·v1 + b2·v2`.
/// Degenerate (zero-area or edge-on) triangles never hit. A point exactly on an edge or vertex counts as a
/// hit, which is what makes a closed mesh watertight.
///
/// The three vertices are processed in the three SIMD lanes of a `Vec3A`; each lane performs exactly the
/// scalar operations of the paper, in the same order, so a vertex shared by two triangles still gets the
/// same sheared coordinates in both.
#[inline(always)]
pub fn intersect_triangle(
    ray: &WatertightRay,
    tri: &[Vec3; 3],
    t_min: f32,
    t_max: f32,
) -> Option<(f32, f32, f32)> {
    let o = ray.origin;
    // Lane i holds vertex i, translated to the ray origin.
    let xs = Vec3A::new(tri[0].x, tri[1].x, tri[2].x) - o.x;
    let ys = Vec3A::new(tri[0].y, tri[1].y, tri[2].y) - o.y;
    let zs = Vec3A::new(tri[0].z, tri[1].z, tri[2].z) - o.z;
    let row = |s: Vec3| xs * s.x + ys * s.y + zs * s.z;
    // Sheared x and y of (A, B, C).
    let sx = row(ray.shear_x);
    let sy = row(ray.shear_y);

    // Scaled barycentrics (U, V, W) = (Cx·By - Cy·Bx, Ax·Cy - Ay·Cx, Bx·Ay - By·Ax): 2D edge functions.
    let mut uvw = sx.zxy() * sy.yzx() - sy.zxy() * sx.yzx();
    if uvw.cmpeq(Vec3A::ZERO).any() {
        // An exact zero may be a rounding artefact; decide it in double precision.
        let (x, y) = (sx.as_dvec3(), sy.as_dvec3());
        uvw = (x.zxy() * y.yzx() - y.zxy() * x.yzx()).as_vec3().into();
    }
    if uvw.cmplt(Vec3A::ZERO).any() && uvw.cmpgt(Vec3A::ZERO).any() {
        return None;
    }
    let (u, v, w) = (uvw.x, uvw.y, uvw.z);
    let det = u + v + w;
    if det == 0.0 {
        return None;
    }
    let zs_scaled = row(ray.scale_z);
    let z = zs_scaled * uvw;
    let t_scaled = z.x + z.y + z.z;
    let rcp = 1.0 / det;
    let t = t_scaled * rcp;
    if !(t >= t_min && t <= t_max) {
        return None;
    }
    if t <= distance_error_bound(sx, sy, zs_scaled, uvw, rcp) {
        // Too close to the origin to tell from rounding whether the hit is in front of it at all.
        return None;
    }
    Some((t, v * rcp, w * rcp))
}

/// Four triangles in structure-of-arrays form, tested against one ray together by [`Triangle4::intersect`]:
/// the packed leaf triangles of a [`crate::geometry::Bvh`] (160 bytes, 40 a triangle). Lanes past the pack's
/// triangle count repeat its first triangle and are masked out by the caller.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(16))]
pub(super) struct Triangle4 {
    /// `vertex[k][a]`: coordinate `a` (x, y, z) of vertex `k` of the four triangles.
    vertex: [[Vec4; 3]; 3],
    /// The triangles' indices in the input list (`u32::MAX` in unused lanes).
    pub(super) ids: [u32; 4],
}

/// What [`Triangle4::intersect`] found: a bit mask of the lanes hit, and their distances and barycentrics.
pub(super) struct Hits4 {
    /// Bit `i` set: lane `i` is hit within the interval.
    pub(super) mask: u32,
    /// Distance of each hit lane.
    pub(super) t: Vec4,
    /// Barycentric weight of each hit lane's second vertex.
    pub(super) b1: Vec4,
    /// Barycentric weight of each hit lane's third vertex.
    pub(super) b2: Vec4,
}

impl Triangle4 {
    /// Packs up to four triangles with their input indices; an empty list gives a pack no valid lane names.
    pub(super) fn new(tris: &[[Vec3; 3]], ids: &[u32]) -> Self {
        let lane = |i: usize| tris.get(i).or(tris.first()).copied().unwrap_or_default();
        let vertex = [0, 1, 2]
            .map(|k| [0, 1, 2].map(|a| Vec4::from_array([0, 1, 2, 3].map(|i| lane(i)[k][a]))));
        Self {
            vertex,
            ids: [0, 1, 2, 3].map(|i| ids.get(i).copied().unwrap_or(u32::MAX)),
        }
    }

    /// The watertight test of [`intersect_triangle`] on the lanes of `valid` (a bit mask) at once. Each lane
    /// performs exactly the scalar operations of [`intersect_triangle`] in the same order, so its hits,
    /// distances and barycentrics are bit for bit those of testing the triangles one at a time.
    #[inline(always)]
    pub(super) fn intersect(
        &self,
        ray: &WatertightRay,
        valid: u32,
        t_min: f32,
        t_max: f32,
    ) -> Hits4 {
        let [o, shear_x, shear_y, scale_z] = &ray.splat;
        // Vertex k translated to the ray origin, then a row of the permute-and-shear transform applied.
        let rel = |k: usize| {
            let v = &self.vertex[k];
            [v[0] - o[0], v[1] - o[1], v[2] - o[2]]
        };
        let (a, b, c) = (rel(0), rel(1), rel(2));
        let row = |p: &[Vec4; 3], s: &[Vec4; 3]| p[0] * s[0] + p[1] * s[1] + p[2] * s[2];
        let (ax, bx, cx) = (row(&a, shear_x), row(&b, shear_x), row(&c, shear_x));
        let (ay, by, cy) = (row(&a, shear_y), row(&b, shear_y), row(&c, shear_y));
        let mut u = cx * by - cy * bx;
        let mut v = ax * cy - ay * cx;
        let mut w = bx * ay - by * ax;
        let zero =
            (u.cmpeq(Vec4::ZERO) | v.cmpeq(Vec4::ZERO) | w.cmpeq(Vec4::ZERO)).bitmask() & valid;
        let mut m = zero;
        while m != 0 {
            // An exact zero may be a rounding artefact; decide that lane in double precision.
            let i = m.trailing_zeros() as usize;
            m &= m - 1;
            let edge = |p: [f32; 4]| -> f64 {
                f64::from(p[0]) * f64::from(p[1]) - f64::from(p[2]) * f64::from(p[3])
            };
            u[i] = edge([cx[i], by[i], cy[i], bx[i]]) as f32;
            v[i] = edge([ax[i], cy[i], ay[i], cx[i]]) as f32;
            w[i] = edge([bx[i], ay[i], by[i], ax[i]]) as f32;
        }
        let negative = u.cmplt(Vec4::ZERO) | v.cmplt(Vec4::ZERO) | w.cmplt(Vec4::ZERO);
        let positive = u.cmpgt(Vec4::ZERO) | v.cmpgt(Vec4::ZERO) | w.cmpgt(Vec4::ZERO);
        let inside = (!(negative & positive)).bitmask() & valid;
        let none = Hits4 {
            mask: 0,
            t: Vec4::ZERO,
            b1: Vec4::ZERO,
            b2: Vec4::ZERO,
        };
        if inside == 0 {
            return none;
        }
        let det = u + v + w;
        let (az, bz, cz) = (row(&a, scale_z), row(&b, scale_z), row(&c, scale_z));
        let t_scaled = az * u + bz * v + cz * w;
        let rcp = Vec4::ONE / det;
        let t = t_scaled * rcp;
        let max_abs = |p: Vec4, q: Vec4, r: Vec4| p.abs().max(q.abs()).max(r.abs());
        let bound = error_bound_from_maxima(
            [
                max_abs(ax, bx, cx),
                max_abs(ay, by, cy),
                max_abs(az, bz, cz),
            ],
            max_abs(u, v, w),
            rcp.abs(),
        );
        let in_range: BVec4A = t.cmpge(Vec4::splat(t_min)) & t.cmple(Vec4::splat(t_max));
        let hit = det.cmpne(Vec4::ZERO) & in_range & t.cmpgt(bound);
        Hits4 {
            mask: hit.bitmask() & inside,
            t,
            b1: v * rcp,
            b2: w * rcp,
        }
    }
}

/// A conservative bound on the rounding error of the distance computed by [`intersect_triangle`], from the
/// magnitudes of the sheared vertex coordinates and edge functions (the forward error analysis of PBRT 4th ed.,
/// §6.8.4, "Robust Triangle Intersections", applied to Woop et al.'s transform, which rounds no more). A hit
/// whose distance does not exceed it may lie behind the origin, as it does for a ray leaving the surface it was
/// spawned from: rejecting it is what lets offset ray origins (see [`crate::geometry::spawn`]) never re-hit
/// their own triangle.
#[inline(always)]
fn distance_error_bound(sx: Vec3A, sy: Vec3A, sz: Vec3A, uvw: Vec3A, rcp: f32) -> f32 {
    let max_z = sz.abs().max_element();
    let max_x = sx.abs().max_element();
    let max_y = sy.abs().max_element();
    let max_e = uvw.abs().max_element();
    error_bound_from_maxima([max_x, max_y, max_z], max_e, rcp.abs())
}

/// The bound of [`distance_error_bound`] from the largest sheared |x|, |y|, |z| of the vertices, the largest
/// |edge function| and |1/det|: for one triangle (`f32`) or lane by lane for four ([`Vec4`]), with the same
/// operations in the same order either way.
#[inline(always)]
fn error_bound_from_maxima<T>(max_xyz: [T; 3], max_e: T, rcp_abs: T) -> T
where
    T: Copy + std::ops::Add<Output = T> + std::ops::Mul<Output = T>,
    f32: std::ops::Mul<T, Output = T>,
{
    let [max_x, max_y, max_z] = max_xyz;
    let delta_z = gamma(3.0) * max_z;
    let delta_x = gamma(5.0) * (max_x + max_z);
    let delta_y = gamma(5.0) * (max_y + max_z);
    let delta_e = 2.0 * (gamma(2.0) * max_x * max_y + delta_y * max_x + delta_x * max_y);
    3.0 * (gamma(3.0) * max_e * max_z + delta_e * max_z + delta_z * max_e) * rcp_abs
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hit(o: Vec3, d: Vec3, tri: &[Vec3; 3]) -> Option<(f32, f32, f32)> {
        intersect_triangle(
            &WatertightRay::new(&Ray::new(o, d)),
            tri,
            0.0,
            f32::INFINITY,
        )
    }

    #[test]
    fn hit_from_both_sides_with_barycentrics() {
        let tri = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let (t, b1, b2) = hit(Vec3::new(0.25, 0.5, 2.0), -Vec3::Z, &tri).unwrap();
        assert!((t - 2.0).abs() < 1e-6 && (b1 - 0.25).abs() < 1e-6 && (b2 - 0.5).abs() < 1e-6);
        let (t, b1, b2) = hit(Vec3::new(0.25, 0.5, -3.0), Vec3::Z, &tri).unwrap();
        assert!((t - 3.0).abs() < 1e-6 && (b1 - 0.25).abs() < 1e-6 && (b2 - 0.5).abs() < 1e-6);
        assert!(hit(Vec3::new(0.75, 0.5, 2.0), -Vec3::Z, &tri).is_none());
        assert!(hit(Vec3::new(0.25, 0.5, 2.0), Vec3::Z, &tri).is_none());
    }

    #[test]
    fn edges_and_vertices_count_as_hits() {
        let tri = [Vec3::ZERO, Vec3::X, Vec3::Y];
        for p in [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(0.5, 0.5, 0.0)] {
            assert!(hit(p + Vec3::Z, -Vec3::Z, &tri).is_some(), "{p}");
        }
    }

    #[test]
    fn degenerate_and_edge_on_triangles_miss() {
        let line = [Vec3::ZERO, Vec3::X, Vec3::X * 2.0];
        assert!(hit(Vec3::new(0.5, 0.0, 1.0), -Vec3::Z, &line).is_none());
        let point = [Vec3::ONE; 3];
        assert!(hit(Vec3::new(1.0, 1.0, 2.0), -Vec3::Z, &point).is_none());
        let tri = [Vec3::ZERO, Vec3::X, Vec3::Y];
        assert!(hit(Vec3::new(-1.0, 0.25, 0.0), Vec3::X, &tri).is_none());
    }

    #[test]
    fn packs_of_four_match_the_single_test_bit_for_bit() {
        let mut rng = crate::math::Rng::new(21, 22);
        let mut point = || Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
        for k in 0..4000 {
            let mut tris: Vec<[Vec3; 3]> = (0..4).map(|_| [point(), point(), point()]).collect();
            // Shared edges and vertices, a degenerate triangle, and axis-aligned rays through vertices.
            tris[1][0] = tris[0][1];
            tris[1][1] = tris[0][0];
            if k % 5 == 0 {
                tris[2] = [tris[0][2]; 3];
            }
            let o = point() * 3.0;
            let d = match k % 4 {
                0 => (tris[k % 3][k % 3] - o).normalize(),
                1 => Vec3::X,
                _ => (point() - o).normalize(),
            };
            let ray = WatertightRay::new(&Ray::new(o, d));
            let used = 1 + k % 4;
            let ids: Vec<u32> = (0..used as u32).collect();
            let pack = Triangle4::new(&tris[..used], &ids);
            let hits = pack.intersect(&ray, (1 << used) - 1, 0.0, 2.5);
            for (i, tri) in tris[..used].iter().enumerate() {
                let single = intersect_triangle(&ray, tri, 0.0, 2.5);
                let packed = (hits.mask >> i & 1 == 1).then(|| (hits.t[i], hits.b1[i], hits.b2[i]));
                assert_eq!(
                    packed.map(|h| h.0.to_bits()),
                    single.map(|h| h.0.to_bits()),
                    "{k} {i}"
                );
                assert_eq!(packed, single, "{k} {i}");
            }
            assert_eq!(hits.mask >> used, 0, "{k}: an unused lane hit");
        }
    }

    /// The rows as Woop et al. 2013 define them, written with an indexed array: `kz` the largest |component|
    /// (the first of equal ones), `kx`, `ky` the others in cyclic order, swapped when `d[kz] < 0`.
    fn rows_by_index(d: Vec3) -> [Vec3; 3] {
        let a = d.abs().to_array();
        let kz = (0..3).fold(0, |k, i| if a[i] > a[k] { i } else { k });
        let (mut kx, mut ky) = ((kz + 1) % 3, (kz + 2) % 3);
        if d[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        let sz = 1.0 / d[kz];
        let row = |k: usize, at_k: f32, at_kz: f32| {
            let mut r = [0.0; 3];
            r[k] = at_k;
            r[kz] = at_kz;
            Vec3::from_array(r)
        };
        [
            row(kx, 1.0, 0.0 - d[kx] * sz),
            row(ky, 1.0, 0.0 - d[ky] * sz),
            row(kz, sz, sz),
        ]
    }

    #[test]
    fn shear_rows_are_those_of_the_indexed_form_bit_for_bit() {
        let mut rng = crate::math::Rng::new(5, 6);
        let mut dirs = vec![
            Vec3::X,
            -Vec3::Y,
            Vec3::Z,
            Vec3::ONE,
            -Vec3::ONE,
            Vec3::new(-0.0, 0.0, 1.0),
        ];
        dirs.extend([
            Vec3::new(1.0, -1.0, 0.0),
            Vec3::new(0.0, 2.0, -2.0),
            Vec3::new(-0.0, -0.0, -0.5),
        ]);
        dirs.extend(
            (0..2000)
                .map(|_| Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0),
        );
        for d in dirs {
            let ray = WatertightRay::new(&Ray::new(Vec3::ZERO, d));
            let bits = |v: Vec3| v.to_array().map(f32::to_bits);
            let got = [ray.shear_x, ray.shear_y, ray.scale_z].map(bits);
            assert_eq!(got, rows_by_index(d).map(bits), "{d}");
        }
    }

    #[test]
    fn t_range_is_inclusive() {
        let tri = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let r = WatertightRay::new(&Ray::new(Vec3::new(0.2, 0.2, 1.0), -Vec3::Z));
        assert!(intersect_triangle(&r, &tri, 1.0, 1.0).is_some());
        assert!(intersect_triangle(&r, &tri, 0.0, 0.999).is_none());
        assert!(intersect_triangle(&r, &tri, 1.001, 2.0).is_none());
    }
}
