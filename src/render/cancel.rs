//! Cancellation of a render from another thread: a [`CancelToken`] is a shared flag that the renderer checks
//! between passes and before every pixel, so a cancel lands within one pixel's samples.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

/// A cloneable handle that cancels the renders it is given to.
///
/// Clones share one flag: cancel any clone and every render holding one stops. A cancelled render returns the
/// image it has (pixels keep the samples they took) with [`RenderStats::cancelled`](super::RenderStats) set.
/// A token stays cancelled; use a new one for the next render.
///
/// ```
/// use nimbus::CancelToken;
///
/// let token = CancelToken::new();
/// let remote = token.clone();
/// std::thread::spawn(move || remote.cancel()).join().unwrap();
/// assert!(token.is_cancelled());
/// ```
#[derive(Clone, Debug, Default)]
pub struct CancelToken(Arc<AtomicBool>);

impl CancelToken {
    /// A token that is not cancelled.
    pub fn new() -> Self {
        Self::default()
    }

    /// Asks every render holding a clone of this token to stop as soon as it can.
    pub fn cancel(&self) {
        self.0.store(true, Ordering::Relaxed);
    }

    /// True once [`cancel`](Self::cancel) was called on any clone.
    pub fn is_cancelled(&self) -> bool {
        self.0.load(Ordering::Relaxed)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::Material;
    use crate::math::{Rgb, Vec3};
    use crate::render::{RenderSettings, Renderer};
    use crate::scene::{Camera, Scene, SceneBuilder};
    use std::time::Duration;

    /// A lit floor seen from above.
    fn floor_scene() -> Scene {
        let mut b = SceneBuilder::new();
        let m = b.add_material(Material::lambertian("grey", Rgb::splat(0.5)));
        let quad = vec![
            Vec3::new(-1.0, 0.0, -1.0),
            Vec3::new(-1.0, 0.0, 1.0),
            Vec3::new(1.0, 0.0, 1.0),
            Vec3::new(1.0, 0.0, -1.0),
        ];
        b.add_triangle_mesh(quad, vec![[0, 1, 2], [0, 2, 3]], m)
            .unwrap();
        b.add_point_light(Vec3::Y, Rgb::ONE);
        b.set_camera(Camera::look_at(Vec3::new(0.0, 2.0, 0.5), Vec3::ZERO, 1.0));
        b.build().unwrap()
    }

    #[test]
    fn a_cancel_from_another_thread_lands_inside_a_pass() {
        let scene = floor_scene();
        // One pass is 10 000 spp over 4096 pixels on one thread: tens of seconds of work. A render that
        // reports no completed pass (and no progress) was stopped inside its first pass; one whose cancel
        // never lands does not return for minutes, and the test harness reports it.
        let settings = RenderSettings {
            width: 64,
            height: 64,
            spp: 160_000,
            threads: 1,
            ..RenderSettings::default()
        };
        let token = CancelToken::new();
        let remote = token.clone();
        let canceller = std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(100));
            remote.cancel();
        });
        let mut reports = 0;
        let (image, stats) = Renderer::new(settings)
            .render_with_cancel(
                &scene,
                &mut |_| {
                    reports += 1;
                    true
                },
                &token,
            )
            .unwrap();
        canceller.join().unwrap();
        assert!(stats.cancelled);
        assert_eq!(stats.samples_per_pixel, 0, "no pass completed");
        assert_eq!(reports, 0);
        assert!(image.beauty.iter().all(|c| c.is_finite()));
    }

    #[test]
    fn a_progress_callback_that_returns_false_cancels_between_passes() {
        let settings = RenderSettings {
            width: 4,
            height: 4,
            spp: 32,
            ..RenderSettings::default()
        };
        let (_, stats) = Renderer::new(settings)
            .render(&floor_scene(), &mut |p| p.samples_done < 2)
            .unwrap();
        assert!(stats.cancelled);
        assert_eq!(stats.samples_per_pixel, 2);
    }
}
