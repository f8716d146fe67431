//! The output's channel table: every layer of a [`RenderImage`], its buffer and its channel names, in one
//! place. The EXR writer, the farm's part files, the C API's channel copies and the image checks all read
//! through it, so adding an AOV means adding its buffer to [`RenderImage`] and one row to [`LAYERS`].
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
    /// The same value in every pixel (the beauty's alpha).
    Constant(f32),
}

/// One layer of the output: its name, its channels' names, and its buffer.
#[derive(Clone, Copy, Debug)]
pub struct Layer {
    /// The layer's name: `""` for the beauty (whose channels are `R`, `G`, `B` and `A`), else the prefix of
    /// its channel names (`albedo` gives `albedo.R`...).
    pub name: &'static str,
    /// The component names, one per component of the buffer, in buffer order.
    pub components: &'static [&'static str],
    /// What the layer holds, as documented in the README and in [`RenderImage`].
    pub meaning: &'static str,
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
            LayerData::Constant(value) => vec![value; image.pixel_count()],
        }
    }

    /// How many pixels the layer's buffer holds in `image` (`None` for a constant layer).
    pub fn buffer_len(&self, image: &RenderImage) -> Option<usize> {
        match (self.data)(image) {
            LayerData::Vectors(v) => Some(v.len()),
            LayerData::Scalars(v) => Some(v.len()),
            LayerData::Constant(_) => None,
        }
    }
}

/// Every layer of a rendered image.
pub const LAYERS: [Layer; 6] = [
    Layer {
        name: "",
        components: &["R", "G", "B"],
        meaning: "beauty: linear Rec.709 radiance, the mean of the pixel's samples",
        data: |image| LayerData::Vectors(&image.beauty),
    },
    Layer {
        name: "",
        components: &["A"],
        meaning: "alpha: 1 everywhere",
        data: |_| LayerData::Constant(1.0),
    },
    Layer {
        name: "albedo",
        components: &["R", "G", "B"],
        meaning: "albedo of the first surface hit (0 where nothing was hit)",
        data: |image| LayerData::Vectors(&image.albedo),
    },
    Layer {
        name: "normal",
        components: &["X", "Y", "Z"],
        meaning: "world-space shading normal of the first surface hit, facing the camera",
        data: |image| LayerData::Vectors(&image.normal),
    },
    Layer {
        name: "depth",
        components: &["Z"],
        meaning: "distance from the camera to the first hit (0 where nothing was hit)",
        data: |image| LayerData::Scalars(&image.depth),
    },
    Layer {
        name: "variance",
        components: &["R", "G", "B"],
        meaning: "variance of the beauty mean (its square root is the standard error)",
        data: |image| LayerData::Vectors(&image.variance),
    },
];

/// Every channel name, sorted as an EXR file lists them (`A`, `B`, `G`, `R`, `albedo.B`, ...).
pub fn channel_names() -> Vec<String> {
    let mut names: Vec<String> = channels().map(|(layer, c)| layer.channel_name(c)).collect();
    names.sort();
    names
}

/// Every (layer, component) pair of [`LAYERS`].
fn channels() -> impl Iterator<Item = (&'static Layer, usize)> {
    LAYERS
        .iter()
        .flat_map(|layer| (0..layer.components.len()).map(move |c| (layer, c)))
}

impl RenderImage {
    /// The samples of channel `name` (one of [`channel_names`]), row-major from the top row, or `None` for
    /// an unknown name.
    ///
    /// ```
    /// let mut image = nimbus::RenderImage::new(2, 1);
    /// image.albedo[1].y = 0.5;
    /// assert_eq!(image.channel("albedo.G"), Some(vec![0.0, 0.5]));
    /// assert_eq!(image.channel("A"), Some(vec![1.0, 1.0]));
    /// assert_eq!(image.channel("albedo.Q"), None);
    /// ```
    pub fn channel(&self, name: &str) -> Option<Vec<f32>> {
        channels()
            .find(|(layer, c)| layer.channel_name(*c) == name)
            .map(|(layer, c)| layer.samples(self, c))
    }

    /// Every channel with its samples, sorted by name as an EXR file lists them.
    pub fn channels(&self) -> Vec<(String, Vec<f32>)> {
        let mut all: Vec<(String, Vec<f32>)> = channels()
            .map(|(layer, c)| (layer.channel_name(c), layer.samples(self, c)))
            .collect();
        all.sort_by(|a, b| a.0.cmp(&b.0));
        all
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
        let names = channel_names();
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
    fn the_readme_lists_every_layer() {
        let readme = include_str!("../../README.md");
        for layer in LAYERS.iter().filter(|l| !l.name.is_empty()) {
            let listed = format!("`{}.{}`", layer.name, layer.components.join("/"));
            assert!(
                readme.contains(&listed),
                "README's Output section lacks {listed}"
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
