//! Pieces the bench binaries share (each includes this folder as `mod support;`).

// Each bench binary compiles this module on its own and uses only some of it.
#![allow(dead_code)]

use nimbus::vdb::{read_file, Grid};
use std::path::Path;

/// The scalar grid a bench tracks through in the VDB file at `path`: the float grid named `density`, else the
/// last float grid. `None`, after printing why, when the file cannot be read or holds no float grid.
pub fn scalar_grid(path: &Path) -> Option<Grid> {
    let file = match read_file(path) {
        Ok(f) => f,
        Err(e) => {
            println!("skipping {}: {e}", path.display());
            return None;
        }
    };
    let grid = file
        .grids
        .into_iter()
        .filter(|g| g.tree.as_float().is_some())
        .max_by_key(|g| g.name == "density");
    if grid.is_none() {
        println!("skipping {}: no scalar grid", path.display());
    }
    grid
}

/// The argument that follows `flag` in `args`, if any.
pub fn flag_value<'a>(args: &'a [String], flag: &str) -> Option<&'a String> {
    args.iter()
        .position(|a| a == flag)
        .and_then(|i| args.get(i + 1))
}
