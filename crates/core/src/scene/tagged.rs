//! Tables whose variant a key selects (`[material]` by `model`, the geometry by `kind`,
//! the weight by `kernel`), with errors that name the table, the variant and the key.

use serde::Deserialize;

/// Deserialises a table whose key `tag` selects the variant; the rest of the table is
/// read by `pick(variant_name, rest)`. Errors name the table, the variant and the key.
pub(crate) fn de_tagged<'de, D, T>(
    d: D,
    table: &str,
    tag: &str,
    pick: impl FnOnce(&str, toml::Value) -> Option<Result<T, toml::de::Error>>,
) -> Result<T, D::Error>
where
    D: serde::Deserializer<'de>,
{
    use serde::de::Error;
    let mut t = toml::Table::deserialize(d)?;
    let name = match t.remove(tag) {
        Some(toml::Value::String(s)) => s,
        Some(other) => {
            return Err(D::Error::custom(format!(
                "`{table}.{tag}` must be a string, got {other}"
            )))
        }
        None => return Err(D::Error::custom(format!("`{table}` needs the key `{tag}`"))),
    };
    match pick(&name, toml::Value::Table(t)) {
        Some(r) => r.map_err(|e| {
            D::Error::custom(format!(
                "`{table}` ({tag} = \"{name}\"): {}",
                e.to_string().trim_end().replace('\n', " ")
            ))
        }),
        None => Err(D::Error::custom(format!(
            "`{table}.{tag}`: unknown variant `{name}`"
        ))),
    }
}
