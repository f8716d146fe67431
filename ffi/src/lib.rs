//! The C API of Nimbus: load a scene, render it with a progress callback that can cancel, read the image's
//! channels and write EXR and PNG files, through opaque handles. The header is `include/nimbus.h`, generated
//! from this file by cbindgen (`cbindgen.toml`); the test `header_is_up_to_date` fails when it is stale and
//! rewrites it when run with `NIMBUS_BLESS_HEADER=1`.
//!
//! Rules every function follows (the header repeats them):
//! - It returns a [`NimbusStatus`]; on failure [`nimbus_last_error`] gives this thread's message.
//! - No panic crosses the boundary: each body runs under `catch_unwind`, and a panic becomes
//!   [`NimbusStatus::Panic`].
//! - A null pointer gives [`NimbusStatus::NullPointer`]; a pointer that is not a live handle of the expected
//!   kind (freed already, another kind of handle, or never a handle) gives [`NimbusStatus::InvalidHandle`]:
//!   every live handle is in a registry, which is checked before the pointer is read.
//! - Handles may be used from any thread, by several threads at once, and a handle may be freed from any
//!   thread at any time, even while a call on another thread uses it: each call holds its own reference to the
//!   handle's value until it returns, so that call finishes as if the free had come after it (its memory is
//!   released when the last such call returns), and every call that starts after the free gives
//!   [`NimbusStatus::InvalidHandle`]. (As with any variable one thread writes, two threads must not free through
//!   the same pointer variable at once; they may free through copies.)
//! - Output handles are written only on success (and, for [`nimbus_render`], on cancellation); on any other
//!   status they are set to null.
//! - Handles are freed with `nimbus_*_free(&handle)`, which nulls the caller's pointer, so freeing twice through
//!   the same variable is a no-op; freeing null is a no-op.

use nimbus::render::{
    AovSelection, GuidingMode, LightGroupMode, RenderImage, RenderSettings, RenderStats, Renderer,
};
use nimbus::scene::{load_builder, LoadOptions};
use nimbus::{Error, Scene};
use std::any::Any;
use std::cell::RefCell;
use std::collections::BTreeMap;
use std::ffi::{c_char, c_int, c_void, CStr, CString};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

/// The outcome of a call.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NimbusStatus {
    /// Success.
    Ok = 0,
    /// A required pointer argument was null.
    NullPointer = 1,
    /// A handle was not a live handle of the expected type.
    InvalidHandle = 2,
    /// An argument was out of range or malformed (bad settings, unknown channel, path not UTF-8...).
    InvalidArgument = 3,
    /// A scene file could not be loaded; the message names the file.
    SceneError = 4,
    /// An image file could not be written; the message names the file.
    OutputError = 5,
    /// The renderer could not run (its worker threads could not start).
    RenderError = 6,
    /// The progress callback asked to stop; the partial image is still returned.
    Cancelled = 7,
    /// The caller's buffer is smaller than the data to copy.
    BufferTooSmall = 8,
    /// An internal error (a Rust panic) was caught at the boundary.
    Panic = 9,
}

/// A loaded scene. Opaque: create with `nimbus_scene_load()`, free with `nimbus_scene_free()`.
pub struct NimbusScene {
    _opaque: [u8; 0],
}

/// A rendered image with its AOV layers. Opaque: create with `nimbus_render()`, free with
/// `nimbus_image_free()`.
pub struct NimbusImage {
    _opaque: [u8; 0],
}

/// What an image handle holds.
struct ImageData {
    image: RenderImage,
    stats: RenderStats,
}

/// How to render, for `nimbus_render()`. Start from `nimbus_render_settings_default()` and change fields.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NimbusRenderSettings {
    /// Image width in pixels, 1 to 32768.
    pub width: u32,
    /// Image height in pixels, 1 to 32768 (and at most 2^26 pixels in all).
    pub height: u32,
    /// Samples per pixel to reach, at least 1.
    pub spp: u32,
    /// Maximum scattering events per path.
    pub max_depth: u32,
    /// Worker threads; 0 uses every core.
    pub threads: u32,
    /// Seed of every random stream: the same seed gives the same image.
    pub seed: u64,
    /// Wall-clock budget in seconds; 0 means none. The render stops after the pass in which it runs out.
    pub time_limit_seconds: f64,
    /// The layers to write beyond the beauty and alpha, as the CLI's `--aovs` takes them (comma-separated
    /// layer and set names: `lightpaths`, `lg_key`, `cryptomatte`...); null for the defaults (the first-hit
    /// layers, `environment` on a transparent film, light groups, `shadow_catcher`).
    pub aovs: *const c_char,
    /// Non-zero for a transparent film: the environment seen directly is left out of the beauty.
    pub transparent: u32,
    /// Light groups: 0 the scene's declared groups, 1 one group per emitter, 2 none.
    pub light_groups: u32,
    /// Cryptomatte ranks per pixel, 1 to 16 (0: the default, 6).
    pub cryptomatte_depth: u32,
    /// Path guiding, as the CLI's `--guiding`: 0 auto (the default: guided where a pilot of unguided paths
    /// finds that it pays), 1 on, 2 off.
    pub guiding: u32,
}

/// Progress callback of `nimbus_render()`, called on the rendering thread after every pass with the fraction
/// done in \[0, 1\], the samples per pixel done so far and the caller's `user_data`. Return non-zero to go on,
/// zero to cancel.
pub type NimbusProgressFn =
    Option<unsafe extern "C" fn(fraction: f32, spp: u32, user_data: *mut c_void) -> c_int>;

const MAX_SIDE: u32 = 32768;
const MAX_PIXELS: u64 = 1 << 26;

thread_local! {
    /// This thread's last error message (empty after a successful call).
    static LAST_ERROR: RefCell<CString> = RefCell::new(CString::default());
}

/// A failed call: its status and message.
struct Failure {
    status: NimbusStatus,
    message: String,
}

impl Failure {
    fn new(status: NimbusStatus, message: impl Into<String>) -> Self {
        Self {
            status,
            message: message.into(),
        }
    }

    fn null(what: &str) -> Self {
        Self::new(NimbusStatus::NullPointer, format!("{what} is null"))
    }
}

impl From<Error> for Failure {
    fn from(e: Error) -> Self {
        let status = match e {
            Error::Scene(_) | Error::Vdb(_) => NimbusStatus::SceneError,
            Error::Output(_) | Error::Farm(_) => NimbusStatus::OutputError,
            Error::Render(_) | Error::Region(_) | Error::Converge(_) => NimbusStatus::RenderError,
        };
        Self::new(status, e.to_string())
    }
}

fn set_last_error(message: String) {
    let message = CString::new(message.replace('\0', " ")).unwrap_or_default();
    LAST_ERROR.with(|e| *e.borrow_mut() = message);
}

/// Runs `body` with the error slot cleared, catching panics, and turns its outcome into a status.
fn call(body: impl FnOnce() -> Result<NimbusStatus, Failure>) -> NimbusStatus {
    set_last_error(String::new());
    let outcome = catch_unwind(AssertUnwindSafe(body)).unwrap_or_else(|payload| {
        let what = payload
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| payload.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "unknown panic".into());
        Err(Failure::new(
            NimbusStatus::Panic,
            format!("internal error: {what}"),
        ))
    });
    match outcome {
        Ok(status) => status,
        Err(f) => {
            set_last_error(f.message);
            f.status
        }
    }
}

/// A live handle's value, shared: the registry holds one reference, and every call that uses the handle holds
/// another for as long as it runs.
type Shared = Arc<dyn Any + Send + Sync>;

/// Every live handle by id, with its value. The pointers handed to C are these ids, never addresses: C never
/// dereferences them, a pointer is looked up here before every use, and ids are never reused, so a freed,
/// foreign or mistyped handle is refused whatever the memory it once named now holds. A free removes the entry
/// and drops the registry's reference; a call that looked the handle up before keeps the value alive until it
/// returns, so a handle may be freed from any thread at any time.
static LIVE_HANDLES: Mutex<BTreeMap<usize, Shared>> = Mutex::new(BTreeMap::new());

/// The next handle id (a multiple of 16, never 0, never reused).
static NEXT_HANDLE: AtomicUsize = AtomicUsize::new(16);

/// Runs `f` on the registry, even if a panic poisoned its lock (the map itself is always consistent).
fn with_live_handles<R>(f: impl FnOnce(&mut BTreeMap<usize, Shared>) -> R) -> R {
    f(&mut LIVE_HANDLES.lock().unwrap_or_else(PoisonError::into_inner))
}

/// An opaque handle type: an id handed to C for a value the registry shares.
trait Handle: Sized {
    /// What the handle holds.
    type Value: Any + Send + Sync;
    /// The handle's name in messages.
    const WHAT: &'static str;

    /// Moves `value` into the registry and returns its new handle.
    fn into_raw(value: Self::Value) -> *mut Self {
        let id = NEXT_HANDLE.fetch_add(16, Ordering::Relaxed);
        with_live_handles(|live| live.insert(id, Arc::new(value)));
        // An id, not an address: a pointer without provenance, never dereferenced.
        std::ptr::without_provenance_mut(id)
    }

    /// The failure for a pointer that is not a live handle of this type.
    fn not_live() -> Failure {
        Failure::new(
            NimbusStatus::InvalidHandle,
            format!(
                "{} is not a live handle of its type (freed, or another kind of handle)",
                Self::WHAT
            ),
        )
    }

    /// The value of the live handle `p`, shared with the registry: it stays alive while the caller holds it,
    /// even when another thread frees the handle meanwhile.
    fn get(p: *const Self) -> Result<Arc<Self::Value>, Failure> {
        if p.is_null() {
            return Err(Failure::null(Self::WHAT));
        }
        with_live_handles(|live| live.get(&p.addr()).cloned())
            .and_then(|value| value.downcast().ok())
            .ok_or_else(Self::not_live)
    }

    /// Frees the handle `*slot` holds, if any, and nulls `*slot`. The value is dropped here unless a call on
    /// another thread still uses it; then it is dropped when the last such call returns.
    ///
    /// # Safety
    /// `slot` must be null or point to a readable and writable pointer.
    unsafe fn free(slot: *mut *mut Self) -> Result<(), Failure> {
        if slot.is_null() || (*slot).is_null() {
            return Ok(());
        }
        let id = (*slot).addr();
        let value = with_live_handles(|live| match live.get(&id) {
            Some(value) if (**value).is::<Self::Value>() => live.remove(&id),
            _ => None,
        })
        .ok_or_else(Self::not_live)?;
        // Outside the lock: dropping a scene takes a while, and other threads look handles up meanwhile.
        drop(value);
        *slot = std::ptr::null_mut();
        Ok(())
    }
}

impl Handle for NimbusScene {
    type Value = Scene;
    const WHAT: &'static str = "scene";
}

impl Handle for NimbusImage {
    type Value = ImageData;
    const WHAT: &'static str = "image";
}

/// Reads a NUL-terminated UTF-8 string argument.
unsafe fn c_str<'a>(p: *const c_char, what: &str) -> Result<&'a str, Failure> {
    if p.is_null() {
        return Err(Failure::null(what));
    }
    CStr::from_ptr(p).to_str().map_err(|_| {
        Failure::new(
            NimbusStatus::InvalidArgument,
            format!("{what} is not UTF-8"),
        )
    })
}

/// Writes `value` through the out-pointer `out`, failing on null.
unsafe fn put<T>(out: *mut T, value: T, what: &str) -> Result<(), Failure> {
    if out.is_null() {
        return Err(Failure::null(what));
    }
    out.write(value);
    Ok(())
}

/// Checks C settings and converts them.
///
/// # Safety
/// `s.aovs` must be null or a NUL-terminated string.
unsafe fn convert_settings(s: &NimbusRenderSettings) -> Result<RenderSettings, Failure> {
    let invalid = |m: String| Failure::new(NimbusStatus::InvalidArgument, m);
    if s.width == 0 || s.height == 0 || s.width > MAX_SIDE || s.height > MAX_SIDE {
        return Err(invalid(format!(
            "image size {}x{} is not within 1..={MAX_SIDE} on each side",
            s.width, s.height
        )));
    }
    if u64::from(s.width) * u64::from(s.height) > MAX_PIXELS {
        return Err(invalid(format!(
            "image size {}x{} has more than {MAX_PIXELS} pixels",
            s.width, s.height
        )));
    }
    if s.spp == 0 {
        return Err(invalid(
            "spp is 0; at least 1 sample per pixel is needed".into(),
        ));
    }
    let time_limit = match s.time_limit_seconds {
        0.0 => None,
        t if t.is_finite() && t > 0.0 => Some(Duration::from_secs_f64(t)),
        t => {
            return Err(invalid(format!(
                "time_limit_seconds {t} is not a non-negative number of seconds"
            )))
        }
    };
    let aovs = if s.aovs.is_null() {
        None
    } else {
        let list = c_str(s.aovs, "settings.aovs")?;
        Some(AovSelection::parse(list).map_err(|e| invalid(e.to_string()))?)
    };
    let light_groups = match s.light_groups {
        0 => LightGroupMode::Scene,
        1 => LightGroupMode::PerLight,
        2 => LightGroupMode::Off,
        g => {
            return Err(invalid(format!(
                "light_groups {g} is not 0 (scene), 1 (per light) or 2 (off)"
            )))
        }
    };
    let guiding = match s.guiding {
        0 => GuidingMode::Auto,
        1 => GuidingMode::On,
        2 => GuidingMode::Off,
        g => {
            return Err(invalid(format!(
                "guiding {g} is not 0 (auto), 1 (on) or 2 (off)"
            )))
        }
    };
    Ok(RenderSettings {
        width: s.width as usize,
        height: s.height as usize,
        spp: s.spp,
        seed: s.seed,
        threads: s.threads as usize,
        max_depth: s.max_depth,
        time_limit,
        media_mis: true,
        aovs,
        transparent: s.transparent != 0,
        light_groups,
        cryptomatte_depth: match s.cryptomatte_depth {
            0 => nimbus::render::cryptomatte::DEFAULT_DEPTH,
            d => d as usize,
        },
        guiding,
        ..RenderSettings::default()
    })
}

/// The message of the last failed call on the calling thread, or an empty string when the last call
/// succeeded. Never null. The text stays valid until the next `nimbus_*` call on this thread.
#[no_mangle]
pub extern "C" fn nimbus_last_error() -> *const c_char {
    LAST_ERROR.with(|e| e.borrow().as_ptr())
}

/// The default render settings: 640x480, 64 spp, max depth 64, every core, seed 0, no time limit, the
/// default layers, an opaque film, the scene's light groups, 6 Cryptomatte ranks, guiding auto.
#[no_mangle]
pub extern "C" fn nimbus_render_settings_default() -> NimbusRenderSettings {
    let d = RenderSettings::default();
    NimbusRenderSettings {
        width: d.width as u32,
        height: d.height as u32,
        spp: d.spp,
        max_depth: d.max_depth,
        threads: d.threads as u32,
        seed: d.seed,
        time_limit_seconds: 0.0,
        aovs: std::ptr::null(),
        transparent: 0,
        light_groups: 0,
        cryptomatte_depth: d.cryptomatte_depth as u32,
        guiding: 0,
    }
}

/// Loads a scene file (`.gltf`, `.glb`, `.obj`, `.usd`, `.usda`, `.usdc` or `.usdz`, chosen by extension) into `*out_scene`.
///
/// A scene without light of its own (no light, emitter, environment or emitting medium that lights it) gets a
/// uniform white environment of radiance 1, as `nimbus render` and Python's `nimbus.load` give it.
///
/// On failure `*out_scene` is set to null, the status is `NIMBUS_STATUS_SCENE_ERROR` (or another) and
/// `nimbus_last_error()` names the file and what is wrong.
///
/// # Safety
/// `path` must be null or a NUL-terminated UTF-8 string; `out_scene` must be null or point to writable storage
/// for a pointer.
#[no_mangle]
pub unsafe extern "C" fn nimbus_scene_load(
    path: *const c_char,
    out_scene: *mut *mut NimbusScene,
) -> NimbusStatus {
    call(|| {
        put(out_scene, std::ptr::null_mut(), "out_scene")?;
        let path = PathBuf::from(c_str(path, "path")?);
        // Lit as the CLI and the Python module light it: a scene without light of its own gets the neutral
        // environment, so that the three interfaces give one image.
        let mut builder = load_builder(&path, &LoadOptions::default()).map_err(Error::from)?;
        builder.light_by_default();
        let scene = builder.build().map_err(Error::from)?;
        *out_scene = NimbusScene::into_raw(scene);
        Ok(NimbusStatus::Ok)
    })
}

/// Frees the scene `*scene` and sets `*scene` to null. A null `scene` or `*scene` is a no-op. Images rendered
/// from the scene stay valid.
///
/// Any thread may free the scene at any time, even while `nimbus_render()` renders it on another thread: that
/// render finishes normally and the scene's memory is released when it returns; renders that start after the
/// free give `NIMBUS_STATUS_INVALID_HANDLE`.
///
/// # Safety
/// `scene` must be null or point to a pointer that is null or was returned by `nimbus_scene_load()`.
#[no_mangle]
pub unsafe extern "C" fn nimbus_scene_free(scene: *mut *mut NimbusScene) -> NimbusStatus {
    call(|| {
        NimbusScene::free(scene)?;
        Ok(NimbusStatus::Ok)
    })
}

/// Renders `scene` with `settings` into a new image stored in `*out_image`.
///
/// `progress` (may be null) is called on the calling thread after every pass with `user_data`; when it returns
/// zero the render stops, `*out_image` receives the partial image and the status is `NIMBUS_STATUS_CANCELLED`.
/// On `NIMBUS_STATUS_OK` and `NIMBUS_STATUS_CANCELLED` the caller owns `*out_image` and frees it with
/// `nimbus_image_free()`; on any other status `*out_image` is null.
///
/// Another thread may free `scene` during the render: the render keeps the scene's value alive until it returns,
/// and its image is the one it would have made without the free.
///
/// # Safety
/// `scene` must be null or a handle from `nimbus_scene_load()`; `settings` must be null or point to settings;
/// `out_image` must be null or point to writable storage for a pointer; `progress` must be safe to call with
/// `user_data` from this thread.
#[no_mangle]
pub unsafe extern "C" fn nimbus_render(
    scene: *const NimbusScene,
    settings: *const NimbusRenderSettings,
    progress: NimbusProgressFn,
    user_data: *mut c_void,
    out_image: *mut *mut NimbusImage,
) -> NimbusStatus {
    call(|| {
        put(out_image, std::ptr::null_mut(), "out_image")?;
        let scene = NimbusScene::get(scene)?;
        let settings = settings.as_ref().ok_or_else(|| Failure::null("settings"))?;
        let renderer = Renderer::new(convert_settings(settings)?);
        let mut report = |p: &nimbus::Progress| match progress {
            Some(f) => f(p.fraction as f32, p.samples_done, user_data) != 0,
            None => true,
        };
        let (image, stats) = renderer.render(&scene, &mut report).map_err(Error::from)?;
        let status = if stats.cancelled {
            set_last_error("the progress callback cancelled the render".into());
            NimbusStatus::Cancelled
        } else {
            NimbusStatus::Ok
        };
        *out_image = NimbusImage::into_raw(ImageData { image, stats });
        Ok(status)
    })
}

/// Frees the image `*image` and sets `*image` to null. A null `image` or `*image` is a no-op.
///
/// Any thread may free the image at any time, even while a `nimbus_image_*()` call on another thread reads it:
/// that call finishes normally and the image's memory is released when it returns; calls that start after the
/// free give `NIMBUS_STATUS_INVALID_HANDLE`.
///
/// # Safety
/// `image` must be null or point to a pointer that is null or was returned by `nimbus_render()`.
#[no_mangle]
pub unsafe extern "C" fn nimbus_image_free(image: *mut *mut NimbusImage) -> NimbusStatus {
    call(|| {
        NimbusImage::free(image)?;
        Ok(NimbusStatus::Ok)
    })
}

/// Stores the image width in pixels in `*out_width`.
///
/// # Safety
/// `image` must be null or a handle from `nimbus_render()`; `out_width` must be null or writable.
#[no_mangle]
pub unsafe extern "C" fn nimbus_image_width(
    image: *const NimbusImage,
    out_width: *mut u32,
) -> NimbusStatus {
    call(|| {
        let data = NimbusImage::get(image)?;
        put(out_width, data.image.width as u32, "out_width")?;
        Ok(NimbusStatus::Ok)
    })
}

/// Stores the image height in pixels in `*out_height`.
///
/// # Safety
/// `image` must be null or a handle from `nimbus_render()`; `out_height` must be null or writable.
#[no_mangle]
pub unsafe extern "C" fn nimbus_image_height(
    image: *const NimbusImage,
    out_height: *mut u32,
) -> NimbusStatus {
    call(|| {
        let data = NimbusImage::get(image)?;
        put(out_height, data.image.height as u32, "out_height")?;
        Ok(NimbusStatus::Ok)
    })
}

/// Stores in `*out_spp` the samples per pixel the render completed (fewer than asked when it was cancelled or
/// ran out of time).
///
/// # Safety
/// `image` must be null or a handle from `nimbus_render()`; `out_spp` must be null or writable.
#[no_mangle]
pub unsafe extern "C" fn nimbus_image_samples_per_pixel(
    image: *const NimbusImage,
    out_spp: *mut u32,
) -> NimbusStatus {
    call(|| {
        let data = NimbusImage::get(image)?;
        put(out_spp, data.stats.samples_per_pixel, "out_spp")?;
        Ok(NimbusStatus::Ok)
    })
}

/// Stores in `*out_count` the number of channels the image has (as its EXR file would list them; see
/// `nimbus_image_channel_name()`).
///
/// # Safety
/// `image` must be null or a handle from `nimbus_render()`; `out_count` must be null or writable.
#[no_mangle]
pub unsafe extern "C" fn nimbus_image_channel_count(
    image: *const NimbusImage,
    out_count: *mut usize,
) -> NimbusStatus {
    call(|| {
        let data = NimbusImage::get(image)?;
        put(out_count, data.image.channel_names().len(), "out_count")?;
        Ok(NimbusStatus::Ok)
    })
}

/// Copies the name of channel `index` (0 to count − 1, sorted as the EXR file lists them: `A`, `B`, `G`,
/// `R`, `albedo.B`, ..., `diffuse_direct.R`, `lg_key.G`, `CryptoObject00.r`...) into `out` as a
/// NUL-terminated UTF-8 string. An index out of range gives `NIMBUS_STATUS_INVALID_ARGUMENT`; a buffer of
/// fewer than the name's bytes + 1 gives `NIMBUS_STATUS_BUFFER_TOO_SMALL` and copies nothing.
///
/// # Safety
/// `image` must be null or a handle from `nimbus_render()`; `out` must be null or point to `len` writable
/// bytes.
#[no_mangle]
pub unsafe extern "C" fn nimbus_image_channel_name(
    image: *const NimbusImage,
    index: usize,
    out: *mut c_char,
    len: usize,
) -> NimbusStatus {
    call(|| {
        let data = NimbusImage::get(image)?;
        if out.is_null() {
            return Err(Failure::null("out"));
        }
        let names = data.image.channel_names();
        let name = names.get(index).ok_or_else(|| {
            Failure::new(
                NimbusStatus::InvalidArgument,
                format!(
                    "channel index {index} is not below the count {}",
                    names.len()
                ),
            )
        })?;
        let bytes = name.as_bytes();
        if len < bytes.len() + 1 {
            return Err(Failure::new(
                NimbusStatus::BufferTooSmall,
                format!(
                    "buffer holds {len} bytes, channel name {name:?} needs {}",
                    bytes.len() + 1
                ),
            ));
        }
        let out = std::slice::from_raw_parts_mut(out.cast::<u8>(), bytes.len() + 1);
        out[..bytes.len()].copy_from_slice(bytes);
        out[bytes.len()] = 0;
        Ok(NimbusStatus::Ok)
    })
}

/// Copies channel `name` of the image into `out`, `width * height` floats, row-major from the top row.
///
/// Channel names are the EXR file's (see `nimbus_image_channel_name()`): `R`, `G`, `B`, `A` (coverage),
/// `albedo.R|G|B`, `normal.X|Y|Z`, `depth.Z`, `variance.R|G|B`, and the layers the settings' `aovs` chose
/// (light paths, colours, light groups, shadow catcher, Cryptomatte). An unknown name gives
/// `NIMBUS_STATUS_INVALID_ARGUMENT`; `len` (in floats) below `width * height` gives
/// `NIMBUS_STATUS_BUFFER_TOO_SMALL` and copies nothing.
///
/// # Safety
/// `image` must be null or a handle from `nimbus_render()`; `name` must be null or a NUL-terminated string;
/// `out` must be null or point to `len` writable floats.
#[no_mangle]
pub unsafe extern "C" fn nimbus_image_channel(
    image: *const NimbusImage,
    name: *const c_char,
    out: *mut f32,
    len: usize,
) -> NimbusStatus {
    call(|| {
        let data = NimbusImage::get(image)?;
        let name = c_str(name, "channel name")?;
        if out.is_null() {
            return Err(Failure::null("out"));
        }
        let samples = data.image.channel(name).ok_or_else(|| {
            Failure::new(
                NimbusStatus::InvalidArgument,
                format!(
                    "unknown channel {name:?}; this image has: {}",
                    data.image.channel_names().join(", ")
                ),
            )
        })?;
        if len < samples.len() {
            return Err(Failure::new(
                NimbusStatus::BufferTooSmall,
                format!(
                    "buffer holds {len} floats, channel {name} needs {}",
                    samples.len()
                ),
            ));
        }
        std::slice::from_raw_parts_mut(out, samples.len()).copy_from_slice(&samples);
        Ok(NimbusStatus::Ok)
    })
}

/// Writes the image, beauty and every AOV, to `path` as a multi-layer OpenEXR file.
///
/// # Safety
/// `image` must be null or a handle from `nimbus_render()`; `path` must be null or a NUL-terminated UTF-8
/// string.
#[no_mangle]
pub unsafe extern "C" fn nimbus_image_write_exr(
    image: *const NimbusImage,
    path: *const c_char,
) -> NimbusStatus {
    call(|| {
        let data = NimbusImage::get(image)?;
        let path = PathBuf::from(c_str(path, "path")?);
        nimbus::write_exr(&data.image, &path).map_err(Error::from)?;
        Ok(NimbusStatus::Ok)
    })
}

/// Writes the beauty pass to `path` as an 8-bit sRGB PNG, scaled by `2^exposure` and clamped.
///
/// # Safety
/// `image` must be null or a handle from `nimbus_render()`; `path` must be null or a NUL-terminated UTF-8
/// string.
#[no_mangle]
pub unsafe extern "C" fn nimbus_image_write_png(
    image: *const NimbusImage,
    path: *const c_char,
    exposure: f32,
) -> NimbusStatus {
    call(|| {
        let data = NimbusImage::get(image)?;
        let path = PathBuf::from(c_str(path, "path")?);
        if !exposure.is_finite() {
            return Err(Failure::new(
                NimbusStatus::InvalidArgument,
                format!("exposure {exposure} is not finite"),
            ));
        }
        nimbus::write_png_preview(&data.image, &path, exposure).map_err(Error::from)?;
        Ok(NimbusStatus::Ok)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn last_error() -> String {
        unsafe { CStr::from_ptr(nimbus_last_error()) }
            .to_string_lossy()
            .into_owned()
    }

    #[test]
    fn a_panic_becomes_a_status_and_a_message() {
        let status = call(|| panic!("boom at the boundary"));
        assert_eq!(status, NimbusStatus::Panic);
        assert!(
            last_error().contains("boom at the boundary"),
            "{}",
            last_error()
        );
        assert_eq!(call(|| Ok(NimbusStatus::Ok)), NimbusStatus::Ok);
        assert_eq!(last_error(), "", "success clears the message");
    }

    /// A handle type for tests of the registry alone: nothing to load or render, so Miri can run them.
    struct Numbers;

    impl Handle for Numbers {
        type Value = Vec<u64>;
        const WHAT: &'static str = "numbers";
    }

    fn status<T>(r: Result<T, Failure>) -> NimbusStatus {
        r.map_or_else(|f| f.status, |_| NimbusStatus::Ok)
    }

    /// Threads look a handle up and read its value while another thread frees it: a value looked up before the
    /// free stays whole until the last reader drops it, lookups after the free are refused, and the handle is
    /// freed once.
    #[test]
    fn a_handle_freed_on_another_thread_outlives_the_calls_using_it() {
        let handle = Numbers::into_raw((0..100).collect());
        let id = handle.addr();
        let held = Numbers::get(handle).unwrap_or_else(|f| panic!("{}", f.message));
        std::thread::scope(|s| {
            for _ in 0..3 {
                s.spawn(move || {
                    for _ in 0..20 {
                        match Numbers::get(std::ptr::without_provenance(id)) {
                            Ok(value) => assert_eq!(value.iter().sum::<u64>(), 4950),
                            Err(f) => {
                                assert_eq!(f.status, NimbusStatus::InvalidHandle);
                                break;
                            }
                        }
                    }
                });
            }
            s.spawn(move || {
                let mut copy = std::ptr::without_provenance_mut::<Numbers>(id);
                assert_eq!(
                    status(unsafe { Numbers::free(&mut copy) }),
                    NimbusStatus::Ok
                );
                assert!(copy.is_null());
            });
        });
        assert_eq!(held.iter().sum::<u64>(), 4950, "read after the free");
        assert_eq!(status(Numbers::get(handle)), NimbusStatus::InvalidHandle);
        let mut stale = handle;
        assert_eq!(
            status(unsafe { Numbers::free(&mut stale) }),
            NimbusStatus::InvalidHandle
        );
        assert_eq!(Arc::strong_count(&held), 1, "the registry let go");
    }

    #[test]
    fn messages_with_nul_bytes_survive() {
        let status = call(|| Err(Failure::new(NimbusStatus::InvalidArgument, "a\0b")));
        assert_eq!(status, NimbusStatus::InvalidArgument);
        assert_eq!(last_error(), "a b");
    }
}
