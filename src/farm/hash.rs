//! The scene hash: a 64-bit fingerprint of what a part was rendered from, so that a merge can refuse parts of
//! different renders.
//!
//! It is FNV-1a (64-bit; Fowler, Noll and Vo) over, in this order, each a length-prefixed field:
//! 1. the tag `nimbus scene hash 1`;
//! 2. the bytes of the scene file (for the bundled demo, its embedded glTF and VDB);
//! 3. the settings that change the image: width, height, seed, max depth, media MIS, equiangular sampling,
//!    the sampler and the light sampler (`--light-sampler` as given: auto, power or bvh), little-endian; the
//!    tags `emitter-edges off` and `decoupled off` when those are off (so that the hashes of renders from
//!    before them stay the same) and `transparent` for a transparent film; and, when the render may be guided
//!    (what `--guiding` decided for the scene before rendering: `on`, or `auto` in a scene with a scattering
//!    medium, which a pilot of unguided paths decides), the tag `guiding`, the mode's tag (`on`, or
//!    `auto` followed by its rule's threshold as an `f64` and its pilot's size as a `u64`), the training
//!    iterations (the cache), the tag `training in image` (the training's samples are the image's first:
//!    guided parts from before that refuse to merge with later ones) and whether guided Russian roulette is on
//!    (one byte). An unguided render (`off`, or `auto` in a scene without a scattering medium) adds none of
//!    these, so it hashes as renders from before guiding existed; `auto` parts of a scene it may guide merge
//!    with each other only (they all decide alike);
//! 4. each scene override of the command line by name and value (`--env-color` as three `f32`, `--variant` as
//!    its name's UTF-8 bytes; the CLI also passes the frame, the shutter, the `--camera` name and, for a camera
//!    with a thin lens, its aperture radius and focus distance as two `f32`, so that parts of different
//!    apertures refuse to merge even when the lens comes from somewhere the scene file's bytes do not show).
//!
//! `scene_hash` names every field of [`RenderSettings`], so a new setting does not compile until it is hashed or
//! said to leave the samples unchanged. The sample count and range, the crop, the thread count and the time
//! limit are not in it: they do not
//! change any one sample (parts carry the sample count and range in their own keys). Files the scene file
//! refers to (buffers, textures, VDB grids, USD layers) are not read: the hash catches a different or edited
//! scene file, not an edited texture beside an unchanged one. FNV-1a is specified byte by byte, so the hash
//! is the same on every platform and Rust version.

use crate::render::RenderSettings;

/// FNV-1a 64-bit offset basis.
const OFFSET_BASIS: u64 = 0xcbf2_9ce4_8422_2325;
/// FNV-1a 64-bit prime.
const PRIME: u64 = 0x0000_0100_0000_01b3;

/// An FNV-1a (64-bit) hasher over length-prefixed fields.
#[derive(Clone, Debug)]
pub struct SceneHasher {
    state: u64,
}

impl Default for SceneHasher {
    fn default() -> Self {
        Self::new()
    }
}

impl SceneHasher {
    /// A hasher that has taken the format tag.
    pub fn new() -> Self {
        let mut h = Self {
            state: OFFSET_BASIS,
        };
        h.field(b"nimbus scene hash 1");
        h
    }

    /// Adds one field: its length (u64, little-endian), then its bytes, so that fields cannot run into each
    /// other.
    pub fn field(&mut self, bytes: &[u8]) {
        self.raw(&(bytes.len() as u64).to_le_bytes());
        self.raw(bytes);
    }

    /// The hash of the fields so far.
    pub fn finish(&self) -> u64 {
        self.state
    }

    fn raw(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.state = (self.state ^ b as u64).wrapping_mul(PRIME);
        }
    }
}

/// The scene hash of a render (see the module docs): `scene_files` are the bytes of the scene file (or of
/// each embedded file), `guiding` the mode's tag where the render may be guided (`"on"`, or `"auto"` where
/// `auto` decides by its pilot; `None` for an unguided render: see
/// [`SceneOverrides::scene_hash`], which derives it from the scene), `overrides` the command line's scene
/// overrides as (name, value bytes).
pub fn scene_hash(
    scene_files: &[&[u8]],
    settings: &RenderSettings,
    guiding: Option<&str>,
    overrides: &[(&str, &[u8])],
) -> u64 {
    let mut h = SceneHasher::new();
    h.field(&(scene_files.len() as u64).to_le_bytes());
    for file in scene_files {
        h.field(file);
    }
    // Every field of the settings is named here, so a new one does not compile until it is either hashed or
    // said to leave every sample unchanged: the hash cannot forget a setting.
    let RenderSettings {
        width,
        height,
        seed,
        max_depth,
        media_mis,
        equiangular,
        decoupled,
        sampler,
        light_sampler,
        emitter_edges,
        transparent,
        // How many samples, and on how many threads for how long: parts carry their sample counts and ranges.
        spp: _,
        threads: _,
        time_limit: _,
        // Which layers are written: a merge compares the parts' layer lists, and the beauty does not change.
        aovs: _,
        light_groups: _,
        cryptomatte_depth: _,
        // Deep output: it leaves the flat image as it is, and a deep render is never split into parts.
        deep_samples: _,
        // The memory budget: the estimators it chooses travel in the part (`nimbus.estimators`) and are
        // compared by the merge, since the default budget depends on the machine.
        limits: _,
        // The mode is hashed by what it decided for the scene before rendering, `guiding`.
        guiding: _,
        guided_roulette,
    } = settings;
    h.field(&(*width as u64).to_le_bytes());
    h.field(&(*height as u64).to_le_bytes());
    h.field(&seed.to_le_bytes());
    h.field(&max_depth.to_le_bytes());
    h.field(&[*media_mis as u8]);
    h.field(&[*equiangular as u8]);
    h.field(&[*sampler as u8]);
    h.field(&[*light_sampler as u8]);
    // Only when off, so that the hashes of renders from before the setting existed stay the same.
    if *emitter_edges == crate::render::EmitterEdgeSampling::Off {
        h.field(b"emitter-edges off");
    }
    // Only when off, as `emitter_edges`.
    if !*decoupled {
        h.field(b"decoupled off");
    }
    // A transparent film leaves the environment out of the beauty (a scene asking for one does so in its bytes).
    if *transparent {
        h.field(b"transparent");
    }
    // Path guiding, only where the render may be guided (so that unguided renders hash as before guiding
    // existed): its cache depends on the training plan, and the scene and the settings above fix everything
    // else it learns from. The tag `on` is the one `--guiding on` parts have always carried; `auto` adds its
    // rule's threshold and its pilot's size, which decide whether it guides.
    if let Some(mode) = guiding {
        h.field(b"guiding");
        h.field(mode.as_bytes());
        if mode == "auto" {
            h.field(&crate::guiding::pilot::AUTO_MAX_SHADOW_TRACED.to_le_bytes());
            h.field(&(crate::guiding::pilot::AUTO_PILOT_PATHS as u64).to_le_bytes());
        }
        h.field(&crate::guiding::TRAINING_ITERATIONS.to_le_bytes());
        h.field(b"training in image");
        h.field(&[*guided_roulette as u8]);
    }
    for (name, value) in overrides {
        h.field(name.as_bytes());
        h.field(value);
    }
    h.finish()
}

/// What a render was loaded and lit with beyond its scene file's bytes: the overrides of item 4 of the module
/// docs, by name. `nimbus render` and the Python module both hash through [`SceneOverrides::scene_hash`], so a
/// part rendered by either merges with the other's.
#[derive(Clone, Copy, Debug, Default)]
pub struct SceneOverrides<'a> {
    /// `--env-color`: a constant environment replacing the scene's.
    pub env_color: Option<crate::math::Rgb>,
    /// The shot's frame.
    pub frame: Option<i64>,
    /// Frames per second (hashed only with a frame or a shutter, where it changes what is loaded).
    pub fps: Option<f64>,
    /// The motion-blur shutter.
    pub shutter: Option<crate::frames::Shutter>,
    /// `--camera`: the scene camera chosen by name.
    pub camera: Option<&'a str>,
    /// The render camera's thin lens, if it has one (hashed only then, so that the hashes of pinhole renders
    /// stay what they were).
    pub lens: Option<crate::scene::ThinLens>,
    /// The glTF material variant.
    pub variant: Option<&'a str>,
    /// `--subdivision-level`.
    pub subdivision_level: Option<u32>,
}

impl SceneOverrides<'_> {
    /// The scene hash ([`scene_hash`]) of `scene_files`, loaded as `scene`, rendered with `settings` under these
    /// overrides: guided or not as `settings.guiding` decides for `scene` before rendering.
    pub fn scene_hash(
        &self,
        scene_files: &[&[u8]],
        settings: &RenderSettings,
        scene: &crate::scene::Scene,
    ) -> u64 {
        let floats =
            |values: &[f32]| -> Vec<u8> { values.iter().flat_map(|v| v.to_le_bytes()).collect() };
        let env = self.env_color.map(|c| floats(&c.to_array()));
        let frame = self.frame.map(i64::to_le_bytes);
        let fps = self
            .fps
            .filter(|_| self.frame.is_some() || self.shutter.is_some())
            .map(f64::to_le_bytes);
        let shutter = self.shutter.map(|s| {
            [s.open, s.close]
                .iter()
                .flat_map(|v| v.to_le_bytes())
                .collect::<Vec<u8>>()
        });
        let subdivision = self.subdivision_level.map(u32::to_le_bytes);
        let lens = self
            .lens
            .map(|l| floats(&[l.aperture_radius, l.focus_distance]));
        let overrides: Vec<(&str, &[u8])> = env
            .iter()
            .map(|e| ("env-color", e.as_slice()))
            .chain(frame.iter().map(|f| ("frame", f.as_slice())))
            .chain(fps.iter().map(|f| ("fps", f.as_slice())))
            .chain(shutter.iter().map(|s| ("shutter", s.as_slice())))
            .chain(self.camera.iter().map(|c| ("camera", c.as_bytes())))
            .chain(lens.iter().map(|l| ("lens", l.as_slice())))
            .chain(self.variant.iter().map(|v| ("variant", v.as_bytes())))
            .chain(
                subdivision
                    .iter()
                    .map(|l| ("subdivision-level", l.as_slice())),
            )
            .collect();
        let decision = settings.guiding.decide(scene);
        let guiding = match (decision.on, decision.provisional) {
            (false, _) => None,
            (true, false) => Some("on"),
            (true, true) => Some("auto"),
        };
        scene_hash(scene_files, settings, guiding, &overrides)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fnv1a_matches_its_published_test_vectors() {
        let fnv = |bytes: &[u8]| {
            let mut h = SceneHasher {
                state: OFFSET_BASIS,
            };
            h.raw(bytes);
            h.finish()
        };
        assert_eq!(fnv(b""), 0xcbf2_9ce4_8422_2325);
        assert_eq!(fnv(b"a"), 0xaf63_dc4c_8601_ec8c);
        assert_eq!(fnv(b"foobar"), 0x8594_4171_f739_67e8);
    }

    #[test]
    fn every_input_changes_the_hash_and_nothing_else_does() {
        let s = RenderSettings {
            width: 64,
            height: 48,
            ..Default::default()
        };
        let base = scene_hash(&[b"scene"], &s, None, &[]);
        assert_eq!(base, scene_hash(&[b"scene"], &s, None, &[]));
        // Each field `scene_hash` leaves out, changed in turn.
        // The mode itself is hashed by its decision, and guided roulette only where paths are guided.
        let unhashed: [fn(&mut RenderSettings); 11] = [
            |s| s.guiding = crate::guiding::GuidingMode::On,
            |s| s.guiding = crate::guiding::GuidingMode::Off,
            |s| s.guided_roulette = true,
            |s| s.spp = 3,
            |s| s.threads = 7,
            |s| s.time_limit = Some(std::time::Duration::from_secs(1)),
            |s| s.aovs = Some(crate::render::AovSelection { aovs: Vec::new() }),
            |s| s.light_groups = crate::render::LightGroupMode::PerLight,
            |s| s.cryptomatte_depth += 2,
            |s| s.deep_samples = Some(4),
            |s| s.limits = crate::limits::Limits::with_memory(1 << 20),
        ];
        for (i, change) in unhashed.iter().enumerate() {
            let mut t = s.clone();
            change(&mut t);
            assert_ne!(
                format!("{t:?}"),
                format!("{s:?}"),
                "unhashed change {i} changes nothing"
            );
            assert_eq!(
                base,
                scene_hash(&[b"scene"], &t, None, &[]),
                "unhashed change {i}"
            );
        }
        let changes: [fn(&mut RenderSettings); 11] = [
            |s| s.width += 1,
            |s| s.height -= 1,
            |s| s.seed = 1,
            |s| s.max_depth = 3,
            |s| s.media_mis = !s.media_mis,
            |s| s.equiangular = !s.equiangular,
            |s| s.decoupled = !s.decoupled,
            |s| s.sampler = crate::render::Sampler::Independent,
            |s| s.light_sampler = crate::light::LightSamplerChoice::Bvh,
            |s| s.emitter_edges = crate::render::EmitterEdgeSampling::Off,
            |s| s.transparent = !s.transparent,
        ];
        let mut changed: Vec<u64> = changes
            .iter()
            .map(|change| {
                let mut t = s.clone();
                change(&mut t);
                scene_hash(&[b"scene"], &t, None, &[])
            })
            .collect();
        changed.extend([
            scene_hash(&[b"scene!"], &s, None, &[]),
            scene_hash(&[b"sce", b"ne"], &s, None, &[]),
            scene_hash(&[b"scene"], &s, None, &[("env-color", &[0, 0, 0])]),
            scene_hash(&[b"scene"], &s, Some("on"), &[]),
            scene_hash(&[b"scene"], &s, Some("auto"), &[]),
        ]);
        assert_ne!(
            scene_hash(&[b"scene"], &s, Some("on"), &[]),
            scene_hash(&[b"scene"], &s, Some("auto"), &[]),
            "auto, which may guide, against on"
        );
        let roulette = RenderSettings {
            guided_roulette: true,
            ..s.clone()
        };
        assert_ne!(
            scene_hash(&[b"scene"], &roulette, Some("on"), &[]),
            scene_hash(&[b"scene"], &s, Some("on"), &[]),
            "guided roulette in a guided render"
        );
        for (i, h) in changed.iter().enumerate() {
            assert_ne!(*h, base, "change {i}");
        }
    }
}
