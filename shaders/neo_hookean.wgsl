// First pass of the compressible neo-Hookean model (models/neo_hookean.rs), composed after
// mls.wgsl: P = mu F + (lambda l(J) - mu) l'(J) cof(F) of F = I + J_i, with l(J) = ln J
// continued by its tangent below J_MIN. Constants from the uniform parameters
// (`neo_hookean`) or node i's own [lambda, mu, eta, alpha mu] (`neo_hookean_mixed`).
// The Kelvin-Voigt pass (`nh_viscous`, after the first pass; composed after
// kelvin_voigt.wgsl) adds P_v = F 2 eta dev(sym(F^T L_i)) (continuum.rs).

const J_MIN: f32 = 0.62;

// The stress P of F, with the cofactor matrix and the volume ratio it used.
struct NeoHookeanStress {
    p: mat3x3<f32>,
    cof: mat3x3<f32>,
    det: f32,
}

fn neo_hookean_stress(f: mat3x3<f32>, lambda: f32, mu: f32) -> NeoHookeanStress {
    // Rows of the cofactor matrix (these matrices hold rows in their columns).
    let cof = mat3x3<f32>(cross(f[1], f[2]), cross(f[2], f[0]), cross(f[0], f[1]));
    let det = dot(f[0], cof[0]);
    var l = log(J_MIN) + (det - J_MIN) / J_MIN;
    var dl = 1.0 / J_MIN;
    if det >= J_MIN {
        l = log(det);
        dl = 1.0 / det;
    }
    return NeoHookeanStress(mu * f + ((lambda * l - mu) * dl) * cof, cof, det);
}

fn neo_hookean_node(i: u32, lambda: f32, mu: f32, hourglass: f32) {
    let g = gradient(i);
    store(i, neo_hookean_stress(g.j + identity(), lambda, mu).p, g, rest[i].w, hourglass);
}

@compute @workgroup_size(64)
fn neo_hookean(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = node_index(gid);
    if i >= params.n_active {
        return;
    }
    neo_hookean_node(i, params.lambda, params.mu, params.hourglass);
}

@compute @workgroup_size(64)
fn neo_hookean_mixed(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = node_index(gid);
    if i >= params.n_active {
        return;
    }
    let m = node_material[i];
    neo_hookean_node(i, m.x, m.y, m.w);
}

// Viscoelastic: S = F^-1 P relaxes (mls.wgsl::relax_stress), P = F S.
fn neo_hookean_visco_node(i: u32, lambda: f32, mu: f32, hourglass: f32) {
    let g = gradient(i);
    let f = g.j + identity();
    let st = neo_hookean_stress(f, lambda, mu);
    // F^-1 = cof^T / det.
    let s = relax_stress(i, mat_mul(transpose(st.cof) * (1.0 / st.det), st.p));
    store(i, mat_mul(f, s), g, rest[i].w, hourglass);
}

@compute @workgroup_size(64)
fn neo_hookean_visco(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = node_index(gid);
    if i >= params.n_active {
        return;
    }
    neo_hookean_visco_node(i, params.lambda, params.mu, params.hourglass);
}

@compute @workgroup_size(64)
fn neo_hookean_visco_mixed(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = node_index(gid);
    if i >= params.n_active {
        return;
    }
    let m = node_material[i];
    neo_hookean_visco_node(i, m.x, m.y, m.w);
}

@compute @workgroup_size(64)
fn nh_viscous(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = node_index(gid);
    if i >= params.n_active {
        return;
    }
    add_finite_viscous(i, params.viscosity);
}

@compute @workgroup_size(64)
fn nh_viscous_mixed(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = node_index(gid);
    if i >= params.n_active {
        return;
    }
    add_finite_viscous(i, node_material[i].z);
}
