//! The tissue stepper: what every run does around the backend's force evaluation and
//! integration, with or without a needle.
//!
//! One step: forces (the backend, then whatever a caller adds, such as the needle's
//! friction), surface loads at `t`, far-field faces, integration, `t += dt`, the held sets
//! projected at the new `t`, and every `physics.check_every` steps the divergence guard.
//! Without loads, prescribed motion or far-field faces the steps between two guards go to
//! the backend as one batch (the GPU backend queues a batch without waiting).

use crate::backend::{check_arrays, Backend};
use crate::boundary::{Boundary, Reaction};
use crate::error::SimError;
use crate::integrator::StepParams;
use crate::math::Vec4;
use crate::scene::Physics;
use crate::tissue::Tissue;

/// Clock, held sets and divergence guard of a tissue run.
#[derive(Debug, Clone)]
pub struct Stepper {
    params: StepParams,
    boundary: Boundary,
    max_speed: f64,
    check_every: u64,
    time: f64,
    steps: u64,
}

impl Stepper {
    /// A stepper at `t = 0` for `tissue` with the guard of `physics` (`max_speed`,
    /// `check_every`; the time step is the tissue's, `"auto"` already resolved).
    pub fn new(tissue: &Tissue, physics: &Physics) -> Stepper {
        Stepper {
            params: tissue.step,
            boundary: tissue.boundary.clone(),
            max_speed: physics.max_speed,
            check_every: physics.check_every.max(1),
            time: 0.0,
            steps: 0,
        }
    }

    /// Puts the prescribed displacements at their `t = 0` values (a ramp starts at zero).
    pub fn start(&self, backend: &mut dyn Backend) -> Result<(), SimError> {
        self.boundary.project(backend, self.time)
    }

    /// Runs `n` whole steps of the tissue alone.
    pub fn run(&mut self, backend: &mut dyn Backend, n: u64) -> Result<(), SimError> {
        if self.boundary.acts_each_step() {
            for _ in 0..n {
                backend.compute_forces();
                self.finish_step(backend)?;
            }
            return Ok(());
        }
        let mut left = n;
        while left > 0 {
            let batch = left.min(self.check_every - self.steps % self.check_every);
            backend.step(batch);
            self.time += batch as f64 * self.params.dt as f64;
            self.steps += batch;
            left -= batch;
            if self.steps.is_multiple_of(self.check_every) {
                self.check(backend)?;
            }
        }
        Ok(())
    }

    /// The second half of a step, once the forces are in: surface loads, integration, the
    /// clock, the held sets' projection and (every `check_every` steps) the guard.
    pub fn finish_step(&mut self, backend: &mut dyn Backend) -> Result<(), SimError> {
        self.boundary.apply_loads(backend, self.time)?;
        self.boundary.apply_far_field(backend, &self.params)?;
        backend.integrate();
        self.time += self.params.dt as f64;
        self.steps += 1;
        self.boundary.project(backend, self.time)?;
        if self.steps.is_multiple_of(self.check_every) {
            self.check(backend)?;
        }
        Ok(())
    }

    /// The divergence guard's speed bound, `physics.max_speed`, m/s.
    pub fn max_speed(&self) -> f64 {
        self.max_speed
    }

    /// The divergence guard, reading positions and velocities back from the backend.
    pub fn check(&self, backend: &mut dyn Backend) -> Result<(), SimError> {
        backend.guard(self.max_speed)
    }

    /// The divergence guard on positions and velocities already read back (an output
    /// frame): an error names the first non-finite value, or the fastest free node
    /// (inverse mass > 0) when it is faster than `physics.max_speed`.
    pub fn check_read(
        &self,
        step: u64,
        positions: &[Vec4],
        velocities: &[Vec4],
    ) -> Result<(), SimError> {
        check_arrays(step, positions, velocities, self.max_speed)
    }

    /// The force each held set's supports exert on the body, from the last step's forces.
    pub fn reactions(&self, backend: &mut dyn Backend) -> Result<Vec<Reaction>, SimError> {
        let g = self.params.gravity.map(|g| g as f64);
        self.boundary.reactions(backend, g)
    }

    /// Whether the stepper must see every step (loads, prescribed motion or far-field
    /// faces).
    pub fn acts_each_step(&self) -> bool {
        self.boundary.acts_each_step()
    }

    /// The held sets and loads.
    pub fn boundary(&self) -> &Boundary {
        &self.boundary
    }

    /// Integration parameters (time step, gravity, damping).
    pub fn params(&self) -> &StepParams {
        &self.params
    }

    /// Time step, s.
    pub fn dt(&self) -> f64 {
        self.params.dt as f64
    }

    /// Simulated time, s.
    pub fn time(&self) -> f64 {
        self.time
    }

    /// Steps taken.
    pub fn steps(&self) -> u64 {
        self.steps
    }

    /// Sets the clock (a run restored from a checkpoint).
    pub fn set_clock(&mut self, time: f64, steps: u64) {
        self.time = time;
        self.steps = steps;
    }
}
