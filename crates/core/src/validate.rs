//! Checks of scene values shared by the scene tables and the model parameters. Each
//! returns a [`SceneError`] naming the dotted key and the value.
//!
//! Every parameter a kernel reads goes through f32, so a value must also survive that
//! conversion ([`fits_f32`]).

use crate::error::SceneError;

/// Checks `rotation_iterations`: between 1 and 100.
pub(crate) fn rotation_iterations_in_range(key: &str, n: u32) -> Result<(), SceneError> {
    if n == 0 || n > 100 {
        return Err(SceneError::invalid(
            format!("{key}.rotation_iterations"),
            format!("must be between 1 and 100, got {n}"),
        ));
    }
    Ok(())
}

/// Checks a Young modulus (> 0) and a Poisson ratio (strictly between -1 and 0.5).
pub(crate) fn elastic_moduli(
    key: &str,
    young_modulus: f64,
    poisson_ratio: f64,
) -> Result<(), SceneError> {
    positive_finite(&format!("{key}.young_modulus"), young_modulus)?;
    if !(poisson_ratio.is_finite() && poisson_ratio > -1.0 && poisson_ratio < 0.5) {
        return Err(SceneError::invalid(
            format!("{key}.poisson_ratio"),
            format!(
                "must lie strictly between -1 and 0.5 (0.5 is incompressible, which an \
                 explicit model cannot step), got {poisson_ratio}"
            ),
        ));
    }
    Ok(())
}

/// Whether `v` survives the f32 conversion every kernel input goes through: finite in f32,
/// and not flushed to zero or a subnormal (only 0 itself is 0).
pub(crate) fn fits_f32(v: f64) -> bool {
    let f = v as f32;
    f.is_finite() && (v == 0.0 || f.is_normal())
}

/// The f32 range a parameter must lie in, for error messages.
pub(crate) const F32_RANGE: &str =
    "its magnitude must lie between 1.2e-38 and 3.4e38 (it is used in f32)";

/// Checks that `v` is finite and fits f32.
pub(crate) fn finite(key: &str, v: f64) -> Result<(), SceneError> {
    if !v.is_finite() {
        Err(SceneError::invalid(key, format!("must be finite, got {v}")))
    } else if !fits_f32(v) {
        Err(SceneError::invalid(key, format!("{v:e}: {F32_RANGE}")))
    } else {
        Ok(())
    }
}

/// Checks that `v` is finite, > 0 and fits f32.
pub(crate) fn positive_finite(key: &str, v: f64) -> Result<(), SceneError> {
    if !(v.is_finite() && v > 0.0) {
        Err(SceneError::invalid(
            key,
            format!("must be a finite number > 0, got {v}"),
        ))
    } else if !fits_f32(v) {
        Err(SceneError::invalid(key, format!("{v:e}: {F32_RANGE}")))
    } else {
        Ok(())
    }
}

/// Checks that `v` is finite, >= 0 and fits f32.
pub(crate) fn non_negative_finite(key: &str, v: f64) -> Result<(), SceneError> {
    if !(v.is_finite() && v >= 0.0) {
        Err(SceneError::invalid(
            key,
            format!("must be a finite number >= 0, got {v}"),
        ))
    } else if !fits_f32(v) {
        Err(SceneError::invalid(key, format!("{v:e}: {F32_RANGE}")))
    } else {
        Ok(())
    }
}
