//! The C API called from Rust: the success path on a tiny scene, and every error path a C caller can hit
//! (null pointers, bad paths, bad settings, unknown channels, small buffers, freed and mistyped handles).

use nimbus_c::*;
use std::ffi::{c_char, c_int, c_void, CStr, CString};
use std::path::Path;
use std::ptr::null_mut;

fn demo_path() -> CString {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/demo.glb");
    CString::new(path.to_str().unwrap()).unwrap()
}

fn last_error() -> String {
    unsafe { CStr::from_ptr(nimbus_last_error()) }
        .to_str()
        .unwrap()
        .to_owned()
}

fn tiny_settings() -> NimbusRenderSettings {
    NimbusRenderSettings {
        width: 6,
        height: 4,
        spp: 2,
        ..nimbus_render_settings_default()
    }
}

fn load_demo() -> *mut NimbusScene {
    let mut scene = null_mut();
    let status = unsafe { nimbus_scene_load(demo_path().as_ptr(), &mut scene) };
    assert_eq!(status, NimbusStatus::Ok, "{}", last_error());
    assert!(!scene.is_null());
    scene
}

fn render(scene: *const NimbusScene) -> *mut NimbusImage {
    let mut image = null_mut();
    let status = unsafe { nimbus_render(scene, &tiny_settings(), None, null_mut(), &mut image) };
    assert_eq!(status, NimbusStatus::Ok, "{}", last_error());
    image
}

#[test]
fn load_render_read_write_and_free() {
    let mut scene = load_demo();
    let mut image = render(scene);
    unsafe {
        let (mut w, mut h, mut spp) = (0, 0, 0);
        assert_eq!(nimbus_image_width(image, &mut w), NimbusStatus::Ok);
        assert_eq!(nimbus_image_height(image, &mut h), NimbusStatus::Ok);
        assert_eq!(
            nimbus_image_samples_per_pixel(image, &mut spp),
            NimbusStatus::Ok
        );
        assert_eq!((w, h, spp), (6, 4, 2));
        assert_eq!(last_error(), "");
        let mut buf = vec![f32::NAN; 24];
        for name in nimbus::channel_names() {
            let name = CString::new(name).unwrap();
            let status = nimbus_image_channel(image, name.as_ptr(), buf.as_mut_ptr(), buf.len());
            assert_eq!(status, NimbusStatus::Ok, "{}", last_error());
            assert!(buf.iter().all(|v| v.is_finite()));
        }
        let dir = std::env::temp_dir().join(format!("nimbus-ffi-api-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let exr = CString::new(dir.join("out.exr").to_str().unwrap()).unwrap();
        let png = CString::new(dir.join("out.png").to_str().unwrap()).unwrap();
        assert_eq!(
            nimbus_image_write_exr(image, exr.as_ptr()),
            NimbusStatus::Ok
        );
        assert_eq!(
            nimbus_image_write_png(image, png.as_ptr(), 0.0),
            NimbusStatus::Ok
        );
        assert!(dir.join("out.exr").is_file() && dir.join("out.png").is_file());
        std::fs::remove_dir_all(&dir).ok();

        assert_eq!(nimbus_scene_free(&mut scene), NimbusStatus::Ok);
        assert!(scene.is_null(), "free nulls the caller's pointer");
        assert_eq!(
            nimbus_scene_free(&mut scene),
            NimbusStatus::Ok,
            "second free is a no-op"
        );
        // The image outlives its scene.
        assert_eq!(nimbus_image_width(image, &mut w), NimbusStatus::Ok);
        assert_eq!(nimbus_image_free(&mut image), NimbusStatus::Ok);
        assert!(image.is_null());
        // Use after free through the nulled pointer is a null-pointer error, not a crash.
        assert_eq!(nimbus_image_width(image, &mut w), NimbusStatus::NullPointer);
        assert!(last_error().contains("image"), "{}", last_error());
    }
}

/// A scene without light of its own renders lit, as from the CLI: a Lambertian triangle (OBJ's default albedo,
/// 0.8) alone under the default environment reflects exactly 0.8 of its radiance wherever it is seen (a convex
/// object sees the whole environment), and the background is the environment itself, so every pixel lies between
/// 0.8 and 1 times `DEFAULT_ENVIRONMENT_RADIANCE`. Unlit, the image was black.
#[test]
fn an_unlit_scene_is_lit_by_the_default_environment() {
    let dir = std::env::temp_dir().join(format!("nimbus-ffi-unlit-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let obj = dir.join("triangle.obj");
    std::fs::write(&obj, "v -1 -1 0\nv 1 -1 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    let path = CString::new(obj.to_str().unwrap()).unwrap();
    unsafe {
        let mut scene = null_mut();
        let status = nimbus_scene_load(path.as_ptr(), &mut scene);
        assert_eq!(status, NimbusStatus::Ok, "{}", last_error());
        let settings = NimbusRenderSettings {
            width: 8,
            height: 8,
            spp: 64,
            ..nimbus_render_settings_default()
        };
        let mut image = null_mut();
        let status = nimbus_render(scene, &settings, None, null_mut(), &mut image);
        assert_eq!(status, NimbusStatus::Ok, "{}", last_error());
        let mut red = vec![f32::NAN; 64];
        let name = CString::new("R").unwrap();
        let status = nimbus_image_channel(image, name.as_ptr(), red.as_mut_ptr(), red.len());
        assert_eq!(status, NimbusStatus::Ok, "{}", last_error());
        let mean = red.iter().map(|&v| v as f64).sum::<f64>() / red.len() as f64;
        let radiance = nimbus::scene::DEFAULT_ENVIRONMENT_RADIANCE as f64;
        // The bound's ends are the closed form; the margin is far above 64 spp's noise of a pixel mean.
        assert!(
            (0.75 * radiance..=1.05 * radiance).contains(&mean),
            "mean red {mean} outside [0.8, 1] x {radiance}"
        );
        assert_eq!(nimbus_image_free(&mut image), NimbusStatus::Ok);
        assert_eq!(nimbus_scene_free(&mut scene), NimbusStatus::Ok);
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_bad_path_names_the_file() {
    let mut scene = std::ptr::dangling_mut::<NimbusScene>(); // garbage that must be overwritten
    let path = CString::new("/no/such/dir/cloud.glb").unwrap();
    let status = unsafe { nimbus_scene_load(path.as_ptr(), &mut scene) };
    assert_eq!(status, NimbusStatus::SceneError);
    assert!(scene.is_null());
    assert!(
        last_error().contains("/no/such/dir/cloud.glb"),
        "{}",
        last_error()
    );

    let path = CString::new("scene.txt").unwrap();
    let status = unsafe { nimbus_scene_load(path.as_ptr(), &mut scene) };
    assert_eq!(status, NimbusStatus::SceneError);
    assert!(last_error().contains("scene.txt"), "{}", last_error());
}

#[test]
fn null_pointers_are_errors() {
    unsafe {
        let mut scene = null_mut();
        assert_eq!(
            nimbus_scene_load(std::ptr::null(), &mut scene),
            NimbusStatus::NullPointer
        );
        assert!(last_error().contains("path"), "{}", last_error());
        assert_eq!(
            nimbus_scene_load(demo_path().as_ptr(), null_mut()),
            NimbusStatus::NullPointer
        );
        let mut image = null_mut();
        let settings = tiny_settings();
        assert_eq!(
            nimbus_render(std::ptr::null(), &settings, None, null_mut(), &mut image),
            NimbusStatus::NullPointer
        );
        let mut w = 0;
        assert_eq!(
            nimbus_image_width(std::ptr::null(), &mut w),
            NimbusStatus::NullPointer
        );
        assert_eq!(
            nimbus_image_height(std::ptr::null(), &mut w),
            NimbusStatus::NullPointer
        );
        let name = CString::new("R").unwrap();
        assert_eq!(
            nimbus_image_channel(std::ptr::null(), name.as_ptr(), null_mut(), 0),
            NimbusStatus::NullPointer
        );
        assert_eq!(
            nimbus_image_write_exr(std::ptr::null(), name.as_ptr()),
            NimbusStatus::NullPointer
        );

        let scene = load_demo();
        assert_eq!(
            nimbus_render(scene, std::ptr::null(), None, null_mut(), &mut image),
            NimbusStatus::NullPointer
        );
        assert!(last_error().contains("settings"), "{}", last_error());
        assert_eq!(
            nimbus_render(scene, &settings, None, null_mut(), null_mut()),
            NimbusStatus::NullPointer
        );
        let mut image = render(scene);
        assert_eq!(
            nimbus_image_width(image, null_mut()),
            NimbusStatus::NullPointer
        );
        assert_eq!(
            nimbus_image_channel(image, std::ptr::null(), [0f32; 24].as_mut_ptr(), 24),
            NimbusStatus::NullPointer
        );
        assert_eq!(
            nimbus_image_channel(image, name.as_ptr(), null_mut(), 24),
            NimbusStatus::NullPointer
        );
        assert_eq!(
            nimbus_image_write_png(image, std::ptr::null(), 0.0),
            NimbusStatus::NullPointer
        );
        nimbus_image_free(&mut image);
        let mut scene = scene;
        nimbus_scene_free(&mut scene);
    }
}

#[test]
fn freeing_null_is_a_no_op() {
    unsafe {
        assert_eq!(nimbus_scene_free(null_mut()), NimbusStatus::Ok);
        assert_eq!(nimbus_image_free(null_mut()), NimbusStatus::Ok);
        let mut scene: *mut NimbusScene = null_mut();
        let mut image: *mut NimbusImage = null_mut();
        assert_eq!(nimbus_scene_free(&mut scene), NimbusStatus::Ok);
        assert_eq!(nimbus_image_free(&mut image), NimbusStatus::Ok);
    }
}

#[test]
fn a_handle_of_the_wrong_type_is_rejected() {
    unsafe {
        let mut scene = load_demo();
        let mut image = render(scene);
        // An image passed as a scene, and a scene passed as an image.
        let mut out = null_mut();
        let status = nimbus_render(
            image.cast::<NimbusScene>(),
            &tiny_settings(),
            None,
            null_mut(),
            &mut out,
        );
        assert_eq!(status, NimbusStatus::InvalidHandle);
        assert!(out.is_null());
        assert!(last_error().contains("scene"), "{}", last_error());
        let mut w = 0;
        assert_eq!(
            nimbus_image_width(scene.cast::<NimbusImage>(), &mut w),
            NimbusStatus::InvalidHandle
        );
        // Freeing through the wrong function frees nothing.
        let mut wrong = scene.cast::<NimbusImage>();
        assert_eq!(nimbus_image_free(&mut wrong), NimbusStatus::InvalidHandle);
        assert!(!wrong.is_null());
        assert_eq!(nimbus_image_free(&mut image), NimbusStatus::Ok);
        assert_eq!(nimbus_scene_free(&mut scene), NimbusStatus::Ok);
    }
}

/// A copy of a freed handle stays invalid, even after new handles are made (which may reuse its memory), and
/// a pointer that never was a handle is refused without being read.
#[test]
fn stale_and_foreign_handles_are_rejected() {
    unsafe {
        let mut scene = load_demo();
        let stale = scene;
        assert_eq!(nimbus_scene_free(&mut scene), NimbusStatus::Ok);
        let mut fresh = load_demo();
        let mut image = render(fresh);
        let mut out = null_mut();
        let status = nimbus_render(stale, &tiny_settings(), None, null_mut(), &mut out);
        assert_eq!(status, NimbusStatus::InvalidHandle);
        let mut copy = stale;
        assert_eq!(nimbus_scene_free(&mut copy), NimbusStatus::InvalidHandle);
        let foreign = 0x1234_5678usize as *mut NimbusImage;
        let mut w = 0;
        assert_eq!(
            nimbus_image_width(foreign, &mut w),
            NimbusStatus::InvalidHandle
        );
        assert_eq!(nimbus_image_free(&mut image), NimbusStatus::Ok);
        assert_eq!(nimbus_scene_free(&mut fresh), NimbusStatus::Ok);
    }
}

#[test]
fn bad_arguments_are_reported() {
    unsafe {
        let mut scene = load_demo();
        let mut image = null_mut();
        for settings in [
            NimbusRenderSettings {
                width: 0,
                ..tiny_settings()
            },
            NimbusRenderSettings {
                height: 40_000,
                ..tiny_settings()
            },
            NimbusRenderSettings {
                width: 32768,
                height: 32768,
                ..tiny_settings()
            },
            NimbusRenderSettings {
                spp: 0,
                ..tiny_settings()
            },
            NimbusRenderSettings {
                time_limit_seconds: -1.0,
                ..tiny_settings()
            },
            NimbusRenderSettings {
                time_limit_seconds: f64::NAN,
                ..tiny_settings()
            },
            NimbusRenderSettings {
                guiding: 3,
                ..tiny_settings()
            },
        ] {
            let status = nimbus_render(scene, &settings, None, null_mut(), &mut image);
            assert_eq!(status, NimbusStatus::InvalidArgument, "{settings:?}");
            assert!(image.is_null());
            assert!(!last_error().is_empty());
        }
        let mut image = render(scene);
        let mut buf = [0f32; 24];
        let name = CString::new("albedo.Q").unwrap();
        assert_eq!(
            nimbus_image_channel(image, name.as_ptr(), buf.as_mut_ptr(), buf.len()),
            NimbusStatus::InvalidArgument
        );
        assert!(last_error().contains("albedo.Q"), "{}", last_error());
        let name = CString::new("G").unwrap();
        assert_eq!(
            nimbus_image_channel(image, name.as_ptr(), buf.as_mut_ptr(), 23),
            NimbusStatus::BufferTooSmall
        );
        assert!(last_error().contains("24"), "{}", last_error());
        let bad_utf8 = [0xffu8, 0];
        assert_eq!(
            nimbus_image_write_exr(image, bad_utf8.as_ptr().cast()),
            NimbusStatus::InvalidArgument
        );
        let unwritable = CString::new("/no/such/dir/out.exr").unwrap();
        assert_eq!(
            nimbus_image_write_exr(image, unwritable.as_ptr()),
            NimbusStatus::OutputError
        );
        assert!(
            last_error().contains("/no/such/dir/out.exr"),
            "{}",
            last_error()
        );
        assert_eq!(
            nimbus_image_write_png(image, unwritable.as_ptr(), f32::INFINITY),
            NimbusStatus::InvalidArgument
        );
        nimbus_image_free(&mut image);
        nimbus_scene_free(&mut scene);
    }
}

/// Cancels after the first pass and counts the calls.
unsafe extern "C" fn cancel_after_first(fraction: f32, spp: u32, user_data: *mut c_void) -> c_int {
    let calls = &mut *user_data.cast::<u32>();
    *calls += 1;
    assert!((0.0..=1.0).contains(&fraction) && spp >= 1);
    0
}

#[test]
fn the_progress_callback_cancels_and_the_partial_image_is_returned() {
    unsafe {
        let mut scene = load_demo();
        let mut image = null_mut();
        let mut calls = 0u32;
        let settings = NimbusRenderSettings {
            spp: 32,
            ..tiny_settings()
        };
        let status = nimbus_render(
            scene,
            &settings,
            Some(cancel_after_first),
            (&mut calls as *mut u32).cast(),
            &mut image,
        );
        assert_eq!(status, NimbusStatus::Cancelled);
        assert_eq!(calls, 1);
        assert!(!image.is_null());
        let mut spp = 0;
        assert_eq!(
            nimbus_image_samples_per_pixel(image, &mut spp),
            NimbusStatus::Ok
        );
        assert_eq!(spp, 2, "one pass of 32 / 16 samples");
        nimbus_image_free(&mut image);
        nimbus_scene_free(&mut scene);
    }
}

#[test]
fn errors_are_per_thread() {
    let path = CString::new("elsewhere.glb").unwrap();
    let mut scene = null_mut();
    assert_eq!(
        unsafe { nimbus_scene_load(path.as_ptr(), &mut scene) },
        NimbusStatus::SceneError
    );
    let other = std::thread::spawn(last_error).join().unwrap();
    assert_eq!(other, "");
    assert!(last_error().contains("elsewhere.glb"));
}

/// `guiding` is the CLI's `--guiding`: 1 (on) trains a cache and guides, 2 (off) does not, and the default 0
/// (auto) leaves a render of fewer than 16 samples per pixel unguided, as off does, bit for bit.
#[test]
fn guiding_is_chosen_by_the_settings() {
    unsafe {
        let mut scene = load_demo();
        let beauty = |guiding: u32| {
            let settings = NimbusRenderSettings {
                spp: 4,
                guiding,
                ..tiny_settings()
            };
            let mut image = null_mut();
            let status = nimbus_render(scene, &settings, None, null_mut(), &mut image);
            assert_eq!(status, NimbusStatus::Ok, "{}", last_error());
            let mut pixels = vec![f32::NAN; 24];
            let name = CString::new("R").unwrap();
            let status = nimbus_image_channel(image, name.as_ptr(), pixels.as_mut_ptr(), 24);
            assert_eq!(status, NimbusStatus::Ok, "{}", last_error());
            nimbus_image_free(&mut image);
            pixels
        };
        let (auto, on, off) = (beauty(0), beauty(1), beauty(2));
        assert!(on.iter().chain(&off).all(|v| v.is_finite()));
        assert_eq!(auto, off, "auto below 16 spp renders unguided");
        assert_ne!(on, off, "a guided render's paths differ from unguided ones");
        nimbus_scene_free(&mut scene);
    }
}

#[test]
fn layers_are_chosen_listed_and_returned() {
    unsafe {
        let mut scene = load_demo();
        let aovs = CString::new("lightpaths,colors,lightgroups,CryptoObject").unwrap();
        let settings = NimbusRenderSettings {
            aovs: aovs.as_ptr(),
            transparent: 1,
            light_groups: 1,
            cryptomatte_depth: 2,
            ..tiny_settings()
        };
        let mut image = null_mut();
        let status = nimbus_render(scene, &settings, None, null_mut(), &mut image);
        assert_eq!(status, NimbusStatus::Ok, "{}", last_error());
        let mut count = 0usize;
        assert_eq!(
            nimbus_image_channel_count(image, &mut count),
            NimbusStatus::Ok
        );
        // Beauty RGBA, 10 light paths, 3 colours, the one light group of demo.glb (its emissive mesh "light"),
        // one Cryptomatte layer.
        assert_eq!(count, 4 + 3 * (10 + 3 + 1) + 4);
        let mut names = Vec::new();
        let mut buf = vec![0 as c_char; 64];
        for i in 0..count {
            let status = nimbus_image_channel_name(image, i, buf.as_mut_ptr(), buf.len());
            assert_eq!(status, NimbusStatus::Ok, "{}", last_error());
            names.push(CStr::from_ptr(buf.as_ptr()).to_str().unwrap().to_owned());
        }
        for name in ["A", "diffuse_direct.R", "lg_light.B", "CryptoObject00.r"] {
            assert!(names.iter().any(|n| n == name), "{name} in {names:?}");
        }
        let mut samples = vec![f32::NAN; 24];
        for name in &names {
            let name = CString::new(name.as_str()).unwrap();
            let status = nimbus_image_channel(image, name.as_ptr(), samples.as_mut_ptr(), 24);
            assert_eq!(status, NimbusStatus::Ok, "{}", last_error());
            assert!(samples.iter().all(|v| v.is_finite()));
        }
        // Out of range, too small a buffer, a layer the image does not have, an unknown layer name.
        assert_eq!(
            nimbus_image_channel_name(image, count, buf.as_mut_ptr(), buf.len()),
            NimbusStatus::InvalidArgument
        );
        assert_eq!(
            nimbus_image_channel_name(image, 0, buf.as_mut_ptr(), 1),
            NimbusStatus::BufferTooSmall
        );
        let albedo = CString::new("albedo.R").unwrap();
        assert_eq!(
            nimbus_image_channel(image, albedo.as_ptr(), samples.as_mut_ptr(), 24),
            NimbusStatus::InvalidArgument
        );
        let bad = CString::new("lightpath").unwrap();
        let settings = NimbusRenderSettings {
            aovs: bad.as_ptr(),
            ..tiny_settings()
        };
        let mut other = null_mut();
        assert_eq!(
            nimbus_render(scene, &settings, None, null_mut(), &mut other),
            NimbusStatus::InvalidArgument
        );
        assert!(last_error().contains("lightpath"), "{}", last_error());
        assert_eq!(nimbus_image_free(&mut image), NimbusStatus::Ok);
        assert_eq!(nimbus_scene_free(&mut scene), NimbusStatus::Ok);
    }
}
