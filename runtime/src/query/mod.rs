//! The query layer: point, range, density-adaptive and sample queries and the whole-grid splat,
//! each written once, generic over its [`Source`](crate::source::Source) (a blend mixing on the
//! fly or one prepared into buffers), and their periodic wrappers ([`periodic`]), which run a
//! query once per image of a periodic blend.

pub(crate) mod adaptive;
pub(crate) mod periodic;
pub(crate) mod point;
pub(crate) mod range;
pub(crate) mod sample;
pub(crate) mod splat;
