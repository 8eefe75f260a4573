//! The uniform parameter block every kernel reads, laid out once here; the `Params`
//! struct of the top-level `shaders/common.wgsl` must match it member by member (checked
//! by naga in this module's test).

use bytemuck::{Pod, Zeroable};

/// The uniform parameter block (`Params` in `shaders/common.wgsl`). Each model writes its
/// own constants ([`crate::models::GpuModel::write_params`]); the rest stay 0.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct Params {
    /// Active nodes.
    pub n_active: u32,
    /// Neighbour slots per node.
    pub k: u32,
    /// Rotation extraction iterations (shape matching, co-rotated Debunne).
    pub iterations: u32,
    /// Workgroups along x of a dispatch (wider ones continue along y).
    pub groups_x: u32,
    /// Time step, s.
    pub dt: f32,
    /// `1 / (1 + dt c)` of the mass-proportional damping.
    pub damping_factor: f32,
    /// Spring or shape matching stiffness, N/m.
    pub stiffness: f32,
    /// Mass-spring spring damping, N s/m.
    pub spring_damping: f32,
    /// Gravity, m/s^2; w = 1.0, a one the shader compiler cannot see (integrate.wgsl).
    pub gravity: [f32; 4],
    /// Lame lambda, Pa (continuum models).
    pub lambda: f32,
    /// Lame mu, Pa (continuum models).
    pub mu: f32,
    /// Volume stiffness, Pa (point based animation).
    pub volume_stiffness: f32,
    /// Hourglass alpha times mu, Pa (continuum models).
    pub hourglass: f32,
    /// Elements between slot `s` and slot `s + 1` of a node in the per-slot arrays: the
    /// capacity (they are stored slot-major, `crate::layout`).
    pub slot_stride: u32,
    /// Prony terms of a viscoelastic material (0: elastic).
    pub visco_terms: u32,
    /// `g_inf = 1 - sum g_i` of the Prony series.
    pub visco_g_inf: f32,
    /// Square of the divergence guard's speed bound, (m/s)^2 (`Backend::guard`): the
    /// integration flags a free node faster than this (infinite: only non-finite ones).
    pub max_speed_sq: f32,
    /// `exp(-dt / tau_i)` of each Prony term.
    pub visco_a: [f32; 4],
    /// `g_i (tau_i / dt) (1 - a_i)` of each Prony term.
    pub visco_b: [f32; 4],
    /// Kelvin-Voigt shear viscosity, Pa s (Debunne, neo-Hookean, point based animation,
    /// with one material).
    pub viscosity: f32,
    /// Hourglass alpha alone (point based animation with several materials: its node rows
    /// hold the viscosity where the neo-Hookean model's hold alpha mu).
    pub hourglass_alpha: f32,
    /// Padding to the WGSL struct's 16-byte size.
    pub pad: [f32; 2],
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::mem::{offset_of, size_of};

    /// The WGSL struct has the Rust struct's members at the same offsets, and the same
    /// size: a member added to one side only, reordered or retyped fails here.
    #[test]
    fn wgsl_params_match_the_rust_layout() {
        // common.wgsl refers to the `params` each kernel declares: parse it with one.
        let source = crate::kernels::INTEGRATE_NODE.sources.join("\n");
        let module = naga::front::wgsl::parse_str(&source).expect("common.wgsl");
        let (_, ty) = module
            .types
            .iter()
            .find(|(_, t)| t.name.as_deref() == Some("Params"))
            .expect("struct Params in common.wgsl");
        let naga::TypeInner::Struct { members, span } = &ty.inner else {
            panic!("Params is not a struct");
        };
        let wgsl: Vec<(String, u32)> = members
            .iter()
            .map(|m| (m.name.clone().unwrap_or_default(), m.offset))
            .collect();
        let rust: Vec<(&str, usize)> = vec![
            ("n_active", offset_of!(Params, n_active)),
            ("k", offset_of!(Params, k)),
            ("iterations", offset_of!(Params, iterations)),
            ("groups_x", offset_of!(Params, groups_x)),
            ("dt", offset_of!(Params, dt)),
            ("damping_factor", offset_of!(Params, damping_factor)),
            ("stiffness", offset_of!(Params, stiffness)),
            ("spring_damping", offset_of!(Params, spring_damping)),
            ("gravity", offset_of!(Params, gravity)),
            ("lambda", offset_of!(Params, lambda)),
            ("mu", offset_of!(Params, mu)),
            ("volume_stiffness", offset_of!(Params, volume_stiffness)),
            ("hourglass", offset_of!(Params, hourglass)),
            ("slot_stride", offset_of!(Params, slot_stride)),
            ("visco_terms", offset_of!(Params, visco_terms)),
            ("visco_g_inf", offset_of!(Params, visco_g_inf)),
            ("max_speed_sq", offset_of!(Params, max_speed_sq)),
            ("visco_a", offset_of!(Params, visco_a)),
            ("visco_b", offset_of!(Params, visco_b)),
            ("viscosity", offset_of!(Params, viscosity)),
            ("hourglass_alpha", offset_of!(Params, hourglass_alpha)),
        ];
        for (name, offset) in &rust {
            let found = wgsl.iter().find(|(n, _)| n == name);
            assert_eq!(
                found.map(|(_, o)| *o as usize),
                Some(*offset),
                "member `{name}`: WGSL {found:?}, Rust offset {offset}"
            );
        }
        // Every WGSL member that is not padding is one of the Rust members.
        for (n, _) in wgsl.iter().filter(|(n, _)| !n.starts_with("pad")) {
            assert!(
                rust.iter().any(|(r, _)| r == n),
                "WGSL member `{n}` not in Rust"
            );
        }
        assert_eq!(*span as usize, size_of::<Params>());
    }
}
