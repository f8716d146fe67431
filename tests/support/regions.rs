//! Checks of VDB region iteration against a voxel-by-voxel scan, shared by the unit tests of `vdb/grid.rs`
//! (synthetic trees) and `tests/suite/vdb_corpus.rs` (corpus files). The including module's parent must have
//! `FloatTree`, `Region` and `IVec3` in scope.

use super::{FloatTree, IVec3, Region};

/// Lists the regions of `t` in the inclusive box `[lo, hi]` and checks them against a voxel-by-voxel scan: no
/// two overlap, each meets the box, their values (bit for bit) and active states are the tree's, and every
/// voxel they leave out holds the inactive background. Returns the number of active voxels found.
pub fn check_regions_in(t: &FloatTree, lo: IVec3, hi: IVec3) -> u64 {
    let size = hi - lo + 1;
    let index = |p: IVec3| {
        let q = p - lo;
        ((q.x * size.y + q.y) * size.z + q.z) as usize
    };
    let mut covered = vec![false; (size.x * size.y * size.z) as usize];
    let mut active = 0;
    for r in t.regions_in(lo, hi) {
        let (a, b) = (r.origin().max(lo), (r.origin() + (r.edge() - 1)).min(hi));
        assert!(a.cmple(b).all(), "region at {} misses the box", r.origin());
        let (rmin, rmax) = r.range();
        for x in a.x..=b.x {
            for y in a.y..=b.y {
                for z in a.z..=b.z {
                    let p = IVec3::new(x, y, z);
                    assert!(
                        !std::mem::replace(&mut covered[index(p)], true),
                        "overlap at {p}"
                    );
                    let (v, on) = match r {
                        Region::Leaf(l) => (l.value(p), l.is_active(p)),
                        Region::Tile(t) => (t.value, t.active),
                    };
                    assert_eq!(v.to_bits(), t.value(p).to_bits(), "value at {p}");
                    assert_eq!(on, t.is_active(p), "active at {p}");
                    assert!(rmin <= v && v <= rmax, "range at {p}");
                    active += on as u64;
                }
            }
        }
    }
    for x in lo.x..=hi.x {
        for y in lo.y..=hi.y {
            for z in lo.z..=hi.z {
                let p = IVec3::new(x, y, z);
                if !covered[index(p)] {
                    assert_eq!(t.value(p).to_bits(), t.background().to_bits(), "at {p}");
                    assert!(!t.is_active(p), "at {p}");
                }
            }
        }
    }
    active
}

/// The active voxels in all of `t`'s regions: a leaf's active voxels, a tile's whole edge³ when active.
pub fn active_voxels_of_regions(t: &FloatTree) -> u64 {
    t.regions()
        .map(|r| match r {
            Region::Leaf(l) => l.active_voxels().count() as u64,
            Region::Tile(t) => t.active as u64 * (t.edge as u64).pow(3),
        })
        .sum()
}
