//! Which closed-mesh interior a ray is in: a ray is in the interior it most recently entered and has not yet
//! left, so interiors nest (a medium stack). Position-filled media (VDB volumes) are not on the stack.
//!
//! Camera paths start with the stack of the media around the camera ([`MediumStack::enclosing`]), found as
//! Cycles finds a camera inside a volume: by walking a ray from the camera out of the scene. pbrt-v4 and
//! Mitsuba 3 are told instead (a camera medium, a sensor medium); glTF and USD have no place to say it.

use crate::math::{Ray, Vec3};
use crate::scene::Scene;

/// Deepest nesting of interiors tracked; deeper entries are ignored.
const CAPACITY: usize = 8;

/// The direction of the walk that finds the media around a point: off every axis and diagonal, so that the
/// walk from a point on a symmetry plane of a box does not run along an edge.
const WALK_DIRECTION: Vec3 = Vec3::new(0.267_261_24, 0.534_522_5, 0.801_783_7);

/// Most surfaces the walk crosses before it stops (media beyond are taken as not around the point).
const WALK_MAX_CROSSINGS: usize = 1024;

/// A small fixed-capacity stack of medium indices.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MediumStack {
    entries: [u32; CAPACITY],
    len: usize,
}

impl MediumStack {
    /// The medium the ray is in now, if any.
    pub fn current(&self) -> Option<u32> {
        self.len.checked_sub(1).map(|i| self.entries[i])
    }

    /// The interior media that enclose `point`, outermost first: a ray walked from `point` out of the scene
    /// leaves, before entering it again, every interior the point is in; crossings of an interior entered on
    /// the way out cancel. The innermost medium around the point is the one the walk leaves first. A boundary
    /// that is not closed, or a walk past [`WALK_MAX_CROSSINGS`] surfaces, can miss a medium (it is then not
    /// around the point), never add one that the walk does not leave.
    pub fn enclosing(scene: &Scene, point: Vec3) -> MediumStack {
        let mut ray = Ray::new(point, WALK_DIRECTION);
        let mut entered_on_the_way: Vec<u32> = Vec::new();
        let mut around_innermost_first: Vec<u32> = Vec::new();
        for _ in 0..WALK_MAX_CROSSINGS {
            let Some(hit) = scene.intersect(&ray, 0.0, f32::INFINITY) else {
                break;
            };
            if let Some(medium) = scene.materials[hit.material as usize].interior {
                if WALK_DIRECTION.dot(hit.geometric_normal) < 0.0 {
                    entered_on_the_way.push(medium);
                } else if let Some(i) = entered_on_the_way.iter().rposition(|&m| m == medium) {
                    entered_on_the_way.remove(i);
                } else {
                    around_innermost_first.push(medium);
                }
            }
            ray = Ray::new(hit.spawn_origin(WALK_DIRECTION), WALK_DIRECTION);
        }
        let mut stack = MediumStack::default();
        for &medium in around_innermost_first.iter().rev() {
            stack.cross(medium, true);
        }
        stack
    }

    /// Updates the stack for a ray crossing the boundary of an interior `medium`: entering when `entering`,
    /// leaving otherwise (the most recent entry of that medium is removed).
    pub fn cross(&mut self, medium: u32, entering: bool) {
        if entering {
            if self.len < CAPACITY {
                self.entries[self.len] = medium;
                self.len += 1;
            }
        } else if let Some(i) = self.entries[..self.len].iter().rposition(|&m| m == medium) {
            self.entries.copy_within(i + 1..self.len, i);
            self.len -= 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nested_interiors() {
        let mut s = MediumStack::default();
        assert_eq!(s.current(), None);
        s.cross(1, true);
        s.cross(2, true);
        assert_eq!(s.current(), Some(2));
        s.cross(1, false); // leaving the outer one first (overlapping meshes)
        assert_eq!(s.current(), Some(2));
        s.cross(2, false);
        assert_eq!(s.current(), None);
        s.cross(3, false); // leaving something never entered is ignored
        assert_eq!(s.current(), None);
    }
}
