//! The CPU backend: the reference implementation of every kernel, on one thread or on all
//! threads (rayon). Each node's force and update depend only on the previous state, so the
//! single- and multi-threaded backends give bitwise identical results.

use crate::backend::{check_range, check_rows, check_shape_write, Backend, NodeField};
use crate::error::SimError;
use crate::integrator::integrate_node;
use crate::math::{with_w, Vec4};
use crate::models::{
    debunne_meshfree, local_shape_matching, mass_spring, mls, point_based, Corotation, ShapeArray,
    ShapeInfo,
};
use crate::scene::{
    DebunneParams, MassSpringParams, Material, PointBasedParams, ShapeMatchingParams,
};
use crate::tissue::Tissue;
use glam::{Mat3, Quat};
use rayon::prelude::*;
use std::ops::Range;

/// Nodes per parallel work item.
const CHUNK: usize = 256;

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

/// Error building a thread pool.
#[derive(Debug, thiserror::Error)]
#[error("cannot create a pool of {threads} threads: {message}")]
pub struct ThreadPoolError {
    /// Threads asked for.
    pub threads: usize,
    /// The pool builder's message.
    pub message: String,
}

/// CPU backend.
pub struct CpuBackend {
    tissue: Tissue,
    pool: Option<rayon::ThreadPool>,
    parallel: bool,
    steps: u64,
}

impl CpuBackend {
    /// A backend that owns `tissue`.
    pub fn new(tissue: Tissue, threading: Threading) -> Result<CpuBackend, ThreadPoolError> {
        let (pool, parallel) = match threading {
            Threading::Single => (None, false),
            Threading::Parallel => (None, true),
            Threading::Threads(n) => {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(n)
                    .build()
                    .map_err(|e| ThreadPoolError {
                        threads: n,
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

    /// The tissue (all arrays) as it is now.
    pub fn tissue(&self) -> &Tissue {
        &self.tissue
    }

    /// Mutable access to the tissue, for drivers that edit arrays in place.
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

/// Runs `f(first, &mut a[chunk], &mut b[chunk])` over consecutive chunks of [`CHUNK`]
/// nodes, serially or in parallel.
fn for_each_chunk<A: Send, B: Send>(
    pool: Option<&rayon::ThreadPool>,
    parallel: bool,
    a: &mut [A],
    b: &mut [B],
    f: impl Fn(usize, &mut [A], &mut [B]) + Sync + Send,
) {
    if !parallel {
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
    match pool {
        Some(p) => p.install(job),
        None => job(),
    }
}

/// Runs `f(i, &mut a[i], &mut b[i])` for every node, serially or in parallel chunks.
fn for_each_node<A: Send, B: Send>(
    pool: Option<&rayon::ThreadPool>,
    parallel: bool,
    a: &mut [A],
    b: &mut [B],
    f: impl Fn(usize, &mut A, &mut B) + Sync + Send,
) {
    for_each_chunk(pool, parallel, a, b, |first, ca, cb| {
        for (k, (x, y)) in ca.iter_mut().zip(cb.iter_mut()).enumerate() {
            f(first + k, x, y);
        }
    });
}

/// Sets `out[i] = f(i)` for every node, serially or in parallel chunks.
fn map_nodes<A: Send>(
    pool: Option<&rayon::ThreadPool>,
    parallel: bool,
    out: &mut [A],
    f: impl Fn(usize) -> A + Sync + Send,
) {
    let mut unit = vec![(); out.len()];
    for_each_node(pool, parallel, out, &mut unit, |i, o, _| *o = f(i));
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
        let t = &mut self.tissue;
        let n = t.state.n_active;
        let pool = self.pool.as_ref();
        let parallel = self.parallel && n >= PARALLEL_MIN_NODES;
        let nb = &t.neighbours;
        let pos = &t.state.positions;
        let vel = &t.state.velocities;
        let forces = &mut t.state.forces[..n];
        match (&t.material, &mut t.shape) {
            (
                Material::MassSpring(MassSpringParams {
                    stiffness,
                    spring_damping,
                    ..
                }),
                ShapeInfo::MassSpring {
                    rest_length,
                    node_material,
                },
            ) => {
                let (k, c) = (*stiffness as f32, *spring_damping as f32);
                let rest_length = &rest_length[..];
                match node_material {
                    None => map_nodes(pool, parallel, forces, |i| {
                        mass_spring::force(i, pos, vel, nb, rest_length, k, c)
                    }),
                    Some(m) => map_nodes(pool, parallel, forces, |i| {
                        mass_spring::force_mixed(i, pos, vel, nb, rest_length, m)
                    }),
                }
            }
            (
                Material::LocalShapeMatching(ShapeMatchingParams {
                    stiffness,
                    rotation_iterations,
                    ..
                }),
                ShapeInfo::LocalShapeMatching {
                    rest_position,
                    shape_vector,
                    rotation,
                    cluster_centre,
                    node_material,
                },
            ) => {
                let (k, iters) = (*stiffness as f32, *rotation_iterations);
                let (rest, sv) = (&rest_position[..], &shape_vector[..]);
                let material = node_material.as_deref();
                match cluster_centre {
                    None => {
                        // With a stiffness per node: the unit-stiffness force times k_s,i
                        // (the same product as with one stiffness).
                        let k = if material.is_some() { 1.0 } else { k };
                        for_each_chunk(
                            pool,
                            parallel,
                            forces,
                            &mut rotation[..n],
                            |first, f, q| {
                                local_shape_matching::node_forces(
                                    first, f, q, pos, rest, sv, nb, k, iters,
                                );
                                if let Some(m) = material {
                                    for (o, f) in f.iter_mut().enumerate() {
                                        let k = m[first + o][0];
                                        *f = [k * f[0], k * f[1], k * f[2], 0.0];
                                    }
                                }
                            },
                        );
                    }
                    Some(centre) => {
                        for_each_node(
                            pool,
                            parallel,
                            &mut centre[..n],
                            &mut rotation[..n],
                            |i, c, q| {
                                let (c_i, q_i) = local_shape_matching::cluster_frame(
                                    i,
                                    pos,
                                    rest,
                                    sv[i],
                                    nb,
                                    iters,
                                    Quat::from_array(*q),
                                );
                                *c = with_w(c_i, 0.0);
                                *q = q_i.to_array();
                            },
                        );
                        let (centre, rotation) = (&centre[..], &rotation[..]);
                        map_nodes(pool, parallel, forces, |j| match material {
                            None => local_shape_matching::cluster_force(
                                j, pos, rest, sv, nb, k, centre, rotation,
                            ),
                            Some(m) => local_shape_matching::cluster_force_mixed(
                                j, pos, rest, sv, nb, m, centre, rotation,
                            ),
                        });
                    }
                }
            }
            (
                Material::DebunneMeshfree(DebunneParams {
                    rotation_iterations,
                    ..
                }),
                ShapeInfo::DebunneMeshfree {
                    rest_position,
                    inverse_moment,
                    first_pass,
                    corotation,
                    node_material,
                    ..
                },
            ) => {
                let c = mls::ContinuumConstants::of(&t.material).expect("Debunne material");
                let one = [c.lambda, c.mu, c.hourglass, 0.0];
                let material = node_material.as_deref();
                // `[lambda, mu, alpha mu]` of node i.
                let constants = |i: usize| material.map_or(one, |m| m[i]);
                let (rest, a_inv) = (&rest_position[..], &inverse_moment[..]);
                match corotation {
                    None => {
                        map_nodes(pool, parallel, &mut first_pass[..n], |i| {
                            let [lambda, mu, hg, _] = constants(i);
                            debunne_meshfree::first_pass(
                                i, pos, rest, nb, &a_inv[i], rest[i][3], lambda, mu, hg, None,
                            )
                        });
                    }
                    Some(Corotation {
                        shape_vector,
                        rotation,
                    }) => {
                        let (sv, iters) = (&shape_vector[..], *rotation_iterations);
                        for_each_node(
                            pool,
                            parallel,
                            &mut first_pass[..n],
                            &mut rotation[..n],
                            |i, q, rot| {
                                let (_, r) = local_shape_matching::cluster_frame(
                                    i,
                                    pos,
                                    rest,
                                    sv[i],
                                    nb,
                                    iters,
                                    Quat::from_array(*rot),
                                );
                                *rot = r.to_array();
                                let [lambda, mu, hg, _] = constants(i);
                                *q = debunne_meshfree::first_pass(
                                    i,
                                    pos,
                                    rest,
                                    nb,
                                    &a_inv[i],
                                    rest[i][3],
                                    lambda,
                                    mu,
                                    hg,
                                    Some(&Mat3::from_quat(r)),
                                );
                            },
                        );
                    }
                }
                let first = &first_pass[..];
                map_nodes(pool, parallel, forces, |i| {
                    mls::gather_force(i, pos, rest, nb, first)
                });
            }
            (
                Material::PointBased(PointBasedParams { .. }),
                ShapeInfo::PointBased {
                    rest_position,
                    inverse_moment,
                    first_pass,
                    node_material,
                    ..
                },
            ) => {
                let c = mls::ContinuumConstants::of(&t.material).expect("point based material");
                let material = node_material.as_deref();
                let (rest, a_inv) = (&rest_position[..], &inverse_moment[..]);
                map_nodes(pool, parallel, &mut first_pass[..n], |i| {
                    let c = material.map_or(c, |m| mls::ContinuumConstants::from_row(m[i]));
                    point_based::first_pass(i, pos, rest, nb, &a_inv[i], rest[i][3], &c)
                });
                let first = &first_pass[..];
                map_nodes(pool, parallel, forces, |i| {
                    mls::gather_force(i, pos, rest, nb, first)
                });
            }
            (m, s) => unreachable!("material {m:?} built with shape info {:?}", s.arrays()),
        }
    }

    fn integrate(&mut self) {
        let t = &mut self.tissue;
        let n = t.state.n_active;
        let params = t.step;
        let forces = &t.state.forces;
        for_each_node(
            self.pool.as_ref(),
            self.parallel && n >= PARALLEL_MIN_NODES,
            &mut t.state.positions[..n],
            &mut t.state.velocities[..n],
            |i, x, v| integrate_node(x, v, forces[i], &params),
        );
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
        let src = match field {
            NodeField::Position => &self.tissue.state.positions,
            NodeField::Velocity => &self.tissue.state.velocities,
            NodeField::Force => &self.tissue.state.forces,
        };
        out.copy_from_slice(&src[range]);
        Ok(())
    }

    fn write(&mut self, field: NodeField, first: usize, data: &[Vec4]) -> Result<(), SimError> {
        let range = first..first + data.len();
        check_range(&range, self.capacity(), "allocated")?;
        let dst = match field {
            NodeField::Position => &mut self.tissue.state.positions,
            NodeField::Velocity => &mut self.tissue.state.velocities,
            NodeField::Force => &mut self.tissue.state.forces,
        };
        dst[range].copy_from_slice(data);
        Ok(())
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
