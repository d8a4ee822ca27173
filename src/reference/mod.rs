//! CPU renderers that mirror parts of the optical model, for checking the GPU renderer.

pub mod straight;
