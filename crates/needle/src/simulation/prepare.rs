//! Preparing a needle scene: the tissue with slots for the needle nodes, the needle's
//! parameters resolved against the mesh (node spacing, grip), then the start on a backend.

use super::{NeedleParams, RegionParams, Simulation};
use crate::checkpoint::{fingerprint, Checkpoint};
use crate::config::Membrane;
use crate::config::NeedleConfig;
use crate::friction::{grip_from_modulus, FrictionModel};
use crate::needle::Needle;
use crate::node_editor::NodeEditor;
use crate::splits::{inside_rest_body, rest_crossings, SurfaceSplits};
use crate::state::NeedleState;
use crate::SimulationError;
use needlesim_core::scene::{Material, Physics};
use needlesim_core::{geometry, Backend, Scene, SceneError, Stepper, Tissue};

/// A tissue built for a needle scene, waiting for a backend.
pub struct Prepared {
    /// The tissue with needle node slots; give it to a backend.
    pub tissue: Tissue,
    editor: NodeEditor,
    config: Option<NeedleConfig>,
    spacing: f64,
    regions: Vec<RegionParams>,
    rest: Vec<[f64; 3]>,
    physics: Physics,
    fingerprint: Vec<(String, u32)>,
}

impl Prepared {
    /// Starts the simulation on `backend` (built from [`Prepared::tissue`]) in the state of
    /// `checkpoint`, taken from a simulation of the same scene; a checkpoint of another
    /// scene is [`crate::CheckpointError::SceneMismatch`]. On the CPU backends the run then
    /// continues bitwise as the checkpointed one would have.
    pub fn resume(
        self,
        backend: Box<dyn Backend>,
        checkpoint: Checkpoint,
    ) -> Result<Simulation, SimulationError> {
        let mut sim = self.start(backend)?;
        sim.restore(checkpoint)?;
        Ok(sim)
    }

    /// Starts the simulation on `backend`, which must have been built from
    /// [`Prepared::tissue`].
    pub fn start(self, mut backend: Box<dyn Backend>) -> Result<Simulation, SimulationError> {
        if backend.capacity() != self.tissue.state.capacity() {
            return Err(SimulationError::BackendMismatch {
                expected: self.tissue.state.capacity(),
                got: backend.capacity(),
            });
        }
        let triangles = self.tissue.triangles.clone();
        let (needle, script, contact) = match &self.config {
            Some(c) => (
                Some(c.start()?),
                c.script().ok().flatten(),
                NeedleParams {
                    friction: c.friction,
                    regions: self.regions.clone(),
                    thresholds: c.thresholds,
                    puncture_force: c.puncture_force,
                    refresh: c.tip_refresh * self.spacing,
                    radius: c.radius,
                    point_length: c.point_length(),
                    tear_time: c.tear_time(),
                    relaxation: self.tissue.material.prony(),
                },
            ),
            None => (
                None,
                None,
                NeedleParams {
                    friction: FrictionModel::default(),
                    regions: self.regions.clone(),
                    thresholds: Default::default(),
                    puncture_force: None,
                    refresh: 0.1 * self.spacing,
                    radius: crate::config::RADIUS_18G,
                    point_length: crate::config::default_point_length(crate::config::RADIUS_18G),
                    tear_time: 0.01,
                    relaxation: self.tissue.material.prony(),
                },
            ),
        };
        if let Some(n) = &needle {
            check_start_outside(&self.rest, &triangles, n)?;
        }
        let stepper = Stepper::new(&self.tissue, &self.physics);
        // Prescribed displacements hold from the start (a ramp starts at zero).
        stepper.start(backend.as_mut())?;
        let surface = SurfaceSplits::new(triangles, &self.rest, 2.0 * self.spacing);
        let regions = &self.tissue.regions;
        let (node_region, region_names) = (regions.of_node.clone(), regions.names.clone());
        let region_inv_mass = regions.node_mass.iter().map(|m| (1.0 / m) as f32).collect();
        Ok(Simulation {
            region_inv_mass,
            node_region,
            region_names,
            backend,
            stepper,
            editor: self.editor,
            script,
            params: contact,
            spacing: self.spacing,
            rest: self.rest,
            state: NeedleState::new(needle, surface),
            fingerprint: self.fingerprint,
            low_water: 0,
        })
    }
}

/// Errs when the start pose has the tip or the base inside the body (one oriented-mesh
/// query for both, [`inside_rest_body`]) or the shaft crossing its surface, on the rest
/// surface.
fn check_start_outside(
    rest: &[[f64; 3]],
    triangles: &[[u32; 3]],
    n: &Needle,
) -> Result<(), SimulationError> {
    let (base, tip) = (n.base(), n.tip());
    let inside = inside_rest_body(rest, triangles, &[tip, base]);
    for ((what, p), inside) in [("tip", tip), ("base", base)].into_iter().zip(inside) {
        if inside {
            return Err(SimulationError::StartsInside {
                what,
                point: p,
                where_: "inside the body",
            });
        }
    }
    let first = rest_crossings(rest, triangles, base, tip)
        .into_iter()
        .min_by(f64::total_cmp);
    if let Some(t) = first {
        return Err(SimulationError::StartsInside {
            what: "shaft",
            point: std::array::from_fn(|a| base[a] + t * (tip[a] - base[a])),
            where_: "crossing the surface",
        });
    }
    Ok(())
}

/// Young's modulus and Poisson ratio of `material`, Pa
/// ([`needlesim_core::models::TissueModel::elastic_moduli`]): for mass-spring and shape
/// matching, the modulus their calibrated stiffness gives at the mesh spacing `h` and the
/// Poisson ratio their lattices show (mass-spring about 1/4, cluster shape matching about
/// 0: docs/report). `key` names the needle table that needs it, for the error when the
/// neighbour count has no calibration.
fn resolve_modulus(
    scene: &Scene,
    material: &Material,
    h: f64,
    key: &str,
) -> Result<(f64, f64), SceneError> {
    let uncalibrated = |e: needlesim_core::calibration::UncalibratedNeighbours| {
        SceneError::invalid(
            format!("{key}.grip"),
            format!(
                "cannot be derived from this material's stiffness ({e}); give the grip (N/m) \
                 and the shear stiffness (N/m^2)"
            ),
        )
    };
    material
        .elastic_moduli(h, scene.tissue.neighbours)
        .map_err(uncalibrated)
}

/// The grip per unit length (N/m), the sheath's shear stiffness and viscous coefficient
/// per unit length (N/m^2, N s/m^2) of the per-length friction model `friction` in a
/// region of `material`: the given values, or from the material's Young's modulus
/// ([`resolve_modulus`]; [`grip_from_modulus`], [`crate::sheath::shaft_stiffness`] with
/// the needle spacing `spacing`), and that modulus and Poisson ratio (0 when both are
/// given and the material has no calibration). `key` is the friction table's key for
/// errors.
#[allow(clippy::too_many_arguments)]
fn resolve_friction(
    scene: &Scene,
    material: &Material,
    friction: &FrictionModel,
    radius: f64,
    h: f64,
    spacing: f64,
    key: &str,
) -> Result<(f64, f64, f64, (f64, f64)), SceneError> {
    let FrictionModel::PerLength(p) = friction else {
        return Ok((0.0, 0.0, 0.0, (0.0, 0.0)));
    };
    let modulus = resolve_modulus(scene, material, h, key);
    let (young, nu) = match (&modulus, p.grip, p.shear_stiffness) {
        (Ok(m), _, _) => *m,
        (Err(_), Some(_), Some(_)) => (0.0, 0.0),
        (Err(_), _, _) => return Err(modulus.unwrap_err()),
    };
    let grip = p
        .grip
        .unwrap_or_else(|| grip_from_modulus(young, nu, radius));
    let shear = p
        .shear_stiffness
        .unwrap_or_else(|| crate::sheath::shaft_stiffness(young, nu, radius, spacing));
    let eta = p
        .sheath_viscosity
        .unwrap_or(crate::friction::DEFAULT_SHEATH_VISCOSITY);
    let viscous = crate::sheath::shaft_viscosity(eta, radius, spacing);
    Ok((grip, shear, viscous, (young, nu)))
}

/// The needle's parameters in every region of `tissue` (region 0 from `[needle]`).
fn resolve_layers(
    scene: &Scene,
    tissue: &Tissue,
    c: Option<&NeedleConfig>,
    h: f64,
    spacing: f64,
) -> Result<Vec<RegionParams>, SceneError> {
    let regions = &tissue.regions;
    let Some(c) = c else {
        let none = RegionParams {
            friction: FrictionModel::default(),
            grip: 0.0,
            shear_stiffness: 0.0,
            shear_viscosity: 0.0,
            modulus: (0.0, 0.0),
            cutting: 0.0,
            membrane: Membrane::None,
            contact_radius: 0.0,
        };
        return Ok(vec![none; regions.names.len()]);
    };
    (0..regions.names.len())
        .map(|r| {
            let name = &regions.names[r];
            let rn = c.region(name, regions.needle[r].as_ref())?;
            let key = match &regions.needle[r] {
                Some(t) if t.contains_key("friction") => format!("region[{name}].needle.friction"),
                _ => "needle.friction".to_string(),
            };
            let (grip, shear_stiffness, shear_viscosity, modulus) = resolve_friction(
                scene,
                &regions.materials[r],
                &rn.friction,
                c.radius,
                h,
                spacing,
                &key,
            )?;
            Ok(RegionParams {
                friction: rn.friction,
                grip,
                shear_stiffness,
                shear_viscosity,
                modulus,
                cutting: rn.cutting,
                membrane: rn.membrane,
                contact_radius: rn.contact_radius,
            })
        })
        .collect()
}

impl Simulation {
    /// Builds the tissue of `scene` with room for the needle nodes its `[needle]` table
    /// needs (none without a needle). Build a backend from [`Prepared::tissue`], then call
    /// [`Prepared::start`].
    pub fn prepare(scene: &Scene) -> Result<Prepared, SimulationError> {
        let config = match &scene.needle {
            Some(t) => Some(NeedleConfig::from_table(t)?),
            None => None,
        };
        // The needle's slots enter the memory estimate before anything is allocated (with
        // its own spacing; the mesh spacing is known only after the build, checked below).
        let given = config
            .as_ref()
            .and_then(|c| c.spacing.map(|h| c.length / h + 4.0))
            .unwrap_or(0.0);
        let cloud = geometry::build_checked(scene, given, "needle.spacing")?;
        let rest = cloud.positions.clone();
        let mesh_spacing = (cloud.volume / rest.len().max(1) as f64).cbrt();
        let spacing = config
            .as_ref()
            .and_then(|c| c.spacing)
            .unwrap_or(mesh_spacing);
        if let Some(c) = &config {
            c.check_radius(spacing)?;
        }
        if let Some(c) = &config {
            let key = if c.spacing.is_some() {
                "needle.spacing"
            } else {
                "needle.length"
            };
            geometry::check_memory(
                scene,
                &geometry::MeshEstimate::built(rest.len()),
                c.length / spacing + 4.0,
                key,
            )?;
        }
        let extra = config.as_ref().map_or(0, |c| c.node_slots(spacing));
        let tissue = Tissue::from_cloud(scene, cloud, extra)?;
        let layers = resolve_layers(scene, &tissue, config.as_ref(), mesh_spacing, spacing)?;
        let editor = NodeEditor::new(&tissue, &rest, scene.tissue.weight);
        let fingerprint = fingerprint(scene, &tissue.state.positions);
        Ok(Prepared {
            fingerprint,
            tissue,
            editor,
            config,
            spacing,
            regions: layers,
            rest,
            physics: scene.physics,
        })
    }
}
