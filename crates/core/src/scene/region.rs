//! `[[region]]`: parts of the tissue with their own material (resolved by
//! [`crate::regions`]).

use super::tissue::{one, AxisRotation};
use serde::Deserialize;
use std::path::PathBuf;

/// One `[[region]]` table.
#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct RegionSpec {
    /// Unique name (errors, CSV and Python name regions by it).
    pub name: String,
    /// Where the region is.
    #[serde(deserialize_with = "de_region_geometry")]
    pub geometry: RegionGeometry,
    /// Mass density in kg/m^3 (default: `tissue.density`).
    #[serde(default)]
    pub density: Option<f64>,
    /// The region's material parameters, for the scene's model (required).
    #[serde(default)]
    pub material: Option<toml::Table>,
    /// The needle's parameters in this region (read by `needlesim-needle`).
    #[serde(default)]
    pub needle: Option<toml::Table>,
}

/// The shape of a region.
#[derive(Debug, Clone, PartialEq)]
pub enum RegionGeometry {
    /// `kind = "box"`: an axis-aligned box, faces included.
    Box {
        /// Lower corner, m.
        min: [f64; 3],
        /// Upper corner, m.
        max: [f64; 3],
    },
    /// `kind = "obj"`, `"stl"` or `"vtk"`: the inside of a closed surface file.
    Surface(RegionSurface),
}

/// A closed surface file bounding a region.
#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct RegionSurface {
    /// `obj`, `stl` or `vtk` (set from `kind`).
    #[serde(skip)]
    pub kind: String,
    /// Path, relative to the scene file.
    pub path: PathBuf,
    /// Factor on the file's coordinates.
    #[serde(default = "one")]
    pub scale: f64,
    /// Rotation after `scale`.
    #[serde(default)]
    pub rotate: Option<AxisRotation>,
    /// Translation in m, applied last.
    #[serde(default)]
    pub translate: [f64; 3],
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RegionBoxKeys {
    min: [f64; 3],
    max: [f64; 3],
}

fn de_region_geometry<'de, D: serde::Deserializer<'de>>(d: D) -> Result<RegionGeometry, D::Error> {
    use serde::de::Error;
    let mut t = toml::Table::deserialize(d)?;
    let kind = match t.remove("kind") {
        Some(toml::Value::String(s)) => s,
        _ => {
            return Err(D::Error::custom(
                "`region.geometry` needs `kind` = \"box\", \"obj\", \"stl\" or \"vtk\"",
            ))
        }
    };
    let msg = |e: toml::de::Error| {
        D::Error::custom(format!(
            "`region.geometry` (kind = \"{kind}\"): {}",
            e.to_string().trim_end().replace('\n', " ")
        ))
    };
    match kind.as_str() {
        "box" => {
            let b: RegionBoxKeys = toml::Value::Table(t).try_into().map_err(msg)?;
            Ok(RegionGeometry::Box {
                min: b.min,
                max: b.max,
            })
        }
        "obj" | "stl" | "vtk" => {
            let mut s: RegionSurface = toml::Value::Table(t).try_into().map_err(msg)?;
            s.kind = kind;
            Ok(RegionGeometry::Surface(s))
        }
        other => Err(D::Error::custom(format!(
            "`region.geometry.kind`: unknown variant `{other}` (box, obj, stl or vtk)"
        ))),
    }
}
