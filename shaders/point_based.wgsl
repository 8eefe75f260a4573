// First pass of point based animation (models/point_based.rs), composed after mls.wgsl:
// P = F S of the Green strain plus the optional volume term, with constants
// [lambda, mu, k_v, alpha mu] from the uniform parameters (`pba`) or from node i's row
// [lambda, mu, k_v, eta] and the material's alpha (`pba_mixed`). The Kelvin-Voigt pass
// (`pba_viscous`, after the first pass; kelvin_voigt.wgsl) adds the finite-strain dashpot.

// The second Piola-Kirchhoff stress S of the Green strain of F, constants c = [lambda, mu, ..].
fn green_stress(f: mat3x3<f32>, c: vec4<f32>) -> mat3x3<f32> {
    let e = 0.5 * (mat_mul(transpose(f), f) - identity());
    let tr = e[0].x + e[1].y + e[2].z;
    return 2.0 * c.y * e + c.x * tr * identity();
}

// p plus the volume term k_v (det F - 1) cof F when k_v = c.z is positive.
fn with_volume_term(p: mat3x3<f32>, f: mat3x3<f32>, c: vec4<f32>) -> mat3x3<f32> {
    if c.z > 0.0 {
        let cof = mat3x3<f32>(cross(f[1], f[2]), cross(f[2], f[0]), cross(f[0], f[1]));
        let det = dot(f[0], cof[0]);
        return p + c.z * (det - 1.0) * cof;
    }
    return p;
}

// Point based animation's first pass of node i with constants c = [lambda, mu, k_v, alpha mu].
fn pba_node(i: u32, c: vec4<f32>) {
    let g = gradient(i);
    let f = g.j + identity();
    store(i, with_volume_term(mat_mul(f, green_stress(f, c)), f, c), g, rest[i].w, c.w);
}

@compute @workgroup_size(64)
fn pba(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = node_index(gid);
    if i >= params.n_active {
        return;
    }
    pba_node(i, vec4<f32>(params.lambda, params.mu, params.volume_stiffness, params.hourglass));
}

@compute @workgroup_size(64)
fn pba_mixed(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = node_index(gid);
    if i >= params.n_active {
        return;
    }
    let m = node_material[i];
    pba_node(i, vec4<f32>(m.x, m.y, m.z, params.hourglass_alpha * m.y));
}

// Viscoelastic: S relaxes (mls.wgsl::relax_stress), P = F S plus the elastic volume term.
fn pba_visco_node(i: u32, c: vec4<f32>) {
    let g = gradient(i);
    let f = g.j + identity();
    let p = mat_mul(f, relax_stress(i, green_stress(f, c)));
    store(i, with_volume_term(p, f, c), g, rest[i].w, c.w);
}

@compute @workgroup_size(64)
fn pba_visco(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = node_index(gid);
    if i >= params.n_active {
        return;
    }
    pba_visco_node(i, vec4<f32>(params.lambda, params.mu, params.volume_stiffness, params.hourglass));
}

@compute @workgroup_size(64)
fn pba_visco_mixed(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = node_index(gid);
    if i >= params.n_active {
        return;
    }
    let m = node_material[i];
    pba_visco_node(i, vec4<f32>(m.x, m.y, m.z, params.hourglass_alpha * m.y));
}

@compute @workgroup_size(64)
fn pba_viscous(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = node_index(gid);
    if i >= params.n_active {
        return;
    }
    add_finite_viscous(i, params.viscosity);
}

@compute @workgroup_size(64)
fn pba_viscous_mixed(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = node_index(gid);
    if i >= params.n_active {
        return;
    }
    add_finite_viscous(i, node_material[i].w);
}
