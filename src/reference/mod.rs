//! CPU renderers that mirror the optical model, for checking and measuring the GPU one.
//!
//! - [`straight`]: emission–absorption along straight rays with the GPU's own planes and
//!   tables; checks the sweep where the method has an exact discrete counterpart.
//! - the independent reference ([`render`]): written for accuracy, not speed (f64, rayon).
//!   It shares only the scene, transfer-function, volume and camera types with the GPU path:
//!   [`medium`] is the continuous optical field, [`rk4`] integrates the ray equation,
//!   [`photons`] traces light forward from the distant source into a fluence grid (caustics
//!   from ray density), and view rays composite with the Oddy–Willis model.
//! - [`plane_light`]: the exact irradiance of the light on planes of constant view depth (what
//!   the GPU's light buffer holds at a plane), by the same forward rays.
//! - [`scatter`]: Monte Carlo multiple scattering (delta tracking, Henyey–Greenstein
//!   sampling) through a scattering medium: where the light of a beam goes and how wide it
//!   spreads.
//! - [`scatter_view`]: the image of a scattering medium by Monte Carlo path tracing from the
//!   eye (next-event estimation to the distant light).
//! - [`graded_ball`]: an analytic graded-index ball lens (the exact object behind the light
//!   bench's voxelised ball).
//! - [`measure`]: the comparisons tests and the bench make between images of light.

// Per-channel loops index several [f64; 3] arrays at once; iterators would hide that.
#![allow(clippy::needless_range_loop)]

pub mod graded_ball;
#[cfg(test)]
mod lens_tests;
pub mod measure;
pub mod medium;
pub mod photons;
pub mod plane_light;
#[cfg(test)]
mod plane_tests;
pub mod rk4;
pub mod scatter;
#[cfg(test)]
mod scatter_tests;
pub mod scatter_view;
#[cfg(test)]
mod scatter_view_tests;
#[cfg(test)]
mod scene_tests;
pub mod shading;
pub mod straight;
#[cfg(test)]
mod tests;
mod view;

pub use view::{render, ReferenceError, ReferenceSettings};
