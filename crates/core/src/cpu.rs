//! The CPU backend: the reference implementation of every kernel, on one thread or on all
//! threads (rayon). Each node's force and update depend only on the previous state, so the
//! single- and multi-threaded backends give bitwise identical results.

use crate::backend::{check_range, check_rows, check_shape_write, Backend, NodeField};
use crate::error::SimError;
use crate::frame::PositionFrame;
use crate::integrator::integrate_node;
use crate::math::Vec4;
use crate::models::ShapeArray;
use crate::parallel::Threads;
use crate::tissue::Tissue;
use std::ops::Range;

/// Below this many active nodes a multi-threaded backend steps on the calling thread: a
/// step is then tens of microseconds, about what waking the pool costs. Measured on the
/// 2-core development machine (mass-spring / shape matching, ms per step, 1 vs 2 threads):
/// 216 nodes 0.012 vs 0.068; 729 nodes 0.041 vs 0.048-0.089 and 0.10 vs 0.09; 1,728
/// nodes 0.08-0.09 vs 0.08-0.09 and 0.19-0.22 vs 0.18-0.19. Results do not depend on it
/// (each node's arithmetic is the same on any thread).
pub const PARALLEL_MIN_NODES: usize = 1024;

/// How the CPU backend uses threads.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Threading {
    /// One thread.
    Single,
    /// rayon's global pool (all hardware threads).
    #[default]
    Parallel,
    /// A pool of exactly this many threads, owned by the backend.
    Threads(usize),
}

/// Most threads a CPU backend may use ([`Threading::Threads`], and `RAYON_NUM_THREADS`
/// for [`Threading::Parallel`]). Each thread takes a stack and a share of every step's
/// synchronisation: past the machine's cores more threads only cost, and a count far
/// beyond any machine is a typing error (5,000 threads made rayon's pool panic or the
/// process abort, 100,000 took a minute to fail). 1,024 is above the hardware threads of
/// the largest machines this runs on.
pub const MAX_THREADS: usize = 1024;

/// Error building a thread pool.
#[derive(Debug, thiserror::Error)]
#[error("cannot create a thread pool{}{}: {message}",
    if *threads > 0 { format!(" of {threads} threads") } else { String::new() },
    match source_name {
        Some(s) => format!(" (from {s})"),
        None => String::new(),
    }
)]
pub struct ThreadPoolError {
    /// Threads asked for (0 when the count could not be read: `RAYON_NUM_THREADS=abc`
    /// said "a pool of 0 threads").
    pub threads: usize,
    /// Where the count came from when not from the caller (`RAYON_NUM_THREADS`).
    pub source_name: Option<&'static str>,
    /// The pool builder's message.
    pub message: String,
}

/// The thread count `RAYON_NUM_THREADS` asks rayon's global pool for, checked against
/// [`MAX_THREADS`] before the pool exists (rayon panics when it cannot build it). `Ok(None)`
/// when it is unset, empty or 0 (rayon then uses every hardware thread).
fn global_pool_threads() -> Result<Option<usize>, ThreadPoolError> {
    const VAR: &str = "RAYON_NUM_THREADS";
    let Ok(text) = std::env::var(VAR) else {
        return Ok(None);
    };
    if text.trim().is_empty() {
        return Ok(None);
    }
    match text.trim().parse::<usize>() {
        Ok(0) => Ok(None),
        Ok(n) if n <= MAX_THREADS => Ok(Some(n)),
        Ok(n) => Err(ThreadPoolError {
            threads: n,
            source_name: Some(VAR),
            message: format!("at most {MAX_THREADS} threads"),
        }),
        Err(_) => Err(ThreadPoolError {
            threads: 0,
            source_name: Some(VAR),
            message: format!("{text:?} is not a thread count"),
        }),
    }
}

/// Checks a thread count before a pool is built: 1 to [`MAX_THREADS`].
pub fn check_threads(n: usize) -> Result<(), ThreadPoolError> {
    if (1..=MAX_THREADS).contains(&n) {
        Ok(())
    } else {
        Err(ThreadPoolError {
            threads: n,
            source_name: None,
            message: format!("the count must be 1 to {MAX_THREADS}"),
        })
    }
}

/// CPU backend.
pub struct CpuBackend {
    tissue: Tissue,
    pool: Option<rayon::ThreadPool>,
    parallel: bool,
    steps: u64,
}

impl CpuBackend {
    /// The model's forces on every active node, or on `subset` (serially).
    fn forces_with(&mut self, parallel: bool, subset: Option<&[u32]>) {
        let n = self.tissue.state.n_active;
        let threads = Threads::all(self.pool.as_ref(), parallel).with_subset(subset);
        let t = &mut self.tissue;
        let s = &mut t.state;
        t.shape.cpu_forces(
            &s.positions,
            &s.velocities,
            &t.neighbours,
            n,
            threads,
            t.step.dt,
            &mut s.forces,
        );
    }

    /// A backend that owns `tissue` (positions in its frame, [`Tissue::frame`]).
    pub fn new(tissue: Tissue, threading: Threading) -> Result<CpuBackend, ThreadPoolError> {
        let (pool, parallel) = match threading {
            Threading::Single => (None, false),
            Threading::Parallel => {
                global_pool_threads()?;
                (None, true)
            }
            Threading::Threads(n) => {
                check_threads(n)?;
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(n)
                    .build()
                    .map_err(|e| ThreadPoolError {
                        threads: n,
                        source_name: None,
                        message: e.to_string(),
                    })?;
                (Some(pool), n > 1)
            }
        };
        Ok(CpuBackend {
            tissue,
            pool,
            parallel,
            steps: 0,
        })
    }

    /// The tissue (all arrays) as it is now; its positions are in its frame
    /// ([`Tissue::frame`]), the world's for a body near the origin.
    pub fn tissue(&self) -> &Tissue {
        &self.tissue
    }

    /// Mutable access to the tissue, for drivers that edit arrays in place (positions in
    /// [`Tissue::frame`]).
    pub fn tissue_mut(&mut self) -> &mut Tissue {
        &mut self.tissue
    }

    /// Threads used per step.
    pub fn threads(&self) -> usize {
        match (&self.pool, self.parallel) {
            (_, false) => 1,
            (Some(p), true) => p.current_num_threads(),
            (None, true) => rayon::current_num_threads(),
        }
    }
}

impl Backend for CpuBackend {
    fn name(&self) -> String {
        match self.threads() {
            1 => "cpu (1 thread)".into(),
            n => format!("cpu-parallel ({n} threads)"),
        }
    }

    fn capacity(&self) -> usize {
        self.tissue.state.capacity()
    }

    fn n_active(&self) -> usize {
        self.tissue.state.n_active
    }

    fn set_n_active(&mut self, n: usize) -> Result<(), SimError> {
        check_range(&(0..n), self.capacity(), "allocated")?;
        self.tissue.state.n_active = n;
        Ok(())
    }

    fn compute_forces(&mut self) {
        let n = self.tissue.state.n_active;
        self.forces_with(self.parallel && n >= PARALLEL_MIN_NODES, None);
    }

    fn compute_forces_on(&mut self, nodes: &[u32]) {
        let n = self.tissue.state.n_active;
        let mut subset: Vec<u32> = nodes
            .iter()
            .copied()
            .filter(|&i| (i as usize) < n)
            .collect();
        subset.sort_unstable();
        subset.dedup();
        // A few nodes and their ring: not worth a parallel dispatch.
        self.forces_with(false, Some(&subset));
    }

    fn integrate(&mut self) {
        let n = self.tissue.state.n_active;
        let threads = Threads::all(self.pool.as_ref(), self.parallel && n >= PARALLEL_MIN_NODES);
        let t = &mut self.tissue;
        let params = t.step;
        let s = &mut t.state;
        let forces = &s.forces;
        threads.for_each_node3(
            &mut s.positions[..n],
            &mut s.velocities[..n],
            &mut s.position_remainders[..n],
            |i, x, v, r| integrate_node(x, v, r, forces[i], &params),
        );
        t.shape.end_step();
        self.steps += 1;
    }

    fn steps_taken(&self) -> u64 {
        self.steps
    }

    fn set_steps_taken(&mut self, steps: u64) {
        self.steps = steps;
    }

    fn read(
        &mut self,
        field: NodeField,
        range: Range<usize>,
        out: &mut [Vec4],
    ) -> Result<(), SimError> {
        check_range(&range, self.capacity(), "allocated")?;
        let s = &self.tissue.state;
        let src = match field {
            NodeField::Position | NodeField::StoredPosition => &s.positions,
            NodeField::Velocity => &s.velocities,
            NodeField::Force => &s.forces,
            NodeField::PositionRemainder | NodeField::StoredRemainder => &s.position_remainders,
        };
        out.copy_from_slice(&src[range.clone()]);
        match field {
            NodeField::Position => self.tissue.frame.positions_to_world(out),
            NodeField::PositionRemainder => self
                .tissue
                .frame
                .remainders_to_world(out, &s.positions[range]),
            NodeField::Velocity
            | NodeField::Force
            | NodeField::StoredPosition
            | NodeField::StoredRemainder => {}
        }
        Ok(())
    }

    fn write(&mut self, field: NodeField, first: usize, data: &[Vec4]) -> Result<(), SimError> {
        let range = first..first + data.len();
        check_range(&range, self.capacity(), "allocated")?;
        let s = &mut self.tissue.state;
        let dst = match field {
            NodeField::Position => {
                s.position_remainders[range.clone()].fill([0.0; 4]);
                &mut s.positions
            }
            NodeField::StoredPosition => &mut s.positions,
            NodeField::Velocity => &mut s.velocities,
            NodeField::Force => &mut s.forces,
            NodeField::PositionRemainder | NodeField::StoredRemainder => &mut s.position_remainders,
        };
        dst[range.clone()].copy_from_slice(data);
        if field == NodeField::Position {
            self.tissue.frame.slice_to_frame(&mut dst[range]);
        }
        Ok(())
    }

    fn position_frame(&self) -> PositionFrame {
        self.tissue.frame
    }

    fn write_neighbour_rows(
        &mut self,
        first: usize,
        index: &[u32],
        weight: &[f32],
    ) -> Result<(), SimError> {
        let k = self.tissue.neighbours.k;
        let rows = check_rows(first, index, weight, k, self.capacity())?;
        let nb = &mut self.tissue.neighbours;
        nb.index[first * k..rows.end * k].copy_from_slice(index);
        nb.weight[first * k..rows.end * k].copy_from_slice(weight);
        Ok(())
    }

    fn write_shape_bytes(
        &mut self,
        array: ShapeArray,
        offset: usize,
        data: &[u8],
    ) -> Result<(), SimError> {
        let mut arrays = self.tissue.shape.bytes_mut();
        let target = arrays.iter_mut().find(|(n, _)| *n == array);
        check_shape_write(
            array,
            offset,
            data.len(),
            target.as_ref().map(|(_, b)| b.len()),
        )?;
        if let Some((_, bytes)) = target {
            bytes[offset..offset + data.len()].copy_from_slice(data);
        }
        Ok(())
    }

    fn read_shape_bytes(
        &mut self,
        array: ShapeArray,
        offset: usize,
        out: &mut [u8],
    ) -> Result<(), SimError> {
        let arrays = self.tissue.shape.bytes();
        let source = arrays.iter().find(|(n, _)| *n == array);
        check_shape_write(array, offset, out.len(), source.map(|(_, b)| b.len()))?;
        if let Some((_, bytes)) = source {
            out.copy_from_slice(&bytes[offset..offset + out.len()]);
        }
        Ok(())
    }
}
