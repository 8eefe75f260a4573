//! How the CPU kernels run over the nodes: serially, or in parallel chunks on a rayon pool.
//!
//! Each node's force and update depend only on the previous state, so the chunking does not
//! change a single bit of the results; [`Threads`] only decides where the work runs, and,
//! with a [`Threads::subset`], on which nodes (a local force evaluation: the needle's
//! settle asks for the forces on the few nodes it places, `Backend::compute_forces_on`).

use rayon::prelude::*;

/// Nodes per parallel work item.
pub const CHUNK: usize = 256;

/// Where a CPU kernel runs: on the calling thread, or in chunks of [`CHUNK`] nodes on a
/// pool (the backend's own, or rayon's global one).
#[derive(Clone, Copy)]
pub struct Threads<'a> {
    /// The backend's own pool; `None` for rayon's global pool.
    pub pool: Option<&'a rayon::ThreadPool>,
    /// Whether to run in parallel at all.
    pub parallel: bool,
    /// Only these nodes (ascending, each below the slices' length), one at a time on the
    /// calling thread; the other entries are left as they were. `None`: every node.
    pub subset: Option<&'a [u32]>,
}

impl<'a> Threads<'a> {
    /// Every node, serially or in parallel.
    pub fn all(pool: Option<&'a rayon::ThreadPool>, parallel: bool) -> Threads<'a> {
        Threads {
            pool,
            parallel,
            subset: None,
        }
    }

    /// The same pool restricted to `subset` (`None`: every node).
    pub fn with_subset<'b>(self, subset: Option<&'b [u32]>) -> Threads<'b>
    where
        'a: 'b,
    {
        Threads {
            pool: self.pool,
            parallel: self.parallel,
            subset,
        }
    }

    /// With a subset: the subset and every neighbour of its nodes below `n`, ascending
    /// (the nodes whose per-node first pass a two-pass force on the subset reads).
    /// `None` without a subset.
    pub fn one_ring(&self, nb: &crate::neighbours::Neighbours, n: usize) -> Option<Vec<u32>> {
        let subset = self.subset?;
        let mut ring: Vec<u32> = subset.to_vec();
        for &i in subset {
            ring.extend(nb.live(i as usize).map(|(_, j, _)| j as u32));
        }
        ring.retain(|&j| (j as usize) < n);
        ring.sort_unstable();
        ring.dedup();
        Some(ring)
    }

    /// Runs `f(first, &mut a[chunk], &mut b[chunk])` over consecutive chunks of [`CHUNK`]
    /// nodes.
    pub fn for_each_chunk<A: Send, B: Send>(
        self,
        a: &mut [A],
        b: &mut [B],
        f: impl Fn(usize, &mut [A], &mut [B]) + Sync + Send,
    ) {
        if let Some(subset) = self.subset {
            for &i in subset {
                let i = i as usize;
                f(i, &mut a[i..i + 1], &mut b[i..i + 1]);
            }
            return;
        }
        if !self.parallel {
            for (c, (ca, cb)) in a.chunks_mut(CHUNK).zip(b.chunks_mut(CHUNK)).enumerate() {
                f(c * CHUNK, ca, cb);
            }
            return;
        }
        let mut job = move || {
            a.par_chunks_mut(CHUNK)
                .zip(b.par_chunks_mut(CHUNK))
                .enumerate()
                .for_each(|(c, (ca, cb))| f(c * CHUNK, ca, cb))
        };
        match self.pool {
            Some(p) => p.install(job),
            None => job(),
        }
    }

    /// Runs `f(i, &mut a[i], &mut b[i])` for every node.
    pub fn for_each_node<A: Send, B: Send>(
        self,
        a: &mut [A],
        b: &mut [B],
        f: impl Fn(usize, &mut A, &mut B) + Sync + Send,
    ) {
        self.for_each_chunk(a, b, |first, ca, cb| {
            for (k, (x, y)) in ca.iter_mut().zip(cb.iter_mut()).enumerate() {
                f(first + k, x, y);
            }
        });
    }

    /// Runs `f(i, &mut a[i], &mut b[i], &mut c[i])` for every node, in chunks of [`CHUNK`]
    /// nodes like [`Threads::for_each_chunk`].
    pub fn for_each_node3<A: Send, B: Send, C: Send>(
        self,
        a: &mut [A],
        b: &mut [B],
        c: &mut [C],
        f: impl Fn(usize, &mut A, &mut B, &mut C) + Sync + Send,
    ) {
        let chunk = |first: usize, ca: &mut [A], cb: &mut [B], cc: &mut [C]| {
            for (k, ((x, y), z)) in ca
                .iter_mut()
                .zip(cb.iter_mut())
                .zip(cc.iter_mut())
                .enumerate()
            {
                f(first + k, x, y, z);
            }
        };
        if let Some(subset) = self.subset {
            for &i in subset {
                let i = i as usize;
                chunk(i, &mut a[i..i + 1], &mut b[i..i + 1], &mut c[i..i + 1]);
            }
            return;
        }
        if !self.parallel {
            let chunks = a
                .chunks_mut(CHUNK)
                .zip(b.chunks_mut(CHUNK))
                .zip(c.chunks_mut(CHUNK));
            for (n, ((ca, cb), cc)) in chunks.enumerate() {
                chunk(n * CHUNK, ca, cb, cc);
            }
            return;
        }
        let mut job = move || {
            a.par_chunks_mut(CHUNK)
                .zip(b.par_chunks_mut(CHUNK))
                .zip(c.par_chunks_mut(CHUNK))
                .enumerate()
                .for_each(|(n, ((ca, cb), cc))| chunk(n * CHUNK, ca, cb, cc))
        };
        match self.pool {
            Some(p) => p.install(job),
            None => job(),
        }
    }

    /// Sets `out[i] = f(i)` for every node.
    pub fn map_nodes<A: Send>(self, out: &mut [A], f: impl Fn(usize) -> A + Sync + Send) {
        let mut unit = vec![(); out.len()];
        self.for_each_node(out, &mut unit, |i, o, _| *o = f(i));
    }
}
