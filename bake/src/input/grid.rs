//! [`Grid`]: a piecewise-constant density over `[0,1]^d` (conventions in the module docs of `input`).

use super::InputError;

/// A density on a regular grid over `[0,1]^d`. Axis 0 varies fastest in the buffers (see the
/// module docs of [`crate::input`] for the cell convention).
#[derive(Clone, Debug, PartialEq)]
pub struct Grid {
    /// Cells per axis, axis 0 first; every entry is > 0.
    pub dims: Vec<usize>,
    /// Mass per cell, `>= 0` and finite; not normalized.
    pub mass: Vec<f32>,
    /// Color-to-mass ratio per cell in linear RGB, or empty when the input has no color.
    pub ratio: Vec<[f32; 3]>,
}

impl Grid {
    /// Checks the sizes (one mass per cell, one ratio per cell or none), that masses and ratios are
    /// finite and `>= 0`, and that the total mass is positive.
    pub fn new(dims: Vec<usize>, mass: Vec<f32>, ratio: Vec<[f32; 3]>) -> Result<Self, InputError> {
        if dims.is_empty() {
            return Err(InputError::GridShape(
                "it has no axes: give at least one dimension".into(),
            ));
        }
        if let Some(axis) = dims.iter().position(|&n| n == 0) {
            return Err(InputError::GridShape(format!(
                "axis {axis} of dims {dims:?} has 0 cells: every axis needs at least one cell"
            )));
        }
        let cells = dims
            .iter()
            .try_fold(1usize, |acc, &n| acc.checked_mul(n))
            .ok_or_else(|| {
                InputError::GridShape(format!("dims {dims:?} have more cells than fit in memory"))
            })?;
        if mass.len() != cells {
            return Err(InputError::GridShape(format!(
                "dims {dims:?} have {cells} cells but {} masses were given",
                mass.len()
            )));
        }
        if !ratio.is_empty() && ratio.len() != cells {
            return Err(InputError::GridShape(format!(
                "dims {dims:?} have {cells} cells but {} color ratios were given (give one per cell, or none)",
                ratio.len()
            )));
        }
        if let Some(index) = mass.iter().position(|m| !(m.is_finite() && *m >= 0.0)) {
            return Err(InputError::GridValue {
                index,
                what: "mass",
                value: mass[index],
            });
        }
        if let Some((index, value)) = ratio.iter().enumerate().find_map(|(i, rgb)| {
            rgb.iter()
                .find(|c| !(c.is_finite() && **c >= 0.0))
                .map(|c| (i, *c))
        }) {
            return Err(InputError::GridValue {
                index,
                what: "color ratio",
                value,
            });
        }
        let grid = Grid { dims, mass, ratio };
        if grid.total_mass() <= 0.0 {
            return Err(InputError::GridNoMass);
        }
        Ok(grid)
    }

    /// Number of axes `d`.
    pub fn dim(&self) -> usize {
        self.dims.len()
    }

    /// Number of cells (the product of `dims`).
    pub fn cells(&self) -> usize {
        self.dims.iter().product()
    }

    /// Sum of all masses in `f64`, added in buffer order (deterministic).
    pub fn total_mass(&self) -> f64 {
        self.mass.iter().map(|&m| f64::from(m)).sum()
    }

    /// Mean mass per cell: the scale that normalization removes and the run-time puts back.
    /// Summed in `f64` in buffer order, so it is the same on every machine and thread count.
    pub fn mean_mass(&self) -> f64 {
        self.total_mass() / self.cells() as f64
    }

    /// Buffer index of the cell containing `p` (`p.len() == dim()`), clamped to the grid; `NaN`
    /// coordinates go to cell 0.
    pub fn cell_index(&self, p: &[f32]) -> usize {
        assert_eq!(p.len(), self.dim(), "point has the wrong dimension");
        let mut index = 0usize;
        let mut stride = 1usize;
        for (&x, &n) in p.iter().zip(&self.dims) {
            // `as usize` saturates: negatives and NaN give 0, +inf gives usize::MAX.
            let i = ((f64::from(x) * n as f64).floor() as usize).min(n - 1);
            index += i * stride;
            stride *= n;
        }
        index
    }

    /// Color-to-mass ratio of the cell containing `p` (clamped to the grid); `[1, 1, 1]` when the
    /// grid has no color, so that `mass · ratio` is a grey of the right brightness.
    pub fn ratio_at(&self, p: &[f32]) -> [f32; 3] {
        if self.ratio.is_empty() {
            assert_eq!(p.len(), self.dim(), "point has the wrong dimension");
            return [1.0; 3];
        }
        self.ratio[self.cell_index(p)]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn new_validates_sizes_and_values() {
        assert!(Grid::new(vec![2, 2], vec![1.0; 4], vec![]).is_ok());
        assert!(matches!(
            Grid::new(vec![], vec![], vec![]),
            Err(InputError::GridShape(_))
        ));
        assert!(matches!(
            Grid::new(vec![0, 3], vec![], vec![]),
            Err(InputError::GridShape(_))
        ));
        assert!(matches!(
            Grid::new(vec![2, 2], vec![1.0; 3], vec![]),
            Err(InputError::GridShape(_))
        ));
        assert!(matches!(
            Grid::new(vec![2, 2], vec![1.0; 4], vec![[1.0; 3]; 3]),
            Err(InputError::GridShape(_))
        ));
        assert!(matches!(
            Grid::new(vec![usize::MAX, 3], vec![1.0], vec![]),
            Err(InputError::GridShape(_))
        ));
        for bad in [f32::NAN, f32::INFINITY, -1.0] {
            let err = Grid::new(vec![3], vec![1.0, bad, 1.0], vec![]).unwrap_err();
            assert!(
                matches!(err, InputError::GridValue { index: 1, .. }),
                "{err}"
            );
        }
        let err = Grid::new(vec![2], vec![1.0; 2], vec![[0.0; 3], [0.0, f32::NAN, 0.0]]);
        assert!(matches!(err, Err(InputError::GridValue { index: 1, .. })));
        assert!(matches!(
            Grid::new(vec![2, 1], vec![0.0; 2], vec![]),
            Err(InputError::GridNoMass)
        ));
    }

    #[test]
    fn density_channel_names_deserialize() {
        #[derive(serde::Deserialize)]
        struct Input {
            #[serde(default)]
            density: crate::input::DensityChannel,
        }
        use crate::input::DensityChannel as D;
        for (text, want) in [
            ("density = \"luminance\"", D::Luminance),
            ("density = \"inverted\"", D::Inverted),
            ("density = \"alpha\"", D::Alpha),
            ("", D::Luminance),
        ] {
            let got: Input = toml::from_str(text).unwrap();
            assert_eq!(got.density, want, "{text}");
            assert_eq!(want.to_string(), want.name());
        }
        assert!(toml::from_str::<Input>("density = \"Inverted\"").is_err());
    }

    #[test]
    fn sizes_mean_and_ratio_lookup() {
        // 3 x 2 grid, axis 0 fastest: cell (x, y) at x + 3 y.
        let ratio: Vec<[f32; 3]> = (0..6).map(|i| [i as f32, 0.0, 0.0]).collect();
        let g = Grid::new(vec![3, 2], vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.0], ratio).unwrap();
        assert_eq!(g.dim(), 2);
        assert_eq!(g.cells(), 6);
        assert_eq!(g.mean_mass(), 3.5);
        assert_eq!(g.ratio_at(&[0.0, 0.0])[0], 0.0);
        assert_eq!(g.ratio_at(&[0.5, 0.0])[0], 1.0);
        assert_eq!(g.ratio_at(&[0.9, 0.2])[0], 2.0);
        assert_eq!(g.ratio_at(&[0.1, 0.5])[0], 3.0);
        assert_eq!(g.ratio_at(&[0.99, 0.99])[0], 5.0);
        // Boundaries belong to the upper cell; outside points clamp.
        assert_eq!(g.ratio_at(&[1.0 / 3.0 + 1e-6, 0.5])[0], 4.0);
        assert_eq!(g.ratio_at(&[1.0, 1.0])[0], 5.0);
        assert_eq!(g.ratio_at(&[-3.0, 7.0])[0], 3.0);
        assert_eq!(g.ratio_at(&[f32::NAN, f32::INFINITY])[0], 3.0);
        let plain = Grid::new(vec![2, 2, 2], vec![1.0; 8], vec![]).unwrap();
        assert_eq!(plain.ratio_at(&[0.2, 0.7, 0.1]), [1.0; 3]);
    }
}
