//! Exact welding: dense ids for distinct position bits and for distinct UV vertices
//! `(welded position, sheet, u bits, v bits)`, plus the bucket grouping both rest on.
//!
//! Grouping many items by a composite key is done in two steps that need only `u32` per item:
//! a counting sort on a dense integer part of the key (the welded position, or the lower UV
//! vertex of an edge) into buckets, then a small sort of each bucket on the rest of the key.
//! Buckets are tiny on meshes (a handful of corners per position), so this is linear in practice
//! and uses a fraction of the memory of sorting wide keys.

use std::ops::Range;

use rayon::prelude::*;

use super::charts::UnionFind;
use super::stats::{FACE_CHUNK, Prep};
use crate::model::Model;

/// Items per parallel task when processing buckets; buckets are never split.
const BUCKET_CHUNK_ITEMS: usize = 1 << 16;

/// Items `0..n` grouped by a dense key in `0..nb`: the items of bucket `b` are
/// `order[start[b]..start[b + 1]]`, initially in increasing item order.
pub(crate) struct Buckets {
    pub start: Vec<u32>,
    pub order: Vec<u32>,
}

impl Buckets {
    /// Counting sort of items `0..n` by `key(i) < nb`.
    pub fn build(nb: usize, n: usize, key: impl Fn(usize) -> u32 + Sync) -> Self {
        let mut start = vec![0u32; nb + 1];
        for i in 0..n {
            start[key(i) as usize + 1] += 1;
        }
        for b in 0..nb {
            start[b + 1] += start[b];
        }
        let mut fill: Vec<u32> = start[..nb].to_vec();
        let mut order = vec![0u32; n];
        for i in 0..n {
            let b = key(i) as usize;
            order[fill[b] as usize] = i as u32;
            fill[b] += 1;
        }
        Self { start, order }
    }

    /// Runs `f(buckets, base, order_part, aux_part)` in parallel over chunks of whole buckets of
    /// about [`BUCKET_CHUNK_ITEMS`] items, where `order_part` and `aux_part` are the slices of
    /// `order` and of `aux` (same length as `order`) starting at item position `base`. The
    /// chunking depends only on the data, so results collected in chunk order are deterministic.
    pub fn par_chunks<R: Send>(
        &mut self,
        aux: &mut [u32],
        f: impl Fn(Range<usize>, usize, &mut [u32], &mut [u32]) -> R + Sync,
    ) -> Vec<R> {
        debug_assert_eq!(aux.len(), self.order.len());
        let nb = self.start.len() - 1;
        let mut cuts = vec![0usize];
        let mut last = 0usize;
        for b in 1..=nb {
            let pos = self.start[b] as usize;
            if pos - last >= BUCKET_CHUNK_ITEMS || b == nb {
                cuts.push(b);
                last = pos;
            }
        }
        if nb == 0 {
            cuts.push(0);
        }
        let mut jobs = Vec::with_capacity(cuts.len());
        let (mut order, mut aux_rest) = (&mut self.order[..], aux);
        for w in cuts.windows(2) {
            let len = (self.start[w[1]] - self.start[w[0]]) as usize;
            let (o, o_rest) = order.split_at_mut(len);
            let (a, a_rest) = aux_rest.split_at_mut(len);
            order = o_rest;
            aux_rest = a_rest;
            jobs.push((w[0]..w[1], self.start[w[0]] as usize, o, a));
        }
        jobs.into_par_iter().map(|(bs, base, o, a)| f(bs, base, o, a)).collect()
    }
}

/// Dense ids of the distinct exact positions (bits of `p + 0.0`, so `-0.0 == 0.0`), one per
/// position record, and their number.
pub(crate) fn weld_positions(positions: &[[f64; 3]]) -> (Vec<u32>, usize) {
    let mut keys: Vec<([u64; 3], u32)> = positions
        .par_iter()
        .enumerate()
        .map(|(i, p)| {
            ([(p[0] + 0.0).to_bits(), (p[1] + 0.0).to_bits(), (p[2] + 0.0).to_bits()], i as u32)
        })
        .collect();
    // (key, index) pairs are distinct, so the unstable sort is deterministic.
    keys.par_sort_unstable();
    let mut pid = vec![0u32; positions.len()];
    let mut next = 0u32;
    for i in 0..keys.len() {
        if i > 0 && keys[i].0 != keys[i - 1].0 {
            next += 1;
        }
        pid[keys[i].1 as usize] = next;
    }
    let n = if keys.is_empty() { 0 } else { next as usize + 1 };
    (pid, n)
}

/// The number of distinct welded positions used by faces.
pub(crate) fn used_ids(model: &Model, pid: &[u32], n_pid: usize) -> u64 {
    let mut used = vec![false; n_pid];
    for f in &model.faces {
        for v in f.v {
            used[pid[v.idx()] as usize] = true;
        }
    }
    used.iter().filter(|&&u| u).count() as u64
}

/// UV vertex ids per face corner (wedge `3·f + k`), their number, and the number of charts of
/// faces sharing a UV vertex.
pub(crate) struct UvVertices {
    pub uvid: Vec<u32>,
    pub count: usize,
    pub charts: u64,
}

/// The welded position of every wedge `3·f + k`.
pub(crate) fn wedge_pids(model: &Model, pid: &[u32]) -> Vec<u32> {
    let mut fw = vec![0u32; model.faces.len() * 3];
    fw.par_chunks_mut(3 * FACE_CHUNK).enumerate().for_each(|(c, out)| {
        for (i, w) in out.chunks_exact_mut(3).enumerate() {
            let v = model.faces[c * FACE_CHUNK + i].v;
            for k in 0..3 {
                w[k] = pid[v[k].idx()];
            }
        }
    });
    fw
}

/// Groups the corners of all faces into UV vertices; `fw` are the wedges' welded positions.
pub(crate) fn uv_vertices(prep: &Prep<'_>, fw: &[u32], n_pid: usize) -> UvVertices {
    let model = prep.model;
    let nw = fw.len();
    let mut buckets = Buckets::build(n_pid, nw, |w| fw[w]);
    // The key inside a position bucket: sheet key and the bits of the UV with non-finite
    // coordinates replaced by 0 and -0.0 folded into 0.0 (evaluate.py's `UVz`), then the wedge,
    // so that the order is total and deterministic.
    let key = |w: u32| {
        let w = w as usize;
        let uv = prep.wedge_uv(w);
        let z = |c: f64| (if c.is_finite() { c } else { 0.0 } + 0.0).to_bits();
        (prep.sheet_key[w / 3], z(uv[0]), z(uv[1]), w as u32)
    };
    let mut gid = vec![0u32; nw];
    // Per chunk: sort each bucket (keys computed once into a scratch buffer reused across
    // buckets), write chunk-local ids into `gid`, return the chunk's item range and id count.
    let chunks = {
        let start = buckets.start.clone();
        buckets.par_chunks(&mut gid, |bs, base, order, ids| {
            let mut next = 0u32;
            let mut scratch: Vec<(u32, u64, u64, u32)> = Vec::new();
            for b in bs {
                let r = start[b] as usize - base..start[b + 1] as usize - base;
                scratch.clear();
                scratch.extend(order[r.clone()].iter().map(|&w| key(w)));
                if scratch.len() > 1 {
                    scratch.sort_unstable();
                }
                let mut prev = None;
                for (i, &(s, u, v, w)) in scratch.iter().enumerate() {
                    if prev != Some((s, u, v)) {
                        next += 1;
                        prev = Some((s, u, v));
                    }
                    order[r.start + i] = w;
                    ids[r.start + i] = next - 1;
                }
            }
            (base..base + order.len(), next)
        })
    };
    // Rebase chunk-local ids, scatter them to the wedges, and join faces sharing a UV vertex
    // (consecutive items of one UV vertex are adjacent in `order`).
    let mut uvid = vec![0u32; nw];
    let mut uf = UnionFind::new(model.faces.len());
    let mut id_base = 0u32;
    for (range, n_ids) in chunks {
        for pos in range.clone() {
            let w = buckets.order[pos] as usize;
            uvid[w] = id_base + gid[pos];
            if pos > range.start && gid[pos] == gid[pos - 1] {
                uf.union((buckets.order[pos - 1] / 3) as usize, w / 3);
            }
        }
        id_base += n_ids;
    }
    let count = id_base as usize;
    UvVertices { uvid, count, charts: uf.count_roots() }
}
