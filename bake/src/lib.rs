//! otbake: bake optimal-transport maps of appearance assets.
pub mod input;
pub mod proxy;
pub mod sample;
pub mod solve;
