use glam::Vec3;

/// A ray with an origin and a direction. The direction is normalised by every constructor in the renderer,
/// so `t` is a distance in world units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Where the ray starts.
    pub origin: Vec3,
    /// Unit-length direction.
    pub dir: Vec3,
}

impl Ray {
    /// Creates a ray; `dir` is expected to be unit length.
    pub fn new(origin: Vec3, dir: Vec3) -> Self {
        Self { origin, dir }
    }

    /// The point at distance `t` along the ray.
    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + self.dir * t
    }
}
