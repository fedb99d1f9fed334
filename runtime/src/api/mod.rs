//! The API layer: the two public types whose methods are the runtime's queries, [`Blend`] (any
//! weights, on every call) and [`Prepared`] (one weight vector, mixed once). Each type's methods
//! live in its one file; each checks its arguments and calls the layers below.
//!
//! [`Blend`]: blend::Blend
//! [`Prepared`]: prepared::Prepared

pub(crate) mod blend;
pub(crate) mod prepared;
