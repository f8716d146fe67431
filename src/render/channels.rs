//! Access to the image's buffers one float channel at a time, by the channel names the EXR writer uses
//! (`R`, `albedo.G`, `normal.Z`, `depth.Z`...), for hosts that copy channels out (the C API does).

use super::RenderImage;

/// Every channel name [`RenderImage::channel`] knows, in the EXR file's sorted order (`A` is constant 1).
pub const CHANNEL_NAMES: [&str; 14] = [
    "A",
    "B",
    "G",
    "R",
    "albedo.B",
    "albedo.G",
    "albedo.R",
    "depth.Z",
    "normal.X",
    "normal.Y",
    "normal.Z",
    "variance.B",
    "variance.G",
    "variance.R",
];

impl RenderImage {
    /// The samples of channel `name` (one of [`CHANNEL_NAMES`]), row-major from the top row, or `None` for
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
        let (layer, component) = match name.rsplit_once('.') {
            Some(("", _)) => return None,
            Some(split) => split,
            None => ("", name),
        };
        let index = |names: &str| names.find(component).filter(|_| component.len() == 1);
        match layer {
            "" if component == "A" => Some(vec![1.0; self.pixel_count()]),
            "" => index("RGB").map(|c| self.beauty.iter().map(|v| v[c]).collect()),
            "albedo" => index("RGB").map(|c| self.albedo.iter().map(|v| v[c]).collect()),
            "variance" => index("RGB").map(|c| self.variance.iter().map(|v| v[c]).collect()),
            "normal" => index("XYZ").map(|c| self.normal.iter().map(|v| v[c]).collect()),
            "depth" if component == "Z" => Some(self.depth.clone()),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Vec3;

    #[test]
    fn every_listed_channel_exists_and_others_do_not() {
        let mut img = RenderImage::new(1, 1);
        img.beauty[0] = Vec3::new(1.0, 2.0, 3.0);
        img.normal[0] = Vec3::new(4.0, 5.0, 6.0);
        img.depth[0] = 7.0;
        for name in CHANNEL_NAMES {
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
}
