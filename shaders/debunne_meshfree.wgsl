// First pass of the Debunne meshfree model (models/debunne_meshfree.rs), composed after
// mls.wgsl: the linear stress of J_i, or co-rotated by node i's shape matching rotation.
// `deb_linear` and `deb_corotated` take the Lame constants and alpha mu from the uniform
// parameters; their `_mixed` variants take node i's `[lambda, mu, alpha mu, eta]`.
// `deb_corotated_mixed` reads the rotation that entry `deb_frame` stored just before, as
// binding both `shape_vector` and `node_material` would make it use 9 storage buffers (the
// device is asked for 8).

// sigma = lambda tr(eps) I + 2 mu eps with eps = sym(H), H a displacement gradient.
fn linear_stress(h: mat3x3<f32>, lambda: f32, mu: f32) -> mat3x3<f32> {
    let tr = h[0].x + h[1].y + h[2].z;
    let eps = 0.5 * (h + transpose(h));
    return 2.0 * mu * eps + lambda * tr * identity();
}

// Debunne's first pass of node i with Lame parameters lambda, mu and hourglass alpha mu.
fn deb_linear_node(i: u32, lambda: f32, mu: f32, hourglass: f32) {
    let g = gradient(i);
    store(i, linear_stress(g.j, lambda, mu), g, rest[i].w, hourglass);
}

// The same, co-rotated by the rotation q of node i's shape matching frame.
fn deb_rotated_node(i: u32, q: vec4<f32>, lambda: f32, mu: f32, hourglass: f32) {
    let r = quat_to_mat(q);
    let g = gradient(i);
    let s = linear_stress(mat_mul(transpose(r), g.j + identity()) - identity(), lambda, mu);
    store(i, mat_mul(r, s), g, rest[i].w, hourglass);
}

@compute @workgroup_size(64)
fn deb_linear(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = node_index(gid);
    if i >= params.n_active {
        return;
    }
    deb_linear_node(i, params.lambda, params.mu, params.hourglass);
}

@compute @workgroup_size(64)
fn deb_linear_mixed(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = node_index(gid);
    if i >= params.n_active {
        return;
    }
    let m = node_material[i];
    deb_linear_node(i, m.x, m.y, m.z);
}

@compute @workgroup_size(64)
fn deb_corotated(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = node_index(gid);
    if i >= params.n_active {
        return;
    }
    let fr = frame(i);
    rotation[i] = fr.q;
    deb_rotated_node(i, fr.q, params.lambda, params.mu, params.hourglass);
}

@compute @workgroup_size(64)
fn deb_frame(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = node_index(gid);
    if i >= params.n_active {
        return;
    }
    rotation[i] = frame(i).q;
}

@compute @workgroup_size(64)
fn deb_corotated_mixed(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = node_index(gid);
    if i >= params.n_active {
        return;
    }
    let m = node_material[i];
    deb_rotated_node(i, rotation[i], m.x, m.y, m.z);
}

// Viscoelastic: the linear stress relaxes (mls.wgsl::relax_stress); co-rotated, the stress
// of R^T F - I relaxes and is pushed by R, the rotation `deb_frame` stored just before.
@compute @workgroup_size(64)
fn deb_linear_visco(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = node_index(gid);
    if i >= params.n_active {
        return;
    }
    let g = gradient(i);
    store(i, relax_stress(i, linear_stress(g.j, params.lambda, params.mu)), g, rest[i].w, params.hourglass);
}

@compute @workgroup_size(64)
fn deb_linear_visco_mixed(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = node_index(gid);
    if i >= params.n_active {
        return;
    }
    let m = node_material[i];
    let g = gradient(i);
    store(i, relax_stress(i, linear_stress(g.j, m.x, m.y)), g, rest[i].w, m.z);
}

@compute @workgroup_size(64)
fn deb_corotated_visco(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = node_index(gid);
    if i >= params.n_active {
        return;
    }
    let r = quat_to_mat(rotation[i]);
    let g = gradient(i);
    let s = linear_stress(mat_mul(transpose(r), g.j + identity()) - identity(), params.lambda, params.mu);
    store(i, mat_mul(r, relax_stress(i, s)), g, rest[i].w, params.hourglass);
}

// Kelvin-Voigt viscosity (debunne_meshfree.rs::viscous_stress), a pass after the first
// pass that adds V_i sigma_v A_i^-1 to it (kelvin_voigt.wgsl): sigma_v = 2 eta
// dev(sym(L_i)), L_i the point-set velocity gradient; co-rotated, of R^T L_i pushed by R
// (the rotation the first pass stored).
fn add_viscous(i: u32, eta: f32, r: mat3x3<f32>) {
    if eta <= 0.0 {
        return;
    }
    let l = mat_mul(transpose(r), velocity_gradient(i));
    let d = 0.5 * (l + transpose(l));
    let mean = (d[0].x + d[1].y + d[2].z) / 3.0;
    add_first_pass_stress(i, mat_mul(r, 2.0 * eta * (d - mean * identity())));
}

@compute @workgroup_size(64)
fn deb_viscous(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = node_index(gid);
    if i >= params.n_active {
        return;
    }
    add_viscous(i, params.viscosity, identity());
}

@compute @workgroup_size(64)
fn deb_viscous_mixed(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = node_index(gid);
    if i >= params.n_active {
        return;
    }
    add_viscous(i, node_material[i].w, identity());
}

@compute @workgroup_size(64)
fn deb_viscous_corotated(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = node_index(gid);
    if i >= params.n_active {
        return;
    }
    add_viscous(i, params.viscosity, quat_to_mat(rotation[i]));
}

@compute @workgroup_size(64)
fn deb_viscous_corotated_mixed(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = node_index(gid);
    if i >= params.n_active {
        return;
    }
    add_viscous(i, node_material[i].w, quat_to_mat(rotation[i]));
}
