use glam::Vec3;

/// A ray with an origin, a direction and a time. The direction is normalised by every constructor in the
/// renderer, so `t` is a distance in world units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Where the ray starts.
    pub origin: Vec3,
    /// Unit-length direction.
    pub dir: Vec3,
    /// The instant the ray samples, in frames relative to the frame being rendered (0 without motion blur;
    /// within the shutter interval with it). Every ray of a path keeps its camera ray's time.
    pub time: f32,
}

impl Ray {
    /// Creates a ray at time 0; `dir` is expected to be unit length.
    pub fn new(origin: Vec3, dir: Vec3) -> Self {
        Self {
            origin,
            dir,
            time: 0.0,
        }
    }

    /// The same ray at time `time` (frames relative to the frame).
    pub fn at_time(self, time: f32) -> Self {
        Self { time, ..self }
    }

    /// The point at distance `t` along the ray.
    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + self.dir * t
    }
}
