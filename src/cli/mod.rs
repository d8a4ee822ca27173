//! The commands of the `caustica` binary that take more than a few lines (modules of the
//! binary, not of the library).

pub mod animate;
pub mod bench;
pub mod info;
pub mod render;
