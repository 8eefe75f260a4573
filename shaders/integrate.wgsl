// Symplectic Euler with implicit mass-proportional damping (integrator.rs):
// v <- (v + dt (f w + g)) * damping_factor, x <- x + dt v; w = inverse mass, 0 = fixed.
// The position update is a compensated sum: remainders keep each update's rounding error
// (TwoSum) and add it to the next increment, so no increment below f32 resolution is lost.

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> positions: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> velocities: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> forces: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read_write> remainders: array<vec4<f32>>;
// The divergence guard (backend.rs, `Backend::guard`): word 0 is set when a free node's new
// position or velocity is not finite or its speed exceeds sqrt(params.max_speed_sq). Only
// such a node writes it, so the atomic costs nothing while the run is sound.
@group(0) @binding(5) var<storage, read_write> guard: array<atomic<u32>>;

// Whether every component is finite, from the exponent bits (a compiler may assume that
// no float is NaN and drop a comparison of a value with itself).
fn finite3(v: vec3<f32>) -> bool {
    let e = bitcast<vec3<u32>>(v) & vec3<u32>(0x7f800000u);
    return all(e != vec3<u32>(0x7f800000u));
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = node_index(gid);
    if i >= params.n_active {
        return;
    }
    var x = positions[i];
    if x.w == 0.0 {
        velocities[i] = vec4<f32>(0.0);
        return;
    }
    let f = forces[i];
    let v = (velocities[i].xyz + params.dt * (f.xyz * x.w + params.gravity.xyz)) * params.damping_factor;
    velocities[i] = vec4<f32>(v, 0.0);
    // TwoSum of x and the increment: x + d = s + e exactly. Shader compilers may treat
    // float arithmetic as real arithmetic and fold (x + d) - x into d, which zeroes e
    // (Mesa's lavapipe did); multiplying by params.gravity.w, 1.0 but unknown to the
    // compiler, keeps each rounded intermediate.
    let one = params.gravity.w;
    let d = params.dt * v + remainders[i].xyz;
    let s = (x.xyz + d) * one;
    let dd = (s - x.xyz) * one;
    let e = (x.xyz - (s - dd)) + (d - dd);
    positions[i] = vec4<f32>(s, x.w);
    remainders[i] = vec4<f32>(e, 0.0);
    if !(finite3(v) && finite3(s)) || dot(v, v) > params.max_speed_sq {
        atomicOr(&guard[0], 1u);
    }
}
