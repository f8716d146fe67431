//! Spawning rays off surfaces without self-intersection and without epsilons that can cancel (PBRT 4th ed.,
//! §6.8.5–6.8.6, "Robust Spawned Ray Origins" and "Avoiding Intersections Behind Ray Origins").
//!
//! A computed hit point is off the true surface by at most its rounding error, which we bound per coordinate
//! ([`SurfacePoint::error`]). A ray leaving the surface starts from the point pushed along the geometric normal
//! by the projection of that error box onto the normal, to the side the ray goes, and rounded further away:
//! the origin is then provably on the correct side of the surface, whatever the scale of the scene. The
//! triangle test, for its part, rejects hits closer than its own distance error
//! ([`crate::geometry::triangle::intersect_triangle`]), so the ray cannot re-hit the surface it left.
//!
//! A shadow ray toward a point on a light is a segment between two such offset points: the origin pushed off
//! the receiver toward the light, and the target pushed off the light toward the receiver. Neither offset is
//! measured from the other's un-offset point, so they cannot cancel; the segment then stops a further
//! [`SHADOW_EPSILON`] of its length short of the target.

use crate::math::{gamma, Mat4, Vec3, Vec4};

/// Fraction of a shadow segment's length left out before its (already offset) target, so that the light's own
/// surface, beyond the target, is never reported as a blocker through the rounding of the hit distance.
pub const SHADOW_EPSILON: f32 = 1e-4;

/// A point on a surface (or, with zero error and normal, a free point in space such as a scattering event),
/// with a conservative bound on the absolute rounding error of each coordinate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfacePoint {
    /// The computed position.
    pub p: Vec3,
    /// Bound on `|p − p_exact|` per coordinate.
    pub error: Vec3,
    /// Unit geometric normal of the surface (either side); zero for a point that is on no surface.
    pub n: Vec3,
}

impl SurfacePoint {
    /// A point in space that lies on no surface (a medium scattering event, a point light): rays leave it
    /// from exactly `p`.
    pub fn free(p: Vec3) -> Self {
        Self {
            p,
            error: Vec3::ZERO,
            n: Vec3::ZERO,
        }
    }

    /// The point with barycentrics `(b0, b1, b2)` on the triangle `v` with unit geometric normal `n`, computed
    /// as `b0·v0 + b1·v1 + b2·v2`, with the error bound `γ(7) · Σ|bᵢ·vᵢ|` (PBRT 4th ed., eq. 6.31), which also
    /// covers barycentrics that sum to 1 only up to rounding.
    pub fn on_triangle(v: [Vec3; 3], b0: f32, b1: f32, b2: f32, n: Vec3) -> Self {
        let p = v[0] * b0 + v[1] * b1 + v[2] * b2;
        let abs_sum = (v[0] * b0).abs() + (v[1] * b1).abs() + (v[2] * b2).abs();
        Self {
            p,
            error: abs_sum * gamma(7.0),
            n,
        }
    }

    /// The point carried by the affine transform `m` (an instance's object-to-world matrix; its last row is
    /// taken as `0 0 0 1`), with `n` as its (already transformed, unit) normal. The error bound stays
    /// conservative through the transform (PBRT 4th ed., §6.8.6, "Transformations"): each computed coordinate
    /// `Σⱼ mᵢⱼ pⱼ + tᵢ` is a sum of four terms after one product each, so it rounds within
    /// `γ(4)·(Σⱼ |mᵢⱼ pⱼ| + |tᵢ|)`, and the point's own error `e` reaches it as `(1 + γ(4))·Σⱼ |mᵢⱼ| eⱼ`.
    pub fn transformed(&self, m: &Mat4, n: Vec3) -> Self {
        let p = m.transform_point3(self.p);
        let abs = |v: Vec4| v.truncate().abs();
        let (cx, cy, cz, t) = (abs(m.x_axis), abs(m.y_axis), abs(m.z_axis), abs(m.w_axis));
        let a = self.p.abs();
        let of_point = cx * a.x + cy * a.y + cz * a.z + t;
        let e = self.error;
        let of_error = cx * e.x + cy * e.y + cz * e.z;
        Self {
            p,
            error: of_point * gamma(4.0) + of_error * (1.0 + gamma(4.0)),
            n,
        }
    }

    /// The origin of a ray leaving this point in direction `w`: `p` moved along the normal, to the side `w`
    /// points to, by the normal's projection of the error box, then rounded away from `p` (PBRT 4th ed.,
    /// §6.8.5). A free point returns `p` itself.
    pub fn spawn_origin(&self, w: Vec3) -> Vec3 {
        let d = self.n.abs().dot(self.error);
        if d == 0.0 {
            return self.p;
        }
        let mut offset = self.n * d;
        if w.dot(self.n) < 0.0 {
            offset = -offset;
        }
        let mut origin = self.p + offset;
        for i in 0..3 {
            if offset[i] > 0.0 {
                origin[i] = origin[i].next_up();
            } else if offset[i] < 0.0 {
                origin[i] = origin[i].next_down();
            }
        }
        origin
    }
}

/// A shadow ray: the open segment from `origin` along unit `dir` up to `t_max` (infinite for lights at
/// infinity).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShadowSegment {
    /// Where the segment starts (offset off the receiving surface).
    pub origin: Vec3,
    /// Unit direction.
    pub dir: Vec3,
    /// Distance along `dir` at which the segment ends.
    pub t_max: f32,
}

impl ShadowSegment {
    /// The segment from `from` to the point `to` on a light: both ends offset off their surfaces toward each
    /// other, the end then pulled in by `SHADOW_EPSILON` (10⁻⁴) of the length. `None` when the two offset points
    /// coincide.
    pub fn between(from: &SurfacePoint, to: &SurfacePoint) -> Option<Self> {
        let origin = from.spawn_origin(to.p - from.p);
        let target = to.spawn_origin(origin - to.p);
        let d = target - origin;
        let length = d.length();
        if !(length > 0.0 && length.is_finite()) {
            return None;
        }
        Some(Self {
            origin,
            dir: d / length,
            t_max: length * (1.0 - SHADOW_EPSILON),
        })
    }

    /// The unbounded segment from `from` in unit direction `dir`, toward a light at infinity.
    pub fn toward_infinity(from: &SurfacePoint, dir: Vec3) -> Self {
        Self {
            origin: from.spawn_origin(dir),
            dir,
            t_max: f32::INFINITY,
        }
    }

    /// The point where the segment ends (meaningful for finite segments).
    pub fn end(&self) -> Vec3 {
        self.origin + self.dir * self.t_max
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::triangle::{intersect_triangle, WatertightRay};
    use crate::math::{Ray, Rng};

    /// Spawned rays never re-hit the triangle they leave, at any scale and any angle, while rays sent through
    /// the triangle still hit it.
    #[test]
    fn spawned_rays_never_rehit_their_own_triangle() {
        let mut rng = Rng::for_sample(3, 0, 0);
        for &scale in &[1e-3f32, 1.0, 1e3, 1e5] {
            for &offset in &[0.0f32, 1.0, 1e3] {
                let base = Vec3::new(offset, -offset, 0.5 * offset) * scale;
                let tri = [
                    base + Vec3::new(-1.0, 0.1, -1.0) * scale,
                    base + Vec3::new(1.5, -0.2, -0.7) * scale,
                    base + Vec3::new(0.1, 0.3, 1.2) * scale,
                ];
                let n = (tri[1] - tri[0]).cross(tri[2] - tri[0]).normalize();
                for _ in 0..2000 {
                    let (b1, b2) = {
                        let u = rng.next_2d();
                        if u.x + u.y > 1.0 {
                            (1.0 - u.x, 1.0 - u.y)
                        } else {
                            (u.x, u.y)
                        }
                    };
                    let sp = SurfacePoint::on_triangle(tri, 1.0 - b1 - b2, b1, b2, n);
                    // A direction anywhere on the sphere, grazing ones included.
                    let u = rng.next_2d();
                    let z = 1.0 - 2.0 * u.x;
                    let r = (1.0 - z * z).max(0.0).sqrt();
                    let phi = 2.0 * std::f32::consts::PI * u.y;
                    let w = Vec3::new(r * phi.cos(), r * phi.sin(), z);
                    let o = sp.spawn_origin(w);
                    let ray = WatertightRay::new(&Ray::new(o, w));
                    assert!(
                        intersect_triangle(&ray, &tri, 0.0, f32::INFINITY).is_none(),
                        "scale {scale} offset {offset}: re-hit leaving {:?} along {w}",
                        sp.p
                    );
                }
            }
        }
    }

    /// A point on a triangle carried by a rotating, non-uniformly scaling, translating matrix: the computed
    /// point lies within its error bound of the exact image of the exact barycentric point, computed in f64
    /// (an independent reference), at scales from 10⁻³ to 10⁵.
    #[test]
    fn transformed_error_bound_covers_the_exact_point() {
        let mut rng = Rng::for_sample(7, 0, 0);
        let mut tight = 0.0f64;
        for &scale in &[1e-3f32, 1.0, 1e3, 1e5] {
            for k in 0..2000 {
                let q = crate::math::Quat::from_axis_angle(
                    Vec3::new(rng.next_f32(), rng.next_f32(), 0.5).normalize(),
                    7.0 * rng.next_f32(),
                );
                let s = Vec3::new(0.1 + rng.next_f32(), -0.2 - 3.0 * rng.next_f32(), 2.0);
                let t = Vec3::new(rng.next_f32(), -rng.next_f32(), 0.3) * scale * 10.0;
                let m = Mat4::from_scale_rotation_translation(s, q, t);
                let tri = [0; 3].map(|_| {
                    Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * scale
                        - Vec3::splat(0.5 * scale) * (k % 3) as f32
                });
                let (b1, b2) = (rng.next_f32() * 0.5, rng.next_f32() * 0.5);
                let b0 = 1.0 - b1 - b2;
                let local = SurfacePoint::on_triangle(tri, b0, b1, b2, Vec3::Z);
                let world = local.transformed(&m, Vec3::Z);
                let exact_local = tri[0].as_dvec3() * b0 as f64
                    + tri[1].as_dvec3() * b1 as f64
                    + tri[2].as_dvec3() * b2 as f64;
                let exact = m.as_dmat4().transform_point3(exact_local);
                let off = (world.p.as_dvec3() - exact).abs();
                for a in 0..3 {
                    assert!(
                        off[a] <= world.error[a] as f64,
                        "axis {a}: {} > bound {}",
                        off[a],
                        world.error[a]
                    );
                    if world.error[a] > 0.0 {
                        tight = tight.max(off[a] / world.error[a] as f64);
                    }
                }
            }
        }
        // The bound is not vacuous: some points come within a few hundredths of it.
        assert!(tight > 0.01, "{tight}");
    }

    /// The two ends of a shadow segment lie on the correct sides of their surfaces, and the segment is never
    /// longer than the un-offset distance.
    #[test]
    fn shadow_segment_ends_are_off_both_surfaces() {
        let floor = SurfacePoint {
            p: Vec3::new(3.0, 0.0, 2.0),
            error: Vec3::splat(1e-6),
            n: Vec3::Y,
        };
        let light = SurfacePoint {
            p: Vec3::new(3.0, 0.5, 2.0),
            error: Vec3::splat(1e-6),
            n: -Vec3::Y,
        };
        let s = ShadowSegment::between(&floor, &light).unwrap();
        assert!(s.origin.y > 0.0);
        assert!(s.end().y < 0.5);
        assert!(s.t_max < 0.5);
        assert!(ShadowSegment::between(&floor, &floor).is_none());
        let free = SurfacePoint::free(Vec3::ONE);
        assert_eq!(free.spawn_origin(Vec3::X), Vec3::ONE);
    }
}
