//! Renders and exports of blends. Every value goes through `otbake-runtime`, exactly as an engine's
//! would, so the images double as tests of the runtime:
//!
//! * [`image`]: 2D blends as images (per-pixel point queries or one splat), and grids of blends;
//! * [`texture`]: textures whose blend weights vary per pixel;
//! * [`volume`]: ray-marched images, slices and `.vol` exports of 3D blends;
//! * [`brdf`]: BRDF blends evaluated and sampled as a BSDF would, their images and MERL exports;
//! * [`points`]: a map as a `.npy` matrix of proxy and mapped positions;
//! * [`imageio`]: PNG and EXR output;
//! * [`memory`]: what each render will allocate, for the budget check before it starts.
//!
//! Architecture Invariant: nothing here bakes or writes archives; renders read archives through
//! [`Archives`] and the runtime only.

pub mod brdf;
pub mod image;
pub mod imageio;
pub mod memory;
pub mod npy;
pub mod points;
pub mod texture;
pub mod volume;

pub use image::{
    composite, grid_cells, render, render_grid, shade, Archives, Method, RenderError,
    RenderSettings,
};
