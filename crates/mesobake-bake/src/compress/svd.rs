//! Truncated SVD of tall matrices, A ≈ W·Eᵀ, for the paper's compression layouts.
//!
//! Algorithm (deterministic; no random numbers):
//! 1. **Gram matrix** G = AᵀA (n × n, n = columns). Rows are read in fixed blocks; each
//!    block's product is formed in f32 (matrixmultiply; only the 128-column panels on and
//!    above the diagonal, G being symmetric) and accumulated in f64, block by block in a fixed
//!    order, so the result does not depend on the thread count.
//! 2. **Spectrum**: the symmetric eigendecomposition of G (f64) gives every σᵢ² = λᵢ, hence the
//!    optimal error of every rank, sqrt(Σ_{i>k} σᵢ²) (Eckart–Young), which chooses the rank
//!    for a target RMSE and is reported.
//! 3. **Refinement**: with V the top k + 8 eigenvectors (oversampled), Q = qr(A·V) (A·V in
//!    f32, since only its span matters; QR in f64) and the small SVD
//!    B = QᵀA = U_B Σ V_Bᵀ (B in f64), whose top k components give
//!    A ≈ (Q U_B Σ)·V_Bᵀ. Projecting A onto span(A·V) recovers the accuracy that squaring the
//!    singular values in an f32 G loses, so small singular values and rank-deficient matrices
//!    come out right to f32 rounding. One more read of A suffices: the QR is a TSQR (each
//!    row block's Householder QR Q_b·R_b, then one of the stacked R_b), so every block forms
//!    its A_b·V, Q_b and Q_bᵀ·A_b as soon as it is read.
//!
//! The weight factor W = Q U_B Σ carries the singular values; the eigen factor E = V_B has
//! orthonormal columns. Singular values below 10⁻⁶ σ₁ (f32 data carries no information there)
//! are dropped, so a zero matrix has rank 0, a constant one rank 1, and no NaN arises.

use mesobake_core::error::{Error, Result};
use mesobake_core::limits::Limits;
use mesobake_core::observer::BakeObserver;
use nalgebra::{DMatrix, SymmetricEigen};
use rayon::prelude::*;

/// A matrix read a block of rows at a time (f32), so that layouts over large arrays need no
/// transposed copy.
pub trait RowSource: Sync {
    /// Number of rows m.
    fn rows(&self) -> usize;
    /// Number of columns n.
    fn cols(&self) -> usize;
    /// Writes rows `start..start + out.len() / cols` into `out` in whichever order this source
    /// gathers fastest, and says which.
    fn read_block(&self, start: usize, out: &mut [f32]) -> BlockOrder;
    /// Writes rows `start..start + out.len() / cols` into `out`, row-major.
    fn read_rows(&self, start: usize, out: &mut [f32]) {
        let (n, count) = (self.cols(), out.len() / self.cols());
        let mut block = vec![0.0f32; out.len()];
        match self.read_block(start, &mut block) {
            BlockOrder::RowMajor => out.copy_from_slice(&block),
            BlockOrder::ColumnMajor => transpose(&block, n, count, out),
        }
    }
}

/// The order of a block of rows as a [`RowSource`] wrote it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BlockOrder {
    /// Row after row.
    RowMajor,
    /// Column after column (each column holds the block's rows).
    ColumnMajor,
}

impl BlockOrder {
    /// (row stride, column stride) of a `count` × `cols` block in this order.
    pub fn strides(self, count: usize, cols: usize) -> (usize, usize) {
        match self {
            BlockOrder::RowMajor => (cols, 1),
            BlockOrder::ColumnMajor => (1, count),
        }
    }
}

/// Writes the transpose of `src` (row-major `rows` × `cols`) into `out`, in cache tiles.
fn transpose(src: &[f32], rows: usize, cols: usize, out: &mut [f32]) {
    const TILE: usize = 32;
    for r0 in (0..rows).step_by(TILE) {
        for c0 in (0..cols).step_by(TILE) {
            for r in r0..(r0 + TILE).min(rows) {
                for c in c0..(c0 + TILE).min(cols) {
                    out[c * rows + r] = src[r * cols + c];
                }
            }
        }
    }
}

/// A dense row-major matrix as a [`RowSource`].
#[derive(Clone, Copy, Debug)]
pub struct DenseRows<'a> {
    data: &'a [f32],
    cols: usize,
}

impl<'a> DenseRows<'a> {
    /// Wraps `data` (row-major, `cols` columns; its length must be a multiple of `cols`).
    pub fn new(data: &'a [f32], cols: usize) -> Result<Self> {
        if cols == 0 || !data.len().is_multiple_of(cols) {
            return Err(Error::InvalidParameter(format!(
                "a dense matrix of {} values cannot have {cols} columns",
                data.len()
            )));
        }
        Ok(DenseRows { data, cols })
    }
}

impl RowSource for DenseRows<'_> {
    fn rows(&self) -> usize {
        self.data.len() / self.cols
    }
    fn cols(&self) -> usize {
        self.cols
    }
    fn read_block(&self, start: usize, out: &mut [f32]) -> BlockOrder {
        out.copy_from_slice(&self.data[start * self.cols..][..out.len()]);
        BlockOrder::RowMajor
    }
}

pub use mesobake_package::manifest::RankChoice;

/// A rank-k factorization A ≈ W·Eᵀ.
#[derive(Clone, Debug, PartialEq)]
pub struct Truncated {
    /// Rows m and columns n of A.
    pub shape: (usize, usize),
    /// Components kept, k.
    pub rank: usize,
    /// Singular values of A, all min(m, n) of them, descending (from the Gram eigenvalues;
    /// values below about 10⁻³ σ₁ are limited by f32 accumulation).
    pub spectrum: Vec<f64>,
    /// W, m × k row-major: left singular vectors scaled by their singular values.
    pub weights: Vec<f32>,
    /// E, n × k row-major: orthonormal right singular vectors.
    pub eigen: Vec<f32>,
}

impl Truncated {
    /// The optimal root-mean-square error of rank `k` over all m·n entries,
    /// sqrt(Σ_{i>k} σᵢ² / (m·n)).
    pub fn optimal_rmse(&self, k: usize) -> f64 {
        let tail: f64 = self.spectrum.iter().skip(k).map(|s| s * s).sum();
        (tail / (self.shape.0 as f64 * self.shape.1 as f64)).sqrt()
    }

    /// The leading `k` components (all of them if `k` ≥ rank): the rank-k truncation, as
    /// accurate as this factorization's basis.
    pub fn leading(&self, k: usize) -> Truncated {
        let (m, n) = self.shape;
        let k = k.min(self.rank);
        let cut = |f: &[f32], rows: usize| -> Vec<f32> {
            (0..rows)
                .flat_map(|r| &f[r * self.rank..][..k])
                .copied()
                .collect()
        };
        Truncated {
            shape: self.shape,
            rank: k,
            spectrum: self.spectrum.clone(),
            weights: cut(&self.weights, m),
            eigen: cut(&self.eigen, n),
        }
    }

    /// Entry (r, c) of W·Eᵀ.
    pub fn reconstruct(&self, r: usize, c: usize) -> f32 {
        let k = self.rank;
        let w = &self.weights[r * k..][..k];
        let e = &self.eigen[c * k..][..k];
        w.iter().zip(e).map(|(a, b)| a * b).sum()
    }
}

/// Rows per block of the Gram accumulation (a fixed function of the shape only).
fn block_rows(m: usize) -> usize {
    m.div_ceil(64).max(2048).min(m.max(1))
}

/// Extra basis vectors beyond the rank asked for.
const OVERSAMPLING: usize = 8;

/// Singular values below this fraction of the largest are dropped.
const RELATIVE_FLOOR: f64 = 1e-6;

/// Computes the truncated SVD of `a` with the rank chosen by `choice`.
pub fn truncated_svd(a: &dyn RowSource, choice: RankChoice, limits: &Limits) -> Result<Truncated> {
    check_choice(choice)?;
    GramEigen::new(a, limits)?.truncate(a, choice, limits)
}

/// Refuses target errors that are negative, NaN or infinite.
fn check_choice(choice: RankChoice) -> Result<()> {
    match choice {
        RankChoice::MaxRmse(e) if !(e >= 0.0 && e.is_finite()) => Err(Error::InvalidParameter(
            format!("the target RMSE must be a finite number ≥ 0, got {e}"),
        )),
        _ => Ok(()),
    }
}

/// Steps 1 and 2 of the algorithm: the eigendecomposition of AᵀA, which fixes the spectrum
/// and serves truncations to any rank (each costs only step 3).
pub struct GramEigen {
    shape: (usize, usize),
    /// Eigenvectors of AᵀA (columns), in the order of `order`.
    vectors: DMatrix<f64>,
    /// Column indices of `vectors` by descending eigenvalue.
    order: Vec<usize>,
    /// Singular values, descending.
    spectrum: Vec<f64>,
}

impl GramEigen {
    /// Forms and decomposes AᵀA; refuses empty matrices and NaN or infinite entries.
    pub fn new(a: &dyn RowSource, limits: &Limits) -> Result<Self> {
        Self::observed(a, limits, &())
    }

    /// [`GramEigen::new`] that stops with [`Error::Cancelled`] when `observer` asks, checked
    /// before each row block of the Gram accumulation (the bulk of the work).
    pub fn observed(
        a: &dyn RowSource,
        limits: &Limits,
        observer: &dyn BakeObserver,
    ) -> Result<Self> {
        let (m, n) = (a.rows(), a.cols());
        if m == 0 || n == 0 {
            return Err(Error::InvalidParameter(format!(
                "cannot factor an empty {m}×{n} matrix"
            )));
        }
        let block = block_rows(m);
        // G (n² f64) and, per block in flight, an f32 block and its f64 product.
        limits.check("the SVD's Gram matrix", (n * n) as u64, 8 * 3)?;
        limits.check(
            "an SVD row block",
            (block * n) as u64,
            4 * rayon::current_num_threads() as u64,
        )?;
        let gram = gram_matrix(a, block, observer)?;
        if !gram.iter().all(|v| v.is_finite()) {
            return Err(Error::InvalidParameter(
                "the matrix holds NaN or infinite values (escapes must be replaced before compression)"
                    .into(),
            ));
        }
        let eig = SymmetricEigen::new(gram);
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by(|&i, &j| eig.eigenvalues[j].total_cmp(&eig.eigenvalues[i]));
        let spectrum = order
            .iter()
            .take(m.min(n))
            .map(|&i| eig.eigenvalues[i].max(0.0).sqrt())
            .collect();
        Ok(GramEigen {
            shape: (m, n),
            vectors: eig.eigenvectors,
            order,
            spectrum,
        })
    }

    /// The truncation of `a` (the matrix this was formed from) with the rank chosen by
    /// `choice`.
    pub fn truncate(
        &self,
        a: &dyn RowSource,
        choice: RankChoice,
        limits: &Limits,
    ) -> Result<Truncated> {
        let (m, n) = self.shape;
        if (a.rows(), a.cols()) != self.shape {
            return Err(Error::InvalidParameter(format!(
                "a {}×{} matrix cannot be truncated with the spectrum of a {m}×{n} one",
                a.rows(),
                a.cols()
            )));
        }
        check_choice(choice)?;
        let mut result = Truncated {
            shape: (m, n),
            rank: 0,
            spectrum: self.spectrum.clone(),
            weights: Vec::new(),
            eigen: Vec::new(),
        };
        let wanted = match choice {
            RankChoice::Rank(k) => k,
            RankChoice::MaxRmse(e) => (0..=n).find(|&k| result.optimal_rmse(k) <= e).unwrap_or(n),
        };
        let k = wanted.min(m).min(n);
        if k == 0 || result.spectrum[0] == 0.0 {
            return Ok(result);
        }
        let block = block_rows(m);
        // The basis is oversampled so that directions the f32 Gram matrix blurs near σ_k are
        // still captured; the small SVD then keeps the best k.
        let k_basis = (k + OVERSAMPLING).min(m).min(n);
        limits.check("the SVD's range basis", (m * k_basis) as u64, 8 * 3)?;
        let (k_out, k) = (k, k_basis);
        // V, n × k row-major.
        let v_k: Vec<f32> = (0..n * k)
            .map(|x| self.vectors[(x / k, self.order[x % k])] as f32)
            .collect();
        let parts: Vec<BlockProjection> = blocks(m, block)
            .into_par_iter()
            .map(|(start, count)| BlockProjection::new(a, start, count, &v_k, k))
            .collect();
        // TSQR: the blocks' R factors stacked, factored again, give Q = diag(Q_b)·Q_top.
        let mut r_all = DMatrix::<f64>::zeros(parts.iter().map(|p| p.r.nrows()).sum(), k);
        let mut offsets = Vec::with_capacity(parts.len());
        let mut row = 0;
        for p in &parts {
            r_all.rows_mut(row, p.r.nrows()).copy_from(&p.r);
            offsets.push(row);
            row += p.r.nrows();
        }
        let q_top = r_all.qr().q();
        // B = QᵀA = Σ_b Q_top,bᵀ·(Q_bᵀ·A_b), summed in block order.
        let mut b = DMatrix::<f64>::zeros(k, n);
        for (p, &o) in parts.iter().zip(&offsets) {
            b += q_top.rows(o, p.r.nrows()).transpose() * &p.qt_a;
        }
        let svd = b.svd(true, true);
        let (u_b, v_bt) = (svd.u.expect("requested"), svd.v_t.expect("requested"));
        let mut idx: Vec<usize> = (0..svd.singular_values.len()).collect();
        idx.sort_by(|&i, &j| svd.singular_values[j].total_cmp(&svd.singular_values[i]));
        let top = svd.singular_values[idx[0]];
        idx.truncate(k_out);
        idx.retain(|&i| svd.singular_values[i] > top * RELATIVE_FLOOR);
        let k = idx.len();
        if k == 0 {
            return Ok(result);
        }
        let scaled_u = DMatrix::from_fn(u_b.nrows(), k, |r, c| {
            u_b[(r, idx[c])] * svd.singular_values[idx[c]]
        });
        // W = Q·U_B·Σ, block by block: W_b = Q_b·(Q_top,b·U_B·Σ).
        result.rank = k;
        result.weights = parts
            .iter()
            .zip(&offsets)
            .flat_map(|(p, &o)| {
                let w = &p.q * (q_top.rows(o, p.r.nrows()) * &scaled_u);
                (0..w.nrows())
                    .flat_map(move |r| (0..k).map(move |c| (r, c)))
                    .map(move |(r, c)| w[(r, c)] as f32)
                    .collect::<Vec<f32>>()
            })
            .collect();
        result.eigen = (0..n)
            .flat_map(|r| (0..k).map(move |c| (r, c)))
            .map(|(r, c)| v_bt[(idx[c], r)] as f32)
            .collect();
        Ok(result)
    }
}

/// One row block's share of the projection step, from a single read of the block.
struct BlockProjection {
    /// Q_b (count × min(count, k)): orthonormal basis of the block's rows of A·V.
    q: DMatrix<f64>,
    /// R_b with Q_b·R_b = A_b·V.
    r: DMatrix<f64>,
    /// Q_bᵀ·A_b (min(count, k) × n).
    qt_a: DMatrix<f64>,
}

impl BlockProjection {
    /// Y_b = A_b·V (f32: only its span matters), its thin QR in f64 (Householder), and
    /// Q_bᵀ·A_b in f64.
    fn new(a: &dyn RowSource, start: usize, count: usize, v: &[f32], k: usize) -> Self {
        let n = a.cols();
        let (rows, (rs, cs)) = read_block(a, start, count);
        let mut y = vec![0.0f32; count * k];
        gemm(count, n, k, (&rows, rs, cs), (v, k, 1), (&mut y, k, 1));
        let qr = DMatrix::from_row_iterator(count, k, y.into_iter().map(f64::from)).qr();
        let (q, r) = (qr.q(), qr.r());
        let rows: Vec<f64> = rows.into_iter().map(f64::from).collect();
        let mut qt_a = vec![0.0f64; q.ncols() * n];
        // Q_b is column-major: Q_bᵀ (min(count, k) × count) has row stride `count`.
        let qt = (q.as_slice(), count, 1);
        gemm(q.ncols(), count, n, qt, (&rows, rs, cs), (&mut qt_a, n, 1));
        let qt_a = DMatrix::from_row_slice(q.ncols(), n, &qt_a);
        BlockProjection { q, r, qt_a }
    }
}

/// The row blocks of `a`: (first row, row count).
fn blocks(m: usize, block: usize) -> Vec<(usize, usize)> {
    (0..m.div_ceil(block))
        .map(|b| (b * block, block.min(m - b * block)))
        .collect()
}

/// A block of rows as read, with its (row, column) strides.
fn read_block(a: &dyn RowSource, start: usize, count: usize) -> (Vec<f32>, (usize, usize)) {
    let mut buf = vec![0.0f32; count * a.cols()];
    let strides = a.read_block(start, &mut buf).strides(count, a.cols());
    (buf, strides)
}

/// A strided matrix operand: (data, row stride, column stride).
type Strided<'a, T> = (&'a [T], usize, usize);

/// The last element a strided r × c operand touches, plus one.
fn extent(r: usize, c: usize, rs: usize, cs: usize) -> usize {
    (r - 1) * rs + (c - 1) * cs + 1
}

/// The element types matrixmultiply multiplies.
pub(crate) trait GemmScalar: Copy {
    /// C = A·B on raw strided operands (`matrixmultiply::sgemm` / `dgemm`, α = 1, β = 0).
    ///
    /// # Safety
    /// The operands must lie within their allocations and C must not alias A or B.
    #[allow(clippy::too_many_arguments)]
    unsafe fn gemm_raw(
        r: usize,
        l: usize,
        c: usize,
        a: *const Self,
        rsa: isize,
        csa: isize,
        b: *const Self,
        rsb: isize,
        csb: isize,
        out: *mut Self,
        rso: isize,
        cso: isize,
    );
}

impl GemmScalar for f32 {
    unsafe fn gemm_raw(
        r: usize,
        l: usize,
        c: usize,
        a: *const f32,
        rsa: isize,
        csa: isize,
        b: *const f32,
        rsb: isize,
        csb: isize,
        out: *mut f32,
        rso: isize,
        cso: isize,
    ) {
        // SAFETY: forwarded from the caller.
        unsafe { matrixmultiply::sgemm(r, l, c, 1.0, a, rsa, csa, b, rsb, csb, 0.0, out, rso, cso) }
    }
}

impl GemmScalar for f64 {
    unsafe fn gemm_raw(
        r: usize,
        l: usize,
        c: usize,
        a: *const f64,
        rsa: isize,
        csa: isize,
        b: *const f64,
        rsb: isize,
        csb: isize,
        out: *mut f64,
        rso: isize,
        cso: isize,
    ) {
        // SAFETY: forwarded from the caller.
        unsafe { matrixmultiply::dgemm(r, l, c, 1.0, a, rsa, csa, b, rsb, csb, 0.0, out, rso, cso) }
    }
}

/// C = A·B for strided A (r × l), B (l × c) and C (r × c) (matrixmultiply).
pub(crate) fn gemm<T: GemmScalar>(
    r: usize,
    l: usize,
    c: usize,
    a: Strided<T>,
    b: Strided<T>,
    out: (&mut [T], usize, usize),
) {
    assert!(a.0.len() >= extent(r, l, a.1, a.2) && b.0.len() >= extent(l, c, b.1, b.2));
    assert!(out.0.len() >= extent(r, c, out.1, out.2));
    // SAFETY: the three operands lie within their slices (checked above); C does not alias.
    unsafe {
        T::gemm_raw(
            r,
            l,
            c,
            a.0.as_ptr(),
            a.1 as isize,
            a.2 as isize,
            b.0.as_ptr(),
            b.1 as isize,
            b.2 as isize,
            out.0.as_mut_ptr(),
            out.1 as isize,
            out.2 as isize,
        )
    }
}

/// Column panel width of the Gram products: only panels on or above the diagonal are formed
/// (AᵀA is symmetric), which saves up to half the work of the full product.
const GRAM_PANEL: usize = 128;

/// AᵀA: per block in f32, accumulated in f64 in block order; blocks done are reported to
/// `observer`.
fn gram_matrix(
    a: &dyn RowSource,
    block: usize,
    observer: &dyn BakeObserver,
) -> Result<DMatrix<f64>> {
    let n = a.cols();
    let panels: Vec<(usize, usize)> = (0..n.div_ceil(GRAM_PANEL))
        .map(|p| (p * GRAM_PANEL, GRAM_PANEL.min(n - p * GRAM_PANEL)))
        .collect();
    let all = blocks(a.rows(), block);
    let total = all.len() as u64;
    let done = std::sync::atomic::AtomicU64::new(0);
    let partial: Vec<Vec<f32>> = all
        .into_par_iter()
        .map(|(start, count)| {
            if observer.cancelled() {
                return Err(Error::Cancelled);
            }
            // Row-major: the panel products below pack row-major blocks fastest (measured on
            // W1: column-major blocks made this pass 1.5–1.9× slower).
            let mut rows = vec![0.0f32; count * n];
            a.read_rows(start, &mut rows);
            let mut g = vec![0.0f32; n * n];
            for (p, &(p0, pw)) in panels.iter().enumerate() {
                for &(q0, qw) in &panels[p..] {
                    // A_b[:, p]ᵀ (pw × count) is A_b read with swapped strides.
                    let (at, b) = ((&rows[p0..], 1, n), (&rows[q0..], n, 1));
                    gemm(pw, count, qw, at, b, (&mut g[p0 * n + q0..], n, 1));
                }
            }
            let finished = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            observer.progress(finished, total);
            Ok(g)
        })
        .collect::<Result<_>>()?;
    let mut sum = vec![0.0f64; n * n];
    for g in partial {
        sum.iter_mut().zip(g).for_each(|(s, v)| *s += v as f64);
    }
    // Mirror the panels above the diagonal to below it.
    for i in 0..n {
        for j in 0..i {
            if i / GRAM_PANEL != j / GRAM_PANEL {
                sum[i * n + j] = sum[j * n + i];
            }
        }
    }
    Ok(DMatrix::from_row_slice(n, n, &sum))
}
