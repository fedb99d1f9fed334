//! The metrics against closed forms, and their determinism for any thread count.

use super::gaussian::{jacobi_eigen, matmul};
use super::*;

fn pool(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
}

/// A deterministic cloud with irregular coordinates (no two sums group alike by accident).
fn cloud(n: usize, dim: usize, salt: f64) -> Vec<f32> {
    (0..n * dim)
        .map(|i| (((i as f64 + salt) * 0.618_034).fract() * 0.8 + 0.1) as f32)
        .collect()
}

#[test]
fn cost_ratio_divides_and_rejects_zero_exact_cost() {
    assert_eq!(cost_ratio(1.5, 1.0), Ok(1.5));
    assert_eq!(cost_ratio(0.25, 0.5), Ok(0.5));
    assert!(matches!(
        cost_ratio(1.0, 0.0),
        Err(MetricError::BadExactCost { .. })
    ));
    assert!(matches!(
        cost_ratio(f64::NAN, 1.0),
        Err(MetricError::NonFiniteValue { .. })
    ));
}

#[test]
fn total_variance_sums_axes() {
    // x ∈ {0, 2}: variance 1; y ∈ {0, 4}: variance 4.
    let t = [0.0, 0.0, 2.0, 0.0, 0.0, 4.0, 2.0, 4.0];
    assert_eq!(total_variance(2, &t), Ok(5.0));
}

#[test]
fn l2_uvp_of_a_known_shift() {
    // Target variance: 1 per axis, total 2. Shifting the reference by (0.1, 0.2) gives
    // |δ|² = 0.05, so UVP = 100 · 0.05 / 2 = 2.5 exactly (up to f32 rounding of the points).
    let target = [0.0f32, 0.0, 2.0, 0.0, 0.0, 2.0, 2.0, 2.0];
    let reference = [0.5f32, 0.5, 1.5, 0.5, 0.5, 1.5, 1.5, 1.5];
    let mapped: Vec<f32> = reference
        .chunks(2)
        .flat_map(|p| [p[0] + 0.1, p[1] + 0.2])
        .collect();
    let uvp = l2_uvp(2, &mapped, &reference, &target).unwrap();
    assert!((uvp - 2.5).abs() < 1e-5, "uvp {uvp}");
    assert_eq!(l2_uvp(2, &reference, &reference, &target), Ok(0.0));
    // The constant map to the target mean has UVP 100 against the identity on the target.
    let mean = [1.0f32; 8];
    let full = l2_uvp(2, &mean, &target, &target).unwrap();
    assert!((full - 100.0).abs() < 1e-9, "uvp {full}");
}

#[test]
fn l2_uvp_rejects_bad_shapes() {
    let t = [0.0f32, 1.0, 2.0, 3.0];
    assert!(matches!(
        l2_uvp(2, &t, &t[..2], &t),
        Err(MetricError::Length { .. })
    ));
    assert!(matches!(
        l2_uvp(2, &t, &t, &[1.0, 1.0, 1.0, 1.0]),
        Err(MetricError::ZeroVariance)
    ));
    assert!(matches!(
        l2_uvp(3, &t, &t, &t),
        Err(MetricError::BadLength { .. })
    ));
    assert_eq!(l2_uvp(0, &t, &t, &t), Err(MetricError::ZeroDim));
}

#[test]
fn metrics_are_thread_count_independent() {
    let n = 3 * 4096 + 77;
    let (a, b, c) = (cloud(n, 3, 0.0), cloud(n, 3, 0.37), cloud(n, 3, 1.91));
    let dirs = fixed_directions(3, 8);
    let run = || {
        (
            l2_uvp(3, &a, &b, &c).unwrap().to_bits(),
            total_variance(3, &c).unwrap().to_bits(),
            sliced_w2(3, &a, &b, &dirs).unwrap().to_bits(),
        )
    };
    assert_eq!(pool(1).install(run), pool(3).install(run));
}

/// Checks A Σs A = Σt and the symmetry of A: together they characterize the OT map's linear part.
fn check_map(dim: usize, cs: &[f64], ct: &[f64]) -> GaussianMap {
    let m = GaussianMap::new(&vec![0.0; dim], cs, &vec![0.0; dim], ct).unwrap();
    let a = m.matrix();
    let asa = matmul(dim, &matmul(dim, a, cs), a);
    for (x, y) in asa.iter().zip(ct) {
        assert!((x - y).abs() < 1e-10, "A Σs A = {asa:?} != Σt = {ct:?}");
    }
    for r in 0..dim {
        for c in 0..dim {
            assert!((a[r * dim + c] - a[c * dim + r]).abs() < 1e-12);
        }
    }
    let (w, _) = jacobi_eigen(dim, a);
    assert!(w.iter().all(|&x| x > 0.0), "A not positive definite: {w:?}");
    m
}

#[test]
fn gaussian_map_matches_the_closed_form() {
    // Σs = I: A = Σt^{1/2}. For Σt = [[5, 4], [4, 5]] (eigenvalues 9 and 1 on (1,1) and (1,-1)),
    // Σt^{1/2} = [[2, 1], [1, 2]].
    let m = check_map(2, &[1.0, 0.0, 0.0, 1.0], &[5.0, 4.0, 4.0, 5.0]);
    let want = [2.0, 1.0, 1.0, 2.0];
    for (x, y) in m.matrix().iter().zip(want) {
        assert!((x - y).abs() < 1e-12, "{:?}", m.matrix());
    }
    // General covariances in 2D and 3D.
    check_map(2, &[2.0, 0.3, 0.3, 0.5], &[0.4, -0.1, -0.1, 1.3]);
    check_map(
        3,
        &[1.0, 0.2, 0.1, 0.2, 0.7, -0.3, 0.1, -0.3, 1.5],
        &[0.3, 0.05, 0.0, 0.05, 2.0, 0.4, 0.0, 0.4, 0.9],
    );
    // Diagonal covariances: the general form reduces to the axis-aligned one.
    let general = GaussianMap::new(
        &[0.5, 0.5],
        &[0.04, 0.0, 0.0, 0.09],
        &[0.3, 0.6],
        &[0.01, 0.0, 0.0, 0.16],
    )
    .unwrap();
    let aligned =
        GaussianMap::axis_aligned(&[0.5, 0.5], &[0.2, 0.3], &[0.3, 0.6], &[0.1, 0.4]).unwrap();
    for (x, y) in general.matrix().iter().zip(aligned.matrix()) {
        assert!((x - y).abs() < 1e-12);
    }
    // Means: T(m_s) = m_t, and a unit step along x scales by σ_t/σ_s = 0.5.
    let mut out = [0.0; 2];
    aligned.map_point(&[0.5, 0.5], &mut out);
    assert_eq!(out, [0.3, 0.6]);
    aligned.map_point(&[1.5, 0.5], &mut out);
    assert!((out[0] - 0.8).abs() < 1e-15 && (out[1] - 0.6).abs() < 1e-15);
    let pts = aligned.apply(&[1.5, 0.5, 0.5, 1.5]).unwrap();
    let want = [0.8, 0.6, 0.3, 0.6 + 4.0 / 3.0];
    for (x, y) in pts.iter().zip(want) {
        assert!((f64::from(*x) - y).abs() < 1e-6, "{pts:?}");
    }
}

#[test]
fn gaussian_map_rejects_bad_covariances() {
    assert!(matches!(
        GaussianMap::new(
            &[0.0, 0.0],
            &[1.0, 2.0, 2.0, 1.0],
            &[0.0, 0.0],
            &[1.0, 0.0, 0.0, 1.0]
        ),
        Err(MetricError::NotPositiveDefinite {
            which: "source",
            ..
        })
    ));
    assert!(matches!(
        GaussianMap::axis_aligned(&[0.0], &[0.0], &[0.0], &[1.0]),
        Err(MetricError::BadStd { .. })
    ));
    assert!(matches!(
        GaussianMap::new(&[0.0], &[1.0, 0.0], &[0.0], &[1.0]),
        Err(MetricError::Length { .. })
    ));
}

#[test]
fn sliced_w2_of_a_shift_and_a_permutation() {
    // Shifting every point by δ shifts each projection by ⟨δ, θ⟩; averaged over directions
    // evenly spaced on a half circle, ⟨δ, θ⟩² averages to |δ|²/2.
    let a = cloud(1000, 2, 0.0);
    let shifted: Vec<f32> = a
        .chunks(2)
        .flat_map(|p| [p[0] + 0.03, p[1] - 0.04])
        .collect();
    let dirs = fixed_directions(2, 16);
    let d = sliced_w2(2, &shifted, &a, &dirs).unwrap();
    let want = (0.05f64 * 0.05 / 2.0).sqrt();
    assert!((d - want).abs() < 1e-6, "{d} vs {want}");
    // A permutation of the same points is at distance 0.
    let perm: Vec<f32> = a.chunks(2).rev().flatten().copied().collect();
    assert_eq!(sliced_w2(2, &perm, &a, &dirs), Ok(0.0));
    assert!(matches!(
        sliced_w2(2, &a, &a[..10], &dirs),
        Err(MetricError::Length { .. })
    ));
    assert_eq!(sliced_w2(2, &a, &a, &[]), Err(MetricError::NoDirections));
}

#[test]
fn fixed_directions_are_unit_and_fixed() {
    for dim in 1..=4 {
        let d = fixed_directions(dim, 10);
        assert_eq!(d.len(), 10 * dim);
        for v in d.chunks(dim) {
            let norm: f64 = v.iter().map(|x| x * x).sum();
            assert!((norm - 1.0).abs() < 1e-12);
        }
        assert_eq!(d, fixed_directions(dim, 10));
    }
}
