//! Denoising with Intel Open Image Denoise (feature `denoise`): `nimbus render --denoise` and `nimbus denoise`.
//!
//! OIDN's `RT` filter denoises the beauty (HDR) guided by two auxiliary images, the render's first-hit `albedo`
//! and `normal` layers: at a surface its base colour and shading normal, in a medium the scattering albedo at
//! the first real collision and the direction back to the camera (see `integrator/path.rs`). The result is the
//! `denoised` layer (`denoised.R/G/B`), written beside the raw beauty, which stays. Denoising runs on a whole
//! frame, after a farm's merge, never on a part: the filter looks at each pixel's neighbours.
//!
//! The auxiliary images are the means of the pixels' samples, so they are noisy too. As OIDN's documentation
//! recommends for the highest quality, each is first denoised alone by an `RT` filter (prefiltering), and the
//! beauty is then filtered with `cleanAux` on. The `oidn` crate 2.5's safe wrapper cannot do either (it always
//! binds a colour image, and sets `cleanAux` under a name OIDN does not know, `clean_aux`), so the filters are
//! run through OIDN's C API in the small [`oidn_c`] module, the one place this crate allows `unsafe`.
//! `docs/denoising.md` has the measurements.
//!
//! A denoised image is never evidence of accuracy: the validation suite measures the raw beauty.

use crate::math::{Rgb, Vec3};
use crate::output::{read_flat_image, write_sorted, OutputError};
use crate::render::{AovLayer, RenderImage};
use ::exr::prelude::{AnyChannel, AnyChannels, FlatSamples, Image, Vec2};
use std::path::{Path, PathBuf};

/// The name of the layer the denoised beauty is written to (`denoised.R`, `denoised.G`, `denoised.B`).
pub const DENOISED_LAYER: &str = "denoised";

/// Why denoising failed.
#[derive(Debug, thiserror::Error)]
pub enum DenoiseError {
    /// OIDN refused (no CPU device, out of memory, an image it cannot take).
    #[error("Open Image Denoise: {0}")]
    Oidn(String),
    /// The input EXR lacks a channel the denoiser needs.
    #[error("{path}: no channel {channel} (nimbus denoise needs R, G, B, albedo.R/G/B and normal.X/Y/Z, as `nimbus render` and `nimbus merge` write them)")]
    MissingChannel {
        /// The input file.
        path: PathBuf,
        /// The channel's name.
        channel: String,
    },
    /// The input EXR is not one `nimbus` can denoise (several parts, a data window that is not the frame's).
    #[error("{path}: {reason}")]
    Unsupported {
        /// The input file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// Reading or writing an EXR failed.
    #[error(transparent)]
    Output(#[from] OutputError),
}

/// The denoised beauty of a `width` × `height` frame (row-major from the top row) with its albedo and normal
/// auxiliaries. Non-finite samples are taken as 0; albedo is clamped to \[0, 1\] and normals to \[−1, 1\], the
/// ranges OIDN's filter expects.
pub fn denoise(
    width: usize,
    height: usize,
    beauty: &[Rgb],
    albedo: &[Rgb],
    normal: &[Vec3],
) -> Result<Vec<Rgb>, DenoiseError> {
    let n = width * height;
    if beauty.len() != n || albedo.len() != n || normal.len() != n {
        return Err(DenoiseError::Oidn(format!(
            "image buffers of {}, {} and {} pixels for a {width}x{height} frame",
            beauty.len(),
            albedo.len(),
            normal.len()
        )));
    }
    let flat = |v: &[Vec3], lo: f32, hi: f32| -> Vec<f32> {
        v.iter()
            .flat_map(|p| p.to_array())
            .map(|x| if x.is_finite() { x.clamp(lo, hi) } else { 0.0 })
            .collect()
    };
    let color = flat(beauty, 0.0, f32::MAX);
    let albedo = flat(albedo, 0.0, 1.0);
    let normal = flat(normal, -1.0, 1.0);
    let mut output = vec![0.0f32; 3 * n];
    // The crate panics where OIDN cannot allocate a buffer: taken as an error, never a crash.
    crate::limits::catch_quietly(|| {
        let device = oidn::Device::cpu().map_err(oidn_c::FilterError::Device)?;
        let mut clean_albedo = vec![0.0f32; 3 * n];
        oidn_c::run_rt_filter(
            &device,
            (width, height),
            &[(c"albedo", &albedo)],
            &[],
            &mut clean_albedo,
        )?;
        let mut clean_normal = vec![0.0f32; 3 * n];
        oidn_c::run_rt_filter(
            &device,
            (width, height),
            &[(c"normal", &normal)],
            &[],
            &mut clean_normal,
        )?;
        oidn_c::run_rt_filter(
            &device,
            (width, height),
            &[
                (c"color", &color),
                (c"albedo", &clean_albedo),
                (c"normal", &clean_normal),
            ],
            &[(c"hdr", true), (c"cleanAux", true)],
            &mut output,
        )
    })
    .map_err(|panic| DenoiseError::Oidn(panic.0))?
    .map_err(|e| DenoiseError::Oidn(e.to_string()))?;
    Ok(output
        .chunks_exact(3)
        .map(|c| Rgb::new(c[0], c[1], c[2]))
        .collect())
}

/// The denoised beauty of `image`, from its beauty, albedo and normal buffers.
pub fn denoise_image(image: &RenderImage) -> Result<Vec<Rgb>, DenoiseError> {
    denoise(
        image.width,
        image.height,
        &image.beauty,
        &image.albedo,
        &image.normal,
    )
}

/// The `denoised` layer of `pixels` (see [`DENOISED_LAYER`]).
pub fn denoised_layer(pixels: &[Rgb]) -> AovLayer {
    let mut layer = AovLayer::rgb(DENOISED_LAYER, pixels.len());
    for (i, p) in pixels.iter().enumerate() {
        for c in 0..3 {
            layer.data[c][i] = p[c];
        }
    }
    layer
}

/// An image whose beauty is `pixels` (denoised) and whose alpha is `alpha` (the raw coverage; 1 where empty),
/// for the PNG preview and its metering; its other buffers are zero.
pub fn preview_image(width: usize, height: usize, pixels: Vec<Rgb>, alpha: &[f32]) -> RenderImage {
    let mut image = RenderImage::new(width, height);
    image.beauty = pixels;
    if alpha.len() == image.alpha.len() {
        image.alpha.copy_from_slice(alpha);
    } else {
        image.alpha.fill(1.0);
    }
    image
}

/// `nimbus denoise`: reads the merged frame `input` (a single-part EXR of `nimbus render` or `nimbus merge`),
/// denoises its beauty with its albedo and normal layers and writes it to `output` with the `denoised` layer
/// added (replacing one it had), every other channel and header attribute as they were. The file is written
/// atomically. Returns the preview image of the denoised frame (see [`preview_image`]).
pub fn denoise_exr(input: &Path, output: &Path) -> Result<RenderImage, DenoiseError> {
    let image = read_flat_image(input)?;
    let unsupported = |reason: String| DenoiseError::Unsupported {
        path: input.to_path_buf(),
        reason,
    };
    let mut layers = image.layer_data.into_iter();
    let (Some(mut layer), None) = (layers.next(), layers.next()) else {
        return Err(unsupported(
            "not a single-part EXR (nimbus denoise takes the merged frame that `nimbus render` or `nimbus merge` wrote)"
                .into(),
        ));
    };
    let (width, height) = (layer.size.x(), layer.size.y());
    let find = |name: &str| -> Result<Vec<f32>, DenoiseError> {
        layer
            .channel_data
            .list
            .iter()
            .find(|c| c.name.to_string() == name)
            .map(|c| c.sample_data.values().map(|s| s.to_f32()).collect())
            .ok_or_else(|| DenoiseError::MissingChannel {
                path: input.to_path_buf(),
                channel: name.to_owned(),
            })
    };
    let vectors = |names: [&str; 3]| -> Result<Vec<Vec3>, DenoiseError> {
        let [x, y, z] = names.map(find);
        let (x, y, z) = (x?, y?, z?);
        Ok((0..x.len()).map(|i| Vec3::new(x[i], y[i], z[i])).collect())
    };
    let beauty = vectors(["R", "G", "B"])?;
    let albedo = vectors(["albedo.R", "albedo.G", "albedo.B"])?;
    let normal = vectors(["normal.X", "normal.Y", "normal.Z"])?;
    let alpha = find("A").unwrap_or_default();
    let denoised = denoise(width, height, &beauty, &albedo, &normal)?;
    let prefix = format!("{DENOISED_LAYER}.");
    let mut list: Vec<AnyChannel<FlatSamples>> = std::mem::take(&mut layer.channel_data.list)
        .into_iter()
        .filter(|c| !c.name.to_string().starts_with(&prefix))
        .collect();
    for (c, component) in ["R", "G", "B"].into_iter().enumerate() {
        list.push(AnyChannel {
            name: format!("{prefix}{component}").as_str().into(),
            sample_data: FlatSamples::F32(denoised.iter().map(|p| p[c]).collect()),
            quantize_linearly: false,
            sampling: Vec2(1, 1),
        });
    }
    layer.channel_data = AnyChannels::sort(list.into_iter().collect());
    let image = Image {
        attributes: image.attributes,
        layer_data: layer,
    };
    write_sorted(&image, output)?;
    Ok(preview_image(width, height, denoised, &alpha))
}

/// OIDN's `RT` filter through its C API (the `oidn` crate's `sys` bindings), for what the crate's safe wrapper
/// cannot do: a filter over an auxiliary image alone, and the `cleanAux` parameter.
#[allow(unsafe_code)]
mod oidn_c {
    use oidn::sys::{
        oidnCommitFilter, oidnExecuteFilter, oidnNewFilter, oidnReleaseFilter, oidnSetFilterBool,
        oidnSetSharedFilterImage, OIDNFormat_OIDN_FORMAT_FLOAT3,
    };
    use std::ffi::{c_void, CStr};

    /// Why an OIDN filter could not run.
    #[derive(Debug, thiserror::Error)]
    pub(super) enum FilterError {
        /// A buffer of another size than the frame's.
        #[error("an image is not {width}x{height} float3 pixels")]
        ImageSize {
            /// The frame's width.
            width: usize,
            /// The frame's height.
            height: usize,
        },
        /// OIDN made no `RT` filter and reported no error.
        #[error("no RT filter")]
        NoFilter,
        /// OIDN's device reported an error.
        #[error("{0}")]
        Device(oidn::Error),
    }

    /// Runs one `RT` filter on `device` over the float3 images `inputs` (OIDN's image name and the pixels, row
    /// by row), with the boolean parameters `flags`, into `output`. Every buffer must hold width × height × 3
    /// floats; OIDN's error, if any, is returned.
    pub(super) fn run_rt_filter(
        device: &oidn::Device,
        (width, height): (usize, usize),
        inputs: &[(&CStr, &[f32])],
        flags: &[(&CStr, bool)],
        output: &mut [f32],
    ) -> Result<(), FilterError> {
        let len = width * height * 3;
        if output.len() != len || inputs.iter().any(|(_, pixels)| pixels.len() != len) {
            return Err(FilterError::ImageSize { width, height });
        }
        // SAFETY: `device.raw()` stays valid while `device` is borrowed here. The filter is created, used and
        // released within this block. Each shared image points into a slice checked above to hold exactly
        // width × height × 3 floats, which outlives the synchronous `oidnExecuteFilter`; OIDN only reads the
        // inputs (the C API takes every shared image as `void *`) and writes only `output`, which we borrow
        // mutably. Names and parameter names are NUL-terminated C strings.
        unsafe {
            let filter = oidnNewFilter(device.raw(), c"RT".as_ptr());
            if filter.is_null() {
                return device
                    .get_error()
                    .map_err(FilterError::Device)
                    .and(Err(FilterError::NoFilter));
            }
            for (name, pixels) in inputs {
                oidnSetSharedFilterImage(
                    filter,
                    name.as_ptr(),
                    pixels.as_ptr() as *mut c_void,
                    OIDNFormat_OIDN_FORMAT_FLOAT3,
                    width,
                    height,
                    0,
                    0,
                    0,
                );
            }
            oidnSetSharedFilterImage(
                filter,
                c"output".as_ptr(),
                output.as_mut_ptr() as *mut c_void,
                OIDNFormat_OIDN_FORMAT_FLOAT3,
                width,
                height,
                0,
                0,
                0,
            );
            for (name, value) in flags {
                oidnSetFilterBool(filter, name.as_ptr(), *value);
            }
            oidnCommitFilter(filter);
            oidnExecuteFilter(filter);
            oidnReleaseFilter(filter);
        }
        device.get_error().map_err(FilterError::Device)
    }
}
