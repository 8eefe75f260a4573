// First pass of point based animation (models/point_based.rs), composed after mls.wgsl:
// P = F S of the Green strain plus the optional volume term, with constants
// [lambda, mu, k_v, alpha mu] from the uniform parameters (`pba`) or node i's own
// (`pba_mixed`).

// Point based animation's first pass of node i with constants c = [lambda, mu, k_v, alpha mu].
fn pba_node(i: u32, c: vec4<f32>) {
    let g = gradient(i);
    let f = g.j + identity();
    let e = 0.5 * (mat_mul(transpose(f), f) - identity());
    let tr = e[0].x + e[1].y + e[2].z;
    let s = 2.0 * c.y * e + c.x * tr * identity();
    var p = mat_mul(f, s);
    if c.z > 0.0 {
        let cof = mat3x3<f32>(cross(f[1], f[2]), cross(f[2], f[0]), cross(f[0], f[1]));
        let det = dot(f[0], cof[0]);
        p += c.z * (det - 1.0) * cof;
    }
    store(i, p, g, rest[i].w, c.w);
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
    pba_node(i, node_material[i]);
}

// Viscoelastic: S relaxes (mls.wgsl::relax_stress), P = F S plus the elastic volume term.
fn pba_visco_node(i: u32, c: vec4<f32>) {
    let g = gradient(i);
    let f = g.j + identity();
    let e = 0.5 * (mat_mul(transpose(f), f) - identity());
    let tr = e[0].x + e[1].y + e[2].z;
    let s = relax_stress(i, 2.0 * c.y * e + c.x * tr * identity());
    var p = mat_mul(f, s);
    if c.z > 0.0 {
        let cof = mat3x3<f32>(cross(f[1], f[2]), cross(f[2], f[0]), cross(f[0], f[1]));
        let det = dot(f[0], cof[0]);
        p += c.z * (det - 1.0) * cof;
    }
    store(i, p, g, rest[i].w, c.w);
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
    pba_visco_node(i, node_material[i]);
}
