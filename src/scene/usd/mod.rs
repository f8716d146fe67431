//! USD loader (`.usd`, `.usda`, `.usdc`, `.usdz`), on top of the `openusd` crate, which parses the three
//! encodings and composes sublayers, references and payloads. Nimbus reads the composed stage at its default
//! time and maps it onto the same scene model as glTF.
//!
//! Stage metadata read: `upAxis` (`"Z"` is rotated −90° about X to Nimbus's +Y up) and `metersPerUnit`
//! (everything is scaled to metres).
//!
//! Prims and attributes read:
//! - every prim: `xformOpOrder` with the ops `translate`, `pivot` (a translate), `scale`, `rotateX/Y/Z`,
//!   `rotateXYZ`/`XZY`/`YXZ`/`YZX`/`ZXY`/`ZYX` (degrees), `orient` (quaternion) and `transform` (matrix4d),
//!   with `!invert!` and `!resetXformStack!`, composed through the hierarchy; `active`; `material:binding`
//!   (inherited by descendants);
//! - `Mesh`: `points`, `faceVertexCounts`, `faceVertexIndices` (polygons triangulated as fans), `normals` /
//!   `primvars:normals` and `primvars:st` (with `interpolation` vertex, varying, faceVarying, uniform or
//!   constant, and `:indices`), `orientation` (`leftHanded` flips the winding), `doubleSided`,
//!   `primvars:displayColor` (the diffuse colour of an unbound mesh);
//! - `Camera` (the first one met): `focalLength`, `horizontalAperture`, `verticalAperture` (yfov from the
//!   vertical aperture, aspect from their ratio); clipping and projection `orthographic` are ignored;
//! - `Material` → `outputs:surface` → a `UsdPreviewSurface` `Shader` (`info:id`): `inputs:diffuseColor`,
//!   `emissiveColor`, `metallic`, `roughness`, `opacity`, `ior`, `normal`, `useSpecularWorkflow` (see
//!   [`preview_surface`] for the mapping); colour and normal inputs may connect to a `UsdUVTexture`
//!   (`inputs:file`, `inputs:sourceColorSpace`);
//! - UsdLux (`inputs:intensity`, `inputs:exposure`, `inputs:color`, `inputs:normalize`): `RectLight`
//!   (`inputs:width`, `inputs:height`), `DiskLight` (`inputs:radius`), `SphereLight` (`inputs:radius`,
//!   `treatAsPoint`), `DistantLight` (`inputs:angle` ignored), `DomeLight` (`inputs:texture:file`);
//! - UsdVol: `Volume` with `field:density` / `field:temperature` relationships to `OpenVDBAsset` prims
//!   (`filePath`, `fieldName`, `fieldIndex`), and the `nimbus:` attributes of [`VolumeSpec`].
//!
//! Lights: the emitted radiance is `color × intensity × 2^exposure`, divided by the light's world-space area
//! when `normalize` is set (UsdLux). Rect and disk lights become one-sided emissive meshes emitting along the
//! −Z axis of their frame; sphere lights become emissive spheres, or with `treatAsPoint` a point light of
//! intensity `L·πr²` (the intensity of a sphere of radiance L). A dome light maps its texture with Nimbus's
//! latitude–longitude contract (see [`crate::light::EnvironmentLight`]: top row +Y, u = 0 toward −Z,
//! u = 0.25 toward +X) after the up-axis correction, so the top row is the stage's up axis; the dome's rotation
//! relative to the stage is ignored (a warning says so). A dome without texture is a constant environment.
//!
//! Asset paths (`filePath`, `inputs:file`, `inputs:texture:file`) resolve relative to the layer that authored
//! them. Prim types Nimbus does not render are listed once each in the warnings.

mod crate_check;

use super::camera::Camera;
use super::{gltf, SceneBuilder, SceneError, SceneErrorKind};
use crate::geometry::Mesh;
use crate::light::{DirectionalLight, EnvironmentLight, EnvironmentMap, Light, PointLight};
use crate::material::{ColorSpace, Material, Texture};
use crate::math::{Mat3, Mat4, Quat, Rgb, Vec2, Vec3};
use crate::volume::VolumeSpec;
use openusd::{ar, sdf, usd};
use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};

/// Deepest prim hierarchy read (guards the recursion).
const MAX_DEPTH: usize = 256;

/// Prim types that carry nothing to render by themselves (grouping, shading networks, volume fields).
const STRUCTURAL_TYPES: &[&str] = &[
    "",
    "Xform",
    "Scope",
    "Material",
    "Shader",
    "NodeGraph",
    "OpenVDBAsset",
    "GeomSubset",
];

/// Loads a USD stage and adds its volumes (see [`read`]).
pub fn load(path: &Path) -> Result<SceneBuilder, SceneError> {
    let (mut builder, volumes) = read(path)?;
    for spec in &volumes {
        builder.add_volume(spec)?;
    }
    Ok(builder)
}

/// Reads a USD stage into a builder, returning the `Volume` prims as [`VolumeSpec`]s not yet added.
///
/// Every `.usdc` layer is bounds-checked before `openusd` parses it (see `crate_check`); `openusd` 0.6 still
/// indexes out of bounds on some damaged `.usdc` files, and such a panic is caught here (a last resort: its
/// message still reaches the panic hook) and returned as a malformed-file error.
pub fn read(path: &Path) -> Result<(SceneBuilder, Vec<VolumeSpec>), SceneError> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| read_stage(path))).unwrap_or_else(
        |panic| {
            let message = panic
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| panic.downcast_ref::<&str>().map(|s| (*s).to_owned()))
                .unwrap_or_default();
            Err(malformed(path, format!("the USD reader failed: {message}")))
        },
    )
}

fn read_stage(path: &Path) -> Result<(SceneBuilder, Vec<VolumeSpec>), SceneError> {
    let stage = open(path)?;
    let mut loader = Loader {
        path,
        stage: &stage,
        builder: SceneBuilder::default(),
        volumes: Vec::new(),
        materials: HashMap::new(),
        textures: HashMap::new(),
        unsupported: HashSet::new(),
        root: Mat4::IDENTITY,
    };
    loader.root = loader.stage_root()?;
    for child in loader.children(&stage.prim("/"))? {
        loader.visit(&child, loader.root, None, 0)?;
    }
    // References and payloads report their errors as the prims that use them are composed.
    composition_errors(path, &stage)?;
    Ok((loader.builder, loader.volumes))
}

/// Opens and composes a stage; any parse or composition error is a [`SceneError`] naming the layer.
fn open(path: &Path) -> Result<usd::Stage, SceneError> {
    std::fs::metadata(path).map_err(|e| SceneError::new(path, SceneErrorKind::Io(e)))?;
    let name = path
        .to_str()
        .ok_or_else(|| malformed(path, "the path is not valid UTF-8".into()))?;
    let stage = usd::Stage::builder()
        .resolver(crate_check::CheckingResolver(ar::DefaultResolver::new()))
        .open(name)
        .map_err(|e| malformed(path, format!("{e:#}")))?;
    composition_errors(path, &stage)?;
    Ok(stage)
}

/// The composition errors met so far (a missing sublayer or referenced layer names it), as one error.
fn composition_errors(path: &Path, stage: &usd::Stage) -> Result<(), SceneError> {
    let errors = stage.composition_errors();
    if errors.is_empty() {
        return Ok(());
    }
    let list: Vec<String> = errors.iter().map(|e| e.to_string()).collect();
    Err(malformed(path, format!("composition: {}", list.join("; "))))
}

fn malformed(path: &Path, message: String) -> SceneError {
    SceneError::new(path, SceneErrorKind::Malformed(message))
}

struct Loader<'a> {
    path: &'a Path,
    stage: &'a usd::Stage,
    builder: SceneBuilder,
    volumes: Vec<VolumeSpec>,
    /// (material prim path, double-sided) → material index.
    materials: HashMap<(String, bool), u32>,
    /// (resolved file, colour space is sRGB) → texture index.
    textures: HashMap<(PathBuf, bool), u32>,
    unsupported: HashSet<String>,
    /// Stage units and up axis to Nimbus's metres and +Y up.
    root: Mat4,
}

impl Loader<'_> {
    fn error(&self, at: &str, message: impl std::fmt::Display) -> SceneError {
        malformed(self.path, format!("{at}: {message}"))
    }

    fn warn(&mut self, message: String) {
        self.builder.warnings.push(message);
    }

    /// The matrix from stage units and axes to Nimbus's metres and +Y up.
    fn stage_root(&self) -> Result<Mat4, SceneError> {
        let meta = |key: &str| {
            self.stage
                .stage_metadata(key)
                .map_err(|e| self.error("stage metadata", format!("{key}: {e:#}")))
        };
        let up = meta("upAxis")?.and_then(|v| token(&v));
        let mpu = meta("metersPerUnit")?
            .and_then(|v| number(&v))
            .unwrap_or(1.0);
        if !(mpu.is_finite() && mpu > 0.0) {
            return Err(self.error(
                "stage metadata",
                format!("metersPerUnit {mpu} must be positive"),
            ));
        }
        let rotate = match up.as_deref() {
            Some("Z") => Mat4::from_rotation_x(-std::f32::consts::FRAC_PI_2),
            _ => Mat4::IDENTITY,
        };
        Ok(rotate * Mat4::from_scale(Vec3::splat(mpu as f32)))
    }

    fn children(&self, prim: &usd::Prim) -> Result<Vec<usd::Prim>, SceneError> {
        prim.children()
            .map_err(|e| self.error(prim.path().as_str(), format!("{e:#}")))
    }

    /// The composed value of attribute `name` on `prim`, if authored.
    fn value(&self, prim: &usd::Prim, name: &str) -> Result<Option<sdf::Value>, SceneError> {
        prim.attribute(name).get::<sdf::Value>().map_err(|e| {
            self.error(
                &format!("{}.{name}", prim.path().as_str()),
                format!("{e:#}"),
            )
        })
    }

    fn float(&self, prim: &usd::Prim, name: &str, default: f32) -> Result<f32, SceneError> {
        match self.value(prim, name)? {
            None => Ok(default),
            Some(v) => number(&v)
                .filter(|x| x.is_finite())
                .map(|x| x as f32)
                .ok_or_else(|| {
                    self.error(
                        &format!("{}.{name}", prim.path().as_str()),
                        "expected a number",
                    )
                }),
        }
    }

    fn color(&self, prim: &usd::Prim, name: &str, default: Rgb) -> Result<Rgb, SceneError> {
        match self.value(prim, name)? {
            None => Ok(default),
            Some(v) => vec3(&v).filter(|c| c.is_finite()).ok_or_else(|| {
                self.error(
                    &format!("{}.{name}", prim.path().as_str()),
                    "expected a colour",
                )
            }),
        }
    }

    fn type_name(&self, prim: &usd::Prim) -> Result<String, SceneError> {
        Ok(prim
            .type_name()
            .map_err(|e| self.error(prim.path().as_str(), format!("{e:#}")))?
            .map(|t| t.as_str().to_owned())
            .unwrap_or_default())
    }

    fn visit(
        &mut self,
        prim: &usd::Prim,
        parent: Mat4,
        binding: Option<String>,
        depth: usize,
    ) -> Result<(), SceneError> {
        let at = prim.path().as_str().to_owned();
        if depth > MAX_DEPTH {
            return Err(self.error(&at, format!("nested deeper than {MAX_DEPTH} levels")));
        }
        if !prim
            .is_active()
            .map_err(|e| self.error(&at, format!("{e:#}")))?
        {
            return Ok(());
        }
        let (local, reset) = self.local_transform(prim)?;
        let world = if reset { local } else { parent * local };
        if !world.is_finite() {
            return Err(self.error(&at, "non-finite transform"));
        }
        let binding = self.binding(prim)?.or(binding);
        let kind = self.type_name(prim)?;
        match kind.as_str() {
            "Mesh" => self.mesh(prim, &world, binding.as_deref())?,
            "Camera" => self.camera(prim, &world)?,
            "RectLight" | "DiskLight" | "SphereLight" | "DistantLight" | "DomeLight" => {
                self.light(prim, &kind, &world)?
            }
            "Volume" => self.volume(prim, &world)?,
            k if STRUCTURAL_TYPES.contains(&k) => {}
            k => {
                if self.unsupported.insert(k.to_owned()) {
                    self.warn(format!(
                        "USD prim type '{k}' is not supported (first at {at}); skipped"
                    ));
                }
            }
        }
        for child in self.children(prim)? {
            self.visit(&child, world, binding.clone(), depth + 1)?;
        }
        Ok(())
    }

    /// The prim's local matrix from its `xformOpOrder`, and whether it resets the parent's transform.
    fn local_transform(&self, prim: &usd::Prim) -> Result<(Mat4, bool), SceneError> {
        let at = prim.path().as_str();
        let Some(order) = self.value(prim, "xformOpOrder")? else {
            return Ok((Mat4::IDENTITY, false));
        };
        let ops =
            tokens(&order).ok_or_else(|| self.error(at, "xformOpOrder must be a token array"))?;
        let mut m = Mat4::IDENTITY;
        let mut reset = false;
        for op in ops {
            if op == "!resetXformStack!" {
                (m, reset) = (Mat4::IDENTITY, true);
                continue;
            }
            let (name, invert) = match op.strip_prefix("!invert!") {
                Some(n) => (n, true),
                None => (op.as_str(), false),
            };
            let value = self
                .value(prim, name)?
                .ok_or_else(|| self.error(at, format!("xformOp '{name}' has no value")))?;
            let op_kind = name.split(':').nth(1).unwrap_or("");
            let mut op_m = xform_op(op_kind, &value).ok_or_else(|| {
                self.error(at, format!("unsupported or malformed xformOp '{name}'"))
            })?;
            if invert {
                op_m = op_m.inverse();
            }
            m *= op_m;
        }
        Ok((m, reset))
    }

    /// The material bound directly to `prim` (`material:binding`), if any.
    fn binding(&self, prim: &usd::Prim) -> Result<Option<String>, SceneError> {
        let targets = prim
            .relationship("material:binding")
            .targets()
            .map_err(|e| self.error(prim.path().as_str(), format!("{e:#}")))?;
        Ok(targets.first().map(|p| p.prim_path().as_str().to_owned()))
    }

    fn mesh(
        &mut self,
        prim: &usd::Prim,
        world: &Mat4,
        binding: Option<&str>,
    ) -> Result<(), SceneError> {
        let at = prim.path().as_str().to_owned();
        let points = match self.value(prim, "points")? {
            Some(v) => {
                vec3_array(&v).ok_or_else(|| self.error(&at, "points must be a point3f[]"))?
            }
            None => return Ok(()),
        };
        let counts = self.int_array(prim, "faceVertexCounts")?;
        let indices = self.int_array(prim, "faceVertexIndices")?;
        let total: usize = counts.iter().map(|&c| c.max(0) as usize).sum();
        if total != indices.len() {
            return Err(self.error(
                &at,
                format!(
                    "faceVertexCounts sum to {total} but faceVertexIndices has {} entries",
                    indices.len()
                ),
            ));
        }
        if let Some(bad) = indices
            .iter()
            .find(|&&i| i < 0 || i as usize >= points.len())
        {
            return Err(self.error(
                &at,
                format!(
                    "face vertex index {bad} is out of range ({} points)",
                    points.len()
                ),
            ));
        }
        if !points.iter().all(|p| p.is_finite()) {
            return Err(self.error(&at, "points must be finite"));
        }
        let normals = self.primvar(prim, &["primvars:normals", "normals"], "vertex", vec3_array)?;
        let uvs = self.primvar(prim, &["primvars:st"], "vertex", vec2_array)?;
        let topology = Topology {
            counts: &counts,
            indices: &indices,
            points: points.len(),
        };
        let normals = normals
            .map(|p| topology.expand(p))
            .transpose()
            .map_err(|m| self.error(&at, m))?;
        let uvs = uvs
            .map(|p| topology.expand(p))
            .transpose()
            .map_err(|m| self.error(&at, m))?;
        let left_handed = self
            .value(prim, "orientation")?
            .and_then(|v| token(&v))
            .is_some_and(|o| o == "leftHanded");
        let double_sided = self
            .value(prim, "doubleSided")?
            .is_some_and(|v| matches!(v, sdf::Value::Bool(true)));
        let material = self.material(prim, binding, double_sided)?;
        // One vertex per face corner: simple, and right for every interpolation.
        let mut mesh = Mesh {
            name: at.clone(),
            material,
            ..Default::default()
        };
        mesh.positions = indices.iter().map(|&i| points[i as usize]).collect();
        mesh.normals = normals.unwrap_or_default();
        mesh.uvs = uvs.map(|st| {
            st.into_iter()
                .map(|t: Vec2| Vec2::new(t.x, 1.0 - t.y))
                .collect()
        });
        let mut start = 0u32;
        for &c in &counts {
            let c = c.max(0) as u32;
            for k in 2..c {
                let tri = [start, start + k - 1, start + k];
                mesh.indices.push(if left_handed {
                    [tri[0], tri[2], tri[1]]
                } else {
                    tri
                });
            }
            start += c;
        }
        mesh.transform(world);
        self.builder.add_mesh(mesh);
        Ok(())
    }

    fn int_array(&self, prim: &usd::Prim, name: &str) -> Result<Vec<i32>, SceneError> {
        match self.value(prim, name)? {
            None => Ok(Vec::new()),
            Some(sdf::Value::IntVec(v)) => Ok(v),
            Some(_) => Err(self.error(
                &format!("{}.{name}", prim.path().as_str()),
                "expected an int[]",
            )),
        }
    }

    /// A primvar's values (from the first of `names` authored), its interpolation and its optional indices.
    fn primvar<T: Copy>(
        &self,
        prim: &usd::Prim,
        names: &[&str],
        default_interpolation: &str,
        convert: fn(&sdf::Value) -> Option<Vec<T>>,
    ) -> Result<Option<Primvar<T>>, SceneError> {
        for name in names {
            let Some(v) = self.value(prim, name)? else {
                continue;
            };
            let at = format!("{}.{name}", prim.path().as_str());
            let values = convert(&v).ok_or_else(|| self.error(&at, "unexpected value type"))?;
            let attr = prim.attribute(*name);
            let interpolation = attr
                .get_metadata::<sdf::Value>("interpolation")
                .map_err(|e| self.error(&at, format!("{e:#}")))?
                .and_then(|v| token(&v))
                .unwrap_or_else(|| default_interpolation.to_owned());
            let indices = match self.value(prim, &format!("{name}:indices"))? {
                Some(sdf::Value::IntVec(ix)) => Some(ix),
                Some(_) => return Err(self.error(&at, "indices must be an int[]")),
                None => None,
            };
            let values = match indices {
                Some(ix) => ix
                    .iter()
                    .map(|&i| usize::try_from(i).ok().and_then(|i| values.get(i).copied()))
                    .collect::<Option<Vec<T>>>()
                    .ok_or_else(|| self.error(&at, "primvar index out of range"))?,
                None => values,
            };
            return Ok(Some(Primvar {
                name: (*name).to_owned(),
                values,
                interpolation,
            }));
        }
        Ok(None)
    }

    fn camera(&mut self, prim: &usd::Prim, world: &Mat4) -> Result<(), SceneError> {
        if self.builder.camera.is_some() {
            return Ok(());
        }
        let focal = self.float(prim, "focalLength", 50.0)?;
        let h = self.float(prim, "horizontalAperture", 20.955)?;
        let v = self.float(prim, "verticalAperture", 15.2908)?;
        if !(focal > 0.0 && h > 0.0 && v > 0.0) {
            return Err(self.error(
                prim.path().as_str(),
                "focalLength and apertures must be positive",
            ));
        }
        if self
            .value(prim, "projection")?
            .and_then(|p| token(&p))
            .is_some_and(|p| p == "orthographic")
        {
            self.warn(format!(
                "camera {}: orthographic projection is not supported; rendered as perspective",
                prim.path().as_str()
            ));
        }
        self.builder.camera = Some(Camera {
            camera_to_world: gltf::rigid(world),
            yfov: 2.0 * (0.5 * v / focal).atan(),
            aspect_ratio: Some(h / v),
        });
        Ok(())
    }

    fn light(&mut self, prim: &usd::Prim, kind: &str, world: &Mat4) -> Result<(), SceneError> {
        let at = prim.path().as_str().to_owned();
        let intensity = self.float(prim, "inputs:intensity", 1.0)?;
        let exposure = self.float(prim, "inputs:exposure", 0.0)?;
        let color = self.color(prim, "inputs:color", Rgb::ONE)?;
        let normalize = matches!(
            self.value(prim, "inputs:normalize")?,
            Some(sdf::Value::Bool(true))
        );
        let radiance = (color * intensity * exposure.exp2()).max(Rgb::ZERO);
        if !radiance.is_finite() {
            return Err(self.error(&at, "light intensity is not finite"));
        }
        let mesh = match kind {
            "RectLight" => {
                let w = 0.5 * self.float(prim, "inputs:width", 1.0)?;
                let h = 0.5 * self.float(prim, "inputs:height", 1.0)?;
                // Counter-clockwise seen from −Z: the front face emits along −Z.
                let positions = vec![
                    Vec3::new(-w, -h, 0.0),
                    Vec3::new(-w, h, 0.0),
                    Vec3::new(w, h, 0.0),
                    Vec3::new(w, -h, 0.0),
                ];
                let uvs = vec![
                    Vec2::new(0.0, 1.0),
                    Vec2::new(0.0, 0.0),
                    Vec2::new(1.0, 0.0),
                    Vec2::new(1.0, 1.0),
                ];
                Mesh {
                    positions,
                    uvs: Some(uvs),
                    indices: vec![[0, 1, 2], [0, 2, 3]],
                    ..Default::default()
                }
            }
            "DiskLight" => disk(self.float(prim, "inputs:radius", 0.5)?, 48),
            "SphereLight" => {
                let r = self.float(prim, "inputs:radius", 0.5)?;
                if matches!(
                    self.value(prim, "treatAsPoint")?,
                    Some(sdf::Value::Bool(true))
                ) {
                    let scale = if normalize {
                        0.25
                    } else {
                        std::f32::consts::PI * r * r
                    };
                    self.builder.lights.push(Light::Point(PointLight {
                        position: world.transform_point3(Vec3::ZERO),
                        intensity: radiance * scale,
                    }));
                    return Ok(());
                }
                Mesh::uv_sphere(Vec3::ZERO, r, 16, 32, 0)
            }
            "DistantLight" => {
                if self.float(prim, "inputs:angle", 0.53)? > 0.0 {
                    self.warn(format!(
                        "{at}: DistantLight inputs:angle is ignored (a delta directional light)"
                    ));
                }
                self.builder
                    .lights
                    .push(Light::Directional(DirectionalLight {
                        direction: world.transform_vector3(-Vec3::Z).normalize_or(-Vec3::Y),
                        irradiance: radiance,
                    }));
                return Ok(());
            }
            _ => return self.dome(prim, radiance, world),
        };
        let mut mesh = mesh;
        mesh.name = at.clone();
        mesh.transform(world);
        let area: f32 = (0..mesh.indices.len())
            .map(|t| {
                let [a, b, c] = mesh.triangle(t);
                0.5 * (b - a).cross(c - a).length()
            })
            .sum();
        let emission = if normalize {
            if area <= 0.0 {
                return Err(self.error(&at, "a normalized light must have a positive area"));
            }
            radiance / area
        } else {
            radiance
        };
        let mut material = Material::lambertian(&at, Rgb::ZERO);
        material.emission = emission;
        mesh.material = self.builder.add_material(material);
        self.builder.add_mesh(mesh);
        Ok(())
    }

    fn dome(&mut self, prim: &usd::Prim, radiance: Rgb, world: &Mat4) -> Result<(), SceneError> {
        let at = prim.path().as_str().to_owned();
        let rotation = Mat4::from_mat3(Mat3::from_mat4(self.root.inverse() * *world))
            .to_scale_rotation_translation()
            .1;
        if rotation.angle_between(Quat::IDENTITY) > 1e-3 {
            self.warn(format!(
                "{at}: the DomeLight's rotation is ignored (Nimbus's lat-long orientation)"
            ));
        }
        let env = match self.asset(prim, "inputs:texture:file")? {
            Some(file) => {
                if (radiance.x - radiance.y).abs() > 1e-6 || (radiance.y - radiance.z).abs() > 1e-6
                {
                    self.warn(format!(
                        "{at}: a textured DomeLight's colour is ignored (only its luminous scale)"
                    ));
                }
                let scale = radiance.max_element();
                let map = EnvironmentMap::load(&file, scale)
                    .map_err(|m| SceneError::new(&file, SceneErrorKind::InvalidReference(m)))?;
                EnvironmentLight::Map(Box::new(map))
            }
            None => EnvironmentLight::Constant(radiance),
        };
        self.builder.set_environment(env);
        Ok(())
    }

    /// The file an asset-valued attribute names, resolved against the layer that authored it.
    fn asset(&self, prim: &usd::Prim, name: &str) -> Result<Option<PathBuf>, SceneError> {
        let at = format!("{}.{name}", prim.path().as_str());
        let file = match self.value(prim, name)? {
            None => return Ok(None),
            Some(sdf::Value::AssetPath(a)) => a.asset_path().to_owned(),
            Some(sdf::Value::String(s)) => s,
            Some(_) => return Err(self.error(&at, "expected an asset path")),
        };
        if file.is_empty() {
            return Ok(None);
        }
        let stack = prim
            .attribute(name)
            .property_stack()
            .map_err(|e| self.error(&at, format!("{e:#}")))?;
        let base = stack
            .first()
            .map(|(layer, _)| PathBuf::from(layer))
            .and_then(|l| l.parent().map(Path::to_path_buf))
            .or_else(|| self.path.parent().map(Path::to_path_buf))
            .unwrap_or_default();
        Ok(Some(base.join(file)))
    }

    /// The material index for a mesh: the bound `UsdPreviewSurface`, else one from `primvars:displayColor`.
    fn material(
        &mut self,
        prim: &usd::Prim,
        binding: Option<&str>,
        double_sided: bool,
    ) -> Result<u32, SceneError> {
        let key = match binding {
            Some(b) => b.to_owned(),
            None => {
                let color = match self.value(prim, "primvars:displayColor")? {
                    Some(v) => vec3(&v).or_else(|| vec3_array(&v).and_then(|c| c.first().copied())),
                    None => None,
                }
                .unwrap_or(Rgb::splat(0.18));
                let mut m = preview_defaults(prim.path().as_str());
                m.base_color = color.clamp(Rgb::ZERO, Rgb::ONE).extend(1.0);
                m.double_sided = double_sided;
                return Ok(self.builder.add_material(m));
            }
        };
        if let Some(&id) = self.materials.get(&(key.clone(), double_sided)) {
            return Ok(id);
        }
        let mut m = self.preview_surface(&key)?;
        m.double_sided = double_sided;
        let id = self.builder.add_material(m);
        self.materials.insert((key, double_sided), id);
        Ok(id)
    }

    /// Maps the `UsdPreviewSurface` behind material prim `path` onto a [`Material`]:
    /// diffuseColor → base colour (default 0.18), metallic (0), roughness (0.5), emissiveColor → emission,
    /// ior (1.5), opacity (1) → transmission 1 − opacity; glTF's default specular layer is kept
    /// (UsdPreviewSurface has no specular factor: a diffuse material with metallic 0 still has a dielectric
    /// coat of the given ior); `useSpecularWorkflow` 1 is read as metallic 0 with a warning.
    fn preview_surface(&mut self, path: &str) -> Result<Material, SceneError> {
        let material = self.stage.prim(path);
        let mut m = preview_defaults(path);
        let surface = material
            .attribute("outputs:surface")
            .connections()
            .map_err(|e| self.error(path, format!("{e:#}")))?;
        let Some(shader_path) = surface.first().map(|p| p.prim_path()) else {
            self.warn(format!(
                "material {path} has no outputs:surface; default surface used"
            ));
            return Ok(m);
        };
        let shader = self.stage.prim(shader_path.as_str());
        let id = self
            .value(&shader, "info:id")?
            .and_then(|v| token(&v))
            .unwrap_or_default();
        if id != "UsdPreviewSurface" {
            self.warn(format!(
                "material {path}: shader '{id}' is not UsdPreviewSurface; default surface used"
            ));
            return Ok(m);
        }
        let (diffuse, diffuse_tex) =
            self.color_input(&shader, "inputs:diffuseColor", Rgb::splat(0.18), true)?;
        m.base_color = diffuse.clamp(Rgb::ZERO, Rgb::ONE).extend(1.0);
        m.base_color_texture = diffuse_tex;
        let (emission, emission_tex) =
            self.color_input(&shader, "inputs:emissiveColor", Rgb::ZERO, true)?;
        m.emission = emission.max(Rgb::ZERO);
        m.emission_texture = emission_tex;
        m.metallic = self.scalar_input(&shader, "inputs:metallic", 0.0)?;
        m.roughness = self.scalar_input(&shader, "inputs:roughness", 0.5)?;
        m.ior = self.scalar_input(&shader, "inputs:ior", 1.5)?;
        m.transmission = (1.0 - self.scalar_input(&shader, "inputs:opacity", 1.0)?).clamp(0.0, 1.0);
        m.normal_texture = self
            .texture_of(&shader, "inputs:normal", false)?
            .map(|t| (t, 1.0));
        let specular_workflow = match self.value(&shader, "inputs:useSpecularWorkflow")? {
            Some(v) => number(&v).unwrap_or(0.0) != 0.0,
            None => false,
        };
        if specular_workflow {
            m.metallic = 0.0;
            self.warn(format!(
                "material {path}: useSpecularWorkflow is not supported; read as metallic 0"
            ));
        }
        Ok(m)
    }

    /// A scalar shader input; a texture connection is reported and its fallback value used.
    fn scalar_input(
        &mut self,
        shader: &usd::Prim,
        name: &str,
        default: f32,
    ) -> Result<f32, SceneError> {
        if self.connection(shader, name)?.is_some() {
            self.warn(format!(
                "{}.{name}: textured scalar inputs are not supported; value used",
                shader.path().as_str()
            ));
        }
        self.float(shader, name, default)
    }

    /// A colour shader input: its value, or white and a texture when it connects to a `UsdUVTexture`.
    fn color_input(
        &mut self,
        shader: &usd::Prim,
        name: &str,
        default: Rgb,
        srgb: bool,
    ) -> Result<(Rgb, Option<u32>), SceneError> {
        match self.texture_of(shader, name, srgb)? {
            Some(t) => Ok((Rgb::ONE, Some(t))),
            None => Ok((self.color(shader, name, default)?, None)),
        }
    }

    /// The prim an input connects to, if any.
    fn connection(&self, shader: &usd::Prim, name: &str) -> Result<Option<usd::Prim>, SceneError> {
        let targets = shader
            .attribute(name)
            .connections()
            .map_err(|e| self.error(shader.path().as_str(), format!("{e:#}")))?;
        Ok(targets
            .first()
            .map(|p| self.stage.prim(p.prim_path().as_str())))
    }

    /// The texture a shader input reads through a `UsdUVTexture`, loaded once per file and colour space.
    fn texture_of(
        &mut self,
        shader: &usd::Prim,
        name: &str,
        srgb_default: bool,
    ) -> Result<Option<u32>, SceneError> {
        let Some(tex) = self.connection(shader, name)? else {
            return Ok(None);
        };
        let Some(file) = self.asset(&tex, "inputs:file")? else {
            return Ok(None);
        };
        let srgb = match self
            .value(&tex, "inputs:sourceColorSpace")?
            .and_then(|v| token(&v))
            .as_deref()
        {
            Some("raw") => false,
            Some("sRGB") => true,
            _ => srgb_default,
        };
        if let Some(&id) = self.textures.get(&(file.clone(), srgb)) {
            return Ok(Some(id));
        }
        let image = image::open(&file)
            .map_err(|e| SceneError::new(&file, SceneErrorKind::InvalidReference(e.to_string())))?
            .to_rgba8();
        let space = if srgb {
            ColorSpace::Srgb
        } else {
            ColorSpace::Linear
        };
        let t = Texture::from_rgba8(
            image.width() as usize,
            image.height() as usize,
            image.as_raw(),
            space,
        )
        .ok_or_else(|| SceneError::new(&file, SceneErrorKind::Malformed("empty image".into())))?;
        self.builder.textures.push(t);
        let id = (self.builder.textures.len() - 1) as u32;
        self.textures.insert((file, srgb), id);
        Ok(Some(id))
    }

    fn volume(&mut self, prim: &usd::Prim, world: &Mat4) -> Result<(), SceneError> {
        let at = prim.path().as_str().to_owned();
        let mut fields = Vec::new();
        for name in ["field:density", "field:temperature"] {
            let targets = prim
                .relationship(name)
                .targets()
                .map_err(|e| self.error(&at, format!("{e:#}")))?;
            let field = match targets.first() {
                Some(t) => {
                    let asset = self.stage.prim(t.prim_path().as_str());
                    let kind = self.type_name(&asset)?;
                    if kind != "OpenVDBAsset" {
                        return Err(self.error(
                            &at,
                            format!("{name} targets a '{kind}', not an OpenVDBAsset"),
                        ));
                    }
                    let file = self
                        .asset(&asset, "filePath")?
                        .ok_or_else(|| self.error(asset.path().as_str(), "filePath is required"))?;
                    let grid = self
                        .value(&asset, "fieldName")?
                        .and_then(|v| token(&v))
                        .unwrap_or_else(|| name["field:".len()..].to_owned());
                    if self.float(&asset, "fieldIndex", 0.0)? != 0.0 {
                        self.warn(format!(
                            "{}: fieldIndex is ignored (the grid is found by name)",
                            asset.path().as_str()
                        ));
                    }
                    Some((file, grid))
                }
                None => None,
            };
            fields.push(field);
        }
        let (Some((file, density_grid)), temperature) = (fields[0].clone(), fields[1].clone())
        else {
            self.warn(format!(
                "{at}: Volume without a field:density relationship; skipped"
            ));
            return Ok(());
        };
        let mut spec = VolumeSpec::new(&at, file.clone(), *world);
        spec.density_grid = density_grid;
        if let Some((t_file, t_grid)) = temperature {
            if t_file != file {
                return Err(self.error(
                    &at,
                    "density and temperature fields must come from the same VDB file",
                ));
            }
            spec.temperature_grid = Some(t_grid);
        }
        spec.density_scale = self.float(prim, "nimbus:density_scale", spec.density_scale)?;
        spec.albedo = match self.value(prim, "nimbus:albedo")? {
            None => spec.albedo,
            Some(v) => vec3(&v)
                .or_else(|| number(&v).map(|a| Rgb::splat(a as f32)))
                .ok_or_else(|| self.error(&at, "nimbus:albedo must be a color3f or a float"))?,
        };
        spec.anisotropy = self.float(prim, "nimbus:anisotropy", spec.anisotropy)?;
        spec.emission_scale = self.float(prim, "nimbus:emission_scale", spec.emission_scale)?;
        spec.temperature_scale =
            self.float(prim, "nimbus:temperature_scale", spec.temperature_scale)?;
        spec.temperature_offset =
            self.float(prim, "nimbus:temperature_offset", spec.temperature_offset)?;
        spec.validate().map_err(|m| self.error(&at, m))?;
        self.volumes.push(spec);
        Ok(())
    }
}

/// The UsdPreviewSurface defaults on Nimbus's material model (see `Loader::preview_surface`).
fn preview_defaults(name: &str) -> Material {
    Material {
        name: name.to_owned(),
        base_color: Rgb::splat(0.18).extend(1.0),
        metallic: 0.0,
        roughness: 0.5,
        ..Material::default()
    }
}

/// A primvar's values after `:indices` were applied, and its interpolation.
struct Primvar<T> {
    /// The attribute's name, for messages.
    name: String,
    values: Vec<T>,
    interpolation: String,
}

/// A polygon mesh's topology, for expanding primvars to one value per face corner.
struct Topology<'a> {
    counts: &'a [i32],
    indices: &'a [i32],
    points: usize,
}

impl Topology<'_> {
    /// One value per face corner, from any interpolation.
    fn expand<T: Copy>(&self, p: Primvar<T>) -> Result<Vec<T>, String> {
        let need = |n: usize| {
            if p.values.len() < n {
                Err(format!(
                    "{}: {} interpolation needs {n} values, has {}",
                    p.name,
                    p.interpolation,
                    p.values.len()
                ))
            } else {
                Ok(())
            }
        };
        match p.interpolation.as_str() {
            "constant" => {
                need(1)?;
                Ok(vec![p.values[0]; self.indices.len()])
            }
            "uniform" => {
                need(self.counts.len())?;
                Ok(self
                    .counts
                    .iter()
                    .enumerate()
                    .flat_map(|(f, &c)| std::iter::repeat_n(p.values[f], c.max(0) as usize))
                    .collect())
            }
            "faceVarying" => {
                need(self.indices.len())?;
                Ok(p.values[..self.indices.len()].to_vec())
            }
            "vertex" | "varying" => {
                need(self.points)?;
                Ok(self.indices.iter().map(|&i| p.values[i as usize]).collect())
            }
            other => Err(format!("{}: unknown interpolation '{other}'", p.name)),
        }
    }
}

/// A disk of radius `r` in the XY plane, its front face toward −Z.
fn disk(r: f32, segments: u32) -> Mesh {
    let mut positions = vec![Vec3::ZERO];
    for s in 0..segments {
        let phi = -2.0 * std::f32::consts::PI * s as f32 / segments as f32;
        positions.push(Vec3::new(r * phi.cos(), r * phi.sin(), 0.0));
    }
    let indices = (0..segments)
        .map(|s| [0, 1 + s, 1 + (s + 1) % segments])
        .collect();
    Mesh {
        positions,
        indices,
        ..Default::default()
    }
}

/// The matrix of one xform op (`op` is the op type, e.g. `rotateXYZ`), or `None` for an unknown op or a
/// value of the wrong type.
fn xform_op(op: &str, value: &sdf::Value) -> Option<Mat4> {
    let rot = |axis: char, degrees: f32| {
        let a = degrees.to_radians();
        match axis {
            'X' => Mat4::from_rotation_x(a),
            'Y' => Mat4::from_rotation_y(a),
            _ => Mat4::from_rotation_z(a),
        }
    };
    match op {
        "translate" | "pivot" => Some(Mat4::from_translation(vec3(value)?)),
        "scale" => Some(Mat4::from_scale(vec3(value)?)),
        "rotateX" | "rotateY" | "rotateZ" => Some(rot(op.chars().last()?, number(value)? as f32)),
        "orient" => {
            let q = match value {
                sdf::Value::Quatf(q) => Quat::from_xyzw(q.x, q.y, q.z, q.w),
                sdf::Value::Quatd(q) => {
                    Quat::from_xyzw(q.x as f32, q.y as f32, q.z as f32, q.w as f32)
                }
                sdf::Value::Quath(q) => {
                    Quat::from_xyzw(q.x.to_f32(), q.y.to_f32(), q.z.to_f32(), q.w.to_f32())
                }
                _ => return None,
            };
            let len = q.length();
            (len.is_finite() && len > 0.0).then(|| Mat4::from_quat(q / len))
        }
        "transform" => match value {
            // USD matrices are row-major for row vectors: the same memory layout as glam's column-major.
            sdf::Value::Matrix4d(m) => Some(Mat4::from_cols_array(&m.0.map(|x| x as f32))),
            _ => None,
        },
        _ => {
            let axes = op.strip_prefix("rotate")?;
            if axes.len() != 3 || !axes.chars().all(|c| matches!(c, 'X' | 'Y' | 'Z')) {
                return None;
            }
            let angles = vec3(value)?;
            // rotateABC rotates about A first, then B, then C.
            let mut m = Mat4::IDENTITY;
            for (i, axis) in axes.chars().enumerate() {
                m = rot(axis, angles[i]) * m;
            }
            Some(m)
        }
    }
}

/// A number from any scalar numeric value.
fn number(v: &sdf::Value) -> Option<f64> {
    match v {
        sdf::Value::Float(x) => Some(*x as f64),
        sdf::Value::Double(x) => Some(*x),
        sdf::Value::Half(x) => Some(x.to_f64()),
        sdf::Value::Int(x) => Some(*x as f64),
        sdf::Value::Int64(x) => Some(*x as f64),
        sdf::Value::Uint(x) => Some(*x as f64),
        sdf::Value::Bool(b) => Some(*b as u8 as f64),
        _ => None,
    }
}

/// A token or string.
fn token(v: &sdf::Value) -> Option<String> {
    match v {
        sdf::Value::Token(t) => Some(t.as_str().to_owned()),
        sdf::Value::String(s) => Some(s.clone()),
        _ => None,
    }
}

fn tokens(v: &sdf::Value) -> Option<Vec<String>> {
    match v {
        sdf::Value::TokenVec(t) => Some(t.iter().map(|t| t.as_str().to_owned()).collect()),
        sdf::Value::StringVec(s) => Some(s.clone()),
        _ => None,
    }
}

fn vec3(v: &sdf::Value) -> Option<Vec3> {
    match v {
        sdf::Value::Vec3f(a) => Some(Vec3::new(a.x, a.y, a.z)),
        sdf::Value::Vec3d(a) => Some(Vec3::new(a.x as f32, a.y as f32, a.z as f32)),
        sdf::Value::Vec3h(a) => Some(Vec3::new(a.x.to_f32(), a.y.to_f32(), a.z.to_f32())),
        _ => None,
    }
}

fn vec3_array(v: &sdf::Value) -> Option<Vec<Vec3>> {
    match v {
        sdf::Value::Vec3fVec(a) => Some(a.iter().map(|a| Vec3::new(a.x, a.y, a.z)).collect()),
        sdf::Value::Vec3dVec(a) => Some(
            a.iter()
                .map(|a| Vec3::new(a.x as f32, a.y as f32, a.z as f32))
                .collect(),
        ),
        sdf::Value::Vec3hVec(a) => Some(
            a.iter()
                .map(|a| Vec3::new(a.x.to_f32(), a.y.to_f32(), a.z.to_f32()))
                .collect(),
        ),
        _ => None,
    }
}

fn vec2_array(v: &sdf::Value) -> Option<Vec<Vec2>> {
    match v {
        sdf::Value::Vec2fVec(a) => Some(a.iter().map(|a| Vec2::new(a.x, a.y)).collect()),
        sdf::Value::Vec2dVec(a) => Some(
            a.iter()
                .map(|a| Vec2::new(a.x as f32, a.y as f32))
                .collect(),
        ),
        sdf::Value::Vec2hVec(a) => Some(
            a.iter()
                .map(|a| Vec2::new(a.x.to_f32(), a.y.to_f32()))
                .collect(),
        ),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rotate_xyz_applies_x_first() {
        let v = sdf::Value::Vec3f([90.0, 90.0, 0.0].into());
        let m = xform_op("rotateXYZ", &v).unwrap();
        // X by 90 takes +Y to +Z, then Y by 90 takes +Z to +X.
        assert!(m.transform_vector3(Vec3::Y).distance(Vec3::X) < 1e-6);
        let zyx = xform_op("rotateZYX", &v).unwrap();
        // Y by 90 takes +Y to +Y, then X by 90 takes +Y to +Z.
        assert!(zyx.transform_vector3(Vec3::Y).distance(Vec3::Z) < 1e-6);
        assert!(xform_op("rotateXYW", &v).is_none());
        assert!(xform_op("translate", &sdf::Value::Float(1.0)).is_none());
    }

    #[test]
    fn usd_matrices_keep_translation_in_the_last_row() {
        let mut a = [0.0f64; 16];
        for i in 0..4 {
            a[i * 5] = 1.0;
        }
        a[12..15].copy_from_slice(&[1.0, 2.0, 3.0]);
        let v = sdf::Value::Matrix4d(openusd::gf::Matrix4d(a));
        let m = xform_op("transform", &v).unwrap();
        assert_eq!(m.transform_point3(Vec3::ZERO), Vec3::new(1.0, 2.0, 3.0));
    }

    #[test]
    fn primvars_expand_to_face_corners() {
        let topo = Topology {
            counts: &[3, 4],
            indices: &[0, 1, 2, 0, 2, 3, 4],
            points: 5,
        };
        let uniform = Primvar {
            name: "p".into(),
            values: vec![1, 2],
            interpolation: "uniform".into(),
        };
        assert_eq!(topo.expand(uniform).unwrap(), [1, 1, 1, 2, 2, 2, 2]);
        let vertex = Primvar {
            name: "p".into(),
            values: vec![10, 11, 12, 13, 14],
            interpolation: "vertex".into(),
        };
        assert_eq!(topo.expand(vertex).unwrap(), [10, 11, 12, 10, 12, 13, 14]);
        let short = Primvar {
            name: "p".into(),
            values: vec![1, 2],
            interpolation: "faceVarying".into(),
        };
        assert!(topo.expand(short).is_err());
    }
}
