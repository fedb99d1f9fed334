//! 3D inputs (paper §5.1, §6.3): Mitsuba `.vol` density grids ([`vol`]) and triangle meshes
//! ([`mesh`]) voxelized by generalized winding numbers ([`winding`], [`voxelize`]).
//!
//! # Domain
//!
//! Volumes live in the unit cube like every input: axis 0 = x, axis 1 = y, axis 2 = z, x fastest in
//! grid buffers (the cell convention of [`crate::input`]). A `.vol` grid fills the cube axis by
//! axis (its header's bounding box is kept, not used for placement); a mesh is scaled uniformly and
//! centered by its bounding box or by one box shared by all mesh inputs ([`voxelize`]).

pub mod mesh;
pub mod render;
pub mod vol;
pub mod voxelize;
pub mod winding;
