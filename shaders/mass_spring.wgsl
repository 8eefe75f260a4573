// Weighted mass-spring force (mass_spring.rs::force). Entry `mixed`, for tissue with
// several materials, gives each spring the series mean of its two nodes' stiffness and
// damping from `node_material` (`[k, c, 0, 0]` per node, mass_spring.rs::force_mixed).

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> velocities: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> nb_index: array<u32>;
@group(0) @binding(4) var<storage, read> nb_weight: array<f32>;
@group(0) @binding(5) var<storage, read> rest_length: array<f32>;
@group(0) @binding(6) var<storage, read_write> forces: array<vec4<f32>>;
@group(0) @binding(10) var<storage, read> node_material: array<vec4<f32>>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = node_index(gid);
    if i >= params.n_active {
        return;
    }
    let xi = positions[i].xyz;
    let vi = velocities[i].xyz;
    var f = vec3<f32>(0.0);
    for (var s = 0u; s < params.k; s++) {
        let slot = slot(i, s);
        let w = nb_weight[slot];
        if w == 0.0 {
            continue;
        }
        let j = nb_index[slot];
        let d = positions[j].xyz - xi;
        let len = length(d);
        if len <= 0.0 {
            continue;
        }
        let inv = 1.0 / len;
        let dv = velocities[j].xyz - vi;
        let mag = w * (params.stiffness * (len - rest_length[slot]) + params.spring_damping * dot(dv, d) * inv) * inv;
        f += mag * d;
    }
    forces[i] = vec4<f32>(f, 0.0);
}

// 2 a b / (a + b), 0 when both are 0 (mass_spring.rs::series_mean).
fn series_mean(a: f32, b: f32) -> f32 {
    let s = a + b;
    if s > 0.0 {
        return 2.0 * a * b / s;
    }
    return 0.0;
}

@compute @workgroup_size(64)
fn mixed(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = node_index(gid);
    if i >= params.n_active {
        return;
    }
    let xi = positions[i].xyz;
    let vi = velocities[i].xyz;
    let mi = node_material[i];
    var f = vec3<f32>(0.0);
    for (var s = 0u; s < params.k; s++) {
        let slot = slot(i, s);
        let w = nb_weight[slot];
        if w == 0.0 {
            continue;
        }
        let j = nb_index[slot];
        let d = positions[j].xyz - xi;
        let len = length(d);
        if len <= 0.0 {
            continue;
        }
        let mj = node_material[j];
        let k = series_mean(mi.x, mj.x);
        let c = series_mean(mi.y, mj.y);
        let inv = 1.0 / len;
        let dv = velocities[j].xyz - vi;
        let mag = w * (k * (len - rest_length[slot]) + c * dot(dv, d) * inv) * inv;
        f += mag * d;
    }
    forces[i] = vec4<f32>(f, 0.0);
}
