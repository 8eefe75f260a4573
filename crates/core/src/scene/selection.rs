//! Node sets and what is done to them: `[[fixed]]`, `[[prescribed]]` and `[[load]]`.

use crate::error::SceneError;
use crate::validate::{finite, non_negative_finite, positive_finite};
use serde::Deserialize;

/// An axis of the scene frame.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum Axis {
    /// x
    X,
    /// y
    Y,
    /// z
    Z,
}

impl Axis {
    /// 0, 1 or 2.
    pub fn index(self) -> usize {
        match self {
            Axis::X => 0,
            Axis::Y => 1,
            Axis::Z => 2,
        }
    }
}

/// A set of nodes, chosen by their rest positions. In a scene table it is given by
/// exactly one of these keys (next to the table's own keys):
///
/// - `axis` with `below` or `above`: every node at or below (above) that coordinate;
/// - `box = { min = [..], max = [..] }`: every node inside the box (faces included);
/// - `sphere = { centre = [..], radius = r }`: every node within `r` of the centre;
/// - `points = [[x, y, z], ...]`: the node nearest to each point.
///
/// A set that selects no node is an error naming the table.
#[derive(Debug, Clone, PartialEq)]
pub enum NodeSet {
    /// Nodes on one side of a plane normal to an axis.
    Plane {
        /// The axis the plane is normal to.
        axis: Axis,
        /// Nodes at or below this coordinate, else at or above `above`.
        below: Option<f64>,
        /// Nodes at or above this coordinate.
        above: Option<f64>,
    },
    /// Nodes inside an axis-aligned box.
    Box {
        /// Lower corner.
        min: [f64; 3],
        /// Upper corner.
        max: [f64; 3],
    },
    /// Nodes inside a sphere.
    Sphere {
        /// Centre.
        centre: [f64; 3],
        /// Radius in m.
        radius: f64,
    },
    /// The node nearest to each point.
    Points(Vec<[f64; 3]>),
}

impl NodeSet {
    /// Indices of the selected nodes among `rest` (sorted, each once).
    pub fn select(&self, rest: &[[f64; 3]]) -> Vec<u32> {
        let mut out: Vec<u32> = match self {
            NodeSet::Points(points) => points
                .iter()
                .filter_map(|q| {
                    (0..rest.len()).min_by(|&a, &b| {
                        let d = |i: usize| {
                            glam::DVec3::from(rest[i]).distance_squared(glam::DVec3::from(*q))
                        };
                        d(a).total_cmp(&d(b))
                    })
                })
                .map(|i| i as u32)
                .collect(),
            _ => (0..rest.len() as u32)
                .filter(|&i| self.contains(rest[i as usize]))
                .collect(),
        };
        out.sort_unstable();
        out.dedup();
        out
    }

    /// Whether a rest position lies in the set's region (`points` sets contain no region:
    /// false).
    pub fn contains(&self, p: [f64; 3]) -> bool {
        match self {
            NodeSet::Plane { axis, below, above } => {
                let c = p[axis.index()];
                match (below, above) {
                    (Some(b), _) => c <= *b,
                    (None, Some(a)) => c >= *a,
                    (None, None) => false,
                }
            }
            NodeSet::Box { min, max } => (0..3).all(|a| p[a] >= min[a] && p[a] <= max[a]),
            NodeSet::Sphere { centre, radius } => {
                glam::DVec3::from(p).distance_squared(glam::DVec3::from(*centre)) <= radius * radius
            }
            NodeSet::Points(_) => false,
        }
    }

    pub(crate) fn validate(&self, key: &str) -> Result<(), SceneError> {
        match self {
            NodeSet::Plane { below, above, .. } => match (below, above) {
                (Some(v), None) | (None, Some(v)) => finite(key, *v),
                _ => Err(SceneError::invalid(
                    key,
                    "give exactly one of `below` and `above` with `axis`",
                )),
            },
            NodeSet::Box { min, max } => {
                for a in 0..3 {
                    finite(&format!("{key}.box.min"), min[a])?;
                    finite(&format!("{key}.box.max"), max[a])?;
                    if max[a] < min[a] {
                        return Err(SceneError::invalid(
                            format!("{key}.box.max"),
                            format!("must not be below min (axis {a}: {} < {})", max[a], min[a]),
                        ));
                    }
                }
                Ok(())
            }
            NodeSet::Sphere { centre, radius } => {
                for c in centre {
                    finite(&format!("{key}.sphere.centre"), *c)?;
                }
                positive_finite(&format!("{key}.sphere.radius"), *radius)
            }
            NodeSet::Points(points) => {
                if points.is_empty() {
                    return Err(SceneError::invalid(format!("{key}.points"), "is empty"));
                }
                for c in points.iter().flatten() {
                    finite(&format!("{key}.points"), *c)?;
                }
                Ok(())
            }
        }
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct BoxKeys {
    min: [f64; 3],
    max: [f64; 3],
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SphereKeys {
    centre: [f64; 3],
    radius: f64,
}

/// Takes the node-set keys out of a boundary table; the rest is the table's own.
fn take_node_set(t: &mut toml::Table) -> Result<NodeSet, String> {
    let picked: Vec<&str> = ["axis", "box", "sphere", "points"]
        .into_iter()
        .filter(|k| t.contains_key(*k))
        .collect();
    if picked.len() != 1 {
        return Err(format!(
            "give exactly one node set: `axis` (with `below` or `above`), `box`, `sphere` or `points`{}",
            if picked.is_empty() {
                String::new()
            } else {
                format!(" (got {})", picked.join(", "))
            }
        ));
    }
    fn e(k: &'static str) -> impl Fn(toml::de::Error) -> String {
        move |e| format!("`{k}`: {}", e.to_string().trim_end())
    }
    let num = |v: Option<toml::Value>, k: &'static str| -> Result<Option<f64>, String> {
        v.map(|v| v.try_into::<f64>().map_err(e(k))).transpose()
    };
    Ok(match picked[0] {
        "axis" => NodeSet::Plane {
            axis: t
                .remove("axis")
                .expect("present")
                .try_into()
                .map_err(e("axis"))?,
            below: num(t.remove("below"), "below")?,
            above: num(t.remove("above"), "above")?,
        },
        "box" => {
            let b: BoxKeys = t
                .remove("box")
                .expect("present")
                .try_into()
                .map_err(e("box"))?;
            NodeSet::Box {
                min: b.min,
                max: b.max,
            }
        }
        "sphere" => {
            let b: SphereKeys = t
                .remove("sphere")
                .expect("present")
                .try_into()
                .map_err(e("sphere"))?;
            NodeSet::Sphere {
                centre: b.centre,
                radius: b.radius,
            }
        }
        _ => NodeSet::Points(
            t.remove("points")
                .expect("present")
                .try_into()
                .map_err(e("points"))?,
        ),
    })
}

/// Deserialises a boundary table: its node set, then the rest into `T`.
fn de_with_node_set<'de, D, T>(d: D) -> Result<(NodeSet, T), D::Error>
where
    D: serde::Deserializer<'de>,
    T: serde::de::DeserializeOwned,
{
    use serde::de::Error;
    let mut t = toml::Table::deserialize(d)?;
    let set = take_node_set(&mut t).map_err(D::Error::custom)?;
    let rest = toml::Value::Table(t)
        .try_into()
        .map_err(|e: toml::de::Error| {
            D::Error::custom(e.to_string().trim_end().replace('\n', " "))
        })?;
    Ok((set, rest))
}

/// Which displacement components a constraint holds: a list of axes (`["y"]` is a roller
/// along y, free to slide in x and z). Default: all three.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Components(pub [bool; 3]);

impl Default for Components {
    fn default() -> Self {
        Components([true; 3])
    }
}

impl Components {
    /// Whether all three are held.
    pub fn all(&self) -> bool {
        self.0 == [true; 3]
    }
}

impl<'de> Deserialize<'de> for Components {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        use serde::de::Error;
        let axes = Vec::<Axis>::deserialize(d)?;
        if axes.is_empty() {
            return Err(D::Error::custom(
                "`components` is empty: list the axes held, e.g. [\"y\"]",
            ));
        }
        let mut c = [false; 3];
        for a in axes {
            if c[a.index()] {
                return Err(D::Error::custom(format!("`components` lists {a:?} twice")));
            }
            c[a.index()] = true;
        }
        Ok(Components(c))
    }
}

/// `[[fixed]]`: a node set held at its rest position, in every component or (with
/// `components`) only in some: `components = ["y"]` on a bottom face is a frictionless
/// floor (roller). With `far_field = { distance = R }` the set's surface is a cut face
/// of a body that goes on beyond it: held by springs and dashpots that stand for the
/// tissue outside instead of rigidly ([`crate::boundary`], "Far-field faces").
#[derive(Debug, Clone, PartialEq)]
pub struct FixedSelection {
    /// The nodes.
    pub nodes: NodeSet,
    /// The components held (default all).
    pub components: Components,
    /// Name in the reaction output (default `fixed<i>`).
    pub name: Option<String>,
    /// A far-field face instead of a rigid hold (default none).
    pub far_field: Option<FarFieldSpec>,
}

/// `far_field = { distance = R }` of a `[[fixed]]` table: the set's surface triangles
/// are a cut face, supported by the tissue beyond it ([`crate::boundary`]).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FarFieldSpec {
    /// The distance from the loads inside (a needle's path) to the face, m: it sets the
    /// face's static springs, `4 G / R` normal and `3 G / R` tangential per unit area.
    pub distance: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FixedKeys {
    #[serde(default)]
    components: Components,
    name: Option<String>,
    far_field: Option<FarFieldSpec>,
}

impl<'de> Deserialize<'de> for FixedSelection {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let (nodes, k): (NodeSet, FixedKeys) = de_with_node_set(d)?;
        Ok(FixedSelection {
            nodes,
            components: k.components,
            name: k.name,
            far_field: k.far_field,
        })
    }
}

impl FixedSelection {
    /// Whether a rest position is in the set's region.
    pub fn contains(&self, p: [f64; 3]) -> bool {
        self.nodes.contains(p)
    }

    /// Checks the node set and the far-field keys; `key` is `fixed[i]`.
    pub fn validate(&self, key: &str) -> Result<(), SceneError> {
        self.nodes.validate(key)?;
        if let Some(f) = &self.far_field {
            if !(f.distance.is_finite() && f.distance > 0.0) {
                return Err(SceneError::invalid(
                    format!("{key}.far_field.distance"),
                    format!("must be a finite distance > 0 in m, got {}", f.distance),
                ));
            }
            if !self.components.all() {
                return Err(SceneError::invalid(
                    format!("{key}.components"),
                    "a far_field face is supported in every component (its springs and \
                     dashpots act normal and tangential to the face); leave `components` out",
                ));
            }
        }
        Ok(())
    }
}

/// `[[prescribed]]`: a node set moved by a prescribed displacement, in every component or
/// only in `components` (the others move freely: a frictionless plate). Give
/// `displacement` (m, reached linearly over `ramp` seconds, then held) or `velocity`
/// (m/s, from the start).
#[derive(Debug, Clone, PartialEq)]
pub struct Prescribed {
    /// The nodes.
    pub nodes: NodeSet,
    /// The components prescribed (default all).
    pub components: Components,
    /// How they move.
    pub motion: Motion,
    /// Name in the reaction output (default `prescribed<i>`).
    pub name: Option<String>,
}

/// A prescribed motion of a node set, as a displacement from the rest position.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Motion {
    /// `u(t) = displacement * min(t / ramp, 1)` (`ramp = 0`: from the first step).
    Displacement {
        /// Final displacement, m.
        displacement: [f64; 3],
        /// Ramp time, s.
        ramp: f64,
    },
    /// `u(t) = velocity * t`.
    Velocity {
        /// Velocity, m/s.
        velocity: [f64; 3],
    },
}

impl Motion {
    /// Displacement at time `t`.
    pub fn displacement(&self, t: f64) -> [f64; 3] {
        match *self {
            Motion::Displacement { displacement, ramp } => {
                let s = if ramp > 0.0 {
                    (t / ramp).clamp(0.0, 1.0)
                } else {
                    1.0
                };
                displacement.map(|u| u * s)
            }
            Motion::Velocity { velocity } => velocity.map(|v| v * t),
        }
    }

    /// Velocity at time `t` (the ramp's slope while it rises).
    pub fn velocity(&self, t: f64) -> [f64; 3] {
        match *self {
            Motion::Displacement { displacement, ramp } => {
                if ramp > 0.0 && t < ramp {
                    displacement.map(|u| u / ramp)
                } else {
                    [0.0; 3]
                }
            }
            Motion::Velocity { velocity } => velocity,
        }
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PrescribedKeys {
    #[serde(default)]
    components: Components,
    displacement: Option<[f64; 3]>,
    velocity: Option<[f64; 3]>,
    #[serde(default)]
    ramp: f64,
    name: Option<String>,
}

impl<'de> Deserialize<'de> for Prescribed {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        use serde::de::Error;
        let (nodes, k): (NodeSet, PrescribedKeys) = de_with_node_set(d)?;
        let motion = match (k.displacement, k.velocity) {
            (Some(displacement), None) => Motion::Displacement {
                displacement,
                ramp: k.ramp,
            },
            (None, Some(velocity)) if k.ramp == 0.0 => Motion::Velocity { velocity },
            (None, Some(_)) => {
                return Err(D::Error::custom(
                    "`ramp` goes with `displacement`, not `velocity`",
                ))
            }
            _ => {
                return Err(D::Error::custom(
                    "give exactly one of `displacement` and `velocity`",
                ))
            }
        };
        Ok(Prescribed {
            nodes,
            components: k.components,
            motion,
            name: k.name,
        })
    }
}

/// `[[load]]`: a surface load on the part of the surface a node set covers (the triangles
/// whose three corners it selects), reached linearly over `ramp` seconds. Give `traction`
/// (a force per area, Pa, in a fixed direction) or `pressure` (Pa, along the inward
/// normal). Each corner takes a third of each loaded triangle's load, on the rest shape
/// (small deformations: the load does not follow the surface as it turns).
#[derive(Debug, Clone, PartialEq)]
pub struct LoadSpec {
    /// The nodes (those on the surface take the load).
    pub nodes: NodeSet,
    /// The load.
    pub load: SurfaceLoad,
    /// Ramp time, s.
    pub ramp: f64,
    /// Name (for errors).
    pub name: Option<String>,
}

/// A load per unit surface area.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SurfaceLoad {
    /// Force per area, Pa.
    Traction([f64; 3]),
    /// Pressure, Pa (positive pushes inward).
    Pressure(f64),
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct LoadKeys {
    traction: Option<[f64; 3]>,
    pressure: Option<f64>,
    #[serde(default)]
    ramp: f64,
    name: Option<String>,
}

impl<'de> Deserialize<'de> for LoadSpec {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        use serde::de::Error;
        let (nodes, k): (NodeSet, LoadKeys) = de_with_node_set(d)?;
        let load = match (k.traction, k.pressure) {
            (Some(t), None) => SurfaceLoad::Traction(t),
            (None, Some(p)) => SurfaceLoad::Pressure(p),
            _ => {
                return Err(D::Error::custom(
                    "give exactly one of `traction` and `pressure`",
                ))
            }
        };
        Ok(LoadSpec {
            nodes,
            load,
            ramp: k.ramp,
            name: k.name,
        })
    }
}

impl Prescribed {
    /// Checks a `[[prescribed]]` table's values; errors name `key.<parameter>`.
    pub fn validate(&self, key: &str) -> Result<(), SceneError> {
        let p = self;
        p.nodes.validate(key)?;
        match p.motion {
            Motion::Displacement { displacement, ramp } => {
                for u in displacement {
                    finite(&format!("{key}.displacement"), u)?;
                }
                non_negative_finite(&format!("{key}.ramp"), ramp)?;
            }
            Motion::Velocity { velocity } => {
                for v in velocity {
                    finite(&format!("{key}.velocity"), v)?;
                }
            }
        }
        Ok(())
    }
}

impl LoadSpec {
    /// Checks a `[[load]]` table's values; errors name `key.<parameter>`.
    pub fn validate(&self, key: &str) -> Result<(), SceneError> {
        let l = self;
        l.nodes.validate(key)?;
        match l.load {
            SurfaceLoad::Traction(t) => {
                for c in t {
                    finite(&format!("{key}.traction"), c)?;
                }
            }
            SurfaceLoad::Pressure(p) => finite(&format!("{key}.pressure"), p)?,
        }
        non_negative_finite(&format!("{key}.ramp"), l.ramp)?;
        Ok(())
    }
}
