// Local shape matching, cluster variant, second pass (local_shape_matching.rs::
// cluster_force): every cluster i containing node j pulls it towards its goal,
// f_j = k_s sum_i w_ij (g_ij - x_j), its own cluster with weight 1. Entry `mixed`, for
// several materials, weighs each cluster by its own k_s,i, which lshm_frame.wgsl's
// `cluster_frame_mixed` put in the w lane of centre[i]
// (local_shape_matching.rs::cluster_force_mixed).

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> rest: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> shape_vector: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read> nb_index: array<u32>;
@group(0) @binding(5) var<storage, read> nb_weight: array<f32>;
@group(0) @binding(6) var<storage, read> rotation: array<vec4<f32>>;
@group(0) @binding(7) var<storage, read> centre: array<vec4<f32>>;
@group(0) @binding(8) var<storage, read_write> forces: array<vec4<f32>>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let j = node_index(gid);
    if j >= params.n_active {
        return;
    }
    let xj = positions[j].xyz;
    let x0j = rest[j].xyz;
    var f = centre[j].xyz + quat_rotate(rotation[j], shape_vector[j].xyz);
    for (var s = 0u; s < params.k; s++) {
        let w = nb_weight[slot(j, s)];
        if w == 0.0 {
            continue;
        }
        let i = nb_index[slot(j, s)];
        let d = positions[i].xyz - xj;
        let q0 = x0j - rest[i].xyz;
        let r = quat_rotate(rotation[i], q0 + shape_vector[i].xyz);
        f += w * (d + centre[i].xyz + r);
    }
    forces[j] = vec4<f32>(params.stiffness * f, 0.0);
}

@compute @workgroup_size(64)
fn mixed(@builtin(global_invocation_id) gid: vec3<u32>) {
    let j = node_index(gid);
    if j >= params.n_active {
        return;
    }
    let xj = positions[j].xyz;
    let x0j = rest[j].xyz;
    var f = centre[j].w * (centre[j].xyz + quat_rotate(rotation[j], shape_vector[j].xyz));
    for (var s = 0u; s < params.k; s++) {
        let w = nb_weight[slot(j, s)];
        if w == 0.0 {
            continue;
        }
        let i = nb_index[slot(j, s)];
        let d = positions[i].xyz - xj;
        let q0 = x0j - rest[i].xyz;
        let r = quat_rotate(rotation[i], q0 + shape_vector[i].xyz);
        f += (centre[i].w * w) * (d + centre[i].xyz + r);
    }
    forces[j] = vec4<f32>(f, 0.0);
}
