//! The output's channel table: every layer of a [`RenderImage`], its buffer and its channel names, in one
//! place. The core layers (beauty, alpha, first-hit AOVs) are the rows of [`LAYERS`]; the layers a render's
//! plan adds (light paths, colours, light groups, shadow catcher, Cryptomatte; see [`super::aovs`]) are the
//! image's [`RenderImage::aovs`]. The EXR writer, the farm's part files, the C API's channel copies and the
//! image checks all read through [`RenderImage::channel_list`].
//!
//! Channel names follow Nuke's convention, `layer.component` (`R`, `albedo.G`, `normal.Z`, `depth.Z`...);
//! OpenEXR and Nuke split them at the last `.` into layer and channel.

use super::RenderImage;
use crate::math::Vec3;

/// Where a layer's values live in a [`RenderImage`].
#[derive(Clone, Copy, Debug)]
pub enum LayerData<'a> {
    /// Three components per pixel.
    Vectors(&'a [Vec3]),
    /// One component per pixel.
    Scalars(&'a [f32]),
}

/// What a channel holds, which decides how `--half` may store it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ChannelKind {
    /// The beauty and its alpha (`R`, `G`, `B`, `A`): half floats only when asked for the beauty too.
    Beauty,
    /// A colour-like AOV (albedo, normal, light paths, colours, light groups, shadow catcher): half floats
    /// under `--half`.
    Color,
    /// Data that half floats would damage (depth, variance, Cryptomatte IDs): always 32-bit floats.
    Data,
}

/// One of the core layers of the output: its name, its channels' names, and its buffer.
#[derive(Clone, Copy, Debug)]
pub struct Layer {
    /// The layer's name: `""` for the beauty (whose channels are `R`, `G`, `B` and `A`), else the prefix of
    /// its channel names (`albedo` gives `albedo.R`...).
    pub name: &'static str,
    /// The component names, one per component of the buffer, in buffer order.
    pub components: &'static [&'static str],
    /// What the layer holds, as documented in `docs/reference.md` and in [`RenderImage`].
    pub meaning: &'static str,
    /// How `--half` may store it.
    pub kind: ChannelKind,
    /// The layer's buffer in an image.
    pub data: for<'a> fn(&'a RenderImage) -> LayerData<'a>,
}

impl Layer {
    /// The full name of component `c` (`albedo.G`; `R` for the beauty).
    pub fn channel_name(&self, c: usize) -> String {
        match self.name {
            "" => self.components[c].to_string(),
            layer => format!("{layer}.{}", self.components[c]),
        }
    }

    /// The samples of component `c` in `image`, row-major from the top row.
    pub fn samples(&self, image: &RenderImage, c: usize) -> Vec<f32> {
        match (self.data)(image) {
            LayerData::Vectors(v) => v.iter().map(|p| p[c]).collect(),
            LayerData::Scalars(v) => v.to_vec(),
        }
    }

    /// How many pixels the layer's buffer holds in `image`.
    pub fn buffer_len(&self, image: &RenderImage) -> usize {
        match (self.data)(image) {
            LayerData::Vectors(v) => v.len(),
            LayerData::Scalars(v) => v.len(),
        }
    }

    /// True when `image` writes this layer: the beauty and alpha always, a first-hit layer when chosen.
    pub fn is_written(&self, image: &RenderImage) -> bool {
        self.name.is_empty() || image.first_hit.iter().any(|f| f.name() == self.name)
    }
}

/// The core layers of a rendered image: the beauty, its alpha and the first-hit layers (each written when
/// chosen; see [`RenderImage::first_hit`]). The other layers are the image's [`RenderImage::aovs`].
pub const LAYERS: [Layer; 6] = [
    Layer {
        name: "",
        components: &["R", "G", "B"],
        meaning: "beauty: linear Rec.709 radiance, the mean of the pixel's samples (premultiplied by alpha)",
        kind: ChannelKind::Beauty,
        data: |image| LayerData::Vectors(&image.beauty),
    },
    Layer {
        name: "",
        components: &["A"],
        meaning: "alpha: coverage, 1 − the camera ray's transmittance to the environment (holdouts cut it)",
        kind: ChannelKind::Beauty,
        data: |image| LayerData::Scalars(&image.alpha),
    },
    Layer {
        name: "albedo",
        components: &["R", "G", "B"],
        meaning: "albedo of the first surface hit, or the scattering albedo at the first collision in a medium \
                  (0 where nothing was hit)",
        kind: ChannelKind::Color,
        data: |image| LayerData::Vectors(&image.albedo),
    },
    Layer {
        name: "normal",
        components: &["X", "Y", "Z"],
        meaning: "world-space shading normal of the first surface hit, facing the camera (at a first collision \
                  in a medium: the direction to the camera)",
        kind: ChannelKind::Color,
        data: |image| LayerData::Vectors(&image.normal),
    },
    Layer {
        name: "depth",
        components: &["Z"],
        meaning: "distance from the camera to the first hit or collision in a medium (0 where nothing was hit)",
        kind: ChannelKind::Data,
        data: |image| LayerData::Scalars(&image.depth),
    },
    Layer {
        name: "variance",
        components: &["R", "G", "B"],
        meaning: "variance of the beauty mean (its square root is the standard error)",
        kind: ChannelKind::Data,
        data: |image| LayerData::Vectors(&image.variance),
    },
];

/// The channel names of a render with the default layers (beauty, alpha and the first-hit layers), sorted as
/// an EXR file lists them (`A`, `B`, `G`, `R`, `albedo.B`, ...). An image's own are
/// [`RenderImage::channel_names`].
pub fn channel_names() -> Vec<String> {
    RenderImage::new(1, 1).channel_names()
}

/// One channel of an image: its full name, what it holds, and its samples.
#[derive(Clone, Debug, PartialEq)]
pub struct Channel {
    /// The full name (`R`, `albedo.G`, `lg_key.B`, `CryptoObject00.r`).
    pub name: String,
    /// What it holds.
    pub kind: ChannelKind,
    /// The samples, row-major from the top row.
    pub samples: Vec<f32>,
}

impl RenderImage {
    /// Every channel the image writes, sorted by name as an EXR file lists them.
    pub fn channel_list(&self) -> Vec<Channel> {
        let mut all: Vec<Channel> = LAYERS
            .iter()
            .filter(|l| l.is_written(self))
            .flat_map(|layer| {
                (0..layer.components.len()).map(move |c| Channel {
                    name: layer.channel_name(c),
                    kind: layer.kind,
                    samples: layer.samples(self, c),
                })
            })
            .collect();
        for layer in &self.aovs {
            for (c, component) in layer.components.iter().enumerate() {
                all.push(Channel {
                    name: format!("{}.{component}", layer.name),
                    kind: if layer.allows_half {
                        ChannelKind::Color
                    } else {
                        ChannelKind::Data
                    },
                    samples: layer.data[c].clone(),
                });
            }
        }
        all.sort_by(|a, b| a.name.cmp(&b.name));
        all
    }

    /// The names of every channel the image writes, sorted as an EXR file lists them.
    pub fn channel_names(&self) -> Vec<String> {
        self.channel_list().into_iter().map(|c| c.name).collect()
    }

    /// The samples of channel `name` (one of [`channel_names`](Self::channel_names)), row-major from the top
    /// row, or `None` for a channel the image does not write.
    ///
    /// ```
    /// let mut image = nimbus::RenderImage::new(2, 1);
    /// image.albedo[1].y = 0.5;
    /// image.alpha[0] = 1.0;
    /// assert_eq!(image.channel("albedo.G"), Some(vec![0.0, 0.5]));
    /// assert_eq!(image.channel("A"), Some(vec![1.0, 0.0]));
    /// assert_eq!(image.channel("albedo.Q"), None);
    /// ```
    pub fn channel(&self, name: &str) -> Option<Vec<f32>> {
        self.channel_list()
            .into_iter()
            .find(|c| c.name == name)
            .map(|c| c.samples)
    }

    /// Every channel with its samples, sorted by name as an EXR file lists them.
    pub fn channels(&self) -> Vec<(String, Vec<f32>)> {
        self.channel_list()
            .into_iter()
            .map(|c| (c.name, c.samples))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_listed_channel_exists_and_others_do_not() {
        let mut img = RenderImage::new(1, 1);
        img.beauty[0] = Vec3::new(1.0, 2.0, 3.0);
        img.normal[0] = Vec3::new(4.0, 5.0, 6.0);
        img.depth[0] = 7.0;
        let names = img.channel_names();
        assert_eq!(names.len(), 14);
        for name in &names {
            assert_eq!(img.channel(name).map(|v| v.len()), Some(1), "{name}");
        }
        assert_eq!(img.channel("B"), Some(vec![3.0]));
        assert_eq!(img.channel("normal.Y"), Some(vec![5.0]));
        assert_eq!(img.channel("depth.Z"), Some(vec![7.0]));
        for bad in [
            "", "RG", "X", "albedo.X", "normal.R", "depth.R", "beauty.R", ".R", "albedo.",
        ] {
            assert_eq!(img.channel(bad), None, "{bad}");
        }
    }

    #[test]
    fn the_reference_lists_every_layer() {
        let readme = include_str!("../../docs/reference.md");
        for layer in LAYERS.iter().filter(|l| !l.name.is_empty()) {
            let listed = format!("`{}.{}`", layer.name, layer.components.join("/"));
            assert!(
                readme.contains(&listed),
                "docs/reference.md's Output section lacks {listed}"
            );
        }
    }

    #[test]
    fn channels_are_sorted_and_match_their_names() {
        let mut img = RenderImage::new(2, 1);
        img.albedo[1] = Vec3::new(0.1, 0.2, 0.3);
        let all = img.channels();
        let names: Vec<String> = all.iter().map(|(n, _)| n.clone()).collect();
        assert_eq!(names, channel_names());
        for (name, samples) in all {
            assert_eq!(img.channel(&name), Some(samples));
        }
    }
}
