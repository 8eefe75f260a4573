// Second pass of the continuum models (mls.rs::gather_force): the force on node k from
// every node's packed first-pass result,
// f_k = sum_i w_ki (Q_i d0_ki + (c_i + c_k) (d_ki - d0_ki)) + Q_k sum_i w_ki d0_ki.

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> rest: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> nb_index: array<u32>;
@group(0) @binding(4) var<storage, read> nb_weight: array<f32>;
@group(0) @binding(5) var<storage, read> first_pass: array<vec4<f32>>;
@group(0) @binding(6) var<storage, read_write> forces: array<vec4<f32>>;

struct Packed {
    q: mat3x3<f32>,
    c: f32,
}

fn packed(i: u32) -> Packed {
    let a = first_pass[3u * i];
    let b = first_pass[3u * i + 1u];
    let e = first_pass[3u * i + 2u];
    return Packed(mat3x3<f32>(a.xyz, vec3<f32>(a.w, b.x, b.y), vec3<f32>(b.z, b.w, e.x)), e.y);
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = node_index(gid);
    if k >= params.n_active {
        return;
    }
    let xk = positions[k].xyz;
    let x0k = rest[k].xyz;
    let own = packed(k);
    var f = vec3<f32>(0.0);
    var m = vec3<f32>(0.0);
    for (var s = 0u; s < params.k; s++) {
        let w = nb_weight[slot(k, s)];
        if w == 0.0 {
            continue;
        }
        let i = nb_index[slot(k, s)];
        let d0 = rest[i].xyz - x0k;
        let d = positions[i].xyz - xk;
        let qi = packed(i);
        f += w * mat_vec(qi.q, d0) + w * (qi.c + own.c) * (d - d0);
        m += w * d0;
    }
    f += mat_vec(own.q, m);
    forces[k] = vec4<f32>(f, 0.0);
}
