// Local shape matching, first part (local_shape_matching.rs): every node's cluster centre
// offset c_i and rotation R_i (warm-started quaternion). Entry `node_force` also writes the
// paper's force k_s (c_i + R_i v_i), and entry `node_force_mixed` the same with node i's own
// k_s from `node_material` (`[k_s, 0, 0, 0]` per node, several materials); entry
// `cluster_frame` writes c_i for the second pass (lshm_cluster_force.wgsl), and
// `cluster_frame_mixed` writes (c_i, k_s,i): the second pass's `mixed` entry reads each
// cluster's stiffness there, as binding `node_material` too would make it use 9 storage
// buffers (the device is asked for 8). Composed after cluster_frame.wgsl.

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> rest: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> shape_vector: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read> nb_index: array<u32>;
@group(0) @binding(5) var<storage, read> nb_weight: array<f32>;
@group(0) @binding(6) var<storage, read_write> rotation: array<vec4<f32>>;
@group(0) @binding(7) var<storage, read_write> out: array<vec4<f32>>;
@group(0) @binding(10) var<storage, read> node_material: array<vec4<f32>>;

@compute @workgroup_size(64)
fn node_force(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = node_index(gid);
    if i >= params.n_active {
        return;
    }
    let fr = frame(i);
    rotation[i] = fr.q;
    let rv = quat_rotate(fr.q, shape_vector[i].xyz);
    out[i] = vec4<f32>(params.stiffness * (fr.c + rv), 0.0);
}

@compute @workgroup_size(64)
fn node_force_mixed(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = node_index(gid);
    if i >= params.n_active {
        return;
    }
    let fr = frame(i);
    rotation[i] = fr.q;
    let rv = quat_rotate(fr.q, shape_vector[i].xyz);
    out[i] = vec4<f32>(node_material[i].x * (fr.c + rv), 0.0);
}

@compute @workgroup_size(64)
fn cluster_frame(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = node_index(gid);
    if i >= params.n_active {
        return;
    }
    let fr = frame(i);
    rotation[i] = fr.q;
    out[i] = vec4<f32>(fr.c, 0.0);
}

@compute @workgroup_size(64)
fn cluster_frame_mixed(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = node_index(gid);
    if i >= params.n_active {
        return;
    }
    let fr = frame(i);
    rotation[i] = fr.q;
    out[i] = vec4<f32>(fr.c, node_material[i].x);
}
