//! The C API under load (issue 36, item 6): threads that each load and render different scenes through the C
//! API at once, a scene freed by another thread in the middle of a render that uses it, and images freed at
//! random moments while other threads read them.
//!
//! `a_short_load_runs_clean` is the short form that `cargo test` runs. `the_library_under_load_keeps_rss_flat`
//! is the long form (8 threads × 50 renders, 64×64), ignored by default; it prints the process's RSS after
//! every round and asserts that it stays flat after warm-up:
//!
//! ```text
//! cargo test -p nimbus-ffi --test load -- --ignored --nocapture
//! ```

use nimbus::math::Rng;
use nimbus_c::*;
use std::ffi::{c_int, c_void, CStr, CString};
use std::path::Path;
use std::ptr::null_mut;
use std::sync::mpsc::{self, RecvTimeoutError, Sender};
use std::sync::{Barrier, Mutex};
use std::time::{Duration, Instant};

/// The scenes the threads render: surfaces with an emissive light and textures, a VDB cloud, a VDB of constant
/// density and a homogeneous slab, so loads and renders differ in work and allocation pattern.
const SCENES: [&str; 4] = [
    "../assets/demo.glb",
    "../assets/cloud.gltf",
    "../tests/scenes/constant_grid.gltf",
    "../tests/scenes/slab_homogeneous.gltf",
];

/// The channels compared with the reference render.
const CHANNELS: [&str; 4] = ["R", "G", "B", "A"];

/// How far the highest RSS after warm-up may rise above the highest of the last 10 warm-up rounds in the long
/// form, in KiB. Measured (2 cores, other builds running): +1.8 to +3.1 MiB in three runs of 50 rounds, and RSS
/// stays within 55–68 MiB from round 11 to 200 of a 200-round run, with no trend. A leaked 64×64 image holds
/// at least 14 f32 channels (224 KiB), so leaking one in five of the 200 renders after warm-up already exceeds
/// the bound; leaking every image (with `nimbus_image_free` forgetting its value) fails with +46 MiB.
const BOUND_KIB: u64 = 8 * 1024;

/// How hard to load the library.
struct Load {
    /// Threads that load and render at once.
    threads: usize,
    /// Load-and-render iterations per thread; the threads meet after each (a round).
    iterations: usize,
    /// Image side in pixels.
    side: u32,
    /// Samples per pixel: 4 makes 4 passes (a progress call after each), so a free after the first pass
    /// happens while three passes still use the scene.
    spp: u32,
    /// Seed of the schedule of frees (the images' seed is fixed).
    seed: u64,
}

impl Load {
    fn settings(&self) -> NimbusRenderSettings {
        NimbusRenderSettings {
            width: self.side,
            height: self.side,
            spp: self.spp,
            threads: 1,
            ..nimbus_render_settings_default()
        }
    }
}

/// What one run saw.
#[derive(Debug, Default)]
struct Tally {
    /// Renders that finished with `Ok`.
    completed: usize,
    /// Renders during which another thread freed their scene (each also counts as completed).
    freed_during_render: usize,
    /// Renders the progress callback cancelled.
    cancelled: usize,
    /// Images freed by the thread that rendered them, by another worker, or by the reaper thread.
    images_freed: usize,
    /// Reads of an image another thread may free at any moment that found it freed (`InvalidHandle`).
    reads_of_freed_images: usize,
    /// Reads of such an image that found it live and equal to what it held before.
    reads_of_live_images: usize,
    /// The process's resident set size in KiB after every round.
    rss_kib: Vec<u64>,
    /// Wall-clock seconds of the whole run.
    seconds: f64,
}

/// A request to the reaper thread, which frees handles on behalf of the workers.
enum Job {
    /// Free this scene handle and send the status back.
    FreeScene(usize, Sender<NimbusStatus>),
    /// Free this image handle after waiting this long (while the thread that sent it reads it).
    FreeImageSoon(usize, Duration),
    /// No more requests: free what is left on the shelf and stop.
    Stop,
}

/// An image handle that any thread may read or free, with what it should hold.
#[derive(Clone, Copy)]
struct Shelved {
    image: usize,
    scene: usize,
    complete: bool,
}

/// The images handed between threads. A thread frees an image only after taking it off the shelf, so each is
/// freed once; a thread that only reads one copies its handle and may find it freed meanwhile.
struct Shelf(Mutex<Vec<Shelved>>);

impl Shelf {
    fn take(&self, rng: &mut Rng) -> Option<Shelved> {
        let mut images = self.0.lock().unwrap();
        if images.is_empty() {
            return None;
        }
        let i = rng.next_u32() as usize % images.len();
        Some(images.swap_remove(i))
    }

    fn peek(&self, rng: &mut Rng) -> Option<Shelved> {
        let images = self.0.lock().unwrap();
        if images.is_empty() {
            return None;
        }
        Some(images[rng.next_u32() as usize % images.len()])
    }
}

fn last_error() -> String {
    unsafe { CStr::from_ptr(nimbus_last_error()) }
        .to_string_lossy()
        .into_owned()
}

fn scene_path(i: usize) -> CString {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(SCENES[i]);
    CString::new(path.to_str().unwrap()).unwrap()
}

fn load_scene(i: usize) -> Result<*mut NimbusScene, String> {
    let mut scene = null_mut();
    match unsafe { nimbus_scene_load(scene_path(i).as_ptr(), &mut scene) } {
        NimbusStatus::Ok => Ok(scene),
        s => Err(format!("loading {:?}: {s:?}: {}", SCENES[i], last_error())),
    }
}

/// The channels `CHANNELS` of `image`, concatenated, or the status of the first read that failed.
fn read_channels(image: usize, pixels: usize) -> Result<Vec<f32>, NimbusStatus> {
    let mut out = vec![f32::NAN; CHANNELS.len() * pixels];
    for (name, chunk) in CHANNELS.iter().zip(out.chunks_mut(pixels)) {
        let name = CString::new(*name).unwrap();
        let status = unsafe {
            nimbus_image_channel(
                image as *const NimbusImage,
                name.as_ptr(),
                chunk.as_mut_ptr(),
                pixels,
            )
        };
        if status != NimbusStatus::Ok {
            return Err(status);
        }
    }
    Ok(out)
}

/// Frees the image handle `image`, which must be live.
fn free_image(image: usize) -> Result<(), String> {
    let mut handle = image as *mut NimbusImage;
    match unsafe { nimbus_image_free(&mut handle) } {
        NimbusStatus::Ok if handle.is_null() => Ok(()),
        s => Err(format!("freeing a live image: {s:?}: {}", last_error())),
    }
}

/// What the progress callback of one render does, and what it saw.
struct Progress<'a> {
    /// Cancel at the first call.
    cancel: bool,
    /// At the first call, have the reaper free this scene handle (and wait until it has).
    free_scene: Option<(usize, &'a Sender<Job>)>,
    /// Calls so far.
    calls: u32,
    /// The status of the free the reaper made.
    free_status: Option<NimbusStatus>,
}

/// The progress callback: asserts nothing (a panic must not unwind into the C API), records instead.
unsafe extern "C" fn on_progress(_fraction: f32, _spp: u32, user_data: *mut c_void) -> c_int {
    let p = &mut *user_data.cast::<Progress>();
    p.calls += 1;
    if p.calls == 1 {
        if let Some((scene, reaper)) = p.free_scene {
            let (ack, done) = mpsc::channel();
            if reaper.send(Job::FreeScene(scene, ack)).is_ok() {
                p.free_status = done.recv().ok();
            }
        }
    }
    c_int::from(!p.cancel)
}

/// Renders every scene once, one after the other: the images every render with the same settings must match
/// (a render's image depends on its seed only).
fn references(load: &Load) -> Vec<Vec<f32>> {
    let pixels = (load.side * load.side) as usize;
    (0..SCENES.len())
        .map(|i| {
            let mut scene = load_scene(i).unwrap();
            let mut image = null_mut();
            let status =
                unsafe { nimbus_render(scene, &load.settings(), None, null_mut(), &mut image) };
            assert_eq!(status, NimbusStatus::Ok, "{}", last_error());
            let values = read_channels(image as usize, pixels).unwrap();
            assert!(
                values.iter().all(|v| v.is_finite()),
                "{} renders non-finite values",
                SCENES[i]
            );
            unsafe {
                nimbus_image_free(&mut image);
                nimbus_scene_free(&mut scene);
            }
            values
        })
        .collect()
}

/// What every worker thread shares.
#[derive(Clone, Copy)]
struct Common<'a> {
    load: &'a Load,
    shelf: &'a Shelf,
    /// The image of each scene.
    references: &'a [Vec<f32>],
    tally: &'a Mutex<Tally>,
}

/// One worker's iteration `i`: load a scene, render it (freeing it from the reaper thread during the render
/// every third iteration, cancelling every third), check the image, shelve it, and read or free other images.
fn iteration(
    common: Common,
    t: usize,
    i: usize,
    rng: &mut Rng,
    reaper: &Sender<Job>,
) -> Result<(), String> {
    let Common {
        load,
        shelf,
        references,
        tally,
    } = common;
    let pixels = (load.side * load.side) as usize;
    let which = (t + i) % SCENES.len();
    let mut scene = load_scene(which)?;
    let free_during_render = i % 3 == 1;
    let mut progress = Progress {
        cancel: i % 3 == 2,
        free_scene: free_during_render.then_some((scene as usize, reaper)),
        calls: 0,
        free_status: None,
    };
    let mut image = null_mut();
    let status = unsafe {
        nimbus_render(
            scene,
            &load.settings(),
            Some(on_progress),
            (&mut progress as *mut Progress).cast(),
            &mut image,
        )
    };
    let context = format!("thread {t}, iteration {i}, {}", SCENES[which]);
    let expected = if progress.cancel {
        NimbusStatus::Cancelled
    } else {
        NimbusStatus::Ok
    };
    if status != expected || image.is_null() {
        return Err(format!(
            "{context}: render gave {status:?} ({}), expected {expected:?} and an image",
            last_error()
        ));
    }
    let mut spp = 0;
    let status = unsafe { nimbus_image_samples_per_pixel(image, &mut spp) };
    let full = spp == load.spp;
    if status != NimbusStatus::Ok || full == progress.cancel || progress.calls == 0 {
        return Err(format!(
            "{context}: {status:?}, {spp} spp after {} progress calls",
            progress.calls
        ));
    }
    let values = read_channels(image as usize, pixels)
        .map_err(|s| format!("{context}: reading its own image: {s:?}: {}", last_error()))?;
    if values.iter().any(|v| !v.is_finite()) {
        return Err(format!("{context}: non-finite pixels"));
    }
    if full && values != references[which] {
        return Err(format!("{context}: the image differs from the reference"));
    }
    if free_during_render {
        if progress.free_status != Some(NimbusStatus::Ok) {
            return Err(format!(
                "{context}: the reaper's free during the render gave {:?}",
                progress.free_status
            ));
        }
        // The handle is gone: using it or freeing it again is refused.
        let mut again = null_mut();
        let status =
            unsafe { nimbus_render(scene, &load.settings(), None, null_mut(), &mut again) };
        let mut copy = scene;
        let freed = unsafe { nimbus_scene_free(&mut copy) };
        if (status, freed) != (NimbusStatus::InvalidHandle, NimbusStatus::InvalidHandle)
            || !again.is_null()
        {
            return Err(format!(
                "{context}: a scene freed during the render gave {status:?} to a render, {freed:?} to a free"
            ));
        }
    } else {
        let status = unsafe { nimbus_scene_free(&mut scene) };
        if status != NimbusStatus::Ok || !scene.is_null() {
            return Err(format!("{context}: freeing the scene: {status:?}"));
        }
    }
    let (mut live_reads, mut freed_reads) = (0, 0);
    if rng.next_u32().is_multiple_of(4) {
        // The reaper frees the image at a random moment in the next millisecond, while this thread reads it
        // without pause: reads before the free are whole and right, the first after it is refused.
        let delay = Duration::from_micros(u64::from(rng.next_u32() % 1000));
        reaper
            .send(Job::FreeImageSoon(image as usize, delay))
            .map_err(|_| format!("{context}: the reaper stopped"))?;
        let give_up = Instant::now() + Duration::from_secs(30);
        loop {
            match read_channels(image as usize, pixels) {
                Ok(v) if v == values => live_reads += 1,
                Ok(_) => return Err(format!("{context}: the image changed while being freed")),
                Err(NimbusStatus::InvalidHandle) => break,
                Err(e) => return Err(format!("{context}: reading an image being freed: {e:?}")),
            }
            if Instant::now() > give_up {
                return Err(format!("{context}: the reaper did not free the image"));
            }
        }
        freed_reads += 1;
    } else {
        shelf.0.lock().unwrap().push(Shelved {
            image: image as usize,
            scene: which,
            complete: full,
        });
    }
    let mut tally_images_freed = 0;
    // Random moments: free an image (perhaps this one), read one another thread may be freeing.
    if rng.next_u32().is_multiple_of(2) {
        if let Some(s) = shelf.take(rng) {
            free_image(s.image).map_err(|e| format!("{context}: {e}"))?;
            tally_images_freed += 1;
        }
    }
    for _ in 0..rng.next_u32() % 3 {
        let Some(s) = shelf.peek(rng) else { break };
        match read_channels(s.image, pixels) {
            Ok(v)
                if v.iter().all(|x| x.is_finite()) && (!s.complete || v == references[s.scene]) =>
            {
                live_reads += 1
            }
            Ok(_) => {
                return Err(format!(
                    "{context}: a shelved image of {} reads wrong",
                    SCENES[s.scene]
                ))
            }
            Err(NimbusStatus::InvalidHandle) => freed_reads += 1,
            Err(e) => {
                return Err(format!(
                    "{context}: reading a shelved image: {e:?}: {}",
                    last_error()
                ))
            }
        }
    }
    // Keep the shelf short, so memory after a round does not depend on how many images happen to wait there.
    while shelf.0.lock().unwrap().len() > 2 * load.threads {
        if let Some(s) = shelf.take(rng) {
            free_image(s.image).map_err(|e| format!("{context}: {e}"))?;
            tally_images_freed += 1;
        }
    }
    let mut tally = tally.lock().unwrap();
    tally.completed += usize::from(full);
    tally.cancelled += usize::from(progress.cancel);
    tally.freed_during_render += usize::from(free_during_render);
    tally.images_freed += tally_images_freed;
    tally.reads_of_live_images += live_reads;
    tally.reads_of_freed_images += freed_reads;
    Ok(())
}

/// The reaper: frees scenes on request, and a random shelved image every few milliseconds.
fn reaper(
    jobs: mpsc::Receiver<Job>,
    shelf: &Shelf,
    seed: u64,
    tally: &Mutex<Tally>,
) -> Result<(), String> {
    let mut rng = Rng::new(seed, 0xdead);
    let mut freed = 0;
    loop {
        let wait = Duration::from_micros(u64::from(rng.next_u32() % 4000));
        match jobs.recv_timeout(wait) {
            Ok(Job::FreeScene(scene, ack)) => {
                let mut handle = scene as *mut NimbusScene;
                let status = unsafe { nimbus_scene_free(&mut handle) };
                ack.send(status).ok();
            }
            Ok(Job::FreeImageSoon(image, delay)) => {
                std::thread::sleep(delay);
                free_image(image).map_err(|e| format!("reaper: {e}"))?;
                freed += 1;
            }
            Ok(Job::Stop) | Err(RecvTimeoutError::Disconnected) => break,
            Err(RecvTimeoutError::Timeout) => {
                if let Some(s) = shelf.take(&mut rng) {
                    free_image(s.image).map_err(|e| format!("reaper: {e}"))?;
                    freed += 1;
                }
            }
        }
    }
    while let Some(s) = shelf.take(&mut rng) {
        free_image(s.image).map_err(|e| format!("reaper: {e}"))?;
        freed += 1;
    }
    tally.lock().unwrap().images_freed += freed;
    Ok(())
}

/// The resident set size of this process in KiB (`VmRSS` of `/proc/self/status`), 0 where there is none.
fn rss_kib() -> u64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find_map(|l| l.strip_prefix("VmRSS:"))
                .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
        })
        .unwrap_or(0)
}

/// Runs `load` and returns what it saw; panics on the first check that failed (after every thread stopped).
fn run(load: &Load) -> Tally {
    let references = references(load);
    let tally = Mutex::new(Tally::default());
    let shelf = Shelf(Mutex::new(Vec::new()));
    let rounds = Barrier::new(load.threads);
    let (jobs, inbox) = mpsc::channel();
    let start = Instant::now();
    let failures: Vec<String> = std::thread::scope(|s| {
        let reaper = s.spawn(|| reaper(inbox, &shelf, load.seed, &tally));
        let workers: Vec<_> = (0..load.threads)
            .map(|t| {
                let common = Common {
                    load,
                    shelf: &shelf,
                    references: &references,
                    tally: &tally,
                };
                let (jobs, rounds) = (jobs.clone(), &rounds);
                s.spawn(move || {
                    let mut rng = Rng::new(load.seed, t as u64);
                    let mut failure = None;
                    for i in 0..load.iterations {
                        // After a failure the thread still meets the others every round, so none waits forever.
                        if failure.is_none() {
                            failure = iteration(common, t, i, &mut rng, &jobs).err();
                        }
                        if rounds.wait().is_leader() {
                            common.tally.lock().unwrap().rss_kib.push(rss_kib());
                        }
                    }
                    failure
                })
            })
            .collect();
        let mut failures: Vec<String> = workers
            .into_iter()
            .filter_map(|w| w.join().unwrap())
            .collect();
        jobs.send(Job::Stop).unwrap();
        if let Err(e) = reaper.join().unwrap() {
            failures.push(e);
        }
        failures
    });
    assert!(failures.is_empty(), "{failures:#?}");
    let mut tally = tally.into_inner().unwrap();
    tally.seconds = start.elapsed().as_secs_f64();
    let renders = load.threads * load.iterations;
    assert_eq!(tally.completed + tally.cancelled, renders, "{tally:?}");
    assert_eq!(
        tally.images_freed, renders,
        "every image freed once: {tally:?}"
    );
    tally
}

#[test]
fn a_short_load_runs_clean() {
    let load = Load {
        threads: 8,
        iterations: 9,
        side: 16,
        spp: 4,
        seed: 36,
    };
    let tally = run(&load);
    assert_eq!(tally.freed_during_render, 24, "{tally:?}");
    assert!(tally.reads_of_freed_images > 0, "{tally:?}");
    println!("{tally:?}");
}

/// The long form of issue 36, item 6: 8 threads × 50 loads and renders (64×64, 4 spp) with the same frees, RSS
/// sampled after every round. After warm-up (the first half of the rounds) RSS must stay flat: its highest
/// value may not rise above the highest of the last 10 warm-up rounds by more than [`BOUND_KIB`].
#[test]
#[ignore = "long: run with --ignored --nocapture"]
fn the_library_under_load_keeps_rss_flat() {
    let load = Load {
        threads: 8,
        iterations: 50,
        side: 64,
        spp: 4,
        seed: 36,
    };
    let tally = run(&load);
    let rss = &tally.rss_kib;
    println!(
        "{} renders ({} complete, {} with their scene freed during the render, {} cancelled) in {:.1} s; \
         {} images freed, {} reads found an image live, {} found it freed",
        load.threads * load.iterations,
        tally.completed,
        tally.freed_during_render,
        tally.cancelled,
        tally.seconds,
        tally.images_freed,
        tally.reads_of_live_images,
        tally.reads_of_freed_images
    );
    println!("round  RSS (MiB)");
    for (round, kib) in rss.iter().enumerate() {
        if round == 0 || (round + 1) % 5 == 0 {
            println!("{:5}  {:.1}", round + 1, *kib as f64 / 1024.0);
        }
    }
    let half = rss.len() / 2;
    let warm = *rss[half - 10..half].iter().max().unwrap();
    let peak = *rss[half..].iter().max().unwrap();
    let growth = peak.saturating_sub(warm);
    println!(
        "highest in rounds {}-{half}: {:.1} MiB; highest since: {:.1} MiB (+{:.1} MiB, bound {:.1} MiB)",
        half - 9,
        warm as f64 / 1024.0,
        peak as f64 / 1024.0,
        growth as f64 / 1024.0,
        BOUND_KIB as f64 / 1024.0
    );
    assert!(
        growth < BOUND_KIB,
        "RSS grew by {growth} KiB after warm-up: {rss:?}"
    );
}
