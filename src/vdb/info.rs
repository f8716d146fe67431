//! `nimbus info`: per-grid summaries of a VDB file, as JSON (serde) or a plain table.

use super::{read_file, Background, Grid, VdbError};
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
    /// Active voxels, tiles included with all their voxels.
    pub active_voxels: u64,
    /// Active voxels in leaves.
    pub leaf_voxels: u64,
    /// Active tiles.
    pub tiles: u64,
    /// Leaf count.
    pub leaves: u64,
    /// Sum of active values.
    pub sum: f64,
    /// Minimum active value.
    pub min: f64,
    /// Maximum active value.
    pub max: f64,
    /// Inclusive active index bbox minimum (zeros if empty).
    pub bbox_min: [i32; 3],
    /// Inclusive active index bbox maximum (zeros if empty).
    pub bbox_max: [i32; 3],
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
    pub fn from_grid(g: &Grid) -> Self {
        let s = g.tree.stats();
        let (bmin, bmax) = s.bbox.unwrap_or_default();
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
            active_voxels: s.active_voxels,
            leaf_voxels: s.leaf_voxels,
            tiles: s.tiles,
            leaves: s.leaves,
            sum: s.sum,
            min: s.min,
            max: s.max,
            bbox_min: bmin.to_array(),
            bbox_max: bmax.to_array(),
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
            let bbox = format!(
                "{},{},{}..{},{},{}",
                g.bbox_min[0],
                g.bbox_min[1],
                g.bbox_min[2],
                g.bbox_max[0],
                g.bbox_max[1],
                g.bbox_max[2]
            );
            writeln!(
                f,
                "{:<16} {:<7} {:<10} {:>4} {:>12} {:>10} {:>7} {:>8} {:>14.6e} {:>12.6} {:>12.6} {:>22} {:>10.6} {:>10.2}",
                if g.name.is_empty() { "(unnamed)" } else { &g.name },
                g.value_type,
                g.class,
                if g.half { "yes" } else { "no" },
                g.active_voxels,
                g.leaf_voxels,
                g.tiles,
                g.leaves,
                g.sum,
                g.min,
                g.max,
                bbox,
                g.voxel_size[0],
                g.memory_bytes as f64 / (1024.0 * 1024.0)
            )?;
        }
        Ok(())
    }
}
