//! The kernel against dense scans: the truncation, the local rebuilds and the transpose.

use super::super::hierarchy::Grid;
use super::*;

fn pts(seed: f64, n: usize) -> Vec<[f64; 2]> {
    (0..n)
        .map(|i| {
            let t = (i as f64 + seed) * 0.754_877_666;
            [t.fract(), ((i as f64 + seed) * 0.569_840_29).fract() * 0.5]
        })
        .collect()
}

/// Smooth potentials with large gradients (like real ones), optionally with noise.
fn potential(ys: &[[f64; 2]], rough: f64) -> Vec<f64> {
    ys.iter()
        .enumerate()
        .map(|(j, y)| {
            0.9 * (y[0] * y[0] + y[1] * y[1]) - 0.6 * y[0]
                + 0.3 * y[1]
                + rough * 1e-3 * ((j as f64 * 12.9898).sin() * 43758.5453).fract()
        })
        .collect()
}

/// Builds the kernel three ways and checks they agree bit for bit: from the row minima searched
/// first (no bounds), from bounds of them `loose` above the exact minima (the walk reads the minima
/// off its band), and from bounds so loose that the band passes its cap and the build falls back
/// to the searched minima. Returns the kernel.
#[allow(clippy::too_many_arguments)]
pub(in crate::sinkhorn) fn build_three_ways<const D: usize>(
    hs: &Hierarchy<D>,
    ht: &Hierarchy<D>,
    level: usize,
    g: &[f64],
    eps: f64,
    theta: f64,
    wrap: Wrap,
    loose: f64,
) -> Kernel {
    let (xs, ys) = (&hs.levels[level], &ht.levels[level]);
    let plain = build(hs, ht, level, g, eps, theta, wrap, usize::MAX, None).unwrap();
    let exact: Vec<f64> = (0..xs.len())
        .map(|i| {
            (0..ys.len())
                .map(|j| cost::sq(wrap, &xs.pos[i], &ys.pos[j]) - g[j])
                .fold(f64::INFINITY, f64::min)
        })
        .collect();
    let noise = |i: usize| ((i as f64 * 78.233).sin() * 43758.5453).fract().abs();
    let same = |k: &Kernel, how: &str| {
        assert_eq!(k.row_ptr, plain.row_ptr, "{how}: level {level}");
        assert_eq!(k.col, plain.col, "{how}: level {level}");
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&k.k), bits(&plain.k), "{how}: level {level}");
        assert_eq!(k.f, plain.f, "{how}: level {level}");
    };
    let upper: Vec<f64> = (0..xs.len()).map(|i| exact[i] + loose * noise(i)).collect();
    same(
        &build(hs, ht, level, g, eps, theta, wrap, usize::MAX, Some(&upper)).unwrap(),
        "bounded",
    );
    // A band of every pair, far past four times the kernel's pairs: the searched minima decide.
    let far: Vec<f64> = exact.iter().map(|v| v + 1e3).collect();
    let max = plain.pairs();
    if xs.len() * ys.len() > 4 * max {
        same(
            &build(hs, ht, level, g, eps, theta, wrap, max, Some(&far)).unwrap(),
            "too wide",
        );
    }
    plain
}

/// The block-parallel transpose equals a sequential counting transpose, for patterns with empty
/// rows, empty columns, rows spanning many blocks and fewer columns than blocks.
#[test]
fn transpose_equals_sequential() {
    for (rows, cols) in [(0usize, 3usize), (5, 2), (300, 1000), (2000, 700)] {
        let mut ptr = vec![0usize];
        let mut idx = Vec::new();
        for i in 0..rows {
            let len = (i * 7919) % 13;
            let mut row: Vec<u32> = (0..len)
                .map(|t| (((i * 31 + t * t * 17) % cols.max(1)) as u32).min(cols as u32 - 1))
                .collect();
            if i % 5 == 0 {
                row.extend((0..cols as u32).step_by(97));
            }
            row.sort_unstable();
            row.dedup();
            idx.extend(&row);
            ptr.push(idx.len());
        }
        let mut want: Vec<Vec<u32>> = vec![Vec::new(); cols];
        for i in 0..rows {
            for e in ptr[i]..ptr[i + 1] {
                want[idx[e] as usize].push(i as u32);
            }
        }
        let (tptr, tidx) = transpose(&ptr, &idx, cols);
        for j in 0..cols {
            assert_eq!(
                &tidx[tptr[j]..tptr[j + 1]],
                &want[j][..],
                "{rows}x{cols} column {j}"
            );
        }
        assert_eq!(tptr[cols], idx.len());
    }
}

/// The truncation keeps exactly the pairs a dense scan keeps.
#[allow(clippy::needless_range_loop)]
#[test]
fn truncation_equals_dense_scan() {
    let (a, b) = (pts(0.3, 700), pts(0.7, 700));
    let grid = Grid::new(&a, &b);
    let (hs, ht) = (Hierarchy::new(&a, &grid, 5), Hierarchy::new(&b, &grid, 5));
    for (level, rough) in [(2usize, 0.0), (4, 1.0), (5, 0.0), (6, 0.0), (6, 1.0)] {
        let (xs, ys) = (&hs.levels[level], &ht.levels[level]);
        let g = potential(&ys.pos, rough);
        let eps = 1e-3;
        let theta = 8.0;
        let kern = build_three_ways(&hs, &ht, level, &g, eps, theta, Wrap::Clamp, 4.0 * eps);
        let f: Vec<f64> = (0..xs.len())
            .map(|i| {
                (0..ys.len())
                    .map(|j| sq(&xs.pos[i], &ys.pos[j]) - g[j])
                    .fold(f64::INFINITY, f64::min)
            })
            .collect();
        for i in 0..xs.len() {
            let cols = &kern.col[kern.row_ptr[i]..kern.row_ptr[i + 1]];
            for j in 0..ys.len() {
                let c = sq(&xs.pos[i], &ys.pos[j]);
                let row_ok = c - g[j] <= f[i] + theta * eps;
                let colmin = (0..xs.len())
                    .map(|i2| sq(&xs.pos[i2], &ys.pos[j]) - f[i2])
                    .fold(f64::INFINITY, f64::min);
                let col_ok = c - f[i] <= colmin + theta * eps;
                assert_eq!(
                    cols.contains(&(j as u32)),
                    row_ok || col_ok,
                    "level {level} pair ({i},{j})"
                );
            }
            assert_eq!(kern.f[i], f[i]);
        }
        // The column form holds the same entries.
        let (col_ptr, row) = kern.columns();
        assert_eq!(row.len(), kern.pairs());
        for j in 0..ys.len() {
            for &i in &row[col_ptr[j]..col_ptr[j + 1]] {
                let i = i as usize;
                assert!(kern.col[kern.row_ptr[i]..kern.row_ptr[i + 1]].contains(&(j as u32)));
            }
        }
    }
}

/// A local rebuild after some potentials moved keeps its promise against a dense scan: f is
/// the exact row minimum (so K ≤ 1), and every pair with reduced cost ≤ (θ − 2τ)ε is kept. So
/// does a second one after more moves, from the references the first moved: it searches the rows
/// and columns that moved since, not again every one that moved since the whole build.
#[allow(clippy::needless_range_loop)]
#[test]
fn local_rebuild_keeps_every_pair_it_promises() {
    let (a, b) = (pts(0.3, 900), pts(0.7, 900));
    let grid = Grid::new(&a, &b);
    let (hs, ht) = (Hierarchy::new(&a, &grid, 5), Hierarchy::new(&b, &grid, 5));
    let level = hs.point_level();
    let (xs, ys) = (&hs.levels[level], &ht.levels[level]);
    let (eps, theta, tau) = (1e-3, 8.0, 0.5);
    // A c-concave g0 (the c-transform of a c-transform), as Sinkhorn's potentials nearly are:
    // every column is some row's best, so moving one changes rows' minima.
    let rough = potential(&ys.pos, 1.0);
    let f_raw: Vec<f64> = (0..xs.len())
        .map(|i| {
            (0..ys.len())
                .map(|j| sq(&xs.pos[i], &ys.pos[j]) - rough[j])
                .fold(f64::INFINITY, f64::min)
        })
        .collect();
    let g0: Vec<f64> = (0..ys.len())
        .map(|j| {
            (0..xs.len())
                .map(|i| sq(&xs.pos[i], &ys.pos[j]) - f_raw[i])
                .fold(f64::INFINITY, f64::min)
        })
        .collect();
    let whole = build(
        &hs,
        &ht,
        level,
        &g0,
        eps,
        theta,
        Wrap::Clamp,
        usize::MAX,
        None,
    )
    .unwrap();
    // Every column moves a little (below τε); a patch of columns moves by up to ±12ε, and one
    // column by 40ε (it becomes the best column of rows that never saw it).
    let g: Vec<f64> = g0
        .iter()
        .zip(&ys.pos)
        .enumerate()
        .map(|(j, (&v, y))| {
            let small = 0.4 * eps * ((j as f64 * 0.37).sin());
            let patch = if (y[0] - 0.5).abs() < 0.15 && y[1] < 0.25 {
                12.0 * eps * ((j as f64 * 1.3).sin())
            } else {
                0.0
            };
            let jump = if j == 17 { 40.0 * eps } else { 0.0 };
            v + small + patch + jump
        })
        .collect();
    let mut kern = whole.clone();
    let (mut f_ref, mut g_ref) = (whole.f.clone(), g0.clone());
    let limits = LocalLimits {
        theta,
        tau,
        tau_whole: tau,
        max_moved: xs.len(),
        max_pairs: usize::MAX,
    };
    let rebuild = |kern: &mut Kernel, g_then: &[f64], g: &[f64], refs: (&mut [f64], &mut [f64])| {
        let (f_ref, g_ref) = refs;
        let (hs, ht) = (&hs, &ht);
        rebuild_local(
            hs,
            ht,
            level,
            kern,
            g_then,
            g,
            f_ref,
            g_ref,
            eps,
            limits,
            Wrap::Clamp,
        )
    };
    let Some(Local::Built(rows, cols)) = rebuild(&mut kern, &g0, &g, (&mut f_ref, &mut g_ref))
    else {
        panic!("the local rebuild was refused");
    };
    assert!(
        rows > 0 && cols > 0 && cols < ys.len() / 4,
        "{rows} rows, {cols} cols"
    );
    keeps_its_promise(&hs, &ht, &kern, &whole, &g, (theta, tau, eps));
    holds_the_invariant(&hs, &ht, &kern, (&f_ref, &g_ref), theta * eps);
    // The references moved where the rebuild searched: to the new row minima and potentials.
    let moved_rows = (0..xs.len()).filter(|&i| f_ref[i] != whole.f[i]).count();
    assert_eq!(moved_rows, rows);
    assert!((0..xs.len()).all(|i| f_ref[i] == whole.f[i] || f_ref[i] == kern.f[i]));
    assert_eq!((0..ys.len()).filter(|&j| g_ref[j] != g0[j]).count(), cols);
    // More moves: the patch goes on moving, and a second patch starts.
    let g2: Vec<f64> = g
        .iter()
        .zip(&ys.pos)
        .enumerate()
        .map(|(j, (&v, y))| {
            let patch = if (y[0] - 0.5).abs() < 0.15 && y[1] < 0.25 {
                3.0 * eps * ((j as f64 * 0.7).cos())
            } else if (y[1] - 0.7).abs() < 0.1 && y[0] < 0.3 {
                5.0 * eps
            } else {
                0.0
            };
            v + patch
        })
        .collect();
    let first = kern.clone();
    let Some(Local::Built(rows2, _)) = rebuild(&mut kern, &g, &g2, (&mut f_ref, &mut g_ref)) else {
        panic!("the second local rebuild was refused");
    };
    keeps_its_promise(&hs, &ht, &kern, &first, &g2, (theta, tau, eps));
    holds_the_invariant(&hs, &ht, &kern, (&f_ref, &g_ref), theta * eps);
    // Against the whole build's potentials more rows moved than the second rebuild searched.
    let since_whole = (0..xs.len())
        .filter(|&i| (kern.f[i] - whole.f[i]).abs() > tau * eps)
        .count();
    assert!(
        rows2 > 0 && rows2 < since_whole,
        "{rows2} rows searched, {since_whole} moved"
    );
}

/// The invariant of local rebuilds (see [`rebuild_local`]): every pair `kern` lacks has
/// C − f0_i − g0_j > θε at the references.
fn holds_the_invariant<const D: usize>(
    hs: &Hierarchy<D>,
    ht: &Hierarchy<D>,
    kern: &Kernel,
    (f0, g0): (&[f64], &[f64]),
    margin: f64,
) {
    let level = hs.point_level();
    let (xs, ys) = (&hs.levels[level], &ht.levels[level]);
    for (i, (x, fi)) in xs.pos.iter().zip(f0).enumerate() {
        let kept = &kern.col[kern.row_ptr[i]..kern.row_ptr[i + 1]];
        for (j, (y, gj)) in ys.pos.iter().zip(g0).enumerate() {
            let reduced = sq(x, y) - fi - gj;
            if reduced <= margin {
                assert!(kept.contains(&(j as u32)), "pair ({i},{j}) at {reduced:e}");
            }
        }
    }
}

/// What [`local_rebuild_keeps_every_pair_it_promises`] checks of a rebuilt `kern` (made from
/// `before`) for potential `g` against a dense scan.
#[allow(clippy::needless_range_loop)]
fn keeps_its_promise<const D: usize>(
    hs: &Hierarchy<D>,
    ht: &Hierarchy<D>,
    kern: &Kernel,
    before: &Kernel,
    g: &[f64],
    (theta, tau, eps): (f64, f64, f64),
) {
    let level = hs.point_level();
    let (xs, ys) = (&hs.levels[level], &ht.levels[level]);
    for i in 0..xs.len() {
        let f = (0..ys.len())
            .map(|j| sq(&xs.pos[i], &ys.pos[j]) - g[j])
            .fold(f64::INFINITY, f64::min);
        assert_eq!(kern.f[i], f, "row {i}: f is the exact row minimum");
        let kept = &kern.col[kern.row_ptr[i]..kern.row_ptr[i + 1]];
        assert!(kept.windows(2).all(|w| w[0] < w[1]), "row {i} is sorted");
        for j in &before.col[before.row_ptr[i]..before.row_ptr[i + 1]] {
            assert!(kept.contains(j), "pair ({i},{j}) of the old kernel is kept");
        }
        for j in 0..ys.len() {
            let reduced = sq(&xs.pos[i], &ys.pos[j]) - f - g[j];
            assert!(reduced >= -1e-12, "pair ({i},{j}) below its row minimum");
            if reduced <= (theta - 2.0 * tau) * eps {
                assert!(kept.contains(&(j as u32)), "pair ({i},{j}) at {reduced:e}");
            }
        }
    }
    // Entries hold the values of the new potentials (the old ones rescaled, to within rounding;
    // the new ones exactly), and the column form the same pairs.
    let mut rescaled = 0;
    for i in 0..xs.len() {
        let old = &before.col[before.row_ptr[i]..before.row_ptr[i + 1]];
        for p in kern.row_ptr[i]..kern.row_ptr[i + 1] {
            let j = kern.col[p] as usize;
            let c = sq(&xs.pos[i], &ys.pos[j]);
            let want = value((kern.f[i] + g[j] - c) / eps);
            if old.contains(&(j as u32)) && want > K_MIN as f32 {
                rescaled += 1;
                let err = (kern.k[p] / want - 1.0).abs();
                assert!(err < 1e-5, "pair ({i},{j}): {} against {want}", kern.k[p]);
            } else if !old.contains(&(j as u32)) {
                assert_eq!(kern.k[p], want, "new pair ({i},{j})");
            }
        }
    }
    assert!(rescaled > before.pairs() / 2, "{rescaled} rescaled entries");
    let (col_ptr, row) = kern.columns();
    assert_eq!(row.len(), kern.pairs());
    for j in 0..ys.len() {
        for &i in &row[col_ptr[j]..col_ptr[j + 1]] {
            let i = i as usize;
            assert!(kern.col[kern.row_ptr[i]..kern.row_ptr[i + 1]].contains(&(j as u32)));
        }
    }
}

/// Merging in place gives every list the sorted union of its entries and the new ones: lists that
/// gain nothing (alone and in a long run, which moves as one block), empty lists, new entries
/// already present, lists before and after the first that gains.
#[test]
fn lists_merge_in_place_into_their_unions() {
    let m = 400;
    let lists: Vec<Vec<u32>> = (0..m)
        .map(|i| {
            let mut l: Vec<u32> = (0..(i * 7919) % 11)
                .map(|t| ((i * 31 + t * 97) % 500) as u32)
                .collect();
            l.sort_unstable();
            l.dedup();
            l
        })
        .collect();
    let adds: Vec<Vec<u32>> = (0..m)
        .map(|i| {
            if i < 37 || i % 3 == 0 || (200..300).contains(&i) {
                return Vec::new();
            }
            // Half of them repeat an entry the list has.
            let mut l: Vec<u32> = (0..(i * 13) % 7)
                .map(|t| ((i * 17 + t * 53) % 500) as u32)
                .collect();
            l.extend(lists[i].iter().step_by(2));
            l.sort_unstable();
            l.dedup();
            l
        })
        .collect();
    let mut ptr = vec![0usize];
    let mut idx = Vec::new();
    for l in &lists {
        idx.extend(l);
        ptr.push(idx.len());
    }
    let want: Vec<Vec<u32>> = lists
        .iter()
        .zip(&adds)
        .map(|(a, b)| {
            let mut u: Vec<u32> = a.iter().chain(b).copied().collect();
            u.sort_unstable();
            u.dedup();
            u
        })
        .collect();
    let total = want.iter().map(Vec::len).sum::<usize>();
    // With values (an entry's value is a function of its list and entry): the old entries keep
    // theirs, the new ones get `NEW_VALUE`.
    let val = |i: usize, j: u32| (i * 1000) as f32 + j as f32;
    let vals0: Vec<f32> = (0..m)
        .flat_map(|i| lists[i].iter().map(move |&j| val(i, j)))
        .collect();
    // In one part and in several (each but the first reading its old entries below where its
    // lists start from a copy): the same unions.
    for parts in [1, 2, 3, 5, 8, 64] {
        let (mut ptr1, mut idx1) = (ptr.clone(), idx.clone());
        sparse::merge_lists_in_parts(
            &mut ptr1,
            &mut idx1,
            None,
            |i| adds[i].iter().copied(),
            parts,
        );
        assert_eq!(idx1.len(), total);
        for i in 0..m {
            assert_eq!(
                &idx1[ptr1[i]..ptr1[i + 1]],
                &want[i][..],
                "{parts} parts, list {i}"
            );
        }
        let (mut ptr2, mut idx2, mut vals) = (ptr.clone(), idx.clone(), vals0.clone());
        sparse::merge_lists_in_parts(
            &mut ptr2,
            &mut idx2,
            Some(&mut vals),
            |i| adds[i].iter().copied(),
            parts,
        );
        assert_eq!((&ptr2, &idx2, vals.len()), (&ptr1, &idx1, total));
        for i in 0..m {
            for p in ptr1[i]..ptr1[i + 1] {
                let j = idx1[p];
                if lists[i].contains(&j) {
                    assert_eq!(
                        vals[p],
                        val(i, j),
                        "{parts} parts: list {i} entry {j} keeps its value"
                    );
                } else {
                    assert!(vals[p].is_nan(), "{parts} parts: list {i} entry {j} is new");
                }
            }
        }
    }
    // The default entry point is one of them.
    let (mut ptr3, mut idx3) = (ptr.clone(), idx.clone());
    sparse::merge_lists_in_place(&mut ptr3, &mut idx3, None, |i| adds[i].iter().copied());
    for i in 0..m {
        assert_eq!(&idx3[ptr3[i]..ptr3[i + 1]], &want[i][..], "list {i}");
    }
}

/// The row minima ([`search::row_minima`]) and the column test's walk over both clouds
/// ([`pattern::column_test`]) keep exactly what dense scans keep, in 3D on the cube and on the
/// torus, at the point level and at a cell level, for a potential with a steep slope and curvature
/// and with noise: the minima and their minimizers, and for every column the rows within the
/// margin of its minimum, and the pair limit. The walk is given the exact row minima as their
/// bounds, and bounds above them by up to twice the margin and by up to 50 times it (a band of
/// nearly every pair); at the smaller margin many columns' minima are too far above g to be found
/// by the walk, and are searched alone.
#[allow(clippy::needless_range_loop)]
#[test]
fn row_minima_and_column_test_equal_dense_scans_in_3d() {
    let cloud = |seed: f64, n: usize| -> Vec<[f64; 3]> {
        (0..n)
            .map(|i| {
                let t = i as f64 + seed;
                [
                    (t * 0.754_877_666).fract(),
                    (t * 0.569_840_29).fract() * 0.7,
                    (t * 0.362_523_12).fract().powi(2),
                ]
            })
            .collect()
    };
    let noise = |i: usize| ((i as f64 * 12.9898).sin() * 43758.5453).fract();
    let (a, b) = (cloud(0.3, 1500), cloud(0.7, 1300));
    let grid = Grid::new(&a, &b);
    let (hs, ht) = (Hierarchy::new(&a, &grid, 4), Hierarchy::new(&b, &grid, 4));
    for wrap in [Wrap::Clamp, Wrap::Periodic] {
        for level in [3, hs.point_level()] {
            let (xs, ys) = (&hs.levels[level], &ht.levels[level]);
            let g: Vec<f64> = ys
                .pos
                .iter()
                .enumerate()
                .map(|(j, y)| 1.4 * y[0] * y[0] - 0.8 * y[1] * y[2] + 0.5 * y[2] + 2e-3 * noise(j))
                .collect();
            let (ptr, idx, f) = search::row_minima(xs, &ht, level, &g, wrap, usize::MAX).unwrap();
            let mut best: Vec<Vec<u32>> = Vec::new();
            for i in 0..xs.len() {
                let vals: Vec<f64> = (0..ys.len())
                    .map(|j| cost::sq(wrap, &xs.pos[i], &ys.pos[j]) - g[j])
                    .collect();
                let min = vals.iter().copied().fold(f64::INFINITY, f64::min);
                let want: Vec<u32> = (0..ys.len() as u32)
                    .filter(|&j| vals[j as usize] == min)
                    .collect();
                assert_eq!(f[i], min, "{wrap:?} level {level} row {i}");
                assert_eq!(
                    &idx[ptr[i]..ptr[i + 1]],
                    &want[..],
                    "{wrap:?} level {level} row {i}"
                );
                best.push(want);
            }
            for (loose, margin) in [(0.0, 1e-3), (0.0, 2e-2), (2e-3, 1e-3), (5e-2, 1e-3)] {
                let upper: Vec<f64> = f
                    .iter()
                    .enumerate()
                    .map(|(i, v)| v + loose * noise(i + 7).abs())
                    .collect();
                let run =
                    |max| pattern::column_test(&hs, &ht, level, &upper, &g, margin, wrap, max);
                let Ok(pat) = run(usize::MAX) else {
                    panic!("{wrap:?} level {level} margin {margin}: refused without a limit");
                };
                assert_eq!(pat.f, f, "{wrap:?} level {level} margin {margin}");
                let mut want: Vec<Vec<u32>> = best.clone();
                let mut alone = 0;
                for j in 0..ys.len() {
                    let vals: Vec<f64> = (0..xs.len())
                        .map(|i| cost::sq(wrap, &ys.pos[j], &xs.pos[i]) - f[i])
                        .collect();
                    let min = vals.iter().copied().fold(f64::INFINITY, f64::min);
                    alone += usize::from(min > g[j] + margin / 8.0);
                    for i in 0..xs.len() {
                        if vals[i] <= min + margin {
                            want[i].push(j as u32);
                        }
                    }
                }
                if margin == 1e-3 {
                    assert!(alone > 10, "{wrap:?} level {level}: {alone} columns alone");
                }
                for (i, w) in want.iter_mut().enumerate() {
                    w.sort_unstable();
                    w.dedup();
                    assert_eq!(
                        &pat.cols[pat.ptr[i]..pat.ptr[i + 1]],
                        &w[..],
                        "{wrap:?} level {level} margin {margin} row {i}"
                    );
                }
                // The pair limit holds exactly: refused one pair below the count, also where
                // most pairs come from columns searched alone.
                let total = pat.cols.len();
                assert!(run(total - 1).is_err(), "{wrap:?} level {level} {margin}");
                if loose == 0.0 {
                    assert!(run(total).is_ok(), "{wrap:?} level {level} {margin}");
                }
            }
        }
    }
}

/// The walk's cell-pair bound ([`pattern::pair_bound`]) is below C − f − g for every pair of the
/// two cells' points, on the cube and on the torus (cells near each other, far apart and across the
/// torus's seam), and equal to it, but for rounding, when each cell is one point.
#[test]
fn pair_bound_is_below_every_pair_and_exact_for_points() {
    use bounds::{Affine, Minorant};
    let noise = |i: usize| ((i as f64 * 12.9898).sin() * 43758.5453).fract();
    let cell = |seed: usize, at: [f64; 3], w: f64, n: usize| -> Vec<[f64; 3]> {
        (0..n)
            .map(|i| std::array::from_fn(|k| at[k] + w * noise(seed * 1000 + 3 * i + k)))
            .collect()
    };
    let pot = |p: &[f64; 3], i: usize| {
        0.7 * p[0] * p[0] - 0.4 * p[1] * p[2] + 0.3 * p[0] + 1e-3 * noise(i)
    };
    let sized = |ps: &[[f64; 3]]| {
        let lo: [f64; 3] =
            std::array::from_fn(|k| ps.iter().map(|p| p[k]).fold(f64::INFINITY, f64::min));
        let hi: [f64; 3] =
            std::array::from_fn(|k| ps.iter().map(|p| p[k]).fold(f64::NEG_INFINITY, f64::max));
        (lo, hi)
    };
    for wrap in [Wrap::Clamp, Wrap::Periodic] {
        for (t, (at_p, at_j, w, n)) in [
            ([0.3, 0.4, 0.5], [0.32, 0.41, 0.47], 0.05, 20),
            ([0.1, 0.2, 0.3], [0.6, 0.7, 0.2], 0.1, 30),
            ([0.02, 0.5, 0.97], [0.9, 0.55, 0.03], 0.06, 25),
            ([0.4, 0.4, 0.4], [0.45, 0.38, 0.41], 0.0, 1),
            ([0.01, 0.99, 0.5], [0.97, 0.02, 0.52], 0.0, 1),
        ]
        .into_iter()
        .enumerate()
        {
            let (ps, js) = (cell(2 * t, at_p, w, n), cell(2 * t + 1, at_j, w, n));
            let f: Vec<f64> = ps.iter().enumerate().map(|(i, p)| pot(p, i)).collect();
            let g: Vec<f64> = js.iter().enumerate().map(|(i, y)| -pot(y, i + 7)).collect();
            let norm = |p: &[f64; 3]| p.iter().map(|v| v * v).sum::<f64>();
            let hs: Vec<f64> = ps.iter().zip(&f).map(|(p, v)| norm(p) - v).collect();
            let ht: Vec<f64> = js.iter().zip(&g).map(|(y, v)| norm(y) - v).collect();
            let (mp, mj) = (Affine::fit(&ps, &hs), Affine::fit(&js, &ht));
            let (bp, bj) = (sized(&ps), sized(&js));
            let bound = pattern::pair_bound(
                &mp,
                (&bp.0, &bp.1),
                &mj,
                (&bj.0, &bj.1),
                pattern::shifts(wrap),
            );
            let mut min = f64::INFINITY;
            for (p, fp) in ps.iter().zip(&f) {
                for (y, gy) in js.iter().zip(&g) {
                    min = min.min(cost::sq(wrap, p, y) - fp - gy);
                }
            }
            assert!(bound <= min, "{wrap:?} case {t}: bound {bound} above {min}");
            if n == 1 {
                assert!(
                    (min - bound).abs() < 1e-9,
                    "{wrap:?} case {t}: {bound} vs {min}"
                );
            }
        }
    }
}

/// Both minorants bound C(x, y_j) − pot_j from below over a cell, for queries inside and far
/// outside it, and on a convex h (what |y|² less a c-concave potential is) the quadratic one is
/// much tighter: what its fit is for. The flat minorants of the cells no search bounds are below
/// too, and the fits here read a subsample (300 points, every second one).
#[test]
fn quadratic_minorant_bounds_below_and_tighter() {
    use bounds::{Affine, Minorant, Quad};
    let ys: Vec<[f64; 3]> = (0..300)
        .map(|i| {
            let t = i as f64 + 0.5;
            [
                0.3 + 0.2 * (t * 0.754_877_666).fract(),
                0.4 + 0.1 * (t * 0.569_840_29).fract(),
                0.2 + 0.3 * (t * 0.362_523_12).fract(),
            ]
        })
        .collect();
    let h: Vec<f64> = ys
        .iter()
        .enumerate()
        .map(|(j, y)| {
            1.7 * y[0] * y[0] + 2.4 * y[1] * y[1] + 0.9 * y[2] * y[2] + 0.4 * y[0] * y[1]
                - 0.3 * y[2]
                + 1e-4 * ((j as f64 * 12.9898).sin() * 43758.5453).fract()
        })
        .collect();
    let pot: Vec<f64> = ys
        .iter()
        .zip(&h)
        .map(|(y, hj)| y.iter().map(|v| v * v).sum::<f64>() - hj)
        .collect();
    let mut lo = ys[0];
    let mut hi = ys[0];
    for y in &ys {
        for k in 0..3 {
            lo[k] = lo[k].min(y[k]);
            hi[k] = hi[k].max(y[k]);
        }
    }
    let (aff, quad) = (Affine::fit(&ys, &h), Quad::fit(&ys, &h));
    // The minorants of cells no search bounds (`bounds::OPENED`): valid, and looser.
    let low = h.iter().copied().fold(f64::INFINITY, f64::min);
    let (flat_a, flat_q) = (Affine::flat(low), Quad::flat(low));
    // At the origin C − pot is h itself: a flat minorant is exact there.
    for b in [
        flat_a.bound(&[0.0; 3], 0.0, &lo, &hi),
        flat_q.bound(&[0.0; 3], 0.0, &lo, &hi),
    ] {
        assert!(b <= low && b > low - 1e-12, "{b} against {low}");
    }
    let (mut slack_a, mut slack_q) = (0.0, 0.0);
    for i in 0..4000 {
        let t = i as f64 + 0.25;
        let x = [
            -0.5 + 2.0 * (t * 0.618_033_99).fract(),
            -0.5 + 2.0 * (t * 0.414_213_56).fract(),
            -0.5 + 2.0 * (t * 0.732_050_81).fract(),
        ];
        let x2 = x.iter().map(|v| v * v).sum::<f64>();
        let truth = ys
            .iter()
            .zip(&pot)
            .map(|(y, p)| sq(&x, y) - p)
            .fold(f64::INFINITY, f64::min);
        let (a, q) = (aff.bound(&x, x2, &lo, &hi), quad.bound(&x, x2, &lo, &hi));
        assert!(
            a <= truth && q <= truth,
            "query {i}: {a} / {q} above {truth}"
        );
        let (fa, fq) = (
            flat_a.bound(&x, x2, &lo, &hi),
            flat_q.bound(&x, x2, &lo, &hi),
        );
        assert!(
            fa <= truth && fq <= truth,
            "query {i}: flat {fa} / {fq} above {truth}"
        );
        // The slack that matters is near the cell: far from it both bounds prune at once.
        if (0..3).all(|k| x[k] > lo[k] - 0.1 && x[k] < hi[k] + 0.1) {
            slack_a += truth - a;
            slack_q += truth - q;
        }
    }
    assert!(
        slack_q < 0.5 * slack_a,
        "quadratic slack {slack_q} against affine {slack_a}"
    );
}

/// Sorting lists by value gives `f32::total_cmp` order, ties by entry, for values of every sign,
/// both zeros and the infinities, and keeps each value with its entry.
#[test]
fn lists_sort_by_value_in_total_order() {
    let specials = [
        0.0f32,
        -0.0,
        1.5,
        -1.5,
        f32::INFINITY,
        f32::NEG_INFINITY,
        1e-40,
        -1e-40,
    ];
    let mut ptr = vec![0usize];
    let (mut idx, mut vals) = (Vec::new(), Vec::new());
    for row in 0..40usize {
        for e in 0..(row * 7) % 23 {
            let h = ((row * 31 + e * 17) as f64 * 0.618_033_988_75).fract();
            let v = if e % 5 == 0 {
                specials[(row + e) % specials.len()]
            } else {
                ((h - 0.4) * 1e3) as f32
            };
            vals.push(v);
            idx.push(((row * 13 + e * 7) % 11) as u32);
        }
        ptr.push(idx.len());
    }
    let (mut idx2, mut vals2) = (idx.clone(), vals.clone());
    sort_lists_by_value(&ptr, &mut idx2, &mut vals2);
    for i in 0..ptr.len() - 1 {
        let r = ptr[i]..ptr[i + 1];
        let mut want: Vec<(f32, u32)> = vals[r.clone()]
            .iter()
            .copied()
            .zip(idx[r.clone()].iter().copied())
            .collect();
        want.sort_by(|p, q| p.0.total_cmp(&q.0).then(p.1.cmp(&q.1)));
        let got: Vec<(f32, u32)> = vals2[r.clone()]
            .iter()
            .copied()
            .zip(idx2[r].iter().copied())
            .collect();
        assert_eq!(want.len(), got.len());
        for (w, g) in want.iter().zip(&got) {
            assert_eq!((w.0.to_bits(), w.1), (g.0.to_bits(), g.1), "row {i}");
        }
    }
}
