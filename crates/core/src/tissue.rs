//! Building the simulated tissue from a scene: node cloud, lumped masses (`density` times
//! each node's cell volume by default), fixed nodes,
//! neighbours, the chosen model's shape information and the initial deformation.

use crate::boundary::{Boundary, HeldSet, LoadSet};
use crate::error::{GeometryError, SceneError};
use crate::frame::PositionFrame;
use crate::geometry::{self, NodeCloud};
use crate::math::Vec4;
use crate::models::{material_row, ArrayInfo, ShapeInfo};
use crate::neighbours::{Neighbours, MIN_LIVE_NEIGHBOURS};
use crate::regions::Regions;
use crate::scene::{Material, NodeMasses, Scene, TimeStep};
use crate::state::NodeState;

/// The key memory errors name for the spare node slots: they hold the needle's nodes
/// (`needle.length` over the needle's spacing).
pub(crate) const EXTRA_KEY: &str = "needle.length";

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
    /// Mass of each mesh node in kg; they add up to `density * volume`.
    pub masses: Vec<f64>,
    /// Mass in kg of a node the needle adds inside the tissue of region 0: an interior
    /// node's, `density * spacing^3` (with `masses = "uniform"`, the mesh nodes' common
    /// mass); [`Regions::node_mass`] has it for every region.
    pub node_mass: f64,
    /// Volume enclosed by the surface in m^3.
    pub volume: f64,
    /// Number of fixed nodes (inverse mass 0: held in all components).
    pub n_fixed: usize,
    /// Held node sets and surface loads.
    pub boundary: Boundary,
    /// The regions and each mesh node's region ([`crate::regions`]).
    pub regions: Regions,
    /// The frame of the positions in `state` and of the rest positions in `shape`: the
    /// world translated to a per-body origin ([`crate::frame`]), the world itself for a
    /// body within about its size of the origin. The backends read and write positions
    /// in world coordinates.
    pub frame: PositionFrame,
}

impl Tissue {
    /// Builds the simulation arrays from a node cloud with `extra` spare slots, with the
    /// time step of `physics.dt` in seconds (`"auto"` gets a provisional 1 ms here;
    /// [`Tissue::from_cloud`] resolves it). The memory estimate of the nodes and the
    /// `extra` slots is checked before the arrays are allocated.
    pub(crate) fn assemble(
        scene: &Scene,
        cloud: NodeCloud,
        extra: usize,
    ) -> Result<Tissue, SceneError> {
        let n = cloud.positions.len();
        let k = scene.tissue.neighbours;
        geometry::check_memory(
            scene,
            &geometry::MeshEstimate::built(n),
            extra as f64,
            EXTRA_KEY,
        )?;
        if n < k + 1 {
            return Err(GeometryError::TooFewNodes {
                nodes: n,
                neighbours: k,
            }
            .into());
        }
        let capacity = n + extra;
        let mut neighbours = Neighbours::build(&cloud.positions, k, scene.tissue.weight, capacity);
        scene
            .material
            .prepare_neighbours(&mut neighbours, &cloud.node_volumes, cloud.spacing, n);
        check_live_neighbours(scene, &neighbours, &cloud.positions)?;
        let mut regions = crate::regions::classify(scene, &cloud.positions, cloud.spacing)?;
        let rho = scene.tissue.density;
        let (masses, node_mass) = match scene.tissue.masses {
            NodeMasses::Cell => (
                cloud
                    .node_volumes
                    .iter()
                    .zip(&regions.of_node)
                    .map(|(v, &r)| regions.densities[r as usize] * v)
                    .collect::<Vec<f64>>(),
                rho * cloud.spacing.powi(3),
            ),
            NodeMasses::Uniform => {
                let m = cloud.volume / n as f64;
                (
                    regions
                        .of_node
                        .iter()
                        .map(|&r| regions.densities[r as usize] * m)
                        .collect(),
                    rho * m,
                )
            }
        };
        regions.node_mass = regions
            .densities
            .iter()
            .map(|&d| {
                if d == rho {
                    node_mass
                } else {
                    node_mass * d / rho
                }
            })
            .collect();
        // Masses and inverse masses are stored in f32: both must be normal f32 numbers
        // (a density of 1e300 would round the mass to infinity and freeze the body).
        let representable = |m: f64| {
            m.is_finite() && m > 0.0 && (m as f32).is_normal() && ((1.0 / m) as f32).is_normal()
        };
        if let Some(i) = masses.iter().position(|&m| !representable(m)) {
            // The density that gave it: the node's region's when it sets its own.
            let r = regions.of_node.get(i).copied().unwrap_or(0) as usize;
            let key = match r {
                0 => "tissue.density".to_string(),
                _ if regions.densities[r] == rho => "tissue.density".to_string(),
                _ => format!("region[{}].density", regions.names[r]),
            };
            return Err(SceneError::invalid(
                key,
                format!(
                    "node {i} gets mass {:e} kg: density times its cell volume must be a positive \
                     number whose value and inverse fit in f32 (1.2e-38 to 3.4e38)",
                    masses[i]
                ),
            ));
        }
        let (boundary, fixed) = build_boundary(scene, &cloud, &masses, &regions)?;
        let n_fixed = fixed.iter().filter(|&&f| f).count();
        let frame = PositionFrame::for_body(&cloud.positions);
        let local = |p: [f64; 3], w: f32| {
            let q = frame.local(p);
            [q[0], q[1], q[2], w]
        };
        let mut rest: Vec<Vec4> = cloud.positions.iter().map(|&p| local(p, 0.0)).collect();
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
            regions.mixed().then(|| {
                let rows: Vec<Vec4> = regions.materials.iter().map(material_row).collect();
                let mut m: Vec<Vec4> = regions.of_node.iter().map(|&r| rows[r as usize]).collect();
                m.resize(capacity, [0.0; 4]);
                m
            }),
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
                    local(p, 0.0)
                } else {
                    let inv_mass = (1.0 / masses[i]) as f32;
                    let q: [f64; 3] = if s == [1.0; 3] {
                        p
                    } else {
                        std::array::from_fn(|a| centre[a] + s[a] * (p[a] - centre[a]))
                    };
                    local(q, inv_mass)
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
            masses,
            node_mass,
            volume: cloud.volume,
            n_fixed,
            boundary,
            regions,
            frame,
        };
        if let TimeStep::Seconds(dt) = scene.physics.dt {
            tissue.step = crate::integrator::StepParams::new(dt, &scene.physics);
        }
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
                name: "position_remainder",
                bytes: bytes(&self.state.position_remainders),
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

/// An error naming the first node with fewer than [`MIN_LIVE_NEIGHBOURS`] live
/// neighbours: `tissue.weight.support` when its mutual neighbours all got weight 0 from
/// the kernel, else `tissue.geometry.spacing` (none of its nearest nodes lists it back:
/// the nodes around it are much closer to each other than to it).
fn check_live_neighbours(
    scene: &Scene,
    neighbours: &Neighbours,
    positions: &[[f64; 3]],
) -> Result<(), SceneError> {
    let n = positions.len();
    let Some(poor) = neighbours.first_poor(n, MIN_LIVE_NEIGHBOURS) else {
        return Ok(());
    };
    let p = positions[poor.node];
    let what = format!(
        "node {} at ({:.4e}, {:.4e}, {:.4e}) m has {} live neighbours of {} slots (at least \
         {MIN_LIVE_NEIGHBOURS} needed, or it feels no elastic force and leaves the body)",
        poor.node, p[0], p[1], p[2], poor.live, scene.tissue.neighbours
    );
    Err(if poor.mutual > poor.live {
        SceneError::invalid(
            "tissue.weight.support",
            format!(
                "{what}: {} of its neighbours list it back but lie outside the kernel's \
                 support; use a larger `support`",
                poor.mutual
            ),
        )
    } else {
        SceneError::invalid(
            "tissue.geometry.spacing",
            format!(
                "{what}: none of its nearest nodes counts it among their own nearest, which \
                 are much closer to each other than to it (with `surface = \"vertices\"`, \
                 a surface vertex far from the interior lattice); use `surface = \"resample\"`, \
                 a spacing nearer the distance between its nodes, or more `tissue.neighbours`"
            ),
        )
    })
}

/// Each node's outward area vector over the surface triangles whose three corners are
/// all in `nodes` (zero off them): the surface a load or a far-field face covers.
fn covered_area_vectors(cloud: &NodeCloud, nodes: &[u32]) -> Vec<[f64; 3]> {
    let mut member = vec![false; cloud.positions.len()];
    nodes.iter().for_each(|&i| member[i as usize] = true);
    let covered: Vec<[u32; 3]> = cloud
        .triangles
        .iter()
        .filter(|t| t.iter().all(|&v| member[v as usize]))
        .copied()
        .collect();
    crate::geometry::vertex_area_vectors(&cloud.positions, &covered)
}

/// The surface nodes of a far-field face (the triangles whose corners are all in `nodes`)
/// and their springs and dashpots ([`crate::boundary`]), from each node's region. `key` is
/// the table's `far_field` key for errors.
fn far_field_face(
    scene: &Scene,
    cloud: &NodeCloud,
    regions: &Regions,
    nodes: &[u32],
    distance: f64,
    key: String,
) -> Result<(Vec<u32>, crate::boundary::FarField), SceneError> {
    let area = covered_area_vectors(cloud, nodes);
    let on_face: Vec<u32> = nodes
        .iter()
        .copied()
        .filter(|&i| area[i as usize] != [0.0; 3])
        .collect();
    if on_face.is_empty() {
        return Err(SceneError::invalid(
            key,
            "covers no surface triangle (a far-field face is the triangles whose three \
             corners the set selects)",
        ));
    }
    let mut far = crate::boundary::FarField {
        key: format!("{key}.distance"),
        normals: Vec::with_capacity(on_face.len()),
        dashpots: Vec::with_capacity(on_face.len()),
        springs: Vec::with_capacity(on_face.len()),
    };
    for &i in &on_face {
        let a = glam::DVec3::from(area[i as usize]);
        let r = regions.of_node[i as usize] as usize;
        let moduli = regions.materials[r]
            .elastic_moduli(cloud.spacing, scene.tissue.neighbours)
            .map_err(|e| {
                SceneError::invalid(
                    key.clone(),
                    format!(
                        "needs the Young's modulus of region `{}` at its nodes: {e}",
                        regions.names[r]
                    ),
                )
            })?;
        let (dashpots, springs) = crate::boundary::far_field_coefficients(
            a.length(),
            moduli,
            regions.densities[r],
            distance,
        );
        far.normals.push(a.normalize().to_array());
        far.dashpots.push(dashpots);
        far.springs.push(springs);
    }
    Ok((on_face, far))
}

/// The held sets and loads of a scene, and which nodes get inverse mass 0 (held in all
/// components). Errors name the table: a set that selects no node, a prescribed
/// displacement on a node that `[[fixed]]` holds in all components, a load or a far-field
/// face on no surface triangle.
fn build_boundary(
    scene: &Scene,
    cloud: &NodeCloud,
    masses: &[f64],
    regions: &Regions,
) -> Result<(Boundary, Vec<bool>), SceneError> {
    let rest = &cloud.positions;
    let n = rest.len();
    let mut fixed = vec![false; n];
    let mut boundary = Boundary::default();
    let names = scene.held_set_names();
    let empty = |key: String| {
        SceneError::invalid(
            key,
            "selects no node (check the coordinates against the geometry's bounds)",
        )
    };
    // Which fixed set holds each node at rest, per component.
    let mut held_by: Vec<[Option<usize>; 3]> = vec![[None; 3]; n];
    for (s, f) in scene.fixed.iter().enumerate() {
        let nodes = f.nodes.select(rest);
        if nodes.is_empty() {
            return Err(empty(format!("fixed[{s}]")));
        }
        for &i in &nodes {
            for a in (0..3).filter(|&a| f.components.0[a]) {
                held_by[i as usize][a].get_or_insert(s);
            }
        }
        if let Some(spec) = &f.far_field {
            let key = format!("fixed[{s}].far_field");
            let (face, far) = far_field_face(scene, cloud, regions, &nodes, spec.distance, key)?;
            boundary.held.push(HeldSet::far_field(
                names[s].1.clone(),
                face,
                far,
                rest,
                masses,
            ));
            continue;
        }
        if f.components.all() {
            nodes.iter().for_each(|&i| fixed[i as usize] = true);
        }
        boundary.held.push(HeldSet::new(
            names[s].1.clone(),
            nodes,
            f.components.0,
            None,
            rest,
            masses,
        ));
    }
    // Which prescribed set moves each node, and in which components: a node follows one
    // motion per component (two sets moving it apart were accepted, and the later one
    // silently won).
    let mut moved_by: Vec<[Option<usize>; 3]> = vec![[None; 3]; n];
    for (s, p) in scene.prescribed.iter().enumerate() {
        let nodes = p.nodes.select(rest);
        if nodes.is_empty() {
            return Err(empty(format!("prescribed[{s}]")));
        }
        for &i in &nodes {
            for a in (0..3).filter(|&a| p.components.0[a]) {
                let by = &mut moved_by[i as usize][a];
                if let Some(other) = *by {
                    return Err(SceneError::invalid(
                        format!("prescribed[{s}]"),
                        format!(
                            "moves node {i} in {}, which prescribed[{other}] already moves: \
                             a node follows one prescribed motion per component (make the \
                             sets disjoint or prescribe different components)",
                            ["x", "y", "z"][a]
                        ),
                    ));
                }
                *by = Some(s);
            }
        }
        // A component both held at rest and moved: the motion won, and both sets
        // reported the same reaction.
        for &i in &nodes {
            if let Some((a, f)) = (0..3)
                .filter(|&a| p.components.0[a])
                .find_map(|a| held_by[i as usize][a].map(|f| (a, f)))
            {
                return Err(SceneError::invalid(
                    format!("prescribed[{s}]"),
                    format!(
                        "moves node {i} in {}, which fixed[{f}] holds at rest: a node \
                         component cannot be both held at rest and moved",
                        ["x", "y", "z"][a]
                    ),
                ));
            }
        }
        if p.components.all() {
            nodes.iter().for_each(|&i| fixed[i as usize] = true);
        }
        boundary.held.push(HeldSet::new(
            names[scene.fixed.len() + s].1.clone(),
            nodes,
            p.components.0,
            Some(p.motion),
            rest,
            masses,
        ));
    }
    for (s, l) in scene.load.iter().enumerate() {
        // The loaded surface: the triangles whose corners are all in the set.
        let area = covered_area_vectors(cloud, &l.nodes.select(rest));
        let nodes: Vec<u32> = (0..n as u32)
            .filter(|&i| area[i as usize] != [0.0; 3])
            .collect();
        {
            if nodes.is_empty() {
                return Err(SceneError::invalid(
                    format!("load[{s}]"),
                    "covers no surface triangle (a load acts on the triangles whose three \
                     corners the set selects)",
                ));
            }
            let forces = nodes
                .iter()
                .map(|&i| {
                    let a = area[i as usize];
                    match l.load {
                        crate::scene::SurfaceLoad::Traction(t) => {
                            let len = glam::DVec3::from(a).length();
                            t.map(|c| c * len)
                        }
                        crate::scene::SurfaceLoad::Pressure(p) => a.map(|c| -p * c),
                    }
                })
                .collect();
            boundary.loads.push(LoadSet {
                name: l.name.clone().unwrap_or_else(|| format!("load{s}")),
                nodes,
                forces,
                ramp: l.ramp,
            });
        }
    }
    Ok((boundary, fixed))
}
