//! Instancing: a two-level hierarchy. Each unique mesh (a *prototype*) has its own [`Bvh`] over its
//! object-space triangles, built once; the top level is a hierarchy over the *instances*, each a prototype
//! placed by an affine object-to-world transform, boxed by its prototype's box transformed to world space.
//! A ray that reaches an instance leaf is carried into the prototype's object space by the instance's
//! world-to-object transform and traced through the prototype's hierarchy (the two-level scheme of Embree's
//! instances and pbrt-v4's `TransformedPrimitive`; PBRT 4th ed. §7.1.4).
//!
//! The object-space ray keeps the world ray's parameter: its direction is the transformed (not renormalised)
//! world direction, so a hit's `t` is the world distance along the world ray, comparable with every other
//! hit. Its origin is computed as `W·(o − c)`, with `c` the instance's world position and `W` the inverse of the
//! linear part, not as `W·o + w` with `w = −W·c`: far from the world origin the latter cancels two large
//! terms and loses the digits a ray spawned off the instance's surface depends on, while `o − c` is exact
//! near the instance. The transformed origin still carries rounding error; as PBRT 4th ed. §6.8.6 does when it
//! transforms a ray, hits closer than that error's reach along the direction are rejected, so a spawned ray
//! cannot re-hit the surface it leaves through the rounding of the transform (see [`InstanceBvh::query`]).
//!
//! `benches/bvh.rs` (64 instances of a 50,880-triangle sphere, rotated and non-uniformly scaled, against the
//! same 3.26 M triangles flattened into one [`Bvh`]; dev profile on a loaded 2-core machine): 3.9 MiB and 0.04
//! CPU-seconds to build against 188 MiB and 3.05 s, and 1.25–1.31 against 0.67–0.75 million random closest-hit
//! rays per CPU-second (the flattened tree's boxes overlap where the instances do).
//!
//! Hits are reported with a primitive index in the hierarchy's own numbering: instance `i`'s triangles are
//! `first[i] .. first[i] + triangles`, in instance order ([`InstanceBvh::locate`] inverts it). Among hits at
//! exactly the same distance the lowest index wins, as in [`Bvh`].

use super::bvh::{prefetch, PrimRef, Tree, TriangleHierarchy};
use super::triangle::TriangleHit;
use super::{Bvh, TooManyTriangles};
use crate::math::{gamma, Aabb, Mat4, Ray, Vec3};
use glam::Mat3A;

/// One placement of a prototype given to [`InstanceBvh::build`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Instance {
    /// Index of the prototype (in the list given to the build).
    pub prototype: u32,
    /// The affine object-to-world transform (its last row is taken as `0 0 0 1`).
    pub object_to_world: Mat4,
}

/// What a top-level leaf holds: how to carry a ray into the instance's prototype, and where its triangle
/// indices start.
#[derive(Clone, Copy, Debug)]
struct Placement {
    /// The instance's world position (the translation of its object-to-world transform).
    position: Vec3,
    /// The inverse of the object-to-world transform's linear part.
    world_to_object: Mat3A,
    /// The prototype's hierarchy.
    prototype: u32,
    /// Index of the instance's first triangle in the hierarchy's numbering.
    first: u32,
}

/// A two-level bounding volume hierarchy: prototypes' object-space [`Bvh`]s under a top-level hierarchy over
/// their instances (see the module documentation). Its queries are those of every [`TriangleHierarchy`].
#[derive(Clone, Debug)]
pub struct InstanceBvh {
    /// The hierarchy over the instances' world boxes.
    tree: Tree,
    /// One object-space hierarchy per prototype.
    prototypes: Vec<Bvh>,
    /// The instances in leaf order.
    placements: Vec<Placement>,
    /// The first triangle index of each instance, in input order, then the total: `instances + 1` entries.
    first: Vec<u32>,
}

impl InstanceBvh {
    /// Builds the prototypes' hierarchies (each from its object-space triangles), then the top level over
    /// `instances`. An instance whose transform is not finite or not invertible (a scale of zero hides an
    /// object in glTF animations), or whose prototype does not exist, can never be hit and is left out. More
    /// than `u32::MAX` instanced triangles in all, or more instances than [`Bvh::MAX_TRIANGLES`], is an error.
    pub fn build(
        prototypes: &[Vec<[Vec3; 3]>],
        instances: &[Instance],
    ) -> Result<InstanceBvh, TooManyTriangles> {
        let prototypes = prototypes
            .iter()
            .map(|tris| Bvh::build(tris))
            .collect::<Result<Vec<_>, _>>()?;
        let mut first = Vec::with_capacity(instances.len() + 1);
        let mut total = 0u64;
        for inst in instances {
            first.push(total as u32);
            let count = prototypes
                .get(inst.prototype as usize)
                .map_or(0, |p| p.triangle_count() as u64);
            total += count;
            if total > u32::MAX as u64 {
                return Err(TooManyTriangles(total as usize));
            }
        }
        first.push(total as u32);
        let refs = instances
            .iter()
            .enumerate()
            .filter_map(|(i, inst)| {
                let proto = prototypes.get(inst.prototype as usize)?;
                let world = world_box(&proto.bounds(), &inst.object_to_world)?;
                inverse_linear(&inst.object_to_world)?;
                Some(PrimRef::new(world, i as u32))
            })
            .collect();
        let tree = Tree::build(refs, instances.len(), 1)?;
        let placements = tree
            .prim_ids()
            .iter()
            .map(|&id| {
                let inst = &instances[id as usize];
                Placement {
                    position: inst.object_to_world.w_axis.truncate(),
                    world_to_object: inverse_linear(&inst.object_to_world).unwrap_or(Mat3A::ZERO),
                    prototype: inst.prototype,
                    first: first[id as usize],
                }
            })
            .collect();
        Ok(InstanceBvh {
            tree,
            prototypes,
            placements,
            first,
        })
    }

    /// Bounds of every instance that can be hit, in world space.
    pub fn bounds(&self) -> Aabb {
        self.tree.bounds()
    }

    /// Number of triangles of all instances together (each instance counts its prototype's).
    pub fn triangle_count(&self) -> usize {
        self.first.last().copied().unwrap_or(0) as usize
    }

    /// The instance and the prototype triangle of hit index `prim`; `None` past the last.
    pub fn locate(&self, prim: u32) -> Option<(u32, u32)> {
        if prim >= *self.first.last()? {
            return None;
        }
        // The last instance whose first index is at most `prim` (empty instances share their first index
        // with the next one, which this skips).
        let instance = self.first.partition_point(|&f| f <= prim) - 1;
        Some((instance as u32, prim - self.first[instance]))
    }

    /// Heap and inline bytes held: the top level, the placements and every prototype's hierarchy.
    #[cfg(any(test, feature = "testing"))]
    pub fn memory_bytes(&self) -> usize {
        std::mem::size_of::<Self>()
            + self.tree.heap_bytes()
            + self.placements.capacity() * std::mem::size_of::<Placement>()
            + self.first.capacity() * std::mem::size_of::<u32>()
            + self.prototypes.iter().map(Bvh::memory_bytes).sum::<usize>()
    }
}

/// The inverse of the linear part of the affine `m`, if `m` is finite and invertible with a finite inverse.
fn inverse_linear(m: &Mat4) -> Option<Mat3A> {
    let linear = Mat3A::from_mat4(*m);
    let det = linear.determinant();
    if !(m.is_finite() && det != 0.0 && det.is_finite()) {
        return None;
    }
    let inverse = linear.inverse();
    inverse.is_finite().then_some(inverse)
}

/// The world box of an object box under `m`: its eight corners transformed, widened by `γ(4)` of each
/// coordinate's magnitude to cover the transform's rounding (three products and three sums per coordinate).
/// `None` for an empty box or a non-finite result.
fn world_box(object: &Aabb, m: &Mat4) -> Option<Aabb> {
    if object.is_empty() {
        return None;
    }
    let b = object.transformed(m);
    let pad = b.min.abs().max(b.max.abs()) * gamma(4.0);
    let b = Aabb::new(b.min - pad, b.max + pad);
    (b.min.is_finite() && b.max.is_finite()).then_some(b)
}

/// The ray carried into the object space of `place`: origin `W·(o − c)` and direction `W·d` (not
/// renormalised, so distances along it stay the world ray's), and the distance below which a hit may be the
/// rounding of the transformed origin. The subtraction rounds within `γ(1)·|o − c|` and the product within
/// `γ(3)·|W|·|o − c|`, so `γ(5)·|W|·|o − c|` bounds the origin's error per axis; it is projected on the direction
/// as PBRT 4th ed. §6.8.6 offsets transformed rays (`|d|·e / |d|²`).
#[inline(always)]
fn to_object(place: &Placement, ray: &Ray) -> (Ray, f32) {
    let w = &place.world_to_object;
    let v = ray.origin - place.position;
    let origin = *w * v;
    let dir = *w * ray.dir;
    let a = v.abs();
    let error = (w.x_axis.abs() * a.x + w.y_axis.abs() * a.y + w.z_axis.abs() * a.z) * gamma(5.0);
    let reach = dir.abs().dot(Vec3::from(error)) / dir.length_squared();
    (
        Ray {
            origin,
            dir,
            time: ray.time,
        },
        if reach.is_finite() { reach } else { 0.0 },
    )
}

impl TriangleHierarchy for InstanceBvh {
    /// The top level's traversal with instance leaves: each carries the ray into its prototype's object space
    /// ([`to_object`]) and runs the prototype's own query there, with `accept` judging hits by their index in
    /// this hierarchy's numbering.
    fn query<const ANY_HIT: bool>(
        &self,
        ray: &Ray,
        t_min: f32,
        t_max: f32,
        accept: &impl Fn(&TriangleHit) -> bool,
    ) -> Option<TriangleHit> {
        self.tree.query::<ANY_HIT>(
            ray,
            t_min,
            t_max,
            &|first, count, _, best| {
                for place in &self.placements[first..first + count] {
                    let (local, reach) = to_object(place, ray);
                    let proto = &self.prototypes[place.prototype as usize];
                    let numbered = |h: &TriangleHit| TriangleHit {
                        prim: place.first + h.prim,
                        ..*h
                    };
                    let hit =
                        proto.query::<ANY_HIT>(&local, t_min.max(reach), best.limit(), &|h| {
                            accept(&numbered(h))
                        });
                    // The prototype's query has applied `accept` already.
                    if let Some(h) = hit {
                        if best.offer::<ANY_HIT>(numbered(&h), &|_| true) {
                            return true;
                        }
                    }
                }
                false
            },
            &|i| prefetch(&self.placements[i] as *const Placement as *const i8),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::super::bvh::tests::{brute_closest_of, random_interval, random_ray, soup};
    use super::*;
    use crate::geometry::Mesh;
    use crate::math::{Quat, Rng};

    /// Transforms with rotation, non-uniform and mirroring scales and translation.
    fn transforms(rng: &mut Rng, n: usize) -> Vec<Mat4> {
        (0..n)
            .map(|i| {
                let axis = crate::math::sampling::uniform_sphere(rng.next_2d());
                let q = Quat::from_axis_angle(axis, 6.0 * rng.next_f32());
                let mut s = Vec3::new(
                    0.3 + 2.0 * rng.next_f32(),
                    0.3 + 2.0 * rng.next_f32(),
                    0.3 + 2.0 * rng.next_f32(),
                );
                if i % 3 == 0 {
                    s.x = -s.x;
                }
                let t = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 30.0 - 15.0;
                Mat4::from_scale_rotation_translation(s, q, t)
            })
            .collect()
    }

    /// Two prototypes placed 40 times: the two-level hierarchy agrees with testing every instance's
    /// world-space triangles (the flattened scene) on hit or miss, and on the distance within rounding.
    #[test]
    fn instances_agree_with_flattened_triangles() {
        let mut rng = Rng::new(21, 22);
        let protos = vec![soup(&mut rng, 200), soup(&mut rng, 50)];
        let instances: Vec<Instance> = transforms(&mut rng, 40)
            .into_iter()
            .enumerate()
            .map(|(i, m)| Instance {
                prototype: (i % 2) as u32,
                object_to_world: m,
            })
            .collect();
        let bvh = InstanceBvh::build(&protos, &instances).unwrap();
        let flat: Vec<[Vec3; 3]> = instances
            .iter()
            .flat_map(|inst| {
                protos[inst.prototype as usize]
                    .iter()
                    .map(move |t| t.map(|v| inst.object_to_world.transform_point3(v)))
            })
            .collect();
        assert_eq!(bvh.triangle_count(), flat.len());
        let (mut hits, mut disagree, rays) = (0, 0, 4000);
        for _ in 0..rays {
            let ray = random_ray(&mut rng, Vec3::splat(-30.0), Vec3::splat(30.0));
            let (t0, t1) = random_interval(&mut rng);
            let (t0, t1) = (t0 * 5.0, t1 * 5.0);
            let want = brute_closest_of(flat.iter().copied().map(Some), &ray, t0, t1);
            let got = bvh.intersect(&ray, t0, t1);
            assert_eq!(bvh.occluded(&ray, t0, t1), got.is_some());
            match (got, want) {
                (Some(g), Some(w)) => {
                    hits += 1;
                    // Rounding of the transforms can move a hit by a few ulps of the distance; edge-grazing
                    // rays may pick a different, equally close triangle.
                    assert!((g.t - w.t).abs() <= 1e-3 * w.t.max(1.0), "{g:?} vs {w:?}");
                    let (inst, tri) = bvh.locate(g.prim).unwrap();
                    let m = instances[inst as usize].object_to_world;
                    let [a, b, c] = protos[instances[inst as usize].prototype as usize]
                        [tri as usize]
                        .map(|v| m.transform_point3(v));
                    let p = a * (1.0 - g.b1 - g.b2) + b * g.b1 + c * g.b2;
                    assert!(p.distance(ray.at(g.t)) < 1e-3 * (1.0 + g.t), "{p} {g:?}");
                }
                (None, None) => {}
                _ => disagree += 1,
            }
        }
        // Only rays grazing an edge within rounding may differ.
        assert!(hits > rays / 10, "{hits}");
        assert!(disagree <= rays / 500, "{disagree} of {rays}");
    }

    /// A unit sphere (fine tessellation) instanced with scale (2, 0.5, 1), a rotation and a translation: an
    /// ellipsoid. Rays from outside toward its centre hit at the analytic distance of the ellipsoid (to the
    /// tessellation's chord error), and any-hit queries agree.
    #[test]
    fn scaled_sphere_instance_hits_at_the_analytic_ellipsoid() {
        let sphere = Mesh::uv_sphere(Vec3::ZERO, 1.0, 256, 512, 0);
        let tris: Vec<[Vec3; 3]> = (0..sphere.indices.len())
            .map(|t| sphere.triangle(t))
            .collect();
        let scale = Vec3::new(2.0, 0.5, 1.0);
        let rotation = Quat::from_rotation_y(0.7) * Quat::from_rotation_x(-0.3);
        let centre = Vec3::new(3.0, -1.0, 2.0);
        let m = Mat4::from_scale_rotation_translation(scale, rotation, centre);
        let bvh = InstanceBvh::build(
            &[tris],
            &[Instance {
                prototype: 0,
                object_to_world: m,
            }],
        )
        .unwrap();
        let mut rng = Rng::new(5, 6);
        let inv = m.inverse();
        for _ in 0..500 {
            let o = centre + 8.0 * crate::math::sampling::uniform_sphere(rng.next_2d());
            let target = centre
                + rotation * (scale * 0.5 * crate::math::sampling::uniform_sphere(rng.next_2d()));
            let d = (target - o).normalize();
            // The ellipsoid |S⁻¹R⁻¹(x − c)| = 1 along o + t·d: a quadratic in t (f64 for the reference).
            let (lo, ld) = (inv.transform_point3(o), inv.transform_vector3(d));
            let (lo, ld) = (lo.as_dvec3(), ld.as_dvec3());
            let (a, b, c) = (ld.dot(ld), 2.0 * lo.dot(ld), lo.dot(lo) - 1.0);
            let t_exact = (-b - (b * b - 4.0 * a * c).sqrt()) / (2.0 * a);
            let hit = bvh
                .intersect(&Ray::new(o, d), 0.0, f32::INFINITY)
                .expect("a ray toward the inside hits");
            // The chord error of a 256-ring sphere is below 1 − cos(π/256) ≈ 7.5e-5 of the radius (2 at most).
            assert!(
                (hit.t as f64 - t_exact).abs() < 2.0 * 1e-4 + 1e-5 * t_exact,
                "{} vs {t_exact}",
                hit.t
            );
            assert!(bvh.occluded(&Ray::new(o, d), 0.0, f32::INFINITY));
            assert!(!bvh.occluded(&Ray::new(o, d), 0.0, hit.t * 0.99));
        }
    }

    #[test]
    fn empty_and_singular_instances_are_left_out() {
        let tri = vec![[Vec3::ZERO, Vec3::X, Vec3::Y]];
        let instances = [
            Instance {
                prototype: 0,
                object_to_world: Mat4::from_scale(Vec3::ZERO),
            },
            Instance {
                prototype: 7,
                object_to_world: Mat4::IDENTITY,
            },
            Instance {
                prototype: 0,
                object_to_world: Mat4::from_translation(Vec3::Z),
            },
        ];
        let bvh = InstanceBvh::build(&[tri], &instances).unwrap();
        assert_eq!(bvh.triangle_count(), 2);
        assert_eq!(bvh.locate(0), Some((0, 0)));
        assert_eq!(bvh.locate(1), Some((2, 0)));
        assert_eq!(bvh.locate(2), None);
        let hit = bvh
            .intersect(
                &Ray::new(Vec3::new(0.2, 0.2, -1.0), Vec3::Z),
                0.0,
                f32::INFINITY,
            )
            .unwrap();
        assert_eq!((hit.prim, hit.t), (1, 2.0));
    }
}
