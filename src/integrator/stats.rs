use crate::volume::TrackingCounters;

/// Rays traced, by kind.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct RayCounters {
    /// Primary rays from the camera.
    pub camera: u64,
    /// Rays continuing a path after a scattering event or an invisible boundary.
    pub bounce: u64,
    /// Shadow rays for next-event estimation (one per light sample, however many surfaces it crosses).
    pub shadow: u64,
    /// Equiangular samples of segments through constant media toward point and spot lights (each also traces
    /// one shadow ray, counted in `shadow`).
    pub equiangular: u64,
    /// Decoupled direct-light samples of segments through constant media, at a distance drawn from the
    /// free-flight density truncated to the segment (each also traces one shadow ray per light sample, counted in
    /// `shadow`).
    pub decoupled: u64,
    /// Extra camera rays of emitter-edge supersampling (`nimbus::render::EmitterEdges`), which only look for
    /// the emission of the first surface they hit.
    pub emitter_edge: u64,
    /// Extra paths guided splitting started at medium scattering events (each goes on from the event, with its
    /// own next-event estimate and bounces, counted in `shadow` and `bounce`).
    pub split: u64,
}

impl RayCounters {
    /// Adds another set of counters to this one.
    pub fn add(&mut self, other: &RayCounters) {
        self.camera += other.camera;
        self.bounce += other.bounce;
        self.shadow += other.shadow;
        self.equiangular += other.equiangular;
        self.decoupled += other.decoupled;
        self.emitter_edge += other.emitter_edge;
        self.split += other.split;
    }

    /// All rays traced.
    pub fn total(&self) -> u64 {
        self.camera + self.bounce + self.shadow
    }
}

/// Work counters gathered while tracing. Each worker keeps its own and they are summed at the end, so the
/// totals do not depend on the number of threads.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct PathCounters {
    /// Rays by kind.
    pub rays: RayCounters,
    /// Tracking work per medium, indexed like `Scene::media`.
    pub media: Vec<TrackingCounters>,
}

impl PathCounters {
    /// Counters for a scene with `media` media.
    pub fn new(media: usize) -> Self {
        Self {
            rays: RayCounters::default(),
            media: vec![TrackingCounters::default(); media],
        }
    }

    /// Adds another set of counters to this one.
    pub fn add(&mut self, other: &PathCounters) {
        self.rays.add(&other.rays);
        if self.media.len() < other.media.len() {
            self.media
                .resize(other.media.len(), TrackingCounters::default());
        }
        for (a, b) in self.media.iter_mut().zip(&other.media) {
            a.add(b);
        }
    }
}
