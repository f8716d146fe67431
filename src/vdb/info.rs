//! `nimbus info`: per-grid summaries of a VDB file, as JSON (serde) or a plain table.

use super::{read_file, Background, Grid, TreeStats, VdbError};
use serde::Serialize;
use std::fmt;
use std::path::Path;

/// Summary of one VDB file.
#[derive(Clone, Debug, Serialize)]
pub struct FileInfo {
    /// The file path as given.
    pub file: String,
    /// One entry per grid, in file order.
    pub grids: Vec<GridInfo>,
}

/// Summary of one grid: counts and statistics over active values (tiles weighted by their voxel count,
/// vector magnitudes for vector grids).
#[derive(Clone, Debug, Serialize)]
pub struct GridInfo {
    /// Grid name.
    pub name: String,
    /// OpenVDB value type name (`float`, `double`, `vec3s`).
    pub value_type: String,
    /// Grid class (`fog volume`, `level set`, `staggered`, `unknown`).
    pub class: String,
    /// Whether the file stored halves.
    pub half: bool,
    /// Counts and statistics of the active values; serialised flat, as `active_voxels`, `leaf_voxels`,
    /// `tiles`, `leaves`, `sum`, `min`, `max`, `bbox_min` and `bbox_max` (zeros when nothing is active).
    #[serde(flatten)]
    pub stats: TreeStats,
    /// World length of a voxel step along each index axis.
    pub voxel_size: [f64; 3],
    /// Background value (number, or array for vectors).
    pub background: Background,
    /// Index-to-world matrix, row-major, column-vector convention (translation in the last column).
    pub index_to_world: [f64; 16],
    /// Memory used by the sparse tree in bytes.
    pub memory_bytes: usize,
}

impl GridInfo {
    /// Summarises one grid.
    pub(crate) fn from_grid(g: &Grid) -> Self {
        Self {
            name: g.name.clone(),
            value_type: match g.value_type {
                super::ValueType::Float => "float",
                super::ValueType::Double => "double",
                super::ValueType::Vec3s => "vec3s",
            }
            .into(),
            class: match g.class {
                super::GridClass::FogVolume => "fog volume",
                super::GridClass::LevelSet => "level set",
                super::GridClass::Staggered => "staggered",
                super::GridClass::Unknown => "unknown",
            }
            .into(),
            half: g.half,
            stats: g.tree.stats(),
            voxel_size: g.voxel_size().to_array(),
            background: g.background,
            // glam stores columns; its transpose's column-major array is our row-major array.
            index_to_world: g.index_to_world.transpose().to_cols_array(),
            memory_bytes: g.tree.memory_bytes(),
        }
    }
}

/// Reads a file and summarises every grid.
pub fn file_info(path: &Path) -> Result<FileInfo, VdbError> {
    let f = read_file(path)?;
    Ok(FileInfo {
        file: path.display().to_string(),
        grids: f.grids.iter().map(GridInfo::from_grid).collect(),
    })
}

impl fmt::Display for FileInfo {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "{}: {} grid(s)", self.file, self.grids.len())?;
        writeln!(
            f,
            "{:<16} {:<7} {:<10} {:>4} {:>12} {:>10} {:>7} {:>8} {:>14} {:>12} {:>12} {:>22} {:>10} {:>10}",
            "name", "type", "class", "half", "active", "leaf_vox", "tiles", "leaves", "sum", "min", "max",
            "bbox", "voxel", "mem_MiB"
        )?;
        for g in &self.grids {
            let s = &g.stats;
            let (bmin, bmax) = s.bbox.unwrap_or_default();
            let bbox = format!(
                "{},{},{}..{},{},{}",
                bmin.x, bmin.y, bmin.z, bmax.x, bmax.y, bmax.z
            );
            writeln!(
                f,
                "{:<16} {:<7} {:<10} {:>4} {:>12} {:>10} {:>7} {:>8} {:>14.6e} {:>12.6} {:>12.6} {:>22} {:>10.6} {:>10.2}",
                if g.name.is_empty() { "(unnamed)" } else { &g.name },
                g.value_type,
                g.class,
                if g.half { "yes" } else { "no" },
                s.active_voxels,
                s.leaf_voxels,
                s.tiles,
                s.leaves,
                s.sum,
                s.min,
                s.max,
                bbox,
                g.voxel_size[0],
                g.memory_bytes as f64 / (1024.0 * 1024.0)
            )?;
        }
        Ok(())
    }
}
