// Second pass of the continuum models (mls.rs::gather_force): the force on node k from
// every node's packed first-pass result,
// f_k = sum_i w_ki (Q_i d0_ki + (c_i + c_k) (d_ki - d0_ki) + (c_i H_i - c_k H_k) s(d0_ki))
//       + Q_k sum_i w_ki d0_ki,
// s the quadratic monomials of the rest offset.

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> rest: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> nb_index: array<u32>;
@group(0) @binding(4) var<storage, read> nb_weight: array<f32>;
@group(0) @binding(5) var<storage, read> first_pass: array<vec4<f32>>;
@group(0) @binding(6) var<storage, read_write> forces: array<vec4<f32>>;

// Written out as fields, not an array (see the loop below for why).
struct Packed {
    q: mat3x3<f32>,
    c: f32,
    h0: vec3<f32>,
    h1: vec3<f32>,
    h2: vec3<f32>,
    h3: vec3<f32>,
    h4: vec3<f32>,
    h5: vec3<f32>,
}

fn packed(i: u32) -> Packed {
    let o = FIRST_PASS_VEC4 * i;
    let a = first_pass[o];
    let b = first_pass[o + 1u];
    let e = first_pass[o + 2u];
    let f = first_pass[o + 3u];
    let g = first_pass[o + 4u];
    let h = first_pass[o + 5u];
    let l = first_pass[o + 6u];
    return Packed(
        mat3x3<f32>(a.xyz, vec3<f32>(a.w, b.x, b.y), vec3<f32>(b.z, b.w, e.x)),
        e.y,
        vec3<f32>(e.z, e.w, f.x),
        f.yzw,
        g.xyz,
        vec3<f32>(g.w, h.x, h.y),
        vec3<f32>(h.z, h.w, l.x),
        l.yzw,
    );
}

// A neighbour's part of the sum: its weight, its index (k itself for an empty slot, so
// that its loads stay in bounds), and what it contributes.
struct Neighbour {
    w: f32,
    i: u32,
}

fn neighbour(k: u32, s: u32) -> Neighbour {
    if s >= params.k {
        return Neighbour(0.0, k);
    }
    let w = nb_weight[slot(k, s)];
    return Neighbour(w, select(nb_index[slot(k, s)], k, w == 0.0));
}

// One neighbour's term of f_k, zero for an empty slot.
fn term(w: f32, q: Packed, d0: vec3<f32>, d: vec3<f32>, own: Packed) -> vec3<f32> {
    if w == 0.0 {
        return vec3<f32>(0.0);
    }
    let h = (q.h0 - own.h0) * (d0.x * d0.x) + (q.h1 - own.h1) * (d0.y * d0.y)
        + (q.h2 - own.h2) * (d0.z * d0.z) + (q.h3 - own.h3) * (d0.x * d0.y)
        + (q.h4 - own.h4) * (d0.y * d0.z) + (q.h5 - own.h5) * (d0.z * d0.x);
    return w * mat_vec(q.q, d0) + w * (q.c + own.c) * (d - d0) + w * h;
}

// One neighbour's term of sum_i w_ki d0_ki, zero for an empty slot.
fn moment(w: f32, d0: vec3<f32>) -> vec3<f32> {
    if w == 0.0 {
        return vec3<f32>(0.0);
    }
    return w * d0;
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
    // Four slots at a time: their indices first, then their loads, then the sums in slot
    // order (the same operations as one slot at a time; see mass_spring.wgsl for why).
    // Written out, not as arrays: arrays indexed in a loop (a struct of a mat3x3 each)
    // went to local memory and made this kernel 2.9 times slower at 1M nodes on an H100.
    for (var s = 0u; s < params.k; s += 4u) {
        let na = neighbour(k, s);
        let nb = neighbour(k, s + 1u);
        let ne = neighbour(k, s + 2u);
        let ng = neighbour(k, s + 3u);
        let d0a = rest[na.i].xyz - x0k;
        let d0b = rest[nb.i].xyz - x0k;
        let d0e = rest[ne.i].xyz - x0k;
        let d0g = rest[ng.i].xyz - x0k;
        let da = positions[na.i].xyz - xk;
        let db = positions[nb.i].xyz - xk;
        let de = positions[ne.i].xyz - xk;
        let dg = positions[ng.i].xyz - xk;
        let qa = packed(na.i);
        let qb = packed(nb.i);
        let qe = packed(ne.i);
        let qg = packed(ng.i);
        f += term(na.w, qa, d0a, da, own);
        m += moment(na.w, d0a);
        f += term(nb.w, qb, d0b, db, own);
        m += moment(nb.w, d0b);
        f += term(ne.w, qe, d0e, de, own);
        m += moment(ne.w, d0e);
        f += term(ng.w, qg, d0g, dg, own);
        m += moment(ng.w, d0g);
    }
    f += mat_vec(own.q, m);
    forces[k] = vec4<f32>(f, 0.0);
}
