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
