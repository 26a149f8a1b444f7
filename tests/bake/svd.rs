//! Truncated SVD against nalgebra's full SVD (f64) on small matrices, and its hard cases.

use mesobake_bake::compress::svd::{DenseRows, RankChoice, Truncated, truncated_svd};
use mesobake_core::limits::Limits;
use nalgebra::DMatrix;

/// Deterministic uniform numbers in [-1, 1).
fn noise(seed: u64) -> impl FnMut() -> f64 {
    let mut s = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }
}

/// An m × n row-major matrix with singular values decaying like `decay`^i, plus `eps` noise.
fn test_matrix(m: usize, n: usize, decay: f64, eps: f64, seed: u64) -> Vec<f32> {
    let mut r = noise(seed);
    let rank = n.min(m);
    let u = DMatrix::from_fn(m, rank, |_, _| r()).qr().q();
    let v = DMatrix::from_fn(n, rank, |_, _| r()).qr().q();
    let s = DMatrix::from_diagonal(&nalgebra::DVector::from_fn(rank, |i, _| {
        100.0 * decay.powi(i as i32)
    }));
    let a = &u * s * v.transpose();
    (0..m * n)
        .map(|i| (a[(i / n, i % n)] + eps * r()) as f32)
        .collect()
}

fn svd(data: &[f32], n: usize, choice: RankChoice) -> Truncated {
    truncated_svd(
        &DenseRows::new(data, n).unwrap(),
        choice,
        &Limits::default(),
    )
    .unwrap()
}

/// Frobenius norm of A − W·Eᵀ, in f64.
fn residual(data: &[f32], n: usize, t: &Truncated) -> f64 {
    let mut sum = 0.0;
    for (i, &a) in data.iter().enumerate() {
        let d = a as f64 - t.reconstruct(i / n, i % n) as f64;
        sum += d * d;
    }
    sum.sqrt()
}

/// Singular values of the f32 data by nalgebra's full SVD in f64, descending.
fn full_spectrum(data: &[f32], n: usize) -> Vec<f64> {
    let a = DMatrix::from_row_slice(data.len() / n, n, data).map(f64::from);
    let mut s: Vec<f64> = a.singular_values().iter().copied().collect();
    s.sort_by(|a, b| b.total_cmp(a));
    s
}

fn tail(s: &[f64], k: usize) -> f64 {
    s.iter().skip(k).map(|x| x * x).sum::<f64>().sqrt()
}

/// Reconstruction error within 1 % of the optimal rank-k error sqrt(Σ_{i>k} σᵢ²) of the full
/// SVD, plus an absolute 2·10⁻⁶·‖A‖ for f32 rounding of the factors; the spectrum agrees
/// with the full SVD to 10⁻³·σ₁ (f32 Gram accumulation).
#[test]
fn error_within_one_percent_of_optimal() {
    for (m, n, decay, eps, seed) in [
        (400, 40, 0.7, 1e-3, 1),
        (3000, 64, 0.85, 1e-2, 2),
        (5000, 24, 0.5, 0.0, 3),
        (64, 64, 0.9, 1e-4, 4),
        // Row blocks of 2048 and 5: the last one is shorter than the basis (k + 8).
        (2053, 32, 0.8, 1e-3, 5),
    ] {
        let data = test_matrix(m, n, decay, eps, seed);
        let full = full_spectrum(&data, n);
        let norm = tail(&full, 0);
        for k in [1, 2, 4, 8, 16] {
            let t = svd(&data, n, RankChoice::Rank(k));
            assert_eq!(t.rank, k.min(n));
            let got = residual(&data, n, &t);
            let best = tail(&full, k);
            assert!(
                got <= 1.01 * best + 2e-6 * norm,
                "{m}×{n} rank {k}: error {got} vs optimal {best}"
            );
            for (a, b) in t.spectrum.iter().zip(&full) {
                assert!((a - b).abs() <= 1e-3 * full[0], "{m}×{n}: σ {a} vs {b}");
            }
            // E has orthonormal columns (f32: 1e-5).
            for p in 0..t.rank {
                for q in 0..t.rank {
                    let d: f64 = (0..n)
                        .map(|r| t.eigen[r * t.rank + p] as f64 * t.eigen[r * t.rank + q] as f64)
                        .sum();
                    let want = if p == q { 1.0 } else { 0.0 };
                    assert!((d - want).abs() < 1e-5, "EᵀE[{p},{q}] = {d}");
                }
            }
        }
    }
}

/// Zero, constant and rank-deficient matrices: exact ranks, reconstruction to f32 rounding
/// (10⁻⁶ relative), no NaN.
#[test]
fn zero_constant_and_rank_deficient() {
    let zero = vec![0.0f32; 50 * 7];
    let t = svd(&zero, 7, RankChoice::Rank(4));
    assert_eq!(t.rank, 0);
    assert!(t.spectrum.iter().all(|&s| s == 0.0));
    assert_eq!(t.reconstruct(3, 2), 0.0);

    let constant = vec![2.5f32; 300 * 11];
    let t = svd(&constant, 11, RankChoice::Rank(5));
    assert_eq!(t.rank, 1);
    for (i, &a) in constant.iter().enumerate() {
        let r = t.reconstruct(i / 11, i % 11);
        assert!((r - a).abs() <= 1e-6 * a, "{r} vs {a}");
    }

    let low = test_matrix(500, 30, 1.0, 0.0, 5); // full rank 30 …
    // 4100 rows: row blocks of 2048, 2048 and 4, the last shorter than the basis.
    let mut rank3 = vec![0.0f32; 4100 * 30];
    let mut r = noise(6);
    let (u, v): (Vec<[f64; 3]>, Vec<[f64; 3]>) = (
        (0..4100).map(|_| [r(), r(), r()]).collect(),
        (0..30).map(|_| [r(), r(), r()]).collect(),
    );
    for (i, x) in rank3.iter_mut().enumerate() {
        let (a, b) = (u[i / 30], v[i % 30]);
        *x = (a[0] * b[0] + 3.0 * a[1] * b[1] + 9.0 * a[2] * b[2]) as f32;
    }
    let t = svd(&rank3, 30, RankChoice::Rank(8));
    assert_eq!(t.rank, 3, "spectrum {:?}", &t.spectrum[..5]);
    let norm = tail(&full_spectrum(&rank3, 30), 0);
    assert!(residual(&rank3, 30, &t) <= 2e-6 * norm);
    assert!(t.weights.iter().chain(&t.eigen).all(|v| v.is_finite()));
    // … and asking for more components than columns gives all of them.
    assert_eq!(svd(&low, 30, RankChoice::Rank(100)).rank, 30);
}

/// A target RMSE picks the smallest rank whose optimal error meets it, and the factorization
/// meets it (1 % slack).
#[test]
fn rank_from_target_rmse() {
    let (m, n) = (2000, 32);
    let data = test_matrix(m, n, 0.6, 1e-3, 7);
    let full = full_spectrum(&data, n);
    let entries = (m * n) as f64;
    for target in [0.5, 0.05, 0.005] {
        let t = svd(&data, n, RankChoice::MaxRmse(target));
        let k = t.rank;
        assert!(
            tail(&full, k) / entries.sqrt() <= target * 1.0001,
            "target {target}"
        );
        assert!(k == 0 || tail(&full, k - 1) / entries.sqrt() > target * 0.9999);
        assert!(residual(&data, n, &t) / entries.sqrt() <= 1.01 * target);
    }
}

/// The same input gives bit-identical factors whatever the thread count.
#[test]
fn deterministic_across_thread_counts() {
    let data = test_matrix(9000, 48, 0.8, 1e-2, 8);
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| svd(&data, 48, RankChoice::Rank(6)))
    };
    assert_eq!(run(1), run(3));
}

#[test]
fn bad_matrices_are_refused() {
    let mut data = test_matrix(100, 10, 0.5, 0.0, 9);
    data[17] = f32::NAN;
    let e = truncated_svd(
        &DenseRows::new(&data, 10).unwrap(),
        RankChoice::Rank(2),
        &Limits::default(),
    )
    .unwrap_err();
    assert!(e.to_string().contains("NaN"), "{e}");
    assert!(DenseRows::new(&data, 7).is_err());
    assert!(DenseRows::new(&[], 0).is_err());
    let e = truncated_svd(
        &DenseRows::new(&data[..20], 10).unwrap(),
        RankChoice::MaxRmse(f64::NAN),
        &Limits::default(),
    )
    .unwrap_err();
    assert!(e.to_string().contains("RMSE"), "{e}");
    let tiny = Limits {
        memory_bytes: 1000,
        ..Limits::default()
    };
    assert!(
        truncated_svd(
            &DenseRows::new(&data, 10).unwrap(),
            RankChoice::Rank(2),
            &tiny
        )
        .is_err()
    );
}

/// The GDM layout: row (b·Y + j)·X + i, column a·Z + k holds d(i, j, k, a, b); raw escapes
/// (+∞) are refused.
#[test]
fn gdm_layout_rows_and_columns() {
    use mesobake_bake::compress::layout::GdmRows;
    use mesobake_bake::compress::svd::RowSource;
    use mesobake_bake::gdm::{EscapeConvention, exact, volume_caster::VolumeCaster};
    use mesobake_bake::mesostructure::volume::Volume;
    use mesobake_package::grid::{Dims, DirectionGrid};
    let d = Dims::new(5, 3, 4).unwrap();
    let limits = Limits::default();
    let v = Volume::from_fn(d, &limits, |i, j, k| (i + 2 * j + k) % 4 == 0).unwrap();
    let dirs = DirectionGrid::new(4, 6).unwrap();
    let mut g = exact::bake(&VolumeCaster::new(&v), dirs, &limits, &()).unwrap();
    assert!(GdmRows::new(&g).is_err());
    g.set_escape_convention(EscapeConvention::Boundary);
    let a = GdmRows::new(&g).unwrap();
    assert_eq!((a.rows(), a.cols()), (5 * 3 * 6, 4 * 4));
    // Read from an odd start so that runs cross φ boundaries.
    let start = 7;
    let mut out = vec![0.0f32; (a.rows() - start) * a.cols()];
    a.read_rows(start, &mut out);
    for (x, &value) in out.iter().enumerate() {
        let (r, c) = (start + x / a.cols(), x % a.cols());
        let (i, j, b) = (r % 5, (r / 5) % 3, r / 15);
        let (th, k) = (c / 4, c % 4);
        let want = g.get(i as u32, j as u32, k as u32, th as u32, b as u32);
        assert_eq!(value, want, "row {r} column {c}");
    }
}

/// Cancels once `after` row blocks have started.
struct CancelAfter {
    after: usize,
    asked: std::sync::atomic::AtomicUsize,
}

impl mesobake_core::observer::BakeObserver for CancelAfter {
    fn cancelled(&self) -> bool {
        self.asked
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed)
            >= self.after
    }
}

#[test]
fn the_gram_accumulation_stops_when_cancelled() {
    use mesobake_bake::compress::svd::GramEigen;
    // 8192 rows make 4 row blocks of 2048.
    let data = test_matrix(8192, 12, 0.5, 1e-3, 7);
    let a = DenseRows::new(&data, 12).unwrap();
    let limits = Limits::default();
    let cancel = |after| CancelAfter {
        after,
        asked: 0.into(),
    };
    let e = GramEigen::observed(&a, &limits, &cancel(2)).err();
    assert!(matches!(e, Some(mesobake_core::Error::Cancelled)), "{e:?}");
    // An observer that never cancels changes nothing.
    let spectrum = |g: GramEigen| {
        g.truncate(&a, RankChoice::Rank(3), &limits)
            .unwrap()
            .spectrum
    };
    let observed = GramEigen::observed(&a, &limits, &cancel(usize::MAX)).unwrap();
    assert_eq!(
        spectrum(observed),
        spectrum(GramEigen::new(&a, &limits).unwrap())
    );
}
