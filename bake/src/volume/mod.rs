//! 3D inputs (paper §5.1, §6.3): Mitsuba `.vol` density grids ([`vol`]).
//!
//! # Domain
//!
//! Volumes live in the unit cube like every input: axis 0 = x, axis 1 = y, axis 2 = z, x fastest in
//! grid buffers (the cell convention of [`crate::input`]). A `.vol` grid fills the cube axis by
//! axis (its header's bounding box is kept, not used for placement).

pub mod vol;
