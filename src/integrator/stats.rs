/// Work counters gathered while tracing. Each worker keeps its own and they are summed at the end, so the
/// totals do not depend on the number of threads.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct RayCounters {
    /// Primary rays from the camera.
    pub camera: u64,
    /// Rays continuing a path after a scattering event or an invisible boundary.
    pub bounce: u64,
    /// Shadow rays for next-event estimation.
    pub shadow: u64,
}

impl RayCounters {
    /// Adds another set of counters to this one.
    pub fn add(&mut self, other: &RayCounters) {
        self.camera += other.camera;
        self.bounce += other.bounce;
        self.shadow += other.shadow;
    }

    /// All rays traced.
    pub fn total(&self) -> u64 {
        self.camera + self.bounce + self.shadow
    }
}
