//! UsdGeom intrinsic gprims (`Cube`, `Sphere`, `Cylinder`, `Cone`, `Capsule`, `Plane`), tessellated to meshes
//! with outward normals, counter-clockwise front faces and natural `st` coordinates.
//!
//! Attributes and defaults (UsdGeom schema, `usdGeom/schema.usda`): `Cube.size` 2 (edges at ±size/2);
//! `Sphere.radius` 1; `Cylinder` and `Cone` `radius` 1, `height` 2, `axis` `"Z"` (the cone's base at
//! −height/2, its apex at +height/2; both capped); `Capsule` `radius` 0.5, `height` 1 (the cylindrical part,
//! hemispheres added beyond it), `axis` `"Z"`; `Plane` `width` 2, `length` 2, `axis` `"Z"`, its front face
//! toward +axis (width along X for axis Z or Y, along Z for axis X; length along Y for axis Z or X, along Z for
//! axis Y).

use super::values::token;
use super::Loader;
use crate::geometry::Mesh;
use crate::math::{Mat4, Vec2, Vec3};
use crate::scene::MalformedPart;
use crate::scene::SceneError;
use openusd::{sdf, usd};
use std::f32::consts::{FRAC_PI_2, TAU};

/// Longitude slices of the round gprims.
pub(super) const SEGMENTS: u32 = 64;
/// Latitude bands of a sphere (half as many per capsule hemisphere).
pub(super) const RINGS: u32 = 32;

impl Loader<'_> {
    /// Tessellates the gprim `kind` and adds it with its material (bound, or from `displayColor`).
    pub(super) fn gprim(
        &mut self,
        prim: &usd::Prim,
        kind: &str,
        world: &Mat4,
        binding: Option<&str>,
    ) -> Result<(), SceneError> {
        let at = prim.path().as_str().to_owned();
        let positive = |name: &str, v: f32| {
            if v > 0.0 {
                Ok(v)
            } else {
                Err(self.error(
                    MalformedPart::Mesh,
                    &at,
                    format!("{name} must be positive, is {v}"),
                ))
            }
        };
        let axis = match self.value(prim, "axis")?.and_then(|v| token(&v)) {
            None => Axis::Z,
            Some(a) => match a.as_str() {
                "X" => Axis::X,
                "Y" => Axis::Y,
                "Z" => Axis::Z,
                other => {
                    return Err(self.error(
                        MalformedPart::Mesh,
                        &at,
                        format!("axis '{other}' is not X, Y or Z"),
                    ))
                }
            },
        };
        let shape = match kind {
            "Cube" => Shape::Cube {
                size: positive("size", self.float(prim, "size", 2.0)?)?,
            },
            "Sphere" => Shape::Sphere {
                radius: positive("radius", self.float(prim, "radius", 1.0)?)?,
            },
            "Cylinder" | "Cone" => {
                let radius = positive("radius", self.float(prim, "radius", 1.0)?)?;
                let height = positive("height", self.float(prim, "height", 2.0)?)?;
                if kind == "Cone" {
                    Shape::Cone {
                        radius,
                        height,
                        axis,
                    }
                } else {
                    Shape::Cylinder {
                        radius,
                        height,
                        axis,
                    }
                }
            }
            "Capsule" => Shape::Capsule {
                radius: positive("radius", self.float(prim, "radius", 0.5)?)?,
                height: {
                    let h = self.float(prim, "height", 1.0)?;
                    if h < 0.0 {
                        return Err(self.error(
                            MalformedPart::Mesh,
                            &at,
                            format!("height must not be negative, is {h}"),
                        ));
                    }
                    h
                },
                axis,
            },
            _ => Shape::Plane {
                width: positive("width", self.float(prim, "width", 2.0)?)?,
                length: positive("length", self.float(prim, "length", 2.0)?)?,
                axis,
            },
        };
        let double_sided = self
            .value(prim, "doubleSided")?
            .is_some_and(|v| matches!(v, sdf::Value::Bool(true)));
        let mut mesh = shape.tessellate();
        mesh.name = at;
        mesh.material = self.material(prim, binding, double_sided, false)?;
        mesh.transform(world);
        self.add_mesh(mesh)?;
        Ok(())
    }
}

/// The spine axis of a round gprim, or the normal of a plane.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Axis {
    X,
    Y,
    Z,
}

impl Axis {
    /// The rotation taking the +Z-axis shape to this axis (a cyclic permutation of the coordinates).
    fn along_axis(self, p: Vec3) -> Vec3 {
        match self {
            Axis::Z => p,
            Axis::X => Vec3::new(p.z, p.x, p.y),
            Axis::Y => Vec3::new(p.y, p.z, p.x),
        }
    }

    /// `mesh`, built about +Z, turned to this axis (positions and normals).
    fn orient(self, mut mesh: Mesh) -> Mesh {
        for p in mesh.positions.iter_mut().chain(&mut mesh.normals) {
            *p = self.along_axis(*p);
        }
        mesh
    }
}

/// An intrinsic gprim with its dimensions (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Shape {
    Cube {
        size: f32,
    },
    Sphere {
        radius: f32,
    },
    Cylinder {
        radius: f32,
        height: f32,
        axis: Axis,
    },
    Cone {
        radius: f32,
        height: f32,
        axis: Axis,
    },
    Capsule {
        radius: f32,
        height: f32,
        axis: Axis,
    },
    Plane {
        width: f32,
        length: f32,
        axis: Axis,
    },
}

/// A point of a profile revolved about +Z: radius, height, the outward normal in the (radius, height) plane,
/// and the `t` texture coordinate.
#[derive(Clone, Copy)]
struct ProfilePoint {
    r: f32,
    z: f32,
    n: Vec2,
    t: f32,
}

impl Shape {
    /// The shape as a triangle mesh in its own frame: per-vertex normals, Nimbus texture coordinates
    /// (`v = 1 − t`), counter-clockwise front faces seen from outside.
    pub(super) fn tessellate(self) -> Mesh {
        let mut mesh = match self {
            Shape::Cube { size } => cube(0.5 * size),
            Shape::Sphere { radius } => {
                revolve(&[arc(radius, 0.0, -FRAC_PI_2, FRAC_PI_2, RINGS, 0.0, 1.0)])
            }
            Shape::Cylinder {
                radius,
                height,
                axis,
            } => axis.orient(cylinder(radius, height)),
            Shape::Cone {
                radius,
                height,
                axis,
            } => axis.orient(cone(radius, height)),
            Shape::Capsule {
                radius,
                height,
                axis,
            } => axis.orient(capsule(radius, height)),
            Shape::Plane {
                width,
                length,
                axis,
            } => plane(0.5 * width, 0.5 * length, axis),
        };
        orient_outward(&mut mesh);
        mesh
    }
}

/// A capped cylinder of `radius` and `height` along +Z, centred on the origin.
fn cylinder(radius: f32, height: f32) -> Mesh {
    let h = 0.5 * height;
    let side = |r: f32, z: f32, t: f32| ProfilePoint {
        r,
        z,
        n: Vec2::X,
        t,
    };
    revolve(&[
        cap(radius, -h, -1.0),
        vec![side(radius, -h, 0.0), side(radius, h, 1.0)],
        cap(radius, h, 1.0),
    ])
}

/// A cone of base `radius` and `height` along +Z (apex up), centred on the origin, its base capped.
fn cone(radius: f32, height: f32) -> Mesh {
    let h = 0.5 * height;
    // The side's outward normal is perpendicular to the slant (−radius, height).
    let n = Vec2::new(height, radius).normalize();
    revolve(&[
        cap(radius, -h, -1.0),
        vec![
            ProfilePoint {
                r: radius,
                z: -h,
                n,
                t: 0.0,
            },
            ProfilePoint {
                r: 0.0,
                z: h,
                n,
                t: 1.0,
            },
        ],
    ])
}

/// A capsule of `radius` along +Z, centred on the origin: a cylinder of `height` between two hemispheres.
fn capsule(radius: f32, height: f32) -> Mesh {
    let h = 0.5 * height;
    let total = height + 2.0 * radius;
    let t = |z: f32| (z + h + radius) / total;
    // One strip: the bottom hemisphere's equator joins the top one's, making the cylinder between.
    let mut profile = arc(
        radius,
        -h,
        -FRAC_PI_2,
        0.0,
        RINGS / 2,
        t(-h - radius),
        t(-h),
    );
    profile.extend(arc(
        radius,
        h,
        0.0,
        FRAC_PI_2,
        RINGS / 2,
        t(h),
        t(h + radius),
    ));
    revolve(&[profile])
}

/// A circular arc of the profile: centre height `z`, latitudes `from..=to` (radians, −π/2 at the bottom),
/// `bands` segments, `t` from `t0` to `t1`.
fn arc(radius: f32, z: f32, from: f32, to: f32, bands: u32, t0: f32, t1: f32) -> Vec<ProfilePoint> {
    (0..=bands)
        .map(|i| {
            let f = i as f32 / bands as f32;
            let lat = from + (to - from) * f;
            let n = Vec2::new(lat.cos(), lat.sin());
            ProfilePoint {
                r: radius * n.x,
                z: z + radius * n.y,
                n,
                t: t0 + (t1 - t0) * f,
            }
        })
        .collect()
}

/// A flat disk of the profile at height `z`, facing `sign` (−1 down, +1 up), from the rim to the centre
/// upward-facing or the centre to the rim downward-facing (the order does not matter: triangles are oriented
/// by their normals).
fn cap(radius: f32, z: f32, sign: f32) -> Vec<ProfilePoint> {
    let n = Vec2::new(0.0, sign);
    let t = if sign < 0.0 { 0.0 } else { 1.0 };
    vec![
        ProfilePoint { r: 0.0, z, n, t },
        ProfilePoint { r: radius, z, n, t },
    ]
}

/// Revolves each profile strip about +Z in [`SEGMENTS`] slices (`s` = longitude / 2π, starting at +X).
fn revolve(strips: &[Vec<ProfilePoint>]) -> Mesh {
    let mut mesh = Mesh::default();
    let mut uvs = Vec::new();
    for strip in strips {
        let base = mesh.positions.len() as u32;
        for p in strip {
            for s in 0..=SEGMENTS {
                let phi = TAU * s as f32 / SEGMENTS as f32;
                let (sin, cos) = if s == SEGMENTS {
                    (0.0, 1.0)
                } else {
                    phi.sin_cos()
                };
                mesh.positions.push(Vec3::new(p.r * cos, p.r * sin, p.z));
                mesh.normals
                    .push(Vec3::new(p.n.x * cos, p.n.x * sin, p.n.y).normalize());
                uvs.push(Vec2::new(s as f32 / SEGMENTS as f32, 1.0 - p.t));
            }
        }
        let row = SEGMENTS + 1;
        for i in 0..strip.len().saturating_sub(1) as u32 {
            for s in 0..SEGMENTS {
                let a = base + i * row + s;
                let b = a + row;
                mesh.indices.push([a, a + 1, b + 1]);
                mesh.indices.push([a, b + 1, b]);
            }
        }
    }
    mesh.uvs = Some(uvs);
    mesh
}

/// An axis-aligned cube of half-size `h`: four vertices a face, flat normals, each face's `st` square.
fn cube(h: f32) -> Mesh {
    let mut mesh = Mesh::default();
    let mut uvs = Vec::new();
    for axis in [Vec3::X, Vec3::Y, Vec3::Z] {
        for sign in [-1.0f32, 1.0] {
            let n = axis * sign;
            // Two in-plane directions with u × v = n.
            let u = Vec3::new(axis.y, axis.z, axis.x) * sign;
            let v = n.cross(u);
            let base = mesh.positions.len() as u32;
            for (a, b) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                mesh.positions.push(h * (n + a * u + b * v));
                mesh.normals.push(n);
                uvs.push(Vec2::new(0.5 * (a + 1.0), 0.5 * (1.0 - b)));
            }
            mesh.indices.push([base, base + 1, base + 2]);
            mesh.indices.push([base, base + 2, base + 3]);
        }
    }
    mesh.uvs = Some(uvs);
    mesh
}

/// A plane of half-extents `w` (width) and `l` (length), its front toward +`axis`.
fn plane(w: f32, l: f32, axis: Axis) -> Mesh {
    // (width direction, length direction, normal) per the UsdGeomPlane schema.
    let (du, dv, n) = match axis {
        Axis::Z => (Vec3::X, Vec3::Y, Vec3::Z),
        Axis::Y => (Vec3::X, Vec3::Z, Vec3::Y),
        Axis::X => (Vec3::Z, Vec3::Y, Vec3::X),
    };
    let corners = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)];
    Mesh {
        positions: corners
            .iter()
            .map(|&(a, b)| a * w * du + b * l * dv)
            .collect(),
        normals: vec![n; 4],
        uvs: Some(
            corners
                .iter()
                .map(|&(a, b)| Vec2::new(0.5 * (a + 1.0), 0.5 * (1.0 - b)))
                .collect(),
        ),
        indices: vec![[0, 1, 2], [0, 2, 3]],
        ..Default::default()
    }
}

/// Drops zero-area triangles (at poles and apexes) and winds every other counter-clockwise about its vertex
/// normals, so that the front face is the outside.
fn orient_outward(mesh: &mut Mesh) {
    let (positions, normals) = (&mesh.positions, &mesh.normals);
    mesh.indices.retain_mut(|tri| {
        let [a, b, c] = tri.map(|i| positions[i as usize]);
        let face = (b - a).cross(c - a);
        if face.length_squared() <= 1e-12 * (b - a).length_squared().max(1e-30) {
            return false;
        }
        let n: Vec3 = tri.iter().map(|&i| normals[i as usize]).sum();
        if face.dot(n) < 0.0 {
            tri.swap(1, 2);
        }
        true
    });
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f32::consts::PI;

    /// Surface area and enclosed volume (divergence theorem) of a closed mesh.
    fn area_volume(m: &Mesh) -> (f32, f32) {
        let (mut area, mut volume) = (0.0, 0.0);
        for t in 0..m.indices.len() {
            let [a, b, c] = m.triangle(t);
            area += 0.5 * (b - a).cross(c - a).length();
            volume += a.dot(b.cross(c)) / 6.0;
        }
        (area, volume)
    }

    fn close(got: f32, want: f32, rel: f32, what: &str) {
        assert!(
            (got - want).abs() <= rel * want.abs(),
            "{what}: {got} vs {want}"
        );
    }

    #[test]
    fn tessellations_converge_to_the_closed_forms() {
        let (r, h) = (0.7f32, 1.6f32);
        // A polygon of n sides inscribed in a circle loses ≈ (2π/n)²/6 of the area: 0.16 % at 64 slices.
        let tol = 0.01;
        let (a, v) = area_volume(&Shape::Sphere { radius: r }.tessellate());
        close(a, 4.0 * PI * r * r, tol, "sphere area");
        close(v, 4.0 / 3.0 * PI * r * r * r, tol, "sphere volume");
        for axis in [Axis::X, Axis::Y, Axis::Z] {
            let (a, v) = area_volume(
                &Shape::Cylinder {
                    radius: r,
                    height: h,
                    axis,
                }
                .tessellate(),
            );
            close(a, 2.0 * PI * r * h + 2.0 * PI * r * r, tol, "cylinder area");
            close(v, PI * r * r * h, tol, "cylinder volume");
            let (a, v) = area_volume(
                &Shape::Cone {
                    radius: r,
                    height: h,
                    axis,
                }
                .tessellate(),
            );
            close(a, PI * r * (r + (r * r + h * h).sqrt()), tol, "cone area");
            close(v, PI * r * r * h / 3.0, tol, "cone volume");
            let (a, v) = area_volume(
                &Shape::Capsule {
                    radius: r,
                    height: h,
                    axis,
                }
                .tessellate(),
            );
            close(a, 2.0 * PI * r * h + 4.0 * PI * r * r, tol, "capsule area");
            close(
                v,
                PI * r * r * h + 4.0 / 3.0 * PI * r * r * r,
                tol,
                "capsule volume",
            );
        }
        let cube = Shape::Cube { size: 3.0 }.tessellate();
        let b = cube.bounds();
        assert_eq!((b.min, b.max), (Vec3::splat(-1.5), Vec3::splat(1.5)));
        let (a, v) = area_volume(&cube);
        close(a, 54.0, 1e-6, "cube area");
        close(v, 27.0, 1e-6, "cube volume");
    }

    #[test]
    fn front_faces_point_outward_and_along_the_axis() {
        for axis in [Axis::X, Axis::Y, Axis::Z] {
            let along = axis.along_axis(Vec3::Z);
            let m = Shape::Cylinder {
                radius: 1.0,
                height: 4.0,
                axis,
            }
            .tessellate();
            let b = m.bounds();
            assert!((b.max.dot(along) - 2.0).abs() < 1e-5, "{axis:?} {b:?}");
            for t in 0..m.indices.len() {
                let [a, b, c] = m.triangle(t);
                let centroid = (a + b + c) / 3.0;
                // Outward: a cap (all three corners at one end) faces along ±axis, the side away from the
                // spine.
                let levels = [a, b, c].map(|p| p.dot(along));
                let out = if levels.iter().all(|&l| (l - levels[0]).abs() < 1e-5) {
                    levels[0] * along
                } else {
                    centroid - centroid.dot(along) * along
                };
                assert!((b - a).cross(c - a).dot(out) > 0.0, "{axis:?} triangle {t}");
            }
            let p = Shape::Plane {
                width: 2.0,
                length: 4.0,
                axis,
            }
            .tessellate();
            let [a, b, c] = p.triangle(0);
            assert!((b - a).cross(c - a).normalize().distance(along) < 1e-6);
            let e = p.bounds().max - p.bounds().min;
            // Width along X (axis Z or Y) or Z (axis X); length along Y (axis Z or X) or Z (axis Y).
            let (w, l) = match axis {
                Axis::Z => (e.x, e.y),
                Axis::Y => (e.x, e.z),
                Axis::X => (e.z, e.y),
            };
            assert_eq!((w, l), (2.0, 4.0), "{axis:?}");
        }
        let s = Shape::Sphere { radius: 2.0 }.tessellate();
        for t in 0..s.indices.len() {
            let [a, b, c] = s.triangle(t);
            assert!((b - a).cross(c - a).dot(a + b + c) > 0.0);
        }
    }
}
