//! Weighted CP-ALS against truth: planted tensors with corrupted entries weighted out, plain
//! CP-ALS at unit weights, the objective's descent, and the errors bad input gets.

use zeroset_tensor::{
    CpInit, CpOptions, CpStop, Kruskal, Tensor3, TensorError, WeightedOptions, cp_als,
    cp_als_weighted, planted,
};

/// `Σ W (X − X̂)²`.
fn weighted_sse(x: &Tensor3, w: &[f64], k: &Kruskal) -> f64 {
    let fit = k.to_tensor();
    x.as_slice()
        .iter()
        .zip(fit.as_slice())
        .zip(w)
        .map(|((a, b), w)| w * (a - b) * (a - b))
        .sum()
}

fn max_abs_diff(a: &Tensor3, b: &Tensor3) -> f64 {
    a.as_slice()
        .iter()
        .zip(b.as_slice())
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

/// Deterministic pseudo-random numbers in `[0, 1)` for the tests' masks and weights.
fn uniform(seed: u64, n: usize) -> Vec<f64> {
    let mut rng = zeroset_field_core::rng::SplitMix64::new(seed);
    (0..n).map(|_| rng.unit()).collect()
}

#[test]
fn entries_weighted_zero_do_not_disturb_a_planted_tensor() {
    for (shape, rank, seed) in [([8, 9, 10], 3, 1), ([6, 6, 6], 2, 2), ([12, 7, 9], 4, 3)] {
        let (_, clean) = planted(shape, rank, 0.0, seed).unwrap();
        let mut x = clean.clone();
        let mut w = vec![1.0; x.len()];
        // A fifth of the entries corrupted by values ten times the tensor's scale.
        let scale = clean.frobenius_norm() / (clean.len() as f64).sqrt();
        for (i, u) in uniform(seed + 10, x.len()).into_iter().enumerate() {
            if u < 0.2 {
                x.as_mut_slice()[i] += 10.0 * scale * (1.0 + u);
                w[i] = 0.0;
            }
        }
        // Plain CP-ALS sees the corruption …
        let plain = cp_als(&x, &CpOptions::new(rank).with_max_iter(200), |_| true).unwrap();
        let plain_err = max_abs_diff(&plain.kruskal.to_tensor(), &clean) / scale;
        // … the weighted fit from its result ignores it, and fills the holes with the truth.
        let options = WeightedOptions {
            max_iter: 500,
            tol: 0.0,
        };
        let fit = cp_als_weighted(&x, &w, &plain.kruskal, &options, |_, _| true).unwrap();
        let err = max_abs_diff(&fit.kruskal.to_tensor(), &clean) / scale;
        assert!(plain_err > 1.0, "{shape:?}: plain {plain_err}");
        assert!(err < 1e-6, "{shape:?}: weighted {err} (plain {plain_err})");
        assert!(fit.rel_error < 1e-8, "{}", fit.rel_error);
    }
}

#[test]
fn with_unit_weights_it_is_plain_cp_als() {
    let (_, x) = planted([7, 8, 9], 3, 0.05, 4).unwrap();
    let (start, _) = planted([7, 8, 9], 3, 0.0, 5).unwrap();
    for sweeps in [1, 5, 20] {
        let plain = cp_als(
            &x,
            &CpOptions::new(3)
                .with_init(CpInit::Given(start.clone()))
                .with_tol(0.0)
                .with_max_iter(sweeps),
            |_| true,
        )
        .unwrap();
        let options = WeightedOptions {
            max_iter: sweeps,
            tol: 0.0,
        };
        let w = vec![1.0; x.len()];
        let fit = cp_als_weighted(&x, &w, &start, &options, |_, _| true).unwrap();
        assert_eq!(fit.iterations, sweeps);
        let (a, b) = (fit.kruskal.to_tensor(), plain.kruskal.to_tensor());
        let diff = max_abs_diff(&a, &b) / x.frobenius_norm();
        assert!(diff < 1e-9, "{sweeps} sweeps: {diff}");
        assert!((fit.rel_error - plain.rel_error).abs() < 1e-9);
    }
}

#[test]
fn the_weighted_error_never_rises_and_beats_plain_cp_where_the_weight_is() {
    // Rank 2 fitted to a noisy rank-4 tensor: no fit is exact, so the weights decide where
    // the error goes.
    let (_, x) = planted([9, 8, 10], 4, 0.1, 6).unwrap();
    let w: Vec<f64> = uniform(7, x.len())
        .into_iter()
        .enumerate()
        .map(|(i, u)| if i % 80 < 16 { 50.0 + u } else { 0.01 * u })
        .collect();
    let plain = cp_als(&x, &CpOptions::new(2).with_max_iter(300), |_| true).unwrap();
    let mut sse = vec![weighted_sse(&x, &w, &plain.kruskal)];
    let options = WeightedOptions {
        max_iter: 100,
        tol: 0.0,
    };
    let fit = cp_als_weighted(&x, &w, &plain.kruskal, &options, |_, k| {
        sse.push(weighted_sse(&x, &w, k));
        true
    })
    .unwrap();
    for pair in sse.windows(2) {
        assert!(pair[1] <= pair[0] * (1.0 + 1e-12), "rose: {pair:?}");
    }
    let (first, last) = (sse[0], *sse.last().unwrap());
    assert!(last < 0.9 * first, "plain {first}, weighted {last}");
    let norm2: f64 = x.as_slice().iter().zip(&w).map(|(v, w)| w * v * v).sum();
    assert!(((last / norm2).sqrt() - fit.rel_error).abs() < 1e-12);
}

#[test]
fn the_callback_stops_the_sweeps() {
    let (_, x) = planted([5, 6, 7], 2, 0.1, 8).unwrap();
    let (start, _) = planted([5, 6, 7], 2, 0.0, 9).unwrap();
    let w = vec![1.0; x.len()];
    let options = WeightedOptions::default();
    let fit = cp_als_weighted(&x, &w, &start, &options, |sweep, _| sweep < 3).unwrap();
    assert_eq!((fit.iterations, fit.stop), (3, CpStop::Cancelled));
    let fit = cp_als_weighted(&x, &w, &start, &options, |_, _| true).unwrap();
    assert_eq!(fit.stop, CpStop::Converged);
}

#[test]
fn bad_input_gives_specific_errors() {
    let (start, x) = planted([4, 5, 6], 2, 0.0, 10).unwrap();
    let ok = vec![1.0; x.len()];
    let options = WeightedOptions::default();
    let run = |x: &Tensor3, w: &[f64], start: &Kruskal, o: &WeightedOptions| {
        cp_als_weighted(x, w, start, o, |_, _| true).map(|_| ())
    };
    assert_eq!(
        run(&x, &ok[1..], &start, &options),
        Err(TensorError::Length {
            shape: [4, 5, 6],
            len: 119
        })
    );
    for (index, bad) in [(3, f64::NAN), (7, -1.0), (9, f64::INFINITY)] {
        let mut w = ok.clone();
        w[index] = bad;
        assert!(matches!(
            run(&x, &w, &start, &options),
            Err(TensorError::Weight { index: i, value }) if i == index && value.to_bits() == bad.to_bits()
        ));
    }
    let mut y = x.clone();
    y.as_mut_slice()[5] = f64::NAN;
    assert_eq!(
        run(&y, &ok, &start, &options),
        Err(TensorError::NonFinite { index: 5 })
    );
    let (other, _) = planted([4, 5, 7], 2, 0.0, 11).unwrap();
    assert!(matches!(
        run(&x, &ok, &other, &options),
        Err(TensorError::Dimensions {
            expected: (6, 2),
            got: (7, 2),
            ..
        })
    ));
    let empty = Tensor3::zeros([0, 5, 6]);
    assert_eq!(
        run(&empty, &[], &start, &options),
        Err(TensorError::EmptyShape { shape: [0, 5, 6] })
    );
    let negative = WeightedOptions {
        tol: -1.0,
        ..options
    };
    assert_eq!(
        run(&x, &ok, &start, &negative),
        Err(TensorError::Tolerance { tol: -1.0 })
    );
}
