//! Importance sampling of a piecewise-constant density grid by inverse CDFs (paper §5.1).
//!
//! The grid is marginalized over its fastest axes: level `k` holds, for every cell of the slower
//! axes `k+1..d`, the cumulative distribution along axis `k` of the mass summed over axes `0..k`.
//! A point samples the slowest axis from the single level-`d−1` CDF, then each faster axis from the
//! CDF conditioned on the cells already chosen, down to axis 0. Axis `k` consumes Sobol dimension
//! `k`; the part of the uniform variate left over inside the chosen cell places the point inside it,
//! so the point is exactly the piecewise-constant inverse CDF of the Sobol point (up to `f32`
//! rounding, which never leaves the cell).

use rayon::prelude::*;

use super::{check_count, map_sobol_points, SampleError, Sobol};
use crate::input::Grid;

/// Draws `n` points distributed like `grid`'s mass, in `[0,1)^d`, point-major (`n · d` values).
/// Point `i` is the inverse CDF of point `i` of the Sobol sequence scrambled by `seed`, so the
/// output depends only on `(grid, n, seed)`, and the first `n` points of a larger request are the
/// same. Cells of zero mass never receive a point.
pub fn importance_sample(grid: &Grid, n: usize, seed: u64) -> Result<Vec<f32>, SampleError> {
    check_count(n)?;
    let table = CdfTable::new(grid)?;
    let sobol = Sobol::new(table.dims.len(), seed)?;
    Ok(map_sobol_points(&sobol, n, table.dims.len(), |u, p| {
        table.invert(u, p)
    }))
}

/// The marginal and conditional CDFs of a grid (cumulative sums in `f64`).
struct CdfTable {
    dims: Vec<usize>,
    /// `levels[k]` holds one inclusive cumulative sum of length `dims[k]` per cell of axes `k+1..d`
    /// (those cells ordered with axis `k+1` fastest), so level `d−1` is a single run.
    levels: Vec<Vec<f64>>,
}

impl CdfTable {
    fn new(grid: &Grid) -> Result<Self, SampleError> {
        let dims = grid.dims.clone();
        let d = dims.len();
        if d == 0 || d > Sobol::MAX_DIMS {
            return Err(SampleError::Dims {
                dims: d,
                max: Sobol::MAX_DIMS,
            });
        }
        if dims.contains(&0) {
            return Err(SampleError::InvalidGrid(format!(
                "dims {dims:?} have an axis with 0 cells"
            )));
        }
        let cells = dims.iter().try_fold(1usize, |a, &n| a.checked_mul(n));
        if cells != Some(grid.mass.len()) {
            return Err(SampleError::InvalidGrid(format!(
                "dims {dims:?} do not match the {} masses given",
                grid.mass.len()
            )));
        }
        if grid.mass.par_iter().any(|m| !(m.is_finite() && *m >= 0.0)) {
            return Err(SampleError::InvalidGrid(
                "a mass is negative, NaN or infinite (build grids with Grid::new)".into(),
            ));
        }
        let mut levels: Vec<Vec<f64>> = Vec::with_capacity(d);
        let mut level0 = vec![0f64; grid.mass.len()];
        level0
            .par_chunks_mut(dims[0])
            .zip(grid.mass.par_chunks(dims[0]))
            .for_each(|(cdf, mass)| prefix_sum(mass.iter().map(|&m| f64::from(m)), cdf));
        levels.push(level0);
        for k in 1..d {
            let below = &levels[k - 1];
            let n_below = dims[k - 1];
            let mut level = vec![0f64; below.len() / n_below];
            level
                .par_chunks_mut(dims[k])
                .enumerate()
                .for_each(|(r, cdf)| {
                    let base = r * dims[k];
                    let totals = (0..dims[k]).map(|j| below[(base + j) * n_below + n_below - 1]);
                    prefix_sum(totals, cdf);
                });
            levels.push(level);
        }
        let total = levels[d - 1][dims[d - 1] - 1];
        if !(total > 0.0 && total.is_finite()) {
            return Err(SampleError::InvalidGrid(format!(
                "its total mass is {total}: give a grid with some mass"
            )));
        }
        Ok(CdfTable { dims, levels })
    }

    /// Maps a uniform point `u` (Sobol dimension `k` drives axis `k`) to a position in the grid.
    fn invert(&self, u: &[f64], out: &mut [f32]) {
        let mut run = 0usize;
        for k in (0..self.dims.len()).rev() {
            let n = self.dims[k];
            let cdf = &self.levels[k][run * n..(run + 1) * n];
            let (i, frac) = pick(cdf, u[k]);
            out[k] = place_in_cell(i, frac, n);
            run = run * n + i;
        }
    }
}

fn prefix_sum(values: impl Iterator<Item = f64>, out: &mut [f64]) {
    let mut acc = 0.0;
    for (o, v) in out.iter_mut().zip(values) {
        acc += v;
        *o = acc;
    }
}

/// Inverse of one cumulative run at `u ∈ [0,1)`: the cell `i` with `cdf[i−1] <= u·total < cdf[i]`
/// (so a cell whose cumulative sum does not grow, i.e. of zero mass, is never chosen) and the
/// fraction of the way through it. The run's total is positive whenever it is reached.
fn pick(cdf: &[f64], u: f64) -> (usize, f64) {
    let last = cdf.len() - 1;
    let target = u * cdf[last];
    let i = cdf.partition_point(|&c| c <= target);
    if i > last {
        // Only if u·total rounded up to total (u < 1 rules it out): take the last cell with mass.
        let i = (1..=last).rev().find(|&i| cdf[i] > cdf[i - 1]).unwrap_or(0);
        return (i, 1.0);
    }
    let lo = if i == 0 { 0.0 } else { cdf[i - 1] };
    (i, ((target - lo) / (cdf[i] - lo)).clamp(0.0, 1.0))
}

/// `(i + frac) / n` as `f32`, nudged so that the cell of the result is `i` both in `f64`
/// (`floor(x · n)`, the convention of `Grid`) and in plain `f32` arithmetic.
fn place_in_cell(i: usize, frac: f64, n: usize) -> f32 {
    let cell_of = |x: f32| {
        let wide = (f64::from(x) * n as f64).floor();
        let narrow = f64::from((x * n as f32).floor());
        (wide.min(narrow), wide.max(narrow))
    };
    let want = i as f64;
    let mut x = ((want + frac) / n as f64) as f32;
    for _ in 0..64 {
        let (lo, hi) = cell_of(x);
        if lo == want && hi == want {
            return x;
        }
        x = if hi > want {
            f32::from_bits(x.to_bits() - 1)
        } else {
            f32::from_bits(x.to_bits() + 1)
        };
    }
    ((want + 0.5) / n as f64) as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small deterministic generator for test grids.
    struct Rng(u64);
    impl Rng {
        fn next(&mut self) -> f64 {
            self.0 = self
                .0
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (self.0 >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    /// A random grid with about a quarter of the cells empty and masses spanning two decades.
    fn random_grid(dims: &[usize], seed: u64) -> Grid {
        let mut rng = Rng(seed);
        let cells = dims.iter().product();
        let mass = (0..cells)
            .map(|_| {
                if rng.next() < 0.25 {
                    0.0
                } else {
                    (10f64.powf(2.0 * rng.next())) as f32
                }
            })
            .collect();
        Grid::new(dims.to_vec(), mass, vec![]).unwrap()
    }

    fn counts(grid: &Grid, pts: &[f32]) -> Vec<u64> {
        let mut c = vec![0u64; grid.cells()];
        for p in pts.chunks_exact(grid.dim()) {
            c[grid.cell_index(p)] += 1;
        }
        c
    }

    /// Pearson's statistic over the cells with mass, and its degrees of freedom.
    fn chi_square(grid: &Grid, counts: &[u64], n: usize) -> (f64, usize) {
        let total = grid.total_mass();
        let (mut stat, mut cells) = (0.0, 0);
        for (&m, &c) in grid.mass.iter().zip(counts) {
            if m > 0.0 {
                let e = n as f64 * f64::from(m) / total;
                stat += (c as f64 - e).powi(2) / e;
                cells += 1;
            }
        }
        (stat, cells - 1)
    }

    /// Exact per-axis means, second moments and axis-0/1 cross moment of the piecewise-constant
    /// density, against the same sums over the points.
    fn check_moments(grid: &Grid, pts: &[f32], tol: f64) {
        let d = grid.dim();
        let total = grid.total_mass();
        let (mut mean, mut sq) = (vec![0.0; d], vec![0.0; d]);
        let mut cross = 0.0;
        for (idx, &m) in grid.mass.iter().enumerate() {
            let w = f64::from(m) / total;
            let mut rest = idx;
            let mut c = vec![0.0; d];
            for k in 0..d {
                let n = grid.dims[k] as f64;
                let i = (rest % grid.dims[k]) as f64;
                rest /= grid.dims[k];
                c[k] = (i + 0.5) / n;
                mean[k] += w * c[k];
                sq[k] += w * (c[k] * c[k] + 1.0 / (12.0 * n * n));
            }
            if d > 1 {
                cross += w * c[0] * c[1];
            }
        }
        let n = (pts.len() / d) as f64;
        for k in 0..d {
            let m: f64 = pts
                .iter()
                .skip(k)
                .step_by(d)
                .map(|&x| f64::from(x))
                .sum::<f64>()
                / n;
            let s: f64 = pts
                .iter()
                .skip(k)
                .step_by(d)
                .map(|&x| f64::from(x).powi(2))
                .sum::<f64>()
                / n;
            assert!(
                (m - mean[k]).abs() < tol,
                "axis {k} mean {m} vs {}",
                mean[k]
            );
            assert!((s - sq[k]).abs() < tol, "axis {k} E[x^2] {s} vs {}", sq[k]);
        }
        if d == 1 {
            return;
        }
        let xy: f64 = pts
            .chunks_exact(d)
            .map(|p| f64::from(p[0]) * f64::from(p[1]))
            .sum::<f64>()
            / n;
        assert!((xy - cross).abs() < tol, "E[x0 x1] {xy} vs {cross}");
    }

    fn check_distribution(dims: &[usize], seed: u64) {
        let grid = random_grid(dims, seed);
        let n = 1 << 16;
        let pts = importance_sample(&grid, n, 1234).unwrap();
        assert_eq!(pts.len(), n * dims.len());
        assert!(pts.iter().all(|&x| (0.0..1.0).contains(&x)));
        let c = counts(&grid, &pts);
        for (i, (&m, &k)) in grid.mass.iter().zip(&c).enumerate() {
            assert!(m > 0.0 || k == 0, "{k} points in empty cell {i}");
        }
        let (stat, df) = chi_square(&grid, &c, n);
        // Independent samples would give stat ≈ df (χ² 0.999 quantile ≈ df + 3.1·sqrt(2 df)).
        // Stratified inverse-CDF points must be far below: require stat < df / 10.
        let quantile_999 = df as f64 + 3.1 * (2.0 * df as f64).sqrt();
        assert!(stat < quantile_999, "χ² {stat} over {df} dof");
        assert!(
            stat < df as f64 / 10.0,
            "χ² {stat} over {df} dof: not stratified"
        );
        check_moments(&grid, &pts, 2e-4);
    }

    #[test]
    fn reproduces_a_random_2d_grid() {
        check_distribution(&[16, 16], 1);
    }

    #[test]
    fn reproduces_a_random_3d_grid() {
        check_distribution(&[6, 5, 4], 2);
    }

    #[test]
    fn reproduces_1d_and_4d_grids() {
        check_distribution(&[37], 3);
        check_distribution(&[3, 4, 2, 5], 4);
    }

    /// Points are the exact piecewise-constant inverse CDF of the Sobol points: slowest axis from
    /// its marginal, then axis 0 from the row chosen.
    #[test]
    fn matches_a_brute_force_inverse_cdf() {
        let mass = [0.0, 1.0, 3.0, 0.0, 0.0, 0.0, 2.0, 0.0, 2.0];
        let grid = Grid::new(vec![3, 3], mass.to_vec(), vec![]).unwrap();
        let pts = importance_sample(&grid, 300, 77).unwrap();
        let mass = mass.map(f64::from);
        let sobol = Sobol::new(2, 77).unwrap();
        let inverse = |w: &[f64], u: f64| -> f64 {
            let total: f64 = w.iter().sum();
            let mut acc = 0.0;
            for (i, &m) in w.iter().enumerate() {
                if m > 0.0 && u * total < acc + m {
                    return (i as f64 + (u * total - acc) / m) / w.len() as f64;
                }
                acc += m;
            }
            unreachable!()
        };
        let mut u = [0.0; 2];
        for (i, p) in pts.chunks_exact(2).enumerate() {
            sobol.point(i as u64, &mut u);
            let rows: Vec<f64> = (0..3)
                .map(|y| mass[3 * y..3 * y + 3].iter().sum())
                .collect();
            let y = inverse(&rows, u[1]);
            let row = (y * 3.0) as usize;
            let x = inverse(&mass[3 * row..3 * row + 3], u[0]);
            assert!(
                (f64::from(p[0]) - x).abs() < 1e-6,
                "point {i}: x {} vs {x}",
                p[0]
            );
            assert!(
                (f64::from(p[1]) - y).abs() < 1e-6,
                "point {i}: y {} vs {y}",
                p[1]
            );
        }
    }

    #[test]
    fn deterministic_for_any_thread_count_and_prefix_stable() {
        let grid = random_grid(&[20, 9], 5);
        let n = 3 * 4096 + 17;
        let run = |threads| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| importance_sample(&grid, n, 9).unwrap())
        };
        let one = run(1);
        assert_eq!(one, run(2));
        assert_eq!(one, run(3));
        assert_eq!(&importance_sample(&grid, 100, 9).unwrap()[..], &one[..200]);
        assert_ne!(one, importance_sample(&grid, n, 10).unwrap());
    }

    #[test]
    fn extreme_masses_stay_in_their_cells() {
        // A lone tiny cell next to huge ones, and fine cells where f32 rounding meets boundaries.
        let mut mass = vec![0.0f32; 1000];
        mass[0] = 1e-30;
        mass[999] = 1e30;
        mass[500] = 3.0e29;
        let grid = Grid::new(vec![1000], mass, vec![]).unwrap();
        let pts = importance_sample(&grid, 5000, 1).unwrap();
        for &x in &pts {
            let i = grid.cell_index(&[x]);
            assert!(i == 999 || i == 500 || i == 0, "point {x} in cell {i}");
            assert!(x < 1.0);
        }
        for i in [0usize, 1, 7, 699, 999] {
            for frac in [0.0, 1e-12, 0.5, 1.0 - 1e-12, 1.0] {
                let x = place_in_cell(i, frac, 1000);
                assert_eq!((f64::from(x) * 1000.0).floor(), i as f64);
                assert_eq!((x * 1000.0f32).floor(), i as f32);
            }
        }
    }

    /// A real shape: every point lands on ink, and the points' cells are the heavy ones.
    #[test]
    fn samples_a_real_shape_on_its_ink() {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../shared/data/shapes/duck.png");
        let path = if path.exists() {
            path
        } else {
            std::path::PathBuf::from("/work/shared/data/shapes/duck.png")
        };
        let grid = crate::input::load_image(&path, crate::input::DensityChannel::Inverted).unwrap();
        let n = 1 << 13;
        let pts = importance_sample(&grid, n, 3).unwrap();
        let c = counts(&grid, &pts);
        assert!(grid.mass.iter().zip(&c).all(|(&m, &k)| m > 0.0 || k == 0));
        let (stat, df) = chi_square(&grid, &c, n);
        assert!(stat < df as f64, "χ² {stat} over {df} dof");
        let at_points: f64 = c
            .iter()
            .zip(&grid.mass)
            .map(|(&k, &m)| k as f64 * f64::from(m))
            .sum();
        // E_p[mass] = Σ m² / Σ m >= mean mass, with equality only for flat images.
        assert!(at_points / n as f64 > 1.5 * grid.mean_mass());
        check_moments(&grid, &pts, 1e-3);
    }

    #[test]
    fn bad_requests_are_errors() {
        let grid = random_grid(&[4, 4], 6);
        assert!(matches!(
            importance_sample(&grid, 0, 0),
            Err(SampleError::NoSamples)
        ));
        let err = importance_sample(&grid, super::super::MAX_SAMPLES + 1, 0).unwrap_err();
        assert!(err.to_string().contains("268435456"), "{err}");
        let bad = |dims: Vec<usize>, mass: Vec<f32>| Grid {
            dims,
            mass,
            ratio: vec![],
        };
        for g in [
            bad(vec![2, 2], vec![1.0; 3]),
            bad(vec![2, 2], vec![1.0, -1.0, 1.0, 1.0]),
            bad(vec![2], vec![f32::NAN, 1.0]),
            bad(vec![2], vec![0.0, 0.0]),
            bad(vec![0], vec![]),
        ] {
            assert!(
                matches!(
                    importance_sample(&g, 10, 0),
                    Err(SampleError::InvalidGrid(_))
                ),
                "{:?}",
                g.dims
            );
        }
        assert!(matches!(
            importance_sample(&bad(vec![1; 22], vec![1.0]), 10, 0),
            Err(SampleError::Dims { dims: 22, .. })
        ));
        assert!(matches!(
            importance_sample(&bad(vec![], vec![]), 10, 0),
            Err(SampleError::Dims { dims: 0, .. })
        ));
    }
}
