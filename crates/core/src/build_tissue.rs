//! Builds a [`Tissue`] from a scene: the node cloud ([`crate::geometry`]), the simulation
//! arrays (`Tissue::assemble`), then `physics.dt = "auto"`: [`AUTO_DT_SAFETY`] times the
//! critical time step that [`crate::stability::max_eigenvalue`] estimates on a CPU probe of
//! the tissue at its initial state, and at most half the inverse frequency of a far-field
//! face's stiffest spring ([`crate::boundary`]).

use crate::cpu::{CpuBackend, Threading};
use crate::error::SceneError;
use crate::geometry::{self, NodeCloud};
use crate::integrator::StepParams;
use crate::scene::{Scene, TimeStep, AUTO_DT_SAFETY};
use crate::tissue::{Tissue, EXTRA_KEY};

impl Tissue {
    /// Builds the tissue a scene describes, with no room for extra (needle) nodes.
    pub fn from_scene(scene: &Scene) -> Result<Tissue, SceneError> {
        Self::from_scene_with_capacity(scene, 0)
    }

    /// Builds the tissue with `extra` spare node slots after the mesh nodes. The memory
    /// estimate ([`geometry::check_memory`]) is checked before the nodes are allocated.
    pub fn from_scene_with_capacity(scene: &Scene, extra: usize) -> Result<Tissue, SceneError> {
        let cloud = geometry::build_checked(scene, extra as f64, EXTRA_KEY)?;
        Self::from_cloud(scene, cloud, extra)
    }

    /// Builds the tissue from an already built node cloud. The memory estimate of its
    /// nodes and the `extra` slots is checked before the simulation arrays are allocated.
    pub fn from_cloud(scene: &Scene, cloud: NodeCloud, extra: usize) -> Result<Tissue, SceneError> {
        let mut tissue = Tissue::assemble(scene, cloud, extra)?;
        if scene.physics.dt == TimeStep::Auto {
            // At most the step the far-field faces' springs take (crate::boundary).
            let spring = tissue.boundary.far_field_frequency();
            let mut dt = auto_dt(&tissue)?;
            if spring > 0.0 {
                dt = dt.min(0.5 / spring);
            }
            tissue.step = StepParams::new(dt, &scene.physics);
        }
        tissue.boundary.check_far_field(tissue.step.dt as f64)?;
        Ok(tissue)
    }
}

impl Tissue {
    /// The largest stable time step of this tissue at its initial state, s
    /// ([`crate::stability::max_eigenvalue`] on a CPU copy, 40 power iterations: the
    /// probe of `dt = "auto"`; with a viscous material also
    /// [`crate::stability::max_damping_eigenvalue`], combined by
    /// [`crate::stability::damped_critical_dt`]); infinite when no free node feels an
    /// elastic force.
    pub fn critical_dt(&self) -> Result<f64, SceneError> {
        let mut probe = CpuBackend::new(self.clone(), Threading::Parallel)
            .map_err(|e| SceneError::invalid("physics.dt", e.to_string()))?;
        let err = |e: crate::SimError| SceneError::invalid("physics.dt", e.to_string());
        let est = crate::stability::max_eigenvalue(&mut probe, 40).map_err(err)?;
        if !self.shape.viscous() {
            return Ok(est.critical_dt);
        }
        // A viscous material's dashpot, taken explicitly, shortens the stable step.
        let c = crate::stability::max_damping_eigenvalue(&mut probe, 40).map_err(err)?;
        Ok(crate::stability::damped_critical_dt(est.max_eigenvalue, c))
    }
}

/// [`AUTO_DT_SAFETY`] times the critical time step of `tissue` at its initial state.
fn auto_dt(tissue: &Tissue) -> Result<f64, SceneError> {
    let critical_dt = tissue.critical_dt()?;
    if !critical_dt.is_finite() {
        return Err(SceneError::invalid(
            "physics.dt",
            "\"auto\" needs a stiffness to size the step from (no free node feels an elastic \
             force); give the step in seconds",
        ));
    }
    Ok(AUTO_DT_SAFETY * critical_dt)
}
