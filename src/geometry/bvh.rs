//! TEMPORARY brute-force stub until the bvh branch lands.
use crate::math::{Aabb, Ray, Vec3};
/// stub
#[derive(Clone, Copy, Debug)]
pub struct TriangleHit {
    pub t: f32,
    pub prim: u32,
    pub b1: f32,
    pub b2: f32,
}
/// stub
pub struct Bvh {
    tris: Vec<[Vec3; 3]>,
    bounds: Aabb,
}
impl Bvh {
    /// stub
    pub fn build(triangles: &[[Vec3; 3]]) -> Bvh {
        let mut b = Aabb::EMPTY;
        for t in triangles {
            for v in t {
                b = b.extend(*v);
            }
        }
        Bvh {
            tris: triangles.to_vec(),
            bounds: b,
        }
    }
    /// stub
    pub fn intersect(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<TriangleHit> {
        let mut best: Option<TriangleHit> = None;
        let mut tmax = t_max;
        for (i, t) in self.tris.iter().enumerate() {
            let e1 = t[1] - t[0];
            let e2 = t[2] - t[0];
            let p = ray.dir.cross(e2);
            let det = e1.dot(p);
            if det.abs() < 1e-12 {
                continue;
            }
            let inv = 1.0 / det;
            let s = ray.origin - t[0];
            let b1 = s.dot(p) * inv;
            if !(0.0..=1.0).contains(&b1) {
                continue;
            }
            let q = s.cross(e1);
            let b2 = ray.dir.dot(q) * inv;
            if b2 < 0.0 || b1 + b2 > 1.0 {
                continue;
            }
            let tt = e2.dot(q) * inv;
            if tt > t_min && tt < tmax {
                tmax = tt;
                best = Some(TriangleHit {
                    t: tt,
                    prim: i as u32,
                    b1,
                    b2,
                });
            }
        }
        best
    }
    /// stub
    pub fn occluded(&self, ray: &Ray, t_min: f32, t_max: f32) -> bool {
        self.intersect(ray, t_min, t_max).is_some()
    }
    /// stub
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }
    /// stub
    pub fn memory_bytes(&self) -> usize {
        self.tris.len() * 36
    }
    /// stub
    pub fn triangle_count(&self) -> usize {
        self.tris.len()
    }
}
