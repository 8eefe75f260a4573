//! Tissue regions (`[[region]]`): parts of the body with their own material, density and
//! needle parameters (layered tissue: skin, fat, muscle, an organ).
//!
//! The body is the `[tissue]` geometry, meshed as one node set; a region is given by a box
//! or a closed surface file, and every node whose rest position lies in it takes its
//! material. Nodes in no region keep the scene's `[material]` and `tissue.density`: region
//! 0, named `"tissue"`. Regions are bonded where they touch: neighbour rows cross the
//! interface as anywhere else, and each node's force comes from its own material:
//!
//! - mass-spring: a spring between two materials has the stiffness of its two halves in
//!   series, `k_ij = 2 k_i k_j / (k_i + k_j)` (and the same mean of the damping), so the
//!   pair force stays equal and opposite;
//! - shape matching: cluster i pulls with its own `k_s,i` (the `cluster` variant's energy
//!   `sum_i k_s,i / 2 sum_j w_ij |g_ij - x_j|^2`);
//! - Debunne and point based animation: node i's strain energy `V_i W(F_i)` uses its own
//!   Lame parameters, hourglass control and volume stiffness (nodal quadrature of a
//!   piecewise constant material).
//!
//! All regions use the scene's model. A region's `material` table gives the keys that
//! differ from `[material]` and inherits the others; the keys that change the model's
//! structure (`forces`, `corotated`, `rotation_iterations`, `node_volumes`,
//! `spring_share`) may not differ. A node on the boundary between two
//! regions belongs to the one listed first; two regions that share interior nodes are an
//! error.
//!
//! ```toml
//! [[region]]
//! name = "fat"
//! geometry = { kind = "box", min = [0.002, 0.0, 0.0], max = [0.02, 0.08, 0.08] }
//! density = 920.0
//! material = { young_modulus = 3000.0, poisson_ratio = 0.45 }
//! needle = { puncture_force = 0.8, cutting = 0.1, friction = { coefficient = 0.3, grip = 20.0 } }
//! ```

use crate::error::SceneError;
use crate::geometry::obj;
use crate::geometry::sampling::FastWinding;
use crate::geometry::triangle_bins::TriangleBins;
use crate::scene::{Material, RegionGeometry, RegionSpec, Scene};
use glam::{DMat3, DVec3};

/// Name of region 0: the nodes in no `[[region]]`.
pub const BASE_REGION: &str = "tissue";

/// Most regions a scene may have (region ids are 16-bit).
pub const MAX_REGIONS: usize = 1024;

/// The regions of a built tissue.
#[derive(Debug, Clone, PartialEq)]
pub struct Regions {
    /// Region names, region 0 first ([`BASE_REGION`]).
    pub names: Vec<String>,
    /// Each region's material.
    pub materials: Vec<Material>,
    /// Each region's density, kg/m^3.
    pub densities: Vec<f64>,
    /// Each region's `needle` table, raw.
    pub needle: Vec<Option<toml::Table>>,
    /// The region of every mesh node.
    pub of_node: Vec<u16>,
    /// Mass in kg of a node the needle adds in each region (its density times an interior
    /// node's volume).
    pub node_mass: Vec<f64>,
}

impl Regions {
    /// One region holding every node.
    pub fn single(scene: &Scene, nodes: usize) -> Regions {
        Regions {
            names: vec![BASE_REGION.into()],
            materials: vec![scene.material],
            densities: vec![scene.tissue.density],
            needle: vec![None],
            of_node: vec![0; nodes],
            node_mass: vec![0.0],
        }
    }

    /// Whether more than one material is in use (per-node material rows are allocated).
    pub fn mixed(&self) -> bool {
        let used = |r: usize| self.of_node.iter().any(|&x| x as usize == r);
        let first = self.materials[self.of_node.first().copied().unwrap_or(0) as usize];
        (0..self.materials.len()).any(|r| used(r) && self.materials[r] != first)
    }

    /// The region id of a name.
    pub fn id(&self, name: &str) -> Option<u16> {
        self.names.iter().position(|n| n == name).map(|i| i as u16)
    }
}

/// The dotted key of region `r` (1-based among `[[region]]`): `region[name]`.
pub fn region_key(spec: &RegionSpec) -> String {
    format!("region[{}]", spec.name)
}

/// Checks the `[[region]]` tables (names, geometry values, densities, materials) without
/// reading surface files.
pub fn validate(scene: &Scene) -> Result<(), SceneError> {
    if scene.region.len() + 1 > MAX_REGIONS {
        return Err(SceneError::invalid(
            "region",
            format!(
                "at most {} regions, got {}",
                MAX_REGIONS - 1,
                scene.region.len()
            ),
        ));
    }
    let mut seen = vec![BASE_REGION.to_string()];
    for (i, r) in scene.region.iter().enumerate() {
        // Commas and quotes are fine: the CSV files quote them (RFC 4180).
        if r.name.trim().is_empty()
            || r.name.contains(['[', ']'])
            || crate::scene::hidden_character(&r.name).is_some()
        {
            return Err(SceneError::invalid(
                format!("region[{i}].name"),
                format!(
                    "must be a non-empty name without brackets, control characters (line \
                     breaks ...) or invisible Unicode characters, got {:?}",
                    r.name
                ),
            ));
        }
        if seen.contains(&r.name) {
            return Err(SceneError::invalid(
                format!("region[{i}].name"),
                format!(
                    "`{}` is used twice (`{BASE_REGION}` is the name of the nodes in no region)",
                    r.name
                ),
            ));
        }
        seen.push(r.name.clone());
        let key = region_key(r);
        match &r.geometry {
            RegionGeometry::Box { min, max } => {
                for a in 0..3 {
                    if !(min[a].is_finite() && max[a].is_finite() && max[a] > min[a]) {
                        return Err(SceneError::invalid(
                            format!("{key}.geometry"),
                            format!(
                                "needs finite corners with max > min along every axis (axis \
                                 {a}: min {}, max {})",
                                min[a], max[a]
                            ),
                        ));
                    }
                }
            }
            RegionGeometry::Surface(s) => {
                if !(s.scale.is_finite() && s.scale > 0.0) {
                    return Err(SceneError::invalid(
                        format!("{key}.geometry.scale"),
                        format!("must be a finite number > 0, got {}", s.scale),
                    ));
                }
                if s.translate.iter().any(|c| !c.is_finite()) {
                    return Err(SceneError::invalid(
                        format!("{key}.geometry.translate"),
                        "must be finite",
                    ));
                }
                if let Some(rot) = s.rotate {
                    let l = DVec3::from(rot.axis).length();
                    if !(rot.degrees.is_finite() && l.is_finite() && l > 0.0) {
                        return Err(SceneError::invalid(
                            format!("{key}.geometry.rotate"),
                            "needs a finite non-zero axis and finite degrees",
                        ));
                    }
                }
            }
        }
        if let Some(d) = r.density {
            if !(d.is_finite() && d > 0.0) {
                return Err(SceneError::invalid(
                    format!("{key}.density"),
                    format!("must be a finite number > 0 (kg/m^3), got {d}"),
                ));
            }
        }
        let m = region_material(scene, r)?;
        m.validate(&format!("{key}.material"))?;
    }
    Ok(())
}

/// The material of a region: its `material` table over `[material]` (every key it leaves
/// out is inherited); the structural keys may not differ.
pub fn region_material(scene: &Scene, spec: &RegionSpec) -> Result<Material, SceneError> {
    let key = format!("{}.material", region_key(spec));
    let Some(table) = &spec.material else {
        return Err(SceneError::invalid(
            key,
            "is missing: every region needs a material (the parameters of the scene's model)",
        ));
    };
    let base = scene.material;
    let model = base.tag();
    let mut t = table.clone();
    match t.remove("model") {
        None => {}
        Some(toml::Value::String(s)) if s == model => {}
        Some(other) => {
            return Err(SceneError::invalid(
                format!("{key}.model"),
                format!(
                    "every region uses the scene's model `{model}` (material.model), got \
                     {other}"
                ),
            ))
        }
    }
    // The region's keys over every key of `[material]`.
    let mut full = base.to_table();
    for (k, v) in t.iter() {
        full.insert(k.clone(), v.clone());
    }
    full.insert("model".into(), toml::Value::String(model.into()));
    let parsed: Result<Material, toml::de::Error> = toml::Value::Table(full)
        .try_into::<crate::scene::MaterialTable>()
        .map(|m| m.0);
    let m = parsed.map_err(|e| {
        SceneError::invalid(key.clone(), e.to_string().trim_end().replace('\n', " "))
    })?;
    let structural = |k: &str| {
        SceneError::invalid(
            format!("{key}.{k}"),
            format!(
                "must equal material.{k}: it is one for the whole tissue (it sets the \
                 model's structure or its node rows' layout; leave it out to inherit it)"
            ),
        )
    };
    let differs = base.structural_difference(&m);
    match differs {
        Some(k) => Err(structural(k)),
        None => Ok(m),
    }
}

/// A region's shape, ready for inside tests.
enum Shape {
    Box([f64; 3], [f64; 3]),
    /// The surface's winding number by clusters and its triangles binned for distances
    /// (each node against every triangle took 48 s for a 327,680-triangle surface).
    Surface(FastWinding, TriangleBins),
}

impl Shape {
    /// Whether `p` is inside (faces included), and whether it is inside by more than `eps`
    /// from the boundary.
    fn contains(&self, p: [f64; 3], eps: f64) -> (bool, bool) {
        match self {
            Shape::Box(lo, hi) => {
                let depth = (0..3)
                    .map(|a| (p[a] - lo[a]).min(hi[a] - p[a]))
                    .fold(f64::INFINITY, f64::min);
                (depth >= 0.0, depth > eps)
            }
            Shape::Surface(winding, bins) => {
                let inside = winding.winding_number(p) > 0.5;
                let deep = inside && bins.distance_capped(p, eps) >= eps;
                (inside, deep)
            }
        }
    }
}

fn load_shape(scene: &Scene, spec: &RegionSpec) -> Result<Shape, SceneError> {
    let key = region_key(spec);
    match &spec.geometry {
        RegionGeometry::Box { min, max } => Ok(Shape::Box(*min, *max)),
        RegionGeometry::Surface(s) => {
            let full = if s.path.is_absolute() {
                s.path.clone()
            } else {
                scene.base_dir.join(&s.path)
            };
            crate::scene::check_input_file(
                &full,
                crate::scene::MAX_SURFACE_FILE_BYTES,
                &format!("{key}.geometry.path"),
            )?;
            let surface = match s.kind.as_str() {
                "stl" => obj::load_closed_stl(&full, s.scale)?,
                "vtk" => obj::load_closed_vtk(&full, s.scale)?,
                _ => obj::load_closed_surface(&full, s.scale)?,
            };
            let m = s
                .rotate
                .map(|r| DMat3::from_cols_array_2d(&r.matrix()).transpose());
            let v: Vec<[f64; 3]> = surface
                .vertices
                .iter()
                .map(|v| {
                    let r = m.map_or(DVec3::from(*v), |m| m * DVec3::from(*v));
                    (r + DVec3::from(s.translate)).into()
                })
                .collect();
            let tris: Vec<[[f64; 3]; 3]> = surface
                .triangles
                .iter()
                .map(|t| t.map(|i| v[i as usize]))
                .collect();
            // Cubes of about two mean edge lengths: a distance query near the surface
            // reads a few dozen triangles.
            let area: f64 = tris
                .iter()
                .map(|t| {
                    let [a, b, c] = t.map(DVec3::from);
                    0.5 * (b - a).cross(c - a).length()
                })
                .sum();
            let cell = (2.0 * (2.0 * area / tris.len().max(1) as f64).sqrt()).max(1e-12);
            Ok(Shape::Surface(
                FastWinding::new(tris.clone()),
                TriangleBins::new(tris, cell),
            ))
        }
    }
}

/// Assigns every node (rest positions `rest`, lattice spacing `h`) its region. Errors
/// name the region: a region with no node, two regions sharing nodes more than
/// `1e-6 h` inside both, an unreadable surface, a bad material.
pub fn classify(scene: &Scene, rest: &[[f64; 3]], h: f64) -> Result<Regions, SceneError> {
    let mut regions = Regions::single(scene, rest.len());
    if scene.region.is_empty() {
        return Ok(regions);
    }
    validate(scene)?;
    let shapes: Vec<Shape> = scene
        .region
        .iter()
        .map(|r| load_shape(scene, r))
        .collect::<Result<_, _>>()?;
    let eps = 1e-6 * h;
    // Two boxes that share a volume overlap even where no node lies in it.
    for (b, sb) in shapes.iter().enumerate() {
        for (a, sa) in shapes[..b].iter().enumerate() {
            if let (Shape::Box(l0, h0), Shape::Box(l1, h1)) = (sa, sb) {
                if (0..3).all(|c| h0[c].min(h1[c]) - l0[c].max(l1[c]) > eps) {
                    return Err(SceneError::invalid(
                        format!("{}.geometry", region_key(&scene.region[b])),
                        format!(
                            "overlaps region `{}`: the boxes share a volume; regions may \
                             touch but not overlap",
                            scene.region[a].name
                        ),
                    ));
                }
            }
        }
    }
    let mut count = vec![0usize; shapes.len()];
    for (i, p) in rest.iter().enumerate() {
        let mut owner: Option<usize> = None;
        let mut deep: Option<usize> = None;
        for (r, s) in shapes.iter().enumerate() {
            let (inside, strictly) = s.contains(*p, eps);
            if !inside {
                continue;
            }
            if strictly {
                if let Some(d) = deep {
                    return Err(SceneError::invalid(
                        format!("{}.geometry", region_key(&scene.region[r])),
                        format!(
                            "overlaps region `{}`: node {i} at ({:.4e}, {:.4e}, {:.4e}) m lies \
                             inside both; regions may touch but not overlap",
                            scene.region[d].name, p[0], p[1], p[2]
                        ),
                    ));
                }
                deep = Some(r);
            }
            owner.get_or_insert(r);
        }
        // A node strictly inside one region and on the face of an earlier one goes to the
        // region it is inside; on the faces of several, to the first listed.
        if let Some(r) = deep.or(owner) {
            regions.of_node[i] = (r + 1) as u16;
            count[r] += 1;
        }
    }
    if let Some(r) = count.iter().position(|&c| c == 0) {
        return Err(SceneError::invalid(
            format!("{}.geometry", region_key(&scene.region[r])),
            "contains no node of the body (check its coordinates against tissue.geometry)",
        ));
    }
    for r in &scene.region {
        regions.names.push(r.name.clone());
        regions.materials.push(region_material(scene, r)?);
        regions
            .densities
            .push(r.density.unwrap_or(scene.tissue.density));
        regions.needle.push(r.needle.clone());
    }
    Ok(regions)
}
