//! Parts of the `nimbus` command line that `main.rs` delegates to.

pub(crate) mod frame;
