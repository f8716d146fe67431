use glam::Vec3;

/// An orthonormal frame (s, t, n). Local coordinates put `n` on +z, the convention of every BSDF and phase
/// function in Nimbus.
#[derive(Clone, Copy, Debug)]
pub struct Frame {
    /// First tangent.
    pub s: Vec3,
    /// Second tangent.
    pub t: Vec3,
    /// Normal (+z in local coordinates).
    pub n: Vec3,
}

impl Frame {
    /// Builds a frame around a unit normal with the branchless construction of Duff et al. 2017,
    /// "Building an Orthonormal Basis, Revisited" (JCGT 6(1)), listing 3.
    pub fn from_normal(n: Vec3) -> Self {
        let sign = 1.0f32.copysign(n.z);
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        let s = Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
        let t = Vec3::new(b, sign + n.y * n.y * a, -n.y);
        Self { s, t, n }
    }

    /// Builds a frame from a normal and a tangent hint (Gram–Schmidt); falls back to `from_normal` when the
    /// tangent is degenerate.
    pub fn from_normal_tangent(n: Vec3, tangent: Vec3) -> Self {
        let s = tangent - n * n.dot(tangent);
        let len = s.length();
        if len.is_nan() || len <= 1e-6 {
            return Self::from_normal(n);
        }
        let s = s / len;
        Self {
            s,
            t: n.cross(s),
            n,
        }
    }

    /// World direction to local coordinates.
    pub fn to_local(self, v: Vec3) -> Vec3 {
        Vec3::new(v.dot(self.s), v.dot(self.t), v.dot(self.n))
    }

    /// Local direction to world coordinates.
    pub fn to_world(self, v: Vec3) -> Vec3 {
        self.s * v.x + self.t * v.y + self.n * v.z
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_are_orthonormal_and_invertible() {
        for n in [
            Vec3::Z,
            -Vec3::Z,
            Vec3::X,
            Vec3::new(0.3, -0.5, 0.8).normalize(),
        ] {
            let f = Frame::from_normal(n);
            assert!(
                f.s.dot(f.t).abs() < 1e-5 && f.s.dot(f.n).abs() < 1e-5 && f.t.dot(f.n).abs() < 1e-5
            );
            assert!(f.s.cross(f.t).distance(f.n) < 1e-5, "right-handed");
            let v = Vec3::new(0.2, 0.7, -0.1);
            assert!(f.to_world(f.to_local(v)).distance(v) < 1e-5);
        }
    }
}
