//! The truncated kernel on the torus keeps exactly the pairs a dense scan with the torus cost keeps
//! (the bounds over the query's images are valid and the search misses nothing).

use super::hierarchy::{Grid, Hierarchy};
use super::kernel::build_three_ways;
use crate::cost::sq;
use otbake_formats::Wrap;

#[allow(clippy::needless_range_loop)]
#[test]
fn torus_truncation_equals_dense_scan() {
    // Points crowding the borders and corners, so that most nearest images are across a seam.
    let pts = |seed: f64, n: usize| -> Vec<[f64; 2]> {
        (0..n)
            .map(|i| {
                let a = ((i as f64 + seed) * 0.754_877_666).fract();
                let b = ((i as f64 + seed) * 0.569_840_29).fract();
                let edge = |t: f64| (1.0 + 0.25 * (t - 0.5)).fract();
                if i % 3 == 0 {
                    [a, b]
                } else {
                    [edge(a), edge(b)]
                }
            })
            .collect()
    };
    let (a, b) = (pts(0.3, 600), pts(0.7, 600));
    let grid = Grid::new(&a, &b);
    let (hs, ht) = (Hierarchy::new(&a, &grid, 5), Hierarchy::new(&b, &grid, 5));
    for (level, rough) in [(2usize, 0.0), (4, 1.0), (5, 0.0), (6, 0.0), (6, 1.0)] {
        let (xs, ys) = (&hs.levels[level], &ht.levels[level]);
        // Smooth periodic potentials with large gradients, optionally with noise.
        let g: Vec<f64> = ys
            .pos
            .iter()
            .enumerate()
            .map(|(j, y)| {
                0.05 * (std::f64::consts::TAU * y[0]).sin()
                    + 0.03 * (std::f64::consts::TAU * (y[0] + 2.0 * y[1])).cos()
                    + rough * 1e-3 * ((j as f64 * 12.9898).sin() * 43758.5453).fract()
            })
            .collect();
        let (eps, theta) = (1e-3, 8.0);
        let kern = build_three_ways(&hs, &ht, level, &g, eps, theta, Wrap::Periodic, 4.0 * eps);
        let c = |i: usize, j: usize| sq(Wrap::Periodic, &xs.pos[i], &ys.pos[j]);
        let f: Vec<f64> = (0..xs.len())
            .map(|i| {
                (0..ys.len())
                    .map(|j| c(i, j) - g[j])
                    .fold(f64::INFINITY, f64::min)
            })
            .collect();
        let mut across = 0;
        for i in 0..xs.len() {
            let cols = &kern.col[kern.row_ptr[i]..kern.row_ptr[i + 1]];
            for j in 0..ys.len() {
                let row_ok = c(i, j) - g[j] <= f[i] + theta * eps;
                let colmin = (0..xs.len())
                    .map(|i2| c(i2, j) - f[i2])
                    .fold(f64::INFINITY, f64::min);
                let col_ok = c(i, j) - f[i] <= colmin + theta * eps;
                let kept = cols.contains(&(j as u32));
                assert_eq!(kept, row_ok || col_ok, "level {level} pair ({i},{j})");
                let euclid = sq(Wrap::Clamp, &xs.pos[i], &ys.pos[j]);
                across += (kept && euclid > c(i, j) + 1e-12) as usize;
            }
            assert_eq!(kern.f[i], f[i]);
        }
        // The test means something: many kept pairs are nearer across a seam than inside.
        assert!(
            across > xs.len() / 4,
            "level {level}: {across} pairs across a seam"
        );
    }
}
