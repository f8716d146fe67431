//! Convenience methods for building a scene in code rather than loading it from a file.

use super::{Camera, SceneBuilder, SceneError, SceneErrorKind};
use crate::geometry::Mesh;
use crate::light::{DirectionalLight, Light, PointLight};
use crate::math::{Rgb, Vec3};

/// The name that errors about a programmatic scene give in place of a file path.
pub const BUILDER_PATH: &str = "<scene builder>";

impl SceneBuilder {
    /// An empty builder: no meshes, materials or lights, and a camera framing whatever is added.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds a world-space triangle mesh made of `positions` and counter-clockwise `indices` into them, with the
    /// material at index `material` (as returned by [`add_material`](Self::add_material)). Normals are
    /// generated from the faces. Returns the index of the mesh.
    ///
    /// Fails, adding nothing, when an index is out of range, a position is not finite or the material does
    /// not exist.
    pub fn add_triangle_mesh(
        &mut self,
        positions: Vec<Vec3>,
        indices: Vec<[u32; 3]>,
        material: u32,
    ) -> Result<usize, SceneError> {
        let invalid =
            |what: String| SceneError::new(BUILDER_PATH, SceneErrorKind::InvalidReference(what));
        if material as usize >= self.materials.len() {
            return Err(invalid(format!(
                "material {material} of a mesh, but only {} materials were added",
                self.materials.len()
            )));
        }
        if let Some(i) = indices
            .iter()
            .flatten()
            .find(|&&i| i as usize >= positions.len())
        {
            return Err(invalid(format!(
                "vertex index {i} of a mesh with {} positions",
                positions.len()
            )));
        }
        if !positions.iter().all(|p| p.is_finite()) {
            return Err(SceneError::new(
                BUILDER_PATH,
                SceneErrorKind::Malformed("a mesh position is not finite".into()),
            ));
        }
        self.add_mesh(Mesh {
            name: format!("mesh{}", self.meshes.len()),
            positions,
            indices,
            material,
            ..Mesh::default()
        });
        Ok(self.meshes.len() - 1)
    }

    /// Sets the camera, replacing any from a loaded file.
    pub fn set_camera(&mut self, camera: Camera) {
        self.camera = Some(camera);
    }

    /// Adds a point light at `position` with radiant `intensity` (W/sr per channel).
    pub fn add_point_light(&mut self, position: Vec3, intensity: Rgb) {
        self.add_light(Light::Point(PointLight {
            position,
            intensity,
        }));
    }

    /// Adds a directional light travelling along `direction` (normalised here) with `irradiance` (W/m² per
    /// channel at normal incidence).
    pub fn add_directional_light(&mut self, direction: Vec3, irradiance: Rgb) {
        self.add_light(Light::Directional(DirectionalLight {
            direction: direction.normalize_or(Vec3::NEG_Y),
            irradiance,
        }));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::light::EnvironmentLight;
    use crate::material::Material;
    use crate::scene::DEFAULT_ENVIRONMENT_RADIANCE;

    #[test]
    fn textured_emission_alone_does_not_light_a_scene() {
        let mut b = SceneBuilder::new();
        let tri = || (vec![Vec3::ZERO, Vec3::X, Vec3::Y], vec![[0, 1, 2]]);
        let grey = b.add_material(Material::lambertian("grey", Rgb::splat(0.5)));
        let (p, i) = tri();
        b.add_triangle_mesh(p, i, grey).unwrap();
        assert!(!b.has_own_lighting());
        let mut glow = Material::lambertian("glow", Rgb::splat(0.5));
        glow.emission = Rgb::ONE;
        glow.emission_texture = Some(0);
        let textured = b.add_material(glow.clone());
        let (p, i) = tri();
        b.add_triangle_mesh(p, i, textured).unwrap();
        assert!(!b.has_own_lighting(), "textured emission is detail");
        glow.emission_texture = None;
        let fixture = b.add_material(glow);
        assert!(
            !b.has_own_lighting(),
            "an emissive material that no mesh uses lights nothing"
        );
        let (p, i) = tri();
        b.add_triangle_mesh(p, i, fixture).unwrap();
        assert!(
            b.has_own_lighting(),
            "an untextured emitter is a light fixture"
        );
        let lighting = b.own_lighting();
        assert_eq!(
            (lighting.emissive_meshes, lighting.textured_emissive_meshes),
            (1, 1)
        );
        assert_eq!(lighting.describe(), "1 mesh with untextured emission");
    }

    #[test]
    fn light_by_default_adds_the_white_environment_only_to_an_unlit_scene() {
        let mut unlit = SceneBuilder::new();
        assert!(unlit.light_by_default());
        let env = unlit.build().unwrap();
        match env.environment_light() {
            Some(EnvironmentLight::Constant(c)) => {
                assert_eq!(*c, Rgb::splat(DEFAULT_ENVIRONMENT_RADIANCE))
            }
            other => panic!("expected the constant default environment, got {other:?}"),
        }
        let mut lit = SceneBuilder::new();
        lit.add_point_light(Vec3::Y, Rgb::ONE);
        assert!(
            !lit.light_by_default(),
            "a scene that lights itself is left alone"
        );
        assert!(lit.build().unwrap().environment_light().is_none());
    }

    #[test]
    fn add_triangle_mesh_validates_indices_and_material() {
        let mut b = SceneBuilder::new();
        let tri = vec![Vec3::ZERO, Vec3::X, Vec3::Y];
        assert!(b
            .add_triangle_mesh(tri.clone(), vec![[0, 1, 2]], 0)
            .is_err());
        let m = b.add_material(Material::lambertian("grey", Rgb::splat(0.5)));
        let err = b
            .add_triangle_mesh(tri.clone(), vec![[0, 1, 3]], m)
            .unwrap_err();
        assert!(err.to_string().contains("vertex index 3"), "{err}");
        assert!(b
            .add_triangle_mesh(vec![Vec3::NAN, Vec3::X, Vec3::Y], vec![[0, 1, 2]], m)
            .is_err());
        assert!(b.meshes().is_empty());
        assert_eq!(b.add_triangle_mesh(tri, vec![[0, 1, 2]], m).unwrap(), 0);
        assert_eq!(b.meshes()[0].normals.len(), 3);
        b.add_point_light(Vec3::Y, Rgb::ONE);
        b.add_directional_light(Vec3::ZERO, Rgb::ONE);
        b.set_camera(Camera::look_at(Vec3::Z, Vec3::ZERO, 1.0));
        let scene = b.build().unwrap();
        assert_eq!(scene.triangle_count(), 1);
        assert_eq!(scene.lights().len(), 2);
    }

    /// Meshes handed to `add_mesh` without normals get them from their faces; a dangling index must reach
    /// `build`'s typed error, not panic while the normals are generated (issue 35).
    #[test]
    fn add_mesh_with_a_dangling_index_is_an_error_at_build_not_a_panic() {
        use crate::geometry::{MeshMotion, MotionSteps};
        use crate::math::Vec2;
        let positions = vec![Vec3::ZERO, Vec3::X, Vec3::Y];
        let dangling = Mesh {
            name: "dangling".into(),
            positions: positions.clone(),
            indices: vec![[0, 1, 7]],
            ..Mesh::default()
        };
        let short_step = Mesh {
            name: "short step".into(),
            positions: positions.clone(),
            indices: vec![[0, 1, 2]],
            motion: Some(MeshMotion {
                steps: MotionSteps {
                    count: 2,
                    open: 0.0,
                    close: 1.0,
                },
                positions: vec![positions.clone(), positions[..2].to_vec()],
                normals: Vec::new(),
            }),
            ..Mesh::default()
        };
        let short_uvs = Mesh {
            name: "short uvs".into(),
            positions: positions.clone(),
            uvs: Some(vec![Vec2::ZERO]),
            indices: vec![[0, 1, 2]],
            ..Mesh::default()
        };
        let cases = [
            (dangling, "vertex index 7"),
            (short_step, "motion steps"),
            (short_uvs, "texture coordinates"),
        ];
        for (mesh, names) in cases {
            let mut b = SceneBuilder::new();
            b.add_material(Material::lambertian("grey", Rgb::splat(0.5)));
            b.add_mesh(mesh);
            let err = b.build().err().expect("refused");
            assert!(err.to_string().contains(names), "{err}");
        }
    }

    #[test]
    fn build_refuses_meshes_over_the_memory_budget_before_allocating() {
        use crate::scene::{BYTES_PER_TRIANGLE, BYTES_PER_VERTEX};
        // Room for two triangles and four vertices.
        let limits =
            crate::limits::Limits::with_memory(2 * BYTES_PER_TRIANGLE + 4 * BYTES_PER_VERTEX);
        let mut b = SceneBuilder::with_limits(limits);
        let m = b.add_material(Material::lambertian("grey", Rgb::splat(0.5)));
        let quad = vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::ONE];
        b.add_triangle_mesh(quad.clone(), vec![[0, 1, 2], [1, 3, 2]], m)
            .unwrap();
        assert!(b.check_mesh("one more", 1, 0).is_err());
        assert!(b.check_mesh("one more", 0, 1).is_err());
        b.add_triangle_mesh(quad, vec![[0, 1, 2]], m).unwrap();
        let Err(err) = b.build() else {
            panic!("3 triangles and 8 vertices must not fit a budget of 2 and 4")
        };
        let msg = err.to_string();
        assert!(
            msg.contains("the scene") && msg.contains("--memory-limit"),
            "{msg}"
        );
    }

    #[test]
    fn build_refuses_non_finite_cameras_lights_and_emission() {
        /// A scene part that `build` must refuse, and a word its error names.
        type Case = (&'static str, fn(&mut SceneBuilder));
        let cases: [Case; 4] = [
            ("camera", |b| {
                b.set_camera(Camera::look_at(Vec3::Z, Vec3::ZERO, f32::NAN))
            }),
            ("camera", |b| {
                b.set_camera(Camera::look_at(Vec3::Z, Vec3::ZERO, 4.0))
            }),
            ("light", |b| {
                b.add_point_light(Vec3::Y, Rgb::splat(f32::INFINITY))
            }),
            ("emission", |b| {
                let mut m = Material::lambertian("lamp", Rgb::ONE);
                m.emission = Rgb::splat(f32::NAN);
                b.add_material(m);
            }),
        ];
        for (what, make) in cases {
            let mut b = SceneBuilder::new();
            make(&mut b);
            let err = b.build().err().expect("refused");
            assert!(err.to_string().contains(what), "{err}");
        }
    }
}
