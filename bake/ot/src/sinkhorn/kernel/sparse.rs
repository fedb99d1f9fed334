//! Sparse lists in fixed chunks: concatenating per-chunk rows, assembling a kernel with its
//! transpose, and the block-parallel transpose itself.

use super::Kernel;
use rayon::prelude::*;

/// Chunks of lists (per chunk: list lengths, entries, values) concatenated in order, as
/// (ptr, entries, values) over `m` lists.
pub(super) fn concat(
    chunks: Vec<(Vec<u32>, Vec<u32>, Vec<f32>)>,
    m: usize,
) -> (Vec<usize>, Vec<u32>, Vec<f32>) {
    let mut ptr = Vec::with_capacity(m + 1);
    ptr.push(0);
    let total: usize = chunks.iter().map(|c| c.1.len()).sum();
    let mut out = Vec::with_capacity(total);
    let mut vals = Vec::with_capacity(total);
    for (lens, o, v) in chunks {
        for l in lens {
            ptr.push(ptr.last().unwrap() + l as usize);
        }
        out.extend(o);
        vals.extend(v);
    }
    (ptr, out, vals)
}

/// A kernel from its rows (per chunk: row lengths, columns, values), with the transpose.
pub(super) fn assemble(
    chunks: Vec<(Vec<u32>, Vec<u32>, Vec<f32>)>,
    m: usize,
    nt: usize,
    f: Vec<f64>,
) -> Kernel {
    let (row_ptr, col, k) = concat(chunks, m);
    let (col_ptr, row, src_pos) = transpose(&row_ptr, &col, nt);
    let kt = src_pos.par_iter().map(|&e| k[e]).collect();
    Kernel {
        row_ptr,
        col,
        k,
        col_ptr,
        row,
        kt,
        f,
    }
}

/// Column blocks of a transpose, filled in parallel: each block owns a contiguous range of the
/// output, so the blocks write disjoint slices, and every entry lands where the sequential fill
/// would put it (the result does not depend on the thread count).
const TRANSPOSE_BLOCKS: usize = 16;

/// Transposes a CSR pattern (rows ascending inside each column): returns (ptr, idx, position of
/// each transposed entry in the original arrays).
///
/// The rows' lists are sorted, and rows and columns are both in Morton order, so a row's columns
/// mostly fall in one block: a block skips a row by its first and last column, and cuts the rest by
/// binary search.
pub(super) fn transpose(
    ptr: &[usize],
    idx: &[u32],
    cols: usize,
) -> (Vec<usize>, Vec<u32>, Vec<usize>) {
    let mut tptr = vec![0usize; cols + 1];
    for &j in idx {
        tptr[j as usize + 1] += 1;
    }
    for j in 0..cols {
        tptr[j + 1] += tptr[j];
    }
    let total = idx.len();
    // Block boundaries (columns) splitting the entries about evenly.
    let mut bounds = vec![0usize];
    for b in 1..TRANSPOSE_BLOCKS {
        let at = tptr
            .partition_point(|&t| t < total * b / TRANSPOSE_BLOCKS)
            .min(cols);
        if at > *bounds.last().unwrap() {
            bounds.push(at);
        }
    }
    bounds.push(cols);
    let mut tidx = vec![0u32; total];
    let mut src = vec![0usize; total];
    // Disjoint output slices, one per block.
    let mut parts = Vec::with_capacity(bounds.len() - 1);
    let (mut rest_idx, mut rest_src) = (&mut tidx[..], &mut src[..]);
    for w in bounds.windows(2) {
        let len = tptr[w[1]] - tptr[w[0]];
        let (a, r) = std::mem::take(&mut rest_idx).split_at_mut(len);
        let (b, s) = std::mem::take(&mut rest_src).split_at_mut(len);
        rest_idx = r;
        rest_src = s;
        parts.push((w[0], w[1], a, b));
    }
    parts
        .into_par_iter()
        .for_each(|(c0, c1, out_idx, out_src)| {
            let base = tptr[c0];
            let mut fill: Vec<usize> = tptr[c0..c1].iter().map(|&t| t - base).collect();
            let (lo, hi) = (c0 as u32, c1 as u32);
            for i in 0..ptr.len() - 1 {
                let row = &idx[ptr[i]..ptr[i + 1]];
                match (row.first(), row.last()) {
                    (Some(&first), Some(&last)) if last >= lo && first < hi => {
                        let a = if first >= lo {
                            0
                        } else {
                            row.partition_point(|&j| j < lo)
                        };
                        let b = if last < hi {
                            row.len()
                        } else {
                            row.partition_point(|&j| j < hi)
                        };
                        for (e, &j) in row.iter().enumerate().take(b).skip(a) {
                            let slot = &mut fill[(j - lo) as usize];
                            out_idx[*slot] = i as u32;
                            out_src[*slot] = ptr[i] + e;
                            *slot += 1;
                        }
                    }
                    _ => {}
                }
            }
        });
    (tptr, tidx, src)
}
