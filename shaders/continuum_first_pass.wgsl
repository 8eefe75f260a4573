// First pass of the two continuum models (mls.rs, debunne_meshfree.rs, point_based.rs):
// the moving-least-squares displacement gradient J_i, the stress P_i of the model, and the
// packed result [V P A^-1 - c J (9 floats), c, 0, 0] as three vec4 per node. The node
// volume V_i is the w lane of its rest position. The entries `deb_linear`, `deb_corotated`
// and `pba` take the material constants from the uniform parameters; their `_mixed`
// variants, for tissue with several materials, take node i's own from `node_material`
// (Debunne `[lambda, mu, alpha mu, 0]`, point based `[lambda, mu, k_v, alpha mu]`,
// models::material_row). Composed after cluster_frame.wgsl (the co-rotated entries).
// `deb_corotated_mixed` reads the rotation that entry `deb_frame` stored just before, as
// binding both `shape_vector` and `node_material` would make it use 9 storage buffers (the
// device is asked for 8).

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> rest: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> nb_index: array<u32>;
@group(0) @binding(4) var<storage, read> nb_weight: array<f32>;
@group(0) @binding(5) var<storage, read> inverse_moment: array<f32>;
@group(0) @binding(6) var<storage, read_write> first_pass: array<vec4<f32>>;
@group(0) @binding(8) var<storage, read> shape_vector: array<vec4<f32>>;
@group(0) @binding(9) var<storage, read_write> rotation: array<vec4<f32>>;
@group(0) @binding(10) var<storage, read> node_material: array<vec4<f32>>;

struct Gradient {
    j: mat3x3<f32>,
    trace: f32,
}

fn a_inv(i: u32) -> mat3x3<f32> {
    let b = 9u * i;
    return mat3x3<f32>(
        vec3<f32>(inverse_moment[b], inverse_moment[b + 1u], inverse_moment[b + 2u]),
        vec3<f32>(inverse_moment[b + 3u], inverse_moment[b + 4u], inverse_moment[b + 5u]),
        vec3<f32>(inverse_moment[b + 6u], inverse_moment[b + 7u], inverse_moment[b + 8u]),
    );
}

fn gradient(i: u32) -> Gradient {
    let xi = positions[i].xyz;
    let x0i = rest[i].xyz;
    var b = mat3x3<f32>(vec3<f32>(0.0), vec3<f32>(0.0), vec3<f32>(0.0));
    var trace = 0.0;
    for (var s = 0u; s < params.k; s++) {
        let w = nb_weight[i * params.k + s];
        if w == 0.0 {
            continue;
        }
        let j = nb_index[i * params.k + s];
        let d = positions[j].xyz - xi;
        let d0 = rest[j].xyz - x0i;
        let du = w * (d - d0);
        b[0] += du.x * d0;
        b[1] += du.y * d0;
        b[2] += du.z * d0;
        trace += w * dot(d0, d0);
    }
    return Gradient(mat_mul(b, a_inv(i)), trace);
}

fn identity() -> mat3x3<f32> {
    return mat3x3<f32>(vec3<f32>(1.0, 0.0, 0.0), vec3<f32>(0.0, 1.0, 0.0), vec3<f32>(0.0, 0.0, 1.0));
}

fn store(i: u32, p: mat3x3<f32>, g: Gradient, vol: f32, hourglass: f32) {
    let q = mat_mul(p, a_inv(i));
    var c = 0.0;
    if g.trace > 0.0 {
        c = hourglass * vol / g.trace;
    }
    let o0 = vol * q[0] - c * g.j[0];
    let o1 = vol * q[1] - c * g.j[1];
    let o2 = vol * q[2] - c * g.j[2];
    first_pass[3u * i] = vec4<f32>(o0, o1.x);
    first_pass[3u * i + 1u] = vec4<f32>(o1.y, o1.z, o2.x, o2.y);
    first_pass[3u * i + 2u] = vec4<f32>(o2.z, c, 0.0, 0.0);
}

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
