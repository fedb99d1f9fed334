//! (to be written by the runtime work)
fn main() {}
