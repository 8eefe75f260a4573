//! Building the simulated tissue from a scene: node cloud, masses, fixed nodes,
//! neighbours, the chosen model's shape information and the initial deformation.

use crate::error::{GeometryError, SceneError};
use crate::geometry::{self, NodeCloud};
use crate::math::Vec4;
use crate::models::{ArrayInfo, ShapeInfo};
use crate::neighbours::Neighbours;
use crate::scene::{MassSpringParams, Material, Scene, SpringShare, TimeStep, AUTO_DT_SAFETY};
use crate::state::NodeState;

/// Everything a backend needs to simulate the tissue.
#[derive(Debug, Clone, PartialEq)]
pub struct Tissue {
    /// Positions, velocities, forces.
    pub state: NodeState,
    /// Neighbour rows.
    pub neighbours: Neighbours,
    /// The model's shape information.
    pub shape: ShapeInfo,
    /// Surface triangles over the mesh nodes.
    pub triangles: Vec<[u32; 3]>,
    /// Nodes of the original mesh (needle nodes come after them).
    pub n_mesh: usize,
    /// Material model and parameters.
    pub material: Material,
    /// Time-stepping parameters.
    pub step: crate::integrator::StepParams,
    /// Mass of one node in kg.
    pub node_mass: f64,
    /// Volume enclosed by the surface in m^3.
    pub volume: f64,
    /// Number of fixed nodes.
    pub n_fixed: usize,
}

impl Tissue {
    /// Builds the tissue a scene describes, with no room for extra (needle) nodes.
    pub fn from_scene(scene: &Scene) -> Result<Tissue, SceneError> {
        Self::from_scene_with_capacity(scene, 0)
    }

    /// Builds the tissue with `extra` spare node slots after the mesh nodes.
    pub fn from_scene_with_capacity(scene: &Scene, extra: usize) -> Result<Tissue, SceneError> {
        let cloud = geometry::build(&scene.tissue.geometry, &scene.base_dir)?;
        Self::from_cloud(scene, cloud, extra)
    }

    /// Builds the tissue from an already built node cloud.
    pub fn from_cloud(scene: &Scene, cloud: NodeCloud, extra: usize) -> Result<Tissue, SceneError> {
        let n = cloud.positions.len();
        let k = scene.tissue.neighbours;
        if n < k + 1 {
            return Err(GeometryError::TooFewNodes {
                nodes: n,
                neighbours: k,
            }
            .into());
        }
        let capacity = n + extra;
        let mut neighbours = Neighbours::build(&cloud.positions, k, scene.tissue.weight, capacity);
        if let Material::MassSpring(MassSpringParams {
            spring_share: SpringShare::Cell,
            ..
        }) = scene.material
        {
            crate::models::mass_spring::apply_cell_shares(
                &mut neighbours,
                &cloud.node_volumes,
                cloud.spacing,
                n,
            );
        }
        let node_mass = scene.tissue.density * cloud.volume / n as f64;
        let mut fixed = vec![false; n];
        for (s, sel) in scene.fixed.iter().enumerate() {
            let mut any = false;
            for (i, p) in cloud.positions.iter().enumerate() {
                if sel.contains(*p) {
                    fixed[i] = true;
                    any = true;
                }
            }
            if !any {
                return Err(SceneError::invalid(
                    format!("fixed[{s}]"),
                    "selects no node (check the axis and the coordinate against the geometry's bounds)",
                ));
            }
        }
        let n_fixed = fixed.iter().filter(|&&f| f).count();
        let inv_mass = (1.0 / node_mass) as f32;
        let mut rest: Vec<Vec4> = cloud
            .positions
            .iter()
            .map(|p| [p[0] as f32, p[1] as f32, p[2] as f32, 0.0])
            .collect();
        rest.resize(capacity, [0.0; 4]);
        let shape = ShapeInfo::build(
            &scene.material,
            &rest,
            &neighbours,
            n,
            crate::models::BuildContext {
                triangles: &cloud.triangles,
                volume: cloud.volume,
                node_volumes: &cloud.node_volumes,
            },
        );

        // Initial deformation: scale the free nodes about their centroid.
        let free: Vec<usize> = (0..n).filter(|&i| !fixed[i]).collect();
        let mut centre = [0.0f64; 3];
        for &i in &free {
            for a in 0..3 {
                centre[a] += cloud.positions[i][a] / free.len().max(1) as f64;
            }
        }
        let s = scene.initial.stretch;
        let positions: Vec<Vec4> = (0..n)
            .map(|i| {
                let p = cloud.positions[i];
                if fixed[i] {
                    [p[0] as f32, p[1] as f32, p[2] as f32, 0.0]
                } else if s == [1.0; 3] {
                    [p[0] as f32, p[1] as f32, p[2] as f32, inv_mass]
                } else {
                    let q: [f64; 3] =
                        std::array::from_fn(|a| centre[a] + s[a] * (p[a] - centre[a]));
                    [q[0] as f32, q[1] as f32, q[2] as f32, inv_mass]
                }
            })
            .collect();
        let mut tissue = Tissue {
            state: NodeState::new(positions, capacity),
            neighbours,
            shape,
            triangles: cloud.triangles,
            n_mesh: n,
            material: scene.material,
            step: crate::integrator::StepParams::new(1e-3, &scene.physics),
            node_mass,
            volume: cloud.volume,
            n_fixed,
        };
        let dt = match scene.physics.dt {
            TimeStep::Seconds(dt) => dt,
            TimeStep::Auto => {
                let mut probe =
                    crate::cpu::CpuBackend::new(tissue.clone(), crate::cpu::Threading::Parallel)
                        .map_err(|e| SceneError::invalid("physics.dt", e.to_string()))?;
                let est = crate::stability::max_eigenvalue(&mut probe, 40)
                    .map_err(|e| SceneError::invalid("physics.dt", e.to_string()))?;
                if !est.critical_dt.is_finite() {
                    return Err(SceneError::invalid(
                        "physics.dt",
                        "\"auto\" needs a stiffness to size the step from (no free node \
                         feels an elastic force); give the step in seconds",
                    ));
                }
                AUTO_DT_SAFETY * est.critical_dt
            }
        };
        tissue.step = crate::integrator::StepParams::new(dt, &scene.physics);
        Ok(tissue)
    }

    /// Every simulation array with its size in bytes: node state, neighbours, then the
    /// model's shape information.
    pub fn allocations(&self) -> Vec<ArrayInfo> {
        fn bytes<T>(v: &[T]) -> usize {
            std::mem::size_of_val(v)
        }
        let mut out = vec![
            ArrayInfo {
                name: "position",
                bytes: bytes(&self.state.positions),
            },
            ArrayInfo {
                name: "velocity",
                bytes: bytes(&self.state.velocities),
            },
            ArrayInfo {
                name: "force",
                bytes: bytes(&self.state.forces),
            },
            ArrayInfo {
                name: "neighbour_index",
                bytes: bytes(&self.neighbours.index),
            },
            ArrayInfo {
                name: "neighbour_weight",
                bytes: bytes(&self.neighbours.weight),
            },
        ];
        out.extend(self.shape.arrays());
        out
    }
}
