//! TEMPORARY: counters only, until the volcore branch lands.

/// Work counters of tracking estimators.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct TrackingCounters {
    /// Density lookups.
    pub density_lookups: u64,
    /// Real collisions.
    pub real_collisions: u64,
    /// Null collisions.
    pub null_collisions: u64,
    /// Majorant segments.
    pub majorant_segments: u64,
    /// Majorant violations.
    pub majorant_violations: u64,
}

impl TrackingCounters {
    /// Adds other.
    pub fn add(&mut self, o: &TrackingCounters) {
        self.density_lookups += o.density_lookups;
        self.real_collisions += o.real_collisions;
        self.null_collisions += o.null_collisions;
        self.majorant_segments += o.majorant_segments;
        self.majorant_violations += o.majorant_violations;
    }
}
