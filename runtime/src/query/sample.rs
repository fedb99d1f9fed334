//! Sample queries: the points of the blend, each a sample of the barycenter distribution.

use crate::base::error::Error;
use crate::source::{Sample, Source};

/// The `index`-th blended point.
pub(crate) fn sample(s: &impl Source, index: u32) -> Result<Sample, Error> {
    if index >= s.n() {
        return Err(Error::IndexOutOfRange { index, n: s.n() });
    }
    let leaf = otbake_formats::tree::leaf_of(s.n(), s.depth(), index);
    let mut state = s.leaf_state();
    s.enter(leaf, &mut state);
    Ok(Sample {
        position: s.position(&state, index as usize),
        color: s.color(index as usize),
    })
}
