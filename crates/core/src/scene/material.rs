//! `[material]`: the model, chosen by the key `model`, and its parameters
//! ([`crate::models`]).

use super::tagged::de_tagged;
use crate::models::Material;
use serde::Deserialize;

/// A material table with its `model` key, deserialised ([`crate::regions`]).
pub(crate) struct MaterialTable(pub Material);

impl<'de> Deserialize<'de> for MaterialTable {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        de_material(d).map(MaterialTable)
    }
}

pub(crate) fn de_material<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Material, D::Error> {
    de_tagged(d, "material", "model", Material::from_tagged)
}
