//! Moving triangles for transform motion blur, stored as vertex motion steps (as Cycles stores deforming
//! meshes): each moving vertex has its world position at `n ≥ 2` instants evenly spaced over the shutter, and a
//! ray at time `t` sees the triangle whose vertices are linearly interpolated between the two steps around `t`
//! ([`MotionSteps::segment`], [`lerp`]).
//!
//! [`MotionBvh`] is the hierarchy over such triangles. It shares the static [`Bvh`](super::Bvh)'s build and
//! traversal; only its boxes and its leaf test differ. A triangle's box is the union of its boxes at every
//! step: a linearly interpolated vertex is a convex combination of two step positions, so it stays inside that
//! union (widened by the interpolation's own rounding, see [`MovingTriangle::bounds`]). The leaf test
//! interpolates the triangle at the ray's time and runs the same watertight test as static triangles, so
//! neighbouring moving triangles stay watertight (a shared vertex interpolates to the same bits in both), and a
//! ray spawned off a moving surface at the same time sees bit for bit the triangle its origin was offset from.
//!
//! A box over all steps is loose for fast or rotating motion (Cycles and pbrt-v4 pay the same price for
//! motion-blurred geometry in a single tree; pbrt-v4's 4D boxes or Embree's linear bounds per time segment are
//! tighter); static triangles stay in their own tree, which motion never slows down.

use super::bvh::{prefetch, PrimRef, Tree, TriangleHierarchy};
use super::triangle::{intersect_triangle, TriangleHit};
use super::TooManyTriangles;
use crate::math::{gamma, Aabb, Ray, Vec3};

/// When the vertex motion steps of a moving mesh are: `count` instants evenly spaced from `open` to `close`
/// (in frames relative to the frame, as [`Ray::time`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotionSteps {
    /// The time of the first step.
    pub open: f32,
    /// The time of the last step (at least `open`).
    pub close: f32,
    /// The number of steps, at least 2.
    pub count: u32,
}

impl MotionSteps {
    /// The steps around `time`: step `i` and the fraction `f` ∈ \[0, 1\] of the way to step `i + 1`. Times
    /// outside `[open, close]` (and a NaN time) hold the nearest end step.
    #[inline(always)]
    pub fn segment(&self, time: f32) -> (usize, f32) {
        let last = self.count.max(2) - 1;
        let span = self.close - self.open;
        let u = if span > 0.0 {
            (time - self.open) / span * last as f32
        } else {
            0.0
        };
        // `max`/`min` drop a NaN, so a NaN time holds the first step.
        let u = u.max(0.0).min(last as f32);
        let i = (u as u32).min(last - 1);
        (i as usize, u - i as f32)
    }
}

/// `a` and `b` mixed as `(1 − f)·a + f·b`: exactly `a` at `f = 0` and `b` at `f = 1`. The one interpolation of
/// motion steps, used by the hierarchy's leaf test and by the hit it reports alike.
#[inline(always)]
pub fn lerp(a: Vec3, b: Vec3, f: f32) -> Vec3 {
    a * (1.0 - f) + b * f
}

/// One moving triangle given to [`MotionBvh::build`]: its three vertices at each motion step.
#[derive(Clone, Debug, PartialEq)]
pub struct MovingTriangle {
    /// When the steps are.
    pub steps: MotionSteps,
    /// The vertices at each step, `steps.count` of them.
    pub vertices: Vec<[Vec3; 3]>,
}

impl MovingTriangle {
    /// The triangle at `time`, interpolated between the steps around it.
    #[inline(always)]
    #[cfg(any(test, feature = "testing"))]
    pub fn at(&self, time: f32) -> [Vec3; 3] {
        interpolate(self.steps, &self.vertices, time)
    }

    /// A box holding the triangle at every time (`None` when a vertex is not finite): the union of its boxes
    /// at the steps, widened by `γ(4)·2·max|coordinate|` per axis, which bounds the rounding of [`lerp`]
    /// (`(1 − f)` and the two products and the sum each round once).
    pub fn bounds(&self) -> Option<Aabb> {
        let finite = self.vertices.iter().flatten().all(|v| v.is_finite());
        if !finite || self.vertices.len() < 2 {
            return None;
        }
        let b = self
            .vertices
            .iter()
            .flatten()
            .fold(Aabb::EMPTY, |b, &v| b.extend(v));
        let pad = b.min.abs().max(b.max.abs()) * (2.0 * gamma(4.0));
        Some(Aabb::new(b.min - pad, b.max + pad))
    }
}

/// The triangle whose step vertices are `vertices` (one triangle per step) at `time`.
#[inline(always)]
fn interpolate(steps: MotionSteps, vertices: &[[Vec3; 3]], time: f32) -> [Vec3; 3] {
    let (i, f) = steps.segment(time);
    let (a, b) = (vertices[i], vertices[i + 1]);
    [
        lerp(a[0], b[0], f),
        lerp(a[1], b[1], f),
        lerp(a[2], b[2], f),
    ]
}

/// A bounding volume hierarchy over moving triangles, hit at each ray's [`Ray::time`] (see the module
/// documentation). Its queries mirror [`Bvh`](super::Bvh)'s, with the same exactness: the closest hit equals
/// testing every triangle, interpolated at the ray's time, in input order.
#[derive(Clone, Debug)]
pub struct MotionBvh {
    /// The hierarchy over the triangles' boxes over all steps.
    tree: Tree,
    /// For each triangle in leaf order: its steps and the index of its first step in `vertices`.
    prims: Vec<(MotionSteps, u32)>,
    /// Every triangle's vertices at its steps, triangle after triangle in leaf order.
    vertices: Vec<[Vec3; 3]>,
}

impl MotionBvh {
    /// Builds the hierarchy over moving triangles (the static [`Bvh`](super::Bvh)'s binned SAH over each
    /// triangle's box over all steps). Triangles with a non-finite vertex, or fewer than two steps, are left
    /// out; more than [`Bvh::MAX_TRIANGLES`](super::Bvh::MAX_TRIANGLES), or more step vertices than 32-bit
    /// indices reach, is an error.
    pub fn build(triangles: &[MovingTriangle]) -> Result<MotionBvh, TooManyTriangles> {
        let refs = triangles
            .iter()
            .enumerate()
            .filter_map(|(i, t)| {
                let usable = t.vertices.len() == t.steps.count as usize;
                Some(PrimRef::new(t.bounds().filter(|_| usable)?, i as u32))
            })
            .collect();
        let tree = Tree::build(refs, triangles.len(), 1)?;
        let mut prims = Vec::with_capacity(tree.prim_ids().len());
        let mut vertices = Vec::new();
        for &id in tree.prim_ids() {
            let t = &triangles[id as usize];
            let first =
                u32::try_from(vertices.len()).map_err(|_| TooManyTriangles(triangles.len()))?;
            prims.push((t.steps, first));
            vertices.extend_from_slice(&t.vertices);
        }
        Ok(MotionBvh {
            tree,
            prims,
            vertices,
        })
    }

    /// Bounds of all (finite) triangles over all their steps.
    pub fn bounds(&self) -> Aabb {
        self.tree.bounds()
    }

    /// Number of triangles given to [`MotionBvh::build`], including any left out.
    pub fn triangle_count(&self) -> usize {
        self.tree.input_count()
    }

    /// Heap and inline bytes held: nodes, input indices, step timings and step vertices.
    #[cfg(any(test, feature = "testing"))]
    pub fn memory_bytes(&self) -> usize {
        std::mem::size_of::<Self>()
            + self.tree.heap_bytes()
            + self.prims.capacity() * std::mem::size_of::<(MotionSteps, u32)>()
            + self.vertices.capacity() * std::mem::size_of::<[Vec3; 3]>()
    }
}

impl TriangleHierarchy for MotionBvh {
    /// The tree's traversal with moving leaves: each triangle interpolated at the ray's time.
    fn query<const ANY_HIT: bool>(
        &self,
        ray: &Ray,
        t_min: f32,
        t_max: f32,
        accept: &impl Fn(&TriangleHit) -> bool,
    ) -> Option<TriangleHit> {
        let time = ray.time;
        self.tree.query::<ANY_HIT>(
            ray,
            t_min,
            t_max,
            &|first, count, r, best| {
                for (i, &prim) in
                    (first..first + count).zip(&self.tree.prim_ids()[first..first + count])
                {
                    let (steps, at) = self.prims[i];
                    let at = at as usize;
                    let tri =
                        interpolate(steps, &self.vertices[at..at + steps.count as usize], time);
                    if let Some((t, b1, b2)) = intersect_triangle(r, &tri, t_min, best.limit()) {
                        if best.offer::<ANY_HIT>(TriangleHit { t, prim, b1, b2 }, accept) {
                            return true;
                        }
                    }
                }
                false
            },
            &|i| {
                let first = self.prims[i].1 as usize;
                prefetch(&self.vertices[first] as *const [Vec3; 3] as *const i8);
            },
        )
    }
}

#[cfg(test)]
mod tests {
    use super::super::bvh::tests::{
        brute_closest_of, random_interval, random_point, random_ray, soup,
    };
    use super::*;
    use crate::math::sampling::uniform_sphere;
    use crate::math::Rng;

    /// Reference: every triangle interpolated at the ray's time, in input order, the first of equally close
    /// hits kept; a triangle with a non-finite vertex at any step is left out, as the build leaves it out.
    fn brute_closest(
        tris: &[MovingTriangle],
        ray: &Ray,
        t_min: f32,
        t_max: f32,
    ) -> Option<TriangleHit> {
        let at_time = tris
            .iter()
            .map(|tri| tri.bounds().map(|_| tri.at(ray.time)));
        brute_closest_of(at_time, ray, t_min, t_max)
    }

    /// Random triangles moving by up to 3 units between steps (2 to 5 steps over the shutter `[-0.5, 0.5]`),
    /// some of them standing still, a few with a non-finite step.
    fn moving_soup(rng: &mut Rng, n: usize) -> Vec<MovingTriangle> {
        soup(rng, n)
            .into_iter()
            .enumerate()
            .map(|(i, tri)| {
                let count = 2 + rng.next_u32() % 4;
                let mut vertices = vec![tri];
                for s in 1..count as usize {
                    let prev = vertices[s - 1];
                    let shift = 3.0 * rng.next_f32() * uniform_sphere(rng.next_2d());
                    let next = match i % 5 {
                        0 => prev,
                        // Deforming: each vertex moves on its own.
                        1 => prev.map(|v| v + shift * uniform_sphere(rng.next_2d())),
                        _ => prev.map(|v| v + shift),
                    };
                    vertices.push(next);
                }
                if i % 97 == 3 {
                    vertices[1][2] = Vec3::NAN;
                }
                MovingTriangle {
                    steps: MotionSteps {
                        open: -0.5,
                        close: 0.5,
                        count,
                    },
                    vertices,
                }
            })
            .collect()
    }

    #[test]
    fn segments_split_the_shutter_evenly_and_hold_outside() {
        let s = MotionSteps {
            open: -0.25,
            close: 0.25,
            count: 3,
        };
        assert_eq!(s.segment(-0.25), (0, 0.0));
        assert_eq!(s.segment(-0.125), (0, 0.5));
        assert_eq!(s.segment(0.0), (1, 0.0));
        assert_eq!(s.segment(0.125), (1, 0.5));
        assert_eq!(s.segment(0.25), (1, 1.0));
        assert_eq!(s.segment(9.0), (1, 1.0));
        assert_eq!(s.segment(-9.0), (0, 0.0));
        assert_eq!(s.segment(f32::NAN), (0, 0.0));
        let instant = MotionSteps {
            open: 0.0,
            close: 0.0,
            count: 2,
        };
        assert_eq!(instant.segment(0.0), (0, 0.0));
        assert_eq!(lerp(Vec3::ONE, Vec3::new(3.0, -1.0, 0.1), 1.0).z, 0.1);
    }

    /// The hierarchy's closest hit at the ray's time equals brute force over the interpolated triangles, bit
    /// for bit, and so does the any-hit query; every hit lies inside its triangle's box over all steps.
    #[test]
    fn moving_soup_matches_brute_force_at_random_times() {
        let mut rng = Rng::new(17, 18);
        let tris = moving_soup(&mut rng, 600);
        let bvh = MotionBvh::build(&tris).unwrap();
        assert_eq!(bvh.triangle_count(), tris.len());
        let mut hits = 0;
        let rays = 4000;
        for k in 0..rays {
            // Times inside the shutter, and a few outside it (held at the end steps).
            let time = -0.6 + 1.2 * rng.next_f32();
            let ray = random_ray(&mut rng, Vec3::splat(-12.0), Vec3::splat(12.0)).at_time(time);
            let (t0, t1) = random_interval(&mut rng);
            let expect = brute_closest(&tris, &ray, t0, t1);
            let got = bvh.intersect(&ray, t0, t1);
            assert_eq!(got, expect, "ray {k}: {ray:?} [{t0}, {t1}]");
            assert_eq!(
                bvh.occluded(&ray, t0, t1),
                expect.is_some(),
                "ray {k}: {ray:?} [{t0}, {t1}]"
            );
            if let Some(h) = got {
                hits += 1;
                let b = tris[h.prim as usize].bounds().unwrap();
                let p = ray.at(h.t);
                let slack = 1e-4 * (1.0 + p.abs().max_element());
                assert!(
                    p.cmpge(b.min - slack).all() && p.cmple(b.max + slack).all(),
                    "ray {k}: hit {p} outside the union box {b:?}"
                );
            }
        }
        assert!(hits > rays / 10 && hits < rays, "{hits}");
    }

    /// A ray that misses every triangle's box over all steps misses the hierarchy at every time.
    #[test]
    fn nothing_is_hit_outside_the_union_bounds() {
        let mut rng = Rng::new(19, 20);
        let tris = moving_soup(&mut rng, 200);
        let bvh = MotionBvh::build(&tris).unwrap();
        let boxes: Vec<Aabb> = tris.iter().filter_map(|t| t.bounds()).collect();
        let mut outside = 0;
        for _ in 0..3000 {
            let o = random_point(&mut rng, Vec3::splat(-30.0), Vec3::splat(30.0));
            let ray = Ray::new(o, uniform_sphere(rng.next_2d())).at_time(rng.next_f32() - 0.5);
            let meets_a_box = boxes.iter().any(|b| {
                let inv = ray.dir.recip();
                let (t0, t1) = ((b.min - o) * inv, (b.max - o) * inv);
                let near = t0.min(t1).max_element().max(0.0);
                let far = t0.max(t1).min_element();
                near <= far * (1.0 + 1e-5)
            });
            if !meets_a_box {
                outside += 1;
                assert!(bvh.intersect(&ray, 0.0, f32::INFINITY).is_none());
                assert!(!bvh.occluded(&ray, 0.0, f32::INFINITY));
            }
        }
        assert!(outside > 100, "{outside}");
    }

    #[test]
    fn a_translating_triangle_is_met_only_while_it_crosses_the_ray() {
        // A unit right triangle moving by 4 along x over the shutter [0, 1]: at y = 0.25 it spans
        // [s, s + 0.75] for a shift s = 4t, so a ray down −z at x = 2.5 meets it for s ∈ [1.75, 2.5], that is
        // for t ∈ [0.4375, 0.625], 18.75 % of the shutter.
        let tri = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let moving = MovingTriangle {
            steps: MotionSteps {
                open: 0.0,
                close: 1.0,
                count: 2,
            },
            vertices: vec![tri, tri.map(|v| v + 4.0 * Vec3::X)],
        };
        let bvh = MotionBvh::build(&[moving]).unwrap();
        let ray = Ray::new(Vec3::new(2.5, 0.25, 1.0), -Vec3::Z);
        let n = 4000;
        let hit = (0..n)
            .filter(|i| {
                let time = (*i as f32 + 0.5) / n as f32;
                bvh.intersect(&ray.at_time(time), 0.0, f32::INFINITY)
                    .is_some()
            })
            .count();
        let fraction = hit as f64 / n as f64;
        assert!((fraction - 0.1875).abs() < 1e-3, "{fraction}");
    }
}
