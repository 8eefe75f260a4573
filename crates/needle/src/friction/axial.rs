//! What both friction laws share: a node's friction state and the split of a force into
//! its axial and normal parts (paper equations 3 and 4).

use glam::DVec3;

/// Friction state of one needle node.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub enum FrictionState {
    /// Moves with the needle (static friction).
    #[default]
    Stick,
    /// Slides along the shaft (dynamic friction).
    Slip,
}

/// Axial component `f . t` and normal part `f - (f . t) t` of a force (eqs. 3 and 4).
pub fn split(f: [f64; 3], t: [f64; 3]) -> (f64, [f64; 3]) {
    let (p, n) = split_v(DVec3::from_array(f), DVec3::from_array(t));
    (p, n.to_array())
}

pub(crate) fn split_v(f: DVec3, t: DVec3) -> (f64, DVec3) {
    let p = f.dot(t);
    (p, f - t * p)
}

/// The needle's axial velocity relative to the node, `(v_needle - v_node) . t`.
pub(crate) fn relative_axial(v_node: [f64; 3], v_needle: [f64; 3], t: DVec3) -> f64 {
    (DVec3::from_array(v_needle) - DVec3::from_array(v_node)).dot(t)
}
