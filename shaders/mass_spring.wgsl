// Weighted mass-spring force (mass_spring.rs::force). Entry `mixed`, for tissue with
// several materials, gives each spring the series mean of its two nodes' stiffness and
// damping from `node_material` (`[k, c, 0, 0]` per node, mass_spring.rs::force_mixed).
//
// The slots are visited four at a time: their weights, neighbour indices and rest lengths
// are loaded first, then the four neighbours' positions and velocities, then the springs
// are summed in slot order as before (the same operations in the same order: the same
// forces). A loop that loaded a slot's weight, then its index, then the neighbour's
// position before the next slot made each thread wait on 48 dependent memory reads in a
// row; at 10,932 nodes (a few warps per multiprocessor, nothing to hide the latency
// behind) the kernel took 17 us on an H100 whatever the size up to 100k nodes. An empty
// slot (weight 0) reads its own node instead of whatever index it holds.

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> velocities: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> nb_index: array<u32>;
@group(0) @binding(4) var<storage, read> nb_weight: array<f32>;
@group(0) @binding(5) var<storage, read> rest_length: array<f32>;
@group(0) @binding(6) var<storage, read_write> forces: array<vec4<f32>>;
@group(0) @binding(10) var<storage, read> node_material: array<vec4<f32>>;

const CHUNK: u32 = 4u;

// One spring's force on node i (mass_spring.rs::force): `d` from i to the neighbour, `dv`
// their velocity difference; zero for an empty slot or coincident nodes.
fn spring(w: f32, d: vec3<f32>, dv: vec3<f32>, rest: f32, k: f32, c: f32) -> vec3<f32> {
    if w == 0.0 {
        return vec3<f32>(0.0);
    }
    let len = length(d);
    if len <= 0.0 {
        return vec3<f32>(0.0);
    }
    let inv = 1.0 / len;
    let mag = w * (k * (len - rest) + c * dot(dv, d) * inv) * inv;
    return mag * d;
}

// Slot `s` of node i, or nothing past the row's end: the weight (0 past the end), the
// neighbour (i itself for an empty slot) and the rest length.
struct Slot {
    w: f32,
    j: u32,
    rest: f32,
}

fn load_slot(i: u32, s: u32) -> Slot {
    if s >= params.k {
        return Slot(0.0, i, 0.0);
    }
    let at = slot(i, s);
    let w = nb_weight[at];
    let j = select(nb_index[at], i, w == 0.0);
    return Slot(w, j, rest_length[at]);
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = node_index(gid);
    if i >= params.n_active {
        return;
    }
    let xi = positions[i].xyz;
    let vi = velocities[i].xyz;
    let k = params.stiffness;
    let c = params.spring_damping;
    var f = vec3<f32>(0.0);
    for (var s = 0u; s < params.k; s += CHUNK) {
        let a = load_slot(i, s);
        let b = load_slot(i, s + 1u);
        let e = load_slot(i, s + 2u);
        let g = load_slot(i, s + 3u);
        let xa = positions[a.j].xyz;
        let xb = positions[b.j].xyz;
        let xe = positions[e.j].xyz;
        let xg = positions[g.j].xyz;
        let va = velocities[a.j].xyz;
        let vb = velocities[b.j].xyz;
        let ve = velocities[e.j].xyz;
        let vg = velocities[g.j].xyz;
        f += spring(a.w, xa - xi, va - vi, a.rest, k, c);
        f += spring(b.w, xb - xi, vb - vi, b.rest, k, c);
        f += spring(e.w, xe - xi, ve - vi, e.rest, k, c);
        f += spring(g.w, xg - xi, vg - vi, g.rest, k, c);
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

// One spring of the `mixed` entry: the series mean of the two nodes' stiffness and damping.
fn mixed_spring(w: f32, d: vec3<f32>, dv: vec3<f32>, rest: f32, mi: vec4<f32>, mj: vec4<f32>) -> vec3<f32> {
    if w == 0.0 {
        return vec3<f32>(0.0);
    }
    let len = length(d);
    if len <= 0.0 {
        return vec3<f32>(0.0);
    }
    let k = series_mean(mi.x, mj.x);
    let c = series_mean(mi.y, mj.y);
    let inv = 1.0 / len;
    let mag = w * (k * (len - rest) + c * dot(dv, d) * inv) * inv;
    return mag * d;
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
    for (var s = 0u; s < params.k; s += CHUNK) {
        let a = load_slot(i, s);
        let b = load_slot(i, s + 1u);
        let e = load_slot(i, s + 2u);
        let g = load_slot(i, s + 3u);
        let xa = positions[a.j].xyz;
        let xb = positions[b.j].xyz;
        let xe = positions[e.j].xyz;
        let xg = positions[g.j].xyz;
        let va = velocities[a.j].xyz;
        let vb = velocities[b.j].xyz;
        let ve = velocities[e.j].xyz;
        let vg = velocities[g.j].xyz;
        let ma = node_material[a.j];
        let mb = node_material[b.j];
        let me = node_material[e.j];
        let mg = node_material[g.j];
        f += mixed_spring(a.w, xa - xi, va - vi, a.rest, mi, ma);
        f += mixed_spring(b.w, xb - xi, vb - vi, b.rest, mi, mb);
        f += mixed_spring(e.w, xe - xi, ve - vi, e.rest, mi, me);
        f += mixed_spring(g.w, xg - xi, vg - vi, g.rest, mi, mg);
    }
    forces[i] = vec4<f32>(f, 0.0);
}
