//! How a scene file is loaded: [`LoadOptions`], the same for every format (glTF, OBJ, USD), the
//! [`VolumeOverride`] applied to every volume declaration, and the report of unknown scene-file keys that
//! every loader shares.

use super::{SceneBuilder, SceneErrorKind};

/// Reports the keys in `unknown`, found at `at` (`node 'smoke': nimbus_volume`), which the loader will ignore:
/// one warning each, or when `strict` ([`LoadOptions::strict`]) an error naming the first.
pub(crate) fn report_unknown_keys(
    builder: &mut SceneBuilder,
    strict: bool,
    at: &str,
    unknown: &[crate::params::UnknownKey],
) -> Result<(), SceneErrorKind> {
    let shown = |key: &crate::params::UnknownKey, verb: &str| {
        crate::limits::one_line(&format!("{at}: {key}{verb}{}", key.hint()), 300)
    };
    if let (true, Some(first)) = (strict, unknown.first()) {
        return Err(SceneErrorKind::UnknownKey(shown(first, "")));
    }
    for key in unknown {
        builder.warn(shown(key, " ignored"));
    }
    Ok(())
}

/// How a scene file is loaded: the same options for every format (glTF, OBJ, USD).
#[derive(Clone, Copy, Default)]
pub struct LoadOptions<'a> {
    /// Applied to every VDB volume declaration (glTF `nimbus_volume`, USD `Volume`) after it is read and before
    /// its medium is built, to compare majorant structures or shadow estimators on the same scene.
    /// Only the crate itself makes one (`nimbus converge`, and its tests with the `testing` feature): volume
    /// declarations are not part of the API.
    pub volume_override: Option<VolumeOverride<'a>>,
    /// VDB files given in memory by name: a volume whose `file` equals one of these names reads its bytes
    /// instead of the file system (the bundled demo).
    pub embedded: &'a [(&'a str, &'static [u8])],
    /// The memory budget for allocations sized by the files (whole-file reads, majorant structures, decoded
    /// textures).
    pub limits: crate::limits::Limits,
    /// The shot's frame: VDB sequences read this frame's file (frame 1 when `None`), glTF animations are
    /// sampled at `frame / fps` seconds (not at all when `None`, unless a shutter is set: then at frame 1)
    /// and USD stages read at the frame's time code.
    pub frame: Option<i64>,
    /// Frames per second of the shot (`--fps`): glTF's default is [`crate::frames::DEFAULT_FPS`]; a USD stage's
    /// own is its `framesPerSecond`.
    pub fps: Option<f64>,
    /// The motion-blur shutter (`--shutter`), in frames relative to the frame; `None` renders an instant.
    /// Moving things are sampled across it (glTF cameras and meshes at motion steps, see
    /// `gltf::animation::shutter_poses`) and media with a velocity grid are blurred over it.
    pub shutter: Option<crate::frames::Shutter>,
    /// Catmull-Clark levels of every USD mesh whose `subdivisionScheme` is `catmullClark` (`--subdivision-level`),
    /// over the mesh's own `refineLevel`; `None`: its `refineLevel`, else 2.
    pub subdivision_level: Option<u32>,
    /// The glTF `KHR_materials_variants` variant to load, by name (`--variant`): each primitive whose mappings
    /// name it takes the mapped material, every other its own. `None` loads every primitive's own material,
    /// and a file with variants warns once, listing them. A name the file does not declare is an error that
    /// lists its variants; so is any name for OBJ and USD files, which have no material variants.
    pub variant: Option<&'a str>,
    /// Refuse scene-file keys the renderer does not know (`--strict`): a `nimbus_*` extras key, a key inside a
    /// `nimbus_volume`, `nimbus_medium`, `nimbus_camera` or `nimbus_environment` object, or a USD `nimbus:`
    /// attribute that no table declares. Without it each is a warning naming the closest known key.
    pub strict: bool,
}

/// A change applied to every volume declaration a loader reads ([`LoadOptions::volume_override`]): a rendering
/// method forced on every medium ([`VolumeOverride::method`], `nimbus converge`'s and the Python module's
/// `volume_method`), or, inside the crate, any change to the declaration.
#[derive(Clone, Copy)]
pub struct VolumeOverride<'a>(Override<'a>);

/// What a [`VolumeOverride`] does.
#[derive(Clone, Copy)]
enum Override<'a> {
    /// Calls the function on each declaration.
    Function(&'a dyn Fn(&mut crate::volume::VolumeSpec)),
    /// Forces the method on each medium.
    Method(crate::converge::Method),
}

impl<'a> VolumeOverride<'a> {
    internal! {
        /// The override that calls `f` on each volume declaration.
        pub fn new(f: &'a dyn Fn(&mut crate::volume::VolumeSpec)) -> Self {
            VolumeOverride(Override::Function(f))
        }
    }

    /// The override that renders every medium by `method` (its free-flight estimator and majorants), as
    /// `nimbus converge` compares them.
    pub fn method(method: crate::converge::Method) -> Self {
        VolumeOverride(Override::Method(method))
    }
}

impl LoadOptions<'_> {
    /// Gives `spec` the memory budget, then applies the volume override, if any. Every loader calls this on
    /// each volume it declares.
    pub(crate) fn apply_volume_override(&self, spec: &mut crate::volume::VolumeSpec) {
        spec.limits = self.limits;
        spec.frame = self.frame;
        spec.shutter = self.shutter;
        if let Some(fps) = self.fps {
            spec.fps = fps;
        }
        match self.volume_override {
            Some(VolumeOverride(Override::Function(f))) => f(spec),
            Some(VolumeOverride(Override::Method(m))) => m.apply_to_volume(spec),
            None => {}
        }
    }

    /// The bytes of the embedded file named `file`, if there is one.
    pub(crate) fn embedded_file(&self, file: &str) -> Option<&'static [u8]> {
        self.embedded
            .iter()
            .find(|(name, _)| *name == file)
            .map(|(_, bytes)| *bytes)
    }
}
