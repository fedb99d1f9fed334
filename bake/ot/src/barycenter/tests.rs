//! Barycenters against what is known independently: the lower bound `t(1−t)W2²` reached by the
//! McCann interpolant, the closed-form barycenter of axis-aligned Gaussians, brute force over the
//! simplex, and determinism.

use super::*;
use crate::rng::SplitMix64;
use crate::{ExactSettings, SinkhornSettings};

fn exact() -> SolverSettings {
    SolverSettings::Exact(ExactSettings::default())
}

/// n points of N(mean, diag σ²) by Box–Muller from a fixed stream.
fn gaussian(n: usize, mean: [f64; 2], sigma: [f64; 2], seed: u64) -> Vec<f32> {
    let mut r = SplitMix64::new(seed);
    let mut out = Vec::with_capacity(2 * n);
    for _ in 0..n {
        let (u, v) = (r.next_f64().max(1e-12), r.next_f64());
        let rad = (-2.0 * u.ln()).sqrt();
        let (s, c) = (std::f64::consts::TAU * v).sin_cos();
        out.push((mean[0] + sigma[0] * rad * c) as f32);
        out.push((mean[1] + sigma[1] * rad * s) as f32);
    }
    out
}

fn moments(p: &[f32]) -> ([f64; 2], [f64; 2]) {
    let n = (p.len() / 2) as f64;
    let m: [f64; 2] = std::array::from_fn(|k| {
        p.iter()
            .skip(k)
            .step_by(2)
            .map(|&v| f64::from(v))
            .sum::<f64>()
            / n
    });
    let s: [f64; 2] = std::array::from_fn(|k| {
        (p.iter()
            .skip(k)
            .step_by(2)
            .map(|&v| (f64::from(v) - m[k]).powi(2))
            .sum::<f64>()
            / n)
            .sqrt()
    });
    (m, s)
}

#[test]
fn two_inputs_reach_the_mccann_lower_bound() {
    let a = gaussian(300, [0.3, 0.4], [0.05, 0.08], 1);
    let b = gaussian(300, [0.6, 0.55], [0.09, 0.04], 2);
    let (d2, mapped) = w2_sq(Wrap::Clamp, 2, &a, &b, &exact()).unwrap();
    for t in [0.0, 0.25, 0.5, 0.9] {
        let m = mccann(Wrap::Clamp, &a, &mapped, t);
        let w = [1.0 - t, t];
        let obj = objective(Wrap::Clamp, 2, &m, &[&a, &b], &w, &exact()).unwrap();
        let bound = t * (1.0 - t) * d2;
        assert!(
            (obj.value - bound).abs() <= 1e-6 * d2,
            "t {t}: {} vs {bound}",
            obj.value
        );
        // The fixed point from input a makes the interpolant in one step and stops on it.
        let fp = free_support(
            Wrap::Clamp,
            2,
            &[&a, &b],
            &w,
            &a,
            &exact(),
            &FixedPointSettings::default(),
        )
        .unwrap();
        assert!(fp.converged);
        // Among several starts the best is kept: a far start does not spoil the input's.
        let far = gaussian(300, [0.8, 0.2], [0.02, 0.02], 7);
        let best = free_support_from(
            Wrap::Clamp,
            2,
            &[&a, &b],
            &w,
            &[&far, &a],
            &exact(),
            &FixedPointSettings::default(),
        )
        .unwrap();
        assert!(
            best.objective <= fp.objective * (1.0 + 1e-12),
            "{} vs {}",
            best.objective,
            fp.objective
        );
        assert!(
            (fp.objective - bound).abs() <= 1e-6 * d2,
            "t {t}: {} vs {bound}",
            fp.objective
        );
    }
}

#[test]
fn fixed_point_matches_the_closed_form_gaussian_barycenter() {
    // Axis-aligned Gaussians: barycenter N(Σ w m, diag (Σ w σ)²), W2² to input k = |m − m_k|² +
    // |σ − σ_k|² (per axis).
    let means = [[0.35, 0.40], [0.62, 0.58], [0.45, 0.65]];
    let sigmas = [[0.06, 0.09], [0.09, 0.05], [0.05, 0.05]];
    let n = 600;
    let inputs: Vec<Vec<f32>> = (0..3)
        .map(|k| gaussian(n, means[k], sigmas[k], 10 + k as u64))
        .collect();
    let refs: Vec<&[f32]> = inputs.iter().map(Vec::as_slice).collect();
    let w = [0.2, 0.5, 0.3];
    let init = gaussian(n, [0.5, 0.5], [0.1, 0.1], 99);
    let fp = free_support(
        Wrap::Clamp,
        2,
        &refs,
        &w,
        &init,
        &exact(),
        &FixedPointSettings::default(),
    )
    .unwrap();
    assert!(fp.converged, "{:?}", fp.history);
    // Exact matchings never raise the objective.
    for pair in fp.history.windows(2) {
        assert!(pair[1] <= pair[0] * (1.0 + 1e-12), "{:?}", fp.history);
    }
    let (m, s) = moments(&fp.points);
    let mut closed = 0.0;
    for axis in 0..2 {
        let want_m: f64 = (0..3).map(|k| w[k] * means[k][axis]).sum();
        let want_s: f64 = (0..3).map(|k| w[k] * sigmas[k][axis]).sum();
        assert!(
            (m[axis] - want_m).abs() < 6e-3,
            "axis {axis}: mean {} vs {want_m}",
            m[axis]
        );
        assert!(
            (s[axis] / want_s - 1.0).abs() < 0.06,
            "axis {axis}: std {} vs {want_s}",
            s[axis]
        );
        for k in 0..3 {
            closed +=
                w[k] * ((want_m - means[k][axis]).powi(2) + (want_s - sigmas[k][axis]).powi(2));
        }
    }
    // The sampled objective sits above the continuous one by the inputs' own sampling error
    // (W2² between two samples of one law at n = 600 is ~1e-4 here), never below it by much.
    assert!(
        fp.objective > 0.9 * closed && fp.objective < closed + 3e-3,
        "{} vs {closed}",
        fp.objective
    );
    // Sinkhorn's matchings land on the same objective within a fraction of a percent.
    let sk = SolverSettings::Sinkhorn(SinkhornSettings::default());
    let fs = free_support(
        Wrap::Clamp,
        2,
        &refs,
        &w,
        &init,
        &sk,
        &FixedPointSettings::default(),
    )
    .unwrap();
    let at = objective(Wrap::Clamp, 2, &fs.points, &refs, &w, &exact())
        .unwrap()
        .value;
    assert!(
        at <= fp.objective * 1.01,
        "sinkhorn fixed point {at} vs exact {}",
        fp.objective
    );
}

#[test]
fn fixed_point_is_deterministic_for_any_thread_count() {
    let inputs: Vec<Vec<f32>> = (0..3)
        .map(|k| gaussian(400, [0.3 + 0.2 * k as f64, 0.5], [0.05, 0.07], k as u64))
        .collect();
    let refs: Vec<&[f32]> = inputs.iter().map(Vec::as_slice).collect();
    let w = [1.0 / 3.0; 3];
    let sk = SolverSettings::Sinkhorn(SinkhornSettings::default());
    let run = || {
        free_support(
            Wrap::Clamp,
            2,
            &refs,
            &w,
            refs[0],
            &sk,
            &FixedPointSettings::default(),
        )
        .unwrap()
    };
    let a = run();
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap()
        .install(run);
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&a.points), bits(&one.points));
    assert_eq!(a.objective.to_bits(), one.objective.to_bits());
}

#[test]
fn torus_barycenters_cross_the_seam() {
    // Two clouds just inside either side of the seam x = 0: their midpoint is at the seam, not at
    // the square's middle.
    let mut r = SplitMix64::new(5);
    let mut a = Vec::new();
    let mut b = Vec::new();
    for _ in 0..200 {
        a.extend([(0.04 + 0.02 * r.next_f64()) as f32, r.next_f64() as f32]);
        b.extend([(0.94 + 0.02 * r.next_f64()) as f32, r.next_f64() as f32]);
    }
    let fp = free_support(
        Wrap::Periodic,
        2,
        &[&a, &b],
        &[0.5, 0.5],
        &a,
        &exact(),
        &FixedPointSettings::default(),
    )
    .unwrap();
    for p in fp.points.chunks(2) {
        assert!((0.0..1.0).contains(&p[0]));
        let d = p[0].min(1.0 - p[0]);
        assert!(d < 0.02, "point {p:?} not at the seam");
    }
    let (d2, _) = w2_sq(Wrap::Periodic, 2, &a, &b, &exact()).unwrap();
    assert!(
        (fp.objective - 0.25 * d2).abs() < 1e-6,
        "{} vs {}",
        fp.objective,
        0.25 * d2
    );
}

#[test]
fn simplex_least_squares_beats_every_point_of_a_fine_grid() {
    let mut r = SplitMix64::new(3);
    for trial in 0..20 {
        // G = AᵀA for a random 3×6 field matrix (rank 3), b and c from a random target.
        let f: Vec<f64> = (0..18).map(|_| r.next_f64() - 0.5).collect();
        let t: Vec<f64> = (0..6).map(|_| r.next_f64() - 0.5).collect();
        let gram: Vec<f64> = (0..9)
            .map(|ij| (0..6).map(|q| f[ij / 3 * 6 + q] * f[ij % 3 * 6 + q]).sum())
            .collect();
        let b: Vec<f64> = (0..3)
            .map(|i| (0..6).map(|q| f[i * 6 + q] * t[q]).sum())
            .collect();
        let c: f64 = t.iter().map(|x| x * x).sum();
        let (w, v) = simplex_least_squares(&gram, &b, c);
        assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12 && w.iter().all(|&x| x >= 0.0));
        let steps = 200;
        for i in 0..=steps {
            for j in 0..=steps - i {
                let g = [
                    i as f64 / steps as f64,
                    j as f64 / steps as f64,
                    (steps - i - j) as f64 / steps as f64,
                ];
                let gv = c - 2.0 * (0..3).map(|p| b[p] * g[p]).sum::<f64>()
                    + (0..9)
                        .map(|ij| g[ij / 3] * gram[ij] * g[ij % 3])
                        .sum::<f64>();
                assert!(v <= gv + 1e-12, "trial {trial}: {v} > {gv} at {g:?}");
            }
        }
        // Projected gradient finds the same minimum.
        let pg = simplex::tests_projected_gradient(&gram, &b);
        let pv = c - 2.0 * (0..3).map(|p| b[p] * pg[p]).sum::<f64>()
            + (0..9)
                .map(|ij| pg[ij / 3] * gram[ij] * pg[ij % 3])
                .sum::<f64>();
        assert!(
            (pv - v).abs() < 1e-9,
            "trial {trial}: gradient {pv} vs exact {v}"
        );
    }
}

#[test]
fn coordinates_recover_blend_weights_and_flag_targets_outside_the_span() {
    let proxy = gaussian(500, [0.5, 0.5], [0.15, 0.15], 1);
    let maps: Vec<Vec<f32>> = (0..4)
        .map(|k| {
            proxy
                .iter()
                .enumerate()
                .map(|(i, &p)| {
                    // Independent fields: a scale, and a bump of its own frequency per map.
                    let bump = 0.03 * ((k as f32 + 2.0) * 7.0 * p + (i % 3) as f32).sin();
                    p * (0.6 + 0.1 * k as f32) + bump + 0.2
                })
                .collect()
        })
        .collect();
    let refs: Vec<&[f32]> = maps.iter().map(Vec::as_slice).collect();
    for w in [
        [0.1, 0.2, 0.3, 0.4],
        [0.0, 1.0, 0.0, 0.0],
        [0.5, 0.0, 0.0, 0.5],
    ] {
        let target = blend(Wrap::Clamp, &proxy, &refs, &w);
        let c = coordinates(Wrap::Clamp, 2, &proxy, &refs, &target).unwrap();
        for k in 0..4 {
            assert!((c.weights[k] - w[k]).abs() < 1e-4, "{w:?}: {:?}", c.weights);
        }
        assert!(c.relative_residual() < 1e-5, "{}", c.relative_residual());
    }
    // A rotation is no blend of these fields.
    let rotated: Vec<f32> = proxy.chunks(2).flat_map(|p| [1.0 - p[1], p[0]]).collect();
    let c = coordinates(Wrap::Clamp, 2, &proxy, &refs, &rotated).unwrap();
    assert!(c.relative_residual() > 0.5, "{}", c.relative_residual());
}

#[test]
fn bad_arguments_are_errors() {
    let a = [0.1f32, 0.2, 0.3, 0.4];
    let b = [0.5f32, 0.6, 0.7, 0.8];
    let fp = FixedPointSettings::default();
    let e = free_support(Wrap::Clamp, 2, &[&a, &b], &[0.5], &a, &exact(), &fp).unwrap_err();
    assert!(e.to_string().contains("one weight per input"), "{e}");
    let e = free_support(Wrap::Clamp, 2, &[&a, &b], &[0.5, 0.6], &a, &exact(), &fp).unwrap_err();
    assert!(e.to_string().contains("sum to"), "{e}");
    let e = free_support(
        Wrap::Clamp,
        2,
        &[&a, &b[..2]],
        &[0.5, 0.5],
        &a,
        &exact(),
        &fp,
    )
    .unwrap_err();
    assert!(matches!(e, BarycenterError::Shape { .. }), "{e}");
    let e = free_support(Wrap::Clamp, 2, &[], &[], &a, &exact(), &fp).unwrap_err();
    assert_eq!(e, BarycenterError::NoInputs);
    let e = coordinates(Wrap::Clamp, 2, &a, &[&b], &a[..2]).unwrap_err();
    assert!(e.to_string().contains("target"), "{e}");
}
